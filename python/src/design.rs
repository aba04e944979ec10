//! `robocal.observability` and `robocal.plan`: the library's pose design, as the command
//! line's `observability` and `plan` make it.

use crate::errors::{self, Kind};
use crate::model::Model;
use numpy::{PyArray1, PyArray2, PyReadonlyArray2};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use robocal::calibration::ParamWords;
use robocal::design::{Constraints, Criterion, Design, Indices};
use robocal::estimation::{MeasurementNoise, NoiseModel};
use robocal::kinematics::Measured;
use robocal::model::JointKind;
use robocal::table::Units;

/// The design's settings, as the command line's flags give them.
#[derive(Debug, Clone, Default, FromPyObject)]
#[pyo3(from_item_all)]
pub struct DesignFlags {
    params: Vec<String>,
    measured: String,
    joint_sigma: Option<Vec<f64>>,
    sigma: Option<f64>,
    sigma_orientation: Option<f64>,
    joint_unit: String,
    length_unit: String,
}

impl DesignFlags {
    /// The units of the poses and of the sigmas.
    fn units(&self) -> PyResult<Units> {
        let joints_in_degrees = match self.joint_unit.as_str() {
            "rad" => false,
            "deg" => true,
            other => return Err(errors::argument("joint_unit", format!("`{other}`: expected rad or deg"))),
        };
        let lengths_in_metres = match self.length_unit.as_str() {
            "m" => true,
            "mm" => false,
            other => return Err(errors::argument("length_unit", format!("`{other}`: expected m or mm"))),
        };
        Ok(Units { joints_in_degrees, lengths_in_metres })
    }

    /// The design of `model`: its parameters chosen, its measurement, its noise if given.
    fn design(&self, model: &Model) -> PyResult<Design> {
        let model = &model.inner;
        let params = model.params();
        // As `--params`: a list joined by commas; `none` leaves nothing to assess.
        let words = ParamWords::parse(&self.params.join(",")).map_err(|e| errors::argument("params", e))?;
        if words == ParamWords::None {
            let message = "none: nothing to assess; give joints, all, offsets, or parameter names";
            return Err(errors::argument("params", message));
        }
        let selection = words.select(&params).map_err(|e| errors::argument("params", e))?;
        let measured = match self.measured.as_str() {
            "position" => Measured::Position,
            "pose" => Measured::Pose,
            other => {
                return Err(errors::argument("measured", format!("`{other}`: expected position or pose")));
            }
        };
        let units = self.units()?;
        let noise = match &self.joint_sigma {
            None => None,
            Some(sigmas) if sigmas.len() != model.dof() => {
                let message =
                    format!("{} values for the {} joints of {}", sigmas.len(), model.dof(), model.name);
                return Err(errors::argument("joint_sigma", message));
            }
            Some(sigmas) => {
                let joint: Vec<f64> = (model.joints.iter().zip(sigmas))
                    .map(|(j, &s)| match j.kind {
                        JointKind::Revolute => units.angle(s),
                        JointKind::Prismatic => s * units.length_scale(),
                    })
                    .collect();
                let measurement = MeasurementNoise::isotropic(
                    self.sigma.unwrap_or(0.0) * units.length_scale(),
                    units.angle(self.sigma_orientation.unwrap_or(0.0)),
                );
                Some(NoiseModel::diagonal(&joint, measurement))
            }
        };
        Design::new(model, selection, measured, noise).map_err(|e| errors::from_error(Kind::Input, &e, None))
    }

    /// `poses` (n x dof, in the joint unit; the length unit for prismatic joints) in rad and mm.
    fn poses(&self, model: &Model, poses: &PyReadonlyArray2<'_, f64>) -> PyResult<Vec<Vec<f64>>> {
        let units = self.units()?;
        let poses = poses.as_array();
        if poses.ncols() != model.inner.dof() {
            let message = format!(
                "{} columns for the {} joints of {}",
                poses.ncols(),
                model.inner.dof(),
                model.inner.name
            );
            return Err(errors::argument("poses", message));
        }
        Ok(poses
            .rows()
            .into_iter()
            .map(|row| {
                (row.iter().zip(&model.inner.joints))
                    .map(|(&v, j)| match j.kind {
                        JointKind::Revolute => units.angle(v),
                        JointKind::Prismatic => v * units.length_scale(),
                    })
                    .collect()
            })
            .collect())
    }
}

/// The indices of one matrix as a dict.
fn indices<'py>(py: Python<'py>, i: &Indices) -> PyResult<Bound<'py, PyDict>> {
    let out = PyDict::new(py);
    for (name, value) in [
        ("o1", i.o1),
        ("o2", i.o2),
        ("o3", i.o3),
        ("o4", i.o4),
        ("o5", i.o5),
        ("log_det", i.log_det),
        ("condition_number", i.condition_number),
    ] {
        out.set_item(name, value)?;
    }
    out.set_item("rank", i.rank)?;
    out.set_item("singular_values", PyArray1::from_slice(py, &i.singular_values))?;
    Ok(out)
}

/// The observability indices O1-O5 of `poses`, as `robocal observability` reports them.
#[pyfunction]
pub fn observability<'py>(
    py: Python<'py>,
    model: &Model,
    poses: PyReadonlyArray2<'py, f64>,
    flags: DesignFlags,
) -> PyResult<Bound<'py, PyDict>> {
    let design = flags.design(model)?;
    let poses = flags.poses(model, &poses)?;
    if poses.iter().all(|q| *q == poses[0]) {
        return Err(errors::argument("poses", "poses that differ: every index would be 0 or infinite"));
    }
    let o = py
        .detach(|| design.observability(&poses))
        .map_err(|e| errors::from_error(Kind::Estimation, &e, None))?;
    let out = PyDict::new(py);
    out.set_item("poses", o.poses)?;
    out.set_item("parameters", o.parameters)?;
    out.set_item("identifiable", o.identifiable)?;
    out.set_item("scaled", indices(py, &o.scaled)?)?;
    out.set_item("whitened", o.whitened.as_ref().map(|w| indices(py, w)).transpose()?)?;
    out.set_item("report", robocal::report::design::observability(&design, &o, "poses"))?;
    Ok(out)
}

/// `points` poses planned among `candidates` random ones to maximise `criterion`, as
/// `robocal plan` plans them (the same seed, the same poses).
#[pyfunction]
#[pyo3(signature = (model, points, candidates, criterion, seed, flags))]
pub fn plan<'py>(
    py: Python<'py>,
    model: &Model,
    points: usize,
    candidates: usize,
    criterion: &str,
    seed: u64,
    flags: DesignFlags,
) -> PyResult<Bound<'py, PyDict>> {
    let design = flags.design(model)?;
    let criterion: Criterion = criterion.parse().map_err(|e| errors::argument("criterion", e))?;
    robocal::io::check_memory(
        design.plan_memory_estimate(candidates),
        &format!("candidates={candidates}"),
        "ask for fewer candidates",
    )
    .map_err(|e| errors::from_error(Kind::Input, &e, None))?;
    let work = design.plan_work(candidates, points);
    if work > robocal::limits::MAX_WORK {
        let message = format!(
            "{work:.1e} row-parameter products a pass of the exchange: ask for fewer candidates or points"
        );
        return Err(errors::argument("candidates", message));
    }
    let constraints = Constraints::default();
    let (plan, pool) = py
        .detach(|| design.plan_seeded(points, candidates, &constraints, criterion, seed))
        .map_err(|e| errors::from_error(Kind::Estimation, &e, None))?;
    let out = PyDict::new(py);
    let rows: Vec<Vec<f64>> = plan.joints.clone();
    out.set_item("joints", PyArray2::from_vec2(py, &rows).map_err(|e| errors::input(e.to_string()))?)?;
    out.set_item("value", plan.value)?;
    out.set_item("initial", plan.initial)?;
    out.set_item(
        "summary",
        robocal::report::design::plan_summary(&design, &plan, pool.joints.len(), pool.draws),
    )?;
    out.set_item("csv", robocal::design::poses_csv(&model.inner, &plan.joints, ""))?;
    Ok(out)
}
