//! `robocal plan`: measurement poses that maximise an observability criterion.

use super::request::PlanRequest;
use super::{design, from_flag_unit};
use anyhow::{Result, bail};
use robocal::design::{Constraints, ExcludedRange};
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
    // Over about a second of work: say it is working, and for how long.
    let spinner = (work > 1_000_000_000 && !super::quiet()).then(|| {
        let bar = indicatif::ProgressBar::new_spinner().with_message(format!(
            "planning {} poses from {} candidates ({work:.1e} row-parameter products a pass)",
            request.points, request.candidates
        ));
        bar.set_style(
            indicatif::ProgressStyle::with_template("{spinner} {msg}, {elapsed}").expect("a valid template"),
        );
        bar.enable_steady_tick(std::time::Duration::from_millis(200));
        bar
    });
    let (plan, pool) = design.plan_seeded(
        request.points,
        request.candidates,
        &constraints,
        request.criterion,
        request.seed,
    )?;
    if let Some(bar) = spinner {
        bar.finish_and_clear();
    }
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
