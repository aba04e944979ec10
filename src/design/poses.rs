//! Pose files: the joint columns of the measurement file (see `docs/formats.md`), one row per
//! pose, so that a planned set can drive a robot program and, with the measured marker
//! columns added, be read by `robocal calibrate`.
//!
//! ```text
//! # units: joints=deg, lengths=mm
//! j1,j2,j3,j4,j5,j6
//! 10.000000,45.000000,-30.000000,0.000000,20.000000,5.000000
//! ```

use crate::model::{JointKind, RobotModel};
use crate::table::{DataError, Table, Units};

/// The poses `joints` (rad, mm) as a pose file: the units line, `comment` lines (each
/// prefixed with `# `), the model's joint names, then one row per pose in degrees (mm for
/// prismatic joints) with 6 decimals.
pub fn poses_csv(model: &RobotModel, joints: &[Vec<f64>], comment: &str) -> String {
    let mut out = String::from("# units: joints=deg, lengths=mm\n");
    for line in comment.lines() {
        out += &format!("# {line}\n");
    }
    let names: Vec<&str> = model.joints.iter().map(|j| j.name.as_str()).collect();
    out += &(names.join(",") + "\n");
    for q in joints {
        let values: Vec<String> = model
            .joints
            .iter()
            .zip(q)
            .map(|(joint, &v)| match joint.kind {
                JointKind::Revolute => format!("{:.6}", v.to_degrees()),
                JointKind::Prismatic => format!("{v:.6}"),
            })
            .map(|s| {
                if s.trim_start_matches('-').trim_matches(['0', '.']).is_empty() {
                    "0.000000".into()
                } else {
                    s
                }
            })
            .collect();
        out += &(values.join(",") + "\n");
    }
    out
}

/// The joint values (rad, mm) of a pose file or of a measurement file (other columns are
/// ignored). `units` given by the caller take the place of the file's `# units:` line.
pub fn poses_from_csv_str(
    text: &str,
    model: &RobotModel,
    units: Option<Units>,
) -> Result<Vec<Vec<f64>>, DataError> {
    let table = Table::parse(text)?;
    let units = table.units(units, "")?;
    let columns = table.joint_columns(model)?;
    table.nonempty_rows()?.iter().map(|row| table.joint_values(row, &columns, model, units)).collect()
}
