//! Any model written as a URDF of its own (DH, MDH, Hayati, URDF origins alike), for MoveIt and
//! ROS: each joint's origin as xyz/rpy in its parent link, the base as the root link's first
//! joint's placement, the tool as a fixed joint to a link `tool0`.
//!
//! Each joint's transform is factored as `T_i(q) = P_i M_i(q) S_i`, `M_i` the motion about or
//! along the joint's axis: standard DH `P = Rz(theta) Tz(d)`, `S = Tx(a) Rx(alpha) Ry(beta)`;
//! modified DH `P = Rx(alpha) Tx(a) Ry(beta) Rz(theta) Tz(d)`, `S = I`; URDF `P` = the origin,
//! `S = I`, the axis its own. URDF joint `i` is then placed at `S_{i-1} P_i` (`S_0` the base),
//! link `i` is the frame after `M_i`, and the tool's fixed joint is at `S_n tool`.

use super::urdf::{DEFLECTION, GRAVITY, origin_element};
use super::{Convention, Joint, JointKind, RobotModel, Tool};
use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion, Vector3};
use std::fmt::Write;

/// `(P, axis, S)` of `joint` under `convention`; see the [module documentation](self).
pub(crate) fn factors(
    joint: &Joint,
    convention: Convention,
) -> (Isometry3<f64>, Vector3<f64>, Isometry3<f64>) {
    let rx = |a: f64| UnitQuaternion::from_axis_angle(&Vector3::x_axis(), a);
    let ry = |a: f64| UnitQuaternion::from_axis_angle(&Vector3::y_axis(), a);
    let rz = |a: f64| UnitQuaternion::from_axis_angle(&Vector3::z_axis(), a);
    let rot = |r: UnitQuaternion<f64>| Isometry3::from_parts(Translation3::identity(), r);
    let tr = |x: f64, y: f64, z: f64| Isometry3::translation(x, y, z);
    match convention {
        Convention::StandardDh => (
            rot(rz(joint.theta)) * tr(0.0, 0.0, joint.d),
            Vector3::z(),
            tr(joint.a, 0.0, 0.0) * rot(rx(joint.alpha)) * rot(ry(joint.beta)),
        ),
        Convention::ModifiedDh => (
            rot(rx(joint.alpha))
                * tr(joint.a, 0.0, 0.0)
                * rot(ry(joint.beta))
                * rot(rz(joint.theta))
                * tr(0.0, 0.0, joint.d),
            Vector3::z(),
            Isometry3::identity(),
        ),
        Convention::Urdf => (joint.origin.isometry(), joint.axis, Isometry3::identity()),
    }
}

/// A joint's origin in its parent link (mm) and its axis there.
pub(crate) type JointOrigin = (Isometry3<f64>, Vector3<f64>);

/// Each joint's origin in its parent link (`S_{i-1} P_i`), its axis, and the tool's placement
/// in the last link (`S_n tool`), as [`factors`] gives them.
pub(crate) fn joint_origins(model: &RobotModel) -> (Vec<JointOrigin>, Isometry3<f64>) {
    let mut before = model.base.isometry();
    let mut origins = Vec::new();
    for joint in &model.joints {
        let (p, axis, s) = factors(joint, model.convention);
        origins.push((before * p, axis));
        before = s;
    }
    let tool = match model.tool {
        Tool::Point(p) => Isometry3::translation(p.x, p.y, p.z),
        Tool::Frame(f) => f.isometry(),
    };
    (origins, before * tool)
}

/// What [`to_urdf`] writes beside the kinematics.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct UrdfOptions {
    /// Standard URDF elements only: the compliances, plays and gravity go into the sidecar
    /// ([`UrdfExport::sidecar`]) instead of robocal's extension elements.
    pub standard: bool,
}

/// A model as URDF.
#[derive(Debug, Clone, PartialEq)]
pub struct UrdfExport {
    /// The URDF text (metres, radians).
    pub urdf: String,
    /// With [`UrdfOptions::standard`]: what standard URDF has no element for, as TOML (each
    /// joint's compliance and play in SI units, gravity in the root link's frame); `None`
    /// otherwise.
    pub sidecar: Option<String>,
}

/// `model` as a URDF of its own: each joint's transform factored as `T_i(q) = P_i M_i(q) S_i`
/// (`M_i` the motion; standard DH `P = Rz(theta) Tz(d)`, `S = Tx(a) Rx(alpha) Ry(beta)`;
/// modified DH `P` the whole transform; URDF `P` the origin), joint `i` placed at
/// `S_{i-1} P_i` (`S_0` the base), the tool a fixed joint at `S_n tool` to link `tool0`.
/// Reading it back from its root link `base_link` to `tool0` gives the same forward kinematics.
pub fn to_urdf(model: &RobotModel, options: UrdfOptions) -> UrdfExport {
    let (origins, tool) = joint_origins(model);
    let mut out = format!("<?xml version=\"1.0\"?>\n<robot name=\"{}\">\n", xml_escape(&model.name));
    let g = model.base.isometry().rotation * model.gravity;
    let gravity = format!("<{GRAVITY} xyz=\"{:?} {:?} {:?}\"/>", g.x, g.y, g.z);
    if options.standard {
        out += "  <link name=\"base_link\"/>\n";
    } else {
        let _ = writeln!(out, "  <link name=\"base_link\">\n    {gravity}\n  </link>");
    }
    let mut sidecar = format!(
        "# What standard URDF has no element for, beside {}.urdf (SI units)\ngravity_m_s2 = [{:?}, {:?}, {:?}]\n",
        model.name, g.x, g.y, g.z
    );
    let mut parent = "base_link".to_string();
    for (i, (joint, (origin, axis))) in model.joints.iter().zip(&origins).enumerate() {
        let child = format!("link_{}", i + 1);
        let (kind, per_m) = match joint.kind {
            JointKind::Revolute => ("revolute", 1.0),
            JointKind::Prismatic => ("prismatic", 1e-3),
        };
        let limits = joint.limits.map(|l| l * per_m);
        let _ = write!(
            out,
            "  <joint name=\"{}\" type=\"{kind}\">\n    <parent link=\"{parent}\"/>\n    <child link=\"{child}\"/>\n    {}\n    <axis xyz=\"{:?} {:?} {:?}\"/>\n    <limit lower=\"{:?}\" upper=\"{:?}\" effort=\"0\" velocity=\"0\"/>\n",
            xml_escape(&joint.name),
            origin_element(origin),
            axis.x,
            axis.y,
            axis.z,
            limits[0],
            limits[1]
        );
        let deflects = joint.compliance != 0.0 || joint.play != 0.0;
        let (compliance, play) = (joint.compliance * per_m, joint.play * per_m);
        if deflects && !options.standard {
            let _ = writeln!(out, "    <{DEFLECTION} compliance=\"{compliance:?}\" play=\"{play:?}\"/>");
        }
        if deflects {
            let _ = write!(
                sidecar,
                "\n[[joints]]\nname = \"{}\"\ncompliance = {compliance:?}\nplay = {play:?}\n",
                joint.name.replace('"', "'")
            );
        }
        out += "  </joint>\n";
        out += &link_element(&child, model, i, joint);
        parent = child;
    }
    let _ = write!(
        out,
        "  <joint name=\"tool\" type=\"fixed\">\n    <parent link=\"{parent}\"/>\n    <child link=\"tool0\"/>\n    {}\n  </joint>\n  <link name=\"tool0\"/>\n</robot>\n",
        origin_element(&tool)
    );
    UrdfExport { urdf: out, sidecar: options.standard.then_some(sidecar) }
}

/// Link `name` after joint `i`, with its mass (its centre of mass carried from the joint's frame
/// after `T_i` to the link frame, `S_i com`) if the model has masses.
fn link_element(name: &str, model: &RobotModel, i: usize, joint: &Joint) -> String {
    let Some(mass) = model.masses.get(i) else { return format!("  <link name=\"{name}\"/>\n") };
    let (_, _, s) = factors(joint, model.convention);
    let com = (s * Point3::from(mass.com)).coords / 1000.0;
    format!(
        "  <link name=\"{name}\">\n    <inertial>\n      <origin xyz=\"{:?} {:?} {:?}\" rpy=\"0 0 0\"/>\n      <mass value=\"{:?}\"/>\n      <inertia ixx=\"0\" ixy=\"0\" ixz=\"0\" iyy=\"0\" iyz=\"0\" izz=\"0\"/>\n    </inertial>\n  </link>\n",
        com.x, com.y, com.z, mass.mass
    )
}

fn xml_escape(text: &str) -> String {
    text.replace('&', "&amp;").replace('<', "&lt;").replace('>', "&gt;").replace('"', "&quot;")
}
