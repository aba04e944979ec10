//! Reports of a simulated study: the paper's tables beside the paper's values, and every
//! sample as CSV.

use crate::simulation::{Case, Compared, PoseChoice, Study, StudyResults, Summary};
use std::fmt::Write;

/// The study's tables in the paper's format (MEAN, SD, LOWEST, HIGHEST, % ABOVE ZERO of dE),
/// one table per compared estimator, with the 95% confidence intervals of each mean and share
/// (clustered by point set: [`Summary::of_sets`]), the mean `E_p` of both estimators, and the
/// paper's row where the study has one.
pub fn tables(study: &Study, results: &StudyResults) -> String {
    let mut out = String::new();
    preamble(&mut out, study, results);
    let poses = poses_column(study);
    for (e, estimator) in study.estimators.iter().enumerate().skip(1) {
        table_header(&mut out, study, estimator, &poses);
        for (c, case) in study.cases.iter().enumerate() {
            case_row(&mut out, study, results, (c, case), e, &poses);
        }
    }
    out
}

/// The `poses` column of a study's tables: `text` right-aligned in 8 characters and a space
/// when some case plans its poses, else nothing (a study of random poses only has no such
/// column).
pub(super) fn poses_column(study: &Study) -> impl Fn(&str) -> String {
    let planned = study.cases.iter().any(|c| c.poses != PoseChoice::Random);
    move |text: &str| if planned { format!("{text:>8} ") } else { String::new() }
}

/// The lines above the tables: the study's name and description, its size, seed and
/// estimate, the numerical rank of `H` over the runs, the error of the joint noise alone, and
/// the measuring device.
fn preamble(out: &mut String, study: &Study, results: &StudyResults) {
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
    if study.estimators.iter().any(|c| c.compliance || c.play) {
        let _ = writeln!(
            out,
            "a +compliance (+play) calibration identifies the joints' compliances (plays) too, those of the joints \
             gravity loads"
        );
    }
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
}

/// The title of `estimator`'s table, `dE (%) = 100 (E_p[baseline] - E_p[estimator]) /
/// E_p[baseline]`, and its column heads with their units.
fn table_header(out: &mut String, study: &Study, estimator: &Compared, poses: &impl Fn(&str) -> String) {
    let baseline = study.estimators[0];
    let _ = writeln!(out, "\ndE (%) = 100 (E_p[{baseline}] - E_p[{estimator}]) / E_p[{baseline}]");
    *out += &poses("poses");
    let _ = writeln!(
        out,
        "{:>5} {:>9} {:>10} {:>10} | {:>6} {:>7} {:>6} {:>7} {:>7} {:>6} {:>11} | {:>6} {:>6} {:>7} {:>7} {:>6}",
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
        "95% CI",
        "paper",
        "SD",
        "LOWEST",
        "HIGHEST",
        "% > 0"
    );
    *out += &poses("");
    let _ = writeln!(out, "{:>5} {:>9} {:>10} {:>10} |", "", "mm", "mm", "mm");
}

/// Case `c`'s row of estimator `e`'s table: the mean `E_p` of the baseline and of `e`, the
/// [`Summary::of_sets`] of dE with its intervals, and the paper's row where there is one.
fn case_row(
    out: &mut String,
    study: &Study,
    results: &StudyResults,
    (c, case): (usize, &Case),
    e: usize,
    poses: &impl Fn(&str) -> String,
) {
    let s = Summary::of_sets(&results.improvements_by_set(c, e));
    *out += &poses(case.poses.name());
    let _ = write!(
        out,
        "{:>5} {:>9.3} {:>10.5} {:>10.5} | {:>6.2} {:>7} {:>6.2} {:>7.1} {:>7.1} {:>6.1} {:>11} |",
        case.points,
        case.sigma_me,
        results.mean_error(c, 0),
        results.mean_error(c, e),
        s.mean,
        mean_interval(&s),
        s.sd,
        s.lowest,
        s.highest,
        s.above_zero,
        share_interval(&s)
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

/// Planned against random poses, for every case with both: for each estimator the mean `E_p`
/// of each and the reduction `100 (E_p[random] - E_p[planned]) / E_p[random]` run by run (the
/// two cases share their real robots and noise draws), with its 95% confidence interval
/// (clustered by point set) and the share of runs the planned poses won, with its interval.
/// `None` if the study has no such pair.
pub fn planned_against_random(study: &Study, results: &StudyResults) -> Option<String> {
    let mut out = String::new();
    let _ = writeln!(
        out,
        "Planned against random poses: E_p reduction (%) = 100 (E_p[random] - E_p[planned]) / E_p[random],\n\
         run by run (same real robots and noise draws)"
    );
    let _ = writeln!(
        out,
        "{:>5} {:>9} {:>9} {:>10} {:>10} | {:>6} {:>7} {:>6} {:>7} {:>7} {:>6} {:>11}",
        "N_p",
        "sigma_me",
        "estimator",
        "E_p random",
        "planned",
        "MEAN",
        "95% CI",
        "SD",
        "LOWEST",
        "HIGHEST",
        "% > 0",
        "95% CI"
    );
    let _ = writeln!(out, "{:>5} {:>9} {:>9} {:>10} {:>10} |", "", "mm", "", "mm", "mm");
    let mut pairs = 0;
    for (p, case) in study.cases.iter().enumerate().filter(|(_, c)| c.poses != PoseChoice::Random) {
        let Some(r) = study.cases.iter().position(|c| {
            c.poses == PoseChoice::Random && c.points == case.points && c.sigma_me == case.sigma_me
        }) else {
            continue;
        };
        pairs += 1;
        let runs = |c: usize| results.runs.iter().filter(move |run| run.case == c);
        for (e, estimator) in study.estimators.iter().enumerate() {
            let mut reductions: Vec<Vec<f64>> = vec![Vec::new(); study.point_sets];
            for (random, planned) in runs(r).zip(runs(p)) {
                debug_assert_eq!((random.set, random.run), (planned.set, planned.run));
                reductions[random.set]
                    .push(crate::simulation::improvement(random.accuracy[e].mean, planned.accuracy[e].mean));
            }
            let s = Summary::of_sets(&reductions);
            let _ = writeln!(
                out,
                "{:>5} {:>9.3} {:>9} {:>10.5} {:>10.5} | {:>6.2} {:>7} {:>6.2} {:>7.1} {:>7.1} {:>6.1} {:>11}",
                case.points,
                case.sigma_me,
                estimator.to_string(),
                results.mean_error(r, e),
                results.mean_error(p, e),
                s.mean,
                mean_interval(&s),
                s.sd,
                s.lowest,
                s.highest,
                s.above_zero,
                share_interval(&s)
            );
        }
    }
    (pairs > 0).then_some(out)
}

/// The 95% interval of the share above zero, as `low-high` (%).
fn share_interval(s: &Summary) -> String {
    let (low, high) = s.above_zero_ci;
    if low.is_nan() { "-".into() } else { format!("{low:.1}-{high:.1}") }
}

/// The half-width of the 95% interval of the mean, as `±h`; `-` without one (one point set).
fn mean_interval(s: &Summary) -> String {
    if s.ci95.is_nan() { "-".into() } else { format!("±{:.2}", s.ci95) }
}

/// Every run as a CSV row: the case, set and run; `E_p` mean, RMS and max (mm) and `E_r`
/// (deg, empty for position studies) of each estimator; and dE (%) of each compared one.
pub fn samples_csv(study: &Study, results: &StudyResults) -> String {
    let planned = study.cases.iter().any(|c| c.poses != PoseChoice::Random);
    let mut header =
        vec!["study".to_string(), "n_points".into(), "sigma_me_mm".into(), "set".into(), "run".into()];
    if planned {
        header.insert(3, "poses".into());
    }
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
        if planned {
            row.insert(3, case.poses.name().to_string());
        }
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
