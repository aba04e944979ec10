//! The report of every calibration ([`Calibration`]): of an arm from markers, a probe,
//! distances, contacts, coordinates and cameras' views ([`crate::calibration::kinds`]), or of a
//! tree from views between its branches ([`crate::calibration::tree`]). Parameters with their
//! standard errors (the set-up's too), what the observations cannot see, the RMS residuals
//! before and after on the training and the held-out files, the worst observations (a tree's
//! views) and those flagged; a tree's cameras and targets as calibrated. Text and JSON carry
//! the same content.

use super::calibration::{DownWeighted, ParameterRow, by_number};
use super::verdict::QuantityRow;
use crate::calibration::Warning;
use crate::calibration::kinds::{
    Calibration, DEFAULT_CAMERA_SIGMA_DEG, DEFAULT_CAMERA_SIGMA_MM, DEFAULT_SIGMA_ANGLE_DEG,
    DEFAULT_SIGMA_MM, GroupRms, Robot, Score, SessionSetUp, ViewResidual,
};
use crate::calibration::prior_scale::PriorScale;
use crate::calibration::selection::SelectionPath;
use crate::calibration::tree::TreeCalibration;
use crate::estimation::{Estimator, POSE_SIGMAS};
use crate::model::{Joint, RobotModel, RobotTree};
use serde::Serialize;
use std::cmp::Ordering;
use std::fmt::Write;

/// The version of the calibration report's JSON: 3, the one report of every calibration
/// (version 2 was a marker file's own report, version 1 had no `schema`).
pub const SCHEMA: u32 = 3;

/// Everything the report says, in the order the JSON writes it: the verdict first, then what
/// was fitted, the parameters, what was held, and the detail. Angles in degrees, lengths in
/// millimetres.
#[derive(Debug, Clone, Serialize)]
pub struct ObservationsReport {
    /// The JSON's version: [`SCHEMA`], for the order and keys of docs/formats.md.
    pub schema: u32,
    /// What the report leads with: each set's errors before and after calibration, a row per
    /// quantity, counted and flagged (the text's and the page's verdict table).
    pub verdict: Vec<super::verdict::QuantityRow>,
    /// The model's name.
    pub model: String,
    /// A tree's: its branches, its joints, and its cameras and targets as calibrated.
    #[serde(flatten, skip_serializing_if = "Option::is_none")]
    pub tree: Option<TreeParts>,
    /// The observation files.
    pub data: String,
    /// Observations fitted (a tree's: views).
    pub observations: usize,
    /// Poses they were made at.
    pub poses: usize,
    /// With marker positions alone (and a probe's orientations): how many markers were
    /// fitted, as the headline counts them (`100 poses, 2 markers`); `None` when other
    /// observations are fitted too.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub markers: Option<usize>,
    /// The estimator's name.
    pub estimator: String,
    /// Gauss-Newton steps taken.
    pub iterations: usize,
    /// Whether a stopping rule was met (with feasible GLS, and the variance components settled).
    pub converged: bool,
    /// Feasible GLS: whether its variance components settled.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub noise_settled: Option<bool>,
    /// With markers: the base their registration placed, `[x, y, z]` mm then roll, pitch, yaw
    /// deg, which the `base.*` estimates correct.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub registered_base: Option<[f64; 6]>,
    /// A 6-DOF probe's calibrated frame, absolute, in the tip link's frame (the model's marker
    /// frame; the last joint's frame of a DH model): `[x, y, z]` mm then roll, pitch, yaw deg.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub tip_frame: Option<[f64; 6]>,
    /// The estimated parameters, the robot's then the set-up's (`point1.x`, `plane1.d`, ...).
    pub parameters: Vec<ParameterRow>,
    /// Each estimated compliance as a stiffness with its 95% interval.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub stiffness: Vec<super::calibration::StiffnessRow>,
    /// Numerical rank and condition number of the weighted, column-scaled `H` (of the data
    /// alone, when a prior anchors some parameters).
    pub rank: usize,
    /// `s_1 / s_r` of the same.
    pub condition_number: f64,
    /// A robust loss (`huber:1.345`), if one was used.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub loss: Option<String>,
    /// The training poses it weighted below 0.1 (a pose's observations weigh as one), by
    /// line: the line of each pose's first observation.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub down_weighted: Vec<DownWeighted>,
    /// `--prior auto`: the scale chosen for the preset's standard deviations, and the curve
    /// (cross-validated RMS of the length residuals, mm) it was chosen from.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub prior_scale: Option<PriorScale>,
    /// `--select`: how the joint parameters were chosen, its path.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub selection: Option<super::calibration::SelectionReport>,
    /// What the observations cannot see as a whole, held ([`Unseen`](crate::calibration::Unseen):
    /// its `kind` and values).
    pub unseen: Vec<crate::calibration::Unseen>,
    /// The parameters held, grouped by why ([`held_groups`](super::verdict::held_groups)).
    pub held_groups: Vec<super::verdict::HeldGroup>,
    /// Each parameter held, in words with its combination, as a marker file's report gives it.
    pub fixed: Vec<String>,
    /// The same, typed: the kind, the parameter, a combination's terms.
    pub held: Vec<crate::calibration::Held>,
    /// What the "before" and "after" of every figure are.
    pub fits: Fits,
    /// The training observations whose row gave no sigma (the kinds' defaults weigh them).
    #[serde(skip_serializing_if = "is_zero")]
    pub assumed_sigmas: usize,
    /// When no sigma was given and the joints are exact: the residuals' variance of unit
    /// weight, by which the standard errors and the whitening are scaled.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub variance_factor: Option<f64>,
    /// With several training files: each one's name and number of observations, in order.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub training_files: Vec<(String, usize)>,
    /// `--folds K`: how the cross-validation was made (nested, what each fold chose again).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub cross_validation: Option<super::calibration::CrossValidationReport>,
    /// The tool point's position error predicted at each held-out set's poses from the
    /// parameter covariance (the floor: the first held-out set's marker RMS after, 0 without
    /// markers).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub predicted: Vec<super::calibration::PredictedAccuracy>,
    /// Feasible GLS: the noise estimated from the residuals, the joints' then each measurement
    /// class's, with 95% intervals.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub noise: Option<Vec<super::calibration::NoiseRow>>,
    /// What to look at, one per cause: estimates past a physical bound (a length corrected by
    /// more than 10 mm, an angle by more than 5 deg, a compliance or play no joint has), an
    /// unconverged fit, the
    /// training observations more than [`FLAG_AT`](crate::calibration::FLAG_AT) standard deviations out after
    /// calibration.
    pub warnings: Vec<Warning>,
    /// The training observations scored, then each held-out file: every observation's
    /// residual, and the RMS of the lengths (mm), of the angles (deg) and of the marker
    /// positions (mm).
    pub sets: Vec<(String, Score)>,
}

/// A tree's parts of the report ([`ObservationsReport::tree`]).
#[derive(Debug, Clone, Serialize)]
pub struct TreeParts {
    /// Its branches' tip links.
    pub branches: Vec<String>,
    /// Its joints, in the order of the view files' columns and of `--joint-sigma-deg`.
    pub joints: Vec<String>,
    /// The cameras and targets as calibrated.
    pub frames: Vec<FrameRow>,
}

/// A camera or target as calibrated: its placement in its tip link's frame (or the root
/// link's, for `world`).
#[derive(Debug, Clone, Serialize)]
pub struct FrameRow {
    /// `camera.head_camera`, `target.l_hand`; a later session's own `@` its name.
    pub name: String,
    /// Position (mm).
    pub xyz_mm: [f64; 3],
    /// Roll, pitch, yaw (deg; `R = Rz(yaw) Ry(pitch) Rx(roll)`).
    pub rpy_deg: [f64; 3],
}

/// What the report reads of the robot calibrated ([`Robot`]): its name and joints, and a
/// tree's parts.
pub trait Reported: Robot {
    /// Its name.
    fn name(&self) -> &str;

    /// Its joints.
    fn joints(&self) -> &[Joint];

    /// A tree's parts of the report of `c`; `None` for an arm.
    fn tree_parts(_c: &Calibration<Self>) -> Option<TreeParts> {
        None
    }
}

impl Reported for RobotModel {
    fn name(&self) -> &str {
        &self.name
    }

    fn joints(&self) -> &[Joint] {
        &self.joints
    }
}

impl Reported for RobotTree {
    fn name(&self) -> &str {
        &self.name
    }

    fn joints(&self) -> &[Joint] {
        &self.joints
    }

    fn tree_parts(c: &TreeCalibration) -> Option<TreeParts> {
        Some(TreeParts {
            branches: c.calibrated.branches.iter().map(|b| b.tip.clone()).collect(),
            joints: c.calibrated.joints.iter().map(|j| j.name.clone()).collect(),
            frames: frame_rows(c),
        })
    }
}

/// Each frame's placement after calibration: xyz (mm) and roll, pitch, yaw (deg); then, with
/// per-session placements, each later session's frames that are its own, `@` its name.
fn frame_rows(c: &TreeCalibration) -> Vec<FrameRow> {
    let names = c.frame_names();
    let per_session = c.setup.per_session();
    let own = |f: usize| (6 * f..6 * f + 6).any(|i| per_session.contains(&i));
    let later = (1..c.setup.session_count())
        .flat_map(|k| (0..names.len()).filter(move |&f| own(f)).map(move |f| (f, k)))
        .map(|(f, k)| (f, k, format!("{}@{}", names[f], c.setup.session_names()[k])));
    let first = (0..names.len()).map(|f| (f, 0, names[f].clone()));
    (first.chain(later))
        .map(|(f, session, name)| {
            let placement = c.frame_in(f, session);
            let (roll, pitch, yaw) = placement.rotation.euler_angles();
            let t = placement.translation.vector;
            FrameRow { name, xyz_mm: [t.x, t.y, t.z], rpy_deg: [roll, pitch, yaw].map(f64::to_degrees) }
        })
        .collect()
}

/// What the report's two fits are, in words: "before" (the set-up and the points on the last
/// link fitted with the joints nominal) and "after" (the calibration).
#[derive(Debug, Clone, Serialize)]
pub struct Fits {
    /// The "before" fit.
    pub before: String,
    /// The "after" fit.
    pub after: String,
    /// The rule an observation (a marker's position) is flagged by.
    pub flagged: String,
}

impl Fits {
    /// The fits of `c` by `estimator`: with markers the base, the markers and the set-up by
    /// ordinary least squares whatever the estimator (it minimises the very errors reported),
    /// else the set-up and the tool point (a tree's cameras and targets) by the estimator's
    /// weights, the joints nominal (of a `tree`: its cameras and targets); after, every
    /// parameter asked for that the observations (and the priors) identify.
    fn of<R>(c: &Calibration<R>, estimator: &str, tree: bool) -> Self {
        let before = match (c.markers.is_empty(), c.setup.names().is_empty()) {
            _ if tree => format!("cameras and targets fitted by {estimator}, the tree's joints nominal"),
            (false, true) => {
                "base and markers fitted by ols (unweighted), joints nominal, whatever the estimator".into()
            }
            (false, false) => {
                "base, markers and set-up fitted by ols (unweighted), joints nominal, whatever the estimator"
                    .into()
            }
            (true, _) => format!("set-up and tool point fitted by {estimator}, joints nominal"),
        };
        let priors = c.prior_sd.iter().any(|s| s.is_finite());
        let after = format!(
            "{estimator}{}{}: every parameter asked for {}",
            if priors { " with priors (maximum a posteriori)" } else { "" },
            c.robust.as_ref().map_or(String::new(), |r| format!(", robust loss {}", r.loss)),
            match priors {
                true => "with a prior, and those without one that the observations identify",
                false => "that the observations identify",
            }
        );
        let flagged = if tree { Self::view_rule() } else { flag_rule() };
        Self { before, after, flagged }
    }

    /// The rule a tree's view is flagged by, in words.
    fn view_rule() -> String {
        format!(
            "a view whose rows' largest whitened residual exceeds {} standard deviations",
            crate::calibration::FLAG_AT
        )
    }
}

/// The rule an observation is flagged by, in words.
fn flag_rule() -> String {
    format!(
        "an observation (a marker's position) whose whitened residual exceeds {} standard deviations \
         times its set's robust spread, if above 1",
        crate::calibration::FLAG_AT
    )
}

/// `text` with the points on the last link named as the files name them: each marker by its
/// number (`marker1.x` of markers 2 and 3 is `marker2.x`) and the tool point, the point after
/// them (the first without markers), `tool.x`, in every fit.
fn point_names<R>(text: &str, c: &Calibration<R>) -> String {
    let tool = format!("marker{}.", c.markers.len() + 1);
    let text: Vec<String> = text
        .split(' ')
        .map(|w| w.strip_prefix(&tool).map_or(w.to_string(), |c| format!("tool.{c}")))
        .collect();
    let ids: Vec<usize> = c.markers.iter().map(|m| m.0 + 1).collect();
    by_number(&text.join(" "), &ids)
}

/// Observations listed per set in the text, the worst first.
pub const WORST: usize = 5;

/// Whether `n` is 0 (a count left out of the JSON).
fn is_zero(n: &usize) -> bool {
    *n == 0
}

/// A scored set's rows of the verdict ([`QuantityRow`]): in a set with markers or lengths of
/// several groups (a ball bar's distances and markers), each group's by name
/// ([`Score::by_group`], its observations) and the markers' positions (each marker's with
/// several; a position counted, and flagged, as a marker file's pose is), a marker's
/// coordinates never pooled with the positions; else (one kind of file) its lengths (mm) and
/// its angles (deg).
fn set_rows(name: &str, score: &Score) -> Vec<QuantityRow> {
    let (angles, lengths): (Vec<&GroupRms>, Vec<&GroupRms>) =
        score.by_group.iter().partition(|g| g.unit == "deg");
    let by_name = score.markers.is_some() || lengths.len() > 1;
    let several_angles = angles.len() > 1;
    let row = |quantity: String, unit, (count, flagged), (rms, max): ((f64, f64), (f64, f64))| QuantityRow {
        set: name.to_string(),
        quantity,
        unit,
        count,
        rms: [rms.0, rms.1],
        max: [max.0, max.1],
        flagged: Some(flagged),
    };
    let group = |g: &GroupRms| {
        let named = by_name || (g.unit == "deg" && several_angles);
        let quantity = if named { g.group.to_string() } else { String::new() };
        row(quantity, g.unit, (g.count, g.flagged), (g.rms, g.max))
    };
    let positions = |quantity: String, rms: (f64, f64), marker: Option<usize>| {
        let p = score.positions_of(marker);
        row(quantity, "mm", (p.count, p.flagged), (rms, p.max))
    };
    let all = score.markers.map(|rms| positions("markers".into(), rms, None));
    let each =
        (score.by_marker.iter()).map(|m| positions(format!("marker {}", m.marker), m.rms, Some(m.marker)));
    (lengths.into_iter().map(group)).chain(all).chain(each).chain(angles.into_iter().map(group)).collect()
}

/// A tree's set's rows of the verdict ([`QuantityRow`]): its view positions (mm) and
/// rotations (deg), the norms of their residuals, the views flagged as the warnings flag them
/// (the largest whitened residual beyond [`FLAG_AT`](crate::calibration::FLAG_AT)) on the
/// position's row.
fn view_rows(name: &str, score: &Score) -> Vec<QuantityRow> {
    let largest = |f: &dyn Fn(&ViewResidual) -> f64| score.views.iter().map(f).fold(0.0, f64::max);
    let row = |unit, rms: (f64, f64), max: [f64; 2], flagged| QuantityRow {
        set: name.to_string(),
        quantity: String::new(),
        unit,
        count: score.views.len(),
        rms: [rms.0, rms.1],
        max,
        flagged,
    };
    let flagged = score.views.iter().filter(|v| v.whitened > crate::calibration::FLAG_AT).count();
    let max = [largest(&|v| v.before_mm), largest(&|v| v.after_mm)];
    let mut rows = vec![row("mm", score.view_position.unwrap_or_default(), max, Some(flagged))];
    if let Some(rms) = score.view_rotation {
        let max = [largest(&|v| v.before_deg.unwrap_or(0.0)), largest(&|v| v.after_deg.unwrap_or(0.0))];
        rows.push(row("deg", rms, max, None));
    }
    rows
}

/// The rows of `c`'s estimated parameters, the robot's then the set-up's, in degrees and
/// millimetres, with each prior's SD and the posterior / prior SD ratio where there is one.
fn parameter_rows<R>(c: &Calibration<R>) -> Vec<ParameterRow> {
    let se = c.refined.estimate.standard_errors();
    let setup = c.setup.names();
    (c.refined.estimate.names.iter().enumerate())
        .map(|(k, name)| {
            let (value, angle, unit) = match c.params.index_by_name(name) {
                Some(i) => {
                    let p = c.params.get(i);
                    (c.after[i], p.kind.is_angle(), if p.kind.is_angle() { "deg" } else { p.unit() })
                }
                None => {
                    let i = setup.iter().position(|n| n == name).expect("a robot or set-up parameter");
                    let angle = c.setup.is_angle(i);
                    (c.setup_values.1[i], angle, if angle { "deg" } else { "mm" })
                }
            };
            let scale = if angle { 180.0 / std::f64::consts::PI } else { 1.0 };
            let prior = c.params.index_by_name(name).map(|i| c.prior_sd[i]).filter(|s| s.is_finite());
            ParameterRow {
                name: point_names(name, c),
                value: value * scale,
                std_error: se[k] * scale,
                unit,
                prior_sd: prior.map(|s| s * scale),
                sd_ratio: prior.map(|s| se[k] / s),
            }
        })
        .collect()
}

/// The training poses `c`'s robust loss weighted below 0.1, by the line of each pose's first
/// observation (a pose's observations come together, each with the pose's weight) in
/// `training` (`c`'s training score); a tree's views, one weight each, by their lines.
fn down_weighted<R>(c: &Calibration<R>, training: &Score, tree: bool) -> Vec<DownWeighted> {
    c.robust.as_ref().map_or_else(Vec::new, |r| {
        let line = |k: usize| if tree { training.views[k].line } else { training.observations[k].line };
        let mut down: Vec<DownWeighted> =
            (r.down_weighted()).map(|(k, weight)| DownWeighted { line: line(k), weight }).collect();
        down.dedup_by_key(|d| d.line);
        down
    })
}

impl ObservationsReport {
    /// The report of `c`, fitted on `data` (names) with `estimator`; `held_out` are the held-out
    /// files' RMS residuals, before and after.
    pub fn new<R: Reported>(
        c: &Calibration<R>,
        data: &str,
        fitted: (usize, usize),
        estimator: &str,
        held_out: Vec<(String, Score)>,
    ) -> Self {
        Self::with_training(c, c.training.clone(), data, fitted, estimator, held_out)
    }

    /// [`ObservationsReport::new`] with `c`'s training score given (`training`, moved out of
    /// `c` by the caller: a score holds a residual per observation, 48 MB at 100,000 poses of
    /// two markers, and is not copied).
    pub fn with_training<R: Reported>(
        c: &Calibration<R>,
        training: Score,
        data: &str,
        fitted: (usize, usize),
        estimator: &str,
        held_out: Vec<(String, Score)>,
    ) -> Self {
        let (parameters, tree) = (parameter_rows(c), R::tree_parts(c));
        let fits = Fits::of(c, estimator, tree.is_some());
        let down_weighted = down_weighted(c, &training, tree.is_some());
        let markers = marker_count(&training.observations);
        let mut sets = vec![("training".to_string(), training)];
        sets.extend(held_out);
        let held: Vec<crate::calibration::Held> =
            c.fixed.iter().map(|f| f.clone().renamed(|n| point_names(n, c))).collect();
        let mut report = Self {
            schema: SCHEMA,
            model: c.calibrated.name().to_string(),
            tree,
            data: data.to_string(),
            observations: fitted.0,
            poses: fitted.1,
            estimator: estimator.to_string(),
            iterations: c.refined.history.len(),
            converged: c.refined.converged && c.noise_settled != Some(false),
            noise_settled: c.noise_settled,
            noise: c
                .noise_estimate
                .as_ref()
                .map(|e| super::calibration::noise_rows(c.calibrated.joints(), e)),
            stiffness: super::calibration::stiffness_rows(&parameters),
            parameters,
            rank: c.refined.estimate.diagnostics.rank,
            condition_number: c.refined.estimate.diagnostics.condition_number,
            unseen: c.unseen.clone(),
            fixed: held.iter().map(crate::calibration::Held::text).collect(),
            held_groups: super::verdict::held_groups(&held),
            held,
            verdict: Vec::new(),
            sets,
            warnings: c.warnings.clone(),
            variance_factor: c.variance_factor,
            registered_base: c.registered_base.as_ref().map(mm_deg),
            tip_frame: c.tip_frame.as_ref().map(mm_deg),
            training_files: Vec::new(),
            loss: c.robust.as_ref().map(|r| r.loss.to_string()),
            down_weighted,
            selection: None,
            prior_scale: None,
            cross_validation: None,
            predicted: Vec::new(),
            assumed_sigmas: 0,
            fits,
            markers,
        };
        report.verdict = report.verdict_rows();
        report
    }

    /// The floor of the accuracy predicted from the parameter covariance: the first held-out
    /// file's marker position RMS after calibration (mm), 0 without one (no position measured
    /// held out).
    pub fn floor_mm(&self) -> f64 {
        let held_out = self.sets.len().saturating_sub(1 + usize::from(self.cross_validation.is_some()));
        let first = self.sets.get(1).filter(|_| held_out > 0);
        first.and_then(|(_, s)| s.markers).map_or(0.0, |m| m.1)
    }

    /// The same report with the training files named (each one's name and number of
    /// observations, in the order fitted): its training rows say which file they are in.
    pub fn with_training_files(mut self, files: Vec<(String, usize)>) -> Self {
        self.training_files = files;
        self
    }

    /// The report with the path of the selection that chose the joint parameters of `c`, its
    /// held parameters named as the report names them.
    pub fn with_selection<R>(mut self, path: &SelectionPath, c: &Calibration<R>) -> Self {
        let mut selection = super::calibration::SelectionReport::of(path);
        selection.held = selection.held.iter().map(|h| point_names(h, c)).collect();
        let with = match (c.markers.is_empty(), c.setup.names().is_empty()) {
            _ if self.tree.is_some() => "the cameras and targets",
            (true, _) => "the set-up",
            (false, true) => "the base and the markers",
            (false, false) => "the base, the markers and the set-up",
        };
        self.fits.after = format!(
            "{}: the joint parameters --select {} chose, with {with}",
            self.estimator,
            path.criterion.name()
        );
        self.selection = Some(selection);
        self
    }

    /// The report with the scale `--prior auto` chose and its curve.
    pub fn with_prior_scale(mut self, scale: PriorScale) -> Self {
        self.prior_scale = Some(scale);
        self
    }

    /// The report saying how many of the training observations took a default sigma.
    pub fn with_assumed_sigmas(mut self, count: usize) -> Self {
        self.assumed_sigmas = count;
        self
    }

    /// The report with the accuracy predicted at the held-out sets' poses.
    pub fn with_predicted(mut self, predicted: Vec<super::calibration::PredictedAccuracy>) -> Self {
        self.predicted = predicted;
        self
    }

    /// The verdict's rows: each set's errors before and after by group and marker; a tree's
    /// by its views ([`view_rows`]).
    fn verdict_rows(&self) -> Vec<QuantityRow> {
        let rows = if self.tree.is_some() { view_rows } else { set_rows };
        self.sets.iter().flat_map(|(name, s)| rows(name, s)).collect()
    }

    /// The verdict: its rows as a table, the warnings by cause.
    fn verdict_text(&self) -> String {
        let (title, count) = match self.sets.len() {
            _ if self.tree.is_some() => {
                ("verdict, the view errors (|y_t| mm, |y_r| deg) before -> after calibration:", "views")
            }
            1 => ("verdict, the errors before -> after calibration:", "count"),
            _ => (
                "verdict, the errors before -> after calibration (training: the poses fitted; every other set held out):",
                "count",
            ),
        };
        super::verdict::quantity_table(title, count, &self.verdict)
            + &super::verdict::count_warnings(&self.warnings)
    }

    /// What was fitted: `observations`, or a tree's `views`.
    fn fitted_word(&self) -> &'static str {
        if self.tree.is_some() { "views" } else { "observations" }
    }

    /// What the observations do not see, what is held, and where each held-out session's set-up comes from.
    fn write_held(&self, out: &mut String) {
        if !self.unseen.is_empty() {
            let _ = writeln!(*out, "\nnot seen by these {}, held:", self.fitted_word());
        }
        for u in &self.unseen {
            let _ = writeln!(*out, "  {u}");
        }
        if !self.held.is_empty() && self.unseen.is_empty() {
            out.push('\n');
        }
        out.push_str(&super::verdict::held_text(&self.held));
        let sets = self.sets.iter().skip(1).map(|(name, score)| (name.as_str(), score.sessions.as_slice()));
        out.push_str(&held_out_sessions(sets));
    }

    /// The worst observations of each set after calibration, whitened (a tree's views, by
    /// their position's residual: [`ObservationsReport::write_worst_views`]).
    fn write_worst(&self, out: &mut String) {
        if self.markers.is_some() {
            return; // marker positions alone: their largest errors say it (write_worst_positions)
        }
        if self.tree.is_some() {
            return self.write_worst_views(out);
        }
        let _ =
            writeln!(*out, "\nworst observations after calibration ({WORST} per set; every one in --json):");
        for (set, (name, score)) in self.sets.iter().enumerate() {
            let worst = first_by(score.observations.iter().enumerate(), WORST, |a, b| {
                b.1.whitened.abs().total_cmp(&a.1.whitened.abs())
            });
            let files =
                super::files_of(&self.training_files, set, self.sets.len(), self.cross_validation.is_some());
            for (k, r) in &worst {
                let _ = writeln!(
                    out,
                    "  {name}, {} ({}): {:.4} {unit} before, {:.4} {unit} after, {:.1} sd",
                    super::line_in(files, *k, r.line),
                    r.label(),
                    r.before,
                    r.after,
                    r.whitened,
                    unit = r.unit
                );
            }
        }
    }

    /// The worst views of each set after calibration, by the norm of their position's residual.
    fn write_worst_views(&self, out: &mut String) {
        let _ = writeln!(*out, "\nworst views after calibration ({WORST} per set; every one in --json):");
        for (set, (name, score)) in self.sets.iter().enumerate() {
            let worst =
                first_by(score.views.iter().enumerate(), WORST, |a, b| b.1.after_mm.total_cmp(&a.1.after_mm));
            let files =
                super::files_of(&self.training_files, set, self.sets.len(), self.cross_validation.is_some());
            for (k, v) in worst {
                let (before, after) = match (v.before_deg, v.after_deg) {
                    (Some(b), Some(a)) => (
                        format!("{:.4} mm / {b:.5} deg", v.before_mm),
                        format!("{:.4} mm / {a:.5} deg", v.after_mm),
                    ),
                    _ => (format!("{:.4} mm", v.before_mm), format!("{:.4} mm", v.after_mm)),
                };
                let at = super::line_in(files, k, v.line);
                let _ = writeln!(*out, "  {name}, {at}: {before} before, {after} after");
            }
        }
    }

    /// A tree's cameras and targets as calibrated; nothing for an arm.
    fn write_frames(&self, out: &mut String) {
        let Some(tree) = &self.tree else { return };
        let _ = writeln!(*out, "\ncameras and targets as calibrated (x, y, z mm; roll, pitch, yaw deg):");
        let width = tree.frames.iter().map(|f| f.name.len()).max().unwrap_or(0);
        for f in &tree.frames {
            let ([x, y, z], [roll, pitch, yaw]) = (f.xyz_mm, f.rpy_deg);
            let _ = writeln!(
                *out,
                "  {:<width$} {x:>10.3} {y:>10.3} {z:>10.3}   {roll:>9.4} {pitch:>9.4} {yaw:>9.4}",
                f.name
            );
        }
    }

    /// The largest marker position errors of each set after calibration, as a marker file's
    /// pose table gives them ([`Score::positions`]); nothing without markers.
    fn write_worst_positions(&self, out: &mut String) {
        if self.sets.iter().all(|(_, score)| score.positions.is_empty()) {
            return;
        }
        let _ = writeln!(
            *out,
            "\nlargest marker position errors after calibration ({WORST} per set; every one in --json, `positions`):"
        );
        for (set, (name, score)) in self.sets.iter().enumerate() {
            let worst = first_by(score.positions.iter(), WORST, |a, b| b.error.1.total_cmp(&a.error.1));
            let files =
                super::files_of(&self.training_files, set, self.sets.len(), self.cross_validation.is_some());
            for p in &worst {
                let _ = writeln!(
                    out,
                    "  {name}, {} marker {}: {:.4} mm before, {:.4} mm after, {:.1} sd",
                    super::line_in(files, p.index, p.line),
                    p.marker,
                    p.error.0,
                    p.error.1,
                    p.whitened
                );
            }
        }
    }

    /// What before and after mean, the sigmas' scale, and the warnings.
    fn write_notes(&self, out: &mut String) {
        let f = &self.fits;
        let _ = write!(out, "\nbefore:    {}\nafter:     {}\nflagged:   {}\n", f.before, f.after, f.flagged);
        if self.assumed_sigmas > 0 && self.estimator == Estimator::Ols.name() {
            // Ordinary least squares weighs every row alike whatever its sigma.
            let w = POSE_SIGMAS.0 / POSE_SIGMAS.1;
            let _ = writeln!(
                out,
                "{} of {} observations gave no sigma: ols weighs every row alike (an angle as {w:.0} mm a radian), \
                 whatever the sigmas",
                self.assumed_sigmas, self.observations,
            );
        } else if self.assumed_sigmas > 0 && self.tree.is_some() {
            let _ = writeln!(
                out,
                "{} of {} views gave no sigma: weighed by the defaults, {DEFAULT_CAMERA_SIGMA_MM} mm and \
                 {DEFAULT_CAMERA_SIGMA_DEG} deg",
                self.assumed_sigmas, self.observations,
            );
        } else if self.assumed_sigmas > 0 {
            let _ = writeln!(
                out,
                "{} of {} observations gave no sigma: weighed by the defaults, {} mm and {} deg ({} mm and {} deg a camera's view; \
                 --sigma-mm and --sigma-orientation-deg set them)",
                self.assumed_sigmas,
                self.observations,
                DEFAULT_SIGMA_MM,
                DEFAULT_SIGMA_ANGLE_DEG,
                DEFAULT_CAMERA_SIGMA_MM,
                DEFAULT_CAMERA_SIGMA_DEG
            );
        }
        if let Some(f) = self.variance_factor {
            let defaults = match self.tree {
                Some(_) => format!(", {DEFAULT_CAMERA_SIGMA_MM} mm and {DEFAULT_CAMERA_SIGMA_DEG} deg,"),
                None => String::new(),
            };
            let _ = writeln!(
                out,
                "no sigma given and the joints exact: standard errors and flags from the residuals' spread (the default \
                 sigmas{defaults} times {:.4})",
                f.sqrt()
            );
        }
        if self.sets.iter().any(|(_, score)| score.markers.is_some()) {
            let _ = writeln!(
                out,
                "with markers: before, the base and the points on the last link fitted too; markers (mm): the RMS of the marker positions' errors"
            );
        }
        if !self.warnings.is_empty() {
            let _ = writeln!(*out, "\nwarnings:");
            for w in &self.warnings {
                let _ = writeln!(
                    *out,
                    "  {}",
                    w.render(&|k, line| super::line_in(&self.training_files, k, line))
                );
            }
        }
    }

    /// What was fitted and how: `100 poses, 2 markers, wls (3 steps, converged)` for marker
    /// files, `150 observations at 50 poses, ...` otherwise.
    fn fit_summary(&self) -> String {
        let plural = |n: usize| if n == 1 { "" } else { "s" };
        let what = match self.markers {
            Some(n) => format!("{} pose{}, {n} marker{}", self.poses, plural(self.poses), plural(n)),
            None => format!("{} {} at {} poses", self.observations, self.fitted_word(), self.poses),
        };
        format!(
            "{what}, {} ({} step{}, {})",
            self.estimator,
            self.iterations,
            plural(self.iterations),
            super::calibration::convergence(self.converged, self.noise_settled)
        )
    }

    /// The report as text, at fixed precision.
    pub fn text(&self) -> String {
        let mut out = String::new();
        let model = match &self.tree {
            Some(t) => {
                format!("{} (branches {}; {} joints)", self.model, t.branches.join(", "), t.joints.len())
            }
            None => self.model.clone(),
        };
        let _ = writeln!(out, "calibration of {model} from {}: {}", self.data, self.fit_summary());
        if let Some(t) = &self.tree {
            let _ = writeln!(out, "joints: {}", t.joints.join(", "));
        }
        if let Some(b) = &self.registered_base {
            let _ = writeln!(
                out,
                "base registered at xyz ({:.3}, {:.3}, {:.3}) mm, rpy ({:.4}, {:.4}, {:.4}) deg (the markers' registration; base.* corrects it)",
                b[0], b[1], b[2], b[3], b[4], b[5]
            );
        }
        if let Some(t) = &self.tip_frame {
            let _ = writeln!(
                out,
                "probe frame in the tip link's frame: xyz ({:.3}, {:.3}, {:.3}) mm, rpy ({:.4}, {:.4}, {:.4}) deg \
                 (the marker1.* parameters below are its corrections)",
                t[0], t[1], t[2], t[3], t[4], t[5]
            );
        }
        let _ = writeln!(out, "\n{}", self.verdict_text());
        super::calibration::write_parameters(&mut out, &self.parameters);
        out.push_str(&super::calibration::stiffness_text(&self.stiffness));
        let fit = (self.converged, self.iterations);
        let identified =
            super::calibration::identified_text(&self.parameters, fit, (self.rank, self.condition_number));
        let _ = write!(out, "\n{identified}");
        if let Some(noise) = &self.noise {
            let table = super::calibration::noise_table(noise);
            let _ = write!(out, "\nnoise estimated from the residuals (feasible GLS):\n{table}");
        }
        let unit = if self.tree.is_some() { "view" } else { "pose" };
        super::calibration::write_down_weighted(&mut out, self.loss.as_deref(), &self.down_weighted, unit);
        out.push_str(&super::calibration::choices_text(self.prior_scale.as_ref(), self.selection.as_ref()));
        if let Some(cv) = &self.cross_validation {
            let _ = write!(out, "\n{}", cv.text());
        }
        if !self.predicted.is_empty() {
            let _ = write!(out, "\n{}", super::calibration::predicted_text(&self.predicted));
        }
        self.write_frames(&mut out);
        self.write_held(&mut out);
        self.write_worst(&mut out);
        self.write_worst_positions(&mut out);
        self.write_notes(&mut out);
        out
    }
}

/// A placement as `[x, y, z]` (mm) then roll, pitch, yaw (deg).
fn mm_deg(p: &crate::model::Placement) -> [f64; 6] {
    [p.xyz.x, p.xyz.y, p.xyz.z, p.rpy.x.to_degrees(), p.rpy.y.to_degrees(), p.rpy.z.to_degrees()]
}

/// The number of markers of `observations` if every one is a marker's (a position's coordinate
/// or a probe's orientation), else `None`.
fn marker_count(observations: &[crate::calibration::kinds::ObservationResidual]) -> Option<usize> {
    let markers: Option<Vec<usize>> = observations.iter().map(|o| o.marker).collect();
    let mut markers = markers.filter(|m| !m.is_empty())?;
    markers.sort_unstable();
    markers.dedup();
    Some(markers.len())
}

/// The first `n` of `items` in the order of `order`, as a stable sort would give them (ties in
/// the order the items come), found without sorting every item: a set's worst few of a
/// hundred thousand.
fn first_by<T>(items: impl Iterator<Item = T>, n: usize, order: impl Fn(&T, &T) -> Ordering) -> Vec<T> {
    let mut ranked: Vec<(usize, T)> = items.enumerate().collect();
    let order = |a: &(usize, T), b: &(usize, T)| order(&a.1, &b.1).then(a.0.cmp(&b.0));
    if ranked.len() > n {
        ranked.select_nth_unstable_by(n, order);
        ranked.truncate(n);
    }
    ranked.sort_by(order);
    ranked.into_iter().map(|(_, item)| item).collect()
}

/// The text of `model` scored as it stands on each file of `scores` (`robocal evaluate`): a
/// table of each file's rows as the verdict's ([`QuantityRow`]: by group and marker; of a
/// `tree`'s views, their norms), after only, and each file's worst positions (marker files),
/// views (a tree's) or observations, whitened.
pub fn as_it_stands_text(model: &str, scores: &[(String, Score)], tree: bool) -> String {
    let plural = if scores.len() == 1 { "" } else { "s" };
    let mut out = match tree {
        true => format!(
            "{model} scored as it stands on {} view file{plural}: each file's cameras and targets fitted, the tree's \
             joints held (calibrate --validate scores with the calibrated cameras and targets instead: its figure can \
             be larger)\n\n",
            scores.len()
        ),
        false => format!(
            "{model} scored as it stands on {} file{plural}, the robot and its tool point held:\n  \
             a marker file with the model's base and markers; any other with its set-up fitted (fixed points, planes,\n  \
             camera and target; with markers the base and the markers): calibrate --validate scores with the\n  \
             calibrated set-up instead\n\n",
            scores.len()
        ),
    };
    let heading = ["set", if tree { "views" } else { "count" }, "RMS", "max", "flagged"].map(String::from);
    let cells = |r: &QuantityRow| {
        let digits = if r.unit == "deg" { 5 } else { 4 };
        let flagged = r.flagged.map_or_else(String::new, |f| format!("{f} of {}", r.count));
        let one = |v: [f64; 2]| format!("{:.digits$} {}", v[1], r.unit);
        [r.label(), r.count.to_string(), one(r.rms), one(r.max), flagged]
    };
    let rows = if tree { view_rows } else { set_rows };
    let rows: Vec<[String; 5]> = std::iter::once(heading)
        .chain(scores.iter().flat_map(|(name, s)| rows(name, s)).map(|r| cells(&r)))
        .collect();
    out.push_str(&super::verdict::table("residuals as it stands:", &rows));
    let _ =
        writeln!(out, "\nlargest errors ({WORST} per file, with their whitened size; every one in --json):");
    for (name, score) in scores {
        out.push_str(&largest_errors(name, score, tree));
    }
    let rule = if tree { Fits::view_rule() } else { flag_rule() };
    let _ = writeln!(out, "\nflagged:   {rule}");
    out
}

/// The largest errors of one file scored as it stands, a line each with its whitened size: a
/// tree's views (position and rotation norms), a marker file's positions, or any other file's
/// observations.
fn largest_errors(name: &str, score: &Score, tree: bool) -> String {
    let mut out = String::new();
    if tree {
        let worst = first_by(score.views.iter(), WORST, |a, b| b.after_mm.total_cmp(&a.after_mm));
        for v in worst {
            let error = match v.after_deg {
                Some(deg) => format!("{:.4} mm / {deg:.5} deg", v.after_mm),
                None => format!("{:.4} mm", v.after_mm),
            };
            let _ = writeln!(out, "  {name}, line {}: {error}, {:.1} sd", v.line, v.whitened);
        }
    } else if score.positions.is_empty() {
        let worst =
            first_by(score.observations.iter(), WORST, |a, b| b.whitened.abs().total_cmp(&a.whitened.abs()));
        for r in worst {
            let (label, unit) = (r.label(), r.unit);
            let _ = writeln!(
                out,
                "  {name}, line {} ({label}): {:.4} {unit}, {:.1} sd",
                r.line, r.after, r.whitened
            );
        }
    } else {
        let worst = first_by(score.positions.iter(), WORST, |a, b| b.error.1.total_cmp(&a.error.1));
        for p in worst {
            let _ = writeln!(
                out,
                "  {name}, line {} marker {}: {:.4} mm, {:.1} sd",
                p.line, p.marker, p.error.1, p.whitened
            );
        }
    }
    out
}

/// Where each held-out set's per-session set-up came from (`sets`: each one's name and its
/// sessions), in words: the training session of its name's, or fitted on it, the robot held;
/// empty without per-session parameters.
pub(super) fn held_out_sessions<'a>(
    sets: impl Iterator<Item = (&'a str, &'a [(String, SessionSetUp)])>,
) -> String {
    let sessions: Vec<String> = sets
        .flat_map(|(name, sessions)| sessions.iter().map(move |s| (name, s)))
        .map(|(name, (session, source))| match source {
            SessionSetUp::Training(t) => format!("  {name}: the per-session set-up of training session `{t}`"),
            _ => format!(
                "  {name}: session `{session}` is no training file's: its per-session set-up fitted on it, the robot held"
            ),
        })
        .collect();
    match sessions.is_empty() {
        true => String::new(),
        false => format!("\nheld-out sessions:\n{}\n", sessions.join("\n")),
    }
}
