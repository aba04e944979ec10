//! Feasible GLS of observation files: the joint noise and one measurement variance per kind
//! of observation estimated from the calibration's own residuals, as
//! [`calibrate_feasible`](crate::calibration::calibrate_feasible) does for marker files, by
//! the same rounds ([`reweighted`]) and the same fit of variance components
//! ([`residual_samples`], [`NoiseEstimate`]).
//!
//! Each pose's observations are one block, `V_k = sum_j G_kj Sigma_q G_kj^T + Sigma_m,k`, as
//! the [module](super) builds them: `G_kj = g_kj^T J_j` the derivatives of the block's rows by
//! the joints of each pose `j` they see, `Sigma_m,k` diagonal with one variance per
//! measurement class ([`super::Observation::class`]): distances, contacts, coordinates (mm), angles
//! (rad), marker coordinates (mm), a camera view's position (mm) and rotation (rad), one
//! component for each class the data hold.

use super::{Calibration, KindCalibration, KindData, KindOptions, Robot, Unscored, fit_kinds};
use crate::calibration::{
    CalibrationError, FeasibleOptions, JointComponents, Loss, Reweighted, Warning, reweighted, unsettled,
};
use crate::estimation::{Estimator, NoiseEstimate, Weights, residual_samples};
use crate::model::RobotModel;
use std::sync::OnceLock;

/// Feasible GLS of observation files: calibrate by ordinary least squares, fit the variance
/// components (the joint variances, or every entry of `Sigma_q`, and each measurement class's
/// variance) to the residuals' outer products `r_k r_k^T` of each pose's block, whose
/// expectation is `(M V M^T)_kk` with `M` the residual maker of the weighted fit; calibrate
/// again by Gauss-Markov with `V_k` from the estimate (every observation's sigma its class's,
/// `Sigma_q` the joints'); repeat until the components settle. The result carries the last
/// estimate in [`KindCalibration::noise_estimate`], with a [`Warning::NoiseUnsettled`] if they
/// did not settle and a [`Warning::SigmaIgnored`] if the files gave sigmas (their noise is
/// what is estimated). `options.estimator` and `options.joint_noise` are not used; a prior or
/// a robust loss is refused (the components would be those of another fit).
pub fn calibrate_kinds_feasible(
    model: &RobotModel,
    data: &KindData,
    options: &KindOptions,
    feasible: &FeasibleOptions,
) -> Result<KindCalibration, CalibrationError> {
    if !options.prior.is_empty() || options.loss != Loss::Squared {
        return Err(CalibrationError::Observations(
            "feasible GLS estimates the noise from the residuals of plain least squares: not with a prior \
             or a robust loss"
                .into(),
        ));
    }
    let ols = KindOptions { estimator: Estimator::Ols, joint_noise: None, ..options.clone() };
    // The first round's "before" fit, which the others share where it is the same; each
    // round's calibration scored only if it is the last.
    let first: OnceLock<(Vec<f64>, Vec<f64>)> = OnceLock::new();
    let calibrate = |estimate: Option<&NoiseEstimate>| match estimate {
        None => {
            let fitted = fit_kinds(model, data, &ols, None)?;
            first.get_or_init(|| fitted.calibration.before_values());
            Ok(fitted)
        }
        Some(e) => {
            let weighted = KindOptions {
                estimator: Estimator::Wls,
                joint_noise: Some(e.joint_covariance()),
                ..ols.clone()
            };
            let sigmas = with_class_sigmas(data, e);
            let fitted = fit_kinds(model, &sigmas, &weighted, first.get().cloned())?;
            Ok(Unscored { fitted_on: Some(sigmas), ..fitted })
        }
    };
    let estimate = |c: &Unscored, previous: Option<&NoiseEstimate>| match (previous, &c.fitted_on) {
        // A weighted round's data, with the sigmas of `previous` it was fitted with: not copied again.
        (Some(_), Some(fitted_on)) => residual_noise_on(&c.calibration, fitted_on, feasible.joints, previous),
        _ => residual_noise(&c.calibration, data, feasible.joints, previous),
    };
    let rounds = reweighted(feasible, calibrate, estimate)?;
    let warning = unsettled(feasible, &rounds);
    let Reweighted { calibration, estimate, settled, .. } = rounds;
    let mut calibration = calibration.scored((&model.name, &model.joints), data)?;
    calibration.noise_settled = Some(settled);
    calibration.warnings.extend(warning);
    if data.assumed_sigmas < data.observations.len() {
        calibration.warnings.push(Warning::SigmaIgnored);
    }
    calibration.noise_estimate = Some(estimate);
    Ok(calibration)
}

/// `data` with every observation's sigma its class's in `estimate`
/// ([`NoiseEstimate::weighting_sigma`]; its own for a class `estimate` does not hold: a
/// held-out file's other kinds), none counted as assumed.
pub(super) fn with_class_sigmas(data: &KindData, estimate: &NoiseEstimate) -> KindData {
    let sigma = |o: &super::Observation| match estimate.measurement.contains(&o.class()) {
        true => estimate.weighting_sigma(o.class()),
        false => o.sigma(),
    };
    let observations = data.observations.iter().map(|o| o.with_sigma(sigma(o))).collect();
    // The classes' variances in place of the sigmas and of any device's covariance.
    KindData { observations, assumed_sigmas: 0, device: Vec::new(), ..data.clone() }
}

/// The variance components fitted to the residuals of `c` on its training `data` (its rows:
/// an arm's observations or a tree's views), each pose's block one sample: calibrated by
/// ordinary least squares without `previous`, else weighted with it (where the fit of the
/// components starts).
pub(in crate::calibration) fn residual_noise<R: Robot>(
    c: &Calibration<R>,
    data: &KindData,
    joints: JointComponents,
    previous: Option<&NoiseEstimate>,
) -> Result<NoiseEstimate, CalibrationError> {
    let weighted = previous.map(|e| with_class_sigmas(data, e));
    residual_noise_on(c, weighted.as_ref().unwrap_or(data), joints, previous)
}

/// [`residual_noise`] of `data` that carries the sigmas of `previous` already
/// ([`with_class_sigmas`]; `data` itself without `previous`).
fn residual_noise_on<R: Robot>(
    c: &Calibration<R>,
    data: &KindData,
    joints: JointComponents,
    previous: Option<&NoiseEstimate>,
) -> Result<NoiseEstimate, CalibrationError> {
    let (kept, kept_setup) = c.estimated();
    let noise = previous.map(NoiseEstimate::joint_covariance);
    let mut problem = c.problem_at_estimate(data, &kept, kept_setup, noise.as_ref());
    let estimator = if previous.is_some() { Estimator::Wls } else { Estimator::Ols };
    let weights = Weights::for_problem(&problem, estimator)?;
    // `V_k` is in the weights now, not held through the samples.
    problem.v = None;
    let (layout, classes) = problem.noise_layout();
    let dof = layout.dof;
    // Each pose's rows built where the samples need them, `H` never held.
    let samples = residual_samples(&problem.rows_at(&problem.start()), &weights, &layout, joints)?;
    drop((weights, layout));
    Ok(NoiseEstimate::fit(&samples, joints, dof, classes, previous)?)
}
