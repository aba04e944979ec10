//! The noise model: joint noise `Sigma_q` and measurement noise `Sigma_m,k` (the paper's
//! Eqs. 7-10), and the covariance `V_k` of each point's pose error.

use super::EstimationError;
use crate::kinematics::Measured;
use nalgebra::{DMatrix, DVector};

/// Measurement noise `Sigma_m,k` of each point.
#[derive(Debug, Clone, PartialEq)]
pub enum MeasurementNoise {
    /// Standard deviation of each measured coordinate, the same at every point and
    /// uncorrelated: x, y, z (mm), then rx, ry, rz (rad) when poses are measured.
    PerAxis([f64; 6]),
    /// A full covariance block per point (`rows x rows` with `rows` 3 or 6; mm², rad²),
    /// e.g. from a device model whose noise varies over the workspace.
    PerPoint(Vec<DMatrix<f64>>),
}

impl MeasurementNoise {
    /// The paper's `Sigma_m = sigma_me^2 I` (Eq. 16), with `sigma_orientation` (rad) for the
    /// orientation rows when poses are measured.
    pub fn isotropic(sigma_position: f64, sigma_orientation: f64) -> Self {
        let (p, o) = (sigma_position, sigma_orientation);
        Self::PerAxis([p, p, p, o, o, o])
    }
}

/// The noise at every point, `e_k = J_k n_q,k + n_m,k` (the paper's Eq. 7), with the joint
/// noise drawn independently at each point.
#[derive(Debug, Clone, PartialEq)]
pub struct NoiseModel {
    /// `Sigma_q` (dof x dof; rad², mm² for prismatic joints).
    pub joint: DMatrix<f64>,
    /// `Sigma_m,k`.
    pub measurement: MeasurementNoise,
}

impl NoiseModel {
    /// Uncorrelated joint noise with these standard deviations (rad, or mm), the paper's
    /// `Sigma_q = diag(sigma_1^2, ..., sigma_N^2)` (Eq. 14).
    pub fn diagonal(joint_sigmas: &[f64], measurement: MeasurementNoise) -> Self {
        let variances: Vec<f64> = joint_sigmas.iter().map(|s| s * s).collect();
        Self { joint: DMatrix::from_diagonal(&variances.into()), measurement }
    }

    /// Whether the measurement noise has an orientation part: a pose's orientation rows
    /// (3 to 5 of each block of 6) with a variance above zero.
    pub fn measures_orientation(&self) -> bool {
        match &self.measurement {
            MeasurementNoise::PerAxis(sigmas) => sigmas[3..].iter().any(|&s| s > 0.0),
            MeasurementNoise::PerPoint(blocks) => {
                blocks.iter().all(|b| b.nrows() == 6 && (3..6).any(|r| b[(r, r)] > 0.0))
            }
        }
    }

    /// Check the model against the robot's `dof`, the number of points and the rows per point.
    pub fn validate(&self, dof: usize, points: usize, rows: usize) -> Result<(), EstimationError> {
        let bad = |what: String| Err(EstimationError::Noise(what));
        if self.joint.shape() != (dof, dof) {
            return bad(format!("Sigma_q is {:?}, expected {dof} x {dof}", self.joint.shape()));
        }
        if self.joint.iter().any(|v| !v.is_finite()) || self.joint.diagonal().iter().any(|&v| v < 0.0) {
            return bad("Sigma_q must be finite with a non-negative diagonal".into());
        }
        if (&self.joint - self.joint.transpose()).amax() > 1e-12 * self.joint.amax() {
            return bad("Sigma_q must be symmetric".into());
        }
        match &self.measurement {
            MeasurementNoise::PerAxis(sigmas) => {
                if sigmas.iter().any(|s| !s.is_finite() || *s < 0.0) {
                    return bad(format!("measurement sigmas must be finite and >= 0, got {sigmas:?}"));
                }
            }
            MeasurementNoise::PerPoint(blocks) => {
                if blocks.len() != points {
                    return bad(format!("{} measurement covariances for {points} points", blocks.len()));
                }
                if let Some(k) = blocks.iter().position(|b| b.shape() != (rows, rows)) {
                    return bad(format!("measurement covariance of point {k} is not {rows} x {rows}"));
                }
                if let Some(k) = blocks.iter().position(|b| b.iter().any(|v| !v.is_finite())) {
                    return bad(format!("measurement covariance of point {k} is not finite"));
                }
            }
        }
        Ok(())
    }

    /// `V_k` of point `k` from the measured rows of its manipulator Jacobians stacked (3 per
    /// marker, or 6 for a tool pose): `V_k = J_k Sigma_q J_k^T + Sigma_m,k`. Per-axis sigmas apply to every
    /// marker's x, y, z alike.
    pub fn pose_covariance(&self, k: usize, jacobian: &DMatrix<f64>, measured: Measured) -> DMatrix<f64> {
        let rows = jacobian.nrows();
        let sigma_m = match &self.measurement {
            MeasurementNoise::PerAxis(sigmas) => {
                let per = measured.rows();
                DMatrix::from_diagonal(&DVector::from_fn(rows, |r, _| sigmas[r % per].powi(2)))
            }
            MeasurementNoise::PerPoint(blocks) => blocks[k].clone(),
        };
        point_covariance(jacobian, &self.joint, &sigma_m)
    }
}

/// The covariance of one point's pose error, the paper's Eq. 10 read per point:
/// `V_k = J_k Sigma_q J_k^T + Sigma_m,k`, with `J_k` the rows of the manipulator Jacobian that
/// are measured (3 for position, 6 for pose).
pub(crate) fn point_covariance(
    j_k: &DMatrix<f64>,
    sigma_q: &DMatrix<f64>,
    sigma_m: &DMatrix<f64>,
) -> DMatrix<f64> {
    j_k * sigma_q * j_k.transpose() + sigma_m
}
