//! `robocal evaluate` of a tree's views: the tree of a URDF file (`--tips`), as it stands or
//! with the branches `calibrate --out-dir` wrote (`--branches`), scored on files of views
//! between its branches, each file's cameras and targets fitted to it, the tree held.

use super::request::{EvaluateRequest, NoiseSource};
use anyhow::{Context, Result, bail};
use robocal::calibration::DataKind;
use robocal::calibration::kinds::{KindOptions, Score, ViewResidual};
use robocal::calibration::tree::{TreeData, evaluate_tree};
use robocal::io;
use robocal::model::RobotTree;
use robocal::report::residuals::ResidualSet;
use serde::Serialize;
use std::fmt::Write;

/// Views listed per file in the text, the worst first (as the tree's calibration report).
const WORST: usize = robocal::report::observations::WORST;

/// What `evaluate` reports of a tree: its name, branches and joints, each file scored.
#[derive(Serialize)]
struct TreeEvaluation {
    /// The robot's name.
    model: String,
    /// Its branches' tip links.
    branches: Vec<String>,
    /// Its joints, in the order of the view files' columns.
    joints: Vec<String>,
    /// Each file, its cameras and targets fitted, the tree held: every view's residual (its
    /// `after`; `before` is the same), and their RMS.
    views: Vec<(String, Score)>,
}

/// Score the tree on every file, print the tables, write the files asked for.
pub fn run(request: &EvaluateRequest, kinds: &[DataKind]) -> Result<()> {
    if let Some((path, _)) = request.data.iter().zip(kinds).find(|(_, k)| **k != DataKind::TreeViews) {
        bail!(
            "{}: not a file of views between a tree's branches (camera, target columns): a tree is scored on its views",
            path.display()
        );
    }
    let tree = load_tree(request)?;
    let files = (request.data.iter())
        .map(|path| {
            let text =
                std::fs::read_to_string(path).with_context(|| format!("{}: cannot read", path.display()))?;
            let data = TreeData::from_csv_str(&text, &tree, request.units)
                .with_context(|| path.display().to_string())?;
            Ok((path.display().to_string(), data))
        })
        .collect::<Result<Vec<_>>>()?;
    let joint_noise = observation_joint_noise(request, (&tree.name, &tree.joints))?;
    let options = KindOptions { joint_noise, ..KindOptions::default() };
    let views = (files.iter())
        .map(|(name, data)| {
            let score = evaluate_tree(&tree, data, &options).with_context(|| name.clone())?;
            Ok((name.clone(), score))
        })
        .collect::<Result<Vec<_>>>()?;
    let text = views_text(&tree.name, &views);
    super::show_report(&text, &super::report_outputs(&request.report));
    let report = TreeEvaluation {
        model: tree.name.clone(),
        branches: tree.branches.iter().map(|b| b.tip.clone()).collect(),
        joints: tree.joints.iter().map(|j| j.name.clone()).collect(),
        views,
    };
    let sets = (files.iter().zip(&report.views))
        .map(|((name, data), (_, score))| {
            let set = ResidualSet::of_views(name, score, &[(name.as_str(), data)], &tree.joints);
            Ok(set.map_err(anyhow::Error::msg)?.at_one_stage("as it stands"))
        })
        .collect::<Result<Vec<_>>>()?;
    let title = format!("{} scored as it stands", tree.name);
    let content = super::ResidualContent {
        json: super::json_if_asked(&request.report, &report)?,
        page: &|figures, sets| robocal::report::html::page(&title, &text, sets, figures),
        sets,
        joints: &tree.joints,
        model: None,
        prior_scale: None,
        selection: None,
    };
    let mut outputs = io::Outputs::new();
    super::write_residual_files(&request.report, content, &mut outputs)?;
    super::commit(outputs)
}

/// The tree of `--model` and `--tips`, its joints those of the branches in `--branches` if
/// given ([`io::load_branches`]).
fn load_tree(request: &EvaluateRequest) -> Result<RobotTree> {
    let name = request.model.name.as_str();
    let text = std::fs::read_to_string(name).with_context(|| format!("{name}: cannot read"))?;
    let tree = RobotTree::from_urdf_str(&text, request.tree_root.as_deref(), &request.tips)
        .with_context(|| name.to_string())?;
    match &request.branches {
        Some(folder) => Ok(io::load_branches(&tree, folder)?),
        None => Ok(tree),
    }
}

/// The view errors of each file, as the tree's calibration report gives them after
/// calibration, then the worst views of each.
fn views_text(model: &str, scores: &[(String, Score)]) -> String {
    let mut text = String::new();
    let _ = writeln!(
        text,
        "{model} scored as it stands on {} view file{}: each file's cameras and targets fitted, the tree's joints held (calibrate --validate scores with the calibrated cameras and targets instead: its figure can be larger)\n",
        scores.len(),
        if scores.len() == 1 { "" } else { "s" }
    );
    let width = scores.iter().map(|(n, _)| n.len() + 6).max().unwrap_or(0).max(24);
    let _ = writeln!(text, "{:<width$} {:>12}", "view errors, RMS", "as it stands");
    for (name, score) in scores {
        let _ = writeln!(
            text,
            "{:<width$} {:>12.4}",
            format!("{name} (mm)"),
            score.view_position.unwrap_or_default().1
        );
        if let Some((_, after)) = score.view_rotation {
            let _ = writeln!(text, "{:<width$} {after:>12.5}", format!("{name} (deg)"));
        }
    }
    let _ = writeln!(text, "\nworst views ({WORST} per file; every one in --json, --poses-csv):");
    for (name, score) in scores {
        let mut worst: Vec<&ViewResidual> = score.views.iter().collect();
        worst.sort_by(|a, b| b.after_mm.total_cmp(&a.after_mm));
        for v in worst.iter().take(WORST) {
            let error = match v.after_deg {
                Some(deg) => format!("{:.4} mm / {deg:.5} deg", v.after_mm),
                None => format!("{:.4} mm", v.after_mm),
            };
            let _ = writeln!(text, "  {name}, line {}: {error}, {:.1} sd", v.line, v.whitened);
        }
    }
    text
}

/// The joint noise `--joint-sigma-deg` gives for scoring view files (of the tree `name` with
/// `joints`); `--noise`, `--sigma-mm` and `--sigma-orientation-deg` refused: a view file's sigma
/// columns are its measurement noise.
fn observation_joint_noise(
    request: &EvaluateRequest,
    (name, joints): (&str, &[robocal::model::Joint]),
) -> Result<Option<nalgebra::DMatrix<f64>>> {
    match &request.noise {
        None => Ok(None),
        Some(NoiseSource::Flags(flags)) if flags.sigma_mm != 0.0 || flags.sigma_orientation_deg != 0.0 => {
            bail!(
                "--sigma-mm and --sigma-orientation-deg are not for view files: the sigma and sigma_angle columns \
                 give the measurement noise here, --joint-sigma-deg the joints'"
            )
        }
        Some(NoiseSource::Flags(flags)) => {
            super::joint_covariance(name, joints, Some(&flags.joint_sigma_deg))
        }
        Some(NoiseSource::File(_)) => bail!(
            "--noise is not for view files: the sigma and sigma_angle columns give the measurement noise here; \
             give the joint noise by --joint-sigma-deg"
        ),
    }
}
