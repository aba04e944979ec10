//! Observability indices of a pose set: scalar summaries of the singular values
//! `sigma_1 >= ... >= sigma_r` of the (column-scaled, or whitened) identification Jacobian of
//! `m` poses, each larger for a better set. The five of Sun and Hollerbach's comparison
//! (Y. Sun and J. M. Hollerbach, "Observability index selection for robot calibration", IEEE
//! ICRA 2008), in the forms used there.
//!
//! A singular value below [`RANK_TOLERANCE`] times the largest counts as zero: a set that
//! cannot identify every identifiable parameter scores 0 on O1, O2, O3, O4 and O5.

use super::{Design, DesignError};
use crate::estimation::{EstimationError, RANK_TOLERANCE};

/// O1 of Borm and Menq (J. H. Borm and C. H. Menq, "Determination of optimal measurement
/// configurations for robot calibration based on observability measure", Int. J. Robotics
/// Research 10(1), 1991): `O1 = (sigma_1 sigma_2 ... sigma_r)^(1/r) / sqrt(m)`, the geometric
/// mean of the singular values per pose; `m` is the number of poses. It is `det(H^T H)^(1/2r)`
/// over `sqrt(m)`: for a fixed `m`, D-optimality.
pub fn o1(s: &[f64], m: usize) -> f64 {
    if s.is_empty() || s.iter().any(|&v| v <= 0.0) {
        return 0.0;
    }
    (s.iter().map(|v| v.ln()).sum::<f64>() / s.len() as f64).exp() / (m as f64).sqrt()
}

/// O2 of Driels and Pathre (M. R. Driels and U. S. Pathre, "Significance of observation
/// strategy on the design of robot calibration experiments", J. Robotic Systems 7(2), 1990):
/// the inverse condition number `O2 = sigma_r / sigma_1`, between 0 and 1 (their condition
/// number is `1 / O2`).
pub fn o2(s: &[f64]) -> f64 {
    match (s.first(), s.last()) {
        (Some(&first), Some(&last)) if first > 0.0 => last / first,
        _ => 0.0,
    }
}

/// O3 of Nahvi, Hollerbach and Hayward (A. Nahvi, J. M. Hollerbach and V. Hayward,
/// "Calibration of a parallel robot using multiple kinematic closed loops", IEEE ICRA 1994):
/// the smallest singular value, `O3 = sigma_r`; it bounds the error of the worst-determined
/// parameter combination (E-optimality).
pub fn o3(s: &[f64]) -> f64 {
    s.last().copied().unwrap_or(0.0)
}

/// O4, the noise amplification index of Nahvi and Hollerbach (A. Nahvi and J. M. Hollerbach,
/// "The noise amplification index for optimal pose selection in robot calibration", IEEE ICRA
/// 1996): the largest singular value over the condition number, `O4 = sigma_r^2 / sigma_1`.
pub fn o4(s: &[f64]) -> f64 {
    match s.first() {
        Some(&first) if first > 0.0 => o3(s) * o3(s) / first,
        _ => 0.0,
    }
}

/// O5 of Sun and Hollerbach (2008): `O5 = 1 / (1/sigma_1 + 1/sigma_2 + ... + 1/sigma_r)`,
/// related to A-optimality (the trace of `(H^T H)^-1` is `sum 1/sigma_i^2`).
pub fn o5(s: &[f64]) -> f64 {
    if s.is_empty() || s.iter().any(|&v| v <= 0.0) {
        return 0.0;
    }
    1.0 / s.iter().map(|v| 1.0 / v).sum::<f64>()
}

/// The indices of one matrix.
#[derive(Debug, Clone, PartialEq)]
pub struct Indices {
    /// Singular values, largest first, with those below the rank tolerance set to 0.
    pub singular_values: Vec<f64>,
    /// How many are not zero.
    pub rank: usize,
    /// [`o1`].
    pub o1: f64,
    /// [`o2`].
    pub o2: f64,
    /// [`o3`].
    pub o3: f64,
    /// [`o4`].
    pub o4: f64,
    /// [`o5`].
    pub o5: f64,
    /// `log det(H^T H)`: the D-criterion ([`super::log_det`]).
    pub log_det: f64,
    /// `sigma_1 / sigma_r` (infinite when rank deficient).
    pub condition_number: f64,
}

impl Indices {
    /// The indices of the singular values `s` (largest first) of a matrix of `poses` poses
    /// and `columns` columns; missing values (fewer rows than columns) count as zeros.
    pub fn from_singular_values(s: &[f64], poses: usize, columns: usize) -> Self {
        let largest = s.first().copied().unwrap_or(0.0);
        let mut s: Vec<f64> =
            s.iter().map(|&v| if v > RANK_TOLERANCE * largest && v > 0.0 { v } else { 0.0 }).collect();
        s.resize(columns, 0.0);
        let rank = s.iter().filter(|&&v| v > 0.0).count();
        let condition_number = if rank == columns && rank > 0 { s[0] / s[rank - 1] } else { f64::INFINITY };
        Self {
            rank,
            o1: o1(&s, poses),
            o2: o2(&s),
            o3: o3(&s),
            o4: o4(&s),
            o5: o5(&s),
            log_det: super::log_det(&s),
            condition_number,
            singular_values: s,
        }
    }

    /// The value of `criterion`.
    pub fn criterion(&self, criterion: super::Criterion) -> f64 {
        use super::Criterion::*;
        match criterion {
            D => self.log_det,
            O1 => self.o1,
            O2 => self.o2,
            O3 => self.o3,
            O4 => self.o4,
            O5 => self.o5,
        }
    }

    /// The indices of the stacked matrix `a` of `poses` poses, by its SVD.
    pub fn of(a: &nalgebra::DMatrix<f64>, poses: usize) -> Result<Self, DesignError> {
        let svd = crate::linalg::svd(a).ok_or(EstimationError::NoConvergence)?;
        Ok(Self::from_singular_values(&svd.s, poses, a.ncols()))
    }
}

/// The observability of a pose set.
#[derive(Debug, Clone, PartialEq)]
pub struct Observability {
    /// Number of poses `m`.
    pub poses: usize,
    /// Parameters selected.
    pub parameters: usize,
    /// Identifiable parameters: the columns the indices are taken on.
    pub identifiable: usize,
    /// Indices of the column-scaled `H D` (what ordinary least squares sees).
    pub scaled: Indices,
    /// Indices of the whitened `S H D` (what Gauss-Markov sees), when the noise is known.
    pub whitened: Option<Indices>,
}

impl Observability {
    /// The indices the planner maximises: the whitened ones when the noise is known.
    pub fn planned(&self) -> &Indices {
        self.whitened.as_ref().unwrap_or(&self.scaled)
    }
}

impl Design {
    /// The observability indices of the poses `joints` (rad, mm for prismatic joints).
    pub fn observability(&self, joints: &[Vec<f64>]) -> Result<Observability, DesignError> {
        let scaled = Indices::of(&self.stacked(joints, false)?, joints.len())?;
        let whitened = match self.weighted() {
            true => Some(Indices::of(&self.stacked(joints, true)?, joints.len())?),
            false => None,
        };
        Ok(Observability {
            poses: joints.len(),
            parameters: self.parameters().len(),
            identifiable: self.columns.len(),
            scaled,
            whitened,
        })
    }

    /// The value of `criterion` on `joints`, on the whitened matrix when the noise is known.
    pub fn criterion(&self, joints: &[Vec<f64>], criterion: super::Criterion) -> Result<f64, DesignError> {
        let whitened = self.weighted();
        Ok(Indices::of(&self.stacked(joints, whitened)?, joints.len())?.criterion(criterion))
    }
}
