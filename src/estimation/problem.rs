//! The calibration problem of measured poses: the robot, its joint values and what was
//! measured at each pose, linearised about any parameter values.
//!
//! A pose measurement has 3 position rows (mm) and 3 orientation rows (rad). Ordinary least
//! squares weights its orientation rows by `w = sigma_position / sigma_orientation` (mm/rad,
//! [`PointProblem::orientation_weight`]): the root mean variances of the position and of the
//! orientation rows of the blocks `V_k` when a noise model is given (its measurement sigmas
//! when the joints are exact), [`POSE_SIGMAS`] without one. The estimate then does not depend
//! on the unit of length, and one radian never counts as one millimetre.

use super::refine::Residuals;
use super::{EstimationError, LinearSystem, NoiseModel, Reduced, Weights};
use crate::kinematics::{
    Chain, ChainAt, HeldArm, JointTrig, Measured, end_positions, marker_jacobians_held, pose_error,
};
use crate::model::Selection;
use nalgebra::{DMatrix, DVector, Isometry3, Matrix6xX, Vector3};
use rayon::prelude::*;
use std::sync::{Arc, OnceLock};

/// Poses measured on a robot: `y(x) = measured - f(q, x)` for the selected parameters `x`,
/// the others held at fixed values. Each pose is one point of the estimators: the positions of
/// all its markers (3 rows each), or one tool pose (6 rows).
#[derive(Debug, Clone)]
pub struct PointProblem<'a> {
    chains: &'a [Chain],
    selection: &'a Selection,
    measured: Measured,
    /// The poses' joint values, what was measured and the blocks `V_k`: shared by the problems
    /// [`PointProblem::reselect`] makes.
    joints: Arc<Vec<Vec<f64>>>,
    observed: Arc<Vec<Isometry3<f64>>>,
    fixed: Vec<f64>,
    v: Option<Arc<DMatrix<f64>>>,
    orientation_weight: f64,
    /// The markers' arm steps no selected parameter moves, undone at each pose once for every
    /// linearisation ([`PointProblem::held`]).
    held: OnceLock<Option<Arc<Vec<HeldArm>>>>,
}

/// The position and orientation standard deviations (mm, rad) that weight a pose's rows for
/// ordinary least squares when no noise model is given: those of a 6-DOF probe on a laser
/// tracker (0.05 mm, 0.01 deg), a weight of about 286 mm/rad.
pub const POSE_SIGMAS: (f64, f64) = (0.05, 0.01 * std::f64::consts::PI / 180.0);

impl<'a> PointProblem<'a> {
    /// The problem of `observed` poses at joint values `joints`, with every parameter error at
    /// `fixed` (full vector; the selected ones are where iterations start). `chains` holds one
    /// chain per measured marker ([`Chain::markers`]) or the single chain of a tool; `observed`
    /// holds, pose by pose, where each chain's end was measured (for position measurements
    /// only the translation is used). With a `noise` model, `V_k` is computed once, from the
    /// manipulator Jacobians at `fixed` (Eq. 10).
    pub fn new(
        chains: &'a [Chain],
        selection: &'a Selection,
        measured: Measured,
        joints: Vec<Vec<f64>>,
        observed: Vec<Isometry3<f64>>,
        fixed: Vec<f64>,
        noise: Option<&NoiseModel>,
    ) -> Result<Self, EstimationError> {
        let dims = |s: String| Err(EstimationError::Dimensions(s));
        let Some(chain) = chains.first() else { return dims("no chain to measure".into()) };
        if measured == Measured::Pose && chains.len() > 1 {
            return dims("pose measurements take one tool frame, not several markers".into());
        }
        if chains.len() > 1 && !chains.iter().all(Chain::ends_at_a_point) {
            return dims("several chains must be markers: points on the last link".into());
        }
        if observed.len() != joints.len() * chains.len() {
            let (o, j, m) = (observed.len(), joints.len(), chains.len());
            return dims(format!("{o} measurements for {j} joint configurations of {m} markers"));
        }
        if let Some(k) = joints.iter().position(|q| q.len() != chain.dof()) {
            return dims(format!("pose {k} has {} joint values, the robot {}", joints[k].len(), chain.dof()));
        }
        if fixed.len() != chain.params().len() {
            return dims(format!("{} parameter values for {} parameters", fixed.len(), chain.params().len()));
        }
        if let Some((k, _)) = joints.iter().enumerate().find(|(_, q)| q.iter().any(|v| !v.is_finite())) {
            return Err(EstimationError::NonFinite { what: "joint values", row: k, value: f64::NAN });
        }
        let weight = POSE_SIGMAS.0 / POSE_SIGMAS.1;
        let mut problem = Self {
            chains,
            selection,
            measured,
            joints: Arc::new(joints),
            observed: Arc::new(observed),
            fixed,
            v: None,
            orientation_weight: weight,
            held: OnceLock::new(),
        };
        if let Some(noise) = noise {
            if measured == Measured::Pose && !noise.measures_orientation() {
                return Err(EstimationError::Noise(
                    "pose measurements need the orientation's standard deviation, and the noise gives none: \
                     give --sigma-orientation-deg, or sigma_orientation_deg in the noise file"
                        .into(),
                ));
            }
            let v = problem.covariance_blocks(noise)?;
            if measured == Measured::Pose {
                problem.orientation_weight = orientation_weight(&v);
            }
            problem.v = Some(Arc::new(v));
        }
        Ok(problem)
    }

    /// The same problem with other parameters identified and others fixed, sharing the
    /// covariance blocks `V_k` (they are the noise's, not the parameters').
    pub fn reselect<'b>(
        &self,
        selection: &'b Selection,
        fixed: Vec<f64>,
    ) -> Result<PointProblem<'b>, EstimationError>
    where
        'a: 'b,
    {
        if fixed.len() != self.fixed.len() {
            return Err(EstimationError::Dimensions(format!(
                "{} parameter values for {}",
                fixed.len(),
                self.fixed.len()
            )));
        }
        Ok(PointProblem {
            chains: self.chains,
            selection,
            measured: self.measured,
            joints: self.joints.clone(),
            observed: self.observed.clone(),
            fixed,
            v: self.v.clone(),
            orientation_weight: self.orientation_weight,
            held: OnceLock::new(),
        })
    }

    /// The weight `w = sigma_position / sigma_orientation` (mm/rad) of a pose's orientation
    /// rows under ordinary least squares (see [`POSE_SIGMAS`] for the default); unused for
    /// positions.
    pub fn orientation_weight(&self) -> f64 {
        self.orientation_weight
    }

    /// `V_k` of every pose at the fixed parameters, stacked.
    fn covariance_blocks(&self, noise: &NoiseModel) -> Result<DMatrix<f64>, EstimationError> {
        let rows = self.rows_per_point();
        noise.validate(self.chains[0].dof(), self.joints.len(), rows)?;
        let mut v = DMatrix::zeros(rows * self.joints.len(), rows);
        // A slice of poses at a time: their blocks are small matrices of their own.
        for first in (0..self.joints.len()).step_by(BLOCKS_AT_ONCE) {
            let poses = first..(first + BLOCKS_AT_ONCE).min(self.joints.len());
            let blocks: Vec<DMatrix<f64>> =
                (self.jacobians_of(&self.fixed, poses.clone()).par_iter().enumerate())
                    .map(|(i, stacked)| noise.pose_covariance(first + i, stacked, self.measured))
                    .collect();
            for (k, block) in poses.zip(&blocks) {
                v.rows_mut(k * rows, rows).copy_from(block);
            }
        }
        Ok(v)
    }

    /// The number of poses (points).
    pub fn poses(&self) -> usize {
        self.joints.len()
    }

    /// [`PointProblem::manipulator_jacobians`] of the poses `poses`.
    fn jacobians_of(&self, at: &[f64], poses: std::ops::Range<usize>) -> Vec<DMatrix<f64>> {
        let (per, rows) = (self.measured.rows(), self.rows_per_point());
        let dof = self.chains[0].dof();
        let at: Vec<_> = self.chains.iter().map(|c| c.with_errors(at)).collect();
        self.joints[poses]
            .par_iter()
            .map_init(
                || Matrix6xX::zeros(dof),
                |jacobian, q| {
                    let mut stacked = DMatrix::zeros(rows, dof);
                    for (m, at) in at.iter().enumerate() {
                        at.manipulator_jacobian(q, jacobian);
                        stacked.rows_mut(m * per, per).copy_from(&jacobian.rows(0, per));
                    }
                    stacked
                },
            )
            .collect()
    }

    /// The chains measured: one per marker, or the tool's.
    pub fn chains(&self) -> &'a [Chain] {
        self.chains
    }

    /// Every parameter of the chains (the full vector's, not only the selected ones).
    pub fn params(&self) -> &'a crate::model::ParamSet {
        self.chains[0].params()
    }

    /// The measurement kind (position or pose).
    pub fn measured(&self) -> Measured {
        self.measured
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
        let mut h = DMatrix::zeros(self.equations(), self.selection.len());
        let y = self.evaluate(x, Some(&mut h));
        LinearSystem {
            h,
            y,
            rows_per_point: self.rows_per_point(),
            v: self.v.as_deref().cloned(),
            names: self.names(),
        }
    }
}

impl Residuals for PointProblem<'_> {
    fn rows_per_point(&self) -> usize {
        self.measured.rows() * self.chains.len()
    }

    fn equations(&self) -> usize {
        self.joints.len() * self.rows_per_point()
    }

    fn parameters(&self) -> usize {
        self.selection.len()
    }

    fn names(&self) -> Vec<String> {
        self.selection.indices().iter().map(|&i| self.chains[0].params().get(i).name.clone()).collect()
    }

    fn covariance(&self) -> Option<&DMatrix<f64>> {
        self.v.as_deref()
    }

    fn ols_row_scale(&self) -> Option<Vec<f64>> {
        let w = self.orientation_weight;
        (self.measured == Measured::Pose)
            .then(|| (0..self.equations()).map(|i| if i % 6 < 3 { 1.0 } else { w }).collect())
    }

    fn evaluate(&self, x: &DVector<f64>, h: Option<&mut DMatrix<f64>>) -> DVector<f64> {
        self.residuals(x, None, h)
    }

    fn evaluate_whitened(
        &self,
        x: &DVector<f64>,
        weights: &Weights,
        h: Option<&mut DMatrix<f64>>,
    ) -> DVector<f64> {
        self.residuals(x, Some(weights), h)
    }

    fn linearise_whitened(&self, x: &DVector<f64>, weights: &Weights) -> (DVector<f64>, Reduced) {
        self.stream(x, weights)
    }
}

impl PointProblem<'_> {
    /// `y(x)` and `H(x)`, whitened by `weights` if given; every entry of `h` is written. The
    /// poses are shared between threads in tasks of [`POSES_PER_TASK`], each writing its own
    /// rows: every number is computed alike on any number of threads.
    fn residuals(
        &self,
        x: &DVector<f64>,
        weights: Option<&Weights>,
        h: Option<&mut DMatrix<f64>>,
    ) -> DVector<f64> {
        let task_rows = POSES_PER_TASK * self.rows_per_point();
        let full = self.full(x);
        let at: Vec<_> = self.chains.iter().map(|c| c.with_errors(&full)).collect();
        let mut y = DVector::zeros(self.equations());
        if y.is_empty() {
            return y;
        }
        let mut h_parts = match h {
            Some(h) => {
                assert_eq!(h.shape(), (y.len(), self.selection.len()), "H is equations x parameters");
                row_parts(h, task_rows).into_iter().map(Some).collect()
            }
            None => Vec::new(),
        };
        h_parts.resize_with(y.len().div_ceil(task_rows), || None);
        y.as_mut_slice().par_chunks_mut(task_rows).zip(h_parts).enumerate().for_each(|(task, (y, h))| {
            self.fill_poses(task * POSES_PER_TASK, &at, weights, y, h);
        });
        y
    }

    /// The rows of the poses from `first` on: `y` holds theirs, and `h`, if given, one slice
    /// of their rows per column of `H`. Each pose's rows of `H` are built, and whitened, in a
    /// small contiguous block, then copied out once.
    fn fill_poses(
        &self,
        first: usize,
        at: &[ChainAt],
        weights: Option<&Weights>,
        y: &mut [f64],
        mut h: Option<Vec<&mut [f64]>>,
    ) {
        let rows = self.rows_per_point();
        let mut scratch = self.scratch(at.len());
        for (i, y_k) in y.chunks_exact_mut(rows).enumerate() {
            let k = first + i;
            self.pose(k, at, &mut scratch, h.is_some(), y_k);
            if let Some(columns) = h.as_deref_mut() {
                let block = &mut scratch.block;
                if let Some(weights) = weights {
                    weights.apply_point(k, block.as_mut_slice());
                }
                for (column, values) in columns.iter_mut().zip(block.as_slice().chunks_exact(rows)) {
                    for (to, from) in column[i * rows..(i + 1) * rows].iter_mut().zip(values) {
                        *to = *from;
                    }
                }
            }
            if let Some(weights) = weights {
                weights.apply_point(k, y_k);
            }
        }
    }

    /// The scratch space of [`PointProblem::pose`] for `chains` chains.
    fn scratch(&self, chains: usize) -> Scratch {
        Scratch {
            block: DMatrix::zeros(self.rows_per_point(), self.selection.len()),
            positions: vec![Vector3::zeros(); chains],
        }
    }

    /// Pose `k`'s residual `y_k` (unwhitened) and, if `jacobian`, its rows of `H` in
    /// `scratch.block`.
    fn pose(&self, k: usize, at: &[ChainAt], scratch: &mut Scratch, jacobian: bool, y_k: &mut [f64]) {
        let q = &self.joints[k];
        let Scratch { block, positions } = scratch;
        if jacobian {
            block.fill(0.0);
            let view = block.view_mut((0, 0), block.shape());
            if at.len() > 1 {
                // Markers: the arm walked once for all of them, from its held steps on.
                let held = self.held(at).map(|held| &held[k]);
                marker_jacobians_held(at, JointTrig::plain(q), self.selection, view, positions, held);
            } else {
                positions[0] = at[0].identification_jacobian(q, self.selection, self.measured, view);
            }
        } else if self.measured == Measured::Position {
            end_positions(at, q, positions);
        }
        let observed = &self.observed[k * at.len()..(k + 1) * at.len()];
        match self.measured {
            Measured::Position => {
                for ((observed, position), y_m) in
                    observed.iter().zip(positions.iter()).zip(y_k.chunks_exact_mut(3))
                {
                    y_m.copy_from_slice((observed.translation.vector - position).as_slice());
                }
            }
            Measured::Pose => y_k.copy_from_slice(pose_error(&observed[0], &at[0].pose(q)).as_slice()),
        }
    }

    /// The markers' arm steps that no selected parameter moves, undone at every pose
    /// ([`HeldArm`]), found at the first linearisation and kept for the problem's others: the
    /// parameters it does not select are fixed, so those steps are the same at any `x`. `at`:
    /// the marker chains at the current `x`; `None` for one chain, or nothing to hold.
    fn held(&self, at: &[ChainAt]) -> Option<&[HeldArm]> {
        let held = self.held.get_or_init(|| {
            let from = at.first().filter(|_| at.len() > 1)?.held_from(self.selection)?;
            let chain = self.chains[0].with_errors(&self.fixed);
            Some(Arc::new(self.joints.par_iter().map(|q| chain.held_arm(q, from)).collect()))
        });
        held.as_deref().map(Vec::as_slice)
    }

    /// [`Residuals::linearise_whitened`] without `H`: each pose's rows are built, whitened and
    /// reduced into the triangular factor in one go ([`Reduced::reduce`]).
    fn stream(&self, x: &DVector<f64>, weights: &Weights) -> (DVector<f64>, Reduced) {
        let (rows, p) = (self.rows_per_point(), self.selection.len());
        let full = self.full(x);
        let at: Vec<_> = self.chains.iter().map(|c| c.with_errors(&full)).collect();
        // Found here, on every thread, not by the first pose's task while the others wait.
        self.held(&at);
        let mut y = DVector::zeros(self.equations());
        let reduced = Reduced::reduce(
            &self.blocks(),
            p,
            weights.noise(),
            y.as_mut_slice(),
            || self.scratch(at.len()),
            |scratch, k, out| {
                let (h, y_k) = out.split_at_mut(rows * p);
                self.pose(k, &at, scratch, true, y_k);
                h.copy_from_slice(scratch.block.as_slice());
                weights.apply_point(k, out);
            },
        );
        (y, reduced)
    }
}

/// The scratch space of one task of a linearisation: a pose's rows of `H`, the chains' ends.
pub(crate) struct Scratch {
    block: DMatrix<f64>,
    positions: Vec<Vector3<f64>>,
}

/// `sigma_position / sigma_orientation` of pose blocks `V_k` stacked (`6N x 6`)
/// ([`length_per_radian`] of their diagonals).
fn orientation_weight(v: &DMatrix<f64>) -> f64 {
    length_per_radian((0..v.nrows()).map(|r| (r % 6 >= 3, v[(r, r % 6)])))
}

/// `w = sigma_length / sigma_angle` (mm/rad) of rows given as (whether an angle, its
/// variance): the square root of the ratio of the mean variances of the length rows `l` and
/// of the angle rows `a`, `w = sqrt((sum_l V_ll / sum_a V_aa) (n_a / n_l))` (as many of each:
/// `sqrt(sum_l V_ll / sum_a V_aa)` to the bit). Not finite without a row of either, or without
/// an angle's variance.
pub(crate) fn length_per_radian(rows: impl IntoIterator<Item = (bool, f64)>) -> f64 {
    let (mut sums, mut counts) = ([0.0; 2], [0.0f64; 2]);
    for (angle, variance) in rows {
        sums[usize::from(angle)] += variance;
        counts[usize::from(angle)] += 1.0;
    }
    ((sums[0] / sums[1]) * (counts[1] / counts[0])).sqrt()
}

/// Poses whose covariance blocks `V_k` are computed at once, before they are stacked.
const BLOCKS_AT_ONCE: usize = 4096;

/// Poses per parallel task of [`PointProblem`]'s linearisation: enough to outweigh a task's
/// overhead, few enough to share a thousand poses between cores.
const POSES_PER_TASK: usize = 64;

/// The rows of `h` cut into parts of `rows` (the last may be shorter), each part one slice per
/// column: disjoint, so that parts can be written in parallel.
fn row_parts(h: &mut DMatrix<f64>, rows: usize) -> Vec<Vec<&mut [f64]>> {
    let (m, n) = h.shape();
    let mut parts: Vec<Vec<&mut [f64]>> = (0..m.div_ceil(rows)).map(|_| Vec::with_capacity(n)).collect();
    if m > 0 {
        for column in h.as_mut_slice().chunks_exact_mut(m) {
            for (part, rows) in parts.iter_mut().zip(column.chunks_mut(rows)) {
                part.push(rows);
            }
        }
    }
    parts
}
