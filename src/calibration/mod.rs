//! Calibrating a real robot from measured marker positions.
//!
//! 1. Registration: the measuring device never shares the robot's frame, so the base is first
//!    placed by the best rigid fit (Kabsch 1976) of the nominal marker positions onto the
//!    measured ones.
//! 2. "Before": the base and the markers fitted, the joints nominal. This is the robot as it
//!    is, seen from the device; its errors are what calibration has to beat. It is fitted by
//!    ordinary least squares whatever the estimator, so that it minimises the very distances
//!    it reports and does not depend on the weighting chosen for step 3.
//! 3. "After": the joint parameters estimated with the base and markers, by Gauss-Newton on
//!    the chosen estimator. Parameters that the poses cannot tell apart are found by the
//!    rank-revealing solve and held at their values, deterministically (QR with column
//!    pivoting, ties to the earlier parameter); their combinations are reported.
//!
//! Errors are in mm and rad inside, and are folded into a calibrated model at the end.

mod data;
pub mod diagnostics;
pub mod evaluation;
pub mod front;
pub mod kinds;
pub mod noise_check;
pub mod prior_scale;
mod regauge;
mod repeatability;
pub mod robust;
pub mod selection;
pub mod tree;

pub use data::{DataKind, Measurements};
pub use diagnostics::{Cause, ComponentMove, Confounder, FarOut, Held, OutsidePose, Scored, Warning};
pub use evaluation::{FLAG_AT, PoseErrors, SetEvaluation, Whitening, pool};
pub use front::{Front, Kinds, Markers, Tree};
pub use repeatability::{
    Repeatability, RepeatabilityData, RepeatabilityOptions, RepeatedPose, repeatability,
};
pub use robust::{Loss, RobustFit};
pub use selection::{
    Choices, Chosen, ChosenFit, Criterion, FoldChoices, Nested, NestedCv, SelectionPath, calibrate_chosen,
    choose, cross_validate_choices, select,
};

use crate::estimation::{
    DeviceError, EstimationError, Estimator, JointComponents, MeasurementClass, MeasurementNoise,
    NoiseEstimate, NoiseLayout, NoiseModel, NoiseSpec, PointProblem, PriorEntry, PriorError, PriorRows,
    RANK_TOLERANCE, RefineOptions, Refined, Residuals, Weights, linearise, prior_sds, refine_from,
    residual_samples,
};
use crate::kinematics::{Chain, Measured, end_positions};
use crate::model::{ParamKind, ParamOwner, ParamSet, Placement, RobotModel, Selection, SelectionError, Tool};
use nalgebra::{DMatrix, DVector, Isometry3, Matrix3, Rotation3, Translation3, UnitQuaternion, Vector3};
use rayon::prelude::*;

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

/// How to calibrate.
#[derive(Debug, Clone, PartialEq)]
pub struct Options {
    /// The estimator: OLS, or a weighted one with `noise`.
    pub estimator: Estimator,
    /// Joint and measurement noise; a `sigma` column of the data replaces the measurement part.
    pub noise: Option<NoiseModel>,
    /// The joint parameters to identify.
    pub joints: JointParams,
    /// Estimate the base (measuring frame to robot): true unless the frames are known to agree.
    pub estimate_base: bool,
    /// Estimate the marker positions on the last link.
    pub estimate_markers: bool,
    /// Nominal marker positions (mm) in the model's [marker frame](RobotModel::marker_frame)
    /// (a URDF's tip link, else the last joint frame); missing ones start at its origin.
    pub markers: Vec<Vector3<f64>>,
    /// Gauss-Newton settings; `max_iterations = 1` is the paper's one-step estimate.
    pub refine: RefineOptions,
    /// Prior standard deviations about the nominal model (maximum a posteriori, see
    /// [`crate::estimation::PriorRows`]): they apply to the parameters `joints` asks for (and
    /// the base and markers, if named); empty: none.
    pub prior: Vec<PriorEntry>,
    /// The loss of each pose's whitened residual ([`robust`]): squared, or a robust one.
    pub loss: Loss,
    /// The user's say in the gauge: parameters held at nominal, parameters kept free first.
    pub gauge: Gauge,
}

impl Default for Options {
    /// `robocal calibrate`'s defaults without a noise model: ordinary least squares of every
    /// joint parameter with the base and the markers, Gauss-Newton to convergence, no prior,
    /// squared loss, the default gauge.
    fn default() -> Self {
        Self {
            estimator: Estimator::Ols,
            noise: None,
            joints: JointParams::All,
            estimate_base: true,
            estimate_markers: true,
            markers: Vec::new(),
            refine: RefineOptions::default(),
            prior: Vec::new(),
            loss: Loss::Squared,
            gauge: Gauge::default(),
        }
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

/// Position errors of measured markers against a model (mm).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct ErrorStats {
    /// Marker measurements compared.
    pub count: usize,
    /// Mean distance.
    pub mean: f64,
    /// Root mean square distance.
    pub rms: f64,
    /// Largest distance.
    pub max: f64,
    /// Root mean square error along x, y and z of the measuring frame.
    pub rms_axis: [f64; 3],
}

impl ErrorStats {
    /// Statistics of error vectors.
    pub fn of(errors: &[Vector3<f64>]) -> Self {
        let n = errors.len().max(1) as f64;
        let norms: Vec<f64> = errors.iter().map(|e| e.norm()).collect();
        let axis = |k: usize| (errors.iter().map(|e| e[k] * e[k]).sum::<f64>() / n).sqrt();
        Self {
            count: errors.len(),
            mean: norms.iter().sum::<f64>() / n,
            rms: (norms.iter().map(|d| d * d).sum::<f64>() / n).sqrt(),
            max: norms.iter().copied().fold(0.0, f64::max),
            rms_axis: [axis(0), axis(1), axis(2)],
        }
    }
}

/// A robot measured with markers: the model with its base placed, one chain per marker, and
/// full parameter vectors for the stages of the calibration.
#[derive(Debug, Clone)]
pub struct Calibration {
    /// The model with the registered base (the start of both stages).
    pub registered: RobotModel,
    /// The calibrated model: every estimate folded in; its tool is marker 1.
    pub calibrated: RobotModel,
    /// Nominal marker positions (mm, last joint frame).
    pub markers: Vec<Vector3<f64>>,
    /// Every parameter: base, joints, markers.
    pub params: ParamSet,
    /// Parameter errors after the base-and-markers fit ("before").
    pub before: Vec<f64>,
    /// Parameter errors after the full calibration ("after").
    pub after: Vec<f64>,
    /// The refined estimate: values, covariance, diagnostics, iterations, by name.
    pub refined: Refined,
    /// Parameters asked for that the poses cannot identify, held fixed: their combinations
    /// with the identified ones, in words.
    pub fixed: Vec<Held>,
    /// Errors on the poses used for fitting, before and after.
    pub training: (ErrorStats, ErrorStats),
    /// The training poses scored pose by pose and marker by marker, before and after.
    pub training_poses: SetEvaluation,
    /// The numbers of the markers fitted (the data's `x<k>` columns), chain by chain.
    pub marker_ids: Vec<usize>,
    /// How residuals are whitened to flag poses: the noise model of the fit, or the spread
    /// of the training residuals without one.
    pub whitening: Whitening,
    /// Feasible GLS only: whether its variance components settled.
    pub noise_settled: Option<bool>,
    /// Things a careful engineer should look at.
    pub warnings: Vec<Warning>,
    /// The noise estimated from the residuals by feasible GLS ([`calibrate_feasible`]).
    pub noise_estimate: Option<NoiseEstimate>,
    /// The prior standard deviation of every parameter (full vector, mm, rad or the
    /// compliance's unit; infinite: no prior).
    pub prior_sd: Vec<f64>,
    /// The robust fit's weights, for a robust loss.
    pub robust: Option<RobustFit>,
    chains: Vec<Chain>,
}

impl Calibration {
    /// Marker position errors of `data` (mm) against the model before and after calibration.
    pub fn validate(&self, data: &Measurements) -> (ErrorStats, ErrorStats) {
        (
            ErrorStats::of(&errors(&self.chains, &self.before, data)),
            ErrorStats::of(&errors(&self.chains, &self.after, data)),
        )
    }

    /// `data` (named `name`) scored before and after, pose by pose and marker by marker, with
    /// the fitted model as it stands (no registration). Its markers must be among the fitted
    /// ones ([`Measurements::with_markers`] picks them). `noise` is the noise model fitted to
    /// `data`'s poses (a device's blocks are per pose), for the whitened residuals; without
    /// it, the calibration's own whitening is used, which must then not be per pose (an
    /// error otherwise).
    pub fn evaluate(
        &self,
        name: &str,
        data: &Measurements,
        noise: Option<&NoiseModel>,
    ) -> Result<SetEvaluation, CalibrationError> {
        let (chains, kind) = self.chains_for(data)?;
        let rows = kind.rows() * chains.len();
        let whitening = match (noise, &self.whitening) {
            (Some(noise), _) => {
                Whitening::Covariance(noise_for(Some(noise.clone()), data, rows).expect("given"))
            }
            (None, Whitening::Covariance(NoiseModel { measurement: MeasurementNoise::PerPoint(_), .. })) => {
                return Err(CalibrationError::Scoring(
                    "the noise has one block per training pose: give the noise at these poses".into(),
                ));
            }
            (None, w) => w.clone(),
        };
        let scored = evaluation::Scored { chains: &chains, marker_ids: &data.marker_ids, kind };
        evaluation::evaluate(
            name,
            &scored,
            data,
            &[("before", &self.before), ("after", &self.after)],
            &whitening,
        )
    }

    /// The calibrated markers, numbered as in the data, positions in the last joint frame
    /// (mm), as the calibrated model's tool is: the nominal ones (in the model's
    /// [marker frame](RobotModel::marker_frame)) with their estimates; empty for a probe (its
    /// frame is the calibrated model's tool).
    pub fn marker_positions(&self) -> Vec<(usize, Vector3<f64>)> {
        let frame = self.registered.marker_frame().isometry();
        if !self.chains.iter().all(Chain::ends_at_a_point) {
            return Vec::new();
        }
        let value =
            |m, kind| self.params.index_of(ParamOwner::Marker(m), kind).map_or(0.0, |i| self.after[i]);
        (self.marker_ids.iter().zip(&self.markers).enumerate())
            .map(|(m, (id, p))| {
                let p =
                    p + Vector3::new(value(m, ParamKind::X), value(m, ParamKind::Y), value(m, ParamKind::Z));
                (*id, frame.transform_point(&p.into()).coords)
            })
            .collect()
    }

    /// A probe's calibrated frame, absolute, in the model's [marker frame](RobotModel::marker_frame)
    /// (a URDF's tip link, else the last joint frame): `T = F^-1 T_tool` with `F` that frame
    /// and `T_tool` the calibrated model's tool frame; `None` for markers.
    pub fn tip_frame(&self) -> Option<Placement> {
        let Tool::Frame(tool) = self.calibrated.tool else { return None };
        if self.chains.iter().all(Chain::ends_at_a_point) {
            return None;
        }
        let frame = self.registered.marker_frame().isometry();
        Some(Placement::from_isometry(&(frame.inverse() * tool.isometry())))
    }

    /// The chains of `data`'s markers.
    fn chains_for(&self, data: &Measurements) -> Result<(Vec<Chain>, Measured), CalibrationError> {
        let kind = if data.orientations.is_some() { Measured::Pose } else { Measured::Position };
        let probe = self.chains.len() == 1 && !self.chains[0].ends_at_a_point();
        if probe != (kind == Measured::Pose) {
            return Err(CalibrationError::Scoring(
                "a probe's calibration is scored on orientations too, and markers' on positions only".into(),
            ));
        }
        let chains = data
            .marker_ids
            .iter()
            .map(|id| {
                let at = self.marker_ids.iter().position(|m| m == id).ok_or_else(|| {
                    CalibrationError::Scoring(format!(
                        "marker {id} was not fitted (fitted: {:?})",
                        self.marker_ids
                    ))
                })?;
                Ok(self.chains[at].clone())
            })
            .collect::<Result<_, CalibrationError>>()?;
        Ok((chains, kind))
    }
}

/// Score `data` with `model` as it stands: its base, its joints, and its markers (`markers`,
/// numbered, mm in the last joint frame; empty: the tool is marker 1, a point or a probe
/// frame). No registration, no fit: the single stage is named `model`. `noise`, fitted to
/// `data`'s poses, whitens the residuals; without it they are divided by their own spread
/// (`sqrt(|r|^2 / N_m)`, nothing being fitted).
pub fn evaluate_model(
    model: &RobotModel,
    markers: &[(usize, Vector3<f64>)],
    name: &str,
    data: &Measurements,
    noise: Option<&NoiseModel>,
) -> Result<SetEvaluation, CalibrationError> {
    let probe = data.orientations.is_some();
    // The chains place markers and probes in the model's marker frame (its tool frame, when the
    // tool is a frame); the markers given are in the last joint frame.
    let frame = model.marker_frame().isometry();
    let (chains, ids): (Vec<Chain>, Vec<usize>) = if probe {
        let at_tool = Placement { xyz: model.tool_point_in_marker_frame(), rpy: Vector3::zeros() };
        (vec![Chain::probe(model, &at_tool)], vec![1])
    } else {
        let given: Vec<(usize, Vector3<f64>)> = if markers.is_empty() {
            vec![(1, model.tool_point_in_marker_frame())]
        } else {
            markers.iter().map(|(id, p)| (*id, frame.inverse_transform_point(&(*p).into()).coords)).collect()
        };
        let mut chosen = Vec::new();
        for id in &data.marker_ids {
            let position = given.iter().find(|(m, _)| m == id).map(|(_, p)| *p).ok_or_else(|| {
                let known: Vec<usize> = given.iter().map(|(m, _)| *m).collect();
                CalibrationError::Scoring(format!("the model has no marker {id} (it has {known:?})"))
            })?;
            chosen.push(position);
        }
        (Chain::markers(model, &chosen), data.marker_ids.clone())
    };
    let kind = if probe { Measured::Pose } else { Measured::Position };
    let zero = vec![0.0; chains[0].params().len()];
    let rows = kind.rows() * chains.len();
    let whitening = match noise {
        Some(noise) => Whitening::Covariance(noise_for(Some(noise.clone()), data, rows).expect("given")),
        None => {
            let r = errors(&chains, &zero, data);
            let rows = r.len() * 3;
            Whitening::Spread((r.iter().map(|e| e.norm_squared()).sum::<f64>() / rows.max(1) as f64).sqrt())
        }
    };
    let scored = evaluation::Scored { chains: &chains, marker_ids: &ids, kind };
    evaluation::evaluate(name, &scored, data, &[("model", &zero)], &whitening)
}

/// Measured minus predicted marker positions of every pose, pose by pose.
fn errors(chains: &[Chain], x: &[f64], data: &Measurements) -> Vec<Vector3<f64>> {
    let at: Vec<_> = chains.iter().map(|c| c.with_errors(x)).collect();
    (data.joints.par_iter().zip(&data.markers))
        .map_init(
            || vec![Vector3::zeros(); chains.len()],
            |predicted, (q, measured)| {
                end_positions(&at, q, predicted);
                measured.iter().zip(predicted.iter()).map(|(m, p)| m - p).collect::<Vec<_>>()
            },
        )
        .flatten_iter()
        .collect()
}

/// Calibrate `model` from `data` with `options`; with a noise model and the squared loss, the
/// noise is checked against the residuals ([`noise_check`]).
pub fn calibrate(
    model: &RobotModel,
    data: &Measurements,
    options: &Options,
) -> Result<Calibration, CalibrationError> {
    calibrate_checking(model, data, options, (true, None))
}

/// [`calibrate`] without the check of the noise: the calibrations inside a choice or a
/// cross-validation, whose warnings nobody reads.
pub(crate) fn calibrate_quietly(
    model: &RobotModel,
    data: &Measurements,
    options: &Options,
) -> Result<Calibration, CalibrationError> {
    calibrate_checking(model, data, options, (false, None))
}

/// The robot before any fit: the base registered to the markers if it is estimated, a
/// probe's mounting started from the data, and the chains of its markers (or its probe).
struct Start {
    registered: RobotModel,
    probe: Option<Placement>,
    markers: Vec<Vector3<f64>>,
    chains: Vec<Chain>,
    kind: Measured,
}

impl Start {
    fn new(model: &RobotModel, data: &Measurements, options: &Options) -> Self {
        let markers: Vec<Vector3<f64>> = (0..data.marker_count())
            .map(|k| options.markers.get(k).copied().unwrap_or_else(Vector3::zeros))
            .collect();
        let mut registered = model.clone();
        if options.estimate_base {
            let chains = Chain::markers(model, &markers);
            let zero = vec![0.0; chains[0].params().len()];
            let measured: Vec<Vector3<f64>> = data.markers.iter().flatten().copied().collect();
            let predicted: Vec<Vector3<f64>> =
                errors(&chains, &zero, data).iter().zip(&measured).map(|(e, m)| m - e).collect();
            registered = with_registered_base(model, &predicted, &measured);
        }
        // With orientations, marker 1 is a probe frame: its mounting rotation starts from the data.
        let probe = data
            .orientations
            .as_ref()
            .map(|measured| probe_mounting(&registered, markers[0], data.joints.iter().zip(measured)));
        let chains = match &probe {
            Some(probe) => vec![Chain::probe(&registered, probe)],
            None => Chain::markers(&registered, &markers),
        };
        let kind = if probe.is_some() { Measured::Pose } else { Measured::Position };
        Self { registered, probe, markers, chains, kind }
    }

    /// The stages of a calibration from this start: `params` fitted to `before`, then `after`.
    fn stages<'a>(&self, data: &'a Measurements, fit: Fit) -> Stages<'a> {
        Stages {
            registered: self.registered.clone(),
            probe: self.probe,
            markers: self.markers.clone(),
            params: fit.params,
            before: fit.before,
            after: fit.after,
            refined: fit.refined,
            fixed: fit.fixed,
            chains: self.chains.clone(),
            noise: fit.noise,
            data,
            marker_ids: data.marker_ids.clone(),
            prior_sd: fit.prior_sd,
            robust: fit.robust,
        }
    }
}

/// What a calibration fitted from its [`Start`].
struct Fit {
    params: ParamSet,
    before: Vec<f64>,
    after: Vec<f64>,
    refined: Refined,
    fixed: Vec<Held>,
    noise: Option<NoiseModel>,
    prior_sd: Vec<f64>,
    robust: Option<RobustFit>,
}

/// The "before" values: the base and markers fitted by ordinary least squares whatever the
/// estimator (the joint parameters at nominal), or zero when nothing of the frame is asked.
fn fit_before(
    base: &PointProblem<'_>,
    params: &ParamSet,
    options: &Options,
) -> Result<Vec<f64>, CalibrationError> {
    let zero = vec![0.0; params.len()];
    let frame = selection(params, &JointParams::None, options)?;
    if frame.is_empty() {
        return Ok(zero);
    }
    let unweighted = Weights::ols_without_noise(base);
    let problem = base.reselect(&frame, zero)?;
    let start = linearise(&problem, &unweighted, problem.start())?;
    let fitted = refine_from(&problem, &unweighted, start, &RefineOptions::default())?;
    Ok(problem.full(&fitted.estimate.x))
}

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

/// Refused when the poses cannot identify what is asked: fewer equations than the parameters
/// without a prior (a parameter with a prior is anchored by it; with fewer equations the rank
/// cannot tell structure from lack of data), or every pose at the same joint values.
fn check_enough_poses(
    data: &Measurements,
    rows: usize,
    asked: &Selection,
    prior_sd: &[f64],
) -> Result<(), CalibrationError> {
    let unanchored = asked.indices().iter().filter(|&&i| !prior_sd[i].is_finite()).count();
    enough_equations(data.len(), data.len() * rows, unanchored)?;
    match asked.is_empty() {
        true => Ok(()),
        false => different_poses(data.lines.iter().copied().zip(data.joints.iter().map(Vec::as_slice))),
    }
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

/// [`calibrate`], the noise checked if `check_noise`: the [`Start`], one problem (and its
/// covariance blocks `V_k`) for every stage, the "before" fit (`known_before` if given: it is
/// the same whatever the noise, as feasible GLS's rounds know), what the poses identify, the
/// robust fit of it, the scores.
fn calibrate_checking(
    model: &RobotModel,
    data: &Measurements,
    options: &Options,
    (check_noise, known_before): (bool, Option<&[f64]>),
) -> Result<Calibration, CalibrationError> {
    check_points(None, &options.markers)?;
    let start = Start::new(model, data, options);
    let rows = start.kind.rows() * start.chains.len();
    let params = start.chains[0].params().clone();
    let noise = noise_for(options.noise.clone(), data, rows);
    let zero = vec![0.0; params.len()];
    let nothing = Selection::from_indices(&params, []);
    let base_problem = PointProblem::new(
        &start.chains,
        &nothing,
        start.kind,
        data.joints.clone(),
        observed(data),
        zero,
        noise.as_ref(),
    )?;
    let weights =
        Weights::for_problem(&base_problem, options.estimator).map_err(|e| at_line(e.into(), data))?;
    let before = match known_before {
        Some(before) if before.len() == params.len() => before.to_vec(),
        _ => fit_before(&base_problem, &params, options)?,
    };
    // "After": everything asked for that the poses can identify.
    let asked = selection(&params, &options.joints, options)?;
    let prior_sd = prior_sds(&options.prior, &params)?;
    check_enough_poses(data, rows, &asked, &prior_sd)?;
    let held_by_flags = held_in_words(&params, &options.joints, options)?;
    if asked.is_empty() {
        // Nothing to estimate: the model as it stands is scored.
        let refined = Refined { estimate: nothing_estimated(), history: Vec::new(), converged: true };
        let fit = Fit {
            params,
            after: before.clone(),
            before,
            refined,
            fixed: held_by_flags,
            noise,
            prior_sd,
            robust: None,
        };
        return finish(start.stages(data, fit), &base_problem);
    }
    let gauged = fit_gauged(&base_problem, &weights, (&asked, &before), data, (options, &prior_sd))?;
    let (kept, refined, robust, after, change) =
        (gauged.gauge.kept, gauged.refined, gauged.fitted, gauged.after, gauged.change);
    let mut fixed = gauged.gauge.fixed;
    fixed.extend(held_by_flags);
    let problem = base_problem.reselect(&kept, after.clone())?;
    let noise_warning = match &noise {
        Some(given) if check_noise => {
            let kept_sd: Vec<f64> = kept.indices().iter().map(|&i| prior_sd[i]).collect();
            noise_check::noise_check(&problem, &refined.estimate.x, given, &kept_sd)
        }
        _ => None,
    };
    let fit = Fit { params, before, after, refined, fixed, noise, prior_sd, robust };
    let mut calibration = finish(start.stages(data, fit), &base_problem)?;
    let poses = data.lines.iter().copied().zip(data.joints.iter().map(Vec::as_slice));
    calibration.warnings.extend(Warning::outside_limits(&model.name, &model.joints, poses));
    calibration.warnings.extend(noise_warning);
    calibration.warnings.extend(change);
    Ok(calibration)
}

/// An [`Identified`] as the fit loop of [`fit_gauged`] takes it: the positions in what is
/// asked for of the parameters it keeps, its start's system until the first fit takes it.
struct Marked {
    kept: Selection,
    columns: Vec<usize>,
    fixed: Vec<Held>,
    start: Option<crate::estimation::Linearisation>,
    prior: Option<PriorRows>,
    data_alone: Option<crate::estimation::Diagnostics>,
}

impl Marked {
    fn new(id: Identified, asked: &Selection) -> Self {
        let columns = (asked.indices().iter().enumerate())
            .filter(|&(_, &i)| id.kept.column(i).is_some())
            .map(|(p, _)| p)
            .collect();
        let Identified { kept, fixed, start, prior, data_alone } = id;
        Self { kept, columns, fixed, start: Some(start), prior, data_alone }
    }
}

impl regauge::Kept for Marked {
    fn kept(&self) -> &[usize] {
        &self.columns
    }

    /// A combination of no other term is a zero column; an unloaded response has none.
    fn unmoved(&self) -> Vec<&str> {
        (self.fixed.iter())
            .filter_map(|h| match h {
                Held::Confounded { parameter, terms, .. } if terms.is_empty() => Some(parameter.as_str()),
                Held::Unloaded { parameter } => Some(parameter.as_str()),
                _ => None,
            })
            .collect()
    }
}

/// What [`fit_gauged`] gives: the last gauge, its fit (the data's identifiability alone where
/// priors were given), the robust fit's record, the values after, what the gauge changed.
struct MarkerFit {
    gauge: Marked,
    refined: Refined,
    fitted: Option<RobustFit>,
    after: Vec<f64>,
    change: Option<Warning>,
}

/// The fit of `asked` from `before` on `base_problem` weighted by `weights`, the gauge found
/// ([`identifiable`]) at "before", then again at the estimate ([`regauge`]).
fn fit_gauged(
    base_problem: &PointProblem<'_>,
    weights: &Weights,
    (asked, before): (&Selection, &[f64]),
    data: &Measurements,
    (options, prior_sd): (&Options, &[f64]),
) -> Result<MarkerFit, CalibrationError> {
    let params = base_problem.params();
    let gauge_at = |at: &[f64]| -> Result<Marked, CalibrationError> {
        let mut full = before.to_vec();
        asked.indices().iter().zip(at).for_each(|(&i, &v)| full[i] = v);
        let id = identifiable(base_problem, weights, asked, &full, data, &options.gauge, Some(prior_sd))?;
        Ok(Marked::new(id, asked))
    };
    let x0: Vec<f64> = asked.indices().iter().map(|&i| before[i]).collect();
    let first = gauge_at(&x0)?;
    let gauge_at = |at: &[f64]| -> Result<(Marked, f64), CalibrationError> {
        let mut g = gauge_at(at)?;
        let weakest =
            regauge::weakest(g.start.as_ref().expect("a gauge found, not fitted"), g.prior.as_ref());
        // Linearised at the settled point, which the next round does not start from: its fit
        // linearises at its own start.
        g.start = None;
        Ok((g, weakest))
    };
    let fit = |g: &mut Marked, at: &[f64], steps: usize| -> Result<(Refined, _), CalibrationError> {
        let mut full = before.to_vec();
        asked.indices().iter().zip(at).for_each(|(&i, &v)| full[i] = v);
        let problem = base_problem.reselect(&g.kept, full)?;
        let start = match g.start.take() {
            Some(start) => start,
            None => linearise(&problem, weights, problem.start())?,
        };
        let refine = RefineOptions { max_iterations: steps, ..options.refine };
        let (mut refined, robust) =
            robust::fit(&problem, weights, start, &refine, g.prior.as_ref(), options.loss)?;
        if let Some(data_alone) = g.data_alone.clone() {
            refined.estimate.diagnostics = data_alone;
        }
        let after = problem.full(&refined.estimate.x);
        Ok((refined, (robust, after)))
    };
    let names: Vec<String> = asked.indices().iter().map(|&i| params.get(i).name.clone()).collect();
    let limit = options.refine.max_iterations;
    let r = regauge::fit_regauged((&x0, &names), first, limit, fit, gauge_at)?;
    let (fitted, after) = r.fitted;
    Ok(MarkerFit { gauge: r.gauge, refined: r.refined, fitted, after, change: r.change })
}

/// What [`identifiable`] finds: the parameters the poses identify, why the others are held,
/// and the system linearised about the "before" values, for the identified columns.
struct Identified {
    kept: Selection,
    fixed: Vec<Held>,
    start: crate::estimation::Linearisation,
    /// The priors' rows for the identified columns, if any parameter has a prior.
    prior: Option<PriorRows>,
    /// With priors, the identifiability of the data alone, to report.
    data_alone: Option<crate::estimation::Diagnostics>,
}

/// The gauge of `asked` at the "before" values `before`: the unloaded compliances held, the
/// system linearised once about `before` and weighted by `weights`, its rank revealed with the
/// identifiable columns chosen by [`gauge_class`] (the user's `gauge.keep` first); every held
/// parameter described with the combination that holds it ([`why_held`]).
fn identifiable(
    base_problem: &PointProblem<'_>,
    weights: &Weights,
    asked: &Selection,
    before: &[f64],
    data: &Measurements,
    gauge: &Gauge,
    prior_sd: Option<&[f64]>,
) -> Result<Identified, CalibrationError> {
    let params = base_problem.params();
    let Loaded { asked, unloaded, at_before, priority } =
        loaded(base_problem, weights, asked, before, data, gauge)?;
    // With priors, what the data and the priors together cannot identify is held: a parameter
    // with a prior never is.
    let asked_sd: Vec<f64> =
        asked.indices().iter().map(|&i| prior_sd.map_or(f64::INFINITY, |s| s[i])).collect();
    let prior = if asked_sd.iter().any(|s| s.is_finite()) {
        let scale = match weights.scale() {
            Some(c) => c,
            None => {
                unregularised_spread(base_problem, params, &asked, before, weights, &at_before, &priority)?
            }
        };
        Some(PriorRows::new(&asked_sd, scale))
    } else {
        None
    };
    let diagnostics = match &prior {
        Some(prior) => at_before.with_prior(prior).diagnose_by_priority(RANK_TOLERANCE, &priority)?,
        None => at_before.diagnose_by_priority(RANK_TOLERANCE, &priority)?,
    };
    if diagnostics.rank == 0 {
        return Err(CalibrationError::NothingIdentified(format!(
            "the identification Jacobian of the {} parameters asked for has rank 0 at these poses",
            asked.len()
        )));
    }
    let names: Vec<String> = asked.indices().iter().map(|&i| params.get(i).name.clone()).collect();
    let owners: Vec<Option<ParamOwner>> =
        asked.indices().iter().map(|&i| Some(params.get(i).owner)).collect();
    let fixed =
        (diagnostics.not_identifiable.iter().map(|c| why_held(c, &names, &owners))).chain(unloaded).collect();
    let kept = Selection::from_indices(params, diagnostics.identifiable.iter().map(|&c| asked.indices()[c]));
    let start = at_before.select(&diagnostics.identifiable);
    // The identifiability the report gives is the data's alone.
    let data_alone = prior.as_ref().map(|_| start.diagnose_data_alone(RANK_TOLERANCE, &[])).transpose()?;
    let prior = prior.map(|p| p.select(&diagnostics.identifiable));
    Ok(Identified { kept, fixed, start, prior, data_alone })
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

/// The results of the stages of [`calibrate`], to be scored and gathered.
struct Stages<'a> {
    registered: RobotModel,
    probe: Option<Placement>,
    markers: Vec<Vector3<f64>>,
    params: ParamSet,
    before: Vec<f64>,
    after: Vec<f64>,
    refined: Refined,
    fixed: Vec<Held>,
    chains: Vec<Chain>,
    noise: Option<NoiseModel>,
    data: &'a Measurements,
    marker_ids: Vec<usize>,
    prior_sd: Vec<f64>,
    robust: Option<RobustFit>,
}

/// The calibration of `s`: the training poses scored on `problem` (the fit's own, with its
/// covariance blocks), the model folded, the warnings.
fn finish(s: Stages<'_>, problem: &PointProblem<'_>) -> Result<Calibration, CalibrationError> {
    let kind = if s.probe.is_some() { Measured::Pose } else { Measured::Position };
    let rank = s.refined.estimate.diagnostics.rank;
    let whitening = match &s.noise {
        Some(noise) => Whitening::Covariance(noise.clone()),
        None => {
            let nothing = Selection::from_indices(&s.params, []);
            let at_after =
                problem.reselect(&nothing, s.after.clone()).expect("the fit's problem has its parameters");
            let mut r = at_after.evaluate(&DVector::zeros(0), None);
            evaluation::in_lengths(&at_after, &mut r);
            let dof = r.len().saturating_sub(rank).max(1);
            Whitening::Spread((r.norm_squared() / dof as f64).sqrt())
        }
    };
    let scored = evaluation::Scored { chains: &s.chains, marker_ids: &s.marker_ids, kind };
    let stages: [(&str, &[f64]); 2] = [("before", &s.before), ("after", &s.after)];
    let training_poses = evaluation::evaluate_on("training", &scored, s.data, &stages, &whitening, problem)
        .map_err(|e| at_line(e, s.data))?;
    let training = (training_poses.pooled[0], training_poses.pooled[1]);
    let calibrated = fold(&s.registered, &s.params, &s.after, (&s.markers, 0), s.probe.as_ref());
    let mut warnings = warnings(&s, &calibrated, &training_poses);
    let condition_number = s.refined.estimate.diagnostics.condition_number;
    if condition_number > CONDITION_WARNING {
        warnings.push(Warning::IllConditioned { condition_number });
    }
    Ok(Calibration {
        registered: s.registered,
        calibrated,
        markers: s.markers,
        params: s.params,
        before: s.before,
        after: s.after,
        refined: s.refined,
        fixed: s.fixed,
        training,
        training_poses,
        marker_ids: s.marker_ids,
        whitening,
        noise_settled: None,
        warnings,
        noise_estimate: None,
        prior_sd: s.prior_sd,
        robust: s.robust,
        chains: s.chains,
    })
}

/// The order in which the rank-revealing solve keeps the columns of `asked`: what
/// `gauge.keep` names first, then by [`gauge_class`].
fn gauge_priority(params: &ParamSet, asked: &Selection, gauge: &Gauge) -> Result<Vec<u32>, SelectionError> {
    let keep = if gauge.keep.is_empty() {
        Selection::from_indices(params, [])
    } else {
        Selection::by_names(params, &gauge.keep)?
    };
    Ok((asked.indices().iter())
        .map(|&i| if keep.column(i).is_some() { 0 } else { 1 + gauge_class(params.get(i)) })
        .collect())
}

/// The noise level that the priors of an OLS fit without a noise model weigh against, as
/// [`calibrate`] takes it at the "before" values `before` ([`unregularised_spread`] of what
/// the poses can load): the residuals' spread of the fit of `asked` without priors (mm).
pub(crate) fn ols_prior_spread(
    base_problem: &PointProblem<'_>,
    weights: &Weights,
    asked: &Selection,
    before: &[f64],
    data: &Measurements,
    gauge: &Gauge,
) -> Result<f64, CalibrationError> {
    let Loaded { asked, at_before, priority, .. } =
        loaded(base_problem, weights, asked, before, data, gauge)?;
    unregularised_spread(base_problem, base_problem.params(), &asked, before, weights, &at_before, &priority)
}

/// What the poses can load of `asked` at the "before" values, linearised there: [`loaded`].
struct Loaded {
    /// `asked` without the unloaded compliances and plays.
    asked: Selection,
    /// Why each of those is held.
    unloaded: Vec<Held>,
    /// The system of `asked` linearised about `before`, weighted by the weights.
    at_before: crate::estimation::Linearisation,
    /// The order the rank-revealing solve keeps its columns in ([`gauge_priority`]).
    priority: Vec<u32>,
}

/// `asked` without the compliances and plays whose joints gravity does not load at these
/// poses (a vertical axis: no column, held and said so), linearised about `before` and weighted
/// by `weights`, with the order of its columns for the rank-revealing solve.
fn loaded(
    base_problem: &PointProblem<'_>,
    weights: &Weights,
    asked: &Selection,
    before: &[f64],
    data: &Measurements,
    gauge: &Gauge,
) -> Result<Loaded, CalibrationError> {
    let (asked, unloaded) =
        without_unloaded_responses(asked, &base_problem.chains()[0], before, &data.joints);
    let problem = base_problem.reselect(&asked, before.to_vec())?;
    let at_before = linearise(&problem, weights, problem.start())?;
    let priority = gauge_priority(base_problem.params(), &asked, gauge)?;
    Ok(Loaded { asked, unloaded, at_before, priority })
}

/// The scale of the rows of an OLS fit without a noise model, for its priors: the residuals'
/// spread `sqrt(|r|^2 / (N_m - rank))` of the fit of `asked` without priors (linearised in
/// `at_before`, held by `priority`), as OLS's own covariance takes it.
fn unregularised_spread(
    base_problem: &PointProblem<'_>,
    params: &ParamSet,
    asked: &Selection,
    before: &[f64],
    weights: &Weights,
    at_before: &crate::estimation::Linearisation,
    priority: &[u32],
) -> Result<f64, CalibrationError> {
    let diagnostics = at_before.diagnose_by_priority(RANK_TOLERANCE, priority)?;
    let kept = Selection::from_indices(params, diagnostics.identifiable.iter().map(|&c| asked.indices()[c]));
    let problem = base_problem.reselect(&kept, before.to_vec())?;
    spread_of_fit(&problem, weights, at_before.select(&diagnostics.identifiable))
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

/// `e`, a covariance block that is not positive definite named by its pose's line in `data`.
fn at_line(e: CalibrationError, data: &Measurements) -> CalibrationError {
    match e {
        CalibrationError::Estimation(EstimationError::NotPositiveDefinite { point }) => {
            CalibrationError::SingularCovariance { line: data.lines.get(point).copied().unwrap_or(0) }
        }
        other => other,
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

/// What was measured at every pose, marker by marker, as frames (the orientation of the probe
/// where measured, the identity otherwise).
fn observed(data: &Measurements) -> Vec<Isometry3<f64>> {
    let rotations = |k: usize| data.orientations.as_ref().map_or(UnitQuaternion::identity(), |o| o[k]);
    data.markers
        .iter()
        .enumerate()
        .flat_map(|(k, m)| m.iter().map(move |p| Isometry3::from_parts(Translation3::from(*p), rotations(k))))
        .collect()
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

/// Feasible GLS: calibrate with the noise estimated from the data itself. Start with ordinary
/// least squares; fit the variance components (the joint variances and `sigma_me^2`) to the
/// residuals' outer products `r_k r_k^T`, whose expectation is `(M V M^T)_kk` with `M` the
/// residual maker of the weighted fit; calibrate again by
/// Gauss-Markov with `V_k = J_k Sigma_q J_k^T + sigma_me^2 I` from the estimate; repeat until
/// the components settle. The result carries the last estimate in
/// [`Calibration::noise_estimate`]. `options.estimator` and `options.noise` are not used; a
/// `sigma` column of the data is ignored (its noise is what is estimated).
pub fn calibrate_feasible(
    model: &RobotModel,
    data: &Measurements,
    options: &Options,
    feasible: &FeasibleOptions,
) -> Result<Calibration, CalibrationError> {
    // Without its `sigma` column: a copy only if it has one.
    let ignored_sigma = data.sigma.is_some();
    let data = match ignored_sigma {
        true => std::borrow::Cow::Owned(Measurements { sigma: None, ..data.clone() }),
        false => std::borrow::Cow::Borrowed(data),
    };
    let ols = Options { estimator: Estimator::Ols, noise: None, ..options.clone() };
    // The "before" fit of marker positions is by ordinary least squares whatever the noise:
    // the first round's serves every round. (A probe's OLS rows are scaled by the noise's
    // orientation weight: fitted again.)
    let before = std::sync::OnceLock::new();
    let reuse_before = data.orientations.is_none();
    let calibrate = |estimate: Option<&NoiseEstimate>| {
        let weighted = Options {
            estimator: if estimate.is_some() { Estimator::Wls } else { Estimator::Ols },
            noise: estimate.map(NoiseEstimate::noise_model),
            ..ols.clone()
        };
        let known = before.get().filter(|_| reuse_before).map(Vec::as_slice);
        let c = calibrate_checking(model, &data, &weighted, (false, known))?;
        before.get_or_init(|| c.before.clone());
        Ok(c)
    };
    let estimate = |c: &Calibration, previous: Option<&NoiseEstimate>| {
        let noise = previous.map(NoiseEstimate::noise_model);
        residual_noise(c, &data, noise.as_ref(), feasible.joints, previous)
    };
    let rounds = reweighted(feasible, calibrate, estimate)?;
    let warning = unsettled(feasible, &rounds);
    let Reweighted { mut calibration, estimate, settled, .. } = rounds;
    calibration.noise_settled = Some(settled);
    calibration.warnings.extend(warning);
    if ignored_sigma {
        calibration.warnings.push(Warning::SigmaIgnored);
    }
    calibration.noise_estimate = Some(estimate);
    Ok(calibration)
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

/// The variance components fitted to the residuals of `c` (calibrated with `noise`, or by
/// ordinary least squares without), reweighted from the `previous` round's if any.
fn residual_noise(
    c: &Calibration,
    data: &Measurements,
    noise: Option<&NoiseModel>,
    joints: JointComponents,
    previous: Option<&NoiseEstimate>,
) -> Result<NoiseEstimate, CalibrationError> {
    let kept = Selection::from_indices(
        &c.params,
        c.refined.estimate.names.iter().filter_map(|n| c.params.index_by_name(n)),
    );
    let kind = if data.orientations.is_some() { Measured::Pose } else { Measured::Position };
    let problem = PointProblem::new(
        &c.chains,
        &kept,
        kind,
        data.joints.clone(),
        observed(data),
        c.after.clone(),
        noise,
    )?;
    let estimator = if noise.is_some() { Estimator::Wls } else { Estimator::Ols };
    let weights = Weights::for_problem(&problem, estimator)?;
    let jacobians = problem.manipulator_jacobians(&c.after);
    // The covariance blocks are in the weights: the rows, built pose by pose where they are
    // needed, are all the problem is kept for.
    let problem = problem.without_noise();
    let per = kind.rows();
    let layout = NoiseLayout::of_points(jacobians, per, weights.blocks());
    let samples = residual_samples(&problem.rows_at(&problem.start()), &weights, &layout, joints)?;
    // The fit needs the packed samples alone.
    drop((problem, weights, layout));
    Ok(NoiseEstimate::fit(&samples, joints, c.chains[0].dof(), MeasurementClass::of_points(per), previous)?)
}

/// The noise model of a noise file for `data`: its `Sigma_q`, and at every pose the measurement
/// covariance of the device at each measured marker (`Sigma_device(p) + sigma_me^2 I`), with
/// the orientation rows of a probe at `sigma_orientation^2` (the file's, else its device's
/// [default](crate::estimation::Device::sigma_orientation); neither: zero, which a calibration
/// refuses, naming the field).
pub fn noise_from_spec(spec: &NoiseSpec, data: &Measurements) -> Result<NoiseModel, DeviceError> {
    let probe = data.orientations.is_some();
    let sigma_orientation = match (&spec.device, spec.sigma_orientation) {
        (Some(device), 0.0) => device.sigma_orientation(),
        (_, s) => s,
    };
    let per = if probe { 6 } else { 3 };
    let rows = per * data.marker_count();
    let mut blocks = Vec::with_capacity(data.len());
    for markers in &data.markers {
        let mut block = DMatrix::zeros(rows, rows);
        for (m, p) in markers.iter().enumerate() {
            block.view_mut((m * per, m * per), (3, 3)).copy_from(&spec.measurement_covariance(p)?);
        }
        if probe {
            for r in 3..6 {
                block[(r, r)] = sigma_orientation.powi(2);
            }
        }
        blocks.push(block);
    }
    Ok(NoiseModel { joint: spec.joint.clone(), measurement: MeasurementNoise::PerPoint(blocks) })
}

/// The selection of base, markers and the chosen joint parameters, without those the user
/// holds ([`Gauge::hold`]).
fn selection(
    params: &ParamSet,
    joints: &JointParams,
    options: &Options,
) -> Result<Selection, SelectionError> {
    let joint = joints.select(params)?;
    let extra = (0..params.len()).filter(|&i| match params.get(i).owner {
        ParamOwner::Base => options.estimate_base,
        ParamOwner::Marker(_) => options.estimate_markers,
        _ => false,
    });
    let held = held_by_user(params, &options.gauge)?;
    let chosen = joint.indices().iter().copied().chain(extra).filter(|&i| held.column(i).is_none());
    Ok(Selection::from_indices(params, chosen))
}

/// The parameters `gauge` holds at nominal (an error for a name that matches none).
fn held_by_user(params: &ParamSet, gauge: &Gauge) -> Result<Selection, SelectionError> {
    if gauge.hold.is_empty() {
        return Ok(Selection::from_indices(params, []));
    }
    Selection::by_names(params, &gauge.hold)
}

/// Why each parameter `joints` asks for and `gauge` holds is not estimated.
fn held_in_words(
    params: &ParamSet,
    joints: &JointParams,
    options: &Options,
) -> Result<Vec<Held>, SelectionError> {
    let without = Options { gauge: Gauge { hold: Vec::new(), ..options.gauge.clone() }, ..options.clone() };
    let asked = selection(params, joints, &without)?;
    let held = held_by_user(params, &options.gauge)?;
    Ok((asked.indices().iter())
        .filter(|&&i| held.column(i).is_some())
        .map(|&i| Held::ByUser { parameter: params.get(i).name.clone(), setup: false })
        .collect())
}

/// The noise model, with the data's `sigma` column as the measurement noise when present.
/// `rows` per pose: 3 per marker, or 6 for a probe, whose orientation rows keep the noise
/// model's orientation sigma.
fn noise_for(noise: Option<NoiseModel>, data: &Measurements, rows: usize) -> Option<NoiseModel> {
    let mut noise = noise?;
    if let Some(sigmas) = &data.sigma {
        let orientation = match &noise.measurement {
            MeasurementNoise::PerAxis(s) => s[3],
            MeasurementNoise::PerPoint(blocks) => {
                blocks.first().filter(|b| b.nrows() > 3).map_or(0.0, |b| b[(3, 3)].sqrt())
            }
        };
        let probe = data.orientations.is_some();
        let variance = |s: f64, r: usize| if probe && r >= 3 { orientation * orientation } else { s * s };
        noise.measurement = MeasurementNoise::PerPoint(
            sigmas
                .iter()
                .map(|&s| DMatrix::from_fn(rows, rows, |i, j| if i == j { variance(s, i) } else { 0.0 }))
                .collect(),
        );
    }
    Some(noise)
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

/// Implausible estimates ([`implausible`]), and the training poses flagged by [`evaluation`]: a
/// residual more than [`FLAG_AT`] standard deviations out once whitened by the full `V_k` of
/// their pose (joint and measurement noise), or, without a noise model, by the residuals' own
/// spread.
fn warnings(s: &Stages<'_>, calibrated: &RobotModel, training: &SetEvaluation) -> Vec<Warning> {
    let se = standard_errors_of(s.params.iter(), &s.refined.estimate);
    let mut out = implausible(s.params.iter(), (&s.before, &s.after), &se, Some(calibrated));
    let flagged = (training.poses.iter().enumerate()).filter(|(_, p)| p.flagged).map(|(index, p)| FarOut {
        index,
        line: p.line,
        label: None,
        sd: p.worst,
    });
    out.extend(Warning::far_out(Scored::Pose, flagged));
    out.extend(not_converged(&s.refined));
    out
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

/// k-fold cross-validation: pose `i` is held out in fold `i mod k`; the errors of every
/// held-out pose, before and after a calibration on the other folds.
pub fn cross_validate(
    model: &RobotModel,
    data: &Measurements,
    options: &Options,
    folds: usize,
) -> Result<(ErrorStats, ErrorStats), CalibrationError> {
    let (mut before, mut after) = (Vec::new(), Vec::new());
    for fold in 0..folds {
        let (test, train): (Vec<usize>, Vec<usize>) = (0..data.len()).partition(|i| i % folds == fold);
        let calibration = calibrate_quietly(model, &data.subset(&train), &options.at_poses(&train))?;
        let held_out = data.subset(&test);
        before.extend(errors(&calibration.chains, &calibration.before, &held_out));
        after.extend(errors(&calibration.chains, &calibration.after, &held_out));
    }
    Ok((ErrorStats::of(&before), ErrorStats::of(&after)))
}

impl Options {
    /// The same options for the poses `poses` of the data (a fold's): a noise model's per-pose
    /// measurement covariances (a noise file's device) follow their poses.
    pub fn at_poses(&self, poses: &[usize]) -> Self {
        Self { noise: self.noise.as_ref().map(|n| n.at_points(poses)), ..self.clone() }
    }
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

/// The standard error of every parameter (NaN for those not estimated), full-vector order.
pub fn standard_errors(c: &Calibration) -> Vec<f64> {
    standard_errors_of(c.params.iter(), &c.refined.estimate)
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
