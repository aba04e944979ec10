//! Feasible GLS: the noise estimated from a calibration's own residuals, against the truth and
//! against Gauss-Markov with the true V.

use nalgebra::Vector3;
use rand::rngs::ChaCha8Rng;
use rand::{RngExt, SeedableRng};
use rand_distr::{Distribution, StandardNormal};
use robocal::calibration::FeasibleOptions;
use robocal::calibration::kinds::{
    KindCalibration, KindData, KindOptions, calibrate_kinds, calibrate_kinds_feasible,
};
use robocal::estimation::{Estimator, MeasurementNoise, NoiseModel};
use robocal::kinematics::Chain;
use robocal::model::{Placement, RobotModel};
use robocal::simulation::measurement_csv;

const DEGREES: [f64; 6] = [0.007, 0.007, 0.007, 0.002, 0.002, 0.002];
const SIGMA_ME: f64 = 0.02;
const TRUE_MARKER: [f64; 3] = [52.0, 1.0, 148.0];

struct Campaign {
    nominal: RobotModel,
    truth: RobotModel,
    /// The marker file, its sigmas given (the true noise's).
    data: KindData,
    /// Gauss-Markov with the true noise.
    options: KindOptions,
    /// The marker file without its sigmas (no noise given).
    plain: KindData,
    /// Ordinary least squares.
    ols: KindOptions,
}

fn configurations(model: &RobotModel, n: usize, rng: &mut ChaCha8Rng) -> Vec<Vec<f64>> {
    (0..n)
        .map(|_| model.joints.iter().map(|j| rng.random_range(j.limits[0]..j.limits[1])).collect())
        .collect()
}

/// A PUMA 560 with errors of the paper's sizes, seen from a device 1.5 m away, measured at
/// `poses` configurations with the paper's joint noise and `SIGMA_ME`.
fn campaign(seed: u64, poses: usize) -> Campaign {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let nominal = RobotModel::preset("puma560").unwrap();
    let mut truth = nominal.clone();
    let n = |rng: &mut ChaCha8Rng| -> f64 { StandardNormal.sample(rng) };
    for joint in &mut truth.joints {
        joint.theta += 0.1f64.to_radians() * n(&mut rng);
        joint.d += 0.5 * n(&mut rng);
        joint.a += 0.5 * n(&mut rng);
        joint.alpha += 0.05f64.to_radians() * n(&mut rng);
        joint.beta += 0.05f64.to_radians() * n(&mut rng);
    }
    truth.base = Placement { xyz: Vector3::new(1500.0, -300.0, 200.0), rpy: Vector3::new(0.1, -0.05, 0.6) };
    let sigmas: Vec<f64> = DEGREES.iter().map(|d| d.to_radians()).collect();
    let joints = configurations(&nominal, poses, &mut rng);
    let text = measurement_csv(&truth, &[Vector3::from(TRUE_MARKER)], &joints, &sigmas, SIGMA_ME, seed + 1);
    let noise = NoiseModel::diagonal(&sigmas, MeasurementNoise::isotropic(SIGMA_ME, 0.0));
    let markers = [Vector3::new(50.0, 0.0, 150.0)];
    let data = crate::marker_data(&text, &nominal, Some(&noise));
    let options = crate::marker_options(&nominal, Estimator::Wls, Some(&noise), &markers);
    let plain = crate::marker_data(&text, &nominal, None);
    let ols = crate::marker_options(&nominal, Estimator::Ols, None, &markers);
    Campaign { nominal, truth, data, options, plain, ols }
}

/// `E_p`: the mean distance between the calibrated model's marker and the true one over 500
/// configurations spread over the workspace.
fn position_error(c: &Campaign, calibration: &KindCalibration) -> f64 {
    let mut rng = ChaCha8Rng::seed_from_u64(99);
    let truth = &Chain::markers(&c.truth, &[Vector3::from(TRUE_MARKER)])[0];
    let truth = truth.with_errors(&vec![0.0; truth.params().len()]);
    let model = Chain::new(&calibration.calibrated);
    let model = model.with_errors(&vec![0.0; model.params().len()]);
    let test = configurations(&c.nominal, 500, &mut rng);
    test.iter().map(|q| (model.position(q) - truth.position(q)).norm()).sum::<f64>() / test.len() as f64
}

/// Six campaigns of 150 poses: the true joint sigmas and sigma_me fall in the reported 95%
/// intervals (at least 36 of the 42), and the mean E_p of feasible GLS is within 5% of
/// Gauss-Markov with the true V.
#[test]
fn feasible_gls_recovers_the_noise_and_the_accuracy_of_the_true_v() {
    let (mut covered, mut checks) = (0, 0);
    let (mut e_wls, mut e_fgls, mut e_ols) = (0.0, 0.0, 0.0);
    for seed in 0..6 {
        let c = campaign(100 + seed, 150);
        let wls = calibrate_kinds(&c.nominal, &c.data, &c.options).unwrap();
        let ols = calibrate_kinds(&c.nominal, &c.plain, &c.ols).unwrap();
        let fgls =
            calibrate_kinds_feasible(&c.nominal, &c.plain, &c.ols, &FeasibleOptions::default()).unwrap();
        let estimate = fgls.noise_estimate.as_ref().unwrap();
        for (j, d) in DEGREES.iter().enumerate() {
            let s = estimate.joint_sigma(j);
            if !s.contains(d.to_radians()) {
                eprintln!("seed {seed}: j{} true {:.3e} outside {s:?}", j + 1, d.to_radians());
            }
            covered += s.contains(d.to_radians()) as usize;
        }
        covered += estimate.sigma_me().contains(SIGMA_ME) as usize;
        checks += 7;
        let (w, f, o) = (position_error(&c, &wls), position_error(&c, &fgls), position_error(&c, &ols));
        eprintln!(
            "seed {seed}: E_p ols {o:.5} wls {w:.5} fgls {f:.5} mm; j1 {:?}, sigma_me {:?}",
            estimate.joint_sigma(0),
            estimate.sigma_me()
        );
        (e_wls, e_fgls, e_ols) = (e_wls + w, e_fgls + f, e_ols + o);
    }
    eprintln!(
        "covered {covered} of {checks}; E_p summed over the campaigns: ols {e_ols:.5} wls {e_wls:.5} fgls {e_fgls:.5}"
    );
    assert!(covered >= 36, "{covered} of {checks} components in their intervals");
    assert!((e_fgls / e_wls - 1.0).abs() < 0.05, "E_p: fgls {e_fgls}, wls {e_wls}");
}

/// The report of feasible GLS gives the noise it estimated: the 6 joints' sigmas and the
/// markers' (`sigma_marker`, the marker class's).
#[test]
fn feasible_gls_reports_its_estimate() {
    let c = campaign(7, 60);
    let fgls = calibrate_kinds_feasible(&c.nominal, &c.plain, &c.ols, &FeasibleOptions::default()).unwrap();
    let fitted = (c.plain.observations.len(), c.plain.joints.len());
    let report =
        robocal::report::observations::ObservationsReport::new(&fgls, "data.csv", fitted, "fgls", Vec::new());
    let text = report.text();
    assert!(text.contains("noise estimated from the residuals (feasible GLS):"), "{text}");
    assert!(text.contains("sigma_marker"), "{text}");
    let json = serde_json::to_value(&report).unwrap();
    assert_eq!(json["noise"].as_array().unwrap().len(), 7, "{json}");
}

fn robocal(args: &[&str]) -> std::process::Output {
    assert_cmd::Command::cargo_bin("robocal").unwrap().args(args).output().unwrap()
}

const EXAMPLE: [&str; 10] = [
    "calibrate",
    "--model",
    "puma560",
    "--data",
    "examples/puma560-measurements.csv",
    "--marker",
    "50,0,150",
    "--marker=-40,60,120",
    "--params",
    "all",
];

#[test]
fn calibrate_with_fgls_prints_the_estimated_noise() {
    let output = robocal(&[&EXAMPLE[..], &["--estimator", "fgls"]].concat());
    let stdout = String::from_utf8(output.stdout).unwrap();
    assert!(output.status.success(), "{}", String::from_utf8_lossy(&output.stderr));
    assert!(stdout.contains("100 poses, 2 markers, fgls ("), "{stdout}");
    assert!(stdout.contains("noise estimated from the residuals (feasible GLS):"), "{stdout}");
}

#[test]
fn calibrate_refuses_fgls_with_a_given_noise() {
    let output =
        robocal(&[&EXAMPLE[..], &["--estimator", "fgls", "--joint-sigma-deg", "1,1,1,1,1,1"]].concat());
    assert_eq!(output.status.code(), Some(2), "a usage error");
    let stderr = String::from_utf8(output.stderr).unwrap();
    assert!(
        stderr.contains("--estimator fgls estimates the noise: do not give --noise or --joint-sigma-deg"),
        "{stderr}"
    );
}

#[test]
fn calibrate_reads_a_noise_file_with_a_device() {
    let dir = std::env::temp_dir().join(format!("robocal-fgls-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let noise = dir.join("tracker.toml");
    std::fs::write(
        &noise,
        "joint_sigma = [0.007, 0.007, 0.007, 0.002, 0.002, 0.002]\n[device]\nkind = \"laser-tracker\"\n\
         position_mm = [0.0, 0.0, 0.0]\nsigma_r_mm = 0.005\nk_ppm = 2\nsigma_angle_arcsec = 1.5\n",
    )
    .unwrap();
    let output = robocal(&[&EXAMPLE[..], &["--noise", noise.to_str().unwrap()]].concat());
    let stdout = String::from_utf8(output.stdout).unwrap();
    assert!(output.status.success(), "{}", String::from_utf8_lossy(&output.stderr));
    assert!(stdout.contains("100 poses, 2 markers, wls ("), "{stdout}");
    std::fs::write(&noise, "joint_sigma = [0.007]\n").unwrap();
    let output = robocal(&[&EXAMPLE[..], &["--noise", noise.to_str().unwrap()]].concat());
    let stderr = String::from_utf8(output.stderr).unwrap();
    assert!(
        stderr.contains("tracker.toml: field `joint_sigma`: 6 values, one per joint of puma560"),
        "{stderr}"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

/// Feasible GLS that does not settle says why, in the text and the JSON: a 6-DOF probe read
/// exactly but for the joints' noise leaves its measurement sigmas at about 0, where their
/// estimates swing from one re-weighting to the next by more than the tolerance (a hundredth
/// of their standard error); the warning names each component still moving, by how much, and
/// that the data barely determine it.
#[test]
fn fgls_that_does_not_settle_names_the_components_still_moving() {
    let mut rng = ChaCha8Rng::seed_from_u64(69);
    let nominal = RobotModel::preset("puma560").unwrap();
    let truth = crate::calibration::true_robot(&nominal, &mut rng);
    let mounting = Placement { xyz: Vector3::new(52.0, 1.0, 148.0), rpy: Vector3::new(0.3, -0.2, 0.5) };
    let chain = Chain::probe(&truth, &mounting);
    let real = chain.with_errors(&vec![0.0; chain.params().len()]);
    let sigmas = crate::calibration::joint_sigmas();
    let dir = std::env::temp_dir().join(format!("robocal-fgls-unsettled-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let (data, json) = (dir.join("probe.csv"), dir.join("report.json"));
    std::fs::write(&data, crate::calibration::probe_csv(&nominal, &real, 80, &sigmas, &mut rng)).unwrap();
    {
        let class = "sigma_marker";
        let output = assert_cmd::Command::cargo_bin("robocal")
            .unwrap()
            .args([
                "calibrate",
                "--model",
                "puma560",
                "--marker",
                "50,0,150",
                "--estimator",
                "fgls",
                "--data",
            ])
            .arg(&data)
            .arg("--json")
            .arg(&json)
            .output()
            .unwrap();
        assert!(output.status.success(), "{}", String::from_utf8_lossy(&output.stderr));
        let text = String::from_utf8(output.stdout).unwrap();
        let line = text.lines().find(|l| l.contains("did not settle in 20 re-weightings;")).expect(&text);
        assert!(
            line.contains("; in the last one moved by more than 0.01 of their standard error: "),
            "{line}"
        );
        for name in [class, "sigma_orientation"] {
            let said = format!("{name} (by ");
            let at = line.find(&said).unwrap_or_else(|| panic!("{name}: {line}"));
            assert!(line[at..].contains("the data barely determine it"), "{line}");
        }
        let report: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
        let warning = (report["warnings"].as_array().unwrap().iter())
            .find(|w| w["cause"] == "noise_unsettled")
            .unwrap_or_else(|| panic!("{}", report["warnings"]))
            .clone();
        assert_eq!((warning["reweightings"].as_u64(), warning["tolerance"].as_f64()), (Some(20), Some(0.01)));
        let moving = warning["moving"].as_array().unwrap();
        let orientation = moving.iter().find(|m| m["component"] == "sigma_orientation").expect("moving");
        assert!(orientation["by"].as_f64().unwrap() > 0.01 && orientation["barely_determined"] == true);
    }
    std::fs::remove_dir_all(&dir).unwrap();
}
