//! `robocal calibrate`'s one command: the data files' kinds (read from their headers) and the
//! flags choose the observation calibration (marker files among them) or a tree's; a flag the
//! chosen one cannot honour is refused, saying why, before any work.

use super::{CalibrateObservationsRequest, CalibrateTreeRequest, UsageError, require};
use crate::cli::args::{CalibrateArgs, CalibrateObservationsArgs, CalibrateTreeArgs};
use robocal::calibration::DataKind;
use std::path::PathBuf;

/// A validated `robocal calibrate`: the calibration its data and flags call for.
#[derive(Debug, Clone, PartialEq)]
pub enum CalibrationRequest {
    /// Marker positions, a probe's poses and observation files (distances, contacts,
    /// coordinates, a camera's views), one or several fitted together.
    Observations(Box<CalibrateObservationsRequest>),
    /// Views between the branches of a URDF tree.
    Tree(Box<CalibrateTreeRequest>),
}

impl CalibrationRequest {
    /// The request for `args`, whose `--data` files hold `kinds` (one each, in order).
    pub fn from_args(args: CalibrateArgs, kinds: &[DataKind]) -> Result<Self, UsageError> {
        let trees = kinds.iter().filter(|&&k| k == DataKind::TreeViews).count();
        let tree_flag = match (args.tree.tips.is_empty(), &args.tree.out_dir) {
            (false, _) => Some("--tips"),
            (true, Some(_)) => Some("--out-dir"),
            (true, None) => None,
        };
        if let (0, Some(flag)) = (trees, tree_flag) {
            return Err(UsageError(format!(
                "{flag}: for views between a tree's branches (camera, target columns), and no --data file \
                 holds them; an arm's calibrated model is written by --out-model or --out-urdf"
            )));
        }
        if trees > 0 {
            require(
                trees == kinds.len(),
                "--data: views between a tree's branches (camera, target columns) are fitted on their own; \
                 give the other files to another calibration (--tips and --out-dir are for tree views)",
            )?;
            return Ok(Self::Tree(Box::new(CalibrateTreeRequest::from_args(tree_args(args)?)?)));
        }
        Ok(Self::Observations(Box::new(CalibrateObservationsRequest::from_args(observation_args(args)?)?)))
    }
}

/// The flags of the observation calibration.
fn observation_args(args: CalibrateArgs) -> Result<CalibrateObservationsArgs, UsageError> {
    Ok(CalibrateObservationsArgs {
        model: args.model,
        data: args.data,
        units: args.units,
        estimator: args.estimator,
        joint_sigma_deg: args.noise_flags.joint_sigma_deg,
        params: args.params,
        tool: args.observations.tool,
        fixed_tool: args.observations.fixed_tool,
        marker: args.marker,
        markers: args.markers,
        fixed_base: args.fixed_base,
        fixed_markers: args.fixed_markers,
        noise: args.noise,
        sigma_mm: Some(args.noise_flags.sigma_mm),
        sigma_orientation_deg: Some(args.noise_flags.sigma_orientation_deg),
        choice: args.choice,
        iterations: args.iterations,
        validate: args.validate,
        per_session: args.observations.per_session,
        select: args.select,
        folds: args.folds,
        report: args.report,
        out_model: args.out_model,
        out_urdf: args.out_urdf,
    })
}

/// The flags of the tree calibration, or the first flag it does not take.
fn tree_args(args: CalibrateArgs) -> Result<CalibrateTreeArgs, UsageError> {
    // Each refusal says why: a meaning trees lack, or what gives it instead.
    let refused = [
        (args.model.links.tip_link.is_some(), "--tip-link: a tree's branches are --tips"),
        (
            args.model.payload.payload_kg.is_some(),
            "--payload-kg: a tree carries no payload (not available for trees yet)",
        ),
        (
            args.noise.is_some(),
            "--noise: a tree's views take their noise from their sigma columns and --joint-sigma-deg",
        ),
        (
            args.noise_flags.sigma_mm > 0.0 || args.noise_flags.sigma_orientation_deg > 0.0,
            "--sigma-mm and --sigma-orientation-deg: a tree's views take their sigmas from their sigma columns",
        ),
        (
            args.fixed_base || args.fixed_markers,
            "--fixed-base and --fixed-markers: a tree's base is never estimated (a view sees one frame from another), \
             and views have no markers",
        ),
        (
            !args.marker.is_empty() || args.markers.is_some(),
            "--marker and --markers: views between a tree's branches have no markers",
        ),
        (
            args.out_model.is_some(),
            "--out-model: a tree's branches go to --out-dir (a model file each), the whole tree to --out-urdf",
        ),
        (
            args.observations.tool.is_some() || args.observations.fixed_tool,
            "--tool and --fixed-tool: views between a tree's branches see its cameras' and targets' frames, no tool point",
        ),
    ];
    if let Some((_, refusal)) = refused.iter().find(|(given, _)| *given) {
        return Err(UsageError(refusal.to_string()));
    }
    Ok(CalibrateTreeArgs {
        model: PathBuf::from(args.model.model),
        base_link: args.model.links.base_link,
        tips: args.tree.tips,
        data: args.data,
        units: args.units,
        estimator: args.estimator,
        joint_sigma_deg: args.noise_flags.joint_sigma_deg,
        params: args.params,
        choice: args.choice,
        iterations: args.iterations,
        validate: args.validate,
        per_session: args.observations.per_session,
        select: args.select,
        folds: args.folds,
        report: args.report,
        out_dir: args.tree.out_dir,
        out_urdf: args.out_urdf,
    })
}
