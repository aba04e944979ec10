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
pub mod kinds;
mod repeatability;
pub mod robust;
pub mod selection;
pub mod tree;

pub use data::Measurements;
pub use diagnostics::{FarOut, Scored, Warning};
pub use evaluation::{FLAG_AT, PoseErrors, SetEvaluation, Whitening, pool};
pub use repeatability::{
    Repeatability, RepeatabilityData, RepeatabilityOptions, RepeatedPose, repeatability,
};
pub use robust::{Loss, RobustFit};
pub use selection::{Criterion, NestedCv, SelectionPath, cross_validate_selection, select};

use crate::estimation::{
    CovarianceSample, DeviceError, EstimationError, Estimator, JointComponents, MeasurementNoise,
    NoiseEstimate, NoiseModel, NoiseSpec, PointProblem, PriorEntry, PriorError, PriorRows, RANK_TOLERANCE,
    RefineOptions, Refined, Residuals, Weights, linearise, noise_design, prior_sds, refine_from,
    residual_design,
};
use crate::kinematics::{Chain, Measured, end_positions};
use crate::model::{ParamKind, ParamOwner, ParamSet, Placement, RobotModel, Selection, SelectionError, Tool};
use nalgebra::{DMatrix, DVector, Isometry3, Matrix3, Rotation3, Translation3, UnitQuaternion, Vector3};
use rayon::prelude::*;

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
    pub fixed: Vec<String>,
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

/// Calibrate `model` from `data` with `options`.
pub fn calibrate(
    model: &RobotModel,
    data: &Measurements,
    options: &Options,
) -> Result<Calibration, CalibrationError> {
    let marker_count = data.marker_count();
    let markers: Vec<Vector3<f64>> =
        (0..marker_count).map(|k| options.markers.get(k).copied().unwrap_or_else(Vector3::zeros)).collect();
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
    let probe =
        data.orientations.as_ref().map(|measured| probe_mounting(&registered, markers[0], data, measured));
    let chains = match &probe {
        Some(probe) => vec![Chain::probe(&registered, probe)],
        None => Chain::markers(&registered, &markers),
    };
    let kind = if probe.is_some() { Measured::Pose } else { Measured::Position };
    let rows = kind.rows() * chains.len();
    let params = chains[0].params().clone();
    let noise = noise_for(options.noise.clone(), data, rows);
    let observed = observed(data);
    let zero = vec![0.0; params.len()];

    // One problem, and its covariance blocks V_k, for every stage.
    let nothing = Selection::from_indices(&params, []);
    let base_problem = PointProblem::new(
        &chains,
        &nothing,
        kind,
        data.joints.clone(),
        observed,
        zero.clone(),
        noise.as_ref(),
    )?;

    // The estimator's weights for the calibration.
    let weights =
        Weights::for_problem(&base_problem, options.estimator).map_err(|e| at_line(e.into(), data))?;

    // "Before": base and markers only, by ordinary least squares whatever the estimator.
    let frame = selection(&params, &JointParams::None, options)?;
    let before = if frame.is_empty() {
        zero.clone()
    } else {
        let unweighted = Weights::for_problem(&base_problem, Estimator::Ols)?;
        let problem = base_problem.reselect(&frame, zero.clone())?;
        let start = linearise(&problem, &unweighted, problem.start())?;
        let fitted = refine_from(&problem, &unweighted, start, &RefineOptions::default())?;
        problem.full(&fitted.estimate.x)
    };

    // "After": everything asked for that the poses can identify.
    let asked = selection(&params, &options.joints, options)?;
    let prior_sd = prior_sds(&options.prior, &params)?;
    // With fewer equations than parameters the rank cannot tell structure from lack of data.
    let equations = data.len() * rows;
    if equations <= asked.len() {
        let needed = asked.len() / rows + 1;
        return Err(CalibrationError::TooFewPoses {
            poses: data.len(),
            equations,
            parameters: asked.len(),
            needed,
        });
    }
    if asked.is_empty() {
        // Nothing to estimate: the model as it stands is scored.
        return finish(
            Stages {
                registered,
                probe,
                markers,
                params,
                before: before.clone(),
                after: before,
                refined: Refined { estimate: nothing_estimated(), history: Vec::new(), converged: true },
                fixed: held_in_words(chains[0].params(), &options.joints, options)?,
                chains: chains.clone(),
                noise,
                data,
                marker_ids: data.marker_ids.clone(),
                prior_sd,
                robust: None,
            },
            &base_problem,
        );
    }
    if data.joints.first().is_some_and(|q| data.joints.iter().all(|other| other == q)) {
        let line = data.lines.first().copied().unwrap_or(0);
        return Err(CalibrationError::NothingIdentified(format!(
            "all {} poses have the joint values of line {line}: measure the robot at different poses",
            data.len()
        )));
    }
    let Identified { kept, mut fixed, start, prior, data_alone } =
        identifiable(&base_problem, &weights, &asked, &before, data, &options.gauge, Some(&prior_sd))?;
    fixed.extend(held_in_words(&params, &options.joints, options)?);
    let problem = base_problem.reselect(&kept, before.clone())?;
    let (mut estimate, robust) =
        robust::fit(&problem, &weights, start, &options.refine, prior.as_ref(), options.loss)?;
    if let Some(data_alone) = data_alone {
        estimate.estimate.diagnostics = data_alone;
    }
    let after = problem.full(&estimate.estimate.x);
    finish(
        Stages {
            registered,
            probe,
            markers,
            params,
            before,
            after,
            refined: estimate,
            fixed,
            chains: chains.clone(),
            noise,
            data,
            marker_ids: data.marker_ids.clone(),
            prior_sd,
            robust,
        },
        &base_problem,
    )
}

/// What [`identifiable`] finds: the parameters the poses identify, why the others are held,
/// and the system linearised about the "before" values, for the identified columns.
struct Identified {
    kept: Selection,
    fixed: Vec<String>,
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
    // A compliance or play whose joint gravity does not load at these poses (a vertical axis)
    // has no column: it is held, and said so.
    let (asked, unloaded) =
        without_unloaded_responses(asked, &base_problem.chains()[0], before, &data.joints);
    let problem = base_problem.reselect(&asked, before.to_vec())?;
    let at_before = linearise(&problem, weights, problem.start())?;
    let keep = if gauge.keep.is_empty() {
        Selection::from_indices(params, [])
    } else {
        Selection::by_names(params, &gauge.keep)?
    };
    let priority: Vec<u32> = (asked.indices().iter())
        .map(|&i| if keep.column(i).is_some() { 0 } else { 1 + gauge_class(params.get(i)) })
        .collect();
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
    let infos: Vec<&crate::model::ParamInfo> = asked.indices().iter().map(|&i| params.get(i)).collect();
    let fixed = (diagnostics.not_identifiable.iter().map(|c| why_held(c, &infos))).chain(unloaded).collect();
    let kept = Selection::from_indices(params, diagnostics.identifiable.iter().map(|&c| asked.indices()[c]));
    let start = at_before.select(&diagnostics.identifiable);
    // The identifiability the report gives is the data's alone.
    let data_alone = prior.as_ref().map(|_| start.diagnose(RANK_TOLERANCE)).transpose()?;
    let prior = prior.map(|p| p.select(&diagnostics.identifiable));
    Ok(Identified { kept, fixed, start, prior, data_alone })
}

/// A held parameter in words a user can act on: the combination `c` of the parameters
/// `infos` (by column) that the poses cannot tell apart, what it means, and the flag that
/// frees it. A parameter confounded with the base alone only moves the whole robot as the
/// base does; with the markers alone, the markers as their positions do.
fn why_held(c: &crate::estimation::Combination, infos: &[&crate::model::ParamInfo]) -> String {
    let names: Vec<&str> = infos.iter().map(|p| p.name.as_str()).collect();
    let held = names[c.column];
    let owners: Vec<ParamOwner> = c.terms.iter().map(|&(t, _)| infos[t].owner).collect();
    let only = |f: fn(&ParamOwner) -> bool| !owners.is_empty() && owners.iter().all(f);
    let reason = if !matches!(infos[c.column].owner, ParamOwner::Joint(_)) {
        "held so that the parameters of --keep stay free".to_string()
    } else if only(|o| *o == ParamOwner::Base) {
        format!(
            "with the base estimated it only moves the whole robot: --fixed-base (if the measuring frame is \
             the robot's) or --keep {held} frees it"
        )
    } else if only(|o| matches!(o, ParamOwner::Marker(_) | ParamOwner::Tool)) {
        format!(
            "with the markers estimated it only moves the markers: --fixed-markers (if their positions are \
             known) or --keep {held} frees it"
        )
    } else {
        format!("these poses cannot tell it from the others: vary them, or --keep {held} to hold another")
    };
    format!("{}: {reason}", c.describe(&names))
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
    fixed: Vec<String>,
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
    let mut warnings = warnings(&s.params, (&s.before, &s.after), &training_poses);
    warnings.extend(implausible_compliances(&calibrated, &s.params, &s.refined));
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
    let fitted = refine_from(
        &problem,
        weights,
        at_before.select(&diagnostics.identifiable),
        &RefineOptions::default(),
    )?;
    let dof = problem.equations().saturating_sub(fitted.estimate.diagnostics.rank).max(1);
    Ok((fitted.estimate.cost / dof as f64).sqrt())
}

/// `asked` without the compliances and plays of joints that gravity does not load at the poses
/// `joints` (every load below 1e-9 of the largest: a vertical axis, a joint carrying no mass)
/// on `chain` with errors `x`, and why each of those is held.
pub(crate) fn without_unloaded_responses(
    asked: &Selection,
    chain: &Chain,
    x: &[f64],
    joints: &[Vec<f64>],
) -> (Selection, Vec<String>) {
    let params = chain.params();
    let responses: Vec<(usize, usize)> = (asked.indices().iter())
        .filter_map(|&i| match params.get(i).owner {
            ParamOwner::Joint(j) if params.get(i).is_load_response() => Some((i, j)),
            _ => None,
        })
        .collect();
    let weighs = |i: usize| params.get(i).owner == ParamOwner::Payload;
    if responses.is_empty() && !asked.indices().iter().any(|&i| weighs(i)) {
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
    let mut why: Vec<String> = unloaded
        .iter()
        .map(|&i| {
            format!(
                "{}: gravity does not load its joint at these poses (a vertical axis?)",
                params.get(i).name
            )
        })
        .collect();
    // The payload's mass moves the arm only through the compliances: with every one zero at
    // `x`, its column vanishes.
    let payload =
        params.index_of(ParamOwner::Payload, ParamKind::Mass).filter(|&i| asked.column(i).is_some());
    let mut held = unloaded;
    if let Some(i) = payload.filter(|_| !at.deflects()) {
        held.push(i);
        why.push(format!(
            "{}: the payload is seen only through the joints' compliances, all zero here: calibrate the \
             compliances first (with a known payload or none), then its mass with the calibrated model",
            params.get(i).name
        ));
    }
    let kept = asked.indices().iter().copied().filter(|i| !held.contains(i));
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
    let mut data = data.clone();
    let ignored_sigma = data.sigma.take().is_some();
    let mut options = Options { estimator: Estimator::Ols, noise: None, ..options.clone() };
    let mut calibration = calibrate(model, &data, &options)?;
    let mut previous: Option<NoiseEstimate> = None;
    let mut settled_at = None;
    for round in 0..feasible.max_iterations.max(1) {
        let estimate = residual_noise(&calibration, &data, options.noise.as_ref(), feasible.joints)?;
        let settled = previous.as_ref().is_some_and(|p| {
            (0..estimate.fit.values.len()).all(|c| {
                let change = (p.fit.values[c] - estimate.fit.values[c]).abs();
                change <= feasible.tolerance * estimate.fit.standard_error(c)
            })
        });
        options.estimator = Estimator::Wls;
        options.noise = Some(estimate.noise_model());
        previous = Some(estimate);
        if settled {
            settled_at = Some(round);
            break;
        }
        calibration = calibrate(model, &data, &options)?;
    }
    calibration.noise_settled = Some(settled_at.is_some());
    if settled_at.is_none() {
        calibration.warnings.push(Warning::NoiseUnsettled { reweightings: feasible.max_iterations.max(1) });
    }
    if ignored_sigma {
        calibration.warnings.push(Warning::SigmaIgnored);
    }
    calibration.noise_estimate = previous;
    Ok(calibration)
}

/// The variance components fitted to the residuals of `c` (calibrated with `noise`, or by
/// ordinary least squares without).
fn residual_noise(
    c: &Calibration,
    data: &Measurements,
    noise: Option<&NoiseModel>,
    joints: JointComponents,
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
    let system = problem.system(&problem.start());
    let rows = system.rows_per_point;
    let estimator = if noise.is_some() { Estimator::Wls } else { Estimator::Ols };
    let weights = Weights::for_problem(&problem, estimator)?;
    // A = pinv(S H) S: the map from y to the estimate.
    let mut sh = system.h.clone();
    weights.apply(&mut sh);
    let g = crate::estimation::pseudo_inverse(&sh)?;
    let points = system.points();
    let mut s_blocks = DMatrix::zeros(rows * points, rows);
    for k in 0..points {
        s_blocks.view_mut((k * rows, 0), (rows, rows)).fill_with_identity();
    }
    weights.apply(&mut s_blocks);
    let mut a = DMatrix::zeros(g.nrows(), g.ncols());
    for k in 0..points {
        let block = g.columns(k * rows, rows) * s_blocks.rows(k * rows, rows);
        a.columns_mut(k * rows, rows).copy_from(&block);
    }
    let jacobians = problem.manipulator_jacobians(&c.after);
    let per = kind.rows();
    let designs: Vec<Vec<DMatrix<f64>>> = jacobians.iter().map(|j| noise_design(j, joints, per)).collect();
    let components: Vec<Vec<DMatrix<f64>>> =
        (0..designs[0].len()).map(|comp| designs.iter().map(|d| d[comp].clone()).collect()).collect();
    let expected = residual_design(&system.h, &a, rows, &components);
    let samples: Vec<CovarianceSample> = expected
        .into_iter()
        .enumerate()
        .map(|(k, design)| {
            let r = system.y.rows(k * rows, rows);
            CovarianceSample { s: r * r.transpose(), dof: 1.0, design }
        })
        .collect();
    Ok(NoiseEstimate::fit(&samples, joints, c.chains[0].dof(), per)?)
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
) -> Result<Vec<String>, SelectionError> {
    let without = Options { gauge: Gauge { hold: Vec::new(), ..options.gauge.clone() }, ..options.clone() };
    let asked = selection(params, joints, &without)?;
    let held = held_by_user(params, &options.gauge)?;
    Ok((asked.indices().iter())
        .filter(|&&i| held.column(i).is_some())
        .map(|&i| format!("{}: held at its nominal value by --hold", params.get(i).name))
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

/// The probe's placement on the last link: at the nominal marker position, turned by the
/// chordal mean of what each pose says the mounting rotation is, `R_arm(q)^-1 R_measured`.
fn probe_mounting(
    model: &RobotModel,
    at: Vector3<f64>,
    data: &Measurements,
    measured: &[UnitQuaternion<f64>],
) -> Placement {
    let unturned = Placement { xyz: at, rpy: Vector3::zeros() };
    let chain = Chain::probe(model, &unturned);
    let arm = chain.with_errors(&vec![0.0; chain.params().len()]);
    let mut sum = Matrix3::zeros();
    for (q, r) in data.joints.iter().zip(measured) {
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

/// Implausible results: large length corrections, and the training poses flagged by
/// [`evaluation`]: a residual more than [`FLAG_AT`] standard deviations out once whitened by
/// the full `V_k` of their pose (joint and measurement noise), or, without a noise model, by
/// the residuals' own spread.
fn warnings(params: &ParamSet, (before, after): (&[f64], &[f64]), training: &SetEvaluation) -> Vec<Warning> {
    let mut out = large_corrections(params.iter(), before, after);
    let flagged = (training.poses.iter().enumerate()).filter(|(_, p)| p.flagged).map(|(index, p)| FarOut {
        index,
        line: p.line,
        label: None,
        sd: p.worst,
    });
    out.extend(Warning::far_out(Scored::Pose, flagged));
    out
}

/// A [`Warning::LargeCorrection`] for each joint length of `params` corrected from `before` to
/// `after` by more than [`LARGE_CORRECTION_MM`](diagnostics::LARGE_CORRECTION_MM).
pub(crate) fn large_corrections<'a>(
    params: impl Iterator<Item = &'a crate::model::ParamInfo>,
    before: &[f64],
    after: &[f64],
) -> Vec<Warning> {
    params
        .enumerate()
        .filter(|(_, p)| matches!(p.owner, ParamOwner::Joint(_)) && p.unit() == "mm")
        .map(|(i, p)| (p, after[i] - before[i]))
        .filter(|(_, c)| c.abs() > diagnostics::LARGE_CORRECTION_MM)
        .map(|(p, correction_mm)| Warning::LargeCorrection { parameter: p.name.clone(), correction_mm })
        .collect()
}

/// The stiffest a joint's compliance may claim to be before it is suspect: a revolute joint
/// softer than 100 N·m/rad (a compliance above 1e-2 rad/N·m), or any negative compliance,
/// is absorbing something else (an error of the geometry, play, a wrong mass).
pub const SOFTEST_COMPLIANCE: f64 = 1e-2;

/// Warnings for the estimated compliances of `calibrated` (`refined` says which were estimated)
/// that no joint has: negative, or softer than [`SOFTEST_COMPLIANCE`], by more than two standard
/// errors; each with its stiffness.
fn implausible_compliances(calibrated: &RobotModel, params: &ParamSet, refined: &Refined) -> Vec<Warning> {
    let mut out = Vec::new();
    let se = refined.estimate.standard_errors();
    for (k, name) in refined.estimate.names.iter().enumerate() {
        let Some(i) = params.index_by_name(name) else { continue };
        let (ParamOwner::Joint(j), ParamKind::Compliance) = (params.get(i).owner, params.get(i).kind) else {
            continue;
        };
        let (value, unit, margin) = (calibrated.joints[j].compliance, params.get(i).unit(), 2.0 * se[k]);
        let parameter = name.clone();
        if value + margin < 0.0 {
            out.push(Warning::NegativeCompliance { parameter, value, unit });
        } else if value - margin > SOFTEST_COMPLIANCE && unit == "rad/N·m" {
            out.push(Warning::SoftCompliance { parameter, value });
        }
    }
    out
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
        let calibration = calibrate(model, &data.subset(&train), options)?;
        let held_out = data.subset(&test);
        before.extend(errors(&calibration.chains, &calibration.before, &held_out));
        after.extend(errors(&calibration.chains, &calibration.after, &held_out));
    }
    Ok((ErrorStats::of(&before), ErrorStats::of(&after)))
}

/// The standard error of every parameter (NaN for those not estimated), full-vector order.
pub fn standard_errors(c: &Calibration) -> Vec<f64> {
    let se: DVector<f64> = c.refined.estimate.standard_errors();
    let mut out = vec![f64::NAN; c.params.len()];
    for (name, s) in c.refined.estimate.names.iter().zip(se.iter()) {
        if let Some(i) = c.params.index_by_name(name) {
            out[i] = *s;
        }
    }
    out
}

#[cfg(test)]
mod compliance_tests {
    use super::*;
    use crate::model::LinkMass;

    /// A compliance estimated negative, or softer than any joint, by more than two standard
    /// errors is warned about with its stiffness; a plausible or uncertain one is not.
    #[test]
    fn implausible_compliances_are_warned() {
        let mut model = RobotModel::preset("puma560").unwrap();
        model.masses = vec![LinkMass { mass: 1.0, com: Vector3::zeros() }; 6];
        let params = model.params();
        let i = params.index_by_name("j2.compliance").unwrap();
        let mut refined = Refined { estimate: nothing_estimated(), history: Vec::new(), converged: true };
        refined.estimate.names = vec![params.get(i).name.clone()];
        refined.estimate.covariance = DMatrix::from_element(1, 1, 1e-10); // SE 1e-5
        let mut warned = |c: f64| {
            model.joints[1].compliance = c;
            implausible_compliances(&model, &params, &refined)
        };
        assert!(warned(4e-5).is_empty());
        assert!(warned(-1e-5).is_empty(), "within two standard errors of zero");
        let negative = warned(-1e-3);
        assert!(
            matches!(negative.as_slice(), [Warning::NegativeCompliance { value, .. }] if *value == -1e-3)
        );
        assert_eq!(
            negative[0].to_string(),
            "j2.compliance is -1.000e-3 rad/N·m: a negative compliance absorbs something else (geometry, play, masses)"
        );
        let soft = warned(2e-2);
        assert!(matches!(soft.as_slice(), [Warning::SoftCompliance { value, .. }] if *value == 2e-2));
        assert_eq!(
            soft.iter().map(ToString::to_string).collect::<Vec<_>>(),
            [
                "j2.compliance is 2.000e-2 rad/N·m, a stiffness of 50 N·m/rad: softer than any real joint, it absorbs something else"
            ]
        );
    }
}
