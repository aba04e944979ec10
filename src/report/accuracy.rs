//! The report of `robocal accuracy`: the predicted standard deviations as CSV, a text summary,
//! and figures: a map over a workspace slice and the distribution over each joint's range,
//! with the calibration's poses marked.

use crate::design::accuracy::Predicted;
use crate::model::{JointKind, RobotModel};
use nalgebra::Vector3;
use plotters::prelude::*;
use std::fmt::Write;

/// One pose's prediction: joint values (rad, mm), tool position (mm), the prediction.
pub type Point<'a> = (&'a [f64], Vector3<f64>, Predicted);

fn in_file_unit(kind: JointKind, v: f64) -> f64 {
    if kind == JointKind::Revolute { v.to_degrees() } else { v }
}

/// The predictions as CSV: the units line, then per pose its joints (deg; mm), the tool
/// position (mm), the standard deviations along x, y, z and of the distance (mm, floor
/// included) and of the orientation (deg).
pub fn csv(model: &RobotModel, points: &[Point<'_>]) -> String {
    let names: Vec<&str> = model.joints.iter().map(|j| j.name.as_str()).collect();
    let mut out = format!(
        "# units: joints=deg, lengths=mm\n{},x,y,z,sd_x_mm,sd_y_mm,sd_z_mm,sd_mm,sd_orientation_deg\n",
        names.join(",")
    );
    for (q, p, s) in points {
        let joints: Vec<String> = model
            .joints
            .iter()
            .zip(q.iter())
            .map(|(j, &v)| format!("{:.6}", in_file_unit(j.kind, v)))
            .collect();
        let _ = writeln!(
            out,
            "{},{:.4},{:.4},{:.4},{:.6},{:.6},{:.6},{:.6},{:.6}",
            joints.join(","),
            p.x,
            p.y,
            p.z,
            s.axes_mm.x,
            s.axes_mm.y,
            s.axes_mm.z,
            s.position_mm,
            s.orientation_rad.to_degrees()
        );
    }
    out
}

/// The summary: how many poses, the floor, and the predicted distance and orientation
/// standard deviations' minimum, median, 95th percentile and maximum.
pub fn text(source: &str, parameters: usize, floor_mm: f64, points: &[Point<'_>]) -> String {
    let quantiles = |mut v: Vec<f64>| -> [f64; 4] {
        v.sort_by(f64::total_cmp);
        let at = |f: f64| v[((v.len() - 1) as f64 * f).round() as usize];
        [v[0], at(0.5), at(0.95), v[v.len() - 1]]
    };
    let mut out = format!(
        "predicted accuracy at {} poses of {source}: {parameters} parameters' covariance, floor {floor_mm:.4} mm\n",
        points.len()
    );
    if points.is_empty() {
        return out;
    }
    out += "\nstandard deviation          min     median        95%        max\n";
    let rows = [
        ("distance (mm)", quantiles(points.iter().map(|p| p.2.position_mm).collect())),
        ("orientation (deg)", quantiles(points.iter().map(|p| p.2.orientation_rad.to_degrees()).collect())),
    ];
    for (name, q) in rows {
        let _ = writeln!(out, "{name:<20} {:>10.5} {:>10.5} {:>10.5} {:>10.5}", q[0], q[1], q[2], q[3]);
    }
    out
}

/// A figure failed to draw.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("figure {name}: {message}")]
pub struct FigureError {
    /// The figure's file name.
    pub name: String,
    /// What went wrong.
    pub message: String,
}

/// The figures: `accuracy-map.svg` (the tool positions over the x-y plane of the measuring
/// frame, coloured by the predicted distance standard deviation, the calibration poses' tool
/// positions as black crosses) and `accuracy-vs-joints.svg` (the predicted standard deviation
/// against each joint, the calibration poses' joint values as ticks).
pub fn figures(
    model: &RobotModel,
    points: &[Point<'_>],
    calibration: &[(Vec<f64>, Vector3<f64>)],
) -> Result<Vec<(String, String)>, FigureError> {
    let wrap = |name: &str| {
        let name = name.to_string();
        move |e: String| FigureError { name: name.clone(), message: e }
    };
    Ok(vec![
        ("accuracy-map.svg".into(), map(points, calibration).map_err(wrap("accuracy-map.svg"))?),
        (
            "accuracy-vs-joints.svg".into(),
            joints(model, points, calibration).map_err(wrap("accuracy-vs-joints.svg"))?,
        ),
    ])
}

fn range(values: impl Iterator<Item = f64>) -> std::ops::Range<f64> {
    let (lo, hi) = values.fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| (lo.min(v), hi.max(v)));
    if !lo.is_finite() {
        return 0.0..1.0;
    }
    let pad = ((hi - lo) * 0.05).max(1e-6);
    lo - pad..hi + pad
}

/// Blue (low) to red (high) for `v` in `low..=high`.
fn colour(v: f64, (low, high): (f64, f64)) -> RGBColor {
    let t = if high > low { ((v - low) / (high - low)).clamp(0.0, 1.0) } else { 0.0 };
    RGBColor((255.0 * t) as u8, (80.0 * (1.0 - (2.0 * t - 1.0).abs())) as u8, (255.0 * (1.0 - t)) as u8)
}

fn map(points: &[Point<'_>], calibration: &[(Vec<f64>, Vector3<f64>)]) -> Result<String, String> {
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, (760, 640)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| e.to_string())?;
        let all = points.iter().map(|p| p.1).chain(calibration.iter().map(|c| c.1));
        let (xs, ys) = (range(all.clone().map(|p| p.x)), range(all.map(|p| p.y)));
        let sd = points.iter().map(|p| p.2.position_mm);
        let scale = (sd.clone().fold(f64::INFINITY, f64::min), sd.fold(0.0, f64::max));
        let caption = format!(
            "predicted SD of the tool position (mm): blue {:.4}, red {:.4}; x = calibration poses",
            scale.0, scale.1
        );
        let mut chart = ChartBuilder::on(&root)
            .caption(caption, ("sans-serif", 16))
            .margin(12)
            .x_label_area_size(40)
            .y_label_area_size(60)
            .build_cartesian_2d(xs, ys)
            .map_err(|e| e.to_string())?;
        chart.configure_mesh().x_desc("x (mm)").y_desc("y (mm)").draw().map_err(|e| e.to_string())?;
        chart
            .draw_series(
                points
                    .iter()
                    .map(|p| Circle::new((p.1.x, p.1.y), 3, colour(p.2.position_mm, scale).filled())),
            )
            .map_err(|e| e.to_string())?;
        chart
            .draw_series(calibration.iter().map(|c| Cross::new((c.1.x, c.1.y), 4, BLACK.stroke_width(2))))
            .map_err(|e| e.to_string())?;
        root.present().map_err(|e| e.to_string())?;
    }
    Ok(svg)
}

fn joints(
    model: &RobotModel,
    points: &[Point<'_>],
    calibration: &[(Vec<f64>, Vector3<f64>)],
) -> Result<String, String> {
    let n = model.dof();
    let rows = n.div_ceil(3);
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, (1200, 300 * rows as u32 + 40)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| e.to_string())?;
        let root = root
            .titled(
                "predicted SD of the tool position (mm) over each joint's range; | = calibration poses",
                ("sans-serif", 16),
            )
            .map_err(|e| e.to_string())?;
        let ys = range(points.iter().map(|p| p.2.position_mm));
        let tick = ys.start + (ys.end - ys.start) * 0.06;
        for (j, panel) in root.split_evenly((rows, 3)).iter().enumerate().take(n) {
            let joint = &model.joints[j];
            let xs = joint.limits.map(|l| in_file_unit(joint.kind, l));
            let unit = if joint.kind == JointKind::Revolute { "deg" } else { "mm" };
            let mut chart = ChartBuilder::on(panel)
                .margin(8)
                .x_label_area_size(34)
                .y_label_area_size(52)
                .build_cartesian_2d(xs[0]..xs[1], ys.clone())
                .map_err(|e| e.to_string())?;
            chart
                .configure_mesh()
                .x_desc(format!("{} ({unit})", joint.name))
                .y_desc("SD (mm)")
                .draw()
                .map_err(|e| e.to_string())?;
            chart
                .draw_series(points.iter().map(|p| {
                    Circle::new(
                        (in_file_unit(joint.kind, p.0[j]), p.2.position_mm),
                        2,
                        BLUE.mix(0.5).filled(),
                    )
                }))
                .map_err(|e| e.to_string())?;
            chart
                .draw_series(calibration.iter().map(|c| {
                    let x = in_file_unit(joint.kind, c.0[j]);
                    PathElement::new(vec![(x, ys.start), (x, tick)], BLACK.stroke_width(2))
                }))
                .map_err(|e| e.to_string())?;
        }
        root.present().map_err(|e| e.to_string())?;
    }
    Ok(svg)
}
