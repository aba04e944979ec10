//! Estimators: the paper's equations computed literally, exact recovery without noise, the
//! predicted covariance against the Monte Carlo spread, and bad input.

use nalgebra::{DMatrix, DVector, Isometry3, Vector3};
use rand::rngs::ChaCha8Rng;
use rand::{RngExt, SeedableRng};
use rand_distr::{Distribution, StandardNormal};
use robocal::estimation::{
    EstimationError, Estimator, LinearSystem, MeasurementNoise, NoiseModel, PointProblem, RANK_TOLERANCE,
    RefineOptions, Residuals, Weights, estimate, linearise, refine, refine_from,
};
use robocal::kinematics::{Chain, Measured};
use robocal::model::{Convention, Joint, JointKind, Placement, RobotModel, Selection, Tool};

fn rng(seed: u64) -> ChaCha8Rng {
    ChaCha8Rng::seed_from_u64(seed)
}

fn normal(rng: &mut ChaCha8Rng) -> f64 {
    StandardNormal.sample(rng)
}

/// A random symmetric positive definite `n x n` matrix.
fn spd(rng: &mut ChaCha8Rng, n: usize) -> DMatrix<f64> {
    let a = DMatrix::from_fn(n, n, |_, _| normal(rng));
    &a * a.transpose() + DMatrix::identity(n, n) * 0.1
}

/// A dense system of `points` x 3 rows with random SPD blocks; `dependent` makes the last
/// column the sum of the first two, so that H has rank p - 1.
fn dense_system(rng: &mut ChaCha8Rng, points: usize, p: usize, dependent: bool) -> LinearSystem {
    let mut h = DMatrix::from_fn(3 * points, p, |_, _| normal(rng));
    if dependent {
        let sum = h.column(0) + h.column(1);
        h.column_mut(p - 1).copy_from(&sum);
    }
    let y = DVector::from_fn(3 * points, |_, _| normal(rng));
    let mut v = DMatrix::zeros(3 * points, 3);
    for k in 0..points {
        v.rows_mut(3 * k, 3).copy_from(&spd(rng, 3));
    }
    LinearSystem { h, y, rows_per_point: 3, v: Some(v), names: Vec::new() }
}

/// `V` as the dense block-diagonal matrix: only for checking against the literal equations.
fn dense_v(system: &LinearSystem) -> DMatrix<f64> {
    let v = system.v.as_ref().unwrap();
    let n = v.nrows();
    let mut dense = DMatrix::zeros(n, n);
    for k in 0..system.points() {
        dense.view_mut((3 * k, 3 * k), (3, 3)).copy_from(&v.rows(3 * k, 3));
    }
    dense
}

fn relative(a: &DMatrix<f64>, b: &DMatrix<f64>) -> f64 {
    (a - b).amax() / b.amax()
}

#[test]
fn whitened_solve_equals_the_papers_equations_computed_literally() {
    let mut rng = rng(1);
    for (dependent, case) in [(false, "full rank, Eqs. 4-5"), (true, "rank deficient, Eq. 6")] {
        for _ in 0..20 {
            let system = dense_system(&mut rng, 6, 5, dependent);
            let (h, y, v) = (&system.h, &system.y, dense_v(&system));
            let v_inv = v.clone().try_inverse().unwrap();
            let m = h.transpose() * &v_inv * h;
            let m_plus = if dependent {
                m.clone().pseudo_inverse(1e-10).unwrap()
            } else {
                m.clone().try_inverse().unwrap()
            };
            let x_literal = &m_plus * h.transpose() * &v_inv * y;

            let wls = estimate(&system, Estimator::Wls, RANK_TOLERANCE).unwrap();
            let x = DMatrix::from_column_slice(5, 1, wls.x.as_slice());
            let x_literal = DMatrix::from_column_slice(5, 1, x_literal.as_slice());
            assert!(relative(&x, &x_literal) < 1e-9, "{case}: x {x} vs literal {x_literal}");
            assert!(relative(&wls.covariance, &m_plus) < 1e-9, "{case}: covariance vs (H^T V^-1 H)^+");
            assert_eq!(wls.diagnostics.rank, if dependent { 4 } else { 5 });

            let hth_plus = (h.transpose() * h).pseudo_inverse(1e-10).unwrap();
            let ols = estimate(&system, Estimator::Ols, RANK_TOLERANCE).unwrap();
            let x_ols = DMatrix::from_column_slice(5, 1, (&hth_plus * h.transpose() * y).as_slice());
            let ours = DMatrix::from_column_slice(5, 1, ols.x.as_slice());
            assert!(relative(&ours, &x_ols) < 1e-9, "{case}: OLS {ours} vs literal {x_ols}");
            let sandwich = &hth_plus * h.transpose() * &v * h * &hth_plus;
            assert!(relative(&ols.covariance, &sandwich) < 1e-9, "{case}: OLS sandwich covariance");
        }
    }
}

#[test]
fn rank_deficient_solve_names_the_invisible_combination() {
    let system = dense_system(&mut rng(2), 6, 5, true);
    let wls = estimate(&system, Estimator::Wls, RANK_TOLERANCE).unwrap();
    let d = &wls.diagnostics;
    assert_eq!(d.identifiable, [0, 1, 2, 3], "ties and pivots pick the first columns");
    assert_eq!(d.not_identifiable.len(), 1);
    let names = ["a", "b", "c", "d", "e"];
    assert_eq!(d.not_identifiable[0].describe(&names), "e - a - b");
    assert!(d.condition_number.is_finite() && d.singular_values[4] < 1e-12 * d.singular_values[0]);
}

/// The problem of one chain's tool positions, the usual set-up of these tests.
fn position_problem<'a>(
    chain: &'a Chain,
    selection: &'a Selection,
    joints: Vec<Vec<f64>>,
    observed: Vec<Isometry3<f64>>,
    fixed: Vec<f64>,
    noise: Option<&NoiseModel>,
) -> PointProblem<'a> {
    PointProblem::new(
        std::slice::from_ref(chain),
        selection,
        Measured::Position,
        joints,
        observed,
        fixed,
        noise,
    )
    .unwrap()
}

/// True parameter errors of the sizes the issue names: joint offsets about 0.1 deg, lengths
/// about 0.5 mm, other angles about 0.05 deg.
fn true_errors(chain: &Chain, selection: &Selection, rng: &mut ChaCha8Rng) -> Vec<f64> {
    let mut x = vec![0.0; chain.params().len()];
    for &i in selection.indices() {
        let p = chain.params().get(i);
        let size = if p.is_offset && p.kind.is_angle() {
            0.1f64.to_radians()
        } else if p.kind.is_angle() {
            0.05f64.to_radians()
        } else {
            0.5
        };
        x[i] = size * normal(rng);
    }
    x
}

fn random_joints(model: &RobotModel, n: usize, rng: &mut ChaCha8Rng) -> Vec<Vec<f64>> {
    (0..n)
        .map(|_| model.joints.iter().map(|j| rng.random_range(j.limits[0]..j.limits[1])).collect())
        .collect()
}

/// Calibrate from noise-free measurements of a robot with random errors; the estimated model
/// must predict the true robot's positions at other points to 1e-6 mm.
fn recovers_without_noise(
    model: &RobotModel,
    selection_of: fn(&robocal::model::ParamSet) -> Selection,
    seed: u64,
) {
    let mut rng = rng(seed);
    let chain = Chain::new(model);
    let selection = selection_of(chain.params());
    let truth = true_errors(&chain, &selection, &mut rng);
    let real = chain.with_errors(&truth);
    let joints = random_joints(model, 60, &mut rng);
    let observed = joints.iter().map(|q| real.pose(q)).collect();
    let zero = vec![0.0; chain.params().len()];
    let problem = position_problem(&chain, &selection, joints, observed, zero, None);
    let refined = refine(&problem, Estimator::Ols, problem.start(), &RefineOptions::default()).unwrap();
    assert!(refined.converged, "history {:?}", refined.history);
    let estimated = chain.with_errors(&problem.full(&refined.estimate.x));
    for q in random_joints(model, 200, &mut rng) {
        let miss = (estimated.position(&q) - real.position(&q)).norm();
        assert!(miss < 1e-6, "{}: predicted position off by {miss:e} mm", model.name);
    }
}

#[test]
fn iterated_estimator_recovers_the_puma560_without_noise() {
    let puma = RobotModel::preset("puma560").unwrap();
    recovers_without_noise(&puma, Selection::joints, 3);
    recovers_without_noise(&puma, Selection::all, 4);
}

/// A 5-joint modified-DH robot with a prismatic third joint and a tool frame.
fn prismatic_robot() -> RobotModel {
    let joint = |name: &str, kind, theta: f64, d, a, alpha: f64, limits| {
        Joint::dh(name, kind, [theta.to_radians(), d, a, alpha.to_radians(), 0.0], limits)
    };
    let turn = [-2.5, 2.5];
    RobotModel {
        name: "mdh-prismatic".into(),
        description: String::new(),
        convention: Convention::ModifiedDh,
        base: Placement { xyz: Vector3::new(100.0, -50.0, 300.0), rpy: Vector3::new(0.1, -0.2, 0.3) },
        joints: vec![
            joint("q1", JointKind::Revolute, 0.0, 400.0, 0.0, 0.0, turn),
            joint("q2", JointKind::Revolute, 10.0, 0.0, 50.0, -90.0, turn),
            joint("slide", JointKind::Prismatic, 0.0, 300.0, 400.0, 0.0, [0.0, 400.0]),
            joint("q4", JointKind::Revolute, 0.0, 100.0, 30.0, 90.0, turn),
            joint("q5", JointKind::Revolute, 0.0, 0.0, 0.0, -90.0, turn),
        ],
        tool: Tool::Frame(Placement {
            xyz: Vector3::new(40.0, 20.0, 120.0),
            rpy: Vector3::new(0.0, 0.3, 0.0),
        }),
        masses: Vec::new(),
        gravity: RobotModel::floor_gravity(),
        payload: None,
    }
}

#[test]
fn iterated_estimator_recovers_a_modified_dh_robot_with_a_prismatic_joint() {
    recovers_without_noise(&prismatic_robot(), Selection::all, 5);
}

#[test]
fn one_step_is_the_first_iterate_and_equals_the_linear_estimate() {
    let mut rng = rng(6);
    let model = RobotModel::preset("puma560").unwrap();
    let chain = Chain::new(&model);
    let selection = Selection::joints(chain.params());
    let real = chain.with_errors(&true_errors(&chain, &selection, &mut rng));
    let joints = random_joints(&model, 30, &mut rng);
    let observed: Vec<Isometry3<f64>> = joints.iter().map(|q| real.pose(q)).collect();
    let (joints_again, observed_again) = (joints.clone(), observed.clone());
    let noise = puma_noise(0.01);
    let problem =
        position_problem(&chain, &selection, joints, observed, vec![0.0; chain.params().len()], Some(&noise));
    let one = RefineOptions { max_iterations: 1, ..RefineOptions::default() };
    let refined = refine(&problem, Estimator::Wls, problem.start(), &one).unwrap();
    let linear = estimate(&problem.system(&problem.start()), Estimator::Wls, RANK_TOLERANCE).unwrap();
    assert_eq!(refined.history.len(), 1);
    assert!((&refined.estimate.x - &linear.x).amax() < 1e-15);
    assert_eq!(refined.estimate.covariance, linear.covariance);
    assert!(
        (refined.estimate.cost - linear.cost).abs() <= 1e-12 * linear.cost,
        "the linearised residual's cost"
    );
    // Without a noise model the covariance comes from the residual: the same for both.
    let ols_system = LinearSystem { v: None, ..problem.system(&problem.start()) };
    let ols_linear = estimate(&ols_system, Estimator::Ols, RANK_TOLERANCE).unwrap();
    let unweighted = position_problem(
        &chain,
        &selection,
        joints_again,
        observed_again,
        vec![0.0; chain.params().len()],
        None,
    );
    let ols_one = refine(&unweighted, Estimator::Ols, unweighted.start(), &one).unwrap();
    assert!((&ols_one.estimate.x - &ols_linear.x).amax() < 1e-15);
    let spread =
        (&ols_one.estimate.covariance - &ols_linear.covariance).amax() / ols_linear.covariance.amax();
    assert!(spread < 1e-12, "covariance from the linearised residual: {spread:e}");
}

/// The paper's joint noise (0.007 deg for joints 1-3, 0.002 deg for 4-6) and isotropic
/// measurement noise `sigma_me` (mm).
fn puma_noise(sigma_me: f64) -> NoiseModel {
    let sigmas: Vec<f64> =
        [0.007, 0.007, 0.007, 0.002, 0.002, 0.002].iter().map(|d: &f64| d.to_radians()).collect();
    NoiseModel::diagonal(&sigmas, MeasurementNoise::isotropic(sigma_me, 0.0))
}

/// With heteroscedastic noise drawn from the blocks `V_k`, the spread of the estimates over
/// 2000 replications matches the predicted covariances: `(H^T V^-1 H)^+` for WLS and the
/// sandwich for OLS. A sample variance of n draws has relative standard error sqrt(2/(n-1))
/// and a sample correlation standard error below 1/sqrt(n): each is allowed 5 of those.
#[test]
fn predicted_covariance_matches_the_monte_carlo_spread() {
    let mut rng = rng(7);
    let model = RobotModel::preset("puma560").unwrap();
    let chain = Chain::new(&model);
    let selection = Selection::joints(chain.params());
    let joints = random_joints(&model, 24, &mut rng);
    let observed = vec![Isometry3::identity(); joints.len()];
    let zero = vec![0.0; chain.params().len()];
    // Heteroscedastic: the joint noise of the paper, and measurement noise growing with the
    // point's distance from the base, as for an optical device.
    let mut noise = puma_noise(0.0);
    let at = chain.with_errors(&zero);
    noise.measurement = MeasurementNoise::PerPoint(
        joints
            .iter()
            .map(|q| DMatrix::identity(3, 3) * (0.02 * at.position(q).norm() / 1000.0).powi(2))
            .collect(),
    );
    let problem = position_problem(&chain, &selection, joints, observed, zero, Some(&noise));
    let system = problem.system(&problem.start());
    let v = system.v.clone().unwrap();
    let factors: Vec<DMatrix<f64>> =
        (0..system.points()).map(|k| v.rows(3 * k, 3).into_owned().cholesky().unwrap().unpack()).collect();

    let n = 2000;
    let x_true = DVector::from_fn(30, |i, _| 1e-3 * (i as f64).sin());
    let mut samples = [Vec::with_capacity(n), Vec::with_capacity(n)];
    let predicted: Vec<DMatrix<f64>> = [Estimator::Ols, Estimator::Wls]
        .iter()
        .map(|&estimator| estimate(&system, estimator, RANK_TOLERANCE).unwrap().covariance)
        .collect();
    for _ in 0..n {
        let mut y = &system.h * &x_true;
        for (k, l) in factors.iter().enumerate() {
            let z = DVector::from_fn(3, |_, _| normal(&mut rng));
            let mut rows = y.rows_mut(3 * k, 3);
            rows += l * z;
        }
        let replicate = LinearSystem { y, ..system.clone() };
        for (e, estimator) in [Estimator::Ols, Estimator::Wls].into_iter().enumerate() {
            samples[e].push(estimate(&replicate, estimator, RANK_TOLERANCE).unwrap().x);
        }
    }
    let variance_tolerance = 5.0 * (2.0 / (n as f64 - 1.0)).sqrt();
    let correlation_tolerance = 5.0 / (n as f64).sqrt();
    let mut traces = Vec::new();
    for (e, name) in ["ols", "wls"].iter().enumerate() {
        let sample = sample_covariance(&samples[e]);
        let theory = &predicted[e];
        for i in 0..30 {
            let ratio = sample[(i, i)] / theory[(i, i)];
            assert!((ratio - 1.0).abs() < variance_tolerance, "{name}: variance {i} off by ratio {ratio}");
            for j in 0..i {
                let r = |c: &DMatrix<f64>| c[(i, j)] / (c[(i, i)] * c[(j, j)]).sqrt();
                let diff = (r(&sample) - r(theory)).abs();
                assert!(diff < correlation_tolerance, "{name}: correlation ({i}, {j}) off by {diff}");
            }
        }
        traces.push((theory.trace(), sample.trace()));
    }
    assert!(traces[1].0 < traces[0].0, "WLS predicted trace {} vs OLS {}", traces[1].0, traces[0].0);
    assert!(traces[1].1 < traces[0].1, "WLS sample trace {} vs OLS {}", traces[1].1, traces[0].1);
}

fn sample_covariance(samples: &[DVector<f64>]) -> DMatrix<f64> {
    let n = samples.len() as f64;
    let mean = samples.iter().fold(DVector::zeros(samples[0].len()), |acc, x| acc + x) / n;
    samples.iter().fold(DMatrix::zeros(mean.len(), mean.len()), |acc, x| {
        let d = x - &mean;
        acc + &d * d.transpose()
    }) / (n - 1.0)
}

#[test]
fn bad_input_gives_typed_errors() {
    let mut rng = rng(8);
    let system = dense_system(&mut rng, 6, 5, false);

    let mut nan = system.clone();
    nan.y[7] = f64::NAN;
    let err = estimate(&nan, Estimator::Wls, RANK_TOLERANCE).unwrap_err();
    assert!(matches!(err, EstimationError::NonFinite { what: "y", row: 7, .. }), "{err}");
    assert_eq!(err.to_string(), "y row 7 holds NaN: expected finite numbers");

    let mut nan_h = system.clone();
    nan_h.h[(4, 2)] = f64::INFINITY;
    let err = estimate(&nan_h, Estimator::Ols, RANK_TOLERANCE).unwrap_err();
    assert!(matches!(err, EstimationError::NonFinite { what: "H", row: 4, .. }), "{err}");

    let mut not_pd = system.clone();
    not_pd.v.as_mut().unwrap().rows_mut(9, 3).copy_from(&DMatrix::from_row_slice(
        3,
        3,
        &[1., 2., 0., 2., 1., 0., 0., 0., 1.],
    ));
    let err = estimate(&not_pd, Estimator::Wls, RANK_TOLERANCE).unwrap_err();
    assert_eq!(err, EstimationError::NotPositiveDefinite { point: 3 });

    let mut short = system.clone();
    short.y = short.y.rows(0, 17).into_owned();
    assert!(matches!(estimate(&short, Estimator::Ols, RANK_TOLERANCE), Err(EstimationError::Dimensions(_))));

    let unknown_noise = LinearSystem { v: None, ..system.clone() };
    assert_eq!(
        estimate(&unknown_noise, Estimator::Wls, RANK_TOLERANCE),
        Err(EstimationError::NoiseRequired(Estimator::Wls))
    );

    let nothing = LinearSystem { h: DMatrix::zeros(18, 0), names: Vec::new(), ..system.clone() };
    assert!(matches!(
        estimate(&nothing, Estimator::Ols, RANK_TOLERANCE),
        Err(EstimationError::NothingToEstimate(_))
    ));
    assert!(matches!(estimate(&system, Estimator::Ols, f64::NAN), Err(EstimationError::Dimensions(_))));
    let mut asymmetric = system.clone();
    asymmetric.v.as_mut().unwrap()[(0, 1)] += 0.5;
    assert!(matches!(
        estimate(&asymmetric, Estimator::Wls, RANK_TOLERANCE),
        Err(EstimationError::Dimensions(_))
    ));

    let few = dense_system(&mut rng, 1, 5, false);
    let err = estimate(&few, Estimator::Ols, RANK_TOLERANCE).unwrap_err();
    assert!(
        matches!(err, EstimationError::TooFewEquations { equations: 3, parameters: 5, rank: 3 }),
        "{err}"
    );
}

#[test]
fn noise_model_must_fit_the_robot() {
    let model = RobotModel::preset("puma560").unwrap();
    let chain = Chain::new(&model);
    let selection = Selection::offsets(chain.params());
    let joints = vec![vec![0.0; 6]; 4];
    let observed = vec![Isometry3::identity(); 4];
    let noise = NoiseModel::diagonal(&[1e-4; 5], MeasurementNoise::isotropic(0.01, 0.0));
    let zero = vec![0.0; chain.params().len()];
    let chains = std::slice::from_ref(&chain);
    let err = PointProblem::new(chains, &selection, Measured::Position, joints, observed, zero, Some(&noise))
        .unwrap_err();
    assert_eq!(err.to_string(), "noise model: Sigma_q is (5, 5), expected 6 x 6");
}

/// The identifiable subset refined from the system that found it gives what a fresh refine
/// gives, and a linearisation or weights that do not fit the problem are refused.
#[test]
fn refining_the_identifiable_subset_from_its_linearisation_is_refining_it_afresh() {
    let mut rng = rng(12);
    let model = RobotModel::preset("puma560").unwrap();
    let chain = Chain::new(&model);
    let selection = Selection::joints(chain.params());
    let real = chain.with_errors(&true_errors(&chain, &selection, &mut rng));
    let joints = random_joints(&model, 40, &mut rng);
    let observed: Vec<_> = joints.iter().map(|q| real.pose(q)).collect();
    let zero = vec![0.0; chain.params().len()];
    let noise = puma_noise(0.01);
    let problem =
        position_problem(&chain, &selection, joints.clone(), observed.clone(), zero.clone(), Some(&noise));
    let weights = Weights::for_problem(&problem, Estimator::Wls).unwrap();
    let at_start = linearise(&problem, &weights, problem.start()).unwrap();
    let diagnostics = at_start.diagnose(RANK_TOLERANCE).unwrap();
    let from_system = estimate(&problem.system(&problem.start()), Estimator::Wls, RANK_TOLERANCE).unwrap();
    assert_eq!(diagnostics.identifiable, from_system.diagnostics.identifiable);
    assert_eq!(diagnostics.rank, 23);

    let kept = Selection::from_indices(
        chain.params(),
        diagnostics.identifiable.iter().map(|&c| selection.indices()[c]),
    );
    let subset = problem.reselect(&kept, zero.clone()).unwrap();
    let options = RefineOptions::default();
    let reused =
        refine_from(&subset, &weights, at_start.select(&diagnostics.identifiable), &options).unwrap();
    let afresh = refine(&subset, Estimator::Wls, subset.start(), &options).unwrap();
    // The selected columns' triangular factor is reduced from the whole system's, not from
    // the rows: the same to rounding.
    let scale = afresh.estimate.x.amax();
    assert!((&reused.estimate.x - &afresh.estimate.x).amax() <= 1e-9 * scale, "{}", reused.estimate.x);
    // The same steps, but where the noise-free cost reaches the rounding floor: there a step
    // more or less is rounding's choice.
    let first = afresh.history[0].cost;
    let above_rounding =
        |r: &robocal::estimation::Refined| r.history.iter().filter(|s| s.cost > 1e-18 * first).count();
    assert_eq!(
        above_rounding(&reused),
        above_rounding(&afresh),
        "{:?}\n{:?}",
        reused.history,
        afresh.history
    );
    assert!(above_rounding(&afresh) >= 3, "{:?}", afresh.history);
    assert!(
        reused.converged && reused.estimate.cost < 1e-20,
        "noise-free data are fitted: {:?}",
        reused.history
    );

    let err = linearise(&subset, &weights, DVector::zeros(3)).unwrap_err();
    assert!(err.to_string().contains("3 start values for 23 parameters"), "{err}");
    let err = refine_from(&problem, &weights, at_start.select(&[0, 1]), &options).unwrap_err();
    assert!(matches!(err, EstimationError::Dimensions(_)), "{err}");
    let fewer = position_problem(
        &chain,
        &selection,
        joints[..20].to_vec(),
        observed[..20].to_vec(),
        zero,
        Some(&noise),
    );
    let err = linearise(&fewer, &weights, fewer.start()).unwrap_err();
    assert!(err.to_string().contains("weights for other points"), "{err}");
}

/// The linearisation shares its poses between threads: its reduced system and y are the same
/// to the bit on any number of threads, for several markers and for one tool.
#[test]
fn linearisation_is_the_same_on_any_number_of_threads() {
    let mut rng = rng(13);
    let model = RobotModel::preset("puma560").unwrap();
    let joints = random_joints(&model, 300, &mut rng);
    let markers = [Vector3::new(50.0, 0.0, 150.0), Vector3::new(-40.0, 60.0, 120.0)];
    let noise = puma_noise(0.01);
    for chains in [Chain::markers(&model, &markers), vec![Chain::new(&model)]] {
        let selection = Selection::all(chains[0].params());
        let observed = vec![Isometry3::translation(500.0, 100.0, 300.0); joints.len() * chains.len()];
        let x = vec![1e-3; chains[0].params().len()];
        let problem = PointProblem::new(
            &chains,
            &selection,
            Measured::Position,
            joints.clone(),
            observed,
            x,
            Some(&noise),
        )
        .unwrap();
        let weights = Weights::for_problem(&problem, Estimator::Wls).unwrap();
        let on = |threads| {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
            pool.install(|| linearise(&problem, &weights, problem.start()).unwrap())
        };
        let (one, two, four) = (on(1), on(2), on(4));
        assert_eq!(one.system, two.system, "{} chains", chains.len());
        assert_eq!(one.system, four.system, "{} chains", chains.len());
        assert_eq!(one.b, four.b, "{} chains", chains.len());
        // The reduced system is the whitened one: R^T R = A^T A, R^T z = A^T b.
        let unweighted = problem.system(&problem.start());
        let (mut whitened, mut b) = (unweighted.h.clone(), unweighted.y.clone());
        weights.apply(&mut whitened);
        weights.apply(&mut b);
        let (r, z) = (one.system.r(), one.system.z());
        let gram = whitened.transpose() * &whitened;
        assert!((r.transpose() * r - &gram).amax() <= 1e-12 * gram.amax(), "R^T R = A^T A");
        let atb = whitened.transpose() * &b;
        assert!((r.transpose() * z - &atb).amax() <= 1e-12 * atb.amax(), "R^T z = A^T b");
        assert!((&b - &one.b).amax() <= 1e-12 * b.amax(), "whitened in blocks as in one pass");
    }
}

/// A problem that keeps the default `evaluate_whitened` (whitening after `evaluate`).
struct Plain<'a>(PointProblem<'a>);

impl Residuals for Plain<'_> {
    fn rows_per_point(&self) -> usize {
        self.0.rows_per_point()
    }
    fn equations(&self) -> usize {
        self.0.equations()
    }
    fn parameters(&self) -> usize {
        self.0.parameters()
    }
    fn covariance(&self) -> Option<&DMatrix<f64>> {
        self.0.covariance()
    }
    fn evaluate(&self, x: &DVector<f64>, h: Option<&mut DMatrix<f64>>) -> DVector<f64> {
        self.0.evaluate(x, h)
    }
}

/// Whitening block by block while linearising is whitening afterwards.
#[test]
fn whitening_while_linearising_is_whitening_after() {
    let mut rng = rng(14);
    let model = RobotModel::preset("puma560").unwrap();
    let chain = Chain::new(&model);
    let selection = Selection::joints(chain.params());
    let joints = random_joints(&model, 30, &mut rng);
    let observed = vec![Isometry3::translation(500.0, 100.0, 300.0); joints.len()];
    let x = vec![1e-3; chain.params().len()];
    let problem = position_problem(&chain, &selection, joints, observed, x, Some(&puma_noise(0.01)));
    let weights = Weights::for_problem(&problem, Estimator::Wls).unwrap();
    let plain = Plain(problem.clone());
    let (ours, after) = (
        linearise(&problem, &weights, problem.start()).unwrap(),
        linearise(&plain, &weights, problem.start()).unwrap(),
    );
    let gram = |s: &robocal::estimation::Reduced| s.r().transpose() * s.r();
    assert!((gram(&ours.system) - gram(&after.system)).amax() <= 1e-12 * gram(&ours.system).amax());
    assert!((&ours.b - &after.b).amax() <= 1e-12 * ours.b.amax());
    assert!(ours.b.amax() > 1.0, "the residuals are not trivial");
}

/// The diagnostics name the seven combinations of the paper's 30 parameters that position
/// measurements cannot see (docs/identifiability.md), dropping the later parameter of each.
#[test]
fn puma560_diagnostics_name_the_non_identifiable_combinations() {
    let mut rng = rng(9);
    let model = RobotModel::preset("puma560").unwrap();
    let chain = Chain::new(&model);
    let selection = Selection::joints(chain.params());
    let joints = random_joints(&model, 50, &mut rng);
    let observed = vec![Isometry3::identity(); joints.len()];
    let zero = vec![0.0; chain.params().len()];
    let noise = puma_noise(0.01);
    let problem = position_problem(&chain, &selection, joints, observed, zero, Some(&noise));
    let wls = estimate(&problem.system(&problem.start()), Estimator::Wls, RANK_TOLERANCE).unwrap();
    let names: Vec<&str> = selection.indices().iter().map(|&i| chain.params().get(i).name.as_str()).collect();
    let described: Vec<String> =
        wls.diagnostics.not_identifiable.iter().map(|c| c.describe(&names)).collect();
    assert_eq!(wls.diagnostics.rank, 23);
    assert_eq!(wls.names[..3], ["j1.theta", "j1.d", "j1.a"]);
    assert_eq!(
        described,
        [
            "j1.beta - j1.theta",
            "j3.d - j2.d",
            "j3.beta + j3.theta - 20.3 j4.d",
            "j4.beta - j4.theta",
            "j5.beta + j5.theta",
            "j6.a - 0.3333 j6.d - 0.006667 j6.beta",
            "j6.alpha + 3 j6.theta",
        ]
    );
    assert_eq!(wls.diagnostics.identifiable.len(), 23);
}

/// Where Gauss-Newton converges, the trust region takes its steps as they are: refined to
/// convergence from noisy measurements of a PUMA 560 with errors of the usual sizes, every
/// step undamped and the estimate that of plain Gauss-Newton (the paper's one step repeated
/// from each estimate) to 1e-9 of each parameter, with the same covariance.
#[test]
fn the_trust_region_is_gauss_newton_where_gauss_newton_converges() {
    let mut rng = rng(24);
    let model = RobotModel::preset("puma560").unwrap();
    let chain = Chain::new(&model);
    let selection = Selection::joints(chain.params());
    let truth = true_errors(&chain, &selection, &mut rng);
    let real = chain.with_errors(&truth);
    let joints = random_joints(&model, 60, &mut rng);
    let observed: Vec<Isometry3<f64>> = joints
        .iter()
        .map(|q| {
            let mut pose = real.pose(q);
            pose.translation.vector += Vector3::from_fn(|_, _| 0.01 * normal(&mut rng));
            pose
        })
        .collect();
    let zero = vec![0.0; chain.params().len()];
    let noise = puma_noise(0.01);
    let problem = position_problem(&chain, &selection, joints, observed, zero.clone(), Some(&noise));
    let weights = Weights::for_problem(&problem, Estimator::Wls).unwrap();
    let diagnostics =
        linearise(&problem, &weights, problem.start()).unwrap().diagnose(RANK_TOLERANCE).unwrap();
    let kept = Selection::from_indices(
        chain.params(),
        diagnostics.identifiable.iter().map(|&c| selection.indices()[c]),
    );
    let subset = problem.reselect(&kept, zero).unwrap();
    let refined = refine(&subset, Estimator::Wls, subset.start(), &RefineOptions::default()).unwrap();
    assert!(refined.converged && refined.history.len() >= 3, "{:?}", refined.history);
    assert!(refined.history.iter().all(|step| step.damping == 0.0), "{:?}", refined.history);

    let one = RefineOptions { max_iterations: 1, ..RefineOptions::default() };
    let mut x = subset.start();
    for _ in 0..refined.history.len() {
        x = refine(&subset, Estimator::Wls, x, &one).unwrap().estimate.x;
    }
    let se = refined.estimate.standard_errors();
    for (j, name) in refined.estimate.names.iter().enumerate() {
        let (lm, gn) = (refined.estimate.x[j], x[j]);
        assert!((lm - gn).abs() <= 1e-9 * lm.abs().max(se[j]), "{name}: {lm} against {gn}");
    }
    // The covariance of the system linearised at the estimate: the next step's.
    let gauss_newton = refine(&subset, Estimator::Wls, x, &one).unwrap().estimate.covariance;
    let spread = (&refined.estimate.covariance - &gauss_newton).amax() / gauss_newton.amax();
    assert!(spread < 1e-9, "{spread:e}");
}
