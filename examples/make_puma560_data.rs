//! Writes the example calibration data of the README: a "true" PUMA 560 (the preset with
//! known geometric errors, standing 1.5 m from a laser tracker and turned 34 degrees), and
//! what a tracker sees of two reflectors on its last link, with the paper's joint noise
//! (0.007 deg joints 1-3, 0.002 deg joints 4-6) and 0.01 mm of measurement noise:
//!
//! - `examples/puma560-true.toml`: the true robot (its base is the tracker-to-robot transform);
//! - `examples/puma560-measurements.csv`: 100 poses for calibration;
//! - `examples/puma560-validation.csv`: 50 other poses for validation.
//!
//! The true reflectors are at (52, 1, 148) and (-38, 61, 121) mm in frame 6; their design
//! positions, given to `calibrate` with --marker, are (50, 0, 150) and (-40, 60, 120).
//!
//! Run: `cargo run --release --example make_puma560_data`.

use nalgebra::Vector3;
use rand::rngs::ChaCha8Rng;
use rand::{RngExt, SeedableRng};
use rand_distr::{Distribution, StandardNormal};
use robocal::model::{Placement, RobotModel};
use robocal::simulation::measurement_csv;

fn main() -> std::io::Result<()> {
    let mut rng = ChaCha8Rng::seed_from_u64(560);
    let nominal = RobotModel::preset("puma560").expect("the preset exists");
    let mut truth = nominal.clone();
    truth.name = "puma560-true".into();
    truth.description = "The example's true PUMA 560: the preset with random errors (offsets 0.1 deg, angles 0.05 deg, lengths 0.5 mm, standard deviations), 1.5 m from the tracker.".into();
    for joint in &mut truth.joints {
        let mut n = || -> f64 { StandardNormal.sample(&mut rng) };
        joint.theta += 0.1f64.to_radians() * n();
        joint.d += 0.5 * n();
        joint.a += 0.5 * n();
        joint.alpha += 0.05f64.to_radians() * n();
        joint.beta += 0.05f64.to_radians() * n();
    }
    truth.base = Placement { xyz: Vector3::new(1500.0, -300.0, 200.0), rpy: Vector3::new(0.1, -0.05, 0.6) };
    let markers = [Vector3::new(52.0, 1.0, 148.0), Vector3::new(-38.0, 61.0, 121.0)];
    truth.tool = robocal::model::Tool::Point(markers[0]);
    let sigmas: Vec<f64> =
        [0.007, 0.007, 0.007, 0.002, 0.002, 0.002].iter().map(|d: &f64| d.to_radians()).collect();
    let mut poses = |n: usize| -> Vec<Vec<f64>> {
        (0..n)
            .map(|_| nominal.joints.iter().map(|j| rng.random_range(j.limits[0]..j.limits[1])).collect())
            .collect()
    };
    let (training, validation) = (poses(100), poses(50));
    std::fs::write("examples/puma560-true.toml", truth.to_toml_string())?;
    std::fs::write(
        "examples/puma560-measurements.csv",
        measurement_csv(&truth, &markers, &training, &sigmas, 0.01, 1),
    )?;
    std::fs::write(
        "examples/puma560-validation.csv",
        measurement_csv(&truth, &markers, &validation, &sigmas, 0.01, 2),
    )?;
    println!(
        "wrote examples/puma560-true.toml, examples/puma560-measurements.csv, examples/puma560-validation.csv"
    );
    Ok(())
}
