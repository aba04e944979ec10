//! Named error parameters and the selection of those to identify.
//!
//! The full error vector of a model has, in this order: the base (6: `base.x`, `base.y`,
//! `base.z` in mm, `base.rx`, `base.ry`, `base.rz` in rad), each joint (5: `theta`, `d`, `a`,
//! `alpha`, `beta`, named after the joint, e.g. `j3.beta`), and the tool (3 for a point:
//! `tool.x`, `tool.y`, `tool.z`; 6 for a frame, adding `tool.rx`, `tool.ry`, `tool.rz`).
//! A joint's offset is the error of the parameter its variable adds to: `theta` for a
//! revolute joint, `d` for a prismatic one. A URDF joint has 7: its origin's displacement
//! (`x`, `y`, `z`, `rx`, `ry`, `rz`, like the base's) and its offset (`theta` or `d`). Some are
//! redundant by construction (a rotation of the origin about the joint's own axis is its
//! offset; a shift along a revolute axis moves nothing the next origin cannot): the
//! rank-revealing solve finds them and holds them fixed.
//!
//! Base and tool errors are a small displacement applied after the nominal placement,
//! `Trans(x, y, z) Rx(rx) Ry(ry) Rz(rz)`, so they are expressed in the robot's base frame and
//! in the tool frame; being zero nominally, their axes never meet in gimbal lock.

use super::{Convention, JointKind, RobotModel, Tool};

/// The kind of an error parameter: what it displaces, and so its unit.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum ParamKind {
    /// Translation along x (mm).
    X,
    /// Translation along y (mm).
    Y,
    /// Translation along z (mm).
    Z,
    /// Rotation about x (rad).
    Rx,
    /// Rotation about y (rad).
    Ry,
    /// Rotation about z (rad).
    Rz,
    /// DH rotation about z (rad).
    Theta,
    /// DH translation along z (mm).
    D,
    /// DH translation along x (mm).
    A,
    /// DH rotation about x (rad).
    Alpha,
    /// Hayati's rotation about y (rad).
    Beta,
    /// A joint's compliance: its deflection per unit of the load gravity puts on it (rad per
    /// N·m for a revolute joint, mm per N for a prismatic one); the joint reaches
    /// `q + c tau(q)`. Only models with masses have it.
    Compliance,
    /// A joint's play: the constant error gravity pushes it to, with the sign of the load on it
    /// (rad for a revolute joint, mm for a prismatic one); the joint reaches `q + p sgn(tau(q))`.
    /// Only models with masses have it.
    Play,
    /// A payload's mass (kg).
    Mass,
}

impl ParamKind {
    /// The displacement parameters of a base or tool, in order.
    pub const PLACEMENT: [ParamKind; 6] = [Self::X, Self::Y, Self::Z, Self::Rx, Self::Ry, Self::Rz];
    /// The parameters of a joint, in order.
    pub const JOINT: [ParamKind; 5] = [Self::Theta, Self::D, Self::A, Self::Alpha, Self::Beta];

    /// The name's suffix: `x`, `rz`, `theta`, ...
    pub fn label(self) -> &'static str {
        match self {
            Self::X => "x",
            Self::Y => "y",
            Self::Z => "z",
            Self::Rx => "rx",
            Self::Ry => "ry",
            Self::Rz => "rz",
            Self::Theta => "theta",
            Self::D => "d",
            Self::A => "a",
            Self::Alpha => "alpha",
            Self::Beta => "beta",
            Self::Compliance => "compliance",
            Self::Play => "play",
            Self::Mass => "mass",
        }
    }

    /// Whether the parameter is an angle (rad) whatever it belongs to; a joint's play is an
    /// angle or a length with its joint ([`ParamInfo::unit`]).
    pub fn is_angle(self) -> bool {
        matches!(self, Self::Rx | Self::Ry | Self::Rz | Self::Theta | Self::Alpha | Self::Beta)
    }
}

/// What an error parameter belongs to.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum ParamOwner {
    /// The base placement (measuring frame to first joint frame).
    Base,
    /// Joint with this index (0-based).
    Joint(usize),
    /// The tool (last joint frame to measured point or frame).
    Tool,
    /// Marker `k` (0-based) on the last link, when several points are measured (`marker1.x`).
    Marker(usize),
    /// The payload the arm carries (`payload.mass`).
    Payload,
}

/// One named error parameter.
#[derive(Debug, Clone, PartialEq)]
pub struct ParamInfo {
    /// What it belongs to.
    pub owner: ParamOwner,
    /// What it displaces.
    pub kind: ParamKind,
    /// Its name in reports: `base.x`, `j3.beta`, `tool.z`.
    pub name: String,
    /// Whether it is the joint's zero offset (`theta` of a revolute joint, `d` of a prismatic).
    pub is_offset: bool,
    unit: &'static str,
}

impl ParamInfo {
    /// The unit of the parameter inside robocal: `"rad"`, `"mm"`, or for a compliance
    /// `"rad/N·m"` (revolute joint) or `"mm/N"` (prismatic); a play is in its joint's unit.
    pub fn unit(&self) -> &'static str {
        self.unit
    }

    /// Whether the parameter is an angle (rad).
    pub fn is_angle(&self) -> bool {
        self.unit == "rad"
    }

    /// Whether the parameter is a joint's response to its gravity load (a compliance or a
    /// play), rather than geometry.
    pub fn is_load_response(&self) -> bool {
        matches!(self.kind, ParamKind::Compliance | ParamKind::Play)
    }
}

/// All error parameters of a model, in canonical order: base (6), each joint (5 DH, or 7 for
/// URDF: 6 origin errors and the offset; then its compliance and play if the model has
/// masses), the payload's mass if it carries one, then the tool (3 or 6) or the markers.
#[derive(Debug, Clone, PartialEq)]
pub struct ParamSet {
    params: Vec<ParamInfo>,
}

impl ParamSet {
    /// The set of `params`, in their order (a tree's, which no one chain's model builds).
    pub fn from_params(params: Vec<ParamInfo>) -> Self {
        Self { params }
    }

    /// The parameters of `model`, with its tool.
    pub fn new(model: &RobotModel) -> Self {
        Self::build(model, None)
    }

    /// The parameters of `model` with points and frames on its last link, `counts[k]` the
    /// parameters of `marker<k + 1>`: 3 for a point (`.x`, `.y`, `.z`, mm), 6 for a measured
    /// frame (then `.rx`, `.ry`, `.rz`, rad).
    pub fn with_marker_ends(model: &RobotModel, counts: &[usize]) -> Self {
        Self::build(model, Some(counts))
    }

    /// `markers`: how many parameters each has (3 for a point, 6 for a frame).
    fn build(model: &RobotModel, markers: Option<&[usize]>) -> Self {
        let mut params = Vec::new();
        let mut push = |owner, kind: ParamKind, prefix: &str, is_offset| {
            let name = format!("{prefix}.{}", kind.label());
            let unit = match (kind, owner) {
                (ParamKind::Compliance, ParamOwner::Joint(i))
                    if model.joints[i].kind == JointKind::Prismatic =>
                {
                    "mm/N"
                }
                (ParamKind::Compliance, _) => "rad/N·m",
                (ParamKind::Play, ParamOwner::Joint(i)) if model.joints[i].kind == JointKind::Prismatic => {
                    "mm"
                }
                (ParamKind::Play, _) => "rad",
                (ParamKind::Mass, _) => "kg",
                (kind, _) if kind.is_angle() => "rad",
                _ => "mm",
            };
            params.push(ParamInfo { owner, kind, name, is_offset, unit });
        };
        for kind in ParamKind::PLACEMENT {
            push(ParamOwner::Base, kind, "base", false);
        }
        for (i, joint) in model.joints.iter().enumerate() {
            let offset = match joint.kind {
                JointKind::Revolute => ParamKind::Theta,
                JointKind::Prismatic => ParamKind::D,
            };
            let kinds: &[ParamKind] = match model.convention {
                Convention::Urdf => &[
                    ParamKind::X,
                    ParamKind::Y,
                    ParamKind::Z,
                    ParamKind::Rx,
                    ParamKind::Ry,
                    ParamKind::Rz,
                    offset,
                ],
                _ => &ParamKind::JOINT,
            };
            for &kind in kinds {
                push(ParamOwner::Joint(i), kind, &joint.name, kind == offset);
            }
            if model.has_masses() {
                push(ParamOwner::Joint(i), ParamKind::Compliance, &joint.name, false);
                push(ParamOwner::Joint(i), ParamKind::Play, &joint.name, false);
            }
        }
        if model.payload.is_some() {
            push(ParamOwner::Payload, ParamKind::Mass, "payload", false);
        }
        match markers {
            Some(each) => {
                for (k, &per) in each.iter().enumerate() {
                    for &kind in &ParamKind::PLACEMENT[..per] {
                        push(ParamOwner::Marker(k), kind, &format!("marker{}", k + 1), false);
                    }
                }
            }
            None => {
                let tool_kinds = match model.tool {
                    Tool::Point(_) => &ParamKind::PLACEMENT[..3],
                    Tool::Frame(_) => &ParamKind::PLACEMENT[..],
                };
                for &kind in tool_kinds {
                    push(ParamOwner::Tool, kind, "tool", false);
                }
            }
        }
        Self { params }
    }

    /// Number of parameters.
    pub fn len(&self) -> usize {
        self.params.len()
    }

    /// Whether there are none (never, for a valid model).
    pub fn is_empty(&self) -> bool {
        self.params.is_empty()
    }

    /// The parameter at `index`.
    pub fn get(&self, index: usize) -> &ParamInfo {
        &self.params[index]
    }

    /// All parameters in order.
    pub fn iter(&self) -> impl Iterator<Item = &ParamInfo> {
        self.params.iter()
    }

    /// Index of the parameter of `owner` and `kind`, if the model has it.
    pub fn index_of(&self, owner: ParamOwner, kind: ParamKind) -> Option<usize> {
        self.params.iter().position(|p| p.owner == owner && p.kind == kind)
    }

    /// Index of the parameter called `name`.
    pub fn index_by_name(&self, name: &str) -> Option<usize> {
        self.params.iter().position(|p| p.name == name)
    }
}

/// A requested parameter that the model does not have.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error(
    "no parameter matches `{pattern}`; parameters are named like `base.x`, `j2.theta`, `tool.z`, with `*` for any part (`j*.theta`, `base.*`)"
)]
pub struct SelectionError {
    /// The name or pattern that matched nothing.
    pub pattern: String,
}

/// Which error parameters are identified: the columns of the identification Jacobian H.
///
/// Columns are in canonical parameter order whatever order they were asked for in, so the
/// same selection always gives the same H.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Selection {
    indices: Vec<usize>,
    columns: Vec<Option<usize>>,
}

impl Selection {
    /// The parameters at these indices of `params`.
    ///
    /// # Panics
    /// If an index is out of range.
    pub fn from_indices(params: &ParamSet, indices: impl IntoIterator<Item = usize>) -> Self {
        let mut columns = vec![None; params.len()];
        for i in indices {
            columns[i] = Some(0);
        }
        let indices: Vec<usize> = (0..params.len()).filter(|&i| columns[i].is_some()).collect();
        for (column, &i) in indices.iter().enumerate() {
            columns[i] = Some(column);
        }
        Self { indices, columns }
    }

    /// No parameter.
    pub(crate) fn empty() -> Self {
        Self { indices: Vec::new(), columns: Vec::new() }
    }

    /// Every parameter of the model.
    pub fn all(params: &ParamSet) -> Self {
        Self::from_indices(params, 0..params.len())
    }

    /// Every geometric joint parameter, base and tool fixed: the paper's set (30 for a 6-joint
    /// robot); not the compliances and plays (select them by name, `j*.compliance`, `j*.play`).
    pub fn joints(params: &ParamSet) -> Self {
        Self::matching(params, |p| matches!(p.owner, ParamOwner::Joint(_)) && !p.is_load_response())
    }

    /// Only the joint offsets.
    pub fn offsets(params: &ParamSet) -> Self {
        Self::matching(params, |p| p.is_offset)
    }

    /// The parameters named, each a name (`j2.theta`) or a pattern with `*` standing for any
    /// characters within one part of the name (`j*.theta`, `base.*`, `*.*`).
    pub fn by_names<S: AsRef<str>>(params: &ParamSet, names: &[S]) -> Result<Self, SelectionError> {
        let mut chosen = Vec::new();
        for pattern in names.iter().map(AsRef::as_ref) {
            let before = chosen.len();
            chosen.extend((0..params.len()).filter(|&i| name_matches(pattern, &params.get(i).name)));
            if chosen.len() == before {
                return Err(SelectionError { pattern: pattern.to_string() });
            }
        }
        Ok(Self::from_indices(params, chosen))
    }

    fn matching(params: &ParamSet, keep: impl Fn(&ParamInfo) -> bool) -> Self {
        Self::from_indices(params, (0..params.len()).filter(|&i| keep(params.get(i))))
    }

    /// Number of selected parameters (columns of H).
    pub fn len(&self) -> usize {
        self.indices.len()
    }

    /// Whether nothing is selected.
    pub fn is_empty(&self) -> bool {
        self.indices.is_empty()
    }

    /// Indices in the full parameter vector of the selected parameters, column by column.
    pub fn indices(&self) -> &[usize] {
        &self.indices
    }

    /// The column of H that holds full parameter `index`, if it is selected.
    pub fn column(&self, index: usize) -> Option<usize> {
        self.columns.get(index).copied().flatten()
    }
}

/// Whether `name` matches `pattern`, where one `*` in either part of the pattern stands for any
/// run of characters within that part (`j*.theta`, `base.*`).
pub(crate) fn name_matches(pattern: &str, name: &str) -> bool {
    let part = |p: &str, n: &str| match p.split_once('*') {
        Some((pre, post)) => n.len() >= pre.len() + post.len() && n.starts_with(pre) && n.ends_with(post),
        None => p == n,
    };
    match (pattern.split_once('.'), name.split_once('.')) {
        (Some((po, pk)), Some((no, nk))) => part(po, no) && part(pk, nk),
        _ => pattern == name,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn puma_has_the_papers_thirty_joint_parameters() {
        let params = RobotModel::preset("puma560").unwrap().params();
        assert_eq!(params.len(), 6 + 30 + 3);
        assert_eq!(params.get(6 + 2 * 5 + 4).name, "j3.beta");
        assert_eq!(Selection::joints(&params).len(), 30);
        assert_eq!(Selection::offsets(&params).len(), 6);
    }

    #[test]
    fn names_and_patterns_select_in_canonical_order() {
        let params = RobotModel::preset("puma560").unwrap().params();
        let sel = Selection::by_names(&params, &["tool.*", "j*.theta", "base.x"]).unwrap();
        let names: Vec<_> = sel.indices().iter().map(|&i| params.get(i).name.as_str()).collect();
        assert_eq!(names[..3], ["base.x", "j1.theta", "j2.theta"]);
        assert_eq!(names.len(), 1 + 6 + 3);
        assert_eq!(sel.column(params.index_by_name("j1.theta").unwrap()), Some(1));
        assert_eq!(sel.column(params.index_by_name("j1.d").unwrap()), None);
        let err = Selection::by_names(&params, &["j7.theta"]).unwrap_err();
        assert!(err.to_string().contains("`j7.theta`"), "{err}");
    }
}
