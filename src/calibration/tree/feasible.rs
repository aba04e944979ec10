//! Feasible GLS of a tree's views: the tree's joint variances and the views' position and
//! rotation variances estimated from the calibration's own residuals, by the rounds and the
//! fit of variance components of marker and observation files ([`reweighted`],
//! [`residual_samples`], [`NoiseEstimate`]). Each view is one block,
//! `V_k = G_k Sigma_q G_k^T + diag(sigma_p^2 I, sigma_r^2 I)`, `G_k` the derivative of its six
//! rows by the tree's joints (both its frames moved by their branches).

use super::{KindOptions, TreeCalibration, TreeData, calibrate_tree};
use crate::calibration::kinds::residual_noise;
use crate::calibration::{
    CalibrationError, FeasibleOptions, Loss, Reweighted, Warning, reweighted, unsettled,
};
use crate::estimation::{Estimator, MeasurementClass, NoiseEstimate};
use crate::model::RobotTree;

/// Feasible GLS of a tree's views: calibrate by ordinary least squares, fit the tree's joint
/// variances (or every entry of `Sigma_q`) and the views' position (mm) and rotation (rad)
/// variances to each view's residual outer product `r_k r_k^T`, whose expectation is
/// `(M V M^T)_kk`, `M` the residual maker of the weighted fit; calibrate again by Gauss-Markov
/// with `V_k` from the estimate; repeat until the components settle. The estimate is
/// [`TreeCalibration::noise_estimate`], with a [`Warning::NoiseUnsettled`] if it did not
/// settle and a [`Warning::SigmaIgnored`]. `options.estimator` and `options.joint_noise` are
/// not used; a prior or a robust loss is refused.
pub fn calibrate_tree_feasible(
    tree: &RobotTree,
    data: &TreeData,
    options: &KindOptions,
    feasible: &FeasibleOptions,
) -> Result<TreeCalibration, CalibrationError> {
    if !options.prior.is_empty() || options.loss != Loss::Squared {
        return Err(CalibrationError::Observations(
            "feasible GLS estimates the noise from the residuals of plain least squares: not with a prior \
             or a robust loss"
                .into(),
        ));
    }
    let ols = KindOptions { estimator: Estimator::Ols, joint_noise: None, ..options.clone() };
    let calibrate = |estimate: Option<&NoiseEstimate>| match estimate {
        None => calibrate_tree(tree, data, &ols),
        Some(e) => {
            let weighted = KindOptions {
                estimator: Estimator::Wls,
                joint_noise: Some(e.joint_covariance()),
                ..ols.clone()
            };
            calibrate_tree(tree, &with_estimated_sigmas(data, e), &weighted)
        }
    };
    let rows = data.observations(&data.frames);
    let estimate = |c: &TreeCalibration, previous: Option<&NoiseEstimate>| {
        residual_noise(c, &rows, feasible.joints, previous)
    };
    let rounds = reweighted(feasible, calibrate, estimate)?;
    let warning = unsettled(feasible, &rounds);
    let Reweighted { mut calibration, estimate, settled, .. } = rounds;
    calibration.noise_settled = Some(settled);
    calibration.warnings.extend(warning);
    calibration.warnings.push(Warning::SigmaIgnored);
    calibration.noise_estimate = Some(estimate);
    Ok(calibration)
}

/// `data` with every view's sigmas the estimate's ([`NoiseEstimate::weighting_sigma`]; its own
/// where the estimate has none).
fn with_estimated_sigmas(data: &TreeData, estimate: &NoiseEstimate) -> TreeData {
    // The sigmas estimated, no longer assumed.
    let mut data = TreeData { assumed_sigmas: false, ..data.clone() };
    for view in &mut data.views {
        for (s, class) in
            view.sigma.iter_mut().zip([MeasurementClass::CameraPosition, MeasurementClass::CameraRotation])
        {
            if estimate.measurement.contains(&class) {
                *s = estimate.weighting_sigma(class);
            }
        }
    }
    data
}
