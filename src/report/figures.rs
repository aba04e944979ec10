//! Figures of a study, and of scored pose sets, as SVG text (plotters, without any font library: the SVG names the
//! font and the viewer draws the text).

use crate::limits::MAX_BINS;
use crate::model::JointKind;
use crate::simulation::{PoseChoice, Replications, Statistic, Study, StudyResults, Summary};
use plotters::coord::types::RangedCoordf64;
use plotters::prelude::*;

/// The series colours: Okabe and Ito's blue, vermillion and bluish green, Tol's purple, and
/// black: told apart under the common colour-vision deficiencies, and each at least 3:1
/// against the white ground (no yellow).
pub const PALETTE: [RGBColor; 5] = [
    RGBColor(0, 114, 178),
    RGBColor(213, 94, 0),
    RGBColor(0, 158, 115),
    RGBColor(170, 51, 119),
    RGBColor(0, 0, 0),
];

/// The `i`-th series colour of [`PALETTE`], cycling.
fn colour(i: usize) -> RGBColor {
    PALETTE[i % PALETTE.len()]
}

/// A figure that could not be drawn.
#[derive(Debug, thiserror::Error)]
#[error("cannot draw figure `{name}`: {message}")]
pub struct FigureError {
    /// The figure's file name.
    pub name: String,
    /// What plotters said.
    pub message: String,
}

/// Every figure of a study, as `(file name, SVG text)`:
/// - `histogram-<estimator>-np<N>-sigma<s>.svg`: the distribution of dE in each case (the
///   paper's Figs. 1 and 4), every one on the same bins, x-range and height; where the study has
///   the paper's row, its mean (solid vermillion), lowest and highest (dashed vermillion) drawn
///   and its SD and share above zero written, beside this study's mean (dashed black);
/// - `improvement-vs-points-<estimator>.svg`: mean dE against `N_p` on a log axis, with the
///   mean of each point set (Fig. 2), when the study has several `N_p`;
/// - `improvement-vs-sigma-<estimator>.svg`: mean dE against `sigma_me` (Fig. 3), when it has
///   several `sigma_me`; the paper's means on both as black squares.
///
/// The paper's values are cited by [`reference_source`].
pub fn study_figures(study: &Study, results: &StudyResults) -> Result<Vec<(String, String)>, FigureError> {
    let mut figures = Vec::new();
    let compared = || (1..study.estimators.len()).flat_map(|e| (0..study.cases.len()).map(move |c| (c, e)));
    // Every histogram on the same bins, x-range and height, so that the panels compare; the
    // range reaches the paper's lowest and highest too.
    let groups: Vec<Vec<f64>> = compared().map(|(c, e)| results.improvements(c, e)).collect();
    let extremes: Vec<f64> = (study.cases.iter().filter_map(|c| paper_row(study, c)))
        .flat_map(|r| [r.lowest, r.highest])
        .collect();
    let scale = HistogramScale::shared(&groups, &extremes);
    let source = reference_source(study);
    for ((c, e), values) in compared().zip(&groups) {
        let (case, estimator) = (&study.cases[c], &study.estimators[e]);
        let (suffix, poses) = pose_labels(case.poses);
        let name = format!("histogram-{estimator}-np{}-sigma{}{suffix}.svg", case.points, case.sigma_me);
        let title =
            format!("dE of {estimator}: N_p = {}, sigma_me = {} mm{poses}", case.points, case.sigma_me);
        let marks = study_marks(values, paper_row(study, case), &source);
        let svg = histogram(&title, values, scale, &marks).map_err(|m| error(&name, m))?;
        figures.push((name, svg));
    }
    for (e, estimator) in study.estimators.iter().enumerate().skip(1) {
        for axis in [Axis::Points, Axis::Sigma] {
            if let Some(svg) = trend_figure(study, results, e, axis) {
                let name = format!("improvement-vs-{}-{estimator}.svg", axis.name());
                figures.push((name.clone(), svg.map_err(|m| error(&name, m))?));
            }
        }
    }
    Ok(figures)
}

/// Where the study's reference rows come from, to cite on its figures: the part of its
/// description before the first colon (`Zak et al., Table 1` for the embedded `paper-table1`),
/// or `the study's reference rows` when its description has no such short prefix.
pub fn reference_source(study: &Study) -> String {
    match study.description.split_once(':') {
        Some((source, _)) if !source.trim().is_empty() && source.len() <= 40 => source.trim().to_string(),
        _ => "the study's reference rows".to_string(),
    }
}

/// The lines drawn over a study's histogram of `values`: the paper's row (mean solid, lowest
/// and highest dashed, vermillion, cited as `source`) if any, and this study's mean (dashed
/// black) with its SD and share above zero.
fn study_marks(values: &[f64], paper: Option<&crate::simulation::Reference>, source: &str) -> Vec<Mark> {
    let mut marks = Vec::new();
    if let Some(r) = paper {
        let label = format!("paper's mean {} ({source}; SD {}, {}% > 0)", r.mean, r.sd, r.above_zero);
        marks.push(Mark { at: vec![r.mean], label, colour: colour(1), dashed: false });
        let label = format!("paper's lowest {} and highest {}", r.lowest, r.highest);
        marks.push(Mark { at: vec![r.lowest, r.highest], label, colour: colour(1), dashed: true });
    }
    if values.len() >= 2 {
        let ours = Summary::of(values);
        let label = format!(
            "this study's mean {} (SD {}, {}% > 0)",
            shown(ours.mean),
            shown(ours.sd),
            shown(ours.above_zero)
        );
        marks.push(Mark { at: vec![ours.mean], label, colour: BLACK, dashed: true });
    }
    marks
}

/// The paper's row for `case`, when the study has it and draws its poses at random, as the
/// paper does.
fn paper_row<'a>(
    study: &'a Study,
    case: &crate::simulation::Case,
) -> Option<&'a crate::simulation::Reference> {
    (case.poses == PoseChoice::Random).then(|| study.reference_for(case)).flatten()
}

/// The paper's mean dE for `case` ([`paper_row`]).
fn paper_mean(study: &Study, case: &crate::simulation::Case) -> Option<f64> {
    paper_row(study, case).map(|r| r.mean)
}

/// The x axis of a trend figure.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Axis {
    /// `N_p`, on a log axis.
    Points,
    /// `sigma_me` (mm).
    Sigma,
}

impl Axis {
    fn name(self) -> &'static str {
        if self == Axis::Points { "points" } else { "sigma" }
    }

    /// `(x, the other parameter)` of `case`.
    fn of(self, case: &crate::simulation::Case) -> (f64, f64) {
        match self {
            Axis::Points => (case.points as f64, case.sigma_me),
            Axis::Sigma => (case.sigma_me, case.points as f64),
        }
    }
}

/// Mean dE of estimator `e` against `axis` (one line per value of the other parameter and pose
/// choice, the point sets' means as dots, the paper's means as black squares), when the study
/// has several values on `axis`.
fn trend_figure(
    study: &Study,
    results: &StudyResults,
    e: usize,
    axis: Axis,
) -> Option<Result<String, String>> {
    let estimator = &study.estimators[e];
    let xs = distinct(study.cases.iter().map(|c| axis.of(c).0));
    if xs.len() < 2 {
        return None;
    }
    let others = distinct(study.cases.iter().map(|c| axis.of(c).1));
    let choices = study.cases.iter().fold(Vec::new(), |mut all, c| {
        if !all.contains(&c.poses) {
            all.push(c.poses);
        }
        all
    });
    let (mut series, mut paper) = (Vec::new(), Vec::new());
    for (&fixed, &choice) in others.iter().flat_map(|f| choices.iter().map(move |c| (f, c))) {
        let (mut means, mut sets, mut theirs) = (Vec::new(), Vec::new(), Vec::new());
        for (c, case) in study.cases.iter().enumerate() {
            let (x, at) = axis.of(case);
            if at == fixed && case.poses == choice {
                means.push((x, Summary::of(&results.improvements(c, e)).mean));
                sets.extend(results.set_means(c, e).into_iter().map(|m| (x, m)));
                theirs.extend(paper_mean(study, case).map(|m| (x, m)));
            }
        }
        let mut label =
            if axis == Axis::Points { format!("sigma_me = {fixed} mm") } else { format!("N_p = {fixed}") };
        if choices.len() > 1 {
            label += &format!(", {} poses", choice.name());
        }
        if !theirs.is_empty() {
            paper.push((format!("the paper's mean ({}), {label}", reference_source(study)), theirs));
        }
        series.push((label, means, sets));
    }
    let x_label = match axis {
        Axis::Points => "number of measurement points N_p (log scale)",
        Axis::Sigma => "measurement noise sigma_me (mm)",
    };
    let title = format!("mean dE of {estimator} (line) and of each point set (dots)");
    let log = (axis == Axis::Points).then_some(xs.as_slice());
    Some(trend(&title, x_label, &series, &paper, log))
}

/// How a case's poses are chosen, for file names (`-planned`) and titles (`, planned poses`);
/// nothing for random poses, the paper's.
fn pose_labels(poses: PoseChoice) -> (String, String) {
    match poses {
        PoseChoice::Random => (String::new(), String::new()),
        other => (format!("-{}", other.name()), format!(", {} poses", other.name())),
    }
}

fn error(name: &str, message: String) -> FigureError {
    FigureError { name: name.to_string(), message }
}

fn distinct(values: impl Iterator<Item = f64>) -> Vec<f64> {
    let mut out: Vec<f64> = Vec::new();
    for v in values {
        if !out.contains(&v) {
            out.push(v);
        }
    }
    out
}

/// `Err` naming how many of `values` are NaN or infinite: such a figure would be nonsense.
fn all_finite(values: impl IntoIterator<Item = f64>) -> Result<(), String> {
    let (mut total, mut bad) = (0, 0);
    for v in values {
        total += 1;
        bad += usize::from(!v.is_finite());
    }
    if bad > 0 {
        return Err(format!("{bad} of its {total} values are not finite (NaN or infinite): not drawn"));
    }
    Ok(())
}

/// The bins and the height shared by the histograms of a study: bins 5 points of dE wide (wider
/// if they would be more than [`MAX_BINS`]) over every finite value of every histogram and the
/// values to be marked on them (the paper's lowest and highest), and the highest count of any.
#[derive(Debug, Clone, Copy, PartialEq)]
struct HistogramScale {
    bins: Bins,
    top: f64,
}

impl HistogramScale {
    /// The scale of the histograms of `groups`, reaching `marked` too.
    fn shared(groups: &[Vec<f64>], marked: &[f64]) -> Self {
        let all: Vec<f64> = (groups.iter().flatten().chain(marked))
            .copied()
            .filter(|v| v.is_finite() && v.abs() < 1e300)
            .collect();
        let range = all.iter().fold(0.0f64, |m, v| m.max(v.abs())) * 2.0;
        let width = 5.0 * (range / 5.0 / MAX_BINS as f64).ceil().max(1.0);
        let low = (all.iter().copied().fold(0.0, f64::min) / width).floor() * width;
        let bins = Bins::from(low, width, &all);
        let top = groups.iter().map(|g| bins.counts(g).into_iter().max().unwrap_or(0)).max().unwrap_or(1);
        Self { bins, top: top as f64 }
    }
}

/// Histogram of dE (%) on the shared `scale`, with `marks` drawn over it.
fn histogram(title: &str, values: &[f64], scale: HistogramScale, marks: &[Mark]) -> Result<String, String> {
    all_finite(values.iter().copied())?;
    if values.is_empty() {
        return Err("no values".into());
    }
    if let Some(v) = values.iter().find(|v| v.abs() > 5e299) {
        return Err(format!("values up to {v:e}: too large to draw"));
    }
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, (720, 460)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| e.to_string())?;
        let y = "number of runs N_r (one scale for every histogram of the study)";
        let x = "dE (%) (one range for every histogram of the study)";
        draw_histogram(&root, title, values, scale.bins, (x, y), marks, Some(scale.top))?;
        root.present().map_err(|e| e.to_string())?;
    }
    Ok(svg)
}

/// The round width (1, 2, 2.5 or 5 times a power of ten) at or above `raw`.
fn round_width(raw: f64) -> f64 {
    let raw = raw.max(1e-9);
    let power = 10f64.powf(raw.log10().floor());
    let step = [1.0, 2.0, 2.5, 5.0, 10.0].into_iter().find(|&m| raw <= m * power * (1.0 + 1e-12));
    step.unwrap_or(10.0) * power
}

/// Equal bins from `low`, `width` wide, enough of them for every value.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Bins {
    low: f64,
    width: f64,
    count: usize,
}

impl Bins {
    fn from(low: f64, width: f64, values: &[f64]) -> Self {
        let high = values.iter().copied().fold(low, f64::max);
        Self { low, width, count: ((high - low) / width).floor() as usize + 1 }
    }

    /// How many of `values` fall in each bin (those beyond an end in the bin at that end).
    fn counts(&self, values: &[f64]) -> Vec<u32> {
        let mut counts = vec![0u32; self.count];
        for v in values {
            counts[(((v - self.low) / self.width).floor().max(0.0) as usize).min(self.count - 1)] += 1;
        }
        counts
    }

    /// About `target` bins of a round width (1, 2, 2.5 or 5 times a power of ten) over `values`
    /// and `marker`; with a `grain` (values on a lattice of that step, like shares of a fixed
    /// number of runs), a whole number of grains wide and edged half a grain off the lattice.
    fn round(values: &[f64], marker: Option<f64>, target: usize, grain: Option<f64>) -> Self {
        let all = || values.iter().copied().chain(marker);
        let (lo, hi) = (all().fold(f64::INFINITY, f64::min), all().fold(f64::NEG_INFINITY, f64::max));
        let mut width = round_width((hi - lo) / target as f64);
        let low = match grain {
            Some(g) => {
                width = (width / g).round().max(1.0) * g;
                ((lo / g).round() - 0.5) * g
            }
            None => (lo / width).floor() * width,
        };
        Self::from(low, width, &[hi])
    }
}

/// Vertical lines at the values `at` drawn over a histogram, with one legend entry.
#[derive(Debug, Clone, PartialEq)]
struct Mark {
    /// Where (x, the histogram's unit).
    at: Vec<f64>,
    /// The legend's text.
    label: String,
    /// The lines' colour.
    colour: RGBColor,
    /// Dashed rather than solid.
    dashed: bool,
}

/// A histogram of `values` on `area` (axes described by `desc`, x then y), with `marks` drawn
/// over it, up to `highest` counts (default: its own highest).
fn draw_histogram(
    area: &DrawingArea<SVGBackend<'_>, plotters::coord::Shift>,
    title: &str,
    values: &[f64],
    bins: Bins,
    (x_desc, y_desc): (&str, &str),
    marks: &[Mark],
    highest: Option<f64>,
) -> Result<(), String> {
    let Bins { low, width, count } = bins;
    let counts = bins.counts(values);
    // Room above the bars for the marks' legend.
    let headroom = if marks.is_empty() { 1.0 } else { 1.15 + 0.12 * marks.len() as f64 };
    let highest = highest.unwrap_or_else(|| f64::from(*counts.iter().max().unwrap_or(&1)));
    let top = (highest * headroom).ceil() + 1.0;
    let high = low + count as f64 * width;
    // Half a bin of room at each end and a wider right margin: no edge bar or end tick label
    // is cut off.
    let mut chart = ChartBuilder::on(area)
        .caption(title, ("sans-serif", 18))
        .margin(12)
        .margin_right(28)
        .x_label_area_size(40)
        .y_label_area_size(48)
        .build_cartesian_2d((low - width / 2.0)..(high + width / 2.0), 0.0..top)
        .map_err(|e| e.to_string())?;
    chart
        .configure_mesh()
        .x_desc(x_desc)
        .y_desc(y_desc)
        .y_labels((top as usize + 1).min(10))
        .y_label_formatter(&|v| if v.fract() == 0.0 { format!("{v:.0}") } else { String::new() })
        .x_label_formatter(&|v| shown_tick(*v))
        .draw()
        .map_err(|e| e.to_string())?;
    let bars = counts.iter().enumerate().map(|(i, &n)| {
        let x0 = low + i as f64 * width;
        Rectangle::new([(x0, 0.0), (x0 + width, f64::from(n))], colour(0).mix(0.6).filled())
    });
    chart.draw_series(bars).map_err(|e| e.to_string())?;
    for mark in marks {
        draw_mark(&mut chart, mark, top)?;
    }
    if !marks.is_empty() {
        legend(&mut chart)?;
    }
    Ok(())
}

/// `mark`'s lines from 0 to `top` on `chart`, and its legend entry.
fn draw_mark<'b>(chart: &mut Chart<'b, 'b>, mark: &Mark, top: f64) -> Result<(), String> {
    let style = mark.colour.stroke_width(if mark.dashed { 2 } else { 3 });
    let mut drawn = None;
    for &x in &mark.at {
        let line = [(x, 0.0), (x, top)];
        drawn = Some(if mark.dashed {
            chart.draw_series(DashedLineSeries::new(line, 8, 5, style)).map_err(|e| e.to_string())?
        } else {
            chart.draw_series(LineSeries::new(line, style)).map_err(|e| e.to_string())?
        });
    }
    if let Some(drawn) = drawn {
        // A dashed line's entry in two dashes, a solid line's in one.
        let gap = if mark.dashed { (8, 12) } else { (20, 0) };
        drawn.label(mark.label.as_str()).legend(move |(x, y)| {
            EmptyElement::at((x, y))
                + PathElement::new(vec![(0, 0), (gap.0, 0)], style)
                + PathElement::new(vec![(gap.1, 0), (20, 0)], style)
        });
    }
    Ok(())
}

/// The replications of a study, one figure per case and compared estimator,
/// `replications-<estimator>-np<N>-sigma<s>.svg`: a histogram over the replications of each
/// statistic of the paper's table (MEAN, SD, LOWEST, HIGHEST, % > 0 of dE), with the paper's
/// value drawn on it as a vermillion line where the study has the paper's row.
pub fn replication_figures(
    study: &Study,
    replications: &Replications,
) -> Result<Vec<(String, String)>, FigureError> {
    let mut figures = Vec::new();
    let count = replications.replications.len();
    let source = reference_source(study);
    for (e, estimator) in study.estimators.iter().enumerate().skip(1) {
        for (c, case) in study.cases.iter().enumerate() {
            let (suffix, poses) = pose_labels(case.poses);
            let name =
                format!("replications-{estimator}-np{}-sigma{}{suffix}.svg", case.points, case.sigma_me);
            let title = format!(
                "dE of {estimator}, N_p = {}, sigma_me = {} mm{poses}: the table over {count} replications",
                case.points, case.sigma_me
            );
            let runs = (study.point_sets * study.runs_per_set) as f64;
            let panels: Vec<Panel> = Statistic::ALL
                .iter()
                .map(|&statistic| {
                    let values = replications.values(c, e, statistic);
                    let paper = study.reference_for(case).map(|r| statistic.of_reference(r));
                    let marker = paper.map(|p| {
                        let rank = replications.paper_percentile(c, e, statistic, p);
                        (p, format!("paper {p}: percentile {rank:.1}"))
                    });
                    let grain = (statistic == Statistic::AboveZero).then_some(100.0 / runs);
                    let bins = Bins::round(&values, marker.as_ref().map(|m| m.0), 16, grain);
                    Panel { statistic, values, bins, marker }
                })
                .collect();
            let notes = [
                format!("{count} replications of {}", study.name),
                format!("master seeds derived from {}", replications.seed),
                format!("{} point sets x {} runs each", study.point_sets, study.runs_per_set),
                format!("vermillion line: the paper's value ({source})"),
            ];
            let svg = panel_figure(&title, &panels, &notes).map_err(|m| error(&name, m))?;
            figures.push((name, svg));
        }
    }
    Ok(figures)
}

/// One statistic's histogram in a replication figure.
struct Panel {
    statistic: Statistic,
    values: Vec<f64>,
    bins: Bins,
    marker: Option<(f64, String)>,
}

/// Five histograms in a 2 x 3 grid, the sixth cell for `notes`.
fn panel_figure(title: &str, panels: &[Panel], notes: &[String]) -> Result<String, String> {
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, (1260, 760)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| e.to_string())?;
        let root = root.titled(title, ("sans-serif", 22)).map_err(|e| e.to_string())?;
        let cells = root.split_evenly((2, 3));
        for (cell, panel) in cells.iter().zip(panels) {
            let name = panel.statistic.name();
            let x_desc = format!("{name} of dE (%)");
            let marks: Vec<Mark> = (panel.marker.iter())
                .map(|(at, label)| Mark {
                    at: vec![*at],
                    label: label.clone(),
                    colour: colour(1),
                    dashed: false,
                })
                .collect();
            draw_histogram(cell, name, &panel.values, panel.bins, (&x_desc, "replications"), &marks, None)?;
        }
        if let Some(cell) = cells.get(panels.len()) {
            for (i, line) in notes.iter().enumerate() {
                let position = (30, 60 + 28 * i as i32);
                cell.draw(&Text::new(line.as_str(), position, ("sans-serif", 18)))
                    .map_err(|e| e.to_string())?;
            }
        }
        root.present().map_err(|e| e.to_string())?;
    }
    Ok(svg)
}

/// A chart of `(x, y)` over a linear y axis and an x axis `X` (linear by default).
type Chart<'a, 'b, X = RangedCoordf64> = ChartContext<'a, SVGBackend<'b>, Cartesian2d<X, RangedCoordf64>>;

/// A 640 x 420 figure with one chart titled `caption` over `x` (a range, or a log axis) and
/// `y`, drawn by `draw`, and the series' legend (top right) if `with_legend`.
fn single_chart<X>(
    caption: &str,
    x: X,
    y: std::ops::Range<f64>,
    with_legend: bool,
    draw: impl FnOnce(&mut Chart<'_, '_, X::CoordDescType>) -> Result<(), String>,
) -> Result<String, String>
where
    X: plotters::coord::ranged1d::AsRangedCoord<Value = f64>,
{
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, (640, 420)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| e.to_string())?;
        let mut chart = ChartBuilder::on(&root)
            .caption(caption, ("sans-serif", 18))
            .margin(12)
            .x_label_area_size(40)
            .y_label_area_size(52)
            .build_cartesian_2d(x, y)
            .map_err(|e| e.to_string())?;
        draw(&mut chart)?;
        if with_legend {
            legend(&mut chart)?;
        }
        root.present().map_err(|e| e.to_string())?;
    }
    Ok(svg)
}

/// The chart's series labels in a box at its top right.
fn legend<'b, X: Ranged<ValueType = f64>>(chart: &mut Chart<'b, 'b, X>) -> Result<(), String> {
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::UpperRight)
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .draw()
        .map_err(|e| e.to_string())
}

/// A trend: `(label, means, per-set means)` of each series.
type Series = (String, Vec<(f64, f64)>, Vec<(f64, f64)>);

/// Lines of mean dE through `(x, mean)` points, with the per-set means as dots and the paper's
/// means (`(label, points)`) as black squares; on a log x axis ticked at `log_ticks` if given.
fn trend(
    title: &str,
    x_label: &str,
    series: &[Series],
    paper: &[(String, Vec<(f64, f64)>)],
    log_ticks: Option<&[f64]>,
) -> Result<String, String> {
    let theirs = paper.iter().flat_map(|(_, p)| p);
    let all = || series.iter().flat_map(|(_, m, s)| m.iter().chain(s)).chain(theirs.clone());
    all_finite(all().flat_map(|&(x, y)| [x, y]))?;
    let (mut x0, mut x1, mut y0, mut y1) = (f64::INFINITY, f64::NEG_INFINITY, 0.0f64, 0.0f64);
    for &(x, y) in all() {
        (x0, x1, y0, y1) = (x0.min(x), x1.max(x), y0.min(y), y1.max(y));
    }
    // Room above the data for the legend, an entry a line.
    let entries = (series.len() + paper.len()) as f64;
    let y = (y0 - 5.0)..(y1 + 5.0 + 0.09 * entries * (y1 - y0 + 10.0));
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, (640, 420)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| e.to_string())?;
        let mut builder = ChartBuilder::on(&root);
        builder.caption(title, ("sans-serif", 18)).margin(12).x_label_area_size(40).y_label_area_size(52);
        match log_ticks {
            Some(ticks) if x0 > 0.0 => {
                let x = ((x0 / 1.15)..(x1 * 1.15)).log_scale().with_key_points(ticks.to_vec());
                let mut chart = builder.build_cartesian_2d(x, y).map_err(|e| e.to_string())?;
                draw_trend(&mut chart, x_label, series, paper)?;
            }
            _ => {
                let pad = 0.05 * (x1 - x0).max(1e-9);
                let mut chart =
                    builder.build_cartesian_2d((x0 - pad)..(x1 + pad), y).map_err(|e| e.to_string())?;
                draw_trend(&mut chart, x_label, series, paper)?;
            }
        }
        root.present().map_err(|e| e.to_string())?;
    }
    Ok(svg)
}

/// The series of [`trend`] on `chart`, with the legend.
fn draw_trend<'b, X>(
    chart: &mut Chart<'b, 'b, X>,
    x_label: &str,
    series: &[Series],
    paper: &[(String, Vec<(f64, f64)>)],
) -> Result<(), String>
where
    X: Ranged<ValueType = f64> + plotters::coord::ranged1d::ValueFormatter<f64>,
{
    chart
        .configure_mesh()
        .x_desc(x_label)
        .y_desc("dE (%)")
        .x_label_formatter(&|v| shown_tick(*v))
        .y_label_formatter(&|v| shown_tick(*v))
        .draw()
        .map_err(|e| e.to_string())?;
    for (i, (label, means, sets)) in series.iter().enumerate() {
        let colour = colour(i);
        chart
            .draw_series(LineSeries::new(means.clone(), colour.stroke_width(2)))
            .map_err(|e| e.to_string())?
            .label(label.as_str())
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], colour.stroke_width(2)));
        chart
            .draw_series(sets.iter().map(|&p| Circle::new(p, 3, colour.filled())))
            .map_err(|e| e.to_string())?;
    }
    for (label, points) in paper {
        chart
            .draw_series(
                points
                    .iter()
                    .map(|&p| EmptyElement::at(p) + Rectangle::new([(-5, -5), (5, 5)], BLACK.filled())),
            )
            .map_err(|e| e.to_string())?
            .label(label.as_str())
            .legend(|(x, y)| Rectangle::new([(x + 5, y - 5), (x + 15, y + 5)], BLACK.filled()));
    }
    legend(chart)
}

/// A tick's value as a person writes it: `12`, `0.025`, `-5` (no `-0`, no trailing zeros).
fn shown_tick(v: f64) -> String {
    let v = if v.abs() < 1e-12 { 0.0 } else { v };
    let text = format!("{v:.6}");
    let text = text.trim_end_matches('0').trim_end_matches('.');
    text.to_string()
}

/// A name made of letters, digits and `-` only, for a file name.
pub(crate) fn file_stem(name: &str) -> String {
    let stem: String = name.chars().map(|c| if c.is_ascii_alphanumeric() { c } else { '-' }).collect();
    stem.trim_matches('-').to_string()
}

/// The bars of one set's items (a pose of markers, an observation, a view), each one's size at
/// every stage, as [`bar_figure`] draws them.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Bars<'a> {
    /// The figure's title.
    pub title: String,
    /// The stages (`before`, `after`; `model`).
    pub stages: &'a [String],
    /// What an item is, for the x axis: `pose`, `observation`, `view`.
    pub item: &'a str,
    /// The unit of the sizes: `mm`, `deg`.
    pub unit: &'a str,
    /// Each item's line in its file.
    pub lines: Vec<usize>,
    /// `values[stage][item]`, at least 0.
    pub values: Vec<Vec<f64>>,
    /// The items flagged at the last stage.
    pub flagged: Vec<bool>,
}

/// One panel with every stage's bar per item on one scale, in the file's order, labelled by
/// its line in the file; when the last stage's values are under a third of that scale, a
/// second panel with the last stage on its own scale, the ratio of the scales written.
pub(crate) fn bar_figure(bars: &Bars<'_>) -> Result<String, String> {
    all_finite(bars.values.iter().flatten().copied())?;
    let stages = bars.stages.len();
    let values = &bars.values;
    let top = |v: &[f64]| v.iter().copied().fold(0.0, f64::max).max(1e-9) * 1.1;
    let common = values.iter().map(|v| top(v)).fold(1e-9, f64::max);
    let own = top(&values[stages - 1]);
    let zoom = stages > 1 && own < common / 3.0;
    let unit = bars.unit;
    let mut svg = String::new();
    {
        let height = 300 * (1 + u32::from(zoom)) + 40;
        let root = SVGBackend::with_string(&mut svg, (900, height)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| e.to_string())?;
        let root = root.titled(&bars.title, ("sans-serif", 18)).map_err(|e| e.to_string())?;
        let panels = root.split_evenly((1 + usize::from(zoom), 1));
        let names: Vec<&str> = bars.stages.iter().map(String::as_str).collect();
        let caption = if stages > 1 {
            format!("{}: one scale, 0 to {} {unit}", names.join(" and "), shown(common))
        } else {
            format!("{}: 0 to {} {unit}", names[0], shown(common))
        };
        let all: Vec<usize> = (0..stages).collect();
        bar_panel(&panels[0], bars, &all, &caption, common)?;
        if zoom {
            let last = &bars.stages[stages - 1];
            let caption = format!(
                "{last} alone: 0 to {} {unit}, a scale {:.0} times finer than above",
                shown(own),
                common / own
            );
            bar_panel(&panels[1], bars, &[stages - 1], &caption, own)?;
        }
        root.present().map_err(|e| e.to_string())?;
    }
    Ok(svg)
}

/// `value` to 3 significant digits, for a scale written in a caption.
fn shown(value: f64) -> String {
    let digits = (2 - value.abs().max(1e-12).log10().floor() as i32).max(0) as usize;
    format!("{value:.digits$}")
}

/// A panel of `bars`' items: the bars of the stages `shown_stages` side by side per item
/// from 0 to `top`, the flagged items of the last stage crossed.
fn bar_panel(
    panel: &DrawingArea<SVGBackend<'_>, plotters::coord::Shift>,
    bars: &Bars<'_>,
    shown_stages: &[usize],
    caption: &str,
    top: f64,
) -> Result<(), String> {
    let (n, values) = (bars.lines.len(), &bars.values);
    let mut chart = ChartBuilder::on(panel)
        .caption(caption, ("sans-serif", 15))
        .margin(10)
        .x_label_area_size(36)
        .y_label_area_size(56)
        .build_cartesian_2d(0.0..n.max(1) as f64, 0.0..top)
        .map_err(|e| e.to_string())?;
    let x_desc = format!("{}, by its line in the file (as the tables name it)", bars.item);
    let y_desc = format!("error ({})", bars.unit);
    chart
        .configure_mesh()
        .x_desc(x_desc)
        .y_desc(y_desc)
        .x_label_formatter(&|v| bars.lines.get(*v as usize).map_or(String::new(), usize::to_string))
        .y_label_formatter(&|v| shown_tick(*v))
        .draw()
        .map_err(|e| e.to_string())?;
    let share = 0.8 / shown_stages.len() as f64;
    let last = bars.stages.len() - 1;
    for (slot, &s) in shown_stages.iter().enumerate() {
        let colour = colour(s);
        let rectangles = values[s].iter().enumerate().map(|(k, &v)| {
            let x0 = k as f64 + 0.1 + slot as f64 * share;
            Rectangle::new([(x0, 0.0), (x0 + share, v)], colour.filled())
        });
        let series = chart.draw_series(rectangles).map_err(|e| e.to_string())?;
        if shown_stages.len() > 1 {
            series
                .label(bars.stages[s].as_str())
                .legend(move |(x, y)| Rectangle::new([(x, y - 5), (x + 12, y + 5)], colour.filled()));
        }
        if s == last {
            let x = |k: usize| k as f64 + 0.1 + (slot as f64 + 0.5) * share;
            let flagged = bars.flagged.iter().enumerate().filter(|(_, f)| **f);
            chart
                .draw_series(flagged.map(|(k, _)| Cross::new((x(k), values[s][k]), 5, BLACK.stroke_width(2))))
                .map_err(|e| e.to_string())?;
        }
    }
    if shown_stages.len() > 1 {
        legend(&mut chart)?;
    }
    Ok(())
}

/// The density (per mm) of `values` over `bins` bins `width` wide from 0 (the last bin takes
/// what lies beyond): each bin's share of the values over its width, so that each set's bars
/// have area 1 whatever its number of values.
fn densities(values: &[f64], width: f64, bins: usize) -> Vec<f64> {
    let mut counts = vec![0usize; bins];
    for x in values {
        counts[((x / width).max(0.0) as usize).min(bins - 1)] += 1;
    }
    let total = values.len().max(1) as f64 * width;
    counts.into_iter().map(|c| c as f64 / total).collect()
}

/// The sizes `values` (`(set, sizes)`, at least 0, in `unit`) titled `what`: each set's
/// density on the same bins, as an outline (the sets overlaid, not interleaved).
pub(crate) fn density_figure(what: &str, values: &[(&str, Vec<f64>)], unit: &str) -> Result<String, String> {
    all_finite(values.iter().flat_map(|(_, v)| v.iter().copied()))?;
    let high = values.iter().flat_map(|(_, v)| v).copied().fold(0.0, f64::max).max(1e-9);
    let width = round_width(high / 20.0);
    let bins = (high / width).floor() as usize + 1;
    let density: Vec<Vec<f64>> = values.iter().map(|(_, v)| densities(v, width, bins)).collect();
    let top = density.iter().flatten().copied().fold(0.0, f64::max).max(1e-9) * 1.15;
    let caption = format!("{what}: each set's density, bins {} {unit}", shown_tick(width));
    let (x_desc, y_desc) =
        (format!("error ({unit})"), format!("density (1/{unit}): share of the set's errors per {unit}"));
    single_chart(&caption, 0.0..width * bins as f64, 0.0..top, true, |chart| {
        chart
            .configure_mesh()
            .x_desc(x_desc)
            .y_desc(y_desc)
            .x_label_formatter(&|v| shown_tick(*v))
            .y_label_formatter(&|v| shown_tick(*v))
            .draw()
            .map_err(|e| e.to_string())?;
        for (i, ((name, v), d)) in values.iter().zip(&density).enumerate() {
            let colour = colour(i);
            let mut outline = vec![(0.0, 0.0)];
            for (b, &h) in d.iter().enumerate() {
                outline.extend([(b as f64 * width, h), ((b + 1) as f64 * width, h)]);
            }
            outline.push((bins as f64 * width, 0.0));
            chart
                .draw_series([Polygon::new(outline.clone(), colour.mix(0.12).filled())])
                .map_err(|e| e.to_string())?;
            chart
                .draw_series(LineSeries::new(outline, colour.stroke_width(2)))
                .map_err(|e| e.to_string())?
                .label(format!("{name} ({} errors)", v.len()))
                .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], colour.stroke_width(2)));
        }
        Ok(())
    })
}

/// The load gravity puts on each joint of `model` (`chain` at its errors) at each of `poses`
/// (joint values in degrees, mm for a prismatic joint): N·m, N for a prismatic joint.
pub(super) fn gravity_loads<'q>(
    chain: &crate::kinematics::ChainAt,
    model: &crate::model::RobotModel,
    poses: impl Iterator<Item = &'q [f64]>,
) -> Vec<Vec<f64>> {
    let (mut q, mut tau) = (vec![0.0; model.dof()], vec![0.0; model.dof()]);
    poses
        .map(|values| {
            for ((q, joint), &v) in q.iter_mut().zip(&model.joints).zip(values) {
                *q = if joint.kind == JointKind::Revolute { v.to_radians() } else { v };
            }
            chain.gravity_torques(&q, &mut tau);
            tau.clone()
        })
        .collect()
}

/// Values of each set's items against a value of each item (a joint's), one panel per
/// component, as [`against_figure`] draws them.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Against<'a> {
    /// The figure's title.
    pub title: String,
    /// The sets' names, one colour each.
    pub sets: Vec<&'a str>,
    /// Each panel's component and unit: `("x", "mm")`.
    pub components: &'a [(&'a str, &'a str)],
    /// `points[component][set]`: `(x, value)`.
    pub points: Vec<Vec<Vec<(f64, f64)>>>,
    /// The x axis' label.
    pub x_label: &'a str,
    /// Signed values (a panel from `-y` to `y`, a line at zero), or sizes (from 0).
    pub signed: bool,
}

/// One panel per component, one scale for the components of a unit, a line at zero (signed
/// values), one colour per set, the sets' legend in a row of its own above the panels.
pub(crate) fn against_figure(a: &Against<'_>) -> Result<String, String> {
    let (components, points) = (a.components, &a.points);
    all_finite(points.iter().flatten().flatten().flat_map(|&(x, y)| [x, y]))?;
    let all = || points.iter().flatten().flatten();
    let (x0, x1) = all().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), p| (a.min(p.0), b.max(p.0)));
    let (x0, x1) = if x0 <= x1 { (x0, x1) } else { (0.0, 1.0) };
    let pad = 0.03 * (x1 - x0).max(1e-6);
    let reach = |unit: &str| {
        let of = components.iter().zip(points).filter(|((_, u), _)| *u == unit);
        of.flat_map(|(_, p)| p.iter().flatten()).fold(1e-9, |m: f64, p| m.max(p.1.abs())) * 1.1
    };
    let mut svg = String::new();
    {
        let height = 170 * components.len() as u32 + 114;
        let root = SVGBackend::with_string(&mut svg, (760, height)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| e.to_string())?;
        let root = root.titled(&a.title, ("sans-serif", 18)).map_err(|e| e.to_string())?;
        // The sets' legend in a row of its own, above the panels: it hides no point.
        let (key, root) = root.split_vertically(24);
        let mut x = 80;
        for (i, set) in a.sets.iter().enumerate() {
            key.draw(&Circle::new((x, 10), 4, colour(i).filled())).map_err(|e| e.to_string())?;
            let text = Text::new(*set, (x + 10, 3), ("sans-serif", 14));
            key.draw(&text).map_err(|e| e.to_string())?;
            // About 8 px a character at 14 px, and a gap.
            x += 10 + 8 * set.chars().count() as i32 + 40;
        }
        let panels = root.split_evenly((components.len(), 1));
        for (c, (panel, &(name, unit))) in panels.iter().zip(components).enumerate() {
            let last = c + 1 == components.len();
            let y = reach(unit);
            let mut chart = ChartBuilder::on(panel)
                .margin(8)
                .x_label_area_size(if last { 40 } else { 20 })
                .y_label_area_size(60)
                .build_cartesian_2d((x0 - pad)..(x1 + pad), if a.signed { -y } else { 0.0 }..y)
                .map_err(|e| e.to_string())?;
            let y_desc = format!("{name} ({unit})");
            let mut mesh = chart.configure_mesh();
            mesh.y_desc(y_desc.as_str()).y_labels(5).y_label_formatter(&|v| shown_tick(*v));
            mesh.x_label_formatter(&|v| shown_tick(*v));
            if last {
                mesh.x_desc(a.x_label);
            }
            mesh.draw().map_err(|e| e.to_string())?;
            let zero = [(x0 - pad, 0.0), (x1 + pad, 0.0)];
            chart.draw_series(LineSeries::new(zero, BLACK.stroke_width(1))).map_err(|e| e.to_string())?;
            for (i, p) in points[c].iter().enumerate() {
                chart
                    .draw_series(p.iter().map(|&xy| Circle::new(xy, 2, colour(i).filled())))
                    .map_err(|e| e.to_string())?;
            }
        }
        root.present().map_err(|e| e.to_string())?;
    }
    Ok(svg)
}

/// The path of a parameter selection (`selection-path.svg`): the score after each step (CV RMS
/// with its standard error as a bar, BIC, or the |t| of each dropped parameter) against the
/// step, the chosen step circled, and for CV the best step's RMS plus its standard error as a
/// line (the one-standard-error rule takes the first step under it); the report's table names
/// each step's parameter.
pub fn selection_figure(
    selection: &crate::report::calibration::SelectionReport,
) -> Result<(String, String), FigureError> {
    let name = "selection-path.svg".to_string();
    let points: Vec<(f64, f64, f64)> = (selection.steps.iter().enumerate())
        .filter(|(_, s)| s.score.is_finite())
        .map(|(k, s)| (k as f64, s.score, if s.se.is_finite() { s.se } else { 0.0 }))
        .collect();
    all_finite(points.iter().flat_map(|p| [p.1, p.2])).map_err(|m| error(&name, m))?;
    let low = points.iter().map(|p| p.1 - p.2).fold(f64::INFINITY, f64::min);
    let high = points.iter().map(|p| p.1 + p.2).fold(f64::NEG_INFINITY, f64::max);
    let (low, high) = if points.is_empty() { (0.0, 1.0) } else { (low, high) };
    let pad = ((high - low) * 0.08).max(1e-9);
    let (what, y_label) = match selection.criterion.as_str() {
        "cv" => ("forward selection, cross-validated RMS ± SE", "CV RMS (mm)"),
        "bic" => ("forward selection, BIC", "BIC"),
        _ => ("backward elimination, |t| of the parameter dropped", "|t|"),
    };
    let steps = selection.steps.len().max(2) as f64;
    let chosen = selection.chosen;
    let svg = single_chart(what, -0.5..steps - 0.5, low - pad..high + pad, false, |chart| {
        chart
            .configure_mesh()
            .x_desc("step (the report names each step's parameter)")
            .y_desc(y_label)
            .x_label_formatter(&|v| format!("{v:.0}"))
            .draw()
            .map_err(|e| e.to_string())?;
        let line = points.iter().map(|p| (p.0, p.1));
        chart.draw_series(LineSeries::new(line, colour(0).stroke_width(2))).map_err(|e| e.to_string())?;
        let bars = points.iter().filter(|p| p.2 > 0.0).map(|p| {
            PathElement::new(vec![(p.0, p.1 - p.2), (p.0, p.1 + p.2)], colour(0).mix(0.6).stroke_width(1))
        });
        chart.draw_series(bars).map_err(|e| e.to_string())?;
        let dots = points.iter().map(|p| Circle::new((p.0, p.1), 3, colour(0).filled()));
        chart.draw_series(dots).map_err(|e| e.to_string())?;
        if selection.criterion == "cv"
            && let Some(best) = points.iter().min_by(|a, b| a.1.total_cmp(&b.1))
        {
            // The one-standard-error rule: the first step under this line is chosen.
            let line = [(-0.5, best.1 + best.2), (steps - 0.5, best.1 + best.2)];
            chart
                .draw_series(LineSeries::new(line, colour(1).mix(0.5).stroke_width(1)))
                .map_err(|e| e.to_string())?;
        }
        let circled = points.iter().filter(|p| p.0 as usize == chosen);
        chart
            .draw_series(circled.map(|p| Circle::new((p.0, p.1), 8, colour(1).stroke_width(2))))
            .map_err(|e| e.to_string())?;
        Ok(())
    })
    .map_err(|m| error(&name, m))?;
    Ok((name, svg))
}

/// The curve `--prior auto` chose its scale from (`prior-scale.svg`): the cross-validated RMS
/// marker error after calibration (mm) against the scale `s` multiplying every standard
/// deviation of the preset, on a log axis ticked at the scales tried, the chosen scale (the
/// lowest RMS, ties to the smaller `s`) circled. Scales whose calibration failed (no finite RMS)
/// are left out. By the marginal likelihood with a scale per class (`auto-ml:PRESET:classes`),
/// each class's profile log evidence `log p(y | s_c, s_others)` (less the largest of the scales
/// per class) dashed beside the one-scale curve, named with its scale.
pub fn prior_scale_figure(
    scale: &crate::calibration::prior_scale::PriorScale,
) -> Result<(String, String), FigureError> {
    use crate::calibration::prior_scale::ScaleBy;
    let name = "prior-scale.svg".to_string();
    let (values, what, unit) = match scale.by {
        ScaleBy::Cv => (&scale.cv_rms, "CV RMS error (mm)", " mm"),
        ScaleBy::Ml => (&scale.log_evidence, "log evidence, less its largest", ""),
    };
    let points: Vec<(f64, f64)> = (scale.scales.iter().zip(values))
        .filter(|(s, r)| **s > 0.0 && s.is_finite() && r.is_finite())
        .map(|(&s, &r)| (s, r))
        .collect();
    if points.is_empty() {
        return Err(error(&name, "no scale has a finite score".into()));
    }
    // `auto-ml:PRESET:classes`: each class's profile, the others at their scales.
    let classes: Vec<(String, Vec<(f64, f64)>)> = (scale.classes.iter())
        .map(|c| {
            let finite = (scale.scales.iter().zip(&c.log_evidence))
                .filter(|(s, e)| **s > 0.0 && s.is_finite() && e.is_finite())
                .map(|(&s, &e)| (s, e));
            let label = format!("{} ({} parameters): s = {:.3}", c.class, c.parameters, c.scale);
            (label, finite.collect())
        })
        .collect();
    let (x0, x1) = points.iter().fold((f64::INFINITY, 0.0f64), |(a, b), p| (a.min(p.0), b.max(p.0)));
    let every = points.iter().chain(classes.iter().flat_map(|c| &c.1));
    let (y0, y1) = every.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), p| (a.min(p.1), b.max(p.1)));
    let pad = ((y1 - y0) * 0.15).max(1e-3 * y1.abs().max(1e-9));
    // The powers of 2 as ticks (the marginal likelihood's grid is finer).
    let ticks: Vec<f64> = points.iter().map(|p| p.0).filter(|s| s.log2().fract().abs() < 1e-9).collect();
    let x = ((x0 / 1.4)..(x1 * 1.4)).log_scale().with_key_points(ticks);
    let chosen = scale.scales.get(scale.chosen).zip(values.get(scale.chosen));
    let caption = format!("--prior {}: {what} by scale", scale.label());
    let svg = single_chart(&caption, x, (y0 - pad)..(y1 + 2.0 * pad), true, |chart| {
        chart
            .configure_mesh()
            .x_desc(format!("scale s of {}'s standard deviations (log scale)", scale.preset))
            .y_desc(what)
            .x_label_formatter(&|v| scale_tick(*v))
            .y_label_formatter(&|v| shown_tick(*v))
            .draw()
            .map_err(|e| e.to_string())?;
        chart
            .draw_series(LineSeries::new(points.clone(), colour(0).stroke_width(2)))
            .map_err(|e| e.to_string())?
            .label(format!("{what} at each scale"))
            .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], colour(0).stroke_width(2)));
        chart
            .draw_series(points.iter().map(|&p| Circle::new(p, 3, colour(0).filled())))
            .map_err(|e| e.to_string())?;
        for (i, (label, curve)) in classes.iter().enumerate() {
            // Blue and vermillion are the one-scale curve and the chosen circle's.
            let c = colour(2 + i);
            let dashed = DashedLineSeries::new(curve.clone(), 6, 4, c.stroke_width(2));
            chart
                .draw_series(dashed)
                .map_err(|e| e.to_string())?
                .label(label.clone())
                .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], c.stroke_width(2)));
        }
        if let Some((&s, &rms)) = chosen.filter(|(s, r)| **s > 0.0 && r.is_finite()) {
            chart
                .draw_series([Circle::new((s, rms), 8, colour(1).stroke_width(2))])
                .map_err(|e| e.to_string())?
                .label(match scale.by {
                    ScaleBy::Cv => format!("chosen: s = {}, {}{unit}", scale_tick(s), shown(rms)),
                    ScaleBy::Ml => format!("chosen: s = {s:.3}, the largest evidence"),
                })
                .legend(|(x, y)| Circle::new((x + 10, y), 6, colour(1).stroke_width(2)));
        }
        Ok(())
    })
    .map_err(|m| error(&name, m))?;
    Ok((name, svg))
}

/// A scale as a tick: `1/16` ... `1/2` below 1, `2` ... `16` above.
fn scale_tick(s: f64) -> String {
    if s < 1.0 && s > 0.0 && (1.0 / s).fract().abs() < 1e-9 {
        format!("1/{}", shown_tick(1.0 / s))
    } else {
        shown_tick(s)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// WCAG's relative luminance of `c`.
    fn luminance(c: RGBColor) -> f64 {
        let linear = |v: u8| {
            let v = f64::from(v) / 255.0;
            if v <= 0.04045 { v / 12.92 } else { ((v + 0.055) / 1.055).powf(2.4) }
        };
        0.2126 * linear(c.0) + 0.7152 * linear(c.1) + 0.0722 * linear(c.2)
    }

    #[test]
    fn the_palette_stands_out_on_white_and_its_colours_differ() {
        for (i, &c) in PALETTE.iter().enumerate() {
            let contrast = 1.05 / (luminance(c) + 0.05);
            assert!(contrast >= 3.0, "colour {i} {c:?}: contrast {contrast:.2} against white, under 3:1");
            assert!(PALETTE[..i].iter().all(|&d| d != c), "colour {i} twice");
        }
        // Yellow (and every light colour) is out: plotters' own YELLOW fails the rule.
        assert!(1.05 / (luminance(YELLOW) + 0.05) < 3.0);
    }

    #[test]
    fn densities_have_area_one_whatever_the_number_of_values() {
        for n in [7, 200] {
            let values: Vec<f64> = (0..n).map(|k| (k as f64 * 0.013) % 0.3).collect();
            let high = values.iter().copied().fold(0.0, f64::max);
            let width = round_width(high / 20.0);
            let bins = (high / width).floor() as usize + 1;
            let d = densities(&values, width, bins);
            let area: f64 = d.iter().sum::<f64>() * width;
            assert!((area - 1.0).abs() < 1e-12, "{n} values: area {area}");
            assert!(bins as f64 * width > high, "the highest value has a bin");
        }
    }

    #[test]
    fn the_study_histograms_share_their_bins_and_height() {
        let scale = HistogramScale::shared(&[vec![1.0, 2.0, 3.0], vec![-22.0, 61.0]], &[]);
        let Bins { low, width, count } = scale.bins;
        assert_eq!((low, width), (-25.0, 5.0));
        assert!(low + count as f64 * width > 61.0);
        assert_eq!(scale.top, 3.0, "the highest count of any histogram");
        // The paper's lowest and highest widen the range, not the height.
        let marked = HistogramScale::shared(&[vec![1.0, 2.0, 3.0], vec![-22.0, 61.0]], &[-53.0, 80.2]);
        let Bins { low, width, count } = marked.bins;
        assert_eq!((low, width, marked.top), (-55.0, 5.0, 3.0));
        assert!(low + count as f64 * width > 80.2);
    }

    #[test]
    fn ticks_are_written_as_a_person_writes_them() {
        assert_eq!(shown_tick(-0.0), "0");
        assert_eq!(shown_tick(-1e-17), "0");
        assert_eq!(shown_tick(0.1 + 0.2), "0.3");
        assert_eq!(shown_tick(192.0), "192");
        assert_eq!(shown_tick(-0.025), "-0.025");
    }

    #[test]
    fn n_p_is_on_a_log_axis_ticked_at_the_study_values_with_the_papers_means() {
        let means: Vec<(f64, f64)> = [12.0, 24.0, 48.0, 96.0, 192.0].iter().map(|&n| (n, 30.0)).collect();
        let series = vec![("sigma_me = 0 mm".to_string(), means.clone(), means.clone())];
        let paper = vec![("the paper's mean".to_string(), vec![(12.0, 3.97), (192.0, 21.71)])];
        let ticks = [12.0, 24.0, 48.0, 96.0, 192.0];
        let svg = trend("t", "N_p (log scale)", &series, &paper, Some(&ticks)).unwrap();
        for tick in ["\n12\n", "\n24\n", "\n192\n", "s mean"] {
            assert!(svg.contains(tick), "`{tick}` in the figure");
        }
        assert!(!svg.contains("\n100\n"), "only the study's values are ticked");
    }
}
