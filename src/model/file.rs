//! The TOML model file: what people write, in mm and degrees, with named fields.

use super::{Convention, Joint, JointKind, LinkMass, Placement, RobotModel, Tool};
use crate::error::FieldError;
use crate::limits::{
    MAX_ANGLE_DEG, MAX_COMPLIANCE, MAX_JOINTS, MAX_LENGTH_MM, MAX_MASS_KG, MAX_PLAY, check_magnitude,
    check_range, exactly, exactly_if_given,
};
use nalgebra::Vector3;
use serde::{Deserialize, Serialize};

/// Why a model file (TOML or URDF) could not be read.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum ModelError {
    /// The text is not valid TOML or does not have the fields of a model file; the source
    /// names the line, the column and the field.
    #[error("the model file has a mistake")]
    Syntax(#[source] toml::de::Error),
    /// The text is not valid XML; the source names the line and the column.
    #[error("not valid XML")]
    Xml(#[source] roxmltree::Error),
    /// A field has a value that makes no model.
    #[error(transparent)]
    Invalid(#[from] FieldError),
}

#[derive(Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct ModelFile {
    name: String,
    #[serde(default, skip_serializing_if = "String::is_empty")]
    description: String,
    convention: ConventionName,
    /// Gravity in the robot's base frame, m/s² (default: -9.80665 along z).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    gravity_m_s2: Option<[f64; 3]>,
    #[serde(default)]
    base: PlacementFile,
    tool: ToolFile,
    joints: Vec<JointFile>,
    /// The mass each joint moves, one table per joint (optional).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    links: Vec<LinkFile>,
    /// A payload the arm carries: its mass (kg) and centre of mass in the tip frame (mm).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    payload: Option<LinkFile>,
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    markers: Vec<MarkerFile>,
}

#[derive(Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct LinkFile {
    mass_kg: f64,
    com_mm: [f64; 3],
}

/// A marker of a calibrated model: its number (the measurement file's `x<id>` columns) and
/// its position in the tool's frame, the last joint frame (mm).
#[derive(Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct MarkerFile {
    id: usize,
    xyz_mm: [f64; 3],
}

#[derive(Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
enum ConventionName {
    StandardDh,
    ModifiedDh,
    Urdf,
}

#[derive(Serialize, Deserialize, Default)]
#[serde(deny_unknown_fields)]
struct PlacementFile {
    #[serde(deserialize_with = "exactly")]
    xyz_mm: [f64; 3],
    #[serde(default, deserialize_with = "exactly")]
    rpy_deg: [f64; 3],
}

#[derive(Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct ToolFile {
    #[serde(deserialize_with = "exactly")]
    xyz_mm: [f64; 3],
    /// Present: the tool is a frame (pose measurable). Absent: a point.
    #[serde(default, deserialize_with = "exactly_if_given", skip_serializing_if = "Option::is_none")]
    rpy_deg: Option<[f64; 3]>,
}

#[derive(Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct JointFile {
    name: String,
    #[serde(rename = "type")]
    kind: KindName,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    theta_deg: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    d_mm: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    a_mm: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    alpha_deg: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    beta_deg: Option<f64>,
    #[serde(default, deserialize_with = "exactly_if_given", skip_serializing_if = "Option::is_none")]
    xyz_mm: Option<[f64; 3]>,
    #[serde(default, deserialize_with = "exactly_if_given", skip_serializing_if = "Option::is_none")]
    rpy_deg: Option<[f64; 3]>,
    #[serde(default, deserialize_with = "exactly_if_given", skip_serializing_if = "Option::is_none")]
    axis: Option<[f64; 3]>,
    #[serde(default, deserialize_with = "exactly_if_given", skip_serializing_if = "Option::is_none")]
    limits_deg: Option<[f64; 2]>,
    #[serde(default, deserialize_with = "exactly_if_given", skip_serializing_if = "Option::is_none")]
    limits_mm: Option<[f64; 2]>,
    /// Deflection per unit of gravity load, revolute joints (rad per N·m).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    compliance_rad_per_nm: Option<f64>,
    /// Deflection per unit of gravity load, prismatic joints (mm per N).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    compliance_mm_per_n: Option<f64>,
    /// Play that gravity pushes to one side, revolute joints (degrees).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    play_deg: Option<f64>,
    /// Play that gravity pushes to one side, prismatic joints (mm).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    play_mm: Option<f64>,
}

#[derive(Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
enum KindName {
    Revolute,
    Prismatic,
}

pub(super) fn parse(text: &str) -> Result<RobotModel, ModelError> {
    let file: ModelFile = toml::from_str(text).map_err(ModelError::Syntax)?;
    let convention = match file.convention {
        ConventionName::StandardDh => Convention::StandardDh,
        ConventionName::ModifiedDh => Convention::ModifiedDh,
        ConventionName::Urdf => Convention::Urdf,
    };
    let model = RobotModel {
        name: file.name,
        description: file.description,
        convention,
        base: placement("base", &file.base.xyz_mm, &file.base.rpy_deg)?,
        tool: match file.tool.rpy_deg {
            None => Tool::Point(vector("tool.xyz_mm", &file.tool.xyz_mm)?),
            Some(rpy) => Tool::Frame(placement("tool", &file.tool.xyz_mm, &rpy)?),
        },
        joints: file
            .joints
            .into_iter()
            .enumerate()
            .map(|(i, j)| joint(i, j, convention))
            .collect::<Result<_, _>>()?,
        masses: file.links.iter().enumerate().map(link_mass).collect::<Result<_, _>>()?,
        payload: match &file.payload {
            Some(p) => {
                let LinkMass { mass, com } = mass_at("payload", p)?;
                Some(super::Payload { mass, com })
            }
            None => None,
        },
        gravity: match file.gravity_m_s2 {
            Some(g) => vector("gravity_m_s2", &g)?,
            None => RobotModel::floor_gravity(),
        },
    };
    validate(&model)?;
    Ok(model)
}

fn invalid(field: impl Into<String>, expected: impl Into<String>) -> ModelError {
    FieldError::new(field, expected).into()
}

/// `value`, finite and (for a field in mm or degrees) within [`MAX_LENGTH_MM`] or
/// [`MAX_ANGLE_DEG`].
fn finite(field: &str, value: f64) -> Result<f64, ModelError> {
    if !value.is_finite() {
        return Err(invalid(field, format!("a finite number, found {value}")));
    }
    let bound = if field.ends_with("_mm") {
        Some((MAX_LENGTH_MM, "mm"))
    } else if field.ends_with("_deg") {
        Some((MAX_ANGLE_DEG, "deg"))
    } else {
        None
    };
    match bound {
        Some((bound, unit)) => check_magnitude(value, bound, unit).map_err(|e| invalid(field, e)),
        None => Ok(value),
    }
}

fn vector(field: &str, v: &[f64; 3]) -> Result<Vector3<f64>, ModelError> {
    for &x in v {
        finite(field, x)?;
    }
    Ok(Vector3::from(*v))
}

fn placement(field: &str, xyz_mm: &[f64; 3], rpy_deg: &[f64; 3]) -> Result<Placement, ModelError> {
    Ok(Placement {
        xyz: vector(&format!("{field}.xyz_mm"), xyz_mm)?,
        rpy: vector(&format!("{field}.rpy_deg"), rpy_deg)?.map(f64::to_radians),
    })
}

/// Joint `index` of the file, with its compliance and play.
fn joint(index: usize, j: JointFile, convention: Convention) -> Result<Joint, ModelError> {
    let revolute = matches!(j.kind, KindName::Revolute);
    let compliance = per_kind(
        (index, "compliance"),
        revolute,
        ("compliance_rad_per_nm", j.compliance_rad_per_nm),
        ("compliance_mm_per_n", j.compliance_mm_per_n),
    )?;
    let at = |field: &str| format!("joints[{index}].{field}");
    // A calibrated model may carry a negative estimate (which `calibrate` warns of): bounded in
    // magnitude only.
    let compliance =
        check_range(compliance, -MAX_COMPLIANCE, MAX_COMPLIANCE, if revolute { "rad/(N·m)" } else { "mm/N" })
            .map_err(|e| {
                invalid(at(if revolute { "compliance_rad_per_nm" } else { "compliance_mm_per_n" }), e)
            })?;
    let play = per_kind((index, "play"), revolute, ("play_deg", j.play_deg), ("play_mm", j.play_mm))?;
    let play = check_range(play, -MAX_PLAY, MAX_PLAY, if revolute { "deg" } else { "mm" })
        .map_err(|e| invalid(at(if revolute { "play_deg" } else { "play_mm" }), e))?;
    let play = if revolute { play.to_radians() } else { play };
    Ok(Joint { compliance, play, ..geometry(index, j, convention)? })
}

/// The value of joint `index`'s field `what`, with a revolute and a prismatic spelling (unit),
/// 0 when absent; the other joint kind's spelling is an error.
fn per_kind(
    (index, what): (usize, &str),
    revolute: bool,
    (rotary, rotary_value): (&str, Option<f64>),
    (linear, linear_value): (&str, Option<f64>),
) -> Result<f64, ModelError> {
    let at = |field: &str| format!("joints[{index}].{field}");
    match (revolute, rotary_value, linear_value) {
        (_, None, None) => Ok(0.0),
        (true, Some(v), None) => Ok(finite(&at(rotary), v)?),
        (false, None, Some(v)) => Ok(finite(&at(linear), v)?),
        (true, _, _) => Err(invalid(at(linear), format!("a revolute joint's {what} as {rotary}"))),
        (false, _, _) => Err(invalid(at(rotary), format!("a prismatic joint's {what} as {linear}"))),
    }
}

/// Joint `index`'s geometry and limits.
fn geometry(index: usize, j: JointFile, convention: Convention) -> Result<Joint, ModelError> {
    let at = |field: &str| format!("joints[{index}].{field}");
    let kind = match j.kind {
        KindName::Revolute => JointKind::Revolute,
        KindName::Prismatic => JointKind::Prismatic,
    };
    let limits = match (kind, j.limits_deg, j.limits_mm) {
        (JointKind::Revolute, Some(l), None) => l,
        (JointKind::Prismatic, None, Some(l)) => l,
        (JointKind::Revolute, _, _) => {
            return Err(invalid(
                at("limits_deg"),
                "a revolute joint's limits as `limits_deg = [lower, upper]` (and no `limits_mm`)",
            ));
        }
        (JointKind::Prismatic, _, _) => {
            return Err(invalid(
                at("limits_mm"),
                "a prismatic joint's limits as `limits_mm = [lower, upper]` (and no `limits_deg`)",
            ));
        }
    };
    let limits_field = at(if kind == JointKind::Revolute { "limits_deg" } else { "limits_mm" });
    finite(&limits_field, limits[0])?;
    finite(&limits_field, limits[1])?;
    if limits[0] >= limits[1] {
        return Err(invalid(limits_field, "[lower, upper] with lower < upper"));
    }
    let limits = if kind == JointKind::Revolute { limits.map(f64::to_radians) } else { limits };
    let dh = [("theta_deg", j.theta_deg), ("d_mm", j.d_mm), ("a_mm", j.a_mm), ("alpha_deg", j.alpha_deg)];
    let urdf = [("xyz_mm", j.xyz_mm.is_some()), ("rpy_deg", j.rpy_deg.is_some()), ("axis", j.axis.is_some())];
    if convention == Convention::Urdf {
        if let Some((field, _)) = dh.iter().chain([&("beta_deg", j.beta_deg)]).find(|(_, v)| v.is_some()) {
            return Err(invalid(at(field), "no DH field in a `urdf` model: give xyz_mm, rpy_deg and axis"));
        }
        let axis = vector(
            &at("axis"),
            &j.axis.ok_or_else(|| invalid(at("axis"), "the joint's axis, `axis = [x, y, z]`"))?,
        )?;
        if axis.norm() < 1e-9 {
            return Err(invalid(at("axis"), "a non-zero axis"));
        }
        let origin = placement(&at("origin"), &j.xyz_mm.unwrap_or_default(), &j.rpy_deg.unwrap_or_default())?;
        return Ok(Joint::urdf(&j.name, kind, origin, axis.normalize(), limits));
    }
    if let Some((field, _)) = urdf.iter().find(|(_, present)| *present) {
        return Err(invalid(
            at(field),
            "DH fields only (theta_deg, d_mm, a_mm, alpha_deg, beta_deg) in a DH model",
        ));
    }
    let required = |(field, v): (&str, Option<f64>)| {
        v.ok_or_else(|| invalid(at(field), format!("`{field}`, required in a DH model")))
            .and_then(|v| finite(&at(field), v))
    };
    let [theta, d, a, alpha] = dh.map(required);
    let beta = finite(&at("beta_deg"), j.beta_deg.unwrap_or(0.0))?;
    Ok(Joint::dh(
        &j.name,
        kind,
        [theta?.to_radians(), d?, a?, alpha?.to_radians(), beta.to_radians()],
        limits,
    ))
}

/// The mass of `[[links]]` table `i`.
fn link_mass((i, link): (usize, &LinkFile)) -> Result<LinkMass, ModelError> {
    mass_at(&format!("links[{i}]"), link)
}

/// The mass of table `field`: kg >= 0 and a finite centre of mass (mm).
fn mass_at(field: &str, link: &LinkFile) -> Result<LinkMass, ModelError> {
    let at = format!("{field}.mass_kg");
    let mass = check_range(link.mass_kg, 0.0, MAX_MASS_KG, "kg").map_err(|e| invalid(&at, e))?;
    Ok(LinkMass { mass, com: vector(&format!("{field}.com_mm"), &link.com_mm)? })
}

fn validate(model: &RobotModel) -> Result<(), ModelError> {
    if model.joints.is_empty() {
        return Err(invalid("joints", "at least one [[joints]] table"));
    }
    if !model.masses.is_empty() && model.masses.len() != model.joints.len() {
        return Err(invalid(
            "links",
            format!("one [[links]] table per joint ({}), found {}", model.joints.len(), model.masses.len()),
        ));
    }
    if model.joints.len() > MAX_JOINTS {
        return Err(invalid("joints", format!("at most {MAX_JOINTS} joints, found {}", model.joints.len())));
    }
    for (i, joint) in model.joints.iter().enumerate() {
        let ok_name = !joint.name.is_empty()
            && joint.name.chars().all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '-');
        if !ok_name {
            return Err(invalid(
                format!("joints[{i}].name"),
                format!("a non-empty name of letters, digits, `_` or `-`, found {:?}", joint.name),
            ));
        }
        if ["base", "tool"].contains(&joint.name.as_str()) {
            return Err(invalid(format!("joints[{i}].name"), "a name other than `base` or `tool`"));
        }
        if model.joints[..i].iter().any(|other| other.name == joint.name) {
            return Err(invalid(
                format!("joints[{i}].name"),
                format!("a unique name, `{}` is used twice", joint.name),
            ));
        }
    }
    Ok(())
}

pub(super) fn write(model: &RobotModel) -> String {
    let deg3 = |v: &Vector3<f64>| [degrees(v.x), degrees(v.y), degrees(v.z)];
    let file = ModelFile {
        name: model.name.clone(),
        description: model.description.clone(),
        convention: match model.convention {
            Convention::StandardDh => ConventionName::StandardDh,
            Convention::ModifiedDh => ConventionName::ModifiedDh,
            Convention::Urdf => ConventionName::Urdf,
        },
        gravity_m_s2: (model.gravity != RobotModel::floor_gravity()).then(|| model.gravity.into()),
        links: model.masses.iter().map(|m| LinkFile { mass_kg: m.mass, com_mm: m.com.into() }).collect(),
        payload: model.payload.map(|p| LinkFile { mass_kg: p.mass, com_mm: p.com.into() }),
        base: PlacementFile { xyz_mm: model.base.xyz.into(), rpy_deg: deg3(&model.base.rpy) },
        tool: match &model.tool {
            Tool::Point(p) => ToolFile { xyz_mm: (*p).into(), rpy_deg: None },
            Tool::Frame(f) => ToolFile { xyz_mm: f.xyz.into(), rpy_deg: Some(deg3(&f.rpy)) },
        },
        joints: model
            .joints
            .iter()
            .map(|j| {
                let revolute = j.kind == JointKind::Revolute;
                let (dh, urdf) = (model.convention != Convention::Urdf, model.convention == Convention::Urdf);
                JointFile {
                    name: j.name.clone(),
                    kind: if revolute { KindName::Revolute } else { KindName::Prismatic },
                    theta_deg: dh.then(|| degrees(j.theta)),
                    d_mm: dh.then_some(j.d),
                    a_mm: dh.then_some(j.a),
                    alpha_deg: dh.then(|| degrees(j.alpha)),
                    beta_deg: dh.then(|| degrees(j.beta)),
                    xyz_mm: urdf.then(|| j.origin.xyz.into()),
                    rpy_deg: urdf.then(|| deg3(&j.origin.rpy)),
                    axis: urdf.then(|| j.axis.into()),
                    limits_deg: revolute.then(|| j.limits.map(degrees)),
                    limits_mm: (!revolute).then_some(j.limits),
                    compliance_rad_per_nm: (revolute && j.compliance != 0.0).then_some(j.compliance),
                    compliance_mm_per_n: (!revolute && j.compliance != 0.0).then_some(j.compliance),
                    play_deg: (revolute && j.play != 0.0).then(|| degrees(j.play)),
                    play_mm: (!revolute && j.play != 0.0).then_some(j.play),
                }
            })
            .collect(),
        markers: Vec::new(),
    };
    toml::to_string(&file).expect("a model always serialises")
}

/// `model` as TOML with a `[[markers]]` list: the markers' numbers and positions (mm, the
/// last joint frame, as the tool), which `calibrate --out-model` writes and `evaluate` reads.
pub fn to_toml_with_markers(model: &RobotModel, markers: &[(usize, Vector3<f64>)]) -> String {
    let mut file: ModelFile = toml::from_str(&write(model)).expect("a written model reads back");
    file.markers = markers.iter().map(|(id, p)| MarkerFile { id: *id, xyz_mm: (*p).into() }).collect();
    toml::to_string(&file).expect("a model always serialises")
}

/// The `[[markers]]` of a model file (empty without): number and position (mm, the last joint
/// frame). Numbers are at least 1 and unique.
pub fn markers_from_toml_str(text: &str) -> Result<Vec<(usize, Vector3<f64>)>, ModelError> {
    let file: ModelFile = toml::from_str(text).map_err(ModelError::Syntax)?;
    let mut out: Vec<(usize, Vector3<f64>)> = Vec::new();
    for (i, m) in file.markers.iter().enumerate() {
        if m.id == 0 || out.iter().any(|(id, _)| *id == m.id) {
            return Err(invalid(format!("markers[{i}].id"), "a unique marker number >= 1"));
        }
        out.push((m.id, vector(&format!("markers[{i}].xyz_mm"), &m.xyz_mm)?));
    }
    Ok(out)
}

/// The shortest decimal number of degrees that reads back as exactly `radians`, so that a
/// written model reads back bit for bit and `90` is written as `90`, not `90.00000000000001`.
/// Every angle read from degrees has such a number; for any other, the nearest is returned.
pub fn degrees(radians: f64) -> f64 {
    let approx = radians.to_degrees();
    let shortest = (1..=17)
        .map(|digits| format!("{approx:.*e}", digits - 1).parse::<f64>().unwrap_or(approx))
        .find(|d| d.to_radians() == radians);
    // `to_degrees` can land an ulp or two off the value that was read: look beside it.
    let beside = || {
        (1..=8u64)
            .flat_map(|k| [approx.to_bits().wrapping_add(k), approx.to_bits().wrapping_sub(k)])
            .map(f64::from_bits)
            .find(|d| d.to_radians() == radians)
    };
    shortest.or_else(beside).unwrap_or(approx)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn degrees_are_short_and_exact() {
        assert_eq!(degrees(90f64.to_radians()), 90.0);
        assert_eq!(degrees((-0.007f64).to_radians()), -0.007);
        for i in 0..100_000 {
            let read = (i as f64 * 0.7131).sin() * 270.0 + 1e-9 * i as f64;
            let r = read.to_radians();
            assert_eq!(degrees(r).to_radians(), r, "read as {read} deg");
        }
    }
}
