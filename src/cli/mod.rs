//! The command line: parse the flags into one validated request, call the library, print.

use anyhow::{Context, Result, bail};
use clap::{Parser, Subcommand};
use indicatif::{ProgressBar, ProgressStyle};
use robocal::kinematics::Chain;
use robocal::model::{JointKind, PRESETS, RobotModel};
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
    },
    /// Forward kinematics: the tool pose of a model at given joint values.
    Fk {
        /// A preset name (see `robocal model list`) or a model TOML file.
        #[arg(long)]
        model: String,
        /// Joint values, comma-separated: degrees for revolute joints, mm for prismatic ones.
        #[arg(long, allow_hyphen_values = true)]
        q: String,
    },
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
        Command::Model { command: ModelCommand::Show { model } } => {
            print!("{}", io::load_model(&model)?.to_toml_string());
        }
        Command::Model { command: ModelCommand::List } => {
            for (name, _) in PRESETS {
                let model = RobotModel::preset(name).expect("presets are valid");
                println!("{name:<12} {}", model.description);
            }
        }
        Command::Reproduce { out, threads } => {
            let started = Instant::now();
            let studies = ["paper-table1", "paper-table2"]
                .map(io::load_study)
                .into_iter()
                .collect::<Result<Vec<_>, _>>()?;
            for study in &studies {
                simulate(study, &out, threads)?;
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
        Command::Simulate { study, out, threads } => simulate(&io::load_study(&study)?, &out, threads)?,
    }
    Ok(())
}

/// Run `study` with a progress bar, print its tables, and write them with the CSV samples and
/// the figures into `out/<study name>/`.
fn simulate(study: &Study, out: &Path, threads: Option<usize>) -> Result<()> {
    let runs = study.cases.len() * study.point_sets * study.runs_per_set;
    let bar = ProgressBar::new(runs as u64).with_message(study.name.clone());
    bar.set_style(ProgressStyle::with_template("{msg} {bar:40} {pos}/{len} runs").expect("a valid template"));
    let pool = rayon::ThreadPoolBuilder::new().num_threads(threads.unwrap_or(0)).build()?;
    let results = pool.install(|| simulation::run(study, &|| bar.inc(1)))?;
    bar.finish_and_clear();
    let tables = report::study::tables(study, &results);
    println!("{tables}");
    let mut files = vec![
        ("tables.txt".to_string(), tables),
        ("samples.csv".to_string(), report::study::samples_csv(study, &results)),
    ];
    files.extend(report::figures::study_figures(study, &results)?);
    let folder = out.join(&study.name);
    io::write_files(&folder, &files)?;
    println!("wrote {} files to {}\n", files.len(), folder.display());
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
