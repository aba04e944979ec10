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
//! so that every `s` costs `O(p)` once `G'` is decomposed.
//!
//! # One scale per class
//!
//! With a scale `s_c` for each class `c` of the scaled columns (a preset's lengths, angles,
//! zeros, plays: [`Evidence::with_classes`]), the prior is `x_X ~ N(0, T D T)`,
//! `T = diag(s_c(j))` (block-diagonal by class), and with `M = D^{1/2} G' D^{1/2}`,
//! `u = T D^{1/2} h'`:
//!
//! ```text
//! log det(I + A_X T D T A_X^T) = log det(I_p + T M T)                   (log_det_of)
//! w^T (...)^-1 w              = w'^2 - u^T (I_p + T M T)^-1 u           (quadratic_of)
//! ```
//!
//! a Cholesky factorisation of a `p x p` matrix for each vector of scales
//! ([`Evidence::log_evidence_of`]); with every `s_c = s` it is the one-scale evidence. The
//! scales are chosen by coordinate ascent on a log grid ([`Evidence::class_ascent`]): each
//! class's scale in turn set to the grid point of the largest evidence, the others held,
//! until a sweep changes none. Each step cannot lower the evidence and the grid is finite, so
//! it stops, at a point no single class's move improves (a coordinate-wise maximum on the
//! grid, of spacing `2^(1/8)`: 9%, well inside what a handful of parameters can tell).
//!
//! A column with a fixed Gaussian prior
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
    /// `M = D^{1/2} G' D^{1/2}` over the scaled columns.
    m: DMatrix<f64>,
    /// `D^{1/2} h'` over the scaled columns.
    hd: DVector<f64>,
    /// The class of each scaled column (all 0 for one scale).
    classes: Vec<usize>,
}

/// Sweeps of [`Evidence::class_ascent`] at most (each moves every class once); it stops
/// earlier, as soon as a sweep moves none.
pub const MAX_SWEEPS: usize = 50;

impl Evidence {
    /// The evidence of the whitened system with Gram matrix `gram = A^T A` (`p x p`),
    /// `atw = A^T w` and `ww = |w|^2`, column `j` entering as `columns[j]`: the flat columns
    /// (and the fixed ones, after `1 / t_j^2` is added to their diagonal) projected out by the
    /// Schur complement, the rest decomposed.
    pub fn new(gram: &DMatrix<f64>, atw: &DVector<f64>, ww: f64, columns: &[Column]) -> Self {
        Self::with_classes(gram, atw, ww, columns, &vec![0; columns.len()])
    }

    /// [`Evidence::new`] with the scaled column `j` in class `classes[j]` (`0..n`; ignored for
    /// the other columns): one scale each ([`Evidence::log_evidence_of`]).
    pub fn with_classes(
        gram: &DMatrix<f64>,
        atw: &DVector<f64>,
        ww: f64,
        columns: &[Column],
        classes: &[usize],
    ) -> Self {
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
        let m = (&b + b.transpose()) * 0.5;
        let eigen = SymmetricEigen::new(m.clone());
        let hd = d.component_mul(&h);
        let g = eigen.eigenvectors.tr_mul(&hd);
        Self {
            lambda: eigen.eigenvalues.iter().map(|l| l.max(0.0)).collect(),
            g: g.iter().copied().collect(),
            residual2,
            m,
            hd,
            classes: scaled.iter().map(|&j| classes[j]).collect(),
        }
    }

    /// How many scaled columns each class `0..n` has (`n` one more than the largest class).
    pub fn class_sizes(&self) -> Vec<usize> {
        let n = self.classes.iter().max().map_or(0, |c| c + 1);
        (0..n).map(|c| self.classes.iter().filter(|&&k| k == c).count()).collect()
    }

    /// `log p(y | s_1..s_n) = -1/2 [log det(I_p + T M T) + w'^2 - u^T (I_p + T M T)^-1 u]`,
    /// `T = diag(s_c(j))`, `u = T D^{1/2} h'` (the [module documentation](self)), up to the
    /// same constant as [`Evidence::log_evidence`]: `scales[c]` is class `c`'s scale.
    pub fn log_evidence_of(&self, scales: &[f64]) -> f64 {
        let t: Vec<f64> = self.classes.iter().map(|&c| scales[c]).collect();
        let p = t.len();
        let k = DMatrix::from_fn(p, p, |i, j| t[i] * self.m[(i, j)] * t[j] + if i == j { 1.0 } else { 0.0 });
        let u = DVector::from_fn(p, |i, _| t[i] * self.hd[i]);
        let Some(cholesky) = k.cholesky() else { return f64::NEG_INFINITY };
        let log_det = 2.0 * cholesky.l().diagonal().iter().map(|l| l.ln()).sum::<f64>();
        let quadratic = self.residual2 - u.dot(&cholesky.solve(&u));
        -0.5 * (log_det + quadratic)
    }

    /// Coordinate ascent of [`Evidence::log_evidence_of`] over `grid` (see the [module
    /// documentation](self)), every class starting at `grid[start]`: each class with a column
    /// in turn moved to the grid point of the largest evidence, the others held (ties to the
    /// point it is at, then the smaller), until a sweep moves none or [`MAX_SWEEPS`]. The
    /// index in `grid` of each class's scale (`start` for a class without a column).
    pub fn class_ascent(&self, grid: &[f64], start: usize) -> Vec<usize> {
        let sizes = self.class_sizes();
        let mut at = vec![start; sizes.len()];
        for _ in 0..MAX_SWEEPS {
            let mut moved = false;
            for c in (0..sizes.len()).filter(|&c| sizes[c] > 0) {
                let curve = self.profile(grid, &at, c);
                let best = arg_max(&curve);
                if curve[best] > curve[at[c]] {
                    (at[c], moved) = (best, true);
                }
            }
            if !moved {
                break;
            }
        }
        at
    }

    /// The log evidence along `grid` for class `c`'s scale, every other class `d` at
    /// `grid[at[d]]`: the profile the ascent moves `c` on.
    pub fn profile(&self, grid: &[f64], at: &[usize], c: usize) -> Vec<f64> {
        let mut scales: Vec<f64> = at.iter().map(|&k| grid[k]).collect();
        (grid.iter())
            .map(|&s| {
                scales[c] = s;
                self.log_evidence_of(&scales)
            })
            .collect()
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
/// non-singular `m`): eigenvalues below [`FLAT_RANK_TOLERANCE`] of the largest are dropped. Of
/// no column (no flat one), the empty matrix.
fn pseudo_inverse(m: &DMatrix<f64>) -> DMatrix<f64> {
    let n = m.nrows();
    if n == 0 {
        return DMatrix::zeros(0, 0);
    }
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

    /// The evidence with a scale per class is the dense evidence whose scaled columns have
    /// their class's scale (a `Fixed` prior of `s_c d_j`), up to one constant; with every
    /// class at `s` it is the one-scale evidence.
    #[test]
    fn the_class_evidence_is_the_dense_evidence() {
        let (m, p) = (40, 7);
        let h = DMatrix::from_fn(m, p, |i, j| ((i * 11 + j * 5) as f64 * 0.29).sin() + 0.2 * j as f64);
        let y = DVector::from_fn(m, |i, _| ((i * 2) as f64 * 0.77).cos());
        let sd = [0.5, 2.0, 0.1, 1.0, 0.7];
        let columns = [
            Column::Flat,
            Column::Scaled(sd[0]),
            Column::Scaled(sd[1]),
            Column::Fixed(0.3),
            Column::Scaled(sd[2]),
            Column::Scaled(sd[3]),
            Column::Scaled(sd[4]),
        ];
        let classes = [0, 1, 0, 0, 2, 1, 2];
        let (gram, atw) = (h.transpose() * &h, h.transpose() * &y);
        let e = Evidence::with_classes(&gram, &atw, y.norm_squared(), &columns, &classes);
        assert_eq!(e.class_sizes(), vec![1, 2, 2]);
        let dense_at = |scales: [f64; 3]| {
            let fixed: Vec<Column> = (columns.iter().zip(&classes))
                .map(|(c, &k)| match c {
                    Column::Scaled(d) => Column::Fixed(d * scales[k]),
                    other => *other,
                })
                .collect();
            dense(&h, &y, &fixed, 1.0)
        };
        let base = (e.log_evidence_of(&[1.0, 1.0, 1.0]), dense_at([1.0, 1.0, 1.0]));
        for scales in [[1.0, 0.2, 3.0], [1.0, 5.0, 0.05], [1.0, 0.7, 0.7]] {
            let small = e.log_evidence_of(&scales) - base.0;
            let full = dense_at(scales) - base.1;
            assert!((small - full).abs() < 1e-9 * (1.0 + full.abs()), "{scales:?}: {small} against {full}");
        }
        for s in [0.03, 0.5, 8.0] {
            let (one, all) = (e.log_evidence(s), e.log_evidence_of(&[s, s, s]));
            assert!((one - all).abs() < 1e-9 * (1.0 + one.abs()), "s {s}: {one} against {all}");
        }
    }

    /// Coordinate ascent ends where no class's move on the grid raises the evidence, at least
    /// as high as the best common scale; a class without a column stays where it started.
    #[test]
    fn the_ascent_ends_at_a_coordinate_maximum() {
        let (m, p) = (60, 6);
        let h = DMatrix::from_fn(m, p, |i, j| ((i * 13 + j * 7) as f64 * 0.41).sin());
        let x = DVector::from_vec(vec![4.0, -3.0, 5.0, 0.02, -0.01, 0.03]);
        let y = &h * x + DVector::from_fn(m, |i, _| 0.1 * ((i * 5) as f64 * 0.3).cos());
        let columns = [Column::Scaled(1.0); 6];
        let classes = [0, 0, 0, 2, 2, 2];
        let (gram, atw) = (h.transpose() * &h, h.transpose() * &y);
        let e = Evidence::with_classes(&gram, &atw, y.norm_squared(), &columns, &classes);
        let grid = evidence_scales();
        let one = arg_max(&grid.iter().map(|&s| e.log_evidence(s)).collect::<Vec<_>>());
        let at = e.class_ascent(&grid, one);
        assert_eq!(at[1], one);
        let best = e.log_evidence_of(&at.iter().map(|&k| grid[k]).collect::<Vec<_>>());
        assert!(best >= e.log_evidence(grid[one]));
        for c in [0, 2] {
            let curve = e.profile(&grid, &at, c);
            assert!(curve.iter().all(|l| *l <= best + 1e-9), "class {c}");
        }
        // The large class's scale far above the small one's.
        assert!(grid[at[0]] > 20.0 * grid[at[2]], "{} against {}", grid[at[0]], grid[at[2]]);
    }
}
