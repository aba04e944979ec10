//! `robocal simulate` and `robocal reproduce`: Monte Carlo studies, their tables and figures.

use super::args::{SimulateArgs, StudyOutputArgs};
use anyhow::{Context, Result};
use indicatif::{ProgressBar, ProgressStyle};
use robocal::simulation::{self, InstrumentStudy, Study};
use robocal::{io, report};
use std::path::Path;
use std::time::Instant;

/// `robocal reproduce`: the paper's two studies, and where their figures are.
pub fn reproduce(output: &StudyOutputArgs) -> Result<()> {
    let started = Instant::now();
    let studies =
        ["paper-table1", "paper-table2"].map(io::load_study).into_iter().collect::<Result<Vec<_>, _>>()?;
    let mut outputs = io::Outputs::new();
    let written =
        studies.iter().map(|study| run_study(study, output, &mut outputs)).collect::<Result<Vec<_>>>()?;
    outputs.commit()?;
    for line in written {
        super::status(line);
    }
    super::status("");
    super::status(
        "The paper's figures: Fig. 1a-e paper-table1/histogram-wls-np{12,24,48,96,192}-sigma0.svg,",
    );
    super::status(
        "Fig. 2 paper-table1/improvement-vs-points-wls.svg, Fig. 3 paper-table2/improvement-vs-sigma-wls.svg,",
    );
    super::status(
        "Fig. 4a-c paper-table2/histogram-wls-np48-sigma{0.025,0.05,0.1}.svg (and the same for wls-diag).",
    );
    super::status(format_args!("Both studies in {:.2} s.", started.elapsed().as_secs_f64()));
    Ok(())
}

/// Refuse a `simulate` whose `--out` folder would take an input's place.
pub(super) fn check_outputs(args: &SimulateArgs) -> Result<()> {
    let mut inputs = vec![("the study", Path::new(&args.study))];
    inputs.extend(args.noise.as_deref().map(|p| ("--noise", p)));
    // `<out>/<study name>/`: tables and replications (.txt), samples (.csv), figures (.svg).
    let writes: fn(&str) -> bool = |name| [".txt", ".csv", ".svg"].iter().any(|e| name.ends_with(e));
    super::request::distinct_outputs_and_folders(&inputs, &[], &[("--out", Some(&args.output.out), writes)])?;
    Ok(())
}

/// `robocal simulate` without `--shard`: one study, its noise replaced by a noise file if one
/// is given; or an instrument study (`instruments`, a file with `[[instruments]]`).
pub fn simulate(args: &SimulateArgs) -> Result<()> {
    check_outputs(args)?;
    match load(&args.study, args.noise.as_deref())? {
        Loaded::Instruments(study) => instruments(&study, args),
        Loaded::Study(study) => {
            let mut outputs = io::Outputs::new();
            let written = run_study(&study, &args.output, &mut outputs)?;
            outputs.commit()?;
            super::status(written);
            Ok(())
        }
    }
}

/// A study as `simulate` reads it.
pub(super) enum Loaded {
    /// An instrument study.
    Instruments(Box<InstrumentStudy>),
    /// An estimator study, its noise replaced by the noise file's if one is given.
    Study(Box<Study>),
}

/// The study named or in the file `study`, its noise replaced by the file `noise` if given.
pub(super) fn load(study: &str, noise: Option<&Path>) -> Result<Loaded> {
    if let Some(study) = io::load_instrument_study(study)? {
        return Ok(Loaded::Instruments(Box::new(study)));
    }
    let mut study = io::load_study(study)?;
    if let Some(path) = noise {
        let spec = io::load_noise(path, &study.robot)?;
        study.set_noise(&spec).with_context(|| format!("{}", path.display()))?;
        study.description = format!("{} (noise from {})", study.description, path.display());
    }
    Ok(Loaded::Study(Box::new(study)))
}

/// `robocal simulate` of an instrument study: its table printed, and with the samples staged
/// for `<out>/<study name>/`. `--noise` and `--replications` are for the other studies.
fn instruments(study: &InstrumentStudy, args: &SimulateArgs) -> Result<()> {
    check_instrument_flags(study, args)?;
    let calibrations = study.runs * study.instruments.len();
    let bar = progress(calibrations, study.name.clone());
    let pool = rayon::ThreadPoolBuilder::new().num_threads(threads(args.output.threads)).build()?;
    let results = pool.install(|| simulation::run_instruments(study, &|| bar.inc(1)))?;
    bar.finish_and_clear();
    write_instruments(study, &results, &args.output.out)
}

/// `--noise` and `--replications` are for the other studies.
pub(super) fn check_instrument_flags(study: &InstrumentStudy, args: &SimulateArgs) -> Result<()> {
    for (flag, given) in
        [("--noise", args.noise.is_some()), ("--replications", args.output.replications.is_some())]
    {
        if given {
            let message =
                format!("{flag} is for estimator studies; study {} compares instruments", study.name);
            return Err(super::request::UsageError(message).into());
        }
    }
    Ok(())
}

/// Print an instrument study's table and write it with the samples to `<out>/<study name>/`.
pub(super) fn write_instruments(
    study: &InstrumentStudy,
    results: &simulation::InstrumentResults,
    out: &Path,
) -> Result<()> {
    let table = report::instruments::table(study, results);
    println!("{table}");
    let files = vec![
        ("tables.txt".to_string(), table),
        ("samples.csv".to_string(), report::instruments::samples_csv(study, results)),
    ];
    let folder = out.join(&study.name);
    let mut outputs = io::Outputs::new();
    outputs.add_folder(&folder, &files);
    outputs.commit()?;
    super::status(format_args!("wrote {} files to {}", files.len(), folder.display()));
    Ok(())
}

/// A progress bar of `runs` runs, labelled `message`.
pub(super) fn progress(runs: usize, message: String) -> ProgressBar {
    if super::quiet() {
        return ProgressBar::hidden();
    }
    let bar = ProgressBar::new(runs as u64).with_message(message);
    let template = "{msg} {bar:40} {pos}/{len} runs, {elapsed} so far, about {eta} left";
    bar.set_style(ProgressStyle::with_template(template).expect("a valid template"));
    bar
}

/// The worker threads: `--threads`, at most the machine's cores (with a note), or all of them.
pub(super) fn threads(requested: Option<usize>) -> usize {
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    match requested {
        Some(n) if n > cores => {
            super::status(format_args!("note: --threads {n}: this machine has {cores} cores, using {cores}"));
            cores
        }
        Some(n) if n > 0 => n,
        _ => cores,
    }
}

/// Run `study` with a progress bar, print its tables, and stage them with the CSV samples and
/// the figures for `<out>/<study name>/` in `outputs` (with `--replications`, those of the
/// study replicated over that many derived seeds too); what to say once they are written.
fn run_study(study: &Study, output: &StudyOutputArgs, outputs: &mut io::Outputs) -> Result<String> {
    let runs = study.cases.len() * study.point_sets * study.runs_per_set;
    if let Some(count) = output.replications {
        check_replications(study, count)?;
    }
    let bar = progress(runs, study.name.clone());
    let pool = study_pool(study, output.threads)?;
    let results = pool.install(|| simulation::run(study, &|| bar.inc(1)))?;
    bar.finish_and_clear();
    let replicated = match output.replications {
        Some(count) => {
            let bar = progress(runs * count, format!("{} x {count} replications", study.name));
            let replicated = pool.install(|| simulation::replicate(study, count, &|| bar.inc(1)))?;
            bar.finish_and_clear();
            Some(replicated)
        }
        None => None,
    };
    stage_study(study, &results, replicated.as_ref(), &output.out, outputs)
}

/// The thread pool for `study` on `threads` threads (default: all cores), once its memory is
/// known to fit.
pub(super) fn study_pool(study: &Study, threads: Option<usize>) -> Result<rayon::ThreadPool> {
    let threads = self::threads(threads);
    let what = format!("study {}", study.name);
    io::check_memory(
        study.memory_estimate(threads),
        &what,
        "ask for fewer test_points, points, point sets or runs",
    )?;
    Ok(rayon::ThreadPoolBuilder::new().num_threads(threads).build()?)
}

/// Print `study`'s tables and stage them with the CSV samples and the figures for
/// `<out>/<study name>/` in `outputs`, with the replications' files if any; what to say once
/// they are written.
pub(super) fn stage_study(
    study: &Study,
    results: &simulation::StudyResults,
    replicated: Option<&simulation::Replications>,
    out: &Path,
    outputs: &mut io::Outputs,
) -> Result<String> {
    let mut tables = report::study::tables(study, results);
    if let Some(comparison) = report::study::planned_against_random(study, results) {
        tables += &format!("\n{comparison}");
    }
    println!("{tables}");
    let mut files = vec![
        ("tables.txt".to_string(), tables),
        ("samples.csv".to_string(), report::study::samples_csv(study, results)),
    ];
    files.extend(report::figures::study_figures(study, results)?);
    let folder = out.join(&study.name);
    outputs.add_folder(&folder, &files);
    let mut written = format!("wrote {} files to {}", files.len(), folder.display());
    if let Some(replicated) = replicated {
        let files = report::replication::files(study, replicated)?;
        println!("{}", files[0].1);
        outputs.add_folder(&folder, &files);
        written += &format!("\nwrote {} replication files to {}", files.len(), folder.display());
    }
    Ok(written)
}

/// Refuse `count` replications of `study` beyond [`robocal::limits::MAX_STUDY_WORK`]
/// kinematic evaluations, with the estimate.
fn check_replications(study: &Study, count: usize) -> Result<()> {
    let work = study.work().saturating_mul(count as u64);
    if work > robocal::limits::MAX_STUDY_WORK {
        anyhow::bail!(
            "--replications {count}: study {} replicated would take about {work:.1e} kinematic evaluations \
             (replications x runs x (points + test_points)), more than {:.0e}: ask for fewer replications or a \
             smaller study",
            study.name,
            robocal::limits::MAX_STUDY_WORK as f64
        );
    }
    Ok(())
}
