//! The synthetic benchmark built to overfit as real data does: a 7-joint arm with masses
//! (`examples/arm7/arm7.urdf`) whose true robot has origin and offset errors, gravity deflection
//! and play; few training poses from a narrow range; held-out sessions partly outside it, one
//! measured with a shifted instrument. The full parameter set with the gravity terms
//! (`joint*.*`) overfits; the choices made from the data (`--prior auto`, `--select cv`) should
//! not, and the nested k-fold figure should say what the held-out sessions find.

use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
use rand::rngs::ChaCha8Rng;
use rand::{RngExt, SeedableRng};
use rand_distr::{Distribution, StandardNormal};
use robocal::calibration::kinds::{KindData, KindOptions, calibrate_kinds};
use robocal::calibration::prior_scale::AutoPrior;
use robocal::calibration::selection::{Choices, Criterion, choose, cross_validate_choices};
use robocal::calibration::{JointParams, Kinds};
use robocal::estimation::Estimator;
use robocal::kinematics::Chain;
use robocal::model::{Placement, RobotModel, from_urdf_str};

const URDF: &str = include_str!("../../examples/arm7/arm7.urdf");
/// Joint deflection per unit of gravity torque (rad per N·m).
const COMPLIANCE: [f64; 7] = [0.0, 4e-5, 0.0, 6e-5, 0.0, 1.5e-4, 0.0];
/// Play of joint 6 (deg), with the sign of its gravity torque.
const PLAY_DEG: f64 = 0.03;
/// Measurement noise per coordinate (mm).
const SIGMA_MM: f64 = 0.2;
/// The share of each joint's range the training poses cover, about its middle.
const BAND: [f64; 7] = [0.4, 0.4, 0.4, 0.4, 0.2, 0.2, 0.2];
/// The markers' design positions (mm, plate frame); the true ones are off by about 0.4 mm.
const DESIGN: [[f64; 3]; 3] = [[40.0, 0.0, 25.0], [-20.0, 35.0, 25.0], [-20.0, -35.0, 25.0]];
const TRUE: [[f64; 3]; 3] = [[40.3, 0.4, 25.2], [-19.6, 35.3, 24.7], [-20.4, -34.8, 25.4]];

/// The nominal robot with random origin and offset errors (0.3 mm, 0.03 deg, 0.05 deg), its
/// joints deflecting under gravity ([`COMPLIANCE`]) and joint 6 with play: the model reaches
/// `q + c tau(q) + p sgn(tau(q))`.
fn true_robot(nominal: &RobotModel, rng: &mut ChaCha8Rng) -> RobotModel {
    let mut n = || -> f64 { StandardNormal.sample(rng) };
    let mut truth = nominal.clone();
    for (j, joint) in truth.joints.iter_mut().enumerate() {
        joint.compliance = COMPLIANCE[j];
        joint.play = if j == 5 { PLAY_DEG.to_radians() } else { 0.0 };
        let displacement = Isometry3::translation(0.3 * n(), 0.3 * n(), 0.3 * n())
            * UnitQuaternion::from_scaled_axis(Vector3::new(n(), n(), n()) * 0.03f64.to_radians());
        let offset = Isometry3::rotation(joint.axis * 0.05f64.to_radians() * n());
        joint.origin = Placement::from_isometry(&(joint.origin.isometry() * displacement * offset));
    }
    truth
}

/// `count` poses within [`BAND`], but a share `outside` drawn over the whole range.
fn poses(model: &RobotModel, count: usize, outside: f64, rng: &mut ChaCha8Rng) -> Vec<Vec<f64>> {
    let wide = (outside * count as f64).round() as usize;
    (0..count)
        .map(|k| {
            (model.joints.iter().enumerate())
                .map(|(i, j)| {
                    let share = if k < wide { 1.0 } else { BAND[i] };
                    let (mid, half) = ((j.limits[0] + j.limits[1]) / 2.0, (j.limits[1] - j.limits[0]) / 2.0);
                    mid + share * half * rng.random_range(-1.0..1.0)
                })
                .collect()
        })
        .collect()
}

/// The true robot's markers at `joints`, seen by an instrument placed at `instrument` from the
/// robot's base, with noise.
fn measure(
    truth: &RobotModel,
    joints: Vec<Vec<f64>>,
    instrument: &Isometry3<f64>,
    rng: &mut ChaCha8Rng,
) -> KindData {
    let markers: Vec<Vector3<f64>> = TRUE.iter().map(|m| Vector3::from(*m)).collect();
    let chains = Chain::markers(truth, &markers);
    let at: Vec<_> = chains.iter().map(|c| c.with_errors(&vec![0.0; c.params().len()])).collect();
    let mut noise = || {
        Vector3::from_fn(|_, _| {
            let z: f64 = StandardNormal.sample(&mut *rng);
            SIGMA_MM * z
        })
    };
    let measured: Vec<Vec<Vector3<f64>>> = (joints.iter())
        .map(|q| {
            at.iter()
                .map(|c| instrument.inverse_transform_point(&c.position(q).into()).coords + noise())
                .collect()
        })
        .collect();
    crate::nested::marker_kind_data(joints, &measured)
}

/// One robot of the benchmark: its training poses and its three held-out sessions, the third
/// measured by an instrument shifted by 0.3 mm and turned by 0.01 deg after the training.
struct Robot {
    train: KindData,
    sessions: Vec<KindData>,
}

fn robot(nominal: &RobotModel, seed: u64) -> Robot {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let truth = true_robot(nominal, &mut rng);
    let frame = Isometry3::identity();
    let shifted = Isometry3::from_parts(
        Translation3::new(0.3, -0.2, 0.1),
        UnitQuaternion::from_scaled_axis(Vector3::new(0.0, 0.0, 0.01f64.to_radians())),
    );
    let train = poses(nominal, 24, 0.0, &mut rng);
    let train = measure(&truth, train, &frame, &mut rng);
    let sessions = [frame, frame, shifted]
        .iter()
        .map(|at| {
            let q = poses(nominal, 30, 0.15, &mut rng);
            measure(&truth, q, at, &mut rng)
        })
        .collect();
    Robot { train, sessions }
}

/// The held-out RMS of the marker positions of the calibration of `robot` with `options`, the
/// sessions pooled.
fn held_out(model: &RobotModel, robot: &Robot, options: &KindOptions) -> f64 {
    let c = calibrate_kinds(model, &robot.train, options).unwrap();
    let (mut sse, mut n) = (0.0, 0.0);
    for s in &robot.sessions {
        let after = c.score(s).unwrap().markers.unwrap().1;
        let count = s.observations.len() as f64;
        sse += after * after * count;
        n += count;
    }
    (sse / n).sqrt()
}

/// The full model with gravity terms, OLS, the base and the design markers estimated.
fn full(model: &RobotModel) -> KindOptions {
    let design: Vec<Vector3<f64>> = DESIGN.iter().map(|m| Vector3::from(*m)).collect();
    KindOptions {
        joints: JointParams::Named(vec!["joint*.*".into()]),
        ..crate::marker_options(model, Estimator::Ols, None, &design)
    }
}

/// On 10 robots (24 training poses in a narrow band, three sessions of 30 held out), what
/// holds (measured on this benchmark, seeds 1-10, held-out RMS mm on average: full 0.581,
/// offsets 0.999, `--prior auto` 0.550, `--select cv` 0.588, `--prior auto-ml:classes` 0.501):
///
/// - the preset's scale chosen by cross-validation (`--prior auto:fabricated`, 3 folds) beats
///   the plain full fit and the offsets alone held out on average (on 7 of the 10 robots both,
///   not the 10: no assertion of it);
/// - a scale per class chosen by the marginal likelihood, the noise not given
///   (`--prior auto-ml:fabricated:classes` with OLS: the residuals' spread taken as the noise)
///   beats both on average by more, the offsets on every robot and the full fit on 9 of the
///   10 (asserted: at least 9), the tenth a tie (0.474 against 0.473 mm, seed 6);
/// - every choice beats the offsets on every robot; `--select cv` (3 folds) does not beat the
///   full fit on average here, and both on 6 robots only (not asserted either).
///
/// The selection's rule is not why (measured on these seeds, held-out mean against the full
/// fit's 0.581): the minimum-CV step 0.604, the one-standard-error rule with the standard error
/// of the paired fold differences against the best step 0.594 (half of it 0.601), half the
/// standard error 0.583; 5, 8 or 12 folds or one pose a fold, with either rule, 0.567-0.602;
/// the path ordered by the training cost, the step by CV, 0.582-0.586; folds of contiguous
/// blocks along the poses' first principal direction 0.69-0.70; `--prior auto` then
/// `--select cv` 0.589. Split by pose, the held-out error is the five wide poses' of each
/// session (full 0.99, `--select cv` 0.98, `--prior auto` 0.87, by class 0.73) over the
/// in-band ones' (0.45, 0.46, 0.45, 0.44): the true robot has every parameter, and a subset
/// chosen on in-band poses extrapolates as badly as the full fit, and no cross-validation on
/// the in-band training poses can see it. Nor is it that the truth is inside the model: with
/// an error no parameter holds added to every joint (a transmission error of 0.01 deg,
/// `sin(2 q_j + j)`), `--select cv` does worse (0.674 against the full fit's 0.592), while
/// `--prior auto` (0.589) and the scales per class (0.513, better than both on all 10) hold.
///
/// The nested 3-fold figure of `--prior auto` is within 15% of the held-out RMS on average
/// (0.92 of it), and the in-sample one (the chosen scale's own cross-validated RMS) is more
/// optimistic than it (0.86); the nested figure of the scales per class is within 15% too
/// (0.89 of it).
#[test]
fn the_choices_beat_the_full_fit_and_the_nested_figure_tells_the_truth() {
    let nominal = from_urdf_str(URDF, "base", "plate").unwrap();
    let auto = AutoPrior::parse("auto:fabricated").unwrap().unwrap();
    let classes = AutoPrior::parse("auto-ml:fabricated:classes").unwrap().unwrap();
    let folds = 3;
    let prior = Choices { auto_prior: Some((auto, folds)), select: None };
    let by_class = Choices { auto_prior: Some((classes, folds)), select: None };
    let select = Choices { auto_prior: None, select: Some(Criterion::Cv { folds }) };
    let full = full(&nominal);
    let offsets = KindOptions { joints: JointParams::Offsets, ..full.clone() };
    let mut rows = Vec::new();
    for seed in 1..=10 {
        let robot = robot(&nominal, seed);
        let chosen = |choices: &Choices| choose(&Kinds(&nominal), &robot.train, &full, choices).unwrap();
        let (by_prior, by_select, by_classes) = (chosen(&prior), chosen(&select), chosen(&by_class));
        let nested = |choices: &Choices| {
            cross_validate_choices(&Kinds(&nominal), &robot.train, &full, choices, folds)
                .unwrap()
                .score
                .markers
                .unwrap()
                .1
        };
        let scale = by_prior.scale.as_ref().unwrap();
        rows.push([
            held_out(&nominal, &robot, &full),
            held_out(&nominal, &robot, &offsets),
            held_out(&nominal, &robot, &by_prior.options),
            held_out(&nominal, &robot, &by_select.options),
            nested(&prior),
            scale.cv_rms[scale.chosen],
            held_out(&nominal, &robot, &by_classes.options),
            nested(&by_class),
        ]);
    }
    eprintln!(
        "full, offsets, auto, select cv, nested auto, in-sample auto, auto-ml:classes, nested: {rows:?}"
    );
    let mean = |c: usize| rows.iter().map(|r| r[c]).sum::<f64>() / rows.len() as f64;
    assert!(mean(2) < mean(0) && mean(2) < mean(1), "--prior auto on average: {rows:?}");
    assert!(mean(6) < mean(2), "the scales per class against --prior auto on average: {rows:?}");
    assert!(
        rows.iter().all(|r| r[2] < r[1] && r[3] < r[1] && r[6] < r[1]),
        "the choices against the offsets: {rows:?}"
    );
    let beat_full = rows.iter().filter(|r| r[6] < r[0]).count();
    assert!(beat_full >= 9, "the scales per class beat the full fit on {beat_full} of 10: {rows:?}");
    let ratio = |c: usize, of: usize| rows.iter().map(|r| r[c] / r[of]).sum::<f64>() / rows.len() as f64;
    assert!((ratio(4, 2) - 1.0).abs() < 0.15, "nested / held out {}: {rows:?}", ratio(4, 2));
    assert!(
        ratio(5, 2) < ratio(4, 2),
        "in-sample / held out {} against nested {}: {rows:?}",
        ratio(5, 2),
        ratio(4, 2)
    );
    assert!((ratio(7, 6) - 1.0).abs() < 0.15, "nested / held out per class {}: {rows:?}", ratio(7, 6));
}
