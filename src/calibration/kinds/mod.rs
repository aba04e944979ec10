//! Measurement kinds beyond marker positions: distances (a ball bar, a length artefact, a laser
//! interferometer) and plane contacts (a touch probe on a table), calibrated with the same
//! Gauss-Markov machinery as marker positions, and with marker positions themselves in one fit.
//!
//! # The observation model
//!
//! The robot carries a point `p(q, x)` on its last link (the tool point, a ball, a stylus
//! tip), in the robot's base frame, and each marker one of its own. Every observation `k` is one
//! number, a function of such a point at one or two poses and of parameters of the set-up `s`
//! (fixed points, planes, a camera and its target):
//!
//! - a marker's coordinate: markers are points of their own on the last link, `p_m(q, x)` of
//!   marker `m` (its position `x_m` among the parameters, `marker<m>.x, y, z`, one chain each
//!   sharing the robot's parameters, [`Chain::markers`]), seen in the measuring frame as a
//!   coordinate is: `f_k = e_c . p_m(q_k, x)`, `g_k = e_c`. The tool point (of every other
//!   kind) is then one more point after the markers. Markers see the measuring frame: the base
//!   is estimated, and starts where the rigid registration (Kabsch) of the nominal markers onto
//!   the measured ones puts it; the "before" fit then
//!   fits the base and the points on the last link with the set-up, the robot's joints nominal.
//!   With angles (roll, pitch, yaw) the tool after the markers is a frame, its rotation
//!   estimated too ([`Chain::markers_and_probe`]); with a camera's views, the camera's (or
//!   target's) mounting is in the last link's frame itself, as without markers (that frame
//!   held). Every point's `H_j` then has its rotation rows.
//! - a 6-DOF probe's orientation (a marker file's `qw,qx,qy,qz` or `roll,pitch,yaw`): marker
//!   1 is then a frame on the last link (6 parameters, [`Chain::marker_ends`]), its rotation
//!   started from the data as `calibrate` starts it; three rows a pose, the rotation vector
//!   `y = log(R_m R^T)` (rad), whose derivative by the frame's rotation vector is `J_r^-1(y)`
//!   (`orientation_prediction`), where `calibrate` takes its first order `I`.
//! - a distance between two poses `a`, `b`: `f_k = |p_a - p_b|`, with `p_a = p(q_a, x)`;
//! - a distance to fixed point `i` (a ball bar's pivot `c_i`, 3 parameters):
//!   `f_k = |p(q_k, x) - c_i|`;
//! - a contact with plane `i` (unit normal `n_i`, offset `d_i`): the signed distance
//!   `f_k = n_i . p(q_k, x) - d_i`, measured as 0;
//! - a partial measurement, one coordinate `e_c . p(q_k, x)` (`c` of x, y, z) in the measuring
//!   frame (with markers, whose measuring frame is a tracker's, in a device frame `D` of its
//!   own: `e_c . D^-1 p`, the position rows of the view of [`camera::relative_view`], `D` 6
//!   set-up parameters `device.*` seen along the measured axes only): any subset of x, y, z of a pose (a height gauge: z only), each its own observation.
//!   Their correlation through the joint noise of their common pose is left out of `V`
//!   (exact when the joints are exact). Roll, pitch and yaw of the tool frame
//!   (`R = Rz(yaw) Ry(pitch) Rx(roll)`, an inclinometer's tilts) likewise: the tool is then a
//!   frame whose rotation is estimated too, and `g_kj` is `E^-1` on the rotation rows, with
//!   `omega = E (roll', pitch', yaw')` the rotation vector's rate (the residual wrapped into
//!   `(-pi, pi]`).
//! - a camera's view of its target (hand-eye: the camera on the tool; eye-to-hand: fixed), the
//!   target's pose in the camera's frame `T_camera^-1 T_target`, 6 observations (position mm,
//!   rotation vector rad) of the tool frame and of the camera's and the target's placements
//!   (6 + 6 set-up parameters): see [`camera`], whose residual of the rotation is `log(R_m R^T)`
//!   rather than `m_k - f_k`.
//!
//! The residual is `y_k = m_k - f_k` (measured minus predicted). With `g_kj = df_k/dp_j` the
//! derivative of the prediction with respect to the point at pose `j` (`u = (p_a - p_b) /
//! |p_a - p_b|` and `-u` for a pair, `u = (p - c) / |p - c|` for a fixed point, `n_i` for a
//! contact, `e_c` for a coordinate),
//! the identification Jacobian is `H_k = sum_j g_kj^T H_j + df_k/ds`, `H_j = dp/dx` at pose
//! `j` ([`ChainAt::identification_jacobian`]), and the derivative with respect to each pose's
//! joint values is `G_kj = g_kj^T J_j`, `J_j` the position rows of the manipulator Jacobian.
//! The joint noise of different poses is independent (each pose is read separately), so
//!
//! `V_k = sum_j G_kj Sigma_q G_kj^T + sigma_k^2`:
//!
//! a pair's variance has the joint noise of both its poses.
//!
//! A plane `i` has 3 parameters, minimal: two tilts `(alpha, beta)` of its normal about the
//! nominal one `n0`, `n = (n0 + alpha t1 + beta t2) / |n0 + alpha t1 + beta t2|` with
//! `(t1, t2, n0)` orthonormal, and its offset `d` (mm). A fixed point has its 3 coordinates.
//!
//! # What each kind cannot see
//!
//! A camera sees the target relative to itself only: with the camera on the arm, the target's
//! placement absorbs the base's; with a fixed camera, the camera's placement does. The base is
//! held and reported; a camera's mounting is the tool frame's (the tool point is not estimated
//! when cameras are the only observations), and what of the last link it cannot tell from the
//! mounting the rank-revealing solve holds and reports.
//!
//! Distances are unchanged when everything moves rigidly: they cannot see the base placement
//! (all 6 parameters), which is held at its nominal value and reported as such. Plane contacts
//! place the robot relative to the planes, which absorb the base: it is held too; and a plane
//! cannot see motions within it (translations along it, rotation about its normal), which the
//! rank-revealing solve then finds among the robot's parameters (the first joint's offset for a
//! horizontal table): each plane is reported with what it cannot see. Contacts alone cannot see
//! the scale either: every length of the robot and every plane offset multiplied by one factor
//! leaves every contact; the robot's longest nominal length is then held (the robot's scale is
//! its nominal one), and said so. (Holding a plane's offset instead is not enough: the robot
//! can shrink onto the planes, its first joint's `d` carrying it there, and fit every contact.)
//! A distance fixes the scale. Coordinates and markers see the measuring frame: with them the
//! base is estimated, as far as they see it (a height alone sees its z, roll and pitch; the
//! rank-revealing solve holds the rest and says so).
//!
//! # Extending
//!
//! A new kind is a prediction `f_k` of the tool's frames at its poses and of set-up parameters,
//! with its derivatives `g_kj` (6-vectors: position, rotation vector) and `df_k/ds`: one arm of
//! `predict`. Observations are one row each, so that `V` is a column of variances and every
//! estimator applies unchanged. A camera's view ([`camera`]) is six rows, one observation each
//! sharing the view: like a pose's coordinates, their correlation through the joint noise of
//! their common pose is left out of `V` (exact when the joints are exact). A target point's
//! pixel (2 rows) would be the same. Several chains (a torso, two arms and a head camera) are
//! [`tree`](super::tree)'s: a camera's view with both its frames on branches.

pub mod camera;
mod covariance;
mod data;
mod feasible;

use camera::relative_view;

pub use feasible::calibrate_kinds_feasible;
pub(super) use feasible::residual_noise;

pub use camera::{CameraSite, Frame, Role};
pub use data::{
    DEFAULT_CAMERA_SIGMA_DEG, DEFAULT_CAMERA_SIGMA_MM, DEFAULT_SIGMA_ANGLE_DEG, DEFAULT_SIGMA_MM, KindData,
    Observation, RowSigmaDefaults,
};
pub(crate) use data::{check_sessions, join_sessions};

use super::noise_check::{CHECK_POSES, at_estimate, check, without_outliers};
use super::{
    CalibrationError, FLAG_AT, FarOut, Gauge, Held, JointParams, Loss, RobustFit, Scored, Unseen, Warning,
    fold, gauge_class, probe_mounting, why_held,
};
use crate::estimation::reml::{Components, Point};
use crate::estimation::{
    Blocks, Estimator, Linearisation, MeasurementClass, NoiseEstimate, NoiseLayout, POSE_SIGMAS, PointRows,
    PriorEntry, PriorRows, RANK_TOLERANCE, Reduced, RefineOptions, Refined, Residuals, Weights,
    length_per_radian, linearise, prior_sds, refine_from,
};
use crate::kinematics::{
    Chain, ChainAt, HeldArm, JointTrig, MarkerEnd, Measured, end_positions_trig, joint_sin_cos,
    marker_jacobians_held,
};
use crate::model::{
    Joint, ParamOwner, ParamSet, Placement, RobotModel, Selection, SelectionError, Tool, name_matches,
};
use nalgebra::{DMatrix, DMatrixViewMut, DVector, Isometry3, Matrix3, UnitQuaternion, Vector3, Vector6};
use rayon::prelude::*;
use std::borrow::Cow;
use std::ops::Range;
use std::sync::{Arc, OnceLock};

/// Every pose's joints' `(sin q_j, cos q_j)` ([`joint_sin_cos`]), made once by the first
/// problem that walks the poses and shared by those [`KindProblem::reselect`] makes; `None`
/// where a pose has not the chains' number of joints.
type SharedTrig = Arc<OnceLock<Option<Vec<(f64, f64)>>>>;

/// How to calibrate from distances, contacts, coordinates, cameras and markers on a serial
/// arm, or from the views of a tree ([`calibrate_tree`](super::tree::calibrate_tree)): one
/// options type for every kind and shape. A tree has no tool point, markers nor registration:
/// those fields are not used for it, `joint_noise` is over the tree's joints and
/// `per_session` names cameras' and targets' placements (`target.l_hand.*`).
#[derive(Debug, Clone, PartialEq)]
pub struct KindOptions {
    /// The estimator; the weighted ones use `V_k` of the [module](self).
    pub estimator: Estimator,
    /// `Sigma_q` (dof x dof; rad², mm²), if the joint noise is known; the measurement noise
    /// is each observation's own sigma.
    pub joint_noise: Option<DMatrix<f64>>,
    /// The joint parameters to identify.
    pub joints: JointParams,
    /// Estimate the tool point on the last link.
    pub estimate_tool: bool,
    /// Estimate the base where the data see it (markers, coordinates), registered on the
    /// markers first (`--fixed-base` clears it: the measuring frame is the model's base frame).
    pub estimate_base: bool,
    /// Estimate the markers' positions on the last link (`--fixed-markers` clears it).
    pub estimate_markers: bool,
    /// The tool point's nominal position (mm) in the model's marker frame; unused when a
    /// camera's views are the only observations (the camera's or target's mounting is then in
    /// the marker frame itself).
    pub tool: Vector3<f64>,
    /// The markers' nominal positions (mm) in the model's marker frame, the `k`-th marker
    /// number `k + 1` (`--marker`); missing ones start at its origin. Used only with marker observations.
    pub markers: Vec<Vector3<f64>>,
    /// Marker 1's frame on the last link (in the model's marker frame), where it is known (a
    /// model's tool frame, scored as it stands): a 6-DOF probe's frame starts there. `None`: at
    /// its nominal position, turned by the chordal mean of what each pose says the rotation is
    /// (`R_arm(q)^-1 R_measured`).
    pub probe: Option<Placement>,
    /// Gauss-Newton settings.
    pub refine: RefineOptions,
    /// Set-up parameters (names or patterns of [`SetUp::base_names`]: `point1.zero`,
    /// `target.*`) with one value per session ([`KindData::sessions`]), estimated: an
    /// instrument re-zeroed or moved between sessions.
    pub per_session: Vec<String>,
    /// Prior standard deviations of the robot's parameters about the nominal model (maximum a
    /// posteriori, [`PriorRows`]): they apply to those `joints` asks for; empty: none.
    pub prior: Vec<PriorEntry>,
    /// The loss of each pose's whitened residuals, all observations made at it together
    /// ([`robust`](super::robust)).
    pub loss: Loss,
    /// The user's say in the gauge: parameters held (the robot's or the set-up's), parameters
    /// kept free first.
    pub gauge: Gauge,
}

impl Default for KindOptions {
    /// Weighted least squares without joint noise, every joint parameter, the tool point
    /// estimated at the origin of the marker frame, no markers, no per-session parameter.
    fn default() -> Self {
        Self {
            estimator: Estimator::Wls,
            joint_noise: None,
            joints: JointParams::All,
            estimate_tool: true,
            estimate_base: true,
            estimate_markers: true,
            tool: Vector3::zeros(),
            markers: Vec::new(),
            probe: None,
            refine: RefineOptions::default(),
            per_session: Vec::new(),
            prior: Vec::new(),
            loss: Loss::Squared,
            gauge: Gauge::default(),
        }
    }
}

/// The set-up's parameters: fixed points and planes, each 3 numbers; the cameras and targets of
/// views, each 6 ([`camera`]).
#[derive(Debug, Clone, PartialEq)]
pub struct SetUp {
    /// The number of fixed points (their coordinates are values, mm, base frame).
    pub points: usize,
    /// The planes: the nominal normal `n0` and two tangents `t1, t2` of each.
    bases: Vec<[Vector3<f64>; 3]>,
    /// Where the camera is, if there is one camera on a serial arm.
    camera: Option<CameraSite>,
    /// The views' cameras and targets, 6 parameters each: a serial arm's camera and target
    /// ([`SetUp::with_camera`]), or a tree's ([`SetUp::with_views`]).
    views: Vec<Frame>,
    /// The tree's branches' tip links, naming its frames; empty for a serial arm.
    tips: Vec<String>,
    /// Whether the coordinates (x, y, z) are read in a device frame of their own (with
    /// markers: a height gauge's, placed in the markers' measuring frame).
    device: bool,
    /// Whether the markers are read in a tracker frame of each session's own (`tracker.*`,
    /// the first session's the measuring frame itself): a tracker moved between sessions.
    tracker: bool,
    /// Whether distances between poses have a length zero (`pair.zero`).
    pair_zero: bool,
    /// The sessions' names (one per data file; empty: one session).
    sessions: Vec<String>,
    /// The parameters (of the one-session layout) with one value per session.
    per_session: Vec<usize>,
}

impl SetUp {
    /// `points` fixed points and a plane of each nominal unit normal `n0` of `normals`, its
    /// tangents `t1 = n0 x e / |n0 x e|` (`e` the x axis, the y axis if `n0` is near x) and
    /// `t2 = n0 x t1`.
    pub fn new(points: usize, normals: &[Vector3<f64>]) -> Self {
        let bases = normals
            .iter()
            .map(|n| {
                let n = n.normalize();
                let helper = if n.x.abs() < 0.9 { Vector3::x() } else { Vector3::y() };
                let t1 = n.cross(&helper).normalize();
                [n, t1, n.cross(&t1)]
            })
            .collect();
        Self {
            points,
            bases,
            camera: None,
            views: Vec::new(),
            tips: Vec::new(),
            device: false,
            tracker: false,
            pair_zero: false,
            sessions: Vec::new(),
            per_session: Vec::new(),
        }
    }

    /// The same set-up with a length zero for distances between poses: 1 parameter more,
    /// `pair.zero` (mm), `f_k = |p_a - p_b| + zero`.
    pub fn with_pair_zero(self) -> Self {
        Self { pair_zero: true, ..self }
    }

    /// The same set-up over the sessions `names`, the parameters `per_session` (indices of the
    /// one-session layout, [`SetUp::names`] of a set-up without sessions) one per session: each
    /// after the first adds one value of each, after the one-session parameters
    /// ([`SetUp::slot`]).
    pub fn with_sessions(self, names: Vec<String>, per_session: Vec<usize>) -> Self {
        let per_session = if names.len() > 1 { per_session } else { Vec::new() };
        Self { sessions: names, per_session, ..self }
    }

    /// The parameters with one value per session (indices of the one-session layout).
    pub fn per_session(&self) -> &[usize] {
        &self.per_session
    }

    /// The number of sessions (at least 1).
    pub fn session_count(&self) -> usize {
        self.sessions.len().max(1)
    }

    /// The sessions' names.
    pub fn session_names(&self) -> &[String] {
        &self.sessions
    }

    /// Where parameter `i` (of the one-session layout) of session `session` is in the values:
    /// `i` itself for the first session and for parameters shared by every session; else after
    /// the one-session parameters, session by session.
    pub fn slot(&self, i: usize, session: usize) -> usize {
        match (session, self.per_session.iter().position(|&p| p == i)) {
            (1.., Some(k)) => self.base_len() + (session - 1) * self.per_session.len() + k,
            _ => i,
        }
    }

    /// The values of session `session` in the one-session layout, from the values `s` of every
    /// session.
    pub fn session_values(&self, s: &[f64], session: usize) -> Vec<f64> {
        (0..self.base_len()).map(|i| s[self.slot(i, session)]).collect()
    }

    /// The values of every session from the one-session values `s`: each session starts where
    /// `s` is.
    pub fn expand(&self, s: &[f64]) -> Vec<f64> {
        let extra = (1..self.session_count()).flat_map(|_| self.per_session.iter().map(|&i| s[i]));
        s.iter().copied().chain(extra).collect()
    }

    /// Fixed point `i`'s length zero (mm), `point<i>.zero`: `f_k = |p - c_i| + zero`.
    pub fn point_zero(&self, i: usize) -> usize {
        self.zeros_at() + i
    }

    /// The pairs' length zero (mm), `pair.zero`, if the set-up has one.
    pub fn pair_zero(&self) -> Option<usize> {
        self.pair_zero.then(|| self.zeros_at() + self.points)
    }

    /// The parameter of the one-session layout that value `i` is one session's value of.
    pub fn base_of(&self, i: usize) -> usize {
        match i.checked_sub(self.base_len()) {
            Some(k) => self.per_session[k % self.per_session.len().max(1)],
            None => i,
        }
    }

    /// Whether parameter `i` (of the one-session layout) is a length zero, held unless named.
    pub fn is_zero(&self, i: usize) -> bool {
        (self.zeros_at()..self.base_len()).contains(&i)
    }

    /// Where the length zeros start.
    fn zeros_at(&self) -> usize {
        self.tracker_at() + if self.tracker { 6 } else { 0 }
    }

    /// Where the tracker's parameters start.
    fn tracker_at(&self) -> usize {
        self.device_at() + if self.device { 6 } else { 0 }
    }

    /// The same set-up with a tracker frame per session: 6 parameters more, `tracker.x, y, z,
    /// rx, ry, rz`, the placement `P` of the session's tracker in the first session's measuring
    /// frame, a marker `m` read as `P^-1 m`. The first session's is the identity,
    /// always held ([`SetUp::is_fixed_frame`]): the base registration places that frame.
    pub fn with_tracker(self) -> Self {
        Self { tracker: true, ..self }
    }

    /// Whether value `i` is held by the layout itself: the first session's tracker placement,
    /// which the base registration stands for.
    pub fn is_fixed_frame(&self, i: usize) -> bool {
        self.tracker && (self.tracker_at()..self.tracker_at() + 6).contains(&i)
    }

    /// The parameters of one session.
    fn base_len(&self) -> usize {
        self.zeros_at() + self.points + usize::from(self.pair_zero)
    }

    /// The same set-up with a camera at `site` and its target: 12 parameters more,
    /// `camera.x, y, z, rx, ry, rz` then `target.*` ([`camera`]).
    pub fn with_camera(self, site: CameraSite) -> Self {
        Self { camera: Some(site), views: site.serial_frames().to_vec(), ..self }
    }

    /// The same set-up with the cameras and targets `frames` of a tree's views, 6 parameters
    /// each, named after the branches' tip links `tips` ([`Frame::name`]).
    pub fn with_views(self, frames: Vec<Frame>, tips: Vec<String>) -> Self {
        Self { views: frames, tips, ..self }
    }

    /// The cameras and targets of its views (a tree's, or a serial arm's camera and target).
    pub fn frames(&self) -> &[Frame] {
        &self.views
    }

    /// The tree's branches' tip links, naming its frames ([`Frame::name`]); empty for a serial
    /// arm.
    pub fn tips(&self) -> &[String] {
        &self.tips
    }

    /// Where the placements of the camera and the target of a view at `site` start, and the
    /// branch each is fixed to (`None`: placed in the base frame): a serial arm's camera and
    /// target are the set-up's first two frames ([`SetUp::with_camera`]), a tree's view names
    /// its own.
    ///
    /// # Panics
    /// If the set-up has no such frame.
    fn view_ends(&self, site: CameraSite) -> [(usize, Option<usize>); 2] {
        let frames = match site {
            CameraSite::Tree { camera, target } => [camera, target].map(usize::from),
            _ => [0, 1],
        };
        frames.map(|f| (self.camera_at() + 6 * f, self.views[f].on))
    }

    /// Where the camera is, if there is one.
    pub fn camera(&self) -> Option<CameraSite> {
        self.camera
    }

    /// The same set-up with the coordinates' device frame: 6 parameters more, `device.x, y, z,
    /// rx, ry, rz`, its placement in the measuring frame (a coordinate `c` is `e_c . D^-1 p`).
    pub fn with_device(self) -> Self {
        Self { device: true, ..self }
    }

    /// Whether the coordinates are read in a device frame of their own.
    pub fn device(&self) -> bool {
        self.device
    }

    /// Parameters: 3 per point, then 3 per plane (`alpha, beta, d`), then 6 for each camera
    /// and target of the views, then 6 for the coordinates' device, 6 for the markers' tracker,
    /// then each point's length
    /// zero and the pairs'; then, with sessions, the per-session ones of every session after
    /// the first ([`SetUp::slot`]).
    pub fn len(&self) -> usize {
        self.base_len() + (self.session_count() - 1) * self.per_session.len()
    }

    /// Where the device's parameters start.
    fn device_at(&self) -> usize {
        self.camera_at() + 6 * self.views.len()
    }

    /// Where the views' cameras' and targets' parameters start.
    fn camera_at(&self) -> usize {
        3 * (self.points + self.bases.len())
    }

    /// Whether parameter `i` is an angle (rad): a plane's tilts, a placement's rotation vector.
    pub fn is_angle(&self, i: usize) -> bool {
        if i >= self.base_len() {
            let k = self.per_session.len().max(1);
            return self.per_session.get((i - self.base_len()) % k).is_some_and(|&b| self.is_angle(b));
        }
        if i >= self.zeros_at() {
            return false;
        }
        match i.checked_sub(self.camera_at()) {
            Some(c) => c % 6 >= 3,
            None => i >= 3 * self.points && (i - 3 * self.points) % 3 < 2,
        }
    }

    /// The number of planes.
    pub fn planes(&self) -> usize {
        self.bases.len()
    }

    /// Whether the set-up has no parameters.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Names of the parameters: `point1.x`, ..., `plane1.alpha`, `plane1.beta`, `plane1.d`.
    pub fn names(&self) -> Vec<String> {
        let points = (1..=self.points).flat_map(|i| ["x", "y", "z"].map(|c| format!("point{i}.{c}")));
        let planes =
            (1..=self.bases.len()).flat_map(|i| ["alpha", "beta", "d"].map(|c| format!("plane{i}.{c}")));
        let frames = self.views.iter().map(|f| f.name(&self.tips));
        let devices = [("device", self.device), ("tracker", self.tracker)];
        let placements = (frames.chain(devices.into_iter().filter(|d| d.1).map(|d| d.0.to_string())))
            .flat_map(|f| ["x", "y", "z", "rx", "ry", "rz"].map(|c| format!("{f}.{c}")));
        let zeros = (1..=self.points).map(|i| format!("point{i}.zero"));
        let pair = self.pair_zero.then(|| "pair.zero".to_string());
        let base: Vec<String> = points.chain(planes).chain(placements).chain(zeros).chain(pair).collect();
        if self.per_session.is_empty() {
            return base;
        }
        let name = |i: usize, k: usize| format!("{}@{}", base[i], self.sessions[k]);
        let first =
            (0..base.len()).map(|i| if self.per_session.contains(&i) { name(i, 0) } else { base[i].clone() });
        let later = (1..self.sessions.len()).flat_map(|k| self.per_session.iter().map(move |&i| name(i, k)));
        first.chain(later).collect()
    }

    /// The names of the one-session layout (no session suffix): what `--per-session` and
    /// `--params` patterns match.
    pub fn base_names(&self) -> Vec<String> {
        Self { per_session: Vec::new(), ..self.clone() }.names()
    }

    /// Plane `i`'s unit normal and offset at the set-up values `s`:
    /// `n = (n0 + alpha t1 + beta t2) / |n0 + alpha t1 + beta t2|`.
    pub fn plane(&self, s: &[f64], i: usize) -> (Vector3<f64>, f64) {
        let at = 3 * (self.points + i);
        let [n0, t1, t2] = self.bases[i];
        ((n0 + t1 * s[at] + t2 * s[at + 1]).normalize(), s[at + 2])
    }

    /// `dn/dalpha` and `dn/dbeta` of plane `i`: `(I - n n^T) t / |v|`.
    fn normal_derivatives(&self, s: &[f64], i: usize) -> [Vector3<f64>; 2] {
        let at = 3 * (self.points + i);
        let [n0, t1, t2] = self.bases[i];
        let v = n0 + t1 * s[at] + t2 * s[at + 1];
        let n = v.normalize();
        [t1, t2].map(|t| (t - n * n.dot(&t)) / v.norm())
    }

    /// Fixed point `i` at the set-up values `s`.
    fn point(&self, s: &[f64], i: usize) -> Vector3<f64> {
        Vector3::new(s[3 * i], s[3 * i + 1], s[3 * i + 2])
    }
}

/// One observation's residual `y_k` (of its prediction `f_k`), the derivatives `g_kj` of `f_k`
/// with respect to each point-and-pose `j` it reads (`(j, g)`, one or two: a point at two poses,
/// or two points at one) and with respect to the set-up (`(index, value)`).
#[derive(Clone, Copy, Default)]
struct Prediction {
    residual: f64,
    by_point: [(usize, Vector6<f64>); 2],
    poses: usize,
    by_setup: [(usize, f64); 12],
    setups: usize,
}

/// The points' frames indexed by point-and-pose (`point * poses + pose`): all of them (a
/// slice), or those one block of observations reads ([`BlockFrames`]).
trait Frames: std::ops::Index<usize, Output = Isometry3<f64>> {}

impl Frames for [Isometry3<f64>] {}

/// `by_setup` of a [`Prediction`] of `n` derivatives.
fn by_setup<const N: usize>(derivatives: [(usize, f64); N]) -> ([(usize, f64); 12], usize) {
    let mut out = [(0, 0.0); 12];
    out[..N].copy_from_slice(&derivatives);
    (out, N)
}

/// Row `axis` of the frame `T = frames[pose]` read in a frame `D` placed by the set-up values
/// `s[at..at + 6]` (a device's, a tracker's): the row of the view `D^-1 T` ([`relative_view`])
/// against the `measured` view (position mm, rotation vector rad; a position row reads its own
/// coordinate only), its derivatives by the point's twist and by the placement.
fn placed_row<F: Frames + ?Sized>(
    at: usize,
    s: &[f64],
    (frames, point): (&F, usize),
    axis: usize,
    measured: &Vector6<f64>,
) -> Prediction {
    let (frame, by_placement) = camera::placed(&s[at..at + 6]);
    let view = relative_view(measured, &frame, &frames[point]);
    let by_frame = view.by_a * by_placement;
    let (by_setup, setups) = by_setup(std::array::from_fn::<_, 6, _>(|i| (at + i, by_frame[(axis, i)])));
    Prediction {
        residual: view.residual[axis],
        by_point: [(point, view.by_b.row(axis).transpose()), (0, Vector6::zeros())],
        poses: 1,
        by_setup,
        setups,
    }
}

/// `f_k` of the [module](self) and its derivatives, at the points' frames `frames` (their
/// rotations used by angles and views only), of which observation `o` reads `seen`
/// ([`KindProblem::seen`]: its point at its pose, at a pair's two poses, or a view's camera's
/// and target's). The derivatives `g_kj` are with respect to the pose error of point-and-pose
/// `j`: its position (mm), then its rotation vector (rad, measuring frame), as
/// [`ChainAt::identification_jacobian`] gives them.
fn predict<F: Frames + ?Sized>(
    o: &Observation,
    (frames, seen): (&F, [usize; 2]),
    setup: &SetUp,
    s: &[f64],
) -> Prediction {
    let none = (0, Vector6::zeros());
    let point = |g: Vector3<f64>| Vector6::new(g.x, g.y, g.z, 0.0, 0.0, 0.0);
    let p = |j: usize| frames[j].translation.vector;
    let none_s = by_setup([]);
    let [at, other] = seen;
    match *o {
        Observation::Distance { .. } => {
            let (a, b) = (at, other);
            // f = |p_a - p_b| + zero: df/dzero = 1.
            let d = p(a) - p(b);
            let u = d / d.norm().max(f64::MIN_POSITIVE);
            let (zero, (by_setup, setups)) = match setup.pair_zero() {
                Some(z) => (s[z], by_setup([(z, 1.0)])),
                None => (0.0, none_s),
            };
            Prediction {
                residual: o.residual(d.norm() + zero),
                by_point: [(a, point(u)), (b, point(-u))],
                poses: 2,
                by_setup,
                setups,
            }
        }
        Observation::ToPoint { point: fixed, .. } => {
            // f = |p - c| + zero: df/dc = -u, df/dzero = 1.
            let d = p(at) - setup.point(s, fixed);
            let u = d / d.norm().max(f64::MIN_POSITIVE);
            let (c, z) = (3 * fixed, setup.point_zero(fixed));
            let (by_setup, setups) = by_setup([(c, -u.x), (c + 1, -u.y), (c + 2, -u.z), (z, 1.0)]);
            Prediction {
                residual: o.residual(d.norm() + s[z]),
                by_point: [(at, point(u)), none],
                poses: 1,
                by_setup,
                setups,
            }
        }
        Observation::Coordinate { axis, measured, .. } if axis < 3 && setup.device => {
            // In the device's frame D: the row of the view D^-1 T of the point's frame T.
            placed_row(setup.device_at(), s, (frames, at), axis, &Vector6::ith(axis, measured))
        }
        Observation::Marker { axis, measured, .. } if setup.tracker => {
            // Read in the session's tracker frame P: the row of the view P^-1 T.
            placed_row(setup.tracker_at(), s, (frames, at), axis, &Vector6::ith(axis, measured))
        }
        Observation::Orientation { axis, measured, .. } => {
            orientation_prediction((frames, at), (axis, &measured), setup, s)
        }
        Observation::Coordinate { axis, .. } | Observation::Marker { axis, .. } if axis < 3 => Prediction {
            residual: o.residual(p(at)[axis]),
            by_point: [(at, Vector6::ith(axis, 1.0)), none],
            poses: 1,
            by_setup: none_s.0,
            setups: 0,
        },
        Observation::Coordinate { axis, .. } | Observation::Marker { axis, .. } => {
            // A marker's axis is below 3 ([`KindData::check`]).
            let (rpy, rates) = angles(&frames[at].rotation);
            let g = rates.row(axis - 3);
            Prediction {
                residual: o.residual(rpy[axis - 3]),
                by_point: [(at, Vector6::new(0.0, 0.0, 0.0, g[0], g[1], g[2])), none],
                poses: 1,
                by_setup: none_s.0,
                setups: 0,
            }
        }
        Observation::Contact { plane, .. } => contact_prediction(o, (p(at), at), plane, setup, s),
        Observation::Camera { axis, view, site, .. } => {
            camera_rows((frames, seen), (&view, site), setup, s)[axis]
        }
    }
}

/// Row `axis` of a probe's measured orientation `R_m` of the frame `T = frames[pose]`:
/// `y = log(R_m R^T)`, the rotation row of the view of `T` from the measuring frame
/// ([`relative_view`]), whose derivative by the frame's rotation vector is `J_r^-1(y)`
/// (`I` to first order in `y`). Read in a session's tracker frame `P`, the view `P^-1 T`
/// ([`placed_row`]).
fn orientation_prediction<F: Frames + ?Sized>(
    (frames, point): (&F, usize),
    (axis, measured): (usize, &UnitQuaternion<f64>),
    setup: &SetUp,
    s: &[f64],
) -> Prediction {
    let r = measured.scaled_axis();
    let view = Vector6::new(0.0, 0.0, 0.0, r.x, r.y, r.z);
    if setup.tracker {
        return placed_row(setup.tracker_at(), s, (frames, point), 3 + axis, &view);
    }
    let seen = relative_view(&view, &Isometry3::identity(), &frames[point]);
    Prediction {
        residual: seen.residual[3 + axis],
        by_point: [(point, seen.by_b.row(3 + axis).transpose()), (0, Vector6::zeros())],
        poses: 1,
        by_setup: by_setup([]).0,
        setups: 0,
    }
}

/// A contact of the tool point `p` (point-and-pose `pose`) with plane `plane`, its signed distance
/// `f = n . p - d` (0 measured) and its derivatives: `n` by the point, `dn/dalpha . p`,
/// `dn/dbeta . p` and `-1` by the plane's tilts and offset.
fn contact_prediction(
    o: &Observation,
    (p, pose): (Vector3<f64>, usize),
    plane: usize,
    setup: &SetUp,
    s: &[f64],
) -> Prediction {
    let (n, d) = setup.plane(s, plane);
    let [dn_a, dn_b] = setup.normal_derivatives(s, plane);
    let at = 3 * (setup.points + plane);
    let (by_setup, setups) = by_setup([(at, dn_a.dot(&p)), (at + 1, dn_b.dot(&p)), (at + 2, -1.0)]);
    Prediction {
        residual: o.residual(n.dot(&p) - d),
        by_point: [(pose, Vector6::new(n.x, n.y, n.z, 0.0, 0.0, 0.0)), (0, Vector6::zeros())],
        poses: 1,
        by_setup,
        setups,
    }
}

/// The six rows of the view `view` (at `site`) between the camera's frame `A` and the
/// target's `B` ([`camera`]'s model): each mounted on its tip's frame (`frames[seen[0]]`, the
/// camera's; `frames[seen[1]]`, the target's) or placed in the base frame
/// ([`camera::view_end`]), the set-up values `s` their placements; row `axis`'s derivatives the
/// row of `S_A` by `E_T` (by the camera's tip) and by `E_C` or `E_W` (by its own placement),
/// and `B`'s likewise. The frames, their derivatives and the relative view are computed once
/// for the six.
fn camera_rows<F: Frames + ?Sized>(
    (frames, seen): (&F, [usize; 2]),
    (view, site): (&Vector6<f64>, CameraSite),
    setup: &SetUp,
    s: &[f64],
) -> [Prediction; 6] {
    let ends = setup.view_ends(site);
    let slots = ends.map(|(slot, _)| slot);
    let [a, b] = [0, 1].map(|e| {
        let tip = ends[e].1.map(|_| &frames[seen[e]]);
        camera::view_end(tip, &s[slots[e]..slots[e] + 6])
    });
    let v = relative_view(view, &a.0, &b.0);
    std::array::from_fn(|axis| {
        let rows = [v.by_a.row(axis).transpose(), v.by_b.row(axis).transpose()];
        let mut f = Prediction { residual: v.residual[axis], setups: 12, ..Prediction::default() };
        for (e, (_, by_tip, by_own)) in [&a, &b].into_iter().enumerate() {
            if let Some(by_tip) = by_tip {
                f.by_point[f.poses] = (seen[e], by_tip.tr_mul(&rows[e]));
                f.poses += 1;
            }
            let by_own = by_own.tr_mul(&rows[e]);
            for i in 0..6 {
                f.by_setup[6 * e + i] = (slots[e] + i, by_own[i]);
            }
        }
        f
    })
}

/// The rows of the last camera view predicted, kept for the view's other rows
/// ([`camera_rows`] gives all six at once): `key`, what they are a function of within one
/// evaluation (the frames and the set-up values being its own): the points read, the site,
/// the measured view and the session.
#[derive(Default)]
struct ViewMemo {
    key: Option<([usize; 2], CameraSite, [u64; 6], usize)>,
    rows: [Prediction; 6],
}

/// Roll, pitch and yaw of `r` (`R = Rz(yaw) Ry(pitch) Rx(roll)`) and their derivatives with
/// respect to its rotation vector in the measuring frame (`dR = [omega]x R`): `E^-1`, with
/// `omega = E (roll', pitch', yaw')` and
/// `E = [cos(yaw) cos(pitch), -sin(yaw), 0; sin(yaw) cos(pitch), cos(yaw), 0; -sin(pitch), 0, 1]`;
/// zero at pitch +-90 deg, where roll and yaw are one angle.
fn angles(r: &UnitQuaternion<f64>) -> (Vector3<f64>, Matrix3<f64>) {
    let (roll, pitch, yaw) = r.euler_angles();
    let (sy, cy, sp, cp) = (yaw.sin(), yaw.cos(), pitch.sin(), pitch.cos());
    let e = Matrix3::new(cy * cp, -sy, 0.0, sy * cp, cy, 0.0, -sp, 0.0, 1.0);
    (Vector3::new(roll, pitch, yaw), e.try_inverse().unwrap_or_else(Matrix3::zeros))
}

/// The most observations one block `V_k` holds: a pose's rows beyond it start another block
/// (their correlation with the first ones left out), so that the stacked blocks stay
/// `N_m x 64` at most whatever a file holds. Every kind robocal reads has at most 6 rows per
/// pose, or 3 per marker.
pub const MAX_BLOCK: usize = 64;

/// The points of a problem's rows: each run of consecutive observations made at one pose (the
/// first pose of a pair) is one block `V_k` of at most [`MAX_BLOCK`] rows, so that the joint
/// noise they share is kept; a pose's observations are consecutive in every file robocal reads.
pub fn pose_blocks(observations: &[Observation]) -> Blocks {
    let mut sizes: Vec<usize> = Vec::new();
    let mut last = None;
    for o in observations {
        match (last == Some(o.pose()), sizes.last_mut()) {
            (true, Some(n)) if *n < MAX_BLOCK => *n += 1,
            _ => sizes.push(1),
        }
        last = Some(o.pose());
    }
    Blocks::from_sizes(sizes)
}

/// The calibration problem of distances and contacts: `y_k(x, s) = m_k - f_k(x, s)` for the
/// selected robot parameters `x` and set-up parameters `s` (others held), one row per
/// observation, `V_k` of the [module](self) computed once at the start. Its points on the last
/// link are one chain each: the markers' (in the order of their numbers), then the tool's; or,
/// on a tree, each branch's tip ([`KindProblem::of_branches`]).
#[derive(Debug, Clone)]
pub struct KindProblem<'a> {
    chains: &'a [Chain],
    /// The markers' numbers less one, of the chains in order; the tool point's chain follows.
    markers: Vec<usize>,
    /// Whether the chains are a tree's branches, each its own arm ([`Chain::on_tree`]), not
    /// points on one arm's last link.
    branches: bool,
    /// Whether an observation sees point `i` at pose `j` (`used[i * poses + j]`): the others
    /// are not computed.
    used: Vec<bool>,
    selection: &'a Selection,
    data: &'a KindData,
    setup: &'a SetUp,
    fixed: Vec<f64>,
    setup_values: Vec<f64>,
    setup_selection: Vec<usize>,
    /// The observations of each pose, one block `V_k` each ([`pose_blocks`]).
    blocks: Blocks,
    /// The blocks `V_k`, shared by the problems [`KindProblem::reselect`] makes.
    v: Option<Arc<DMatrix<f64>>>,
    /// What the chains' ends are ([`KindProblem::measured`]), found once: every row asks.
    measured: Measured,
    /// The points' arm steps no selected parameter moves, undone at each pose once for every
    /// linearisation ([`KindProblem::held`]).
    held: OnceLock<Option<Arc<Vec<HeldArm>>>>,
    /// Each pose's joints' sines and cosines ([`joint_sin_cos`]), computed at the first walk
    /// of the points and shared by the problems [`KindProblem::reselect`] makes: the walks of
    /// the points turn the joints by the angle-sum identity ([`KindProblem::joint_trig`]).
    trig: SharedTrig,
}

impl<'a> KindProblem<'a> {
    /// The problem of `data` on `chain` (a point chain, or a frame for angles and cameras),
    /// the robot parameters at `fixed` (full vector) and the set-up at `setup_values`,
    /// estimating `selection` and the set-up parameters `setup_selection`. With
    /// `joint_noise`, `V_k` includes the joint noise of each of the observation's poses; the
    /// measurement sigmas always.
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        chain: &'a Chain,
        selection: &'a Selection,
        data: &'a KindData,
        setup: &'a SetUp,
        fixed: Vec<f64>,
        setup_values: Vec<f64>,
        setup_selection: Vec<usize>,
        joint_noise: Option<&DMatrix<f64>>,
    ) -> Self {
        let chains = std::slice::from_ref(chain);
        let problem =
            Self::of_points(chains, &[], selection, data, setup, fixed, setup_values, setup_selection);
        problem.with_noise(joint_noise)
    }

    /// The problem of [`KindProblem::new`] with several points on the last link: `chains`,
    /// one per point sharing their parameters ([`Chain::markers`]), the markers numbered
    /// `markers` (less one, ascending; [`KindData::markers`]) first, then the tool point if
    /// any observation is of it.
    #[allow(clippy::too_many_arguments)]
    pub fn of_points(
        chains: &'a [Chain],
        markers: &[usize],
        selection: &'a Selection,
        data: &'a KindData,
        setup: &'a SetUp,
        fixed: Vec<f64>,
        setup_values: Vec<f64>,
        setup_selection: Vec<usize>,
    ) -> Self {
        let values = (fixed, setup_values, setup_selection);
        Self::on_chains(chains, (markers.to_vec(), false), (selection, data, setup), values)
    }

    /// The problem of views between the frames of a tree (camera observations at
    /// [`CameraSite::Tree`]): `chains` each branch's tip's ([`Chain::on_tree`]: all at the
    /// tree's parameters and joints), the rest as of [`KindProblem::of_points`], the values
    /// `(fixed, setup_values, setup_selection)`.
    pub fn of_branches(
        chains: &'a [Chain],
        selection: &'a Selection,
        data: &'a KindData,
        setup: &'a SetUp,
        values: (Vec<f64>, Vec<f64>, Vec<usize>),
    ) -> Self {
        Self::on_chains(chains, (Vec::new(), true), (selection, data, setup), values)
    }

    /// The problem on `chains`: points on one arm's last link (`markers` first), or a tree's
    /// branches; its frames are points alone ([`Measured::Position`]) when every chain ends at a
    /// point on one arm and no observation is an angle.
    pub(super) fn on_chains(
        chains: &'a [Chain],
        (markers, branches): (Vec<usize>, bool),
        (selection, data, setup): (&'a Selection, &'a KindData, &'a SetUp),
        (fixed, setup_values, setup_selection): (Vec<f64>, Vec<f64>, Vec<usize>),
    ) -> Self {
        let points = !branches && chains.iter().all(Chain::ends_at_a_point) && !data.has_angles();
        let measured = if points { Measured::Position } else { Measured::Pose };
        let mut problem = Self {
            measured,
            chains,
            markers,
            branches,
            used: Vec::new(),
            selection,
            data,
            setup,
            fixed,
            setup_values,
            setup_selection,
            blocks: pose_blocks(&data.observations),
            v: None,
            held: OnceLock::new(),
            trig: Arc::default(),
        };
        problem.used = problem.points_used();
        problem
    }

    /// Whether an observation sees each point-and-pose ([`KindProblem::seen`]).
    fn points_used(&self) -> Vec<bool> {
        let mut used = vec![false; self.chains.len() * self.data.joints.len()];
        for o in &self.data.observations {
            for n in self.seen(o) {
                if let Some(u) = used.get_mut(n) {
                    *u = true;
                }
            }
        }
        used
    }

    /// The length one radian of an angle counts as under ordinary least squares (mm/rad): the
    /// noise's `w = sqrt(mean_l V_ll / mean_a V_aa)` of `V_k`'s diagonal over the length rows
    /// `l` and the angle rows `a` ([`length_per_radian`]; with exact joints, `sigma_length /
    /// sigma_angle`; with every sigma assumed, [`POSE_SIGMAS`]' ratio, which
    /// `KindData::with_ols_sigmas` gives the angles); [`POSE_SIGMAS`]' ratio without `V_k`.
    fn angle_weight(&self) -> f64 {
        let fixed = POSE_SIGMAS.0 / POSE_SIGMAS.1;
        let Some(v) = self.v.as_deref() else { return fixed };
        let rows = (self.blocks.ranges(self.data.observations.len()))
            .flat_map(|range| range.clone().map(move |r| (r, r - range.start)))
            .map(|(r, column)| (self.data.observations[r].is_angle(), v[(r, column)]));
        match length_per_radian(rows) {
            w if w.is_finite() && w > 0.0 => w,
            _ => fixed,
        }
    }

    /// The same problem with `V_k` computed at its values, with `joint_noise` if given.
    pub fn with_noise(mut self, joint_noise: Option<&DMatrix<f64>>) -> Self {
        self.v = Some(Arc::new(self.covariance_blocks(joint_noise)));
        self
    }

    /// The chain (point) of observation `o`: its marker's, else the tool's, after the markers.
    fn point_of(&self, o: &Observation) -> usize {
        match o.marker() {
            Some(marker) => self.markers.iter().position(|&m| m == marker).expect("a marker of the problem"),
            None => self.markers.len(),
        }
    }

    /// The chain of the tip of branch `b` (a view's camera's or target's): a tree's branch's
    /// own; a serial arm's one branch ends at the tool, after the markers.
    fn chain_of_branch(&self, b: usize) -> usize {
        if self.branches { b } else { self.markers.len() }
    }

    /// The points (`point * poses + pose`, as [`KindProblem::frames`] lays them out) that
    /// observation `o` reads: its point at its pose, at both of a pair's, or a view's camera's
    /// and target's tips (one placed in the base frame reads none: the other's twice).
    fn seen(&self, o: &Observation) -> [usize; 2] {
        let poses = self.data.joints.len();
        match *o {
            Observation::Distance { a, b, .. } => [a, b].map(|j| self.point_of(o) * poses + j),
            Observation::Camera { pose, site, .. } => {
                let ends = self.setup.view_ends(site);
                let [camera, target] = ends.map(|(_, on)| on.map(|b| self.chain_of_branch(b) * poses + pose));
                let either = camera.or(target).unwrap_or(pose);
                [camera.unwrap_or(either), target.unwrap_or(either)]
            }
            _ => [self.point_of(o) * poses + o.pose(); 2],
        }
    }

    /// The frame of every point at every pose, point by point (`frames[i * poses + j]`), at the
    /// parameters `at`, those no observation sees left at the identity; with `blocks`, the
    /// `H_j` (`rows x columns`, column-major) of those some observation sees, packed in their
    /// order ([`KindProblem::slots`]): a noise check's sample of a few poses holds theirs alone.
    fn frames(&self, at: &[ChainAt], blocks: Option<(&mut [f64], usize)>) -> Vec<Isometry3<f64>> {
        let poses = self.data.joints.len();
        let (measured, rows) = (self.measured(), self.measured().rows());
        let columns = self.selection.len();
        let frame = |n: usize| (&at[n / poses], &self.data.joints[n % poses]);
        match blocks {
            Some((blocks, block)) if block > 0 => {
                let seen: Vec<usize> = (0..self.used.len()).filter(|&n| self.used[n]).collect();
                let computed: Vec<Isometry3<f64>> = (blocks.par_chunks_mut(block).zip(seen.par_iter()))
                    .map(|(h_j, &n)| {
                        let (at, q) = frame(n);
                        let view = DMatrixViewMut::from_slice(h_j, rows, columns);
                        at.identification_jacobian(q, self.selection, measured, view);
                        at.pose(q)
                    })
                    .collect();
                let mut frames = vec![Isometry3::identity(); self.used.len()];
                for (&n, f) in seen.iter().zip(computed) {
                    frames[n] = f;
                }
                frames
            }
            _ if measured == Measured::Position => {
                // Points alone: every point of a pose from one walk of the arm they share.
                self.trig_table();
                let points = at.len();
                let mut flat = vec![Vector3::zeros(); poses * points];
                (flat.par_chunks_mut(points).enumerate())
                    .for_each(|(j, chunk)| end_positions_trig(at, self.joint_trig(j), chunk));
                (0..points * poses)
                    .map(|n| match self.used[n] {
                        true => Isometry3::from_parts(
                            flat[(n % poses) * points + n / poses].into(),
                            Default::default(),
                        ),
                        false => Isometry3::identity(),
                    })
                    .collect()
            }
            _ => (0..at.len() * poses)
                .into_par_iter()
                .map(|n| match self.used[n] {
                    true => frame(n).0.pose(frame(n).1),
                    false => Isometry3::identity(),
                })
                .collect(),
        }
    }

    /// Where each point-and-pose `n` (`point * poses + pose`) has its `H_j` among those packed
    /// by [`KindProblem::frames`]: the number of points seen before it, `slot_n = sum_{m < n}
    /// used_m` (for one seen, its place).
    fn slots(&self) -> Vec<usize> {
        let mut next = 0;
        (self.used.iter())
            .map(|&u| {
                let slot = next;
                next += usize::from(u);
                slot
            })
            .collect()
    }

    /// The set-up values `s` of every session, each in the one-session layout.
    fn session_views(&self, s: &[f64]) -> Vec<Vec<f64>> {
        (0..self.setup.session_count()).map(|k| self.setup.session_values(s, k)).collect()
    }

    /// [`predict`] of `o` in its pose's session, from that session's values of `views`
    /// ([`KindProblem::session_views`]); its set-up derivatives by slot of every session's
    /// values. A camera's row from `memo`, the view's six rows computed at its first.
    fn predict<F: Frames + ?Sized>(
        &self,
        o: &Observation,
        frames: &F,
        views: &[Vec<f64>],
        memo: &mut ViewMemo,
    ) -> Prediction {
        let k = self.data.session_of(o.pose()).min(views.len() - 1);
        let seen = self.seen(o);
        let mut f = match *o {
            Observation::Camera { axis, view, site, .. } => {
                let key = Some((seen, site, std::array::from_fn(|i| view[i].to_bits()), k));
                if memo.key != key {
                    memo.rows = camera_rows((frames, seen), (&view, site), self.setup, &views[k]);
                    memo.key = key;
                }
                memo.rows[axis]
            }
            _ => predict(o, (frames, seen), self.setup, &views[k]),
        };
        for (i, _) in &mut f.by_setup[..f.setups] {
            *i = self.setup.slot(*i, k);
        }
        f
    }

    /// The same problem estimating other parameters from other values, sharing `V_k`.
    pub fn reselect<'b>(
        &self,
        selection: &'b Selection,
        fixed: Vec<f64>,
        setup_values: Vec<f64>,
        setup_selection: Vec<usize>,
    ) -> KindProblem<'b>
    where
        'a: 'b,
    {
        let held = OnceLock::new();
        KindProblem { selection, fixed, setup_values, setup_selection, held, ..self.clone() }
    }

    /// Every pose's joints' `(sin q_j, cos q_j)`, pose after pose ([`joint_sin_cos`]),
    /// computed at the first call and shared by the problems [`KindProblem::reselect`] makes;
    /// `None` if a pose has not the chains' number of joints (the walk then fails as it would
    /// without them). Called before a parallel walk of the poses, so that the table is made
    /// on every thread, not by one task while the others wait for it.
    fn trig_table(&self) -> Option<&[(f64, f64)]> {
        let dof = self.chains[0].dof();
        let trig = self.trig.get_or_init(|| {
            let every = self.data.joints.iter().all(|q| q.len() == dof);
            every.then(|| joint_sin_cos(&self.data.joints))
        });
        trig.as_deref()
    }

    /// Pose `pose`'s joint values with their sines and cosines ([`JointTrig::with`], from
    /// [`KindProblem::trig_table`]); plain without the table.
    fn joint_trig(&self, pose: usize) -> JointTrig<'_> {
        let dof = self.chains[0].dof();
        let q = &self.data.joints[pose];
        match self.trig_table() {
            Some(trig) => JointTrig::with(q, &trig[pose * dof..(pose + 1) * dof]),
            None => JointTrig::plain(q),
        }
    }

    /// The points' arm steps that no selected parameter moves, undone at every pose
    /// ([`HeldArm`]), found at the first linearisation and kept for the problem's others, as
    /// a marker file's problem keeps them: the parameters it does not select are fixed, so
    /// those steps are the same at any `x`. `at`: the point chains at the current `x`; `None`
    /// for one point, or nothing to hold.
    fn held(&self, at: &[ChainAt]) -> Option<&[HeldArm]> {
        let held = self.held.get_or_init(|| {
            let from = at.first().filter(|_| at.len() > 1 && !self.branches)?.held_from(self.selection)?;
            let chain = self.chains[0].with_errors(&self.fixed);
            Some(Arc::new(self.data.joints.par_iter().map(|q| chain.held_arm(q, from)).collect()))
        });
        held.as_deref().map(Vec::as_slice)
    }

    /// How the noise enters the rows, for feasible GLS ([`residual_samples`]): each pose
    /// block's joint-noise Jacobian, its observations' rows `g_kj^T J_kj` by the distinct poses
    /// `j` they see, side by side (a distance between two poses sees both), at the problem's
    /// values; each observation's measurement class among those present, which are returned
    /// in order ([`Observation::class`]).
    ///
    /// [`residual_samples`]: crate::estimation::residual_samples
    pub(crate) fn noise_layout(&self) -> (NoiseLayout, Vec<MeasurementClass>) {
        let present = self.data.classes();
        let classes = (self.data.observations.iter())
            .map(|o| present.iter().position(|&c| c == o.class()).expect("present"))
            .collect();
        let (mut jacobians, dof) = (self.noise_jacobians(), self.chains[0].dof());
        without_unmoved_joints(&mut jacobians, dof);
        (NoiseLayout { jacobians, dof, classes, class_count: present.len() }, present)
    }

    /// What the chains' ends are: points ([`Measured::Position`]) or, for angles and cameras,
    /// frames ([`Measured::Pose`]; with markers, the points' frames, their rotation the last
    /// link's).
    pub fn measured(&self) -> Measured {
        self.measured
    }

    /// The full robot parameter vector and the set-up values at `x`.
    pub fn full(&self, x: &DVector<f64>) -> (Vec<f64>, Vec<f64>) {
        let mut full = self.fixed.clone();
        for (&i, &v) in self.selection.indices().iter().zip(x.iter()) {
            full[i] = v;
        }
        let mut s = self.setup_values.clone();
        for (&i, &v) in self.setup_selection.iter().zip(x.iter().skip(self.selection.len())) {
            s[i] = v;
        }
        (full, s)
    }

    /// The estimated parameters' values: where iterations start.
    pub fn start(&self) -> DVector<f64> {
        let robot = self.selection.indices().iter().map(|&i| self.fixed[i]);
        DVector::from_iterator(
            self.parameters(),
            robot.chain(self.setup_selection.iter().map(|&i| self.setup_values[i])),
        )
    }

    /// The residuals `y_k` at `x` (mm).
    pub fn residuals(&self, x: &DVector<f64>) -> DVector<f64> {
        self.evaluate(x, None)
    }
}

impl Residuals for KindProblem<'_> {
    fn rows_per_point(&self) -> usize {
        1
    }

    fn equations(&self) -> usize {
        self.data.observations.len()
    }

    fn parameters(&self) -> usize {
        self.selection.len() + self.setup_selection.len()
    }

    fn blocks(&self) -> Blocks {
        self.blocks.clone()
    }

    fn covariance(&self) -> Option<&DMatrix<f64>> {
        self.v.as_deref()
    }

    /// Angles (rad) count as lengths for ordinary least squares: times the noise's
    /// `w = sigma_length / sigma_angle` (`KindProblem::angle_weight`, mm/rad), so that an
    /// angle's row weighs as the noise makes it whatever the units.
    fn ols_row_scale(&self) -> Option<Vec<f64>> {
        let observations = &self.data.observations;
        observations.iter().any(Observation::is_angle).then(|| {
            let w = self.angle_weight();
            observations.iter().map(|o| if o.is_angle() { w } else { 1.0 }).collect()
        })
    }

    fn names(&self) -> Vec<String> {
        let setup = self.setup.names();
        let robot = self.selection.indices().iter().map(|&i| self.chains[0].params().get(i).name.clone());
        robot.chain(self.setup_selection.iter().map(|&i| setup[i].clone())).collect()
    }

    /// `y_k` at `x` and with `h` the rows `H_k = sum_j g_kj^T H_j + df_k/ds`
    /// (`KindProblem::observation_row`), from the `H_j` of the points some observation sees
    /// (a sample of a few poses holds theirs alone, not every pose's).
    fn evaluate(&self, x: &DVector<f64>, h: Option<&mut DMatrix<f64>>) -> DVector<f64> {
        let (full, s) = self.full(x);
        let at: Vec<ChainAt> = self.chains.iter().map(|c| c.with_errors(&full)).collect();
        let rows = self.measured().rows();
        // Each seen point's H_j at each pose (rows x columns, column-major) in one buffer,
        // filled in parallel.
        let block = if h.is_some() { rows * self.selection.len() } else { 0 };
        let seen = self.used.iter().filter(|&&u| u).count();
        let mut jacobians = vec![0.0; if block > 0 { block * seen } else { 0 }];
        let frames = self.frames(&at, Some((&mut jacobians, block)));
        let slots = if block > 0 { self.slots() } else { Vec::new() };
        let views = self.session_views(&s);
        let mut y = DVector::zeros(self.equations());
        let at = PointsAt { views: &views, jacobians: Jacobians::All(&frames, &jacobians, &slots), block };
        let Some(h) = h else {
            // The residuals alone: each its own, in parallel.
            let residuals = y.as_mut_slice().par_iter_mut().enumerate();
            residuals.for_each_init(ViewMemo::default, |memo, (k, y_k)| {
                *y_k = self.observation_row(k, at, None, memo);
            });
            return y;
        };
        let (mut row, mut memo) = (vec![0.0; self.parameters()], ViewMemo::default());
        for k in 0..self.data.observations.len() {
            y[k] = self.observation_row(k, at, Some(&mut row), &mut memo);
            row.iter().enumerate().for_each(|(c, &v)| h[(k, c)] = v);
        }
        y
    }

    /// Each pose's observations built, whitened and reduced into the triangular factor in one
    /// go (`Reduced::reduce`), `H` never held: the default's whole system, to rounding. The
    /// frames and `H_j` a block reads are computed as it is reduced (`BlockJacobians`: a
    /// point's position from the walk that gives its `H_j`), not held for every point at every
    /// pose.
    fn linearise_whitened(&self, x: &DVector<f64>, weights: &Weights) -> (DVector<f64>, Reduced) {
        let rows = self.rows_at(x);
        let mut y = DVector::zeros(self.equations());
        let (layout, p) = (self.blocks(), self.parameters());
        let reduced = Reduced::reduce(
            &layout,
            p,
            weights.noise(),
            y.as_mut_slice(),
            || rows.scratch(),
            |scratch, point, out| {
                let r = layout.range(point);
                let (h, y) = out.split_at_mut(p * r.len());
                rows.point(scratch, point, r, h, y);
                weights.apply_point(point, out);
            },
        );
        (y, reduced)
    }
}

impl KindProblem<'_> {
    /// The rows at `x` point by point ([`RowsAt`]): its chains with the errors of `x` and its
    /// sessions' set-up values, the joints' sines and cosines and the held steps found here,
    /// on every thread, not by the first block's task while the others wait.
    fn rows_at(&self, x: &DVector<f64>) -> RowsAt<'_, '_> {
        let (full, s) = self.full(x);
        let chains: Vec<ChainAt> = self.chains.iter().map(|c| c.with_errors(&full)).collect();
        if self.measured() == Measured::Position {
            self.trig_table();
            if !self.selection.is_empty() {
                self.held(&chains);
            }
        }
        let block = self.measured().rows() * self.selection.len();
        RowsAt { problem: self, views: self.session_views(&s), chains, block }
    }
}

/// A problem's rows `H_k` and residuals `y_k` at one `x`, built point by point where they are
/// needed (a linearisation's reduction, the variance components' samples), `H` never held:
/// each point's frames and `H_j` from one walk ([`BlockJacobians`]).
struct RowsAt<'a, 'p> {
    problem: &'a KindProblem<'p>,
    /// Each session's set-up values.
    views: Vec<Vec<f64>>,
    /// The chains with the errors of `x`.
    chains: Vec<ChainAt>,
    /// The numbers of one `H_j`.
    block: usize,
}

impl PointRows for RowsAt<'_, '_> {
    /// A row of `H`, a block's `H_j` and the views' memo.
    type Scratch = (Vec<f64>, BlockJacobians, ViewMemo);

    fn shape(&self) -> (usize, usize) {
        (self.problem.equations(), self.problem.parameters())
    }

    fn scratch(&self) -> Self::Scratch {
        (vec![0.0; self.problem.parameters()], BlockJacobians::default(), ViewMemo::default())
    }

    fn point(
        &self,
        scratch: &mut Self::Scratch,
        _: usize,
        range: Range<usize>,
        h: &mut [f64],
        y: &mut [f64],
    ) {
        let (row, jacobians, memo) = scratch;
        jacobians.fill(self.problem, &self.chains, range.clone(), self.block);
        let at = PointsAt { views: &self.views, jacobians: Jacobians::Block(jacobians), block: self.block };
        let n = range.len();
        for (i, k) in range.enumerate() {
            y[i] = self.problem.observation_row(k, at, Some(row), memo);
            row.iter().enumerate().for_each(|(c, &v)| h[c * n + i] = v);
        }
    }
}

/// The `H_j` (`rows x columns`, column-major) of the points at the poses that one block of
/// observations reads, by their index `point * poses + pose`; its buffers reused block after
/// block.
#[derive(Default)]
struct BlockJacobians {
    keys: Vec<usize>,
    values: Vec<f64>,
    /// The frame of each key's point at its pose.
    frames: Vec<Isometry3<f64>>,
    /// Of points alone: the poses of the block, every point's `H_j` at one of them stacked
    /// 3 rows a point (column-major), and their positions.
    poses: Vec<usize>,
    stacked: Vec<f64>,
    positions: Vec<Vector3<f64>>,
    /// Of points alone, for `V_k`: every point's manipulator Jacobian and pose at one pose,
    /// and the walk's scratch ([`crate::kinematics::points_manipulator`]).
    manipulators: Vec<nalgebra::Matrix6xX<f64>>,
    ends: Vec<Isometry3<f64>>,
    walked: Vec<Vector3<f64>>,
}

impl BlockJacobians {
    /// Compute the frames and the `H_j` of the observations `range` of `problem` at the
    /// parameters `at` (`block` numbers each).
    fn fill(
        &mut self,
        problem: &KindProblem<'_>,
        at: &[ChainAt],
        range: std::ops::Range<usize>,
        block: usize,
    ) {
        self.keys.clear();
        for o in &problem.data.observations[range] {
            self.keys.extend(problem.seen(o));
        }
        self.keys.sort_unstable();
        self.keys.dedup();
        // Zeros: `identification_jacobian` leaves the columns of no step untouched.
        self.values.clear();
        self.values.resize(self.keys.len() * block, 0.0);
        self.frames.clear();
        let (poses, rows, columns) =
            (problem.data.joints.len(), problem.measured().rows(), problem.selection.len());
        if problem.measured() == Measured::Position {
            return self.fill_points(problem, at, columns);
        }
        for (k, &n) in self.keys.iter().enumerate() {
            let (at, q) = (&at[n / poses], &problem.data.joints[n % poses]);
            if block > 0 {
                let view =
                    DMatrixViewMut::from_slice(&mut self.values[k * block..(k + 1) * block], rows, columns);
                at.identification_jacobian(q, problem.selection, problem.measured(), view);
            }
            self.frames.push(at.pose(q));
        }
    }

    /// [`BlockJacobians::fill`] of points alone (markers and the tool point, no frame): every
    /// point of a pose from one walk of the arm they share, from its held steps on
    /// ([`marker_jacobians_held`], [`KindProblem::held`]), each needed one's 3 rows copied out.
    fn fill_points(&mut self, problem: &KindProblem<'_>, at: &[ChainAt], columns: usize) {
        let held = if columns > 0 { problem.held(at) } else { None };
        let (poses, points) = (problem.data.joints.len(), at.len());
        self.poses.clear();
        self.poses.extend(self.keys.iter().map(|n| n % poses));
        self.poses.sort_unstable();
        self.poses.dedup();
        self.stacked.resize(3 * points * columns, 0.0);
        self.positions.resize(points, Vector3::zeros());
        self.frames.resize(self.keys.len(), Isometry3::identity());
        for &pose in &self.poses {
            let q = problem.joint_trig(pose);
            match columns {
                // No robot parameter: the points' positions alone.
                0 => end_positions_trig(at, q, &mut self.positions),
                _ => {
                    // Zeros: `marker_jacobians_held` writes the columns of its parameters only.
                    self.stacked.fill(0.0);
                    let h = DMatrixViewMut::from_slice(&mut self.stacked, 3 * points, columns);
                    let held = held.map(|held| &held[pose]);
                    marker_jacobians_held(at, q, problem.selection, h, &mut self.positions, held);
                }
            }
            for (k, &n) in self.keys.iter().enumerate().filter(|(_, n)| *n % poses == pose) {
                let at = 3 * (n / poses);
                self.frames[k] = Isometry3::from_parts(self.positions[n / poses].into(), Default::default());
                let h_j = &mut self.values[3 * columns * k..3 * columns * (k + 1)];
                for (c, column) in h_j.chunks_exact_mut(3).enumerate() {
                    column.copy_from_slice(&self.stacked[3 * points * c + at..3 * points * c + at + 3]);
                }
            }
        }
    }

    /// The frame of point-and-pose `n`, one of those filled.
    fn frame(&self, n: usize) -> &Isometry3<f64> {
        &self.frames[self.keys.binary_search(&n).expect("a point the block reads")]
    }

    /// The `H_j` of point-and-pose `n`, one of those filled.
    fn get(&self, n: usize, block: usize) -> &[f64] {
        let i = self.keys.binary_search(&n).expect("a point the block reads");
        &self.values[i * block..(i + 1) * block]
    }
}

/// Where an observation's row reads its points' frames and `H_j`: every point's at every
/// pose, or a block's.
#[derive(Clone, Copy)]
enum Jacobians<'f> {
    /// Every point at every pose: the frames (point by point, then pose by pose), the `H_j` of
    /// those seen, `block` numbers each, and where each one's is ([`KindProblem::slots`]).
    All(&'f [Isometry3<f64>], &'f [f64], &'f [usize]),
    /// Those one block reads.
    Block(&'f BlockJacobians),
}

impl Jacobians<'_> {
    /// The `H_j` of point-and-pose `n` (`block` numbers).
    fn of(&self, n: usize, block: usize) -> &[f64] {
        match self {
            // No robot parameter estimated: no `H_j`, nor their places.
            Self::All(..) if block == 0 => &[],
            Self::All(_, all, slots) => &all[slots[n] * block..(slots[n] + 1) * block],
            Self::Block(some) => some.get(n, block),
        }
    }
}

/// The points' frames at the poses a block reads, indexed by point-and-pose.
struct BlockFrames<'f> {
    block: &'f BlockJacobians,
}

impl std::ops::Index<usize> for BlockFrames<'_> {
    type Output = Isometry3<f64>;

    fn index(&self, n: usize) -> &Isometry3<f64> {
        self.block.frame(n)
    }
}

impl Frames for BlockFrames<'_> {}

/// Every point at every pose, as an observation's row reads it
/// ([`KindProblem::observation_row`]).
#[derive(Clone, Copy)]
struct PointsAt<'f> {
    /// Each session's set-up values.
    views: &'f [Vec<f64>],
    /// Each point's `H_j` at each pose (or those of one block), `block` numbers each
    /// (column-major).
    jacobians: Jacobians<'f>,
    /// The numbers of one `H_j`: 0 when no robot parameter is estimated.
    block: usize,
}

impl KindProblem<'_> {
    /// Observation `k`'s residual `y_k`, and with `h` its row of `H` written over it (one
    /// number a column): `H_k = sum_j g_kj^T H_j + df_k/ds`, from every point at every pose
    /// (`at`); a camera's view's rows through `memo`.
    fn observation_row(
        &self,
        k: usize,
        PointsAt { views, jacobians, block }: PointsAt<'_>,
        h: Option<&mut [f64]>,
        memo: &mut ViewMemo,
    ) -> f64 {
        let o = &self.data.observations[k];
        let (columns, rows) = (self.selection.len(), self.measured().rows());
        let f = match jacobians {
            Jacobians::All(frames, ..) => self.predict(o, frames, views, memo),
            Jacobians::Block(block) => self.predict(o, &BlockFrames { block }, views, memo),
        };
        let Some(h) = h else { return f.residual };
        h.fill(0.0);
        for &(n, g) in &f.by_point[..f.poses] {
            let h_j = jacobians.of(n, block);
            if let (1, Some(axis)) = (f.poses, unit_axis(&g, rows)) {
                // One coordinate of one point (a marker's): `g^T H_j` is row `axis` of `H_j`,
                // `0 + (0 + h_axis)` to the bit as the sum below gives it.
                for (c, column) in h_j.chunks_exact(rows).enumerate() {
                    h[c] += column[axis] + 0.0;
                }
                continue;
            }
            for (c, column) in h_j.chunks_exact(rows).enumerate() {
                h[c] += (0..rows).map(|r| g[r] * column[r]).sum::<f64>();
            }
        }
        for &(i, d) in &f.by_setup[..f.setups] {
            if let Some(c) = self.setup_selection.iter().position(|&e| e == i) {
                h[columns + c] += d;
            }
        }
        f.residual
    }
}

/// The noise Jacobians `jacobians` (each block's, `dof` columns per pose it sees) with the
/// columns of every joint that moves no observation zeroed: those whose largest entry is below
/// `1e-9` of the largest of any joint's, rounding alone (a tree's torso joint under a head
/// camera looking at a hand moves both frames alike). Its variance is then left unestimated.
fn without_unmoved_joints(jacobians: &mut [DMatrix<f64>], dof: usize) {
    let largest = |jacobians: &[DMatrix<f64>], t: usize| {
        let columns =
            |j: &DMatrix<f64>| (t..j.ncols()).step_by(dof).map(|c| j.column(c).amax()).fold(0.0, f64::max);
        jacobians.iter().map(columns).fold(0.0, f64::max)
    };
    let each: Vec<f64> = (0..dof).map(|t| largest(jacobians, t)).collect();
    let overall = each.iter().copied().fold(0.0, f64::max);
    for t in (0..dof).filter(|&t| each[t] <= 1e-9 * overall) {
        for j in jacobians.iter_mut() {
            for c in (t..j.ncols()).step_by(dof) {
                j.column_mut(c).fill(0.0);
            }
        }
    }
}

/// The axis `a` where `g`'s first `rows` entries are the unit vector `e_a` (`g_a = 1`, every
/// other `0`), if they are: then `g^T H_j` is row `a` of `H_j`.
fn unit_axis(g: &Vector6<f64>, rows: usize) -> Option<usize> {
    let axis = (0..rows).find(|&r| g[r] == 1.0)?;
    (0..rows).all(|r| r == axis || g[r] == 0.0).then_some(axis)
}

/// A robot calibrated by the one pipeline: a serial arm ([`KindCalibration`], its observations
/// points and frames on its tip) or a tree ([`TreeCalibration`](super::tree::TreeCalibration),
/// its views between frames on its branches). `R` is the robot as calibrated; everything else
/// is the same for both.
#[derive(Debug, Clone)]
pub struct Calibration<R> {
    /// The robot as calibrated: the estimates folded in (an arm's tool point calibrated; a
    /// tree's base not folded, which a view never sees).
    pub calibrated: R,
    /// The robot's parameters (a tree's: the base's, then each joint's once).
    pub params: ParamSet,
    /// Robot parameter errors after the set-up and the tool point (with markers, the base and
    /// the markers too) fitted with the robot's joints nominal ("before"; a tree's: all zero).
    pub before: Vec<f64>,
    /// Robot parameter errors after the full calibration ("after").
    pub after: Vec<f64>,
    /// The set-up ([`SetUp::names`]): its definition, and its values before and after.
    pub setup: SetUp,
    /// The set-up values, before and after.
    pub setup_values: (Vec<f64>, Vec<f64>),
    /// The refined estimate (names, values, covariance, diagnostics).
    pub refined: Refined,
    /// What the measurements cannot see as a whole, by kind: held and reported.
    pub unseen: Vec<Unseen>,
    /// What was held and why: by `--hold`, unmoved, combinations the poses cannot tell apart.
    pub fixed: Vec<Held>,
    /// The training observations scored, before and after.
    pub training: Score,
    /// The markers' numbers less one ([`KindData::markers`]), and each one's calibrated
    /// position (mm) as the calibrated model's tool point is given (the last joint's frame).
    pub markers: Vec<(usize, Vector3<f64>)>,
    /// When no observation gave its sigma and the joints are exact: the variance of unit
    /// weight `f` of the residuals, by which the covariance and the whitening are scaled
    /// (standard errors from the residuals' spread); `None` when the sigmas were given.
    pub variance_factor: Option<f64>,
    /// With markers (and the base estimated): where their rigid registration placed the base
    /// (the measuring frame to the robot's), which the `base.*` estimates correct.
    pub registered_base: Option<Placement>,
    /// A 6-DOF probe's calibrated frame, absolute, in the model's
    /// [marker frame](RobotModel::marker_frame) (a URDF's tip link, else the last joint's
    /// frame): `F^-1 T`, `F` that frame and `T` the calibrated tool frame; `None` without a
    /// probe.
    pub tip_frame: Option<Placement>,
    pub(super) joint_noise: Option<DMatrix<f64>>,
    /// One chain per point: the markers', then the tool's if observed; or a tree's branches'.
    pub(super) chains: Vec<Chain>,
    /// Whether the chains are a tree's branches ([`Chain::on_tree`]).
    pub(super) branches: bool,
    /// No robot parameter: the selection of a problem that scores.
    pub(super) nothing: Selection,
    /// With a robust loss: each observation's final weight and how the reweighting went.
    pub robust: Option<RobustFit>,
    /// The prior standard deviation of each robot parameter (infinite: none).
    pub prior_sd: Vec<f64>,
    /// What to look at, one per cause: joint lengths corrected by more than 10 mm, training
    /// observations far out.
    pub warnings: Vec<Warning>,
    /// Feasible GLS ([`calibrate_kinds_feasible`]): the noise estimated from the residuals,
    /// the joints' and each measurement class's, with which the calibration was weighted.
    pub noise_estimate: Option<NoiseEstimate>,
    /// Feasible GLS: whether its variance components settled.
    pub noise_settled: Option<bool>,
}

/// A serial arm calibrated from its observation files.
pub type KindCalibration = Calibration<RobotModel>;

/// One observation scored: its residual `m_k - f_k` before and after (mm; rad for an angle),
/// and after whitened by `sqrt(V_k)`.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct ObservationResidual {
    /// Its line in the file.
    pub line: usize,
    /// `distance`, `point`, `contact`, `x` ... `yaw`, `marker x` ... `marker z`, `camera x` ...
    /// `camera rz`.
    pub kind: &'static str,
    /// The marker's number (1, 2, ...), for a marker's coordinate.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub marker: Option<usize>,
    /// The residual before calibration, in [`unit`](Self::unit).
    pub before: f64,
    /// After, in [`unit`](Self::unit).
    pub after: f64,
    /// The unit of `before` and `after`: `mm`, or `deg` for an angle (a camera's `rx`, a
    /// `roll`).
    pub unit: &'static str,
    /// After, divided by its standard deviation `sqrt(V_k)`.
    pub whitened: f64,
}

/// A set of observations scored: each one, and the RMS residuals before and after of the
/// lengths (mm) and of the angles (deg, if any).
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize)]
pub struct Score {
    /// Every observation, in order.
    pub observations: Vec<ObservationResidual>,
    /// RMS of the length residuals (mm), before and after.
    pub lengths: (f64, f64),
    /// RMS of the angle residuals (deg), before and after, if angles were measured.
    pub angles: Option<(f64, f64)>,
    /// RMS of the marker positions' errors (mm), before and after, if markers were measured:
    /// `sqrt(3 sum e_c^2 / n)` over the `n` measured coordinates `e_c`, the RMS of the
    /// position errors `|e|` when every coordinate is measured (as `calibrate` reports it).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub markers: Option<(f64, f64)>,
    /// Each group's RMS residuals before and after ([`Observation::group`]: distances, probe
    /// orientations, camera rotations, ...), in its unit, but the markers' (their positions'
    /// RMS is [`Score::markers`]).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub by_group: Vec<GroupRms>,
    /// With several markers, each one's position RMS before and after (mm), as
    /// [`Score::markers`] takes it of all: a marker coming loose stands out.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub by_marker: Vec<MarkerRms>,
    /// Each marker's position error at each pose, as a marker file's pose table gives it
    /// ([`PositionError`]), in the order of the observations.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub positions: Vec<PositionError>,
    /// Each camera view (a camera's or a tree's, its rows together), in the order of the
    /// observations: the norms of its position and rotation residuals ([`ViewResidual`]).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub views: Vec<ViewResidual>,
    /// RMS of the views' position residual norms `|y_t|` (mm), before and after, if views
    /// were scored.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub view_position: Option<(f64, f64)>,
    /// RMS of the views' rotation residual norms `|y_r|` (deg), before and after, if their
    /// rotations were measured.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub view_rotation: Option<(f64, f64)>,
    /// With per-session set-up parameters: each session of the set and where its set-up came
    /// from.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub sessions: Vec<(String, SessionSetUp)>,
    /// The whitened residual beyond which an observation is flagged, as a marker file's pose
    /// is: [`FLAG_AT`] standard deviations times the set's robust spread when above 1,
    /// `max(1, median |z_k| / sqrt(median chi^2(1)))` ([`Score::flagged`]): when every
    /// observation lies further out than its `V_k` says (a noise given too small), one is
    /// flagged only if it stands out from the others.
    pub flag_at: f64,
}

/// One group's RMS residuals in a set of several ([`Score::by_group`]).
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct GroupRms {
    /// The group: `distances`, `coordinates`, `camera rotations`, ... ([`Observation::group`]).
    pub group: &'static str,
    /// `mm`, or `deg` for angles.
    pub unit: &'static str,
    /// The RMS residual before and after, in `unit`.
    pub rms: (f64, f64),
    /// Its observations.
    pub count: usize,
    /// The largest residual's size before and after, in `unit`.
    pub max: (f64, f64),
    /// Its observations flagged after calibration (beyond [`Score::flag_at`]).
    pub flagged: usize,
}

/// One marker's position RMS in a set of several markers ([`Score::by_marker`]).
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct MarkerRms {
    /// The marker's number (1, 2, ...).
    pub marker: usize,
    /// Its coordinates measured.
    pub coordinates: usize,
    /// The RMS of its positions' errors before and after (mm).
    pub rms: (f64, f64),
}

/// One marker's position error at one pose ([`Score::positions`]): the norm of its measured
/// coordinates' residuals, `|e| = sqrt(sum e_c^2)` (mm), before and after, and of their
/// whitened residuals, `sqrt(sum z_c^2)` (each by its own variance, the pose's correlations
/// left out).
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct PositionError {
    /// The index of its first coordinate among the set's observations.
    pub index: usize,
    /// Its line in the file.
    pub line: usize,
    /// The marker's number (1, 2, ...).
    pub marker: usize,
    /// Its coordinates measured (3, or fewer where a cell was empty).
    pub coordinates: usize,
    /// `|e|` before and after (mm).
    pub error: (f64, f64),
    /// `sqrt(sum z_c^2)` after.
    pub whitened: f64,
}

/// One camera view scored ([`Score::views`]): the norms of its position residuals `|y_t|`
/// (mm) and of its rotation residuals `|y_r|` (deg), before and after, and its largest
/// whitened residual after.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct ViewResidual {
    /// The index of its first row among the set's observations.
    pub index: usize,
    /// Its line in the file.
    pub line: usize,
    /// `|y_t|` before (mm).
    pub before_mm: f64,
    /// `|y_t|` after (mm).
    pub after_mm: f64,
    /// `|y_r|` before (deg), if rotations were measured.
    pub before_deg: Option<f64>,
    /// `|y_r|` after (deg), if rotations were measured.
    pub after_deg: Option<f64>,
    /// After, the largest of its rows' residuals divided by its standard deviation (`sqrt`
    /// of `V_k`'s diagonal).
    pub whitened: f64,
}

/// The [`ViewResidual`]s of `observations` (of the observations `kinds`): each run of a
/// camera's rows from its first axis on one line.
fn view_residuals(observations: &[ObservationResidual], kinds: &[Observation]) -> Vec<ViewResidual> {
    let mut views: Vec<ViewResidual> = Vec::new();
    // Sums of squares of the position's and the rotation's rows here, their roots below.
    let mut squares: Vec<[f64; 4]> = Vec::new();
    for (index, (r, o)) in observations.iter().zip(kinds).enumerate() {
        let Observation::Camera { axis, .. } = *o else { continue };
        if axis == 0 || views.last().is_none_or(|v| v.line != r.line) {
            let (before_deg, after_deg) = (None, None);
            let whitened = 0.0;
            views.push(ViewResidual {
                index,
                line: r.line,
                before_mm: 0.0,
                after_mm: 0.0,
                before_deg,
                after_deg,
                whitened,
            });
            squares.push([0.0; 4]);
        }
        let (v, sum) = (views.last_mut().expect("pushed"), squares.last_mut().expect("pushed"));
        let at = if axis < 3 { 0 } else { 2 };
        sum[at] += r.before * r.before;
        sum[at + 1] += r.after * r.after;
        v.whitened = v.whitened.max(r.whitened.abs());
        if axis >= 3 {
            (v.before_deg, v.after_deg) = (Some(0.0), Some(0.0));
        }
    }
    for (v, sum) in views.iter_mut().zip(&squares) {
        (v.before_mm, v.after_mm) = (sum[0].sqrt(), sum[1].sqrt());
        if v.after_deg.is_some() {
            (v.before_deg, v.after_deg) = (Some(sum[2].sqrt()), Some(sum[3].sqrt()));
        }
    }
    views
}

/// The RMS of `views`' position norms (mm) and, where every view has them, rotation norms
/// (deg), before and after; `None` without views.
#[allow(clippy::type_complexity)]
fn view_rms(views: &[ViewResidual]) -> (Option<(f64, f64)>, Option<(f64, f64)>) {
    if views.is_empty() {
        return (None, None);
    }
    let rms = |f: fn(&ViewResidual) -> f64| {
        (views.iter().map(|v| f(v).powi(2)).sum::<f64>() / views.len() as f64).sqrt()
    };
    let position = (rms(|v| v.before_mm), rms(|v| v.after_mm));
    let rotation = views
        .iter()
        .all(|v| v.after_deg.is_some())
        .then(|| (rms(|v| v.before_deg.unwrap_or(0.0)), rms(|v| v.after_deg.unwrap_or(0.0))));
    (Some(position), rotation)
}

/// The [`PositionError`]s of `observations` (of the observations `kinds`): each run of
/// consecutive coordinates of one marker on one line.
fn position_errors(observations: &[ObservationResidual], kinds: &[Observation]) -> Vec<PositionError> {
    let mut positions: Vec<PositionError> = Vec::new();
    for (index, (r, o)) in observations.iter().zip(kinds).enumerate() {
        let Observation::Marker { marker, .. } = *o else { continue };
        let (line, marker) = (r.line, marker + 1);
        let same =
            |p: &PositionError| p.line == line && p.marker == marker && p.index + p.coordinates == index;
        if !positions.last().is_some_and(same) {
            positions.push(PositionError {
                index,
                line,
                marker,
                coordinates: 0,
                error: (0.0, 0.0),
                whitened: 0.0,
            });
        }
        let p = positions.last_mut().expect("pushed");
        p.coordinates += 1;
        // Sums of squares here, their roots below.
        p.error = (p.error.0 + r.before * r.before, p.error.1 + r.after * r.after);
        p.whitened += r.whitened * r.whitened;
    }
    for p in &mut positions {
        (p.error, p.whitened) = ((p.error.0.sqrt(), p.error.1.sqrt()), p.whitened.sqrt());
    }
    positions
}

/// Where a scored session's per-session set-up parameters come from.
#[derive(Debug, Clone, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
#[non_exhaustive]
pub enum SessionSetUp {
    /// The training session of this name (a training file of the same stem).
    Training(String),
    /// Fitted on the scored set alone, the robot held at its calibration.
    Fitted,
}

/// [`rms_of`] the residuals among `observations` of the observations `kinds` that are
/// `chosen`.
fn rms_where(
    observations: &[ObservationResidual],
    kinds: &[Observation],
    chosen: &dyn Fn(&Observation) -> bool,
    scale: f64,
) -> Option<(f64, f64)> {
    rms_of((observations.iter().zip(kinds)).filter(|(_, o)| chosen(o)).map(|(r, _)| r), scale)
}

/// The RMS of `residuals` before and after, each residual times `scale` (`sqrt 3` makes a
/// marker's coordinates' RMS its position's); `None` for none.
fn rms_of<'r>(
    residuals: impl Iterator<Item = &'r ObservationResidual> + Clone,
    scale: f64,
) -> Option<(f64, f64)> {
    let n = residuals.clone().count();
    let of = |f: fn(&ObservationResidual) -> f64| {
        (residuals.clone().map(|r| (f(r) * scale).powi(2)).sum::<f64>() / n as f64).sqrt()
    };
    (n > 0).then(|| (of(|r| r.before), of(|r| r.after)))
}

impl ObservationResidual {
    /// What it is, for a person: its kind, a marker's with its number (`marker 2 z`).
    pub fn label(&self) -> String {
        match self.marker {
            Some(m) => self.kind.replacen("marker", &format!("marker {m}"), 1),
            None => self.kind.to_string(),
        }
    }
}

impl Score {
    /// The RMS length error before and after (mm) of the observations `kinds` scored here:
    /// `sqrt(sum e_i^2 / sum s_i)` over the lengths, `s_i` each one's share of an error
    /// ([`Observation::error_share`]): a marker's position error `|e|` counts once, as a marker
    /// file's calibration counts it, a distance or a coordinate once.
    pub fn length_errors(&self, kinds: &[Observation]) -> (f64, f64) {
        let (mut before, mut after, mut errors) = (0.0, 0.0, 0.0);
        for (r, o) in self.observations.iter().zip(kinds).filter(|(_, o)| !o.is_angle()) {
            (before, after, errors) =
                (before + r.before * r.before, after + r.after * r.after, errors + o.error_share());
        }
        let rms = |sum: f64| if errors > 0.0 { (sum / errors).sqrt() } else { 0.0 };
        (rms(before), rms(after))
    }

    /// The same residuals of `data` whitened by `V_k f`, each whitened residual over `sqrt(f)`,
    /// and what is summed from them again.
    pub(super) fn whitened_by(self, f: f64, data: &KindData) -> Self {
        let scale = f.sqrt();
        let mut observations = self.observations;
        observations.iter_mut().for_each(|r| r.whitened /= scale);
        Self { observations, ..self }.flagged_anew(&data.observations)
    }

    /// `data`'s residuals before and after (`y`), and after whitened (`z`).
    /// `variances`: each observation's (the diagonal of its `V_k`).
    pub(super) fn new(
        data: &KindData,
        (before, after): (&DVector<f64>, &DVector<f64>),
        variances: &[f64],
    ) -> Self {
        let observations: Vec<ObservationResidual> = (data.observations.par_iter().enumerate())
            .map(|(k, o)| {
                // The residuals of angles are in radians: reported in degrees, as every angle.
                let (scale, unit) = if o.is_angle() { (1f64.to_degrees(), "deg") } else { (1.0, "mm") };
                ObservationResidual {
                    line: data.lines[k],
                    kind: o.kind(),
                    marker: o.marker().map(|m| m + 1),
                    before: before[k] * scale,
                    after: after[k] * scale,
                    unit,
                    whitened: after[k] / variances[k].sqrt(),
                }
            })
            .collect();
        Self::of(observations, &data.observations)
    }

    /// The RMS residuals of `observations`, of the observations `kinds`.
    pub(super) fn of(observations: Vec<ObservationResidual>, kinds: &[Observation]) -> Self {
        let rms = |chosen: &dyn Fn(&Observation) -> bool, scale: f64| {
            rms_where(&observations, kinds, chosen, scale)
        };
        let lengths = rms(&|o| !o.is_angle(), 1.0).unwrap_or((0.0, 0.0));
        let angles = rms(&Observation::is_angle, 1.0);
        let markers = rms(&|o| matches!(o, Observation::Marker { .. }), 3f64.sqrt());
        // A set, ascending: a few numbers among every coordinate's.
        let numbers: std::collections::BTreeSet<usize> =
            observations.iter().filter_map(|r| r.marker).collect();
        let by_marker = match numbers.len() > 1 {
            true => (numbers.into_iter())
                .filter_map(|m| {
                    // Its position's coordinates (not a probe's orientation).
                    let of =
                        |o: &Observation| matches!(*o, Observation::Marker { marker, .. } if marker + 1 == m);
                    let coordinates = kinds.iter().filter(|o| of(o)).count();
                    let rms = rms(&of, 3f64.sqrt())?;
                    Some(MarkerRms { marker: m, coordinates, rms })
                })
                .collect(),
            false => Vec::new(),
        };
        #[rustfmt::skip]
        let score = Self {
            observations, lengths, angles, markers, by_group: Vec::new(), by_marker, positions: Vec::new(),
            views: Vec::new(), view_position: None, view_rotation: None, sessions: Vec::new(), flag_at: 0.0,
        };
        score.flagged_anew(kinds)
    }

    /// The same score with what its whitened residuals decide found again: where it flags
    /// ([`Score::flag_at`]), each group's row (its count flagged), the marker positions (their
    /// whitened norms). The RMS residuals do not change with the whitening: kept.
    fn flagged_anew(self, kinds: &[Observation]) -> Self {
        let observations = &self.observations;
        let mut groups: Vec<(&'static str, bool)> = Vec::new();
        for o in kinds {
            if !groups.iter().any(|g| g.0 == o.group()) {
                groups.push((o.group(), o.is_angle()));
            }
        }
        let whitened: Vec<f64> = observations.iter().map(|r| r.whitened.abs()).collect();
        let flag_at = FLAG_AT * super::robust::robust_scale(&whitened, 1).max(1.0);
        // Every group's, the markers' coordinates aside (their positions' RMS is `markers`).
        let by_group = (groups.into_iter().filter(|g| g.0 != "markers"))
            .filter_map(|(group, angle)| {
                let unit = if angle { "deg" } else { "mm" };
                let rms = rms_where(observations, kinds, &|o| o.group() == group, 1.0)?;
                let members = || (observations.iter().zip(kinds)).filter(|(_, o)| o.group() == group);
                let max = members().fold((0.0, 0.0), |m: (f64, f64), (r, _)| {
                    (m.0.max(r.before.abs()), m.1.max(r.after.abs()))
                });
                let (count, flagged) =
                    (members().count(), members().filter(|(r, _)| r.whitened.abs() > flag_at).count());
                Some(GroupRms { group, unit, rms, count, max, flagged })
            })
            .collect();
        let positions = position_errors(observations, kinds);
        let views = view_residuals(observations, kinds);
        let (view_position, view_rotation) = view_rms(&views);
        Self { flag_at, by_group, positions, views, view_position, view_rotation, ..self }
    }

    /// The observations flagged ([`Score::flag_at`]), with their index.
    pub fn flagged(&self) -> impl Iterator<Item = (usize, &ObservationResidual)> {
        self.observations.iter().enumerate().filter(|(_, r)| r.whitened.abs() > self.flag_at)
    }

    /// Marker `marker`'s positions (every marker's: `None`), as a marker file's pose table
    /// counts them: how many, the largest error, and those flagged (a coordinate beyond
    /// [`Score::flag_at`]).
    pub fn positions_of(&self, marker: Option<usize>) -> PositionSummary {
        let chosen = self.positions.iter().filter(|p| marker.is_none_or(|m| p.marker == m));
        let flagged = |p: &&PositionError| {
            self.observations[p.index..p.index + p.coordinates]
                .iter()
                .any(|r| r.whitened.abs() > self.flag_at)
        };
        PositionSummary {
            count: chosen.clone().count(),
            max: chosen.clone().fold((0.0, 0.0), |m, p| (m.0.max(p.error.0), m.1.max(p.error.1))),
            flagged: chosen.filter(flagged).count(),
        }
    }
}

/// Marker positions summed up ([`Score::positions_of`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PositionSummary {
    /// The positions (a marker at a pose).
    pub count: usize,
    /// The largest position error `|e|` before and after (mm).
    pub max: (f64, f64),
    /// The positions flagged after calibration.
    pub flagged: usize,
}

/// A robot the one pipeline calibrates ([`Calibration`]): the data it is calibrated from, as
/// the rows of observations a calibration of it scores.
pub trait Robot: Clone + std::fmt::Debug {
    /// Its data: an arm's observation files, a tree's views.
    type Data;

    /// `data` as the rows of observations of `c` (checked against it): an arm's as they are;
    /// a tree's views each a camera observation between `c`'s frames.
    fn rows<'d>(c: &Calibration<Self>, data: &'d Self::Data) -> Result<Cow<'d, KindData>, CalibrationError>;

    /// The serial arm's model, where it is one (its joints' physical bounds checked).
    fn arm(&self) -> Option<&RobotModel> {
        None
    }
}

impl Robot for RobotModel {
    type Data = KindData;

    /// `data` as they are, checked: one value per joint at each pose, and only the points `c`
    /// calibrated (its markers; the tool point where it was calibrated).
    fn rows<'d>(c: &KindCalibration, data: &'d KindData) -> Result<Cow<'d, KindData>, CalibrationError> {
        data.check(c.calibrated.dof())?;
        let markers: Vec<usize> = c.markers.iter().map(|m| m.0).collect();
        data.check_points(&markers, c.chains.len() > markers.len())?;
        Ok(Cow::Borrowed(data))
    }

    fn arm(&self) -> Option<&RobotModel> {
        Some(self)
    }
}

impl<R: Robot> Calibration<R> {
    /// What the fit estimated, by the names of its estimate: the robot's parameters, and the
    /// indices of the set-up's.
    fn estimated(&self) -> (Selection, Vec<usize>) {
        let names = &self.refined.estimate.names;
        let robot = names.iter().filter_map(|n| self.params.index_by_name(n));
        let setup = self.setup.names();
        let kept_setup = (names.iter())
            .filter(|n| self.params.index_by_name(n).is_none())
            .filter_map(|n| setup.iter().position(|s| s == n))
            .collect();
        (Selection::from_indices(&self.params, robot), kept_setup)
    }

    /// The robot's full vector and the set-up's values of the "before" fit.
    pub(super) fn before_values(&self) -> (Vec<f64>, Vec<f64>) {
        (self.before.clone(), self.setup_values.0.clone())
    }

    /// `data` scored before and after, the set-up as calibrated (with per-session parameters,
    /// each session's: a training session's of the same name, else fitted on `data` with the
    /// robot held), whitened by `V_k f` with the calibration's joint noise
    /// and [`Calibration::variance_factor`] `f` where the noise was assumed (by feasible GLS,
    /// with the estimated noise: each observation's sigma its class's).
    pub fn score(&self, data: &R::Data) -> Result<Score, CalibrationError> {
        self.score_rows(R::rows(self, data)?.as_ref())
    }

    /// [`Calibration::score`] of the rows `data`.
    fn score_rows(&self, data: &KindData) -> Result<Score, CalibrationError> {
        let estimated = self.noise_estimate.as_ref().map(|e| feasible::with_class_sigmas(data, e));
        let data = estimated.as_ref().unwrap_or(data);
        let (setup, values, sessions) = self.setup_for(data)?;
        data.check_against(&setup)?;
        let noise = self.joint_noise.as_ref();
        // The weights only whiten the residuals after: the joint noise is for those alone.
        // Before: its residuals alone, no V_k.
        let before = self.problem_on(data, &setup, (&self.before, &values.0), &[]);
        // The same problem at other values: one table of the joints' sines and cosines.
        let after = before.reselect(&self.nothing, self.after.clone(), values.1.clone(), Vec::new());
        let zero = DVector::zeros(0);
        // The assumed sigmas scaled by the residuals' spread, when they were; the diagonal of
        // `V_k` alone.
        let factor = self.variance_factor.unwrap_or(1.0);
        let variances: Vec<f64> = after.variances(noise).into_iter().map(|d| d * factor).collect();
        let mut score = Score::new(data, (&before.residuals(&zero), &after.residuals(&zero)), &variances);
        score.sessions = sessions;
        Ok(score)
    }

    /// The problem of `data` on this calibration's points (or branches), the robot at `x` and
    /// the set-up `setup` at `s`, estimating the set-up values `free` only.
    fn problem_on<'b>(
        &'b self,
        data: &'b KindData,
        setup: &'b SetUp,
        (x, s): (&[f64], &[f64]),
        free: &[usize],
    ) -> KindProblem<'b> {
        let values = (x.to_vec(), s.to_vec(), free.to_vec());
        KindProblem::on_chains(&self.chains, self.points(), (&self.nothing, data, setup), values)
    }

    /// What its chains end at ([`KindProblem::on_chains`]): its markers' numbers (less one),
    /// and whether they are a tree's branches.
    fn points(&self) -> (Vec<usize>, bool) {
        (self.markers.iter().map(|m| m.0).collect(), self.branches)
    }

    /// The problem of `data` (rows of this calibration's observations) on its points or
    /// branches and its set-up, estimating what it estimated, from its estimate; `V_k` with
    /// `joint_noise`: what feasible GLS and the check of the noise linearise.
    fn problem_at_estimate<'b>(
        &'b self,
        data: &'b KindData,
        kept: &'b Selection,
        kept_setup: Vec<usize>,
        joint_noise: Option<&DMatrix<f64>>,
    ) -> KindProblem<'b> {
        let values = (self.after.clone(), self.setup_values.1.clone(), kept_setup);
        KindProblem::on_chains(&self.chains, self.points(), (kept, data, &self.setup), values)
            .with_noise(joint_noise)
    }

    /// The set-up to score `data` with, and its values before and after ([`setup_for`]).
    #[allow(clippy::type_complexity)]
    fn setup_for(
        &self,
        data: &KindData,
    ) -> Result<(SetUp, (Vec<f64>, Vec<f64>), Vec<(String, SessionSetUp)>), CalibrationError> {
        let points = (self.chains.as_slice(), self.points(), &self.nothing);
        setup_for((&self.setup, &self.setup_values), (&self.before, &self.after), points, data)
    }

    /// RMS of the length residuals of `data` (mm) before and after ([`Calibration::score`]).
    pub fn validate(&self, data: &R::Data) -> Result<(f64, f64), CalibrationError> {
        Ok(self.score(data)?.lengths)
    }

    /// The calibrated markers as a model file writes them: each one's number and position (mm)
    /// as the calibrated model's tool point is given (the last joint's frame).
    pub fn marker_positions(&self) -> Vec<(usize, Vector3<f64>)> {
        self.markers.iter().map(|&(m, p)| (m + 1, p)).collect()
    }

    /// Plane `i`'s calibrated unit normal and offset (mm).
    pub fn plane(&self, i: usize) -> (Vector3<f64>, f64) {
        self.setup.plane(&self.setup.session_values(&self.setup_values.1, 0), i)
    }

    /// The joint noise the calibration weighted by, if any.
    pub fn joint_noise(&self) -> Option<&DMatrix<f64>> {
        self.joint_noise.as_ref()
    }
}

/// The set-up to score `data` with, and its values before and after, of a calibration whose
/// set-up is `setup` at `values` (before, after) and the robot at `robot` (before, after), on
/// `chains` (points `(markers, branches)`, [`KindProblem::on_chains`]; `nothing` the selection
/// of no robot parameter): the calibration's, or with per-session parameters, over `data`'s
/// sessions, each one the training session's of its name where there is one
/// ([`SessionSetUp::Training`]), else fitted on `data` by ordinary least squares with the
/// robot held ([`SessionSetUp::Fitted`]).
#[allow(clippy::type_complexity)]
pub(super) fn setup_for(
    (setup, values): (&SetUp, &(Vec<f64>, Vec<f64>)),
    robot: (&[f64], &[f64]),
    (chains, points, nothing): (&[Chain], (Vec<usize>, bool), &Selection),
    data: &KindData,
) -> Result<(SetUp, (Vec<f64>, Vec<f64>), Vec<(String, SessionSetUp)>), CalibrationError> {
    let per_session = setup.per_session().to_vec();
    if per_session.is_empty() {
        return Ok((setup.clone(), values.clone(), Vec::new()));
    }
    let names: Vec<String> = (0..data.session_count()).map(|k| data.session_name(k)).collect();
    let trained = |name: &String| setup.session_names().iter().position(|n| n == name);
    let scored = setup.clone().with_sessions(names.clone(), per_session.clone());
    // Each session's values: the training session's of its name, else the first's to start.
    let of_sessions = |s: &[f64]| -> Vec<f64> {
        let view = |k: usize| setup.session_values(s, trained(&names[k]).unwrap_or(0));
        let first = view(0);
        let later = (1..scored.session_count()).flat_map(|k| {
            let v = view(k);
            per_session.iter().map(move |&i| v[i]).collect::<Vec<_>>()
        });
        first.iter().copied().chain(later).collect()
    };
    let free: Vec<usize> = (0..names.len())
        .filter(|k| trained(&names[*k]).is_none())
        .flat_map(|k| per_session.iter().map(move |&i| (i, k)))
        .map(|(i, k)| scored.slot(i, k))
        .collect();
    let mut fitted = (of_sessions(&values.0), of_sessions(&values.1));
    if !free.is_empty() {
        for (x, s) in [(robot.0, &mut fitted.0), (robot.1, &mut fitted.1)] {
            let held = (x.to_vec(), s.clone(), free.clone());
            let problem = KindProblem::on_chains(chains, points.clone(), (nothing, data, &scored), held)
                .with_noise(None);
            let weights = Weights::for_problem(&problem, Estimator::Ols)?;
            let start = linearise(&problem, &weights, problem.start())?;
            let refined = refine_from(&problem, &weights, start, &RefineOptions::default())?;
            *s = problem.full(&refined.estimate.x).1;
        }
    }
    let sessions = names
        .iter()
        .map(|n| {
            let source = trained(n)
                .map_or(SessionSetUp::Fitted, |t| SessionSetUp::Training(setup.session_names()[t].clone()));
            (n.clone(), source)
        })
        .collect();
    Ok((scored, fitted, sessions))
}

/// Calibrate `model` from distances, contacts, coordinates, cameras' views and marker
/// positions: with markers, the base first placed by the rigid registration of the nominal
/// markers onto the measured ones (Kabsch); the
/// set-up fitted with the robot nominal, with markers the base and the points on the last link
/// too ("before"), then the robot's parameters asked for and the set-up together ("after");
/// what the observations cannot see held and said ([`KindCalibration::unseen`]), what the
/// poses cannot tell apart held by the rank-revealing solve.
///
/// The example's ball bar on the PUMA 560, scored on its held-out file:
///
/// ```
/// use robocal::calibration::kinds::{KindData, KindOptions, calibrate_kinds};
/// use robocal::model::RobotModel;
///
/// let model = RobotModel::preset("puma560").ok_or("no such preset")?;
/// let read = |file: &str| -> Result<KindData, Box<dyn std::error::Error>> {
///     Ok(KindData::from_csv_str(&std::fs::read_to_string(file)?, &model, None)?)
/// };
/// let (training, held_out) = (read("examples/puma560-ballbar.csv")?, read("examples/puma560-ballbar-2.csv")?);
/// let options = KindOptions { tool: nalgebra::Vector3::new(50.0, 0.0, 150.0), ..KindOptions::default() };
/// let calibration = calibrate_kinds(&model, &training, &options)?;
/// let (before, after) = calibration.validate(&held_out)?; // RMS of the lengths, mm
/// assert!(before > 0.5 && after < 0.1, "held out: {before} mm before, {after} mm after");
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub fn calibrate_kinds(
    model: &RobotModel,
    data: &KindData,
    options: &KindOptions,
) -> Result<KindCalibration, CalibrationError> {
    fit_kinds(model, data, options, None)?.scored((&model.name, &model.joints), data)
}

/// A calibration fitted but not yet scored on its training data nor warned about
/// ([`Unscored::scored`]): what feasible GLS fits round after round, scoring only the last.
pub(super) struct Unscored<R = RobotModel> {
    /// The calibration, its training score and warnings not yet made.
    pub(super) calibration: Calibration<R>,
    /// The data it was fitted to, where not the data given: with the sigmas ordinary least
    /// squares takes, or a feasible GLS round's.
    pub(super) fitted_on: Option<KindData>,
    /// The spread the priors weighed against ([`prior_spread`]), in the assumed sigmas.
    pub(super) spread: Option<f64>,
    /// What the gauge found at the estimate changed.
    pub(super) change: Option<Warning>,
}

impl<R: Robot> Unscored<R> {
    /// The calibration scored on the rows it was fitted to (`data`, where
    /// [`Unscored::fitted_on`] does not hold others), and its warnings (the poses outside the
    /// limits of the robot `(name, joints)` among them), as [`calibrate_kinds`] gives it.
    pub(super) fn scored(
        self,
        (name, joints): (&str, &[Joint]),
        data: &KindData,
    ) -> Result<Calibration<R>, CalibrationError> {
        let Unscored { mut calibration, fitted_on, spread, change } = self;
        let data = fitted_on.as_ref().unwrap_or(data);
        scored(&mut calibration, data, spread)?;
        calibration.warnings.extend(Warning::outside_limits(name, joints, data.pose_lines()));
        calibration.warnings.extend(noise_check(&calibration, data));
        calibration.warnings.extend(change);
        calibration.warnings.extend(super::ill_conditioned(&calibration.refined));
        Ok(calibration)
    }
}

/// [`calibrate_kinds`] but its scoring ([`Unscored::scored`]), the "before" fit taken from
/// `earlier`'s (a calibration's robot vector and set-up values before,
/// [`KindCalibration::before_values`]) where it would be made again the same: with markers it
/// is ordinary least squares without the noise ([`before_fit`]), whatever the estimator and
/// the sigmas, so a calibration of the same data that differs only in those (a round of
/// feasible GLS) has the same "before" fit to the bit. Without markers it is weighted, and
/// made again; with angles (a probe's) too, as ordinary least squares weighs them by the
/// sigmas' ratio ([`KindProblem::angle_weight`]).
pub(super) fn fit_kinds(
    model: &RobotModel,
    data: &KindData,
    options: &KindOptions,
    earlier: Option<(Vec<f64>, Vec<f64>)>,
) -> Result<Unscored, CalibrationError> {
    let as_ols = (options.estimator == Estimator::Ols && options.joint_noise.is_none())
        .then(|| data.with_ols_sigmas())
        .flatten();
    let data = as_ols.as_ref().unwrap_or(data);
    let (Arm { registered, ends }, prepared) = prepare(model, data, options)?;
    let angles = data.observations.iter().any(Observation::is_angle);
    let about = earlier.filter(|_| !prepared.markers.is_empty() && !angles);
    let started = start_about(&prepared, data, options, about)?;
    let (before, before_setup) = (started.before.clone(), started.before_setup.clone());
    let spread = started.prior_spread.map(|s| s / started.weights.scale().unwrap_or(1.0));
    let Fitted { refined: estimate, robust, fixed, after, after_setup, change } =
        fit_gauged(&prepared, started, options)?;
    let fixed = prepared.every_held(fixed);
    let Prepared { chains, params, markers, setup, nothing, .. } = prepared;
    let calibrated_points = calibrated_points(&params, &after, &ends);
    // The model's tool is the tool point (or frame), after the markers; of markers alone, marker
    // 1 (a point, or a probe's frame), as `calibrate` makes it.
    let tool_point = if data.sees_the_tool() { markers.len() } else { 0 };
    let points: Vec<Vector3<f64>> = ends.iter().map(MarkerEnd::origin).collect();
    let probe = match ends.get(tool_point) {
        Some(MarkerEnd::Frame(f)) => Some(f),
        _ => None,
    };
    let calibrated = fold(&registered, &params, &after, (&points, tool_point), probe);
    let frame = registered.marker_frame().isometry();
    let tip_frame = match calibrated.tool {
        Tool::Frame(t) if !data.probes().is_empty() => {
            Some(Placement::from_isometry(&(frame.inverse() * t.isometry())))
        }
        _ => None,
    };
    let prior_sd = prior_sds(&options.prior, &params)?;
    let calibration = KindCalibration {
        calibrated,
        before,
        after,
        unseen: data.unseen(&setup, &setup.session_values(&after_setup, 0)),
        params,
        setup,
        setup_values: (before_setup, after_setup),
        refined: estimate,
        fixed,
        training: Score { flag_at: FLAG_AT, ..Score::default() },
        nothing,
        robust,
        prior_sd,
        warnings: Vec::new(),
        markers: markers.iter().zip(&calibrated_points).map(|(&m, p)| (m, (frame * p).coords)).collect(),
        variance_factor: None,
        registered_base: (!markers.is_empty() && options.estimate_base).then_some(registered.base),
        tip_frame,
        joint_noise: options.joint_noise.clone(),
        chains,
        branches: false,
        noise_estimate: None,
        noise_settled: None,
    };
    Ok(Unscored { calibration, fitted_on: as_ols, spread, change })
}

/// Whether the noise given (the files' sigmas, the joint noise) agrees with the residuals of
/// `c` on its training `data` ([`check`](super::noise_check::check), as for a marker file):
/// each pose's block (of at most [`CHECK_POSES`] poses, evenly spread) linearised about the
/// estimate, with its joint part `sum_j G_kj Sigma_q G_kj^T` and its measurement part
/// `diag(sigma_i^2)`, the lengths cross-validated (a marker's position one error, angles not
/// scored: [`Observation::error_share`]). `None` when it agrees,
/// without a noise given (every sigma assumed and the joints exact: the residuals' spread
/// scales the fit instead), or with too few residuals to tell. Under a robust loss too: the
/// points far out are left out of the check ([`without_outliers`]) as the loss leaves them out.
fn noise_check<R: Robot>(c: &Calibration<R>, data: &KindData) -> Option<Warning> {
    let assumed = c.joint_noise.is_none() && data.assumed_sigmas == data.observations.len();
    if assumed {
        return None;
    }
    let stride = data.joints.len().div_ceil(CHECK_POSES).max(1);
    let sample = data.keeping(|o| o.pose() % stride == 0);
    let (kept, kept_setup) = c.estimated();
    let problem = c.problem_at_estimate(&sample, &kept, kept_setup, c.joint_noise.as_ref());
    let robot: Vec<f64> = kept.indices().iter().map(|&i| c.prior_sd[i]).collect();
    // A tree's view's position is one error (a marker's is), its rotation none.
    let view_share = |o: &Observation| if o.is_angle() { 0.0 } else { 1.0 / 3.0 };
    match c.branches {
        true => check_noise(&problem, view_share, &robot),
        false => check_noise(&problem, Observation::error_share, &robot),
    }
}

/// The check of the noise `problem` was weighted by ([`check`]) at its start (a calibration's
/// estimate, its estimated parameters selected): each pose's block one sample, its joint part
/// `sum_j G_kj Sigma_q G_kj^T` and its measurement part, every row scored by its `share` of
/// one error; `prior_sd` the prior standard deviations of its robot parameters (the set-up's
/// have none). `None` when the noise agrees or the residuals are too few to tell; the blocks
/// far out are left out ([`without_outliers`]), as a robust loss leaves them out.
pub(in crate::calibration) fn check_noise(
    problem: &KindProblem<'_>,
    share: impl Fn(&Observation) -> f64,
    prior_sd: &[f64],
) -> Option<Warning> {
    let start = problem.start();
    let (h, y, v) = at_estimate(problem, &start)?;
    let data = problem.data;
    let points = (problem.blocks().ranges(y.len()))
        .map(|r| {
            let b = r.len();
            let measurement =
                DMatrix::from_fn(b, b, |i, j| data.measurement_covariance(r.start + i, r.start + j));
            let joint = DMatrix::from_fn(b, b, |i, j| v[(r.start + i, j)]) - &measurement;
            let (h, r_k) = (h.rows(r.start, b).into_owned(), y.rows(r.start, b).into_owned());
            let shares: Vec<f64> = r.map(|i| share(&data.observations[i])).collect();
            (Point { h, r: r_k, joint, measurement }, shares)
        })
        .collect();
    let (points, shares): (Vec<Point>, Vec<Vec<f64>>) = without_outliers(points).into_iter().unzip();
    let components = Components::new(points)?;
    let prior_sd: Vec<f64> =
        prior_sd.iter().copied().chain(std::iter::repeat(f64::INFINITY)).take(start.len()).collect();
    check(&components, (&start, &prior_sd), &|k: usize, i: usize| shares[k][i])
}

/// What [`fit_gauged`] gives: the fit (every step of every round in its history), the robust
/// fit's record, what the last gauge held, the robot's and the set-up's values after, and what
/// the gauge found at the estimate changed.
pub(super) struct Fitted {
    pub(super) refined: Refined,
    /// With a robust loss: its final weights, one per observation (its pose's).
    pub(super) robust: Option<RobustFit>,
    pub(super) fixed: Vec<Held>,
    pub(super) after: Vec<f64>,
    pub(super) after_setup: Vec<f64>,
    pub(super) change: Option<Warning>,
}

impl super::regauge::Kept for Gauged {
    fn kept(&self) -> &[usize] {
        &self.identifiable
    }

    fn unmoved(&self) -> Vec<&str> {
        (self.fixed.iter())
            .filter_map(|h| match h {
                Held::Unmoved { parameter } => Some(parameter.as_str()),
                _ => None,
            })
            .collect()
    }
}

/// The fit of what `prepared` asks for from `started`, the gauge found again at the estimate
/// ([`super::regauge`]): with the start's gauge from "before", then, while the gauge found at
/// the estimate's settled point keeps other columns, with it from the estimate.
pub(super) fn fit_gauged(
    prepared: &Prepared,
    started: Started<'_>,
    options: &KindOptions,
) -> Result<Fitted, CalibrationError> {
    let Started { base, weights, before, before_setup, linearised, prior_spread, gauged } = started;
    let weigh = (weights.scale().unwrap_or(1.0), prior_spread);
    let (asked, asked_setup) = (&prepared.asked, &prepared.asked_setup);
    let whole = base.reselect(asked, before, before_setup, asked_setup.clone());
    let x0: Vec<f64> = whole.start().iter().copied().collect();
    let names = whole.names();
    if names.is_empty() {
        // Nothing asked for (`--params none`, the base, markers and tool fixed, no set-up): the
        // model as it stands is scored, as a marker file's is.
        let refined = Refined { estimate: super::nothing_estimated(), history: Vec::new(), converged: true };
        let (after, after_setup) = whole.full(&DVector::zeros(0));
        return Ok(Fitted { refined, robust: None, fixed: gauged.fixed, after, after_setup, change: None });
    }
    let mut first = Some(linearised);
    type Out = (Option<RobustFit>, Vec<f64>, Vec<f64>);
    let fit = |g: &mut Gauged, at: &[f64], steps: usize| -> Result<(Refined, Out), CalibrationError> {
        let (full, full_setup) = whole.full(&DVector::from_column_slice(at));
        let (kept, kept_setup) = prepared.kept(&g.identifiable);
        let problem = base.reselect(&kept, full, full_setup, kept_setup);
        let start = match first.take() {
            Some(at_before) => at_before.select(&g.identifiable),
            None => linearise(&problem, &weights, problem.start())?,
        };
        let prior = g.prior.as_ref().map(|p| p.select(&g.identifiable));
        let refine = RefineOptions { max_iterations: steps, ..options.refine };
        let (refined, robust) =
            super::robust::fit(&problem, &weights, start, &refine, prior.as_ref(), options.loss)?;
        // A pose's weight is every one of its observations'.
        let blocks = problem.blocks();
        let robust = robust.map(|mut r| {
            r.weights =
                (0..r.weights.len()).flat_map(|k| vec![r.weights[k]; blocks.range(k).len()]).collect();
            r
        });
        let (after, after_setup) = problem.full(&refined.estimate.x);
        Ok((refined, (robust, after, after_setup)))
    };
    let gauge_at = |x: &[f64]| -> Result<(Gauged, f64), CalibrationError> {
        let (full, full_setup) = whole.full(&DVector::from_column_slice(x));
        let problem = base.reselect(asked, full, full_setup, asked_setup.clone());
        let there = linearise(&problem, &weights, problem.start())?;
        let g = gauge(&problem, &there, (&prepared.params, asked), options, weigh)?;
        let prior = g.prior.as_ref().map(|p| p.select(&g.identifiable));
        let weakest = super::regauge::weakest(&there.select(&g.identifiable), prior.as_ref());
        Ok((g, weakest))
    };
    let limit = options.refine.max_iterations;
    let mut r = super::regauge::fit_regauged((&x0, &names), gauged, limit, fit, gauge_at)?;
    if let Some(data_alone) = r.gauge.data_alone {
        r.refined.estimate.diagnostics = data_alone;
    }
    let (robust, after, after_setup) = r.fitted;
    Ok(Fitted { refined: r.refined, robust, fixed: r.gauge.fixed, after, after_setup, change: r.change })
}

/// The robot and the set-up of a calibration of some data, before any fit: the model with its
/// base registered on the markers, the chains of its points (the markers', then the tool's),
/// the set-up and its start, and what is asked for.
pub(super) struct Prepared {
    pub(super) chains: Vec<Chain>,
    /// Whether the chains are a tree's branches ([`Chain::on_tree`]), not points on one arm.
    branches: bool,
    pub(super) params: ParamSet,
    markers: Vec<usize>,
    pub(super) setup: SetUp,
    /// The set-up's start values, one per session where per session.
    setup_start: Vec<f64>,
    /// The robot's parameters asked for (`--params`, the registration's), less `--hold`'s.
    pub(super) asked: Selection,
    /// The set-up's parameters asked for, less `--hold`'s.
    asked_setup: Vec<usize>,
    /// What `--hold` held.
    held_words: Vec<Held>,
    /// The set-up values of the "before" fit: all but the length zeros not asked for.
    every: Vec<usize>,
    /// The robot's length held for the scale (contacts without a distance).
    scale: Option<usize>,
    nothing: Selection,
}

impl Prepared {
    /// The robot's and the set-up's parameters of the `identifiable` columns (of the problem
    /// of what is asked: the robot's, then the set-up's).
    pub(super) fn kept(&self, identifiable: &[usize]) -> (Selection, Vec<usize>) {
        let (asked, robot) = (&self.asked, self.asked.len());
        let kept = Selection::from_indices(
            &self.params,
            identifiable.iter().filter(|&&c| c < robot).map(|&c| asked.indices()[c]),
        );
        let setup = identifiable.iter().filter(|&&c| c >= robot).map(|&c| self.asked_setup[c - robot]);
        (kept, setup.collect())
    }

    /// [`Prepared`] of a tree's branches: `chains` each a branch's tip's, on the tree's
    /// parameters `params` ([`Chain::on_tree`]); `setup` the views' cameras' and targets'
    /// placements ([`SetUp::with_views`]) from `start`, every one estimated (no registration,
    /// no length held for a scale: a view sees lengths); the tree's parameters `asked`; what
    /// `hold` names (the tree's or the set-up's) held.
    pub(super) fn of_branches(
        chains: Vec<Chain>,
        params: ParamSet,
        (setup, start): (SetUp, Vec<f64>),
        asked: Selection,
        hold: &[String],
    ) -> Result<Self, CalibrationError> {
        let every: Vec<usize> = (0..setup.len()).collect();
        let (asked, asked_setup, held_words) = without_held(&params, asked, every.clone(), &setup, hold)?;
        let nothing = Selection::from_indices(&params, []);
        let setup_start = setup.expand(&start);
        #[rustfmt::skip]
        let prepared = Self {
            chains, branches: true, params, markers: Vec::new(), setup, setup_start, asked, asked_setup,
            held_words, every, scale: None, nothing,
        };
        Ok(prepared)
    }

    /// What the gauge held (`fixed`), then what `--hold` held, then the length held for the
    /// scale.
    pub(super) fn every_held(&self, mut fixed: Vec<Held>) -> Vec<Held> {
        fixed.extend(self.held_words.iter().cloned());
        fixed.extend(self.scale.map(|i| Held::Scale { parameter: self.params.get(i).name.clone() }));
        fixed
    }
}

/// An arm's side of [`Prepared`]: the model with its base registered on the markers, and what
/// each chain ends at (the markers' points and frames, then the tool's).
pub(super) struct Arm {
    registered: RobotModel,
    ends: Vec<MarkerEnd>,
}

/// The ends of the chains on the last link of `registered`: the markers' points (`markers`,
/// their numbers less one, at `nominal`; a probe's frame, [`KindOptions::probe`] or its
/// rotation started from the data), then the tool's (a point at `tool`, or a frame for angles)
/// if observed.
fn marker_ends(
    registered: &RobotModel,
    data: &KindData,
    options: &KindOptions,
    (markers, nominal): (&[usize], &[Vector3<f64>]),
    tool: Vector3<f64>,
) -> Vec<MarkerEnd> {
    let probes = data.probes();
    let mut ends: Vec<MarkerEnd> = (markers.iter().zip(nominal))
        .map(|(&m, &at)| match probes.contains(&m) {
            true => MarkerEnd::Frame(match options.probe.filter(|_| m == 0) {
                Some(given) => given,
                None => probe_mounting(registered, at, data.orientations_of(m)),
            }),
            false => MarkerEnd::Point(at),
        })
        .collect();
    if data.sees_the_tool() {
        ends.push(match data.has_angles() {
            true => MarkerEnd::Frame(Placement { xyz: tool, rpy: Vector3::zeros() }),
            false => MarkerEnd::Point(tool),
        });
    }
    ends
}

/// [`Prepared`] of `data` on `model` with `options`, and the arm it is on.
pub(super) fn prepare(
    model: &RobotModel,
    data: &KindData,
    options: &KindOptions,
) -> Result<(Arm, Prepared), CalibrationError> {
    data.check(model.dof())?;
    super::check_points(Some(&options.tool), &options.markers)?;
    let markers = data.markers();
    let nominal_markers: Vec<Vector3<f64>> =
        markers.iter().map(|&m| options.markers.get(m).copied().unwrap_or_else(Vector3::zeros)).collect();
    let registered = match markers.is_empty() || !options.estimate_base {
        true => model.clone(),
        false => {
            // Poses all alike cannot place the measuring frame, nor identify anything.
            super::different_poses(data.pose_lines())?;
            registered(model, data, &markers, &nominal_markers)?
        }
    };
    // Angles need a tool frame: the tool point, turned as the marker frame to start with.
    // Cameras alone: their mounting is in the tool (tip link's) frame itself, no tool point.
    // With markers, a camera's mounting is in the tool frame as well: the last point at its
    // origin, held.
    let tool = if data.measures_the_tool_point() { options.tool } else { Vector3::zeros() };
    let ends = marker_ends(&registered, data, options, (&markers, &nominal_markers), tool);
    let chains = Chain::marker_ends(&registered, &ends);
    let params = chains[0].params().clone();
    let zero = vec![0.0; params.len()];
    // The tool's frames at every pose, where the set-up starts from them (fixed points,
    // planes, a camera): the tool's chain, the last.
    let (points, planes) = data.setup_counts();
    let nominal: Vec<Isometry3<f64>> = match points + planes > 0 || data.camera().is_some() {
        true => {
            let at = chains[chains.len() - 1].with_errors(&zero);
            data.joints.par_iter().map(|q| at.pose(q)).collect()
        }
        false => Vec::new(),
    };
    let (setup, start) = with_tracker(data.initial_setup(&nominal)?, data, options)?;
    let sessions = (0..data.session_count()).map(|k| data.session_name(k)).collect();
    let per_session = matching(&setup.base_names(), &options.per_session)?;
    let setup = setup.with_sessions(sessions, per_session);
    let setup_start = setup.expand(&start);
    let nothing = Selection::from_indices(&params, []);
    let (asked, asked_setup) = asked(model, &params, &setup, data, options)?;
    let (asked, asked_setup, mut held_words) =
        without_held(&params, asked, asked_setup, &setup, &options.gauge.hold)?;
    // What no gravity load moves at these poses is held, wherever the estimate goes.
    let (asked, unloaded) = super::without_unloaded_joints(&asked, &chains[0], &zero, &data.joints);
    held_words.extend(unloaded);
    if !asked.is_empty() {
        super::different_poses(data.pose_lines())?;
    }
    let every: Vec<usize> = (0..setup.len())
        .filter(|&i| {
            !setup.is_fixed_frame(i) && (!setup.is_zero(setup.base_of(i)) || asked_setup.contains(&i))
        })
        .collect();
    let scale =
        (!data.sees_the_scale() && setup.planes() > 0).then(|| longest_length(model, &params)).flatten();
    #[rustfmt::skip]
    let prepared = Prepared {
        chains, branches: false, params, markers, setup, setup_start, asked, asked_setup,
        held_words, every, scale, nothing,
    };
    Ok((Arm { registered, ends }, prepared))
}

/// The set-up `(setup, start)` with a tracker frame per session ([`SetUp::with_tracker`], its
/// start the identity) when markers are read in several sessions and `--per-session` names
/// `tracker.*`; else as it is. A pattern naming the tracker without such files is refused.
fn with_tracker(
    (setup, mut start): (SetUp, Vec<f64>),
    data: &KindData,
    options: &KindOptions,
) -> Result<(SetUp, Vec<f64>), CalibrationError> {
    let names = ["x", "y", "z", "rx", "ry", "rz"].map(|c| format!("tracker.{c}"));
    let named = options.per_session.iter().find(|p| names.iter().any(|n| name_matches(p, n)));
    let Some(pattern) = named else { return Ok((setup, start)) };
    if data.markers().is_empty() || data.session_count() < 2 {
        return Err(CalibrationError::Observations(format!(
            "--per-session `{pattern}`: a tracker's placement per session needs marker positions (x1, y1, z1 \
             columns) in two data files or more; these have {} session(s) and {} marker(s)",
            data.session_count(),
            data.markers().len()
        )));
    }
    let setup = setup.with_tracker();
    let at = setup.tracker_at();
    start.splice(at..at, [0.0; 6]);
    Ok((setup, start))
}

/// A calibration linearised at its "before" fit: the problem of every parameter held (its
/// `V_k`), the estimator's weights, the "before" values, the system of what is asked for about
/// them, and its gauge.
pub(super) struct Started<'p> {
    pub(super) base: KindProblem<'p>,
    pub(super) weights: Weights,
    pub(super) before: Vec<f64>,
    pub(super) before_setup: Vec<f64>,
    /// `A = S H`, `b = S y` of what is asked for, about "before".
    pub(super) linearised: Linearisation,
    /// Where every sigma is assumed and the joints are exact: the residuals' spread the priors
    /// weigh against ([`prior_spread`]).
    pub(super) prior_spread: Option<f64>,
    pub(super) gauged: Gauged,
}

/// [`Started`] of `prepared` on `data`: the "before" fit (the set-up and the tool point, the
/// robot's joints nominal; with markers, the base and the markers too, by ordinary least
/// squares whatever the estimator, as `calibrate` fits its base and markers: it minimises the
/// very errors it reports), then the system of what is asked for and its gauge.
pub(super) fn start<'p>(
    prepared: &'p Prepared,
    data: &'p KindData,
    options: &KindOptions,
) -> Result<Started<'p>, CalibrationError> {
    start_about(prepared, data, options, None)
}

/// [`start`] about the registration where coordinates (a height gauge's) see the base without
/// markers: the base, the tool point and the set-up fitted by the calibration of no joint
/// parameter (`model`'s), the point a selection's linear model is linearised about
/// ([`selection`](super::selection)); the nominal base of a gauge on a tilted table is off by
/// more than a linearisation bears. Other data: [`start`].
pub(super) fn start_registered<'p>(
    model: &RobotModel,
    prepared: &'p Prepared,
    data: &'p KindData,
    options: &KindOptions,
) -> Result<Started<'p>, CalibrationError> {
    let coordinates =
        (data.observations.iter()).any(|o| matches!(o, Observation::Coordinate { axis: ..3, .. }));
    if !coordinates || !prepared.markers.is_empty() {
        return start(prepared, data, options);
    }
    let registration = KindOptions { joints: JointParams::None, loss: Loss::Squared, ..options.clone() };
    let c = calibrate_kinds(model, data, &registration)?;
    start_about(prepared, data, options, Some((c.after, c.setup_values.1)))
}

/// [`start`], about `about` (the robot's full vector and the set-up's values) instead of the
/// "before" fit if given.
fn start_about<'p>(
    prepared: &'p Prepared,
    data: &'p KindData,
    options: &KindOptions,
    about: Option<(Vec<f64>, Vec<f64>)>,
) -> Result<Started<'p>, CalibrationError> {
    let Prepared { chains, branches, markers, params, setup, asked, asked_setup, nothing, .. } = prepared;
    let zero = vec![0.0; params.len()];
    let (start, every) = (prepared.setup_start.clone(), prepared.every.clone());
    let values = (zero, start, every.clone());
    let base = KindProblem::on_chains(chains, (markers.clone(), *branches), (nothing, data, setup), values)
        .with_noise(options.joint_noise.as_ref());
    let weights = Weights::for_problem(&base, options.estimator)?;
    let frame = Selection::from_indices(
        params,
        (asked.indices().iter().copied()).filter(|&i| match params.get(i).owner {
            ParamOwner::Marker(_) => true,
            ParamOwner::Joint(_) => false,
            _ => !markers.is_empty(),
        }),
    );
    let (before, before_setup) = match about {
        Some(about) => about,
        None => before_fit(&base, &frame, every, &weights, markers.is_empty())?,
    };
    // "After": what was asked for that the observations identify.
    let problem = base.reselect(asked, before.clone(), before_setup.clone(), asked_setup.clone());
    // A parameter with a prior is anchored by it: only the others need the data's equations.
    let sd = prior_sds(&options.prior, params)?;
    let unanchored = problem.parameters() - asked.indices().iter().filter(|&&i| sd[i].is_finite()).count();
    super::enough_equations(data.joints.len(), problem.equations(), unanchored)?;
    let linearised = linearise(&problem, &weights, problem.start())?;
    let prior_spread = prior_spread((prepared, &problem), &linearised, &weights, data, options)?;
    let weigh = (weights.scale().unwrap_or(1.0), prior_spread);
    let gauged = gauge(&problem, &linearised, (params, asked), options, weigh)?;
    Ok(Started { base, weights, before, before_setup, linearised, prior_spread, gauged })
}

/// What the priors weigh against when every sigma is assumed and the joints are exact (the
/// fit then takes its scale from the residuals, [`scored`]): the residuals' spread
/// `sqrt(|r|^2 / (N_m - rank))` of the fit of `problem` (about `linearised`) without priors,
/// as a marker file's ordinary least squares takes it, so that a prior weighs against the
/// data's own noise, not against the assumed sigmas ([`PriorRows::weighed_against`]); `None`
/// when the noise is known (the priors weigh against the weights' own scale) or no prior is
/// given.
fn prior_spread(
    (prepared, problem): (&Prepared, &KindProblem<'_>),
    linearised: &Linearisation,
    weights: &Weights,
    data: &KindData,
    options: &KindOptions,
) -> Result<Option<f64>, CalibrationError> {
    let assumed = options.joint_noise.is_none() && data.assumed_sigmas == data.observations.len();
    if options.prior.is_empty() || !assumed || problem.parameters() == 0 {
        return Ok(None);
    }
    let identifiable = linearised.diagnose(RANK_TOLERANCE)?.identifiable;
    let (kept, kept_setup) = prepared.kept(&identifiable);
    let (at, at_setup) = problem.full(&problem.start());
    let plain = problem.reselect(&kept, at, at_setup, kept_setup);
    super::spread_of_fit(&plain, weights, linearised.select(&identifiable)).map(Some)
}

/// What the marginal likelihood needs of a calibration ([`Front::evidence`](super::Front::evidence)):
/// the system of what is asked for, whitened by `S` (`S V S^T = c^2 I`: of observation files or
/// a tree's views each pose's block `V_k` of the observations' sigmas and the joint noise,
/// divided by the normalisation `c`), its columns the robot's parameters `asked` (indices into
/// `params`) then the set-up's (none of a marker file).
pub(crate) struct EvidenceSystem {
    /// The robot's (or tree's) parameters.
    pub(crate) params: Vec<crate::model::ParamInfo>,
    /// The robot's parameters of the first columns, in order.
    pub(crate) asked: Vec<usize>,
    /// `A = S H`, `b = S y` about the point asked for.
    pub(crate) linearised: Linearisation,
    /// The normalisation `c` of the whitening.
    pub(crate) c: f64,
}

/// The [`EvidenceSystem`] of `data` with `options` (their estimator's weights), linearised
/// about `about` (the robot's full vector and the set-up's values of a calibration of `data`)
/// or, `None`, about the "before" fit.
pub(crate) fn evidence_system(
    model: &RobotModel,
    data: &KindData,
    options: &KindOptions,
    about: Option<(&[f64], &[f64])>,
) -> Result<EvidenceSystem, CalibrationError> {
    let (_, prepared) = prepare(model, data, options)?;
    let started = start(&prepared, data, options)?;
    evidence_of(&prepared, started, about)
}

/// The [`EvidenceSystem`] of what `prepared` asks for, `started` (its "before" fit and
/// weights), linearised about `about` (the robot's full vector and the set-up's values) or,
/// `None`, about "before".
pub(super) fn evidence_of(
    prepared: &Prepared,
    started: Started<'_>,
    about: Option<(&[f64], &[f64])>,
) -> Result<EvidenceSystem, CalibrationError> {
    let c = started.weights.scale().unwrap_or(1.0);
    let linearised = match about {
        None => started.linearised,
        Some((fixed, setup)) => {
            let (asked, asked_setup) = (&prepared.asked, prepared.asked_setup.clone());
            let problem = started.base.reselect(asked, fixed.to_vec(), setup.to_vec(), asked_setup);
            linearise(&problem, &started.weights, problem.start())?
        }
    };
    let asked = prepared.asked.indices().to_vec();
    Ok(EvidenceSystem { params: prepared.params.iter().cloned().collect(), asked, linearised, c })
}

/// The "before" fit of `base_problem`: the robot parameters `frame` (the tool point, with
/// markers the base and the markers) and the set-up values `every` from the robot nominal, by
/// the estimator's `weights`, or with markers by ordinary least squares; nothing to fit, the
/// start.
fn before_fit(
    base_problem: &KindProblem<'_>,
    frame: &Selection,
    every: Vec<usize>,
    weights: &Weights,
    no_markers: bool,
) -> Result<(Vec<f64>, Vec<f64>), CalibrationError> {
    if every.is_empty() && frame.is_empty() {
        return Ok(base_problem.full(&base_problem.start()));
    }
    let zero = vec![0.0; base_problem.fixed.len()];
    let problem = base_problem.reselect(frame, zero, base_problem.setup_values.clone(), every);
    let ols = match no_markers {
        true => weights.clone(),
        false => Weights::ols_without_noise(base_problem),
    };
    let fit = linearise(&problem, &ols, problem.start())?;
    let refined = refine_from(&problem, &ols, fit, &RefineOptions::default())?;
    Ok(problem.full(&refined.estimate.x))
}

/// The gauge of `problem` linearised in `linearised`: the user's `--keep` free first, then the
/// set-up, then the robot's parameters (`asked` of `params`) by gauge class; with priors, what
/// the data and the priors together cannot identify is held. The identifiable columns, the
/// held ones in words, and the prior rows of every column.
fn gauge(
    problem: &KindProblem<'_>,
    linearised: &Linearisation,
    (params, asked): (&ParamSet, &Selection),
    options: &KindOptions,
    weigh: (f64, Option<f64>),
) -> Result<Gauged, CalibrationError> {
    let keep = problem_columns(problem, &options.gauge.keep)?;
    let priority: Vec<u32> = (0..problem.parameters())
        .map(|c| match keep.contains(&c) {
            true => 0,
            false => 1 + asked.indices().get(c).map_or(0, |&i| gauge_class(params.get(i))),
        })
        .collect();
    let prior = prior_rows(problem, asked, params, &options.prior, weigh)?;
    let owners: Vec<Option<ParamOwner>> =
        (0..problem.parameters()).map(|c| asked.indices().get(c).map(|&i| params.get(i).owner)).collect();
    let (identifiable, fixed) =
        identifiable(linearised, (&problem.names(), &owners), &priority, prior.as_ref())?;
    let data_alone = match prior {
        Some(_) => Some(linearised.diagnose_data_alone(RANK_TOLERANCE, &priority)?),
        None => None,
    };
    Ok(Gauged { identifiable, fixed, prior, data_alone })
}

/// What [`gauge`] finds: the identifiable columns, the held ones in words, the prior rows.
pub(super) struct Gauged {
    pub(super) identifiable: Vec<usize>,
    pub(super) fixed: Vec<Held>,
    pub(super) prior: Option<PriorRows>,
    /// With priors, the identifiability of the data alone, to report.
    pub(super) data_alone: Option<crate::estimation::Diagnostics>,
}

/// `calibration` scored on its training `data` (its rows); with every sigma assumed and the
/// joints exact, the covariance and the whitening scaled by the residuals' variance of unit
/// weight `f = sum z_k^2 / (N - rank)` (`z_k` whitened by the assumed sigmas), as ordinary least
/// squares without a noise model takes it, or with priors by `f = spread^2`, the spread (in
/// the assumed sigmas) they weighed against ([`prior_spread`]); then its warnings: estimates
/// past a physical bound, an unconverged fit, the training observations (a tree's views) more
/// than [`FLAG_AT`] standard deviations out.
pub(super) fn scored<R: Robot>(
    calibration: &mut Calibration<R>,
    data: &KindData,
    spread: Option<f64>,
) -> Result<(), CalibrationError> {
    calibration.training = calibration.score_rows(data)?;
    let (n, rank) = (data.observations.len(), calibration.refined.estimate.diagnostics.rank);
    if calibration.joint_noise.is_none() && data.assumed_sigmas == n && n > rank {
        let sum: f64 = calibration.training.observations.iter().map(|r| r.whitened * r.whitened).sum();
        let f = spread.map_or(sum / (n - rank) as f64, |s| s * s);
        calibration.refined.estimate.covariance *= f;
        calibration.variance_factor = Some(f);
        // As `score` whitens with `V_k f`: each whitened residual over sqrt(f).
        let training = std::mem::take(&mut calibration.training);
        calibration.training = training.whitened_by(f, data);
    }
    let c = &*calibration;
    let se = super::standard_errors_of(c.params.iter(), &c.refined.estimate);
    let mut warnings = super::implausible(c.params.iter(), (&c.before, &c.after), &se, c.calibrated.arm());
    warnings.extend(super::not_converged(&c.refined));
    warnings.extend(match c.branches {
        true => Warning::far_out(
            Scored::View,
            (c.training.views.iter().enumerate())
                .filter(|(_, v)| v.whitened > FLAG_AT)
                .map(|(index, v)| FarOut { index, line: v.line, label: None, sd: v.whitened }),
        ),
        false => Warning::far_out(
            Scored::Observation,
            (c.training.flagged()).map(|(index, r)| FarOut {
                index,
                line: r.line,
                label: Some(r.label()),
                sd: r.whitened,
            }),
        ),
    });
    calibration.warnings = warnings;
    Ok(())
}

/// `model` scored as it stands on `data`: the set-up (fixed points, planes, a camera and its
/// target, a device; with markers the base and the markers) fitted to it with the robot's
/// parameters and its tool point held at the model's (`options.tool`); the residuals after
/// that fit. What `robocal evaluate` reports of a file that is not a marker file.
pub fn evaluate_kinds(
    model: &RobotModel,
    data: &KindData,
    options: &KindOptions,
) -> Result<Score, CalibrationError> {
    let held = KindOptions { joints: JointParams::None, estimate_tool: false, ..options.clone() };
    Ok(calibrate_kinds(model, data, &held)?.training)
}

/// Whether `data` are a marker file's with every cell measured: every observation a marker's
/// (a position's coordinate or a probe's orientation), each marker's three coordinates at
/// every pose.
fn every_marker_measured(data: &KindData) -> bool {
    let markers = data.markers();
    let mut coordinates = vec![0; markers.last().map_or(0, |m| m + 1)];
    for o in &data.observations {
        match o {
            Observation::Marker { marker, .. } => coordinates[*marker] += 1,
            Observation::Orientation { .. } => {}
            _ => return false,
        }
    }
    !data.observations.is_empty() && markers.iter().all(|&m| coordinates[m] == 3 * data.joints.len())
}

impl KindOptions {
    /// The options that score `model` as it stands on `data` ([`evaluate_kinds`]): its tool
    /// point, and, where the data are a marker file's (every observation a marker's, every
    /// marker measured at every pose), its base and its markers held as the model gives them:
    /// `markers` numbered from 1 (mm, in the last joint frame, as a model file's
    /// `[[markers]]`), each taken into the marker frame `F` as `F^-1 p`; none given, the tool
    /// point is marker 1; a 6-DOF probe's frame is the model's tool frame, where it has one,
    /// taken into the marker frame as `F^-1 T` ([`KindOptions::probe`]). Any other data (a
    /// marker file with empty cells among them) have their set-up, with markers the base and
    /// the markers too, fitted.
    ///
    /// # Errors
    /// A marker of `data` that `markers` lacks.
    pub fn as_it_stands(
        model: &RobotModel,
        markers: &[(usize, Vector3<f64>)],
        data: &KindData,
    ) -> Result<Self, CalibrationError> {
        let tool = model.tool_point_in_marker_frame();
        let as_it_stands = Self { tool, ..Self::default() };
        if !every_marker_measured(data) {
            return Ok(as_it_stands);
        }
        let frame = model.marker_frame().isometry();
        let given: Vec<(usize, Vector3<f64>)> = if markers.is_empty() {
            vec![(1, tool)]
        } else {
            markers.iter().map(|(id, p)| (*id, frame.inverse_transform_point(&(*p).into()).coords)).collect()
        };
        let markers_seen = data.markers();
        let mut held = vec![Vector3::zeros(); markers_seen.last().map_or(0, |m| m + 1)];
        for marker in markers_seen {
            let id = marker + 1;
            held[marker] = given.iter().find(|(m, _)| *m == id).map(|(_, p)| *p).ok_or_else(|| {
                let known: Vec<usize> = given.iter().map(|(m, _)| *m).collect();
                CalibrationError::Scoring(format!("the model has no marker {id} (it has {known:?})"))
            })?;
        }
        let probe = match &model.tool {
            crate::model::Tool::Frame(t) if !data.probes().is_empty() => {
                Some(Placement::from_isometry(&(frame.inverse() * t.isometry())))
            }
            _ => None,
        };
        Ok(Self { markers: held, probe, estimate_base: false, estimate_markers: false, ..as_it_stands })
    }
}

/// k-fold cross-validation of [`calibrate_kinds`]: the observations of pose `p` (every row of
/// a view, every marker of a pose; a pair by its first pose) are held out in fold `p mod
/// folds`, the others calibrated with `options` (every choice, the prior's and the loss's,
/// made again inside each fold) and the held-out ones scored; the folds' held-out residuals
/// pooled (the RMS summed fold by fold), each listed in the data's order. The sessions are kept in every fold: each fold's held-out
/// observations are scored with the set-up of their own session.
pub fn cross_validate_kinds(
    model: &RobotModel,
    data: &KindData,
    options: &KindOptions,
    folds: usize,
) -> Result<Score, CalibrationError> {
    cross_validate_kinds_by(data, folds, |train| calibrate_kinds(model, train, options))
}

/// [`cross_validate_kinds`] with each fold's calibration made by `calibrate` from its training
/// observations (every choice made from the data made again inside it).
pub(crate) fn cross_validate_kinds_by(
    data: &KindData,
    folds: usize,
    mut calibrate: impl FnMut(&KindData) -> Result<KindCalibration, CalibrationError>,
) -> Result<Score, CalibrationError> {
    let fold_of_pose =
        super::pose_folds(data.observations.iter().map(Observation::pose), data.joints.len(), folds)?;
    let mut scored = Vec::with_capacity(data.observations.len());
    for fold in 0..folds {
        let (test, train) = (
            data.keeping(|o| fold_of_pose[o.pose()] == fold),
            data.keeping(|o| fold_of_pose[o.pose()] != fold),
        );
        scored.extend(calibrate(&train)?.score(&test)?.observations);
    }
    // Scored fold by fold; summed up in the data's order (a marker position's index is its
    // first coordinate's there).
    let fold_of: Vec<usize> = data.observations.iter().map(|o| fold_of_pose[o.pose()]).collect();
    Ok(Score::of(super::in_data_order(scored, &fold_of, folds), &data.observations))
}

/// `model` with its base placed by the rigid registration of the nominal markers (the
/// positions `nominal`, numbered `markers`, at every pose) onto the measured ones, as
/// `calibrate` places it (`with_registered_base`), from every pose and marker whose x, y and z
/// were all measured (at least 3, not on one line).
fn registered(
    model: &RobotModel,
    data: &KindData,
    markers: &[usize],
    nominal: &[Vector3<f64>],
) -> Result<RobotModel, CalibrationError> {
    let mut measured = vec![[None; 3]; data.joints.len() * markers.len()];
    for o in &data.observations {
        if let Observation::Marker { marker, axis, pose, measured: m, .. } = *o {
            let k = markers.iter().position(|&id| id == marker).expect("one of the data's markers");
            measured[pose * markers.len() + k][axis] = Some(m);
        }
    }
    let chains = Chain::markers(model, nominal);
    let zero = vec![0.0; chains[0].params().len()];
    let at: Vec<ChainAt> = chains.iter().map(|c| c.with_errors(&zero)).collect();
    // Each pose's markers in parallel, in order.
    let pairs: Vec<(Vector3<f64>, Vector3<f64>)> = (measured.par_iter().enumerate())
        .filter_map(|(n, m)| match *m {
            [Some(x), Some(y), Some(z)] => {
                let (pose, k) = (n / markers.len(), n % markers.len());
                Some((at[k].pose(&data.joints[pose]).translation.vector, Vector3::new(x, y, z)))
            }
            _ => None,
        })
        .collect();
    let (predicted, measured): (Vec<Vector3<f64>>, Vec<Vector3<f64>>) = pairs.into_iter().unzip();
    let too_few = || {
        CalibrationError::Observations(format!(
            "marker positions: {} with x, y and z all measured, expected at least 3 not on one line to place the \
             measuring frame",
            predicted.len()
        ))
    };
    if predicted.len() < 3 {
        return Err(too_few());
    }
    // The spread of the predicted positions about their centre: two directions at least.
    let centre = predicted.iter().sum::<Vector3<f64>>() / predicted.len() as f64;
    let spread = DMatrix::from_fn(predicted.len(), 3, |r, c| predicted[r][c] - centre[c]).singular_values();
    let mut s: Vec<f64> = spread.iter().copied().collect();
    s.sort_by(|a, b| b.total_cmp(a));
    if s[1].is_nan() || s[1] <= 1e-9 * s[0] {
        return Err(too_few());
    }
    Ok(super::with_registered_base(model, &predicted, &measured))
}

/// Each point's calibrated position (mm) in the model's marker frame: its nominal position
/// `p0` of `points` plus its estimate, `p0 + (x, y, z)`.
fn calibrated_points(params: &ParamSet, x: &[f64], ends: &[MarkerEnd]) -> Vec<nalgebra::Point3<f64>> {
    use crate::model::ParamKind;
    (ends.iter().enumerate())
        .map(|(k, end)| {
            let value = |kind| params.index_of(ParamOwner::Marker(k), kind).map_or(0.0, |i| x[i]);
            let shift = Vector3::new(value(ParamKind::X), value(ParamKind::Y), value(ParamKind::Z));
            match end {
                MarkerEnd::Point(p) => (p + shift).into(),
                // A frame's errors displace it along its own axes.
                MarkerEnd::Frame(f) => (f.xyz + f.isometry().rotation * shift).into(),
            }
        })
        .collect()
}

/// The robot parameters and the set-up parameters asked for: the joints of `options`, the tool
/// point unless held or only cameras see it (their mountings are the tool), the base only if
/// coordinates see it; every set-up parameter. When
/// contacts alone cannot see the scale (every length and plane offset times one factor leaves
/// every contact), the robot's longest nominal length is held at its nominal value: it sets the
/// scale. (Holding a plane's offset instead leaves a robot shrunk onto the planes, its first
/// joint's `d` carrying it there, as free as the true one: it fits every contact.)
fn asked(
    model: &RobotModel,
    params: &ParamSet,
    setup: &SetUp,
    data: &KindData,
    options: &KindOptions,
) -> Result<(Selection, Vec<usize>), CalibrationError> {
    let names = setup.base_names();
    // Patterns of --params that name set-up parameters only (a length zero) free those.
    let (setup_named, joints) = match &options.joints {
        JointParams::Named(patterns) => {
            let (of_setup, of_robot): (Vec<String>, Vec<String>) = patterns.iter().cloned().partition(|p| {
                names.iter().any(|n| name_matches(p, n)) && !params.iter().any(|q| name_matches(p, &q.name))
            });
            let robot = match of_robot.is_empty() {
                true => JointParams::None,
                false => JointParams::Named(of_robot),
            };
            (matching(&names, &of_setup)?, robot)
        }
        other => (Vec::new(), other.clone()),
    };
    let joints = joints.select(params)?;
    let markers = data.markers().len();
    let extra = (0..params.len()).filter(|&i| match params.get(i).owner {
        // The markers' points unless held; the tool point's (after them) unless held. A camera's
        // mounting is the tool frame's, estimated as the set-up's.
        ParamOwner::Marker(k) if k < markers => options.estimate_markers,
        ParamOwner::Marker(_) => options.estimate_tool && data.measures_the_tool_point(),
        ParamOwner::Base => options.estimate_base && data.sees_the_base(),
        _ => false,
    });
    let scale =
        (!data.sees_the_scale() && setup.planes() > 0).then(|| longest_length(model, params)).flatten();
    let robot = joints.indices().iter().copied().chain(extra).filter(|&i| Some(i) != scale);
    let robot = Selection::from_indices(params, robot);
    // A device frame is seen only along the axes its coordinates measure.
    let unseen: Vec<usize> = match setup.device() {
        true => data.device_unseen().iter().map(|i| setup.device_at() + i).collect(),
        false => Vec::new(),
    };
    // A length zero is held unless named (by --params or as per session).
    let held = |b: usize| {
        unseen.contains(&b)
            || (setup.is_zero(b) && !setup_named.contains(&b) && !setup.per_session().contains(&b))
    };
    let setup_asked = (0..setup.len()).filter(|&i| !setup.is_fixed_frame(i) && !held(setup.base_of(i)));
    Ok((robot, setup_asked.collect()))
}

/// The columns of `problem` (robot then set-up, by [`Residuals::names`], a per-session
/// value by its parameter's name too) that `patterns` name; a pattern naming none is refused.
fn problem_columns(problem: &KindProblem<'_>, patterns: &[String]) -> Result<Vec<usize>, SelectionError> {
    let names: Vec<String> =
        problem.names().iter().map(|n| n.split('@').next().unwrap_or(n).to_string()).collect();
    let mut columns = Vec::new();
    for pattern in patterns {
        let found = (0..names.len())
            .filter(|&c| name_matches(pattern, &names[c]) || name_matches(pattern, &problem.names()[c]));
        let before = columns.len();
        columns.extend(found);
        if columns.len() == before {
            return Err(SelectionError { pattern: pattern.clone() });
        }
    }
    Ok(columns)
}

/// `asked` (robot) and `asked_setup` without the parameters `hold` names (robot or set-up,
/// names or patterns), and each held one in words; a pattern naming none is refused.
fn without_held(
    params: &ParamSet,
    asked: Selection,
    asked_setup: Vec<usize>,
    setup: &SetUp,
    hold: &[String],
) -> Result<(Selection, Vec<usize>, Vec<Held>), SelectionError> {
    if hold.is_empty() {
        return Ok((asked, asked_setup, Vec::new()));
    }
    let (names, base) = (setup.names(), setup.base_names());
    let setup_held = |i: usize| {
        hold.iter().any(|p| name_matches(p, &names[i]) || name_matches(p, &base[setup.base_of(i)]))
    };
    let robot_held = |i: usize| hold.iter().any(|p| name_matches(p, &params.get(i).name));
    if let Some(p) = hold.iter().find(|p| {
        !params.iter().any(|q| name_matches(p, &q.name))
            && !(0..names.len())
                .any(|i| name_matches(p, &names[i]) || name_matches(p, &base[setup.base_of(i)]))
    }) {
        return Err(SelectionError { pattern: p.clone() });
    }
    let mut words: Vec<Held> = (asked.indices().iter().filter(|&&i| robot_held(i)))
        .map(|&i| Held::ByUser { parameter: params.get(i).name.clone(), setup: false })
        .collect();
    words.extend(
        (asked_setup.iter().filter(|&&i| setup_held(i)))
            .map(|&i| Held::ByUser { parameter: names[i].clone(), setup: true }),
    );
    let robot = Selection::from_indices(params, asked.indices().iter().copied().filter(|&i| !robot_held(i)));
    let setup_kept = asked_setup.into_iter().filter(|&i| !setup_held(i)).collect();
    Ok((robot, setup_kept, words))
}

/// The prior rows of `problem`'s columns: the robot's asked parameters' standard deviations
/// of `entries`, none for the set-up; for whitened rows of standard deviation `scale`,
/// weighed against the residuals' `spread` where the noise is a guess ([`prior_spread`]);
/// `None` when no column has a prior.
fn prior_rows(
    problem: &KindProblem<'_>,
    asked: &Selection,
    params: &ParamSet,
    entries: &[PriorEntry],
    (scale, spread): (f64, Option<f64>),
) -> Result<Option<PriorRows>, CalibrationError> {
    if entries.is_empty() {
        return Ok(None);
    }
    let sd = prior_sds(entries, params)?;
    let columns: Vec<f64> =
        (0..problem.parameters()).map(|c| asked.indices().get(c).map_or(f64::INFINITY, |&i| sd[i])).collect();
    if columns.iter().all(|s| !s.is_finite()) {
        return Ok(None);
    }
    Ok(Some(PriorRows::new(&columns, scale).weighed_against(spread)))
}

/// The indices of `names` that the `patterns` match (`*` as in [`Selection::by_names`]); a
/// pattern that matches none is refused.
pub(super) fn matching(names: &[String], patterns: &[String]) -> Result<Vec<usize>, SelectionError> {
    let mut out = Vec::new();
    for pattern in patterns {
        let found: Vec<usize> = (0..names.len()).filter(|&i| name_matches(pattern, &names[i])).collect();
        if found.is_empty() {
            return Err(SelectionError { pattern: pattern.clone() });
        }
        out.extend(found.into_iter().filter(|i| !out.contains(i)).collect::<Vec<_>>());
    }
    out.sort_unstable();
    Ok(out)
}

/// The joint length parameter (`a`, `d`, a URDF origin's `x`, `y`, `z`) of the longest nominal
/// value: the robot's scale.
pub(super) fn longest_length(model: &RobotModel, params: &ParamSet) -> Option<usize> {
    use crate::model::ParamKind;
    let value = |i: usize| -> f64 {
        let p = params.get(i);
        let ParamOwner::Joint(j) = p.owner else { return 0.0 };
        let joint = &model.joints[j];
        match p.kind {
            ParamKind::A => joint.a,
            ParamKind::D => joint.d,
            ParamKind::X => joint.origin.xyz.x,
            ParamKind::Y => joint.origin.xyz.y,
            ParamKind::Z => joint.origin.xyz.z,
            _ => 0.0,
        }
        .abs()
    };
    // The first of equal lengths.
    (0..params.len())
        .filter(|&i| value(i) > 0.0)
        .max_by(|&a, &b| value(a).total_cmp(&value(b)).then(b.cmp(&a)))
}

/// The columns of `linearised` to estimate, and the others in words: first those it does not
/// move at all (a column norm below 1e-10 of the largest: the column scaling of the
/// rank-revealing solve would blow their rounding up into directions of their own), then the
/// combinations the rank-revealing solve holds, by `priority` ([`gauge_class`]).
pub(super) fn identifiable(
    linearised: &Linearisation,
    (names, owners): (&[String], &[Option<ParamOwner>]),
    priority: &[u32],
    prior: Option<&PriorRows>,
) -> Result<(Vec<usize>, Vec<Held>), CalibrationError> {
    if names.is_empty() {
        // Nothing asked for: nothing to identify, nothing held.
        return Ok((Vec::new(), Vec::new()));
    }
    let norms: Vec<f64> = linearised.column_norms();
    let largest = norms.iter().copied().fold(0.0, f64::max);
    let (seen, unseen): (Vec<usize>, Vec<usize>) =
        (0..norms.len()).partition(|&c| norms[c] > 1e-10 * largest);
    if seen.is_empty() {
        return Err(CalibrationError::NothingIdentified(format!(
            "the identification Jacobian of the {} parameters asked for is zero at these poses: the observations \
             move none of them (pairs of identical poses, for one, measure no change); measure at poses that differ",
            names.len()
        )));
    }
    let mut fixed: Vec<Held> = unseen.iter().map(|&c| unmoved(&names[c], owners[c])).collect();
    let seen_priority: Vec<u32> = seen.iter().map(|&c| priority[c]).collect();
    let seen_system = linearised.select(&seen);
    let diagnostics = match prior {
        // With priors, what the data and the priors together cannot identify is held.
        Some(prior) => seen_system
            .with_prior(&prior.select(&seen))
            .diagnose_by_priority(RANK_TOLERANCE, &seen_priority)?,
        None => seen_system.diagnose_by_priority(RANK_TOLERANCE, &seen_priority)?,
    };
    // The combinations of the columns seen, classified by their parameters' owners.
    let (seen_names, seen_owners): (Vec<String>, Vec<Option<ParamOwner>>) =
        seen.iter().map(|&c| (names[c].clone(), owners[c])).unzip();
    fixed.extend(diagnostics.not_identifiable.iter().map(|c| why_held(c, &seen_names, &seen_owners)));
    Ok((diagnostics.identifiable.iter().map(|&c| seen[c]).collect(), fixed))
}

/// Why a parameter no observation moves at the start is held: the observations do not move
/// it ([`Held::Unmoved`], never freed by the gauge found at the estimate), or, of the payload's
/// mass, that it is seen only through compliances zero at the start ([`Held::Unseen`]: where
/// the estimate's compliances see it, the gauge found there frees it, [`super::regauge`]).
fn unmoved(name: &str, owner: Option<ParamOwner>) -> Held {
    match owner {
        Some(ParamOwner::Payload) => Held::Unseen {
            parameter: name.to_string(),
            why:
                "the payload is seen only through the joints' compliances, all zero at the start: estimated \
                  where the fitted compliances see it (the gauge found again at the estimate)"
                    .into(),
        },
        _ => Held::Unmoved { parameter: name.to_string() },
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Each point's rows as [`RowsAt`] builds them (what a linearisation reduces and the
    /// variance components' samples read) against the whole system's `H` and `y`
    /// ([`Residuals::evaluate`]) to rounding: two markers' coordinates and, with the tool
    /// frame measured, a camera's views, at poses and parameter errors off the nominal.
    #[test]
    fn rows_point_by_point_are_the_whole_systems() {
        let model = RobotModel::preset("puma560").unwrap();
        let joints: Vec<Vec<f64>> =
            (0..5).map(|k| (0..6).map(|j| 0.3 * ((k * 7 + j * 3) % 11) as f64 - 1.4).collect()).collect();
        let marker =
            |marker, axis, pose| Observation::Marker { marker, axis, pose, measured: 100.0, sigma: 0.01 };
        let view = Vector6::new(10.0, -20.0, 900.0, 0.1, -0.2, 0.3);
        let camera =
            |axis, pose| Observation::Camera { axis, pose, view, site: CameraSite::World, sigma: 0.1 };
        let data = |observations: Vec<Observation>| KindData {
            joints: joints.clone(),
            lines: (0..observations.len()).collect(),
            observations,
            ..KindData::default()
        };
        let markers = data((0..5).flat_map(|p| (0..6).map(move |i| marker(i / 3, i % 3, p))).collect());
        let cameras = data((0..5).flat_map(|p| (0..6).map(move |axis| camera(axis, p))).collect());
        let chains =
            Chain::markers(&model, &[Vector3::new(50.0, 0.0, 150.0), Vector3::new(-40.0, 60.0, 120.0)]);
        let probe =
            Chain::probe(&model, &Placement { xyz: Vector3::new(0.0, 0.0, 100.0), rpy: Vector3::zeros() });
        let selection = Selection::all(chains[0].params());
        // The first half alone: the steps after the last it moves held, each walk back starting
        // there.
        let count = chains[0].params().len();
        let first = Selection::from_indices(chains[0].params(), 0..count / 2);
        let errors = |n: usize| (0..n).map(|i| 1e-3 * ((i * 5) % 7) as f64 - 2e-3).collect::<Vec<f64>>();
        let (none, with_camera) = (SetUp::new(0, &[]), SetUp::new(0, &[]).with_camera(CameraSite::World));
        let camera_values: Vec<f64> =
            (0..12).map(|i| [300.0, -200.0, 100.0, 0.1, 0.2, -0.3][i % 6]).collect();
        let problems = [
            KindProblem::of_points(
                &chains,
                &[0, 1],
                &selection,
                &markers,
                &none,
                errors(selection.len()),
                vec![],
                vec![],
            ),
            KindProblem::of_points(&chains, &[0, 1], &first, &markers, &none, errors(count), vec![], vec![]),
            KindProblem::new(
                &probe,
                &selection,
                &cameras,
                &with_camera,
                errors(selection.len()),
                camera_values,
                (0..12).collect(),
                None,
            ),
        ];
        for problem in &problems {
            let (n, p) = (problem.equations(), problem.parameters());
            let x = problem.start();
            let mut h = DMatrix::zeros(n, p);
            let y = problem.evaluate(&x, Some(&mut h));
            let rows = problem.rows_at(&x);
            let held = problem.held.get().is_some_and(Option::is_some);
            assert_eq!(held, problem.selection.len() < count, "steps held for the first half alone");
            let mut scratch = rows.scratch();
            let blocks = problem.blocks();
            for (k, r) in blocks.ranges(n).enumerate() {
                let b = r.len();
                let (mut h_k, mut y_k) = (vec![0.0; b * p], vec![0.0; b]);
                rows.point(&mut scratch, k, r.clone(), &mut h_k, &mut y_k);
                let whole = h.rows(r.start, b);
                let scale = whole.amax().max(1.0);
                assert!(
                    (DMatrix::from_column_slice(b, p, &h_k) - whole).amax() < 1e-12 * scale,
                    "H of point {k}"
                );
                assert!(r.clone().all(|i| (y_k[i - r.start] - y[i]).abs() < 1e-9), "y of point {k}");
            }
        }
    }

    /// A block per run of one pose's observations, at most [`MAX_BLOCK`] rows each.
    #[test]
    fn each_poses_observations_are_one_block_of_at_most_max_block() {
        let at = |pose: usize| Observation::Coordinate { axis: 2, pose, measured: 0.0, sigma: 0.01 };
        let poses = [0, 0, 0, 1, 2, 2].into_iter().chain([3; MAX_BLOCK + 6]).chain([0]);
        let observations: Vec<Observation> = poses.map(at).collect();
        let blocks = pose_blocks(&observations);
        let sizes: Vec<usize> = blocks.ranges(observations.len()).map(|r| r.len()).collect();
        assert_eq!(sizes, [3, 1, 2, MAX_BLOCK, 6, 1]);
        assert_eq!(blocks.width(), MAX_BLOCK);
    }
}
