//! Measuring-device noise models and the noise file: each device's covariance against
//! finite-difference and Monte Carlo propagation of its own reading noise; the file's errors.

use nalgebra::{DMatrix, DVector, Matrix3, Vector3};
use rand::SeedableRng;
use rand::rngs::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};
use robocal::estimation::{Device, DeviceError, NoiseSpec};
use robocal::io::load_model;
use robocal::model::RobotModel;
use robocal::simulation::{self, Study};

const ARCSEC: f64 = std::f64::consts::PI / (180.0 * 3600.0);

fn tracker() -> Device {
    Device::LaserTracker {
        position: Vector3::new(2500.0, -800.0, 300.0),
        sigma_r: 0.005,
        k: 2e-6,
        sigma_angle: 1.5 * ARCSEC,
    }
}

fn theodolites() -> Device {
    Device::Theodolites {
        stations: [Vector3::new(2000.0, -1500.0, 400.0), Vector3::new(2000.0, 1500.0, 400.0)],
        sigma_horizontal: 0.5 * ARCSEC,
        sigma_vertical: 0.7 * ARCSEC,
    }
}

fn devices() -> Vec<Device> {
    vec![Device::Cmm { sigma: 0.02 }, tracker(), theodolites()]
}

/// Points spread over a PUMA-sized workspace.
fn points() -> Vec<Vector3<f64>> {
    vec![
        Vector3::new(600.0, 100.0, 400.0),
        Vector3::new(-300.0, 500.0, -200.0),
        Vector3::new(100.0, -700.0, 800.0),
        Vector3::new(-650.0, -150.0, 50.0),
    ]
}

/// `T Sigma_readings T^T` with `T = d(locate)/d(readings)` by central differences.
fn finite_difference_covariance(device: &Device, p: &Vector3<f64>) -> Matrix3<f64> {
    let readings = device.observe(p);
    let sigmas = device.reading_sigmas(p);
    let n = readings.len();
    let mut t = DMatrix::zeros(3, n);
    for i in 0..n {
        // A step of a hundredth of the reading's own noise: linear, and far above rounding.
        let h = sigmas[i] * 1e-2;
        let (mut plus, mut minus) = (readings.clone(), readings.clone());
        plus[i] += h;
        minus[i] -= h;
        let d = (device.locate(&plus).unwrap() - device.locate(&minus).unwrap()) / (2.0 * h);
        t.column_mut(i).copy_from(&d);
    }
    let s = DMatrix::from_diagonal(&sigmas.map(|s| s * s));
    let c = &t * s * t.transpose();
    Matrix3::from_fn(|i, j| c[(i, j)])
}

#[test]
fn device_covariances_match_finite_difference_propagation() {
    for device in devices() {
        for p in points() {
            let analytic = device.covariance(&p).unwrap();
            let numeric = finite_difference_covariance(&device, &p);
            let error = (analytic - numeric).norm() / analytic.norm();
            assert!(
                error < 1e-5,
                "{} at {p:?}: relative error {error:e}\n{analytic}{numeric}",
                device.kind()
            );
        }
    }
}

/// The covariance of points located from readings with their noise drawn, against the
/// analytic covariance: every eigenvalue of `Sigma^-1/2 S Sigma^-1/2` within 6 standard errors
/// (`sqrt(2 / n)`) of 1.
#[test]
fn device_covariances_match_monte_carlo() {
    let n = 20_000;
    let mut rng = ChaCha8Rng::seed_from_u64(2024);
    for device in devices() {
        let p = points()[0];
        let (readings, sigmas) = (device.observe(&p), device.reading_sigmas(&p));
        let located: Vec<DVector<f64>> = (0..n)
            .map(|_| {
                let noisy = DVector::from_fn(readings.len(), |i, _| {
                    let z: f64 = StandardNormal.sample(&mut rng);
                    readings[i] + sigmas[i] * z
                });
                let x = device.locate(&noisy).unwrap();
                DVector::from_column_slice(x.as_slice())
            })
            .collect();
        let (_, s, _) = robocal::estimation::sample_covariance(&located).unwrap();
        let sigma = device.covariance(&p).unwrap();
        let root = sigma.cholesky().unwrap().l().try_inverse().unwrap();
        let s = Matrix3::from_fn(|i, j| s[(i, j)]);
        let ratio = root * s * root.transpose();
        let eig = ratio.symmetric_eigenvalues();
        let tolerance = 6.0 * (2.0 / n as f64).sqrt();
        assert!(eig.iter().all(|e| (e - 1.0).abs() < tolerance), "{}: {eig:?}", device.kind());
    }
}

#[test]
fn a_laser_tracker_is_coarse_along_the_line_of_sight_and_worse_far_away() {
    let Device::LaserTracker { position, sigma_r, k, sigma_angle } = tracker() else { unreachable!() };
    let device = tracker();
    for p in points() {
        let d = p - position;
        let (r, u) = (d.norm(), d.normalize());
        let sigma = device.covariance(&p).unwrap();
        let along = (u.transpose() * sigma * u)[0].sqrt();
        assert!((along - (sigma_r + k * r)).abs() < 1e-12, "along the line of sight: {along}");
        // Across it, in the vertical plane through the line of sight: r sigma_angle.
        let horizontal = Vector3::new(-u.y, u.x, 0.0).normalize();
        let across = u.cross(&horizontal).normalize();
        let vertical = (across.transpose() * sigma * across)[0].sqrt();
        assert!((vertical - r * sigma_angle).abs() < 1e-9 * r, "across: {vertical}");
    }
    let near = device.covariance(&Vector3::new(1500.0, -800.0, 300.0)).unwrap().trace();
    let far = device.covariance(&Vector3::new(-500.0, -800.0, 300.0)).unwrap().trace();
    assert!(far > 4.0 * near, "three times the range: {far} vs {near}");
}

#[test]
fn theodolites_cannot_locate_a_point_on_their_baseline() {
    let error = theodolites().covariance(&Vector3::new(2000.0, 0.0, 400.0)).unwrap_err();
    assert!(matches!(error, DeviceError::Singular { .. }), "{error}");
    assert!(error.to_string().contains("baseline"), "{error}");
}

fn puma() -> RobotModel {
    RobotModel::preset("puma560").unwrap()
}

fn noise_error(text: &str) -> String {
    robocal::error::chain(&NoiseSpec::from_toml_str(text, &puma()).unwrap_err())
}

const SIGMAS: &str = "joint_sigma = [0.007, 0.007, 0.007, 0.002, 0.002, 0.002]\n";

#[test]
fn a_noise_file_reads_back_as_written() {
    for device in [
        "",
        "[device]\nkind = \"theodolites\"\nstations_mm = [[2000.0, -1500.0, 400.0], \
                       [2000.0, 1500.0, 400.0]]\nsigma_horizontal_arcsec = 0.5\nsigma_vertical_arcsec = 0.7\n",
    ] {
        let text = format!("{SIGMAS}sigma_me_mm = 0.01\n{device}");
        let spec = NoiseSpec::from_toml_str(&text, &puma()).unwrap();
        assert!((spec.joint_sigmas()[0] - 0.007f64.to_radians()).abs() < 1e-15);
        let again = NoiseSpec::from_toml_str(&spec.to_toml_string(&puma(), "a comment"), &puma()).unwrap();
        assert!((&again.joint - &spec.joint).amax() < 1e-6 * spec.joint.amax());
        assert_eq!(again.sigma_me, spec.sigma_me);
        assert_eq!(again.device.is_some(), !device.is_empty());
        if let (Some(a), Some(b)) = (&again.device, &spec.device) {
            let p = Vector3::new(300.0, 200.0, 100.0);
            let (ca, cb) = (a.covariance(&p).unwrap(), b.covariance(&p).unwrap());
            assert!((ca - cb).norm() < 1e-9 * cb.norm());
        }
    }
    let full = "joint_covariance = [[1e-4, 1e-5, 0, 0, 0, 0], [1e-5, 1e-4, 0, 0, 0, 0], [0, 0, 1e-4, 0, 0, 0], \
                [0, 0, 0, 1e-5, 0, 0], [0, 0, 0, 0, 1e-5, 0], [0, 0, 0, 0, 0, 1e-5]]\n";
    let spec = NoiseSpec::from_toml_str(full, &puma()).unwrap();
    assert!(spec.full && spec.joint[(0, 1)] > 0.0 && spec.sigma_me.is_none());
    let again = NoiseSpec::from_toml_str(&spec.to_toml_string(&puma(), ""), &puma()).unwrap();
    assert!((&again.joint - &spec.joint).amax() < 1e-6 * spec.joint.amax());
}

#[test]
fn a_noise_file_with_a_negative_sigma_is_refused() {
    let message = noise_error("joint_sigma = [0.007, -0.007, 0.007, 0.002, 0.002, 0.002]\n");
    assert_eq!(message, "field `joint_sigma`: finite values >= 0, found -0.007");
    let message = noise_error(&format!("{SIGMAS}[device]\nkind = \"cmm\"\nsigma_mm = -0.1\n"));
    assert_eq!(message, "field `device.sigma_mm`: a finite value >= 0, found -0.1");
}

#[test]
fn a_noise_file_with_an_unknown_device_is_refused() {
    let message = noise_error(&format!("{SIGMAS}[device]\nkind = \"sextant\"\n"));
    assert!(message.contains("unknown variant `sextant`"), "{message}");
    assert!(message.contains("`cmm`, `laser-tracker`, `theodolites`"), "{message}");
    assert!(message.contains("line 3"), "{message}");
}

#[test]
fn a_noise_file_with_a_missing_or_misspelled_field_is_refused() {
    let message =
        noise_error(&format!("{SIGMAS}[device]\nkind = \"laser-tracker\"\nposition_mm = [0, 0, 0]\n"));
    assert!(message.contains("missing field `sigma_r_mm`"), "{message}");
    let message = noise_error(&format!("{SIGMAS}sigma_me = 0.01\n"));
    assert!(message.contains("unknown field `sigma_me`"), "{message}");
    let message = noise_error("sigma_me_mm = 0.01\n");
    assert!(message.starts_with("field `joint_sigma`: give one of"), "{message}");
}

#[test]
fn a_noise_file_with_nan_or_a_wrong_count_is_refused() {
    let message = noise_error(&format!("{SIGMAS}sigma_me_mm = nan\n"));
    assert_eq!(message, "field `sigma_me_mm`: a finite value >= 0, found NaN");
    let message = noise_error("joint_sigma = [0.007, 0.007]\n");
    assert_eq!(message, "field `joint_sigma`: 6 values, one per joint of puma560");
    let message = noise_error(&format!(
        "{SIGMAS}[device]\nkind = \"theodolites\"\nstations_mm = [[0, 0, 0], [0, 0, 0]]\n\
         sigma_horizontal_arcsec = 0.5\nsigma_vertical_arcsec = 0.5\n"
    ));
    assert_eq!(message, "field `device.stations_mm`: two distinct stations (a baseline)");
}

/// A reduced PUMA 560 study (2 sets x 3 runs at N_p = 24) with `noise` appended to its
/// `[noise]` section and the cases' `sigma_me_mm`.
fn study(device: &str, sigma_me: &str) -> Study {
    let text = include_str!("../../presets/paper-table2.toml")
        .replace("point_sets = 6", "point_sets = 2")
        .replace("runs_per_set = 16", "runs_per_set = 3")
        .replace("test_points = 1000", "test_points = 200")
        .replace("points = [48]", "points = [24]")
        .replace("sigma_me_mm = [0.0, 0.025, 0.05, 0.1]", &format!("sigma_me_mm = [{sigma_me}]"))
        .replace("[errors]", &format!("{device}\n[errors]"));
    Study::from_toml_str(&text, load_model).unwrap()
}

/// A CMM device is the paper's isotropic noise: the same random numbers (its Cholesky factor
/// is `sigma I`) and the same `V_k`, so the same results.
#[test]
fn a_cmm_study_is_the_isotropic_study() {
    let device =
        simulation::run(&study("[noise.device]\nkind = \"cmm\"\nsigma_mm = 0.05", "0.0"), &|| {}).unwrap();
    let isotropic = simulation::run(&study("", "0.05"), &|| {}).unwrap();
    for (a, b) in device.runs.iter().zip(&isotropic.runs) {
        for (a, b) in a.accuracy.iter().zip(&b.accuracy) {
            assert!((a.mean - b.mean).abs() < 1e-9 * b.mean, "{a:?} vs {b:?}");
        }
    }
}

#[test]
fn a_theodolite_study_runs_and_weighting_helps() {
    let device = "[noise.device]\nkind = \"theodolites\"\nstations_mm = [[1500.0, -1000.0, 300.0], \
                  [1500.0, 1000.0, 300.0]]\nsigma_horizontal_arcsec = 2.5\nsigma_vertical_arcsec = 2.5";
    let s = study(device, "0.0");
    assert_eq!(s.device.as_ref().unwrap().kind(), "theodolites");
    let results = simulation::run(&s, &|| {}).unwrap();
    assert!(results.mean_error(0, 1) < results.mean_error(0, 0), "WLS beats OLS on average");
    let tables = robocal::report::study::tables(&s, &results);
    assert!(tables.contains("measurement device: theodolites at (1500, -1000, 300) and"), "{tables}");
}

#[test]
fn a_study_with_a_bad_device_says_which_field() {
    let text = include_str!("../../presets/device-laser-tracker.toml")
        .replace("sigma_r_mm = 0.01", "sigma_r_mm = -1");
    let message = Study::from_toml_str(&text, load_model).unwrap_err();
    assert_eq!(message.to_string(), "field `noise.device.sigma_r_mm`: a finite value >= 0, found -1");
    let text = include_str!("../../presets/device-cmm.toml").replace("kind = \"cmm\"", "kind = \"camera\"");
    let message = Study::from_toml_str(&text, load_model).unwrap_err();
    let message = robocal::error::chain(&message);
    assert!(message.contains("unknown variant `camera`"), "{message}");
}

#[test]
fn a_noise_file_replaces_a_studys_noise() {
    let mut s = study("", "0.0, 0.1");
    let spec = NoiseSpec::from_toml_str(
        "joint_sigma = [0.01, 0.01, 0.01, 0.003, 0.003, 0.003]\nsigma_me_mm = 0.02\n\
         [device]\nkind = \"cmm\"\nsigma_mm = 0.01\n",
        &puma(),
    )
    .unwrap();
    s.set_noise(&spec).unwrap();
    assert_eq!(s.cases.len(), 1);
    assert_eq!(s.cases[0].sigma_me, 0.02);
    assert!((s.joint_sigmas[0] - 0.01f64.to_radians()).abs() < 1e-15);
    assert!(s.device.is_some());
    let correlated = "joint_covariance = [[1e-4, 1e-5, 0, 0, 0, 0], [1e-5, 1e-4, 0, 0, 0, 0], [0, 0, 1e-4, 0, 0, 0], \
                      [0, 0, 0, 1e-5, 0, 0], [0, 0, 0, 0, 1e-5, 0], [0, 0, 0, 0, 0, 1e-5]]\n";
    let message = s.set_noise(&NoiseSpec::from_toml_str(correlated, &puma()).unwrap()).unwrap_err();
    assert_eq!(
        message.to_string(),
        "field `joint_covariance`: per-joint sigmas: a study simulates uncorrelated joint noise"
    );
}

/// The theodolites' stations are two points of three coordinates: a third station, or a fourth
/// coordinate, is refused rather than left unread.
#[test]
fn theodolite_stations_are_exactly_two_points_of_three_coordinates() {
    let device = |stations: &str| {
        format!(
            "{SIGMAS}[device]\nkind = \"theodolites\"\nstations_mm = {stations}\nsigma_horizontal_arcsec = 1.0\nsigma_vertical_arcsec = 1.0\n"
        )
    };
    assert!(NoiseSpec::from_toml_str(&device("[[0, 0, 0], [2000, 0, 0]]"), &puma()).is_ok());
    let message = noise_error(&device("[[0, 0, 0], [2000, 0, 0], [0, 2000, 0]]"));
    assert!(message.contains("invalid length 3, expected 2 arrays"), "{message}");
    let message = noise_error(&device("[[0, 0, 0, 5], [2000, 0, 0]]"));
    assert!(message.contains("invalid length 4, expected 3 numbers in each array"), "{message}");
}

/// A noise file's per-pose measurement covariances follow the poses into each fold: `--noise
/// FILE` with `--folds 2`, `--prior auto` and nested `--select cv` calibrates (it was refused,
/// "100 measurement covariances for 50 points"), and the 2-fold figure is near the held-out one.
#[test]
fn a_noise_files_covariances_follow_the_poses_into_each_fold() {
    let base = [
        "calibrate",
        "--model",
        "puma560",
        "--data",
        "examples/puma560-measurements.csv",
        "--marker",
        "50,0,150",
        "--marker=-40,60,120",
        "--validate",
        "examples/puma560-validation.csv",
        "--noise",
        "examples/puma560-noise.toml",
    ];
    for extra in [&["--folds", "2"][..], &["--prior", "auto:machined"], &["--select", "cv", "--folds", "3"]] {
        let output =
            assert_cmd::Command::cargo_bin("robocal").unwrap().args(base).args(extra).output().unwrap();
        let text = String::from_utf8(output.stdout).unwrap();
        assert!(output.status.success(), "{extra:?}: {}", String::from_utf8_lossy(&output.stderr));
        let after = |label: &str| -> Option<f64> {
            let row = text.lines().find(|l| l.starts_with(label))?;
            row.split_whitespace().skip_while(|w| *w != "->").nth(1)?.parse().ok()
        };
        let held_out = after("examples/puma560-validation.csv markers (mm)").expect("the held-out row");
        if let Some(folds) = after("2-fold cross-validation").or(after("3-fold cross-validation")) {
            assert!(
                (folds - held_out).abs() < 0.25 * held_out,
                "{extra:?}: {folds} against {held_out} mm\n{text}"
            );
        }
    }
}
