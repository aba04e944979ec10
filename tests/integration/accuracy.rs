//! Accuracy prediction against a Monte Carlo: the spread of many calibrations' errors at test
//! poses is what the covariance of one of them predicts there.

use assert_cmd::Command;
use nalgebra::Vector3;
use rand::rngs::ChaCha8Rng;
use rand::{RngExt, SeedableRng};
use rand_distr::{Distribution, StandardNormal};
use rayon::prelude::*;
use robocal::calibration::kinds::calibrate_kinds;
use robocal::design::accuracy::{AccuracyModel, ParameterCovariance};
use robocal::estimation::{Estimator, MeasurementNoise, NoiseModel};
use robocal::kinematics::Chain;
use robocal::model::{Placement, RobotModel};
use robocal::simulation::measurement_csv;

/// One calibration's position errors at the test poses, and (the first's) predictions there.
type Run = (Vec<Vector3<f64>>, Option<Vec<f64>>);

fn positions(model: &RobotModel, poses: &[Vec<f64>]) -> Vec<Vector3<f64>> {
    let chain = Chain::new(model);
    let at = chain.with_errors(&vec![0.0; chain.params().len()]);
    poses.iter().map(|q| at.position(q)).collect()
}

/// 200 calibrations of one true PUMA from one set of 40 poses, each with its own noise: at each
/// of 50 test poses, the standard deviation of the calibrated models' position errors (the
/// RMS distance from their mean) against `sqrt(trace(J_x Sigma_x J_x^T))` of one calibration.
#[test]
fn predicted_accuracy_matches_the_spread_of_200_calibrations() {
    let mut rng = ChaCha8Rng::seed_from_u64(2028);
    let nominal = RobotModel::preset("puma560").unwrap();
    let mut truth = nominal.clone();
    for joint in &mut truth.joints {
        let mut n = || -> f64 { StandardNormal.sample(&mut rng) };
        (joint.theta, joint.d, joint.a) =
            (joint.theta + 0.1f64.to_radians() * n(), joint.d + 0.5 * n(), joint.a + 0.5 * n());
        joint.alpha += 0.05f64.to_radians() * n();
    }
    truth.base = Placement { xyz: Vector3::new(1500.0, -300.0, 200.0), rpy: Vector3::new(0.1, -0.05, 0.6) };
    let marker = Vector3::new(52.0, 1.0, 148.0);
    truth.tool = robocal::model::Tool::Point(marker);
    let draw = |n: usize, rng: &mut ChaCha8Rng| -> Vec<Vec<f64>> {
        (0..n)
            .map(|_| nominal.joints.iter().map(|j| rng.random_range(j.limits[0]..j.limits[1])).collect())
            .collect()
    };
    let (training, test) = (draw(40, &mut rng), draw(50, &mut rng));
    let sigmas: Vec<f64> =
        [0.007, 0.007, 0.007, 0.002, 0.002, 0.002].iter().map(|d: &f64| d.to_radians()).collect();
    let noise = NoiseModel::diagonal(&sigmas, MeasurementNoise::isotropic(0.01, 0.0));
    let options =
        crate::marker_options(&nominal, Estimator::Wls, Some(&noise), &[Vector3::new(50.0, 0.0, 150.0)]);
    let truth_at_test = positions(&truth, &test);
    let runs: Vec<Run> = (0..200u64)
        .into_par_iter()
        .map(|run| {
            let text = measurement_csv(&truth, &[marker], &training, &sigmas, 0.01, 100 + run);
            let data = crate::marker_data(&text, &nominal, Some(&noise));
            let c = calibrate_kinds(&nominal, &data, &options).unwrap();
            let errors =
                positions(&c.calibrated, &test).iter().zip(&truth_at_test).map(|(a, b)| a - b).collect();
            let predicted = (run == 0).then(|| {
                let e = &c.refined.estimate;
                let covariance = ParameterCovariance::new(e.names.clone(), &e.covariance, 0.0);
                let model = AccuracyModel::new(&c.calibrated, &covariance).unwrap();
                test.iter().map(|q| model.predict(q).position_mm).collect()
            });
            (errors, predicted)
        })
        .collect();
    let predicted = runs[0].1.clone().unwrap();
    let mut ratios = Vec::new();
    for (k, predicted) in predicted.iter().enumerate() {
        let errors: Vec<Vector3<f64>> = runs.iter().map(|r| r.0[k]).collect();
        let mean = errors.iter().sum::<Vector3<f64>>() / errors.len() as f64;
        let spread = (errors.iter().map(|e| (e - mean).norm_squared()).sum::<f64>()
            / (errors.len() - 1) as f64)
            .sqrt();
        ratios.push(predicted / spread);
    }
    let (lo, hi) = ratios.iter().fold((f64::INFINITY, 0.0f64), |(lo, hi), r| (lo.min(*r), hi.max(*r)));
    eprintln!("predicted / Monte Carlo SD at 50 test poses: {lo:.3} .. {hi:.3}");
    assert!(lo > 0.85 && hi < 1.15, "{ratios:?}");
}

fn temp(name: &str) -> std::path::PathBuf {
    let dir = std::env::temp_dir().join(format!("robocal-accuracy-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir.join(name)
}

#[test]
fn calibrate_writes_the_covariance_and_accuracy_maps_it() {
    let model = temp("calibrated.toml");
    let output = Command::cargo_bin("robocal")
        .unwrap()
        .args(["calibrate", "--model", "puma560", "--data", "examples/puma560-measurements.csv"])
        .args([
            "--validate",
            "examples/puma560-validation.csv",
            "--marker",
            "50,0,150",
            "--marker=-40,60,120",
        ])
        .args([
            "--joint-sigma-deg",
            "0.007,0.007,0.007,0.002,0.002,0.002",
            "--sigma-mm",
            "0.01",
            "--out-model",
        ])
        .arg(&model)
        .output()
        .unwrap();
    assert!(output.status.success(), "{}", String::from_utf8_lossy(&output.stderr));
    let sidecar = std::fs::read_to_string(temp("calibrated.toml.covariance.json")).unwrap();
    let covariance = ParameterCovariance::from_json(&sidecar).unwrap();
    assert_eq!(covariance.names.len(), 30, "the README's 30 parameters");
    assert!((covariance.floor_mm - 0.1162).abs() < 1e-4, "the held-out rms after: {}", covariance.floor_mm);
    let (csv, figures) = (temp("accuracy.csv"), temp("figures"));
    let output = Command::cargo_bin("robocal")
        .unwrap()
        .args([
            "accuracy",
            "--poses",
            "examples/puma560-validation.csv",
            "--calibration-poses",
            "examples/puma560-measurements.csv",
            "--model",
        ])
        .arg(&model)
        .arg("--out")
        .arg(&csv)
        .arg("--figures")
        .arg(&figures)
        .output()
        .unwrap();
    assert!(output.status.success(), "{}", String::from_utf8_lossy(&output.stderr));
    let report = String::from_utf8(output.stdout).unwrap();
    assert!(
        report.contains("predicted accuracy at 50 poses") && report.contains("27 parameters"),
        "{report}"
    );
    let text = std::fs::read_to_string(&csv).unwrap();
    let rows: Vec<&str> = text.lines().skip(2).collect();
    assert_eq!(rows.len(), 50);
    for row in rows {
        let sd: f64 = row.split(',').nth(12).unwrap().parse().unwrap();
        assert!(sd > covariance.floor_mm && sd < 2.0 * covariance.floor_mm, "{row}");
    }
    for name in ["accuracy-map.svg", "accuracy-vs-joints.svg"] {
        assert!(std::fs::read_to_string(figures.join(name)).unwrap().starts_with("<svg"), "{name}");
    }
    // without the sidecar: one clear error naming it
    let output = Command::cargo_bin("robocal")
        .unwrap()
        .args(["accuracy", "--model", "puma560", "--grid", "3"])
        .output()
        .unwrap();
    let message = String::from_utf8_lossy(&output.stderr);
    assert!(!output.status.success() && message.contains("puma560.covariance.json"), "{message}");
}

/// `calibrate --validate` reports the accuracy predicted at the held-out poses from its own
/// covariance, as `robocal accuracy` predicts it: with the floor (the held-out RMS) in
/// quadrature, and from the parameters alone below it.
#[test]
fn calibrate_reports_the_accuracy_predicted_at_its_held_out_poses() {
    let dir = std::env::temp_dir().join(format!("robocal-predicted-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let json = dir.join("report.json");
    let output = assert_cmd::Command::cargo_bin("robocal")
        .unwrap()
        .args(["calibrate", "--model", "puma560", "--data", "examples/puma560-measurements.csv"])
        .args([
            "--marker",
            "50,0,150",
            "--marker=-40,60,120",
            "--validate",
            "examples/puma560-validation.csv",
        ])
        .args(["--joint-sigma-deg", "0.007,0.007,0.007,0.002,0.002,0.002", "--sigma-mm", "0.05", "--json"])
        .arg(&json)
        .output()
        .unwrap();
    assert!(output.status.success(), "{}", String::from_utf8_lossy(&output.stderr));
    let report: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    let predicted = &report["predicted"][0];
    let (mean, alone, floor) = (
        predicted["mean_mm"].as_f64().unwrap(),
        predicted["parameters_mm"].as_f64().unwrap(),
        predicted["floor_mm"].as_f64().unwrap(),
    );
    assert_eq!(predicted["set"], "examples/puma560-validation.csv");
    assert!(alone > 0.0 && alone < floor && floor < mean, "{predicted}");
    assert!(mean <= (alone * alone * 4.0 + floor * floor).sqrt(), "{predicted}");
    std::fs::remove_dir_all(&dir).unwrap();
}

/// An observation calibration predicts the tool point's position error at the held-out poses
/// from its covariance, as a marker calibration does: on 40 ball-bar calibrations (150
/// distances, 0.02 mm) of a robot with errors on the parameters a ball bar identifies, the
/// predicted variance (from the parameters alone: no position measured, no floor) averaged
/// over the runs is the calibrated tool's squared position error against the truth at the
/// held-out poses, to 25% (40 runs x 150 poses: a few % of sampling spread, the rest the
/// linearisation).
#[test]
fn an_observation_calibration_predicts_its_tool_points_error() {
    use crate::kinds::{TOOL, ball_bar, errors_on, options, puma, robot_estimates};
    use robocal::calibration::kinds::{KindData, calibrate_kinds};
    use robocal::calibration::{Choices, Kinds};
    use robocal::pipeline::{Fitting, calibrate_files};
    let mut rng = ChaCha8Rng::seed_from_u64(91);
    let model = puma();
    let chain = Chain::markers(&model, &[TOOL]).remove(0);
    let zero = vec![0.0; chain.params().len()];
    let first = calibrate_kinds(
        &model,
        &ball_bar(&chain.with_errors(&zero), &mut rng, 0.0),
        &options(Estimator::Ols),
    );
    let identified = robot_estimates(&first.unwrap().refined.estimate.names, &chain);
    let truth = chain.with_errors(&errors_on(&chain, &identified, &mut rng));
    let (mut predicted, mut actual) = (0.0, 0.0);
    let runs = 40;
    for _ in 0..runs {
        let fit: KindData = ball_bar(&truth, &mut rng, 0.02);
        let held = ball_bar(&truth, &mut rng, 0.02);
        let fitting = Fitting::new(false, Choices::default(), None);
        let outcome = calibrate_files(
            &Kinds(&model),
            &[("fit".into(), fit)],
            &[("held".into(), held.clone())],
            &options(Estimator::Wls),
            &fitting,
        )
        .unwrap();
        let p = &outcome.report.predicted[0];
        assert_eq!((p.set.as_str(), p.floor_mm, p.mean_mm), ("held", 0.0, p.parameters_mm));
        predicted += p.parameters_mm.powi(2) / runs as f64;
        let calibrated = Chain::new(&outcome.calibration.calibrated);
        let calibrated = calibrated.with_errors(&vec![0.0; calibrated.params().len()]);
        let errors: f64 =
            held.joints.iter().map(|q| (calibrated.position(q) - truth.position(q)).norm_squared()).sum();
        actual += errors / (held.joints.len() * runs) as f64;
    }
    let ratio = (predicted / actual).sqrt();
    assert!((0.8..1.25).contains(&ratio), "predicted {} mm, actual {} mm", predicted.sqrt(), actual.sqrt());
}

/// An observation calibration (markers with a ball bar) writes the covariance sidecar of the
/// robot's parameters beside `--out-model`, the ball bar's centre left out (it does not move
/// the tool), the markers kept (marker 1 is the written tool), the floor the held-out marker
/// RMS; `robocal accuracy` reads it
/// and predicts at the held-out poses what the report predicted there (to its CSV's digits).
#[test]
fn an_observation_calibration_writes_the_covariance_accuracy_reads() {
    let dir = std::env::temp_dir().join(format!("robocal-kinds-sidecar-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let (model, csv) = (dir.join("m.toml"), dir.join("a.csv"));
    let (_, report) = crate::nested::calibrate_puma(&[
        "--data",
        "examples/puma560-ballbar.csv",
        "--validate",
        "examples/puma560-validation.csv",
        "--out-model",
        model.to_str().unwrap(),
    ]);
    let sidecar = std::fs::read_to_string(dir.join("m.toml.covariance.json")).unwrap();
    let covariance = ParameterCovariance::from_json(&sidecar).unwrap();
    assert!(covariance.names.iter().all(|n| !n.starts_with("point")), "{:?}", covariance.names);
    assert!(covariance.names.iter().any(|n| n == "marker1.x"), "{:?}", covariance.names);
    assert!(covariance.names.iter().any(|n| n == "j2.theta"), "{:?}", covariance.names);
    let predicted = &report["predicted"][0];
    assert_eq!(Some(covariance.floor_mm), predicted["floor_mm"].as_f64());
    let output = Command::cargo_bin("robocal")
        .unwrap()
        .args(["accuracy", "-q", "--poses", "examples/puma560-validation.csv", "--model"])
        .arg(&model)
        .arg("--out")
        .arg(&csv)
        .output()
        .unwrap();
    assert!(output.status.success(), "{}", String::from_utf8_lossy(&output.stderr));
    let text = std::fs::read_to_string(&csv).unwrap();
    let sd: Vec<f64> =
        text.lines().skip(2).map(|row| row.split(',').nth(12).unwrap().parse().unwrap()).collect();
    let mean = sd.iter().sum::<f64>() / sd.len() as f64;
    let expected = predicted["mean_mm"].as_f64().unwrap();
    // The CSV's SDs to 6 decimals (mm): each within 5e-7 of the prediction.
    assert!((mean - expected).abs() < 5e-7, "{mean} {expected}");
    std::fs::remove_dir_all(&dir).unwrap();
}

/// A marker file's predicted held-out accuracy is the same whichever fit makes it: the marker
/// calibration's, and the observation fit's (`--tool 0,0,0` sends the file there), whose
/// covariance keeps the markers (marker 1 is the tool the prediction moves).
#[test]
fn a_marker_files_predicted_accuracy_is_the_same_through_the_observation_fit() {
    let predicted = |extra: &[&str]| -> String {
        let noise = ["--joint-sigma-deg", "0.007,0.007,0.007,0.002,0.002,0.002", "--sigma-mm", "0.01"];
        let validate = ["--validate", "examples/puma560-validation.csv"];
        let (text, _) = crate::nested::calibrate_puma(&[&validate[..], &noise, extra].concat());
        let at = text.find("predicted position error SD").unwrap_or_else(|| panic!("{text}"));
        text[at..].lines().take(2).collect::<Vec<_>>().join("\n")
    };
    let markers = predicted(&[]);
    assert!(markers.contains("from the parameters alone 0.0201 mm"), "{markers}");
    assert_eq!(predicted(&["--tool", "0,0,0"]), markers);
}
