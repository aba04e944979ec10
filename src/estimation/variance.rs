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
use nalgebra::{DMatrix, DVector};
use rayon::prelude::*;

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
    let mut design: Vec<DMatrix<f64>> = joints
        .entries(jacobian.ncols())
        .into_iter()
        .map(|(i, j)| {
            let (ci, cj) = (jacobian.column(i), jacobian.column(j));
            if i == j { ci * ci.transpose() } else { ci * cj.transpose() + cj * ci.transpose() }
        })
        .collect();
    let rows =
        |orientation: bool| {
            DMatrix::from_fn(b, b, |r, c| {
                if r == c && ((per == 6 && r % 6 >= 3) == orientation) { 1.0 } else { 0.0 }
            })
        };
    design.push(rows(false));
    if per == 6 {
        design.push(rows(true));
    }
    design
}

/// The design of feasible GLS: the expectation of each point's residual outer product
/// `r_k r_k^T` per unit of each component, `D_c,k = (M V_c M^T)_kk`, for residuals `r = M e`
/// of the weighted fit `x = (H^T W H)^+ H^T W y`, `M = I - H A`, `A = (H^T W H)^+ H^T W`.
/// With `W = S^T S` (`weights`, block diagonal), `C = (H^T W H)^+ = pinv(R) pinv(R)^T` from
/// the triangular factor `R` of `S H` (`R^T R = H^T W H`), `A_k = C (S_k H_k)^T S_k` the
/// columns of `A` of point `k`, and `V_c` block diagonal,
///
/// `(M V_c M^T)_kk = V_c,k - P_k V_c,k - V_c,k P_k^T + H_k (sum_j A_j V_c,j A_j^T) H_k^T`,
/// `P_k = H_k A_k`,
///
/// point by point: no `N_m x N_m` matrix, no pseudoinverse of the tall `S H`, time and memory
/// linear in the points. `h` is the unwhitened `H` (`N_m x p`, laid out by `weights`' blocks);
/// `components[c][k]` is `V_c,k`. Points are shared between threads; every sum runs in the
/// points' order, so the result does not depend on their number.
pub(crate) fn residual_design(
    h: &DMatrix<f64>,
    weights: &super::Weights,
    components: &[Vec<DMatrix<f64>>],
) -> Result<Vec<Vec<DMatrix<f64>>>, EstimationError> {
    let blocks = weights.blocks();
    let points = blocks.points(h.nrows());
    let mut sh = h.clone();
    weights.apply(&mut sh);
    let reduced = Reduced::of_whitened(&sh, &DVector::zeros(h.nrows()), blocks, None);
    let r = reduced.r().into_owned();
    let r_pinv = super::pseudo_inverse(&r)?;
    let c = &r_pinv * r_pinv.transpose();
    // A_k = C (S_k H_k)^T S_k, point by point.
    let a: Vec<DMatrix<f64>> = (0..points)
        .into_par_iter()
        .map(|k| {
            let range = blocks.range(k);
            let mut s_k = DMatrix::identity(range.len(), range.len());
            weights.apply_point(k, s_k.as_mut_slice());
            &c * sh.rows(range.start, range.len()).transpose() * s_k
        })
        .collect();
    // sum_j A_j V_c,j A_j^T, per component, summed in the points' order.
    let middles: Vec<DMatrix<f64>> = components
        .par_iter()
        .map(|blocks_c| {
            let mut middle = DMatrix::zeros(c.nrows(), c.nrows());
            for (a_j, v) in a.iter().zip(blocks_c) {
                middle += a_j * v * a_j.transpose();
            }
            middle
        })
        .collect();
    Ok((0..points)
        .into_par_iter()
        .map(|k| {
            let range = blocks.range(k);
            let h_k = h.rows(range.start, range.len());
            let p_k = h_k * &a[k];
            components
                .iter()
                .zip(&middles)
                .map(|(blocks_c, middle)| {
                    let v = &blocks_c[k];
                    let pv = &p_k * v;
                    let d = v - &pv - pv.transpose() + h_k * middle * h_k.transpose();
                    (&d + d.transpose()) / 2.0
                })
                .collect()
        })
        .collect())
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
    samples: &[CovarianceSample],
    constrained: &[bool],
    start: Option<&DVector<f64>>,
) -> Result<ComponentFit, EstimationError> {
    let m = constrained.len();
    let bad = |s: String| Err(EstimationError::Noise(s));
    if samples.is_empty() {
        return bad("no covariances to fit the variance components to".into());
    }
    for (k, sample) in samples.iter().enumerate() {
        let b = sample.s.nrows();
        if sample.design.len() != m
            || sample.design.iter().any(|d| d.shape() != (b, b))
            || sample.s.ncols() != b
        {
            return bad(format!(
                "covariance {k}: the design does not match its {b} x {b} matrix and {m} components"
            ));
        }
        if sample.dof.is_nan()
            || sample.dof <= 0.0
            || sample.s.iter().chain(sample.design.iter().flatten()).any(|v| !v.is_finite())
        {
            return bad(format!("covariance {k}: expected finite values and degrees of freedom > 0"));
        }
    }
    let rows: usize = samples.iter().map(|s| s.s.len()).sum();
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
    if scale.iter().any(|&s| s.is_nan() || s <= 0.0 || !s.is_finite()) {
        return bad("a variance component has no influence on the data: it cannot be estimated".into());
    }
    let scaled = DMatrix::from_fn(m, m, |i, j| information[(i, j)] / (scale[i] * scale[j]));
    let inverse = scaled
        .cholesky()
        .ok_or(EstimationError::Noise(
            "the variance components cannot be told apart by these poses (singular information)".into(),
        ))?
        .inverse();
    let covariance = DMatrix::from_fn(m, m, |i, j| inverse[(i, j)] / (scale[i] * scale[j]));
    let at_bound = (0..m).map(|c| constrained[c] && theta[c] == 0.0).collect();
    Ok(ComponentFit { values: theta, covariance, constrained: constrained.to_vec(), at_bound, iterations })
}

/// The largest fitted entries `|f_k sum_c theta_c D_c,k|` of the unweighted system, of the
/// components `change` and of `theta`, in one pass over the samples (a maximum: the same on
/// any number of threads).
fn largest_fitted(samples: &[CovarianceSample], change: &DVector<f64>, theta: &DVector<f64>) -> (f64, f64) {
    let largest = |sample: &CovarianceSample| {
        let f = (sample.dof / 2.0).sqrt();
        (0..sample.s.len()).fold((0.0_f64, 0.0_f64), |(a, b), i| {
            let (mut u, mut v) = (0.0, 0.0);
            for ((d, c), t) in sample.design.iter().zip(change.iter()).zip(theta.iter()) {
                u += d[i] * c;
                v += d[i] * t;
            }
            (a.max((u * f).abs()), b.max((v * f).abs()))
        })
    };
    samples.par_iter().map(largest).reduce(|| (0.0, 0.0), |a, b| (a.0.max(b.0), a.1.max(b.1)))
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
/// ([`precision`]): one product `P X` per matrix of a sample, never the rows themselves.
fn weighted_gram(samples: &[CovarianceSample], theta: Option<&DVector<f64>>) -> DMatrix<f64> {
    let m = samples[0].design.len();
    let parts: Vec<DMatrix<f64>> = samples
        .par_chunks(SAMPLES_PER_TASK)
        .map(|chunk| {
            let mut gram = DMatrix::zeros(m + 1, m + 1);
            let (mut products, mut transposes) = (Vec::new(), Vec::new());
            for sample in chunk {
                add_sample(sample, theta, &mut gram, (&mut products, &mut transposes));
            }
            gram
        })
        .collect();
    parts.into_iter().fold(DMatrix::zeros(m + 1, m + 1), |sum, part| sum + part)
}

/// One sample's part of [`weighted_gram`]: `f^2 tr(P X P Y)` for every pair of its designs
/// and its `S`, the products `P X` and their transposes in scratch reused from sample to
/// sample.
fn add_sample(
    sample: &CovarianceSample,
    theta: Option<&DVector<f64>>,
    gram: &mut DMatrix<f64>,
    (products, transposes): (&mut Vec<DMatrix<f64>>, &mut Vec<DMatrix<f64>>),
) {
    let b = sample.s.nrows();
    let matrices = || sample.design.iter().chain([&sample.s]);
    if products.first().is_some_and(|p| p.shape() != (b, b)) {
        products.clear();
        transposes.clear();
    }
    products.resize_with(sample.design.len() + 1, || DMatrix::zeros(b, b));
    let precision = theta.map(|t| precision(sample, t));
    for (x, product) in matrices().zip(products.iter_mut()) {
        match &precision {
            Some(p) => p.mul_to(x, product),
            None => product.clone_from(x),
        }
    }
    // tr(A C) = sum_rs A_rs (C^T)_rs: each product against the others' transposes.
    transposes.resize_with(products.len(), || DMatrix::zeros(b, b));
    for (product, transpose) in products.iter().zip(transposes.iter_mut()) {
        product.transpose_to(transpose);
    }
    let f2 = sample.dof / 2.0;
    for (i, a) in products.iter().enumerate() {
        for (j, c) in transposes.iter().enumerate().take(i + 1) {
            let trace: f64 = a.as_slice().iter().zip(c.as_slice()).map(|(a, c)| a * c).sum();
            gram[(i, j)] += f2 * trace;
            if i != j {
                gram[(j, i)] += f2 * trace;
            }
        }
    }
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

/// Estimated noise: `Sigma_q` (its diagonal, or every entry) and `sigma_me^2` (and
/// `sigma_orientation^2` for poses), with their covariance; the components in the order:
/// the estimated entries of `Sigma_q` (its diagonal, or its upper triangle row by row), then
/// `sigma_me^2`, then `sigma_orientation^2` if orientations were measured.
#[derive(Debug, Clone, PartialEq)]
pub struct NoiseEstimate {
    /// The fitted components.
    pub fit: ComponentFit,
    /// Which entries of `Sigma_q` were estimated.
    pub joints: JointComponents,
    /// Number of joints.
    pub dof: usize,
    /// Whether orientations were measured (a `sigma_orientation^2` component follows `sigma_me^2`).
    pub orientation: bool,
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
    /// `residual_design` of it) with `joints`, `dof` joints and `per` rows per measured item;
    /// the reweighting starts from `start`'s components if given (a previous round of feasible
    /// GLS), else from the unweighted fit.
    pub(crate) fn fit(
        samples: &[CovarianceSample],
        joints: JointComponents,
        dof: usize,
        per: usize,
        start: Option<&Self>,
    ) -> Result<Self, EstimationError> {
        let mut constrained: Vec<bool> = joints.entries(dof).iter().map(|(i, j)| i == j).collect();
        constrained.push(true);
        if per == 6 {
            constrained.push(true);
        }
        let fit = fit_components(samples, &constrained, start.map(|s| &s.fit.values))?;
        Ok(Self { fit, joints, dof, orientation: per == 6 })
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

    /// `sigma_me` (mm) with its 95% interval.
    pub fn sigma_me(&self) -> SigmaInterval {
        self.sigma(self.joints.entries(self.dof).len())
    }

    /// `sigma_orientation` (rad) with its 95% interval, when orientations were measured.
    pub fn sigma_orientation(&self) -> Option<SigmaInterval> {
        self.orientation.then(|| self.sigma(self.joints.entries(self.dof).len() + 1))
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

    /// The measurement sigmas to weight with: `sigma_me` and `sigma_orientation`, each
    /// replaced, where its variance ended at the bound 0, by the square root of the variance's
    /// standard error. Zero measurement noise would claim that the markers are exact in every
    /// direction the joint noise cannot move them (with two markers on the last link, the turn
    /// about the line through them), and `V_k` would be singular; one standard error above
    /// zero is what the data cannot rule out.
    pub fn weighting_sigmas(&self) -> (f64, f64) {
        let m = self.joints.entries(self.dof).len();
        let usable = |c: usize| {
            let v = self.fit.values[c];
            if v > 0.0 { v.sqrt() } else { self.fit.standard_error(c).sqrt() }
        };
        (usable(m), if self.orientation { usable(m + 1) } else { 0.0 })
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

/// `P = Sigma^-1` of `Sigma = sum_c theta_c D_c` (with a small ridge, so that a component at
/// zero cannot make it singular), by its Cholesky factorisation.
fn precision(sample: &CovarianceSample, theta: &DVector<f64>) -> DMatrix<f64> {
    let b = sample.s.nrows();
    let mut sigma = DMatrix::zeros(b, b);
    for (d, t) in sample.design.iter().zip(theta.iter()) {
        sigma += d * *t;
    }
    let trace = (sigma.trace() / b as f64).max(sample.s.trace() / b as f64).max(f64::MIN_POSITIVE);
    for ridge in [1e-10, 1e-6, 1e-3, 1.0] {
        let mut regular = sigma.clone();
        for i in 0..b {
            regular[(i, i)] += ridge * trace;
        }
        if let Some(c) = regular.cholesky() {
            return c.inverse();
        }
    }
    DMatrix::identity(b, b) / trace
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
    /// `M = I - H pinv(S H) S`, on a small problem with correlated weights of every kind.
    #[test]
    fn the_residual_design_is_the_dense_residual_makers() {
        let (points, rows, p) = (5, 3, 2);
        let n = points * rows;
        let h = DMatrix::from_fn(n, p, |i, j| {
            ((i * 7 + j * 3) % 11) as f64 / 5.0 - 1.0 + f64::from(u8::from(i == j))
        });
        let spd = |seed: usize| {
            let b = DMatrix::from_fn(rows, rows, |i, j| (((seed + 1) * (i + 2) * (j + 3)) % 7) as f64 / 7.0);
            &b * b.transpose() + DMatrix::identity(rows, rows) * 0.5
        };
        let stacked = |seed: usize| {
            let mut v = DMatrix::zeros(n, rows);
            for k in 0..points {
                v.rows_mut(k * rows, rows).copy_from(&spd(seed + k));
            }
            v
        };
        let v = stacked(0);
        let components: Vec<Vec<DMatrix<f64>>> =
            (1..3).map(|c| (0..points).map(|k| spd(10 * c + k)).collect()).collect();
        for estimator in [super::super::Estimator::Ols, super::super::Estimator::Wls] {
            let weights = super::super::Weights::new(Some(&v), rows, estimator, true).unwrap();
            let designs = residual_design(&h, &weights, &components).unwrap();
            let mut s = DMatrix::identity(n, n);
            weights.apply(&mut s);
            let mut sh = h.clone();
            weights.apply(&mut sh);
            let m = DMatrix::identity(n, n) - &h * super::super::pseudo_inverse(&sh).unwrap() * &s;
            for (c, blocks) in components.iter().enumerate() {
                let mut v_c = DMatrix::zeros(n, n);
                for (k, b) in blocks.iter().enumerate() {
                    v_c.view_mut((k * rows, k * rows), (rows, rows)).copy_from(b);
                }
                let dense = &m * v_c * m.transpose();
                for (k, design) in designs.iter().enumerate() {
                    let want = dense.view((k * rows, k * rows), (rows, rows));
                    assert!(
                        (&design[c] - want).amax() < 1e-12 * want.amax().max(1.0),
                        "{estimator:?} {c} {k}"
                    );
                }
            }
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
        for sample in &samples {
            let l = precision(sample, &theta).cholesky().unwrap().l().transpose();
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
}
