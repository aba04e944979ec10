//! Robust fitting: one gross error among 100 poses, under OLS and Gauss-Markov.

use nalgebra::Vector3;
use robocal::calibration::Loss;
use robocal::calibration::kinds::{KindCalibration, KindData, KindOptions, Observation, calibrate_kinds};
use robocal::estimation::Estimator;
use robocal::model::RobotModel;

/// Calibration's campaign (`campaign_of`: a PUMA 560 with errors, an unknown base and two
/// markers, 0.01 mm of noise and its joint noise) as `robocal calibrate` reads its marker files:
/// the nominal model, the training file (`poses` poses) and the held-out one (60 poses), and
/// the design markers.
struct Campaign {
    nominal: RobotModel,
    training: String,
    validation: String,
    markers: Vec<Vector3<f64>>,
}

fn campaign(seed: u64, poses: usize) -> Campaign {
    let (nominal, _, _, [training, validation]) = crate::calibration::campaign_files(seed, poses);
    Campaign { nominal, training, validation, markers: crate::calibration::CAMPAIGN_MARKERS.to_vec() }
}

impl Campaign {
    /// Its training and held-out data and its options: by Gauss-Markov with the true noise, or
    /// (`ols`) by ordinary least squares with no noise given.
    fn read(&self, ols: bool) -> (KindData, KindData, KindOptions) {
        let noise = crate::calibration::campaign_noise();
        let (estimator, noise) = if ols { (Estimator::Ols, None) } else { (Estimator::Wls, Some(&noise)) };
        let read = |text: &str| crate::marker_data(text, &self.nominal, noise);
        let options = crate::marker_options(&self.nominal, estimator, noise, &self.markers);
        (read(&self.training), read(&self.validation), options)
    }
}

/// The lines of the observations `indices` of `data`, each once.
fn lines_of(data: &KindData, indices: impl Iterator<Item = usize>) -> Vec<usize> {
    let mut lines: Vec<usize> = indices.map(|k| data.lines[k]).collect();
    lines.dedup();
    lines
}

/// The lines of the training observations `c` flagged, each once.
fn flagged(c: &KindCalibration, data: &KindData) -> Vec<usize> {
    lines_of(data, c.training.flagged().map(|(k, _)| k))
}

/// A marker read 1 m off at one of 100 training poses: least squares is pulled far off, a
/// Huber (or Cauchy) loss leaves the held-out RMS within 10% of the fit on clean data, and the
/// bad pose is the one pose down-weighted, and the one flagged, for OLS and for WLS.
#[test]
fn one_gross_outlier_among_100_poses_is_down_weighted_and_flagged_alone() {
    let c = campaign(31, 100);
    for ols in [false, true] {
        let (training, validation, options) = c.read(ols);
        let held_out = |data: &KindData, options: &KindOptions| {
            let result = calibrate_kinds(&c.nominal, data, options).unwrap();
            (result.score(&validation).unwrap().markers.unwrap().1, result)
        };
        let (clean, _) = held_out(&training, &options);
        let mut bad = training.clone();
        let k = (bad.observations.iter())
            .position(|o| matches!(o, Observation::Marker { marker: 0, axis: 0, pose: 40, .. }))
            .unwrap();
        if let Observation::Marker { measured, .. } = &mut bad.observations[k] {
            *measured += 1000.0;
        }
        let line = bad.lines[k];
        let (pulled, plain) = held_out(&bad, &options);
        assert!(pulled > 10.0 * clean, "least squares is pulled: {pulled:.4} mm against {clean:.4} mm");
        assert_eq!(
            flagged(&plain, &bad),
            [line],
            "only the outlier is flagged by the fit it pulled (ols: {ols})"
        );
        for loss in [Loss::Huber(Loss::HUBER_K), Loss::Cauchy(Loss::CAUCHY_K)] {
            let options = KindOptions { loss, ..options.clone() };
            let (robust, result) = held_out(&bad, &options);
            assert!(
                robust <= 1.1 * clean,
                "{loss} (ols: {ols}): held-out RMS {robust:.4} mm, clean fit {clean:.4} mm"
            );
            let fit = result.robust.as_ref().expect("a robust fit");
            assert!(fit.settled, "{fit:?}");
            let listed = lines_of(&bad, fit.down_weighted().map(|(k, _)| k));
            assert_eq!(listed, [line], "{loss} (ols: {ols})");
            assert_eq!(flagged(&result, &bad), [line], "{loss} (ols: {ols})");
        }
    }
}

/// A robust fit with priors gives the same numbers, to the bit, on 1 and 3 threads.
#[test]
fn a_robust_fit_with_priors_is_the_same_on_any_number_of_threads() {
    let (mut training, _, options) = campaign(33, 100).read(false);
    let nominal = RobotModel::preset("puma560").unwrap();
    for o in &mut training.observations {
        if let Observation::Marker { marker: 0, axis: 1, pose: 7, measured, .. } = o {
            *measured -= 50.0;
        }
    }
    let options = KindOptions {
        loss: Loss::Cauchy(Loss::CAUCHY_K),
        prior: robocal::estimation::PriorEntry::parse_list("machined").unwrap(),
        ..options
    };
    let on = |threads| {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        pool.install(|| calibrate_kinds(&nominal, &training, &options).unwrap())
    };
    let (one, three) = (on(1), on(3));
    assert_eq!(one.after, three.after);
    assert_eq!(one.refined, three.refined);
    assert_eq!(one.robust, three.robust);
    let mut listed: Vec<usize> =
        one.robust.as_ref().unwrap().down_weighted().map(|(k, _)| training.observations[k].pose()).collect();
    listed.dedup();
    assert_eq!(listed, [7]);
}
