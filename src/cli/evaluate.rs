//! `robocal evaluate`: a model scored as it stands on measurement files, with the tables of
//! `calibrate` (pooled, per marker, worst poses) and its files (JSON, poses, figures, page).

use super::calibrate::noise_for;
use super::request::EvaluateRequest;
use super::{ReportContent, write_report_files};
use anyhow::{Context, Result};
use robocal::calibration::{SetEvaluation, evaluate_model, pool};
use robocal::io;
use robocal::report::poses::{in_degrees, per_marker_table, pooled_table, worst_poses};
use serde::Serialize;
use std::fmt::Write;
use std::path::Path;

/// What `evaluate` reports: the model, each file scored, and the files pooled.
#[derive(Serialize)]
struct EvaluationReport {
    /// The model's name.
    model: String,
    /// Each file, pose by pose (joint values in degrees, mm for prismatic joints).
    sets: Vec<SetEvaluation>,
    /// With several files, all their poses pooled (summaries only).
    #[serde(skip_serializing_if = "Option::is_none")]
    pooled: Option<SetEvaluation>,
}

/// Score the model on every file, print the tables, write the files asked for.
pub fn run(request: &EvaluateRequest) -> Result<()> {
    let model = io::load_model(&request.model)?;
    let path = Path::new(&request.model.name);
    let markers = if request.model.is_urdf() {
        robocal::model::markers_from_urdf_str(&read(path)?).with_context(|| path.display().to_string())?
    } else if path.exists() {
        robocal::model::markers_from_toml_str(&read(path)?).with_context(|| path.display().to_string())?
    } else {
        Vec::new()
    };
    let mut sets = Vec::new();
    for path in &request.data {
        let mut data = io::load_measurements(path, &model, request.units)?;
        if let Some(ids) = &request.marker_ids {
            data = data.with_markers(ids).with_context(|| {
                format!("{}: none of the markers {ids:?} (it has {:?})", path.display(), data.marker_ids)
            })?;
        }
        let noise = noise_for(request.noise.as_ref(), &model, &data)?;
        let name = path.display().to_string();
        let set = evaluate_model(&model, &markers, &name, &data, noise.as_ref())
            .with_context(|| path.display().to_string())?;
        sets.push(in_degrees(&set, &model.joints));
    }
    let refs: Vec<&SetEvaluation> = sets.iter().collect();
    let pooled = if sets.len() > 1 { pool("all files, pooled", &refs) } else { None };
    let mut text = String::new();
    let _ = writeln!(
        text,
        "{} scored as it stands on {} file{}: no registration, no fit",
        model.name,
        sets.len(),
        if sets.len() == 1 { "" } else { "s" }
    );
    let _ = writeln!(
        text,
        "errors:    distances and their x, y, z components, unweighted\nwhitened:  {}\n",
        sets[0].whitening
    );
    let mut tables: Vec<&SetEvaluation> = refs.clone();
    tables.extend(&pooled);
    text.push_str(&pooled_table(&tables, &[]));
    if sets.iter().any(|s| s.marker_ids.len() > 1) {
        let _ = writeln!(text);
        text.push_str(&per_marker_table(&tables));
    }
    let _ = writeln!(
        text,
        "\nworst poses ({} per file; every pose in --poses-csv, --json, --html):",
        robocal::report::poses::WORST
    );
    text.push_str(&worst_poses(&refs));
    print!("{text}");
    let report = EvaluationReport { model: model.name.clone(), sets, pooled };
    let json = serde_json::to_string_pretty(&report)? + "\n";
    let title = format!("{} scored as it stands", model.name);
    let mut outputs = io::Outputs::new();
    let content = ReportContent {
        title: &title,
        text: &text,
        json: &json,
        sets: &report.sets,
        joints: &model.joints,
        extra_figures: Vec::new(),
    };
    write_report_files(&request.report, content, &mut outputs)?;
    super::commit(outputs)
}

/// A file's text.
fn read(path: &Path) -> Result<String> {
    std::fs::read_to_string(path).with_context(|| format!("{}: cannot read", path.display()))
}
