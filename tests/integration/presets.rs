//! The presets of current arms against their makers' own descriptions: the tool pose of each
//! preset at two configurations equals the pose its maker's (or the maker-sanctioned ROS)
//! URDF chain gives, composed here joint by joint from that file's numbers (metres, radians):
//! an independent forward kinematics, not robocal's, from a source other than the preset's
//! DH table.

use nalgebra::{Isometry3, Translation3, Unit, UnitQuaternion, Vector3};
use robocal::kinematics::Chain;
use robocal::model::{PRESETS, RobotModel};
use std::f64::consts::{FRAC_PI_2, PI};

/// A URDF joint: origin xyz (m), rpy (rad), axis.
type UrdfJoint = ([f64; 3], [f64; 3], [f64; 3]);
/// A fixed URDF joint: origin xyz (m), rpy (rad).
type Fixed = ([f64; 3], [f64; 3]);

fn origin(xyz: [f64; 3], rpy: [f64; 3]) -> Isometry3<f64> {
    Isometry3::from_parts(
        Translation3::new(xyz[0] * 1000.0, xyz[1] * 1000.0, xyz[2] * 1000.0),
        UnitQuaternion::from_euler_angles(rpy[0], rpy[1], rpy[2]),
    )
}

/// The pose (mm) of the URDF chain `joints` at `q`, then the fixed joints `tool`.
fn urdf_pose(joints: &[UrdfJoint], tool: &[Fixed], q: &[f64]) -> Isometry3<f64> {
    let mut pose = Isometry3::identity();
    for ((xyz, rpy, axis), &q) in joints.iter().zip(q) {
        let turn = UnitQuaternion::from_axis_angle(&Unit::new_normalize(Vector3::from(*axis)), q);
        pose = pose * origin(*xyz, *rpy) * Isometry3::from_parts(Translation3::identity(), turn);
    }
    for (xyz, rpy) in tool {
        pose *= origin(*xyz, *rpy);
    }
    pose
}

fn preset_pose(name: &str, q: &[f64]) -> Isometry3<f64> {
    let model = RobotModel::preset(name).unwrap();
    Chain::new(&model).with_errors(&vec![0.0; model.params().len()]).pose(q)
}

fn assert_same_pose(name: &str, q: &[f64], reference: &Isometry3<f64>) {
    let pose = preset_pose(name, q);
    let dp = (pose.translation.vector - reference.translation.vector).norm();
    let dr = pose.rotation.angle_to(&reference.rotation);
    assert!(
        dp < 1e-9 && dr < 1e-12,
        "{name} at {q:?}: {dp} mm, {dr} rad from the maker's chain\n{pose}\n{reference}"
    );
}

const Z: [f64; 3] = [0.0, 0.0, 1.0];

/// Universal Robots' URDF chain (Universal_Robots_ROS2_Description: the per-joint origins of
/// `config/<model>/default_kinematics.yaml`, whose UR5e file reads shoulder z 0.1625,
/// upper_arm roll pi/2, forearm x -0.425, wrist_1 x -0.3922 z 0.1333, wrist_2 y -0.0997 roll
/// pi/2, wrist_3 y 0.0996 roll pi/2 pitch pi yaw pi; `urdf/ur_macro.xacro`: the flange at rpy
/// (0, -pi/2, -pi/2) of wrist_3_link and tool0 at (pi/2, 0, pi/2) of the flange), in the
/// controller's `base` frame (base_link_inertia: base_link turned by pi, as `base` is).
fn ur_chain([d1, a2, a3, d4, d5, d6]: [f64; 6]) -> (Vec<UrdfJoint>, Vec<Fixed>) {
    let joints = vec![
        ([0.0, 0.0, d1], [0.0, 0.0, 0.0], Z),
        ([0.0, 0.0, 0.0], [FRAC_PI_2, 0.0, 0.0], Z),
        ([a2, 0.0, 0.0], [0.0, 0.0, 0.0], Z),
        ([a3, 0.0, d4], [0.0, 0.0, 0.0], Z),
        ([0.0, -d5, 0.0], [FRAC_PI_2, 0.0, 0.0], Z),
        ([0.0, d6, 0.0], [FRAC_PI_2, PI, PI], Z),
    ];
    let tool = vec![([0.0; 3], [0.0, -FRAC_PI_2, -FRAC_PI_2]), ([0.0; 3], [FRAC_PI_2, 0.0, FRAC_PI_2])];
    (joints, tool)
}

const CONFIGURATIONS_6: [[f64; 6]; 2] =
    [[0.3, -1.2, 0.9, -0.4, 1.1, 2.0], [-2.1, -0.5, -1.7, 1.3, -0.6, -0.8]];

#[test]
fn universal_robots_e_series_match_the_makers_urdf_chain() {
    for (name, lengths) in [
        ("ur3e", [0.15185, -0.24355, -0.2132, 0.13105, 0.08535, 0.0921]),
        ("ur5e", [0.1625, -0.425, -0.3922, 0.1333, 0.0997, 0.0996]),
        ("ur10e", [0.1807, -0.6127, -0.57155, 0.17415, 0.11985, 0.11655]),
        ("ur16e", [0.1807, -0.4784, -0.36, 0.17415, 0.11985, 0.11655]),
    ] {
        let (joints, tool) = ur_chain(lengths);
        for q in CONFIGURATIONS_6 {
            assert_same_pose(name, &q, &urdf_pose(&joints, &tool, &q));
        }
    }
}

#[test]
fn franka_panda_matches_franka_description() {
    // franka_ros franka_description/robots/panda_arm.xacro: joint1 ... joint7, joint8 (flange).
    let joints: Vec<UrdfJoint> = vec![
        ([0.0, 0.0, 0.333], [0.0, 0.0, 0.0], Z),
        ([0.0, 0.0, 0.0], [-FRAC_PI_2, 0.0, 0.0], Z),
        ([0.0, -0.316, 0.0], [FRAC_PI_2, 0.0, 0.0], Z),
        ([0.0825, 0.0, 0.0], [FRAC_PI_2, 0.0, 0.0], Z),
        ([-0.0825, 0.384, 0.0], [-FRAC_PI_2, 0.0, 0.0], Z),
        ([0.0, 0.0, 0.0], [FRAC_PI_2, 0.0, 0.0], Z),
        ([0.088, 0.0, 0.0], [FRAC_PI_2, 0.0, 0.0], Z),
    ];
    let tool = [([0.0, 0.0, 0.107], [0.0; 3])];
    for q in [[0.4, -0.7, 0.2, -2.1, 0.5, 1.8, -0.9], [-1.9, 1.2, -2.4, -0.3, 2.2, 0.1, 2.5]] {
        assert_same_pose("panda", &q, &urdf_pose(&joints, &tool, &q));
    }
}

#[test]
fn kuka_iiwa14_matches_iiwa_description() {
    // IFL-CAMP iiwa_stack iiwa_description/urdf/iiwa14.xacro: joint_1 ... joint_7, joint_ee.
    let joints: Vec<UrdfJoint> = vec![
        ([0.0, 0.0, 0.1575], [0.0, 0.0, 0.0], Z),
        ([0.0, 0.0, 0.2025], [FRAC_PI_2, 0.0, PI], Z),
        ([0.0, 0.2045, 0.0], [FRAC_PI_2, 0.0, PI], Z),
        ([0.0, 0.0, 0.2155], [FRAC_PI_2, 0.0, 0.0], Z),
        ([0.0, 0.1845, 0.0], [-FRAC_PI_2, PI, 0.0], Z),
        ([0.0, 0.0, 0.2155], [FRAC_PI_2, 0.0, 0.0], Z),
        ([0.0, 0.081, 0.0], [-FRAC_PI_2, PI, 0.0], Z),
    ];
    let tool = [([0.0, 0.0, 0.045], [PI, PI, PI])];
    for q in [[0.4, -0.7, 0.2, -1.1, 0.5, 1.8, -0.9], [-1.9, 1.2, -2.4, 0.3, 2.2, -0.1, 2.5]] {
        assert_same_pose("iiwa14", &q, &urdf_pose(&joints, &tool, &q));
    }
}

#[test]
fn abb_irb120_matches_the_ros_industrial_description() {
    // ros-industrial/abb abb_irb120_support/urdf/irb120_3_58_macro.xacro: joint_1 ... joint_6,
    // flange, tool0 (rpy 0, 90 deg, 0).
    let (x, y) = ([1.0, 0.0, 0.0], [0.0, 1.0, 0.0]);
    let joints: Vec<UrdfJoint> = vec![
        ([0.0, 0.0, 0.0], [0.0; 3], Z),
        ([0.0, 0.0, 0.29], [0.0; 3], y),
        ([0.0, 0.0, 0.27], [0.0; 3], y),
        ([0.0, 0.0, 0.07], [0.0; 3], x),
        ([0.302, 0.0, 0.0], [0.0; 3], y),
        ([0.072, 0.0, 0.0], [0.0; 3], x),
    ];
    let tool = [([0.0; 3], [0.0, FRAC_PI_2, 0.0])];
    for q in CONFIGURATIONS_6 {
        assert_same_pose("irb120", &q, &urdf_pose(&joints, &tool, &q));
    }
    // all zeros: the wrist flange 374 mm forward, 630 mm up (the specification's drawing)
    let zero = preset_pose("irb120", &[0.0; 6]).translation.vector;
    assert!((zero - Vector3::new(374.0, 0.0, 630.0)).norm() < 1e-9, "{zero}");
}

#[test]
fn every_preset_has_limits_and_a_source() {
    for (name, _) in PRESETS {
        let model = RobotModel::preset(name).unwrap();
        assert!(!model.description.is_empty(), "{name}");
        assert!(model.joints.iter().all(|j| j.limits[0] < j.limits[1]), "{name}");
        if name.starts_with("ur") {
            assert_eq!(model.masses.len(), 6, "{name}: UR publishes its link masses");
        }
    }
    let panda = RobotModel::preset("panda").unwrap();
    assert_eq!(panda.convention, robocal::model::Convention::ModifiedDh);
    let [lower, upper] = panda.joints[3].limits; // Franka's -3.0718 .. -0.0698 rad
    assert!((lower + 3.0718).abs() < 1e-7 && (upper + 0.0698).abs() < 1e-7, "{lower} {upper}");
}
