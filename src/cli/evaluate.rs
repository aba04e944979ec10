//! `robocal evaluate`: a model scored as it stands on measurement files, with the tables of
//! `calibrate` (pooled, per marker, worst poses) and its files (JSON, poses, figures, page).

use super::observations::Noise;
use super::request::{EvaluateRequest, NoiseSource};
use super::{ReportContent, noise_model, write_report_files};
use anyhow::{Context, Result, bail};
use robocal::calibration::kinds::{KindData, KindOptions, RowSigmaDefaults, Score, evaluate_kinds};
use robocal::calibration::{self, DataKind, Measurements, SetEvaluation, evaluate_model, pool};
use robocal::estimation::NoiseModel;
use robocal::io;
use robocal::model::RobotModel;
use robocal::report::poses::{in_degrees, per_marker_table, pooled_table, worst_poses};
use robocal::report::residuals::ResidualSet;
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
    /// The files of other kinds, each scored with its set-up fitted, the robot held.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    observations: Vec<(String, Score)>,
}

/// Score the model on every file, print the tables, write the files asked for.
pub fn run(request: &EvaluateRequest) -> Result<()> {
    let kinds = (request.data.iter()).map(|path| io::data_kind(path)).collect::<Result<Vec<_>, _>>()?;
    if !request.tips.is_empty() || request.branches.is_some() || kinds.contains(&DataKind::TreeViews) {
        return super::evaluate_tree::run(request, &kinds);
    }
    let model = io::load_model(&request.model)?;
    let path = Path::new(&request.model.name);
    let markers = if request.model.is_urdf() {
        robocal::model::markers_from_urdf_str(&read(path)?).with_context(|| path.display().to_string())?
    } else if path.exists() {
        robocal::model::markers_from_toml_str(&read(path)?).with_context(|| path.display().to_string())?
    } else {
        Vec::new()
    };
    // Marker files are scored as they are; any other kind with its set-up fitted.
    let (marker_files, others): (Vec<&std::path::PathBuf>, Vec<&std::path::PathBuf>) =
        request.data.iter().partition(|p| read(p).is_ok_and(|t| is_marker_file(&t)));
    let observed =
        others.iter().map(|path| observation_file(path, &model, request)).collect::<Result<Vec<_>>>()?;
    let observations: Vec<(String, Score)> =
        observed.iter().map(|(name, _, score)| (name.clone(), score.clone())).collect();
    let mut sets = Vec::new();
    for path in marker_files {
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
    if !observations.is_empty() {
        text.push_str(&observations_text(&model.name, &observations));
    }
    if !sets.is_empty() {
        text.push_str(&markers_text(&model.name, &sets, pooled.as_ref()));
    }
    super::show_report(&text, &super::report_outputs(&request.report));
    let report = EvaluationReport { model: model.name.clone(), sets, pooled, observations };
    let json = super::json_if_asked(&request.report, &report)?;
    let title = format!("{} scored as it stands", model.name);
    let mut outputs = io::Outputs::new();
    if report.sets.is_empty() {
        write_observation_files(request, &model, &observed, json, &title, &text, &mut outputs)?;
        return super::commit(outputs);
    }
    if !observed.is_empty() && request.report.wants_files() {
        bail!(
            "--poses-csv, --figures and --html: marker files and observation files have files of their own; \
             evaluate them in two runs"
        );
    }
    let extra_figures = if request.report.figures.is_some() || request.report.html.is_some() {
        robocal::report::figures::torque_figures(&report.sets.iter().collect::<Vec<_>>(), &model)?
    } else {
        Vec::new()
    };
    let content = ReportContent {
        title: &title,
        text: &text,
        json,
        sets: &report.sets,
        joints: &model.joints,
        extra_figures,
        calibration: None,
    };
    write_report_files(&request.report, content, &mut outputs)?;
    super::commit(outputs)
}

/// An observation file read and scored as it stands, its set-up fitted, the model held, its
/// whitened residuals under its sigma column (or `--sigma-mm`'s, a noise file's `sigma_me_mm`
/// and device for rows without) and the joint noise: its name, its observations and their
/// residuals.
fn observation_file(
    path: &Path,
    model: &robocal::model::RobotModel,
    request: &EvaluateRequest,
) -> Result<(String, KindData, Score)> {
    let noise = observation_noise(request, model)?;
    let data = super::observations::read(path, model, request.units, noise.sigmas, noise.device.as_ref())?;
    let tool = model.tool_point_in_marker_frame();
    let options = KindOptions { tool, joint_noise: noise.joint, ..KindOptions::default() };
    let score = evaluate_kinds(model, &data, &options).with_context(|| path.display().to_string())?;
    Ok((path.display().to_string(), data, score))
}

/// The noise of observation files as `calibrate` reads it ([`Noise::of`]): a noise file's, or
/// the flags' (`--joint-sigma-deg`, and `--sigma-mm` and `--sigma-orientation-deg` for rows
/// without their own sigma).
fn observation_noise(request: &EvaluateRequest, model: &robocal::model::RobotModel) -> Result<Noise> {
    match &request.noise {
        None => Noise::of(None, None, RowSigmaDefaults::default(), model),
        Some(NoiseSource::Flags(flags)) => {
            let angle = flags.sigma_orientation_deg.to_radians();
            let sigmas = RowSigmaDefaults::positive(Some(flags.sigma_mm), Some(angle));
            Noise::of(None, Some(&flags.joint_sigma_deg), sigmas, model)
        }
        Some(NoiseSource::File(path)) => Noise::of(Some(path), None, RowSigmaDefaults::default(), model),
    }
}

/// The joint noise `--joint-sigma-deg` gives for scoring view files (of the tree `name` with
/// `joints`); `--noise`, `--sigma-mm` and `--sigma-orientation-deg` refused: a view file's sigma
/// columns are its measurement noise.
pub(super) fn observation_joint_noise(
    request: &EvaluateRequest,
    (name, joints): (&str, &[robocal::model::Joint]),
) -> Result<Option<nalgebra::DMatrix<f64>>> {
    match &request.noise {
        None => Ok(None),
        Some(NoiseSource::Flags(flags)) if flags.sigma_mm != 0.0 || flags.sigma_orientation_deg != 0.0 => {
            bail!(
                "--sigma-mm and --sigma-orientation-deg are not for view files: the sigma and sigma_angle columns \
                 give the measurement noise here, --joint-sigma-deg the joints'"
            )
        }
        Some(NoiseSource::Flags(flags)) => {
            super::joint_covariance(name, joints, Some(&flags.joint_sigma_deg))
        }
        Some(NoiseSource::File(_)) => bail!(
            "--noise is not for view files: the sigma and sigma_angle columns give the measurement noise here; \
             give the joint noise by --joint-sigma-deg"
        ),
    }
}

/// Stage the files `request` asks for of observation files scored as they stand: the JSON,
/// every observation's residual (`--poses-csv`), the residual figures and the page.
fn write_observation_files(
    request: &EvaluateRequest,
    model: &robocal::model::RobotModel,
    observed: &[(String, KindData, Score)],
    json: Option<String>,
    title: &str,
    text: &str,
    outputs: &mut io::Outputs,
) -> Result<()> {
    let sets = (observed.iter())
        .map(|(name, data, score)| {
            let set = ResidualSet::of_observations(name, score, &[(name.as_str(), data)], &model.joints);
            Ok(set.map_err(anyhow::Error::msg)?.at_one_stage("as it stands"))
        })
        .collect::<Result<Vec<_>>>()?;
    let content = super::ResidualContent {
        json,
        page: &|figures, sets| robocal::report::html::page(title, text, (&[], sets), figures),
        sets,
        joints: &model.joints,
        model: Some(model),
        prior_scale: None,
        selection: None,
    };
    super::write_residual_files(&request.report, content, outputs)
}

/// Whether `text` is a marker file scored pose by pose ([`DataKind::Markers`]: marker columns,
/// every cell measured); one with an empty marker cell is scored as observations.
fn is_marker_file(text: &str) -> bool {
    DataKind::of_csv_str(text).is_ok_and(|k| k == DataKind::Markers)
}

/// The residual table of the observation files, each scored with its set-up fitted and the
/// model held.
fn observations_text(model: &str, scores: &[(String, Score)]) -> String {
    let mut text = String::new();
    let width = scores.iter().map(|(n, _)| n.len() + 6).max().unwrap_or(0).max(24);
    let _ = writeln!(
        text,
        "{model} scored as it stands on {} observation file{}: each file's set-up (fixed points, planes, camera and target; with markers the base and the markers) fitted, the robot and its tool point held (calibrate --validate scores with the calibrated set-up instead: its figure can be larger)\n",
        scores.len(),
        if scores.len() == 1 { "" } else { "s" }
    );
    let _ = writeln!(text, "{:<width$} {:>10}", "residuals, RMS", "as it stands");
    for (name, score) in scores {
        let _ = writeln!(text, "{:<width$} {:>10.4}", format!("{name} (mm)"), score.lengths.1);
        if let Some((_, after)) = score.markers {
            let _ = writeln!(text, "{:<width$} {after:>10.4}", format!("{name} markers (mm)"));
        }
        if let Some((_, after)) = score.angles {
            let _ = writeln!(text, "{:<width$} {after:>10.5}", format!("{name} (deg)"));
        }
    }
    text
}

/// The tables of the marker files, scored as they stand.
fn markers_text(model: &str, sets: &[SetEvaluation], pooled: Option<&SetEvaluation>) -> String {
    let refs: Vec<&SetEvaluation> = sets.iter().collect();
    let mut text = String::new();
    let _ = writeln!(
        text,
        "{} scored as it stands on {} file{}: no registration, no fit",
        model,
        sets.len(),
        if sets.len() == 1 { "" } else { "s" }
    );
    let _ = writeln!(
        text,
        "errors:    distances and their x, y, z components, unweighted\nwhitened:  {}\n",
        sets[0].whitening
    );
    let mut tables: Vec<&SetEvaluation> = refs.clone();
    tables.extend(pooled);
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
    text
}

/// A file's text.
fn read(path: &Path) -> Result<String> {
    std::fs::read_to_string(path).with_context(|| format!("{}: cannot read", path.display()))
}

/// The noise of `source` at the poses of `data`: the flags' everywhere, a noise file's device
/// at each measured marker.
fn noise_for(
    source: Option<&NoiseSource>,
    model: &RobotModel,
    data: &Measurements,
) -> Result<Option<NoiseModel>> {
    Ok(match source {
        None => None,
        Some(NoiseSource::Flags(flags)) => Some(noise_model(model, flags)?),
        Some(NoiseSource::File(path)) => {
            let spec = io::load_noise(path, model)?;
            let noise = calibration::noise_from_spec(&spec, data)
                .with_context(|| format!("{}: the device's covariance", path.display()))?;
            Some(noise)
        }
    })
}
