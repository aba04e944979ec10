//! Distances, plane contacts and partial coordinates: H against finite differences, exact
//! recovery without noise, estimates within 3 predicted standard errors with noise, and what
//! each kind cannot see.

use crate::kinematics::{point, robot};
use nalgebra::{DMatrix, DVector, Vector3, Vector6};
use proptest::prelude::*;
use rand::rngs::ChaCha8Rng;
use rand::{RngExt, SeedableRng};
use rand_distr::{Distribution, StandardNormal};
use robocal::calibration::kinds::{
    CameraSite, KindCalibration, KindData, KindOptions, KindProblem, Observation, SetUp, calibrate_kinds,
};
use robocal::calibration::{BaseAbsorber, Held, Loss, PointName, Unseen};
use robocal::estimation::{Estimator, RefineOptions, Residuals};
use robocal::kinematics::{Chain, ChainAt};
use robocal::model::{Convention, Placement, RobotModel, Selection};

/// Six poses of `model` from unit draws, and one observation of every kind on them: a pair,
/// a fixed point, two planes, the three coordinates, and with `angles` roll, pitch and yaw.
fn every_kind(model: &RobotModel, u: &[f64], angles: bool) -> KindData {
    let joints: Vec<Vec<f64>> = (0..6).map(|k| point(model, &u[k * 7..]).0).collect();
    let observations = vec![
        Observation::Distance { a: 0, b: 1, measured: 500.0, sigma: 0.01 },
        Observation::ToPoint { pose: 2, point: 0, measured: 300.0, sigma: 0.01 },
        Observation::Contact { pose: 3, plane: 0, sigma: 0.01 },
        Observation::Contact { pose: 4, plane: 1, sigma: 0.01 },
        Observation::Coordinate { pose: 5, axis: 0, measured: 1.0, sigma: 0.01 },
        Observation::Coordinate { pose: 5, axis: 1, measured: 2.0, sigma: 0.01 },
        Observation::Coordinate { pose: 5, axis: 2, measured: 3.0, sigma: 0.01 },
    ];
    let angles = (3..6).filter(|_| angles).map(|axis| Observation::Coordinate {
        pose: 4,
        axis,
        measured: 0.3,
        sigma: 1e-4,
    });
    let observations: Vec<Observation> = observations.into_iter().chain(angles).collect();
    let lines = (0..observations.len()).map(|i| i + 2).collect();
    KindData { joints, observations, lines, ..KindData::default() }
}

/// Every column of `H` (robot parameters and set-up) against central differences of the
/// residuals: `H = -dy/dx`.
fn check_kind_jacobians(model: &RobotModel, u: &[f64], angles: bool) -> Result<(), TestCaseError> {
    let tool = Vector3::new(u[0], u[1], u[2]) * 200.0;
    let chain = match angles {
        true => Chain::probe(model, &Placement { xyz: tool, rpy: Vector3::new(u[7], u[8], u[9]) }),
        false => Chain::markers(model, &[tool]).remove(0),
    };
    let params = chain.params();
    let (_, x) = point(model, &u[20..]);
    let x: Vec<f64> = (0..params.len()).map(|i| x[i % x.len()]).collect();
    let data = every_kind(model, u, angles);
    let setup =
        SetUp::new(1, &[Vector3::new(u[3], u[4], 1.0), Vector3::new(1.0, u[5], u[6])]).with_pair_zero();
    let s: Vec<f64> =
        (0..setup.len()).map(|i| u[(i + 11) % u.len()] * if i % 3 == 2 { 300.0 } else { 0.3 }).collect();
    let all = Selection::all(params);
    let every: Vec<usize> = (0..setup.len()).collect();
    let problem = KindProblem::new(&chain, &all, &data, &setup, x.clone(), s.clone(), every, None);
    h_matches_finite_differences(&problem, &data)
}

/// [`check_kind_jacobians`] with marker positions: markers 1 and 3 and the tool point, one
/// chain each sharing the parameters ([`Chain::markers`]), each marker's x, y, z at three
/// poses (two markers at one) with every kind of the tool point's; with `angles`, roll, pitch
/// and yaw too, the tool a frame ([`Chain::markers_and_probe`]); with `camera`, a camera's
/// views at two poses too (the tool's frame, the rotation rows of every point's `H_j`); with
/// `tracker`, the markers read in a tracker frame placed away from the measuring frame
/// ([`SetUp::with_tracker`]); with `probe`, marker 1 a 6-DOF probe's frame
/// ([`Chain::marker_ends`]), its orientation measured at two poses too.
fn check_marker_jacobians(
    model: &RobotModel,
    u: &[f64],
    angles: bool,
    (camera, tracker, probe): (Option<CameraSite>, bool, bool),
) -> Result<(), TestCaseError> {
    use robocal::kinematics::MarkerEnd;
    let points = [0, 7, 3].map(|i| Vector3::new(u[i], u[i + 1], u[i + 2]) * 200.0);
    let frame = |at: usize, rpy: usize| Placement {
        xyz: points[at],
        rpy: Vector3::new(u[rpy], u[rpy + 1], u[rpy + 2]),
    };
    let first = if probe { MarkerEnd::Frame(frame(0, 13)) } else { MarkerEnd::Point(points[0]) };
    let tool =
        if angles || camera.is_some() { MarkerEnd::Frame(frame(2, 10)) } else { MarkerEnd::Point(points[2]) };
    let chains = Chain::marker_ends(model, &[first, MarkerEnd::Point(points[1]), tool]);
    let params = chains[0].params();
    let (_, x) = point(model, &u[20..]);
    let x: Vec<f64> = (0..params.len()).map(|i| x[i % x.len()]).collect();
    let mut data = every_kind(model, u, angles);
    for (pose, marker) in [(0, 0), (3, 2), (5, 0), (5, 2)] {
        for axis in 0..3 {
            let measured = 100.0 * u[axis + 30];
            data.observations.push(Observation::Marker { marker, axis, pose, measured, sigma: 0.01 });
            data.lines.push(data.lines.len() + 2);
        }
        if probe && marker == 0 {
            let measured =
                nalgebra::UnitQuaternion::from_scaled_axis(Vector3::new(u[34], u[35], u[36]) * 2.0);
            for axis in 0..3 {
                data.observations.push(Observation::Orientation {
                    marker,
                    axis,
                    pose,
                    measured,
                    sigma: 1e-4,
                });
                data.lines.push(data.lines.len() + 2);
            }
        }
    }
    let mut setup = SetUp::new(1, &[Vector3::new(u[3], u[4], 1.0), Vector3::new(1.0, u[5], u[6])]);
    // The points' and planes' values here; the point's length zero last, after the placements.
    let mut s: Vec<f64> =
        (0..setup.len() - 1).map(|i| u[(i + 11) % u.len()] * if i % 3 == 2 { 300.0 } else { 0.3 }).collect();
    if let Some(site) = camera {
        for pose in [1, 4] {
            let view = Vector6::from_fn(|i, _| u[40 + 6 * pose + i] * if i < 3 { 500.0 } else { 2.0 });
            for axis in 0..6 {
                data.observations.push(Observation::Camera { axis, pose, view, site, sigma: 0.1 });
                data.lines.push(data.lines.len() + 2);
            }
        }
        setup = setup.with_camera(site);
        s.extend((0..12).map(|i| u[70 + i] * if i % 6 < 3 { 300.0 } else { 2.0 }));
    }
    // With markers, the coordinates x, y, z are read in a device frame of their own.
    setup = setup.with_device();
    s.extend((0..6).map(|i| u[82 + i] * if i < 3 { 300.0 } else { 0.5 }));
    if tracker {
        setup = setup.with_tracker();
        s.extend((0..6).map(|i| u[89 + i] * if i < 3 { 300.0 } else { 0.5 }));
    }
    s.push(u[88] * 3.0);
    let all = Selection::all(params);
    let every: Vec<usize> = (0..setup.len()).collect();
    let problem = KindProblem::of_points(&chains, &[0, 2], &all, &data, &setup, x, s, every).with_noise(None);
    h_matches_finite_differences(&problem, &data)
}

/// Every column of `problem`'s `H` at its start against central differences of its residuals
/// (`y = m - f`), relative to the row's largest entry (or absolute below 1).
pub(crate) fn h_matches_finite_differences(
    problem: &KindProblem<'_>,
    data: &KindData,
) -> Result<(), TestCaseError> {
    h_matches_central_differences(problem, &problem.start(), |r| format!("{:?}", data.observations[r]))
}

/// Every column of `problem`'s `H` at `x0` against central differences of its residuals
/// (`y = m - f`), relative to the row's largest entry (or absolute below 1); `row` describes
/// a row in the message. A rotation residual `log(R_m R^T)` whose angle is at pi jumps by
/// about 2 pi across the step (the log's branch cut, where it has no derivative): such a row
/// and column (a change above 0.1 across a step of 2e-6 relative) is left out, and at most 2%
/// of the entries may be.
pub(crate) fn h_matches_central_differences(
    problem: &impl Residuals,
    x0: &DVector<f64>,
    row: impl Fn(usize) -> String,
) -> Result<(), TestCaseError> {
    let mut h = DMatrix::zeros(problem.equations(), problem.parameters());
    problem.evaluate(x0, Some(&mut h));
    let names = problem.names();
    let mut wrapped = 0;
    for c in 0..problem.parameters() {
        let step = 1e-6 * x0[c].abs().max(1.0);
        let (mut plus, mut minus) = (x0.clone(), x0.clone());
        plus[c] += step;
        minus[c] -= step;
        let change = problem.evaluate(&plus, None) - problem.evaluate(&minus, None);
        let fd: DVector<f64> = -&change / (2.0 * step);
        for r in 0..problem.equations() {
            if change[r].abs() > 0.1 {
                wrapped += 1;
                continue;
            }
            let gap = (h[(r, c)] - fd[r]).abs();
            prop_assert!(
                gap < 1e-5 * h.row(r).amax().max(1.0),
                "row {r} ({}), column {c} ({}): H {} against {}",
                row(r),
                names[c],
                h[(r, c)],
                fd[r]
            );
        }
    }
    // A case near the rotation log's branch cut (a random view turned by nearly pi) wraps many
    // entries: rejected, not failed (whether an entry wraps is the residuals', not H's).
    let entries = problem.equations() * problem.parameters();
    prop_assume!(wrapped * 50 <= entries, "entries across the log's branch cut");
    linearisation_is_the_whole_systems(problem, x0)
}

/// `problem`'s linearisation at `x0` (which may reduce its rows as they are built, `H` never
/// held) is the least-squares system of its whole whitened `A = S H` and `b = S y`:
/// `R^T R = A^T A` and `R^T z = A^T b` (ordinary least squares' weights: a view's rotation
/// rows scaled to lengths).
fn linearisation_is_the_whole_systems(
    problem: &impl Residuals,
    x0: &DVector<f64>,
) -> Result<(), TestCaseError> {
    let weights = robocal::estimation::Weights::for_problem(problem, Estimator::Ols).unwrap();
    let linearised = robocal::estimation::linearise(problem, &weights, x0.clone()).unwrap();
    let mut a = DMatrix::zeros(problem.equations(), problem.parameters());
    let b = problem.evaluate_whitened(x0, &weights, Some(&mut a));
    let r = linearised.system.r();
    let (gram, rtz) = (r.transpose() * r, r.transpose() * linearised.system.z());
    let (whole, atb) = (a.transpose() * &a, a.transpose() * &b);
    // The points' positions come from the walk that gives their H_j: the residuals to rounding.
    prop_assert!((&linearised.b - &b).amax() <= 1e-12 * b.amax().max(1.0), "y against the whole y");
    prop_assert!((&gram - &whole).amax() <= 1e-9 * whole.amax().max(1.0), "R^T R against A^T A");
    prop_assert!((&rtz - &atb).amax() <= 1e-9 * atb.amax().max(1.0), "R^T z against A^T b");
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(1000))]

    #[test]
    fn kind_jacobians_match_finite_differences_standard_dh(model in robot(Convention::StandardDh, true), u in prop::collection::vec(-1.0..1.0f64, 96)) {
        check_kind_jacobians(&model, &u, false)?;
    }

    #[test]
    fn kind_jacobians_match_finite_differences_urdf(model in robot(Convention::Urdf, false), u in prop::collection::vec(-1.0..1.0f64, 96)) {
        check_kind_jacobians(&model, &u, false)?;
    }

    #[test]
    fn marker_jacobians_match_finite_differences_modified_dh(model in robot(Convention::ModifiedDh, true), u in prop::collection::vec(-1.0..1.0f64, 96)) {
        check_marker_jacobians(&model, &u, false, (None, false, false))?;
    }

    #[test]
    fn marker_jacobians_match_finite_differences_urdf(model in robot(Convention::Urdf, false), u in prop::collection::vec(-1.0..1.0f64, 96)) {
        check_marker_jacobians(&model, &u, false, (None, false, false))?;
    }

    #[test]
    fn tracker_jacobians_match_finite_differences_modified_dh(model in robot(Convention::ModifiedDh, true), u in prop::collection::vec(-1.0..1.0f64, 96)) {
        check_marker_jacobians(&model, &u, false, (None, true, false))?;
    }

    #[test]
    fn tracker_and_camera_jacobians_match_finite_differences_urdf(model in robot(Convention::Urdf, false), u in prop::collection::vec(-1.0..1.0f64, 96)) {
        check_marker_jacobians(&model, &u, true, (Some(CameraSite::World), true, false))?;
    }

    #[test]
    fn marker_and_angle_jacobians_match_finite_differences_modified_dh(model in robot(Convention::ModifiedDh, true), u in prop::collection::vec(-1.0..1.0f64, 96)) {
        check_marker_jacobians(&model, &u, true, (None, false, false))?;
    }

    #[test]
    fn marker_and_camera_jacobians_match_finite_differences_standard_dh(model in robot(Convention::StandardDh, true), u in prop::collection::vec(-1.0..1.0f64, 96)) {
        check_marker_jacobians(&model, &u, false, (Some(CameraSite::Hand), false, false))?;
    }

    #[test]
    fn marker_and_camera_jacobians_match_finite_differences_urdf(model in robot(Convention::Urdf, false), u in prop::collection::vec(-1.0..1.0f64, 96)) {
        check_marker_jacobians(&model, &u, true, (Some(CameraSite::World), false, false))?;
    }

    #[test]
    fn probe_jacobians_match_finite_differences_standard_dh(model in robot(Convention::StandardDh, true), u in prop::collection::vec(-1.0..1.0f64, 96)) {
        check_marker_jacobians(&model, &u, false, (None, false, true))?;
    }

    #[test]
    fn probe_and_tracker_jacobians_match_finite_differences_urdf(model in robot(Convention::Urdf, false), u in prop::collection::vec(-1.0..1.0f64, 96)) {
        check_marker_jacobians(&model, &u, true, (None, true, true))?;
    }

    #[test]
    fn angle_jacobians_match_finite_differences_modified_dh(model in robot(Convention::ModifiedDh, true), u in prop::collection::vec(-1.0..1.0f64, 96)) {
        check_kind_jacobians(&model, &u, true)?;
    }
}

pub(crate) fn puma() -> RobotModel {
    RobotModel::preset("puma560").unwrap()
}

/// Random joint values within `model`'s limits.
pub(crate) fn random_pose(model: &RobotModel, rng: &mut ChaCha8Rng) -> Vec<f64> {
    model.joints.iter().map(|j| rng.random_range(j.limits[0]..j.limits[1])).collect()
}

/// Small parameter errors on the `kept` parameters of `chain` (the others zero).
pub(crate) fn errors_on(chain: &Chain, kept: &[String], rng: &mut ChaCha8Rng) -> Vec<f64> {
    let params = chain.params();
    let mut x = vec![0.0; params.len()];
    for name in kept {
        if let Some(i) = params.index_by_name(name) {
            let z: f64 = StandardNormal.sample(&mut *rng);
            x[i] = z * if params.get(i).kind.is_angle() { 0.1f64.to_radians() } else { 0.5 };
        }
    }
    x
}

pub(crate) const TOOL: Vector3<f64> = Vector3::new(20.0, -10.0, 120.0);

pub(crate) fn options(estimator: Estimator) -> KindOptions {
    KindOptions { estimator, tool: TOOL, ..KindOptions::default() }
}

/// What a set-up measures of the robot `real`: a function from the data's poses to the
/// observations, noise of `sigma` (mm) added.
type Measure = dyn Fn(&ChainAt, &mut ChaCha8Rng, f64) -> KindData;

/// Calibrate on exact data from errors on every parameter (the base's if `base_errors`): the training and held-out residuals
/// vanish. Then errors on the identifiable parameters only, measured with noise: every estimate
/// within 3 predicted standard errors of the truth (the set-up's too, when `setup_truth` is
/// given). Returns the noisy calibration.
/// The robot's parameters among the estimated `names` (not the set-up's).
pub(crate) fn robot_estimates(names: &[String], chain: &Chain) -> Vec<String> {
    names.iter().filter(|n| chain.params().index_by_name(n).is_some()).cloned().collect()
}

fn recovers(measure: &Measure, setup_truth: Option<&[f64]>, base_errors: bool, seed: u64) -> KindCalibration {
    recovers_with(measure, setup_truth, base_errors, None, false, seed)
}

/// [`recovers`], the noisy data weighted with the joint noise `sigma_q` too when given.
fn recovers_with(
    measure: &Measure,
    setup_truth: Option<&[f64]>,
    base_errors: bool,
    sigma_q: Option<DMatrix<f64>>,
    frame: bool,
    seed: u64,
) -> KindCalibration {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let model = puma();
    // Angles make the tool a frame, as the calibration does.
    let chain = match frame {
        true => Chain::probe(&model, &Placement { xyz: TOOL, rpy: Vector3::zeros() }),
        false => Chain::markers(&model, &[TOOL]).remove(0),
    };
    let all: Vec<String> = chain
        .params()
        .iter()
        .filter(|p| base_errors || !p.name.starts_with("base."))
        .map(|p| p.name.clone())
        .collect();
    let everything = errors_on(&chain, &all, &mut rng);
    let exact = measure(&chain.with_errors(&everything), &mut rng, 0.0);
    let c = calibrate_kinds(&model, &exact, &options(Estimator::Ols)).unwrap();
    assert!(c.training.lengths.1 < 1e-7, "exact data: training RMS {} mm after", c.training.lengths.1);
    assert!(
        c.training.lengths.0 > 1e3 * c.training.lengths.1,
        "before {} mm, after {} mm",
        c.training.lengths.0,
        c.training.lengths.1
    );
    let held_out = measure(&chain.with_errors(&everything), &mut rng, 0.0);
    let (before, after) = c.validate(&held_out).unwrap();
    assert!(after < 1e-6 && before > 0.1, "exact held-out RMS {before} mm before, {after} mm after");

    let robot = robot_estimates(&c.refined.estimate.names, &chain);
    let truth = errors_on(&chain, &robot, &mut rng);
    let noisy = measure(&chain.with_errors(&truth), &mut rng, 0.01);
    let weighted = KindOptions { joint_noise: sigma_q, ..options(Estimator::Wls) };
    let c = calibrate_kinds(&model, &noisy, &weighted).unwrap();
    let se = c.refined.estimate.standard_errors();
    let setup_names = c.setup.names();
    let mut checked = 0;
    for (k, name) in c.refined.estimate.names.iter().enumerate() {
        let (found, real) = match chain.params().index_by_name(name) {
            Some(i) => (c.after[i], truth[i]),
            None => match (setup_truth, setup_names.iter().position(|n| n == name)) {
                (Some(s), Some(i)) => (c.setup_values.1[i], s[i]),
                _ => continue,
            },
        };
        assert!((found - real).abs() < 3.0 * se[k], "{name}: {found} against {real}, SE {}", se[k]);
        checked += 1;
    }
    assert!(checked >= 20, "{checked} estimates checked");
    c
}

/// A ball bar from fixed point (400, 200, 300) mm: the distances of random poses.
pub(crate) fn ball_bar(real: &ChainAt, rng: &mut ChaCha8Rng, sigma: f64) -> KindData {
    let pivot = Vector3::new(400.0, 200.0, 300.0);
    let mut data = KindData::default();
    for k in 0..150 {
        let q = random_pose(&puma(), rng);
        let z: f64 = StandardNormal.sample(&mut *rng);
        let measured = (real.position(&q) - pivot).norm() + sigma * z;
        data.joints.push(q);
        data.observations.push(Observation::ToPoint { pose: k, point: 0, measured, sigma: sigma.max(0.01) });
        data.lines.push(k + 3);
    }
    data
}

/// A length artefact: the distances between pairs of random poses.
pub(crate) fn pairs(real: &ChainAt, rng: &mut ChaCha8Rng, sigma: f64) -> KindData {
    let mut data = KindData::default();
    for k in 0..150 {
        let (a, b) = (random_pose(&puma(), rng), random_pose(&puma(), rng));
        let z: f64 = StandardNormal.sample(&mut *rng);
        let measured = (real.position(&a) - real.position(&b)).norm() + sigma * z;
        data.joints.extend([a, b]);
        data.observations.push(Observation::Distance {
            a: 2 * k,
            b: 2 * k + 1,
            measured,
            sigma: sigma.max(0.01),
        });
        data.lines.push(k + 3);
    }
    data
}

#[test]
fn a_ball_bar_calibrates_the_robot_and_its_pivot_without_the_base() {
    let pivot = [400.0, 200.0, 300.0];
    let c = recovers(&ball_bar, Some(&pivot), true, 61);
    assert_eq!(c.unseen, [Unseen::Base { absorbed_by: BaseAbsorber::Distances }]);
    let words = c.unseen[0].to_string();
    assert!(words.starts_with("base (6 parameters): distances cannot see the base placement"), "{words}");
    assert!(c.refined.estimate.names.iter().all(|n| !n.starts_with("base.")));
    assert!(c.refined.estimate.names.iter().any(|n| n == "point1.x"));
}

#[test]
fn distances_between_poses_calibrate_the_robot_without_the_base() {
    let c = recovers(&pairs, None, true, 62);
    assert_eq!(c.unseen, [Unseen::Base { absorbed_by: BaseAbsorber::Distances }]);
    assert!(c.refined.estimate.names.iter().all(|n| !n.starts_with("base.")));
}

/// Pairs measured with joint noise (0.01 deg on every joint, independent at the two poses of a
/// pair) and 0.005 mm on the distance: weighted by `V_k` with the joint noise of both poses,
/// the estimates lie within 3 standard errors.
#[test]
fn distances_with_joint_noise_are_weighted_by_both_poses() {
    let sigma_joint = 0.01f64.to_radians();
    let noisy_pairs = move |real: &ChainAt, rng: &mut ChaCha8Rng, sigma: f64| {
        let mut data = KindData::default();
        let read = |q: &[f64], rng: &mut ChaCha8Rng| -> Vec<f64> {
            q.iter()
                .map(|q| {
                    let z: f64 = StandardNormal.sample(&mut *rng);
                    q + if sigma > 0.0 { sigma_joint * z } else { 0.0 }
                })
                .collect()
        };
        for k in 0..200 {
            let (a, b) = (random_pose(&puma(), rng), random_pose(&puma(), rng));
            let z: f64 = StandardNormal.sample(&mut *rng);
            let measured =
                (real.position(&read(&a, rng)) - real.position(&read(&b, rng))).norm() + sigma * 0.5 * z;
            data.joints.extend([a, b]);
            data.observations.push(Observation::Distance { a: 2 * k, b: 2 * k + 1, measured, sigma: 0.005 });
            data.lines.push(k + 3);
        }
        data
    };
    let sigma_q = DMatrix::from_diagonal_element(6, 6, sigma_joint * sigma_joint);
    let c = recovers_with(&noisy_pairs, None, true, Some(sigma_q), false, 68);
    assert!(c.training.lengths.1 > 0.005, "the joint noise shows in the residuals: {:?}", c.training.lengths);
}

/// The planes of a cell in the robot's base frame: a table below, two walls.
const PLANES: [([f64; 3], f64); 3] =
    [([0.0, 0.0, 1.0], -350.0), ([1.0, 0.0, 0.0], 500.0), ([0.0, 1.0, 0.0], -450.0)];

/// Contacts with the first `count` planes of [`PLANES`]: random poses moved onto a plane by
/// turning joint 2 or 3 (Newton on the signed distance), those that reach it within the limits.
pub(crate) fn contacts(count: usize) -> impl Fn(&ChainAt, &mut ChaCha8Rng, f64) -> KindData {
    move |real, rng, sigma| {
        let model = puma();
        let mut data = KindData::default();
        let mut plane = 0;
        while data.observations.len() < 150 {
            let (n, d) = (Vector3::from(PLANES[plane].0), PLANES[plane].1);
            let z: f64 = StandardNormal.sample(&mut *rng);
            let target = d + sigma * z;
            let mut q = random_pose(&model, rng);
            let joint = if rng.random_bool(0.5) { 1 } else { 2 };
            for _ in 0..30 {
                let f = n.dot(&real.position(&q)) - target;
                let mut moved = q.clone();
                moved[joint] += 1e-6;
                let slope = (n.dot(&real.position(&moved)) - target - f) / 1e-6;
                if slope.abs() < 1e-3 {
                    break;
                }
                q[joint] -= (f / slope).clamp(-0.3, 0.3);
            }
            let limits = model.joints[joint].limits;
            if (n.dot(&real.position(&q)) - target).abs() > 1e-9
                || q[joint] < limits[0]
                || q[joint] > limits[1]
            {
                continue;
            }
            let pose = data.joints.len();
            data.joints.push(q);
            data.observations.push(Observation::Contact { pose, plane, sigma: sigma.max(0.01) });
            data.lines.push(pose + 3);
            plane = (plane + 1) % count;
        }
        data
    }
}

/// Contacts with three planes and a few distances between poses (a gauge length: contacts
/// alone cannot see the scale) recover the robot and the planes.
#[test]
fn plane_contacts_calibrate_the_robot_and_the_planes() {
    let with_a_length = |real: &ChainAt, rng: &mut ChaCha8Rng, sigma: f64| {
        let mut lengths = pairs(real, rng, sigma);
        lengths.observations.truncate(30);
        lengths.lines.truncate(30);
        contacts(3)(real, rng, sigma).join(&lengths)
    };
    let c = recovers(&with_a_length, None, true, 63);
    for (i, (normal, d)) in PLANES.iter().enumerate() {
        let (n, offset) = c.plane(i);
        // The normal towards the robot's side (the base frame's origin).
        let side = -d.signum();
        assert!((n - Vector3::from(*normal) * side).norm() < 1e-3, "plane {}: normal {n:?}", i + 1);
        assert!((offset - d * side).abs() < 0.5, "plane {}: offset {offset}", i + 1);
    }
    assert!(matches!(c.unseen[0], Unseen::Base { .. }), "{:?}", c.unseen);
    assert!(!c.unseen.contains(&Unseen::Scale), "{:?}", c.unseen);
    let plane = c.unseen.iter().find(|u| matches!(u, Unseen::Plane { plane: 1, .. })).expect("plane 1");
    let words = plane.to_string();
    assert!(
        words.starts_with("plane 1: normal (0.0000, 0.0000, 1.0000)")
            && words.contains("contacts cannot see motions within it"),
        "{words}"
    );
}

/// One horizontal plane cannot see turns about the vertical: the first joint's offset is held,
/// and said so.
#[test]
fn a_table_alone_cannot_see_turns_about_its_normal() {
    let model = puma();
    let chain = Chain::markers(&model, &[TOOL]).remove(0);
    let mut rng = ChaCha8Rng::seed_from_u64(64);
    let data = contacts(1)(&chain.with_errors(&vec![0.0; chain.params().len()]), &mut rng, 0.0);
    let c = calibrate_kinds(&model, &data, &options(Estimator::Ols)).unwrap();
    assert!(c.fixed.iter().map(Held::text).any(|f| f.starts_with("j1.theta")), "{:?}", c.fixed);
    assert!(c.refined.estimate.names.iter().all(|n| n != "j1.theta" && n != "j2.a"));
    assert!(
        c.fixed.iter().any(|f| matches!(f, Held::Scale { parameter } if parameter == "j2.a")),
        "{:?}",
        c.fixed
    );
    assert_eq!(c.unseen[..2], [Unseen::Base { absorbed_by: BaseAbsorber::Planes }, Unseen::Scale]);
    assert!(c.unseen[1].to_string().starts_with("scale: contacts alone cannot see it"));
    let Unseen::Plane { plane: 1, normal, offset_mm } = c.unseen[2] else { panic!("{:?}", c.unseen) };
    assert_eq!(normal, [0.0, 0.0, 1.0]);
    assert!((offset_mm + 350.0).abs() < 5e-4, "{offset_mm} mm");
    let words = c.unseen[2].to_string();
    assert!(words.starts_with("plane 1: normal (0.0000, 0.0000, 1.0000), offset -350.000 mm"), "{words}");
    // Not collapsed: exact contacts are fitted by a robot of the nominal scale.
    assert!(c.training.lengths.1 < 1e-7, "{:?}", c.training.lengths);
    let fitted = chain.with_errors(&c.after);
    let q = &data.joints[0];
    assert!(
        (fitted.position(q) - chain.with_errors(&vec![0.0; chain.params().len()]).position(q)).norm() < 1e-6
    );
}

/// A height gauge: the tool point's z in the measuring frame at 200 random poses of `real`,
/// with noise `sigma` (mm; its sigma column at least 0.01).
pub(crate) fn heights(real: &ChainAt, rng: &mut ChaCha8Rng, sigma: f64) -> KindData {
    let mut data = KindData::default();
    for k in 0..200 {
        let q = random_pose(&puma(), rng);
        let z: f64 = StandardNormal.sample(&mut *rng);
        let measured = real.position(&q).z + sigma * z;
        data.joints.push(q);
        data.observations.push(Observation::Coordinate {
            pose: k,
            axis: 2,
            measured,
            sigma: sigma.max(0.01),
        });
        data.lines.push(k + 3);
    }
    data
}

/// Heights only (a height gauge): z of the tool point in the measuring frame. The base's z,
/// roll and pitch are seen, its x, y and yaw are not; the robot's parameters are recovered.
#[test]
fn heights_alone_calibrate_what_they_see() {
    let c = recovers(&heights, None, false, 65);
    let names = &c.refined.estimate.names;
    assert!(names.iter().any(|n| n == "base.z"), "{names:?}");
    assert!(!names.iter().any(|n| n == "base.x" || n == "base.y" || n == "base.rz"), "{names:?}");
}

/// A height gauge and an inclinometer: z, roll and pitch of the tool. The base's z, roll and
/// pitch are seen, its x, y and yaw are not; the robot and the tool frame's turn are recovered.
#[test]
fn heights_and_tilts_calibrate_what_they_see() {
    let tilts = |real: &ChainAt, rng: &mut ChaCha8Rng, sigma: f64| {
        let mut data = KindData::default();
        for k in 0..150 {
            let q = random_pose(&puma(), rng);
            let pose = real.pose(&q);
            let (roll, pitch, _) = pose.rotation.euler_angles();
            let mut z = || -> f64 { StandardNormal.sample(&mut *rng) };
            let (zn, rn, pn) = (z(), z(), z());
            let observations = [
                Observation::Coordinate {
                    pose: k,
                    axis: 2,
                    measured: pose.translation.z + sigma * zn,
                    sigma: 0.01,
                },
                Observation::Coordinate { pose: k, axis: 3, measured: roll + sigma * 1e-3 * rn, sigma: 1e-5 },
                Observation::Coordinate {
                    pose: k,
                    axis: 4,
                    measured: pitch + sigma * 1e-3 * pn,
                    sigma: 1e-5,
                },
            ];
            data.joints.push(q);
            data.observations.extend(observations);
            data.lines.extend([k + 3; 3]);
        }
        data
    };
    let c = recovers_with(&tilts, None, false, None, true, 69);
    // Ordinary least squares counts the angles as lengths (286 mm/rad): on the same data its
    // standard errors stay within a factor of 3 of Gauss-Markov's; one radian counted as one
    // millimetre would all but drop the tilts.
    let mut rng = ChaCha8Rng::seed_from_u64(73);
    let chain = Chain::probe(&puma(), &Placement { xyz: TOOL, rpy: Vector3::zeros() });
    let data = tilts(&chain.with_errors(&vec![0.0; chain.params().len()]), &mut rng, 0.01);
    let se = |estimator| {
        let c = calibrate_kinds(&puma(), &data, &options(estimator)).unwrap();
        let se = c.refined.estimate.standard_errors();
        c.refined.estimate.names.iter().cloned().zip(se.iter().copied()).collect::<Vec<(String, f64)>>()
    };
    let (ols, wls) = (se(Estimator::Ols), se(Estimator::Wls));
    for ((name, o), (_, w)) in ols.iter().zip(&wls) {
        assert!(o / w < 3.0, "{name}: SE {o} by ols, {w} by wls");
    }
    let names = &c.refined.estimate.names;
    assert!(names.iter().any(|n| n == "base.rx") && names.iter().any(|n| n == "marker1.rx"), "{names:?}");
    assert!(!names.iter().any(|n| n == "base.x" || n == "base.y" || n == "base.rz"), "{names:?}");
    assert!(matches!(c.calibrated.tool, robocal::model::Tool::Frame(_)));
}

#[test]
fn kind_files_read_and_their_errors() {
    let model = puma();
    let read = |text: &str| KindData::from_csv_str(text, &model, None);
    let head = "# units: joints=deg, lengths=mm\n";
    let pairs = read(&format!(
        "{head}j1,j2,j3,j4,j5,j6,j1_b,j2_b,j3_b,j4_b,j5_b,j6_b,distance,sigma\n0,10,20,0,0,0,5,15,25,0,0,0,123.4,0.02\n"
    ))
    .unwrap();
    assert_eq!(pairs.joints.len(), 2);
    assert_eq!(pairs.observations, [Observation::Distance { a: 0, b: 1, measured: 123.4, sigma: 0.02 }]);
    let bar = read("# units: joints=deg, lengths=m\nj1,j2,j3,j4,j5,j6,point,distance\n0,10,20,0,0,0,2,0.5\n")
        .unwrap();
    assert_eq!(bar.observations, [Observation::ToPoint { pose: 0, point: 1, measured: 500.0, sigma: 0.01 }]);
    let planes = read(&format!("{head}j1,j2,j3,j4,j5,j6,plane\n0,10,20,0,0,0,1\n")).unwrap();
    assert_eq!(planes.observations, [Observation::Contact { pose: 0, plane: 0, sigma: 0.01 }]);
    let partial =
        read(&format!("{head}j1,j2,j3,j4,j5,j6,x,y,z\n0,10,20,0,0,0,,,812.5\n0,10,20,0,0,0,1,,2\n")).unwrap();
    assert_eq!(partial.observations.len(), 3);
    assert_eq!(
        partial.observations[0],
        Observation::Coordinate { pose: 0, axis: 2, measured: 812.5, sigma: 0.01 }
    );
    assert_eq!(partial.lines, [3, 4, 4]);
    let tilts =
        read(&format!("{head}j1,j2,j3,j4,j5,j6,roll,pitch,sigma_angle\n0,10,20,0,0,0,,2.5,0.001\n")).unwrap();
    let sigma = 0.001f64.to_radians();
    assert_eq!(
        tilts.observations,
        [Observation::Coordinate { pose: 0, axis: 4, measured: 2.5f64.to_radians(), sigma }]
    );
    assert!(tilts.has_angles() && tilts.sees_the_base());
    // A `kind` column mixes them in one file, each row using its own columns.
    let mixed = read(&format!(
        "{head}kind,j1,j2,j3,j4,j5,j6,j1_b,j2_b,j3_b,j4_b,j5_b,j6_b,distance,point,plane,z,sigma\n\
         pair,0,10,20,0,0,0,5,15,25,0,0,0,123.4,,,,0.02\n\
         point,0,10,20,0,0,0,,,,,,,300,2,,,\n\
         contact,0,10,20,0,0,0,,,,,,,,,3,,\n\
         coordinates,0,10,20,0,0,0,,,,,,,,,,812.5,\n"
    ))
    .unwrap();
    assert_eq!(
        mixed.observations,
        [
            Observation::Distance { a: 0, b: 1, measured: 123.4, sigma: 0.02 },
            Observation::ToPoint { pose: 2, point: 1, measured: 300.0, sigma: 0.01 },
            Observation::Contact { pose: 3, plane: 2, sigma: 0.01 },
            Observation::Coordinate { pose: 4, axis: 2, measured: 812.5, sigma: 0.01 },
        ]
    );
    assert_eq!(mixed.lines, [3, 4, 5, 6]);
    let mixed_error = |rows: &str| {
        read(&format!("{head}kind,j1,j2,j3,j4,j5,j6,distance,plane\n{rows}")).unwrap_err().to_string()
    };
    assert_eq!(
        mixed_error("ball,0,10,20,0,0,0,1,\n"),
        "line 3, column `kind`: `ball`: expected pair, point, contact, coordinates or camera"
    );
    assert_eq!(
        mixed_error("contact,0,10,20,0,0,0,1,\n"),
        "line 3, column `plane`: this kind of row needs a `plane` value"
    );
    assert_eq!(
        mixed_error("pair,0,10,20,0,0,0,1,\n"),
        "line 3, column `kind`: a pair needs the second pose's columns, <joint>_b"
    );
    let error = |text: &str| read(&format!("{head}{text}")).unwrap_err().to_string();
    assert_eq!(
        error("j1,j2,j3,j4,j5,j6,plane\n0,10,20,0,0,0,0\n"),
        "line 3, column `plane`: 0: expected a number 1, 2, ... (at most 1000)"
    );
    assert_eq!(
        error("j1,j2,j3,j4,j5,j6,distance\n0,10,20,0,0,0,-3\n"),
        "line 3, column `distance`: -3: expected a value > 0"
    );
    assert_eq!(
        error("j1,j2,j3,j4,j5,j6,x,y,z\n0,10,20,0,0,0,,,\n"),
        "line 3: no coordinate: give at least one of x, y, z, roll, pitch, yaw"
    );
    assert_eq!(
        error("j1,j2,j3,j4,j5,j6,j1_b,distance\n0,10,20,0,0,0,1,2\n"),
        "line 2: pairs of poses need every joint of the second pose: <joint>_b"
    );
    assert_eq!(
        error("j1,j2,j3,j4,j5,j6,distance,plane\n0,10,20,0,0,0,1,2\n"),
        "line 2: expected one kind: a `distance` column (pairs or to a `point`), a `plane` column, coordinates (x, y, z, roll, pitch, yaw), or a `camera` column (hand or world) with a camera's view of its target (x, y, z, roll, pitch, yaw); or a `kind` column naming each row's"
    );
}

/// A ball bar's file: `count` random poses of the true robot `real`, distances to the pivot
/// (400, 200, 300) mm with noise 0.005 mm, in the file format.
pub(crate) fn ball_bar_csv(real: &ChainAt, count: usize, rng: &mut ChaCha8Rng) -> String {
    let pivot = Vector3::new(400.0, 200.0, 300.0);
    let mut text = String::from("# units: joints=deg, lengths=mm\nj1,j2,j3,j4,j5,j6,distance,sigma\n");
    for _ in 0..count {
        let q = random_pose(&puma(), rng);
        let z: f64 = StandardNormal.sample(&mut *rng);
        let d = (real.position(&q) - pivot).norm() + 0.005 * z;
        let degrees: Vec<String> = q.iter().map(|v| format!("{:.9}", v.to_degrees())).collect();
        text += &format!("{},{d:.6},0.005\n", degrees.join(","));
    }
    text
}

/// `robocal calibrate-observations` on a ball bar's files: the report names what distances
/// cannot see, and the held-out RMS falls; a bad file is named with its line and column.
#[test]
fn the_command_calibrates_from_a_ball_bar_and_validates() {
    let dir = std::env::temp_dir().join(format!("robocal-kinds-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let mut rng = ChaCha8Rng::seed_from_u64(66);
    let chain = Chain::markers(&puma(), &[TOOL]).remove(0);
    let all: Vec<String> = chain.params().iter().map(|p| p.name.clone()).collect();
    let real = chain.with_errors(&errors_on(&chain, &all, &mut rng));
    let (train, test) = (dir.join("train.csv"), dir.join("test.csv"));
    std::fs::write(&train, ball_bar_csv(&real, 120, &mut rng)).unwrap();
    std::fs::write(&test, ball_bar_csv(&real, 60, &mut rng)).unwrap();
    let json = dir.join("report.json");
    let path = |p: &std::path::Path| p.to_str().unwrap().to_string();
    let output = assert_cmd::Command::cargo_bin("robocal")
        .unwrap()
        .args(["calibrate", "--model", "puma560", "--tool", "20,-10,120"])
        .args(["--data", &path(&train), "--validate", &path(&test), "--json", &path(&json)])
        .output()
        .unwrap();
    let text = String::from_utf8(output.stdout).unwrap();
    assert!(output.status.success(), "{text}{}", String::from_utf8_lossy(&output.stderr));
    assert!(text.contains("base (6 parameters): distances cannot see the base placement"), "{text}");
    assert!(text.contains("point1.x"), "{text}");
    let report: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    let held_out = &report["sets"][1][1]["lengths"];
    let (before, after) = (held_out[0].as_f64().unwrap(), held_out[1].as_f64().unwrap());
    assert_eq!(report["sets"][1][1]["observations"].as_array().unwrap().len(), 60);
    // What was held, typed in the JSON and the same in words: a combination with the pivot.
    let (held, fixed) = (report["held"].as_array().unwrap(), report["fixed"].as_array().unwrap());
    assert_eq!(held.len(), fixed.len());
    // The robot's parameter held with the pivot: of kind `confounded` (with `poses`), as a
    // marker file's report classifies it.
    let combination = held
        .iter()
        .position(|h| h["kind"] == "confounded" || h["kind"] == "combination")
        .expect("a combination held");
    let terms = held[combination]["terms"].as_array().unwrap();
    assert!(terms.iter().any(|t| t[0].as_str().unwrap().starts_with("point1.")), "{terms:?}");
    let words = fixed[combination].as_str().unwrap();
    assert!(
        words.starts_with(held[combination]["parameter"].as_str().unwrap()) && words.contains("point1."),
        "{words}"
    );
    assert!(
        after * 20.0 < before && after < 0.02,
        "held-out RMS {before} mm before, {after} mm after\n{text}"
    );

    std::fs::write(&test, "# units: joints=deg, lengths=mm\nj1,j2,j3,j4,j5,j6,distance\n0,1,2,3,4,5,-1\n")
        .unwrap();
    let output = assert_cmd::Command::cargo_bin("robocal")
        .unwrap()
        .args(["calibrate", "--model", "puma560", "--data", &path(&train), "--validate", &path(&test)])
        .output()
        .unwrap();
    assert_eq!(output.status.code(), Some(1));
    let message = String::from_utf8(output.stderr).unwrap();
    assert!(
        message.contains("test.csv")
            && message.contains("line 3, column `distance`: -1: expected a value > 0"),
        "{message}"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

/// `V_k` against Monte Carlo: the joints of each pose read with noise `Sigma_q`, independently
/// at the two poses of a pair; the sample variance of each observation's prediction over 4000
/// draws within 5 standard errors of the variance (`sqrt(2 / (n - 1))` relative) of `V_k`.
#[test]
fn the_covariance_of_each_kind_is_the_joint_noise_of_its_poses() {
    let model = puma();
    let chain = Chain::markers(&model, &[TOOL]).remove(0);
    let zero = vec![0.0; chain.params().len()];
    let at = chain.with_errors(&zero);
    let mut rng = ChaCha8Rng::seed_from_u64(67);
    let sigmas = [0.05f64, 0.05, 0.05, 0.02, 0.02, 0.02].map(f64::to_radians);
    let sigma_q = DMatrix::from_diagonal(&DVector::from_iterator(6, sigmas.iter().map(|s| s * s)));
    let joints: Vec<Vec<f64>> = (0..5).map(|_| random_pose(&model, &mut rng)).collect();
    let data = KindData {
        observations: vec![
            Observation::Distance { a: 0, b: 1, measured: 0.0, sigma: 1e-9 },
            Observation::ToPoint { pose: 2, point: 0, measured: 0.0, sigma: 1e-9 },
            Observation::Contact { pose: 3, plane: 0, sigma: 1e-9 },
            Observation::Coordinate { pose: 4, axis: 1, measured: 0.0, sigma: 1e-9 },
        ],
        lines: vec![2, 3, 4, 5],
        joints,
        ..KindData::default()
    };
    let setup = SetUp::new(1, &[Vector3::new(0.3, -0.2, 1.0)]);
    // The point, the plane, the point's length zero.
    let s = vec![400.0, 200.0, 300.0, 0.0, 0.0, -350.0, 0.0];
    let nothing = Selection::from_indices(chain.params(), []);
    let problem =
        KindProblem::new(&chain, &nothing, &data, &setup, zero, s.clone(), Vec::new(), Some(&sigma_q));
    let v = problem.covariance().unwrap().clone();
    let draws = 4000;
    let mut samples: Vec<Vec<f64>> = (0..4).map(|_| Vec::with_capacity(draws)).collect();
    for _ in 0..draws {
        let noisy: Vec<Vec<f64>> = (data.joints.iter())
            .map(|q| {
                q.iter()
                    .zip(&sigmas)
                    .map(|(q, s)| {
                        let z: f64 = StandardNormal.sample(&mut rng);
                        q + s * z
                    })
                    .collect()
            })
            .collect();
        let p: Vec<Vector3<f64>> = noisy.iter().map(|q| at.position(q)).collect();
        let (n, d) = setup.plane(&s, 0);
        samples[0].push((p[0] - p[1]).norm());
        samples[1].push((p[2] - Vector3::new(400.0, 200.0, 300.0)).norm());
        samples[2].push(n.dot(&p[3]) - d);
        samples[3].push(p[4].y);
    }
    for (k, values) in samples.iter().enumerate() {
        let mean = values.iter().sum::<f64>() / draws as f64;
        let variance = values.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (draws - 1) as f64;
        let relative = (variance / v[(k, 0)] - 1.0).abs();
        let tolerance = 5.0 * (2.0 / (draws - 1) as f64).sqrt();
        assert!(
            relative < tolerance,
            "{:?}: {variance} mm² sampled, V_k {} mm²",
            data.observations[k],
            v[(k, 0)]
        );
    }
}

/// The calibrated model (as `--out-model` writes it) is the fitted one: its tool point, at any
/// pose, is where the calibration's parameters put it.
#[test]
fn the_calibrated_model_is_the_fitted_one() {
    let mut rng = ChaCha8Rng::seed_from_u64(70);
    let model = puma();
    let chain = Chain::markers(&model, &[TOOL]).remove(0);
    let all: Vec<String> = chain.params().iter().map(|p| p.name.clone()).collect();
    let real = chain.with_errors(&errors_on(&chain, &all, &mut rng));
    let c = calibrate_kinds(&model, &ball_bar(&real, &mut rng, 0.01), &options(Estimator::Wls)).unwrap();
    let written = robocal::model::to_toml_with_markers(&c.calibrated, &[]);
    let read = RobotModel::from_toml_str(&written).unwrap();
    let calibrated = Chain::new(&read);
    let as_written = calibrated.with_errors(&vec![0.0; calibrated.params().len()]);
    let fitted = chain.with_errors(&c.after);
    for _ in 0..20 {
        let q = random_pose(&model, &mut rng);
        let gap = (as_written.position(&q) - fitted.position(&q)).norm();
        assert!(gap < 1e-6, "{gap} mm");
    }
}

/// Observations that cannot be fitted are refused with what is wrong, never a panic: too few
/// distances for a fixed point (a point number with a gap before it), too few contacts for a
/// plane, data built by hand with a pose that does not exist or a sigma of 0.
#[test]
fn observations_that_cannot_be_fitted_are_refused() {
    let model = puma();
    let mut rng = ChaCha8Rng::seed_from_u64(71);
    let joints: Vec<Vec<f64>> = (0..8).map(|_| random_pose(&model, &mut rng)).collect();
    let error = |observations: Vec<Observation>| {
        let lines = (0..observations.len()).map(|i| i + 3).collect();
        let data = KindData { joints: joints.clone(), observations, lines, ..KindData::default() };
        calibrate_kinds(&model, &data, &options(Estimator::Ols)).unwrap_err().to_string()
    };
    let to_point_2 =
        (0..8).map(|pose| Observation::ToPoint { pose, point: 1, measured: 500.0, sigma: 0.01 }).collect();
    assert_eq!(
        error(to_point_2),
        "fixed point 1: 0 distances, expected at least 4 from poses not on one plane"
    );
    let contacts = (0..2).map(|pose| Observation::Contact { pose, plane: 0, sigma: 0.01 }).collect();
    assert_eq!(error(contacts), "plane 1: 2 contacts, expected at least 3 not on one line");
    assert_eq!(
        error(vec![Observation::Distance { a: 0, b: 9, measured: 1.0, sigma: 0.01 }]),
        "line 3: a pose beyond the 8 given"
    );
    assert_eq!(
        error(vec![Observation::Contact { pose: 0, plane: 0, sigma: 0.0 }]),
        "line 3: a finite value and a sigma above 0 expected"
    );
}

/// A length 0.1 mm (10 standard deviations) off among 150 is flagged by its whitened residual,
/// and only it; every observation is scored in the report.
#[test]
fn an_observation_far_out_is_flagged() {
    let mut rng = ChaCha8Rng::seed_from_u64(72);
    let model = puma();
    let chain = Chain::markers(&model, &[TOOL]).remove(0);
    let all: Vec<String> = chain.params().iter().map(|p| p.name.clone()).collect();
    let real = chain.with_errors(&errors_on(&chain, &all, &mut rng));
    let mut data = ball_bar(&real, &mut rng, 0.01);
    if let Observation::ToPoint { measured, .. } = &mut data.observations[40] {
        *measured += 0.1;
    }
    let c = calibrate_kinds(&model, &data, &options(Estimator::Wls)).unwrap();
    let report =
        robocal::report::observations::ObservationsReport::new(&c, "bar.csv", (150, 150), "wls", vec![]);
    assert_eq!(report.sets[0].1.observations.len(), 150);
    let line = data.lines[40];
    let [robocal::calibration::Warning::FarOut { observations, .. }] = report.warnings.as_slice() else {
        panic!("one warning of far-out observations: {:?}", report.warnings)
    };
    assert!(matches!(observations.as_slice(), [o] if o.line == line && o.label.as_deref() == Some("point")));
    assert!(report.text().contains(&format!("line {line} (point): a residual")), "{}", report.text());
    assert!(report.text().contains(&format!("training, line {line} (point)")));
}

/// A draw-wire's anchor, mm in the base frame: below and beside the robot.
const ANCHOR: Vector3<f64> = Vector3::new(700.0, -400.0, -300.0);

/// A draw-wire from [`ANCHOR`] to a point 1.8 mm off the last joint's axis of a PUMA 560 whose
/// every joint parameter is in error (5 times [`errors_on`]'s sizes): its lengths, noise of
/// 0.01 mm, at 150 poses from a narrow range (0.5 rad wide about one pose), as a real draw-wire
/// reaches them. Distances alone, from a narrow range, leave the last joints' parameters in a
/// flat, curved valley. The data, and the tool positions relative to the anchor at 50 other
/// poses of the range (the arm's state that a calibration must find).
fn draw_wire() -> (KindData, Vec<Vec<f64>>) {
    let mut rng = ChaCha8Rng::seed_from_u64(25);
    let model = puma();
    let chain = Chain::markers(&model, &[Vector3::new(1.5, -1.0, 60.0)]).remove(0);
    let robot: Vec<String> =
        chain.params().iter().filter(|p| !p.name.starts_with("base.")).map(|p| p.name.clone()).collect();
    let truth: Vec<f64> = errors_on(&chain, &robot, &mut rng).iter().map(|e| 5.0 * e).collect();
    let real = chain.with_errors(&truth);
    let centre = random_pose(&model, &mut rng);
    let near = |rng: &mut ChaCha8Rng| -> Vec<f64> {
        centre.iter().map(|c| c + 0.5 * (rng.random::<f64>() - 0.5)).collect()
    };
    let mut data = KindData::default();
    for k in 0..150 {
        let q = near(&mut rng);
        let z: f64 = StandardNormal.sample(&mut rng);
        let measured = (real.position(&q) - ANCHOR).norm() + 0.01 * z;
        data.joints.push(q);
        data.observations.push(Observation::ToPoint { pose: k, point: 0, measured, sigma: 0.01 });
        data.lines.push(k + 3);
    }
    let others = (0..50).map(|_| near(&mut rng)).collect();
    (data, others)
}

/// The tool positions of calibration `c` at the poses `others`, relative to its fixed point.
fn state(c: &KindCalibration, others: &[Vec<f64>]) -> Vec<Vector3<f64>> {
    let chain = Chain::new(&c.calibrated);
    let at = chain.with_errors(&vec![0.0; chain.params().len()]);
    let point = Vector3::new(c.setup_values.1[0], c.setup_values.1[1], c.setup_values.1[2]);
    others.iter().map(|q| at.position(q) - point).collect()
}

/// The draw-wire of [`draw_wire`] calibrated from three starts of the tool point (on the last
/// joint's axis, and 2 to 3 mm off it) converges within the default step limit from each, to
/// one estimate: the tool positions relative to the anchor at other poses within 1e-6 mm.
/// Gauss-Newton with its damping reset at every step (the solver before the trust region,
/// `robocal calibrate --model puma560 --tool 0,0,60 --iterations 1000` at 4c90724) stopped at
/// 1000 steps unconverged on these data; the trust region takes 40 to 60. The fit's valley is
/// real: `j5.theta` moves by 14 deg, its standard error 9 deg.
#[test]
fn a_draw_wire_converges_from_three_starts_to_one_estimate() {
    let (data, others) = draw_wire();
    let model = puma();
    let limit = RefineOptions::default().max_iterations;
    let mut states = Vec::new();
    for tool in [Vector3::new(0.0, 0.0, 60.0), Vector3::new(2.0, 1.0, 60.0), Vector3::new(-2.0, 3.0, 55.0)] {
        let c = calibrate_kinds(&model, &data, &KindOptions { tool, ..KindOptions::default() }).unwrap();
        let steps = c.refined.history.len();
        assert!(c.refined.converged && steps < limit, "from {tool:?}: {steps} steps");
        assert!(steps > 20, "from {tool:?}: {steps} steps, a valley no longer");
        assert!(!c.warnings.iter().any(|w| w.to_string().starts_with("not converged")), "{:?}", c.warnings);
        states.push(state(&c, &others));
    }
    for (k, s) in states.iter().enumerate().skip(1) {
        let miss = s.iter().zip(&states[0]).map(|(a, b)| (a - b).norm()).fold(0.0, f64::max);
        assert!(miss < 1e-6, "start {k}: {miss:e} mm from the first start's estimate");
    }
}

/// The draw-wire of [`draw_wire`] with its tool point started on the last joint's axis and
/// off it: the "before" fit (the tool point and the fixed point, the robot nominal) takes both
/// to one point 2.0 mm off the axis, where the gauge is found, so both hold the same parameters
/// (the last joint's, which the tool point absorbs; the third joint's `d`, the second's along the
/// parallel axis), the gauge found again at the estimate keeps as many as the start's (the start's
/// choice stands, no [`Warning::GaugeMoved`](robocal::calibration::Warning)), and every
/// estimate is within 1e-4 of its standard error from the other start's (the solver stops in the
/// flat valley of `j5.theta` 1.3e-5 of its standard error apart).
#[test]
fn a_tool_point_started_on_the_axis_is_gauged_as_one_started_off_it() {
    let (data, _) = draw_wire();
    let model = puma();
    let fit = |tool| calibrate_kinds(&model, &data, &KindOptions { tool, ..KindOptions::default() }).unwrap();
    let tools = [Vector3::new(0.0, 0.0, 60.0), Vector3::new(2.0, 1.0, 60.0)];
    let (on, off) = (fit(tools[0]), fit(tools[1]));
    let moved = |c: &KindCalibration| {
        c.warnings.iter().any(|w| matches!(w, robocal::calibration::Warning::GaugeMoved { .. }))
    };
    assert!(!moved(&on) && !moved(&off), "{:?}\n{:?}", on.warnings, off.warnings);
    let held = |c: &KindCalibration| c.fixed.iter().map(|h| h.parameter().to_string()).collect::<Vec<_>>();
    assert_eq!(held(&on), held(&off));
    assert!(
        held(&on).iter().any(|h| h == "j6.theta") && held(&on).iter().any(|h| h == "j3.d"),
        "{:?}",
        held(&on)
    );
    assert_eq!(on.refined.estimate.names, off.refined.estimate.names);
    let se = off.refined.estimate.standard_errors();
    for (k, name) in off.refined.estimate.names.iter().enumerate() {
        // The tool point's parameters are its errors from the tool started at.
        let from = |tool: Vector3<f64>| {
            ["x", "y", "z"].iter().position(|a| *name == format!("marker1.{a}")).map_or(0.0, |i| tool[i])
        };
        let (a, b) = (on.refined.estimate.x[k] + from(tools[0]), off.refined.estimate.x[k] + from(tools[1]));
        assert!((a - b).abs() < 1e-4 * se[k], "{name}: {a} from the axis, {b} off it, SE {}", se[k]);
    }
}

/// A robust fit counts every step of every reweighting against the one step limit: on the
/// draw-wire, Huber's loss with a limit of 30 stops at 30 steps in all, unconverged and said so.
#[test]
fn a_robust_fit_counts_its_reweightings_steps_against_one_limit() {
    let (data, _) = draw_wire();
    let refine = RefineOptions { max_iterations: 30, ..RefineOptions::default() };
    let options = KindOptions {
        tool: Vector3::new(0.0, 0.0, 60.0),
        refine,
        loss: Loss::Huber(1.345),
        ..KindOptions::default()
    };
    let c = calibrate_kinds(&puma(), &data, &options).unwrap();
    assert_eq!(c.refined.history.len(), 30);
    assert!(!c.refined.converged);
    assert!(
        c.warnings.iter().any(|w| w.to_string().starts_with("not converged in 30 steps")),
        "{:?}",
        c.warnings
    );
    let plenty = KindOptions { refine: RefineOptions::default(), ..options };
    let c = calibrate_kinds(&puma(), &data, &plenty).unwrap();
    let robust = c.robust.as_ref().unwrap();
    assert!(
        c.refined.converged && robust.settled,
        "{} steps, {} reweightings",
        c.refined.history.len(),
        robust.reweightings
    );
    assert!(c.refined.history.len() < plenty.refine.max_iterations);
}

/// A tool point or marker that is not finite, or beyond 1e6 mm, is refused before any solve,
/// naming which: a NaN tool point once hung the ball bar's sphere start (nalgebra's SVD of a
/// NaN matrix does not return) for every user of the library and the Python package.
#[test]
fn a_tool_or_marker_not_finite_is_refused_before_any_solve() {
    use robocal::calibration::CalibrationError;
    let model = RobotModel::preset("puma560").unwrap();
    let text = std::fs::read_to_string("examples/puma560-ballbar.csv").unwrap();
    let data = KindData::from_csv_str(&text, &model, None).unwrap();
    for (tool, markers, field) in [
        (Vector3::new(f64::NAN, 0.0, 0.0), vec![], "tool"),
        (Vector3::new(0.0, 2e6, 0.0), vec![], "tool"),
        (Vector3::zeros(), vec![Vector3::zeros(), Vector3::new(0.0, 0.0, f64::INFINITY)], "marker 2"),
    ] {
        let options = KindOptions { tool, markers, ..KindOptions::default() };
        match calibrate_kinds(&model, &data, &options) {
            Err(e @ CalibrationError::Point { .. }) => {
                let message = e.to_string();
                assert!(
                    message.starts_with(&format!("{field}: (")) && message.contains("finite"),
                    "{message}"
                );
            }
            other => panic!("{field}: {:?}", other.map(|c| c.training.lengths)),
        }
    }
    let text = std::fs::read_to_string("examples/puma560-measurements.csv").unwrap();
    let measured = crate::marker_data(&text, &model, None);
    let options = crate::marker_options(&model, Estimator::Ols, None, &[Vector3::new(f64::NAN, 0.0, 0.0)]);
    let refused = calibrate_kinds(&model, &measured, &options).unwrap_err();
    assert!(matches!(&refused, CalibrationError::Point { field: PointName::Marker(1), .. }), "{refused}");
}

/// A ball bar's noise given four times too small (its sigma column a quarter of the 0.05 mm
/// it was measured with, the joints exact): the residuals say so, once, the measurement
/// sigmas' factor within 20% of 4 (a variance from about 150 residuals is within 12% at one
/// standard deviation), with the cross-validated errors at the sigmas given and estimated; the
/// observations are flagged against the set's robust spread, so the noise given too small
/// flags none. Given right, the noise agrees and nothing is said.
#[test]
fn a_ball_bar_s_noise_is_checked_against_its_residuals() {
    use robocal::calibration::Warning;
    let chain = Chain::markers(&puma(), &[TOOL]).remove(0);
    let mut rng = ChaCha8Rng::seed_from_u64(41);
    let names: Vec<String> = ["j2.a", "j3.a", "j2.theta", "j3.theta"].iter().map(|s| s.to_string()).collect();
    let x = errors_on(&chain, &names, &mut rng);
    let data = ball_bar(&chain.with_errors(&x), &mut rng, 0.05);
    let small = KindData {
        observations: data.observations.iter().map(|o| o.with_sigma(0.0125)).collect(),
        ..data.clone()
    };
    let c = calibrate_kinds(&puma(), &small, &options(Estimator::Wls)).unwrap();
    let said: Vec<_> = (c.warnings.iter())
        .filter_map(|w| match w {
            Warning::NoiseDisagrees(n) => Some(*n),
            _ => None,
        })
        .collect();
    assert_eq!(said.len(), 1, "{:?}", c.warnings);
    let n = &said[0];
    assert!((n.measurement_factor / 4.0 - 1.0).abs() < 0.2, "factor {} against 4", n.measurement_factor);
    assert_eq!(n.joint_factor, None);
    assert!(n.cv_given > 0.0 && n.cv_estimated > 0.0, "{n:?}");
    assert!(c.training.flag_at > 3.0 * 5.0, "flagged beyond {}", c.training.flag_at);
    assert_eq!(c.training.flagged().count(), 0);
    assert!(!c.warnings.iter().any(|w| matches!(w, Warning::FarOut { .. })), "{:?}", c.warnings);
    let right = calibrate_kinds(&puma(), &data, &options(Estimator::Wls)).unwrap();
    assert!(!right.warnings.iter().any(|w| matches!(w, Warning::NoiseDisagrees(_))), "{:?}", right.warnings);
    assert!((right.training.flag_at - 5.0).abs() < 1.5, "{}", right.training.flag_at);
}

/// Training poses with joint values outside the robot's limits are a typed warning of the
/// calibration (its line and the joints, each pose once), not a line on standard error alone.
#[test]
fn poses_outside_the_limits_are_a_warning_of_the_calibration() {
    use robocal::calibration::{OutsidePose, Warning};
    let chain = Chain::markers(&puma(), &[TOOL]).remove(0);
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    let mut data = ball_bar(&chain.with_errors(&vec![0.0; chain.params().len()]), &mut rng, 0.01);
    let limits = puma().joints[0].limits;
    data.joints[2][0] = limits[1] + 0.1;
    let c = calibrate_kinds(&puma(), &data, &options(Estimator::Wls)).unwrap();
    let outside: Vec<&Warning> =
        c.warnings.iter().filter(|w| matches!(w, Warning::OutsideLimits { .. })).collect();
    let expected = Warning::OutsideLimits {
        robot: "puma560".into(),
        poses: vec![OutsidePose { line: data.lines[2], joints: vec!["j1".into()] }],
    };
    assert_eq!(outside, [&expected], "{:?}", c.warnings);
}
