//! The command line: clap parses the flags ([`args`]), each command's flags become one
//! validated request ([`request`]), and the command's file calls the library and prints.

mod accuracy;
mod args;
mod compensate;
mod evaluate;
mod fk;
mod manual;
mod model;
mod observability;
mod observations;
mod plan;
mod repeatability;
mod request;
mod robot;
mod shard;
mod simulate;
mod tree;

use anyhow::{Context, Result, bail};
use args::{
    CalibrateArgs, CalibrateObservationsArgs, CalibrateTreeArgs, EvaluateArgs, FkArgs, MergeArgs,
    ObservabilityArgs, PlanArgs, RepeatabilityArgs, ReportArgs, SimulateArgs, StudyOutputArgs,
};
use clap::{CommandFactory, Parser, Subcommand};
use request::{
    CalibrateObservationsRequest, CalibrateTreeRequest, CalibrationRequest, DesignRequest, EvaluateRequest,
    NoiseFlags, ObservabilityRequest, PlanRequest, RepeatabilityRequest,
};
use robocal::design::Design;
use robocal::estimation::{MeasurementNoise, NoiseModel};
use robocal::io;
use robocal::model::{JointKind, RobotModel};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};

pub use request::UsageError;

/// Kinematic calibration of robot arms by ordinary and weighted least squares.
///
/// Exit codes: 0 success, 1 an error in the input or the computation (the message says which
/// file, line or field), 2 a usage error on the command line.
#[derive(Parser, Debug)]
#[command(name = "robocal", version, about, long_about)]
pub struct Cli {
    /// The command to run.
    #[command(subcommand)]
    command: Command,
    /// Print only the results (standard output), warnings and errors: no progress bars, no
    /// "wrote ..." lines, notes or summaries on standard error.
    #[arg(long, short = 'q', global = true)]
    quiet: bool,
}

/// The commands.
#[derive(Subcommand, Debug)]
enum Command {
    /// Run the paper's two studies on the embedded PUMA 560: Tables 1-2, Figures 1-4.
    Reproduce(StudyOutputArgs),
    /// Run a study: a TOML file, or an embedded one (paper-table1, paper-table2,
    /// planned-poses, device-cmm, device-laser-tracker, device-theodolites, compliance, and the
    /// instrument study instruments: the files in presets/).
    ///
    /// --noise and --replications are for the estimator studies, not for an instrument study
    /// (a file with [[instruments]]).
    Simulate(SimulateArgs),
    /// Combine the shards of a study run with `simulate --shard I/N` (on a cluster: one
    /// process per shard) into exactly the tables, samples and figures one `simulate` writes.
    Merge(MergeArgs),
    /// Estimate the joint noise and sigma_me from repeated measurements at a set of poses,
    /// and write them as a noise file.
    Repeatability(Box<RepeatabilityArgs>),
    /// Forward kinematics: the tool pose of a model at given joint values.
    Fk(FkArgs),
    /// Calibrate a robot from measured data of any kind, each file's kind read from its header:
    /// marker positions or a probe's poses, distances (a ball bar, a length artefact), plane
    /// contacts, coordinates (a height gauge), a camera's views of a target, or views between
    /// the branches of a URDF tree; several files fitted together: docs/formats.md.
    Calibrate(Box<CalibrateArgs>),
    /// The old name of `calibrate` for observation files, an alias for one release.
    #[command(hide = true)]
    CalibrateObservations(Box<CalibrateObservationsArgs>),
    /// The old name of `calibrate` for a tree's views, an alias for one release.
    #[command(hide = true)]
    CalibrateTree(Box<CalibrateTreeArgs>),
    /// Score a model as it stands (a calibrated one, base and markers included) on
    /// measurement files: no registration, no fit.
    Evaluate(Box<EvaluateArgs>),
    /// Observability indices O1-O5 of a pose file (or a measurement file's joint columns).
    Observability(Box<ObservabilityArgs>),
    /// Plan measurement poses that maximise an observability criterion; writes a pose file.
    Plan(Box<PlanArgs>),
    /// Compensate a robot program: the joint values to send a controller that computes with
    /// the nominal model so that the calibrated (real) robot reaches each target.
    Compensate(Box<compensate::CompensateArgs>),
    /// The calibrated robot's predicted accuracy (the calibration's covariance carried to the
    /// tool, plus the held-out floor) over a pose file or a grid of the joint ranges: CSV and
    /// figures.
    Accuracy(Box<accuracy::AccuracyArgs>),
    /// Inspect robot models.
    Model {
        /// What to do with the models.
        #[command(subcommand)]
        command: args::ModelCommand,
    },
    /// Print a shell's completion script for robocal to standard output (bash: `robocal
    /// completions bash > ~/.local/share/bash-completion/completions/robocal`).
    Completions {
        /// The shell.
        shell: clap_complete::Shell,
    },
    /// Print robocal's manual page (roff) to standard output (`robocal man | man -l -`), or write
    /// one page per command into a folder (`robocal.1`, `robocal-calibrate.1`, ...).
    Man {
        /// Write the pages into this folder instead (created if missing).
        #[arg(long, value_name = "DIR")]
        out: Option<std::path::PathBuf>,
    },
}

/// Run the command line. A broken rule between flags is a [`UsageError`].
pub fn run(cli: Cli) -> Result<()> {
    QUIET.store(cli.quiet, Ordering::Relaxed);
    match cli.command {
        Command::Reproduce(output) => simulate::reproduce(&output),
        Command::Simulate(args) => match args.shard {
            Some(part) => shard::simulate(&args, part),
            None => simulate::simulate(&args),
        },
        Command::Merge(args) => shard::merge(&args),
        Command::Repeatability(args) => repeatability::run(&RepeatabilityRequest::from_args(*args)?),
        Command::Fk(args) => fk::run(&args),
        Command::Calibrate(args) => calibrate_any(*args),
        Command::CalibrateObservations(args) => {
            eprintln!(
                "note: `robocal calibrate-observations` is now `robocal calibrate`, with the same flags; this name goes in the next release"
            );
            observations::run(&CalibrateObservationsRequest::from_args(*args)?)
        }
        Command::CalibrateTree(args) => {
            eprintln!(
                "note: `robocal calibrate-tree` is now `robocal calibrate --tips ...`, with the same flags (--out-dir for the branches); this name goes in the next release"
            );
            tree::run(&CalibrateTreeRequest::from_args(*args)?)
        }
        Command::Evaluate(args) => evaluate::run(&EvaluateRequest::from_args(*args)?),
        Command::Observability(args) => observability::run(&ObservabilityRequest::from_args(*args)?),
        Command::Plan(args) => plan::run(&PlanRequest::from_args(*args)?),
        Command::Compensate(args) => compensate::run(&args),
        Command::Accuracy(args) => accuracy::run(&args),
        Command::Model { command } => model::run(&command),
        Command::Completions { shell } => {
            clap_complete::generate(shell, &mut Cli::command(), "robocal", &mut std::io::stdout());
            Ok(())
        }
        Command::Man { out } => manual::run(out.as_deref()),
    }
}

/// Whether `--quiet` was given.
static QUIET: AtomicBool = AtomicBool::new(false);

/// Whether `--quiet` was given: no progress bars, no "wrote ..." lines, notes or summaries on
/// standard error.
fn quiet() -> bool {
    QUIET.load(Ordering::Relaxed)
}

/// Say `line` on standard error (progress, what was written, a note), unless `--quiet`:
/// standard output holds the results only.
fn status(line: impl std::fmt::Display) {
    if !quiet() {
        eprintln!("{line}");
    }
}

/// A summary (lines ending in a newline) on standard error, when standard output holds the
/// results (a CSV); unless `--quiet`.
fn status_text(text: &str) {
    if !quiet() {
        eprint!("{text}");
    }
}

/// `robocal calibrate`: each data file's kind read from its header, then the calibration its
/// data and flags call for ([`CalibrationRequest`]).
fn calibrate_any(args: args::CalibrateArgs) -> Result<()> {
    let kinds = (args.data.iter()).map(|path| robocal::io::data_kind(path)).collect::<Result<Vec<_>, _>>()?;
    match CalibrationRequest::from_args(args, &kinds)? {
        CalibrationRequest::Observations(request) => observations::run(&request),
        CalibrationRequest::Tree(request) => tree::run(&request),
    }
}

/// `value` as the JSON report (pretty, one trailing newline) if `report` asks for one: a
/// large campaign's JSON is many times its input, and is not built for nothing.
fn json_if_asked<T: serde::Serialize>(report: &ReportArgs, value: &T) -> Result<Option<String>> {
    Ok(match report.json {
        Some(_) => Some(serde_json::to_string_pretty(value)? + "\n"),
        None => None,
    })
}

/// A page of the figures (`(file name, SVG)`) it embeds.
type PageOf<'a> = &'a dyn Fn(&[(String, String)], &[&robocal::report::residuals::ResidualSet]) -> String;

/// What a calibration of observation files or of a tree's views reports: its JSON and page,
/// each scored set's residuals (the training files', each held-out file's) and the choices
/// made from the data.
struct ResidualContent<'a> {
    /// The JSON report, built only if `--json` asks for it ([`json_if_asked`]).
    json: Option<String>,
    /// The page, of the figures it embeds.
    page: PageOf<'a>,
    sets: Vec<robocal::report::residuals::ResidualSet>,
    /// The robot's (the tree's) joints, in the order of each residual's joint values.
    joints: &'a [robocal::model::Joint],
    /// The calibrated robot, whose masses (if any) give each pose's gravity loads to draw the
    /// residuals against; none for a tree.
    model: Option<&'a robocal::model::RobotModel>,
    /// `--prior auto`'s scale and curve, if it chose one.
    prior_scale: Option<&'a robocal::calibration::prior_scale::PriorScale>,
    /// `--select`'s path, if it chose the parameters.
    selection: Option<&'a robocal::report::calibration::SelectionReport>,
}

/// Stage in `outputs` the files of `report` that were asked for: the JSON, every residual
/// (CSV), the figures (SVG) and the page with the figures inline.
fn write_residual_files(
    report: &ReportArgs,
    content: ResidualContent<'_>,
    outputs: &mut io::Outputs,
) -> Result<()> {
    use robocal::report::{figures, residuals};
    if let (Some(path), Some(json)) = (&report.json, content.json) {
        outputs.add(path, json);
    }
    let sets: Vec<&residuals::ResidualSet> = content.sets.iter().collect();
    if let Some(path) = &report.poses_csv {
        outputs.add(path, residuals::residuals_csv(&sets, content.joints));
    }
    if report.figures.is_none() && report.html.is_none() {
        return Ok(());
    }
    let mut all = residuals::residual_figures(&sets, content.joints)?;
    if let Some(model) = content.model {
        all.extend(residuals::residual_torque_figures(&sets, model)?);
    }
    if let Some(scale) = content.prior_scale {
        all.push(figures::prior_scale_figure(scale)?);
    }
    if let Some(selection) = content.selection {
        all.push(figures::selection_figure(selection)?);
    }
    if let Some(path) = &report.html {
        outputs.add(path, (content.page)(&all, &sets));
    }
    if let Some(folder) = &report.figures {
        outputs.add_folder(folder, &all);
    }
    Ok(())
}

/// Each `(name, file)` of `files` with its name borrowed.
fn by_name<T>(files: &[(String, T)]) -> Vec<(&str, &T)> {
    files.iter().map(|(name, file)| (name.as_str(), file)).collect()
}

/// A joint value given on the command line (degrees; mm for a prismatic joint) in the model's
/// units (radians; mm).
fn from_flag_unit(kind: JointKind, value: f64) -> f64 {
    if kind == JointKind::Revolute { value.to_radians() } else { value }
}

/// The noise model of `--joint-sigma-deg`, `--sigma-mm` and `--sigma-orientation-deg`: one joint
/// sigma per joint of `model`.
fn noise_model(model: &RobotModel, flags: &NoiseFlags) -> Result<NoiseModel> {
    let joint = joint_sigmas(&model.name, &model.joints, &flags.joint_sigma_deg)?;
    let measurement = MeasurementNoise::isotropic(flags.sigma_mm, flags.sigma_orientation_deg.to_radians());
    Ok(NoiseModel::diagonal(&joint, measurement))
}

/// The joint noise standard deviations of `--joint-sigma-deg` (deg, mm for prismatic joints)
/// in the model's units (rad, mm): one value per joint of the robot `name`, or one for every
/// joint. The one reader of the flag for every command.
fn joint_sigmas(name: &str, joints: &[robocal::model::Joint], sigmas: &[f64]) -> Result<Vec<f64>> {
    if sigmas.len() != 1 && sigmas.len() != joints.len() {
        let names: Vec<&str> = joints.iter().map(|j| j.name.as_str()).collect();
        bail!(
            "--joint-sigma-deg: {} values for the {} joints of {} ({}): give one per joint or one for all",
            sigmas.len(),
            joints.len(),
            name,
            names.join(", ")
        );
    }
    let sigma = |j: usize| if sigmas.len() == 1 { sigmas[0] } else { sigmas[j] };
    Ok(joints.iter().enumerate().map(|(j, joint)| from_flag_unit(joint.kind, sigma(j))).collect())
}

/// `Sigma_q = diag(sigma_j^2)` (rad², mm²) of `--joint-sigma-deg`, if given ([`joint_sigmas`]).
fn joint_covariance(
    name: &str,
    joints: &[robocal::model::Joint],
    sigmas: Option<&[f64]>,
) -> Result<Option<nalgebra::DMatrix<f64>>> {
    let Some(sigmas) = sigmas else { return Ok(None) };
    let variances = joint_sigmas(name, joints, sigmas)?.into_iter().map(|s| s * s);
    Ok(Some(nalgebra::DMatrix::from_diagonal(&nalgebra::DVector::from_iterator(joints.len(), variances))))
}

/// The design of `observability` and `plan`: the model loaded, the parameters chosen.
fn design(request: &DesignRequest) -> Result<Design> {
    let model = io::load_model(&request.model)?;
    let params = model.params();
    let selection = request.params.select(&params).context("--params")?;
    let noise = request.noise.as_ref().map(|flags| noise_model(&model, flags)).transpose()?;
    Ok(Design::new(&model, selection, request.measured, noise)?)
}

/// Warn, naming the lines (the first ten), about the poses of `path` (`(line, joint values)`)
/// with joint values outside `model`'s limits: a repeatability study there measures the arm
/// where it does not go. (A calibration says so in its report: [`robocal::calibration::Warning`].)
fn warn_outside_limits<'a>(path: &Path, model: &RobotModel, poses: impl Iterator<Item = (usize, &'a [f64])>) {
    let (name, joints) = (&model.name, &model.joints);
    let outside: Vec<String> = poses
        .filter_map(|(line, q)| {
            let joints = robocal::model::outside_limits(joints, q);
            (!joints.is_empty()).then(|| format!("{line} ({})", joints.join(", ")))
        })
        .collect();
    if outside.is_empty() {
        return;
    }
    let more = if outside.len() > 10 { format!(" and {} more", outside.len() - 10) } else { String::new() };
    let lines = outside.iter().take(10).cloned().collect::<Vec<_>>().join(", ");
    eprintln!("warning: {}: joint values outside the limits of {name} at line {lines}{more}", path.display(),);
}

/// Whether `path` is `-`: standard output.
fn is_stdout(path: &Path) -> bool {
    path.as_os_str() == "-"
}

/// The text report on standard output; on standard error instead (unless `--quiet`) when one
/// of the command's `outputs` is `-`, whose contents then have standard output to themselves.
fn show_report(text: &str, outputs: &[Option<&PathBuf>]) {
    match outputs.iter().flatten().any(|p| is_stdout(p)) {
        true => status_text(text),
        false => print!("{text}"),
    }
}

/// The report files of `report` that may be `-` (the JSON, the poses' CSV, the page).
fn report_outputs(report: &args::ReportArgs) -> [Option<&PathBuf>; 3] {
    [report.json.as_ref(), report.poses_csv.as_ref(), report.html.as_ref()]
}

/// Write the files of `outputs` (all or none) and say on standard error which were written, so
/// that standard output stays the report (`-`: standard output).
fn commit(outputs: io::Outputs) -> Result<()> {
    let name = |p: &Path| if is_stdout(p) { "standard output".to_string() } else { p.display().to_string() };
    let written: Vec<String> = outputs.paths().map(name).collect();
    outputs.commit()?;
    if !written.is_empty() {
        status(format_args!("wrote {}", written.join(", ")));
    }
    Ok(())
}

/// Warn when `--fixed-markers` holds markers that no `--marker` placed (`given` of the
/// `highest` number the files have): they are held at the tool frame's origin.
fn warn_unplaced_fixed_markers(fixed: bool, given: usize, highest: usize) {
    if fixed && given < highest {
        let unplaced: Vec<String> = (given + 1..=highest).map(|k| k.to_string()).collect();
        let (markers, are) = if unplaced.len() == 1 { ("marker", "is") } else { ("markers", "are") };
        eprintln!(
            "warning: --fixed-markers: {markers} {} {are} held at the tool frame's origin, as no --marker gives {}",
            unplaced.join(", "),
            if unplaced.len() == 1 { "its position" } else { "their positions" }
        );
    }
}

/// At most as many `--marker`s as the data file has markers.
fn check_marker_count(given: usize, data: &Path, in_file: usize) -> Result<()> {
    if given > in_file {
        let markers = if in_file == 1 { "marker" } else { "markers" };
        bail!("{given} --marker given, {} has {in_file} {markers}", data.display());
    }
    Ok(())
}
