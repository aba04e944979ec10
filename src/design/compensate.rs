//! Compensation ("filtering" a robot program): the joint values a controller that computes with
//! the nominal model must be sent so that the real robot, described by the calibrated model,
//! reaches each target.
//!
//! A target is either joint values taught or generated on the nominal model (the target is the
//! nominal pose there, and those joints are the seed) or a pose with the nominal joint solution
//! as the seed. Each is solved by damped least squares (Levenberg-Marquardt) on the calibrated
//! model's manipulator Jacobian from the seed, clamped to the joint limits:
//!
//! `dq = J^T (J J^T + mu I)^-1 e`, `e` the pose error (mm; orientation rows in rad times
//! [`CompensateOptions::orientation_scale_mm`]), `mu` divided by 10 after a step that lowers
//! `|e|` and multiplied by 10 after one that does not (the step is then not taken).
//!
//! Frames ([`TargetFrame`]): a calibrated model carries its base placement in the measuring
//! frame. By default pose targets, and the nominal poses of joint targets (the nominal model's
//! forward kinematics, its own base included), are in that frame. In the robot's base frame
//! ([`TargetFrame::Base`]) both models' bases are left out: targets are taken relative to the
//! robot's base as the calibrated base places it.

use crate::kinematics::{ChainAt, pose_error};
use crate::model::{Placement, RobotModel, Tool};
use crate::table::{DataError, Table, Units};
use nalgebra::{Isometry3, Matrix6, Matrix6xX, Translation3, UnitQuaternion, Vector3, Vector6};
use rayon::prelude::*;

/// The frame targets are given in; see the [module documentation](self).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum TargetFrame {
    /// The measuring (cell) frame the calibrated base is placed in.
    #[default]
    Measuring,
    /// The robot's base frame, as the calibrated base places it.
    Base,
}

/// How targets are solved.
#[derive(Debug, Clone, PartialEq)]
pub struct CompensateOptions {
    /// Reach the position only (a 5-DOF task: a drill, a glue nozzle), not the orientation.
    pub position_only: bool,
    /// The frame targets are given in.
    pub frame: TargetFrame,
    /// Iterations at most per target.
    pub max_iterations: usize,
    /// Position error (mm) below which a target is reached.
    pub tolerance_mm: f64,
    /// Orientation error (rad) below which a target is reached.
    pub tolerance_rad: f64,
    /// The length (mm) that weighs one radian of orientation error against position error.
    pub orientation_scale_mm: f64,
    /// A joint moving more than this from its seed (rad; mm for a prismatic joint) has changed
    /// branch: the solution is not the nominal configuration's.
    pub max_joint_change: f64,
}

impl Default for CompensateOptions {
    fn default() -> Self {
        Self {
            position_only: false,
            frame: TargetFrame::Measuring,
            max_iterations: 100,
            tolerance_mm: 1e-9,
            tolerance_rad: 1e-11,
            orientation_scale_mm: 1000.0,
            max_joint_change: 10f64.to_radians(),
        }
    }
}

/// One target of a program.
#[derive(Debug, Clone, PartialEq)]
pub enum Target {
    /// Joint values (rad, mm) on the nominal model: the target is the nominal pose there.
    Joints(Vec<f64>),
    /// A pose (mm) and the nominal joint solution (rad, mm) as the seed.
    Pose {
        /// The tool pose to reach.
        pose: Isometry3<f64>,
        /// The nominal joint solution, where the solve starts.
        seed: Vec<f64>,
    },
}

impl Target {
    /// The seed joint values.
    pub fn seed(&self) -> &[f64] {
        match self {
            Self::Joints(q) => q,
            Self::Pose { seed, .. } => seed,
        }
    }
}

/// A target reached.
#[derive(Debug, Clone, PartialEq)]
pub struct Compensated {
    /// The joint values to send (rad, mm).
    pub joints: Vec<f64>,
    /// Their change from the seed (rad, mm).
    pub change: Vec<f64>,
    /// Iterations taken.
    pub iterations: usize,
    /// Remaining position error of the calibrated model (mm).
    pub error_mm: f64,
    /// Remaining orientation error (rad); 0 with [`CompensateOptions::position_only`].
    pub error_rad: f64,
    /// The calibrated model's position error at the seed, uncompensated (mm).
    pub before_mm: f64,
    /// Its orientation error at the seed (rad).
    pub before_rad: f64,
}

/// Why a target cannot be reached.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum Unreachable {
    /// The seed's joints lie outside their limits.
    #[error("the seed lies outside the limits of {}", .joints.join(", "))]
    SeedOutsideLimits {
        /// The joints outside their limits.
        joints: Vec<String>,
    },
    /// The solution would leave the joint limits: these joints stop at a limit.
    #[error("beyond the joint limits: {} at a limit, {error_mm:.4} mm and {:.4} deg remain", .joints.join(", "), .error_rad.to_degrees())]
    Limits {
        /// The joints held at a limit.
        joints: Vec<String>,
        /// The position error left (mm).
        error_mm: f64,
        /// The orientation error left (rad).
        error_rad: f64,
    },
    /// The arm is at or near a singularity: the Jacobian's smallest singular value is this
    /// fraction of its largest.
    #[error("singular (Jacobian condition {condition:.3e}): {error_mm:.4} mm and {:.4} deg remain", .error_rad.to_degrees())]
    Singular {
        /// Smallest over largest singular value of the weighted Jacobian.
        condition: f64,
        /// The position error left (mm).
        error_mm: f64,
        /// The orientation error left (rad).
        error_rad: f64,
    },
    /// The solution left the seed's branch: a joint moved more than
    /// [`CompensateOptions::max_joint_change`].
    #[error("a branch change: {joint} moves {change:.3} ({unit}) from the seed")]
    BranchChange {
        /// The joint that moved most.
        joint: String,
        /// How far (deg; mm for a prismatic joint).
        change: f64,
        /// `deg` or `mm`.
        unit: &'static str,
    },
    /// The iterations ran out.
    #[error("no convergence in {iterations} iterations: {error_mm:.4} mm and {:.4} deg remain", .error_rad.to_degrees())]
    NotConverged {
        /// Iterations taken.
        iterations: usize,
        /// The position error left (mm).
        error_mm: f64,
        /// The orientation error left (rad).
        error_rad: f64,
    },
}

/// The nominal and calibrated models, compiled in the frame targets are given in.
#[derive(Debug, Clone)]
pub struct Compensator {
    nominal: ChainAt,
    calibrated: ChainAt,
    joints: Vec<crate::model::Joint>,
    options: CompensateOptions,
}

/// Why the two models cannot be used together.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error(
    "the calibrated model {calibrated} has {calibrated_dof} joints, the nominal {nominal} has {nominal_dof}"
)]
pub struct JointCountMismatch {
    /// The nominal model's name.
    pub nominal: String,
    /// Its joints.
    pub nominal_dof: usize,
    /// The calibrated model's name.
    pub calibrated: String,
    /// Its joints.
    pub calibrated_dof: usize,
}

fn at_nominal(model: &RobotModel, frame: TargetFrame) -> ChainAt {
    let mut model = model.clone();
    if frame == TargetFrame::Base {
        model.base = Placement::default();
    }
    let chain = crate::kinematics::Chain::new(&model);
    chain.with_errors(&vec![0.0; chain.params().len()])
}

impl Compensator {
    /// The compensator of `calibrated` (the real robot) for a controller computing with
    /// `nominal`; the joint limits are the calibrated model's.
    pub fn new(
        nominal: &RobotModel,
        calibrated: &RobotModel,
        options: &CompensateOptions,
    ) -> Result<Self, JointCountMismatch> {
        if nominal.dof() != calibrated.dof() {
            return Err(JointCountMismatch {
                nominal: nominal.name.clone(),
                nominal_dof: nominal.dof(),
                calibrated: calibrated.name.clone(),
                calibrated_dof: calibrated.dof(),
            });
        }
        Ok(Self {
            nominal: at_nominal(nominal, options.frame),
            calibrated: at_nominal(calibrated, options.frame),
            joints: calibrated.joints.clone(),
            options: options.clone(),
        })
    }

    /// The pose `target` asks for, in the targets' frame.
    pub fn target_pose(&self, target: &Target) -> Isometry3<f64> {
        match target {
            Target::Joints(q) => self.nominal.pose(q),
            Target::Pose { pose, .. } => *pose,
        }
    }

    /// The calibrated model's tool pose at `q`, in the targets' frame.
    pub fn reached(&self, q: &[f64]) -> Isometry3<f64> {
        self.calibrated.pose(q)
    }

    /// Every target, in order, on the threads of the current rayon pool (the same results on
    /// any number of threads).
    pub fn solve_all(&self, targets: &[Target]) -> Vec<Result<Compensated, Unreachable>> {
        targets.par_iter().map(|t| self.solve(t)).collect()
    }

    /// The weighted error `target - reached(q)`: position (mm), then orientation (rad, times the
    /// orientation scale; zero when only the position counts).
    fn error(&self, target: &Isometry3<f64>, q: &[f64]) -> Vector6<f64> {
        let mut e = pose_error(target, &self.calibrated.pose(q));
        if self.options.position_only {
            e.fixed_rows_mut::<3>(3).fill(0.0);
        } else {
            e.fixed_rows_mut::<3>(3).scale_mut(self.options.orientation_scale_mm);
        }
        e
    }

    /// (position error mm, orientation error rad) of a weighted error.
    fn split(&self, e: &Vector6<f64>) -> (f64, f64) {
        (e.fixed_rows::<3>(0).norm(), e.fixed_rows::<3>(3).norm() / self.options.orientation_scale_mm)
    }

    fn reached_target(&self, e: &Vector6<f64>) -> bool {
        let (mm, rad) = self.split(e);
        mm < self.options.tolerance_mm && rad < self.options.tolerance_rad
    }

    /// The weighted manipulator Jacobian at `q` into `j` (orientation rows scaled, or zero).
    fn jacobian(&self, q: &[f64], j: &mut Matrix6xX<f64>) {
        self.calibrated.manipulator_jacobian(q, j);
        let scale = if self.options.position_only { 0.0 } else { self.options.orientation_scale_mm };
        j.fixed_rows_mut::<3>(3).scale_mut(scale);
    }

    /// Solve one target; see the [module documentation](self).
    pub fn solve(&self, target: &Target) -> Result<Compensated, Unreachable> {
        let seed = target.seed();
        let outside = crate::model::outside_limits(&self.joints, seed);
        if !outside.is_empty() {
            return Err(Unreachable::SeedOutsideLimits {
                joints: outside.iter().map(|s| s.to_string()).collect(),
            });
        }
        let goal = self.target_pose(target);
        let (mut q, mut trial) = (seed.to_vec(), seed.to_vec());
        let mut e = self.error(&goal, &q);
        let (before_mm, before_rad) = self.split(&e);
        let mut j = Matrix6xX::zeros(q.len());
        let mut mu = 1e-6;
        let mut iterations = 0;
        while !self.reached_target(&e) && iterations < self.options.max_iterations {
            iterations += 1;
            self.jacobian(&q, &mut j);
            let mut a: Matrix6<f64> = &j * j.transpose() + Matrix6::identity() * mu;
            if self.options.position_only {
                a.fixed_view_mut::<3, 3>(3, 3).fill_with_identity();
            }
            let Some(y) = a.cholesky().map(|c| c.solve(&e)) else {
                mu *= 10.0;
                continue;
            };
            let dq = j.tr_mul(&y);
            for ((t, (q, dq)), joint) in trial.iter_mut().zip(q.iter().zip(dq.iter())).zip(&self.joints) {
                *t = (q + dq).clamp(joint.limits[0], joint.limits[1]);
            }
            let e_trial = self.error(&goal, &trial);
            if e_trial.norm() < e.norm() {
                q.copy_from_slice(&trial);
                e = e_trial;
                mu = (mu / 10.0).max(1e-12);
            } else {
                mu *= 10.0;
                if mu > 1e12 {
                    break;
                }
            }
        }
        let (error_mm, error_rad) = self.split(&e);
        if !self.reached_target(&e) {
            return Err(self.why_not(&q, &mut j, iterations, error_mm, error_rad));
        }
        let change: Vec<f64> = q.iter().zip(seed).map(|(q, s)| q - s).collect();
        self.same_branch(&change)?;
        Ok(Compensated { joints: q, change, iterations, error_mm, error_rad, before_mm, before_rad })
    }

    /// A branch change if a joint moved more than the options allow.
    fn same_branch(&self, change: &[f64]) -> Result<(), Unreachable> {
        let (i, most) = change
            .iter()
            .enumerate()
            .fold((0, 0.0f64), |(bi, b), (i, c)| if c.abs() > b { (i, c.abs()) } else { (bi, b) });
        if most <= self.options.max_joint_change {
            return Ok(());
        }
        let joint = &self.joints[i];
        let revolute = joint.kind == crate::model::JointKind::Revolute;
        Err(Unreachable::BranchChange {
            joint: joint.name.clone(),
            change: if revolute { most.to_degrees() } else { most },
            unit: if revolute { "deg" } else { "mm" },
        })
    }

    /// Why the solve stopped short at `q`: a joint at its limit, a singularity, or the
    /// iterations.
    fn why_not(
        &self,
        q: &[f64],
        j: &mut Matrix6xX<f64>,
        iterations: usize,
        error_mm: f64,
        error_rad: f64,
    ) -> Unreachable {
        let at_limit: Vec<String> = self
            .joints
            .iter()
            .zip(q)
            .filter(|(joint, q)| **q <= joint.limits[0] || **q >= joint.limits[1])
            .map(|(joint, _)| joint.name.clone())
            .collect();
        if !at_limit.is_empty() {
            return Unreachable::Limits { joints: at_limit, error_mm, error_rad };
        }
        self.jacobian(q, j);
        let rows = if self.options.position_only { 3 } else { 6 };
        let sv = j.rows(0, rows).into_owned().singular_values();
        let (max, min) = (sv.max(), sv.min());
        let condition = if max > 0.0 { min / max } else { 0.0 };
        if condition < 1e-6 {
            return Unreachable::Singular { condition, error_mm, error_rad };
        }
        Unreachable::NotConverged { iterations, error_mm, error_rad }
    }
}

/// `model` with `point` (mm, in the marker frame: a model file's `[[markers]]` position) as
/// its tool point in place of its own, to bring a marker to the targets: with a tool point,
/// `p_tool = point`; with a tool frame `T_tool`, the frame moved to `T_tool * point`, its
/// orientation kept.
pub fn with_tool_point(model: RobotModel, point: Vector3<f64>) -> RobotModel {
    let tool = match model.tool {
        Tool::Point(_) => Tool::Point(point),
        Tool::Frame(frame) => Tool::Frame(Placement {
            xyz: (frame.isometry() * nalgebra::Point3::from(point)).coords,
            rpy: frame.rpy,
        }),
    };
    RobotModel { tool, ..model }
}

/// One target of a target file, with its line.
#[derive(Debug, Clone, PartialEq)]
pub struct TargetRow {
    /// The line in the file (1-based).
    pub line: usize,
    /// The target.
    pub target: Target,
}

/// The pose columns of a target file.
pub const POSE_COLUMNS: [&str; 6] = ["x", "y", "z", "roll", "pitch", "yaw"];

/// The targets of a CSV file for `model` (the nominal one): its joint columns, and, if it has
/// the pose columns `x, y, z, roll, pitch, yaw` (lengths in the length unit, angles in the joint
/// angle unit, roll-pitch-yaw as URDF: `Rz(yaw) Ry(pitch) Rx(roll)`), a pose target per row
/// with the joint values as the seed; otherwise a joint target per row. `units` given by the
/// caller take the place of the file's `# units:` line.
pub fn targets_from_csv_str(
    text: &str,
    model: &RobotModel,
    units: Option<Units>,
) -> Result<Vec<TargetRow>, DataError> {
    let table = Table::parse(text)?;
    let units = table.units(units, "")?;
    let pose_columns: Vec<Option<usize>> = POSE_COLUMNS.iter().map(|c| table.column(c)).collect();
    let poses = pose_columns.iter().any(Option::is_some);
    if let Some(missing) = POSE_COLUMNS.iter().zip(&pose_columns).find(|(_, c)| poses && c.is_none()) {
        let message = format!("a pose target needs all of {}", POSE_COLUMNS.join(", "));
        return Err(DataError::new(table.header_line, Some(missing.0), message));
    }
    let columns = table.joint_columns(model).map_err(|e| {
        if poses {
            DataError::new(
                e.line,
                e.column.as_deref(),
                format!("{}: pose targets need the nominal joint solution as the seed", e.message),
            )
        } else {
            e
        }
    })?;
    table
        .nonempty_rows()?
        .iter()
        .map(|row| {
            let q = table.joint_values(row, &columns, model, units)?;
            let target = if poses {
                let mut v = [0.0; 6];
                for (k, (value, column)) in v.iter_mut().zip(&pose_columns).enumerate() {
                    let c = column.expect("checked above");
                    let x = table.number(row, c)?;
                    *value = if k < 3 {
                        table.within(row, c, x * units.length_scale(), crate::limits::MAX_LENGTH_MM, "mm")?
                    } else {
                        units.angle(x)
                    };
                }
                let pose = Isometry3::from_parts(
                    Translation3::from(Vector3::new(v[0], v[1], v[2])),
                    UnitQuaternion::from_euler_angles(v[3], v[4], v[5]),
                );
                Target::Pose { pose, seed: q }
            } else {
                Target::Joints(q)
            };
            Ok(TargetRow { line: row.line, target })
        })
        .collect()
}
