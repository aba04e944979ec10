//! `robocal simulate --shard I/N` and `robocal merge`: a study spread over processes or machines.
//!
//! A shard file (`<out>/<study name>/shard-I-of-N.json`) holds what the shard computed, every
//! number as the bits of its `f64` (so that merging loses nothing), with the study as given to
//! `simulate` (name or path, noise file, replications) and a fingerprint of the study as read.
//! `merge` reads the study again, checks the fingerprint, and writes what `simulate` writes.

use super::args::{MergeArgs, SimulateArgs};
use super::simulate::{self, Loaded};
use anyhow::{Context, Result, bail};
use robocal::io;
use robocal::simulation::{self, Accuracy, InstrumentPart, Run, Scores, Shard, StudyResults};
use serde::{Deserialize, Serialize};
use std::hash::{Hash, Hasher};
use std::path::{Path, PathBuf};

/// The `format` of a shard file.
const FORMAT: &str = "robocal shard 1";

/// A shard file.
#[derive(Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct ShardFile {
    format: String,
    /// The study as given to `simulate`: a name or a path.
    study: String,
    /// The noise file as given to `simulate`.
    noise: Option<PathBuf>,
    /// The folder `simulate` ran in: relative paths are from there.
    folder: PathBuf,
    replications: Option<usize>,
    /// A hash of the study as read.
    fingerprint: String,
    index: usize,
    count: usize,
    /// An estimator study's results: the study's, then each replication's.
    results: Vec<PartFile>,
    /// An instrument study's.
    instruments: Option<InstrumentFile>,
}

/// A shard of one study's runs.
#[derive(Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct PartFile {
    /// (case, set, run, per estimator the bits of mean, rms, max, orientation)
    runs: Vec<(usize, usize, usize, Vec<[u64; 4]>)>,
    ranks: Vec<(usize, usize, usize)>,
    joint_noise_error: u64,
}

/// A shard of an instrument study's calibrations: the bits of each score's (aligned,
/// unaligned).
#[derive(Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct InstrumentFile {
    first: usize,
    scores: Vec<[u64; 2]>,
    nominal: Vec<[u64; 2]>,
}

impl PartFile {
    fn of(results: &StudyResults) -> Self {
        let bits = |a: &Accuracy| [a.mean, a.rms, a.max, a.orientation].map(f64::to_bits);
        Self {
            runs: (results.runs.iter())
                .map(|r| (r.case, r.set, r.run, r.accuracy.iter().map(bits).collect()))
                .collect(),
            ranks: results.ranks.clone(),
            joint_noise_error: results.joint_noise_error.to_bits(),
        }
    }

    fn results(&self) -> StudyResults {
        let accuracy = |b: &[u64; 4]| {
            let [mean, rms, max, orientation] = b.map(f64::from_bits);
            Accuracy { mean, rms, max, orientation }
        };
        StudyResults {
            runs: (self.runs.iter())
                .map(|(case, set, run, a)| Run {
                    case: *case,
                    set: *set,
                    run: *run,
                    accuracy: a.iter().map(accuracy).collect(),
                })
                .collect(),
            ranks: self.ranks.clone(),
            joint_noise_error: f64::from_bits(self.joint_noise_error),
        }
    }
}

fn score_bits(s: &Scores) -> [u64; 2] {
    [s.aligned.to_bits(), s.unaligned.to_bits()]
}

fn score_of(b: &[u64; 2]) -> Scores {
    Scores { aligned: f64::from_bits(b[0]), unaligned: f64::from_bits(b[1]) }
}

/// A hash of the study as read: its every field, as `Debug` prints them.
fn fingerprint(study: &dyn std::fmt::Debug) -> String {
    let mut hasher = std::collections::hash_map::DefaultHasher::new();
    format!("{study:?}").hash(&mut hasher);
    format!("{:016x}", hasher.finish())
}

/// `robocal simulate STUDY --shard I/N`.
pub fn simulate(args: &SimulateArgs, shard: Shard) -> Result<()> {
    simulate::check_outputs(args)?;
    let loaded = simulate::load(&args.study, args.noise.as_deref())?;
    let mut file = ShardFile {
        format: FORMAT.into(),
        study: args.study.clone(),
        noise: args.noise.clone(),
        folder: std::env::current_dir().context("the working folder")?,
        replications: args.output.replications,
        fingerprint: String::new(),
        index: shard.index,
        count: shard.count,
        results: Vec::new(),
        instruments: None,
    };
    let name = match &loaded {
        Loaded::Instruments(study) => {
            simulate::check_instrument_flags(study, args)?;
            let calibrations = shard.range(study.runs * study.instruments.len()).len();
            let bar = simulate::progress(calibrations, format!("{} shard {shard}", study.name));
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(simulate::threads(args.output.threads))
                .build()?;
            let part = pool.install(|| simulation::run_instruments_shard(study, shard, &|| bar.inc(1)))?;
            bar.finish_and_clear();
            file.fingerprint = fingerprint(study);
            file.instruments = Some(InstrumentFile {
                first: part.first,
                scores: part.scores.iter().map(score_bits).collect(),
                nominal: part.nominal.iter().map(score_bits).collect(),
            });
            study.name.clone()
        }
        Loaded::Study(study) => {
            let runs = shard.range(study.cases.len() * study.point_sets * study.runs_per_set).len();
            let replications = args.output.replications.unwrap_or(0);
            let bar = simulate::progress(runs * (1 + replications), format!("{} shard {shard}", study.name));
            let pool = simulate::study_pool(study, args.output.threads)?;
            let results = pool.install(|| simulation::run_shard(study, shard, &|| bar.inc(1)))?;
            file.results.push(PartFile::of(&results));
            if let Some(count) = args.output.replications {
                let replicated =
                    pool.install(|| simulation::replicate_shard(study, count, shard, &|| bar.inc(1)))?;
                file.results.extend(replicated.iter().map(PartFile::of));
            }
            bar.finish_and_clear();
            file.fingerprint = fingerprint(study);
            study.name.clone()
        }
    };
    let folder = args.output.out.join(name);
    let file_name = format!("shard-{}-of-{}.json", shard.index, shard.count);
    let mut outputs = io::Outputs::new();
    outputs.add_folder(&folder, &[(file_name.clone(), serde_json::to_string(&file)? + "\n")]);
    outputs.commit()?;
    super::status(format_args!("wrote shard {shard} to {}", folder.join(file_name).display()));
    Ok(())
}

/// The shard files among `paths`: a file as given, a folder's `shard-*-of-*.json` files and
/// those of its subfolders.
fn shard_files(paths: &[PathBuf]) -> Result<Vec<PathBuf>> {
    let is_shard = |p: &Path| {
        let name = p.file_name().and_then(|n| n.to_str()).unwrap_or_default();
        p.is_file() && name.starts_with("shard-") && name.contains("-of-") && name.ends_with(".json")
    };
    let mut files = Vec::new();
    for path in paths {
        if !path.is_dir() {
            if !path.is_file() {
                bail!("{}: no such shard file or folder", path.display());
            }
            files.push(path.clone());
            continue;
        }
        let list = |dir: &Path| -> Result<Vec<PathBuf>> {
            let mut entries = Vec::new();
            for entry in std::fs::read_dir(dir).with_context(|| format!("{}", dir.display()))? {
                entries.push(entry.with_context(|| format!("{}", dir.display()))?.path());
            }
            entries.sort();
            Ok(entries)
        };
        let mut found = Vec::new();
        for entry in list(path)? {
            if entry.is_dir() {
                found.extend(list(&entry)?.into_iter().filter(|p| is_shard(p)));
            } else if is_shard(&entry) {
                found.push(entry);
            }
        }
        if found.is_empty() {
            bail!(
                "{}: no shard files (shard-I-of-N.json, as `simulate --shard` writes) in it or its subfolders",
                path.display()
            );
        }
        files.extend(found);
    }
    Ok(files)
}

/// Read one shard file.
fn read_shard(path: &Path) -> Result<ShardFile> {
    let text = std::fs::read_to_string(path).with_context(|| format!("{}", path.display()))?;
    let file: ShardFile = serde_json::from_str(&text)
        .with_context(|| format!("{}: not a shard file of `robocal simulate --shard`", path.display()))?;
    if file.format != FORMAT {
        bail!("{}: field `format`: expected \"{FORMAT}\", found {:?}", path.display(), file.format);
    }
    Ok(file)
}

/// Every shard of one study, each once, in order; what they were computed from.
fn check_shards(files: Vec<(PathBuf, ShardFile)>) -> Result<Vec<(PathBuf, ShardFile)>> {
    let (first_path, first) = &files[0];
    let count = first.count;
    let mut by_index: Vec<Option<&Path>> = vec![None; count];
    for (path, file) in &files {
        let same = file.study == first.study
            && file.noise == first.noise
            && file.replications == first.replications
            && file.fingerprint == first.fingerprint
            && file.count == count;
        if !same {
            bail!(
                "{} and {}: shards of different runs (study, noise, replications or shard count differ): merge the shards of one `simulate --shard` study",
                first_path.display(),
                path.display()
            );
        }
        if file.index >= count {
            bail!("{}: shard {} of {count}: expected 0 to {}", path.display(), file.index, count - 1);
        }
        if let Some(other) = by_index[file.index] {
            bail!("{} and {}: both are shard {}/{count}", other.display(), path.display(), file.index);
        }
        by_index[file.index] = Some(path);
    }
    let missing: Vec<String> =
        (0..count).filter(|&i| by_index[i].is_none()).map(|i| format!("{i}/{count}")).collect();
    if !missing.is_empty() {
        bail!("study {}: shards missing: {} (given: {} files)", first.study, missing.join(", "), files.len());
    }
    let mut files = files;
    files.sort_by_key(|(_, f)| f.index);
    Ok(files)
}

/// A path as given to `simulate` in `folder`: relative paths are from there.
fn from_folder(folder: &Path, given: &Path) -> PathBuf {
    let there = folder.join(given);
    if given.is_relative() && there.exists() { there } else { given.to_path_buf() }
}

/// `robocal merge DIR...`.
pub fn merge(args: &MergeArgs) -> Result<()> {
    let paths = shard_files(&args.shards)?;
    let files = paths.into_iter().map(|p| read_shard(&p).map(|f| (p, f))).collect::<Result<Vec<_>>>()?;
    let files = check_shards(files)?;
    let first = &files[0].1;
    let study_path = from_folder(&first.folder, Path::new(&first.study));
    let study_arg =
        if study_path.exists() { study_path.to_string_lossy().into_owned() } else { first.study.clone() };
    let noise = first.noise.as_deref().map(|n| from_folder(&first.folder, n));
    let changed = |name: &str| {
        anyhow::anyhow!(
            "study {name}: it is not the study the shards computed (its file, its noise file or robocal changed since): run the shards again"
        )
    };
    match load_as_given(&study_arg, noise.as_deref(), first.noise.as_deref())? {
        Loaded::Instruments(study) => {
            if fingerprint(&study) != first.fingerprint {
                return Err(changed(&study.name));
            }
            let parts = files.iter().map(|(path, f)| match &f.instruments {
                Some(i) => Ok(InstrumentPart {
                    first: i.first,
                    scores: i.scores.iter().map(score_of).collect(),
                    nominal: i.nominal.iter().map(score_of).collect(),
                }),
                None => bail!("{}: no instrument results in it", path.display()),
            });
            let parts = parts.collect::<Result<Vec<_>>>()?;
            let Some(results) = simulation::InstrumentResults::merge(&study, parts) else {
                bail!("study {}: the shards do not hold each calibration once", study.name);
            };
            simulate::write_instruments(&study, &results, &args.out)
        }
        Loaded::Study(study) => {
            if fingerprint(&study) != first.fingerprint {
                return Err(changed(&study.name));
            }
            let parts = 1 + first.replications.unwrap_or(0);
            if let Some((path, _)) = files.iter().find(|(_, f)| f.results.len() != parts) {
                bail!(
                    "{}: expected the results of {parts} studies (the study and its replications)",
                    path.display()
                );
            }
            let merged = |p: usize| StudyResults::merge(files.iter().map(|(_, f)| f.results[p].results()));
            let results = merged(0);
            let runs = study.cases.len() * study.point_sets * study.runs_per_set;
            if results.runs.len() != runs {
                bail!("study {}: the shards hold {} of its {runs} runs", study.name, results.runs.len());
            }
            let replicated = first.replications.map(|count| {
                let all: Vec<StudyResults> = (1..=count).map(merged).collect();
                simulation::Replications::of_results(&study, &all)
            });
            let mut outputs = io::Outputs::new();
            let written =
                simulate::stage_study(&study, &results, replicated.as_ref(), &args.out, &mut outputs)?;
            outputs.commit()?;
            super::status(written);
            Ok(())
        }
    }
}

/// [`simulate::load`] of the study and noise found at `study` and `noise`, the noise named
/// in the description as `given` was (as `simulate` named it).
fn load_as_given(study: &str, noise: Option<&Path>, given: Option<&Path>) -> Result<Loaded> {
    let mut loaded = simulate::load(study, noise)?;
    if let (Loaded::Study(study), Some(noise), Some(given)) = (&mut loaded, noise, given) {
        study.description = study.description.replace(
            &format!("(noise from {})", noise.display()),
            &format!("(noise from {})", given.display()),
        );
    }
    Ok(loaded)
}
