//! The command line's conventions: results on standard output, progress and "wrote ..." on
//! standard error, `--quiet`, shell completions, the manual pages, help that names every
//! embedded study.

use assert_cmd::Command;
use std::path::{Path, PathBuf};

/// A fresh scratch folder for the test `name`.
fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("robocal-conventions-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// `robocal args` run in `dir`, which must succeed: its standard output and standard error.
fn run_in(dir: &Path, args: &[&str]) -> (String, String) {
    let output = Command::cargo_bin("robocal").unwrap().current_dir(dir).args(args).output().unwrap();
    let text = |b: Vec<u8>| String::from_utf8(b).unwrap();
    let (stdout, stderr) = (text(output.stdout), text(output.stderr));
    assert!(output.status.success(), "robocal {args:?}:\n{stdout}\n{stderr}");
    (stdout, stderr)
}

/// A small estimator study (the paper's Table 2 with 2 x 2 runs of one case, 50 test points).
fn small_study(dir: &Path) -> PathBuf {
    let text = include_str!("../../presets/paper-table2.toml");
    let text = text[..text.find("[[reference]]").unwrap()]
        .replace("point_sets = 6", "point_sets = 2")
        .replace("runs_per_set = 16", "runs_per_set = 2")
        .replace("test_points = 1000", "test_points = 50")
        .replace("sigma_me_mm = [0.0, 0.025, 0.05, 0.1]", "sigma_me_mm = [0.0]");
    let path = dir.join("small.toml");
    std::fs::write(&path, text).unwrap();
    path
}

/// Commands that print a result and write files: each one's arguments, what its standard
/// output holds, and the start of what it says on standard error.
fn writing_commands(dir: &Path) -> Vec<(Vec<String>, &'static str, &'static str)> {
    let study = small_study(dir).display().to_string();
    let examples = |name: &str| std::fs::canonicalize(name).unwrap().display().to_string();
    let owned = |args: &[&str]| args.iter().map(|a| a.to_string()).collect::<Vec<_>>();
    vec![
        (
            owned(&["simulate", &study, "--out", "out"]),
            "dE (%) = 100 (E_p[ols] - E_p[wls]) / E_p[ols]",
            "wrote ",
        ),
        (
            owned(&[
                "plan",
                "--model",
                "puma560",
                "--points",
                "8",
                "--candidates",
                "100",
                "--out",
                "poses.csv",
            ]),
            "planned 8 poses of puma560 from 100 candidates",
            "wrote 8 poses to poses.csv",
        ),
        (
            owned(&[
                "repeatability",
                "--model",
                "puma560",
                "--data",
                &examples("examples/puma560-repeatability.csv"),
                "--out",
                "noise.toml",
            ]),
            "repeatability of puma560 from",
            "\nwrote noise.toml",
        ),
        (
            owned(&[
                "calibrate",
                "--model",
                "puma560",
                "--data",
                &examples("examples/puma560-measurements.csv"),
                "--marker",
                "50,0,150",
                "--marker=-40,60,120",
                "--json",
                "report.json",
            ]),
            "calibration of puma560 from",
            "wrote report.json",
        ),
        (owned(&["man", "--out", "man"]), "", "wrote 19 manual pages to man"),
    ]
}

/// Every command that writes files prints its result on standard output and says what it
/// wrote on standard error only; with `--quiet` (before or after the command), the same
/// standard output and nothing on standard error.
#[test]
fn results_go_to_standard_output_and_wrote_to_standard_error_unless_quiet() {
    let dir = scratch("streams");
    for (args, result, said) in writing_commands(&dir) {
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        let (stdout, stderr) = run_in(&dir, &args);
        assert!(stdout.contains(result), "robocal {args:?} prints its result:\n{stdout}");
        assert!(!stdout.contains("wrote"), "robocal {args:?}: `wrote` on standard output:\n{stdout}");
        assert!(stderr.contains(said), "robocal {args:?} says `{said}` on standard error:\n{stderr}");
        for quiet in [[&["--quiet"], &args[..]].concat(), [&args[..], &["-q"]].concat()] {
            let (quiet_stdout, quiet_stderr) = run_in(&dir, &quiet);
            assert_eq!(quiet_stdout, stdout, "robocal {quiet:?}: the same results");
            assert_eq!(quiet_stderr, "", "robocal {quiet:?} says nothing");
        }
    }
    assert!(dir.join("man/robocal-calibrate.1").is_file() && dir.join("man/robocal-model-show.1").is_file());
    std::fs::remove_dir_all(&dir).unwrap();
}

/// When the result is a file's contents on standard output (plan's poses), the summary goes to
/// standard error, and `--quiet` leaves it out; warnings stay.
#[test]
fn a_summary_beside_data_on_standard_output_goes_to_standard_error_unless_quiet() {
    let dir = scratch("summary");
    let plan = ["plan", "--model", "puma560", "--points", "8", "--candidates", "100"];
    let (stdout, stderr) = run_in(&dir, &plan);
    assert!(
        stdout.starts_with("# units: joints=deg, lengths=mm\n# robocal plan --model puma560"),
        "{stdout}"
    );
    assert!(stderr.starts_with("planned 8 poses of puma560"), "{stderr}");
    let (quiet_stdout, quiet_stderr) = run_in(&dir, &[&["-q"], &plan[..]].concat());
    assert_eq!((quiet_stdout, quiet_stderr.as_str()), (stdout, ""));
    let (_, warning) = run_in(&dir, &["fk", "--quiet", "--model", "puma560", "--q", "0 45 180 0 45 0"]);
    assert_eq!(warning, "warning: joint j3 lies outside its limits\n");
    std::fs::remove_dir_all(&dir).unwrap();
}

/// `robocal completions SHELL` prints a script for bash, zsh and fish that knows the commands
/// and their flags; bash's parses (`bash -n`) where bash is installed.
#[test]
fn completions_for_bash_zsh_and_fish() {
    let dir = scratch("completions");
    for (shell, start) in [("bash", "_robocal() {"), ("zsh", "#compdef robocal"), ("fish", "")] {
        let (script, stderr) = run_in(&dir, &["completions", shell]);
        assert!(script.starts_with(start), "{shell}:\n{}", &script[..script.len().min(200)]);
        for word in ["per-session", "quiet", "joint-sigma-deg", "ur-kinematics"] {
            assert!(script.contains(word), "{shell}: `{word}` completed");
        }
        assert_eq!(stderr, "");
        let path = dir.join(format!("robocal.{shell}"));
        std::fs::write(&path, &script).unwrap();
        if shell == "bash"
            && let Ok(status) = std::process::Command::new("bash").arg("-n").arg(&path).status()
        {
            assert!(status.success(), "bash -n {}", path.display());
        }
    }
    let output = Command::cargo_bin("robocal").unwrap().args(["completions", "tcsh"]).output().unwrap();
    assert_eq!(output.status.code(), Some(2), "an unknown shell is a usage error");
    std::fs::remove_dir_all(&dir).unwrap();
}

/// `robocal man` prints the top page as roff, naming every command.
#[test]
fn man_prints_the_manual_page() {
    let dir = scratch("man");
    let (page, _) = run_in(&dir, &["man"]);
    assert!(page.contains(".TH robocal 1"), "{page}");
    for command in ["calibrate", "simulate", "completions", "model"] {
        assert!(page.contains(&format!("robocal\\-{command}(1)")), "`{command}` in\n{page}");
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

/// `simulate --help` names every embedded study, the instrument studies included.
#[test]
fn simulate_help_names_every_embedded_study() {
    let dir = scratch("help");
    let (help, _) = run_in(&dir, &["simulate", "--help"]);
    let names = robocal::simulation::STUDIES.iter().chain(robocal::simulation::INSTRUMENT_STUDIES);
    for (name, _) in names {
        assert!(help.contains(name), "`{name}` in\n{help}");
    }
    std::fs::remove_dir_all(&dir).unwrap();
}
