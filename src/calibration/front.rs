//! The calibrations as the choices made from the data see them: observation files of every
//! kind, marker files among them ([`Kinds`]), and a tree's views ([`Tree`]), each a
//! [`Front`]. The choices (`--prior auto`'s scale, [`choose_prior_scale`]; `--select`,
//! [`select`]; both, [`choose`]; nested, [`cross_validate_choices`]) are written once over it;
//! what differs between the fronts is here, side by side.
//!
//! [`choose_prior_scale`]: super::prior_scale::choose_prior_scale
//! [`select`]: super::selection::select
//! [`choose`]: super::selection::choose
//! [`cross_validate_choices`]: super::selection::cross_validate_choices

use super::choice::{Criterion, Fitted, FoldChoices, FoldFit, Front, Nested, SelectionPath};
use super::kinds::{self, KindCalibration, KindData, KindOptions, Score};
use super::prior_scale::{AutoPrior, FrontEvidence, needs_the_noise, system_evidence};
use super::selection::{LinearModel, named_joints};
use super::tree::{self, TreeCalibration, TreeData};
use super::{CalibrationError, JointParams, Loss, RobotModel};
use crate::estimation::{Estimator, PriorEntry};
use crate::model::{RobotTree, name_matches};
use std::borrow::Cow;

type Result<T> = std::result::Result<T, CalibrationError>;

/// A nested cross-validation's score, as `cross` makes it calibrating each fold's training data
/// by `fit` (`options` before any choice), with what each fold chose.
fn with_choices<F: Front, S>(
    options: &F::Options,
    fit: FoldFit<F>,
    cross: impl FnOnce(&mut dyn FnMut(&F::Data) -> Result<F::Fit>) -> Result<S>,
) -> Result<Nested<S>> {
    let mut choices = FoldChoices::default();
    let score = cross(&mut |train| {
        let chosen = fit(train, options)?;
        choices.push(&chosen);
        Ok(chosen.calibration)
    })?;
    Ok(Nested { score, choices })
}

/// A robot calibrated from observation files ([`kinds::calibrate_kinds`]).
#[derive(Debug, Clone, Copy)]
pub struct Kinds<'a>(pub &'a RobotModel);

impl Front for Kinds<'_> {
    type Data = KindData;
    type Options = KindOptions;
    type Fit = KindCalibration;
    type Nested = Nested<Score>;

    /// The poses its observations hold (a fold's training data keeps the others' joints).
    fn poses(data: &KindData) -> usize {
        data.pose_lines().count()
    }

    fn prior(options: &mut KindOptions) -> &mut Vec<PriorEntry> {
        &mut options.prior
    }

    /// The patterns of `--params` that name no robot parameter (a set-up's, a marker's) kept.
    fn with_joints(&self, options: &KindOptions, names: &[String]) -> KindOptions {
        let robot = self.0.params();
        let others = match &options.joints {
            JointParams::Named(patterns) => {
                patterns.iter().filter(|p| !robot.iter().any(|q| name_matches(p, &q.name))).cloned().collect()
            }
            _ => Vec::new(),
        };
        let joints = named_joints(names.iter().cloned().chain(others).collect());
        KindOptions { joints, ..options.clone() }
    }

    fn calibrate(&self, data: &KindData, options: &KindOptions) -> Result<KindCalibration> {
        kinds::calibrate_kinds(self.0, data, options)
    }

    fn fitted(c: &KindCalibration) -> Fitted<'_> {
        let (params, values) =
            (Cow::Borrowed(&c.params), (Cow::Borrowed(c.before.as_slice()), c.after.as_slice()));
        Fitted { params, values, estimate: &c.refined.estimate, fixed: &c.fixed }
    }

    /// The length errors' ([`kinds::cross_validate_kinds`]: every observation of a pose held
    /// out together; [`kinds::Score::length_errors`]: a marker's position one error).
    fn cv_rms(&self, data: &KindData, options: &KindOptions, folds: usize) -> Result<f64> {
        Ok(kinds::cross_validate_kinds(self.0, data, options, folds)?.length_errors(&data.observations).1)
    }

    /// Their system of what `options` asks for (the robot's parameters, then the set-up's,
    /// flat), whitened by `V_k` (weighted least squares, `kinds::evidence_system`), about
    /// `about`'s estimate (`None`: the "before" fit). Without the noise (no sigma given, the
    /// joints exact) the noise is taken, as a marker file's is, from the residuals' spread of
    /// the fit without priors: the whitening's scale times `sqrt(f)`, `f` that fit's variance
    /// of unit weight ([`KindCalibration::variance_factor`](kinds::KindCalibration)), said
    /// in mm as a length row's sigma times `sqrt(f)` ([`FrontEvidence::noise_spread`]).
    fn evidence(
        &self,
        data: &KindData,
        options: &KindOptions,
        auto: &AutoPrior,
        about: Option<&KindCalibration>,
    ) -> Result<FrontEvidence> {
        let options = KindOptions { estimator: Estimator::Wls, ..options.clone() };
        let spread = match options.joint_noise.is_none() && data.assumed_sigmas == data.observations.len() {
            true => {
                let plain = KindOptions { prior: Vec::new(), loss: Loss::Squared, ..options.clone() };
                let f = kinds::calibrate_kinds(self.0, data, &plain)?.variance_factor.unwrap_or(1.0);
                let length = data.observations.iter().find(|o| !o.is_angle()).map_or(1.0, |o| o.sigma());
                Some((f.sqrt(), f.sqrt() * length))
            }
            false => None,
        };
        let about = about.map(|c| (c.after.as_slice(), c.setup_values.1.as_slice()));
        let mut system = kinds::evidence_system(self.0, data, &options, about)?;
        system.c *= spread.map_or(1.0, |s| s.0);
        let evidence = system_evidence(auto, &options.prior, &system)?;
        Ok(FrontEvidence { evidence, noise_spread: spread.map(|s| s.1) })
    }

    /// The CV RMS is of the lengths: observations that are all angles refuse `cv`.
    fn forward(&self, data: &KindData, options: &KindOptions, criterion: Criterion) -> Result<SelectionPath> {
        if matches!(criterion, Criterion::Cv { .. }) && data.observations.iter().all(|o| o.is_angle()) {
            return Err(CalibrationError::Scoring(
                "--select cv scores the held-out lengths (mm), and these observations are all angles: use \
                 --select bic or t"
                    .into(),
            ));
        }
        Ok(LinearModel::of_kinds(self.0, data, options)?.forward(criterion))
    }

    fn nested(
        &self,
        data: &KindData,
        options: &KindOptions,
        folds: usize,
        fit: FoldFit<Self>,
    ) -> Result<Nested<Score>> {
        with_choices::<Self, _>(options, fit, |calibrate| {
            kinds::cross_validate_kinds_by(data, folds, calibrate)
        })
    }
}

/// A tree calibrated from its views ([`tree::calibrate_tree`]).
#[derive(Debug, Clone, Copy)]
pub struct Tree<'a>(pub &'a RobotTree);

impl Front for Tree<'_> {
    type Data = TreeData;
    type Options = KindOptions;
    type Fit = TreeCalibration;
    type Nested = Nested<Score>;

    /// The poses its views hold (a fold's training data keeps the others' joints).
    fn poses(data: &TreeData) -> usize {
        let mut held = vec![false; data.joints.len()];
        data.views.iter().for_each(|v| held[v.pose] = true);
        held.into_iter().filter(|&h| h).count()
    }

    fn prior(options: &mut KindOptions) -> &mut Vec<PriorEntry> {
        &mut options.prior
    }

    fn with_joints(&self, options: &KindOptions, names: &[String]) -> KindOptions {
        KindOptions { joints: named_joints(names.to_vec()), ..options.clone() }
    }

    fn calibrate(&self, data: &TreeData, options: &KindOptions) -> Result<TreeCalibration> {
        tree::calibrate_tree(self.0, data, options)
    }

    /// "Before" is the nominal tree.
    fn fitted(c: &TreeCalibration) -> Fitted<'_> {
        let (params, values) =
            (Cow::Borrowed(&c.params), (Cow::Borrowed(c.before.as_slice()), c.after.as_slice()));
        Fitted { params, values, estimate: &c.refined.estimate, fixed: &c.fixed }
    }

    /// The views' positions' ([`tree::cross_validate_tree`]).
    fn cv_rms(&self, data: &TreeData, options: &KindOptions, folds: usize) -> Result<f64> {
        Ok(tree::cross_validate_tree(self.0, data, options, folds)?.view_position.map_or(0.0, |p| p.1))
    }

    /// As of observation files: the tree's parameters `options` asks for, then the cameras' and
    /// targets' placements (flat), whitened by each view's `V_k` (`tree::evidence_system`).
    /// The noise must be known: the views' sigma columns or the joint noise.
    fn evidence(
        &self,
        data: &TreeData,
        options: &KindOptions,
        auto: &AutoPrior,
        about: Option<&TreeCalibration>,
    ) -> Result<FrontEvidence> {
        if options.joint_noise.is_none() && data.assumed_sigmas {
            let give = "sigma and sigma_angle columns in the views' file, or --joint-sigma-deg";
            return Err(needs_the_noise(auto, give));
        }
        let options = KindOptions { estimator: Estimator::Wls, ..options.clone() };
        let about = about.map(|c| (c.after.as_slice(), c.setup_values.1.as_slice()));
        let system = tree::evidence_system(self.0, data, &options, about)?;
        Ok(FrontEvidence { evidence: system_evidence(auto, &options.prior, &system)?, noise_spread: None })
    }

    fn forward(&self, data: &TreeData, options: &KindOptions, criterion: Criterion) -> Result<SelectionPath> {
        Ok(tree::selection_model(self.0, data, options)?.forward(criterion))
    }

    fn nested(
        &self,
        data: &TreeData,
        options: &KindOptions,
        folds: usize,
        fit: FoldFit<Self>,
    ) -> Result<Nested<Score>> {
        with_choices::<Self, _>(options, fit, |calibrate| {
            tree::cross_validate_tree_by(data, folds, calibrate)
        })
    }
}
