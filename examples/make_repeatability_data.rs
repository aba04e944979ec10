//! Writes the example repeatability study of the README: the example's true PUMA 560
//! (`examples/puma560-true.toml`, written by `make_puma560_data`) sent 10 times to each of 20
//! poses, reflector 1 measured by the tracker each time, with the paper's joint noise
//! (0.007 deg joints 1-3, 0.002 deg joints 4-6) and 0.01 mm of measurement noise:
//! `examples/puma560-repeatability.csv`.
//!
//! Run: `cargo run --release --example make_repeatability_data`.

use rand::rngs::ChaCha8Rng;
use rand::{RngExt, SeedableRng};
use rand_distr::{Distribution, StandardNormal};
use robocal::kinematics::Chain;
use robocal::model::RobotModel;
use std::fmt::Write;

fn main() -> std::io::Result<()> {
    let truth = RobotModel::from_toml_str(&std::fs::read_to_string("examples/puma560-true.toml")?)
        .expect("the example's true robot");
    let chain = Chain::new(&truth);
    let at = chain.with_errors(&vec![0.0; chain.params().len()]);
    let sigmas: Vec<f64> =
        [0.007, 0.007, 0.007, 0.002, 0.002, 0.002].iter().map(|d: &f64| d.to_radians()).collect();
    let mut rng = ChaCha8Rng::seed_from_u64(6);
    let mut out = String::from("# units: joints=deg, lengths=mm\npose,j1,j2,j3,j4,j5,j6,x1,y1,z1\n");
    for k in 1..=20 {
        let q: Vec<f64> = truth.joints.iter().map(|j| rng.random_range(j.limits[0]..j.limits[1])).collect();
        for _ in 0..10 {
            let mut n = || -> f64 { StandardNormal.sample(&mut rng) };
            let noisy: Vec<f64> = q.iter().zip(&sigmas).map(|(q, s)| q + s * n()).collect();
            let p = at.position(&noisy);
            let joints: Vec<String> = q.iter().map(|v| format!("{:.6}", v.to_degrees())).collect();
            let (x, y, z) = (p.x + 0.01 * n(), p.y + 0.01 * n(), p.z + 0.01 * n());
            let _ = writeln!(out, "P{k},{},{x:.4},{y:.4},{z:.4}", joints.join(","));
        }
    }
    std::fs::write("examples/puma560-repeatability.csv", out)?;
    println!("wrote examples/puma560-repeatability.csv");
    Ok(())
}
