//! Reports of a replicated study: each statistic of the paper's tables over the replications,
//! with the paper's value and where it falls, and how often one study's intervals hold.

use super::figures::{FigureError, replication_figures};
use super::study::poses_column;
use crate::simulation::{Case, Compared, Replications, Statistic, Study};
use std::fmt::Write;

/// For each compared estimator and case, each statistic of the paper's table (MEAN, SD,
/// LOWEST, HIGHEST, % > 0 of dE) over the replications: its mean, SD and central 95% range,
/// the paper's value and its percentile among the replications; then how often one study's
/// 95% intervals of MEAN and % > 0 contain the mean over the replications, clustered by point
/// set (as the tables print them) and with the runs taken as independent.
pub fn tables(study: &Study, replications: &Replications) -> String {
    let mut out = String::new();
    preamble(&mut out, study, replications);
    let poses = poses_column(study);
    for (e, estimator) in study.estimators.iter().enumerate().skip(1) {
        spread_header(&mut out, study, estimator, &poses);
        for (c, case) in study.cases.iter().enumerate() {
            for (i, &statistic) in Statistic::ALL.iter().enumerate() {
                spread_row(&mut out, study, replications, (c, case), e, (i, statistic), &poses);
            }
        }
        coverage_header(&mut out, replications.replications.len(), &poses);
        for (c, case) in study.cases.iter().enumerate() {
            coverage_row(&mut out, replications, (c, case), e, &poses);
        }
    }
    out
}

/// The lines above the tables: the replications, their seeds, and each one's size.
fn preamble(out: &mut String, study: &Study, replications: &Replications) {
    let count = replications.replications.len();
    let _ = writeln!(
        out,
        "{} over {count} replications: master seeds derived from the study's seed {} (replications.csv lists them),",
        study.name, replications.seed
    );
    let _ = writeln!(
        out,
        "each replication {} point sets x {} runs per case and {} test points of its own",
        study.point_sets, study.runs_per_set, study.test_points
    );
}

/// The title of `estimator`'s table of the statistics over the replications, `dE (%) = 100
/// (E_p[baseline] - E_p[estimator]) / E_p[baseline]`, and its column heads with their units.
fn spread_header(out: &mut String, study: &Study, estimator: &Compared, poses: &impl Fn(&str) -> String) {
    let baseline = study.estimators[0];
    let _ = writeln!(
        out,
        "\ndE (%) = 100 (E_p[{baseline}] - E_p[{estimator}]) / E_p[{baseline}]: the table's statistics over the replications"
    );
    *out += &poses("poses");
    let _ = writeln!(
        out,
        "{:>5} {:>9} {:<9} | {:>6} {:>6} {:>7} {:>7} | {:>6} {:>10}",
        "N_p", "sigma_me", "statistic", "mean", "SD", "2.5%", "97.5%", "paper", "percentile"
    );
    *out += &poses("");
    let _ = writeln!(out, "{:>5} {:>9} {:<9} |", "", "mm", "");
}

/// The row of `statistic` (the `i`-th of [`Statistic::ALL`]; the first names the case) of case
/// `c` and estimator `e`: its mean, SD and central 95% range over the replications, and the
/// paper's value with its percentile among them where the study has one.
fn spread_row(
    out: &mut String,
    study: &Study,
    replications: &Replications,
    (c, case): (usize, &Case),
    e: usize,
    (i, statistic): (usize, Statistic),
    poses: &impl Fn(&str) -> String,
) {
    let s = replications.spread(c, e, statistic);
    if i == 0 {
        *out += &poses(case.poses.name());
        let _ = write!(out, "{:>5} {:>9.3} ", case.points, case.sigma_me);
    } else {
        *out += &poses("");
        let _ = write!(out, "{:>5} {:>9} ", "", "");
    }
    let _ = write!(
        out,
        "{:<9} | {:>6.2} {:>6} {:>7.2} {:>7.2} |",
        statistic.name(),
        s.mean,
        if s.sd.is_nan() { "-".to_string() } else { format!("{:.2}", s.sd) },
        s.low,
        s.high
    );
    match study.reference_for(case) {
        Some(r) => {
            let paper = statistic.of_reference(r);
            let rank = replications.paper_percentile(c, e, statistic, paper);
            let _ = writeln!(out, " {paper:>6.2} {rank:>10.1}");
        }
        None => out.push('\n'),
    }
}

/// The title and column heads of the coverage table: how often one study's 95% intervals
/// contain the mean over the `count` replications, and the half-widths of MEAN's.
fn coverage_header(out: &mut String, count: usize, poses: &impl Fn(&str) -> String) {
    let _ = writeln!(
        out,
        "\nOne study's 95% intervals against the mean over the {count} replications: how often they contain it (%),\n\
         and the half-width of MEAN's: clustered by point set (as the tables print them), the runs taken as\n\
         independent, and the half-width needed (1.96 x the SD of MEAN over the replications)"
    );
    *out += &poses("");
    let _ = writeln!(
        out,
        "{:>5} {:>9} | {:>21} | {:>21} | {:>21}",
        "", "", "MEAN covered", "MEAN half-width", "% > 0 covered"
    );
    *out += &poses("poses");
    let _ = writeln!(
        out,
        "{:>5} {:>9} | {:>10} {:>10} | {:>6} {:>6} {:>7} | {:>10} {:>10}",
        "N_p", "sigma_me", "clustered", "as indep.", "clust.", "indep.", "needed", "clustered", "as indep."
    );
}

/// Case `c`'s row of estimator `e`'s coverage table ([`Replications::coverage`]).
fn coverage_row(
    out: &mut String,
    replications: &Replications,
    (c, case): (usize, &Case),
    e: usize,
    poses: &impl Fn(&str) -> String,
) {
    let k = replications.coverage(c, e);
    *out += &poses(case.poses.name());
    let _ = writeln!(
        out,
        "{:>5} {:>9.3} | {:>10.1} {:>10.1} | {:>6.2} {:>6.2} {:>7.2} | {:>10.1} {:>10.1}",
        case.points,
        case.sigma_me,
        k.mean_clustered,
        k.mean_independent,
        k.half_width_clustered,
        k.half_width_independent,
        k.half_width_needed,
        k.share_clustered,
        k.share_independent
    );
}

/// Every replication's table as CSV rows: the replication and its master seed, the case, the
/// compared estimator, and its MEAN with the clustered half-width, SD, LOWEST, HIGHEST and
/// % > 0 with its clustered interval.
pub fn csv(study: &Study, replications: &Replications) -> String {
    let mut out = String::from(
        "study,replication,seed,n_points,sigma_me_mm,poses,estimator,mean,mean_ci95,sd,lowest,highest,\
         above_zero,above_zero_low,above_zero_high\n",
    );
    for (r, replication) in replications.replications.iter().enumerate() {
        for (c, case) in study.cases.iter().enumerate() {
            for (e, estimator) in study.estimators.iter().enumerate().skip(1) {
                let s = &replication.clustered[c][e - 1];
                let _ = writeln!(
                    out,
                    "{},{r},{},{},{},{},{estimator},{},{},{},{},{},{},{},{}",
                    study.name,
                    replication.seed,
                    case.points,
                    case.sigma_me,
                    case.poses.name(),
                    s.mean,
                    s.ci95,
                    s.sd,
                    s.lowest,
                    s.highest,
                    s.above_zero,
                    s.above_zero_ci.0,
                    s.above_zero_ci.1
                );
            }
        }
    }
    out
}

/// Everything a replicated study writes, as `(file name, text)`: `replications.txt` (the
/// [`tables`]), `replications.csv` ([`csv()`]) and the figures ([`replication_figures`]).
pub fn files(study: &Study, replications: &Replications) -> Result<Vec<(String, String)>, FigureError> {
    let mut files = vec![
        ("replications.txt".to_string(), tables(study, replications)),
        ("replications.csv".to_string(), csv(study, replications)),
    ];
    files.extend(replication_figures(study, replications)?);
    Ok(files)
}
