//! `--prior auto[:PRESET]`: one scale `s` for a preset's standard deviations, chosen from the
//! training poses by k-fold cross-validation. A preset's tolerances are a guess at how far a
//! robot is from its drawing; how far this one is, the poses tell: each `s` of [`SCALES`]
//! multiplies every standard deviation of the preset, the calibration with those priors is
//! cross-validated ([`cross_validate`]: pose `i` held out in fold
//! `i mod k`), and the scale of the lowest held-out RMS is chosen (ties to the smaller scale,
//! the stronger prior). The curve it was chosen from is reported. The choice is made from the
//! data, so `--folds` cross-validates it nested
//! ([`cross_validate_choices`](super::selection::cross_validate_choices)).

use super::kinds::{KindData, KindOptions, cross_validate_kinds};
use super::tree::{TreeData, TreeOptions, cross_validate_tree};
use super::{CalibrationError, Measurements, Options, RobotModel, cross_validate};
use crate::estimation::PriorEntry;
use crate::model::RobotTree;

/// The scales tried: powers of 2 from 1/16 to 16.
pub const SCALES: [f64; 9] = [0.0625, 0.125, 0.25, 0.5, 1.0, 2.0, 4.0, 8.0, 16.0];

/// The preset taken by `--prior auto` without one.
pub const DEFAULT_PRESET: &str = "fabricated";

/// A preset whose standard deviations are to be scaled from the data.
#[derive(Debug, Clone, PartialEq)]
pub struct AutoPrior {
    /// The preset's name (`fabricated`).
    pub preset: String,
    /// Its entries at scale 1.
    pub entries: Vec<PriorEntry>,
}

impl AutoPrior {
    /// `auto` or `auto:PRESET`: the preset's entries; `None` for any other text; an error
    /// naming the presets for an unknown one.
    pub fn parse(text: &str) -> Option<Result<Self, String>> {
        let preset = match text.trim() {
            "auto" => DEFAULT_PRESET,
            other => other.strip_prefix("auto:")?.trim(),
        };
        let known = crate::estimation::PRIOR_PRESETS.iter().find(|(name, _)| *name == preset);
        Some(match known {
            Some((name, _)) => PriorEntry::parse_list(name)
                .map(|entries| Self { preset: name.to_string(), entries })
                .map_err(|e| e.to_string()),
            None => {
                let names: Vec<&str> = crate::estimation::PRIOR_PRESETS.iter().map(|(n, _)| *n).collect();
                Err(format!("`{text}`: expected auto or auto:PRESET, a preset among {}", names.join(", ")))
            }
        })
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
}

/// The scale chosen, and the curve it was chosen from.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct PriorScale {
    /// The preset scaled.
    pub preset: String,
    /// The folds of the cross-validation.
    pub folds: usize,
    /// The scales tried ([`SCALES`]).
    pub scales: Vec<f64>,
    /// The cross-validated RMS marker error after calibration at each scale (mm).
    pub cv_rms: Vec<f64>,
    /// The index of the scale chosen.
    pub chosen: usize,
}

impl PriorScale {
    /// The scale chosen.
    pub fn scale(&self) -> f64 {
        self.scales[self.chosen]
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
    scale_by_curve(auto, folds, data.joints.len(), |s| {
        Ok(cross_validate_kinds(model, data, &with_kinds_scale(options, auto, s), folds)?.lengths.1)
    })
}

/// [`with_scale`] for a tree's views.
pub fn with_tree_scale(options: &TreeOptions, auto: &AutoPrior, s: f64) -> TreeOptions {
    TreeOptions { prior: auto.before(&options.prior, s), ..options.clone() }
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
    Ok(PriorScale { preset: auto.preset.clone(), folds, scales: SCALES.to_vec(), cv_rms, chosen })
}
