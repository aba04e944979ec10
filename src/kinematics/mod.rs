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
//!
//! A model with masses also gives the static load gravity puts on each joint
//! ([`ChainAt::gravity_torques`]), and its joints may deflect under it: a joint with
//! compliance `c` and play `p` reaches `q + c tau(q) + p sgn(tau(q))`, and the column of `H` of
//! its compliance is its joint's column scaled by `tau_j(q)`, that of its play by
//! `sgn(tau_j(q))` (the load at the commanded `q`; its dependence on the geometry is not
//! linearised, a term of the order of `c`; the play's column is exact wherever the load is not
//! zero).
//! [`Chain::with_errors`] applies a parameter vector once (and with it the trigonometry of every
//! step no joint moves); evaluating a point then allocates nothing: the Jacobians are written
//! into views the caller owns. They come from one walk backwards from the end, in which the end
//! point is the origin (`e - o = -o`), turned into the world frame by the end rotation once.

mod batch;
mod gravity;
mod trig;

pub use batch::{BATCH, Configurations, Frames};
use trig::Angles;
pub(crate) use trig::{JointTrig, joint_sin_cos};

use crate::limits::MAX_JOINTS;

use crate::model::{
    Convention, Joint, JointKind, ParamKind, ParamOwner, ParamSet, Placement, RobotModel, Selection, Tool,
};
use nalgebra::{
    DMatrix, DMatrixViewMut, Isometry3, Matrix3, Matrix6xX, Rotation3, Translation3, UnitQuaternion, Vector3,
    Vector6,
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
    /// A joint's step: the joint's compliance parameter, if the model has one.
    compliance: Option<usize>,
    /// A joint's step: the joint's play parameter, if the model has one.
    play: Option<usize>,
}

impl Step {
    /// The columns of the joint's load responses among `selection`'s, each with the factor that
    /// scales the joint's own column into it: `tau_j` for the compliance, `sgn(tau_j)` for the
    /// play, `c_j dtau_j/dm` for the payload's mass (`loads` holds them).
    fn load_columns<'s>(
        &self,
        selection: &'s Selection,
        loads: &'s Loads<'s>,
    ) -> impl Iterator<Item = (usize, f64)> + 's {
        // The loads are empty when no response is selected.
        let tau = move || self.joint.map_or(0.0, |j| loads.tau[j]);
        let compliance = self.compliance.and_then(|i| selection.column(i)).map(move |c| (c, tau()));
        let play = self.play.and_then(|i| selection.column(i)).map(move |c| (c, sign(tau())));
        let payload = (loads.payload.zip(self.joint)).map(|(c, j)| (c, loads.per_payload_kg[j]));
        compliance.into_iter().chain(play).chain(payload)
    }

    /// A step that no joint moves and no parameter displaces.
    fn fixed(motion: Motion, nominal: f64) -> Self {
        Self { motion, nominal, joint: None, param: None, compliance: None, play: None }
    }
}

/// What the load-response columns of `H` scale the joints' columns by, at one pose.
struct Loads<'a> {
    /// Each joint's gravity load `tau_j`.
    tau: &'a [f64],
    /// The payload mass's column, if selected.
    payload: Option<usize>,
    /// Each joint's deflection per kilogram of payload: `c_j dtau_j/dm`.
    per_payload_kg: &'a [f64],
}

/// The sign of a load, 0 for none: the side gravity pushes a joint's play to.
fn sign(tau: f64) -> f64 {
    if tau > 0.0 {
        1.0
    } else if tau < 0.0 {
        -1.0
    } else {
        0.0
    }
}

/// A joint's response to the load gravity puts on it: it reaches
/// `q + compliance tau + play sgn(tau)`.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
struct Deflection {
    compliance: f64,
    play: f64,
}

impl Deflection {
    /// The deflection under the load `tau`: `c tau + p sgn(tau)`.
    fn under(&self, tau: f64) -> f64 {
        self.compliance * tau + self.play * sign(tau)
    }

    fn is_zero(&self) -> bool {
        self.compliance == 0.0 && self.play == 0.0
    }
}

/// A frame during the walk along the chain: rotation columns are the frame's axes.
#[derive(Debug, Clone, Copy)]
struct Frame {
    r: Matrix3<f64>,
    p: Vector3<f64>,
}

impl Frame {
    const IDENTITY: Frame = Frame {
        r: Matrix3::new(1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0),
        p: Vector3::new(0.0, 0.0, 0.0),
    };

    fn translate(&mut self, k: usize, v: f64) {
        self.p += self.r.column(k) * v;
    }

    /// Post-multiply by the rotation about axis k whose sine and cosine are `s`, `c`: it mixes
    /// the other two columns.
    fn rotate(&mut self, k: usize, s: f64, c: f64) {
        let (i, j) = ((k + 1) % 3, (k + 2) % 3);
        let (ci, cj) = (self.r.column(i).into_owned(), self.r.column(j).into_owned());
        self.r.set_column(i, &(ci * c + cj * s));
        self.r.set_column(j, &(cj * c - ci * s));
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

/// A step with its parameter error applied: the value `nominal + x[param]`, and its sine and
/// cosine when it is a rotation no joint moves, so that only joint steps need trigonometry.
#[derive(Debug, Clone, Copy)]
struct Resolved {
    step: Step,
    value: f64,
    sin_cos: (f64, f64),
}

/// The motion of each parameter kind: about or along which axis of the current frame.
fn motion_of(kind: ParamKind) -> Motion {
    use ParamKind::*;
    match kind {
        X | A => Motion::Translate(0),
        Y => Motion::Translate(1),
        Z | D => Motion::Translate(2),
        Rx | Alpha => Motion::Rotate(0),
        Ry | Beta => Motion::Rotate(1),
        Rz | Theta => Motion::Rotate(2),
        Compliance | Play | Mass => unreachable!("a load response rides on its joint's step"),
    }
}

/// Builds the steps of a chain in order, naming each error parameter in the [`ParamSet`].
struct Builder {
    params: ParamSet,
    steps: Vec<Step>,
    /// Where the base ends and each joint's link frame is reached, as step counts.
    ends: gravity::LinkEnds,
}

impl Builder {
    /// A step that carries error parameter `kind` of `owner` and may be moved by a joint.
    fn step(&mut self, nominal: f64, joint: Option<usize>, owner: ParamOwner, kind: ParamKind) {
        let param = Some(self.params.index_of(owner, kind).expect("the ParamSet names every step"));
        let response = |kind| joint.and_then(|j| self.params.index_of(ParamOwner::Joint(j), kind));
        let (compliance, play) = (response(ParamKind::Compliance), response(ParamKind::Play));
        self.steps.push(Step { motion: motion_of(kind), nominal, joint, param, compliance, play });
    }

    /// A nominal placement `Trans(xyz) Rz(yaw) Ry(pitch) Rx(roll)`, then the error
    /// displacement `Trans(x, y, z) Rx(rx) Ry(ry) Rz(rz)` limited to `kinds`.
    fn placement(&mut self, owner: ParamOwner, nominal: &Placement, kinds: &[ParamKind]) {
        let (t, r) = (nominal.xyz, nominal.rpy);
        let fixed = [
            (0, t.x, false),
            (1, t.y, false),
            (2, t.z, false),
            (2, r.z, true),
            (1, r.y, true),
            (0, r.x, true),
        ];
        for (k, value, rotation) in fixed {
            let motion = if rotation { Motion::Rotate(k) } else { Motion::Translate(k) };
            if value != 0.0 {
                self.steps.push(Step::fixed(motion, value));
            }
        }
        for &kind in kinds {
            self.step(0.0, None, owner, kind);
        }
    }

    /// A DH joint: five steps, each with its error, in the convention's order.
    fn dh_joint(&mut self, i: usize, joint: &Joint, convention: Convention) {
        let moves = |kind| Some(i).filter(|_| kind == joint.kind);
        let theta = (ParamKind::Theta, joint.theta, moves(JointKind::Revolute));
        let d = (ParamKind::D, joint.d, moves(JointKind::Prismatic));
        let a = (ParamKind::A, joint.a, None);
        let alpha = (ParamKind::Alpha, joint.alpha, None);
        let beta = (ParamKind::Beta, joint.beta, None);
        let order = match convention {
            Convention::ModifiedDh => [alpha, a, beta, theta, d],
            _ => [theta, d, a, alpha, beta],
        };
        for (kind, nominal, moved_by) in order {
            self.step(nominal, moved_by, ParamOwner::Joint(i), kind);
        }
    }

    /// A URDF joint: its origin with 6 errors, then the motion along or about its axis (with
    /// the offset error), framed by the constant rotation `A = Rz(phi) Ry(theta)` that takes z
    /// onto the axis and its inverse.
    fn urdf_joint(&mut self, i: usize, joint: &Joint) {
        let owner = ParamOwner::Joint(i);
        self.placement(owner, &joint.origin, &ParamKind::PLACEMENT);
        let (theta, phi) = (joint.axis.z.clamp(-1.0, 1.0).acos(), joint.axis.y.atan2(joint.axis.x));
        self.rotation(2, phi);
        self.rotation(1, theta);
        match joint.kind {
            JointKind::Revolute => self.step(0.0, Some(i), owner, ParamKind::Theta),
            JointKind::Prismatic => self.step(0.0, Some(i), owner, ParamKind::D),
        }
        self.rotation(1, -theta);
        self.rotation(2, -phi);
    }

    /// A constant rotation about axis `k`, if it is not zero.
    fn rotation(&mut self, k: usize, angle: f64) {
        if angle != 0.0 {
            self.steps.push(Step::fixed(Motion::Rotate(k), angle));
        }
    }

    /// The chain of these steps, the first `arm` of them the arm's, for `model`.
    fn finish(self, arm: usize, model: &RobotModel) -> Chain {
        let load = gravity::Load::new(self.ends, model);
        let deflection =
            model.joints.iter().map(|j| Deflection { compliance: j.compliance, play: j.play }).collect();
        let payload = self.params.index_of(ParamOwner::Payload, ParamKind::Mass);
        Chain { steps: self.steps, arm, params: self.params, dof: model.dof(), load, deflection, payload }
    }

    /// A point at `xyz` (mm) with its 3 translation errors.
    fn point(&mut self, owner: ParamOwner, xyz: &Vector3<f64>) {
        self.placement(owner, &Placement { xyz: *xyz, rpy: Vector3::zeros() }, &ParamKind::PLACEMENT[..3]);
    }
}

/// What a chain of [`Chain::marker_ends`] ends at on the robot's last link, in the model's
/// [marker frame](RobotModel::marker_frame).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum MarkerEnd {
    /// A marker: a point (mm), its position estimated.
    Point(Vector3<f64>),
    /// A measured frame (a 6-DOF probe), its position and rotation estimated.
    Frame(Placement),
}

impl MarkerEnd {
    /// Where it is (mm): the point, or the frame's origin.
    pub fn origin(&self) -> Vector3<f64> {
        match self {
            Self::Point(p) => *p,
            Self::Frame(f) => f.xyz,
        }
    }

    /// Its error parameters: 3 for a point, 6 for a frame.
    pub fn parameters(&self) -> usize {
        match self {
            Self::Point(_) => 3,
            Self::Frame(_) => 6,
        }
    }
}

/// A robot model compiled for fast kinematics; see the [module documentation](self).
#[derive(Debug, Clone)]
pub struct Chain {
    steps: Vec<Step>,
    /// The steps of the base and joints (and, for markers and probes, the fixed marker frame);
    /// the rest place the tool, marker or probe.
    arm: usize,
    params: ParamSet,
    dof: usize,
    /// The masses the joints move and gravity, for the static joint loads.
    load: gravity::Load,
    /// Each joint's nominal compliance and play (the model's).
    deflection: Vec<Deflection>,
    /// The payload mass's parameter, if the model carries a payload.
    payload: Option<usize>,
}

impl Chain {
    /// Compile `model`, ending at its tool.
    pub fn new(model: &RobotModel) -> Self {
        let mut builder = Self::arm(model, model.params());
        let arm = builder.steps.len();
        match &model.tool {
            Tool::Point(p) => builder.point(ParamOwner::Tool, p),
            Tool::Frame(f) => builder.placement(ParamOwner::Tool, f, &ParamKind::PLACEMENT),
        }
        builder.finish(arm, model)
    }

    /// One chain per marker, each ending at its marker (nominal position `markers[k]`, mm, in
    /// the model's [marker frame](RobotModel::marker_frame): the tool frame of a URDF model's
    /// tip link, else the last joint frame), all indexed by [`ParamSet::with_marker_ends`]: they
    /// share the base and joint parameters, and each has its own `marker<k>.x/y/z` (along the
    /// marker frame's axes). The tool frame is fixed; its error parameters are not used.
    pub fn markers(model: &RobotModel, markers: &[Vector3<f64>]) -> Vec<Self> {
        let ends: Vec<MarkerEnd> = markers.iter().map(|&p| MarkerEnd::Point(p)).collect();
        Self::marker_ends(model, &ends)
    }

    /// [`Chain::markers`] and, after them, the chain of a measured frame (a 6-DOF probe) at
    /// `probe` in the marker frame, as [`Chain::probe`] is, all indexed by
    /// [`ParamSet::with_marker_ends`]: the probe's errors are `marker<n + 1>.x` ...
    /// `.rz` of `n` markers.
    pub fn markers_and_probe(model: &RobotModel, markers: &[Vector3<f64>], probe: &Placement) -> Vec<Self> {
        let points = markers.iter().map(|&p| MarkerEnd::Point(p));
        let ends: Vec<MarkerEnd> = points.chain([MarkerEnd::Frame(*probe)]).collect();
        Self::marker_ends(model, &ends)
    }

    /// One chain per end of `ends` on the last link, in the model's
    /// [marker frame](RobotModel::marker_frame): a point (a marker: 3 errors
    /// `marker<k>.x/y/z`) or a measured frame (a 6-DOF probe: 6 errors `marker<k>.x` ...
    /// `.rz`), `k` counting from 1, all indexed by [`ParamSet::with_marker_ends`]. The tool
    /// frame is fixed; its error parameters are not used.
    pub fn marker_ends(model: &RobotModel, ends: &[MarkerEnd]) -> Vec<Self> {
        let counts: Vec<usize> = ends.iter().map(MarkerEnd::parameters).collect();
        let params = ParamSet::with_marker_ends(model, &counts);
        (ends.iter().enumerate())
            .map(|(k, end)| {
                let mut builder = Self::arm(model, params.clone());
                builder.placement(ParamOwner::Tool, &model.marker_frame(), &[]);
                let arm = builder.steps.len();
                match end {
                    MarkerEnd::Point(p) => builder.point(ParamOwner::Marker(k), p),
                    MarkerEnd::Frame(f) => builder.placement(ParamOwner::Marker(k), f, &ParamKind::PLACEMENT),
                }
                builder.finish(arm, model)
            })
            .collect()
    }

    /// The chain ending at a measured frame (a 6-DOF probe) placed at `probe` in the model's
    /// [marker frame](RobotModel::marker_frame), indexed by [`ParamSet::with_marker_ends`]: its 6
    /// errors are `marker1.x` ... `marker1.rz`.
    pub fn probe(model: &RobotModel, probe: &Placement) -> Self {
        Self::marker_ends(model, &[MarkerEnd::Frame(*probe)]).remove(0)
    }

    /// The chain as a branch of a tree: the same steps, its parameter `i` the tree's
    /// `params[map[i]]` (`None`: not one of the tree's, held at nominal) and its joint `j` the
    /// tree's `joints[j]` of `dof`, so that it is evaluated at the tree's error vector `x` and
    /// joint values `q` directly: `T_b(q, x) = T(q_{joints}, x_{map})`. Its identification
    /// Jacobian has the tree's parameter columns (those of other branches left untouched) and
    /// its manipulator Jacobian the tree's joint columns.
    ///
    /// # Panics
    /// If `map` or `joints` is shorter than the chain's parameters or joints, or a joint is
    /// past `dof`.
    pub fn on_tree(&self, params: ParamSet, map: &[Option<usize>], joints: &[usize], dof: usize) -> Self {
        let to_tree = |i: Option<usize>| i.and_then(|i| map[i]);
        let steps = (self.steps.iter())
            .map(|s| Step {
                joint: s.joint.map(|j| joints[j]),
                param: to_tree(s.param),
                compliance: to_tree(s.compliance),
                play: to_tree(s.play),
                ..*s
            })
            .collect();
        let mut deflection = vec![Deflection::default(); dof];
        for (j, d) in self.deflection.iter().enumerate() {
            deflection[joints[j]] = *d;
        }
        let payload = to_tree(self.payload);
        Self { steps, params, dof, deflection, payload, ..self.clone() }
    }

    /// The steps of the base and the joints.
    fn arm(model: &RobotModel, params: ParamSet) -> Builder {
        let mut builder = Builder { params, steps: Vec::new(), ends: gravity::LinkEnds::default() };
        builder.placement(ParamOwner::Base, &model.base, &ParamKind::PLACEMENT);
        builder.ends.base = builder.steps.len();
        for (i, joint) in model.joints.iter().enumerate() {
            match model.convention {
                Convention::Urdf => builder.urdf_joint(i, joint),
                convention => builder.dh_joint(i, joint, convention),
            }
            builder.ends.links.push(builder.steps.len());
        }
        builder
    }

    /// Whether the chain ends at a point on the last link, as markers do: after the arm it
    /// only translates ([`marker_jacobians`] needs this).
    pub fn ends_at_a_point(&self) -> bool {
        self.steps[self.arm..].iter().all(|s| matches!(s.motion, Motion::Translate(_)))
    }

    /// Number of joints.
    pub fn dof(&self) -> usize {
        self.dof
    }

    /// The model's error parameters; `x` vectors are indexed like this set.
    pub fn params(&self) -> &ParamSet {
        &self.params
    }

    /// The chain with parameter errors `x` (mm, rad; indexed like [`Chain::params`]) applied,
    /// ready to evaluate at any number of joint configurations.
    ///
    /// # Panics
    /// If `x` has the wrong length.
    pub fn with_errors(&self, x: &[f64]) -> ChainAt {
        assert_eq!(x.len(), self.params.len(), "x has one value per error parameter");
        let steps = self
            .steps
            .iter()
            .map(|&step| {
                let value = step.nominal + step.param.map_or(0.0, |i| x[i]);
                Resolved { step, value, sin_cos: value.sin_cos() }
            })
            .collect();
        let mut deflection = self.deflection.clone();
        for step in &self.steps {
            if let Some(j) = step.joint {
                deflection[j].compliance += step.compliance.map_or(0.0, |i| x[i]);
                deflection[j].play += step.play.map_or(0.0, |i| x[i]);
            }
        }
        let flexible = self.load.has_masses() && deflection.iter().any(|d| !d.is_zero());
        let deflection = flexible.then_some(deflection);
        let mut load = self.load.clone();
        if let (Some(payload), Some(i)) = (&mut load.payload, self.payload) {
            payload.mass += x[i];
        }
        // The load of one kilogram of payload, for the payload mass's column: built once here,
        // not at every pose.
        let unit_payload = self.payload.and_then(|_| load.unit_payload());
        ChainAt { steps, arm: self.arm, dof: self.dof, load, deflection, payload: self.payload, unit_payload }
    }
}

/// A [`Chain`] with its parameter errors applied: forward kinematics and Jacobians at any
/// joint values `q` (rad for revolute joints, mm for prismatic ones).
///
/// All methods panic if `q` or an output has the wrong size.
#[derive(Debug, Clone)]
pub struct ChainAt {
    steps: Vec<Resolved>,
    arm: usize,
    dof: usize,
    load: gravity::Load,
    /// Each joint's compliance and play, when one is not zero: the joints then reach
    /// `q + c tau(q) + p sgn(tau(q))`.
    deflection: Option<Vec<Deflection>>,
    /// The payload mass's parameter, if the model carries a payload.
    payload: Option<usize>,
    /// One kilogram at the payload's centre of mass, the links massless, if the model carries
    /// a payload.
    unit_payload: Option<gravity::Load>,
}

impl ChainAt {
    /// Whether any joint deflects under its load (a compliance or a play not zero, with masses).
    pub fn deflects(&self) -> bool {
        self.deflection.is_some()
    }

    /// Position of the tool point (mm).
    pub fn position(&self, q: &[f64]) -> Vector3<f64> {
        assert_eq!(q.len(), self.dof, "q has one value per joint");
        self.at_reached(q, |q| walk(&self.steps, q, Frame::IDENTITY).p)
    }

    /// `f` of the gravity loads at `q` if `selection` holds a compliance, a play or the
    /// payload's mass, whose columns of `H` are their joints' scaled by the joint's load, its
    /// sign, or its deflection per kilogram of payload `c_j dtau_j/dm` (the load of one
    /// kilogram at the payload's centre of mass, times the compliance); of nothing otherwise
    /// (then unused).
    fn with_loads<R>(&self, selection: &Selection, q: &[f64], f: impl FnOnce(&Loads<'_>) -> R) -> R {
        let selected = |i: Option<usize>| i.is_some_and(|i| selection.column(i).is_some());
        let payload = self.payload.and_then(|i| selection.column(i));
        let compliant = self.has_masses()
            && (payload.is_some()
                || self.steps.iter().any(|s| selected(s.step.compliance) || selected(s.step.play)));
        if !compliant {
            return f(&Loads { tau: &[], payload: None, per_payload_kg: &[] });
        }
        let (mut tau, mut per_kg) = ([0.0; MAX_JOINTS], [0.0; MAX_JOINTS]);
        self.gravity_torques(q, &mut tau[..self.dof]);
        if let (Some(_), Some(unit)) = (payload, &self.unit_payload) {
            self.torques_of(unit, q, &mut per_kg[..self.dof]);
            let compliance = self.deflection.as_ref().map(|d| d.iter().map(|d| d.compliance));
            for (u, c) in per_kg[..self.dof].iter_mut().zip(compliance.into_iter().flatten()) {
                *u *= c;
            }
            if self.deflection.is_none() {
                per_kg.fill(0.0);
            }
        }
        f(&Loads { tau: &tau[..self.dof], payload, per_payload_kg: &per_kg[..self.dof] })
    }

    /// `f` of the joint values the arm reaches when commanded `q`: `q + c tau(q) + p sgn(tau(q))`,
    /// each joint deflected by its compliance `c` and pushed to one side of its play `p` by the
    /// gravity load `tau` at `q` ([`ChainAt::gravity_torques`]); of `q` itself when no joint
    /// deflects. The load is taken at the commanded values: the deflection's own effect on it
    /// is of second order.
    fn at_reached<R>(&self, q: &[f64], f: impl FnOnce(&[f64]) -> R) -> R {
        let Some(deflection) = &self.deflection else { return f(q) };
        let mut buffer = [0.0; MAX_JOINTS];
        let reached = &mut buffer[..self.dof];
        self.gravity_torques(q, reached);
        for ((r, &q), d) in reached.iter_mut().zip(q).zip(deflection) {
            *r = q + d.under(*r);
        }
        f(reached)
    }

    /// [`ChainAt::at_reached`] of joint values with, perhaps, their sines and cosines: `f` of
    /// `q` itself when no joint deflects; of the values reached, plain, when one does (their
    /// sines and cosines are not `q`'s).
    fn at_reached_trig<R>(&self, q: JointTrig<'_>, f: impl FnOnce(JointTrig<'_>) -> R) -> R {
        if self.deflection.is_none() {
            return f(q);
        }
        self.at_reached(q.q(), |reached| f(JointTrig::plain(reached)))
    }

    /// Pose of the tool frame: `base * T_1(q_1) * ... * T_n(q_n) * tool`.
    pub fn pose(&self, q: &[f64]) -> Isometry3<f64> {
        assert_eq!(q.len(), self.dof, "q has one value per joint");
        let end = self.at_reached(q, |q| walk(&self.steps, q, Frame::IDENTITY));
        let rotation = UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(end.r));
        Isometry3::from_parts(Translation3::from(end.p), rotation)
    }

    /// The manipulator Jacobian `J = d(pose)/dq` (6 x dof: linear rows in mm per joint unit,
    /// then angular rows in rad per joint unit), written into `out`; returns the tool position.
    pub fn manipulator_jacobian(&self, q: &[f64], out: &mut Matrix6xX<f64>) -> Vector3<f64> {
        let mut no_h = DMatrix::zeros(0, 0);
        let empty = Selection::empty();
        self.jacobians(q, &empty, Measured::Position, no_h.view_mut((0, 0), (0, 0)), Some(out))
    }

    /// The identification Jacobian of one point, `H_k = d(pose)/dx` for the selected
    /// parameters (Wu 1984; the paper's Eq. 1), written into `out` (`measured.rows()` x
    /// `selection.len()`); returns the tool position.
    pub fn identification_jacobian(
        &self,
        q: &[f64],
        selection: &Selection,
        measured: Measured,
        out: DMatrixViewMut<'_, f64>,
    ) -> Vector3<f64> {
        self.jacobians(q, selection, measured, out, None)
    }

    /// `H_k` into `h` as [`ChainAt::identification_jacobian`] does and, if asked, `J` into `j`
    /// in the same walk; returns the tool position.
    pub fn jacobians(
        &self,
        q: &[f64],
        selection: &Selection,
        measured: Measured,
        mut h: DMatrixViewMut<'_, f64>,
        mut j: Option<&mut Matrix6xX<f64>>,
    ) -> Vector3<f64> {
        if h.ncols() > 0 {
            assert_eq!(h.shape(), (measured.rows(), selection.len()), "H block is rows x selected");
        }
        if let Some(j) = &j {
            assert_eq!(j.ncols(), self.dof, "J has one column per joint");
        }
        // One walk from the end: the screws come out in end-frame coordinates, with the end
        // point at the origin, and are turned into the world frame at the end.
        let origin = Vector3::zeros();
        assert_eq!(q.len(), self.dof, "q has one value per joint");
        if let Some(c) = self.payload.and_then(|i| selection.column(i)).filter(|_| h.ncols() > 0) {
            h.column_mut(c).fill(0.0);
        }
        let mut visit = |loads: &Loads<'_>, q: &[f64]| {
            walk_back(&self.steps, q, |step, frame| {
                let with_h = h.ncols() > 0;
                let column = step.param.and_then(|i| selection.column(i)).filter(|_| with_h);
                let mut responses = step.load_columns(selection, loads).filter(|_| with_h).peekable();
                let joint = step.joint.filter(|_| j.is_some());
                if column.is_none() && responses.peek().is_none() && joint.is_none() {
                    return;
                }
                let (linear, angular) = frame.screw(step.motion, &origin);
                // A load response moves its joint: its column is the joint's, scaled.
                for (c, scale) in column.map(|c| (c, 1.0)).into_iter().chain(responses) {
                    // The payload's mass moves every joint: its column sums over them.
                    let keep = if Some(c) == loads.payload { 1.0 } else { 0.0 };
                    let linear = h.fixed_view::<3, 1>(0, c) * keep + linear * scale;
                    h.fixed_view_mut::<3, 1>(0, c).copy_from(&linear);
                    if measured == Measured::Pose {
                        let angular = h.fixed_view::<3, 1>(3, c) * keep + angular * scale;
                        h.fixed_view_mut::<3, 1>(3, c).copy_from(&angular);
                    }
                }
                if let (Some(col), Some(j)) = (joint, j.as_deref_mut()) {
                    j.fixed_view_mut::<3, 1>(0, col).copy_from(&linear);
                    j.fixed_view_mut::<3, 1>(3, col).copy_from(&angular);
                }
            })
        };
        let end = self.with_loads(selection, q, |loads| self.at_reached(q, |reached| visit(loads, reached)));
        to_world(&end.r, &mut h);
        if let Some(j) = j {
            to_world(&end.r, j);
        }
        end.p
    }
}

/// The arm's steps from `from` to its end that no selected parameter moves, undone at one
/// pose: the frame [`walk_back`] reaches there, where each linearisation's walk back can start
/// instead of at the end ([`marker_jacobians_held`]). The same arithmetic in the same order:
/// the Jacobians are bit for bit those of the whole walk. A registration's fits (base and
/// markers alone) walk only the base's steps.
#[derive(Debug, Clone, Copy)]
pub(crate) struct HeldArm {
    /// The first step held.
    from: usize,
    /// The frame after undoing the steps `from..arm`.
    frame: Frame,
}

impl ChainAt {
    /// The first step of the arm from which on no parameter of `selection` moves a step (its
    /// own, its joint's compliance or play); `None` when no joint's step is among those (no
    /// trigonometry to save: the fixed steps after the last joint cost next to nothing), the
    /// payload's mass is selected (its column sums over every joint) or a joint deflects (its
    /// gravity load, and so where it reaches, moves with every parameter).
    pub(crate) fn held_from(&self, selection: &Selection) -> Option<usize> {
        if self.deflects() || self.payload.and_then(|i| selection.column(i)).is_some() {
            return None;
        }
        let selected = |i: Option<usize>| i.and_then(|i| selection.column(i)).is_some();
        let moved =
            |r: &Resolved| selected(r.step.param) || selected(r.step.compliance) || selected(r.step.play);
        let from = self.steps[..self.arm].iter().rposition(moved).map_or(0, |i| i + 1);
        self.steps[from..self.arm].iter().any(|r| r.step.joint.is_some()).then_some(from)
    }

    /// The steps `from..arm` undone at the joint values `q` reaches ([`ChainAt::held_from`]).
    pub(crate) fn held_arm(&self, q: &[f64], from: usize) -> HeldArm {
        let frame =
            self.at_reached(q, |q| back_from(&self.steps[from..self.arm], q, Frame::IDENTITY, |_, _| ()));
        HeldArm { from, frame }
    }
}

/// The identification Jacobians of several markers on the last link (chains from
/// [`Chain::markers`], with the same errors applied), stacked 3 rows per marker into `h`
/// (`3 * markers x selection.len()`), with each marker's position written into `positions`.
/// The arm, which all markers share, is walked once: a step's screw at marker `m` is its screw
/// at the last joint frame's origin plus `omega x r_m`, with `r_m` the marker's offset there.
/// Like [`ChainAt::identification_jacobian`], it writes only the columns of its parameters:
/// `h` starts at zero.
///
/// # Panics
/// If the chains are not markers of one arm, or a size does not match.
pub fn marker_jacobians(
    markers: &[ChainAt],
    q: &[f64],
    selection: &Selection,
    h: DMatrixViewMut<'_, f64>,
    positions: &mut [Vector3<f64>],
) {
    marker_jacobians_held(markers, JointTrig::plain(q), selection, h, positions, None);
}

/// Column `c` of `h` (3 rows a point at `positions`, in the end frame) set to `keep` times
/// itself plus `scale` times the screw `(linear, angular)` moving each point:
/// `h_c <- keep h_c + scale (linear + angular x r_m)`.
#[inline(always)]
fn add_screw(
    h: &mut DMatrixViewMut<'_, f64>,
    (c, keep, scale): (usize, f64, f64),
    (linear, angular): (Vector3<f64>, Vector3<f64>),
    positions: &[Vector3<f64>],
) {
    let mut column = h.column_mut(c);
    for (m, r) in positions.iter().enumerate() {
        let moved = linear + angular.cross(r);
        for i in 0..3 {
            column[3 * m + i] = column[3 * m + i] * keep + moved[i] * scale;
        }
    }
}

/// [`marker_jacobians`], the walk back starting at `held`'s frame if given (this pose's, from
/// [`ChainAt::held_arm`]; the steps it holds are not visited: no selected parameter moves them),
/// the joints turned by `q`'s sines and cosines if it has them ([`JointTrig`]).
pub(crate) fn marker_jacobians_held(
    markers: &[ChainAt],
    q: JointTrig<'_>,
    selection: &Selection,
    mut h: DMatrixViewMut<'_, f64>,
    positions: &mut [Vector3<f64>],
    held: Option<&HeldArm>,
) {
    let first = &markers[0];
    assert_eq!(q.q().len(), first.dof, "q has one value per joint");
    assert_eq!(h.shape(), (3 * markers.len(), selection.len()), "H block is 3 per marker x selected");
    assert_eq!(positions.len(), markers.len(), "one position per marker");
    // Each marker's offset in the last joint frame: its tail is translations only.
    let offset = |at: &ChainAt| {
        at.steps[at.arm..].iter().fold(Vector3::zeros(), |r, s| match s.step.motion {
            Motion::Translate(k) => r + Vector3::ith(k, s.value),
            Motion::Rotate(_) => panic!("a marker is a point: its tail only translates"),
        })
    };
    // `positions` holds the offsets until the end frame is known.
    for (p, at) in positions.iter_mut().zip(markers) {
        *p = offset(at);
    }
    if let Some(c) = first.payload.and_then(|i| selection.column(i)) {
        h.column_mut(c).fill(0.0);
    }
    let mut visit = |loads: &Loads<'_>, q: JointTrig<'_>| {
        let (steps, start) = match held {
            Some(held) => (&first.steps[..held.from], held.frame),
            None => (&first.steps[..first.arm], Frame::IDENTITY),
        };
        let walked = back_from(steps, q, start, |step, frame| {
            let column = step.param.and_then(|i| selection.column(i)).map(|c| (c, 1.0));
            if loads.payload.is_none() && step.compliance.is_none() && step.play.is_none() {
                // No load response (the walk's common case, at every step of every pose): the
                // step's own column alone, nothing kept, without the responses' iterator.
                if let Some((c, scale)) = column {
                    add_screw(
                        &mut h,
                        (c, 0.0, scale),
                        frame.screw(step.motion, &Vector3::zeros()),
                        positions,
                    );
                }
                return;
            }
            // A load response moves its joint: its column is the joint's, scaled.
            let mut responses = step.load_columns(selection, loads).peekable();
            if column.is_none() && responses.peek().is_none() {
                return;
            }
            let screw = frame.screw(step.motion, &Vector3::zeros());
            for (c, scale) in column.into_iter().chain(responses) {
                // The payload's mass moves every joint: its column sums over them.
                let keep = if Some(c) == loads.payload { 1.0 } else { 0.0 };
                add_screw(&mut h, (c, keep, scale), screw, positions);
            }
        });
        seen_from_the_end(walked)
    };
    let end =
        first.with_loads(selection, q.q(), |loads| first.at_reached_trig(q, |reached| visit(loads, reached)));
    for (m, at) in markers.iter().enumerate() {
        assert_eq!(at.arm, first.arm, "markers of one arm");
        for s in &at.steps[at.arm..] {
            if let (Motion::Translate(k), Some(c)) =
                (s.step.motion, s.step.param.and_then(|i| selection.column(i)))
            {
                h.fixed_view_mut::<3, 1>(3 * m, c).copy_from(&Vector3::ith(k, 1.0));
            }
        }
        positions[m] = end.p + end.r * positions[m];
    }
    to_world(&end.r, &mut h);
}

/// The end positions of chains that share their arm (one model's markers, or its probe, with
/// the same errors applied), written into `positions`: the arm is walked once, then each
/// chain's own end.
///
/// # Panics
/// If the chains' arms differ in length, or a size does not match.
pub fn end_positions(chains: &[ChainAt], q: &[f64], positions: &mut [Vector3<f64>]) {
    end_positions_trig(chains, JointTrig::plain(q), positions);
}

/// [`end_positions`], the joints turned by `q`'s sines and cosines if it has them
/// ([`JointTrig`]).
pub(crate) fn end_positions_trig(chains: &[ChainAt], q: JointTrig<'_>, positions: &mut [Vector3<f64>]) {
    let first = &chains[0];
    assert_eq!(q.q().len(), first.dof, "q has one value per joint");
    assert_eq!(positions.len(), chains.len(), "one position per chain");
    first.at_reached_trig(q, |q| {
        let arm = walk(&first.steps[..first.arm], q, Frame::IDENTITY);
        for (p, at) in positions.iter_mut().zip(chains) {
            assert_eq!(at.arm, first.arm, "chains of one arm");
            *p = walk(&at.steps[at.arm..], q, arm).p;
        }
    });
}

/// The manipulator Jacobians `J_m = d(pose_m)/dq` and the poses of points that share their
/// arm (one model's markers, [`Chain::ends_at_a_point`], with the same errors applied) at `q`,
/// from one walk of the arm each way: `jacobians[m]` and `poses[m]` as
/// [`ChainAt::manipulator_jacobian`] and [`ChainAt::pose`] of `chains[m]` give them, bit for
/// bit. The walk back keeps one rotation `R` (a point's tail only translates, so `R` is every
/// point's) and a position `p_m` per point (`walked`, scratch): each step does to `R` and to
/// each `p_m` what it does to one point's frame, `p_m += R e_k v` for a translation, and a
/// joint's column is the screw `(u x (0 - p_m), u)`, `u = R e_k`, turned into the world by
/// `R^T`. The walk forwards is the arm's once, then each point's tail from its end frame
/// (`end_positions`), the rotation the arm's. The joints turn by `q`'s sines and cosines if it
/// has them ([`JointTrig`]).
///
/// # Panics
/// If a point's tail rotates, the arms differ, or a size does not match.
pub(crate) fn points_manipulator(
    chains: &[ChainAt],
    q: JointTrig<'_>,
    jacobians: &mut [Matrix6xX<f64>],
    poses: &mut [Isometry3<f64>],
    walked: &mut [Vector3<f64>],
) {
    let first = &chains[0];
    assert_eq!(q.q().len(), first.dof, "q has one value per joint");
    assert!(jacobians.len() == chains.len() && poses.len() == chains.len() && walked.len() == chains.len());
    first.at_reached_trig(q, |q| {
        let mut r = Matrix3::identity();
        for (p, at) in walked.iter_mut().zip(chains) {
            assert_eq!(at.arm, first.arm, "points of one arm");
            let mut frame = Frame::IDENTITY;
            // The tail, undone: translations alone.
            for resolved in at.steps[at.arm..].iter().rev() {
                let Motion::Translate(k) = resolved.step.motion else {
                    panic!("a point's tail only translates")
                };
                frame.translate(k, -(resolved.value + resolved.step.joint.map_or(0.0, |j| q.value(j))));
            }
            *p = frame.p;
        }
        for resolved in first.steps[..first.arm].iter().rev() {
            let step = &resolved.step;
            if let Some(col) = step.joint {
                for (p, j) in walked.iter().zip(jacobians.iter_mut()) {
                    let (linear, angular) = Frame { r, p: *p }.screw(step.motion, &Vector3::zeros());
                    j.fixed_view_mut::<3, 1>(0, col).copy_from(&linear);
                    j.fixed_view_mut::<3, 1>(3, col).copy_from(&angular);
                }
            }
            undo_shared(resolved, q, &mut r, walked);
        }
        let end = seen_from_the_end(Frame { r, p: Vector3::zeros() });
        for j in jacobians.iter_mut() {
            to_world(&end.r, j);
        }
        let arm = walk(&first.steps[..first.arm], q, Frame::IDENTITY);
        let rotation = UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(arm.r));
        for (pose, at) in poses.iter_mut().zip(chains) {
            let end = walk(&at.steps[at.arm..], q, arm);
            *pose = Isometry3::from_parts(Translation3::from(end.p), rotation);
        }
    });
}

/// Step `resolved` undone at `q` on frames that share their rotation `r` and differ in their
/// positions `walked`, as [`back_from`] undoes it on each: a rotation turns `r` alone (once), a
/// translation by `v` moves each position along `r`'s axis `k`, `p_m += R e_k (-v)`.
fn undo_shared(resolved: &Resolved, q: impl Angles, r: &mut Matrix3<f64>, walked: &mut [Vector3<f64>]) {
    let mut frame = Frame { r: *r, p: Vector3::zeros() };
    match (resolved.step.motion, resolved.step.joint) {
        (Motion::Translate(k), joint) => {
            let v = -(resolved.value + joint.map_or(0.0, |j| q.value(j)));
            for p in walked.iter_mut() {
                *p += r.column(k) * v;
            }
            return;
        }
        (Motion::Rotate(k), None) => frame.rotate(k, -resolved.sin_cos.0, resolved.sin_cos.1),
        (Motion::Rotate(k), Some(j)) => {
            let (s, c) = q.sin_cos(resolved, j);
            frame.rotate(k, -s, c);
        }
    }
    *r = frame.r;
}

/// Walk `steps` forwards at `q` from `frame`: the frame at their end.
fn walk(steps: &[Resolved], q: impl Angles, mut frame: Frame) -> Frame {
    for resolved in steps {
        advance(&mut frame, resolved, q);
    }
    frame
}

/// Move `frame` by one step at `q`.
fn advance(frame: &mut Frame, resolved: &Resolved, q: impl Angles) {
    let step = &resolved.step;
    match (step.motion, step.joint) {
        (Motion::Translate(k), joint) => {
            frame.translate(k, resolved.value + joint.map_or(0.0, |j| q.value(j)))
        }
        (Motion::Rotate(k), None) => frame.rotate(k, resolved.sin_cos.0, resolved.sin_cos.1),
        (Motion::Rotate(k), Some(j)) => {
            let (s, c) = q.sin_cos(resolved, j);
            frame.rotate(k, s, c);
        }
    }
}

/// Walk `steps` backwards from their end at `q`, calling `visit` with each step and the frame it
/// acts in, expressed in the end frame's coordinates (where the end point is the origin);
/// returns the end frame in world coordinates. A step's axis and, for a rotation, its origin
/// are the same before and after it, so each frame is the one left by undoing the later steps.
fn walk_back(steps: &[Resolved], q: impl Angles, visit: impl FnMut(&Step, &Frame)) -> Frame {
    seen_from_the_end(back_from(steps, q, Frame::IDENTITY, visit))
}

/// [`walk_back`]'s loop from `frame` (the frame after the later steps were undone, `IDENTITY`
/// at the end): the frame after undoing `steps` too, still in the end frame's coordinates.
fn back_from(
    steps: &[Resolved],
    q: impl Angles,
    mut frame: Frame,
    mut visit: impl FnMut(&Step, &Frame),
) -> Frame {
    for resolved in steps.iter().rev() {
        let step = &resolved.step;
        visit(step, &frame);
        match (step.motion, step.joint) {
            (Motion::Translate(k), joint) => {
                frame.translate(k, -(resolved.value + joint.map_or(0.0, |j| q.value(j))))
            }
            (Motion::Rotate(k), None) => frame.rotate(k, -resolved.sin_cos.0, resolved.sin_cos.1),
            (Motion::Rotate(k), Some(j)) => {
                let (s, c) = q.sin_cos(resolved, j);
                frame.rotate(k, -s, c);
            }
        }
    }
    frame
}

/// The end frame in world coordinates from the world frame seen from the end (`frame`, all
/// steps undone): its inverse.
fn seen_from_the_end(frame: Frame) -> Frame {
    let r = frame.r.transpose();
    Frame { r, p: -(r * frame.p) }
}

/// The columns of `m`, in blocks of 3 rows, turned from end-frame into world coordinates.
fn to_world<R: nalgebra::Dim, C: nalgebra::Dim, S: nalgebra::StorageMut<f64, R, C>>(
    r: &Matrix3<f64>,
    m: &mut nalgebra::Matrix<f64, R, C, S>,
) {
    for c in 0..m.ncols() {
        for row in (0..m.nrows()).step_by(3) {
            let world = r * m.fixed_view::<3, 1>(row, c);
            m.fixed_view_mut::<3, 1>(row, c).copy_from(&world);
        }
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

#[cfg(test)]
mod held_tests {
    use super::*;
    use crate::model::RobotModel;

    /// Two markers on the PUMA 560, its parameters, and the chains at small errors.
    fn two_markers() -> ([Vector3<f64>; 2], ParamSet, Vec<ChainAt>) {
        let model = RobotModel::preset("puma560").unwrap();
        let markers = [Vector3::new(50.0, 0.0, 150.0), Vector3::new(-40.0, 60.0, 120.0)];
        let chains = Chain::markers(&model, &markers);
        let params = chains[0].params().clone();
        let x: Vec<f64> = (0..params.len()).map(|i| 1e-3 * ((i * 7 % 11) as f64 - 5.0)).collect();
        let at: Vec<ChainAt> = chains.iter().map(|c| c.with_errors(&x)).collect();
        (markers, params, at)
    }

    /// The markers' Jacobians walked back from the held steps are bit for bit the whole walk's,
    /// for a registration (base and markers), with early joint parameters selected too, and
    /// with none of the base: the steps held differ, the numbers do not.
    #[test]
    fn the_held_walk_is_the_whole_walk() {
        let (markers, params, at) = two_markers();
        let named = |names: &[&str]| Selection::by_names(&params, names).unwrap();
        for selection in [
            named(&["base.*", "marker*.*"]),
            named(&["base.*", "marker*.*", "j1.*", "j2.a"]),
            named(&["marker*.*"]),
        ] {
            let from = at[0].held_from(&selection).expect("steps to hold");
            for k in 0..5 {
                let q: Vec<f64> = (0..6).map(|j| 0.3 * (k as f64) - 0.2 * j as f64).collect();
                let rows = 3 * markers.len();
                let (mut whole, mut held) =
                    (DMatrix::zeros(rows, selection.len()), DMatrix::zeros(rows, selection.len()));
                let (mut p, mut p_held) = (vec![Vector3::zeros(); 2], vec![Vector3::zeros(); 2]);
                marker_jacobians(
                    &at,
                    &q,
                    &selection,
                    whole.view_mut((0, 0), (rows, selection.len())),
                    &mut p,
                );
                let arm = at[0].held_arm(&q, from);
                let view = held.view_mut((0, 0), (rows, selection.len()));
                marker_jacobians_held(&at, JointTrig::plain(&q), &selection, view, &mut p_held, Some(&arm));
                assert_eq!((whole, p), (held, p_held), "from step {from}");
            }
        }
        let froms: Vec<_> =
            [&["base.*"][..], &["j1.*"], &["marker*.*"]].map(|n| at[0].held_from(&named(n))).to_vec();
        // The markers' parameters are past the arm: with them alone, the whole arm is held.
        assert!(froms[2] == Some(0) && froms[0] > froms[2] && froms[1] > froms[0], "{froms:?}");
    }

    /// The walks with the joints' sines and cosines ([`JointTrig::with`]: the angle-sum
    /// identity) agree with those of the plain joint values to rounding: the markers'
    /// positions, their Jacobians and the points' manipulator Jacobians.
    #[test]
    fn the_trig_walk_is_the_plain_walk_to_rounding() {
        let (_, params, at) = two_markers();
        let selection = Selection::by_names(&params, &["base.*", "marker*.*", "j1.*", "j2.a"]).unwrap();
        let joints: Vec<Vec<f64>> =
            (0..5).map(|k| (0..6).map(|j| 0.9 * (k as f64) - 0.7 * j as f64).collect()).collect();
        let table = joint_sin_cos(&joints);
        let close =
            |a: &[f64], b: &[f64]| a.iter().zip(b).all(|(a, b)| (a - b).abs() <= 1e-12 * (1.0 + a.abs()));
        for (k, q) in joints.iter().enumerate() {
            let trig = JointTrig::with(q, &table[6 * k..6 * (k + 1)]);
            let (mut plain, mut turned) = ([Vector3::zeros(); 2], [Vector3::zeros(); 2]);
            end_positions(&at, q, &mut plain);
            end_positions_trig(&at, trig, &mut turned);
            assert!(
                close(plain[0].as_slice(), turned[0].as_slice())
                    && close(plain[1].as_slice(), turned[1].as_slice())
            );
            let mut h = [DMatrix::zeros(6, selection.len()), DMatrix::zeros(6, selection.len())];
            for (h, q) in h.iter_mut().zip([JointTrig::plain(q), trig]) {
                marker_jacobians_held(
                    &at,
                    q,
                    &selection,
                    h.view_mut((0, 0), (6, selection.len())),
                    &mut plain,
                    None,
                );
            }
            assert!(close(h[0].as_slice(), h[1].as_slice()), "pose {k}");
            let mut manipulators = [vec![Matrix6xX::zeros(6); 2], vec![Matrix6xX::zeros(6); 2]];
            let (mut ends, mut walked) = (vec![Isometry3::identity(); 2], vec![Vector3::zeros(); 2]);
            for (m, q) in manipulators.iter_mut().zip([JointTrig::plain(q), trig]) {
                points_manipulator(&at, q, m, &mut ends, &mut walked);
            }
            assert!((0..2).all(|m| close(manipulators[0][m].as_slice(), manipulators[1][m].as_slice())));
        }
    }
}
