//! Calibration end to end: a known robot measured with noise, an unknown base and two markers.

use nalgebra::Vector3;
use rand::rngs::ChaCha8Rng;
use rand::{RngExt, SeedableRng};
use rand_distr::{Distribution, StandardNormal};
use robocal::calibration::Held;
use robocal::calibration::kinds::{
    DEFAULT_SIGMA_ANGLE_DEG, KindCalibration, KindData, KindOptions, KindProblem, Observation,
    RowSigmaDefaults, SetUp, calibrate_kinds, calibrate_kinds_feasible, evaluate_kinds,
};
use robocal::calibration::{JointParams, Scored, Warning};
use robocal::estimation::{
    Estimator, MeasurementNoise, NoiseModel, RefineOptions, Weights, linearise, refine_from,
};
use robocal::kinematics::{Chain, ChainAt};
use robocal::model::{ParamKind, ParamOwner, Placement, RobotModel, Selection, Tool};
use robocal::simulation::measurement_csv;
use robocal::table::Units;

const DEGREES: [f64; 6] = [0.007, 0.007, 0.007, 0.002, 0.002, 0.002];

pub(crate) fn joint_sigmas() -> Vec<f64> {
    DEGREES.iter().map(|d| d.to_radians()).collect()
}

/// The nominal model with errors of the sizes folded in, and a base far from the
/// measuring frame (a tracker 1.5 m away, turned 34 degrees).
pub(crate) fn true_robot(nominal: &RobotModel, rng: &mut ChaCha8Rng) -> RobotModel {
    let mut n = || -> f64 { StandardNormal.sample(&mut *rng) };
    let mut truth = nominal.clone();
    for joint in &mut truth.joints {
        joint.theta += 0.1f64.to_radians() * n();
        joint.d += 0.5 * n();
        joint.a += 0.5 * n();
        joint.alpha += 0.05f64.to_radians() * n();
        joint.beta += 0.05f64.to_radians() * n();
    }
    truth.base = Placement { xyz: Vector3::new(1500.0, -300.0, 200.0), rpy: Vector3::new(0.1, -0.05, 0.6) };
    truth
}

fn poses(model: &RobotModel, n: usize, rng: &mut ChaCha8Rng) -> Vec<Vec<f64>> {
    (0..n)
        .map(|_| model.joints.iter().map(|j| rng.random_range(j.limits[0]..j.limits[1])).collect())
        .collect()
}

/// A calibration campaign ([`campaign_of`]): the models, the files read as `robocal calibrate`
/// reads them, and the options it sets.
pub(crate) struct Campaign {
    pub nominal: RobotModel,
    pub truth: RobotModel,
    pub true_markers: Vec<Vector3<f64>>,
    pub training: KindData,
    pub validation: KindData,
    pub options: KindOptions,
}

fn campaign(seed: u64) -> Campaign {
    campaign_of(seed, 120)
}

/// The measurement noise of [`campaign_files`]: the joints' and 0.01 mm.
pub(crate) fn campaign_noise() -> NoiseModel {
    NoiseModel::diagonal(&joint_sigmas(), MeasurementNoise::isotropic(0.01, 0.0))
}

/// A PUMA 560 with errors, an unknown base and two markers, measured with [`campaign_noise`]
/// at `poses` training poses and 60 held-out ones: the nominal model, the true one, its
/// markers, and the two marker files' text.
pub(crate) fn campaign_files(
    seed: u64,
    poses_: usize,
) -> (RobotModel, RobotModel, Vec<Vector3<f64>>, [String; 2]) {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let nominal = RobotModel::preset("puma560").unwrap();
    let truth = true_robot(&nominal, &mut rng);
    let true_markers = vec![Vector3::new(52.0, 1.0, 148.0), Vector3::new(-38.0, 61.0, 121.0)];
    let mut file = |n: usize, seed| {
        let joints = poses(&nominal, n, &mut rng);
        measurement_csv(&truth, &true_markers, &joints, &joint_sigmas(), 0.01, seed)
    };
    let files = [file(poses_, 1), file(60, 2)];
    (nominal, truth, true_markers, files)
}

/// The design markers of [`campaign_files`] (mm, the marker frame).
pub(crate) const CAMPAIGN_MARKERS: [Vector3<f64>; 2] =
    [Vector3::new(50.0, 0.0, 150.0), Vector3::new(-40.0, 60.0, 120.0)];

/// [`campaign_files`] read as `robocal calibrate` reads them, calibrated by Gauss-Markov with
/// the true noise.
pub(crate) fn campaign_of(seed: u64, poses_: usize) -> Campaign {
    let (nominal, truth, true_markers, [training, validation]) = campaign_files(seed, poses_);
    let noise = campaign_noise();
    let read = |text: &str| crate::marker_data(text, &nominal, Some(&noise));
    let (training, validation) = (read(&training), read(&validation));
    let options = crate::marker_options(&nominal, Estimator::Wls, Some(&noise), &CAMPAIGN_MARKERS);
    Campaign { nominal, truth, true_markers, training, validation, options }
}

/// Held out, the marker positions' RMS falls at least five-fold; the positions cannot separate
/// 12 of the 42 parameters, which are held, `j1.theta - base.rz` first.
#[test]
fn held_out_accuracy_improves_at_least_five_fold() {
    let c = campaign(11);
    let calibration = calibrate_kinds(&c.nominal, &c.training, &c.options).unwrap();
    let (before, after) = calibration.score(&c.validation).unwrap().markers.unwrap();
    assert!(before / after >= 5.0, "held-out RMS {before:.4} mm before, {after:.4} mm after");
    assert!(calibration.refined.converged);
    // 6 base + 30 joint + 6 marker parameters; the 12 that positions cannot separate (e.g.
    // `j1.theta - base.rz`: both turn the whole arm about joint 1's axis) are held fixed.
    assert_eq!(calibration.fixed.len(), 12, "{:?}", calibration.fixed);
    assert!(
        calibration.fixed[0]
            .text()
            .starts_with("j1.theta - base.rz: with the base estimated it only moves the whole robot"),
        "{}",
        calibration.fixed[0].text()
    );
    assert_eq!(calibration.refined.estimate.names.len(), 42 - 12);
}

/// A calibration of 400 poses (2400 rows: several parallel tasks and row parts) gives the
/// same numbers, to the bit, on 1 and 3 threads.
#[test]
fn calibration_is_the_same_on_any_number_of_threads() {
    let mut c = campaign(12);
    let mut rng = ChaCha8Rng::seed_from_u64(12);
    let text = measurement_csv(
        &c.truth,
        &c.true_markers,
        &poses(&c.nominal, 400, &mut rng),
        &joint_sigmas(),
        0.01,
        3,
    );
    let noise = NoiseModel::diagonal(&joint_sigmas(), MeasurementNoise::isotropic(0.01, 0.0));
    c.training = crate::marker_data(&text, &c.nominal, Some(&noise));
    let on = |threads| {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        pool.install(|| calibrate_kinds(&c.nominal, &c.training, &c.options).unwrap())
    };
    let (one, three) = (on(1), on(3));
    assert_eq!(one.after, three.after);
    assert_eq!(one.before, three.before);
    assert_eq!(one.refined, three.refined, "estimate, covariance, diagnostics and history");
    assert_eq!(one.fixed, three.fixed);
}

/// The true parameter errors, in the calibration's parameter vector: the base as the
/// displacement from the registered base, the markers from their nominal positions.
fn true_vector(c: &Campaign, calibration: &KindCalibration) -> Vec<f64> {
    let params = &calibration.params;
    let mut x = vec![0.0; params.len()];
    let set = |x: &mut Vec<f64>, owner, kind, v| x[params.index_of(owner, kind).unwrap()] = v;
    for (i, (t, n)) in c.truth.joints.iter().zip(&c.nominal.joints).enumerate() {
        let o = ParamOwner::Joint(i);
        set(&mut x, o, ParamKind::Theta, t.theta - n.theta);
        set(&mut x, o, ParamKind::D, t.d - n.d);
        set(&mut x, o, ParamKind::A, t.a - n.a);
        set(&mut x, o, ParamKind::Alpha, t.alpha - n.alpha);
        set(&mut x, o, ParamKind::Beta, t.beta - n.beta);
    }
    let registered = calibration.registered_base.expect("the base registered on the markers");
    let base = displacement_parameters(&registered.isometry(), &c.truth.base.isometry());
    for (kind, v) in ParamKind::PLACEMENT.into_iter().zip(base) {
        set(&mut x, ParamOwner::Base, kind, v);
    }
    for (k, (t, n)) in c.true_markers.iter().zip(&c.options.markers).enumerate() {
        for (a, kind) in [ParamKind::X, ParamKind::Y, ParamKind::Z].into_iter().enumerate() {
            set(&mut x, ParamOwner::Marker(k), kind, t[a] - n[a]);
        }
    }
    x
}

/// Within 3 predicted standard errors in the identifiable directions. The truth (a full
/// parameter vector) is first expressed in the identified parameters, exactly: those values
/// of them, the others held where the calibration held them, that reproduce the true robot's
/// noise-free marker positions at the same poses (a nonlinear fit of the kinds problem on the
/// registered base, the `markers` nominal). The estimate must lie within 3 of its predicted
/// standard errors of that, parameter by parameter.
pub fn assert_within_three_standard_errors(
    model: &RobotModel,
    markers: &[Vector3<f64>],
    calibration: &KindCalibration,
    truth: &[f64],
    data: &KindData,
) {
    let params = &calibration.params;
    let registered = RobotModel { base: calibration.registered_base.unwrap_or(model.base), ..model.clone() };
    let ids = data.markers();
    let nominal: Vec<Vector3<f64>> = ids.iter().map(|&m| markers[m]).collect();
    let chains = Chain::markers(&registered, &nominal);
    let kept = Selection::by_names(params, &calibration.refined.estimate.names).unwrap();
    let real: Vec<_> = chains.iter().map(|c| c.with_errors(truth)).collect();
    // The data with each marker's coordinate the true robot's, noise-free.
    let mut exact = data.clone();
    for o in &mut exact.observations {
        if let Observation::Marker { marker, axis, pose, measured, .. } = o {
            let k = ids.iter().position(|m| m == marker).unwrap();
            *measured = real[k].pose(&data.joints[*pose]).translation.vector[*axis];
        }
    }
    let setup = SetUp::new(0, &[]);
    let problem = KindProblem::of_points(
        &chains,
        &ids,
        &kept,
        &exact,
        &setup,
        calibration.after.clone(),
        Vec::new(),
        Vec::new(),
    )
    .with_noise(None);
    let weights = Weights::for_problem(&problem, Estimator::Ols).unwrap();
    let start = linearise(&problem, &weights, problem.start()).unwrap();
    let equivalent = refine_from(&problem, &weights, start, &RefineOptions::default()).unwrap();
    assert!(equivalent.estimate.cost < 1e-12, "the truth is reproduced by the identified parameters");
    let delta = &calibration.refined.estimate.x - &equivalent.estimate.x;
    let se = calibration.refined.estimate.standard_errors();
    let names = &calibration.refined.estimate.names;
    let worst = (0..kept.len())
        .max_by(|&i, &j| (delta[i] / se[i]).abs().total_cmp(&(delta[j] / se[j]).abs()))
        .unwrap();
    let sigmas = (delta[worst] / se[worst]).abs();
    assert!(sigmas < 3.0, "{} is {sigmas:.2} standard errors from the truth", names[worst]);
}

/// The base's true errors: the displacement `Trans(t) Rx(a) Ry(b) Rz(c)` from the registered
/// base to the true one (`R = Rx Ry Rz` has `R^T = Rz(-c) Ry(-b) Rx(-a)`).
pub fn displacement_parameters(from: &nalgebra::Isometry3<f64>, to: &nalgebra::Isometry3<f64>) -> [f64; 6] {
    let d = from.inverse() * to;
    let (ma, mb, mc) = d.rotation.inverse().euler_angles();
    let t = d.translation.vector;
    [t.x, t.y, t.z, -ma, -mb, -mc]
}

#[test]
fn identified_parameters_lie_within_three_standard_errors_of_the_truth() {
    let c = campaign(12);
    let calibration = calibrate_kinds(&c.nominal, &c.training, &c.options).unwrap();
    let truth = true_vector(&c, &calibration);
    assert_within_three_standard_errors(&c.nominal, &c.options.markers, &calibration, &truth, &c.training);
}

/// A marker file in metres and radians reads as in millimetres and degrees, with its units
/// line or with the units given; a column that is neither a joint nor a marker's is left.
#[test]
fn units_in_metres_and_radians_read_the_same() {
    let c = campaign(13);
    let model = &c.nominal;
    let text = "# units: joints=rad, lengths=m\nj1,j2,j3,j4,j5,j6,x1,y1,z1,note\n0.1,0.2,0.3,0.4,0.5,0.6,1.5,-0.25,0.125,hello\n";
    let data = KindData::from_csv_str(text, model, None).unwrap();
    assert_eq!(data.joints[0], vec![0.1, 0.2, 0.3, 0.4, 0.5, 0.6]);
    let measured: Vec<f64> = data.observations.iter().map(Observation::measured).collect();
    assert_eq!(measured, [1500.0, -250.0, 125.0]);
    let flagged = Units { joints_in_degrees: false, lengths_in_metres: true };
    let without_line = text.lines().skip(1).collect::<Vec<_>>().join("\n");
    assert_eq!(
        KindData::from_csv_str(&without_line, model, Some(flagged)).unwrap(),
        KindData { lines: vec![2; 3], ..data }
    );
}

fn data_error(text: &str) -> String {
    let model = RobotModel::preset("puma560").unwrap();
    KindData::from_csv_str(text, &model, None).unwrap_err().to_string()
}

#[test]
fn bad_measurement_files_name_the_line_and_column() {
    let head = "# units: joints=deg, lengths=mm\nj1,j2,j3,j4,j5,j6,x1,y1,z1\n";
    assert_eq!(
        data_error("j1,j2,j3,j4,j5,j6,x1,y1,z1\n1,2,3,4,5,6,7,8,9\n"),
        "line 1: units not declared: start the file with `# units: joints=deg, lengths=mm` (or rad, m) or give --joint-unit and --length-unit"
    );
    assert_eq!(
        data_error(&format!("{head}1,2,3,4,5,6,7,8,nan\n")),
        "line 3, column `z1`: NaN: expected a finite number"
    );
    assert_eq!(
        data_error(&format!("{head}1,2,3,4,5,6,7,8,9\n1,2,3,4,5,x,7,8,9\n")),
        "line 4, column `j6`: `x` is not a number"
    );
    assert_eq!(data_error(&format!("{head}1,2,3,4,5,6,7,8\n")), "line 3: 8 values, the header has 9");
    assert!(
        data_error("# units: joints=deg, lengths=mm\nj1,j2,j3,j4,j5,J6,x1,y1,z1\n1,2,3,4,5,6,7,8,9\n")
            .starts_with("line 2, column `j6`: missing joint column; the model's joints are j1, j2")
    );
    assert_eq!(
        data_error("# units: joints=deg, lengths=mm\nj1,j2,j3,j4,j5,j6,x1,y1\n"),
        "line 2, column `x1`: marker 1 needs y1 and z1 too"
    );
    assert_eq!(
        data_error("# units: joints=degrees, lengths=mm\nj1\n"),
        "line 1: `joints=degrees` in the units line: expected joints=deg|rad and lengths=mm|m"
    );
    assert_eq!(data_error(head), "line 2: no poses after the header");
}

/// `data` with `by` added to the coordinate `axis` of marker `marker` (less one) at `pose`; its
/// line.
fn bump(data: &mut KindData, (pose, marker, axis): (usize, usize, usize), by: f64) -> usize {
    let k = (data.observations.iter())
        .position(|o| matches!(*o, Observation::Marker { marker: m, axis: a, pose: p, .. } if (p, m, a) == (pose, marker, axis)))
        .expect("the coordinate measured");
    if let Observation::Marker { measured, .. } = &mut data.observations[k] {
        *measured += by;
    }
    data.lines[k]
}

/// The far-out observations of `warnings`, each warning's.
fn far_out(warnings: &[Warning]) -> Vec<(&Scored, &Vec<robocal::calibration::FarOut>)> {
    (warnings.iter())
        .filter_map(|w| match w {
            Warning::FarOut { scored, observations } => Some((scored, observations)),
            _ => None,
        })
        .collect()
}

/// Clean data give no warning; a marker's coordinate 2 mm off is flagged, by its line, the
/// worst first, with at most two neighbours it pulled near the threshold.
#[test]
fn an_outlier_is_flagged_with_its_line_and_clean_data_is_not() {
    let c = campaign(15);
    let clean = calibrate_kinds(&c.nominal, &c.training, &c.options).unwrap();
    assert!(clean.warnings.is_empty(), "{:?}", clean.warnings);
    let mut bumped = c.training.clone();
    let line = bump(&mut bumped, (40, 1, 2), 2.0);
    let flagged = calibrate_kinds(&c.nominal, &bumped, &c.options).unwrap();
    // The outlier pulls the fit, so a neighbour may come near the threshold; it stands out.
    let [(_, observations)] = far_out(&flagged.warnings)[..] else {
        panic!("one warning of far-out observations: {:?}", flagged.warnings)
    };
    assert_eq!(observations[0].line, line, "the worst first: {observations:?}");
    assert!(observations.len() <= 3, "{observations:?}");
}

#[test]
fn fewer_poses_than_identifiable_parameters_is_an_error() {
    let c = campaign(14);
    let mut few = c.training.keeping(|o| o.pose() < 6);
    few.joints.truncate(6);
    let err = calibrate_kinds(&c.nominal, &few, &c.options).unwrap_err();
    assert_eq!(
        err.to_string(),
        "6 poses give 36 equations for 42 parameters: measure more poses (at least 8) or identify fewer parameters"
    );
}

/// A 6-DOF probe's measurement file (position of marker 1 and the frame's orientation,
/// quaternion) on `real` at `count` random poses of `nominal`, the joints read with standard
/// deviations `sigmas` (rad), read as `robocal calibrate` reads it with `noise`.
fn probe_file(
    nominal: &RobotModel,
    real: &ChainAt,
    count: usize,
    sigmas: &[f64],
    rng: &mut ChaCha8Rng,
    noise: Option<&NoiseModel>,
) -> KindData {
    crate::marker_data(&probe_csv(nominal, real, count, sigmas, rng), nominal, noise)
}

/// The text of [`probe_file`].
pub(crate) fn probe_csv(
    nominal: &RobotModel,
    real: &ChainAt,
    count: usize,
    sigmas: &[f64],
    rng: &mut ChaCha8Rng,
) -> String {
    let mut text = String::from(PROBE_HEADER);
    for q in poses(nominal, count, rng) {
        let noisy: Vec<f64> = q
            .iter()
            .zip(sigmas)
            .map(|(q, s)| {
                let z: f64 = StandardNormal.sample(&mut *rng);
                q + s * z
            })
            .collect();
        let pose = real.pose(&noisy);
        text += &probe_row(&q, &pose.translation.vector, &pose.rotation);
    }
    text
}

/// The header of a 6-DOF probe's file on a 6-joint arm: the joints, marker 1, the quaternion.
pub(crate) const PROBE_HEADER: &str =
    "# units: joints=deg, lengths=mm\nj1,j2,j3,j4,j5,j6,x1,y1,z1,qw,qx,qy,qz\n";

/// A row of a 6-DOF probe's file: the joints `q` (rad, written in deg), the frame's origin `p`
/// (mm) and orientation `r`.
pub(crate) fn probe_row(q: &[f64], p: &Vector3<f64>, r: &nalgebra::UnitQuaternion<f64>) -> String {
    let degrees: Vec<String> = q.iter().map(|v| format!("{:.9}", v.to_degrees())).collect();
    format!(
        "{},{:.6},{:.6},{:.6},{:.12},{:.12},{:.12},{:.12}\n",
        degrees.join(","),
        p.x,
        p.y,
        p.z,
        r.w,
        r.i,
        r.j,
        r.k
    )
}

/// A 6-DOF probe: the file gives marker 1's position and the frame's orientation (quaternion);
/// the probe is mounted turned by about 30 degrees, which the calibration must find.
#[test]
fn a_probe_with_orientation_calibrates_its_mounting_too() {
    let mut rng = ChaCha8Rng::seed_from_u64(31);
    let nominal = RobotModel::preset("puma560").unwrap();
    let truth = true_robot(&nominal, &mut rng);
    let mounting = Placement { xyz: Vector3::new(52.0, 1.0, 148.0), rpy: Vector3::new(0.3, -0.2, 0.5) };
    let chain = Chain::probe(&truth, &mounting);
    let real = chain.with_errors(&vec![0.0; chain.params().len()]);
    let noise = NoiseModel::diagonal(&joint_sigmas(), MeasurementNoise::isotropic(1e-3, 1e-6));
    let texts = (
        probe_csv(&nominal, &real, 120, &joint_sigmas(), &mut rng),
        probe_csv(&nominal, &real, 60, &joint_sigmas(), &mut rng),
    );
    let read = |text: &str| crate::marker_data(text, &nominal, Some(&noise));
    let (training, validation) = (read(&texts.0), read(&texts.1));
    assert_eq!(training.probes(), [0]);
    let options =
        crate::marker_options(&nominal, Estimator::Wls, Some(&noise), &[Vector3::new(50.0, 0.0, 150.0)]);
    let calibration = calibrate_kinds(&nominal, &training, &options).unwrap();
    let held_out = calibration.score(&validation).unwrap();
    let (before, after) = held_out.markers.unwrap();
    assert!(before / after >= 5.0, "held-out RMS {before:.4} mm before, {after:.4} mm after");
    let robocal::model::Tool::Frame(found) = calibration.calibrated.tool else {
        panic!("a probe gives a tool frame")
    };
    // The mounting is seen through the registered base: compare what the whole chain does.
    let calibrated = Chain::new(&calibration.calibrated);
    let fitted = calibrated.with_errors(&vec![0.0; calibrated.params().len()]);
    let q = &validation.joints[0];
    let angle = fitted.pose(q).rotation.angle_to(&real.pose(q).rotation).to_degrees();
    assert!(angle < 0.01, "the calibrated frame is turned {angle} deg from the true one ({found:?})");
    // The probe's orientation error falls too.
    let orientation = held_out.angles.expect("a probe's orientation errors");
    assert!(orientation.1 < orientation.0, "orientation error falls: {orientation:?}");
    // The calibrated model scored as it stands gives the same residuals, observation by
    // observation, its orientations too: the probe's frame is the model's tool frame, not one
    // turned to the held-out data.
    let as_it_stands =
        KindOptions::as_it_stands(&calibration.calibrated, &calibration.marker_positions(), &validation)
            .unwrap();
    let scored = evaluate_kinds(&calibration.calibrated, &validation, &as_it_stands).unwrap();
    assert_eq!(held_out.observations.len(), scored.observations.len());
    assert!(held_out.observations.iter().any(|a| a.kind != "marker"), "orientations are scored");
    for (a, b) in held_out.observations.iter().zip(&scored.observations) {
        assert!(
            (a.after - b.before).abs() < 1e-9,
            "line {} {}: {} against {}",
            a.line,
            a.kind,
            a.after,
            b.before
        );
    }
}

#[test]
fn orientation_columns_read_and_their_errors() {
    let model = RobotModel::preset("puma560").unwrap();
    let text = "# units: joints=deg, lengths=mm\nj1,j2,j3,j4,j5,j6,x1,y1,z1,roll,pitch,yaw\n1,2,3,4,5,6,7,8,9,90,0,0\n";
    let data = KindData::from_csv_str(text, &model, None).unwrap();
    let orientations: Vec<_> = (data.observations.iter())
        .filter_map(|o| match *o {
            Observation::Orientation { measured, .. } => Some(measured),
            _ => None,
        })
        .collect();
    assert_eq!(orientations.len(), 3, "the three rows of one orientation");
    let r = orientations[0];
    assert!((r.angle() - std::f64::consts::FRAC_PI_2).abs() < 1e-12 && r.axis().unwrap().x > 0.999);
    let head = "# units: joints=deg, lengths=mm\n";
    assert_eq!(
        data_error(&format!("{head}j1,j2,j3,j4,j5,j6,x1,y1,z1,qw,qx,qy\n1,2,3,4,5,6,7,8,9,1,0,0\n")),
        "line 2: orientation: give all of qw,qx,qy,qz or all of roll,pitch,yaw, not parts or both"
    );
    assert_eq!(
        data_error(&format!(
            "{head}j1,j2,j3,j4,j5,j6,x1,y1,z1,x2,y2,z2,roll,pitch,yaw\n1,2,3,4,5,6,7,8,9,1,2,3,0,0,0\n"
        )),
        "line 2: orientation columns need exactly one marker (x1,y1,z1): the measured frame's origin"
    );
    assert_eq!(
        data_error(&format!("{head}j1,j2,j3,j4,j5,j6,x1,y1,z1,qw,qx,qy,qz\n1,2,3,4,5,6,7,8,9,0.9,0,0,0\n")),
        "line 3, column `qw`: a unit quaternion, its norm is 0.900000"
    );
    // A file that fits two kinds (marker columns and a distance) is read as neither, said why.
    assert_eq!(
        data_error(&format!("{head}j1,j2,j3,j4,j5,j6,x1,y1,z1,distance\n1,2,3,4,5,6,7,8,9,500\n")),
        "line 2, column `distance`: a marker file (x1,y1,z1, ...) has marker positions and a probe's \
         orientation only: give the other kinds in files of their own"
    );
    // A joint named as one of those columns (a gantry's `x`) is the joint's.
    let mut gantry = RobotModel::preset("puma560").unwrap();
    gantry.joints[0].name = "x".into();
    let text = format!("{head}x,j2,j3,j4,j5,j6,x1,y1,z1\n1,2,3,4,5,6,7,8,9\n");
    assert_eq!(KindData::from_csv_str(&text, &gantry, None).unwrap().joints[0][0], 1f64.to_radians());
}

/// The gauge is physical: of every combination the poses cannot tell apart, the joint
/// parameter is held, never the measuring frame (base) or a marker, which no external device
/// shares with the robot. On the PUMA 560 with an unknown base and two markers, the held set is
/// exactly: what the base absorbs (joint 1's offset, its `d` and `beta`), what the markers
/// absorb (joint 6's offset, `d`, `a`, `alpha`, `beta`), and the joint-joint redundancies of
/// the DH parameterisation, where Hayati's `beta` and a revolute joint's `d` are held before
/// the offsets (`j3.d` with `j2.d`; `beta` with `theta` on joints 3 to 5).
#[test]
fn the_gauge_holds_joint_parameters_never_the_base_or_the_markers() {
    for seed in [11, 12, 13] {
        let c = campaign(seed);
        let calibration = calibrate_kinds(&c.nominal, &c.training, &c.options).unwrap();
        let held: Vec<&str> = calibration.fixed.iter().map(Held::parameter).collect();
        let expected = [
            "j1.theta", "j1.d", "j1.beta", "j3.d", "j3.beta", "j4.beta", "j5.beta", "j6.theta", "j6.d",
            "j6.a", "j6.alpha", "j6.beta",
        ];
        assert_eq!(held, expected, "seed {seed}: {:?}", calibration.fixed);
        let names = &calibration.refined.estimate.names;
        for p in calibration.params.iter().filter(|p| !matches!(p.owner, ParamOwner::Joint(_))) {
            assert!(names.contains(&p.name), "seed {seed}: {} is estimated", p.name);
        }
    }
}

/// A probe's campaign: the true robot's probe chain, the texts of a training and a validation
/// file.
fn probe_campaign(seed: u64) -> (RobotModel, ChainAt, String, String) {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let nominal = RobotModel::preset("puma560").unwrap();
    let truth = true_robot(&nominal, &mut rng);
    let mounting = Placement { xyz: Vector3::new(52.0, 1.0, 148.0), rpy: Vector3::new(0.3, -0.2, 0.5) };
    let chain = Chain::probe(&truth, &mounting);
    let real = chain.with_errors(&vec![0.0; chain.params().len()]);
    let training = probe_csv(&nominal, &real, 80, &joint_sigmas(), &mut rng);
    let validation = probe_csv(&nominal, &real, 60, &joint_sigmas(), &mut rng);
    (nominal, real, training, validation)
}

/// The probe's options as `robocal calibrate` sets them: marker 1 at its nominal mounting.
fn probe_options(nominal: &RobotModel, estimator: Estimator, noise: Option<&NoiseModel>) -> KindOptions {
    crate::marker_options(nominal, estimator, noise, &[Vector3::new(50.0, 0.0, 150.0)])
}

/// The probe's noise: the joints', 0.01 mm and 0.002 deg.
fn probe_noise() -> NoiseModel {
    NoiseModel::diagonal(&joint_sigmas(), MeasurementNoise::isotropic(0.01, 0.002f64.to_radians()))
}

/// A noise file with a device and no `sigma_orientation_deg` gives a probe's orientation rows
/// the device's typical figure (a laser tracker's 6-DOF probe: 0.01 deg); its own value wins
/// when given; without a device nothing is given, and the rows keep the default, counted as
/// assumed.
#[test]
fn a_devices_orientation_sigma_is_the_default_for_a_probe() {
    let (nominal, _, training, _) = probe_campaign(53);
    let spec = |text: &str| robocal::estimation::NoiseSpec::from_toml_str(text, &nominal).unwrap();
    let joints = "joint_sigma = [0.007, 0.007, 0.007, 0.002, 0.002, 0.002]\nsigma_me_mm = 0.01\n";
    let device = "[device]\nkind = \"laser-tracker\"\nposition_mm = [2500.0, 0.0, 300.0]\nsigma_r_mm = 0.01\n\
                  k_ppm = 5.0\nsigma_angle_arcsec = 2.0\n";
    let orientation_sigmas = |text: &str| -> Vec<f64> {
        let defaults = RowSigmaDefaults::of_noise(&spec(text));
        let data = KindData::from_csv_str_with(&training, &nominal, None, defaults).unwrap();
        data.observations.iter().filter(|o| o.is_angle()).map(|o| o.sigma().to_degrees()).collect()
    };
    let with_device = orientation_sigmas(&format!("{joints}{device}"));
    assert_eq!(with_device.len(), 3 * 80, "three orientation rows a pose");
    assert!(with_device.iter().all(|s| (s - 0.01).abs() < 1e-12), "{:?}", &with_device[..3]);
    let given = orientation_sigmas(&format!("{joints}sigma_orientation_deg = 0.003\n{device}"));
    assert!(given.iter().all(|s| (s - 0.003).abs() < 1e-12), "{:?}", &given[..3]);
    assert_eq!(RowSigmaDefaults::of_noise(&spec(joints)).angle_rad, None);
    let default = orientation_sigmas(joints);
    assert!(default.iter().all(|s| (s - DEFAULT_SIGMA_ANGLE_DEG).abs() < 1e-12), "{:?}", &default[..3]);
}

/// Ordinary least squares counts a probe's angle rows as lengths by the noise's
/// `sigma_position / sigma_orientation`: with exact joints and one sigma per class, it
/// minimises the weighted cost itself, so its estimate is the WLS estimate (to 1e-9), for a
/// ratio far from the default pose sigmas' (here 22.9 mm/rad against 286).
#[test]
fn ols_weighs_a_probes_angles_by_the_noises_sigma_ratio() {
    let mut rng = ChaCha8Rng::seed_from_u64(59);
    let nominal = RobotModel::preset("puma560").unwrap();
    let truth = true_robot(&nominal, &mut rng);
    let mounting = Placement { xyz: Vector3::new(52.0, 1.0, 148.0), rpy: Vector3::new(0.3, -0.2, 0.5) };
    let chain = Chain::probe(&truth, &mounting);
    let real = chain.with_errors(&vec![0.0; chain.params().len()]);
    // Exact joints; every position and orientation measured with noise, so that the
    // weighting matters.
    let mut text = String::from(PROBE_HEADER);
    for q in poses(&nominal, 40, &mut rng) {
        let pose = real.pose(&q);
        let mut draw = || Vector3::from_fn(|_, _| StandardNormal.sample(&mut rng));
        let p = pose.translation.vector + 0.02 * draw();
        let turn = nalgebra::UnitQuaternion::from_scaled_axis(0.05f64.to_radians() * draw());
        text += &probe_row(&q, &p, &(turn * pose.rotation));
    }
    let noise = NoiseModel::diagonal(&[0.0; 6], MeasurementNoise::isotropic(0.02, 0.05f64.to_radians()));
    let data = crate::marker_data(&text, &nominal, Some(&noise));
    let fit = |estimator| {
        let c = calibrate_kinds(&nominal, &data, &probe_options(&nominal, estimator, Some(&noise))).unwrap();
        c.refined.estimate.x.clone()
    };
    let (ols, wls) = (fit(Estimator::Ols), fit(Estimator::Wls));
    let gap = (&ols - &wls).amax() / wls.amax();
    assert!(gap < 1e-9, "ols {ols} against wls {wls}: {gap:e}");
}

/// On 6-DOF data, ordinary least squares (with and without a noise model) and Gauss-Markov
/// both lower the orientation and position errors of held-out poses, and OLS, its orientation
/// rows counted as lengths by `sigma_position / sigma_orientation` of the default pose sigmas,
/// comes within a factor of 2 of WLS.
#[test]
fn ols_and_wls_on_probe_data_lower_the_held_out_orientation_error() {
    let (nominal, _, training, validation) = probe_campaign(41);
    let mut rms = Vec::new();
    for (estimator, noise) in
        [(Estimator::Ols, None), (Estimator::Ols, Some(probe_noise())), (Estimator::Wls, Some(probe_noise()))]
    {
        let read = |text: &str| crate::marker_data(text, &nominal, noise.as_ref());
        let options = probe_options(&nominal, estimator, noise.as_ref());
        let calibration = calibrate_kinds(&nominal, &read(&training), &options).unwrap();
        let held_out = calibration.score(&read(&validation)).unwrap();
        let (before, after) = held_out.angles.expect("a probe's orientation errors");
        assert!(
            after * 5.0 < before,
            "{estimator:?}: held-out orientation RMS {before:.5} deg before, {after:.5} deg after"
        );
        let positions = held_out.markers.unwrap();
        assert!(positions.1 * 5.0 < positions.0, "{estimator:?}: positions {positions:?}");
        rms.push(after);
    }
    assert!(rms[0] < 2.0 * rms[2] && rms[1] < 2.0 * rms[2], "OLS against WLS (deg): {rms:?}");
}

/// `model` with its lengths in metres (a DH model without prismatic joints).
pub(crate) fn in_metres(model: &RobotModel) -> RobotModel {
    let mut m = model.clone();
    for joint in &mut m.joints {
        joint.d /= 1000.0;
        joint.a /= 1000.0;
    }
    m.base.xyz /= 1000.0;
    m.tool = match m.tool {
        Tool::Point(p) => Tool::Point(p / 1000.0),
        Tool::Frame(f) => Tool::Frame(Placement { xyz: f.xyz / 1000.0, rpy: f.rpy }),
    };
    m
}

/// The standard error of each of `c`'s parameters (NaN: not estimated).
pub(crate) fn standard_errors(c: &KindCalibration) -> Vec<f64> {
    let estimate = &c.refined.estimate;
    let se = estimate.standard_errors();
    let at = |name: &String| estimate.names.iter().position(|n| n == name).map_or(f64::NAN, |k| se[k]);
    c.params.iter().map(|p| at(&p.name)).collect()
}

/// The probe's frame is found absolutely, in the tip link's frame: with only the base and the
/// probe estimated on exact data, the calibrated tool frame is the true mounting, whatever the
/// data-derived start; the report gives it in the tip link's frame `F` (the model's tool
/// frame, here 66 mm past the last joint and turned), `F^-1 T`, in its text and JSON.
#[test]
fn the_probe_frame_is_reported_absolutely_in_the_tip_link_frame() {
    let mut rng = ChaCha8Rng::seed_from_u64(47);
    let tip = Placement { xyz: Vector3::new(0.0, 0.0, 66.0), rpy: Vector3::new(0.0, 0.3, 0.0) };
    let nominal = RobotModel { tool: Tool::Frame(tip), ..RobotModel::preset("puma560").unwrap() };
    let mut truth = nominal.clone();
    truth.base = Placement { xyz: Vector3::new(1500.0, -300.0, 200.0), rpy: Vector3::new(0.1, -0.05, 0.6) };
    let mounting = Placement { xyz: Vector3::new(52.0, 1.0, 148.0), rpy: Vector3::new(0.3, -0.2, 0.5) };
    let chain = Chain::probe(&truth, &mounting);
    let real = chain.with_errors(&vec![0.0; chain.params().len()]);
    let training = probe_file(&nominal, &real, 30, &[0.0; 6], &mut rng, None);
    let options = KindOptions { joints: JointParams::None, ..probe_options(&nominal, Estimator::Ols, None) };
    let calibration = calibrate_kinds(&nominal, &training, &options).unwrap();
    let found = calibration.tip_frame.expect("a probe's frame");
    assert!((found.xyz - mounting.xyz).norm() < 1e-4, "{:?} against {:?}", found.xyz, mounting.xyz);
    let angle = found.isometry().rotation.angle_to(&mounting.isometry().rotation);
    assert!(angle < 1e-8, "turned {angle} rad from the true mounting");
    let Tool::Frame(tool) = calibration.calibrated.tool else { panic!("a probe's frame") };
    let through_tip = tip.isometry() * mounting.isometry();
    assert!((tool.xyz - through_tip.translation.vector).norm() < 1e-4, "the tool in the last joint's frame");
    let report = robocal::report::observations::ObservationsReport::new(
        &calibration,
        "probe.csv",
        (240, 40),
        "ols",
        vec![],
    );
    let t = report.tip_frame.expect("in the report");
    assert!((t[0] - 52.0).abs() < 1e-4 && (t[3] - 0.3f64.to_degrees()).abs() < 1e-6, "{t:?}");
    assert!(report.text().contains("probe frame in the tip link's frame: xyz (52.000, 1.000, 148.000) mm"));
    assert!(serde_json::to_value(&report).unwrap()["tip_frame"].is_array());
}

/// Without a noise model the training residuals are whitened by their spread, a pose's
/// orientation rows by the default orientation sigma: a pose whose orientation is 1 degree
/// off (its position right) is flagged, by its line, alone.
#[test]
fn a_probe_pose_turned_off_is_flagged_without_a_noise_model() {
    let (nominal, _, training, _) = probe_campaign(49);
    let mut data = crate::marker_data(&training, &nominal, None);
    let turned = nalgebra::UnitQuaternion::from_euler_angles(0.0, 1f64.to_radians(), 0.0);
    let mut line = None;
    for (k, o) in data.observations.iter_mut().enumerate() {
        if let Observation::Orientation { pose: 7, measured, .. } = o {
            *measured = turned * *measured;
            line = Some(k);
        }
    }
    let line = data.lines[line.expect("pose 7's orientation")];
    let calibration =
        calibrate_kinds(&nominal, &data, &probe_options(&nominal, Estimator::Ols, None)).unwrap();
    let flagged = far_out(&calibration.warnings);
    assert!(
        matches!(flagged.as_slice(), [(_, o)] if !o.is_empty() && o.iter().all(|f| f.line == line)),
        "{:?}",
        calibration.warnings
    );
}

/// Feasible GLS on 6-DOF data: it starts from OLS (orientation rows weighted by the default
/// sigmas), estimates an orientation sigma with the others, weights with one above 0, and
/// lowers the held-out errors.
#[test]
fn feasible_gls_on_probe_data_estimates_the_orientation_sigma() {
    let (nominal, _, training, validation) = probe_campaign(51);
    let options = probe_options(&nominal, Estimator::Ols, None);
    let read = |text: &str| crate::marker_data(text, &nominal, None);
    let c = calibrate_kinds_feasible(&nominal, &read(&training), &options, &Default::default()).unwrap();
    let estimate = c.noise_estimate.as_ref().expect("the estimated noise");
    // The probe's readings are exact here (only the joints are noisy): the estimate is at
    // the bound 0, and the weights use what the data cannot rule out, above 0.
    let orientation = estimate.sigma_orientation().expect("an orientation sigma");
    assert!(orientation.high < 1e-4, "{orientation:?}");
    assert!(estimate.weighting_sigmas().1 > 0.0);
    let o = c.score(&read(&validation)).unwrap().angles.expect("orientation errors");
    assert!(o.1 * 5.0 < o.0, "orientation RMS {} -> {} deg", o.0, o.1);
}

/// On the example's marker file (the README's calibration, by ordinary least squares and
/// Gauss-Markov with the paper's noise) every step of the trust region is Gauss-Newton's,
/// undamped.
#[test]
fn the_example_calibrations_take_gauss_newton_steps_alone() {
    let model = RobotModel::preset("puma560").unwrap();
    let text = std::fs::read_to_string("examples/puma560-measurements.csv").unwrap();
    let markers = vec![Vector3::new(50.0, 0.0, 150.0), Vector3::new(-40.0, 60.0, 120.0)];
    let sigmas: Vec<f64> =
        [0.007, 0.007, 0.007, 0.002, 0.002, 0.002].iter().map(|d: &f64| d.to_radians()).collect();
    let noise = NoiseModel::diagonal(&sigmas, MeasurementNoise::isotropic(0.01, 0.0));
    for (estimator, noise) in [(Estimator::Ols, None), (Estimator::Wls, Some(noise))] {
        let data = crate::marker_data(&text, &model, noise.as_ref());
        let options = crate::marker_options(&model, estimator, noise.as_ref(), &markers);
        let c = calibrate_kinds(&model, &data, &options).unwrap();
        let history = &c.refined.history;
        assert!(c.refined.converged && history.len() >= 2, "{history:?}");
        assert!(history.iter().all(|step| step.damping == 0.0), "{estimator:?}: {history:?}");
    }
}
