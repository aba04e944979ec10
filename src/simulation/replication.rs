//! The whole study repeated with independent master seeds: how the paper's statistics vary
//! from one draw of the study to the next.
//!
//! One run of a study (its cases of `S` point sets x `m` runs, its test set) is one random
//! draw of its tables. Replication `r` (`0 <= r < R`) is the same study with the master seed
//! `seed_r` = the 64-bit word `r` of the ChaCha8 stream [`REPLICATION_STREAM`] of the study's
//! seed ([`replication_seed`]): its own point sets, real robots, noise and test set.
//! Replication `r` alone is the study run with `seed_r` ([`replication_study`]), so the
//! replications are the same run all at once, one by one, on any number of threads.
//!
//! For each case and compared estimator, replication `r` gives the table's statistics `T_r`
//! (MEAN, SD, LOWEST, HIGHEST, % > 0 of dE, [`Statistic`]). Over the `R` replications
//! ([`Replications::spread`]):
//! - their mean `Tbar = (1/R) sum_r T_r` and standard deviation
//!   `s_T = sqrt(sum_r (T_r - Tbar)^2 / (R-1))`;
//! - the central 95% range, the 2.5th and 97.5th percentiles (linear between order
//!   statistics): where one study's statistic falls 19 times in 20;
//! - where a published value `T*` falls ([`Replications::paper_percentile`]): its mid-rank
//!   `100 (#{T_r < T*} + #{T_r = T*} / 2) / R` in percent, 0 below every replication.
//!
//! And how honest one study's intervals are ([`Replications::coverage`]): the share of
//! replications whose 95% interval of MEAN (of % > 0) contains `Tbar` of MEAN (of % > 0), the
//! best estimate of the true value. For an honest interval it is 95%, within the binomial
//! `± 1.96 sqrt(0.95 x 0.05 / R)` (4.3 points at R = 100, 3.0 at R = 200); the clustered
//! intervals of [`Summary::of_sets`] are compared with intervals that take the runs as
//! independent ([`Summary::of`]).

use super::{SimulationError, Study, StudyResults, Summary, run, stats};
use rand::Rng;
use rayon::prelude::*;

/// The most replications one call runs (each is a whole study: 100 of the paper's two take
/// about a minute on two cores).
pub const MAX_REPLICATIONS: usize = 10_000;

/// The stream of the study's seed that the replications' master seeds are drawn from.
pub const REPLICATION_STREAM: u64 = u64::MAX - 2;

/// Why replications could not be run.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ReplicationError {
    /// A count of replications out of range.
    #[error("replications: from 1 to {MAX_REPLICATIONS}, found {0}")]
    Count(usize),
    /// A replication failed.
    #[error(transparent)]
    Simulation(#[from] SimulationError),
}

/// `count` if it is a count of replications one call runs (1 to [`MAX_REPLICATIONS`]).
pub fn check_replications(count: usize) -> Result<usize, ReplicationError> {
    if (1..=MAX_REPLICATIONS).contains(&count) { Ok(count) } else { Err(ReplicationError::Count(count)) }
}

/// The master seed of replication `r` of a study with seed `seed`: word `r` (64 bits) of the
/// ChaCha8 stream [`REPLICATION_STREAM`] of `seed`.
pub fn replication_seed(seed: u64, r: usize) -> u64 {
    let mut rng = super::rng(seed, REPLICATION_STREAM);
    rng.set_word_pos(2 * r as u128);
    rng.next_u64()
}

/// Replication `r` of `study`: the same study with the master seed [`replication_seed`].
pub fn replication_study(study: &Study, r: usize) -> Study {
    Study { seed: replication_seed(study.seed, r), ..study.clone() }
}

/// The statistics of the paper's tables.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Statistic {
    /// Mean dE.
    Mean,
    /// Standard deviation of dE.
    Sd,
    /// Lowest dE.
    Lowest,
    /// Highest dE.
    Highest,
    /// Share of runs with dE > 0.
    AboveZero,
}

impl Statistic {
    /// All five, in the tables' order.
    pub const ALL: [Statistic; 5] = [Self::Mean, Self::Sd, Self::Lowest, Self::Highest, Self::AboveZero];

    /// The column's name in the tables.
    pub fn name(self) -> &'static str {
        match self {
            Self::Mean => "MEAN",
            Self::Sd => "SD",
            Self::Lowest => "LOWEST",
            Self::Highest => "HIGHEST",
            Self::AboveZero => "% > 0",
        }
    }

    /// Its value in a summary.
    pub fn of(self, s: &Summary) -> f64 {
        match self {
            Self::Mean => s.mean,
            Self::Sd => s.sd,
            Self::Lowest => s.lowest,
            Self::Highest => s.highest,
            Self::AboveZero => s.above_zero,
        }
    }

    /// Its value in a published row.
    pub fn of_reference(self, r: &super::Reference) -> f64 {
        match self {
            Self::Mean => r.mean,
            Self::Sd => r.sd,
            Self::Lowest => r.lowest,
            Self::Highest => r.highest,
            Self::AboveZero => r.above_zero,
        }
    }
}

/// One replication's tables: for each case and compared estimator, dE summarised.
#[derive(Debug, Clone, PartialEq)]
pub struct Replication {
    /// Its master seed.
    pub seed: u64,
    /// `[case][e - 1]` for compared estimator `e`: the runs in their point sets.
    pub clustered: Vec<Vec<Summary>>,
    /// The same runs taken as independent (for the coverage of such intervals).
    pub independent: Vec<Vec<Summary>>,
}

impl Replication {
    /// The summaries of a study's results.
    pub fn of(study: &Study, results: &StudyResults) -> Self {
        let compared = 1..study.estimators.len();
        let each = |f: &dyn Fn(usize, usize) -> Summary| {
            (0..study.cases.len()).map(|c| compared.clone().map(|e| f(c, e)).collect()).collect()
        };
        Self {
            seed: study.seed,
            clustered: each(&|c, e| Summary::of_sets(&results.improvements_by_set(c, e))),
            independent: each(&|c, e| Summary::of(&results.improvements(c, e))),
        }
    }
}

/// How often one replication's 95% intervals contain the mean over all replications (%), and
/// how wide they are.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Coverage {
    /// Of MEAN, clustered by point set.
    pub mean_clustered: f64,
    /// Of MEAN, the runs taken as independent.
    pub mean_independent: f64,
    /// Of % > 0, clustered (Wilson on the effective sample size).
    pub share_clustered: f64,
    /// Of % > 0, the runs taken as independent (Wilson on all runs).
    pub share_independent: f64,
    /// Mean half-width of the clustered interval of MEAN.
    pub half_width_clustered: f64,
    /// Mean half-width of the interval of MEAN with the runs taken as independent.
    pub half_width_independent: f64,
    /// `1.96 s_T`: the half-width an interval of MEAN needs, from its spread over replications.
    pub half_width_needed: f64,
}

/// A study repeated with independent master seeds.
#[derive(Debug, Clone, PartialEq)]
pub struct Replications {
    /// The study's own seed, which the replications' seeds derive from.
    pub seed: u64,
    /// Every replication, in order.
    pub replications: Vec<Replication>,
}

/// Run `count` replications of `study` (1 to [`MAX_REPLICATIONS`]) in parallel, calling
/// `progress` once per finished run. The same for any number of threads.
pub fn replicate(
    study: &Study,
    count: usize,
    progress: &(dyn Fn() + Sync),
) -> Result<Replications, ReplicationError> {
    check_replications(count)?;
    let replications = (0..count)
        .into_par_iter()
        .map(|r| {
            let study = replication_study(study, r);
            Ok(Replication::of(&study, &run(&study, progress)?))
        })
        .collect::<Result<_, SimulationError>>()?;
    Ok(Replications { seed: study.seed, replications })
}

/// Shard `shard` ([`super::Shard`]) of each of `count` replications of `study`: the partial
/// results of replication `r` at index `r`, for [`StudyResults::merge`] and
/// [`Replications::of_results`].
pub fn replicate_shard(
    study: &Study,
    count: usize,
    shard: super::Shard,
    progress: &(dyn Fn() + Sync),
) -> Result<Vec<StudyResults>, ReplicationError> {
    check_replications(count)?;
    let results = (0..count)
        .into_par_iter()
        .map(|r| super::run_shard(&replication_study(study, r), shard, progress))
        .collect::<Result<_, SimulationError>>()?;
    Ok(results)
}

impl Replications {
    /// The replications of `study` from each one's whole results, in order.
    pub fn of_results(study: &Study, results: &[StudyResults]) -> Self {
        let replications = results
            .iter()
            .enumerate()
            .map(|(r, res)| Replication::of(&replication_study(study, r), res))
            .collect();
        Self { seed: study.seed, replications }
    }

    /// Statistic `statistic` of dE of compared estimator `e` in `case`, one per replication.
    pub fn values(&self, case: usize, e: usize, statistic: Statistic) -> Vec<f64> {
        self.replications.iter().map(|r| statistic.of(&r.clustered[case][e - 1])).collect()
    }

    /// The spread of a statistic over the replications.
    pub fn spread(&self, case: usize, e: usize, statistic: Statistic) -> stats::Spread {
        stats::Spread::of(&self.values(case, e, statistic))
    }

    /// Where `value` (the paper's) falls among the replications: its percentile rank (%).
    pub fn paper_percentile(&self, case: usize, e: usize, statistic: Statistic, value: f64) -> f64 {
        stats::percentile_rank(&self.values(case, e, statistic), value)
    }

    /// How often each replication's 95% intervals contain the mean over the replications.
    pub fn coverage(&self, case: usize, e: usize) -> Coverage {
        let mean = stats::mean(&self.values(case, e, Statistic::Mean));
        let share = stats::mean(&self.values(case, e, Statistic::AboveZero));
        let share_of = |f: &dyn Fn(&Replication) -> bool| {
            100.0 * self.replications.iter().filter(|r| f(r)).count() as f64 / self.replications.len() as f64
        };
        let covers_mean = |s: &Summary| (s.mean - mean).abs() <= s.ci95;
        let covers_share = |s: &Summary| (s.above_zero_ci.0..=s.above_zero_ci.1).contains(&share);
        let half_width = |f: &dyn Fn(&Replication) -> f64| {
            stats::mean(&self.replications.iter().map(f).collect::<Vec<_>>())
        };
        Coverage {
            mean_clustered: share_of(&|r| covers_mean(&r.clustered[case][e - 1])),
            mean_independent: share_of(&|r| covers_mean(&r.independent[case][e - 1])),
            share_clustered: share_of(&|r| covers_share(&r.clustered[case][e - 1])),
            share_independent: share_of(&|r| covers_share(&r.independent[case][e - 1])),
            half_width_clustered: half_width(&|r| r.clustered[case][e - 1].ci95),
            half_width_independent: half_width(&|r| r.independent[case][e - 1].ci95),
            half_width_needed: stats::Z_975 * self.spread(case, e, Statistic::Mean).sd,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn replication_seeds_are_distinct_and_fixed() {
        let seeds: Vec<u64> = (0..1000).map(|r| replication_seed(1991, r)).collect();
        let mut sorted = seeds.clone();
        sorted.sort_unstable();
        sorted.dedup();
        assert_eq!(sorted.len(), 1000);
        assert!(!seeds.contains(&1991));
        // Word r of the stream, read in order, is seed r.
        let mut rng = crate::simulation::rng(1991, REPLICATION_STREAM);
        assert!(seeds.iter().all(|&s| s == rng.next_u64()));
        assert_ne!(replication_seed(1992, 0), seeds[0]);
    }

    #[test]
    fn replication_counts_are_checked() {
        assert!(matches!(check_replications(0), Err(ReplicationError::Count(0))));
        assert_eq!(check_replications(1).unwrap(), 1);
        assert_eq!(check_replications(MAX_REPLICATIONS).unwrap(), MAX_REPLICATIONS);
        assert_eq!(
            check_replications(MAX_REPLICATIONS + 1).unwrap_err().to_string(),
            "replications: from 1 to 10000, found 10001"
        );
    }
}
