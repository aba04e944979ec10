//! Estimation of the parameter errors from `y = H x + e` (the paper's Eq. 1).
//!
//! - [`Estimator::Ols`]: ordinary least squares.
//! - [`Estimator::Wls`]: the Gauss-Markov estimator `x = (H^T V^-1 H)^-1 H^T V^-1 y` (Eq. 4),
//!   and for rank `r < p` its extension `x = M^+ H^T V^-1 y`, `M = H^T V^-1 H` (Eq. 6), with the
//!   full blocks `V_k = J_k Sigma_q J_k^T + Sigma_m,k` (Eq. 10, per point).
//! - [`Estimator::WlsDiag`]: weights from the diagonal of each `V_k` only.
//! - [`Estimator::WlsSigma`]: weights `1/sigma` instead of `1/sigma^2` (the paper says it tried
//!   such alternatives and found them no better).
//!
//! Every weighted estimator is computed by whitening, never with a dense `N_m x N_m` matrix:
//! each block of rows is multiplied by `S_k` (for Gauss-Markov `S_k = L_k^-1`, with
//! `V_k = L_k L_k^T`), and the whitened least-squares problem is solved by a rank-revealing
//! factorisation (see [`LinearEstimate`]). `M^+ H^T V^-1 y = pinv(S H) S y` exactly, so this
//! is Eq. 6 itself. The paper's normalisation `W = sigma_max^2 V^-1` (before Eq. 18) is applied;
//! it scales every weight by one constant and leaves `x` unchanged.

mod blocks;
mod device;
pub mod evidence;
mod noise;
mod noise_file;
pub mod prior;
mod problem;
mod reduced;
mod refine;
pub mod reml;
mod solve;
pub mod trust;
mod variance;
pub(crate) use variance::Z_95;

pub use blocks::Blocks;
use blocks::block_weights;
pub(crate) use blocks::{block_diagonal_mul, check_covariance};
pub use device::{Device, DeviceError};
pub use noise::{MeasurementNoise, NoiseModel};
pub(crate) use noise_file::DeviceTable;
pub use noise_file::{NoiseFileError, NoiseSpec};
pub use prior::{
    PRESETS as PRIOR_PRESETS, PriorEntry, PriorError, PriorRows, PriorUnit, prior_entry_of, prior_sds,
    prior_sds_of,
};
pub(crate) use problem::length_per_radian;
pub use problem::{POSE_SIGMAS, PointProblem};
pub use reduced::Reduced;
pub(crate) use refine::refine_within;
pub use refine::{
    Iteration, Linearisation, RefineOptions, Refined, Residuals, linearise, refine, refine_from, refine_map,
};
pub use solve::{Combination, Diagnostics, LinearEstimate, RANK_TOLERANCE, combination_text};
pub use variance::{
    ComponentFit, JointComponents, MeasurementClass, NoiseEstimate, SigmaInterval, sample_covariance,
};
pub(crate) use variance::{CovarianceSample, NoiseLayout, PointRows, noise_design, residual_samples};

use nalgebra::storage::{IsContiguous, StorageMut};
use nalgebra::{DMatrix, DVector, Dim, Dyn, Matrix};
use std::fmt;
use std::str::FromStr;

/// The weighting of the least-squares problem.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Estimator {
    /// Ordinary least squares: every row weighted alike.
    Ols,
    /// Gauss-Markov: the inverse of the full covariance blocks `V_k` (Eqs. 4, 6).
    Wls,
    /// The inverse of the diagonal of each `V_k` (each coordinate's variance).
    WlsDiag,
    /// `1/sigma` of each coordinate instead of `1/sigma^2`.
    WlsSigma,
}

impl Estimator {
    /// Every estimator, in the order reports list them.
    pub const ALL: [Estimator; 4] = [Self::Ols, Self::Wls, Self::WlsDiag, Self::WlsSigma];

    /// The name on the command line and in reports: `ols`, `wls`, `wls-diag`, `wls-sigma`.
    pub fn name(self) -> &'static str {
        match self {
            Self::Ols => "ols",
            Self::Wls => "wls",
            Self::WlsDiag => "wls-diag",
            Self::WlsSigma => "wls-sigma",
        }
    }
}

impl fmt::Display for Estimator {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for Estimator {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        Self::ALL.into_iter().find(|e| e.name() == s).ok_or_else(|| {
            let names: Vec<_> = Self::ALL.iter().map(|e| e.name()).collect();
            format!("unknown estimator `{s}`, expected one of: {}", names.join(", "))
        })
    }
}

/// Why an estimate could not be computed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum EstimationError {
    /// A value in y, H or V is NaN or infinite.
    #[error("{what} row {row} holds {value}: expected finite numbers")]
    NonFinite {
        /// `y`, `H` or `V`.
        what: &'static str,
        /// The row (0-based) of the stacked system.
        row: usize,
        /// The offending value.
        value: f64,
    },
    /// A covariance block `V_k` has no Cholesky factor.
    #[error("the covariance V_k of point {point} is not positive definite")]
    NotPositiveDefinite {
        /// The point (0-based).
        point: usize,
    },
    /// The parts of the system do not fit together.
    #[error("mismatched dimensions: {0}")]
    Dimensions(String),
    /// No parameter to estimate, or no equation.
    #[error("nothing to estimate: {0}")]
    NothingToEstimate(String),
    /// Fewer equations than the rank the parameters need.
    #[error(
        "{equations} equations cannot identify {parameters} parameters: the rank ({rank}) is limited by the \
         number of equations; measure more points or identify fewer parameters"
    )]
    TooFewEquations {
        /// Rows of y.
        equations: usize,
        /// Columns of H.
        parameters: usize,
        /// The numerical rank found.
        rank: usize,
    },
    /// The singular value decomposition did not converge (non-finite or extreme values).
    #[error("the singular value decomposition of the weighted H did not converge")]
    NoConvergence,
    /// A weighted estimator was asked for without a noise covariance.
    #[error("estimator `{0}` needs the noise covariance (Sigma_q and Sigma_m)")]
    NoiseRequired(Estimator),
    /// The noise model does not fit the robot or the points.
    #[error("noise model: {0}")]
    Noise(String),
}

/// The linear model of `N_p` points, `y = H x + e` (Eq. 1), with the covariance of `e`.
#[derive(Debug, Clone, PartialEq)]
pub struct LinearSystem {
    /// Identification Jacobian, `N_m x p` (rows point by point).
    pub h: DMatrix<f64>,
    /// Pose errors: measured minus predicted, `N_m`.
    pub y: DVector<f64>,
    /// Rows per point: 3 (position), 6 (pose), or 3 per marker when several are measured.
    pub rows_per_point: usize,
    /// The blocks `V_k`, stacked: `N_m x rows_per_point`, rows of point k at `k * rows_per_point`.
    /// `None` when the noise is unknown (then only OLS, with the variance from the residuals).
    pub v: Option<DMatrix<f64>>,
    /// The name of each column's parameter (`j3.beta`); empty for `x1`, `x2`, ...
    pub names: Vec<String>,
}

impl LinearSystem {
    /// The column names, `x1`, `x2`, ... where none are given.
    pub fn column_names(&self) -> Vec<String> {
        column_names(self.names.clone(), self.h.ncols())
    }

    /// Number of points.
    pub fn points(&self) -> usize {
        self.y.len() / self.rows_per_point
    }

    /// Check dimensions and finiteness.
    pub fn validate(&self) -> Result<(), EstimationError> {
        let (rows, b) = (self.y.len(), self.rows_per_point);
        let dims = |s: String| Err(EstimationError::Dimensions(s));
        if b == 0 {
            return dims("0 rows per point".into());
        }
        if rows % b != 0 || self.h.nrows() != rows {
            return dims(format!("y has {rows} rows and H {}; both must be {b} per point", self.h.nrows()));
        }
        if !self.names.is_empty() && self.names.len() != self.h.ncols() {
            return dims(format!("{} names for {} columns of H", self.names.len(), self.h.ncols()));
        }
        if let Some(v) = &self.v
            && v.shape() != (rows, b)
        {
            return dims(format!("V blocks are {:?}, expected {rows} x {b}", v.shape()));
        }
        self.check_finite()?;
        match &self.v {
            Some(v) => check_covariance(v, &Blocks::Uniform(b)),
            None => Ok(()),
        }
    }

    /// Check that y and H hold finite numbers (what changes between Gauss-Newton steps).
    fn check_finite(&self) -> Result<(), EstimationError> {
        finite_system(&self.h, &self.y)
    }
}

/// Check that `h` and `y` (or their whitened forms) hold finite numbers; rows as in the
/// stacked system.
pub(crate) fn finite_system(h: &DMatrix<f64>, y: &DVector<f64>) -> Result<(), EstimationError> {
    finite("y", y.as_slice(), y.len())?;
    finite("H", h.as_slice(), h.nrows())
}

/// `names`, or `x1`, `x2`, ... for `columns` columns where none are given.
fn column_names(names: Vec<String>, columns: usize) -> Vec<String> {
    if names.is_empty() { (1..=columns).map(|i| format!("x{i}")).collect() } else { names }
}

/// The first non-finite value of a column-major matrix with `rows` rows, as an error.
pub(crate) fn finite(what: &'static str, values: &[f64], rows: usize) -> Result<(), EstimationError> {
    match values.iter().position(|v| !v.is_finite()) {
        Some(i) => Err(EstimationError::NonFinite { what, row: i % rows.max(1), value: values[i] }),
        None => Ok(()),
    }
}

/// The whitened problem `min |b - A x|^2`, `A = S H`, `b = S y`, and the covariance of `b`,
/// `S_k V_k S_k^T` stacked like `V` (identity blocks for Gauss-Markov).
pub(crate) struct Whitened {
    pub a: DMatrix<f64>,
    pub b: DVector<f64>,
    pub noise: Option<RowCovariance>,
    pub blocks: Blocks,
}

/// The covariance of the whitened rows, `S_k V_k S_k^T` of every point.
#[derive(Debug, Clone, PartialEq)]
pub(crate) enum RowCovariance {
    /// Every block `c I` to a relative 1e-9 (Gauss-Markov whitening leaves `sigma_max^2 I` to
    /// rounding): `c` alone, `N_m x width` numbers not held.
    Scale(f64),
    /// The blocks stacked (`N_m x width`, laid out as the rows).
    Blocks(DMatrix<f64>),
}

impl RowCovariance {
    /// The covariance of the stacked blocks `stacked` laid out by `blocks`: [`Self::Scale`] if
    /// every block is a multiple of the identity ([`blocks::identity_multiple`]).
    fn of(stacked: DMatrix<f64>, blocks: &Blocks) -> Self {
        match blocks::identity_multiple(&stacked, blocks) {
            Some(c) => Self::Scale(c),
            None => Self::Blocks(stacked),
        }
    }

    /// Every block times `factor`.
    fn scale(&mut self, factor: f64) {
        match self {
            Self::Scale(c) => *c *= factor,
            Self::Blocks(stacked) => *stacked *= factor,
        }
    }

    /// The stacked blocks, `c I` written out for [`Self::Scale`] (`rows` rows).
    fn into_blocks(self, blocks: &Blocks, rows: usize) -> DMatrix<f64> {
        match self {
            Self::Blocks(stacked) => stacked,
            Self::Scale(c) => {
                let mut stacked = DMatrix::zeros(rows, blocks.width());
                for r in blocks.ranges(rows) {
                    stacked.view_mut((r.start, 0), (r.len(), r.len())).fill_diagonal(c);
                }
                stacked
            }
        }
    }
}

/// The whitening operator `S = blockdiag(S_k)` of an estimator, with the paper's normalisation.
#[derive(Debug, Clone)]
pub struct Weights {
    /// `S_k` stacked (`N_m x width`, laid out by `blocks`); `None` for OLS (the identity).
    s: Option<DMatrix<f64>>,
    /// `S_k V_k S_k^T` stacked, if `V` is known.
    noise: Option<RowCovariance>,
    blocks: Blocks,
    /// The standard deviation of a whitened row, `sigma_max` of the normalisation (1 without
    /// it), if `V` is known.
    scale: Option<f64>,
    /// Whether `s` whitens (a weighted estimator), rather than only scaling rows of different
    /// units to one (OLS of poses).
    whitened: bool,
}

impl Weights {
    /// The weights of `estimator` for blocks `v` (`N_m x rows`, stacked `V_k`), normalised
    /// as the paper does (`W = sigma_max^2 V^-1`) if `normalise`.
    pub fn new(
        v: Option<&DMatrix<f64>>,
        rows: usize,
        estimator: Estimator,
        normalise: bool,
    ) -> Result<Self, EstimationError> {
        Self::of_blocks(v, Blocks::Uniform(rows), estimator, normalise)
    }

    /// [`Weights::new`] for points laid out by `blocks` (`v` stacked `N_m x blocks.width()`).
    pub fn of_blocks(
        v: Option<&DMatrix<f64>>,
        blocks: Blocks,
        estimator: Estimator,
        normalise: bool,
    ) -> Result<Self, EstimationError> {
        let Some(v) = v else {
            return match estimator {
                Estimator::Ols => Ok(Self { s: None, noise: None, blocks, scale: None, whitened: false }),
                _ => Err(EstimationError::NoiseRequired(estimator)),
            };
        };
        let sigma_max = blocks.diagonal(v).into_iter().fold(0.0, f64::max).sqrt();
        if estimator == Estimator::Ols {
            let noise = Some(RowCovariance::of(v.clone(), &blocks));
            return Ok(Self { s: None, noise, blocks, scale: Some(sigma_max), whitened: false });
        }
        let (mut s, mut noise) = block_weights(v, &blocks, estimator)?;
        let mut scale = 1.0;
        if normalise {
            // W = sigma_max^2 V^-1: S scaled by sigma_max (by its square root for 1/sigma weights).
            let c = if estimator == Estimator::WlsSigma { sigma_max.sqrt() } else { sigma_max };
            if c > 0.0 {
                s *= c;
                noise.scale(c * c);
                scale = sigma_max;
            }
        }
        Ok(Self { s: Some(s), noise: Some(noise), blocks, scale: Some(scale), whitened: true })
    }

    /// The standard deviation `c` of a whitened row: `sigma_max` under the paper's
    /// normalisation, for every estimator (OLS leaves rows in mm and takes the largest noise
    /// for them); `None` without a noise model. Priors scale their rows by it ([`PriorRows`]).
    pub fn scale(&self) -> Option<f64> {
        self.scale
    }

    /// Whether the rows are whitened (a weighted estimator), not taken as they are or only
    /// scaled to one unit.
    pub fn whitens(&self) -> bool {
        self.whitened
    }

    /// How the rows fall into points.
    pub fn blocks(&self) -> &Blocks {
        &self.blocks
    }

    /// These weights with point `k`'s whitening multiplied by `sqrt(w_k)`, as if its covariance
    /// were `V_k / w_k` (iteratively reweighted least squares): the whitened noise blocks are
    /// multiplied by `w_k`. `w` has one weight per point.
    pub fn reweighted(&self, w: &[f64]) -> Self {
        let b = &self.blocks;
        let rows = if w.is_empty() { 0 } else { b.range(w.len() - 1).end };
        let mut s = match &self.s {
            Some(s) => s.clone(),
            None => {
                let mut identity = DMatrix::zeros(rows, b.width());
                for r in b.ranges(rows) {
                    identity.view_mut((r.start, 0), (r.len(), r.len())).fill_with_identity();
                }
                identity
            }
        };
        let mut noise = self.noise.clone().map(|n| n.into_blocks(b, rows));
        for (k, &w_k) in w.iter().enumerate() {
            let r = b.range(k);
            s.rows_mut(r.start, r.len()).scale_mut(w_k.sqrt());
            if let Some(noise) = &mut noise {
                noise.rows_mut(r.start, r.len()).scale_mut(w_k);
            }
        }
        let noise = noise.map(RowCovariance::Blocks);
        Self { s: Some(s), noise, blocks: b.clone(), scale: self.scale, whitened: self.whitened }
    }

    /// Ordinary least squares on rows of different units: every row of `y` multiplied by its
    /// factor in `scale` (`N_m` factors; `S_k` the diagonal of point `k`'s, points laid out by
    /// `blocks`), so that the unweighted fit minimises `|S y|^2`. A pose's orientation rows
    /// (rad) are scaled by `sigma_position / sigma_orientation` (mm/rad): one radian then
    /// counts as the length whose error is as likely, never as one millimetre. `v` (the blocks
    /// `V_k`, if known) gives the covariance of the scaled errors, `S_k V_k S_k`.
    pub fn scaled_rows(v: Option<&DMatrix<f64>>, blocks: Blocks, scale: &[f64]) -> Self {
        let (rows, width) = (scale.len(), blocks.width());
        let mut s = DMatrix::zeros(rows, width);
        let mut noise = v.map(|v| DMatrix::zeros(v.nrows(), width));
        for r in blocks.ranges(rows) {
            for i in r.clone() {
                s[(i, i - r.start)] = scale[i];
                if let (Some(noise), Some(v)) = (&mut noise, v) {
                    for j in 0..r.len() {
                        noise[(i, j)] = scale[i] * v[(i, j)] * scale[r.start + j];
                    }
                }
            }
        }
        // The rows' largest standard deviation, as OLS with a noise model takes it.
        let sigma_max = noise.as_ref().map(|n| blocks.diagonal(n).into_iter().fold(0.0, f64::max).sqrt());
        let noise = noise.map(RowCovariance::Blocks);
        Self { s: Some(s), noise, blocks, scale: sigma_max, whitened: false }
    }

    /// Whether these weights are for `equations` rows in points laid out by `blocks`.
    pub(crate) fn fits(&self, equations: usize, blocks: &Blocks) -> bool {
        self.blocks == *blocks
            && match (&self.s, &self.noise) {
                (Some(s), _) | (None, Some(RowCovariance::Blocks(s))) => s.nrows() == equations,
                _ => true,
            }
    }

    /// Multiply `m` (`N_m` rows) by `S` in place, block by block, without allocating.
    pub fn apply<C: Dim, St: StorageMut<f64, Dyn, C> + IsContiguous>(&self, m: &mut Matrix<f64, Dyn, C, St>) {
        if let Some(s) = &self.s {
            block_diagonal_mul(s, &self.blocks, m);
        }
    }

    /// Multiply the rows of point `k` by `S_k` in place: `block` holds one or more columns of
    /// that point's rows, one after the other (a column-major `size_k x n` block). Whitening a
    /// point's block while it is in cache costs a third of a pass over the whole of `H`.
    pub fn apply_point(&self, k: usize, block: &mut [f64]) {
        if let Some(s) = &self.s {
            let r = self.blocks.range(k);
            blocks::block_mul(s, r.start, r.len(), block.chunks_exact_mut(r.len()));
        }
    }

    /// The covariance of the whitened errors, `S_k V_k S_k^T` (`V` itself for OLS), laid out
    /// by [`Self::blocks`]; `None` without a noise model.
    pub(crate) fn noise(&self) -> Option<&RowCovariance> {
        self.noise.as_ref()
    }

    /// `A = S H`, `b = S y` and the whitened noise blocks of `system`.
    pub(crate) fn whiten(&self, system: &LinearSystem) -> Whitened {
        let (mut a, mut b) = (system.h.clone(), system.y.clone());
        self.apply(&mut a);
        self.apply(&mut b);
        Whitened { a, b, noise: self.noise.clone(), blocks: self.blocks.clone() }
    }
}

/// Estimate `x` from `system` with `estimator` in one linear step (Eqs. 4-6), with the
/// diagnostics and covariance of [`LinearEstimate`]. `rank_tolerance` is relative to the
/// largest singular value of the column-scaled whitened `H` ([`RANK_TOLERANCE`] by default).
///
/// Two points of 3 rows, one parameter seen by both, the second point four times as noisy:
/// Gauss-Markov trusts the first point more, ordinary least squares does not.
///
/// ```
/// use nalgebra::{DMatrix, DVector};
/// use robocal::estimation::{Estimator, LinearSystem, RANK_TOLERANCE, estimate};
///
/// let h = DMatrix::from_column_slice(6, 1, &[1.0, 0.0, 0.0, 1.0, 0.0, 0.0]);
/// let y = DVector::from_column_slice(&[1.0, 0.0, 0.0, 2.0, 0.0, 0.0]);
/// let mut v = DMatrix::zeros(6, 3); // the blocks V_1, V_2 stacked
/// v.view_mut((0, 0), (3, 3)).fill_with_identity();
/// v.view_mut((3, 0), (3, 3)).copy_from(&(DMatrix::identity(3, 3) * 16.0));
/// let system = LinearSystem { h, y, rows_per_point: 3, v: Some(v), names: vec!["d".into()] };
/// let ols = estimate(&system, Estimator::Ols, RANK_TOLERANCE).unwrap();
/// let wls = estimate(&system, Estimator::Wls, RANK_TOLERANCE).unwrap();
/// assert!((ols.x[0] - 1.5).abs() < 1e-12);
/// assert!((wls.x[0] - (1.0 * 1.0 + 2.0 / 16.0) / (1.0 + 1.0 / 16.0)).abs() < 1e-12);
/// assert!(wls.covariance[(0, 0)] < ols.covariance[(0, 0)]);
/// ```
pub fn estimate(
    system: &LinearSystem,
    estimator: Estimator,
    rank_tolerance: f64,
) -> Result<LinearEstimate, EstimationError> {
    system.validate()?;
    let weights = Weights::new(system.v.as_ref(), system.rows_per_point, estimator, true)?;
    solve::solve(&weights.whiten(system), rank_tolerance, system.column_names())
}

/// What [`estimate`] reports on identifiability, without the estimate: rank, singular values,
/// identifiable subset and non-identifiable combinations of the column-scaled whitened `H`.
/// `system.y` is not used.
pub fn diagnose(
    system: &LinearSystem,
    estimator: Estimator,
    rank_tolerance: f64,
) -> Result<Diagnostics, EstimationError> {
    system.validate()?;
    let weights = Weights::new(system.v.as_ref(), system.rows_per_point, estimator, true)?;
    let w = weights.whiten(system);
    let reduced = Reduced::of_whitened(&w.a, &w.b, &w.blocks, None);
    solve::diagnose_reduced(&reduced, rank_tolerance, &[], false)
}

/// The pseudoinverse `pinv(A)` by the same rank-revealing factorisation as every estimate.
pub fn pseudo_inverse(a: &DMatrix<f64>) -> Result<DMatrix<f64>, EstimationError> {
    Ok(solve::factorise(a, RANK_TOLERANCE)?.pinv(a))
}

/// An estimator factored for one `H` and `V`: the estimate for any `y` is then one product,
/// `x = pinv(S H) S y`. This is how a Monte Carlo study solves many runs on one point set.
#[derive(Debug, Clone)]
pub struct Prepared {
    weights: Weights,
    pinv: DMatrix<f64>,
    diagnostics: Diagnostics,
}

impl Prepared {
    /// Factor `h` (`N_m x p`) for `estimator`, with the stacked blocks `v` (`N_m x rows`).
    pub fn new(
        h: &DMatrix<f64>,
        v: Option<&DMatrix<f64>>,
        rows_per_point: usize,
        estimator: Estimator,
        rank_tolerance: f64,
    ) -> Result<Self, EstimationError> {
        let (y, names) = (DVector::zeros(h.nrows()), Vec::new());
        let system = LinearSystem { h: h.clone(), y, rows_per_point, v: v.cloned(), names };
        system.validate()?;
        let weights = Weights::new(v, rows_per_point, estimator, true)?;
        let a = weights.whiten(&system).a;
        let factorised = solve::factorise(&a, rank_tolerance)?;
        Ok(Self { weights, pinv: factorised.pinv(&a), diagnostics: factorised.diagnostics })
    }

    /// Factor `h` for the weights `weights` (as [`Weights::for_problem`] gives them: an
    /// ordinary least squares of pose rows scales their orientation rows).
    pub fn with_weights(
        h: &DMatrix<f64>,
        weights: Weights,
        rank_tolerance: f64,
    ) -> Result<Self, EstimationError> {
        let mut a = h.clone();
        weights.apply(&mut a);
        let factorised = solve::factorise(&a, rank_tolerance)?;
        Ok(Self { weights, pinv: factorised.pinv(&a), diagnostics: factorised.diagnostics })
    }

    /// The estimate for pose errors `y` (Eqs. 4-6).
    pub fn estimate(&self, y: &DVector<f64>) -> DVector<f64> {
        let mut b = y.clone();
        self.weights.apply(&mut b);
        &self.pinv * b
    }

    /// Rank, singular values and identifiability of the factored system.
    pub fn diagnostics(&self) -> &Diagnostics {
        &self.diagnostics
    }
}

#[cfg(test)]
mod tests;
