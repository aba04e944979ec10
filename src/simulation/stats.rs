//! Summaries of a sample, in the paper's format (MEAN, SD, LOWEST, HIGHEST, % ABOVE ZERO), with
//! confidence intervals that respect how the sample was drawn: runs in point sets.
//!
//! The runs of one point set share `H` and the `V_k`, so they are correlated; the sets are
//! independent. With `S` sets of `m` runs (`n = S m`), set means `xbar_s` and set shares
//! `p_s` of values above zero:
//!
//! - the mean is the mean of the set means, `xbar = (1/S) sum_s xbar_s` (with equal sets, the
//!   mean of all runs), and its 95% interval is `xbar ± t(0.975, S-1) s_b / sqrt(S)`,
//!   `s_b^2 = sum_s (xbar_s - xbar)^2 / (S-1)` the between-set variance
//!   ([`clustered_half_width`]);
//! - the share above zero `p = (1/S) sum_s p_s` has the clustered variance
//!   `v = s_b^2(p_s) / S`; against the variance of `n` independent runs,
//!   `p (1-p) / (n-1)`, it makes the design effect `deff`, and `n_eff = n / deff` runs
//!   (at most `n`; `n` when `p` is 0 or 1) enter Wilson's score interval with the normal
//!   quantile `z = 1.96` (the design-effect Wilson interval of Dean and Pagano 2015;
//!   [`effective_sample_size`], [`wilson_interval`]). Korn and Graubard's further
//!   `t(0.975, S-1)` for `z` over-covers here: 99-100% instead of 95% in the coverage test of
//!   the study's replications, where `z` gives 95-96.5%.
//!
//! A sample of independent values is the special case of sets of one run: `S = n`, the
//! classic `t(0.975, n-1) sd / sqrt(n)` and Wilson's interval on `n` runs.

/// A sample summarised as the paper's tables do, with 95% confidence intervals of the mean and
/// of the share above zero, clustered by point set.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Summary {
    /// Number of values.
    pub n: usize,
    /// Number of point sets (independent clusters) they come in.
    pub sets: usize,
    /// Mean of the set means (with equal sets, the mean of all values).
    pub mean: f64,
    /// Sample standard deviation of all values (divisor n - 1).
    pub sd: f64,
    /// Smallest value.
    pub lowest: f64,
    /// Largest value.
    pub highest: f64,
    /// Share of values above zero (%).
    pub above_zero: f64,
    /// Half-width of the 95% confidence interval of the mean, from the between-set spread:
    /// [`clustered_half_width`] of the set means.
    pub ci95: f64,
    /// The 95% interval of the share above zero (%): Wilson's, on the clustered effective
    /// sample size.
    pub above_zero_ci: (f64, f64),
}

impl Summary {
    /// Summarise independent `values` (at least two): each value is its own set.
    pub fn of(values: &[f64]) -> Self {
        let sets: Vec<Vec<f64>> = values.iter().map(|&v| vec![v]).collect();
        Self::of_sets(&sets)
    }

    /// Summarise values that come in point sets (none empty): the values of a set are
    /// correlated, the sets independent. With one set the intervals are NaN: it says nothing
    /// of how sets vary.
    pub fn of_sets(sets: &[Vec<f64>]) -> Self {
        let all: Vec<f64> = sets.iter().flatten().copied().collect();
        let n = all.len();
        let set_means: Vec<f64> = sets.iter().map(|s| mean(s)).collect();
        let above = |v: &f64| *v > 0.0;
        let set_shares: Vec<f64> =
            sets.iter().map(|s| s.iter().filter(|v| above(v)).count() as f64 / s.len() as f64).collect();
        let share = mean(&set_shares);
        let n_eff = effective_sample_size(share, variance(&set_shares) / sets.len() as f64, n);
        // One set says nothing of how sets vary: no interval.
        let (low, high) =
            if sets.len() < 2 { (f64::NAN, f64::NAN) } else { wilson_interval(share, n_eff, Z_975) };
        Self {
            n,
            sets: sets.len(),
            mean: mean(&set_means),
            sd: variance(&all).sqrt(),
            lowest: all.iter().copied().fold(f64::INFINITY, f64::min),
            highest: all.iter().copied().fold(f64::NEG_INFINITY, f64::max),
            above_zero: 100.0 * share,
            ci95: clustered_half_width(&set_means),
            above_zero_ci: (100.0 * low, 100.0 * high),
        }
    }
}

/// The spread of one statistic over replications: mean, SD and the central 95% range.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Spread {
    /// Mean over the replications.
    pub mean: f64,
    /// Standard deviation over the replications (divisor R - 1; NaN for one replication).
    pub sd: f64,
    /// 2.5th percentile ([`percentile`]).
    pub low: f64,
    /// 97.5th percentile.
    pub high: f64,
}

impl Spread {
    /// The spread of `values` (at least one).
    pub fn of(values: &[f64]) -> Self {
        Self {
            mean: mean(values),
            sd: variance(values).sqrt(),
            low: percentile(values, 2.5),
            high: percentile(values, 97.5),
        }
    }
}

/// `xbar = (1/n) sum_i x_i`.
pub fn mean(values: &[f64]) -> f64 {
    values.iter().sum::<f64>() / values.len() as f64
}

/// The sample variance `s^2 = sum_i (x_i - xbar)^2 / (n - 1)` (NaN for one value).
pub fn variance(values: &[f64]) -> f64 {
    let m = mean(values);
    values.iter().map(|v| (v - m).powi(2)).sum::<f64>() / (values.len() as f64 - 1.0)
}

/// Half-width of the 95% interval of the mean of `S` independent set means:
/// `t(0.975, S-1) s_b / sqrt(S)`, `s_b^2` their [`variance`] (the between-set variance).
pub fn clustered_half_width(set_means: &[f64]) -> f64 {
    let s = set_means.len();
    t_quantile_975(s.saturating_sub(1)) * (variance(set_means) / s as f64).sqrt()
}

/// The effective number of independent runs behind a share `p` (0-1) of `n` runs whose
/// clustered variance is `v`: `n_eff = n / deff`, `deff = v / (p (1-p) / (n-1))`, at most
/// `n`; `n` when `p` is 0 or 1 (no spread to measure a design effect by).
pub fn effective_sample_size(share: f64, clustered_variance: f64, n: usize) -> f64 {
    let n = n as f64;
    let independent = share * (1.0 - share) / (n - 1.0);
    if independent <= 0.0 || clustered_variance <= independent {
        return n;
    }
    n * independent / clustered_variance
}

/// Wilson's score interval of a share `p` (0-1) of `n` runs with quantile `z`:
/// `(p + z^2/2n ± z sqrt(p (1-p)/n + z^2/4n^2)) / (1 + z^2/n)`.
pub fn wilson_interval(share: f64, n: f64, z: f64) -> (f64, f64) {
    let z2 = z * z;
    let centre = share + z2 / (2.0 * n);
    let half = z * (share * (1.0 - share) / n + z2 / (4.0 * n * n)).sqrt();
    let scale = 1.0 + z2 / n;
    (((centre - half) / scale).max(0.0), ((centre + half) / scale).min(1.0))
}

/// The `p`-th percentile (0-100) of `values`, interpolated linearly between order statistics:
/// with `x_(0) <= ... <= x_(R-1)` and `h = (R-1) p / 100`,
/// `x_(floor h) + (h - floor h) (x_(floor h + 1) - x_(floor h))` (Hyndman and Fan's type 7).
pub fn percentile(values: &[f64], p: f64) -> f64 {
    let mut sorted = values.to_vec();
    sorted.sort_by(f64::total_cmp);
    let h = (sorted.len() - 1) as f64 * p / 100.0;
    let (below, fraction) = (h.floor() as usize, h - h.floor());
    match sorted.get(below + 1) {
        Some(&next) => sorted[below] + fraction * (next - sorted[below]),
        None => sorted[below],
    }
}

/// Where `x` falls in `values`, in percent: `100 (#{v < x} + #{v = x} / 2) / R` (the mid-rank;
/// 0 below every value, 100 above every one).
pub fn percentile_rank(values: &[f64], x: f64) -> f64 {
    let below = values.iter().filter(|&&v| v < x).count() as f64;
    let equal = values.iter().filter(|&&v| v == x).count() as f64;
    100.0 * (below + equal / 2.0) / values.len() as f64
}

/// The 0.975 quantile of the standard normal distribution.
pub const Z_975: f64 = 1.959_963_984_540_054;

/// The 0.975 quantile of Student's t with `dof` degrees of freedom, by the Cornish-Fisher
/// expansion about the normal quantile (Abramowitz and Stegun 26.7.5); within 1e-3 of the
/// exact value from 10 degrees of freedom on; from tables below that.
pub fn t_quantile_975(dof: usize) -> f64 {
    const SMALL: [f64; 10] =
        [f64::NAN, 12.7062, 4.3027, 3.1824, 2.7764, 2.5706, 2.4469, 2.3646, 2.3060, 2.2622];
    if dof < SMALL.len() {
        return SMALL[dof];
    }
    let z = Z_975;
    let v = dof as f64;
    let g1 = (z.powi(3) + z) / 4.0;
    let g2 = (5.0 * z.powi(5) + 16.0 * z.powi(3) + 3.0 * z) / 96.0;
    let g3 = (3.0 * z.powi(7) + 19.0 * z.powi(5) + 17.0 * z.powi(3) - 15.0 * z) / 384.0;
    z + g1 / v + g2 / (v * v) + g3 / (v * v * v)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: f64, b: f64, tolerance: f64) -> bool {
        (a - b).abs() < tolerance
    }

    #[test]
    fn t_quantiles_match_the_tables() {
        for (dof, t) in
            [(5, 2.5706), (9, 2.2622), (10, 2.2281), (12, 2.1788), (30, 2.0423), (95, 1.9853), (1000, 1.9623)]
        {
            assert!((t_quantile_975(dof) - t).abs() < 1e-3, "dof {dof}: {}", t_quantile_975(dof));
        }
    }

    #[test]
    fn summary_of_a_known_sample() {
        let s = Summary::of(&[-1.0, 1.0, 2.0, 6.0]);
        assert_eq!((s.n, s.sets, s.mean, s.lowest, s.highest, s.above_zero), (4, 4, 2.0, -1.0, 6.0, 75.0));
        assert!((s.sd - (26.0f64 / 3.0).sqrt()).abs() < 1e-12);
        assert!((s.ci95 - 3.1824 * s.sd / 2.0).abs() < 1e-12);
        // Independent runs: Wilson on n = 4 with z = 1.959964, by hand:
        // (0.75 + 0.480182 ± 1.959964 sqrt(0.046875 + 0.060023)) / 1.960365 = (0.30064, 0.95441).
        let (low, high) = s.above_zero_ci;
        assert!(close(low, 30.064, 0.001) && close(high, 95.441, 0.001), "{low} {high}");
    }

    #[test]
    fn one_set_has_no_interval() {
        let s = Summary::of_sets(&[vec![1.0, 2.0, 3.0]]);
        assert_eq!((s.n, s.sets, s.mean), (3, 1, 2.0));
        assert!(s.ci95.is_nan() && s.above_zero_ci.0.is_nan() && s.above_zero_ci.1.is_nan());
    }

    #[test]
    fn mean_and_variance_by_hand() {
        assert_eq!(mean(&[1.0, 2.0, 6.0]), 3.0);
        // (4 + 1 + 9) / 2
        assert_eq!(variance(&[1.0, 2.0, 6.0]), 7.0);
        assert!(variance(&[1.0]).is_nan());
    }

    #[test]
    fn clustered_half_width_by_hand() {
        // Set means 10, 14, 12: s_b^2 = (4 + 4 + 0) / 2 = 4, t(2) = 4.3027: 4.3027 * 2 / sqrt(3).
        assert!(close(clustered_half_width(&[10.0, 14.0, 12.0]), 4.3027 * 2.0 / 3f64.sqrt(), 1e-12));
    }

    #[test]
    fn the_clustered_interval_uses_the_set_means_not_the_run_count() {
        // Two sets of three runs, tight within and far apart between: the interval is the one of
        // two set means (t with 1 degree of freedom), far wider than six independent runs'.
        let sets = vec![vec![0.9, 1.0, 1.1], vec![2.9, 3.0, 3.1]];
        let s = Summary::of_sets(&sets);
        assert_eq!((s.n, s.sets), (6, 2));
        assert!(close(s.mean, 2.0, 1e-12));
        // s_b = sqrt(2), half-width 12.7062 sqrt(2) / sqrt(2).
        assert!(close(s.ci95, 12.7062, 1e-9), "{}", s.ci95);
        assert!(s.ci95 > 5.0 * Summary::of(&sets.concat()).ci95);
    }

    #[test]
    fn effective_sample_size_by_hand() {
        // p = 0.5 of n = 11: independent variance 0.25 / 10 = 0.025; clustered 0.05: deff 2.
        assert!(close(effective_sample_size(0.5, 0.05, 11), 5.5, 1e-12));
        // Less spread than independent runs, or no spread at all: n.
        assert_eq!(effective_sample_size(0.5, 0.01, 11), 11.0);
        assert_eq!(effective_sample_size(1.0, 0.0, 11), 11.0);
    }

    #[test]
    fn wilson_interval_by_hand() {
        // p = 0.8, n = 25, z = 1.96: centre 0.8 + 0.076832 = 0.876832, half
        // 1.96 sqrt(0.0064 + 0.00153664) = 0.174612, scale 1.153664: (0.608687, 0.911395).
        let (low, high) = wilson_interval(0.8, 25.0, 1.96);
        assert!(close(low, 0.608687, 1e-6) && close(high, 0.911395, 1e-6), "{low} {high}");
        // All runs above zero: the upper end is 1, the lower n / (n + z^2).
        let (low, high) = wilson_interval(1.0, 96.0, 1.96);
        assert!(close(low, 96.0 / (96.0 + 1.96 * 1.96), 1e-12) && high == 1.0);
    }

    #[test]
    fn a_clustered_share_has_a_wider_interval() {
        // Sets all above or all below zero: the share's information is in the 4 sets, not the
        // 16 runs. p = 0.5, set shares 1, 0, 1, 0: v = (1/3) / 4 = 1/12, independent
        // 0.25 / 15: n_eff = 16 (1/60) / (1/12) = 3.2, Wilson with z.
        let sets: Vec<Vec<f64>> = (0..4).map(|s| vec![if s % 2 == 0 { 1.0 } else { -1.0 }; 4]).collect();
        let s = Summary::of_sets(&sets);
        let (low, high) = wilson_interval(0.5, 3.2, Z_975);
        assert!(close(s.above_zero_ci.0, 100.0 * low, 1e-9) && close(s.above_zero_ci.1, 100.0 * high, 1e-9));
        let independent = Summary::of(&sets.concat()).above_zero_ci;
        assert!(independent.1 - independent.0 < s.above_zero_ci.1 - s.above_zero_ci.0);
    }

    #[test]
    fn percentiles_by_hand() {
        let values = [4.0, 1.0, 3.0, 2.0, 5.0];
        // h = 4 p / 100: 2.5 -> h = 0.1: 1 + 0.1; 97.5 -> h = 3.9: 4 + 0.9; 50 -> 3.
        assert!(close(percentile(&values, 2.5), 1.1, 1e-12));
        assert!(close(percentile(&values, 97.5), 4.9, 1e-12));
        assert_eq!(percentile(&values, 50.0), 3.0);
        assert_eq!(percentile(&[7.0], 97.5), 7.0);
        let s = Spread::of(&values);
        assert_eq!(s.mean, 3.0);
        assert!(close(s.sd, 2.5f64.sqrt(), 1e-12));
    }

    #[test]
    fn percentile_ranks_by_hand() {
        let values = [1.0, 2.0, 3.0, 4.0];
        assert_eq!(percentile_rank(&values, 0.5), 0.0);
        assert_eq!(percentile_rank(&values, 2.5), 50.0);
        // One below, one equal (half): 100 * 1.5 / 4.
        assert_eq!(percentile_rank(&values, 2.0), 37.5);
        assert_eq!(percentile_rank(&values, 9.0), 100.0);
    }
}
