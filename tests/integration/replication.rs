//! The study replicated over seeds: the same on any threads and one by one, and the clustered
//! intervals' coverage.

use robocal::io::load_model;
use robocal::report;
use robocal::simulation::{self, Study};

/// A small study whose tables are cheap: one case, `sets` point sets of `runs` runs, 100 test
/// points, OLS against WLS.
fn small_study(points: usize, sets: usize, runs: usize) -> Study {
    let text = include_str!("../../presets/paper-table1.toml")
        .replace("points = [12, 24, 48, 96, 192]", &format!("points = [{points}]"))
        .replace("point_sets = 6", &format!("point_sets = {sets}"))
        .replace("runs_per_set = 16", &format!("runs_per_set = {runs}"))
        .replace("test_points = 1000", "test_points = 100")
        .replace("estimators = [\"ols\", \"wls\", \"wls-diag\"]", "estimators = [\"ols\", \"wls\"]");
    Study::from_toml_str(&text, |name| load_model(name).map_err(|e| e.to_string())).unwrap()
}

#[test]
fn replications_are_the_same_on_any_threads_and_one_by_one() {
    let study = small_study(12, 2, 3);
    let with = |threads| {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        pool.install(|| simulation::replicate(&study, 4, &|| {}).unwrap())
    };
    let (one, two) = (with(1), with(2));
    assert_eq!(one, two);
    for (r, replication) in two.replications.iter().enumerate() {
        // Replication r is the study run alone with the derived seed.
        let alone = simulation::replication_study(&study, r);
        assert_eq!(alone.seed, simulation::replication_seed(study.seed, r));
        assert_eq!(
            *replication,
            simulation::Replication::of(&alone, &simulation::run(&alone, &|| {}).unwrap())
        );
    }
    assert_ne!(two.replications[0].clustered, two.replications[1].clustered);
    let files = report::replication::files(&study, &two).unwrap();
    let names: Vec<&str> = files.iter().map(|(name, _)| name.as_str()).collect();
    assert_eq!(names, ["replications.txt", "replications.csv", "replications-wls-np12-sigma0.svg"]);
    assert_eq!(files[1].1.lines().count(), 1 + 4);
    assert!(files[2].1.contains("paper 3.97"), "the paper's value is drawn");
}

/// The clustered 95% intervals of one study's MEAN and % > 0 hold: over 200 replications of a
/// small study (6 point sets x 8 runs at N_p = 12, 100 test points, seeded), each contains
/// the mean over the 200 replications in 93-97% of them. For an interval with exactly 95%
/// coverage the count is binomial (200, 0.95), SD 3.1: 186-194 of 200 is 95 ± 1.46 SD, which a
/// correct interval meets with probability 0.86, an interval covering 90% with probability
/// 0.09 and one covering 86% (the runs taken as independent, on the paper's study) 0.002.
#[test]
fn the_clustered_interval_covers_the_mean_of_200_replications() {
    let study = small_study(12, 6, 8);
    let replications = simulation::replicate(&study, 200, &|| {}).unwrap();
    let coverage = replications.coverage(0, 1);
    eprintln!("{coverage:?}");
    assert!((93.0..=97.0).contains(&coverage.mean_clustered), "{coverage:?}");
    assert!((93.0..=97.0).contains(&coverage.share_clustered), "{coverage:?}");
    // The runs taken as independent: narrower than needed, and covering less.
    assert!(coverage.half_width_independent < coverage.half_width_needed, "{coverage:?}");
    assert!(coverage.mean_independent < coverage.mean_clustered, "{coverage:?}");
}

#[test]
fn the_replication_count_is_checked_on_the_command_line() {
    for (count, message) in
        [("0", "from 1 to 10000, found 0"), ("10001", "found 10001"), ("many", "expected a whole number")]
    {
        let output = assert_cmd::Command::cargo_bin("robocal")
            .unwrap()
            .args(["simulate", "paper-table1", "--replications", count])
            .output()
            .unwrap();
        assert_eq!(output.status.code(), Some(2));
        let stderr = String::from_utf8_lossy(&output.stderr);
        assert!(stderr.contains("--replications") && stderr.contains(message), "{stderr}");
    }
}
