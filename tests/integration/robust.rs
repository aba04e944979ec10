//! Robust fitting: one gross error among 100 poses, under OLS and Gauss-Markov.

use super::calibration::campaign_of;
use robocal::calibration::{self, Loss};
use robocal::estimation::Estimator;

/// A marker read 1 m off at one of 100 training poses: least squares is pulled far off, a
/// Huber (or Cauchy) loss leaves the held-out RMS within 10% of the fit on clean data, and the
/// bad pose is the one pose down-weighted, and the one flagged, for OLS and for WLS.
#[test]
fn one_gross_outlier_among_100_poses_is_down_weighted_and_flagged_alone() {
    for ols in [false, true] {
        let mut c = campaign_of(31, 100);
        if ols {
            c.options.estimator = Estimator::Ols;
            c.options.noise = None;
        }
        let held_out = |data: &calibration::Measurements, options: &calibration::Options| {
            let result = calibration::calibrate(&c.nominal, data, options).unwrap();
            (result.validate(&c.validation).1.rms, result)
        };
        let (clean, _) = held_out(&c.training, &c.options);
        let mut bad = c.training.clone();
        bad.markers[40][0].x += 1000.0;
        let line = bad.lines[40];
        let (pulled, plain) = held_out(&bad, &c.options);
        assert!(pulled > 10.0 * clean, "least squares is pulled: {pulled:.4} mm against {clean:.4} mm");
        let flagged: Vec<usize> = plain.training_poses.flagged().map(|p| p.line).collect();
        assert_eq!(flagged, [line], "only the outlier is flagged by the fit it pulled (ols: {ols})");
        for loss in [Loss::Huber(Loss::HUBER_K), Loss::Cauchy(Loss::CAUCHY_K)] {
            let options = calibration::Options { loss, ..c.options.clone() };
            let (robust, result) = held_out(&bad, &options);
            assert!(
                robust <= 1.1 * clean,
                "{loss} (ols: {ols}): held-out RMS {robust:.4} mm, clean fit {clean:.4} mm"
            );
            let fit = result.robust.as_ref().expect("a robust fit");
            assert!(fit.settled, "{fit:?}");
            let listed: Vec<usize> = fit.down_weighted().map(|(k, _)| bad.lines[k]).collect();
            assert_eq!(listed, [line], "{loss} (ols: {ols})");
            let flagged: Vec<usize> = result.training_poses.flagged().map(|p| p.line).collect();
            assert_eq!(flagged, [line], "{loss} (ols: {ols})");
        }
    }
}

/// A robust fit with priors gives the same numbers, to the bit, on 1 and 3 threads.
#[test]
fn a_robust_fit_with_priors_is_the_same_on_any_number_of_threads() {
    let mut c = campaign_of(33, 100);
    c.training.markers[7][1].y -= 50.0;
    let options = calibration::Options {
        loss: Loss::Cauchy(Loss::CAUCHY_K),
        prior: robocal::estimation::PriorEntry::parse_list("machined").unwrap(),
        ..c.options.clone()
    };
    let on = |threads| {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        pool.install(|| calibration::calibrate(&c.nominal, &c.training, &options).unwrap())
    };
    let (one, three) = (on(1), on(3));
    assert_eq!(one.after, three.after);
    assert_eq!(one.refined, three.refined);
    assert_eq!(one.robust, three.robust);
    let listed: Vec<usize> = one.robust.as_ref().unwrap().down_weighted().map(|(k, _)| k).collect();
    assert_eq!(listed, [7]);
}
