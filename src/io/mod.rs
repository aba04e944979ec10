//! The edge where robocal meets files: every error names the file it came from.
//!
//! This is the only library module that touches the file system; the core (model,
//! kinematics, estimation, simulation) works on values.

use crate::model::{ModelError, PRESETS, RobotModel};
use std::path::{Path, PathBuf};

/// A file that could not be read or understood.
#[derive(Debug, thiserror::Error)]
pub enum InputError {
    /// The file could not be opened or read.
    #[error("{path}: cannot read: {source}")]
    Read {
        /// The file.
        path: PathBuf,
        /// What the system said.
        source: std::io::Error,
    },
    /// The file is not a valid model.
    #[error("{path}: {source}")]
    Model {
        /// The file.
        path: PathBuf,
        /// What is wrong, with line or field.
        source: ModelError,
    },
    /// Neither a preset nor an existing file.
    #[error("no model `{name}`: not a preset ({presets}) and no such file")]
    UnknownModel {
        /// What was asked for.
        name: String,
        /// The preset names, comma-separated.
        presets: String,
    },
}

/// A model by preset name (`puma560`) or from a TOML file.
pub fn load_model(name_or_path: &str) -> Result<RobotModel, InputError> {
    if let Some(model) = RobotModel::preset(name_or_path) {
        return Ok(model);
    }
    let path = Path::new(name_or_path);
    if !path.exists() {
        let presets = PRESETS.iter().map(|(n, _)| *n).collect::<Vec<_>>().join(", ");
        return Err(InputError::UnknownModel { name: name_or_path.to_string(), presets });
    }
    let text =
        std::fs::read_to_string(path).map_err(|source| InputError::Read { path: path.into(), source })?;
    RobotModel::from_toml_str(&text).map_err(|source| InputError::Model { path: path.into(), source })
}
