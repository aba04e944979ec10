//! Choosing the measurement poses, beyond the paper (which draws them at random): the
//! observability indices of a pose set, and poses planned to maximise one of them.
//!
//! ## The matrix the indices describe
//!
//! The identification Jacobian `H` of a pose set, with two changes that make its singular
//! values comparable between sets, robots and parameter units:
//!
//! - **Identifiable columns only.** A redundant parameter set is rank deficient for *every*
//!   pose set (the paper's 30 PUMA 560 parameters from positions have rank 23, see
//!   `docs/identifiability.md`): on all 30 columns the smallest singular values are zero
//!   whatever the poses, and O1, O3, O4, O5 would be 0 for every set. So the indices are taken
//!   on the identifiable subset of the columns, chosen once per robot by the estimator's own
//!   rank-revealing solve ([`crate::estimation::Diagnostics::identifiable`]) on a reference set
//!   of 500 configurations uniform within the joint limits (from a fixed seed). Structurally redundant columns are fixed combinations of those, so
//!   the determinant on the subset is the pseudo-determinant on all columns times a constant:
//!   the D-optimal design is the same. A pose set that cannot identify what the robot could
//!   (all poses at one joint-1 angle, say) keeps zero singular values, and its indices are 0.
//! - **A fixed column scaling.** Parameters come in mm and rad. Each column is divided by its
//!   root mean square per pose over the same reference set, a constant of the robot: so every
//!   parameter has a typical effect of 1 mm per pose, singular values grow like `sqrt(m)` for
//!   `m` poses, and the indices of two sets can be compared (scaling each set's columns to unit
//!   norm, as the rank decision of the solver does, would remove the set's size from its
//!   indices and reward sets with weak columns).
//!
//! The **column-scaled** `H_s = H D` is what ordinary least squares sees. The **whitened**
//! `H_w = S H D`, with `S = blockdiag(L_k^-1)` and `V_k = L_k L_k^T` (the estimator's own
//! [`Weights`], without the paper's normalisation, which would scale each set by its own
//! largest variance), is what Gauss-Markov sees: `H_w^T H_w = D H^T V^-1 H D` is the inverse of
//! the covariance of the weighted estimate of the scaled parameters. Its singular values are
//! per mm of noise: a set whose `V_k` are smaller scores higher.
//!
//! - **Pose rows in lengths.** When poses are measured, each pose's orientation rows (rad) are
//!   multiplied by `w = sigma_position / sigma_orientation` (mm/rad): the noise model's
//!   measurement sigmas, else [`crate::estimation::POSE_SIGMAS`], as ordinary least squares
//!   weights them; one radian never counts as one millimetre. `V_k` is scaled alike
//!   (`S V_k S`), so the whitened matrix does not change.
//!
//! The indices are [`o1`] ... [`o5`], all of them at once [`Design::observability`]; the
//! planner, a Fedorov exchange over a pool of candidate poses, is [`Design::plan`].

pub mod accuracy;
pub mod compensate;
mod observability;
mod plan;
mod poses;

pub use observability::{Indices, Observability, o1, o2, o3, o4, o5};
pub use plan::{Candidates, Constraints, ExcludedRange, Plan, PlanProgress};
pub use poses::{poses_csv, poses_from_csv_str};

use crate::estimation::{
    EstimationError, Estimator, MeasurementNoise, NoiseModel, Prepared, RANK_TOLERANCE, Weights,
};
use crate::kinematics::{Chain, ChainAt, Measured};
use crate::model::{RobotModel, Selection};
use nalgebra::{DMatrix, Matrix6xX};
use rand::SeedableRng;
use rand::rngs::ChaCha8Rng;
use std::fmt;
use std::str::FromStr;

/// Configurations in the reference set that fixes the identifiable columns and their scaling.
pub(crate) const REFERENCE_POSES: usize = 500;
/// Seed of the reference set (ChaCha8, stream 0).
pub(crate) const REFERENCE_SEED: u64 = 0x000b_5e57_ab1e;

/// What a planned pose set maximises.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Criterion {
    /// D-optimality: `log det(H^T H)` of the identifiable columns, `2 sum(ln sigma_i)`. For a
    /// fixed number of poses it orders sets exactly as O1 does.
    D,
    /// [`o1`]: the geometric mean of the singular values over `sqrt(m)` (Borm and Menq).
    O1,
    /// [`o2`]: the inverse condition number (Driels and Pathre).
    O2,
    /// [`o3`]: the smallest singular value (Nahvi, Hollerbach and Hayward).
    O3,
    /// [`o4`]: the noise amplification index (Nahvi and Hollerbach).
    O4,
    /// [`o5`]: the harmonic combination of the singular values (Sun and Hollerbach).
    O5,
}

impl Criterion {
    /// Every criterion, in the order reports list them.
    pub const ALL: [Criterion; 6] = [Self::D, Self::O1, Self::O2, Self::O3, Self::O4, Self::O5];

    /// The name on the command line and in files: `d`, `o1` ... `o5`.
    pub fn name(self) -> &'static str {
        match self {
            Self::D => "d",
            Self::O1 => "o1",
            Self::O2 => "o2",
            Self::O3 => "o3",
            Self::O4 => "o4",
            Self::O5 => "o5",
        }
    }

    /// The criterion of singular values `s` (largest first, zeros included) of `poses` poses:
    /// larger is better for every criterion.
    pub fn value(self, s: &[f64], poses: usize) -> f64 {
        match self {
            Self::D => log_det(s),
            Self::O1 => o1(s, poses),
            Self::O2 => o2(s),
            Self::O3 => o3(s),
            Self::O4 => o4(s),
            Self::O5 => o5(s),
        }
    }
}

/// `log det(H^T H) = 2 sum(ln sigma_i)`, minus infinity if a singular value is zero.
pub fn log_det(s: &[f64]) -> f64 {
    s.iter().map(|&v| 2.0 * v.ln()).sum()
}

impl fmt::Display for Criterion {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for Criterion {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        Self::ALL.into_iter().find(|c| c.name() == s).ok_or_else(|| {
            let names: Vec<_> = Self::ALL.iter().map(|c| c.name()).collect();
            format!("unknown criterion `{s}`, expected one of: {}", names.join(", "))
        })
    }
}

/// Why a pose set could not be assessed or planned.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum DesignError {
    /// The selection is empty.
    #[error("no parameters to identify")]
    NoParameters,
    /// No pose was given.
    #[error("no poses")]
    NoPoses,
    /// A pose with the wrong number of joint values.
    #[error("pose {pose} has {found} joint values, the robot {expected}")]
    JointCount {
        /// The pose (1-based).
        pose: usize,
        /// Values given.
        found: usize,
        /// Joints of the robot.
        expected: usize,
    },
    /// A joint value that is NaN or infinite.
    #[error("pose {pose}, joint {joint}: {value} is not a finite number")]
    NonFinite {
        /// The pose (1-based).
        pose: usize,
        /// The joint's name.
        joint: String,
        /// The value.
        value: f64,
    },
    /// Fewer equations than identifiable parameters.
    #[error(
        "{points} poses give {equations} equations for {identifiable} identifiable parameters: plan at \
         least {minimum} poses"
    )]
    TooFewPoses {
        /// Poses asked for.
        points: usize,
        /// Equations they give.
        equations: usize,
        /// Identifiable parameters.
        identifiable: usize,
        /// The fewest poses that can identify them.
        minimum: usize,
    },
    /// No candidate satisfied the constraints.
    #[error(
        "no candidate pose within the joint limits satisfies the constraints ({constraints}) in {draws} draws"
    )]
    EmptyPool {
        /// Configurations drawn.
        draws: usize,
        /// The constraints, in words.
        constraints: String,
    },
    /// Fewer usable candidates than poses to choose.
    #[error(
        "only {usable} usable candidate poses to choose {points} from: ask for more candidates or \
         loosen the constraints"
    )]
    PoolTooSmall {
        /// Candidates that satisfy the constraints and have a positive definite `V_k`.
        usable: usize,
        /// Poses asked for.
        points: usize,
    },
    /// A constraint that makes no sense.
    #[error("constraint: {0}")]
    Constraint(String),
    /// The noise model does not fit.
    #[error("noise model: {0}")]
    Noise(String),
    /// The estimator's machinery failed (a `V_k` without a Cholesky factor, an SVD).
    #[error(transparent)]
    Estimation(#[from] EstimationError),
}

/// A robot, the parameters to identify, what is measured and (optionally) the noise: what
/// the indices and the planner need, with the identifiable columns and their scaling fixed
/// (see the [module documentation](self)).
#[derive(Debug, Clone)]
pub struct Design {
    model: RobotModel,
    nominal: ChainAt,
    selection: Selection,
    measured: Measured,
    noise: Option<NoiseModel>,
    columns: Vec<usize>,
    scales: Vec<f64>,
    names: Vec<String>,
    /// `w` of a pose's orientation rows (1 for positions).
    orientation_weight: f64,
}

impl Design {
    /// The design of `model` for the `selection` of its parameters, from `measured` data, with
    /// the noise model (per-axis measurement noise) if known: without it only the
    /// column-scaled indices exist and the planner uses them.
    pub fn new(
        model: &RobotModel,
        selection: Selection,
        measured: Measured,
        noise: Option<NoiseModel>,
    ) -> Result<Self, DesignError> {
        if selection.is_empty() {
            return Err(DesignError::NoParameters);
        }
        if let Some(noise) = &noise {
            if matches!(noise.measurement, MeasurementNoise::PerPoint(_)) {
                return Err(DesignError::Noise(
                    "per-point measurement covariances belong to measured poses; planning needs per-axis sigmas"
                        .into(),
                ));
            }
            noise.validate(model.dof(), 1, measured.rows()).map_err(|e| DesignError::Noise(e.to_string()))?;
        }
        let chain = Chain::new(model);
        let nominal = chain.with_errors(&vec![0.0; chain.params().len()]);
        let names = selection.indices().iter().map(|&i| chain.params().get(i).name.clone()).collect();
        let mut design = Self {
            model: model.clone(),
            nominal,
            selection,
            measured,
            noise,
            columns: Vec::new(),
            scales: Vec::new(),
            names,
            orientation_weight: 1.0,
        };
        if measured == Measured::Pose {
            let (p, o) = match &design.noise {
                Some(NoiseModel { measurement: MeasurementNoise::PerAxis(s), .. })
                    if s[3] > 0.0 && s[0] > 0.0 =>
                {
                    (s[0], s[3])
                }
                _ => crate::estimation::POSE_SIGMAS,
            };
            design.orientation_weight = p / o;
        }
        let mut rng = ChaCha8Rng::seed_from_u64(REFERENCE_SEED);
        let reference = model.uniform_configurations(REFERENCE_POSES, &mut rng);
        let rows = measured.rows();
        let mut h = DMatrix::zeros(rows * REFERENCE_POSES, design.selection.len());
        for (k, q) in reference.iter().enumerate() {
            design.jacobians(q, &mut h, k * rows, None);
        }
        let prepared = Prepared::new(&h, None, rows, Estimator::Ols, RANK_TOLERANCE)?;
        design.columns = prepared.diagnostics().identifiable.clone();
        let per_pose = (REFERENCE_POSES as f64).sqrt();
        design.scales = design.columns.iter().map(|&c| per_pose / h.column(c).norm()).collect();
        Ok(design)
    }

    /// The robot.
    pub fn model(&self) -> &RobotModel {
        &self.model
    }

    /// What is measured at each pose.
    pub fn measured(&self) -> Measured {
        self.measured
    }

    /// Whether the noise is known, so that the whitened indices exist.
    pub fn weighted(&self) -> bool {
        self.noise.is_some()
    }

    /// The names of the identifiable parameters the indices are taken on.
    pub fn identifiable(&self) -> Vec<&str> {
        self.columns.iter().map(|&c| self.names[c].as_str()).collect()
    }

    /// The names of all selected parameters.
    pub fn parameters(&self) -> &[String] {
        &self.names
    }

    /// The scale `D_jj` of each identifiable column (parameter unit per mm of typical effect).
    pub fn scales(&self) -> &[f64] {
        &self.scales
    }

    /// The fewest poses whose equations can identify the identifiable parameters.
    pub fn minimum_poses(&self) -> usize {
        self.columns.len().div_ceil(self.measured.rows())
    }

    /// `H_k` of all selected parameters into rows `row..` of `h`, a pose's orientation rows
    /// times `w`, and, if asked, `J_k` (unscaled).
    fn jacobians(&self, q: &[f64], h: &mut DMatrix<f64>, row: usize, j: Option<&mut Matrix6xX<f64>>) {
        let (rows, p) = (self.measured.rows(), self.selection.len());
        self.nominal.jacobians(q, &self.selection, self.measured, h.view_mut((row, 0), (rows, p)), j);
        if self.measured == Measured::Pose {
            h.view_mut((row + 3, 0), (3, p)).scale_mut(self.orientation_weight);
        }
    }

    /// The rows of one pose: `H_k D` on the identifiable columns, whitened by `L_k^-1` if
    /// `whitened` and the noise is known.
    fn pose_rows(&self, q: &[f64], whitened: bool) -> Result<DMatrix<f64>, EstimationError> {
        let (rows, dof) = (self.measured.rows(), self.model.dof());
        let mut h = DMatrix::zeros(rows, self.selection.len());
        let mut jacobian = Matrix6xX::zeros(dof);
        self.jacobians(q, &mut h, 0, Some(&mut jacobian));
        let mut a =
            DMatrix::from_fn(rows, self.columns.len(), |r, c| h[(r, self.columns[c])] * self.scales[c]);
        if let (true, Some(noise)) = (whitened, &self.noise) {
            let j_k = DMatrix::from_fn(rows, dof, |r, c| jacobian[(r, c)]);
            let mut v_k = noise.pose_covariance(0, &j_k, self.measured);
            // S V_k S, as the rows of H: whitening is then unchanged.
            let w = self.orientation_weight;
            for r in 0..rows {
                for c in 0..rows {
                    v_k[(r, c)] *= if r >= 3 { w } else { 1.0 } * if c >= 3 { w } else { 1.0 };
                }
            }
            Weights::new(Some(&v_k), rows, Estimator::Wls, false)?.apply(&mut a);
        }
        Ok(a)
    }

    /// Check that every pose has finite values, one per joint.
    fn check(&self, joints: &[Vec<f64>]) -> Result<(), DesignError> {
        if joints.is_empty() {
            return Err(DesignError::NoPoses);
        }
        let dof = self.model.dof();
        for (k, q) in joints.iter().enumerate() {
            if q.len() != dof {
                return Err(DesignError::JointCount { pose: k + 1, found: q.len(), expected: dof });
            }
            if let Some(i) = q.iter().position(|v| !v.is_finite()) {
                let joint = self.model.joints[i].name.clone();
                return Err(DesignError::NonFinite { pose: k + 1, joint, value: q[i] });
            }
        }
        Ok(())
    }

    /// The stacked rows of `joints` (`rows * m x r`), column-scaled, whitened if asked.
    pub fn stacked(&self, joints: &[Vec<f64>], whitened: bool) -> Result<DMatrix<f64>, DesignError> {
        self.check(joints)?;
        let rows = self.measured.rows();
        let mut a = DMatrix::zeros(rows * joints.len(), self.columns.len());
        for (k, q) in joints.iter().enumerate() {
            let block = self.pose_rows(q, whitened).map_err(|e| match e {
                EstimationError::NotPositiveDefinite { .. } => {
                    EstimationError::NotPositiveDefinite { point: k }
                }
                e => e,
            })?;
            a.rows_mut(k * rows, rows).copy_from(&block);
        }
        Ok(a)
    }
}
