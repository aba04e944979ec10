//! Accuracy maps: how accurate a calibrated robot is, and where. The calibration's parameter
//! covariance `Sigma_x` carried to the tool by the identification Jacobian `J_x = d(pose)/dx`
//! of the calibrated model at each pose gives the standard deviation of the tool's error there,
//! `sqrt(diag(J_x Sigma_x J_x^T))`, per axis; the floor (the residual the model cannot explain,
//! measured on held-out poses) is added in quadrature.

use crate::kinematics::{Chain, ChainAt, Measured};
use crate::model::{RobotModel, Selection};
use nalgebra::{DMatrix, Vector3};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

/// A calibration's parameter covariance, as `calibrate --out-model` writes it beside the model
/// (`<model>.covariance.json`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ParameterCovariance {
    /// What the numbers are in.
    #[serde(default)]
    pub units: String,
    /// The estimated parameters, by name (`j2.a`, `marker1.x`: marker 1 is the calibrated
    /// model's tool point).
    pub names: Vec<String>,
    /// Their covariance (mm and rad), row by row.
    pub covariance: Vec<Vec<f64>>,
    /// The residual floor (mm): the rms distance error on held-out poses after calibration, or
    /// 0 when none was measured.
    #[serde(default)]
    pub floor_mm: f64,
}

/// Why a covariance cannot be used with a model.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum CovarianceError {
    /// The matrix is not `names.len()` square, or not finite.
    #[error("the covariance is not a finite {0} x {0} matrix")]
    Shape(usize),
    /// The floor is negative or not finite.
    #[error("floor_mm: a finite number >= 0, found {0}")]
    Floor(f64),
}

impl ParameterCovariance {
    /// The covariance of the parameters `names` (mm, rad), and the floor (mm).
    pub fn new(names: Vec<String>, covariance: &DMatrix<f64>, floor_mm: f64) -> Self {
        let rows = covariance.row_iter().map(|r| r.iter().copied().collect()).collect();
        Self { units: "mm, rad".into(), names, covariance: rows, floor_mm }
    }

    /// The sidecar as JSON.
    pub fn to_json(&self) -> String {
        serde_json::to_string_pretty(self).expect("numbers and strings") + "\n"
    }

    /// Read a sidecar; the error of a malformed one names its line and column.
    pub fn from_json(text: &str) -> Result<Self, serde_json::Error> {
        serde_json::from_str(text)
    }
}

/// The predicted standard deviations of the tool's error at one pose.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Predicted {
    /// Along x, y and z of the measuring frame (mm), floor included.
    pub axes_mm: Vector3<f64>,
    /// Of the distance: `sqrt(trace)` of the position block plus the floor squared (mm).
    pub position_mm: f64,
    /// Of the orientation: `sqrt(trace)` of the orientation block (rad); 0 without orientation
    /// parameters' effect.
    pub orientation_rad: f64,
}

/// A calibrated model and its covariance, ready to predict at any pose.
#[derive(Debug, Clone)]
pub struct AccuracyModel {
    chain: ChainAt,
    selection: Selection,
    sigma: DMatrix<f64>,
    floor_mm: f64,
}

impl AccuracyModel {
    /// The predictor of `model` (its tool point the point predicted) with `covariance`: the
    /// parameters of the covariance the model has (`markerN.*` of marker 1 are its `tool.*`);
    /// others (markers other than the tool) do not move the tool and are left out.
    pub fn new(model: &RobotModel, covariance: &ParameterCovariance) -> Result<Self, CovarianceError> {
        let n = covariance.names.len();
        let square = covariance.covariance.len() == n
            && covariance.covariance.iter().all(|r| r.len() == n && r.iter().all(|v| v.is_finite()));
        if !square {
            return Err(CovarianceError::Shape(n));
        }
        if !(covariance.floor_mm.is_finite() && covariance.floor_mm >= 0.0) {
            return Err(CovarianceError::Floor(covariance.floor_mm));
        }
        let chain = Chain::new(model);
        let params = chain.params();
        // (index in the model's parameters, index in the covariance)
        let mut pairs: Vec<(usize, usize)> = covariance
            .names
            .iter()
            .enumerate()
            .filter_map(|(k, name)| {
                let name = name.strip_prefix("marker1.").map_or(name.clone(), |rest| format!("tool.{rest}"));
                params.index_by_name(&name).map(|i| (i, k))
            })
            .collect();
        pairs.sort();
        let selection = Selection::from_indices(params, pairs.iter().map(|p| p.0));
        let sigma =
            DMatrix::from_fn(pairs.len(), pairs.len(), |r, c| covariance.covariance[pairs[r].1][pairs[c].1]);
        let zero = vec![0.0; params.len()];
        Ok(Self { chain: chain.with_errors(&zero), selection, sigma, floor_mm: covariance.floor_mm })
    }

    /// The number of covariance parameters that move the tool.
    pub fn parameters(&self) -> usize {
        self.selection.len()
    }

    /// The prediction at joint values `q` (rad, mm); `h` is a 6 x parameters work matrix.
    fn predict_into(&self, q: &[f64], h: &mut DMatrix<f64>) -> Predicted {
        let k = self.selection.len();
        self.chain.identification_jacobian(q, &self.selection, Measured::Pose, h.view_mut((0, 0), (6, k)));
        let hs = &*h * &self.sigma;
        let variance = |row: usize| hs.row(row).dot(&h.row(row)).max(0.0);
        let floor_axis = self.floor_mm * self.floor_mm / 3.0;
        let axes = Vector3::new(variance(0), variance(1), variance(2));
        Predicted {
            axes_mm: axes.map(|v| (v + floor_axis).sqrt()),
            position_mm: (axes.sum() + self.floor_mm * self.floor_mm).sqrt(),
            orientation_rad: (variance(3) + variance(4) + variance(5)).sqrt(),
        }
    }

    /// The prediction at joint values `q` (rad, mm).
    pub fn predict(&self, q: &[f64]) -> Predicted {
        let mut h = DMatrix::zeros(6, self.selection.len());
        self.predict_into(q, &mut h)
    }

    /// The predictions at every pose of `poses`, in order, on the current rayon pool (the same
    /// on any number of threads), with the tool position (mm) at each.
    pub fn map(&self, poses: &[Vec<f64>]) -> Vec<(Vector3<f64>, Predicted)> {
        poses
            .par_iter()
            .map_init(
                || DMatrix::zeros(6, self.selection.len()),
                |h, q| (self.chain.position(q), self.predict_into(q, h)),
            )
            .collect()
    }
}

/// A grid over the joint ranges: `per_joint` values of each of the first joints that move the
/// tool's position (all but the last `wrist` joints, held at the middle of their ranges),
/// `per_joint ^ (dof - wrist)` poses in all.
pub fn joint_grid(model: &RobotModel, per_joint: usize, wrist: usize) -> Vec<Vec<f64>> {
    let per_joint = per_joint.max(1);
    let moving = model.dof().saturating_sub(wrist);
    let value = |j: usize, i: usize| {
        let [lo, hi] = model.joints[j].limits;
        if per_joint == 1 { 0.5 * (lo + hi) } else { lo + (hi - lo) * i as f64 / (per_joint - 1) as f64 }
    };
    let total = per_joint.pow(moving as u32);
    (0..total)
        .map(|mut index| {
            (0..model.dof())
                .map(|j| {
                    if j < moving {
                        let i = index % per_joint;
                        index /= per_joint;
                        value(j, i)
                    } else {
                        let [lo, hi] = model.joints[j].limits;
                        0.5 * (lo + hi)
                    }
                })
                .collect()
        })
        .collect()
}
