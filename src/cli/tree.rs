//! `robocal calibrate-tree`: a robot of several chains (a torso with arms and a head camera)
//! calibrated in one fit from camera views between its branches
//! ([`robocal::calibration::tree`]); every file read and the fit made before anything is
//! written.

use super::request::CalibrateTreeRequest;
use anyhow::{Context, Result};
use robocal::calibration::Tree;
use robocal::calibration::kinds::KindOptions;
use robocal::calibration::kinds::Score;
use robocal::calibration::tree::TreeData;
use robocal::estimation::RefineOptions;
use robocal::io;
use robocal::model::{Joint, RobotModel, RobotTree};
use robocal::pipeline::TreeOutcome;
use robocal::report::residuals::ResidualSet;
use std::path::Path;

/// Calibrate, print the report, write the files asked for.
pub fn run(request: &CalibrateTreeRequest) -> Result<()> {
    let name = request.model.display().to_string();
    let text_of_model =
        std::fs::read_to_string(&request.model).with_context(|| format!("{name}: cannot read"))?;
    let tree = RobotTree::from_urdf_str(&text_of_model, request.base_link.as_deref(), &request.tips)
        .with_context(|| name)?;
    let mut sessions = Vec::with_capacity(request.data.len());
    for path in &request.data {
        let file = read(path, &tree, request)?;
        sessions.push((path.display().to_string(), file));
    }
    let held_out = (request.validate.iter())
        .map(|path| Ok((path.display().to_string(), read(path, &tree, request)?)))
        .collect::<Result<Vec<_>>>()?;
    let options = KindOptions {
        estimator: request.estimator,
        joint_noise: super::joint_covariance(&tree.name, &tree.joints, request.joint_sigma_deg.as_deref())?,
        joints: request.joints.clone(),
        refine: RefineOptions { max_iterations: request.iterations, ..RefineOptions::default() },
        gauge: request.gauge.clone(),
        prior: request.prior.clone(),
        loss: request.loss,
        per_session: request.per_session.clone(),
        ..KindOptions::default()
    };
    let choices =
        robocal::calibration::Choices::from_flags(request.auto_prior.clone(), request.select, request.folds);
    let fitting = robocal::pipeline::Fitting::new(request.feasible, choices, request.folds);
    let TreeOutcome { calibration: c, report } =
        robocal::pipeline::calibrate_files(&Tree(&tree), &sessions, &held_out, &options, &fitting)?;
    let text = report.text();
    super::show_report(&text, &super::report_outputs(&request.report));
    let mut outputs = io::Outputs::new();
    if request.report != super::args::ReportArgs::default() {
        let content = super::ResidualContent {
            json: super::json_if_asked(&request.report, &report)?,
            page: &|figures, sets| {
                report.page(&format!("Calibration of {}", report.model), &text, figures, sets)
            },
            sets: residual_sets(&report.sets, &sessions, &held_out, &tree.joints)?,
            joints: &tree.joints,
            model: None,
            prior_scale: report.prior_scale.as_ref(),
            selection: report.selection.as_ref(),
        };
        super::write_residual_files(&request.report, content, &mut outputs)?;
    }
    if let Some(folder) = &request.out_dir {
        let note = "calibrated by robocal calibrate from camera views between branches: right relative to the \
                    other branches; its placement in the root link's frame the views cannot see (held)";
        let mut files: Vec<(String, String)> = (c.calibrated.branches.iter())
            .map(|b| {
                let model = RobotModel { description: note.to_string(), ..b.model.clone() };
                (format!("{}.toml", b.tip), robocal::model::to_toml_with_markers(&model, &[]))
            })
            .collect();
        let frames = report.tree.as_ref().map_or(&[][..], |t| t.frames.as_slice());
        files.push(("frames.json".to_string(), serde_json::to_string_pretty(frames)? + "\n"));
        outputs.add_folder(folder, &files);
    }
    if let Some(path) = &request.out_urdf {
        outputs.add(path, robocal::model::tree_to_urdf_string(&text_of_model, &c.calibrated)?);
    }
    super::commit(outputs)
}

/// The residuals of each scored set (`scores`: the training files', then each held-out
/// file's, then any cross-validation's, each training view held out in its fold) with their
/// files.
fn residual_sets(
    scores: &[(String, Score)],
    sessions: &[(String, TreeData)],
    held_out: &[(String, TreeData)],
    joints: &[Joint],
) -> Result<Vec<ResidualSet>> {
    let training = || std::iter::once(super::by_name(sessions));
    // Each held-out file, the held-out files pooled when the report pools them, the folds.
    let pooled = scores.iter().any(|(name, _)| name == robocal::pipeline::HELD_OUT_POOLED);
    let pooled = pooled.then(|| super::by_name(held_out));
    let files = training().chain(held_out.chunks(1).map(super::by_name)).chain(pooled).chain(training());
    (files.zip(scores))
        .map(|(files, (name, score))| {
            ResidualSet::of_views(name, score, &files, joints).map_err(anyhow::Error::msg)
        })
        .collect()
}

/// One view file.
fn read(path: &Path, tree: &RobotTree, request: &CalibrateTreeRequest) -> Result<TreeData> {
    let text = std::fs::read_to_string(path).with_context(|| format!("{}: cannot read", path.display()))?;
    let data =
        TreeData::from_csv_str(&text, tree, request.units).with_context(|| path.display().to_string())?;
    Ok(data.named(&super::request::session_name(path)))
}
