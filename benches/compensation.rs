//! Using a calibration: compensating 10,000 joint targets of the PUMA 560 (the example's true
//! robot as the calibrated model, full pose), and an accuracy map of 100,000 poses (30
//! parameters' covariance). Targets: each under 1 s on 2 cores.

use criterion::{Criterion, criterion_group, criterion_main};
use nalgebra::DMatrix;
use rand::SeedableRng;
use rand::rngs::ChaCha8Rng;
use robocal::design::accuracy::{AccuracyModel, ParameterCovariance};
use robocal::design::compensate::{CompensateOptions, Compensator, Target};
use robocal::model::{Placement, RobotModel};

fn compensation(c: &mut Criterion) {
    let nominal = RobotModel::preset("puma560").unwrap();
    let text = std::fs::read_to_string("examples/puma560-true.toml").unwrap();
    let truth = RobotModel { base: Placement::default(), ..RobotModel::from_toml_str(&text).unwrap() };
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    let targets: Vec<Target> =
        nominal.uniform_configurations(10_000, &mut rng).into_iter().map(Target::Joints).collect();
    let compensator = Compensator::new(&nominal, &truth, &CompensateOptions::default()).unwrap();
    let names: Vec<String> = truth.params().iter().take(30).map(|p| p.name.clone()).collect();
    let covariance = ParameterCovariance::new(names, &(DMatrix::identity(30, 30) * 1e-6), 0.01);
    let accuracy = AccuracyModel::new(&truth, &covariance).unwrap();
    let poses = nominal.uniform_configurations(100_000, &mut rng);
    let mut group = c.benchmark_group("using a calibration");
    group.sample_size(10);
    group.bench_function("compensate 10,000 joint targets", |b| b.iter(|| compensator.solve_all(&targets)));
    group.bench_function("accuracy map of 100,000 poses", |b| b.iter(|| accuracy.map(&poses)));
    group.finish();
}

criterion_group!(benches, compensation);
criterion_main!(benches);
