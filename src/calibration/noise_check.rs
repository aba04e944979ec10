//! Whether the noise given agrees with the residuals (`calibrate` with a noise model): the
//! joint and measurement variance components estimated by REML about the fit
//! ([`crate::estimation::reml`]), and where a sigma is off by more than a factor
//! [`NOISE_FACTOR`], a [`Warning::NoiseDisagrees`] with the k-fold cross-validated error at the
//! sigmas given and at the estimated ones, and how far the estimate moves between them in its
//! standard errors (linearised about the fit: no refit). The weights and every prior's
//! strength follow the sigmas, so a guess off by a factor may move the estimate; the warning
//! says whether it does. The check is made under any loss: a point whose whitened residual is
//! far beyond the others' is left out of it ([`OUTLIER_FACTOR`]), as a robust loss leaves it
//! out of the fit.

use super::Warning;
use super::diagnostics::NoiseDisagrees;
use crate::estimation::Residuals;
use crate::estimation::reml::{ComponentEstimate, Components, Point};
use nalgebra::{DMatrix, DVector};

/// A sigma off by more than this factor (either way) is warned of.
pub const NOISE_FACTOR: f64 = 2.0;

/// The likelihood ratio above which the residuals reject the ratio of the joint to the
/// measurement variance given (chi-square, one degree of freedom, 95%); below it both sigmas
/// are taken as off by the whitened residual's factor alone.
pub const RATIO_REJECTED: f64 = 3.841_458_820_694_124;

/// Folds of the cross-validated error the warning gives.
pub const CHECK_FOLDS: usize = 5;

/// Residual degrees of freedom below which nothing is checked: too few to tell.
pub(crate) const MIN_DOF: usize = 10;

/// The poses the check reads at most: every `n / CHECK_POSES`-th (rounded up) of more. A
/// factor 2 in a sigma shows in far fewer residuals (a variance is
/// within about 8% of its value at 120 poses of 3 rows), and the check then costs the same on any campaign.
pub const CHECK_POSES: usize = 120;

/// The check of the noise of `components` (the fit's points linearised about its estimate `x`,
/// with the priors' standard deviations `prior_sd`): `None` when it agrees; else the
/// [`Warning::NoiseDisagrees`] with the cross-validated error of the rows, each counting its
/// `share` of an error ([`Components::cv_rms`]).
pub(crate) fn check(
    components: &Components,
    (x, prior_sd): (&DVector<f64>, &[f64]),
    share: &dyn Fn(usize, usize) -> f64,
) -> Option<Warning> {
    let estimate = components.estimate()?;
    let (joint, measurement) = factors(&estimate, components.has_joint_noise());
    let off = |f: f64| !(1.0 / NOISE_FACTOR..=NOISE_FACTOR).contains(&f);
    if !(off(measurement) || joint.is_some_and(off)) {
        return None;
    }
    let folds = CHECK_FOLDS.min(components.points());
    let cv = |a: f64, b: f64| components.cv_rms((a, b), folds, (x, prior_sd), share);
    let estimated = (joint.map_or(1.0, |f| f * f), measurement * measurement);
    Some(Warning::NoiseDisagrees(NoiseDisagrees {
        joint_factor: joint,
        measurement_factor: measurement,
        whitened_sd: estimate.whitened.sqrt(),
        folds,
        cv_given: cv(1.0, 1.0)?,
        cv_estimated: cv(estimated.0, estimated.1)?,
        estimate_shift: components.estimate_shift(estimated, (x, prior_sd))?,
    }))
}

/// `problem`'s identification Jacobian `H` and residuals `y` at its estimate `x`, with its
/// stacked covariance blocks `V_k`; `None` with fewer than [`MIN_DOF`] residual degrees of
/// freedom (too few to tell) or no covariance.
pub(crate) fn at_estimate<'p>(
    problem: &'p impl Residuals,
    x: &DVector<f64>,
) -> Option<(DMatrix<f64>, DVector<f64>, &'p DMatrix<f64>)> {
    if problem.equations() < problem.parameters() + MIN_DOF {
        return None;
    }
    let mut h = DMatrix::zeros(problem.equations(), problem.parameters());
    let y = problem.evaluate(x, Some(&mut h));
    Some((h, y, problem.covariance()?))
}

/// The sigmas' factors the residuals say, `(joint, measurement)`: `sqrt(a)` and `sqrt(b)` where
/// the ratio given is rejected ([`RATIO_REJECTED`]), else the whitened residual's `sqrt(b(1))`
/// for both; no joint factor without joint noise.
fn factors(estimate: &ComponentEstimate, joint_noise: bool) -> (Option<f64>, f64) {
    let both = estimate.whitened.sqrt();
    match (joint_noise, estimate.likelihood_ratio > RATIO_REJECTED) {
        (false, _) => (None, both),
        (true, true) => (Some(estimate.joint.sqrt()), estimate.measurement.sqrt()),
        (true, false) => (Some(both), both),
    }
}

/// A point whose whitened residual per row, `q_k = r_k^T V_k^-1 r_k / rows`, exceeds this many
/// times the median of the points' is left out of the check: one gross outlier would otherwise
/// say the noise is larger (it is warned of as far out on its own).
pub const OUTLIER_FACTOR: f64 = 25.0;

/// `points` without those whose `q_k` exceeds [`OUTLIER_FACTOR`] times the median `q` (the
/// noise as given, `V_k = V_q,k + V_m,k`); a point whose `V_k` is not positive definite is kept
/// (the check then declines).
/// Each point comes with what its caller keeps of it (`T`).
pub(crate) fn without_outliers<T>(points: Vec<(Point, T)>) -> Vec<(Point, T)> {
    let q: Vec<f64> = (points.iter())
        .map(|(p, _)| {
            let v = &p.joint + &p.measurement;
            let whitened = v.cholesky().and_then(|l| l.l().solve_lower_triangular(&p.r));
            whitened.map_or(0.0, |w| w.norm_squared() / p.r.len().max(1) as f64)
        })
        .collect();
    let mut sorted = q.clone();
    sorted.sort_by(f64::total_cmp);
    let median = sorted.get(sorted.len() / 2).copied().unwrap_or(0.0);
    (points.into_iter().zip(q)).filter(|(_, q)| *q <= OUTLIER_FACTOR * median).map(|(p, _)| p).collect()
}
