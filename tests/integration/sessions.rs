//! Measuring sessions: an instrument re-zeroed between data files, its length zero one set-up
//! parameter per session (`--per-session point1.zero`).

use crate::kinds::{TOOL, errors_on, options, puma, random_pose};
use nalgebra::Vector3;
use rand::SeedableRng;
use rand::rngs::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};
use robocal::calibration::kinds::{
    KindCalibration, KindData, KindOptions, Observation, SessionSetUp, calibrate_kinds,
};
use robocal::estimation::Estimator;
use robocal::kinematics::{Chain, ChainAt};

/// The draw-wire's fixed point (mm, base frame).
const PIVOT: Vector3<f64> = Vector3::new(600.0, -250.0, -300.0);

/// The zero of the three sessions (mm): it jumps by +3.9 mm, then by -0.9 mm.
const ZEROS: [f64; 3] = [1.2, 5.1, 4.2];

/// Noise of a draw-wire reading (mm).
const SIGMA: f64 = 0.01;

/// `count` draw-wire readings of the robot `real` from [`PIVOT`], the instrument's zero `zero`,
/// as one session named `name`.
fn draw_wire(real: &ChainAt, zero: f64, count: usize, name: &str, rng: &mut ChaCha8Rng) -> KindData {
    let mut data = KindData::default();
    for k in 0..count {
        let q = random_pose(&puma(), rng);
        let z: f64 = StandardNormal.sample(&mut *rng);
        let measured = (real.position(&q) - PIVOT).norm() + zero + SIGMA * z;
        data.joints.push(q);
        data.observations.push(Observation::ToPoint { pose: k, point: 0, measured, sigma: SIGMA });
        data.lines.push(k + 3);
    }
    data.named(name)
}

/// Three training sessions and three held-out files of the same names, from a robot with
/// errors on its joints.
fn three_sessions(seed: u64) -> (KindData, Vec<KindData>) {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let chain = Chain::markers(&puma(), &[TOOL]).remove(0);
    let joints: Vec<String> =
        chain.params().iter().filter(|p| p.name.starts_with('j')).map(|p| p.name.clone()).collect();
    let real = chain.with_errors(&errors_on(&chain, &joints, &mut rng));
    let names = ["monday", "tuesday", "wednesday"];
    let training = (0..3)
        .map(|s| draw_wire(&real, ZEROS[s], 120, names[s], &mut rng))
        .fold(KindData::default(), |all, session| all.join(&session));
    let held_out = (0..3).map(|s| draw_wire(&real, ZEROS[s], 60, names[s], &mut rng)).collect();
    (training, held_out)
}

/// The estimate and standard error of `b - a`, two estimated parameters of `c`.
fn difference(c: &KindCalibration, a: &str, b: &str) -> (f64, f64) {
    let est = &c.refined.estimate;
    let at =
        |n: &str| est.names.iter().position(|m| m == n).unwrap_or_else(|| panic!("{n} in {:?}", est.names));
    let (i, j) = (at(a), at(b));
    let cov = &est.covariance;
    (est.x[j] - est.x[i], (cov[(i, i)] + cov[(j, j)] - 2.0 * cov[(i, j)]).sqrt())
}

/// The held-out RMS after calibration of each file, and where each one's set-up came from.
fn held_out(c: &KindCalibration, files: &[KindData]) -> Vec<(f64, Vec<(String, SessionSetUp)>)> {
    files.iter().map(|f| c.score(f).unwrap()).map(|s| (s.lengths.1, s.sessions)).collect()
}

#[test]
fn a_draw_wire_re_zeroed_between_sessions_is_modelled_by_per_session_zeros() {
    let (training, validation) = three_sessions(7);
    let per_session = KindOptions { per_session: vec!["point1.zero".into()], ..options(Estimator::Wls) };
    let c = calibrate_kinds(&puma(), &training, &per_session).unwrap();
    // The jumps, recovered within 3 standard errors.
    for (a, b, jump) in [("monday", "tuesday", 3.9), ("tuesday", "wednesday", -0.9)] {
        let (found, se) = difference(&c, &format!("point1.zero@{a}"), &format!("point1.zero@{b}"));
        assert!((found - jump).abs() < 3.0 * se, "{a} to {b}: {found} mm against {jump}, SE {se}");
        assert!(se < 0.05, "{a} to {b}: SE {se} mm");
    }
    // Held out, each file scored with the set-up of the training session of its name: the
    // noise level.
    let scored = held_out(&c, &validation);
    for (rms, sessions) in &scored {
        assert!(*rms < 2.0 * SIGMA, "held-out RMS {rms} mm after, noise {SIGMA} mm");
        assert!(
            matches!(sessions[0].1, SessionSetUp::Training(ref n) if *n == sessions[0].0),
            "{sessions:?}"
        );
    }
    // Without per-session zeros the jumps are errors of the robot: several times larger.
    let one_zero = KindOptions {
        joints: robocal::calibration::JointParams::Named(vec!["j*.*".into(), "point1.zero".into()]),
        ..options(Estimator::Wls)
    };
    let shared = calibrate_kinds(&puma(), &training, &one_zero).unwrap();
    assert!(shared.refined.estimate.names.iter().any(|n| n == "point1.zero"));
    for ((with, _), (without, _)) in scored.iter().zip(held_out(&shared, &validation)) {
        assert!(without > 5.0 * with, "held out: {without} mm with one zero, {with} mm per session");
    }
}

#[test]
fn a_held_out_session_of_another_name_has_its_zero_fitted_with_the_robot_held() {
    let (training, validation) = three_sessions(11);
    let per_session = KindOptions { per_session: vec!["point1.zero".into()], ..options(Estimator::Wls) };
    let c = calibrate_kinds(&puma(), &training, &per_session).unwrap();
    // Tuesday's held-out readings under another name: its zero is fitted on the file alone.
    let renamed = validation[1].clone().named("thursday");
    let score = c.score(&renamed).unwrap();
    assert_eq!(score.sessions, vec![("thursday".to_string(), SessionSetUp::Fitted)]);
    assert!(score.lengths.1 < 2.0 * SIGMA, "fitted zero: held-out RMS {} mm", score.lengths.1);
    // Scored with Monday's set-up instead, its jump of 3.9 mm remains.
    let as_monday = c.score(&validation[1].clone().named("monday")).unwrap();
    assert!((as_monday.lengths.1 - 3.9).abs() < 0.1, "{} mm", as_monday.lengths.1);
}

#[test]
fn per_session_names_must_name_set_up_parameters() {
    let (training, _) = three_sessions(3);
    let wrong = KindOptions { per_session: vec!["point7.zero".into()], ..options(Estimator::Wls) };
    let e = calibrate_kinds(&puma(), &training, &wrong).unwrap_err().to_string();
    assert!(e.contains("point7.zero"), "{e}");
}

/// `data` as a draw-wire file (`j1..j6,point,distance,sigma`, degrees and mm).
fn csv(data: &KindData) -> String {
    let mut text = String::from("# units: joints=deg, lengths=mm\nj1,j2,j3,j4,j5,j6,point,distance,sigma\n");
    for (q, o) in data.joints.iter().zip(&data.observations) {
        let degrees: Vec<String> = q.iter().map(|v| format!("{:.12}", v.to_degrees())).collect();
        text += &format!("{},1,{:.9},{SIGMA}\n", degrees.join(","), o.measured());
    }
    text
}

/// `robocal calibrate-observations --per-session point1.zero` on three session files: each
/// session's zero reported with its standard error, the held-out files of the same stems
/// scored with their sessions' set-up (said), at the noise level; a file of another stem has
/// its zero fitted (said); one --data file, or two of one stem, refused.
#[test]
fn the_command_models_sessions_from_the_files() {
    let (dir, train_dir, test_dir) = session_folders("sessions");
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    let chain = Chain::markers(&puma(), &[TOOL]).remove(0);
    let joints: Vec<String> =
        chain.params().iter().filter(|p| p.name.starts_with('j')).map(|p| p.name.clone()).collect();
    let real = chain.with_errors(&errors_on(&chain, &joints, &mut rng));
    let names = ["monday", "tuesday", "wednesday"];
    let path = |p: std::path::PathBuf| p.to_str().unwrap().to_string();
    let mut args: Vec<String> =
        ["calibrate", "--model", "puma560", "--tool", "20,-10,120"].map(String::from).to_vec();
    for (s, name) in names.iter().enumerate() {
        let file = train_dir.join(format!("{name}.csv"));
        std::fs::write(&file, csv(&draw_wire(&real, ZEROS[s], 120, name, &mut rng))).unwrap();
        args.extend(["--data".into(), path(file)]);
        let held_out = test_dir.join(format!("{name}.csv"));
        std::fs::write(&held_out, csv(&draw_wire(&real, ZEROS[s], 60, name, &mut rng))).unwrap();
        args.extend(["--validate".into(), path(held_out)]);
    }
    let other = test_dir.join("thursday.csv");
    std::fs::write(&other, csv(&draw_wire(&real, 2.0, 60, "thursday", &mut rng))).unwrap();
    args.extend(["--validate".into(), path(other), "--per-session".into(), "point1.zero".into()]);
    args.extend(["--folds".into(), "4".into()]);
    let output = assert_cmd::Command::cargo_bin("robocal").unwrap().args(&args).output().unwrap();
    let text = String::from_utf8(output.stdout).unwrap();
    assert!(output.status.success(), "{text}{}", String::from_utf8_lossy(&output.stderr));
    for name in names {
        assert!(text.contains(&format!("point1.zero@{name} ")), "{text}");
        assert!(
            text.contains(&format!("{name}.csv: the per-session set-up of training session `{name}`")),
            "{text}"
        );
    }
    assert!(text.contains("session `thursday` is no training file's"), "{text}");
    let rms = |line: &str| -> f64 {
        let row =
            text.lines().find(|l| l.contains(line) && l.contains("(mm)")).unwrap_or_else(|| panic!("{text}"));
        crate::verdict_rms(row).1
    };
    for name in ["monday.csv", "tuesday.csv", "wednesday.csv", "thursday.csv", "4-fold cross-validation"] {
        assert!(rms(name) < 2.0 * SIGMA, "{name}\n{text}");
    }

    let one = assert_cmd::Command::cargo_bin("robocal")
        .unwrap()
        .args(&args[..7])
        .args(["--per-session", "point1.zero"])
        .output()
        .unwrap();
    assert_eq!(one.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&one.stderr).contains("give two --data files or more"));
    let same_stem = assert_cmd::Command::cargo_bin("robocal")
        .unwrap()
        .args(&args[..7])
        .args(["--data", &args[8].replace("monday", "tuesday").replace("train", "test")])
        .args(["--data", &args[10], "--per-session", "point1.zero"])
        .output()
        .unwrap();
    assert_eq!(same_stem.status.code(), Some(2));
    assert!(
        String::from_utf8_lossy(&same_stem.stderr).contains("have one stem, `tuesday`"),
        "{}",
        String::from_utf8_lossy(&same_stem.stderr)
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

/// k-fold cross-validation keeps each session's zero in every fold: with per-session zeros the
/// pooled held-out folds are at the noise level, as the held-out files are; with one zero they
/// are not.
#[test]
fn cross_validation_keeps_the_sessions_in_every_fold() {
    use robocal::calibration::kinds::cross_validate_kinds;
    let (training, _) = three_sessions(17);
    let per_session = KindOptions { per_session: vec!["point1.zero".into()], ..options(Estimator::Wls) };
    let folds = cross_validate_kinds(&puma(), &training, &per_session, 5).unwrap();
    assert_eq!(folds.observations.len(), training.observations.len());
    assert!(folds.lengths.1 < 2.0 * SIGMA, "5-fold RMS {} mm", folds.lengths.1);
    let shared = cross_validate_kinds(&puma(), &training, &options(Estimator::Wls), 5).unwrap();
    assert!(shared.lengths.1 > 5.0 * folds.lengths.1, "{} mm against {}", shared.lengths.1, folds.lengths.1);
    let e = cross_validate_kinds(&puma(), &training, &per_session, 1).unwrap_err().to_string();
    assert!(e.contains("1 folds for 360 poses: expected 2 to the number of poses"), "{e}");
}

/// Any set-up parameter may be per session: a hand-eye camera's board moved between two
/// sessions (by 20 mm and 3 deg). With `target.*` per session, exact views are fitted exactly,
/// each session's board found, and the held-out views of each session vanish; with one board
/// they do not.
#[test]
fn a_camera_target_moved_between_sessions_is_one_placement_per_session() {
    use crate::camera::{flange, truth, views};
    use robocal::calibration::kinds::CameraSite;
    let mut rng = ChaCha8Rng::seed_from_u64(8);
    let model = puma();
    let chain = flange(&model);
    let joints: Vec<String> =
        chain.params().iter().filter(|p| p.name.starts_with('j')).map(|p| p.name.clone()).collect();
    let real = chain.with_errors(&errors_on(&chain, &joints, &mut rng));
    let first = truth(CameraSite::Hand);
    let mut moved = first.clone();
    moved[6] += 20.0;
    moved[11] += 3f64.to_radians();
    let session = |s: &[f64], n: usize, name: &str, rng: &mut ChaCha8Rng| {
        views(&real, CameraSite::Hand, s, n, (0.0, 0.0), rng).named(name)
    };
    let training = session(&first, 40, "before", &mut rng).join(&session(&moved, 40, "after", &mut rng));
    let camera = KindOptions { tool: Vector3::zeros(), ..options(Estimator::Ols) };
    let per_session = KindOptions { per_session: vec!["target.*".into()], ..camera.clone() };
    let c = calibrate_kinds(&model, &training, &per_session).unwrap();
    assert!(c.training.lengths.1 < 1e-6, "training RMS {} mm", c.training.lengths.1);
    let names = c.setup.names();
    let at = |n: &str| c.setup_values.1[names.iter().position(|m| m == n).unwrap()];
    let shift = at("target.x@after") - at("target.x@before");
    assert!((shift - 20.0).abs() < 1e-4, "the board moved by {shift} mm in x");
    for (s, name) in [(&first, "before"), (&moved, "after")] {
        let held_out = c.score(&session(s, 20, name, &mut rng)).unwrap();
        assert!(held_out.lengths.1 < 1e-5, "{name}: held out {} mm", held_out.lengths.1);
    }
    let one_board = calibrate_kinds(&model, &training, &camera).unwrap();
    assert!(
        one_board.training.lengths.1 > 1.0,
        "one board: training RMS {} mm",
        one_board.training.lengths.1
    );
}

/// Where the tracker stood in the second session, in the first session's measuring frame:
/// moved by 41 mm and turned by 1.5 deg.
fn moved_tracker() -> nalgebra::Isometry3<f64> {
    robocal::model::Placement { xyz: Vector3::new(30.0, -25.0, 12.0), rpy: Vector3::new(0.01, -0.02, 0.015) }
        .isometry()
}

/// One robot with errors on its joints, seen by the tracker of the first session and of the
/// second ([`moved_tracker`]): the chains of its markers and tool point in each tracker's frame.
fn tracker_robot(rng: &mut ChaCha8Rng) -> [Vec<robocal::kinematics::ChainAt>; 2] {
    use crate::kinds_markers::{chains, device, true_chains_seen};
    let chain = &chains()[0];
    let joints: Vec<String> =
        chain.params().iter().filter(|p| p.name.starts_with('j')).map(|p| p.name.clone()).collect();
    let x = errors_on(chain, &joints, rng);
    let tuesday =
        robocal::model::Placement::from_isometry(&(moved_tracker().inverse() * device().isometry()));
    [true_chains_seen(&x, TOOL, device()), true_chains_seen(&x, TOOL, tuesday)]
}

/// Marker sessions `monday` and `tuesday` of one robot with errors on its joints, the tracker
/// moved between them ([`moved_tracker`]): training files of `poses` poses each, and held-out
/// files of the same names.
fn tracker_sessions(seed: u64, poses: usize) -> (KindData, Vec<KindData>) {
    use crate::kinds_markers::markers;
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let real = tracker_robot(&mut rng);
    let names = ["monday", "tuesday"];
    let mut session = |s: usize, n: usize| markers(&real[s], n, &mut rng, 0.01).named(names[s]);
    let training = session(0, poses).join(&session(1, poses));
    let held_out = vec![session(0, 20), session(1, 20)];
    (training, held_out)
}

/// A tracker moved between two marker sessions, `--per-session 'tracker.*'`: its placement in
/// the first session's frame recovered within 3 standard errors, and each held-out file, scored
/// with its session's tracker, at the markers' noise; one frame for both sessions leaves
/// held-out errors many times larger.
#[test]
fn a_tracker_moved_between_marker_sessions_is_modelled_by_a_per_session_placement() {
    let (training, held_out) = tracker_sessions(21, 40);
    let options = KindOptions {
        per_session: vec!["tracker.*".into()],
        ..crate::kinds_markers::marker_options(Estimator::Wls)
    };
    let c = calibrate_kinds(&puma(), &training, &options).unwrap();
    let est = &c.refined.estimate;
    let se = est.standard_errors();
    let truth = moved_tracker();
    let truth: Vec<f64> =
        truth.translation.vector.iter().chain(truth.rotation.scaled_axis().iter()).copied().collect();
    for (k, axis) in ["x", "y", "z", "rx", "ry", "rz"].iter().enumerate() {
        let name = format!("tracker.{axis}@tuesday");
        let i =
            est.names.iter().position(|n| *n == name).unwrap_or_else(|| panic!("{name} in {:?}", est.names));
        assert!(
            (est.x[i] - truth[k]).abs() < 3.0 * se[i],
            "{name}: {} against {}, SE {}",
            est.x[i],
            truth[k],
            se[i]
        );
    }
    assert!(
        !est.names.iter().any(|n| n.contains("@monday")),
        "the first session's tracker is the frame: {:?}",
        est.names
    );
    let after = |c: &KindCalibration| -> Vec<f64> {
        held_out.iter().map(|f| c.score(f).unwrap().markers.unwrap().1).collect()
    };
    let with = after(&c);
    assert!(with.iter().all(|&rms| rms < 0.05), "held out per session: {with:?} mm");
    // Tuesday's held-out file under another name: its tracker fitted on it alone, the robot held.
    let renamed = c.score(&held_out[1].clone().named("thursday")).unwrap();
    assert_eq!(renamed.sessions, vec![("thursday".to_string(), SessionSetUp::Fitted)]);
    assert!(renamed.markers.unwrap().1 < 0.05, "fitted tracker: {:?}", renamed.markers);
    let shared =
        calibrate_kinds(&puma(), &training, &crate::kinds_markers::marker_options(Estimator::Wls)).unwrap();
    for (w, without) in with.iter().zip(after(&shared)) {
        assert!(without > 10.0 * w, "held out: {without} mm in one frame, {w} mm per session");
    }
}

/// `robocal calibrate --per-session 'tracker.*'` on two marker files of a tracker moved between
/// them: the second session's placement reported, each held-out file scored with its session's
/// tracker at the markers' noise; `tracker.*` without markers in several files refused, naming
/// the pattern.
#[test]
fn the_command_models_a_tracker_moved_between_marker_files() {
    use crate::kinds_markers::marker_csv;
    let (dir, train_dir, test_dir) = session_folders("tracker-sessions");
    let mut rng = ChaCha8Rng::seed_from_u64(23);
    let real = tracker_robot(&mut rng);
    let path = |p: std::path::PathBuf| p.to_str().unwrap().to_string();
    let mut args: Vec<String> = ["calibrate", "--model", "puma560", "--marker", "60,0,90"]
        .into_iter()
        .chain(["--marker=-30,50,90", "--marker=-30,-50,90"])
        .map(String::from)
        .collect();
    for (s, name) in ["monday", "tuesday"].iter().enumerate() {
        let file = train_dir.join(format!("{name}.csv"));
        std::fs::write(&file, marker_csv(&real[s], 40, &mut rng)).unwrap();
        args.extend(["--data".into(), path(file)]);
        let held_out = test_dir.join(format!("{name}.csv"));
        std::fs::write(&held_out, marker_csv(&real[s], 20, &mut rng)).unwrap();
        args.extend(["--validate".into(), path(held_out)]);
    }
    let run = |extra: &[&str]| {
        let output =
            assert_cmd::Command::cargo_bin("robocal").unwrap().args(&args).args(extra).output().unwrap();
        let text = String::from_utf8(output.stdout).unwrap();
        (output.status.code(), text, String::from_utf8(output.stderr).unwrap())
    };
    let (code, text, stderr) = run(&["--per-session", "tracker.*"]);
    assert_eq!(code, Some(0), "{text}{stderr}");
    for axis in ["x", "y", "z", "rx", "ry", "rz"] {
        assert!(text.contains(&format!("tracker.{axis}@tuesday ")), "{text}");
    }
    let after = |text: &str, file: &str| -> f64 {
        let row = (text.lines())
            .find(|l| l.contains(file) && l.contains("markers (mm)"))
            .unwrap_or_else(|| panic!("{file}:\n{text}"));
        crate::verdict_rms(row).1
    };
    let shared = run(&[]).1;
    for file in ["test/monday.csv", "test/tuesday.csv"] {
        let (with, without) = (after(&text, file), after(&shared, file));
        assert!(with < 0.05, "{file}: {with} mm\n{text}");
        assert!(without > 10.0 * with, "{file}: {without} mm in one frame, {with} mm per session");
    }
    let balls = assert_cmd::Command::cargo_bin("robocal")
        .unwrap()
        .args(["calibrate", "--model", "puma560", "--tool", "50,0,150"])
        .args(["--joint-sigma-deg", "0.007,0.007,0.007,0.002,0.002,0.002"])
        .args(["--data", "examples/puma560-ballbar.csv", "--data", "examples/puma560-ballbar-2.csv"])
        .args(["--per-session", "tracker.*"])
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&balls.stderr);
    assert!(!balls.status.success() && stderr.contains("`tracker.*`: a tracker's placement"), "{stderr}");
    std::fs::remove_dir_all(&dir).unwrap();
}

/// A scratch folder named after `name` and this process, with `train` and `test` in it.
fn session_folders(name: &str) -> (std::path::PathBuf, std::path::PathBuf, std::path::PathBuf) {
    let dir = std::env::temp_dir().join(format!("robocal-{name}-{}", std::process::id()));
    let (train, test) = (dir.join("train"), dir.join("test"));
    std::fs::create_dir_all(&train).unwrap();
    std::fs::create_dir_all(&test).unwrap();
    (dir, train, test)
}
