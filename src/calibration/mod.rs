//! Calibrating a real robot from what was measured: marker positions, a probe's poses,
//! distances, plane contacts, coordinates and camera views through one pipeline ([`kinds`]),
//! a tree's views ([`tree`]), and the choices made from the data over both ([`front`]:
//! [`selection`], [`prior_scale`], [`robust`] losses, over the types and the trait of
//! [`choice`]).
//!
//! 1. Registration: the measuring device never shares the robot's frame, so where markers are
//!    measured the base is first placed by the best rigid fit (Kabsch 1976) of the nominal
//!    marker positions onto the measured ones.
//! 2. "Before": the set-up (base, markers, tool point, pivots, planes, cameras' mountings)
//!    fitted with the robot's joints nominal. This is the robot as it is, seen from the
//!    device; its errors are what calibration has to beat.
//! 3. "After": the joint parameters estimated with the set-up, by Gauss-Newton (a trust
//!    region) on the chosen estimator. Parameters that the poses cannot tell apart are found by
//!    the rank-revealing solve and held at their values, deterministically (QR with column
//!    pivoting, ties to the earlier parameter); their combinations are reported.
//!
//! Errors are in mm and rad inside, and are folded into a calibrated model at the end.

pub mod choice;
mod data;
pub mod diagnostics;
pub mod front;
pub mod kinds;
pub mod noise_check;
pub mod prior_scale;
mod regauge;
mod repeatability;
pub mod robust;
pub mod selection;
pub mod tree;

pub use choice::Front;
pub use data::{DataKind, Measurements};
pub use diagnostics::{
    BaseAbsorber, Cause, ComponentMove, Confounder, FLAG_AT, FarOut, Held, OutsidePose, Scored, Unseen,
    Warning,
};
pub use front::{Kinds, Tree};
pub use repeatability::{
    Repeatability, RepeatabilityData, RepeatabilityOptions, RepeatedPose, repeatability,
};
pub use robust::{Loss, RobustFit};
pub use selection::{
    Choices, Chosen, ChosenFit, Criterion, FoldChoices, Nested, SelectionPath, calibrate_chosen, choose,
    cross_validate_choices, select,
};

use crate::estimation::{
    EstimationError, JointComponents, NoiseEstimate, PriorError, RefineOptions, Refined, Weights, refine_from,
};
use crate::kinematics::Chain;
use crate::model::{ParamKind, ParamOwner, ParamSet, Placement, RobotModel, Selection, SelectionError, Tool};
use nalgebra::{DMatrix, DVector, Isometry3, Matrix3, Rotation3, Translation3, UnitQuaternion, Vector3};

/// What `--params` (and Python's `params`) names: a parameter set, or parameter names and
/// patterns; read by [`ParamWords::parse`], one reader for the command line and Python.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum ParamWords {
    /// Every joint parameter.
    Joints,
    /// Every parameter: the joints, the base and the tool (the markers in `calibrate`).
    All,
    /// The joint offsets.
    Offsets,
    /// No joint parameter (`calibrate` only: the base and the markers).
    None,
    /// These names and patterns (`j*.theta`, `j2.a`).
    Named(Vec<String>),
}

impl ParamWords {
    /// `joints`, `all`, `offsets`, `none`, or comma-separated names and patterns; a set's word
    /// among names, or nothing at all, is refused, saying what is expected.
    pub fn parse(text: &str) -> Result<Self, String> {
        let set = match text.trim() {
            "joints" => Self::Joints,
            "all" => Self::All,
            "offsets" => Self::Offsets,
            "none" => Self::None,
            _ => {
                let names: Vec<String> =
                    text.split(',').map(str::trim).filter(|s| !s.is_empty()).map(String::from).collect();
                if let Some(word) =
                    names.iter().find(|n| ["joints", "all", "offsets", "none"].contains(&n.as_str()))
                {
                    return Err(format!("`{word}` is a parameter set: give it alone, not with names"));
                }
                if names.is_empty() {
                    return Err("expected joints, all, offsets, none, or parameter names".into());
                }
                Self::Named(names)
            }
        };
        Ok(set)
    }

    /// The joint parameters a calibration identifies: `joints` and `all` every one (`all`
    /// frees the base and the markers too, which each front-end checks against its flags).
    pub fn joint_params(self) -> JointParams {
        match self {
            Self::Joints | Self::All => JointParams::All,
            Self::Offsets => JointParams::Offsets,
            Self::None => JointParams::None,
            Self::Named(names) => JointParams::Named(names),
        }
    }

    /// These parameters among `params` (`All` every one, the base's and the tool's too; `None`
    /// nothing), as a design assesses them.
    pub fn select(&self, params: &ParamSet) -> Result<Selection, SelectionError> {
        Ok(match self {
            Self::Joints => Selection::joints(params),
            Self::All => Selection::all(params),
            Self::Offsets => Selection::offsets(params),
            Self::Named(names) => Selection::by_names(params, names)?,
            Self::None => Selection::from_indices(params, []),
        })
    }
}

/// Which joint parameters to identify.
#[derive(Debug, Clone, PartialEq)]
pub enum JointParams {
    /// Every joint parameter (theta, d, a, alpha, beta of each joint).
    All,
    /// Only the joint offsets.
    Offsets,
    /// None: only the base and the markers.
    None,
    /// These names or patterns (`j*.theta`, `j2.a`).
    Named(Vec<String>),
}

impl JointParams {
    /// These parameters among `params`.
    pub fn select(&self, params: &ParamSet) -> Result<Selection, SelectionError> {
        Ok(match self {
            Self::All => Selection::joints(params),
            Self::Offsets => Selection::offsets(params),
            Self::None => Selection::from_indices(params, []),
            Self::Named(names) => Selection::by_names(params, names)?,
        })
    }
}

/// The user's override of the gauge: names or patterns as [`JointParams::Named`] takes them
/// (`j*.beta`, `j2.d`). By default, of a combination the poses cannot tell apart, the base and
/// the markers stay free (what they absorb, the first joint's parameters along and about its
/// axis and the last joint's with the markers, is held); then the offsets, `a`, `alpha` and a
/// URDF origin's six stay free before Hayati's `beta` and a revolute joint's `d`; within those
/// the rank-revealing pivoting decides, the same on every machine.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct Gauge {
    /// Held at their nominal values (base and markers: at the registration), never estimated.
    pub hold: Vec<String>,
    /// Kept free before every other parameter, the base and the markers included, when the
    /// poses cannot tell a combination apart and one of it must be held.
    pub keep: Vec<String>,
}

/// Why a calibration could not be done.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum CalibrationError {
    /// The estimation failed.
    #[error(transparent)]
    Estimation(#[from] EstimationError),
    /// A named parameter does not exist.
    #[error(transparent)]
    Selection(#[from] SelectionError),
    /// A prior names no parameter of its unit.
    #[error(transparent)]
    Prior(#[from] PriorError),
    /// Too few poses for the parameters.
    #[error(
        "{poses} poses give {equations} equations for {parameters} parameters: measure more poses (at \
         least {needed}) or identify fewer parameters"
    )]
    TooFewPoses {
        /// Poses given.
        poses: usize,
        /// Equations they give.
        equations: usize,
        /// Parameters asked for.
        parameters: usize,
        /// Poses needed for one redundant equation.
        needed: usize,
    },
    /// A point of the options (the tool point, a marker's nominal position) that is not three
    /// finite numbers of magnitude at most [`MAX_LENGTH_MM`](crate::limits::MAX_LENGTH_MM).
    #[error(
        "{field}: ({}, {}, {}) mm: expected three finite numbers, each of magnitude at most {:e} mm",
        value[0], value[1], value[2], crate::limits::MAX_LENGTH_MM
    )]
    Point {
        /// Which point: the tool, or a marker.
        field: PointName,
        /// What was given (mm).
        value: [f64; 3],
    },
    /// A k-fold cross-validation of other than 2 to the number of poses folds.
    #[error("{folds} folds for {poses} poses: expected 2 to the number of poses")]
    Folds {
        /// The folds asked for.
        folds: usize,
        /// The poses there are.
        poses: usize,
    },
    /// A set of poses cannot be scored: its markers, or its noise, do not fit the model's.
    #[error("{0}")]
    Scoring(String),
    /// The noise makes a pose's covariance `V_k` singular: joint noise alone spans at most as
    /// many directions as there are joints.
    #[error(
        "the covariance V_k of the pose at line {line} is not positive definite: joint noise alone can leave \
         it singular; give the measurement noise too (--sigma-mm above 0, a sigma column, or a noise file's \
         sigma_me_mm)"
    )]
    SingularCovariance {
        /// The pose's line in the measurement file.
        line: usize,
    },
    /// The poses cannot identify any parameter (all alike, or a system of rank 0).
    #[error("nothing can be identified: {0}")]
    NothingIdentified(String),
    /// Distances, contacts or coordinates that cannot be fitted: too few to place a fixed point
    /// or a plane, a point or plane the calibration has not, data built by hand that does not
    /// hold together (a pose missing, a sigma not above 0).
    #[error("{0}")]
    Observations(String),
}

/// The column-scaled condition number of the identified system above which a calibration
/// warns: its estimates lose more than 6 of 16 digits to the poses' geometry.
pub const CONDITION_WARNING: f64 = 1e6;

/// [`CalibrationError::TooFewPoses`] when `poses` giving `equations` do not outnumber the
/// `unanchored` parameters (those without a prior, which anchors the others): with no
/// redundant equation the rank cannot tell structure from lack of data. The poses needed for
/// one redundant equation at the data's mean equations per pose,
/// `ceil((unanchored + 1) poses / equations)`: every kind of observation, one rule.
pub(crate) fn enough_equations(
    poses: usize,
    equations: usize,
    unanchored: usize,
) -> Result<(), CalibrationError> {
    if equations > unanchored {
        return Ok(());
    }
    let needed = ((unanchored + 1) * poses).div_ceil(equations.max(1));
    Err(CalibrationError::TooFewPoses { poses, equations, parameters: unanchored, needed })
}

/// A point of a calibration's options, as [`CalibrationError::Point`] names it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum PointName {
    /// The tool point (`--tool`).
    Tool,
    /// Marker `m`, numbered from 1 as `--marker` gives them.
    Marker(usize),
}

impl std::fmt::Display for PointName {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Tool => write!(f, "tool"),
            Self::Marker(m) => write!(f, "marker {m}"),
        }
    }
}

/// [`CalibrationError::Point`] unless the tool point `tool` (if any) and every marker of
/// `markers` are finite and within [`MAX_LENGTH_MM`](crate::limits::MAX_LENGTH_MM): a NaN
/// start never reaches the solver.
pub(crate) fn check_points(
    tool: Option<&Vector3<f64>>,
    markers: &[Vector3<f64>],
) -> Result<(), CalibrationError> {
    let named = tool.map(|t| (PointName::Tool, t));
    let markers = markers.iter().enumerate().map(|(m, p)| (PointName::Marker(m + 1), p));
    for (field, p) in named.into_iter().chain(markers) {
        if !p.iter().all(|v| v.is_finite() && v.abs() <= crate::limits::MAX_LENGTH_MM) {
            return Err(CalibrationError::Point { field, value: [p.x, p.y, p.z] });
        }
    }
    Ok(())
}

/// Refused when every one of the `poses` (file line, joint values) has the joint values of the
/// first: nothing can then be identified.
fn different_poses<'q>(mut poses: impl Iterator<Item = (usize, &'q [f64])>) -> Result<(), CalibrationError> {
    let Some((line, first)) = poses.next() else { return Ok(()) };
    let mut count = 1;
    for (_, q) in poses {
        if q != first {
            return Ok(());
        }
        count += 1;
    }
    Err(CalibrationError::NothingIdentified(format!(
        "all {count} poses have the joint values of line {line}: measure the robot at different poses"
    )))
}

/// A held parameter, typed: the combination `c` of the parameters `names` (by column) that
/// the poses cannot tell apart, and what it shares its effect with, by the parameters'
/// `owners` (`None`: a set-up parameter, a fixed point's, a plane's). A parameter confounded
/// with the base alone only moves the whole robot as the base does; with the points on the
/// last link alone (markers, the tool point), those points as their positions do
/// ([`Confounder`]). A set-up parameter held is a plain [`Held::Combination`].
pub(crate) fn why_held(
    c: &crate::estimation::Combination,
    names: &[String],
    owners: &[Option<ParamOwner>],
) -> Held {
    let (parameter, terms) =
        (names[c.column].clone(), c.terms.iter().map(|&(j, v)| (names[j].clone(), v)).collect());
    let Some(owner) = owners[c.column] else { return Held::Combination { parameter, terms } };
    let of_terms: Vec<Option<ParamOwner>> = c.terms.iter().map(|&(t, _)| owners[t]).collect();
    let only = |f: fn(&ParamOwner) -> bool| {
        !of_terms.is_empty() && of_terms.iter().all(|o| o.as_ref().is_some_and(f))
    };
    let with = if !matches!(owner, ParamOwner::Joint(_)) {
        Confounder::Keep
    } else if only(|o| *o == ParamOwner::Base) {
        Confounder::Base
    } else if only(|o| matches!(o, ParamOwner::Marker(_) | ParamOwner::Tool)) {
        Confounder::Markers
    } else {
        Confounder::Poses
    };
    Held::Confounded { parameter, terms, with }
}

/// The residuals' spread `sqrt(|r|^2 / (N_m - rank))` of `problem` fitted without priors from
/// `start` (its identifiable columns, linearised with `weights`): the standard deviation of a
/// row that the priors weigh against when the noise is a guess (every calibration's, one rule).
pub(crate) fn spread_of_fit(
    problem: &impl crate::estimation::Residuals,
    weights: &Weights,
    start: crate::estimation::Linearisation,
) -> Result<f64, CalibrationError> {
    let fitted = refine_from(problem, weights, start, &RefineOptions::default())?;
    let dof = problem.equations().saturating_sub(fitted.estimate.diagnostics.rank).max(1);
    Ok((fitted.estimate.cost / dof as f64).sqrt())
}

/// `asked` without the compliances and plays of joints that gravity does not load at the poses
/// `joints` (every load below 1e-9 of the largest: a vertical axis, a joint carrying no mass)
/// on `chain` with errors `x`, and why each of those is held; the payload's mass too where
/// every compliance is zero at `x` (its column vanishes: [`without_unloaded_joints`] keeps it,
/// for the gauge found again at the estimate to free).
pub(crate) fn without_unloaded_responses(
    asked: &Selection,
    chain: &Chain,
    x: &[f64],
    joints: &[Vec<f64>],
) -> (Selection, Vec<Held>) {
    let (asked, mut why) = without_unloaded_joints(asked, chain, x, joints);
    let params = chain.params();
    // The payload's mass moves the arm only through the compliances: with every one zero at
    // `x`, its column vanishes.
    let payload =
        params.index_of(ParamOwner::Payload, ParamKind::Mass).filter(|&i| asked.column(i).is_some());
    let Some(i) = payload.filter(|_| !chain.with_errors(x).deflects()) else { return (asked, why) };
    why.push(Held::Unseen {
        parameter: params.get(i).name.clone(),
        why: "the payload is seen only through the joints' compliances, all zero here: calibrate the \
              compliances first (with a known payload or none), then its mass with the calibrated model"
            .into(),
    });
    let kept = asked.indices().iter().copied().filter(|&k| k != i);
    (Selection::from_indices(params, kept), why)
}

/// `asked` without the compliances and plays of joints that gravity does not load at the poses
/// `joints` (every load below 1e-9 of the largest: a vertical axis, a joint carrying no mass)
/// on `chain` with errors `x`, each held as [`Held::Unloaded`]: what no load can ever move,
/// wherever the estimate goes.
pub(crate) fn without_unloaded_joints(
    asked: &Selection,
    chain: &Chain,
    x: &[f64],
    joints: &[Vec<f64>],
) -> (Selection, Vec<Held>) {
    let params = chain.params();
    let responses: Vec<(usize, usize)> = (asked.indices().iter())
        .filter_map(|&i| match params.get(i).owner {
            ParamOwner::Joint(j) if params.get(i).is_load_response() => Some((i, j)),
            _ => None,
        })
        .collect();
    if responses.is_empty() {
        return (asked.clone(), Vec::new());
    }
    let at = chain.with_errors(x);
    let dof = chain.dof();
    let mut largest = vec![0.0f64; dof];
    let mut tau = vec![0.0; dof];
    for q in joints {
        at.gravity_torques(q, &mut tau);
        largest.iter_mut().zip(&tau).for_each(|(m, t)| *m = m.max(t.abs()));
    }
    let heaviest = largest.iter().copied().fold(0.0, f64::max);
    let unloaded: Vec<usize> =
        responses.iter().filter(|&&(_, j)| largest[j] <= 1e-9 * heaviest).map(|&(i, _)| i).collect();
    let why = unloaded.iter().map(|&i| Held::Unloaded { parameter: params.get(i).name.clone() }).collect();
    let kept = asked.indices().iter().copied().filter(|i| !unloaded.contains(i));
    (Selection::from_indices(params, kept), why)
}

/// The gauge: which of a combination the poses cannot tell apart is held, by class (the lower
/// stays free first). The parameters of [`Gauge::keep`] come before all others. Then class 0:
/// the measuring frame (base) and the markers, since no external device shares the robot's
/// frame; so what the base absorbs is held (the first joint's offset and its parameters along
/// and about the first axis; a prismatic first joint's zero), and what free markers absorb
/// (the last joint's offset and the parameters of its axis). Between joint parameters, class 1:
/// the joint offsets, `a`, `alpha` and a URDF joint's origin; then class 2: Hayati's `beta`
/// and the `d` of a revolute joint, which nearly parallel axes make redundant, so they are held
/// first; last (class 3) a joint's play, which is its offset wherever the load keeps one sign,
/// and the payload's mass. The compliances are in class 1. Within a class the rank-revealing
/// pivoting decides (the best conditioned choice, ties to the earlier parameter), the same on
/// every machine.
pub(crate) fn gauge_class(p: &crate::model::ParamInfo) -> u32 {
    match (p.owner, p.kind) {
        (ParamOwner::Joint(_), ParamKind::Play) | (ParamOwner::Payload, _) => 3,
        (ParamOwner::Joint(_), ParamKind::Beta) => 2,
        (ParamOwner::Joint(_), ParamKind::D) if !p.is_offset => 2,
        (ParamOwner::Joint(_), _) => 1,
        _ => 0,
    }
}

/// The estimate of no parameters: what [`calibrate`] reports when it only scores.
fn nothing_estimated() -> crate::estimation::LinearEstimate {
    crate::estimation::LinearEstimate {
        names: Vec::new(),
        x: DVector::zeros(0),
        covariance: DMatrix::zeros(0, 0),
        cost: 0.0,
        diagnostics: crate::estimation::Diagnostics {
            rank: 0,
            singular_values: Vec::new(),
            condition_number: f64::NAN,
            identifiable: Vec::new(),
            not_identifiable: Vec::new(),
        },
    }
}

/// Settings of feasible GLS.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FeasibleOptions {
    /// Per-joint variances or the full `Sigma_q`.
    pub joints: JointComponents,
    /// Re-weightings at most.
    pub max_iterations: usize,
    /// Stop when no component changes by more than this fraction of its standard error.
    pub tolerance: f64,
}

impl Default for FeasibleOptions {
    fn default() -> Self {
        Self { joints: JointComponents::Diagonal, max_iterations: 20, tolerance: 0.01 }
    }
}

/// What [`reweighted`] ends with: the last calibration, the last estimate (settled: from that
/// calibration's residuals; else the one it was weighted with), and whether the components
/// settled.
pub(crate) struct Reweighted<C> {
    pub(crate) calibration: C,
    pub(crate) estimate: NoiseEstimate,
    pub(crate) settled: bool,
    /// Unsettled: the components that moved in the last re-weighting.
    pub(crate) moving: Vec<ComponentMove>,
}

/// The rounds of feasible GLS over any calibration `C`: `calibrate(None)` by ordinary least
/// squares; then, up to `feasible.max_iterations` times, the components estimated from its
/// residuals (`estimate(c, previous)`, `previous` the estimate `c` was weighted with, where
/// the fit of the components starts) and `calibrate(Some(estimate))` with them, until no
/// component moves by more than `feasible.tolerance` of its standard error between two
/// rounds (settled: the calibration of the round before, and the estimate from its residuals).
pub(crate) fn reweighted<C>(
    feasible: &FeasibleOptions,
    calibrate: impl Fn(Option<&NoiseEstimate>) -> Result<C, CalibrationError>,
    estimate: impl Fn(&C, Option<&NoiseEstimate>) -> Result<NoiseEstimate, CalibrationError>,
) -> Result<Reweighted<C>, CalibrationError> {
    let mut calibration = calibrate(None)?;
    let (mut previous, mut moving): (Option<NoiseEstimate>, Vec<ComponentMove>) = (None, Vec::new());
    for _ in 0..feasible.max_iterations.max(1) {
        let next = estimate(&calibration, previous.as_ref())?;
        if let Some(p) = &previous {
            moving = moved(p, &next, feasible.tolerance);
            if moving.is_empty() {
                return Ok(Reweighted { calibration, estimate: next, settled: true, moving });
            }
        }
        calibration = calibrate(Some(&next))?;
        previous = Some(next);
    }
    let estimate = previous.expect("at least one round");
    Ok(Reweighted { calibration, estimate, settled: false, moving })
}

/// The components of `next` that moved from `previous` by more than `tolerance` of their
/// standard error: `|theta_next - theta_previous| > tolerance * SE(theta_next)`.
fn moved(previous: &NoiseEstimate, next: &NoiseEstimate, tolerance: f64) -> Vec<ComponentMove> {
    (0..next.fit.values.len())
        .filter_map(|c| {
            let (se, value) = (next.fit.standard_error(c), next.fit.values[c]);
            let change = (previous.fit.values[c] - value).abs();
            (change > tolerance * se).then(|| ComponentMove {
                component: next.component_name(c),
                by: change / se,
                barely_determined: value.abs() < se,
            })
        })
        .collect()
}

/// [`Warning::NoiseUnsettled`] unless `r` settled, with the components still moving.
pub(crate) fn unsettled<C>(feasible: &FeasibleOptions, r: &Reweighted<C>) -> Option<Warning> {
    (!r.settled).then(|| Warning::NoiseUnsettled {
        reweightings: feasible.max_iterations.max(1),
        tolerance: feasible.tolerance,
        moving: r.moving.clone(),
    })
}

/// The probe's placement on the last link: at the nominal marker position `at`, turned by the
/// chordal mean of what each pose (joints `q`, measured rotation `R_measured`) says the
/// mounting rotation is, `R_arm(q)^-1 R_measured`.
pub(crate) fn probe_mounting<'a>(
    model: &RobotModel,
    at: Vector3<f64>,
    poses: impl Iterator<Item = (&'a Vec<f64>, &'a UnitQuaternion<f64>)>,
) -> Placement {
    let unturned = Placement { xyz: at, rpy: Vector3::zeros() };
    let chain = Chain::probe(model, &unturned);
    let arm = chain.with_errors(&vec![0.0; chain.params().len()]);
    let mut sum = Matrix3::zeros();
    for (q, r) in poses {
        sum += (arm.pose(q).rotation.inverse() * r).to_rotation_matrix().into_inner();
    }
    let rotation = UnitQuaternion::from_rotation_matrix(&nearest_rotation(&sum));
    Placement::from_isometry(&Isometry3::from_parts(Translation3::from(at), rotation))
}

/// The rotation nearest to `m` in the Frobenius norm: `U diag(1, 1, det) V^T` from its SVD.
fn nearest_rotation(m: &Matrix3<f64>) -> Rotation3<f64> {
    let svd = m.svd(true, true);
    let (u, v_t) = (svd.u.expect("asked for U"), svd.v_t.expect("asked for V"));
    let mut d = Matrix3::identity();
    d[(2, 2)] = (u * v_t).determinant().signum();
    Rotation3::from_matrix_unchecked(u * d * v_t)
}

/// The rigid transform `T` minimising `sum |measured - T predicted|^2` (Kabsch 1976).
pub(crate) fn register(predicted: &[Vector3<f64>], measured: &[Vector3<f64>]) -> Isometry3<f64> {
    let n = predicted.len() as f64;
    let (cp, cm) = (predicted.iter().sum::<Vector3<f64>>() / n, measured.iter().sum::<Vector3<f64>>() / n);
    let mut cross = Matrix3::zeros();
    for (p, m) in predicted.iter().zip(measured) {
        cross += (m - cm) * (p - cp).transpose();
    }
    let rotation = nearest_rotation(&cross);
    let translation = cm - rotation * cp;
    Isometry3::from_parts(Translation3::from(translation), UnitQuaternion::from_rotation_matrix(&rotation))
}

/// `model` with its base placed by the registration `T` ([`register`]) of the nominal marker
/// positions `predicted` (with its base `base_0`) onto the `measured` ones: `base = T base_0`.
pub(crate) fn with_registered_base(
    model: &RobotModel,
    predicted: &[Vector3<f64>],
    measured: &[Vector3<f64>],
) -> RobotModel {
    let mut out = model.clone();
    out.base = Placement::from_isometry(&(register(predicted, measured) * model.base.isometry()));
    out
}

/// `model` with the parameter errors `x` folded into its numbers; the tool becomes the point
/// `tool` of `markers` (marker 1 for `calibrate`), or the probe at it.
pub(crate) fn fold(
    model: &RobotModel,
    params: &ParamSet,
    x: &[f64],
    (markers, tool): (&[Vector3<f64>], usize),
    probe: Option<&Placement>,
) -> RobotModel {
    let mut out = model.clone();
    let value = |owner, kind| params.index_of(owner, kind).map_or(0.0, |i| x[i]);
    // A displacement Trans(x, y, z) Rx(rx) Ry(ry) Rz(rz), as the kinematics applies it.
    let displacement = |owner| {
        let v = |kind| value(owner, kind);
        Isometry3::translation(v(ParamKind::X), v(ParamKind::Y), v(ParamKind::Z))
            * UnitQuaternion::from_euler_angles(v(ParamKind::Rx), 0.0, 0.0)
            * UnitQuaternion::from_euler_angles(0.0, v(ParamKind::Ry), 0.0)
            * UnitQuaternion::from_euler_angles(0.0, 0.0, v(ParamKind::Rz))
    };
    for (i, joint) in out.joints.iter_mut().enumerate() {
        let owner = ParamOwner::Joint(i);
        joint.compliance += value(owner, ParamKind::Compliance);
        joint.play += value(owner, ParamKind::Play);
        let (theta, d) = (value(owner, ParamKind::Theta), value(owner, ParamKind::D));
        if model.convention == crate::model::Convention::Urdf {
            // URDF has no offset: it turns (or shifts) the origin about (along) the axis.
            let offset = Isometry3::rotation(joint.axis * theta)
                * Isometry3::translation(joint.axis.x * d, joint.axis.y * d, joint.axis.z * d);
            joint.origin =
                Placement::from_isometry(&(joint.origin.isometry() * displacement(owner) * offset));
            continue;
        }
        joint.theta += theta;
        joint.d += d;
        joint.a += value(owner, ParamKind::A);
        joint.alpha += value(owner, ParamKind::Alpha);
        joint.beta += value(owner, ParamKind::Beta);
    }
    if let Some(payload) = &mut out.payload {
        payload.mass += value(ParamOwner::Payload, ParamKind::Mass);
    }
    out.base = Placement::from_isometry(&(model.base.isometry() * displacement(ParamOwner::Base)));
    let point = markers.get(tool).copied().unwrap_or_else(Vector3::zeros);
    let mounting = probe.copied().unwrap_or(Placement { xyz: point, rpy: Vector3::zeros() });
    let frame = model.marker_frame().isometry();
    let tool =
        Placement::from_isometry(&(frame * mounting.isometry() * displacement(ParamOwner::Marker(tool))));
    // Markers end up in the last joint frame, as a point tool is; a probe is a frame.
    out.tool = if probe.is_some() { Tool::Frame(tool) } else { Tool::Point(tool.xyz) };
    out
}

/// A [`Warning::IllConditioned`] when the identified system's column-scaled condition number
/// is above [`CONDITION_WARNING`].
pub(crate) fn ill_conditioned(refined: &Refined) -> Option<Warning> {
    let condition_number = refined.estimate.diagnostics.condition_number;
    (condition_number > CONDITION_WARNING).then_some(Warning::IllConditioned { condition_number })
}

/// A [`Warning::NotConverged`] for a fit that stopped at its step limit, with its last step;
/// not for the paper's one-step estimate (`--iterations 1`, a single step is all it takes: a
/// limit above 1 stops at 2 steps at least).
pub(crate) fn not_converged(refined: &Refined) -> Option<Warning> {
    let last = refined.history.last().filter(|_| !refined.converged && refined.history.len() > 1)?;
    let last_fall = (last.cost - last.cost_after) / last.cost.max(f64::MIN_POSITIVE);
    Some(Warning::NotConverged { steps: refined.history.len(), last_step: last.step, last_fall })
}

/// The standard error of each of `params` in `estimate` (NaN for those it did not estimate).
pub(crate) fn standard_errors_of<'a>(
    params: impl Iterator<Item = &'a crate::model::ParamInfo>,
    estimate: &crate::estimation::LinearEstimate,
) -> Vec<f64> {
    let se = estimate.standard_errors();
    let by_name: std::collections::HashMap<&str, f64> =
        estimate.names.iter().map(String::as_str).zip(se.iter().copied()).collect();
    params.map(|p| by_name.get(p.name.as_str()).copied().unwrap_or(f64::NAN)).collect()
}

/// The most compliant a revolute joint may be before it is suspect (rad/N·m): softer than
/// 1000 N·m/rad, a joint's compliance absorbs something else (an error of the geometry, play,
/// a wrong mass).
pub const SOFTEST_COMPLIANCE: f64 = 1e-3;

/// Every estimate of `params` outside a physical [`Bound`](diagnostics::Bound), whatever its
/// standard error `se` (full-vector order, internal units; NaN: none), one warning per bound,
/// the largest first: a joint's length or origin shift corrected from `before` to `after` by
/// more than 10 mm, an angle by more than 5 deg; with the `calibrated` model (its values are
/// the estimates'), a revolute joint's compliance above [`SOFTEST_COMPLIANCE`], any negative
/// compliance, and a revolute joint's play beyond 1 deg. Only the joints' parameters: the base
/// and the markers are the registration's, any size.
pub(crate) fn implausible<'a>(
    params: impl Iterator<Item = &'a crate::model::ParamInfo>,
    (before, after): (&[f64], &[f64]),
    se: &[f64],
    calibrated: Option<&RobotModel>,
) -> Vec<Warning> {
    use diagnostics::{Bound, OutOfRange};
    let mut found: Vec<(Bound, OutOfRange)> = Vec::new();
    for (i, p) in params.enumerate() {
        let ParamOwner::Joint(j) = p.owner else { continue };
        let correction = after[i] - before[i];
        let estimated = se[i].is_finite() || correction != 0.0;
        // A compliance's or a play's value: the calibrated model's (its nominal value and the
        // correction), else the correction.
        let joint = calibrated.and_then(|m| m.joints.get(j));
        let (value, scale, unit, bound) = match (p.kind, p.unit()) {
            (ParamKind::Compliance, unit) if estimated => {
                let c = joint.map_or(correction, |joint| joint.compliance);
                let bound = if c < 0.0 {
                    Some(Bound::Negative)
                } else {
                    (unit == "rad/N·m" && c > SOFTEST_COMPLIANCE).then_some(Bound::Stiffness)
                };
                (c, 1.0, unit, bound)
            }
            (ParamKind::Play, "rad") if estimated => {
                let play = joint.map_or(correction, |joint| joint.play).to_degrees();
                (
                    play,
                    180.0 / std::f64::consts::PI,
                    "deg",
                    (play.abs() > diagnostics::LARGE_PLAY_DEG).then_some(Bound::Play),
                )
            }
            (ParamKind::Compliance | ParamKind::Play | ParamKind::Mass, _) => continue,
            (_, "rad") => {
                let deg = correction.to_degrees();
                (
                    deg,
                    180.0 / std::f64::consts::PI,
                    "deg",
                    (deg.abs() > diagnostics::LARGE_ANGLE_DEG).then_some(Bound::Angle),
                )
            }
            (_, "mm") => (
                correction,
                1.0,
                "mm",
                (correction.abs() > diagnostics::LARGE_CORRECTION_MM).then_some(Bound::Length),
            ),
            _ => continue,
        };
        let Some(bound) = bound else { continue };
        let margin = crate::estimation::Z_95 * se[i] * scale;
        let parameter = p.name.clone();
        found.push((bound, OutOfRange { parameter, value, low: value - margin, high: value + margin, unit }));
    }
    let bounds = [Bound::Length, Bound::Angle, Bound::Stiffness, Bound::Negative, Bound::Play];
    bounds
        .into_iter()
        .filter_map(|bound| {
            let mut estimates: Vec<OutOfRange> =
                found.iter().filter(|(b, _)| *b == bound).map(|(_, e)| e.clone()).collect();
            estimates.sort_by(|a, b| b.value.abs().total_cmp(&a.value.abs()));
            (!estimates.is_empty()).then_some(Warning::Implausible { bound, estimates })
        })
        .collect()
}

/// `folds` of a k-fold cross-validation of `poses` poses: 2 at least, the poses at most.
pub(crate) fn check_folds(folds: usize, poses: usize) -> Result<(), CalibrationError> {
    match (2..=poses).contains(&folds) {
        true => Ok(()),
        false => Err(CalibrationError::Folds { folds, poses }),
    }
}

/// The fold of each pose of a k-fold cross-validation, indexed by pose number (`poses` of
/// them), `usize::MAX` for a pose `held` does not hold: the pose of rank `r` among those held
/// (in number order) goes to fold `r mod folds`. A fold's training data keeps its poses'
/// numbers and holds every other one of them, so a nested split by the numbers alone would
/// leave a fold empty; by rank it splits as the whole data does. At least 2 folds, at most a
/// fold per pose held.
pub(crate) fn pose_folds(
    held: impl Iterator<Item = usize>,
    poses: usize,
    folds: usize,
) -> Result<Vec<usize>, CalibrationError> {
    let mut fold = vec![usize::MAX; poses];
    held.for_each(|p| fold[p] = 0);
    let mut rank = 0;
    for f in fold.iter_mut().filter(|f| **f == 0) {
        *f = rank % folds.max(1);
        rank += 1;
    }
    check_folds(folds, rank)?;
    Ok(fold)
}

/// The held-out items of a k-fold cross-validation, scored fold by fold (`scored`: fold 0's in
/// their order, then fold 1's, ...), put back in the data's order: item `k` of the data was
/// held out in fold `fold_of[k]`.
pub(crate) fn in_data_order<T>(scored: Vec<T>, fold_of: &[usize], folds: usize) -> Vec<T> {
    debug_assert_eq!(scored.len(), fold_of.len(), "one scored item for each of the data's");
    let order = (0..folds).flat_map(|f| (0..fold_of.len()).filter(move |&k| fold_of[k] == f));
    let mut indexed: Vec<(usize, T)> = order.zip(scored).collect();
    indexed.sort_by_key(|(k, _)| *k);
    indexed.into_iter().map(|(_, item)| item).collect()
}

#[cfg(test)]
mod fold_tests {
    /// Poses 0..5 in 2 folds, pose 1 with two items: fold 0 scored poses 0, 2, 4, fold 1
    /// poses 1, 1, 3; put back, every item at its place in the data.
    #[test]
    fn held_out_items_go_back_to_the_datas_order() {
        let pose_of = [0, 1, 1, 2, 3, 4];
        let fold = super::pose_folds(pose_of.into_iter(), 5, 2).unwrap();
        let fold_of: Vec<usize> = pose_of.iter().map(|&p| fold[p]).collect();
        let scored = vec!["p0", "p2", "p4", "p1a", "p1b", "p3"];
        assert_eq!(super::in_data_order(scored, &fold_of, 2), ["p0", "p1a", "p1b", "p2", "p3", "p4"]);
    }

    /// A fold's training poses (every other one, numbers kept) split again by their rank: both
    /// inner folds hold poses, where their numbers' parity would put every one in one fold.
    #[test]
    fn a_training_folds_poses_split_by_rank() {
        let fold = super::pose_folds([0, 2, 4, 6, 2].into_iter(), 8, 2).unwrap();
        assert_eq!(fold, [0, usize::MAX, 1, usize::MAX, 0, usize::MAX, 1, usize::MAX]);
        let refused = super::pose_folds([0, 2, 4].into_iter(), 8, 4).unwrap_err().to_string();
        assert!(refused.contains('4') && refused.contains('3'), "{refused}");
    }
}

#[cfg(test)]
mod plausibility_tests {
    use super::*;
    use crate::model::LinkMass;
    use diagnostics::{Bound, OutOfRange};

    /// The PUMA 560 with masses (so that it has compliances and plays), its parameters, and
    /// the index of `name`.
    fn puma() -> (RobotModel, ParamSet) {
        let mut model = RobotModel::preset("puma560").unwrap();
        model.masses = vec![LinkMass { mass: 1.0, com: Vector3::zeros() }; 6];
        let params = model.params();
        (model, params)
    }

    /// Every estimate past its physical bound is warned of whatever its standard error (a
    /// huge one too), one warning per bound with each estimate and its 95% interval, the
    /// largest first; within the bounds, nothing.
    #[test]
    fn every_estimate_past_a_physical_bound_is_warned_whatever_its_se() {
        let (mut model, params) = puma();
        let n = params.len();
        let at = |name: &str| params.index_by_name(name).unwrap();
        let (before, mut after, mut se) = (vec![0.0; n], vec![0.0; n], vec![f64::NAN; n]);
        let mut set = |name: &str, value: f64, sd: f64| {
            after[at(name)] = value;
            se[at(name)] = sd;
        };
        // Within the bounds: 9 mm, 4.9 deg, a 0.9 deg play, a stiffness of 1250 N·m/rad.
        set("j2.a", 9.0, 100.0);
        set("j3.alpha", 4.9f64.to_radians(), 1.0);
        set("j5.play", 0.9f64.to_radians(), 1e-3);
        set("j2.compliance", 8e-4, 1.0);
        model.joints[1].compliance = 8e-4;
        model.joints[4].play = 0.9f64.to_radians();
        // A correction of the base or a marker is the registration's: any size.
        set("base.x", 500.0, 1.0);
        assert_eq!(implausible(params.iter(), (&before, &after), &se, Some(&model)), []);

        let mut set = |name: &str, value: f64, sd: f64| {
            after[at(name)] = value;
            se[at(name)] = sd;
        };
        set("j2.a", 105.0, 85.0);
        set("j3.d", -12.0, 0.5);
        set("j2.theta", (-80f64).to_radians(), 80f64.to_radians());
        set("j2.compliance", 1.33, 5.0);
        set("j3.compliance", -1e-6, 1e-5);
        set("j6.play", 1.5f64.to_radians(), 0.5f64.to_radians());
        model.joints[1].compliance = 1.33;
        model.joints[2].compliance = -1e-6;
        model.joints[5].play = 1.5f64.to_radians();
        let warnings = implausible(params.iter(), (&before, &after), &se, Some(&model));
        let bounds: Vec<Bound> = warnings
            .iter()
            .map(|w| match w {
                Warning::Implausible { bound, .. } => *bound,
                other => panic!("{other}"),
            })
            .collect();
        assert_eq!(bounds, [Bound::Length, Bound::Angle, Bound::Stiffness, Bound::Negative, Bound::Play]);
        let Warning::Implausible { estimates, .. } = &warnings[0] else { unreachable!() };
        let names: Vec<&str> = estimates.iter().map(|e| e.parameter.as_str()).collect();
        assert_eq!(names, ["j2.a", "j3.d"], "the largest first");
        let z = crate::estimation::Z_95;
        assert_eq!(
            estimates[0],
            OutOfRange {
                parameter: "j2.a".into(),
                value: 105.0,
                low: 105.0 - z * 85.0,
                high: 105.0 + z * 85.0,
                unit: "mm"
            }
        );
        warnings_read_as_they_should(&warnings);
    }

    /// The text of each warning of [`every_estimate_past_a_physical_bound_is_warned_whatever_its_se`].
    fn warnings_read_as_they_should(warnings: &[Warning]) {
        let text: Vec<String> = warnings.iter().map(ToString::to_string).collect();
        assert_eq!(
            text[0],
            "2 joint lengths corrected by more than 10 mm, whatever the standard error: j2.a 105.000 mm (95% -61.597 to \
             271.597), j3.d -12.000 mm (95% -12.980 to -11.020); check the model and the units"
        );
        assert_eq!(
            text[1],
            "joint angle corrected by more than 5 deg, whatever the standard error: j2.theta -80.000 deg (95% -236.797 to \
             76.797); a joint zero or an axis this far off: check the model's zeros and conventions"
        );
        assert_eq!(
            text[2],
            "compliance above 1e-3 rad/N·m (a stiffness below 1000 N·m/rad), whatever the standard error: j2.compliance \
             1.330e0 rad/N·m (a stiffness of 0.7519 N·m/rad; 95% -8.470e0 to 1.113e1); softer than a real joint: it \
             absorbs something else (geometry, play, masses)"
        );
        assert!(text[3].starts_with("negative compliance, whatever the standard error: j3.compliance -1.000e-6 rad/N·m (95% -2.060e-5 to 1.860e-5)"), "{}", text[3]);
        assert!(
            text[4].starts_with(
                "play beyond 1 deg, whatever the standard error: j6.play 1.500 deg (95% 0.520 to 2.480)"
            ),
            "{}",
            text[4]
        );
    }

    /// A fit stopped at its step limit is a warning with its last step's size and the cost's
    /// fall; a converged one is not, nor the one-step estimate.
    #[test]
    fn an_unconverged_fit_is_a_warning_with_its_last_step() {
        let step = |cost: f64, cost_after: f64, step: f64| crate::estimation::Iteration {
            cost,
            cost_after,
            step,
            damping: 0.0,
        };
        let mut refined = Refined {
            estimate: nothing_estimated(),
            history: vec![step(10.0, 4.0, 3.0), step(4.0, 3.0, 0.25)],
            converged: false,
        };
        let warning = not_converged(&refined).unwrap();
        assert_eq!(warning, Warning::NotConverged { steps: 2, last_step: 0.25, last_fall: 0.25 });
        assert!(warning.to_string().starts_with(
            "not converged in 2 steps: the last moved a prediction by 2.500e-1 standard deviations and lowered the cost \
             by 2.500e-1 of itself; the estimates and their standard errors are where the fit stopped"
        ));
        refined.converged = true;
        assert_eq!(not_converged(&refined), None);
        // The one-step estimate stops after its step by design.
        refined.converged = false;
        refined.history.pop();
        assert_eq!(not_converged(&refined), None);
    }
}

#[cfg(test)]
mod enough_equations_tests {
    use super::*;

    fn needed(poses: usize, equations: usize, unanchored: usize) -> Option<usize> {
        match enough_equations(poses, equations, unanchored) {
            Ok(()) => None,
            Err(CalibrationError::TooFewPoses { needed, .. }) => Some(needed),
            Err(e) => panic!("{e}"),
        }
    }

    /// One more equation than unanchored parameters passes, as many is refused; the poses
    /// needed give one redundant equation at the data's equations per pose, and no fewer do.
    #[test]
    fn the_poses_needed_give_one_redundant_equation() {
        assert_eq!(needed(2, 12, 11), None);
        assert_eq!(needed(2, 12, 12), Some(3));
        assert_eq!(needed(6, 36, 42), Some(8));
        for (poses, equations, unanchored) in [(3, 10, 10), (5, 7, 30), (1, 6, 6), (4, 24, 40), (0, 0, 3)] {
            let n = needed(poses, equations, unanchored).unwrap();
            let per_pose = equations as f64 / poses.max(1) as f64;
            let at = |n: usize| n as f64 * per_pose;
            if equations > 0 {
                let redundant = (unanchored + 1) as f64;
                assert!(at(n) >= redundant && at(n - 1) < redundant, "{poses} {equations} {unanchored}");
            }
        }
    }
}
