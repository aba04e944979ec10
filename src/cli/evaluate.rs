//! `robocal evaluate`: a model scored as it stands on measurement files of any kind, through
//! the one observation pipeline ([`KindOptions::as_it_stands`]): marker files with the model's
//! base and markers, other files with their set-up fitted; the robot held in both. A tree (a
//! URDF with `--tips`, or the branches `calibrate --out-dir` wrote) is scored on its views the
//! same way ([`evaluate_tree`]: each file's cameras and targets fitted), into the same report.

use super::observations::{Noise, marker_ids_known, named_markers};
use super::request::{EvaluateRequest, NoiseSource};
use anyhow::{Context, Result, bail};
use nalgebra::Vector3;
use robocal::calibration::DataKind;
use robocal::calibration::kinds::{KindData, KindOptions, RowSigmaDefaults, Score, evaluate_kinds};
use robocal::calibration::tree::{TreeData, evaluate_tree};
use robocal::io;
use robocal::model::{RobotModel, RobotTree};
use robocal::report::residuals::ResidualSet;
use serde::Serialize;
use std::path::Path;

/// What `evaluate` reports: the model and each file scored.
#[derive(Serialize)]
struct EvaluationReport {
    /// The model's name.
    model: String,
    /// A tree's branches (their tip links) and joints, in the order of the view files' columns.
    #[serde(skip_serializing_if = "Option::is_none", flatten)]
    tree: Option<TreeNames>,
    /// Each file, its name and its score (of a tree's: its views, their `after`; `before` the
    /// same).
    observations: Vec<(String, Score)>,
}

/// A tree's branches and joints, by name ([`EvaluationReport::tree`]).
#[derive(Serialize)]
struct TreeNames {
    /// Its branches' tip links.
    branches: Vec<String>,
    /// Its joints.
    joints: Vec<String>,
}

/// Score the model on every file, print the table, write the files asked for.
pub fn run(request: &EvaluateRequest) -> Result<()> {
    let kinds = (request.data.iter()).map(|path| io::data_kind(path)).collect::<Result<Vec<_>, _>>()?;
    if !request.tips.is_empty() || request.branches.is_some() || kinds.contains(&DataKind::TreeViews) {
        return run_tree(request, &kinds);
    }
    let model = io::load_model(&request.model)?;
    let markers = model_markers(request)?;
    let noise = observation_noise(request, &model)?;
    let read = |path: &std::path::PathBuf| {
        super::observations::read(path, &model, request.units, noise.sigmas, noise.device.as_ref())
    };
    let files =
        (request.data.iter()).map(|path| Ok((path.as_path(), read(path)?))).collect::<Result<Vec<_>>>()?;
    let observed = (chosen_markers(files, request.marker_ids.as_deref())?.into_iter())
        .map(|(path, data)| scored(path, data, &model, &markers, noise.joint.clone()))
        .collect::<Result<Vec<_>>>()?;
    let observations: Vec<(String, Score)> =
        observed.iter().map(|(name, _, score)| (name.clone(), score.clone())).collect();
    let text = robocal::report::observations::as_it_stands_text(&model.name, &observations, false);
    super::show_report(&text, &super::report_outputs(&request.report));
    let report = EvaluationReport { model: model.name.clone(), tree: None, observations };
    let json = super::json_if_asked(&request.report, &report)?;
    let title = format!("{} scored as it stands", model.name);
    let mut outputs = io::Outputs::new();
    write_observation_files(request, &model, &observed, json, &title, &text, &mut outputs)?;
    super::commit(outputs)
}

/// The markers of the model file (numbered from 1, mm in the last joint frame): a TOML model's
/// `[[markers]]`, a URDF's marker links; none for a built-in model.
fn model_markers(request: &EvaluateRequest) -> Result<Vec<(usize, Vector3<f64>)>> {
    let path = Path::new(&request.model.name);
    Ok(if request.model.is_urdf() {
        robocal::model::markers_from_urdf_str(&read(path)?).with_context(|| path.display().to_string())?
    } else if path.exists() {
        robocal::model::markers_from_toml_str(&read(path)?).with_context(|| path.display().to_string())?
    } else {
        Vec::new()
    })
}

/// The files with the markers `--markers` names only ([`named_markers`]); a number that no
/// file's marker has is refused.
fn chosen_markers<'a>(
    files: Vec<(&'a Path, KindData)>,
    ids: Option<&[usize]>,
) -> Result<Vec<(&'a Path, KindData)>> {
    if let Some(ids) = ids {
        let have: std::collections::BTreeSet<usize> = files.iter().flat_map(|(_, d)| d.markers()).collect();
        marker_ids_known(ids, &have.into_iter().collect::<Vec<_>>())?;
    }
    named_markers(files, ids)
}

/// A file's data scored as it stands ([`KindOptions::as_it_stands`]: a marker file with the
/// model's base and `markers`, any other with its set-up fitted; the robot and its tool point
/// held), whitened under its sigma column (or `--sigma-mm`'s, a noise file's `sigma_me_mm`
/// and device for rows without) and the joint noise `joint`: its name, its observations and
/// their residuals.
fn scored(
    path: &Path,
    data: KindData,
    model: &RobotModel,
    markers: &[(usize, Vector3<f64>)],
    joint: Option<nalgebra::DMatrix<f64>>,
) -> Result<(String, KindData, Score)> {
    let options =
        KindOptions::as_it_stands(model, markers, &data).with_context(|| path.display().to_string())?;
    let options = KindOptions { joint_noise: joint, ..options };
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
        page: &|figures, sets| robocal::report::html::page(title, text, sets, figures),
        sets,
        joints: &model.joints,
        model: Some(model),
        prior_scale: None,
        selection: None,
    };
    super::write_residual_files(&request.report, content, outputs)
}

/// A file's text.
fn read(path: &Path) -> Result<String> {
    std::fs::read_to_string(path).with_context(|| format!("{}: cannot read", path.display()))
}

/// Score the tree on every view file, print the table, write the files asked for.
fn run_tree(request: &EvaluateRequest, kinds: &[DataKind]) -> Result<()> {
    if let Some((path, _)) = request.data.iter().zip(kinds).find(|(_, k)| **k != DataKind::TreeViews) {
        bail!(
            "{}: not a file of views between a tree's branches (camera, target columns): a tree is scored on its views",
            path.display()
        );
    }
    let tree = load_tree(request)?;
    let files = (request.data.iter())
        .map(|path| {
            let data = TreeData::from_csv_str(&read(path)?, &tree, request.units)
                .with_context(|| path.display().to_string())?;
            Ok((path.display().to_string(), data))
        })
        .collect::<Result<Vec<_>>>()?;
    let joint_noise = observation_joint_noise(request, (&tree.name, &tree.joints))?;
    let options = KindOptions { joint_noise, ..KindOptions::default() };
    let views = (files.iter())
        .map(|(name, data)| {
            let score = evaluate_tree(&tree, data, &options).with_context(|| name.clone())?;
            Ok((name.clone(), score))
        })
        .collect::<Result<Vec<_>>>()?;
    let text = robocal::report::observations::as_it_stands_text(&tree.name, &views, true);
    super::show_report(&text, &super::report_outputs(&request.report));
    let report = EvaluationReport {
        model: tree.name.clone(),
        tree: Some(TreeNames {
            branches: tree.branches.iter().map(|b| b.tip.clone()).collect(),
            joints: tree.joints.iter().map(|j| j.name.clone()).collect(),
        }),
        observations: views,
    };
    let sets = (files.iter().zip(&report.observations))
        .map(|((name, data), (_, score))| {
            let set = ResidualSet::of_views(name, score, &[(name.as_str(), data)], &tree.joints);
            Ok(set.map_err(anyhow::Error::msg)?.at_one_stage("as it stands"))
        })
        .collect::<Result<Vec<_>>>()?;
    let title = format!("{} scored as it stands", tree.name);
    let content = super::ResidualContent {
        json: super::json_if_asked(&request.report, &report)?,
        page: &|figures, sets| robocal::report::html::page(&title, &text, sets, figures),
        sets,
        joints: &tree.joints,
        model: None,
        prior_scale: None,
        selection: None,
    };
    let mut outputs = io::Outputs::new();
    super::write_residual_files(&request.report, content, &mut outputs)?;
    super::commit(outputs)
}

/// The tree of `--model` and `--tips`, its joints those of the branches in `--branches` if
/// given ([`io::load_branches`]).
fn load_tree(request: &EvaluateRequest) -> Result<RobotTree> {
    let name = request.model.name.as_str();
    let tree = RobotTree::from_urdf_str(&read(Path::new(name))?, request.tree_root.as_deref(), &request.tips)
        .with_context(|| name.to_string())?;
    match &request.branches {
        Some(folder) => Ok(io::load_branches(&tree, folder)?),
        None => Ok(tree),
    }
}

/// The joint noise `--joint-sigma-deg` gives for scoring view files (of the tree `name` with
/// `joints`); `--noise`, `--sigma-mm` and `--sigma-orientation-deg` refused: a view file's sigma
/// columns are its measurement noise.
fn observation_joint_noise(
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
