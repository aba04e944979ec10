//! Writes a large simulated calibration campaign for the calibration benchmarks
//! (`benches/calibrate-memory.sh`): `POSES` uniform poses of a PUMA 560 whose geometry is off
//! by a fixed pattern (1.5 m from the tracker, as in the README's example), `MARKERS` reflectors
//! on its last link (1 to 4), the paper's joint noise and 0.01 mm of measurement noise.
//!
//! Run: `cargo run --release --example make_campaign -- POSES MARKERS FILE`.

use nalgebra::Vector3;
use rand::rngs::ChaCha8Rng;
use rand::{RngExt, SeedableRng};
use robocal::model::{Placement, RobotModel};
use robocal::simulation::measurement_csv;

/// The true markers; the design positions given to `calibrate` are these rounded (the
/// script's `--marker` flags).
const MARKERS: [[f64; 3]; 4] =
    [[52.0, 1.0, 148.0], [-38.0, 61.0, 121.0], [1.0, -59.0, 91.0], [41.0, 42.0, 60.0]];

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let [poses, markers, path] = &args[..] else {
        return Err("usage: make_campaign POSES MARKERS FILE".into());
    };
    let (poses, markers): (usize, usize) = (poses.parse()?, markers.parse()?);
    if !(1..=MARKERS.len()).contains(&markers) {
        return Err(format!("MARKERS: 1 to {}, found {markers}", MARKERS.len()).into());
    }
    let nominal = RobotModel::preset("puma560").expect("the preset exists");
    let mut truth = nominal.clone();
    for (i, joint) in truth.joints.iter_mut().enumerate() {
        joint.theta += 1e-3 * (i as f64).sin();
        joint.a += 0.3 * (i as f64).cos();
    }
    truth.base = Placement { xyz: Vector3::new(1500.0, -300.0, 200.0), rpy: Vector3::new(0.1, -0.05, 0.6) };
    let markers: Vec<Vector3<f64>> = MARKERS[..markers].iter().map(|m| Vector3::from(*m)).collect();
    let mut rng = ChaCha8Rng::seed_from_u64(26);
    let poses: Vec<Vec<f64>> = (0..poses)
        .map(|_| nominal.joints.iter().map(|j| rng.random_range(j.limits[0]..j.limits[1])).collect())
        .collect();
    let sigmas: Vec<f64> =
        [0.007, 0.007, 0.007, 0.002, 0.002, 0.002].iter().map(|d: &f64| d.to_radians()).collect();
    std::fs::write(path, measurement_csv(&truth, &markers, &poses, &sigmas, 0.01, 3))?;
    Ok(())
}
