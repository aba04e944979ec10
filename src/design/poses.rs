//! Pose files: the joint columns of the measurement file (see `docs/formats.md`), one row per
//! pose, so that a planned set can drive a robot program and, with the measured marker
//! columns added, be read by `robocal calibrate`.
//!
//! ```text
//! # units: joints=deg, lengths=mm
//! j1,j2,j3,j4,j5,j6
//! 10.000000,45.000000,-30.000000,0.000000,20.000000,5.000000
//! ```

use crate::calibration::{CsvTable, DataError, Units, csv_table, table_joint_columns};
use crate::model::{JointKind, RobotModel};

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
    let error = |line: usize, column: Option<&str>, message: String| DataError {
        line,
        column: column.map(str::to_string),
        message,
    };
    let units = match (units, crate::calibration::declared_units(text)?) {
        (Some(units), _) | (None, Some(units)) => units,
        (None, None) => {
            return Err(error(
                1,
                None,
                "units not declared: start the file with `# units: joints=deg, lengths=mm` (or rad, m)"
                    .into(),
            ));
        }
    };
    let CsvTable { mut reader, header, header_line } = csv_table(text).map_err(|e| error(1, None, e))?;
    let columns = table_joint_columns(&header, header_line, model)?;
    let length = if units.lengths_in_metres { 1000.0 } else { 1.0 };
    let mut poses = Vec::new();
    for record in reader.records() {
        let record =
            record.map_err(|e| error(e.position().map_or(0, |p| p.line() as usize), None, e.to_string()))?;
        let line = record.position().map_or(0, |p| p.line() as usize);
        let q = model
            .joints
            .iter()
            .zip(&columns)
            .map(|(joint, &c)| {
                let text = record.get(c).ok_or_else(|| {
                    error(
                        line,
                        Some(&header[c]),
                        format!("{} values, the header has {}", record.len(), header.len()),
                    )
                })?;
                let v: f64 = text
                    .parse()
                    .map_err(|_| error(line, Some(&header[c]), format!("`{text}` is not a number")))?;
                if !v.is_finite() {
                    return Err(error(line, Some(&header[c]), format!("{v}: expected a finite number")));
                }
                Ok(match joint.kind {
                    JointKind::Revolute if units.joints_in_degrees => v.to_radians(),
                    JointKind::Revolute => v,
                    JointKind::Prismatic => v * length,
                })
            })
            .collect::<Result<Vec<_>, _>>()?;
        poses.push(q);
    }
    if poses.is_empty() {
        return Err(error(header_line, None, "no poses after the header".into()));
    }
    Ok(poses)
}
