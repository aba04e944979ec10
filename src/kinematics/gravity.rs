//! The static load gravity puts on each joint: the generalised gravity force.
//!
//! With `m_j` the mass joint `j` moves (its link and everything fixed to it), `c_j(q)` its
//! centre of mass and `g` gravity, both in the walk's (measuring) frame, the potential energy is
//! `U(q) = -sum_j m_j g . c_j(q)`, and the load on joint `i` is `tau_i = -dU/dq_i`:
//!
//! - revolute joint, axis `z_i` through `p_i`: `tau_i = z_i . sum_{j >= i} (c_j - p_i) x m_j g`
//!   (N·m: the torque gravity exerts about the axis, positive in the joint's sense);
//! - prismatic joint, direction `z_i`: `tau_i = z_i . sum_{j >= i} m_j g` (N).
//!
//! Only the links after joint `i` move with it, hence `j >= i`. Both sums come from two walks
//! along the chain, with no allocation: the first adds up `M = sum_j m_j` and
//! `S = sum_j m_j c_j` over all links, the second subtracts each link's share as it passes its
//! end, so that at joint `i` the links after it hold `M_i` and `S_i`, and
//! `(S_i - M_i p_i) x g` is the torque about `p_i`. Gravity is given in the robot's base frame
//! ([`crate::model::RobotModel::gravity`]) and turned into the walk's frame by the base's
//! rotation at the end of the base steps.

use super::{ChainAt, Frame, Motion, advance};
use crate::model::{LinkMass, RobotModel};
use nalgebra::Vector3;

/// Where the base's steps end and where each joint's link frame is reached, as step counts.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub(super) struct LinkEnds {
    /// Steps of the base placement.
    pub base: usize,
    /// Steps up to and including each joint's own, in joint order.
    pub links: Vec<usize>,
}

/// What gravity needs of a model: its link ends, masses and gravity.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct Load {
    ends: LinkEnds,
    /// One per joint (massless links when the model has only a payload); empty without masses.
    masses: Vec<LinkMass>,
    /// The payload's mass (kg) and centre of mass in the last joint's frame (mm): carried by
    /// the last link.
    pub payload: Option<LinkMass>,
    /// m/s², in the robot's base frame.
    gravity: Vector3<f64>,
}

impl Load {
    /// The load of `model`, whose steps end as `ends` says.
    pub fn new(ends: LinkEnds, model: &RobotModel) -> Self {
        let payload =
            model.payload.map(|p| LinkMass { mass: p.mass, com: model.payload_com().unwrap_or_default() });
        let masses = match (model.masses.is_empty(), payload) {
            (true, Some(_)) => vec![LinkMass { mass: 0.0, com: Vector3::zeros() }; model.dof()],
            _ => model.masses.clone(),
        };
        Self { ends, masses, payload, gravity: model.gravity }
    }

    /// Whether there are masses: without them every load is zero.
    pub fn has_masses(&self) -> bool {
        !self.masses.is_empty()
    }

    /// The load of one kilogram at the payload's centre of mass alone (the links massless):
    /// the derivative of every joint's load with respect to the payload's mass.
    pub fn unit_payload(&self) -> Option<Load> {
        let payload = self.payload?;
        let masses = vec![LinkMass { mass: 0.0, com: Vector3::zeros() }; self.masses.len()];
        let unit = LinkMass { mass: 1.0, com: payload.com };
        Some(Load { ends: self.ends.clone(), masses, payload: Some(unit), gravity: self.gravity })
    }

    /// Link `j`'s mass, with the payload on the last link.
    fn mass_of(&self, j: usize) -> (f64, Vector3<f64>) {
        let m = &self.masses[j];
        let (mut mass, mut moment) = (m.mass, m.com * m.mass);
        if let Some(p) = self.payload.filter(|_| j + 1 == self.masses.len()) {
            mass += p.mass;
            moment += p.com * p.mass;
        }
        (mass, moment)
    }
}

impl ChainAt {
    /// Whether the model has masses: without them every gravity load is zero.
    pub fn has_masses(&self) -> bool {
        self.load.has_masses()
    }

    /// The load gravity puts on each joint at `q`, written into `tau`: `tau_i = -dU/dq_i` for
    /// the potential energy `U(q) = -sum_j m_j g . c_j(q)` of the masses the joints move
    /// ([`crate::model::RobotModel::masses`]). A revolute joint with axis `z_i` through `p_i`
    /// carries `z_i . sum_{j >= i} (c_j - p_i) x m_j g` (N·m), a prismatic one
    /// `z_i . sum_{j >= i} m_j g` (N). Zero without masses. Allocates nothing.
    ///
    /// # Panics
    /// If `q` or `tau` has the wrong length.
    pub fn gravity_torques(&self, q: &[f64], tau: &mut [f64]) {
        self.torques_of(&self.load, q, tau);
    }

    /// The loads at `q` of `load`'s masses (this chain's or another's, such as a unit payload).
    pub(super) fn torques_of(&self, load: &Load, q: &[f64], tau: &mut [f64]) {
        assert_eq!(q.len(), self.dof, "q has one value per joint");
        assert_eq!(tau.len(), self.dof, "tau has one value per joint");
        tau.fill(0.0);
        if load.masses.is_empty() {
            return;
        }
        // First walk: gravity in the walk's frame, and every link's mass and moment.
        let arm = &self.steps[..*load.ends.links.last().expect("a chain has joints")];
        let (mut gravity, mut total_mass, mut total_moment) = (Vector3::zeros(), 0.0, Vector3::zeros());
        let mut frame = Frame::IDENTITY;
        let mut link = 0;
        for (s, resolved) in arm.iter().enumerate() {
            advance(&mut frame, resolved, q);
            if s + 1 == load.ends.base {
                gravity = frame.r * load.gravity;
            }
            while link < load.masses.len() && s + 1 == load.ends.links[link] {
                let (mass, moment) = load.mass_of(link);
                total_mass += mass;
                total_moment += frame.p * mass + frame.r * moment;
                link += 1;
            }
        }
        if load.ends.base == 0 {
            gravity = load.gravity;
        }
        // Second walk: at each joint's step, the links after it are what remains.
        let mut frame = Frame::IDENTITY;
        let mut link = 0;
        for (s, resolved) in arm.iter().enumerate() {
            if let Some(j) = resolved.step.joint {
                tau[j] = match resolved.step.motion {
                    Motion::Rotate(k) => {
                        let axis = frame.r.column(k);
                        axis.dot(&(total_moment - frame.p * total_mass).cross(&gravity)) / 1000.0
                    }
                    Motion::Translate(k) => frame.r.column(k).dot(&gravity) * total_mass,
                };
            }
            advance(&mut frame, resolved, q);
            while link < load.masses.len() && s + 1 == load.ends.links[link] {
                let (mass, moment) = load.mass_of(link);
                total_mass -= mass;
                total_moment -= frame.p * mass + frame.r * moment;
                link += 1;
            }
        }
    }
}
