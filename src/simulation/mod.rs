//! Monte Carlo simulation of a calibration campaign: the paper's steps 1-8.
//!
//! For each case (`N_p`, `sigma_me`) and point set:
//! 1. `N_p` joint configurations uniform within the joint limits (or, beyond the paper,
//!    planned from a pool that starts with them: [`PoseChoice`]);
//!
//! and for each run on that set:
//! 2. a "real" robot: the nominal parameters plus geometric errors (and, beyond the paper,
//!    the joints' compliances and plays of the study's `[truth]`, which no geometric
//!    parameter expresses);
//! 3. its forward kinematics at `q + n_q`, the joint noise drawn anew at every point;
//! 4. plus measurement noise `n_m`: the measured positions (or poses);
//! 5. pose errors: measured minus the nominal forward kinematics at the commanded `q`;
//! 6. `y` and `H` (at the nominal parameters; `H` and `V` are the set's, factored once);
//! 7. the estimate of every compared calibration from the same `y` (common random numbers):
//!    each an estimator, identifying the study's parameters and, as asked
//!    (`wls+compliance`), the joints' compliances and plays;
//! 8. each estimated model's position error against the real robot's noise-free kinematics
//!    over a test set of configurations separate from the measurement points: `E_p`.
//!
//! Random numbers: every stream is ChaCha8 seeded with the study's master seed, on a stream
//! number made of (`N_p`, set, run): `N_p` in bits 42 and up, the set in bits 21-41, the
//! run plus one in bits 0-20. Cases that differ only in `sigma_me` so
//! share their point sets and standard normal draws, as the paper's tables share their
//! `N_p = 48`, `sigma_me = 0` row; cases that differ only in how the poses are chosen share
//! their real robots and noise draws, so that random and planned poses compare run by run. Runs are spread over threads with rayon, and the results
//! are the same, bit for bit, for any number of threads.

pub mod instruments;
mod replication;
mod stats;
mod study;
mod synthetic;
pub mod tree;

pub use instruments::{
    EXACT_SIGMA_MM, INSTRUMENT_STUDIES, Instrument, InstrumentKind, InstrumentPart, InstrumentResults,
    InstrumentStudy, MOST_DRAWS_PER_VIEW, Scores, Sight, interval as stats_interval, is_instrument_study,
    run_instruments, run_instruments_shard,
};
pub use replication::{
    Coverage, MAX_REPLICATIONS, REPLICATION_STREAM, Replication, ReplicationError, Replications, Statistic,
    check_replications, replicate, replicate_shard, replication_seed, replication_study,
};
pub use stats::{
    Spread, Summary, Z_975, clustered_half_width, effective_sample_size, mean, percentile, percentile_rank,
    t_quantile_975, variance, wilson_interval,
};
pub use study::{
    Case, Compared, ErrorSizes, PoseChoice, Redraw, Reference, STUDIES, Study, StudyError, TrueLoads,
};
pub use synthetic::measurement_csv;

use crate::design::{Criterion, Design, DesignError};
use crate::estimation::{
    DeviceError, EstimationError, MeasurementNoise, NoiseModel, PointProblem, Prepared, RANK_TOLERANCE,
    RefineOptions, Weights, refine,
};
use crate::kinematics::{BATCH, Chain, ChainAt, Configurations, Frames, Measured, pose_error};
use crate::model::{ParamKind, ParamSet};
use nalgebra::{DMatrix, DVector, Isometry3, Matrix3, Translation3, UnitQuaternion, Vector3};
use rand::SeedableRng;
use rand::rngs::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};
use rayon::prelude::*;

/// The stream of a point set (`run = None`) or of one run: `N_p` in bits 42 and up, the set in
/// bits 21-41, the run plus one in bits 0-20.
pub(crate) fn stream(points: usize, set: usize, run: Option<usize>) -> u64 {
    ((points as u64) << 42) | ((set as u64) << 21) | run.map_or(0, |r| r as u64 + 1)
}

/// The stream of the test set.
pub(crate) const TEST_STREAM: u64 = u64::MAX;
/// The stream that measures the error caused by joint noise alone.
pub(crate) const JOINT_NOISE_STREAM: u64 = u64::MAX - 1;

fn rng(seed: u64, stream: u64) -> ChaCha8Rng {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    rng.set_stream(stream);
    rng
}

fn normal(rng: &mut ChaCha8Rng) -> f64 {
    StandardNormal.sample(rng)
}

/// A real robot's geometric errors on the parameters `indices` of `params`: normal, zero mean,
/// standard deviation `sizes.offset` for a revolute joint's offset, `sizes.angle` for every
/// other angle, `sizes.length` for every length; the others (load responses included, which
/// a study's `[truth]` sets) zero.
pub(crate) fn draw_errors(
    params: &ParamSet,
    indices: &[usize],
    sizes: &ErrorSizes,
    rng: &mut ChaCha8Rng,
) -> Vec<f64> {
    let mut x = vec![0.0; params.len()];
    for &i in indices.iter().filter(|&&i| !params.get(i).is_load_response()) {
        let p = params.get(i);
        let size = match p.kind {
            ParamKind::Theta if p.is_offset => sizes.offset,
            kind if kind.is_angle() => sizes.angle,
            _ => sizes.length,
        };
        x[i] = size * normal(rng);
    }
    x
}

/// How accurate a calibrated model is over the test set.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Accuracy {
    /// Mean position error `E_p` (mm).
    pub mean: f64,
    /// Root mean square position error (mm).
    pub rms: f64,
    /// Largest position error (mm).
    pub max: f64,
    /// Mean orientation error `E_r` (rad) when poses are measured; NaN otherwise.
    pub orientation: f64,
}

/// One run: the accuracy of every compared estimator, from the same random numbers.
#[derive(Debug, Clone, PartialEq)]
pub struct Run {
    /// Index into [`Study::cases`].
    pub case: usize,
    /// Point set within the case.
    pub set: usize,
    /// Run within the set.
    pub run: usize,
    /// One per estimator, in the study's order.
    pub accuracy: Vec<Accuracy>,
}

impl Run {
    /// `dE = 100 (E_p - E_p^w) / E_p` (the paper's Eq. 18) of estimator `e` against the
    /// baseline, the study's first estimator.
    pub fn improvement(&self, e: usize) -> f64 {
        improvement(self.accuracy[0].mean, self.accuracy[e].mean)
    }
}

/// The paper's Eq. 18: `dE = 100 (E_p - E_p^w) / E_p`, in percent.
pub fn improvement(baseline: f64, weighted: f64) -> f64 {
    100.0 * (baseline - weighted) / baseline
}

/// Everything a study produced.
#[derive(Debug, Clone, PartialEq)]
pub struct StudyResults {
    /// Every run, case by case, set by set.
    pub runs: Vec<Run>,
    /// Numerical rank of the baseline's `H` at each point set, `(case, set, rank)`.
    pub ranks: Vec<(usize, usize, usize)>,
    /// Mean end-effector position error (mm) that the joint noise alone causes, over the
    /// test set: the robot's repeatability in the paper's sense.
    pub joint_noise_error: f64,
}

impl StudyResults {
    /// The results of a study's shards ([`run_shard`]), together: as the study run whole
    /// gives them when the parts are its shards. The joint noise's error is the first part's.
    pub fn merge(parts: impl IntoIterator<Item = StudyResults>) -> Self {
        let mut merged = StudyResults { runs: Vec::new(), ranks: Vec::new(), joint_noise_error: f64::NAN };
        for (i, part) in parts.into_iter().enumerate() {
            merged.runs.extend(part.runs);
            merged.ranks.extend(part.ranks);
            if i == 0 {
                merged.joint_noise_error = part.joint_noise_error;
            }
        }
        merged.runs.sort_by_key(|r| (r.case, r.set, r.run));
        merged.ranks.sort_unstable();
        merged.ranks.dedup();
        merged
    }

    /// The dE samples of estimator `e` in case `case`.
    pub fn improvements(&self, case: usize, e: usize) -> Vec<f64> {
        self.runs.iter().filter(|r| r.case == case).map(|r| r.improvement(e)).collect()
    }

    /// The dE samples of estimator `e` in case `case`, point set by point set.
    pub fn improvements_by_set(&self, case: usize, e: usize) -> Vec<Vec<f64>> {
        let mut sets: Vec<Vec<f64>> = Vec::new();
        for r in self.runs.iter().filter(|r| r.case == case) {
            if sets.len() <= r.set {
                sets.resize(r.set + 1, Vec::new());
            }
            sets[r.set].push(r.improvement(e));
        }
        sets
    }

    /// Mean dE of estimator `e` on each point set of `case`.
    pub fn set_means(&self, case: usize, e: usize) -> Vec<f64> {
        self.improvements_by_set(case, e).iter().map(|s| stats::mean(s)).collect()
    }

    /// Mean `E_p` (mm) of estimator `e` in case `case`.
    pub fn mean_error(&self, case: usize, e: usize) -> f64 {
        let values: Vec<f64> =
            self.runs.iter().filter(|r| r.case == case).map(|r| r.accuracy[e].mean).collect();
        values.iter().sum::<f64>() / values.len() as f64
    }
}

/// One point set, ready for its runs.
struct PointSet {
    case: usize,
    set: usize,
    joints: Vec<Vec<f64>>,
    nominal: Vec<Isometry3<f64>>,
    noise: NoiseModel,
    /// One per estimator (one-step studies only).
    prepared: Vec<Prepared>,
    /// The real robot's errors when drawn once per set.
    errors: Option<Vec<f64>>,
    rank: usize,
    /// With a device: the Cholesky factor of each point's measurement covariance (position).
    factors: Vec<Matrix3<f64>>,
}

/// The test set and the study's compiled robot.
struct Bench<'a> {
    study: &'a Study,
    chain: Chain,
    nominal: ChainAt,
    /// The real robot before its geometric errors (with the true compliances and plays),
    /// indexed as `chain`.
    real: Chain,
    /// The parameters each compared calibration identifies.
    selections: Vec<crate::model::Selection>,
    test: Vec<Vec<f64>>,
    /// The test set, its joints' sines and cosines computed once.
    test_trig: Configurations,
}

/// Why a study could not be run.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum SimulationError {
    /// The study's values make no study (checked again here, since its fields are public).
    #[error(transparent)]
    Study(#[from] StudyError),
    /// An estimate could not be computed.
    #[error(transparent)]
    Estimation(#[from] EstimationError),
    /// The poses of a planned case could not be planned.
    #[error("planning the poses")]
    Design(#[from] DesignError),
    /// A calibration of an instrument study failed.
    #[error("calibrating a simulated run")]
    Calibration(#[from] crate::calibration::CalibrationError),
    /// The measuring device cannot give the covariance at a measurement point.
    #[error("the study's measuring device")]
    Device(#[from] DeviceError),
}

/// One part of a study's work, for spreading it over processes or machines: shard `index` of
/// `count` (from 0) computes the runs `index * R / count` to `(index + 1) * R / count - 1` of
/// the `R` runs in their order (case by case, point set by point set, run by run), and the
/// point sets they need. Every run's random numbers depend only on (`N_p`, set, run), so the
/// shards' results together are the whole study's, bit for bit ([`StudyResults::merge`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Shard {
    /// This shard, from 0.
    pub index: usize,
    /// How many shards share the work.
    pub count: usize,
}

/// The most shards a study can be split into.
pub const MAX_SHARDS: usize = 1_000_000;

impl Default for Shard {
    fn default() -> Self {
        Self::WHOLE
    }
}

impl Shard {
    /// All the work in one shard.
    pub const WHOLE: Shard = Shard { index: 0, count: 1 };

    /// This shard's part of `total` units of work, in order.
    pub fn range(&self, total: usize) -> std::ops::Range<usize> {
        let at = |i: usize| (i as u128 * total as u128 / self.count.max(1) as u128) as usize;
        at(self.index)..at(self.index + 1)
    }
}

impl std::fmt::Display for Shard {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}/{}", self.index, self.count)
    }
}

impl std::str::FromStr for Shard {
    type Err = String;
    /// `I/N`: shard `I` (0 to `N - 1`) of `N` (1 to [`MAX_SHARDS`]).
    fn from_str(text: &str) -> Result<Self, String> {
        let expected = || format!("I/N with 0 <= I < N <= {MAX_SHARDS} (as 0/4 ... 3/4), found `{text}`");
        let (index, count) = text.split_once('/').ok_or_else(expected)?;
        let (index, count) =
            (index.trim().parse().map_err(|_| expected())?, count.trim().parse().map_err(|_| expected())?);
        if index >= count || count > MAX_SHARDS {
            return Err(expected());
        }
        Ok(Self { index, count })
    }
}

/// Run `study`, calling `progress` once per finished run (from any thread). The study is
/// checked first ([`Study::check`]).
pub fn run(study: &Study, progress: &(dyn Fn() + Sync)) -> Result<StudyResults, SimulationError> {
    run_shard(study, Shard::WHOLE, progress)
}

/// Run shard `shard` of `study` ([`Shard`]): its runs, the ranks of the point sets they use,
/// and the joint noise's error (which every shard computes).
pub fn run_shard(
    study: &Study,
    shard: Shard,
    progress: &(dyn Fn() + Sync),
) -> Result<StudyResults, SimulationError> {
    study.check()?;
    let chain = Chain::new(&study.robot);
    let nominal = chain.with_errors(&vec![0.0; chain.params().len()]);
    let test = study.robot.uniform_configurations(study.test_points, &mut rng(study.seed, TEST_STREAM));
    let real = Chain::new(&study.real_robot());
    // A compliance or play of a joint gravity does not load (a vertical axis) has no column.
    let zero = vec![0.0; chain.params().len()];
    let selections = (study.estimators.iter())
        .map(|c| {
            let asked = c.selection(&study.robot, &study.selection);
            crate::calibration::without_unloaded_responses(&asked, &chain, &zero, &test).0
        })
        .collect();
    let test_trig = Configurations::new(&test, study.robot.dof());
    let bench = Bench { study, chain, nominal, real, selections, test, test_trig };

    let per_set = study.runs_per_set;
    let runs = shard.range(study.cases.len() * study.point_sets * per_set);
    // The point sets, numbered case by case, that the shard's runs use.
    let (first, end) = (runs.start / per_set, runs.end.div_ceil(per_set).max(runs.start / per_set));
    let sets: Vec<(usize, usize)> =
        (first..end).map(|i| (i / study.point_sets, i % study.point_sets)).collect();
    let sets: Vec<PointSet> =
        sets.par_iter().map(|&(c, s)| bench.point_set(c, s)).collect::<Result<_, _>>()?;
    let runs: Vec<(usize, usize)> = runs.map(|g| (g / per_set - first, g % per_set)).collect();
    let runs: Vec<Run> = runs
        .par_iter()
        .map(|&(i, r)| {
            let run = bench.run(&sets[i], r);
            progress();
            run
        })
        .collect::<Result<_, _>>()?;
    Ok(StudyResults {
        runs,
        ranks: sets.iter().map(|s| (s.case, s.set, s.rank)).collect(),
        joint_noise_error: bench.joint_noise_error(),
    })
}

impl Bench<'_> {
    /// Step 1, and what every run on the set shares: `H`, `V` and the factored estimators.
    fn point_set(&self, case: usize, set: usize) -> Result<PointSet, SimulationError> {
        let study = self.study;
        let Case { points, sigma_me, poses } = study.cases[case];
        let mut rng = rng(study.seed, stream(points, set, None));
        let mut joints = study.robot.uniform_configurations(points, &mut rng);
        let errors = (study.errors.redraw == Redraw::Set).then(|| self.draw_errors(&mut rng));
        if let PoseChoice::Planned { criterion, candidates } = poses {
            joints = self.planned(joints, sigma_me, criterion, candidates, &mut rng)?;
        }
        let nominal: Vec<Isometry3<f64>> = joints.iter().map(|q| self.nominal.pose(q)).collect();
        let mut noise = NoiseModel::diagonal(
            &study.joint_sigmas,
            MeasurementNoise::isotropic(sigma_me, study.sigma_orientation),
        );
        let mut factors = Vec::new();
        if let Some(device) = &study.device {
            // Sigma_m,k = Sigma_device(p_k) + sigma_me^2 I at the nominal point.
            let rows = study.measured.rows();
            let mut blocks = Vec::with_capacity(points);
            for pose in &nominal {
                let covariance =
                    device.covariance(&pose.translation.vector)? + Matrix3::identity() * sigma_me * sigma_me;
                let factor = covariance.cholesky().map_or(Matrix3::zeros(), |c| c.l());
                factors.push(factor);
                let mut block = DMatrix::from_diagonal_element(rows, rows, study.sigma_orientation.powi(2));
                block.view_mut((0, 0), (3, 3)).copy_from(&covariance);
                blocks.push(block);
            }
            noise.measurement = MeasurementNoise::PerPoint(blocks);
        }
        let zero = vec![0.0; self.chain.params().len()];
        let mut prepared = Vec::new();
        let mut rank = None;
        for (compared, selection) in study.estimators.iter().zip(&self.selections) {
            let problem = PointProblem::new(
                std::slice::from_ref(&self.chain),
                selection,
                study.measured,
                joints.clone(),
                nominal.clone(),
                zero.clone(),
                Some(&noise),
            )?;
            let system = problem.system(&problem.start());
            if study.iterations == 1 {
                // The problem's weights: an ols of poses weights their orientation rows.
                let weights = Weights::for_problem(&problem, compared.estimator)?;
                let one = Prepared::with_weights(&system.h, weights, RANK_TOLERANCE)?;
                rank = rank.or(Some(one.diagnostics().rank));
                prepared.push(one);
            } else if rank.is_none() {
                rank = Some(crate::estimation::diagnose(&system, compared.estimator, RANK_TOLERANCE)?.rank);
            }
        }
        let rank = rank.unwrap_or(0);
        Ok(PointSet { case, set, joints, nominal, noise, prepared, errors, rank, factors })
    }

    /// Planned poses instead of step 1: the random set `joints` and further uniform
    /// configurations from the same stream make the pool, the random set is the starting set.
    /// The plan sees the noise model the weighted estimator uses.
    fn planned(
        &self,
        joints: Vec<Vec<f64>>,
        sigma_me: f64,
        criterion: Criterion,
        candidates: usize,
        rng: &mut ChaCha8Rng,
    ) -> Result<Vec<Vec<f64>>, DesignError> {
        let study = self.study;
        let noise = NoiseModel::diagonal(
            &study.joint_sigmas,
            MeasurementNoise::isotropic(sigma_me, study.sigma_orientation),
        );
        let design = Design::new(&study.robot, study.selection.clone(), study.measured, Some(noise))?;
        let points = joints.len();
        let mut pool = joints;
        pool.extend(study.robot.uniform_configurations(candidates.saturating_sub(points), rng));
        Ok(design.plan(&pool, points, criterion)?.joints)
    }

    /// Step 2: the real robot's errors, for the identified parameters.
    fn draw_errors(&self, rng: &mut ChaCha8Rng) -> Vec<f64> {
        draw_errors(self.chain.params(), self.study.selection.indices(), &self.study.errors, rng)
    }

    /// Steps 2-8 of one run.
    fn run(&self, set: &PointSet, run: usize) -> Result<Run, EstimationError> {
        let study = self.study;
        let Case { points, sigma_me, .. } = study.cases[set.case];
        let mut rng = rng(study.seed, stream(points, set.set, Some(run)));
        let truth = match &set.errors {
            Some(errors) => errors.clone(),
            None => self.draw_errors(&mut rng),
        };
        let real = self.real.with_errors(&truth);
        let rows = study.measured.rows();
        let mut y = DVector::zeros(points * rows);
        let mut observed = Vec::with_capacity(points);
        let mut q_noisy = vec![0.0; study.robot.dof()];
        for (k, (q, nominal)) in set.joints.iter().zip(&set.nominal).enumerate() {
            for ((noisy, &q), &sigma) in q_noisy.iter_mut().zip(q).zip(&study.joint_sigmas) {
                *noisy = q + sigma * normal(&mut rng);
            }
            let measured = self.measure(&real, &q_noisy, sigma_me, set.factors.get(k), &mut rng);
            match study.measured {
                Measured::Position => y
                    .fixed_rows_mut::<3>(3 * k)
                    .copy_from(&(measured.translation.vector - nominal.translation.vector)),
                Measured::Pose => y.fixed_rows_mut::<6>(6 * k).copy_from(&pose_error(&measured, nominal)),
            }
            observed.push(measured);
        }
        let mut models = Vec::with_capacity(study.estimators.len());
        for (e, (compared, selection)) in study.estimators.iter().zip(&self.selections).enumerate() {
            let estimate = match set.prepared.get(e) {
                Some(prepared) => prepared.estimate(&y),
                None => {
                    let zero = vec![0.0; self.chain.params().len()];
                    let problem = PointProblem::new(
                        std::slice::from_ref(&self.chain),
                        selection,
                        study.measured,
                        set.joints.clone(),
                        observed.clone(),
                        zero,
                        Some(&set.noise),
                    )?;
                    let options =
                        RefineOptions { max_iterations: study.iterations, ..RefineOptions::default() };
                    refine(&problem, compared.estimator, problem.start(), &options)?.estimate.x
                }
            };
            let mut full = vec![0.0; self.chain.params().len()];
            for (&i, &v) in selection.indices().iter().zip(estimate.iter()) {
                full[i] = v;
            }
            models.push(self.chain.with_errors(&full));
        }
        Ok(Run { case: set.case, set: set.set, run, accuracy: self.accuracy(&real, &models) })
    }

    /// Steps 3-4 at one point: the real robot's pose at the noisy joints, measured with noise:
    /// `sigma_me` on each axis, or with a device `L_k z` (`L_k L_k^T` the point's measurement
    /// covariance). Always draws the same number of normals, whatever the sigmas, so that the
    /// streams of cases differing only in noise stay aligned.
    fn measure(
        &self,
        real: &ChainAt,
        q: &[f64],
        sigma_me: f64,
        factor: Option<&Matrix3<f64>>,
        rng: &mut ChaCha8Rng,
    ) -> Isometry3<f64> {
        let pose = real.pose(q);
        let z = Vector3::new(normal(rng), normal(rng), normal(rng));
        let dp = match factor {
            Some(l) => l * z,
            None => z * sigma_me,
        };
        let translation = Translation3::from(pose.translation.vector + dp);
        match self.study.measured {
            Measured::Position => Isometry3::from_parts(translation, pose.rotation),
            Measured::Pose => {
                let omega =
                    Vector3::new(normal(rng), normal(rng), normal(rng)) * self.study.sigma_orientation;
                Isometry3::from_parts(translation, UnitQuaternion::from_scaled_axis(omega) * pose.rotation)
            }
        }
    }

    /// Step 8: each calibrated model against the real robot over the test set, in one pass
    /// over its blocks: the real robot's frames once per block, every model's beside them.
    fn accuracy(&self, real: &ChainAt, models: &[ChainAt]) -> Vec<Accuracy> {
        let pose = self.study.measured == Measured::Pose;
        // Per model: sum, sum of squares, largest, sum of angles.
        let mut sums = vec![(0.0, 0.0, 0.0f64, 0.0); models.len()];
        let (mut truth, mut frames) = (Frames::default(), Frames::default());
        let mut errors = [0.0; BATCH];
        for b in 0..self.test_trig.blocks() {
            real.frames(&self.test_trig, b, &mut truth);
            let n = self.test_trig.block_len(b);
            for (model, (sum, sum_sq, max, angle)) in models.iter().zip(&mut sums) {
                model.frames(&self.test_trig, b, &mut frames);
                frames.distances(&truth, &mut errors);
                for &error in &errors[..n] {
                    *sum += error;
                    *sum_sq += error * error;
                    *max = max.max(error);
                }
                if pose {
                    for i in 0..n {
                        *angle += frames.rotation(i).angle_to(&truth.rotation(i));
                    }
                }
            }
        }
        let n = self.test.len() as f64;
        (sums.into_iter())
            .map(|(sum, sum_sq, max, angle)| Accuracy {
                mean: sum / n,
                rms: (sum_sq / n).sqrt(),
                max,
                orientation: if pose { angle / n } else { f64::NAN },
            })
            .collect()
    }

    /// Mean position error caused by the joint noise alone, over the test set.
    fn joint_noise_error(&self) -> f64 {
        let mut rng = rng(self.study.seed, JOINT_NOISE_STREAM);
        let total: f64 = self
            .test
            .iter()
            .map(|q| {
                let noisy: Vec<f64> =
                    q.iter().zip(&self.study.joint_sigmas).map(|(q, s)| q + s * normal(&mut rng)).collect();
                (self.nominal.position(&noisy) - self.nominal.position(q)).norm()
            })
            .sum();
        total / self.test.len() as f64
    }
}
