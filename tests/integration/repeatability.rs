//! Repeatability studies: the joint noise and sigma_me from repeated measurements, the
//! coverage of their 95% intervals, the file's errors, and the command end to end.

use assert_cmd::Command;
use nalgebra::{DVector, Isometry3, Translation3, UnitQuaternion, Vector3};
use rand::rngs::ChaCha8Rng;
use rand::{RngExt, SeedableRng};
use rand_distr::{Distribution, StandardNormal};
use robocal::calibration::{RepeatabilityData, RepeatabilityOptions, RepeatedPose, repeatability};
use robocal::estimation::JointComponents;
use robocal::kinematics::Chain;
use robocal::model::RobotModel;

/// The paper's joint noise (deg).
const DEGREES: [f64; 6] = [0.007, 0.007, 0.007, 0.002, 0.002, 0.002];
const SIGMA_ME: f64 = 0.01;

fn puma() -> RobotModel {
    RobotModel::preset("puma560").unwrap()
}

/// `poses` commanded configurations, each measured `repeats` times: the robot at `q + n_q`,
/// seen by a device 2 m away and turned (so the frames must be registered), with isotropic
/// noise `SIGMA_ME`.
fn simulate(model: &RobotModel, poses: usize, repeats: usize, rng: &mut ChaCha8Rng) -> RepeatabilityData {
    let chain = Chain::new(model).with_errors(&vec![0.0; model.params().len()]);
    let device = Isometry3::from_parts(
        Translation3::new(2000.0, -500.0, 100.0),
        UnitQuaternion::from_euler_angles(0.1, -0.2, 0.9),
    );
    let n = |rng: &mut ChaCha8Rng| -> f64 { StandardNormal.sample(rng) };
    let poses = (0..poses)
        .map(|k| {
            let q: Vec<f64> =
                model.joints.iter().map(|j| rng.random_range(j.limits[0]..j.limits[1])).collect();
            let measured = (0..repeats)
                .map(|_| {
                    let noisy: Vec<f64> =
                        q.iter().zip(DEGREES).map(|(q, s)| q + s.to_radians() * n(rng)).collect();
                    let p = device * nalgebra::Point3::from(chain.position(&noisy));
                    let e = Vector3::new(n(rng), n(rng), n(rng)) * SIGMA_ME;
                    DVector::from_column_slice((p.coords + e).as_slice())
                })
                .collect();
            RepeatedPose { id: format!("P{k}"), joints: q, measured, lines: vec![0; repeats] }
        })
        .collect();
    RepeatabilityData { poses, markers: 1 }
}

fn options(joints: JointComponents) -> RepeatabilityOptions {
    RepeatabilityOptions { joints, markers: Vec::new(), register: true }
}

/// 200 seeded studies of 24 poses x 10 measurements: the true sigma of every joint and
/// sigma_me lies in its reported 95% interval in at least 90% of them (a binomial 95% would
/// fall below 90% with probability under 0.1%).
#[test]
fn the_true_sigmas_fall_within_the_95_percent_intervals() {
    let model = puma();
    let replications = 200;
    let truth: Vec<f64> = DEGREES.iter().map(|d| d.to_radians()).chain([SIGMA_ME]).collect();
    let results: Vec<Vec<bool>> = (0..replications)
        .map(|r| {
            let mut rng = ChaCha8Rng::seed_from_u64(1000 + r);
            let data = simulate(&model, 24, 10, &mut rng);
            let estimate =
                repeatability(&model, &data, &options(JointComponents::Diagonal)).unwrap().estimate;
            let mut covered: Vec<bool> = (0..6).map(|j| estimate.joint_sigma(j).contains(truth[j])).collect();
            covered.push(estimate.sigma_me().contains(SIGMA_ME));
            covered
        })
        .collect();
    let coverage: Vec<f64> =
        (0..7).map(|c| results.iter().filter(|r| r[c]).count() as f64 / replications as f64).collect();
    eprintln!("coverage of the 95% intervals (j1..j6, sigma_me): {coverage:?}");
    assert!(coverage.iter().all(|&c| c >= 0.90), "{coverage:?}");
}

#[test]
fn a_long_study_pins_the_sigmas_down() {
    let model = puma();
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    let data = simulate(&model, 60, 30, &mut rng);
    let result = repeatability(&model, &data, &options(JointComponents::Diagonal)).unwrap();
    let e = &result.estimate;
    for (j, d) in DEGREES.iter().enumerate().take(3) {
        let s = e.joint_sigma(j);
        assert!(s.contains(d.to_radians()), "j{}: {s:?}", j + 1);
        assert!(s.high / s.low < 1.25, "j{}: a narrow interval {s:?}", j + 1);
    }
    assert!(
        e.sigma_me().contains(SIGMA_ME) && e.sigma_me().high / e.sigma_me().low < 1.5,
        "{:?}",
        e.sigma_me()
    );
    // A full Sigma_q: every sigma within its interval, the correlations near zero.
    let full = repeatability(&model, &data, &options(JointComponents::Full)).unwrap().estimate;
    for (j, d) in DEGREES.iter().enumerate() {
        assert!(full.joint_sigma(j).contains(d.to_radians()), "j{}: {:?}", j + 1, full.joint_sigma(j));
    }
    let c = full.joint_covariance();
    assert!((c[(0, 1)] / (c[(0, 0)] * c[(1, 1)]).sqrt()).abs() < 0.3, "{c}");
    assert!(full.sigma_me().contains(SIGMA_ME), "{:?}", full.sigma_me());
    // Written and read back: positive semi-definite to the file's digits.
    let text = full.spec().to_toml_string(&model, "a full Sigma_q");
    let back = robocal::estimation::NoiseSpec::from_toml_str(&text, &model).unwrap();
    assert!(back.full && (&back.joint - &c).amax() < 1e-6 * c.amax(), "{text}");
}

const HEADER: &str = "# units: joints=deg, lengths=mm\npose,j1,j2,j3,j4,j5,j6,x1,y1,z1\n";

fn read(text: &str) -> String {
    RepeatabilityData::from_csv_str(text, &puma(), None).unwrap_err().to_string()
}

#[test]
fn a_file_without_a_pose_column_is_refused() {
    let message = read("# units: joints=deg, lengths=mm\nj1,j2,j3,j4,j5,j6,x1,y1,z1\n1,2,3,4,5,6,7,8,9\n");
    assert_eq!(
        message,
        "line 2, column `pose`: missing pose column: a repeatability file names the commanded pose of each row"
    );
}

#[test]
fn a_file_without_a_joint_column_is_refused() {
    let message = read("# units: joints=deg, lengths=mm\npose,j1,j2,j3,j4,j5,x1,y1,z1\nA,1,2,3,4,5,7,8,9\n");
    assert!(message.starts_with("line 2, column `j6`: missing joint column"), "{message}");
}

#[test]
fn a_pose_measured_once_is_refused() {
    let text = format!("{HEADER}A,1,2,3,4,5,6,7,8,9\nA,1,2,3,4,5,6,7,8,9.01\nB,1,2,3,4,5,6,7,8,9\n");
    assert_eq!(
        read(&text),
        "line 5, column `pose`: pose `B` is measured once: a repeatability study needs at least 2 \
         measurements a pose"
    );
}

#[test]
fn a_nan_in_the_file_is_refused() {
    let text = format!("{HEADER}A,1,2,3,4,5,6,7,8,9\nA,1,2,3,4,5,6,7,NaN,9\n");
    assert_eq!(read(&text), "line 4, column `y1`: NaN: expected a finite number");
}

#[test]
fn an_empty_pose_id_is_refused() {
    let text = format!("{HEADER}A,1,2,3,4,5,6,7,8,9\n,1,2,3,4,5,6,7,8,9\n");
    assert_eq!(read(&text), "line 4, column `pose`: empty pose id");
}

/// The study as a file, `robocal repeatability` writing the noise file, and `robocal calibrate
/// --noise` reading it back.
#[test]
fn the_command_writes_a_noise_file_that_calibrate_reads() {
    let model = puma();
    let mut rng = ChaCha8Rng::seed_from_u64(77);
    let data = simulate(&model, 20, 8, &mut rng);
    let mut csv = String::from(HEADER);
    for pose in &data.poses {
        for m in &pose.measured {
            let q: Vec<String> = pose.joints.iter().map(|v| format!("{:.9}", v.to_degrees())).collect();
            csv += &format!("{},{},{:.6},{:.6},{:.6}\n", pose.id, q.join(","), m[0], m[1], m[2]);
        }
    }
    let dir = std::env::temp_dir().join(format!("robocal-repeatability-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let (file, noise) = (dir.join("repeat.csv"), dir.join("noise.toml"));
    std::fs::write(&file, &csv).unwrap();
    let output = Command::cargo_bin("robocal")
        .unwrap()
        .args(["repeatability", "--model", "puma560", "--data"])
        .arg(&file)
        .arg("--out")
        .arg(&noise)
        .output()
        .unwrap();
    let stdout = String::from_utf8(output.stdout).unwrap();
    assert!(output.status.success(), "{stdout}{}", String::from_utf8_lossy(&output.stderr));
    assert!(stdout.contains("20 poses, 160 measurements"), "{stdout}");
    assert!(stdout.contains("sigma_me"), "{stdout}");
    let spec = robocal::io::load_noise(&noise, &model).unwrap();
    assert!((spec.joint_sigmas()[1].to_degrees() / 0.007 - 1.0).abs() < 0.5, "{spec:?}");

    // The calibration data: the measurement format, 40 poses of the same robot.
    let measurements = robocal::simulation::measurement_csv(
        &model,
        &[Vector3::new(50.0, 0.0, 150.0)],
        &(0..40)
            .map(|_| model.joints.iter().map(|j| rng.random_range(j.limits[0]..j.limits[1])).collect())
            .collect::<Vec<_>>(),
        &DEGREES.map(f64::to_radians),
        SIGMA_ME,
        3,
    );
    let calibration = dir.join("measurements.csv");
    std::fs::write(&calibration, measurements).unwrap();
    let output = Command::cargo_bin("robocal")
        .unwrap()
        .args(["calibrate", "--model", "puma560", "--params", "offsets", "--data"])
        .arg(&calibration)
        .arg("--noise")
        .arg(&noise)
        .output()
        .unwrap();
    let stdout = String::from_utf8(output.stdout).unwrap();
    assert!(output.status.success(), "{stdout}{}", String::from_utf8_lossy(&output.stderr));
    assert!(stdout.contains(", wls ("), "{stdout}");
    std::fs::remove_dir_all(&dir).unwrap();
}
