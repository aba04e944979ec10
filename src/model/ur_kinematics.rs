//! The Universal Robots ROS driver's kinematics file (`default_kinematics.yaml`, or the one
//! `ur_calibration` extracts from a robot): per joint the origin of its URDF joint in its
//! parent link, `x, y, z` (m) and `roll, pitch, yaw` (rad), under `kinematics:`:
//!
//! ```text
//! kinematics:
//!   shoulder:
//!     x: 0
//!     y: 0
//!     z: 0.1625
//!     roll: 0
//!     pitch: 0
//!     yaw: 0
//!   upper_arm:
//!   ...
//! ```
//!
//! The segments are `shoulder`, `upper_arm`, `forearm`, `wrist_1`, `wrist_2`, `wrist_3`, in the
//! controller's base frame (`base_link_inertia`); the driver's `tool0` is the `wrist_3` link's
//! frame, so a tool (a TCP) is not in the file. Only this layout is read (a subset of YAML:
//! two-space indents, `key: number`); other keys at the top level (`hash:`) are ignored.

use super::urdf_export::joint_origins;
use super::{Convention, Joint, JointKind, ModelError, Placement, RobotModel, Tool};
use crate::error::FieldError;
use nalgebra::{Isometry3, Vector3};
use std::fmt::Write;

/// The six segments, base to tip.
pub const UR_SEGMENTS: [&str; 6] = ["shoulder", "upper_arm", "forearm", "wrist_1", "wrist_2", "wrist_3"];
/// The joint names of the UR driver, base to tip.
pub const UR_JOINTS: [&str; 6] = ["shoulder_pan", "shoulder_lift", "elbow", "wrist_1", "wrist_2", "wrist_3"];
const KEYS: [&str; 6] = ["x", "y", "z", "roll", "pitch", "yaw"];

/// A UR model as the driver's kinematics file, and the tool placement it cannot hold (in the
/// `wrist_3` link's frame, mm; the identity for a model whose tool is the flange): set it as
/// the controller's TCP. `model` needs six revolute joints.
pub fn to_ur_kinematics(model: &RobotModel) -> Result<(String, Isometry3<f64>), ModelError> {
    if model.dof() != 6 || model.joints.iter().any(|j| j.kind != JointKind::Revolute) {
        return Err(FieldError::new("joints", "six revolute joints, a UR arm's").into());
    }
    let (origins, tool) = joint_origins(model);
    let mut out = String::from("kinematics:\n");
    for (segment, (origin, axis)) in UR_SEGMENTS.iter().zip(&origins) {
        // The driver's joints turn about z: a joint about another axis has its origin turned
        // to take z onto that axis.
        let origin = origin * z_onto(axis);
        let p = Placement::from_isometry(&origin);
        let _ = writeln!(out, "  {segment}:");
        let values = [p.xyz.x / 1000.0, p.xyz.y / 1000.0, p.xyz.z / 1000.0, p.rpy.x, p.rpy.y, p.rpy.z];
        for (key, v) in KEYS.iter().zip(values) {
            let _ = writeln!(out, "    {key}: {v:?}");
        }
    }
    Ok((out, tool))
}

/// A nominal UR model from the driver's kinematics file: URDF joints at its segments, about
/// z, limits +-360 deg, the tool the `wrist_3` link's frame (`tool0`).
pub fn from_ur_kinematics(text: &str, name: &str) -> Result<RobotModel, ModelError> {
    let mut values = [[None::<f64>; 6]; 6];
    let (mut in_kinematics, mut segment) = (false, None::<usize>);
    for (n, raw) in text.lines().enumerate() {
        let line = raw.split('#').next().unwrap_or("").trim_end();
        if line.trim().is_empty() {
            continue;
        }
        let at = |expected: &str| {
            ModelError::from(FieldError::new(format!("line {}", n + 1), expected.to_string()))
        };
        let indent = line.len() - line.trim_start().len();
        let (key, value) = line.trim().split_once(':').ok_or_else(|| at("`key: value`"))?;
        let value = value.trim();
        match indent {
            0 => (in_kinematics, segment) = (key == "kinematics", None),
            2 if in_kinematics && value.is_empty() => {
                let i = UR_SEGMENTS.iter().position(|s| *s == key);
                segment = Some(i.ok_or_else(|| at(&format!("a segment: {}", UR_SEGMENTS.join(", "))))?);
            }
            2 => segment = None, // `hash: calib_...`
            4 if in_kinematics => {
                let s = segment.ok_or_else(|| at("a value under a segment"))?;
                let k = KEYS
                    .iter()
                    .position(|k| *k == key)
                    .ok_or_else(|| at("one of x, y, z, roll, pitch, yaw"))?;
                let v: f64 =
                    value.parse().map_err(|_| at(&format!("a number for `{key}`, found `{value}`")))?;
                if !v.is_finite() || v.abs() > 1e3 {
                    return Err(at(&format!("a finite number of at most 1000 for `{key}`, found {v}")));
                }
                values[s][k] = Some(v);
            }
            _ => {}
        }
    }
    let mut joints = Vec::new();
    for (s, segment) in UR_SEGMENTS.iter().enumerate() {
        let v: Vec<f64> = (0..6)
            .map(|k| {
                values[s][k].ok_or_else(|| {
                    ModelError::from(FieldError::new(format!("kinematics.{segment}.{}", KEYS[k]), "a number"))
                })
            })
            .collect::<Result<_, _>>()?;
        let origin =
            Placement { xyz: Vector3::new(v[0], v[1], v[2]) * 1000.0, rpy: Vector3::new(v[3], v[4], v[5]) };
        let limit = 360f64.to_radians();
        joints.push(Joint::urdf(UR_JOINTS[s], JointKind::Revolute, origin, Vector3::z(), [-limit, limit]));
    }
    Ok(RobotModel {
        name: name.to_string(),
        description: "from a Universal Robots driver kinematics file".into(),
        convention: Convention::Urdf,
        base: Placement::default(),
        joints,
        tool: Tool::Frame(Placement::default()),
        masses: Vec::new(),
        gravity: RobotModel::floor_gravity(),
        payload: None,
    })
}

/// The rotation taking z onto the unit `axis`.
fn z_onto(axis: &Vector3<f64>) -> Isometry3<f64> {
    let rotation = nalgebra::UnitQuaternion::rotation_between(&Vector3::z(), axis).unwrap_or_else(|| {
        nalgebra::UnitQuaternion::from_axis_angle(&Vector3::x_axis(), std::f64::consts::PI)
    });
    Isometry3::from_parts(nalgebra::Translation3::identity(), rotation)
}
