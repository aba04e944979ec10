//! `robocal simulate` and `robocal reproduce`: Monte Carlo studies, their tables and figures.

use super::args::{SimulateArgs, StudyOutputArgs};
use anyhow::{Context, Result};
use indicatif::{ProgressBar, ProgressStyle};
use robocal::simulation::{self, Study};
use robocal::{io, report};
use std::time::Instant;

/// `robocal reproduce`: the paper's two studies, and where their figures are.
pub fn reproduce(output: &StudyOutputArgs) -> Result<()> {
    let started = Instant::now();
    let studies =
        ["paper-table1", "paper-table2"].map(io::load_study).into_iter().collect::<Result<Vec<_>, _>>()?;
    for study in &studies {
        run_study(study, output)?;
    }
    println!("The paper's figures: Fig. 1a-e paper-table1/histogram-wls-np{{12,24,48,96,192}}-sigma0.svg,");
    println!(
        "Fig. 2 paper-table1/improvement-vs-points-wls.svg, Fig. 3 paper-table2/improvement-vs-sigma-wls.svg,"
    );
    println!(
        "Fig. 4a-c paper-table2/histogram-wls-np48-sigma{{0.025,0.05,0.1}}.svg (and the same for wls-diag)."
    );
    println!("Both studies in {:.2} s.", started.elapsed().as_secs_f64());
    Ok(())
}

/// `robocal simulate`: one study, its noise replaced by a noise file if one is given.
pub fn simulate(args: &SimulateArgs) -> Result<()> {
    let mut study = io::load_study(&args.study)?;
    if let Some(path) = &args.noise {
        let spec = io::load_noise(path, &study.robot)?;
        study.set_noise(&spec).with_context(|| format!("{}", path.display()))?;
        study.description = format!("{} (noise from {})", study.description, path.display());
    }
    run_study(&study, &args.output)
}

/// A progress bar of `runs` runs, labelled `message`.
fn progress(runs: usize, message: String) -> ProgressBar {
    let bar = ProgressBar::new(runs as u64).with_message(message);
    bar.set_style(ProgressStyle::with_template("{msg} {bar:40} {pos}/{len} runs").expect("a valid template"));
    bar
}

/// Run `study` with a progress bar, print its tables, and write them with the CSV samples and
/// the figures into `<out>/<study name>/`; with `--replications`, the same for the study
/// replicated over that many derived seeds.
fn run_study(study: &Study, output: &StudyOutputArgs) -> Result<()> {
    let runs = study.cases.len() * study.point_sets * study.runs_per_set;
    let bar = progress(runs, study.name.clone());
    let pool = rayon::ThreadPoolBuilder::new().num_threads(output.threads.unwrap_or(0)).build()?;
    let results = pool.install(|| simulation::run(study, &|| bar.inc(1)))?;
    bar.finish_and_clear();
    let mut tables = report::study::tables(study, &results);
    if let Some(comparison) = report::study::planned_against_random(study, &results) {
        tables += &format!("\n{comparison}");
    }
    println!("{tables}");
    let mut files = vec![
        ("tables.txt".to_string(), tables),
        ("samples.csv".to_string(), report::study::samples_csv(study, &results)),
    ];
    files.extend(report::figures::study_figures(study, &results)?);
    let folder = output.out.join(&study.name);
    io::write_files(&folder, &files)?;
    println!("wrote {} files to {}\n", files.len(), folder.display());
    if let Some(count) = output.replications {
        let bar = progress(runs * count, format!("{} x {count} replications", study.name));
        let replicated = pool.install(|| simulation::replicate(study, count, &|| bar.inc(1)))?;
        bar.finish_and_clear();
        let files = report::replication::files(study, &replicated)?;
        println!("{}", files[0].1);
        io::write_files(&folder, &files)?;
        println!("wrote {} files to {}\n", files.len(), folder.display());
    }
    Ok(())
}
