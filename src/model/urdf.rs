//! Reading a serial chain from a URDF file (lengths in metres there, millimetres here).
//!
//! The chain runs from a named base link to a named tip link. Each revolute, continuous or
//! prismatic joint on it becomes a [`Joint`] of the `urdf` convention: its origin (xyz, rpy)
//! and axis. Fixed joints are folded into the origin of the next moving joint, or into the tool
//! after the last one (the tool is then the tip link's frame). Continuous joints get limits of
//! plus or minus one turn. A joint on the chain that mimics another (`<mimic>`) and a link on
//! it with two parent joints are refused: robocal calibrates serial chains of independent
//! joints. Lengths are bounded by [`MAX_LENGTH_MM`], angles by [`MAX_ANGLE_DEG`].
//! Each moving joint carries its child link's `<inertial>` mass and those of the links fixed
//! to it (a flange, a tool, a gripper), as one body.

use super::{Convention, Joint, JointKind, LinkMass, ModelError, Placement, RobotModel, Tool};
use crate::error::FieldError;
use crate::limits::{MAX_ANGLE_DEG, MAX_COMPLIANCE, MAX_LENGTH_MM, MAX_MASS_KG, MAX_PLAY, check_range};
use nalgebra::{Isometry3, Vector3};

fn invalid(field: String, expected: impl Into<String>) -> ModelError {
    FieldError::new(field, expected).into()
}

/// The XML of a URDF file, refused if two links or two joints share a name (the error names
/// it and its lines): which one a chain would take is anybody's guess.
fn document(text: &str) -> Result<roxmltree::Document<'_>, ModelError> {
    let document = roxmltree::Document::parse(text).map_err(ModelError::Xml)?;
    for tag in ["link", "joint"] {
        let mut seen = std::collections::HashMap::new();
        let named = document.root_element().children().filter(|n| n.has_tag_name(tag));
        for node in named {
            let Some(name) = node.attribute("name") else { continue };
            let line = document.text_pos_at(node.range().start).row;
            if let Some(first) = seen.insert(name, line) {
                let expected = format!("one {tag} of each name, found this one on lines {first} and {line}");
                return Err(invalid(format!("<{tag} name=\"{name}\">"), expected));
            }
        }
    }
    Ok(document)
}

/// The numbers of an attribute such as `xyz="0 0 0.1"`.
fn numbers<const N: usize>(
    node: roxmltree::Node<'_, '_>,
    attribute: &str,
    default: [f64; N],
    field: &str,
) -> Result<[f64; N], ModelError> {
    let Some(text) = node.attribute(attribute) else { return Ok(default) };
    let values: Vec<f64> = text
        .split_whitespace()
        .map(str::parse)
        .collect::<Result<_, _>>()
        .map_err(|_| invalid(format!("{field}.{attribute}"), format!("{N} numbers, found `{text}`")))?;
    let values: [f64; N] = values
        .try_into()
        .map_err(|_| invalid(format!("{field}.{attribute}"), format!("{N} numbers, found `{text}`")))?;
    if values.iter().any(|v| !v.is_finite()) {
        return Err(invalid(format!("{field}.{attribute}"), "finite numbers"));
    }
    // Metres (xyz) or radians (rpy); an axis is normalised.
    let bound = if attribute == "rpy" { MAX_ANGLE_DEG.to_radians() } else { MAX_LENGTH_MM / 1000.0 };
    if let Some(v) = values.iter().find(|v| v.abs() > bound) {
        return Err(invalid(
            format!("{field}.{attribute}"),
            format!("magnitudes at most {bound:e}, found {v}"),
        ));
    }
    Ok(values)
}

/// The joint's `<origin>` as an isometry (mm).
fn origin(joint: roxmltree::Node<'_, '_>, field: &str) -> Result<Isometry3<f64>, ModelError> {
    let Some(node) = joint.children().find(|c| c.has_tag_name("origin")) else {
        return Ok(Isometry3::identity());
    };
    let xyz = numbers(node, "xyz", [0.0; 3], &format!("{field}.origin"))?;
    let rpy = numbers(node, "rpy", [0.0; 3], &format!("{field}.origin"))?;
    Ok(Placement { xyz: Vector3::from(xyz) * 1000.0, rpy: Vector3::from(rpy) }.isometry())
}

/// The link a joint's `<parent>` or `<child>` names.
fn link_of(joint: &roxmltree::Node<'_, '_>, tag: &str) -> String {
    joint
        .children()
        .find(|c| c.has_tag_name(tag))
        .and_then(|c| c.attribute("link"))
        .unwrap_or_default()
        .to_string()
}

/// The joints from `base_link` to `tip_link`, base first, found by walking up from the tip.
fn chain<'a, 'input>(
    robot: roxmltree::Node<'a, 'input>,
    base_link: &str,
    tip_link: &str,
) -> Result<Vec<roxmltree::Node<'a, 'input>>, ModelError> {
    let joints: Vec<roxmltree::Node<'a, 'input>> =
        robot.children().filter(|n| n.has_tag_name("joint")).collect();
    let mut parents: std::collections::HashMap<String, Vec<roxmltree::Node<'a, 'input>>> =
        std::collections::HashMap::new();
    for joint in &joints {
        parents.entry(link_of(joint, "child")).or_default().push(*joint);
    }
    let mut chain = Vec::new();
    let mut link = tip_link.to_string();
    while link != base_link {
        let Some(joint) = parents.get(&link).and_then(|p| p.first()) else {
            return Err(invalid(
                "tip link".into(),
                format!(
                    "a chain of joints from `{base_link}` to `{tip_link}`, but link `{link}` has no parent joint"
                ),
            ));
        };
        if let [first, second, ..] = parents[&link][..] {
            let name = |j: roxmltree::Node<'_, '_>| j.attribute("name").unwrap_or_default().to_string();
            return Err(invalid(
                format!("link `{link}`"),
                format!(
                    "one parent joint (a URDF is a tree), found `{}` and `{}`: not supported",
                    name(first),
                    name(second)
                ),
            ));
        }
        if let Some(mimic) = joint.children().find(|c| c.has_tag_name("mimic")) {
            let name = joint.attribute("name").unwrap_or_default();
            let leader = mimic.attribute("joint").unwrap_or_default();
            return Err(invalid(
                format!("joint `{name}`.mimic"),
                format!(
                    "a joint of its own: it mimics `{leader}`, and a chain with coupled joints is not supported; \
                     give a chain without mimic joints"
                ),
            ));
        }
        if chain.len() > joints.len() {
            return Err(invalid("joints".into(), "a tree: the parent links form a loop"));
        }
        chain.push(*joint);
        link = link_of(joint, "parent");
    }
    chain.reverse();
    Ok(chain)
}

/// The links a chain of `text` runs between: `base_link` and `tip_link` where given, else the
/// root link (the one link that is no joint's child) and the only leaf (the one link that is no
/// joint's parent); an error lists the candidates when there are several.
pub fn chain_links(
    text: &str,
    base_link: Option<&str>,
    tip_link: Option<&str>,
) -> Result<(String, String), ModelError> {
    let (roots, leaves) = ends(text)?;
    let pick = |given: Option<&str>, candidates: &[String], field: &str, role: &str, flag: &str| {
        if let Some(given) = given {
            return Ok(given.to_string());
        }
        match candidates {
            [one] => Ok(one.clone()),
            _ => {
                let names: Vec<&str> = candidates.iter().map(String::as_str).collect();
                Err(invalid(field.into(), format!("a single {role}, found {}: give {flag}", list(&names))))
            }
        }
    };
    let base = pick(base_link, &roots, "base link", "root link to start the chain at", "--base-link")?;
    let tip = pick(tip_link, &leaves, "tip link", "leaf link to end the chain at", "--tip-link")?;
    Ok((base, tip))
}

/// The root links of `text` (no joint's child) and its leaf links (no joint's parent), in the
/// file's order.
pub(super) fn ends(text: &str) -> Result<(Vec<String>, Vec<String>), ModelError> {
    let document = document(text)?;
    let robot = document.root_element();
    let joints: Vec<_> = robot.children().filter(|n| n.has_tag_name("joint")).collect();
    let links: Vec<&str> =
        robot.children().filter(|n| n.has_tag_name("link")).filter_map(|n| n.attribute("name")).collect();
    // the links that are no joint's `tag` (child: roots; parent: leaves)
    let no = |tag: &str| -> Vec<String> {
        (links.iter())
            .filter(|l| !joints.iter().any(|j| link_of(j, tag) == **l))
            .map(|l| l.to_string())
            .collect()
    };
    Ok((no("child"), no("parent")))
}

/// The names of the links of `text`, in the file's order.
pub(super) fn link_names(text: &str) -> Result<Vec<String>, ModelError> {
    let document = document(text)?;
    let robot = document.root_element();
    let links = robot.children().filter(|n| n.has_tag_name("link")).filter_map(|n| n.attribute("name"));
    Ok(links.map(str::to_string).collect())
}

/// Whether a joint on the chain of `text` from `base_link` to `tip_link` moves (is not fixed).
pub(super) fn chain_moves(text: &str, base_link: &str, tip_link: &str) -> Result<bool, ModelError> {
    let document = document(text)?;
    let chain = chain(document.root_element(), base_link, tip_link)?;
    Ok(chain.iter().any(|j| j.attribute("type") != Some("fixed")))
}

/// `a, b, c` in backticks, or `none`.
fn list(names: &[&str]) -> String {
    if names.is_empty() {
        "none".into()
    } else {
        names.iter().map(|n| format!("`{n}`")).collect::<Vec<_>>().join(", ")
    }
}

/// The chain of `text` from `base_link` to `tip_link`: its moving joints (fixed joints folded
/// into the next one's origin, or into the tool after the last), their carried masses and the
/// base link's gravity, checked as a TOML model's.
pub fn from_urdf_str(text: &str, base_link: &str, tip_link: &str) -> Result<RobotModel, ModelError> {
    let document = document(text)?;
    let robot = document.root_element();
    check_root(robot, base_link)?;
    let chain = chain(robot, base_link, tip_link)?;
    let MovingJoints { joints: model_joints, masses, tool } = moving_joints(robot, chain)?;
    if model_joints.is_empty() {
        return Err(invalid(
            "joints".into(),
            format!("at least one moving joint between `{base_link}` and `{tip_link}`"),
        ));
    }
    let gravity = gravity(robot, base_link)?;
    let model = RobotModel {
        name: robot.attribute("name").unwrap_or("urdf").to_string(),
        description: format!("URDF chain from `{base_link}` to `{tip_link}`"),
        convention: Convention::Urdf,
        base: Placement::default(),
        joints: model_joints,
        tool: Tool::Frame(Placement::from_isometry(&tool)),
        // all masses, or none when no link on the chain declares one
        masses: if masses.iter().any(|m: &LinkMass| m.mass > 0.0) { masses } else { Vec::new() },
        gravity,
        payload: None,
    };
    // The names and limits pass the same checks as a TOML model's.
    super::RobotModel::from_toml_str(&model.to_toml_string())
}

/// The root element is `<robot>` and it has a link named `base_link`.
fn check_root(robot: roxmltree::Node<'_, '_>, base_link: &str) -> Result<(), ModelError> {
    if !robot.has_tag_name("robot") {
        let found = robot.tag_name().name();
        return Err(invalid("root element".into(), format!("<robot> in a URDF file, found <{found}>")));
    }
    if !robot.children().any(|n| n.has_tag_name("link") && n.attribute("name") == Some(base_link)) {
        return Err(invalid("base link".into(), format!("a link named `{base_link}` in the file")));
    }
    Ok(())
}

/// What a chain's joints make of a model: its moving joints, the mass each carries, and the
/// tool.
struct MovingJoints {
    /// The moving joints, base first.
    joints: Vec<Joint>,
    /// The mass each moving joint carries ([`carried_mass`]).
    masses: Vec<LinkMass>,
    /// The tool: the fixed joints after the last moving one, in its frame (mm).
    tool: Isometry3<f64>,
}

/// The moving joints of `chain` (base first) as model joints, the mass each carries
/// ([`carried_mass`]), and the tool: the fixed joints after the last moving one. A fixed
/// joint's origin `F` is folded into the next moving joint's, `origin = F * origin`.
fn moving_joints(
    robot: roxmltree::Node<'_, '_>,
    chain: Vec<roxmltree::Node<'_, '_>>,
) -> Result<MovingJoints, ModelError> {
    let mut model_joints = Vec::new();
    let mut masses = Vec::new();
    let mut pending = Isometry3::identity();
    for joint in chain {
        let name = joint.attribute("name").unwrap_or_default();
        let field = format!("joint `{name}`");
        let here = pending * origin(joint, &field)?;
        let Some(kind) = joint_kind(joint, &field)? else {
            pending = here;
            continue;
        };
        pending = Isometry3::identity();
        model_joints.push(model_joint(joint, &field, kind, &here)?);
        masses.push(carried_mass(robot, &link_of(&joint, "child"))?);
    }
    Ok(MovingJoints { joints: model_joints, masses, tool: pending })
}

/// A joint's `type`: revolute (`revolute` or `continuous`), prismatic, or `None` for a fixed
/// joint; any other type is refused.
fn joint_kind(joint: roxmltree::Node<'_, '_>, field: &str) -> Result<Option<JointKind>, ModelError> {
    match joint.attribute("type").unwrap_or_default() {
        "fixed" => Ok(None),
        "revolute" | "continuous" => Ok(Some(JointKind::Revolute)),
        "prismatic" => Ok(Some(JointKind::Prismatic)),
        other => Err(invalid(
            format!("{field}.type"),
            format!("revolute, continuous, prismatic or fixed, found `{other}`"),
        )),
    }
}

/// The model joint of a moving URDF joint of `kind` at origin `here` (mm): its axis, limits
/// and [`DEFLECTION`], if any.
fn model_joint(
    joint: roxmltree::Node<'_, '_>,
    field: &str,
    kind: JointKind,
    here: &Isometry3<f64>,
) -> Result<Joint, ModelError> {
    let name = joint.attribute("name").unwrap_or_default();
    let axis = axis(joint, field)?;
    let limits = limits(joint, field, kind)?;
    let mut model_joint = Joint::urdf(name, kind, Placement::from_isometry(here), axis.normalize(), limits);
    if let Some(node) = joint.children().find(|c| c.has_tag_name(DEFLECTION)) {
        let (compliance, play) = deflection(node, field, kind)?;
        model_joint.compliance = compliance;
        model_joint.play = play;
    }
    Ok(model_joint)
}

/// A joint's `<axis xyz>` (default x), not normalised; a zero axis is refused.
fn axis(joint: roxmltree::Node<'_, '_>, field: &str) -> Result<Vector3<f64>, ModelError> {
    let axis_node = joint.children().find(|c| c.has_tag_name("axis"));
    let axis = Vector3::from(match axis_node {
        Some(node) => numbers(node, "xyz", [1.0, 0.0, 0.0], &format!("{field}.axis"))?,
        None => [1.0, 0.0, 0.0],
    });
    if axis.norm() < 1e-9 {
        return Err(invalid(format!("{field}.axis"), "a non-zero axis"));
    }
    Ok(axis)
}

/// A joint's `[lower, upper]` limits (rad, or mm for a prismatic joint, from metres): plus or
/// minus one turn for a continuous joint, else the `<limit>`'s, with `lower < upper`.
fn limits(joint: roxmltree::Node<'_, '_>, field: &str, kind: JointKind) -> Result<[f64; 2], ModelError> {
    let continuous = joint.attribute("type") == Some("continuous");
    let limit = joint.children().find(|c| c.has_tag_name("limit"));
    let bound = |attribute: &str| -> Result<Option<f64>, ModelError> {
        let Some(text) = limit.and_then(|l| l.attribute(attribute)) else { return Ok(None) };
        let v: f64 = text.parse().map_err(|_| {
            invalid(format!("{field}.limit.{attribute}"), format!("a number, found `{text}`"))
        })?;
        Ok(Some(if kind == JointKind::Prismatic { v * 1000.0 } else { v }))
    };
    match (continuous, bound("lower")?, bound("upper")?) {
        (true, _, _) => Ok([-std::f64::consts::TAU, std::f64::consts::TAU]),
        (false, Some(lower), Some(upper)) if lower < upper => Ok([lower, upper]),
        _ => Err(invalid(format!("{field}.limit"), "lower < upper limits for a revolute or prismatic joint")),
    }
}

/// A joint's compliance and play from its [`DEFLECTION`] element `node` (SI as URDF:
/// rad/(N·m) and rad, or m/N and m for a prismatic joint, within [`MAX_COMPLIANCE`] and
/// [`MAX_PLAY`]), in the model's units (a prismatic joint's times 1000: mm/N and mm).
fn deflection(node: roxmltree::Node<'_, '_>, field: &str, kind: JointKind) -> Result<(f64, f64), ModelError> {
    let per_mm = if kind == JointKind::Prismatic { 1000.0 } else { 1.0 };
    let at = format!("{field}.{DEFLECTION}");
    let revolute = kind == JointKind::Revolute;
    let (compliance_unit, play_unit) = if revolute { ("rad/(N·m)", "rad") } else { ("m/N", "m") };
    let compliance = numbers(node, "compliance", [0.0], &at)?[0];
    let max_compliance = if revolute { MAX_COMPLIANCE } else { MAX_COMPLIANCE / 1000.0 };
    check_range(compliance, -max_compliance, max_compliance, compliance_unit)
        .map_err(|e| invalid(format!("{at}.compliance"), e))?;
    let play = numbers(node, "play", [0.0], &at)?[0];
    let max_play = if revolute { MAX_PLAY.to_radians() } else { MAX_PLAY / 1000.0 };
    check_range(play, -max_play, max_play, play_unit).map_err(|e| invalid(format!("{at}.play"), e))?;
    Ok((compliance * per_mm, play * per_mm))
}

/// The gravity of the link `base_link`'s [`GRAVITY`] element (m/s², default `-z`
/// [`STANDARD_GRAVITY`](super::STANDARD_GRAVITY)); without one, [`RobotModel::floor_gravity`].
fn gravity(robot: roxmltree::Node<'_, '_>, base_link: &str) -> Result<Vector3<f64>, ModelError> {
    let base_node =
        robot.children().find(|n| n.has_tag_name("link") && n.attribute("name") == Some(base_link));
    Ok(match base_node.and_then(|n| n.children().find(|c| c.has_tag_name(GRAVITY))) {
        Some(node) => Vector3::from(numbers(
            node,
            "xyz",
            [0.0, 0.0, -super::STANDARD_GRAVITY],
            &format!("link `{base_link}`.{GRAVITY}"),
        )?),
        None => RobotModel::floor_gravity(),
    })
}

/// robocal's extension element of a URDF link: gravity (m/s²) in the link's frame,
/// `<robocal_gravity xyz="0 0 -9.80665"/>`. A chain read from that link takes it as the model's
/// gravity (default: -z of the chain's first link, as ROS has it). `to_urdf_string` writes it in
/// the `measuring_frame` link, whose frame is not the robot's.
pub const GRAVITY: &str = "robocal_gravity";

/// robocal's extension element of a URDF joint, which URDF has no field for: the joint's
/// compliance and play (see [`crate::model::Joint`]) in SI units as the rest of the file,
/// `<robocal_deflection compliance="4e-05" play="0.0005"/>` (rad/(N·m) and rad for a revolute
/// joint, m/N and m for a prismatic one). URDF readers ignore elements they do not know.
pub const DEFLECTION: &str = "robocal_deflection";

/// `original` (the URDF the model was read from, chain `base_link` to `tip_link`) with the
/// origins of its moving joints replaced by `calibrated`'s (a URDF model carries its offsets
/// in its origins, as URDF has no offset field), and their compliance and play in a
/// [`DEFLECTION`] element where either is not zero. The calibrated base
/// becomes a fixed joint from a new link `measuring_frame`, and the tool (in the last moving
/// joint's frame, as markers are) a fixed joint to a new link `tool` on that joint's child
/// link. Everything else is kept as written.
pub fn to_urdf_string(
    original: &str,
    base_link: &str,
    tip_link: &str,
    calibrated: &RobotModel,
) -> Result<String, ModelError> {
    let document = document(original)?;
    let robot = document.root_element();
    let chain = chain(robot, base_link, tip_link)?;
    let mut edits: Vec<(std::ops::Range<usize>, String)> =
        earlier_export(robot, &chain, [base_link, tip_link])?
            .into_iter()
            .map(|r| (r, String::new()))
            .collect();
    let mut fixed_before = Isometry3::identity();
    let mut moving = calibrated.joints.iter();
    let mut last_moving_link = base_link.to_string();
    for joint in chain {
        if joint.attribute("type") == Some("fixed") {
            fixed_before *= origin(joint, "joint")?;
            continue;
        }
        let j = moving.next().ok_or_else(|| invalid("joints".into(), "the model read from this URDF"))?;
        edits.extend(joint_edits(joint, &fixed_before, j));
        fixed_before = Isometry3::identity();
        last_moving_link = link_of(&joint, "child");
    }
    let tool = match &calibrated.tool {
        Tool::Point(p) => Isometry3::translation(p.x, p.y, p.z),
        Tool::Frame(f) => f.isometry(),
    };
    // Gravity in the measuring frame, which the chain read back starts from: the robot's
    // gravity turned by the calibrated base.
    let g = calibrated.base.isometry().rotation * calibrated.gravity;
    let extra = format!(
        "  <link name=\"measuring_frame\">\n    <{GRAVITY} xyz=\"{:?} {:?} {:?}\"/>\n  </link>\n  <joint name=\"measuring_frame_to_{base_link}\" type=\"fixed\">\n    <parent link=\"measuring_frame\"/>\n    <child link=\"{base_link}\"/>\n    {}\n  </joint>\n  <link name=\"tool\"/>\n  <joint name=\"{last_moving_link}_to_tool\" type=\"fixed\">\n    <parent link=\"{last_moving_link}\"/>\n    <child link=\"tool\"/>\n    {}\n  </joint>\n",
        g.x,
        g.y,
        g.z,
        origin_element(&calibrated.base.isometry()),
        origin_element(&tool)
    );
    let end = robot.range().end - "</robot>".len();
    edits.push((end..end, extra));
    edits.sort_by_key(|(range, _)| std::cmp::Reverse(range.start));
    let mut out = original.to_string();
    for (range, text) in edits {
        out.replace_range(range, &text);
    }
    Ok(out)
}

/// The edits that write the calibrated joint `j` into the URDF element `joint` (a moving
/// joint): its origin, `fixed_before^-1 X_j` (`X_j` the model's origin, which holds the fixed
/// joints `fixed_before` between the last moving joint and this one, as the URDF is read), and
/// its compliance and play in a [`DEFLECTION`] element where either is not zero (an earlier
/// one removed).
fn joint_edits(
    joint: roxmltree::Node<'_, '_>,
    fixed_before: &Isometry3<f64>,
    j: &Joint,
) -> Vec<(std::ops::Range<usize>, String)> {
    let mut edits = Vec::new();
    let mut element = origin_element(&(fixed_before.inverse() * j.origin.isometry()));
    if let Some(old) = joint.children().find(|c| c.has_tag_name(DEFLECTION)) {
        edits.push((old.range(), String::new()));
    }
    if j.compliance != 0.0 || j.play != 0.0 {
        let per_m = if j.kind == JointKind::Prismatic { 1e-3 } else { 1.0 };
        element += &format!(
            "\n    <{DEFLECTION} compliance=\"{:?}\" play=\"{:?}\"/>",
            j.compliance * per_m,
            j.play * per_m
        );
    }
    match joint.children().find(|c| c.has_tag_name("origin")) {
        Some(node) => edits.push((node.range(), element)),
        None => {
            let at = joint.children().next().map_or(joint.range().end, |c| c.range().start);
            edits.push((at..at, element));
        }
    }
    edits
}

/// `original` (the URDF `tree` was read from) with the origins of the tree's moving joints
/// replaced by `tree`'s (a calibrated tree, its joints' errors folded in), each once however
/// many branches share it, as [`to_urdf_string`] writes a chain's. Everything
/// else is kept as written: the tree's placement in its root link, which views never see, and
/// its cameras' and targets' placements, which are a calibration's set-up, not links of the
/// robot.
pub fn tree_to_urdf_string(original: &str, tree: &super::RobotTree) -> Result<String, ModelError> {
    let document = document(original)?;
    let robot = document.root_element();
    let mut edits: Vec<(std::ops::Range<usize>, String)> = Vec::new();
    let mut written: Vec<usize> = Vec::new();
    for branch in &tree.branches {
        let mut fixed_before = Isometry3::identity();
        let mut moving = branch.joints.iter().map(|&j| &tree.joints[j]);
        for joint in chain(robot, &tree.root, &branch.tip)? {
            if joint.attribute("type") == Some("fixed") {
                fixed_before *= origin(joint, "joint")?;
                continue;
            }
            let j = moving.next().ok_or_else(|| invalid("joints".into(), "the tree read from this URDF"))?;
            if !written.contains(&joint.range().start) {
                written.push(joint.range().start);
                edits.extend(joint_edits(joint, &fixed_before, j));
            }
            fixed_before = Isometry3::identity();
        }
    }
    edits.sort_by_key(|(range, _)| std::cmp::Reverse(range.start));
    let mut out = original.to_string();
    for (range, text) in edits {
        out.replace_range(range, &text);
    }
    Ok(out)
}

/// The elements of an earlier export in `robot` (a URDF that [`to_urdf_string`] and
/// [`with_urdf_markers`] wrote): the links `measuring_frame`, `tool` and `marker_<k>` and the
/// fixed joints that hang them on, which this export writes anew (twice, they would be two
/// links of one name). A `chain` from `ends[0]` to `ends[1]` through one of them is refused:
/// its placement would be written on top of itself.
fn earlier_export(
    robot: roxmltree::Node<'_, '_>,
    chain: &[roxmltree::Node<'_, '_>],
    ends: [&str; 2],
) -> Result<Vec<std::ops::Range<usize>>, ModelError> {
    let ours = |name: &str| {
        name == "measuring_frame"
            || name == "tool"
            || name.strip_prefix("marker_").is_some_and(|k| k.parse::<usize>().is_ok())
    };
    let links = chain.iter().flat_map(|j| [link_of(j, "parent"), link_of(j, "child")]);
    if let Some(link) = links.chain(ends.map(str::to_string)).find(|l| ours(l)) {
        let expected = format!(
            "links of the robot itself, not `{link}`, which every calibrated URDF gets anew: the original \
             robot's (--base-link, --tip-link)"
        );
        return Err(invalid("chain".into(), expected));
    }
    let earlier = robot.children().filter(|n| match n.tag_name().name() {
        "link" => n.attribute("name").is_some_and(ours),
        "joint" => ours(&link_of(n, "parent")) || ours(&link_of(n, "child")),
        _ => false,
    });
    Ok(earlier.map(|n| n.range()).collect())
}

/// The mass a joint whose child is `link` moves: `link`'s `<inertial>` and those of every link
/// fixed to it (through fixed joints, down the tree: a flange, a tool, a gripper), as one body
/// with its centre of mass in `link`'s frame (mm). Links behind a moving joint are not carried.
fn carried_mass(robot: roxmltree::Node<'_, '_>, link: &str) -> Result<LinkMass, ModelError> {
    let (mut mass, mut moment) = (0.0, Vector3::zeros());
    let mut stack = vec![(link.to_string(), Isometry3::identity())];
    let links = robot.children().filter(|n| n.has_tag_name("link")).count();
    let mut visited = 0;
    while let Some((name, placed)) = stack.pop() {
        visited += 1;
        if visited > links + 1 {
            return Err(invalid("joints".into(), "a tree: the fixed joints form a loop"));
        }
        let node = robot.children().find(|n| n.has_tag_name("link") && n.attribute("name") == Some(&name));
        if let Some(inertial) = node.and_then(|n| n.children().find(|c| c.has_tag_name("inertial"))) {
            let field = format!("link `{name}`.inertial");
            let m = match inertial.children().find(|c| c.has_tag_name("mass")) {
                Some(node) => numbers(node, "value", [0.0], &format!("{field}.mass"))?[0],
                None => 0.0,
            };
            check_range(m, 0.0, MAX_MASS_KG, "kg").map_err(|e| invalid(format!("{field}.mass.value"), e))?;
            let com = origin(inertial, &field)?.translation.vector;
            mass += m;
            moment += (placed * nalgebra::Point3::from(com)).coords * m;
        }
        for joint in robot.children().filter(|n| n.has_tag_name("joint")) {
            if joint.attribute("type") == Some("fixed") && link_of(&joint, "parent") == name {
                let field = format!("joint `{}`", joint.attribute("name").unwrap_or_default());
                stack.push((link_of(&joint, "child"), placed * origin(joint, &field)?));
            }
        }
    }
    let com = if mass > 0.0 { moment / mass } else { Vector3::zeros() };
    Ok(LinkMass { mass, com })
}

/// `<origin xyz=".." rpy=".."/>` in metres and radians, at full precision.
pub(super) fn origin_element(iso: &Isometry3<f64>) -> String {
    let p = Placement::from_isometry(iso);
    let t = p.xyz / 1000.0;
    format!(
        "<origin xyz=\"{:?} {:?} {:?}\" rpy=\"{:?} {:?} {:?}\"/>",
        t.x, t.y, t.z, p.rpy.x, p.rpy.y, p.rpy.z
    )
}

/// A URDF written by [`to_urdf_string`] with a link `marker_<id>` for each of `markers`
/// (numbers and positions, mm, in the last moving joint's frame), fixed to the link that
/// carries `tool`.
pub fn with_urdf_markers(urdf: &str, markers: &[(usize, Vector3<f64>)]) -> Result<String, ModelError> {
    let document = document(urdf)?;
    let robot = document.root_element();
    let parent = tool_parent(robot)?;
    let mut extra = String::new();
    for (id, p) in markers {
        extra += &format!(
            "  <link name=\"marker_{id}\"/>\n  <joint name=\"{parent}_to_marker_{id}\" type=\"fixed\">\n    <parent link=\"{parent}\"/>\n    <child link=\"marker_{id}\"/>\n    {}\n  </joint>\n",
            origin_element(&Isometry3::translation(p.x, p.y, p.z))
        );
    }
    let end = robot.range().end - "</robot>".len();
    let mut out = urdf.to_string();
    out.insert_str(end, &extra);
    Ok(out)
}

/// The link that carries the `tool` link.
fn tool_parent(robot: roxmltree::Node<'_, '_>) -> Result<String, ModelError> {
    robot
        .children()
        .filter(|n| n.has_tag_name("joint"))
        .find(|j| link_of(j, "child") == "tool")
        .map(|j| link_of(&j, "parent"))
        .ok_or_else(|| invalid("tool".into(), "a link `tool` fixed to the last link, as calibrate writes"))
}

/// The markers of a URDF written by `calibrate --out-urdf`: each link `marker_<id>` fixed to
/// the link that carries `tool`, its position in mm (empty if there are none).
pub fn markers_from_urdf_str(text: &str) -> Result<Vec<(usize, Vector3<f64>)>, ModelError> {
    let document = document(text)?;
    let robot = document.root_element();
    let Ok(parent) = tool_parent(robot) else { return Ok(Vec::new()) };
    let mut out = Vec::new();
    for joint in robot.children().filter(|n| n.has_tag_name("joint")) {
        let child = link_of(&joint, "child");
        let Some(id) = child.strip_prefix("marker_").and_then(|n| n.parse::<usize>().ok()) else { continue };
        if link_of(&joint, "parent") != parent {
            continue;
        }
        out.push((id, origin(joint, &format!("joint to `{child}`"))?.translation.vector));
    }
    out.sort_by_key(|m| m.0);
    Ok(out)
}
