//! The report of `robocal compensate`: the compensated program as CSV, a text summary and JSON,
//! from the targets and their solutions.

use crate::design::compensate::{Compensated, TargetRow, Unreachable};
use crate::model::{JointKind, RobotModel};
use std::fmt::Write;

/// One target's outcome: its line in the target file and the solution or why there is none.
pub type Outcome<'a> = (&'a TargetRow, &'a Result<Compensated, Unreachable>);

/// A joint value (rad, mm) in the files' unit: degrees, mm for a prismatic joint.
fn in_file_unit(kind: JointKind, v: f64) -> f64 {
    if kind == JointKind::Revolute { v.to_degrees() } else { v }
}

/// The compensated program: the units line, `comment` lines, then per reached target its line in
/// the target file, the joint values to send (deg; mm), each joint's change from the seed
/// (`change_<joint>`), the remaining error (mm, deg) and the iterations. Unreachable targets
/// are left out (the report names them).
pub fn csv(model: &RobotModel, outcomes: &[Outcome<'_>], comment: &str) -> String {
    let mut out = String::from("# units: joints=deg, lengths=mm\n");
    for line in comment.lines() {
        let _ = writeln!(out, "# {line}");
    }
    let names: Vec<&str> = model.joints.iter().map(|j| j.name.as_str()).collect();
    let changes: Vec<String> = names.iter().map(|n| format!("change_{n}")).collect();
    let _ = writeln!(out, "line,{},{},error_mm,error_deg,iterations", names.join(","), changes.join(","));
    for (row, outcome) in outcomes {
        let Ok(c) = outcome else { continue };
        let values = |v: &[f64]| -> Vec<String> {
            model.joints.iter().zip(v).map(|(j, &v)| format!("{:.9}", in_file_unit(j.kind, v))).collect()
        };
        let _ = writeln!(
            out,
            "{},{},{},{:.3e},{:.3e},{}",
            row.line,
            values(&c.joints).join(","),
            values(&c.change).join(","),
            c.error_mm,
            c.error_rad.to_degrees(),
            c.iterations
        );
    }
    out
}

/// Statistics of a list of errors: (max, rms).
fn max_rms(values: impl Iterator<Item = f64> + Clone) -> (f64, f64) {
    let n = values.clone().count().max(1) as f64;
    let max = values.clone().fold(0.0, f64::max);
    (max, (values.map(|v| v * v).sum::<f64>() / n).sqrt())
}

/// The text report: how many targets were reached, the calibrated model's errors before and
/// after (max, rms), the largest joint change, and every unreachable target with its line and
/// reason.
pub fn text(source: &str, model: &RobotModel, outcomes: &[Outcome<'_>]) -> String {
    let reached: Vec<&Compensated> = outcomes.iter().filter_map(|(_, o)| o.as_ref().ok()).collect();
    let mut out = String::new();
    let _ = writeln!(out, "compensated {} of {} targets of {source}", reached.len(), outcomes.len());
    if !reached.is_empty() {
        let _ = writeln!(out, "\nerror of the calibrated model      max mm    rms mm   max deg   rms deg");
        type Errors = fn(&&Compensated) -> (f64, f64);
        let rows: [(&str, Errors); 2] = [
            ("uncompensated (at the seeds)", |c| (c.before_mm, c.before_rad)),
            ("compensated", |c| (c.error_mm, c.error_rad)),
        ];
        for (name, f) in rows {
            let (mm, rms_mm) = max_rms(reached.iter().map(|c| f(c).0));
            let (rad, rms_rad) = max_rms(reached.iter().map(|c| f(c).1));
            let _ = writeln!(
                out,
                "{name:<32} {mm:>9.6} {rms_mm:>9.6} {:>9.6} {:>9.6}",
                rad.to_degrees(),
                rms_rad.to_degrees()
            );
        }
        let iterations = reached.iter().map(|c| c.iterations).max().unwrap_or(0);
        let _ = writeln!(out, "at most {iterations} iterations per target");
        let _ = writeln!(out, "\nlargest change per joint (deg; mm for prismatic joints)");
        for (k, joint) in model.joints.iter().enumerate() {
            let most = reached.iter().map(|c| c.change[k].abs()).fold(0.0, f64::max);
            let _ = writeln!(out, "  {:<10} {:>10.6}", joint.name, in_file_unit(joint.kind, most));
        }
    }
    let unreachable: Vec<String> = outcomes
        .iter()
        .filter_map(|(row, o)| o.as_ref().err().map(|e| format!("  line {}: {e}", row.line)))
        .collect();
    if !unreachable.is_empty() {
        let _ = writeln!(out, "\nunreachable targets ({}), not written:", unreachable.len());
        out += &(unreachable.join("\n") + "\n");
    }
    out
}

/// The JSON report: every target with its line, the joints sent, their changes, the remaining
/// error and iterations, or the reason it cannot be reached.
pub fn json(model: &RobotModel, outcomes: &[Outcome<'_>]) -> String {
    let to_file = |v: &[f64]| -> Vec<f64> {
        model.joints.iter().zip(v).map(|(j, &v)| in_file_unit(j.kind, v)).collect()
    };
    let targets: Vec<serde_json::Value> = outcomes
        .iter()
        .map(|(row, outcome)| match outcome {
            Ok(c) => serde_json::json!({
                "line": row.line,
                "reached": true,
                "joints": to_file(&c.joints),
                "change": to_file(&c.change),
                "error_mm": c.error_mm,
                "error_deg": c.error_rad.to_degrees(),
                "before_mm": c.before_mm,
                "before_deg": c.before_rad.to_degrees(),
                "iterations": c.iterations,
            }),
            Err(e) => serde_json::json!({ "line": row.line, "reached": false, "reason": e.to_string() }),
        })
        .collect();
    let joints: Vec<&str> = model.joints.iter().map(|j| j.name.as_str()).collect();
    let report = serde_json::json!({
        "units": { "joints": "deg (mm for prismatic joints)", "errors": "mm, deg" },
        "joint_names": joints,
        "targets": targets,
    });
    serde_json::to_string_pretty(&report).expect("JSON of numbers and strings") + "\n"
}
