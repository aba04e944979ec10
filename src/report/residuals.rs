//! The residuals of a calibration from observation files ([`crate::calibration::kinds`]) or
//! from a tree's views ([`crate::calibration::tree`]), one row per observation or view, where
//! it is in its file and at which joint values: the CSV of `--poses-csv` and the figures of
//! `--figures`.

use super::figures::{Against, Bars, FigureError, against_figure, bar_figure, density_figure};
use crate::calibration::FLAG_AT;
use crate::calibration::kinds::{KindData, Observation, Score};
use crate::calibration::tree::TreeData;
use crate::model::{Joint, JointKind};
use std::fmt::Write;

/// One observation's or view's residual, before and after calibration.
#[derive(Debug, Clone, PartialEq)]
pub struct Residual {
    /// The file it is in.
    pub file: String,
    /// Its line there.
    pub line: usize,
    /// What it is: `distance`, `point`, `contact`, `x` ... `yaw`, `marker 2 z`, `camera rx`,
    /// `view`.
    pub kind: String,
    /// Its pose's number in the file, from 1 (a pair's first pose).
    pub pose: usize,
    /// A pair's second pose, numbered as `pose`.
    pub pose_b: Option<usize>,
    /// The joint values at `pose` (deg, mm for a prismatic joint).
    pub joints: Vec<f64>,
    /// A length's residual (mm), before and after: an observation's signed `m - f`, a view's
    /// position error's norm `|y_t|`.
    pub mm: Option<(f64, f64)>,
    /// An angle's residual (deg), before and after: signed for an observation, a view's
    /// rotation error's norm `|y_r|`.
    pub deg: Option<(f64, f64)>,
    /// After, in standard deviations (a view's largest of its six).
    pub whitened: f64,
    /// The whitened residual beyond which it is flagged: its set's
    /// [`Score::flag_at`] for an observation, [`FLAG_AT`] for a view.
    pub flag_at: f64,
}

impl Residual {
    /// Whether it is flagged: its whitened residual beyond [`Residual::flag_at`].
    pub fn flagged(&self) -> bool {
        self.whitened.abs() > self.flag_at
    }
}

/// A scored set's residuals: the training files', or a held-out file's.
#[derive(Debug, Clone, PartialEq)]
pub struct ResidualSet {
    /// `training`, or the held-out file.
    pub name: String,
    /// What an item is: `observation` or `view`.
    pub item: &'static str,
    /// Whether the residuals are signed (an observation's `m - f`) or norms (a view's).
    pub signed: bool,
    /// The stages drawn: `before` and `after` a calibration, or one (`as it stands`: a model
    /// scored by `evaluate`, whose residuals' `after` it draws).
    pub stages: Vec<String>,
    /// Every residual, in the files' order.
    pub residuals: Vec<Residual>,
}

/// `values` (rad, mm) in the files' units: degrees, mm for a prismatic joint.
fn in_file_units(values: &[f64], joints: &[Joint]) -> Vec<f64> {
    (values.iter().zip(joints))
        .map(|(&v, j)| if j.kind == JointKind::Revolute { v.to_degrees() } else { v })
        .collect()
}

/// Where a set's items run out before its files' rows do, or the other way round.
fn mismatch(name: &str, scored: usize, rows: usize) -> String {
    format!("{name}: {scored} residuals scored for {rows} rows in its files")
}

impl ResidualSet {
    /// The set `name` of observation files `files` (each a name and its observations, in the
    /// order they were scored) scored by `score`, the robot's joints `joints`.
    pub fn of_observations(
        name: &str,
        score: &Score,
        files: &[(&str, &KindData)],
        joints: &[Joint],
    ) -> Result<Self, String> {
        let rows: usize = files.iter().map(|(_, d)| d.observations.len()).sum();
        if rows != score.observations.len() {
            return Err(mismatch(name, score.observations.len(), rows));
        }
        let mut scored = score.observations.iter();
        let mut residuals = Vec::with_capacity(rows);
        for (file, data) in files {
            for (o, r) in data.observations.iter().zip(scored.by_ref()) {
                let values = (r.before, r.after);
                residuals.push(Residual {
                    file: file.to_string(),
                    line: r.line,
                    kind: r.label(),
                    pose: o.pose() + 1,
                    pose_b: match *o {
                        Observation::Distance { b, .. } => Some(b + 1),
                        _ => None,
                    },
                    joints: in_file_units(&data.joints[o.pose()], joints),
                    mm: (r.unit == "mm").then_some(values),
                    deg: (r.unit == "deg").then_some(values),
                    whitened: r.whitened,
                    flag_at: score.flag_at,
                });
            }
        }
        Ok(Self {
            name: name.to_string(),
            item: "observation",
            signed: true,
            stages: before_after(),
            residuals,
        })
    }

    /// The set `name` of view files `files` (each a name and its views, in the order they
    /// were scored) scored by `score`, the tree's joints `joints`.
    pub fn of_views(
        name: &str,
        score: &Score,
        files: &[(&str, &TreeData)],
        joints: &[Joint],
    ) -> Result<Self, String> {
        let rows: usize = files.iter().map(|(_, d)| d.views.len()).sum();
        if rows != score.views.len() {
            return Err(mismatch(name, score.views.len(), rows));
        }
        let mut scored = score.views.iter();
        let mut residuals = Vec::with_capacity(rows);
        for (file, data) in files {
            for (view, r) in data.views.iter().zip(scored.by_ref()) {
                residuals.push(Residual {
                    file: file.to_string(),
                    line: r.line,
                    kind: "view".to_string(),
                    pose: view.pose + 1,
                    pose_b: None,
                    joints: in_file_units(&data.joints[view.pose], joints),
                    mm: Some((r.before_mm, r.after_mm)),
                    deg: r.before_deg.zip(r.after_deg),
                    whitened: r.whitened,
                    flag_at: FLAG_AT,
                });
            }
        }
        Ok(Self { name: name.to_string(), item: "view", signed: false, stages: before_after(), residuals })
    }
}

/// A calibration's stages: `before` and `after`.
fn before_after() -> Vec<String> {
    vec!["before".to_string(), "after".to_string()]
}

/// The same set scored as it stands (`evaluate`): one stage, its residuals' `after`.
impl ResidualSet {
    /// The set drawn at one stage, `stage` (its residuals' `after`).
    pub fn at_one_stage(self, stage: &str) -> Self {
        Self { stages: vec![stage.to_string()], ..self }
    }
}

/// A number for a CSV cell, empty if there is none.
fn cell(value: Option<f64>) -> String {
    value.map_or_else(String::new, |v| format!("{v}"))
}

/// Every residual of every set as CSV, one row per observation or view: the set, the file,
/// the line, the kind, the pose (and a pair's second pose), the joint values
/// (`<joint>_deg`, `<joint>_mm` for a prismatic joint), the residual before and after in mm
/// or in deg (the other pair empty; a view has both, as norms), the whitened residual and
/// whether it is flagged.
pub fn residuals_csv(sets: &[&ResidualSet], joints: &[Joint]) -> String {
    let mut head: Vec<String> = ["set", "file", "line", "kind", "pose", "pose_b"].map(String::from).to_vec();
    head.extend(joints.iter().map(|j| match j.kind {
        JointKind::Revolute => format!("{}_deg", j.name),
        JointKind::Prismatic => format!("{}_mm", j.name),
    }));
    head.extend(
        ["before_mm", "after_mm", "before_deg", "after_deg", "whitened", "flagged"].map(String::from),
    );
    let mut out = head.join(",") + "\n";
    for set in sets {
        for r in &set.residuals {
            let mut cells = vec![
                csv_cell(&set.name),
                csv_cell(&r.file),
                r.line.to_string(),
                csv_cell(&r.kind),
                r.pose.to_string(),
                r.pose_b.map_or_else(String::new, |b| b.to_string()),
            ];
            cells.extend(r.joints.iter().map(|v| format!("{v}")));
            for pair in [r.mm, r.deg] {
                cells.extend([cell(pair.map(|p| p.0)), cell(pair.map(|p| p.1))]);
            }
            cells.extend([format!("{}", r.whitened), r.flagged().to_string()]);
            let _ = writeln!(out, "{}", cells.join(","));
        }
    }
    out
}

/// The residual (before, after) in `unit` (`mm` or `deg`) of `r`.
fn in_unit(r: &Residual, unit: &str) -> Option<(f64, f64)> {
    if unit == "mm" { r.mm } else { r.deg }
}

/// The file name's suffix of `unit`: none for mm, `-deg` for deg.
fn suffix(unit: &str) -> &'static str {
    if unit == "mm" { "" } else { "-deg" }
}

/// The figures of scored sets of observations or views, as `(file name, SVG text)`, for each
/// unit the residuals have (mm; deg with a `-deg` suffix):
/// - `errors-by-<item>-<set>.svg`: each residual's size `|r|` before and after on one scale,
///   bars in the files' order labelled by line, and after on its own scale (the ratio
///   written) when it is under a third of before; the flagged ones crossed;
/// - `histogram.svg`: the density of the sizes after calibration (at the last stage), each
///   set on the same bins;
/// - `error-vs-<joint>.svg`: each residual after calibration (an observation's signed, a
///   view's norm) against the joint's value at its pose, one panel per unit, one colour per
///   set.
///
/// A set at one stage ([`ResidualSet::at_one_stage`]) has one bar per residual, its `after`.
/// Sets without residuals are skipped.
pub fn residual_figures(
    sets: &[&ResidualSet],
    joints: &[Joint],
) -> Result<Vec<(String, String)>, FigureError> {
    let sets: Vec<&ResidualSet> = sets.iter().copied().filter(|s| !s.residuals.is_empty()).collect();
    let units = units_of(&sets);
    let mut figures = Vec::new();
    for (i, set) in sets.iter().enumerate() {
        let twice = sets[..i]
            .iter()
            .any(|s| super::figures::file_stem(&s.name) == super::figures::file_stem(&set.name));
        let number = if twice { format!("-{}", i + 1) } else { String::new() };
        for &unit in &units {
            let of: Vec<&Residual> = set.residuals.iter().filter(|r| in_unit(r, unit).is_some()).collect();
            if of.is_empty() {
                continue;
            }
            let stem = super::figures::file_stem(&set.name);
            let name = format!("errors-by-{}-{stem}{number}{}.svg", set.item, suffix(unit));
            // The last stage is after; with two, the first is before.
            let size = |before: bool| {
                of.iter()
                    .map(|r| in_unit(r, unit).map_or(0.0, |p| if before { p.0 } else { p.1 }).abs())
                    .collect()
            };
            let last = set.stages.len() - 1;
            let bars = Bars {
                title: format!("residual of each {}, {} ({unit})", set.item, set.name),
                stages: &set.stages,
                item: set.item,
                unit,
                lines: of.iter().map(|r| r.line).collect(),
                values: (0..=last).map(|s| size(s < last)).collect(),
                flagged: of.iter().map(|r| r.flagged()).collect(),
            };
            figures.push((name.clone(), bar_figure(&bars).map_err(|m| error(&name, m))?));
        }
    }
    if sets.is_empty() {
        return Ok(figures);
    }
    for &unit in &units {
        let name = format!("histogram{}.svg", suffix(unit));
        let values: Vec<(&str, Vec<f64>)> = (sets.iter())
            .map(|s| {
                (
                    s.name.as_str(),
                    s.residuals.iter().filter_map(|r| in_unit(r, unit)).map(|p| p.1.abs()).collect(),
                )
            })
            .collect();
        let what = format!("{} residuals, {}", sets[0].item, stage(&sets));
        figures.push((name.clone(), density_figure(&what, &values, unit).map_err(|m| error(&name, m))?));
    }
    figures.extend(joint_figures(&sets, joints, &units)?);
    Ok(figures)
}

/// `error-vs-<joint>.svg` of each joint: [`residual_figures`]'.
fn joint_figures(
    sets: &[&ResidualSet],
    joints: &[Joint],
    units: &[&str],
) -> Result<Vec<(String, String)>, FigureError> {
    let mut figures = Vec::new();
    for (j, joint) in joints.iter().enumerate() {
        let name = format!("error-vs-{}.svg", super::figures::file_stem(&joint.name));
        let unit = if joint.kind == JointKind::Revolute { "deg" } else { "mm" };
        let xs: Vec<Vec<f64>> =
            sets.iter().map(|s| s.residuals.iter().map(|r| r.joints[j]).collect()).collect();
        let figure = against_each(sets, units, &xs, &format!("{} ({unit})", joint.name));
        figures.push((name.clone(), figure.map_err(|m| error(&name, m))?));
    }
    Ok(figures)
}

/// For a model with masses, `error-vs-torque-<joint>.svg` per joint: each residual at the last
/// stage against the load gravity puts on the joint at its pose (N·m; N for a prismatic
/// joint), computed with `model` (the calibrated one): a compliance left out of the model shows
/// as a slope. Nothing without masses, nor for a joint no pose loads (a vertical first axis).
pub fn residual_torque_figures(
    sets: &[&ResidualSet],
    model: &crate::model::RobotModel,
) -> Result<Vec<(String, String)>, FigureError> {
    let sets: Vec<&ResidualSet> = sets.iter().copied().filter(|s| !s.residuals.is_empty()).collect();
    let chain = crate::kinematics::Chain::new(model).with_errors(&vec![0.0; model.params().len()]);
    if sets.is_empty() || !chain.has_masses() {
        return Ok(Vec::new());
    }
    let units = units_of(&sets);
    // loads[set][residual][joint]
    let loads: Vec<Vec<Vec<f64>>> = (sets.iter())
        .map(|s| {
            super::figures::gravity_loads(&chain, model, s.residuals.iter().map(|r| r.joints.as_slice()))
        })
        .collect();
    let mut figures = Vec::new();
    for (j, joint) in model.joints.iter().enumerate() {
        let xs: Vec<Vec<f64>> = loads.iter().map(|s| s.iter().map(|tau| tau[j]).collect()).collect();
        if xs.iter().flatten().all(|t| t.abs() < 1e-6) {
            continue; // no load at any pose (a vertical first axis): nothing to plot against
        }
        let name = format!("error-vs-torque-{}.svg", super::figures::file_stem(&joint.name));
        let unit = if joint.kind == JointKind::Revolute { "N·m" } else { "N" };
        let figure = against_each(&sets, &units, &xs, &format!("gravity load on {} ({unit})", joint.name));
        figures.push((name.clone(), figure.map_err(|m| error(&name, m))?));
    }
    Ok(figures)
}

/// The units (`mm`, `deg`) some residual of `sets` has, in that order.
fn units_of(sets: &[&ResidualSet]) -> Vec<&'static str> {
    (["mm", "deg"].into_iter())
        .filter(|&u| sets.iter().any(|s| s.residuals.iter().any(|r| in_unit(r, u).is_some())))
        .collect()
}

/// The panels a signed residual of `kind` is drawn in, in order: a coordinate's axis (`marker
/// 2 z`, `z`, `camera rx`: `z`, `rx`; `roll`, `pitch`, `yaw`), so that a marker file's
/// residuals fall into `x`, `y` and `z` panels; any other (a distance, a contact) `residual`.
const PANELS: [&str; 10] = ["residual", "x", "y", "z", "rx", "ry", "rz", "roll", "pitch", "yaw"];

/// The panel of a signed residual of `kind` ([`PANELS`]).
fn panel_of(kind: &str) -> &'static str {
    let axis = kind.rsplit(' ').next().unwrap_or(kind);
    PANELS.iter().copied().find(|&p| p == axis).unwrap_or(PANELS[0])
}

/// The panels of `sets` and what each residual is drawn in: signed residuals by component
/// ([`panel_of`]), each unit's in [`PANELS`]' order; sizes (a view's) one per unit.
fn panels_of<'a>(sets: &[&ResidualSet], units: &[&'a str], signed: bool) -> Vec<(&'static str, &'a str)> {
    let size = |u: &str| if u == "mm" { "|position error|" } else { "|rotation error|" };
    (units.iter())
        .flat_map(|&u| {
            let seen = |p: &str| {
                sets.iter()
                    .flat_map(|s| &s.residuals)
                    .any(|r| in_unit(r, u).is_some() && panel_of(&r.kind) == p)
            };
            let panels: Vec<(&'static str, &'a str)> = if signed {
                PANELS.iter().copied().filter(|p| seen(p)).map(|p| (p, u)).collect()
            } else {
                vec![(size(u), u)]
            };
            panels
        })
        .collect()
}

/// Each residual of `sets` at the last stage against a value of its own (`xs[set][residual]`:
/// its pose's joint value, a gravity load), a panel per component and unit ([`panels_of`]),
/// as [`against_figure`] draws it.
fn against_each(
    sets: &[&ResidualSet],
    units: &[&str],
    xs: &[Vec<f64>],
    x_label: &str,
) -> Result<String, String> {
    let signed = sets.iter().all(|s| s.signed);
    let components = panels_of(sets, units, signed);
    let points = (components.iter())
        .map(|&(panel, u)| {
            let drawn = |r: &Residual| !signed || panel_of(&r.kind) == panel;
            (sets.iter().zip(xs))
                .map(|(s, xs)| {
                    (s.residuals.iter().zip(xs))
                        .filter(|(r, _)| drawn(r))
                        .filter_map(|(r, &x)| Some((x, in_unit(r, u)?.1)))
                        .collect()
                })
                .collect()
        })
        .collect();
    let what = if signed { "residuals (measured - predicted)" } else { "view errors" };
    against_figure(&Against {
        title: format!("{what}, {}, against {x_label}", stage(sets)),
        sets: sets.iter().map(|s| s.name.as_str()).collect(),
        components: &components,
        points,
        x_label,
        signed,
    })
}

/// The last stage of `sets` (`after`; `as it stands`), which the histogram and the figures
/// against the joints draw.
fn stage(sets: &[&ResidualSet]) -> String {
    sets[0].stages.last().map_or_else(String::new, Clone::clone)
}

/// A figure that could not be drawn.
fn error(name: &str, message: String) -> FigureError {
    FigureError { name: name.to_string(), message }
}

/// A CSV cell, quoted if it holds a comma or a quote.
pub(crate) fn csv_cell(text: &str) -> String {
    if text.contains([',', '"', '\n']) {
        format!("\"{}\"", text.replace('"', "\"\""))
    } else {
        text.to_string()
    }
}
