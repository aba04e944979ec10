//! The gauge chosen at the estimate, and chosen again while the estimate moves it.
//!
//! The gauge (which parameter of a combination the data cannot tell apart is held,
//! [`gauge_class`](super::gauge_class)) is found where the system is linearised. Found at the
//! start `x_0` (the "before" fit) alone, it depends on the start: a tool point started on the
//! last joint's axis makes that joint's offset, and what it combines with, invisible there,
//! though the fitted point, off the axis, identifies it (where the "before" fit does not
//! already move the point off the axis, as it does for an observation file's tool point). So
//! the fit is made with the start's gauge, the gauge found again at the estimate `x^`, and
//! where it keeps other parameters the fit made again from `x^` with it (what it no longer
//! keeps back at its start value), until the gauge does not change, at most [`ROUNDS`] times
//! ([`fit_regauged`]).
//!
//! **What a fitted point identifies.** A direction that the start cannot see may become visible
//! at `x^` only through fitted values that are noise or small: a height gauge's fitted base
//! tilt `t` makes the base's yaw and x, y visible to heights, the singular value of their
//! direction proportional to `t`, far above the rank tolerance; the second and third joints'
//! `d` of a PUMA, one combination on its parallel axes, part by the fitted `alpha` of a
//! fraction of a degree. Freed, such directions wander along a curved valley by thousands of
//! standard errors. Three rules keep them held:
//!
//! 1. The gauge at the estimate is found at the *settled* point `x~`,
//!
//!    ```text
//!      x~_i = x^_i    if |x^_i - x_0,i| > K s_i      (moved significantly from its start)
//!      x~_i = x_0,i   otherwise,                      K = SIGNIFICANT = 3,
//!    ```
//!
//!    `s_i = sqrt(C_ii)` the standard error of `x^_i` from the fit's covariance `C` (the
//!    posterior one with priors): what a fitted zero makes visible stays invisible. With every
//!    kept value within `K s_i` of its start, `x~ = x_0` and the start's gauge stands without a
//!    second diagnosis.
//! 2. A gauge at `x~` that keeps more than the start's is taken only if the weakest direction
//!    of what it keeps is seen at first order: the smallest singular value of its column-scaled
//!    whitened system (with the prior rows), relative to the largest,
//!
//!    ```text
//!      s_min / s_max >= tau_free = FREE_TOLERANCE = 1e-4
//!    ```
//!
//!    (the rank tolerance is 1e-10: a direction between the two is identified at the start's
//!    geometry, kept if the start keeps it, but not freed by fitted values; the parallel axes'
//!    `d` parts at 4e-5 to 5e-9 in the tests), and it frees no parameter the observations did
//!    not move at all at the start (a zero column: the instrument's geometry does not see it,
//!    as heights do not see the base's yaw; a marker file's gauge says so as a combination of
//!    no other term, or an unloaded compliance).
//! 3. A gauge at `x~` that keeps as many as the start's, other ones, is not taken: the start's
//!    choice between what is as identifiable stands (the rank-revealing pivoting swaps nearly
//!    tied columns between nearby points). A gauge that keeps fewer (what the start kept is
//!    singular at `x~`) is taken.
//!
//! Not covered: a kept set of the same size that is singular at `x~` (one direction lost, another
//! gained) keeps the start's; a direction freed with a singular value just above `tau_free` has
//! the large standard error the data give it; the linear selection path (`--select`) and the
//! feasible GLS fits keep the start's gauge.

use super::CalibrationError;
use super::diagnostics::Warning;
use crate::estimation::{Linearisation, PriorRows, Refined};

/// Times at most the gauge is found again at an estimate.
pub(crate) const ROUNDS: usize = 3;

/// The smallest singular value, relative to the largest, of the column-scaled whitened system
/// of what a gauge found at a settled point keeps, for it to free more than the start's:
/// `tau_free` of the module's criterion.
pub(crate) const FREE_TOLERANCE: f64 = 1e-4;

/// Standard errors a fitted value must move from its start by to count at the settled point
/// (`K` of the module's criterion).
pub(crate) const SIGNIFICANT: f64 = 3.0;

/// The settled point `x~` of the module's criterion, over every parameter asked for: `start`
/// (`x_0`), where each of the kept ones (`kept`, positions in `start`, in the fit's column
/// order) whose fitted value (`refined.estimate.x`) moved from its start by more than
/// [`SIGNIFICANT`] standard errors takes that value.
pub(crate) fn settled(start: &[f64], kept: &[usize], refined: &Refined) -> Vec<f64> {
    let e = &refined.estimate;
    let mut at = start.to_vec();
    for (j, &c) in kept.iter().enumerate() {
        let se = e.covariance[(j, j)].max(0.0).sqrt();
        let moved = e.x[j] - start[c];
        // A NaN standard error (no redundancy) counts every move as significant.
        let within = moved.abs() <= SIGNIFICANT * se;
        if !within {
            at[c] = e.x[j];
        }
    }
    at
}

/// The smallest singular value of the column-scaled whitened system `kept` (with the prior
/// rows `prior` below it), relative to its largest; 0 if it has none or cannot be diagnosed.
pub(crate) fn weakest(kept: &Linearisation, prior: Option<&PriorRows>) -> f64 {
    let diagnosed = match prior {
        Some(prior) => kept.with_prior(prior).diagnose(crate::estimation::RANK_TOLERANCE),
        None => kept.diagnose(crate::estimation::RANK_TOLERANCE),
    };
    let Ok(d) = diagnosed else { return 0.0 };
    let s = &d.singular_values;
    match (s.first(), d.rank) {
        (Some(&largest), r) if r > 0 && largest > 0.0 => s[r - 1] / largest,
        _ => 0.0,
    }
}

/// A gauge as the fit loop needs it: the parameters it keeps free (positions in the vector
/// of what is asked for, ascending).
pub(crate) trait Kept {
    /// The positions kept free.
    fn kept(&self) -> &[usize];

    /// The parameters held because no observation moves them (a zero column of `H`), by name.
    fn unmoved(&self) -> Vec<&str>;
}

/// What [`fit_regauged`] gives: the last gauge, its fit (every step of every round in the
/// history), what that fit's closure returned, the estimate over everything asked for, and
/// what changed.
pub(crate) struct Regauged<G, F> {
    pub(crate) gauge: G,
    pub(crate) refined: Refined,
    pub(crate) fitted: F,
    /// `None` if the start's gauge stood.
    pub(crate) change: Option<Warning>,
}

/// The fit of a calibration whose gauge is found again at its estimate (the module's
/// criterion): `fit(gauge, at, steps)` fits the parameters `gauge` keeps from `at` (the
/// values of everything asked for, those held at their start) in at most `steps` steps;
/// `gauge_at(x~)` finds the gauge at a settled point. `start` is `x_0`, `names` the names of
/// what is asked for, `limit` the steps of every round together.
pub(crate) fn fit_regauged<G: Kept, F>(
    (start, names): (&[f64], &[String]),
    gauge: G,
    limit: usize,
    mut fit: impl FnMut(&mut G, &[f64], usize) -> Result<(Refined, F), CalibrationError>,
    mut gauge_at: impl FnMut(&[f64]) -> Result<(G, f64), CalibrationError>,
) -> Result<Regauged<G, F>, CalibrationError> {
    let (mut gauge, mut at, mut history) = (gauge, start.to_vec(), Vec::new());
    let first: Vec<usize> = gauge.kept().to_vec();
    let never: Vec<usize> = {
        let unmoved = gauge.unmoved();
        (0..names.len()).filter(|&c| unmoved.contains(&names[c].as_str())).collect()
    };
    // Fewer kept; or more, none unmoved at the start, the weakest direction above the tolerance.
    let another = |(next, weakest): &(G, f64), now: &G| {
        let (n, m) = (next.kept().len(), now.kept().len());
        n < m || (n > m && *weakest >= FREE_TOLERANCE && !next.kept().iter().any(|c| never.contains(c)))
    };
    for round in 0..=ROUNDS {
        let (mut refined, fitted) = fit(&mut gauge, &at, limit.saturating_sub(history.len()))?;
        history.append(&mut refined.history);
        let again = round < ROUNDS && refined.converged && history.len() < limit;
        let settled = again.then(|| settled(start, gauge.kept(), &refined)).filter(|s| s != start);
        let next = match settled {
            Some(point) => Some(gauge_at(&point)?).filter(|g| another(g, &gauge)).map(|g| g.0),
            None => None,
        };
        let Some(next) = next else {
            refined.history = history;
            let change = changed(&first, gauge.kept(), names, round);
            return Ok(Regauged { gauge, refined, fitted, change });
        };
        // From the estimate, what the new gauge holds back at its start.
        for (j, &c) in gauge.kept().iter().enumerate() {
            at[c] = if next.kept().contains(&c) { refined.estimate.x[j] } else { start[c] };
        }
        gauge = next;
    }
    unreachable!("the last round returns")
}

/// What the gauge found at the estimate changed against the start's (`first`, `last`: the
/// positions kept), after `rounds` new gauges; `None` if nothing.
fn changed(first: &[usize], last: &[usize], names: &[String], rounds: usize) -> Option<Warning> {
    let name = |c: &usize| names[*c].clone();
    let freed: Vec<String> = last.iter().filter(|c| !first.contains(c)).map(name).collect();
    let held: Vec<String> = first.iter().filter(|c| !last.contains(c)).map(name).collect();
    (rounds > 0 && !(freed.is_empty() && held.is_empty())).then_some(Warning::GaugeMoved {
        freed,
        held,
        rounds,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::estimation::{Diagnostics, LinearEstimate};
    use nalgebra::{DMatrix, DVector};

    fn refined(x: &[f64], se: &[f64]) -> Refined {
        let covariance = DMatrix::from_diagonal(&DVector::from_iterator(se.len(), se.iter().map(|s| s * s)));
        let estimate = LinearEstimate {
            names: Vec::new(),
            x: DVector::from_column_slice(x),
            covariance,
            cost: 0.0,
            diagnostics: Diagnostics {
                rank: x.len(),
                singular_values: Vec::new(),
                condition_number: 1.0,
                identifiable: (0..x.len()).collect(),
                not_identifiable: Vec::new(),
            },
        };
        Refined { estimate, history: Vec::new(), converged: true }
    }

    /// The toy gauge: the positions kept, nothing unmoved.
    struct Toy(Vec<usize>);

    impl Kept for Toy {
        fn kept(&self) -> &[usize] {
            &self.0
        }
        fn unmoved(&self) -> Vec<&str> {
            Vec::new()
        }
    }

    /// `y_k = (a + b) u_k + t (b v_k + w_k) + e_k` with `t` true: at `t = 0` the columns of `a`
    /// and `b` are one, `b` is held; where `t` is fitted significantly away from 0 they part.
    /// Its Jacobian at `x = (a, b, t)`, its residuals, with `e_k = sigma z_k`.
    fn toy(x: &[f64], truth: &[f64], sigma: f64) -> (DMatrix<f64>, DVector<f64>) {
        let n = 40;
        let (u, v, w) = (|k: f64| 1.0 + 0.1 * k, |k: f64| (0.7 * k).sin(), |k: f64| (0.3 * k).cos());
        let f = |p: &[f64], k: f64| (p[0] + p[1]) * u(k) + p[2] * (p[1] * v(k) + w(k));
        let noise = |k: usize| sigma * ((k as f64 * 12.9898).sin() * 43758.5453).fract();
        let j = DMatrix::from_fn(n, 3, |k, c| {
            let k = k as f64;
            [u(k), u(k) + x[2] * v(k), x[1] * v(k) + w(k)][c]
        });
        let r = DVector::from_fn(n, |k, _| f(truth, k as f64) + noise(k) - f(x, k as f64));
        (j, r)
    }

    /// Gauss-Newton on the kept columns of [`toy`] from `at`; the covariance `sigma^2 (J^T J)^-1`.
    fn toy_fit(kept: &[usize], at: &[f64], truth: &[f64], sigma: f64) -> Refined {
        let mut x = at.to_vec();
        let mut jk = DMatrix::zeros(0, 0);
        for _ in 0..50 {
            let (j, r) = toy(&x, truth, sigma);
            jk = j.select_columns(kept);
            let step = jk.clone().svd(true, true).solve(&r, 1e-14).unwrap();
            kept.iter().zip(step.iter()).for_each(|(&c, d)| x[c] += d);
        }
        let covariance = (jk.transpose() * &jk).try_inverse().unwrap() * sigma * sigma;
        let mut r = refined(&kept.iter().map(|&c| x[c]).collect::<Vec<_>>(), &[]);
        r.estimate.covariance = covariance;
        r
    }

    /// The toy's gauge at `x`: `b` held where the column-scaled Jacobian has rank 2; the
    /// weakest direction of what it keeps, relative to the strongest.
    fn toy_gauge(x: &[f64]) -> (Toy, f64) {
        let (mut j, _) = toy(x, x, 0.0);
        j.column_iter_mut().for_each(|mut c| c /= c.norm());
        let s = j.singular_values();
        match s.min() > 1e-10 * s.max() {
            true => (Toy(vec![0, 1, 2]), s.min() / s.max()),
            false => (Toy(vec![0, 2]), j.select_columns(&[0, 2]).singular_values().min() / s.max()),
        }
    }

    /// Started at `t = 0`, where `b` is held: a `t` fitted 0.5 from zero (hundreds of standard
    /// errors) frees `b` and the estimate is the truth's, as from a start that sees `b`; a `t`
    /// within its noise settles back to 0 and `b` stays held.
    #[test]
    fn a_combination_the_start_cannot_part_is_freed_where_the_estimate_parts_it_significantly() {
        let names: Vec<String> = ["a", "b", "t"].map(String::from).to_vec();
        let start = [0.0, 0.0, 0.0];
        let run = |truth: [f64; 3], sigma: f64| {
            let fit = |g: &mut Toy, at: &[f64], _: usize| Ok((toy_fit(&g.0, at, &truth, sigma), ()));
            fit_regauged((&start, &names), toy_gauge(&start).0, 100, fit, |x| Ok(toy_gauge(x))).unwrap()
        };
        let truth = [1.0, 2.0, 0.5];
        let r = run(truth, 1e-3);
        assert_eq!(r.gauge.0, [0, 1, 2]);
        assert_eq!(r.change, Some(Warning::GaugeMoved { freed: vec!["b".into()], held: vec![], rounds: 1 }));
        let direct = toy_fit(&[0, 1, 2], &[0.9, 1.9, 0.4], &truth, 1e-3);
        assert!((r.refined.estimate.x.clone() - direct.estimate.x).amax() < 1e-9, "{}", r.refined.estimate.x);
        // t = 0 really, fitted within its noise: b stays held.
        let r = run([1.0, 2.0, 0.0], 1e-3);
        assert_eq!(r.gauge.0, [0, 2]);
        assert_eq!(r.change, None);
    }

    /// A value within 3 standard errors of its start goes back to it, one beyond stays; what is
    /// not kept stays at its start.
    #[test]
    fn only_significant_moves_settle() {
        let start = [1.0, 2.0, 3.0, 4.0];
        let r = refined(&[1.2, 3.5, 10.0], &[0.1, 0.1, f64::NAN]);
        assert_eq!(settled(&start, &[0, 1, 3], &r), [1.0, 3.5, 3.0, 10.0]);
        let r = refined(&[1.31, 2.29], &[0.1, 0.1]);
        assert_eq!(settled(&start, &[0, 1], &r), [1.31, 2.0, 3.0, 4.0]);
    }
}
