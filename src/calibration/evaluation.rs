//! Scoring a model on measured poses, pose by pose and marker by marker.
//!
//! A set of poses is scored at one or more *stages*: full parameter vectors `x` of the same
//! chains ("before" and "after" of a calibration, or a model as it stands, `x = 0`). At pose
//! `k` and stage `s` the error of marker `m` is
//!
//! ```text
//! e_k,m(s) = p_k,m - f_m(q_k, x_s)        (mm, the measuring frame)
//! ```
//!
//! measured minus predicted; for a 6-DOF probe also the rotation vector `omega` with
//! `R_measured = exp([omega]x) R_predicted`, whose norm is the orientation error. Summaries
//! ([`ErrorStats`]) are over the distances `|e_k,m|`: pooled over the markers of the set, and
//! per marker. They weight nothing: they are what a ruler would say.
//!
//! The *whitened residual* of pose `k` is the Mahalanobis norm of its stacked errors at the
//! last stage, `|L_k^-1 r_k|` with `V_k = L_k L_k^T` the pose's full covariance (joint and
//! measurement noise, Eq. 10, at the registered nominal model), whatever estimator fitted the
//! model. Without a noise model it is `|r_k| / sigma` with `sigma` the residuals' own spread
//! (see [`Whitening`]). A pose is *flagged* when one whitened component lies more than
//! [`FLAG_AT`] standard deviations out: the rule of the calibration's outlier warning. Under a
//! noise model the threshold is `FLAG_AT max(1, s)`, `s` the robust scale of the poses'
//! whitened norms (`median(|z_k|) / sqrt(median chi^2(n))`, [`super::robust`]): when every pose
//! lies further out than `V_k` says, as when a gross error pulls the fit, a pose is flagged
//! only if it stands out from the others.

use super::{CalibrationError, ErrorStats};
use crate::estimation::{NoiseModel, PointProblem, Residuals};
use crate::kinematics::{Chain, Measured};
use crate::model::Selection;
use nalgebra::{DVector, Vector3};
use rayon::prelude::*;
use serde::Serialize;

/// A pose is flagged when a component of its whitened residual exceeds this (under a noise
/// model, times the set's robust scale when above 1: see the [module documentation](self)).
pub const FLAG_AT: f64 = 5.0;

/// How residuals are whitened.
#[derive(Debug, Clone, PartialEq)]
pub enum Whitening {
    /// By the full covariance `V_k` of each pose under this noise model (already fitted to
    /// the set's poses: per-pose blocks, or a `sigma` column, must be the set's own).
    Covariance(NoiseModel),
    /// No noise model: divided by this standard deviation (mm), the spread of the training
    /// residuals `sqrt(|r|^2 / (N_m - rank))`, a pose's orientation rows (rad) counted as
    /// lengths by the weight of ordinary least squares ([`PointProblem::orientation_weight`]).
    Spread(f64),
}

impl Whitening {
    /// In words, for the report.
    pub fn describe(&self) -> String {
        match self {
            Self::Covariance(_) => {
                "Mahalanobis norm under each pose's full V_k (joint and measurement noise)".into()
            }
            Self::Spread(s) => {
                format!("norm divided by the residuals' spread, sigma = {s:.4} mm (no noise model)")
            }
        }
    }

    /// When a pose is flagged, in words: a whitened component beyond [`FLAG_AT`] standard
    /// deviations, under a noise model times the poses' robust spread when it is above 1.
    pub fn flag_rule(&self) -> String {
        match self {
            Self::Covariance(_) => format!(
                "flagged when a component exceeds {FLAG_AT} standard deviations times the poses' robust spread, \
                 if above 1"
            ),
            Self::Spread(_) => format!("flagged when a component exceeds {FLAG_AT} standard deviations"),
        }
    }
}

/// One pose of a set, scored.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PoseErrors {
    /// The pose's line in its file.
    pub line: usize,
    /// The joint values (rad; mm for prismatic joints).
    pub joints: Vec<f64>,
    /// `errors[stage][marker]`: measured minus predicted position (mm), x, y, z.
    pub errors: Vec<Vec<[f64; 3]>>,
    /// For a probe, `orientation[stage]`: the rotation vector of the orientation error (deg).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub orientation: Option<Vec<[f64; 3]>>,
    /// The whitened residual at the last stage (see the [module documentation](self)).
    pub whitened: f64,
    /// Its largest component, in standard deviations.
    pub worst: f64,
    /// Whether `worst` exceeds [`FLAG_AT`] (times the set's robust scale, if above 1, under a
    /// noise model; see the [module documentation](self)).
    pub flagged: bool,
}

impl PoseErrors {
    /// The distance of marker `m` at stage `s` (mm).
    pub fn distance(&self, s: usize, m: usize) -> f64 {
        Vector3::from(self.errors[s][m]).norm()
    }
}

/// A set of poses scored at every stage.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SetEvaluation {
    /// The set's name (a file, `training`).
    pub name: String,
    /// The stages' names (`before`, `after`; `model`).
    pub stages: Vec<String>,
    /// The numbers of the markers scored (the file's `x<k>` columns).
    pub marker_ids: Vec<usize>,
    /// Every pose, in the file's order.
    pub poses: Vec<PoseErrors>,
    /// Per stage: the distances of every marker of every pose.
    pub pooled: Vec<ErrorStats>,
    /// `per_marker[marker][stage]`.
    pub per_marker: Vec<Vec<ErrorStats>>,
    /// For a probe, per stage: the orientation errors (deg).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub orientation: Option<Vec<ErrorStats>>,
    /// How the whitened residuals were computed.
    pub whitening: String,
}

impl SetEvaluation {
    /// The flagged poses.
    pub fn flagged(&self) -> impl Iterator<Item = &PoseErrors> {
        self.poses.iter().filter(|p| p.flagged)
    }
}

/// What is measured in a set: the poses, the chains of its markers, their numbers.
pub(crate) struct Scored<'a> {
    /// One chain per marker of the set (or the probe's).
    pub chains: &'a [Chain],
    /// The markers' numbers.
    pub marker_ids: &'a [usize],
    /// Position or pose.
    pub kind: Measured,
}

/// Score `data` (its markers measured by `scored.chains`) at `stages`, whitened by
/// `whitening`.
pub(crate) fn evaluate(
    name: &str,
    scored: &Scored<'_>,
    data: &super::Measurements,
    stages: &[(&str, &[f64])],
    whitening: &Whitening,
) -> Result<SetEvaluation, CalibrationError> {
    let params = scored.chains[0].params();
    let nothing = Selection::from_indices(params, []);
    let zero = vec![0.0; params.len()];
    let noise = match whitening {
        Whitening::Covariance(noise) => Some(noise),
        Whitening::Spread(_) => None,
    };
    let problem = PointProblem::new(
        scored.chains,
        &nothing,
        scored.kind,
        data.joints.clone(),
        super::observed(data),
        zero,
        noise,
    )?;
    evaluate_on(name, scored, data, stages, whitening, &problem)
}

/// `r` (residuals of `problem`, pose by pose) in lengths: a pose's orientation rows (rad)
/// times the weight `w = sigma_position / sigma_orientation` (mm/rad) of ordinary least squares.
pub(crate) fn in_lengths(problem: &PointProblem<'_>, r: &mut DVector<f64>) {
    if problem.measured() == Measured::Pose {
        let w = problem.orientation_weight();
        r.iter_mut().enumerate().filter(|(i, _)| i % 6 >= 3).for_each(|(_, v)| *v *= w);
    }
}

/// [`evaluate`] on `problem`, the problem of `data` measured by `scored.chains` whose
/// covariance blocks `V_k` are those of `whitening` (a calibration's own, reused rather than
/// computed again).
pub(crate) fn evaluate_on(
    name: &str,
    scored: &Scored<'_>,
    data: &super::Measurements,
    stages: &[(&str, &[f64])],
    whitening: &Whitening,
    problem: &PointProblem<'_>,
) -> Result<SetEvaluation, CalibrationError> {
    let nothing = Selection::from_indices(scored.chains[0].params(), []);
    let residuals: Vec<DVector<f64>> = stages
        .iter()
        .map(|(_, x)| Ok(problem.reselect(&nothing, x.to_vec())?.evaluate(&DVector::zeros(0), None)))
        .collect::<Result<_, CalibrationError>>()?;
    let (z, bulk) = whitened(problem, whitening, residuals.last().expect("at least one stage"))?;
    let poses = pose_errors(scored, data, &residuals, &z, bulk * FLAG_AT);
    let probe = scored.kind == Measured::Pose;
    let (pooled, per_marker, orientation) = summaries(&poses, stages.len(), scored.chains.len(), probe);
    Ok(SetEvaluation {
        name: name.to_string(),
        stages: stages.iter().map(|(n, _)| n.to_string()).collect(),
        marker_ids: scored.marker_ids.to_vec(),
        poses,
        pooled,
        per_marker,
        orientation,
        whitening: whitening.describe(),
    })
}

/// The held-out poses of a k-fold cross-validation as one set named `name`: `folds[f]` scored
/// the poses `i` with `i mod k = f` (`k = folds.len()`) with the calibration of the others;
/// their poses joined in the data's order, the summaries over them all.
pub(crate) fn joined(name: &str, folds: Vec<SetEvaluation>) -> SetEvaluation {
    let k = folds.len();
    let mut folds = folds.into_iter();
    let first = folds.next().expect("at least two folds");
    let (stages, markers, probe) = (first.stages.len(), first.marker_ids.len(), first.orientation.is_some());
    // Each pose whitened, and flagged, as its fold's calibration whitens its own.
    let whitening = format!("each fold's own: {}", first.whitening);
    let (marker_ids, stage_names) = (first.marker_ids, first.stages);
    let poses: Vec<PoseErrors> = first.poses.into_iter().chain(folds.flat_map(|f| f.poses)).collect();
    let fold_of: Vec<usize> = (0..poses.len()).map(|p| p % k).collect();
    let poses = super::in_data_order(poses, &fold_of, k);
    let (pooled, per_marker, orientation) = summaries(&poses, stages, markers, probe);
    SetEvaluation {
        name: name.to_string(),
        stages: stage_names,
        marker_ids,
        poses,
        pooled,
        per_marker,
        orientation,
        whitening,
    }
}

/// The last stage's residuals `last` whitened (by `V_k` block by block, or by the spread in
/// lengths), and the bulk's robust scale under a noise model (1 otherwise): when the poses all
/// lie further out than `V_k` says (a fit pulled by a gross error, effects the model lacks), a
/// pose's flag threshold grows with it.
fn whitened(
    problem: &PointProblem<'_>,
    whitening: &Whitening,
    last: &DVector<f64>,
) -> Result<(DVector<f64>, f64), CalibrationError> {
    let rows = problem.rows_per_point();
    let mut z = last.clone();
    match whitening {
        Whitening::Covariance(_) => {
            // V_k's whitening, block by block: S is not stored.
            if let Some(v) = problem.covariance() {
                crate::estimation::whiten_in_place(v, &crate::estimation::Blocks::Uniform(rows), &mut z)?
            }
            let norms: Vec<f64> = z
                .as_slice()
                .chunks_exact(rows)
                .map(|r| r.iter().map(|v| v * v).sum::<f64>().sqrt())
                .collect();
            Ok((z, super::robust::robust_scale(&norms, rows).max(1.0)))
        }
        Whitening::Spread(sigma) => {
            if *sigma > 0.0 {
                in_lengths(problem, &mut z);
                z /= *sigma
            }
            Ok((z, 1.0))
        }
    }
}

/// Each pose's errors at every stage (`residuals`, one vector per stage), its whitened
/// residual `z`'s norm and largest entry, flagged beyond `flag_at`.
fn pose_errors(
    scored: &Scored<'_>,
    data: &super::Measurements,
    residuals: &[DVector<f64>],
    z: &DVector<f64>,
    flag_at: f64,
) -> Vec<PoseErrors> {
    let probe = scored.kind == Measured::Pose;
    let per = scored.kind.rows();
    let markers = scored.chains.len();
    let rows = per * markers;
    (0..data.len())
        .into_par_iter()
        .map(|k| {
            let errors = residuals
                .iter()
                .map(|y| (0..markers).map(|m| [0, 1, 2].map(|c| y[k * rows + m * per + c])).collect())
                .collect();
            let orientation = probe
                .then(|| residuals.iter().map(|y| [3, 4, 5].map(|r| y[k * rows + r].to_degrees())).collect());
            let zk = z.rows(k * rows, rows);
            let worst = zk.iter().fold(0.0f64, |m, v| m.max(v.abs()));
            PoseErrors {
                line: data.lines[k],
                joints: data.joints[k].clone(),
                errors,
                orientation,
                whitened: zk.norm(),
                worst,
                flagged: worst > flag_at,
            }
        })
        .collect()
}

/// The poses' error statistics at each of `stages` stages: pooled, per marker, and of the
/// orientation for a probe.
#[allow(clippy::type_complexity)]
fn summaries(
    poses: &[PoseErrors],
    stages: usize,
    markers: usize,
    probe: bool,
) -> (Vec<ErrorStats>, Vec<Vec<ErrorStats>>, Option<Vec<ErrorStats>>) {
    let stats = |s: usize, m: Option<usize>| {
        let vectors: Vec<Vector3<f64>> = poses
            .iter()
            .flat_map(|p| p.errors[s].iter().enumerate())
            .filter(|(i, _)| m.is_none_or(|m| m == *i))
            .map(|(_, e)| Vector3::from(*e))
            .collect();
        ErrorStats::of(&vectors)
    };
    let pooled = (0..stages).map(|s| stats(s, None)).collect();
    let per_marker = (0..markers).map(|m| (0..stages).map(|s| stats(s, Some(m))).collect()).collect();
    let orientation = probe.then(|| {
        (0..stages)
            .map(|s| {
                let v: Vec<Vector3<f64>> = poses
                    .iter()
                    .filter_map(|p| p.orientation.as_ref().map(|o| Vector3::from(o[s])))
                    .collect();
                ErrorStats::of(&v)
            })
            .collect()
    });
    (pooled, per_marker, orientation)
}

/// The sets pooled into one: every pose of each (their stages must agree; markers are pooled
/// by number), named `name`. `None` without sets.
pub fn pool(name: &str, sets: &[&SetEvaluation]) -> Option<SetEvaluation> {
    let first = sets.first()?;
    let stages = first.stages.len();
    let mut ids: Vec<usize> = sets.iter().flat_map(|s| s.marker_ids.iter().copied()).collect();
    ids.sort_unstable();
    ids.dedup();
    let mut pooled_vectors = vec![Vec::new(); stages];
    let mut per_marker_vectors = vec![vec![Vec::new(); stages]; ids.len()];
    let mut orientation_vectors = vec![Vec::new(); stages];
    for set in sets {
        for pose in &set.poses {
            for s in 0..stages {
                for (m, e) in pose.errors[s].iter().enumerate() {
                    let at = ids.iter().position(|&id| id == set.marker_ids[m]).expect("pooled ids");
                    pooled_vectors[s].push(Vector3::from(*e));
                    per_marker_vectors[at][s].push(Vector3::from(*e));
                }
                if let Some(o) = &pose.orientation {
                    orientation_vectors[s].push(Vector3::from(o[s]));
                }
            }
        }
    }
    let of = |v: &Vec<Vector3<f64>>| ErrorStats::of(v);
    Some(SetEvaluation {
        name: name.to_string(),
        stages: first.stages.clone(),
        marker_ids: ids,
        poses: Vec::new(),
        pooled: pooled_vectors.iter().map(of).collect(),
        per_marker: per_marker_vectors.iter().map(|m| m.iter().map(of).collect()).collect(),
        orientation: first.orientation.is_some().then(|| orientation_vectors.iter().map(of).collect()),
        whitening: first.whitening.clone(),
    })
}
