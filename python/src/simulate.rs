//! `robocal.simulate`: a Monte Carlo study of the library's simulation, its samples as arrays
//! and as the command line's CSV.

use crate::errors::{self, Kind};
use indicatif::{ProgressBar, ProgressStyle};
use numpy::{PyArray1, PyArray2};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use robocal::simulation::{self, STUDIES};
use std::io::IsTerminal;

/// The names of the preset studies.
#[pyfunction]
pub fn studies() -> Vec<&'static str> {
    STUDIES.iter().map(|(n, _)| *n).collect()
}

/// The command line's progress bar of `runs` runs, on standard error when it is a terminal
/// (hidden otherwise, and when `quiet`).
fn progress(runs: usize, name: &str, quiet: bool) -> ProgressBar {
    if quiet || !std::io::stderr().is_terminal() {
        return ProgressBar::hidden();
    }
    let bar = ProgressBar::new(runs as u64).with_message(name.to_string());
    let template = "{msg} {bar:40} {pos}/{len} runs, {elapsed} so far, about {eta} left";
    bar.set_style(ProgressStyle::with_template(template).expect("a valid template"));
    bar
}

/// Run the study named `study` (a preset or a TOML file) on `threads` threads (all cores by
/// default; the results are the same on any number), its noise replaced by the noise file
/// `noise` if given, with the command line's progress bar on a terminal unless `quiet`. Returns a dict: `name`, `estimators`, `tables` and `samples_csv` (the
/// command line's `tables.txt` and `samples.csv`), and per run `n_points`, `sigma_me_mm`,
/// `set`, `run` (arrays) and `e_p_mean_mm`, `e_p_rms_mm`, `e_p_max_mm`, `e_r_mean_deg` (runs x
/// estimators) and `de_percent` (runs x compared estimators).
#[pyfunction]
#[pyo3(signature = (study, threads=None, noise=None, quiet=false))]
pub fn simulate<'py>(
    py: Python<'py>,
    study: &str,
    threads: Option<usize>,
    noise: Option<&str>,
    quiet: bool,
) -> PyResult<Bound<'py, PyDict>> {
    let mut study = robocal::io::load_study(study).map_err(|e| errors::from_error(Kind::Input, &e, None))?;
    if let Some(path) = noise {
        let spec = robocal::io::load_noise(std::path::Path::new(path), &study.robot)
            .map_err(|e| errors::from_error(Kind::Input, &e, None))?;
        study.set_noise(&spec).map_err(|e| errors::from_error(Kind::Input, &e, Some(path)))?;
        study.description = format!("{} (noise from {path})", study.description);
    }
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    let threads = threads.filter(|&n| n > 0).unwrap_or(cores).min(cores);
    robocal::io::check_memory(
        study.memory_estimate(threads),
        &format!("study {}", study.name),
        "ask for fewer test_points, points, point sets or runs",
    )
    .map_err(|e| errors::from_error(Kind::Input, &e, None))?;
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .map_err(|e| errors::input(format!("threads: {e}")))?;
    let bar = progress(study.cases.len() * study.point_sets * study.runs_per_set, &study.name, quiet);
    let results = py
        .detach(|| pool.install(|| simulation::run(&study, &|| bar.inc(1))))
        .map_err(|e| errors::from_error(Kind::Estimation, &e, Some(&study.name)))?;
    bar.finish_and_clear();
    let mut tables = robocal::report::study::tables(&study, &results);
    if let Some(comparison) = robocal::report::study::planned_against_random(&study, &results) {
        tables += &format!("\n{comparison}");
    }
    let out = PyDict::new(py);
    out.set_item("name", &study.name)?;
    out.set_item("estimators", study.estimators.iter().map(|e| e.to_string()).collect::<Vec<_>>())?;
    out.set_item("tables", tables)?;
    out.set_item("samples_csv", robocal::report::study::samples_csv(&study, &results))?;
    let runs = &results.runs;
    let case =
        |f: fn(&simulation::Case) -> f64| runs.iter().map(|r| f(&study.cases[r.case])).collect::<Vec<_>>();
    out.set_item("n_points", PyArray1::from_vec(py, case(|c| c.points as f64)))?;
    out.set_item("sigma_me_mm", PyArray1::from_vec(py, case(|c| c.sigma_me)))?;
    out.set_item("set", PyArray1::from_vec(py, runs.iter().map(|r| r.set).collect()))?;
    out.set_item("run", PyArray1::from_vec(py, runs.iter().map(|r| r.run).collect()))?;
    let per = |f: fn(&simulation::Accuracy) -> f64| {
        let rows: Vec<Vec<f64>> = runs.iter().map(|r| r.accuracy.iter().map(f).collect()).collect();
        PyArray2::from_vec2(py, &rows).expect("one value per estimator")
    };
    out.set_item("e_p_mean_mm", per(|a| a.mean))?;
    out.set_item("e_p_rms_mm", per(|a| a.rms))?;
    out.set_item("e_p_max_mm", per(|a| a.max))?;
    out.set_item("e_r_mean_deg", per(|a| a.orientation.to_degrees()))?;
    let de: Vec<Vec<f64>> =
        runs.iter().map(|r| (1..study.estimators.len()).map(|e| r.improvement(e)).collect()).collect();
    out.set_item("de_percent", PyArray2::from_vec2(py, &de).expect("one value per compared estimator"))?;
    Ok(out)
}
