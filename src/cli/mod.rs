//! The command line: parse the flags into one validated request, call the library, print.

use anyhow::{Context, Result, bail};
use clap::{Parser, Subcommand};
use indicatif::{ProgressBar, ProgressStyle};
use robocal::calibration::{self, FeasibleOptions, JointParams, Options, RepeatabilityOptions, Units};
use robocal::design::{Constraints, Criterion, Design, ExcludedRange};
use robocal::estimation::{Estimator, JointComponents, MeasurementNoise, NoiseModel, RefineOptions};
use robocal::kinematics::{Chain, Measured};
use robocal::model::{JointKind, PRESETS, RobotModel, Selection};
use robocal::report::calibration::CalibrationReport;
use robocal::simulation::{self, Study};
use robocal::{io, report};
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Kinematic calibration of robot arms by ordinary and weighted least squares.
///
/// Exit codes: 0 success, 1 an error in the input or the computation (the message says which
/// file, line or field), 2 a usage error on the command line.
#[derive(Parser, Debug)]
#[command(name = "robocal", version, about, long_about)]
pub struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand, Debug)]
enum Command {
    /// Run the paper's two studies on the embedded PUMA 560: Tables 1-2, Figures 1-4.
    Reproduce {
        /// Folder for the tables, the CSV samples and the SVG figures.
        #[arg(long, default_value = "robocal-out")]
        out: PathBuf,
        /// Worker threads (default: all cores). The numbers do not depend on it.
        #[arg(long)]
        threads: Option<usize>,
        /// Also repeat the whole study R times with master seeds derived from its seed (in
        /// parallel), and report each statistic of its tables over the replications, with the
        /// paper's value and its percentile (1 to 10000; 100 take about a minute).
        #[arg(long, value_name = "R", value_parser = parse_replications)]
        replications: Option<usize>,
    },
    /// Run a study: a TOML file, or an embedded one (paper-table1, paper-table2).
    Simulate {
        /// The study file or name.
        study: String,
        /// Folder for the tables, the CSV samples and the SVG figures.
        #[arg(long, default_value = "robocal-out")]
        out: PathBuf,
        /// Worker threads (default: all cores). The numbers do not depend on it.
        #[arg(long)]
        threads: Option<usize>,
        /// A noise file (TOML, see docs/formats.md) replacing the study's noise: joint sigmas,
        /// device, and sigma_me if it gives one.
        #[arg(long)]
        noise: Option<PathBuf>,
        /// Also repeat the whole study R times with master seeds derived from its seed (in
        /// parallel), and report each statistic of its tables over the replications, with the
        /// paper's value and its percentile (1 to 10000; 100 take about a minute).
        #[arg(long, value_name = "R", value_parser = parse_replications)]
        replications: Option<usize>,
    },
    /// Estimate the joint noise and sigma_me from repeated measurements at a set of poses,
    /// and write them as a noise file.
    Repeatability(Box<RepeatabilityArgs>),
    /// Forward kinematics: the tool pose of a model at given joint values.
    Fk {
        /// A preset name (see `robocal model list`) or a model TOML file.
        #[arg(long)]
        model: String,
        /// Joint values, comma-separated: degrees for revolute joints, mm for prismatic ones.
        #[arg(long, allow_hyphen_values = true)]
        q: String,
    },
    /// Calibrate a robot from measured marker positions.
    Calibrate(Box<CalibrateArgs>),
    /// Observability indices O1-O5 of a pose file (or a measurement file's joint columns).
    Observability(Box<ObservabilityArgs>),
    /// Plan measurement poses that maximise an observability criterion; writes a pose file.
    Plan(Box<PlanArgs>),
    /// Inspect robot models.
    Model {
        #[command(subcommand)]
        command: ModelCommand,
    },
}

#[derive(Subcommand, Debug)]
enum ModelCommand {
    /// Print a model (preset name or file) as TOML, in mm and degrees.
    Show {
        /// A preset name or a model TOML file.
        model: String,
    },
    /// List the embedded presets.
    List,
}

/// The flags of `robocal repeatability`.
#[derive(clap::Args, Debug)]
struct RepeatabilityArgs {
    /// The nominal robot: a preset name or a model TOML file.
    #[arg(long)]
    model: String,
    /// The repeatability file (CSV: a measurement file with a `pose` column; docs/formats.md).
    #[arg(long)]
    data: PathBuf,
    /// Unit of revolute joint values in the file, if it does not declare it.
    #[arg(long, value_parser = ["deg", "rad"])]
    joint_unit: Option<String>,
    /// Unit of lengths in the file, if it does not declare it.
    #[arg(long, value_parser = ["mm", "m"])]
    length_unit: Option<String>,
    /// Estimate the full joint covariance Sigma_q, not only one sigma per joint.
    #[arg(long)]
    full_covariance: bool,
    /// Nominal position of a marker on the last link, "x,y,z" in mm; repeat per marker
    /// (default: marker 1 at the model's tool point).
    #[arg(long, allow_hyphen_values = true)]
    marker: Vec<String>,
    /// The device measures in the model's base frame: do not register the frames.
    #[arg(long)]
    fixed_base: bool,
    /// Write the estimated noise here (a noise file for `calibrate --noise` and
    /// `simulate --noise`).
    #[arg(long)]
    out: Option<PathBuf>,
    /// Write the estimates with their intervals as JSON here.
    #[arg(long)]
    json: Option<PathBuf>,
}

/// The flags of `robocal calibrate`.
#[derive(clap::Args, Debug)]
struct CalibrateArgs {
    /// The nominal robot: a preset name, a model TOML file, or a URDF file (`.urdf`, with
    /// --base-link and --tip-link).
    #[arg(long)]
    model: String,
    /// URDF: the link the chain starts from.
    #[arg(long)]
    base_link: Option<String>,
    /// URDF: the link the chain ends at.
    #[arg(long)]
    tip_link: Option<String>,
    /// The measurement file (CSV; see docs/formats.md).
    #[arg(long)]
    data: PathBuf,
    /// Unit of revolute joint values in the files, if they do not declare it.
    #[arg(long, value_parser = ["deg", "rad"])]
    joint_unit: Option<String>,
    /// Unit of lengths in the files, if they do not declare it.
    #[arg(long, value_parser = ["mm", "m"])]
    length_unit: Option<String>,
    /// Estimator: `ols`; `wls` (Gauss-Markov, needs the noise: --noise or --joint-sigma-deg);
    /// `wls-diag`, `wls-sigma`; or `fgls` (feasible GLS: the joint sigmas and sigma_me
    /// estimated from the residuals, iterated, and reported). Default: wls when the noise is
    /// given, ols otherwise.
    #[arg(long)]
    estimator: Option<String>,
    /// A noise file (TOML, see docs/formats.md): joint noise, sigma_me and the measuring
    /// device. Replaces --joint-sigma-deg, --sigma-mm and --sigma-orientation-deg.
    #[arg(long)]
    noise: Option<PathBuf>,
    /// Joint noise standard deviations, one per joint (deg; mm for prismatic joints).
    #[arg(long, value_delimiter = ',', allow_hyphen_values = true)]
    joint_sigma_deg: Option<Vec<f64>>,
    /// Measurement noise standard deviation (mm), unless the data has a `sigma` column.
    #[arg(long, default_value_t = 0.0)]
    sigma_mm: f64,
    /// Orientation measurement noise (deg), when the data has orientation columns.
    #[arg(long, default_value_t = 0.0)]
    sigma_orientation_deg: f64,
    /// Joint parameters to identify: `all`, `offsets`, `none`, or names and patterns
    /// (`j*.theta,j2.a`).
    #[arg(long, default_value = "all", value_delimiter = ',')]
    params: Vec<String>,
    /// Do not estimate the base: the measuring frame is the model's base frame.
    #[arg(long)]
    fixed_base: bool,
    /// Do not estimate the marker positions.
    #[arg(long)]
    fixed_markers: bool,
    /// Nominal position of a marker on the last link, "x,y,z" in mm; repeat per marker.
    #[arg(long, allow_hyphen_values = true)]
    marker: Vec<String>,
    /// Gauss-Newton steps at most; 1 is the paper's one-step estimate.
    #[arg(long, default_value_t = 50)]
    iterations: usize,
    /// A measurement file of held-out poses to validate on; repeatable.
    #[arg(long)]
    validate: Vec<PathBuf>,
    /// k-fold cross-validation on the data (k >= 2).
    #[arg(long)]
    folds: Option<usize>,
    /// Write the report as JSON here.
    #[arg(long)]
    json: Option<PathBuf>,
    /// Write the calibrated model (TOML) here.
    #[arg(long)]
    out_model: Option<PathBuf>,
    /// Write the calibrated model as URDF here (URDF input only): the original file with the
    /// calibrated joint origins, a `measuring_frame` link and a `tool` link (marker 1).
    #[arg(long)]
    out_urdf: Option<PathBuf>,
}

/// The robot, parameters, measurements and noise of `observability` and `plan`.
#[derive(clap::Args, Debug)]
struct DesignArgs {
    /// The nominal robot: a preset name or a model TOML file.
    #[arg(long)]
    model: String,
    /// Parameters to identify: `joints` (the paper's set), `all`, `offsets`, or names and
    /// patterns (`j*.theta,j2.a`).
    #[arg(long, default_value = "joints", value_delimiter = ',')]
    params: Vec<String>,
    /// What is measured at each pose.
    #[arg(long, default_value = "position", value_parser = ["position", "pose"])]
    measured: String,
    /// Joint noise standard deviations, one per joint (deg; mm for prismatic joints): gives
    /// the whitened indices, which the planner then maximises.
    #[arg(long, value_delimiter = ',', allow_hyphen_values = true)]
    joint_sigma_deg: Option<Vec<f64>>,
    /// Measurement noise standard deviation (mm).
    #[arg(long, default_value_t = 0.0)]
    sigma_mm: f64,
    /// Orientation measurement noise (deg), for pose measurements.
    #[arg(long, default_value_t = 0.0)]
    sigma_orientation_deg: f64,
}

/// The flags of `robocal observability`.
#[derive(clap::Args, Debug)]
struct ObservabilityArgs {
    /// The pose file (CSV with the model's joint columns and a `# units:` line).
    poses: PathBuf,
    #[command(flatten)]
    design: DesignArgs,
    /// Unit of revolute joint values in the file, if it does not declare it.
    #[arg(long, value_parser = ["deg", "rad"])]
    joint_unit: Option<String>,
}

/// The flags of `robocal plan`.
#[derive(clap::Args, Debug)]
struct PlanArgs {
    #[command(flatten)]
    design: DesignArgs,
    /// Number of poses to plan.
    #[arg(long)]
    points: usize,
    /// Candidate poses drawn uniformly within the joint limits (and the constraints).
    #[arg(long, default_value_t = 5000)]
    candidates: usize,
    /// What to maximise: `d` (D-optimal), `o1` ... `o5`.
    #[arg(long, default_value = "d")]
    criterion: Criterion,
    /// Seed of the candidate pool: the same seed gives the same poses.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// A box the tool point must stay in: "xmin,ymin,zmin,xmax,ymax,zmax" in mm, in the
    /// robot's base (measuring) frame.
    #[arg(long, allow_hyphen_values = true)]
    tool_box: Option<String>,
    /// A joint range to avoid, "JOINT:FROM:TO" in degrees (mm for a prismatic joint);
    /// repeatable.
    #[arg(long, allow_hyphen_values = true)]
    exclude: Vec<String>,
    /// Write the poses here (CSV) and the summary to standard output; without it the poses go
    /// to standard output and the summary to standard error.
    #[arg(long)]
    out: Option<PathBuf>,
}

/// Run the command line.
pub fn run(cli: Cli) -> Result<()> {
    match cli.command {
        Command::Fk { model, q } => {
            let model = io::load_model(&model)?;
            let q = parse_joint_values(&model, &q)?;
            for (joint, &v) in model.joints.iter().zip(&q) {
                if v < joint.limits[0] || v > joint.limits[1] {
                    eprintln!("warning: joint {} lies outside its limits", joint.name);
                }
            }
            let pose = Chain::new(&model).with_errors(&vec![0.0; model.params().len()]).pose(&q);
            print!("{}", report::tool_pose(&model, &q, &pose));
        }
        Command::Calibrate(args) => calibrate(&args)?,
        Command::Observability(args) => {
            let design = design(&args.design)?;
            let units = args
                .joint_unit
                .as_deref()
                .map(|u| Units { joints_in_degrees: u == "deg", lengths_in_metres: false });
            let poses = io::load_poses(&args.poses, design.model(), units)?;
            let observability =
                design.observability(&poses).with_context(|| format!("{}", args.poses.display()))?;
            print!(
                "{}",
                report::design::observability(&design, &observability, &args.poses.display().to_string())
            );
        }
        Command::Plan(args) => plan(&args)?,
        Command::Model { command: ModelCommand::Show { model } } => {
            print!("{}", io::load_model(&model)?.to_toml_string());
        }
        Command::Model { command: ModelCommand::List } => {
            for (name, _) in PRESETS {
                let model = RobotModel::preset(name).expect("presets are valid");
                println!("{name:<12} {}", model.description);
            }
        }
        Command::Reproduce { out, threads, replications } => {
            let started = Instant::now();
            let studies = ["paper-table1", "paper-table2"]
                .map(io::load_study)
                .into_iter()
                .collect::<Result<Vec<_>, _>>()?;
            for study in &studies {
                simulate(study, &out, threads, replications)?;
            }
            println!(
                "The paper's figures: Fig. 1a-e paper-table1/histogram-wls-np{{12,24,48,96,192}}-sigma0.svg,"
            );
            println!(
                "Fig. 2 paper-table1/improvement-vs-points-wls.svg, Fig. 3 paper-table2/improvement-vs-sigma-wls.svg,"
            );
            println!(
                "Fig. 4a-c paper-table2/histogram-wls-np48-sigma{{0.025,0.05,0.1}}.svg (and the same for wls-diag)."
            );
            println!("Both studies in {:.2} s.", started.elapsed().as_secs_f64());
        }
        Command::Simulate { study, out, threads, noise, replications } => {
            let mut study = io::load_study(&study)?;
            if let Some(path) = noise {
                let spec = io::load_noise(&path, &study.robot)?;
                study.set_noise(&spec).with_context(|| format!("{}", path.display()))?;
                study.description = format!("{} (noise from {})", study.description, path.display());
            }
            simulate(&study, &out, threads, replications)?
        }
        Command::Repeatability(args) => repeatability(&args)?,
    }
    Ok(())
}

/// `--joint-unit` and `--length-unit`, which go together.
fn units(joint: Option<&str>, length: Option<&str>) -> Result<Option<Units>> {
    match (joint, length) {
        (None, None) => Ok(None),
        (Some(j), Some(l)) => Ok(Some(Units { joints_in_degrees: j == "deg", lengths_in_metres: l == "m" })),
        _ => bail!("--joint-unit and --length-unit go together"),
    }
}

/// `--marker x,y,z` values (mm).
fn parse_markers(markers: &[String]) -> Result<Vec<nalgebra::Vector3<f64>>> {
    markers
        .iter()
        .map(|m| {
            let v: Vec<f64> = m
                .split(',')
                .map(|s| s.trim().parse())
                .collect::<Result<_, _>>()
                .with_context(|| format!("--marker `{m}`: expected x,y,z in mm"))?;
            match v[..] {
                [x, y, z] if v.iter().all(|c| c.is_finite()) => Ok(nalgebra::Vector3::new(x, y, z)),
                _ => bail!("--marker `{m}`: expected three finite numbers x,y,z in mm"),
            }
        })
        .collect()
}

/// `robocal repeatability`: the noise from repeated measurements, printed and written.
fn repeatability(args: &RepeatabilityArgs) -> Result<()> {
    let model = io::load_model(&args.model)?;
    let units = units(args.joint_unit.as_deref(), args.length_unit.as_deref())?;
    let data = io::load_repeatability(&args.data, &model, units)?;
    let markers = parse_markers(&args.marker)?;
    if markers.len() > data.markers {
        bail!("{} --marker given, {} has {} markers", markers.len(), args.data.display(), data.markers);
    }
    let joints = if args.full_covariance { JointComponents::Full } else { JointComponents::Diagonal };
    let options = RepeatabilityOptions { joints, markers, register: !args.fixed_base };
    let result = calibration::repeatability(&model, &data, &options)
        .with_context(|| format!("{}: the variance components", args.data.display()))?;
    let rows = report::calibration::noise_rows(&model.joints, &result.estimate);
    println!(
        "repeatability of {} from {}: {} poses, {} measurements, rms spread {:.4} mm\n",
        model.name,
        args.data.display(),
        result.poses,
        result.measurements,
        result.rms_spread
    );
    print!("{}", report::calibration::noise_table(&rows));
    let estimate = &result.estimate;
    let bound = |s: f64, name: &str, unit: &str, used: f64| {
        (s == 0.0).then(|| {
            format!(
                "{name} is at its bound 0: the noise file gives {used:.3e} {unit} (the square root of its \
                 standard error), so that V_k stays positive definite"
            )
        })
    };
    let (me, _) = estimate.weighting_sigmas();
    let mut notes: Vec<String> = bound(estimate.sigma_me().sigma, "sigma_me", "mm", me).into_iter().collect();
    if args.full_covariance {
        notes.push(
            "the noise file holds Sigma_q made positive semi-definite (negative eigenvalues set to 0): \
             its diagonal can differ from the sigmas above"
                .into(),
        );
    }
    for note in &notes {
        println!("note: {note}");
    }
    if let Some(path) = &args.out {
        let header = format!(
            "robocal noise file, estimated by `robocal repeatability` from {} ({} poses, {} measurements).\n\
             95% intervals:\n{}{}",
            args.data.display(),
            result.poses,
            result.measurements,
            report::calibration::noise_table(&rows),
            notes.iter().map(|n| format!("note: {n}\n")).collect::<String>()
        );
        let text = result.estimate.spec().to_toml_string(&model, &header);
        std::fs::write(path, text).with_context(|| format!("{}: cannot write", path.display()))?;
        println!("\nwrote {}", path.display());
    }
    if let Some(path) = &args.json {
        let json = serde_json::to_string_pretty(&rows)?;
        std::fs::write(path, json + "\n").with_context(|| format!("{}: cannot write", path.display()))?;
    }
    Ok(())
}

/// `robocal calibrate`: everything is read and computed before anything is written.
fn calibrate(args: &CalibrateArgs) -> Result<()> {
    let (model, urdf) = if args.model.ends_with(".urdf") {
        let (Some(base), Some(tip)) = (&args.base_link, &args.tip_link) else {
            bail!("{}: a URDF model needs --base-link and --tip-link", args.model);
        };
        let (model, text) = io::load_urdf(Path::new(&args.model), base, tip)?;
        (model, Some((text, base.clone(), tip.clone())))
    } else {
        (io::load_model(&args.model)?, None)
    };
    if args.out_urdf.is_some() && urdf.is_none() {
        bail!("--out-urdf needs a URDF model");
    }
    let units = units(args.joint_unit.as_deref(), args.length_unit.as_deref())?;
    let data = io::load_measurements(&args.data, &model, units)?;
    if !data.ignored.is_empty() {
        eprintln!("note: {}: ignoring columns {}", args.data.display(), data.ignored.join(", "));
    }
    let feasible = args.estimator.as_deref() == Some("fgls");
    let chosen: Option<Estimator> = match args.estimator.as_deref() {
        None | Some("fgls") => None,
        Some(name) => Some(name.parse().map_err(|e: String| anyhow::anyhow!("--estimator: {e}, fgls"))?),
    };
    let noise = match (&args.noise, &args.joint_sigma_deg) {
        (Some(_), Some(_)) => bail!("--noise and --joint-sigma-deg: give one of the two"),
        (Some(path), None) => {
            let spec = io::load_noise(path, &model)?;
            Some(
                calibration::noise_from_spec(&spec, &data)
                    .with_context(|| format!("{}: the device's covariance", path.display()))?,
            )
        }
        (None, None) => None,
        (None, Some(sigmas)) => {
            Some(noise_from_flags(&model, sigmas, args.sigma_mm, args.sigma_orientation_deg)?)
        }
    };
    if feasible && noise.is_some() {
        bail!("--estimator fgls estimates the noise: do not give --noise or --joint-sigma-deg");
    }
    let estimator = chosen.unwrap_or(if noise.is_some() { Estimator::Wls } else { Estimator::Ols });
    if estimator != Estimator::Ols && noise.is_none() {
        bail!(
            "--estimator {estimator} needs the noise: give --noise or --joint-sigma-deg (and --sigma-mm or a \
             sigma column), or use --estimator fgls"
        );
    }
    let markers = parse_markers(&args.marker)?;
    if markers.len() > data.marker_count() {
        bail!(
            "{} --marker given, {} has {} markers",
            markers.len(),
            args.data.display(),
            data.marker_count()
        );
    }
    if args.iterations == 0 {
        bail!("--iterations: at least 1");
    }
    let joints = match args.params.iter().map(String::as_str).collect::<Vec<_>>()[..] {
        ["all"] => JointParams::All,
        ["offsets"] => JointParams::Offsets,
        ["none"] => JointParams::None,
        _ => JointParams::Named(args.params.clone()),
    };
    let options = Options {
        estimator,
        noise,
        joints,
        estimate_base: !args.fixed_base,
        estimate_markers: !args.fixed_markers,
        markers,
        refine: RefineOptions { max_iterations: args.iterations, ..RefineOptions::default() },
    };
    let mut held_out = Vec::new();
    for path in &args.validate {
        held_out.push((path.display().to_string(), io::load_measurements(path, &model, units)?));
    }
    if held_out.iter().any(|(_, d)| d.marker_count() != data.marker_count()) {
        bail!("the validation files must have the markers of {}", args.data.display());
    }
    let result = if feasible {
        calibration::calibrate_feasible(&model, &data, &options, &FeasibleOptions::default())?
    } else {
        calibration::calibrate(&model, &data, &options)?
    };
    let mut validation: Vec<_> = held_out
        .iter()
        .map(|(name, d)| {
            let (before, after) = result.validate(d);
            (name.clone(), before, after)
        })
        .collect();
    if let Some(k) = args.folds {
        if k < 2 || k > data.len() {
            bail!("--folds {k}: expected 2 to {} (the number of poses)", data.len());
        }
        if feasible {
            bail!("--folds with --estimator fgls: not supported; estimate the noise once and give --noise");
        }
        let (before, after) = calibration::cross_validate(&model, &data, &options, k)?;
        validation.push((format!("{k}-fold cross-validation"), before, after));
    }
    let name = if feasible { "fgls" } else { estimator.name() };
    let report = CalibrationReport::new(&result, &args.data.display().to_string(), name, validation);
    print!("{}", report.text());
    if let Some(path) = &args.json {
        let json = serde_json::to_string_pretty(&report)?;
        std::fs::write(path, json + "\n").with_context(|| format!("{}: cannot write", path.display()))?;
    }
    if let Some(path) = &args.out_model {
        std::fs::write(path, result.calibrated.to_toml_string())
            .with_context(|| format!("{}: cannot write", path.display()))?;
    }
    if let (Some(path), Some((text, base, tip))) = (&args.out_urdf, &urdf) {
        let written = robocal::model::to_urdf_string(text, base, tip, &result.calibrated)?;
        std::fs::write(path, written).with_context(|| format!("{}: cannot write", path.display()))?;
    }
    Ok(())
}

/// The design of `robocal observability` and `robocal plan` from their flags.
fn design(args: &DesignArgs) -> Result<Design> {
    let model = io::load_model(&args.model)?;
    let params = model.params();
    let selection = match args.params.iter().map(String::as_str).collect::<Vec<_>>()[..] {
        ["joints"] => Selection::joints(&params),
        ["all"] => Selection::all(&params),
        ["offsets"] => Selection::offsets(&params),
        _ => Selection::by_names(&params, &args.params).context("--params")?,
    };
    let measured = if args.measured == "pose" { Measured::Pose } else { Measured::Position };
    let noise = match &args.joint_sigma_deg {
        None if args.sigma_mm > 0.0 => {
            bail!("--sigma-mm needs --joint-sigma-deg too (zeros if the joints are exact)")
        }
        None => None,
        Some(sigmas) => Some(noise_from_flags(&model, sigmas, args.sigma_mm, args.sigma_orientation_deg)?),
    };
    Ok(Design::new(&model, selection, measured, noise)?)
}

/// `robocal plan`: the constraints from the flags, the plan, the pose file.
fn plan(args: &PlanArgs) -> Result<()> {
    let design = design(&args.design)?;
    let model = design.model();
    let mut constraints = Constraints::default();
    if let Some(text) = &args.tool_box {
        let v: Vec<f64> =
            text.split(',').map(|s| s.trim().parse()).collect::<Result<_, _>>().with_context(|| {
                format!("--tool-box `{text}`: expected xmin,ymin,zmin,xmax,ymax,zmax in mm")
            })?;
        if v.len() != 6 || v.iter().any(|c| !c.is_finite()) {
            bail!("--tool-box `{text}`: expected six finite numbers xmin,ymin,zmin,xmax,ymax,zmax in mm");
        }
        let (low, high) =
            (nalgebra::Vector3::new(v[0], v[1], v[2]), nalgebra::Vector3::new(v[3], v[4], v[5]));
        if (0..3).any(|i| low[i] > high[i]) {
            bail!("--tool-box `{text}`: each minimum must not exceed its maximum");
        }
        constraints.tool_box = Some([low, high]);
    }
    for text in &args.exclude {
        let parts: Vec<&str> = text.split(':').map(str::trim).collect();
        let [name, from, to] = parts[..] else {
            bail!("--exclude `{text}`: expected JOINT:FROM:TO, e.g. j2:-30:10 (degrees)");
        };
        let Some(joint) = model.joints.iter().position(|j| j.name == name) else {
            let names: Vec<&str> = model.joints.iter().map(|j| j.name.as_str()).collect();
            bail!("--exclude `{text}`: no joint `{name}`; the model's joints are {}", names.join(", "));
        };
        let value = |s: &str| -> Result<f64> {
            let v: f64 = s.parse().with_context(|| format!("--exclude `{text}`: `{s}` is not a number"))?;
            if !v.is_finite() {
                bail!("--exclude `{text}`: `{s}` is not a finite number");
            }
            Ok(if model.joints[joint].kind == JointKind::Revolute { v.to_radians() } else { v })
        };
        let range = [value(from)?, value(to)?];
        if range[0] > range[1] {
            bail!("--exclude `{text}`: FROM must not exceed TO");
        }
        constraints.excluded.push(ExcludedRange { joint, range });
    }
    let (plan, pool) =
        design.plan_seeded(args.points, args.candidates, &constraints, args.criterion, args.seed)?;
    let summary = report::design::plan_summary(&design, &plan, pool.joints.len(), pool.draws);
    let comment = format!(
        "robocal plan --model {} --points {} --candidates {} --criterion {} --seed {}\n{}",
        args.design.model,
        args.points,
        args.candidates,
        args.criterion,
        args.seed,
        summary.trim_end()
    );
    let csv = robocal::design::poses_csv(model, &plan.joints, &comment);
    match &args.out {
        Some(path) => {
            std::fs::write(path, csv).with_context(|| format!("{}: cannot write", path.display()))?;
            print!("{summary}");
            println!("wrote {} poses to {}", plan.joints.len(), path.display());
        }
        None => {
            eprint!("{summary}");
            print!("{csv}");
        }
    }
    Ok(())
}

/// `--replications`: 1 to `MAX_REPLICATIONS`.
fn parse_replications(text: &str) -> Result<usize, String> {
    let count: usize = text.parse().map_err(|_| format!("expected a whole number, found `{text}`"))?;
    simulation::check_replications(count).map_err(|e| e.to_string())
}

/// Run `study` with a progress bar, print its tables, and write them with the CSV samples and
/// the figures into `out/<study name>/`; with `replications`, the same for the study
/// replicated over that many derived seeds.
fn simulate(study: &Study, out: &Path, threads: Option<usize>, replications: Option<usize>) -> Result<()> {
    let runs = study.cases.len() * study.point_sets * study.runs_per_set;
    let progress = |runs: usize, message: String| {
        let bar = ProgressBar::new(runs as u64).with_message(message);
        bar.set_style(
            ProgressStyle::with_template("{msg} {bar:40} {pos}/{len} runs").expect("a valid template"),
        );
        bar
    };
    let bar = progress(runs, study.name.clone());
    let pool = rayon::ThreadPoolBuilder::new().num_threads(threads.unwrap_or(0)).build()?;
    let results = pool.install(|| simulation::run(study, &|| bar.inc(1)))?;
    bar.finish_and_clear();
    let mut tables = report::study::tables(study, &results);
    if let Some(comparison) = report::study::planned_against_random(study, &results) {
        tables += &format!("\n{comparison}");
    }
    println!("{tables}");
    let mut files = vec![
        ("tables.txt".to_string(), tables),
        ("samples.csv".to_string(), report::study::samples_csv(study, &results)),
    ];
    files.extend(report::figures::study_figures(study, &results)?);
    let folder = out.join(&study.name);
    io::write_files(&folder, &files)?;
    println!("wrote {} files to {}\n", files.len(), folder.display());
    if let Some(count) = replications {
        let bar = progress(runs * count, format!("{} x {count} replications", study.name));
        let replicated = pool.install(|| simulation::replicate(study, count, &|| bar.inc(1)))?;
        bar.finish_and_clear();
        let files = report::replication::files(study, &replicated)?;
        println!("{}", files[0].1);
        io::write_files(&folder, &files)?;
        println!("wrote {} files to {}\n", files.len(), folder.display());
    }
    Ok(())
}

/// `"0, 45,180"` into joint values in rad (revolute) or mm (prismatic), one per joint.
fn parse_joint_values(model: &RobotModel, text: &str) -> Result<Vec<f64>> {
    let values: Vec<f64> = text
        .split(|c: char| c == ',' || c.is_whitespace())
        .filter(|s| !s.is_empty())
        .enumerate()
        .map(|(i, s)| {
            let v: f64 = s.parse().with_context(|| format!("--q: value {} `{s}` is not a number", i + 1))?;
            if !v.is_finite() {
                bail!("--q: value {} is {v}, expected a finite number", i + 1);
            }
            Ok(v)
        })
        .collect::<Result<_>>()?;
    if values.len() != model.dof() {
        bail!(
            "--q: {} has {} joints, got {} values (degrees for revolute joints, mm for prismatic)",
            model.name,
            model.dof(),
            values.len()
        );
    }
    Ok(model
        .joints
        .iter()
        .zip(values)
        .map(|(joint, v)| if joint.kind == JointKind::Revolute { v.to_radians() } else { v })
        .collect())
}

/// The noise model of `--joint-sigma-deg` (deg; mm for prismatic joints), `--sigma-mm` and
/// `--sigma-orientation-deg`, checked against the robot.
fn noise_from_flags(
    model: &RobotModel,
    sigmas: &[f64],
    sigma_mm: f64,
    orientation_deg: f64,
) -> Result<NoiseModel> {
    if sigmas.len() != model.dof() {
        bail!("--joint-sigma-deg: {} values for the {} joints of {}", sigmas.len(), model.dof(), model.name);
    }
    if sigmas.iter().chain([&sigma_mm, &orientation_deg]).any(|s| !s.is_finite() || *s < 0.0) {
        bail!("--joint-sigma-deg, --sigma-mm and --sigma-orientation-deg: expected finite values >= 0");
    }
    let joint: Vec<f64> = model
        .joints
        .iter()
        .zip(sigmas)
        .map(|(j, &s)| if j.kind == JointKind::Revolute { s.to_radians() } else { s })
        .collect();
    Ok(NoiseModel::diagonal(&joint, MeasurementNoise::isotropic(sigma_mm, orientation_deg.to_radians())))
}
