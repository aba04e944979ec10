//! The simulated study: the paper's trends, reproducibility across thread counts, study files.

use robocal::io::load_model;
use robocal::report;
use robocal::simulation::{self, Study, StudyResults, Summary};

/// A study of the PUMA 560 like the paper's, with the cases, point sets and runs given and
/// 300 test points.
fn reduced_study(points: &str, sigmas: &str, sets: usize, runs: usize) -> Study {
    let text = format!(
        r#"
name = "reduced"
robot = "puma560"
measured = "position"
parameters = "joints"
estimators = ["ols", "wls", "wls-diag"]
seed = 7
point_sets = {sets}
runs_per_set = {runs}
test_points = 300

[noise]
joint_sigma = [0.007, 0.007, 0.007, 0.002, 0.002, 0.002]

[errors]
offset_deg = 0.1
angle_deg = 0.05
length_mm = 0.5
redraw = "run"

[cases]
points = {points}
sigma_me_mm = {sigmas}
"#
    );
    Study::from_toml_str(&text, |name| load_model(name).map_err(|e| e.to_string())).unwrap()
}

fn run(study: &Study) -> StudyResults {
    simulation::run(study, &|| {}).unwrap()
}

/// How many standard errors a difference must clear: the two-sided 99.9% point of Student's
/// t is below 3.5 for 20 or more degrees of freedom.
const MARGIN: f64 = 3.5;

#[test]
fn the_papers_trends_hold_on_a_reduced_study() {
    let study = reduced_study("[12, 48]", "[0.0, 0.1]", 6, 16);
    let results = run(&study);
    let case = |points: usize, sigma: f64| {
        study.cases.iter().position(|c| c.points == points && c.sigma_me == sigma).unwrap()
    };
    for (e, name) in [(1, "wls"), (2, "wls-diag")] {
        let at48 = Summary::of(&results.improvements(case(48, 0.0), e));
        let at12 = Summary::of(&results.improvements(case(12, 0.0), e));
        let se = |s: &Summary| s.sd / (s.n as f64).sqrt();
        assert!(at48.mean > MARGIN * se(&at48), "{name}: dE at N_p = 48 is {} ± {}", at48.mean, se(&at48));
        let gap = at48.mean - at12.mean;
        let gap_se = (se(&at48).powi(2) + se(&at12).powi(2)).sqrt();
        assert!(
            gap > MARGIN * gap_se,
            "{name}: dE at 48 ({}) not clearly above 12 ({})",
            at48.mean,
            at12.mean
        );

        // The same runs with and without measurement noise (common random numbers): paired.
        let quiet = results.improvements(case(48, 0.0), e);
        let noisy = results.improvements(case(48, 0.1), e);
        let drop: Vec<f64> = quiet.iter().zip(&noisy).map(|(a, b)| a - b).collect();
        let d = Summary::of(&drop);
        assert!(
            d.mean > MARGIN * se(&d),
            "{name}: dE does not fall with sigma_me: drop {} ± {}",
            d.mean,
            se(&d)
        );
    }
    assert!(results.ranks.iter().all(|&(_, _, rank)| rank == 23), "{:?}", results.ranks);
    let repeatability = results.joint_noise_error;
    assert!(
        (0.07..0.15).contains(&repeatability),
        "the paper's joint noise gives about 0.1 mm: {repeatability}"
    );
}

#[test]
fn the_same_seed_gives_the_same_csv_on_one_and_two_threads() {
    let study = reduced_study("[12, 24]", "[0.0, 0.05]", 2, 4);
    let csv_with = |threads| {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        pool.install(|| report::study::samples_csv(&study, &run(&study)))
    };
    let (one, two) = (csv_with(1), csv_with(2));
    assert_eq!(one.lines().count(), 1 + 4 * 2 * 4);
    assert_eq!(one, two);
}

#[test]
fn cases_differing_only_in_noise_share_their_random_numbers() {
    // The draws must not depend on sigma_me: a vanishing noise changes dE by next to nothing.
    let study = reduced_study("[24]", "[0.0, 1e-9]", 2, 3);
    let results = run(&study);
    for (a, b) in results.improvements(0, 1).iter().zip(results.improvements(1, 1)) {
        assert!((a - b).abs() < 1e-4, "dE {a} vs {b}");
    }
}

#[test]
fn study_tables_snapshot() {
    let study = reduced_study("[12, 24]", "[0.0]", 2, 3);
    let results = run(&study);
    insta::assert_snapshot!(report::study::tables(&study, &results));
}

fn study_error(replace: &str, with: &str) -> String {
    let text = include_str!("../../presets/paper-table1.toml").replacen(replace, with, 1);
    assert_ne!(text, include_str!("../../presets/paper-table1.toml"), "the test must change the file");
    Study::from_toml_str(&text, |name| load_model(name).map_err(|e| e.to_string())).unwrap_err().to_string()
}

#[test]
fn bad_study_files_say_what_is_wrong() {
    let message = study_error("runs_per_set", "runs_per_sett");
    assert!(message.contains("runs_per_sett") && message.contains("line"), "{message}");
    assert_eq!(
        study_error("0.002, 0.002]", "0.002]"),
        "field `noise.joint_sigma`: 6 values, one per joint of puma560"
    );
    assert!(study_error("\"wls\", ", "\"gls\", ").contains("unknown estimator `gls`"));
    assert_eq!(
        study_error("length_mm = 0.5", "length_mm = -0.5"),
        "field `errors.length_mm`: finite values >= 0, found -0.5"
    );
    assert!(
        study_error("robot = \"puma560\"", "robot = \"puma600\"")
            .starts_with("field `robot`: no model `puma600`")
    );
    assert_eq!(study_error("point_sets = 6", "point_sets = 0"), "field `point_sets`: at least 1");
    assert_eq!(
        study_error("parameters = \"joints\"", "parameters = []"),
        "field `parameters`: at least one parameter"
    );
    assert!(study_error("redraw = \"run\"", "redraw = \"always\"").contains("run"));
}

#[test]
fn a_pose_study_measures_orientation_too() {
    let text = include_str!("../../presets/paper-table1.toml")
        .replace("measured = \"position\"", "measured = \"pose\"")
        .replace("points = [12, 24, 48, 96, 192]", "points = [24]")
        .replace("point_sets = 6", "point_sets = 2")
        .replace("runs_per_set = 16", "runs_per_set = 4")
        .replace("[noise]", "[noise]\nsigma_orientation_deg = 0.001");
    let study = Study::from_toml_str(&text, |name| load_model(name).map_err(|e| e.to_string())).unwrap();
    let results = run(&study);
    // 6 rows a point: the orientation rows make two more combinations identifiable (23 -> 25).
    assert!(results.ranks.iter().all(|&(_, _, rank)| rank == 25), "{:?}", results.ranks);
    for r in &results.runs {
        assert!(r.accuracy.iter().all(|a| a.orientation.is_finite() && a.orientation > 0.0));
    }
    let csv = report::study::samples_csv(&study, &results);
    assert!(csv.lines().next().unwrap().contains("wls_e_r_mean_deg"));
    assert!(!csv.lines().nth(1).unwrap().contains(",,"), "every orientation column is filled");
}
