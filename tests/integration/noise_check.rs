//! The noise given against the residuals: a guess off by more than a factor 2 is warned of,
//! with the factor the residuals say and the cross-validated error at both.

use super::nested::{MARKER, given, measured, options};
use rand::SeedableRng;
use rand::rngs::ChaCha8Rng;
use robocal::calibration::kinds::KindData;
use robocal::calibration::kinds::{KindOptions, calibrate_kinds};
use robocal::calibration::{Cause, Loss, Warning};
use robocal::estimation::{Estimator, MeasurementNoise, NoiseModel};
use robocal::kinematics::Chain;
use robocal::model::RobotModel;

/// Measurement noise of `sigma` mm per axis, exact joints.
fn noise(sigma: f64) -> NoiseModel {
    NoiseModel {
        joint: nalgebra::DMatrix::zeros(6, 6),
        measurement: MeasurementNoise::PerAxis([sigma, sigma, sigma, 0.0, 0.0, 0.0]),
    }
}

/// Gauss-Markov with the noise said to be `sigma` mm per axis: the options, and `data` with
/// that sigma on each coordinate (as `--noise` gives it).
fn said(data: &KindData, sigma: f64) -> (KindOptions, KindData) {
    let model = RobotModel::preset("puma560").unwrap();
    (crate::marker_options(&model, Estimator::Wls, Some(&noise(sigma)), &[MARKER]), given(data, sigma))
}

/// A PUMA 560 measured with 0.2 mm of noise (60 poses), calibrated by Gauss-Markov with the
/// noise said to be 0.05 mm, 0.2 mm and 0.8 mm: the right one passes, the others are warned of
/// once, with the factor the residuals say within 20% of the truth (4 and 1/4), no joint factor
/// (no joint noise given), and the cross-validated errors at both.
#[test]
fn a_guessed_noise_off_by_a_factor_4_is_warned_of() {
    let model = RobotModel::preset("puma560").unwrap();
    let chain = Chain::markers(&model, &[MARKER]).remove(0);
    let x: Vec<f64> = (0..chain.params().len()).map(|i| if i % 3 == 0 { 1e-3 } else { 0.0 }).collect();
    let data = measured(&x, 60, 0.8, 0.2, &mut ChaCha8Rng::seed_from_u64(5));
    let disagreement = |sigma: f64| {
        let (o, data) = said(&data, sigma);
        let c = calibrate_kinds(&model, &data, &o).unwrap();
        let found: Vec<&Warning> = c.warnings.iter().filter(|w| w.cause() == Cause::NoiseDisagrees).collect();
        assert!(found.len() <= 1, "{found:?}");
        found.first().map(|w| match w {
            Warning::NoiseDisagrees(n) => (*n, w.to_string()),
            _ => unreachable!(),
        })
    };
    assert_eq!(disagreement(0.2), None);
    for (sigma, factor) in [(0.05, 4.0), (0.8, 0.25)] {
        let (n, text) = disagreement(sigma).unwrap();
        assert!((n.measurement_factor / factor - 1.0).abs() < 0.2, "{sigma}: {n:?}");
        assert!((n.whitened_sd / factor - 1.0).abs() < 0.2, "{sigma}: {n:?}");
        assert_eq!((n.joint_factor, n.folds), (None, 5));
        assert!(
            n.cv_given > 0.15 && n.cv_given < 0.5 && n.cv_estimated > 0.15 && n.cv_estimated < 0.5,
            "{n:?}"
        );
        assert!(text.starts_with("the noise given disagrees with the residuals: their REML estimate is the measurement sigmas x"), "{text}");
        assert!(text.contains("5-fold CV RMS"), "{text}");
    }
}

/// Without a noise model (OLS, nothing given) nothing is checked.
#[test]
fn nothing_given_nothing_checked() {
    let model = RobotModel::preset("puma560").unwrap();
    let data = measured(
        &vec![0.0; Chain::markers(&model, &[MARKER])[0].params().len()],
        30,
        0.8,
        0.2,
        &mut ChaCha8Rng::seed_from_u64(6),
    );
    let c = calibrate_kinds(&model, &data, &options()).unwrap();
    assert!(c.warnings.iter().all(|w| w.cause() != Cause::NoiseDisagrees), "{:?}", c.warnings);
}

/// The noise is checked under a robust loss too (it was skipped): Huber's loss on data measured
/// with 0.2 mm of noise, said to be 0.05 mm, is warned of with the factor within 20% of 4.
/// The warning says whether the estimate moves with the noise: scaling every sigma alike moves
/// no estimate without priors and joint noise (below 1e-6 of a standard error: "barely
/// moves"); with priors on the joint parameters, the noise estimated 4 times the given weighs
/// each prior 16 times more against the data, and the estimate moves by more than 0.1 standard
/// errors, the text saying by how much.
#[test]
fn the_noise_is_checked_under_a_robust_loss_and_says_whether_the_estimate_moves() {
    let model = RobotModel::preset("puma560").unwrap();
    let chain = Chain::markers(&model, &[MARKER]).remove(0);
    let x: Vec<f64> = (0..chain.params().len()).map(|i| if i % 3 == 0 { 1e-3 } else { 0.0 }).collect();
    let data = measured(&x, 60, 0.8, 0.2, &mut ChaCha8Rng::seed_from_u64(5));
    let (given, data) = said(&data, 0.05);
    let disagreement = |o: KindOptions| {
        let c = calibrate_kinds(&model, &data, &o).unwrap();
        c.warnings.iter().find_map(|w| match w {
            Warning::NoiseDisagrees(n) => Some((*n, w.to_string())),
            _ => None,
        })
    };
    let huber = KindOptions { loss: Loss::Huber(1.345), ..given.clone() };
    let (n, text) = disagreement(huber).expect("checked under Huber's loss");
    assert!((n.measurement_factor / 4.0 - 1.0).abs() < 0.2, "{n:?}");
    assert!(text.contains("the estimate barely moves with them"), "{text}");

    let (n, text) = disagreement(given.clone()).unwrap();
    assert!(n.estimate_shift < 1e-6, "{n:?}");
    assert!(
        text.contains("the estimate barely moves with them (by at most 0.000 standard errors)"),
        "{text}"
    );
    let prior =
        robocal::estimation::PriorEntry::parse_list("lengths=0.05mm,angles=0.005deg,offsets=0.005deg")
            .unwrap();
    let (n, text) = disagreement(KindOptions { prior, ..given }).unwrap();
    println!("with priors: {n:?}");
    assert!(n.estimate_shift > 0.1, "{n:?}");
    assert!(
        text.contains(&format!(
            "the estimate moves with them by up to {:.2} standard errors",
            n.estimate_shift
        ))
    );
}
