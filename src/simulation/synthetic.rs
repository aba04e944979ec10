//! Synthetic measurement files: a known "true" robot measured with joint and device noise, for
//! testing a calibration end to end and for trying the workflow without a robot.

use super::normal;
use crate::kinematics::Chain;
use crate::model::{JointKind, RobotModel};
use nalgebra::Vector3;
use rand::SeedableRng;
use rand::rngs::ChaCha8Rng;
use std::fmt::Write;

/// A measurement file (the format of [`crate::calibration::Measurements`], degrees and mm) of
/// `truth` (its base is the measuring frame to the robot) carrying `markers` (mm, in its
/// [marker frame](crate::model::RobotModel::marker_frame)) at the commanded joint values `joints` (rad, mm). The robot reaches `q + n_q` with
/// `n_q` normal with `joint_sigmas`; each marker is measured with isotropic normal noise
/// `sigma_me` (mm). ChaCha8 with `seed`: the same file for the same arguments.
pub fn measurement_csv(
    truth: &RobotModel,
    markers: &[Vector3<f64>],
    joints: &[Vec<f64>],
    joint_sigmas: &[f64],
    sigma_me: f64,
    seed: u64,
) -> String {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let chains = Chain::markers(truth, markers);
    let zero = vec![0.0; chains[0].params().len()];
    let at: Vec<_> = chains.iter().map(|c| c.with_errors(&zero)).collect();
    let mut header: Vec<String> = truth.joints.iter().map(|j| j.name.clone()).collect();
    for k in 1..=markers.len() {
        header.extend([format!("x{k}"), format!("y{k}"), format!("z{k}")]);
    }
    let mut out = format!("# units: joints=deg, lengths=mm\n{}\n", header.join(","));
    for q in joints {
        let noisy: Vec<f64> = q.iter().zip(joint_sigmas).map(|(q, s)| q + s * normal(&mut rng)).collect();
        let mut row: Vec<String> = truth
            .joints
            .iter()
            .zip(q)
            .map(|(j, &v)| {
                if j.kind == JointKind::Revolute {
                    format!("{:.9}", v.to_degrees())
                } else {
                    format!("{v:.9}")
                }
            })
            .collect();
        for at in &at {
            let p = at.position(&noisy)
                + Vector3::new(normal(&mut rng), normal(&mut rng), normal(&mut rng)) * sigma_me;
            row.extend([format!("{:.6}", p.x), format!("{:.6}", p.y), format!("{:.6}", p.z)]);
        }
        let _ = writeln!(out, "{}", row.join(","));
    }
    out
}
