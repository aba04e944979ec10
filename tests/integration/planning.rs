//! The planner: planned sets against random ones, determinism, constraints, errors; planned
//! poses in the simulation.

use rand::SeedableRng;
use rand::rngs::ChaCha8Rng;
use robocal::design::{Constraints, Criterion, Design, DesignError, ExcludedRange};
use robocal::estimation::{MeasurementNoise, NoiseModel};
use robocal::kinematics::{Chain, Measured};
use robocal::model::{RobotModel, Selection};
use robocal::simulation::uniform_configurations;

/// The paper's setting: the PUMA 560's 30 joint parameters from positions, its joint noise,
/// `sigma_me` = 0.01 mm.
fn puma_design() -> Design {
    let model = RobotModel::preset("puma560").unwrap();
    let selection = Selection::joints(&model.params());
    let sigmas: Vec<f64> =
        [0.007, 0.007, 0.007, 0.002, 0.002, 0.002].iter().map(|s: &f64| s.to_radians()).collect();
    let noise = NoiseModel::diagonal(&sigmas, MeasurementNoise::isotropic(0.01, 0.0));
    Design::new(&model, selection, Measured::Position, Some(noise)).unwrap()
}

#[test]
fn planned_sets_beat_the_best_of_100_random_sets() {
    let design = puma_design();
    for (criterion, points) in [(Criterion::D, 24), (Criterion::O3, 24), (Criterion::O5, 12)] {
        let started = std::time::Instant::now();
        let (plan, _) = design.plan_seeded(points, 2000, &Constraints::default(), criterion, 11).unwrap();
        eprintln!("{criterion}: {:?} {} passes {} exchanges", started.elapsed(), plan.passes, plan.exchanges);
        let mut rng = ChaCha8Rng::seed_from_u64(99);
        let best = (0..100)
            .map(|_| {
                design
                    .criterion(&uniform_configurations(design.model(), points, &mut rng), criterion)
                    .unwrap()
            })
            .fold(f64::NEG_INFINITY, f64::max);
        eprintln!("{criterion}: planned {} (from {}), best random {best}", plan.value, plan.initial);
        assert!(plan.value > best, "{criterion}: planned {} <= best of 100 random {best}", plan.value);
    }
}
