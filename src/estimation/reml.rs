//! The noise the residuals say: restricted maximum likelihood (REML) of the joint and the
//! measurement variance components about a fit, and the k-fold cross-validated error the fit
//! would have with them.
//!
//! About the estimate, `r = H d + e`, `e_k ~ N(0, V_k)` with the user's components
//! `V_k = J_k Sigma_q J_k^T + Sigma_m,k` scaled apart, `V_k(a, b) = a V_q,k + b V_m,k`
//! (`a = b = 1`: the noise as given). Written `V_k = b (rho V_q,k + V_m,k)`, the scale `b` is
//! profiled out of the restricted likelihood ([`Components::profile`]):
//!
//! ```text
//! -2 l(rho) = sum_k log det V_k(rho) + log pdet M(rho) + (n - q) log b(rho)      (+ const)
//! b(rho)    = [ |w|^2 - g^T M^+ g ] / (n - q)
//! ```
//!
//! with `V_k(rho) = rho V_q,k + V_m,k = L_k L_k^T`, the whitened blocks `L_k^-1 H_k`,
//! `L_k^-1 r_k` summed to `M = sum H_k^T V_k^-1 H_k` (`p x p`), `g = sum H_k^T V_k^-1 r_k`,
//! `|w|^2 = sum r_k^T V_k^-1 r_k`; `n` rows, `q` the rank of `M` (its pseudo-determinant and
//! quadratic form on a fixed basis of its range). Only blocks of a point and `p x p` matrices:
//! never an `n x n` one. `rho` is searched on a coarse grid of `log rho` ([`RHO_GRID`]), then
//! by golden section, and the estimate is
//! `a = rho b(rho)`, `b = b(rho)`; `b(1)` is the whitened residual variance of the noise as
//! given, the simple check (`sum r^T V^-1 r / (n - q)`, 1 when the noise is right).
//!
//! The cross-validated error ([`Components::cv_rms`]) is linearised about the same fit: pose
//! `k` held out in fold `k mod K`, the others refitted by the step
//! `d_f = (M_f + P^2)^+ (g_f - P^2 x)` (`M_f`, `g_f` of the training poses at the components
//! tried, `P^2 = diag(1 / s_j^2)` the priors about the nominal, `x` the estimate), the held-out
//! rows' unweighted errors `r_k - H_k d_f` pooled: what the noise flags change, as they weigh
//! the poses against each other and against the priors.

use nalgebra::{DMatrix, DVector, SymmetricEigen};

/// The coarse grid of `log2 rho`: `rho = 2^k` for `k` from -10 to 10, every other (`4^-5` to
/// `4^5`); the best is refined by golden-section search between its neighbours.
pub const RHO_GRID: std::ops::RangeInclusive<i32> = -5..=5;

/// Golden-section steps refining `log2 rho` within the coarse grid's bracket (4 wide): to
/// `4 * 0.618^16`, about 0.0005.
const GOLDEN_STEPS: usize = 16;

/// Relative size (to the largest) of an eigenvalue of the column-scaled `M` counted in its rank.
const RANK_TOLERANCE: f64 = 1e-12;

/// One point of the linearised fit: its rows `H_k`, residuals `r_k`, and the two components
/// of its covariance as given, `V_q,k` (joint noise) and `V_m,k` (measurement noise).
#[derive(Debug, Clone, PartialEq)]
pub struct Point {
    /// `H_k`, `rows x p`.
    pub h: DMatrix<f64>,
    /// `r_k`, the residual at the estimate.
    pub r: DVector<f64>,
    /// `V_q,k = J_k Sigma_q J_k^T`.
    pub joint: DMatrix<f64>,
    /// `V_m,k = Sigma_m,k`.
    pub measurement: DMatrix<f64>,
}

/// The linearised fit, point by point, with a basis `T` (`p x q`) of the range of `M`: `q` is
/// its rank, and `T^T M T` (non-singular) stands for `M` in the pseudo-determinant and the
/// quadratic form (`g^T M^+ g = (T^T g)^T (T^T M T)^-1 T^T g`).
#[derive(Debug, Clone, PartialEq)]
pub struct Components {
    points: Vec<Point>,
    rotated: Rotated,
    basis: DMatrix<f64>,
}

/// The points' rows in the coordinates that diagonalise both components at once
/// ([`Rotated::new`]), stacked.
#[derive(Debug, Clone, PartialEq)]
struct Rotated {
    /// `U_k^T L_k^-1 H_k`, every point's rows.
    g: DMatrix<f64>,
    /// `U_k^T L_k^-1 r_k`.
    c: DVector<f64>,
    /// `lambda_k,i`, the eigenvalues of `L_k^-1 V_q,k L_k^-T`.
    lambda: Vec<f64>,
    /// Each row's point.
    point_of_row: Vec<usize>,
    /// `log det V_m,k`, point by point.
    log_det_m: Vec<f64>,
}

impl Rotated {
    /// With `V_m,k = L_k L_k^T` and `L_k^-1 V_q,k L_k^-T = U_k diag(lambda_k) U_k^T`,
    /// `V_k(a, b) = a V_q,k + b V_m,k = L_k U_k diag(a lambda_k + b) U_k^T L_k^T`: the rows
    /// `U_k^T L_k^-1 [H_k r_k]` are whitened by `1 / sqrt(a lambda_k,i + b)` each, and
    /// `log det V_k(a, b) = log det V_m,k + sum_i log(a lambda_k,i + b)`. `None` where a
    /// `V_m,k` is not positive definite.
    fn new(points: &[Point]) -> Option<Self> {
        let p = points.first().map_or(0, |q| q.h.ncols());
        let n: usize = points.iter().map(|q| q.r.len()).sum();
        let mut s = Self {
            g: DMatrix::zeros(n, p),
            c: DVector::zeros(n),
            lambda: Vec::with_capacity(n),
            point_of_row: Vec::with_capacity(n),
            log_det_m: Vec::with_capacity(points.len()),
        };
        let mut row = 0;
        for (k, point) in points.iter().enumerate() {
            let l = point.measurement.clone().cholesky()?;
            let lq = l.l().solve_lower_triangular(&point.joint)?;
            let c = l.l().solve_lower_triangular(&lq.transpose())?;
            let eigen = SymmetricEigen::new((&c + c.transpose()) * 0.5);
            let u = &eigen.eigenvectors;
            let h = u.tr_mul(&l.l().solve_lower_triangular(&point.h)?);
            let r = u.tr_mul(&l.l().solve_lower_triangular(&point.r)?);
            s.g.rows_mut(row, h.nrows()).copy_from(&h);
            s.c.rows_mut(row, r.len()).copy_from(&r);
            s.lambda.extend(eigen.eigenvalues.iter().map(|v| v.max(0.0)));
            s.point_of_row.extend(std::iter::repeat_n(k, r.len()));
            s.log_det_m.push(2.0 * l.l().diagonal().iter().map(|d| d.ln()).sum::<f64>());
            row += r.len();
        }
        Some(s)
    }
}

/// The sums of the whitened points at one covariance.
struct Sums {
    log_det: f64,
    m: DMatrix<f64>,
    g: DVector<f64>,
    ww: f64,
    rows: usize,
}

/// What the residuals say of the noise.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ComponentEstimate {
    /// `a`: the joint variances' factor (`sqrt(a)` multiplies the joint sigmas); 1 when the
    /// joint noise is zero (nothing to scale).
    pub joint: f64,
    /// `b`: the measurement variances' factor.
    pub measurement: f64,
    /// `b(1)`: the whitened residual variance with the noise as given.
    pub whitened: f64,
    /// `2 [l(rho) - l(1)]`: how much likelier the ratio found is than the one given
    /// (chi-square with one degree of freedom if the ratio given is right).
    pub likelihood_ratio: f64,
}

impl Components {
    /// The points of a fit, the range of `M` from the covariance as given; `None` where a
    /// block is not positive definite.
    pub fn new(points: Vec<Point>) -> Option<Self> {
        let rotated = Rotated::new(&points)?;
        let mut c = Self { points, rotated, basis: DMatrix::zeros(0, 0) };
        c.basis = range_basis(&c.sums(1.0, 1.0, |_| true)?.m);
        Some(c)
    }

    /// The number of points.
    pub fn points(&self) -> usize {
        self.points.len()
    }

    /// Whether the joint noise is given (some `V_q,k` not zero): the ratio can be estimated.
    pub fn has_joint_noise(&self) -> bool {
        self.points.iter().any(|p| p.joint.iter().any(|v| *v != 0.0))
    }

    /// `(-2 l(rho) + const, b(rho))` of the [module documentation](self); `None` where a
    /// block is not positive definite.
    pub fn profile(&self, rho: f64) -> Option<(f64, f64)> {
        let sums = self.sums(rho, 1.0, |_| true)?;
        let t = &self.basis;
        let l = (t.transpose() * &sums.m * t).cholesky()?;
        let gt = t.tr_mul(&sums.g);
        let log_pdet = 2.0 * l.l().diagonal().iter().map(|d| d.ln()).sum::<f64>();
        let dof = sums.rows.saturating_sub(t.ncols()).max(1) as f64;
        let b = (sums.ww - gt.dot(&l.solve(&gt))).max(0.0) / dof;
        Some((sums.log_det + log_pdet + dof * b.max(f64::MIN_POSITIVE).ln(), b))
    }

    /// The components the residuals make likeliest ([`Components::profile`] on the coarse grid
    /// `rho = 4^k`, `k` in [`RHO_GRID`], then by golden-section search on `log2 rho` between the
    /// best one's neighbours; at `rho = 1` alone without joint noise).
    pub fn estimate(&self) -> Option<ComponentEstimate> {
        let (given, whitened) = self.profile(1.0)?;
        let mut best = (1.0, given, whitened);
        if self.has_joint_noise() {
            let at = |log2: f64| self.profile(2f64.powf(log2)).map(|(v, b)| (2f64.powf(log2), v, b));
            let grid: Vec<(f64, f64, f64)> = RHO_GRID.filter_map(|k| at(2.0 * f64::from(k))).collect();
            let coarse = grid.iter().copied().min_by(|x, y| x.1.total_cmp(&y.1))?;
            let refined = golden(|log2| at(log2).map_or(f64::INFINITY, |(_, v, _)| v), coarse.0.log2())
                .and_then(at)
                .filter(|r| r.1 < coarse.1)
                .unwrap_or(coarse);
            if refined.1 < best.1 {
                best = refined;
            }
        }
        let (rho, value, b) = best;
        let joint = if self.has_joint_noise() { rho * b } else { 1.0 };
        Some(ComponentEstimate { joint, measurement: b, whitened, likelihood_ratio: given - value })
    }

    /// The k-fold cross-validated RMS error of the fit with the components scaled by
    /// `(a, b)`, linearised about the estimate `x` with the priors' standard deviations `sd`
    /// (infinite: none), over the rows `share(point, row)` counts: each row that share of one
    /// error (a marker's coordinate a third of its position's, another length one, an angle
    /// none), `sqrt(sum e_i^2 / sum share_i)`, the RMS of the errors' norms. `None` where a
    /// block is not positive definite.
    pub fn cv_rms(
        &self,
        (a, b): (f64, f64),
        folds: usize,
        (x, sd): (&DVector<f64>, &[f64]),
        share: &dyn Fn(usize, usize) -> f64,
    ) -> Option<f64> {
        let precision = DVector::from_iterator(
            sd.len(),
            sd.iter().map(|s| if s.is_finite() { 1.0 / (s * s) } else { 0.0 }),
        );
        let (mut sse, mut count) = (0.0, 0.0);
        for fold in 0..folds {
            let sums = self.sums(a, b, |k| k % folds != fold)?;
            let m = sums.m + DMatrix::from_diagonal(&precision);
            let g = sums.g - precision.component_mul(x);
            let d = pseudo_inverse(&m) * g;
            for (k, point) in self.points.iter().enumerate().skip(fold).step_by(folds) {
                let e = &point.r - &point.h * &d;
                sse += (0..e.len()).filter(|&i| share(k, i) > 0.0).map(|i| e[i] * e[i]).sum::<f64>();
                count += (0..e.len()).map(|i| share(k, i)).sum::<f64>();
            }
        }
        Some((sse / count.max(1.0)).sqrt())
    }

    /// How far the estimate moves when the components given are scaled by `(a, b)`: the fit
    /// on every point, linearised about the estimate `x` with the priors' standard deviations
    /// `sd` (infinite: none), `d(a, b) = (M(a, b) + P^2)^+ (g(a, b) - P^2 x)` against `d(1, 1)`,
    /// each parameter's change over its standard error with the components scaled
    /// (`sqrt` of the diagonal of `(M(a, b) + P^2)^+`); the largest. `None` where a block is not
    /// positive definite.
    pub fn estimate_shift(&self, (a, b): (f64, f64), (x, sd): (&DVector<f64>, &[f64])) -> Option<f64> {
        let precision = DVector::from_iterator(
            sd.len(),
            sd.iter().map(|s| if s.is_finite() { 1.0 / (s * s) } else { 0.0 }),
        );
        let fit = |a: f64, b: f64| -> Option<(DVector<f64>, DMatrix<f64>)> {
            let sums = self.sums(a, b, |_| true)?;
            let inverse = pseudo_inverse(&(sums.m + DMatrix::from_diagonal(&precision)));
            let d = &inverse * (sums.g - precision.component_mul(x));
            Some((d, inverse))
        };
        let (given, _) = fit(1.0, 1.0)?;
        let (scaled, covariance) = fit(a, b)?;
        let shift = (0..given.len())
            .filter(|&j| covariance[(j, j)] > 0.0)
            .map(|j| (scaled[j] - given[j]).abs() / covariance[(j, j)].sqrt())
            .fold(0.0, f64::max);
        Some(shift)
    }

    /// The sums of the points `take` keeps, whitened by `V_k = a V_q,k + b V_m,k`
    /// ([`Rotated::new`]): one product of the stacked rows, each scaled by
    /// `1 / sqrt(a lambda + b)`. `None` where a block is not positive definite.
    fn sums(&self, a: f64, b: f64, take: impl Fn(usize) -> bool) -> Option<Sums> {
        let t = &self.rotated;
        let rows: Vec<usize> = (0..t.c.len()).filter(|&i| take(t.point_of_row[i])).collect();
        let variance: Vec<f64> = rows.iter().map(|&i| a * t.lambda[i] + b).collect();
        if variance.iter().any(|v| *v <= 0.0) {
            return None;
        }
        let scale: Vec<f64> = variance.iter().map(|v| 1.0 / v.sqrt()).collect();
        let h = DMatrix::from_fn(rows.len(), t.g.ncols(), |r, j| t.g[(rows[r], j)] * scale[r]);
        let w = DVector::from_fn(rows.len(), |r, _| t.c[rows[r]] * scale[r]);
        let points = (0..self.points.len()).filter(|&k| take(k));
        Some(Sums {
            log_det: points.map(|k| t.log_det_m[k]).sum::<f64>()
                + variance.iter().map(|v| v.ln()).sum::<f64>(),
            m: crate::linalg::gram(&h),
            g: h.tr_mul(&w),
            ww: w.norm_squared(),
            rows: rows.len(),
        })
    }
}

/// The minimum of `f` by golden-section search in `[centre - 2, centre + 2]`
/// ([`GOLDEN_STEPS`] steps); `None` if `f` is nowhere finite there.
fn golden(f: impl Fn(f64) -> f64, centre: f64) -> Option<f64> {
    let ratio = (5f64.sqrt() - 1.0) / 2.0;
    let (mut low, mut high) = (centre - 2.0, centre + 2.0);
    let (mut x1, mut x2) = (high - ratio * (high - low), low + ratio * (high - low));
    let (mut f1, mut f2) = (f(x1), f(x2));
    for _ in 0..GOLDEN_STEPS {
        if f1 < f2 {
            (high, x2, f2) = (x2, x1, f1);
            x1 = high - ratio * (high - low);
            f1 = f(x1);
        } else {
            (low, x1, f1) = (x1, x2, f2);
            x2 = low + ratio * (high - low);
            f2 = f(x2);
        }
    }
    let x = if f1 < f2 { x1 } else { x2 };
    f(x).is_finite().then_some(x)
}

/// A basis `T` (`p x q`) of the range of the symmetric positive semi-definite `m`: the
/// eigenvectors of the column-scaled `E^-1 m E^-1` (`E` the square root of its diagonal) above
/// [`RANK_TOLERANCE`] of the largest eigenvalue, scaled back, `T = E^-1 W`. `m = H^T V^-1 H`
/// has the null space of `H` whatever `V`, so one basis serves every covariance, and
/// `T^T m T` is non-singular.
fn range_basis(m: &DMatrix<f64>) -> DMatrix<f64> {
    let (e, eigen) = scaled_eigen(m);
    let largest = eigen.eigenvalues.iter().copied().fold(0.0, f64::max);
    let kept: Vec<usize> =
        (0..m.nrows()).filter(|&i| eigen.eigenvalues[i] > RANK_TOLERANCE * largest).collect();
    let w = eigen.eigenvectors.select_columns(&kept);
    DMatrix::from_fn(w.nrows(), w.ncols(), |i, j| w[(i, j)] / e[i])
}

/// The Moore-Penrose inverse of the symmetric positive semi-definite `m` on its range, by the
/// column-scaled eigenvalues above [`RANK_TOLERANCE`] of the largest
/// (`m^+ = E^-1 (E^-1 m E^-1)^+ E^-1`, exact for a non-singular `m`).
fn pseudo_inverse(m: &DMatrix<f64>) -> DMatrix<f64> {
    let (e, eigen) = scaled_eigen(m);
    let largest = eigen.eigenvalues.iter().copied().fold(0.0, f64::max);
    let inverse = eigen.eigenvalues.map(|l| if l > RANK_TOLERANCE * largest { 1.0 / l } else { 0.0 });
    let v = &eigen.eigenvectors;
    let p = v * DMatrix::from_diagonal(&inverse) * v.transpose();
    DMatrix::from_fn(p.nrows(), p.ncols(), |i, j| p[(i, j)] / (e[i] * e[j]))
}

/// `E` (the square roots of `m`'s diagonal, 1 where it is 0) and the eigen-decomposition of
/// `E^-1 m E^-1`.
fn scaled_eigen(m: &DMatrix<f64>) -> (Vec<f64>, SymmetricEigen<f64, nalgebra::Dyn>) {
    let n = m.nrows();
    if n == 0 {
        // Nothing estimated: no direction (nalgebra's decomposition refuses an empty matrix).
        return (
            Vec::new(),
            SymmetricEigen { eigenvectors: DMatrix::zeros(0, 0), eigenvalues: DVector::zeros(0) },
        );
    }
    let e: Vec<f64> = (0..n).map(|i| if m[(i, i)] > 0.0 { m[(i, i)].sqrt() } else { 1.0 }).collect();
    (e.clone(), SymmetricEigen::new(DMatrix::from_fn(n, n, |i, j| m[(i, j)] / (e[i] * e[j]))))
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand::rngs::ChaCha8Rng;
    use rand_distr::{Distribution, StandardNormal};

    /// 400 points of 3 rows, 5 parameters; each point's joint part `J J^T` (a random 3 x 2 `J`)
    /// and measurement part `I`, the data drawn with factors `(a0, b0)`.
    fn drawn(a0: f64, b0: f64, seed: u64) -> Components {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let mut z = || -> f64 { StandardNormal.sample(&mut rng) };
        let x = DVector::from_fn(5, |_, _| 10.0 * z());
        let points = (0..400)
            .map(|_| {
                let h = DMatrix::from_fn(3, 5, |_, _| z());
                let j = DMatrix::from_fn(3, 2, |_, _| z());
                let joint = &j * j.transpose();
                let noise = &j * DVector::from_fn(2, |_, _| z()) * a0.sqrt()
                    + DVector::from_fn(3, |_, _| z()) * b0.sqrt();
                let r = &h * &x + noise;
                Point { h, r, joint, measurement: DMatrix::identity(3, 3) }
            })
            .collect();
        Components::new(points).unwrap()
    }

    /// The components the data were drawn with are found within 25%, the ratio given (1:1)
    /// rejected when it is wrong and the whitened residual variance 1 when the noise is right.
    #[test]
    fn reml_finds_the_components_drawn() {
        let right = drawn(1.0, 1.0, 1).estimate().unwrap();
        assert!((right.whitened - 1.0).abs() < 0.15, "{right:?}");
        assert!(right.likelihood_ratio < 6.0, "{right:?}");
        let wrong = drawn(4.0, 0.25, 2).estimate().unwrap();
        assert!((wrong.joint / 4.0 - 1.0).abs() < 0.25, "{wrong:?}");
        assert!((wrong.measurement / 0.25 - 1.0).abs() < 0.25, "{wrong:?}");
        assert!(wrong.likelihood_ratio > 20.0, "{wrong:?}");
    }

    /// A column the others repeat (a rank-deficient `M`) changes neither the profile nor the
    /// estimate.
    #[test]
    fn a_repeated_column_changes_nothing() {
        let c = drawn(2.0, 0.5, 3);
        let repeated = Components::new(
            c.points
                .iter()
                .map(|p| {
                    let mut h = p.h.clone().insert_column(5, 0.0);
                    h.column_mut(5).copy_from(&(p.h.column(0) * 3.0));
                    Point { h, ..p.clone() }
                })
                .collect(),
        )
        .unwrap();
        for rho in [0.1, 1.0, 10.0] {
            let (a, b) = (c.profile(rho).unwrap(), repeated.profile(rho).unwrap());
            assert!((a.1 - b.1).abs() < 1e-9 * a.1, "rho {rho}: {a:?} {b:?}");
        }
        let (a, b) = (c.estimate().unwrap(), repeated.estimate().unwrap());
        assert!((a.joint - b.joint).abs() < 1e-9 * a.joint, "{a:?} {b:?}");
    }

    /// The rotated sums ([`Rotated::new`]) are the direct ones, `L^-1 H` and `L^-1 r` with
    /// `a V_q,k + b V_m,k = L L^T`, for a measurement part that is not a multiple of `I`.
    #[test]
    fn the_rotated_sums_are_the_direct_ones() {
        let mut rng = ChaCha8Rng::seed_from_u64(4);
        let mut z = || -> f64 { StandardNormal.sample(&mut rng) };
        let points: Vec<Point> = (0..20)
            .map(|_| {
                let (j, m) = (DMatrix::from_fn(3, 2, |_, _| z()), DMatrix::from_fn(3, 3, |_, _| z()));
                let h = DMatrix::from_fn(3, 4, |_, _| z());
                let r = DVector::from_fn(3, |_, _| z());
                Point {
                    h,
                    r,
                    joint: &j * j.transpose(),
                    measurement: &m * m.transpose() + DMatrix::identity(3, 3),
                }
            })
            .collect();
        let c = Components::new(points.clone()).unwrap();
        let (a, b) = (2.5, 0.3);
        let rotated = c.sums(a, b, |k| k % 3 != 1).unwrap();
        let (mut log_det, mut m, mut g, mut ww) = (0.0, DMatrix::zeros(4, 4), DVector::zeros(4), 0.0);
        for point in points.iter().enumerate().filter(|(k, _)| k % 3 != 1).map(|(_, p)| p) {
            let l = (&point.joint * a + &point.measurement * b).cholesky().unwrap();
            let (h, r) = (
                l.l().solve_lower_triangular(&point.h).unwrap(),
                l.l().solve_lower_triangular(&point.r).unwrap(),
            );
            log_det += 2.0 * l.l().diagonal().iter().map(|d| d.ln()).sum::<f64>();
            m += h.tr_mul(&h);
            g += h.tr_mul(&r);
            ww += r.norm_squared();
        }
        assert!((rotated.log_det - log_det).abs() < 1e-9 * log_det.abs().max(1.0));
        assert!((&rotated.m - &m).norm() < 1e-9 * m.norm());
        assert!((&rotated.g - &g).norm() < 1e-9 * g.norm());
        assert!((rotated.ww - ww).abs() < 1e-9 * ww);
    }
}
