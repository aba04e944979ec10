//! Measuring devices and the covariance `Sigma_m,k` of the point they measure.
//!
//! The paper's simulation measures with a constant `sigma_me` everywhere, and its conclusion
//! expects devices whose noise varies over the workspace (theodolites) to profit more from
//! Gauss-Markov weighting than those with constant noise (coordinate measuring machines). A
//! [`Device`] gives the full 3 x 3 covariance of a measured point from the device's own
//! reading noise, propagated to the point to first order:
//!
//! `Sigma_m(p) = T(p) Sigma_readings(p) T(p)^T`, `T = d(point)/d(readings)`,
//!
//! with the readings (ranges, angles) and their inverse, [`Device::observe`] and
//! [`Device::locate`], exposed so that the propagation can be checked by finite differences
//! and by Monte Carlo. Positions are in the device frame (the robot's base frame in a study),
//! mm; angles in rad; the z axis is vertical for the devices that measure angles.

use crate::error::FieldError;
use nalgebra::{DMatrix, DVector, Matrix3, Vector3};

/// Why a device cannot give a covariance.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum DeviceError {
    /// A device parameter out of range (the field, e.g. `sigma_r_mm`, and what was expected).
    #[error("device {0}")]
    Invalid(FieldError),
    /// The point is where the device cannot locate it (at a station, on the theodolites'
    /// baseline): its covariance is infinite.
    #[error("the device cannot locate the point ({x:.1}, {y:.1}, {z:.1}) mm: {why}")]
    Singular {
        /// The point, x (mm).
        x: f64,
        /// y (mm).
        y: f64,
        /// z (mm).
        z: f64,
        /// Why.
        why: &'static str,
    },
}

/// A measuring device: how noisy the point it measures is, as a function of where it is.
#[derive(Debug, Clone, PartialEq)]
pub enum Device {
    /// A coordinate measuring machine: isotropic noise, the same everywhere,
    /// `Sigma_m = sigma^2 I` (the paper's Eq. 16).
    Cmm {
        /// Standard deviation of each coordinate (mm).
        sigma: f64,
    },
    /// A laser tracker at `position` measuring range `r` and two angles, azimuth `az` about
    /// the vertical and elevation `el` above the horizontal. The range noise grows with the
    /// range, `sigma_r(r) = sigma_r + k r`; both angles have `sigma_angle`. With `u` the line
    /// of sight and `e_az`, `e_el` the unit directions in which azimuth and elevation move the
    /// point, `p = c + r (cos el cos az, cos el sin az, sin el)` gives
    ///
    /// `Sigma_m = sigma_r(r)^2 u u^T + (r cos(el) sigma_angle)^2 e_az e_az^T
    ///          + (r sigma_angle)^2 e_el e_el^T`:
    ///
    /// anisotropic (fine across the line of sight near the tracker, coarse along it) and
    /// distance dependent.
    LaserTracker {
        /// The tracker's head (mm).
        position: Vector3<f64>,
        /// Constant part of the range noise (mm).
        sigma_r: f64,
        /// Range noise per unit range (dimensionless; 1e-6 is 1 um/m).
        k: f64,
        /// Standard deviation of each angle (rad).
        sigma_angle: f64,
    },
    /// Two theodolites at `stations`, each reading the horizontal angle (azimuth about the
    /// vertical) and the vertical angle (elevation) of the point. The point is the Gauss-Markov
    /// intersection of the four angles, `p = argmin sum_i (a_i(p) - a_i)^2 / sigma_i^2`, and
    /// its covariance is `(G^T Sigma_a^-1 G)^-1` with `G = d(angles)/d(point)` (4 x 3): large
    /// far from the stations and where the two lines of sight meet at a shallow angle.
    Theodolites {
        /// The two stations (mm).
        stations: [Vector3<f64>; 2],
        /// Standard deviation of a horizontal angle (rad).
        sigma_horizontal: f64,
        /// Standard deviation of a vertical angle (rad).
        sigma_vertical: f64,
    },
}

impl Device {
    /// The kind's name in files: `cmm`, `laser-tracker`, `theodolites`.
    pub fn kind(&self) -> &'static str {
        match self {
            Self::Cmm { .. } => "cmm",
            Self::LaserTracker { .. } => "laser-tracker",
            Self::Theodolites { .. } => "theodolites",
        }
    }

    /// The orientation standard deviation (rad) of a frame this device measures (a 6-DOF
    /// probe), when a noise file does not give `sigma_orientation_deg`: typical figures, a
    /// laser tracker's 6-DOF probe 0.01 deg, a CMM (a frame from three spheres) 0.001 deg,
    /// theodolites (from three targets) 0.002 deg.
    pub fn sigma_orientation(&self) -> f64 {
        let degrees = match self {
            Self::Cmm { .. } => 0.001,
            Self::LaserTracker { .. } => 0.01,
            Self::Theodolites { .. } => 0.002,
        };
        f64::to_radians(degrees)
    }

    /// The device in words, in the units of files: `theodolites at (1500, -1000, 300) and
    /// (1500, 1000, 300) mm, angles 2.5 / 2.5 arcsec`.
    pub fn describe(&self) -> String {
        let arcsec = |a: f64| a.to_degrees() * 3600.0;
        let at = |p: &Vector3<f64>| format!("({}, {}, {})", p.x, p.y, p.z);
        match self {
            Self::Cmm { sigma } => format!("cmm, sigma {sigma} mm"),
            Self::LaserTracker { position, sigma_r, k, sigma_angle } => format!(
                "laser tracker at {} mm, range sigma {sigma_r} mm + {} ppm, angles {:.3} arcsec",
                at(position),
                k * 1e6,
                arcsec(*sigma_angle)
            ),
            Self::Theodolites { stations, sigma_horizontal, sigma_vertical } => format!(
                "theodolites at {} and {} mm, angles {:.3} / {:.3} arcsec (horizontal / vertical)",
                at(&stations[0]),
                at(&stations[1]),
                arcsec(*sigma_horizontal),
                arcsec(*sigma_vertical)
            ),
        }
    }

    /// Check that every parameter is finite, sigmas `>= 0` (theodolites' `> 0`), the stations apart.
    pub fn validate(&self) -> Result<(), DeviceError> {
        let check = |field: &'static str, v: f64| {
            if v.is_finite() && v >= 0.0 {
                Ok(())
            } else {
                Err(DeviceError::Invalid(FieldError::new(field, format!("a finite value >= 0, found {v}"))))
            }
        };
        let finite = |field: &'static str, p: &Vector3<f64>| {
            if p.iter().all(|v| v.is_finite()) {
                Ok(())
            } else {
                Err(DeviceError::Invalid(FieldError::new(field, format!("finite coordinates, found {p:?}"))))
            }
        };
        match self {
            Self::Cmm { sigma } => check("sigma_mm", *sigma),
            Self::LaserTracker { position, sigma_r, k, sigma_angle } => {
                finite("position_mm", position)?;
                check("sigma_r_mm", *sigma_r)?;
                check("k_ppm", *k)?;
                check("sigma_angle_arcsec", *sigma_angle)
            }
            Self::Theodolites { stations, sigma_horizontal, sigma_vertical } => {
                finite("stations_mm", &stations[0])?;
                finite("stations_mm", &stations[1])?;
                if (stations[0] - stations[1]).norm() == 0.0 {
                    return Err(DeviceError::Invalid(FieldError::new(
                        "stations_mm",
                        "two distinct stations (a baseline)",
                    )));
                }
                for (field, s) in [
                    ("sigma_horizontal_arcsec", *sigma_horizontal),
                    ("sigma_vertical_arcsec", *sigma_vertical),
                ] {
                    if !(s.is_finite() && s > 0.0) {
                        return Err(DeviceError::Invalid(FieldError::new(
                            field,
                            format!("a finite value > 0, found {s}"),
                        )));
                    }
                }
                Ok(())
            }
        }
    }

    /// The device's readings of `point`: a CMM's x, y, z (mm); a tracker's range (mm), azimuth
    /// and elevation (rad); the theodolites' azimuth and elevation from station 1, then from
    /// station 2 (rad).
    pub fn observe(&self, point: &Vector3<f64>) -> DVector<f64> {
        match self {
            Self::Cmm { .. } => DVector::from_column_slice(point.as_slice()),
            Self::LaserTracker { position, .. } => {
                let (r, az, el) = spherical(&(point - position));
                DVector::from_vec(vec![r, az, el])
            }
            Self::Theodolites { stations, .. } => {
                let (_, az1, el1) = spherical(&(point - stations[0]));
                let (_, az2, el2) = spherical(&(point - stations[1]));
                DVector::from_vec(vec![az1, el1, az2, el2])
            }
        }
    }

    /// The standard deviation of each reading of [`Device::observe`] at `point` (independent).
    pub fn reading_sigmas(&self, point: &Vector3<f64>) -> DVector<f64> {
        match self {
            Self::Cmm { sigma } => DVector::from_element(3, *sigma),
            Self::LaserTracker { position, sigma_r, k, sigma_angle } => {
                let r = (point - position).norm();
                DVector::from_vec(vec![sigma_r + k * r, *sigma_angle, *sigma_angle])
            }
            Self::Theodolites { sigma_horizontal: h, sigma_vertical: v, .. } => {
                DVector::from_vec(vec![*h, *v, *h, *v])
            }
        }
    }

    /// The point from the readings: the inverse of [`Device::observe`] (for the theodolites,
    /// the Gauss-Markov intersection of the four angles by Gauss-Newton from the midpoint of
    /// the common perpendicular of the two lines of sight).
    pub fn locate(&self, readings: &DVector<f64>) -> Result<Vector3<f64>, DeviceError> {
        match self {
            Self::Cmm { .. } => Ok(Vector3::new(readings[0], readings[1], readings[2])),
            Self::LaserTracker { position, .. } => {
                Ok(position + direction(readings[1], readings[2]) * readings[0])
            }
            Self::Theodolites { stations, .. } => {
                let (d1, d2) = (direction(readings[0], readings[1]), direction(readings[2], readings[3]));
                let mut p = midpoint(&stations[0], &d1, &stations[1], &d2)
                    .ok_or_else(|| singular(&stations[0], "the lines of sight are parallel"))?;
                let w = self.reading_sigmas(&p).map(|s| 1.0 / s);
                for _ in 0..20 {
                    let g = self.angle_jacobian(&p)?;
                    let mut residual = readings - self.observe(&p);
                    for i in [0, 2] {
                        residual[i] = wrap(residual[i]);
                    }
                    let a = DMatrix::from_fn(4, 3, |i, j| g[(i, j)] * w[i]);
                    let b = residual.component_mul(&w);
                    let step = (a.transpose() * &a)
                        .try_inverse()
                        .ok_or_else(|| singular(&p, "the lines of sight are parallel"))?
                        * (a.transpose() * b);
                    p += Vector3::new(step[0], step[1], step[2]);
                    if step.norm() < 1e-12 * (1.0 + p.norm()) {
                        break;
                    }
                }
                Ok(p)
            }
        }
    }

    /// `Sigma_m` (3 x 3, mm²) of a point measured at `point`; see [`Device`] for each model.
    pub fn covariance(&self, point: &Vector3<f64>) -> Result<Matrix3<f64>, DeviceError> {
        match self {
            Self::Cmm { sigma } => Ok(Matrix3::identity() * (sigma * sigma)),
            Self::LaserTracker { position, sigma_r, k, sigma_angle } => {
                let (r, az, el) = spherical(&(point - position));
                if r == 0.0 {
                    return Err(singular(point, "it is at the tracker"));
                }
                let u = direction(az, el);
                let e_az = Vector3::new(-az.sin(), az.cos(), 0.0);
                let e_el = Vector3::new(-el.sin() * az.cos(), -el.sin() * az.sin(), el.cos());
                let (s_r, s_az, s_el) = (sigma_r + k * r, r * el.cos() * sigma_angle, r * sigma_angle);
                Ok(u * u.transpose() * s_r * s_r
                    + e_az * e_az.transpose() * s_az * s_az
                    + e_el * e_el.transpose() * s_el * s_el)
            }
            Self::Theodolites { sigma_horizontal: h, sigma_vertical: v, .. } => {
                let g = self.angle_jacobian(point)?;
                let weights = [h, v, h, v].map(|s| 1.0 / (s * s));
                let w = DMatrix::from_diagonal(&DVector::from_fn(4, |i, _| weights[i]));
                let info: Matrix3<f64> = (g.transpose() * w * &g).fixed_view::<3, 3>(0, 0).into_owned();
                // The information is singular on the baseline; nearly so close to it.
                let eig = info.symmetric_eigenvalues();
                if eig.min() <= 1e-12 * eig.max() {
                    return Err(singular(point, "it lies on the baseline of the two stations"));
                }
                info.try_inverse()
                    .ok_or_else(|| singular(point, "it lies on the baseline of the two stations"))
            }
        }
    }

    /// `G = d(angles)/d(point)` of the theodolites (4 x 3, rad/mm).
    fn angle_jacobian(&self, point: &Vector3<f64>) -> Result<DMatrix<f64>, DeviceError> {
        let Self::Theodolites { stations, .. } = self else {
            return Err(DeviceError::Invalid(FieldError::new("kind", "theodolites")));
        };
        let mut g = DMatrix::zeros(4, 3);
        for (i, station) in stations.iter().enumerate() {
            let d = point - station;
            let rho2 = d.x * d.x + d.y * d.y;
            let (rho, r2) = (rho2.sqrt(), d.norm_squared());
            if rho == 0.0 {
                return Err(singular(point, "it is vertically above or below a station"));
            }
            // az = atan2(dy, dx), el = atan2(dz, rho).
            g.row_mut(2 * i).copy_from_slice(&[-d.y / rho2, d.x / rho2, 0.0]);
            g.row_mut(2 * i + 1).copy_from_slice(&[
                -d.z * d.x / (rho * r2),
                -d.z * d.y / (rho * r2),
                rho / r2,
            ]);
        }
        Ok(g)
    }
}

fn singular(p: &Vector3<f64>, why: &'static str) -> DeviceError {
    DeviceError::Singular { x: p.x, y: p.y, z: p.z, why }
}

/// Range, azimuth about z and elevation above the xy plane of `d`.
fn spherical(d: &Vector3<f64>) -> (f64, f64, f64) {
    (d.norm(), d.y.atan2(d.x), d.z.atan2((d.x * d.x + d.y * d.y).sqrt()))
}

/// The unit vector at azimuth `az` and elevation `el`.
fn direction(az: f64, el: f64) -> Vector3<f64> {
    Vector3::new(el.cos() * az.cos(), el.cos() * az.sin(), el.sin())
}

/// An angle difference into [-pi, pi).
fn wrap(a: f64) -> f64 {
    let t = std::f64::consts::TAU;
    a - t * ((a + std::f64::consts::PI) / t).floor()
}

/// The midpoint of the common perpendicular of the lines `a + s u` and `b + t v`.
fn midpoint(a: &Vector3<f64>, u: &Vector3<f64>, b: &Vector3<f64>, v: &Vector3<f64>) -> Option<Vector3<f64>> {
    let w = a - b;
    let (uu, uv, vv, uw, vw) = (u.dot(u), u.dot(v), v.dot(v), u.dot(&w), v.dot(&w));
    let det = uu * vv - uv * uv;
    if det <= 1e-15 {
        return None;
    }
    let s = (uv * vw - vv * uw) / det;
    let t = (uu * vw - uv * uw) / det;
    Some((a + u * s + b + v * t) / 2.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn wrap_and_round_trip() {
        assert!((wrap(3.0 * std::f64::consts::PI) + std::f64::consts::PI).abs() < 1e-12);
        assert!((wrap(0.5 - 4.0 * std::f64::consts::PI) - 0.5).abs() < 1e-12);
        let p = Vector3::new(800.0, -300.0, 400.0);
        let tracker = Device::LaserTracker {
            position: Vector3::new(-2000.0, 500.0, 0.0),
            sigma_r: 0.01,
            k: 2e-6,
            sigma_angle: 1e-5,
        };
        let theodolites = Device::Theodolites {
            stations: [Vector3::new(-1500.0, -1500.0, 0.0), Vector3::new(-1500.0, 1500.0, 0.0)],
            sigma_horizontal: 2.5e-6,
            sigma_vertical: 2.5e-6,
        };
        for device in [tracker, theodolites, Device::Cmm { sigma: 0.01 }] {
            let back = device.locate(&device.observe(&p)).unwrap();
            assert!((back - p).norm() < 1e-8, "{}: {back:?}", device.kind());
        }
    }
}
