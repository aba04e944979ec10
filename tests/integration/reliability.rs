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
/// error (exit 1 or 2 with a message), never an abort; observability of the same 120 000
/// poses fits and runs.
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
        (
            "calibrate --model puma560 --data huge.csv",
            1,
            "calibrating the 120000 poses of huge.csv would need about",
        ),
        ("observability huge.csv --model puma560", 0, ""), // within the limit: it runs
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
        assert!(stderr.contains("m.toml: not a model file: TOML parse error at line"), "{stderr}");
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
    let (code, _, stderr) = run_in(&dir, &CALIBRATE);
    assert_eq!(code, 0, "{stderr}");
    assert!(
        stderr.contains("warning: d.csv: joint values outside the limits of puma560 at line 4 (j3), 8 (j3)"),
        "{stderr}"
    );
}

#[test]
fn identical_poses_and_a_rank_zero_system_identify_nothing() {
    let dir = scratch("nothing");
    let lines: Vec<&str> = MEASUREMENTS.lines().collect();
    let same = format!("{}\n{}\n", lines[..2].join("\n"), vec![lines[2]; 30].join("\n"));
    file(&dir, "d.csv", &same);
    let (code, _, stderr) = run_in(&dir, &CALIBRATE);
    assert_eq!(code, 1);
    assert!(
        stderr.contains("d.csv: nothing can be identified: all 30 poses have the joint values of line 3"),
        "{stderr}"
    );
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
fn clustered(spread: f64, poses: usize) -> (robocal::model::RobotModel, robocal::calibration::Measurements) {
    use rand::{RngExt, SeedableRng};
    let model = robocal::model::RobotModel::preset("puma560").unwrap();
    let mut rng = rand::rngs::ChaCha8Rng::seed_from_u64(5);
    let centre = [0.3, 0.8, -0.6, 0.4, 0.9, 0.2];
    let joints: Vec<Vec<f64>> = (0..poses)
        .map(|_| centre.iter().map(|c| c + spread * rng.random_range(-1.0..1.0)).collect())
        .collect();
    let markers = [nalgebra::Vector3::new(50.0, 0.0, 150.0), nalgebra::Vector3::new(-40.0, 60.0, 120.0)];
    let text = robocal::simulation::measurement_csv(&model, &markers, &joints, &[0.0; 6], 0.0, 1);
    let data = robocal::calibration::Measurements::from_csv_str(&text, &model, None).unwrap();
    (model, data)
}

/// A rank-full system with a scaled condition number above 1e6 calibrates, with a warning;
/// one below it without.
#[test]
fn a_badly_conditioned_system_is_warned() {
    use robocal::calibration::{JointParams, Options};
    for (spread, warned) in [(1e-3, false), (1e-7, true)] {
        let (model, data) = clustered(spread, 60);
        let options = Options {
            estimator: robocal::estimation::Estimator::Ols,
            noise: None,
            joints: JointParams::Offsets,
            estimate_base: false,
            estimate_markers: false,
            markers: vec![
                nalgebra::Vector3::new(50.0, 0.0, 150.0),
                nalgebra::Vector3::new(-40.0, 60.0, 120.0),
            ],
            prior: Vec::new(),
            loss: robocal::calibration::Loss::Squared,
            refine: robocal::estimation::RefineOptions::default(),
            gauge: Default::default(),
        };
        let result = robocal::calibration::calibrate(&model, &data, &options).unwrap();
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
