//! Selection and the gauge respect the physics (#24 item 3): what no gravity load moves is
//! held on the observation path as on the marker path, a payload's mass held at the start is
//! freed where the fitted compliances see it, and a joint's zero or play is never left out
//! while parameters that can only stand in for it (one, or a group) are chosen, unless the
//! report says the trade.

use crate::selection::arm7;
use crate::urdf::arm7_options;
use nalgebra::{DMatrix, DVector, Vector3};
use rand::SeedableRng;
use rand::rngs::ChaCha8Rng;
use robocal::calibration::kinds::{KindData, KindOptions, calibrate_kinds};
use robocal::calibration::selection::{Criterion, select};
use robocal::calibration::{Held, JointParams, Kinds, Warning};
use robocal::estimation::{Estimator, PriorEntry};
use robocal::kinematics::Chain;
use robocal::model::{Payload, RobotModel};

/// The PUMA 560 with link masses (its first axis vertical: gravity never loads it), no
/// compliance, a nominal payload of 2 kg.
fn rigid_puma() -> RobotModel {
    let mut model = crate::compliance::puma_with_masses();
    model.payload = Some(Payload { mass: 2.0, com: Vector3::new(0.0, 20.0, 80.0) });
    model
}

/// On the observation path (every marker file's calibration), the first joint's compliance and
/// play (a vertical axis: no load at any pose) are held as unloaded, not estimated nor left to
/// the rank; the payload's mass, unseen at the start (every compliance zero there), is freed by
/// the gauge found again at the estimate, where the fitted compliances see it, and said so: the
/// truth (3.5 kg, the second and third joints' compliances 5e-5 and 8e-5 rad/N·m) is recovered
/// from noise-free data. Before, the mass was held as unmoved and never freed (the fit said 2 kg).
#[test]
fn unloaded_responses_are_held_and_a_payloads_mass_is_freed_at_the_estimate() {
    let nominal = rigid_puma();
    let mut truth = nominal.clone();
    truth.joints[1].compliance = 5e-5;
    truth.joints[2].compliance = 8e-5;
    truth.payload = Some(Payload { mass: 3.5, com: Vector3::new(0.0, 20.0, 80.0) });
    let markers = [Vector3::new(40.0, 0.0, 25.0), Vector3::new(-20.0, 35.0, 25.0)];
    let data = crate::nested::given(&crate::compliance::measured(&truth, &markers, 60, 11), 0.01);
    let asked = ["payload.mass", "j1.compliance", "j1.play", "j2.compliance", "j3.compliance", "j*.theta"];
    let options = KindOptions {
        estimator: Estimator::Ols,
        joints: JointParams::Named(asked.iter().map(|s| s.to_string()).collect()),
        estimate_base: false,
        estimate_markers: false,
        markers: markers.to_vec(),
        ..KindOptions::default()
    };
    let c = calibrate_kinds(&nominal, &data, &options).unwrap();
    let held: Vec<&Held> = c.fixed.iter().collect();
    for name in ["j1.compliance", "j1.play"] {
        assert!(
            held.iter().any(|h| matches!(h, Held::Unloaded { parameter } if parameter == name)),
            "{name}: {held:?}"
        );
    }
    assert!(c.refined.converged);
    let freed = c.warnings.iter().find_map(|w| match w {
        Warning::GaugeMoved { freed, .. } => Some(freed.clone()),
        _ => None,
    });
    assert_eq!(freed, Some(vec!["payload.mass".to_string()]), "{:?}", c.warnings);
    let mass = c.calibrated.payload.unwrap().mass;
    assert!((mass - 3.5).abs() < 1e-6, "payload {mass} kg, truth 3.5");
    for (j, compliance) in [(1, 5e-5), (2, 8e-5)] {
        let found = c.calibrated.joints[j].compliance;
        assert!((found - compliance).abs() < 1e-6 * compliance, "joint {}: {found:e}", j + 1);
    }
}

/// The correlation of the estimate at position `z` of covariance `c` with the group `g`
/// (positions): signed for one, the multiple correlation `sqrt(r_zg^T R_gg^-1 r_gz)` of more;
/// NaN where the group's correlations are singular.
fn correlation(c: &DMatrix<f64>, z: usize, g: &[usize]) -> f64 {
    let r = |a: usize, b: usize| c[(a, b)] / (c[(a, a)] * c[(b, b)]).sqrt();
    if let [k] = g {
        return r(z, *k);
    }
    let inner = DMatrix::from_fn(g.len(), g.len(), |a, b| r(g[a], g[b]));
    let cross = DVector::from_fn(g.len(), |a, _| r(z, g[a]));
    inner.cholesky().map_or(f64::NAN, |l| cross.dot(&l.solve(&cross)).sqrt())
}

/// The strongest stand-in for `zero` among `chosen`, computed here: the largest correlation
/// (in magnitude) of its estimate with one chosen parameter or a group of two or three, from
/// the calibration of `chosen` with `zero` added back; `None` if the zero is not estimated there.
fn strongest_stand_in(
    model: &RobotModel,
    train: &KindData,
    options: &KindOptions,
    chosen: &[String],
    zero: &str,
) -> Option<f64> {
    let names: Vec<String> = chosen.iter().cloned().chain([zero.to_string()]).collect();
    let c =
        calibrate_kinds(model, train, &KindOptions { joints: JointParams::Named(names), ..options.clone() })
            .unwrap();
    let e = &c.refined.estimate;
    let at = |n: &str| e.names.iter().position(|m| m == n);
    let z = at(zero)?;
    let zero_or_play = |n: &str| n.ends_with(".theta") || n.ends_with(".play");
    let others: Vec<usize> = chosen.iter().filter(|n| !zero_or_play(n)).filter_map(|n| at(n)).collect();
    let mut best = 0.0f64;
    for (a, &i) in others.iter().enumerate() {
        best = best.max(correlation(&e.covariance, z, &[i]).abs());
        for (b, &j) in others.iter().enumerate().skip(a + 1) {
            best = best.max(correlation(&e.covariance, z, &[i, j]).abs());
            for &k in &others[b + 1..] {
                best = best.max(correlation(&e.covariance, z, &[i, j, k]).abs());
            }
        }
    }
    Some(best)
}

/// On the arm7 benchmark (a simulated 7-joint arm with geometric errors, deflection and play),
/// every joint parameter with the compliances and plays asked for, without priors and with the
/// `fabricated` and `machined` ones, every criterion: no candidate joint zero (`theta`) or play
/// (one the gauge does not hold) is left out of the chosen model while chosen parameters clearly stand in for it (a correlation of
/// 0.95 or more, alone or in a group of up to three, computed here from the calibration of the
/// chosen set with the zero added back), unless the path reports the trade; and every trade
/// reported is of a zero or play left out, its stand-ins chosen, at 0.9 or more. The margin
/// (0.95 here against the rule's 0.9) keeps the check off the threshold, where the path's own
/// figure (a forward path's from its linearisation about the registration, the `t` rule's from
/// its fits) and this one may fall either side. At least one trade is of a group (here
/// `machined` cv's `joint6.theta` with three), and the `t` rule drops a group's weak member
/// before the zero it stands in for (`fabricated`, `joint3.theta`).
#[test]
fn no_zero_or_play_is_left_to_a_stand_in_unsaid() {
    let (model, train, _) = arm7("examples/arm7");
    let (mut groups, mut group_notes) = (0, 0);
    for prior in ["", "fabricated", "machined"] {
        let options = KindOptions {
            prior: if prior.is_empty() { Vec::new() } else { PriorEntry::parse_list(prior).unwrap() },
            ..arm7_options(&model, JointParams::Named(vec!["joint*.*".into()]))
        };
        for criterion in [Criterion::Bic, Criterion::Cv { folds: 5 }, Criterion::T] {
            let path = select(&Kinds(&model), &train, &options, criterion).unwrap();
            let chosen = &path.selected;
            for trade in &path.trades {
                assert!(!chosen.contains(&trade.parameter), "{prior} {criterion:?}: {trade}");
                assert!(trade.stand_ins.iter().all(|s| chosen.contains(s)), "{prior} {criterion:?}: {trade}");
                assert!(trade.correlation.abs() >= 0.9 && trade.stand_ins.len() <= 3, "{trade}");
                groups += usize::from(trade.stand_ins.len() > 1);
            }
            group_notes +=
                path.steps.iter().filter(|s| s.note.as_ref().is_some_and(|n| !n.with.is_empty())).count();
            // The candidates: a forward path adds every one, the t rule drops what it leaves out
            // (a zero the gauge holds is no candidate: the report holds it with its combination).
            let candidates = path.steps.iter().filter_map(|s| s.parameter.clone());
            let zeros = candidates.filter(|n| n.ends_with(".theta") || n.ends_with(".play"));
            for zero in zeros.filter(|z| !chosen.contains(z)) {
                let Some(r) = strongest_stand_in(&model, &train, &options, chosen, &zero) else { continue };
                let traded = path.trades.iter().any(|t| t.parameter == zero);
                assert!(
                    r < 0.95 || traded,
                    "{prior} {criterion:?}: {zero} left to a stand-in at {r:.3}, unsaid: {:?}",
                    path.trades
                );
            }
        }
    }
    assert!(groups >= 1 && group_notes >= 1, "groups {groups}, notes {group_notes}");
}

/// A height gauge on a table 150 mm above the robot's base, tilted by 3 and 2 deg (the truth's
/// `base.z`, `base.rx`, `base.ry`), the robot's joints in error: selection is linearised about
/// the registration (the base fitted with the tool point first), not about the nominal base,
/// where the tilt's second-order error (a few mm over the arm's reach) swamps the joints'. The
/// path's first score, the registration's CV RMS, is the registration refitted fold by fold
/// (`cross_validate_kinds` of the base and tool point alone) within 20%; the chosen model's
/// held-out RMS within 1.2 times the plain fit's.
#[test]
fn a_height_gauges_selection_is_linearised_about_its_registration() {
    use crate::kinds::{TOOL, errors_on, heights, options, puma};
    use robocal::calibration::kinds::cross_validate_kinds;
    let mut rng = ChaCha8Rng::seed_from_u64(68);
    let chain = Chain::markers(&puma(), &[TOOL]).remove(0);
    let joints: Vec<String> =
        chain.params().iter().filter(|p| p.name.starts_with('j')).map(|p| p.name.clone()).collect();
    let mut x = errors_on(&chain, &joints, &mut rng);
    for (name, value) in [("base.z", 150.0), ("base.rx", 3f64.to_radians()), ("base.ry", -2f64.to_radians())]
    {
        x[chain.params().index_by_name(name).unwrap()] = value;
    }
    let real = chain.with_errors(&x);
    let (training, validation) = (heights(&real, &mut rng, 0.01), heights(&real, &mut rng, 0.01));
    let plain = options(Estimator::Wls);
    let path = select(&Kinds(&puma()), &training, &plain, Criterion::Cv { folds: 5 }).unwrap();
    let registration = KindOptions { joints: JointParams::None, ..plain.clone() };
    let refitted = cross_validate_kinds(&puma(), &training, &registration, 5).unwrap().lengths.1;
    let first = path.steps[0].score;
    assert!(
        (first / refitted - 1.0).abs() < 0.2,
        "the path's registration {first} mm, refitted {refitted} mm"
    );
    let held_out = |o: &KindOptions| {
        calibrate_kinds(&puma(), &training, o).unwrap().score(&validation).unwrap().lengths.1
    };
    let chosen = KindOptions { joints: JointParams::Named(path.selected.clone()), ..plain.clone() };
    let (selected, all) = (held_out(&chosen), held_out(&plain));
    assert!(
        selected < 1.2 * all,
        "selected {selected} mm held out, every parameter {all} mm: {:?}",
        path.selected
    );
}
