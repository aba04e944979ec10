//! `robocal.calibrate_tree`: a robot of several chains (a URDF tree) calibrated from views
//! between its branches, as `robocal calibrate` calibrates view files
//! ([`robocal::pipeline::calibrate_files`]).

use crate::calibrate::{Calibration, Flags, Source, data_error, joint_sigmas, require, text_of, units_for};
use crate::errors::{self, Kind, Place};
use crate::model::Model;
use nalgebra::{DMatrix, DVector};
use pyo3::prelude::*;
use robocal::calibration::kinds::KindOptions;
use robocal::calibration::tree::TreeData;
use robocal::calibration::{CalibrationError, ParamWords, Tree};
use robocal::estimation::{Estimator, RefineOptions};
use robocal::model::RobotTree;
use robocal::table::Units;
use std::path::Path;

/// `Sigma_q` of the tree's joints (rad², mm²) from `sigmas` in `units` (the joint unit, the
/// length unit for prismatic joints): one per joint, or one for all.
fn joint_noise(tree: &RobotTree, sigmas: &[f64], units: Units) -> PyResult<DMatrix<f64>> {
    let sigmas = joint_sigmas((&tree.name, &tree.joints), sigmas, units)?;
    Ok(DMatrix::from_diagonal(&DVector::from_iterator(sigmas.len(), sigmas.iter().map(|s| s * s))))
}

/// Calibrate the tree of the URDF file `urdf` (from `base_link`, default its only root, to
/// the `tips`, default every leaf) from the views of `sources` fitted together, scoring
/// `validate`, as `robocal calibrate` does with view files. The flags are `calibrate`'s; a
/// tree takes ols, wls or fgls (the joint and view noise estimated from the residuals), its
/// joint parameters (not `all`), priors as standard deviations or a preset, a loss, held and
/// kept parameters, every selection, and `joint_sigma` one per joint or one for all.
#[pyfunction]
#[pyo3(signature = (urdf, tips, base_link, sources, validate, flags))]
pub fn calibrate_tree(
    py: Python<'_>,
    urdf: String,
    tips: Vec<String>,
    base_link: Option<String>,
    sources: Vec<Source>,
    validate: Vec<Source>,
    flags: Flags,
) -> PyResult<Calibration> {
    let request = flags.request()?;
    // fgls: ordinary least squares first, then the noise estimated from the residuals.
    let estimator =
        request.estimator.unwrap_or(if request.feasible { Estimator::Ols } else { Estimator::Wls });
    require(
        matches!(estimator, Estimator::Ols | Estimator::Wls),
        "estimator",
        "a tree takes ols, wls or fgls",
    )?;
    require(
        flags.params_words()? != ParamWords::All,
        "params",
        "all: the base is never estimated from views; give joints",
    )?;
    require(
        flags.per_session.is_empty() || sources.len() >= 2,
        "per_session",
        "one value per views file (each file a session): give two files or more",
    )?;
    let tree = read_tree(&urdf, base_link.as_deref(), &tips)?;
    let read = |s: &Source| -> PyResult<(String, TreeData)> {
        let data = TreeData::from_csv_str(&text_of(s)?, &tree, units_for(s, request.units))
            .map_err(|e| data_error(s, &e))?;
        let stem =
            Path::new(&s.0).file_stem().map_or_else(|| s.0.clone(), |n| n.to_string_lossy().into_owned());
        Ok((s.0.clone(), data.named(&stem)))
    };
    let sessions = sources.iter().map(read).collect::<PyResult<Vec<_>>>()?;
    let held_out = validate.iter().map(read).collect::<PyResult<Vec<_>>>()?;
    let joint_noise = match &flags.joint_sigma {
        Some(sigmas) => Some(joint_noise(&tree, sigmas, request.noise_units)?),
        None => None,
    };
    let options = KindOptions {
        estimator,
        joint_noise,
        joints: request.joints.clone(),
        refine: RefineOptions { max_iterations: flags.iterations, ..RefineOptions::default() },
        gauge: robocal::calibration::Gauge { hold: flags.hold.clone(), keep: flags.keep.clone() },
        prior: request.prior.clone(),
        loss: request.loss,
        per_session: flags.per_session.clone(),
        ..KindOptions::default()
    };
    let choices =
        robocal::calibration::Choices::from_flags(request.auto_prior.clone(), request.select, flags.folds);
    let fitting = robocal::pipeline::Fitting::new(request.feasible, choices, flags.folds);
    let outcome = py
        .detach(|| robocal::pipeline::calibrate_files(&Tree(&tree), &sessions, &held_out, &options, &fitting))
        .map_err(|e| match e.source {
            CalibrationError::Selection(_) | CalibrationError::Prior(_) => {
                errors::calibration(&e.source, &e.context)
            }
            _ => errors::from_error(Kind::Estimation, &e, None),
        })?;
    let (c, report) = (outcome.calibration, outcome.report);
    let branches =
        (c.calibrated.branches.iter()).map(|b| (b.tip.clone(), Model::new(b.model.clone(), None))).collect();
    let estimate = &c.refined.estimate;
    Calibration::new(py, &report, estimate, estimate.diagnostics.rank, Vec::new(), None, branches)
}

/// The tree of the URDF file `urdf` (from `base_link` to the `tips`) scored as it stands on the
/// views of `source`, as `robocal evaluate --model tree.urdf --tips ...` scores a file: its
/// cameras and targets fitted to it, the tree held, whitened by the views' sigmas and
/// `joint_sigma`; its joints those of the branch models in `branches` if given (as
/// `--branches`: the `<tip>.toml` that `calibrate --out-dir` wrote). The score as JSON
/// (`views`, `view_position`, `view_rotation` and every row, as `Score`).
#[pyfunction]
#[pyo3(signature = (urdf, tips, base_link, branches, source, flags))]
pub fn evaluate_tree(
    py: Python<'_>,
    urdf: String,
    tips: Vec<String>,
    base_link: Option<String>,
    branches: Option<String>,
    source: Source,
    flags: Flags,
) -> PyResult<String> {
    let request = flags.request()?;
    require(
        flags.noise.is_none() && !flags.measurement_sigmas(),
        "noise",
        "views: their sigma columns are the measurement noise; give joint_sigma only",
    )?;
    let tree = read_tree(&urdf, base_link.as_deref(), &tips)?;
    let tree = match branches {
        Some(folder) => robocal::io::load_branches(&tree, std::path::Path::new(&folder))
            .map_err(|e| errors::from_error(errors::Kind::Input, &e, None))?,
        None => tree,
    };
    let data = TreeData::from_csv_str(&text_of(&source)?, &tree, units_for(&source, request.units))
        .map_err(|e| data_error(&source, &e))?;
    let joint_noise = match &flags.joint_sigma {
        Some(sigmas) => Some(joint_noise(&tree, sigmas, request.noise_units)?),
        None => None,
    };
    let options = KindOptions { joint_noise, ..KindOptions::default() };
    let score = py
        .detach(|| robocal::calibration::tree::evaluate_tree(&tree, &data, &options))
        .map_err(|e| errors::calibration(&e, &source.0))?;
    Ok(serde_json::to_string(&score).expect("a score serialises"))
}

/// The tree of the URDF file `urdf`, from `base_link` to `tips`; an input error naming the file.
fn read_tree(urdf: &str, base_link: Option<&str>, tips: &[String]) -> PyResult<RobotTree> {
    let text = std::fs::read_to_string(urdf).map_err(|e| {
        let place = Place { file: Some(urdf.to_string()), ..Place::default() };
        errors::raise(Kind::Input, format!("{urdf}: cannot read: {e}"), place)
    })?;
    RobotTree::from_urdf_str(&text, base_link, tips)
        .map_err(|e| errors::from_error(Kind::Input, &e, Some(urdf)))
}
