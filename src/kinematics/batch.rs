//! Forward kinematics of many models over one fixed set of joint configurations, in blocks of
//! [`BATCH`] configurations laid out as structure of arrays, so that the compiler vectorises
//! the walk along the chain.
//!
//! What does not change between models is computed once, in [`Configurations::new`]: each
//! configuration's joint values and the sine and cosine of each revolute joint's. A model's
//! revolute joint step of value `v` (nominal plus offset error) then turns by `v + q`
//! through the angle-sum identity, `sin(v + q) = sin v cos q + cos v sin q` and
//! `cos(v + q) = cos v cos q - sin v sin q`, with `sin v`, `cos v` once per model: no
//! trigonometry per configuration. This agrees with [`ChainAt::pose`], which takes
//! `sin_cos(v + q)`, to the last digits (a few units in the last place of each sine and
//! cosine), not bit for bit.
//!
//! The steps before the first joint (the base) are the same at every configuration: they are
//! walked once per block, and the block starts from the frame they reach.

use super::{ChainAt, Frame, Motion, Resolved};
use nalgebra::{Matrix3, Rotation3, UnitQuaternion, Vector3};

/// Configurations per block.
pub const BATCH: usize = 64;

/// One block of values, one per configuration.
type Lane = [f64; BATCH];

/// Joint configurations prepared for the forward kinematics of many models: their joint
/// values, and each joint's sine and cosine, block by block ([`BATCH`] configurations a
/// block, the last one padded with zeros). A model's revolute joint of value `v` then turns
/// by `sin(v + q) = sin v cos q + cos v sin q`, `cos(v + q) = cos v cos q - sin v sin q`: no
/// trigonometry per configuration, and the same as [`ChainAt::pose`]'s `sin_cos(v + q)` to a
/// few units in the last place.
#[derive(Debug, Clone)]
pub struct Configurations {
    len: usize,
    dof: usize,
    /// Per block, per joint: the joint values.
    q: Vec<Lane>,
    /// Per block, per joint: `sin q`.
    sin: Vec<Lane>,
    /// Per block, per joint: `cos q`.
    cos: Vec<Lane>,
}

impl Configurations {
    /// Prepare `configurations`, each of `dof` joint values.
    ///
    /// # Panics
    /// If a configuration does not have `dof` values.
    pub fn new(configurations: &[Vec<f64>], dof: usize) -> Self {
        let blocks = configurations.len().div_ceil(BATCH);
        let mut q = vec![[0.0; BATCH]; blocks * dof];
        for (i, config) in configurations.iter().enumerate() {
            assert_eq!(config.len(), dof, "a configuration has one value per joint");
            for (j, &value) in config.iter().enumerate() {
                q[(i / BATCH) * dof + j][i % BATCH] = value;
            }
        }
        let (mut sin, mut cos) = (q.clone(), q.clone());
        for ((q, s), c) in q.iter().zip(&mut sin).zip(&mut cos) {
            for ((&q, s), c) in q.iter().zip(s.iter_mut()).zip(c.iter_mut()) {
                (*s, *c) = q.sin_cos();
            }
        }
        Self { len: configurations.len(), dof, q, sin, cos }
    }

    /// Number of configurations.
    pub fn len(&self) -> usize {
        self.len
    }

    /// Whether there are none.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// Number of blocks.
    pub fn blocks(&self) -> usize {
        self.q.len().checked_div(self.dof).unwrap_or(0)
    }

    /// The configurations of block `b` that are real (not padding).
    pub fn block_len(&self, b: usize) -> usize {
        self.len.saturating_sub(b * BATCH).min(BATCH)
    }

    /// Configuration `i` of block `b`, into `q`.
    fn configuration(&self, b: usize, i: usize, q: &mut [f64]) {
        for (j, q) in q.iter_mut().enumerate() {
            *q = self.q[b * self.dof + j][i];
        }
    }
}

/// The end frames of one block of configurations: rotation (column-major: `r[3 * column +
/// row]`) and position, one lane per configuration.
#[derive(Debug, Clone)]
pub struct Frames {
    r: [Lane; 9],
    p: [Lane; 3],
}

impl Default for Frames {
    fn default() -> Self {
        Self { r: [[0.0; BATCH]; 9], p: [[0.0; BATCH]; 3] }
    }
}

impl Frames {
    /// Position (mm) of configuration `i` of the block.
    pub fn position(&self, i: usize) -> Vector3<f64> {
        Vector3::new(self.p[0][i], self.p[1][i], self.p[2][i])
    }

    /// Orientation of configuration `i` of the block, as [`ChainAt::pose`] gives it.
    pub fn rotation(&self, i: usize) -> UnitQuaternion<f64> {
        let r = Matrix3::from_fn(|row, column| self.r[3 * column + row][i]);
        UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(r))
    }

    /// The distance between the positions of `self` and `other`, configuration by
    /// configuration, into `out`.
    pub fn distances(&self, other: &Frames, out: &mut [f64; BATCH]) {
        for (i, out) in out.iter_mut().enumerate() {
            let dx = self.p[0][i] - other.p[0][i];
            let dy = self.p[1][i] - other.p[1][i];
            let dz = self.p[2][i] - other.p[2][i];
            *out = (dx * dx + dy * dy + dz * dz).sqrt();
        }
    }

    fn fill(&mut self, frame: &Frame) {
        for (lane, &value) in self.r.iter_mut().zip(frame.r.iter()) {
            lane.fill(value);
        }
        for (lane, &value) in self.p.iter_mut().zip(frame.p.iter()) {
            lane.fill(value);
        }
    }

    /// `p += r[:, k] * (value + q)`, per lane (`q` zero for a step no joint moves).
    fn translate(&mut self, k: usize, value: f64, q: Option<&Lane>) {
        for (p, r) in self.p.iter_mut().zip(&self.r[3 * k..3 * k + 3]) {
            match q {
                Some(q) => (0..BATCH).for_each(|i| p[i] += r[i] * (value + q[i])),
                None => (0..BATCH).for_each(|i| p[i] += r[i] * value),
            }
        }
    }

    /// The lanes of row `row` of columns `i` and `j` (`i != j`) of the rotation.
    fn columns(&mut self, i: usize, j: usize, row: usize) -> (&mut Lane, &mut Lane) {
        let (a, b) = (3 * i + row, 3 * j + row);
        if a < b {
            let (low, high) = self.r.split_at_mut(b);
            (&mut low[a], &mut high[0])
        } else {
            let (low, high) = self.r.split_at_mut(a);
            (&mut high[0], &mut low[b])
        }
    }

    /// Post-multiply by the rotation about axis `k` of sine `s` and cosine `c` per lane.
    fn rotate(&mut self, k: usize, s: &Lane, c: &Lane) {
        let (i, j) = ((k + 1) % 3, (k + 2) % 3);
        for row in 0..3 {
            let (ci, cj) = self.columns(i, j, row);
            for l in 0..BATCH {
                let (x, y) = (ci[l], cj[l]);
                ci[l] = x * c[l] + y * s[l];
                cj[l] = y * c[l] - x * s[l];
            }
        }
    }

    /// Post-multiply by the constant rotation about axis `k` of sine `s` and cosine `c`.
    fn rotate_by(&mut self, k: usize, s: f64, c: f64) {
        let (i, j) = ((k + 1) % 3, (k + 2) % 3);
        for row in 0..3 {
            let (ci, cj) = self.columns(i, j, row);
            for l in 0..BATCH {
                let (x, y) = (ci[l], cj[l]);
                ci[l] = x * c + y * s;
                cj[l] = y * c - x * s;
            }
        }
    }
}

impl ChainAt {
    /// The end frames at the configurations of block `block` of `configurations`, into
    /// `frames`: [`ChainAt::pose`] at each, up to the last digits (a revolute joint turns by
    /// the angle-sum identity: see [`Configurations`]). A chain whose joints deflect under gravity takes its
    /// configurations one by one through [`ChainAt::pose`]'s own walk.
    ///
    /// # Panics
    /// If the configurations are not of this chain's joints.
    pub fn frames(&self, configurations: &Configurations, block: usize, frames: &mut Frames) {
        assert_eq!(configurations.dof, self.dof, "configurations of this chain's joints");
        if self.deflects() {
            return self.frames_one_by_one(configurations, block, frames);
        }
        let at = |lanes: &[Lane], j: usize| lanes[block * self.dof + j];
        // The steps before the first joint are the same everywhere.
        let first = self.steps.iter().position(|s| s.step.joint.is_some()).unwrap_or(self.steps.len());
        frames.fill(&super::walk(
            &self.steps[..first],
            &[0.0; super::MAX_JOINTS][..self.dof],
            Frame::IDENTITY,
        ));
        for resolved in &self.steps[first..] {
            let Resolved { step, value, sin_cos: (sv, cv) } = *resolved;
            if step.joint.is_none() && value == 0.0 {
                // No motion: adding zeros changes no value (but a zero's sign).
                continue;
            }
            match (step.motion, step.joint) {
                (Motion::Translate(k), joint) => {
                    frames.translate(k, value, joint.map(|j| &configurations.q[block * self.dof + j]))
                }
                (Motion::Rotate(k), None) => frames.rotate_by(k, sv, cv),
                (Motion::Rotate(k), Some(j)) => {
                    let (sq, cq) = (at(&configurations.sin, j), at(&configurations.cos, j));
                    let (mut s, mut c) = ([0.0; BATCH], [0.0; BATCH]);
                    for l in 0..BATCH {
                        s[l] = sv * cq[l] + cv * sq[l];
                        c[l] = cv * cq[l] - sv * sq[l];
                    }
                    frames.rotate(k, &s, &c);
                }
            }
        }
    }

    /// [`ChainAt::frames`] through the scalar walk, configuration by configuration.
    fn frames_one_by_one(&self, configurations: &Configurations, block: usize, frames: &mut Frames) {
        let mut q = [0.0; super::MAX_JOINTS];
        for i in 0..configurations.block_len(block) {
            configurations.configuration(block, i, &mut q[..self.dof]);
            let end = self.at_reached(&q[..self.dof], |q| super::walk(&self.steps, q, Frame::IDENTITY));
            for (lane, &value) in frames.r.iter_mut().zip(end.r.iter()) {
                lane[i] = value;
            }
            for (lane, &value) in frames.p.iter_mut().zip(end.p.iter()) {
                lane[i] = value;
            }
        }
    }
}
