//! The planner: planned sets against random ones, determinism, constraints, errors; planned
//! poses in the simulation.

use rand::SeedableRng;
use rand::rngs::ChaCha8Rng;
use robocal::design::{Constraints, Criterion, Design, DesignError, ExcludedRange, Plan, PlanProgress};
use robocal::estimation::{MeasurementNoise, NoiseModel};
use robocal::kinematics::{Chain, Measured};
use robocal::model::{RobotModel, Selection};

/// The paper's setting: the PUMA 560's 30 joint parameters from positions, its joint noise,
/// `sigma_me` = 0.01 mm.
fn puma_design() -> Design {
    let model = RobotModel::preset("puma560").unwrap();
    let selection = Selection::joints(&model.params());
    let sigmas: Vec<f64> =
        [0.007, 0.007, 0.007, 0.002, 0.002, 0.002].iter().map(|s: &f64| s.to_radians()).collect();
    let noise = NoiseModel::diagonal(&sigmas, MeasurementNoise::isotropic(0.01, 0.0));
    Design::new(&model, selection, Measured::Position, Some(noise)).unwrap()
}

#[test]
fn planned_sets_beat_the_best_of_100_random_sets() {
    let design = puma_design();
    for (criterion, points) in [(Criterion::D, 24), (Criterion::O3, 24), (Criterion::O5, 12)] {
        let started = std::time::Instant::now();
        let (plan, _) = design.plan_seeded(points, 2000, &Constraints::default(), criterion, 11).unwrap();
        eprintln!("{criterion}: {:?} {} passes {} exchanges", started.elapsed(), plan.passes, plan.exchanges);
        let mut rng = ChaCha8Rng::seed_from_u64(99);
        let best = (0..100)
            .map(|_| {
                design.criterion(&design.model().uniform_configurations(points, &mut rng), criterion).unwrap()
            })
            .fold(f64::NEG_INFINITY, f64::max);
        eprintln!("{criterion}: planned {} (from {}), best random {best}", plan.value, plan.initial);
        assert!(plan.value > best, "{criterion}: planned {} <= best of 100 random {best}", plan.value);
    }
}

/// The progress a plan reports, for a bar with the time left: the candidates' rows in steps of
/// 1024 from 0, then every pose of every pass in order, pass after pass, as many passes as the
/// plan made; the plan itself is the one planned without a listener.
#[test]
fn planning_reports_its_progress_pass_by_pass() {
    let design = puma_design();
    for criterion in [Criterion::D, Criterion::O3] {
        let seen = std::cell::RefCell::new(Vec::new());
        let (plan, pool) = design
            .plan_seeded_reporting(16, 3000, &Constraints::default(), criterion, 5, &|p| {
                seen.borrow_mut().push(p)
            })
            .unwrap();
        assert_eq!(plan, design.plan_seeded(16, 3000, &Constraints::default(), criterion, 5).unwrap().0);
        let seen = seen.into_inner();
        let rows: Vec<PlanProgress> =
            (0..3000).step_by(1024).map(|done| PlanProgress::Rows { done, of: 3000 }).collect();
        assert_eq!(seen[..rows.len()], rows[..], "{criterion}");
        assert_eq!(pool.joints.len(), 3000);
        let passes: Vec<PlanProgress> = (1..=plan.passes)
            .flat_map(|pass| (0..16).map(move |done| PlanProgress::Pass { pass, done, of: 16 }))
            .collect();
        assert_eq!(seen[rows.len()..], passes[..], "{criterion}: {} passes", plan.passes);
        assert!(plan.passes >= 2 && plan.passes <= 2 * Plan::MAX_PASSES, "{criterion}: {}", plan.passes);
    }
}

#[test]
fn planning_is_deterministic_for_a_seed() {
    let design = puma_design();
    let plan = |seed| design.plan_seeded(16, 600, &Constraints::default(), Criterion::D, seed).unwrap().0;
    let (a, b, c) = (plan(3), plan(3), plan(4));
    assert_eq!(a, b);
    assert_ne!(a.joints, c.joints);
    // The pool's first poses are the starting set; a better set was found and it is no worse
    // than the start.
    assert!(a.exchanges > 0 && a.value > a.initial);
}

#[test]
fn planned_poses_keep_to_the_constraints() {
    let design = puma_design();
    let model = design.model().clone();
    let low = nalgebra::Vector3::new(-600.0, -600.0, 0.0);
    let high = nalgebra::Vector3::new(600.0, 600.0, 900.0);
    let excluded = ExcludedRange { joint: 1, range: [-30f64.to_radians(), 10f64.to_radians()] };
    let constraints = Constraints { tool_box: Some([low, high]), excluded: vec![excluded] };
    let (plan, pool) = design.plan_seeded(16, 500, &constraints, Criterion::D, 1).unwrap();
    assert_eq!(pool.joints.len(), 500);
    assert!(pool.draws > 500, "the box and the range reject some draws");
    let chain = Chain::new(&model);
    let nominal = chain.with_errors(&vec![0.0; chain.params().len()]);
    for q in &plan.joints {
        let p = nominal.position(q);
        assert!((0..3).all(|i| p[i] >= low[i] && p[i] <= high[i]), "tool at {p:?}");
        assert!(q[1] < excluded.range[0] || q[1] > excluded.range[1], "j2 at {}", q[1].to_degrees());
        for (v, joint) in q.iter().zip(&model.joints) {
            assert!(*v >= joint.limits[0] && *v <= joint.limits[1]);
        }
    }
}

#[test]
fn planning_errors_say_what_is_wrong() {
    let design = puma_design();
    let none = Constraints::default();
    let few = design.plan_seeded(7, 100, &none, Criterion::D, 1).unwrap_err();
    assert_eq!(
        few.to_string(),
        "7 poses give 21 equations for 23 identifiable parameters: plan at least 8 poses"
    );
    let far =
        [nalgebra::Vector3::new(5000.0, 5000.0, 5000.0), nalgebra::Vector3::new(6000.0, 6000.0, 6000.0)];
    let nowhere = Constraints { tool_box: Some(far), excluded: Vec::new() };
    let empty = design.plan_seeded(8, 10, &nowhere, Criterion::D, 1).unwrap_err();
    assert!(matches!(empty, DesignError::EmptyPool { draws: 1000, .. }), "{empty:?}");
    assert!(empty.to_string().starts_with("no candidate pose within the joint limits satisfies"), "{empty}");
    let small = design.plan_seeded(12, 10, &none, Criterion::D, 1).unwrap_err();
    assert_eq!(small, DesignError::PoolTooSmall { usable: 10, points: 12 });
    let mut bad_pool = vec![vec![0.0; 6]; 12];
    bad_pool[4][2] = f64::NAN;
    let nan = design.plan(&bad_pool, 8, Criterion::D).unwrap_err();
    assert_eq!(nan.to_string(), "pose 5, joint j3: NaN is not a finite number");
    let reversed = ExcludedRange { joint: 0, range: [1.0, -1.0] };
    let reversed = Constraints { tool_box: None, excluded: vec![reversed] };
    let message = design.plan_seeded(8, 10, &reversed, Criterion::D, 1).unwrap_err().to_string();
    assert!(message.contains("excluded range of j1: expected finite values, lowest first"), "{message}");
}

fn robocal() -> assert_cmd::Command {
    assert_cmd::Command::cargo_bin("robocal").unwrap()
}

const NOISE: [&str; 4] = ["--joint-sigma-deg", "0.007,0.007,0.007,0.002,0.002,0.002", "--sigma-mm", "0.01"];

#[test]
fn plan_writes_poses_that_observability_reads() {
    let dir = std::env::temp_dir().join(format!("robocal-plan-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("poses.csv");
    let output = robocal()
        .args(["plan", "--model", "puma560", "--points", "12", "--candidates", "400", "--seed", "5"])
        .args(NOISE)
        .args(["--exclude", "j3:-20:20", "--out", path.to_str().unwrap()])
        .output()
        .unwrap();
    assert!(output.status.success(), "{}", String::from_utf8_lossy(&output.stderr));
    let summary = String::from_utf8(output.stdout).unwrap();
    assert!(summary.contains("planned 12 poses of puma560 from 400 candidates"), "{summary}");
    let text = std::fs::read_to_string(&path).unwrap();
    assert!(text.starts_with("# units: joints=deg, lengths=mm\n"), "{text}");
    let model = RobotModel::preset("puma560").unwrap();
    let poses = robocal::design::poses_from_csv_str(&text, &model, None).unwrap();
    assert_eq!(poses.len(), 12);
    assert!(poses.iter().all(|q| q[2].to_degrees().abs() > 20.0));
    // The D value in the summary is the whitened log det that `observability` prints.
    let value =
        |text: &str, key: &str| -> String { text.lines().find(|l| l.contains(key)).unwrap().to_string() };
    let planned = value(&summary, "criterion d on the whitened H");
    let planned: f64 = planned.split(": ").nth(1).unwrap().split(' ').next().unwrap().parse().unwrap();
    let output = robocal()
        .args(["observability", path.to_str().unwrap(), "--model", "puma560"])
        .args(NOISE)
        .output()
        .unwrap();
    let report = String::from_utf8(output.stdout).unwrap();
    let row = value(&report, "log det");
    let whitened: f64 = row.split_whitespace().last().unwrap().parse().unwrap();
    assert!((whitened - planned).abs() < 1e-2, "planned {planned}, read back {whitened}");
    // Deterministic: the same command writes the same file.
    let again = robocal()
        .args(["plan", "--model", "puma560", "--points", "12", "--candidates", "400", "--seed", "5"])
        .args(NOISE)
        .args(["--exclude", "j3:-20:20"])
        .output()
        .unwrap();
    assert_eq!(String::from_utf8(again.stdout).unwrap(), text);
}

#[test]
fn plan_rejects_bad_requests_with_a_message() {
    let cases: [(&[&str], i32, &str); 5] = [
        (
            &["--points", "4"],
            1,
            "4 poses give 12 equations for 23 identifiable parameters: plan at least 8 poses",
        ),
        (
            &["--points", "12", "--tool-box", "3000,3000,3000,4000,4000,4000"],
            1,
            "no candidate pose within the joint limits satisfies the constraints (joint limits, tool in the box",
        ),
        (&["--points", "12", "--exclude", "j9:0:10"], 1, "--exclude `j9:0:10`: no joint `j9`"),
        (
            &["--points", "12", "--exclude", "j2:10"],
            2,
            "'j2:10' for '--exclude <JOINT:FROM:TO>': expected JOINT:FROM:TO",
        ),
        (
            &["--points", "12", "--tool-box", "1,2,3"],
            2,
            "'1,2,3' for '--tool-box <XMIN,YMIN,ZMIN,XMAX,YMAX,ZMAX>': expected six finite numbers",
        ),
    ];
    for (args, code, expected) in cases {
        let output =
            robocal().args(["plan", "--model", "puma560", "--candidates", "50"]).args(args).output().unwrap();
        assert_eq!(output.status.code(), Some(code), "{args:?}");
        let message = String::from_utf8(output.stderr).unwrap();
        assert!(message.contains(expected), "{args:?}: {message}");
    }
    let output = robocal()
        .args(["plan", "--model", "puma560", "--points", "12", "--criterion", "o9"])
        .output()
        .unwrap();
    assert_eq!(output.status.code(), Some(2));
    assert!(String::from_utf8(output.stderr).unwrap().contains("unknown criterion `o9`"));
}

/// A reduced `planned-poses` study: N_p = 12 and 24, sigma_me = 0 and 0.05 mm, random and
/// D-optimal poses from 1000 candidates.
fn planned_study(points: &str, sets: usize, runs: usize) -> robocal::simulation::Study {
    let text = format!(
        r#"
name = "planned"
robot = "puma560"
measured = "position"
parameters = "joints"
estimators = ["ols", "wls"]
seed = 1991
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
sigma_me_mm = [0.0, 0.05]

[design]
poses = ["random", "planned"]
candidates = 1000
"#
    );
    robocal::simulation::Study::from_toml_str(&text, robocal::io::load_model).unwrap()
}

/// How many standard errors a mean reduction must clear: the two-sided 99.9% point of
/// Student's t is below 3.6 for 30 or more degrees of freedom. (Runs on one point set share
/// their poses, so the run-level standard error is somewhat optimistic; the margins below are
/// 5-10 of them.)
const MARGIN: f64 = 3.6;

#[test]
fn planned_poses_lower_e_p_at_12_and_24_points() {
    use robocal::simulation::{PoseChoice, Summary, improvement};
    let study = planned_study("[12, 24]", 6, 12);
    let results = robocal::simulation::run(&study, &|| {}).unwrap();
    let mut report = String::new();
    for (p, case) in study.cases.iter().enumerate().filter(|(_, c)| c.poses != PoseChoice::Random) {
        let r = study
            .cases
            .iter()
            .position(|c| {
                c.poses == PoseChoice::Random && c.points == case.points && c.sigma_me == case.sigma_me
            })
            .unwrap();
        for (e, estimator) in study.estimators.iter().enumerate() {
            let runs = |c: usize| results.runs.iter().filter(move |run| run.case == c);
            let reductions: Vec<f64> = runs(r)
                .zip(runs(p))
                .map(|(a, b)| improvement(a.accuracy[e].mean, b.accuracy[e].mean))
                .collect();
            let s = Summary::of(&reductions);
            let se = s.sd / (s.n as f64).sqrt();
            report += &format!(
                "N_p {} sigma {} {estimator}: {:.1} % ± {:.1} (SE)\n",
                case.points, case.sigma_me, s.mean, se
            );
            // OLS on poses planned for the weighted estimator gains little without measurement
            // noise (the study's figure: 7-8 % ± 3); everything else must clearly gain.
            if !(estimator.estimator.name() == "ols" && case.sigma_me == 0.0) {
                assert!(s.mean > MARGIN * se, "{report}");
                assert!(results.mean_error(p, e) < results.mean_error(r, e), "{report}");
            }
        }
    }
    eprintln!("{report}");
}

#[test]
fn planned_studies_do_not_depend_on_the_thread_count() {
    let study = planned_study("[12]", 2, 2);
    let on = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        pool.install(|| robocal::simulation::run(&study, &|| {}).unwrap())
    };
    // Compared as text: the orientation errors of a position study are NaN, never equal.
    let one = on(1);
    assert_eq!(format!("{one:?}"), format!("{:?}", on(3)));
    assert_eq!(one.runs.len(), 4 * 2 * 2, "2 sigmas x (random, planned) x 2 sets x 2 runs");
}

#[test]
fn study_files_reject_a_bad_design_table() {
    let base = include_str!("../../presets/planned-poses.toml");
    let load = |text: &str| robocal::simulation::Study::from_toml_str(text, robocal::io::load_model);
    assert_eq!(load(base).unwrap().cases.len(), 4 * 2 * 2);
    for (from, to, expected) in [
        ("candidates = 2000", "candidates = 50", "field `design.candidates`: from the largest N_p (96)"),
        (r#"criterion = "d""#, r#"criterion = "e""#, "field `design.criterion`: unknown criterion `e`"),
        (r#"poses = ["random", "planned"]"#, r#"poses = ["random", "clever"]"#, r#"found "clever""#),
        (r#"poses = ["random", "planned"]"#, r#"poses = ["planned", "planned"]"#, r#""planned" given twice"#),
    ] {
        let message = load(&base.replace(from, to)).unwrap_err().to_string();
        assert!(message.contains(expected), "{message}");
    }
}
