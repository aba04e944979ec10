//! The rank-revealing solve of the whitened problem `min |b - A x|^2` (the paper's Eqs. 4-6).
//!
//! The columns of `A` are first scaled to unit norm (`A_s = A D`): parameters come in mixed
//! units (mm, rad), and the numerical rank is only meaningful on a scale-free matrix. Its SVD
//! `A_s = U S V^T` (faer's, accurate when rank deficient) gives the rank `r`: the singular
//! values above `tolerance * s_1`. With `N = D V_null` a basis of the null space of `A` and
//! `P = I - N (N^T N)^-1 N^T` the projector onto its complement,
//!
//! - `x = P D V_r S_r^-1 U_r^T b`, the minimum-norm solution `pinv(A) b = M^+ A^T b` of
//!   Eq. 6 (exact: the scaling decides the rank, not which solution is returned);
//! - `M^+ = P G P` with `G = D V_r S_r^-2 V_r^T D`, the covariance of Eq. 5 for Gauss-Markov.
//!
//! A well-conditioned `A` (column-scaled condition number under 1e4) takes a cheaper road to
//! the same numbers: the normal equations (see [`NORMAL_EQUATIONS_CONDITION`]).
//!
//! For any weighting the covariance is the sandwich `(P G) A^T (S V S^T) A (P G)^T`, which is
//! `M^+` for Gauss-Markov and `(H^T H)^+ H^T V H (H^T H)^+` for OLS.

use super::prior::PriorRows;
use super::{EstimationError, Reduced, Whitened};
use nalgebra::{DMatrix, DVector};

/// Default relative tolerance on the singular values of the column-scaled whitened `H` below
/// which a direction counts as not identifiable. Structural redundancies give values near
/// 1e-16; the weakest real direction of the PUMA 560's 30 parameters is near 1e-1.
pub const RANK_TOLERANCE: f64 = 1e-10;

/// A direction in parameter space that no measurement sees: moving `x` along
/// `e_column + sum(coefficient * e_term)` (each in its parameter's unit) changes no prediction.
#[derive(Debug, Clone, PartialEq)]
pub struct Combination {
    /// The column (parameter) dropped from the identifiable subset.
    pub column: usize,
    /// The identifiable columns it is confounded with, and their coefficients.
    pub terms: Vec<(usize, f64)>,
}

impl Combination {
    /// The direction in words, e.g. `j1.beta - j1.theta`, given the name of each column.
    pub fn describe<S: AsRef<str>>(&self, names: &[S]) -> String {
        combination_text(names[self.column].as_ref(), self.terms.iter().map(|&(j, c)| (names[j].as_ref(), c)))
    }
}

/// A combination in words: `head` then each term `+ c name` (`- name` for a coefficient of -1),
/// coefficients to 4 significant digits.
pub fn combination_text<'n>(head: &str, terms: impl Iterator<Item = (&'n str, f64)>) -> String {
    let mut text = head.to_string();
    for (name, c) in terms {
        let sign = if c < 0.0 { '-' } else { '+' };
        if (c.abs() - 1.0).abs() < 1e-9 {
            text += &format!(" {sign} {name}");
        } else {
            text += &format!(" {sign} {} {name}", format_coefficient(c.abs()));
        }
    }
    text
}

/// `c > 0` to 4 significant digits, without trailing zeros: `20.3`, `0.006667`, `3`.
fn format_coefficient(c: f64) -> String {
    let decimals = (3 - c.log10().floor() as i32).clamp(0, 12) as usize;
    let text = format!("{c:.decimals$}");
    if text.contains('.') { text.trim_end_matches('0').trim_end_matches('.').to_string() } else { text }
}

/// Soft outcomes of a solve: what is identifiable, and how well.
#[derive(Debug, Clone, PartialEq)]
pub struct Diagnostics {
    /// Numerical rank of the column-scaled whitened `H`.
    pub rank: usize,
    /// Its singular values, largest first.
    pub singular_values: Vec<f64>,
    /// `s_1 / s_r`: how much the least identifiable direction amplifies noise.
    pub condition_number: f64,
    /// An identifiable subset of the columns, chosen by QR with column pivoting on the
    /// column-scaled whitened `H`, ties broken by column order; ascending.
    pub identifiable: Vec<usize>,
    /// One combination per column outside that subset: the null space of `H`.
    pub not_identifiable: Vec<Combination>,
}

/// A linear estimate with its uncertainty.
#[derive(Debug, Clone, PartialEq)]
pub struct LinearEstimate {
    /// The parameter of each column of `H`, by name (`j3.beta`).
    pub names: Vec<String>,
    /// The estimated parameter errors, column by column of `H` (mm, rad).
    pub x: DVector<f64>,
    /// Covariance of `x` (the sandwich; `M^+` for Gauss-Markov). Without a noise model, OLS
    /// uses `sigma^2 (H^T H)^+` with `sigma^2` from the residuals (NaN without redundancy).
    pub covariance: DMatrix<f64>,
    /// The weighted residual sum of squares `|S (y - H x)|^2`. For Gauss-Markov it is
    /// `sigma_max^2` times a chi-squared with `N_m - rank` degrees of freedom: the paper's
    /// normalisation `W = sigma_max^2 V^-1` scales it.
    pub cost: f64,
    /// Rank, singular values, identifiable subset, non-identifiable combinations.
    pub diagnostics: Diagnostics,
}

impl LinearEstimate {
    /// Standard errors: square roots of the covariance diagonal.
    pub fn standard_errors(&self) -> DVector<f64> {
        self.covariance.diagonal().map(|v| v.max(0.0).sqrt())
    }

    /// Correlations of the estimates (0 where a standard error is 0).
    pub fn correlations(&self) -> DMatrix<f64> {
        let se = self.standard_errors();
        DMatrix::from_fn(se.len(), se.len(), |i, j| {
            let d = se[i] * se[j];
            if d > 0.0 { self.covariance[(i, j)] / d } else { 0.0 }
        })
    }
}

/// `A` factored once: the linear map `b -> x` and what is needed for the covariance, so many
/// right-hand sides (Monte Carlo runs on one point set) cost one product each.
pub(crate) struct Factorised {
    /// `P D V_r S_r^-1`, `p x r`: with `U_r^T` it is `pinv(A)`, never formed for one solve.
    /// (From the normal equations: `G`, with `A^T` in place of `U_r^T`.)
    left: DMatrix<f64>,
    /// How `b` reaches `left`.
    right: Right,
    /// `P G`, `p x p`: the covariance is `(P G) C (P G)^T` for `C = A^T Cov(b) A`.
    pg: DMatrix<f64>,
    pub diagnostics: Diagnostics,
}

/// The right factor of `pinv(A) = left * right`.
enum Right {
    /// `U_r^T = U_R,r^T Q^T` with `Q` kept as Householder reflectors (`u_r` is `U_R,r`, `p x r`).
    Orthogonal { tall: Box<crate::linalg::TallSvd>, u_r: DMatrix<f64> },
    /// `A^T` (the caller's `A`), for the normal equations.
    Transpose,
    /// `U_R,r^T` of a [`Reduced`] system, whose `Q^T b` it holds (`u_r` is `p x r`).
    Triangular { u_r: DMatrix<f64> },
}

/// Factor the whitened `a` as described in the [module documentation](self).
pub(crate) fn factorise(a: &DMatrix<f64>, tolerance: f64) -> Result<Factorised, EstimationError> {
    check(a, tolerance)?;
    match factorise_well_conditioned(a, tolerance) {
        Some(factorised) => Ok(factorised),
        None => factorise_rank_revealing(a, tolerance),
    }
}

/// The sizes and the tolerance of a factorisation.
fn check(a: &DMatrix<f64>, tolerance: f64) -> Result<(), EstimationError> {
    check_sizes(a.nrows(), a.ncols(), tolerance)
}

/// [`check`] of a system of `m` rows and `p` columns.
fn check_sizes(m: usize, p: usize, tolerance: f64) -> Result<(), EstimationError> {
    if m == 0 || p == 0 {
        return Err(EstimationError::NothingToEstimate(match p {
            0 => "no parameter is selected, or none is left once those the data cannot see are held".into(),
            _ => format!("no equations for the {p} parameters"),
        }));
    }
    if !(0.0..1.0).contains(&tolerance) {
        return Err(EstimationError::Dimensions(format!("rank tolerance {tolerance}: expected 0 <= t < 1")));
    }
    Ok(())
}

/// [`factorise`] by the SVD, without trying the normal equations first: for systems that are
/// expected to be rank deficient, such as every parameter a calibration asks for.
pub(crate) fn factorise_rank_revealing(
    a: &DMatrix<f64>,
    tolerance: f64,
) -> Result<Factorised, EstimationError> {
    check(a, tolerance)?;
    let (m, p) = a.shape();
    let (scales, d) = column_scales(a);
    let tall = if m >= p {
        crate::linalg::tall_svd(a, &scales)
    } else {
        // Zero rows change no least-squares solution; they make the SVD complete.
        let mut padded = DMatrix::zeros(p, p);
        padded.rows_mut(0, m).copy_from(a);
        crate::linalg::tall_svd(&padded, &scales)
    };
    let tall = tall.ok_or(EstimationError::NoConvergence)?;
    let FromSvd { left, u_r, pg, diagnostics } = from_svd(&tall.small, &d, m, tolerance)?;
    Ok(Factorised { left, right: Right::Orthogonal { tall: Box::new(tall), u_r }, pg, diagnostics })
}

/// What [`from_svd`] finds: the parts of a [`Factorised`] but its right factor's kind.
struct FromSvd {
    /// `P D V_r S_r^-1`.
    left: DMatrix<f64>,
    /// `U_r`: the SVD's first `rank` left singular vectors.
    u_r: DMatrix<f64>,
    /// `P G`.
    pg: DMatrix<f64>,
    diagnostics: Diagnostics,
}

/// The factors of a system of `m` rows from the SVD of its column-scaled `A D` (or `R D`),
/// as [`Factorised`] holds them, with the diagnostics of the rank-revealing solve.
fn from_svd(
    svd: &crate::linalg::Svd,
    d: &DMatrix<f64>,
    m: usize,
    tolerance: f64,
) -> Result<FromSvd, EstimationError> {
    let (diagnostics, null_basis) = rank_revealed(svd, d, tolerance, &[]);
    enough_rows(m, d.nrows(), diagnostics.rank)?;
    let rank = diagnostics.rank;
    let projector = complement_projector(&null_basis)?;
    let pdv = &projector * d * svd.v.columns(0, rank);
    let inverse_s =
        DMatrix::from_diagonal(&DVector::from_iterator(rank, svd.s[..rank].iter().map(|s| 1.0 / s)));
    let left = &pdv * &inverse_s;
    let u_r = svd.u.columns(0, rank).into_owned();
    let pg = &pdv * &inverse_s * &inverse_s * svd.v.columns(0, rank).transpose() * d;
    Ok(FromSvd { left, u_r, pg, diagnostics })
}

/// A [`Reduced`] system factored as in the [module documentation](self), by the SVD of its
/// column-scaled triangular factor `R D` (`p x p`), which has the singular values and right
/// singular vectors of `A D`.
pub(crate) fn factorise_reduced(system: &Reduced, tolerance: f64) -> Result<Factorised, EstimationError> {
    let m = system.rows();
    check_sizes(m, system.parameters(), tolerance)?;
    let (svd, d) = scaled_svd(system)?;
    let FromSvd { left, u_r, pg, diagnostics } = from_svd(&svd, &d, m, tolerance)?;
    Ok(Factorised { left, right: Right::Triangular { u_r }, pg, diagnostics })
}

/// The SVD of `R D` of a reduced system, `D` its column scales (`1 / |a_j|`, 1 for a zero
/// column), with `D`.
fn scaled_svd(system: &Reduced) -> Result<(crate::linalg::Svd, DMatrix<f64>), EstimationError> {
    let scales: Vec<f64> =
        system.column_norms().into_iter().map(|n| if n > 0.0 { 1.0 / n } else { 1.0 }).collect();
    let r = system.r();
    let scaled = DMatrix::from_fn(r.nrows(), r.ncols(), |i, j| r[(i, j)] * scales[j]);
    let svd = crate::linalg::svd(&scaled).ok_or(EstimationError::NoConvergence)?;
    Ok((svd, DMatrix::from_diagonal(&DVector::from_column_slice(&scales))))
}

/// [`diagnose_rank_by_priority`] of a [`Reduced`] system, from its triangular factor;
/// refused when it has fewer rows than columns and they all count (`short` allows it: the
/// data alone of a fit anchored by priors).
pub(crate) fn diagnose_reduced(
    system: &Reduced,
    tolerance: f64,
    priority: &[u32],
    short: bool,
) -> Result<Diagnostics, EstimationError> {
    let m = system.rows();
    check_sizes(m, system.parameters(), tolerance)?;
    let (svd, d) = scaled_svd(system)?;
    let (diagnostics, _) = rank_revealed(&svd, &d, tolerance, priority);
    if !short {
        enough_rows(m, system.parameters(), diagnostics.rank)?;
    }
    Ok(diagnostics)
}

/// Refused when `m` rows of rank `rank` cannot tell `p` parameters' structure from the lack of
/// rows: fewer rows than parameters, each of them counting.
fn enough_rows(m: usize, p: usize, rank: usize) -> Result<(), EstimationError> {
    match m < p && rank >= m {
        true => Err(EstimationError::TooFewEquations { equations: m, parameters: p, rank }),
        false => Ok(()),
    }
}

/// `1 / |a_j|` for each column (1 for a zero column), as a list and as the diagonal `D`.
fn column_scales(a: &DMatrix<f64>) -> (Vec<f64>, DMatrix<f64>) {
    let scales: Vec<f64> =
        a.column_iter().map(|c| c.norm()).map(|n| if n > 0.0 { 1.0 / n } else { 1.0 }).collect();
    let d = DMatrix::from_diagonal(&DVector::from_column_slice(&scales));
    (scales, d)
}

/// Rank, identifiable subset and non-identifiable combinations from the SVD of the
/// column-scaled `A D` (`m` rows, `D = d`), with a basis of the null space of `A`.
fn rank_revealed(
    svd: &crate::linalg::Svd,
    d: &DMatrix<f64>,
    tolerance: f64,
    priority: &[u32],
) -> (Diagnostics, DMatrix<f64>) {
    let p = d.nrows();
    let largest = svd.s[0];
    let rank = svd.s.iter().take_while(|&&s| s > tolerance * largest && s > 0.0).count();
    let null_basis = d * svd.v.columns(rank, p - rank);
    // A_s = U (S V^T) with U orthonormal: S V^T has the same column norms and inner products,
    // so pivoting on it picks the same columns at p x p cost.
    let sv_t = DMatrix::from_diagonal(&DVector::from_column_slice(&svd.s)) * svd.v.transpose();
    let identifiable = pivoted_columns(&sv_t, rank, priority);
    let singular_values = svd.s.clone();
    let not_identifiable = combinations(&null_basis, &identifiable);
    let condition_number = if rank > 0 { largest / singular_values[rank - 1] } else { f64::INFINITY };
    let diagnostics = Diagnostics { rank, singular_values, condition_number, identifiable, not_identifiable };
    (diagnostics, null_basis)
}

/// Largest condition number of the column-scaled matrix for which
/// [`factorise_well_conditioned`] is used: its normal equations then lose at most 8 of 16
/// digits, and the rank is certainly full (the rank tolerance is far below `1 / 1e4`).
pub(crate) const NORMAL_EQUATIONS_CONDITION: f64 = 1e4;

/// `a` factored through its normal equations when its column-scaled condition number is under
/// [`NORMAL_EQUATIONS_CONDITION`]: `G = (A^T A)^-1` by Cholesky of the column-scaled Gram
/// matrix `D A^T A D`, so that `pinv(A) b = G A^T b` and the covariance is `G C G`. The singular
/// values of `A D` are the square roots of that Gram matrix's eigenvalues (to a relative
/// `1e-16 * kappa^2`, at most 1e-8 here). The Gram matrix costs a quarter of a Householder QR
/// of a tall `A`; `None` (use the QR) when the condition number is larger or unknown, or when
/// `tolerance` could call a singular value zero.
fn factorise_well_conditioned(a: &DMatrix<f64>, tolerance: f64) -> Option<Factorised> {
    let (m, p) = a.shape();
    if m < p {
        return None;
    }
    let gram = crate::linalg::gram(a);
    let scales = DVector::from_iterator(p, (0..p).map(|j| 1.0 / gram[(j, j)].sqrt()));
    if scales.iter().any(|s| !s.is_finite()) {
        return None;
    }
    let scaled = DMatrix::from_fn(p, p, |i, j| gram[(i, j)] * scales[i] * scales[j]);
    let mut eigenvalues: Vec<f64> = scaled.symmetric_eigenvalues().iter().copied().collect();
    eigenvalues.sort_by(|x, y| y.total_cmp(x));
    let singular_values: Vec<f64> = eigenvalues.iter().map(|l| l.max(0.0).sqrt()).collect();
    let condition_number = singular_values[0] / singular_values[p - 1];
    let full_rank = condition_number < NORMAL_EQUATIONS_CONDITION && condition_number * tolerance < 0.5;
    if !full_rank {
        return None;
    }
    let inverse = scaled.cholesky()?.inverse();
    let g = DMatrix::from_fn(p, p, |i, j| inverse[(i, j)] * scales[i] * scales[j]);
    let diagnostics = Diagnostics {
        rank: p,
        singular_values,
        condition_number,
        identifiable: (0..p).collect(),
        not_identifiable: Vec::new(),
    };
    Some(Factorised { left: g.clone(), right: Right::Transpose, pg: g, diagnostics })
}

/// `I - Q Q^T`, `Q` an orthonormal basis of the span of `N`'s columns: the orthogonal projector
/// onto their complement (`I - N (N^T N)^-1 N^T`, without forming `N^T N`). `N = D V_null` mixes
/// the column scales of `A`, which may differ by many orders (a parameter the poses barely
/// move, a mass of 1e300 kg): its columns can then be far from orthogonal, `N^T N` singular to
/// rounding or overflowing. So each column is scaled to unit norm (the span is the same) and `Q`
/// is taken from its SVD, keeping the directions of singular value above `p` rounding errors of
/// the largest (a direction below is already spanned by the others, to rounding).
fn complement_projector(null_basis: &DMatrix<f64>) -> Result<DMatrix<f64>, EstimationError> {
    let p = null_basis.nrows();
    let mut projector = DMatrix::identity(p, p);
    let mut n = null_basis.clone();
    for mut column in n.column_iter_mut() {
        // By the largest entry first, so that the norm cannot overflow.
        let largest = column.amax();
        if largest > 0.0 && largest.is_finite() {
            column /= largest;
            let norm = column.norm();
            column /= norm;
        }
    }
    if n.ncols() == 0 {
        return Ok(projector);
    }
    if n.iter().any(|x| !x.is_finite()) {
        return Err(EstimationError::NoConvergence);
    }
    let svd =
        nalgebra::SVD::try_new(n, true, false, f64::EPSILON, 10_000).ok_or(EstimationError::NoConvergence)?;
    let u = svd.u.as_ref().expect("the SVD was asked for U");
    let largest = svd.singular_values.max();
    for (i, &s) in svd.singular_values.iter().enumerate() {
        if s > largest * p as f64 * f64::EPSILON {
            let q = u.column(i);
            projector.ger(-1.0, &q, &q, 1.0);
        }
    }
    Ok(projector)
}

/// `rank` columns of `a` chosen by QR with column pivoting (greedy Gram-Schmidt on the
/// residual norms): at each step the column with the largest norm once the chosen ones are
/// projected out, norms within 1e-9 of the largest counting as ties that go to the lowest
/// column, so that every platform picks the same subset; returned ascending. With a
/// `priority` class per column, the classes are taken in turn: a column of a later class is
/// chosen only when no column of an earlier one is left independent of the chosen ones (its
/// remaining norm above `sqrt(RANK_TOLERANCE)` of its own, the columns being scaled to one).
fn pivoted_columns(a: &DMatrix<f64>, rank: usize, priority: &[u32]) -> Vec<usize> {
    let class = |j: usize| priority.get(j).copied().unwrap_or(0);
    let independent = RANK_TOLERANCE.sqrt();
    let mut work = a.clone();
    let original: Vec<f64> = work.column_iter().map(|c| c.norm_squared()).collect();
    let mut norms = original.clone();
    let mut chosen: Vec<usize> = Vec::with_capacity(rank);
    for _ in 0..rank {
        let open = |j: &usize| !chosen.contains(j);
        // the earliest class with a column still independent, else every column
        let first = (0..norms.len())
            .filter(open)
            .filter(|&j| norms[j] > independent * independent * original[j])
            .map(class)
            .min();
        let candidates = || (0..norms.len()).filter(open).filter(|&j| first.is_none_or(|c| class(j) == c));
        let best = candidates().map(|j| norms[j]).fold(0.0, f64::max);
        let pick = candidates().find(|&j| norms[j] >= best * (1.0 - 1e-9)).expect("rank <= columns");
        chosen.push(pick);
        let q = work.column(pick) / norms[pick].sqrt();
        for j in (0..norms.len()).filter(|j| !chosen.contains(j)) {
            let projection = q.dot(&work.column(j));
            work.column_mut(j).axpy(-projection, &q, 1.0);
            norms[j] = work.column(j).norm_squared();
        }
    }
    chosen.sort_unstable();
    chosen
}

/// Express the null space through the dropped columns: `B = N N_D^-1` has the identity on the
/// dropped rows, so its column i reads "dropped_i + sum(B_ji e_j) is invisible".
fn combinations(null_basis: &DMatrix<f64>, identifiable: &[usize]) -> Vec<Combination> {
    let p = null_basis.nrows();
    let dropped: Vec<usize> = (0..p).filter(|j| !identifiable.contains(j)).collect();
    if dropped.is_empty() {
        return Vec::new();
    }
    let n_d = DMatrix::from_fn(dropped.len(), dropped.len(), |i, c| null_basis[(dropped[i], c)]);
    let Some(inverse) = n_d.try_inverse() else {
        return Vec::new();
    };
    let b = null_basis * inverse;
    dropped
        .iter()
        .enumerate()
        .map(|(i, &column)| {
            let largest = b.column(i).amax();
            let terms = identifiable
                .iter()
                .filter(|&&j| b[(j, i)].abs() > 1e-9 * largest)
                .map(|&j| (j, b[(j, i)]))
                .collect();
            Combination { column, terms }
        })
        .collect()
}

/// Solve the whitened problem: estimate, covariance, cost and diagnostics, by its
/// [`Reduced`] form (as every linearisation of a [`super::Residuals`] problem).
pub(crate) fn solve(
    w: &Whitened,
    tolerance: f64,
    names: Vec<String>,
) -> Result<LinearEstimate, EstimationError> {
    let reduced = Reduced::of_whitened(&w.a, &w.b, &w.blocks, w.noise.as_ref());
    let f = factorise_reduced(&reduced, tolerance)?;
    let x = f.solve(&reduced);
    let cost = reduced.cost_after(&x);
    let covariance = f.covariance(&reduced, cost);
    Ok(LinearEstimate { names, x, covariance, cost, diagnostics: f.diagnostics })
}

impl Factorised {
    /// `pinv(A) b` of the [`Reduced`] system that was factored: `P D V_r S_r^-1 U_R,r^T z`.
    pub fn solve(&self, system: &Reduced) -> DVector<f64> {
        self.filtered(&self.projected(system))
    }

    /// `c = U_R,r^T z`: the right-hand side of the [`Reduced`] system that was factored, on the
    /// `r` identifiable directions (the left singular vectors of the column-scaled `R D`).
    pub(crate) fn projected(&self, system: &Reduced) -> DVector<f64> {
        match &self.right {
            Right::Triangular { u_r } => u_r.tr_mul(&system.z()),
            // Dense factorisations are made for their pseudoinverse (`factorise`).
            _ => unreachable!("only a factorise_reduced system is solved"),
        }
    }

    /// `P D V_r S_r^-1 c` for a projected right-hand side `c` (`r` entries): with
    /// [`Factorised::projected`], the solve; with `c` filtered (`c_i s_i^2 / (s_i^2 + lambda)`),
    /// the Levenberg-Marquardt step ([`super::trust`]).
    pub(crate) fn filtered(&self, c: &DVector<f64>) -> DVector<f64> {
        &self.left * c
    }

    /// The covariance of the solve of the [`Reduced`] system that was factored:
    /// `(P G) A^T N A (P G)^T`, `N` the covariance of `b` (the whitened noise blocks), or
    /// `sigma^2 I` with `sigma^2 = cost / (N_m - rank)` where the noise is unknown. Gauss-Markov
    /// whitening leaves `N = sigma_max^2 I`, and `A^T N A` is then `sigma_max^2 R^T R`.
    pub(crate) fn covariance(&self, system: &Reduced, cost: f64) -> DMatrix<f64> {
        let dof = system.rows().saturating_sub(self.diagnostics.rank);
        let sigma2 = if dof > 0 { cost / dof as f64 } else { f64::NAN };
        &self.pg * system.information(sigma2) * self.pg.transpose()
    }

    /// The covariance of a solve of the data rows `data` with the prior rows below them (this
    /// factorisation's system, [`super::prior`]): `(P G) (C_data + C_prior) (P G)^T`, the data
    /// rows' covariance the noise blocks (or `c^2 I` without them), the prior's
    /// [`PriorRows::information`]. For Gauss-Markov, `(H^T V^-1 H + P^2)^-1`: the posterior.
    pub(crate) fn posterior_covariance(&self, data: &Reduced, prior: &PriorRows) -> DMatrix<f64> {
        let information = data.information(prior.scale().powi(2));
        &self.pg * (information + prior.information()) * self.pg.transpose()
    }

    /// `pinv(A)` itself (`p x N_m`), for solving many right-hand sides.
    pub fn pinv(&self, a: &DMatrix<f64>) -> DMatrix<f64> {
        match &self.right {
            Right::Orthogonal { tall, u_r } => tall.q(&(u_r * self.left.transpose()), a.nrows()).transpose(),
            Right::Transpose => &self.left * a.transpose(),
            // A reduced system's rows are gone: it is factored to be solved.
            Right::Triangular { .. } => unreachable!("a factorise_reduced system has no pseudoinverse"),
        }
    }
}

#[cfg(test)]
mod projector_tests {
    use super::*;

    /// `P` is an orthogonal projector that removes every column of `n` (relative to its norm).
    fn assert_projects_out(projector: &DMatrix<f64>, n: &DMatrix<f64>) {
        assert!((projector - projector.transpose()).amax() < 1e-12, "symmetric");
        assert!((projector * projector - projector).amax() < 1e-12, "idempotent");
        for column in n.column_iter() {
            let left = projector * column;
            assert!(left.norm() <= 1e-9 * column.norm(), "{column} is left as {left}");
        }
    }

    #[test]
    fn the_complement_projector_survives_columns_parallel_to_rounding_and_overflowing_grams() {
        // Parallel once the scales are applied: N^T N is singular to rounding.
        let parallel = DMatrix::from_row_slice(3, 2, &[1e11, 1e11, 1e-5, 0.0, 0.0, 1e-3]);
        assert!((parallel.transpose() * &parallel).cholesky().is_none(), "the old way fails here");
        let projector = complement_projector(&parallel).unwrap();
        assert_projects_out(&projector, &parallel);
        // N^T N overflows.
        let huge = DMatrix::from_row_slice(3, 2, &[1e200, 0.0, 1.0, 1e180, 0.0, 1.0]);
        let projector = complement_projector(&huge).unwrap();
        assert_projects_out(&projector, &huge);
        assert!((projector[(2, 2)] - 1.0).abs() < 1e-12, "the third axis is kept: {projector}");
        // An ordinary basis: the textbook projector.
        let ordinary = DMatrix::from_row_slice(3, 1, &[1.0, 2.0, 2.0]);
        let expected = DMatrix::identity(3, 3) - &ordinary * ordinary.transpose() / 9.0;
        assert!((complement_projector(&ordinary).unwrap() - expected).amax() < 1e-15);
        assert_eq!(complement_projector(&DMatrix::zeros(3, 0)).unwrap(), DMatrix::identity(3, 3));
    }
}
