//! Forward kinematics, the manipulator Jacobian and the identification Jacobian.
//!
//! A [`Chain`] is the model compiled into a list of elementary motions, each a rotation about
//! or a translation along one axis of the current frame, with value
//! `nominal + x[param] + q[joint]`. Every DH parameter, joint variable and base or tool
//! displacement is one such step. This gives both Jacobians in closed form, from the same
//! frames as the forward kinematics (the geometric Jacobian of Whitney 1972, applied to
//! parameters as by Wu 1984 and Hayati and Mirmirani 1985): a step along or about the
//! world-frame unit axis `u`, located at the point `o`, moves the end point `e` and frame by
//!
//! - rotation:    `de/dv = u x (e - o)`, `dω/dv = u`
//! - translation: `de/dv = u`,           `dω/dv = 0`
//!
//! where `ω` is the small rotation of the end frame in world coordinates (see [`pose_error`]).
//! Nothing here allocates: the Jacobians are written into views the caller owns.

use crate::model::{
    Convention, JointKind, ParamKind, ParamOwner, ParamSet, RobotModel, Selection, Tool,
};
use nalgebra::{
    DMatrixViewMut, Isometry3, Matrix3, Matrix6xX, Rotation3, Translation3, UnitQuaternion,
    Vector3, Vector6,
};

/// What a measurement observes at each point, and so how many rows it adds to y and H.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Measured {
    /// The tool point's position: 3 rows (x, y, z in mm).
    Position,
    /// The tool frame's pose: 6 rows (x, y, z in mm, then the rotation vector in rad).
    Pose,
}

impl Measured {
    /// Rows of y and H per measured point.
    pub fn rows(self) -> usize {
        match self {
            Self::Position => 3,
            Self::Pose => 6,
        }
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Motion {
    Rotate(usize),
    Translate(usize),
}

#[derive(Debug, Clone, Copy)]
struct Step {
    motion: Motion,
    nominal: f64,
    joint: Option<usize>,
    param: Option<usize>,
}

/// A frame during the walk along the chain: rotation columns are the frame's axes.
#[derive(Clone, Copy)]
struct Frame {
    r: Matrix3<f64>,
    p: Vector3<f64>,
}

impl Frame {
    fn apply(&mut self, motion: Motion, v: f64) {
        if v == 0.0 {
            return;
        }
        match motion {
            Motion::Translate(k) => self.p += self.r.column(k) * v,
            Motion::Rotate(k) => {
                // Post-multiplying by a rotation about axis k mixes the other two columns.
                let (i, j) = ((k + 1) % 3, (k + 2) % 3);
                let (s, c) = v.sin_cos();
                let (ci, cj) = (self.r.column(i).into_owned(), self.r.column(j).into_owned());
                self.r.set_column(i, &(ci * c + cj * s));
                self.r.set_column(j, &(cj * c - ci * s));
            }
        }
    }

    /// Linear and angular velocity of the end point `e` per unit of `motion`.
    fn screw(&self, motion: Motion, e: &Vector3<f64>) -> (Vector3<f64>, Vector3<f64>) {
        match motion {
            Motion::Translate(k) => (self.r.column(k).into_owned(), Vector3::zeros()),
            Motion::Rotate(k) => {
                let u = self.r.column(k).into_owned();
                (u.cross(&(e - self.p)), u)
            }
        }
    }
}

/// A robot model compiled for fast kinematics; see the [module documentation](self).
#[derive(Debug, Clone)]
pub struct Chain {
    steps: Vec<Step>,
    params: ParamSet,
    dof: usize,
}

impl Chain {
    /// Compile `model`.
    pub fn new(model: &RobotModel) -> Self {
        let params = model.params();
        let mut steps = Vec::new();
        let mut push = |motion, nominal, joint, param: Option<(ParamOwner, ParamKind)>| {
            let param =
                param.map(|(owner, kind)| params.index_of(owner, kind).expect("ParamSet has it"));
            steps.push(Step {
                motion,
                nominal,
                joint,
                param,
            });
        };
        use Motion::{Rotate, Translate};
        let (x, y, z) = (0, 1, 2);

        let placement =
            |push: &mut dyn FnMut(Motion, f64, Option<usize>, Option<(ParamOwner, ParamKind)>),
             owner: ParamOwner,
             xyz: Vector3<f64>,
             rpy: Vector3<f64>,
             kinds: &[ParamKind]| {
                // Nominal: Trans(xyz) Rz(yaw) Ry(pitch) Rx(roll); then the error displacement.
                for (k, v) in [(x, xyz.x), (y, xyz.y), (z, xyz.z)] {
                    push(Translate(k), v, None, None);
                }
                for (k, v) in [(z, rpy.z), (y, rpy.y), (x, rpy.x)] {
                    push(Rotate(k), v, None, None);
                }
                for &kind in kinds {
                    let motion = match kind {
                        ParamKind::X => Translate(x),
                        ParamKind::Y => Translate(y),
                        ParamKind::Z => Translate(z),
                        ParamKind::Rx => Rotate(x),
                        ParamKind::Ry => Rotate(y),
                        _ => Rotate(z),
                    };
                    push(motion, 0.0, None, Some((owner, kind)));
                }
            };

        placement(
            &mut push,
            ParamOwner::Base,
            model.base.xyz,
            model.base.rpy,
            &ParamKind::PLACEMENT,
        );
        for (i, joint) in model.joints.iter().enumerate() {
            let owner = ParamOwner::Joint(i);
            let (on_theta, on_d) = match joint.kind {
                JointKind::Revolute => (Some(i), None),
                JointKind::Prismatic => (None, Some(i)),
            };
            let theta = (
                Rotate(z),
                joint.theta,
                on_theta,
                Some((owner, ParamKind::Theta)),
            );
            let d = (Translate(z), joint.d, on_d, Some((owner, ParamKind::D)));
            let a = (Translate(x), joint.a, None, Some((owner, ParamKind::A)));
            let alpha = (
                Rotate(x),
                joint.alpha,
                None,
                Some((owner, ParamKind::Alpha)),
            );
            let beta = (Rotate(y), joint.beta, None, Some((owner, ParamKind::Beta)));
            let order = match model.convention {
                Convention::StandardDh => [theta, d, a, alpha, beta],
                Convention::ModifiedDh => [alpha, a, beta, theta, d],
            };
            for (motion, nominal, joint, param) in order {
                push(motion, nominal, joint, param);
            }
        }
        match model.tool {
            Tool::Point(p) => placement(
                &mut push,
                ParamOwner::Tool,
                p,
                Vector3::zeros(),
                &ParamKind::PLACEMENT[..3],
            ),
            Tool::Frame(f) => placement(
                &mut push,
                ParamOwner::Tool,
                f.xyz,
                f.rpy,
                &ParamKind::PLACEMENT,
            ),
        }
        steps.retain(|s| s.nominal != 0.0 || s.joint.is_some() || s.param.is_some());
        Self {
            steps,
            params,
            dof: model.dof(),
        }
    }

    /// Number of joints.
    pub fn dof(&self) -> usize {
        self.dof
    }

    /// The model's error parameters; `x` vectors are indexed like this set.
    pub fn params(&self) -> &ParamSet {
        &self.params
    }

    /// Walk the chain at joint values `q` and parameter errors `x`, calling `visit` with each
    /// step and the frame it acts in; returns the end frame.
    fn walk(&self, q: &[f64], x: &[f64], mut visit: impl FnMut(&Step, &Frame)) -> Frame {
        assert_eq!(q.len(), self.dof, "q has one value per joint");
        assert_eq!(
            x.len(),
            self.params.len(),
            "x has one value per error parameter"
        );
        let mut frame = Frame {
            r: Matrix3::identity(),
            p: Vector3::zeros(),
        };
        for step in &self.steps {
            visit(step, &frame);
            let v =
                step.nominal + step.joint.map_or(0.0, |j| q[j]) + step.param.map_or(0.0, |i| x[i]);
            frame.apply(step.motion, v);
        }
        frame
    }

    /// Position of the tool point (mm) at joint values `q` (rad, or mm for prismatic joints)
    /// with parameter errors `x`.
    ///
    /// # Panics
    /// If `q` or `x` has the wrong length.
    pub fn position(&self, q: &[f64], x: &[f64]) -> Vector3<f64> {
        self.walk(q, x, |_, _| {}).p
    }

    /// Pose of the tool frame: `base * T_1(q_1) * ... * T_n(q_n) * tool`, with errors `x`.
    ///
    /// # Panics
    /// If `q` or `x` has the wrong length.
    pub fn pose(&self, q: &[f64], x: &[f64]) -> Isometry3<f64> {
        let end = self.walk(q, x, |_, _| {});
        let rotation =
            UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(end.r));
        Isometry3::from_parts(Translation3::from(end.p), rotation)
    }

    /// The manipulator Jacobian `J = d(pose)/dq` (6 x dof: linear rows in mm per joint unit,
    /// then angular rows in rad per joint unit), written into `out`; returns the tool position.
    ///
    /// # Panics
    /// If `q`, `x` or `out` has the wrong size.
    pub fn manipulator_jacobian(
        &self,
        q: &[f64],
        x: &[f64],
        out: &mut Matrix6xX<f64>,
    ) -> Vector3<f64> {
        assert_eq!(out.ncols(), self.dof, "J has one column per joint");
        let e = self.position(q, x);
        self.walk(q, x, |step, frame| {
            if let Some(j) = step.joint {
                let (linear, angular) = frame.screw(step.motion, &e);
                out.fixed_view_mut::<3, 1>(0, j).copy_from(&linear);
                out.fixed_view_mut::<3, 1>(3, j).copy_from(&angular);
            }
        });
        e
    }

    /// The identification Jacobian of one point, `H_k = d(pose)/dx` for the selected
    /// parameters (Wu 1984; the paper's Eq. 1), written into `out` (`measured.rows()` x
    /// `selection.len()`); returns the tool position.
    ///
    /// # Panics
    /// If `q`, `x` or `out` has the wrong size.
    pub fn identification_jacobian(
        &self,
        q: &[f64],
        x: &[f64],
        selection: &Selection,
        measured: Measured,
        mut out: DMatrixViewMut<'_, f64>,
    ) -> Vector3<f64> {
        assert_eq!(
            out.shape(),
            (measured.rows(), selection.len()),
            "H block is rows x selected"
        );
        let e = self.position(q, x);
        self.walk(q, x, |step, frame| {
            if let Some(column) = step.param.and_then(|i| selection.column(i)) {
                let (linear, angular) = frame.screw(step.motion, &e);
                out.fixed_view_mut::<3, 1>(0, column).copy_from(&linear);
                if measured == Measured::Pose {
                    out.fixed_view_mut::<3, 1>(3, column).copy_from(&angular);
                }
            }
        });
        e
    }
}

/// The error of `actual` relative to `nominal` as a 6-vector: position difference (mm), then
/// the rotation vector `ω` (rad, world frame) with `R_actual = exp([ω]x) R_nominal`. To first
/// order it equals `H dx` and `J dq`.
pub fn pose_error(actual: &Isometry3<f64>, nominal: &Isometry3<f64>) -> Vector6<f64> {
    let dp = actual.translation.vector - nominal.translation.vector;
    let omega = (actual.rotation * nominal.rotation.inverse()).scaled_axis();
    Vector6::new(dp.x, dp.y, dp.z, omega.x, omega.y, omega.z)
}
