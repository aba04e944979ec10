//! Kinematics: Jacobians against finite differences, PUMA 560 closed forms, DH conventions.

use nalgebra::{DMatrix, Isometry3, Matrix6xX, Vector3};
use proptest::prelude::*;
use robocal::kinematics::{Chain, Measured, end_positions, marker_jacobians, pose_error};
use robocal::model::{Convention, Joint, JointKind, Placement, RobotModel, Selection, Tool};

fn puma() -> RobotModel {
    RobotModel::preset("puma560").unwrap()
}

/// A random serial robot of the given convention; `beta` decides whether the Hayati angles
/// are used (non-zero) or left at zero. URDF joints get a random origin and axis.
pub(crate) fn robot(convention: Convention, beta: bool) -> impl Strategy<Value = RobotModel> {
    let joint = (any::<bool>(), prop::array::uniform9(-1.0..1.0f64)).prop_map(move |(prismatic, u)| {
        let kind = if prismatic { JointKind::Prismatic } else { JointKind::Revolute };
        if convention == Convention::Urdf {
            let origin = Placement {
                xyz: Vector3::new(u[0], u[1], u[2]) * 300.0,
                rpy: Vector3::new(u[3], u[4], u[5]) * 3.0,
            };
            let axis = Vector3::new(u[6], u[7], u[8] + 0.01).normalize();
            return Joint::urdf("", kind, origin, axis, [-3.0, 3.0]);
        }
        let beta = if beta { u[4] * 0.5 } else { 0.0 };
        Joint::dh("", kind, [u[0] * 3.0, u[1] * 400.0, u[2] * 400.0, u[3] * 3.0, beta], [-3.0, 3.0])
    });
    let placement = prop::array::uniform6(-1.0..1.0f64).prop_map(|u| Placement {
        xyz: Vector3::new(u[0], u[1], u[2]) * 300.0,
        rpy: Vector3::new(u[3], u[4], u[5]) * 3.0,
    });
    (prop::collection::vec(joint, 1..=7), placement.clone(), placement, any::<bool>()).prop_map(
        move |(mut joints, base, tool, frame)| {
            for (i, joint) in joints.iter_mut().enumerate() {
                joint.name = format!("j{}", i + 1);
            }
            RobotModel {
                name: "random".into(),
                description: String::new(),
                convention,
                base,
                joints,
                tool: if frame { Tool::Frame(tool) } else { Tool::Point(tool.xyz) },
                masses: Vec::new(),
                gravity: RobotModel::floor_gravity(),
                payload: None,
            }
        },
    )
}

/// Joint values (rad or mm) and small parameter errors for `model`, from unit draws.
pub(crate) fn point(model: &RobotModel, u: &[f64]) -> (Vec<f64>, Vec<f64>) {
    let q = model
        .joints
        .iter()
        .zip(u)
        .map(|(j, u)| if j.kind == JointKind::Revolute { u * 3.0 } else { u * 200.0 })
        .collect();
    let params = model.params();
    let x = params
        .iter()
        .zip(u.iter().cycle().skip(3))
        .map(|(p, u)| if p.kind.is_angle() { u * 0.01 } else { u * 2.0 })
        .collect();
    (q, x)
}

/// Largest difference, each row relative to its own largest entry (or to 1 for small rows),
/// so that the angular rows (entries up to 1) are held as tightly as the linear ones (mm).
fn relative_error(a: &DMatrix<f64>, b: &DMatrix<f64>) -> f64 {
    (0..a.nrows()).map(|r| (a.row(r) - b.row(r)).amax() / a.row(r).amax().max(1.0)).fold(0.0, f64::max)
}

/// Central difference of the pose along `direction` of `values`, as a 6-vector column.
fn central_difference(
    values: &[f64],
    index: usize,
    pose: impl Fn(&[f64]) -> Isometry3<f64>,
) -> nalgebra::Vector6<f64> {
    let h = 1e-5;
    let (mut plus, mut minus) = (values.to_vec(), values.to_vec());
    plus[index] += h;
    minus[index] -= h;
    pose_error(&pose(&plus), &pose(&minus)) / (2.0 * h)
}

fn check_jacobians(model: &RobotModel, u: &[f64]) -> Result<(), TestCaseError> {
    let chain = Chain::new(model);
    let (q, x) = point(model, u);
    let params = chain.params();
    let at = chain.with_errors(&x);

    let all = Selection::all(params);
    let mut h = DMatrix::zeros(6, all.len());
    let mut j = Matrix6xX::zeros(model.dof());
    let e = at.jacobians(&q, &all, Measured::Pose, h.view_mut((0, 0), (6, all.len())), Some(&mut j));
    // The Jacobians walk the chain backwards: the same point, to rounding on arms of a metre.
    let moved = (e - at.position(&q)).amax();
    prop_assert!(moved < 1e-11, "position {moved:e}");

    let h_fd = DMatrix::from_fn(6, params.len(), |r, c| {
        central_difference(&x, c, |x| chain.with_errors(x).pose(&q))[r]
    });
    let err = relative_error(&h, &h_fd);
    prop_assert!(err < 1e-6, "H vs finite differences: relative error {err:e}");

    let j_fd = DMatrix::from_fn(6, model.dof(), |r, c| central_difference(&q, c, |q| at.pose(q))[r]);
    let err = relative_error(&DMatrix::from_column_slice(6, model.dof(), j.as_slice()), &j_fd);
    prop_assert!(err < 1e-6, "J vs finite differences: relative error {err:e}");

    // The single-Jacobian calls give the same numbers; position rows of a partial selection
    // are the matching rows and columns of the full H.
    let mut j_alone = Matrix6xX::zeros(model.dof());
    at.manipulator_jacobian(&q, &mut j_alone);
    prop_assert_eq!(&j_alone, &j);
    let partial = Selection::joints(params);
    let mut h3 = DMatrix::zeros(3, partial.len());
    at.identification_jacobian(&q, &partial, Measured::Position, h3.view_mut((0, 0), (3, partial.len())));
    for (column, &index) in partial.indices().iter().enumerate() {
        prop_assert_eq!(h3.column(column), h.fixed_view::<3, 1>(0, index));
    }
    Ok(())
}

/// The markers' shared walk equals each marker's own chain: H block by block, and positions.
fn check_marker_jacobians(model: &RobotModel, u: &[f64]) -> Result<(), TestCaseError> {
    let markers: Vec<Vector3<f64>> =
        (0..3).map(|m| Vector3::new(u[3 * m], u[3 * m + 1], u[3 * m + 2]) * 200.0).collect();
    let chains = Chain::markers(model, &markers);
    prop_assert!(chains.iter().all(Chain::ends_at_a_point));
    let params = chains[0].params();
    let x: Vec<f64> = (0..params.len()).map(|i| u[(i + 9) % u.len()] * 0.5).collect();
    let q: Vec<f64> = u.iter().skip(40).take(model.dof()).map(|v| v * 3.0).collect();
    let at: Vec<_> = chains.iter().map(|c| c.with_errors(&x)).collect();
    let all = Selection::all(params);
    let mut shared = DMatrix::zeros(9, all.len());
    let mut positions = vec![Vector3::zeros(); 3];
    marker_jacobians(&at, &q, &all, shared.view_mut((0, 0), (9, all.len())), &mut positions);
    for (m, at) in at.iter().enumerate() {
        let mut own = DMatrix::zeros(3, all.len());
        let e =
            at.identification_jacobian(&q, &all, Measured::Position, own.view_mut((0, 0), (3, all.len())));
        let err = relative_error(&own, &shared.rows(3 * m, 3).into_owned());
        prop_assert!(err < 1e-12, "marker {m}: H differs by {err:e}");
        prop_assert!((e - positions[m]).amax() < 1e-9, "marker {m}: position {e} against {}", positions[m]);
    }
    // Positions alone, the arm walked once: the same as each chain's forward kinematics.
    let mut ends = vec![Vector3::zeros(); 3];
    end_positions(&at, &q, &mut ends);
    for (m, at) in at.iter().enumerate() {
        let own = at.position(&q);
        prop_assert!(
            (own - ends[m]).amax() < 1e-9 * (1.0 + own.amax()),
            "marker {m}: {own} against {}",
            ends[m]
        );
    }
    // A probe's end rotates after the arm: its tail is walked as it is.
    let probe = Chain::probe(model, &Placement { xyz: markers[0], rpy: Vector3::new(u[0], u[1], u[2]) });
    let x: Vec<f64> = (0..probe.params().len()).map(|i| u[(i + 5) % u.len()] * 0.5).collect();
    let at = probe.with_errors(&x);
    end_positions(std::slice::from_ref(&at), &q, &mut ends[..1]);
    prop_assert!((at.position(&q) - ends[0]).amax() < 1e-9 * (1.0 + ends[0].amax()));
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(1000))]

    #[test]
    fn markers_share_one_walk_modified_dh(model in robot(Convention::ModifiedDh, true), u in prop::collection::vec(-1.0..1.0f64, 48)) {
        check_marker_jacobians(&model, &u)?;
    }

    #[test]
    fn markers_share_one_walk_urdf(model in robot(Convention::Urdf, false), u in prop::collection::vec(-1.0..1.0f64, 48)) {
        check_marker_jacobians(&model, &u)?;
    }

    #[test]
    fn jacobians_match_finite_differences_standard_dh(model in robot(Convention::StandardDh, false), u in prop::collection::vec(-1.0..1.0f64, 64)) {
        check_jacobians(&model, &u)?;
    }

    #[test]
    fn jacobians_match_finite_differences_standard_dh_with_beta(model in robot(Convention::StandardDh, true), u in prop::collection::vec(-1.0..1.0f64, 64)) {
        check_jacobians(&model, &u)?;
    }

    #[test]
    fn jacobians_match_finite_differences_modified_dh(model in robot(Convention::ModifiedDh, false), u in prop::collection::vec(-1.0..1.0f64, 64)) {
        check_jacobians(&model, &u)?;
    }

    #[test]
    fn jacobians_match_finite_differences_modified_dh_with_beta(model in robot(Convention::ModifiedDh, true), u in prop::collection::vec(-1.0..1.0f64, 64)) {
        check_jacobians(&model, &u)?;
    }

    #[test]
    fn jacobians_match_finite_differences_urdf(model in robot(Convention::Urdf, false), u in prop::collection::vec(-1.0..1.0f64, 64)) {
        check_jacobians(&model, &u)?;
    }

    #[test]
    fn jacobians_match_finite_differences_puma560(u in prop::collection::vec(-1.0..1.0f64, 64)) {
        check_jacobians(&puma(), &u)?;
    }

    /// Standard DH regrouped as modified DH: `Tx(a_i) Rx(alpha_i) Ry(beta_i)` moves to the
    /// front of joint i+1, and the last joint's to the tool.
    #[test]
    fn standard_and_modified_dh_describe_the_same_robot(model in robot(Convention::StandardDh, true), u in prop::collection::vec(-1.0..1.0f64, 8)) {
        let modified = to_modified_dh(&model);
        let q: Vec<f64> = u.iter().take(model.dof()).map(|u| u * 3.0).collect();
        let a = Chain::new(&model).with_errors(&vec![0.0; model.params().len()]);
        let b = Chain::new(&modified).with_errors(&vec![0.0; modified.params().len()]);
        // A tool point carries no orientation of its own: the last joint frames differ.
        let err = match model.tool {
            Tool::Point(_) => (a.position(&q) - b.position(&q)).amax(),
            Tool::Frame(_) => pose_error(&a.pose(&q), &b.pose(&q)).amax(),
        };
        prop_assert!(err < 1e-9, "tools differ by {err:e}");
    }
}

fn to_modified_dh(model: &RobotModel) -> RobotModel {
    let mut modified = model.clone();
    modified.convention = Convention::ModifiedDh;
    let mut lead = (0.0, 0.0, 0.0); // (a, alpha, beta) leading into the next joint
    for (standard, joint) in model.joints.iter().zip(&mut modified.joints) {
        (joint.a, joint.alpha, joint.beta) = lead;
        lead = (standard.a, standard.alpha, standard.beta);
    }
    // The last joint's Tx(a) Rx(alpha) Ry(beta) goes in front of the tool.
    let (a, alpha, beta) = lead;
    let last = Isometry3::translation(a, 0.0, 0.0)
        * nalgebra::UnitQuaternion::from_euler_angles(alpha, 0.0, 0.0)
        * nalgebra::UnitQuaternion::from_euler_angles(0.0, beta, 0.0);
    let tool = |p: &Placement| last * p.isometry();
    modified.tool = match &model.tool {
        Tool::Point(p) => Tool::Point((last * nalgebra::Point3::from(*p)).coords),
        Tool::Frame(f) => {
            let iso = tool(f);
            let (roll, pitch, yaw) = iso.rotation.euler_angles();
            Tool::Frame(Placement { xyz: iso.translation.vector, rpy: Vector3::new(roll, pitch, yaw) })
        }
    };
    modified
}

/// PUMA 560 by hand. Standard DH with d1 = d2 = a1 = 0, alpha = (90, 0, -90, 90, -90, 0) deg:
/// the wrist centre (origin of frames 4-6) is
///   X = a2 c2 + a3 c23 - d4 s23,  Y = a2 s2 + a3 s23 + d4 c23,
///   p = (c1 X + s1 d3, s1 X - c1 d3, Y),
/// and with q1 = q4 = q5 = q6 = 0 the frame-6 rotation is R = Rx(90) Rz(q2 + q3) Rx(-90),
/// a rotation by q2 + q3 about -y: [[c, 0, -s], [0, 1, 0], [s, 0, c]].
fn puma_by_hand(q2: f64, q3: f64, tool: Vector3<f64>) -> Vector3<f64> {
    let (a2, a3, d3, d4) = (431.8, 20.3, 150.05, 431.8);
    let (c2, s2) = (q2.cos(), q2.sin());
    let (c23, s23) = ((q2 + q3).cos(), (q2 + q3).sin());
    let wrist = Vector3::new(a2 * c2 + a3 * c23 - d4 * s23, -d3, a2 * s2 + a3 * s23 + d4 * c23);
    let rotated = Vector3::new(c23 * tool.x - s23 * tool.z, tool.y, s23 * tool.x + c23 * tool.z);
    wrist + rotated
}

#[test]
fn puma560_named_poses_match_the_closed_form() {
    let model = puma();
    let Tool::Point(tool) = model.tool else { panic!("the PUMA preset has a tool point") };
    let chain = Chain::new(&model).with_errors(&vec![0.0; model.params().len()]);
    let deg = f64::to_radians;
    for (name, q2, q3, expected) in [
        ("zero", 0.0, 0.0, Vector3::new(502.1, -150.05, 581.8)),
        ("ready", 90.0, -90.0, Vector3::new(70.3, -150.05, 1013.6)),
        ("stretched", 0.0, -90.0, Vector3::new(1013.6, -150.05, -70.3)),
    ] {
        let q = [0.0, deg(q2), deg(q3), 0.0, 0.0, 0.0];
        let by_hand = puma_by_hand(deg(q2), deg(q3), tool);
        assert!((by_hand - expected).amax() < 1e-9, "{name}: by hand {by_hand} vs {expected}");
        let fk = chain.position(&q);
        assert!((fk - by_hand).amax() < 1e-9, "{name}: fk {fk} vs by hand {by_hand}");
    }
}

#[test]
fn puma560_wrist_centre_matches_the_closed_form_everywhere() {
    let mut model = puma();
    model.tool = Tool::Point(Vector3::zeros());
    let chain = Chain::new(&model).with_errors(&vec![0.0; model.params().len()]);
    let (a2, a3, d3, d4) = (431.8, 20.3, 150.05, 431.8);
    for i in 0..200 {
        let q: Vec<f64> = (0..6).map(|k| ((i * 7 + k * 13) as f64 * 0.37).sin() * 3.0).collect();
        let (c1, s1) = (q[0].cos(), q[0].sin());
        let big_x = a2 * q[1].cos() + a3 * (q[1] + q[2]).cos() - d4 * (q[1] + q[2]).sin();
        let big_y = a2 * q[1].sin() + a3 * (q[1] + q[2]).sin() + d4 * (q[1] + q[2]).cos();
        let by_hand = Vector3::new(c1 * big_x + s1 * d3, s1 * big_x - c1 * d3, big_y);
        assert!((chain.position(&q) - by_hand).amax() < 1e-9);
    }
}

/// Joint values spread uniformly within the limits by a fixed hash, so the test needs no RNG.
fn spread_points(model: &RobotModel, n: usize) -> Vec<Vec<f64>> {
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

/// The paper's 30 joint parameters from position-only data have numerical rank 23 on the
/// PUMA 560 (column-scaled H, 50 random points). The 7 non-identifiable combinations are
/// structural, the same at any points, and are the ones documented in docs/identifiability.md.
#[test]
fn puma560_thirty_parameter_position_rank_is_23() {
    let model = puma();
    let chain = Chain::new(&model);
    let params = chain.params();
    let selection = Selection::joints(params);
    let points = spread_points(&model, 50);
    let at = chain.with_errors(&vec![0.0; params.len()]);
    let mut h = DMatrix::zeros(3 * points.len(), selection.len());
    for (k, q) in points.iter().enumerate() {
        at.identification_jacobian(q, &selection, Measured::Position, h.view_mut((3 * k, 0), (3, 30)));
    }
    let mut scaled = h.clone();
    for mut column in scaled.column_iter_mut() {
        column /= column.norm();
    }
    let mut sv: Vec<f64> = scaled.singular_values().iter().copied().collect();
    sv.sort_by(|a, b| b.total_cmp(a));
    assert!(sv[22] > 1e-2 && sv[23] < 1e-12 * sv[0], "singular values {sv:?}");

    let (a3, tool_x, tool_z) = (20.3, 50.0, 150.0);
    let null_combinations: [&[(&str, f64)]; 7] = [
        &[("j1.theta", -1.0), ("j1.beta", 1.0)],
        &[("j2.d", -1.0), ("j3.d", 1.0)],
        &[("j3.theta", -1.0 / a3), ("j3.beta", -1.0 / a3), ("j4.d", 1.0)],
        &[("j4.theta", -1.0), ("j4.beta", 1.0)],
        &[("j5.theta", 1.0), ("j5.beta", 1.0)],
        &[("j6.theta", tool_z / tool_x), ("j6.alpha", 1.0)],
        &[("j6.d", tool_x), ("j6.a", -tool_z), ("j6.beta", 1.0)],
    ];
    for combination in null_combinations {
        let mut v = nalgebra::DVector::zeros(30);
        for &(name, coefficient) in combination {
            v[selection.column(params.index_by_name(name).unwrap()).unwrap()] = coefficient;
        }
        let moved = (&h * &v).amax();
        assert!(moved < 1e-9, "{combination:?} moves the tool by {moved:e} mm");
    }
}

/// The gravity loads against central differences of the potential energy
/// `U(q) = -sum_j m_j g . c_j(q)` of the links and a payload, each centre of mass `c_j` from a
/// model cut after joint `j` with its tool at the centre of mass: a path through the forward
/// kinematics alone.
/// A mass of 0 to 20 kg on each of `dof` links, its centre within 200 mm of the joint's frame
/// on each axis, from the numbers `u` (in -1..1).
fn link_masses(dof: usize, u: &[f64]) -> Vec<robocal::model::LinkMass> {
    (0..dof)
        .map(|j| robocal::model::LinkMass {
            mass: 10.0 * (u[3 * j] + 1.0),
            com: Vector3::new(u[3 * j + 1], u[3 * j + 2], u[3 * j + 3]) * 200.0,
        })
        .collect()
}

fn check_gravity_torques(model: &RobotModel, u: &[f64]) -> Result<(), TestCaseError> {
    let mut model = model.clone();
    model.masses = link_masses(model.dof(), u);
    model.gravity = Vector3::new(u[30], u[31], u[32] - 1.5).normalize() * robocal::model::STANDARD_GRAVITY;
    let payload =
        robocal::model::Payload { mass: 3.0 * (u[33] + 1.0), com: Vector3::new(u[34], u[35], u[36]) * 100.0 };
    model.payload = Some(payload);
    let q: Vec<f64> = model
        .joints
        .iter()
        .zip(&u[40..])
        .map(|(j, u)| if j.kind == JointKind::Revolute { u * 3.0 } else { u * 200.0 })
        .collect();
    let chain = Chain::new(&model);
    let mut tau = vec![0.0; model.dof()];
    chain.with_errors(&vec![0.0; chain.params().len()]).gravity_torques(&q, &mut tau);

    let gravity = model.base.isometry().rotation * model.gravity;
    // The height of a point `com` (mm) in joint `j`'s frame, by a model cut after that joint.
    let weight = |j: usize, com: Vector3<f64>, mass: f64, q: &[f64]| {
        let cut = RobotModel {
            joints: model.joints[..=j].to_vec(),
            tool: Tool::Point(com),
            masses: Vec::new(),
            payload: None,
            ..model.clone()
        };
        let c = Chain::new(&cut);
        -mass * gravity.dot(&c.with_errors(&vec![0.0; c.params().len()]).position(&q[..=j]))
    };
    let last = model.dof() - 1;
    let potential = |q: &[f64]| -> f64 {
        (0..model.dof()).map(|j| weight(j, model.masses[j].com, model.masses[j].mass, q)).sum::<f64>()
            + weight(last, model.payload_com().unwrap(), payload.mass, q)
    };
    let scale = tau.iter().fold(1.0f64, |m, t| m.max(t.abs()));
    for (i, joint) in model.joints.iter().enumerate() {
        // A centre of mass is affine in a prismatic joint's value: a long step loses nothing,
        // and keeps the rounding of U (N·mm, up to 1e5) small. N·mm per rad is N·m / 1000.
        let (h, unit) = if joint.kind == JointKind::Revolute { (1e-5, 1000.0) } else { (1.0, 1.0) };
        let (mut plus, mut minus) = (q.clone(), q.clone());
        plus[i] += h;
        minus[i] -= h;
        let fd = -(potential(&plus) - potential(&minus)) / (2.0 * h) / unit;
        prop_assert!(
            (tau[i] - fd).abs() <= 1e-7 * scale,
            "joint {i} ({:?}): {} against {fd}",
            joint.kind,
            tau[i]
        );
    }
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(300))]

    #[test]
    fn gravity_torques_match_the_potential_energy_standard_dh(model in robot(Convention::StandardDh, true), u in prop::collection::vec(-1.0..1.0f64, 48)) {
        check_gravity_torques(&model, &u)?;
    }

    #[test]
    fn gravity_torques_match_the_potential_energy_modified_dh(model in robot(Convention::ModifiedDh, true), u in prop::collection::vec(-1.0..1.0f64, 48)) {
        check_gravity_torques(&model, &u)?;
    }

    #[test]
    fn gravity_torques_match_the_potential_energy_urdf(model in robot(Convention::Urdf, false), u in prop::collection::vec(-1.0..1.0f64, 48)) {
        check_gravity_torques(&model, &u)?;
    }
}

/// A chain put on a tree ([`Chain::on_tree`]) is the chain at the values it maps: its parameter
/// `i` the tree's `2 i + 1` (of twice as many, the others another branch's), its joint `j` the
/// tree's `2 j + 1`. Its pose is the chain's to the bit, and its identification and manipulator
/// Jacobians have the chain's columns at the mapped places and zero in the others; with masses,
/// a payload, compliances and plays (the gravity loads indexed by the tree's joints).
fn check_chain_on_tree(model: &RobotModel, u: &[f64]) -> Result<(), TestCaseError> {
    let mut model = model.clone();
    model.masses = link_masses(model.dof(), u);
    model.payload =
        Some(robocal::model::Payload { mass: 5.0 * (u[50] + 1.0), com: Vector3::new(u[51], 0.0, 50.0) });
    let (q, mut x) = point(&model, u);
    let chain = Chain::new(&model);
    let params = chain.params();
    for i in 0..params.len() {
        match params.get(i).unit() {
            "rad/N·m" => x[i] = 1e-4 * u[(i + 7) % u.len()],
            "mm/N" => x[i] = 1e-3 * u[(i + 7) % u.len()],
            _ => {}
        }
    }
    let (n, dof) = (params.len(), model.dof());
    let tree_params =
        robocal::model::ParamSet::from_params(params.iter().flat_map(|p| [p.clone(), p.clone()]).collect());
    let map: Vec<Option<usize>> = (0..n).map(|i| Some(2 * i + 1)).collect();
    let joints: Vec<usize> = (0..dof).map(|j| 2 * j + 1).collect();
    let on_tree = chain.on_tree(tree_params.clone(), &map, &joints, 2 * dof + 1);
    let mut tree_x = vec![0.0; 2 * n];
    let mut tree_q: Vec<f64> = (0..=2 * dof).map(|k| u[(k + 20) % u.len()]).collect();
    for i in 0..n {
        tree_x[2 * i + 1] = x[i];
    }
    for j in 0..dof {
        tree_q[2 * j + 1] = q[j];
    }
    let (at, tree_at) = (chain.with_errors(&x), on_tree.with_errors(&tree_x));
    prop_assert_eq!(at.pose(&q), tree_at.pose(&tree_q));
    let (all, tree_all) = (Selection::all(params), Selection::all(&tree_params));
    let mut h = DMatrix::zeros(6, n);
    at.identification_jacobian(&q, &all, Measured::Pose, h.as_view_mut());
    let mut tree_h = DMatrix::zeros(6, 2 * n);
    tree_at.identification_jacobian(&tree_q, &tree_all, Measured::Pose, tree_h.as_view_mut());
    for i in 0..n {
        prop_assert_eq!(h.column(i), tree_h.column(2 * i + 1), "parameter {}", params.get(i).name);
        prop_assert!(tree_h.column(2 * i).iter().all(|&v| v == 0.0));
    }
    let (mut j, mut tree_j) = (Matrix6xX::zeros(dof), Matrix6xX::zeros(2 * dof + 1));
    at.manipulator_jacobian(&q, &mut j);
    tree_at.manipulator_jacobian(&tree_q, &mut tree_j);
    for k in 0..=2 * dof {
        match k % 2 {
            1 => prop_assert_eq!(j.column(k / 2), tree_j.column(k)),
            _ => prop_assert!(tree_j.column(k).iter().all(|&v| v == 0.0)),
        }
    }
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(100))]

    #[test]
    fn a_chain_on_a_tree_is_the_chain_at_the_values_it_maps_urdf(model in robot(Convention::Urdf, false), u in prop::collection::vec(-1.0..1.0f64, 64)) {
        check_chain_on_tree(&model, &u)?;
    }

    #[test]
    fn a_chain_on_a_tree_is_the_chain_at_the_values_it_maps_standard_dh(model in robot(Convention::StandardDh, true), u in prop::collection::vec(-1.0..1.0f64, 64)) {
        check_chain_on_tree(&model, &u)?;
    }
}

/// One horizontal link of 1 kg, its centre of mass 1 m out along x from a joint turning about
/// y: gravity (-z) turns it about +y by 9.80665 N·m; vertical (q = -90 deg), by nothing; a
/// model without masses has no load.
#[test]
fn a_horizontal_link_of_one_kilogram_at_one_metre_weighs_9_81_newton_metres() {
    let joint = Joint::urdf("j1", JointKind::Revolute, Placement::default(), Vector3::y(), [-3.0, 3.0]);
    let mut model = RobotModel {
        name: "pendulum".into(),
        description: String::new(),
        convention: Convention::Urdf,
        base: Placement::default(),
        joints: vec![joint],
        tool: Tool::Point(Vector3::zeros()),
        masses: vec![robocal::model::LinkMass { mass: 1.0, com: Vector3::new(1000.0, 0.0, 0.0) }],
        gravity: RobotModel::floor_gravity(),
        payload: None,
    };
    let torque = |model: &RobotModel, q: f64| {
        let chain = Chain::new(model);
        let mut tau = [0.0];
        chain.with_errors(&vec![0.0; chain.params().len()]).gravity_torques(&[q], &mut tau);
        tau[0]
    };
    assert!((torque(&model, 0.0) - 9.80665).abs() < 1e-12);
    assert!(torque(&model, -std::f64::consts::FRAC_PI_2).abs() < 1e-12);
    model.masses.clear();
    assert_eq!(torque(&model, 0.0), 0.0);
}

/// With masses and a payload, each joint has a compliance and a play, and the payload a mass:
/// the joints reach `q + c tau(q) + p sgn(tau(q))`, `tau` including the payload's weight. Their
/// columns of `H` (pose and markers) against central differences of the full model, and the
/// pose against the rigid model at the deflected joint values.
fn check_load_responses(model: &RobotModel, u: &[f64]) -> Result<(), TestCaseError> {
    use robocal::model::ParamKind;
    let mut model = model.clone();
    model.masses = link_masses(model.dof(), u);
    model.payload = Some(robocal::model::Payload {
        mass: 5.0 * (u[50] + 1.0),
        com: Vector3::new(u[51], u[52], u[53]) * 100.0,
    });
    let (q, mut x) = point(&model, u);
    let chain = Chain::new(&model);
    let params = chain.params();
    let of_kind = |kind| (0..params.len()).filter(|&i| params.get(i).kind == kind).collect::<Vec<usize>>();
    let payload = of_kind(ParamKind::Mass);
    prop_assert_eq!(payload.len(), 1);
    let (compliances, plays) = (of_kind(ParamKind::Compliance), of_kind(ParamKind::Play));
    prop_assert_eq!(compliances.len(), model.dof());
    prop_assert_eq!(plays.len(), model.dof());
    for (k, (&c, &p)) in compliances.iter().zip(&plays).enumerate() {
        // about 1e-4 rad per N·m (1e-3 mm per N): millimetres at a metre under 10 N·m; a play
        // of up to 1e-3 rad (0.1 mm)
        let prismatic = params.get(c).unit() == "mm/N";
        x[c] = u[(k + 7) % u.len()] * if prismatic { 1e-3 } else { 1e-4 };
        x[p] = u[(k + 13) % u.len()] * if prismatic { 0.1 } else { 1e-3 };
    }
    let at = chain.with_errors(&x);

    // The pose is the rigid model's at q + c tau(q) + p sgn(tau(q)).
    let mut rigid_x = x.clone();
    compliances.iter().chain(&plays).for_each(|&i| rigid_x[i] = 0.0);
    let rigid = chain.with_errors(&rigid_x);
    let mut tau = vec![0.0; model.dof()];
    rigid.gravity_torques(&q, &mut tau);
    let reached: Vec<f64> = (0..model.dof())
        .map(|j| {
            q[j] + x[compliances[j]] * tau[j]
                + x[plays[j]] * if tau[j] == 0.0 { 0.0 } else { tau[j].signum() }
        })
        .collect();
    let miss = (at.pose(&q).translation.vector - rigid.pose(&reached).translation.vector).amax();
    prop_assert!(miss < 1e-9, "pose {miss:e}");

    let all = Selection::all(params);
    let mut h = DMatrix::zeros(6, all.len());
    at.identification_jacobian(&q, &all, Measured::Pose, h.view_mut((0, 0), (6, all.len())));
    let responses = compliances.iter().enumerate().chain(plays.iter().enumerate()).chain([(0, &payload[0])]);
    for (j, &i) in responses {
        // A step that moves the joint by 1e-6 (rad or mm) under its load: the pose is then
        // all but linear over it.
        let step = match params.get(i).kind {
            ParamKind::Play => 1e-6,
            // a kilogram moves a joint by c dtau/dm: about 1e-3 rad at most
            ParamKind::Mass => 1e-4,
            _ => 1e-6 / (1.0 + tau[j].abs()),
        };
        let (mut plus, mut minus) = (x.clone(), x.clone());
        plus[i] += step;
        minus[i] -= step;
        // The play's sign is a step where a load is zero: no derivative there.
        let signs = |x: &[f64]| {
            let mut tau = vec![0.0; model.dof()];
            chain.with_errors(x).gravity_torques(&q, &mut tau);
            tau.iter().map(|&t| if t == 0.0 { 0.0 } else { t.signum() }).collect::<Vec<f64>>()
        };
        if params.get(i).kind == ParamKind::Mass
            && (signs(&plus) != signs(&minus) || signs(&plus) != signs(&x))
        {
            continue;
        }
        let fd = pose_error(&chain.with_errors(&plus).pose(&q), &chain.with_errors(&minus).pose(&q))
            / (2.0 * step);
        // relative to the column, or absolute (mm or rad per unit of compliance) for a joint
        // that gravity barely loads here
        let scale = fd.amax().max(h.column(i).amax()).max(1.0);
        let err = (h.column(i) - fd).amax() / scale;
        prop_assert!(err < 1e-6, "{}: relative error {err:e}", params.get(i).name);
    }

    // The markers' shared walk gives the same load-response columns as each marker's chain.
    let markers = [Vector3::new(u[40], u[41], u[42]) * 100.0, Vector3::new(u[43], u[44], u[45]) * 100.0];
    let chains = Chain::markers(&model, &markers);
    let mx: Vec<f64> = chains[0]
        .params()
        .iter()
        .map(|p| x.get(params.index_by_name(&p.name).unwrap_or(usize::MAX)).copied().unwrap_or(0.0))
        .collect();
    let ats: Vec<_> = chains.iter().map(|c| c.with_errors(&mx)).collect();
    let every = Selection::all(chains[0].params());
    let mut shared = DMatrix::zeros(6, every.len());
    let mut positions = [Vector3::zeros(); 2];
    marker_jacobians(&ats, &q, &every, shared.view_mut((0, 0), (6, every.len())), &mut positions);
    for (m, at) in ats.iter().enumerate() {
        let mut own = DMatrix::zeros(3, every.len());
        at.identification_jacobian(&q, &every, Measured::Position, own.view_mut((0, 0), (3, every.len())));
        let err = relative_error(&shared.rows(3 * m, 3).into_owned(), &own);
        prop_assert!(err < 1e-9, "marker {m}: {err:e}");
        prop_assert!((positions[m] - at.position(&q)).amax() < 1e-9);
    }
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(350))]

    #[test]
    fn compliance_and_play_columns_match_finite_differences_standard_dh(model in robot(Convention::StandardDh, true), u in prop::collection::vec(-1.0..1.0f64, 64)) {
        check_load_responses(&model, &u)?;
    }

    #[test]
    fn compliance_and_play_columns_match_finite_differences_modified_dh(model in robot(Convention::ModifiedDh, true), u in prop::collection::vec(-1.0..1.0f64, 64)) {
        check_load_responses(&model, &u)?;
    }

    #[test]
    fn compliance_and_play_columns_match_finite_differences_urdf(model in robot(Convention::Urdf, false), u in prop::collection::vec(-1.0..1.0f64, 64)) {
        check_load_responses(&model, &u)?;
    }
}

/// The batched forward kinematics over prepared configurations (angle-sum identity, structure
/// of arrays, blocks of `BATCH` with a padded last block) against `ChainAt::pose` at each
/// configuration: positions to 1e-9 mm, orientations to 1e-12 rad; a chain whose joints deflect
/// goes the scalar way and agrees exactly.
fn check_batched_frames(model: &RobotModel, u: &[f64], deflecting: bool) -> Result<(), TestCaseError> {
    use robocal::kinematics::{BATCH, Configurations, Frames};
    let mut model = model.clone();
    if deflecting {
        model.masses = (0..model.dof())
            .map(|j| robocal::model::LinkMass { mass: 10.0, com: Vector3::new(u[j], 1.0, 0.5) * 100.0 })
            .collect();
        model.joints.iter_mut().for_each(|j| j.compliance = 1e-4);
    }
    let (_, x) = point(&model, u);
    let at = Chain::new(&model).with_errors(&x);
    prop_assert_eq!(at.deflects(), deflecting);
    let configurations: Vec<Vec<f64>> = (0..BATCH + 7).map(|i| point(&model, &u[i % 17..]).0).collect();
    let prepared = Configurations::new(&configurations, model.dof());
    prop_assert_eq!(prepared.blocks(), 2);
    prop_assert_eq!(prepared.block_len(1), 7);
    let mut frames = Frames::default();
    for b in 0..prepared.blocks() {
        at.frames(&prepared, b, &mut frames);
        for i in 0..prepared.block_len(b) {
            let pose = at.pose(&configurations[b * BATCH + i]);
            let (p, r) = (frames.position(i), frames.rotation(i));
            if deflecting {
                prop_assert_eq!(p, pose.translation.vector);
                prop_assert_eq!(r, pose.rotation);
            }
            prop_assert!((p - pose.translation.vector).norm() < 1e-9, "{p} {pose}");
            prop_assert!(r.angle_to(&pose.rotation) < 1e-12);
        }
    }
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(32))]
    #[test]
    fn batched_frames_match_the_pose_standard_dh(model in robot(Convention::StandardDh, true), u in prop::collection::vec(-1.0..1.0f64, 64), deflecting in any::<bool>()) {
        check_batched_frames(&model, &u, deflecting)?;
    }
    #[test]
    fn batched_frames_match_the_pose_modified_dh(model in robot(Convention::ModifiedDh, true), u in prop::collection::vec(-1.0..1.0f64, 64), deflecting in any::<bool>()) {
        check_batched_frames(&model, &u, deflecting)?;
    }
    #[test]
    fn batched_frames_match_the_pose_urdf(model in robot(Convention::Urdf, false), u in prop::collection::vec(-1.0..1.0f64, 64), deflecting in any::<bool>()) {
        check_batched_frames(&model, &u, deflecting)?;
    }
}
