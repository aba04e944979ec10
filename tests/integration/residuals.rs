//! One pipeline for every kind (issue #23): `calibrate --poses-csv` and `--figures` for
//! observation files and a tree's views, and `evaluate` of a tree's views; a written model
//! (an observation file's `--out-model`, a tree's `--out-dir`) re-scores its training file as
//! its calibration scored it.

use std::path::{Path, PathBuf};

/// A fresh scratch folder for test `name`.
fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("robocal-residuals-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// `robocal args`, which must succeed: its standard output.
fn robocal(args: &[&str]) -> String {
    let output = assert_cmd::Command::cargo_bin("robocal").unwrap().args(args).output().unwrap();
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(output.status.success(), "robocal {}: {stderr}", args.join(" "));
    String::from_utf8(output.stdout).unwrap()
}

/// `path` as a `&str`.
fn s(path: &Path) -> &str {
    path.to_str().unwrap()
}

/// A JSON file.
fn json(path: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap()
}

/// The CSV at `path`: its header, and its rows as cells by column name.
fn csv(text: &str) -> (String, Vec<std::collections::HashMap<String, String>>) {
    let mut lines = text.lines();
    let header = lines.next().unwrap().to_string();
    let names: Vec<&str> = header.split(',').collect();
    let rows = lines
        .map(|line| {
            let cells: Vec<&str> = line.split(',').collect();
            assert_eq!(cells.len(), names.len(), "{line}");
            names.iter().zip(cells).map(|(n, c)| (n.to_string(), c.to_string())).collect()
        })
        .collect();
    (header, rows)
}

/// The files in `dir`, sorted, each SVG parsed (roxmltree) and drawn with at least one shape.
fn figures(dir: &Path) -> Vec<String> {
    let mut names: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    for name in &names {
        let text = std::fs::read_to_string(dir.join(name)).unwrap();
        let document = roxmltree::Document::parse(&text).unwrap_or_else(|e| panic!("{name}: {e}"));
        let shapes = document
            .descendants()
            .filter(|n| matches!(n.tag_name().name(), "rect" | "circle" | "polyline" | "path"));
        assert!(shapes.count() > 3, "{name}: nothing drawn");
    }
    names
}

/// The RMS of the cells `column` of `rows`.
fn rms(rows: &[&std::collections::HashMap<String, String>], column: &str) -> f64 {
    let values: Vec<f64> = rows.iter().map(|r| r[column].parse::<f64>().unwrap()).collect();
    (values.iter().map(|v| v * v).sum::<f64>() / values.len() as f64).sqrt()
}

/// `(a - b) / b`.
fn relative(a: f64, b: f64) -> f64 {
    ((a - b) / b).abs()
}

const BALL_BAR: &str = "examples/puma560-ballbar.csv";
const BALL_BAR_2: &str = "examples/puma560-ballbar-2.csv";

/// A ball bar's calibration writes one row per observation, training and held out, each at
/// its file's line and joint values, and the residual figures with the prior's scale curve.
#[test]
fn a_ball_bar_writes_a_row_per_observation_and_its_figures() {
    let dir = scratch("ball-bar");
    let (poses, folder, report) = (dir.join("residuals.csv"), dir.join("figures"), dir.join("report.json"));
    let args = ["calibrate", "-q", "--model", "puma560", "--tool", "50,0,150", "--data", BALL_BAR];
    let mut args = args.to_vec();
    args.extend(["--validate", BALL_BAR_2, "--prior", "auto", "--json", s(&report)]);
    args.extend(["--poses-csv", s(&poses), "--figures", s(&folder)]);
    robocal(&args);
    let (header, rows) = csv(&std::fs::read_to_string(&poses).unwrap());
    assert_eq!(
        header,
        "set,file,line,kind,pose,pose_b,j1_deg,j2_deg,j3_deg,j4_deg,j5_deg,j6_deg,\
         before_mm,after_mm,before_deg,after_deg,whitened,flagged"
    );
    let training: Vec<_> = rows.iter().filter(|r| r["set"] == "training").collect();
    let held_out: Vec<_> = rows.iter().filter(|r| r["set"] == BALL_BAR_2).collect();
    assert_eq!((training.len(), held_out.len(), rows.len()), (150, 60, 210));
    assert!(
        rows.iter().all(|r| r["kind"] == "point" && r["before_deg"].is_empty() && r["after_deg"].is_empty())
    );
    // Each row where its file has it: line L is the file's (L - 2)-th pose, at its joint values.
    let file: Vec<String> = std::fs::read_to_string(BALL_BAR).unwrap().lines().map(String::from).collect();
    for r in &training {
        let line: usize = r["line"].parse().unwrap();
        assert_eq!(r["pose"], (line - 2).to_string());
        let j2: f64 = file[line - 1].split(',').nth(1).unwrap().parse().unwrap();
        assert!((r["j2_deg"].parse::<f64>().unwrap() - j2).abs() < 1e-9, "line {line}");
    }
    // The rows' RMS after is the report's.
    let scored = json(&report);
    assert!(
        relative(rms(&training, "after_mm"), scored["sets"][0][1]["lengths"][1].as_f64().unwrap()) < 1e-9
    );
    assert!(
        relative(rms(&held_out, "before_mm"), scored["sets"][1][1]["lengths"][0].as_f64().unwrap()) < 1e-9
    );
    let mut expected: Vec<String> = (1..=6).map(|j| format!("error-vs-j{j}.svg")).collect();
    expected.extend(
        [
            "errors-by-observation-examples-puma560-ballbar-2-csv.svg",
            "errors-by-observation-training.svg",
            "histogram.svg",
            "prior-scale.svg",
        ]
        .map(String::from),
    );
    expected.sort();
    assert_eq!(figures(&folder), expected);
    let bars = std::fs::read_to_string(folder.join("errors-by-observation-training.svg")).unwrap();
    assert!(bars.contains("before and after: one scale, 0 to"), "before and after on one scale");
    // `-`: the rows on standard output.
    let out = robocal(&[
        "calibrate",
        "-q",
        "--model",
        "puma560",
        "--tool",
        "50,0,150",
        "--data",
        BALL_BAR,
        "--poses-csv",
        "-",
    ]);
    assert!(
        out.starts_with("set,file,line,kind,pose,pose_b,j1_deg"),
        "standard output the rows alone: {out}"
    );
    assert_eq!(out.lines().filter(|l| l.starts_with("training,")).count(), 150);
    std::fs::remove_dir_all(&dir).unwrap();
}

/// A camera's views: its angle rows in degrees, its length rows in mm, a figure of each.
#[test]
fn a_camera_file_writes_its_angles_in_degrees_and_its_lengths_in_mm() {
    let dir = scratch("camera");
    let (poses, folder) = (dir.join("residuals.csv"), dir.join("figures"));
    robocal(&[
        "calibrate",
        "-q",
        "--model",
        "puma560",
        "--data",
        "examples/puma560-camera.csv",
        "--poses-csv",
        s(&poses),
        "--figures",
        s(&folder),
    ]);
    let (_, rows) = csv(&std::fs::read_to_string(&poses).unwrap());
    let rows_in_file = std::fs::read_to_string("examples/puma560-camera.csv").unwrap().lines().count() - 2;
    assert_eq!(rows.len(), rows_in_file * 6, "six numbers a view");
    for r in &rows {
        let angle = ["camera rx", "camera ry", "camera rz"].contains(&r["kind"].as_str());
        assert_eq!(r["after_deg"].is_empty(), !angle, "{r:?}");
        assert_eq!(r["after_mm"].is_empty(), angle, "{r:?}");
    }
    let names = figures(&folder);
    for name in [
        "errors-by-observation-training.svg",
        "errors-by-observation-training-deg.svg",
        "histogram.svg",
        "histogram-deg.svg",
    ] {
        assert!(names.contains(&name.to_string()), "{name}: {names:?}");
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

/// An observation file's written model re-scores its training file as its calibration scored
/// it, to 1e-9.
#[test]
fn an_observation_files_written_model_rescores_its_training_file() {
    let dir = scratch("rescore-ball-bar");
    let (model, calibrated, evaluated) = (dir.join("model.toml"), dir.join("c.json"), dir.join("e.json"));
    robocal(&[
        "calibrate",
        "-q",
        "--model",
        "puma560",
        "--tool",
        "50,0,150",
        "--data",
        BALL_BAR,
        "--out-model",
        s(&model),
        "--json",
        s(&calibrated),
    ]);
    let (poses, folder, page) = (dir.join("rows.csv"), dir.join("figures"), dir.join("page.html"));
    let text =
        robocal(&["evaluate", "-q", "--model", s(&model), "--data", BALL_BAR, "--json", s(&evaluated)]);
    // Why its figure is not calibrate --validate's: the set-up is fitted on the file.
    assert!(
        text.contains("set-up fitted (fixed points") && text.contains("calibrated set-up instead"),
        "{text}"
    );
    robocal(&["evaluate", "-q", "--model", s(&model), "--data", BALL_BAR, "--poses-csv", s(&poses)]);
    robocal(&["evaluate", "-q", "--model", s(&model), "--data", BALL_BAR, "--figures", s(&folder)]);
    robocal(&["evaluate", "-q", "--model", s(&model), "--data", BALL_BAR, "--html", s(&page)]);
    let after = json(&calibrated)["sets"][0][1]["lengths"][1].as_f64().unwrap();
    let again = json(&evaluated)["observations"][0][1]["lengths"][1].as_f64().unwrap();
    assert!(relative(again, after) < 1e-9, "re-scored {again} mm, calibrated {after} mm");
    // Its rows, one per observation as it stands, their RMS the score; its figures; its page
    // with them.
    let (_, rows) = csv(&std::fs::read_to_string(&poses).unwrap());
    let rows: Vec<_> = rows.iter().collect();
    assert_eq!(rows.len(), 150);
    assert!(rows.iter().all(|r| r["set"] == BALL_BAR && r["before_mm"] == r["after_mm"]), "as it stands");
    assert!(relative(rms(&rows, "after_mm"), after) < 1e-9);
    let mut expected: Vec<String> = (1..=6).map(|j| format!("error-vs-j{j}.svg")).collect();
    expected.extend(
        ["errors-by-observation-examples-puma560-ballbar-csv.svg", "histogram.svg"].map(String::from),
    );
    expected.sort();
    assert_eq!(figures(&folder), expected);
    let html = std::fs::read_to_string(&page).unwrap();
    let figures_section = html.split("<section id=\"figures\"").nth(1).expect("a figures section");
    assert_eq!(figures_section.matches("<svg").count(), 8, "the eight figures on the page");
    // Every observation on the page, as it stands: one stage, a row each below the head.
    let poses_section = html.split("<section id=\"poses\"").nth(1).expect("a poses section");
    assert!(poses_section.contains("<th>as it stands mm</th>"), "{poses_section}");
    assert_eq!(poses_section.split("</section>").next().unwrap().matches("<tr").count(), 151);
    // Marker and observation files together: one run, one page, their rows side by side.
    let markers = dir.join("one-marker.csv");
    crate::write_first_marker_only("examples/puma560-measurements.csv", &markers);
    robocal(&["evaluate", "-q", "--model", s(&model), "--data", s(&markers)]);
    let out = assert_cmd::Command::cargo_bin("robocal")
        .unwrap()
        .args(["evaluate", "--model", s(&model), "--data", BALL_BAR, "--data", s(&markers)])
        .args(["--html", s(&page), "--poses-csv", s(&poses)])
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let (_, rows) = csv(&std::fs::read_to_string(&poses).unwrap());
    let sets: Vec<&str> = rows.iter().map(|r| r["set"].as_str()).collect();
    assert_eq!(sets.iter().filter(|&&set| set == BALL_BAR).count(), 150);
    assert_eq!(
        sets.iter().filter(|&&set| set == s(&markers)).count(),
        3 * 100,
        "marker 1's x, y, z at 100 poses"
    );
    let html = std::fs::read_to_string(&page).unwrap();
    assert!(html.contains(BALL_BAR) && html.contains(s(&markers)), "both files on the page");
    std::fs::remove_dir_all(&dir).unwrap();
}

const TORSO: &str = "presets/torso.urdf";
const VIEWS: &str = "examples/torso/views.csv";
const VIEWS_2: &str = "examples/torso/views-2.csv";

/// A tree's calibration writes one row per view (its position error in mm, its rotation's in
/// deg) and the residual figures; `evaluate` of the branches it wrote re-scores its training
/// views as the calibration scored them after, and of the URDF as it stands before, to 1e-9.
#[test]
fn a_tree_writes_a_row_per_view_and_its_branches_rescore_its_views() {
    let dir = scratch("tree");
    let (poses, folder, report, out) =
        (dir.join("views.csv"), dir.join("figures"), dir.join("report.json"), dir.join("branches"));
    robocal(&[
        "calibrate",
        "-q",
        "--model",
        TORSO,
        "--data",
        VIEWS,
        "--validate",
        VIEWS_2,
        "--json",
        s(&report),
        "--poses-csv",
        s(&poses),
        "--figures",
        s(&folder),
        "--out-dir",
        s(&out),
    ]);
    let (header, rows) = csv(&std::fs::read_to_string(&poses).unwrap());
    assert!(header.starts_with("set,file,line,kind,pose,pose_b,torso_deg,head_pan_deg,"), "{header}");
    assert!(header.ends_with(",r_wrist_pitch_deg,before_mm,after_mm,before_deg,after_deg,whitened,flagged"));
    let training: Vec<_> = rows.iter().filter(|r| r["set"] == "training").collect();
    let held_out: Vec<_> = rows.iter().filter(|r| r["set"] == VIEWS_2).collect();
    assert_eq!((training.len(), held_out.len(), rows.len()), (120, 80, 200));
    assert!(rows.iter().all(|r| r["kind"] == "view" && !r["after_deg"].is_empty()));
    let calibrated = json(&report);
    let score =
        |set: usize, what: &str, stage: usize| calibrated["sets"][set][1][what][stage].as_f64().unwrap();
    assert!(relative(rms(&training, "after_mm"), score(0, "view_position", 1)) < 1e-9);
    assert!(relative(rms(&held_out, "after_deg"), score(1, "view_rotation", 1)) < 1e-9);
    let names = figures(&folder);
    for name in [
        "errors-by-view-training.svg",
        "errors-by-view-training-deg.svg",
        "errors-by-view-examples-torso-views-2-csv.svg",
        "histogram.svg",
        "histogram-deg.svg",
        "error-vs-torso.svg",
        "error-vs-r-wrist-pitch.svg",
    ] {
        assert!(names.contains(&name.to_string()), "{name}: {names:?}");
    }
    assert_eq!(names.len(), 6 + 15, "{names:?}");
    // The written branches re-score the training views as calibrated (and the tree written as
    // URDF); the URDF as it stands, as before calibration.
    let evaluated = dir.join("evaluated.json");
    let text = robocal(&[
        "evaluate",
        "--model",
        TORSO,
        "--branches",
        s(&out),
        "--data",
        VIEWS,
        "--json",
        s(&evaluated),
        "--poses-csv",
        s(&poses),
        "--figures",
        s(&dir.join("evaluated")),
    ]);
    assert!(
        text.contains("residuals as it stands:") && text.contains("view file: each file's cameras"),
        "{text}"
    );
    let (_, rows) = csv(&std::fs::read_to_string(&poses).unwrap());
    assert_eq!(rows.len(), 120);
    assert!(rows.iter().all(|r| r["set"] == VIEWS && r["before_mm"] == r["after_mm"]), "as it stands");
    let names = figures(&dir.join("evaluated"));
    assert_eq!(names.len(), 4 + 15, "{names:?}");
    let bars =
        std::fs::read_to_string(dir.join("evaluated/errors-by-view-examples-torso-views-csv.svg")).unwrap();
    assert!(bars.contains("as it stands: 0 to") && !bars.contains("before"), "one stage");
    let again = json(&evaluated);
    let view = |what: &str| again["observations"][0][1][what][1].as_f64().unwrap();
    assert!(
        relative(view("view_position"), score(0, "view_position", 1)) < 1e-9,
        "{} mm",
        view("view_position")
    );
    assert!(
        relative(view("view_rotation"), score(0, "view_rotation", 1)) < 1e-9,
        "{} deg",
        view("view_rotation")
    );
    // The tree written as URDF re-scores them too.
    let urdf = dir.join("torso-calibrated.urdf");
    robocal(&["calibrate", "-q", "--model", TORSO, "--data", VIEWS, "--out-urdf", s(&urdf)]);
    robocal(&["evaluate", "--model", s(&urdf), "--data", VIEWS, "--json", s(&evaluated)]);
    let from_urdf = json(&evaluated);
    for (what, stage) in [("view_position", 1), ("view_rotation", 1)] {
        let again = from_urdf["observations"][0][1][what][stage].as_f64().unwrap();
        assert!(relative(again, score(0, what, stage)) < 1e-9, "{what}: {again}");
    }
    robocal(&[
        "evaluate",
        "--model",
        TORSO,
        "--tips",
        "head_camera,l_hand,r_hand",
        "--data",
        VIEWS,
        "--json",
        s(&evaluated),
    ]);
    let nominal = json(&evaluated)["observations"][0][1]["view_position"][1].as_f64().unwrap();
    assert!(relative(nominal, score(0, "view_position", 0)) < 1e-9, "{nominal} mm as it stands");
    std::fs::remove_dir_all(&dir).unwrap();
}

/// `evaluate` of a tree: a model that is no URDF, a file that holds no views, a branch file
/// of another tree are refused, naming what.
#[test]
fn evaluate_of_a_tree_refuses_what_it_cannot_score() {
    let dir = scratch("tree-refusals");
    let fails = |args: &[&str]| {
        let output = assert_cmd::Command::cargo_bin("robocal").unwrap().args(args).output().unwrap();
        (output.status.code(), String::from_utf8_lossy(&output.stderr).into_owned())
    };
    let (code, message) = fails(&["evaluate", "--model", "puma560", "--tips", "a,b", "--data", VIEWS]);
    assert_eq!(code, Some(2), "{message}");
    assert!(message.contains("--tips and --branches"), "{message}");
    let (code, message) =
        fails(&["evaluate", "--model", TORSO, "--tips", "head_camera,l_hand", "--data", BALL_BAR]);
    assert_eq!(code, Some(1));
    assert!(message.contains(BALL_BAR) && message.contains("not a file of views"), "{message}");
    std::fs::write(
        dir.join("head_camera.toml"),
        std::fs::read_to_string("examples/puma560-true.toml").unwrap(),
    )
    .unwrap();
    let (code, message) = fails(&["evaluate", "--model", TORSO, "--branches", s(&dir), "--data", VIEWS]);
    assert_eq!(code, Some(1));
    assert!(message.contains("head_camera.toml: 6 joints, the branch to head_camera has"), "{message}");
    std::fs::remove_dir_all(&dir).unwrap();
}

/// `--folds K` writes each training observation (view) once more, held out in its fold, in
/// the file's order: its line and pose the training row's, the rows' RMS after the report's
/// cross-validation row; for observation files and a tree's views.
#[test]
fn the_folds_rows_are_each_observation_held_out_in_its_fold() {
    let dir = scratch("folds-rows");
    let (poses, report) = (dir.join("residuals.csv"), dir.join("report.json"));
    let ball_bar = ["calibrate", "-q", "--model", "puma560", "--tool", "50,0,150", "--data", BALL_BAR];
    let views = ["calibrate", "-q", "--model", TORSO, "--data", VIEWS];
    for (args, quantity, n) in [(&ball_bar[..], "lengths", 150), (&views[..], "view_position", 120)] {
        let mut args = args.to_vec();
        args.extend(["--folds", "3", "--json", s(&report), "--poses-csv", s(&poses)]);
        robocal(&args);
        let (_, rows) = csv(&std::fs::read_to_string(&poses).unwrap());
        let training: Vec<_> = rows.iter().filter(|r| r["set"] == "training").collect();
        let folds: Vec<_> = rows.iter().filter(|r| r["set"] == "3-fold cross-validation").collect();
        assert_eq!((training.len(), folds.len()), (n, n), "{args:?}");
        for (t, f) in training.iter().zip(&folds) {
            assert_eq!((&t["line"], &t["pose"], &t["kind"]), (&f["line"], &f["pose"], &f["kind"]));
        }
        let scored = json(&report);
        let sets = scored["sets"].as_array().unwrap();
        let cv = sets.last().unwrap();
        assert_eq!(cv[0], "3-fold cross-validation");
        let after = cv[1][quantity][1].as_f64().unwrap();
        assert!(relative(rms(&folds, "after_mm"), after) < 1e-9, "{args:?}: {after} mm");
        // Held out, each row is worse on average than in training.
        assert!(rms(&folds, "after_mm") > rms(&training, "after_mm"), "{args:?}");
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

/// A marker file's `--folds K`: each training coordinate once more in `--poses-csv`, held out
/// in its fold, in the file's order (its line, kind and joint values the training row's); the
/// verdict's cross-validation row is their positions' RMS (`sqrt(3)` times the coordinates'
/// RMS, every coordinate measured), before and after; the figures draw them as a set.
#[test]
fn a_marker_files_folds_rows_are_each_coordinate_held_out_in_its_fold() {
    let dir = scratch("marker-folds-rows");
    let (poses, report, folder) = (dir.join("poses.csv"), dir.join("report.json"), dir.join("figures"));
    let data = "examples/puma560-measurements.csv";
    let args =
        ["calibrate", "-q", "--model", "puma560", "--data", data, "--folds", "3", "--json", s(&report)];
    let mut args = args.to_vec();
    args.extend(["--poses-csv", s(&poses), "--figures", s(&folder)]);
    robocal(&args);
    let (_, rows) = csv(&std::fs::read_to_string(&poses).unwrap());
    let training: Vec<_> = rows.iter().filter(|r| r["set"] == "training").collect();
    let folds: Vec<_> = rows.iter().filter(|r| r["set"] == "3-fold cross-validation").collect();
    assert_eq!((training.len(), folds.len()), (600, 600), "100 poses, 2 markers, 3 coordinates");
    for (t, f) in training.iter().zip(&folds) {
        assert_eq!((&t["line"], &t["kind"], &t["j2_deg"]), (&f["line"], &f["kind"], &f["j2_deg"]));
    }
    let report = json(&report);
    let verdict = report["verdict"].as_array().unwrap();
    let row = verdict.iter().find(|r| r["set"] == "3-fold cross-validation" && r["quantity"] == "markers");
    let row = row.expect("the cross-validation's markers row");
    for (stage, column) in [(0, "before_mm"), (1, "after_mm")] {
        let rms_mm = row["rms"][stage].as_f64().unwrap();
        assert!(relative(3f64.sqrt() * rms(&folds, column), rms_mm) < 1e-9, "{column}: {rms_mm} mm");
    }
    assert!(rms(&folds, "after_mm") > rms(&training, "after_mm"), "held out, worse than in training");
    let names = figures(&folder);
    assert!(names.contains(&"errors-by-observation-3-fold-cross-validation.svg".to_string()), "{names:?}");
    std::fs::remove_dir_all(&dir).unwrap();
}

/// `evaluate` whitens an observation file's residuals by its sigma column and
/// `--joint-sigma-deg`'s joint noise: the ball bar example, made with the paper's joint noise,
/// scored on its true robot flags none of its 150 rows with the noise it was made with, their
/// whitened RMS near 1, and without the joints' share several times that (flagged against the
/// set's robust spread, as a marker file's poses: few); a noise file of those sigmas is the same
/// noise, and `--sigma-mm` leaves rows with their own sigma as they are.
#[test]
fn evaluate_whitens_an_observation_file_by_the_joint_noise() {
    let dir = scratch("evaluate-joint-noise");
    let poses = dir.join("rows.csv");
    let truth = ["evaluate", "-q", "--model", "examples/puma560-true.toml", "--data", BALL_BAR];
    let flagged = |extra: &[&str]| {
        let mut args = truth.to_vec();
        args.extend(extra);
        args.extend(["--poses-csv", s(&poses)]);
        robocal(&args);
        let (_, rows) = csv(&std::fs::read_to_string(&poses).unwrap());
        assert_eq!(rows.len(), 150);
        let z2: f64 = rows.iter().map(|r| r["whitened"].parse::<f64>().unwrap().powi(2)).sum();
        (rows.iter().filter(|r| r["flagged"] == "true").count(), (z2 / 150.0).sqrt())
    };
    let sigmas = "0.007,0.007,0.007,0.002,0.002,0.002";
    let (with, rms) = flagged(&["--joint-sigma-deg", sigmas]);
    assert!(with == 0 && (0.7..1.4).contains(&rms), "{with} flagged, whitened RMS {rms}");
    let (without, rms) = flagged(&[]);
    assert!(rms > 4.0 && without < 15, "the joints' noise left out: {without} flagged, whitened RMS {rms}");
    // A noise file with those joint sigmas is the same noise; --sigma-mm is for rows without a
    // sigma cell, and every row of this file has one: neither changes a whitened residual.
    let noise = dir.join("noise.toml");
    std::fs::write(&noise, format!("joint_sigma = [{sigmas}]\n")).unwrap();
    assert_eq!(flagged(&["--noise", s(&noise)]), (with, flagged(&["--joint-sigma-deg", sigmas]).1));
    assert_eq!(
        flagged(&["--joint-sigma-deg", sigmas, "--sigma-mm", "0.5"]).1,
        flagged(&["--noise", s(&noise)]).1
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

/// `evaluate` of a tree's views takes `--joint-sigma-deg` into each view's covariance: the
/// nominal torso's views are millimetres out (5 mm RMS), tens of their own sigmas (0.2 mm,
/// 0.05 deg); a joint noise of 1 deg (about 9 mm at half a metre) covers them, each view
/// within 2 standard deviations. A wrong count names the tree's joints.
#[test]
fn evaluate_of_a_tree_whitens_by_the_joint_noise() {
    let dir = scratch("evaluate-tree-joint-noise");
    let report = dir.join("e.json");
    let largest = |extra: &[&str]| {
        let mut args = vec!["evaluate", "-q", "--model", TORSO, "--tips", "head_camera,l_hand,r_hand"];
        args.extend(["--data", VIEWS, "--json", s(&report)]);
        args.extend(extra);
        robocal(&args);
        let views = json(&report)["observations"][0][1]["views"].as_array().unwrap().clone();
        views.iter().map(|v| v["whitened"].as_f64().unwrap().abs()).fold(0.0, f64::max)
    };
    let (noisy, alone) = (largest(&["--joint-sigma-deg", "1"]), largest(&[]));
    assert!(
        noisy < 2.0 && alone > 20.0,
        "largest whitened {noisy} with 1 deg of joint noise, {alone} without"
    );
    let out = assert_cmd::Command::cargo_bin("robocal")
        .unwrap()
        .args(["evaluate", "--model", TORSO, "--tips", "head_camera,l_hand,r_hand", "--data", VIEWS])
        .args(["--joint-sigma-deg", "1,1"])
        .output()
        .unwrap();
    assert!(String::from_utf8_lossy(&out.stderr).contains("2 values for the 15 joints of torso"));
    std::fs::remove_dir_all(&dir).unwrap();
}
