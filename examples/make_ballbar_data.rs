//! Writes the README's ball-bar example: the true PUMA 560 of `examples/puma560-true.toml`
//! (written by `make_puma560_data`) with a ball bar from a pivot 400, 200, 300 mm from its
//! base frame's origin to the ball at its reflector (52, 1, 148) mm in frame 6. Each row is the
//! bar's length at one pose, read with the paper's joint noise (0.007 deg joints 1-3, 0.002 deg
//! joints 4-6) and 0.005 mm on the length:
//!
//! - `examples/puma560-ballbar.csv`: 150 poses for calibration;
//! - `examples/puma560-ballbar-2.csv`: 60 other poses for validation.
//!
//! Run: `cargo run --release --example make_ballbar_data`.

use nalgebra::Point3;
use rand::rngs::ChaCha8Rng;
use rand::{RngExt, SeedableRng};
use rand_distr::{Distribution, StandardNormal};
use robocal::kinematics::Chain;
use robocal::model::RobotModel;
use std::fmt::Write;

fn main() -> std::io::Result<()> {
    let truth = RobotModel::from_toml_str(&std::fs::read_to_string("examples/puma560-true.toml")?)
        .expect("examples/puma560-true.toml is a model");
    let chain = Chain::new(&truth);
    let real = chain.with_errors(&vec![0.0; chain.params().len()]);
    let pivot = truth.base.isometry().transform_point(&Point3::new(400.0, 200.0, 300.0)).coords;
    let sigmas: Vec<f64> =
        [0.007, 0.007, 0.007, 0.002, 0.002, 0.002].iter().map(|d: &f64| d.to_radians()).collect();
    let mut rng = ChaCha8Rng::seed_from_u64(1982);
    let mut file = |n: usize| -> String {
        let mut text = String::from("# units: joints=deg, lengths=mm\nj1,j2,j3,j4,j5,j6,distance,sigma\n");
        for _ in 0..n {
            let q: Vec<f64> =
                truth.joints.iter().map(|j| rng.random_range(j.limits[0]..j.limits[1])).collect();
            let read: Vec<f64> = q
                .iter()
                .zip(&sigmas)
                .map(|(q, s)| {
                    let z: f64 = StandardNormal.sample(&mut rng);
                    q + s * z
                })
                .collect();
            let z: f64 = StandardNormal.sample(&mut rng);
            let length = (real.position(&read) - pivot).norm() + 0.005 * z;
            let degrees: Vec<String> = q.iter().map(|v| format!("{:.6}", v.to_degrees())).collect();
            let _ = writeln!(text, "{},{length:.4},0.005", degrees.join(","));
        }
        text
    };
    let (training, validation) = (file(150), file(60));
    std::fs::write("examples/puma560-ballbar.csv", training)?;
    std::fs::write("examples/puma560-ballbar-2.csv", validation)?;
    println!("wrote examples/puma560-ballbar.csv, examples/puma560-ballbar-2.csv");
    Ok(())
}
