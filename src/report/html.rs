//! One self-contained HTML page: the report's text tables, a table of every pose of every
//! set, and the figures inline as SVG. It refers to nothing outside itself (no scripts, no
//! style sheets, no images by address), so it opens in any browser without a network, and it
//! is written as well-formed XML (XHTML-compatible markup) so that an XML parser reads it.

use crate::calibration::SetEvaluation;
use std::fmt::Write;

/// `text` with `&`, `<`, `>` and `"` escaped for HTML and XML.
pub fn escape(text: &str) -> String {
    text.replace('&', "&amp;").replace('<', "&lt;").replace('>', "&gt;").replace('"', "&quot;")
}

/// An SVG from plotters made fit to sit inside HTML: without its XML declaration, and without
/// the namespace address (HTML does not need it, and the page names no address).
fn inline_svg(svg: &str) -> String {
    let start = svg.find("<svg").unwrap_or(0);
    svg[start..].replace(" xmlns=\"http://www.w3.org/2000/svg\"", "")
}

/// The page titled `title`: `text` (the report as printed) in a preformatted block, each
/// set's poses as a table (line, marker, error at each stage, and a probe's orientation
/// error, whitened residual, flag), and
/// `figures` (`(file name, SVG text)`) inline.
pub fn page(title: &str, text: &str, sets: &[&SetEvaluation], figures: &[(String, String)]) -> String {
    let mut out = String::new();
    let _ = writeln!(out, "<!DOCTYPE html>");
    let _ = writeln!(out, "<html lang=\"en\">");
    let _ = writeln!(out, "<head>\n<meta charset=\"utf-8\"/>\n<title>{}</title>", escape(title));
    let _ = writeln!(
        out,
        "<style>\nbody {{ font-family: sans-serif; margin: 2em; }}\npre {{ font-size: 12px; background: #f6f6f6; \
         padding: 1em; overflow-x: auto; }}\ntable {{ border-collapse: collapse; font-size: 12px; }}\ntd, th {{ \
         border: 1px solid #ccc; padding: 2px 6px; text-align: right; }}\ntr.flagged {{ background: #fdd; }}\n\
         figure {{ display: inline-block; margin: 0.5em; }}\n</style>\n</head>\n<body>"
    );
    let _ = writeln!(out, "<h1>{}</h1>", escape(title));
    let _ = writeln!(out, "<h2>Report</h2>\n<pre>{}</pre>", escape(text));
    let _ = writeln!(out, "<h2>Figures</h2>");
    for (name, svg) in figures {
        let _ = writeln!(
            out,
            "<figure id=\"{0}\">\n{1}\n<figcaption>{0}</figcaption>\n</figure>",
            escape(name),
            inline_svg(svg)
        );
    }
    for set in sets.iter().filter(|s| !s.poses.is_empty()) {
        let _ =
            writeln!(out, "<h2>Poses: {}</h2>\n<table>\n<tr><th>line</th><th>marker</th>", escape(&set.name));
        let probe = set.orientation.is_some();
        for stage in &set.stages {
            let _ = write!(out, "<th>{} (mm)</th><th>x</th><th>y</th><th>z</th>", escape(stage));
            if probe {
                let _ = write!(out, "<th>{} (deg)</th>", escape(stage));
            }
        }
        let _ = writeln!(out, "<th>whitened</th><th>worst (sd)</th><th>flagged</th></tr>");
        for p in &set.poses {
            for (m, id) in set.marker_ids.iter().enumerate() {
                let class = if p.flagged { " class=\"flagged\"" } else { "" };
                let _ = write!(out, "<tr{class}><td>{}</td><td>{id}</td>", p.line);
                for s in 0..set.stages.len() {
                    let e = p.errors[s][m];
                    let _ = write!(
                        out,
                        "<td>{:.4}</td><td>{:.4}</td><td>{:.4}</td><td>{:.4}</td>",
                        p.distance(s, m),
                        e[0],
                        e[1],
                        e[2]
                    );
                    if let Some(o) = &p.orientation {
                        let _ = write!(out, "<td>{:.4}</td>", nalgebra::Vector3::from(o[s]).norm());
                    }
                }
                let flag = if p.flagged { "yes" } else { "no" };
                let _ =
                    writeln!(out, "<td>{:.2}</td><td>{:.2}</td><td>{flag}</td></tr>", p.whitened, p.worst);
            }
        }
        let _ = writeln!(out, "</table>");
    }
    let _ = writeln!(out, "</body>\n</html>");
    out
}
