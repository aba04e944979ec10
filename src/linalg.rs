//! The one place robocal calls faer: a singular value decomposition that stays accurate for
//! rank-deficient matrices (nalgebra's returned a reconstruction error of 2e-3 on an exactly
//! rank-deficient 5 x 5 triangular matrix; see the test below). faer is built single-threaded
//! (`default-features = false`), so it composes with rayon. faer does not truncate small
//! singular values: the rank decision is the caller's.
//!
//! The tall-skinny QR of the whitened rows ([`RowReducer`]) is robocal's own: LAPACK's
//! triangular-pentagonal QR, which faer lacks, compiled for the machine's vector instructions
//! by pulp (faer's own dispatcher), with the same bits on any of them.

use nalgebra::DMatrix;
use rayon::prelude::*;

/// Rows per part of [`gram`]: the parts are fixed, so the sums over them, and
/// every result, are the same on any number of threads.
const ROWS_PER_PART: usize = 1024;

/// The row parts of `a`, as faer views.
fn row_parts(a: &DMatrix<f64>) -> impl IndexedParallelIterator<Item = faer::MatRef<'_, f64>> {
    let (m, n) = a.shape();
    let whole = faer::MatRef::from_column_major_slice(a.as_slice(), m, n);
    (0..m.div_ceil(ROWS_PER_PART))
        .into_par_iter()
        .map(move |i| whole.subrows(i * ROWS_PER_PART, ROWS_PER_PART.min(m - i * ROWS_PER_PART)))
}

/// `a^T a`, the products of fixed row parts computed in parallel and summed in order.
pub(crate) fn gram(a: &DMatrix<f64>) -> DMatrix<f64> {
    let n = a.ncols();
    let parts: Vec<faer::Mat<f64>> = row_parts(a).map(|rows| rows.transpose() * rows).collect();
    let mut total = faer::Mat::<f64>::zeros(n, n);
    for part in &parts {
        total += part;
    }
    DMatrix::from_fn(n, n, |i, j| total[(i, j)])
}

/// Rows a [`RowReducer`] gathers below its triangular factor before each reduction: the
/// gathered block (`128 x 43` for a 42-parameter system) stays in the first level of cache
/// while every reflection passes over it.
const REDUCE_ROWS: usize = 128;

/// The triangular factor `R` (`n x n`) of a tall matrix whose rows are pushed block by block,
/// never held together: the rows gathered so far, `B`, are stacked below `R` and `[R; B]` is
/// reduced to its own `R` every [`REDUCE_ROWS`] rows (a tall-skinny QR). The reduction is
/// LAPACK's triangular-pentagonal QR (`tpqrt`): the reflection `j` is
///
/// ```text
///   H_j = I - tau_j [1; v_j] [1; v_j]^T,   acting on row j of R and on B alone,
///   beta_j = -sign(R_jj) sqrt(R_jj^2 + |B_j|^2),  v_j = B_j / (R_jj - beta_j),
///   tau_j = (beta_j - R_jj) / beta_j,             R_jj <- beta_j,  B_j <- 0,
/// ```
///
/// (`B_j` the column `j` of `B`), so the zeros below `R`'s diagonal are never touched (faer's
/// general QR of the stacked block works on them too, and does 3 times fewer floating-point
/// operations a second at these sizes: 3.2 against 10.4 GFLOP/s on one core of the
/// development machine, 300,000 x 43). `R^T R = A^T A` and `R` has the singular values and
/// right singular vectors of `A`, to the rounding of a Householder QR of `A` itself (unlike
/// the Gram matrix, whose rounding is that of `A`'s condition number squared).
///
/// The arithmetic depends only on the sequence of rows pushed, not on how it is cut into
/// pushes, nor on the machine: every dot product is summed in [`LANES`] fixed lanes, then the
/// lanes in a fixed order, and the loops are compiled once per instruction set
/// ([`pulp::Arch::dispatch`]) with the same operations in the same order (no fused
/// multiply-add), so the bits are the same with SSE2, AVX2 or none. Nothing is allocated after
/// [`RowReducer::new`].
pub(crate) struct RowReducer {
    columns: usize,
    /// `[R; B]`, `(n + REDUCE_ROWS) x n`, column-major.
    work: Vec<f64>,
    /// Rows gathered in `B`.
    filled: usize,
}

impl RowReducer {
    /// A reducer of rows of `columns` entries, with `R = 0`.
    pub fn new(columns: usize) -> Self {
        Self { columns, work: vec![0.0; (columns + REDUCE_ROWS) * columns], filled: 0 }
    }

    /// Push the rows of `block`, a column-major `rows x n` slice (`rows = block.len() / n`).
    pub fn push(&mut self, block: &[f64]) {
        let n = self.columns;
        if n == 0 {
            return;
        }
        let (rows, ld) = (block.len() / n, n + REDUCE_ROWS);
        let mut done = 0;
        while done < rows {
            if self.filled == REDUCE_ROWS {
                self.reduce();
            }
            let take = (rows - done).min(REDUCE_ROWS - self.filled);
            let at = n + self.filled;
            for (into, column) in self.work.chunks_exact_mut(ld).zip(block.chunks_exact(rows)) {
                into[at..at + take].copy_from_slice(&column[done..done + take]);
            }
            self.filled += take;
            done += take;
        }
    }

    /// `[R; B]` reduced to `R` in place, `B` emptied.
    fn reduce(&mut self) {
        if self.filled > 0 {
            let (n, ld) = (self.columns, self.columns + REDUCE_ROWS);
            pulp::Arch::new().dispatch(Reduction { work: &mut self.work, ld, n, m: self.filled });
            self.filled = 0;
        }
    }

    /// `R` of every row pushed (`n x n`, upper triangular; zero rows where fewer rows than
    /// columns were pushed).
    pub fn finish(mut self) -> nalgebra::DMatrix<f64> {
        self.reduce();
        let (n, ld) = (self.columns, self.columns + REDUCE_ROWS);
        nalgebra::DMatrix::from_fn(n, n, |i, j| if i <= j { self.work[j * ld + i] } else { 0.0 })
    }
}

/// Lanes of [`dot`]'s sums: eight, one AVX-512 register, two AVX2, four SSE2.
const LANES: usize = 8;

/// `a . b`, summed in [`LANES`] lanes (lane `l` the products `l, l + LANES, ...`), then the lanes
/// pairwise in a fixed order: the same bits however the loop is vectorised.
#[inline(always)]
fn dot(a: &[f64], b: &[f64]) -> f64 {
    let mut lanes = [0.0; LANES];
    let (a_chunks, b_chunks) = (a.chunks_exact(LANES), b.chunks_exact(LANES));
    let (a_rest, b_rest) = (a_chunks.remainder(), b_chunks.remainder());
    for (x, y) in a_chunks.zip(b_chunks) {
        for l in 0..LANES {
            lanes[l] += x[l] * y[l];
        }
    }
    for (l, (x, y)) in a_rest.iter().zip(b_rest).enumerate() {
        lanes[l] += x * y;
    }
    let [l0, l1, l2, l3, l4, l5, l6, l7] = lanes;
    ((l0 + l1) + (l2 + l3)) + ((l4 + l5) + (l6 + l7))
}

/// One reduction of [`RowReducer`]: `[R; B]` in `work` (column-major, leading dimension `ld`,
/// `R` its first `n` rows, `B` the `m` below) reduced to `R` by the reflections of
/// [`RowReducer`]'s equations, compiled for the machine's instruction set by `pulp`.
struct Reduction<'a> {
    work: &'a mut [f64],
    ld: usize,
    n: usize,
    m: usize,
}

impl pulp::WithSimd for Reduction<'_> {
    type Output = ();

    #[inline(always)]
    fn with_simd<S: pulp::Simd>(self, _simd: S) {
        let Reduction { work, ld, n, m } = self;
        for j in 0..n {
            let (left, right) = work.split_at_mut((j + 1) * ld);
            let column = &mut left[j * ld..];
            let Some((tau, beta)) = reflection(column[j], &column[n..n + m]) else { continue };
            let pivot = column[j] - beta;
            column[n..n + m].iter_mut().for_each(|x| *x /= pivot);
            column[j] = beta;
            let v = &column[n..n + m];
            for c in right.chunks_exact_mut(ld) {
                let t = tau * (c[j] + dot(v, &c[n..n + m]));
                c[j] -= t;
                c[n..n + m].iter_mut().zip(v).for_each(|(x, y)| *x -= t * y);
            }
        }
    }
}

/// The reflection `(tau, beta)` that maps `[alpha; b]` to `[beta; 0]` ([`RowReducer`]'s
/// equations), or `None` if `b` is zero already. `alpha^2 + |b|^2` is summed as it is unless it
/// would overflow or `|b|^2` lose its digits to underflow; then scaled by the largest entry.
#[inline(always)]
fn reflection(alpha: f64, b: &[f64]) -> Option<(f64, f64)> {
    let squares = dot(b, b);
    let total = alpha * alpha + squares;
    let norm = if total.is_finite() && squares > f64::MIN_POSITIVE / f64::EPSILON {
        total.sqrt()
    } else if b.iter().all(|&x| x == 0.0) {
        return None;
    } else {
        let largest = b.iter().fold(alpha.abs(), |m, x| m.max(x.abs()));
        let scaled = b.iter().fold(0.0, |s, x| s + (x / largest) * (x / largest));
        largest * ((alpha / largest) * (alpha / largest) + scaled).sqrt()
    };
    let beta = -norm.copysign(alpha);
    Some(((beta - alpha) / beta, beta))
}

/// `a b` by faer's blocked product: the planner multiplies a tall pool of candidate rows
/// (15000 x 23 for 5000 PUMA poses) by a small matrix after every exchange.
pub(crate) fn mul(a: &DMatrix<f64>, b: &DMatrix<f64>) -> DMatrix<f64> {
    let a_ref = faer::MatRef::from_column_major_slice(a.as_slice(), a.nrows(), a.ncols());
    let b_ref = faer::MatRef::from_column_major_slice(b.as_slice(), b.nrows(), b.ncols());
    let product = a_ref * b_ref;
    DMatrix::from_fn(a.nrows(), b.ncols(), |i, j| product[(i, j)])
}

/// `A = U diag(s) V^T`, thin, singular values in descending order.
#[derive(Debug, Clone)]
pub(crate) struct Svd {
    /// Left singular vectors, `m x min(m, n)`.
    pub u: DMatrix<f64>,
    /// Singular values, largest first.
    pub s: Vec<f64>,
    /// Right singular vectors, `n x min(m, n)`.
    pub v: DMatrix<f64>,
}

/// The thin SVD of `a`, or `None` if the iteration did not converge, on `a` nor on `a^T`
/// (`a^T = V diag(s) U^T`): faer's fails now and then where its transpose's does not, as on
/// a well-conditioned 76 x 76 triangular factor of a tree's calibration (smallest singular
/// value 1.4e-3, largest 1).
pub(crate) fn svd(a: &DMatrix<f64>) -> Option<Svd> {
    thin_svd(a).or_else(|| {
        let Svd { u, s, v } = thin_svd(&a.transpose())?;
        Some(Svd { u: v, s, v: u })
    })
}

/// faer's thin SVD of `a`, singular values in descending order.
fn thin_svd(a: &DMatrix<f64>) -> Option<Svd> {
    let (m, n) = a.shape();
    let decomposition = faer::Mat::from_fn(m, n, |i, j| a[(i, j)]).thin_svd().ok()?;
    let (u, v, s) = (decomposition.U(), decomposition.V(), decomposition.S().column_vector());
    let k = m.min(n);
    let mut order: Vec<usize> = (0..k).collect();
    order.sort_by(|&i, &j| s[j].total_cmp(&s[i]));
    Some(Svd {
        u: DMatrix::from_fn(m, k, |i, c| u[(i, order[c])]),
        s: order.iter().map(|&i| s[i]).collect(),
        v: DMatrix::from_fn(n, k, |i, c| v[(i, order[c])]),
    })
}

/// The SVD of a tall matrix (`m >= n`) without its `m x n` left factor: Householder QR
/// `A = Q [R; 0]`, then the SVD of the small `R = U_R diag(s) V^T`, so `U = Q [U_R; 0]` with
/// `Q` kept as its reflectors. Four times cheaper than a thin SVD for 6000 x 42, and as
/// accurate: `R` is the exact factor of a matrix within rounding of `A`.
pub(crate) struct TallSvd {
    qr: faer::linalg::solvers::Qr<f64>,
    /// The SVD of `R`: `u` is `U_R` (`n x n`).
    pub small: Svd,
}

/// [`TallSvd`] of `a D`, `D = diag(column_scales)`, or `None` if `a` is wide or the iteration
/// did not converge. `A D = Q (R D)`: the columns are scaled in the small `R`, not in a copy
/// of `a`.
pub(crate) fn tall_svd(a: &DMatrix<f64>, column_scales: &[f64]) -> Option<TallSvd> {
    let (m, n) = a.shape();
    if m < n || column_scales.len() != n {
        return None;
    }
    let qr = faer::MatRef::from_column_major_slice(a.as_slice(), m, n).qr();
    let r = qr.thin_R();
    let small = svd(&DMatrix::from_fn(n, n, |i, j| r[(i, j)] * column_scales[j]))?;
    Some(TallSvd { qr, small })
}

impl TallSvd {
    /// `Q x` (or `Q^T x` if `transpose`) in place, for `x` with `m` rows, by the reflectors.
    fn apply_q(&self, x: &mut faer::Mat<f64>, transpose: bool) {
        use faer::linalg::householder as hh;
        let (basis, coeff) = (self.qr.Q_basis(), self.qr.Q_coeff());
        let req = hh::apply_block_householder_sequence_on_the_left_in_place_scratch::<f64>(
            basis.nrows(),
            coeff.nrows(),
            x.ncols(),
        );
        let mut buffer = faer::dyn_stack::MemBuffer::new(req);
        let stack = faer::dyn_stack::MemStack::new(&mut buffer);
        let (no, seq) = (faer::Conj::No, faer::Par::Seq);
        if transpose {
            hh::apply_block_householder_sequence_transpose_on_the_left_in_place_with_conj(
                basis,
                coeff,
                no,
                x.as_mut(),
                seq,
                stack,
            );
        } else {
            hh::apply_block_householder_sequence_on_the_left_in_place_with_conj(
                basis,
                coeff,
                no,
                x.as_mut(),
                seq,
                stack,
            );
        }
    }

    /// The first `rows` rows of `Q [z; 0]` for `z` with `n` rows.
    pub fn q(&self, z: &DMatrix<f64>, rows: usize) -> DMatrix<f64> {
        let m = self.qr.Q_basis().nrows();
        let mut work =
            faer::Mat::<f64>::from_fn(m, z.ncols(), |i, j| if i < z.nrows() { z[(i, j)] } else { 0.0 });
        self.apply_q(&mut work, false);
        DMatrix::from_fn(rows, z.ncols(), |i, j| work[(i, j)])
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::DVector;

    /// The matrix on which nalgebra 0.35's SVD lost three digits: R of a 18 x 5 column-scaled
    /// matrix whose last column is the sum of the first two.
    #[test]
    fn reconstructs_a_rank_deficient_matrix() {
        for seed in 0..50u64 {
            let mut h =
                DMatrix::from_fn(18, 5, |r, c| (((r * 5 + c) as f64 + seed as f64 * 7.3) * 12.9898).sin());
            let sum = h.column(0) + h.column(1);
            h.column_mut(4).copy_from(&sum);
            for mut column in h.column_iter_mut() {
                column /= column.norm();
            }
            let r = h.qr().r();
            let svd = svd(&r).unwrap();
            let back = &svd.u * DMatrix::from_diagonal(&svd.s.clone().into()) * svd.v.transpose();
            assert!((back - &r).amax() < 1e-14, "seed {seed}");
            assert!(svd.s.windows(2).all(|w| w[0] >= w[1]) && svd.s[4] < 1e-15);
        }
    }

    /// `Q [U_R; 0] diag(s) V^T` rebuilds `A`.
    #[test]
    fn tall_svd_is_the_thin_svd() {
        let a = DMatrix::from_fn(50, 4, |r, c| ((r * 4 + c) as f64 * 0.71).sin());
        let tall = tall_svd(&a, &[1.0; 4]).unwrap();
        let u = tall.q(&tall.small.u, 50);
        let back = &u * DMatrix::from_diagonal(&tall.small.s.clone().into()) * tall.small.v.transpose();
        assert!((back - &a).amax() < 1e-13);
        let thin = svd(&a).unwrap();
        assert!(thin.s.iter().zip(&tall.small.s).all(|(x, y)| (x - y).abs() < 1e-13));
        assert!(tall_svd(&a.transpose(), &[1.0; 50]).is_none(), "wide matrices are refused");
        // Scaled columns: the SVD of A D.
        let scales = [2.0, 0.5, 3.0, 1e-3];
        let scaled = tall_svd(&a, &scales).unwrap();
        let direct = svd(&(&a * DMatrix::from_diagonal(&DVector::from_column_slice(&scales)))).unwrap();
        assert!(direct.s.iter().zip(&scaled.small.s).all(|(x, y)| (x - y).abs() < 1e-13 * direct.s[0]));
    }

    /// Test matrices of the sizes `(m, n)`: smooth entries, columns of growing scale.
    fn matrices(sizes: &[(usize, usize)]) -> Vec<DMatrix<f64>> {
        let entry = |r: usize, c: usize| ((r * 7 + c * 3) as f64 * 0.61).sin() * (c + 1) as f64;
        sizes.iter().map(|&(m, n)| DMatrix::from_fn(m, n, entry)).collect()
    }

    /// Several row parts (2500 rows), a single part, and fewer rows than columns.
    fn tall_matrices() -> Vec<DMatrix<f64>> {
        matrices(&[(2500, 7), (300, 7), (4, 7)])
    }

    #[test]
    fn gram_is_a_transpose_a_on_any_number_of_threads() {
        for a in tall_matrices() {
            let on = |threads| {
                let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
                pool.install(|| gram(&a))
            };
            let g = on(1);
            assert_eq!(g, on(3), "{} rows", a.nrows());
            assert!((&g - a.transpose() * &a).amax() < 1e-12 * g.amax(), "{} rows", a.nrows());
        }
    }

    #[test]
    fn mul_is_the_product() {
        let a = DMatrix::from_fn(37, 5, |r, c| ((r * 5 + c) as f64).sin());
        let b = DMatrix::from_fn(5, 3, |r, c| ((r * 3 + c) as f64).cos());
        assert!((mul(&a, &b) - &a * &b).amax() < 1e-12);
    }

    /// `R` of the rows of `a` pushed in pieces of `cut` rows (all at once for 0).
    fn reduced(a: &DMatrix<f64>, cut: usize) -> DMatrix<f64> {
        let mut reducer = RowReducer::new(a.ncols());
        let cut = if cut == 0 { a.nrows().max(1) } else { cut };
        for first in (0..a.nrows()).step_by(cut) {
            let rows = a.rows(first, cut.min(a.nrows() - first)).clone_owned();
            reducer.push(rows.as_slice());
        }
        reducer.finish()
    }

    /// Tall, square, short and single-row matrices, gathered blocks whole and cut short.
    fn shapes() -> Vec<DMatrix<f64>> {
        matrices(&[(3 * REDUCE_ROWS, 7), (1000, 43), (300, 13), (7, 7), (4, 7), (1, 5)])
    }

    /// `R` is the triangular factor of a Householder QR of `A`: upper triangular, `R^T R =
    /// A^T A`, and of a tall `A` each row faer's QR's up to its sign, to rounding.
    #[test]
    fn the_row_reduction_is_the_qr_factor() {
        for a in shapes() {
            let r = reduced(&a, 0);
            let n = a.ncols();
            assert!((0..n).all(|j| (j + 1..n).all(|i| r[(i, j)] == 0.0)), "upper triangular");
            let gram = a.transpose() * &a;
            assert!((r.transpose() * &r - &gram).amax() < 1e-13 * gram.amax(), "{:?}", a.shape());
            let qr = faer::MatRef::from_column_major_slice(a.as_slice(), a.nrows(), n).qr();
            let faer_r = qr.R();
            if a.nrows() < n {
                continue; // Fewer rows than columns: R's rows are not unique.
            }
            for i in 0..n {
                let sign = if (r[(i, i)] < 0.0) == (faer_r[(i, i)] < 0.0) { 1.0 } else { -1.0 };
                for j in i..n {
                    let close = (r[(i, j)] - sign * faer_r[(i, j)]).abs() < 1e-12 * r.amax();
                    assert!(close, "{:?}: ({i}, {j}) {} against {}", a.shape(), r[(i, j)], faer_r[(i, j)]);
                }
            }
        }
    }

    /// The bits depend on the rows alone: pushed at once, one by one or in uneven pieces.
    #[test]
    fn the_row_reduction_is_the_same_however_the_rows_are_cut() {
        for a in shapes() {
            let whole = reduced(&a, 0);
            for cut in [1, 5, REDUCE_ROWS - 1, REDUCE_ROWS + 3] {
                assert_eq!(reduced(&a, cut), whole, "{:?} in pieces of {cut}", a.shape());
            }
        }
    }

    /// The same bits with the machine's vector instructions as without any.
    #[test]
    fn the_row_reduction_is_the_same_without_vector_instructions() {
        use pulp::WithSimd;
        for a in shapes() {
            let (m, n) = a.shape();
            let ld = n + m;
            let mut work = vec![0.0; ld * n];
            for (into, column) in work.chunks_exact_mut(ld).zip(a.as_slice().chunks_exact(m)) {
                into[n..].copy_from_slice(column);
            }
            let mut scalar = work.clone();
            pulp::Arch::new().dispatch(Reduction { work: &mut work, ld, n, m });
            Reduction { work: &mut scalar, ld, n, m }.with_simd(pulp::Scalar::new());
            assert_eq!(work, scalar, "{:?}", a.shape());
        }
    }

    /// Rows of entries near the ends of the floating-point range are reduced without overflow
    /// or underflow: `R(s A) = s R(A)` for `s` of 1e-200 and 1e200; a zero column stays zero.
    #[test]
    fn the_row_reduction_keeps_its_digits_at_extreme_scales() {
        let a = &shapes()[1];
        let r = reduced(a, 0);
        for s in [1e-200, 1e200] {
            let scaled = reduced(&(a * s), 0) / s;
            assert!(scaled.iter().all(|x| x.is_finite()), "scale {s}");
            assert!((scaled - &r).amax() < 1e-12 * r.amax(), "scale {s}");
        }
        let mut zero_column = a.clone();
        zero_column.column_mut(3).fill(0.0);
        let r = reduced(&zero_column, 0);
        assert!(r.column(3).iter().all(|&x| x == 0.0) && r.row(3).iter().all(|&x| x == 0.0));
    }

    /// The SVD by the transpose, the fallback where faer's iteration fails on `a`: the same
    /// factors as of `a` itself.
    #[test]
    fn the_svd_of_the_transpose_is_the_svd() {
        for a in tall_matrices() {
            let direct = thin_svd(&a).unwrap();
            let Svd { u: v, s, v: u } = thin_svd(&a.transpose()).unwrap();
            let back = &u * DMatrix::from_diagonal(&DVector::from_column_slice(&s)) * v.transpose();
            let error = (back - &a).amax();
            assert!(error < 1e-12 * s[0], "{:?}: {error:e} of {}", a.shape(), s[0]);
            assert!(s.iter().zip(&direct.s).all(|(x, y)| (x - y).abs() < 1e-13 * direct.s[0]));
        }
    }
}
