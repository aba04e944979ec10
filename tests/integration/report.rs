//! The calibration report an engineer decides from (issue 12): per marker and per pose,
//! scored anywhere (`evaluate`), honest baselines, figures and a self-contained page, and every
//! error printed once.

use super::cli::CALIBRATE;
use assert_cmd::Command;
use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
use robocal::model::{RobotModel, Tool};
use serde_json::Value;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

fn robocal() -> Command {
    Command::cargo_bin("robocal").unwrap()
}

/// A scratch folder for one test.
fn scratch(test: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("robocal-report-{test}-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// Run `args`, which must succeed; its standard output.
fn run(args: &[&str]) -> String {
    let output = robocal().args(args).output().unwrap();
    assert!(output.status.success(), "{args:?}: {}", String::from_utf8_lossy(&output.stderr));
    String::from_utf8(output.stdout).unwrap()
}

fn json(path: &Path) -> Value {
    serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap()
}

/// The README's calibration without the noise (so by OLS), with `extra` flags.
fn calibrate(extra: &[&str]) -> String {
    let mut args = CALIBRATE[..7].to_vec();
    args.extend(&CALIBRATE[11..]);
    args.extend(extra);
    run(&args)
}

/// The README's calibration (with the noise, by WLS unless `extra` says otherwise).
fn calibrate_weighted(extra: &[&str]) -> String {
    let mut args = CALIBRATE.to_vec();
    args.extend(extra);
    run(&args)
}

/// Standard DH with Hayati's beta, written out: `Rz(theta + q) Tz(d) Tx(a) Rx(alpha)
/// Ry(beta)` per joint after the base, then the marker point.
fn literal_position(model: &RobotModel, q: &[f64], marker: &Vector3<f64>) -> Vector3<f64> {
    let mut t = Isometry3::from_parts(
        Translation3::from(model.base.xyz),
        UnitQuaternion::from_euler_angles(model.base.rpy.x, model.base.rpy.y, model.base.rpy.z),
    );
    for (j, q) in model.joints.iter().zip(q) {
        t = t
            * Isometry3::rotation(Vector3::z() * (j.theta + q))
            * Isometry3::translation(0.0, 0.0, j.d)
            * Isometry3::translation(j.a, 0.0, 0.0)
            * Isometry3::rotation(Vector3::x() * j.alpha)
            * Isometry3::rotation(Vector3::y() * j.beta);
    }
    t.transform_point(&(*marker).into()).coords
}

/// Each marker's position error (measured - predicted, mm) at `stage` (`before`, `after`) in
/// set `s` of `calibrate`'s JSON report, from its observations, by line and marker number.
fn calibrated_errors(report: &Value, s: usize, stage: &str) -> BTreeMap<(u64, u64), Vector3<f64>> {
    marker_errors(&report["sets"][s][1], stage)
}

/// Each marker's position error at `stage` in a scored set of observations (a JSON `Score`),
/// by line and marker number.
fn marker_errors(score: &Value, stage: &str) -> BTreeMap<(u64, u64), Vector3<f64>> {
    let mut errors = BTreeMap::new();
    for o in score["observations"].as_array().unwrap() {
        let Some(axis) = o["kind"].as_str().unwrap().strip_prefix("marker ") else { continue };
        let axis = ["x", "y", "z"].iter().position(|a| *a == axis).unwrap();
        let key = (o["line"].as_u64().unwrap(), o["marker"].as_u64().unwrap());
        errors.entry(key).or_insert_with(Vector3::zeros)[axis] = o[stage].as_f64().unwrap();
    }
    errors
}

/// Each marker's position error in file `s` of `evaluate`'s JSON report, by line and marker
/// number, as [`calibrated_errors`] gives `calibrate`'s.
fn evaluated_errors(report: &Value, s: usize) -> BTreeMap<(u64, u64), Vector3<f64>> {
    marker_errors(&report["observations"][s][1], "after")
}

/// `calibrate`'s own report is snapshot-tested in `cli.rs` (and is the README's example); this
/// is `evaluate`'s on two sessions: each file's markers and each marker, the worst positions.
#[test]
fn the_evaluate_report_has_per_marker_rows_and_the_worst_positions() {
    let dir = scratch("snapshot");
    let model = dir.join("calibrated.toml");
    calibrate_weighted(&["--out-model", model.to_str().unwrap()]);
    let (validation, measurements) = (CALIBRATE[6], CALIBRATE[4]);
    let mut args = vec!["evaluate", "--model", model.to_str().unwrap(), "--data", validation, measurements];
    args.extend(&CALIBRATE[7..11]);
    let text = run(&args);
    insta::assert_snapshot!(text);
}

#[test]
fn json_errors_per_pose_are_the_written_models_forward_kinematics() {
    let dir = scratch("fk");
    let (report, model) = (dir.join("report.json"), dir.join("calibrated.toml"));
    calibrate(&["--json", report.to_str().unwrap(), "--out-model", model.to_str().unwrap()]);
    let report = json(&report);
    let text = std::fs::read_to_string(&model).unwrap();
    let model = RobotModel::from_toml_str(&text).unwrap();
    let markers = robocal::model::markers_from_toml_str(&text).unwrap();
    assert_eq!(markers.iter().map(|m| m.0).collect::<Vec<_>>(), [1, 2]);
    assert_eq!(Tool::Point(markers[0].1), model.tool, "the tool is marker 1");
    for (s, file) in
        ["examples/puma560-measurements.csv", "examples/puma560-validation.csv"].iter().enumerate()
    {
        let data = robocal::io::load_measurements(Path::new(file), &model, None).unwrap();
        let errors = calibrated_errors(&report, s, "after");
        assert_eq!(errors.len(), 2 * data.len());
        let mut worst = 0.0f64;
        for k in 0..data.len() {
            for (m, (id, marker)) in markers.iter().enumerate() {
                let expected = data.markers[k][m] - literal_position(&model, &data.joints[k], marker);
                worst = worst.max((errors[&(data.lines[k] as u64, *id as u64)] - expected).norm());
            }
        }
        assert!(worst < 1e-9, "{file}: the report and the written model differ by {worst} mm");
    }
}

#[test]
fn evaluate_reproduces_calibrates_validation_from_the_written_toml_and_urdf() {
    let dir = scratch("evaluate");
    let (report, model) = (dir.join("report.json"), dir.join("calibrated.toml"));
    calibrate_weighted(&["--json", report.to_str().unwrap(), "--out-model", model.to_str().unwrap()]);
    let calibrated = json(&report);
    let scored = dir.join("scored.json");
    let text = run(&[
        "evaluate",
        "--model",
        model.to_str().unwrap(),
        "--data",
        "examples/puma560-validation.csv",
        "--json",
        scored.to_str().unwrap(),
    ]);
    assert!(text.contains("examples/puma560-validation.csv markers (mm)     100  0.1"), "{text}");
    let scored = json(&scored);
    assert_same_errors(&calibrated, 1, &scored, 0);
    let (a, b) = (&calibrated["sets"][1][1]["markers"][1], &scored["observations"][0][1]["markers"][1]);
    assert!((a.as_f64().unwrap() - b.as_f64().unwrap()).abs() < 1e-9, "rms: {a} and {b}");

    // The same from a URDF robot written back by --out-urdf, its markers as links.
    let (urdf, data, out) = (dir.join("arm.urdf"), dir.join("arm.csv"), dir.join("calibrated.urdf"));
    let arm = super::urdf::arm_urdf();
    std::fs::write(&urdf, &arm).unwrap();
    let mut truth = robocal::model::from_urdf_str(&arm, "base", "flange").unwrap();
    truth.base.xyz = Vector3::new(1000.0, 0.0, 0.0);
    truth.joints[1].origin.xyz.x += 0.3;
    let poses: Vec<Vec<f64>> = (0..60)
        .map(|k| {
            (truth.joints.iter().enumerate())
                .map(|(j, joint)| {
                    let u = (((k * 7 + j) as f64) * 12.9898).sin() * 0.5 + 0.5;
                    joint.limits[0] + u * (joint.limits[1] - joint.limits[0])
                })
                .collect()
        })
        .collect();
    let markers = [Vector3::new(30.0, 0.0, 60.0), Vector3::new(-20.0, 40.0, 50.0)];
    let sigmas = [0.0; 7];
    std::fs::write(&data, robocal::simulation::measurement_csv(&truth, &markers, &poses, &sigmas, 0.01, 1))
        .unwrap();
    let report = dir.join("urdf.json");
    run(&[
        "calibrate",
        "--model",
        urdf.to_str().unwrap(),
        "--base-link",
        "base",
        "--tip-link",
        "flange",
        "--data",
        data.to_str().unwrap(),
        "--validate",
        data.to_str().unwrap(),
        "--marker",
        "30,0,60",
        "--marker=-20,40,50",
        "--params",
        "offsets",
        "--json",
        report.to_str().unwrap(),
        "--out-urdf",
        out.to_str().unwrap(),
    ]);
    let scored = dir.join("urdf-scored.json");
    run(&[
        "evaluate",
        "--model",
        out.to_str().unwrap(),
        "--data",
        data.to_str().unwrap(),
        "--json",
        scored.to_str().unwrap(),
    ]);
    assert_same_errors(&json(&report), 1, &json(&scored), 0);
}

/// Every marker position's error "after" in set `a` of `calibrated` equals set `b` of `scored`'s,
/// to 1e-9 mm.
fn assert_same_errors(calibrated: &Value, a: usize, scored: &Value, b: usize) {
    let (x, y) = (calibrated_errors(calibrated, a, "after"), evaluated_errors(scored, b));
    assert_eq!(x.keys().collect::<Vec<_>>(), y.keys().collect::<Vec<_>>(), "the same poses and markers");
    let worst = x.iter().map(|(key, e)| (e - y[key]).norm()).fold(0.0, f64::max);
    assert!(worst < 1e-9, "evaluate differs from calibrate by {worst} mm");
}

#[test]
fn the_before_numbers_do_not_depend_on_the_estimator() {
    let dir = scratch("before");
    let mut reports = Vec::new();
    for estimator in ["ols", "wls", "wls-diag"] {
        let path = dir.join(format!("{estimator}.json"));
        calibrate_weighted(&["--estimator", estimator, "--json", path.to_str().unwrap()]);
        reports.push(json(&path));
    }
    for r in &reports[1..] {
        for s in 0..2 {
            assert_eq!(
                r["sets"][s][1]["markers"][0], reports[0]["sets"][s][1]["markers"][0],
                "set {s}, before"
            );
            assert_eq!(calibrated_errors(r, s, "before"), calibrated_errors(&reports[0], s, "before"));
        }
    }
    let after = |r: &Value| r["sets"][0][1]["markers"][1].as_f64().unwrap();
    assert_ne!(after(&reports[1]), after(&reports[0]), "after does depend on it");
    assert!(reports[1]["fits"]["before"].as_str().unwrap().contains("ols"));
}

#[test]
fn markers_chosen_by_the_user_fit_and_score_a_subset() {
    let dir = scratch("markers");
    // A held-out file with marker 2 only.
    let text = std::fs::read_to_string("examples/puma560-validation.csv").unwrap();
    let mut lines = text.lines().filter(|l| !l.starts_with('#'));
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let keep: Vec<usize> = (0..header.len()).filter(|&i| !["x1", "y1", "z1"].contains(&header[i])).collect();
    let pick = |line: &str| {
        let cells: Vec<&str> = line.split(',').collect();
        keep.iter().map(|&i| cells[i]).collect::<Vec<_>>().join(",")
    };
    let mut only2 = String::from("# units: joints=deg, lengths=mm\n");
    only2 += &(pick(&header.join(",")) + "\n");
    for line in lines {
        only2 += &(pick(line) + "\n");
    }
    let held_out = dir.join("marker2.csv");
    std::fs::write(&held_out, only2).unwrap();
    let report = dir.join("report.json");
    let out = calibrate(&[
        "--markers",
        "2",
        "--validate",
        held_out.to_str().unwrap(),
        "--json",
        report.to_str().unwrap(),
    ]);
    assert!(out.contains("100 poses, 1 marker,"), "{out}");
    assert!(
        out.contains("marker2.y") && !out.contains("marker1."),
        "parameters named by the file's numbers: {out}"
    );
    let report = json(&report);
    for s in 0..3 {
        let positions = report["sets"][s][1]["positions"].as_array().unwrap();
        assert_eq!(positions.len(), [100, 50, 50][s], "set {s}");
        assert!(positions.iter().all(|p| p["marker"] == 2), "set {s}: marker 2 alone");
    }
    // Marker 2 of the full held-out file and the file with marker 2 alone score the same.
    assert_eq!(report["sets"][1][1]["markers"], report["sets"][2][1]["markers"]);
    // Fitted on both markers, a file with marker 2 alone is scored on marker 2.
    let both = dir.join("both.json");
    calibrate(&["--validate", held_out.to_str().unwrap(), "--json", both.to_str().unwrap()]);
    let both = json(&both);
    assert!(both["sets"][2][1]["positions"].as_array().unwrap().iter().all(|p| p["marker"] == 2));
    assert_eq!(both["sets"][2][1]["markers"], both["sets"][1][1]["by_marker"][1]["rms"]);
}

#[test]
fn poses_csv_has_a_row_per_marker_coordinate() {
    let dir = scratch("csv");
    let csv = dir.join("poses.csv");
    calibrate(&["--poses-csv", csv.to_str().unwrap()]);
    let text = std::fs::read_to_string(&csv).unwrap();
    let mut lines = text.lines();
    let header = lines.next().unwrap();
    assert!(
        header.starts_with("set,file,line,kind,pose,pose_b,j1_deg,")
            && header.contains("before_mm,after_mm")
            && header.ends_with("whitened,flagged"),
        "{header}"
    );
    // A row per marker coordinate: 3 of each of 2 markers at 100 and 50 poses.
    assert_eq!(lines.count(), 3 * 2 * (100 + 50));
}

/// The page leads with the verdict as a card, has every figure inline with a caption that says
/// what to look for, the combinations held and every observation in collapsible sections, and
/// refers to nothing outside itself.
#[test]
fn the_page_is_one_well_formed_file_with_every_table_and_figure() {
    let dir = scratch("html");
    let (page, figures) = (dir.join("report.html"), dir.join("figures"));
    calibrate(&["--html", page.to_str().unwrap(), "--figures", figures.to_str().unwrap()]);
    let html = std::fs::read_to_string(&page).unwrap();
    assert!(!html.contains("http") && !html.contains("src=") && !html.contains("<script"), "self-contained");
    let document = parse_page(&html);
    let body = document.descendants().find(|n| n.has_tag_name("body")).unwrap();
    let sections: Vec<&str> =
        body.children().filter(|n| n.has_tag_name("section")).filter_map(|n| n.attribute("id")).collect();
    assert_eq!(sections, ["summary", "parameters", "held", "figures", "poses", "warnings", "report"]);
    let summary = body.children().find(|n| n.attribute("id") == Some("summary")).unwrap();
    assert_eq!(summary.attribute("class"), Some("card"));
    let verdict = summary.descendants().find(|n| n.has_tag_name("table")).expect("the verdict's table");
    let card: String = summary.descendants().filter_map(|n| n.text()).collect();
    assert!(
        card.contains("RMS after calibration on examples/puma560-validation.csv markers (held out)"),
        "{card}"
    );
    let mut names: Vec<String> = std::fs::read_dir(&figures)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    assert_eq!(names.len(), 2 + 1 + 6, "{names:?}");
    for name in &names {
        let figure = document.descendants().find(|n| n.attribute("id") == Some(name.as_str())).unwrap();
        assert!(
            figure.has_tag_name("figure") && figure.descendants().any(|n| n.has_tag_name("svg")),
            "{name}"
        );
        let caption = figure.children().find(|n| n.has_tag_name("figcaption")).expect("a caption");
        let words: String = caption.descendants().filter_map(|n| n.text()).collect();
        assert!(words.contains("Look for") || words.contains("look for"), "{name}: {words}");
        let svg = std::fs::read_to_string(figures.join(name)).unwrap();
        assert!(svg.contains("<svg"), "{name}");
    }
    // The verdict's rows: each set's markers and each marker, the parameters with their
    // intervals drawn, every observation of each set in a table.
    let tables: Vec<roxmltree::Node> = document.descendants().filter(|n| n.has_tag_name("table")).collect();
    assert_eq!(
        verdict.descendants().filter(|n| n.has_tag_name("tr")).count(),
        1 + 2 * 3,
        "a head, 3 rows a set"
    );
    for set in ["training", "examples/puma560-validation.csv"] {
        let table = tables
            .iter()
            .find(|t| t.attribute("data-set") == Some(set) && t.attribute("class") == Some("poses"));
        let rows = table
            .unwrap_or_else(|| panic!("a table of {set}"))
            .descendants()
            .filter(|n| n.has_tag_name("tr"));
        assert_eq!(
            rows.count(),
            1 + if set == "training" { 600 } else { 300 },
            "{set}: a head, a row per observation"
        );
    }
    let parameters = tables.iter().find(|t| t.attribute("class") == Some("parameters")).unwrap();
    let bars = parameters.descendants().filter(|n| n.has_tag_name("svg")).count();
    assert_eq!(bars, 30, "an interval drawn per parameter");
    // The combinations and the poses collapsed.
    let details: Vec<roxmltree::Node> =
        document.descendants().filter(|n| n.has_tag_name("details")).collect();
    assert!(details.iter().any(|d| d.attribute("class") == Some("combinations")));
    assert_eq!(details.iter().filter(|d| d.attribute("class") == Some("poses")).count(), 2);
    // A headless browser, where the machine has one, draws the same page offline.
    let url = format!("file://{}", page.display());
    let browser = ["chromium", "chromium-browser", "google-chrome"].into_iter().find_map(|name| {
        let args = ["--headless", "--no-sandbox", "--disable-gpu", "--dump-dom", url.as_str()];
        std::process::Command::new(name).args(args).output().ok().filter(|o| o.status.success())
    });
    if let Some(output) = browser {
        let dom = String::from_utf8_lossy(&output.stdout);
        assert_eq!(dom.matches("<svg").count(), names.len() + 30, "the browser sees every figure and bar");
        assert!(dom.contains("Every observation"), "and the tables");
    }
}

/// The keys documented in docs/formats.md's section on the calibration report's JSON, as
/// `(key, always present)`: the top-level ones and the verdict's (`verdict.sets[].rms_mm`).
fn documented_keys() -> Vec<(String, bool)> {
    let docs = std::fs::read_to_string("docs/formats.md").unwrap();
    let start = docs.find("## Calibration report (JSON)").expect("the section");
    let section = &docs[start..];
    let section = &section[..section[3..].find("\n## ").map_or(section.len(), |e| e + 3)];
    section
        .lines()
        .filter_map(|l| l.strip_prefix("| `"))
        .filter_map(|l| {
            let (key, rest) = l.split_once("` | ")?;
            Some((key.to_string(), rest.starts_with("always")))
        })
        .collect()
}

/// Whether `path` (`a.b[].c`) names something in `json` (in some element of an array; in a
/// `[name, value]` pair, as `sets` holds its scores, in the value).
fn has(json: &Value, path: &str) -> bool {
    if let Some([Value::String(_), value]) = json.as_array().map(Vec::as_slice) {
        return has(value, path);
    }
    match path.split_once('.') {
        None => match path.strip_suffix("[]") {
            Some(key) => json.get(key).is_some_and(Value::is_array),
            None => json.get(path).is_some(),
        },
        Some((head, rest)) => match head.strip_suffix("[]") {
            Some(key) => {
                json.get(key).and_then(Value::as_array).is_some_and(|a| a.iter().any(|e| has(e, rest)))
            }
            None => json.get(head).is_some_and(|v| has(v, rest)),
        },
    }
}

/// The JSON of a calibration is schema 3 (of marker files and of a tree's views): every key it
/// writes is documented, in the documented order, the verdict first; every key documented is in
/// real output (those of a probe, of several groups, of sessions and of `--prior auto` in their
/// own tests); the verdict's numbers are the sets' scores.
#[test]
fn the_json_schema_is_documented_and_every_documented_key_is_real() {
    let dir = scratch("schema");
    let (a, b, c, d) = (dir.join("a.json"), dir.join("b.json"), dir.join("c.json"), dir.join("d.json"));
    // The README's file with marker 1 of line 10 moved by 20 mm: an outlier a robust loss
    // weighs down.
    let text = std::fs::read_to_string("examples/puma560-measurements.csv").unwrap();
    let moved: Vec<String> = (text.lines().enumerate())
        .map(|(k, line)| match k {
            9 => {
                let mut cells: Vec<String> = line.split(',').map(String::from).collect();
                cells[6] = format!("{}", cells[6].parse::<f64>().unwrap() + 20.0);
                cells.join(",")
            }
            _ => line.to_string(),
        })
        .collect();
    let outlier = dir.join("outlier.csv");
    std::fs::write(&outlier, moved.join("\n") + "\n").unwrap();
    let mut args = CALIBRATE.to_vec();
    args[4] = outlier.to_str().unwrap();
    let validation = "examples/puma560-validation.csv";
    args.extend(["--validate", validation, "--folds", "2", "--select", "bic", "--loss", "cauchy"]);
    args.extend(["--json", a.to_str().unwrap()]);
    run(&args);
    let arm7 = ["--params", "joint*.theta,joint*.compliance", "--estimator", "fgls"];
    super::nested::calibrate_arm7(&arm7, &b);
    // Without any noise: ordinary least squares, scaled by the residuals' spread.
    calibrate(&["--json", c.to_str().unwrap()]);
    // A tree's views: the same report, with its branches, joints and frames.
    let torso = ["calibrate", "-q", "--model", "presets/torso.urdf", "--data", "examples/torso/views.csv"];
    run(&[&torso[..], &["--json", d.to_str().unwrap()]].concat());
    let documented = documented_keys();
    let top: Vec<&str> = documented.iter().map(|(k, _)| k.as_str()).filter(|k| !k.contains('.')).collect();
    assert_eq!(&top[..2], ["schema", "verdict"]);
    // A probe's angles: kinds_markers.rs; groups: its verdict test; sessions: kinds.rs's
    // per-session tests; `--prior auto`: nested.rs.
    let elsewhere = ["sets[].angles", "sets[].by_group", "sets[].sessions", "prior_scale"];
    let reports: Vec<(String, Value)> =
        [&a, &b, &c, &d].iter().map(|p| (std::fs::read_to_string(p).unwrap(), json(p))).collect();
    for (text, report) in &reports {
        assert_eq!(report["schema"], 3);
        // Every top-level key documented, in the documented order.
        let keys: Vec<&String> = report.as_object().unwrap().keys().collect();
        for key in &keys {
            assert!(top.contains(&key.as_str()), "`{key}` is not documented in docs/formats.md");
        }
        let at: Vec<usize> = (top.iter())
            .filter(|k| keys.iter().any(|key| key == *k))
            .map(|k| text.find(&format!("\n  \"{k}\": ")).unwrap())
            .collect();
        assert!(at.windows(2).all(|w| w[0] < w[1]), "the keys in the documented order");
        for (key, always) in &documented {
            assert!(!always || has(report, key), "`{key}` is always present");
        }
    }
    for (key, _) in documented.iter().filter(|(k, _)| !elsewhere.contains(&k.as_str())) {
        assert!(reports.iter().any(|(_, r)| has(r, key)), "`{key}` documented, in no real output");
    }
    // The verdict's numbers are the sets' scores.
    let report = &reports[0].1;
    let sets = report["sets"].as_array().unwrap();
    let names: Vec<&str> = sets.iter().map(|s| s[0].as_str().unwrap()).collect();
    assert_eq!(names, ["training", validation, validation, "2-fold cross-validation, nested"]);
    let rows = report["verdict"].as_array().unwrap();
    for (name, score) in sets.iter().map(|s| (&s[0], &s[1])) {
        let row = rows.iter().find(|r| r["set"] == *name && r["quantity"] == "markers").expect("a row");
        assert_eq!(row["rms"], score["markers"], "{name}");
        assert_eq!(row["count"].as_u64().unwrap() as usize, score["positions"].as_array().unwrap().len());
    }
}

/// Feasible GLS stopped after one reweighting has not settled: the report's first line says so,
/// and the report is not called converged.
#[test]
fn fgls_says_when_its_variance_components_did_not_settle() {
    let model = RobotModel::preset("puma560").unwrap();
    let text = std::fs::read_to_string("examples/puma560-measurements.csv").unwrap();
    let data = crate::marker_data(&text, &model, None);
    let markers = [Vector3::new(50.0, 0.0, 150.0), Vector3::new(-40.0, 60.0, 120.0)];
    let options = crate::marker_options(&model, robocal::estimation::Estimator::Ols, None, &markers);
    let feasible = robocal::calibration::FeasibleOptions { max_iterations: 1, ..Default::default() };
    let c =
        robocal::calibration::kinds::calibrate_kinds_feasible(&model, &data, &options, &feasible).unwrap();
    assert_eq!(c.noise_settled, Some(false));
    let counts = (data.observations.len(), data.joints.len());
    let report =
        robocal::report::observations::ObservationsReport::new(&c, "data", counts, "fgls", Vec::new());
    assert!(!report.converged);
    let text = report.text();
    assert!(
        text.lines().next().unwrap().contains("not converged: the variance components did not settle"),
        "{text}"
    );
}

/// Every failing command prints one message, once: no part of it (the file, the line and
/// column, the cause) is printed twice.
#[test]
fn every_error_is_printed_once() {
    let dir = scratch("once");
    let write = |name: &str, text: &str| {
        let path = dir.join(name);
        std::fs::write(&path, text).unwrap();
        path.display().to_string()
    };
    let bad_csv =
        write("bad.csv", "# units: joints=deg, lengths=mm\nj1,j2,j3,j4,j5,j6,x1,y1,z1\n1,2,3,4,5,6,a,2,3\n");
    let bad_model = write("bad.toml", "name = \"x\"\n[[joints]]\nfoo = 1\n");
    let bad_noise = write("noise.toml", "[joints]\nsigma = 1\n");
    let bad_urdf = write("bad.urdf", "<robot name=\"r\"><link name=\"a\"/></robot");
    let bad_study = write("study.toml", "seed = -1\n");
    let bad_poses = write("poses.csv", "# units: joints=deg\nj1,j2,j3,j4,j5,j6\n1,2,x,4,5,6\n");
    let measurements = "examples/puma560-measurements.csv";
    let cases: Vec<Vec<&str>> = vec![
        vec!["calibrate", "--model", "puma560", "--data", &bad_csv],
        vec!["calibrate", "--model", "puma560", "--data", "no-such.csv"],
        vec!["calibrate", "--model", &bad_model, "--data", measurements],
        vec!["calibrate", "--model", "puma561", "--data", measurements],
        vec!["calibrate", "--model", "puma560", "--data", measurements, "--noise", &bad_noise],
        vec![
            "calibrate",
            "--model",
            &bad_urdf,
            "--base-link",
            "a",
            "--tip-link",
            "b",
            "--data",
            measurements,
        ],
        vec!["calibrate", "--model", "puma560", "--data", measurements, "--params", "j9.theta"],
        vec!["calibrate", "--model", "puma560", "--data", measurements, "--markers", "3"],
        vec!["calibrate", "--model", "puma560", "--data", measurements, "--estimator", "wls"],
        vec!["evaluate", "--model", &bad_model, "--data", measurements],
        vec!["evaluate", "--model", "puma560", "--data", &bad_csv],
        vec!["evaluate", "--model", "puma560", "--data", measurements, "--markers", "5"],
        vec!["fk", "--model", &bad_model, "--q", "0,0,0,0,0,0"],
        vec!["model", "show", &bad_model],
        vec!["simulate", &bad_study],
        vec!["observability", &bad_poses, "--model", "puma560"],
        vec!["repeatability", "--model", "puma560", "--data", measurements],
    ];
    for args in cases {
        let output = robocal().args(&args).output().unwrap();
        let code = output.status.code();
        assert!(code == Some(1) || code == Some(2), "{args:?}: exit code {code:?}");
        let stderr = String::from_utf8(output.stderr).unwrap();
        assert_eq!(stderr.matches("error:").count(), 1, "{args:?}:\n{stderr}");
        // No part of the message, cut at ": " and at line ends, appears twice.
        let message = stderr.split("\n\nFor more information").next().unwrap();
        let parts: Vec<&str> = message.split([':', '\n']).map(str::trim).filter(|p| p.len() > 12).collect();
        for (i, part) in parts.iter().enumerate() {
            assert!(!parts[..i].contains(part), "{args:?}: `{part}` printed twice:\n{stderr}");
        }
    }
}

/// The page of `args`' calibration (observation files or a tree's views), parsed: its body's
/// section ids, the verdict table's text, and every table's text.
fn files_page(args: &[&str], name: &str) -> (Vec<String>, String, String) {
    let dir = scratch(name);
    let page = dir.join("report.html");
    let output = assert_cmd::Command::cargo_bin("robocal")
        .unwrap()
        .args(args)
        .args(["--html", page.to_str().unwrap(), "--quiet"])
        .output()
        .unwrap();
    assert!(output.status.success(), "{}", String::from_utf8_lossy(&output.stderr));
    let html = std::fs::read_to_string(&page).unwrap();
    assert!(!html.contains("http") && !html.contains("src=") && !html.contains("<script"), "self-contained");
    let document = parse_page(&html);
    let body = document.descendants().find(|n| n.has_tag_name("body")).unwrap();
    let sections = body
        .children()
        .filter(|n| n.has_tag_name("section"))
        .filter_map(|n| n.attribute("id"))
        .map(String::from);
    let text = |n: roxmltree::Node| -> String { n.descendants().filter_map(|d| d.text()).collect() };
    let summary = body.children().find(|n| n.attribute("id") == Some("summary")).expect("a verdict");
    let verdict = text(summary.descendants().find(|n| n.has_tag_name("table")).expect("the verdict's table"));
    let tables = document.descendants().filter(|n| n.has_tag_name("table")).map(text).collect();
    (sections.collect(), verdict, tables)
}

/// Observation files and a tree's views get the designed page too: the verdict first (the text
/// verdict's rows: a row per set and quantity, counted and flagged, the held-out file's), the
/// robot's parameters apart from the set-up's, the
/// prior's curve when `--prior auto` chose it, the text report in full.
#[test]
fn observation_files_and_trees_have_a_page_that_leads_with_the_verdict() {
    let ball_bar: Vec<&str> =
        "calibrate --model puma560 --tool 50,0,150 --data examples/puma560-ballbar.csv \
         --validate examples/puma560-ballbar-2.csv --joint-sigma-deg 0.007,0.007,0.007,0.002,0.002,0.002 \
         --prior auto:machined --folds 3"
            .split_whitespace()
            .collect();
    let (sections, verdict, tables) = files_page(&ball_bar, "ballbar-page");
    assert_eq!(
        sections,
        ["summary", "parameters", "held", "unseen", "figures", "poses", "warnings", "report"]
    );
    // Every observation of each set, a table each: a row per observation and the head's.
    let html = std::fs::read_to_string(scratch("ballbar-page").join("report.html")).unwrap();
    let document = parse_page(&html);
    let rows_of = |set: &str| {
        let table = document
            .descendants()
            .find(|n| n.attribute("data-set") == Some(set) && n.attribute("class") == Some("poses"));
        table.unwrap_or_else(|| panic!("{set}")).descendants().filter(|n| n.has_tag_name("tr")).count()
    };
    let sets =
        [("training", 150), ("examples/puma560-ballbar-2.csv", 60), ("3-fold cross-validation, nested", 150)];
    for (set, observations) in sets {
        assert_eq!(rows_of(set), observations + 1, "{set}");
    }
    // The text's verdict rows: label, count, RMS and max before -> after, flagged.
    for row in [
        "training (mm)150",
        "examples/puma560-ballbar-2.csv (mm)60",
        "3-fold cross-validation, nested (mm)150",
        "0 of 150",
        " mm0 of 60",
    ] {
        assert!(verdict.contains(row), "{row}: {verdict}");
    }
    assert!(
        tables.contains("j2.theta") && tables.contains("point1.x") && tables.contains("CV RMS mm"),
        "{tables}"
    );
    let torso: Vec<&str> =
        "calibrate --model presets/torso.urdf --data examples/torso/views.csv --validate examples/torso/views-2.csv"
            .split_whitespace()
            .collect();
    let (sections, verdict, _) = files_page(&torso, "tree-page");
    assert_eq!(sections[0], "summary");
    for row in ["examples/torso/views-2.csv (mm)80", "examples/torso/views-2.csv (deg)80", "0 of 80"] {
        assert!(verdict.contains(row), "{row}: {verdict}");
    }
}

/// `html` parsed as XML (its document type allowed): a page must be well-formed.
fn parse_page(html: &str) -> roxmltree::Document<'_> {
    roxmltree::Document::parse_with_options(
        html,
        roxmltree::ParsingOptions { allow_dtd: true, ..Default::default() },
    )
    .expect("well-formed")
}

/// What a fit held, in words, as every report says it (a marker file's, observations', a
/// tree's: `held_text`): the parameters held for one reason on one line, in order where the
/// first of them was (a tree's joint that no view sees prints once, not once per parameter);
/// then each combination as algebra.
#[test]
fn parameters_held_for_one_reason_are_one_line() {
    use robocal::calibration::Held;
    let unseen = |p: &str| Held::Unseen { parameter: p.into(), why: "not seen".into() };
    let held = [
        unseen("torso.x"),
        Held::Combination { parameter: "j1.d".into(), terms: vec![("point1.z".into(), -1.0)] },
        unseen("torso.y"),
        Held::ByUser { parameter: "j2.a".into(), setup: false },
        Held::ByUser { parameter: "plane1.d".into(), setup: true },
        Held::ByUser { parameter: "j3.a".into(), setup: false },
    ];
    assert_eq!(
        robocal::report::verdict::held_text(&held),
        "held fixed (6 parameters):\n\
         \x20 torso.x, torso.y: not seen\n\
         \x20 j1.d: the observations cannot tell them from a combination of the others\n\
         \x20 j2.a, j3.a: held at their nominal values by --hold\n\
         \x20 plane1.d: held at their start by --hold\n\
         the combinations held (the held parameter first; the others' estimates absorb it):\n\
         \x20 j1.d - point1.z\n"
    );
    assert_eq!(held[0].text(), "torso.x: not seen");
}
