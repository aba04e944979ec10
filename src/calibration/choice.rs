//! What the choices made from the data are and what they ask of a calibration: `--prior
//! auto`'s scale ([`PriorScale`], chosen by
//! [`choose_prior_scale`](super::prior_scale::choose_prior_scale)), `--select`'s path
//! ([`SelectionPath`], by [`select`](super::selection::select)), a nested cross-validation's
//! choices ([`FoldChoices`]), and [`Front`], the calibration front-end they are written once
//! over (its implementations, observation files and a tree's views, are
//! [`front`](super::front)'s). The types the choices' stages pass between them live here, below
//! the stages, so that [`selection`](super::selection), [`prior_scale`](super::prior_scale) and
//! [`front`](super::front) import them and not each other.

use super::{CalibrationError, Held};
use crate::estimation::evidence::Evidence;
use crate::estimation::{LinearEstimate, PriorEntry};
use std::borrow::Cow;

/// A result of the choices' stages.
type Result<T> = std::result::Result<T, CalibrationError>;

/// Each fold's calibration of a nested cross-validation: the choices made on its training data
/// with its options, and the model chosen calibrated
/// ([`calibrate_chosen`](super::selection::calibrate_chosen)).
pub type FoldFit<'f, F> =
    &'f dyn Fn(&<F as Front>::Data, &<F as Front>::Options) -> Result<ChosenFit<<F as Front>::Fit>>;

/// A calibration front-end: its data, options and calibration, and what the choices made from
/// the data ask of them.
pub trait Front: Sized {
    /// The data calibrated from.
    type Data: Clone;
    /// How to calibrate.
    type Options: Clone;
    /// A calibration.
    type Fit;
    /// A nested cross-validation's report ([`Front::nested`]).
    type Nested;

    /// The data's poses (the folds at most).
    fn poses(data: &Self::Data) -> usize;

    /// The options' prior entries.
    fn prior(options: &mut Self::Options) -> &mut Vec<PriorEntry>;

    /// `options` with the prior `prior` makes of their own entries.
    fn with_prior(
        options: &Self::Options,
        prior: impl FnOnce(&[PriorEntry]) -> Vec<PriorEntry>,
    ) -> Self::Options {
        let mut options = options.clone();
        let own = Self::prior(&mut options);
        *own = prior(own);
        options
    }

    /// `options` asking for the joint parameters `names` only.
    fn with_joints(&self, options: &Self::Options, names: &[String]) -> Self::Options;

    /// Calibrate `data` with `options`.
    fn calibrate(&self, data: &Self::Data, options: &Self::Options) -> Result<Self::Fit>;

    /// What the `t` rule of `--select` reads of `fit`.
    fn fitted(fit: &Self::Fit) -> Fitted<'_>;

    /// The cross-validated RMS of `--prior auto`'s curve (mm), `folds` folds.
    fn cv_rms(&self, data: &Self::Data, options: &Self::Options, folds: usize) -> Result<f64>;

    /// The marginal likelihood ([`FrontEvidence`]) for `auto`'s scale, linearised about `about`
    /// (`None`: the "before" fit), and the noise level it took where none was given.
    fn evidence(
        &self,
        data: &Self::Data,
        options: &Self::Options,
        auto: &AutoPrior,
        about: Option<&Self::Fit>,
    ) -> Result<FrontEvidence>;

    /// Refuse `--select` on `data` before anything is done: a probe's orientations.
    fn refuse_select(_data: &Self::Data) -> Result<()> {
        Ok(())
    }

    /// The forward path of `criterion` (`cv`, `bic`) on one linearisation about "before".
    fn forward(
        &self,
        data: &Self::Data,
        options: &Self::Options,
        criterion: Criterion,
    ) -> Result<SelectionPath>;

    /// The `folds`-fold cross-validation of `fit` (each fold's choices and calibration).
    fn nested(
        &self,
        data: &Self::Data,
        options: &Self::Options,
        folds: usize,
        fit: FoldFit<Self>,
    ) -> Result<Self::Nested>;
}

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
    pub fn parse(text: &str) -> Option<std::result::Result<Self, String>> {
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
    pub(crate) fn class_of(&self, params: &[&crate::model::ParamInfo]) -> Vec<usize> {
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
    /// The scales tried ([`SCALES`], or [`evidence_scales`](crate::estimation::evidence::evidence_scales) for the marginal likelihood).
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

/// How the joint parameters are chosen.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Criterion {
    /// Forward selection by `folds`-fold cross-validated RMS, one-standard-error rule.
    Cv {
        /// Number of folds (at least 2, at most the number of poses).
        folds: usize,
    },
    /// Forward selection by the Bayesian information criterion.
    Bic,
    /// Backward elimination of the estimates within 2 standard errors of zero.
    T,
}

impl Criterion {
    /// The name on the command line: `cv`, `bic`, `t`.
    pub fn name(self) -> &'static str {
        match self {
            Self::Cv { .. } => "cv",
            Self::Bic => "bic",
            Self::T => "t",
        }
    }
}

/// One step of a selection path.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Step {
    /// The parameter added (forward) or dropped (`t`); `None` for the start: the registration
    /// alone (forward), every candidate (`t`).
    pub parameter: Option<String>,
    /// The model's score after the step: its CV RMS (mm), its BIC, or for `t` the dropped
    /// parameter's `|t|` (NaN at the start).
    pub score: f64,
    /// The CV RMS's standard error (mm); NaN for the other criteria.
    pub se: f64,
    /// Why this parameter, when not by its score alone (`t`: a stand-in dropped before the
    /// joint's zero or play it stands in for).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub note: Option<StandInFirst>,
}

impl Step {
    /// Its note in words ([`StandInFirst::text`]), if it has one.
    pub fn note_text(&self) -> Option<String> {
        let parameter = self.parameter.as_deref().unwrap_or("");
        self.note.as_ref().map(|n| n.text(parameter, self.score))
    }
}

/// Why the `t` rule dropped a parameter that is not the weakest: it stands in (alone, or in a
/// group of up to [`STAND_IN_GROUP`](super::selection::STAND_IN_GROUP)) for a joint's zero or play that is weaker still, and
/// a joint's zero and play go last.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct StandInFirst {
    /// The joint's zero or play it stands in for.
    pub stands_in_for: String,
    /// The other parameters of its group, if it stands in with others (empty: alone).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub with: Vec<String>,
    /// The correlation of the zero's or play's estimate with the group's: signed for one
    /// parameter, the multiple correlation (0 to 1) of a group.
    pub correlation: f64,
}

impl StandInFirst {
    /// In words, of the step that dropped `parameter` at `|t|` `t`: `joint4.rz (|t| 0.12)
    /// before joint4.theta, for which it stands in (correlation -1.00): a joint's zero and play
    /// go last`.
    pub fn text(&self, parameter: &str, t: f64) -> String {
        let how = match self.with.is_empty() {
            true => format!("for which it stands in (correlation {:+.2})", self.correlation),
            false => format!(
                "for which it stands in with {} (multiple correlation {:.2})",
                self.with.join(", "),
                self.correlation
            ),
        };
        format!(
            "{parameter} (|t| {t:.2}) before {}, {how}: a joint's zero and play go last",
            self.stands_in_for
        )
    }
}

/// A joint's zero or play left out of the chosen model (a forward path), or dropped by the `t`
/// rule, while chosen parameters that can only stand in for it are in: their estimates
/// correlated with its own by [`STANDS_IN`](super::selection::STANDS_IN) or more (one parameter, or the multiple
/// correlation of a group of up to [`STAND_IN_GROUP`](super::selection::STAND_IN_GROUP)). They carry its error.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Trade {
    /// The joint's zero or play left out.
    pub parameter: String,
    /// Its `|t|` when the `t` rule dropped it; none on a forward path.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub t: Option<f64>,
    /// The chosen parameters that stand in for it, one to [`STAND_IN_GROUP`](super::selection::STAND_IN_GROUP).
    pub stand_ins: Vec<String>,
    /// Their `|t|`, in the same order, under the `t` rule; empty on a forward path.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub stand_in_t: Vec<f64>,
    /// The correlation of its estimate with theirs: signed for one parameter, the multiple
    /// correlation (0 to 1) of a group.
    pub correlation: f64,
}

impl std::fmt::Display for Trade {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let (one, named) = (self.stand_ins.len() == 1, self.stand_ins.join(", "));
        let named_t = || -> Vec<String> {
            (self.stand_ins.iter().zip(&self.stand_in_t))
                .map(|(n, t)| format!("{n} (|t| = {t:.2})"))
                .collect()
        };
        let who = match self.t {
            None if one => format!("{} left out while {named} is in", self.parameter),
            None => format!("{} left out while {named} are in", self.parameter),
            Some(t) if one => {
                format!("{} dropped at |t| = {t:.2} while {} stays", self.parameter, named_t()[0])
            }
            Some(t) => {
                format!("{} dropped at |t| = {t:.2} while {} stay", self.parameter, named_t().join(", "))
            }
        };
        match one {
            true => write!(
                f,
                "{who}, which stands in for it (correlation {:+.2}): {named} carries its error",
                self.correlation
            ),
            false => write!(
                f,
                "{who}, which together stand in for it (multiple correlation {:.2}): they carry its error",
                self.correlation
            ),
        }
    }
}

/// The path of a selection and the parameters it chose.
#[derive(Debug, Clone, PartialEq)]
pub struct SelectionPath {
    /// How they were chosen.
    pub criterion: Criterion,
    /// Every step, the start first.
    pub steps: Vec<Step>,
    /// The step chosen: the model is the start and the steps up to it.
    pub chosen: usize,
    /// The joint parameters of the chosen model, in canonical order.
    pub selected: Vec<String>,
    /// The parameters asked for that are held, not candidates, each with why in words: the
    /// gauge's (the poses cannot tell them apart from the others, with the combination), an
    /// unloaded compliance's, and for `t` those of `--hold`.
    pub held: Vec<String>,
    /// Each joint's zero or play left out while chosen parameters that stand in for it are in
    /// ([`Trade`]): the error the zero or play would carry is carried by them.
    pub trades: Vec<Trade>,
}

impl SelectionPath {
    /// `options` of `front` asking for the selected parameters only ([`Front::with_joints`]).
    pub fn options<F: Front>(&self, front: &F, options: &F::Options) -> F::Options {
        front.with_joints(options, &self.selected)
    }
}

/// A calibration with the choices made from its data ([`calibrate_chosen`](super::selection::calibrate_chosen)).
#[derive(Debug, Clone)]
pub struct ChosenFit<C> {
    /// The scale of the preset, and its curve.
    pub scale: Option<PriorScale>,
    /// The selection's path.
    pub path: Option<SelectionPath>,
    /// The calibration with the options chosen.
    pub calibration: C,
}

/// What the folds of a nested cross-validation chose, fold by fold.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct FoldChoices {
    /// With a selection: the joint parameters each fold's selection chose.
    pub selected: Vec<Vec<String>>,
    /// With `--prior auto`: the scale each fold chose (none with a scale per class,
    /// `auto-ml:PRESET:classes`).
    pub scales: Vec<f64>,
}

impl FoldChoices {
    /// The next fold's choices: its selection and its one prior scale, where it made them.
    pub(crate) fn push<C>(&mut self, chosen: &ChosenFit<C>) {
        self.selected.extend(chosen.path.as_ref().map(|p| p.selected.clone()));
        // A scale per class (auto-ml:PRESET:classes) is no one number: not listed.
        self.scales.extend(chosen.scale.as_ref().filter(|s| s.classes.is_empty()).map(|s| s.scale()));
    }
}

/// A nested k-fold cross-validation of observation files or a tree's views
/// ([`cross_validate_choices`](super::selection::cross_validate_choices)): the held-out observations scored, each with its fold's
/// calibration, and what each fold chose.
#[derive(Debug, Clone, PartialEq)]
pub struct Nested<S> {
    /// The held-out observations scored.
    pub score: S,
    /// What each fold chose.
    pub choices: FoldChoices,
}

/// A calibration as the `t` rule of [`select`](super::selection::select) reads it ([`Front::fitted`]).
pub struct Fitted<'a> {
    /// Its parameters.
    pub params: Cow<'a, crate::model::ParamSet>,
    /// Their values before and after (full vectors).
    pub values: (Cow<'a, [f64]>, &'a [f64]),
    /// Its estimate.
    pub estimate: &'a LinearEstimate,
    /// What it held.
    pub fixed: &'a [Held],
}
