//! Joints that follow their gravity load: compliance and play recovered exactly from
//! noise-free data, on a 6-joint DH arm and a 7-joint URDF arm.

use nalgebra::Vector3;
use rand::rngs::ChaCha8Rng;
use rand::{RngExt, SeedableRng};
use robocal::calibration::Held;
use robocal::calibration::JointParams;
use robocal::calibration::kinds::{KindData, KindOptions, calibrate_kinds, evaluate_kinds};
use robocal::estimation::Estimator;
use robocal::kinematics::Chain;
use robocal::model::{LinkMass, ParamOwner, RobotModel};

/// Noise-free marker positions of `truth` at `n` poses drawn within its limits, as a marker
/// file's coordinates (their sigmas not given).
pub(crate) fn measured(truth: &RobotModel, markers: &[Vector3<f64>], n: usize, seed: u64) -> KindData {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let joints: Vec<Vec<f64>> = (0..n)
        .map(|_| truth.joints.iter().map(|j| rng.random_range(j.limits[0]..j.limits[1])).collect())
        .collect();
    let chains = Chain::markers(truth, markers);
    let at: Vec<_> = chains.iter().map(|c| c.with_errors(&vec![0.0; c.params().len()])).collect();
    let positions: Vec<Vec<Vector3<f64>>> =
        joints.iter().map(|q| at.iter().map(|a| a.position(q)).collect()).collect();
    crate::nested::marker_kind_data(joints, &positions)
}

/// Calibrates `nominal` on noise-free data of `truth` (which differs from it in its compliances,
/// plays and `geometry`), every joint parameter with the compliances and plays, and checks
/// that each load response estimated is the truth's, and that those of `expected` are.
fn recovers(nominal: &RobotModel, truth: &RobotModel, expected: &[&str]) {
    let true_markers =
        [Vector3::new(40.0, 0.0, 25.0), Vector3::new(-20.0, 35.0, 25.0), Vector3::new(0.0, -30.0, 60.0)];
    let data = measured(truth, &true_markers, 80, 7);
    let design: Vec<Vector3<f64>> = true_markers.iter().map(|m| m + Vector3::new(0.3, -0.2, 0.1)).collect();
    let options = KindOptions {
        joints: JointParams::Named(vec!["*.*".into()]),
        ..crate::marker_options(nominal, Estimator::Ols, None, &design)
    };
    let result = calibrate_kinds(nominal, &data, &options).unwrap();
    assert!(result.refined.converged);
    let max = result.training.positions_of(None).max.1;
    assert!(max < 1e-7, "training error {max:e} mm");
    let mut checked = Vec::new();
    for name in &result.refined.estimate.names {
        let i = result.params.index_by_name(name).unwrap();
        let p = result.params.get(i);
        let ParamOwner::Joint(j) = p.owner else { continue };
        if !p.is_load_response() {
            continue;
        }
        let (found, truth) = match p.kind {
            robocal::model::ParamKind::Compliance => {
                (result.calibrated.joints[j].compliance, truth.joints[j].compliance)
            }
            _ => (result.calibrated.joints[j].play, truth.joints[j].play),
        };
        let scale =
            truth.abs().max(if p.kind == robocal::model::ParamKind::Compliance { 1e-6 } else { 1e-4 });
        assert!((found - truth).abs() < 1e-5 * scale, "{name}: {found:e}, truth {truth:e}");
        checked.push(name.clone());
    }
    for name in expected {
        assert!(checked.iter().any(|c| c == name), "{name} not estimated: {checked:?}");
    }
}

/// The PUMA 560 with link masses; its first axis is vertical: gravity never loads it.
pub(crate) fn puma_with_masses() -> RobotModel {
    let mut model = RobotModel::preset("puma560").unwrap();
    let masses = [
        (0.0, [0.0, 0.0, 0.0]),
        (17.4, [68.0, 6.0, -16.0]),
        (4.8, [0.0, -70.0, 14.0]),
        (0.82, [0.0, 0.0, -19.0]),
        (0.34, [0.0, 0.0, 0.0]),
        (0.09, [0.0, 0.0, 32.0]),
    ];
    model.masses = masses.iter().map(|&(mass, c)| LinkMass { mass, com: Vector3::from(c) }).collect();
    model
}

#[test]
fn compliance_and_play_are_recovered_exactly_on_a_six_joint_arm() {
    let nominal = puma_with_masses();
    let mut truth = nominal.clone();
    truth.joints[1].compliance = 5e-5;
    truth.joints[2].compliance = 8e-5;
    truth.joints[2].play = 0.02f64.to_radians();
    truth.joints[4].compliance = 3e-4;
    truth.joints[1].a += 0.4;
    truth.joints[3].alpha += 0.03f64.to_radians();
    recovers(&nominal, &truth, &["j2.compliance", "j3.compliance", "j3.play", "j5.compliance"]);
}

#[test]
fn compliance_and_play_are_recovered_exactly_on_a_seven_joint_arm() {
    let nominal =
        robocal::io::load_model(&robocal::model::ModelRef::named("examples/arm7/arm7.urdf")).unwrap();
    let mut truth = nominal.clone();
    truth.joints[1].compliance = 4e-5;
    truth.joints[3].compliance = 6e-5;
    truth.joints[5].compliance = 1.5e-4;
    truth.joints[5].play = 0.03f64.to_radians();
    truth.joints[2].origin.xyz.x += 0.3;
    recovers(
        &nominal,
        &truth,
        &["joint2.compliance", "joint4.compliance", "joint6.compliance", "joint6.play"],
    );
}

/// A payload joins the last link's mass: on a pendulum (a revolute joint about y carrying 1 kg
/// at 1 m), 2 kg at 0.5 m in the tip frame adds 2 x 0.5 x g N·m; a model without masses
/// carries the payload alone, and then has compliances.
#[test]
fn a_payload_adds_its_weight_to_the_joint_loads() {
    use robocal::model::{Convention, Joint, JointKind, Payload, Placement, Tool};
    let joint = Joint::urdf("j1", JointKind::Revolute, Placement::default(), Vector3::y(), [-3.0, 3.0]);
    let tip = Placement { xyz: Vector3::new(200.0, 0.0, 0.0), rpy: Vector3::zeros() };
    let pendulum = RobotModel {
        name: "pendulum".into(),
        description: String::new(),
        convention: Convention::Urdf,
        base: Placement::default(),
        joints: vec![joint],
        tool: Tool::Frame(tip),
        masses: vec![LinkMass { mass: 1.0, com: Vector3::new(1000.0, 0.0, 0.0) }],
        gravity: RobotModel::floor_gravity(),
        payload: None,
    };
    let torque = |model: &RobotModel| {
        let chain = Chain::new(model);
        let mut tau = [0.0];
        chain.with_errors(&vec![0.0; chain.params().len()]).gravity_torques(&[0.0], &mut tau);
        tau[0]
    };
    // 300 mm past the tip frame, which is 200 mm past the joint: 0.5 m.
    let payload = Payload { mass: 2.0, com: Vector3::new(300.0, 0.0, 0.0) };
    let loaded = pendulum.with_payload(&payload);
    assert!((torque(&loaded) - 9.80665 * (1.0 + 2.0 * 0.5)).abs() < 1e-12, "{}", torque(&loaded));
    let massless = RobotModel { masses: Vec::new(), ..pendulum.clone() };
    assert!(massless.params().index_by_name("j1.compliance").is_none());
    let carried = massless.with_payload(&payload);
    assert!((torque(&carried) - 9.80665).abs() < 1e-12);
    assert!(carried.params().index_by_name("j1.compliance").is_some());
}

/// `fk --payload-kg` deflects a compliant model's joints under the payload; a rigid model does
/// not move, and a centre of mass without a mass is a usage error.
#[test]
fn fk_applies_a_payload_to_a_compliant_model() {
    let mut model = puma_with_masses();
    model.joints[1].compliance = 1e-4;
    let dir = std::env::temp_dir().join(format!("robocal-payload-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("compliant.toml");
    std::fs::write(&path, model.to_toml_string()).unwrap();
    let fk = |model: &str, payload: &[&str]| {
        let mut args = vec!["fk", "--model", model, "--q", "0,10,-90,0,0,0"];
        args.extend(payload);
        let output = assert_cmd::Command::cargo_bin("robocal").unwrap().args(&args).output().unwrap();
        assert!(output.status.success(), "{}", String::from_utf8_lossy(&output.stderr));
        String::from_utf8(output.stdout).unwrap()
    };
    let path = path.to_str().unwrap();
    let payload = ["--payload-kg", "5", "--payload-com-mm", "0,0,50"];
    assert_ne!(fk(path, &[]), fk(path, &payload));
    assert_eq!(fk("puma560", &[]), fk("puma560", &payload));
    let output = assert_cmd::Command::cargo_bin("robocal")
        .unwrap()
        .args(["fk", "--model", "puma560", "--q", "0,0,0,0,0,0", "--payload-com-mm", "0,0,50"])
        .output()
        .unwrap();
    assert_eq!(output.status.code(), Some(2));
    std::fs::remove_dir_all(&dir).unwrap();
}

/// URDF has no field for a joint's compliance or play: `to_urdf_string` writes them in
/// robocal's extension element, which the reader takes back (and a second write replaces).
#[test]
fn compliance_and_play_survive_a_urdf_round_trip() {
    use robocal::model::{DEFLECTION, JointKind, from_urdf_str, to_urdf_string};
    let text = std::fs::read_to_string("examples/arm7/arm7.urdf").unwrap();
    let (base, tip) = robocal::model::chain_links(&text, None, None).unwrap();
    let nominal = from_urdf_str(&text, &base, &tip).unwrap();
    let mut calibrated = nominal.clone();
    calibrated.joints[1].compliance = 4.25e-5;
    calibrated.joints[5].play = 0.03f64.to_radians();
    let prismatic = calibrated.joints.iter().position(|j| j.kind == JointKind::Prismatic);
    if let Some(k) = prismatic {
        calibrated.joints[k].compliance = 2e-3;
    }
    let written = to_urdf_string(&text, &base, &tip, &calibrated).unwrap();
    assert_eq!(written.matches(DEFLECTION).count(), 2 + usize::from(prismatic.is_some()));
    let again = to_urdf_string(&written, &base, &tip, &calibrated).unwrap();
    assert_eq!(again.matches(DEFLECTION).count(), written.matches(DEFLECTION).count());
    let read = from_urdf_str(&again, &base, &tip).unwrap();
    for (r, c) in read.joints.iter().zip(&calibrated.joints) {
        assert!((r.compliance - c.compliance).abs() <= 1e-15 * c.compliance.abs(), "{}", r.name);
        assert!((r.play - c.play).abs() <= 1e-12 * c.play.abs().max(1e-12), "{}", r.name);
    }
}

/// The `compliance` study, reduced: joints 2 and 3 of the PUMA 560 deflect under gravity and a
/// 2 kg payload. Identifying the compliances lowers `E_p` below the geometric model's on the
/// same runs by far more than 3 standard errors of the paired difference, and the table says
/// by how much.
#[test]
fn a_study_shows_what_modelling_compliance_gains() {
    let text = include_str!("../../presets/compliance.toml")
        .replace("points = [48, 96]", "points = [48]")
        .replace("point_sets = 6", "point_sets = 3")
        .replace("runs_per_set = 16", "runs_per_set = 4")
        .replace("test_points = 1000", "test_points = 200");
    let study = robocal::simulation::Study::from_toml_str(&text, robocal::io::load_model).unwrap();
    assert_eq!(study.estimators[1].to_string(), "wls+compliance");
    assert_eq!(study.truth.compliance, vec![0.0, 5e-5, 5e-5, 0.0, 0.0, 0.0]);
    assert_eq!(study.robot.payload.map(|p| p.mass), Some(2.0));
    let results = robocal::simulation::run(&study, &|| {}).unwrap();
    let differences: Vec<f64> =
        results.runs.iter().map(|r| r.accuracy[0].mean - r.accuracy[1].mean).collect();
    let s = robocal::simulation::Summary::of(&differences);
    let se = s.sd / (s.n as f64).sqrt();
    assert!(s.mean > 3.0 * se && s.mean > 0.0, "E_p lowered by {} mm, SE {se}", s.mean);
    assert!(results.mean_error(0, 1) < 0.2 * results.mean_error(0, 0));
    let tables = robocal::report::study::tables(&study, &results);
    assert!(tables.contains("dE (%) = 100 (E_p[wls] - E_p[wls+compliance]) / E_p[wls]"), "{tables}");
}

/// A study's `[truth]` and `+compliance` say what is wrong with them.
#[test]
fn bad_compliance_studies_say_what_is_wrong() {
    let error = |from: &str, to: &str| {
        let base = include_str!("../../presets/compliance.toml");
        let text = base.replacen(from, to, 1);
        assert_ne!(text, base, "the test must change the file");
        robocal::error::chain(
            &robocal::simulation::Study::from_toml_str(&text, robocal::io::load_model).unwrap_err(),
        )
    };
    assert!(error("\"wls+compliance\"", "\"wls+stiffness\"").contains("found `+stiffness`"));
    assert_eq!(
        error("j2 = 5e-5", "j9 = 5e-5"),
        "field `truth.compliance.j9`: a joint of the robot: j1, j2, j3, j4, j5, j6"
    );
    let rigid = include_str!("../../presets/compliance.toml")
        .replace("robot = \"puma560-masses\"", "robot = \"puma560\"")
        .replace("payload_kg = 2.0", "payload_kg = 0.0");
    let message = robocal::error::chain(
        &robocal::simulation::Study::from_toml_str(&rigid, robocal::io::load_model).unwrap_err(),
    );
    assert!(message.starts_with("field `estimators`: a robot with masses for `wls+compliance`"), "{message}");
}

/// `calibrate --payload-kg` loads the joints with the payload during the fit; the model it
/// writes is the robot's own, without the payload of that session: of a marker file and of
/// observation files alike.
#[test]
fn calibrate_with_a_payload_writes_the_robot_without_it() {
    let dir = std::env::temp_dir().join(format!("robocal-payload-calibrate-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let out = dir.join("calibrated.toml");
    let own = robocal::io::load_model(&robocal::model::ModelRef::named("examples/arm7/arm7.urdf")).unwrap();
    // One marker file and two (they wrote the session's payload).
    for (data, fitted) in [
        (&[][..], "37 poses, 3 markers"),
        (&["--data", "examples/arm7/session1.csv"][..], "97 poses, 3 markers"),
    ] {
        let output = assert_cmd::Command::cargo_bin("robocal")
            .unwrap()
            .args([
                "calibrate",
                "-q",
                "--model",
                "examples/arm7/arm7.urdf",
                "--data",
                "examples/arm7/train.csv",
            ])
            .args(data)
            .args(["--marker", "40,0,25", "--marker=-20,35,25", "--marker=-20,-35,25"])
            .args(["--params", "joint*.compliance", "--payload-kg", "2", "--payload-com-mm", "0,0,40"])
            .arg("--out-model")
            .arg(&out)
            .output()
            .unwrap();
        assert!(output.status.success(), "{}", String::from_utf8_lossy(&output.stderr));
        assert!(String::from_utf8_lossy(&output.stdout).contains(fitted), "{fitted}");
        let written = RobotModel::from_toml_str(&std::fs::read_to_string(&out).unwrap()).unwrap();
        assert_eq!((&written.masses, written.payload), (&own.masses, None));
        assert!(written.joints[1].compliance != 0.0);
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

/// `calibrate` reports each estimated compliance as a stiffness `1 / c` with its 95% interval
/// `[1 / (c + 1.96 SE), 1 / (c - 1.96 SE)]`, in the text and the JSON (docs/formats.md).
#[test]
fn the_report_gives_each_compliance_as_a_stiffness() {
    let dir = std::env::temp_dir().join(format!("robocal-stiffness-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let json = dir.join("report.json");
    let output = assert_cmd::Command::cargo_bin("robocal")
        .unwrap()
        .args(["calibrate", "--model", "examples/arm7/arm7.urdf", "--data", "examples/arm7/train.csv"])
        .args(["--marker", "40,0,25", "--marker=-20,35,25", "--marker=-20,-35,25"])
        .args(["--params", "joint2.compliance,joint4.compliance", "--json"])
        .arg(&json)
        .output()
        .unwrap();
    assert!(output.status.success(), "{}", String::from_utf8_lossy(&output.stderr));
    let text = String::from_utf8_lossy(&output.stdout);
    assert!(text.contains("joint stiffness") && text.contains("N·m/rad"), "{text}");
    let report: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    let rows = report["stiffness"].as_array().expect("a stiffness table");
    assert_eq!(rows.len(), 2, "{rows:?}");
    for row in rows {
        let joint = row["joint"].as_str().unwrap();
        let p = (report["parameters"].as_array().unwrap().iter())
            .find(|p| p["name"] == format!("{joint}.compliance"))
            .unwrap();
        let (c, se) = (p["value"].as_f64().unwrap(), p["std_error"].as_f64().unwrap());
        let near = |key: &str, v: f64| {
            let got = row[key].as_f64().unwrap_or(f64::NAN);
            assert!((got - v).abs() <= 1e-9 * v.abs(), "{joint} {key}: {got} against {v}");
        };
        if c > 0.0 {
            near("stiffness", 1.0 / c);
        }
        if c + 1.96 * se > 0.0 {
            near("low", 1.0 / (c + 1.959_963_984_540_054 * se));
        }
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

/// A payload's mass is seen through the joints' compliances: with a model whose compliances
/// are known (calibrated), `payload.mass` is recovered exactly from noise-free data; with every
/// compliance zero it is held, and said why.
#[test]
fn a_payload_mass_is_estimated_where_the_compliances_show_it() {
    use robocal::model::Payload;
    let mut nominal = puma_with_masses();
    nominal.joints[1].compliance = 5e-5;
    nominal.joints[2].compliance = 8e-5;
    nominal.payload = Some(Payload { mass: 2.0, com: Vector3::new(0.0, 20.0, 80.0) });
    let truth = RobotModel {
        payload: Some(Payload { mass: 3.5, com: Vector3::new(0.0, 20.0, 80.0) }),
        ..nominal.clone()
    };
    let markers = [Vector3::new(40.0, 0.0, 25.0), Vector3::new(-20.0, 35.0, 25.0)];
    let data = measured(&truth, &markers, 60, 11);
    let options = KindOptions {
        joints: JointParams::Named(vec!["payload.mass".into(), "j*.theta".into()]),
        estimate_base: false,
        estimate_markers: false,
        ..crate::marker_options(&nominal, Estimator::Ols, None, &markers)
    };
    let result = calibrate_kinds(&nominal, &data, &options).unwrap();
    let mass = result.calibrated.payload.unwrap().mass;
    assert!((mass - 3.5).abs() < 1e-6, "payload {mass} kg, truth 3.5");

    let rigid = RobotModel { joints: RobotModel::preset("puma560").unwrap().joints, ..nominal.clone() };
    let result = calibrate_kinds(&rigid, &data, &options).unwrap();
    assert!(
        result
            .fixed
            .iter()
            .map(Held::text)
            .any(|f| f.starts_with("payload.mass: the payload is seen only through the joints' compliances")),
        "{:?}",
        result.fixed
    );
    assert_eq!(result.calibrated.payload.unwrap().mass, 2.0);
}

/// A URDF written by `to_urdf_string` from a fit with compliances and plays scores as the fit
/// itself: the compliances in their element, and gravity in the measuring frame (which is not
/// the robot's) in the `measuring_frame` link's.
#[test]
fn a_written_urdf_with_compliances_scores_as_the_fit() {
    use robocal::model::{
        GRAVITY, chain_links, from_urdf_str, markers_from_urdf_str, to_urdf_string, with_urdf_markers,
    };
    let text = std::fs::read_to_string("examples/arm7/arm7.urdf").unwrap();
    let (base, tip) = chain_links(&text, None, None).unwrap();
    let model = from_urdf_str(&text, &base, &tip).unwrap();
    let read = |name: &str| {
        crate::marker_data(&std::fs::read_to_string(format!("examples/arm7/{name}")).unwrap(), &model, None)
    };
    let (train, session) = (read("train.csv"), read("session1.csv"));
    let options = crate::urdf::arm7_options(&model, JointParams::Named(vec!["joint*.*".into()]));
    let result = calibrate_kinds(&model, &train, &options).unwrap();
    let written = to_urdf_string(&text, &base, &tip, &result.calibrated).unwrap();
    let written = with_urdf_markers(&written, &result.marker_positions()).unwrap();
    assert_eq!(written.matches(GRAVITY).count(), 1);
    let reread = from_urdf_str(&written, "measuring_frame", "tool").unwrap();
    let markers = markers_from_urdf_str(&written).unwrap();
    let as_it_stands = KindOptions::as_it_stands(&reread, &markers, &session).unwrap();
    let scored = evaluate_kinds(&reread, &session, &as_it_stands).unwrap();
    let fitted = result.score(&session).unwrap();
    let (rms, fitted_rms) = (scored.markers.unwrap().1, fitted.markers.unwrap().1);
    assert!((rms - fitted_rms).abs() < 1e-9, "{rms} against {fitted_rms}");
    let (max, fitted_max) = (scored.positions_of(None).max.1, fitted.positions_of(None).max.1);
    assert!((max - fitted_max).abs() < 1e-9, "{max} against {fitted_max}");
}
