//! A model written as URDF or as the UR driver's kinematics file and read back gives the same
//! forward kinematics; the standard URDF parses with a URDF library other than robocal's.

use nalgebra::{Isometry3, Vector3};
use rand::SeedableRng;
use rand::rngs::ChaCha8Rng;
use robocal::kinematics::Chain;
use robocal::model::{
    LinkMass, RobotModel, UrdfOptions, from_ur_kinematics, from_urdf_str, to_ur_kinematics, to_urdf,
};

fn pose(model: &RobotModel, q: &[f64]) -> Isometry3<f64> {
    let chain = Chain::new(model);
    chain.with_errors(&vec![0.0; chain.params().len()]).pose(q)
}

/// The largest position (mm) and orientation (rad) difference of two models over `n` random
/// configurations within the limits.
fn worst_difference(a: &RobotModel, b: &RobotModel, n: usize) -> (f64, f64) {
    let mut rng = ChaCha8Rng::seed_from_u64(1000);
    a.uniform_configurations(n, &mut rng).iter().fold((0.0f64, 0.0f64), |(mm, rad), q| {
        let (pa, pb) = (pose(a, q), pose(b, q));
        (
            (pa.translation.vector - pb.translation.vector).norm().max(mm),
            pa.rotation.angle_to(&pb.rotation).max(rad),
        )
    })
}

/// The PUMA with every error of the example's true robot (Hayati betas included), placed 1.5 m
/// from a tracker, with masses.
fn calibrated_like_puma() -> RobotModel {
    let text = std::fs::read_to_string("examples/puma560-true.toml").unwrap();
    let mut model = RobotModel::from_toml_str(&text).unwrap();
    model.masses = RobotModel::preset("puma560-masses").unwrap().masses;
    model.joints[1].compliance = 2e-5;
    model
}

#[test]
fn dh_mdh_and_urdf_models_survive_urdf_export_to_1e_9_mm() {
    let models =
        [calibrated_like_puma(), RobotModel::preset("panda").unwrap(), RobotModel::preset("irb120").unwrap()];
    for model in models {
        let exported = to_urdf(&model, UrdfOptions::default());
        let back = from_urdf_str(&exported.urdf, "base_link", "tool0").unwrap();
        let (mm, rad) = worst_difference(&model, &back, 1000);
        assert!(mm < 1e-9 && rad < 1e-12, "{}: {mm} mm, {rad} rad\n{}", model.name, exported.urdf);
        assert_eq!(
            back.joints.iter().map(|j| j.limits).collect::<Vec<_>>(),
            model.joints.iter().map(|j| j.limits).collect::<Vec<_>>()
        );
        assert_eq!(back.joints[1].compliance, model.joints[1].compliance, "{}", model.name);
        // the masses come back, their centres of mass in the URDF link frames
        let masses: f64 = back.masses.iter().map(|m: &LinkMass| m.mass).sum();
        let expected: f64 = model.masses.iter().map(|m| m.mass).sum();
        assert!((masses - expected).abs() < 1e-12, "{masses} {expected}");
        // a URDF model written again is the same URDF
        let again = to_urdf(&back, UrdfOptions::default());
        let twice = from_urdf_str(&again.urdf, "base_link", "tool0").unwrap();
        assert!(worst_difference(&model, &twice, 100).0 < 1e-9);
    }
}

#[test]
fn standard_urdf_parses_with_urdf_rs_and_keeps_the_extras_in_the_sidecar() {
    let model = calibrated_like_puma();
    let exported = to_urdf(&model, UrdfOptions { standard: true });
    assert!(!exported.urdf.contains("robocal_"), "{}", exported.urdf);
    let robot = urdf_rs::read_from_string(&exported.urdf).unwrap();
    assert_eq!(robot.joints.iter().filter(|j| j.joint_type != urdf_rs::JointType::Fixed).count(), 6);
    let first = &robot.joints[0];
    let xyz: Vector3<f64> = Vector3::new(first.origin.xyz[0], first.origin.xyz[1], first.origin.xyz[2]);
    // the base and joint 1's offset along z (standard DH: Rz(theta) Tz(d) before the motion)
    let expected = model.base.isometry() * nalgebra::Point3::new(0.0, 0.0, model.joints[0].d);
    assert!((xyz * 1000.0 - expected.coords).norm() < 1e-9, "the first joint's origin: {xyz}");
    let sidecar: toml::Table = toml::from_str(exported.sidecar.as_deref().unwrap()).unwrap();
    let joints = sidecar["joints"].as_array().unwrap();
    assert_eq!(joints.len(), 1);
    assert_eq!(joints[0]["name"].as_str(), Some("j2"));
    assert_eq!(joints[0]["compliance"].as_float(), Some(2e-5));
    // the kinematics alone still read back the same
    let back = from_urdf_str(&exported.urdf, "base_link", "tool0").unwrap();
    let rigid = RobotModel {
        joints: model.joints.iter().map(|j| robocal::model::Joint { compliance: 0.0, ..j.clone() }).collect(),
        ..model.clone()
    };
    assert!(worst_difference(&rigid, &back, 200).0 < 1e-9);
}

#[test]
fn the_ur_driver_kinematics_file_round_trips() {
    // a calibrated UR5e: small errors on every DH parameter, the base in the controller's frame
    let mut model = RobotModel::preset("ur5e").unwrap();
    for (i, joint) in model.joints.iter_mut().enumerate() {
        let e = (i as f64 + 1.0) * 1e-3;
        (joint.theta, joint.d, joint.a, joint.alpha, joint.beta) = (
            joint.theta + e,
            joint.d + 0.3 * e * 100.0,
            joint.a - 0.2,
            joint.alpha - e,
            if i == 1 { 2e-3 } else { 0.0 },
        );
    }
    let (yaml, tcp) = to_ur_kinematics(&model).unwrap();
    assert!(yaml.starts_with("kinematics:\n  shoulder:\n    x: "), "{yaml}");
    let back = from_ur_kinematics(&yaml, "ur5e-calibrated").unwrap();
    let with_tcp = RobotModel {
        tool: robocal::model::Tool::Frame(robocal::model::Placement::from_isometry(&tcp)),
        ..back.clone()
    };
    let (mm, rad) = worst_difference(&model, &with_tcp, 1000);
    assert!(mm < 1e-9 && rad < 1e-12, "{mm} mm {rad} rad\n{yaml}");
    // the nominal UR5e's tool is the flange: nothing is left for the TCP
    let (_, nominal_tcp) = to_ur_kinematics(&RobotModel::preset("ur5e").unwrap()).unwrap();
    assert!(nominal_tcp.translation.vector.norm() < 1e-12 && nominal_tcp.rotation.angle() < 1e-12);
    // a driver file as UR ships it (the UR5e's, with its hash line) reads as the preset's kinematics
    let shipped = "kinematics:\n  shoulder:\n    x: 0\n    y: 0\n    z: 0.1625\n    roll: 0\n    pitch: 0\n    yaw: 0\n  upper_arm:\n    x: 0\n    y: 0\n    z: 0\n    roll: 1.570796327\n    pitch: 0\n    yaw: 0\n  forearm:\n    x: -0.425\n    y: 0\n    z: 0\n    roll: 0\n    pitch: 0\n    yaw: 0\n  wrist_1:\n    x: -0.3922\n    y: 0\n    z: 0.1333\n    roll: 0\n    pitch: 0\n    yaw: 0\n  wrist_2:\n    x: 0\n    y: -0.0997\n    z: -2.044881182297852e-11\n    roll: 1.570796327\n    pitch: 0\n    yaw: 0\n  wrist_3:\n    x: 0\n    y: 0.09959999999999999\n    z: -2.042830148012698e-11\n    roll: 1.570796326589793\n    pitch: 3.141592653589793\n    yaw: 3.141592653589793\n  hash: calib_12788084448423163542\n";
    let ur5e = from_ur_kinematics(shipped, "ur5e").unwrap();
    let (mm, _) = worst_difference(&RobotModel::preset("ur5e").unwrap(), &ur5e, 100);
    assert!(mm < 1e-3, "{mm}");
    let bad = from_ur_kinematics(&shipped.replace("z: 0.1625", "z: high"), "x").unwrap_err().to_string();
    assert!(bad.contains("line 5"), "{bad}");
    let missing =
        from_ur_kinematics(&shipped.replace("    yaw: 0\n  upper_arm", "  upper_arm"), "x").unwrap_err();
    assert!(format!("{missing}").contains("shoulder.yaw"), "{missing}");
}

/// `model urdf --urdf-standard` of a calibrated model carries the calibration's covariance
/// (`<model>.covariance.json`) into its sidecar, and warns of a negative compliance.
#[test]
fn the_standard_urdf_sidecar_carries_the_covariance_and_a_negative_compliance_is_warned() {
    let dir = std::env::temp_dir().join(format!("robocal-urdf-sidecar-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let calibrated = dir.join("calibrated.toml");
    let run = |args: &[&str]| assert_cmd::Command::cargo_bin("robocal").unwrap().args(args).output().unwrap();
    let path = |p: &std::path::Path| p.to_str().unwrap().to_string();
    let out = run(&[
        "calibrate",
        "--model",
        "puma560",
        "--data",
        "examples/puma560-measurements.csv",
        "--marker",
        "50,0,150",
        "--marker=-40,60,120",
        "--validate",
        "examples/puma560-validation.csv",
        "--out-model",
        &path(&calibrated),
    ]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let urdf = dir.join("calibrated.urdf");
    let out = run(&["model", "urdf", &path(&calibrated), "--urdf-standard", "--out", &path(&urdf)]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let sidecar: toml::Table =
        toml::from_str(&std::fs::read_to_string(dir.join("calibrated.extras.toml")).unwrap()).unwrap();
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("calibrated.toml.covariance.json")).unwrap())
            .unwrap();
    let covariance = &sidecar["covariance"];
    let names = covariance["names"].as_array().unwrap();
    assert_eq!(names.len(), json["names"].as_array().unwrap().len());
    let matrix = covariance["matrix"].as_array().unwrap();
    assert_eq!(matrix.len(), names.len());
    assert_eq!(matrix[3].as_array().unwrap()[3].as_float(), json["covariance"][3][3].as_f64());

    let mut soft = RobotModel::preset("puma560-masses").unwrap();
    soft.joints[1].compliance = -1e-4;
    let negative = dir.join("negative.toml");
    std::fs::write(&negative, soft.to_toml_string()).unwrap();
    let out =
        run(&["model", "urdf", &path(&negative), "--urdf-standard", "--out", &path(&dir.join("n.urdf"))]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let warning = String::from_utf8_lossy(&out.stderr);
    assert!(warning.contains("j2: a negative compliance (-1.000e-4)"), "{warning}");
    std::fs::remove_dir_all(&dir).unwrap();
}
