//! The one place robocal calls faer: a singular value decomposition that stays accurate for
//! rank-deficient matrices (nalgebra's returned a reconstruction error of 2e-3 on an exactly
//! rank-deficient 5 x 5 triangular matrix; see the test below). faer is built single-threaded
//! (`default-features = false`), so it composes with rayon. faer does not truncate small
//! singular values: the rank decision is the caller's.

use nalgebra::DMatrix;

/// `a^T b` by faer's blocked product: nalgebra's takes 6.5 ms for a 6000 x 30 Gram matrix.
pub(crate) fn tr_mul(a: &DMatrix<f64>, b: &DMatrix<f64>) -> DMatrix<f64> {
    let a_ref = faer::MatRef::from_column_major_slice(a.as_slice(), a.nrows(), a.ncols());
    let b_ref = faer::MatRef::from_column_major_slice(b.as_slice(), b.nrows(), b.ncols());
    let product = a_ref.transpose() * b_ref;
    DMatrix::from_fn(a.ncols(), b.ncols(), |i, j| product[(i, j)])
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

#[cfg(test)]
mod tests {
    use super::*;

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

    #[test]
    fn mul_is_the_product() {
        let a = DMatrix::from_fn(37, 5, |r, c| ((r * 5 + c) as f64).sin());
        let b = DMatrix::from_fn(5, 3, |r, c| ((r * 3 + c) as f64).cos());
        assert!((mul(&a, &b) - &a * &b).amax() < 1e-12);
    }

    #[test]
    fn tr_mul_is_the_transposed_product() {
        let a = DMatrix::from_fn(37, 5, |r, c| ((r * 5 + c) as f64).sin());
        let b = DMatrix::from_fn(37, 3, |r, c| ((r * 3 + c) as f64).cos());
        assert!((tr_mul(&a, &b) - a.transpose() * &b).amax() < 1e-12);
    }
}
