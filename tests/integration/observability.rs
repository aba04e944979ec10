//! Observability indices: their formulas on hand-computed values, against a literal dense
//! computation of the scaled and whitened H, rank deficiency, pose files, `robocal observability`.

use assert_cmd::Command;
use nalgebra::{DMatrix, Matrix6xX};
use rand::SeedableRng;
use rand::rngs::ChaCha8Rng;
use robocal::design::{Design, Indices, o1, o2, o3, o4, o5, poses_csv, poses_from_csv_str};
use robocal::estimation::{MeasurementNoise, NoiseModel};
use robocal::kinematics::{Chain, Measured};
use robocal::model::{RobotModel, Selection};

const JOINT_SIGMA_DEG: [f64; 6] = [0.007, 0.007, 0.007, 0.002, 0.002, 0.002];

fn puma_design(sigma_scale: f64) -> Design {
    let model = RobotModel::preset("puma560").unwrap();
    let sigmas: Vec<f64> = JOINT_SIGMA_DEG.iter().map(|s| s.to_radians() * sigma_scale).collect();
    let noise = NoiseModel::diagonal(&sigmas, MeasurementNoise::isotropic(0.01 * sigma_scale, 0.0));
    Design::new(&model, Selection::joints(&model.params()), Measured::Position, Some(noise)).unwrap()
}

fn random_poses(n: usize, seed: u64) -> Vec<Vec<f64>> {
    let model = RobotModel::preset("puma560").unwrap();
    model.uniform_configurations(n, &mut ChaCha8Rng::seed_from_u64(seed))
}

#[test]
fn indices_follow_their_formulas() {
    // sigma = (4, 2, 1) of m = 4 poses.
    let s = [4.0, 2.0, 1.0];
    assert!((o1(&s, 4) - 8f64.powf(1.0 / 3.0) / 2.0).abs() < 1e-15);
    assert_eq!(o2(&s), 0.25);
    assert_eq!(o3(&s), 1.0);
    assert_eq!(o4(&s), 0.25);
    assert!((o5(&s) - 4.0 / 7.0).abs() < 1e-15);
    let indices = Indices::from_singular_values(&s, 4, 3);
    assert!((indices.log_det - 2.0 * 8f64.ln()).abs() < 1e-14);
    assert_eq!((indices.rank, indices.condition_number), (3, 4.0));
    // A zero singular value (or a missing one: fewer rows than columns) zeroes all five.
    let deficient = Indices::from_singular_values(&[4.0, 2.0], 4, 3);
    assert_eq!(deficient.rank, 2);
    assert_eq!([deficient.o1, deficient.o2, deficient.o3, deficient.o4, deficient.o5], [0.0; 5]);
    assert_eq!(deficient.log_det, f64::NEG_INFINITY);
    assert!(deficient.condition_number.is_infinite());
}

/// H of the identifiable columns, scaled by the design's scales, and whitened by the literal
/// inverse Cholesky factor of V_k = J Sigma_q J^T + Sigma_m, then nalgebra's dense SVD.
#[test]
fn indices_match_a_literal_dense_computation() {
    let design = puma_design(1.0);
    let model = design.model().clone();
    let chain = Chain::new(&model);
    let nominal = chain.with_errors(&vec![0.0; chain.params().len()]);
    let selection = Selection::joints(&model.params());
    let names = design.parameters().to_vec();
    let columns: Vec<usize> =
        design.identifiable().iter().map(|n| names.iter().position(|m| m == n).unwrap()).collect();
    assert_eq!(columns.len(), 23, "the paper's 30 parameters have rank 23 from positions");
    let poses = random_poses(20, 5);
    let sigma_q = DMatrix::from_diagonal(&JOINT_SIGMA_DEG.map(|s| s.to_radians().powi(2)).to_vec().into());
    let (mut scaled, mut whitened) = (DMatrix::zeros(60, 23), DMatrix::zeros(60, 23));
    for (k, q) in poses.iter().enumerate() {
        let mut h = DMatrix::zeros(3, 30);
        let mut j = Matrix6xX::zeros(6);
        nominal.jacobians(q, &selection, Measured::Position, h.view_mut((0, 0), (3, 30)), Some(&mut j));
        let h_s = DMatrix::from_fn(3, 23, |r, c| h[(r, columns[c])] * design.scales()[c]);
        let j_p = j.rows(0, 3).into_owned();
        let v = &j_p * &sigma_q * j_p.transpose() + DMatrix::identity(3, 3) * 0.01f64.powi(2);
        let l_inv = v.cholesky().unwrap().l().try_inverse().unwrap();
        scaled.rows_mut(3 * k, 3).copy_from(&h_s);
        whitened.rows_mut(3 * k, 3).copy_from(&(l_inv * &h_s));
    }
    let observability = design.observability(&poses).unwrap();
    for (name, dense, ours) in [
        ("scaled", &scaled, &observability.scaled),
        ("whitened", &whitened, observability.whitened.as_ref().unwrap()),
    ] {
        let mut s: Vec<f64> = dense.clone().svd(false, false).singular_values.iter().copied().collect();
        s.sort_by(|a, b| b.total_cmp(a));
        let close = |a: f64, b: f64| (a - b).abs() <= 1e-9 * b.abs();
        for (a, b) in ours.singular_values.iter().zip(&s) {
            assert!(close(*a, *b), "{name}: singular values {a} against {b}");
        }
        let m = poses.len() as f64;
        let geometric = (s.iter().map(|v| v.ln()).sum::<f64>() / 23.0).exp();
        let expected = [
            geometric / m.sqrt(),
            s[22] / s[0],
            s[22],
            s[22] * s[22] / s[0],
            1.0 / s.iter().map(|v| 1.0 / v).sum::<f64>(),
        ];
        let got = [ours.o1, ours.o2, ours.o3, ours.o4, ours.o5];
        for (i, (g, e)) in got.iter().zip(expected).enumerate() {
            assert!(close(*g, e), "{name}: O{} = {g}, literal {e}", i + 1);
        }
        assert_eq!(ours.rank, 23);
    }
}

#[test]
fn the_redundant_paper_set_is_judged_on_its_identifiable_columns() {
    let design = puma_design(1.0);
    let observability = design.observability(&random_poses(12, 3)).unwrap();
    assert_eq!((observability.parameters, observability.identifiable), (30, 23));
    assert!(observability.scaled.o1 > 0.1 && observability.scaled.o3 > 0.0, "{observability:?}");
    // One pose repeated identifies 3 combinations at most: every index is 0.
    let repeated = vec![random_poses(1, 3)[0].clone(); 12];
    let degenerate = design.observability(&repeated).unwrap();
    assert_eq!(degenerate.scaled.rank, 3);
    let w = degenerate.whitened.unwrap();
    assert_eq!([w.o1, w.o2, w.o3, w.o4, w.o5], [0.0; 5]);
}

#[test]
fn whitened_singular_values_scale_inversely_with_the_noise() {
    let poses = random_poses(16, 8);
    let (once, twice) = (puma_design(1.0), puma_design(2.0));
    let (a, b) = (once.observability(&poses).unwrap(), twice.observability(&poses).unwrap());
    let (wa, wb) = (a.whitened.unwrap(), b.whitened.unwrap());
    assert!((wa.o3 / wb.o3 - 2.0).abs() < 1e-9 && (wa.o1 / wb.o1 - 2.0).abs() < 1e-9);
    assert!((wa.o2 - wb.o2).abs() < 1e-12, "the inverse condition number does not see the scale");
    assert_eq!(a.scaled, b.scaled, "the column-scaled indices do not see the noise");
}

#[test]
fn pose_files_read_back() {
    let model = RobotModel::preset("puma560").unwrap();
    let poses = random_poses(5, 1);
    let text = poses_csv(&model, &poses, "a comment\nand another");
    assert!(
        text.starts_with("# units: joints=deg, lengths=mm\n# a comment\n# and another\nj1,j2,j3,j4,j5,j6\n")
    );
    let back = poses_from_csv_str(&text, &model, None).unwrap();
    for (q, r) in poses.iter().zip(&back) {
        for (a, b) in q.iter().zip(r) {
            assert!((a - b).abs() < 1e-8, "{a} against {b}");
        }
    }
}

#[test]
fn pose_file_errors_name_the_line_and_column() {
    let model = RobotModel::preset("puma560").unwrap();
    let units = "# units: joints=deg, lengths=mm\n";
    let missing =
        poses_from_csv_str(&format!("{units}j1,j2,j3,j4,j6\n1,2,3,4,5\n"), &model, None).unwrap_err();
    assert_eq!(
        missing.to_string(),
        "line 2, column `j5`: missing joint column; the model's joints are j1, j2, j3, j4, j5, j6"
    );
    let nan =
        poses_from_csv_str(&format!("{units}j1,j2,j3,j4,j5,j6\n1,2,3,NaN,5,6\n"), &model, None).unwrap_err();
    assert_eq!(nan.to_string(), "line 3, column `j4`: NaN: expected a finite number");
    let text =
        poses_from_csv_str(&format!("{units}j1,j2,j3,j4,j5,j6\n1,2,x,4,5,6\n"), &model, None).unwrap_err();
    assert_eq!(text.to_string(), "line 3, column `j3`: `x` is not a number");
    let none = poses_from_csv_str("j1,j2,j3,j4,j5,j6\n1,2,3,4,5,6\n", &model, None).unwrap_err();
    assert!(none.to_string().contains("units not declared"), "{none}");
    let empty = poses_from_csv_str(&format!("{units}j1,j2,j3,j4,j5,j6\n"), &model, None).unwrap_err();
    assert!(empty.to_string().contains("no poses"), "{empty}");
}

fn robocal() -> Command {
    Command::cargo_bin("robocal").unwrap()
}

fn temp(name: &str) -> std::path::PathBuf {
    let dir = std::env::temp_dir().join(format!("robocal-observability-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir.join(name)
}

#[test]
fn observability_prints_the_indices_of_a_measurement_file() {
    let output = robocal()
        .args(["observability", "examples/puma560-measurements.csv", "--model", "puma560"])
        .args(["--joint-sigma-deg", "0.007,0.007,0.007,0.002,0.002,0.002", "--sigma-mm", "0.01"])
        .output()
        .unwrap();
    assert!(output.status.success(), "{}", String::from_utf8_lossy(&output.stderr));
    let text = String::from_utf8(output.stdout).unwrap();
    assert!(text.contains("observability of 100 poses"), "{text}");
    assert!(text.contains("30 parameters, 23 identifiable from position measurements"), "{text}");
    for index in ["O1", "O2", "O3", "O4", "O5", "log det", "condition number"] {
        assert!(text.contains(index), "{index} missing: {text}");
    }
    let rank = text.lines().find(|l| l.starts_with("rank")).unwrap();
    assert_eq!(rank.split_whitespace().collect::<Vec<_>>(), ["rank", "23", "23"]);
}

#[test]
fn observability_errors_name_the_file_line_and_column() {
    let path = temp("nan.csv");
    std::fs::write(&path, "# units: joints=deg, lengths=mm\nj1,j2,j3,j4,j5,j6\n1,2,3,4,5,6\n1,2,3,inf,5,6\n")
        .unwrap();
    let output =
        robocal().args(["observability", path.to_str().unwrap(), "--model", "puma560"]).output().unwrap();
    assert_eq!(output.status.code(), Some(1));
    let message = String::from_utf8(output.stderr).unwrap();
    assert!(message.contains("nan.csv: line 4, column `j4`: inf: expected a finite number"), "{message}");
    let output = robocal()
        .args(["observability", path.to_str().unwrap(), "--model", "puma560", "--joint-sigma-deg", "0.1,0.1"])
        .output()
        .unwrap();
    let message = String::from_utf8(output.stderr).unwrap();
    assert!(message.contains("--joint-sigma-deg: 2 values for the 6 joints of puma560"), "{message}");
}

/// Pose rows in lengths: the indices of a pose design do not depend on the length unit (the
/// robot and the noise in metres give the same column-scaled indices, and whitened ones per
/// metre of noise instead of per mm), since the
/// orientation rows are weighted by `sigma_position / sigma_orientation`.
#[test]
fn pose_indices_do_not_depend_on_the_length_unit() {
    let model = RobotModel::preset("puma560").unwrap();
    let sigmas: Vec<f64> =
        [0.007, 0.007, 0.007, 0.002, 0.002, 0.002].iter().map(|d: &f64| d.to_radians()).collect();
    let design = |model: &RobotModel, sigma_mm: f64| {
        let noise =
            NoiseModel::diagonal(&sigmas, MeasurementNoise::isotropic(sigma_mm, 0.002f64.to_radians()));
        Design::new(model, Selection::joints(&model.params()), Measured::Pose, Some(noise)).unwrap()
    };
    let poses = random_poses(15, 7);
    let mm = design(&model, 0.01).observability(&poses).unwrap();
    let m = design(&crate::calibration::in_metres(&model), 1e-5).observability(&poses).unwrap();
    let (a, b) = (&mm.scaled, &m.scaled);
    for (x, y) in [(a.o1, b.o1), (a.o2, b.o2), (a.o3, b.o3), (a.o4, b.o4), (a.o5, b.o5)] {
        assert!((x - y).abs() <= 1e-6 * x.abs().max(y.abs()), "{a:?} against {b:?}");
    }
    // The whitened singular values are per unit of noise: a thousand per metre for one per mm.
    let (a, b) = (mm.whitened.as_ref().unwrap(), m.whitened.as_ref().unwrap());
    for (x, y) in a.singular_values.iter().zip(&b.singular_values) {
        assert!((1000.0 * x - y).abs() <= 1e-6 * y, "{a:?} against {b:?}");
    }
}
