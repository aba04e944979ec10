//! `robocal compensate`: the joint values to send a controller that computes with the nominal
//! model so that the real (calibrated) robot reaches each target.

use super::args::UnitArgs;
use anyhow::{Context, Result, bail};
use clap::{Args, ValueEnum};
use robocal::design::compensate::{CompensateOptions, Compensator, TargetFrame, targets_from_csv_str};
use robocal::model::{ModelRef, RobotModel, markers_from_toml_str};
use robocal::report::compensation;
use std::path::{Path, PathBuf};

/// The frame targets are given in.
#[derive(ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum FrameName {
    /// The measuring (cell) frame the calibrated model's base is placed in.
    Measuring,
    /// The robot's base frame, as the calibrated base places it.
    Base,
}

/// The flags of `robocal compensate`.
///
/// Targets: a CSV file with the units line. With the model's joint columns only, each row is
/// a joint target taught or generated on the nominal model: the target is the nominal pose
/// there. With the columns x, y, z, roll, pitch, yaw too (lengths in the length unit, angles in
/// the joint unit, R = Rz(yaw) Ry(pitch) Rx(roll)), each row is a pose target and its joint
/// values the nominal joint solution, the seed.
///
/// Frames: a calibrated model carries its base placement in the measuring frame. By default
/// (--frame measuring) pose targets, and joint targets' nominal poses (the nominal model with
/// its own base), are in that frame; --frame base takes both in the robot's base frame as the
/// calibrated base places it (both models' bases left out).
#[derive(Args, Debug)]
pub struct CompensateArgs {
    /// The target file (CSV).
    pub targets: PathBuf,
    /// The calibrated model, the real robot: a model TOML file (as `calibrate --out-model`
    /// writes it), a preset, or a URDF file.
    #[arg(long)]
    pub model: String,
    /// The nominal model the controller computes with: a preset, a model TOML file, or a URDF
    /// file.
    #[arg(long)]
    pub nominal: String,
    /// The calibrated model's marker (its `[[markers]]` id) to bring to the targets in place of
    /// its tool point.
    #[arg(long)]
    pub marker: Option<usize>,
    /// Reach the positions only, not the orientations (a 5-DOF task).
    #[arg(long)]
    pub position_only: bool,
    /// The frame the targets are in.
    #[arg(long, value_enum, default_value_t = FrameName::Measuring)]
    pub frame: FrameName,
    /// A joint moving more than this from its seed (deg; mm for prismatic joints) changes
    /// branch: the target is reported unreachable.
    #[arg(long, default_value_t = 10.0)]
    pub max_joint_change_deg: f64,
    /// Write the compensated program here (CSV) and the report to standard output; without it
    /// the program goes to standard output and the report to standard error.
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Write the report as JSON here: every target's joints, changes, error and iterations,
    /// or why it cannot be reached.
    #[arg(long)]
    pub json: Option<PathBuf>,
    #[command(flatten)]
    pub units: UnitArgs,
}

/// `model` with marker `id` of its file as its tool point.
fn with_marker(model: RobotModel, path: &str, id: usize) -> Result<RobotModel> {
    let text =
        std::fs::read_to_string(path).with_context(|| format!("--marker needs a model file: {path}"))?;
    let markers = markers_from_toml_str(&text).with_context(|| path.to_string())?;
    let Some((_, point)) = markers.iter().find(|(k, _)| *k == id) else {
        let ids: Vec<String> = markers.iter().map(|(k, _)| k.to_string()).collect();
        bail!(
            "--marker {id}: {path} has markers {}",
            if ids.is_empty() { "none".into() } else { ids.join(", ") }
        );
    };
    Ok(robocal::design::compensate::with_tool_point(model, *point))
}

/// Compensate the targets; write the program and the report.
pub fn run(args: &CompensateArgs) -> Result<()> {
    let units = args.units.units()?;
    let nominal = robocal::io::load_model(&ModelRef::named(&args.nominal))?;
    let mut calibrated = robocal::io::load_model(&ModelRef::named(&args.model))?;
    if let Some(id) = args.marker {
        calibrated = with_marker(calibrated, &args.model, id)?;
    }
    if !(args.max_joint_change_deg.is_finite() && args.max_joint_change_deg > 0.0) {
        bail!("--max-joint-change-deg: a positive number, got {}", args.max_joint_change_deg);
    }
    let options = CompensateOptions {
        position_only: args.position_only,
        frame: if args.frame == FrameName::Base { TargetFrame::Base } else { TargetFrame::Measuring },
        max_joint_change: args.max_joint_change_deg.to_radians(),
        ..CompensateOptions::default()
    };
    let compensator = Compensator::new(&nominal, &calibrated, &options)?;
    let text = std::fs::read_to_string(&args.targets).with_context(|| args.targets.display().to_string())?;
    let rows =
        targets_from_csv_str(&text, &nominal, units).with_context(|| args.targets.display().to_string())?;
    let targets: Vec<_> = rows.iter().map(|r| r.target.clone()).collect();
    let solved = compensator.solve_all(&targets);
    let outcomes: Vec<_> = rows.iter().zip(&solved).collect();
    let source = args.targets.display().to_string();
    let report = compensation::text(&source, &calibrated, &outcomes);
    let comment = format!(
        "robocal compensate {source} --model {} --nominal {} --frame {}{}",
        args.model,
        args.nominal,
        if options.frame == TargetFrame::Base { "base" } else { "measuring" },
        if args.position_only { " --position-only" } else { "" }
    );
    let csv = compensation::csv(&calibrated, &outcomes, &comment);
    write(args, &csv, &report, compensation::json(&calibrated, &outcomes))
}

/// The program to `--out` (or standard output), the JSON, the report: all files or none.
fn write(args: &CompensateArgs, csv: &str, report: &str, json: String) -> Result<()> {
    let mut outputs = robocal::io::Outputs::new();
    if let Some(path) = &args.json {
        outputs.add(path, json);
    }
    match &args.out {
        Some(path) => {
            outputs.add(path, csv);
            commit(outputs, path)?;
            print!("{report}");
        }
        None => {
            outputs.commit()?;
            super::status_text(report);
            print!("{csv}");
        }
    }
    Ok(())
}

fn commit(outputs: robocal::io::Outputs, path: &Path) -> Result<()> {
    outputs.commit()?;
    super::status(format_args!("wrote {}", path.display()));
    Ok(())
}
