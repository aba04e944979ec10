//! Robust fitting: iteratively reweighted least squares, a pose at a time.
//!
//! A gross error (a marker swapped, a pose recorded while the robot still moved) pulls a
//! least-squares fit towards it. A robust loss bounds that pull. Each pose `k` is judged as a
//! whole by its whitened residual norm `d_k = |S_k r_k| / c` (`S_k = c L_k^-1` the estimator's
//! whitening, `c` its normalisation: for Gauss-Markov `d_k` is the Mahalanobis norm under
//! `V_k`; for OLS `S_k = I`, `c = 1`), standardised for the `n` rows of a pose:
//!
//! ```text
//! u_k = d_k / (sigma sqrt(n)),   sigma = robust scale of the d_k (see robust_scale); for a
//!                                weighted estimator max(1, that): V_k says what is noise
//! ```
//!
//! so that a pose whose rows are all one standard deviation out has `u = 1` (for `n = 1` it is
//! the usual standardised residual). The loss gives the weight of a pose:
//!
//! ```text
//! Huber:   w(u) = min(1, k / u)            k = 1.345 by default (95% efficiency for one row)
//! Cauchy:  w(u) = 1 / (1 + (u / k)^2)      k = 2.385 by default (95% efficiency for one row)
//! ```
//!
//! and the pose's whitening is multiplied by `sqrt(w_k)`, as if its covariance were `V_k / w_k`
//! ([`crate::estimation::Weights::reweighted`]). The fit is repeated with the new weights until
//! no weight moves by more than 1e-6 ([`MAX_REWEIGHTINGS`] at most), every step of every fit
//! counted against the one limit [`RefineOptions::max_iterations`] (but the paper's one-step
//! estimate, `max_iterations = 1`, is one step a fit). Everything is sequential
//! over the weights and deterministic. The covariance reported is that of the last weighted fit
//! (the weights taken as fixed).

use crate::estimation::{
    EstimationError, Linearisation, PriorRows, RefineOptions, Refined, Residuals, Weights, linearise,
    refine_within,
};
use std::fmt;
use std::str::FromStr;

/// At most this many reweighted fits after the first.
pub const MAX_REWEIGHTINGS: usize = 50;

/// Poses whose final weight is below this are listed as down-weighted: a tenth of a
/// least-squares pose, further out than 10 times the loss's threshold (Huber) or 3 times
/// (Cauchy). Milder weights are common on clean data (OLS's rows are not alike when the joint
/// noise varies from pose to pose); every weight is in [`RobustFit::weights`].
pub const LISTED_BELOW: f64 = 0.1;

/// The loss of each pose's standardised residual `u`.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub enum Loss {
    /// Least squares: every pose weighs alike.
    #[default]
    Squared,
    /// Huber's: quadratic up to `k`, linear beyond.
    Huber(f64),
    /// Cauchy's (Lorentzian): `log(1 + (u/k)^2)`, whose weight falls to 0 for gross errors.
    Cauchy(f64),
}

impl Loss {
    /// Huber's default threshold.
    pub const HUBER_K: f64 = 1.345;
    /// Cauchy's default threshold.
    pub const CAUCHY_K: f64 = 2.385;

    /// The weight of a pose whose standardised residual is `u`.
    pub fn weight(self, u: f64) -> f64 {
        match self {
            Self::Squared => 1.0,
            Self::Huber(k) => {
                if u <= k {
                    1.0
                } else {
                    k / u
                }
            }
            Self::Cauchy(k) => 1.0 / (1.0 + (u / k).powi(2)),
        }
    }
}

impl fmt::Display for Loss {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Squared => f.write_str("squared"),
            Self::Huber(k) => write!(f, "huber:{k}"),
            Self::Cauchy(k) => write!(f, "cauchy:{k}"),
        }
    }
}

impl FromStr for Loss {
    type Err = String;

    /// `squared`, `huber`, `huber:K`, `cauchy`, `cauchy:K` (`K` above 0).
    fn from_str(s: &str) -> Result<Self, String> {
        let (name, k) = match s.split_once(':') {
            Some((name, k)) => {
                let k: f64 =
                    k.trim().parse().map_err(|_| format!("loss `{s}`: expected a number after `:`"))?;
                if !(k.is_finite() && k > 0.0) {
                    return Err(format!("loss `{s}`: expected a threshold above 0"));
                }
                (name.trim(), Some(k))
            }
            None => (s.trim(), None),
        };
        match (name, k) {
            ("squared", None) => Ok(Self::Squared),
            ("huber", k) => Ok(Self::Huber(k.unwrap_or(Self::HUBER_K))),
            ("cauchy", k) => Ok(Self::Cauchy(k.unwrap_or(Self::CAUCHY_K))),
            _ => Err(format!("unknown loss `{s}`: expected squared, huber[:K] or cauchy[:K]")),
        }
    }
}

/// What a robust fit did.
#[derive(Debug, Clone, PartialEq)]
pub struct RobustFit {
    /// The loss.
    pub loss: Loss,
    /// The final weights, in the file's order: of each training observation (its pose's:
    /// every observation made at a pose shares its weight), or for a tree of each view.
    pub weights: Vec<f64>,
    /// Reweighted fits after the first.
    pub reweightings: usize,
    /// Whether the weights settled.
    pub settled: bool,
}

impl RobustFit {
    /// The observations (a tree's views) weighted below [`LISTED_BELOW`]: their index among
    /// [`RobustFit::weights`] and their weight.
    pub fn down_weighted(&self) -> impl Iterator<Item = (usize, f64)> + '_ {
        self.weights.iter().copied().enumerate().filter(|(_, w)| *w < LISTED_BELOW)
    }
}

/// The median of `d^2 / sigma^2 ~ chi^2(n)`, by Wilson and Hilferty: `n (1 - 2 / (9 n))^3`.
fn chi_squared_median(n: usize) -> f64 {
    let n = n as f64;
    n * (1.0 - 2.0 / (9.0 * n)).powi(3)
}

/// The scale `sigma` of the per-pose norms `d_k` of `n` rows each, robust to a minority of
/// gross errors: if every row had standard deviation `sigma`, `(d_k / sigma)^2` would be
/// chi-squared with `n` degrees of freedom, so `sigma = median(d_k) / sqrt(median chi^2(n))`.
pub(crate) fn robust_scale(norms: &[f64], n: usize) -> f64 {
    if n == 0 {
        return f64::NAN;
    }
    median(norms) / chi_squared_median(n).sqrt()
}

/// The median of `values` (NaN if there are none).
fn median(values: &[f64]) -> f64 {
    if values.is_empty() {
        return f64::NAN;
    }
    // The middle one selected, not every value sorted: the lower half's largest is its
    // neighbour.
    let (mut values, odd) = (values.to_vec(), values.len() % 2 == 1);
    let mid = values.len() / 2;
    let (lower, middle, _) = values.select_nth_unstable_by(mid, f64::total_cmp);
    let below = || lower.iter().copied().max_by(f64::total_cmp).expect("an even count above 0");
    if odd { *middle } else { 0.5 * (below() + *middle) }
}

/// The fit of `problem` from `start` (linearised with `weights`), with the prior rows if any,
/// made robust by `loss` as the [module documentation](self) says; the robust fit's record,
/// unless the loss is squared.
pub(crate) fn fit(
    problem: &impl Residuals,
    weights: &Weights,
    start: Linearisation,
    options: &RefineOptions,
    prior: Option<&PriorRows>,
    loss: Loss,
) -> Result<(Refined, Option<RobustFit>), EstimationError> {
    // Every step of every reweighted fit counts against the one limit.
    let cap = options.max_iterations;
    let once = |weights: &Weights, start: Linearisation, taken: usize| {
        refine_within(problem, weights, start, options, prior, cap.saturating_sub(taken))
    };
    let mut refined = once(weights, start, 0)?;
    if loss == Loss::Squared {
        return Ok((refined, None));
    }
    let points = problem.blocks().points(problem.equations());
    let mut w = vec![1.0; points];
    let (mut reweightings, mut settled) = (0, false);
    // Every step of every reweighting, for the report's count.
    let mut history = std::mem::take(&mut refined.history);
    loop {
        let next = pose_weights(problem, weights, &refined.estimate.x, loss);
        let change = next.iter().zip(&w).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
        w = next;
        if change <= 1e-6 {
            settled = true;
            break;
        }
        // The paper's one step is one step a reweighting; otherwise the limit is spent.
        let used_up = cap > 1 && history.len() >= cap;
        if reweightings == MAX_REWEIGHTINGS || used_up {
            refined.converged &= !used_up;
            break;
        }
        reweightings += 1;
        let reweighted = weights.reweighted(&w);
        let start = linearise(problem, &reweighted, refined.estimate.x.clone())?;
        refined = once(&reweighted, start, if cap > 1 { history.len() } else { 0 })?;
        history.append(&mut refined.history);
    }
    refined.history = history;
    Ok((refined, Some(RobustFit { loss, weights: w, reweightings, settled })))
}

/// The weight of every pose of `problem` at `x` under `loss`, its residual whitened by
/// `weights` (the estimator's, not reweighted).
fn pose_weights(
    problem: &impl Residuals,
    weights: &Weights,
    x: &nalgebra::DVector<f64>,
    loss: Loss,
) -> Vec<f64> {
    let blocks = problem.blocks();
    let r = problem.evaluate_whitened(x, weights, None);
    let c = if weights.whitens() { weights.scale().unwrap_or(1.0) } else { 1.0 };
    let norms: Vec<(f64, usize)> =
        (blocks.ranges(r.len())).map(|k| (r.rows_range(k.clone()).norm() / c, k.len())).collect();
    // Each norm over its chi-squared median: the scale of the bulk whatever the points' sizes
    // (of one size, `robust_scale` itself).
    let scaled: Vec<f64> = norms.iter().map(|&(d, n)| d / chi_squared_median(n).sqrt()).collect();
    let bulk = median(&scaled);
    let sigma = if weights.whitens() { bulk.max(1.0) } else { bulk };
    norms
        .iter()
        .map(|&(d, n)| if sigma > 0.0 { loss.weight(d / (sigma * (n as f64).sqrt())) } else { 1.0 })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn losses_parse_and_weigh() {
        assert_eq!("huber".parse::<Loss>().unwrap(), Loss::Huber(1.345));
        assert_eq!("cauchy:3".parse::<Loss>().unwrap(), Loss::Cauchy(3.0));
        assert_eq!("squared".parse::<Loss>().unwrap(), Loss::Squared);
        assert!("huber:-1".parse::<Loss>().unwrap_err().contains("above 0"));
        assert!("l1".parse::<Loss>().unwrap_err().contains("expected squared, huber[:K] or cauchy[:K]"));
        assert_eq!(Loss::Huber(1.0).weight(0.5), 1.0);
        assert_eq!(Loss::Huber(1.0).weight(4.0), 0.25);
        assert_eq!(Loss::Cauchy(2.0).weight(2.0), 0.5);
    }

    /// The scale of norms of 3 rows of unit normal noise is 1, and one gross error does not
    /// move it.
    #[test]
    fn the_robust_scale_ignores_a_gross_error() {
        use rand::SeedableRng;
        use rand_distr::{Distribution, StandardNormal};
        let mut rng = rand::rngs::ChaCha8Rng::seed_from_u64(3);
        let mut norms: Vec<f64> = (0..4000)
            .map(|_| (0..3).map(|_| StandardNormal.sample(&mut rng)).map(|v: f64| v * v).sum::<f64>().sqrt())
            .collect();
        assert!((robust_scale(&norms, 3) - 1.0).abs() < 0.03, "{}", robust_scale(&norms, 3));
        norms[0] = 1e6;
        assert!((robust_scale(&norms, 3) - 1.0).abs() < 0.03);
    }
}
