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

use super::front::Front;
use super::kinds::EvidenceSystem;
use super::{CalibrationError, check_folds};
use crate::estimation::evidence::{Column, Evidence, arg_max, evidence_scales};
use crate::estimation::{Linearisation, PriorEntry, prior_sds_of};
use crate::model::ParamInfo;

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
    /// One scale per class of the preset's parameters (`auto-ml:PRESET:classes`,
    /// [`AutoPrior::classes`]), not one for all.
    pub by_class: bool,
}

/// The word after a preset that asks for one scale per class: `auto-ml:PRESET:classes`.
pub const BY_CLASS: &str = "classes";

impl AutoPrior {
    /// `auto`, `auto:PRESET` (by cross-validation), `auto-ml` or `auto-ml:PRESET` (by the
    /// marginal likelihood), `auto-ml:PRESET:classes` or `auto-ml:classes` (one scale per class,
    /// by the marginal likelihood): the preset's entries; `None` for any other text; an error
    /// naming the presets for an unknown one, and for classes by cross-validation.
    pub fn parse(text: &str) -> Option<Result<Self, String>> {
        let trimmed = text.trim();
        let (by, rest) = match trimmed.strip_prefix("auto-ml") {
            Some(rest) => (ScaleBy::Ml, rest),
            None => (ScaleBy::Cv, trimmed.strip_prefix("auto")?),
        };
        let words: Vec<&str> = match rest {
            "" => Vec::new(),
            other => other.strip_prefix(':')?.split(':').map(str::trim).collect(),
        };
        let (preset, by_class) = match words.as_slice() {
            [] => (DEFAULT_PRESET, false),
            [BY_CLASS] => (DEFAULT_PRESET, true),
            [preset] => (*preset, false),
            [preset, BY_CLASS] => (*preset, true),
            _ => return Some(Err(Self::expected(text))),
        };
        if by_class && by == ScaleBy::Cv {
            return Some(Err(format!(
                "`{text}`: a scale per class is chosen by the marginal likelihood only: auto-ml:{preset}:classes"
            )));
        }
        let known = crate::estimation::PRIOR_PRESETS.iter().find(|(name, _)| *name == preset);
        Some(match known {
            Some((name, _)) => PriorEntry::parse_list(name)
                .map(|entries| Self { preset: name.to_string(), entries, by, by_class })
                .map_err(|e| e.to_string()),
            None => Err(Self::expected(text)),
        })
    }

    /// The error of a `--prior auto...` that is none of [`AutoPrior::parse`]'s spellings.
    fn expected(text: &str) -> String {
        let names: Vec<&str> = crate::estimation::PRIOR_PRESETS.iter().map(|(n, _)| *n).collect();
        format!(
            "`{text}`: expected auto[:PRESET], auto-ml[:PRESET] or auto-ml[:PRESET]:classes, a preset among {}",
            names.join(", ")
        )
    }

    /// The classes of its parameters, one scale each with [`AutoPrior::by_class`]: its
    /// entries' targets in order, once each (`lengths`, `angles`, `offsets`, `plays`).
    pub fn classes(&self) -> Vec<String> {
        let mut classes: Vec<String> = Vec::new();
        for e in &self.entries {
            if !classes.contains(&e.target) {
                classes.push(e.target.clone());
            }
        }
        classes
    }

    /// The class index of each of `params` ([`AutoPrior::classes`]; 0 for every one unless
    /// [`AutoPrior::by_class`]), by the entry that sets its prior; 0 for one without.
    fn class_of(&self, params: &[&crate::model::ParamInfo]) -> Vec<usize> {
        let classes = self.classes();
        let class = |e: usize| classes.iter().position(|c| *c == self.entries[e].target).unwrap_or(0);
        (crate::estimation::prior_entry_of(&self.entries, params).into_iter())
            .map(|e| if self.by_class { e.map_or(0, class) } else { 0 })
            .collect()
    }

    /// Its entries, each standard deviation times its class's scale: `scales[c]` of class `c`
    /// of [`AutoPrior::classes`], or one scale for all (`scales` of length 1).
    pub fn scaled_by(&self, scales: &[f64]) -> Vec<PriorEntry> {
        let classes = self.classes();
        let at = |e: &PriorEntry| {
            let c = classes.iter().position(|c| *c == e.target).unwrap_or(0);
            let s = if scales.len() == 1 { scales[0] } else { scales[c] };
            PriorEntry { sd: e.sd * s, text: format!("{} x {s}", e.text), ..e.clone() }
        };
        self.entries.iter().map(at).collect()
    }

    /// Its entries at the scales `chosen` chose (one for all, or one per class), then `own`
    /// (which win where both name a parameter).
    pub fn chosen(&self, own: &[PriorEntry], chosen: &PriorScale) -> Vec<PriorEntry> {
        let scales: Vec<f64> = match chosen.classes.is_empty() {
            true => vec![chosen.scale()],
            false => (self.classes().iter())
                .map(|c| chosen.classes.iter().find(|k| k.class == *c).map_or(chosen.scale(), |k| k.scale))
                .collect(),
        };
        self.before(own, &scales)
    }

    /// `auto:PRESET`, `auto-ml:PRESET` or `auto-ml:PRESET:classes`, as `--prior` takes it.
    pub fn label(&self) -> String {
        let classes = if self.by_class { format!(":{BY_CLASS}") } else { String::new() };
        format!("{}:{}{classes}", self.by.word(), self.preset)
    }

    /// Its entries scaled by `scales` ([`AutoPrior::scaled_by`]), then `own` (which win where
    /// both name a parameter).
    pub fn before(&self, own: &[PriorEntry], scales: &[f64]) -> Vec<PriorEntry> {
        self.scaled_by(scales).into_iter().chain(own.iter().cloned()).collect()
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
    /// The index of the scale chosen (with [`PriorScale::classes`]: of the one scale for every
    /// class, for comparison).
    pub chosen: usize,
    /// `auto-ml:PRESET:classes`: each class's scale and its profile; `log_evidence` is then
    /// the one-scale curve less the largest evidence of the scales per class (its largest
    /// below 0 by what the scales per class gain).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub classes: Vec<ClassScale>,
    /// By the marginal likelihood without a noise model (a marker file fitted by OLS): the
    /// noise level it took, the one the fit's priors weigh against, the residuals' spread
    /// `sqrt(|r|^2 / (N_m - rank))` of the fit without priors (mm).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub noise_spread: Option<f64>,
}

/// A front's marginal likelihood ([`Front::evidence`]): the [`Evidence`] of its system, and
/// the noise level it took where none was given ([`PriorScale::noise_spread`], mm).
#[derive(Debug, Clone, PartialEq)]
pub struct FrontEvidence {
    /// The evidence as a function of the scales.
    pub evidence: Evidence,
    /// The residuals' spread taken as the noise, without a noise model.
    pub noise_spread: Option<f64>,
}

/// One class's scale (`auto-ml:PRESET:classes`), chosen by the marginal likelihood with the
/// other classes' ([`Evidence::class_ascent`]).
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct ClassScale {
    /// The class: a preset entry's target (`lengths`, `angles`, `offsets`, `plays`,
    /// `compliances`).
    pub class: String,
    /// How many estimated parameters have the class's prior.
    pub parameters: usize,
    /// The scale chosen.
    pub scale: f64,
    /// The index of the scale chosen in [`PriorScale::scales`].
    pub chosen: usize,
    /// `log p(y | s)` with this class's scale at each of [`PriorScale::scales`] and the
    /// others' at theirs, less its largest (0 at the scale chosen).
    pub log_evidence: Vec<f64>,
}

impl PriorScale {
    /// The scale chosen (with [`PriorScale::classes`]: the one scale for every class, for
    /// comparison; each class's is in [`ClassScale::scale`]).
    pub fn scale(&self) -> f64 {
        self.scales[self.chosen]
    }

    /// `auto:PRESET`, `auto-ml:PRESET` or `auto-ml:PRESET:classes`, as `--prior` took it.
    pub fn label(&self) -> String {
        let classes = if self.classes.is_empty() { String::new() } else { format!(":{BY_CLASS}") };
        format!("{}:{}{classes}", self.by.word(), self.preset)
    }
}

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
