//! Self-contained HTML pages: the pieces every report page shares (the style, HTML tables, the
//! figures inline as SVG with a caption that says what to look for, every pose of every set in
//! a collapsible section), and the page of a report that has only text ([`page`]).
//! [`crate::report::calibration_page`] builds the calibration's designed page from them.
//!
//! A page refers to nothing outside itself (no scripts, no style sheets, no images by
//! address), so it opens in any browser without a network and prints; it is written as
//! well-formed XML (XHTML-compatible markup) so that an XML parser reads it.

use super::residuals::ResidualSet;
use std::fmt::Write;

/// `text` with `&`, `<`, `>` and `"` escaped for HTML and XML.
pub fn escape(text: &str) -> String {
    text.replace('&', "&amp;").replace('<', "&lt;").replace('>', "&gt;").replace('"', "&quot;")
}

/// The style of every page: readable on screen, printable (A4, no link or figure split
/// across pages), colours from the Okabe-Ito palette (safe for colour-blind readers).
const STYLE: &str = "\
:root { --ink: #1b1f24; --muted: #57606a; --line: #d0d7de; --head: #f0f3f6; --good: #009E73;
  --warn: #D55E00; --blue: #0072B2; }
body { font: 14px/1.45 system-ui, 'Segoe UI', Roboto, 'DejaVu Sans', sans-serif; color: var(--ink);
  max-width: 1240px; margin: 0 auto; padding: 24px 32px; }
h1 { font-size: 24px; margin: 0 0 2px; }
h2 { font-size: 18px; margin: 32px 0 8px; padding-bottom: 4px; border-bottom: 1px solid var(--line); }
h3 { font-size: 15px; margin: 20px 0 6px; }
p.meta { color: var(--muted); margin: 0 0 16px; }
.card { border: 1px solid var(--line); border-left: 6px solid var(--good); border-radius: 8px;
  padding: 12px 20px 16px; background: #f6fbf9; }
.card.warned { border-left-color: var(--warn); background: #fdf8f4; }
.card h2 { border: none; margin: 4px 0 8px; }
.headline { font-size: 16px; margin: 4px 0 12px; }
.big { font-size: 30px; font-weight: 700; }
.note { color: var(--muted); }
table { border-collapse: collapse; margin: 6px 0 18px; font-variant-numeric: tabular-nums; }
caption { caption-side: top; text-align: left; font-weight: 600; padding: 4px 0; }
th, td { padding: 3px 9px; border-bottom: 1px solid var(--line); text-align: right; white-space: nowrap; }
th { background: var(--head); font-weight: 600; }
th.name, td.name { text-align: left; }
td.good { color: #006b4f; font-weight: 600; }
tr.flagged td { background: #fbe3d5; }
tr.group td { border-top: 2px solid var(--line); }
td.bar { padding: 0 6px; }
td.bar svg { display: block; }
ul.warnings li { margin: 2px 0; }
.count { display: inline-block; min-width: 2.2em; padding: 0 6px; margin-right: 6px; border-radius: 10px;
  background: var(--warn); color: #fff; text-align: center; font-weight: 600; }
code { font-family: ui-monospace, 'DejaVu Sans Mono', monospace; font-size: 12.5px; }
details { margin: 8px 0; }
summary { cursor: pointer; font-weight: 600; }
dl.weighting { display: grid; grid-template-columns: max-content auto; gap: 2px 12px; }
dl.weighting dt { font-weight: 600; }
dl.weighting dd { margin: 0; }
figure { margin: 18px 0 26px; break-inside: avoid; }
figure svg { max-width: 100%; height: auto; border: 1px solid var(--line); }
figcaption { max-width: 900px; margin-top: 4px; }
figcaption b { font-family: ui-monospace, 'DejaVu Sans Mono', monospace; font-weight: 600; }
pre { font-size: 12px; background: #f6f8fa; padding: 12px; overflow-x: auto; }
@page { size: A4; margin: 12mm; }
@media print {
  body { max-width: none; padding: 0; font-size: 10.5px; }
  .card, figure, table.small { break-inside: avoid; }
  h2, h3, caption { break-after: avoid; }
  details::details-content { content-visibility: visible; display: block; }
  summary { list-style: none; }
}
";

/// The page's start: the document type, the head with `title` and the style, the heading
/// `title` and the line `meta` under it.
pub fn start(title: &str, meta: &str) -> String {
    format!(
        "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\"/>\n\
         <meta name=\"viewport\" content=\"width=device-width, initial-scale=1\"/>\n<title>{0}</title>\n\
         <style>\n{STYLE}</style>\n</head>\n<body>\n<header>\n<h1>{0}</h1>\n<p class=\"meta\">{1}</p>\n</header>\n",
        escape(title),
        escape(meta)
    )
}

/// The page's end.
pub fn end() -> &'static str {
    "</body>\n</html>\n"
}

/// One cell of an HTML table: its markup (already escaped) and its class.
#[derive(Debug, Clone, Default)]
pub struct Cell {
    /// Its content, HTML.
    pub html: String,
    /// Its class (`name` for a left-aligned label).
    pub class: &'static str,
}

impl Cell {
    /// A cell of `text`, escaped.
    pub fn text(text: &str) -> Self {
        Self { html: escape(text), class: "" }
    }

    /// A label: `text`, escaped, left-aligned.
    pub fn name(text: &str) -> Self {
        Self { html: escape(text), class: "name" }
    }

    /// A cell of markup, with a class.
    pub fn html(html: String, class: &'static str) -> Self {
        Self { html, class }
    }
}

/// One row of an HTML table, with its class (`flagged`, `group`).
#[derive(Debug, Clone, Default)]
pub struct Row {
    /// Its cells.
    pub cells: Vec<Cell>,
    /// Its class, if any.
    pub class: &'static str,
}

impl From<Vec<Cell>> for Row {
    fn from(cells: Vec<Cell>) -> Self {
        Self { cells, class: "" }
    }
}

/// An HTML table of class `class` (and `data-set` = `set` when given), captioned `caption`,
/// the heads `head` (left-aligned over the first column and over labels), the rows `rows`.
pub fn table(class: &str, set: Option<&str>, caption: &str, head: &[&str], rows: &[Row]) -> String {
    let mut out = format!("<table class=\"{class}\"");
    if let Some(set) = set {
        let _ = write!(out, " data-set=\"{}\"", escape(set));
    }
    out.push_str(">\n");
    if !caption.is_empty() {
        let _ = writeln!(out, "<caption>{}</caption>", escape(caption));
    }
    out.push_str("<thead><tr>");
    for (k, h) in head.iter().enumerate() {
        // a head over labels is left-aligned as they are
        let label = rows.first().and_then(|r| r.cells.get(k)).is_some_and(|c| c.class == "name");
        let class = if k == 0 || label { " class=\"name\"" } else { "" };
        let _ = write!(out, "<th{class}>{}</th>", escape(h));
    }
    out.push_str("</tr></thead>\n<tbody>\n");
    for row in rows {
        match row.class {
            "" => out.push_str("<tr>"),
            class => {
                let _ = write!(out, "<tr class=\"{class}\">");
            }
        }
        for cell in &row.cells {
            match cell.class {
                "" => {
                    let _ = write!(out, "<td>{}</td>", cell.html);
                }
                class => {
                    let _ = write!(out, "<td class=\"{class}\">{}</td>", cell.html);
                }
            }
        }
        out.push_str("</tr>\n");
    }
    out.push_str("</tbody>\n</table>\n");
    out
}

/// An SVG from plotters made fit to sit inside HTML: without its XML declaration, and without
/// the namespace address (HTML does not need it, and the page names no address).
fn inline_svg(svg: &str) -> String {
    let start = svg.find("<svg").unwrap_or(0);
    svg[start..].replace(" xmlns=\"http://www.w3.org/2000/svg\"", "")
}

/// What a figure of [`crate::report::figures`] shows and what to look for in it, by the name
/// its module gives it (`errors-by-pose-<set>.svg`, `histogram.svg`, `error-vs-<joint>.svg`,
/// `error-vs-torque-<joint>.svg`, `selection-path.svg`, `prior-scale.svg`).
pub fn caption(name: &str) -> String {
    let stem = name.strip_suffix(".svg").unwrap_or(name);
    if let Some(set) = stem.strip_prefix("errors-by-pose-") {
        return format!(
            "Each pose of {set} in the file's order: its error (RMS over its markers, mm) at every stage on one \
             scale; when the errors after are under a third of those before, a second panel draws them on their \
             own scale, the ratio written. Look for poses that stay high after calibration (crossed when \
             flagged) and runs of neighbouring poses that share an error (a drift while measuring)."
        );
    }
    if let Some(set) = ["errors-by-observation-", "errors-by-view-"].iter().find_map(|p| stem.strip_prefix(p))
    {
        let (set, unit) = set.strip_suffix("-deg").map_or((set, "mm"), |set| (set, "deg"));
        return format!(
            "Each observation of {set} by its line in the file: its error ({unit}) at every stage on one scale, \
             crossed when flagged. Look for lines that stay high after calibration and runs of neighbouring lines \
             that share an error (a drift while measuring)."
        );
    }
    if let Some(unit) =
        ["histogram", "histogram-deg"].iter().position(|h| *h == stem).map(|i| ["mm", "deg"][i])
    {
        return format!(
            "The density of the errors at the last stage ({unit}), each set on the same bins, so that sets of \
             different sizes compare. Look for a held-out set that reaches further right than the training set \
             (over-fitting, or a change between the sessions) and a long tail (outliers)."
        );
    }
    if let Some(joint) = stem.strip_prefix("error-vs-torque-") {
        return format!(
            "Each marker's signed error after calibration (x, y, z, mm) against the gravity torque on {joint}. Look \
             for a slope: a compliance the model leaves out."
        );
    }
    if let Some(joint) = stem.strip_prefix("error-vs-") {
        return format!(
            "Each signed residual at the last stage (a marker's x, y, z or an observation's row, mm; a probe's \
             rotation too) against {joint}'s value. A flat band about zero is the aim; look for trends, steps where the motion turns (backlash) \
             and waves (a gear's cyclic error): errors the model does not describe."
        );
    }
    if stem == "selection-path" {
        return "The selection's score after each step (the table of the path names each step's parameter). Look for \
                where the curve flattens: the chosen step (circled) is the smallest model within one standard error \
                of the best."
            .to_string();
    }
    if stem == "prior-scale" {
        return "The cross-validated RMS error (mm) after calibrating with the preset's standard deviations \
                times each scale s (log axis); the chosen scale, the lowest, is circled. Look for a clear minimum: \
                a flat curve says the data barely care how strong the prior is, a minimum at an end that the \
                preset is far from this robot."
            .to_string();
    }
    format!("The figure {name}.")
}

/// The figures (`(file name, SVG)`) inline, each with its name and [`caption`].
pub fn figures(figures: &[(String, String)]) -> String {
    let mut out = String::new();
    for (name, svg) in figures {
        let _ = writeln!(
            out,
            "<figure id=\"{0}\">\n{1}\n<figcaption><b>{0}</b>: {2}</figcaption>\n</figure>",
            escape(name),
            inline_svg(svg),
            escape(&caption(name))
        );
    }
    out
}

/// Every residual of each set of observations or views (`sets`), a collapsible section per
/// set: its file and line, what it is, each stage's residual (mm for a length, deg for an
/// angle: signed for an observation, a norm for a view), whitened, and the flag; flagged rows
/// shaded.
pub fn residual_details(sets: &[&ResidualSet]) -> String {
    let mut out = String::new();
    for set in sets.iter().filter(|s| !s.residuals.is_empty()) {
        let flagged = set.residuals.iter().filter(|r| r.flagged()).count();
        let _ = writeln!(
            out,
            "<details class=\"poses\">\n<summary>{}: {} {}s, {} flagged</summary>",
            escape(&set.name),
            set.residuals.len(),
            set.item,
            flagged
        );
        let (mm, deg) =
            (set.residuals.iter().any(|r| r.mm.is_some()), set.residuals.iter().any(|r| r.deg.is_some()));
        let mut head: Vec<String> = vec!["file".into(), "line".into(), "kind".into()];
        for stage in &set.stages {
            head.extend(
                (mm.then(|| format!("{stage} mm")).into_iter()).chain(deg.then(|| format!("{stage} deg"))),
            );
        }
        head.extend(["whitened".into(), "flagged".into()]);
        // One stage drawn (a model as it stands): the residuals' "after".
        let stages: Vec<usize> = if set.stages.len() == 1 { vec![1] } else { vec![0, 1] };
        let value = |v: Option<(f64, f64)>, s: usize| {
            v.map_or(String::new(), |v| format!("{:.4}", if s == 0 { v.0 } else { v.1 }))
        };
        let rows: Vec<Row> = (set.residuals.iter())
            .map(|r| {
                let mut cells =
                    vec![Cell::text(&r.file), Cell::name(&r.line.to_string()), Cell::text(&r.kind)];
                for &s in &stages {
                    cells.extend(
                        (mm.then(|| Cell::text(&value(r.mm, s))))
                            .into_iter()
                            .chain(deg.then(|| Cell::text(&value(r.deg, s)))),
                    );
                }
                cells.push(Cell::text(&format!("{:.2}", r.whitened)));
                cells.push(Cell::text(if r.flagged() { "yes" } else { "no" }));
                Row { cells, class: if r.flagged() { "flagged" } else { "" } }
            })
            .collect();
        let head: Vec<&str> = head.iter().map(String::as_str).collect();
        out.push_str(&table("poses", Some(&set.name), "", &head, &rows));
        out.push_str("</details>\n");
    }
    out
}

/// The page of a report that has only text (`evaluate`'s): `text` as printed, then the
/// `figures` (`(file name, SVG text)`) inline with their captions, then every residual of
/// `residuals` (markers', observations', views').
pub fn page(title: &str, text: &str, residuals: &[&ResidualSet], figures: &[(String, String)]) -> String {
    let mut out = start(title, "");
    let _ =
        writeln!(out, "<section id=\"report\">\n<h2>Report</h2>\n<pre>{}</pre>\n</section>", escape(text));
    if !figures.is_empty() {
        let _ =
            writeln!(out, "<section id=\"figures\">\n<h2>Figures</h2>\n{}</section>", self::figures(figures));
    }
    let every = residual_details(residuals);
    let _ = writeln!(out, "<section id=\"poses\">\n<h2>Every pose</h2>\n{every}</section>");
    out.push_str(end());
    out
}
