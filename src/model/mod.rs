//! Robot models: a serial chain of revolute and prismatic joints with a base and a tool.
//!
//! Inside the library every length is in millimetres and every angle in radians. Degrees
//! appear only in files and on the command line, in fields named so (`alpha_deg`).
//!
//! Each joint's geometry follows the model's [`Convention`], both extended with Hayati's
//! rotation `beta` about y (Hayati and Mirmirani 1985), which keeps the parameterisation well
//! conditioned where consecutive axes are nearly parallel (PUMA 560 joints 2 and 3):
//!
//! - standard DH:  `T_i = Rz(theta_i) Tz(d_i) Tx(a_i) Rx(alpha_i) Ry(beta_i)`
//! - modified DH (Craig): `T_i = Rx(alpha_i) Tx(a_i) Ry(beta_i) Rz(theta_i) Tz(d_i)`, where
//!   `alpha_i`, `a_i` are Craig's `alpha_{i-1}`, `a_{i-1}`: they lead to joint i's axis.
//!
//! - URDF: `T_i = origin_i A_i M(q_i) A_i^-1`, where `origin_i` is the joint's placement in its
//!   parent link (xyz, roll-pitch-yaw), `A_i` the rotation taking z onto the joint's axis, and
//!   `M` the rotation about (or translation along) z by the joint variable.
//!
//! A revolute DH joint's variable adds to `theta`, a prismatic one's to `d`. The whole chain is
//! `base * T_1 * ... * T_n * tool`.

mod file;
mod params;
mod tree;
mod ur_kinematics;
mod urdf;
mod urdf_export;

pub use file::{ModelError, degrees, markers_from_toml_str, to_toml_with_markers};
pub(crate) use params::name_matches;
pub use params::{ParamInfo, ParamKind, ParamOwner, ParamSet, Selection, SelectionError};
pub use tree::{Branch, RobotTree};
pub use ur_kinematics::{UR_JOINTS, UR_SEGMENTS, from_ur_kinematics, to_ur_kinematics};
pub use urdf::{
    DEFLECTION, GRAVITY, chain_links, from_urdf_str, markers_from_urdf_str, to_urdf_string,
    tree_to_urdf_string, with_urdf_markers,
};
pub use urdf_export::{UrdfExport, UrdfOptions, to_urdf};

use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
use rand::RngExt;
use rand::rngs::ChaCha8Rng;

/// How a joint's geometry is described; see the [module documentation](self).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Convention {
    /// Standard Denavit-Hartenberg: `Rz(theta) Tz(d) Tx(a) Rx(alpha) Ry(beta)`.
    StandardDh,
    /// Modified Denavit-Hartenberg (Craig): `Rx(alpha) Tx(a) Ry(beta) Rz(theta) Tz(d)`.
    ModifiedDh,
    /// URDF: an origin placement and a motion about or along an axis.
    Urdf,
}

/// Whether a joint turns (its variable adds to `theta`) or slides (adds to `d`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum JointKind {
    /// Rotation about the joint axis; joint variable in radians.
    Revolute,
    /// Translation along the joint axis; joint variable in millimetres.
    Prismatic,
}

/// One joint's nominal geometry (mm, rad) and travel limits.
#[derive(Debug, Clone, PartialEq)]
pub struct Joint {
    /// Name used in reports and parameter names (`j3` gives `j3.beta`).
    pub name: String,
    /// Revolute or prismatic.
    pub kind: JointKind,
    /// Rotation about z (rad); for a revolute joint, its zero offset.
    pub theta: f64,
    /// Translation along z (mm); for a prismatic joint, its zero offset.
    pub d: f64,
    /// Translation along x (mm).
    pub a: f64,
    /// Rotation about x (rad).
    pub alpha: f64,
    /// Hayati's rotation about y (rad), nominally zero.
    pub beta: f64,
    /// Lower and upper travel limit of the joint variable (rad, or mm if prismatic).
    pub limits: [f64; 2],
    /// URDF only: the joint's placement in its parent link (identity for DH joints).
    pub origin: Placement,
    /// URDF only: the unit axis of the motion, in the joint frame (z for DH joints).
    pub axis: Vector3<f64>,
    /// The joint's deflection per unit of the load gravity puts on it (rad per N·m; mm per N
    /// for a prismatic joint): it reaches `q + compliance tau(q)` in a model with masses.
    pub compliance: f64,
    /// The joint's play (rad; mm for a prismatic joint): gravity pushes it to one side, so it
    /// reaches `q + play sgn(tau(q))` besides its compliance's deflection, in a model with masses.
    pub play: f64,
}

impl Joint {
    /// A Denavit-Hartenberg joint (mm, rad).
    pub fn dh(name: &str, kind: JointKind, [theta, d, a, alpha, beta]: [f64; 5], limits: [f64; 2]) -> Self {
        let (origin, axis) = (Placement::default(), Vector3::z());
        Self {
            name: name.into(),
            kind,
            theta,
            d,
            a,
            alpha,
            beta,
            limits,
            origin,
            axis,
            compliance: 0.0,
            play: 0.0,
        }
    }

    /// A URDF joint: placement in its parent link and unit axis (mm, rad).
    pub fn urdf(
        name: &str,
        kind: JointKind,
        origin: Placement,
        axis: Vector3<f64>,
        limits: [f64; 2],
    ) -> Self {
        Self {
            name: name.into(),
            kind,
            theta: 0.0,
            d: 0.0,
            a: 0.0,
            alpha: 0.0,
            beta: 0.0,
            limits,
            origin,
            axis,
            compliance: 0.0,
            play: 0.0,
        }
    }
}

/// The names of the `joints` whose value in `q` (rad, mm) lies outside their limits.
pub fn outside_limits<'a>(joints: &'a [Joint], q: &[f64]) -> Vec<&'a str> {
    joints
        .iter()
        .zip(q)
        .filter(|(j, v)| **v < j.limits[0] || **v > j.limits[1])
        .map(|(j, _)| j.name.as_str())
        .collect()
}

/// A rigid placement: translation (mm) then roll-pitch-yaw rotation (rad),
/// `T = Trans(xyz) Rz(yaw) Ry(pitch) Rx(roll)` (the URDF convention).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Placement {
    /// Translation (mm).
    pub xyz: Vector3<f64>,
    /// Roll, pitch, yaw (rad).
    pub rpy: Vector3<f64>,
}

impl Placement {
    /// The placement (xyz, roll-pitch-yaw) of an isometry.
    pub fn from_isometry(iso: &Isometry3<f64>) -> Self {
        let (roll, pitch, yaw) = iso.rotation.euler_angles();
        Self { xyz: iso.translation.vector, rpy: Vector3::new(roll, pitch, yaw) }
    }

    /// The placement as an isometry.
    pub fn isometry(&self) -> Isometry3<f64> {
        let rotation = UnitQuaternion::from_euler_angles(self.rpy.x, self.rpy.y, self.rpy.z);
        Isometry3::from_parts(Translation3::from(self.xyz), rotation)
    }
}

/// What the measuring device sees at the end of the chain.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Tool {
    /// A point (mm) in the last joint frame, such as a tracker reflector: position only.
    Point(Vector3<f64>),
    /// A frame fixed to the last joint frame: position and orientation.
    Frame(Placement),
}

/// Standard gravity (m/s²), pointing along -z of the robot's base frame by default.
pub const STANDARD_GRAVITY: f64 = 9.80665;

/// The mass a joint moves: the link after it (with everything fixed to that link) as one rigid
/// body, for the static load on the joints (gravity torques, compliance).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LinkMass {
    /// Mass (kg).
    pub mass: f64,
    /// Centre of mass (mm) in the link's frame: the frame after its joint (DH: after the
    /// joint's `T_i`; URDF: the joint's child link frame).
    pub com: Vector3<f64>,
}

/// A payload the arm carries (a workpiece, a tool not in the model): a mass at a point of the
/// [marker frame](RobotModel::marker_frame), the tip link's.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Payload {
    /// Mass (kg).
    pub mass: f64,
    /// Centre of mass (mm) in the marker frame.
    pub com: Vector3<f64>,
}

/// A serial robot: base placement, joints, tool.
#[derive(Debug, Clone, PartialEq)]
pub struct RobotModel {
    /// Short name (`puma560`).
    pub name: String,
    /// Free text: where the numbers come from.
    pub description: String,
    /// How the joints' geometry is described.
    pub convention: Convention,
    /// Measuring frame to the first joint's frame.
    pub base: Placement,
    /// The joints, base to tip.
    pub joints: Vec<Joint>,
    /// Last joint frame to the measured point or frame.
    pub tool: Tool,
    /// The mass each joint moves, one per joint in order; empty when the masses are unknown.
    pub masses: Vec<LinkMass>,
    /// Gravity in the robot's base frame (the frame after [`RobotModel::base`]), m/s²:
    /// `(0, 0, -STANDARD_GRAVITY)` for a robot on the floor; another direction for a wall or
    /// ceiling mount.
    pub gravity: Vector3<f64>,
    /// A payload the arm carries beyond its links (a workpiece, a tool not in the model), in
    /// the tip frame: its mass loads the joints with the links', and may be estimated
    /// (`payload.mass`).
    pub payload: Option<Payload>,
}

impl RobotModel {
    /// Gravity along -z of the robot's base frame (m/s²): a robot standing on the floor.
    pub fn floor_gravity() -> Vector3<f64> {
        Vector3::new(0.0, 0.0, -STANDARD_GRAVITY)
    }

    /// Number of joints.
    pub fn dof(&self) -> usize {
        self.joints.len()
    }

    /// The names of the joints whose value in `q` (rad, mm) lies outside their limits.
    pub fn joints_outside_limits(&self, q: &[f64]) -> Vec<&str> {
        outside_limits(&self.joints, q)
    }

    /// The named error parameters of this model, in their canonical order.
    pub fn params(&self) -> ParamSet {
        ParamSet::new(self)
    }

    /// Read a model from TOML text (lengths in mm, angles in degrees; see `docs/formats.md`).
    pub fn from_toml_str(text: &str) -> Result<Self, ModelError> {
        file::parse(text)
    }

    /// Write the model as TOML; [`RobotModel::from_toml_str`] reads it back exactly.
    pub fn to_toml_string(&self) -> String {
        file::write(self)
    }

    /// `n` configurations drawn uniformly within the joint limits, joint by joint, from `rng`
    /// (the paper's step 1; the candidate pools of pose planning).
    pub fn uniform_configurations(&self, n: usize, rng: &mut ChaCha8Rng) -> Vec<Vec<f64>> {
        (0..n)
            .map(|_| self.joints.iter().map(|j| rng.random_range(j.limits[0]..=j.limits[1])).collect())
            .collect()
    }

    /// The frame marker and probe coordinates are given in, in the last joint's frame: the
    /// tool frame when the tool is a frame (a URDF model's tip link), the last joint's frame
    /// itself (the identity) when the tool is a point.
    pub fn marker_frame(&self) -> Placement {
        match self.tool {
            Tool::Point(_) => Placement::default(),
            Tool::Frame(frame) => frame,
        }
    }

    /// The model carrying `payload` (in place of any payload it had). A model without masses
    /// then carries the payload alone: its links count as massless.
    pub fn with_payload(&self, payload: &Payload) -> RobotModel {
        RobotModel { payload: Some(*payload), ..self.clone() }
    }

    /// Whether gravity loads the joints: the model has link masses or a payload.
    pub fn has_masses(&self) -> bool {
        !self.masses.is_empty() || self.payload.is_some()
    }

    /// The payload's centre of mass (mm) in the last joint's frame: its position in the
    /// [marker frame](RobotModel::marker_frame), placed by that frame.
    pub fn payload_com(&self) -> Option<Vector3<f64>> {
        let payload = self.payload?;
        Some((self.marker_frame().isometry() * nalgebra::Point3::from(payload.com)).coords)
    }

    /// The tool point in the [marker frame](RobotModel::marker_frame): the tool point of a
    /// point tool, the origin of a tool frame.
    pub fn tool_point_in_marker_frame(&self) -> Vector3<f64> {
        match self.tool {
            Tool::Point(p) => p,
            Tool::Frame(_) => Vector3::zeros(),
        }
    }

    /// A model shipped with robocal, by name; see [`PRESETS`].
    pub fn preset(name: &str) -> Option<Self> {
        let text = PRESETS.iter().find(|(n, _)| *n == name)?.1;
        Some(Self::from_toml_str(text).expect("embedded presets are valid"))
    }
}

/// A robot model as a user names it: a preset name, a model TOML file, or a URDF file (`.urdf`)
/// with the links its chain runs between. The links default to the URDF's root link and its
/// only leaf, so a serial arm needs neither; a tree (two arms, a head) needs the tip.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct ModelRef {
    /// The preset name or the file.
    pub name: String,
    /// URDF: the link the chain starts from (default: the root link).
    pub base_link: Option<String>,
    /// URDF: the link the chain ends at (default: the only leaf link).
    pub tip_link: Option<String>,
    /// A payload the arm carries, added to the model's masses ([`RobotModel::with_payload`]).
    pub payload: Option<Payload>,
}

impl ModelRef {
    /// A preset or a file, with a URDF's default links.
    pub fn named(name: impl Into<String>) -> Self {
        Self { name: name.into(), ..Self::default() }
    }

    /// Whether the name is a URDF file (ends with `.urdf`).
    pub fn is_urdf(&self) -> bool {
        self.name.ends_with(".urdf")
    }
}

/// The models embedded in robocal: `(name, TOML text)`.
pub const PRESETS: &[(&str, &str)] = &[
    ("puma560", include_str!("../../presets/puma560.toml")),
    ("puma560-masses", include_str!("../../presets/puma560-masses.toml")),
    ("ur3e", include_str!("../../presets/ur3e.toml")),
    ("ur5e", include_str!("../../presets/ur5e.toml")),
    ("ur10e", include_str!("../../presets/ur10e.toml")),
    ("ur16e", include_str!("../../presets/ur16e.toml")),
    ("panda", include_str!("../../presets/panda.toml")),
    ("iiwa14", include_str!("../../presets/iiwa14.toml")),
    ("irb120", include_str!("../../presets/irb120.toml")),
];
