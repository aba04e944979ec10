//! The table of an instrument study ([`crate::simulation::run_instruments`]) and its samples.

use crate::simulation::{InstrumentResults, InstrumentStudy, stats_interval};
use std::fmt::Write;

/// The study's table: per instrument its kind, noise, time per observation, observations in
/// the budget, the mean `E_p` after rigid alignment with its 95 % interval, the paired
/// difference against the first instrument with its interval, and the mean error without
/// alignment; then the nominal robot's error.
pub fn table(study: &InstrumentStudy, results: &InstrumentResults) -> String {
    let mut out = String::new();
    let _ = writeln!(out, "{}: {}", study.name, study.description);
    let _ = writeln!(
        out,
        "{} runs (real robots, shared by every instrument), {} test points, seed {}, {} s of measurement each",
        study.runs, study.test_points, study.seed, study.time_budget
    );
    let _ = writeln!(out, "E_p: mean position error over the test set after the best rigid alignment (mm)");
    let first = &study.instruments[0].name;
    let _ = writeln!(
        out,
        "{:<16} {:<9} {:>9} {:>7} {:>6}  {:>18}  {:>20}  {:>10}",
        "instrument",
        "kind",
        "sigma mm",
        "s/obs",
        "obs",
        "E_p mm (95% CI)",
        "vs first mm (95% CI)",
        "unaligned"
    );
    for (i, instrument) in study.instruments.iter().enumerate() {
        let (mean, half) = results.mean_error(i);
        let paired = match i {
            0 => "-".to_string(),
            _ => {
                let (d, h) = results.paired_difference(i);
                format!("{d:+.4} +- {h:.4}")
            }
        };
        let unaligned: Vec<f64> = results.scores.iter().map(|r| r[i].unaligned).collect();
        let _ = writeln!(
            out,
            "{:<16} {:<9} {:>9.4} {:>7.1} {:>6}  {:>18}  {:>20}  {:>10.4}",
            instrument.name,
            instrument.kind.name(),
            instrument.sigma,
            instrument.seconds,
            study.observations(i),
            format!("{mean:.4} +- {half:.4}"),
            paired,
            stats_interval(&unaligned).0,
        );
    }
    let aligned: Vec<f64> = results.nominal.iter().map(|s| s.aligned).collect();
    let _ = writeln!(
        out,
        "nominal robot (uncalibrated): E_p {:.4} mm; paired differences against {first}",
        stats_interval(&aligned).0
    );
    out
}

/// One line per run and instrument: `run,instrument,observations,e_p_aligned_mm,e_p_mm`.
pub fn samples_csv(study: &InstrumentStudy, results: &InstrumentResults) -> String {
    let mut out = String::from("run,instrument,observations,e_p_aligned_mm,e_p_mm\n");
    for (r, scores) in results.scores.iter().enumerate() {
        for (i, s) in scores.iter().enumerate() {
            let name = &study.instruments[i].name;
            let _ = writeln!(
                out,
                "{},{name},{},{:.6},{:.6}",
                r + 1,
                study.observations(i),
                s.aligned,
                s.unaligned
            );
        }
    }
    out
}
