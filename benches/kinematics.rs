//! Kinematics of one point on the PUMA 560: forward kinematics, the manipulator Jacobian J and
//! the identification Jacobian H for the paper's 30 parameters (position rows) and for all
//! 39 parameters (pose rows), and two markers' H in one walk (42 parameters).

use criterion::{Criterion, criterion_group, criterion_main};
use nalgebra::{DMatrix, Matrix6xX};
use robocal::kinematics::{Chain, Measured, marker_jacobians};
use robocal::model::{RobotModel, Selection};
use std::hint::black_box;

fn kinematics(c: &mut Criterion) {
    let model = RobotModel::preset("puma560").unwrap();
    let chain = Chain::new(&model);
    let q = [0.3, 0.9, -1.2, 0.4, 0.7, -0.5];
    let x: Vec<f64> = (0..chain.params().len()).map(|i| 1e-3 * (i as f64).sin()).collect();
    let paper = Selection::joints(chain.params());
    let all = Selection::all(chain.params());
    let mut j = Matrix6xX::zeros(6);
    let mut h3 = DMatrix::zeros(3, paper.len());
    let mut h6 = DMatrix::zeros(6, all.len());

    c.bench_function("apply errors (once per parameter vector)", |b| {
        b.iter(|| chain.with_errors(black_box(&x)))
    });
    let at = chain.with_errors(&x);
    c.bench_function("fk position", |b| b.iter(|| at.position(black_box(&q))));
    c.bench_function("fk pose", |b| b.iter(|| at.pose(black_box(&q))));
    c.bench_function("manipulator jacobian 6x6", |b| {
        b.iter(|| at.manipulator_jacobian(black_box(&q), &mut j))
    });
    c.bench_function("identification jacobian 3x30", |b| {
        b.iter(|| {
            at.identification_jacobian(
                black_box(&q),
                &paper,
                Measured::Position,
                h3.view_mut((0, 0), (3, 30)),
            )
        })
    });
    c.bench_function("identification jacobian 6x39", |b| {
        b.iter(|| {
            at.identification_jacobian(black_box(&q), &all, Measured::Pose, h6.view_mut((0, 0), (6, 39)))
        })
    });
    c.bench_function("H 3x30 and J 6x6 in one walk", |b| {
        b.iter(|| {
            at.jacobians(
                black_box(&q),
                &paper,
                Measured::Position,
                h3.view_mut((0, 0), (3, 30)),
                Some(&mut j),
            )
        })
    });

    // Two markers on the last link, every parameter (6 base, 30 joint, 6 marker): one pose of
    // the calibration benchmark.
    let markers = [nalgebra::Vector3::new(50.0, 0.0, 150.0), nalgebra::Vector3::new(-40.0, 60.0, 120.0)];
    let chains = Chain::markers(&model, &markers);
    let every = Selection::all(chains[0].params());
    let x: Vec<f64> = (0..every.len()).map(|i| 1e-3 * (i as f64).sin()).collect();
    let ats: Vec<_> = chains.iter().map(|c| c.with_errors(&x)).collect();
    let mut h = DMatrix::zeros(6, every.len());
    let mut positions = [nalgebra::Vector3::zeros(); 2];
    c.bench_function("marker jacobians 2 x 3x42, one walk", |b| {
        b.iter(|| {
            let view = h.view_mut((0, 0), (6, every.len()));
            marker_jacobians(&ats, black_box(&q), &every, view, &mut positions)
        })
    });
}

criterion_group!(benches, kinematics);
criterion_main!(benches);
