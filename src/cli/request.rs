//! One validated request per command: every rule between flags is checked here, before a file
//! is read, and a broken one is a [`UsageError`] (exit code 2). The rules that need a file's
//! contents are the commands' own.

use super::args::{
    CalibrateObservationsArgs, CalibrateTreeArgs, DesignArgs, EstimatorName, EvaluateArgs, Excluded,
    JointUnit, LengthUnit, LinkArgs, MeasuredName, ModelArgs, NoiseArgs, ObservabilityArgs, PayloadArgs,
    PlanArgs, PriorArg, RepeatabilityArgs, ReportArgs, SelectName, ToolBox, UnitArgs,
};
use nalgebra::Vector3;
use robocal::calibration::selection::{Criterion, DEFAULT_FOLDS};
use robocal::calibration::{JointParams, ParamWords};
use robocal::design::Criterion as DesignCriterion;
use robocal::estimation::Estimator;
use robocal::kinematics::Measured;
use robocal::limits::{MAX_CANDIDATES, MAX_LENGTH_MM, MAX_MASS_KG, MAX_POINTS, check_magnitude, check_range};
use robocal::model::{ModelRef, Payload};
use robocal::table::Units;
use std::path::{Path, PathBuf};

mod route;
#[cfg(test)]
mod tests;
pub use route::CalibrationRequest;

/// Flags that clap accepted one by one but that do not fit together: exit code 2.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{0}")]
pub struct UsageError(pub String);

/// `Err(UsageError)` with this message unless `ok`.
fn require(ok: bool, message: &str) -> Result<(), UsageError> {
    if ok { Ok(()) } else { Err(UsageError(message.to_string())) }
}

/// The file `path` names, to compare paths: the canonical path of its longest existing
/// ancestor (`.` for a relative path none of whose folders exists) followed by the rest.
fn file_identity(path: &Path) -> PathBuf {
    let mut rest = Vec::new();
    let mut base = path;
    loop {
        if let Ok(canonical) = base.canonicalize() {
            return rest.iter().rev().fold(canonical, |p, name| p.join(name));
        }
        match (base.parent(), base.file_name()) {
            (Some(parent), Some(name)) => {
                rest.push(name);
                base = if parent.as_os_str().is_empty() { Path::new(".") } else { parent };
            }
            _ => return path.to_path_buf(),
        }
    }
}

/// Whether an output `path` may be named twice: standard output (`-`) or a file other than a
/// regular file or a folder (`/dev/null`, a FIFO), which are written in place, not replaced.
fn written_in_place(path: &Path) -> bool {
    path.as_os_str() == "-" || std::fs::metadata(path).is_ok_and(|m| !m.is_file() && !m.is_dir())
}

/// An output folder: its flag, its path if given, and whether the command may write a file of
/// this name in it (at any depth).
pub(super) type OutputFolder<'a> = (&'a str, Option<&'a Path>, fn(&str) -> bool);

/// The report flags' folders: `--figures` (SVG figures) and `calibrate-tree`'s `--out-dir`
/// (one model a branch, `frames.json`).
fn known_folder(flag: &str) -> Option<fn(&str) -> bool> {
    match flag {
        "--figures" => Some(|name| name.ends_with(".svg")),
        "--out-dir" => Some(|name| name.ends_with(".toml") || name == "frames.json"),
        _ => None,
    }
}

/// Refuse an output path that is also an input's (writing it would lose the input) or
/// another output's (one would overwrite the other), and an input or another output inside an
/// output folder under a name the command writes there: `(flag, path)` each,
/// outputs not asked for `None`; `--figures` and `--out-dir` are folders.
pub(super) fn distinct_outputs(
    inputs: &[(&str, &Path)],
    outputs: &[(&str, Option<&Path>)],
) -> Result<(), UsageError> {
    let (folders, files): (Vec<_>, Vec<_>) =
        outputs.iter().partition(|(flag, path)| path.is_some() && known_folder(flag).is_some());
    let folders: Vec<OutputFolder<'_>> = folders
        .iter()
        .map(|&&(flag, path)| (flag, path, known_folder(flag).expect("a folder flag")))
        .collect();
    distinct_outputs_and_folders(inputs, &files.into_iter().copied().collect::<Vec<_>>(), &folders)
}

/// Whether the file `file` (a [`file_identity`]) is in `folder` or below, under a name that
/// `writes`: the command may write it there.
fn inside(file: &Path, folder: &Path, writes: fn(&str) -> bool) -> bool {
    let folder = file_identity(folder);
    *file == folder
        || file.starts_with(&folder) && file.file_name().is_some_and(|name| writes(&name.to_string_lossy()))
}

/// [`distinct_outputs`] with the output folders given apart.
pub(super) fn distinct_outputs_and_folders(
    inputs: &[(&str, &Path)],
    outputs: &[(&str, Option<&Path>)],
    folders: &[OutputFolder<'_>],
) -> Result<(), UsageError> {
    type Given<'a> = (&'a str, &'a Path, fn(&str) -> bool);
    let folders: Vec<Given<'_>> =
        folders.iter().filter_map(|&(flag, path, writes)| Some((flag, path?, writes))).collect();
    let mut outputs: Vec<(&str, &Path)> =
        outputs.iter().filter_map(|&(flag, path)| Some((flag, path?))).collect();
    for (i, (flag, path)) in outputs.iter().enumerate() {
        let file = file_identity(path);
        if let Some((folder_flag, folder, _)) =
            folders.iter().find(|(_, f, writes)| inside(&file, f, *writes))
        {
            return Err(UsageError(format!(
                "{flag} {}: inside the folder of {folder_flag} {}, under a name this command writes there; give \
                 a path outside it",
                path.display(),
                folder.display()
            )));
        }
        if written_in_place(path) {
            continue;
        }
        if let Some((other, _)) = outputs[..i].iter().find(|(_, p)| file_identity(p) == file) {
            return Err(UsageError(format!(
                "{other} and {flag} both name {}: give each output its own path",
                path.display()
            )));
        }
    }
    outputs.extend(folders.iter().map(|&(flag, path, _)| (flag, path)));
    for (flag, path) in &outputs {
        let file = file_identity(path);
        if let Some((input, _)) = inputs.iter().find(|(_, p)| file_identity(p) == file) {
            return Err(UsageError(format!(
                "{flag} {}: that is the input file of {input}, which writing would overwrite; give another path",
                path.display()
            )));
        }
    }
    for &(flag, folder, writes) in &folders {
        if let Some((input, path)) = inputs.iter().find(|(_, p)| inside(&file_identity(p), folder, writes)) {
            return Err(UsageError(format!(
                "{input} {}: inside the folder of {flag} {}, under a name this command writes there, which \
                 writing would overwrite; move it or give another folder",
                path.display(),
                folder.display()
            )));
        }
    }
    Ok(())
}

impl UnitArgs {
    /// The units, if given: `--joint-unit` and `--length-unit` go together.
    pub(super) fn units(&self) -> Result<Option<Units>, UsageError> {
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

impl ReportArgs {
    /// The report's outputs, by flag, for [`distinct_outputs`].
    fn outputs(&self) -> Vec<(&'static str, Option<&Path>)> {
        vec![
            ("--json", self.json.as_deref()),
            ("--poses-csv", self.poses_csv.as_deref()),
            ("--figures", self.figures.as_deref()),
            ("--html", self.html.as_deref()),
        ]
    }
}

impl LinkArgs {
    /// The model named `name` with these links, which only a URDF file takes.
    pub fn model_ref(&self, name: &str) -> Result<ModelRef, UsageError> {
        let model = ModelRef {
            name: name.into(),
            base_link: self.base_link.clone(),
            tip_link: self.tip_link.clone(),
            payload: None,
        };
        require(
            model.is_urdf() || (model.base_link.is_none() && model.tip_link.is_none()),
            "--base-link and --tip-link choose a chain of a URDF file (`.urdf`)",
        )?;
        Ok(model)
    }
}

impl ModelArgs {
    /// The model, with links only for a URDF file, and the payload.
    pub fn model_ref(&self) -> Result<ModelRef, UsageError> {
        Ok(ModelRef { payload: self.payload.payload()?, ..self.links.model_ref(&self.model)? })
    }
}

impl PayloadArgs {
    /// The payload, if a mass is given: at least 0 kg, its centre of mass three finite numbers
    /// (mm), the tip frame's origin by default.
    pub fn payload(&self) -> Result<Option<Payload>, UsageError> {
        let Some(mass) = self.payload_kg else { return Ok(None) };
        check_range(mass, 0.0, MAX_MASS_KG, "kg").map_err(|e| UsageError(format!("--payload-kg: {e}")))?;
        let com = match self.payload_com_mm.as_deref() {
            None => [0.0; 3],
            Some(&[x, y, z]) => [x, y, z],
            Some(_) => {
                return Err(UsageError("--payload-com-mm takes three finite numbers: X,Y,Z in mm".into()));
            }
        };
        for v in com {
            check_magnitude(v, MAX_LENGTH_MM, "mm")
                .map_err(|e| UsageError(format!("--payload-com-mm: {e}")))?;
        }
        Ok(Some(Payload { mass, com: com.into() }))
    }
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
    /// The library's estimator: feasible GLS starts from OLS (and sets its own).
    pub fn estimator(self) -> Estimator {
        match self {
            Self::Given(estimator) => estimator,
            Self::Feasible => Estimator::Ols,
        }
    }
}

/// A validated `robocal calibrate` of observation files (or the `calibrate-observations` alias).
#[derive(Debug, Clone, PartialEq)]
pub struct CalibrateObservationsRequest {
    /// The nominal robot.
    pub model: ModelRef,
    /// The observation files, fitted together.
    pub data: Vec<PathBuf>,
    /// The files' units, if given.
    pub units: Option<Units>,
    /// The estimator (wls by default: the files' sigma columns are the noise), or feasible GLS.
    pub method: Method,
    /// Whether `--estimator` was given: the default wls is ols where the data and the flags
    /// give no noise at all, and a weighted estimator given then is refused
    /// ([`crate::cli::observations`]).
    pub estimator_given: bool,
    /// Joint sigmas (deg; mm for prismatic joints), if given.
    pub joint_sigma_deg: Option<Vec<f64>>,
    /// The joint parameters to identify.
    pub joints: JointParams,
    /// The tool point (mm, tool frame), or the model's.
    pub tool: Option<Vector3<f64>>,
    /// Estimate the tool point.
    pub estimate_tool: bool,
    /// Nominal marker positions (mm, tool frame): the k-th is marker k.
    pub markers: Vec<Vector3<f64>>,
    /// The markers to fit (numbers), or every marker of the files.
    pub marker_ids: Option<Vec<usize>>,
    /// Estimate the base where the data see it (not `--fixed-base`).
    pub estimate_base: bool,
    /// Estimate the markers (not `--fixed-markers`).
    pub estimate_markers: bool,
    /// The sigmas of rows that give none (`--sigma-mm`, `--sigma-orientation-deg`).
    pub sigmas: robocal::calibration::kinds::RowSigmaDefaults,
    /// A noise file: the joint noise, the sigmas of rows that give none, a prior.
    pub noise: Option<PathBuf>,
    /// Gauss-Newton steps at most (>= 1).
    pub iterations: usize,
    /// Held-out files.
    pub validate: Vec<PathBuf>,
    /// Set-up parameters with one value per data file (names or patterns).
    pub per_session: Vec<String>,
    /// k-fold cross-validation, if asked for.
    pub folds: Option<usize>,
    /// How the joint parameters are chosen from the data (`--select`), if they are.
    pub select: Option<Criterion>,
    /// Held and kept parameters.
    pub gauge: robocal::calibration::Gauge,
    /// Prior standard deviations.
    pub prior: Vec<robocal::estimation::PriorEntry>,
    /// `--prior auto[:PRESET]`: the preset whose scale is chosen from the data.
    pub auto_prior: Option<robocal::calibration::prior_scale::AutoPrior>,
    /// The loss of each observation.
    pub loss: robocal::calibration::Loss,
    /// Where the JSON report, the CSV of every residual, the figures and the HTML page go.
    pub report: ReportArgs,
    /// Where the calibrated model TOML goes.
    pub out_model: Option<PathBuf>,
    /// Where the calibrated URDF goes (URDF input only).
    pub out_urdf: Option<PathBuf>,
}

/// The criterion of `--select`, cv's folds `--folds` (or [`DEFAULT_FOLDS`]); refused with
/// `--params none`, which leaves nothing to choose among.
fn selection(
    select: Option<SelectName>,
    folds: Option<usize>,
    joints: &JointParams,
) -> Result<Option<Criterion>, UsageError> {
    let select = select.map(|name| match name {
        SelectName::Cv => Criterion::Cv { folds: folds.unwrap_or(DEFAULT_FOLDS) },
        SelectName::Bic => Criterion::Bic,
        SelectName::T => Criterion::T,
    });
    require(
        select.is_none() || *joints != JointParams::None,
        "--select chooses among the joint parameters --params names: not with --params none",
    )?;
    Ok(select)
}

/// The session name of a data file: its stem.
pub fn session_name(path: &Path) -> String {
    path.file_stem().map_or_else(|| path.display().to_string(), |s| s.to_string_lossy().into_owned())
}

impl CalibrateObservationsRequest {
    /// The request, or the first rule between `args`' flags that it breaks.
    pub fn from_args(args: CalibrateObservationsArgs) -> Result<Self, UsageError> {
        let model = args.model.model_ref()?;
        // The files' sigma columns are the noise: wls by default. Feasible GLS estimates it.
        let method = match args.estimator {
            None | Some(EstimatorName::Wls) => Method::Given(Estimator::Wls),
            Some(EstimatorName::Ols) => Method::Given(Estimator::Ols),
            Some(EstimatorName::WlsDiag) => Method::Given(Estimator::WlsDiag),
            Some(EstimatorName::WlsSigma) => Method::Given(Estimator::WlsSigma),
            fgls @ Some(EstimatorName::Fgls) => {
                method(fgls, args.joint_sigma_deg.is_some() || args.noise.is_some(), args.folds.is_some())?
            }
        };
        let sigmas = observation_sigmas(&args)?;
        // `all`: the joints with the base and the markers, as for a marker file (the set-up is
        // always estimated).
        let joints = joint_params(args.params, args.fixed_base || args.fixed_markers)?;
        let select = selection(args.select, args.folds, &joints)?;
        if method == Method::Feasible {
            feasible_alone(select.is_some(), &args.choice)?;
        }
        let mut inputs = vec![("--model", Path::new(&model.name))];
        inputs.extend(args.data.iter().map(|p| ("--data", p.as_path())));
        inputs.extend(args.validate.iter().map(|p| ("--validate", p.as_path())));
        inputs.extend(args.noise.iter().map(|p| ("--noise", p.as_path())));
        require(args.out_urdf.is_none() || model.is_urdf(), "--out-urdf needs a URDF model")?;
        distinct_outputs(
            &inputs,
            &[
                args.report.outputs().as_slice(),
                &[("--out-model", args.out_model.as_deref()), ("--out-urdf", args.out_urdf.as_deref())],
            ]
            .concat(),
        )?;
        sessions(&args.data, &args.per_session)?;
        if let Some(name) = args.choice.hold.iter().find(|h| args.choice.keep.contains(h)) {
            return Err(UsageError(format!("`{name}` is given to both --hold and --keep: choose one")));
        }
        let (prior, auto_prior) = priors(args.choice.prior)?;
        Ok(Self {
            model,
            marker_ids: args.markers,
            noise: args.noise,
            estimate_base: !args.fixed_base,
            estimate_markers: !args.fixed_markers,
            sigmas,
            per_session: args.per_session,
            folds: args.folds,
            select,
            gauge: robocal::calibration::Gauge { hold: args.choice.hold, keep: args.choice.keep },
            prior,
            auto_prior,
            loss: args.choice.loss,
            data: args.data,
            units: args.units.units()?,
            method,
            estimator_given: args.estimator.is_some(),
            joint_sigma_deg: args.joint_sigma_deg,
            joints,
            tool: args.tool,
            estimate_tool: !args.fixed_tool,
            markers: args.marker,
            iterations: args.iterations,
            validate: args.validate,
            report: args.report,
            out_model: args.out_model,
            out_urdf: args.out_urdf,
        })
    }
}

/// The sigmas of observation rows without their own (`--sigma-mm`, `--sigma-orientation-deg`;
/// zero is none, as calibrate's default `--sigma-mm 0`), refused with `--noise`, which gives them.
fn observation_sigmas(
    args: &CalibrateObservationsArgs,
) -> Result<robocal::calibration::kinds::RowSigmaDefaults, UsageError> {
    let (mm, deg) = (args.sigma_mm.filter(|&s| s > 0.0), args.sigma_orientation_deg.filter(|&s| s > 0.0));
    require(
        args.noise.is_none() || (args.joint_sigma_deg.is_none() && mm.is_none() && deg.is_none()),
        "--noise gives the joint noise and the measurement sigmas: do not give --joint-sigma-deg, --sigma-mm or \
         --sigma-orientation-deg with it",
    )?;
    Ok(robocal::calibration::kinds::RowSigmaDefaults::positive(mm, deg.map(f64::to_radians)))
}

/// `--per-session` over the `data` files: two files at least, each of its own stem (its
/// session's name).
fn sessions(data: &[PathBuf], per_session: &[String]) -> Result<(), UsageError> {
    if per_session.is_empty() {
        return Ok(());
    }
    require(
        data.len() >= 2,
        "--per-session: one value per --data file (each file a session): give two --data files or more",
    )?;
    for (k, a) in data.iter().enumerate() {
        if let Some(b) = data[..k].iter().find(|b| session_name(b) == session_name(a)) {
            return Err(UsageError(format!(
                "--per-session: --data {} and {} have one stem, `{}`: each file's stem names its session",
                b.display(),
                a.display(),
                session_name(a)
            )));
        }
    }
    Ok(())
}

/// A validated `robocal evaluate`.
#[derive(Debug, Clone, PartialEq)]
pub struct EvaluateRequest {
    /// The model: a file or preset, or a URDF chain.
    pub model: ModelRef,
    /// The files to score.
    pub data: Vec<PathBuf>,
    /// The files' units, if given.
    pub units: Option<Units>,
    /// The noise for the whitened residuals, if given.
    pub noise: Option<NoiseSource>,
    /// The markers to score, or every marker of each file.
    pub marker_ids: Option<Vec<usize>>,
    /// Where the JSON, CSV, figures and HTML go.
    pub report: ReportArgs,
    /// A URDF tree's branches (`--tips`), to score views between them.
    pub tips: Vec<String>,
    /// A tree's branches as `calibrate --out-dir` wrote them, if given.
    pub branches: Option<PathBuf>,
    /// `--base-link` as given: for a tree, the link its branches start from (default: its
    /// root link).
    pub tree_root: Option<String>,
}

impl EvaluateRequest {
    /// The request, or the first rule between `args`' flags that it breaks.
    pub fn from_args(args: EvaluateArgs) -> Result<Self, UsageError> {
        // A calibrated URDF: the chain from its measuring frame to its tool, by default.
        let tree = !args.tips.is_empty() || args.branches.is_some();
        let links = ModelRef {
            name: args.model,
            base_link: Some(args.base_link.clone().unwrap_or_else(|| "measuring_frame".into())),
            tip_link: Some(args.tip_link),
            payload: args.payload.payload()?,
        };
        let model =
            if links.is_urdf() { links } else { ModelRef { base_link: None, tip_link: None, ..links } };
        require(
            !tree || model.is_urdf(),
            "--tips and --branches: a tree's branches are read from its URDF file; give it to --model",
        )?;
        let noise = noise_source(args.noise, &args.noise_flags)?;
        let mut inputs = vec![("--model", Path::new(&model.name))];
        inputs.extend(args.data.iter().map(|p| ("--data", p.as_path())));
        if let Some(NoiseSource::File(path)) = &noise {
            inputs.push(("--noise", path));
        }
        distinct_outputs(&inputs, &args.report.outputs())?;
        Ok(Self {
            model,
            data: args.data,
            units: args.units.units()?,
            noise,
            marker_ids: args.markers,
            report: args.report,
            tips: args.tips,
            branches: args.branches,
            tree_root: args.base_link,
        })
    }
}

/// `--noise` or `--joint-sigma-deg` (with `--sigma-mm`, `--sigma-orientation-deg`), not both.
fn noise_source(file: Option<PathBuf>, args: &NoiseArgs) -> Result<Option<NoiseSource>, UsageError> {
    let measurement = args.sigma_mm != 0.0 || args.sigma_orientation_deg != 0.0;
    match (file, args.flags()) {
        (Some(_), Some(_)) => Err(UsageError("--noise and --joint-sigma-deg: give one of the two".into())),
        (Some(_), None) if measurement => Err(UsageError(
            "--noise gives the measurement noise too: do not give --sigma-mm or --sigma-orientation-deg with it".into(),
        )),
        (Some(path), None) => Ok(Some(NoiseSource::File(path))),
        (None, None) if measurement => Err(UsageError(
            "--sigma-mm needs --joint-sigma-deg too (zeros if the joints are exact); so does --sigma-orientation-deg"
                .into(),
        )),
        (None, flags) => Ok(flags.map(NoiseSource::Flags)),
    }
}

/// What `--estimator fgls` refuses besides a noise and `--folds` ([`method`]), of marker and
/// observation files alike: `--select` (`selected`), a prior or a robust loss. Feasible GLS
/// estimates the noise from the residuals of plain least squares: a prior shrinks them, a
/// robust loss sets poses aside, and the variance components would be those of another fit.
fn feasible_alone(selected: bool, choice: &crate::cli::args::ModelChoiceArgs) -> Result<(), UsageError> {
    require(
        !selected,
        "--select with --estimator fgls: not supported; estimate the noise once and give --noise",
    )?;
    require(
        choice.prior.is_empty(),
        "--prior with --estimator fgls: not supported; estimate the noise first (fgls reports it) and give it with --noise or the sigma flags",
    )?;
    require(
        choice.loss == robocal::calibration::Loss::Squared,
        "--loss with --estimator fgls: not supported; estimate the noise first (fgls reports it) and give it with --noise or the sigma flags",
    )
}

/// The `--prior` entries in order, and the preset of `--prior auto` (at most one).
fn priors(
    args: Vec<PriorArg>,
) -> Result<
    (Vec<robocal::estimation::PriorEntry>, Option<robocal::calibration::prior_scale::AutoPrior>),
    UsageError,
> {
    let (mut entries, mut auto) = (Vec::new(), None);
    for arg in args {
        match arg {
            PriorArg::Entries(e) => entries.extend(e),
            PriorArg::Auto(a) if auto.is_none() => auto = Some(a),
            PriorArg::Auto(_) => return Err(UsageError("--prior auto: give it once".into())),
        }
    }
    Ok((entries, auto))
}

/// `--estimator` (default: wls with the noise, ols without): a weighted estimator needs the
/// noise; fgls estimates it, so takes none, and does not cross-validate.
fn method(name: Option<EstimatorName>, noise: bool, folds: bool) -> Result<Method, UsageError> {
    let estimator = match name {
        Some(EstimatorName::Fgls) => {
            require(
                !noise,
                "--estimator fgls estimates the noise: do not give --noise or --joint-sigma-deg",
            )?;
            require(
                !folds,
                "--folds with --estimator fgls: not supported; estimate the noise once and give --noise",
            )?;
            return Ok(Method::Feasible);
        }
        Some(EstimatorName::Ols) => Estimator::Ols,
        Some(EstimatorName::Wls) => Estimator::Wls,
        Some(EstimatorName::WlsDiag) => Estimator::WlsDiag,
        Some(EstimatorName::WlsSigma) => Estimator::WlsSigma,
        None if noise => Estimator::Wls,
        None => Estimator::Ols,
    };
    if estimator != Estimator::Ols && !noise {
        return Err(UsageError(format!(
            "--estimator {estimator} needs the noise: give --noise or --joint-sigma-deg (and --sigma-mm or a sigma \
             column), or use --estimator fgls"
        )));
    }
    Ok(Method::Given(estimator))
}

/// `--params` in calibrate: `joints` and `all` identify every joint parameter, and `all` frees
/// the base and the markers too, so it refuses `--fixed-base` and `--fixed-markers`.
fn joint_params(params: ParamWords, fixed_base_or_markers: bool) -> Result<JointParams, UsageError> {
    require(
        params != ParamWords::All || !fixed_base_or_markers,
        "--params all frees the base and the markers: with --fixed-base or --fixed-markers, give --params joints",
    )?;
    Ok(params.joint_params())
}

/// The parameters, measurements and noise of a validated `plan` or `observability`.
#[derive(Debug, Clone, PartialEq)]
pub struct DesignRequest {
    /// The nominal robot.
    pub model: ModelRef,
    /// The parameters to identify (not [`ParamWords::None`]).
    pub params: ParamWords,
    /// What is measured at each pose.
    pub measured: Measured,
    /// The noise, if given.
    pub noise: Option<NoiseFlags>,
}

impl DesignRequest {
    /// The request, or the first rule between `args`' flags that it breaks.
    fn from_args(args: DesignArgs) -> Result<Self, UsageError> {
        require(
            args.params != ParamWords::None,
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
        Ok(Self { model: args.model.model_ref()?, params: args.params, measured, noise })
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
    pub criterion: DesignCriterion,
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
        for (flag, count, bound) in
            [("--points", args.points, MAX_POINTS), ("--candidates", args.candidates, MAX_CANDIDATES)]
        {
            require(count <= bound, &format!("{flag} {count}: at most {bound}"))?;
        }
        distinct_outputs(
            &[("--model", Path::new(&args.design.model.model))],
            &[("--out", args.out.as_deref())],
        )?;
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
    /// The nominal robot.
    pub model: ModelRef,
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
        let inputs = [("--model", Path::new(&args.model.model)), ("--data", args.data.as_path())];
        distinct_outputs(&inputs, &[("--out", args.out.as_deref()), ("--json", args.json.as_deref())])?;
        Ok(Self {
            model: args.model.model_ref()?,
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

/// `--estimator` of a command that takes ols or wls (the default); `why` says so.
fn ols_or_wls(estimator: Option<EstimatorName>, why: &str) -> Result<Estimator, UsageError> {
    match estimator {
        None | Some(EstimatorName::Wls) => Ok(Estimator::Wls),
        Some(EstimatorName::Ols) => Ok(Estimator::Ols),
        Some(other) => {
            let name = clap::ValueEnum::to_possible_value(&other).map(|v| v.get_name().to_string());
            Err(UsageError(format!("--estimator {}: {why}", name.unwrap_or_default())))
        }
    }
}

/// A validated `robocal calibrate` of a tree's views (or the `calibrate-tree` alias).
#[derive(Debug, Clone, PartialEq)]
pub struct CalibrateTreeRequest {
    /// The URDF file.
    pub model: PathBuf,
    /// The root link, if given.
    pub base_link: Option<String>,
    /// The tip links, if given.
    pub tips: Vec<String>,
    /// The view files, fitted together.
    pub data: Vec<PathBuf>,
    /// The files' units, if given.
    pub units: Option<Units>,
    /// The estimator: ols or wls (ols to start feasible GLS with).
    pub estimator: Estimator,
    /// Feasible GLS (`--estimator fgls`): the noise estimated from the residuals.
    pub feasible: bool,
    /// Joint sigmas (deg; mm for prismatic joints), one per tree joint or one for all.
    pub joint_sigma_deg: Option<Vec<f64>>,
    /// The joint parameters to identify.
    pub joints: JointParams,
    /// Gauss-Newton steps at most (>= 1).
    pub iterations: usize,
    /// Held and kept parameters.
    pub gauge: robocal::calibration::Gauge,
    /// Prior standard deviations.
    pub prior: Vec<robocal::estimation::PriorEntry>,
    /// `--prior auto[:PRESET]`: the preset whose scale is chosen from the views.
    pub auto_prior: Option<robocal::calibration::prior_scale::AutoPrior>,
    /// How the joint parameters are chosen from the views (`--select t`), if they are.
    pub select: Option<Criterion>,
    /// The loss of each view.
    pub loss: robocal::calibration::Loss,
    /// Held-out files.
    pub validate: Vec<PathBuf>,
    /// Placement parameters with one value per --data file.
    pub per_session: Vec<String>,
    /// `--folds k`: the k-fold cross-validation of the training poses.
    pub folds: Option<usize>,
    /// Where the JSON report, the CSV of every residual, the figures and the HTML page go.
    pub report: ReportArgs,
    /// Where the calibrated branches go.
    pub out_dir: Option<PathBuf>,
    /// Where the calibrated tree goes, as URDF.
    pub out_urdf: Option<PathBuf>,
}

impl CalibrateTreeRequest {
    /// The request, or the first rule between `args`' flags that it breaks.
    pub fn from_args(args: CalibrateTreeArgs) -> Result<Self, UsageError> {
        let feasible = args.estimator == Some(EstimatorName::Fgls);
        let estimator = match feasible {
            true => method(args.estimator, args.joint_sigma_deg.is_some(), args.folds.is_some())?.estimator(),
            false => ols_or_wls(args.estimator, "a tree takes ols, wls or fgls")?,
        };
        require(
            args.params != ParamWords::All,
            "--params all: the base is never estimated from views; give --params joints",
        )?;
        require(
            args.model.extension().is_some_and(|e| e.eq_ignore_ascii_case("urdf")),
            "--model: a URDF file (.urdf) whose links form a tree",
        )?;
        let joints = joint_params(args.params, false)?;
        if let Some(name) = args.choice.hold.iter().find(|h| args.choice.keep.contains(h)) {
            return Err(UsageError(format!("`{name}` is given to both --hold and --keep: choose one")));
        }
        let select = selection(args.select, args.folds, &joints)?;
        if feasible {
            feasible_alone(select.is_some(), &args.choice)?;
        }
        let (prior, auto_prior) = priors(args.choice.prior)?;
        sessions(&args.data, &args.per_session)?;
        let mut inputs = vec![("--model", args.model.as_path())];
        inputs.extend(args.data.iter().map(|p| ("--data", p.as_path())));
        inputs.extend(args.validate.iter().map(|p| ("--validate", p.as_path())));
        distinct_outputs(
            &inputs,
            &[
                args.report.outputs().as_slice(),
                &[("--out-dir", args.out_dir.as_deref()), ("--out-urdf", args.out_urdf.as_deref())],
            ]
            .concat(),
        )?;
        Ok(Self {
            model: args.model,
            base_link: args.base_link,
            tips: args.tips,
            data: args.data,
            units: args.units.units()?,
            estimator,
            feasible,
            joint_sigma_deg: args.joint_sigma_deg,
            joints,
            iterations: args.iterations,
            gauge: robocal::calibration::Gauge { hold: args.choice.hold, keep: args.choice.keep },
            prior,
            auto_prior,
            select,
            loss: args.choice.loss,
            validate: args.validate,
            per_session: args.per_session,
            folds: args.folds,
            report: args.report,
            out_dir: args.out_dir,
            out_urdf: args.out_urdf,
        })
    }
}
