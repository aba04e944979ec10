//! Several chains: a torso with two arms and a head camera, calibrated in one fit from the head
//! camera's views of both hands (issue #16, point 5).

use nalgebra::{DMatrix, DVector, Isometry3};
use proptest::prelude::*;
use rand::rngs::ChaCha8Rng;
use rand::{RngExt, SeedableRng};
use robocal::calibration::Held;
use robocal::calibration::kinds::KindOptions;
use robocal::calibration::tree::{
    Frame, Role, TreeCalibration, TreeData, TreeParams, TreeRows, calibrate_tree, cross_validate_tree,
};
use robocal::calibration::{Gauge, JointParams, Loss, Unseen, Warning};
use robocal::estimation::{Estimator, MeasurementClass, PriorEntry, Residuals, SigmaInterval};
use robocal::model::RobotTree;
use robocal::simulation::tree::{frame_at, perturbed_tree, simulate_views};

use crate::kinds::h_matches_central_differences;

const TORSO: &str = include_str!("../../presets/torso.urdf");

fn torso() -> RobotTree {
    RobotTree::from_urdf_str(TORSO, None, &[]).unwrap()
}

/// The head camera and a target on each hand, and their true placements (mm, rad).
fn frames(tree: &RobotTree) -> (Vec<Frame>, Vec<f64>) {
    let on = |tip: &str| Some(tree.branch(tip).unwrap());
    let frames = vec![
        Frame { role: Role::Camera, on: on("head_camera") },
        Frame { role: Role::Target, on: on("l_hand") },
        Frame { role: Role::Target, on: on("r_hand") },
    ];
    let placements = vec![
        12.0, -4.0, 8.0, 0.05, -0.03, 0.02, //
        3.0, 5.0, -40.0, 0.2, -0.1, 0.3, //
        -2.0, 4.0, -35.0, -0.15, 0.1, -0.2,
    ];
    (frames, placements)
}

/// The head camera sees each hand's target.
const PAIRS: [(usize, usize); 2] = [(0, 1), (0, 2)];

fn options(estimator: Estimator) -> KindOptions {
    KindOptions { estimator, joint_noise: None, joints: JointParams::All, ..KindOptions::default() }
}

#[test]
fn a_urdf_tree_reads_as_its_branches_sharing_their_joints() {
    let tree = torso();
    let tips: Vec<&str> = tree.branches.iter().map(|b| b.tip.as_str()).collect();
    assert_eq!(tips, ["head_camera", "l_hand", "r_hand"]);
    assert_eq!(tree.dof(), 15, "torso, 2 head joints, 6 per arm");
    for branch in &tree.branches {
        assert_eq!(branch.joints[0], 0, "every branch starts at the shared torso joint");
        assert_eq!(branch.model.joints[0].name, "torso");
    }
    assert_eq!(tree.branches[1].joints, [0, 3, 4, 5, 6, 7, 8]);
    // One parameter per name: the torso's 7 once, the base's 6 once.
    let params = TreeParams::new(&tree);
    assert_eq!(params.len(), 6 + 7 * 15);
    // A tip that is no link, and a serial arm, are refused by name.
    let error = RobotTree::from_urdf_str(TORSO, None, &["l_hand".into(), "nose".into()]).unwrap_err();
    assert!(format!("{error:#}").contains("nose"), "{error:#}");
    let error = RobotTree::from_urdf_str(TORSO, None, &["l_hand".into()]).unwrap_err();
    assert!(error.to_string().contains("two tips or more"), "{error}");
}

/// A random tree near the torso, its frames and one pose of views; `H` of the problem over
/// every tree parameter and every frame parameter.
fn check_tree_jacobian(seed: u64) -> Result<(), TestCaseError> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    // Every other tree lifts its torso: a prismatic joint shared by every branch.
    let nominal = match seed % 2 {
        0 => torso(),
        _ => {
            let lifting = TORSO.replace(
                r#"<joint name="torso" type="revolute">"#,
                r#"<joint name="torso" type="prismatic">"#,
            );
            assert_ne!(lifting, TORSO);
            let tree = RobotTree::from_urdf_str(&lifting, None, &[]).unwrap();
            assert_eq!(tree.joints[0].kind, robocal::model::JointKind::Prismatic);
            tree
        }
    };
    let tree = perturbed_tree(&nominal, 20.0, 0.2, &mut rng);
    let (mut frames, mut placements) = frames(&tree);
    // A camera and a target fixed in the world too.
    frames.extend([Frame { role: Role::Camera, on: None }, Frame { role: Role::Target, on: None }]);
    placements.extend([1500.0, 100.0, 1200.0, 0.1, -1.4, 0.2, 600.0, -300.0, 200.0, 0.3, 0.2, -0.1]);
    let q = tree.uniform_configurations(1, &mut rng);
    // Views of another tree, so that the residuals (and J_r^-1) are not zero.
    let other = perturbed_tree(&nominal, 20.0, 0.3, &mut rng);
    let pairs = [(0, 1), (0, 2), (1, 2), (3, 1), (0, 4), (3, 2)];
    let data = simulate_views(&other, &frames, &placements, &pairs, &q, [0.0; 2], &mut rng);
    let params = TreeParams::new(&tree);
    let x: Vec<f64> =
        (0..params.len()).map(|i| 0.01 * ((i * 7919 + seed as usize) % 13) as f64 - 0.06).collect();
    let all: Vec<usize> = (0..params.len()).collect();
    let every: Vec<usize> = (0..placements.len()).collect();
    let all = params.selection(&all);
    let rows = TreeRows::new(&params, &data, &data.frames).unwrap();
    let values = (x.clone(), placements.clone(), every.clone());
    let problem = rows.problem(&params, &all, values, None);
    let views = &data.views;
    h_matches_central_differences(&problem, &problem.start(), |r| format!("{:?}", views[r / 6]))?;
    // A tracker's positions of points on the hands.
    let tracked = simulate_views(&other, &frames, &placements, &[(3, 1), (3, 2)], &q, [0.0; 2], &mut rng);
    let tracked = tracked.positions_only();
    let rows = TreeRows::new(&params, &tracked, &tracked.frames).unwrap();
    let problem = rows.problem(&params, &all, (x, placements, every), None);
    h_matches_central_differences(&problem, &problem.start(), |r| format!("{:?}", tracked.views[r / 3]))
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(1000))]

    #[test]
    fn tree_view_jacobians_match_finite_differences(seed in any::<u64>()) {
        check_tree_jacobian(seed)?;
    }
}

/// The frames' placements composed at `q` on `tree`: each target seen from the camera, and the
/// right hand's target seen from the left's (never measured).
fn relative_frames(tree: &RobotTree, frames: &[Frame], placements: &[f64], q: &[f64]) -> [Isometry3<f64>; 3] {
    let at = |f: usize| frame_at(tree, &frames[f], &placements[6 * f..6 * f + 6], q);
    [at(0).inverse() * at(1), at(0).inverse() * at(2), at(1).inverse() * at(2)]
}

/// The largest position (mm) and rotation (rad) gap between the calibrated and the true
/// relative frames over `configurations`.
fn largest_gap(
    c: &TreeCalibration,
    truth: &RobotTree,
    placements: &[f64],
    configurations: &[Vec<f64>],
) -> (f64, f64) {
    let (mut mm, mut rad) = (0.0f64, 0.0f64);
    for q in configurations {
        let real = relative_frames(truth, c.frames(), placements, q);
        let found = relative_frames(&c.calibrated, c.frames(), &c.setup_values.1, q);
        for (r, f) in real.iter().zip(&found) {
            let gap = r.inverse() * f;
            mm = mm.max(gap.translation.vector.norm());
            rad = rad.max(gap.rotation.angle());
        }
    }
    (mm, rad)
}

#[test]
fn one_fit_of_a_head_camera_seeing_both_hands_recovers_every_chain() {
    let mut rng = ChaCha8Rng::seed_from_u64(16);
    let nominal = torso();
    let truth = perturbed_tree(&nominal, 1.0, 0.005, &mut rng);
    let (frames, placements) = frames(&nominal);
    let training = nominal.uniform_configurations(60, &mut rng);
    let data = simulate_views(&truth, &frames, &placements, &PAIRS, &training, [0.0; 2], &mut rng);
    let c = calibrate_tree(&nominal, &data, &options(Estimator::Ols)).unwrap();
    assert!(c.training.view_position.unwrap().1 < 1e-7, "training {:?} mm", c.training.view_position);
    assert!(
        c.training.view_position.unwrap().0 > 1.0,
        "the nominal tree is off: {:?} mm",
        c.training.view_position
    );
    // Held out: every view, and the two hands relative to each other, which no view measures.
    let held_out = nominal.uniform_configurations(40, &mut rng);
    let (mm, rad) = largest_gap(&c, &truth, &placements, &held_out);
    assert!(mm < 1e-6 && rad < 1e-9, "held-out gap {mm} mm, {rad} rad");
    let before = {
        let nothing = calibrate_tree(
            &nominal,
            &data,
            &KindOptions { joints: JointParams::None, ..options(Estimator::Ols) },
        )
        .unwrap();
        largest_gap(&nothing, &truth, &placements, &held_out)
    };
    assert!(before.0 > 1.0, "the frames alone leave {} mm", before.0);
    // What the views cannot see: the base, and the torso, which moves the camera and the hands
    // alike.
    assert_eq!(c.unseen, [Unseen::TreeBase { world: None }]);
    assert!(c.unseen[0].to_string().starts_with("base.*: a view sees one frame relative to another"));
    for name in ["torso.x", "torso.rz", "torso.theta"] {
        assert!(
            c.fixed.iter().map(Held::text).any(|f| f.starts_with(&format!(
                "{name}: its joint is on the way to both frames of every view past it"
            ))),
            "{name}: {:?}",
            c.fixed
        );
    }
    assert!(c.refined.estimate.names.iter().all(|n| !n.starts_with("torso.") && !n.starts_with("base.")));
    // Each arm and the head are estimated.
    for joint in ["head_tilt", "l_elbow", "r_wrist_pitch"] {
        assert!(c.refined.estimate.names.iter().any(|n| n.starts_with(&format!("{joint}."))), "{joint}");
    }
}

/// A tree's fit warns of an ill-conditioned system as a serial arm's does: views at poses
/// spread over the joints' range calibrate without the warning; views at poses clustered
/// within 1e-7 rad of one configuration, rank-full in the joint offsets, with it.
#[test]
fn a_badly_conditioned_tree_is_warned() {
    let mut rng = ChaCha8Rng::seed_from_u64(23);
    let nominal = torso();
    let truth = perturbed_tree(&nominal, 1.0, 0.005, &mut rng);
    let (frames, placements) = frames(&nominal);
    let spread = nominal.uniform_configurations(60, &mut rng);
    let centre = spread[0].clone();
    let clustered: Vec<Vec<f64>> =
        (0..60).map(|_| centre.iter().map(|c| c + 1e-7 * rng.random_range(-1.0..1.0)).collect()).collect();
    for (poses, warned) in [(spread, false), (clustered, true)] {
        let data = simulate_views(&truth, &frames, &placements, &PAIRS, &poses, [0.0; 2], &mut rng);
        let offsets = KindOptions { joints: JointParams::Offsets, ..options(Estimator::Ols) };
        let c = calibrate_tree(&nominal, &data, &offsets).unwrap();
        let warning = (c.warnings.iter())
            .find(|w| matches!(w, robocal::calibration::Warning::IllConditioned { .. }))
            .map(ToString::to_string);
        let d = &c.refined.estimate.diagnostics;
        assert_eq!(
            warning.is_some(),
            warned,
            "condition {:e}, rank {}: {:?}",
            d.condition_number,
            d.rank,
            c.warnings
        );
        if let Some(warning) = warning {
            assert!(warning.contains("above 1e6: the estimates are poorly determined"), "{warning}");
        }
    }
}

#[test]
fn tree_estimates_with_noise_fall_within_three_standard_errors() {
    let mut rng = ChaCha8Rng::seed_from_u64(61);
    let nominal = torso();
    let params = TreeParams::new(&nominal);
    let (frames, placements) = frames(&nominal);
    let training = nominal.uniform_configurations(80, &mut rng);
    // What the views identify: the estimate of exact views of any tree.
    let exact = simulate_views(&nominal, &frames, &placements, &PAIRS, &training, [0.0; 2], &mut rng);
    let kept = calibrate_tree(&nominal, &exact, &options(Estimator::Ols)).unwrap().refined.estimate.names;
    // A true tree with errors on those, views with noise of 0.05 mm and 0.01 deg.
    let mut truth_x = vec![0.0; params.len()];
    for (i, p) in params.params.iter().enumerate() {
        if kept.contains(&p.name) {
            truth_x[i] = if p.is_angle() { 0.003 } else { 0.8 } * (((i * 37) % 11) as f64 / 5.0 - 1.0);
        }
    }
    let truth = params.fold(&nominal, &truth_x);
    let sigma = [0.05, 0.01f64.to_radians()];
    let noisy = simulate_views(&truth, &frames, &placements, &PAIRS, &training, sigma, &mut rng);
    let c = calibrate_tree(&nominal, &noisy, &options(Estimator::Wls)).unwrap();
    let se = c.refined.estimate.standard_errors();
    let frame_names: Vec<String> = c
        .frame_names()
        .iter()
        .flat_map(|f| ["x", "y", "z", "rx", "ry", "rz"].map(|a| format!("{f}.{a}")))
        .collect();
    let mut checked = 0;
    for (k, name) in c.refined.estimate.names.iter().enumerate() {
        let (found, real) = match params.params.iter().position(|p| p.name == *name) {
            Some(i) => (c.after[i], truth_x[i]),
            None => {
                let i = frame_names.iter().position(|n| n == name).unwrap();
                (c.setup_values.1[i], placements[i])
            }
        };
        assert!((found - real).abs() < 3.0 * se[k], "{name}: {found} against {real}, SE {}", se[k]);
        checked += 1;
    }
    assert!(checked >= 60, "{checked} estimates checked");
}

#[test]
fn tree_view_files_read_and_their_errors() {
    let tree = torso();
    let joints: Vec<&str> = tree.joints.iter().map(|j| j.name.as_str()).collect();
    let header = format!("camera,target,{},x,y,z,roll,pitch,yaw", joints.join(","));
    let zeros = vec!["0"; joints.len()].join(",");
    let file = |rows: &[&str]| format!("# units: joints=deg, lengths=mm\n{header}\n{}\n", rows.join("\n"));
    let good = format!("head_camera,l_hand,{zeros},10,20,500,1,2,3");
    let data =
        TreeData::from_csv_str(&file(&[&good, &good.replace("l_hand", "r_hand")]), &tree, None).unwrap();
    assert_eq!(data.views.len(), 2);
    assert_eq!(data.frames.len(), 3);
    assert_eq!(data.joints.len(), 1, "two views of one pose");
    assert_eq!(data.lines, [3, 4]);
    let error = |rows: &[&str]| TreeData::from_csv_str(&file(rows), &tree, None).unwrap_err().to_string();
    let e = error(&[&good.replace("l_hand", "l_foot")]);
    assert!(e.contains("line 3") && e.contains("target") && e.contains("l_foot"), "{e}");
    let e = error(&[&good.replace("l_hand", "head_camera")]);
    assert!(e.contains("line 3") && e.contains("sees no joint"), "{e}");
    let e = error(&[&good.replace(",500,", ",x,")]);
    assert!(e.contains("line 3") && e.contains("column `z`") && e.contains("`x` is not a number"), "{e}");
    // Positions only (no roll, pitch, yaw): a device fixed in the world, not a camera on a branch.
    let positions = |rows: &[&str]| file(rows).replace(",roll,pitch,yaw", "").replace(",1,2,3\n", "\n");
    let tracked =
        TreeData::from_csv_str(&positions(&[&good.replace("head_camera", "world")]), &tree, None).unwrap();
    assert!(tracked.position_only && tracked.rows() == 3);
    let e = TreeData::from_csv_str(&positions(&[&good]), &tree, None).unwrap_err().to_string();
    assert!(e.contains("line 3") && e.contains("camera") && e.contains("expected world"), "{e}");
    let e = TreeData::from_csv_str(&file(&[&good]).replace(",yaw", ",yow"), &tree, None);
    assert!(e.unwrap_err().to_string().contains("yaw"));
    assert!(tracked.clone().join(&data).unwrap_err().to_string().contains("cannot be fitted together"));
    let missing =
        TreeData::from_csv_str(&file(&[&good]).replace("r_elbow", "r_knee"), &tree, None).unwrap_err();
    assert!(missing.to_string().contains("r_elbow"), "{missing}");
}

#[test]
fn tree_view_covariance_matches_a_monte_carlo_of_joint_noise() {
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    let tree = torso();
    let params = TreeParams::new(&tree);
    let (frames, placements) = frames(&tree);
    let q = tree.uniform_configurations(1, &mut rng).remove(0);
    let sigma_q: Vec<f64> = (0..tree.dof()).map(|j| (0.01 + 0.002 * j as f64).to_radians()).collect();
    let noise = DMatrix::from_diagonal(&DVector::from_iterator(sigma_q.len(), sigma_q.iter().map(|s| s * s)));
    let sigma = [0.02, 0.005f64.to_radians()];
    let commanded =
        simulate_views(&tree, &frames, &placements, &PAIRS, std::slice::from_ref(&q), sigma, &mut rng);
    let zero = vec![0.0; params.len()];
    let nothing = params.selection(&[]);
    let rows = TreeRows::new(&params, &commanded, &commanded.frames).unwrap();
    let problem =
        rows.problem(&params, &nothing, (zero.clone(), placements.clone(), Vec::new()), Some(&noise));
    // Both views are at one pose: one block, the joint noise they share kept.
    assert_eq!(problem.blocks().width(), 12);
    let v = problem.covariance().unwrap().clone();
    // Views at q + n_q with measurement noise, predicted at q.
    let draws = 4000;
    let mut samples = Vec::with_capacity(draws);
    for _ in 0..draws {
        let moved: Vec<f64> = q
            .iter()
            .zip(&sigma_q)
            .map(|(v, s)| {
                v + s * rand_distr::Distribution::<f64>::sample(&rand_distr::StandardNormal, &mut rng)
            })
            .collect();
        let mut data = simulate_views(&tree, &frames, &placements, &PAIRS, &[moved], sigma, &mut rng);
        data.joints[0] = q.clone();
        let rows = TreeRows::new(&params, &data, &data.frames).unwrap();
        let p = rows.problem(&params, &nothing, (zero.clone(), placements.clone(), Vec::new()), None);
        samples.push(p.evaluate(&DVector::zeros(0), None));
    }
    let n = draws as f64;
    let mean = samples.iter().fold(DVector::zeros(12), |a, y| a + y) / n;
    // Every entry of the pose's block, those between its two views too.
    let mut correlation = 0.0f64;
    for i in 0..12 {
        for j in 0..12 {
            let cov: f64 =
                samples.iter().map(|y| (y[i] - mean[i]) * (y[j] - mean[j])).sum::<f64>() / (n - 1.0);
            let predicted = v[(i, j)];
            // The sample covariance's standard error: sqrt((V_ii V_jj + V_ij^2) / n).
            let se = ((v[(i, i)] * v[(j, j)] + predicted * predicted) / n).sqrt();
            assert!((cov - predicted).abs() < 5.0 * se, "({i}, {j}): {cov} against {predicted}, SE {se}");
            if i < 6 && j >= 6 {
                correlation = correlation.max((predicted / (v[(i, i)] * v[(j, j)]).sqrt()).abs());
            }
        }
    }
    // The two views are correlated through the joints they share (the head's and the torso's).
    assert!(correlation > 0.1, "largest correlation between the views: {correlation}");
    // The joint noise is most of it: the blocks are not the measurement noise alone.
    assert!(v[(0, 0)] > 4.0 * sigma[0] * sigma[0], "{}", v[(0, 0)]);
}

fn robocal(args: &[&str]) -> std::process::Output {
    assert_cmd::Command::cargo_bin("robocal").unwrap().args(args).output().unwrap()
}

const TREE_EXAMPLE: [&str; 7] = [
    "calibrate",
    "--model",
    "presets/torso.urdf",
    "--data",
    "examples/torso/views.csv",
    "--validate",
    "examples/torso/views-2.csv",
];

/// The held-out line's RMS (mm or deg) before and after, from the report's text.
fn held_out(text: &str, unit: &str) -> (f64, f64) {
    let line = text.lines().find(|l| l.starts_with(&format!("examples/torso/views-2.csv ({unit})"))).unwrap();
    crate::verdict_rms(line)
}

#[test]
fn calibrate_tree_fits_the_example_and_writes_each_branch() {
    let out_dir = std::env::temp_dir().join(format!("robocal-tree-{}", std::process::id()));
    let json = out_dir.with_extension("json");
    let mut args = TREE_EXAMPLE.to_vec();
    let (dir, report) = (out_dir.to_str().unwrap(), json.to_str().unwrap());
    args.extend(["--out-dir", dir, "--json", report]);
    let out = robocal(&args);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let text = String::from_utf8(out.stdout).unwrap();
    assert!(
        text.starts_with("calibration of torso (branches head_camera, l_hand, r_hand; 15 joints)"),
        "{text}"
    );
    // The README's figures: held out, 5.31 -> 0.37 mm and 0.679 -> 0.086 deg, the views' own
    // noise (0.2 mm and 0.05 deg per axis: 0.35 mm and 0.087 deg).
    let (before, after) = held_out(&text, "mm");
    assert!((before - 5.305).abs() < 1e-3 && (after - 0.366).abs() < 1e-3, "{before} -> {after} mm");
    let (before, after) = held_out(&text, "deg");
    assert!((before - 0.6788).abs() < 1e-4 && (after - 0.0856).abs() < 1e-4, "{before} -> {after} deg");
    assert!(text.contains("base.*: a view sees one frame relative to another"), "{text}");
    for tip in ["head_camera", "l_hand", "r_hand"] {
        let model = std::fs::read_to_string(out_dir.join(format!("{tip}.toml"))).unwrap();
        let model = robocal::model::RobotModel::from_toml_str(&model).unwrap();
        assert_eq!(model.joints[0].name, "torso");
    }
    let report: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    assert_eq!(report["frames"].as_array().unwrap().len(), 3);
    assert_eq!(report["sets"][1][1]["views"].as_array().unwrap().len(), 80);
    std::fs::remove_dir_all(&out_dir).unwrap();
    std::fs::remove_file(&json).unwrap();
}

#[test]
fn calibrate_tree_refuses_what_it_cannot_fit_by_name() {
    let stderr = |args: &[&str], code: i32| {
        let out = robocal(args);
        assert_eq!(out.status.code(), Some(code), "{args:?}");
        String::from_utf8(out.stderr).unwrap()
    };
    let mut args = TREE_EXAMPLE.to_vec();
    args[2] = "puma560";
    assert!(stderr(&args, 2).contains("--model: a URDF file"));
    let mut args = TREE_EXAMPLE.to_vec();
    args.extend(["--joint-sigma-deg", "0.01,0.02"]);
    let e = stderr(&args, 1);
    assert!(e.contains("--joint-sigma-deg: 2 values for the 15 joints") && e.contains("head_tilt"), "{e}");
    let mut args = TREE_EXAMPLE.to_vec();
    args.extend(["--params", "l_knee.x"]);
    assert!(stderr(&args, 1).contains("l_knee.x"));
    let e =
        stderr(&["calibrate", "--model", "presets/torso.urdf", "--data", "examples/puma560-camera.csv"], 1);
    assert!(e.contains("presets/torso.urdf") && e.contains("--tip-link"), "{e}");
    // A serial arm is calibrate's.
    let e =
        stderr(&["calibrate", "--model", "examples/arm7/arm7.urdf", "--data", "examples/torso/views.csv"], 1);
    assert!(
        e.contains("two tips or more") && e.contains("a serial arm is calibrated from its markers"),
        "{e}"
    );
}

#[test]
fn the_readme_tree_example_is_the_real_output() {
    crate::cli::the_readme_block_is_printed("$ robocal calibrate --model presets/torso.urdf", &TREE_EXAMPLE);
}

/// A calibrated tree written into its URDF ([`tree_to_urdf_string`]) reads back as that tree:
/// every joint's origin to 1e-9 (mm, rad), each shared joint written once; the rest of the file
/// (every element but the moving joints' origins) as it was.
#[test]
fn a_calibrated_tree_written_as_urdf_reads_back_as_calibrated() {
    let nominal = torso();
    let views = std::fs::read_to_string("examples/torso/views.csv").unwrap();
    let data = TreeData::from_csv_str(&views, &nominal, None).unwrap();
    let c = calibrate_tree(&nominal, &data, &options(Estimator::Wls)).unwrap();
    let written = robocal::model::tree_to_urdf_string(TORSO, &c.calibrated).unwrap();
    let read = RobotTree::from_urdf_str(&written, None, &[]).unwrap();
    assert_eq!(read.joints.len(), c.calibrated.joints.len());
    let mut moved = 0;
    for (a, b) in read.joints.iter().zip(&c.calibrated.joints) {
        let gap = a.origin.isometry().inverse() * b.origin.isometry();
        assert!(gap.translation.vector.norm() < 1e-9 && gap.rotation.angle() < 1e-9, "{}: {gap}", a.name);
        let nominal = nominal.joints.iter().find(|n| n.name == a.name).unwrap();
        moved += usize::from(
            (nominal.origin.isometry().inverse() * a.origin.isometry()).translation.vector.norm() > 1e-3,
        );
    }
    assert!(moved > 10, "the calibration moved the joints' origins: {moved} of 15");
    let without_origins = |text: &str| -> Vec<String> {
        text.lines().filter(|l| !l.trim_start().starts_with("<origin")).map(str::to_string).collect()
    };
    assert_eq!(without_origins(&written), without_origins(TORSO));
}

/// The same with a camera that sees a hand only where it is in view (70 deg, 200 to 1200 mm,
/// facing it at 60 deg at most): every chain is still recovered on held-out poses in view.
#[test]
fn a_head_camera_seeing_each_hand_only_in_view_recovers_every_chain() {
    use robocal::simulation::Sight;
    use robocal::simulation::tree::seen_configurations;
    let mut rng = ChaCha8Rng::seed_from_u64(70);
    let nominal = torso();
    let truth = perturbed_tree(&nominal, 1.0, 0.005, &mut rng);
    let (frames, mut placements) = frames(&nominal);
    placements[4] = 110f64.to_radians(); // forward, 20 deg down
    let sight =
        Sight { half_angle: 35f64.to_radians(), range: [200.0, 1200.0], incidence: 60f64.to_radians() };
    let mut seen = |n: usize, pair: (usize, usize)| {
        seen_configurations(&truth, &frames, &placements, pair, &sight, n, &mut rng).expect("in view")
    };
    let (left, right) = (seen(60, (0, 1)), seen(60, (0, 2)));
    let (held_left, held_right) = (seen(20, (0, 1)), seen(20, (0, 2)));
    let mut rng = ChaCha8Rng::seed_from_u64(71);
    let data = simulate_views(&truth, &frames, &placements, &[(0, 1)], &left, [0.0; 2], &mut rng)
        .join(&simulate_views(&truth, &frames, &placements, &[(0, 2)], &right, [0.0; 2], &mut rng))
        .unwrap();
    let c = calibrate_tree(&nominal, &data, &options(Estimator::Ols)).unwrap();
    assert!(c.training.view_position.unwrap().1 < 1e-7, "training {:?} mm", c.training.view_position);
    let held_out: Vec<Vec<f64>> = held_left.into_iter().chain(held_right).collect();
    let (mm, rad) = largest_gap(&c, &truth, &placements, &held_out);
    assert!(mm < 1e-6 && rad < 1e-9, "held-out gap {mm} mm, {rad} rad");
}

/// A camera fixed in the world seeing both hands: the views now see the torso's joint move the
/// hands (its placement the camera's to absorb), and one fit recovers every chain.
#[test]
fn a_fixed_camera_seeing_both_hands_sees_the_torso_too() {
    let mut rng = ChaCha8Rng::seed_from_u64(17);
    let nominal = torso();
    let truth = perturbed_tree(&nominal, 1.0, 0.005, &mut rng);
    let (mut frames, mut placements) = frames(&nominal);
    frames[0].on = None;
    placements[..6].copy_from_slice(&[1500.0, 100.0, 1200.0, 0.1, -1.4, 0.2]);
    let training = nominal.uniform_configurations(60, &mut rng);
    let data = simulate_views(&truth, &frames, &placements, &PAIRS, &training, [0.0; 2], &mut rng);
    let c = calibrate_tree(&nominal, &data, &options(Estimator::Ols)).unwrap();
    assert_eq!(c.frame_names(), ["camera.world", "target.l_hand", "target.r_hand"]);
    assert!(c.training.view_position.unwrap().1 < 1e-7, "training {:?} mm", c.training.view_position);
    let (mm, rad) = largest_gap(&c, &truth, &placements, &nominal.uniform_configurations(30, &mut rng));
    assert!(mm < 1e-6 && rad < 1e-9, "held-out gap {mm} mm, {rad} rad");
    // The torso's joint now moves the hands and not the camera; its placement, the tree's
    // first, is the camera's to absorb (a combination with camera.world, as a serial arm's
    // first joint with its base).
    assert!(
        c.fixed.iter().map(Held::text).any(|f| f.starts_with("torso.theta - ") && f.contains("camera.world")),
        "{:?}",
        c.fixed
    );
    assert!(
        !c.fixed.iter().map(Held::text).any(|f| f.starts_with("torso.") && f.contains("no view sees it")),
        "{:?}",
        c.fixed
    );
    // No view has a frame on the head: its joints are not seen.
    assert!(
        c.fixed
            .iter()
            .map(Held::text)
            .any(|f| f.starts_with("head_tilt.x: no view has a camera or target past its joint")),
        "{:?}",
        c.fixed
    );
}

#[test]
fn tips_that_are_one_rigid_body_and_a_root_that_is_no_link_are_refused() {
    let tips = ["l_palm", "l_hand", "head_camera"].map(String::from);
    let e = RobotTree::from_urdf_str(TORSO, None, &tips).unwrap_err().to_string();
    assert!(e.contains("`l_hand` and `l_palm` have the same moving joints"), "{e}");
    let e = RobotTree::from_urdf_str(TORSO, Some("nope"), &[]).unwrap_err().to_string();
    assert!(e.contains("base link") && e.contains("`nope`"), "{e}");
}

/// Views of the left hand only: the right arm's joints are said to be seen by no view, the
/// torso's to move both frames alike.
#[test]
fn what_no_view_sees_is_said_for_what_it_is() {
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let nominal = torso();
    let (frames, placements) = frames(&nominal);
    let q = nominal.uniform_configurations(40, &mut rng);
    let data = simulate_views(&nominal, &frames, &placements, &[(0, 1)], &q, [0.0; 2], &mut rng);
    let c = calibrate_tree(&nominal, &data, &options(Estimator::Ols)).unwrap();
    let said = |name: &str| {
        c.fixed.iter().map(Held::text).find(|f| f.starts_with(&format!("{name}: "))).unwrap_or_default()
    };
    assert!(said("r_elbow.x").contains("no view has a camera or target past its joint"), "{:?}", c.fixed);
    assert!(said("torso.z").contains("on the way to both frames of every view past it"), "{:?}", c.fixed);
    // Exact views: the only warning is the noise check's, their sigmas far above the residuals.
    let exact = |w: &Warning| matches!(w, Warning::NoiseDisagrees(n) if n.measurement_factor < 1e-3);
    assert!(c.warnings.iter().all(exact) && c.warnings.len() == 1, "{:?}", c.warnings);
}

#[test]
fn calibrate_tree_warns_of_implausible_corrections_and_joints_beyond_their_limits() {
    // The example's millimetres read as metres (its units line dropped, the units given
    // wrong): the fit is nonsense, and says so.
    let dir = std::env::temp_dir().join(format!("robocal-tree-metres-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    for name in ["views.csv", "views-2.csv"] {
        let text = std::fs::read_to_string(format!("examples/torso/{name}")).unwrap();
        let undeclared: Vec<&str> = text.lines().filter(|l| !l.starts_with("# units:")).collect();
        std::fs::write(dir.join(name), undeclared.join("\n") + "\n").unwrap();
    }
    let (views, views_2) = (dir.join("views.csv"), dir.join("views-2.csv"));
    let mut args = TREE_EXAMPLE.to_vec();
    (args[4], args[6]) = (views.to_str().unwrap(), views_2.to_str().unwrap());
    args.extend(["--joint-unit", "deg", "--length-unit", "m"]);
    let out = robocal(&args);
    std::fs::remove_dir_all(&dir).unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let text = String::from_utf8(out.stdout).unwrap();
    let warnings = &text[text.find("\nwarnings:\n").expect("warnings")..];
    assert!(
        warnings.contains("joint lengths corrected by more than 10 mm, whatever the standard error: "),
        "{warnings}"
    );
    assert!(warnings.contains("; check the model and the units"), "{warnings}");
    // A joint beyond its limits, named with its line.
    let dir = std::env::temp_dir().join(format!("robocal-tree-limits-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let views = std::fs::read_to_string("examples/torso/views.csv").unwrap();
    let mut lines: Vec<String> = views.lines().map(String::from).collect();
    let mut cells: Vec<String> = lines[2].split(',').map(String::from).collect();
    cells[4] = "170".into(); // head_tilt, limits +-34 deg
    lines[2] = cells.join(",");
    let file = dir.join("views.csv");
    std::fs::write(&file, lines.join("\n") + "\n").unwrap();
    let json = dir.join("report.json");
    let (file, json_arg) = (file.to_str().unwrap(), json.to_str().unwrap());
    let out = robocal(&["calibrate", "--model", "presets/torso.urdf", "--data", file, "--json", json_arg]);
    let stdout = String::from_utf8(out.stdout).unwrap();
    assert!(stdout.contains("1  training pose with joint values outside the limits of torso"), "{stdout}");
    assert!(
        stdout.contains("joint values outside the limits of torso at line 3 (head_tilt): the calibration")
    );
    let report: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    let warning = report["warnings"].as_array().unwrap().iter().find(|w| w["cause"] == "outside_limits");
    assert_eq!(
        warning.unwrap()["poses"],
        serde_json::json!([{ "line": 3, "joints": ["head_tilt"] }]),
        "{}",
        report["warnings"]
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn calibrate_tree_fits_several_files_of_chosen_tips_and_writes_the_frames() {
    let out_dir = std::env::temp_dir().join(format!("robocal-tree-files-{}", std::process::id()));
    let out = robocal(&[
        "calibrate",
        "--model",
        "presets/torso.urdf",
        "--tips",
        "head_camera,l_hand,r_hand",
        "--data",
        "examples/torso/views.csv",
        "--data",
        "examples/torso/views-2.csv",
        "--joint-sigma-deg",
        "0.01",
        "--out-dir",
        out_dir.to_str().unwrap(),
    ]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let text = String::from_utf8(out.stdout).unwrap();
    assert!(text.contains("200 views at 200 poses, wls"), "{text}");
    // How many were identified, with the rank and condition number the JSON holds too.
    let identified = text.lines().find(|l| l.contains(" parameters identified (rank ")).unwrap_or_default();
    let count =
        text.lines().skip_while(|l| !l.starts_with("parameter ")).skip(1).take_while(|l| !l.is_empty());
    assert!(identified.starts_with(&format!("{} parameters identified", count.count())), "{text}");
    // Several training files: each worst view says which file it is in.
    assert!(text.contains("  training, examples/torso/views"), "{text}");
    let stderr = String::from_utf8(out.stderr).unwrap();
    assert!(
        stderr.starts_with("wrote ") && stderr.contains("l_hand.toml") && stderr.contains("frames.json"),
        "{stderr}"
    );
    assert!(text.contains("joints: torso, head_pan, head_tilt, l_shoulder_pitch"), "{text}");
    let frames: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out_dir.join("frames.json")).unwrap()).unwrap();
    let names: Vec<&str> = frames.as_array().unwrap().iter().map(|f| f["name"].as_str().unwrap()).collect();
    assert_eq!(names, ["camera.head_camera", "target.l_hand", "target.r_hand"]);
    let model = std::fs::read_to_string(out_dir.join("l_hand.toml")).unwrap();
    assert!(model.contains("right relative to the other branches"), "{model}");
    std::fs::remove_dir_all(&out_dir).unwrap();
}

/// A laser tracker fixed in the world measuring a reflector on each hand and on the head:
/// positions only, one fit recovers every chain (where each point is, seen from the tracker).
#[test]
fn a_tracker_measuring_points_on_every_branch_recovers_every_chain() {
    let mut rng = ChaCha8Rng::seed_from_u64(23);
    let nominal = torso();
    let truth = perturbed_tree(&nominal, 1.0, 0.005, &mut rng);
    let on = |tip: &str| Some(nominal.branch(tip).unwrap());
    let frames = [
        Frame { role: Role::Camera, on: None },
        Frame { role: Role::Target, on: on("head_camera") },
        Frame { role: Role::Target, on: on("l_hand") },
        Frame { role: Role::Target, on: on("r_hand") },
    ];
    let placements = [
        2500.0, 300.0, 900.0, 0.2, -0.1, 2.5, // the tracker, 2.5 m away and turned
        40.0, 0.0, 60.0, 0.0, 0.0, 0.0, // reflectors: their positions on each tip
        0.0, 25.0, -30.0, 0.0, 0.0, 0.0, //
        0.0, -25.0, -30.0, 0.0, 0.0, 0.0,
    ];
    let pairs = [(0, 1), (0, 2), (0, 3)];
    let training = nominal.uniform_configurations(60, &mut rng);
    let data =
        simulate_views(&truth, &frames, &placements, &pairs, &training, [0.0; 2], &mut rng).positions_only();
    let c = calibrate_tree(&nominal, &data, &options(Estimator::Ols)).unwrap();
    assert!(c.training.view_position.unwrap().1 < 1e-7, "training {:?} mm", c.training.view_position);
    assert!(c.training.view_rotation.is_none());
    // Held out: each point seen from the tracker.
    let mut largest = 0.0f64;
    for q in nominal.uniform_configurations(30, &mut rng) {
        for &(a, b) in &pairs {
            let at =
                |tree: &RobotTree, p: &[f64], f: usize| frame_at(tree, &frames[f], &p[6 * f..6 * f + 6], &q);
            let real = (at(&truth, &placements, a).inverse() * at(&truth, &placements, b)).translation.vector;
            let found = (at(&c.calibrated, &c.setup_values.1, a).inverse()
                * at(&c.calibrated, &c.setup_values.1, b))
            .translation
            .vector;
            largest = largest.max((real - found).norm());
        }
    }
    assert!(largest < 1e-6, "held-out gap {largest} mm");
    // A point has no orientation; the tracker absorbs the tree's placement.
    assert!(
        c.fixed
            .iter()
            .map(Held::text)
            .any(|f| f.starts_with("target.l_hand.rx: a point measured by its position has no orientation"))
    );
    assert_eq!(c.unseen, [Unseen::TreeBase { world: Some("camera.world".into()) }]);
    assert!(c.unseen[0].to_string().contains("camera.world is placed in the root link's frame"));
    // As a file, through the command: positions only, no angle columns.
    let dir = std::env::temp_dir().join(format!("robocal-tree-tracker-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let file = dir.join("tracker.csv");
    std::fs::write(&file, robocal::simulation::tree::views_csv(&nominal, &data)).unwrap();
    let text = std::fs::read_to_string(&file).unwrap();
    assert!(text.lines().nth(1).unwrap().ends_with(",x,y,z,sigma"), "{text}");
    let out = robocal(&["calibrate", "--model", "presets/torso.urdf", "--data", file.to_str().unwrap()]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let report = String::from_utf8(out.stdout).unwrap();
    assert!(report.contains("180 views at 60 poses") && !report.contains("(deg)"), "{report}");
    std::fs::remove_dir_all(&dir).unwrap();
}

/// A tree's calibration with a prior, a robust loss and a held parameter, as a marker file's:
/// each holds out within 1.2 times the plain fit's error; the held parameter (a length with no
/// error) is not estimated and stays nominal, and `--keep` of a parameter the gauge holds frees it; a `--hold` name that
/// matches nothing is refused.
#[test]
fn a_tree_takes_priors_robust_losses_and_held_parameters() {
    let mut rng = ChaCha8Rng::seed_from_u64(62);
    let nominal = torso();
    let params = TreeParams::new(&nominal);
    let (frames, placements) = frames(&nominal);
    let training = nominal.uniform_configurations(80, &mut rng);
    let exact = simulate_views(&nominal, &frames, &placements, &PAIRS, &training, [0.0; 2], &mut rng);
    let plain = calibrate_tree(&nominal, &exact, &options(Estimator::Ols)).unwrap();
    let kept = plain.refined.estimate.names.clone();
    // A length with no error, to hold.
    let length = |n: &String| params.params.iter().any(|p| p.name == *n && !p.is_angle());
    let hold = kept.iter().find(|n| length(n)).unwrap().clone();
    let mut truth_x = vec![0.0; params.len()];
    for (i, p) in params.params.iter().enumerate() {
        if kept.contains(&p.name) && p.name != hold {
            truth_x[i] = if p.is_angle() { 0.003 } else { 0.8 } * (((i * 37) % 11) as f64 / 5.0 - 1.0);
        }
    }
    let truth = params.fold(&nominal, &truth_x);
    let sigma = [0.05, 0.01f64.to_radians()];
    let noisy = simulate_views(&truth, &frames, &placements, &PAIRS, &training, sigma, &mut rng);
    let held_q = nominal.uniform_configurations(80, &mut rng);
    let validation = simulate_views(&truth, &frames, &placements, &PAIRS, &held_q, sigma, &mut rng);
    let wls = options(Estimator::Wls);
    let held_out = |o: &KindOptions| {
        let c = calibrate_tree(&nominal, &noisy, o).unwrap();
        (c.score(&validation).unwrap().view_position.unwrap().1, c)
    };
    let (reference, _) = held_out(&wls);
    assert!(reference < 0.1, "plain wls: {reference} mm held out");
    let held_combination =
        plain.fixed.iter().find(|h| matches!(h, Held::Combination { .. } | Held::Confounded { .. })).unwrap();
    let cases = [
        (
            "--prior machined",
            KindOptions { prior: PriorEntry::parse_list("machined").unwrap(), ..wls.clone() },
        ),
        ("--loss huber", KindOptions { loss: Loss::Huber(1.345), ..wls.clone() }),
        ("--hold", KindOptions { gauge: Gauge { hold: vec![hold.clone()], keep: vec![] }, ..wls.clone() }),
    ];
    for (name, o) in &cases {
        let (found, c) = held_out(o);
        assert!(found < 1.2 * reference, "{name}: {found} mm held out, plain {reference} mm");
        if *name == "--hold" {
            assert!(!c.refined.estimate.names.contains(&hold), "{name}: {hold} estimated");
            assert_eq!(c.after[params.params.iter().position(|p| p.name == hold).unwrap()], 0.0);
            assert!(
                c.fixed.contains(&Held::ByUser { parameter: hold.clone(), setup: false }),
                "{:?}",
                c.fixed
            );
        }
        if *name == "--loss huber" {
            assert!(c.robust.is_some(), "{name}: its weights");
        }
    }
    // A view far out: the robust loss weighs its pose's views down, and says so view by view
    // (one weight per view, not per pose: a pose here has several).
    let mut bad = noisy.clone();
    let several = |k: usize| bad.views.iter().filter(|v| v.pose == bad.views[k].pose).count() > 1;
    let k = (0..bad.views.len()).rev().find(|&k| several(k)).unwrap();
    bad.views[k].view[0] += 5.0;
    let huber = KindOptions { loss: Loss::Huber(1.345), ..wls.clone() };
    let robust = calibrate_tree(&nominal, &bad, &huber).unwrap().robust.unwrap();
    assert_eq!(robust.weights.len(), bad.views.len(), "one weight per view");
    let down: Vec<usize> = robust.down_weighted().map(|(j, _)| j).collect();
    let of_its_pose: Vec<usize> =
        (0..bad.views.len()).filter(|&j| bad.views[j].pose == bad.views[k].pose).collect();
    assert_eq!(down, of_its_pose, "the far view {k}'s pose's views down-weighted: {:?}", robust.weights);
    let freed = held_combination.parameter().to_string();
    let keep = KindOptions { gauge: Gauge { hold: vec![], keep: vec![freed.clone()] }, ..wls.clone() };
    let c = calibrate_tree(&nominal, &noisy, &keep).unwrap();
    assert!(c.refined.estimate.names.contains(&freed), "--keep {freed}: {:?}", c.fixed);
    let nothing = KindOptions { gauge: Gauge { hold: vec!["no_such.x".into()], keep: vec![] }, ..wls };
    let error = calibrate_tree(&nominal, &noisy, &nothing).unwrap_err().to_string();
    assert!(error.contains("no_such.x"), "{error}");
}

/// k-fold cross-validation of a tree: every view held out exactly once, in the fold of its
/// pose, and scored by a fit that did not see it: its RMS is above the training fit's and near
/// that of a held-out set of the same robot (within 25%); and the command prints the row.
#[test]
fn a_tree_cross_validates_each_view_once_by_a_fit_without_it() {
    let mut rng = ChaCha8Rng::seed_from_u64(63);
    let nominal = torso();
    let params = TreeParams::new(&nominal);
    let (frames, placements) = frames(&nominal);
    let training = nominal.uniform_configurations(60, &mut rng);
    let truth_x: Vec<f64> = (0..params.len())
        .map(|i| if params.params[i].is_angle() { 0.002 } else { 0.5 } * (((i * 37) % 11) as f64 / 5.0 - 1.0))
        .collect();
    let truth = params.fold(&nominal, &truth_x);
    let sigma = [0.05, 0.01f64.to_radians()];
    let data = simulate_views(&truth, &frames, &placements, &PAIRS, &training, sigma, &mut rng);
    let held_q = nominal.uniform_configurations(60, &mut rng);
    let validation = simulate_views(&truth, &frames, &placements, &PAIRS, &held_q, sigma, &mut rng);
    let wls = options(Estimator::Wls);
    let c = calibrate_tree(&nominal, &data, &wls).unwrap();
    let cv = cross_validate_tree(&nominal, &data, &wls, 4).unwrap();
    let mut lines: Vec<usize> = cv.views.iter().map(|v| v.line).collect();
    lines.sort_unstable();
    let mut all = data.lines.clone();
    all.sort_unstable();
    assert_eq!(lines, all, "every view held out once");
    let held_out = c.score(&validation).unwrap().view_position.unwrap().1;
    assert!(
        cv.view_position.unwrap().1 > c.training.view_position.unwrap().1,
        "{:?} against {:?}",
        cv.view_position,
        c.training.view_position
    );
    assert!(
        (cv.view_position.unwrap().1 / held_out - 1.0).abs() < 0.25,
        "k-fold {} mm, held out {held_out} mm",
        cv.view_position.unwrap().1
    );
    assert!(cross_validate_tree(&nominal, &data, &wls, 61).is_err(), "more folds than poses");
    let output = assert_cmd::Command::cargo_bin("robocal")
        .unwrap()
        .args([
            "calibrate",
            "--model",
            "presets/torso.urdf",
            "--data",
            "examples/torso/views.csv",
            "--folds",
            "3",
        ])
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .unwrap();
    let text = String::from_utf8(output.stdout).unwrap();
    assert!(output.status.success(), "{}", String::from_utf8_lossy(&output.stderr));
    assert!(text.contains("3-fold cross-validation (mm)"), "{text}");
}

/// `calibrate --prior auto:machined --folds 3` on a tree's views: the scale chosen by the
/// cross-validated view positions, printed with its curve, in the JSON and on the page; the
/// k-fold row nested, each fold choosing its scale again.
#[test]
fn a_tree_scales_a_preset_prior_from_its_views() {
    let dir = std::env::temp_dir().join(format!("robocal-tree-prior-auto-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let (json, page) = (dir.join("report.json"), dir.join("report.html"));
    let output = assert_cmd::Command::cargo_bin("robocal")
        .unwrap()
        .args(["calibrate", "--model", "presets/torso.urdf", "--data", "examples/torso/views.csv"])
        .args(["--validate", "examples/torso/views-2.csv", "--prior", "auto:machined", "--folds", "3"])
        .args(["--json", json.to_str().unwrap(), "--html", page.to_str().unwrap()])
        .output()
        .unwrap();
    assert!(output.status.success(), "{}", String::from_utf8_lossy(&output.stderr));
    let text = String::from_utf8(output.stdout).unwrap();
    let report: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    crate::choice::assert_prior_scale(&report, &text, 3);
    assert!(text.contains("3-fold cross-validation, nested (mm)"), "{text}");
    let html = std::fs::read_to_string(&page).unwrap();
    assert!(html.contains("Prior scale: --prior auto:machined chose"));
    // The page embeds the residual figures and the scale's curve.
    let figures = html.split("<section id=\"figures\"").nth(1).expect("a figures section");
    assert!(figures.contains("<figure id=\"prior-scale.svg\">"), "the scale's curve on the page");
    assert!(figures.contains("<figure id=\"histogram.svg\">") && figures.matches("<svg").count() > 10);
    std::fs::remove_dir_all(&dir).unwrap();
}

/// `calibrate --select t` on a tree's views: the backward path printed and in the JSON, the
/// parameters it kept calibrated, held out within 1.2 times the plain fit's error; `--select
/// cv` and `bic` likewise, forward on the views linearised about "before".
#[test]
fn a_tree_selects_its_parameters_by_the_t_rule() {
    let dir = std::env::temp_dir().join(format!("robocal-tree-select-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let json = dir.join("report.json");
    let torso = ["calibrate", "--model", "presets/torso.urdf", "--data", "examples/torso/views.csv"];
    let run = |extra: &[&str]| {
        let output = assert_cmd::Command::cargo_bin("robocal")
            .unwrap()
            .args(torso)
            .args(["--validate", "examples/torso/views-2.csv", "--json", json.to_str().unwrap()])
            .args(extra)
            .output()
            .unwrap();
        let report = std::fs::read_to_string(&json)
            .ok()
            .map(|t| serde_json::from_str::<serde_json::Value>(&t).unwrap());
        (
            output.status.code(),
            String::from_utf8(output.stdout).unwrap(),
            String::from_utf8(output.stderr).unwrap(),
            report,
        )
    };
    let held_out = |report: &serde_json::Value| report["sets"][1][1]["view_position"][1].as_f64().unwrap();
    let (code, _, stderr, plain) = run(&[]);
    assert_eq!(code, Some(0), "{stderr}");
    let plain = held_out(&plain.unwrap());
    let (code, text, stderr, report) = run(&["--select", "t"]);
    assert_eq!(code, Some(0), "{stderr}");
    let report = report.unwrap();
    assert!(text.contains("parameter selection: backward elimination while |t| < 2"), "{text}");
    let selected: Vec<&str> =
        report["selection"]["selected"].as_array().unwrap().iter().map(|v| v.as_str().unwrap()).collect();
    let estimated: Vec<&str> =
        report["parameters"].as_array().unwrap().iter().map(|p| p["name"].as_str().unwrap()).collect();
    assert!(!selected.is_empty() && selected.iter().all(|s| estimated.contains(s)), "{selected:?}");
    let found = held_out(&report);
    assert!(found < 1.2 * plain, "held out {found} mm with --select t, {plain} mm plain");
    // Forward by cv and bic on the views linearised about "before": the path printed and in the
    // JSON, the set chosen calibrated, held out within 1.2 times the plain fit's error.
    for (criterion, words) in [
        ("cv", "parameter selection: forward selection by 3-fold cross-validation"),
        ("bic", "parameter selection: forward selection by BIC"),
    ] {
        let (code, text, stderr, report) = run(&["--select", criterion, "--folds", "3"]);
        assert_eq!(code, Some(0), "{stderr}");
        let report = report.unwrap();
        assert!(text.contains(words), "{criterion}: {text}");
        assert!(text.contains("nested"), "the k-fold row chooses again in each fold: {text}");
        let selection = &report["selection"];
        assert_eq!(selection["criterion"], criterion);
        let selected = selection["selected"].as_array().unwrap();
        assert!(!selected.is_empty() && selected.len() == selection["chosen"].as_u64().unwrap() as usize);
        let estimated: Vec<&str> =
            report["parameters"].as_array().unwrap().iter().map(|p| p["name"].as_str().unwrap()).collect();
        assert!(selected.iter().all(|s| estimated.contains(&s.as_str().unwrap())), "{selected:?}");
        let found = held_out(&report);
        assert!(found < 1.2 * plain, "held out {found} mm with --select {criterion}, {plain} mm plain");
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

/// The marginal likelihood on a tree's views (`--prior auto-ml:machined`): the torso whose
/// joint errors are drawn from the `machined` tolerances times `s0` (1 or 4), the head camera
/// seeing both hands at 40 configurations (0.05 mm, 0.01 deg, the sigmas known), held out on
/// 40 more, 10 trees: the scale chosen is within a factor 1.5 of `s0` on at least 8 of 10
/// (measured 10 of 10, in 10 s), and the held-out position RMS at that scale within 1.2 times the plain
/// weighted least squares fit's on every tree. Views without their sigmas nor the joint noise
/// are refused.
#[test]
fn auto_ml_finds_the_scale_of_a_tree() {
    use rand_distr::{Distribution, StandardNormal};
    use robocal::calibration::Tree;
    use robocal::calibration::prior_scale::{AutoPrior, choose_prior_scale};
    let nominal = torso();
    let params = TreeParams::new(&nominal);
    let (frames, placements) = frames(&nominal);
    let auto = AutoPrior::parse("auto-ml:machined").unwrap().unwrap();
    let infos: Vec<_> = params.params.iter().collect();
    let sd = robocal::estimation::prior_sds_of(&auto.entries, &infos).unwrap();
    let (plain, sigma) = (options(Estimator::Wls), [0.05, 0.01f64.to_radians()]);
    let (mut within, mut found) = (0, Vec::new());
    for seed in 0..10 {
        let s0 = if seed % 2 == 0 { 1.0 } else { 4.0 };
        let mut rng = ChaCha8Rng::seed_from_u64(900 + seed);
        let x: Vec<f64> = (0..infos.len())
            .map(|i| match sd[i].is_finite() && !infos[i].name.starts_with("base.") {
                true => Distribution::<f64>::sample(&StandardNormal, &mut rng) * sd[i] * s0,
                false => 0.0,
            })
            .collect::<Vec<f64>>();
        let truth = params.fold(&nominal, &x);
        let (training, held) =
            (nominal.uniform_configurations(40, &mut rng), nominal.uniform_configurations(40, &mut rng));
        let train = simulate_views(&truth, &frames, &placements, &PAIRS, &training, sigma, &mut rng);
        let test = simulate_views(&truth, &frames, &placements, &PAIRS, &held, sigma, &mut rng);
        let scale = choose_prior_scale(&Tree(&nominal), &train, &plain, &auto, 5).unwrap();
        assert_eq!((scale.folds, scale.log_evidence[scale.chosen]), (None, 0.0));
        within += usize::from((1.0 / 1.5..=1.5).contains(&(scale.scale() / s0)));
        let score = |o: &KindOptions| {
            calibrate_tree(&nominal, &train, o).unwrap().score(&test).unwrap().view_position.unwrap().1
        };
        let chosen = KindOptions { prior: auto.chosen(&[], &scale), ..plain.clone() };
        let (at, wls) = (score(&chosen), score(&plain));
        found.push((s0, scale.scale(), at, wls));
        assert!(
            at < 1.2 * wls,
            "seed {seed}: held out {at} mm at the scale chosen, {wls} mm plain: {found:?}"
        );
    }
    eprintln!("tree: {within} of 10 within a factor 1.5: {found:?}");
    assert!(within >= 8, "{within} of 10 within a factor 1.5: {found:?}");
    let assumed = TreeData {
        assumed_sigmas: true,
        ..simulate_views(
            &nominal,
            &frames,
            &placements,
            &PAIRS,
            &nominal.uniform_configurations(20, &mut ChaCha8Rng::seed_from_u64(1)),
            sigma,
            &mut ChaCha8Rng::seed_from_u64(2),
        )
    };
    let e = choose_prior_scale(&Tree(&nominal), &assumed, &plain, &auto, 5).unwrap_err().to_string();
    assert!(e.contains("the marginal likelihood needs the noise"), "{e}");
}

/// Feasible GLS of a tree's views (`calibrate_tree_feasible`): a torso whose joints carry
/// errors of 0.5 mm and 0.3 deg, seen by the head camera with 0.1 mm and 0.02 deg of noise
/// (the joints read exactly): the views' sigmas in their 95% intervals, every joint's interval
/// reaching down to its true zero (the torso's, which the views cannot see, unbounded), the
/// components settled, and the error on exact held-out
/// views within 1.2 times that of Gauss-Markov given the true sigmas; exact views: the
/// residuals vanish.
#[test]
fn feasible_gls_of_a_trees_views_finds_their_noise() {
    use robocal::calibration::FeasibleOptions;
    use robocal::calibration::tree::calibrate_tree_feasible;
    let mut rng = ChaCha8Rng::seed_from_u64(64);
    let nominal = torso();
    let truth = perturbed_tree(&nominal, 0.5, 0.3f64.to_radians(), &mut rng);
    let (frames, placements) = frames(&nominal);
    let sigma = [0.1, 0.02f64.to_radians()];
    let views = |rng: &mut ChaCha8Rng, s: [f64; 2]| {
        let q = nominal.uniform_configurations(80, rng);
        simulate_views(&truth, &frames, &placements, &PAIRS, &q, s, rng)
    };
    let (noisy, exact) = (views(&mut rng, sigma), views(&mut rng, [0.0; 2]));
    let fgls =
        calibrate_tree_feasible(&nominal, &noisy, &options(Estimator::Ols), &FeasibleOptions::default())
            .unwrap();
    assert_eq!(fgls.noise_settled, Some(true), "{:?}", fgls.warnings);
    assert!(fgls.warnings.iter().all(|w| !matches!(w, Warning::NoiseUnsettled { .. })));
    let estimate = fgls.noise_estimate.as_ref().unwrap();
    // The torso moves the head camera and both hands alike: its variance is not estimated.
    assert_eq!(estimate.joint_sigma(0), SigmaInterval { sigma: 0.0, low: 0.0, high: f64::INFINITY });
    let [position, rotation] = [MeasurementClass::CameraPosition, MeasurementClass::CameraRotation]
        .map(|c| estimate.measurement_sigma(c).unwrap());
    assert!(position.contains(sigma[0]) && rotation.contains(sigma[1]), "{position:?} {rotation:?}");
    for j in 0..nominal.dof() {
        assert_eq!(estimate.joint_sigma(j).low, 0.0, "joint {j}: {:?}", estimate.joint_sigma(j));
    }
    let wls = calibrate_tree(&nominal, &noisy, &options(Estimator::Wls)).unwrap();
    let (f, w) = (
        fgls.score(&exact).unwrap().view_position.unwrap().1,
        wls.score(&exact).unwrap().view_position.unwrap().1,
    );
    assert!(f < 1.2 * w, "held out: fgls {f} mm, wls with the true sigmas {w} mm");
    let c = calibrate_tree_feasible(&nominal, &exact, &options(Estimator::Ols), &FeasibleOptions::default())
        .unwrap();
    assert!(
        c.training.view_position.unwrap().1 < 1e-6 && c.training.view_position.unwrap().0 > 0.1,
        "{:?}",
        c.training.view_position
    );
}

/// `calibrate --estimator fgls` of the example's views prints the estimated noise: each tree
/// joint's and the views' (the example's true 0.2 mm and 0.05 deg within their intervals).
#[test]
fn calibrate_tree_with_fgls_prints_the_estimated_noise() {
    let output = robocal(&[&TREE_EXAMPLE[..], &["--estimator", "fgls"]].concat());
    let stdout = String::from_utf8(output.stdout).unwrap();
    assert!(output.status.success(), "{}", String::from_utf8_lossy(&output.stderr));
    assert!(stdout.contains("120 views at 120 poses, fgls ("), "{stdout}");
    assert!(stdout.contains("noise estimated from the residuals (feasible GLS):"), "{stdout}");
    let row = |name: &str| -> Vec<f64> {
        let line = stdout.lines().find(|l| l.starts_with(name)).unwrap();
        line.split_whitespace().skip(1).take(3).map(|v| v.parse().unwrap()).collect()
    };
    let (position, rotation) = (row("sigma_camera_position"), row("sigma_camera_rotation"));
    assert!(position[1] <= 0.2 && 0.2 <= position[2], "{position:?}");
    assert!(rotation[1] <= 0.05 && 0.05 <= rotation[2], "{rotation:?}");
}

/// Views without sigma columns take the camera's default sigmas (0.5 mm, 0.1 deg) and, the
/// joints exact, their standard errors from the residuals' spread, said in the report and the
/// JSON (`variance_factor`), as observation files do: the example's views (their noise 0.2 mm
/// and 0.05 deg, as their sigma columns say) give, stripped of those columns, standard errors
/// within a few tenths of the columns' (the defaults' 5 mm a degree weighs the rotations a
/// little otherwise than the columns' 4), where the assumed sigmas made them 2.3 times too large;
/// and a prior weighs against that spread.
#[test]
fn views_without_sigmas_take_their_standard_errors_from_the_residuals_spread() {
    let dir = std::env::temp_dir().join(format!("robocal-tree-assumed-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let text = std::fs::read_to_string("examples/torso/views.csv").unwrap();
    let stripped: Vec<String> = (text.lines())
        .map(|l| match l.starts_with('#') {
            true => l.to_string(),
            false => l.split(',').collect::<Vec<_>>()[..l.split(',').count() - 2].join(","),
        })
        .collect();
    assert!(text.lines().nth(1).unwrap().ends_with("sigma,sigma_angle"));
    let assumed = dir.join("views.csv");
    std::fs::write(&assumed, stripped.join("\n") + "\n").unwrap();
    let run = |data: &str| -> (String, serde_json::Value) {
        let json = dir.join("r.json");
        let output = assert_cmd::Command::cargo_bin("robocal")
            .unwrap()
            .args(["calibrate", "-q", "--model", "presets/torso.urdf", "--data", data, "--json"])
            .arg(&json)
            .output()
            .unwrap();
        assert!(output.status.success(), "{}", String::from_utf8_lossy(&output.stderr));
        let report = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
        (String::from_utf8(output.stdout).unwrap(), report)
    };
    let (_, given) = run("examples/torso/views.csv");
    let (text, report) = run(assumed.to_str().unwrap());
    assert!(given.get("variance_factor").is_none());
    let f = report["variance_factor"].as_f64().expect("the variance of unit weight");
    assert!(
        text.contains(&format!("the default sigmas, 0.5 mm and 0.1 deg, times {:.4})", f.sqrt())),
        "{text}"
    );
    let se = |r: &serde_json::Value| -> Vec<f64> {
        r["parameters"].as_array().unwrap().iter().map(|p| p["std_error"].as_f64().unwrap()).collect()
    };
    let ratios: Vec<f64> = se(&report).iter().zip(se(&given)).map(|(a, b)| a / b).collect();
    assert!(ratios.iter().all(|r| (0.8..1.25).contains(r)), "{ratios:?}");
    // A prior weighs against the residuals' spread too, not against the assumed sigmas: the
    // cross-validated curve of `--prior auto:machined` follows the known sigmas' (weighed
    // against 0.5 mm, the prior was as if 2.5 times stronger: 1.74 times the CV RMS at 1/2).
    let curve = |data: &str| -> Vec<f64> {
        let json = dir.join("p.json");
        let output = assert_cmd::Command::cargo_bin("robocal")
            .unwrap()
            .args(["calibrate", "-q", "--model", "presets/torso.urdf", "--data", data])
            .args(["--params", "joints", "--prior", "auto:machined", "--json"])
            .arg(&json)
            .output()
            .unwrap();
        assert!(output.status.success(), "{}", String::from_utf8_lossy(&output.stderr));
        let report: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
        report["prior_scale"]["cv_rms"].as_array().unwrap().iter().map(|v| v.as_f64().unwrap()).collect()
    };
    let (known, guessed) = (curve("examples/torso/views.csv"), curve(assumed.to_str().unwrap()));
    let ratios: Vec<f64> = guessed.iter().zip(&known).map(|(g, k)| g / k).collect();
    assert!(ratios.iter().all(|r| (0.9..1.15).contains(r)), "{ratios:?}");
    // A parameter the views cannot see keeps its prior SD, and the rank said is the views'
    // alone (scaled by the residuals' variance a second time, that SD came out 0.6 times the
    // prior's, and the report called all 116 identified).
    let json = dir.join("m.json");
    let output = assert_cmd::Command::cargo_bin("robocal")
        .unwrap()
        .args(["calibrate", "--model", "presets/torso.urdf", "--data", assumed.to_str().unwrap()])
        .args(["--params", "joints", "--prior", "machined", "--json"])
        .arg(&json)
        .output()
        .unwrap();
    let text = String::from_utf8(output.stdout).unwrap();
    assert!(text.contains("116 parameters estimated with their priors; the data alone: rank 74"), "{text}");
    let report: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    let params = report["parameters"].as_array().unwrap();
    let tilt = params.iter().find(|p| p["name"] == "head_tilt.theta").unwrap();
    assert!((tilt["std_error"].as_f64().unwrap() / 0.5 - 1.0).abs() < 1e-9, "{tilt}");
    assert_eq!(tilt["prior_sd"], 0.5);
    std::fs::remove_dir_all(&dir).unwrap();
}

/// A tree's views are checked against their residuals as marker and observation files are:
/// the torso's views with their sigmas cut tenfold are warned of (the REML factor about 10),
/// the views as measured are not.
#[test]
fn a_trees_noise_is_checked_against_its_residuals() {
    let dir = std::env::temp_dir().join(format!("robocal-tree-noise-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let text = std::fs::read_to_string("examples/torso/views.csv").unwrap();
    let cut: Vec<String> = (text.lines())
        .map(|l| match l.starts_with('#') || l.starts_with("camera") || l.is_empty() {
            true => l.to_string(),
            false => {
                let mut cells: Vec<String> = l.split(',').map(String::from).collect();
                let n = cells.len();
                for c in &mut cells[n - 2..] {
                    *c = (c.parse::<f64>().unwrap() / 10.0).to_string();
                }
                cells.join(",")
            }
        })
        .collect();
    let (small, json) = (dir.join("small.csv"), dir.join("r.json"));
    std::fs::write(&small, cut.join("\n") + "\n").unwrap();
    let warning = |data: &std::path::Path| {
        let output = (assert_cmd::Command::cargo_bin("robocal").unwrap())
            .args(["calibrate", "-q", "--model", "presets/torso.urdf", "--data"])
            .arg(data)
            .arg("--json")
            .arg(&json)
            .output()
            .unwrap();
        assert!(output.status.success(), "{}", String::from_utf8_lossy(&output.stderr));
        let report: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
        let warnings = report["warnings"].as_array().unwrap().clone();
        warnings.into_iter().find(|w| w["cause"] == "noise_disagrees")
    };
    assert!(warning(std::path::Path::new("examples/torso/views.csv")).is_none());
    let found = warning(&small).expect("sigmas cut tenfold");
    let factor = found["measurement_factor"].as_f64().unwrap();
    assert!((8.0..12.0).contains(&factor), "{found}");
    std::fs::remove_dir_all(&dir).unwrap();
}

/// A torso with machined errors (0.1 mm, 0.05 deg) seen by a head camera looking at both hands
/// (views), or by a tracker measuring a reflector on every branch (positions only); its
/// training poses, held-out poses and frames.
fn machined_case(tracker: bool, seed: u64) -> (RobotTree, TreeData, TreeData) {
    let nominal = torso();
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let truth = perturbed_tree(&nominal, 0.1, 0.05f64.to_radians(), &mut rng);
    let on = |tip: &str| Some(nominal.branch(tip).unwrap());
    let (frames, placements, pairs, sigma) = match tracker {
        false => {
            let (frames, placements) = frames(&nominal);
            (frames, placements, PAIRS.to_vec(), [0.05, 0.01f64.to_radians()])
        }
        true => {
            let frames = vec![
                Frame { role: Role::Camera, on: None },
                Frame { role: Role::Target, on: on("head_camera") },
                Frame { role: Role::Target, on: on("l_hand") },
                Frame { role: Role::Target, on: on("r_hand") },
            ];
            let placements = vec![
                2500.0, 300.0, 900.0, 0.2, -0.1, 2.5, //
                40.0, 0.0, 60.0, 0.0, 0.0, 0.0, //
                0.0, 25.0, -30.0, 0.0, 0.0, 0.0, //
                0.0, -25.0, -30.0, 0.0, 0.0, 0.0,
            ];
            (frames, placements, vec![(0, 1), (0, 2), (0, 3)], [0.05, 0.01f64.to_radians()])
        }
    };
    let mut set = |poses: usize| {
        let q = nominal.uniform_configurations(poses, &mut rng);
        let data = simulate_views(&truth, &frames, &placements, &pairs, &q, sigma, &mut rng);
        if tracker { data.positions_only() } else { data }
    };
    let (training, validation) = (set(80), set(40));
    (nominal, training, validation)
}

/// Every tool of a calibration on a tree, its views and a tracker's points alike: `--prior
/// machined`, `--loss huber`, `--hold` (of an elbow's offset, which the poses cannot tell from
/// the others: the fit the same), feasible GLS and `--select cv` each hold out within 1.2 times
/// the plain wls fit's error (the views' positions, mm; measured 0.0884 and 0.0891 mm, the
/// noise's level), and the 5-fold cross-validated figure is within a factor 1.5 of the
/// held-out one.
#[test]
fn every_tool_works_on_a_trees_views_and_points_as_well_as_the_plain_fit() {
    use robocal::calibration::Tree;
    use robocal::calibration::selection::{Choices, Criterion, choose};
    use robocal::calibration::tree::calibrate_tree_feasible;
    for (tracker, seed) in [(false, 71), (true, 72)] {
        let (nominal, training, validation) = machined_case(tracker, seed);
        let held_out = |options: &KindOptions| {
            let c = calibrate_tree(&nominal, &training, options).unwrap();
            c.score(&validation).unwrap().view_position.unwrap().1
        };
        let plain = options(Estimator::Wls);
        let base = held_out(&plain);
        assert!(base < 0.1, "tracker {tracker}: plain wls held out {base} mm");
        let select = Choices { auto_prior: None, select: Some(Criterion::Cv { folds: 5 }) };
        let features = [
            (
                "--prior machined",
                KindOptions { prior: PriorEntry::parse_list("machined").unwrap(), ..plain.clone() },
            ),
            ("--loss huber", KindOptions { loss: Loss::Huber(1.345), ..plain.clone() }),
            (
                "--hold l_elbow.theta",
                KindOptions {
                    gauge: Gauge { hold: vec!["l_elbow.theta".into()], keep: Vec::new() },
                    ..plain.clone()
                },
            ),
            ("--select cv", choose(&Tree(&nominal), &training, &plain, &select).unwrap().options),
        ];
        let mut found: Vec<(&str, f64)> = features.iter().map(|(name, o)| (*name, held_out(o))).collect();
        let fgls = calibrate_tree_feasible(&nominal, &training, &plain, &Default::default()).unwrap();
        found.push(("fgls", fgls.score(&validation).unwrap().view_position.unwrap().1));
        eprintln!("tracker {tracker}: plain {base:.5} mm, {found:?}");
        for (feature, mm) in found {
            assert!(mm < 1.2 * base, "tracker {tracker} {feature}: held out {mm} mm, plain wls {base} mm");
        }
        let folds = cross_validate_tree(&nominal, &training, &plain, 5).unwrap().view_position.unwrap().1;
        assert!(
            folds < 1.5 * base && base < 1.5 * folds,
            "tracker {tracker}: 5-fold {folds} mm, held out {base}"
        );
    }
}

/// A target re-mounted between sessions (`--per-session`): a torso measured in three sessions
/// whose left hand's target moves by (+3.9, -0.9, 1.5) mm, then by (-1, 2, 0) mm and 0.25 deg
/// about its z axis. With that target's placement per session, each jump is recovered within 3
/// standard errors, and a held-out file of the second session (its stem) scores with that
/// session's placement at the noise level of a robot measured without a jump; without it, the
/// held-out error is several times larger.
#[test]
fn a_target_remounted_between_sessions_is_placed_per_session() {
    use robocal::calibration::kinds::SessionSetUp;
    let nominal = torso();
    let mut rng = ChaCha8Rng::seed_from_u64(81);
    let truth = perturbed_tree(&nominal, 0.1, 0.05f64.to_radians(), &mut rng);
    let (frames, placements) = frames(&nominal);
    let jumps: [[f64; 6]; 3] =
        [[0.0; 6], [3.9, -0.9, 1.5, 0.0, 0.0, 0.0], [-1.0, 2.0, 0.0, 0.0, 0.0, 0.25f64.to_radians()]];
    let sigma = [0.05, 0.01f64.to_radians()];
    let mut session = |k: usize, poses: usize, name: &str| {
        let mut at = placements.clone();
        (0..6).for_each(|i| at[6 + i] += jumps[k][i]);
        let q = nominal.uniform_configurations(poses, &mut rng);
        simulate_views(&truth, &frames, &at, &PAIRS, &q, sigma, &mut rng).named(name)
    };
    let sessions = [session(0, 40, "a"), session(1, 40, "b"), session(2, 40, "c")];
    let (held_out, unmoved, unmoved_held_out) =
        (session(1, 40, "b"), session(0, 120, "a"), session(0, 40, "a"));
    let elsewhere = session(2, 40, "d");
    let training = (sessions.iter()).try_fold(TreeData::default(), |all, s| all.join(s)).unwrap();
    let plain = options(Estimator::Wls);
    let per_session = KindOptions { per_session: vec!["target.l_hand.*".into()], ..plain.clone() };
    let c = calibrate_tree(&nominal, &training, &per_session).unwrap();
    // Each jump: the session's value less the first's, against the truth's, within 3 SE.
    let estimate = &c.refined.estimate;
    let at = |name: String| estimate.names.iter().position(|n| *n == name).unwrap();
    for (k, s) in [(1, "b"), (2, "c")] {
        for (i, axis) in ["x", "y", "z", "rx", "ry", "rz"].iter().enumerate() {
            let (first, later) =
                (at(format!("target.l_hand.{axis}@a")), at(format!("target.l_hand.{axis}@{s}")));
            let jump = estimate.x[later] - estimate.x[first];
            let cov = &estimate.covariance;
            let se = (cov[(later, later)] + cov[(first, first)] - 2.0 * cov[(first, later)]).sqrt();
            let error = jump - jumps[k][i];
            assert!(error.abs() < 3.0 * se, "session {s} {axis}: jump {jump}, true {}, SE {se}", jumps[k][i]);
        }
    }
    // Held out: the second session's placement, from the training file of its name.
    let score = c.score(&held_out).unwrap();
    assert_eq!(score.sessions, vec![("b".to_string(), SessionSetUp::Training("b".into()))]);
    // The noise level: the same robot measured as often without a jump, held out likewise.
    let reference = calibrate_tree(&nominal, &unmoved, &plain).unwrap().score(&unmoved_held_out).unwrap();
    let (with, noise) = (score.view_position.unwrap().1, reference.view_position.unwrap().1);
    let without = calibrate_tree(&nominal, &training, &plain)
        .unwrap()
        .score(&held_out)
        .unwrap()
        .view_position
        .unwrap()
        .1;
    eprintln!("held out: per session {with} mm, one placement {without} mm, without a jump {noise} mm");
    assert!(with < 1.2 * noise, "per session {with} mm, without a jump {noise} mm");
    assert!(without > 4.0 * with, "per session {with} mm, one placement {without} mm");
    // A session of no training file's name: its target placed on it alone, the tree held.
    let fitted = c.score(&elsewhere).unwrap();
    assert_eq!(fitted.sessions, vec![("d".to_string(), SessionSetUp::Fitted)]);
    assert!(
        fitted.view_position.unwrap().1 < 1.2 * noise,
        "session d: {} mm",
        fitted.view_position.unwrap().1
    );
    // Feasible GLS weighs the same set-up: its placements per session too.
    let fgls = robocal::calibration::tree::calibrate_tree_feasible(
        &nominal,
        &training,
        &per_session,
        &Default::default(),
    );
    let fgls = fgls.unwrap().score(&held_out).unwrap().view_position.unwrap().1;
    assert!(fgls < 1.2 * noise, "fgls per session {fgls} mm, without a jump {noise} mm");
    // Every fold keeps each session's placement.
    let folds = cross_validate_tree(&nominal, &training, &per_session, 5).unwrap().view_position.unwrap().1;
    assert!(folds < 1.5 * noise && noise < 1.5 * folds, "5-fold {folds} mm, without a jump {noise} mm");
}

/// `calibrate --per-session` on a tree's files: each later file's own placement of the named
/// target, reported as a frame of its session, and a held-out file of a training file's stem
/// scored with that session's placement (the report says which).
#[test]
fn calibrate_places_a_trees_target_per_file() {
    let json = std::env::temp_dir().join(format!("robocal-tree-sessions-{}.json", std::process::id()));
    let out = robocal(&[
        "calibrate",
        "--model",
        "presets/torso.urdf",
        "--data",
        "examples/torso/views.csv",
        "--data",
        "examples/torso/views-2.csv",
        "--per-session",
        "target.l_hand.*",
        "--validate",
        "examples/torso/views-2.csv",
        "--json",
        json.to_str().unwrap(),
    ]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let text = String::from_utf8(out.stdout).unwrap();
    for expected in [
        "target.l_hand.x@views-2",
        "  target.l_hand@views-2 ",
        "held-out sessions:\n  examples/torso/views-2.csv: the per-session set-up of training session `views-2`",
    ] {
        assert!(text.contains(expected), "{expected}: {text}");
    }
    let report: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    let frames: Vec<&str> =
        report["frames"].as_array().unwrap().iter().map(|f| f["name"].as_str().unwrap()).collect();
    assert_eq!(frames, ["camera.head_camera", "target.l_hand", "target.r_hand", "target.l_hand@views-2"]);
    assert_eq!(report["sets"][1][1]["sessions"][0][1]["training"], "views-2", "{}", report["sets"][1][1]);
    std::fs::remove_file(&json).unwrap();
}
