//! The edge where robocal meets files: every error names the file it came from, once, and
//! keeps what is wrong inside it (line, column, field) as its source: print the chain
//! (`{:#}` of anyhow, or [`std::error::Error::source`] in turn) to see both.
//!
//! This is the only library module that touches the file system; the core (model,
//! kinematics, estimation, simulation) works on values.

use crate::calibration::{Measurements, RepeatabilityData};
use crate::estimation::{NoiseFileError, NoiseSpec};
use crate::model::{ModelError, ModelRef, PRESETS, RobotModel, chain_links, from_urdf_str};
use crate::simulation::{STUDIES, Study, StudyError};
use crate::table::{DataError, Units};
use std::path::{Path, PathBuf};

/// A file that could not be read or understood.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum InputError {
    /// The file could not be opened or read.
    #[error("{}: cannot read", path.display())]
    Read {
        /// The file.
        path: PathBuf,
        /// What the system said.
        source: std::io::Error,
    },
    /// The file is not a valid model.
    #[error("{}", path.display())]
    Model {
        /// The file.
        path: PathBuf,
        /// What is wrong, with line or field.
        source: ModelError,
    },
    /// The file is not a valid study.
    #[error("{}", path.display())]
    Study {
        /// The file.
        path: PathBuf,
        /// What is wrong, with line or field.
        source: StudyError,
    },
    /// The measurement file is not valid.
    #[error("{}", path.display())]
    Data {
        /// The file.
        path: PathBuf,
        /// The line, column and problem.
        source: DataError,
    },
    /// The noise file is not valid.
    #[error("{}", path.display())]
    Noise {
        /// The file.
        path: PathBuf,
        /// The field or line, and the problem.
        source: NoiseFileError,
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

/// A file that could not be written.
#[derive(Debug, thiserror::Error)]
#[error("{}: cannot write", path.display())]
pub struct OutputError {
    /// The file or folder.
    pub path: PathBuf,
    /// What the system said.
    pub source: std::io::Error,
}

/// Write `files` (name, contents) into `folder`, creating it if needed.
pub fn write_files(folder: &Path, files: &[(String, String)]) -> Result<(), OutputError> {
    std::fs::create_dir_all(folder).map_err(|source| OutputError { path: folder.into(), source })?;
    for (name, contents) in files {
        let path = folder.join(name);
        std::fs::write(&path, contents).map_err(|source| OutputError { path, source })?;
    }
    Ok(())
}

/// The text of the file at `path`.
fn read(path: &Path) -> Result<String, InputError> {
    std::fs::read_to_string(path).map_err(|source| InputError::Read { path: path.into(), source })
}

/// A study by name (`paper-table1`, see [`STUDIES`]) or from a TOML file; its `robot` field
/// is loaded by [`load_model`].
pub fn load_study(name_or_path: &str) -> Result<Study, InputError> {
    let robot = load_model;
    if let Some((_, text)) = STUDIES.iter().find(|(n, _)| *n == name_or_path) {
        return Ok(Study::from_toml_str(text, robot).expect("embedded studies are valid"));
    }
    let path = Path::new(name_or_path);
    let text = read(path)?;
    Study::from_toml_str(&text, robot).map_err(|source| InputError::Study { path: path.into(), source })
}

/// A chain read from a URDF file, with what it takes to write the calibrated URDF.
#[derive(Debug, Clone, PartialEq)]
pub struct UrdfChain {
    /// The chain as a model of the `urdf` convention.
    pub model: RobotModel,
    /// The file's text.
    pub text: String,
    /// The link the chain starts from.
    pub base_link: String,
    /// The link the chain ends at (the model's tool frame).
    pub tip_link: String,
}

/// The chain of a URDF file from `base_link` to `tip_link`, by default from the root link to
/// the only leaf ([`chain_links`]).
pub fn load_urdf(
    path: &Path,
    base_link: Option<&str>,
    tip_link: Option<&str>,
) -> Result<UrdfChain, InputError> {
    let text = read(path)?;
    let model_error = |source| InputError::Model { path: path.into(), source };
    let (base_link, tip_link) = chain_links(&text, base_link, tip_link).map_err(model_error)?;
    let model = from_urdf_str(&text, &base_link, &tip_link).map_err(model_error)?;
    Ok(UrdfChain { model, text, base_link, tip_link })
}

/// A measurement file for `model`; `units` given by the caller replace the file's line.
pub fn load_measurements(
    path: &Path,
    model: &RobotModel,
    units: Option<Units>,
) -> Result<Measurements, InputError> {
    let text = read(path)?;
    Measurements::from_csv_str(&text, model, units)
        .map_err(|source| InputError::Data { path: path.into(), source })
}

/// A repeatability file (a measurement file with a `pose` column) for `model`.
pub fn load_repeatability(
    path: &Path,
    model: &RobotModel,
    units: Option<Units>,
) -> Result<RepeatabilityData, InputError> {
    let text = read(path)?;
    RepeatabilityData::from_csv_str(&text, model, units)
        .map_err(|source| InputError::Data { path: path.into(), source })
}

/// A noise file (TOML; see [`NoiseSpec`]) for `model`.
pub fn load_noise(path: &Path, model: &RobotModel) -> Result<NoiseSpec, InputError> {
    let text = read(path)?;
    NoiseSpec::from_toml_str(&text, model).map_err(|source| InputError::Noise { path: path.into(), source })
}

/// A model by preset name (`puma560`), from a TOML file, or the chain of a URDF file
/// ([`load_urdf`]).
pub fn load_model(model: &ModelRef) -> Result<RobotModel, InputError> {
    let name_or_path = model.name.as_str();
    if let Some(model) = RobotModel::preset(name_or_path) {
        return Ok(model);
    }
    let path = Path::new(name_or_path);
    if model.is_urdf() {
        return Ok(load_urdf(path, model.base_link.as_deref(), model.tip_link.as_deref())?.model);
    }
    if !path.exists() {
        let presets = PRESETS.iter().map(|(n, _)| *n).collect::<Vec<_>>().join(", ");
        return Err(InputError::UnknownModel { name: name_or_path.to_string(), presets });
    }
    let text = read(path)?;
    RobotModel::from_toml_str(&text).map_err(|source| InputError::Model { path: path.into(), source })
}

/// The joint values of a pose file (or of a measurement file) for `model`; `units` given by
/// the caller replace the file's line.
pub fn load_poses(
    path: &Path,
    model: &RobotModel,
    units: Option<Units>,
) -> Result<Vec<Vec<f64>>, InputError> {
    let text = read(path)?;
    crate::design::poses_from_csv_str(&text, model, units)
        .map_err(|source| InputError::Data { path: path.into(), source })
}
