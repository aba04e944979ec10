//! `robocal observability`: the indices O1-O5 of a pose file.

use super::design;
use super::request::ObservabilityRequest;
use anyhow::{Context, Result, bail};
use robocal::{io, report};

/// Print the observability indices of the request's pose file.
pub fn run(request: &ObservabilityRequest) -> Result<()> {
    let design = design(&request.design)?;
    let poses = io::load_poses(&request.poses, design.model(), request.units)?;
    let name = request.poses.display().to_string();
    if poses.iter().all(|q| *q == poses[0]) {
        let count = if poses.len() == 1 {
            "one pose".to_string()
        } else {
            format!("{} poses, all alike", poses.len())
        };
        bail!(
            "{name}: {count}: observability indices need poses that differ (every index would be 0 or infinite)"
        );
    }
    let what = format!("the {} poses of {name}", poses.len());
    io::check_memory(design.plan_memory_estimate(poses.len()), &what, "give fewer poses")?;
    let observability = design.observability(&poses).with_context(|| name.clone())?;
    print!("{}", report::design::observability(&design, &observability, &name));
    Ok(())
}
