//! The calibration problem of measured points: the robot, its joint values and what was
//! measured at each point, linearised about any parameter values.

use super::refine::Residuals;
use super::{EstimationError, LinearSystem, NoiseModel};
use crate::kinematics::{Chain, Measured, pose_error};
use crate::model::Selection;
use nalgebra::{DMatrix, DVector, Isometry3, Matrix6xX};

/// Points measured on a robot: `y(x) = measured - f(q, x)` for the selected parameters `x`,
/// the others held at fixed values.
#[derive(Debug, Clone)]
pub struct PointProblem<'a> {
    chain: &'a Chain,
    selection: &'a Selection,
    measured: Measured,
    joints: Vec<Vec<f64>>,
    observed: Vec<Isometry3<f64>>,
    fixed: Vec<f64>,
    v: Option<DMatrix<f64>>,
}

impl<'a> PointProblem<'a> {
    /// The problem of `observed` poses (for position measurements only the translation is
    /// used) at joint values `joints`, with every parameter error at `fixed` (full vector; the
    /// selected ones are where iterations start). With a `noise` model, `V_k` is computed
    /// once, from the manipulator Jacobian at `fixed` (Eq. 10).
    pub fn new(
        chain: &'a Chain,
        selection: &'a Selection,
        measured: Measured,
        joints: Vec<Vec<f64>>,
        observed: Vec<Isometry3<f64>>,
        fixed: Vec<f64>,
        noise: Option<&NoiseModel>,
    ) -> Result<Self, EstimationError> {
        let dims = |s: String| Err(EstimationError::Dimensions(s));
        if observed.len() != joints.len() {
            return dims(format!(
                "{} measurements for {} joint configurations",
                observed.len(),
                joints.len()
            ));
        }
        if let Some(k) = joints.iter().position(|q| q.len() != chain.dof()) {
            return dims(format!(
                "point {k} has {} joint values, the robot {}",
                joints[k].len(),
                chain.dof()
            ));
        }
        if fixed.len() != chain.params().len() {
            return dims(format!("{} parameter values for {} parameters", fixed.len(), chain.params().len()));
        }
        if let Some((k, _)) = joints.iter().enumerate().find(|(_, q)| q.iter().any(|v| !v.is_finite())) {
            return Err(EstimationError::NonFinite { what: "joint values", row: k, value: f64::NAN });
        }
        let v = match noise {
            None => None,
            Some(noise) => {
                noise.validate(chain.dof(), joints.len(), measured)?;
                let rows = measured.rows();
                let at = chain.with_errors(&fixed);
                let mut jacobian = Matrix6xX::zeros(chain.dof());
                let mut v = DMatrix::zeros(rows * joints.len(), rows);
                for (k, q) in joints.iter().enumerate() {
                    at.manipulator_jacobian(q, &mut jacobian);
                    v.rows_mut(k * rows, rows).copy_from(&noise.point_covariance(k, &jacobian, measured));
                }
                Some(v)
            }
        };
        Ok(Self { chain, selection, measured, joints, observed, fixed, v })
    }

    /// The selected parameters' values in `fixed`: where iterations start.
    pub fn start(&self) -> DVector<f64> {
        DVector::from_iterator(self.selection.len(), self.selection.indices().iter().map(|&i| self.fixed[i]))
    }

    /// The full parameter vector with the selected parameters at `x`.
    pub fn full(&self, x: &DVector<f64>) -> Vec<f64> {
        let mut full = self.fixed.clone();
        for (&i, &v) in self.selection.indices().iter().zip(x.iter()) {
            full[i] = v;
        }
        full
    }

    /// The linear system `y = H dx` about `x` (Eq. 1).
    pub fn system(&self, x: &DVector<f64>) -> LinearSystem {
        let mut h = DMatrix::zeros(self.joints.len() * self.measured.rows(), self.selection.len());
        let y = self.evaluate(x, Some(&mut h));
        LinearSystem { h, y, rows_per_point: self.measured.rows(), v: self.v.clone(), names: self.names() }
    }
}

impl Residuals for PointProblem<'_> {
    fn rows_per_point(&self) -> usize {
        self.measured.rows()
    }

    fn names(&self) -> Vec<String> {
        self.selection.indices().iter().map(|&i| self.chain.params().get(i).name.clone()).collect()
    }

    fn equations(&self) -> usize {
        self.joints.len() * self.measured.rows()
    }

    fn covariance(&self) -> Option<&DMatrix<f64>> {
        self.v.as_ref()
    }

    fn evaluate(&self, x: &DVector<f64>, mut h: Option<&mut DMatrix<f64>>) -> DVector<f64> {
        let rows = self.measured.rows();
        let at = self.chain.with_errors(&self.full(x));
        let mut y = DVector::zeros(self.joints.len() * rows);
        for (k, (q, observed)) in self.joints.iter().zip(&self.observed).enumerate() {
            let position = match h.as_deref_mut() {
                Some(h) => {
                    let block = h.view_mut((k * rows, 0), (rows, self.selection.len()));
                    at.identification_jacobian(q, self.selection, self.measured, block)
                }
                None => at.position(q),
            };
            match self.measured {
                Measured::Position => {
                    y.fixed_rows_mut::<3>(k * 3).copy_from(&(observed.translation.vector - position));
                }
                Measured::Pose => y.fixed_rows_mut::<6>(k * 6).copy_from(&pose_error(observed, &at.pose(q))),
            }
        }
        y
    }
}
