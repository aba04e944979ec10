//! Marker positions as a kind of observation, fitted with the others in one calibration
//! (`calibrate-observations`): exact recovery from markers and a ball bar together, estimates
//! within 3 predicted standard errors with noise, the true robot from a marker file or a
//! probe's file alone, and the command on a marker file and a ball bar's file. (H against finite
//! differences: `kinds::marker_jacobians_match_finite_differences_*`.)

use crate::kinds::{TOOL, errors_on, options, puma, random_pose};
use nalgebra::{Isometry3, Vector3};
use rand::SeedableRng;
use rand::rngs::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};
use robocal::calibration::Kinds;
use robocal::calibration::kinds::{KindCalibration, KindData, KindOptions, Observation, calibrate_kinds};
use robocal::calibration::selection::{Criterion, select};
use robocal::estimation::{Estimator, RefineOptions};
use robocal::kinematics::{Chain, ChainAt};
use robocal::model::{Placement, Tool};
use robocal::table::Units;

/// Three markers on the last link (mm, its frame), as `--marker` gives them.
const MARKERS: [Vector3<f64>; 3] =
    [Vector3::new(60.0, 0.0, 90.0), Vector3::new(-30.0, 50.0, 90.0), Vector3::new(-30.0, -50.0, 90.0)];

/// The measuring device's frame: far from the robot's and turned (its base in the device's
/// frame), so that the registration has work to do.
pub(crate) fn device() -> Placement {
    Placement { xyz: Vector3::new(1500.0, -800.0, 300.0), rpy: Vector3::new(0.05, -0.03, 2.0) }
}

/// The ball bar's pivot, in the robot's base frame (mm).
const PIVOT: Vector3<f64> = Vector3::new(400.0, 200.0, 300.0);

/// The true robot: puma560 seen from [`device`], the three markers then the tool point, one
/// chain each, with errors `x`.
pub(crate) fn true_chains(x: &[f64]) -> Vec<ChainAt> {
    true_chains_with(x, TOOL)
}

/// [`true_chains`] with the tool point at `tool`.
fn true_chains_with(x: &[f64], tool: Vector3<f64>) -> Vec<ChainAt> {
    true_chains_seen(x, tool, device())
}

/// [`true_chains`] seen from a device whose frame places the robot's base at `base`.
pub(crate) fn true_chains_seen(x: &[f64], tool: Vector3<f64>, base: Placement) -> Vec<ChainAt> {
    let mut model = puma();
    model.base = base;
    let points: Vec<Vector3<f64>> = MARKERS.iter().copied().chain([tool]).collect();
    Chain::markers(&model, &points).iter().map(|c| c.with_errors(x)).collect()
}

/// The parameters of the markers and the tool (the chains' shared set).
pub(crate) fn chains() -> Vec<Chain> {
    let points: Vec<Vector3<f64>> = MARKERS.iter().copied().chain([TOOL]).collect();
    Chain::markers(&puma(), &points)
}

/// A marker file's observations: `poses` random poses, each marker's x, y, z measured with
/// noise `sigma` (mm); marker 2's z not measured at every third pose (an empty cell).
pub(crate) fn markers(real: &[ChainAt], poses: usize, rng: &mut ChaCha8Rng, sigma: f64) -> KindData {
    let mut data = KindData::default();
    for pose in 0..poses {
        let q = random_pose(&puma(), rng);
        for (marker, at) in real[..3].iter().enumerate() {
            let p = at.position(&q);
            for axis in (0..3).filter(|&a| !(marker == 1 && a == 2 && pose % 3 == 0)) {
                let z: f64 = StandardNormal.sample(&mut *rng);
                let measured = p[axis] + sigma * z;
                data.observations.push(Observation::Marker {
                    marker,
                    axis,
                    pose,
                    measured,
                    sigma: sigma.max(0.01),
                });
                data.lines.push(pose + 3);
            }
        }
        data.joints.push(q);
    }
    data
}

/// A ball bar from [`PIVOT`] (in the device's frame): the tool's distances at `poses` random
/// poses.
fn ball_bar(real: &[ChainAt], poses: usize, rng: &mut ChaCha8Rng, sigma: f64) -> KindData {
    let pivot = device().isometry() * nalgebra::Point3::from(PIVOT);
    let mut data = KindData::default();
    for pose in 0..poses {
        let q = random_pose(&puma(), rng);
        let z: f64 = StandardNormal.sample(&mut *rng);
        let measured = (real[3].position(&q) - pivot.coords).norm() + sigma * z;
        data.joints.push(q);
        data.observations.push(Observation::ToPoint { pose, point: 0, measured, sigma: sigma.max(0.01) });
        data.lines.push(pose + 3);
    }
    data
}

pub(crate) fn marker_options(estimator: Estimator) -> KindOptions {
    KindOptions { markers: MARKERS.to_vec(), ..options(estimator) }
}

/// Markers and a ball bar in one fit. Exact, from errors on every parameter: the training and
/// held-out residuals of both vanish, the pivot is found in the device's frame. With noise,
/// from errors on what the first fit identified: every joint and marker estimate, the pivot
/// and the base (its placement, the device's) within 3 predicted standard errors.
#[test]
fn markers_and_a_ball_bar_calibrate_the_robot_the_markers_the_base_and_the_pivot() {
    let mut rng = ChaCha8Rng::seed_from_u64(81);
    let chains = chains();
    let params = chains[0].params();
    let all: Vec<String> = params.iter().map(|p| p.name.clone()).collect();
    let everything = errors_on(&chains[0], &all, &mut rng);
    let real = true_chains(&everything);
    let exact = markers(&real, 40, &mut rng, 0.0).join(&ball_bar(&real, 100, &mut rng, 0.0));
    let c = calibrate_kinds(&puma(), &exact, &marker_options(Estimator::Ols)).unwrap();
    let (before, after) = c.training.markers.unwrap();
    assert!(after < 1e-7 && c.training.lengths.1 < 1e-7, "exact: {:?}", c.training);
    assert!(before > 1e3 * after, "markers before {before} mm, after {after} mm");
    let pivot = device().isometry() * nalgebra::Point3::from(PIVOT);
    let found = Vector3::from_column_slice(&c.setup_values.1[..3]);
    assert!((found - pivot.coords).norm() < 1e-6, "pivot {found:?} against {pivot:?}");
    let held_out = markers(&real, 20, &mut rng, 0.0).join(&ball_bar(&real, 30, &mut rng, 0.0));
    let score = c.score(&held_out).unwrap();
    assert!(score.markers.unwrap().1 < 1e-6 && score.lengths.1 < 1e-6, "held out: {score:?}");
    assert!(score.markers.unwrap().0 > 0.1, "held out before: {score:?}");
    assert!(c.unseen.is_empty(), "markers see the base: {:?}", c.unseen);

    // With noise: errors on what the exact fit identified, the base the device's.
    let identified: Vec<String> = c
        .refined
        .estimate
        .names
        .iter()
        .filter(|n| !n.starts_with("base.") && !n.starts_with("point"))
        .cloned()
        .collect();
    let truth = errors_on(&chains[0], &identified, &mut rng);
    let real = true_chains(&truth);
    let noisy = markers(&real, 60, &mut rng, 0.01).join(&ball_bar(&real, 150, &mut rng, 0.01));
    let c = calibrate_kinds(&puma(), &noisy, &marker_options(Estimator::Wls)).unwrap();
    let se = c.refined.estimate.standard_errors();
    let mut checked = 0;
    for (k, name) in c.refined.estimate.names.iter().enumerate() {
        let (found, real) = match (params.index_by_name(name), name.as_str()) {
            (_, n) if n.starts_with("base.") => continue,
            (Some(i), _) => (c.after[i], truth[i]),
            (None, n) => {
                let axis = ["point1.x", "point1.y", "point1.z"].iter().position(|p| *p == n).unwrap();
                (c.setup_values.1[axis], pivot[axis])
            }
        };
        assert!((found - real).abs() < 3.0 * se[k], "{name}: {found} against {real}, SE {}", se[k]);
        checked += 1;
    }
    assert!(checked >= 30, "{checked} estimates checked");
    // The base: the calibrated placement against the device's, position within 3 SE of the
    // base's x, y, z, orientation within 3 SE of its rx, ry, rz (small angles).
    let base_se = |axis: &str| {
        let k = c.refined.estimate.names.iter().position(|n| n == &format!("base.{axis}")).unwrap();
        se[k]
    };
    let gap: Isometry3<f64> = device().isometry().inverse() * c.calibrated.base.isometry();
    for (axis, v) in ["x", "y", "z"].iter().zip(gap.translation.vector.iter()) {
        assert!(v.abs() < 3.0 * base_se(axis), "base {axis}: {v} mm off, SE {}", base_se(axis));
    }
    for (axis, v) in ["rx", "ry", "rz"].iter().zip(gap.rotation.scaled_axis().iter()) {
        assert!(v.abs() < 3.0 * base_se(axis), "base {axis}: {v} rad off, SE {}", base_se(axis));
    }
}

/// A marker file in `calibrate`'s format: `poses` random poses of `real`, the three markers'
/// x, y, z with noise 0.01 mm, every cell measured.
pub(crate) fn marker_csv(real: &[ChainAt], poses: usize, rng: &mut ChaCha8Rng) -> String {
    marker_csv_with(real, poses, rng, 0.01)
}

/// [`marker_csv`] with noise `sigma` (mm) on each coordinate.
fn marker_csv_with(real: &[ChainAt], poses: usize, rng: &mut ChaCha8Rng, sigma: f64) -> String {
    let mut text =
        String::from("# units: joints=deg, lengths=mm\nj1,j2,j3,j4,j5,j6,x1,y1,z1,x2,y2,z2,x3,y3,z3\n");
    for _ in 0..poses {
        let q = random_pose(&puma(), rng);
        let mut cells: Vec<String> = q.iter().map(|v| format!("{:.9}", v.to_degrees())).collect();
        for at in &real[..3] {
            let p = at.position(&q);
            cells.extend(p.iter().map(|v| {
                let z: f64 = StandardNormal.sample(&mut *rng);
                format!("{:.9}", v + sigma * z)
            }));
        }
        text += &(cells.join(",") + "\n");
    }
    text
}

/// Gauss-Newton to the minimum: steps until they move no residual by 1e-12 mm.
fn to_the_minimum() -> RefineOptions {
    RefineOptions { step_tolerance: 1e-12, cost_tolerance: 0.0, ..RefineOptions::default() }
}

/// A marker file of `poses` poses of the true robot (errors on every parameter, seed `seed`),
/// each coordinate with noise `sigma` (mm), read as observations; the model and the true
/// chains.
fn marker_file_with(
    seed: u64,
    poses: usize,
    sigma: f64,
) -> (robocal::model::RobotModel, KindData, Vec<ChainAt>) {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let chains = chains();
    let all: Vec<String> = chains[0].params().iter().map(|p| p.name.clone()).collect();
    let real = true_chains(&errors_on(&chains[0], &all, &mut rng));
    let text = marker_csv_with(&real, poses, &mut rng, sigma);
    let model = puma();
    let observations = KindData::from_csv_str(&text, &model, None).unwrap();
    (model, observations, real)
}

/// [`marker_file_with`] of 0.01 mm of noise.
fn marker_file(seed: u64, poses: usize) -> (robocal::model::RobotModel, KindData, Vec<ChainAt>) {
    marker_file_with(seed, poses, 0.01)
}

/// The largest distance (mm) between marker 1 as `c` calibrated it (its model's tool point, as
/// a marker file's calibration writes it) and the true one (`real[0]`) over 100 random poses:
/// what the calibrated model predicts against the truth.
fn largest_error(c: &robocal::calibration::kinds::KindCalibration, real: &[ChainAt]) -> f64 {
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    let model = Chain::new(&c.calibrated);
    let model = model.with_errors(&vec![0.0; model.params().len()]);
    (0..100)
        .map(|_| random_pose(&puma(), &mut rng))
        .map(|q| (model.position(&q) - real[0].position(&q)).norm())
        .fold(0.0, f64::max)
}

/// A marker file alone (the registration, the "before" fit of the base and markers, the gauge,
/// one row per coordinate): from noise-free data, the calibrated robot is the true one (its
/// marker 1 within 1e-6 mm of the truth's at other poses, every training residual gone); with
/// noise, ordinary least squares and `wls` with a measurement sigma alone (`V_k = sigma^2 I`)
/// give the same estimates (1e-6 relative) and standard errors (1e-5), the residuals' spread's
/// (no sigma in the file, the joints exact); the training RMS is that of the markers' position
/// errors, each marker at each pose one row of the pose table (its line, 3 coordinates); the
/// calibrated marker 1 is within 0.05 mm (5 times the coordinates' noise) of the truth.
#[test]
fn a_marker_file_alone_calibrates_the_true_robot() {
    let refine = to_the_minimum();
    let (model, exact, real) = marker_file_with(82, 50, 0.0);
    for estimator in [Estimator::Ols, Estimator::Wls] {
        let c =
            calibrate_kinds(&model, &exact, &KindOptions { refine, ..marker_options(estimator) }).unwrap();
        let (before, after) = c.training.markers.unwrap();
        let error = largest_error(&c, &real);
        assert!(
            before > 0.5 && after < 1e-6 && error < 1e-6,
            "{estimator:?}: {before} -> {after} mm, {error} mm"
        );
    }
    let (model, observations, real) = marker_file(82, 50);
    assert_eq!(observations.observations.len(), 50 * 9);
    let fit = |estimator| {
        calibrate_kinds(&model, &observations, &KindOptions { refine, ..marker_options(estimator) }).unwrap()
    };
    let (ols, c) = (fit(Estimator::Ols), fit(Estimator::Wls));
    assert_eq!(c.refined.estimate.names, ols.refined.estimate.names);
    let (se, found_se) = (ols.refined.estimate.standard_errors(), c.refined.estimate.standard_errors());
    for (k, name) in ols.refined.estimate.names.iter().enumerate() {
        let i = ols.params.index_by_name(name).unwrap();
        let (a, b) = (c.after[i], ols.after[i]);
        assert!((a - b).abs() <= 1e-6 * b.abs().max(se[k]), "{name}: wls {a} against ols {b}, SE {}", se[k]);
        assert!((found_se[k] - se[k]).abs() <= 1e-5 * se[k], "{name}: SE {} against {}", found_se[k], se[k]);
    }
    assert!(c.variance_factor.is_some() && ols.variance_factor.is_some());
    let error = largest_error(&c, &real);
    assert!(error < 0.05, "marker 1 within {error} mm of the truth");
    assert_eq!(c.training.positions.len(), 50 * MARKERS.len());
    let mut squares = (0.0, 0.0);
    for (k, p) in c.training.positions.iter().enumerate() {
        assert_eq!((p.line, p.marker, p.coordinates), (k / MARKERS.len() + 3, k % MARKERS.len() + 1, 3));
        squares = (squares.0 + p.error.0.powi(2), squares.1 + p.error.1.powi(2));
    }
    let n = c.training.positions.len() as f64;
    let (rms, by_positions) = (c.training.markers.unwrap(), ((squares.0 / n).sqrt(), (squares.1 / n).sqrt()));
    assert!(
        (rms.0 - by_positions.0).abs() < 1e-9 && (rms.1 - by_positions.1).abs() < 1e-12,
        "{rms:?}: {by_positions:?}"
    );
}

/// With joint noise, Gauss-Markov weighs each pose by its full `V_k` (its three markers
/// correlated through the pose's joint noise, one block a pose): from noise-free data the
/// calibrated robot is the true one (marker 1 within 1e-6 mm at other poses); with noise, the
/// joint noise adds to every standard error (each at least the one without it) and moves the
/// estimate (by more than 0.01 of a standard error somewhere), and the calibrated marker 1 is
/// within 0.05 mm (5 times the coordinates' noise) of the truth at other poses (measured 0.031).
#[test]
fn with_joint_noise_a_marker_file_weighs_each_pose_as_one_block() {
    let sigmas: Vec<f64> =
        [0.007, 0.007, 0.007, 0.002, 0.002, 0.002].iter().map(|s: &f64| s.to_radians()).collect();
    let joint_noise = Some(nalgebra::DMatrix::from_diagonal(&nalgebra::DVector::from_iterator(
        6,
        sigmas.iter().map(|s| s * s),
    )));
    let refine = to_the_minimum();
    let weighted = KindOptions { refine, joint_noise, ..marker_options(Estimator::Wls) };
    let (model, exact, real) = marker_file_with(83, 40, 0.0);
    let given = |d: &KindData| {
        let sigma = 0.01;
        KindData {
            observations: d.observations.iter().map(|o| o.with_sigma(sigma)).collect(),
            assumed_sigmas: 0,
            ..d.clone()
        }
    };
    let c = calibrate_kinds(&model, &given(&exact), &weighted).unwrap();
    let error = largest_error(&c, &real);
    assert!(c.training.markers.unwrap().1 < 1e-6 && error < 1e-6, "{error} mm");
    let (model, observations, real) = marker_file(83, 40);
    let observations = given(&observations);
    let c = calibrate_kinds(&model, &observations, &weighted).unwrap();
    let plain =
        calibrate_kinds(&model, &observations, &KindOptions { joint_noise: None, ..weighted.clone() })
            .unwrap();
    let moved = more_noise_raises_every_se(&c, &plain, "the joint noise");
    assert!(moved > 0.01, "the joint noise moves no estimate: {moved} SE at most");
    let error = largest_error(&c, &real);
    assert!(error < 0.05, "marker 1 within {error} mm of the truth");
}

/// Asserts that `with`, a calibration weighted by more noise (`what`) than `without`, estimates
/// the same parameters, each with a standard error at least `without`'s; returns how far the
/// estimates moved, at most, in `with`'s standard errors.
fn more_noise_raises_every_se(with: &KindCalibration, without: &KindCalibration, what: &str) -> f64 {
    assert_eq!(with.refined.estimate.names, without.refined.estimate.names);
    let (se, without_se) =
        (with.refined.estimate.standard_errors(), without.refined.estimate.standard_errors());
    let mut moved = 0.0f64;
    for (k, name) in with.refined.estimate.names.iter().enumerate() {
        assert!(
            se[k] >= without_se[k] * (1.0 - 1e-9),
            "{name}: SE {} with {what}, {} without",
            se[k],
            without_se[k]
        );
        let i = with.params.index_by_name(name).unwrap();
        moved = moved.max((with.after[i] - without.after[i]).abs() / se[k]);
    }
    moved
}

/// `--fixed-base` and `--fixed-markers` on observations: a robot measured in its own base
/// frame by markers at known places, its joints' errors alone. Neither the base nor a marker is
/// estimated nor registered, only joint parameters; from noise-free data the calibrated robot
/// fits every marker exactly (what the poses cannot tell apart held, its combination absorbed)
/// and is the true one (marker 1 within 1e-6 mm of the truth's at other poses).
#[test]
fn with_the_base_and_markers_fixed_a_marker_file_calibrates_the_joints() {
    let mut rng = ChaCha8Rng::seed_from_u64(84);
    let chains = chains();
    let joints: Vec<String> =
        chains[0].params().iter().filter(|p| p.name.starts_with('j')).map(|p| p.name.clone()).collect();
    let truth = errors_on(&chains[0], &joints, &mut rng);
    let real = true_chains_seen(&truth, TOOL, puma().base);
    let text = marker_csv_with(&real, 40, &mut rng, 0.0);
    let model = puma();
    let observations = KindData::from_csv_str(&text, &model, None).unwrap();
    let refine = to_the_minimum();
    let fixed = KindOptions {
        refine,
        estimate_base: false,
        estimate_markers: false,
        ..marker_options(Estimator::Ols)
    };
    let c = calibrate_kinds(&model, &observations, &fixed).unwrap();
    assert!(c.registered_base.is_none());
    let names = &c.refined.estimate.names;
    assert!(names.iter().all(|n| n.starts_with('j')), "only joints estimated: {names:?}");
    let (before, after) = c.training.markers.unwrap();
    assert!(before > 0.5 && after < 1e-6, "marker RMS {before} mm before, {after} mm after");
    let error = largest_error(&c, &real);
    assert!(error < 1e-6, "marker 1 within {error} mm of the truth");
    // Estimated (the default), the markers absorb the last joint's parameters: fixed, they do not.
    let free =
        calibrate_kinds(&model, &observations, &KindOptions { refine, ..marker_options(Estimator::Ols) });
    let free = free.unwrap();
    assert!(free.refined.estimate.names.len() > names.len() + 6, "{:?}", free.refined.estimate.names);
}

/// A laser tracker's covariance (anisotropic, varying over the workspace) at each measured
/// marker: a marker file fitted with the device's rows in `V_k` ([`KindData::with_device`]):
/// from noise-free data the calibrated robot is the true one (marker 1 within 1e-6 mm at other
/// poses); with noise, the device's rows add to every standard error (each at least the one of
/// `sigma_me` alone) and move the estimate by more than 0.05 of a standard error somewhere. A
/// point measured along some axes only is refused, naming its line.
#[test]
fn a_devices_covariance_weighs_marker_observations() {
    use robocal::estimation::NoiseSpec;
    let model = puma();
    let spec = NoiseSpec::from_toml_str(
        "joint_sigma = [0.007, 0.007, 0.007, 0.002, 0.002, 0.002]\nsigma_me_mm = 0.005\n[device]\n\
         kind = \"laser-tracker\"\nposition_mm = [0.0, 0.0, 0.0]\nsigma_r_mm = 0.04\nk_ppm = 20.0\n\
         sigma_angle_arcsec = 8.0\n",
        &model,
    )
    .unwrap();
    let device = spec.device.clone().unwrap();
    let refine = to_the_minimum();
    let sigma_me = spec.sigma_me.unwrap();
    let read = |observations: &KindData| KindData {
        observations: observations.observations.iter().map(|o| o.with_sigma(sigma_me)).collect(),
        assumed_sigmas: 0,
        ..observations.clone()
    };
    let kinds =
        KindOptions { refine, joint_noise: Some(spec.joint.clone()), ..marker_options(Estimator::Wls) };
    let (_, exact, real) = marker_file_with(85, 40, 0.0);
    let c = calibrate_kinds(&model, &read(&exact).with_device(|p| device.covariance(p)).unwrap(), &kinds)
        .unwrap();
    let error = largest_error(&c, &real);
    assert!(error < 1e-6, "marker 1 within {error} mm of the truth");
    let (_, observations, _) = marker_file(85, 40);
    let read = read(&observations);
    let with_device = read.clone().with_device(|p| device.covariance(p)).unwrap();
    let c = calibrate_kinds(&model, &with_device, &kinds).unwrap();
    let without = calibrate_kinds(&model, &read, &kinds).unwrap();
    let largest_without = more_noise_raises_every_se(&c, &without, "the device");
    assert!(largest_without > 0.05, "without the device: {largest_without} SE at most from the fit with it");

    let partial =
        observations.keeping(|o| !matches!(o, Observation::Marker { marker: 0, axis: 2, pose: 3, .. }));
    let e = partial.with_device(|p| device.covariance(p)).unwrap_err();
    assert!(e.to_string().starts_with("line 6") && e.to_string().contains("x, y and z"), "{e}");

    // Coordinates: a row of x, y and z takes the device's covariance there; a height (z alone)
    // is another instrument's, its sigma alone.
    let coordinate = |axis, pose, measured| Observation::Coordinate { axis, pose, measured, sigma: 0.01 };
    let p = Vector3::new(1000.0, -200.0, 300.0);
    let rows = KindData {
        joints: vec![vec![0.0; 6]; 2],
        observations: vec![
            coordinate(0, 0, p.x),
            coordinate(1, 0, p.y),
            coordinate(2, 0, p.z),
            coordinate(2, 1, 5.0),
        ],
        lines: vec![3, 3, 3, 4],
        ..KindData::default()
    };
    let rows = rows.with_device(|p| device.covariance(p)).unwrap();
    let c = device.covariance(&p).unwrap();
    assert!(c[(0, 0)] > 1e-4 && c[(0, 1)].abs() > 1e-8, "an anisotropic covariance: {c}");
    for (k, row) in rows.device.iter().enumerate().take(3) {
        assert_eq!(*row, [c[(k, 0)], c[(k, 1)], c[(k, 2)]]);
        assert_eq!(rows.measurement_covariance(k, (k + 1) % 3), c[(k, (k + 1) % 3)]);
    }
    assert_eq!((rows.device[3], rows.measurement_covariance(3, 3)), ([0.0; 3], 0.01 * 0.01));
}

/// A marker file read as observations: one per cell, an empty cell not measured; the file's
/// units; its errors name the line and the column.
#[test]
fn marker_files_read_cell_by_cell() {
    let model = puma();
    let text = "# units: joints=deg, lengths=m\nj1,j2,j3,j4,j5,j6,x1,y1,z1,x3,y3,z3,sigma\n\
                0,10,20,30,40,50,1.0,2.0,3.0,,,0.5,0.00002\n";
    let data = KindData::from_csv_str(text, &model, None).unwrap();
    let expected = [(0, 0, 1000.0), (0, 1, 2000.0), (0, 2, 3000.0), (2, 2, 500.0)];
    assert_eq!(data.observations.len(), expected.len());
    for (o, (marker, axis, mm)) in data.observations.iter().zip(expected) {
        let Observation::Marker { marker: m, axis: a, pose: 0, measured, sigma } = *o else {
            panic!("{o:?}")
        };
        assert_eq!((m, a), (marker, axis));
        assert!((measured - mm).abs() < 1e-9 && (sigma - 0.02).abs() < 1e-12, "{o:?}");
    }
    assert_eq!(data.markers(), vec![0, 2]);
    let error = |text: &str| {
        KindData::from_csv_str(
            text,
            &model,
            Some(Units { joints_in_degrees: true, lengths_in_metres: false }),
        )
        .unwrap_err()
        .to_string()
    };
    let header = "j1,j2,j3,j4,j5,j6,x1,y1,z1\n";
    assert!(
        error(&format!("{header}0,0,0,0,0,0,1,x,3\n")).contains("line 2, column `y1`"),
        "{}",
        error(&format!("{header}0,0,0,0,0,0,1,x,3\n"))
    );
    assert!(error(&format!("{header}0,0,0,0,0,0,,,\n")).contains("line 2: no marker coordinate"));
    // A probe's orientation: three rows a pose where given; its cells all empty, not measured.
    let probe = "j1,j2,j3,j4,j5,j6,x1,y1,z1,qw,qx,qy,qz\n0,0,0,0,0,0,1,2,3,0,1,0,0\n0,0,0,0,0,0,1,2,3,,,,\n";
    let read = KindData::from_csv_str(
        probe,
        &model,
        Some(Units { joints_in_degrees: true, lengths_in_metres: false }),
    )
    .unwrap();
    assert_eq!(read.lines, [2, 2, 2, 2, 2, 2, 3, 3, 3]);
    let Observation::Orientation { marker: 0, axis: 1, pose: 0, measured, .. } = read.observations[4] else {
        panic!("{:?}", read.observations[4])
    };
    assert!((measured.angle() - std::f64::consts::PI).abs() < 1e-12, "{measured:?}");
    assert_eq!(read.probes(), vec![0]);
    let half = probe.replace(",,,,", ",1,,0,0");
    assert!(error(&half).contains("line 3, column `qx`"), "{}", error(&half));
    let two = "j1,j2,j3,j4,j5,j6,x1,y1,z1,x2,y2,z2,roll,pitch,yaw\n0,0,0,0,0,0,1,2,3,1,2,3,0,0,0\n";
    assert!(error(two).contains("need exactly one marker"), "{}", error(two));
    let other = "j1,j2,j3,j4,j5,j6,x1,y1,z1,distance\n0,0,0,0,0,0,1,2,3,4\n";
    assert!(error(other).contains("column `distance`: a marker file"), "{}", error(other));
    assert!(error("j1,j2,j3,j4,j5,j6,x1,y1\n").contains("marker 1 needs y1 and z1 too"));
}

/// `robocal calibrate-observations` on the example's marker file and ball bar file together
/// (the same true PUMA 560, `examples/make_puma560_data.rs` and `make_ballbar_data.rs`), each
/// validated on its held-out file: the markers' held-out RMS falls from 2.2 to 0.12 mm and the
/// ball bar's to 0.05 mm; the report names the tool point `tool.*` and the markers by number;
/// the calibrated model carries the markers. A bad cell of a marker file is named with its
/// file, line and column.
#[test]
fn the_command_fits_a_marker_file_and_a_ball_bar_together() {
    let dir = std::env::temp_dir().join(format!("robocal-markers-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let (json, model) = (dir.join("report.json"), dir.join("calibrated.toml"));
    let path = |p: &std::path::Path| p.to_str().unwrap().to_string();
    let output = assert_cmd::Command::cargo_bin("robocal")
        .unwrap()
        .args(["calibrate", "--model", "puma560", "--tool", "50,0,150"])
        .args(["--marker", "50,0,150", "--marker=-40,60,120"])
        .args(["--data", "examples/puma560-measurements.csv", "--data", "examples/puma560-ballbar.csv"])
        .args([
            "--validate",
            "examples/puma560-validation.csv",
            "--validate",
            "examples/puma560-ballbar-2.csv",
        ])
        .args(["--joint-sigma-deg", "0.007,0.007,0.007,0.002,0.002,0.002"])
        .args(["--json", &path(&json), "--out-model", &path(&model)])
        .output()
        .unwrap();
    let text = String::from_utf8(output.stdout).unwrap();
    assert!(output.status.success(), "{text}{}", String::from_utf8_lossy(&output.stderr));
    for expected in
        ["marker2.z", "tool.x", "point1.x", "base.rz", "examples/puma560-validation.csv markers (mm)"]
    {
        assert!(text.contains(expected), "{expected}: {text}");
    }
    assert!(!text.contains("marker3"), "{text}");
    // Two training files: each worst observation says which file it is in.
    assert!(text.contains("  training, examples/puma560-"), "{text}");
    // The base the markers' registration placed, as calibrate reports it.
    assert!(text.contains("base registered at xyz (1499.880, -299.565, 200.231) mm"), "{text}");
    // What was held, in calibrate's words (the README's marker report): grouped by why.
    for group in [
        "held fixed (12 parameters):\n",
        "  j1.theta, j1.d, j1.beta: with the base estimated they only move the whole robot: --fixed-base",
        "  j3.d, j3.beta, j4.beta, j5.beta: these poses cannot tell them from the others",
        "  j6.theta, j6.d, j6.a, j6.alpha, j6.beta: with the markers estimated they only move the markers",
        "the combinations held (the held parameter first; the others' estimates absorb it):\n  j1.theta - base.rz\n",
    ] {
        assert!(text.contains(group), "{group}: {text}");
    }
    let report: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    assert!((report["registered_base"][0].as_f64().unwrap() - 1499.88).abs() < 1e-2, "{report}");
    let rms = |set: usize, what: &str| {
        let v = &report["sets"][set][1][what];
        (v[0].as_f64().unwrap(), v[1].as_f64().unwrap())
    };
    let (before, after) = rms(1, "markers");
    assert!(before > 2.0 && after < 0.15, "held-out markers: {before} mm before, {after} mm after\n{text}");
    assert!(report["sets"][2][1].get("markers").is_none(), "a ball bar has no markers");
    let (before, after) = rms(2, "lengths");
    assert!(before > 0.5 && after < 0.08, "held-out ball bar: {before} mm before, {after} mm after\n{text}");
    assert_eq!(report["sets"][1][1]["observations"][0]["kind"], "marker x");
    assert_eq!(report["sets"][1][1]["observations"][0]["marker"], 1);
    // The training set's distances are a row of their own, not pooled with the markers'
    // coordinates: their RMS is the distances' alone.
    let training = &report["sets"][0][1];
    let distances: Vec<f64> = (training["observations"].as_array().unwrap().iter())
        .filter(|o| o["kind"] == "point")
        .map(|o| o["after"].as_f64().unwrap())
        .collect();
    let rms = (distances.iter().map(|d| d * d).sum::<f64>() / distances.len() as f64).sqrt();
    let group = &training["by_group"][0];
    assert_eq!((group["group"].as_str(), group["unit"].as_str()), (Some("distances"), Some("mm")), "{group}");
    assert!((group["rms"][1].as_f64().unwrap() - rms).abs() < 1e-12, "{group} against {rms}");
    assert_eq!(training["by_group"].as_array().unwrap().len(), 1, "the markers are their own row");
    assert!(report["sets"][1][1].get("by_group").is_none(), "a set of markers alone is one group");
    // Each marker's position RMS, as the markers' of all: sqrt(3 mean e_c^2) of its coordinates.
    for (k, m) in training["by_marker"].as_array().unwrap().iter().enumerate() {
        assert_eq!(m["marker"], k + 1, "{m}");
        let e: Vec<f64> = (training["observations"].as_array().unwrap().iter())
            .filter(|o| o["marker"] == k + 1)
            .map(|o| o["before"].as_f64().unwrap())
            .collect();
        let rms = (3.0 * e.iter().map(|v| v * v).sum::<f64>() / e.len() as f64).sqrt();
        assert_eq!(m["coordinates"], e.len(), "{m}");
        assert!((m["rms"][0].as_f64().unwrap() - rms).abs() < 1e-12, "{m} against {rms}");
    }
    assert_eq!(training["by_marker"].as_array().unwrap().len(), 2);
    assert!(text.contains("\ntraining marker 2 (mm) "), "{text}");
    assert!(text.contains("\ntraining distances (mm) ") && !text.contains("\ntraining (mm)"), "{text}");
    let calibrated = std::fs::read_to_string(&model).unwrap();
    assert_eq!(calibrated.matches("[[markers]]").count(), 2, "{calibrated}");

    let output = assert_cmd::Command::cargo_bin("robocal")
        .unwrap()
        .args(["calibrate", "--model", "puma560", "--data", "examples/puma560-ballbar.csv"])
        .args(["--marker", "50,0,150"])
        .output()
        .unwrap();
    assert_eq!(output.status.code(), Some(1));
    let message = String::from_utf8(output.stderr).unwrap();
    assert!(
        message.contains("1 --marker given, the files (examples/puma560-ballbar.csv) have 0 markers"),
        "{message}"
    );

    let bad = dir.join("bad.csv");
    std::fs::write(&bad, "# units: joints=deg, lengths=mm\nj1,j2,j3,j4,j5,j6,x1,y1,z1\n0,1,2,3,4,5,1,2,3\n0,1,2,3,4,5,1,2,mm\n")
        .unwrap();
    let output = assert_cmd::Command::cargo_bin("robocal")
        .unwrap()
        .args(["calibrate", "--model", "puma560", "--data", "examples/puma560-ballbar.csv"])
        .args(["--data", &path(&bad)])
        .output()
        .unwrap();
    assert_eq!(output.status.code(), Some(1));
    let message = String::from_utf8(output.stderr).unwrap();
    assert!(message.contains("bad.csv") && message.contains("line 4, column `z1`"), "{message}");
    std::fs::remove_dir_all(&dir).unwrap();
}

/// `robocal calibrate -q` of the example's marker file and ball bar fitted together (the tool
/// point and the two markers given) with `extra`.
fn with_a_ball_bar(extra: &[&str]) -> std::process::Output {
    assert_cmd::Command::cargo_bin("robocal")
        .unwrap()
        .args(["calibrate", "-q", "--model", "puma560", "--tool", "50,0,150"])
        .args(["--marker", "50,0,150", "--marker=-40,60,120"])
        .args(["--data", "examples/puma560-measurements.csv", "--data", "examples/puma560-ballbar.csv"])
        .args(extra)
        .output()
        .unwrap()
}

/// The marker file's flags with a ball bar: `--markers 2` fits marker 2 alone (on the held-out
/// file too), `--fixed-markers` holds it at `--marker`'s place, `--sigma-mm` is the sigma of the
/// rows without their own (the markers'; the ball bar's own 0.005 mm stays), each seen in the
/// JSON; a marker no file has, and `--fixed-base` with nothing that sees the base, are said.
#[test]
fn marker_flags_apply_to_marker_files_fitted_with_others() {
    let dir = std::env::temp_dir().join(format!("robocal-marker-flags-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let json = dir.join("report.json");
    let run = with_a_ball_bar;
    let output = run(&[
        "--markers",
        "2",
        "--fixed-markers",
        "--sigma-mm",
        "0.05",
        "--validate",
        "examples/puma560-validation.csv",
        "--json",
        json.to_str().unwrap(),
    ]);
    assert!(output.status.success(), "{}", String::from_utf8_lossy(&output.stderr));
    let report: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    let names: Vec<&str> =
        report["parameters"].as_array().unwrap().iter().map(|p| p["name"].as_str().unwrap()).collect();
    assert!(names.contains(&"tool.x") && names.contains(&"j2.a"), "{names:?}");
    assert!(!names.iter().any(|n| n.starts_with("marker")), "the markers are held: {names:?}");
    assert!(report.get("assumed_sigmas").is_none(), "every sigma given (--sigma-mm, the ball bar's column)");
    for set in [0, 1] {
        let observations = report["sets"][set][1]["observations"].as_array().unwrap();
        let markers: Vec<_> = observations.iter().filter(|o| o.get("marker").is_some()).collect();
        assert!(!markers.is_empty() && markers.iter().all(|o| o["marker"] == 2), "set {set}: marker 2 alone");
        // No joint noise: whitened = after / sigma.
        for o in observations {
            let sigma = o["after"].as_f64().unwrap() / o["whitened"].as_f64().unwrap();
            let expected = if o.get("marker").is_some() { 0.05 } else { 0.005 };
            assert!((sigma - expected).abs() < 1e-9 * expected, "{o}: sigma {sigma}, expected {expected}");
        }
    }
    let output = run(&["--markers", "3"]);
    assert_eq!(output.status.code(), Some(1));
    let message = String::from_utf8(output.stderr).unwrap();
    assert!(
        message.contains("--markers 3: no data file has marker 3") && message.contains("1, 2"),
        "{message}"
    );

    let output = assert_cmd::Command::cargo_bin("robocal")
        .unwrap()
        .args(["calibrate", "-q", "--model", "puma560", "--fixed-base"])
        .args(["--data", "examples/puma560-ballbar.csv", "--data", "examples/puma560-ballbar-2.csv"])
        .output()
        .unwrap();
    assert!(output.status.success(), "{}", String::from_utf8_lossy(&output.stderr));
    let message = String::from_utf8(output.stderr).unwrap();
    assert!(message.contains("--fixed-base holds the base, which no observation here sees"), "{message}");
    // Markers held where no --marker placed them: said, in either pipeline.
    for extra in [&[][..], &["--data", "examples/puma560-ballbar.csv"][..]] {
        let output = assert_cmd::Command::cargo_bin("robocal")
            .unwrap()
            .args(["calibrate", "-q", "--model", "puma560", "--fixed-markers", "--marker", "50,0,150"])
            .args(["--data", "examples/puma560-measurements.csv"])
            .args(extra)
            .output()
            .unwrap();
        assert!(output.status.success(), "{}", String::from_utf8_lossy(&output.stderr));
        let message = String::from_utf8(output.stderr).unwrap();
        assert!(
            message.contains("--fixed-markers: marker 2 is held at the tool frame's origin"),
            "{message}"
        );
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

/// `--noise` with a marker file and a ball bar: the file's joint sigmas and `sigma_me_mm` are
/// the flags' (`--joint-sigma-deg`, `--sigma-mm`: the same report to 1e-12), its `[prior]`
/// comes before `--prior`'s, a `[device]` weighs the markers; a marker measured along some axes
/// only (an empty cell) cannot take a device's covariance, which is said naming the file and
/// line; `--noise` with the sigma flags is a usage error.
#[test]
fn a_noise_file_gives_observation_files_their_noise() {
    let dir = std::env::temp_dir().join(format!("robocal-obs-noise-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let noise = dir.join("noise.toml");
    std::fs::write(&noise, "joint_sigma = [0.007, 0.007, 0.007, 0.002, 0.002, 0.002]\nsigma_me_mm = 0.02\n")
        .unwrap();
    let run = |extra: &[&str], json: &std::path::Path| {
        with_a_ball_bar(&[&["--json", json.to_str().unwrap()], extra].concat())
    };
    let report = |json: &std::path::Path| -> serde_json::Value {
        serde_json::from_str(&std::fs::read_to_string(json).unwrap()).unwrap()
    };
    let (by_file, by_flags) = (dir.join("file.json"), dir.join("flags.json"));
    let out = run(&["--noise", noise.to_str().unwrap()], &by_file);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let flags = ["--joint-sigma-deg", "0.007,0.007,0.007,0.002,0.002,0.002", "--sigma-mm", "0.02"];
    assert!(run(&flags, &by_flags).status.success());
    let (a, b) = (report(&by_file), report(&by_flags));
    let values = |r: &serde_json::Value, key: &str| -> Vec<f64> {
        r["parameters"].as_array().unwrap().iter().map(|p| p[key].as_f64().unwrap()).collect()
    };
    for key in ["value", "std_error"] {
        let (x, y) = (values(&a, key), values(&b, key));
        assert_eq!(x.len(), y.len());
        for (x, y) in x.iter().zip(&y) {
            assert!((x - y).abs() <= 1e-12 * y.abs().max(1.0), "{key}: {x} by the file, {y} by the flags");
        }
    }
    // The weights are the noise's, not the files' default sigmas'.
    let plain = report_of(&dir, &run);
    assert!(values(&a, "value") != values(&plain, "value"), "the noise changes the weights");
    // Without it the markers' 600 coordinates took the default sigma, and the report says so.
    assert_eq!(plain["assumed_sigmas"], 600, "{}", plain["assumed_sigmas"]);
    assert!(a.get("assumed_sigmas").is_none(), "sigma_me_mm given");

    std::fs::write(&noise, "joint_sigma = [0.007, 0.007, 0.007, 0.002, 0.002, 0.002]\nsigma_me_mm = 0.02\n[prior]\n\"j2.a\" = \"0.001mm\"\n")
        .unwrap();
    let out = run(&["--noise", noise.to_str().unwrap()], &by_file);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let j2a =
        report(&by_file)["parameters"].as_array().unwrap().iter().find(|p| p["name"] == "j2.a").cloned();
    let j2a = j2a.unwrap();
    assert!((j2a["prior_sd"].as_f64().unwrap() - 0.001).abs() < 1e-12, "{j2a}");

    // A device: its covariance at each marker measured (the ball bar's rows keep their sigma).
    let tracker = dir.join("tracker.json");
    let out = run(&["--noise", "examples/noise/laser-tracker-0.1mm.toml"], &tracker);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    assert!(values(&report(&tracker), "value") != values(&b, "value"), "the device weighs the markers");
    let text = std::fs::read_to_string("examples/puma560-measurements.csv").unwrap();
    let partial: Vec<String> = (text.lines().enumerate())
        .map(|(i, l)| if i == 4 { l.rsplit_once(',').unwrap().0.to_string() + "," } else { l.to_string() })
        .collect();
    let partial_file = dir.join("partial.csv");
    std::fs::write(&partial_file, partial.join("\n")).unwrap();
    let out = assert_cmd::Command::cargo_bin("robocal")
        .unwrap()
        .args(["calibrate", "-q", "--model", "puma560", "--data", partial_file.to_str().unwrap()])
        .args(["--noise", "examples/noise/laser-tracker-0.1mm.toml"])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(1));
    let message = String::from_utf8(out.stderr).unwrap();
    assert!(
        message.contains("partial.csv") && message.contains("line 5") && message.contains("x, y and z"),
        "{message}"
    );
    let out = run(&["--noise", noise.to_str().unwrap(), "--sigma-mm", "0.01"], &by_file);
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8(out.stderr).unwrap().contains("--noise gives the joint noise"));
    std::fs::remove_dir_all(&dir).unwrap();
}

/// The report of the plain run (the files' default sigmas, no joint noise) in `dir`.
fn report_of(
    dir: &std::path::Path,
    run: &dyn Fn(&[&str], &std::path::Path) -> std::process::Output,
) -> serde_json::Value {
    let json = dir.join("plain.json");
    assert!(run(&[], &json).status.success());
    serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap()
}

/// A file's kind, from its header, is the calibration that reads it: marker columns a marker
/// file, unless a marker cell is empty (an occlusion: read cell by cell, as observations);
/// an empty cell of another column, or in a comment, changes nothing.
#[test]
fn a_marker_file_with_an_occlusion_is_read_cell_by_cell() {
    use robocal::calibration::DataKind;
    let head = "# units: joints=deg, lengths=mm\nj1,j2,j3,j4,j5,j6,x1,y1,z1,x2,y2,z2,sigma\n";
    let kind = |rows: &str| DataKind::of_csv_str(&format!("{head}{rows}")).unwrap();
    assert_eq!(kind("0,1,2,3,4,5,1,2,3,4,5,6,0.01\n"), DataKind::Markers);
    assert_eq!(kind("0,1,2,3,4,5,1,2,3,4,5,6,\n# 0,1,2,3,4,5,,,,,,\n\n"), DataKind::Markers);
    assert_eq!(kind("0,1,2,3,4,5,1,2,3,4,5,6,\n0,1,2,3,4,5,1,2,3, ,5,6,\n"), DataKind::Observations);
    assert_eq!(kind("0,1,2,3,4,5,1,2,3,4,5,,\n"), DataKind::Observations);
    let other = |text: &str| DataKind::of_csv_str(text).unwrap();
    assert_eq!(other("j1,j2,j3,j4,j5,j6,distance\n0,1,2,3,4,5,100\n"), DataKind::Observations);
    assert_eq!(other("j1,camera,target,x,y,z,roll,pitch,yaw\n"), DataKind::TreeViews);
    // A probe's orientation not measured at a pose: read cell by cell too.
    let probe = "j1,j2,j3,j4,j5,j6,x1,y1,z1,qw,qx,qy,qz\n0,1,2,3,4,5,1,2,3,1,0,0,0\n";
    assert_eq!(other(probe), DataKind::Markers);
    assert_eq!(other(&format!("{probe}0,1,2,3,4,5,1,2,3,,,,\n")), DataKind::Observations);

    // The command fits such a file alone, every measured cell.
    let dir = std::env::temp_dir().join(format!("robocal-occluded-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let text = std::fs::read_to_string("examples/puma560-measurements.csv").unwrap();
    let occluded: Vec<String> = (text.lines().enumerate())
        .map(|(i, line)| match i % 7 == 3 {
            true => line.rsplitn(4, ',').last().unwrap().to_string() + ",,,",
            false => line.to_string(),
        })
        .collect();
    let path = dir.join("occluded.csv");
    std::fs::write(&path, occluded.join("\n") + "\n").unwrap();
    let out = assert_cmd::Command::cargo_bin("robocal")
        .unwrap()
        .args(["calibrate", "--model", "puma560", "--data", path.to_str().unwrap()])
        .args([
            "--marker",
            "50,0,150",
            "--marker=-40,60,120",
            "--validate",
            "examples/puma560-validation.csv",
        ])
        .output()
        .unwrap();
    let (report, stderr) = (String::from_utf8(out.stdout).unwrap(), String::from_utf8(out.stderr).unwrap());
    assert!(out.status.success(), "{report}{stderr}");
    let (poses, markers) = (text.lines().count() - 2, 2);
    let cells = 3 * markers * poses - 3 * (0..text.lines().count()).filter(|i| i % 7 == 3).count();
    assert!(stderr.contains(&format!("read {cells} marker coordinates at {poses} poses")), "{stderr}");
    assert!(report.contains(&format!("{poses} poses, 2 markers")), "{report}");
    let held_out = report.lines().find(|l| l.starts_with("examples/puma560-validation.csv markers")).unwrap();
    let after = crate::verdict_rms(held_out).1;
    assert!(after < 0.15, "held-out markers after: {held_out}");

    // evaluate scores it as calibrate reads it: --sigma-mm the sigma of its rows (no sigma
    // column), the joints exact: each whitened residual is the residual over 0.05 mm.
    let json = dir.join("evaluated.json");
    let out = assert_cmd::Command::cargo_bin("robocal")
        .unwrap()
        .args(["evaluate", "-q", "--model", "puma560", "--data", path.to_str().unwrap()])
        .args(["--joint-sigma-deg", "0", "--sigma-mm", "0.05", "--json", json.to_str().unwrap()])
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let scored: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    let rows = scored["observations"][0][1]["observations"].as_array().unwrap();
    assert_eq!(rows.len(), cells);
    for o in rows {
        let sigma = o["after"].as_f64().unwrap() / o["whitened"].as_f64().unwrap();
        assert!((sigma - 0.05).abs() < 1e-9, "{o}");
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

/// Marker observations that cannot be fitted are refused, each with one clear error: too few
/// complete positions to place the measuring frame, a held-out
/// marker the calibration does not have, the tool point's observations scored by a calibration
/// of markers alone.
#[test]
fn marker_observations_that_cannot_be_fitted_are_refused() {
    let mut rng = ChaCha8Rng::seed_from_u64(83);
    let real = true_chains(&vec![0.0; chains()[0].params().len()]);
    let model = puma();
    let message = |data: &KindData| {
        calibrate_kinds(&model, data, &marker_options(Estimator::Ols)).unwrap_err().to_string()
    };

    let mut two = markers(&real, 2, &mut rng, 0.0);
    two.observations.retain(|o| matches!(o, Observation::Marker { marker: 0, .. }));
    two.lines.truncate(two.observations.len());
    assert!(
        message(&two).contains("marker positions: 2 with x, y and z all measured, expected at least 3"),
        "{}",
        message(&two)
    );

    let c =
        calibrate_kinds(&model, &markers(&real, 20, &mut rng, 0.0), &marker_options(Estimator::Ols)).unwrap();
    let mut other = markers(&real, 5, &mut rng, 0.0);
    for o in &mut other.observations {
        if let Observation::Marker { marker, .. } = o {
            *marker = 6;
        }
    }
    let error = c.score(&other).unwrap_err().to_string();
    assert!(error.contains("marker 7: not among the calibration's markers (1, 2, 3)"), "{error}");
    let mut height = markers(&real, 5, &mut rng, 0.0);
    height.observations.push(Observation::Coordinate { axis: 2, pose: 0, measured: 500.0, sigma: 0.01 });
    height.lines.push(99);
    let error = c.score(&height).unwrap_err().to_string();
    assert!(error.contains("its tool point was not calibrated"), "{error}");
}

/// Markers and a wrist camera's views of a board in one fit: the camera's mounting in the last
/// link's frame (the tool point at its origin, held), the board placed in the device's frame,
/// the base estimated (the markers see it). Exact, from errors on every parameter but the held
/// tool point: the markers' and the views' residuals vanish, on held-out poses too. With noise
/// (0.01 mm on the markers, 0.5 mm and 0.1 deg on the views), from errors on what the exact fit
/// identified: the robot's, the markers', the camera's and the board's estimates within 3
/// predicted standard errors.
#[test]
fn markers_and_a_wrist_camera_calibrate_together() {
    use crate::camera::{truth, views};
    use robocal::calibration::kinds::CameraSite;
    use robocal::calibration::kinds::camera::{isometry, placement};
    let site = CameraSite::Hand;
    let mut setup = truth(site);
    let board = device().isometry() * isometry(&setup[6..]);
    setup.splice(6.., placement(&board).iter().copied());
    let mut rng = ChaCha8Rng::seed_from_u64(84);
    let chains = chains();
    let params = chains[0].params();
    let all: Vec<String> =
        params.iter().filter(|p| !p.name.starts_with("marker4.")).map(|p| p.name.clone()).collect();
    let everything = errors_on(&chains[0], &all, &mut rng);
    let real = true_chains_with(&everything, Vector3::zeros());
    let measure = |real: &[ChainAt], n: usize, sigma: (f64, f64), rng: &mut ChaCha8Rng| {
        markers(real, n, rng, sigma.0.min(0.01)).join(&views(&real[3], site, &setup, n, sigma, rng))
    };
    let exact = measure(&real, 40, (0.0, 0.0), &mut rng);
    let c = calibrate_kinds(&puma(), &exact, &marker_options(Estimator::Ols)).unwrap();
    assert!(c.training.markers.unwrap().1 < 1e-7 && c.training.lengths.1 < 1e-7, "{:?}", c.training);
    assert!(c.training.angles.unwrap().1 < 1e-7, "{:?}", c.training.angles);
    assert!(c.unseen.is_empty(), "{:?}", c.unseen);
    assert!(c.refined.estimate.names.iter().all(|n| !n.starts_with("marker4.")));
    let score = c.score(&measure(&real, 20, (0.0, 0.0), &mut rng)).unwrap();
    assert!(score.markers.unwrap().1 < 1e-6 && score.lengths.1 < 1e-6, "held out: {score:?}");

    let identified: Vec<String> = c
        .refined
        .estimate
        .names
        .iter()
        .filter(|n| params.index_by_name(n).is_some() && !n.starts_with("base."))
        .cloned()
        .collect();
    let truth_x = errors_on(&chains[0], &identified, &mut rng);
    let real = true_chains_with(&truth_x, Vector3::zeros());
    let noisy = measure(&real, 80, (0.5, 0.1), &mut rng);
    let c = calibrate_kinds(&puma(), &noisy, &marker_options(Estimator::Wls)).unwrap();
    let se = c.refined.estimate.standard_errors();
    let names = c.setup.names();
    let mut checked = 0;
    for (k, name) in c.refined.estimate.names.iter().enumerate() {
        let (found, real) = match params.index_by_name(name) {
            _ if name.starts_with("base.") => continue,
            Some(i) => (c.after[i], truth_x[i]),
            None => {
                let i = names.iter().position(|n| n == name).unwrap();
                (c.setup_values.1[i], setup[i])
            }
        };
        assert!((found - real).abs() < 3.0 * se[k], "{name}: {found} against {real}, SE {}", se[k]);
        checked += 1;
    }
    assert!(checked >= 35, "{checked} estimates checked");
}

/// Markers and an inclinometer's tilts (roll and pitch of the tool frame, in the measuring
/// frame) in one fit: the tool a frame after the markers, its rotation estimated
/// ([`Chain::markers_and_probe`]). Exact, from errors on every parameter: the markers' and the
/// tilts' residuals vanish, on held-out poses too. With noise (0.01 mm, 0.001 deg), from errors
/// on what the exact fit identified: every estimate but the base's within 3 predicted standard
/// errors.
#[test]
fn markers_and_tilts_calibrate_together() {
    let mut model = puma();
    model.base = device();
    let probe = Placement { xyz: TOOL, rpy: Vector3::zeros() };
    let truth_chains = Chain::markers_and_probe(&model, &MARKERS, &probe);
    let fitted = Chain::markers_and_probe(&puma(), &MARKERS, &probe);
    let params = fitted[0].params();
    let real = |x: &[f64]| -> Vec<ChainAt> { truth_chains.iter().map(|c| c.with_errors(x)).collect() };
    let measure = |real: &[ChainAt], n: usize, sigma: (f64, f64), rng: &mut ChaCha8Rng| {
        let mut tilts = KindData::default();
        for pose in 0..n {
            let q = random_pose(&puma(), rng);
            let (roll, pitch, _) = real[3].pose(&q).rotation.euler_angles();
            for (axis, angle) in [(3, roll), (4, pitch)] {
                let z: f64 = StandardNormal.sample(&mut *rng);
                let sigma = sigma.1.to_radians();
                let measured = angle + sigma * z;
                tilts.observations.push(Observation::Coordinate {
                    axis,
                    pose,
                    measured,
                    sigma: sigma.max(1e-5),
                });
                tilts.lines.push(pose + 3);
            }
            tilts.joints.push(q);
        }
        markers(real, n, rng, sigma.0).join(&tilts)
    };
    let mut rng = ChaCha8Rng::seed_from_u64(85);
    let all: Vec<String> = params.iter().map(|p| p.name.clone()).collect();
    let everything = errors_on(&fitted[0], &all, &mut rng);
    let exact = measure(&real(&everything), 40, (0.0, 0.0), &mut rng);
    let c = calibrate_kinds(&puma(), &exact, &marker_options(Estimator::Ols)).unwrap();
    assert!(c.training.markers.unwrap().1 < 1e-7, "{:?}", c.training);
    assert!(c.training.angles.unwrap().1 < 1e-7, "{:?}", c.training.angles);
    assert!(c.refined.estimate.names.iter().any(|n| n == "marker4.rx"), "{:?}", c.refined.estimate.names);
    let score = c.score(&measure(&real(&everything), 20, (0.0, 0.0), &mut rng)).unwrap();
    assert!(score.markers.unwrap().1 < 1e-6 && score.angles.unwrap().1 < 1e-6, "held out: {score:?}");

    let identified: Vec<String> =
        c.refined.estimate.names.iter().filter(|n| !n.starts_with("base.")).cloned().collect();
    let truth = errors_on(&fitted[0], &identified, &mut rng);
    let noisy = measure(&real(&truth), 80, (0.01, 0.001), &mut rng);
    let c = calibrate_kinds(&puma(), &noisy, &marker_options(Estimator::Wls)).unwrap();
    let se = c.refined.estimate.standard_errors();
    let mut checked = 0;
    for (k, name) in c.refined.estimate.names.iter().enumerate().filter(|(_, n)| !n.starts_with("base.")) {
        let i = params.index_by_name(name).unwrap();
        assert!(
            (c.after[i] - truth[i]).abs() < 3.0 * se[k],
            "{name}: {} against {}, SE {}",
            c.after[i],
            truth[i],
            se[k]
        );
        checked += 1;
    }
    assert!(checked >= 30, "{checked} estimates checked");
}

/// Heights given with a marker file are read in a device frame of their own (a height gauge
/// zeroed 150 mm below the tracker's z = 0): the device is estimated with the robot, and the
/// markers are fitted as well as without the heights.
#[test]
fn heights_with_markers_are_read_in_their_own_device_frame() {
    let dir = std::env::temp_dir().join(format!("robocal-heights-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    // Marker 1's z (the tool point) of the first 40 poses, 150 mm up: heights above the
    // gauge's zero.
    let text = std::fs::read_to_string("examples/puma560-measurements.csv").unwrap();
    let mut heights = String::from("# units: joints=deg, lengths=mm\nj1,j2,j3,j4,j5,j6,z\n");
    for line in text.lines().skip(2).take(40) {
        let cells: Vec<&str> = line.split(',').collect();
        let z: f64 = cells[8].parse().unwrap();
        heights += &format!("{},{}\n", cells[..6].join(","), z + 150.0);
    }
    let file = dir.join("heights.csv");
    std::fs::write(&file, heights).unwrap();
    let run = |data: &[&str]| {
        let mut command = assert_cmd::Command::cargo_bin("robocal").unwrap();
        command.args(["calibrate", "--model", "puma560", "--tool", "50,0,150"]);
        command.args([
            "--marker",
            "50,0,150",
            "--marker=-40,60,120",
            "--validate",
            "examples/puma560-validation.csv",
        ]);
        for d in data {
            command.args(["--data", d]);
        }
        let output = command.output().unwrap();
        assert!(output.status.success(), "{}", String::from_utf8_lossy(&output.stderr));
        String::from_utf8(output.stdout).unwrap()
    };
    let held_out = |text: &str| -> f64 {
        let line =
            text.lines().find(|l| l.starts_with("examples/puma560-validation.csv markers (mm)")).unwrap();
        crate::verdict_rms(line).1
    };
    let alone = run(&["examples/puma560-measurements.csv"]);
    let with_heights = run(&["examples/puma560-measurements.csv", file.to_str().unwrap()]);
    assert!(held_out(&with_heights) < 1.05 * held_out(&alone), "{with_heights}");
    let device_z = with_heights.lines().find(|l| l.starts_with("device.z ")).expect("device.z estimated");
    let z: f64 = device_z.split_whitespace().nth(1).unwrap().parse().unwrap();
    assert!((z + 150.0).abs() < 0.5, "{device_z}");
    std::fs::remove_dir_all(&dir).unwrap();
}

/// --fixed-tool with markers alone changes nothing, and the command says so.
#[test]
fn a_fixed_tool_with_markers_alone_is_said_to_change_nothing() {
    let output = assert_cmd::Command::cargo_bin("robocal")
        .unwrap()
        .args(["calibrate", "--model", "puma560", "--fixed-tool"])
        .args(["--marker", "50,0,150", "--marker=-40,60,120", "--data", "examples/puma560-measurements.csv"])
        .output()
        .unwrap();
    let stderr = String::from_utf8(output.stderr).unwrap();
    assert!(output.status.success(), "{stderr}");
    assert!(
        stderr.contains("--fixed-tool holds the tool point, which no observation here measures"),
        "{stderr}"
    );
}

/// `--select` on a marker file with the joint noise: every parameter is in error, so the
/// forward paths (bic, 4-fold cv) take at least 11 steps and the chosen models more than 10
/// parameters; the chosen model predicts a held-out file of the same robot within 1.2 times
/// the full fit's RMS; and the cv path's own figure of its chosen model (its linear model's
/// cross-validated RMS of the marker positions, a marker's three coordinates one error) is
/// within 20% of that model refitted fold by fold (`cross_validate_kinds`).
#[test]
fn a_marker_file_selects_the_parameters_in_error() {
    use robocal::calibration::kinds::cross_validate_kinds;
    let (model, observations, real) = marker_file(84, 40);
    let held_out = marker_csv(&real, 40, &mut ChaCha8Rng::seed_from_u64(184));
    let held_out = KindData::from_csv_str(&held_out, &model, None).unwrap();
    let sigmas: Vec<f64> =
        [0.007, 0.007, 0.007, 0.002, 0.002, 0.002].iter().map(|s: &f64| s.to_radians()).collect();
    let joint_noise =
        nalgebra::DMatrix::from_diagonal(&nalgebra::DVector::from_iterator(6, sigmas.iter().map(|s| s * s)));
    let kind_options = KindOptions { joint_noise: Some(joint_noise), ..marker_options(Estimator::Wls) };
    let rms = |o: &KindOptions| {
        let c = calibrate_kinds(&model, &observations, o).unwrap();
        c.score(&held_out).unwrap().markers.unwrap().1
    };
    let all = rms(&kind_options);
    for criterion in [Criterion::Bic, Criterion::Cv { folds: 4 }, Criterion::T] {
        let found = select(&Kinds(&model), &observations, &kind_options, criterion).unwrap();
        let steps = if criterion == Criterion::T { 1 } else { 11 };
        assert!(found.steps.len() >= steps, "{criterion:?}: {} steps", found.steps.len());
        assert!(found.selected.len() > 10, "{criterion:?}: {:?}", found.selected);
        let chosen = found.options(&Kinds(&model), &kind_options);
        let selected = rms(&chosen);
        assert!(selected < 1.2 * all, "{criterion:?}: held out {selected} mm, every parameter {all} mm");
        if let Criterion::Cv { folds } = criterion {
            let score = found.steps[found.chosen].score;
            let refitted =
                cross_validate_kinds(&model, &observations, &chosen, folds).unwrap().markers.unwrap().1;
            assert!((score / refitted - 1.0).abs() < 0.2, "the path's {score} mm, refitted {refitted} mm");
        }
    }
}

/// A 6-DOF probe's file (marker 1 and the frame's orientation, a quaternion) read as
/// observations: three marker rows and three orientation rows a pose (`log(R_m R^T)`), the
/// probe a frame on the last link (`marker1.x` ... `.rz`), its rotation started from the data,
/// one block `V_k` a pose. From exact joint readings, by `wls` (the noise model's sigmas), the
/// calibrated probe frame is the true one: at 100 other poses within 1e-5 mm and 1e-8 rad of
/// the truth's (the file's rounding: measured 7e-7 mm, 1.4e-9 rad). With the joints read with noise, by ordinary least squares (rows of no sigma:
/// the residuals' spread) and by `wls`, within 0.2 mm and 4e-4 rad (the readings' 0.007 deg,
/// 1.2e-4 rad, at the probe; measured 0.089 mm and 1.3e-4 rad by ordinary least squares).
#[test]
fn a_probe_file_calibrates_the_true_probe_frame() {
    use robocal::calibration::kinds::RowSigmaDefaults;
    let mut rng = ChaCha8Rng::seed_from_u64(85);
    let nominal = puma();
    let truth = crate::calibration::true_robot(&nominal, &mut rng);
    let mounting = Placement { xyz: Vector3::new(52.0, 1.0, 148.0), rpy: Vector3::new(0.3, -0.2, 0.5) };
    let chain = Chain::probe(&truth, &mounting);
    let real = chain.with_errors(&vec![0.0; chain.params().len()]);
    let sigmas = crate::calibration::joint_sigmas();
    let (refine, markers) = (to_the_minimum(), vec![Vector3::new(50.0, 0.0, 150.0)]);
    let joint_noise =
        nalgebra::DMatrix::from_diagonal(&nalgebra::DVector::from_iterator(6, sigmas.iter().map(|s| s * s)));
    let given = RowSigmaDefaults { length_mm: Some(1e-3), angle_rad: Some(1e-6) };
    let runs = [
        (0.0, Estimator::Wls, Some(joint_noise.clone()), given, (1e-5, 1e-8)),
        (1.0, Estimator::Ols, None, RowSigmaDefaults::default(), (0.2, 4e-4)),
        (1.0, Estimator::Wls, Some(joint_noise), given, (0.2, 4e-4)),
    ];
    for (read, estimator, joint_noise, defaults, (mm, rad)) in runs {
        let read_with: Vec<f64> = sigmas.iter().map(|s| s * read).collect();
        let text = crate::calibration::probe_csv(&nominal, &real, 60, &read_with, &mut rng);
        let observations = KindData::from_csv_str_with(&text, &nominal, None, defaults).unwrap();
        assert_eq!((observations.observations.len(), observations.probes()), (60 * 6, vec![0]));
        let kind_options =
            KindOptions { refine, joint_noise, markers: markers.clone(), ..options(estimator) };
        let c = calibrate_kinds(&nominal, &observations, &kind_options).unwrap();
        assert!(
            matches!(c.calibrated.tool, Tool::Frame(_)),
            "a probe's tool is a frame: {:?}",
            c.calibrated.tool
        );
        let model = Chain::new(&c.calibrated);
        let model = model.with_errors(&vec![0.0; model.params().len()]);
        let mut poses = ChaCha8Rng::seed_from_u64(8);
        let (mut position, mut rotation) = (0.0f64, 0.0f64);
        for _ in 0..100 {
            let q = random_pose(&nominal, &mut poses);
            let (found, true_pose) = (model.pose(&q), real.pose(&q));
            position = position.max((found.translation.vector - true_pose.translation.vector).norm());
            rotation = rotation.max(found.rotation.angle_to(&true_pose.rotation));
        }
        eprintln!("probe, read x{read} {estimator:?}: {position:.3e} mm, {rotation:.3e} rad");
        assert!(position < mm && rotation < rad, "{estimator:?} x{read}: {position} mm, {rotation} rad");
    }
}

/// `robocal calibrate` of a 6-DOF probe's file (marker 1 and its frame's orientation) with the
/// example's ball bar, on the example's true robot (exact joints): the probe file goes to the
/// observation fit with the other, and a held-out probe file's positions and orientations
/// come out near exact (the ball bar's noise of 0.05 mm moves the robot a little): below
/// 0.05 mm and 0.01 deg RMS (0.032 mm and 0.006 deg), from 2.3 mm and 0.16 deg before.
#[test]
fn the_command_fits_a_probe_file_with_a_ball_bar() {
    let dir = std::env::temp_dir().join(format!("robocal-probe-ball-bar-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let text = std::fs::read_to_string("examples/puma560-true.toml").unwrap();
    let truth = robocal::model::RobotModel::from_toml_str(&text).unwrap();
    let mounting = Placement { xyz: Vector3::new(60.0, 5.0, 140.0), rpy: Vector3::new(0.2, -0.1, 0.3) };
    let chain = Chain::probe(&truth, &mounting);
    let real = chain.with_errors(&vec![0.0; chain.params().len()]);
    let mut rng = ChaCha8Rng::seed_from_u64(86);
    let (training, held_out) = (dir.join("probe.csv"), dir.join("probe-2.csv"));
    let path = |p: &std::path::Path| p.to_str().unwrap().to_string();
    for (file, poses) in [(&training, 80), (&held_out, 40)] {
        std::fs::write(file, crate::calibration::probe_csv(&puma(), &real, poses, &[0.0; 6], &mut rng))
            .unwrap();
    }
    let output = assert_cmd::Command::cargo_bin("robocal")
        .unwrap()
        .args(["calibrate", "--model", "puma560", "--data", &path(&training)])
        .args(["--data", "examples/puma560-ballbar.csv", "--marker", "60,5,140"])
        .args(["--validate", &path(&held_out)])
        .output()
        .unwrap();
    let (stdout, stderr) = (String::from_utf8_lossy(&output.stdout), String::from_utf8_lossy(&output.stderr));
    assert!(output.status.success(), "{stderr}");
    let row = |name: &str| -> (f64, f64) {
        let line = stdout
            .lines()
            .find(|l| l.contains(&format!("probe-2.csv {name}")))
            .unwrap_or_else(|| panic!("{stdout}"));
        crate::verdict_rms(line)
    };
    let (positions, orientations) = (row("markers (mm)"), row("probe orientations (deg)"));
    assert!(positions.0 > 1.0 && positions.1 < 0.05, "{positions:?}\n{stdout}");
    assert!(orientations.0 > 0.1 && orientations.1 < 0.01, "{orientations:?}\n{stdout}");
    assert!(stdout.contains("training probe orientations (deg)"), "{stdout}");
    // The largest position errors of the probe's origin, 5 a set, the largest first.
    let section: Vec<&str> = (stdout.lines())
        .skip_while(|l| !l.starts_with("largest marker position errors after calibration (5 per set"))
        .skip(1)
        .take_while(|l| l.starts_with("  "))
        .collect();
    assert_eq!(section.len(), 10, "{stdout}");
    let after = |l: &str| -> f64 {
        l.split(" mm before, ").nth(1).unwrap().split(' ').next().unwrap().parse().unwrap()
    };
    assert!(section[5].contains("probe-2.csv, line") && section[5].contains("marker 1:"), "{}", section[5]);
    assert!(after(section[5]) >= after(section[6]) && after(section[5]) >= positions.1, "{section:?}");
    std::fs::remove_dir_all(&dir).unwrap();
}

/// Rows without a sigma are said to be weighed by the defaults under the weighted estimators,
/// and alike under ordinary least squares (which weighs every row alike whatever its sigma):
/// the report says which, and how many rows gave none (the marker file's 600 coordinates).
#[test]
fn the_report_says_how_rows_without_a_sigma_are_weighed() {
    let note = |estimator: &str| {
        let output = with_a_ball_bar(&["--estimator", estimator]);
        assert!(output.status.success(), "{}", String::from_utf8_lossy(&output.stderr));
        let text = String::from_utf8(output.stdout).unwrap();
        text.lines().find(|l| l.contains("gave no sigma")).unwrap_or_else(|| panic!("{text}")).to_string()
    };
    let (wls, ols) = (note("wls"), note("ols"));
    assert!(
        wls.starts_with("600 of 750 observations gave no sigma: weighed by the defaults, 0.01 mm"),
        "{wls}"
    );
    assert!(ols.starts_with("600 of 750 observations gave no sigma: ols weighs every row alike"), "{ols}");
}

/// The verdict of a marker file flags the position a 3 mm slip moved, one of the 200, in its
/// marker's row only; a group's row (the ball bar's) has its observations' count, largest
/// residual and flags, as the JSON's observations give them.
#[test]
fn the_verdict_flags_a_slipped_markers_position_and_a_groups_row_is_its_observations() {
    let dir = std::env::temp_dir().join(format!("robocal-kinds-verdict-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let example = std::fs::read_to_string("examples/puma560-measurements.csv").unwrap();
    // Line 40's marker 1 x moved by 3 mm.
    let mut lines: Vec<String> = example.lines().map(String::from).collect();
    let header: Vec<&str> = lines[1].split(',').collect();
    let x1 = header.iter().position(|&h| h == "x1").unwrap();
    let mut cells: Vec<String> = lines[39].split(',').map(String::from).collect();
    cells[x1] = format!("{}", cells[x1].parse::<f64>().unwrap() + 3.0);
    lines[39] = cells.join(",");
    let (slipped, json) = (dir.join("slipped.csv"), dir.join("r.json"));
    std::fs::write(&slipped, lines.join("\n") + "\n").unwrap();
    let run = |extra: &[&str]| {
        let output = assert_cmd::Command::cargo_bin("robocal")
            .unwrap()
            .args(["calibrate", "-q", "--model", "puma560", "--data"])
            .arg(&slipped)
            .args(["--marker", "50,0,150", "--marker=-40,60,120"])
            .args(extra)
            .output()
            .unwrap();
        assert!(output.status.success(), "{}", String::from_utf8_lossy(&output.stderr));
        String::from_utf8(output.stdout).unwrap()
    };
    let cells_of = |text: &str, start: &str| -> Vec<String> {
        let row = text.lines().find(|l| l.starts_with(start)).unwrap_or_else(|| panic!("{start}: {text}"));
        row.split_whitespace().map(String::from).collect()
    };
    let observations = run(&["--data", "examples/puma560-ballbar.csv", "--json", json.to_str().unwrap()]);
    let alone = run(&[]);
    // training markers (mm) 200 b -> a mm b -> a mm 1 of 200: the slipped marker's pose, one
    // position of the 200, flagged, and in marker 1's row, not marker 2's.
    let flagged = |start: &str| {
        let k = cells_of(&alone, start);
        (k[k.len() - 3].clone(), k[k.len() - 1].clone())
    };
    assert_eq!(flagged("training markers (mm)"), ("1".into(), "200".into()), "{alone}");
    assert_eq!(flagged("training marker 1 (mm)"), ("1".into(), "100".into()), "{alone}");
    assert_eq!(flagged("training marker 2 (mm)"), ("0".into(), "100".into()), "{alone}");
    // The ball bar's row against its observations in the JSON.
    let report: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    let training = &report["sets"][0][1];
    let distances: Vec<&serde_json::Value> =
        (training["observations"].as_array().unwrap().iter()).filter(|o| o["kind"] == "point").collect();
    let group = &training["by_group"][0];
    assert_eq!(group["count"].as_u64(), Some(distances.len() as u64));
    let largest =
        |stage: &str| distances.iter().map(|o| o[stage].as_f64().unwrap().abs()).fold(0.0, f64::max);
    assert_eq!(group["max"], serde_json::json!([largest("before"), largest("after")]));
    assert_eq!(group["flagged"].as_u64(), Some(0));
    let row = cells_of(&observations, "training distances (mm)");
    assert_eq!(row[3], distances.len().to_string(), "{observations}");
    std::fs::remove_dir_all(&dir).unwrap();
}

/// The verdict is typed data that the text renders: `--json`'s `verdict` rows are the text's
/// table, row for row (label, count, RMS and max before and after, flagged).
#[test]
fn the_verdict_in_the_json_is_the_texts_table() {
    let (text, report) = crate::nested::calibrate_puma(&[
        "--data",
        "examples/puma560-ballbar.csv",
        "--validate",
        "examples/puma560-validation.csv",
    ]);
    let rows = report["verdict"].as_array().unwrap();
    assert_eq!(rows.len(), 7, "distances, markers, 2 markers; held out: markers, 2 markers");
    for row in rows {
        let (set, quantity, unit) =
            (row["set"].as_str().unwrap(), row["quantity"].as_str().unwrap(), row["unit"].as_str().unwrap());
        let label = format!("{set} {quantity} ({unit})");
        let line =
            text.lines().find(|l| l.starts_with(&format!("{label} "))).unwrap_or_else(|| panic!("{label}"));
        let pair = |v: &serde_json::Value| {
            format!("{:.4} -> {:.4} {unit}", v[0].as_f64().unwrap(), v[1].as_f64().unwrap())
        };
        let count = row["count"].as_u64().unwrap();
        for cell in [pair(&row["rms"]), pair(&row["max"]), format!("{} of {count}", row["flagged"])] {
            assert!(line.contains(&cell), "{cell}: {line}");
        }
    }
}

/// With nothing to estimate (`--params none`, the base and the markers fixed, no set-up) the
/// model is scored as it stands, and said so: before and after alike, no step taken; with the
/// joint noise too.
#[test]
fn with_nothing_to_estimate_the_model_is_scored_as_it_stands() {
    let run = |extra: &[&str]| {
        let output = assert_cmd::Command::cargo_bin("robocal")
            .unwrap()
            .args(["calibrate", "-q", "--model", "puma560", "--data", "examples/puma560-measurements.csv"])
            .args(["--marker", "50,0,150", "--marker=-40,60,120", "--params", "none", "--fixed-base"])
            .args(["--fixed-markers"])
            .args(extra)
            .output()
            .unwrap();
        assert!(output.status.success(), "{extra:?}: {}", String::from_utf8_lossy(&output.stderr));
        String::from_utf8(output.stdout).unwrap()
    };
    // No noise is given: ordinary least squares.
    let text = run(&[]);
    assert!(text.contains("100 poses, 2 markers, ols (0 steps, converged)"), "{text}");
    assert!(text.contains("nothing estimated: the model is scored as it stands"), "{text}");
    let row =
        text.lines().find(|l| l.starts_with("training markers (mm)")).unwrap_or_else(|| panic!("{text}"));
    let k: Vec<&str> = row.split_whitespace().collect();
    // training markers (mm) 200 b -> a mm b -> a mm 0 of 200
    assert_eq!((k[4], k[8]), (k[6], k[10]), "before and after alike: {text}");
    // With the joint noise too: the noise check has no parameter to linearise about (it
    // panicked on an empty eigen-decomposition).
    let noisy = run(&["--joint-sigma-deg", "0.007,0.007,0.007,0.002,0.002,0.002", "--sigma-mm", "0.01"]);
    assert!(noisy.contains("100 poses, 2 markers, wls (0 steps, converged)"), "{noisy}");
}

/// Without any noise (no sigma column, no sigma flag, the joints exact) the observation fit is
/// ordinary least squares, as a marker file's calibration, and a weighted estimator asked for
/// is a usage error (exit 2) that says what gives the noise; a sigma column is a noise.
#[test]
fn a_weighted_estimator_needs_a_noise_and_without_one_the_fit_is_ols() {
    let run = |data: &[&str], extra: &[&str]| {
        (assert_cmd::Command::cargo_bin("robocal").unwrap())
            .args(["calibrate", "-q", "--model", "puma560", "--tool", "50,0,150"])
            .args(data.iter().flat_map(|d| ["--data", d]))
            .args(extra)
            .output()
            .unwrap()
    };
    let markers = ["examples/puma560-measurements.csv"];
    for estimator in ["wls", "wls-diag", "wls-sigma"] {
        let output = run(&markers, &["--estimator", estimator]);
        let stderr = String::from_utf8_lossy(&output.stderr);
        assert_eq!(output.status.code(), Some(2), "{estimator}: {stderr}");
        assert!(
            stderr.contains(&format!("--estimator {estimator} needs the noise: give --noise or")),
            "{stderr}"
        );
    }
    let header = |output: std::process::Output| {
        assert!(output.status.success(), "{}", String::from_utf8_lossy(&output.stderr));
        String::from_utf8(output.stdout).unwrap().lines().next().unwrap().to_string()
    };
    assert!(header(run(&markers, &[])).ends_with("100 poses, 2 markers, ols (2 steps, converged)"));
    let with_sigmas = ["examples/puma560-ballbar.csv"];
    assert!(header(run(&with_sigmas, &[])).contains(", wls ("), "the ball bar's sigma column");
    assert!(header(run(&with_sigmas, &["--estimator", "wls"])).contains(", wls ("));
}

/// The observation report says what "before" and "after" are, as a marker file's does, in
/// its text and its JSON (`fits`): with markers, the base and the markers fitted by ols
/// whatever the estimator; without, the set-up and the tool point by the estimator; after, the
/// estimator with its priors and robust loss, or the selection's choice.
#[test]
fn the_report_says_what_before_and_after_are() {
    let dir = std::env::temp_dir().join(format!("robocal-kinds-fits-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let json = dir.join("r.json");
    let run = |data: &str, extra: &[&str]| {
        let output = (assert_cmd::Command::cargo_bin("robocal").unwrap())
            .args(["calibrate", "-q", "--model", "puma560", "--tool", "50,0,150", "--data", data])
            .args(["--json", json.to_str().unwrap()])
            .args(extra)
            .output()
            .unwrap();
        assert!(output.status.success(), "{}", String::from_utf8_lossy(&output.stderr));
        let text = String::from_utf8(output.stdout).unwrap();
        let report: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
        let line = |start: &str| text.lines().find(|l| l.starts_with(start)).expect(&text).to_string();
        assert_eq!(line("before: "), format!("before:    {}", report["fits"]["before"].as_str().unwrap()));
        assert_eq!(line("after: "), format!("after:     {}", report["fits"]["after"].as_str().unwrap()));
        (line("before: "), line("after: "))
    };
    let markers = "examples/puma560-measurements.csv";
    let (before, after) = run(markers, &["--marker", "50,0,150", "--marker=-40,60,120"]);
    assert_eq!(
        before,
        "before:    base and markers fitted by ols (unweighted), joints nominal, whatever the estimator"
    );
    assert_eq!(after, "after:     ols: every parameter asked for that the observations identify");
    let (_, after) = run(markers, &["--params", "joints", "--select", "bic"]);
    assert_eq!(
        after,
        "after:     ols: the joint parameters --select bic chose, with the base and the markers"
    );
    let (before, after) = run("examples/puma560-ballbar.csv", &["--prior", "machined", "--loss", "huber"]);
    assert_eq!(before, "before:    set-up and tool point fitted by wls, joints nominal");
    assert!(
        after.starts_with("after:     wls with priors (maximum a posteriori), robust loss huber"),
        "{after}"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

/// Several held-out files of their own sessions are pooled too, as a marker file's are: the
/// validation file cut in two scores, pooled, as it does whole (its markers' row, cell for
/// cell), each half on a row of its own; two files of one stem (one session) are not pooled.
#[test]
fn several_held_out_files_are_pooled_too() {
    let dir = std::env::temp_dir().join(format!("robocal-kinds-pooled-{}", std::process::id()));
    std::fs::create_dir_all(dir.join("other")).unwrap();
    let text = std::fs::read_to_string("examples/puma560-validation.csv").unwrap();
    let lines: Vec<&str> = text.lines().collect();
    let (head, rows) = (&lines[..2], &lines[2..]);
    assert!(head[1].starts_with("j1,"), "{head:?}");
    let (a, b, c) = (dir.join("a.csv"), dir.join("b.csv"), dir.join("other").join("a.csv"));
    let half = rows.len() / 2;
    for (path, part) in [(&a, &rows[..half]), (&b, &rows[half..]), (&c, &rows[half..])] {
        std::fs::write(path, [head, part].concat().join("\n") + "\n").unwrap();
    }
    let run = |validate: &[&std::path::Path]| {
        let output = (assert_cmd::Command::cargo_bin("robocal").unwrap())
            .args(["calibrate", "-q", "--model", "puma560", "--tool", "0,0,0"])
            .args([
                "--data",
                "examples/puma560-measurements.csv",
                "--marker",
                "50,0,150",
                "--marker=-40,60,120",
            ])
            .args(validate.iter().flat_map(|v| [std::ffi::OsStr::new("--validate"), v.as_os_str()]))
            .output()
            .unwrap();
        assert!(output.status.success(), "{}", String::from_utf8_lossy(&output.stderr));
        String::from_utf8(output.stdout).unwrap()
    };
    let cells = |text: &str, start: &str| -> Vec<String> {
        let row = text.lines().find(|l| l.starts_with(start)).unwrap_or_else(|| panic!("{start}: {text}"));
        row[start.len()..].split_whitespace().map(String::from).collect()
    };
    let whole = run(&[std::path::Path::new("examples/puma560-validation.csv")]);
    let split = run(&[&a, &b]);
    assert_eq!(
        cells(&split, "held out, pooled markers (mm)"),
        cells(&whole, "examples/puma560-validation.csv markers (mm)"),
        "{split}"
    );
    // Two markers a pose: the first half's positions on its own row.
    assert_eq!(cells(&split, &format!("{} markers (mm)", a.display()))[0], (2 * half).to_string());
    assert!(!run(&[&a, &c]).contains("held out, pooled"), "one stem, one session");
    std::fs::remove_dir_all(&dir).unwrap();
}

/// The noise check's cross-validated errors of a marker file through the observation fit are
/// the marker calibration's (a marker's position one error in both), with the sigmas given and
/// with the estimated ones, to the two fits' agreement; its factors too.
#[test]
fn the_noise_checks_cv_figures_are_the_marker_calibrations() {
    let noise = ["--joint-sigma-deg", "0.007,0.007,0.007,0.002,0.002,0.002", "--sigma-mm", "0.05"];
    let warning = |extra: &[&str]| {
        let (_, report) = crate::nested::calibrate_puma(&[&noise[..], extra].concat());
        let warnings = report["warnings"].as_array().unwrap().clone();
        warnings.into_iter().find(|w| w["cause"] == "noise_disagrees").expect("a sigma 5 times too large")
    };
    let (markers, observations) = (warning(&[]), warning(&["--tool", "0,0,0"]));
    for key in ["cv_given", "cv_estimated", "measurement_factor"] {
        let (m, o) = (markers[key].as_f64().unwrap(), observations[key].as_f64().unwrap());
        assert!((o / m - 1.0).abs() < 1e-4, "{key}: {m} against {o}\n{markers}\n{observations}");
    }
}

/// Without the noise (no sigma given, the joints exact), a prior weighs against the data's own
/// spread, not against the assumed sigmas: `--prior auto:machined`'s cross-validated curve of a
/// marker file through the observation fit (`--tool 0,0,0`) is the marker calibration's (the
/// RMS of the marker positions' errors in both), to the two fits' agreement, and chooses the
/// same scale. (Weighed against the
/// default 0.01 mm, the prior was drowned: the curve flat, the smallest scale chosen.)
#[test]
fn a_prior_weighs_against_the_residuals_spread_when_no_sigma_is_given() {
    let curve = |extra: &[&str]| -> (Vec<f64>, u64) {
        let prior = ["--params", "offsets", "--prior", "auto:machined"];
        let (_, report) = crate::nested::calibrate_puma(&[&prior[..], extra].concat());
        let scale = &report["prior_scale"];
        let rms = scale["cv_rms"].as_array().unwrap().iter().map(|v| v.as_f64().unwrap()).collect();
        (rms, scale["chosen"].as_u64().unwrap())
    };
    let (markers, chosen) = curve(&[]);
    let (observations, chosen_there) = curve(&["--tool", "0,0,0"]);
    assert_eq!(chosen, chosen_there);
    assert!(markers[0] > 1.05 * markers[4], "the prior at 1/16 of its scale costs: {markers:?}");
    for (m, o) in markers.iter().zip(&observations) {
        assert!((o / m - 1.0).abs() < 1e-6, "{markers:?}\n{observations:?}");
    }
}

/// Without the noise, a prior's posterior standard deviations through the observation fit
/// are the marker calibration's, to the two fits' agreement: a parameter the data cannot see
/// keeps its prior SD (`j6.theta`: SD ratio 1; scaled by the residuals' variance of unit
/// weight a second time, it came out 7.3 times the prior's), and the rank said is the data's
/// alone (30, where the fit with its priors has 42).
#[test]
fn a_priors_posterior_sds_and_the_datas_rank_are_the_marker_calibrations() {
    let with = ["--prior", "machined"];
    let (_, markers) = crate::nested::calibrate_puma(&with);
    let (text, observations) = crate::nested::calibrate_puma(&[&with[..], &["--tool", "0,0,0"]].concat());
    assert!(text.contains("42 parameters estimated with their priors; the data alone: rank 30"), "{text}");
    assert_eq!(observations["rank"], markers["rank"]);
    let sds = |report: &serde_json::Value| -> Vec<(String, f64)> {
        (report["parameters"].as_array().unwrap().iter())
            .map(|p| (p["name"].as_str().unwrap().to_string(), p["std_error"].as_f64().unwrap()))
            .collect()
    };
    let (m, o) = (sds(&markers), sds(&observations));
    assert_eq!(m.len(), o.len());
    for ((name, a), (other, b)) in m.iter().zip(&o) {
        assert_eq!(name, other);
        assert!((a / b - 1.0).abs() < 1e-6, "{name}: {a} against {b}");
    }
    let j6 = o.iter().find(|(n, _)| n == "j6.theta").unwrap().1;
    assert!((j6 / 0.5 - 1.0).abs() < 1e-9, "{j6}");
}
