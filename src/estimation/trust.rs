//! The trust region of the Levenberg-Marquardt refinement ([`refine`](super::refine())).
//!
//! Each linearisation is the whitened system `min |z - R x|^2` ([`super::Reduced`]), factored
//! once by the SVD of its column-scaled factor `R D = U S V^T` (the rank-revealing solve). In the
//! scaled coordinates `u = D^-1 x`, the Levenberg-Marquardt step of damping `lambda >= 0`
//!
//! ```text
//! u(lambda) = argmin |z - R D u|^2 + lambda |u|^2 = V_r diag(s_i / (s_i^2 + lambda)) c,
//! c = U_r^T z,   x(lambda) = P D u(lambda),
//! |u(lambda)|^2 = sum_i (s_i c_i / (s_i^2 + lambda))^2
//! ```
//!
//! is the Gauss-Newton step `x(0) = P D V_r S_r^-1 c` with each identifiable direction's part
//! filtered by `s_i^2 / (s_i^2 + lambda)`: every trial of a linearisation costs a `p x r` product,
//! not a factorisation. `P` is the solve's projector: a direction below the rank tolerance
//! (the gauge) is never moved, as in the Gauss-Newton step. Damping by `lambda |u|^2` in the
//! scaled coordinates is Marquardt's `lambda |a_j|^2` on the diagonal of `A^T A`.
//!
//! The damping is that of a trust region of radius `Delta` in `|u|` (Moré 1978): `lambda = 0`
//! when the Gauss-Newton step is inside (`|u(0)| <= Delta`), else the `lambda > 0` for which
//! `|u(lambda)| = Delta`. The radius is kept from step to step and moved by the gain ratio of
//! each trial, actual over predicted fall of the cost `F`:
//!
//! ```text
//! rho = (F(x) - F(x + dx)) / (F(x) - |z - R dx|^2 - rho_0^2)
//! rho < 1/4:  Delta <- |u| / 2              (the model was poor: a shorter step)
//! rho > 3/4:  Delta <- max(Delta, 2 |u|)    (the model was good: room for a longer one)
//! ```
//!
//! The radius starts infinite, so that the first trial is Gauss-Newton's, and every step is
//! Gauss-Newton's as long as those steps keep their promises.

use super::solve::Factorised;
use nalgebra::DVector;

/// Below this gain ratio the radius shrinks.
const SHRINK_BELOW: f64 = 0.25;
/// Above this gain ratio the radius grows.
const GROW_ABOVE: f64 = 0.75;

/// The singular values `s_1 >= ... >= s_r` of the identifiable directions of a linearisation's
/// column-scaled `R D` and the projected right-hand side `c = U_r^T z`: the length of every
/// Levenberg-Marquardt step, and the damping of a given length.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Spectrum {
    s: Vec<f64>,
    c: DVector<f64>,
}

impl Spectrum {
    /// The spectrum of singular values `s` (those beyond `c`'s length are the gauge's, unused)
    /// and right-hand side `c`.
    pub(crate) fn new(s: &[f64], c: DVector<f64>) -> Self {
        Self { s: s[..c.len()].to_vec(), c }
    }

    /// `s_1`: how far a scaled step of length 1 can move the whitened predictions at most.
    pub(crate) fn largest(&self) -> f64 {
        self.s.first().copied().unwrap_or(0.0)
    }

    /// `|u(lambda)|` and its derivative in `lambda`,
    /// `-sum_i (s_i c_i)^2 / (s_i^2 + lambda)^3 / |u(lambda)|`.
    fn length_and_slope(&self, lambda: f64) -> (f64, f64) {
        let (mut squared, mut slope) = (0.0, 0.0);
        for (s, c) in self.s.iter().zip(self.c.iter()) {
            let (a, d) = (s * c, s * s + lambda);
            squared += (a / d).powi(2);
            slope -= a * a / (d * d * d);
        }
        let length = squared.sqrt();
        (length, if length > 0.0 { slope / length } else { 0.0 })
    }

    /// `|u(lambda)|`, the step's length in the scaled coordinates.
    pub(crate) fn length(&self, lambda: f64) -> f64 {
        self.length_and_slope(lambda).0
    }

    /// The filtered right-hand side `c_i s_i^2 / (s_i^2 + lambda)`: with
    /// [`Factorised::filtered`], the step `x(lambda)`. `lambda = 0` leaves `c` as it is.
    fn filter(&self, lambda: f64) -> DVector<f64> {
        if lambda == 0.0 {
            return self.c.clone();
        }
        DVector::from_iterator(
            self.c.len(),
            self.s.iter().zip(self.c.iter()).map(|(s, c)| c * s * s / (s * s + lambda)),
        )
    }

    /// The damping whose step has length `radius`: 0 if the Gauss-Newton step is no longer,
    /// else the root of `1 / |u(lambda)| = 1 / radius` by Newton's method (Hebden's, on the
    /// function that is nearly linear in `lambda`),
    /// `lambda <- lambda - (|u| - Delta) |u| / (Delta d|u|/dlambda)`, kept inside the bracket
    /// `[0, |S c| / Delta]` (`|u(lambda)| <= |S c| / lambda`) by bisection, to `1e-9` of the radius.
    pub(crate) fn damping_for(&self, radius: f64) -> f64 {
        let (full, _) = self.length_and_slope(0.0);
        if full <= radius {
            return 0.0;
        }
        let sc = self.s.iter().zip(self.c.iter()).map(|(s, c)| (s * c).powi(2)).sum::<f64>().sqrt();
        let (mut low, mut high, mut lambda) = (0.0, sc / radius, 0.0);
        for _ in 0..200 {
            let (length, slope) = self.length_and_slope(lambda);
            if (length - radius).abs() <= 1e-9 * radius {
                break;
            }
            if length > radius {
                low = lambda;
            } else {
                high = lambda;
            }
            let newton = lambda - (length - radius) * length / (radius * slope);
            lambda = if newton > low && newton < high { newton } else { 0.5 * (low + high) };
        }
        lambda
    }
}

/// The Levenberg-Marquardt steps of one linearisation: its factorisation and its spectrum.
pub(crate) struct Steps<'f> {
    factorised: &'f Factorised,
    pub(crate) spectrum: Spectrum,
}

impl<'f> Steps<'f> {
    /// The steps of the system `system` factored as `factorised`.
    pub(crate) fn new(factorised: &'f Factorised, system: &super::Reduced) -> Self {
        let c = factorised.projected(system);
        let spectrum = Spectrum::new(&factorised.diagnostics.singular_values, c);
        Self { factorised, spectrum }
    }

    /// `x(lambda) = P D V_r diag(s_i / (s_i^2 + lambda)) c`; `x(0)` is the Gauss-Newton step,
    /// to the bit [`Factorised::solve`]'s.
    pub(crate) fn step(&self, lambda: f64) -> DVector<f64> {
        self.factorised.filtered(&self.spectrum.filter(lambda))
    }
}

/// The trust region: its radius `Delta` in the scaled coordinates, kept across linearisations.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Region {
    radius: f64,
}

impl Default for Region {
    /// Infinite: the first trial is the Gauss-Newton step.
    fn default() -> Self {
        Self { radius: f64::INFINITY }
    }
}

impl Region {
    /// The damping of the next trial of `spectrum`: 0 while the Gauss-Newton step fits.
    pub(crate) fn damping(&self, spectrum: &Spectrum) -> f64 {
        spectrum.damping_for(self.radius)
    }

    /// The radius after a trial of scaled length `length` whose gain ratio was `gain`, as the
    /// [module documentation](self) says.
    pub(crate) fn update(&mut self, gain: f64, length: f64) {
        if gain < SHRINK_BELOW || gain.is_nan() {
            self.radius = length / 2.0;
        } else if gain > GROW_ABOVE {
            self.radius = self.radius.max(2.0 * length);
        }
    }

    /// Whether no step inside the region can move a whitened prediction by more than
    /// `tolerance`: `s_1 Delta <= tolerance` (`|R D u| <= s_1 |u|`). A region made NaN by a
    /// NaN trial (a system that is not finite) has collapsed too: the trials stop, never spin.
    pub(crate) fn collapsed(&self, spectrum: &Spectrum, tolerance: f64) -> bool {
        let reach = spectrum.largest() * self.radius;
        reach.is_nan() || reach <= tolerance
    }
}

/// The gain ratio of a trial: the actual fall of the cost over the fall the linearised system
/// predicted. A fall predicted as nothing (to rounding) gains 1 if the cost did not rise.
pub(crate) fn gain(cost: f64, cost_after: f64, predicted: f64) -> f64 {
    let (actual, promised) = (cost - cost_after, cost - predicted);
    if promised > 0.0 {
        actual / promised
    } else if actual >= 0.0 {
        1.0
    } else {
        0.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The damping found gives the asked length, the length falls with the damping, and its
    /// slope is the finite difference's.
    #[test]
    fn the_damping_of_a_radius_gives_a_step_of_that_length() {
        let spectrum = Spectrum::new(&[3.0, 1.0, 1e-3, 1e-14], DVector::from_vec(vec![0.5, -2.0, 1e-3]));
        let full = spectrum.length(0.0);
        assert!((full - (0.5f64 / 3.0).hypot(2.0).hypot(1.0)).abs() < 1e-12, "{full}");
        assert_eq!(spectrum.damping_for(full * 1.01), 0.0, "the Gauss-Newton step fits");
        for radius in [0.9 * full, 0.5, 1e-3, 1e-9] {
            let lambda = spectrum.damping_for(radius);
            assert!(lambda > 0.0);
            assert!((spectrum.length(lambda) - radius).abs() <= 1e-9 * radius, "{radius}: {lambda}");
        }
        for lambda in [1e-6, 1e-2, 1.0, 10.0] {
            let (length, slope) = spectrum.length_and_slope(lambda);
            let h = 1e-6 * lambda;
            let difference = (spectrum.length(lambda + h) - spectrum.length(lambda - h)) / (2.0 * h);
            assert!((slope - difference).abs() < 1e-6 * difference.abs(), "{slope} against {difference}");
            assert!(spectrum.length(2.0 * lambda) < length);
        }
    }

    /// The radius shrinks to half a poor step, grows to twice a good one, and stays for one in
    /// between; it starts infinite.
    #[test]
    fn the_radius_follows_the_gain() {
        let mut region = Region::default();
        assert!(region.radius.is_infinite());
        region.update(0.5, 8.0);
        assert!(region.radius.is_infinite(), "a fair step keeps the radius");
        region.update(-3.0, 8.0);
        assert_eq!(region.radius, 4.0);
        region.update(0.9, 3.0);
        assert_eq!(region.radius, 6.0);
        region.update(0.9, 1.0);
        assert_eq!(region.radius, 6.0, "a good short step does not shrink it");
        region.update(f64::NAN, 1.0);
        assert_eq!(region.radius, 0.5, "a step to where the cost is not a number is a poor one");
        assert_eq!(gain(10.0, 4.0, 2.0), 0.75);
        assert_eq!(gain(10.0, 10.0, 10.0), 1.0);
        assert_eq!(gain(10.0, 11.0, 10.0), 0.0);
    }

    /// A region made NaN (a NaN step's length, a system that is not finite) has collapsed: the
    /// trials stop instead of spinning (a NaN tool point once hung a calibration).
    #[test]
    fn a_nan_region_has_collapsed() {
        let spectrum = Spectrum::new(&[3.0, 1.0], DVector::from_vec(vec![0.5, -2.0]));
        let mut region = Region::default();
        assert!(!region.collapsed(&spectrum, 1e-9));
        region.update(f64::NAN, f64::NAN);
        assert!(region.radius.is_nan() && region.collapsed(&spectrum, 1e-9));
        let nan = Spectrum::new(&[f64::NAN, 1.0], DVector::from_vec(vec![0.5, -2.0]));
        assert!(Region::default().collapsed(&nan, 1e-9));
    }
}
