//! One validated request per command: every rule between flags is checked here, before a file
//! is read, and a broken one is a [`UsageError`] (exit code 2). The rules that need a file's
//! contents are the commands' own.

use super::args::{
    CalibrateArgs, DesignArgs, EstimatorName, Excluded, JointUnit, LengthUnit, MeasuredName, NoiseArgs,
    ObservabilityArgs, ParamSet, PlanArgs, RepeatabilityArgs, ToolBox, UnitArgs,
};
use nalgebra::Vector3;
use robocal::calibration::{JointParams, Units};
use robocal::design::Criterion;
use robocal::estimation::Estimator;
use robocal::kinematics::Measured;
use std::path::PathBuf;

#[cfg(test)]
mod tests;

/// Flags that clap accepted one by one but that do not fit together: exit code 2.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct UsageError(pub String);

impl std::fmt::Display for UsageError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for UsageError {}

/// `Err(UsageError)` with this message unless `ok`.
fn require(ok: bool, message: &str) -> Result<(), UsageError> {
    if ok { Ok(()) } else { Err(UsageError(message.to_string())) }
}

impl UnitArgs {
    /// The units, if given: `--joint-unit` and `--length-unit` go together.
    fn units(&self) -> Result<Option<Units>, UsageError> {
        match (self.joint_unit, self.length_unit) {
            (None, None) => Ok(None),
            (Some(joint), Some(length)) => Ok(Some(Units {
                joints_in_degrees: joint == JointUnit::Deg,
                lengths_in_metres: length == LengthUnit::M,
            })),
            _ => Err(UsageError("--joint-unit and --length-unit go together".into())),
        }
    }
}

/// Noise given as numbers, in the flags' units (deg, mm); the joint count is checked against
/// the model by [`super::noise_model`].
#[derive(Debug, Clone, PartialEq)]
pub struct NoiseFlags {
    /// One standard deviation per joint: deg (mm for prismatic joints).
    pub joint_sigma_deg: Vec<f64>,
    /// The measurement's (mm).
    pub sigma_mm: f64,
    /// The orientation measurement's (deg).
    pub sigma_orientation_deg: f64,
}

impl NoiseArgs {
    /// The noise, if `--joint-sigma-deg` gives it.
    fn flags(&self) -> Option<NoiseFlags> {
        self.joint_sigma_deg.clone().map(|joint_sigma_deg| NoiseFlags {
            joint_sigma_deg,
            sigma_mm: self.sigma_mm,
            sigma_orientation_deg: self.sigma_orientation_deg,
        })
    }
}

/// Where `calibrate` takes the noise from.
#[derive(Debug, Clone, PartialEq)]
pub enum NoiseSource {
    /// A noise file (TOML).
    File(PathBuf),
    /// `--joint-sigma-deg`, `--sigma-mm`, `--sigma-orientation-deg`.
    Flags(NoiseFlags),
}

/// The model of `calibrate`: a preset or model file, or a chain in a URDF file.
#[derive(Debug, Clone, PartialEq)]
pub enum ModelSource {
    /// A preset name or a model TOML file.
    Named(String),
    /// A URDF file and the links the chain runs between.
    Urdf {
        /// The URDF file.
        path: PathBuf,
        /// The link the chain starts from.
        base_link: String,
        /// The link the chain ends at.
        tip_link: String,
    },
}

/// How `calibrate` estimates.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Method {
    /// One estimator with the given noise (or none, for OLS).
    Given(Estimator),
    /// Feasible GLS: the noise estimated from the residuals.
    Feasible,
}

impl Method {
    /// The name in the report.
    pub fn name(self) -> &'static str {
        match self {
            Self::Given(estimator) => estimator.name(),
            Self::Feasible => "fgls",
        }
    }
}

/// A validated `robocal calibrate`.
#[derive(Debug, Clone, PartialEq)]
pub struct CalibrateRequest {
    /// The nominal robot.
    pub model: ModelSource,
    /// The measurement file.
    pub data: PathBuf,
    /// The files' units, if given.
    pub units: Option<Units>,
    /// The estimator.
    pub method: Method,
    /// The noise, if given.
    pub noise: Option<NoiseSource>,
    /// The joint parameters to identify.
    pub joints: JointParams,
    /// Estimate the base.
    pub estimate_base: bool,
    /// Estimate the markers.
    pub estimate_markers: bool,
    /// Nominal marker positions (mm).
    pub markers: Vec<Vector3<f64>>,
    /// Gauss-Newton steps at most (>= 1).
    pub iterations: usize,
    /// Held-out measurement files.
    pub validate: Vec<PathBuf>,
    /// k of the k-fold cross-validation (>= 2).
    pub folds: Option<usize>,
    /// Where the JSON report goes.
    pub json: Option<PathBuf>,
    /// Where the calibrated model TOML goes.
    pub out_model: Option<PathBuf>,
    /// Where the calibrated URDF goes (URDF models only).
    pub out_urdf: Option<PathBuf>,
}

impl CalibrateRequest {
    /// The request, or the first rule between `args`' flags that it breaks.
    pub fn from_args(args: CalibrateArgs) -> Result<Self, UsageError> {
        let model = if args.model.ends_with(".urdf") {
            let (Some(base_link), Some(tip_link)) = (args.base_link, args.tip_link) else {
                return Err(UsageError(format!(
                    "{}: a URDF model needs --base-link and --tip-link",
                    args.model
                )));
            };
            ModelSource::Urdf { path: args.model.into(), base_link, tip_link }
        } else {
            require(args.out_urdf.is_none(), "--out-urdf needs a URDF model")?;
            ModelSource::Named(args.model)
        };
        let noise = match (args.noise, args.noise_flags.flags()) {
            (Some(_), Some(_)) => {
                return Err(UsageError("--noise and --joint-sigma-deg: give one of the two".into()));
            }
            (Some(path), None) => Some(NoiseSource::File(path)),
            (None, flags) => flags.map(NoiseSource::Flags),
        };
        let method = match args.estimator {
            Some(EstimatorName::Fgls) => {
                require(
                    noise.is_none(),
                    "--estimator fgls estimates the noise: do not give --noise or --joint-sigma-deg",
                )?;
                require(
                    args.folds.is_none(),
                    "--folds with --estimator fgls: not supported; estimate the noise once and give --noise",
                )?;
                Method::Feasible
            }
            Some(EstimatorName::Ols) => Method::Given(Estimator::Ols),
            Some(EstimatorName::Wls) => Method::Given(Estimator::Wls),
            Some(EstimatorName::WlsDiag) => Method::Given(Estimator::WlsDiag),
            Some(EstimatorName::WlsSigma) => Method::Given(Estimator::WlsSigma),
            None if noise.is_some() => Method::Given(Estimator::Wls),
            None => Method::Given(Estimator::Ols),
        };
        if let Method::Given(estimator) = method {
            require(
                estimator == Estimator::Ols || noise.is_some(),
                &format!(
                    "--estimator {estimator} needs the noise: give --noise or --joint-sigma-deg (and --sigma-mm or \
                     a sigma column), or use --estimator fgls"
                ),
            )?;
        }
        let joints = match args.params {
            ParamSet::All => {
                require(
                    !args.fixed_base && !args.fixed_markers,
                    "--params all frees the base and the markers: with --fixed-base or --fixed-markers, give \
                     --params joints",
                )?;
                JointParams::All
            }
            ParamSet::Joints => JointParams::All,
            ParamSet::Offsets => JointParams::Offsets,
            ParamSet::None => JointParams::None,
            ParamSet::Named(names) => JointParams::Named(names),
        };
        Ok(Self {
            model,
            data: args.data,
            units: args.units.units()?,
            method,
            noise,
            joints,
            estimate_base: !args.fixed_base,
            estimate_markers: !args.fixed_markers,
            markers: args.marker,
            iterations: args.iterations,
            validate: args.validate,
            folds: args.folds,
            json: args.json,
            out_model: args.out_model,
            out_urdf: args.out_urdf,
        })
    }
}

/// The parameters, measurements and noise of a validated `plan` or `observability`.
#[derive(Debug, Clone, PartialEq)]
pub struct DesignRequest {
    /// The nominal robot: a preset name or a model file.
    pub model: String,
    /// The parameters to identify (not [`ParamSet::None`]).
    pub params: ParamSet,
    /// What is measured at each pose.
    pub measured: Measured,
    /// The noise, if given.
    pub noise: Option<NoiseFlags>,
}

impl DesignRequest {
    /// The request, or the first rule between `args`' flags that it breaks.
    fn from_args(args: DesignArgs) -> Result<Self, UsageError> {
        require(
            args.params != ParamSet::None,
            "--params none: nothing to assess; give joints, all, offsets, or parameter names",
        )?;
        let noise = args.noise.flags();
        require(
            noise.is_some() || args.noise.sigma_mm == 0.0,
            "--sigma-mm needs --joint-sigma-deg too (zeros if the joints are exact)",
        )?;
        let measured = match args.measured {
            MeasuredName::Position => Measured::Position,
            MeasuredName::Pose => Measured::Pose,
        };
        Ok(Self { model: args.model, params: args.params, measured, noise })
    }
}

/// A validated `robocal observability`.
#[derive(Debug, Clone, PartialEq)]
pub struct ObservabilityRequest {
    /// The pose file.
    pub poses: PathBuf,
    /// The robot, parameters, measurements and noise.
    pub design: DesignRequest,
    /// The pose file's units, if given (lengths are not read from it).
    pub units: Option<Units>,
}

impl ObservabilityRequest {
    /// The request, or the first rule between `args`' flags that it breaks.
    pub fn from_args(args: ObservabilityArgs) -> Result<Self, UsageError> {
        let units = args
            .joint_unit
            .map(|unit| Units { joints_in_degrees: unit == JointUnit::Deg, lengths_in_metres: false });
        Ok(Self { poses: args.poses, design: DesignRequest::from_args(args.design)?, units })
    }
}

/// A validated `robocal plan`.
#[derive(Debug, Clone, PartialEq)]
pub struct PlanRequest {
    /// The robot, parameters, measurements and noise.
    pub design: DesignRequest,
    /// Number of poses.
    pub points: usize,
    /// Number of candidate poses.
    pub candidates: usize,
    /// What to maximise.
    pub criterion: Criterion,
    /// Seed of the candidate pool.
    pub seed: u64,
    /// A box the tool point must stay in.
    pub tool_box: Option<ToolBox>,
    /// Joint ranges to avoid (degrees; mm for prismatic joints).
    pub exclude: Vec<Excluded>,
    /// Where the poses go (standard output without it).
    pub out: Option<PathBuf>,
}

impl PlanRequest {
    /// The request, or the first rule between `args`' flags that it breaks.
    pub fn from_args(args: PlanArgs) -> Result<Self, UsageError> {
        Ok(Self {
            design: DesignRequest::from_args(args.design)?,
            points: args.points,
            candidates: args.candidates,
            criterion: args.criterion,
            seed: args.seed,
            tool_box: args.tool_box,
            exclude: args.exclude,
            out: args.out,
        })
    }
}

/// A validated `robocal repeatability`.
#[derive(Debug, Clone, PartialEq)]
pub struct RepeatabilityRequest {
    /// The nominal robot: a preset name or a model file.
    pub model: String,
    /// The repeatability file.
    pub data: PathBuf,
    /// The file's units, if given.
    pub units: Option<Units>,
    /// Estimate the full joint covariance.
    pub full_covariance: bool,
    /// Nominal marker positions (mm).
    pub markers: Vec<Vector3<f64>>,
    /// Register the measuring frame to the robot's.
    pub register: bool,
    /// Where the noise file goes.
    pub out: Option<PathBuf>,
    /// Where the JSON estimates go.
    pub json: Option<PathBuf>,
}

impl RepeatabilityRequest {
    /// The request, or the first rule between `args`' flags that it breaks.
    pub fn from_args(args: RepeatabilityArgs) -> Result<Self, UsageError> {
        Ok(Self {
            model: args.model,
            data: args.data,
            units: args.units.units()?,
            full_covariance: args.full_covariance,
            markers: args.marker,
            register: !args.fixed_base,
            out: args.out,
            json: args.json,
        })
    }
}
