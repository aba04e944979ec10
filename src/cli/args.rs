//! The flags of every command as clap parses them: units, estimators, markers, joint lists,
//! the tool box and the excluded ranges arrive typed and checked one by one, so nothing is
//! parsed by hand after clap. The rules between flags are in [`super::request`].

use clap::{Args, ValueEnum};
use nalgebra::Vector3;
use robocal::calibration::prior_scale::AutoPrior;
use robocal::calibration::{Loss, ParamWords};
use robocal::design::Criterion;
use robocal::estimation::{PriorEntry, RefineOptions};
use robocal::limits::{MAX_ANGLE_DEG, MAX_ITERATIONS, MAX_LENGTH_MM};
use std::path::PathBuf;

/// The unit of revolute joint values in a file.
#[derive(ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum JointUnit {
    /// Degrees.
    Deg,
    /// Radians.
    Rad,
}

/// The unit of lengths in a file.
#[derive(ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum LengthUnit {
    /// Millimetres.
    Mm,
    /// Metres.
    M,
}

/// The estimator of `calibrate`: the library's four, or feasible GLS.
#[derive(ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum EstimatorName {
    /// Ordinary least squares: every row weighted alike.
    Ols,
    /// Gauss-Markov: the inverse of each pose's full covariance (needs the noise).
    Wls,
    /// The inverse of the diagonal of each pose's covariance (needs the noise).
    WlsDiag,
    /// 1/sigma of each coordinate instead of 1/sigma^2 (needs the noise).
    WlsSigma,
    /// Feasible GLS: the joint sigmas and the measurement sigmas (sigma_me; of observation
    /// files, one per kind of observation) estimated from the residuals, iterated.
    Fgls,
}

/// How `calibrate --select` chooses the parameters.
#[derive(ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum SelectName {
    /// Forward selection by k-fold cross-validated RMS, one-standard-error rule.
    Cv,
    /// Forward selection by the Bayesian information criterion.
    Bic,
    /// Backward elimination of the estimates below 2 standard errors.
    T,
}

/// What is measured at each pose.
#[derive(ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum MeasuredName {
    /// The tool point's position.
    Position,
    /// The tool's position and orientation.
    Pose,
}

/// A box the tool point must stay in (mm, the robot's base frame).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ToolBox {
    /// The lowest corner.
    pub low: Vector3<f64>,
    /// The highest corner.
    pub high: Vector3<f64>,
}

/// An `--exclude JOINT:FROM:TO` range, in degrees (mm for a prismatic joint); the joint name
/// is checked against the model by the command.
#[derive(Clone, Debug, PartialEq)]
pub struct Excluded {
    /// The joint's name.
    pub joint: String,
    /// The range to avoid, lowest first.
    pub range: [f64; 2],
}

/// Joint values of `fk --q`, one per joint: degrees (mm for prismatic joints).
#[derive(Clone, Debug, PartialEq)]
pub struct JointValues(pub Vec<f64>);

/// `--joint-unit` and `--length-unit`, which go together.
#[derive(Args, Debug)]
pub struct UnitArgs {
    /// Unit of revolute joint values in the files, if they do not declare it (with
    /// --length-unit).
    #[arg(long)]
    pub joint_unit: Option<JointUnit>,
    /// Unit of lengths in the files, if they do not declare it (with --joint-unit).
    #[arg(long)]
    pub length_unit: Option<LengthUnit>,
}

/// The robot model: a preset, a model TOML file, or a URDF file and the chain in it.
#[derive(Args, Debug)]
pub struct ModelArgs {
    /// The nominal robot: a preset name (see `robocal model list`), a model TOML file, or a
    /// URDF file (`.urdf`: the chain from its root link to its only leaf, unless --base-link
    /// or --tip-link say otherwise).
    #[arg(long)]
    pub model: String,
    #[command(flatten)]
    pub links: LinkArgs,
    #[command(flatten)]
    pub payload: PayloadArgs,
}

/// A payload the arm carries.
#[derive(Args, Debug)]
pub struct PayloadArgs {
    /// A payload the arm carries (kg), added to the last link's mass for the gravity loads on
    /// the joints: the model's compliances and plays deflect under it too.
    #[arg(long, allow_hyphen_values = true)]
    pub payload_kg: Option<f64>,
    /// The payload's centre of mass (mm) in the tip link's frame (the frame markers are given
    /// in; default its origin).
    #[arg(long, value_delimiter = ',', allow_hyphen_values = true, requires = "payload_kg")]
    pub payload_com_mm: Option<Vec<f64>>,
}

/// Which chain of a URDF file: its first and last link.
#[derive(Args, Debug)]
pub struct LinkArgs {
    /// URDF: the link the chain starts from (default: the root link).
    #[arg(long)]
    pub base_link: Option<String>,
    /// URDF: the link the chain ends at, whose frame is the tool frame that markers are given
    /// in (default: the only leaf link).
    #[arg(long)]
    pub tip_link: Option<String>,
}

/// The noise given as numbers: joint sigmas, measurement sigma, orientation sigma.
#[derive(Args, Debug)]
pub struct NoiseArgs {
    /// Joint noise standard deviations, one per joint or one for every joint (deg; mm for
    /// prismatic joints): the weights of calibrate, the whitened H of plan and observability,
    /// the whitened residuals of evaluate. Give --sigma-mm too: joint noise alone can leave a
    /// pose's covariance singular.
    #[arg(long, value_delimiter = ',', allow_hyphen_values = true, value_parser = parse_sigma_deg)]
    pub joint_sigma_deg: Option<Vec<f64>>,
    /// Measurement noise standard deviation (mm), with --joint-sigma-deg; a data file's `sigma`
    /// column takes its place when it has one. Observation files (calibrate): the sigma of every
    /// row without its own `sigma` cell, in place of its kind's default (--joint-sigma-deg not
    /// needed).
    #[arg(long, default_value_t = 0.0, value_parser = parse_sigma_mm)]
    pub sigma_mm: f64,
    /// Orientation measurement noise (deg), for pose or orientation measurements; observation
    /// files: the sigma of every angle without its own `sigma_angle` cell.
    #[arg(long, default_value_t = 0.0, value_parser = parse_sigma_deg)]
    pub sigma_orientation_deg: f64,
}

/// Where a study's tables, samples and figures go, and the threads that compute them.
#[derive(Args, Debug)]
pub struct StudyOutputArgs {
    /// Folder for the tables, the CSV samples and the SVG figures.
    #[arg(long, default_value = "robocal-out")]
    pub out: PathBuf,
    /// Worker threads (default: all cores). The numbers do not depend on it.
    #[arg(long)]
    pub threads: Option<usize>,
    /// Also repeat the whole study R times with master seeds derived from its seed (in
    /// parallel), and report each statistic of its tables over the replications, with the
    /// paper's value and its percentile (1 to 10000; 100 take about a minute).
    #[arg(long, value_name = "R", value_parser = parse_replications)]
    pub replications: Option<usize>,
}

/// `--replications`: 1 to [`robocal::simulation::MAX_REPLICATIONS`].
fn parse_replications(text: &str) -> Result<usize, String> {
    let count: usize = text.parse().map_err(|_| format!("expected a whole number, found `{text}`"))?;
    robocal::simulation::check_replications(count).map_err(|e| e.to_string())
}

/// The flags of `robocal simulate`.
#[derive(Args, Debug)]
pub struct SimulateArgs {
    /// The study file or name.
    pub study: String,
    #[command(flatten)]
    pub output: StudyOutputArgs,
    /// A noise file (TOML, see docs/formats.md) replacing the study's noise: joint sigmas,
    /// device, and sigma_me if it gives one.
    #[arg(long)]
    pub noise: Option<PathBuf>,
    /// Compute only shard I of N (0 <= I < N) of the study's runs (with --replications, of
    /// each replication's; of an instrument study, its calibrations) and write its samples to
    /// `<out>/<study name>/shard-I-of-N.json`, for `robocal merge`.
    #[arg(long, value_name = "I/N", value_parser = parse_shard)]
    pub shard: Option<robocal::simulation::Shard>,
}

/// `--shard I/N`.
fn parse_shard(text: &str) -> Result<robocal::simulation::Shard, String> {
    text.parse()
}

/// The flags of `robocal merge`.
#[derive(Args, Debug)]
pub struct MergeArgs {
    /// Folders holding the shards (`shard-I-of-N.json`, in the folder or one level below) or
    /// shard files: every shard of one `simulate --shard` study, each once.
    #[arg(required = true)]
    pub shards: Vec<PathBuf>,
    /// Folder for the tables, the CSV samples and the SVG figures, as `simulate` writes them.
    #[arg(long, default_value = "robocal-out")]
    pub out: PathBuf,
}

/// The flags of `robocal fk`.
#[derive(Args, Debug)]
pub struct FkArgs {
    #[command(flatten)]
    pub model: ModelArgs,
    /// Joint values, separated by commas or spaces: degrees for revolute joints, mm for
    /// prismatic ones.
    #[arg(long, allow_hyphen_values = true, value_parser = parse_joint_values)]
    pub q: JointValues,
}

/// The flags of `robocal repeatability`.
#[derive(Args, Debug)]
pub struct RepeatabilityArgs {
    #[command(flatten)]
    pub model: ModelArgs,
    /// The repeatability file (CSV: a measurement file with a `pose` column; docs/formats.md).
    #[arg(long)]
    pub data: PathBuf,
    #[command(flatten)]
    pub units: UnitArgs,
    /// Estimate the full joint covariance Sigma_q, not only one sigma per joint.
    #[arg(long)]
    pub full_covariance: bool,
    /// Nominal position of a marker on the last link, "x,y,z" in mm, in the tool frame (a
    /// URDF's tip link; the last joint's frame for a model whose tool is a point); repeat per
    /// marker (default: marker 1 at the model's tool point).
    #[arg(long, allow_hyphen_values = true, value_name = "X,Y,Z", value_parser = parse_marker)]
    pub marker: Vec<Vector3<f64>>,
    /// The device measures in the model's base frame: do not register the frames.
    #[arg(long)]
    pub fixed_base: bool,
    /// Write the estimated noise here (a noise file for `calibrate --noise` and
    /// `simulate --noise`).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Write the estimates with their intervals as JSON here.
    #[arg(long)]
    pub json: Option<PathBuf>,
}

/// The flags that choose the model beyond `--params`: what is held, kept, given a prior, and
/// the loss (`calibrate` of markers and of observations).
#[derive(Args, Debug, Clone, Default, PartialEq)]
pub struct ModelChoiceArgs {
    /// Hold these parameters at their nominal values (names and patterns, as --params takes
    /// them: `j*.beta,j2.d`): they are not estimated.
    #[arg(long, value_delimiter = ',', value_name = "NAMES")]
    pub hold: Vec<String>,
    /// Keep these parameters free first (names and patterns): when the poses cannot tell a
    /// combination apart, another of it is held, the base's and the markers' included.
    #[arg(long, value_delimiter = ',', value_name = "NAMES")]
    pub keep: Vec<String>,
    /// Prior standard deviations about the nominal model (maximum a posteriori): comma-separated
    /// `PATTERN=SD` entries, repeatable, later ones overriding earlier ones. PATTERN is a name or
    /// pattern as --params takes it (`j*.alpha`), or `lengths`, `angles`, `offsets`,
    /// `compliances`, `plays` (those of every joint); SD has a unit, which also picks the
    /// parameters: mm, um, m, deg, rad, mrad, or a plain number for a compliance (rad/N·m,
    /// mm/N). Presets of typical tolerances (lengths, angles, joint zeros, plays): `machined`
    /// (0.1 mm, 0.05 deg, 0.5 deg, 0.02 deg), `precision` (0.02 mm, 0.01 deg, 0.1 deg,
    /// 0.005 deg), `fabricated` (0.5 mm, 0.2 deg, 2 deg, 0.1 deg); none puts a prior on the
    /// compliances.
    /// A prior applies to the parameters --params asks for; with one, a parameter the poses
    /// cannot identify is not held, and the standard errors are the posterior ones. A noise
    /// file's [prior] table comes first. Example: `--prior 'machined,j6.theta=0.1deg'`.
    /// `calibrate --prior auto[:PRESET]` (default preset `fabricated`) scales the preset's
    /// standard deviations by one factor from 1/16 to 16, chosen by k-fold cross-validation
    /// on the training poses (--folds K, default 5); other --prior entries override it.
    /// `--prior auto-ml[:PRESET]` chooses the factor (1/64 to 64 in steps of 2^(1/8)) by the
    /// marginal likelihood instead (type-II maximum likelihood), with no refit per factor:
    /// with the noise (--sigma-mm with --joint-sigma-deg, or --noise; on observation files
    /// their sigma columns or --joint-sigma-deg), or on a marker file without it, the noise
    /// taken as the residuals' spread of the fit without priors, which OLS's priors weigh
    /// against (printed). `--prior auto-ml:PRESET:classes`
    /// (or `auto-ml:classes`) chooses one factor per class of the preset (lengths, angles,
    /// offsets, plays) by the marginal likelihood, each reported with the one factor's.
    #[arg(long, value_name = "PATTERN=SD,...", value_parser = parse_prior)]
    pub prior: Vec<PriorArg>,
    /// The loss of each pose's whitened residual: `squared` (least squares), `huber[:K]`
    /// (K = 1.345 by default) or `cauchy[:K]` (K = 2.385), by iteratively reweighted least
    /// squares; a pose is down-weighted as a whole, and those weighted below 0.1 are listed.
    #[arg(long, default_value = "squared", value_name = "LOSS", value_parser = parse_loss)]
    pub loss: Loss,
}

/// The flags of `robocal calibrate`.
#[derive(Args, Debug)]
pub struct CalibrateArgs {
    #[command(flatten)]
    pub model: ModelArgs,
    /// A data file (CSV; see docs/formats.md), its kind read from its header: marker positions
    /// or a probe's poses (x1,y1,z1, ...), distances, plane contacts, coordinates, a camera's
    /// views, or views between the branches of a URDF tree (camera, target); repeatable: the
    /// files are fitted together, each a session (--per-session).
    #[arg(long, required = true)]
    pub data: Vec<PathBuf>,
    #[command(flatten)]
    pub units: UnitArgs,
    /// The estimator. Default: wls when a noise is given (--noise, --joint-sigma-deg, or an
    /// observation file's sigma column or --sigma-mm), ols otherwise (every row alike, the
    /// residuals' spread their sigma).
    #[arg(long)]
    pub estimator: Option<EstimatorName>,
    /// A noise file (TOML, see docs/formats.md): joint noise, sigma_me and the measuring
    /// device. Replaces --joint-sigma-deg, --sigma-mm and --sigma-orientation-deg (observation
    /// files: sigma_me for the rows without a sigma cell).
    #[arg(long)]
    pub noise: Option<PathBuf>,
    #[command(flatten)]
    pub noise_flags: NoiseArgs,
    /// Parameters to identify: `joints` (every joint parameter), `all` (the joint parameters,
    /// the base and the markers: not with --fixed-base or --fixed-markers), `offsets` (the
    /// joint offsets), `none` (only the base and the markers), or names and patterns
    /// (`j*.theta,j2.a`). The base and the markers are estimated unless --fixed-base and
    /// --fixed-markers say otherwise.
    #[arg(long, default_value = "joints", value_parser = parse_params)]
    pub params: ParamWords,
    /// Marker files (and coordinates): do not estimate the base (the measuring frame is the
    /// model's base frame).
    #[arg(long)]
    pub fixed_base: bool,
    /// Marker files: do not estimate the marker positions (held at --marker's).
    #[arg(long)]
    pub fixed_markers: bool,
    #[command(flatten)]
    pub choice: ModelChoiceArgs,
    /// Choose the joint parameters by held-out error among those --params names: `cv`
    /// (forward selection by k-fold cross-validated RMS, --folds K, default 5,
    /// one-standard-error rule), `bic` (forward selection by the Bayesian information criterion), `t`
    /// (backward elimination of the estimates below 2 standard errors).
    #[arg(long, value_enum)]
    pub select: Option<SelectName>,
    /// Nominal position of a marker on the last link, "x,y,z" in mm, in the tool frame (a
    /// URDF's tip link; the last joint's frame for a model whose tool is a point); repeat per
    /// marker (missing ones start at that frame's origin).
    #[arg(long, allow_hyphen_values = true, value_name = "X,Y,Z", value_parser = parse_marker)]
    pub marker: Vec<Vector3<f64>>,
    /// Gauss-Newton steps at most (at least 1), damped in a trust region where they overshoot;
    /// a robust loss's reweightings share them; 1 is the paper's one-step estimate.
    #[arg(long, default_value_t = RefineOptions::default().max_iterations, value_parser = parse_iterations)]
    pub iterations: usize,
    /// A measurement file of held-out poses to validate on; repeatable.
    #[arg(long)]
    pub validate: Vec<PathBuf>,
    /// k-fold cross-validation on the data (k >= 2, at most the number of poses), nested with
    /// --select (the selection made again inside each fold); with --select cv, the selection's
    /// folds too.
    #[arg(long, value_parser = parse_count::<2>)]
    pub folds: Option<usize>,
    /// Marker files: fit with these markers only (their numbers, `x<k>` columns: `1,3`);
    /// held-out files are scored on those of them they hold. Default: every marker.
    #[arg(long, value_delimiter = ',', value_parser = parse_count::<1>)]
    pub markers: Option<Vec<usize>>,
    #[command(flatten)]
    pub report: ReportArgs,
    /// Write the calibrated model (TOML, with a [[markers]] list) here.
    #[arg(long)]
    pub out_model: Option<PathBuf>,
    /// Write the calibrated model as URDF here (URDF input only): the original file with the
    /// calibrated joint origins, a `measuring_frame` link, a `tool` link (marker 1) and a
    /// `marker_<k>` link per fitted marker (what `evaluate` reads); of a tree, the original file
    /// with every joint's calibrated origin.
    #[arg(long)]
    pub out_urdf: Option<PathBuf>,
    #[command(flatten)]
    pub observations: ObservationArgs,
    #[command(flatten)]
    pub tree: TreeArgs,
}

/// The flags of `robocal calibrate` for observation files (distances, contacts, coordinates,
/// camera views, several files).
#[derive(Args, Debug, Default)]
pub struct ObservationArgs {
    /// Observation files: the tool point on the last link, "x,y,z" in mm, in the tool frame
    /// (default: the model's tool point); unused with a camera's views alone.
    #[arg(long, allow_hyphen_values = true, value_name = "X,Y,Z", value_parser = parse_marker)]
    pub tool: Option<Vector3<f64>>,
    /// Observation files: do not estimate the tool point.
    #[arg(long)]
    pub fixed_tool: bool,
    /// Set-up parameters with one value per --data file (each file a session, named by its
    /// stem), estimated: names or patterns (`point1.zero`, `pair.zero`, `target.*`), for an
    /// instrument re-zeroed or moved between sessions. A length zero (`point<i>.zero`,
    /// `pair.zero`, mm: distance = |p - c| + zero) is held unless named here or in --params.
    /// `tracker.*`: marker files measured by a tracker moved between sessions, each later
    /// session's tracker placed in the first one's frame (mm, rotation vector in deg). A
    /// tree's views: its cameras' and targets' placements (`target.l_hand.*`).
    #[arg(long, value_delimiter = ',', value_name = "NAMES")]
    pub per_session: Vec<String>,
}

/// The flags of `robocal calibrate` for a robot of several branches (a URDF tree).
#[derive(Args, Debug, Default)]
pub struct TreeArgs {
    /// A URDF tree's branches: their tip links, comma-separated (with views between branches,
    /// default: every leaf link with a moving joint on its way).
    #[arg(long, value_delimiter = ',')]
    pub tips: Vec<String>,
    /// A URDF tree: write each branch's calibrated model here, as `<tip>.toml`, and the
    /// cameras and targets as `frames.json`.
    #[arg(long, value_name = "DIR")]
    pub out_dir: Option<PathBuf>,
}

/// The flags of `robocal calibrate-observations` (an alias of `calibrate` for one release).
#[derive(Args, Debug)]
pub struct CalibrateObservationsArgs {
    #[command(flatten)]
    pub model: ModelArgs,
    /// A file of distances (pairs of poses, or to a fixed point), plane contacts,
    /// coordinates, a camera's views of its target, or marker positions (calibrate's
    /// measurement file, x1,y1,z1, ...) (CSV; see docs/formats.md); repeatable: the files are
    /// fitted together.
    #[arg(long, required = true)]
    pub data: Vec<PathBuf>,
    #[command(flatten)]
    pub units: UnitArgs,
    /// The estimator: wls (default where a noise is given; each pose's observations weighted
    /// by their sigmas and, with --joint-sigma-deg, the joint noise they share), wls-diag,
    /// wls-sigma or ols (the default without any noise: no sigma column or flag, the joints
    /// exact).
    #[arg(long, hide_possible_values = true)]
    pub estimator: Option<EstimatorName>,
    /// Joint noise standard deviations, one per joint or one for every joint (deg; mm for
    /// prismatic joints): a distance between two poses carries the joint noise of both.
    #[arg(long, value_delimiter = ',', allow_hyphen_values = true, value_parser = parse_sigma_deg)]
    pub joint_sigma_deg: Option<Vec<f64>>,
    /// Parameters to identify: `joints` (every joint parameter), `offsets`, `none` (the tool
    /// and the set-up only), or names and patterns (`j*.theta,j2.a`). The base is estimated
    /// only from coordinates and markers: distances, contacts and cameras cannot see it.
    #[arg(long, default_value = "joints", value_parser = parse_params)]
    pub params: ParamWords,
    /// The tool point on the last link, "x,y,z" in mm, in the tool frame (default: the model's
    /// tool point); unused with a camera's views alone (its mounting is in the tool frame).
    #[arg(long, allow_hyphen_values = true, value_name = "X,Y,Z", value_parser = parse_marker)]
    pub tool: Option<Vector3<f64>>,
    /// Do not estimate the tool point.
    #[arg(long)]
    pub fixed_tool: bool,
    /// Nominal position of a marker of a marker file (x1,y1,z1, ...) on the last link, "x,y,z"
    /// in mm, in the tool frame, as `calibrate --marker` takes it: the k-th is marker k; repeat
    /// per marker (missing ones start at that frame's origin).
    #[arg(long, allow_hyphen_values = true, value_name = "X,Y,Z", value_parser = parse_marker)]
    pub marker: Vec<Vector3<f64>>,
    /// Marker files: fit with these markers only (their numbers: `1,3`); held-out files are
    /// scored on those of them they hold. Default: every marker.
    #[arg(long, value_delimiter = ',', value_parser = parse_count::<1>)]
    pub markers: Option<Vec<usize>>,
    /// Marker files and coordinates: do not estimate the base (the measuring frame is the
    /// model's base frame; the markers are not registered).
    #[arg(long)]
    pub fixed_base: bool,
    /// Marker files: do not estimate the marker positions (held at --marker's).
    #[arg(long)]
    pub fixed_markers: bool,
    /// A noise file (TOML, see docs/formats.md): the joint noise (in place of
    /// --joint-sigma-deg), `sigma_me_mm` and `sigma_orientation_deg` for the rows without their
    /// own sigma (in place of --sigma-mm and --sigma-orientation-deg), a [device]'s covariance at
    /// each point measured, its [prior] table before --prior's.
    #[arg(long)]
    pub noise: Option<PathBuf>,
    /// The measurement standard deviation (mm) of every row without a `sigma` cell, in place
    /// of its kind's default (0.01 mm; a camera's 0.5 mm).
    #[arg(long, value_parser = parse_sigma_mm)]
    pub sigma_mm: Option<f64>,
    /// The standard deviation of an angle (deg) of every row without a `sigma_angle` cell, in
    /// place of its kind's default (0.01 deg; a camera's 0.1 deg).
    #[arg(long, value_parser = parse_sigma_deg)]
    pub sigma_orientation_deg: Option<f64>,
    #[command(flatten)]
    pub choice: ModelChoiceArgs,
    /// Gauss-Newton steps at most (at least 1), damped in a trust region where they overshoot.
    #[arg(long, default_value_t = RefineOptions::default().max_iterations, value_parser = parse_iterations)]
    pub iterations: usize,
    /// A held-out file of the same kinds to validate on (the set-up as calibrated); repeatable.
    /// With --per-session, a file of a training file's stem takes that session's set-up; any
    /// other has its per-session parameters fitted on it alone, the robot held.
    #[arg(long)]
    pub validate: Vec<PathBuf>,
    /// Set-up parameters with one value per --data file (each file a session, named by its
    /// stem), estimated: names or patterns (`point1.zero`, `pair.zero`, `target.*`), for an
    /// instrument re-zeroed or moved between sessions. A length zero (`point<i>.zero`,
    /// `pair.zero`, mm: distance = |p - c| + zero) is held unless named here or in --params.
    /// `tracker.*`: marker files measured by a tracker moved between sessions, each later
    /// session's tracker placed in the first one's frame (mm, rotation vector in deg).
    #[arg(long, value_delimiter = ',', value_name = "NAMES")]
    pub per_session: Vec<String>,
    /// Choose the joint parameters by held-out error among those --params names: `cv`, `bic`
    /// or `t`, as for a marker file (a fold holds out the observations of its poses; cv scores
    /// the lengths).
    #[arg(long, value_enum)]
    pub select: Option<SelectName>,
    /// k-fold cross-validation on the data (k >= 2, at most the number of poses): the
    /// observations of pose p held out in fold p mod k, each fold calibrated with every flag
    /// (priors, loss, sessions) on the others; their held-out residuals pooled as a set.
    #[arg(long, value_parser = parse_count::<2>)]
    pub folds: Option<usize>,
    #[command(flatten)]
    pub report: ReportArgs,
    /// Write the calibrated model (TOML; its tool the calibrated tool point) here.
    #[arg(long)]
    pub out_model: Option<PathBuf>,
    /// Write the calibrated model as URDF here (URDF input only): the original file with the
    /// calibrated joint origins, its tool the calibrated tool point, a `marker_<k>` link per
    /// fitted marker.
    #[arg(long)]
    pub out_urdf: Option<PathBuf>,
}

/// Where the report of scored poses goes, besides standard output.
#[derive(Args, Debug, Clone, Default, PartialEq)]
pub struct ReportArgs {
    /// Write the report as JSON here (every pose of every set included; `-`: standard output,
    /// the text report then on standard error).
    #[arg(long)]
    pub json: Option<PathBuf>,
    /// Write every pose of every set here (CSV; `-`: standard output): for a marker file one
    /// row per pose and marker (errors before and after, whitened residual, flag); for
    /// observation files and a tree's views one row per observation or view (file, line,
    /// kind, pose, joint values, residual before and after in mm or deg, whitened, flag).
    #[arg(long, value_name = "FILE")]
    pub poses_csv: Option<PathBuf>,
    /// Write the figures here (SVG): per-pose (per-observation, per-view) errors before and
    /// after on one scale, the errors' densities, the errors against each joint (and its
    /// gravity load, for a model with masses), the curve --prior auto chose its scale from.
    #[arg(long, value_name = "DIR")]
    pub figures: Option<PathBuf>,
    /// Write one self-contained HTML page here: the report's tables and figures inline.
    #[arg(long, value_name = "FILE")]
    pub html: Option<PathBuf>,
}

/// The flags of `robocal evaluate`.
#[derive(Args, Debug)]
pub struct EvaluateArgs {
    /// The model to score as it stands: a model TOML file (as `calibrate --out-model` writes
    /// it, with its [[markers]]), a preset, or a URDF file (as `calibrate --out-urdf` writes
    /// it).
    #[arg(long)]
    pub model: String,
    /// URDF: the link the chain starts from (default: `measuring_frame`; for a tree, its
    /// root link).
    #[arg(long)]
    pub base_link: Option<String>,
    /// URDF: the link the chain ends at (its markers are the `marker_<k>` links beside it).
    #[arg(long, default_value = "tool")]
    pub tip_link: String,
    /// A URDF tree's branches: their tip links, comma-separated, as `calibrate --tips` takes
    /// them (with views between branches, default: every leaf link with a moving joint on its
    /// way).
    #[arg(long, value_delimiter = ',')]
    pub tips: Vec<String>,
    /// A URDF tree: score the branches as `calibrate --out-dir` wrote them in this folder
    /// (`<tip>.toml`), the tree's joints taken from them.
    #[arg(long, value_name = "DIR")]
    pub branches: Option<PathBuf>,
    #[command(flatten)]
    pub payload: PayloadArgs,
    /// Files to score (CSV); repeatable, or several after one --data. A marker file is scored
    /// as it stands (no registration); a file of any other kind (distances, contacts,
    /// coordinates, camera views) with its set-up (pivots, planes, camera and target) fitted
    /// to it, the model and its tool point held; a file of views between a tree's branches
    /// with its cameras and targets fitted, the tree held.
    #[arg(long, required = true, num_args = 1..)]
    pub data: Vec<PathBuf>,
    #[command(flatten)]
    pub units: UnitArgs,
    /// A noise file (TOML) for the whitened residuals (marker and observation files; not view files).
    #[arg(long)]
    pub noise: Option<PathBuf>,
    #[command(flatten)]
    pub noise_flags: NoiseArgs,
    /// Score these markers only (their numbers: `1,3`). Default: every marker of each file.
    #[arg(long, value_delimiter = ',', value_parser = parse_count::<1>)]
    pub markers: Option<Vec<usize>>,
    #[command(flatten)]
    pub report: ReportArgs,
}

/// The robot, parameters, measurements and noise of `observability` and `plan`.
#[derive(Args, Debug)]
pub struct DesignArgs {
    #[command(flatten)]
    pub model: ModelArgs,
    /// Parameters to identify: `joints` (every joint parameter: the paper's set), `all` (every
    /// parameter: the joints, the base and the tool), `offsets` (the joint offsets), or names
    /// and patterns (`j*.theta,j2.a`).
    #[arg(long, default_value = "joints", value_parser = parse_params)]
    pub params: ParamWords,
    /// What is measured at each pose.
    #[arg(long, value_enum, default_value_t = MeasuredName::Position)]
    pub measured: MeasuredName,
    #[command(flatten)]
    pub noise: NoiseArgs,
}

/// The flags of `robocal observability`.
#[derive(Args, Debug)]
pub struct ObservabilityArgs {
    /// The pose file (CSV with the model's joint columns and a `# units:` line).
    pub poses: PathBuf,
    #[command(flatten)]
    pub design: DesignArgs,
    /// Unit of revolute joint values in the file, if it does not declare it.
    #[arg(long)]
    pub joint_unit: Option<JointUnit>,
}

/// The flags of `robocal plan`.
#[derive(Args, Debug)]
pub struct PlanArgs {
    #[command(flatten)]
    pub design: DesignArgs,
    /// Number of poses to plan.
    #[arg(long)]
    pub points: usize,
    /// Candidate poses drawn uniformly within the joint limits (and the constraints).
    #[arg(long, default_value_t = 5000)]
    pub candidates: usize,
    /// What to maximise: `d` (D-optimal), `o1` ... `o5`.
    #[arg(long, default_value = "d")]
    pub criterion: Criterion,
    /// Seed of the candidate pool: the same seed gives the same poses.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// A box the tool point must stay in: "xmin,ymin,zmin,xmax,ymax,zmax" in mm, in the
    /// robot's base (measuring) frame.
    #[arg(long, allow_hyphen_values = true, value_name = "XMIN,YMIN,ZMIN,XMAX,YMAX,ZMAX", value_parser = parse_tool_box)]
    pub tool_box: Option<ToolBox>,
    /// A joint range to avoid, "JOINT:FROM:TO" in degrees (mm for a prismatic joint);
    /// repeatable.
    #[arg(long, allow_hyphen_values = true, value_name = "JOINT:FROM:TO", value_parser = parse_exclude)]
    pub exclude: Vec<Excluded>,
    /// Write the poses here (CSV) and the summary to standard output; without it the poses go
    /// to standard output and the summary to standard error.
    #[arg(long)]
    pub out: Option<PathBuf>,
}

/// `text` split at `separator` into finite numbers of magnitude at most [`MAX_LENGTH_MM`], or
/// `None` if one is not.
fn finite_numbers(text: &str, separator: char) -> Option<Vec<f64>> {
    let plausible = |v: &f64| v.is_finite() && v.abs() <= MAX_LENGTH_MM;
    text.split(separator).map(|s| s.trim().parse().ok().filter(plausible)).collect()
}

/// A standard deviation in degrees (mm for a prismatic joint's): a finite number from 0 to
/// [`MAX_ANGLE_DEG`].
fn parse_sigma_deg(text: &str) -> Result<f64, String> {
    parse_sigma(text, MAX_ANGLE_DEG)
}

/// A standard deviation in mm: a finite number from 0 to [`MAX_LENGTH_MM`].
fn parse_sigma_mm(text: &str) -> Result<f64, String> {
    parse_sigma(text, MAX_LENGTH_MM)
}

/// A standard deviation: a finite number from 0 to `bound`.
fn parse_sigma(text: &str, bound: f64) -> Result<f64, String> {
    match text.trim().parse::<f64>() {
        Ok(v) if v.is_finite() && (0.0..=bound).contains(&v) => Ok(v),
        _ => Err(format!("expected a finite number from 0 to {bound:e}")),
    }
}

/// A count of at least `MIN`.
fn parse_count<const MIN: usize>(text: &str) -> Result<usize, String> {
    match text.trim().parse::<usize>() {
        Ok(n) if n >= MIN => Ok(n),
        _ => Err(format!("expected a whole number >= {MIN}")),
    }
}

/// Gauss-Newton steps: 1 to [`MAX_ITERATIONS`].
fn parse_iterations(text: &str) -> Result<usize, String> {
    match parse_count::<1>(text)? {
        n if n <= MAX_ITERATIONS => Ok(n),
        _ => Err(format!("expected a whole number from 1 to {MAX_ITERATIONS}")),
    }
}

/// One `--prior`: entries, or a preset to scale from the data.
#[derive(Debug, Clone, PartialEq)]
pub enum PriorArg {
    /// `PATTERN=SD` entries and presets.
    Entries(Vec<PriorEntry>),
    /// `auto[:PRESET]`, `auto-ml[:PRESET]` or `auto-ml[:PRESET]:classes`.
    Auto(AutoPrior),
}

/// Prior entries, `PATTERN=SD` separated by commas, or presets; or `auto[:PRESET]`,
/// `auto-ml[:PRESET]` or `auto-ml[:PRESET]:classes` ([`AutoPrior::parse`], the one parser).
fn parse_prior(text: &str) -> Result<PriorArg, String> {
    if let Some(auto) = AutoPrior::parse(text) {
        return auto.map(PriorArg::Auto);
    }
    PriorEntry::parse_list(text).map(PriorArg::Entries).map_err(|e| e.to_string())
}

/// A loss: `squared`, `huber[:K]`, `cauchy[:K]`.
fn parse_loss(text: &str) -> Result<Loss, String> {
    text.parse()
}

/// A marker position "x,y,z" (mm).
fn parse_marker(text: &str) -> Result<Vector3<f64>, String> {
    match finite_numbers(text, ',').as_deref() {
        Some(&[x, y, z]) => Ok(Vector3::new(x, y, z)),
        _ => Err("expected three finite numbers x,y,z in mm, each of magnitude at most 1e6".into()),
    }
}

/// A tool box "xmin,ymin,zmin,xmax,ymax,zmax" (mm), each minimum at most its maximum.
fn parse_tool_box(text: &str) -> Result<ToolBox, String> {
    let Some(&[x0, y0, z0, x1, y1, z1]) = finite_numbers(text, ',').as_deref() else {
        return Err(
            "expected six finite numbers xmin,ymin,zmin,xmax,ymax,zmax in mm, each of magnitude at most 1e6"
                .into(),
        );
    };
    let (low, high) = (Vector3::new(x0, y0, z0), Vector3::new(x1, y1, z1));
    if (0..3).any(|i| low[i] > high[i]) {
        return Err("each minimum must not exceed its maximum".into());
    }
    Ok(ToolBox { low, high })
}

/// An excluded range "JOINT:FROM:TO" with FROM at most TO.
fn parse_exclude(text: &str) -> Result<Excluded, String> {
    let expected = "expected JOINT:FROM:TO with finite FROM and TO, e.g. j2:-30:10 (degrees)";
    let (name, range) = text.split_once(':').ok_or(expected)?;
    let Some(&[from, to]) = finite_numbers(range, ':').as_deref() else {
        return Err(expected.into());
    };
    if from > to {
        return Err("FROM must not exceed TO".into());
    }
    Ok(Excluded { joint: name.trim().to_string(), range: [from, to] })
}

/// `"0, 45,180"` or `"0 45 180"`: finite joint values of magnitude at most [`MAX_LENGTH_MM`]
/// (values outside a joint's limits are warned about by `fk`).
fn parse_joint_values(text: &str) -> Result<JointValues, String> {
    text.split(|c: char| c == ',' || c.is_whitespace())
        .filter(|s| !s.is_empty())
        .enumerate()
        .map(|(i, s)| match s.parse::<f64>() {
            Ok(v) if v.is_finite() && v.abs() <= MAX_LENGTH_MM => Ok(v),
            Ok(v) => Err(format!(
                "value {} is {}, expected a finite number of magnitude at most {MAX_LENGTH_MM:e}",
                i + 1,
                robocal::limits::shown(v)
            )),
            Err(_) => Err(format!("value {} `{s}` is not a number", i + 1)),
        })
        .collect::<Result<_, _>>()
        .map(JointValues)
}

/// `--params`: [`ParamWords::parse`].
fn parse_params(text: &str) -> Result<ParamWords, String> {
    ParamWords::parse(text)
}

/// The subcommands of `robocal model`.
#[derive(clap::Subcommand, Debug)]
pub enum ModelCommand {
    /// Print a model (preset name or file) as TOML, in mm and degrees.
    Show {
        /// A preset name, a model TOML file, or a URDF file (the chain it reads is printed).
        model: String,
        #[command(flatten)]
        links: LinkArgs,
    },
    /// List the embedded presets.
    List,
    /// Write a model (any convention) as a URDF of its own, for MoveIt and ROS: each joint's
    /// origin as xyz/rpy, the tool as a fixed joint to `tool0`.
    Urdf {
        /// A preset name, a model TOML file, or a URDF file.
        model: String,
        #[command(flatten)]
        links: LinkArgs,
        /// Standard URDF elements only; the compliances, plays and gravity go into a TOML
        /// sidecar beside --out (`<out>.extras.toml`).
        #[arg(long)]
        urdf_standard: bool,
        /// The URDF file to write (default: standard output).
        #[arg(long)]
        out: Option<PathBuf>,
    },
    /// Write a UR model (six revolute joints) as the Universal Robots ROS driver's kinematics
    /// file (per joint x, y, z, roll, pitch, yaw); a tool offset, which the file cannot hold,
    /// is printed as the TCP to set on the controller.
    UrKinematics {
        /// A preset name (ur3e, ur5e, ur10e, ur16e), a model TOML file (a calibrated UR), or a
        /// URDF file.
        model: String,
        #[command(flatten)]
        links: LinkArgs,
        /// The YAML file to write (default: standard output).
        #[arg(long)]
        out: Option<PathBuf>,
    },
}

impl std::fmt::Display for Excluded {
    /// As given: `JOINT:FROM:TO`.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}:{}:{}", self.joint, self.range[0], self.range[1])
    }
}

/// The flags of `robocal calibrate-tree` (an alias of `calibrate` for one release).
#[derive(Args, Debug)]
pub struct CalibrateTreeArgs {
    /// The robot: a URDF file whose links form a tree (a torso with arms and a head); each
    /// branch is the chain from the root link to a tip link.
    #[arg(long)]
    pub model: PathBuf,
    /// The link every branch starts from (default: the root link).
    #[arg(long)]
    pub base_link: Option<String>,
    /// The branches' tip links, comma-separated (default: every leaf link with a moving joint
    /// on its way).
    #[arg(long, value_delimiter = ',')]
    pub tips: Vec<String>,
    /// A file of camera views between the branches, or of a tracker's positions of points on
    /// them (no roll, pitch, yaw columns) (CSV; see docs/formats.md); repeatable: the files are
    /// fitted together.
    #[arg(long, required = true)]
    pub data: Vec<PathBuf>,
    #[command(flatten)]
    pub units: UnitArgs,
    /// The estimator: wls (default; each view weighted by its sigmas and, with
    /// --joint-sigma-deg, the joint noise of both its frames' branches) or ols.
    #[arg(long, hide_possible_values = true)]
    pub estimator: Option<EstimatorName>,
    /// Joint noise standard deviations, one per joint of the tree in the order the report's
    /// `joints:` line lists them (deg, mm for prismatic joints), or one for every joint.
    #[arg(long, value_delimiter = ',', allow_hyphen_values = true, value_parser = parse_sigma_deg)]
    pub joint_sigma_deg: Option<Vec<f64>>,
    /// Parameters to identify: `joints` (every joint parameter), `offsets`, `none` (the
    /// cameras and targets only), or names and patterns (`l_*.x,head_tilt.*`). The base is
    /// never estimated: views cannot see it.
    #[arg(long, default_value = "joints", value_parser = parse_params)]
    pub params: ParamWords,
    #[command(flatten)]
    pub choice: ModelChoiceArgs,
    /// Gauss-Newton steps at most (at least 1), damped in a trust region where they overshoot.
    #[arg(long, default_value_t = RefineOptions::default().max_iterations, value_parser = parse_iterations)]
    pub iterations: usize,
    /// A held-out file of views to validate on (the cameras and targets as calibrated);
    /// repeatable. With --per-session, a file of a training file's stem takes that session's
    /// placements; any other has its per-session placements fitted on it alone, the tree held.
    #[arg(long)]
    pub validate: Vec<PathBuf>,
    /// Cameras' and targets' placement parameters with one value per --data file (each file a
    /// session, named by its stem), estimated: names or patterns (`target.l_hand.*`), for a
    /// camera or target moved or re-mounted between sessions.
    #[arg(long, value_delimiter = ',', value_name = "NAMES")]
    pub per_session: Vec<String>,
    /// Choose the joint parameters among those --params names by `t`: backward elimination of
    /// the estimates below 2 standard errors, as for a marker file (`cv` and `bic` are not for a
    /// tree's views yet).
    #[arg(long, value_enum)]
    pub select: Option<SelectName>,
    /// k-fold cross-validation on the data (k >= 2, at most the number of poses): the views of
    /// pose p held out in fold p mod k, each fold calibrated with every flag on the others;
    /// their held-out residuals pooled as a set.
    #[arg(long, value_parser = parse_count::<2>)]
    pub folds: Option<usize>,
    #[command(flatten)]
    pub report: ReportArgs,
    /// Write each branch's calibrated model here, as `<tip>.toml` (a serial model TOML that
    /// every other command reads), and the cameras and targets as `frames.json`. The branches
    /// are right relative to each other; their placement in the root link's frame is what the
    /// views cannot see, held.
    #[arg(long, value_name = "DIR")]
    pub out_dir: Option<PathBuf>,
    /// Write the calibrated tree as URDF here: the original file with every joint's calibrated
    /// origin (the cameras and targets go to `--out-dir`'s `frames.json`).
    #[arg(long)]
    pub out_urdf: Option<PathBuf>,
}
