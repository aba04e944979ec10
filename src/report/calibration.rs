//! The report of a calibration: parameters with their uncertainty, identifiability, accuracy
//! before and after on the training and the validation poses, warnings. Text and JSON carry
//! the same content.

use crate::calibration::prior_scale::{PriorScale, ScaleBy};
use crate::calibration::selection::{Criterion, SelectionPath, Step, Trade};
use crate::estimation::{NoiseEstimate, SigmaInterval};
use crate::model::{Joint, JointKind};
use serde::Serialize;
use std::fmt::Write;

/// The version of the calibration report's JSON: its `schema` key, first. Version 2 leads
/// with the verdict (docs/formats.md, "Calibration report (JSON)").
pub const SCHEMA: u32 = 2;

/// How many `parameters` were estimated, and how well the data determine them: the rank and
/// the condition number `s_1 / s_r` of the whitened, column-scaled `H` (`(rank, condition)`),
/// said as "identified" only when the fit (`(converged, iterations)`) converged; with priors,
/// those of the data alone.
pub fn identified_text(
    parameters: &[ParameterRow],
    (converged, iterations): (bool, usize),
    (rank, condition): (usize, f64),
) -> String {
    let n = parameters.len();
    if n == 0 {
        "nothing estimated: the model is scored as it stands\n".to_string()
    } else if parameters.iter().any(|p| p.prior_sd.is_some()) {
        format!(
            "{n} parameters estimated with their priors; the data alone: rank {rank}, condition number {condition:.3e}\n"
        )
    } else if !converged && iterations > 1 {
        format!(
            "{n} parameters estimated, not converged (rank {rank}, condition number {condition:.3e}): not identified \
             estimates; their standard errors are those of where the fit stopped\n"
        )
    } else {
        format!("{n} parameters identified (rank {rank}), condition number {condition:.3e}\n")
    }
}

/// The label of a k-fold cross-validation's row: `5-fold cross-validation`, and `, nested`
/// when every choice made from the data was made again inside each fold.
pub fn fold_label(folds: usize, nested: bool) -> String {
    format!("{folds}-fold cross-validation{}", if nested { ", nested" } else { "" })
}

/// How a k-fold cross-validation was made: nested when the model is chosen from the data
/// (`--select`, a robust loss), every choice made again on each fold's training poses, so that
/// its figure is one of poses no choice has seen.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CrossValidationReport {
    /// The folds.
    pub folds: usize,
    /// Whether a choice made from the data was made again inside each fold.
    pub nested: bool,
    /// The choices made again inside each fold (`--select bic`, `--loss huber:1.345`).
    pub redone: Vec<String>,
    /// With `--select`: the joint parameters each fold's selection chose, fold by fold.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub selected: Vec<Vec<String>>,
    /// With `--prior auto`: the scale each fold chose, fold by fold.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub scales: Vec<f64>,
}

impl CrossValidationReport {
    /// The label of its row in the error table: `5-fold cross-validation`, `, nested` when it is.
    pub fn label(&self) -> String {
        fold_label(self.folds, self.nested)
    }

    /// What it redid, in words.
    pub fn text(&self) -> String {
        if !self.nested {
            return format!(
                "{}: nothing is chosen from the data, each fold is calibrated as the whole is\n",
                self.label()
            );
        }
        let mut out = format!("{}: {} made again inside each fold", self.label(), self.redone.join(" and "));
        if !self.selected.is_empty() {
            let mut distinct = self.selected.clone();
            distinct.sort();
            distinct.dedup();
            let sizes: Vec<String> = self.selected.iter().map(|s| s.len().to_string()).collect();
            let _ = write!(
                out,
                " (the folds chose {} parameters; {} distinct set{}, each in --json)",
                sizes.join(", "),
                distinct.len(),
                if distinct.len() == 1 { "" } else { "s" }
            );
        }
        if !self.scales.is_empty() {
            let scales: Vec<String> = self.scales.iter().map(|&s| short(s)).collect();
            let _ = write!(out, " (the folds' prior scales: {})", scales.join(", "));
        }
        out + "\n"
    }
}

/// The accuracy `predicted` at the held-out poses, a line each, under its heading (nothing
/// without held-out sets).
pub(super) fn predicted_text(predicted: &[PredictedAccuracy]) -> String {
    let mut out = String::new();
    match predicted.first() {
        Some(first) if first.floor_mm > 0.0 => {
            let _ = writeln!(
                out,
                "predicted position error SD at the held-out poses (parameter covariance, floor {:.4} mm in quadrature):",
                first.floor_mm
            );
        }
        Some(_) => {
            let _ = writeln!(
                out,
                "predicted position error SD of the tool point at the held-out poses (parameter covariance; no floor: no \
                 position measured held out):"
            );
        }
        None => {}
    }
    for p in predicted {
        let _ = writeln!(
            out,
            "  {}: mean {:.4} mm, max {:.4} mm; from the parameters alone {:.4} mm",
            p.set, p.mean_mm, p.max_mm, p.parameters_mm
        );
    }
    out
}

/// The tool's position error predicted at a set's poses: `sqrt(trace(J_x Sigma_x J_x^T))` of
/// the calibration's parameter covariance, with and without the floor (the first held-out
/// set's RMS after calibration) added in quadrature.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PredictedAccuracy {
    /// The set.
    pub set: String,
    /// The mean over its poses of the predicted position SD, floor included (mm).
    pub mean_mm: f64,
    /// Its largest (mm).
    pub max_mm: f64,
    /// The mean from the parameters' uncertainty alone, without the floor (mm).
    pub parameters_mm: f64,
    /// The floor (mm).
    pub floor_mm: f64,
}

/// The choices made from the data, each after a blank line: `--prior auto`'s scale with its
/// curve ([`prior_scale_text`]), then `--select`'s path.
pub(super) fn choices_text(scale: Option<&PriorScale>, selection: Option<&SelectionReport>) -> String {
    let scale = scale.map(|s| format!("\n{}", prior_scale_text(s)));
    let selection = selection.map(|s| format!("\n{}", s.text()));
    scale.into_iter().chain(selection).collect()
}

/// The scale `--prior auto` or `auto-ml` chose, with its curve: every scale tried by
/// cross-validation; of the marginal likelihood's fine grid, the powers of 2 and the scale
/// chosen (the JSON has every one).
pub(super) fn prior_scale_text(scale: &PriorScale) -> String {
    if !scale.classes.is_empty() {
        return class_scales_text(scale);
    }
    let mut out = format!(
        "prior scale: --prior {} chose {} x its standard deviations, by {} (in-sample: --folds K gives the \
         nested figure)\n",
        scale.label(),
        short(scale.scale()),
        prior_scale_method(scale),
    );
    let (heading, values) = match scale.by {
        ScaleBy::Cv => ("CV RMS mm", &scale.cv_rms),
        ScaleBy::Ml => ("log evidence", &scale.log_evidence),
    };
    let _ = writeln!(out, "{:>8} {:>12}", "scale", heading);
    for (k, (s, value)) in scale.scales.iter().zip(values).enumerate() {
        if scale.by == ScaleBy::Ml && k != scale.chosen && s.log2().fract() != 0.0 {
            continue;
        }
        let mark = if k == scale.chosen { "  <- chosen" } else { "" };
        let _ = writeln!(out, "{:>8} {value:>12.4}{mark}", short(*s));
    }
    out
}

/// The scales `--prior auto-ml:PRESET:classes` chose, one per class, then the one scale for
/// every class for comparison, its log evidence below the classes'.
fn class_scales_text(scale: &PriorScale) -> String {
    let mut out = format!(
        "prior scale: --prior {} chose a scale per class of its standard deviations, by {} (in-sample: \
         --folds K gives the nested figure)\n",
        scale.label(),
        prior_scale_method(scale),
    );
    let _ = writeln!(out, "{:>12} {:>10} {:>8}", "class", "parameters", "scale");
    for c in &scale.classes {
        let _ = writeln!(out, "{:>12} {:>10} {:>8}", c.class, c.parameters, short(c.scale));
    }
    let _ = writeln!(
        out,
        "one scale for every class: {} x, log evidence {:.4} below the scales per class",
        short(scale.scale()),
        -scale.log_evidence[scale.chosen]
    );
    out
}

/// How a prior's scale was chosen, in words.
pub(crate) fn prior_scale_method(scale: &PriorScale) -> String {
    match (scale.by, scale.folds) {
        (ScaleBy::Cv, Some(k)) => format!("{k}-fold cross-validation"),
        (ScaleBy::Cv, None) => "cross-validation".into(),
        (ScaleBy::Ml, _) => match scale.noise_spread {
            None => "the marginal likelihood (type-II maximum likelihood, the noise as given)".into(),
            Some(c) => format!(
                "the marginal likelihood (type-II maximum likelihood, no noise given: the noise taken as the \
                 residuals' spread without priors, {c:.4} mm, which the priors weigh against)"
            ),
        },
    }
}

/// A scale with 4 significant digits at most (`0.0625`, `2.181`, `16`).
fn short(s: f64) -> String {
    let text = format!("{s:.4}");
    let digits = if s >= 1.0 { format!("{s:.3}") } else { text };
    let trimmed = digits.trim_end_matches('0').trim_end_matches('.');
    trimmed.to_string()
}

/// What the scores of a selection path by `criterion` are, in words.
fn path_scores(criterion: Criterion) -> String {
    let nested = "--folds K gives the nested cross-validation";
    match criterion {
        Criterion::Cv { .. } => format!(
            "in-sample: the folds that score the steps also chose the path and the model, so the chosen \
             step's CV RMS is not a held-out figure ({nested})"
        ),
        Criterion::Bic => format!("in-sample: BIC of the fit on every training pose ({nested})"),
        Criterion::T => format!("in-sample: |t| of each dropped estimate on every training pose ({nested})"),
    }
}

/// The path of a parameter selection, as reported.
#[derive(Debug, Clone, Serialize)]
pub struct SelectionReport {
    /// `cv`, `bic` or `t`.
    pub criterion: String,
    /// The folds of `cv`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub folds: Option<usize>,
    /// Every step, the start first: the parameter added (dropped for `t`), the score after it
    /// (CV RMS in mm, BIC, or the dropped parameter's |t|), the CV RMS's standard error.
    pub steps: Vec<Step>,
    /// What the steps' scores are: figures of the training poses the path was chosen on, not
    /// held-out ones.
    pub scores: String,
    /// The step chosen.
    pub chosen: usize,
    /// The joint parameters chosen.
    pub selected: Vec<String>,
    /// The parameters asked for that the gauge holds, not candidates: each with its
    /// combination in words.
    pub held: Vec<String>,
    /// Each joint's zero or play left out while chosen parameters that stand in for it are in
    /// (the text's `trade:` lines).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub trades: Vec<Trade>,
}

impl SelectionReport {
    /// The report of `path`.
    pub fn of(path: &SelectionPath) -> Self {
        Self {
            criterion: path.criterion.name().to_string(),
            folds: match path.criterion {
                Criterion::Cv { folds } => Some(folds),
                _ => None,
            },
            steps: path.steps.clone(),
            scores: path_scores(path.criterion),
            chosen: path.chosen,
            selected: path.selected.clone(),
            held: path.held.clone(),
            trades: path.trades.clone(),
        }
    }

    /// The path as a text table.
    pub fn text(&self) -> String {
        let mut out = String::new();
        let (what, start, score) = match self.criterion.as_str() {
            "cv" => (
                format!(
                    "forward selection by {}-fold cross-validation, one-standard-error rule",
                    self.folds.unwrap_or(0)
                ),
                "no joint parameter",
                "CV RMS mm ± SE",
            ),
            "bic" => ("forward selection by BIC".to_string(), "no joint parameter", "BIC"),
            _ => ("backward elimination while |t| < 2".to_string(), "every candidate", "|t| dropped"),
        };
        let _ = writeln!(out, "parameter selection: {what}");
        let _ = writeln!(out, "{:>5}  {:<22} {:>22}", "step", "parameter", score);
        for (k, step) in self.steps.iter().enumerate() {
            let name = step.parameter.as_deref().unwrap_or(start);
            let value = if step.score.is_nan() {
                String::new()
            } else if step.se.is_nan() {
                format!("{:.4}", step.score)
            } else {
                format!("{:.4} ± {:.4}", step.score, step.se)
            };
            let mark = if k == self.chosen { "  <- chosen" } else { "" };
            let _ = writeln!(out, "{k:>5}  {name:<22} {value:>22}{mark}");
        }
        let _ = writeln!(out, "selected ({}): {}", self.selected.len(), self.selected.join(", "));
        let _ = writeln!(out, "path scores: {}", self.scores);
        for (k, step) in self.steps.iter().enumerate() {
            if let Some(note) = step.note_text() {
                let _ = writeln!(out, "step {k}: {note}");
            }
        }
        for trade in &self.trades {
            let _ = writeln!(out, "trade: {trade}");
        }
        if !self.held.is_empty() {
            // Only the names: the combinations are in the JSON.
            let names: Vec<&str> =
                self.held.iter().map(|h| h.split([' ', ':']).next().unwrap_or(h)).collect();
            let _ = writeln!(
                out,
                "not candidates, held ({}; why in the JSON): {}",
                names.len(),
                names.join(", ")
            );
        }
        out
    }
}

/// `text` with the markers' parameters named by the markers' numbers in the data
/// (`marker1.x` of a fit with markers `[2, 3]` is `marker2.x`).
pub(super) fn by_number(text: &str, ids: &[usize]) -> String {
    text.split(' ')
        .map(|word| {
            let renamed = word.strip_prefix("marker").and_then(|rest| {
                let (k, kind) = rest.split_once('.')?;
                let id = ids.get(k.parse::<usize>().ok()?.checked_sub(1)?)?;
                Some(format!("marker{id}.{kind}"))
            });
            renamed.unwrap_or_else(|| word.to_string())
        })
        .collect::<Vec<_>>()
        .join(" ")
}

/// One estimated noise component: a standard deviation with its 95% interval.
#[derive(Debug, Clone, Serialize)]
pub struct NoiseRow {
    /// `j1` (joint noise), `sigma_me` or `sigma_orientation`.
    pub name: String,
    /// The estimated standard deviation.
    pub sigma: f64,
    /// Lower end of the 95% interval.
    pub low: f64,
    /// Upper end of the 95% interval.
    pub high: f64,
    /// `deg` or `mm`.
    pub unit: &'static str,
}

/// The rows of an estimated noise for the robot's `joints`: each joint's sigma (deg, mm), then
/// each measurement class's (`sigma_me` mm and `sigma_orientation` deg of marker files;
/// `sigma_distance`, `sigma_camera_rotation`, ... of observation files): lengths in mm, angles
/// in deg.
pub fn noise_rows(joints: &[Joint], estimate: &NoiseEstimate) -> Vec<NoiseRow> {
    let row = |name: String, s: SigmaInterval, scale: f64, unit| NoiseRow {
        name,
        sigma: s.sigma * scale,
        low: s.low * scale,
        high: s.high * scale,
        unit,
    };
    let mut rows: Vec<NoiseRow> = joints
        .iter()
        .enumerate()
        .map(|(i, j)| match j.kind {
            JointKind::Revolute => row(j.name.clone(), estimate.joint_sigma(i), 1f64.to_degrees(), "deg"),
            JointKind::Prismatic => row(j.name.clone(), estimate.joint_sigma(i), 1.0, "mm"),
        })
        .collect();
    for (class, s) in estimate.measurement_sigmas() {
        rows.push(match class.is_angle() {
            true => row(class.name().into(), s, 1f64.to_degrees(), "deg"),
            false => row(class.name().into(), s, 1.0, "mm"),
        });
    }
    rows
}

/// The rows as a table: name, sigma, 95% interval, unit.
pub fn noise_table(rows: &[NoiseRow]) -> String {
    let mut out = String::new();
    let _ = writeln!(out, "{:<18} {:>12} {:>12} {:>12}  unit", "noise", "sigma", "95% low", "95% high");
    for r in rows {
        let _ =
            writeln!(out, "{:<18} {:>12.3e} {:>12.3e} {:>12.3e}  {}", r.name, r.sigma, r.low, r.high, r.unit);
    }
    out
}

/// One identified parameter.
#[derive(Debug, Clone, Serialize)]
pub struct ParameterRow {
    /// `j3.beta`.
    pub name: String,
    /// The estimated error (for the base, the correction to the registered base).
    pub value: f64,
    /// Its standard error (the posterior one, with a prior).
    pub std_error: f64,
    /// `deg` or `mm`.
    pub unit: &'static str,
    /// Its prior standard deviation, if it has one (same unit).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub prior_sd: Option<f64>,
    /// Posterior over prior standard deviation: near 1, the data barely moved it from the
    /// prior; near 0, the data determined it.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub sd_ratio: Option<f64>,
}

/// A joint's estimated compliance `c` as a stiffness `k = 1 / c`, with the 95% interval
/// `[1 / (c + 1.96 SE), 1 / (c - 1.96 SE)]`, open above when `c - 1.96 SE <= 0` (the data do
/// not bound the stiffness). A compliance that is not positive has no stiffness: it absorbs
/// something else (the warnings say so).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct StiffnessRow {
    /// The joint (`joint2`).
    pub joint: String,
    /// `1 / c`: N·m/rad for a revolute joint, N/mm for a prismatic one; `None` when `c <= 0`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub stiffness: Option<f64>,
    /// Lower end of the 95% interval: `1 / (c + 1.96 SE)`; `None` when `c + 1.96 SE <= 0`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub low: Option<f64>,
    /// Upper end of the 95% interval, `1 / (c - 1.96 SE)`; `None` when unbounded.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub high: Option<f64>,
    /// `N·m/rad` or `N/mm`.
    pub unit: &'static str,
}

/// The stiffness rows of the estimated compliances among `rows` (their values and standard
/// errors, in rad/N·m or mm/N): [`StiffnessRow`].
pub(super) fn stiffness_rows(rows: &[ParameterRow]) -> Vec<StiffnessRow> {
    rows.iter()
        .filter_map(|p| Some((p.name.strip_suffix(".compliance")?, p)))
        .map(|(joint, p)| {
            let (c, margin) = (p.value, crate::estimation::Z_95 * p.std_error);
            let inverse = |v: f64| (v > 0.0).then(|| 1.0 / v);
            StiffnessRow {
                joint: joint.to_string(),
                stiffness: inverse(c),
                low: inverse(c + margin),
                high: inverse(c).and(inverse(c - margin)),
                unit: if p.unit == "mm/N" { "N/mm" } else { "N·m/rad" },
            }
        })
        .collect()
}

/// The stiffness of each estimated compliance ([`stiffness_rows`]) as a table, after a blank
/// line; nothing without one.
pub(super) fn stiffness_text(rows: &[StiffnessRow]) -> String {
    let mut out = String::new();
    if rows.is_empty() {
        return out;
    }
    let _ = writeln!(
        out,
        "\n{:<18} {:>12} {:>12} {:>12}  unit (1 / compliance, its 95% interval)",
        "joint stiffness", "estimate", "low", "high"
    );
    let number = |v: Option<f64>, none: &str| v.map_or(none.to_string(), |v| format!("{v:.4e}"));
    for r in rows {
        let open = if r.stiffness.is_some() { "unbounded" } else { "-" };
        let _ = writeln!(
            out,
            "{:<18} {:>12} {:>12} {:>12}  {}",
            r.joint,
            number(r.stiffness, "none"),
            number(r.low, "-"),
            number(r.high, open),
            r.unit
        );
    }
    if rows.iter().any(|r| r.stiffness.is_none()) {
        let _ = writeln!(
            out,
            "(none: a compliance estimated at or below 0 gives no stiffness; low is still the least stiffness the data allow)"
        );
    }
    out
}

/// A training pose that a robust loss weighted below [`crate::calibration::robust::LISTED_BELOW`].
#[derive(Debug, Clone, Serialize)]
pub struct DownWeighted {
    /// Its line in the measurement file.
    pub line: usize,
    /// Its final weight (1: a least-squares pose).
    pub weight: f64,
}

/// The parameter table: name, estimate, standard error, with priors the prior SD and the SD
/// ratio, and the unit; compliances in scientific notation.
pub(super) fn write_parameters(out: &mut String, parameters: &[ParameterRow]) {
    let w = parameters.iter().map(|p| p.name.len()).max().unwrap_or(0).max(14);
    let priors = parameters.iter().any(|p| p.prior_sd.is_some());
    match priors {
        true => {
            let _ = writeln!(
                out,
                "{:<w$} {:>12} {:>12} {:>12} {:>9}  unit",
                "parameter", "estimate", "std. error", "prior SD", "SD ratio"
            );
        }
        false => {
            let _ = writeln!(out, "{:<w$} {:>12} {:>12}  unit", "parameter", "estimate", "std. error");
        }
    }
    for p in parameters {
        // compliances: small numbers, in scientific notation
        let number = |v: f64| if p.unit.contains('N') { format!("{v:>12.4e}") } else { format!("{v:>12.5}") };
        let mut line = format!("{:<w$} {} {}", p.name, number(p.value), number(p.std_error));
        match (p.prior_sd, p.sd_ratio) {
            (Some(prior), Some(ratio)) => line += &format!(" {} {ratio:>9.3}", number(prior)),
            _ if priors => line += &format!(" {:>12} {:>9}", "-", "-"),
            _ => {}
        }
        let _ = writeln!(out, "{line}  {}", p.unit);
    }
    if priors {
        let _ = writeln!(
            out,
            "(with priors: posterior standard errors; SD ratio = posterior / prior SD, near 1 where the \
             data barely moved a parameter from its prior)"
        );
    }
}

/// The robust loss's line, if one was used, and what it weighted below 0.1 (`what`: a pose,
/// an observation), each by its line.
pub(super) fn write_down_weighted(out: &mut String, loss: Option<&str>, down: &[DownWeighted], what: &str) {
    let Some(loss) = loss else { return };
    let _ = writeln!(
        out,
        "robust loss {loss}: {} {what}{} weighted below 0.1{}",
        down.len(),
        if down.len() == 1 { "" } else { "s" },
        if down.is_empty() { "" } else { ":" }
    );
    for d in down {
        let _ = writeln!(out, "  line {}: weight {:.4}", d.line, d.weight);
    }
}

/// A fit's end in words: converged, or not, and why when feasible GLS's variance components
/// did not settle (`noise_settled` `Some(false)`).
pub(crate) fn convergence(converged: bool, noise_settled: Option<bool>) -> &'static str {
    match (converged, noise_settled) {
        (true, _) => "converged",
        (false, Some(false)) => "not converged: the variance components did not settle",
        (false, _) => "not converged",
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn row(value: f64, std_error: f64) -> ParameterRow {
        ParameterRow {
            name: "joint2.compliance".into(),
            value,
            std_error,
            unit: "rad/N·m",
            prior_sd: None,
            sd_ratio: None,
        }
    }

    /// A compliance's stiffness and its interval: bounded, open above, or none when the
    /// compliance is not positive; other parameters give none.
    #[test]
    fn stiffness_is_the_inverse_compliance_with_its_interval() {
        let rows = stiffness_rows(&[row(5e-5, 1e-5), row(5e-5, 5e-5), row(-1e-4, 1e-5), row(0.1, 0.0)]);
        assert_eq!(rows[0].joint, "joint2");
        assert!((rows[0].stiffness.unwrap() - 2e4).abs() < 1e-6);
        let z = crate::estimation::Z_95;
        assert!((rows[0].low.unwrap() - 1.0 / (5e-5 + z * 1e-5)).abs() < 1e-6);
        assert!((rows[0].high.unwrap() - 1.0 / (5e-5 - z * 1e-5)).abs() < 1e-6);
        assert_eq!((rows[1].stiffness.is_some(), rows[1].high), (true, None), "open above");
        assert_eq!((rows[2].stiffness, rows[2].low, rows[2].high), (None, None, None));
        assert_eq!(rows.len(), 4);
        assert_eq!(stiffness_rows(&[ParameterRow { name: "joint2.a".into(), ..row(1.0, 0.1) }]).len(), 0);
        let text = stiffness_text(&rows);
        assert!(text.contains("joint2") && text.contains("unbounded") && text.contains("(none:"), "{text}");
        assert_eq!(stiffness_text(&[]), "");
    }
}
