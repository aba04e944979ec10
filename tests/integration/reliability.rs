//! Issue 13, case by case: bad input gets one clear error naming the file, line and field;
//! nothing already on disk is lost; nothing half-written is left; sizes and magnitudes are
//! bounded before anything is allocated; what would be silent nonsense is refused or warned.
//! Each test asserts the message and the state of the disk after the error.

use assert_cmd::Command;
use std::path::{Path, PathBuf};

const MEASUREMENTS: &str = include_str!("../../examples/puma560-measurements.csv");
const MODEL: &str = include_str!("../../presets/puma560.toml");
const TABLE1: &str = include_str!("../../presets/paper-table1.toml");

/// A fresh, empty folder for one test.
fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("robocal-reliability-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// `text` written to `dir/name`; its path.
fn file(dir: &Path, name: &str, text: &str) -> PathBuf {
    let path = dir.join(name);
    std::fs::write(&path, text).unwrap();
    path
}

/// `robocal args` in `dir`: (exit code, stdout, stderr).
fn run_in(dir: &Path, args: &[&str]) -> (i32, String, String) {
    let output = Command::cargo_bin("robocal").unwrap().current_dir(dir).args(args).output().unwrap();
    let text = |b: Vec<u8>| String::from_utf8(b).unwrap();
    (output.status.code().unwrap_or(-1), text(output.stdout), text(output.stderr))
}

/// The names in `dir`, sorted.
fn listing(dir: &Path) -> Vec<String> {
    let mut names: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    names
}

/// The paper's first study, small: one case of 12 points, 2 x 2 runs, 20 test points; `edit`
/// replaces text in it.
fn small_study(edits: &[(&str, &str)]) -> String {
    let mut text = TABLE1[..TABLE1.find("[[reference]]").unwrap()]
        .replace("points = [12, 24, 48, 96, 192]", "points = [12]")
        .replace("point_sets = 6", "point_sets = 2")
        .replace("runs_per_set = 16", "runs_per_set = 2")
        .replace("test_points = 1000", "test_points = 20")
        .replace("name = \"paper-table1\"", "name = \"small\"");
    for (from, to) in edits {
        assert!(text.contains(from), "{from}");
        text = text.replace(from, to);
    }
    text
}

const CALIBRATE: [&str; 6] = ["calibrate", "--model", "puma560", "--data", "d.csv", "--marker=50,0,150"];

// 1. Nothing lost, nothing half-written.

#[test]
fn an_output_that_is_the_input_is_refused_before_any_work() {
    let dir = scratch("out-is-in");
    file(&dir, "d.csv", MEASUREMENTS);
    for (flag, path) in
        [("--out-model", "d.csv"), ("--json", "./d.csv"), ("--out-model", "../out-is-in/d.csv")]
    {
        let path = if path.starts_with("..") {
            format!("../{}/d.csv", dir.file_name().unwrap().to_string_lossy())
        } else {
            path.to_string()
        };
        let (code, stdout, stderr) = run_in(&dir, &[&CALIBRATE[..], &[flag, &path]].concat());
        assert_eq!(code, 2, "{stderr}");
        assert!(stdout.is_empty(), "no work done: {stdout}");
        assert!(
            stderr.contains(&format!(
                "{flag} {path}: that is the input file of --data, which writing would overwrite"
            )),
            "{stderr}"
        );
        assert_eq!(std::fs::read_to_string(dir.join("d.csv")).unwrap(), MEASUREMENTS, "input intact");
        assert_eq!(listing(&dir), ["d.csv"]);
    }
}

#[test]
fn two_outputs_with_one_path_are_refused() {
    let dir = scratch("out-twice");
    file(&dir, "d.csv", MEASUREMENTS);
    let (code, _, stderr) =
        run_in(&dir, &[&CALIBRATE[..], &["--json", "r.json", "--out-model", "r.json"]].concat());
    assert_eq!(code, 2);
    assert!(
        stderr.contains("--json and --out-model both name r.json: give each output its own path"),
        "{stderr}"
    );
    assert_eq!(listing(&dir), ["d.csv"]);
}

#[test]
fn repeatability_plan_and_simulate_refuse_an_output_that_is_an_input() {
    let dir = scratch("out-is-in-2");
    file(&dir, "r.csv", include_str!("../../examples/puma560-repeatability.csv"));
    file(&dir, "m.toml", MODEL);
    file(&dir, "s.toml", &small_study(&[]));
    let cases: [&[&str]; 3] = [
        &["repeatability", "--model", "puma560", "--data", "r.csv", "--out", "r.csv"],
        &["plan", "--model", "m.toml", "--points", "12", "--out", "m.toml"],
        &["simulate", "s.toml", "--out", "s.toml"],
    ];
    for args in cases {
        let (code, _, stderr) = run_in(&dir, args);
        assert_eq!(code, 2, "{args:?}: {stderr}");
        assert!(stderr.contains("that is the input file of"), "{stderr}");
    }
    assert_eq!(listing(&dir), ["m.toml", "r.csv", "s.toml"]);
    assert_eq!(std::fs::read_to_string(dir.join("m.toml")).unwrap(), MODEL);
}

#[test]
fn when_one_output_fails_none_is_written_and_old_files_are_kept() {
    let dir = scratch("all-or-none");
    file(&dir, "d.csv", MEASUREMENTS);
    file(&dir, "old.json", "the previous report\n");
    let args = ["--json", "old.json", "--out-model", "missing/model.toml"];
    let (code, stdout, stderr) = run_in(&dir, &[&CALIBRATE[..], &args].concat());
    assert_eq!(code, 1);
    assert!(stdout.contains("parameters identified"), "the work was done");
    assert_eq!(stderr.matches("missing/model.toml: cannot write").count(), 1, "{stderr}");
    assert_eq!(std::fs::read_to_string(dir.join("old.json")).unwrap(), "the previous report\n");
    assert_eq!(listing(&dir), ["d.csv", "old.json"], "no temporary file left");
}

#[test]
fn outputs_are_committed_together_or_not_at_all() {
    let dir = scratch("outputs");
    file(&dir, "kept.txt", "old\n");
    let mut outputs = robocal::io::Outputs::new();
    outputs.add(dir.join("kept.txt"), "new\n");
    outputs.add_folder(
        &dir.join("study/sub"),
        &[("a.csv".into(), "1\n".into()), ("b.svg".into(), "<svg/>".into())],
    );
    outputs.add(dir.join("no-such-folder/c.txt"), "c\n");
    let error = outputs.commit().unwrap_err();
    assert!(error.to_string().ends_with("no-such-folder/c.txt: cannot write"), "{error}");
    assert_eq!(listing(&dir), ["kept.txt"], "the folders created are removed");
    assert_eq!(std::fs::read_to_string(dir.join("kept.txt")).unwrap(), "old\n");

    let mut outputs = robocal::io::Outputs::new();
    outputs.add(dir.join("kept.txt"), "new\n");
    outputs.add_folder(&dir.join("study/sub"), &[("a.csv".into(), "1\n".into())]);
    assert_eq!(outputs.len(), 2);
    outputs.commit().unwrap();
    assert_eq!(std::fs::read_to_string(dir.join("kept.txt")).unwrap(), "new\n");
    assert_eq!(listing(&dir.join("study/sub")), ["a.csv"]);
}

#[test]
fn reproduce_leaves_no_first_study_when_the_second_cannot_be_written() {
    let dir = scratch("reproduce");
    std::fs::create_dir(dir.join("out")).unwrap();
    file(&dir.join("out"), "paper-table2", "a file where the second study's folder would go\n");
    let (code, _, stderr) = run_in(&dir, &["reproduce", "--out", "out"]);
    assert_eq!(code, 1);
    assert_eq!(stderr.matches("cannot write").count(), 1, "{stderr}");
    assert!(stderr.contains("paper-table2"), "{stderr}");
    assert_eq!(listing(&dir.join("out")), ["paper-table2"], "no paper-table1 folder, no temporary file");
}

// 2. Bounded sizes before allocation.

#[test]
fn study_sizes_are_bounded_and_named() {
    let dir = scratch("study-sizes");
    let cases = [
        (
            "test_points = 20",
            "test_points = 1000000000000",
            "field `test_points`: at most 1000000, found 1000000000000",
        ),
        (
            "points = [12]",
            "points = [2000000]",
            "field `cases.points`: point counts from 1 to 1000000, found 2000000",
        ),
        (
            "runs_per_set = 2",
            "runs_per_set = 5000000",
            "field `runs_per_set`: at most 1000000, found 5000000",
        ),
        (
            "runs_per_set = 2\ntest_points = 20",
            "runs_per_set = 100000\ntest_points = 1000000",
            "field `runs_per_set`: a study of at most 1e10 kinematic evaluations (runs x (points + test_points)), \
             found 2.000024e11",
        ),
        ("iterations = 1", "iterations = 1000000", "field `iterations`: at most 1000, found 1000000"),
    ];
    for (from, to, message) in cases {
        let path = file(&dir, "s.toml", &small_study(&[(from, to)]));
        let (code, _, stderr) = run_in(&dir, &["simulate", path.to_str().unwrap(), "--out", "out"]);
        assert_eq!(code, 1, "{stderr}");
        assert!(stderr.contains(&format!("s.toml: {message}")), "{stderr}");
        assert_eq!(listing(&dir), ["s.toml"]);
    }
}

#[test]
fn a_study_too_large_for_the_memory_is_refused_before_it_runs() {
    let dir = scratch("study-memory");
    let edits = [("points = [12]", "points = [1000000]"), ("point_sets = 2", "point_sets = 1000")];
    let path = file(&dir, "s.toml", &small_study(&edits));
    let (code, stdout, stderr) = run_in(&dir, &["simulate", path.to_str().unwrap(), "--out", "out"]);
    assert_eq!(code, 1, "{stderr}");
    assert!(stdout.is_empty());
    assert!(stderr.contains("error: study small would need about"), "{stderr}");
    assert!(stderr.contains("ask for fewer test_points, points, point sets or runs"), "{stderr}");
    assert_eq!(listing(&dir), ["s.toml"]);
}

#[test]
fn threads_are_capped_at_the_cores_with_a_note() {
    let dir = scratch("threads");
    let path = file(&dir, "s.toml", &small_study(&[]));
    let (code, _, stderr) =
        run_in(&dir, &["simulate", path.to_str().unwrap(), "--out", "out", "--threads", "100000"]);
    assert_eq!(code, 0, "{stderr}");
    assert!(stderr.contains("note: --threads 100000: this machine has"), "{stderr}");
    assert_eq!(
        listing(&dir.join("out/small")).len(),
        4,
        "tables, samples, one histogram per weighted estimator"
    );
}

#[test]
fn plan_sizes_are_bounded() {
    let dir = scratch("plan-sizes");
    let (code, _, stderr) =
        run_in(&dir, &["plan", "--model", "puma560", "--points", "12", "--candidates", "99999999999"]);
    assert_eq!(code, 2);
    assert!(stderr.contains("--candidates 99999999999: at most 1000000"), "{stderr}");
    assert!(listing(&dir).is_empty());
}

#[test]
fn a_model_with_too_many_joints_is_refused() {
    let dir = scratch("joints");
    let joint = &MODEL[MODEL.find("[[joints]]").unwrap()..]
        [..MODEL[MODEL.find("[[joints]]").unwrap() + 1..].find("[[joints]]").unwrap() + 1];
    let mut text = MODEL.to_string();
    for i in 0..70 {
        text += &joint.replace("name = \"j1\"", &format!("name = \"x{i}\""));
    }
    let path = file(&dir, "m.toml", &text);
    let (code, _, stderr) = run_in(&dir, &["model", "show", path.to_str().unwrap()]);
    assert_eq!(code, 1);
    assert!(stderr.contains("m.toml: field `joints`: at most 64 joints, found 76"), "{stderr}");
}

/// Each command under a 2 GiB address-space limit, on inputs that ask for far more: a clean
/// error (exit 1 or 2 with a message), never an abort; observability and calibrate of the
/// same 120 000 poses fit and run.
#[cfg(target_os = "linux")]
#[test]
fn commands_asking_for_far_more_memory_fail_cleanly_under_a_2_gib_limit() {
    let dir = scratch("ulimit");
    let edits = [("points = [12]", "points = [1000000]"), ("point_sets = 2", "point_sets = 100")];
    file(&dir, "big.toml", &small_study(&edits));
    let design = "\n[design]\nposes = [\"planned\"]\ncandidates = 1000000\n";
    file(&dir, "planned.toml", &(small_study(&[]) + design));
    let lines: Vec<&str> = MEASUREMENTS.lines().collect();
    let rows = lines[2..].join("\n") + "\n";
    file(&dir, "huge.csv", &(lines[..2].join("\n") + "\n" + &rows.repeat(1200)));
    let binary = assert_cmd::cargo::cargo_bin("robocal");
    let cases = [
        ("simulate big.toml --out out", 1, "would need about"),
        ("simulate planned.toml --out out --threads 2", 1, "would need about"),
        ("plan --model puma560 --points 12 --candidates 1000000", 1, "would need about"),
        ("plan --model puma560 --points 99999999999", 2, "at most 1000000"),
        ("calibrate --model puma560 --data huge.csv", 0, ""), // within the limit: it runs
        ("observability huge.csv --model puma560", 0, ""),    // within the limit: it runs
    ];
    for (args, expected, message) in cases {
        let script = format!("ulimit -v 2097152; exec '{}' {args}", binary.display());
        let output =
            std::process::Command::new("sh").arg("-c").arg(&script).current_dir(&dir).output().unwrap();
        let stderr = String::from_utf8(output.stderr).unwrap();
        assert_eq!(output.status.code(), Some(expected), "{args}: {stderr}");
        assert!(stderr.contains(message), "{args}: {stderr}");
        assert!(!dir.join("out").exists());
    }
}

// 3. Magnitudes.

#[test]
fn implausible_magnitudes_are_refused_naming_the_field() {
    let dir = scratch("magnitudes");
    let model = file(&dir, "m.toml", &MODEL.replacen("a_mm = 431.8", "a_mm = 1e300", 1));
    let (code, _, stderr) = run_in(&dir, &["model", "show", model.to_str().unwrap()]);
    assert_eq!(code, 1);
    assert!(
        stderr.contains(
            "m.toml: field `joints[1].a_mm`: a finite number of magnitude at most 1e6 mm, found 1e300"
        ),
        "{stderr}"
    );
    let mut lines: Vec<String> = MEASUREMENTS.lines().map(String::from).collect();
    let cells: Vec<&str> = lines[4].split(',').collect();
    lines[4] = [&cells[..6], &["1e300"], &cells[7..]].concat().join(",");
    file(&dir, "d.csv", &(lines.join("\n") + "\n"));
    let (code, _, stderr) = run_in(&dir, &CALIBRATE);
    assert_eq!(code, 1);
    assert!(
        stderr
            .contains("d.csv: line 5, column `x1`: a finite number of magnitude at most 1e6 mm, found 1e300"),
        "{stderr}"
    );
    for (from, to, field) in [
        ("length_mm = 0.5", "length_mm = 1e7", "errors.length_mm"),
        ("sigma_me_mm = [0.0]", "sigma_me_mm = [1e300]", "cases.sigma_me_mm"),
        ("joint_sigma = [0.007", "joint_sigma = [1e5", "noise.joint_sigma"),
    ] {
        let path = file(&dir, "s.toml", &small_study(&[(from, to)]));
        let (code, _, stderr) = run_in(&dir, &["simulate", path.to_str().unwrap(), "--out", "out"]);
        assert_eq!(code, 1, "{stderr}");
        assert!(
            stderr.contains(&format!("s.toml: field `{field}`: a finite number of magnitude at most")),
            "{stderr}"
        );
    }
    file(&dir, "d.csv", MEASUREMENTS);
    let noise =
        file(&dir, "n.toml", "joint_sigma = [0.007, 0.007, 0.007, 0.002, 0.002, 0.002]\nsigma_me_mm = 1e9\n");
    let (code, _, stderr) = run_in(&dir, &[&CALIBRATE[..], &["--noise", noise.to_str().unwrap()]].concat());
    assert_eq!(code, 1);
    assert!(
        stderr.contains("n.toml: field `sigma_me_mm`: a finite number of magnitude at most 1e6 mm"),
        "{stderr}"
    );
    assert!(!dir.join("out").exists());
}

#[test]
fn figures_of_non_finite_statistics_are_refused_naming_the_case() {
    let study =
        robocal::simulation::Study::from_toml_str(&small_study(&[]), |model: &robocal::model::ModelRef| {
            robocal::model::RobotModel::preset(&model.name).ok_or("no such preset")
        })
        .unwrap();
    let mut results = robocal::simulation::run(&study, &|| {}).unwrap();
    results.runs[1].accuracy[1].mean = f64::NAN;
    let error = robocal::report::figures::study_figures(&study, &results).unwrap_err();
    assert_eq!(
        error.to_string(),
        "cannot draw figure `histogram-wls-np12-sigma0.svg`: 1 of its 4 values are not finite (NaN or infinite): not drawn"
    );
}

// 4. No silent acceptance.

#[test]
fn table_mistakes_are_refused_with_line_and_column() {
    let dir = scratch("tables");
    let lines: Vec<&str> = MEASUREMENTS.lines().collect();
    let longer = format!("{}\n{},7\n{}\n", lines[..3].join("\n"), lines[3], lines[4..].join("\n"));
    let duplicate = MEASUREMENTS.replacen("x2,y2,z2", "x2,y2,x1", 1);
    for (text, message) in [
        (longer, "d.csv: line 4: 13 values, the header has 12"),
        (duplicate, "d.csv: line 2, column `x1`: a column named once, `x1` is column 7 and 12"),
    ] {
        file(&dir, "d.csv", &text);
        let (code, _, stderr) = run_in(&dir, &CALIBRATE);
        assert_eq!(code, 1);
        assert!(stderr.contains(message), "{stderr}");
        assert_eq!(listing(&dir), ["d.csv"]);
    }
}

#[test]
fn a_byte_order_mark_and_cr_line_endings_are_read_correctly() {
    let dir = scratch("bom-cr");
    file(&dir, "d.csv", MEASUREMENTS);
    let (code, expected, _) = run_in(&dir, &CALIBRATE);
    assert_eq!(code, 0);
    file(&dir, "d.csv", &format!("\u{feff}{}", MEASUREMENTS.replace('\n', "\r")));
    let (code, stdout, stderr) = run_in(&dir, &CALIBRATE);
    assert_eq!(code, 0, "{stderr}");
    assert_eq!(stdout, expected);
}

#[test]
fn limits_deg_with_other_than_two_values_is_refused() {
    let dir = scratch("limits");
    for limits in ["[-160, 160, 30]", "[-160]"] {
        let model = file(
            &dir,
            "m.toml",
            &MODEL.replacen("limits_deg = [-160.0, 160.0]", &format!("limits_deg = {limits}"), 1),
        );
        let (code, _, stderr) = run_in(&dir, &["model", "show", model.to_str().unwrap()]);
        assert_eq!(code, 1, "{limits}");
        assert!(
            stderr.contains("m.toml: the model file has a mistake: TOML parse error at line"),
            "{stderr}"
        );
        assert!(stderr.contains("expected 2 numbers"), "{stderr}");
    }
}

#[test]
fn a_negative_or_nan_sigma_is_a_usage_error() {
    let dir = scratch("sigma");
    file(&dir, "d.csv", MEASUREMENTS);
    for sigma in ["-0.01", "NaN"] {
        let flag = format!("--sigma-mm={sigma}");
        let args =
            [&CALIBRATE[..], &["--joint-sigma-deg", "0.007,0.007,0.007,0.002,0.002,0.002", &flag]].concat();
        let (code, _, stderr) = run_in(&dir, &args);
        assert_eq!(code, 2);
        assert!(stderr.contains("expected a finite number from 0 to 1e6"), "{stderr}");
    }
}

#[test]
fn joint_values_outside_the_limits_are_warned_with_their_lines() {
    let dir = scratch("outside");
    let mut lines: Vec<String> = MEASUREMENTS.lines().map(String::from).collect();
    for line in [3, 7] {
        let cells: Vec<&str> = lines[line].split(',').collect();
        lines[line] = [&cells[..2], &["260.0"], &cells[3..]].concat().join(",");
    }
    file(&dir, "d.csv", &(lines.join("\n") + "\n"));
    let (code, stdout, stderr) = run_in(&dir, &CALIBRATE);
    assert_eq!(code, 0, "{stderr}");
    assert!(stdout.contains("2  training poses with joint values outside the limits of puma560"), "{stdout}");
    assert!(
        stdout.contains("joint values outside the limits of puma560 at line 4 (j3), 8 (j3): the calibration"),
        "{stdout}"
    );
}

#[test]
fn identical_poses_and_a_rank_zero_system_identify_nothing() {
    let dir = scratch("nothing");
    let lines: Vec<&str> = MEASUREMENTS.lines().collect();
    let same = format!("{}\n{}\n", lines[..2].join("\n"), vec![lines[2]; 30].join("\n"));
    file(&dir, "d.csv", &same);
    // The marker calibration, and the observation fit (`--tool 0,0,0` sends the file there).
    for args in [&CALIBRATE[..], &[&CALIBRATE[..], &["--tool", "0,0,0"]].concat()] {
        let (code, _, stderr) = run_in(&dir, args);
        assert_eq!(code, 1);
        assert!(
            stderr.contains("d.csv: nothing can be identified: all 30 poses have the joint values of line 3"),
            "{stderr}"
        );
    }
    file(&dir, "d.csv", MEASUREMENTS);
    let args = ["calibrate", "--model", "puma560", "--data", "d.csv", "--fixed-base", "--fixed-markers"];
    let (code, _, stderr) = run_in(
        &dir,
        &[&args[..], &["--params", "j6.theta", "--marker", "0,0,0", "--marker", "0,0,0"]].concat(),
    );
    assert_eq!(code, 1);
    assert!(stderr.contains("d.csv: nothing can be identified: the identification Jacobian"), "{stderr}");
    assert_eq!(listing(&dir), ["d.csv"]);
}

#[test]
fn urdf_mimic_joints_and_links_with_two_parents_are_refused() {
    let text = crate::urdf::arm_urdf();
    let mimic = text.replacen(
        "<parent link=\"l3\"/>",
        "<parent link=\"l3\"/>\n    <mimic joint=\"shoulder_lift\" multiplier=\"1\"/>",
        1,
    );
    let error = robocal::model::from_urdf_str(&mimic, "base", "flange").unwrap_err().to_string();
    assert!(
        error.starts_with("field `joint `elbow`.mimic`: a joint of its own: it mimics `shoulder_lift`"),
        "{error}"
    );
    let two_parents = text.replacen(
        "</robot>",
        "  <joint name=\"extra\" type=\"fixed\">\n    <parent link=\"base\"/>\n    <child link=\"l4\"/>\n  </joint>\n</robot>",
        1,
    );
    let error = robocal::model::from_urdf_str(&two_parents, "base", "flange").unwrap_err().to_string();
    assert_eq!(
        error,
        "field `link `l4``: one parent joint (a URDF is a tree), found `elbow` and `extra`: not supported"
    );
}

// 5. Errors once.

/// Over a table of bad inputs, each message names its file once and its line or field once,
/// with the cause after it, and is printed once.
#[test]
fn each_error_is_printed_once_naming_file_and_line_once() {
    let dir = scratch("once");
    let mut bad_cell: Vec<String> = MEASUREMENTS.lines().map(String::from).collect();
    let cells: Vec<&str> = bad_cell[4].split(',').collect();
    bad_cell[4] = [&cells[..1], &["4x5"], &cells[2..]].concat().join(",");
    file(&dir, "bad-cell.csv", &(bad_cell.join("\n") + "\n"));
    file(&dir, "d.csv", MEASUREMENTS);
    file(&dir, "bad-syntax.toml", &MODEL.replacen("a_mm = 431.8", "a_mm = [431.8", 1));
    file(&dir, "bad-field.toml", &MODEL.replacen("a_mm = 431.8", "a_mm = inf", 1));
    file(&dir, "bad-noise.toml", "joint_sigma = [0.1, 0.2]\n");
    file(&dir, "bad-study.toml", &small_study(&[("test_points = 20", "test_points = 0")]));
    file(&dir, "bad.urdf", &crate::urdf::arm_urdf().replacen("0 0 0.35", "0 0 zero", 1));
    let repeatability = include_str!("../../examples/puma560-repeatability.csv");
    let mut lines: Vec<&str> = repeatability.lines().collect();
    lines.insert(6, "a,b");
    file(&dir, "bad-rep.csv", &(lines.join("\n") + "\n"));
    let cases: [(&[&str], &str, &str); 10] = [
        (
            &["calibrate", "--model", "puma560", "--data", "bad-cell.csv"],
            "bad-cell.csv",
            "line 5, column `j2`",
        ),
        (&["model", "show", "bad-syntax.toml"], "bad-syntax.toml", "line 48"),
        (&["model", "show", "bad-field.toml"], "bad-field.toml", "`joints[1].a_mm`"),
        (
            &["calibrate", "--model", "bad-field.toml", "--data", "d.csv"],
            "bad-field.toml",
            "`joints[1].a_mm`",
        ),
        (
            &["calibrate", "--model", "puma560", "--data", "d.csv", "--noise", "bad-noise.toml"],
            "bad-noise.toml",
            "`joint_sigma`",
        ),
        (
            &["calibrate", "--model", "puma560", "--data", "d.csv", "--validate", "bad-cell.csv"],
            "bad-cell.csv",
            "line 5",
        ),
        (&["simulate", "bad-study.toml", "--out", "out"], "bad-study.toml", "`test_points`"),
        (
            &[
                "calibrate",
                "--model",
                "bad.urdf",
                "--base-link",
                "base",
                "--tip-link",
                "flange",
                "--data",
                "d.csv",
            ],
            "bad.urdf",
            "joint `slide`.origin.xyz",
        ),
        (&["repeatability", "--model", "puma560", "--data", "bad-rep.csv"], "bad-rep.csv", "line 7"),
        (&["calibrate", "--model", "puma560", "--data", "missing.csv"], "missing.csv", "No such file"),
    ];
    for (args, name, place) in cases {
        let (code, stdout, stderr) = run_in(&dir, args);
        assert_eq!(code, 1, "{args:?}: {stderr}");
        assert!(stdout.is_empty(), "{args:?}: {stdout}");
        assert_eq!(stderr.matches("error:").count(), 1, "{args:?}: {stderr}");
        assert_eq!(stderr.matches(name).count(), 1, "{args:?}: the file named once: {stderr}");
        assert_eq!(stderr.matches(place).count(), 1, "{args:?}: the place named once: {stderr}");
        assert!(
            stderr.find(name) < stderr.find(place),
            "{args:?}: the file, then what is wrong in it: {stderr}"
        );
    }
    assert!(!dir.join("out").exists());
}

/// Poses within `spread` rad of one pose, measured without noise with two markers.
fn clustered(
    spread: f64,
    poses: usize,
) -> (robocal::model::RobotModel, robocal::calibration::kinds::KindData) {
    use rand::{RngExt, SeedableRng};
    let model = robocal::model::RobotModel::preset("puma560").unwrap();
    let mut rng = rand::rngs::ChaCha8Rng::seed_from_u64(5);
    let centre = [0.3, 0.8, -0.6, 0.4, 0.9, 0.2];
    let joints: Vec<Vec<f64>> = (0..poses)
        .map(|_| centre.iter().map(|c| c + spread * rng.random_range(-1.0..1.0)).collect())
        .collect();
    let markers = [nalgebra::Vector3::new(50.0, 0.0, 150.0), nalgebra::Vector3::new(-40.0, 60.0, 120.0)];
    let text = robocal::simulation::measurement_csv(&model, &markers, &joints, &[0.0; 6], 0.0, 1);
    let data = crate::marker_data(&text, &model, None);
    (model, data)
}

/// A rank-full system with a scaled condition number above 1e6 calibrates, with a warning;
/// one below it without.
#[test]
fn a_badly_conditioned_system_is_warned() {
    use robocal::calibration::JointParams;
    use robocal::calibration::kinds::{KindOptions, calibrate_kinds};
    for (spread, warned) in [(1e-3, false), (1e-7, true)] {
        let (model, data) = clustered(spread, 60);
        let markers = [nalgebra::Vector3::new(50.0, 0.0, 150.0), nalgebra::Vector3::new(-40.0, 60.0, 120.0)];
        let options = KindOptions {
            joints: JointParams::Offsets,
            estimate_base: false,
            estimate_markers: false,
            ..crate::marker_options(&model, robocal::estimation::Estimator::Ols, None, &markers)
        };
        let result = calibrate_kinds(&model, &data, &options).unwrap();
        let diagnostics = &result.refined.estimate.diagnostics;
        assert_eq!(diagnostics.rank, 6, "rank-full");
        let warning = (result.warnings.iter())
            .find(|w| matches!(w, robocal::calibration::Warning::IllConditioned { .. }))
            .map(ToString::to_string);
        assert_eq!(warning.is_some(), warned, "{spread}: {:?}", result.warnings);
        if let Some(warning) = warning {
            assert!(
                warning.starts_with("the identified system's scaled condition number is 9.2"),
                "{warning}"
            );
            assert!(warning.contains("above 1e6: the estimates are poorly determined"), "{warning}");
        }
    }
}

// Issue 25. 1. Special files are written in place; a symbolic link is followed.

/// Whether the system command `program args` succeeded (a reason printed if not).
fn system(program: &str, args: &[&str]) -> bool {
    match std::process::Command::new(program).args(args).output() {
        Ok(out) if out.status.success() => true,
        Ok(out) => {
            eprintln!("{program} {args:?}: {}", String::from_utf8_lossy(&out.stderr).trim());
            false
        }
        Err(e) => {
            eprintln!("{program}: {e}");
            false
        }
    }
}

#[test]
fn a_device_node_given_as_an_output_is_written_in_place_and_stays_a_device() {
    use std::os::unix::fs::FileTypeExt;
    let dir = scratch("device");
    file(&dir, "d.csv", MEASUREMENTS);
    let node = dir.join("null");
    // The null device (1, 3), made here: never the system's /dev/null.
    if !system("mknod", &[node.to_str().unwrap(), "c", "1", "3"]) {
        eprintln!("skipped: mknod is not permitted here (the test needs root or CAP_MKNOD)");
        return;
    }
    let (code, _, stderr) =
        run_in(&dir, &[&CALIBRATE[..], &["--json", "null", "--out-model", "m.toml"]].concat());
    assert_eq!(code, 0, "{stderr}");
    assert!(std::fs::symlink_metadata(&node).unwrap().file_type().is_char_device(), "still a device");
    // The model's covariance beside it (`calibrate --out-model` writes both).
    assert_eq!(listing(&dir), ["d.csv", "m.toml", "m.toml.covariance.json", "null"], "no temporary file");
    // Read back: the null device reads empty.
    assert_eq!(std::fs::read(&node).unwrap(), b"");
}

#[test]
fn a_fifo_given_as_an_output_is_written_in_place_and_stays_a_fifo() {
    use std::os::unix::fs::FileTypeExt;
    let dir = scratch("fifo");
    file(&dir, "d.csv", MEASUREMENTS);
    let fifo = dir.join("pipe");
    if !system("mkfifo", &[fifo.to_str().unwrap()]) {
        eprintln!("skipped: mkfifo failed");
        return;
    }
    let reader = {
        let fifo = fifo.clone();
        std::thread::spawn(move || std::fs::read_to_string(fifo).unwrap())
    };
    let (code, _, stderr) = run_in(&dir, &[&CALIBRATE[..], &["--json", "pipe"]].concat());
    assert_eq!(code, 0, "{stderr}");
    let json: serde_json::Value = serde_json::from_str(&reader.join().unwrap()).unwrap();
    assert!(json.get("parameters").is_some(), "the report came through the FIFO: {json}");
    assert!(std::fs::symlink_metadata(&fifo).unwrap().file_type().is_fifo(), "still a FIFO");
    assert_eq!(listing(&dir), ["d.csv", "pipe"]);
}

#[test]
fn a_dash_is_standard_output_and_no_file_named_dash_is_made() {
    let dir = scratch("dash");
    file(&dir, "d.csv", MEASUREMENTS);
    let (code, stdout, stderr) = run_in(&dir, &[&CALIBRATE[..], &["--out-model", "-"]].concat());
    assert_eq!(code, 0, "{stderr}");
    assert!(stdout.contains("[[joints]]"), "the model on standard output: {stdout}");
    assert_eq!(listing(&dir), ["d.csv"], "no file named -");
}

#[test]
fn a_symbolic_link_is_followed_and_its_target_replaced() {
    let dir = scratch("symlink");
    file(&dir, "d.csv", MEASUREMENTS);
    file(&dir, "old.json", "old\n");
    std::os::unix::fs::symlink("old.json", dir.join("link.json")).unwrap();
    std::os::unix::fs::symlink("new.toml", dir.join("dangling.toml")).unwrap();
    let args = ["--json", "link.json", "--out-model", "dangling.toml"];
    let (code, _, stderr) = run_in(&dir, &[&CALIBRATE[..], &args].concat());
    assert_eq!(code, 0, "{stderr}");
    for (link, target) in [("link.json", "old.json"), ("dangling.toml", "new.toml")] {
        let meta = std::fs::symlink_metadata(dir.join(link)).unwrap();
        assert!(meta.file_type().is_symlink(), "{link} stays a link");
        assert_eq!(std::fs::read_link(dir.join(link)).unwrap(), Path::new(target));
    }
    assert!(std::fs::read_to_string(dir.join("old.json")).unwrap().contains("\"parameters\""));
    assert!(std::fs::read_to_string(dir.join("new.toml")).unwrap().contains("[[joints]]"));
    // The model's covariance beside the name given (a file of its own, not through the link).
    assert_eq!(
        listing(&dir),
        ["d.csv", "dangling.toml", "dangling.toml.covariance.json", "link.json", "new.toml", "old.json"]
    );
}

/// `--json -` (and `--out-model -`) has standard output to itself: the text report goes to
/// standard error, so that the JSON parses; the status line names standard output, not `-`.
#[test]
fn a_dash_output_has_standard_output_to_itself() {
    let dir = scratch("dash-alone");
    file(&dir, "d.csv", MEASUREMENTS);
    let (code, stdout, stderr) = run_in(&dir, &[&CALIBRATE[..], &["--json", "-"]].concat());
    assert_eq!(code, 0, "{stderr}");
    let report: serde_json::Value = serde_json::from_str(&stdout).expect("standard output is the JSON alone");
    assert!(report["parameters"].is_array(), "{stdout}");
    assert!(
        stderr.contains("verdict, the errors before -> after calibration")
            && stderr.contains("wrote standard output")
    );
    assert!(!stderr.contains("wrote -"), "{stderr}");
    let (code, stdout, stderr) = run_in(&dir, &[&CALIBRATE[..], &["--out-model", "-"]].concat());
    assert_eq!(code, 0, "{stderr}");
    assert!(
        stdout.starts_with(|c: char| c == '#' || c == '[' || c.is_alphabetic())
            && !stdout.contains("verdict")
    );
}

#[test]
fn outputs_written_in_place_may_be_named_twice() {
    let dir = scratch("dash-twice");
    file(&dir, "d.csv", MEASUREMENTS);
    let (code, stdout, stderr) =
        run_in(&dir, &[&CALIBRATE[..], &["--json", "-", "--out-model", "-"]].concat());
    assert_eq!(code, 0, "{stderr}");
    assert!(stdout.contains("\"parameters\"") && stdout.contains("[[joints]]"), "{stdout}");
    assert_eq!(listing(&dir), ["d.csv"]);
}

// 2. Signals: the temporary files and the folders a run created are removed.

/// `robocal args` started in `dir`, its output discarded.
fn spawn_in(dir: &Path, args: &[&str]) -> std::process::Child {
    std::process::Command::new(assert_cmd::cargo::cargo_bin("robocal"))
        .current_dir(dir)
        .args(args)
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .spawn()
        .unwrap()
}

/// `signal` (`TERM`, `INT`) sent to `child`; its exit code.
fn signal_and_wait(child: &mut std::process::Child, signal: &str) -> Option<i32> {
    assert!(
        system("kill", &[&format!("-{signal}"), &child.id().to_string()])
            || child.try_wait().unwrap().is_some()
    );
    child.wait().unwrap().code()
}

/// The names below `dir` (relative, sorted), folders included.
fn tree_listing(dir: &Path) -> Vec<String> {
    let mut names = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(folder) = stack.pop() {
        for entry in std::fs::read_dir(&folder).unwrap() {
            let path = entry.unwrap().path();
            names.push(path.strip_prefix(dir).unwrap().to_string_lossy().into_owned());
            if path.is_dir() {
                stack.push(path);
            }
        }
    }
    names.sort();
    names
}

#[test]
fn sigterm_at_random_points_of_a_simulation_leaves_no_temporary_and_no_folder_it_made() {
    let dir = scratch("sigterm");
    file(
        &dir,
        "s.toml",
        &small_study(&[
            ("runs_per_set = 2", "runs_per_set = 300"),
            ("test_points = 20", "test_points = 400"),
        ]),
    );
    // How long a whole run takes here, to spread the signals over it: the quickest of three (a
    // first run, cold, or one beside a load that ends, would spread them past most runs' end).
    let runs = (0..3).map(|i| {
        let started = std::time::Instant::now();
        let (code, _, stderr) = run_in(&dir, &["simulate", "s.toml", "--out", &format!("whole{i}")]);
        assert_eq!(code, 0, "{stderr}");
        started.elapsed()
    });
    let whole = runs.min().unwrap();
    let complete = tree_listing(&dir.join("whole0"));
    let (mut stopped, mut finished) = (0, 0);
    let mut state = 0x2545_f491_4f6c_dd1du64;
    for i in 0..20 {
        // A deterministic spread of points from the start to a little past the end.
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        let delay = whole.mul_f64((state % 1000) as f64 / 900.0);
        let out = format!("out{i}");
        let mut child = spawn_in(&dir, &["simulate", "s.toml", "--out", &out]);
        std::thread::sleep(delay);
        match signal_and_wait(&mut child, "TERM") {
            // A signal between the last commit and the exit stops a run whose outputs are all
            // in place: they stay, whole (a finished commit is never undone).
            Some(143) if dir.join(&out).exists() => {
                finished += 1;
                assert_eq!(
                    tree_listing(&dir.join(&out)),
                    complete,
                    "run {i} (after {delay:?}): stopped after its commit"
                );
            }
            Some(143) => stopped += 1,
            Some(0) => {
                finished += 1;
                assert_eq!(tree_listing(&dir.join(&out)), complete, "run {i}: finished whole");
            }
            code => panic!("run {i} (after {delay:?}): exit {code:?}"),
        }
    }
    eprintln!(
        "20 signals: {stopped} stopped the run, {finished} came after it ended (a run takes {whole:?})"
    );
    assert!(stopped >= 10, "{stopped} of 20 stopped");
    let left: Vec<String> = tree_listing(&dir).into_iter().filter(|n| n.ends_with(".tmp")).collect();
    assert!(left.is_empty(), "{left:?}");
}

#[test]
fn a_signal_while_outputs_are_written_removes_their_temporaries_and_folders() {
    let dir = scratch("signal-commit");
    file(&dir, "d.csv", MEASUREMENTS);
    if !system("mkfifo", &[dir.join("pipe").to_str().unwrap()]) {
        eprintln!("skipped: mkfifo failed");
        return;
    }
    // The figures' temporaries are written to a new folder, then the FIFO, which nobody
    // reads, blocks the commit: a signal then finds them all on disk.
    for (signal, code) in [("TERM", 143), ("INT", 130)] {
        let args =
            [&CALIBRATE[..], &["--figures", "new/figs", "--out-model", "m.toml", "--json", "pipe"]].concat();
        let mut child = spawn_in(&dir, &args);
        let deadline = std::time::Instant::now() + std::time::Duration::from_secs(120);
        while !dir.join("new/figs").exists() && std::time::Instant::now() < deadline {
            std::thread::sleep(std::time::Duration::from_millis(20));
        }
        std::thread::sleep(std::time::Duration::from_millis(200));
        assert!(!tree_listing(&dir.join("new")).is_empty(), "the commit had begun");
        assert_eq!(signal_and_wait(&mut child, signal), Some(code));
        assert_eq!(listing(&dir), ["d.csv", "pipe"], "SIG{signal}");
    }
}

// 5. Paths: an input or an output inside an output folder, under a name written there.

#[test]
fn an_input_inside_an_output_folder_under_a_name_written_there_is_refused_before_any_work() {
    let dir = scratch("input-in-folder");
    std::fs::create_dir_all(dir.join("o/small")).unwrap();
    file(&dir, "o/small/tables.txt", &small_study(&[]));
    std::fs::create_dir(dir.join("d")).unwrap();
    // A file of views (its header says so) under the name a tree's calibration writes there.
    file(&dir, "d/frames.json", "camera,target,torso\n");
    std::fs::create_dir(dir.join("figs")).unwrap();
    file(&dir, "figs/keep.csv", MEASUREMENTS);
    let torso = Path::new(env!("CARGO_MANIFEST_DIR")).join("presets/torso.urdf");
    let cases: [(&[&str], &str); 4] = [
        (
            &["simulate", "o/small/tables.txt", "--out", "o"],
            "the study o/small/tables.txt: inside the folder of --out o",
        ),
        (
            &["calibrate", "--model", torso.to_str().unwrap(), "--data", "d/frames.json", "--out-dir", "d"],
            "--data d/frames.json: inside the folder of --out-dir d",
        ),
        (&[&CALIBRATE[..], &["--figures", "."]].concat(), ""),
        (
            &["simulate", "o/small/tables.txt", "--out", "."],
            "the study o/small/tables.txt: inside the folder of --out .",
        ),
    ];
    for (args, message) in cases {
        let (code, stdout, stderr) = run_in(&dir, args);
        if message.is_empty() {
            continue;
        }
        assert_eq!(code, 2, "{args:?}: {stderr}");
        assert!(stdout.is_empty(), "no work done: {stdout}");
        assert!(
            stderr.contains(message) && stderr.contains("under a name this command writes there"),
            "{stderr}"
        );
    }
    assert_eq!(std::fs::read_to_string(dir.join("o/small/tables.txt")).unwrap(), small_study(&[]));
    assert_eq!(std::fs::read_to_string(dir.join("d/frames.json")).unwrap(), "camera,target,torso\n");
    // Under a name the command does not write there, an input may stay in the folder.
    let (code, _, stderr) = run_in(
        &dir,
        &[
            "calibrate",
            "--model",
            "puma560",
            "--data",
            "figs/keep.csv",
            "--marker=50,0,150",
            "--figures",
            "figs",
        ],
    );
    assert_eq!(code, 0, "{stderr}");
    assert_eq!(std::fs::read_to_string(dir.join("figs/keep.csv")).unwrap(), MEASUREMENTS);
}

#[test]
fn an_output_inside_another_outputs_folder_is_a_usage_error_before_any_work() {
    let dir = scratch("output-in-folder");
    file(&dir, "d.csv", MEASUREMENTS);
    for (args, message) in [
        (
            ["--figures", "figs", "--json", "figs/histogram.svg"],
            "--json figs/histogram.svg: inside the folder of --figures figs",
        ),
        (["--figures", "figs", "--html", "figs"], "--html figs: inside the folder of --figures figs"),
        (
            ["--json", "./figs/sub/a.svg", "--figures", "figs"],
            "--json ./figs/sub/a.svg: inside the folder of --figures figs",
        ),
    ] {
        let (code, stdout, stderr) = run_in(&dir, &[&CALIBRATE[..], &args].concat());
        assert_eq!(code, 2, "{args:?}: {stderr}");
        assert!(stdout.is_empty(), "no work done: {stdout}");
        assert!(stderr.contains(message), "{stderr}");
        assert_eq!(listing(&dir), ["d.csv"]);
    }
    // Beside the figures, under another name: written.
    let (code, _, stderr) =
        run_in(&dir, &[&CALIBRATE[..], &["--figures", "figs", "--json", "figs/report.json"]].concat());
    assert_eq!(code, 0, "{stderr}");
    assert!(dir.join("figs/report.json").is_file());
}

// 3. The last panic (`complement_projector`), three causes: a null space whose columns are
// almost parallel once scaled back, or whose Gram matrix overflows.

/// Plane contacts at 40 poses (joints in whole degrees from an LCG of `seed`), three planes in
/// turn, the fourth pose's j2 = 0 if `j2_zero`.
fn contacts_file(seed: u64, j2_zero: bool) -> String {
    let mut state = seed;
    let mut next = || {
        state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        ((state >> 33) % 121) as i64 - 60
    };
    let mut text = String::from("# units: joints=deg, lengths=mm\nj1,j2,j3,j4,j5,j6,plane\n");
    for i in 0..40 {
        let mut q: Vec<i64> = (0..6).map(|_| next()).collect();
        if i == 3 && j2_zero {
            q[1] = 0;
        }
        let q: Vec<String> = q.iter().map(|v| v.to_string()).collect();
        text += &format!("{},{}\n", q.join(","), 1 + i % 3);
    }
    text
}

#[test]
fn plane_contacts_alone_with_one_at_j2_zero_calibrate_without_a_panic() {
    let dir = scratch("contacts-j2-zero");
    for seed in [1, 2] {
        file(&dir, "c.csv", &contacts_file(seed, true));
        let args =
            ["calibrate", "--model", "puma560", "--tool", "50,0,150", "--fixed-tool", "--data", "c.csv"];
        let (code, stdout, stderr) = run_in(&dir, &args);
        assert!(!stderr.contains("panicked"), "seed {seed}: {stderr}");
        assert_eq!(code, 0, "seed {seed}: {stderr}");
        assert!(stdout.contains("40 observations at 40 poses"), "{stdout}");
    }
}

/// A calibration of the compliances (and the payload's mass) of the PUMA with link masses and
/// a payload, as `edit` changes them, on the example's poses: whatever it returns, no panic.
fn calibrate_loaded(edit: impl Fn(&mut robocal::model::RobotModel)) -> Result<(), String> {
    use nalgebra::Vector3;
    use robocal::model::{LinkMass, Payload};
    let mut model = robocal::model::RobotModel::preset("puma560").unwrap();
    let masses = [0.0, 17.4, 4.8, 0.82, 0.34, 0.09];
    model.masses = masses.iter().map(|&mass| LinkMass { mass, com: Vector3::new(0.0, 10.0, 20.0) }).collect();
    model.joints[1].compliance = 5e-5;
    model.joints[2].compliance = 8e-5;
    model.payload = Some(Payload { mass: 2.0, com: Vector3::new(0.0, 20.0, 80.0) });
    edit(&mut model);
    let data = crate::marker_data(MEASUREMENTS, &model, None);
    let markers = [Vector3::new(50.0, 0.0, 150.0)];
    let options = robocal::calibration::kinds::KindOptions {
        joints: robocal::calibration::JointParams::Named(vec!["j*.*".into(), "payload.mass".into()]),
        refine: robocal::estimation::RefineOptions { max_iterations: 5, ..Default::default() },
        ..crate::marker_options(&model, robocal::estimation::Estimator::Ols, None, &markers)
    };
    robocal::calibration::kinds::calibrate_kinds(&model, &data, &options)
        .map(|_| ())
        .map_err(|e| e.to_string())
}

#[test]
fn masses_or_a_payload_of_1e300_and_a_centre_of_mass_of_minus_1e300_do_not_panic_the_solve() {
    // The readers refuse these now (see the bounds below); the solve must not panic on them.
    type Edit = fn(&mut robocal::model::RobotModel);
    let cases: [(&str, Edit); 3] = [
        ("link masses of 1e300 kg", |m| m.masses.iter_mut().for_each(|l| l.mass = 1e300)),
        ("a payload of 1e300 kg", |m| m.payload.as_mut().unwrap().mass = 1e300),
        ("a payload's centre of mass at -1e300 mm", |m| m.payload.as_mut().unwrap().com.z = -1e300),
    ];
    let mut panicked = Vec::new();
    for (what, edit) in cases {
        match std::panic::catch_unwind(|| calibrate_loaded(edit)) {
            Ok(outcome) => eprintln!("{what}: {outcome:?}"),
            Err(_) => panicked.push(what),
        }
    }
    assert!(panicked.is_empty(), "panicked: {panicked:?}");
    assert!(calibrate_loaded(|_| ()).is_ok(), "the ordinary loaded robot calibrates");
}

// 4. Bounds on the new physics, each naming its field.

#[test]
fn masses_compliances_plays_priors_and_truths_beyond_their_bounds_are_refused_naming_the_field() {
    let dir = scratch("physics-bounds");
    file(&dir, "d.csv", MEASUREMENTS);
    let masses = include_str!("../../presets/puma560-masses.toml");
    let study = include_str!("../../presets/compliance.toml");
    let model_cases = [
        ("mass_kg = 17.4", "mass_kg = 1e300", "links[1].mass_kg`: a number from 0 to 100000 kg, found 1e300"),
        ("mass_kg = 17.4", "mass_kg = -1", "links[1].mass_kg`: a number from 0 to 100000 kg, found -1"),
        (
            "[[joints]]\nname = \"j2\"",
            "[[joints]]\nname = \"j2\"\ncompliance_rad_per_nm = -2",
            "joints[1].compliance_rad_per_nm`: a number from -1 to 1 rad/(N·m), found -2",
        ),
        (
            "[[joints]]\nname = \"j2\"",
            "[[joints]]\nname = \"j2\"\ncompliance_rad_per_nm = 1e300",
            "found 1e300",
        ),
        (
            "[[joints]]\nname = \"j2\"",
            "[[joints]]\nname = \"j2\"\nplay_deg = 100",
            "joints[1].play_deg`: a number from -10 to 10 deg, found 100",
        ),
    ];
    for (from, to, message) in model_cases {
        assert!(masses.contains(from), "{from}");
        file(&dir, "m.toml", &masses.replacen(from, to, 1));
        let (code, _, stderr) =
            run_in(&dir, &[&["calibrate", "--model", "m.toml"], &CALIBRATE[3..]].concat());
        assert_eq!(code, 1, "{to}: {stderr}");
        assert!(stderr.contains(message), "{to}: {stderr}");
    }
    let flag_cases: [(&[&str], &str); 4] = [
        (&["--payload-kg", "1e300"], "--payload-kg: a number from 0 to 100000 kg, found 1e300"),
        (
            &["--payload-kg", "2", "--payload-com-mm=0,0,-1e300"],
            "--payload-com-mm: a finite number of magnitude at most 1e6 mm, found -1e300",
        ),
        (&["--prior", "j*.a=1e300mm"], "a standard deviation from 1e-15 to 1e12 mm, found 1e300 mm"),
        (&["--prior", "j*.alpha=1e-20deg"], "a standard deviation from 1e-15 to 1e12 rad, found 1.745"),
    ];
    for (args, message) in flag_cases {
        let (code, stdout, stderr) = run_in(&dir, &[&CALIBRATE[..], args].concat());
        assert!(code == 2 || code == 1, "{args:?}: {stderr}");
        assert!(stdout.is_empty(), "no work done: {stdout}");
        assert!(stderr.contains(message), "{args:?}: {stderr}");
    }
    let study_cases = [
        (
            "payload_kg = 2.0",
            "payload_kg = 1e300",
            "truth.payload_kg`: a number from 0 to 100000 kg, found 1e300",
        ),
        (
            "payload_com_mm = [0.0, 0.0, 100.0]",
            "payload_com_mm = [0.0, 0.0, -1e300]",
            "truth.payload_com_mm`: a finite number of magnitude at most 1e6 mm, found -1e300",
        ),
        (
            "compliance = { j2 = 5e-5",
            "compliance = { j2 = -5e-5",
            "truth.compliance.j2`: a number from 0 to 1 rad/(N·m), found -5e-5",
        ),
        (
            "compliance = { j2 = 5e-5",
            "play = { j6 = 1e300 }\ncompliance = { j2 = 5e-5",
            "truth.play.j6`: a number from -10 to 10 deg, found 1e300",
        ),
    ];
    for (from, to, message) in study_cases {
        assert!(study.contains(from), "{from}");
        file(&dir, "s.toml", &study.replacen(from, to, 1));
        let (code, _, stderr) = run_in(&dir, &["simulate", "s.toml", "--out", "o"]);
        assert_eq!(code, 1, "{to}: {stderr}");
        assert!(stderr.contains(message), "{to}: {stderr}");
    }
    assert_eq!(listing(&dir), ["d.csv", "m.toml", "s.toml"], "nothing written");
}

// 8. Work bounded by its estimate, refused beyond it with the estimate, before any work.

#[test]
fn work_beyond_its_bound_is_refused_with_the_estimate_before_any_work() {
    let dir = scratch("work-bounds");
    let instruments = include_str!("../../presets/instruments.toml");
    assert!(instruments.contains("time_budget_s = 600"));
    file(&dir, "i.toml", &instruments.replacen("time_budget_s = 600", "time_budget_s = 1048576", 1));
    file(
        &dir,
        "s.toml",
        &small_study(&[("runs_per_set = 2", "runs_per_set = 100000"), ("point_sets = 2", "point_sets = 4")]),
    );
    let cases: [(&[&str], &str); 3] = [
        (
            &["simulate", "i.toml", "--out", "o"],
            "time_budget_s`: a study of at most 1e9 row-parameter products",
        ),
        (
            &["plan", "--model", "puma560", "--points", "100000", "--candidates", "1000000"],
            "more than 1e10 (hours of work): ask for fewer candidates or points",
        ),
        (
            &["simulate", "s.toml", "--out", "o", "--replications", "10000"],
            "--replications 10000: study small replicated would take about 1.3e11 kinematic evaluations",
        ),
    ];
    for (args, message) in cases {
        let started = std::time::Instant::now();
        let (code, _, stderr) = run_in(&dir, args);
        assert_eq!(code, 1, "{args:?}: {stderr}");
        assert!(stderr.contains(message), "{args:?}: {stderr}");
        assert!(started.elapsed().as_secs() < 30, "{args:?}: refused before the work");
    }
    assert_eq!(listing(&dir), ["i.toml", "s.toml"]);
}

// 6. Silent accepts, now errors naming the field. 7. Help that says what a command takes.

#[test]
fn one_pose_or_identical_poses_and_an_estimator_named_twice_are_refused_naming_the_field() {
    let dir = scratch("silent-accepts");
    let repeatability = include_str!("../../examples/puma560-repeatability.csv");
    let first = repeatability.lines().nth(2).unwrap().split(',').next().unwrap().to_string();
    let one_pose: String = repeatability
        .lines()
        .filter(|l| l.starts_with('#') || l.starts_with("pose") || l.starts_with(&format!("{first},")))
        .map(|l| format!("{l}\n"))
        .collect();
    file(&dir, "r.csv", &one_pose);
    let (code, _, stderr) = run_in(&dir, &["repeatability", "--model", "puma560", "--data", "r.csv"]);
    assert_eq!(code, 1, "{stderr}");
    assert!(stderr.contains("r.csv, column `pose`: 1 pose: the spread at one pose cannot tell"), "{stderr}");

    let pose = "# units: joints=deg, lengths=mm\nj1,j2,j3,j4,j5,j6\n10,20,30,40,50,60\n";
    file(&dir, "one.csv", pose);
    file(&dir, "same.csv", &format!("{pose}10,20,30,40,50,60\n10,20,30,40,50,60\n"));
    for (name, what) in [("one.csv", "one.csv: one pose"), ("same.csv", "same.csv: 3 poses, all alike")] {
        let (code, stdout, stderr) = run_in(&dir, &["observability", "--model", "puma560", name]);
        assert_eq!(code, 1, "{stderr}");
        assert!(stdout.is_empty() && !stdout.contains("inf"), "{stdout}");
        assert!(stderr.contains(what) && stderr.contains("need poses that differ"), "{stderr}");
    }

    file(&dir, "s.toml", &small_study(&[("estimators = [", "estimators = [\"ols\", ")]));
    let (code, _, stderr) = run_in(&dir, &["simulate", "s.toml", "--out", "o"]);
    assert_eq!(code, 1, "{stderr}");
    assert!(stderr.contains("field `estimators`: each estimator once, found \"ols\" twice"), "{stderr}");
    assert!(!dir.join("o").exists());
}

#[test]
fn help_lists_only_the_estimators_a_command_takes() {
    for command in ["calibrate-observations", "calibrate-tree"] {
        let (code, stdout, _) = run_in(Path::new("."), &[command, "--help"]);
        assert_eq!(code, 0);
        let estimator = &stdout[stdout.find("--estimator").unwrap()..];
        let estimator = &estimator[..estimator[2..].find("\n      --").map_or(estimator.len(), |i| i + 2)];
        assert!(!estimator.contains("fgls") && estimator.contains("or ols"), "{command}: {estimator}");
    }
}

/// `MEASUREMENTS` with `edit` applied to the cells of every pose row (`cells[6..]` are the
/// markers' x1, y1, z1, x2, y2, z2).
fn edited_rows(edit: impl Fn(&mut Vec<String>)) -> String {
    let mut lines = MEASUREMENTS.lines();
    let mut text = format!("{}\n{}\n", lines.next().unwrap(), lines.next().unwrap());
    for line in lines {
        let mut cells: Vec<String> = line.split(',').map(str::to_string).collect();
        edit(&mut cells);
        text += &format!("{}\n", cells.join(","));
    }
    text
}

#[test]
fn a_marker_header_typo_a_marker_never_measured_and_a_urdf_name_twice_are_refused_naming_them() {
    let dir = scratch("silent-accepts-2");
    assert!(MEASUREMENTS.lines().nth(1).unwrap().starts_with("j1,j2,j3,j4,j5,j6,x1,y1,z1,x2,y2,z2"));
    // Before: `X1` dropped marker 1 with a note, and the calibration went on with marker 2.
    let cases = [
        (
            MEASUREMENTS.replacen(",x1,", ",X1,", 1),
            "line 2, column `X1`: expected `x1`: marker columns are x1,y1,z1",
        ),
        (MEASUREMENTS.replacen(",x2,", ",q2,", 1), "line 2, column `y2`: marker 2 needs x2 too"),
        (
            edited_rows(|cells| cells[6..].iter_mut().for_each(|c| *c = "0".into())),
            "line 2, column `x1`: marker 1 is at 0, 0, 0 in every row: a placeholder, not a measurement",
        ),
        (
            edited_rows(|cells| cells[9..].iter_mut().for_each(|c| *c = "0.0".into())),
            "line 2, column `x2`: marker 2 is at 0, 0, 0 in every row",
        ),
    ];
    for (text, message) in &cases {
        file(&dir, "d.csv", text);
        for command in ["calibrate", "calibrate-observations", "evaluate"] {
            let (code, stdout, stderr) = run_in(&dir, &[command, "--model", "puma560", "--data", "d.csv"]);
            assert_eq!(code, 1, "{command}: {stderr}");
            assert!(stdout.is_empty(), "{command}: {stdout}");
            assert!(stderr.contains(&format!("d.csv: {message}")), "{command}: {stderr}");
        }
    }
    // A marker measured at 0, 0, 0 in some rows only is a measurement.
    file(
        &dir,
        "d.csv",
        &edited_rows(|cells| {
            if cells[0].starts_with('4') {
                cells[9..].iter_mut().for_each(|c| *c = "0".into())
            }
        }),
    );
    let (code, _, stderr) = run_in(&dir, &CALIBRATE);
    assert_eq!(code, 0, "{stderr}");

    let torso = include_str!("../../presets/torso.urdf");
    let link = "  <link name=\"neck\"/>\n";
    assert!(torso.contains(link) && torso.contains("<joint name=\"head_pan\""));
    let line = torso[..torso.find(link).unwrap()].lines().count() + 1;
    let cases = [
        (
            torso.replacen(link, &format!("{link}{link}"), 1),
            format!(
                "field `<link name=\"neck\">`: one link of each name, found this one on lines {line} and {}",
                line + 1
            ),
        ),
        (
            torso.replacen("<joint name=\"head_pan\"", "<joint name=\"torso\"", 1),
            "field `<joint name=\"torso\">`: one joint of each name".to_string(),
        ),
    ];
    for (text, message) in cases {
        file(&dir, "t.urdf", &text);
        for args in [
            &["model", "show", "t.urdf", "--tip-link", "head"][..],
            &["observability", "--model", "t.urdf", "--tip-link", "head", "d.csv"],
        ] {
            let (code, stdout, stderr) = run_in(&dir, args);
            assert_eq!(code, 1, "{args:?}: {stderr}");
            assert!(stdout.is_empty(), "{stdout}");
            assert!(stderr.contains(&format!("t.urdf: {message}")), "{args:?}: {stderr}");
        }
    }
    assert_eq!(listing(&dir), ["d.csv", "t.urdf"], "nothing written");
}

// 7. Messages that say what is wrong, before the work.

#[test]
fn messages_name_what_is_wrong_and_come_before_the_work() {
    let dir = scratch("messages");
    file(&dir, "d.csv", MEASUREMENTS);
    // A file that exists, whose folder takes no temporary: the message says what failed.
    if Path::new("/proc/version").is_file() {
        let (code, _, stderr) = run_in(&dir, &[&CALIBRATE[..], &["--json", "/proc/version"]].concat());
        assert_eq!(code, 1, "{stderr}");
        assert!(
            stderr.contains("/proc/version: cannot write: the temporary file /proc/.version.")
                && stderr.contains(".tmp could not be written beside it"),
            "{stderr}"
        );
    }
    let (code, _, stderr) = run_in(&dir, &[&CALIBRATE[..], &["--json", "no-such-folder/r.json"]].concat());
    assert_eq!(code, 1, "{stderr}");
    assert!(stderr.contains("no-such-folder/r.json: cannot write: no folder no-such-folder"), "{stderr}");

    // A pose study without orientation noise: refused naming the field, not the flag of
    // another command (`--sigma-orientation-deg`), before any run.
    let pose = small_study(&[("measured = \"position\"", "measured = \"pose\"")]);
    let tiny = small_study(&[("sigma_me_mm = [0.0]", "sigma_me_mm = [4e-320]")]);
    let instruments = include_str!("../../presets/instruments.toml");
    assert!(instruments.contains("pivot_mm = [400.0, 200.0, 300.0]"));
    let pivot = instruments.replacen("pivot_mm = [400.0, 200.0, 300.0]", "pivot_mm = [1e300, 0.0, 0.0]", 1);
    let cases = [
        (pose, "field `noise.sigma_orientation_deg`: a standard deviation above 0 deg in a pose study"),
        (
            tiny,
            "field `cases.sigma_me_mm`: 0 (exact) or a standard deviation of at least 1e-9 mm, found 4e-320",
        ),
        (pivot, "field `instruments[1].pivot_mm`: a finite number of magnitude at most 1e6 mm, found 1e300"),
    ];
    for (text, message) in cases {
        file(&dir, "s.toml", &text);
        let (code, stdout, stderr) = run_in(&dir, &["simulate", "s.toml", "--out", "o"]);
        assert_eq!(code, 1, "{stderr}");
        assert!(stdout.is_empty(), "no work done: {stdout}");
        assert!(stderr.contains(&format!("s.toml: {message}")), "{stderr}");
        assert!(!stderr.contains("--sigma-orientation-deg") && !stderr.contains("calibrating"), "{stderr}");
    }

    // Pairs of identical poses see nothing: said in words, not as the shape of H.
    let mut pairs = String::from(
        "# units: joints=deg, lengths=mm\nj1,j2,j3,j4,j5,j6,j1_b,j2_b,j3_b,j4_b,j5_b,j6_b,distance\n",
    );
    for k in 0..60 {
        let q: Vec<String> = (0..6).map(|j| format!("{}", (k * 7 + j * 13) % 90 - 45)).collect();
        pairs += &format!("{},{},100\n", q.join(","), q.join(","));
    }
    file(&dir, "pairs.csv", &pairs);
    let (code, _, stderr) =
        run_in(&dir, &["calibrate-observations", "--model", "puma560", "--data", "pairs.csv"]);
    assert_eq!(code, 1, "{stderr}");
    assert!(
        stderr.contains("pairs.csv: nothing can be identified: the identification Jacobian of the ")
            && stderr.contains("is zero at these poses: the observations move none of them")
            && stderr.contains("pairs of identical poses"),
        "{stderr}"
    );
    assert!(!stderr.contains("H is") && !stderr.contains(" x 0"), "{stderr}");

    // The outlier flag's rule as it is, with a noise model and without one.
    let noise = Path::new(env!("CARGO_MANIFEST_DIR")).join("examples/puma560-noise.toml");
    let with_noise = [&CALIBRATE[..], &["--estimator", "wls", "--noise", noise.to_str().unwrap()]].concat();
    for args in [&CALIBRATE[..], &with_noise[..]] {
        let (code, stdout, stderr) = run_in(&dir, args);
        assert_eq!(code, 0, "{stderr}");
        let rule = "flagged:   an observation (a marker's position) whose whitened residual exceeds 5 standard \
                    deviations times its set's robust spread, if above 1\n";
        assert!(stdout.contains(rule), "{args:?}: {stdout}");
    }
    assert_eq!(listing(&dir), ["d.csv", "pairs.csv", "s.toml"], "nothing written");
}
