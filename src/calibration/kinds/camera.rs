//! Camera targets: a camera's view of a calibration target, on the arm (hand-eye) or fixed in
//! the world (eye-to-hand).
//!
//! # The observation model
//!
//! The camera's frame `A` and the target's frame `B`, both in the base (measuring) frame, are
//! one of them mounted on the tool and the other placed in the world:
//!
//! - hand-eye ([`CameraSite::Hand`]): `A = T(q) C`, `B = W`, the camera mounting `C` in the tool
//!   frame `T(q)` ([`ChainAt::pose`](crate::kinematics::ChainAt::pose)) and the target's
//!   placement `W` in the base frame;
//! - eye-to-hand ([`CameraSite::World`]): `A = W`, `B = T(q) C`, the camera's placement `W` and
//!   the target mounting `C`.
//!
//! The camera measures the view `M = A^-1 B`: its position `t_M = R_A^T (p_B - p_A)` (mm) and
//! rotation `R_M = R_A^T R_B`, given as a rotation vector `m_r` (`R_m = exp([m_r]x)`). Its six
//! residuals are `y_t = m_t - t_M` and `y_r = log(R_m R_M^T)`, the rotation that takes the
//! predicted view to the measured one.
//!
//! Each placement is 6 set-up parameters `(x, y, z, rx, ry, rz)`: its position (mm) and the
//! rotation vector `r` of its rotation `exp([r]x)` (rad); the camera's are `camera.*`, the
//! target's `target.*` (the mounting is the camera's in hand-eye, the target's in eye-to-hand).
//!
//! # Derivatives
//!
//! A frame's error is its twist in the base frame, `(dp, omega)`: `p -> p + dp`,
//! `R -> exp([omega]x) R`. The view's error `(dt_M, delta)` (`R_M -> exp([delta]x) R_M`) is
//!
//! `dt_M = R_A^T (dp_B - dp_A + [p_B - p_A]x omega_A)`, `delta = R_A^T (omega_B - omega_A)`,
//!
//! and `y_r` moves by `-J_r^-1(y_r) delta`, `J_r^-1(y) = J_l(-y)^-1` with the left Jacobian of
//! SO(3) `J_l(v) = I + (1 - cos t)/t^2 [v]x + (t - sin t)/t^3 [v]x^2`, `t = |v|`. The twist of a
//! mounted frame `X = T C` is `(dp - [p_X - p_T]x omega, omega)` for the tool's error
//! `(dp, omega)`, and `(R_T dt, R_T J_l(r) dr)` for its mounting's `(dt, dr)`; a placed frame's
//! is `(dt, J_l(r) dr)`. So the camera's rows of `H` are exact derivatives at any residual.
//!
//! # The start
//!
//! With the nominal robot, every view gives `T_k C N_k^-1 = W`, `N_k = M_k^-1` (hand-eye) or
//! `M_k` (eye-to-hand). Two views `i, j` give `A_ij C = C B_ij`, `A_ij = T_j^-1 T_i`,
//! `B_ij = N_j^-1 N_i` (the hand-eye equation `AX = XB`). Its rotation part says
//! `log(R_A) = R_C log(R_B)`: `R_C` is the rotation that best turns every `log(R_B)` into its
//! `log(R_A)` (Kabsch, by SVD); then `(R_A - I) t_C = R_C t_B - t_A`, stacked, in least squares
//! (Park and Martin, 1994). `W` is then the chordal mean of every `T_k C N_k^-1` (the mean
//! rotation matrix projected on SO(3) by SVD, the mean position). Pairs are every view with the
//! next 30. The robot's motions must turn about two axes at least, else `C` is not determined.
//!
//! # What it cannot see
//!
//! Only `A^-1 B` is seen: a rigid motion of the base with the world's placement leaves every
//! view, so the base is held and the world placement absorbs it.

use crate::calibration::CalibrationError;
use nalgebra::{Isometry3, Matrix3, Matrix6, Rotation3, Translation3, UnitQuaternion, Vector3, Vector6};

/// Where the camera is: on the arm looking at a target fixed in the world (hand-eye), or fixed
/// in the world looking at a target on the arm (eye-to-hand), the two cases of a serial arm;
/// or, on a tree, between two of its cameras and targets, each fixed to a branch's tip or
/// placed in the root link's frame ([`Frame`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CameraSite {
    /// On the tool (`camera` mounted in the tool frame, `target` placed in the base frame).
    Hand,
    /// Fixed (`camera` placed in the base frame, `target` mounted in the tool frame).
    World,
    /// Between the frames of a tree: the camera's and the target's, their numbers among the
    /// set-up's ([`SetUp::with_views`](super::SetUp::with_views)).
    Tree {
        /// The camera's frame.
        camera: u16,
        /// The target's frame.
        target: u16,
    },
}

impl CameraSite {
    /// `hand`, `world` or `tree`.
    pub fn name(self) -> &'static str {
        match self {
            Self::Hand => "hand",
            Self::World => "world",
            Self::Tree { .. } => "tree",
        }
    }

    /// The camera's and the target's frames ([`Frame`]) of a serial arm's camera (its tool is
    /// branch 0), the set-up's first two; a tree's view's are the set-up's `Tree` names.
    pub fn serial_frames(self) -> [Frame; 2] {
        let (camera, target) = match self {
            Self::Hand => (Some(0), None),
            _ => (None, Some(0)),
        };
        [Frame { role: Role::Camera, on: camera }, Frame { role: Role::Target, on: target }]
    }
}

/// What a [`Frame`] is: a camera or a target.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Role {
    /// A camera.
    Camera,
    /// A target it sees.
    Target,
}

/// A camera or a target, fixed to a branch's tip link (a serial arm's tool: branch 0) or placed
/// in the base (root link's) frame: 6 set-up parameters, its placement `(x, y, z, rx, ry, rz)`
/// (mm, rotation vector rad) in that frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Frame {
    /// A camera or a target.
    pub role: Role,
    /// The branch whose tip it is fixed to; `None`: fixed in the root link's frame.
    pub on: Option<usize>,
}

impl Frame {
    /// `camera.<tip>` or `target.<tip>` (`world` for the root link's frame), `tips` the
    /// branches' tip links; `camera` or `target` without tips (a serial arm's).
    pub fn name(&self, tips: &[String]) -> String {
        let role = match self.role {
            Role::Camera => "camera",
            Role::Target => "target",
        };
        match tips.is_empty() {
            true => role.to_string(),
            false => format!("{role}.{}", self.on.map_or("world", |b| tips[b].as_str())),
        }
    }
}

/// The frame of a placement `(x, y, z, rx, ry, rz)`: position (mm), rotation vector (rad).
pub fn isometry(v: &[f64]) -> Isometry3<f64> {
    Isometry3::from_parts(
        Translation3::new(v[0], v[1], v[2]),
        UnitQuaternion::from_scaled_axis(Vector3::new(v[3], v[4], v[5])),
    )
}

/// The placement `(x, y, z, rx, ry, rz)` of a frame, the inverse of [`isometry`].
pub fn placement(f: &Isometry3<f64>) -> Vector6<f64> {
    let (t, r) = (f.translation.vector, f.rotation.scaled_axis());
    Vector6::new(t.x, t.y, t.z, r.x, r.y, r.z)
}

/// The left Jacobian of SO(3): `J_l(v) = I + (1 - cos t)/t^2 [v]x + (t - sin t)/t^3 [v]x^2`,
/// `t = |v|`, with `exp([v + dv]x) = exp([J_l(v) dv]x) exp([v]x)` to first order.
pub fn left_jacobian(v: &Vector3<f64>) -> Matrix3<f64> {
    let t = v.norm();
    let k = v.cross_matrix();
    let (a, b) = if t < 1e-6 {
        (0.5 - t * t / 24.0, 1.0 / 6.0 - t * t / 120.0)
    } else {
        ((1.0 - t.cos()) / (t * t), (t - t.sin()) / (t * t * t))
    };
    Matrix3::identity() + k * a + k * k * b
}

/// The view `M = A^-1 B` of the target's frame `B` from the camera's frame `A` against the
/// measured one: its six residuals `y = (m_t - t_M, log(R_m R_M^T))` and `S_A`, `S_B`, the
/// derivatives `-dy` with respect to the twists `(dp, omega)` of `A` and of `B` (base frame):
///
/// `S_A = [-R_A^T, R_A^T [p_B - p_A]x; 0, -J_r^-1(y_r) R_A^T]`,
/// `S_B = [R_A^T, 0; 0, J_r^-1(y_r) R_A^T]`.
#[derive(Debug, Clone, Copy)]
pub struct RelativeView {
    /// The residuals: position (mm), rotation vector (rad).
    pub residual: Vector6<f64>,
    /// `-dy / d(twist of A)`.
    pub by_a: Matrix6<f64>,
    /// `-dy / d(twist of B)`.
    pub by_b: Matrix6<f64>,
}

/// The [`RelativeView`] of the measured view `view` (position mm, rotation vector rad) between
/// the frames `a` (the camera's) and `b` (the target's).
pub fn relative_view(view: &Vector6<f64>, a: &Isometry3<f64>, b: &Isometry3<f64>) -> RelativeView {
    let m = a.inverse() * b;
    let measured = isometry(view.as_slice());
    let y_t = measured.translation.vector - m.translation.vector;
    let y_r = (measured.rotation * m.rotation.inverse()).scaled_axis();
    let r_a_t = a.rotation.to_rotation_matrix().into_inner().transpose();
    let jr_inv = left_jacobian(&-y_r).try_inverse().unwrap_or_else(Matrix3::zeros);
    let d = b.translation.vector - a.translation.vector;
    let mut by_a = Matrix6::zeros();
    by_a.fixed_view_mut::<3, 3>(0, 0).copy_from(&-r_a_t);
    by_a.fixed_view_mut::<3, 3>(0, 3).copy_from(&(r_a_t * d.cross_matrix()));
    by_a.fixed_view_mut::<3, 3>(3, 3).copy_from(&(-jr_inv * r_a_t));
    let mut by_b = Matrix6::zeros();
    by_b.fixed_view_mut::<3, 3>(0, 0).copy_from(&r_a_t);
    by_b.fixed_view_mut::<3, 3>(3, 3).copy_from(&(jr_inv * r_a_t));
    RelativeView { residual: Vector6::new(y_t.x, y_t.y, y_t.z, y_r.x, y_r.y, y_r.z), by_a, by_b }
}

/// A frame mounted on a tool, `X = T C` (`C` the mounting `(x, y, z, rx, ry, rz)`), and the
/// derivatives of its twist: `E_T = [I, -[p_X - p_T]x; 0, I]` by the tool's error `(dp, omega)`
/// and `E_C = [R_T, 0; 0, R_T J_l(r)]` by the mounting's `(dt, dr)`.
pub fn mounted(tool: &Isometry3<f64>, mounting: &[f64]) -> (Isometry3<f64>, Matrix6<f64>, Matrix6<f64>) {
    let frame = tool * isometry(mounting);
    let r_t = tool.rotation.to_rotation_matrix().into_inner();
    let arm = frame.translation.vector - tool.translation.vector;
    let mut by_tool = Matrix6::identity();
    by_tool.fixed_view_mut::<3, 3>(0, 3).copy_from(&-arm.cross_matrix());
    let mut by_mounting = Matrix6::zeros();
    by_mounting.fixed_view_mut::<3, 3>(0, 0).copy_from(&r_t);
    let j_mounting = left_jacobian(&Vector3::new(mounting[3], mounting[4], mounting[5]));
    by_mounting.fixed_view_mut::<3, 3>(3, 3).copy_from(&(r_t * j_mounting));
    (frame, by_tool, by_mounting)
}

/// A frame placed in the base frame, `W` of `(x, y, z, rx, ry, rz)`, and the derivative of
/// its twist by its placement: `E_W = [I, 0; 0, J_l(r)]`.
pub fn placed(world: &[f64]) -> (Isometry3<f64>, Matrix6<f64>) {
    let mut by_world = Matrix6::identity();
    let j_world = left_jacobian(&Vector3::new(world[3], world[4], world[5]));
    by_world.fixed_view_mut::<3, 3>(3, 3).copy_from(&j_world);
    (isometry(world), by_world)
}

/// One end of a view, the camera's or the target's frame `X`: mounted on a tip, `X = T C`
/// ([`mounted`]), or placed in the base frame, `X = W` ([`placed`]), its placement `own`
/// `(x, y, z, rx, ry, rz)`; with the derivatives of its twist by the tip's error (`E_T`, if
/// on a tip) and by its own 6 parameters (`E_C` or `E_W`).
pub fn view_end(
    tip: Option<&Isometry3<f64>>,
    own: &[f64],
) -> (Isometry3<f64>, Option<Matrix6<f64>>, Matrix6<f64>) {
    match tip {
        Some(tip) => {
            let (frame, by_tip, by_own) = mounted(tip, own);
            (frame, Some(by_tip), by_own)
        }
        None => {
            let (frame, by_own) = placed(own);
            (frame, None, by_own)
        }
    }
}

/// The camera's and the target's placements `(camera, target)` that best explain the views
/// `(T_k, M_k)` (the tool frame on the nominal robot, the view), by the [module](self)'s
/// closed form: hand-eye at [`CameraSite::Hand`], else eye-to-hand.
pub fn camera_start(
    views: &[(Isometry3<f64>, Isometry3<f64>)],
    site: CameraSite,
) -> Result<(Isometry3<f64>, Isometry3<f64>), CalibrationError> {
    let too_few = |why: &str| {
        CalibrationError::Observations(format!(
            "camera: {} views, {why}: expected at least 3 poses turning the tool about two axes or more",
            views.len()
        ))
    };
    if views.len() < 3 {
        return Err(too_few("too few"));
    }
    // Hand-eye: the camera is the one on the tool.
    let hand = site == CameraSite::Hand;
    let n: Vec<Isometry3<f64>> = views.iter().map(|(_, m)| if hand { m.inverse() } else { *m }).collect();
    let pairs: Vec<(Isometry3<f64>, Isometry3<f64>)> = (0..views.len())
        .flat_map(|i| ((i + 1)..views.len().min(i + 31)).map(move |j| (i, j)))
        .map(|(i, j)| (views[j].0.inverse() * views[i].0, n[j].inverse() * n[i]))
        .collect();
    // Rotation: argmax sum alpha^T R beta, alpha = log(R_A), beta = log(R_B).
    let m: Matrix3<f64> =
        pairs.iter().map(|(a, b)| a.rotation.scaled_axis() * b.rotation.scaled_axis().transpose()).sum();
    let svd = m.svd(true, true);
    let s = svd.singular_values;
    let mut sorted = [s[0], s[1], s[2]];
    sorted.sort_by(|a, b| b.total_cmp(a));
    if sorted[1].is_nan() || sorted[1] <= 1e-6 * sorted[0] {
        return Err(too_few("the tool turns about one axis only"));
    }
    let rotation = nearest_rotation(&m);
    // Translation: (R_A - I) t = R t_B - t_A, in least squares by its normal equations.
    let (mut normal, mut right) = (Matrix3::zeros(), Vector3::zeros());
    for (a, b) in &pairs {
        let k = a.rotation.to_rotation_matrix().into_inner() - Matrix3::identity();
        normal += k.transpose() * k;
        right += k.transpose() * (rotation * b.translation.vector - a.translation.vector);
    }
    let t = normal.try_inverse().ok_or_else(|| too_few("the tool turns about one axis only"))? * right;
    let mounting = Isometry3::from_parts(
        Translation3::from(t),
        UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(rotation)),
    );
    // The world placement: the chordal mean of T_k C N_k^-1.
    let worlds: Vec<Isometry3<f64>> =
        views.iter().zip(&n).map(|((tk, _), nk)| tk * mounting * nk.inverse()).collect();
    let count = worlds.len() as f64;
    let position = worlds.iter().map(|w| w.translation.vector).sum::<Vector3<f64>>() / count;
    let mean: Matrix3<f64> = worlds.iter().map(|w| w.rotation.to_rotation_matrix().into_inner()).sum();
    let world = Isometry3::from_parts(
        Translation3::from(position),
        UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(nearest_rotation(&mean))),
    );
    Ok(if hand { (mounting, world) } else { (world, mounting) })
}

/// The rotation `R` maximising `trace(R^T m)`: `U diag(1, 1, det(U V^T)) V^T`, `m = U S V^T`.
fn nearest_rotation(m: &Matrix3<f64>) -> Matrix3<f64> {
    let svd = m.svd(true, true);
    let (u, v_t) = (svd.u.expect("asked for U"), svd.v_t.expect("asked for V"));
    let d = (u * v_t).determinant().signum();
    u * Matrix3::from_diagonal(&Vector3::new(1.0, 1.0, d)) * v_t
}
