//! `robocal.compensate`: the library's compensation of a program (targets as arrays or a
//! target file read by the library's reader), its outcome per target as arrays, and the
//! command line's program, report and JSON.

use crate::calibrate::Flags;
use crate::errors::{self, Kind};
use crate::model::Model;
use nalgebra::{Isometry3, Matrix3, Rotation3, Translation3, UnitQuaternion};
use numpy::{
    PyArray1, PyArray2, PyArrayMethods, PyReadonlyArray2, PyReadonlyArrayDyn, PyUntypedArrayMethods,
};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use robocal::design::compensate::{
    CompensateOptions, Compensated, Compensator, Target, TargetFrame, TargetRow, Unreachable,
    targets_from_csv_str, with_tool_point,
};
use robocal::report::compensation;

/// How far a target's rotation may be from orthonormal (`|R^T R - I|`, max entry).
const ROTATION_TOLERANCE: f64 = 1e-9;

/// The options of `robocal.compensate`, as the command line's flags give them.
#[derive(Debug, Clone, FromPyObject)]
#[pyo3(from_item_all)]
pub struct CompensateFlags {
    marker: Option<usize>,
    position_only: bool,
    frame: String,
    max_joint_change_deg: f64,
    joint_unit: Option<String>,
    length_unit: Option<String>,
}

/// The targets of arrays: `targets` n x dof joint targets; or n x 4 x 4 poses (mm) or n x 3
/// positions (mm, `position_only`), each with its row of `seeds` (n x dof). Rows are numbered
/// as the lines of a table with its header on line 1.
fn array_targets(
    dof: usize,
    targets: &PyReadonlyArrayDyn<'_, f64>,
    seeds: Option<&PyReadonlyArray2<'_, f64>>,
    position_only: bool,
) -> PyResult<Vec<TargetRow>> {
    let (shape, values) = (targets.shape().to_vec(), targets.as_array());
    let values: Vec<f64> = values.iter().copied().collect();
    let n = shape.first().copied().unwrap_or(0);
    let row = |i: usize, target| TargetRow { line: i + 2, target };
    if shape.len() == 2 && shape[1] == dof && seeds.is_none() {
        return Ok((0..n).map(|i| row(i, Target::Joints(values[i * dof..(i + 1) * dof].to_vec()))).collect());
    }
    let seeds = seeds.map(|s| s.as_array().to_owned()).ok_or_else(|| {
        errors::argument(
            "seeds",
            format!(
                "targets of shape {shape:?}: poses (n x 4 x 4) and positions (n x 3) need seeds (n x {dof})"
            ),
        )
    })?;
    if seeds.nrows() != n || seeds.ncols() != dof {
        return Err(errors::argument("seeds", format!("expected {n} x {dof}, got {:?}", seeds.shape())));
    }
    let pose = |i: usize| -> PyResult<Isometry3<f64>> {
        match shape[1..] {
            [4, 4] => {
                let m = &values[i * 16..(i + 1) * 16];
                let r = Matrix3::from_fn(|a, b| m[a * 4 + b]);
                let orthonormal = (r.transpose() * r - Matrix3::identity()).amax() < ROTATION_TOLERANCE;
                if !orthonormal || (m[12], m[13], m[14], m[15]) != (0.0, 0.0, 0.0, 1.0) {
                    let message = format!("row {i}: not a rigid transform (a rotation and a translation)");
                    return Err(errors::argument("targets", message));
                }
                let rotation = UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(r));
                Ok(Isometry3::from_parts(Translation3::new(m[3], m[7], m[11]), rotation))
            }
            [3] if position_only => {
                Ok(Isometry3::translation(values[i * 3], values[i * 3 + 1], values[i * 3 + 2]))
            }
            [3] => Err(errors::argument("targets", "positions (n x 3) are targets of position_only=True")),
            _ => Err(errors::argument(
                "targets",
                format!("shape {shape:?}: expected n x {dof} joints, n x 4 x 4 poses or n x 3 positions"),
            )),
        }
    };
    (0..n).map(|i| Ok(row(i, Target::Pose { pose: pose(i)?, seed: seeds.row(i).to_vec() }))).collect()
}

/// Compensate `targets` (arrays: rad, mm) or the target file `file` for the calibrated `model`
/// against `nominal`, as `robocal compensate` does. Returns a dict: per target `lines`,
/// `reached`, `joints` and `change` (n x dof, rad and mm; NaN where unreachable), `error_mm`,
/// `error_deg`, `before_mm`, `before_deg`, `iterations`, `reasons` (None where reached); and the
/// command line's `report`, `csv` and `json`.
#[pyfunction]
#[pyo3(signature = (model, nominal, flags, targets=None, file=None, seeds=None))]
pub fn compensate<'py>(
    py: Python<'py>,
    model: &Model,
    nominal: &Model,
    flags: CompensateFlags,
    targets: Option<PyReadonlyArrayDyn<'py, f64>>,
    file: Option<String>,
    seeds: Option<PyReadonlyArray2<'py, f64>>,
) -> PyResult<Bound<'py, PyDict>> {
    let mut calibrated = model.inner.clone();
    if let Some(id) = flags.marker {
        let Some((_, point)) = model.markers.iter().find(|(k, _)| *k == id) else {
            let ids: Vec<String> = model.markers.iter().map(|(k, _)| k.to_string()).collect();
            let has = if ids.is_empty() { "none".into() } else { ids.join(", ") };
            return Err(errors::argument("marker", format!("{id}: the model has markers {has}")));
        };
        calibrated = with_tool_point(calibrated, *point);
    }
    if !(flags.max_joint_change_deg.is_finite() && flags.max_joint_change_deg > 0.0) {
        let message = format!("a positive number, got {}", flags.max_joint_change_deg);
        return Err(errors::argument("max_joint_change_deg", message));
    }
    let frame = match flags.frame.as_str() {
        "measuring" => TargetFrame::Measuring,
        "base" => TargetFrame::Base,
        other => return Err(errors::argument("frame", format!("`{other}`: expected measuring or base"))),
    };
    let options = CompensateOptions {
        position_only: flags.position_only,
        frame,
        max_joint_change: flags.max_joint_change_deg.to_radians(),
        ..CompensateOptions::default()
    };
    let compensator = Compensator::new(&nominal.inner, &calibrated, &options)
        .map_err(|e| errors::from_error(Kind::Input, &e, Some("nominal")))?;
    let (source, rows) = match (&targets, &file) {
        (Some(t), None) => (
            "arrays".to_string(),
            array_targets(nominal.inner.dof(), t, seeds.as_ref(), flags.position_only)?,
        ),
        (None, Some(path)) => {
            let units = Flags::with_units(flags.joint_unit.clone(), flags.length_unit.clone()).units()?.0;
            let text = std::fs::read_to_string(path)
                .map_err(|e| errors::from_error(Kind::Input, &e, Some(path.as_str())))?;
            let rows = targets_from_csv_str(&text, &nominal.inner, units)
                .map_err(|e| errors::from_error(Kind::Input, &e, Some(path.as_str())))?;
            (path.clone(), rows)
        }
        _ => return Err(errors::argument("targets", "give the targets as arrays or a file, one of them")),
    };
    let wanted: Vec<Target> = rows.iter().map(|r| r.target.clone()).collect();
    let solved = py.detach(|| compensator.solve_all(&wanted));
    let outcomes: Vec<_> = rows.iter().zip(&solved).collect();
    let comment = format!(
        "robocal.compensate of {source}, frame {}{}",
        flags.frame,
        if flags.position_only { ", position only" } else { "" }
    );
    let out = PyDict::new(py);
    out.set_item("report", compensation::text(&source, &calibrated, &outcomes))?;
    out.set_item("csv", compensation::csv(&calibrated, &outcomes, &comment))?;
    out.set_item("json", compensation::json(&calibrated, &outcomes))?;
    outcome_arrays(py, &out, calibrated.dof(), &rows, &solved)?;
    Ok(out)
}

/// Each target's outcome into `out` as arrays (see [`compensate`]).
fn outcome_arrays(
    py: Python<'_>,
    out: &Bound<'_, PyDict>,
    dof: usize,
    rows: &[TargetRow],
    solved: &[Result<Compensated, Unreachable>],
) -> PyResult<()> {
    let reached: Vec<Option<&Compensated>> = solved.iter().map(|s| s.as_ref().ok()).collect();
    let per =
        |f: fn(&Compensated) -> f64| -> Vec<f64> { reached.iter().map(|c| c.map_or(f64::NAN, f)).collect() };
    let matrix = |f: fn(&Compensated) -> &[f64]| -> Vec<Vec<f64>> {
        reached.iter().map(|c| c.map_or_else(|| vec![f64::NAN; dof], |c| f(c).to_vec())).collect()
    };
    let array2 = |rows: Vec<Vec<f64>>| -> PyResult<Bound<'_, PyArray2<f64>>> {
        if rows.is_empty() {
            return PyArray1::from_vec(py, Vec::new()).reshape([0, dof]);
        }
        Ok(PyArray2::from_vec2(py, &rows).expect("dof values per target"))
    };
    out.set_item("lines", PyArray1::from_vec(py, rows.iter().map(|r| r.line).collect()))?;
    out.set_item("reached", PyArray1::from_vec(py, reached.iter().map(Option::is_some).collect()))?;
    out.set_item("joints", array2(matrix(|c| &c.joints))?)?;
    out.set_item("change", array2(matrix(|c| &c.change))?)?;
    out.set_item("error_mm", PyArray1::from_vec(py, per(|c| c.error_mm)))?;
    out.set_item("error_deg", PyArray1::from_vec(py, per(|c| c.error_rad.to_degrees())))?;
    out.set_item("before_mm", PyArray1::from_vec(py, per(|c| c.before_mm)))?;
    out.set_item("before_deg", PyArray1::from_vec(py, per(|c| c.before_rad.to_degrees())))?;
    let iterations: Vec<usize> = reached.iter().map(|c| c.map_or(0, |c| c.iterations)).collect();
    out.set_item("iterations", PyArray1::from_vec(py, iterations))?;
    let reasons: Vec<Option<String>> =
        solved.iter().map(|s| s.as_ref().err().map(|e| e.to_string())).collect();
    out.set_item("reasons", reasons)?;
    Ok(())
}
