//! The report of a calibration from observation files or from a tree's views
//! ([`ObservationsReport`]) as a designed, self-contained page, as
//! [`calibration_page`](super::calibration_page) makes the marker report's: the verdict as a
//! card (the text's verdict rows: each set's errors before and after calibration by quantity,
//! counted and flagged; the warnings by cause), the parameters with their 95% intervals drawn, the choices made from the data (a
//! prior's scale, a selection's path), what was held, the figures inline, what the data cannot
//! see, every residual of each set and the warnings in full, and the text report in full in a
//! collapsible section. No script, no address.

use super::calibration::ParameterRow;
use super::calibration_page::{held_section, parameter_table, prior_scale, selection_table};
use super::html::{Cell, Row, escape, table};
use super::observations::ObservationsReport;
use super::residuals::ResidualSet;
use super::verdict::{QuantityRow, WarningCount};
use crate::calibration::{Held, Warning};
use std::fmt::Write;

/// What a page of observation files or views shows ([`page`]).
#[derive(Debug, Clone)]
pub struct FilesPage<'a> {
    /// The fit in one line (the text report's first).
    pub meta: &'a str,
    /// The verdict's rows, the training set's first.
    pub residuals: &'a [QuantityRow],
    /// Whether the fit converged.
    pub converged: bool,
    /// The warnings.
    pub warnings: &'a [Warning],
    /// The estimates.
    pub parameters: &'a [ParameterRow],
    /// What was held, typed.
    pub held: &'a [Held],
    /// What the data cannot see as a whole.
    pub unseen: &'a [crate::calibration::Unseen],
    /// `--prior auto`'s scale and curve.
    pub prior_scale: Option<&'a crate::calibration::prior_scale::PriorScale>,
    /// `--select`'s path.
    pub selection: Option<&'a super::calibration::SelectionReport>,
    /// The text report, in full.
    pub text: &'a str,
    /// The figures, inline: `(file name, SVG)` ([`super::html::figures`]).
    pub figures: &'a [(String, String)],
    /// Every residual of each set ([`super::html::residual_details`]).
    pub residuals_of_sets: &'a [&'a ResidualSet],
    /// With several training files: each one's name and number of observations (a warning's
    /// row named in its file).
    pub training_files: &'a [(String, usize)],
}

/// The page of `report`, titled `title`.
pub fn page(report: &FilesPage<'_>, title: &str) -> String {
    let mut out = super::html::start(title, report.meta);
    out.push_str(&summary(report));
    out.push_str("<section id=\"parameters\">\n<h2>Parameters</h2>\n");
    let (setup, robot): (Vec<ParameterRow>, Vec<ParameterRow>) =
        report.parameters.iter().cloned().partition(|p| is_setup(&p.name));
    out.push_str(&parameter_table(&robot));
    out.push_str(
        "<p class=\"note\">The robot's corrections: the bars draw each estimate (dot) and its 95% interval \
         (estimate ± 1.96 standard errors) on one scale per unit, 0 at the centre line.</p>\n",
    );
    if !setup.is_empty() {
        out.push_str("<h3>The set-up</h3>\n");
        out.push_str(&parameter_table(&setup));
        out.push_str(
            "<p class=\"note\">Where the instruments are (fixed points, planes, cameras and targets, a device's \
             or a tracker's placement, length zeros): values, not corrections.</p>\n",
        );
    }
    if let Some(scale) = report.prior_scale {
        out.push_str(&prior_scale(scale));
    }
    if let Some(selection) = report.selection {
        out.push_str(&selection_table(selection));
    }
    out.push_str("</section>\n");
    out.push_str(&held_section(report.held));
    if !report.unseen.is_empty() {
        out.push_str("<section id=\"unseen\">\n<h2>Not seen by these data, held</h2>\n<ul>\n");
        for u in report.unseen {
            let _ = writeln!(out, "<li>{}</li>", escape(&u.to_string()));
        }
        out.push_str("</ul>\n</section>\n");
    }
    if !report.figures.is_empty() {
        let _ = writeln!(
            out,
            "<section id=\"figures\">\n<h2>Figures</h2>\n{}</section>",
            super::html::figures(report.figures)
        );
    }
    let _ = writeln!(
        out,
        "<section id=\"poses\">\n<h2>Every observation</h2>\n<p class=\"note\">Each set's residuals, one row \
         per observation (also in --poses-csv and --json); flagged rows are shaded.</p>\n{}</section>",
        super::html::residual_details(report.residuals_of_sets)
    );
    out.push_str(&warnings(report));
    let _ = writeln!(
        out,
        "<section id=\"report\">\n<h2>The report in full</h2>\n<details>\n<summary>The text report (every \
         residual is in --json)</summary>\n<pre>{}</pre>\n</details>\n</section>",
        escape(report.text)
    );
    out.push_str(super::html::end());
    out
}

/// Every warning in full, its rows named in their files.
fn warnings(report: &FilesPage<'_>) -> String {
    let mut out = String::from("<section id=\"warnings\">\n<h2>Warnings</h2>\n");
    if report.warnings.is_empty() {
        out.push_str("<p>None.</p>\n");
    } else {
        out.push_str("<ul>\n");
        for w in report.warnings {
            let text = w.render(&|k, line| super::line_in(report.training_files, k, line));
            let _ = writeln!(out, "<li>{}</li>", escape(&text));
        }
        out.push_str("</ul>\n");
    }
    out.push_str("</section>\n");
    out
}

/// Whether the parameter `name` is the set-up's (`point1.x`, `plane2.d`, `camera.rx`,
/// `tracker.z@tuesday`, `pair.zero`), not the robot's.
fn is_setup(name: &str) -> bool {
    let owner = name.split('.').next().unwrap_or(name);
    let numbered =
        |prefix: &str| owner.strip_prefix(prefix).is_some_and(|n| n.chars().all(|c| c.is_ascii_digit()));
    numbered("point")
        || numbered("plane")
        || ["camera", "target", "device", "tracker", "pair"].contains(&owner)
}

/// The verdict card: the headline (the first held-out set's first quantity, else the
/// training set's), a row per set and quantity, the warnings by cause.
fn summary(report: &FilesPage<'_>) -> String {
    let class = if report.warnings.is_empty() && report.converged { "card" } else { "card warned" };
    let mut out = format!("<section id=\"summary\" class=\"{class}\">\n<h2>Verdict</h2>\n");
    let headline = (report.residuals.iter().find(|r| r.set != "training")).or(report.residuals.first());
    if let Some(h) = headline {
        let unit = h.unit;
        let role = if h.set == "training" { "training" } else { "held out" };
        let _ = writeln!(
            out,
            "<p class=\"headline\"><span class=\"big\">{:.4} {unit}</span> RMS after calibration on {} ({role}), \
             {:.4} {unit} before: {:.1} times lower.</p>",
            h.rms[1],
            escape(format!("{} {}", h.set, h.quantity).trim_end()),
            h.rms[0],
            h.rms[0] / h.rms[1].max(f64::MIN_POSITIVE)
        );
    }
    let rows: Vec<Row> = (report.residuals.iter())
        .map(|r| {
            let [label, count, rms, max, flagged] = r.cells();
            let cells = vec![
                Cell::name(&label),
                Cell::text(&count),
                Cell::html(escape(&rms), "good"),
                Cell::text(&max),
                Cell::text(&flagged),
            ];
            cells.into()
        })
        .collect();
    let head = ["set", "count", "RMS before -> after", "max before -> after", "flagged"];
    out.push_str(&table("verdict small", None, "Errors before and after calibration", &head, &rows));
    if !report.converged {
        out.push_str("<p><strong>The fit did not converge</strong>: see the warnings.</p>\n");
    }
    if report.warnings.is_empty() {
        out.push_str("<p>No warnings.</p>\n");
    } else {
        out.push_str("<p>Warnings by cause:</p>\n<ul class=\"warnings\">\n");
        for w in report.warnings.iter().map(WarningCount::of) {
            let _ = writeln!(out, "<li><span class=\"count\">{}</span>{}</li>", w.count, escape(&w.about));
        }
        out.push_str("</ul>\n");
    }
    out.push_str("</section>\n");
    out
}

/// The page of a report of observation files or views (`$report`, whose text is `$text`):
/// the fields both reports share by name (its verdict's rows, its selection, ...), taken once.
macro_rules! files_page {
    ($report:expr, $text:expr, $figures:expr, $residuals:expr) => {
        FilesPage {
            meta: $text.lines().next().unwrap_or(""),
            residuals: &$report.verdict,
            converged: $report.converged,
            warnings: &$report.warnings,
            parameters: &$report.parameters,
            held: &$report.held,
            unseen: &$report.unseen,
            prior_scale: $report.prior_scale.as_ref(),
            selection: $report.selection.as_ref(),
            text: $text,
            figures: $figures,
            residuals_of_sets: $residuals,
            training_files: &$report.training_files,
        }
    };
}

/// `page` for each report of observation files or views: the designed page of its fields
/// ([`files_page!`]).
macro_rules! files_page_of {
    ($($report:ty),*) => {$(
        impl $report {
            /// The report as a designed page titled `title` ([`page`]); `text` is [`Self::text`],
            /// `figures` the figures it shows inline (`(file name, SVG)`), `residuals` every
            /// residual of each set.
            pub fn page(
                &self,
                title: &str,
                text: &str,
                figures: &[(String, String)],
                residuals: &[&ResidualSet],
            ) -> String {
                page(&files_page!(self, text, figures, residuals), title)
            }
        }
    )*};
}

files_page_of!(ObservationsReport);
