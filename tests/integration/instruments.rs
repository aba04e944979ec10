//! Instruments compared at equal measurement time: the embedded study at a reduced size, its
//! determinism over thread counts, exact recovery without noise, and errors naming the field.

use robocal::model::{ModelRef, RobotModel};
use robocal::report;
use robocal::simulation::{INSTRUMENT_STUDIES, InstrumentKind, InstrumentStudy, StudyError, run_instruments};

fn load(reference: &ModelRef) -> Result<RobotModel, String> {
    RobotModel::preset(&reference.name).ok_or_else(|| format!("no preset {}", reference.name))
}

/// The embedded `instruments` study's text.
fn embedded() -> &'static str {
    INSTRUMENT_STUDIES.iter().find(|(n, _)| *n == "instruments").unwrap().1
}

/// The embedded study with `runs`, `test_points` and `time_budget_s` replaced.
fn reduced(runs: usize, test_points: usize, budget: f64) -> InstrumentStudy {
    let mut study = InstrumentStudy::from_toml_str(embedded(), load).unwrap();
    (study.runs, study.test_points, study.time_budget) = (runs, test_points, budget);
    study
}

fn on_threads(threads: usize, study: &InstrumentStudy) -> String {
    let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
    let results = pool.install(|| run_instruments(study, &|| {})).unwrap();
    report::instruments::table(study, &results)
}

#[test]
fn the_instrument_study_runs_at_a_reduced_size_and_calibration_beats_the_nominal_robot() {
    let study = reduced(3, 100, 400.0);
    let results = run_instruments(&study, &|| {}).unwrap();
    let table = report::instruments::table(&study, &results);
    println!("{table}");
    assert_eq!(results.scores.len(), 3);
    for (i, instrument) in study.instruments.iter().enumerate() {
        assert!(table.contains(&instrument.name), "{table}");
        let nominal = results.nominal.iter().map(|s| s.aligned).sum::<f64>() / 3.0;
        let (mean, _) = results.mean_error(i);
        assert!(
            mean < 0.5 * nominal,
            "{}: E_p {mean} mm against {nominal} nominal\n{table}",
            instrument.name
        );
    }
    assert_eq!(study.observations(0), 80, "400 s at 5 s per tracker pose");
    assert_eq!(study.observations(1), 133, "400 s at 3 s per ball-bar length");
}

#[test]
fn the_same_seed_gives_the_same_table_on_one_and_two_threads() {
    let study = reduced(2, 50, 300.0);
    assert_eq!(on_threads(1, &study), on_threads(2, &study));
}

/// Without noise on the joints and the instrument (a camera: position and angle).
fn exact(study: &mut InstrumentStudy) {
    study.joint_sigmas.iter_mut().for_each(|s| *s = 0.0);
    for instrument in &mut study.instruments {
        instrument.sigma = 0.0;
        if let InstrumentKind::Camera { sigma_angle, .. } = &mut instrument.kind {
            *sigma_angle = 0.0;
        }
    }
}

/// Without noise the tracker, the ball bar, the artefact and the camera recover the real robot up to a
/// rigid motion. A height gauge cannot: heights do not depend on joint 1 and do not see the
/// geometry the first joint turns about its vertical axis, which is held at nominal (its
/// error stays well above zero, and says so).
#[test]
fn exact_instruments_recover_the_robot() {
    let mut study = reduced(2, 100, 600.0);
    exact(&mut study);
    let results = run_instruments(&study, &|| {}).unwrap();
    for (i, instrument) in study.instruments.iter().enumerate() {
        for run in &results.scores {
            match instrument.name.as_str() {
                "height gauge" => assert!(run[i].aligned > 0.01, "a height gauge: E_p {}", run[i].aligned),
                name => assert!(run[i].aligned < 1e-6, "{name}: E_p {} mm without noise", run[i].aligned),
            }
        }
    }
}

/// A wrist camera alone, exact, mounted turned about every axis and looking at a tilted
/// board: its calibrated camera frame carries the tool point onto the real robot's (the last
/// link's errors the camera cannot tell from its mounting are absorbed by the mounting).
#[test]
fn an_exact_wrist_camera_recovers_the_robot() {
    let text = embedded()
        .replace("camera_rpy_deg = [0.0, 0.0, 0.0]", "camera_rpy_deg = [10.0, -20.0, 30.0]")
        .replace("target_rpy_deg = [0.0, 0.0, 0.0]", "target_rpy_deg = [170.0, 15.0, -40.0]")
        .lines()
        .filter(|l| !["field_of_view_deg", "range_mm", "max_incidence_deg"].iter().any(|f| l.starts_with(f)))
        .map(|l| format!("{l}\n"))
        .collect::<String>();
    let mut study = InstrumentStudy::from_toml_str(&text, load).unwrap();
    (study.runs, study.test_points, study.time_budget) = (2, 100, 200.0);
    study.instruments.retain(|i| i.kind.name() == "camera");
    assert_eq!(study.observations(0), 100, "200 s at 2 s per view");
    exact(&mut study);
    let results = run_instruments(&study, &|| {}).unwrap();
    for run in &results.scores {
        assert!(run[0].aligned < 1e-6, "a wrist camera: E_p {} mm without noise", run[0].aligned);
    }
    assert!(results.nominal.iter().all(|s| s.aligned > 0.5), "{:?}", results.nominal);
}

/// The error of the embedded study with `from` replaced by `to`, as one line.
fn error_of(from: &str, to: &str) -> String {
    let text = embedded().replacen(from, to, 1);
    assert_ne!(text, embedded(), "{from} is in the study");
    let error: StudyError = InstrumentStudy::from_toml_str(&text, load).unwrap_err();
    let mut message = error.to_string();
    let mut source = std::error::Error::source(&error);
    while let Some(s) = source {
        message += &format!(": {s}");
        source = s.source();
    }
    message
}

#[test]
fn errors_in_the_study_file_name_the_field() {
    for (from, to, field) in [
        ("sigma_mm = 0.005", "sigma_mm = -1.0", "instruments[1].sigma_mm"),
        ("kind = \"height\"", "kind = \"laser\"", "instruments[3].kind"),
        ("pivot_mm = [400.0, 200.0, 300.0]", "", "instruments[1].pivot_mm"),
        (
            "seconds_per_observation = 5",
            "seconds_per_observation = 0",
            "instruments[0].seconds_per_observation",
        ),
        (
            "seconds_per_observation = 5",
            "seconds_per_observation = 900",
            "instruments[0].seconds_per_observation",
        ),
        ("time_budget_s = 600", "time_budget_s = -1", "time_budget_s"),
        ("runs = 200", "runs = 1", "runs"),
        ("runs = 200\ntest_points = 1000", "runs = 100000\ntest_points = 100000", "runs"),
        (
            "joint_sigma = [0.007, 0.007, 0.007, 0.002, 0.002, 0.002]",
            "joint_sigma = [0.007]",
            "noise.joint_sigma",
        ),
        ("name = \"height gauge\"", "name = \"ball bar\"", "instruments[3].name"),
        ("kind = \"artefact\"", "kind = \"artefact\"\npivot_mm = [1.0, 2.0, 3.0]", "instruments[2].pivot_mm"),
        ("kind = \"artefact\"", "kind = \"plane\"", "instruments[2].planes"),
        (
            "kind = \"artefact\"",
            "kind = \"plane\"\nplanes = [{ normal = [0.0, 0.0, 0.0], offset_mm = 1.0 }]",
            "instruments[2].planes[0].normal",
        ),
        ("kind = \"height\"", "kind = \"height\"\nplanes = []", "instruments[3].planes"),
        ("sigma_deg = 0.05", "", "instruments[4].sigma_deg"),
        ("sigma_deg = 0.05", "sigma_deg = -0.05", "instruments[4].sigma_deg"),
        ("sigma_deg = 0.05", "sigma_deg = nan", "instruments[4].sigma_deg"),
        ("camera_xyz_mm = [0.0, -60.0, 100.0]", "", "instruments[4].camera_xyz_mm"),
        ("camera_rpy_deg = [0.0, 0.0, 0.0]", "", "instruments[4].camera_rpy_deg"),
        ("target_xyz_mm = [600.0, 0.0, -400.0]", "", "instruments[4].target_xyz_mm"),
        (
            "target_xyz_mm = [600.0, 0.0, -400.0]",
            "target_xyz_mm = [1e12, 0.0, 0.0]",
            "instruments[4].target_xyz_mm",
        ),
        (
            "target_rpy_deg = [0.0, 0.0, 0.0]",
            "target_rpy_deg = [inf, 0.0, 0.0]",
            "instruments[4].target_rpy_deg",
        ),
        ("kind = \"artefact\"", "kind = \"artefact\"\nsigma_deg = 0.1", "instruments[2].sigma_deg"),
        ("range_mm = [300.0, 1200.0]", "", "instruments[4].field_of_view_deg"),
        ("field_of_view_deg = 40.0", "field_of_view_deg = 180.0", "instruments[4].field_of_view_deg"),
        ("range_mm = [300.0, 1200.0]", "range_mm = [1200.0, 300.0]", "instruments[4].range_mm"),
        ("max_incidence_deg = 45.0", "max_incidence_deg = 0.0", "instruments[4].max_incidence_deg"),
        ("kind = \"height\"", "kind = \"height\"\nrange_mm = [1.0, 2.0]", "instruments[3].range_mm"),
        (
            "kind = \"height\"",
            "kind = \"height\"\ntarget_rpy_deg = [0.0, 0.0, 0.0]",
            "instruments[3].target_rpy_deg",
        ),
    ] {
        let message = error_of(from, to);
        assert!(message.contains(&format!("`{field}`")), "{from} -> {to}: {message}");
    }
    let message = error_of("time_budget_s = 600", "time_budget = 600");
    assert!(message.contains("time_budget"), "{message}");
}

/// Contacts alone (three planes, exact) no longer collapse the robot (every length zero, the
/// tool point where the planes meet, which fits every contact): the robot's longest length is
/// held, and sets the scale. They still cannot see the scale itself, so with exact contacts the
/// error is that of the held length's own error (0.5 mm on 431.8 mm here), not zero: why the
/// embedded study leaves the plane probe out.
#[test]
fn plane_contacts_alone_see_the_robot_but_not_its_scale() {
    let text = embedded().to_string()
        + r#"
[[instruments]]
name = "plane probe"
kind = "plane"
sigma_mm = 0.0
seconds_per_observation = 4
planes = [
    { normal = [0.0, 0.0, 1.0], offset_mm = -300.0 },
    { normal = [1.0, 0.0, 0.0], offset_mm = 500.0 },
    { normal = [0.0, 1.0, 0.0], offset_mm = 400.0 },
]
"#;
    let mut study = InstrumentStudy::from_toml_str(&text, load).unwrap();
    (study.runs, study.test_points) = (2, 100);
    study.instruments.drain(..5);
    study.joint_sigmas.iter_mut().for_each(|s| *s = 0.0);
    let results = run_instruments(&study, &|| {}).unwrap();
    assert!(results.scores.iter().all(|r| r[0].aligned < 2.0), "collapsed: {:?}", results.scores);
    assert!(results.scores.iter().all(|r| r[0].aligned > 0.01), "the scale seen: {:?}", results.scores);
}

/// `robocal simulate FILE` with `args`: its exit code, standard output and error.
fn simulate(file_text: &str, tag: &str, args: &[&str]) -> (Option<i32>, String, String, std::path::PathBuf) {
    let dir = std::env::temp_dir().join(format!("robocal-instruments-{tag}-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("study.toml");
    std::fs::write(&path, file_text).unwrap();
    let out = dir.join("out");
    let output = std::process::Command::new(env!("CARGO_BIN_EXE_robocal"))
        .args(["simulate", path.to_str().unwrap(), "--out", out.to_str().unwrap()])
        .args(args)
        .output()
        .unwrap();
    let text = |b: Vec<u8>| String::from_utf8(b).unwrap();
    (output.status.code(), text(output.stdout), text(output.stderr), dir)
}

#[test]
fn simulate_runs_an_instrument_study_file_and_writes_its_table_and_samples() {
    let text = embedded().replace("runs = 200", "runs = 2").replace("test_points = 1000", "test_points = 50");
    let (code, stdout, stderr, dir) = simulate(&text, "run", &["--threads", "1"]);
    assert_eq!(code, Some(0), "{stderr}");
    let tables = std::fs::read_to_string(dir.join("out/instruments/tables.txt")).unwrap();
    assert!(stdout.contains(&tables) && tables.contains("laser tracker"), "{stdout}");
    let csv = std::fs::read_to_string(dir.join("out/instruments/samples.csv")).unwrap();
    assert_eq!(csv.lines().count(), 1 + 2 * 5, "{csv}");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn simulate_names_the_file_and_field_of_a_bad_instrument_study_and_refuses_estimator_flags() {
    let text = embedded().replace("sigma_mm = 0.02", "sigma_mm = -0.02");
    let (code, _, stderr, dir) = simulate(&text, "bad", &[]);
    assert_eq!(code, Some(1));
    assert!(stderr.contains("study.toml") && stderr.contains("instruments[0].sigma_mm"), "{stderr}");
    std::fs::remove_dir_all(&dir).unwrap();
    let (code, _, stderr, dir) = simulate(embedded(), "flags", &["--replications", "2"]);
    assert_eq!(code, Some(2), "{stderr}");
    assert!(stderr.contains("--replications"), "{stderr}");
    std::fs::remove_dir_all(&dir).unwrap();
}

/// The README's table is what `robocal simulate instruments` prints.
#[test]
fn the_readme_instrument_table_is_the_real_output() {
    let readme = std::fs::read_to_string("README.md").unwrap();
    let start = readme.find("$ robocal simulate instruments\n").expect("the README's study");
    let block = &readme[start..start + readme[start..].find("```").unwrap()];
    let expected: String = block.lines().skip(1).map(|line| format!("{line}\n")).collect();
    let (code, stdout, stderr, dir) = simulate(embedded(), "readme", &["--threads", "2"]);
    assert_eq!(code, Some(0), "{stderr}");
    let table = stdout.split("\n\nwrote").next().unwrap();
    assert_eq!(table.trim_end(), expected.trim_end(), "regenerate the README's instrument table");
    std::fs::remove_dir_all(&dir).unwrap();
}

/// A camera sees a target in front of it, within its cone and range, facing it.
#[test]
fn a_camera_sees_only_a_target_in_its_cone_range_and_facing_it() {
    use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
    use robocal::simulation::Sight;
    let sight =
        Sight { half_angle: 20f64.to_radians(), range: [300.0, 1200.0], incidence: 45f64.to_radians() };
    // The board 800 mm along the optical axis, facing the camera (its normal back at it).
    let facing = UnitQuaternion::from_euler_angles(std::f64::consts::PI, 0.0, 0.0);
    let at = |p: Vector3<f64>, r: UnitQuaternion<f64>| Isometry3::from_parts(Translation3::from(p), r);
    assert!(sight.sees(&at(Vector3::new(0.0, 0.0, 800.0), facing)));
    // 15 deg off the axis: seen; 25 deg: not.
    let off = |deg: f64| Vector3::new(800.0 * deg.to_radians().tan(), 0.0, 800.0);
    assert!(sight.sees(&at(off(15.0), facing)));
    assert!(!sight.sees(&at(off(25.0), facing)));
    // Too near, too far, behind the camera.
    for z in [200.0, 1500.0, -800.0] {
        assert!(!sight.sees(&at(Vector3::new(0.0, 0.0, z), facing)), "{z}");
    }
    // The board turned 40 deg off facing the camera: seen; 50 deg or its back: not.
    for (deg, seen) in [(40.0f64, true), (50.0, false), (180.0, false)] {
        let turned = facing * UnitQuaternion::from_euler_angles(deg.to_radians(), 0.0, 0.0);
        assert_eq!(sight.sees(&at(Vector3::new(0.0, 0.0, 800.0), turned)), seen, "{deg} deg");
    }
}

/// The preset's camera sees the board from some poses only, and is worse for it than the same
/// camera drawn over every pose; a board it never sees is refused by name.
#[test]
fn a_camera_that_must_see_its_board_calibrates_worse() {
    let camera_only = |text: &str| {
        let mut study = InstrumentStudy::from_toml_str(text, load).unwrap();
        (study.runs, study.test_points) = (8, 200);
        study.instruments.retain(|i| i.kind.name() == "camera");
        study
    };
    let blind: String = embedded()
        .lines()
        .filter(|l| !["field_of_view_deg", "range_mm", "max_incidence_deg"].iter().any(|f| l.starts_with(f)))
        .map(|l| format!("{l}\n"))
        .collect();
    let mean = |study: &InstrumentStudy| {
        let results = run_instruments(study, &|| {}).unwrap();
        results.scores.iter().map(|r| r[0].aligned).sum::<f64>() / results.scores.len() as f64
    };
    let (seeing, everywhere) = (mean(&camera_only(embedded())), mean(&camera_only(&blind)));
    assert!(seeing > 1.3 * everywhere, "in sight only: {seeing} mm; everywhere: {everywhere} mm");
    let unseen = embedded().replace("range_mm = [300.0, 1200.0]", "range_mm = [5000.0, 6000.0]");
    let error = run_instruments(&camera_only(&unseen), &|| {}).unwrap_err().to_string();
    assert!(error.contains("field_of_view_deg") && error.contains("none of"), "{error}");
}
