//! Every tool of the one calibration pipeline on every kind of observation: a simulated PUMA
//! 560 with known joint errors measured by markers, a 6-DOF probe, a ball bar, a length artefact, plane
//! contacts, a height gauge, a wrist camera and a fixed camera; each calibrated plainly (wls), with a prior,
//! a robust loss, a held parameter, the diagonal weights and feasible GLS, and cross-validated. Each tool's
//! held-out error is within 1.2 times the plain fit's or better (the tools must not cost
//! accuracy on data that need none of them), and the k-fold figure is within a factor 1.5 of
//! the held-out one (both estimate the same error).

use crate::camera::{flange, truth, views};
use crate::kinds::{TOOL, ball_bar, contacts, errors_on, heights, options, pairs, puma};
use crate::kinds_markers::{chains, marker_options, markers, true_chains};
use nalgebra::Vector3;
use rand::SeedableRng;
use rand::rngs::ChaCha8Rng;
use robocal::calibration::FeasibleOptions;
use robocal::calibration::kinds::{
    CameraSite, KindCalibration, KindData, KindOptions, RowSigmaDefaults, calibrate_kinds,
    calibrate_kinds_feasible, cross_validate_kinds,
};
use robocal::calibration::selection::{
    Choices, Criterion, SelectionPath, calibrate_chosen, cross_validate_choices,
};
use robocal::calibration::{Gauge, Kinds, Loss};
use robocal::estimation::{Estimator, MeasurementClass, PriorEntry};
use robocal::kinematics::{Chain, ChainAt};
use robocal::model::Placement;

/// A kind's training and held-out data of one true robot, and its plain options.
struct Case {
    name: &'static str,
    training: KindData,
    validation: KindData,
    plain: KindOptions,
}

/// Joint errors only (what every kind sees), on `chain`.
fn joint_errors(chain: &Chain, rng: &mut ChaCha8Rng) -> Vec<f64> {
    let joints: Vec<String> =
        chain.params().iter().filter(|p| p.name.starts_with('j')).map(|p| p.name.clone()).collect();
    errors_on(chain, &joints, rng)
}

/// A kind measured by the tool point (`measure`), twice: training and held out.
fn tool_point_case(
    name: &'static str,
    seed: u64,
    measure: &dyn Fn(&ChainAt, &mut ChaCha8Rng) -> KindData,
) -> Case {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let chain = Chain::markers(&puma(), &[TOOL]).remove(0);
    let real = chain.with_errors(&joint_errors(&chain, &mut rng));
    let (training, validation) = (measure(&real, &mut rng), measure(&real, &mut rng));
    Case { name, training, validation, plain: options(Estimator::Wls) }
}

/// A camera at `site`: 60 views to train, 60 held out (0.05 mm, 0.01 deg).
fn camera_case(name: &'static str, site: CameraSite, seed: u64) -> Case {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let chain = flange(&puma());
    let real = chain.with_errors(&joint_errors(&chain, &mut rng));
    let view = |rng: &mut ChaCha8Rng| views(&real, site, &truth(site), 60, (0.05, 0.01), rng);
    let (training, validation) = (view(&mut rng), view(&mut rng));
    Case {
        name,
        training,
        validation,
        plain: KindOptions { estimator: Estimator::Wls, ..KindOptions::default() },
    }
}

/// A 6-DOF probe (marker 1's position and its frame's orientation, a quaternion) mounted
/// turned, on a robot with errors on every joint parameter and a far base, read with 0.01 mm
/// and 0.01 deg of noise (each row's sigma given): 80 poses to train, 60 held out.
fn probe_case(seed: u64) -> Case {
    use rand::RngExt;
    use rand_distr::{Distribution, StandardNormal};
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let nominal = puma();
    let truth = crate::calibration::true_robot(&nominal, &mut rng);
    let mounting = Placement { xyz: Vector3::new(52.0, 1.0, 148.0), rpy: Vector3::new(0.3, -0.2, 0.5) };
    let chain = Chain::probe(&truth, &mounting);
    let real = chain.with_errors(&vec![0.0; chain.params().len()]);
    let defaults = RowSigmaDefaults { length_mm: Some(0.01), angle_rad: Some(0.01f64.to_radians()) };
    let mut read = |count: usize| {
        let mut text = String::from(crate::calibration::PROBE_HEADER);
        for _ in 0..count {
            let q: Vec<f64> =
                nominal.joints.iter().map(|j| rng.random_range(j.limits[0]..j.limits[1])).collect();
            let pose = real.pose(&q);
            let mut normal = |s: f64| -> f64 {
                let z: f64 = StandardNormal.sample(&mut rng);
                s * z
            };
            let p = pose.translation.vector + Vector3::new(normal(0.01), normal(0.01), normal(0.01));
            let turn = Vector3::new(normal(1.0), normal(1.0), normal(1.0)) * 0.01f64.to_radians();
            let r = pose.rotation * nalgebra::UnitQuaternion::from_scaled_axis(turn);
            text += &crate::calibration::probe_row(&q, &p, &r);
        }
        KindData::from_csv_str_with(&text, &nominal, None, defaults).unwrap()
    };
    let (training, validation) = (read(80), read(60));
    let plain = KindOptions { markers: vec![Vector3::new(50.0, 0.0, 150.0)], ..options(Estimator::Wls) };
    Case { name: "6-DOF probe", training, validation, plain }
}

/// Three markers seen by a tracker: 40 poses to train, 40 held out.
fn marker_case(seed: u64) -> Case {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let real = true_chains(&joint_errors(&chains()[0], &mut rng));
    let (training, validation) = (markers(&real, 40, &mut rng, 0.01), markers(&real, 40, &mut rng, 0.01));
    Case { name: "markers", training, validation, plain: marker_options(Estimator::Wls) }
}

fn cases() -> Vec<Case> {
    vec![
        marker_case(61),
        probe_case(69),
        tool_point_case("ball bar", 62, &|real, rng| ball_bar(real, rng, 0.01)),
        tool_point_case("length artefact", 63, &|real, rng| pairs(real, rng, 0.01)),
        tool_point_case("plane contacts", 64, &|real, rng| contacts(3)(real, rng, 0.01)),
        tool_point_case("height gauge", 68, &|real, rng| heights(real, rng, 0.01)),
        camera_case("wrist camera", CameraSite::Hand, 65),
        camera_case("fixed camera", CameraSite::World, 66),
    ]
}

/// The held-out RMS (mm) of `case` calibrated with `options`.
fn held_out(case: &Case, options: &KindOptions) -> f64 {
    let c =
        calibrate_kinds(&puma(), &case.training, options).unwrap_or_else(|e| panic!("{}: {e}", case.name));
    c.score(&case.validation).unwrap().lengths.1
}

#[test]
fn every_tool_works_on_every_kind_as_well_as_the_plain_fit() {
    for case in cases() {
        let plain = held_out(&case, &case.plain);
        assert!(plain < 0.1, "{}: plain wls held out {plain} mm", case.name);
        let features = [
            (
                "--prior machined",
                KindOptions { prior: PriorEntry::parse_list("machined").unwrap(), ..case.plain.clone() },
            ),
            ("--loss huber", KindOptions { loss: Loss::Huber(1.345), ..case.plain.clone() }),
            (
                "--hold j6.d",
                KindOptions {
                    gauge: Gauge { hold: vec!["j6.d".into()], keep: Vec::new() },
                    ..case.plain.clone()
                },
            ),
            ("--estimator wls-diag", KindOptions { estimator: Estimator::WlsDiag, ..case.plain.clone() }),
        ];
        for (feature, options) in &features {
            let found = held_out(&case, options);
            assert!(
                found < 1.2 * plain,
                "{} {feature}: held out {found} mm, plain wls {plain} mm",
                case.name
            );
        }
        let folds = cross_validate_kinds(&puma(), &case.training, &case.plain, 5).unwrap().lengths.1;
        assert!(
            folds < 1.5 * plain && plain < 1.5 * folds,
            "{}: 5-fold {folds} mm against held out {plain} mm",
            case.name
        );
    }
}

/// `--estimator fgls` on every kind: the joint noise and each kind's measurement noise
/// estimated from the residuals, settled, and the held-out error within 1.2 times the plain
/// fit's (which is given each row's true sigma). These data have no joint noise: at least 90%
/// of the components (each joint's zero, each kind's sigma: 0.01 mm; the camera's 0.05 mm and
/// 0.01 deg, the probe's orientation 0.01 deg) in their 95% intervals. (What a kind barely sees is barely determined: plane
/// contacts put the sixth joint's sigma anywhere up to 0.02 deg.)
#[test]
fn fgls_works_on_every_kind_as_well_as_the_plain_fit() {
    let (mut covered, mut checks) = (0, 0);
    for case in cases() {
        let plain = held_out(&case, &case.plain);
        let c = calibrate_kinds_feasible(&puma(), &case.training, &case.plain, &FeasibleOptions::default())
            .unwrap_or_else(|e| panic!("{} fgls: {e}", case.name));
        let found = c.score(&case.validation).unwrap().lengths.1;
        eprintln!("{}: held out fgls {found:.5} mm, plain wls {plain:.5} mm", case.name);
        assert!(found < 1.2 * plain, "{} fgls: held out {found} mm, plain wls {plain} mm", case.name);
        assert_eq!(c.noise_settled, Some(true), "{}: {:?}", case.name, c.warnings);
        let estimate = c.noise_estimate.as_ref().unwrap();
        let joints = (0..6).map(|j| (format!("j{}", j + 1), estimate.joint_sigma(j), 0.0));
        let classes = estimate.measurement_sigmas().into_iter().map(|(class, s)| {
            let truth = match class {
                MeasurementClass::CameraPosition => 0.05,
                MeasurementClass::CameraRotation | MeasurementClass::Orientation => 0.01f64.to_radians(),
                _ => 0.01,
            };
            (class.name().to_string(), s, truth)
        });
        for (name, s, truth) in joints.chain(classes) {
            if !s.contains(truth) {
                eprintln!("{} fgls: {name} {truth:.3e} outside {s:?}", case.name);
            }
            covered += usize::from(s.contains(truth));
            checks += 1;
        }
    }
    assert!(10 * covered >= 9 * checks, "{covered} of {checks} components in their 95% intervals");
}

/// `--prior auto:machined` on every kind: the scale chosen by 5-fold cross-validation of the
/// training data, held out within 1.2 times the plain fit's error, and its nested 5-fold
/// figure (the scale chosen again in each fold) within a factor 1.5 of the held-out one.
#[test]
fn a_scaled_prior_works_on_every_kind_as_well_as_the_plain_fit() {
    let auto = robocal::calibration::prior_scale::AutoPrior::parse("auto:machined").unwrap().unwrap();
    let choices = Choices { auto_prior: Some((auto, 5)), select: None };
    for case in cases() {
        let plain = held_out(&case, &case.plain);
        let chosen = calibrate_chosen(&Kinds(&puma()), &case.training, &case.plain, &choices)
            .unwrap_or_else(|e| panic!("{}: {e}", case.name));
        assert!(chosen.scale.is_some(), "{}: a scale chosen", case.name);
        let found = chosen.calibration.score(&case.validation).unwrap().lengths.1;
        assert!(found < 1.2 * plain, "{} --prior auto: held out {found} mm, plain wls {plain} mm", case.name);
        let nested =
            cross_validate_choices(&Kinds(&puma()), &case.training, &case.plain, &choices, 5).unwrap();
        let nested = nested.score.lengths.1;
        assert!(
            nested < 1.5 * found && found < 1.5 * nested,
            "{}: nested 5-fold {nested} mm against held out {found} mm",
            case.name
        );
    }
}

/// `--select criterion` alone on the puma's observations `data`: the path, and the calibration
/// of what it chose.
fn selected(
    data: &KindData,
    options: &KindOptions,
    criterion: Criterion,
) -> Result<(SelectionPath, KindCalibration), robocal::calibration::CalibrationError> {
    let choices = Choices { select: Some(criterion), auto_prior: None };
    let chosen = calibrate_chosen(&Kinds(&puma()), data, options, &choices)?;
    Ok((chosen.path.expect("a selection's path"), chosen.calibration))
}

/// `--select cv`, `bic` and `t` on every kind: each runs, chooses some of the joint parameters,
/// holds out within 1.2 times the plain fit's error, and its nested 5-fold figure (the
/// selection made again in each fold) is within a factor 1.5 of the held-out one.
#[test]
fn selection_works_on_every_kind_as_well_as_the_plain_fit() {
    for case in cases() {
        let plain = held_out(&case, &case.plain);
        for criterion in [Criterion::Cv { folds: 5 }, Criterion::Bic, Criterion::T] {
            let (path, c) = selected(&case.training, &case.plain, criterion)
                .unwrap_or_else(|e| panic!("{} {criterion:?}: {e}", case.name));
            let found = c.score(&case.validation).unwrap().lengths.1;
            let name = format!("{} --select {}", case.name, criterion.name());
            assert!(!path.selected.is_empty(), "{name}: chose nothing");
            assert!(found < 1.2 * plain, "{name}: held out {found} mm, plain wls {plain} mm");
            let every = c.refined.estimate.names.iter().filter(|n| n.starts_with('j')).count();
            assert_eq!(every, path.selected.len(), "{name}: calibrated what it chose");
        }
        let bic = Choices { select: Some(Criterion::Bic), auto_prior: None };
        let nested = cross_validate_choices(&Kinds(&puma()), &case.training, &case.plain, &bic, 5)
            .unwrap()
            .score
            .lengths
            .1;
        assert!(
            nested < 1.5 * plain && plain < 1.5 * nested,
            "{}: nested 5-fold {nested} mm against held out {plain} mm",
            case.name
        );
    }
}

/// A ball bar's robot with errors on three joint parameters only, measured with 0.05 mm of
/// noise: every selection keeps those three (here, exactly those), and each fit of what it
/// chose predicts exact held-out distances by a fifth or more better than the fit of every joint parameter (which fits the noise with
/// the parameters that have no error).
#[test]
fn selection_on_a_ball_bar_finds_the_few_parameters_in_error() {
    let mut rng = ChaCha8Rng::seed_from_u64(67);
    let chain = Chain::markers(&puma(), &[TOOL]).remove(0);
    let truth: Vec<String> = ["j2.theta", "j3.a", "j3.alpha"].map(String::from).to_vec();
    let mut x = errors_on(&chain, &truth, &mut rng);
    for name in &truth {
        let i = chain.params().index_by_name(name).unwrap();
        x[i] = x[i].signum() * if chain.params().get(i).kind.is_angle() { 0.2f64.to_radians() } else { 1.0 };
    }
    let real = chain.with_errors(&x);
    let (training, exact) = (ball_bar(&real, &mut rng, 0.05), ball_bar(&real, &mut rng, 0.0));
    let plain = options(Estimator::Wls);
    let full = calibrate_kinds(&puma(), &training, &plain).unwrap().score(&exact).unwrap().lengths.1;
    for criterion in [Criterion::Cv { folds: 5 }, Criterion::Bic, Criterion::T] {
        let (path, c) = selected(&training, &plain, criterion).unwrap();
        let name = criterion.name();
        for t in &truth {
            assert!(path.selected.contains(t), "--select {name} left out {t}: {:?}", path.selected);
        }
        let found = c.score(&exact).unwrap().lengths.1;
        assert!(found < 0.8 * full, "--select {name}: {found} mm held out, every parameter {full} mm");
    }
}
