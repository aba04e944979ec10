//! One solve of each estimator on the PUMA 560's 30 joint parameters from N_p position points
//! (N_p = 12, 48, 192): whitening, the rank-revealing factorisation, covariance and
//! diagnostics. Also one iterated (Gauss-Newton) WLS calibration at N_p = 48.

use criterion::{BenchmarkId, Criterion, criterion_group, criterion_main};
use nalgebra::Isometry3;
use robocal::estimation::{
    Estimator, MeasurementNoise, NoiseModel, PointProblem, RANK_TOLERANCE, RefineOptions, estimate, refine,
};
use robocal::kinematics::{Chain, Measured};
use robocal::model::{RobotModel, Selection};
use std::hint::black_box;

fn points(model: &RobotModel, n: usize) -> Vec<Vec<f64>> {
    (0..n)
        .map(|k| {
            let joints = model.joints.iter().enumerate();
            joints
                .map(|(j, joint)| {
                    let u = (((k * 6 + j) as f64 * 12.9898).sin() * 43758.5453).fract().abs();
                    joint.limits[0] + u * (joint.limits[1] - joint.limits[0])
                })
                .collect()
        })
        .collect()
}

fn estimators(c: &mut Criterion) {
    let model = RobotModel::preset("puma560").unwrap();
    let chain = Chain::new(&model);
    let selection = Selection::joints(chain.params());
    let sigmas: Vec<f64> =
        [0.007, 0.007, 0.007, 0.002, 0.002, 0.002].iter().map(|d: &f64| d.to_radians()).collect();
    let noise = NoiseModel::diagonal(&sigmas, MeasurementNoise::isotropic(0.01, 0.0));
    let truth: Vec<f64> = (0..chain.params().len()).map(|i| 1e-3 * (i as f64).sin()).collect();
    let real = chain.with_errors(&truth);
    let mut group = c.benchmark_group("solve 30 parameters");
    for n in [12, 48, 192] {
        let joints = points(&model, n);
        let observed: Vec<Isometry3<f64>> = joints.iter().map(|q| real.pose(q)).collect();
        let zero = vec![0.0; chain.params().len()];
        let problem = PointProblem::new(
            std::slice::from_ref(&chain),
            &selection,
            Measured::Position,
            joints,
            observed,
            zero,
            Some(&noise),
        )
        .unwrap();
        let system = problem.system(&problem.start());
        for estimator in Estimator::ALL {
            group.bench_with_input(BenchmarkId::new(estimator.name(), n), &system, |b, s| {
                b.iter(|| estimate(black_box(s), estimator, RANK_TOLERANCE).unwrap())
            });
        }
        if n == 48 {
            group.bench_function("wls iterated to convergence/48", |b| {
                b.iter(|| {
                    refine(&problem, Estimator::Wls, problem.start(), &RefineOptions::default()).unwrap()
                })
            });
        }
    }
    group.finish();
}

criterion_group!(benches, estimators);
criterion_main!(benches);
