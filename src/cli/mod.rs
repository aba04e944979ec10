//! The command line: parse the flags into one validated request, call the library, print.

use anyhow::{Context, Result, bail};
use clap::{Parser, Subcommand};
use robocal::kinematics::Chain;
use robocal::model::{JointKind, PRESETS, RobotModel};
use robocal::{io, report};

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
    /// Run the paper's study on the embedded PUMA 560 (Tables 1-2, Figures 1-4).
    Reproduce {
        /// Folder for the CSV samples and the figures.
        #[arg(long, default_value = "robocal-out")]
        out: std::path::PathBuf,
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
        Command::Reproduce { out: _ } => {
            let model = RobotModel::preset("puma560").expect("presets are valid");
            println!("The paper's Monte Carlo study is not implemented yet: this prints the embedded");
            println!("PUMA 560 model it will run on.\n");
            print!("{}", model.to_toml_string());
        }
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
