//! Sets of poses scored pose by pose and marker by marker ([`SetEvaluation`]) as text tables
//! and CSV, shared by `calibrate` and `evaluate`.
//!
//! The text keeps to summaries, so that it stays readable for hundreds of poses: pooled and
//! per marker for each set, then the [`WORST`] worst poses of each set. Every pose is in the
//! CSV (one row per pose and marker), the JSON and the HTML page.

use crate::calibration::{ErrorStats, SetEvaluation};
use crate::model::{Joint, JointKind};
use std::fmt::Write;

/// Poses of each set the text lists, the worst first.
pub const WORST: usize = 5;

/// `set` with its joint values in the files' units: degrees (mm for prismatic joints).
pub fn in_degrees(set: &SetEvaluation, joints: &[Joint]) -> SetEvaluation {
    let mut out = set.clone();
    for pose in &mut out.poses {
        for (v, joint) in pose.joints.iter_mut().zip(joints) {
            if joint.kind == JointKind::Revolute {
                *v = v.to_degrees();
            }
        }
    }
    out
}

/// One row of an error table: label, count, mean, RMS, max, RMS per axis.
fn row(out: &mut String, width: usize, label: &str, s: &ErrorStats) {
    let _ = writeln!(
        out,
        "{label:<width$} {:>6} {:>9.4} {:>9.4} {:>9.4} {:>9.4} {:>9.4} {:>9.4}",
        s.count, s.mean, s.rms, s.max, s.rms_axis[0], s.rms_axis[1], s.rms_axis[2]
    );
}

/// The header of an error table titled `title`.
fn header(out: &mut String, width: usize, title: &str) {
    let _ = writeln!(
        out,
        "{title:<width$} {:>6} {:>9} {:>9} {:>9} {:>9} {:>9} {:>9}",
        "count", "mean", "rms", "max", "rms x", "rms y", "rms z"
    );
}

/// The pooled errors of each set at each stage (`training, before`), then any `extra` rows
/// (`(label, stats)`, such as k-fold cross-validation).
pub fn pooled_table(sets: &[&SetEvaluation], extra: &[(String, ErrorStats)]) -> String {
    let labels: Vec<(String, &ErrorStats)> = sets
        .iter()
        .flat_map(|set| {
            set.stages.iter().zip(&set.pooled).map(move |(stage, s)| (format!("{}, {stage}", set.name), s))
        })
        .chain(extra.iter().map(|(l, s)| (l.clone(), s)))
        .collect();
    let (mut out, width) = table("marker position errors (mm)", &labels);
    let probes: Vec<&&SetEvaluation> = sets.iter().filter(|s| s.orientation.is_some()).collect();
    if !probes.is_empty() {
        let title = "orientation errors (deg)";
        let _ = writeln!(out);
        header(&mut out, width, title);
        for set in probes {
            for (stage, s) in set.stages.iter().zip(set.orientation.iter().flatten()) {
                row(&mut out, width, &format!("{}, {stage}", set.name), s);
            }
        }
    }
    out
}

/// The errors of each marker of each set at each stage (`training, marker 2, after`).
pub fn per_marker_table(sets: &[&SetEvaluation]) -> String {
    let labels: Vec<(String, &ErrorStats)> = sets
        .iter()
        .flat_map(|set| {
            set.marker_ids.iter().zip(&set.per_marker).flat_map(move |(id, stats)| {
                set.stages
                    .iter()
                    .zip(stats)
                    .map(move |(stage, s)| (format!("{}, marker {id}, {stage}", set.name), s))
            })
        })
        .collect();
    table("per marker (mm)", &labels).0
}

/// An error table titled `title` with a row per `(label, stats)`, and its label width.
fn table(title: &str, labels: &[(String, &ErrorStats)]) -> (String, usize) {
    let width = labels.iter().map(|(l, _)| l.len()).chain([title.len()]).max().unwrap_or(0);
    let mut out = String::new();
    header(&mut out, width, title);
    for (label, s) in labels {
        row(&mut out, width, label, s);
    }
    (out, width)
}

/// The [`WORST`] poses of `set` with the largest marker error at the last stage, the worst
/// first: `(pose, marker)`, the marker the pose's largest error.
pub fn worst(set: &SetEvaluation) -> Vec<(usize, usize)> {
    let last = set.stages.len().saturating_sub(1);
    let mut ranked: Vec<(usize, usize, f64)> = set
        .poses
        .iter()
        .enumerate()
        .map(|(k, p)| {
            let (m, d) = (0..set.marker_ids.len())
                .map(|m| (m, p.distance(last, m)))
                .fold((0, f64::NEG_INFINITY), |a, b| if b.1 > a.1 { b } else { a });
            (k, m, d)
        })
        .collect();
    ranked.sort_by(|a, b| b.2.total_cmp(&a.2).then(a.0.cmp(&b.0)));
    ranked.into_iter().take(WORST).map(|(k, m, _)| (k, m)).collect()
}

/// The [`WORST`] poses of each set with the largest marker error at the last stage: line,
/// marker, the error at each stage, the whitened residual and the flag.
pub fn worst_poses(sets: &[&SetEvaluation]) -> String {
    let Some(first) = sets.iter().find(|s| !s.poses.is_empty()) else { return String::new() };
    let width = sets.iter().map(|s| s.name.len()).chain([3]).max().unwrap_or(3);
    let mut out = String::new();
    let _ = write!(out, "{:<width$} {:>6} {:>6}", "set", "line", "marker");
    for stage in &first.stages {
        let _ = write!(out, " {:>9}", format!("{stage} mm"));
    }
    let _ = writeln!(out, " {:>9} {:>6}  flagged", "whitened", "worst");
    for set in sets {
        for (k, m) in worst(set) {
            let p = &set.poses[k];
            let _ = write!(out, "{:<width$} {:>6} {:>6}", set.name, p.line, set.marker_ids[m]);
            for s in 0..set.stages.len() {
                let _ = write!(out, " {:>9.4}", p.distance(s, m));
            }
            let _ = writeln!(
                out,
                " {:>9.2} {:>6.2}  {}",
                p.whitened,
                p.worst,
                if p.flagged { "yes" } else { "no" }
            );
        }
    }
    out
}

/// Every pose of every set (joint values already in degrees, [`in_degrees`]) as CSV, one row
/// per pose and marker: the set, the file line, the
/// joint values (`<joint>_deg`, `<joint>_mm` for prismatic joints), the marker, its error at
/// each stage (norm and x, y, z, mm; and for a probe the orientation error, deg: the angle and
/// the rotation vector's x, y, z), the pose's
/// whitened residual, its largest whitened component and whether it is flagged.
pub fn poses_csv(sets: &[&SetEvaluation], joints: &[Joint]) -> String {
    let mut out = String::new();
    let mut head: Vec<String> = vec!["set".into(), "line".into()];
    head.extend(joints.iter().map(|j| match j.kind {
        JointKind::Revolute => format!("{}_deg", j.name),
        JointKind::Prismatic => format!("{}_mm", j.name),
    }));
    head.push("marker".into());
    let Some(first) = sets.first() else { return head.join(",") + "\n" };
    let probe = sets.iter().any(|s| s.orientation.is_some());
    for stage in &first.stages {
        for part in ["mm", "x_mm", "y_mm", "z_mm"] {
            head.push(format!("{stage}_{part}"));
        }
        if probe {
            for part in ["orientation_deg", "rx_deg", "ry_deg", "rz_deg"] {
                head.push(format!("{stage}_{part}"));
            }
        }
    }
    head.extend(["whitened", "worst_sd", "flagged"].map(String::from));
    let _ = writeln!(out, "{}", head.join(","));
    for set in sets {
        for p in &set.poses {
            for (m, id) in set.marker_ids.iter().enumerate() {
                let mut cells: Vec<String> = vec![csv_cell(&set.name), p.line.to_string()];
                cells.extend(p.joints.iter().map(|v| format!("{v}")));
                cells.push(id.to_string());
                for s in 0..set.stages.len() {
                    let e = p.errors[s][m];
                    cells.push(format!("{}", p.distance(s, m)));
                    cells.extend(e.iter().map(|v| format!("{v}")));
                    if probe {
                        let turn = p.orientation.as_ref().map_or([0.0; 3], |o| o[s]);
                        cells.push(format!("{}", nalgebra::Vector3::from(turn).norm()));
                        cells.extend(turn.iter().map(|v| format!("{v}")));
                    }
                }
                cells.push(format!("{}", p.whitened));
                cells.push(format!("{}", p.worst));
                cells.push(p.flagged.to_string());
                let _ = writeln!(out, "{}", cells.join(","));
            }
        }
    }
    out
}

/// A CSV cell, quoted if it holds a comma or a quote.
pub(crate) fn csv_cell(text: &str) -> String {
    if text.contains([',', '"', '\n']) {
        format!("\"{}\"", text.replace('"', "\"\""))
    } else {
        text.to_string()
    }
}
