//! The `robocal` command: outputs snapshot-tested, errors and exit codes.

use assert_cmd::Command;

fn robocal() -> Command {
    Command::cargo_bin("robocal").unwrap()
}

/// The README's console block that starts with `start` (`$ robocal ...`, its command over one
/// or more lines ending in `\`): every line it shows but `...` is a line of what `args` print.
pub(crate) fn the_readme_block_is_printed(start: &str, args: &[&str]) {
    let readme = std::fs::read_to_string("README.md").unwrap();
    let at = readme.find(start).unwrap_or_else(|| panic!("the README shows `{start}`"));
    let block = &readme[at..at + readme[at..].find("```").unwrap()];
    let command = block.lines().take_while(|l| l.ends_with('\\')).count() + 1;
    let out = robocal().args(args).output().unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let text = String::from_utf8(out.stdout).unwrap();
    let shown: Vec<&str> =
        block.lines().skip(command).filter(|l| *l != "..." && !l.trim().is_empty()).collect();
    assert!(shown.len() >= 5, "{shown:?}");
    for line in shown {
        assert!(text.lines().any(|l| l == line), "the README shows `{line}`, not in the output:\n{text}");
    }
}

#[test]
fn the_readme_ball_bar_and_forward_kinematics_examples_are_the_real_output() {
    the_readme_block_is_printed(
        "$ robocal calibrate --model puma560 --tool 50,0,150 --data examples/puma560-ballbar.csv",
        &[
            "calibrate",
            "--model",
            "puma560",
            "--tool",
            "50,0,150",
            "--data",
            "examples/puma560-ballbar.csv",
            "--validate",
            "examples/puma560-ballbar-2.csv",
            "--joint-sigma-deg",
            "0.007,0.007,0.007,0.002,0.002,0.002",
        ],
    );
    the_readme_block_is_printed(
        "$ robocal fk --model puma560",
        &["fk", "--model", "puma560", "--q", "0,90,-90,0,0,0"],
    );
}

#[test]
fn the_readme_markers_with_a_ball_bar_example_is_the_real_output() {
    the_readme_block_is_printed(
        "$ robocal calibrate --model puma560 --tool 50,0,150 \\\n    --marker",
        &[
            "calibrate",
            "--model",
            "puma560",
            "--tool",
            "50,0,150",
            "--marker",
            "50,0,150",
            "--marker=-40,60,120",
            "--data",
            "examples/puma560-measurements.csv",
            "--data",
            "examples/puma560-ballbar.csv",
            "--validate",
            "examples/puma560-validation.csv",
            "--validate",
            "examples/puma560-ballbar-2.csv",
            "--joint-sigma-deg",
            "0.007,0.007,0.007,0.002,0.002,0.002",
        ],
    );
}

/// The message of an error in the input or the computation (exit code 1).
fn stderr_of(args: &[&str]) -> String {
    stderr_with_code(args, 1)
}

/// The message of a usage error (exit code 2): flags that clap refuses or that do not fit
/// together.
fn usage_error_of(args: &[&str]) -> String {
    stderr_with_code(args, 2)
}

/// The standard error of `robocal args`, which must exit with `code`.
fn stderr_with_code(args: &[&str], code: i32) -> String {
    let output = robocal().args(args).output().unwrap();
    assert_eq!(output.status.code(), Some(code), "exit code {code}");
    String::from_utf8(output.stderr).unwrap()
}

#[test]
fn fk_prints_the_tool_pose() {
    let output = robocal().args(["fk", "--model", "puma560", "--q", "0,90,-90,0,0,0"]).output().unwrap();
    assert!(output.status.success());
    insta::assert_snapshot!(String::from_utf8(output.stdout).unwrap());
}

#[test]
fn fk_warns_outside_the_limits() {
    let output = robocal().args(["fk", "--model", "puma560", "--q", "0 45 180 0 45 0"]).output().unwrap();
    assert!(output.status.success());
    assert_eq!(String::from_utf8(output.stderr).unwrap(), "warning: joint j3 lies outside its limits\n");
}

#[test]
fn fk_rejects_a_wrong_number_of_joint_values() {
    let message = stderr_of(&["fk", "--model", "puma560", "--q", "0,45"]);
    assert!(message.contains("puma560 has 6 joints, got 2 values"), "{message}");
}

#[test]
fn fk_rejects_a_non_number() {
    let message = usage_error_of(&["fk", "--model", "puma560", "--q", "0,4x5,0,0,0,0"]);
    assert!(message.contains("for '--q <Q>': value 2 `4x5` is not a number"), "{message}");
}

#[test]
fn unknown_model_lists_the_presets() {
    let message = stderr_of(&["model", "show", "puma561"]);
    assert!(message.contains("no model `puma561`: not a preset (puma560, puma560-masses, ur3e, ur5e, ur10e, ur16e, panda, iiwa14, irb120)"), "{message}");
}

#[test]
fn unknown_study_lists_the_embedded_ones() {
    let message = stderr_of(&["simulate", "paper-table3"]);
    assert!(
        message.contains("no study `paper-table3`: not an embedded one (paper-table1, paper-table2, ")
            && message.contains("instruments) and no such file"),
        "{message}"
    );
}

#[test]
fn bad_model_file_is_named_with_the_field() {
    let dir = std::env::temp_dir().join(format!("robocal-cli-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("bad.toml");
    let text = include_str!("../../presets/puma560.toml").replacen("a_mm = 20.3", "a_mm = \"20.3\"", 1);
    std::fs::write(&path, text).unwrap();
    let message = stderr_of(&["model", "show", path.to_str().unwrap()]);
    assert!(message.contains("bad.toml") && message.contains("a_mm"), "{message}");
}

#[test]
fn model_show_prints_a_model_that_reads_back() {
    let output = robocal().args(["model", "show", "puma560"]).output().unwrap();
    let text = String::from_utf8(output.stdout).unwrap();
    let model = robocal::model::RobotModel::from_toml_str(&text).unwrap();
    assert_eq!(model, robocal::model::RobotModel::preset("puma560").unwrap());
}

#[test]
fn usage_errors_exit_with_2() {
    assert_eq!(robocal().args(["fk"]).output().unwrap().status.code(), Some(2));
}

#[test]
fn simulate_writes_tables_csv_and_figures() {
    let out = std::env::temp_dir().join(format!("robocal-simulate-{}", std::process::id()));
    let output =
        robocal().args(["simulate", "paper-table2", "--out", out.to_str().unwrap()]).output().unwrap();
    assert!(output.status.success(), "{}", String::from_utf8_lossy(&output.stderr));
    let folder = out.join("paper-table2");
    let tables = std::fs::read_to_string(folder.join("tables.txt")).unwrap();
    assert!(tables.contains("dE (%) = 100 (E_p[ols] - E_p[wls]) / E_p[ols]"), "{tables}");
    let csv = std::fs::read_to_string(folder.join("samples.csv")).unwrap();
    assert_eq!(csv.lines().count(), 1 + 4 * 96);
    let svg = std::fs::read_to_string(folder.join("improvement-vs-sigma-wls.svg")).unwrap();
    assert!(svg.starts_with("<svg") && svg.contains("dE (%)"));
    assert!(String::from_utf8(output.stdout).unwrap().contains(&tables));
}

#[test]
fn simulate_names_a_bad_study_file() {
    let dir = std::env::temp_dir().join(format!("robocal-cli-study-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("study.toml");
    let text = include_str!("../../presets/paper-table1.toml").replace("seed = 1991", "seed = -1");
    std::fs::write(&path, text).unwrap();
    let message = stderr_of(&["simulate", path.to_str().unwrap()]);
    assert!(message.contains("study.toml") && message.contains("seed"), "{message}");
}

/// The README's calibration (also used by `report.rs`).
pub const CALIBRATE: [&str; 14] = [
    "calibrate",
    "--model",
    "puma560",
    "--data",
    "examples/puma560-measurements.csv",
    "--validate",
    "examples/puma560-validation.csv",
    "--joint-sigma-deg",
    "0.007,0.007,0.007,0.002,0.002,0.002",
    "--sigma-mm",
    "0.01",
    "--marker",
    "50,0,150",
    "--marker=-40,60,120",
];

#[test]
fn calibrate_the_example_report_json_and_model() {
    let dir = std::env::temp_dir().join(format!("robocal-calibrate-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let (json, model) = (dir.join("report.json"), dir.join("calibrated.toml"));
    let mut args = CALIBRATE.to_vec();
    args.extend(["--json", json.to_str().unwrap(), "--out-model", model.to_str().unwrap()]);
    let output = robocal().args(&args).output().unwrap();
    assert!(output.status.success(), "{}", String::from_utf8_lossy(&output.stderr));
    let report = String::from_utf8(output.stdout).unwrap();
    insta::assert_snapshot!(report);
    let json: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    assert_eq!(json["parameters"].as_array().unwrap().len(), 30);
    assert_eq!(json["sets"][1][0], "examples/puma560-validation.csv");
    let (before, after) = (
        json["sets"][1][1]["markers"][0].as_f64().unwrap(),
        json["sets"][1][1]["markers"][1].as_f64().unwrap(),
    );
    assert!(before / after > 5.0, "held out: {before} mm before, {after} mm after");
    // The calibrated model predicts the held-out marker 1 as well as the report says.
    let calibrated =
        robocal::model::RobotModel::from_toml_str(&std::fs::read_to_string(&model).unwrap()).unwrap();
    let data = robocal::io::load_measurements(
        std::path::Path::new("examples/puma560-validation.csv"),
        &calibrated,
        None,
    )
    .unwrap();
    let chain =
        robocal::kinematics::Chain::new(&calibrated).with_errors(&vec![0.0; calibrated.params().len()]);
    let worst = data
        .joints
        .iter()
        .zip(&data.markers)
        .map(|(q, m)| (chain.position(q) - m[0]).norm())
        .fold(0.0, f64::max);
    assert!(worst < 0.5, "calibrated model misses marker 1 by {worst} mm");
}

#[test]
fn calibrate_bad_input_is_named() {
    let mut args = CALIBRATE.to_vec();
    args[4] = "examples/no-such-file.csv";
    assert!(stderr_of(&args).contains("examples/no-such-file.csv: cannot read"));
    let mut wls_without_noise = CALIBRATE[..7].to_vec();
    wls_without_noise.extend(["--estimator", "wls"]);
    assert!(usage_error_of(&wls_without_noise).contains("--estimator wls needs the noise"));
    let mut short_sigma = CALIBRATE.to_vec();
    short_sigma[8] = "0.007,0.007";
    assert!(stderr_of(&short_sigma).contains("--joint-sigma-deg: 2 values for the 6 joints of puma560"));
    let mut bad_marker = CALIBRATE.to_vec();
    bad_marker[12] = "50,0";
    assert!(
        usage_error_of(&bad_marker).contains("'50,0' for '--marker <X,Y,Z>': expected three finite numbers")
    );
    let dir = std::env::temp_dir().join(format!("robocal-calibrate-bad-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("short.csv");
    let text = std::fs::read_to_string("examples/puma560-measurements.csv").unwrap();
    let lines: Vec<&str> = text.lines().take(8).collect();
    std::fs::write(&path, lines.join("\n") + "\n").unwrap();
    let mut few = CALIBRATE[..7].to_vec();
    few[4] = path.to_str().unwrap();
    let message = stderr_of(&few);
    assert!(message.contains("6 poses give 36 equations for 42 parameters"), "{message}");
    let json = dir.join("never.json");
    few.extend(["--json", json.to_str().unwrap()]);
    stderr_of(&few);
    assert!(!json.exists(), "nothing is written when the input is bad");
}

#[test]
fn calibrate_a_urdf_robot_and_write_it_back() {
    let dir = std::env::temp_dir().join(format!("robocal-urdf-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let (urdf, data, out) = (dir.join("arm7.urdf"), dir.join("arm7.csv"), dir.join("calibrated.urdf"));
    let text = super::urdf::arm_urdf();
    std::fs::write(&urdf, &text).unwrap();
    // The nominal arm placed 1 m from the device, measured without noise at 60 poses.
    let mut truth = robocal::model::from_urdf_str(&text, "base", "flange").unwrap();
    truth.base.xyz = nalgebra::Vector3::new(1000.0, 0.0, 0.0);
    let poses: Vec<Vec<f64>> = (0..60)
        .map(|k| {
            truth
                .joints
                .iter()
                .enumerate()
                .map(|(j, joint)| {
                    let u = (((k * 7 + j) as f64) * 12.9898).sin() * 0.5 + 0.5;
                    joint.limits[0] + u * (joint.limits[1] - joint.limits[0])
                })
                .collect()
        })
        .collect();
    let markers = [nalgebra::Vector3::new(30.0, 0.0, 60.0)];
    std::fs::write(&data, robocal::simulation::measurement_csv(&truth, &markers, &poses, &[0.0; 7], 0.0, 1))
        .unwrap();
    let (urdf_s, data_s, out_s) = (urdf.to_str().unwrap(), data.to_str().unwrap(), out.to_str().unwrap());
    let args =
        ["calibrate", "--model", urdf_s, "--data", data_s, "--marker", "30,0,60", "--params", "offsets"];
    let mut full = args.to_vec();
    full.extend(["--out-urdf", out_s]); // the chain from the root link to the only leaf
    let output = robocal().args(&full).output().unwrap();
    assert!(output.status.success(), "{}", String::from_utf8_lossy(&output.stderr));
    let report = String::from_utf8(output.stdout).unwrap();
    assert!(report.contains("shoulder_pan.theta") && report.contains("slide.d"), "{report}");
    let written = std::fs::read_to_string(&out).unwrap();
    let calibrated = robocal::model::from_urdf_str(&written, "measuring_frame", "tool").unwrap();
    assert_eq!(calibrated.dof(), 7);
    assert!((calibrated.joints[0].origin.xyz.x - 1000.0).abs() < 1e-6, "the base is in the written URDF");
}

/// The README's worked calibration is what this version prints, to the last digit: the
/// command is read from the README and run (its output files go to a scratch directory).
#[test]
fn the_readme_calibration_example_is_the_real_output() {
    let readme = std::fs::read_to_string("README.md").unwrap();
    let start = readme.find("$ robocal calibrate --model").expect("the README's calibration example");
    let block = &readme[start..start + readme[start..].find("```").unwrap()];
    let mut lines = block.lines();
    let mut command = String::new();
    for line in lines.by_ref() {
        command.push_str(line.trim_end_matches('\\'));
        if !line.ends_with('\\') {
            break;
        }
    }
    let expected: String = lines.map(|line| format!("{line}\n")).collect();
    let dir = std::env::temp_dir().join(format!("robocal-readme-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let args: Vec<String> = command
        .split_whitespace()
        .skip(2) // `$ robocal`
        .map(|word| match word {
            "report.json" | "calibrated.toml" => dir.join(word).display().to_string(),
            _ => word.to_string(),
        })
        .collect();
    let output = robocal().args(&args).output().unwrap();
    assert!(output.status.success(), "{}", String::from_utf8_lossy(&output.stderr));
    // As a terminal shows it: the files read (standard error), the report, the files written.
    let (stdout, stderr) =
        (String::from_utf8(output.stdout).unwrap(), String::from_utf8(output.stderr).unwrap());
    let (read, wrote) = stderr.split_at(stderr.find("wrote ").unwrap_or(stderr.len()));
    let printed = format!("{read}{stdout}{wrote}");
    // The files written, named as the README's command names them.
    let printed = printed.replace(&format!("{}{}", dir.display(), std::path::MAIN_SEPARATOR), "");
    assert_eq!(printed.trim_end(), expected.trim_end(), "regenerate the README example");
    std::fs::remove_dir_all(&dir).unwrap();
}

/// Joint noise alone leaves no pose's covariance singular: the marker coordinates, which give
/// no sigma, are weighed by the default measurement sigma, and the report says so, whatever
/// the estimator.
#[test]
fn joint_noise_alone_weighs_the_markers_by_the_default_sigma_and_says_so() {
    for (estimator, said) in [
        ("ols", "600 of 600 observations gave no sigma: ols weighs every row alike"),
        ("wls", "600 of 600 observations gave no sigma: weighed by the defaults, 0.01 mm"),
    ] {
        let output = robocal()
            .args([
                "calibrate",
                "--model",
                "puma560",
                "--data",
                "examples/puma560-measurements.csv",
                "--estimator",
                estimator,
                "--joint-sigma-deg",
                "0.007,0.007,0.007,0.002,0.002,0.002",
            ])
            .output()
            .unwrap();
        assert!(output.status.success(), "{}", String::from_utf8_lossy(&output.stderr));
        let text = String::from_utf8(output.stdout).unwrap();
        assert!(text.contains(&format!("100 poses, 2 markers, {estimator} (")), "{text}");
        assert!(text.contains(said), "{text}");
    }
}

/// `--markers` picks the fitted markers by number; `--marker` positions are given for the
/// file's markers, the k-th for marker k, fitted or not.
#[test]
fn markers_chosen_with_positions_for_every_marker_of_the_file() {
    // the example's model, data and two markers, without its validation file and noise
    let example = [&CALIBRATE[..5], &CALIBRATE[11..]].concat();
    let output = robocal().args([&example[..], &["--markers", "1"]].concat()).output().unwrap();
    assert!(output.status.success(), "{}", String::from_utf8_lossy(&output.stderr));
    assert!(String::from_utf8(output.stdout).unwrap().contains("100 poses, 1 marker,"));
    let message = stderr_of(&[&example[..], &["--marker=1,2,3"]].concat());
    assert!(
        message.contains("3 --marker given, the files (examples/puma560-measurements.csv) have 2 markers"),
        "{message}"
    );
    // A held-out file whose markers `--markers` names none of is refused, naming it.
    let dir = std::env::temp_dir().join(format!("robocal-cli-markers-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let first = dir.join("marker1.csv");
    crate::write_first_marker_only("examples/puma560-validation.csv", &first);
    let held_out = first.display().to_string();
    let message = stderr_of(&[&example[..], &["--markers", "2", "--validate", &held_out]].concat());
    assert!(message.contains(&format!("{held_out}: --markers [2] names none of its markers")), "{message}");
    let _ = std::fs::remove_dir_all(&dir);
}

/// Output piped into a reader that stops early ends the command quietly (SIGPIPE, as for other
/// Unix tools), never with a panic.
#[cfg(unix)]
#[test]
fn a_closed_pipe_ends_the_command_quietly() {
    use std::os::unix::process::ExitStatusExt;
    let mut child = std::process::Command::new(env!("CARGO_BIN_EXE_robocal"))
        // about 100 kB of poses on standard output, more than a pipe holds
        .args(["plan", "--model", "puma560", "--points", "1500", "--candidates", "1500"])
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    drop(child.stdout.take()); // the reader goes away before anything is read
    let output = child.wait_with_output().unwrap();
    let stderr = String::from_utf8(output.stderr).unwrap();
    assert!(!stderr.contains("panicked"), "{stderr}");
    assert!(output.status.success() || output.status.signal() == Some(libc_sigpipe()), "{:?}", output.status);
}

/// SIGPIPE's number on Linux and the BSDs.
#[cfg(unix)]
fn libc_sigpipe() -> i32 {
    13
}

/// `--prior` and `--loss` on the example: the report gives the prior SDs and their ratios and
/// the robust fit's verdict; a bad entry is a usage error naming it.
#[test]
fn calibrate_with_priors_and_a_robust_loss() {
    let output = robocal()
        .args([
            "calibrate",
            "--model",
            "puma560",
            "--data",
            "examples/puma560-measurements.csv",
            "--marker",
            "50,0,150",
            "--marker=-40,60,120",
            "--prior",
            "machined",
            "--loss",
            "huber",
        ])
        .output()
        .unwrap();
    assert!(output.status.success(), "{}", String::from_utf8_lossy(&output.stderr));
    let text = String::from_utf8(output.stdout).unwrap();
    assert!(text.contains("prior SD  SD ratio"), "{text}");
    assert!(text.contains("parameters estimated with their priors; the data alone: rank"), "{text}");
    assert!(text.contains("robust loss huber:1.345: 0 poses weighted below 0.1"), "{text}");
    assert!(!text.contains("held fixed"), "every joint parameter has a prior: {text}");
    let bad =
        usage_error_of(&["calibrate", "--model", "puma560", "--data", "d.csv", "--prior", "j*.a=5inch"]);
    assert!(bad.contains("prior `j*.a=5inch`: unknown unit `inch`"), "{bad}");
    // A plain number is a compliance's: the PUMA has none named so.
    let data = ["calibrate", "--model", "puma560", "--data", "examples/puma560-measurements.csv"];
    let wrong = stderr_of(
        &[&data[..], &["--marker", "50,0,150", "--marker=-40,60,120", "--prior", "j*.a=0.5"]].concat(),
    );
    assert!(wrong.contains("prior `j*.a=0.5`: no compliance parameter matches `j*.a`"), "{wrong}");
}

/// `calibrate --select cv` prints the path and the selected set, writes them in the JSON and
/// adds the path's figure; a `--hold` or `--keep` name that matches no parameter is an error.
#[test]
fn calibrate_select_prints_and_writes_its_path() {
    let dir = std::env::temp_dir().join(format!("robocal-select-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let (json, figures) = (dir.join("report.json"), dir.join("figures"));
    let arm7: Vec<&str> =
        ["calibrate"].iter().chain(&super::nested::ARM7).chain(&["--params", "joint*.*"]).copied().collect();
    let mut args = arm7.clone();
    let page = dir.join("report.html");
    args.extend(["--select", "cv", "--json", json.to_str().unwrap(), "--figures", figures.to_str().unwrap()]);
    args.extend(["--html", page.to_str().unwrap()]);
    let output = robocal().args(&args).output().unwrap();
    assert!(output.status.success(), "{}", String::from_utf8_lossy(&output.stderr));
    let text = String::from_utf8(output.stdout).unwrap();
    assert!(text.contains(
        "parameter selection: forward selection by 5-fold cross-validation, one-standard-error rule"
    ));
    assert!(text.contains("    0  no joint parameter            1.0599 ± 0.1193\n"), "{text}");
    assert!(text.contains("   13  joint3.x                      0.3867 ± 0.0179  <- chosen\n"), "{text}");
    assert!(
        text.contains(
            "after:     ols: the joint parameters --select cv chose, with the base and the markers"
        )
    );
    let report: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    let selection = &report["selection"];
    assert_eq!((selection["criterion"].as_str(), selection["folds"].as_u64()), (Some("cv"), Some(5)));
    assert_eq!(selection["chosen"], 13);
    assert_eq!(selection["selected"].as_array().unwrap().len(), 13);
    assert_eq!(selection["steps"][1]["parameter"], "joint2.rx");
    assert!(std::fs::read_to_string(figures.join("selection-path.svg")).unwrap().contains("<svg"));
    assert!(std::fs::read_to_string(&page).unwrap().contains("<figure id=\"selection-path.svg\">"));
    std::fs::remove_dir_all(&dir).unwrap();

    for flag in ["--hold", "--keep"] {
        let mut args = arm7.clone();
        args.extend([flag, "joint9.x"]);
        let message = stderr_of(&args);
        assert!(
            message.contains(
                "error: --params, --hold, --keep or --per-session: no parameter matches `joint9.x`"
            ),
            "{message}"
        );
    }
}

/// One command: `calibrate` of a ball bar's file is what `calibrate-observations` printed, and
/// the old names remain for one release as aliases that say what to use instead (on standard
/// error, the report unchanged on standard output).
#[test]
fn the_old_calibration_commands_are_aliases_of_calibrate() {
    let args = ["--model", "puma560", "--tool", "50,0,150", "--data", "examples/puma560-ballbar.csv"];
    let run = |command: &str| robocal().arg(command).args(args).output().unwrap();
    let (new, old) = (run("calibrate"), run("calibrate-observations"));
    assert!(new.status.success() && old.status.success(), "{}", String::from_utf8_lossy(&old.stderr));
    assert_eq!(new.stdout, old.stdout);
    let stdout = String::from_utf8(new.stdout).unwrap();
    assert!(
        stdout.starts_with("calibration of puma560 from examples/puma560-ballbar.csv: 150 observations"),
        "{stdout}"
    );
    let note = String::from_utf8(old.stderr).unwrap();
    assert!(note.contains("`robocal calibrate-observations` is now `robocal calibrate`"), "{note}");
    // Each file says what its header made of it.
    let said = String::from_utf8(new.stderr).unwrap();
    assert!(!said.contains("is now"), "{said}");
    assert!(
        said.contains("examples/puma560-ballbar.csv: read 150 distances to a fixed point at 150 poses"),
        "{said}"
    );
    let tree = robocal()
        .args(["calibrate-tree", "--model", "presets/torso.urdf", "--data", "examples/torso/views.csv"])
        .output()
        .unwrap();
    assert!(tree.status.success());
    assert!(
        String::from_utf8(tree.stderr)
            .unwrap()
            .contains("`robocal calibrate-tree` is now `robocal calibrate --tips ...`")
    );
}

/// `calibrate --select bic --folds 5` of a ball bar's file prints the path and the parameters it
/// chose, calibrates those, and cross-validates nested (the selection made again in each fold);
/// the JSON has the path.
#[test]
fn calibrate_selects_on_observation_files() {
    let dir = std::env::temp_dir().join(format!("robocal-select-kinds-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let json = dir.join("r.json");
    let args =
        ["calibrate", "--model", "puma560", "--tool", "50,0,150", "--data", "examples/puma560-ballbar.csv"];
    let mut args = args.to_vec();
    args.extend(["--select", "bic", "--folds", "5", "--json", json.to_str().unwrap()]);
    let out = robocal().args(&args).output().unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let text = String::from_utf8(out.stdout).unwrap();
    assert!(text.contains("parameter selection: forward selection by BIC\n"), "{text}");
    assert!(text.contains("5-fold cross-validation, nested (mm)"), "{text}");
    let report: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    let selected: Vec<&str> =
        report["selection"]["selected"].as_array().unwrap().iter().map(|v| v.as_str().unwrap()).collect();
    assert_eq!(report["selection"]["criterion"], "bic");
    assert!(!selected.is_empty() && selected.len() < 18, "{selected:?}");
    let estimated: Vec<&str> = (report["parameters"].as_array().unwrap().iter())
        .map(|p| p["name"].as_str().unwrap())
        .filter(|n| n.starts_with('j'))
        .collect();
    assert_eq!(estimated, selected, "the calibration is of the parameters chosen");
    std::fs::remove_dir_all(&dir).unwrap();
}

/// `calibrate` refuses, before any work, flags that do not go together on observation files,
/// naming them and saying what holds instead (exit code 2, nothing written).
#[test]
fn calibrate_refuses_flags_that_do_not_go_together_on_observation_files() {
    let out = robocal()
        .args(["calibrate", "--model", "puma560", "--data", "examples/puma560-ballbar.csv"])
        .args(["--noise", "examples/puma560-noise.toml", "--sigma-mm", "0.01"])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    let stderr = String::from_utf8(out.stderr).unwrap();
    assert!(stderr.contains("--noise gives the joint noise and the measurement sigmas"), "{stderr}");
    let out = robocal()
        .args([
            "calibrate",
            "--model",
            "puma560",
            "--data",
            "examples/puma560-ballbar.csv",
            "--data",
            "no-such.csv",
        ])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(1));
    assert!(String::from_utf8(out.stderr).unwrap().contains("no-such.csv"));
}

/// `--joint-sigma-deg` reads one value per joint or one for every joint, the same for a marker
/// file and an observation file (one reader of the flag), and names the joints when the count
/// is neither.
#[test]
fn one_joint_sigma_is_every_joints() {
    let stdout = |args: &[&str]| {
        let out = robocal().args(args).output().unwrap();
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
        String::from_utf8(out.stdout).unwrap()
    };
    let mut ball_bar = crate::kinds_fgls::BALL_BAR[..7].to_vec();
    ball_bar.extend(["--joint-sigma-deg", ""]);
    for args in [CALIBRATE.to_vec(), ball_bar] {
        let sigma_at = args.iter().position(|a| *a == "--joint-sigma-deg").unwrap() + 1;
        let (mut one, mut six) = (args.clone(), args.clone());
        one[sigma_at] = "0.005";
        six[sigma_at] = "0.005,0.005,0.005,0.005,0.005,0.005";
        let (one, six) = (stdout(&one), stdout(&six));
        assert!(one.contains("after"), "{one}");
        assert_eq!(one, six);
        let mut three = args.clone();
        three[sigma_at] = "0.005,0.005,0.005";
        let message = stderr_of(&three);
        assert!(
            message
                .contains("--joint-sigma-deg: 3 values for the 6 joints of puma560 (j1, j2, j3, j4, j5, j6)")
                && message.contains("give one per joint or one for all"),
            "{message}"
        );
    }
}
