//! Variance components from data: the noise `V_k = J_k Sigma_q J_k^T + Sigma_m` estimated
//! instead of assumed.
//!
//! The paper's conclusion: the gain of weighted least squares depends on how well `V` is
//! known, and for a fleet of similar robots it pays to measure their random error behaviour
//! first. Both ways to do that come down to one fit. Observed covariance matrices `S_k`
//! (`b x b`, from `nu_k` degrees of freedom) have the expectation
//!
//! `E[S_k] = sum_c theta_c D_c,k`,
//!
//! linear in the components `theta` (joint variances `sigma_j^2`, or every entry of
//! `Sigma_q`, and `sigma_me^2`):
//!
//! - a repeatability study ([`sample_covariance`]): `S_k` the sample covariance of the
//!   repeated measurements at pose `k`, `D_c,k = J_k E_c J_k^T` and `I` ([`noise_design`]);
//! - feasible GLS: `S_k = r_k r_k^T` of a calibration's residuals, `nu_k = 1`, and
//!   `D_c,k = (M V_c M^T)_kk` with `M = I - H (H^T W H)^+ H^T W` ([`residual_design`]), the
//!   residuals being `r = M e`.
//!
//! [`fit_components`] solves it by the normal-theory generalised least squares of covariance
//! structures (Browne 1974):
//!
//! `min_theta sum_k nu_k / 2 |L_k^-1 (S_k - sum_c theta_c D_c,k) L_k^-T|_F^2`, `Sigma_k = L_k L_k^T`,
//!
//! with `Sigma_k = sum_c theta_c D_c,k` at the previous estimate (iterated; the first pass
//! unweighted), variances kept non-negative by an active-set non-negative least squares
//! ([`nnls`]). Since `Cov(S_ij, S_kl) = (Sigma_ik Sigma_jl + Sigma_il Sigma_jk) / nu` for a
//! Wishart `S`, these weights are the inverse covariance of the observations and the
//! covariance of `theta` is the inverse Fisher information `F^-1`, `F = A^T A` with `A` the
//! weighted design. Intervals are `theta +- z se`, clipped at zero for variances.

use super::{EstimationError, Reduced};
use nalgebra::allocator::Allocator;
use nalgebra::{Const, DMatrix, DMatrixView, DVector, DefaultAllocator, Dim, Dyn, OMatrix};
use rayon::prelude::*;
use std::ops::Range;

/// One observed covariance: `S_k`, its degrees of freedom and the design of its expectation.
#[derive(Debug, Clone, PartialEq)]
pub struct CovarianceSample {
    /// The observed `S_k` (`b x b`, symmetric).
    pub s: DMatrix<f64>,
    /// Degrees of freedom `nu_k` (repeats minus one; 1 for one residual).
    pub dof: f64,
    /// `D_c,k` for each component `c` (`b x b`): `E[S_k] = sum_c theta_c D_c,k`.
    pub design: Vec<DMatrix<f64>>,
}

/// One observed covariance as [`fit_components`] reads it: `S_k` and the designs `D_c,k`,
/// each `b x b` column-major, the designs one after the other.
#[derive(Debug, Clone, Copy)]
pub(crate) struct SampleView<'a> {
    /// Rows of the block, `b`.
    pub b: usize,
    /// Degrees of freedom `nu_k`.
    pub dof: f64,
    /// `S_k`.
    pub s: &'a [f64],
    /// `D_c,k` of every component, in order.
    pub design: &'a [f64],
}

impl<'a> SampleView<'a> {
    /// Each `D_c,k`, in order.
    fn designs(&self) -> std::slice::ChunksExact<'a, f64> {
        self.design.chunks_exact((self.b * self.b).max(1))
    }
}

/// What [`fit_components`] fits: observed covariances `S_k` with the designs of their
/// expectation `E[S_k] = sum_c theta_c D_c,k`, read one at a time ([`SampleView`]) so that
/// they can be held packed ([`ResidualSamples`]).
pub(crate) trait Samples: Sync {
    /// The number of samples.
    fn count(&self) -> usize;
    /// The number of components `m`.
    fn components(&self) -> usize;
    /// Entries of every `S_k`, `sum_k b_k^2`.
    fn entries(&self) -> usize;
    /// Sample `k`, unpacked into `scratch` where it is not held whole.
    fn view<'s>(&'s self, k: usize, scratch: &'s mut Vec<f64>) -> SampleView<'s>;
    /// Refused, said why, unless every sample has `m` designs of its size and finite values,
    /// its degrees of freedom positive.
    fn check(&self, m: usize) -> Result<(), String>;
}

impl Samples for [CovarianceSample] {
    fn count(&self) -> usize {
        self.len()
    }

    fn components(&self) -> usize {
        self.first().map_or(0, |s| s.design.len())
    }

    fn entries(&self) -> usize {
        self.iter().map(|s| s.s.len()).sum()
    }

    fn view<'s>(&'s self, k: usize, scratch: &'s mut Vec<f64>) -> SampleView<'s> {
        let sample = &self[k];
        scratch.clear();
        for d in &sample.design {
            scratch.extend_from_slice(d.as_slice());
        }
        SampleView { b: sample.s.nrows(), dof: sample.dof, s: sample.s.as_slice(), design: scratch }
    }

    fn check(&self, m: usize) -> Result<(), String> {
        for (k, sample) in self.iter().enumerate() {
            let b = sample.s.nrows();
            if sample.design.len() != m
                || sample.design.iter().any(|d| d.shape() != (b, b))
                || sample.s.ncols() != b
            {
                return Err(format!(
                    "covariance {k}: the design does not match its {b} x {b} matrix and {m} components"
                ));
            }
            if sample.dof.is_nan()
                || sample.dof <= 0.0
                || sample.s.iter().chain(sample.design.iter().flatten()).any(|v| !v.is_finite())
            {
                return Err(format!("covariance {k}: expected finite values and degrees of freedom > 0"));
            }
        }
        Ok(())
    }
}

impl Samples for Vec<CovarianceSample> {
    fn count(&self) -> usize {
        self.as_slice().count()
    }

    fn components(&self) -> usize {
        self.as_slice().components()
    }

    fn entries(&self) -> usize {
        self.as_slice().entries()
    }

    fn view<'s>(&'s self, k: usize, scratch: &'s mut Vec<f64>) -> SampleView<'s> {
        self.as_slice().view(k, scratch)
    }

    fn check(&self, m: usize) -> Result<(), String> {
        self.as_slice().check(m)
    }
}

/// The samples of feasible GLS held packed ([`residual_samples`]): each point's residual
/// `r_k` (`S_k = r_k r_k^T`, `nu_k = 1`) and the upper triangle of each of its designs
/// `D_c,k` (symmetric), column by column: `m b_k (b_k + 1) / 2 + b_k` numbers a point
/// instead of `(m + 1) b_k^2` in matrices of their own.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct ResidualSamples {
    /// The points' rows.
    blocks: super::Blocks,
    /// `r` (`N_m`).
    r: Vec<f64>,
    /// Where each point's packed designs start, and their end.
    starts: Vec<usize>,
    /// The packed designs.
    packed: Vec<f64>,
    /// `m`.
    components: usize,
}

/// Entries of the upper triangle of a `b x b` matrix.
fn triangle(b: usize) -> usize {
    b * (b + 1) / 2
}

impl ResidualSamples {
    /// `D_c,k` of every component of point `k`, unpacked.
    #[cfg(test)]
    fn designs_of(&self, k: usize) -> Vec<DMatrix<f64>> {
        let mut scratch = Vec::new();
        let view = self.view(k, &mut scratch);
        view.designs().map(|d| DMatrix::from_column_slice(view.b, view.b, d)).collect()
    }
}

impl Samples for ResidualSamples {
    fn count(&self) -> usize {
        self.starts.len() - 1
    }

    fn components(&self) -> usize {
        self.components
    }

    fn entries(&self) -> usize {
        self.blocks.ranges(self.r.len()).map(|r| r.len() * r.len()).sum()
    }

    fn view<'s>(&'s self, k: usize, scratch: &'s mut Vec<f64>) -> SampleView<'s> {
        let rows = self.blocks.range(k);
        let b = rows.len();
        let size = b * b;
        // Every entry is written below: no clearing.
        scratch.resize((self.components + 1) * size, 0.0);
        let (design, s) = scratch.split_at_mut(self.components * size);
        let packed = &self.packed[self.starts[k]..self.starts[k + 1]];
        for (full, packed) in design.chunks_exact_mut(size).zip(packed.chunks_exact(triangle(b))) {
            for col in 0..b {
                let column = &packed[triangle(col)..triangle(col) + col + 1];
                full[col * b..col * b + col + 1].copy_from_slice(column);
                for (row, &v) in column.iter().enumerate().take(col) {
                    full[row * b + col] = v;
                }
            }
        }
        let r = &self.r[rows];
        for (col, s) in s.chunks_exact_mut(b).enumerate() {
            for (s, r_row) in s.iter_mut().zip(r) {
                *s = r_row * r[col];
            }
        }
        SampleView { b, dof: 1.0, s, design }
    }

    fn check(&self, _m: usize) -> Result<(), String> {
        match self.r.iter().chain(&self.packed).all(|v| v.is_finite()) {
            true => Ok(()),
            false => Err("the residuals or their expected covariances are not finite".into()),
        }
    }
}

/// The fitted components.
#[derive(Debug, Clone, PartialEq)]
pub struct ComponentFit {
    /// `theta`.
    pub values: DVector<f64>,
    /// `Cov(theta) = F^-1` at the estimate.
    pub covariance: DMatrix<f64>,
    /// Which components are variances (kept `>= 0`).
    pub constrained: Vec<bool>,
    /// Which constrained components ended at their bound, 0.
    pub at_bound: Vec<bool>,
    /// Reweighting passes made.
    pub iterations: usize,
}

/// The two-sided 95% point of the standard normal.
pub(crate) const Z_95: f64 = 1.959_963_984_540_054;

impl ComponentFit {
    /// Standard error of component `c`, `sqrt((F^-1)_cc)`.
    pub fn standard_error(&self, c: usize) -> f64 {
        self.covariance[(c, c)].max(0.0).sqrt()
    }

    /// The two-sided interval of component `c` at the normal quantile `z` (1.96 for
    /// 95%). A free component (a covariance): `theta_c +- z se_c`. A variance: the union of
    /// the normal interval clipped at zero, `[max(0, theta_c - z se_c), theta_c + z se_c]`,
    /// and Satterthwaite's scaled chi-square, `theta_c` taken as `theta chi2_nu / nu` with
    /// `nu = 2 theta_c^2 / se_c^2` effective degrees of freedom,
    /// `[nu theta_c / chi2_nu(1 - a/2), nu theta_c / chi2_nu(a/2)]` (Wilson-Hilferty's
    /// quantiles). The second is skewed as a variance's sampling distribution is, which the
    /// normal interval misses for well-determined components; the first alone where the
    /// component is barely determined (`nu < 2`, where the chi-square approximation fails).
    /// At the bound 0: `[0, z se_c]`.
    pub fn interval(&self, c: usize, z: f64) -> (f64, f64) {
        let (v, se) = (self.values[c], self.standard_error(c));
        if !self.constrained[c] {
            return (v - z * se, v + z * se);
        }
        if v <= 0.0 || se <= 0.0 {
            return (0.0, v.max(0.0) + z * se);
        }
        let nu = 2.0 * v * v / (se * se);
        let normal = ((v - z * se).max(0.0), v + z * se);
        if nu < 2.0 {
            return normal;
        }
        let quantile = |z: f64| {
            let a = 2.0 / (9.0 * nu);
            nu * (1.0 - a + z * a.sqrt()).max(0.0).powi(3)
        };
        let (upper_q, lower_q) = (quantile(z), quantile(-z));
        let high = if lower_q > 0.0 { nu * v / lower_q } else { f64::INFINITY };
        let low = if upper_q > 0.0 { nu * v / upper_q } else { 0.0 };
        (low.min(normal.0), high.max(normal.1))
    }
}

/// The sample mean and covariance `S = sum (x_i - mean)(x_i - mean)^T / (n - 1)` of `n >= 2`
/// vectors, with its degrees of freedom `n - 1`.
pub fn sample_covariance(samples: &[DVector<f64>]) -> Option<(DVector<f64>, DMatrix<f64>, f64)> {
    let n = samples.len();
    if n < 2 {
        return None;
    }
    let mean = samples.iter().fold(DVector::zeros(samples[0].len()), |a, x| a + x) / n as f64;
    let mut s = DMatrix::zeros(mean.len(), mean.len());
    for x in samples {
        let d = x - &mean;
        s += &d * d.transpose();
    }
    Some((mean, s / (n - 1) as f64, (n - 1) as f64))
}

/// Which components of `Sigma_q` to estimate.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum JointComponents {
    /// `sigma_j^2` of each joint: `Sigma_q = diag(sigma_1^2, ..., sigma_n^2)` (the paper's Eq. 14).
    Diagonal,
    /// Every entry of the upper triangle, row by row: a full `Sigma_q`.
    Full,
}

impl JointComponents {
    /// The `(i, j)` entry of `Sigma_q` of each joint component, in order.
    pub fn entries(self, dof: usize) -> Vec<(usize, usize)> {
        match self {
            Self::Diagonal => (0..dof).map(|i| (i, i)).collect(),
            Self::Full => (0..dof).flat_map(|i| (i..dof).map(move |j| (i, j))).collect(),
        }
    }
}

/// The design `D_c` of one point whose measured rows have manipulator Jacobian `jacobian`
/// (`b x dof`, rows of each marker's position, or of a pose with `per = 6`): for joint
/// component `(i, j)`, `J E_ij J^T` with `E_ij = e_i e_j^T + e_j e_i^T` (`e_i e_i^T` on the
/// diagonal); then `sigma_me^2`: the identity on every position row; then, for poses
/// (`per = 6`), `sigma_orientation^2`: the identity on the orientation rows.
pub(crate) fn noise_design(
    jacobian: &DMatrix<f64>,
    joints: JointComponents,
    per: usize,
) -> Vec<DMatrix<f64>> {
    let b = jacobian.nrows();
    let classes: Vec<usize> = (0..b).map(|r| point_row_class(per, r)).collect();
    block_noise_design(jacobian, jacobian.ncols(), joints, (&classes, if per == 6 { 2 } else { 1 }))
}

/// The measurement class of row `r` of a point of `per` rows a measured item (3: positions, 0;
/// 6: a pose's position 0 and orientation 1).
fn point_row_class(per: usize, r: usize) -> usize {
    usize::from(per == 6 && r % 6 >= 3)
}

/// The design `D_c` of one block whose rows see the joint noise of `P` poses through
/// `jacobian` (`b x P dof`: `J^p`, the rows' derivatives by pose `p`'s joints, side by side,
/// zero where a row does not see that pose) and whose rows are of the measurement classes
/// `classes` (`(class of each row, number of classes)`): for joint component `(i, j)`,
/// `sum_p J^p E_ij (J^p)^T` (the joint noise of different poses independent); then for each
/// class `m`, the identity on the rows of that class.
pub(crate) fn block_noise_design(
    jacobian: &DMatrix<f64>,
    dof: usize,
    joints: JointComponents,
    (classes, class_count): (&[usize], usize),
) -> Vec<DMatrix<f64>> {
    let b = jacobian.nrows();
    let poses = jacobian.ncols().checked_div(dof).unwrap_or(0);
    let mut design: Vec<DMatrix<f64>> = joints
        .entries(dof)
        .into_iter()
        .map(|(i, j)| {
            (0..poses).fold(DMatrix::zeros(b, b), |sum, p| {
                let (ci, cj) = (jacobian.column(p * dof + i), jacobian.column(p * dof + j));
                sum + if i == j { ci * ci.transpose() } else { ci * cj.transpose() + cj * ci.transpose() }
            })
        })
        .collect();
    for class in 0..class_count {
        design.push(DMatrix::from_fn(b, b, |r, c| f64::from(u8::from(r == c && classes[r] == class))));
    }
    design
}

/// How the noise enters the rows of a system for [`residual_design`]: each point's joint-noise
/// Jacobian `J_k` (`b_k x P_k dof`, the derivatives of its rows by the joints of each of the
/// `P_k` poses they see, side by side: [`block_noise_design`]'s), and the measurement class of
/// every row of the system.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct NoiseLayout {
    /// `J_k` of every point.
    pub jacobians: Vec<DMatrix<f64>>,
    /// Joints of each pose.
    pub dof: usize,
    /// The class of every row (`N_m`), each below `class_count`.
    pub classes: Vec<usize>,
    /// The number of measurement classes, one variance component each.
    pub class_count: usize,
}

impl NoiseLayout {
    /// Whether it fits a system of `rows` rows laid out by `blocks`: one `J_k` per point, of
    /// its rows and a whole number of poses, and a class below `class_count` per row.
    fn fits(&self, blocks: &super::Blocks, rows: usize) -> bool {
        let points = blocks.points(rows);
        self.jacobians.len() == points
            && self.dof > 0
            && (0..points).all(|k| {
                let j = &self.jacobians[k];
                j.nrows() == blocks.range(k).len() && j.ncols() % self.dof == 0
            })
            && self.classes.len() == rows
            && self.classes.iter().all(|&c| c < self.class_count)
    }
}

/// A system's rows point by point: what [`residual_samples`] reads of `H` and `y`, written
/// where it is needed, so that `H` (`N_m x p`) is never held for all points at once.
pub(crate) trait PointRows: Sync {
    /// The scratch space of one task.
    type Scratch;
    /// `(N_m, p)`: the rows and columns of `H`.
    fn shape(&self) -> (usize, usize);
    /// A task's scratch space.
    fn scratch(&self) -> Self::Scratch;
    /// Point `k`'s rows `range`: `H_k` into `h` (column-major, `b_k x p`), `y_k` into `y`.
    fn point(&self, scratch: &mut Self::Scratch, k: usize, range: Range<usize>, h: &mut [f64], y: &mut [f64]);
}

/// A system held whole, `H` (`N_m x p`) and `y`, read point by point: the tests' reference
/// for the streamed rows.
#[cfg(test)]
pub(crate) struct HeldRows<'a> {
    /// `H`.
    pub h: &'a DMatrix<f64>,
    /// `y`, `N_m` long.
    pub y: &'a DVector<f64>,
}

#[cfg(test)]
impl PointRows for HeldRows<'_> {
    type Scratch = ();

    fn shape(&self) -> (usize, usize) {
        self.h.shape()
    }

    fn scratch(&self) {}

    fn point(&self, _: &mut (), _: usize, range: Range<usize>, h: &mut [f64], y: &mut [f64]) {
        let (n, b) = (self.h.nrows(), range.len());
        for (j, column) in h.chunks_exact_mut(b).enumerate() {
            column.copy_from_slice(&self.h.as_slice()[j * n + range.start..j * n + range.end]);
        }
        y.copy_from_slice(&self.y.as_slice()[range]);
    }
}

/// The samples of feasible GLS, streamed: each point's residual `r_k` (of `y`, laid out by
/// `weights`' blocks) with the designs `D_c,k = (M V_c M^T)_kk` of [`residual_design`], packed
/// ([`ResidualSamples`]). The same arithmetic point by point, without holding what
/// [`residual_design`] holds for all points at once: `H` itself (`rows` writes each point's
/// `H_k` and `y_k` where they are needed: in `R`, in `N_c`, in the designs), `R` of `S H`
/// reduced row block by row block (no whitened copy of `H`), `A_k = C (S_k H_k)^T S_k` of
/// each point computed where it is used (no `p x N_m` matrix `A`), `N_c = sum_j A_j V_c,j
/// A_j^T` accumulated task by task ([`streamed_middles`]). Points are shared between threads
/// in tasks of [`POINTS_PER_TASK`], the tasks' sums added in order: the result does not
/// depend on the number of threads.
pub(crate) fn residual_samples(
    rows: &impl PointRows,
    weights: &super::Weights,
    layout: &NoiseLayout,
    joints: JointComponents,
) -> Result<ResidualSamples, EstimationError> {
    let blocks = weights.blocks();
    let n = rows.shape().0;
    let points = blocks.points(n);
    if !layout.fits(blocks, n) {
        return Err(EstimationError::Dimensions(format!(
            "{} Jacobians and {} row classes for the {points} points and {n} rows of the residual design",
            layout.jacobians.len(),
            layout.classes.len(),
        )));
    }
    let c = spread(rows, weights)?;
    let shared = Shared { rows, weights, c: &c, layout, joints };
    let middles = streamed_middles(&shared);
    let m = middles.len();
    let mut starts = vec![0];
    for k in 0..points {
        starts.push(starts[k] + m * triangle(blocks.range(k).len()));
    }
    let mut packed = vec![0.0; starts[points]];
    let mut r = vec![0.0; n];
    let tasks: Vec<Range<usize>> =
        (0..points).step_by(POINTS_PER_TASK).map(|s| s..(s + POINTS_PER_TASK).min(points)).collect();
    let mut slices = Vec::with_capacity(tasks.len());
    let (mut rest, mut rest_r) = (packed.as_mut_slice(), r.as_mut_slice());
    for task in &tasks {
        let (mine, others) = rest.split_at_mut(starts[task.end] - starts[task.start]);
        let task_rows = blocks.range(task.end - 1).end - blocks.range(task.start).start;
        let (mine_r, others_r) = rest_r.split_at_mut(task_rows);
        slices.push((mine, mine_r));
        (rest, rest_r) = (others, others_r);
    }
    tasks.into_par_iter().zip(slices).for_each(|(task, (out, r))| {
        let first = starts[task.start];
        shared.task_designs(&middles, task, &starts, (first, out), r);
    });
    Ok(ResidualSamples { blocks: blocks.clone(), r, starts, packed, components: m })
}

/// What every task of [`residual_samples`] reads: the rows, the weights, `C = (H^T W H)^+`,
/// the noise layout and the joint components.
struct Shared<'a, P> {
    rows: &'a P,
    weights: &'a super::Weights,
    c: &'a DMatrix<f64>,
    layout: &'a NoiseLayout,
    joints: JointComponents,
}

impl<P: PointRows> Shared<'_, P> {
    /// The rows of the points `task`, `H` of them (`rows x p`) returned, `y` written to `y`.
    fn task_rows(&self, scratch: &mut P::Scratch, task: Range<usize>, y: &mut [f64]) -> DMatrix<f64> {
        let blocks = self.weights.blocks();
        let first = blocks.range(task.start).start;
        let (rows, p) = (blocks.range(task.end - 1).end - first, self.c.nrows());
        let mut h = DMatrix::zeros(rows, p);
        let mut h_k = vec![0.0; blocks.width() * p];
        for k in task {
            let range = blocks.range(k);
            let (b, at) = (range.len(), range.start - first);
            self.rows.point(scratch, k, range, &mut h_k[..b * p], &mut y[at..at + b]);
            h.rows_mut(at, b).copy_from(&DMatrixView::from_slice(&h_k[..b * p], b, p));
        }
        h
    }

    /// The packed designs ([`PointTerms::designs`]) of the points `task` into `out` (which
    /// starts at `first` of the packed designs, points starting at `starts`), their
    /// residuals into `r`: `H^T` and `N_c H^T` of the task's rows at once (`p x rows`).
    fn task_designs(
        &self,
        middles: &[DMatrix<f64>],
        task: Range<usize>,
        starts: &[usize],
        (first, out): (usize, &mut [f64]),
        r: &mut [f64],
    ) {
        let blocks = self.weights.blocks();
        let start = blocks.range(task.start).start;
        let mut scratch = self.rows.scratch();
        let h = self.task_rows(&mut scratch, task.clone(), r);
        let ht = h.transpose();
        let nht: Vec<DMatrix<f64>> = middles.iter().map(|n| n * &ht).collect();
        let (mut influence, mut products) = (Influence::default(), DesignScratch::default());
        for k in task {
            let range = blocks.range(k);
            let (b, at) = (range.len(), range.start - start..range.end - start);
            let a_k = influence.of(self.weights, self.c, k, h.rows(at.start, b));
            let terms = PointTerms {
                ht: ht.columns(at.start, b),
                a: a_k.columns(0, b),
                jacobian: &self.layout.jacobians[k],
                dof: self.layout.dof,
                classes: &self.layout.classes[range],
            };
            let out = &mut out[starts[k] - first..starts[k + 1] - first];
            let nht = nht.iter().map(|n| n.columns(at.start, b));
            terms.designs(nht, self.joints, &mut products, |c, design| {
                let packed = &mut out[c * triangle(b)..(c + 1) * triangle(b)];
                for col in 0..b {
                    for row in 0..=col {
                        packed[triangle(col) + row] = design.entry(row, col);
                    }
                }
            });
        }
    }
}

/// `C = (H^T W H)^+ = pinv(R) pinv(R)^T`, `R` the triangular factor of `S H` reduced point by
/// point (each point's rows written by `rows`, whitened in place).
fn spread(rows: &impl PointRows, weights: &super::Weights) -> Result<DMatrix<f64>, EstimationError> {
    let blocks = weights.blocks();
    let (n, p) = rows.shape();
    let width = blocks.width();
    let reduced = Reduced::reduce_rows(
        blocks,
        n,
        p,
        None,
        None,
        || (rows.scratch(), vec![0.0; width]),
        |(scratch, y), k, out| {
            let range = blocks.range(k);
            let b = range.len();
            rows.point(scratch, k, range, &mut out[..p * b], &mut y[..b]);
            weights.apply_point(k, &mut out[..p * b]);
        },
    );
    let r_pinv = super::pseudo_inverse(&reduced.r().into_owned())?;
    Ok(&r_pinv * r_pinv.transpose())
}

/// The products of `A_k = C (S_k H_k)^T S_k` ([`Influence::of`]), kept from point to point:
/// `S_k H_k` (`b x p`), its transpose, `S_k` (`b x b`, as `S_k I`), `C (S_k H_k)^T` and `A_k`.
#[derive(Default)]
struct Influence {
    sh: DMatrix<f64>,
    sht: DMatrix<f64>,
    s: DMatrix<f64>,
    cs: DMatrix<f64>,
    a: DMatrix<f64>,
}

impl Influence {
    /// `A_k = C (S_k H_k)^T S_k` (`p x b_k`), point `k`'s columns of `A = (H^T W H)^+ H^T W`,
    /// from its rows `h_k` (`b_k x p`): `(C (S_k H_k)^T) S_k`, in products kept for the next
    /// point.
    fn of<S>(
        &mut self,
        weights: &super::Weights,
        c: &DMatrix<f64>,
        k: usize,
        h_k: nalgebra::Matrix<f64, Dyn, Dyn, S>,
    ) -> &DMatrix<f64>
    where
        S: nalgebra::RawStorage<f64, Dyn, Dyn>,
    {
        let (b, p) = h_k.shape();
        if self.s.nrows() != b || self.sh.ncols() != p {
            *self = Self {
                sh: DMatrix::zeros(b, p),
                sht: DMatrix::zeros(p, b),
                s: DMatrix::zeros(b, b),
                cs: DMatrix::zeros(p, b),
                a: DMatrix::zeros(p, b),
            };
        }
        self.sh.copy_from(&h_k);
        weights.apply_point(k, self.sh.as_mut_slice());
        self.s.fill_with_identity();
        weights.apply_point(k, self.s.as_mut_slice());
        self.sh.transpose_to(&mut self.sht);
        self.cs.gemm(1.0, c, &self.sht, 0.0);
        self.a.gemm(1.0, &self.cs, &self.s, 0.0);
        &self.a
    }
}

/// `N_c = sum_j A_j V_c,j A_j^T` of every component ([`design_middles`]'s), accumulated in
/// tasks of [`POINTS_PER_TASK`] points ([`Shared::task_middles`]), the tasks' sums added in
/// order.
fn streamed_middles<P: PointRows>(shared: &Shared<'_, P>) -> Vec<DMatrix<f64>> {
    let p = shared.c.nrows();
    let points = shared.weights.blocks().points(shared.rows.shape().0);
    let m = shared.joints.entries(shared.layout.dof).len() + shared.layout.class_count;
    let parts: Vec<Vec<DMatrix<f64>>> = (0..points.div_ceil(POINTS_PER_TASK))
        .into_par_iter()
        .map(|task| shared.task_middles(task * POINTS_PER_TASK..((task + 1) * POINTS_PER_TASK).min(points)))
        .collect();
    let mut middles = vec![DMatrix::zeros(p, p); m];
    for part in parts {
        for (sum, n) in middles.iter_mut().zip(part) {
            *sum += n;
        }
    }
    middles
}

impl<P: PointRows> Shared<'_, P> {
    /// The part of every `N_c` of the points `task`: `U_i` (`p x R`, a column per point `j`
    /// and pose `q` it sees, the column `i` of `Z_jq = A_j J_j^q`) gives `U_i U_i^T` for
    /// `sigma_i^2` and `U_i U_j^T + U_j U_i^T` for a covariance; a class, the Gram matrix of
    /// the task's columns of `A` on its rows.
    fn task_middles(&self, task: Range<usize>) -> Vec<DMatrix<f64>> {
        let (layout, blocks) = (self.layout, self.weights.blocks());
        let (p, dof) = (self.c.nrows(), layout.dof);
        let first = blocks.range(task.start).start;
        let rows = first..blocks.range(task.end - 1).end;
        // Products of the task at once: its `Z_jq` in `U_i`, its columns of `A` by class.
        let (a, u) = self.task_influences(task);
        let mut sums: Vec<DMatrix<f64>> = (self.joints.entries(dof).iter())
            .map(|&(i, j)| {
                let n = &u[i] * u[j].transpose();
                if i == j { n } else { &n + n.transpose() }
            })
            .collect();
        for class in 0..layout.class_count {
            let columns: Vec<usize> = rows.clone().filter(|&row| layout.classes[row] == class).collect();
            let selected = DMatrix::from_fn(p, columns.len(), |r, n| a[(r, columns[n] - first)]);
            sums.push(&selected * selected.transpose());
        }
        sums
    }

    /// The columns `A_j` of the points `task` side by side (`p x` their rows), and `U_i`
    /// (`p x R`) of every joint `i`: the column `i` of each `Z_jq = A_j J_j^q`, a column per
    /// point `j` and pose `q` it sees, in order. Each point's rows are written by the rows'
    /// source and its products kept for the next ([`Influence`]).
    fn task_influences(&self, task: Range<usize>) -> (DMatrix<f64>, Vec<DMatrix<f64>>) {
        let (layout, blocks) = (self.layout, self.weights.blocks());
        let (p, dof) = (self.c.nrows(), layout.dof);
        let first = blocks.range(task.start).start;
        let rows = blocks.range(task.end - 1).end - first;
        let replicas = task.clone().map(|k| layout.jacobians[k].ncols() / dof).sum();
        let (mut a, mut u) = (DMatrix::zeros(p, rows), vec![DMatrix::zeros(p, replicas); dof]);
        let mut scratch = self.rows.scratch();
        let width = blocks.width();
        let (mut h_k, mut y_k) = (vec![0.0; width * p], vec![0.0; width]);
        let (mut influence, mut z) = (Influence::default(), DMatrix::zeros(0, 0));
        let mut replica = 0;
        for k in task {
            let range = blocks.range(k);
            let (b, at) = (range.len(), range.start - first);
            self.rows.point(&mut scratch, k, range, &mut h_k[..b * p], &mut y_k[..b]);
            let a_k = influence.of(self.weights, self.c, k, DMatrixView::from_slice(&h_k[..b * p], b, p));
            a.columns_mut(at, b).copy_from(a_k);
            let j = &layout.jacobians[k];
            if z.shape() != (p, j.ncols()) {
                z = DMatrix::zeros(p, j.ncols());
            }
            z.gemm(1.0, a_k, j, 0.0);
            for q in 0..j.ncols() / dof {
                for (i, u) in u.iter_mut().enumerate() {
                    u.column_mut(replica).copy_from(&z.column(q * dof + i));
                }
                replica += 1;
            }
        }
        (a, u)
    }
}

#[cfg(test)]
/// The design of feasible GLS: the expectation of each point's residual outer product
/// `r_k r_k^T` per unit of each component, `D_c,k = (M V_c M^T)_kk`, for residuals `r = M e`
/// of the weighted fit `x = (H^T W H)^+ H^T W y`, `M = I - H A`, `A = (H^T W H)^+ H^T W`.
/// With `W = S^T S` (`weights`, block diagonal), `C = (H^T W H)^+ = pinv(R) pinv(R)^T` from
/// the triangular factor `R` of `S H` (`R^T R = H^T W H`), `A_k = C (S_k H_k)^T S_k` the
/// columns of `A` of point `k`, and `V_c` block diagonal,
///
/// `(M V_c M^T)_kk = V_c,k - P_k V_c,k - V_c,k P_k^T + H_k N_c H_k^T`, `P_k = H_k A_k`,
/// `N_c = sum_j A_j V_c,j A_j^T`,
///
/// point by point: no `N_m x N_m` matrix, no pseudoinverse of the tall `S H`, time and memory
/// linear in the points. The components are [`block_noise_design`]'s of `layout`'s Jacobians
/// `J_k` (`b_k x P_k dof`, one `J_k^p` per pose the point's rows see) and classes: a joint
/// component is `V_c,k = sum_p J_k^p E_c (J_k^p)^T`, so `N_c = sum_jp Z_jp E_c Z_jp^T` with
/// `Z_jp = A_j J_j^p` (`p x dof`), `U_i^T U_i` for `sigma_i^2` and `U_i^T U_j + U_j^T U_i` for
/// a covariance, `U_i` the columns `i` of every `Z_jp` stacked as rows; a measurement
/// component is the identity on the rows of its class, and `N_c` the Gram matrix of those
/// columns of `A`. `h` is the unwhitened `H` (`N_m x p`, laid out by `weights`' blocks).
/// Points are shared between threads in tasks of a fixed size; every sum runs in the points'
/// order, so the result does not depend on the number of threads.
pub(crate) fn residual_design(
    h: &DMatrix<f64>,
    weights: &super::Weights,
    layout: &NoiseLayout,
    joints: JointComponents,
) -> Result<Vec<Vec<DMatrix<f64>>>, EstimationError> {
    let blocks = weights.blocks();
    let points = blocks.points(h.nrows());
    if !layout.fits(blocks, h.nrows()) {
        return Err(EstimationError::Dimensions(format!(
            "{} Jacobians and {} row classes for the {points} points and {} rows of the residual design",
            layout.jacobians.len(),
            layout.classes.len(),
            h.nrows()
        )));
    }
    let a = influence(h, weights)?;
    let middles = design_middles(&a, blocks, layout, joints);
    let tasks: Vec<Vec<Vec<DMatrix<f64>>>> = (0..points)
        .collect::<Vec<_>>()
        .par_chunks(POINTS_PER_TASK)
        .map(|task| {
            let rows = blocks.range(task[0]).start..blocks.range(task[task.len() - 1]).end;
            // H^T and N_c H^T of the task's rows (`p x rows`): their columns are contiguous.
            let ht = h.rows(rows.start, rows.len()).transpose();
            let nht: Vec<DMatrix<f64>> = middles.iter().map(|n| n * &ht).collect();
            let point = |k: usize| {
                let range = blocks.range(k);
                let at = range.start - rows.start..range.end - rows.start;
                let terms = PointTerms {
                    ht: ht.columns(at.start, at.len()),
                    a: a.columns(range.start, range.len()),
                    jacobian: &layout.jacobians[k],
                    dof: layout.dof,
                    classes: &layout.classes[range],
                };
                let nht = nht.iter().map(|n| n.columns(at.start, at.len()));
                let mut designs = Vec::new();
                terms.designs(nht, joints, &mut DesignScratch::default(), |_, design| {
                    designs.push(DMatrix::from_fn(at.len(), at.len(), |r, s| design.entry(r, s)));
                });
                designs
            };
            task.iter().map(|&k| point(k)).collect()
        })
        .collect();
    Ok(tasks.into_iter().flatten().collect())
}

#[cfg(test)]
/// `A = (H^T W H)^+ H^T W` (`p x N_m`) of [`residual_design`], point by point:
/// `A_k = C (S_k H_k)^T S_k`, `C = pinv(R) pinv(R)^T` from the triangular factor `R` of `S H`.
fn influence(h: &DMatrix<f64>, weights: &super::Weights) -> Result<DMatrix<f64>, EstimationError> {
    let blocks = weights.blocks();
    let points = blocks.points(h.nrows());
    let mut sh = h.clone();
    weights.apply(&mut sh);
    let reduced = Reduced::of_whitened(&sh, &DVector::zeros(h.nrows()), blocks, None);
    let r = reduced.r().into_owned();
    let r_pinv = super::pseudo_inverse(&r)?;
    let c = &r_pinv * r_pinv.transpose();
    drop(sh);
    let mut a = DMatrix::zeros(c.nrows(), h.nrows());
    let chunks: Vec<(usize, DMatrix<f64>)> = (0..points)
        .into_par_iter()
        .map(|k| {
            let range = blocks.range(k);
            let mut sh_k = h.rows(range.start, range.len()).into_owned();
            weights.apply_point(k, sh_k.as_mut_slice());
            let mut s_k = DMatrix::identity(range.len(), range.len());
            weights.apply_point(k, s_k.as_mut_slice());
            (range.start, &c * sh_k.transpose() * s_k)
        })
        .collect();
    for (start, a_k) in chunks {
        a.columns_mut(start, a_k.ncols()).copy_from(&a_k);
    }
    Ok(a)
}

/// What [`residual_design`] needs of point `k` for its designs: `H_k^T` (`p x b`), `A_k`
/// (`p x b`), `J_k` (`b x P dof`) and its rows' measurement classes.
struct PointTerms<'a> {
    ht: nalgebra::DMatrixView<'a, f64>,
    a: nalgebra::DMatrixView<'a, f64>,
    jacobian: &'a DMatrix<f64>,
    dof: usize,
    classes: &'a [usize],
}

/// The products of [`PointTerms::designs`], kept from point to point: `H_k` (`b x p`),
/// `P_k = H_k A_k`, `P_k J_k`, and of the component at hand `H_k N_c H_k^T`, `V_c,k` and
/// `P_k V_c,k` (`b x b`).
#[derive(Default)]
struct DesignScratch {
    h: DMatrix<f64>,
    p: DMatrix<f64>,
    pj: DMatrix<f64>,
    hnh: DMatrix<f64>,
    v: DMatrix<f64>,
    pv: DMatrix<f64>,
}

impl DesignScratch {
    /// The products' shapes for `b` rows, `p` parameters and a `J_k` of `jacobian` columns.
    fn fit(&mut self, b: usize, p: usize, jacobian: usize) {
        if self.h.shape() != (b, p) || self.pj.shape() != (b, jacobian) {
            *self = Self {
                h: DMatrix::zeros(b, p),
                p: DMatrix::zeros(b, b),
                pj: DMatrix::zeros(b, jacobian),
                hnh: DMatrix::zeros(b, b),
                v: DMatrix::zeros(b, b),
                pv: DMatrix::zeros(b, b),
            };
        }
    }

    /// The entry `(r, s)` of `D_c,k = V_c,k - P_k V_c,k - (P_k V_c,k)^T + (H_k N_c H_k^T + its
    /// transpose) / 2` of the component at hand.
    fn entry(&self, r: usize, s: usize) -> f64 {
        self.v[(r, s)] - self.pv[(r, s)] - self.pv[(s, r)] + (self.hnh[(r, s)] + self.hnh[(s, r)]) / 2.0
    }
}

impl PointTerms<'_> {
    /// `D_c,k = V_c,k - P_k V_c,k - (P_k V_c,k)^T + (H_k N_c H_k^T + its transpose) / 2` of
    /// every component `c`, in order, each handed to `design(c, scratch)` to read by
    /// [`DesignScratch::entry`]; `nht` the `N_c H_k^T`, with `P_k = H_k A_k`: for a joint
    /// component `(i, l)`, `V_c,k = sum_p (J^p_i (J^p_l)^T + J^p_l (J^p_i)^T)` (`J^p_i (J^p_i)^T`
    /// on the diagonal) and `P V = sum_p ((P J^p)_i (J^p_l)^T + (P J^p)_l (J^p_i)^T)`, by
    /// rank-one updates; for a measurement component, `V` the identity on the rows of its
    /// class and `P V` the columns of `P` on them.
    fn designs<'n>(
        &self,
        nht: impl Iterator<Item = nalgebra::DMatrixView<'n, f64>>,
        joints: JointComponents,
        scratch: &mut DesignScratch,
        mut design: impl FnMut(usize, &DesignScratch),
    ) {
        let j = self.jacobian;
        let b = j.nrows();
        scratch.fit(b, self.ht.nrows(), j.ncols());
        self.ht.transpose_to(&mut scratch.h);
        scratch.p.gemm(1.0, &scratch.h, &self.a, 0.0);
        scratch.pj.gemm(1.0, &scratch.p, j, 0.0);
        let (dof, poses) = (self.dof, j.ncols() / self.dof);
        let components = joints.entries(dof);
        for (c, nht) in nht.enumerate() {
            let DesignScratch { h, p, pj, hnh, v, pv } = &mut *scratch;
            hnh.gemm(1.0, &*h, &nht, 0.0);
            v.fill(0.0);
            pv.fill(0.0);
            match components.get(c) {
                Some(&(i, l)) => {
                    for q in 0..poses {
                        let (ji, jl) = (j.column(q * dof + i), j.column(q * dof + l));
                        v.ger(1.0, &ji, &jl, 1.0);
                        pv.ger(1.0, &pj.column(q * dof + i), &jl, 1.0);
                        if i != l {
                            v.ger(1.0, &jl, &ji, 1.0);
                            pv.ger(1.0, &pj.column(q * dof + l), &ji, 1.0);
                        }
                    }
                }
                None => {
                    let class = c - components.len();
                    for row in (0..b).filter(|&row| self.classes[row] == class) {
                        v[(row, row)] = 1.0;
                        pv.column_mut(row).copy_from(&p.column(row));
                    }
                }
            }
            design(c, scratch);
        }
    }
}

/// Points per parallel task of [`residual_design`]'s last step: the tasks, and so every
/// product, are the same on any number of threads.
const POINTS_PER_TASK: usize = 64;

#[cfg(test)]
/// `N_c = sum_j A_j V_c,j A_j^T` of every component of [`residual_design`], from `A`
/// (`p x N_m`, point `j`'s columns `A_j`): for joint components through `U_i` (`R x p`, a row
/// per point `j` and pose `q` it sees, the column `i` of `Z_jq = A_j J_j^q`), `N_ii = U_i^T U_i`,
/// `N_ij = U_i^T U_j + U_j^T U_i`; for a measurement class, the Gram matrix of the columns of
/// `A` of its rows.
fn design_middles(
    a: &DMatrix<f64>,
    blocks: &super::Blocks,
    layout: &NoiseLayout,
    joints: JointComponents,
) -> Vec<DMatrix<f64>> {
    let (p, dof) = (a.nrows(), layout.dof);
    let z: Vec<DMatrix<f64>> = (0..layout.jacobians.len())
        .into_par_iter()
        .map(|k| {
            let range = blocks.range(k);
            a.columns(range.start, range.len()) * &layout.jacobians[k]
        })
        .collect();
    let replicas: Vec<(usize, usize)> =
        z.iter().enumerate().flat_map(|(k, z)| (0..z.ncols() / dof).map(move |q| (k, q * dof))).collect();
    let u: Vec<DMatrix<f64>> = (0..dof)
        .map(|i| DMatrix::from_fn(replicas.len(), p, |n, r| z[replicas[n].0][(r, replicas[n].1 + i)]))
        .collect();
    drop(z);
    let mut middles: Vec<DMatrix<f64>> = joints
        .entries(dof)
        .par_iter()
        .map(|&(i, j)| {
            let n = u[i].tr_mul(&u[j]);
            if i == j { n } else { &n + n.transpose() }
        })
        .collect();
    for class in 0..layout.class_count {
        let rows: Vec<usize> = (0..a.ncols()).filter(|&row| layout.classes[row] == class).collect();
        let selected = a.select_columns(&rows);
        middles.push(&selected * selected.transpose());
    }
    middles
}

/// Fit the components `theta` to `samples`, `E[S_k] = sum_c theta_c D_c,k`; `constrained[c]`
/// says whether component `c` is a variance, kept `>= 0`. Normal-theory generalised least
/// squares of covariance structures (Browne 1974):
///
/// `min_theta sum_k nu_k / 2 |L_k^-1 (S_k - sum_c theta_c D_c,k) L_k^-T|_F^2`,
///
/// `L_k L_k^T = Sigma_k = sum_c theta_c D_c,k` at the previous estimate (the first pass
/// unweighted, then iterated to convergence), each pass a non-negative least squares
/// ([`nnls`]). For a Wishart `S_k`, `Cov(S_ij, S_kl) = (Sigma_ik Sigma_jl + Sigma_il Sigma_jk) / nu`,
/// so these weights are the inverse covariance of the observations, and `Cov(theta) = F^-1`
/// with `F = A^T A`, `A` the weighted design (the Fisher information).
pub(crate) fn fit_components(
    samples: &(impl Samples + ?Sized),
    constrained: &[bool],
    start: Option<&DVector<f64>>,
) -> Result<ComponentFit, EstimationError> {
    let m = constrained.len();
    let bad = |s: String| Err(EstimationError::Noise(s));
    if samples.count() == 0 {
        return bad("no covariances to fit the variance components to".into());
    }
    samples.check(m).map_err(EstimationError::Noise)?;
    let rows = samples.entries();
    if rows < m {
        return bad(format!("{rows} covariance entries cannot determine {m} components"));
    }
    // From `start` (a previous fit's estimate) if given, else from the unweighted fit.
    let mut theta = match start {
        Some(start) if start.len() == m && start.iter().all(|t| t.is_finite()) => start.clone(),
        _ => nnls_gram(&weighted_gram(samples, None), constrained),
    };
    let mut gram = DMatrix::zeros(m + 1, m + 1);
    let mut iterations = 0;
    for _ in 0..50 {
        iterations += 1;
        gram = weighted_gram(samples, Some(&theta));
        let next = nnls_gram(&gram, constrained);
        // Converged when the change no longer moves any fitted covariance noticeably.
        let (moved, size) = largest_fitted(samples, &(&next - &theta), &next);
        let size = size.max(f64::MIN_POSITIVE);
        theta = next;
        if moved <= COMPONENT_TOLERANCE * size {
            break;
        }
    }
    // The information at the estimate: the Gram matrix of the weights it was found with.
    let information = gram.view((0, 0), (m, m)).into_owned();
    let scale = DVector::from_fn(m, |c, _| information[(c, c)].sqrt());
    // A variance whose design is zero everywhere (a joint no observation moves) stays at 0,
    // unbounded: its variance is infinite, and it is left out of the inverse.
    let seen: Vec<usize> = (0..m).filter(|&c| !(constrained[c] && scale[c] == 0.0)).collect();
    if seen.iter().any(|&c| scale[c].is_nan() || scale[c] <= 0.0 || !scale[c].is_finite()) {
        return bad("a variance component has no influence on the data: it cannot be estimated".into());
    }
    let scaled = DMatrix::from_fn(seen.len(), seen.len(), |i, j| {
        information[(seen[i], seen[j])] / (scale[seen[i]] * scale[seen[j]])
    });
    let inverse = scaled
        .cholesky()
        .ok_or(EstimationError::Noise(
            "the variance components cannot be told apart by these poses (singular information)".into(),
        ))?
        .inverse();
    let mut covariance = DMatrix::from_fn(m, m, |i, j| if i == j { f64::INFINITY } else { 0.0 });
    for (a, &i) in seen.iter().enumerate() {
        for (b, &j) in seen.iter().enumerate() {
            covariance[(i, j)] = inverse[(a, b)] / (scale[i] * scale[j]);
        }
    }
    let at_bound = (0..m).map(|c| constrained[c] && theta[c] == 0.0).collect();
    Ok(ComponentFit { values: theta, covariance, constrained: constrained.to_vec(), at_bound, iterations })
}

/// The largest fitted entries `|f_k sum_c theta_c D_c,k|` of the unweighted system, of the
/// components `change` and of `theta`, in one pass over the samples (a maximum: the same on
/// any number of threads).
fn largest_fitted(
    samples: &(impl Samples + ?Sized),
    change: &DVector<f64>,
    theta: &DVector<f64>,
) -> (f64, f64) {
    let largest = |(u, v, scratch): &mut (Vec<f64>, Vec<f64>, Vec<f64>), k: usize| {
        let sample = samples.view(k, scratch);
        let f = (sample.dof / 2.0).sqrt();
        for w in [&mut *u, &mut *v] {
            w.clear();
            w.resize(sample.s.len(), 0.0);
        }
        for ((d, c), t) in sample.designs().zip(change.iter()).zip(theta.iter()) {
            for ((u, v), d) in u.iter_mut().zip(v.iter_mut()).zip(d) {
                *u += d * c;
                *v += d * t;
            }
        }
        let most = |w: &[f64]| w.iter().fold(0.0_f64, |a, w| a.max((w * f).abs()));
        (most(u), most(v))
    };
    (0..samples.count())
        .into_par_iter()
        .map_init(|| (Vec::new(), Vec::new(), Vec::new()), largest)
        .reduce(|| (0.0, 0.0), |a, b| (a.0.max(b.0), a.1.max(b.1)))
}

/// The reweighting of [`fit_components`] stops when a pass moves no fitted covariance entry by
/// more than this fraction of the largest: a thousand times below any component's standard
/// error on data of a few thousand entries, and each pass costs one sweep over the samples.
const COMPONENT_TOLERANCE: f64 = 1e-7;

/// Samples per parallel task of [`weighted_gram`]: the tasks, and so the order of every sum,
/// are the same on any number of threads.
const SAMPLES_PER_TASK: usize = 64;

/// The Gram matrix `[A y]^T [A y]` (`(m + 1) x (m + 1)`) of the weighted system of
/// [`fit_components`]: a row per entry of every `S_k`, `A`'s columns the entries of
/// `f_k L_k^-1 D_c,k L_k^-T` and `y` those of `f_k L_k^-1 S_k L_k^-T`, `f_k = sqrt(nu_k / 2)`,
/// `L_k L_k^T = Sigma_k = sum_c theta_c D_c,k` (the identity without `theta`). Its entries
/// are Frobenius products, `<L^-1 X L^-T, L^-1 Y L^-T> = tr(P X P Y)` with `P = Sigma_k^-1`
/// ([`add_sample`]): one product `P X` per matrix of a sample, never the rows themselves.
fn weighted_gram(samples: &(impl Samples + ?Sized), theta: Option<&DVector<f64>>) -> DMatrix<f64> {
    let (n, m) = (samples.count(), samples.components());
    let parts: Vec<DMatrix<f64>> = (0..n.div_ceil(SAMPLES_PER_TASK))
        .into_par_iter()
        .map(|task| {
            let mut gram = DMatrix::zeros(m + 1, m + 1);
            let (mut unpacked, mut scratch) = (Vec::new(), Vec::new());
            for k in task * SAMPLES_PER_TASK..((task + 1) * SAMPLES_PER_TASK).min(n) {
                add_sample(samples.view(k, &mut unpacked), theta, &mut gram, &mut scratch);
            }
            gram
        })
        .collect();
    parts.into_iter().fold(DMatrix::zeros(m + 1, m + 1), |sum, part| sum + part)
}

/// One sample's part of [`weighted_gram`]: `f^2 tr(P X P Y)` for every pair of its designs
/// and its `S`. Blocks of 3, 6, 9 and 12 rows (one to four markers, a pose) are worked on the
/// stack, the products kept in `scratch`, reused from sample to sample: no allocation.
fn add_sample(
    sample: SampleView<'_>,
    theta: Option<&DVector<f64>>,
    gram: &mut DMatrix<f64>,
    scratch: &mut Vec<f64>,
) {
    match sample.b {
        3 => add_sized(Const::<3>, sample, theta, gram, scratch),
        6 => add_sized(Const::<6>, sample, theta, gram, scratch),
        9 => add_sized(Const::<9>, sample, theta, gram, scratch),
        12 => add_sized(Const::<12>, sample, theta, gram, scratch),
        b => add_sized(Dyn(b), sample, theta, gram, scratch),
    }
}

/// [`add_sample`] for blocks of `d` rows: the products `P X` and their transposes in
/// `scratch` (`tr(A C) = sum_rs A_rs (C^T)_rs`), `P` from [`precision`].
fn add_sized<D: Dim>(
    d: D,
    sample: SampleView<'_>,
    theta: Option<&DVector<f64>>,
    gram: &mut DMatrix<f64>,
    scratch: &mut Vec<f64>,
) where
    DefaultAllocator: Allocator<D, D> + Allocator<D>,
{
    let b = d.value();
    let size = b * b;
    let count = sample.design.len() / size + 1;
    scratch.resize(2 * count * size, 0.0);
    let (products, transposes) = scratch.split_at_mut(count * size);
    let matrices = || sample.designs().chain([sample.s]);
    let precision = theta.map(|t| precision(d, sample, t));
    for ((x, product), transpose) in
        matrices().zip(products.chunks_exact_mut(size)).zip(transposes.chunks_exact_mut(size))
    {
        let x = OMatrix::<f64, D, D>::from_column_slice_generic(d, d, x);
        let px = match &precision {
            Some(p) => p * x,
            None => x,
        };
        product.copy_from_slice(px.as_slice());
        transpose.copy_from_slice(px.transpose().as_slice());
    }
    let f2 = sample.dof / 2.0;
    for (i, a) in products.chunks_exact(size).enumerate() {
        for (j, c) in transposes.chunks_exact(size).enumerate().take(i + 1) {
            let trace = dot(a, c);
            gram[(i, j)] += f2 * trace;
            if i != j {
                gram[(j, i)] += f2 * trace;
            }
        }
    }
}

/// `sum_i a_i c_i`, in four running sums (so that it vectorises), the rest after.
fn dot(a: &[f64], c: &[f64]) -> f64 {
    let mut sums = [0.0; 4];
    let (a4, c4) = (a.chunks_exact(4), c.chunks_exact(4));
    let rest: f64 = a4.remainder().iter().zip(c4.remainder()).map(|(a, c)| a * c).sum();
    for (a, c) in a4.zip(c4) {
        for (sum, (a, c)) in sums.iter_mut().zip(a.iter().zip(c)) {
            *sum += a * c;
        }
    }
    (sums[0] + sums[1]) + (sums[2] + sums[3]) + rest
}

/// [`nnls`] of the least squares whose Gram matrix `[A y]^T [A y]` is `gram`: the same
/// problem as `min |y - A theta|` (`|y - A theta|^2 = theta^T A^T A theta - 2 theta^T A^T y +
/// y^T y`), posed through a square root of `A^T A` scaled to a unit diagonal, `A^T A =
/// D^-1 V L V^T D^-1` (`D` the scaling, `V L V^T` its symmetric eigendecomposition): `A' =
/// L^(1/2) V^T D^-1`, `y' = L^(-1/2) V^T D^-1 A^T y` (directions of a zero eigenvalue left out).
fn nnls_gram(gram: &DMatrix<f64>, constrained: &[bool]) -> DVector<f64> {
    let m = constrained.len();
    let d: Vec<f64> =
        (0..m).map(|c| if gram[(c, c)] > 0.0 { 1.0 / gram[(c, c)].sqrt() } else { 0.0 }).collect();
    let scaled = DMatrix::from_fn(m, m, |i, j| gram[(i, j)] * d[i] * d[j]);
    let eigen = scaled.symmetric_eigen();
    let largest = eigen.eigenvalues.amax();
    let mut a = DMatrix::zeros(m, m);
    let mut y = DVector::zeros(m);
    for (k, &lambda) in eigen.eigenvalues.iter().enumerate() {
        if lambda <= 1e-15 * largest {
            continue;
        }
        let v = eigen.eigenvectors.column(k);
        let root = lambda.sqrt();
        y[k] = (0..m).map(|c| v[c] * d[c] * gram[(c, m)]).sum::<f64>() / root;
        for c in 0..m {
            a[(k, c)] = if d[c] > 0.0 { root * v[c] / d[c] } else { 0.0 };
        }
    }
    nnls(&a, &y, constrained)
}

/// What a measurement variance component is the variance of: a marker's position
/// coordinates, a probe's orientation, or one kind of observation of an observation file.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum MeasurementClass {
    /// A marker's coordinates in a marker calibration (mm): `sigma_me`.
    Position,
    /// A probe's orientation (rad): `sigma_orientation`.
    Orientation,
    /// A distance, between two poses or to a fixed point (mm): a ball bar, a length artefact.
    Distance,
    /// A plane contact (mm): a touch probe.
    Contact,
    /// A coordinate x, y or z of the tool point (mm).
    Coordinate,
    /// A roll, pitch or yaw of the tool frame (rad): an inclinometer.
    Angle,
    /// A marker's coordinate in an observation file (mm): a tracker.
    Marker,
    /// The position of a camera's view of its target (mm).
    CameraPosition,
    /// The rotation of a camera's view of its target (rad).
    CameraRotation,
}

impl MeasurementClass {
    /// The component's name in a report: `sigma_me`, `sigma_distance`, `sigma_camera_rotation`.
    pub fn name(self) -> &'static str {
        match self {
            Self::Position => "sigma_me",
            Self::Orientation => "sigma_orientation",
            Self::Distance => "sigma_distance",
            Self::Contact => "sigma_contact",
            Self::Coordinate => "sigma_coordinate",
            Self::Angle => "sigma_angle",
            Self::Marker => "sigma_marker",
            Self::CameraPosition => "sigma_camera_position",
            Self::CameraRotation => "sigma_camera_rotation",
        }
    }

    /// Whether its sigma is an angle (rad), else a length (mm).
    pub fn is_angle(self) -> bool {
        matches!(self, Self::Orientation | Self::Angle | Self::CameraRotation)
    }

    /// The classes of a marker calibration's rows, `per` rows a measured item: positions
    /// (`sigma_me`), and for a probe's poses (`per = 6`) orientations.
    pub fn of_points(per: usize) -> Vec<Self> {
        if per == 6 { vec![Self::Position, Self::Orientation] } else { vec![Self::Position] }
    }
}

/// Estimated noise: `Sigma_q` (its diagonal, or every entry) and one measurement variance per
/// class (`sigma_me^2`, and `sigma_orientation^2` for poses; of observation files, one per kind
/// of observation), with their covariance; the components in the order: the estimated entries
/// of `Sigma_q` (its diagonal, or its upper triangle row by row), then the measurement
/// classes' variances in the order of [`NoiseEstimate::measurement`].
#[derive(Debug, Clone, PartialEq)]
pub struct NoiseEstimate {
    /// The fitted components.
    pub fit: ComponentFit,
    /// Which entries of `Sigma_q` were estimated.
    pub joints: JointComponents,
    /// Number of joints.
    pub dof: usize,
    /// The measurement classes, one variance component each after the joints'.
    pub measurement: Vec<MeasurementClass>,
}

/// A standard deviation with its 95% interval (the square roots of the variance's).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct SigmaInterval {
    /// The estimate.
    pub sigma: f64,
    /// Lower end of the 95% interval.
    pub low: f64,
    /// Upper end of the 95% interval.
    pub high: f64,
}

impl SigmaInterval {
    /// Whether `sigma` lies in the interval.
    pub fn contains(&self, sigma: f64) -> bool {
        self.low <= sigma && sigma <= self.high
    }
}

impl NoiseEstimate {
    /// Fit the components to `samples` whose designs come from `noise_design` (or
    /// `residual_design` of it) with `joints`, `dof` joints and the `measurement` classes;
    /// the reweighting starts from `start`'s components if given (a previous round of feasible
    /// GLS), else from the unweighted fit.
    pub(crate) fn fit(
        samples: &(impl Samples + ?Sized),
        joints: JointComponents,
        dof: usize,
        measurement: Vec<MeasurementClass>,
        start: Option<&Self>,
    ) -> Result<Self, EstimationError> {
        let mut constrained: Vec<bool> = joints.entries(dof).iter().map(|(i, j)| i == j).collect();
        constrained.extend(measurement.iter().map(|_| true));
        let fit = fit_components(samples, &constrained, start.map(|s| &s.fit.values))?;
        Ok(Self { fit, joints, dof, measurement })
    }

    /// The name of component `c`: `joint i` (its variance, joints from 1), `joint i, joint k`
    /// (a covariance), a measurement class's `sigma_*` ([`MeasurementClass::name`]).
    pub fn component_name(&self, c: usize) -> String {
        let entries = self.joints.entries(self.dof);
        match entries.get(c) {
            Some(&(i, j)) if i == j => format!("joint {}", i + 1),
            Some(&(i, j)) => format!("joint {}, joint {}", i + 1, j + 1),
            None => self.measurement[c - entries.len()].name().to_string(),
        }
    }

    /// Index of component `sigma_j^2` of joint `j`.
    fn joint_index(&self, j: usize) -> usize {
        self.joints.entries(self.dof).iter().position(|&(a, b)| a == j && b == j).expect("every joint")
    }

    fn sigma(&self, c: usize) -> SigmaInterval {
        let (low, high) = self.fit.interval(c, Z_95);
        SigmaInterval { sigma: self.fit.values[c].max(0.0).sqrt(), low: low.sqrt(), high: high.sqrt() }
    }

    /// `sigma_j` of joint `j` (rad, mm) with its 95% interval.
    pub fn joint_sigma(&self, j: usize) -> SigmaInterval {
        self.sigma(self.joint_index(j))
    }

    /// The index of `class`'s component, if estimated.
    fn class_index(&self, class: MeasurementClass) -> Option<usize> {
        let first = self.joints.entries(self.dof).len();
        self.measurement.iter().position(|&c| c == class).map(|m| first + m)
    }

    /// The sigma of the measurement class `class` (mm or rad) with its 95% interval, if
    /// estimated.
    pub fn measurement_sigma(&self, class: MeasurementClass) -> Option<SigmaInterval> {
        self.class_index(class).map(|c| self.sigma(c))
    }

    /// Every measurement class's sigma (mm or rad) with its 95% interval, in order.
    pub fn measurement_sigmas(&self) -> Vec<(MeasurementClass, SigmaInterval)> {
        let first = self.joints.entries(self.dof).len();
        self.measurement.iter().enumerate().map(|(m, &class)| (class, self.sigma(first + m))).collect()
    }

    /// `sigma_me` (mm) with its 95% interval: the marker positions' (of observation files, the
    /// first measurement class's).
    pub fn sigma_me(&self) -> SigmaInterval {
        let first = self.joints.entries(self.dof).len();
        self.sigma(self.class_index(MeasurementClass::Position).unwrap_or(first))
    }

    /// `sigma_orientation` (rad) with its 95% interval, when orientations were measured.
    pub fn sigma_orientation(&self) -> Option<SigmaInterval> {
        self.measurement_sigma(MeasurementClass::Orientation)
    }

    /// `Sigma_q` from the components, made positive semi-definite (negative eigenvalues of a
    /// full estimate set to zero).
    pub fn joint_covariance(&self) -> DMatrix<f64> {
        let mut m = DMatrix::zeros(self.dof, self.dof);
        for (c, (i, j)) in self.joints.entries(self.dof).into_iter().enumerate() {
            m[(i, j)] = self.fit.values[c];
            m[(j, i)] = self.fit.values[c];
        }
        if self.joints == JointComponents::Full {
            let eigen = m.clone().symmetric_eigen();
            let clipped = eigen.eigenvalues.map(|v| v.max(0.0));
            m = &eigen.eigenvectors * DMatrix::from_diagonal(&clipped) * eigen.eigenvectors.transpose();
            m = (&m + m.transpose()) / 2.0;
        }
        m
    }

    /// The sigma to weight the rows of `class` with: its estimate, or, where its variance ended
    /// at the bound 0, the square root of the variance's standard error (0 for a class not
    /// estimated). Zero measurement noise would claim that the markers are exact in every
    /// direction the joint noise cannot move them (with two markers on the last link, the turn
    /// about the line through them), and `V_k` would be singular; one standard error above
    /// zero is what the data cannot rule out.
    pub fn weighting_sigma(&self, class: MeasurementClass) -> f64 {
        self.class_index(class).map_or(0.0, |c| {
            let v = self.fit.values[c];
            if v > 0.0 { v.sqrt() } else { self.fit.standard_error(c).sqrt() }
        })
    }

    /// The measurement sigmas of a marker calibration to weight with: `sigma_me` and
    /// `sigma_orientation` ([`NoiseEstimate::weighting_sigma`]).
    pub fn weighting_sigmas(&self) -> (f64, f64) {
        (
            self.weighting_sigma(MeasurementClass::Position),
            self.weighting_sigma(MeasurementClass::Orientation),
        )
    }

    /// The estimate as a noise file: `Sigma_q`, and `sigma_me` isotropic (as
    /// [`NoiseEstimate::weighting_sigmas`]).
    pub fn spec(&self) -> super::NoiseSpec {
        let (me, orientation) = self.weighting_sigmas();
        super::NoiseSpec {
            joint: self.joint_covariance(),
            full: self.joints == JointComponents::Full,
            sigma_me: Some(me),
            sigma_orientation: orientation,
            device: None,
            prior: Vec::new(),
        }
    }

    /// The estimate as a noise model for weighting: `Sigma_q`, and `sigma_me` (and
    /// `sigma_orientation`) on every axis, as [`NoiseEstimate::weighting_sigmas`].
    pub fn noise_model(&self) -> super::NoiseModel {
        let (me, orientation) = self.weighting_sigmas();
        super::NoiseModel {
            joint: self.joint_covariance(),
            measurement: super::MeasurementNoise::isotropic(me, orientation),
        }
    }
}

/// `P = Sigma^-1` of `Sigma = sum_c theta_c D_c` (`d x d`), with the smallest ridge of
/// `1e-10, 1e-6, 1e-3, 1` times the mean variance (the larger of `Sigma`'s and `S`'s) added to
/// its diagonal that leaves it positive definite, so that a component at zero cannot make it
/// singular (`I` over the mean variance if none does), by its Cholesky factorisation.
fn precision<D: Dim>(d: D, sample: SampleView<'_>, theta: &DVector<f64>) -> OMatrix<f64, D, D>
where
    DefaultAllocator: Allocator<D, D> + Allocator<D>,
{
    let b = d.value();
    let mut sigma = OMatrix::<f64, D, D>::zeros_generic(d, d);
    for (x, t) in sample.designs().zip(theta.iter()) {
        for (s, x) in sigma.as_mut_slice().iter_mut().zip(x) {
            *s += x * t;
        }
    }
    let s_trace: f64 = (0..b).map(|i| sample.s[i * b + i]).sum();
    let trace = (sigma.trace() / b as f64).max(s_trace / b as f64).max(f64::MIN_POSITIVE);
    for ridge in [1e-10, 1e-6, 1e-3, 1.0] {
        let mut regular = sigma.clone();
        for i in 0..b {
            regular[(i, i)] += ridge * trace;
        }
        if let Some(c) = regular.cholesky() {
            return c.inverse();
        }
    }
    OMatrix::<f64, D, D>::identity_generic(d, d) / trace
}

/// Non-negative least squares with free variables: `min |b - A x|` subject to `x_c >= 0` where
/// `constrained[c]`, by the active-set method of Lawson and Hanson (1974, ch. 23), the free
/// variables always in the passive set. Columns are scaled to unit norm first, which leaves
/// the constraints unchanged. A tall `A` (more rows than columns) is reduced first to the
/// small system `R x = Q^T b` of its QR factorisation (`|b - A x|^2 = |Q^T b - R x|^2` plus a
/// constant; `R` has `A`'s singular values), so that the active set's solves and gradients
/// cost nothing per row.
pub(crate) fn nnls(a: &DMatrix<f64>, b: &DVector<f64>, constrained: &[bool]) -> DVector<f64> {
    let n = a.ncols();
    let norms: Vec<f64> = a.column_iter().map(|c| c.norm()).collect();
    let scale: Vec<f64> = norms.iter().map(|&s| if s > 0.0 { 1.0 / s } else { 0.0 }).collect();
    let a = DMatrix::from_fn(a.nrows(), n, |i, j| a[(i, j)] * scale[j]);
    let tolerance = 1e-12 * (n as f64) * b.norm().max(f64::MIN_POSITIVE);
    let (a, b) = if a.nrows() > n {
        let qr = a.qr();
        let mut qtb = b.clone();
        qr.q_tr_mul(&mut qtb);
        (qr.r(), qtb.rows(0, n).into_owned())
    } else {
        (a, b.clone())
    };
    let b = &b;
    let solve_on = |passive: &[bool]| -> DVector<f64> {
        let columns: Vec<usize> = (0..n).filter(|&j| passive[j]).collect();
        let mut z = DVector::zeros(n);
        if columns.is_empty() {
            return z;
        }
        let sub = a.select_columns(&columns);
        let svd = sub.svd(true, true);
        let eps = 1e-12 * svd.singular_values.max();
        if let Ok(solution) = svd.solve(b, eps) {
            for (k, &j) in columns.iter().enumerate() {
                z[j] = solution[k];
            }
        }
        z
    };
    let mut passive: Vec<bool> = (0..n).map(|j| !constrained[j] && scale[j] > 0.0).collect();
    let mut x = solve_on(&passive);
    for _ in 0..3 * n + 3 {
        let w = a.transpose() * (b - &a * &x);
        let candidate = (0..n)
            .filter(|&j| constrained[j] && !passive[j] && scale[j] > 0.0 && w[j] > tolerance)
            .max_by(|&i, &j| w[i].total_cmp(&w[j]));
        let Some(j) = candidate else { break };
        passive[j] = true;
        loop {
            let z = solve_on(&passive);
            let infeasible: Vec<usize> =
                (0..n).filter(|&i| passive[i] && constrained[i] && z[i] <= 0.0).collect();
            if infeasible.is_empty() {
                x = z;
                break;
            }
            let alpha = infeasible
                .iter()
                .map(|&i| x[i] / (x[i] - z[i]))
                .filter(|a| a.is_finite())
                .fold(1.0, f64::min)
                .clamp(0.0, 1.0);
            x += (z - &x) * alpha;
            for i in 0..n {
                if passive[i] && constrained[i] && x[i] <= 1e-15 {
                    passive[i] = false;
                    x[i] = 0.0;
                }
            }
        }
    }
    DVector::from_fn(n, |j, _| if constrained[j] { x[j].max(0.0) * scale[j] } else { x[j] * scale[j] })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The layout of points of `per` rows a measured item (a marker's position, 3; a probe's
    /// pose, 6: [`noise_design`]'s classes), each seeing its pose through its manipulator
    /// Jacobian `jacobians[k]` (`b_k x dof`), laid out by `blocks`.
    fn layout_of_points(
        jacobians: Vec<DMatrix<f64>>,
        per: usize,
        blocks: &crate::estimation::Blocks,
    ) -> NoiseLayout {
        let dof = jacobians.first().map_or(0, DMatrix::ncols);
        let rows = (0..jacobians.len()).map(|k| blocks.range(k)).map(|r| r.len());
        let classes = rows.flat_map(|b| (0..b).map(|r| point_row_class(per, r))).collect();
        NoiseLayout { jacobians, dof, classes, class_count: if per == 6 { 2 } else { 1 } }
    }

    #[test]
    fn nnls_matches_the_bound_solution() {
        // min |b - A x|, x >= 0: the unconstrained solution has x2 < 0, so x2 = 0 and x1 = its
        // one-variable fit.
        let a = DMatrix::from_row_slice(3, 2, &[1.0, 0.0, 0.0, 1.0, 1.0, 1.0]);
        let b = DVector::from_vec(vec![2.0, -1.0, 1.0]);
        let x = nnls(&a, &b, &[true, true]);
        assert!((x[0] - 1.5).abs() < 1e-12 && x[1] == 0.0, "{x}");
        let free = nnls(&a, &b, &[true, false]);
        let unconstrained = a.clone().svd(true, true).solve(&b, 1e-14).unwrap();
        assert!((free - unconstrained).norm() < 1e-12);
    }

    #[test]
    fn an_exact_covariance_gives_its_components() {
        let j = DMatrix::from_row_slice(3, 2, &[1.0, 2.0, 0.5, -1.0, 0.0, 3.0]);
        let j2 = DMatrix::from_row_slice(3, 2, &[0.0, 1.0, 2.0, 0.0, 1.0, 1.0]);
        let theta = [0.3, 0.05, 0.01];
        let samples: Vec<CovarianceSample> = [j, j2]
            .iter()
            .map(|j| {
                let design = noise_design(j, JointComponents::Diagonal, 3);
                let s = design.iter().zip(theta).fold(DMatrix::zeros(3, 3), |s, (d, t)| s + d * t);
                CovarianceSample { s, dof: 10.0, design }
            })
            .collect();
        let fit = fit_components(&samples, &[true; 3], None).unwrap();
        for (c, t) in theta.iter().enumerate() {
            assert!((fit.values[c] - t).abs() < 1e-9, "{}", fit.values);
        }
    }

    /// `(M V_c M^T)_kk` point by point equals the diagonal blocks of the dense product, with
    /// `M = I - H pinv(S H) S`, on a small problem with correlated weights of every kind, for
    /// the components of two markers' positions with a full `Sigma_q` and of a pose's with
    /// joint variances; more points than one parallel task takes.
    #[test]
    fn the_residual_design_is_the_dense_residual_makers() {
        let (points, rows, p, dof) = (POINTS_PER_TASK + 3, 6, 4, 3);
        let n = points * rows;
        let (h, v, jacobians) = pose_blocks(points, p, dof);
        for (per, joints) in [(3, JointComponents::Full), (6, JointComponents::Diagonal)] {
            for estimator in [super::super::Estimator::Ols, super::super::Estimator::Wls] {
                let weights = super::super::Weights::new(Some(&v), rows, estimator, true).unwrap();
                let layout = layout_of_points(jacobians.clone(), per, weights.blocks());
                let designs = residual_design(&h, &weights, &layout, joints).unwrap();
                let mut s = DMatrix::identity(n, n);
                weights.apply(&mut s);
                let mut sh = h.clone();
                weights.apply(&mut sh);
                let m = DMatrix::identity(n, n) - &h * super::super::pseudo_inverse(&sh).unwrap() * &s;
                let blocks: Vec<Vec<DMatrix<f64>>> =
                    jacobians.iter().map(|j| noise_design(j, joints, per)).collect();
                assert_eq!(designs.len(), points);
                for (k, design) in designs.iter().enumerate() {
                    assert_eq!(design.len(), blocks[0].len());
                    for (c, got) in design.iter().enumerate() {
                        // (M V_c M^T)_kk = sum_j M_kj V_c,j M_kj^T, V_c block diagonal.
                        let want = (0..points).fold(DMatrix::zeros(rows, rows), |sum, j| {
                            let m_kj = m.view((k * rows, j * rows), (rows, rows));
                            sum + m_kj * &blocks[j][c] * m_kj.transpose()
                        });
                        assert!(
                            (got - &want).amax() < 1e-12 * want.amax().max(1.0),
                            "{per} {estimator:?} {c} {k}"
                        );
                    }
                }
            }
        }
    }

    /// `points` poses of six rows each: a fixed full-rank `H` (`6 points x p`), each pose's
    /// correlated covariance block `B B^T + I / 2` stacked (`6 points x 6`), and each pose's
    /// joint Jacobian (`6 x dof`).
    fn pose_blocks(points: usize, p: usize, dof: usize) -> (DMatrix<f64>, DMatrix<f64>, Vec<DMatrix<f64>>) {
        let (rows, n) = (6, 6 * points);
        let h = DMatrix::from_fn(n, p, |i, j| {
            ((i * 7 + j * 3) % 11) as f64 / 5.0 - 1.0 + f64::from(u8::from(i == j))
        });
        let mut v = DMatrix::zeros(n, rows);
        for k in 0..points {
            let b = DMatrix::from_fn(rows, rows, |i, j| (((k + 1) * (i + 2) * (j + 3)) % 7) as f64 / 7.0);
            v.rows_mut(k * rows, rows).copy_from(&(&b * b.transpose() + DMatrix::identity(rows, rows) * 0.5));
        }
        let jacobians = (0..points)
            .map(|k| DMatrix::from_fn(rows, dof, |i, j| (((k + 2) * (i + 1) + 5 * j) % 9) as f64 / 4.0 - 1.0))
            .collect();
        (h, v, jacobians)
    }

    /// What `run` gives on a pool of `threads` threads.
    fn on_threads<T: Send>(threads: usize, run: impl Fn() -> T + Send + Sync) -> T {
        rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap().install(run)
    }

    /// Ragged blocks of 1 to 6 rows over more points than a task's (their sizes, the blocks,
    /// their rows `n`), and a fixed full-rank `H` (`n x p`).
    fn ragged_blocks(p: usize) -> (Vec<usize>, super::super::Blocks, usize, DMatrix<f64>) {
        let sizes: Vec<usize> = (0..POINTS_PER_TASK + 5).map(|k| 1 + (k * 5) % 6).collect();
        let blocks = super::super::Blocks::from_sizes(sizes.clone());
        let n: usize = sizes.iter().sum();
        let h = DMatrix::from_fn(n, p, |i, j| {
            ((i * 7 + j * 3) % 11) as f64 / 5.0 - 1.0 + f64::from(u8::from(i == j))
        });
        (sizes, blocks, n, h)
    }

    /// The same for an observation file's layout: ragged blocks (1 to 6 rows), each row seeing
    /// one or two poses (a distance between two), rows of three measurement classes, the
    /// estimator's weights and correlated ones; and the exact components recovered from the
    /// dense expectation `E[r r^T] = M V M^T`.
    #[test]
    fn the_residual_design_of_ragged_blocks_is_the_dense_residual_makers() {
        let (p, dof) = (4, 2);
        let (sizes, blocks, n, h) = ragged_blocks(p);
        let jacobians: Vec<DMatrix<f64>> = (sizes.iter().enumerate())
            .map(|(k, &b)| {
                let poses = 1 + k % 2;
                DMatrix::from_fn(b, poses * dof, |i, j| {
                    // The second pose seen by the first row only (a distance to another pose).
                    if j >= dof && i > 0 { 0.0 } else { (((k + 2) * (i + 1) + 5 * j) % 9) as f64 / 4.0 - 1.0 }
                })
            })
            .collect();
        let classes: Vec<usize> = (0..n).map(|r| (r * 7 / 3) % 3).collect();
        let layout = NoiseLayout { jacobians, dof, classes, class_count: 3 };
        let theta = [0.3, 0.2, 0.05, 0.01, 0.02];
        let mut v = DMatrix::zeros(n, blocks.width());
        let dense_v = |c: Option<usize>| {
            let mut full = DMatrix::zeros(n, n);
            for (k, r) in blocks.ranges(n).enumerate() {
                let design = block_noise_design(
                    &layout.jacobians[k],
                    dof,
                    JointComponents::Diagonal,
                    (&layout.classes[r.clone()], 3),
                );
                let block = match c {
                    Some(c) => design[c].clone(),
                    None => {
                        design.iter().zip(theta).fold(DMatrix::zeros(r.len(), r.len()), |s, (d, t)| s + d * t)
                    }
                };
                full.view_mut((r.start, r.start), (r.len(), r.len())).copy_from(&block);
            }
            full
        };
        let true_v = dense_v(None);
        for r in blocks.ranges(n) {
            v.view_mut((r.start, 0), (r.len(), r.len()))
                .copy_from(&true_v.view((r.start, r.start), (r.len(), r.len())));
        }
        for estimator in [super::super::Estimator::Ols, super::super::Estimator::Wls] {
            let weights =
                super::super::Weights::of_blocks(Some(&v), blocks.clone(), estimator, true).unwrap();
            let designs = residual_design(&h, &weights, &layout, JointComponents::Diagonal).unwrap();
            let mut s = DMatrix::identity(n, n);
            weights.apply(&mut s);
            let mut sh = h.clone();
            weights.apply(&mut sh);
            let m = DMatrix::identity(n, n) - &h * super::super::pseudo_inverse(&sh).unwrap() * &s;
            let mut samples = Vec::new();
            for (k, r) in blocks.ranges(n).enumerate() {
                for (c, got) in designs[k].iter().enumerate() {
                    let want = (&m * dense_v(Some(c)) * m.transpose())
                        .view((r.start, r.start), (r.len(), r.len()))
                        .into_owned();
                    assert!((got - &want).amax() < 1e-12 * want.amax().max(1.0), "{estimator:?} {c} {k}");
                }
                let expected =
                    (&m * &true_v * m.transpose()).view((r.start, r.start), (r.len(), r.len())).into_owned();
                samples.push(CovarianceSample { s: expected, dof: 1.0, design: designs[k].clone() });
            }
            let fit = fit_components(&samples, &[true; 5], None).unwrap();
            for (c, t) in theta.iter().enumerate() {
                assert!((fit.values[c] - t).abs() < 1e-8, "{estimator:?}: {}", fit.values);
            }
        }
    }

    /// The designs and the fitted components are the same, to the bit, on one thread and on
    /// three (the parallel tasks are of fixed sizes, every sum in the points' order).
    #[test]
    fn the_residual_fit_does_not_depend_on_the_threads() {
        let (points, rows, p, dof) = (2 * POINTS_PER_TASK + 5, 6, 5, 3);
        let n = points * rows;
        let h = DMatrix::from_fn(n, p, |i, j| ((i * 13 + j * 7) % 17) as f64 / 8.0 - 1.0);
        let jacobians: Vec<DMatrix<f64>> = (0..points)
            .map(|k| {
                DMatrix::from_fn(rows, dof, |i, j| (((k + 3) * (i + 2) + 7 * j) % 11) as f64 / 5.0 - 1.0)
            })
            .collect();
        let weights = super::super::Weights::new(None, rows, super::super::Estimator::Ols, false).unwrap();
        let run = || {
            let layout = layout_of_points(jacobians.clone(), 3, weights.blocks());
            let designs = residual_design(&h, &weights, &layout, JointComponents::Diagonal).unwrap();
            let samples: Vec<CovarianceSample> = designs
                .into_iter()
                .enumerate()
                .map(|(k, design)| {
                    let r = DVector::from_fn(rows, |i, _| ((i + 3 * k) % 7) as f64 / 3.0 - 1.0);
                    CovarianceSample { s: &r * r.transpose(), dof: 1.0, design }
                })
                .collect();
            let fit = fit_components(&samples, &[true; 4], None).unwrap();
            (samples, fit)
        };
        let (one, three) = (on_threads(1, run), on_threads(3, run));
        assert!(one.0 == three.0 && one.1 == three.1, "{} {}", one.1.values, three.1.values);
        assert!(one.1.iterations > 1, "reweighted: {}", one.1.iterations);
    }

    /// The Gram matrix of blocks worked on the stack (12 rows) is that of the general path,
    /// the ridge included (a component at zero leaves `Sigma` singular).
    #[test]
    fn the_stack_gram_is_the_general_one() {
        let j = DMatrix::from_fn(12, 6, |i, c| ((i * 5 + c * 3) % 7) as f64 / 3.0 - 1.0);
        let samples: Vec<CovarianceSample> = (0..3)
            .map(|k| {
                let design = noise_design(&(&j * (1.0 + k as f64)), JointComponents::Diagonal, 3);
                let r = DVector::from_fn(12, |i, _| ((i + 2 * k) % 5) as f64 - 2.0);
                CovarianceSample { s: &r * r.transpose(), dof: 1.0, design }
            })
            .collect();
        for theta in [
            DVector::from_fn(7, |c, _| 0.1 + c as f64 * 0.05),
            DVector::from_fn(7, |c, _| f64::from(u8::from(c == 0))),
        ] {
            let (mut fixed, mut general) = (DMatrix::zeros(8, 8), DMatrix::zeros(8, 8));
            let (mut scratch, mut unpacked) = (Vec::new(), Vec::new());
            for k in 0..samples.len() {
                let sample = samples.view(k, &mut unpacked);
                add_sample(sample, Some(&theta), &mut fixed, &mut scratch);
                add_sized(Dyn(12), sample, Some(&theta), &mut general, &mut scratch);
            }
            assert!((&fixed - &general).amax() <= 1e-12 * general.amax(), "{fixed} {general}");
            assert!(general.amax() > 0.0 && general.iter().all(|g| g.is_finite()));
        }
    }

    /// The Gram matrix of the weighted rows, built sample by sample from `tr(P X P Y)`, gives
    /// the same components as the rows `f L^-1 X L^-T` themselves fitted by [`nnls`].
    #[test]
    fn the_gram_matrix_fit_is_the_row_fit() {
        let j = DMatrix::from_row_slice(3, 2, &[1.0, 2.0, 0.5, -1.0, 0.0, 3.0]);
        let samples: Vec<CovarianceSample> = (0..6)
            .map(|k| {
                let jk = &j * (1.0 + k as f64 * 0.3);
                let design = noise_design(&jk, JointComponents::Diagonal, 3);
                let r = DVector::from_fn(3, |i, _| ((i + 2 * k) % 5) as f64 - 2.0);
                CovarianceSample { s: &r * r.transpose(), dof: 1.0 + k as f64, design }
            })
            .collect();
        let theta = DVector::from_vec(vec![0.2, 0.05, 0.3]);
        let constrained = [true; 3];
        let mut rows = Vec::new();
        let mut unpacked = Vec::new();
        for (k, sample) in samples.iter().enumerate() {
            let view = samples.view(k, &mut unpacked);
            let l = precision(Dyn(3), view, &theta).cholesky().unwrap().l().transpose();
            let f = (sample.dof / 2.0).sqrt();
            let weigh = |x: &DMatrix<f64>| (&l * x * l.transpose() * f).as_slice().to_vec();
            let columns: Vec<Vec<f64>> = sample.design.iter().chain([&sample.s]).map(weigh).collect();
            for e in 0..9 {
                rows.extend(columns.iter().map(|c| c[e]));
            }
        }
        let system = DMatrix::from_row_slice(rows.len() / 4, 4, &rows);
        let want = nnls(&system.columns(0, 3).into_owned(), &system.column(3).into_owned(), &constrained);
        let gram = weighted_gram(&samples, Some(&theta));
        assert!((gram.clone() - system.transpose() * &system).amax() < 1e-10 * gram.amax());
        let got = nnls_gram(&gram, &constrained);
        assert!((&got - &want).amax() < 1e-9 * want.amax(), "{got} {want}");
    }

    /// The streamed, packed samples ([`residual_samples`]) hold the designs of the dense path
    /// ([`residual_design`]) to `1e-10` of the largest entry, and `S_k = r_k r_k^T`: on points
    /// of a pose's six rows with correlated weights (a full `Sigma_q` and joint variances, OLS
    /// and Gauss-Markov) and on ragged blocks of three classes seeing one or two poses; and
    /// the components fitted to them are the dense samples' to `1e-10`.
    #[test]
    fn the_streamed_samples_are_the_dense_designs() {
        let check = |h: &DMatrix<f64>, weights: &super::super::Weights, layout: &NoiseLayout, joints| {
            let n = h.nrows();
            let y = DVector::from_fn(n, |i, _| ((i * 5) % 13) as f64 / 6.0 - 1.0);
            let dense = residual_design(h, weights, layout, joints).unwrap();
            let streamed = residual_samples(&HeldRows { h, y: &y }, weights, layout, joints).unwrap();
            assert_eq!(streamed.count(), dense.len());
            let mut samples = Vec::new();
            let mut scratch = Vec::new();
            for (k, want) in dense.into_iter().enumerate() {
                let got = streamed.designs_of(k);
                assert_eq!(got.len(), want.len());
                for (c, (got, want)) in got.iter().zip(&want).enumerate() {
                    assert!((got - want).amax() <= 1e-10 * want.amax().max(1e-300), "{k} {c}: {got} {want}");
                }
                let r = y.rows(weights.blocks().range(k).start, got[0].nrows());
                let s = r * r.transpose();
                assert_eq!(streamed.view(k, &mut scratch).s, s.as_slice());
                samples.push(CovarianceSample { s, dof: 1.0, design: want });
            }
            let m = samples[0].design.len();
            let constrained = vec![true; m];
            let (want, got) = (
                fit_components(&samples, &constrained, None).unwrap(),
                fit_components(&streamed, &constrained, None).unwrap(),
            );
            for c in 0..m {
                let scale = want.values.amax();
                assert!(
                    (got.values[c] - want.values[c]).abs() <= 1e-10 * scale,
                    "{} {}",
                    got.values,
                    want.values
                );
                let se = want.standard_error(c);
                assert!((got.standard_error(c) - se).abs() <= 1e-10 * se.max(1e-300));
            }
        };
        // A pose's six rows a point, correlated weights.
        let (points, rows, p, dof) = (2 * POINTS_PER_TASK + 3, 6, 4, 3);
        let (h, v, jacobians) = pose_blocks(points, p, dof);
        for (per, joints) in [(3, JointComponents::Full), (6, JointComponents::Diagonal)] {
            for estimator in [super::super::Estimator::Ols, super::super::Estimator::Wls] {
                let weights = super::super::Weights::new(Some(&v), rows, estimator, true).unwrap();
                let layout = layout_of_points(jacobians.clone(), per, weights.blocks());
                check(&h, &weights, &layout, joints);
            }
        }
        // Ragged blocks of three classes, some rows seeing two poses.
        let dof = 2;
        let (sizes, blocks, n, h) = ragged_blocks(p);
        let jacobians: Vec<DMatrix<f64>> = (sizes.iter().enumerate())
            .map(|(k, &b)| {
                DMatrix::from_fn(b, (1 + k % 2) * dof, |i, j| {
                    if j >= dof && i > 0 { 0.0 } else { (((k + 2) * (i + 1) + 5 * j) % 9) as f64 / 4.0 - 1.0 }
                })
            })
            .collect();
        let classes: Vec<usize> = (0..n).map(|r| (r * 7 / 3) % 3).collect();
        let layout = NoiseLayout { jacobians, dof, classes, class_count: 3 };
        let mut v = DMatrix::zeros(n, blocks.width());
        for r in blocks.ranges(n) {
            let b = r.len();
            let m = DMatrix::from_fn(b, b, |i, j| ((r.start + i * 3 + j) % 5) as f64 / 5.0);
            v.view_mut((r.start, 0), (b, b)).copy_from(&(&m * m.transpose() + DMatrix::identity(b, b)));
        }
        for estimator in [super::super::Estimator::Ols, super::super::Estimator::Wls] {
            let weights =
                super::super::Weights::of_blocks(Some(&v), blocks.clone(), estimator, true).unwrap();
            check(&h, &weights, &layout, JointComponents::Diagonal);
        }
    }

    /// The streamed samples and the components fitted to them are the same, to the bit, on
    /// one thread and on two (tasks of fixed sizes, their sums added in order), with
    /// Gauss-Markov weights and more points than two tasks take.
    #[test]
    fn the_streamed_fit_does_not_depend_on_the_threads() {
        let (points, rows, p, dof) = (2 * POINTS_PER_TASK + 5, 12, 5, 3);
        let n = points * rows;
        let h = DMatrix::from_fn(n, p, |i, j| ((i * 13 + j * 7) % 17) as f64 / 8.0 - 1.0);
        let y = DVector::from_fn(n, |i, _| ((i * 3) % 7) as f64 / 3.0 - 1.0);
        let jacobians: Vec<DMatrix<f64>> = (0..points)
            .map(|k| {
                DMatrix::from_fn(rows, dof, |i, j| (((k + 3) * (i + 2) + 7 * j) % 11) as f64 / 5.0 - 1.0)
            })
            .collect();
        let mut v = DMatrix::zeros(n, rows);
        for (k, j) in jacobians.iter().enumerate() {
            let jv = j * j.transpose() * 0.1;
            v.rows_mut(k * rows, rows).copy_from(&(jv + DMatrix::identity(rows, rows)));
        }
        let weights = super::super::Weights::new(Some(&v), rows, super::super::Estimator::Wls, true).unwrap();
        let run = || {
            let layout = layout_of_points(jacobians.clone(), 3, weights.blocks());
            let samples =
                residual_samples(&HeldRows { h: &h, y: &y }, &weights, &layout, JointComponents::Full)
                    .unwrap();
            let fit = fit_components(&samples, &[true, false, false, true, false, true, true], None).unwrap();
            (samples, fit)
        };
        let (one, two) = (on_threads(1, run), on_threads(2, run));
        assert!(one.0 == two.0 && one.1 == two.1, "{} {}", one.1.values, two.1.values);
        assert!(one.1.iterations > 1, "reweighted: {}", one.1.iterations);
    }
}
