//! The marginal likelihood (evidence) of a prior's scale: type-II maximum likelihood.
//!
//! With `y = H x + e`, `e ~ N(0, V)` known, and the prior `x_X ~ N(0, s^2 D)` on some columns
//! `X` (`D` diagonal, a preset's variances), the others `F` flat (no prior), the scale `s` the
//! data make most likely maximises the restricted log evidence
//!
//! ```text
//! log p(y | s) = -1/2 [ log det(V + s^2 H_X D H_X^T) + r^T P_s r ] + const,
//! ```
//!
//! `P_s` the inverse of that covariance restricted to the error contrasts the flat columns
//! leave (their effect integrated out under a flat prior, as REML does). It is computed on the
//! small system only, never with an `N_m x N_m` matrix. Whitened by `S` (`S V S^T = I`),
//! `A = S H`, `w = S r`, the flat columns are projected out with the Schur complement of the
//! Gram matrix `G = A^T A` ([`Evidence::new`]):
//!
//! ```text
//! G' = G_XX - G_XF G_FF^+ G_FX,   h' = h_X - G_XF G_FF^+ h_F,   w'^2 = |w|^2 - h_F^T G_FF^+ h_F,
//! ```
//!
//! with `h = A^T w`. With `B^T B = D^{1/2} G' D^{1/2} = Q diag(lambda) Q^T` and
//! `g = Q^T D^{1/2} h'`, the determinant lemma and Woodbury's identity give
//!
//! ```text
//! log det(I + s^2 B B^T) = sum_i log(1 + s^2 lambda_i)                  (log_det)
//! w^T (I + s^2 B B^T)^-1 w = w'^2 - sum_i s^2 g_i^2 / (1 + s^2 lambda_i)  (quadratic)
//! ```
//!
//! so that every `s` costs `O(p)` once `G'` is decomposed. A column with a fixed Gaussian prior
//! `N(0, t^2)` (not scaled) is a flat one with the pseudo-observation `0 = x_j + N(0, t^2)`:
//! `1 / t^2` on its diagonal of `G` ([`Evidence::new`]'s `fixed`).

use nalgebra::{DMatrix, DVector, SymmetricEigen};

/// Relative size (to the largest) below which an eigenvalue of the column-scaled Gram matrix of
/// the flat columns is taken as zero in its pseudo-inverse: a singular value of `1e-6`, well
/// above the Gram matrix's rounding.
const FLAT_RANK_TOLERANCE: f64 = 1e-12;

/// How each column of the system enters the evidence.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Column {
    /// No prior: integrated out under a flat prior.
    Flat,
    /// A prior of this standard deviation, not scaled.
    Fixed(f64),
    /// A prior of this standard deviation at scale 1, scaled by `s`.
    Scaled(f64),
}

/// The evidence of a linear system as a function of the prior's scale: the eigenvalues
/// `lambda_i` of `D^{1/2} G' D^{1/2}`, the projections `g_i`, and `w'^2` (see the
/// [module documentation](self)).
#[derive(Debug, Clone, PartialEq)]
pub struct Evidence {
    lambda: Vec<f64>,
    g: Vec<f64>,
    residual2: f64,
}

impl Evidence {
    /// The evidence of the whitened system with Gram matrix `gram = A^T A` (`p x p`),
    /// `atw = A^T w` and `ww = |w|^2`, column `j` entering as `columns[j]`: the flat columns
    /// (and the fixed ones, after `1 / t_j^2` is added to their diagonal) projected out by the
    /// Schur complement, the rest decomposed.
    pub fn new(gram: &DMatrix<f64>, atw: &DVector<f64>, ww: f64, columns: &[Column]) -> Self {
        let mut gram = gram.clone();
        for (j, c) in columns.iter().enumerate() {
            if let Column::Fixed(t) = c {
                gram[(j, j)] += 1.0 / (t * t);
            }
        }
        let scaled: Vec<usize> =
            (0..columns.len()).filter(|&j| matches!(columns[j], Column::Scaled(_))).collect();
        let flat: Vec<usize> =
            (0..columns.len()).filter(|&j| !matches!(columns[j], Column::Scaled(_))).collect();
        let gff_pinv = pseudo_inverse(&gram.select_rows(&flat).select_columns(&flat));
        let gxf = gram.select_rows(&scaled).select_columns(&flat);
        let (hx, hf) = (atw.select_rows(&scaled), atw.select_rows(&flat));
        let schur = gram.select_rows(&scaled).select_columns(&scaled) - &gxf * &gff_pinv * gxf.transpose();
        let h = hx - &gxf * (&gff_pinv * &hf);
        let residual2 = ww - hf.dot(&(&gff_pinv * &hf));
        let d: DVector<f64> = DVector::from_iterator(
            scaled.len(),
            scaled.iter().map(|&j| match columns[j] {
                Column::Scaled(sd) => sd,
                _ => unreachable!("a scaled column"),
            }),
        );
        let b = DMatrix::from_fn(d.len(), d.len(), |i, k| d[i] * schur[(i, k)] * d[k]);
        let eigen = SymmetricEigen::new((&b + b.transpose()) * 0.5);
        let g = eigen.eigenvectors.tr_mul(&d.component_mul(&h));
        Self {
            lambda: eigen.eigenvalues.iter().map(|l| l.max(0.0)).collect(),
            g: g.iter().copied().collect(),
            residual2,
        }
    }

    /// `log det(I + s^2 B B^T) = sum_i log(1 + s^2 lambda_i)` (the determinant lemma).
    pub fn log_det(&self, s: f64) -> f64 {
        self.lambda.iter().map(|l| (s * s * l).ln_1p()).sum()
    }

    /// `w^T (I + s^2 B B^T)^-1 w = w'^2 - sum_i s^2 g_i^2 / (1 + s^2 lambda_i)` (Woodbury).
    pub fn quadratic(&self, s: f64) -> f64 {
        let s2 = s * s;
        self.residual2
            - self.lambda.iter().zip(&self.g).map(|(l, g)| s2 * g * g / (1.0 + s2 * l)).sum::<f64>()
    }

    /// `log p(y | s) = -1/2 [log_det(s) + quadratic(s)]`, up to a constant independent of `s`.
    pub fn log_evidence(&self, s: f64) -> f64 {
        -0.5 * (self.log_det(s) + self.quadratic(s))
    }
}

/// The scales of the marginal likelihood's grid: `2^(k/8)` for `k` from -48 to 48 (1/64 to 64,
/// steps of 9%).
pub fn evidence_scales() -> Vec<f64> {
    (-48..=48).map(|k| 2f64.powf(k as f64 / 8.0)).collect()
}

/// The index of the largest of `values` (the first of equals; 0 for none).
pub fn arg_max(values: &[f64]) -> usize {
    (0..values.len()).fold(0, |best, k| if values[k] > values[best] { k } else { best })
}

/// The Moore-Penrose inverse of the symmetric positive semi-definite `m`, column-scaled by
/// its diagonal `E` (`m^+ = E^-1 (E^-1 m E^-1)^+ E^-1` for the range's projector, exact for a
/// non-singular `m`): eigenvalues below [`FLAT_RANK_TOLERANCE`] of the largest are dropped.
fn pseudo_inverse(m: &DMatrix<f64>) -> DMatrix<f64> {
    let n = m.nrows();
    let e: Vec<f64> = (0..n).map(|i| if m[(i, i)] > 0.0 { m[(i, i)].sqrt() } else { 1.0 }).collect();
    let scaled = DMatrix::from_fn(n, n, |i, j| m[(i, j)] / (e[i] * e[j]));
    let eigen = SymmetricEigen::new(scaled);
    let largest = eigen.eigenvalues.iter().copied().fold(0.0, f64::max);
    let inverse = eigen.eigenvalues.map(|l| if l > FLAT_RANK_TOLERANCE * largest { 1.0 / l } else { 0.0 });
    let v = &eigen.eigenvectors;
    let p = v * DMatrix::from_diagonal(&inverse) * v.transpose();
    DMatrix::from_fn(n, n, |i, j| p[(i, j)] / (e[i] * e[j]))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The dense restricted log evidence of `y = H x + e`, `V = I`, flat columns `F` of `H`
    /// integrated out: `-1/2 [log det C + log det(H_F^T C^-1 H_F) + y^T P y]`, `C = I + s^2
    /// H_X D H_X^T`, `P = C^-1 - C^-1 H_F (H_F^T C^-1 H_F)^-1 H_F^T C^-1`.
    fn dense(h: &DMatrix<f64>, y: &DVector<f64>, columns: &[Column], s: f64) -> f64 {
        let m = h.nrows();
        let mut c = DMatrix::identity(m, m);
        let mut flat = Vec::new();
        for (j, col) in columns.iter().enumerate() {
            let hj = h.column(j);
            match col {
                Column::Scaled(sd) => c += hj * hj.transpose() * (s * s * sd * sd),
                Column::Fixed(t) => c += hj * hj.transpose() * (t * t),
                Column::Flat => flat.push(j),
            }
        }
        let ci = c.clone().try_inverse().unwrap();
        let hf = h.select_columns(&flat);
        let inner = hf.transpose() * &ci * &hf;
        let p = &ci - &ci * &hf * inner.clone().try_inverse().unwrap() * hf.transpose() * &ci;
        let log_det_c = c.cholesky().unwrap().l().diagonal().map(f64::ln).sum() * 2.0;
        let log_det_inner = inner.cholesky().unwrap().l().diagonal().map(f64::ln).sum() * 2.0;
        -0.5 * (log_det_c + log_det_inner + (y.transpose() * p * y)[0])
    }

    /// The small-system evidence differs from the dense one by a constant only: their
    /// differences between scales agree to 1e-9.
    #[test]
    fn the_small_system_is_the_dense_evidence() {
        let (m, p) = (40, 7);
        let h = DMatrix::from_fn(m, p, |i, j| ((i * 7 + j * 13) as f64 * 0.37).sin() + 0.1 * j as f64);
        let y = DVector::from_fn(m, |i, _| ((i * 3) as f64 * 0.91).cos());
        let columns = [
            Column::Flat,
            Column::Scaled(0.5),
            Column::Fixed(0.3),
            Column::Scaled(2.0),
            Column::Flat,
            Column::Scaled(0.1),
            Column::Scaled(1.0),
        ];
        let e = Evidence::new(&(h.transpose() * &h), &(h.transpose() * &y), y.norm_squared(), &columns);
        let base = (e.log_evidence(1.0), dense(&h, &y, &columns, 1.0));
        for s in [0.01, 0.2, 3.0, 40.0] {
            let small = e.log_evidence(s) - base.0;
            let full = dense(&h, &y, &columns, s) - base.1;
            assert!((small - full).abs() < 1e-9 * (1.0 + full.abs()), "s {s}: {small} against {full}");
        }
    }

    /// A flat column the others repeat (a gauge) leaves the evidence defined: the same as
    /// without the repeated column.
    #[test]
    fn a_repeated_flat_column_changes_nothing() {
        let (m, p) = (30, 4);
        let h = DMatrix::from_fn(m, p, |i, j| ((i * 5 + j * 11) as f64 * 0.23).sin());
        let y = DVector::from_fn(m, |i, _| (i as f64 * 0.7).cos());
        let columns = [Column::Flat, Column::Scaled(1.0), Column::Scaled(0.5), Column::Flat];
        let once = Evidence::new(&(h.transpose() * &h), &(h.transpose() * &y), y.norm_squared(), &columns);
        let mut twice_h = h.clone().insert_column(p, 0.0);
        twice_h.column_mut(p).copy_from(&(h.column(0) * 2.0));
        let mut twice_columns = columns.to_vec();
        twice_columns.push(Column::Flat);
        let twice = Evidence::new(
            &(twice_h.transpose() * &twice_h),
            &(twice_h.transpose() * &y),
            y.norm_squared(),
            &twice_columns,
        );
        for s in [0.1, 1.0, 10.0] {
            assert!((once.log_evidence(s) - twice.log_evidence(s)).abs() < 1e-8, "s {s}");
        }
    }
}
