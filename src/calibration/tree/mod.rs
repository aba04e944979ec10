//! Several chains: a tree (a torso carrying two arms and a head camera, [`RobotTree`])
//! calibrated in one fit from camera views between its branches.
//!
//! # The observation model
//!
//! A view is the camera of [`camera`](super::kinds::camera)'s model, with either frame on any
//! branch: the camera's frame `A` and the target's frame `B` are each fixed to a branch's tip,
//! `X = T_b(q) C` (`T_b` the tip link's frame of branch `b` at the tree's joint values `q`,
//! `C` the mounting, 6 set-up parameters), or placed in the root link's frame, `X = W`. The
//! camera measures `M = A^-1 B`, six residuals `y = (m_t - t_M, log(R_m R_M^T))`, and
//!
//! `H_k = S_A dA/dx + S_B dB/dx`,
//!
//! `S_A`, `S_B` the derivatives of the view by the frames' twists
//! ([`relative_view`](super::kinds::camera::relative_view)), `dX/dx = E_T H_b` by the robot's
//! parameters (`H_b` the identification Jacobian of branch `b`'s tip,
//! [`ChainAt::identification_jacobian`], its columns those of the tree's parameters: a shared
//! joint's parameter has one column, to which both frames add) and `E_C`, `E_W` by the
//! mounting's or placement's 6 ([`mounted`](super::kinds::camera::mounted),
//! [`placed`](super::kinds::camera::placed)). Each branch's chain is put on the tree
//! ([`Chain::on_tree`]): it reads the tree's parameters and joints, so `H_b` has the tree's
//! columns. The views are observations of the one problem of every kind
//! ([`KindProblem::of_branches`], [`TreeRows`]): with the joint noise `Sigma_q` (tree joints)
//! every view at one pose is in one block,
//!
//! `V_k = G_k Sigma_q G_k^T + diag(sigma_t^2 I_3, sigma_r^2 I_3, ...)`,
//! `G_k` stacking each view's `S_A E_T J_a(q) + S_B E_T J_b(q)`,
//!
//! `J_b` the manipulator Jacobian of branch `b` in the tree's joints: the joints two branches
//! share move both frames, so their noise partly cancels, and the views of one pose are
//! correlated through the joints they share.
//!
//! # What the views cannot see
//!
//! A view sees one frame relative to the other: the base placement and every joint on the way
//! to both frames (the torso's, for a head camera looking at a hand) move both alike and
//! cancel; they are held and reported. After the joints they share, one rigid motion `G` of
//! every branch's next joint origin (`O -> G O` for the head's first joint and each arm's)
//! leaves every view too: 6 combinations of those origins, which the rank-revealing solve
//! holds, with what each mounting cannot be told from (the set-up is held last, as the gauge of
//! [`calibrate_kinds`](super::kinds::calibrate_kinds) orders it). What is recovered is every branch's motion
//! relative to the others: on held-out poses, every view, and the pose of any camera or target
//! relative to any other (one hand's target from the other's, never measured).
//!
//! # The start
//!
//! With the nominal tree, a camera `A = T_a C_A` seeing a target `B = T_b C_B` gives
//! `C_A M_k C_B^-1 = D_k`, `D_k = T_a^-1 T_b` (`T = I` for a frame in the world): the
//! eye-to-hand problem of [`camera_start`] with `D_k` as the robot, the camera's mounting as
//! its world placement and the target's as its mounting. Each frame starts from the first
//! camera-target pair that has it.

mod data;
mod feasible;

pub use data::{Frame, Role, TreeData, View};
pub use feasible::calibrate_tree_feasible;

use super::kinds::camera::{camera_start, isometry, placement};
use super::kinds::{
    self, Calibration, KindData, KindOptions, KindProblem, Prepared, Robot, Score, SetUp, Unscored,
};
use super::{CalibrationError, Gauge, Held, JointParams, RobustFit, Unseen, fold};
use crate::estimation::prior_sds_of;
use crate::kinematics::{Chain, ChainAt};
use crate::model::{ParamInfo, ParamOwner, ParamSet, Placement, RobotTree, Selection, SelectionError};
use nalgebra::{DMatrix, Isometry3, Vector3};
use std::borrow::Cow;

/// The tree's error parameters: the base's, then each joint's once (named after it), and how
/// each branch's parameters map onto them.
#[derive(Debug, Clone)]
pub struct TreeParams {
    /// The parameters (a joint's `owner` is its index on the first branch that has it).
    pub params: Vec<ParamInfo>,
    /// Each branch's chain to its tip link's frame, on the tree ([`Chain::on_tree`]): at the
    /// tree's parameters and joints.
    chains: Vec<Chain>,
    /// Each branch's own parameters, as a serial robot's.
    local: Vec<ParamSet>,
    /// The tree's parameters, as a set the chains index.
    set: ParamSet,
    /// Each branch's parameters' tree parameter (`None`: the chain's own end frame's, unused).
    maps: Vec<Vec<Option<usize>>>,
    /// Each branch's joints' tree joints ([`Branch::joints`](crate::model::Branch::joints)).
    joints: Vec<Vec<usize>>,
    /// Each branch's tip link.
    tips: Vec<String>,
    /// Each parameter's tree joint, if it is a joint's.
    joint_of: Vec<Option<usize>>,
}

impl TreeParams {
    /// The parameters of `tree`.
    pub fn new(tree: &RobotTree) -> Self {
        let mut params: Vec<ParamInfo> = Vec::new();
        let mut chains: Vec<Chain> = Vec::with_capacity(tree.branches.len());
        let mut maps = Vec::with_capacity(tree.branches.len());
        let mut joint_of = Vec::new();
        for branch in &tree.branches {
            let chain = Chain::probe(&branch.model, &Placement::default());
            let map: Vec<Option<usize>> = (chain.params().iter())
                .map(|p| match p.owner {
                    ParamOwner::Base | ParamOwner::Joint(_) => {
                        Some(params.iter().position(|t| t.name == p.name).unwrap_or_else(|| {
                            params.push(p.clone());
                            joint_of.push(match p.owner {
                                ParamOwner::Joint(j) => Some(branch.joints[j]),
                                _ => None,
                            });
                            params.len() - 1
                        }))
                    }
                    _ => None,
                })
                .collect();
            chains.push(chain);
            maps.push(map);
        }
        let joints: Vec<Vec<usize>> = tree.branches.iter().map(|b| b.joints.clone()).collect();
        let tips = tree.branches.iter().map(|b| b.tip.clone()).collect();
        let set = ParamSet::from_params(params.clone());
        let local = chains.iter().map(|c| c.params().clone()).collect();
        let chains = (chains.iter().zip(&maps).zip(&joints))
            .map(|((c, map), joints)| c.on_tree(set.clone(), map, joints, tree.dof()))
            .collect();
        Self { params, chains, local, set, maps, joints, tips, joint_of }
    }

    /// The number of parameters.
    pub fn len(&self) -> usize {
        self.params.len()
    }

    /// Whether there are none.
    pub fn is_empty(&self) -> bool {
        self.params.is_empty()
    }

    /// The number of the tree's joints.
    pub fn dof(&self) -> usize {
        self.joints.iter().flatten().max().map_or(0, |j| j + 1)
    }

    /// The number of branches.
    pub fn branches(&self) -> usize {
        self.chains.len()
    }

    /// Their names.
    pub fn names(&self) -> Vec<String> {
        self.params.iter().map(|p| p.name.clone()).collect()
    }

    /// `tree` with the errors `x` (one per parameter) folded into its joints: the tree whose
    /// nominal kinematics is `tree`'s with errors `x` (the base's are not folded: a view never
    /// sees it).
    pub fn fold(&self, tree: &RobotTree, x: &[f64]) -> RobotTree {
        let mut joints = tree.joints.clone();
        for (b, branch) in tree.branches.iter().enumerate() {
            let identity = Placement::default();
            let x_b = self.branch_values(b, x);
            let folded = fold(&branch.model, &self.local[b], &x_b, (&[], 0), Some(&identity));
            for (joint, &j) in folded.joints.into_iter().zip(&branch.joints) {
                joints[j] = joint;
            }
        }
        tree.with_joints(joints)
    }

    /// Why no view sees parameter `name` (a joint's), in words: no view has a frame past its
    /// joint, or every view that has one has both (the joint moves them alike); `None` for
    /// another.
    fn unseen(&self, name: &str, data: &TreeData) -> Option<String> {
        let i = self.params.iter().position(|p| p.name == name)?;
        let j = self.joint_of[i]?;
        let past = |f: usize| data.frames[f].on.is_some_and(|b| self.joints[b].contains(&j));
        let seen: Vec<&View> = data.views.iter().filter(|v| past(v.camera) || past(v.target)).collect();
        if seen.is_empty() {
            Some("no view has a camera or target past its joint: not seen".into())
        } else if seen.iter().all(|v| past(v.camera) && past(v.target)) {
            Some("its joint is on the way to both frames of every view past it: it moves them alike, no view sees it".into())
        } else {
            None
        }
    }

    /// Branch `b`'s parameter values out of the tree's `x`.
    fn branch_values(&self, b: usize, x: &[f64]) -> Vec<f64> {
        self.maps[b].iter().map(|m| m.map_or(0.0, |i| x[i])).collect()
    }

    /// The selection of the tree parameters `indices` (ascending).
    pub fn selection(&self, indices: &[usize]) -> Selection {
        Selection::from_indices(&self.set, indices.iter().copied())
    }

    /// The tree parameters `joints` selects, in order: on each branch as for a serial arm
    /// (every geometric joint parameter, the offsets, none) or, by name, every parameter a
    /// name or pattern matches (each must match one). Never the base.
    pub fn select(&self, joints: &JointParams) -> Result<Vec<usize>, SelectionError> {
        let mut chosen = vec![false; self.len()];
        match joints {
            JointParams::Named(names) => {
                for pattern in names {
                    let matched: Vec<usize> = (0..self.len())
                        .filter(|&i| crate::model::name_matches(pattern, &self.params[i].name))
                        .collect();
                    if matched.is_empty() {
                        return Err(SelectionError { pattern: pattern.clone() });
                    }
                    matched.into_iter().for_each(|i| chosen[i] = true);
                }
            }
            other => {
                for (local, map) in self.local.iter().zip(&self.maps) {
                    for &i in other.select(local)?.indices() {
                        if let Some(t) = map[i] {
                            chosen[t] = true;
                        }
                    }
                }
            }
        }
        let base = |i: usize| self.params[i].owner == ParamOwner::Base;
        Ok((0..self.len()).filter(|&i| chosen[i] && !base(i)).collect())
    }
}

/// A tree's views on the one observation problem ([`KindProblem::of_branches`]): their rows
/// ([`TreeData::observations`]), the set-up of the cameras' and targets' placements (6
/// parameters each, [`SetUp::with_views`]), which the problems borrow.
pub struct TreeRows {
    /// The views' rows.
    pub rows: KindData,
    /// The cameras' and targets' placements.
    pub setup: SetUp,
}

impl TreeRows {
    /// The views of `data` (checked against `params`) with the frames `frames` (the data's,
    /// or a calibration's that has every one of the data's).
    pub fn new(params: &TreeParams, data: &TreeData, frames: &[Frame]) -> Result<Self, CalibrationError> {
        data.check(params.dof(), params.branches())?;
        let setup = SetUp::new(0, &[]).with_views(frames.to_vec(), params.tips.clone());
        Ok(Self { rows: data.observations(frames), setup })
    }

    /// The problem estimating `selection` (of `params`) and, of the `values` `(fixed,
    /// setup_values, setup_selection)`, the placements `setup_selection`, the tree at `fixed`
    /// and the placements at `setup_values`; `V_k` with `joint_noise`.
    pub fn problem<'a>(
        &'a self,
        params: &'a TreeParams,
        selection: &'a Selection,
        values: (Vec<f64>, Vec<f64>, Vec<usize>),
        joint_noise: Option<&DMatrix<f64>>,
    ) -> KindProblem<'a> {
        let (rows, setup) = (&self.rows, &self.setup);
        KindProblem::of_branches(&params.chains, selection, rows, setup, values).with_noise(joint_noise)
    }
}

/// `tree` scored as it stands on `data`: the cameras and targets fitted to it (the "before"
/// fit of [`calibrate_tree`]) with the tree's joints held as they are; the views' residuals
/// after that fit. What `robocal evaluate` reports of a file of views: a tree calibrated on
/// `data` re-scores there as its calibration scored it, at the same minimum of
/// `sum_k y_k^T W_k y_k` over the frames.
pub fn evaluate_tree(
    tree: &RobotTree,
    data: &TreeData,
    options: &KindOptions,
) -> Result<Score, CalibrationError> {
    let held = KindOptions {
        joints: JointParams::None,
        prior: Vec::new(),
        gauge: Gauge::default(),
        ..options.clone()
    };
    Ok(calibrate_tree(tree, data, &held)?.training)
}

/// `data`'s poses cross-validated in `folds` folds (pose `i` held out in fold `i mod k`): the
/// tree calibrated on the views of the other poses, every choice made from the data (a robust
/// loss's weights) made again in each fold, and the held-out views scored with the frames as
/// that fold calibrated them; the scores of every fold pooled, view by view (the RMS summed
/// fold by fold), each view listed in the data's order.
pub fn cross_validate_tree(
    tree: &RobotTree,
    data: &TreeData,
    options: &KindOptions,
    folds: usize,
) -> Result<Score, CalibrationError> {
    cross_validate_tree_by(data, folds, |train| calibrate_tree(tree, train, options))
}

/// [`cross_validate_tree`] with each fold's calibration made by `calibrate` from its training
/// views (every choice made from the data made again inside it: nested).
pub fn cross_validate_tree_by(
    data: &TreeData,
    folds: usize,
    mut calibrate: impl FnMut(&TreeData) -> Result<TreeCalibration, CalibrationError>,
) -> Result<Score, CalibrationError> {
    let fold_of_pose = super::pose_folds(data.views.iter().map(|v| v.pose), data.joints.len(), folds)?;
    let rows = data.observations(&data.frames);
    let mut scored = Vec::with_capacity(rows.observations.len());
    for fold in 0..folds {
        let (test, train) = (
            data.keeping(|pose| fold_of_pose[pose] == fold),
            data.keeping(|pose| fold_of_pose[pose] != fold),
        );
        scored.extend(calibrate(&train)?.score(&test)?.observations);
    }
    // Scored fold by fold; summed up in the data's order.
    let fold_of: Vec<usize> = rows.observations.iter().map(|o| fold_of_pose[o.pose()]).collect();
    Ok(Score::of(super::in_data_order(scored, &fold_of, folds), &rows.observations))
}

/// A tree calibrated from camera views: its `calibrated` the tree with the estimates folded
/// into its joints ([`TreeParams::fold`]), its set-up the cameras' and targets' placements
/// ([`SetUp::with_views`], `(x, y, z, rx, ry, rz)` mm and rad, 6 per frame, then each later
/// session's own: [`SetUp::slot`]); "before" the nominal tree (its errors all zero).
pub type TreeCalibration = Calibration<RobotTree>;

impl Robot for RobotTree {
    type Data = TreeData;

    /// The views of `data`, each a camera observation between the calibration's frames (every
    /// camera and target of `data` must be one of them).
    fn rows<'d>(c: &TreeCalibration, data: &'d TreeData) -> Result<Cow<'d, KindData>, CalibrationError> {
        if let Some(frame) = data.frames.iter().find(|f| !c.frames().contains(f)) {
            return Err(CalibrationError::Scoring(format!(
                "{}: not a camera or target of the calibration ({})",
                frame.name(c.setup.tips()),
                c.frame_names().join(", ")
            )));
        }
        data.check(c.calibrated.dof(), c.calibrated.branches.len())?;
        Ok(Cow::Owned(data.observations(c.frames())))
    }
}

impl TreeCalibration {
    /// The cameras and targets ([`Frame::name`]).
    pub fn frames(&self) -> &[Frame] {
        self.setup.frames()
    }

    /// The placement of frame `f` as calibrated (in the first session).
    pub fn frame(&self, f: usize) -> Isometry3<f64> {
        self.frame_in(f, 0)
    }

    /// The placement of frame `f` as calibrated in training session `session`.
    pub fn frame_in(&self, f: usize, session: usize) -> Isometry3<f64> {
        isometry(&self.setup.session_values(&self.setup_values.1, session)[6 * f..6 * f + 6])
    }

    /// The frames' names.
    pub fn frame_names(&self) -> Vec<String> {
        self.frames().iter().map(|f| f.name(self.setup.tips())).collect()
    }
}

/// The frames' start values (6 per frame) on the nominal tree, by the [module](self)'s closed
/// form.
fn initial_setup(params: &TreeParams, data: &TreeData) -> Result<Vec<f64>, CalibrationError> {
    let zero = vec![0.0; params.len()];
    let chains: Vec<ChainAt> = params.chains.iter().map(|c| c.with_errors(&zero)).collect();
    let tip = |f: usize, pose: usize| -> Isometry3<f64> {
        data.frames[f].on.map_or(Isometry3::identity(), |b| chains[b].pose(&data.joints[pose]))
    };
    let mut values = vec![0.0; 6 * data.frames.len()];
    let mut placed = vec![false; data.frames.len()];
    if data.position_only {
        // Each device by the rigid registration of its measured points onto the targets' tip
        // origins on the nominal tree; each target's point at its tip's origin.
        for (f, frame) in data.frames.iter().enumerate().filter(|(_, f)| f.role == Role::Camera) {
            let seen: Vec<&View> = data.views.iter().filter(|v| v.camera == f).collect();
            if seen.len() < 3 {
                return Err(CalibrationError::Observations(format!(
                    "{}: {} positions, expected at least 3 not on one line to place it",
                    frame.name(&params.tips),
                    seen.len()
                )));
            }
            let predicted: Vec<Vector3<f64>> =
                seen.iter().map(|v| tip(v.target, v.pose).translation.vector).collect();
            let measured: Vec<Vector3<f64>> =
                seen.iter().map(|v| v.view.fixed_rows::<3>(0).into_owned()).collect();
            let device = super::register(&predicted, &measured).inverse();
            values[6 * f..6 * f + 6].copy_from_slice(placement(&device).as_slice());
        }
        return Ok(values);
    }
    let mut pairs: Vec<(usize, usize)> = data.views.iter().map(|v| (v.camera, v.target)).collect();
    pairs.sort_unstable();
    pairs.dedup();
    // A pair that cannot start its frames leaves them to the others; its error, if none can.
    let mut failed: Vec<((usize, usize), CalibrationError)> = Vec::new();
    for (camera, target) in pairs {
        if placed[camera] && placed[target] {
            continue;
        }
        let views: Vec<(Isometry3<f64>, Isometry3<f64>)> = (data.views.iter())
            .filter(|v| v.camera == camera && v.target == target)
            .map(|v| (tip(camera, v.pose).inverse() * tip(target, v.pose), isometry(v.view.as_slice())))
            .collect();
        match camera_start(&views, super::kinds::CameraSite::World) {
            Ok((c, t)) => {
                for (f, start) in [(camera, c), (target, t)] {
                    if !placed[f] {
                        values[6 * f..6 * f + 6].copy_from_slice(placement(&start).as_slice());
                        placed[f] = true;
                    }
                }
            }
            Err(_) => {
                let [a, b] = [camera, target].map(|f| data.frames[f].name(&params.tips));
                let why = match views.len() {
                    n if n < 3 => format!("{n} views, expected at least 3"),
                    n => format!(
                        "in its {n} views the target turns relative to the camera about one axis only"
                    ),
                };
                let message = format!(
                    "{a} seeing {b}: {why}: the closed-form start of their placements needs 3 views or more, \
                     turning about two axes or more"
                );
                failed.push(((camera, target), CalibrationError::Observations(message)));
            }
        }
    }
    if let Some((_, e)) = failed.into_iter().find(|((a, b), _)| !placed[*a] || !placed[*b]) {
        return Err(e);
    }
    Ok(values)
}

/// The one pipeline's preparation of `data`'s views (`observed`) on the tree of `params`: the
/// cameras' and targets' placements started by the [module](self)'s closed form
/// ([`initial_setup`]), the tree's parameters `options` asks for, `--hold`'s held.
fn prepared(
    params: &TreeParams,
    observed: &TreeRows,
    data: &TreeData,
    options: &KindOptions,
) -> Result<Prepared, CalibrationError> {
    let start = initial_setup(params, data)?;
    let asked = params.selection(&params.select(&options.joints)?);
    let rows = &observed.rows;
    let sessions = (0..rows.session_count()).map(|k| rows.session_name(k)).collect();
    let per_session = kinds::matching(&observed.setup.base_names(), &options.per_session)?;
    let setup = (observed.setup.clone().with_sessions(sessions, per_session), start);
    Prepared::of_branches(params.chains.clone(), params.set.clone(), setup, asked, &options.gauge.hold)
}

/// Each of `fixed` that no observation moves, said why where the data say it: a point's
/// orientation (a reflector seen by its position), or a joint no view can see
/// ([`TreeParams::unseen`]).
fn say_why_unseen(fixed: &mut [Held], params: &TreeParams, data: &TreeData) {
    for f in fixed {
        let Held::Unmoved { parameter } = f else { continue };
        let turn = ["rx", "ry", "rz"].iter().any(|r| parameter.ends_with(&format!(".{r}")));
        let why = match data.position_only && parameter.starts_with("target.") && turn {
            true => Some("a point measured by its position has no orientation: not seen".to_string()),
            false => params.unseen(parameter, data),
        };
        if let Some(why) = why {
            *f = Held::Unseen { parameter: std::mem::take(parameter), why };
        }
    }
}

/// Why views cannot see the tree's base: a frame in the world absorbs it, or views see only
/// frames relative to each other.
fn base_unseen(params: &TreeParams, data: &TreeData) -> Unseen {
    let world = data.frames.iter().find(|f| f.on.is_none()).map(|f| f.name(&params.tips));
    Unseen::TreeBase { world }
}

/// The [`EvidenceSystem`](super::kinds::EvidenceSystem) of a tree's views with `options`
/// (their estimator's weights): the tree's parameters `options` asks for (less `--hold`'s),
/// then every camera's and target's placement, linearised about `about` (the tree's full
/// vector and the placements of a calibration of `data`) or, `None`, about the "before" fit
/// (the placements fitted with the tree nominal), as [`calibrate_tree`] starts.
pub(crate) fn evidence_system(
    tree: &RobotTree,
    data: &TreeData,
    options: &KindOptions,
    about: Option<(&[f64], &[f64])>,
) -> Result<super::kinds::EvidenceSystem, CalibrationError> {
    let params = TreeParams::new(tree);
    let observed = TreeRows::new(&params, data, &data.frames)?;
    let prepared = prepared(&params, &observed, data, options)?;
    let started = kinds::start(&prepared, &observed.rows, options)?;
    kinds::evidence_of(&prepared, started, about)
}

/// The linear model of `--select cv` and `bic` ([`super::selection`]) of a tree's views, as of
/// observation files ([`LinearModel::of_started`](super::selection::LinearModel)): linearised
/// once about "before" (the placements fitted, the tree nominal). Each view's rows are in the
/// fold of its pose; a position coordinate counts a third of one scored error, a rotation
/// none: the CV RMS is of the view positions (mm), as `--folds` scores them.
pub(crate) fn selection_model(
    tree: &RobotTree,
    data: &TreeData,
    options: &KindOptions,
) -> Result<super::selection::LinearModel, CalibrationError> {
    let params = TreeParams::new(tree);
    let observed = TreeRows::new(&params, data, &data.frames)?;
    let prepared = prepared(&params, &observed, data, options)?;
    let started = kinds::start(&prepared, &observed.rows, options)?;
    let n = data.rows();
    let rows: Vec<(usize, f64)> = (data.views.iter())
        .flat_map(|v| (0..n).map(move |r| (v.pose, if r < 3 { 1.0 / 3.0 } else { 0.0 })))
        .collect();
    let mut fixed = started.gauged.fixed.clone();
    say_why_unseen(&mut fixed, &params, data);
    Ok(super::selection::LinearModel::of_started(&prepared, &started, rows, fixed))
}

/// Calibrate `tree` from camera views between its branches by the one pipeline of every
/// observation (as [`kinds::calibrate_kinds`] fits): the cameras and targets fitted with
/// the tree nominal ("before"), then the joint parameters asked for with them ("after"); the
/// base and what the views cannot see held and said ([`TreeCalibration::unseen`]), what the
/// poses cannot tell apart held by the rank-revealing solve ([`TreeCalibration::fixed`]).
pub fn calibrate_tree(
    tree: &RobotTree,
    data: &TreeData,
    options: &KindOptions,
) -> Result<TreeCalibration, CalibrationError> {
    let params = TreeParams::new(tree);
    let observed = TreeRows::new(&params, data, &data.frames)?;
    if let Some(noise) = &options.joint_noise
        && noise.shape() != (tree.dof(), tree.dof())
    {
        return Err(CalibrationError::Observations(format!(
            "joint noise of {} x {}, expected {} x {} (one row per tree joint)",
            noise.nrows(),
            noise.ncols(),
            tree.dof(),
            tree.dof()
        )));
    }
    let prepared = prepared(&params, &observed, data, options)?;
    let started = kinds::start(&prepared, &observed.rows, options)?;
    let spread = started.prior_spread.map(|s| s / started.weights.scale().unwrap_or(1.0));
    let before_setup = started.before_setup.clone();
    let kinds::Fitted { refined, robust, mut fixed, after, after_setup, change } =
        kinds::fit_gauged(&prepared, started, options)?;
    say_why_unseen(&mut fixed, &params, data);
    // A pose's weight is each of its views' (every row of a view has it).
    let robust =
        robust.map(|r| RobustFit { weights: r.weights.iter().step_by(data.rows()).copied().collect(), ..r });
    let calibration = Calibration {
        calibrated: params.fold(tree, &after),
        before: vec![0.0; after.len()],
        after,
        setup_values: (before_setup, after_setup),
        refined,
        unseen: vec![base_unseen(&params, data)],
        fixed: prepared.every_held(fixed),
        training: Score::default(),
        setup: prepared.setup.clone(),
        markers: Vec::new(),
        variance_factor: None,
        registered_base: None,
        tip_frame: None,
        joint_noise: options.joint_noise.clone(),
        chains: params.chains.clone(),
        branches: true,
        nothing: params.selection(&[]),
        robust,
        prior_sd: prior_sds_of(&options.prior, &params.params.iter().collect::<Vec<_>>())?,
        warnings: Vec::new(),
        noise_estimate: None,
        noise_settled: None,
        params: params.set,
    };
    let unscored = Unscored { calibration, fitted_on: None, spread, change };
    unscored.scored((&tree.name, &tree.joints), &observed.rows)
}
