//! Reports: text at fixed precision (so that it can be snapshot-tested), CSV and SVG. Nothing
//! here touches a file: [`crate::io`] writes what these functions return.

pub mod accuracy;
pub mod calibration;
pub mod calibration_page;
pub mod compensation;
pub mod design;
pub mod figures;
pub mod files_page;
pub mod html;
pub mod instruments;
pub mod observations;
pub mod replication;
pub mod residuals;
pub mod study;
pub mod verdict;

use crate::model::{JointKind, RobotModel, degrees};
use nalgebra::Isometry3;
use std::fmt::Write;

/// Where training row `k` is, when several files were fitted together (`files`: each one's
/// name and number of rows, in order): `FILE line N`; with one file, `line N`.
pub(crate) fn line_in(files: &[(String, usize)], k: usize, line: usize) -> String {
    let mut first = 0;
    for (name, rows) in files.iter().filter(|_| files.len() > 1) {
        if k < first + rows {
            return format!("{name} line {line}");
        }
        first += rows;
    }
    format!("line {line}")
}

/// The training files by which set `set` of `sets` is numbered (`files`: each training file's
/// name and number of rows): the training set's (the first) and, with `--folds` (`folds`), the
/// cross-validation's (the last, the training rows in their order); none for a held-out
/// file's.
pub(crate) fn files_of(
    files: &[(String, usize)],
    set: usize,
    sets: usize,
    folds: bool,
) -> &[(String, usize)] {
    if set == 0 || (folds && set + 1 == sets) { files } else { &[] }
}

/// The tool pose at joint values `q` (rad or mm) as a person checks it against a controller:
/// position (mm), roll-pitch-yaw (deg, `R = Rz(yaw) Ry(pitch) Rx(roll)`), quaternion and the
/// homogeneous transform.
pub fn tool_pose(model: &RobotModel, q: &[f64], pose: &Isometry3<f64>) -> String {
    let joints: Vec<String> = model
        .joints
        .iter()
        .zip(q)
        .map(|(joint, &v)| match joint.kind {
            JointKind::Revolute => format!("{} deg", degrees(v)),
            JointKind::Prismatic => format!("{v} mm"),
        })
        .collect();
    let p = pose.translation.vector.map(|v| tidy(v, 6));
    let (roll, pitch, yaw) = pose.rotation.euler_angles();
    let (roll, pitch, yaw) =
        (tidy(roll.to_degrees(), 6), tidy(pitch.to_degrees(), 6), tidy(yaw.to_degrees(), 6));
    let quat = pose.rotation.quaternion().coords.map(|v| tidy(v, 9));
    let m = pose.to_homogeneous().map(|v| tidy(v, 9));
    let mut out = String::new();
    let _ = writeln!(out, "model       {}", model.name);
    let _ = writeln!(out, "joints      {}", joints.join(", "));
    let _ = writeln!(out, "position    x = {:.6} mm, y = {:.6} mm, z = {:.6} mm", p.x, p.y, p.z);
    let _ = writeln!(
        out,
        "rotation    roll = {:.6} deg, pitch = {:.6} deg, yaw = {:.6} deg  (R = Rz(yaw) Ry(pitch) Rx(roll))",
        roll, pitch, yaw
    );
    let _ = writeln!(
        out,
        "quaternion  w = {:.9}, x = {:.9}, y = {:.9}, z = {:.9}",
        quat.w, quat.x, quat.y, quat.z
    );
    let _ = writeln!(out, "transform   (rotation | translation in mm)");
    for r in 0..3 {
        let _ = writeln!(
            out,
            "            {:>12.9} {:>12.9} {:>12.9} | {:>12.6}",
            m[(r, 0)],
            m[(r, 1)],
            m[(r, 2)],
            m[(r, 3)]
        );
    }
    out
}

/// `v` with anything that prints as zero at `decimals` places made a plain zero, so reports
/// never show `-0.000`.
fn tidy(v: f64, decimals: i32) -> f64 {
    if v.abs() < 0.5 * 10f64.powi(-decimals) { 0.0 } else { v }
}
