//! Figures of a study as SVG text (plotters, without any font library: the SVG names the
//! font and the viewer draws the text).

use crate::limits::MAX_BINS;
use crate::simulation::{PoseChoice, Study, StudyResults, Summary};
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
            let (suffix, poses) = match case.poses {
                PoseChoice::Random => (String::new(), String::new()),
                other => (format!("-{}", other.name()), format!(", {} poses", other.name())),
            };
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
    let high = (values.iter().copied().fold(f64::NEG_INFINITY, f64::max) / width).floor() * width + width;
    let bins = ((high - low) / width).round() as usize;
    let mut counts = vec![0u32; bins];
    for v in values {
        counts[(((v - low) / width).floor() as usize).min(bins - 1)] += 1;
    }
    let top = f64::from(*counts.iter().max().unwrap_or(&1)) + 1.0;
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, (640, 420)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| e.to_string())?;
        let mut chart = ChartBuilder::on(&root)
            .caption(title, ("sans-serif", 18))
            .margin(12)
            .x_label_area_size(40)
            .y_label_area_size(48)
            .build_cartesian_2d(low..high, 0.0..top)
            .map_err(|e| e.to_string())?;
        chart
            .configure_mesh()
            .x_desc("dE (%)")
            .y_desc("number of runs N_r")
            .y_label_formatter(&|v| format!("{v:.0}"))
            .draw()
            .map_err(|e| e.to_string())?;
        let bars = counts.iter().enumerate().map(|(i, &n)| {
            let x0 = low + i as f64 * width;
            Rectangle::new([(x0, 0.0), (x0 + width, f64::from(n))], BLUE.mix(0.6).filled())
        });
        chart.draw_series(bars).map_err(|e| e.to_string())?;
        root.present().map_err(|e| e.to_string())?;
    }
    Ok(svg)
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
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, (640, 420)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| e.to_string())?;
        let mut chart = ChartBuilder::on(&root)
            .caption(title, ("sans-serif", 18))
            .margin(12)
            .x_label_area_size(40)
            .y_label_area_size(48)
            .build_cartesian_2d((x0 - pad)..(x1 + pad), (y0 - 5.0)..(y1 + 5.0))
            .map_err(|e| e.to_string())?;
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
        chart
            .configure_series_labels()
            .background_style(WHITE.mix(0.8))
            .border_style(BLACK)
            .draw()
            .map_err(|e| e.to_string())?;
        root.present().map_err(|e| e.to_string())?;
    }
    Ok(svg)
}
