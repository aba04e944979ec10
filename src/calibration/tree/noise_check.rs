//! Whether the noise given to a tree's views (their sigmas, the joint noise) agrees with the
//! residuals of its calibration, as for marker and observation files
//! ([`check`](super::super::noise_check::check)): each view's block (of at most
//! [`CHECK_POSES`] views, evenly spread) linearised about the estimate, by the check of every
//! kind ([`check_noise`]): each pose's views one block with its joint part
//! `G_k Sigma_q G_k^T` and its measurement part `diag(sigma_position^2, sigma_rotation^2)`,
//! the views' positions cross-validated (a view's position one error, its rotation none).

use super::{TreeCalibration, TreeData, TreeRows};
use crate::calibration::Warning;
use crate::calibration::kinds::check_noise;
use crate::calibration::noise_check::CHECK_POSES;

/// The check of `c`'s noise on its training `data`: `None` when it agrees, without a noise
/// given (every sigma assumed and the joints exact: the residuals' spread scales the fit
/// instead), or with too few residuals to tell; under any loss (the views far out are left out
/// of the check, as a robust loss leaves them out of the fit).
pub(super) fn tree_noise_check(c: &TreeCalibration, data: &TreeData) -> Option<Warning> {
    if c.joint_noise.is_none() && data.assumed_sigmas {
        return None;
    }
    let stride = data.views.len().div_ceil(CHECK_POSES).max(1);
    let mut sample = data.clone();
    sample.views = data.views.iter().step_by(stride).cloned().collect();
    sample.lines = data.lines.iter().step_by(stride).copied().collect();
    let (selection, setup_selection) = estimated(c);
    let observed = TreeRows::new(&c.params, &sample, &c.frames).ok()?;
    let selection = c.params.selection(&selection);
    let values = (c.after.clone(), c.setup_values.1.clone(), setup_selection);
    let problem = c.problem_on(&observed.rows, &selection, values, c.joint_noise.as_ref());
    let prior_sd: Vec<f64> = (c.refined.estimate.names.iter())
        .filter_map(|name| c.params.params.iter().position(|p| &p.name == name).map(|i| c.prior_sd[i]))
        .collect();
    // A view's position is one error, its rotation none.
    check_noise(&problem, |o| if o.is_angle() { 0.0 } else { 1.0 / 3.0 }, &prior_sd)
}

/// The robot's parameters `c` estimated (their indices among its parameters) and the
/// placements' (among its set-up's: the frames' six each, then the later sessions' own), by
/// the names of its estimate.
pub(super) fn estimated(c: &TreeCalibration) -> (Vec<usize>, Vec<usize>) {
    let setup = c.setup.names();
    let names = &c.refined.estimate.names;
    let robot = names.iter().filter_map(|n| c.params.params.iter().position(|p| &p.name == n)).collect();
    let placed = names.iter().filter_map(|n| setup.iter().position(|s| s == n)).collect();
    (robot, placed)
}
