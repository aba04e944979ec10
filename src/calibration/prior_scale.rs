//! `--prior auto[:PRESET]`: one scale `s` for a preset's standard deviations, chosen from the
//! training poses by k-fold cross-validation. A preset's tolerances are a guess at how far a
//! robot is from its drawing; how far this one is, the poses tell: each `s` of [`SCALES`]
//! multiplies every standard deviation of the preset, the calibration with those priors is
//! cross-validated ([`cross_validate`]: pose `i` held out in fold
//! `i mod k`), and the scale of the lowest held-out RMS is chosen (ties to the smaller scale,
//! the stronger prior). The curve it was chosen from is reported. The choice is made from the
//! data, so `--folds` cross-validates it nested
//! ([`cross_validate_choices`](super::selection::cross_validate_choices)).
//!
//! `--prior auto-ml[:PRESET]` chooses `s` by the marginal likelihood instead (type-II maximum
//! likelihood, [`choose_prior_scale_ml`]), where the noise is known: the `s` that makes the
//! training poses most likely, `max_s log p(y | s)`, `y = H x + e`, `e ~ N(0, V)`,
//! `x ~ N(0, s^2 D)`, linearised about the registration, the base and the markers (and the
//! parameters without a preset's prior) integrated out under a flat prior
//! ([`crate::estimation::evidence`]). It needs no refit: one linearisation, then `O(p)` a
//! scale, on the grid [`evidence_scales`] (1/64 to 64 in steps of `2^(1/8)`).

use super::kinds::{KindData, KindOptions, cross_validate_kinds};
use super::tree::{TreeData, TreeOptions, cross_validate_tree};
use super::{
    CalibrationError, JointParams, Measurements, Options, RobotModel, Whitening, calibrate_quietly,
    cross_validate, observed, selection,
};
use crate::estimation::evidence::{Column, Evidence, arg_max, evidence_scales};
use crate::estimation::{Estimator, PointProblem, PriorEntry, Weights, linearise, prior_sds};
use crate::kinematics::Measured;
use crate::model::{RobotTree, Selection};

/// The scales tried: powers of 2 from 1/16 to 16.
pub const SCALES: [f64; 9] = [0.0625, 0.125, 0.25, 0.5, 1.0, 2.0, 4.0, 8.0, 16.0];

/// The preset taken by `--prior auto` without one.
pub const DEFAULT_PRESET: &str = "fabricated";

/// How the scale is chosen.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum ScaleBy {
    /// k-fold cross-validation of the calibration at each scale (`--prior auto`).
    #[default]
    Cv,
    /// The marginal likelihood, the noise known (`--prior auto-ml`).
    Ml,
}

impl ScaleBy {
    /// The word of `--prior`: `auto` or `auto-ml`.
    pub fn word(self) -> &'static str {
        match self {
            Self::Cv => "auto",
            Self::Ml => "auto-ml",
        }
    }
}

/// A preset whose standard deviations are to be scaled from the data.
#[derive(Debug, Clone, PartialEq)]
pub struct AutoPrior {
    /// The preset's name (`fabricated`).
    pub preset: String,
    /// Its entries at scale 1.
    pub entries: Vec<PriorEntry>,
    /// How the scale is chosen.
    pub by: ScaleBy,
}

impl AutoPrior {
    /// `auto`, `auto:PRESET` (by cross-validation), `auto-ml` or `auto-ml:PRESET` (by the
    /// marginal likelihood): the preset's entries; `None` for any other text; an error naming
    /// the presets for an unknown one.
    pub fn parse(text: &str) -> Option<Result<Self, String>> {
        let trimmed = text.trim();
        let (by, rest) = match trimmed.strip_prefix("auto-ml") {
            Some(rest) => (ScaleBy::Ml, rest),
            None => (ScaleBy::Cv, trimmed.strip_prefix("auto")?),
        };
        let preset = match rest {
            "" => DEFAULT_PRESET,
            other => other.strip_prefix(':')?.trim(),
        };
        let known = crate::estimation::PRIOR_PRESETS.iter().find(|(name, _)| *name == preset);
        Some(match known {
            Some((name, _)) => PriorEntry::parse_list(name)
                .map(|entries| Self { preset: name.to_string(), entries, by })
                .map_err(|e| e.to_string()),
            None => {
                let names: Vec<&str> = crate::estimation::PRIOR_PRESETS.iter().map(|(n, _)| *n).collect();
                Err(format!(
                    "`{text}`: expected auto[:PRESET] or auto-ml[:PRESET], a preset among {}",
                    names.join(", ")
                ))
            }
        })
    }

    /// `auto:PRESET` or `auto-ml:PRESET`, as `--prior` takes it.
    pub fn label(&self) -> String {
        format!("{}:{}", self.by.word(), self.preset)
    }

    /// Its entries with every standard deviation times `s`.
    pub fn scaled(&self, s: f64) -> Vec<PriorEntry> {
        let at = |e: &PriorEntry| PriorEntry { sd: e.sd * s, text: format!("{} x {s}", e.text), ..e.clone() };
        self.entries.iter().map(at).collect()
    }

    /// Its entries scaled by `s` ([`AutoPrior::scaled`]), then `own` (which win where both
    /// name a parameter).
    pub fn before(&self, own: &[PriorEntry], s: f64) -> Vec<PriorEntry> {
        self.scaled(s).into_iter().chain(own.iter().cloned()).collect()
    }

    /// An error unless the scale is chosen by cross-validation: the marginal likelihood
    /// ([`choose_prior_scale_ml`]) is of marker data only, so far; `data` names what this is.
    pub fn by_cross_validation(&self, data: &str) -> Result<(), CalibrationError> {
        match self.by {
            ScaleBy::Cv => Ok(()),
            ScaleBy::Ml => Err(CalibrationError::Scoring(format!(
                "--prior {}: the marginal likelihood is for marker files yet, not {data}; --prior auto:{} \
                 chooses the scale by cross-validation",
                self.label(),
                self.preset
            ))),
        }
    }
}

/// The scale chosen, and the curve it was chosen from.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct PriorScale {
    /// The preset scaled.
    pub preset: String,
    /// How the scale was chosen.
    pub by: ScaleBy,
    /// The folds of the cross-validation (none for the marginal likelihood).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub folds: Option<usize>,
    /// The scales tried ([`SCALES`], or [`evidence_scales`] for the marginal likelihood).
    pub scales: Vec<f64>,
    /// By cross-validation: the cross-validated RMS marker error after calibration at each
    /// scale (mm).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub cv_rms: Vec<f64>,
    /// By the marginal likelihood: `log p(y | s)` at each scale less its largest (0 at the
    /// scale chosen).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub log_evidence: Vec<f64>,
    /// The index of the scale chosen.
    pub chosen: usize,
}

impl PriorScale {
    /// The scale chosen.
    pub fn scale(&self) -> f64 {
        self.scales[self.chosen]
    }

    /// `auto:PRESET` or `auto-ml:PRESET`, as `--prior` took it.
    pub fn label(&self) -> String {
        format!("{}:{}", self.by.word(), self.preset)
    }
}

/// `options` with `auto`'s preset scaled by `s` before its own priors (which win where both
/// name a parameter).
pub fn with_scale(options: &Options, auto: &AutoPrior, s: f64) -> Options {
    Options { prior: auto.before(&options.prior, s), ..options.clone() }
}

/// [`with_scale`] for a calibration from observation files.
pub fn with_kinds_scale(options: &KindOptions, auto: &AutoPrior, s: f64) -> KindOptions {
    KindOptions { prior: auto.before(&options.prior, s), ..options.clone() }
}

/// [`with_scale`] for a tree's views.
pub fn with_tree_scale(options: &TreeOptions, auto: &AutoPrior, s: f64) -> TreeOptions {
    TreeOptions { prior: auto.before(&options.prior, s), ..options.clone() }
}

/// Choose the scale of `auto`'s preset for calibrating `data` with `options` by `folds`-fold
/// cross-validation (see the [module documentation](self)).
pub fn choose_prior_scale(
    model: &RobotModel,
    data: &Measurements,
    options: &Options,
    auto: &AutoPrior,
    folds: usize,
) -> Result<PriorScale, CalibrationError> {
    scale_by_curve(auto, folds, data.len(), |s| {
        Ok(cross_validate(model, data, &with_scale(options, auto, s), folds)?.1.rms)
    })
}

/// [`choose_prior_scale`] for observation files: each scale scored by the cross-validated RMS
/// of the length residuals (mm; [`cross_validate_kinds`]'s folds, every observation of a pose
/// held out together).
pub fn choose_kinds_prior_scale(
    model: &RobotModel,
    data: &KindData,
    options: &KindOptions,
    auto: &AutoPrior,
    folds: usize,
) -> Result<PriorScale, CalibrationError> {
    auto.by_cross_validation("observation files")?;
    scale_by_curve(auto, folds, data.joints.len(), |s| {
        Ok(cross_validate_kinds(model, data, &with_kinds_scale(options, auto, s), folds)?.lengths.1)
    })
}

/// [`choose_prior_scale`] for a tree's views: each scale scored by the cross-validated RMS of
/// the views' position residuals (mm; [`cross_validate_tree`]'s folds).
pub fn choose_tree_prior_scale(
    tree: &RobotTree,
    data: &TreeData,
    options: &TreeOptions,
    auto: &AutoPrior,
    folds: usize,
) -> Result<PriorScale, CalibrationError> {
    auto.by_cross_validation("a tree's views")?;
    scale_by_curve(auto, folds, data.joints.len(), |s| {
        Ok(cross_validate_tree(tree, data, &with_tree_scale(options, auto, s), folds)?.position.1)
    })
}

/// The scale of [`SCALES`] of the lowest `cv_rms_at(s)` (ties to the smaller scale), with the
/// curve; `folds` checked against the `poses` first.
fn scale_by_curve(
    auto: &AutoPrior,
    folds: usize,
    poses: usize,
    cv_rms_at: impl Fn(f64) -> Result<f64, CalibrationError>,
) -> Result<PriorScale, CalibrationError> {
    super::check_folds(folds, poses).map_err(|e| CalibrationError::Scoring(format!("--prior auto: {e}")))?;
    let cv_rms = SCALES.iter().map(|&s| cv_rms_at(s)).collect::<Result<Vec<f64>, CalibrationError>>()?;
    let chosen = (0..cv_rms.len()).min_by(|&a, &b| cv_rms[a].total_cmp(&cv_rms[b])).unwrap_or(0);
    Ok(PriorScale {
        preset: auto.preset.clone(),
        by: ScaleBy::Cv,
        folds: Some(folds),
        scales: SCALES.to_vec(),
        cv_rms,
        log_evidence: Vec::new(),
        chosen,
    })
}

/// The scale of `auto`'s preset by the preset's and `auto`'s method: cross-validation
/// ([`choose_prior_scale`], `folds` folds) or the marginal likelihood
/// ([`choose_prior_scale_ml`]).
pub fn choose_scale(
    model: &RobotModel,
    data: &Measurements,
    options: &Options,
    auto: &AutoPrior,
    folds: usize,
) -> Result<PriorScale, CalibrationError> {
    match auto.by {
        ScaleBy::Cv => choose_prior_scale(model, data, options, auto, folds),
        ScaleBy::Ml => choose_prior_scale_ml(model, data, options, auto),
    }
}

/// Linearisations about the maximum a posteriori estimate after the first, about the
/// registration, at most: the scale is chosen again about the estimate at the scale chosen
/// until it stays.
pub const EVIDENCE_ROUNDS: usize = 4;

/// Choose the scale of `auto`'s preset for calibrating `data` with `options` by the marginal
/// likelihood: `s = argmax log p(y | s)` over [`evidence_scales`] ([`scale_evidence`]), about
/// the registration first, then about the calibration at the scale chosen (MacKay's
/// re-estimation: where the errors are large, the registration's linearisation leaves a
/// second-order residual that a larger scale would explain), until the scale stays (at most
/// [`EVIDENCE_ROUNDS`] linearisations). The noise must be known (`options.noise`);
/// `options.prior` applies unscaled, where both name a parameter instead of the preset's.
pub fn choose_prior_scale_ml(
    model: &RobotModel,
    data: &Measurements,
    options: &Options,
    auto: &AutoPrior,
) -> Result<PriorScale, CalibrationError> {
    let scales = evidence_scales();
    let (mut about, mut previous) = (None, None);
    let mut curve = Vec::new();
    for _ in 0..EVIDENCE_ROUNDS {
        let evidence = scale_evidence(model, data, options, auto, about.as_deref())?;
        curve = scales.iter().map(|&s| evidence.log_evidence(s)).collect();
        let chosen = arg_max(&curve);
        if previous == Some(chosen) {
            break;
        }
        previous = Some(chosen);
        about = Some(calibrate_quietly(model, data, &with_scale(options, auto, scales[chosen]))?.after);
    }
    let chosen = arg_max(&curve);
    let log_evidence = curve.iter().map(|l| l - curve[chosen]).collect();
    Ok(PriorScale {
        preset: auto.preset.clone(),
        by: ScaleBy::Ml,
        folds: None,
        scales,
        cv_rms: Vec::new(),
        log_evidence,
        chosen,
    })
}

/// The [`Evidence`] of `data` for the scale of `auto`'s preset: the system of the parameters
/// `options` asks for, linearised about `about` (a full parameter vector of a calibration of
/// `data`; `None`: the registration, the base and markers fitted as [`calibrate`](super::calibrate)'s "before")
/// and whitened by Gauss-Markov (`S V S^T = I`: the rows divided by the normalisation
/// `c = sigma_max`). About `x0` the model is linear in the errors `x` from nominal,
/// `w0 + A x0 = A x + e` (`w0` the whitened residual at `x0`), so with `A = R / c`
/// (`R^T R = A^T A c^2`, `z` and `rho` of [`crate::estimation::Reduced`]):
/// `G = R^T R / c^2`, `A^T w = (R^T z + R^T R x0) / c^2`,
/// `|w|^2 = (|z|^2 + rho^2 + 2 x0^T R^T z + x0^T R^T R x0) / c^2`. A parameter with an entry of
/// `options.prior` has that fixed prior, one with the preset's only is scaled, the others are
/// flat.
pub fn scale_evidence(
    model: &RobotModel,
    data: &Measurements,
    options: &Options,
    auto: &AutoPrior,
    about: Option<&[f64]>,
) -> Result<Evidence, CalibrationError> {
    let frame = calibrate_quietly(model, data, &Options { joints: JointParams::None, ..options.clone() })?;
    let Whitening::Covariance(noise) = &frame.whitening else {
        return Err(CalibrationError::Scoring(format!(
            "--prior {}: the marginal likelihood needs the noise; give it (--sigma-mm with \
             --joint-sigma-deg, or --noise), or choose the scale by cross-validation (--prior auto:{})",
            auto.label(),
            auto.preset
        )));
    };
    let params = &frame.params;
    let zero = vec![0.0; params.len()];
    let kind = if data.orientations.is_some() { Measured::Pose } else { Measured::Position };
    let nothing = Selection::from_indices(params, []);
    let base_problem = PointProblem::new(
        &frame.chains,
        &nothing,
        kind,
        data.joints.clone(),
        observed(data),
        zero,
        Some(noise),
    )?;
    let weights = Weights::for_problem(&base_problem, Estimator::Wls)?;
    let c2 = weights.scale().unwrap_or(1.0).powi(2);
    let asked = selection(params, &options.joints, options)?;
    let problem = base_problem.reselect(&asked, about.unwrap_or(&frame.before).to_vec())?;
    let start = linearise(&problem, &weights, problem.start())?;
    let (fixed, preset) = (prior_sds(&options.prior, params)?, prior_sds(&auto.entries, params)?);
    let columns: Vec<Column> = (asked.indices().iter())
        .map(|&i| match (fixed[i].is_finite(), preset[i].is_finite()) {
            (true, _) => Column::Fixed(fixed[i]),
            (false, true) => Column::Scaled(preset[i]),
            (false, false) => Column::Flat,
        })
        .collect();
    let (r, z, x0) = (start.system.r(), start.system.z(), &start.x);
    let gram = r.tr_mul(&r);
    let (rtz, gx) = (r.tr_mul(&z), &gram * x0);
    let ww = start.system.cost_after(&(x0 * 0.0)) + 2.0 * x0.dot(&rtz) + x0.dot(&gx);
    Ok(Evidence::new(&(gram / c2), &((rtz + gx) / c2), ww / c2, &columns))
}
