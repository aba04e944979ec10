//! The calibrations as one library call each: what `robocal calibrate` does between reading
//! its inputs and writing its outputs, for the command line and the Python package alike, so
//! that neither keeps a copy. Of every kind of file (markers, a probe's poses, distances,
//! contacts, coordinates, camera views) and of views on a tree, one pipeline over both ([`calibrate_files`], what each needs in [`Files`]): the sessions
//! joined, the calibration (the choices made from the data, or feasible GLS), the held-out
//! sets scored, the (nested) cross-validation, the report. Above every other
//! module: it joins the calibration, the design's accuracy prediction and the report.

use crate::calibration::kinds::{KindCalibration, KindData, KindOptions, Score, calibrate_kinds_feasible};
use crate::calibration::tree::{TreeCalibration, TreeData, calibrate_tree_feasible};
use crate::calibration::{
    CalibrationError, Choices, ChosenFit, FeasibleOptions, FoldChoices, Front, Kinds, Loss, Nested, Tree,
    calibrate_chosen, cross_validate_choices,
};
use crate::design::accuracy::{AccuracyModel, CovarianceError, ParameterCovariance};
use crate::estimation::Estimator;
use crate::model::RobotModel;
use crate::report::calibration::{CrossValidationReport, PredictedAccuracy};
use crate::report::observations::{ObservationsReport, Reported};
use std::borrow::Cow;

/// The choices of `choices` as the command line's flags: `--prior auto:fabricated's scale`,
/// `--select bic`.
pub fn choices_in_words(choices: &Choices) -> Vec<String> {
    let auto = choices.auto_prior.iter().map(|(a, _)| format!("--prior {}'s scale", a.label()));
    auto.chain(choices.select.map(|c| format!("--select {}", c.name()))).collect()
}

/// How a `k`-fold cross-validation was made: nested when `choices` or a robust `loss`'s
/// weights are made from the data (each fold made them again, `made` what they chose).
fn fold_report(k: usize, choices: &Choices, loss: Loss, made: FoldChoices) -> CrossValidationReport {
    let mut redone = choices_in_words(choices);
    if loss != Loss::Squared {
        redone.push(format!("--loss {loss}'s weights"));
    }
    let (selected, scales) = (made.selected, made.scales);
    CrossValidationReport { folds: k, nested: !redone.is_empty(), redone, selected, scales }
}

/// The tool's position error predicted from `covariance` (its floor in quadrature, and
/// without it) at the poses of each set, `(name, joint values)`, on `model`:
/// `sigma_p^2 = tr(J_p C J_p^T) + floor^2` ([`AccuracyModel`]), its mean and maximum.
fn predicted_at<'a>(
    model: &RobotModel,
    covariance: ParameterCovariance,
    sets: impl Iterator<Item = (&'a str, &'a [Vec<f64>])>,
) -> Result<Vec<PredictedAccuracy>, CovarianceError> {
    let floor_mm = covariance.floor_mm;
    let with_floor = AccuracyModel::new(model, &covariance)?;
    let alone = AccuracyModel::new(model, &ParameterCovariance { floor_mm: 0.0, ..covariance })?;
    Ok(sets
        .map(|(name, joints)| {
            let (all, params) = (with_floor.map(joints), alone.map(joints));
            let n = all.len().max(1) as f64;
            PredictedAccuracy {
                set: name.to_string(),
                mean_mm: all.iter().map(|p| p.1.position_mm).sum::<f64>() / n,
                max_mm: all.iter().map(|p| p.1.position_mm).fold(0.0, f64::max),
                parameters_mm: params.iter().map(|p| p.1.position_mm).sum::<f64>() / n,
                floor_mm,
            }
        })
        .collect())
}

/// The tool point's position error predicted at each held-out set's poses from an observation
/// calibration's covariance of the robot's parameters ([`robot_covariance`]), with `floor_mm`
/// (the first held-out set's marker RMS after calibration; 0 without markers: no position
/// measured).
fn predicted_for_kinds(
    c: &KindCalibration,
    held_out: &[(String, KindData)],
    floor_mm: f64,
) -> Result<Vec<PredictedAccuracy>, CovarianceError> {
    predicted_at(
        &c.calibrated,
        robot_covariance(c, floor_mm),
        held_out.iter().map(|(name, d)| (name.as_str(), d.joints.as_slice())),
    )
}

/// An observation calibration's covariance of the robot's parameters with `floor_mm` in
/// quadrature: what the accuracy at new poses is predicted from, and `--out-model`'s
/// covariance sidecar holds. The set-up is left out (it does not move the tool); the markers
/// are kept unless a tool point was estimated, since marker 1 is then the written model's tool
/// ([`AccuracyModel`] reads `marker1.*` as `tool.*`).
pub fn robot_covariance(c: &KindCalibration, floor_mm: f64) -> ParameterCovariance {
    let estimate = &c.refined.estimate;
    let tool = estimate.names.iter().any(|n| n.starts_with("tool."));
    let kept: Vec<usize> = (0..estimate.names.len())
        .filter(|&k| {
            let name = &estimate.names[k];
            c.params.index_by_name(name).is_some() && !(tool && name.starts_with("marker"))
        })
        .collect();
    let names = kept.iter().map(|&k| estimate.names[k].clone()).collect();
    let covariance = nalgebra::DMatrix::from_fn(kept.len(), kept.len(), |r, col| {
        estimate.covariance[(kept[r], kept[col])]
    });
    ParameterCovariance::new(names, &covariance, floor_mm)
}

/// Why a calibration of observation files or of views on a tree failed: the calibration's
/// error, and the file (or files) or the flags it concerns.
#[derive(Debug, thiserror::Error)]
#[error("{context}")]
pub struct FilesError {
    /// The file or files (a session that cannot be joined, the sessions fitted, a held-out
    /// set), or the flags: a name that matches no parameter is `--params`', `--hold`'s,
    /// `--keep`'s or `--per-session`'s, a bad prior `--prior`'s.
    pub context: String,
    /// The calibration's error.
    #[source]
    pub source: CalibrationError,
}

/// A function making a calibration's error a [`FilesError`] about `files`, or about the flags
/// where the error is theirs.
fn in_context(files: &str) -> impl Fn(CalibrationError) -> FilesError + '_ {
    move |source| {
        let context = match source {
            CalibrationError::Selection(_) => "--params, --hold, --keep or --per-session",
            CalibrationError::Prior(_) => "--prior",
            _ => files,
        };
        FilesError { context: context.to_string(), source }
    }
}

/// What the files' pipeline ([`calibrate_files`]) needs of a calibration beyond its
/// [`Front`]: of observation files ([`Kinds`]) and of a tree's views ([`Tree`]), how sessions
/// join, how a held-out set is scored (as the cross-validation scores its folds,
/// [`Front::Nested`]), feasible GLS, and the report.
pub trait Files: Front<Nested = Nested<Score>> {
    /// The sessions' data joined into one set (an error naming the file that does not join);
    /// one session's data as it is, not copied.
    fn join(sessions: &[(String, Self::Data)]) -> Result<Cow<'_, Self::Data>, FilesError>;

    /// The observations (or views) and the poses of `data`.
    fn counts(data: &Self::Data) -> (usize, usize);

    /// `data` scored by `fit`, as calibrated.
    fn score(fit: &Self::Fit, data: &Self::Data) -> Result<Score, CalibrationError>;

    /// The estimator and the loss `options` ask for.
    fn asked(options: &Self::Options) -> (Estimator, Loss);

    /// Calibrate `data` by feasible GLS, the noise estimated from the residuals.
    fn feasible(
        &self,
        data: &Self::Data,
        options: &Self::Options,
        feasible: &FeasibleOptions,
    ) -> Result<Self::Fit, CalibrationError>;

    /// The report of `chosen` fitted on `data` from the files `names` (and `files`, each with
    /// its observations) by `estimator`, with the held-out sets' and the cross-validation's
    /// `scores`, and how the cross-validation was made (`cv`). The report may take what it
    /// shows out of `chosen` rather than copy it: of observation files, the training score
    /// (a residual per observation), the outcome's calibration then holding an empty one.
    fn report(
        chosen: &mut ChosenFit<Self::Fit>,
        fitted: (&Self::Data, &str, Vec<(String, usize)>),
        estimator: &str,
        scores: (Vec<(String, Score)>, Option<CrossValidationReport>),
    ) -> ObservationsReport;

    /// `report` with the tool's position error predicted at the `held_out` sets' poses from
    /// `fit`'s parameter covariance; as it is where the kind predicts none.
    fn with_predicted(
        report: ObservationsReport,
        _fit: &Self::Fit,
        _held_out: &[(String, Self::Data)],
    ) -> Result<ObservationsReport, CalibrationError> {
        Ok(report)
    }
}

impl Files for Kinds<'_> {
    fn join(sessions: &[(String, KindData)]) -> Result<Cow<'_, KindData>, FilesError> {
        Ok(match sessions {
            [(_, one)] => Cow::Borrowed(one),
            _ => Cow::Owned(sessions.iter().fold(KindData::default(), |data, (_, file)| data.join(file))),
        })
    }

    fn counts(data: &KindData) -> (usize, usize) {
        (data.observations.len(), data.joints.len())
    }

    fn score(fit: &KindCalibration, data: &KindData) -> Result<Score, CalibrationError> {
        fit.score(data)
    }

    fn asked(options: &KindOptions) -> (Estimator, Loss) {
        (options.estimator, options.loss)
    }

    fn feasible(
        &self,
        data: &KindData,
        options: &KindOptions,
        feasible: &FeasibleOptions,
    ) -> Result<KindCalibration, CalibrationError> {
        calibrate_kinds_feasible(self.0, data, options, feasible)
    }

    fn report(
        chosen: &mut ChosenFit<KindCalibration>,
        (data, names, files): (&KindData, &str, Vec<(String, usize)>),
        estimator: &str,
        scores: (Vec<(String, Score)>, Option<CrossValidationReport>),
    ) -> ObservationsReport {
        report_of(chosen, (names, files), (Self::counts(data), data.assumed_sigmas), estimator, scores)
    }

    fn with_predicted(
        report: ObservationsReport,
        fit: &KindCalibration,
        held_out: &[(String, KindData)],
    ) -> Result<ObservationsReport, CalibrationError> {
        let predicted = predicted_for_kinds(fit, held_out, report.floor_mm()).map_err(|e| {
            CalibrationError::Scoring(format!("the accuracy predicted at the held-out poses: {e}"))
        })?;
        Ok(report.with_predicted(predicted))
    }
}

/// The report of `chosen` (of an arm or a tree), fitted on `(observations, poses)` with
/// `assumed` observations of no sigma, from the files `names` (each with its observations,
/// `files`), by `estimator`, with the held-out sets' and the cross-validation's `scores`; its
/// training score moved into it (the calibration's left empty).
fn report_of<R: Reported>(
    chosen: &mut ChosenFit<crate::calibration::kinds::Calibration<R>>,
    (names, files): (&str, Vec<(String, usize)>),
    (counts, assumed): ((usize, usize), usize),
    estimator: &str,
    (scores, cv): (Vec<(String, Score)>, Option<CrossValidationReport>),
) -> ObservationsReport {
    let training = std::mem::take(&mut chosen.calibration.training);
    let c = &chosen.calibration;
    let mut report = ObservationsReport::with_training(c, training, names, counts, estimator, scores);
    report.cross_validation = cv;
    report = report.with_training_files(files).with_assumed_sigmas(assumed);
    if let Some(path) = &chosen.path {
        report = report.with_selection(path, c);
    }
    match &chosen.scale {
        Some(scale) => report.with_prior_scale(scale.clone()),
        None => report,
    }
}

impl Files for Tree<'_> {
    fn join(sessions: &[(String, TreeData)]) -> Result<Cow<'_, TreeData>, FilesError> {
        let mut data = TreeData::default();
        for (name, file) in sessions {
            data = data.join(file).map_err(in_context(name))?;
        }
        Ok(Cow::Owned(data))
    }

    fn counts(data: &TreeData) -> (usize, usize) {
        (data.views.len(), data.joints.len())
    }

    fn score(fit: &TreeCalibration, data: &TreeData) -> Result<Score, CalibrationError> {
        fit.score(data)
    }

    fn asked(options: &KindOptions) -> (Estimator, Loss) {
        (options.estimator, options.loss)
    }

    fn feasible(
        &self,
        data: &TreeData,
        options: &KindOptions,
        feasible: &FeasibleOptions,
    ) -> Result<TreeCalibration, CalibrationError> {
        calibrate_tree_feasible(self.0, data, options, feasible)
    }

    /// Its views counted as its observations.
    fn report(
        chosen: &mut ChosenFit<TreeCalibration>,
        (data, names, files): (&TreeData, &str, Vec<(String, usize)>),
        estimator: &str,
        scores: (Vec<(String, Score)>, Option<CrossValidationReport>),
    ) -> ObservationsReport {
        let assumed = if data.assumed_sigmas { data.views.len() } else { 0 };
        report_of(chosen, (names, files), (Self::counts(data), assumed), estimator, scores)
    }
}

/// A calibration of files and its report (the command line's): of observation files
/// or of a tree's views ([`TreeOutcome`]).
pub struct Outcome<F: Files> {
    /// The calibration (of observation files, its training score moved into the report's
    /// first set, [`Files::report`]).
    pub calibration: F::Fit,
    /// The report: the training data, each held-out set and the cross-validation scored, the
    /// files fitted, the choices made.
    pub report: ObservationsReport,
}

/// A tree calibrated from views, and the report.
pub type TreeOutcome<'a> = Outcome<Tree<'a>>;

/// How a calibration of observation files or of a tree's views is fitted: with the noise
/// given (the files' sigmas and the joint noise), `choices` made from the data and `folds`
/// cross-validating it; or by feasible GLS, the noise estimated from the residuals.
#[derive(Debug, Clone, PartialEq)]
pub enum Fitting {
    /// The noise given.
    Given {
        /// The choices made from the data.
        choices: Choices,
        /// `--folds k`: the k-fold cross-validation of the training poses.
        folds: Option<usize>,
    },
    /// The noise estimated by feasible GLS ([`Files::feasible`]).
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

/// The name of the set of several held-out files pooled, after each file's.
pub const HELD_OUT_POOLED: &str = "held out, pooled";

/// Calibrate `front`'s robot from the data of `sessions` (each a file's name and data) fitted
/// together, as `fitting` says: with the noise given, the choices made from the data
/// ([`calibrate_chosen`]: `--prior auto`'s scale, then `--select`'s parameters; none: every
/// parameter asked for), and with `folds` the training poses cross-validated
/// ([`cross_validate_choices`]; "nested" with a choice or a robust loss, each fold making them
/// again); or by feasible GLS ([`Files::feasible`]: the joint noise and each kind's
/// measurement noise estimated from the residuals). Each `held_out` set is scored with the
/// robot and set-up as calibrated (whitened by the estimated noise with feasible GLS), several
/// of distinct stems (sessions) pooled too ([`HELD_OUT_POOLED`]), and reported.
pub fn calibrate_files<F: Files>(
    front: &F,
    sessions: &[(String, F::Data)],
    held_out: &[(String, F::Data)],
    options: &F::Options,
    fitting: &Fitting,
) -> Result<Outcome<F>, FilesError> {
    let data = F::join(sessions)?;
    let data: &F::Data = &data;
    let names = sessions.iter().map(|(name, _)| name.as_str()).collect::<Vec<_>>().join(", ");
    let (mut chosen, estimator, folds) = match fitting {
        Fitting::Given { choices, folds } => {
            let context = match choices_in_words(choices) {
                words if words.is_empty() => names.clone(),
                words => format!("{}: {names}", words.join(", ")),
            };
            let chosen = calibrate_chosen(front, data, options, choices).map_err(in_context(&context))?;
            (chosen, F::asked(options).0.name(), folds.map(|k| (k, choices)))
        }
        Fitting::Feasible(feasible) => {
            let calibration = front.feasible(data, options, feasible).map_err(in_context(&names))?;
            (ChosenFit { scale: None, path: None, calibration }, "fgls", None)
        }
    };
    let scored = |(name, d): &(String, F::Data)| {
        Ok((name.clone(), F::score(&chosen.calibration, d).map_err(in_context(name))?))
    };
    let mut scores = held_out.iter().map(scored).collect::<Result<Vec<_>, FilesError>>()?;
    let stems: std::collections::BTreeSet<_> =
        held_out.iter().map(|(name, _)| std::path::Path::new(name).file_stem()).collect();
    if held_out.len() > 1 && stems.len() == held_out.len() {
        // Several held-out files, each its own session (a stem names a file's session): their
        // observations pooled too, as a marker file's are.
        let pooled = F::join(held_out)?;
        scores.push(scored(&(HELD_OUT_POOLED.to_string(), pooled.into_owned()))?);
    }
    let mut cv = None;
    if let Some((k, choices)) = folds {
        let nested = cross_validate_choices(front, data, options, choices, k)
            .map_err(in_context(&format!("--folds {k}: {names}")))?;
        let how = fold_report(k, choices, F::asked(options).1, nested.choices);
        scores.push((how.label(), nested.score));
        cv = Some(how);
    }
    let files = sessions.iter().map(|(name, file)| (name.clone(), F::counts(file).0)).collect();
    let report = F::report(&mut chosen, (data, &names, files), estimator, (scores, cv));
    let report = F::with_predicted(report, &chosen.calibration, held_out).map_err(in_context(&names))?;
    Ok(Outcome { calibration: chosen.calibration, report })
}
