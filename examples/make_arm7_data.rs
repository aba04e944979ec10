//! Writes the development benchmark of real-robot accuracy (`examples/arm7/`): a 7-joint arm,
//! described by a URDF file with link masses, whose "true" robot has what real arms have and a
//! geometric model lacks, measured by motion capture as a real one would be.
//!
//! The true robot is the nominal one with
//! - geometric errors: every joint origin displaced (0.3 mm per axis, 0.03 deg per angle,
//!   standard deviations) and turned about its axis (offsets, 0.05 deg);
//! - joint deflection under gravity: joints 2, 4 and 6 turn by `c_j tau_j(q)` with
//!   `c = 4e-5, 6e-5, 1.5e-4 rad/(N·m)` and `tau_j` the gravity torque of the URDF's masses
//!   (`robocal::kinematics::ChainAt::gravity_torques`);
//! - play in joint 6: 0.03 deg with the sign of its gravity torque;
//! - three markers on the plate (the tip link) at (40.3, 0.4, 25.2), (-19.6, 35.3, 24.7),
//!   (-20.4, -34.8, 25.4) mm; their design positions, given to `calibrate` with `--marker`,
//!   are (40, 0, 25), (-20, 35, 25), (-20, -35, 25);
//! - the motion-capture frame at (1200, -400, 50) mm, turned (0.5, -1, 132) deg (roll, pitch,
//!   yaw) from the robot's base.
//!
//! Each marker is measured with 0.2 mm of isotropic noise; the joints are read exactly. The
//! training set has 37 poses with joints 1-4 within the central 60% of their range and the
//! wrist (joints 5-7) within the central 25%, so that the wrist's terms are weakly seen, as on
//! real data; three held-out sessions of 60 poses each draw 85% of their poses the same way
//! and 15% over the whole range, outside the training ranges (at least one joint outside its
//! band):
//!
//! - `examples/arm7/arm7.urdf`: the nominal robot (link masses in `<inertial>`);
//! - `examples/arm7/arm7-true.toml`: the true geometry (its base is the capture frame), with the
//!   deflection, play and markers above in its header;
//! - `examples/arm7/train.csv`, `session1.csv`, `session2.csv`, `session3.csv` (joints in rad,
//!   lengths in m, as capture systems write them).
//!
//! Run: `cargo run --release --example make_arm7_data`; `-- SEED DIR` draws another robot and
//! its measurements with `SEED` (default 7) into `DIR` (default `examples/arm7`), for the
//! spread of a result over robots.

use nalgebra::{Isometry3, UnitQuaternion, Vector3};
use rand::rngs::ChaCha8Rng;
use rand::{RngExt, SeedableRng};
use rand_distr::{Distribution, StandardNormal};
use robocal::kinematics::Chain;
use robocal::model::{Placement, RobotModel, from_urdf_str};
use std::fmt::Write;

/// The nominal arm: a 7-joint arm of a metre's reach with a marker plate on its flange.
const URDF: &str = include_str!("arm7/arm7.urdf");

/// Joint deflection per unit of gravity torque (rad per N·m), joint by joint.
const COMPLIANCE: [f64; 7] = [0.0, 4e-5, 0.0, 6e-5, 0.0, 1.5e-4, 0.0];
/// Play of joint 6 (deg), with the sign of its gravity torque.
const PLAY_DEG: f64 = 0.03;
/// Measurement noise of each marker coordinate (mm).
const SIGMA_MM: f64 = 0.2;

fn main() -> std::io::Result<()> {
    let mut args = std::env::args().skip(1);
    let seed: u64 = args.next().map_or(7, |s| s.parse().expect("SEED: a whole number"));
    let dir = args.next().unwrap_or_else(|| "examples/arm7".into());
    std::fs::create_dir_all(&dir)?;
    let nominal = from_urdf_str(URDF, "base", "plate").expect("the example URDF is valid");
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let truth = true_robot(&nominal, &mut rng);
    let markers =
        [Vector3::new(40.3, 0.4, 25.2), Vector3::new(-19.6, 35.3, 24.7), Vector3::new(-20.4, -34.8, 25.4)];

    let train = poses(&nominal, 37, 0.0, &mut rng);
    let mut files = vec![("train.csv".to_string(), measurements(&truth, &markers, &train, &mut rng))];
    for session in 1..=3 {
        let poses = poses(&nominal, 60, 0.15, &mut rng);
        files.push((format!("session{session}.csv"), measurements(&truth, &markers, &poses, &mut rng)));
    }
    let header = format!(
        "# The true robot of examples/make_arm7_data.rs: its geometry (base: the capture frame).\n\
         # Beyond it: joint deflection c_j tau_j(q), c = {COMPLIANCE:?} rad/(N m);\n\
         # play of joint 6: {PLAY_DEG} deg with the sign of its gravity torque;\n\
         # markers in the plate frame (mm): {markers:?}.\n"
    );
    std::fs::write(format!("{dir}/arm7-true.toml"), header + &truth.to_toml_string())?;
    for (name, text) in &files {
        std::fs::write(format!("{dir}/{name}"), text)?;
    }
    println!("wrote {dir}/arm7-true.toml and {} measurement files (seed {seed})", files.len());
    Ok(())
}

/// The nominal robot with random origin and offset errors, seen from the capture frame.
fn true_robot(nominal: &RobotModel, rng: &mut ChaCha8Rng) -> RobotModel {
    let mut n = || -> f64 { StandardNormal.sample(rng) };
    let mut truth = nominal.clone();
    truth.name = "arm7-true".into();
    for joint in &mut truth.joints {
        let displacement = Isometry3::translation(0.3 * n(), 0.3 * n(), 0.3 * n())
            * UnitQuaternion::from_scaled_axis(Vector3::new(n(), n(), n()) * 0.03f64.to_radians());
        let offset = Isometry3::rotation(joint.axis * 0.05f64.to_radians() * n());
        joint.origin = Placement::from_isometry(&(joint.origin.isometry() * displacement * offset));
    }
    truth.base = Placement {
        xyz: Vector3::new(1200.0, -400.0, 50.0),
        rpy: Vector3::new(0.5f64.to_radians(), -1f64.to_radians(), 132f64.to_radians()),
    };
    truth
}

/// The share of each joint's range, about its middle, that the training poses cover: the
/// wrist (joints 5 to 7) moves little while the arm is measured, as on real data.
const BAND: [f64; 7] = [0.6, 0.6, 0.6, 0.6, 0.25, 0.25, 0.25];

/// Joint `j`'s [`BAND`] within its `limits`.
fn band(j: usize, limits: [f64; 2]) -> [f64; 2] {
    let margin = (1.0 - BAND[j]) / 2.0 * (limits[1] - limits[0]);
    [limits[0] + margin, limits[1] - margin]
}

/// `count` poses: each joint uniform within its [`BAND`], except a share `outside` of the
/// poses, drawn over the whole range until a joint leaves its band.
fn poses(model: &RobotModel, count: usize, outside: f64, rng: &mut ChaCha8Rng) -> Vec<Vec<f64>> {
    let outside_count = (outside * count as f64).round() as usize;
    let draw = |wide: bool, rng: &mut ChaCha8Rng| -> Vec<f64> {
        (model.joints.iter().enumerate())
            .map(|(i, j)| {
                let [low, high] = if wide { j.limits } else { band(i, j.limits) };
                rng.random_range(low..high)
            })
            .collect()
    };
    let in_bands = |q: &[f64]| {
        (model.joints.iter().enumerate().zip(q)).all(|((i, j), &v)| {
            let [low, high] = band(i, j.limits);
            (low..=high).contains(&v)
        })
    };
    (0..count)
        .map(|k| {
            let wide = k < outside_count;
            std::iter::repeat_with(|| draw(wide, rng))
                .find(|q| !wide || !in_bands(q))
                .expect("an endless draw")
        })
        .collect()
}

/// A measurement file (rad, m) of `truth` carrying `markers` at the commanded `joints`: the
/// joints deflect under gravity and play, the markers are measured with noise.
fn measurements(
    truth: &RobotModel,
    markers: &[Vector3<f64>],
    joints: &[Vec<f64>],
    rng: &mut ChaCha8Rng,
) -> String {
    let chains = Chain::markers(truth, markers);
    let at: Vec<_> = chains.iter().map(|c| c.with_errors(&vec![0.0; c.params().len()])).collect();
    let names: Vec<&str> = truth.joints.iter().map(|j| j.name.as_str()).collect();
    let mut out = format!("# units: joints=rad, lengths=m\n{}", names.join(","));
    for k in 1..=markers.len() {
        let _ = write!(out, ",x{k},y{k},z{k}");
    }
    out.push('\n');
    let mut tau = vec![0.0; truth.dof()];
    for q in joints {
        at[0].gravity_torques(q, &mut tau);
        let reached: Vec<f64> = (0..q.len())
            .map(|j| {
                let play = if j == 5 { PLAY_DEG.to_radians() * tau[j].signum() } else { 0.0 };
                q[j] + COMPLIANCE[j] * tau[j] + play
            })
            .collect();
        let mut row: Vec<String> = q.iter().map(|v| format!("{v:.9}")).collect();
        for chain in &at {
            let p = chain.position(&reached);
            for c in 0..3 {
                let z: f64 = StandardNormal.sample(rng);
                row.push(format!("{:.7}", (p[c] + SIGMA_MM * z) / 1000.0));
            }
        }
        out += &(row.join(",") + "\n");
    }
    out
}
