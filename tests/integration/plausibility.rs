//! Estimates a real arm cannot have are warned of whatever their standard errors, and a fit
//! that did not converge says so with its last step.

use crate::kinds::{TOOL, ball_bar, options, puma};
use nalgebra::Vector3;
use rand::SeedableRng;
use rand::rngs::ChaCha8Rng;
use robocal::calibration::Warning;
use robocal::calibration::diagnostics::Bound;
use robocal::calibration::kinds::calibrate_kinds;
use robocal::estimation::Estimator;
use robocal::kinematics::Chain;
use robocal::model::RobotModel;

/// The parameters of each implausible warning of `warnings`, by bound.
fn implausible(warnings: &[Warning]) -> Vec<(Bound, Vec<String>)> {
    (warnings.iter())
        .filter_map(|w| match w {
            Warning::Implausible { bound, estimates } => {
                Some((*bound, estimates.iter().map(|e| e.parameter.clone()).collect()))
            }
            _ => None,
        })
        .collect()
}

/// A nominal PUMA whose `j2.a` is 30 mm and `j3.theta` 8 deg off the robot measured: the
/// calibration corrects both, and warns of each beside its bound (the registration's base, far
/// larger, is not warned of); the same robot within its bounds is not warned of. Markers
/// (`calibrate`) and a ball bar (`calibrate-observations`) alike.
#[test]
fn corrections_past_a_physical_bound_are_warned_for_every_kind() {
    let mut wrong = RobotModel::preset("puma560").unwrap();
    wrong.joints[1].a += 30.0;
    wrong.joints[2].theta += 8f64.to_radians();
    let text = std::fs::read_to_string("examples/puma560-measurements.csv").unwrap();
    let data = crate::marker_data(&text, &wrong, None);
    let design = [Vector3::new(50.0, 0.0, 150.0), Vector3::new(-40.0, 60.0, 120.0)];
    let markers = crate::marker_options(&wrong, Estimator::Ols, None, &design);
    let right = RobotModel::preset("puma560").unwrap();
    let plain = calibrate_kinds(&right, &data, &markers).unwrap();
    assert_eq!(implausible(&plain.warnings), []);
    let c = calibrate_kinds(&wrong, &data, &markers).unwrap();
    assert!(c.refined.converged);
    assert_eq!(
        implausible(&c.warnings),
        [(Bound::Length, vec!["j2.a".to_string()]), (Bound::Angle, vec!["j3.theta".to_string()])]
    );

    let mut rng = ChaCha8Rng::seed_from_u64(5);
    let real = Chain::markers(&puma(), &[TOOL]).remove(0);
    let real = real.with_errors(&vec![0.0; real.params().len()]);
    let bar = ball_bar(&real, &mut rng, 0.01);
    let kinds = options(Estimator::Wls);
    assert_eq!(implausible(&calibrate_kinds(&puma(), &bar, &kinds).unwrap().warnings), []);
    let c = calibrate_kinds(&wrong, &bar, &kinds).unwrap();
    let found = implausible(&c.warnings);
    assert_eq!(
        found,
        [(Bound::Length, vec!["j2.a".to_string()]), (Bound::Angle, vec!["j3.theta".to_string()])]
    );
}

/// `calibrate --iterations 2` stops before converging: the report warns with the steps and
/// the last step's size, and calls its parameters estimated, not identified: the marker
/// calibration's, and the observation fit's (`--tool 0,0,0` sends the file there), whose
/// line is the marker calibration's; converged, both say the same "identified" line.
#[test]
fn an_unconverged_calibration_is_warned_and_not_called_identified() {
    let run = |extra: &[&str]| crate::nested::calibrate_puma(extra).0;
    let line = |text: &str, part: &str| -> String {
        text.lines().find(|l| l.contains(part)).unwrap_or_else(|| panic!("{part}: {text}")).to_string()
    };
    let markers = run(&["--iterations", "2"]);
    let observations = run(&["--iterations", "2", "--tool", "0,0,0"]);
    for text in [&markers, &observations] {
        assert!(text.contains("(2 steps, not converged)"), "{text}");
        assert!(text.contains(" parameters estimated, not converged (rank "), "{text}");
        assert!(!text.contains("parameters identified"), "{text}");
        let warning =
            text.lines().find(|l| l.trim_start().starts_with("not converged in 2 steps: the last moved"));
        assert!(warning.is_some_and(|w| w.contains("standard deviations and lowered the cost by")), "{text}");
    }
    let unconverged = " parameters estimated, not converged";
    assert_eq!(line(&markers, unconverged), line(&observations, unconverged));
    let identified = " parameters identified (rank ";
    assert_eq!(line(&run(&[]), identified), line(&run(&["--tool", "0,0,0"]), identified));
}
