//! `--prior auto[:PRESET]`: one scale `s` for a preset's standard deviations, chosen from the
//! training poses by k-fold cross-validation. A preset's tolerances are a guess at how far a
//! robot is from its drawing; how far this one is, the poses tell: each `s` of [`SCALES`]
//! multiplies every standard deviation of the preset, the calibration with those priors is
//! cross-validated ([`Front::cv_rms`]: pose `i` held out in fold `i mod k`), and the scale of
//! the lowest held-out RMS is chosen (ties to the smaller scale, the stronger prior). The
//! curve it was chosen from is reported. The choice is made from the data, so `--folds`
//! cross-validates it nested ([`cross_validate_choices`](super::selection::cross_validate_choices)).
//! Written once for the three calibrations ([`Front`]: markers, observation files, a tree's
//! views).
//!
//! `--prior auto-ml[:PRESET]` chooses `s` by the marginal likelihood instead (type-II maximum
//! likelihood, [`choose_prior_scale_ml`]), where the noise is known: the `s` that makes the
//! training poses most likely, `max_s log p(y | s)`, `y = H x + e`, `e ~ N(0, V)`,
//! `x ~ N(0, s^2 D)`, linearised about the registration, the base and the markers (and the
//! parameters without a preset's prior) integrated out under a flat prior
//! ([`crate::estimation::evidence`]). It needs no refit: one linearisation, then `O(p)` a
//! scale, on the grid [`evidence_scales`] (1/64 to 64 in steps of `2^(1/8)`).
//!
//! A marker file fitted by OLS has no noise model: its priors weigh against the residuals'
//! spread of the fit without priors, `c = sqrt(|r|^2 / (N_m - rank))` (mm,
//! [`prior`](crate::estimation::prior)'s rows). The evidence then takes the same `c` as the
//! noise, `e ~ N(0, c^2 I)`, so that the scale it chooses is the one the fit applies, and
//! reports it ([`PriorScale::noise_spread`]).

use super::choice::Front;
pub use super::choice::{
    AutoPrior, BY_CLASS, ClassScale, DEFAULT_PRESET, FrontEvidence, PriorScale, SCALES, ScaleBy,
};
use super::kinds::EvidenceSystem;
use super::{CalibrationError, check_folds};
use crate::estimation::evidence::{Column, Evidence, arg_max, evidence_scales};
use crate::estimation::{Linearisation, PriorEntry, prior_sds_of};
use crate::model::ParamInfo;

/// `options` with `auto`'s preset scaled by `s` before its own priors (which win where both
/// name a parameter).
pub fn with_scale<F: Front>(options: &F::Options, auto: &AutoPrior, s: f64) -> F::Options {
    F::with_prior(options, |own| auto.before(own, &[s]))
}

/// Choose the scale of `auto`'s preset for calibrating `data` with `options` by `auto`'s
/// method: by `folds`-fold cross-validation (see the [module documentation](self)), each scale
/// scored by the front's cross-validated RMS ([`Front::cv_rms`]: of the marker positions, of
/// the observations' lengths, every observation of a pose held out together, of the views'
/// positions; mm), or by the marginal likelihood for `auto-ml` ([`choose_prior_scale_ml`],
/// `folds` unused).
pub fn choose_prior_scale<F: Front>(
    front: &F,
    data: &F::Data,
    options: &F::Options,
    auto: &AutoPrior,
    folds: usize,
) -> Result<PriorScale, CalibrationError> {
    if auto.by == ScaleBy::Ml {
        return choose_prior_scale_ml(front, data, options, auto);
    }
    check_folds(folds, F::poses(data))?;
    let cv_rms = (SCALES.iter())
        .map(|&s| front.cv_rms(data, &with_scale::<F>(options, auto, s), folds))
        .collect::<Result<Vec<f64>, CalibrationError>>()?;
    let chosen = (0..cv_rms.len()).min_by(|&a, &b| cv_rms[a].total_cmp(&cv_rms[b])).unwrap_or(0);
    Ok(PriorScale {
        preset: auto.preset.clone(),
        by: ScaleBy::Cv,
        folds: Some(folds),
        scales: SCALES.to_vec(),
        cv_rms,
        log_evidence: Vec::new(),
        chosen,
        classes: Vec::new(),
        noise_spread: None,
    })
}

/// Linearisations about the maximum a posteriori estimate after the first, about the
/// registration, at most: the scale is chosen again about the estimate at the scale chosen
/// until it stays.
pub const EVIDENCE_ROUNDS: usize = 4;

/// Choose the scale of `auto`'s preset for calibrating `data` with `options` by the marginal
/// likelihood: `s = argmax log p(y | s)` over [`evidence_scales`] ([`Front::evidence`]), about
/// the registration (the "before" fit) first, then about the calibration at the scale chosen
/// (MacKay's re-estimation: where the errors are large, the registration's linearisation
/// leaves a second-order residual that a larger scale would explain), until the scale stays
/// (at most [`EVIDENCE_ROUNDS`] linearisations). The noise must be known, or for a marker
/// file fitted by OLS is the residuals' spread its priors weigh against; `options.prior`
/// applies unscaled, where both name a parameter instead of the preset's. With
/// [`AutoPrior::by_class`], one scale per class, `argmax log p(y | s_1..s_n)` by
/// [`Evidence::class_ascent`] from the one scale's choice, in the same rounds.
pub fn choose_prior_scale_ml<F: Front>(
    front: &F,
    data: &F::Data,
    options: &F::Options,
    auto: &AutoPrior,
) -> Result<PriorScale, CalibrationError> {
    let grid = evidence_scales();
    let (mut about, mut previous) = (None, None);
    let mut last = None;
    for _ in 0..EVIDENCE_ROUNDS {
        let evidence = front.evidence(data, options, auto, about.as_ref())?;
        let at = evidence_choice(&evidence.evidence, &grid, auto);
        let stays = previous.as_ref() == Some(&at);
        last = Some((evidence, at.clone()));
        if stays {
            break;
        }
        let scales: Vec<f64> = at.iter().map(|&k| grid[k]).collect();
        let options = F::with_prior(options, |own| auto.before(own, &scales));
        about = Some(front.calibrate(data, &options)?);
        previous = Some(at);
    }
    let (evidence, at) = last.expect("at least one round");
    Ok(PriorScale { noise_spread: evidence.noise_spread, ..ml_scale(auto, &evidence.evidence, &grid, &at) })
}

/// The grid indices the evidence chooses: the one scale of the largest
/// [`Evidence::log_evidence`]; with [`AutoPrior::by_class`], one per class of
/// [`AutoPrior::classes`] by [`Evidence::class_ascent`] from it (a class without an estimated
/// parameter at the one scale).
fn evidence_choice(evidence: &Evidence, grid: &[f64], auto: &AutoPrior) -> Vec<usize> {
    let one = arg_max(&grid.iter().map(|&s| evidence.log_evidence(s)).collect::<Vec<_>>());
    if !auto.by_class {
        return vec![one];
    }
    let mut at = evidence.class_ascent(grid, one);
    at.resize(auto.classes().len().max(at.len()), one);
    at
}

/// The [`PriorScale`] of the marginal likelihood chosen at the grid indices `at`
/// ([`evidence_choice`]): the one-scale curve, and with classes each class's profile.
fn ml_scale(auto: &AutoPrior, evidence: &Evidence, grid: &[f64], at: &[usize]) -> PriorScale {
    let curve: Vec<f64> = grid.iter().map(|&s| evidence.log_evidence(s)).collect();
    let chosen = arg_max(&curve);
    let (sizes, names) = (evidence.class_sizes(), auto.classes());
    let classes: Vec<ClassScale> = (0..sizes.len())
        .filter(|&c| auto.by_class && sizes[c] > 0)
        .map(|c| {
            let profile = evidence.profile(grid, at, c);
            let top = profile.iter().copied().fold(f64::NEG_INFINITY, f64::max);
            ClassScale {
                class: names[c].clone(),
                parameters: sizes[c],
                scale: grid[at[c]],
                chosen: at[c],
                log_evidence: profile.iter().map(|l| l - top).collect(),
            }
        })
        .collect();
    let top = match classes.is_empty() {
        true => curve[chosen],
        false => {
            curve[chosen].max(evidence.log_evidence_of(&at.iter().map(|&k| grid[k]).collect::<Vec<_>>()))
        }
    };
    PriorScale {
        preset: auto.preset.clone(),
        by: ScaleBy::Ml,
        folds: None,
        scales: grid.to_vec(),
        cv_rms: Vec::new(),
        log_evidence: curve.iter().map(|l| l - top).collect(),
        chosen,
        classes,
        noise_spread: None,
    }
}

/// The [`Evidence`] of a whitened `system` ([`linear_evidence`]), its columns by
/// [`evidence_columns`] (`own` the user's fixed priors; after the parameters, flat set-up ones).
pub(crate) fn system_evidence(
    auto: &AutoPrior,
    own: &[PriorEntry],
    system: &EvidenceSystem,
) -> Result<Evidence, CalibrationError> {
    let infos: Vec<&ParamInfo> = system.params.iter().collect();
    let extra = system.linearised.x.len() - system.asked.len();
    let (columns, classes) = evidence_columns(auto, own, &infos, &system.asked, extra)?;
    if !columns.iter().any(|c| matches!(c, Column::Scaled(_))) {
        return Err(CalibrationError::Scoring(format!(
            "--prior {}: no parameter asked for takes the preset's prior (each has another --prior entry, \
             or the preset has none for it): there is no scale to choose",
            auto.label()
        )));
    }
    Ok(linear_evidence(&system.linearised, system.c * system.c, &columns, &classes))
}

/// The error of the marginal likelihood without the noise: `give` says how to give it.
pub(crate) fn needs_the_noise(auto: &AutoPrior, give: &str) -> CalibrationError {
    CalibrationError::Scoring(format!(
        "--prior {}: the marginal likelihood needs the noise; give it ({give}), or choose the scale by \
         cross-validation (--prior auto:{})",
        auto.label(),
        auto.preset
    ))
}

/// How each column of a system enters the evidence, and its class
/// ([`AutoPrior::class_of`]): the first are the parameters `asked` (indices into `params`),
/// one with an entry of `own` a fixed prior, one with `auto`'s only scaled, the others flat;
/// then `extra` flat ones (a set-up's).
fn evidence_columns(
    auto: &AutoPrior,
    own: &[PriorEntry],
    params: &[&ParamInfo],
    asked: &[usize],
    extra: usize,
) -> Result<(Vec<Column>, Vec<usize>), CalibrationError> {
    let (fixed, preset) = (prior_sds_of(own, params)?, prior_sds_of(&auto.entries, params)?);
    let class = auto.class_of(params);
    let robot = asked.iter().map(|&i| match (fixed[i].is_finite(), preset[i].is_finite()) {
        (true, _) => Column::Fixed(fixed[i]),
        (false, true) => Column::Scaled(preset[i]),
        (false, false) => Column::Flat,
    });
    let columns = robot.chain(std::iter::repeat_n(Column::Flat, extra)).collect();
    let classes = asked.iter().map(|&i| class[i]).chain(std::iter::repeat_n(0, extra)).collect();
    Ok((columns, classes))
}

/// The [`Evidence`] of a system linearised about `x0` (`A` held as `R`, `R^T R = A^T A c^2`,
/// `z` and `rho` of [`crate::estimation::Reduced`], the rows whitened and divided by `c`).
/// About `x0` the model is linear in the errors `x` from nominal, `w0 + A x0 = A x + e` (`w0`
/// the whitened residual at `x0`), so `G = R^T R / c^2`, `A^T w = (R^T z + R^T R x0) / c^2`,
/// `|w|^2 = (|z|^2 + rho^2 + 2 x0^T R^T z + x0^T R^T R x0) / c^2`.
fn linear_evidence(start: &Linearisation, c2: f64, columns: &[Column], classes: &[usize]) -> Evidence {
    let (r, z, x0) = (start.system.r(), start.system.z(), &start.x);
    let gram = r.tr_mul(&r);
    let (rtz, gx) = (r.tr_mul(&z), &gram * x0);
    let ww = start.system.cost_after(&(x0 * 0.0)) + 2.0 * x0.dot(&rtz) + x0.dot(&gx);
    Evidence::with_classes(&(gram / c2), &((rtz + gx) / c2), ww / c2, columns, classes)
}
