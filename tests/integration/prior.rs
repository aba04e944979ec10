//! Priors: maximum a posteriori calibration.

use super::calibration::{campaign_of, standard_errors};
use nalgebra::{DMatrix, DVector};
use rand::SeedableRng;
use rand::rngs::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};
use robocal::calibration::JointParams;
use robocal::calibration::kinds::{KindCalibration, KindOptions, calibrate_kinds};
use robocal::estimation::{
    Estimator, PriorEntry, PriorRows, RefineOptions, Residuals, Weights, linearise, refine_map,
};

fn with_prior(options: &KindOptions, entries: &str) -> KindOptions {
    KindOptions { prior: PriorEntry::parse_list(entries).unwrap(), ..options.clone() }
}

/// How far the fit `map` is from the fit `plain`, which hold the same parameters: the largest
/// difference of an estimate in `plain`'s standard errors, and the largest relative difference
/// of a standard error. The held parameters, which have none, are at the same values.
fn apart(map: &KindCalibration, plain: &KindCalibration) -> (f64, f64) {
    let (sa, sb) = (standard_errors(map), standard_errors(plain));
    let (mut estimates, mut errors) = (0.0f64, 0.0f64);
    for (k, (a, b)) in map.after.iter().zip(&plain.after).enumerate() {
        match sb[k].is_finite() {
            true => {
                estimates = estimates.max((a - b).abs() / sb[k]);
                errors = errors.max((sa[k] - sb[k]).abs() / sb[k]);
            }
            false => assert_eq!(a, b, "held at its start in both"),
        }
    }
    (estimates, errors)
}

/// Priors with standard deviations of 1e12 change nothing: the same parameters held, the same
/// estimates to 1e-4 of their standard errors (the cost's rounding lets each fit stop up to
/// 3.3e-5 of them from the minimum, see below), the same standard errors to 1e-9. A prior on
/// one estimated length, 2 mm wide (440 of its standard errors, held parameters unchanged),
/// moves the estimates by more than that, and one 50 mm wide the standard errors.
#[test]
fn infinitely_wide_priors_give_the_unregularised_fit() {
    let mut c = campaign_of(41, 60);
    // Iterated as far as the cost can tell: a step is taken while it promises a fall of 1e-15
    // of the cost. Where a fit stops is still decided by the cost's rounding: the cost
    // `|S y|^2` (6.15 here, of 360 rows and 30 estimates) is a sum of squared residuals of
    // positions near 1 m, rounded near 1e-13 mm, whitened by hundredths of a millimetre, so it
    // is known to about 2e-11 only (the cost at one `x` from the walk of the points and from
    // the linearisation differs by that much: `Refined::history`). A Gauss-Newton
    // step that falls by less can be refused, and the trust region's damped steps after it
    // stop where they can no longer tell a lower cost: anywhere with `|A (x - x*)|^2 <= d`,
    // `A = S H`, `d = 2e-11`. As `se_i^2 = s^2 ((A^T A)^-1)_ii` (`s^2 = 6.15 / 330`, the
    // variance factor), that is `|x_i - x*_i| <= sqrt(d) se_i / s = 3.3e-5 se_i` for each fit:
    // 1e-4 of a standard error for two. (Measured: 9e-10 of one where both fits end on
    // Gauss-Newton steps, 6e-6 where one is refused by the rounding; an absolute 1e-9 is 2e-7 of a
    // length's standard error, below what the cost resolves.) The standard errors depend on
    // the point only through the Jacobian, 1e-9 apart (4e-11 measured).
    c.options.refine.cost_tolerance = 1e-15;
    c.options.refine.step_tolerance = 1e-14;
    let plain = calibrate_kinds(&c.nominal, &c.training, &c.options).unwrap();
    // The same held parameters and combinations (their coefficients to rounding).
    let text = |c: &KindCalibration| c.fixed.iter().map(|h| h.text()).collect::<Vec<_>>();
    let map = |entries: &str| {
        let map = calibrate_kinds(&c.nominal, &c.training, &with_prior(&c.options, entries)).unwrap();
        assert_eq!(text(&map), text(&plain), "{entries}");
        assert_eq!(map.refined.estimate.names, plain.refined.estimate.names, "{entries}");
        apart(&map, &plain)
    };
    let (estimates, errors) = map("j*.*=1e12mm,j*.*=1e12deg");
    assert!(estimates < 1e-4 && errors < 1e-9, "{estimates:e} {errors:e}");
    // Wide but finite: j4.a (0.35 mm, standard error 4.5e-3 mm) pulled by about
    // `se^2 / sd^2 x`, 1.8e-6 mm, 3.9e-4 of its standard error; at 50 mm, its standard error
    // by `se^2 / (2 sd^2)`, 4.1e-9 of itself.
    let (estimates, _) = map("j4.a=2mm");
    assert!(estimates > 1e-4, "{estimates:e}");
    let (estimates, errors) = map("j4.a=50mm");
    assert!(estimates < 1e-4 && errors > 1e-9, "{estimates:e} {errors:e}");
}

/// A prior of 1e-12 keeps its parameter at the nominal value, even one the poses cannot tell
/// from the base (`j1.theta`, held without a prior, is estimated and stays at 0); the others
/// are still estimated.
#[test]
fn a_prior_sd_near_zero_keeps_the_parameter_nominal() {
    let c = campaign_of(42, 60);
    let options = with_prior(&c.options, "j2.a=1e-12mm,j1.theta=1e-12deg");
    let map = calibrate_kinds(&c.nominal, &c.training, &options).unwrap();
    let at = |name: &str| map.after[map.params.index_by_name(name).unwrap()];
    assert!(map.refined.estimate.names.iter().any(|n| n == "j1.theta"), "kept with its prior");
    assert!(!map.fixed.iter().any(|f| f.parameter() == "j1.theta"), "{:?}", map.fixed);
    assert!(at("j2.a").abs() < 1e-9 && at("j1.theta").abs() < 1e-9, "{} {}", at("j2.a"), at("j1.theta"));
    assert!(at("j3.a").abs() > 1e-3, "the others move: {}", at("j3.a"));
    let se = standard_errors(&map);
    assert!(se[map.params.index_by_name("j2.a").unwrap()] < 1e-11);
}

/// A linear problem `y = H x + e`, with correlated noise `V_k` in blocks of `v.ncols()` rows.
struct Linear {
    h: DMatrix<f64>,
    y: DVector<f64>,
    v: DMatrix<f64>,
}

impl Residuals for Linear {
    fn rows_per_point(&self) -> usize {
        self.v.ncols()
    }
    fn equations(&self) -> usize {
        self.h.nrows()
    }
    fn parameters(&self) -> usize {
        self.h.ncols()
    }
    fn covariance(&self) -> Option<&DMatrix<f64>> {
        Some(&self.v)
    }
    fn evaluate(&self, x: &DVector<f64>, h: Option<&mut DMatrix<f64>>) -> DVector<f64> {
        if let Some(h) = h {
            h.copy_from(&self.h);
        }
        &self.y - &self.h * x
    }
}

/// The MAP estimates of `runs` replications of `y = H x + e` with the truth drawn from the
/// prior (`sd`, infinite: no prior, that component fixed at 1), `e` from the blocks `V_k`
/// (Gauss-Markov weights): the posterior covariance `refine_map` reports is the closed form
/// `(H^T V^-1 H + P^2)^-1`, and each variance of the MAP's error lies within 4 standard errors
/// of a sample variance (`sqrt(2 / n)` relative) of it, its mean within 4 standard errors of 0.
/// This is the Bayesian reading, exact for a linear problem with Gaussian noise.
fn check_posterior_by_monte_carlo(h: &DMatrix<f64>, v: &DMatrix<f64>, sd: &[f64], runs: usize, seed: u64) {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut n = || -> f64 { StandardNormal.sample(&mut rng) };
    let b = v.ncols();
    let (points, p) = (h.nrows() / b, h.ncols());
    let factors: Vec<DMatrix<f64>> =
        (0..points).map(|k| v.rows(b * k, b).into_owned().cholesky().unwrap().unpack()).collect();
    let mut errors = Vec::with_capacity(runs);
    let mut reported = None;
    for _ in 0..runs {
        let truth = DVector::from_iterator(p, sd.iter().map(|s| if s.is_finite() { s * n() } else { 1.0 }));
        let mut y = h * &truth;
        for (k, l) in factors.iter().enumerate() {
            let mut rows = y.rows_mut(b * k, b);
            rows += l * DVector::from_fn(b, |_, _| n());
        }
        let problem = Linear { h: h.clone(), y, v: v.clone() };
        let weights = Weights::for_problem(&problem, Estimator::Wls).unwrap();
        let prior = PriorRows::new(sd, weights.scale().unwrap());
        let start = linearise(&problem, &weights, DVector::zeros(p)).unwrap();
        let map = refine_map(&problem, &weights, start, &RefineOptions::default(), &prior).unwrap();
        errors.push(&map.estimate.x - truth);
        reported.get_or_insert(map.estimate.covariance);
    }
    let reported = reported.unwrap();
    let mut information = DMatrix::from_diagonal(&DVector::from_iterator(
        p,
        sd.iter().map(|s| if s.is_finite() { 1.0 / (s * s) } else { 0.0 }),
    ));
    for k in 0..points {
        let hk = h.rows(b * k, b);
        information += hk.transpose() * v.rows(b * k, b).into_owned().try_inverse().unwrap() * hk;
    }
    let posterior = information.try_inverse().unwrap();
    for i in 0..p {
        for j in 0..p {
            let scale = (posterior[(i, i)] * posterior[(j, j)]).sqrt();
            assert!((reported[(i, j)] - posterior[(i, j)]).abs() < 1e-8 * scale, "({i}, {j})");
        }
    }
    let mean = errors.iter().fold(DVector::zeros(p), |m, e| m + e) / runs as f64;
    let tolerance = 4.0 * (2.0 / runs as f64).sqrt();
    for j in 0..p {
        let variance = errors.iter().map(|e| (e[j] - mean[j]).powi(2)).sum::<f64>() / (runs - 1) as f64;
        let relative = variance / posterior[(j, j)] - 1.0;
        assert!(
            relative.abs() < tolerance,
            "parameter {j}: sample {variance:.4e}, posterior {:.4e}",
            posterior[(j, j)]
        );
        let se = (posterior[(j, j)] / runs as f64).sqrt();
        assert!(mean[j].abs() < 4.0 * se, "parameter {j}: mean error {:.3e}, SE {se:.3e}", mean[j]);
    }
}

/// A small problem: four parameters, three with priors, one weakly seen by the data, and
/// correlated noise blocks.
#[test]
fn the_posterior_covariance_is_the_spread_of_the_map_estimate() {
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    let mut n = || -> f64 { StandardNormal.sample(&mut rng) };
    let (points, p) = (12, 4);
    let mut h = DMatrix::from_fn(3 * points, p, |_, _| n());
    h.column_mut(3).scale_mut(0.05); // weakly identified
    let mut v = DMatrix::zeros(3 * points, 3);
    for k in 0..points {
        let l = DMatrix::from_fn(3, 3, |i, j| match i.cmp(&j) {
            std::cmp::Ordering::Greater => 0.3 * n(),
            std::cmp::Ordering::Equal => 0.5 + 0.2 * n().abs(),
            std::cmp::Ordering::Less => 0.0,
        });
        v.rows_mut(3 * k, 3).copy_from(&(&l * l.transpose()));
    }
    check_posterior_by_monte_carlo(&h, &v, &[0.5, f64::INFINITY, 2.0, 0.3], 2000, 6);
}

/// The PUMA 560 at 12 poses with two markers: every joint parameter, the base and the markers
/// (rank-deficient by 12 without priors), the machining priors on the joints, the full `V_k`
/// of the joint and measurement noise (one 6 x 6 block per pose, its two markers correlated
/// through the joints). The priors make every parameter estimable, and the
/// posterior covariance is the MAP's spread.
#[test]
fn the_posterior_covariance_is_the_spread_of_the_map_estimate_on_the_puma() {
    use robocal::calibration::kinds::{KindProblem, SetUp};
    use robocal::estimation::{MeasurementNoise, NoiseModel, prior_sds};
    use robocal::kinematics::Chain;
    use robocal::model::{RobotModel, Selection};
    let model = RobotModel::preset("puma560").unwrap();
    let markers = [nalgebra::Vector3::new(50.0, 0.0, 150.0), nalgebra::Vector3::new(-40.0, 60.0, 120.0)];
    let chains = Chain::markers(&model, &markers);
    let params = chains[0].params().clone();
    let all = Selection::from_indices(&params, 0..params.len());
    let mut rng = ChaCha8Rng::seed_from_u64(8);
    let joints = model.uniform_configurations(12, &mut rng);
    let sigmas: Vec<f64> =
        [0.007, 0.007, 0.007, 0.002, 0.002, 0.002].iter().map(|d: &f64| d.to_radians()).collect();
    let noise = NoiseModel::diagonal(&sigmas, MeasurementNoise::isotropic(0.01, 0.0));
    // The nominal robot's marker positions, exact, each coordinate's sigma 0.01 mm.
    let text = robocal::simulation::measurement_csv(&model, &markers, &joints, &[0.0; 6], 0.0, 1);
    let data = crate::marker_data(&text, &model, Some(&noise));
    let zero = vec![0.0; params.len()];
    let setup = SetUp::new(0, &[]);
    let problem = KindProblem::of_points(&chains, &[0, 1], &all, &data, &setup, zero, Vec::new(), Vec::new())
        .with_noise(Some(&noise.joint));
    let mut h = DMatrix::zeros(problem.equations(), problem.parameters());
    problem.evaluate(&DVector::zeros(params.len()), Some(&mut h));
    let v = problem.covariance().unwrap().clone();
    assert_eq!((h.nrows(), v.ncols()), (12 * 6, 6), "one block of 6 rows a pose");
    let sd = prior_sds(&PriorEntry::parse_list("machined").unwrap(), &params).unwrap();
    check_posterior_by_monte_carlo(&h, &v, &sd, 2000, 9);
}

/// The arm7 benchmark's files (seed 7), calibrated by OLS with `joints` and priors `prior`.
fn arm7_held_out(joints: JointParams, prior: &str) -> f64 {
    let model = robocal::io::load_model(&robocal::model::ModelRef::named("examples/arm7/arm7.urdf")).unwrap();
    let train = super::urdf::arm7_file(&model, "train.csv");
    let sessions: Vec<_> =
        (1..=3).map(|k| super::urdf::arm7_file(&model, &format!("session{k}.csv"))).collect();
    let prior = PriorEntry::parse_list(prior).unwrap();
    let options = KindOptions { prior, ..super::urdf::arm7_options(&model, joints) };
    let result = calibrate_kinds(&model, &train, &options).unwrap();
    super::urdf::arm7_held_out(&result, &sessions)
}

/// The smallest gains of the priors over seeds 1 to 10 of the benchmark's generator, less a
/// third: on every geometric joint parameter 0.280 mm (seed 9), on the offsets 0.355 mm
/// (seed 4) (`--params 'joint*.*' --prior machined`, the plays included, against
/// `--params joints` and `--params offsets`, OLS; 0.30 and 0.66 mm at seed 7).
const MARGIN_JOINTS: f64 = 0.18;
const MARGIN_OFFSETS: f64 = 0.23;

/// On the arm7 benchmark (seed 7) the machining-tolerance priors on every joint parameter (the
/// compliances estimated without a prior) beat every geometric parameter without priors and
/// the offsets alone, by margins the other seeds keep too.
#[test]
fn priors_beat_every_parameter_and_the_offsets_on_the_arm7_benchmark() {
    let prior = arm7_held_out(JointParams::Named(vec!["joint*.*".into()]), "machined");
    let joints = arm7_held_out(JointParams::All, "");
    let offsets = arm7_held_out(JointParams::Offsets, "");
    assert!(prior < joints - MARGIN_JOINTS, "priors {prior:.4} mm, every parameter {joints:.4} mm");
    assert!(prior < offsets - MARGIN_OFFSETS, "priors {prior:.4} mm, offsets {offsets:.4} mm");
}

/// `calibrate` on the first `poses` poses of `file` (a marker file or a ball bar's) with
/// `extra` flags, validated on `validate`: the exit code, standard output and error.
fn on_few_poses(file: &str, poses: usize, validate: &str, extra: &[&str]) -> (Option<i32>, String, String) {
    let text = std::fs::read_to_string(file).unwrap();
    let kept: Vec<&str> = text.lines().take(2 + poses).collect();
    let dir =
        std::env::temp_dir().join(format!("robocal-few-{}-{poses}-{}", std::process::id(), extra.len()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("few.csv");
    std::fs::write(&path, kept.join("\n") + "\n").unwrap();
    let output = assert_cmd::Command::cargo_bin("robocal")
        .unwrap()
        .args(["calibrate", "--model", "puma560", "--data", path.to_str().unwrap(), "--validate", validate])
        .args(extra)
        .output()
        .unwrap();
    std::fs::remove_dir_all(&dir).unwrap();
    let text = |b: Vec<u8>| String::from_utf8(b).unwrap();
    (output.status.code(), text(output.stdout), text(output.stderr))
}

/// The RMS before and after of the report's row for `set` (mm): its numbers `at` and `at + 1`.
fn held_out_rms(text: &str, set: &str, at: usize) -> (f64, f64) {
    let row = text.lines().find(|l| l.starts_with(set)).unwrap_or_else(|| panic!("{set}:\n{text}"));
    let numbers: Vec<f64> = row.split_whitespace().filter_map(|w| w.parse().ok()).collect();
    (numbers[at], numbers[at + 1])
}

/// Fewer equations than parameters: refused without priors (the rank cannot tell the
/// structure from the lack of data), calibrated with them (each parameter with a prior is
/// anchored by it), on five poses of markers and on twenty ball-bar readings; held out, better
/// than before calibration.
#[test]
fn priors_anchor_what_too_few_poses_cannot() {
    let markers = ["--marker", "50,0,150", "--marker=-40,60,120"];
    let file = "examples/puma560-measurements.csv";
    let validation = "examples/puma560-validation.csv";
    let (code, _, stderr) = on_few_poses(file, 5, validation, &markers);
    assert_eq!(code, Some(1), "{stderr}");
    assert!(stderr.contains("5 poses give 30 equations for"), "{stderr}");
    let with_prior = [&markers[..], &["--prior", "fabricated"]].concat();
    let (code, text, stderr) = on_few_poses(file, 5, validation, &with_prior);
    assert_eq!(code, Some(0), "{stderr}");
    let (before, after) = held_out_rms(&text, "examples/puma560-validation.csv markers (mm)", 1);
    assert!(after < 0.5 * before, "held out {before} -> {after} mm\n{text}");

    let ball_bar = ["--tool", "50,0,150", "--joint-sigma-deg", "0.007,0.007,0.007,0.002,0.002,0.002"];
    let (code, _, stderr) =
        on_few_poses("examples/puma560-ballbar.csv", 20, "examples/puma560-ballbar-2.csv", &ball_bar);
    assert_eq!(code, Some(1), "{stderr}");
    assert!(stderr.contains("20 poses give 20 equations"), "{stderr}");
    let with_prior = [&ball_bar[..], &["--prior", "machined"]].concat();
    let (code, text, stderr) =
        on_few_poses("examples/puma560-ballbar.csv", 20, "examples/puma560-ballbar-2.csv", &with_prior);
    assert_eq!(code, Some(0), "{stderr}");
    let (before, after) = held_out_rms(&text, "examples/puma560-ballbar-2.csv (mm)", 0);
    assert!(after < 0.5 * before, "held out {before} -> {after} mm\n{text}");
    // The data alone, twenty readings, identify at most twenty directions: said, not refused.
    let line = text.lines().find(|l| l.contains("estimated with their priors")).expect(&text);
    let rank: usize = line.split("rank ").nth(1).and_then(|r| r.split(',').next()?.parse().ok()).expect(line);
    assert!(line.starts_with("36 parameters") && (1..=20).contains(&rank), "{line}");
}
