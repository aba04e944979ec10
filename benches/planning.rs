//! Planning 48 poses of the PUMA 560 (30 joint parameters, 23 identifiable, the paper's joint
//! noise and 0.01 mm measurement noise) from a pool of 5000 candidates, D-optimal on the
//! whitened information matrix: candidates drawn, their rows computed, Fedorov exchange.
//! Target: under 2 s.

use criterion::{Criterion as Bench, criterion_group, criterion_main};
use robocal::design::{Constraints, Criterion, Design};
use robocal::estimation::{MeasurementNoise, NoiseModel};
use robocal::kinematics::Measured;
use robocal::model::{RobotModel, Selection};

fn planning(c: &mut Bench) {
    let model = RobotModel::preset("puma560").unwrap();
    let sigmas: Vec<f64> =
        [0.007, 0.007, 0.007, 0.002, 0.002, 0.002].iter().map(|s: &f64| s.to_radians()).collect();
    let noise = NoiseModel::diagonal(&sigmas, MeasurementNoise::isotropic(0.01, 0.0));
    let design =
        Design::new(&model, Selection::joints(&model.params()), Measured::Position, Some(noise)).unwrap();
    let mut group = c.benchmark_group("planning");
    group.sample_size(10);
    group.bench_function("48 poses from 5000 candidates, D-optimal, whitened", |b| {
        b.iter(|| design.plan_seeded(48, 5000, &Constraints::default(), Criterion::D, 1).unwrap())
    });
    group.bench_function("48 poses from 5000 candidates, O3 (D exchange, then O3 on a shortlist)", |b| {
        b.iter(|| design.plan_seeded(48, 5000, &Constraints::default(), Criterion::O3, 1).unwrap())
    });
    group.finish();
}

criterion_group!(benches, planning);
criterion_main!(benches);
