//! Robots of several chains: [`RobotTree`].

use super::urdf::{chain_moves, ends, link_names};
use super::{Joint, ModelError, RobotModel, from_urdf_str};
use crate::error::FieldError;
use rand::RngExt;
use rand::rngs::ChaCha8Rng;

/// One serial chain of a [`RobotTree`], from the root link to a tip link.
#[derive(Debug, Clone, PartialEq)]
pub struct Branch {
    /// The tip link's name: the branch's name in files and reports.
    pub tip: String,
    /// The chain as a serial robot (lengths mm, angles rad; no masses).
    pub model: RobotModel,
    /// The tree joint of each of the chain's joints, in order ([`RobotTree::joints`]).
    pub joints: Vec<usize>,
}

impl Branch {
    /// The branch's joint values out of the tree's `q` (one per tree joint).
    pub fn values(&self, q: &[f64]) -> Vec<f64> {
        self.joints.iter().map(|&j| q[j]).collect()
    }
}

/// Robots of several chains: a tree of links (a torso carrying two arms and a head) read from a
/// URDF file as one serial chain from the root link to each tip link, a *branch*, with the
/// joints they share named once.
///
/// Each branch is a [`RobotModel`], the chain [`from_urdf_str`](super::from_urdf_str) reads
/// from the root to its tip. A joint on several branches (the torso's) is one joint: the
/// tree's joints are the branches' moving joints by name, in the order they are met (branch by
/// branch, base to tip), and a pose gives one value per tree joint, each branch taking its own
/// ([`Branch::joints`]). The error parameters of a joint are named after it (`torso.x`), so the
/// branches' parameters of one name are the tree's one parameter.
///
/// The tips are every leaf link (a link that is no joint's parent) with a moving joint between
/// it and the root, in the file's order, unless named. The tree's geometry is what is
/// calibrated: the branches are read without their masses (a shared joint carries every
/// branch's links, which no one branch's model holds).
#[derive(Debug, Clone, PartialEq)]
pub struct RobotTree {
    /// The robot's name (the URDF's).
    pub name: String,
    /// The root link every branch starts at.
    pub root: String,
    /// The tree's moving joints, each once.
    pub joints: Vec<Joint>,
    /// The chains from the root to each tip.
    pub branches: Vec<Branch>,
}

impl RobotTree {
    /// The tree of URDF `text` from `root` (default: its only root link) to the tip links
    /// `tips` (default: every leaf link with a moving joint on its way, in the file's order).
    pub fn from_urdf_str(text: &str, root: Option<&str>, tips: &[String]) -> Result<Self, ModelError> {
        let (roots, leaves) = ends(text)?;
        let root = match (root, &roots[..]) {
            (Some(root), _) => root.to_string(),
            (None, [one]) => one.clone(),
            (None, _) => {
                return Err(FieldError::new(
                    "base link",
                    format!("a single root link, found {}: give --base-link", roots.join(", ")),
                )
                .into());
            }
        };
        if !link_names(text)?.contains(&root) {
            return Err(FieldError::new("base link", format!("a link named `{root}` in the file")).into());
        }
        let tips: Vec<String> = if tips.is_empty() {
            let mut moving = Vec::new();
            for leaf in leaves {
                if chain_moves(text, &root, &leaf)? {
                    moving.push(leaf);
                }
            }
            moving
        } else {
            tips.to_vec()
        };
        if tips.len() < 2 {
            return Err(FieldError::new(
                "tip links",
                format!(
                    "two tips or more for a tree, found {}: a serial arm is calibrated from its markers or tool point, not from views between branches",
                    tips.len()
                ),
            )
            .into());
        }
        if let Some(tip) = tips.iter().enumerate().find_map(|(i, t)| tips[..i].contains(t).then_some(t)) {
            return Err(FieldError::new("tip links", format!("each tip once, found `{tip}` twice")).into());
        }
        let mut joints: Vec<Joint> = Vec::new();
        let mut branches = Vec::with_capacity(tips.len());
        for tip in tips {
            let mut model = from_urdf_str(text, &root, &tip)?;
            model.masses.clear();
            let mut indices = Vec::with_capacity(model.joints.len());
            for joint in &model.joints {
                match joints.iter().position(|j| j.name == joint.name) {
                    Some(i) if joints[i] == *joint => indices.push(i),
                    Some(_) => {
                        return Err(FieldError::new(
                            format!("joint `{}`", joint.name),
                            "one geometry on every branch it is on",
                        )
                        .into());
                    }
                    None => {
                        indices.push(joints.len());
                        joints.push(joint.clone());
                    }
                }
            }
            if let Some(other) = branches.iter().find(|b: &&Branch| b.joints == indices) {
                return Err(FieldError::new(
                    "tip links",
                    format!(
                        "branches that move: `{tip}` and `{}` have the same moving joints (one rigid body): give one of them",
                        other.tip
                    ),
                )
                .into());
            }
            branches.push(Branch { tip, model, joints: indices });
        }
        let name = branches[0].model.name.clone();
        Ok(Self { name, root, joints, branches })
    }

    /// The number of joints (each shared joint once).
    pub fn dof(&self) -> usize {
        self.joints.len()
    }

    /// The same tree with its joints replaced by `joints` (one per tree joint, in order), on
    /// every branch that has them: a tree with other geometry (a simulated true robot).
    ///
    /// # Panics
    /// If `joints` is not one per tree joint.
    pub fn with_joints(&self, joints: Vec<Joint>) -> Self {
        assert_eq!(joints.len(), self.dof(), "one joint per tree joint");
        let mut out = self.clone();
        for branch in &mut out.branches {
            for (joint, &j) in branch.model.joints.iter_mut().zip(&branch.joints) {
                *joint = joints[j].clone();
            }
        }
        out.joints = joints;
        out
    }

    /// `n` configurations of the tree's joints drawn uniformly within their limits, joint by
    /// joint, from `rng`.
    pub fn uniform_configurations(&self, n: usize, rng: &mut ChaCha8Rng) -> Vec<Vec<f64>> {
        (0..n)
            .map(|_| self.joints.iter().map(|j| rng.random_range(j.limits[0]..=j.limits[1])).collect())
            .collect()
    }

    /// The branch ending at link `tip`, if there is one.
    pub fn branch(&self, tip: &str) -> Option<usize> {
        self.branches.iter().position(|b| b.tip == tip)
    }
}
