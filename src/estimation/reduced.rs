//! The whitened system `min |b - A x|^2` of `N_m` rows reduced to `p + 1` numbers a row:
//! the triangular factor of `[A b] = Q [R z; 0 rho]`, accumulated point by point while the
//! rows are computed, so that no `N_m x p` matrix is ever held (a tall-skinny QR by blocks,
//! [`crate::linalg::RowReducer`]).
//!
//! Everything a solve needs is in it: `|b - A x|^2 = |z - R x|^2 + rho^2`; `R` has the
//! singular values and right singular vectors of `A`, so the rank-revealing SVD of the
//! column-scaled `A D` is that of the `p x p` matrix `R D` (and the column norms of `A` are
//! those of `R`); `A^T A = R^T R`. The Gram matrix would hold the same information in fewer
//! flops, but squares the condition number: a singular value of the column-scaled `A` below
//! `1e-8` (`sqrt` of the rounding) would be lost in its rounding, and the rank tolerance is
//! `1e-10` ([`super::RANK_TOLERANCE`]), so a structurally unidentifiable direction could not
//! be told from a weak one. The QR keeps them apart.
//!
//! The points are cut into parts that depend only on their number ([`part_points`]); each part
//! is reduced on its own (in parallel), then the parts' factors in order: the result is the
//! same to the bit on any number of threads.

use super::prior::PriorRows;
use super::{Blocks, EstimationError, RowCovariance};
use crate::linalg::RowReducer;
use nalgebra::{DMatrix, DMatrixView, DVector};
use rayon::prelude::*;

/// What is known of the covariance `N` of the whitened rows, for the estimate's covariance
/// (the sandwich `G A^T N A G`).
#[derive(Debug, Clone, PartialEq)]
enum RowNoise {
    /// Unknown: `sigma^2 I`, `sigma^2` from the residuals.
    Unknown,
    /// `c I` (Gauss-Markov whitening: `c = sigma_max^2`).
    Scale(f64),
    /// `A^T N A` itself (`p x p`), accumulated with the factor.
    Information(DMatrix<f64>),
}

/// A whitened least-squares system `min |b - A x|^2` reduced to the triangular factor of
/// `[A b] = Q [R z; 0 rho]`, `(p + 1) x (p + 1)` whatever the number of rows, with what is known
/// of the covariance of `b`: `|b - A x|^2 = |z - R x|^2 + rho^2`, and `R` has the singular values
/// and right singular vectors of `A`. The rows are reduced block by block as they are computed
/// (a tall-skinny QR), in parts fixed by the number of points: the same to the bit on any
/// number of threads.
#[derive(Debug, Clone, PartialEq)]
pub struct Reduced {
    /// `[R z; 0 rho]`, `(p + 1) x (p + 1)`, upper triangular.
    factor: DMatrix<f64>,
    /// Rows of `A`: `N_m`, with any rows stacked below.
    rows: usize,
    noise: RowNoise,
    /// The first value of `A` or `b` that is not finite, as an error.
    non_finite: Option<EstimationError>,
}

/// The points `0..points` of `blocks` in parts of [`part_points`] each: each part's range of
/// points, its first row, and its rows of `b` if `b` is given.
#[allow(clippy::type_complexity)]
fn parts_of<'b>(
    blocks: &Blocks,
    points: usize,
    b: Option<&'b mut [f64]>,
) -> Vec<(std::ops::Range<usize>, usize, Option<&'b mut [f64]>)> {
    let per_part = part_points(points);
    let mut slices = Vec::with_capacity(points.div_ceil(per_part));
    let mut rest = b;
    for first in (0..points).step_by(per_part) {
        let last = (first + per_part).min(points) - 1;
        let (start, end) = (blocks.range(first).start, blocks.range(last).end);
        let mine = match rest.take() {
            Some(all) => {
                let (mine, others) = all.split_at_mut(end - start);
                rest = Some(others);
                Some(mine)
            }
            None => None,
        };
        slices.push((first..last + 1, start, mine));
    }
    slices
}

/// The triangular factors of the parts, in order, reduced to one (`[R z; 0 rho]`, `p1` square).
fn combined(parts: Vec<Part>, p1: usize) -> DMatrix<f64> {
    match parts.len() {
        0 => DMatrix::zeros(p1, p1),
        1 => parts.into_iter().next().map(|part| part.factor).expect("one part"),
        _ => {
            let mut reducer = RowReducer::new(p1);
            for part in &parts {
                reducer.push(part.factor.as_slice());
            }
            reducer.finish()
        }
    }
}

/// Points per part of a reduction: about 64 parts, of at least 32 points, so that a part
/// outweighs its overhead and a thousand points still share two cores.
fn part_points(points: usize) -> usize {
    points.div_ceil(64).max(32)
}

/// What one part of a reduction gives.
struct Part {
    factor: DMatrix<f64>,
    information: Option<DMatrix<f64>>,
    non_finite: Option<EstimationError>,
}

impl Reduced {
    /// Reduce the whitened rows of `points` points laid out by `blocks`, `p` columns: `fill`
    /// writes point `k`'s rows `[A_k b_k]` (column-major, `size_k x (p + 1)`), with a scratch
    /// state from `init` per part; `b` receives every `b_k`. With `noise` (the stacked
    /// covariance blocks of the whitened rows) `A^T N A` is accumulated too, unless every
    /// block is a multiple of the identity.
    pub(crate) fn reduce<S>(
        blocks: &Blocks,
        p: usize,
        noise: Option<&RowCovariance>,
        b: &mut [f64],
        init: impl Fn() -> S + Sync,
        fill: impl Fn(&mut S, usize, &mut [f64]) + Sync,
    ) -> Self {
        let rows = b.len();
        Self::reduce_rows(blocks, rows, p, noise, Some(b), init, fill)
    }

    /// [`Reduced::reduce`] of `rows` rows, `b` kept only if a place is given for it.
    pub(crate) fn reduce_rows<S>(
        blocks: &Blocks,
        rows: usize,
        p: usize,
        noise: Option<&RowCovariance>,
        b: Option<&mut [f64]>,
        init: impl Fn() -> S + Sync,
        fill: impl Fn(&mut S, usize, &mut [f64]) + Sync,
    ) -> Self {
        let points = blocks.points(rows);
        let (scale, information) = match noise {
            Some(RowCovariance::Scale(c)) => (Some(*c), None),
            Some(RowCovariance::Blocks(n)) => match super::blocks::identity_multiple(n, blocks) {
                Some(c) => (Some(c), None),
                None => (None, Some(n)),
            },
            None => (None, None),
        };
        let slices = parts_of(blocks, points, b);
        let width = blocks.width();
        let parts: Vec<Part> = slices
            .into_par_iter()
            .map(|(range, start, mut b)| {
                let mut state = init();
                let mut reducer = RowReducer::new(p + 1);
                let mut block = vec![0.0; width * (p + 1)];
                let mut product = DMatrix::zeros(width, p);
                let mut info = information.map(|_| DMatrix::zeros(p, p));
                let mut non_finite = None;
                for k in range {
                    let r = blocks.range(k);
                    let n = r.len();
                    let rows = &mut block[..n * (p + 1)];
                    rows.fill(0.0);
                    fill(&mut state, k, rows);
                    let (h, y) = rows.split_at(n * p);
                    if let Some(b) = b.as_deref_mut() {
                        b[r.start - start..r.end - start].copy_from_slice(y);
                    }
                    if non_finite.is_none() {
                        non_finite = first_non_finite(h, y, r.start, n);
                    }
                    if let (Some(info), Some(stacked)) = (&mut info, information) {
                        let a = DMatrixView::from_slice(h, n, p);
                        let v = stacked.view((r.start, 0), (n, n));
                        let mut t = product.rows_mut(0, n);
                        t.gemm(1.0, &v, &a, 0.0);
                        info.gemm_tr(1.0, &a, &t, 1.0);
                    }
                    reducer.push(rows);
                }
                Part { factor: reducer.finish(), information: info, non_finite }
            })
            .collect();
        let non_finite = parts.iter().find_map(|part| part.non_finite.clone());
        let noise = match (noise, scale) {
            (None, _) => RowNoise::Unknown,
            (Some(_), Some(c)) => RowNoise::Scale(c),
            (Some(_), None) => RowNoise::Information(
                parts
                    .iter()
                    .filter_map(|part| part.information.as_ref())
                    .fold(DMatrix::zeros(p, p), |s, i| s + i),
            ),
        };
        let factor = combined(parts, p + 1);
        Self { factor, rows, noise, non_finite }
    }

    /// The reduction of a whitened system held whole: `a` (`N_m x p`) and `b`, points laid out
    /// by `blocks`, `noise` the covariance blocks of `b` if known. The same arithmetic as a
    /// reduction of the rows as they are computed.
    pub(crate) fn of_whitened(
        a: &DMatrix<f64>,
        b: &DVector<f64>,
        blocks: &Blocks,
        noise: Option<&RowCovariance>,
    ) -> Self {
        let (m, p) = a.shape();
        let mut copy = b.clone();
        Self::reduce(
            blocks,
            p,
            noise,
            copy.as_mut_slice(),
            || (),
            |_, k, rows| {
                let r = blocks.range(k);
                let n = r.len();
                for j in 0..p {
                    rows[j * n..(j + 1) * n].copy_from_slice(&a.as_slice()[j * m + r.start..j * m + r.end]);
                }
                rows[p * n..].copy_from_slice(&b.as_slice()[r.clone()]);
            },
        )
    }

    /// Number of parameters `p`.
    pub fn parameters(&self) -> usize {
        self.factor.ncols() - 1
    }

    /// Rows of the system reduced: `N_m`, with the rows of priors or damping stacked below.
    pub fn rows(&self) -> usize {
        self.rows
    }

    /// `R`, `p x p` upper triangular: `A^T A = R^T R`.
    pub fn r(&self) -> DMatrixView<'_, f64> {
        let p = self.parameters();
        self.factor.view((0, 0), (p, p))
    }

    /// `z`, the first `p` entries of `Q^T b`.
    pub fn z(&self) -> DVector<f64> {
        let p = self.parameters();
        self.factor.view((0, p), (p, 1)).column(0).into_owned()
    }

    /// `|b - A x|^2 = |z - R x|^2 + rho^2`: the cost of the linearised system after a step `x`.
    pub fn cost_after(&self, x: &DVector<f64>) -> f64 {
        let p = self.parameters();
        (self.z() - self.r() * x).norm_squared() + self.factor[(p, p)].powi(2)
    }

    /// The column norms of `A` (those of `R`).
    pub fn column_norms(&self) -> Vec<f64> {
        self.r().column_iter().map(|c| c.norm()).collect()
    }

    /// `A^T A` as `R^T R`.
    pub(crate) fn gram(&self) -> DMatrix<f64> {
        self.r().tr_mul(&self.r())
    }

    /// The error of the first value of `A` or `b` that is not finite, if any.
    pub fn check_finite(&self) -> Result<(), EstimationError> {
        self.non_finite.clone().map_or(Ok(()), Err)
    }

    /// `A^T N A` for the covariance `N` of `b`: `c R^T R` for `N = c I`, `sigma2 R^T R` where
    /// the noise is unknown.
    pub(crate) fn information(&self, sigma2: f64) -> DMatrix<f64> {
        match &self.noise {
            RowNoise::Unknown => self.gram() * sigma2,
            RowNoise::Scale(c) => self.gram() * *c,
            RowNoise::Information(information) => information.clone(),
        }
    }

    /// The system of the columns `columns` (ascending) of `A`: `[A_c b] = Q [R_c z; 0 rho]`,
    /// reduced again at `(p + 1)^2` cost.
    pub fn select(&self, columns: &[usize]) -> Self {
        let p = self.parameters();
        let kept: Vec<usize> = columns.iter().copied().chain([p]).collect();
        let mut reducer = RowReducer::new(kept.len());
        reducer.push(self.factor.select_columns(&kept).as_slice());
        let noise = match &self.noise {
            RowNoise::Information(i) => RowNoise::Information(i.select_rows(columns).select_columns(columns)),
            other => other.clone(),
        };
        Self { factor: reducer.finish(), rows: self.rows, noise, non_finite: self.non_finite.clone() }
    }

    /// The system with the rows `extra` (`k x (p + 1)`: `[A_e b_e]`) stacked below.
    fn stacked(&self, extra: &DMatrix<f64>) -> Self {
        let mut reducer = RowReducer::new(self.factor.ncols());
        reducer.push(self.factor.as_slice());
        reducer.push(extra.as_slice());
        let (factor, rows) = (reducer.finish(), self.rows + extra.nrows());
        Self { factor, rows, noise: self.noise.clone(), non_finite: self.non_finite.clone() }
    }

    /// The system with the prior rows `c P` below it, about `x` ([`PriorRows::augment`]).
    pub fn with_prior(&self, prior: &PriorRows, x: &DVector<f64>) -> Self {
        let (a, b) = prior.augment(&DMatrix::zeros(0, self.parameters()), &DVector::zeros(0), x);
        let mut extra = a.clone().insert_column(a.ncols(), 0.0);
        extra.column_mut(a.ncols()).copy_from(&b);
        self.stacked(&extra)
    }

    /// Marquardt's damped system: `sqrt(damping) |A_j|` on the diagonal of rows stacked below,
    /// their right-hand side zero.
    #[cfg(test)]
    pub(crate) fn damped(&self, damping: f64) -> Self {
        let p = self.parameters();
        let norms = self.column_norms();
        let extra = DMatrix::from_fn(p, p + 1, |i, j| if i == j { damping.sqrt() * norms[j] } else { 0.0 });
        self.stacked(&extra)
    }
}

/// The first value of point rows `h` (`n x p`, column-major) or `y` (`n`) that is not
/// finite, as an error with its row in the stacked system (`start` the point's first row).
fn first_non_finite(h: &[f64], y: &[f64], start: usize, n: usize) -> Option<EstimationError> {
    if h.iter().chain(y).all(|v| v.is_finite()) {
        return None;
    }
    super::finite("y", y, n).and_then(|()| super::finite("H", h, n)).err().map(|e| match e {
        EstimationError::NonFinite { what, row, value } => {
            EstimationError::NonFinite { what, row: start + row, value }
        }
        other => other,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::estimation::solve::{factorise_rank_revealing, factorise_reduced};

    /// `m x p` rows of 3-row points: smooth columns of scales 1e-6 to 1e6, the last within
    /// `1e-5` (relative) of a combination of two others, and `b = A x_true + noise`.
    fn ill_conditioned(m: usize) -> (DMatrix<f64>, DVector<f64>, DVector<f64>) {
        let p = 6;
        let mut a = DMatrix::from_fn(m, p, |r, c| (r as f64 * (0.011 + 0.37 * c as f64) + c as f64).sin());
        for r in 0..m {
            a[(r, 5)] = a[(r, 0)] - 2.0 * a[(r, 1)] + 1e-5 * ((r as f64) * 1.7).cos();
        }
        for (c, scale) in [1e-6, 1e-3, 1.0, 1e3, 1e6, 1.0].into_iter().enumerate() {
            a.column_mut(c).scale_mut(scale);
        }
        let x = DVector::from_fn(p, |c, _| (c as f64 + 1.0) / [1e-6, 1e-3, 1.0, 1e3, 1e6, 1.0][c]);
        let noise = DVector::from_fn(m, |r, _| 1e-3 * ((r as f64) * 2.3).sin());
        (a.clone(), &a * &x + noise, x)
    }

    fn reduced(a: &DMatrix<f64>, b: &DVector<f64>) -> Reduced {
        Reduced::of_whitened(a, b, &Blocks::Uniform(3), None)
    }

    /// An ill-conditioned but full-rank system (column-scaled condition number near 1e5)
    /// solved from its reduction as by the dense Householder QR of every row, to 1e-9
    /// (relative); the normal equations lose far more.
    #[test]
    fn the_reduced_solve_is_the_dense_solve() {
        let (a, b, _) = ill_conditioned(3000);
        let system = reduced(&a, &b);
        let f = factorise_reduced(&system, crate::estimation::RANK_TOLERANCE).unwrap();
        assert_eq!(f.diagnostics.rank, 6);
        assert!(f.diagnostics.condition_number > 1e4, "{}", f.diagnostics.condition_number);
        let x = f.solve(&system);
        let dense = factorise_rank_revealing(&a, crate::estimation::RANK_TOLERANCE).unwrap().pinv(&a) * &b;
        let relative =
            |x: &DVector<f64>| (0..6).map(|c| ((x[c] - dense[c]) / dense[c]).abs()).fold(0.0, f64::max);
        assert!(relative(&x) < 1e-9, "{x} against {dense}");
        let cost = (&b - &a * &dense).norm_squared();
        assert!((system.cost_after(&x) - cost).abs() < 1e-9 * cost);
        // The Gram matrix A^T A squares the condition number: its solution is worse.
        let gram = a.transpose() * &a;
        let normal = gram.clone().cholesky().map(|c| c.solve(&(a.transpose() * &b)));
        assert!(normal.is_none_or(|n| relative(&n) > 1e-9), "the normal equations would do");
    }

    /// The reduction is the same to the bit on any number of threads, and `R^T R = A^T A`.
    #[test]
    fn reductions_are_the_same_on_any_number_of_threads() {
        let (a, b, _) = ill_conditioned(6000);
        let on = |threads| {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
            pool.install(|| reduced(&a, &b))
        };
        let one = on(1);
        assert_eq!(one, on(2));
        let gram = a.transpose() * &a;
        assert!((one.gram() - &gram).amax() <= 1e-12 * gram.amax());
    }

    /// Columns selected, prior rows and damping rows stacked: as reducing the system so
    /// changed from its rows.
    #[test]
    fn select_prior_and_damping_are_those_of_the_changed_rows() {
        let (a, b, _) = ill_conditioned(300);
        let system = reduced(&a, &b);
        let same = |x: &Reduced, y: &Reduced| {
            let (gx, gy) = (x.gram(), y.gram());
            assert!((&gx - &gy).amax() <= 1e-11 * gx.amax(), "{gx} against {gy}");
            let (zx, zy) = (x.r().transpose() * x.z(), y.r().transpose() * y.z());
            assert!((&zx - &zy).amax() <= 1e-11 * zx.amax());
            assert_eq!(x.rows(), y.rows());
        };
        let columns = [0, 2, 5];
        same(&system.select(&columns), &reduced(&a.select_columns(&columns), &b));
        let prior = PriorRows::new(&[1.0, f64::INFINITY, 0.5, f64::INFINITY, 2.0, 1.0], 0.1);
        let x = DVector::from_fn(6, |c, _| c as f64 * 0.1);
        let (stacked_a, stacked_b) = prior.augment(&a, &b, &x);
        let pad = |m: DMatrix<f64>| m.clone().insert_rows(m.nrows(), (3 - m.nrows() % 3) % 3, 0.0);
        let (pa, pb) =
            (pad(stacked_a), pad(DMatrix::from_column_slice(stacked_b.len(), 1, stacked_b.as_slice())));
        let mut expected = reduced(&pa, &DVector::from_column_slice(pb.as_slice()));
        expected.rows = system.rows() + 4;
        same(&system.with_prior(&prior, &x), &expected);
        let norms = system.column_norms();
        let damped = a.clone().insert_rows(a.nrows(), 6, 0.0);
        let mut damped = damped;
        for j in 0..6 {
            damped[(a.nrows() + j, j)] = 1e-2f64.sqrt() * norms[j];
        }
        let mut expected = reduced(&damped, &b.clone().insert_rows(b.len(), 6, 0.0));
        expected.rows = system.rows() + 6;
        same(&system.damped(1e-2), &expected);
    }
}
