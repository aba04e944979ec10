//! A repeatability study: the robot sent to the same poses again and again, measured each time.
//!
//! The file is a measurement file ([`Measurements`]) with a `pose` column naming the commanded
//! pose of each row:
//!
//! ```text
//! # units: joints=deg, lengths=mm
//! pose,j1,j2,j3,j4,j5,j6,x1,y1,z1
//! P1,10.0,45.0,-30.0,0.0,20.0,5.0,512.31,-140.22,601.70
//! P1,10.0,45.0,-30.0,0.0,20.0,5.0,512.29,-140.20,601.73
//! ```
//!
//! The spread of each pose's measurements, its sample covariance `S_k` (`n_k - 1` degrees of
//! freedom), has the expectation `J_k Sigma_q J_k^T + sigma_me^2 I`: the joint noise seen
//! through the manipulator Jacobian plus the device's noise. [`repeatability`] fits the joint
//! variances (or the full `Sigma_q`) and `sigma_me^2` to every `S_k` at once
//! ([`NoiseEstimate`], with 95% intervals). The device's frame is first registered onto the
//! robot's by the pose means (as a calibration does), so that `J_k` and `S_k` share a frame.

use super::{Measurements, register};
use crate::estimation::{
    CovarianceSample, EstimationError, JointComponents, MeasurementClass, NoiseEstimate, noise_design,
    sample_covariance,
};
use crate::kinematics::Chain;
use crate::model::RobotModel;
use crate::table::{DataError, Table, Units};
use nalgebra::{DMatrix, DVector, Matrix6xX, Vector3};

/// The measurements of one commanded pose.
#[derive(Debug, Clone, PartialEq)]
pub struct RepeatedPose {
    /// The pose's id (the `pose` column).
    pub id: String,
    /// The mean of its joint values (rad, mm).
    pub joints: Vec<f64>,
    /// Each measurement: the markers' positions stacked (3 per marker, mm).
    pub measured: Vec<DVector<f64>>,
    /// The file line of each measurement.
    pub lines: Vec<usize>,
}

/// A repeatability file, grouped by pose in the order poses first appear.
#[derive(Debug, Clone, PartialEq)]
pub struct RepeatabilityData {
    /// The poses.
    pub poses: Vec<RepeatedPose>,
    /// Markers per measurement.
    pub markers: usize,
}

impl RepeatabilityData {
    /// Read a repeatability file's text for `model` (the measurement file's columns and units,
    /// plus `pose`). Every pose needs at least 2 measurements.
    pub fn from_csv_str(text: &str, model: &RobotModel, units: Option<Units>) -> Result<Self, DataError> {
        let table = Table::parse(text)?;
        let data = Measurements::from_table(&table, model, units)?;
        let column = table.column("pose").ok_or_else(|| {
            let message = "missing pose column: a repeatability file names the commanded pose of each row";
            DataError::new(table.header_line, Some("pose"), message)
        })?;
        let mut poses: Vec<RepeatedPose> = Vec::new();
        for (k, row) in table.rows.iter().enumerate() {
            let line = row.line;
            let id = row.cells[column].to_string();
            if id.is_empty() {
                return Err(DataError::new(line, Some("pose"), "empty pose id"));
            }
            let markers = DVector::from_iterator(
                3 * data.marker_count(),
                data.markers[k].iter().flat_map(|m| [m.x, m.y, m.z]),
            );
            match poses.iter_mut().find(|p| p.id == id) {
                Some(pose) => {
                    pose.joints.iter_mut().zip(&data.joints[k]).for_each(|(s, q)| *s += q);
                    pose.measured.push(markers);
                    pose.lines.push(line);
                }
                None => poses.push(RepeatedPose {
                    id,
                    joints: data.joints[k].clone(),
                    measured: vec![markers],
                    lines: vec![line],
                }),
            }
        }
        for pose in &mut poses {
            if pose.measured.len() < 2 {
                let message = format!(
                    "pose `{}` is measured once: a repeatability study needs at least 2 measurements a pose",
                    pose.id
                );
                return Err(DataError::new(pose.lines[0], Some("pose"), message));
            }
            let n = pose.measured.len() as f64;
            pose.joints.iter_mut().for_each(|q| *q /= n);
        }
        Ok(Self { poses, markers: data.marker_count() })
    }
}

/// How to analyse a repeatability study.
#[derive(Debug, Clone, PartialEq)]
pub struct RepeatabilityOptions {
    /// Per-joint variances or the full `Sigma_q`.
    pub joints: JointComponents,
    /// Nominal marker positions in the last joint frame (mm); marker 1 defaults to the model's
    /// tool point, the others to zero.
    pub markers: Vec<Vector3<f64>>,
    /// Register the device's frame onto the robot's (needs 3 poses or more); otherwise the
    /// device measures in the model's base frame.
    pub register: bool,
}

/// The result of a repeatability study.
#[derive(Debug, Clone, PartialEq)]
pub struct Repeatability {
    /// The estimated noise with intervals.
    pub estimate: NoiseEstimate,
    /// Poses.
    pub poses: usize,
    /// Measurements in all.
    pub measurements: usize,
    /// Root mean square distance of each pose's measurements from their mean (mm): the
    /// repeatability as a single number.
    pub rms_spread: f64,
}

/// Estimate the joint noise and `sigma_me` from `data` on `model`: each pose's sample
/// covariance `S_k` (`n_k - 1` degrees of freedom) has the expectation
/// `J_k Sigma_q J_k^T + sigma_me^2 I`, `J_k` the manipulator Jacobian of the
/// measured markers at the pose's mean joint values, turned into the device's frame by the
/// rigid registration of the pose means onto the nominal positions (with 3 poses or more,
/// unless `options.register` is false); the components are fitted by normal-theory
/// generalised least squares ([`NoiseEstimate`]) with 95% intervals.
pub fn repeatability(
    model: &RobotModel,
    data: &RepeatabilityData,
    options: &RepeatabilityOptions,
) -> Result<Repeatability, EstimationError> {
    let tool = model.tool_point_in_marker_frame();
    let markers: Vec<Vector3<f64>> = (0..data.markers)
        .map(|k| options.markers.get(k).copied().unwrap_or(if k == 0 { tool } else { Vector3::zeros() }))
        .collect();
    let chains = Chain::markers(model, &markers);
    let at: Vec<_> = chains.iter().map(|c| c.with_errors(&vec![0.0; c.params().len()])).collect();
    let mut samples = Vec::with_capacity(data.poses.len());
    let mut means = Vec::new();
    for pose in &data.poses {
        let (mean, s, dof) = sample_covariance(&pose.measured).ok_or_else(|| {
            EstimationError::Noise(format!("pose `{}`: at least 2 measurements needed", pose.id))
        })?;
        means.push(mean);
        samples.push((s, dof));
    }
    // The rotation from the model's frame to the device's.
    let rotation = if options.register && data.poses.len() >= 3 {
        let predicted: Vec<Vector3<f64>> = data.poses.iter().map(|p| at[0].position(&p.joints)).collect();
        let measured: Vec<Vector3<f64>> = means.iter().map(|m| Vector3::new(m[0], m[1], m[2])).collect();
        register(&predicted, &measured).rotation.to_rotation_matrix().into_inner()
    } else {
        nalgebra::Matrix3::identity()
    };
    let dof = model.dof();
    let rows = 3 * data.markers;
    let mut jacobian = Matrix6xX::zeros(dof);
    let mut fit_samples = Vec::with_capacity(samples.len());
    let mut spread = 0.0;
    for (pose, (s, nu)) in data.poses.iter().zip(samples) {
        let mut stacked = DMatrix::zeros(rows, dof);
        for (m, at) in at.iter().enumerate() {
            at.manipulator_jacobian(&pose.joints, &mut jacobian);
            stacked.rows_mut(3 * m, 3).copy_from(&(rotation * jacobian.fixed_rows::<3>(0)));
        }
        spread += s.trace() * nu;
        fit_samples.push(CovarianceSample { s, dof: nu, design: noise_design(&stacked, options.joints, 3) });
    }
    let measurements: usize = data.poses.iter().map(|p| p.measured.len()).sum();
    let estimate =
        NoiseEstimate::fit(&fit_samples, options.joints, dof, MeasurementClass::of_points(3), None)?;
    let freedom: f64 = fit_samples.iter().map(|s| s.dof).sum();
    let rms_spread = (spread / (freedom * data.markers as f64)).sqrt();
    Ok(Repeatability { estimate, poses: data.poses.len(), measurements, rms_spread })
}
