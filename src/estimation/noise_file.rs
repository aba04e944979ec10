//! The noise file (TOML): joint noise and measurement noise as data, in the units of files.
//!
//! ```toml
//! joint_sigma = [0.007, 0.007, 0.007, 0.002, 0.002, 0.002]  # deg (mm for prismatic joints)
//! # joint_covariance = [[...], ...]  # instead: the full Sigma_q, deg² (mm², deg mm)
//! sigma_me_mm = 0.01                 # isotropic measurement noise, mm (added to the device's)
//! sigma_orientation_deg = 0.0        # orientation measurement noise, for probes
//!
//! [device]                           # optional: the measuring device's noise model
//! kind = "laser-tracker"             # or "cmm", "theodolites"
//! position_mm = [2500.0, 0.0, 0.0]
//! sigma_r_mm = 0.005
//! k_ppm = 2.0
//! sigma_angle_arcsec = 1.0
//! ```
//!
//! See `docs/formats.md` for every field. `robocal repeatability` writes this file;
//! `robocal calibrate --noise` and `robocal simulate --noise` read it.

use super::device::Device;
use super::prior::PriorEntry;
use crate::error::FieldError;
use crate::limits::{MAX_ANGLE_DEG, MAX_LENGTH_MM, check_magnitude};
use crate::model::{JointKind, RobotModel};
use nalgebra::{DMatrix, Matrix3, Vector3};
use serde::Deserialize;
use std::fmt::Write;

/// Arcseconds in a radian.
const ARCSEC: f64 = std::f64::consts::PI / (180.0 * 3600.0);

/// Why a noise file (or a study's noise section) could not be used.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum NoiseFileError {
    /// Not valid TOML, or missing, misspelled or mistyped fields (the source names the line).
    #[error("the noise file has a mistake")]
    Syntax(#[source] toml::de::Error),
    /// A field with a value that makes no noise model.
    #[error(transparent)]
    Invalid(#[from] FieldError),
}

/// The `[device]` table of a noise file or of a study's `[noise]` section.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(tag = "kind", rename_all = "kebab-case", deny_unknown_fields)]
pub(crate) enum DeviceTable {
    Cmm {
        sigma_mm: f64,
    },
    LaserTracker {
        #[serde(deserialize_with = "crate::limits::exactly")]
        position_mm: [f64; 3],
        sigma_r_mm: f64,
        #[serde(default)]
        k_ppm: f64,
        sigma_angle_arcsec: f64,
    },
    Theodolites {
        #[serde(deserialize_with = "crate::limits::exactly_nested")]
        stations_mm: [[f64; 3]; 2],
        sigma_horizontal_arcsec: f64,
        sigma_vertical_arcsec: f64,
    },
}

/// `Ok` if a joint sigma (deg for a revolute joint, mm for a prismatic one) is within
/// [`MAX_ANGLE_DEG`] or [`MAX_LENGTH_MM`].
fn joint_sigma_bound(kind: JointKind, sigma: f64) -> Result<f64, String> {
    match kind {
        JointKind::Revolute => check_magnitude(sigma, MAX_ANGLE_DEG, "deg"),
        JointKind::Prismatic => check_magnitude(sigma, MAX_LENGTH_MM, "mm"),
    }
}

impl DeviceTable {
    /// The device in mm and rad, validated; errors name the field under `prefix`.
    pub(crate) fn device(&self, prefix: &str) -> Result<Device, FieldError> {
        let arcsec = MAX_ANGLE_DEG * 3600.0;
        let bounded: Vec<(&str, f64, f64, &str)> = match self {
            Self::Cmm { sigma_mm } => vec![("sigma_mm", *sigma_mm, MAX_LENGTH_MM, "mm")],
            Self::LaserTracker { position_mm, sigma_r_mm, k_ppm, sigma_angle_arcsec } => {
                let position = position_mm.iter().map(|&v| ("position_mm", v, MAX_LENGTH_MM, "mm"));
                position
                    .chain([
                        ("sigma_r_mm", *sigma_r_mm, MAX_LENGTH_MM, "mm"),
                        ("k_ppm", *k_ppm, 1e6, "ppm"),
                        ("sigma_angle_arcsec", *sigma_angle_arcsec, arcsec, "arcsec"),
                    ])
                    .collect()
            }
            Self::Theodolites { stations_mm, sigma_horizontal_arcsec, sigma_vertical_arcsec } => {
                let stations = stations_mm.iter().flatten().map(|&v| ("stations_mm", v, MAX_LENGTH_MM, "mm"));
                stations
                    .chain([
                        ("sigma_horizontal_arcsec", *sigma_horizontal_arcsec, arcsec, "arcsec"),
                        ("sigma_vertical_arcsec", *sigma_vertical_arcsec, arcsec, "arcsec"),
                    ])
                    .collect()
            }
        };
        for (field, value, bound, unit) in bounded {
            check_magnitude(value, bound, unit).map_err(|e| FieldError::new(field, e).within(prefix))?;
        }
        let device = match self {
            Self::Cmm { sigma_mm } => Device::Cmm { sigma: *sigma_mm },
            Self::LaserTracker { position_mm, sigma_r_mm, k_ppm, sigma_angle_arcsec } => {
                Device::LaserTracker {
                    position: Vector3::from(*position_mm),
                    sigma_r: *sigma_r_mm,
                    k: k_ppm * 1e-6,
                    sigma_angle: sigma_angle_arcsec * ARCSEC,
                }
            }
            Self::Theodolites { stations_mm, sigma_horizontal_arcsec, sigma_vertical_arcsec } => {
                Device::Theodolites {
                    stations: [Vector3::from(stations_mm[0]), Vector3::from(stations_mm[1])],
                    sigma_horizontal: sigma_horizontal_arcsec * ARCSEC,
                    sigma_vertical: sigma_vertical_arcsec * ARCSEC,
                }
            }
        };
        device.validate().map_err(|e| match e {
            super::DeviceError::Invalid(field) => field.within(prefix),
            other => FieldError::new(prefix.trim_end_matches('.'), other.to_string()),
        })?;
        Ok(device)
    }
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct NoiseToml {
    joint_sigma: Option<Vec<f64>>,
    joint_covariance: Option<Vec<Vec<f64>>>,
    sigma_me_mm: Option<f64>,
    #[serde(default)]
    sigma_orientation_deg: f64,
    device: Option<DeviceTable>,
    prior: Option<std::collections::BTreeMap<String, toml::Value>>,
}

/// The entries of a `[prior]` table, `PATTERN = "SD UNIT"` (a plain number for a compliance),
/// ordered so that the more specific wins: the classes (`lengths`, ...), then the patterns with
/// `*`, then the names; alphabetically within each.
fn prior_table(
    table: std::collections::BTreeMap<String, toml::Value>,
) -> Result<Vec<PriorEntry>, NoiseFileError> {
    let mut entries = Vec::new();
    for (key, value) in table {
        let value = match value {
            toml::Value::String(s) => s,
            toml::Value::Float(v) => v.to_string(),
            toml::Value::Integer(v) => v.to_string(),
            other => {
                let expected = format!("a standard deviation with its unit (\"0.5mm\"), found {other}");
                return Err(NoiseFileError::Invalid(FieldError::new(format!("prior.{key}"), expected)));
            }
        };
        let entry = PriorEntry::parse(&format!("{key}={value}"))
            .map_err(|e| NoiseFileError::Invalid(FieldError::new(format!("prior.{key}"), e.to_string())))?;
        entries.push(entry);
    }
    let rank = |e: &PriorEntry| match e.target.as_str() {
        "lengths" | "angles" | "offsets" | "compliances" | "plays" => 0,
        t if t.contains('*') => 1,
        _ => 2,
    };
    entries.sort_by_key(rank);
    Ok(entries)
}

/// A noise model as a file gives it, in mm and rad: `Sigma_q`, and the measurement noise
/// `Sigma_m(p) = Sigma_device(p) + sigma_me^2 I` at a measured point `p`.
#[derive(Debug, Clone, PartialEq)]
pub struct NoiseSpec {
    /// `Sigma_q` (dof x dof; rad², mm² for prismatic joints).
    pub joint: DMatrix<f64>,
    /// Whether the file gave a full `Sigma_q` (`joint_covariance`) rather than sigmas.
    pub full: bool,
    /// Isotropic measurement noise `sigma_me` (mm), if given (0 otherwise).
    pub sigma_me: Option<f64>,
    /// Orientation measurement noise (rad).
    pub sigma_orientation: f64,
    /// The measuring device, if given.
    pub device: Option<Device>,
    /// The `[prior]` table's entries, the more specific last (classes, then patterns, then names).
    pub prior: Vec<PriorEntry>,
}

impl NoiseSpec {
    /// Read a noise file's text for `model` (one joint sigma per joint).
    pub fn from_toml_str(text: &str, model: &RobotModel) -> Result<Self, NoiseFileError> {
        let file: NoiseToml = toml::from_str(text).map_err(NoiseFileError::Syntax)?;
        let invalid =
            |field: &str, expected: String| NoiseFileError::Invalid(FieldError::new(field, expected));
        let dof = model.dof();
        // deg -> rad for revolute joints.
        let unit: Vec<f64> = model
            .joints
            .iter()
            .map(|j| if j.kind == JointKind::Revolute { 1f64.to_radians() } else { 1.0 })
            .collect();
        let (joint, full) = match (&file.joint_sigma, &file.joint_covariance) {
            (Some(sigmas), None) => {
                if sigmas.len() != dof {
                    return Err(invalid(
                        "joint_sigma",
                        format!("{dof} values, one per joint of {}", model.name),
                    ));
                }
                if let Some(s) = sigmas.iter().find(|s| !(s.is_finite() && **s >= 0.0)) {
                    return Err(invalid("joint_sigma", format!("finite values >= 0, found {s}")));
                }
                for (joint, &s) in model.joints.iter().zip(sigmas) {
                    joint_sigma_bound(joint.kind, s).map_err(|e| invalid("joint_sigma", e))?;
                }
                (
                    DMatrix::from_fn(
                        dof,
                        dof,
                        |i, j| if i == j { (sigmas[i] * unit[i]).powi(2) } else { 0.0 },
                    ),
                    false,
                )
            }
            (None, Some(rows)) => {
                if rows.len() != dof || rows.iter().any(|r| r.len() != dof) {
                    return Err(invalid("joint_covariance", format!("{dof} rows of {dof} values (deg²)")));
                }
                let m = DMatrix::from_fn(dof, dof, |i, j| rows[i][j] * unit[i] * unit[j]);
                if m.iter().any(|v| !v.is_finite()) {
                    return Err(invalid("joint_covariance", "finite values".into()));
                }
                for (i, joint) in model.joints.iter().enumerate() {
                    joint_sigma_bound(joint.kind, rows[i][i].abs().sqrt())
                        .map_err(|e| invalid("joint_covariance", format!("diagonal: the square of {e}")))?;
                }
                if (&m - m.transpose()).amax() > 1e-9 * m.amax() {
                    return Err(invalid("joint_covariance", "a symmetric matrix".into()));
                }
                // Rounding a semi-definite matrix to the digits of a file leaves tiny negative eigenvalues.
                if m.clone().symmetric_eigen().eigenvalues.min() < -1e-6 * m.amax() {
                    return Err(invalid("joint_covariance", "a positive semi-definite matrix".into()));
                }
                (m, true)
            }
            _ => {
                return Err(invalid(
                    "joint_sigma",
                    "give one of `joint_sigma` (deg, per joint) or `joint_covariance` (deg²)".into(),
                ));
            }
        };
        if let Some(s) = file.sigma_me_mm
            && !(s.is_finite() && s >= 0.0)
        {
            return Err(invalid("sigma_me_mm", format!("a finite value >= 0, found {s}")));
        }
        if let Some(s) = file.sigma_me_mm {
            check_magnitude(s, MAX_LENGTH_MM, "mm").map_err(|e| invalid("sigma_me_mm", e))?;
        }
        let o = file.sigma_orientation_deg;
        if !(o.is_finite() && o >= 0.0) {
            return Err(invalid("sigma_orientation_deg", format!("a finite value >= 0, found {o}")));
        }
        check_magnitude(o, MAX_ANGLE_DEG, "deg").map_err(|e| invalid("sigma_orientation_deg", e))?;
        let device = file.device.as_ref().map(|d| d.device("device.")).transpose()?;
        let prior = prior_table(file.prior.unwrap_or_default())?;
        Ok(Self { joint, full, sigma_me: file.sigma_me_mm, sigma_orientation: o.to_radians(), device, prior })
    }

    /// The joint standard deviations (rad, mm): the square roots of the diagonal of `Sigma_q`.
    pub fn joint_sigmas(&self) -> Vec<f64> {
        self.joint.diagonal().iter().map(|v| v.max(0.0).sqrt()).collect()
    }

    /// `Sigma_m` (mm²) of a point measured at `point` (mm, the device frame):
    /// `Sigma_device(point) + sigma_me^2 I`.
    pub fn measurement_covariance(&self, point: &Vector3<f64>) -> Result<Matrix3<f64>, super::DeviceError> {
        let s = self.sigma_me.unwrap_or(0.0);
        let device = match &self.device {
            Some(d) => d.covariance(point)?,
            None => Matrix3::zeros(),
        };
        Ok(device + Matrix3::identity() * s * s)
    }

    /// The file's text for `model`, after the comment lines of `header`; it reads back as
    /// `self` (to the printed precision).
    pub fn to_toml_string(&self, model: &RobotModel, header: &str) -> String {
        let mut out = String::new();
        for line in header.lines() {
            let _ = writeln!(out, "# {line}");
        }
        let unit =
            |i: usize| if model.joints[i].kind == JointKind::Revolute { 1f64.to_degrees() } else { 1.0 };
        let dof = model.dof();
        if self.full {
            let _ = writeln!(out, "joint_covariance = [  # deg² (mm² for prismatic joints)");
            for i in 0..dof {
                let row: Vec<String> =
                    (0..dof).map(|j| format!("{:.9e}", self.joint[(i, j)] * unit(i) * unit(j))).collect();
                let _ = writeln!(out, "    [{}],", row.join(", "));
            }
            let _ = writeln!(out, "]");
        } else {
            let sigmas: Vec<String> =
                self.joint_sigmas().iter().enumerate().map(|(i, s)| format!("{:.6e}", s * unit(i))).collect();
            let _ = writeln!(out, "joint_sigma = [{}]  # deg (mm for prismatic joints)", sigmas.join(", "));
        }
        if let Some(s) = self.sigma_me {
            let _ = writeln!(out, "sigma_me_mm = {s:.6e}");
        }
        if self.sigma_orientation > 0.0 {
            let _ = writeln!(out, "sigma_orientation_deg = {:.6e}", self.sigma_orientation.to_degrees());
        }
        if !self.prior.is_empty() {
            let _ = writeln!(out, "\n[prior]");
            for entry in &self.prior {
                let value = entry.text.split_once('=').map_or("", |(_, v)| v.trim());
                let _ = writeln!(out, "\"{}\" = \"{value}\"", entry.target);
            }
        }
        if let Some(device) = &self.device {
            let _ = writeln!(out, "\n[device]\nkind = \"{}\"", device.kind());
            match device {
                Device::Cmm { sigma } => {
                    let _ = writeln!(out, "sigma_mm = {sigma}");
                }
                Device::LaserTracker { position, sigma_r, k, sigma_angle } => {
                    let _ = writeln!(
                        out,
                        "position_mm = [{}, {}, {}]\nsigma_r_mm = {sigma_r}\nk_ppm = {}\n\
                         sigma_angle_arcsec = {}",
                        position.x,
                        position.y,
                        position.z,
                        k * 1e6,
                        sigma_angle / ARCSEC
                    );
                }
                Device::Theodolites { stations, sigma_horizontal, sigma_vertical } => {
                    let [a, b] = stations;
                    let _ = writeln!(
                        out,
                        "stations_mm = [[{}, {}, {}], [{}, {}, {}]]\nsigma_horizontal_arcsec = {}\n\
                         sigma_vertical_arcsec = {}",
                        a.x,
                        a.y,
                        a.z,
                        b.x,
                        b.y,
                        b.z,
                        sigma_horizontal / ARCSEC,
                        sigma_vertical / ARCSEC
                    );
                }
            }
        }
        out
    }
}
