//! The calibration report as a designed, self-contained HTML page, in the text's order: the
//! verdict as a card, the parameters with their 95% intervals drawn, what was held (the
//! combinations in a collapsible section), the errors per set and per marker as tables, the
//! figures with captions that say what to look for, every pose in collapsible sections, the
//! warnings in full. No script, no address: it opens and prints offline.

use super::calibration::{CalibrationReport, ParameterRow};
use super::html::{Cell, Row, escape, table};
use super::verdict::{Role, SetVerdict, combination, held_groups};
use crate::calibration::{ErrorStats, Held, SetEvaluation};
use std::fmt::Write;

/// The page of `report`, titled `title`, with `figures` (`(file name, SVG)`) inline.
pub fn calibration_page(report: &CalibrationReport, title: &str, figures: &[(String, String)]) -> String {
    let meta = report.fit_summary();
    let mut out = super::html::start(title, &meta);
    out.push_str(&summary(report));
    out.push_str(&parameters(report));
    out.push_str(&held(report));
    out.push_str(&errors(report));
    if !figures.is_empty() {
        let _ = writeln!(
            out,
            "<section id=\"figures\">\n<h2>Figures</h2>\n{}</section>",
            super::html::figures(figures)
        );
    }
    let sets: Vec<&SetEvaluation> = report.sets.iter().collect();
    let _ = writeln!(
        out,
        "<section id=\"poses\">\n<h2>Every pose</h2>\n<p class=\"note\">Each set's poses, one row per pose and \
         marker (also in --poses-csv and --json); flagged poses are shaded.</p>\n{}</section>",
        super::html::poses(&sets)
    );
    out.push_str(&warnings(report));
    out.push_str(super::html::end());
    out
}

/// `[before, after]` as two cells, the after one marked as the result.
fn before_after(v: [f64; 2]) -> [Cell; 2] {
    [Cell::text(&format!("{:.4}", v[0])), Cell::html(format!("{:.4}", v[1]), "good")]
}

/// The verdict: the headline set's figures large, a row per set, the flags, the warnings by
/// cause.
fn summary(report: &CalibrationReport) -> String {
    let verdict = &report.verdict;
    let class = if verdict.warnings.is_empty() && verdict.converged { "card" } else { "card warned" };
    let mut out = format!("<section id=\"summary\" class=\"{class}\">\n<h2>Verdict</h2>\n");
    if let Some(h) = verdict.headline() {
        let on = match h.role {
            Role::Pooled => "the held-out files pooled".to_string(),
            role => format!("{} ({})", h.set, role.words()),
        };
        let _ = writeln!(
            out,
            "<p class=\"headline\"><span class=\"big\">{:.4} mm</span> RMS after calibration on {}, \
             {:.4} mm before: {:.1} times lower; the largest {:.4} mm ({:.4} mm before).</p>",
            h.rms_mm[1],
            escape(&on),
            h.rms_mm[0],
            h.improvement(),
            h.max_mm[1],
            h.max_mm[0]
        );
    }
    let rows: Vec<Row> = verdict.sets.iter().flat_map(verdict_rows).collect();
    let head =
        ["set", "role", "poses", "RMS before mm", "RMS after mm", "max before mm", "max after mm", "flagged"];
    out.push_str(&table(
        "verdict small",
        None,
        "Marker position error before and after calibration",
        &head,
        &rows,
    ));
    if !verdict.converged {
        out.push_str("<p><strong>The fit did not converge</strong>: see the warnings.</p>\n");
    }
    if verdict.warnings.is_empty() {
        out.push_str("<p>No warnings.</p>\n");
    } else {
        out.push_str("<p>Warnings by cause (in full <a href=\"#warnings\">at the end</a>):</p>\n<ul class=\"warnings\">\n");
        for w in &verdict.warnings {
            let _ = writeln!(out, "<li><span class=\"count\">{}</span>{}</li>", w.count, escape(&w.about));
        }
        out.push_str("</ul>\n");
    }
    out.push_str("</section>\n");
    out
}

/// A set's rows of the verdict table: the position error, and a probe's orientation error.
fn verdict_rows(s: &SetVerdict) -> Vec<Row> {
    let flagged = s.flagged.map_or("-".to_string(), |f| format!("{f} of {}", s.poses));
    let mut cells = vec![Cell::name(&s.set), Cell::name(s.role.words()), Cell::text(&s.poses.to_string())];
    cells.extend(before_after(s.rms_mm));
    cells.extend(before_after(s.max_mm));
    cells.push(Cell::text(&flagged));
    let mut rows = vec![Row::from(cells)];
    if let (Some(rms), Some(max)) = (s.orientation_rms_deg, s.orientation_max_deg) {
        let mut cells =
            vec![Cell::name(&format!("{}, orientation (deg)", s.set)), Cell::text(""), Cell::text("")];
        cells.extend(before_after(rms));
        cells.extend(before_after(max));
        cells.push(Cell::text(""));
        rows.push(cells.into());
    }
    rows
}

/// Half the width of an interval's drawing (px).
const HALF: f64 = 70.0;

/// The estimate of `p` (a dot) and its 95% interval (a bar) on a line through 0 (the centre),
/// `scale` (in `p`'s unit) at the ends: blue when the interval leaves out 0, grey when not.
fn interval_bar(p: &ParameterRow, scale: f64) -> String {
    let margin = crate::estimation::Z_95 * p.std_error;
    let x = |v: f64| HALF + (HALF - 4.0) * (v / scale).clamp(-1.0, 1.0);
    let (low, high) = (x(p.value - margin), x(p.value + margin));
    let colour = if (p.value - margin) * (p.value + margin) > 0.0 { "#0072B2" } else { "#8c959f" };
    format!(
        "<svg width=\"{w}\" height=\"14\" viewBox=\"0 0 {w} 14\" role=\"img\"><title>{} {} ± {} {}</title>\
         <line x1=\"{HALF}\" y1=\"1\" x2=\"{HALF}\" y2=\"13\" stroke=\"#57606a\" stroke-width=\"1\"/>\
         <line x1=\"2\" y1=\"7\" x2=\"{e}\" y2=\"7\" stroke=\"#d0d7de\" stroke-width=\"1\"/>\
         <rect x=\"{low:.1}\" y=\"4\" width=\"{:.1}\" height=\"6\" fill=\"{colour}\" opacity=\"0.55\"/>\
         <circle cx=\"{:.1}\" cy=\"7\" r=\"2.5\" fill=\"{colour}\"/></svg>",
        escape(&p.name),
        p.value,
        margin,
        p.unit,
        (high - low).max(1.5),
        x(p.value),
        w = 2.0 * HALF,
        e = 2.0 * HALF - 2.0,
    )
}

/// A number of `unit`: a compliance in scientific notation, the rest to 5 places.
fn number(v: f64, unit: &str) -> String {
    if unit.contains('N') { format!("{v:.4e}") } else { format!("{v:.5}") }
}

/// The parameter table, the interval of each drawn on one scale per unit.
pub(super) fn parameter_table(parameters: &[ParameterRow]) -> String {
    let priors = parameters.iter().any(|p| p.prior_sd.is_some());
    let reach = |p: &ParameterRow| p.value.abs() + crate::estimation::Z_95 * p.std_error;
    let scale = |unit: &str| {
        let s = parameters.iter().filter(|p| p.unit == unit).map(reach).fold(0.0, f64::max);
        if s > 0.0 && s.is_finite() { s } else { 1.0 }
    };
    let rows: Vec<Row> = parameters
        .iter()
        .map(|p| {
            let mut cells = vec![
                Cell::name(&p.name),
                Cell::text(&number(p.value, p.unit)),
                Cell::text(&number(p.std_error, p.unit)),
                Cell::html(interval_bar(p, scale(p.unit)), "bar"),
            ];
            if priors {
                cells.push(Cell::text(&p.prior_sd.map_or("-".into(), |s| number(s, p.unit))));
                cells.push(Cell::text(&p.sd_ratio.map_or("-".into(), |r| format!("{r:.3}"))));
            }
            cells.push(Cell::name(p.unit));
            cells.into()
        })
        .collect();
    let mut head = vec!["parameter", "estimate", "std. error", "95% interval (0 at the centre)"];
    if priors {
        head.extend(["prior SD", "SD ratio"]);
    }
    head.push("unit");
    table("parameters", None, "", &head, &rows)
}

/// The parameters: the registration, the table, the stiffnesses, how well the data identify
/// them, the robust loss, the prior's scale, the selection's path.
fn parameters(report: &CalibrationReport) -> String {
    let mut out = String::from("<section id=\"parameters\">\n<h2>Parameters</h2>\n");
    for line in report_lines(&report.setup_text()) {
        let _ = writeln!(out, "<p>{}</p>", escape(line));
    }
    out.push_str(&parameter_table(&report.parameters));
    let _ = writeln!(
        out,
        "<p class=\"note\">The bars draw each estimate (dot) and its 95% interval (estimate ± 1.96 standard \
         errors) on one scale per unit, 0 at the centre line: blue when the interval leaves out 0, grey when the \
         data cannot tell the estimate from 0.</p>"
    );
    if !report.stiffness.is_empty() {
        let rows: Vec<Row> = report
            .stiffness
            .iter()
            .map(|r| {
                let n = |v: Option<f64>, none: &str| v.map_or(none.to_string(), |v| format!("{v:.4e}"));
                let unbounded = if r.stiffness.is_some() { "unbounded" } else { "-" };
                vec![
                    Cell::name(&r.joint),
                    Cell::text(&n(r.stiffness, "none")),
                    Cell::text(&n(r.low, "-")),
                    Cell::text(&n(r.high, unbounded)),
                    Cell::name(r.unit),
                ]
                .into()
            })
            .collect();
        let head = ["joint", "stiffness", "95% low", "95% high", "unit"];
        out.push_str(&table("small", None, "Joint stiffness (1 / compliance)", &head, &rows));
    }
    for line in report_lines(&report.identified_text()) {
        let _ = writeln!(out, "<p>{}</p>", escape(line));
    }
    let mut down = String::new();
    super::calibration::write_down_weighted(&mut down, report.loss.as_deref(), &report.down_weighted, "pose");
    for line in report_lines(&down) {
        let _ = writeln!(out, "<p>{}</p>", escape(line));
    }
    if let Some(scale) = &report.prior_scale {
        out.push_str(&prior_scale(scale));
    }
    if let Some(selection) = &report.selection {
        out.push_str(&selection_table(selection));
    }
    out.push_str("</section>\n");
    out
}

/// The non-empty lines of `text`.
fn report_lines(text: &str) -> impl Iterator<Item = &str> {
    text.lines().map(str::trim).filter(|l| !l.is_empty())
}

/// `--prior auto`'s or `auto-ml`'s curve as a table, the chosen scale marked.
pub(super) fn prior_scale(scale: &crate::calibration::prior_scale::PriorScale) -> String {
    use crate::calibration::prior_scale::ScaleBy;
    let (heading, values) = match scale.by {
        ScaleBy::Cv => ("CV RMS mm", &scale.cv_rms),
        ScaleBy::Ml => ("log evidence", &scale.log_evidence),
    };
    let rows: Vec<Row> = (scale.scales.iter().zip(values).enumerate())
        .filter(|(k, (s, _))| scale.by == ScaleBy::Cv || *k == scale.chosen || s.log2().fract() == 0.0)
        .map(|(k, (s, value))| {
            let cells = vec![Cell::name(&format!("{s:.4}")), Cell::text(&format!("{value:.4}"))];
            Row { cells, class: if k == scale.chosen { "flagged" } else { "" } }
        })
        .collect();
    let caption = format!(
        "Prior scale: --prior {} chose {:.4} times its standard deviations by {} (in-sample: --folds K gives \
         the nested figure)",
        scale.label(),
        scale.scale(),
        super::calibration::prior_scale_method(scale),
    );
    let classes: Vec<Row> = (scale.classes.iter())
        .map(|c| Row {
            cells: vec![
                Cell::name(&c.class),
                Cell::text(&c.parameters.to_string()),
                Cell::text(&format!("{:.4}", c.scale)),
            ],
            class: "",
        })
        .collect();
    let by_class = match classes.is_empty() {
        true => String::new(),
        false => table(
            "small",
            None,
            &format!(
                "Prior scales per class: --prior {} (the one scale's curve below, for comparison)",
                scale.label()
            ),
            &["class", "parameters", "scale"],
            &classes,
        ),
    };
    by_class + &table("small", None, &caption, &["scale", heading], &rows)
}

/// `--select`'s path as a table, the chosen step marked, and its notes.
pub(super) fn selection_table(selection: &super::calibration::SelectionReport) -> String {
    let start = if selection.criterion == "t" { "every candidate" } else { "no joint parameter" };
    let rows: Vec<Row> = (selection.steps.iter().enumerate())
        .map(|(k, step)| {
            let score = match (step.score.is_nan(), step.se.is_nan()) {
                (true, _) => String::new(),
                (false, true) => format!("{:.4}", step.score),
                (false, false) => format!("{:.4} ± {:.4}", step.score, step.se),
            };
            let cells = vec![
                Cell::name(&k.to_string()),
                Cell::name(step.parameter.as_deref().unwrap_or(start)),
                Cell::text(&score),
                Cell::name(&step.note_text().unwrap_or_default()),
            ];
            Row { cells, class: if k == selection.chosen { "flagged" } else { "" } }
        })
        .collect();
    let caption = format!("Parameter selection by {} (the chosen step shaded)", selection.criterion);
    let mut out = table("selection", None, &caption, &["step", "parameter", "score", "note"], &rows);
    let _ = writeln!(
        out,
        "<p>Selected ({}): {}</p>\n<p class=\"note\">Path scores: {}</p>",
        selection.selected.len(),
        escape(&selection.selected.join(", ")),
        escape(&selection.scores)
    );
    for trade in &selection.trades {
        let _ = writeln!(out, "<p>Trade: {}</p>", escape(&trade.to_string()));
    }
    if !selection.held.is_empty() {
        let items: Vec<String> = selection.held.iter().map(|h| format!("<li>{}</li>", escape(h))).collect();
        let _ = writeln!(
            out,
            "<details><summary>Not candidates, held ({})</summary><ul>{}</ul></details>",
            selection.held.len(),
            items.concat()
        );
    }
    out
}

/// What was held: each reason in words with its parameters, then the combinations.
fn held(report: &CalibrationReport) -> String {
    held_section(&report.held)
}

/// The section of what was held (`held`): each reason in words with its parameters, then the
/// combinations in a collapsible list.
pub(super) fn held_section(held: &[Held]) -> String {
    let mut out = format!("<section id=\"held\">\n<h2>Held fixed ({} parameters)</h2>\n<ul>\n", held.len());
    if held.is_empty() {
        out.push_str("<li>Nothing: every parameter asked for was estimated.</li>\n");
    }
    for g in held_groups(held) {
        let names: Vec<String> = g.parameters.iter().map(|p| format!("<code>{}</code>", escape(p))).collect();
        let _ = writeln!(out, "<li>{}: {}</li>", names.join(", "), escape(&g.words));
    }
    out.push_str("</ul>\n");
    let combinations: Vec<String> = held.iter().filter_map(combination).collect();
    if !combinations.is_empty() {
        let _ = writeln!(
            out,
            "<details class=\"combinations\">\n<summary>The {} combinations held (the held parameter first; the \
             others' estimates absorb it)</summary>\n<ul>",
            combinations.len()
        );
        for c in &combinations {
            let _ = writeln!(out, "<li><code>{}</code></li>", escape(c));
        }
        out.push_str("</ul>\n</details>\n");
    }
    out.push_str("</section>\n");
    out
}

/// The cells of an error table's row: count, mean, RMS, max, RMS per axis.
fn stats_cells(label: &str, s: &ErrorStats) -> Vec<Cell> {
    let mut cells = vec![Cell::name(label), Cell::text(&s.count.to_string())];
    cells.extend([s.mean, s.rms, s.max].iter().chain(&s.rms_axis).map(|v| Cell::text(&format!("{v:.4}"))));
    cells
}

/// The heads of an error table.
const STATS: [&str; 8] = ["", "count", "mean", "rms", "max", "rms x", "rms y", "rms z"];

/// One set's table: pooled and per marker at each stage, a probe's orientation errors.
fn set_table(set: &SetEvaluation, role: Role) -> String {
    let mut rows: Vec<Row> = Vec::new();
    let mut group = |label: String, stats: &[ErrorStats]| {
        for (k, (stage, s)) in set.stages.iter().zip(stats).enumerate() {
            let cells = stats_cells(&format!("{label}, {stage}"), s);
            rows.push(Row { cells, class: if k == 0 { "group" } else { "" } });
        }
    };
    group("every marker".into(), &set.pooled);
    if set.marker_ids.len() > 1 {
        for (id, stats) in set.marker_ids.iter().zip(&set.per_marker) {
            group(format!("marker {id}"), stats);
        }
    }
    if let Some(o) = &set.orientation {
        group("orientation (deg)".into(), o);
    }
    let caption = format!("{} ({}): marker position errors (mm)", set.name, role.words());
    table("set small", Some(&set.name), &caption, &STATS, &rows)
}

/// The errors: what each number weighs, a table per set (and per marker), the k-fold
/// cross-validation, the worst poses, the predicted accuracy, the noise.
fn errors(report: &CalibrationReport) -> String {
    let mut out = String::from("<section id=\"errors\">\n<h2>Errors per set and per marker</h2>\n");
    let w = &report.weighting;
    let _ = writeln!(
        out,
        "<dl class=\"weighting\"><dt>before</dt><dd>{}</dd><dt>after</dt><dd>{}</dd><dt>errors</dt><dd>{}</dd>\
         <dt>whitened</dt><dd>{}</dd></dl>",
        escape(&w.before),
        escape(&w.after),
        escape(&w.errors),
        escape(&w.whitened)
    );
    for (k, set) in report.sets.iter().enumerate() {
        out.push_str(&set_table(set, if k == 0 { Role::Training } else { Role::HeldOut }));
    }
    if let Some(pooled) = &report.held_out {
        out.push_str(&set_table(pooled, Role::Pooled));
    }
    let folds: Vec<&SetVerdict> =
        report.verdict.sets.iter().filter(|s| s.role == Role::CrossValidation).collect();
    for (name, before, after) in
        report.validation.iter().filter(|(n, _, _)| folds.iter().any(|f| &f.set == n))
    {
        let rows = vec![stats_cells("before", before).into(), stats_cells("after", after).into()];
        out.push_str(&table(
            "set small",
            Some(name),
            &format!("{name}: marker position errors (mm)"),
            &STATS,
            &rows,
        ));
    }
    if let Some(cv) = &report.cross_validation {
        let _ = writeln!(out, "<p class=\"note\">{}</p>", escape(cv.text().trim()));
    }
    out.push_str(&worst(report));
    if !report.predicted.is_empty() {
        let rows: Vec<Row> = (report.predicted.iter())
            .map(|p| {
                let cells = [p.mean_mm, p.max_mm, p.parameters_mm, p.floor_mm]
                    .map(|v| Cell::text(&format!("{v:.4}")));
                std::iter::once(Cell::name(&p.set)).chain(cells).collect::<Vec<_>>().into()
            })
            .collect();
        let head = ["set", "mean mm", "max mm", "parameters alone mm", "floor mm"];
        let caption = "Predicted position error SD at the held-out poses (parameter covariance, the floor in quadrature)";
        out.push_str(&table("small", None, caption, &head, &rows));
    }
    if let Some(noise) = &report.noise {
        let rows: Vec<Row> = (noise.iter())
            .map(|r| {
                let cells = [r.sigma, r.low, r.high].map(|v| Cell::text(&format!("{v:.3e}")));
                let mut row: Vec<Cell> = std::iter::once(Cell::name(&r.name)).chain(cells).collect();
                row.push(Cell::name(r.unit));
                row.into()
            })
            .collect();
        let head = ["noise", "sigma", "95% low", "95% high", "unit"];
        out.push_str(&table(
            "small",
            None,
            "Noise estimated from the residuals (feasible GLS)",
            &head,
            &rows,
        ));
    }
    out.push_str("</section>\n");
    out
}

/// The worst poses of each set after calibration, as a table.
fn worst(report: &CalibrationReport) -> String {
    let Some(first) = report.sets.iter().find(|s| !s.poses.is_empty()) else { return String::new() };
    let mut head: Vec<String> = vec!["set".into(), "line".into(), "marker".into()];
    head.extend(first.stages.iter().map(|s| format!("{s} mm")));
    head.extend(["whitened".into(), "worst (sd)".into(), "flagged".into()]);
    let mut rows: Vec<Row> = Vec::new();
    for set in &report.sets {
        for (k, m) in super::poses::worst(set) {
            let p = &set.poses[k];
            let mut cells = vec![
                Cell::name(&set.name),
                Cell::text(&p.line.to_string()),
                Cell::text(&set.marker_ids[m].to_string()),
            ];
            cells.extend((0..set.stages.len()).map(|s| Cell::text(&format!("{:.4}", p.distance(s, m)))));
            cells.push(Cell::text(&format!("{:.2}", p.whitened)));
            cells.push(Cell::text(&format!("{:.2}", p.worst)));
            cells.push(Cell::text(if p.flagged { "yes" } else { "no" }));
            rows.push(Row { cells, class: if p.flagged { "flagged" } else { "" } });
        }
    }
    let caption =
        format!("The worst poses after calibration ({} per set; every pose below)", super::poses::WORST);
    let head: Vec<&str> = head.iter().map(String::as_str).collect();
    table("worst small", None, &caption, &head, &rows)
}

/// The warnings in full.
fn warnings(report: &CalibrationReport) -> String {
    let mut out = String::from("<section id=\"warnings\">\n<h2>Warnings</h2>\n");
    if report.warnings.is_empty() {
        out.push_str("<p>None.</p>\n");
    } else {
        out.push_str("<ul>\n");
        for w in &report.warnings {
            let _ = writeln!(out, "<li>{}</li>", escape(&w.to_string()));
        }
        out.push_str("</ul>\n");
    }
    out.push_str("</section>\n");
    out
}
