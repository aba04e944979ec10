//! The tools that choose a model, on observations of every kind (`calibrate-observations`):
//! priors, robust losses, held and kept parameters. Each on a simulated robot with known errors:
//! its held-out error within 1.2 times the plain weighted fit's, or better.

use crate::kinds::{TOOL, ball_bar, errors_on, options, puma};
use rand::SeedableRng;
use rand::rngs::ChaCha8Rng;
use robocal::calibration::Gauge;
use robocal::calibration::Held;
use robocal::calibration::Loss;
use robocal::calibration::kinds::{KindData, KindOptions, Observation, calibrate_kinds};
use robocal::estimation::{Estimator, PriorEntry};
use robocal::kinematics::Chain;

/// A ball bar's training and held-out readings of a robot with errors on its joints (0.01 mm
/// noise).
fn ball_bar_sets(seed: u64) -> (KindData, KindData) {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let chain = Chain::markers(&puma(), &[TOOL]).remove(0);
    let joints: Vec<String> =
        chain.params().iter().filter(|p| p.name.starts_with('j')).map(|p| p.name.clone()).collect();
    let real = chain.with_errors(&errors_on(&chain, &joints, &mut rng));
    (ball_bar(&real, &mut rng, 0.01), ball_bar(&real, &mut rng, 0.01))
}

/// The held-out RMS after calibrating `training` with `options`.
fn held_out(training: &KindData, validation: &KindData, options: &KindOptions) -> f64 {
    let c = calibrate_kinds(&puma(), training, options).unwrap();
    c.score(validation).unwrap().lengths.1
}

#[test]
fn priors_losses_and_held_parameters_fit_a_ball_bar_as_well_as_plain_wls() {
    let (training, validation) = ball_bar_sets(21);
    let plain = held_out(&training, &validation, &options(Estimator::Wls));
    assert!(plain < 0.02, "plain WLS held out {plain} mm");
    let prior = KindOptions { prior: PriorEntry::parse_list("machined").unwrap(), ..options(Estimator::Wls) };
    let huber = KindOptions { loss: Loss::Huber(1.345), ..options(Estimator::Wls) };
    let hold = KindOptions {
        gauge: Gauge { hold: vec!["j6.d".into()], keep: vec!["j6.a".into()] },
        ..options(Estimator::Wls)
    };
    for (name, o) in [("prior", &prior), ("huber", &huber), ("hold", &hold)] {
        let found = held_out(&training, &validation, o);
        assert!(found < 1.2 * plain, "{name}: held out {found} mm, plain WLS {plain} mm");
    }
    // The prior's standard deviations and the posterior standard errors are reported.
    let c = calibrate_kinds(&puma(), &training, &prior).unwrap();
    let i = c.params.index_by_name("j2.a").unwrap();
    assert!((c.prior_sd[i] - 0.1).abs() < 1e-12, "{}", c.prior_sd[i]);
    // --hold: the held parameter is not estimated, and said so.
    let c = calibrate_kinds(&puma(), &training, &hold).unwrap();
    assert!(!c.refined.estimate.names.iter().any(|n| n == "j6.d"));
    assert!(c.fixed.contains(&Held::ByUser { parameter: "j6.d".into(), setup: false }), "{:?}", c.fixed);
    let e = calibrate_kinds(
        &puma(),
        &training,
        &KindOptions {
            gauge: Gauge { hold: vec!["j9.d".into()], keep: Vec::new() },
            ..options(Estimator::Wls)
        },
    )
    .unwrap_err()
    .to_string();
    assert!(e.contains("j9.d"), "{e}");
}

/// A prior holds nothing: a parameter the ball bar cannot see alone (the first joint's offset,
/// which the pivot absorbs) is estimated at its prior, with a posterior SE near its prior SD.
#[test]
fn with_a_prior_an_unseen_parameter_stays_at_its_prior() {
    let (training, _) = ball_bar_sets(4);
    let c = calibrate_kinds(
        &puma(),
        &training,
        &KindOptions { prior: PriorEntry::parse_list("machined").unwrap(), ..options(Estimator::Wls) },
    )
    .unwrap();
    let names = &c.refined.estimate.names;
    let k = names.iter().position(|n| n == "j1.theta").expect("estimated with its prior");
    let se = c.refined.estimate.standard_errors()[k];
    let prior = 0.5f64.to_radians();
    assert!((se / prior - 1.0).abs() < 0.05, "j1.theta: SE {se} rad, prior SD {prior} rad");
    assert!(c.refined.estimate.x[k].abs() < 1e-6, "j1.theta moved to {}", c.refined.estimate.x[k]);
}

/// A gross error in one reading: Huber's loss weights it down (listed by its line) and the fit
/// of the others is as good as without it; least squares is pulled off.
#[test]
fn a_robust_loss_sets_a_gross_reading_aside() {
    let (mut training, validation) = ball_bar_sets(9);
    if let Observation::ToPoint { measured, .. } = &mut training.observations[17] {
        *measured += 5.0;
    }
    let squared = held_out(&training, &validation, &options(Estimator::Wls));
    let huber = KindOptions { loss: Loss::Huber(1.345), ..options(Estimator::Wls) };
    let robust = held_out(&training, &validation, &huber);
    assert!(robust < 0.02 && squared > 2.0 * robust, "held out: squared {squared} mm, huber {robust} mm");
    let c = calibrate_kinds(&puma(), &training, &huber).unwrap();
    let fit = c.robust.as_ref().unwrap();
    let down: Vec<usize> = fit.down_weighted().map(|(k, _)| k).collect();
    assert_eq!(down, vec![17]);
}

/// The PUMA 560 with errors on every parameter, from seed `seed`, and the stream that drew them
/// (to draw its measurements from).
fn real_puma(seed: u64) -> (robocal::kinematics::ChainAt, ChaCha8Rng) {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let chain = Chain::markers(&puma(), &[TOOL]).remove(0);
    let all: Vec<String> = chain.params().iter().map(|p| p.name.clone()).collect();
    (chain.with_errors(&errors_on(&chain, &all, &mut rng)), rng)
}

/// `calibrate-observations --prior --loss --hold --keep` end to end: the report shows the prior
/// SD column, the loss's line, what --hold held, its k-fold figure called nested (the robust
/// weights made again in each fold; not without a robust loss); --hold and --keep of one name
/// refused.
#[test]
fn the_command_takes_priors_losses_and_the_gauge() {
    let dir = std::env::temp_dir().join(format!("robocal-choice-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let (real, mut rng) = real_puma(12);
    let train = dir.join("train.csv");
    std::fs::write(&train, crate::kinds::ball_bar_csv(&real, 120, &mut rng)).unwrap();
    let run = |extra: &[&str]| {
        assert_cmd::Command::cargo_bin("robocal")
            .unwrap()
            .args(["calibrate", "--model", "puma560", "--tool", "20,-10,120", "--data"])
            .arg(&train)
            .args(extra)
            .output()
            .unwrap()
    };
    let output =
        run(&["--prior", "machined", "--loss", "huber", "--hold", "j6.d", "--keep", "j6.a", "--folds", "3"]);
    let text = String::from_utf8(output.stdout).unwrap();
    assert!(output.status.success(), "{text}{}", String::from_utf8_lossy(&output.stderr));
    assert!(text.contains("prior SD") && text.contains("SD ratio"), "{text}");
    assert!(text.contains("robust loss huber:1.345: "), "{text}");
    assert!(text.contains("j6.d: held at their nominal values by --hold"), "{text}");
    assert!(
        text.contains("3-fold cross-validation, nested"),
        "the loss's weights redone in each fold: {text}"
    );
    let squared = String::from_utf8(run(&["--folds", "3"]).stdout).unwrap();
    assert!(squared.contains("3-fold cross-validation") && !squared.contains("nested"), "{squared}");
    let both = run(&["--hold", "j6.d", "--keep", "j6.d"]);
    assert_eq!(both.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&both.stderr).contains("both --hold and --keep"));
    std::fs::remove_dir_all(&dir).unwrap();
}

/// `evaluate` scores a model on any kind of file: a ball bar's, its pivot fitted with the
/// model held. The model written by `calibrate-observations` re-scores its own training file as
/// the calibration scored it, and a held-out file near the calibration's held-out figure.
#[test]
fn evaluate_scores_a_written_model_on_a_ball_bar() {
    let dir = std::env::temp_dir().join(format!("robocal-evaluate-kinds-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let (real, mut rng) = real_puma(31);
    let (train, test, model, json) =
        (dir.join("train.csv"), dir.join("test.csv"), dir.join("model.toml"), dir.join("report.json"));
    std::fs::write(&train, crate::kinds::ball_bar_csv(&real, 120, &mut rng)).unwrap();
    std::fs::write(&test, crate::kinds::ball_bar_csv(&real, 60, &mut rng)).unwrap();
    let calibrated = assert_cmd::Command::cargo_bin("robocal")
        .unwrap()
        .args(["calibrate", "--model", "puma560", "--tool", "20,-10,120", "--data"])
        .arg(&train)
        .arg("--out-model")
        .arg(&model)
        .arg("--json")
        .arg(&json)
        .output()
        .unwrap();
    assert!(calibrated.status.success(), "{}", String::from_utf8_lossy(&calibrated.stderr));
    let report: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    let training = report["sets"][0][1]["lengths"][1].as_f64().unwrap();
    let evaluated = assert_cmd::Command::cargo_bin("robocal")
        .unwrap()
        .args(["evaluate", "--model"])
        .arg(&model)
        .arg("--data")
        .arg(&train)
        .arg("--data")
        .arg(&test)
        .arg("--json")
        .arg(&json)
        .output()
        .unwrap();
    let text = String::from_utf8(evaluated.stdout).unwrap();
    assert!(evaluated.status.success(), "{text}{}", String::from_utf8_lossy(&evaluated.stderr));
    assert!(text.contains("on 2 files, the robot and its tool point held"), "{text}");
    let scored: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    let again = scored["observations"][0][1]["lengths"][1].as_f64().unwrap();
    assert!((again - training).abs() < 1e-6 * training, "re-scored {again} mm, calibrated {training} mm");
    let held_out = scored["observations"][1][1]["lengths"][1].as_f64().unwrap();
    assert!(held_out < 0.02, "held out {held_out} mm\n{text}");
    std::fs::remove_dir_all(&dir).unwrap();
}

/// A URDF arm calibrated from a ball bar writes its calibrated URDF (`--out-urdf`), which
/// `evaluate` re-scores on the training file as the calibration scored it.
#[test]
fn a_urdf_arm_calibrated_from_a_ball_bar_writes_its_urdf() {
    use rand::RngExt;
    use rand_distr::{Distribution, StandardNormal};
    let dir = std::env::temp_dir().join(format!("robocal-kinds-urdf-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let urdf = "examples/arm7/arm7.urdf";
    let model = robocal::io::load_model(&robocal::model::ModelRef::named(urdf)).unwrap();
    let mut rng = ChaCha8Rng::seed_from_u64(40);
    let chain = Chain::markers(&model, &[TOOL]).remove(0);
    let joints: Vec<String> = (chain.params().iter())
        .filter(|p| p.name.starts_with('j') && !p.is_load_response())
        .map(|p| p.name.clone())
        .collect();
    let real = chain.with_errors(&errors_on(&chain, &joints, &mut rng));
    let names: Vec<&str> = model.joints.iter().map(|j| j.name.as_str()).collect();
    let mut text = format!("# units: joints=deg, lengths=mm\n{},distance,sigma\n", names.join(","));
    for _ in 0..200 {
        let q: Vec<f64> = model.joints.iter().map(|j| rng.random_range(j.limits[0]..j.limits[1])).collect();
        let z: f64 = StandardNormal.sample(&mut rng);
        let d = (real.position(&q) - nalgebra::Vector3::new(500.0, 100.0, 200.0)).norm() + 0.005 * z;
        let degrees: Vec<String> = q.iter().map(|v| format!("{:.9}", v.to_degrees())).collect();
        text += &format!("{},{d:.6},0.005\n", degrees.join(","));
    }
    let (train, out, json) = (dir.join("bar.csv"), dir.join("calibrated.urdf"), dir.join("report.json"));
    std::fs::write(&train, text).unwrap();
    let tool = format!("{},{},{}", TOOL.x, TOOL.y, TOOL.z);
    let calibrated = assert_cmd::Command::cargo_bin("robocal")
        .unwrap()
        .args(["calibrate", "--model", urdf, "--tool", &tool, "--data"])
        .arg(&train)
        .arg("--out-urdf")
        .arg(&out)
        .arg("--json")
        .arg(&json)
        .output()
        .unwrap();
    assert!(calibrated.status.success(), "{}", String::from_utf8_lossy(&calibrated.stderr));
    let report: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    let training = report["sets"][0][1]["lengths"][1].as_f64().unwrap();
    assert!(training < 0.01, "training RMS {training} mm");
    let evaluated = assert_cmd::Command::cargo_bin("robocal")
        .unwrap()
        .args(["evaluate", "--model"])
        .arg(&out)
        .arg("--data")
        .arg(&train)
        .arg("--json")
        .arg(&json)
        .output()
        .unwrap();
    assert!(evaluated.status.success(), "{}", String::from_utf8_lossy(&evaluated.stderr));
    let scored: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    let again = scored["observations"][0][1]["lengths"][1].as_f64().unwrap();
    assert!((again - training).abs() < 1e-6 * training, "re-scored {again} mm, calibrated {training} mm");
    let refused = assert_cmd::Command::cargo_bin("robocal")
        .unwrap()
        .args(["calibrate", "--model", "puma560", "--data"])
        .arg(&train)
        .arg("--out-urdf")
        .arg(&out)
        .output()
        .unwrap();
    assert_eq!(refused.status.code(), Some(2));
    std::fs::remove_dir_all(&dir).unwrap();
}

/// `n` ball-bar readings (noise `sigma` mm) of the robot `real` from the pivot (400, 200, 300)
/// mm, at random poses.
fn few_readings(real: &robocal::kinematics::ChainAt, n: usize, sigma: f64, rng: &mut ChaCha8Rng) -> KindData {
    use rand_distr::{Distribution, StandardNormal};
    let pivot = nalgebra::Vector3::new(400.0, 200.0, 300.0);
    let mut data = KindData::default();
    for pose in 0..n {
        let q = crate::kinds::random_pose(&puma(), rng);
        let z: f64 = StandardNormal.sample(&mut *rng);
        let measured = (real.position(&q) - pivot).norm() + sigma * z;
        data.joints.push(q);
        data.observations.push(Observation::ToPoint { pose, point: 0, measured, sigma });
        data.lines.push(pose + 3);
    }
    data
}

/// `--prior auto` on observation files follows the robot as on marker data: a PUMA whose joint
/// errors are drawn from the `machined` tolerances times 1/4 or times 4, measured by a ball bar
/// (60 readings, 0.05 mm), on 3 seeds. The scale chosen for the robot 16 times further off is
/// larger on every seed, and the held-out RMS (300 readings) with the chosen scale is within 15%
/// of the best of the scales' (an oracle that sees the held-out readings).
#[test]
fn prior_auto_scales_the_preset_with_the_robot_under_a_ball_bar() {
    use robocal::calibration::Kinds;
    use robocal::calibration::prior_scale::{AutoPrior, SCALES, choose_prior_scale, with_scale};
    let chain = Chain::markers(&puma(), &[TOOL]).remove(0);
    let auto = AutoPrior::parse("auto:machined").unwrap().unwrap();
    let sd = robocal::estimation::prior_sds(&auto.entries, chain.params()).unwrap();
    let plain = options(Estimator::Wls);
    for seed in 0..3 {
        let mut chosen = Vec::new();
        for truth in [0.25, 4.0] {
            let mut rng = ChaCha8Rng::seed_from_u64(seed);
            let x: Vec<f64> = (chain.params().iter().zip(&sd))
                .map(|(p, s)| {
                    let z: f64 = rand_distr::Distribution::sample(&rand_distr::StandardNormal, &mut rng);
                    if p.name.starts_with('j') && s.is_finite() { z * s * truth } else { 0.0 }
                })
                .collect();
            let real = chain.with_errors(&x);
            let (train, test) =
                (few_readings(&real, 60, 0.05, &mut rng), few_readings(&real, 300, 0.05, &mut rng));
            let scale = choose_prior_scale(&Kinds(&puma()), &train, &plain, &auto, 5).unwrap();
            assert_eq!(scale.cv_rms.len(), SCALES.len());
            let held = |s: f64| held_out(&train, &test, &with_scale::<Kinds>(&plain, &auto, s));
            let all: Vec<f64> = SCALES.iter().map(|&s| held(s)).collect();
            let (found, best) = (all[scale.chosen], all.iter().copied().fold(f64::INFINITY, f64::min));
            assert!(found < 1.15 * best, "seed {seed}, x{truth}: {found} against the best {best}: {all:?}");
            chosen.push(scale.scale());
        }
        assert!(chosen[1] > chosen[0], "seed {seed}: {chosen:?}");
    }
}

/// `calibrate --prior auto:machined --folds 3` on a ball bar's file prints the scale it chose
/// with its curve and labels the cross-validation nested; the JSON has the curve.
#[test]
fn the_command_scales_a_prior_on_observation_files() {
    let dir = std::env::temp_dir().join(format!("robocal-kinds-prior-auto-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let json = dir.join("report.json");
    let output = assert_cmd::Command::cargo_bin("robocal")
        .unwrap()
        .args(["calibrate", "--model", "puma560", "--tool", "50,0,150"])
        .args(["--data", "examples/puma560-ballbar.csv", "--validate", "examples/puma560-ballbar-2.csv"])
        .args(["--joint-sigma-deg", "0.007,0.007,0.007,0.002,0.002,0.002"])
        .args(["--prior", "auto:machined", "--folds", "3", "--json"])
        .arg(&json)
        .output()
        .unwrap();
    assert!(output.status.success(), "{}", String::from_utf8_lossy(&output.stderr));
    let text = String::from_utf8(output.stdout).unwrap();
    let report: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    assert_prior_scale(&report, &text, 3);
    assert!(text.contains("3-fold cross-validation, nested (mm)"), "{text}");
    std::fs::remove_dir_all(&dir).unwrap();
}

/// A command's `--prior auto:machined` with `folds` folds, in its JSON `report` and its `text`:
/// the scale chosen the lowest of the 9 scales' curve, printed with the curve.
pub(crate) fn assert_prior_scale(report: &serde_json::Value, text: &str, folds: u64) {
    let scale = &report["prior_scale"];
    assert_eq!((scale["preset"].as_str(), scale["folds"].as_u64()), (Some("machined"), Some(folds)));
    let chosen = scale["chosen"].as_u64().unwrap() as usize;
    let rms: Vec<f64> = scale["cv_rms"].as_array().unwrap().iter().map(|v| v.as_f64().unwrap()).collect();
    assert!(rms.len() == 9 && rms.iter().all(|r| *r >= rms[chosen]), "{rms:?}");
    let s = scale["scales"][chosen].as_f64().unwrap();
    let line =
        format!("prior scale: --prior auto:machined chose {s} x its standard deviations, by {folds}-fold");
    assert!(text.contains(&line) && text.contains("  <- chosen\n"), "{text}");
}
