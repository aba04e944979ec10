//! The one place robocal calls faer: a singular value decomposition that stays accurate for
//! rank-deficient matrices (nalgebra's returned a reconstruction error of 2e-3 on an exactly
//! rank-deficient 5 x 5 triangular matrix; see the test below). faer is built single-threaded
//! (`default-features = false`), so it composes with rayon. faer does not truncate small
//! singular values: the rank decision is the caller's.

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

/// Rows a [`RowReducer`] gathers below its triangular factor before each QR: enough for
/// faer's blocked Householder QR to run at speed, few enough to stay in cache.
const REDUCE_ROWS: usize = 512;

/// The triangular factor `R` (`n x n`) of a tall matrix whose rows are pushed block by block,
/// never held together: the rows gathered so far are stacked below `R` and `[R; rows]` is
/// reduced to its own `R` by a Householder QR in place (a tall-skinny QR), every
/// [`REDUCE_ROWS`] rows. The arithmetic depends only on the sequence of rows pushed, not on
/// how it is cut into pushes, and nothing is allocated after [`RowReducer::new`]. `R^T R =
/// A^T A` and `R` has the singular values and right singular vectors of `A`, to rounding of
/// the QR of `A` itself (unlike the Gram matrix, whose rounding is that of `A`'s condition
/// number squared).
pub(crate) struct RowReducer {
    columns: usize,
    /// `[R; rows gathered]`, `(n + REDUCE_ROWS) x n`.
    work: faer::Mat<f64>,
    /// The Householder coefficients of the last QR (not used after it).
    coefficients: faer::Mat<f64>,
    buffer: faer::dyn_stack::MemBuffer,
    /// Rows gathered below `R`.
    filled: usize,
}

impl RowReducer {
    /// A reducer of rows of `columns` entries, with `R = 0`.
    pub fn new(columns: usize) -> Self {
        use faer::linalg::qr::no_pivoting::factor;
        let rows = columns + REDUCE_ROWS;
        let block = factor::recommended_block_size::<f64>(rows, columns).max(1);
        let scratch =
            factor::qr_in_place_scratch::<f64>(rows, columns, block, faer::Par::Seq, Default::default());
        Self {
            columns,
            work: faer::Mat::zeros(rows, columns),
            coefficients: faer::Mat::zeros(block, columns.max(1)),
            buffer: faer::dyn_stack::MemBuffer::new(scratch),
            filled: 0,
        }
    }

    /// Push the rows of `block`, a column-major `rows x n` slice (`rows = block.len() / n`).
    pub fn push(&mut self, block: &[f64]) {
        let n = self.columns;
        if n == 0 {
            return;
        }
        let rows = block.len() / n;
        let mut done = 0;
        while done < rows {
            if self.filled == REDUCE_ROWS {
                self.reduce();
            }
            let take = (rows - done).min(REDUCE_ROWS - self.filled);
            for (j, column) in block.chunks_exact(rows).enumerate() {
                self.work.col_as_slice_mut(j)[n + self.filled..n + self.filled + take]
                    .copy_from_slice(&column[done..done + take]);
            }
            self.filled += take;
            done += take;
        }
    }

    /// `[R; rows gathered]` reduced to `R` in place.
    fn reduce(&mut self) {
        use faer::linalg::qr::no_pivoting::factor;
        let n = self.columns;
        if self.filled == 0 {
            return;
        }
        let rows = n + self.filled;
        let stack = faer::dyn_stack::MemStack::new(&mut self.buffer);
        factor::qr_in_place(
            self.work.as_mut().subrows_mut(0, rows),
            self.coefficients.as_mut(),
            faer::Par::Seq,
            stack,
            Default::default(),
        );
        // The Householder vectors below the diagonal are not part of R.
        for j in 0..n {
            for i in j + 1..n {
                self.work[(i, j)] = 0.0;
            }
        }
        self.filled = 0;
    }

    /// `R` of every row pushed (`n x n`, upper triangular; zero rows where fewer rows than
    /// columns were pushed).
    pub fn finish(mut self) -> nalgebra::DMatrix<f64> {
        self.reduce();
        let n = self.columns;
        nalgebra::DMatrix::from_fn(n, n, |i, j| if i <= j { self.work[(i, j)] } else { 0.0 })
    }
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

/// The thin SVD of `a`, or `None` if the iteration did not converge.
pub(crate) fn svd(a: &DMatrix<f64>) -> Option<Svd> {
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

    /// Several row parts (2500 rows), a single part, and fewer rows than columns.
    fn tall_matrices() -> Vec<DMatrix<f64>> {
        [(2500, 7), (300, 7), (4, 7)]
            .into_iter()
            .map(|(m, n)| {
                DMatrix::from_fn(m, n, |r, c| ((r * 7 + c * 3) as f64 * 0.61).sin() * (c + 1) as f64)
            })
            .collect()
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
}
