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
    let (plan, pool) = design.plan_seeded(
        request.points,
        request.candidates,
        &constraints,
        request.criterion,
        request.seed,
    )?;
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
            println!("wrote {} poses to {}", plan.joints.len(), path.display());
        }
        None => {
            eprint!("{summary}");
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
