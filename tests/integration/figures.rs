//! The figures of a calibration as the command writes them: signed components against each
//! joint, and against each joint's gravity load when the model has masses.

use assert_cmd::Command;

/// The names of the figures `calibrate --model MODEL` writes for the README's data (with the
/// `extra` flags), and the folder (to be removed by the caller).
fn figures_of(model: &str, extra: &[&str]) -> (Vec<String>, std::path::PathBuf) {
    // A folder of its own for each call: the tests run at once, some with the same flags.
    static CALLS: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);
    let call = CALLS.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    let dir = std::env::temp_dir().join(format!("robocal-figures-{}-{model}-{call}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let output = Command::cargo_bin("robocal")
        .unwrap()
        .args(["-q", "calibrate", "--model", model, "--data", "examples/puma560-measurements.csv"])
        .args(["--marker", "50,0,150", "--marker=-40,60,120"])
        .args(extra)
        .arg("--figures")
        .arg(&dir)
        .output()
        .unwrap();
    assert!(output.status.success(), "{}", String::from_utf8_lossy(&output.stderr));
    let mut names: Vec<String> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    (names, dir)
}

/// The held-out file of the README's example.
const VALIDATE: [&str; 2] = ["--validate", "examples/puma560-validation.csv"];

#[test]
fn a_model_with_masses_adds_the_errors_against_each_loaded_joints_gravity_load() {
    let (names, dir) = figures_of("puma560-masses", &VALIDATE);
    let torques: Vec<&str> = names.iter().map(String::as_str).filter(|n| n.contains("torque")).collect();
    // j1's axis is vertical: gravity puts no load on it, so it has no figure.
    assert_eq!(
        torques,
        [
            "error-vs-torque-j2.svg",
            "error-vs-torque-j3.svg",
            "error-vs-torque-j4.svg",
            "error-vs-torque-j5.svg"
        ]
    );
    let svg = std::fs::read_to_string(dir.join("error-vs-torque-j2.svg")).unwrap();
    assert!(svg.contains("gravity load on j2 (N·m)"), "the load's unit on the axis");
    // Through the observation fit (`--tool 0,0,0` sends the file there): the same joints'
    // figures, each residual against its pose's load.
    let (names, there) = figures_of("puma560-masses", &[&VALIDATE[..], &["--tool", "0,0,0"]].concat());
    let loads: Vec<&str> = names.iter().map(String::as_str).filter(|n| n.contains("torque")).collect();
    assert_eq!(loads, torques);
    let svg = std::fs::read_to_string(there.join("error-vs-torque-j3.svg")).unwrap();
    assert!(svg.contains("residuals (measured - predicted), after, against gravity load on j3 (N·m)"));
    std::fs::remove_dir_all(&there).unwrap();
    let against_joint = std::fs::read_to_string(dir.join("error-vs-j2.svg")).unwrap();
    for panel in ["x (mm)", "y (mm)", "z (mm)"] {
        assert!(against_joint.contains(panel), "the signed component {panel}");
    }
    std::fs::remove_dir_all(&dir).unwrap();
    let (names, dir) = figures_of("puma560", &VALIDATE);
    assert!(names.iter().all(|n| !n.contains("torque")), "no masses, no load figures: {names:?}");
    assert!(names.contains(&"error-vs-j6.svg".to_string()), "{names:?}");
    std::fs::remove_dir_all(&dir).unwrap();
}

/// The data points (circles of radius 2) of an error-against figure, panel by panel, with the
/// y of each panel's zero line: the long horizontal black lines come as each panel's x axis,
/// then its zero line, and a panel's points lie between the axis above and its own.
fn error_panels(svg: &str) -> Vec<(f64, Vec<(f64, f64)>)> {
    let document = roxmltree::Document::parse(svg).unwrap();
    let number = |n: &roxmltree::Node, a: &str| n.attribute(a).unwrap().parse::<f64>().unwrap();
    let mut lines = Vec::new();
    for n in document.descendants().filter(|n| n.has_tag_name("polyline")) {
        let points: Vec<(f64, f64)> = (n.attribute("points").unwrap().split_whitespace())
            .map(|p| p.split_once(',').map(|(x, y)| (x.parse().unwrap(), y.parse().unwrap())).unwrap())
            .collect();
        let black = n.attribute("stroke") == Some("#000000") && n.attribute("opacity") == Some("1");
        if black && points.len() == 2 && points[0].1 == points[1].1 && points[1].0 - points[0].0 > 400.0 {
            lines.push(points[0].1);
        }
    }
    let circles: Vec<(f64, f64)> = (document.descendants())
        .filter(|n| n.has_tag_name("circle") && n.attribute("r") == Some("2"))
        .map(|n| (number(&n, "cx"), number(&n, "cy")))
        .collect();
    let mut above = 0.0;
    lines
        .chunks(2)
        .map(|pair| {
            let (axis, zero) = (pair[0], pair[1]);
            let inside = circles.iter().copied().filter(|p| p.1 > above && p.1 < axis).collect();
            above = axis;
            (zero, inside)
        })
        .collect()
}

/// The shares of a panel's points above its zero line on the left half and on the right
/// half of its x range (split at the median point).
fn shares_above(panel: &(f64, Vec<(f64, f64)>)) -> (f64, f64) {
    let (zero, points) = panel;
    let mut xs: Vec<f64> = points.iter().map(|p| p.0).collect();
    xs.sort_by(f64::total_cmp);
    let median = xs[xs.len() / 2];
    let share = |side: &dyn Fn(f64) -> bool| {
        let on: Vec<&(f64, f64)> = points.iter().filter(|p| side(p.0)).collect();
        on.iter().filter(|p| p.1 < *zero).count() as f64 / on.len() as f64
    };
    (share(&|x| x < median), share(&|x| x > median))
}

/// A 6-DOF probe on the nominal PUMA 560 whose measurements jump where joint 2 passes the
/// middle of its travel (a backlash-like sign flip): +0.3 mm in x and +0.1 deg about z past
/// it, -0.3 mm and -0.1 deg before. After calibration (which cannot follow a step) the
/// figure against j2 shows the flip in the signed x and rz panels, points on both sides of
/// zero split by the step, where a norm would show none; y has no step.
#[test]
fn a_sign_flip_against_a_joint_shows_in_its_signed_components() {
    use nalgebra::{UnitQuaternion, Vector3};
    use rand::{RngExt, SeedableRng};
    use robocal::calibration::kinds::calibrate_kinds;
    use robocal::estimation::Estimator;
    use robocal::kinematics::Chain;
    use robocal::model::{Placement, RobotModel};
    use robocal::report::residuals::{ResidualSet, residual_figures};
    let model = RobotModel::preset("puma560").unwrap();
    let mounting = Placement { xyz: Vector3::new(50.0, 0.0, 150.0), rpy: Vector3::zeros() };
    let chain = Chain::probe(&model, &mounting);
    let at = chain.with_errors(&vec![0.0; chain.params().len()]);
    let mut rng = rand::rngs::ChaCha8Rng::seed_from_u64(29);
    let middle = (model.joints[1].limits[0] + model.joints[1].limits[1]) / 2.0;
    let mut text = String::from(crate::calibration::PROBE_HEADER);
    for _ in 0..80 {
        let q: Vec<f64> = model.joints.iter().map(|j| rng.random_range(j.limits[0]..j.limits[1])).collect();
        let step = if q[1] > middle { 1.0 } else { -1.0 };
        let pose = at.pose(&q);
        let p = pose.translation.vector + Vector3::new(0.3 * step, 0.0, 0.0);
        let r = UnitQuaternion::from_euler_angles(0.0, 0.0, (0.1 * step).to_radians()) * pose.rotation;
        text += &crate::calibration::probe_row(&q, &p, &r);
    }
    let data = crate::marker_data(&text, &model, None);
    let options = crate::marker_options(&model, Estimator::Ols, None, &[mounting.xyz]);
    let result = calibrate_kinds(&model, &data, &options).unwrap();
    let set =
        ResidualSet::of_observations("training", &result.training, &[("probe.csv", &data)], &model.joints)
            .unwrap();
    let figures = residual_figures(&[&set], &model.joints).unwrap();
    let svg = &figures.iter().find(|(name, _)| name == "error-vs-j2.svg").unwrap().1;
    std::fs::write("/tmp/port36-error-vs-j2.svg", svg).unwrap();
    for label in ["x (mm)", "y (mm)", "z (mm)", "rx (deg)", "ry (deg)", "rz (deg)", "j2 (deg)"] {
        assert!(svg.contains(label), "the panel or axis `{label}`");
    }
    let panels = error_panels(svg);
    assert_eq!(panels.len(), 6, "x, y, z, rx, ry, rz");
    assert!(panels.iter().all(|p| p.1.len() == 80), "every pose in every panel");
    for (c, name) in [(0, "x"), (5, "rz")] {
        let (left, right) = shares_above(&panels[c]);
        assert!(
            left < 0.2 && right > 0.8,
            "{name}: {left:.2} above zero before the step, {right:.2} past it"
        );
    }
    let (left, right) = shares_above(&panels[1]);
    assert!((left - right).abs() < 0.5, "y has no step: {left:.2} and {right:.2} above zero");
}

/// Every `#RRGGBB` colour an SVG paints with (its `fill` and `stroke` attributes).
fn colours(svg: &str) -> Vec<[u8; 3]> {
    let document = roxmltree::Document::parse(svg).unwrap();
    let hex = |h: &str| [1, 3, 5].map(|i| u8::from_str_radix(&h[i..i + 2], 16).unwrap());
    (document.descendants())
        .flat_map(|n| [n.attribute("fill"), n.attribute("stroke")])
        .flatten()
        .filter(|c| c.starts_with('#') && c.len() == 7)
        .map(hex)
        .collect()
}

/// WCAG's contrast of `c` against white.
fn contrast_on_white(c: [u8; 3]) -> f64 {
    let linear = |v: u8| {
        let v = f64::from(v) / 255.0;
        if v <= 0.04045 { v / 12.92 } else { ((v + 0.055) / 1.055).powf(2.4) }
    };
    1.05 / (0.2126 * linear(c[0]) + 0.7152 * linear(c[1]) + 0.0722 * linear(c[2]) + 0.05)
}

/// Every figure of a calibration with two sets paints in greys and the palette only (Okabe and
/// Ito's blue and vermillion for the two sets), each colour but white at least 3:1 on white:
/// no yellow anywhere.
#[test]
fn the_figures_paint_with_the_colour_blind_safe_palette_only() {
    let palette = robocal::report::figures::PALETTE.map(|c| [c.0, c.1, c.2]);
    assert_eq!(&palette[..3], &[[0, 114, 178], [213, 94, 0], [0, 158, 115]], "Okabe-Ito");
    let (names, dir) = figures_of("puma560-masses", &VALIDATE);
    let mut used = Vec::new();
    for name in &names {
        let svg = std::fs::read_to_string(dir.join(name)).unwrap();
        for c in colours(&svg) {
            let grey = c[0] == c[1] && c[1] == c[2];
            assert!(grey || palette.contains(&c), "{name}: colour {c:?} is neither grey nor the palette's");
            assert!(c == [255; 3] || contrast_on_white(c) >= 3.0, "{name}: {c:?} under 3:1 on white");
            used.extend((!grey).then_some(c));
        }
    }
    assert!(used.contains(&palette[0]) && used.contains(&palette[1]), "the two sets' colours");
    std::fs::remove_dir_all(&dir).unwrap();
}

/// The `<text>` elements of an SVG: (x, y, text).
fn texts(svg: &str) -> Vec<(f64, f64, String)> {
    let document = roxmltree::Document::parse(svg).unwrap();
    let number = |n: &roxmltree::Node, a: &str| n.attribute(a).unwrap().parse::<f64>().unwrap();
    (document.descendants())
        .filter(|n| n.has_tag_name("text"))
        .map(|n| (number(&n, "x"), number(&n, "y"), n.text().unwrap_or("").trim().to_string()))
        .collect()
}

/// The words of an SVG's texts, one text a line (entities decoded: `paper's`).
fn words(svg: &str) -> String {
    texts(svg).into_iter().map(|t| t.2 + "\n").collect()
}

/// The x of each tick label among `labels` in `svg` (the first text of that content).
fn tick_xs(svg: &str, labels: &[&str]) -> Vec<f64> {
    let all = texts(svg);
    let x = |l: &&str| all.iter().find(|t| t.2 == *l).unwrap_or_else(|| panic!("tick `{l}`")).0;
    labels.iter().map(x).collect()
}

/// Whether `xs` are evenly spaced (a log axis at values each twice the last), to a pixel.
fn evenly_spaced(xs: &[f64]) -> bool {
    let steps: Vec<f64> = xs.windows(2).map(|w| w[1] - w[0]).collect();
    steps.iter().all(|s| *s > 10.0 && (s - steps[0]).abs() <= 1.0)
}

/// `--prior auto` with `--figures` draws the curve it chose the scale from: the scales 1/16 to
/// 16 on a log axis (evenly spaced ticks), the chosen one circled and named.
#[test]
fn the_prior_scale_curve_is_drawn_on_a_log_axis() {
    let (names, dir) = figures_of("puma560", &["--params", "offsets", "--prior", "auto:machined"]);
    assert!(names.contains(&"prior-scale.svg".to_string()), "{names:?}");
    let svg = std::fs::read_to_string(dir.join("prior-scale.svg")).unwrap();
    let ticks = ["1/16", "1/8", "1/4", "1/2", "1", "2", "4", "8", "16"];
    assert!(evenly_spaced(&tick_xs(&svg, &ticks)), "the scales on a log axis");
    assert!(svg.contains("chosen: s = 1, 1.71 mm"), "the chosen scale named");
    assert!(svg.contains("CV RMS error (mm)"));
    std::fs::remove_dir_all(&dir).unwrap();
}

/// `--prior auto-ml:machined:classes` draws each class's profile log evidence beside the one
/// scale's curve: one dashed curve per class (lengths, angles, offsets), each in its own
/// colour of the palette and named with its scale in the legend.
#[test]
fn the_prior_scale_figure_has_a_curve_per_class() {
    let sigmas = ["--sigma-mm", "0.01", "--joint-sigma-deg", "0.007,0.007,0.007,0.007,0.007,0.007"];
    let (names, dir) =
        figures_of("puma560", &[&sigmas[..], &["--prior", "auto-ml:machined:classes"]].concat());
    assert!(names.contains(&"prior-scale.svg".to_string()), "{names:?}");
    let svg = std::fs::read_to_string(dir.join("prior-scale.svg")).unwrap();
    let text = words(&svg);
    for class in ["lengths", "angles", "offsets"] {
        assert!(text.lines().any(|l| l.starts_with(&format!("{class} (")) && l.contains("s = ")), "{text}");
    }
    // The one scale's curve in blue, each class's in a colour of its own after vermillion.
    let palette = robocal::report::figures::PALETTE.map(|c| [c.0, c.1, c.2]);
    let used = colours(&svg);
    for (i, colour) in palette.iter().enumerate().filter(|&(i, _)| i != 1) {
        assert!(used.contains(colour), "colour {i} {colour:?} not drawn: {used:?}");
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

/// The paper's first study, reduced (2 point sets x 2 runs, 100 test points), with its
/// Table 1 rows.
fn reduced_table1() -> robocal::simulation::Study {
    let text = include_str!("../../presets/paper-table1.toml")
        .replace("point_sets = 6", "point_sets = 2")
        .replace("runs_per_set = 16", "runs_per_set = 2")
        .replace("test_points = 1000", "test_points = 100");
    robocal::simulation::Study::from_toml_str(&text, |name| {
        robocal::io::load_model(name).map_err(|e| e.to_string())
    })
    .unwrap()
}

/// The paper's Figs. 1 and 2 as `reproduce` draws them: each histogram carries the paper's
/// Table 1 row (mean, SD, share above zero, lowest and highest), every histogram on one
/// x-range (the same ticks at the same places); N_p on a log axis ticked 12 to 192, with the
/// paper's five means as black squares, cited.
#[test]
fn the_papers_figures_carry_its_values_on_shared_and_log_axes() {
    let study = reduced_table1();
    let results = robocal::simulation::run(&study, &|| {}).unwrap();
    let figures = robocal::report::figures::study_figures(&study, &results).unwrap();
    let figure = |name: &str| &figures.iter().find(|f| f.0 == name).unwrap_or_else(|| panic!("{name}")).1;
    let np12 = words(figure("histogram-wls-np12-sigma0.svg"));
    assert!(np12.contains("paper's mean 3.97 (Zak et al., Table 1; SD 16.31, 67.7% > 0)"), "{np12}");
    assert!(np12.contains("paper's lowest -53 and highest 60.6"));
    assert!(np12.contains("this study's mean"));
    let np192 = words(figure("histogram-wls-np192-sigma0.svg"));
    assert!(np192.contains("paper's mean 21.71 (Zak et al., Table 1; SD 17.16, 89.6% > 0)"));
    // One x-range: the axis's tick labels (below the bars) alike in every histogram.
    let x_ticks = |svg: &str| -> Vec<(f64, String)> {
        (texts(svg).into_iter())
            .filter(|t| t.1 > 400.0 && t.2.parse::<f64>().is_ok())
            .map(|t| (t.0, t.2))
            .collect()
    };
    let histograms: Vec<&(String, String)> =
        figures.iter().filter(|f| f.0.starts_with("histogram-")).collect();
    assert_eq!(histograms.len(), 10, "5 cases x wls and wls-diag");
    let first = x_ticks(&histograms[0].1);
    assert!(
        first.iter().any(|t| t.1 == "-40") && first.len() >= 5,
        "the range reaches the paper's -53: {first:?}"
    );
    for (name, svg) in &histograms {
        assert_eq!(x_ticks(svg), first, "{name}: the same x-range as the others");
    }
    let fig2 = figure("improvement-vs-points-wls.svg");
    assert!(evenly_spaced(&tick_xs(fig2, &["12", "24", "48", "96", "192"])), "N_p on a log axis");
    assert!(words(fig2).contains("the paper's mean (Zak et al., Table 1)"));
    let document = roxmltree::Document::parse(fig2).unwrap();
    let squares =
        document.descendants().filter(|n| n.has_tag_name("rect") && n.attribute("fill") == Some("#000000"));
    assert_eq!(squares.count(), 5 + 1, "the paper's five means and the legend's square");
}

/// The replication panels keep their bars and tick labels inside: every bar stands on its
/// panel's x axis within the axis's span, and every text lies inside the canvas.
#[test]
fn replication_panels_are_not_clipped() {
    let mut study = reduced_table1();
    study.cases.truncate(1);
    let replications = robocal::simulation::replicate(&study, 4, &|| {}).unwrap();
    let figures = robocal::report::figures::replication_figures(&study, &replications).unwrap();
    assert_eq!(figures.len(), 2, "wls and wls-diag");
    for (name, svg) in &figures {
        assert!(words(svg).contains("vermillion line: the paper's value (Zak et al., Table 1)"), "{name}");
        let document = roxmltree::Document::parse(svg).unwrap();
        let number = |n: &roxmltree::Node, a: &str| n.attribute(a).unwrap().parse::<f64>().unwrap();
        let root = document.root_element();
        let (width, height) = (number(&root, "width"), number(&root, "height"));
        let mut axes = Vec::new();
        for n in document
            .descendants()
            .filter(|n| n.has_tag_name("polyline") && n.attribute("opacity") == Some("1"))
        {
            let p: Vec<f64> = (n.attribute("points").unwrap().split(|c: char| c == ',' || c.is_whitespace()))
                .filter(|t| !t.is_empty())
                .map(|t| t.parse().unwrap())
                .collect();
            if p.len() == 4 && p[1] == p[3] && p[2] - p[0] > 200.0 {
                axes.push((p[0], p[2], p[1]));
            }
        }
        let bars = document
            .descendants()
            .filter(|n| n.has_tag_name("rect") && n.attribute("fill") == Some("#0072B2"));
        let mut count = 0;
        for bar in bars {
            let (x, y, w, h) =
                (number(&bar, "x"), number(&bar, "y"), number(&bar, "width"), number(&bar, "height"));
            // The panel's axis: at the bar's foot, under the bar's middle.
            let on = axes.iter().find(|a| (y + h - a.2).abs() <= 2.0 && (a.0..a.1).contains(&(x + w / 2.0)));
            let (x0, x1, _) = on.unwrap_or_else(|| panic!("{name}: a bar at ({x}, {y}) on no axis"));
            assert!(x >= *x0 && x + w <= *x1, "{name}: the bar {x}..{} past its axis {x0}..{x1}", x + w);
            count += 1;
        }
        assert!(count >= 5, "{name}: the panels' bars");
        for (x, y, text) in texts(svg) {
            // At most about 0.6 of the font size per character, centred on x.
            let half = 0.3 * 10.0 * text.chars().count() as f64;
            let inside = x >= 0.0 && x <= width && y >= 0.0 && y <= height;
            assert!(inside, "{name}: `{text}` at ({x}, {y}) outside {width} x {height}");
            if text.parse::<f64>().is_ok() {
                assert!(x - half >= 0.0 && x + half <= width, "{name}: the tick `{text}` at {x} cut off");
            }
        }
    }
}
