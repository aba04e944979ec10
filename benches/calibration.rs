//! `calibrate` end to end on 1000 poses of the PUMA 560 with two markers: 42 parameters
//! (6 base, 30 joint, 6 marker; 30 identifiable), WLS iterated to convergence, including the
//! registration, the base-and-markers fit and the identifiability analysis; and the same with
//! link masses, joints 2 and 3 compliant, and the 6 compliances asked for too (5 loaded); and
//! `select` by 5-fold cross-validation on 100 poses of a 12-joint arm (two PUMA 560 arms end
//! to end) with three markers: 60 candidate joint parameters; and `calibrate_tree` on the
//! torso preset (15 joints, 3 branches) from 500 poses of its head camera seeing both hands
//! (1000 views, 6000 rows, 123 parameters asked for), WLS with joint noise, to convergence;
//! and on the same 100 poses and 60 candidates the choices made from the data (`--prior auto`,
//! `--prior auto-ml`, nested `--select cv --folds 5`) and `--loss huber` beside the plain fit;
//! and a marker file of 10,000 poses. Every fit is the one pipeline's (`calibrate_kinds`, its
//! choices by the `Kinds` front), a marker file read as `robocal calibrate` reads it.

use criterion::{Criterion, criterion_group, criterion_main};
use nalgebra::Vector3;
use rand::rngs::ChaCha8Rng;
use rand::{RngExt, SeedableRng};
use robocal::calibration::kinds::{
    KindData, KindOptions, RowSigmaDefaults, calibrate_kinds, calibrate_kinds_feasible,
};
use robocal::calibration::selection::{self, Criterion as Select};
use robocal::calibration::{FeasibleOptions, JointParams, Kinds};
use robocal::estimation::Estimator;
use robocal::model::{Placement, RobotModel};
use robocal::simulation::measurement_csv;

/// A marker file's `text` for `model` as `robocal calibrate` reads it, each coordinate's sigma
/// `sigma_mm` where given (`--sigma-mm`), else assumed.
fn read(text: &str, model: &RobotModel, sigma_mm: Option<f64>) -> KindData {
    KindData::from_csv_str_with(text, model, None, RowSigmaDefaults::positive(sigma_mm, None)).unwrap()
}

/// The options of a marker calibration of `model` by `estimator`: the joints' standard
/// deviations `joint_sigmas` (rad; none: exact), the design `markers`, every joint parameter.
fn marker_options(
    model: &RobotModel,
    estimator: Estimator,
    joint_sigmas: Option<&[f64]>,
    markers: Vec<Vector3<f64>>,
) -> KindOptions {
    let variances = |s: &[f64]| {
        nalgebra::DMatrix::from_diagonal(&nalgebra::DVector::from_iterator(s.len(), s.iter().map(|v| v * v)))
    };
    KindOptions {
        estimator,
        joint_noise: joint_sigmas.map(variances),
        tool: model.tool_point_in_marker_frame(),
        markers,
        ..KindOptions::default()
    }
}

/// The data of 1000 poses of a PUMA 560 (`preset`) whose joints 2 and 3 have `compliance`,
/// and the options of a WLS calibration of `params`.
fn campaign(preset: &str, compliance: f64, params: JointParams) -> (RobotModel, KindData, KindOptions) {
    campaign_of(preset, compliance, params, 1000, 2)
}

/// [`campaign`] of `poses` poses seen by `markers` markers (1 to 4).
fn campaign_of(
    preset: &str,
    compliance: f64,
    params: JointParams,
    poses: usize,
    markers: usize,
) -> (RobotModel, KindData, KindOptions) {
    let nominal = RobotModel::preset(preset).unwrap();
    let mut truth = nominal.clone();
    for (i, joint) in truth.joints.iter_mut().enumerate() {
        joint.theta += 1e-3 * (i as f64).sin();
        joint.a += 0.3 * (i as f64).cos();
    }
    truth.joints[1].compliance = compliance;
    truth.joints[2].compliance = compliance;
    truth.base = Placement { xyz: Vector3::new(1500.0, -300.0, 200.0), rpy: Vector3::new(0.1, -0.05, 0.6) };
    let truths = [[52.0, 1.0, 148.0], [-38.0, 61.0, 121.0], [1.0, -59.0, 91.0], [41.0, 42.0, 60.0]];
    let designs = [[50.0, 0.0, 150.0], [-40.0, 60.0, 120.0], [0.0, -60.0, 90.0], [40.0, 40.0, 60.0]];
    let markers: Vec<Vector3<f64>> = truths[..markers].iter().map(|m| Vector3::from(*m)).collect();
    let designs: Vec<Vector3<f64>> = designs[..markers.len()].iter().map(|m| Vector3::from(*m)).collect();
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    let poses: Vec<Vec<f64>> = (0..poses)
        .map(|_| nominal.joints.iter().map(|j| rng.random_range(j.limits[0]..j.limits[1])).collect())
        .collect();
    let sigmas: Vec<f64> =
        [0.007, 0.007, 0.007, 0.002, 0.002, 0.002].iter().map(|d: &f64| d.to_radians()).collect();
    let text = measurement_csv(&truth, &markers, &poses, &sigmas, 0.01, 2);
    let data = read(&text, &nominal, Some(0.01));
    let options =
        KindOptions { joints: params, ..marker_options(&nominal, Estimator::Wls, Some(&sigmas), designs) };
    (nominal, data, options)
}

fn calibration(c: &mut Criterion) {
    let mut group = c.benchmark_group("calibrate");
    group.sample_size(10);
    let (nominal, data, options) = campaign("puma560", 0.0, JointParams::All);
    group.bench_function("1000 poses, 2 markers, 42 parameters, wls iterated", |b| {
        b.iter(|| calibrate_kinds(&nominal, &data, &options).unwrap())
    });
    let names = ["theta", "d", "a", "alpha", "beta", "compliance"].map(|k| format!("j*.{k}"));
    let (nominal, data, options) = campaign("puma560-masses", 5e-5, JointParams::Named(names.to_vec()));
    group.bench_function("1000 poses, 2 markers, 48 parameters with compliances, wls iterated", |b| {
        b.iter(|| calibrate_kinds(&nominal, &data, &options).unwrap())
    });
    let (nominal, data, options) = campaign_of("puma560", 0.0, JointParams::All, 1000, 4);
    // Feasible GLS estimates the noise (the file's sigmas and the joint noise are not used).
    group.bench_function("1000 poses, 4 markers, fgls (the noise from the residuals)", |b| {
        b.iter(|| calibrate_kinds_feasible(&nominal, &data, &options, &FeasibleOptions::default()).unwrap())
    });
    let (nominal, data, options) = campaign_of("puma560", 0.0, JointParams::All, 10_000, 2);
    group.bench_function("10,000 poses, 2 markers, 42 parameters, wls iterated", |b| {
        b.iter(|| calibrate_kinds(&nominal, &data, &options).unwrap())
    });
    // Peak memory: benches/calibrate-memory.sh (the whole command under /usr/bin/time -v).
    let (nominal, data, options) = campaign_of("puma560", 0.0, JointParams::All, 100_000, 2);
    group.bench_function("100,000 poses, 2 markers, 42 parameters, wls iterated", |b| {
        b.iter(|| calibrate_kinds(&nominal, &data, &options).unwrap())
    });
    group.finish();
}

/// Two PUMA 560 arms end to end (12 DH joints, 60 candidate joint parameters) off by a
/// little, 100 poses seen by 3 markers with 0.05 mm of noise, and the options of an OLS
/// calibration of every joint parameter; the marker file's text.
fn two_pumas() -> (RobotModel, KindData, KindOptions, String) {
    let puma = RobotModel::preset("puma560").unwrap();
    let mut nominal = puma.clone();
    nominal.joints.extend(puma.joints.iter().cloned().map(|mut j| {
        j.name = format!("k{}", &j.name[1..]);
        j
    }));
    nominal.name = "two PUMA 560 end to end".into();
    let mut truth = nominal.clone();
    for (i, joint) in truth.joints.iter_mut().enumerate() {
        joint.theta += 1e-3 * (i as f64).sin();
        joint.a += 0.3 * (i as f64).cos();
        joint.d += 0.2 * (i as f64 * 0.7).sin();
    }
    truth.base = Placement { xyz: Vector3::new(1500.0, -300.0, 200.0), rpy: Vector3::new(0.1, -0.05, 0.6) };
    let markers =
        [Vector3::new(52.0, 1.0, 148.0), Vector3::new(-38.0, 61.0, 121.0), Vector3::new(0.0, -60.0, 90.0)];
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let poses: Vec<Vec<f64>> = (0..100)
        .map(|_| nominal.joints.iter().map(|j| rng.random_range(j.limits[0]..j.limits[1])).collect())
        .collect();
    let text = measurement_csv(&truth, &markers, &poses, &[1e-5; 12], 0.05, 4);
    let data = read(&text, &nominal, None);
    let designs = vec![
        Vector3::new(50.0, 0.0, 150.0),
        Vector3::new(-40.0, 60.0, 120.0),
        Vector3::new(0.0, -60.0, 90.0),
    ];
    let options = marker_options(&nominal, Estimator::Ols, None, designs);
    assert_eq!(robocal::model::Selection::joints(&nominal.params()).len(), 60);
    (nominal, data, options, text)
}

/// `select` by 5-fold cross-validation: 100 poses, 3 markers, 60 candidate joint parameters
/// (12 DH joints), by OLS; the registration, the linearisation, the gauge and the whole path.
fn selection(c: &mut Criterion) {
    let (nominal, data, options, _) = two_pumas();
    let path = selection::select(&Kinds(&nominal), &data, &options, Select::Cv { folds: 5 }).unwrap();
    eprintln!(
        "the path: {} steps (the candidates the poses identify), {} chosen",
        path.steps.len() - 1,
        path.chosen
    );
    let mut group = c.benchmark_group("select");
    group.sample_size(10);
    group.bench_function("cv, 5 folds, 100 poses, 3 markers, 60 candidates", |b| {
        b.iter(|| selection::select(&Kinds(&nominal), &data, &options, Select::Cv { folds: 5 }).unwrap())
    });
    group.finish();
}

/// The choices made from the data on [`two_pumas`] (issue 24's targets: under 2 s on 2 cores,
/// a robust loss at most 3 times the plain fit): `--prior auto` (the scale of `fabricated` by
/// 5-fold cross-validation: 9 scales, 45 calibrations, then the calibration), `--prior auto-ml`
/// (the marginal likelihood, the noise given), the nested 5-fold cross-validation of
/// `--select cv --folds 5` (the selection and the calibration again in each fold), and the
/// calibration with `--loss huber` beside the plain one.
fn choices(c: &mut Criterion) {
    use robocal::calibration::prior_scale::AutoPrior;
    use robocal::calibration::selection::{Choices, choose, cross_validate_choices};
    let (nominal, data, options, text) = two_pumas();
    let auto = |text: &str| Choices {
        auto_prior: Some((AutoPrior::parse(text).unwrap().unwrap(), 5)),
        select: None,
    };
    let (cv, ml) = (auto("auto"), auto("auto-ml"));
    // The noise given: 1e-5 rad on each joint, 0.05 mm on each coordinate.
    let given = read(&text, &nominal, Some(0.05));
    let with_noise = KindOptions {
        estimator: Estimator::Wls,
        ..marker_options(&nominal, Estimator::Wls, Some(&[1e-5; 12]), options.markers.clone())
    };
    let select = Choices { auto_prior: None, select: Some(Select::Cv { folds: 5 }) };
    let huber = KindOptions { loss: "huber".parse().unwrap(), ..options.clone() };
    let mut group = c.benchmark_group("choices");
    group.sample_size(10);
    group.bench_function("--prior auto, 5 folds, 100 poses, 60 candidates, then calibrate", |b| {
        b.iter(|| {
            let chosen = choose(&Kinds(&nominal), &data, &options, &cv).unwrap();
            calibrate_kinds(&nominal, &data, &chosen.options).unwrap()
        })
    });
    group.bench_function("--prior auto-ml, 100 poses, 60 candidates, then calibrate", |b| {
        b.iter(|| {
            let chosen = choose(&Kinds(&nominal), &given, &with_noise, &ml).unwrap();
            calibrate_kinds(&nominal, &given, &chosen.options).unwrap()
        })
    });
    group.bench_function("--select cv --folds 5 nested, 100 poses, 60 candidates", |b| {
        b.iter(|| cross_validate_choices(&Kinds(&nominal), &data, &options, &select, 5).unwrap())
    });
    group.bench_function("plain calibration, 100 poses, 60 candidates", |b| {
        b.iter(|| calibrate_kinds(&nominal, &data, &options).unwrap())
    });
    group.bench_function(
        "plain wls calibration, the noise given (and checked), 100 poses, 60 candidates",
        |b| b.iter(|| calibrate_kinds(&nominal, &given, &with_noise).unwrap()),
    );
    group.bench_function("--loss huber, 100 poses, 60 candidates", |b| {
        b.iter(|| calibrate_kinds(&nominal, &data, &huber).unwrap())
    });
    group.finish();
}

/// `calibrate_tree`: the torso of `presets/torso.urdf`, every joint origin off by about 1 mm
/// and 0.3 deg, its head camera's views of both hands at 500 poses (0.2 mm, 0.05 deg).
fn tree(c: &mut Criterion) {
    use robocal::calibration::tree::calibrate_tree;
    use robocal::model::RobotTree;
    use robocal::simulation::tree::{head_camera_and_hands, perturbed_tree, simulate_views};
    let nominal = RobotTree::from_urdf_str(include_str!("../presets/torso.urdf"), None, &[]).unwrap();
    let mut rng = ChaCha8Rng::seed_from_u64(15);
    let truth = perturbed_tree(&nominal, 1.0, 0.3f64.to_radians(), &mut rng);
    let (frames, placements) = head_camera_and_hands(&nominal);
    let q = nominal.uniform_configurations(500, &mut rng);
    let sigma = [0.2, 0.05f64.to_radians()];
    let data = simulate_views(&truth, &frames, &placements, &[(0, 1), (0, 2)], &q, sigma, &mut rng);
    let sigma_q = 0.01f64.to_radians().powi(2);
    let options = KindOptions {
        estimator: Estimator::Wls,
        joint_noise: Some(nalgebra::DMatrix::from_diagonal_element(nominal.dof(), nominal.dof(), sigma_q)),
        joints: JointParams::All,
        ..KindOptions::default()
    };
    let mut group = c.benchmark_group("calibrate-tree");
    group.sample_size(10);
    group.bench_function("torso, 500 poses, 1000 views, wls iterated", |b| {
        b.iter(|| calibrate_tree(&nominal, &data, &options).unwrap())
    });
    group.finish();
}

criterion_group!(benches, calibration, selection, choices, tree);
criterion_main!(benches);
