//! Simulated camera views of a tree (a head camera seeing both hands of a torso,
//! [`calibrate_tree`](crate::calibration::tree::calibrate_tree)): a true tree drawn about the
//! nominal one, its cameras' and targets' true placements, and their views at random
//! configurations with measurement noise.
//!
//! A true joint is the nominal one with its origin displaced: `xyz + n_t`, `rpy + n_r`, each
//! component of `n_t ~ N(0, sigma_mm^2)`, of `n_r ~ N(0, sigma_rad^2)`. A measured view is the
//! true one `M = A^-1 B` with `t_m = t_M + n_t` and `R_m = exp([n_r]x) R_M` (each component
//! normal with the view's sigma), so that its residual against the truth is `(n_t, n_r)`.
//! Views are drawn over the joints' whole ranges: whether the camera would see the target
//! (its field of view, occlusion) is not checked.

use super::Sight;
use crate::calibration::kinds::camera::isometry;
use crate::calibration::tree::{Frame, TreeData, View};
use crate::kinematics::Chain;
use crate::model::{Joint, RobotTree};
use nalgebra::{Isometry3, UnitQuaternion, Vector3, Vector6};
use rand::rngs::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};

/// `tree` with every joint's origin displaced by normal errors (mm, rad): a "real" tree.
pub fn perturbed_tree(tree: &RobotTree, sigma_mm: f64, sigma_rad: f64, rng: &mut ChaCha8Rng) -> RobotTree {
    let mut normal = |sigma: f64| -> f64 {
        let z: f64 = StandardNormal.sample(rng);
        sigma * z
    };
    let joints: Vec<Joint> = (tree.joints.iter())
        .map(|j| {
            let mut j = j.clone();
            j.origin.xyz += Vector3::new(normal(sigma_mm), normal(sigma_mm), normal(sigma_mm));
            j.origin.rpy += Vector3::new(normal(sigma_rad), normal(sigma_rad), normal(sigma_rad));
            j
        })
        .collect();
    tree.with_joints(joints)
}

/// The frame of branch `b`'s tip link at the tree's joint values `q`, on `tree`'s nominal
/// geometry.
pub fn tip(tree: &RobotTree, b: usize, q: &[f64]) -> Isometry3<f64> {
    let model = &tree.branches[b].model;
    let chain = Chain::new(model);
    chain.with_errors(&vec![0.0; chain.params().len()]).pose(&tree.branches[b].values(q))
}

/// The frame `frame`, placed at `placement` (`x, y, z, rx, ry, rz`: mm, rotation vector rad,
/// in its tip link's frame or the root link's), at the joint values `q` of `tree`.
pub fn frame_at(tree: &RobotTree, frame: &Frame, placement: &[f64], q: &[f64]) -> Isometry3<f64> {
    let own = isometry(placement);
    match frame.on {
        Some(b) => tip(tree, b, q) * own,
        None => own,
    }
}

/// The views of `pairs` (camera, target: indices into `frames`) at each of `configurations`
/// of the true tree `truth`, `frames[f]` at `placements[6f..6f + 6]`, with noise of `sigma`
/// (mm, rad; zero for exact views): one pose per configuration, one view per pair, lines
/// counted from 2 as in a file with a header.
pub fn simulate_views(
    truth: &RobotTree,
    frames: &[Frame],
    placements: &[f64],
    pairs: &[(usize, usize)],
    configurations: &[Vec<f64>],
    sigma: [f64; 2],
    rng: &mut ChaCha8Rng,
) -> TreeData {
    let mut data = TreeData { frames: frames.to_vec(), ..TreeData::default() };
    for (pose, q) in configurations.iter().enumerate() {
        data.joints.push(q.clone());
        for &(camera, target) in pairs {
            let a = frame_at(truth, &frames[camera], &placements[6 * camera..6 * camera + 6], q);
            let b = frame_at(truth, &frames[target], &placements[6 * target..6 * target + 6], q);
            let m = a.inverse() * b;
            let mut normal = |s: f64| -> f64 {
                let z: f64 = StandardNormal.sample(rng);
                s * z
            };
            let t = m.translation.vector + Vector3::new(normal(sigma[0]), normal(sigma[0]), normal(sigma[0]));
            let n_r = Vector3::new(normal(sigma[1]), normal(sigma[1]), normal(sigma[1]));
            let r = (UnitQuaternion::from_scaled_axis(n_r) * m.rotation).scaled_axis();
            data.lines.push(data.views.len() + 2);
            data.views.push(View {
                pose,
                camera,
                target,
                view: Vector6::new(t.x, t.y, t.z, r.x, r.y, r.z),
                sigma: [sigma[0].max(1e-6), sigma[1].max(1e-9)],
            });
        }
    }
    data
}

/// `data` as a view file of `tree` (see `docs/formats.md`): joints in degrees (mm for
/// prismatic ones), lengths in mm, each view's sigmas in `sigma` and `sigma_angle` columns.
pub fn views_csv(tree: &RobotTree, data: &TreeData) -> String {
    use std::fmt::Write;
    let tips: Vec<String> = tree.branches.iter().map(|b| b.tip.clone()).collect();
    let names: Vec<&str> = tree.joints.iter().map(|j| j.name.as_str()).collect();
    let angles = if data.position_only { "" } else { ",roll,pitch,yaw" };
    let sigma_angle = if data.position_only { "" } else { ",sigma_angle" };
    let mut out = format!(
        "# units: joints=deg, lengths=mm\ncamera,target,{},x,y,z{angles},sigma{sigma_angle}\n",
        names.join(",")
    );
    let on = |f: usize| data.frames[f].on.map_or("world", |b| tips[b].as_str());
    for view in &data.views {
        let q: Vec<String> = (tree.joints.iter().zip(&data.joints[view.pose]))
            .map(|(j, v)| match j.kind {
                crate::model::JointKind::Revolute => format!("{:.6}", v.to_degrees()),
                crate::model::JointKind::Prismatic => format!("{v:.6}"),
            })
            .collect();
        let v = view.view;
        let _ = write!(
            out,
            "{},{},{},{:.6},{:.6},{:.6}",
            on(view.camera),
            on(view.target),
            q.join(","),
            v[0],
            v[1],
            v[2]
        );
        if data.position_only {
            let _ = writeln!(out, ",{}", view.sigma[0]);
        } else {
            let (roll, pitch, yaw) =
                UnitQuaternion::from_scaled_axis(Vector3::new(v[3], v[4], v[5])).euler_angles();
            let _ = writeln!(
                out,
                ",{:.8},{:.8},{:.8},{},{}",
                roll.to_degrees(),
                pitch.to_degrees(),
                yaw.to_degrees(),
                view.sigma[0],
                view.sigma[1].to_degrees()
            );
        }
    }
    out
}

/// `n` configurations of `truth` drawn uniformly within its joint limits at which the camera
/// `frames[camera]` sees the target `frames[target]` (`frames[f]` at `placements[6f..6f + 6]`)
/// by `sight`: each drawn again until it does, at most
/// [`MOST_DRAWS_PER_VIEW`](super::MOST_DRAWS_PER_VIEW) times; `None` if one never does.
pub fn seen_configurations(
    truth: &RobotTree,
    frames: &[Frame],
    placements: &[f64],
    (camera, target): (usize, usize),
    sight: &Sight,
    n: usize,
    rng: &mut ChaCha8Rng,
) -> Option<Vec<Vec<f64>>> {
    let at = |f: usize, q: &[f64]| frame_at(truth, &frames[f], &placements[6 * f..6 * f + 6], q);
    (0..n)
        .map(|_| {
            (0..super::MOST_DRAWS_PER_VIEW)
                .map(|_| truth.uniform_configurations(1, rng).remove(0))
                .find(|q| sight.sees(&(at(camera, q).inverse() * at(target, q))))
        })
        .collect()
}

/// The torso's camera set-up (`presets/torso.urdf`): the camera fixed 10 mm off the
/// `head_camera` link, looking along the link's x (forward) and 20 deg down, and a target
/// 40 mm past each hand (`l_hand`, `r_hand`), turned; their placements `(x, y, z, rx, ry,
/// rz)` (mm, rotation vector rad), 6 per frame. The pairs it views are `(0, 1)` and `(0, 2)`.
pub fn head_camera_and_hands(tree: &RobotTree) -> ([Frame; 3], [f64; 18]) {
    use crate::calibration::tree::Role;
    let on = |tip: &str| tree.branch(tip);
    let frames = [
        Frame { role: Role::Camera, on: on("head_camera") },
        Frame { role: Role::Target, on: on("l_hand") },
        Frame { role: Role::Target, on: on("r_hand") },
    ];
    #[rustfmt::skip]
    let placements = [
        10.0, -5.0, 8.0, 0.05, 110f64.to_radians(), 0.02,
        3.0, 5.0, -40.0, 0.2, -0.1, 0.3,
        -2.0, 4.0, -35.0, -0.15, 0.1, -0.2,
    ];
    (frames, placements)
}
