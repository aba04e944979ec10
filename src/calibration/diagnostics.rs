//! What a calibration warns of, as typed values: one per cause, with what it concerns (the
//! parameter, the observations and their lines), which the reports render as text and write
//! as JSON. Nothing downstream matches the text.

use serde::Serialize;
use std::fmt;

/// A joint length corrected by more than this (mm) is suspect: check the model and the units.
pub const LARGE_CORRECTION_MM: f64 = 10.0;

/// A joint angle corrected by more than this (deg) is suspect: a joint zero or an axis far off.
pub const LARGE_ANGLE_DEG: f64 = 5.0;

/// A revolute joint's play beyond this (deg) is suspect: it absorbs something else.
pub const LARGE_PLAY_DEG: f64 = 1.0;

/// An observation is flagged when its whitened residual `z = r / sigma` (`sigma` from
/// `V_k`) exceeds this many standard deviations times the set's robust scale when above 1
/// (`median(|z|) / 0.6745`, [`robust`](super::robust)): when every observation lies further
/// out than `V_k` says, as when a gross error pulls the fit, one is flagged only if it stands
/// out from the others.
pub const FLAG_AT: f64 = 5.0;

/// Far-out observations listed in the text (the worst first; every one in the JSON).
pub const LISTED: usize = 5;

/// The physical range an estimate of a real arm stays within, whatever its standard error.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Bound {
    /// A joint length or a joint origin's shift corrected by at most [`LARGE_CORRECTION_MM`].
    Length,
    /// A joint angle (offset, twist, `beta`, an origin's turn) corrected by at most
    /// [`LARGE_ANGLE_DEG`].
    Angle,
    /// A revolute joint's compliance at most [`SOFTEST_COMPLIANCE`](super::SOFTEST_COMPLIANCE)
    /// (a stiffness of 1000 N·m/rad or more).
    Stiffness,
    /// A compliance of at least 0.
    Negative,
    /// A revolute joint's play within [`LARGE_PLAY_DEG`] of 0.
    Play,
}

/// An estimate outside its [`Bound`], with its 95% interval, in the report's units (mm, deg,
/// rad/N·m or mm/N).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct OutOfRange {
    /// Its name (`j2.theta`).
    pub parameter: String,
    /// A length's or an angle's correction; a compliance's or a play's value.
    pub value: f64,
    /// `value - 1.96 SE`; NaN (null in JSON) without a standard error.
    pub low: f64,
    /// `value + 1.96 SE`; NaN (null in JSON) without a standard error.
    pub high: f64,
    /// Its unit.
    pub unit: &'static str,
}

impl OutOfRange {
    /// `j2.theta -80.000 deg (95% -85.000 to -75.000)`; a compliance in scientific notation
    /// with its stiffness.
    fn text(&self) -> String {
        let compliance = self.unit.contains('/');
        let number = |v: f64| if compliance { format!("{v:.3e}") } else { format!("{v:.3}") };
        let interval = if self.low.is_finite() && self.high.is_finite() {
            format!("95% {} to {}", number(self.low), number(self.high))
        } else {
            "no standard error".to_string()
        };
        let stiffness = if self.unit == "rad/N·m" && self.value > 0.0 {
            format!("a stiffness of {:.4} N·m/rad; ", 1.0 / self.value)
        } else {
            String::new()
        };
        format!("{} {} {} ({stiffness}{interval})", self.parameter, number(self.value), self.unit)
    }
}

impl Bound {
    /// What the estimates past it are, by their number, and what to do.
    fn describe(self, count: usize) -> (String, &'static str) {
        let s = if count == 1 { "" } else { "s" };
        match self {
            Self::Length => (
                format!("joint length{s} corrected by more than {LARGE_CORRECTION_MM} mm"),
                "check the model and the units",
            ),
            Self::Angle => (
                format!("joint angle{s} corrected by more than {LARGE_ANGLE_DEG} deg"),
                "a joint zero or an axis this far off: check the model's zeros and conventions",
            ),
            Self::Stiffness => (
                format!(
                    "compliance{s} above {:e} rad/N·m (a stiffness below {:.0} N·m/rad)",
                    super::SOFTEST_COMPLIANCE,
                    1.0 / super::SOFTEST_COMPLIANCE
                ),
                "softer than a real joint: it absorbs something else (geometry, play, masses)",
            ),
            Self::Negative => (
                format!("negative compliance{s}"),
                "no joint has one: it absorbs something else (geometry, play, masses)",
            ),
            Self::Play => (
                format!("play{s} beyond {LARGE_PLAY_DEG} deg"),
                "more than a real joint's: it absorbs something else (an offset, a compliance)",
            ),
        }
    }
}

/// One training observation (a pose, an observation row or a view) far out after calibration.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FarOut {
    /// Its index in the training set (to find its file among several).
    pub index: usize,
    /// Its line in its file.
    pub line: usize,
    /// What it is, when a set mixes kinds (`point`, `marker 2 z`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub label: Option<String>,
    /// Its whitened residual, in standard deviations (its largest component for a pose).
    pub sd: f64,
}

/// What is far out: the unit a set is scored by.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Scored {
    /// A pose of markers or a probe.
    Pose,
    /// One observation (a distance, a contact, a coordinate, a camera's row).
    Observation,
    /// A camera's view of a tree.
    View,
}

impl Scored {
    /// Its name, singular or plural.
    fn name(self, count: usize) -> &'static str {
        match (self, count) {
            (Self::Pose, 1) => "pose",
            (Self::Pose, _) => "poses",
            (Self::Observation, 1) => "observation",
            (Self::Observation, _) => "observations",
            (Self::View, 1) => "view",
            (Self::View, _) => "views",
        }
    }
}

/// A variance component of feasible GLS that moved in its last re-weighting by more than the
/// tolerance ([`Warning::NoiseUnsettled`]).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ComponentMove {
    /// Its name: `joint 2`, a joint pair's covariance `joint 2, joint 3`, a measurement class's
    /// `sigma_*`.
    pub component: String,
    /// The change `|theta_after - theta_before|` over its standard error.
    pub by: f64,
    /// Whether its estimate lies within one standard error of 0: the data barely determine it.
    pub barely_determined: bool,
}

impl ComponentMove {
    /// [`Warning::NoiseUnsettled`] in full: the re-weightings made, then each component that
    /// `moving` says moved by more than `tolerance` of its standard error.
    fn unsettled_text(reweightings: usize, tolerance: f64, moving: &[Self]) -> String {
        let moves: Vec<String> = moving.iter().map(Self::text).collect();
        let why = match moves.is_empty() {
            true => String::new(),
            false => format!(
                "; in the last one moved by more than {tolerance} of their standard error: {}",
                moves.join(", ")
            ),
        };
        format!("feasible GLS: the variance components did not settle in {reweightings} re-weightings{why}")
    }

    /// In words: `sigma_orientation (by 0.09; within one standard error of 0: the data barely
    /// determine it)`.
    fn text(&self) -> String {
        let barely = match self.barely_determined {
            true => "; within one standard error of 0: the data barely determine it",
            false => "",
        };
        format!("{} (by {:.2}{barely})", self.component, self.by)
    }
}

/// A warning about a calibration: one per cause.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(tag = "cause", rename_all = "snake_case")]
#[non_exhaustive]
pub enum Warning {
    /// Estimates outside a physical [`Bound`], whatever their standard errors: every one, the
    /// largest first.
    Implausible {
        /// The range they left.
        bound: Bound,
        /// Each with its 95% interval.
        estimates: Vec<OutOfRange>,
    },
    /// The fit stopped at its step limit before a stopping rule was met: its estimates and
    /// standard errors are where it stopped, not a minimum's.
    NotConverged {
        /// The steps taken.
        steps: usize,
        /// The last step's size: the largest change of a whitened prediction it made
        /// (standard deviations).
        last_step: f64,
        /// The cost's fall in that step, as a fraction of the cost.
        last_fall: f64,
    },
    /// Training observations more than [`FLAG_AT`] standard deviations out after
    /// calibration, the worst first.
    FarOut {
        /// What they are.
        scored: Scored,
        /// Every one of them.
        observations: Vec<FarOut>,
    },
    /// The identified system's scaled condition number above
    /// [`CONDITION_WARNING`](super::CONDITION_WARNING).
    IllConditioned {
        /// The condition number.
        condition_number: f64,
    },
    /// Feasible GLS: the variance components did not settle.
    NoiseUnsettled {
        /// The re-weightings made.
        reweightings: usize,
        /// The largest change allowed a settled component, in its standard errors.
        tolerance: f64,
        /// The components that still moved by more in the last re-weighting.
        moving: Vec<ComponentMove>,
    },
    /// Feasible GLS ignored the data's sigma column (of observation files, their sigma columns).
    SigmaIgnored,
    /// The noise given disagrees with the residuals by more than a factor
    /// [`NOISE_FACTOR`](super::noise_check::NOISE_FACTOR).
    NoiseDisagrees(NoiseDisagrees),
    /// The gauge found at the estimate kept other parameters than the start's
    /// (the module `calibration::regauge`): the fit was made again from the estimate with it. The
    /// estimates are those of the estimate's gauge; from another start they would be the same.
    GaugeMoved {
        /// Held at the start, estimated (the estimate identifies them).
        freed: Vec<String>,
        /// Estimated at the start, held (the estimate cannot tell them from the others).
        held: Vec<String>,
        /// The gauges found after the start's.
        rounds: usize,
    },
    /// Training poses with joint values outside the robot's limits (the model's or the URDF's):
    /// a calibration there extrapolates the model.
    OutsideLimits {
        /// The robot's name.
        robot: String,
        /// Every one of them, in the files' order.
        poses: Vec<OutsidePose>,
    },
}

/// What the residuals say of the noise given ([`super::noise_check`]).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct NoiseDisagrees {
    /// The factor of the joint sigmas the residuals say (REML); none without joint noise.
    pub joint_factor: Option<f64>,
    /// The factor of the measurement sigmas.
    pub measurement_factor: f64,
    /// The whitened residuals' standard deviation with the noise given (1 if it is right).
    pub whitened_sd: f64,
    /// The folds of the cross-validated errors.
    pub folds: usize,
    /// The k-fold CV RMS (mm) with the sigmas given, linearised about the fit.
    pub cv_given: f64,
    /// The same with the sigmas times their factors.
    pub cv_estimated: f64,
    /// How far the estimate moves from the sigmas given to the estimated ones: the largest
    /// change of a parameter over its standard error (linearised about the fit).
    pub estimate_shift: f64,
}

/// An estimate moving by less than this many of its standard errors with the noise barely
/// moves ([`NoiseDisagrees::shift_text`]).
pub const BARELY_MOVES: f64 = 0.1;

impl NoiseDisagrees {
    /// Whether the estimate moves with the noise, in words: `the estimate moves with them by up
    /// to 1.52 standard errors`, or below [`BARELY_MOVES`] `the estimate barely moves with them
    /// (by at most 0.03 standard errors)`.
    pub fn shift_text(&self) -> String {
        match self.estimate_shift < BARELY_MOVES {
            true => format!(
                "the estimate barely moves with them (by at most {:.3} standard errors)",
                self.estimate_shift
            ),
            false => {
                format!("the estimate moves with them by up to {:.2} standard errors", self.estimate_shift)
            }
        }
    }

    /// `the joint sigmas x0.45 and the measurement sigmas x2.31`.
    fn factors(&self) -> String {
        let measurement = format!("the measurement sigmas x{:.3}", self.measurement_factor);
        match self.joint_factor {
            Some(j) => format!("the joint sigmas x{j:.3} and {measurement}"),
            None => measurement,
        }
    }
}

/// What a [`Warning`] is about, as its JSON `cause` names it: the key a report counts warnings
/// by.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Cause {
    /// [`Warning::Implausible`].
    Implausible,
    /// [`Warning::NotConverged`].
    NotConverged,
    /// [`Warning::FarOut`].
    FarOut,
    /// [`Warning::IllConditioned`].
    IllConditioned,
    /// [`Warning::NoiseUnsettled`].
    NoiseUnsettled,
    /// [`Warning::SigmaIgnored`].
    SigmaIgnored,
    /// [`Warning::NoiseDisagrees`].
    NoiseDisagrees,
    /// [`Warning::GaugeMoved`].
    GaugeMoved,
    /// [`Warning::OutsideLimits`].
    OutsideLimits,
}

impl Warning {
    /// Its cause.
    pub fn cause(&self) -> Cause {
        match self {
            Self::Implausible { .. } => Cause::Implausible,
            Self::NotConverged { .. } => Cause::NotConverged,
            Self::FarOut { .. } => Cause::FarOut,
            Self::IllConditioned { .. } => Cause::IllConditioned,
            Self::NoiseUnsettled { .. } => Cause::NoiseUnsettled,
            Self::SigmaIgnored => Cause::SigmaIgnored,
            Self::NoiseDisagrees(_) => Cause::NoiseDisagrees,
            Self::GaugeMoved { .. } => Cause::GaugeMoved,
            Self::OutsideLimits { .. } => Cause::OutsideLimits,
        }
    }

    /// How many things it concerns: the estimates past a bound, the far-out observations; 1
    /// for the others.
    pub fn count(&self) -> usize {
        match self {
            Self::Implausible { estimates, .. } => estimates.len(),
            Self::FarOut { observations, .. } => observations.len(),
            Self::OutsideLimits { poses, .. } => poses.len(),
            _ => 1,
        }
    }

    /// What it is about in a few words, without the items (which [`fmt::Display`] lists):
    /// `joint lengths corrected by more than 10 mm`, `training poses more than 5 standard
    /// deviations out after calibration`.
    pub fn headline(&self) -> String {
        match self {
            Self::Implausible { bound, estimates } => bound.describe(estimates.len()).0,
            Self::NotConverged { steps, .. } => {
                format!("not converged in {steps} steps (raise --iterations)")
            }
            Self::FarOut { scored, observations } => format!(
                "training {} more than {} standard deviations out after calibration",
                scored.name(observations.len()),
                super::FLAG_AT
            ),
            Self::IllConditioned { condition_number } => {
                format!(
                    "scaled condition number {condition_number:.3e}, above {:e}",
                    super::CONDITION_WARNING
                )
            }
            Self::NoiseUnsettled { reweightings, moving, .. } => {
                let names: Vec<&str> = moving.iter().map(|m| m.component.as_str()).collect();
                let still = if names.is_empty() {
                    String::new()
                } else {
                    format!(" ({} still moving)", names.join(", "))
                };
                format!(
                    "feasible GLS: variance components not settled in {reweightings} re-weightings{still}"
                )
            }
            Self::SigmaIgnored => "feasible GLS ignored the sigma column".to_string(),
            Self::NoiseDisagrees(n) => format!("the residuals say {}", n.factors()),
            Self::GaugeMoved { .. } => "the gauge found again at the estimate".to_string(),
            Self::OutsideLimits { robot, poses } => {
                let poses = if poses.len() == 1 { "pose" } else { "poses" };
                format!("training {poses} with joint values outside the limits of {robot}")
            }
        }
    }

    /// The far-out ones of `scored` (`(index, line, label, sd)`), worst first; `None` if none.
    pub fn far_out(scored: Scored, found: impl IntoIterator<Item = FarOut>) -> Option<Self> {
        let mut observations: Vec<FarOut> = found.into_iter().collect();
        observations.sort_by(|a, b| b.sd.abs().total_cmp(&a.sd.abs()).then(a.index.cmp(&b.index)));
        (!observations.is_empty()).then_some(Self::FarOut { scored, observations })
    }

    /// The text, each far-out observation's line by `line` (its index, its line: the file's
    /// name where several were fitted).
    pub fn render(&self, line: &dyn Fn(usize, usize) -> String) -> String {
        let Self::FarOut { scored, observations } = self else { return self.to_string() };
        let one = |o: &FarOut| {
            let label = o.label.as_ref().map_or(String::new(), |l| format!(" ({l})"));
            format!("{}{label}", line(o.index, o.line))
        };
        if let [o] = observations.as_slice() {
            return format!(
                "{}: a residual {:.1} standard deviations out after calibration",
                one(o),
                o.sd.abs()
            );
        }
        let listed: Vec<String> =
            observations.iter().take(LISTED).map(|o| format!("{} ({:.1})", one(o), o.sd.abs())).collect();
        let more = if observations.len() > LISTED { ", ..." } else { "" };
        format!(
            "{} training {} more than {} standard deviations out after calibration, the worst: {}{more} (every one in --json)",
            observations.len(),
            scored.name(observations.len()),
            super::FLAG_AT,
            listed.join(", ")
        )
    }
}

impl fmt::Display for Warning {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Implausible { bound, estimates } => {
                let (what, why) = bound.describe(estimates.len());
                let listed: Vec<String> = estimates.iter().take(LISTED).map(OutOfRange::text).collect();
                let more = if estimates.len() > LISTED { ", ... (every one in --json)" } else { "" };
                let count =
                    if estimates.len() == 1 { String::new() } else { format!("{} ", estimates.len()) };
                write!(f, "{count}{what}, whatever the standard error: {}{more}; {why}", listed.join(", "))
            }
            Self::NotConverged { steps, last_step, last_fall } => write!(
                f,
                "not converged in {steps} steps: the last moved a prediction by {last_step:.3e} standard deviations and lowered the cost by {last_fall:.3e} of itself; the estimates and their standard errors are where the fit stopped, not those of an identified minimum (raise --iterations)"
            ),
            Self::FarOut { .. } => f.write_str(&self.render(&|_, line| format!("line {line}"))),
            Self::IllConditioned { condition_number } => write!(
                f,
                "the identified system's scaled condition number is {condition_number:.3e}, above {:e}: the estimates are poorly determined; measure more varied poses or identify fewer parameters",
                super::CONDITION_WARNING
            ),
            Self::NoiseUnsettled { reweightings, tolerance, moving } => {
                f.write_str(&ComponentMove::unsettled_text(*reweightings, *tolerance, moving))
            }
            Self::SigmaIgnored => f.write_str(
                "feasible GLS ignored the sigma column: it estimates the measurement noise itself",
            ),
            Self::NoiseDisagrees(n) => write!(
                f,
                "the noise given disagrees with the residuals: their REML estimate is {} (whitened residual SD \
                 {:.3}, 1 if the noise were right); the weights and every prior's strength follow the sigmas: \
                 {}-fold CV RMS {:.4} mm with the sigmas given, {:.4} mm with the estimated ones, and {} \
                 (linearised about the fit); give the noise measured (robocal repeatability) or estimate it \
                 (--estimator fgls)",
                n.factors(),
                n.whitened_sd,
                n.folds,
                n.cv_given,
                n.cv_estimated,
                n.shift_text()
            ),
            Self::GaugeMoved { freed, held, rounds } => {
                let list = |v: &[String]| if v.is_empty() { "nothing".to_string() } else { v.join(", ") };
                write!(
                    f,
                    "the gauge found at the estimate is not the start's: estimated {} and held {} that the start's \
                     gauge held and estimated ({rounds} fit(s) again from the estimate); the estimates no longer \
                     depend on the start",
                    list(freed),
                    list(held)
                )
            }
            Self::OutsideLimits { robot, poses } => {
                let listed: Vec<String> = poses
                    .iter()
                    .take(LISTED)
                    .map(|p| format!("{} ({})", p.line, p.joints.join(", ")))
                    .collect();
                let more = if poses.len() > LISTED {
                    format!(" and {} more", poses.len() - LISTED)
                } else {
                    String::new()
                };
                write!(
                    f,
                    "joint values outside the limits of {robot} at line {}{more}: the calibration extrapolates \
                     the model there",
                    listed.join(", ")
                )
            }
        }
    }
}

/// A training pose with joint values outside the robot's limits.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct OutsidePose {
    /// Its line in the file.
    pub line: usize,
    /// The joints outside their limits, by name.
    pub joints: Vec<String>,
}

impl Warning {
    /// The training poses (`(line, joint values)`, rad and mm) whose values of `joints` lie
    /// outside their limits, of the robot `robot`; `None` if none does.
    pub fn outside_limits<'a>(
        robot: &str,
        joints: &[crate::model::Joint],
        poses: impl IntoIterator<Item = (usize, &'a [f64])>,
    ) -> Option<Self> {
        let poses: Vec<OutsidePose> = (poses.into_iter())
            .filter_map(|(line, q)| {
                let outside = crate::model::outside_limits(joints, q);
                let joints = outside.iter().map(|j| j.to_string()).collect();
                (!outside.is_empty()).then_some(OutsidePose { line, joints })
            })
            .collect();
        (!poses.is_empty()).then(|| Self::OutsideLimits { robot: robot.to_string(), poses })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn far(index: usize, sd: f64) -> FarOut {
        FarOut { index, line: index + 3, label: None, sd }
    }

    /// One far-out observation reads as one; many, as one warning with their count and the
    /// worst few.
    #[test]
    fn far_out_observations_are_one_warning_with_a_count() {
        assert_eq!(Warning::far_out(Scored::Pose, []), None);
        let one = Warning::far_out(Scored::Pose, [far(4, -6.04)]).unwrap();
        assert_eq!(one.to_string(), "line 7: a residual 6.0 standard deviations out after calibration");
        let many =
            Warning::far_out(Scored::Observation, (0..360).map(|k| far(k, 5.5 + k as f64 / 100.0))).unwrap();
        let text = many.to_string();
        assert!(text.starts_with("360 training observations more than 5 standard deviations out"), "{text}");
        assert!(text.contains("the worst: line 362 (9.1), line 361 (9.1), line 360 (9.1)"), "{text}");
        assert!(text.ends_with(", ... (every one in --json)"), "{text}");
        let Warning::FarOut { observations, .. } = many else { panic!() };
        assert_eq!(observations.len(), 360);
    }
}

/// A parameter a calibration held (did not estimate), and why: typed, so that a report renames
/// its parameters (`marker3.x` to `tool.x`) without touching its words, and the JSON carries
/// the kind, the parameter and a combination's coefficients. [`Held::text`] renders it.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
#[non_exhaustive]
pub enum Held {
    /// Held by `--hold`: a robot parameter at its nominal value, a set-up one at its start.
    ByUser {
        /// The parameter.
        parameter: String,
        /// Whether a set-up parameter (held at its start) rather than the robot's.
        setup: bool,
    },
    /// No observation moves it: its column of `H` is zero.
    Unmoved {
        /// The parameter.
        parameter: String,
    },
    /// No observation can see it, for a reason the data give (a tree's joint on the way to both
    /// frames of every view; a point's orientation).
    Unseen {
        /// The parameter.
        parameter: String,
        /// Why, in words (after the parameter's name and a colon).
        why: String,
    },
    /// Of a combination the poses cannot tell apart, `parameter + sum c_i name_i`: this
    /// parameter is held, the others estimated.
    Combination {
        /// The parameter held.
        parameter: String,
        /// The combination's other terms: (parameter, coefficient).
        terms: Vec<(String, f64)>,
    },
    /// Contacts alone cannot see the robot's scale, which this longest length sets.
    Scale {
        /// The length held.
        parameter: String,
    },
    /// Of a combination the poses cannot tell apart, `parameter + sum c_i name_i`, held so
    /// that the others stay free, with what the combination shares its effect with (a marker
    /// file's gauge: the base, the markers, the parameters of `--keep`, or the poses).
    Confounded {
        /// The parameter held.
        parameter: String,
        /// The combination's other terms: (parameter, coefficient).
        terms: Vec<(String, f64)>,
        /// What its effect is also: the flag that frees it follows from it.
        with: Confounder,
    },
    /// A compliance or play whose joint gravity does not load at these poses (a vertical axis).
    Unloaded {
        /// The parameter.
        parameter: String,
    },
}

/// What a held combination's effect is also, and so the flag that frees it
/// ([`Held::Confounded`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
#[non_exhaustive]
pub enum Confounder {
    /// It is not a joint's: held so that the parameters of `--keep` stay free.
    Keep,
    /// With the base estimated, it only moves the whole robot (`--fixed-base` frees it).
    Base,
    /// With the markers estimated, it only moves the markers (`--fixed-markers` frees it).
    Markers,
    /// These poses cannot tell it from the others' (other poses, or `--keep`, free it).
    Poses,
}

impl Held {
    /// The parameter held.
    pub fn parameter(&self) -> &str {
        match self {
            Self::ByUser { parameter, .. }
            | Self::Unmoved { parameter }
            | Self::Unseen { parameter, .. }
            | Self::Combination { parameter, .. }
            | Self::Confounded { parameter, .. }
            | Self::Unloaded { parameter }
            | Self::Scale { parameter } => parameter,
        }
    }

    /// The same, every parameter named by `rename` (the held one and a combination's terms).
    pub fn renamed(mut self, rename: impl Fn(&str) -> String) -> Self {
        match &mut self {
            Self::ByUser { parameter, .. }
            | Self::Unmoved { parameter }
            | Self::Unseen { parameter, .. }
            | Self::Unloaded { parameter }
            | Self::Scale { parameter } => *parameter = rename(parameter),
            Self::Combination { parameter, terms } | Self::Confounded { parameter, terms, .. } => {
                *parameter = rename(parameter);
                for (name, _) in terms {
                    *name = rename(name);
                }
            }
        }
        self
    }

    /// In words, one line: `j6.d: held at its nominal value by --hold`, or a combination as
    /// `j1.d - 0.5 point1.z`.
    pub fn text(&self) -> String {
        match self {
            Self::Combination { parameter, terms } | Self::Confounded { parameter, terms, .. } => {
                let terms = terms.iter().map(|(name, c)| (name.as_str(), *c));
                let combination = crate::estimation::combination_text(parameter, terms);
                match self {
                    Self::Confounded { with, .. } => format!("{combination}: {}", with.advice(parameter)),
                    _ => combination,
                }
            }
            _ => self.reason().map(|(parameter, why)| format!("{parameter}: {why}")).unwrap_or_default(),
        }
    }

    /// Of a parameter held alone, not in a combination: the parameter and why, in words.
    fn reason(&self) -> Option<(&str, String)> {
        let (parameter, why) = match self {
            Self::ByUser { parameter, setup: false } => (parameter, "held at its nominal value by --hold".into()),
            Self::ByUser { parameter, setup: true } => (parameter, "held at its start by --hold".into()),
            Self::Unmoved { parameter } => (parameter, "the observations do not move it".into()),
            Self::Unseen { parameter, why } => (parameter, why.clone()),
            Self::Scale { parameter } => (
                parameter,
                "held at its nominal value: contacts alone cannot see the robot's scale, which this longest length \
                 sets"
                    .into(),
            ),
            Self::Unloaded { parameter } => {
                (parameter, "gravity does not load its joint at these poses (a vertical axis?)".into())
            }
            Self::Combination { .. } | Self::Confounded { .. } => return None,
        };
        Some((parameter.as_str(), why))
    }
}

impl Confounder {
    /// Why `parameter` is held, and the flag that frees it, in words.
    pub fn advice(self, parameter: &str) -> String {
        match self {
            Self::Keep => "held so that the parameters of --keep stay free".to_string(),
            Self::Base => format!(
                "with the base estimated it only moves the whole robot: --fixed-base (if the measuring frame is \
                 the robot's) or --keep {parameter} frees it"
            ),
            Self::Markers => format!(
                "with the markers estimated it only moves the markers: --fixed-markers (if their positions are \
                 known) or --keep {parameter} frees it"
            ),
            Self::Poses => {
                format!(
                    "these poses cannot tell it from the others: vary them, or --keep {parameter} to hold another"
                )
            }
        }
    }
}

/// What a calibration's observations cannot see as a whole, held, and why (a parameter held
/// alone is a [`Held`]): typed, so that the JSON carries the kind and its values and the text
/// is rendered from them ([`fmt::Display`]).
#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
#[non_exhaustive]
pub enum Unseen {
    /// An arm's base placement (6 parameters), held at its nominal value: what the
    /// observations are relative to absorbs it.
    Base {
        /// What absorbs it.
        absorbed_by: BaseAbsorber,
    },
    /// The robot's scale: contacts alone cannot see it (every length and plane offset times one
    /// factor leaves every contact); its longest length is held.
    Scale,
    /// A plane's motions within it (translations along it, rotation about its normal).
    Plane {
        /// The plane's number, from 1.
        plane: usize,
        /// Its calibrated unit normal.
        normal: [f64; 3],
        /// Its calibrated offset (mm).
        offset_mm: f64,
    },
    /// The coordinates' device placement along the axes it does not measure, held at the
    /// markers' frame.
    Device {
        /// The parameters held (`device.x`, `device.rz`, ...).
        parameters: Vec<String>,
    },
    /// A tree's base placement (`base.*`), held: a view sees one frame relative to another.
    TreeBase {
        /// The frame placed in the root link's frame, which absorbs the tree's placement, if
        /// one is (`camera.world`).
        world: Option<String>,
    },
}

/// What absorbs an arm's base placement ([`Unseen::Base`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
#[non_exhaustive]
pub enum BaseAbsorber {
    /// A camera on the arm sees the target relative to the robot only: the target's placement.
    Target,
    /// A fixed camera sees the robot relative to itself only: the camera's placement.
    Camera,
    /// Distances: a rigid motion of the whole set-up changes none.
    Distances,
    /// Plane contacts: the planes.
    Planes,
}

impl fmt::Display for Unseen {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Base { absorbed_by } => {
                let why = match absorbed_by {
                    BaseAbsorber::Target => {
                        "a camera on the arm sees the target relative to the robot only (base^-1 target): the target \
                         placement absorbs the base placement"
                    }
                    BaseAbsorber::Camera => {
                        "a fixed camera sees the robot relative to itself only (camera^-1 base): the camera placement \
                         absorbs the base placement"
                    }
                    BaseAbsorber::Distances => {
                        "distances cannot see the base placement (a rigid motion of the whole set-up changes no distance)"
                    }
                    BaseAbsorber::Planes => "the planes absorb the base placement",
                };
                write!(f, "base (6 parameters): {why}; held at its nominal value")
            }
            Self::Scale => f.write_str(
                "scale: contacts alone cannot see it (every length and plane offset times one factor leaves every \
                 contact); the robot's longest length is held at its nominal value: add a distance to see it",
            ),
            Self::Plane { plane, normal: [x, y, z], offset_mm } => write!(
                f,
                "plane {plane}: normal ({x:.4}, {y:.4}, {z:.4}), offset {offset_mm:.3} mm; contacts cannot see motions \
                 within it (translations along it, rotation about its normal)"
            ),
            Self::Device { parameters } => write!(
                f,
                "{}: the coordinates' device (its placement in the markers' frame) is seen only along the axes it \
                 measures; held at the markers' frame",
                parameters.join(", ")
            ),
            Self::TreeBase { world: Some(frame) } => write!(
                f,
                "base.*: {frame} is placed in the root link's frame, which absorbs the tree's placement: the base is held"
            ),
            Self::TreeBase { world: None } => f.write_str(
                "base.*: a view sees one frame relative to another, never the tree's placement: the base is held",
            ),
        }
    }
}
