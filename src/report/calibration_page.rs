//! The calibration report as a designed, self-contained HTML page, in the text's order: the
//! verdict as a card, the parameters with their 95% intervals drawn, what was held (the
//! combinations in a collapsible section), the errors per set and per marker as tables, the
//! figures with captions that say what to look for, every pose in collapsible sections, the
//! warnings in full. No script, no address: it opens and prints offline.

use super::calibration::ParameterRow;
use super::html::{Cell, Row, escape, table};
use super::verdict::{combination, held_groups};
use crate::calibration::Held;
use std::fmt::Write;

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
