//! Writes the README's hand-eye camera example: the true PUMA 560 of
//! `examples/puma560-true.toml` (written by `make_puma560_data`) carrying a camera on its
//! flange, mounted at (30, -20, 60) mm turned by the rotation vector (0.1, -0.2, 0.3) rad in
//! the flange's frame (frame 6), looking at a checkerboard placed at (700, 100, -300) mm, turned
//! by (0.2, 1.4, -0.1) rad, in the robot's base frame (as the ball bar's pivot). Each row is the board's pose in the
//! camera's frame (position mm; roll, pitch, yaw deg), from joints read with the paper's joint
//! noise (0.007 deg joints 1-3, 0.002 deg joints 4-6) and a pose estimate with 0.5 mm and
//! 0.1 deg of noise per axis (the camera rows' default sigmas). The poses are drawn over the
//! joints' whole ranges: the example tests the algebra, not whether the board is in view.
//!
//! - `examples/puma560-camera.csv`: 60 views for calibration;
//! - `examples/puma560-camera-2.csv`: 30 other views for validation.
//!
//! Run: `cargo run --release --example make_camera_data`.

use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
use rand::rngs::ChaCha8Rng;
use rand::{RngExt, SeedableRng};
use rand_distr::{Distribution, StandardNormal};
use robocal::kinematics::Chain;
use robocal::model::{Placement, RobotModel};
use std::fmt::Write;

/// The frame at `xyz` (mm) turned by the rotation vector `r` (rad).
fn placed(xyz: [f64; 3], r: [f64; 3]) -> Isometry3<f64> {
    Isometry3::from_parts(
        Translation3::new(xyz[0], xyz[1], xyz[2]),
        UnitQuaternion::from_scaled_axis(Vector3::from(r)),
    )
}

fn main() -> std::io::Result<()> {
    let truth = RobotModel::from_toml_str(&std::fs::read_to_string("examples/puma560-true.toml")?)
        .expect("examples/puma560-true.toml is a model");
    let chain = Chain::probe(&truth, &Placement { xyz: Vector3::zeros(), rpy: Vector3::zeros() });
    let real = chain.with_errors(&vec![0.0; chain.params().len()]);
    let camera = placed([30.0, -20.0, 60.0], [0.1, -0.2, 0.3]);
    let board = truth.base.isometry() * placed([700.0, 100.0, -300.0], [0.2, 1.4, -0.1]);
    let sigmas: Vec<f64> =
        [0.007, 0.007, 0.007, 0.002, 0.002, 0.002].iter().map(|d: &f64| d.to_radians()).collect();
    let mut rng = ChaCha8Rng::seed_from_u64(1994);
    let mut file = |n: usize| -> String {
        let mut text =
            String::from("# units: joints=deg, lengths=mm\nj1,j2,j3,j4,j5,j6,camera,x,y,z,roll,pitch,yaw\n");
        for _ in 0..n {
            let q: Vec<f64> =
                truth.joints.iter().map(|j| rng.random_range(j.limits[0]..j.limits[1])).collect();
            let mut normal = || -> f64 { StandardNormal.sample(&mut rng) };
            let read: Vec<f64> = q.iter().zip(&sigmas).map(|(q, s)| q + s * normal()).collect();
            let view = (real.pose(&read) * camera).inverse() * board;
            let z = Vector3::new(normal(), normal(), normal());
            let t = view.translation.vector + z * 0.5;
            let z = Vector3::new(normal(), normal(), normal());
            let r = UnitQuaternion::from_scaled_axis(z * 0.1f64.to_radians()) * view.rotation;
            let (roll, pitch, yaw) = r.euler_angles();
            let degrees: Vec<String> = q.iter().map(|v| format!("{:.6}", v.to_degrees())).collect();
            let angles = [roll, pitch, yaw].map(|a| format!("{:.5}", a.to_degrees()));
            let _ = writeln!(
                text,
                "{},hand,{:.4},{:.4},{:.4},{}",
                degrees.join(","),
                t.x,
                t.y,
                t.z,
                angles.join(",")
            );
        }
        text
    };
    let (training, validation) = (file(60), file(30));
    std::fs::write("examples/puma560-camera.csv", training)?;
    std::fs::write("examples/puma560-camera-2.csv", validation)?;
    println!("wrote examples/puma560-camera.csv, examples/puma560-camera-2.csv");
    Ok(())
}
