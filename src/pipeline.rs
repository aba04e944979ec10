//! The calibrations as one library call each: what `robocal calibrate` does between reading
//! its inputs and writing its outputs, for the command line and the Python package alike, so
//! that neither keeps a copy. Of marker data ([`calibrate_markers`]): the choices made from
//! the data, the calibration, the held-out sets scored, the cross-validation, the accuracy
//! predicted at the held-out poses, the report. Of observation files
//! ([`calibrate_observations`]) and of views on a tree ([`calibrate_views`]): the sessions
//! joined, the calibration (with `--select`'s choice for observations), the held-out sets
//! scored, the (nested) cross-validation, the report. Above every other
//! module: it joins the calibration, the design's accuracy prediction and the report.

use crate::calibration::kinds::{KindCalibration, KindData, KindOptions, Score, calibrate_kinds_feasible};
use crate::calibration::tree::{TreeCalibration, TreeData, TreeOptions, TreeScore, calibrate_tree_feasible};
use crate::calibration::{
    self, Calibration, CalibrationError, Choices, ChosenFit, ErrorStats, FeasibleOptions, Kinds, Loss,
    Markers, Measurements, Options, SetEvaluation, Tree, calibrate_chosen, cross_validate_choices,
};
use crate::design::accuracy::{AccuracyModel, CovarianceError, ParameterCovariance};
use crate::estimation::NoiseModel;
use crate::model::{RobotModel, RobotTree};
use crate::report::calibration::{CalibrationReport, CrossValidationReport, PredictedAccuracy, fold_label};
use crate::report::observations::ObservationsReport;
use crate::report::tree::TreeReport;

/// A calibration of marker data as `robocal calibrate` asks for it.
#[derive(Debug, Clone, Default)]
pub struct MarkerRequest {
    /// The data's name in the report (its file).
    pub data: String,
    /// The options before any choice is made from the data.
    pub options: Options,
    /// The choices made from the data (`--prior auto`, `--select`).
    pub choices: Choices,
    /// Feasible GLS (`--estimator fgls`): the noise estimated from the residuals, the
    /// held-out sets scored with it.
    pub feasible: bool,
    /// The held-out sets: name, data, and the noise at their poses (unused with `feasible`
    /// when the noise was estimated).
    pub held_out: Vec<(String, Measurements, Option<NoiseModel>)>,
    /// `--folds k`: the k-fold cross-validation of the training poses.
    pub folds: Option<usize>,
}

/// Why a calibration of marker data failed, by the step that failed.
#[derive(Debug, thiserror::Error)]
pub enum MarkerError {
    /// Making the choices from the data ([`calibration::choose`]).
    #[error(transparent)]
    Choice(CalibrationError),
    /// The calibration itself.
    #[error(transparent)]
    Calibration(CalibrationError),
    /// Scoring a held-out set.
    #[error(transparent)]
    Validation(CalibrationError),
    /// The cross-validation.
    #[error(transparent)]
    CrossValidation(CalibrationError),
    /// The accuracy predicted from the parameter covariance.
    #[error(transparent)]
    Accuracy(#[from] CovarianceError),
}

/// A finished calibration of marker data and its report (the command line's).
#[derive(Debug, Clone)]
pub struct MarkerOutcome {
    /// The calibration, of the chosen options.
    pub calibration: Calibration,
    /// The report: the sets scored, the cross-validation, the choices, the accuracy predicted.
    pub report: CalibrationReport,
}

/// The choices of `choices` as the command line's flags: `--prior auto:fabricated's scale`,
/// `--select bic`.
pub fn choices_in_words(choices: &Choices) -> Vec<String> {
    let auto = choices.auto_prior.iter().map(|(a, _)| format!("--prior {}'s scale", a.label()));
    auto.chain(choices.select.map(|c| format!("--select {}", c.name()))).collect()
}

/// Calibrate `model` on `fit` as `request` asks: make its choices on `fit`
/// ([`calibration::choose`]), calibrate with the chosen options (by feasible GLS if asked),
/// score each held-out set pose by pose, cross-validate (nested when a choice is made from
/// the data or the loss is robust), predict the position error at the held-out poses from the
/// parameter covariance `C` (`sigma_p^2 = tr(J_p C J_p^T) + floor^2`, the floor the first
/// held-out set's rms after calibration), and report.
pub fn calibrate_markers(
    model: &RobotModel,
    fit: &Measurements,
    request: &MarkerRequest,
) -> Result<MarkerOutcome, MarkerError> {
    let chosen = calibration::choose(&Markers(model), fit, &request.options, &request.choices)
        .map_err(MarkerError::Choice)?;
    let result = if request.feasible {
        calibration::calibrate_feasible(model, fit, &chosen.options, &FeasibleOptions::default())
    } else {
        calibration::calibrate(model, fit, &chosen.options)
    }
    .map_err(MarkerError::Calibration)?;
    let estimated = result.noise_estimate.as_ref().filter(|_| request.feasible).map(|e| e.noise_model());
    let sets = (request.held_out.iter())
        .map(|(name, d, noise)| result.evaluate(name, d, estimated.as_ref().or(noise.as_ref())))
        .collect::<Result<Vec<_>, _>>()
        .map_err(MarkerError::Validation)?;
    let cv = match request.folds {
        Some(k) => Some(cross_validate(model, fit, request, k).map_err(MarkerError::CrossValidation)?),
        None => None,
    };
    let folds = cv.as_ref().map(|(before, after, how)| (how.label(), *before, *after));
    let name = if request.feasible { "fgls" } else { request.options.estimator.name() };
    let mut report = CalibrationReport::new(&result, &request.data, name, sets, folds);
    if let Some((_, _, how)) = cv {
        report = report.with_cross_validation(how);
    }
    if let Some(path) = &chosen.path {
        report = report.with_selection(path);
    }
    if let Some(scale) = chosen.scale {
        report = report.with_prior_scale(scale);
    }
    let predicted = predicted_accuracy(&report.sets, &result, &request.held_out)?;
    let report = report.with_predicted(predicted);
    Ok(MarkerOutcome { calibration: result, report })
}

/// The k-fold cross-validation of `fit` with the options asked (before any choice), nested
/// when a choice is made from the data: with `--select` or `--prior auto` the choice is made
/// again on each fold's training poses (a robust loss's weights always are). Before, after,
/// and how it was made.
fn cross_validate(
    model: &RobotModel,
    fit: &Measurements,
    request: &MarkerRequest,
    k: usize,
) -> Result<(ErrorStats, ErrorStats, CrossValidationReport), CalibrationError> {
    let (asked, choices) = (&request.options, &request.choices);
    let mut redone = choices_in_words(choices);
    if asked.loss != Loss::Squared {
        redone.push(format!("--loss {}'s weights", asked.loss));
    }
    // Without choices, each fold calibrates with the options asked ([`calibration::cross_validate`]'s folds).
    let cv = cross_validate_choices(&Markers(model), fit, asked, choices, k)?;
    let poses = Some(crate::report::poses::in_degrees(&cv.poses, &model.joints));
    let (selected, scales) = (cv.selected, cv.scales);
    let how = CrossValidationReport { folds: k, nested: !redone.is_empty(), redone, selected, scales, poses };
    Ok((cv.before, cv.after, how))
}

/// The position error predicted at each held-out set's poses from the calibration's
/// parameter covariance, with the floor (the first held-out set's rms after calibration) and
/// without it, as `robocal accuracy` predicts it from the covariance sidecar.
fn predicted_accuracy(
    sets: &[SetEvaluation],
    result: &Calibration,
    held_out: &[(String, Measurements, Option<NoiseModel>)],
) -> Result<Vec<PredictedAccuracy>, CovarianceError> {
    let floor_mm =
        sets.iter().find(|s| s.name != "training").and_then(|s| s.pooled.last()).map_or(0.0, |s| s.rms);
    let estimate = &result.refined.estimate;
    let covariance = ParameterCovariance::new(estimate.names.clone(), &estimate.covariance, floor_mm);
    let with_floor = AccuracyModel::new(&result.calibrated, &covariance)?;
    let alone = AccuracyModel::new(&result.calibrated, &ParameterCovariance { floor_mm: 0.0, ..covariance })?;
    Ok((held_out.iter())
        .map(|(name, d, _)| {
            let (all, params) = (with_floor.map(&d.joints), alone.map(&d.joints));
            let n = all.len().max(1) as f64;
            PredictedAccuracy {
                set: name.clone(),
                mean_mm: all.iter().map(|p| p.1.position_mm).sum::<f64>() / n,
                max_mm: all.iter().map(|p| p.1.position_mm).fold(0.0, f64::max),
                parameters_mm: params.iter().map(|p| p.1.position_mm).sum::<f64>() / n,
                floor_mm,
            }
        })
        .collect())
}

/// Why a calibration of observation files or of views on a tree failed: the calibration's
/// error, and the file (or files) it concerns.
#[derive(Debug, thiserror::Error)]
#[error("{context}")]
pub struct FilesError {
    /// The file or files: a session that cannot be joined, the sessions fitted, a held-out set.
    pub context: String,
    /// The calibration's error.
    #[source]
    pub source: CalibrationError,
}

/// A tree calibrated from views and its report (the command line's).
#[derive(Debug, Clone)]
pub struct TreeOutcome {
    /// The calibration.
    pub calibration: TreeCalibration,
    /// The report: the training views and each held-out set scored, the files fitted.
    pub report: TreeReport,
}

/// A function making a calibration's error a [`FilesError`] about `context`.
fn in_context(context: &str) -> impl Fn(CalibrationError) -> FilesError + '_ {
    move |source| FilesError { context: context.to_string(), source }
}

/// How a calibration of observation files or of a tree's views is fitted: with the noise
/// given (the files' sigmas and the joint noise), `choices` made from the data and `folds`
/// cross-validating it; or by feasible GLS, the noise estimated from the residuals.
#[derive(Debug, Clone, PartialEq)]
pub enum Fitting {
    /// The noise given: [`calibrate_observations`], [`calibrate_views`].
    Given {
        /// The choices made from the data.
        choices: Choices,
        /// `--folds k`: the k-fold cross-validation of the training poses.
        folds: Option<usize>,
    },
    /// The noise estimated: [`calibrate_observations_feasible`], [`calibrate_views_feasible`].
    Feasible(FeasibleOptions),
}

impl Fitting {
    /// Feasible GLS (its default options) if `feasible`, else the noise given with `choices`
    /// and `folds`.
    pub fn new(feasible: bool, choices: Choices, folds: Option<usize>) -> Self {
        match feasible {
            true => Self::Feasible(FeasibleOptions::default()),
            false => Self::Given { choices, folds },
        }
    }
}

/// [`calibrate_views`] or [`calibrate_views_feasible`], as `fitting` says.
pub fn calibrate_views_by(
    tree: &RobotTree,
    sessions: &[(String, TreeData)],
    held_out: &[(String, TreeData)],
    options: &TreeOptions,
    fitting: &Fitting,
) -> Result<TreeOutcome, FilesError> {
    match fitting {
        Fitting::Given { choices, folds } => {
            calibrate_views(tree, sessions, held_out, options, choices, *folds)
        }
        Fitting::Feasible(feasible) => calibrate_views_feasible(tree, sessions, held_out, options, feasible),
    }
}

/// [`calibrate_observations`] or [`calibrate_observations_feasible`], as `fitting` says.
pub fn calibrate_observations_by(
    model: &RobotModel,
    sessions: &[(String, KindData)],
    held_out: &[(String, KindData)],
    options: &KindOptions,
    fitting: &Fitting,
) -> Result<ObservationOutcome, FilesError> {
    match fitting {
        Fitting::Given { choices, folds } => {
            calibrate_observations(model, sessions, held_out, options, choices, *folds)
        }
        Fitting::Feasible(feasible) => {
            calibrate_observations_feasible(model, sessions, held_out, options, feasible)
        }
    }
}

/// Calibrate `tree` from the views of `sessions` (each a file's name and views) fitted
/// together, with `choices` made from them ([`calibrate_chosen`]: `--prior auto`'s
/// scale, then `--select`'s parameters; none: the tree as
/// [`calibrate_tree`](crate::calibration::tree::calibrate_tree) calibrates it, which gives the
/// model and its estimator), score each `held_out` set with the frames as calibrated, with
/// `folds` cross-validate the training poses ([`cross_validate_choices`]; "nested" with a
/// choice or a robust loss, each fold making them again), and report.
pub fn calibrate_views(
    tree: &RobotTree,
    sessions: &[(String, TreeData)],
    held_out: &[(String, TreeData)],
    options: &TreeOptions,
    choices: &Choices,
    folds: Option<usize>,
) -> Result<TreeOutcome, FilesError> {
    let (data, names) = joined_views(sessions)?;
    let chosen = calibrate_chosen(&Tree(tree), &data, options, choices).map_err(in_context(&names))?;
    let c = chosen.calibration;
    let mut scores = view_scores(&c, held_out)?;
    if let Some(k) = folds {
        let score = cross_validate_choices(&Tree(tree), &data, options, choices, k)
            .map_err(in_context(&format!("--folds {k}: {names}")))?;
        scores.push((fold_label(k, *choices != Choices::default() || options.loss != Loss::Squared), score));
    }
    let fitted = (data.views.len(), data.joints.len());
    let files = sessions.iter().map(|(name, file)| (name.clone(), file.views.len())).collect();
    let mut report =
        TreeReport::new(&c, &names, fitted, options.estimator.name(), scores).with_training_files(files);
    if let Some(scale) = chosen.scale {
        report = report.with_prior_scale(scale);
    }
    if let Some(path) = &chosen.path {
        report = report.with_selection(path);
    }
    Ok(TreeOutcome { calibration: c, report })
}

/// Calibrate `tree` from the views of `sessions` fitted together by feasible GLS
/// ([`calibrate_tree_feasible`]: the tree's joint noise and the views' position and rotation
/// noise estimated from the residuals), score each `held_out` set whitened by the estimate, and
/// report, the estimate with it.
pub fn calibrate_views_feasible(
    tree: &RobotTree,
    sessions: &[(String, TreeData)],
    held_out: &[(String, TreeData)],
    options: &TreeOptions,
    feasible: &FeasibleOptions,
) -> Result<TreeOutcome, FilesError> {
    let (data, names) = joined_views(sessions)?;
    let c = calibrate_tree_feasible(tree, &data, options, feasible).map_err(in_context(&names))?;
    let scores = view_scores(&c, held_out)?;
    let fitted = (data.views.len(), data.joints.len());
    let files = sessions.iter().map(|(name, file)| (name.clone(), file.views.len())).collect();
    let report = TreeReport::new(&c, &names, fitted, "fgls", scores).with_training_files(files);
    Ok(TreeOutcome { calibration: c, report })
}

/// The views of `sessions` joined into one set (an error naming the file that does not join),
/// and the sessions' names.
fn joined_views(sessions: &[(String, TreeData)]) -> Result<(TreeData, String), FilesError> {
    let mut data = TreeData::default();
    for (name, file) in sessions {
        data = data.join(file).map_err(in_context(name))?;
    }
    let names: Vec<&str> = sessions.iter().map(|(name, _)| name.as_str()).collect();
    Ok((data, names.join(", ")))
}

/// Each `held_out` set of views scored by `c`, with its name.
fn view_scores(
    c: &TreeCalibration,
    held_out: &[(String, TreeData)],
) -> Result<Vec<(String, TreeScore)>, FilesError> {
    (held_out.iter()).map(|(name, d)| Ok((name.clone(), c.score(d).map_err(in_context(name))?))).collect()
}

/// An observation files' calibration and its report (the command line's).
#[derive(Debug, Clone)]
pub struct ObservationOutcome {
    /// The calibration.
    pub calibration: KindCalibration,
    /// The report: the training observations, each held-out set and the cross-validation
    /// scored, the files fitted, the selection's path if one was made.
    pub report: ObservationsReport,
}

/// Calibrate `model` from the observations of `sessions` (each a file's name and
/// observations) fitted together, with `choices` made from them ([`calibrate_chosen`]:
/// `--prior auto`'s scale, then `--select`'s parameters; none: every parameter asked for);
/// score each `held_out` set with the calibrated robot and set-up; with `folds`,
/// cross-validate the training poses, the choices and a robust loss's weights made again in
/// each fold (labelled "nested"); and report.
pub fn calibrate_observations(
    model: &RobotModel,
    sessions: &[(String, KindData)],
    held_out: &[(String, KindData)],
    options: &KindOptions,
    choices: &Choices,
    folds: Option<usize>,
) -> Result<ObservationOutcome, FilesError> {
    let (data, names) = joined(sessions);
    let context = match choices_in_words(choices) {
        words if words.is_empty() => names.clone(),
        words => format!("{}: {names}", words.join(", ")),
    };
    let chosen = calibrate_chosen(&Kinds(model), &data, options, choices).map_err(in_context(&context))?;
    let mut scores = held_out_scores(&chosen.calibration, held_out)?;
    if let Some(k) = folds {
        let score = cross_validate_choices(&Kinds(model), &data, options, choices, k)
            .map_err(in_context(&format!("--folds {k}: {names}")))?;
        // The choices and a robust loss's weights are made from the data: made again in each
        // fold.
        scores.push((fold_label(k, *choices != Choices::default() || options.loss != Loss::Squared), score));
    }
    let fitted = (data.observations.len(), data.joints.len());
    Ok(observations_outcome(chosen, (sessions, &names, fitted), options.estimator.name(), scores))
}

/// Calibrate `model` from the observations of `sessions` fitted together by feasible GLS
/// ([`calibrate_kinds_feasible`]: the joint noise and each kind of observation's measurement
/// noise estimated from the residuals), score each `held_out` set with the calibrated robot
/// and set-up, whitened by the estimated noise, and report, the estimate with it.
pub fn calibrate_observations_feasible(
    model: &RobotModel,
    sessions: &[(String, KindData)],
    held_out: &[(String, KindData)],
    options: &KindOptions,
    feasible: &FeasibleOptions,
) -> Result<ObservationOutcome, FilesError> {
    let (data, names) = joined(sessions);
    let calibration =
        calibrate_kinds_feasible(model, &data, options, feasible).map_err(in_context(&names))?;
    let scores = held_out_scores(&calibration, held_out)?;
    let chosen = ChosenFit { scale: None, path: None, calibration };
    let fitted = (data.observations.len(), data.joints.len());
    Ok(observations_outcome(chosen, (sessions, &names, fitted), "fgls", scores))
}

/// The observations of `sessions` as one set, and their names, joined by commas.
fn joined(sessions: &[(String, KindData)]) -> (KindData, String) {
    let data = sessions.iter().fold(KindData::default(), |data, (_, file)| data.join(file));
    let names: Vec<&str> = sessions.iter().map(|(name, _)| name.as_str()).collect();
    (data, names.join(", "))
}

/// Each `held_out` set scored by `c`, with its name.
fn held_out_scores(
    c: &KindCalibration,
    held_out: &[(String, KindData)],
) -> Result<Vec<(String, Score)>, FilesError> {
    (held_out.iter()).map(|(name, d)| Ok((name.clone(), c.score(d).map_err(in_context(name))?))).collect()
}

/// The outcome of the calibration `chosen` of `sessions` (named `names`, with the observations
/// and poses `fitted`) by `estimator`, with the `scores` of the held-out sets and the
/// cross-validation.
fn observations_outcome(
    chosen: ChosenFit<KindCalibration>,
    (sessions, names, fitted): (&[(String, KindData)], &str, (usize, usize)),
    estimator: &str,
    scores: Vec<(String, Score)>,
) -> ObservationOutcome {
    let c = chosen.calibration;
    let files = sessions.iter().map(|(name, file)| (name.clone(), file.observations.len())).collect();
    let mut report = ObservationsReport::new(&c, names, fitted, estimator, scores).with_training_files(files);
    if let Some(path) = &chosen.path {
        report = report.with_selection(path, &c);
    }
    if let Some(scale) = chosen.scale {
        report = report.with_prior_scale(scale);
    }
    ObservationOutcome { calibration: c, report }
}
