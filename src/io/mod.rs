//! The edge where robocal meets files: every error names the file it came from, once, and
//! keeps what is wrong inside it (line, column, field) as its source: print the chain
//! (`{:#}` of anyhow, or [`std::error::Error::source`] in turn) to see both.
//!
//! This is the only library module that touches the file system; the core (model,
//! kinematics, estimation, simulation) works on values.

use crate::calibration::{DataKind, Measurements, RepeatabilityData};
use crate::estimation::{NoiseFileError, NoiseSpec};
use crate::limits::{FALLBACK_MEMORY, MEMORY_SHARE};
use crate::model::{ModelError, ModelRef, PRESETS, RobotModel, chain_links, from_urdf_str};
use crate::simulation::{
    INSTRUMENT_STUDIES, InstrumentStudy, STUDIES, Study, StudyError, is_instrument_study,
};
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
    /// A branch model that does not fit its tree ([`load_branches`]).
    #[error("{}", path.display())]
    Branch {
        /// The branch's file.
        path: PathBuf,
        /// How it does not fit.
        source: BranchError,
    },
    /// Neither a preset nor an existing file.
    #[error("no model `{name}`: not a preset ({presets}) and no such file")]
    UnknownModel {
        /// What was asked for.
        name: String,
        /// The preset names, comma-separated.
        presets: String,
    },
    /// Neither an embedded study nor an existing file.
    #[error("no study `{name}`: not an embedded one ({studies}) and no such file")]
    UnknownStudy {
        /// What was asked for.
        name: String,
        /// The embedded studies' names, comma-separated.
        studies: String,
    },
}

/// How a branch model written by `calibrate --out-dir` does not fit the tree it is read into.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum BranchError {
    /// Another number of joints than the branch's.
    #[error("{found} joints, the branch to {tip} has {expected}")]
    JointCount {
        /// The branch's tip link.
        tip: String,
        /// Joints in the file.
        found: usize,
        /// Joints of the branch.
        expected: usize,
    },
    /// A joint named otherwise than the branch's joint at its place.
    #[error("joint `{found}` where the branch to {tip} has `{expected}`")]
    JointName {
        /// The branch's tip link.
        tip: String,
        /// The file's joint.
        found: String,
        /// The branch's joint.
        expected: String,
    },
    /// A joint shared with a branch read before, with another geometry.
    #[error("joint `{joint}` differs from {other}'s: one geometry on every branch it is on")]
    Differs {
        /// The joint.
        joint: String,
        /// The file it was read from before.
        other: String,
    },
}

/// `tree` with the joints of the branch models `calibrate --out-dir` wrote to `folder` (one
/// `<tip>.toml` per branch): a joint on several branches must have one geometry in every file.
pub fn load_branches(
    tree: &crate::model::RobotTree,
    folder: &Path,
) -> Result<crate::model::RobotTree, InputError> {
    let mut joints = tree.joints.clone();
    let mut from: Vec<Option<PathBuf>> = vec![None; tree.dof()];
    for branch in &tree.branches {
        let path = folder.join(format!("{}.toml", branch.tip));
        let model = load_model(&ModelRef::named(path.display().to_string()))?;
        let bad = |source| InputError::Branch { path: path.clone(), source };
        if model.joints.len() != branch.joints.len() {
            let (found, expected) = (model.joints.len(), branch.joints.len());
            return Err(bad(BranchError::JointCount { tip: branch.tip.clone(), found, expected }));
        }
        for (joint, &j) in model.joints.iter().zip(&branch.joints) {
            if joint.name != tree.joints[j].name {
                let (found, expected) = (joint.name.clone(), tree.joints[j].name.clone());
                return Err(bad(BranchError::JointName { tip: branch.tip.clone(), found, expected }));
            }
            if let Some(other) = &from[j]
                && joints[j] != *joint
            {
                let other = other.display().to_string();
                return Err(bad(BranchError::Differs { joint: joint.name.clone(), other }));
            }
            joints[j] = joint.clone();
            from[j] = Some(path.clone());
        }
    }
    Ok(tree.with_joints(joints))
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

/// The outputs of a command, staged in memory and written together by [`Outputs::commit`]:
/// all of them appear, or none does, and a file already on disk is replaced only when every
/// output has been written.
///
/// Each regular file is first written in full to a temporary file beside its target
/// (`.NAME.PID.tmp` in the same folder), then every temporary file is renamed into place. If
/// writing any of them fails, the temporary files and the folders `commit` created are removed
/// and the targets are left as they were. (A rename within a folder is atomic; only a file
/// system that fails between two renames could leave some outputs new and the others old,
/// never a file half-written.)
///
/// A target that is not a regular file (a character device such as `/dev/null`, a FIFO, a
/// socket) is written in place, streaming, once every temporary file is written; `-` is
/// standard output. A symbolic link is followed: its target gets the temporary and the
/// rename, and the link stays a link.
///
/// While a commit runs, its temporary files and the folders it created are listed for
/// [`abandon_pending_outputs`], which a process stopped by a signal calls to remove them.
#[derive(Debug, Default)]
pub struct Outputs {
    /// (target, contents, may create the target's folder)
    files: Vec<(PathBuf, Vec<u8>, bool)>,
}

/// Where an output goes.
#[derive(Debug, Clone, PartialEq, Eq)]
enum Destination {
    /// A regular file (new or to replace) at this path, symbolic links resolved: a temporary
    /// file beside it, renamed over it.
    Replace(PathBuf),
    /// Not a regular file (a device, a FIFO): opened and written in place.
    InPlace(PathBuf),
    /// `-`: standard output.
    Stdout,
}

/// Where the output `path` goes: `-` is standard output, an existing file other than a regular
/// file or a folder is written in place, and a symbolic link is followed to what it names
/// (which need not exist yet).
fn destination(path: &Path) -> Destination {
    if path.as_os_str() == "-" {
        return Destination::Stdout;
    }
    if let Ok(meta) = std::fs::metadata(path) {
        if !meta.is_file() && !meta.is_dir() {
            return Destination::InPlace(path.to_path_buf());
        }
    }
    Destination::Replace(follow_links(path))
}

/// `path` with its last component's symbolic links followed (at most 40, as the system does),
/// to a path that is not a link, whether or not it exists.
fn follow_links(path: &Path) -> PathBuf {
    let mut path = path.to_path_buf();
    for _ in 0..40 {
        let is_link = std::fs::symlink_metadata(&path).is_ok_and(|m| m.file_type().is_symlink());
        let Some(target) = is_link.then(|| std::fs::read_link(&path).ok()).flatten() else {
            return path;
        };
        path = match path.parent() {
            Some(folder) if target.is_relative() => folder.join(target),
            _ => target,
        };
    }
    path
}

/// The temporary files and folders of unfinished commits, for [`abandon_pending_outputs`].
#[derive(Debug, Default)]
struct Pending {
    temporaries: Vec<PathBuf>,
    folders: Vec<PathBuf>,
}

/// What every commit in progress has on disk that is not an output yet. A commit holds the
/// lock while it creates folders and temporary files and while it renames them into place,
/// so that [`abandon_pending_outputs`] sees either none of its outputs or all of them.
static PENDING: std::sync::Mutex<Pending> =
    std::sync::Mutex::new(Pending { temporaries: Vec::new(), folders: Vec::new() });

fn pending() -> std::sync::MutexGuard<'static, Pending> {
    PENDING.lock().unwrap_or_else(std::sync::PoisonError::into_inner)
}

/// Remove the temporary files and the folders (empty but for them) of every commit in progress,
/// and keep any commit from going on: for a process about to exit on a signal (SIGINT,
/// SIGTERM). Outputs already renamed into place by a finished commit stay.
pub fn abandon_pending_outputs() {
    let pending = pending();
    for temporary in &pending.temporaries {
        let _ = std::fs::remove_file(temporary);
    }
    for folder in pending.folders.iter().rev() {
        let _ = std::fs::remove_dir(folder);
    }
    // Held until the process exits: no commit renames anything after this.
    std::mem::forget(pending);
}

/// `path` removed from `list` (once).
fn unlist(list: &mut Vec<PathBuf>, path: &Path) {
    if let Some(i) = list.iter().position(|p| p == path) {
        list.swap_remove(i);
    }
}

impl Outputs {
    /// No outputs yet.
    pub fn new() -> Self {
        Self::default()
    }

    /// Stage `contents` for `path`, whose folder must exist when the outputs are committed.
    pub fn add(&mut self, path: impl Into<PathBuf>, contents: impl Into<Vec<u8>>) {
        self.files.push((path.into(), contents.into(), false));
    }

    /// Stage `files` (name, contents) in `folder`, which is created if needed.
    pub fn add_folder(&mut self, folder: &Path, files: &[(String, String)]) {
        for (name, contents) in files {
            self.files.push((folder.join(name), contents.clone().into_bytes(), true));
        }
    }

    /// The number of files staged.
    pub fn len(&self) -> usize {
        self.files.len()
    }

    /// Whether nothing is staged.
    pub fn is_empty(&self) -> bool {
        self.files.is_empty()
    }

    /// The files staged, in order.
    pub fn paths(&self) -> impl Iterator<Item = &Path> {
        self.files.iter().map(|(path, _, _)| path.as_path())
    }

    /// Write every staged file; on an error, nothing staged is left on disk and every target
    /// keeps what it held. (A device, FIFO or standard output already written to cannot be
    /// taken back: they are written after every temporary file, just before the renames.)
    pub fn commit(self) -> Result<(), OutputError> {
        let destinations = self.destinations()?;
        let mut created = Vec::new();
        let mut temporaries = Vec::new();
        let written = {
            let mut pending = pending();
            self.write_temporaries(&destinations, &mut created, &mut temporaries, &mut pending)
        };
        let result = written.and_then(|()| self.write_in_place(&destinations)).and_then(|()| {
            let _pending = pending();
            for (temporary, target) in &temporaries {
                std::fs::rename(temporary, target)
                    .map_err(|source| OutputError { path: target.clone(), source })?;
            }
            Ok(())
        });
        let mut pending = pending();
        if result.is_err() {
            for (temporary, _) in &temporaries {
                let _ = std::fs::remove_file(temporary);
            }
            for folder in created.iter().rev() {
                let _ = std::fs::remove_dir(folder);
            }
        }
        for (temporary, _) in &temporaries {
            unlist(&mut pending.temporaries, temporary);
        }
        for folder in &created {
            unlist(&mut pending.folders, folder);
        }
        result
    }

    /// Where each staged file goes; an error for a target asked for twice or that is a folder.
    fn destinations(&self) -> Result<Vec<Destination>, OutputError> {
        let destinations: Vec<Destination> =
            self.files.iter().map(|(path, _, _)| destination(path)).collect();
        for (i, (target, _, _)) in self.files.iter().enumerate() {
            let Destination::Replace(resolved) = &destinations[i] else { continue };
            if destinations[..i].contains(&destinations[i]) {
                let source = std::io::Error::other("the same output is asked for twice");
                return Err(OutputError { path: target.clone(), source });
            }
            if resolved.is_dir() {
                let source = std::io::Error::other("a folder is there");
                return Err(OutputError { path: target.clone(), source });
            }
        }
        Ok(destinations)
    }

    /// Create the folders asked for (recording those created) and write each regular file to
    /// its temporary file (recording each `(temporary, target)`), listing both in `pending`.
    fn write_temporaries(
        &self,
        destinations: &[Destination],
        created: &mut Vec<PathBuf>,
        temporaries: &mut Vec<(PathBuf, PathBuf)>,
        pending: &mut Pending,
    ) -> Result<(), OutputError> {
        let folder_of = |target: &Path| match target.parent() {
            Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
            _ => PathBuf::from("."),
        };
        // The folders first, so that a file may go into a folder another output makes.
        for ((_, _, create), destination) in self.files.iter().zip(destinations) {
            if let (true, Destination::Replace(target)) = (create, destination) {
                let before = created.len();
                let made = create_folders(&folder_of(target), created);
                pending.folders.extend(created[before..].iter().cloned());
                made?;
            }
        }
        for ((path, contents, _), destination) in self.files.iter().zip(destinations) {
            let Destination::Replace(target) = destination else { continue };
            let folder = folder_of(target);
            let name = target.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
            let temporary = folder.join(format!(".{name}.{}.tmp", std::process::id()));
            pending.temporaries.push(temporary.clone());
            temporaries.push((temporary.clone(), target.clone()));
            std::fs::write(&temporary, contents).map_err(|source| OutputError {
                path: path.clone(),
                source: beside(&folder, &temporary, source),
            })?;
        }
        Ok(())
    }

    /// Write the files that are not regular files (devices, FIFOs, standard output) in place.
    fn write_in_place(&self, destinations: &[Destination]) -> Result<(), OutputError> {
        use std::io::Write;
        for ((path, contents, _), destination) in self.files.iter().zip(destinations) {
            let error = |source| OutputError { path: path.clone(), source };
            match destination {
                Destination::Replace(_) => {}
                Destination::InPlace(target) => {
                    let mut file = std::fs::OpenOptions::new().write(true).open(target).map_err(error)?;
                    file.write_all(contents).and_then(|()| file.flush()).map_err(error)?;
                }
                Destination::Stdout => {
                    let mut stdout = std::io::stdout().lock();
                    stdout.write_all(contents).and_then(|()| stdout.flush()).map_err(error)?;
                }
            }
        }
        Ok(())
    }
}

/// Why the `temporary` file in `folder` could not be written, in words: the system's own
/// error names neither (`/proc/version: No such file or directory` of a file that exists).
fn beside(folder: &Path, temporary: &Path, source: std::io::Error) -> std::io::Error {
    let why = match folder.is_dir() {
        true => format!(
            "the temporary file {} could not be written beside it (an output is written there, then renamed \
             over its target): {source}",
            temporary.display()
        ),
        false => format!("no folder {}", folder.display()),
    };
    std::io::Error::new(source.kind(), why)
}

/// Create `folder` and the folders above it that are missing, recording each one created.
fn create_folders(folder: &Path, created: &mut Vec<PathBuf>) -> Result<(), OutputError> {
    let missing: Vec<&Path> =
        folder.ancestors().take_while(|p| !p.as_os_str().is_empty() && !p.exists()).collect();
    for path in missing.into_iter().rev() {
        std::fs::create_dir(path).map_err(|source| OutputError { path: path.into(), source })?;
        created.push(path.into());
    }
    Ok(())
}

/// The text of the file at `path`.
fn read(path: &Path) -> Result<String, InputError> {
    std::fs::read_to_string(path).map_err(|source| InputError::Read { path: path.into(), source })
}

/// A command that would need more memory than robocal allows itself (see [`check_memory`]).
#[derive(Debug, thiserror::Error)]
#[error(
    "{what} would need about {:.1} GiB of memory, more than {:.1} GiB ({}% of the {:.1} GiB this process may use): {advice}",
    gib(*needed), gib(*budget), (MEMORY_SHARE * 100.0).round(), gib(*machine)
)]
pub struct MemoryError {
    /// What would need it (`study paper-table1`, `plan`).
    pub what: String,
    /// The estimate (bytes).
    pub needed: u64,
    /// What may be used (bytes).
    pub budget: u64,
    /// The machine's memory, or the process's address-space limit if lower (bytes).
    pub machine: u64,
    /// What to ask for instead.
    pub advice: String,
}

fn gib(bytes: u64) -> f64 {
    bytes as f64 / f64::from(1u32 << 30)
}

/// The memory of this machine in bytes: the total memory (`MemTotal` of `/proc/meminfo`), or
/// the process's address-space limit (`ulimit -v`, `/proc/self/limits`) if lower;
/// [`FALLBACK_MEMORY`] where neither can be read.
pub fn machine_memory() -> u64 {
    let total = std::fs::read_to_string("/proc/meminfo").ok().and_then(|text| {
        let line = text.lines().find(|l| l.starts_with("MemTotal:"))?;
        let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
        Some(kib * 1024)
    });
    let limit = std::fs::read_to_string("/proc/self/limits").ok().and_then(|text| {
        let line = text.lines().find(|l| l.starts_with("Max address space"))?;
        line.split_whitespace().nth(3)?.parse::<u64>().ok()
    });
    match (total, limit) {
        (Some(t), Some(l)) => t.min(l),
        (Some(m), None) | (None, Some(m)) => m,
        (None, None) => FALLBACK_MEMORY,
    }
}

/// `Ok` if `needed` bytes are within [`MEMORY_SHARE`] of [`machine_memory`]; otherwise an error saying what would
/// need it and what to ask for instead.
pub fn check_memory(needed: u64, what: &str, advice: &str) -> Result<(), MemoryError> {
    let machine = machine_memory();
    let budget = (machine as f64 * MEMORY_SHARE) as u64;
    if needed <= budget {
        return Ok(());
    }
    Err(MemoryError { what: what.into(), needed, budget, machine, advice: advice.into() })
}

/// A study by name (`paper-table1`, see [`STUDIES`]) or from a TOML file; its `robot` field
/// is loaded by [`load_model`].
pub fn load_study(name_or_path: &str) -> Result<Study, InputError> {
    let robot = load_model;
    if let Some((_, text)) = STUDIES.iter().find(|(n, _)| *n == name_or_path) {
        return Ok(Study::from_toml_str(text, robot).expect("embedded studies are valid"));
    }
    let (path, text) = study_file(name_or_path)?;
    Study::from_toml_str(&text, robot).map_err(|source| InputError::Study { path: path.into(), source })
}

/// The path and text of the study file `name_or_path`; an error listing the embedded studies
/// where no such file exists.
fn study_file(name_or_path: &str) -> Result<(&Path, String), InputError> {
    let path = Path::new(name_or_path);
    if !path.exists() {
        let names = STUDIES.iter().chain(INSTRUMENT_STUDIES).map(|(n, _)| *n);
        let studies = names.collect::<Vec<_>>().join(", ");
        return Err(InputError::UnknownStudy { name: name_or_path.to_string(), studies });
    }
    Ok((path, read(path)?))
}

/// The instrument study named (an embedded one: [`INSTRUMENT_STUDIES`]) or in the file
/// `name_or_path`, if it is one (a file with `[[instruments]]`); `None` for any other study
/// name or file, which [`load_study`] reads.
pub fn load_instrument_study(name_or_path: &str) -> Result<Option<InstrumentStudy>, InputError> {
    let robot = load_model;
    if let Some((_, text)) = INSTRUMENT_STUDIES.iter().find(|(n, _)| *n == name_or_path) {
        return Ok(Some(InstrumentStudy::from_toml_str(text, robot).expect("embedded studies are valid")));
    }
    if STUDIES.iter().any(|(n, _)| *n == name_or_path) {
        return Ok(None);
    }
    let (path, text) = study_file(name_or_path)?;
    if !is_instrument_study(&text) {
        return Ok(None);
    }
    let study = InstrumentStudy::from_toml_str(&text, robot);
    study.map(Some).map_err(|source| InputError::Study { path: path.into(), source })
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

/// What the data file at `path` holds, from its header ([`DataKind::of_csv_str`]).
pub fn data_kind(path: &Path) -> Result<DataKind, InputError> {
    let text = read(path)?;
    DataKind::of_csv_str(&text).map_err(|source| InputError::Data { path: path.into(), source })
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
/// ([`load_urdf`]), carrying the reference's payload if it names one.
pub fn load_model(model: &ModelRef) -> Result<RobotModel, InputError> {
    let loaded = load_chain(model)?;
    Ok(match &model.payload {
        Some(payload) => loaded.with_payload(payload),
        None => loaded,
    })
}

/// The model `model` names, without its payload.
fn load_chain(model: &ModelRef) -> Result<RobotModel, InputError> {
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

/// The joint values of a pose file (or of a measurement file) for `model`, in the units of
/// its `# units:` line, else `units` given by the caller (which must agree with the line).
pub fn load_poses(
    path: &Path,
    model: &RobotModel,
    units: Option<Units>,
) -> Result<Vec<Vec<f64>>, InputError> {
    let text = read(path)?;
    crate::design::poses_from_csv_str(&text, model, units)
        .map_err(|source| InputError::Data { path: path.into(), source })
}
