//! Joint values as the walks read them: each joint's value and, for a rotation a joint moves,
//! the sine and cosine of the step's value plus the joint's. [`JointTrig`] carries the
//! joints' own sines and cosines, computed once per pose, and turns a step by the angle-sum
//! identity (as [`Configurations`](super::Configurations) does for the simulation):
//! `sin(v + q) = sin v cos q + cos v sin q`, `cos(v + q) = cos v cos q - sin v sin q`, with
//! `sin v`, `cos v` the step's own (from [`Chain::with_errors`](super::Chain::with_errors)).
//! No trigonometry per pose and linearisation, and the same as `sin_cos(v + q)` to a few units
//! in the last place.

use super::Resolved;

/// What a walk reads of the joint values: joint `j`'s value, and the sine and cosine of
/// rotation step `resolved` moved by joint `j`.
pub(super) trait Angles: Copy {
    /// Joint `j`'s value.
    fn value(self, j: usize) -> f64;
    /// `sin(v + q_j)`, `cos(v + q_j)` of step `resolved` (value `v`), which joint `j` moves.
    fn sin_cos(self, resolved: &Resolved, j: usize) -> (f64, f64);
}

impl Angles for &[f64] {
    fn value(self, j: usize) -> f64 {
        self[j]
    }

    fn sin_cos(self, resolved: &Resolved, j: usize) -> (f64, f64) {
        (resolved.value + self[j]).sin_cos()
    }
}

/// One pose's joint values with, if given, each joint's `(sin q_j, cos q_j)`: a rotation
/// step then turns by the angle-sum identity, without trigonometry; without them, by
/// `sin_cos(v + q_j)` as the plain joint values do (bit for bit).
#[derive(Debug, Clone, Copy)]
pub(crate) struct JointTrig<'a> {
    q: &'a [f64],
    sin_cos: Option<&'a [(f64, f64)]>,
}

impl<'a> JointTrig<'a> {
    /// The joint values `q` alone: steps turn by `sin_cos(v + q_j)`.
    pub(crate) fn plain(q: &'a [f64]) -> Self {
        JointTrig { q, sin_cos: None }
    }

    /// The joint values `q` with each one's `(sin q_j, cos q_j)` ([`joint_sin_cos`]).
    ///
    /// # Panics
    /// If the lengths differ.
    pub(crate) fn with(q: &'a [f64], sin_cos: &'a [(f64, f64)]) -> Self {
        assert_eq!(q.len(), sin_cos.len(), "a sine and cosine per joint");
        JointTrig { q, sin_cos: Some(sin_cos) }
    }

    /// The joint values.
    pub(crate) fn q(self) -> &'a [f64] {
        self.q
    }
}

impl Angles for JointTrig<'_> {
    fn value(self, j: usize) -> f64 {
        self.q[j]
    }

    fn sin_cos(self, resolved: &Resolved, j: usize) -> (f64, f64) {
        match self.sin_cos {
            None => (resolved.value + self.q[j]).sin_cos(),
            Some(trig) => {
                let ((sv, cv), (sq, cq)) = (resolved.sin_cos, trig[j]);
                (sv * cq + cv * sq, cv * cq - sv * sq)
            }
        }
    }
}

/// Each pose's joints' `(sin q_j, cos q_j)`, pose after pose (`dof` a pose), for
/// [`JointTrig::with`].
pub(crate) fn joint_sin_cos(joints: &[Vec<f64>]) -> Vec<(f64, f64)> {
    use rayon::prelude::*;
    joints.par_iter().flat_map_iter(|q| q.iter().map(|q| q.sin_cos())).collect()
}
