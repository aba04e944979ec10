//! Reports of a simulated study: the paper's tables beside the paper's values, and every
//! sample as CSV.

use crate::simulation::{Study, StudyResults, Summary};
use std::fmt::Write;

/// The study's tables in the paper's format (MEAN, SD, LOWEST, HIGHEST, % ABOVE ZERO of dE),
/// one table per compared estimator, with the 95% confidence interval of each mean, the mean
/// `E_p` of both estimators, and the paper's row where the study has one.
pub fn tables(study: &Study, results: &StudyResults) -> String {
    let mut out = String::new();
    let baseline = study.estimators[0];
    let _ = writeln!(out, "{}: {}", study.name, study.description);
    let _ = writeln!(
        out,
        "{} point sets x {} runs per case, {} test points, seed {}, {} of {} parameters identified by {}",
        study.point_sets,
        study.runs_per_set,
        study.test_points,
        study.seed,
        study.selection.len(),
        study.robot.params().len(),
        if study.iterations == 1 {
            "one linear step".to_string()
        } else {
            format!("up to {} steps", study.iterations)
        },
    );
    let ranks: Vec<usize> = results.ranks.iter().map(|r| r.2).collect();
    let (low, high) = (ranks.iter().min().unwrap_or(&0), ranks.iter().max().unwrap_or(&0));
    let rank = if low == high { format!("{low}") } else { format!("{low} to {high}") };
    let _ = writeln!(out, "numerical rank of H: {rank} (of {} columns)", study.selection.len());
    let _ = writeln!(
        out,
        "joint noise alone: mean position error {:.4} mm over the test set",
        results.joint_noise_error
    );
    if let Some(device) = &study.device {
        let _ = writeln!(out, "measurement device: {}, plus each case's sigma_me", device.describe());
    }
    for (e, estimator) in study.estimators.iter().enumerate().skip(1) {
        let _ = writeln!(out, "\ndE (%) = 100 (E_p[{baseline}] - E_p[{estimator}]) / E_p[{baseline}]");
        let _ = writeln!(
            out,
            "{:>5} {:>9} {:>10} {:>10} | {:>6} {:>7} {:>6} {:>7} {:>7} {:>6} | {:>6} {:>6} {:>7} {:>7} {:>6}",
            "N_p",
            "sigma_me",
            format!("E_p {baseline}"),
            format!("E_p {estimator}"),
            "MEAN",
            "95% CI",
            "SD",
            "LOWEST",
            "HIGHEST",
            "% > 0",
            "paper",
            "SD",
            "LOWEST",
            "HIGHEST",
            "% > 0"
        );
        let _ = writeln!(out, "{:>5} {:>9} {:>10} {:>10} |", "", "mm", "mm", "mm");
        for (c, case) in study.cases.iter().enumerate() {
            let s = Summary::of(&results.improvements(c, e));
            let _ = write!(
                out,
                "{:>5} {:>9.3} {:>10.5} {:>10.5} | {:>6.2} {:>7} {:>6.2} {:>7.1} {:>7.1} {:>6.1} |",
                case.points,
                case.sigma_me,
                results.mean_error(c, 0),
                results.mean_error(c, e),
                s.mean,
                format!("±{:.2}", s.ci95),
                s.sd,
                s.lowest,
                s.highest,
                s.above_zero
            );
            match study.reference_for(case) {
                Some(r) => {
                    let _ = writeln!(
                        out,
                        " {:>6.2} {:>6.2} {:>7.1} {:>7.1} {:>6.1}",
                        r.mean, r.sd, r.lowest, r.highest, r.above_zero
                    );
                }
                None => out.push('\n'),
            }
        }
    }
    out
}

/// Every run as a CSV row: the case, set and run; `E_p` mean, RMS and max (mm) and `E_r`
/// (deg, empty for position studies) of each estimator; and dE (%) of each compared one.
pub fn samples_csv(study: &Study, results: &StudyResults) -> String {
    let mut header =
        vec!["study".to_string(), "n_points".into(), "sigma_me_mm".into(), "set".into(), "run".into()];
    for e in &study.estimators {
        for column in ["e_p_mean_mm", "e_p_rms_mm", "e_p_max_mm", "e_r_mean_deg"] {
            header.push(format!("{e}_{column}"));
        }
    }
    for e in &study.estimators[1..] {
        header.push(format!("de_{e}_percent"));
    }
    let mut out = header.join(",") + "\n";
    for run in &results.runs {
        let case = &study.cases[run.case];
        let mut row = vec![
            study.name.clone(),
            case.points.to_string(),
            case.sigma_me.to_string(),
            run.set.to_string(),
            run.run.to_string(),
        ];
        for a in &run.accuracy {
            let orientation =
                if a.orientation.is_nan() { String::new() } else { a.orientation.to_degrees().to_string() };
            row.extend([a.mean.to_string(), a.rms.to_string(), a.max.to_string(), orientation]);
        }
        for e in 1..study.estimators.len() {
            row.push(run.improvement(e).to_string());
        }
        out += &(row.join(",") + "\n");
    }
    out
}
