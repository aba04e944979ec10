//! Camera targets, hand-eye and eye-to-hand: H against finite differences, the closed-form
//! start, exact recovery without noise, estimates within 3 predicted standard errors with
//! noise, what a camera cannot see, and the command end to end.

use crate::kinds::{h_matches_finite_differences, robot_estimates};
use crate::kinematics::{point, robot};
use nalgebra::{DMatrix, DVector, Isometry3, UnitQuaternion, Vector3, Vector6};
use proptest::prelude::*;
use rand::rngs::ChaCha8Rng;
use rand::{RngExt, SeedableRng};
use rand_distr::{Distribution, StandardNormal};
use robocal::calibration::kinds::camera::{camera_start, isometry, placement};
use robocal::calibration::kinds::{
    CameraSite, KindCalibration, KindData, KindOptions, KindProblem, Observation, SetUp, calibrate_kinds,
};
use robocal::calibration::{BaseAbsorber, Unseen};
use robocal::estimation::{Estimator, Residuals};
use robocal::kinematics::{Chain, ChainAt};
use robocal::model::{Convention, ParamOwner, Placement, RobotModel, Selection};

/// Every column of `H` (robot parameters, camera and target; and the camera and target alone)
/// against central differences of the residuals (`H = -dy/dx`), and its linearisation against
/// the whole system, for a camera at `site` seeing its target at three poses, the
/// views and the set-up drawn from `u` (rotations up to 2 rad: residuals far from 0).
fn check_camera_jacobians(model: &RobotModel, u: &[f64], site: CameraSite) -> Result<(), TestCaseError> {
    let tool = Vector3::new(u[0], u[1], u[2]) * 200.0;
    let chain = Chain::probe(model, &Placement { xyz: tool, rpy: Vector3::new(u[7], u[8], u[9]) });
    let params = chain.params();
    let (_, x) = point(model, &u[20..]);
    let x: Vec<f64> = (0..params.len()).map(|i| x[i % x.len()]).collect();
    let joints: Vec<Vec<f64>> = (0..3).map(|k| point(model, &u[k * 7..]).0).collect();
    let mut data = KindData { joints, ..KindData::default() };
    for pose in 0..3 {
        let view = Vector6::from_fn(|i, _| u[40 + 6 * pose + i] * if i < 3 { 500.0 } else { 2.0 });
        for axis in 0..6 {
            data.observations.push(Observation::Camera { axis, pose, view, site, sigma: 0.1 });
            data.lines.push(data.lines.len() + 2);
        }
    }
    let setup = SetUp::new(0, &[]).with_camera(site);
    let s: Vec<f64> = (0..12).map(|i| u[60 + i] * if i % 6 < 3 { 300.0 } else { 2.0 }).collect();
    // The robot's parameters and the placements; the placements alone (a "before" fit's).
    for selection in [Selection::all(params), Selection::from_indices(params, [])] {
        let (x, s) = (x.clone(), s.clone());
        let problem = KindProblem::new(&chain, &selection, &data, &setup, x, s, (0..12).collect(), None);
        h_matches_finite_differences(&problem, &data)?;
    }
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(1000))]

    #[test]
    fn hand_eye_jacobians_match_finite_differences(model in robot(Convention::StandardDh, true), u in prop::collection::vec(-1.0..1.0f64, 72)) {
        check_camera_jacobians(&model, &u, CameraSite::Hand)?;
    }

    #[test]
    fn eye_to_hand_jacobians_match_finite_differences(model in robot(Convention::Urdf, false), u in prop::collection::vec(-1.0..1.0f64, 72)) {
        check_camera_jacobians(&model, &u, CameraSite::World)?;
    }
}

fn puma() -> RobotModel {
    RobotModel::preset("puma560").unwrap()
}

/// Random joint values within `model`'s limits.
fn random_pose(model: &RobotModel, rng: &mut ChaCha8Rng) -> Vec<f64> {
    model.joints.iter().map(|j| rng.random_range(j.limits[0]..j.limits[1])).collect()
}

/// Small parameter errors on the `kept` parameters of `chain` (the others zero).
fn errors_on(chain: &Chain, kept: &[String], rng: &mut ChaCha8Rng) -> Vec<f64> {
    let params = chain.params();
    let mut x = vec![0.0; params.len()];
    for name in kept {
        if let Some(i) = params.index_by_name(name) {
            let z: f64 = StandardNormal.sample(&mut *rng);
            x[i] = z * if params.get(i).kind.is_angle() { 0.1f64.to_radians() } else { 0.5 };
        }
    }
    x
}

/// The camera's and the target's placements (`x, y, z, rx, ry, rz`) of a set-up at `site`:
/// hand-eye, a camera 60 mm out of the flange looking at a board 700 mm in front of the robot;
/// eye-to-hand, a camera 1.5 m away looking at a board on the flange.
pub(crate) fn truth(site: CameraSite) -> Vec<f64> {
    match site {
        CameraSite::Hand => vec![30.0, -20.0, 60.0, 0.1, -0.2, 0.3, 700.0, 100.0, -300.0, 0.2, 1.4, -0.1],
        CameraSite::World => vec![1200.0, -600.0, 500.0, 1.2, -0.8, 0.4, 10.0, 15.0, 40.0, -0.3, 0.1, 0.2],
        CameraSite::Tree { .. } => unreachable!("a serial arm's camera"),
    }
}

/// Views of the target by the camera at `site` from `count` random poses of the robot `real`
/// (the tool frame the flange's), the set-up `s`, noise of `sigma` (mm, and deg on the rotation)
/// on each view.
pub(crate) fn views(
    real: &ChainAt,
    site: CameraSite,
    s: &[f64],
    count: usize,
    sigma: (f64, f64),
    rng: &mut ChaCha8Rng,
) -> KindData {
    let mut data = KindData::default();
    let (camera, target) = (isometry(&s[..6]), isometry(&s[6..]));
    for pose in 0..count {
        let q = random_pose(&puma(), rng);
        let tool = real.pose(&q);
        let m = match site {
            CameraSite::Hand => (tool * camera).inverse() * target,
            CameraSite::World => camera.inverse() * tool * target,
            CameraSite::Tree { .. } => unreachable!("a serial arm's camera"),
        };
        let z = |rng: &mut ChaCha8Rng| Vector3::from_fn(|_, _| StandardNormal.sample(&mut *rng));
        let turn = UnitQuaternion::from_scaled_axis(z(rng) * sigma.1.to_radians());
        let m = Isometry3::from_parts((m.translation.vector + z(rng) * sigma.0).into(), turn * m.rotation);
        let view = placement(&m);
        data.joints.push(q);
        for axis in 0..6 {
            let sigma = if axis < 3 { sigma.0.max(1e-3) } else { sigma.1.max(1e-3).to_radians() };
            data.observations.push(Observation::Camera { axis, pose, view, site, sigma });
            data.lines.push(pose + 3);
        }
    }
    data
}

fn options(estimator: Estimator) -> KindOptions {
    KindOptions { estimator, ..KindOptions::default() }
}

/// The flange's frame as the calibration's tool frame.
pub(crate) fn flange(model: &RobotModel) -> Chain {
    Chain::probe(model, &Placement { xyz: Vector3::zeros(), rpy: Vector3::zeros() })
}

/// The closed-form start on exact views of the nominal robot is the set-up itself.
#[test]
fn the_start_solves_the_hand_eye_equation() {
    let model = puma();
    let at = flange(&model).with_errors(&vec![0.0; flange(&model).params().len()]);
    let mut rng = ChaCha8Rng::seed_from_u64(80);
    for site in [CameraSite::Hand, CameraSite::World] {
        let data = views(&at, site, &truth(site), 10, (0.0, 0.0), &mut rng);
        let pairs: Vec<_> = (0..10)
            .map(|k| match data.observations[6 * k] {
                Observation::Camera { pose, view, .. } => {
                    (at.pose(&data.joints[pose]), isometry(view.as_slice()))
                }
                _ => unreachable!(),
            })
            .collect();
        let (camera, target) = camera_start(&pairs, site).unwrap();
        let found: Vec<f64> = placement(&camera).iter().chain(placement(&target).iter()).copied().collect();
        for (f, t) in found.iter().zip(truth(site)) {
            assert!((f - t).abs() < 1e-8 * t.abs().max(1.0), "{site:?}: {found:?} against {:?}", truth(site));
        }
        assert!(camera_start(&pairs[..2], site).is_err());
    }
}

/// Exact views from errors on every parameter but the base's: the training and held-out
/// residuals vanish. Then errors on the parameters the views identify, noiseless: the robot, the
/// camera and the target recovered exactly; with noise, each within 3 predicted standard errors.
fn camera_recovers(site: CameraSite, seed: u64) -> KindCalibration {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let model = puma();
    let chain = flange(&model);
    let s = truth(site);
    let all: Vec<String> =
        chain.params().iter().filter(|p| !p.name.starts_with("base.")).map(|p| p.name.clone()).collect();
    let real = chain.with_errors(&errors_on(&chain, &all, &mut rng));
    let exact = views(&real, site, &s, 40, (0.0, 0.0), &mut rng);
    let c = calibrate_kinds(&model, &exact, &options(Estimator::Ols)).unwrap();
    let (train, angles) = (c.training.lengths, c.training.angles.unwrap());
    assert!(train.1 < 1e-7 && angles.1 < 1e-8, "exact data: training RMS {train:?} mm, {angles:?} deg");
    assert!(train.0 > 1e3 * train.1, "before {} mm, after {} mm", train.0, train.1);
    let held_out = c.score(&views(&real, site, &s, 20, (0.0, 0.0), &mut rng)).unwrap();
    assert!(
        held_out.lengths.1 < 1e-6 && held_out.lengths.0 > 0.1,
        "exact held-out RMS {:?} mm",
        held_out.lengths
    );

    let robot = robot_estimates(&c.refined.estimate.names, &chain);
    let truth_x = errors_on(&chain, &robot, &mut rng);
    let real = chain.with_errors(&truth_x);
    let c =
        calibrate_kinds(&model, &views(&real, site, &s, 40, (0.0, 0.0), &mut rng), &options(Estimator::Ols))
            .unwrap();
    let names = c.setup.names();
    for name in &c.refined.estimate.names {
        let (found, real) = match chain.params().index_by_name(name) {
            Some(i) => (c.after[i], truth_x[i]),
            None => {
                let i = names.iter().position(|n| n == name).unwrap();
                (c.setup_values.1[i], s[i])
            }
        };
        assert!((found - real).abs() < 1e-7 * real.abs().max(1.0), "{name}: {found} against {real}");
    }

    let noisy = views(&real, site, &s, 80, (0.05, 0.01), &mut rng);
    let c = calibrate_kinds(&model, &noisy, &options(Estimator::Wls)).unwrap();
    let se = c.refined.estimate.standard_errors();
    let mut checked = 0;
    for (k, name) in c.refined.estimate.names.iter().enumerate() {
        let (found, real) = match chain.params().index_by_name(name) {
            Some(i) => (c.after[i], truth_x[i]),
            None => {
                let i = names.iter().position(|n| n == name).unwrap();
                (c.setup_values.1[i], s[i])
            }
        };
        assert!((found - real).abs() < 3.0 * se[k], "{name}: {found} against {real}, SE {}", se[k]);
        checked += 1;
    }
    assert!(checked >= 30, "{checked} estimates checked");
    c
}

#[test]
fn a_camera_on_the_arm_calibrates_the_robot_its_mounting_and_the_target() {
    let c = camera_recovers(CameraSite::Hand, 81);
    assert_eq!(c.unseen, [Unseen::Base { absorbed_by: BaseAbsorber::Target }]);
    assert!(c.unseen[0].to_string().contains("the target placement absorbs the base placement"));
    assert!(c.refined.estimate.names.iter().any(|n| n == "camera.rz"));
    assert!(c.refined.estimate.names.iter().any(|n| n == "target.x"));
    let robot = c.refined.estimate.names.iter().filter_map(|n| c.params.index_by_name(n));
    let owners: Vec<ParamOwner> = robot.map(|i| c.params.get(i).owner).collect();
    assert!(owners.iter().all(|o| matches!(o, ParamOwner::Joint(_))), "{owners:?}");
}

#[test]
fn a_fixed_camera_calibrates_the_robot_its_placement_and_the_target_on_the_arm() {
    let c = camera_recovers(CameraSite::World, 82);
    assert_eq!(c.unseen, [Unseen::Base { absorbed_by: BaseAbsorber::Camera }]);
    assert!(c.unseen[0].to_string().contains("the camera placement absorbs the base placement"));
}

/// A camera's file: the views of `data` as rows `j1..j6,camera,x,y,z,roll,pitch,yaw` (deg, mm).
fn views_csv(data: &KindData, site: &str) -> String {
    let mut text =
        String::from("# units: joints=deg, lengths=mm\nj1,j2,j3,j4,j5,j6,camera,x,y,z,roll,pitch,yaw\n");
    for (q, k) in data.joints.iter().zip((0..data.observations.len()).step_by(6)) {
        let Observation::Camera { view, .. } = data.observations[k] else { unreachable!() };
        let (roll, pitch, yaw) = isometry(view.as_slice()).rotation.euler_angles();
        let joints: Vec<String> = q.iter().map(|v| format!("{:.10}", v.to_degrees())).collect();
        let angles = [roll, pitch, yaw].map(|a| format!("{:.10}", a.to_degrees()));
        text += &format!(
            "{},{site},{:.8},{:.8},{:.8},{}\n",
            joints.join(","),
            view[0],
            view[1],
            view[2],
            angles.join(",")
        );
    }
    text
}

/// A camera file reads back into the views written; bad rows are named by line and column.
#[test]
fn camera_files_read_and_their_errors() {
    let model = puma();
    let mut rng = ChaCha8Rng::seed_from_u64(83);
    let at = flange(&model).with_errors(&vec![0.0; flange(&model).params().len()]);
    let data = views(&at, CameraSite::Hand, &truth(CameraSite::Hand), 4, (0.0, 0.0), &mut rng);
    let read = KindData::from_csv_str(&views_csv(&data, "hand"), &model, None).unwrap();
    assert_eq!(read.observations.len(), 24);
    for (a, b) in read.observations.iter().zip(&data.observations) {
        assert!((a.measured() - b.measured()).abs() < 1e-7, "{a:?} against {b:?}");
        assert_eq!(a.kind(), b.kind());
        assert!(matches!(a, Observation::Camera { site: CameraSite::Hand, .. }));
    }
    let Observation::Camera { sigma, .. } = read.observations[0] else { unreachable!() };
    assert_eq!(sigma, robocal::calibration::kinds::DEFAULT_CAMERA_SIGMA_MM);
    // Through a `kind` column, with sigmas.
    let mixed = "# units: joints=deg, lengths=mm\nkind,j1,j2,j3,j4,j5,j6,camera,x,y,z,roll,pitch,yaw,sigma,sigma_angle\n\
                 camera,0,10,20,0,30,0,world,1,2,300,10,20,30,0.2,0.05\n";
    let read = KindData::from_csv_str(mixed, &model, None).unwrap();
    assert_eq!(read.camera(), Some(CameraSite::World));
    assert_eq!(read.observations[2].sigma(), 0.2);
    assert!((read.observations[5].sigma() - 0.05f64.to_radians()).abs() < 1e-15);
    let header = "# units: joints=deg, lengths=mm\nj1,j2,j3,j4,j5,j6,camera,x,y,z,roll,pitch,yaw\n";
    for (row, expected) in [
        (
            "0,0,0,0,0,0,head,1,2,3,0,0,0",
            "line 3, column `camera`: `head`: expected hand (on the arm) or world",
        ),
        ("0,0,0,0,0,0,hand,1,2,3,0,,0", "line 3, column `pitch`: this kind of row needs a `pitch` value"),
        ("0,0,0,0,0,0,hand,1,x,3,0,0,0", "line 3, column `y`"),
        (
            "0,0,0,0,0,0,hand,1,2,3,0,0,0\n0,0,0,0,0,0,world,1,2,3,0,0,0",
            "line 4, column `camera`: a camera on the world",
        ),
    ] {
        let message =
            KindData::from_csv_str(&format!("{header}{row}\n"), &model, None).unwrap_err().to_string();
        assert!(message.contains(expected), "{message}");
    }
}

/// `robocal calibrate-observations` on a hand-eye camera's files: the report names the
/// camera's and the target's parameters and what a camera cannot see, and the held-out RMS of
/// the views falls to their noise.
#[test]
fn the_command_calibrates_from_a_camera_and_validates() {
    let dir = std::env::temp_dir().join(format!("robocal-camera-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let mut rng = ChaCha8Rng::seed_from_u64(84);
    let chain = flange(&puma());
    let all: Vec<String> =
        chain.params().iter().filter(|p| !p.name.starts_with("base.")).map(|p| p.name.clone()).collect();
    let real = chain.with_errors(&errors_on(&chain, &all, &mut rng));
    let s = truth(CameraSite::Hand);
    let (train, test) = (dir.join("train.csv"), dir.join("test.csv"));
    let noise = (0.05, 0.01);
    std::fs::write(&train, views_csv(&views(&real, CameraSite::Hand, &s, 60, noise, &mut rng), "hand"))
        .unwrap();
    std::fs::write(&test, views_csv(&views(&real, CameraSite::Hand, &s, 30, noise, &mut rng), "hand"))
        .unwrap();
    let json = dir.join("report.json");
    let path = |p: &std::path::Path| p.to_str().unwrap().to_string();
    let output = assert_cmd::Command::cargo_bin("robocal")
        .unwrap()
        .args(["calibrate", "--model", "puma560"])
        .args(["--data", &path(&train), "--validate", &path(&test), "--json", &path(&json)])
        .output()
        .unwrap();
    let text = String::from_utf8(output.stdout).unwrap();
    assert!(output.status.success(), "{text}{}", String::from_utf8_lossy(&output.stderr));
    assert!(text.contains("the target placement absorbs the base placement"), "{text}");
    assert!(text.contains("camera.rx") && text.contains("target.z"), "{text}");
    let report: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    let held_out = &report["sets"][1][1];
    assert_eq!(held_out["observations"].as_array().unwrap().len(), 180);
    let (before, after) =
        (held_out["lengths"][0].as_f64().unwrap(), held_out["lengths"][1].as_f64().unwrap());
    assert!(after * 5.0 < before && after < 0.2, "held-out RMS {before} mm before, {after} mm after\n{text}");
    std::fs::remove_dir_all(&dir).unwrap();
}

/// The README's camera example is the real output of its command on the example's files.
#[test]
fn the_readme_camera_example_is_the_real_output() {
    crate::cli::the_readme_block_is_printed(
        "$ robocal calibrate --model puma560 --data examples/puma560-camera.csv",
        &[
            "calibrate",
            "--model",
            "puma560",
            "--data",
            "examples/puma560-camera.csv",
            "--validate",
            "examples/puma560-camera-2.csv",
            "--joint-sigma-deg",
            "0.007,0.007,0.007,0.002,0.002,0.002",
        ],
    );
}

/// A camera and a ball bar in one fit: the camera's mounting in the tool frame at the tool
/// point, the ball's position on the same frame; exact data fitted exactly, training and held out.
#[test]
fn a_camera_and_a_ball_bar_fit_together() {
    let mut rng = ChaCha8Rng::seed_from_u64(85);
    let model = puma();
    let tool = Vector3::new(20.0, -10.0, 120.0);
    let chain = Chain::probe(&model, &Placement { xyz: tool, rpy: Vector3::zeros() });
    let all: Vec<String> =
        chain.params().iter().filter(|p| p.name.starts_with('j')).map(|p| p.name.clone()).collect();
    let real = chain.with_errors(&errors_on(&chain, &all, &mut rng));
    let pivot = Vector3::new(400.0, 200.0, 300.0);
    let measure = |rng: &mut ChaCha8Rng| {
        let mut bar = KindData::default();
        for pose in 0..60 {
            let q = random_pose(&model, rng);
            let measured = (real.position(&q) - pivot).norm();
            bar.joints.push(q);
            bar.observations.push(Observation::ToPoint { pose, point: 0, measured, sigma: 0.01 });
            bar.lines.push(pose + 3);
        }
        views(&real, CameraSite::Hand, &truth(CameraSite::Hand), 30, (0.0, 0.0), rng).join(&bar)
    };
    let options = KindOptions { tool, ..options(Estimator::Ols) };
    let c = calibrate_kinds(&model, &measure(&mut rng), &options).unwrap();
    let (lengths, angles) = (c.training.lengths, c.training.angles.unwrap());
    assert!(lengths.1 < 1e-7 && angles.1 < 1e-8, "training RMS {lengths:?} mm, {angles:?} deg");
    assert!(lengths.0 > 0.1, "before {lengths:?}");
    let held_out = c.score(&measure(&mut rng)).unwrap();
    assert!(held_out.lengths.1 < 1e-6 && held_out.lengths.0 > 0.1, "held-out RMS {:?} mm", held_out.lengths);
    let names = &c.refined.estimate.names;
    assert!(names.iter().any(|n| n == "point1.x") && names.iter().any(|n| n == "camera.rz"), "{names:?}");
}

/// `V_k` of a camera's rows against Monte Carlo: the joints read with noise `Sigma_q`, the
/// sample covariance of the view's six residuals over 3000 draws within 5 standard errors of
/// `V_k`, entry by entry: one block per pose, its rows correlated through the joint noise.
#[test]
fn the_covariance_of_a_view_is_the_joint_noise_of_its_pose() {
    let model = puma();
    let chain = flange(&model);
    let zero = vec![0.0; chain.params().len()];
    let mut rng = ChaCha8Rng::seed_from_u64(86);
    let sigmas = [0.05f64, 0.05, 0.05, 0.02, 0.02, 0.02].map(f64::to_radians);
    let sigma_q = DMatrix::from_diagonal(&DVector::from_iterator(6, sigmas.iter().map(|s| s * s)));
    let nothing = Selection::from_indices(chain.params(), []);
    for site in [CameraSite::Hand, CameraSite::World] {
        let s = truth(site);
        let mut data = views(&chain.with_errors(&zero), site, &s, 1, (0.0, 0.0), &mut rng);
        for o in &mut data.observations {
            if let Observation::Camera { sigma, .. } = o {
                *sigma = 1e-9;
            }
        }
        let setup = SetUp::new(0, &[]).with_camera(site);
        let problem = KindProblem::new(
            &chain,
            &nothing,
            &data,
            &setup,
            zero.clone(),
            s.clone(),
            vec![],
            Some(&sigma_q),
        );
        let v = problem.covariance().unwrap().clone();
        let draws = 3000;
        let mut samples: Vec<Vec<f64>> = (0..6).map(|_| Vec::with_capacity(draws)).collect();
        let q = data.joints[0].clone();
        for _ in 0..draws {
            data.joints[0] = q
                .iter()
                .zip(&sigmas)
                .map(|(q, s)| q + s * Distribution::<f64>::sample(&StandardNormal, &mut rng))
                .collect::<Vec<f64>>();
            let noisy =
                KindProblem::new(&chain, &nothing, &data, &setup, zero.clone(), s.clone(), vec![], None);
            for (k, y) in noisy.residuals(&DVector::zeros(0)).iter().enumerate() {
                samples[k].push(*y);
            }
        }
        // Every entry of the pose's block, the correlation between its rows included: the
        // sample covariance within 5 of its standard errors, sqrt((V_ii V_jj + V_ij^2) / (n - 1)).
        let mean: Vec<f64> = samples.iter().map(|v| v.iter().sum::<f64>() / draws as f64).collect();
        for i in 0..6 {
            for j in 0..6 {
                let sampled = (samples[i].iter().zip(&samples[j]))
                    .map(|(a, b)| (a - mean[i]) * (b - mean[j]))
                    .sum::<f64>()
                    / (draws - 1) as f64;
                let se = ((v[(i, i)] * v[(j, j)] + v[(i, j)].powi(2)) / (draws - 1) as f64).sqrt();
                assert!(
                    (sampled - v[(i, j)]).abs() < 5.0 * se,
                    "{site:?} ({i}, {j}): {sampled} sampled, V_k {}",
                    v[(i, j)]
                );
            }
        }
        let correlation = |i: usize, j: usize| v[(i, j)] / (v[(i, i)] * v[(j, j)]).sqrt();
        let strongest =
            (0..6).flat_map(|i| (0..i).map(move |j| (i, j))).map(|(i, j)| correlation(i, j).abs());
        assert!(strongest.fold(0.0, f64::max) > 0.5, "{site:?}: the view's rows are correlated: {v}");
    }
}

/// A view between a tree's frames in data for a serial arm is refused by name, not fitted.
#[test]
fn a_trees_view_in_a_serial_arms_data_is_refused() {
    let model = puma();
    let mut rng = ChaCha8Rng::seed_from_u64(84);
    let at = flange(&model).with_errors(&vec![0.0; flange(&model).params().len()]);
    let mut data = views(&at, CameraSite::Hand, &truth(CameraSite::Hand), 4, (0.0, 0.0), &mut rng);
    if let Observation::Camera { site, .. } = &mut data.observations[6] {
        *site = CameraSite::Tree { camera: 0, target: 1 };
    }
    let options = KindOptions { tool: Vector3::zeros(), ..KindOptions::default() };
    let e = calibrate_kinds(&model, &data, &options).unwrap_err().to_string();
    assert!(e.contains(&format!("line {}", data.lines[6])) && e.contains("tree"), "{e}");
}
