//! The report of a tree calibrated from camera views ([`crate::calibration::tree`]): the joint
//! parameters with their standard errors, the cameras and targets as calibrated, what the views
//! cannot see, and the RMS view errors before and after on the training and the held-out
//! files, with the worst views. Text and JSON carry the same content.

use super::calibration::ParameterRow;
use crate::calibration::Warning;
use crate::calibration::kinds::{Score, ViewResidual};
use crate::calibration::tree::TreeCalibration;
use serde::Serialize;
use std::fmt::Write;

/// A camera or target as calibrated: its placement in its tip link's frame (or the root
/// link's, for `world`).
#[derive(Debug, Clone, Serialize)]
pub struct FrameRow {
    /// `camera.head_camera`, `target.l_hand`.
    pub name: String,
    /// Position (mm).
    pub xyz_mm: [f64; 3],
    /// Roll, pitch, yaw (deg; `R = Rz(yaw) Ry(pitch) Rx(roll)`).
    pub rpy_deg: [f64; 3],
}

/// Everything the report says. Angles in degrees, lengths in millimetres.
#[derive(Debug, Clone, Serialize)]
pub struct TreeReport {
    /// The robot's name.
    pub model: String,
    /// Its branches' tip links.
    pub branches: Vec<String>,
    /// Its joints, in the order of the view files' columns and of `--joint-sigma-deg`.
    pub joints: Vec<String>,
    /// The view files.
    pub data: String,
    /// Views fitted.
    pub views: usize,
    /// Poses they were taken at.
    pub poses: usize,
    /// The estimator's name.
    pub estimator: String,
    /// Gauss-Newton steps taken.
    pub iterations: usize,
    /// Whether a stopping rule was met.
    pub converged: bool,
    /// Feasible GLS: whether its variance components settled.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub noise_settled: Option<bool>,
    /// Feasible GLS: the noise estimated from the residuals, each tree joint's and the views'
    /// position and rotation sigmas, with 95% intervals.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub noise: Option<Vec<super::calibration::NoiseRow>>,
    /// The estimated parameters, the tree's then the cameras' and targets'.
    pub parameters: Vec<ParameterRow>,
    /// Numerical rank and condition number of the weighted, column-scaled `H` (of the data
    /// alone, when a prior anchors some parameters).
    pub rank: usize,
    /// `s_1 / s_r` of the same.
    pub condition_number: f64,
    /// The cameras and targets as calibrated.
    pub frames: Vec<FrameRow>,
    /// What the views cannot see, held, in words.
    pub unseen: Vec<String>,
    /// Each parameter held, in words with its combination, as a marker file's report gives it.
    pub fixed: Vec<String>,
    /// The parameters held, grouped by why ([`held_groups`](super::verdict::held_groups)).
    pub held_groups: Vec<super::verdict::HeldGroup>,
    /// The same, typed: the kind, the parameter, a combination's terms.
    pub held: Vec<crate::calibration::Held>,
    /// What the report leads with: each set's errors before and after calibration, a row per
    /// quantity, counted and flagged (the text's and the page's verdict table).
    pub verdict: Vec<super::verdict::QuantityRow>,
    /// The training views scored, then each held-out file's.
    pub sets: Vec<(String, Score)>,
    /// Implausible results, one per cause.
    pub warnings: Vec<Warning>,
    /// When no view gave its sigmas and the joints are exact: the residuals' variance of unit
    /// weight, by which the standard errors and the whitening are scaled.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub variance_factor: Option<f64>,
    /// With several training files: each one's name and number of views, in order.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub training_files: Vec<(String, usize)>,
    /// A robust loss (`huber:1.345`), if one was used.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub loss: Option<String>,
    /// The training views it weighted below 0.1, by line.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub down_weighted: Vec<super::calibration::DownWeighted>,
    /// `--folds K`: how the cross-validation was made (nested, what each fold chose again).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub cross_validation: Option<super::calibration::CrossValidationReport>,
    /// `--prior auto`: the scale chosen for the preset's standard deviations, and the curve
    /// (cross-validated RMS of the views' position residuals, mm) it was chosen from.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub prior_scale: Option<crate::calibration::prior_scale::PriorScale>,
    /// `--select`: how the joint parameters were chosen, its path.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub selection: Option<super::calibration::SelectionReport>,
}

/// Views listed per set in the text, the worst first.
pub const WORST: usize = 3;

impl TreeReport {
    /// The report of `c`, fitted on `data` (names; `fitted` its views and poses) with
    /// `estimator`; `held_out` the held-out files scored.
    pub fn new(
        c: &TreeCalibration,
        data: &str,
        fitted: (usize, usize),
        estimator: &str,
        held_out: Vec<(String, Score)>,
    ) -> Self {
        let (parameters, frames) = (parameter_rows(c), frame_rows(c));
        let mut sets = vec![("training".to_string(), c.training.clone())];
        sets.extend(held_out);
        let held: Vec<crate::calibration::Held> = c.fixed.clone();
        let mut report = Self {
            model: c.calibrated.name.clone(),
            branches: c.calibrated.branches.iter().map(|b| b.tip.clone()).collect(),
            joints: c.calibrated.joints.iter().map(|j| j.name.clone()).collect(),
            data: data.to_string(),
            views: fitted.0,
            poses: fitted.1,
            estimator: estimator.to_string(),
            iterations: c.refined.history.len(),
            converged: c.refined.converged && c.noise_settled != Some(false),
            noise_settled: c.noise_settled,
            noise: c.noise_estimate.as_ref().map(|e| super::calibration::noise_rows(&c.calibrated.joints, e)),
            parameters,
            rank: c.refined.estimate.diagnostics.rank,
            condition_number: c.refined.estimate.diagnostics.condition_number,
            frames,
            unseen: c.unseen.clone(),
            fixed: held.iter().map(crate::calibration::Held::text).collect(),
            held_groups: super::verdict::held_groups(&held),
            held,
            verdict: Vec::new(),
            sets,
            warnings: c.warnings.clone(),
            variance_factor: c.variance_factor,
            training_files: Vec::new(),
            loss: c.robust.as_ref().map(|r| r.loss.to_string()),
            down_weighted: c.robust.as_ref().map_or_else(Vec::new, |r| {
                (r.down_weighted())
                    .map(|(k, weight)| super::calibration::DownWeighted {
                        line: c.training.views[k].line,
                        weight,
                    })
                    .collect()
            }),
            prior_scale: None,
            cross_validation: None,
            selection: None,
        };
        report.verdict = report.verdict_rows();
        report
    }

    /// The same report with the training files named (each one's name and number of views, in
    /// the order fitted): its worst training views say which file they are in.
    pub fn with_training_files(self, files: Vec<(String, usize)>) -> Self {
        Self { training_files: files, ..self }
    }

    /// The report with the scale `--prior auto` chose and its curve.
    pub fn with_prior_scale(self, scale: crate::calibration::prior_scale::PriorScale) -> Self {
        Self { prior_scale: Some(scale), ..self }
    }

    /// The report with the path of the selection that chose the tree's joint parameters.
    pub fn with_selection(self, path: &crate::calibration::selection::SelectionPath) -> Self {
        Self { selection: Some(super::calibration::SelectionReport::of(path)), ..self }
    }

    /// The verdict: the views' RMS errors of each set before and after, the warnings by cause.
    fn verdict_text(&self) -> String {
        let title = "verdict, the view errors (|y_t| mm, |y_r| deg) before -> after calibration:";
        super::verdict::quantity_table(title, "views", &self.verdict)
            + &super::verdict::count_warnings(&self.warnings)
    }

    /// The verdict's rows: each set's view positions (mm) and rotations (deg), the norms of
    /// their residuals, the views flagged as the warnings flag them (the largest whitened
    /// residual beyond [`FLAG_AT`](crate::calibration::FLAG_AT)) on the position's row.
    fn verdict_rows(&self) -> Vec<super::verdict::QuantityRow> {
        let mut rows = Vec::new();
        for (name, score) in &self.sets {
            let largest = |f: &dyn Fn(&ViewResidual) -> f64| score.views.iter().map(f).fold(0.0, f64::max);
            let row = |unit, rms: (f64, f64), max: [f64; 2], flagged| super::verdict::QuantityRow {
                set: name.clone(),
                quantity: String::new(),
                unit,
                count: score.views.len(),
                rms: [rms.0, rms.1],
                max,
                flagged,
            };
            let flagged = score.views.iter().filter(|v| v.whitened > crate::calibration::FLAG_AT).count();
            let max = [largest(&|v| v.before_mm), largest(&|v| v.after_mm)];
            rows.push(row("mm", score.view_position.unwrap_or_default(), max, Some(flagged)));
            if let Some(rms) = score.view_rotation {
                let max =
                    [largest(&|v| v.before_deg.unwrap_or(0.0)), largest(&|v| v.after_deg.unwrap_or(0.0))];
                rows.push(row("deg", rms, max, None));
            }
        }
        rows
    }

    /// The worst views of each set after calibration.
    fn write_worst(&self, out: &mut String) {
        let _ = writeln!(*out, "\nworst views after calibration ({WORST} per set; every one in --json):");
        for (set, (name, score)) in self.sets.iter().enumerate() {
            let mut worst: Vec<(usize, &ViewResidual)> = score.views.iter().enumerate().collect();
            worst.sort_by(|a, b| b.1.after_mm.total_cmp(&a.1.after_mm));
            let files =
                super::files_of(&self.training_files, set, self.sets.len(), self.cross_validation.is_some());
            for &(k, v) in worst.iter().take(WORST) {
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

    /// The report as text, at fixed precision.
    pub fn text(&self) -> String {
        let mut out = String::new();
        let _ = writeln!(
            out,
            "calibration of {} (branches {}; {} joints) from {}: {} views at {} poses, {} ({} steps, {})",
            self.model,
            self.branches.join(", "),
            self.joints.len(),
            self.data,
            self.views,
            self.poses,
            self.estimator,
            self.iterations,
            super::calibration::convergence(self.converged, self.noise_settled)
        );
        let _ = writeln!(out, "joints: {}\n", self.joints.join(", "));
        let _ = writeln!(out, "{}", self.verdict_text());
        super::calibration::write_parameters(&mut out, &self.parameters);
        let fit = (self.converged, self.iterations);
        let identified =
            super::calibration::identified_text(&self.parameters, fit, (self.rank, self.condition_number));
        let _ = write!(out, "\n{identified}");
        if let Some(noise) = &self.noise {
            let table = super::calibration::noise_table(noise);
            let _ = write!(out, "\nnoise estimated from the residuals (feasible GLS):\n{table}");
        }
        super::calibration::write_down_weighted(&mut out, self.loss.as_deref(), &self.down_weighted, "view");
        out.push_str(&super::calibration::choices_text(self.prior_scale.as_ref(), self.selection.as_ref()));
        if let Some(cv) = &self.cross_validation {
            let _ = write!(out, "\n{}", cv.text());
        }
        let _ = writeln!(out, "\ncameras and targets as calibrated (x, y, z mm; roll, pitch, yaw deg):");
        let width = self.frames.iter().map(|f| f.name.len()).max().unwrap_or(0);
        for f in &self.frames {
            let [x, y, z] = f.xyz_mm;
            let [roll, pitch, yaw] = f.rpy_deg;
            let _ = writeln!(
                out,
                "  {:<width$} {x:>10.3} {y:>10.3} {z:>10.3}   {roll:>9.4} {pitch:>9.4} {yaw:>9.4}",
                f.name
            );
        }
        let _ = writeln!(out, "\nnot seen by these views, held:");
        for u in &self.unseen {
            let _ = writeln!(out, "  {u}");
        }
        out.push_str(&super::verdict::held_text(&self.held));
        let sets = self.sets.iter().skip(1).map(|(name, score)| (name.as_str(), score.sessions.as_slice()));
        out.push_str(&super::observations::held_out_sessions(sets));
        self.write_worst(&mut out);
        let _ = writeln!(
            out,
            "\nbefore: the cameras and targets fitted with the tree nominal; after: the tree's joints with them"
        );
        if let Some(f) = self.variance_factor {
            let _ = writeln!(
                out,
                "no sigma given and the joints exact: standard errors and flags from the residuals' spread (the default \
                 sigmas, {} mm and {} deg, times {:.4})",
                crate::calibration::kinds::DEFAULT_CAMERA_SIGMA_MM,
                crate::calibration::kinds::DEFAULT_CAMERA_SIGMA_DEG,
                f.sqrt()
            );
        }
        if !self.warnings.is_empty() {
            let _ = writeln!(out, "\nwarnings:");
            for w in &self.warnings {
                let _ =
                    writeln!(out, "  {}", w.render(&|k, line| super::line_in(&self.training_files, k, line)));
            }
        }
        out
    }
}

/// Each estimated parameter of `c` (the tree's, then each frame's placement) with its standard
/// error, angles in degrees.
fn parameter_rows(c: &TreeCalibration) -> Vec<ParameterRow> {
    let se = c.refined.estimate.standard_errors();
    let setup_names = c.setup.names();
    (c.refined.estimate.names.iter().enumerate())
        .map(|(k, name)| {
            let index = c.params.index_by_name(name);
            // Not the tree's: a placement's (of a session, `@` its name).
            let (value, angle) = match index {
                Some(i) => (c.after[i], c.params.get(i).is_angle()),
                None => match setup_names.iter().position(|n| n == name) {
                    Some(i) => (c.setup_values.1[i], c.setup.is_angle(i)),
                    None => (f64::NAN, false),
                },
            };
            let scale = if angle { 180.0 / std::f64::consts::PI } else { 1.0 };
            let prior = index.map(|i| c.prior_sd[i]).filter(|s| s.is_finite());
            ParameterRow {
                name: name.clone(),
                value: value * scale,
                std_error: se[k] * scale,
                unit: if angle { "deg" } else { "mm" },
                prior_sd: prior.map(|s| s * scale),
                sd_ratio: prior.map(|s| se[k] / s),
            }
        })
        .collect()
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
