//! `robocal model`: list the presets, show a model.

use super::args::ModelCommand;
use anyhow::Result;
use robocal::io;
use robocal::model::{PRESETS, RobotModel};

/// Print the presets, or a model as TOML.
pub fn run(command: &ModelCommand) -> Result<()> {
    match command {
        ModelCommand::Show { model, links } => {
            let model = links.model_ref(model)?;
            let read = io::load_model(&model)?;
            if model.is_urdf() {
                println!("# the chain of {}: {}", model.name, read.description);
            }
            print!("{}", read.to_toml_string());
        }
        ModelCommand::List => {
            for (name, _) in PRESETS {
                let model = RobotModel::preset(name).expect("presets are valid");
                println!("{name:<15} {} joints  {}", model.dof(), model.description);
            }
        }
    }
    Ok(())
}
