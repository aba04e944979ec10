//! `robocal repeatability`: the noise from repeated measurements, printed and written.

use super::check_marker_count;
use super::request::RepeatabilityRequest;
use anyhow::{Context, Result};
use robocal::calibration::{self, RepeatabilityOptions};
use robocal::estimation::JointComponents;
use robocal::{io, report};

/// Estimate the noise; print it, and write the noise file and the JSON if asked.
pub fn run(request: &RepeatabilityRequest) -> Result<()> {
    let model = io::load_model(&request.model)?;
    let data = io::load_repeatability(&request.data, &model, request.units)?;
    check_marker_count(request.markers.len(), &request.data, data.markers)?;
    if data.poses.len() < 2 {
        anyhow::bail!(
            "{}, column `pose`: {} pose: the spread at one pose cannot tell the joint noise from sigma_me; \
             measure at least 2 poses (several, far apart, are better)",
            request.data.display(),
            data.poses.len()
        );
    }
    let poses = data.poses.iter().map(|p| (p.lines.first().copied().unwrap_or(0), p.joints.as_slice()));
    super::warn_outside_limits(&request.data, &model, poses);
    let joints = if request.full_covariance { JointComponents::Full } else { JointComponents::Diagonal };
    let options =
        RepeatabilityOptions { joints, markers: request.markers.clone(), register: request.register };
    let result = calibration::repeatability(&model, &data, &options)
        .with_context(|| format!("{}: the variance components", request.data.display()))?;
    let rows = report::calibration::noise_rows(&model.joints, &result.estimate);
    println!(
        "repeatability of {} from {}: {} poses, {} measurements, rms spread {:.4} mm\n",
        model.name,
        request.data.display(),
        result.poses,
        result.measurements,
        result.rms_spread
    );
    print!("{}", report::calibration::noise_table(&rows));
    let estimate = &result.estimate;
    let bound = |s: f64, name: &str, unit: &str, used: f64| {
        (s == 0.0).then(|| {
            format!(
                "{name} is at its bound 0: the noise file gives {used:.3e} {unit} (the square root of its \
                 standard error), so that V_k stays positive definite"
            )
        })
    };
    let (me, _) = estimate.weighting_sigmas();
    let mut notes: Vec<String> = bound(estimate.sigma_me().sigma, "sigma_me", "mm", me).into_iter().collect();
    if request.full_covariance {
        notes.push(
            "the noise file holds Sigma_q made positive semi-definite (negative eigenvalues set to 0): \
             its diagonal can differ from the sigmas above"
                .into(),
        );
    }
    for note in &notes {
        println!("note: {note}");
    }
    let mut outputs = io::Outputs::new();
    if let Some(path) = &request.out {
        let header = format!(
            "robocal noise file, estimated by `robocal repeatability` from {} ({} poses, {} measurements).\n\
             95% intervals:\n{}{}",
            request.data.display(),
            result.poses,
            result.measurements,
            report::calibration::noise_table(&rows),
            notes.iter().map(|n| format!("note: {n}\n")).collect::<String>()
        );
        outputs.add(path, result.estimate.spec().to_toml_string(&model, &header));
    }
    if let Some(path) = &request.json {
        outputs.add(path, serde_json::to_string_pretty(&rows)? + "\n");
    }
    outputs.commit()?;
    if let Some(path) = &request.out {
        super::status(format_args!("\nwrote {}", path.display()));
    }
    Ok(())
}
