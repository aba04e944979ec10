//! `robocal plan`: measurement poses that maximise an observability criterion.

use super::request::PlanRequest;
use super::{design, from_flag_unit};
use anyhow::{Result, bail};
use robocal::design::{Constraints, ExcludedRange, PlanProgress};
use robocal::model::{ModelRef, RobotModel};
use robocal::report;

/// Plan the poses; write them with the summary (or print them, the summary to standard error).
pub fn run(request: &PlanRequest) -> Result<()> {
    let design = design(&request.design)?;
    let model = design.model();
    let constraints = constraints(request, model)?;
    let needed = design.plan_memory_estimate(request.candidates);
    robocal::io::check_memory(
        needed,
        &format!("--candidates {}", request.candidates),
        "ask for fewer candidates",
    )?;
    let work = design.plan_work(request.candidates, request.points);
    if work > robocal::limits::MAX_WORK {
        bail!(
            "--candidates {} for --points {}: about {work:.1e} row-parameter products a pass of the exchange, more \
             than {:.0e} (hours of work): ask for fewer candidates or points",
            request.candidates,
            request.points,
            robocal::limits::MAX_WORK as f64
        );
    }
    // Over a few seconds of work (about 1e8 row-parameter products a pass, measured): a bar for
    // the candidates' rows, then for each pass of the exchange, with the time left in it.
    let bar = (work > PROGRESS_FROM && !super::quiet()).then(|| plan_bar(request.candidates));
    let progress = |p: PlanProgress| {
        let Some(bar) = &bar else { return };
        let (message, done, of) = match p {
            PlanProgress::Rows { done, of } => (ROWS.to_string(), done, of),
            PlanProgress::Pass { pass, done, of } => (format!("exchange pass {pass}"), done, of),
        };
        if bar.message() != message {
            bar.set_message(message);
            bar.set_length(of as u64);
            bar.set_position(0);
            bar.reset_eta();
        }
        bar.set_position(done as u64);
    };
    let planned = design.plan_seeded_reporting(
        request.points,
        request.candidates,
        &constraints,
        request.criterion,
        request.seed,
        &progress,
    );
    if let Some(bar) = &bar {
        bar.finish_and_clear();
    }
    let (plan, pool) = planned?;
    let summary = report::design::plan_summary(&design, &plan, pool.joints.len(), pool.draws);
    let comment = format!(
        "robocal plan --model {} --points {} --candidates {} --criterion {} --seed {}\n{}",
        model_flags(&request.design.model),
        request.points,
        request.candidates,
        request.criterion,
        request.seed,
        summary.trim_end()
    );
    let csv = robocal::design::poses_csv(model, &plan.joints, &comment);
    match &request.out {
        Some(path) => {
            let mut outputs = robocal::io::Outputs::new();
            outputs.add(path, csv);
            outputs.commit()?;
            print!("{summary}");
            super::status(format_args!("wrote {} poses to {}", plan.joints.len(), path.display()));
        }
        None => {
            super::status_text(&summary);
            print!("{csv}");
        }
    }
    Ok(())
}

/// The work a pass (row-parameter products, [`robocal::design::Design::plan_work`]) beyond which
/// `plan` shows a progress bar: about a second a pass on one core (measured: 9e8 took 8 s a
/// pass on a loaded two-core machine, 13 passes).
const PROGRESS_FROM: u64 = 100_000_000;

/// The progress bar of a plan: the candidates' rows, then each pass of the exchange, each with
/// the time left in it (how many passes there will be is not known in advance).
fn plan_bar(candidates: usize) -> indicatif::ProgressBar {
    let bar = indicatif::ProgressBar::new(candidates as u64).with_message(ROWS);
    let template = "plan: {msg} {bar:20} {pos}/{len}, {elapsed} in all, ~{eta} left of it";
    bar.set_style(indicatif::ProgressStyle::with_template(template).expect("a valid template"));
    bar.enable_steady_tick(std::time::Duration::from_millis(500));
    bar
}

/// The bar's message while the candidates' rows are computed.
const ROWS: &str = "the candidates' rows";

/// The tool box and the excluded ranges, each range's joint found in `model`.
fn constraints(request: &PlanRequest, model: &RobotModel) -> Result<Constraints> {
    let mut excluded = Vec::new();
    for exclude in &request.exclude {
        let Some(joint) = model.joints.iter().position(|j| j.name == exclude.joint) else {
            let names: Vec<&str> = model.joints.iter().map(|j| j.name.as_str()).collect();
            bail!(
                "--exclude `{exclude}`: no joint `{}`; the model's joints are {}",
                exclude.joint,
                names.join(", ")
            );
        };
        let range = exclude.range.map(|v| from_flag_unit(model.joints[joint].kind, v));
        excluded.push(ExcludedRange { joint, range });
    }
    Ok(Constraints { tool_box: request.tool_box.map(|b| [b.low, b.high]), excluded })
}

/// `--model` (with its URDF links) as the command line gives it.
fn model_flags(model: &ModelRef) -> String {
    let mut text = model.name.clone();
    for (flag, link) in [("--base-link", &model.base_link), ("--tip-link", &model.tip_link)] {
        if let Some(link) = link {
            text += &format!(" {flag} {link}");
        }
    }
    text
}
