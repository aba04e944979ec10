//! Figures of a study, and of scored pose sets, as SVG text (plotters, without any font library: the SVG names the
//! font and the viewer draws the text).

use crate::calibration::{PoseErrors, SetEvaluation};
use crate::limits::MAX_BINS;
use crate::model::{Joint, JointKind};
use crate::simulation::{PoseChoice, Replications, Statistic, Study, StudyResults, Summary};
use plotters::coord::types::RangedCoordf64;
use plotters::prelude::*;

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
///   paper's Figs. 1 and 4);
/// - `improvement-vs-points-<estimator>.svg`: mean dE against `N_p`, with the mean of each
///   point set (Fig. 2), when the study has several `N_p`;
/// - `improvement-vs-sigma-<estimator>.svg`: mean dE against `sigma_me` (Fig. 3), when it has
///   several `sigma_me`.
pub fn study_figures(study: &Study, results: &StudyResults) -> Result<Vec<(String, String)>, FigureError> {
    let mut figures = Vec::new();
    for (e, estimator) in study.estimators.iter().enumerate().skip(1) {
        for (c, case) in study.cases.iter().enumerate() {
            let (suffix, poses) = pose_labels(case.poses);
            let name = format!("histogram-{estimator}-np{}-sigma{}{suffix}.svg", case.points, case.sigma_me);
            let title =
                format!("dE of {estimator}: N_p = {}, sigma_me = {} mm{poses}", case.points, case.sigma_me);
            let svg = histogram(&title, &results.improvements(c, e)).map_err(|m| error(&name, m))?;
            figures.push((name, svg));
        }
        let points = distinct(study.cases.iter().map(|c| c.points as f64));
        let sigmas = distinct(study.cases.iter().map(|c| c.sigma_me));
        for (axis, values, other) in [("points", &points, &sigmas), ("sigma", &sigmas, &points)] {
            if values.len() < 2 {
                continue;
            }
            let name = format!("improvement-vs-{axis}-{estimator}.svg");
            let mut series = Vec::new();
            let choices = study.cases.iter().fold(Vec::new(), |mut all, c| {
                if !all.contains(&c.poses) {
                    all.push(c.poses);
                }
                all
            });
            for (&fixed, &choice) in other.iter().flat_map(|f| choices.iter().map(move |c| (f, c))) {
                let (mut means, mut sets) = (Vec::new(), Vec::new());
                for (c, case) in study.cases.iter().enumerate() {
                    let (x, at) = if axis == "points" {
                        (case.points as f64, case.sigma_me)
                    } else {
                        (case.sigma_me, case.points as f64)
                    };
                    if at == fixed && case.poses == choice {
                        means.push((x, Summary::of(&results.improvements(c, e)).mean));
                        sets.extend(results.set_means(c, e).into_iter().map(|m| (x, m)));
                    }
                }
                let mut label = if axis == "points" {
                    format!("sigma_me = {fixed} mm")
                } else {
                    format!("N_p = {fixed}")
                };
                if choices.len() > 1 {
                    label += &format!(", {} poses", choice.name());
                }
                series.push((label, means, sets));
            }
            let x_label = if axis == "points" {
                "number of measurement points N_p"
            } else {
                "measurement noise sigma_me (mm)"
            };
            let title = format!("mean dE of {estimator} (line) and of each point set (dots)");
            let svg = trend(&title, x_label, &series).map_err(|m| error(&name, m))?;
            figures.push((name, svg));
        }
    }
    Ok(figures)
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

/// Histogram of dE (%) in bins 5 points wide, wider if it would have more than [`MAX_BINS`].
fn histogram(title: &str, values: &[f64]) -> Result<String, String> {
    all_finite(values.iter().copied())?;
    if values.is_empty() {
        return Err("no values".into());
    }
    let range = values.iter().fold(0.0f64, |m, v| m.max(v.abs())) * 2.0;
    if range > 1e300 {
        return Err(format!("values up to {:e}: too large to draw", range / 2.0));
    }
    let width = 5.0 * (range / 5.0 / MAX_BINS as f64).ceil().max(1.0);
    let low = (values.iter().copied().fold(f64::INFINITY, f64::min) / width).floor() * width;
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, (640, 420)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| e.to_string())?;
        let bins = Bins::from(low, width, values);
        draw_histogram(&root, title, values, bins, "dE (%)", "number of runs N_r", None)?;
        root.present().map_err(|e| e.to_string())?;
    }
    Ok(svg)
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

    /// About `target` bins of a round width (1, 2, 2.5 or 5 times a power of ten) over `values`
    /// and `marker`; with a `grain` (values on a lattice of that step, like shares of a fixed
    /// number of runs), a whole number of grains wide and edged half a grain off the lattice.
    fn round(values: &[f64], marker: Option<f64>, target: usize, grain: Option<f64>) -> Self {
        let all = || values.iter().copied().chain(marker);
        let (lo, hi) = (all().fold(f64::INFINITY, f64::min), all().fold(f64::NEG_INFINITY, f64::max));
        let raw = ((hi - lo) / target as f64).max(1e-9);
        let power = 10f64.powf(raw.log10().floor());
        let step = [1.0, 2.0, 2.5, 5.0, 10.0].into_iter().find(|&m| raw <= m * power * (1.0 + 1e-12));
        let mut width = step.unwrap_or(10.0) * power;
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

/// A histogram of `values` on `area`, with a red vertical line at `marker` (value, label).
fn draw_histogram(
    area: &DrawingArea<SVGBackend<'_>, plotters::coord::Shift>,
    title: &str,
    values: &[f64],
    bins: Bins,
    x_desc: &str,
    y_desc: &str,
    marker: Option<(f64, String)>,
) -> Result<(), String> {
    let Bins { low, width, count } = bins;
    let mut counts = vec![0u32; count];
    for v in values {
        counts[(((v - low) / width).floor().max(0.0) as usize).min(count - 1)] += 1;
    }
    // Room above the bars for the marker's legend.
    let headroom = if marker.is_some() { 1.3 } else { 1.0 };
    let top = (f64::from(*counts.iter().max().unwrap_or(&1)) * headroom).ceil() + 1.0;
    let high = low + count as f64 * width;
    let mut chart = ChartBuilder::on(area)
        .caption(title, ("sans-serif", 18))
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(48)
        .build_cartesian_2d(low..high, 0.0..top)
        .map_err(|e| e.to_string())?;
    chart
        .configure_mesh()
        .x_desc(x_desc)
        .y_desc(y_desc)
        .y_labels((top as usize + 1).min(10))
        .y_label_formatter(&|v| if v.fract() == 0.0 { format!("{v:.0}") } else { String::new() })
        .draw()
        .map_err(|e| e.to_string())?;
    let bars = counts.iter().enumerate().map(|(i, &n)| {
        let x0 = low + i as f64 * width;
        Rectangle::new([(x0, 0.0), (x0 + width, f64::from(n))], BLUE.mix(0.6).filled())
    });
    chart.draw_series(bars).map_err(|e| e.to_string())?;
    if let Some((x, label)) = marker {
        chart
            .draw_series(LineSeries::new([(x, 0.0), (x, top)], RED.stroke_width(3)))
            .map_err(|e| e.to_string())?
            .label(label)
            .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], RED.stroke_width(3)));
        legend(&mut chart)?;
    }
    Ok(())
}

/// The replications of a study, one figure per case and compared estimator,
/// `replications-<estimator>-np<N>-sigma<s>.svg`: a histogram over the replications of each
/// statistic of the paper's table (MEAN, SD, LOWEST, HIGHEST, % > 0 of dE), with the paper's
/// value drawn on it as a red line where the study has the paper's row.
pub fn replication_figures(
    study: &Study,
    replications: &Replications,
) -> Result<Vec<(String, String)>, FigureError> {
    let mut figures = Vec::new();
    let count = replications.replications.len();
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
                "red line: the paper's value".to_string(),
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
            let marker = panel.marker.clone();
            draw_histogram(cell, name, &panel.values, panel.bins, &x_desc, "replications", marker)?;
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

/// A chart of `(x, y)` over two linear axes.
type Chart<'a, 'b> = ChartContext<'a, SVGBackend<'b>, Cartesian2d<RangedCoordf64, RangedCoordf64>>;

/// A 640 x 420 figure with one chart titled `caption` over `x` and `y`, drawn by `draw`, and
/// the series' legend (top right) if `with_legend`.
fn single_chart(
    caption: &str,
    x: std::ops::Range<f64>,
    y: std::ops::Range<f64>,
    with_legend: bool,
    draw: impl FnOnce(&mut Chart<'_, '_>) -> Result<(), String>,
) -> Result<String, String> {
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
fn legend<'b>(chart: &mut Chart<'b, 'b>) -> Result<(), String> {
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::UpperRight)
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .draw()
        .map_err(|e| e.to_string())
}

/// Lines of mean dE through `(x, mean)` points, with the per-set means as dots.
#[allow(clippy::type_complexity)]
fn trend(
    title: &str,
    x_label: &str,
    series: &[(String, Vec<(f64, f64)>, Vec<(f64, f64)>)],
) -> Result<String, String> {
    all_finite(series.iter().flat_map(|(_, m, s)| m.iter().chain(s)).flat_map(|&(x, y)| [x, y]))?;
    let all = series.iter().flat_map(|(_, m, s)| m.iter().chain(s));
    let (mut x0, mut x1, mut y0, mut y1) = (f64::INFINITY, f64::NEG_INFINITY, 0.0f64, 0.0f64);
    for &(x, y) in all {
        (x0, x1, y0, y1) = (x0.min(x), x1.max(x), y0.min(y), y1.max(y));
    }
    let pad = 0.05 * (x1 - x0).max(1e-9);
    single_chart(title, (x0 - pad)..(x1 + pad), (y0 - 5.0)..(y1 + 5.0), true, |chart| {
        chart.configure_mesh().x_desc(x_label).y_desc("dE (%)").draw().map_err(|e| e.to_string())?;
        for (i, (label, means, sets)) in series.iter().enumerate() {
            let colour = Palette99::pick(i).to_rgba();
            chart
                .draw_series(LineSeries::new(means.clone(), colour.stroke_width(2)))
                .map_err(|e| e.to_string())?
                .label(label.as_str())
                .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], colour.stroke_width(2)));
            chart
                .draw_series(sets.iter().map(|&p| Circle::new(p, 3, colour.filled())))
                .map_err(|e| e.to_string())?;
        }
        Ok(())
    })
}

/// The figures of scored pose sets (joint values in degrees, mm for prismatic joints), as
/// `(file name, SVG text)`:
/// - `errors-by-pose-<set>.svg`: each pose's error (RMS over its markers) at each stage, one
///   panel per stage, bars in the file's order;
/// - `histogram.svg`: the markers' errors at the last stage, one series per set;
/// - `error-vs-<joint>.svg`: each marker's error at the last stage against the joint's value
///   (compliance and backlash show as trends and steps), one colour per set.
///
/// Sets without poses (pooled summaries) are skipped.
pub fn pose_figures(sets: &[&SetEvaluation], joints: &[Joint]) -> Result<Vec<(String, String)>, FigureError> {
    let sets: Vec<&SetEvaluation> = sets.iter().copied().filter(|s| !s.poses.is_empty()).collect();
    let mut figures = Vec::new();
    for (i, set) in sets.iter().enumerate() {
        // Two sets of one name (a file given twice) get two figures.
        let twice = sets[..i].iter().any(|s| file_stem(&s.name) == file_stem(&set.name));
        let suffix = if twice { format!("-{}", i + 1) } else { String::new() };
        let name = format!("errors-by-pose-{}{suffix}.svg", file_stem(&set.name));
        let svg = pose_bars(set).map_err(|m| error(&name, m))?;
        figures.push((name, svg));
    }
    if sets.is_empty() {
        return Ok(figures);
    }
    let name = "histogram.svg".to_string();
    let svg = error_histogram(&sets).map_err(|m| error(&name, m))?;
    figures.push((name, svg));
    for (j, joint) in joints.iter().enumerate() {
        let name = format!("error-vs-{}.svg", file_stem(&joint.name));
        let unit = if joint.kind == JointKind::Revolute { "deg" } else { "mm" };
        let svg =
            against_joint(&sets, j, &format!("{} ({unit})", joint.name)).map_err(|m| error(&name, m))?;
        figures.push((name, svg));
    }
    Ok(figures)
}

/// A name made of letters, digits and `-` only, for a file name.
fn file_stem(name: &str) -> String {
    let stem: String = name.chars().map(|c| if c.is_ascii_alphanumeric() { c } else { '-' }).collect();
    stem.trim_matches('-').to_string()
}

/// The error of pose `p` at stage `s`: the RMS of its markers' distances (mm).
fn pose_rms(p: &PoseErrors, s: usize) -> f64 {
    let n = p.errors[s].len().max(1) as f64;
    ((0..p.errors[s].len()).map(|m| p.distance(s, m).powi(2)).sum::<f64>() / n).sqrt()
}

/// One panel per stage: a bar per pose, in the file's order, labelled by its line in the file.
fn pose_bars(set: &SetEvaluation) -> Result<String, String> {
    let stages = set.stages.len();
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, (900, 260 * stages as u32 + 40)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| e.to_string())?;
        let root = root
            .titled(&format!("error of each pose, {} (RMS over its markers)", set.name), ("sans-serif", 18))
            .map_err(|e| e.to_string())?;
        let panels = root.split_evenly((stages, 1));
        let n = set.poses.len();
        for (s, panel) in panels.iter().enumerate() {
            let values: Vec<f64> = set.poses.iter().map(|p| pose_rms(p, s)).collect();
            let top = values.iter().copied().fold(0.0, f64::max).max(1e-9) * 1.1;
            let mut chart = ChartBuilder::on(panel)
                .caption(set.stages[s].as_str(), ("sans-serif", 15))
                .margin(10)
                .x_label_area_size(36)
                .y_label_area_size(56)
                .build_cartesian_2d(0.0..n as f64, 0.0..top)
                .map_err(|e| e.to_string())?;
            chart
                .configure_mesh()
                .x_desc("pose, by its line in the file (as the tables name it)")
                .y_desc("error (mm)")
                .x_label_formatter(&|v| {
                    set.poses.get(*v as usize).map_or(String::new(), |p| p.line.to_string())
                })
                .draw()
                .map_err(|e| e.to_string())?;
            let colour = Palette99::pick(s).to_rgba();
            let bars = values
                .iter()
                .enumerate()
                .map(|(k, &v)| Rectangle::new([(k as f64 + 0.1, 0.0), (k as f64 + 0.9, v)], colour.filled()));
            chart.draw_series(bars).map_err(|e| e.to_string())?;
            let flagged = set.poses.iter().enumerate().filter(|(_, p)| p.flagged && s + 1 == stages);
            chart
                .draw_series(
                    flagged.map(|(k, _)| Cross::new((k as f64 + 0.5, values[k]), 5, RED.stroke_width(2))),
                )
                .map_err(|e| e.to_string())?;
        }
        root.present().map_err(|e| e.to_string())?;
    }
    Ok(svg)
}

/// The markers' errors at the last stage, one series of bins per set.
fn error_histogram(sets: &[&SetEvaluation]) -> Result<String, String> {
    let values: Vec<Vec<f64>> = sets
        .iter()
        .map(|set| {
            let last = set.stages.len() - 1;
            set.poses
                .iter()
                .flat_map(|p| (0..p.errors[last].len()).map(move |m| p.distance(last, m)))
                .collect()
        })
        .collect();
    let high = values.iter().flatten().copied().fold(0.0, f64::max).max(1e-9);
    let bins = 30;
    let width = high / bins as f64 * 1.0001;
    let counts: Vec<Vec<u32>> = values
        .iter()
        .map(|v| {
            let mut c = vec![0u32; bins];
            for x in v {
                c[((x / width) as usize).min(bins - 1)] += 1;
            }
            c
        })
        .collect();
    let top = f64::from(counts.iter().flatten().copied().max().unwrap_or(1)) * 1.1 + 1.0;
    let stage = &sets[0].stages[sets[0].stages.len() - 1];
    single_chart(&format!("marker errors, {stage}"), 0.0..width * bins as f64, 0.0..top, true, |chart| {
        chart
            .configure_mesh()
            .x_desc("error (mm)")
            .y_desc("number of marker measurements")
            .y_label_formatter(&|v| format!("{v:.0}"))
            .draw()
            .map_err(|e| e.to_string())?;
        let share = 1.0 / sets.len() as f64;
        for (i, (set, c)) in sets.iter().zip(&counts).enumerate() {
            let colour = Palette99::pick(i).to_rgba();
            let bars = c.iter().enumerate().map(move |(b, &n)| {
                let x0 = (b as f64 + i as f64 * share) * width;
                Rectangle::new([(x0, 0.0), (x0 + share * width, f64::from(n))], colour.mix(0.7).filled())
            });
            chart
                .draw_series(bars)
                .map_err(|e| e.to_string())?
                .label(set.name.as_str())
                .legend(move |(x, y)| Rectangle::new([(x, y - 5), (x + 12, y + 5)], colour.filled()));
        }
        Ok(())
    })
}

/// Each marker's error at the last stage against joint `j`'s value, one colour per set.
fn against_joint(sets: &[&SetEvaluation], j: usize, x_label: &str) -> Result<String, String> {
    let points: Vec<Vec<(f64, f64)>> = sets
        .iter()
        .map(|set| {
            let last = set.stages.len() - 1;
            set.poses
                .iter()
                .flat_map(|p| (0..p.errors[last].len()).map(move |m| (p.joints[j], p.distance(last, m))))
                .collect()
        })
        .collect();
    let (mut x0, mut x1, mut y1) = (f64::INFINITY, f64::NEG_INFINITY, 0.0f64);
    for &(x, y) in points.iter().flatten() {
        (x0, x1, y1) = (x0.min(x), x1.max(x), y1.max(y));
    }
    let pad = 0.03 * (x1 - x0).max(1e-6);
    let stage = &sets[0].stages[sets[0].stages.len() - 1];
    let caption = format!("marker errors, {stage}, against {x_label}");
    single_chart(&caption, (x0 - pad)..(x1 + pad), 0.0..(y1 * 1.1).max(1e-9), true, |chart| {
        chart.configure_mesh().x_desc(x_label).y_desc("error (mm)").draw().map_err(|e| e.to_string())?;
        for (i, (set, p)) in sets.iter().zip(&points).enumerate() {
            let colour = Palette99::pick(i).to_rgba();
            chart
                .draw_series(p.iter().map(|&xy| Circle::new(xy, 2, colour.filled())))
                .map_err(|e| e.to_string())?
                .label(set.name.as_str())
                .legend(move |(x, y)| Circle::new((x + 6, y), 3, colour.filled()));
        }
        Ok(())
    })
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
        chart.draw_series(LineSeries::new(line, BLUE.stroke_width(2))).map_err(|e| e.to_string())?;
        let bars = points.iter().filter(|p| p.2 > 0.0).map(|p| {
            PathElement::new(vec![(p.0, p.1 - p.2), (p.0, p.1 + p.2)], BLUE.mix(0.6).stroke_width(1))
        });
        chart.draw_series(bars).map_err(|e| e.to_string())?;
        let dots = points.iter().map(|p| Circle::new((p.0, p.1), 3, BLUE.filled()));
        chart.draw_series(dots).map_err(|e| e.to_string())?;
        if selection.criterion == "cv"
            && let Some(best) = points.iter().min_by(|a, b| a.1.total_cmp(&b.1))
        {
            // The one-standard-error rule: the first step under this line is chosen.
            let line = [(-0.5, best.1 + best.2), (steps - 0.5, best.1 + best.2)];
            chart
                .draw_series(LineSeries::new(line, RED.mix(0.5).stroke_width(1)))
                .map_err(|e| e.to_string())?;
        }
        let circled = points.iter().filter(|p| p.0 as usize == chosen);
        chart
            .draw_series(circled.map(|p| Circle::new((p.0, p.1), 8, RED.stroke_width(2))))
            .map_err(|e| e.to_string())?;
        Ok(())
    })
    .map_err(|m| error(&name, m))?;
    Ok((name, svg))
}
