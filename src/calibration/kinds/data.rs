//! The files of distances, contacts and partial coordinates (see `docs/formats.md`).
//!
//! ```text
//! # units: joints=deg, lengths=mm
//! j1,j2,j3,j4,j5,j6,j1_b,j2_b,j3_b,j4_b,j5_b,j6_b,distance     pairs of poses
//! j1,j2,j3,j4,j5,j6,point,distance                             to fixed point `point` (1, 2, ...)
//! j1,j2,j3,j4,j5,j6,plane                                      contacts with plane `plane`
//! j1,j2,j3,j4,j5,j6,x,y,z,roll,pitch,yaw                       coordinates, any empty or absent
//! j1,j2,j3,j4,j5,j6,camera,x,y,z,roll,pitch,yaw                the target's pose seen by a camera
//! j1,j2,j3,j4,j5,j6,x1,y1,z1,x2,y2,z2                          marker positions (`calibrate --data`)
//! ```
//!
//! A marker file is the measurement file of `robocal calibrate` (its marker columns `x<k>,
//! y<k>, z<k>`, the number naming the marker), read cell by cell: each of a marker's x, y, z is
//! one [`Observation::Marker`], an empty cell one not measured.
//!
//! Each may add `sigma`, the row's measurement standard deviation (length unit; every measured
//! length of the row), without it [`DEFAULT_SIGMA_MM`]; and `sigma_angle` for angles (the
//! joints' angle unit), without it [`DEFAULT_SIGMA_ANGLE_DEG`]. A camera row (`camera` is
//! `hand` or `world`, [`CameraSite`]) gives all six, the target's pose in the camera's frame;
//! its defaults are [`DEFAULT_CAMERA_SIGMA_MM`] and [`DEFAULT_CAMERA_SIGMA_DEG`].

use super::SetUp;
use super::camera::{CameraSite, camera_start, isometry};
use crate::calibration::{BaseAbsorber, CalibrationError, Unseen};
use crate::estimation::MeasurementClass;
use crate::limits::MAX_LENGTH_MM;
use crate::model::RobotModel;
use crate::table::{DataError, Row, Table, Units};
use nalgebra::{DMatrix, DVector, Isometry3, Matrix3, UnitQuaternion, Vector3, Vector6};

/// The measurement standard deviation of a row without a `sigma` column (mm).
pub const DEFAULT_SIGMA_MM: f64 = 0.01;

/// The standard deviation of an angle (roll, pitch, yaw) without a `sigma_angle` column (deg).
pub const DEFAULT_SIGMA_ANGLE_DEG: f64 = 0.01;

/// A camera row's position standard deviation without a `sigma` column (mm): a checkerboard's
/// pose from a calibrated camera at about half a metre.
pub const DEFAULT_CAMERA_SIGMA_MM: f64 = 0.5;

/// A camera row's orientation standard deviation without a `sigma_angle` column (deg).
pub const DEFAULT_CAMERA_SIGMA_DEG: f64 = 0.1;

/// The standard deviations of rows that give none in a `sigma` or `sigma_angle` cell, where
/// the user gave them (`--sigma-mm`, `--sigma-orientation-deg`); `None` leaves the kind's
/// default ([`DEFAULT_SIGMA_MM`], [`DEFAULT_SIGMA_ANGLE_DEG`], a camera's own), which counts as
/// assumed.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct RowSigmaDefaults {
    /// A length's standard deviation (mm).
    pub length_mm: Option<f64>,
    /// An angle's standard deviation (rad).
    pub angle_rad: Option<f64>,
}

impl RowSigmaDefaults {
    /// A length's sigma `length_mm` (mm) and an angle's `angle_rad` (rad), each where given
    /// and above 0 (a zero one is none, as the flags' default 0).
    pub fn positive(length_mm: Option<f64>, angle_rad: Option<f64>) -> Self {
        let positive = |s: Option<f64>| s.filter(|&s| s > 0.0);
        Self { length_mm: positive(length_mm), angle_rad: positive(angle_rad) }
    }

    /// A noise file's: its `sigma_me_mm`, and its `sigma_orientation_deg` or, where that is 0,
    /// its device's typical orientation sigma ([`Device::sigma_orientation`](crate::estimation::Device::sigma_orientation));
    /// each where above 0 ([`positive`](Self::positive)).
    pub fn of_noise(spec: &crate::estimation::NoiseSpec) -> Self {
        let orientation = match (&spec.device, spec.sigma_orientation) {
            (Some(device), 0.0) => device.sigma_orientation(),
            (_, given) => given,
        };
        Self::positive(spec.sigma_me, Some(orientation))
    }
}

/// One measured number. Poses are indices into [`KindData::joints`]; points and planes count
/// from 0 (`point = 1` in a file is 0 here).
#[derive(Debug, Clone, Copy, PartialEq)]
#[non_exhaustive]
pub enum Observation {
    /// The distance (mm) between the tool point at poses `a` and `b`.
    Distance {
        /// The first pose.
        a: usize,
        /// The second pose.
        b: usize,
        /// The distance (mm).
        measured: f64,
        /// Its standard deviation (mm).
        sigma: f64,
    },
    /// The distance (mm) from the tool point at `pose` to fixed point `point`.
    ToPoint {
        /// The pose.
        pose: usize,
        /// The fixed point.
        point: usize,
        /// The distance (mm).
        measured: f64,
        /// Its standard deviation (mm).
        sigma: f64,
    },
    /// The tool point at `pose` touches plane `plane`: signed distance 0.
    Contact {
        /// The pose.
        pose: usize,
        /// The plane.
        plane: usize,
        /// The standard deviation of the contact (mm).
        sigma: f64,
    },
    /// One coordinate of the tool at `pose`, in the measuring frame: `axis` 0, 1, 2 the
    /// point's x, y, z (mm); 3, 4, 5 the tool frame's roll, pitch, yaw (rad,
    /// `R = Rz(yaw) Ry(pitch) Rx(roll)`).
    Coordinate {
        /// 0 to 5: x, y, z, roll, pitch, yaw.
        axis: usize,
        /// The pose.
        pose: usize,
        /// The coordinate (mm or rad).
        measured: f64,
        /// Its standard deviation (mm or rad).
        sigma: f64,
    },
    /// One coordinate of marker `marker`'s point on the last link at `pose`, in the measuring
    /// frame: `axis` 0, 1, 2 its x, y, z (mm). A marker file's cell.
    Marker {
        /// The marker's number less one (`x3` is marker 2 here).
        marker: usize,
        /// 0 to 2: x, y, z.
        axis: usize,
        /// The pose.
        pose: usize,
        /// The coordinate (mm).
        measured: f64,
        /// Its standard deviation (mm).
        sigma: f64,
    },
    /// One of the three rows of the measured orientation of marker `marker`'s frame at `pose`
    /// (a 6-DOF probe: a marker file's `qw,qx,qy,qz` or `roll,pitch,yaw` with marker 1, the
    /// frame's origin): row `axis` of the rotation vector `log(R_m R^T)` (rad, measuring
    /// frame), `R_m` measured, `R` predicted. The three rows carry the whole rotation.
    Orientation {
        /// The marker's number less one (its frame's origin is the marker).
        marker: usize,
        /// 0 to 2: the rotation vector's x, y, z.
        axis: usize,
        /// The pose.
        pose: usize,
        /// The measured rotation `R_m`.
        measured: UnitQuaternion<f64>,
        /// Its standard deviation (rad), each row alike.
        sigma: f64,
    },
    /// One of the six numbers of a camera's view of the target at `pose`: the target's pose
    /// in the camera's frame, `T_camera^-1 T_target`, its position (`axis` 0, 1, 2; mm) and
    /// its rotation vector (3, 4, 5; rad). Each of the six rows carries the whole view.
    Camera {
        /// 0 to 5: x, y, z (mm), then the rotation vector's x, y, z (rad).
        axis: usize,
        /// The pose.
        pose: usize,
        /// The target's pose in the camera frame: position (mm), rotation vector (rad).
        view: Vector6<f64>,
        /// Where the camera is.
        site: CameraSite,
        /// The standard deviation of this row (mm or rad).
        sigma: f64,
    },
}

impl Observation {
    /// The measured value `m_k` (mm; 0 for a contact).
    pub fn measured(&self) -> f64 {
        match *self {
            Self::Distance { measured, .. }
            | Self::ToPoint { measured, .. }
            | Self::Coordinate { measured, .. }
            | Self::Marker { measured, .. } => measured,
            Self::Contact { .. } => 0.0,
            Self::Camera { view, axis, .. } => view.get(axis).copied().unwrap_or(f64::NAN),
            Self::Orientation { measured, axis, .. } => {
                measured.scaled_axis().get(axis).copied().unwrap_or(f64::NAN)
            }
        }
    }

    /// Its kind in words: `distance` (a pair), `point`, `contact`, `marker`, or the coordinate
    /// `x` ... `yaw`.
    pub fn kind(&self) -> &'static str {
        match *self {
            Self::Distance { .. } => "distance",
            Self::ToPoint { .. } => "point",
            Self::Contact { .. } => "contact",
            Self::Marker { axis, .. } => {
                ["marker x", "marker y", "marker z"].get(axis).copied().unwrap_or("?")
            }
            Self::Coordinate { axis, .. } => {
                ["x", "y", "z", "roll", "pitch", "yaw"].get(axis).copied().unwrap_or("?")
            }
            Self::Orientation { axis, .. } => {
                ["probe rx", "probe ry", "probe rz"].get(axis).copied().unwrap_or("?")
            }
            Self::Camera { axis, .. } => {
                ["camera x", "camera y", "camera z", "camera rx", "camera ry", "camera rz"]
                    .get(axis)
                    .copied()
                    .unwrap_or("?")
            }
        }
    }

    /// The kind in words, plural, as a file's summary counts it (`distances to a fixed point`).
    pub fn kind_words(&self) -> &'static str {
        match self {
            Self::Distance { .. } => "distances between two poses",
            Self::ToPoint { .. } => "distances to a fixed point",
            Self::Contact { .. } => "plane contacts",
            Self::Coordinate { .. } => "coordinates",
            Self::Marker { .. } => "marker coordinates",
            Self::Orientation { .. } => "numbers of a probe's orientations (3 a pose)",
            Self::Camera { .. } => "numbers of camera views (6 a view)",
        }
    }

    /// Its group in a report's rows: `distances` (between poses or to a point), `contacts`,
    /// `coordinates`, `angles`, `markers`, `camera positions`, `camera rotations`.
    pub fn group(&self) -> &'static str {
        match *self {
            Self::Distance { .. } | Self::ToPoint { .. } => "distances",
            Self::Contact { .. } => "contacts",
            Self::Coordinate { axis: 3.., .. } => "angles",
            Self::Coordinate { .. } => "coordinates",
            Self::Marker { .. } => "markers",
            Self::Orientation { .. } => "probe orientations",
            Self::Camera { axis: 3.., .. } => "camera rotations",
            Self::Camera { .. } => "camera positions",
        }
    }

    /// Whether it is an angle (rad).
    pub fn is_angle(&self) -> bool {
        matches!(
            self,
            Self::Coordinate { axis: 3.., .. } | Self::Camera { axis: 3.., .. } | Self::Orientation { .. }
        )
    }

    /// Its share of one length error in a set's RMS error (cross-validation's, the selection
    /// path's): a marker's coordinate a third of its position's error (three make the
    /// position error `|e|`, as a marker file's calibration counts it), any other length one
    /// error, an angle none (the RMS error is of lengths, mm).
    pub fn error_share(&self) -> f64 {
        match self {
            _ if self.is_angle() => 0.0,
            Self::Marker { .. } => 1.0 / 3.0,
            _ => 1.0,
        }
    }

    /// The pose it was made at (the first of a pair).
    pub fn pose(&self) -> usize {
        match *self {
            Self::Distance { a: pose, .. }
            | Self::ToPoint { pose, .. }
            | Self::Contact { pose, .. }
            | Self::Coordinate { pose, .. }
            | Self::Marker { pose, .. }
            | Self::Orientation { pose, .. }
            | Self::Camera { pose, .. } => pose,
        }
    }

    /// The residual `m_k - f` of a prediction `f`; an angle's wrapped into `(-pi, pi]`.
    pub fn residual(&self, f: f64) -> f64 {
        let r = self.measured() - f;
        match self {
            Self::Coordinate { axis, .. } if *axis >= 3 => {
                let t = std::f64::consts::TAU;
                r - t * ((r + std::f64::consts::PI) / t).ceil() + t
            }
            _ => r,
        }
    }

    /// The measurement class whose variance feasible GLS estimates for it: a distance (between
    /// poses or to a fixed point), a contact, a coordinate or an angle, a marker's coordinate,
    /// a camera view's position or rotation.
    pub fn class(&self) -> MeasurementClass {
        match *self {
            Self::Distance { .. } | Self::ToPoint { .. } => MeasurementClass::Distance,
            Self::Contact { .. } => MeasurementClass::Contact,
            Self::Coordinate { axis: 3.., .. } => MeasurementClass::Angle,
            Self::Coordinate { .. } => MeasurementClass::Coordinate,
            Self::Marker { .. } => MeasurementClass::Marker,
            Self::Orientation { .. } => MeasurementClass::Orientation,
            Self::Camera { axis: 3.., .. } => MeasurementClass::CameraRotation,
            Self::Camera { .. } => MeasurementClass::CameraPosition,
        }
    }

    /// The same observation with standard deviation `to` (mm, or rad for an angle).
    pub fn with_sigma(mut self, to: f64) -> Self {
        match &mut self {
            Self::Distance { sigma, .. }
            | Self::ToPoint { sigma, .. }
            | Self::Contact { sigma, .. }
            | Self::Coordinate { sigma, .. }
            | Self::Marker { sigma, .. }
            | Self::Orientation { sigma, .. }
            | Self::Camera { sigma, .. } => *sigma = to,
        }
        self
    }

    /// Its standard deviation `sigma_k` (mm).
    pub fn sigma(&self) -> f64 {
        match *self {
            Self::Distance { sigma, .. }
            | Self::ToPoint { sigma, .. }
            | Self::Contact { sigma, .. }
            | Self::Coordinate { sigma, .. }
            | Self::Marker { sigma, .. }
            | Self::Orientation { sigma, .. }
            | Self::Camera { sigma, .. } => sigma,
        }
    }

    /// The marker whose point or frame it sees (its number less one), if a marker's.
    pub fn marker(&self) -> Option<usize> {
        match *self {
            Self::Marker { marker, .. } | Self::Orientation { marker, .. } => Some(marker),
            _ => None,
        }
    }
}

/// A point measured at a pose: a marker's or the tool's (by coordinates).
struct MeasuredPoint {
    /// The pose, and the marker (`None`: the tool point).
    key: (usize, Option<usize>),
    /// Its x, y, z measured (mm; NaN where not).
    position: [f64; 3],
    /// The observations of its x, y, z (`usize::MAX` where none).
    observations: [usize; 3],
}

/// Observations of distances, contacts and coordinates, with the poses they were made at.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct KindData {
    /// Joint values of each pose (rad, mm for prismatic joints).
    pub joints: Vec<Vec<f64>>,
    /// The observations.
    pub observations: Vec<Observation>,
    /// The file line of each observation.
    pub lines: Vec<usize>,
    /// How many observations carry a default sigma (their row gave none): when all do and the
    /// joints are exact, the calibration takes its standard errors from the residuals' spread.
    pub assumed_sigmas: usize,
    /// The measuring sessions (one per data file), each its name and its first pose: the poses
    /// from one to the next are its. Empty: one session, `1`. Set-up parameters made per session
    /// ([`KindOptions::per_session`](super::KindOptions::per_session)) take one value per session.
    pub sessions: Vec<(String, usize)>,
    /// A measuring device's covariance at each observation's point, empty for none: for a
    /// marker's or the tool point's x, y or z (`axis` a) at a pose, row a of
    /// `Sigma_device(p)` (mm²) at the point `p` measured there ([`with_device`](Self::with_device)),
    /// zeros for the others. `V_k` adds it between the coordinates of one point at one pose,
    /// to `sigma^2` on the diagonal ([`measurement_covariance`](Self::measurement_covariance)).
    pub device: Vec<[f64; 3]>,
}

/// The sessions `sessions` of data of `offset` poses, then those of `other` (its sessions and
/// poses) after them: a session unnamed is numbered (`1`, `2`, ...), each from its first pose.
pub(crate) fn join_sessions(
    sessions: &mut Vec<(String, usize)>,
    offset: usize,
    (other, poses): (&[(String, usize)], usize),
) {
    if offset > 0 && sessions.is_empty() {
        sessions.push(("1".to_string(), 0));
    }
    if poses > 0 {
        let count = sessions.len();
        match other.is_empty() {
            true => sessions.push(((count + 1).to_string(), offset)),
            false => sessions.extend(other.iter().map(|(n, first)| (n.clone(), first + offset))),
        }
    }
}

/// Refuse `sessions` (names and first poses) that do not start at pose 0 and ascend, or name a
/// session twice.
pub(crate) fn check_sessions(sessions: &[(String, usize)]) -> Result<(), CalibrationError> {
    let bad = |what: String| Err(CalibrationError::Observations(what));
    let firsts: Vec<usize> = sessions.iter().map(|s| s.1).collect();
    if firsts.first().is_some_and(|&f| f != 0) || firsts.windows(2).any(|w| w[1] <= w[0]) {
        return bad(format!("sessions starting at poses {firsts:?}: expected 0 first, then ascending"));
    }
    if let Some(k) = (1..sessions.len()).find(|&k| sessions[..k].iter().any(|s| s.0 == sessions[k].0)) {
        return bad(format!(
            "session `{}` named twice: each data file's stem names its session",
            sessions[k].0
        ));
    }
    Ok(())
}

impl KindData {
    /// Whether a noise is given for these observations: the joints' (`joint_noise`), or one
    /// observation's own sigma (a column, a flag, a noise file). Without one, every sigma is
    /// assumed: the fit is ordinary least squares, its noise the residuals' spread, and a
    /// weighted estimator has nothing to weigh by.
    pub fn noise_given(&self, joint_noise: bool) -> bool {
        joint_noise || self.assumed_sigmas < self.observations.len()
    }

    /// Read a file of distances (pairs `<joint>,<joint>_b,distance`, or to fixed points
    /// `<joint>,point,distance`), contacts (`<joint>,plane`) or coordinates (any of
    /// `x,y,z,roll,pitch,yaw`, empty cells for coordinates not measured) for `model`; or of
    /// them all, a `kind` column naming each row's (`pair`, `point`, `contact`, `coordinates`).
    /// `units` from the caller take the place of the file's `# units:` line.
    pub fn from_csv_str(text: &str, model: &RobotModel, units: Option<Units>) -> Result<Self, DataError> {
        Self::from_csv_str_with(text, model, units, RowSigmaDefaults::default())
    }

    /// [`from_csv_str`](Self::from_csv_str) with the standard deviations of rows that give
    /// none taken from `defaults` where it has them (`--sigma-mm`, `--sigma-orientation-deg`):
    /// those are the user's, not assumed.
    pub fn from_csv_str_with(
        text: &str,
        model: &RobotModel,
        units: Option<Units>,
        defaults: RowSigmaDefaults,
    ) -> Result<Self, DataError> {
        let table = Table::parse(text)?;
        let units = table.units(units, " or give --joint-unit and --length-unit")?;
        let columns = KindColumns { defaults, ..KindColumns::resolve(&table, model)? };
        crate::calibration::data::check_markers_measured(&table, &columns.markers)?;
        let mut data = Self::default();
        let rows = table.nonempty_rows()?;
        data.joints.reserve_exact(rows.len());
        for (r, row) in rows.iter().enumerate() {
            let kind = match columns.kind {
                Some(c) => RowKind::named(&row.cells[c]).ok_or_else(|| {
                    let message =
                        format!("`{}`: expected pair, point, contact, coordinates or camera", &row.cells[c]);
                    DataError::new(row.line, Some("kind"), message)
                })?,
                None => columns.file_kind.expect("a file without a kind column has one kind"),
            };
            columns.read_row(&table, row, kind, model, units, &mut data)?;
            if r == 0 {
                // As many observations in every row as in the first: the vectors sized once,
                // not grown by doubling (600k observations of a 100k-pose marker file).
                let rest = data.observations.len() * (rows.len() - 1);
                data.observations.reserve_exact(rest);
                data.lines.reserve_exact(rest);
            }
        }
        Ok(data)
    }

    /// The same data as one session named `name` (a file's stem).
    pub fn named(mut self, name: &str) -> Self {
        self.sessions = vec![(name.to_string(), 0)];
        self
    }

    /// The observations that `keep` keeps, at the same poses and sessions. Their sigmas count
    /// as assumed if every observation's here did.
    pub fn keeping(&self, keep: impl Fn(&Observation) -> bool) -> Self {
        let kept: Vec<usize> =
            (0..self.observations.len()).filter(|&k| keep(&self.observations[k])).collect();
        let all_assumed = self.assumed_sigmas == self.observations.len();
        Self {
            joints: self.joints.clone(),
            observations: kept.iter().map(|&k| self.observations[k]).collect(),
            lines: kept.iter().map(|&k| self.lines[k]).collect(),
            assumed_sigmas: if all_assumed { kept.len() } else { 0 },
            sessions: self.sessions.clone(),
            device: match self.device.is_empty() {
                true => Vec::new(),
                false => kept.iter().map(|&k| self.device[k]).collect(),
            },
        }
    }

    /// The same data with a measuring device's covariance `covariance(p)` (mm², at a point `p`
    /// measured in the measuring frame, mm) at each marker's measured position, and at the tool
    /// point's where a row of coordinates measures its x, y and z ([`KindData::device`]). A
    /// marker measured at a pose along some of x, y and z only is refused, naming its line: the
    /// covariance is taken where it was measured. Coordinates measured in part (a height gauge's
    /// z) are another instrument's: their own sigma alone weighs them.
    pub fn with_device<E: std::fmt::Display>(
        mut self,
        covariance: impl Fn(&Vector3<f64>) -> Result<Matrix3<f64>, E>,
    ) -> Result<Self, DataError> {
        let mut device = vec![[0.0; 3]; self.observations.len()];
        for point in self.measured_points() {
            let members = point.observations;
            let line = self.lines[members.into_iter().find(|&k| k != usize::MAX).expect("one observation")];
            let [Some(x), Some(y), Some(z)] = members.map(|k| Some(k).filter(|&k| k != usize::MAX)) else {
                if point.key.1.is_none() {
                    continue;
                }
                let message = "a device's covariance needs the marker's x, y and z where it was measured: this row \
                               measures some of them only";
                return Err(DataError::new(line, None, message));
            };
            let p = Vector3::from(point.position);
            let c = covariance(&p).map_err(|e| DataError::new(line, None, e.to_string()))?;
            for (a, k) in [x, y, z].into_iter().enumerate() {
                device[k] = [c[(a, 0)], c[(a, 1)], c[(a, 2)]];
            }
        }
        self.device = device;
        Ok(self)
    }

    /// Each point measured at a pose (a marker's, or the tool's by coordinates), in the order
    /// of its first observation.
    fn measured_points(&self) -> Vec<MeasuredPoint> {
        let mut points: Vec<MeasuredPoint> = Vec::new();
        let mut at_key = std::collections::HashMap::new();
        for (k, o) in self.observations.iter().enumerate() {
            let (key, axis, m) = match *o {
                Observation::Marker { marker, axis, pose, measured, .. } => {
                    ((pose, Some(marker)), axis, measured)
                }
                Observation::Coordinate { axis: axis @ 0..3, pose, measured, .. } => {
                    ((pose, None), axis, measured)
                }
                _ => continue,
            };
            let at = *at_key.entry(key).or_insert_with(|| {
                points.push(MeasuredPoint { key, position: [f64::NAN; 3], observations: [usize::MAX; 3] });
                points.len() - 1
            });
            points[at].position[axis] = m;
            points[at].observations[axis] = k;
        }
        points
    }

    /// The measurement covariance of observations `i` and `j` (mm², rad²): `sigma_i^2` if they
    /// are one, plus the device's between two coordinates of one point at one pose
    /// ([`KindData::device`]).
    pub fn measurement_covariance(&self, i: usize, j: usize) -> f64 {
        let own = if i == j { self.observations[i].sigma().powi(2) } else { 0.0 };
        let point = |o: &Observation| match *o {
            Observation::Marker { marker, axis, pose, .. } => Some((pose, Some(marker), axis)),
            Observation::Coordinate { axis: axis @ 0..3, pose, .. } => Some((pose, None, axis)),
            _ => None,
        };
        match (self.device.is_empty(), point(&self.observations[i]), point(&self.observations[j])) {
            (false, Some((p, m, _)), Some((p2, m2, axis))) if (p, m) == (p2, m2) => {
                own + self.device[i][axis]
            }
            _ => own,
        }
    }

    /// Each pose once, with the line of its first observation, in the file's order: `(line,
    /// joint values)`.
    pub fn pose_lines(&self) -> impl Iterator<Item = (usize, &[f64])> + '_ {
        let mut seen = vec![false; self.joints.len()];
        (self.observations.iter().zip(&self.lines)).filter_map(move |(o, &line)| {
            let pose = o.pose();
            let first = !std::mem::replace(&mut seen[pose], true);
            first.then(|| (line, self.joints[pose].as_slice()))
        })
    }

    /// The number of sessions (at least 1).
    pub fn session_count(&self) -> usize {
        self.sessions.len().max(1)
    }

    /// The name of session `i`: its file's stem, or its number from 1.
    pub fn session_name(&self, i: usize) -> String {
        self.sessions.get(i).map_or_else(|| (i + 1).to_string(), |s| s.0.clone())
    }

    /// The session of pose `pose`: the last whose first pose is at or before it.
    pub fn session_of(&self, pose: usize) -> usize {
        self.sessions.iter().rposition(|s| s.1 <= pose).unwrap_or(0)
    }

    /// These observations and `other`'s in one set (the same point or plane numbers are the
    /// same point or plane); `other`'s sessions follow these.
    pub fn join(mut self, other: &Self) -> Self {
        let offset = self.joints.len();
        join_sessions(&mut self.sessions, offset, (&other.sessions, other.joints.len()));
        if !self.device.is_empty() || !other.device.is_empty() {
            // One device row per observation: zeros for those of data without a device.
            self.device.resize(self.observations.len(), [0.0; 3]);
            self.device.extend(other.device.iter().copied());
            self.device.resize(self.observations.len() + other.observations.len(), [0.0; 3]);
        }
        self.joints.extend(other.joints.iter().cloned());
        self.lines.extend(&other.lines);
        self.assumed_sigmas += other.assumed_sigmas;
        self.observations.extend(other.observations.iter().map(|o| match *o {
            Observation::Distance { a, b, measured, sigma } => {
                Observation::Distance { a: a + offset, b: b + offset, measured, sigma }
            }
            Observation::ToPoint { pose, point, measured, sigma } => {
                Observation::ToPoint { pose: pose + offset, point, measured, sigma }
            }
            Observation::Contact { pose, plane, sigma } => {
                Observation::Contact { pose: pose + offset, plane, sigma }
            }
            Observation::Coordinate { pose, axis, measured, sigma } => {
                Observation::Coordinate { pose: pose + offset, axis, measured, sigma }
            }
            Observation::Marker { marker, axis, pose, measured, sigma } => {
                Observation::Marker { marker, axis, pose: pose + offset, measured, sigma }
            }
            Observation::Orientation { marker, axis, pose, measured, sigma } => {
                Observation::Orientation { marker, axis, pose: pose + offset, measured, sigma }
            }
            Observation::Camera { pose, axis, view, site, sigma } => {
                Observation::Camera { pose: pose + offset, axis, view, site, sigma }
            }
        }));
        self
    }

    /// The number of fixed points and of planes (the highest number of each).
    pub fn setup_counts(&self) -> (usize, usize) {
        let mut counts = (0, 0);
        for o in &self.observations {
            match *o {
                Observation::ToPoint { point, .. } => counts.0 = counts.0.max(point + 1),
                Observation::Contact { plane, .. } => counts.1 = counts.1.max(plane + 1),
                _ => {}
            }
        }
        counts
    }

    /// What the data hold, in words: each kind's count, in the order first seen
    /// (`150 distances to a fixed point`), so that a file read by its header says what was found.
    pub fn summary(&self) -> String {
        let mut counts: Vec<(&str, usize)> = Vec::new();
        for o in &self.observations {
            match counts.iter_mut().find(|(k, _)| *k == o.kind_words()) {
                Some((_, n)) => *n += 1,
                None => counts.push((o.kind_words(), 1)),
            }
        }
        let kinds: Vec<String> = counts.iter().map(|(k, n)| format!("{n} {k}")).collect();
        format!("{} at {} poses", kinds.join(", "), self.joints.len())
    }

    /// The bytes a calibration on these data holds, roughly and from above: 16 bytes for each
    /// entry of the rows x columns Jacobian, its columns the robot's `params` and the base's
    /// and markers' (`6 + 3 m`); with `feasible` GLS, its variance components' samples too,
    /// `8 (c b (b + 1) / 2 + b + b dof)` bytes for each pose's block of `b` rows, `c` the joints'
    /// variances and the measurement classes (its packed designs, residuals and the joints'
    /// Jacobians). Measured at the peak (the process's resident set): WLS on 100,000 poses of
    /// two markers (600,000 rows, 48 columns) 224 MB, 7.8 bytes an entry; feasible GLS on
    /// 20,000 poses of four markers 263 MB against an estimate of 308 MB, and on 100,000 of two
    /// 448 MB against 612 MB.
    pub fn memory_estimate(&self, params: usize, feasible: bool) -> u64 {
        let columns = (params + 6 + 3 * self.markers().len()) as u64;
        let rows = (self.observations.len() as u64).saturating_mul(columns).saturating_mul(16);
        rows.saturating_add(if feasible { self.samples_estimate() } else { 0 })
    }

    /// The measurement classes of the observations ([`Observation::class`]), each once, in
    /// order.
    pub(crate) fn classes(&self) -> Vec<MeasurementClass> {
        let mut classes: Vec<MeasurementClass> = self.observations.iter().map(Observation::class).collect();
        classes.sort();
        classes.dedup();
        classes
    }

    /// The bytes of feasible GLS's samples ([`KindData::memory_estimate`]).
    fn samples_estimate(&self) -> u64 {
        let dof = self.joints.first().map_or(0, Vec::len) as u64;
        let components = dof + self.classes().len() as u64;
        let blocks = super::pose_blocks(&self.observations);
        (blocks.ranges(self.observations.len()))
            .map(|r| r.len() as u64)
            .map(|b| 8 * (components * b * (b + 1) / 2 + b + b * dof))
            .fold(0, u64::saturating_add)
    }

    /// Whether any observation is an angle of the tool frame (a roll, pitch or yaw, a
    /// camera's view: the tool is a frame).
    pub fn has_angles(&self) -> bool {
        self.observations
            .iter()
            .any(|o| matches!(o, Observation::Coordinate { axis: 3.., .. } | Observation::Camera { .. }))
    }

    /// Where the camera is, if any observation is a camera's.
    pub fn camera(&self) -> Option<CameraSite> {
        self.observations.iter().find_map(|o| match *o {
            Observation::Camera { site, .. } => Some(site),
            _ => None,
        })
    }

    /// Whether any observation sees the measuring frame's coordinates, a coordinate or a
    /// marker's (then the base is estimated; distances and contacts alone cannot see it).
    pub fn sees_the_base(&self) -> bool {
        self.observations.iter().any(|o| matches!(o, Observation::Coordinate { .. }) || o.marker().is_some())
    }

    /// These data with the markers numbered `ids` (from 1) only, their positions and
    /// orientations; every other observation kept. `None` where they have markers and `ids`
    /// names none of them.
    pub fn with_markers(&self, ids: &[usize]) -> Option<Self> {
        let have = self.markers();
        if !have.is_empty() && !have.iter().any(|m| ids.contains(&(m + 1))) {
            return None;
        }
        Some(self.keeping(|o| o.marker().is_none_or(|m| ids.contains(&(m + 1)))))
    }

    /// The markers observed (their numbers less one), ascending: one point each on the last
    /// link.
    pub fn markers(&self) -> Vec<usize> {
        distinct(self.observations.iter().filter_map(Observation::marker))
    }

    /// The noise ordinary least squares assumes, where every sigma is assumed (`None` if one
    /// is given, or if no row is an angle): every row alike in its metric, an angle (rad)
    /// counting `w = sigma_position / sigma_orientation` of [`POSE_SIGMAS`] mm
    /// ([`Residuals::ols_row_scale`]), so that an angle's sigma is its kind's default length
    /// sigma over `w`. The residuals' spread then scales the covariance as `calibrate`'s
    /// ordinary least squares without a noise model: `s^2 (H^T S^2 H)^-1`.
    ///
    /// [`POSE_SIGMAS`]: crate::estimation::POSE_SIGMAS
    /// [`Residuals::ols_row_scale`]: crate::estimation::Residuals::ols_row_scale
    pub(crate) fn with_ols_sigmas(&self) -> Option<Self> {
        let all_assumed = self.assumed_sigmas == self.observations.len();
        if !all_assumed || !self.observations.iter().any(Observation::is_angle) {
            return None;
        }
        let w = crate::estimation::POSE_SIGMAS.0 / crate::estimation::POSE_SIGMAS.1;
        let mut data = self.clone();
        for o in &mut data.observations {
            if o.is_angle() {
                let length = if matches!(o, Observation::Camera { .. }) {
                    DEFAULT_CAMERA_SIGMA_MM
                } else {
                    DEFAULT_SIGMA_MM
                };
                *o = o.with_sigma(length / w);
            }
        }
        Some(data)
    }

    /// Each pose's joints and measured rotation of marker `marker`'s frame, where measured.
    pub(crate) fn orientations_of(
        &self,
        marker: usize,
    ) -> impl Iterator<Item = (&Vec<f64>, &UnitQuaternion<f64>)> + '_ {
        self.observations.iter().filter_map(move |o| match o {
            Observation::Orientation { marker: m, axis: 0, pose, measured, .. } if *m == marker => {
                Some((&self.joints[*pose], measured))
            }
            _ => None,
        })
    }

    /// The markers whose frame's orientation is measured (a 6-DOF probe's), ascending: a frame
    /// each on the last link, its origin the marker.
    pub fn probes(&self) -> Vec<usize> {
        distinct(
            (self.observations.iter())
                .filter(|o| matches!(o, Observation::Orientation { .. }))
                .filter_map(Observation::marker),
        )
    }

    /// Whether any observation is of the tool point (or frame): any but a marker's.
    pub fn sees_the_tool(&self) -> bool {
        self.observations.iter().any(|o| o.marker().is_none())
    }

    /// Whether any observation sees the tool point on its own: any but a marker's or a
    /// camera's (a camera's mounting is the tool frame's, its placement the set-up's).
    pub fn measures_the_tool_point(&self) -> bool {
        self.observations.iter().any(|o| o.marker().is_none() && !matches!(o, Observation::Camera { .. }))
    }

    /// Whether any observation is a length (a distance, a coordinate): contacts alone cannot
    /// see the robot's scale.
    pub fn sees_the_scale(&self) -> bool {
        self.observations.iter().any(|o| !matches!(o, Observation::Contact { .. }))
    }

    /// Fixed point `i` by the linear sphere fit of its distances from the nominal tool points
    /// `nominal`: `2 p_k . c - t = |p_k|^2 - m_k^2`, `t = |c|^2` (at least 4, not on one plane).
    fn sphere_start(&self, i: usize, nominal: &[Vector3<f64>]) -> Result<[f64; 3], CalibrationError> {
        let rows: Vec<(Vector3<f64>, f64)> = (self.observations.iter())
            .filter_map(|o| match *o {
                Observation::ToPoint { pose, point, measured, .. } if point == i => {
                    Some((nominal[pose], measured))
                }
                _ => None,
            })
            .collect();
        let few = |what: String| CalibrationError::Observations(what);
        let too_few = || {
            few(format!(
                "fixed point {}: {} distances, expected at least 4 from poses not on one plane",
                i + 1,
                rows.len()
            ))
        };
        if rows.len() < 4 {
            return Err(too_few());
        }
        let a = DMatrix::from_fn(rows.len(), 4, |r, c| if c < 3 { 2.0 * rows[r].0[c] } else { -1.0 });
        let b = DVector::from_fn(rows.len(), |r, _| rows[r].0.norm_squared() - rows[r].1 * rows[r].1);
        let svd = a.svd(true, true);
        let largest = svd.singular_values.max();
        let smallest = svd.singular_values.min();
        if smallest.is_nan() || smallest <= 1e-9 * largest {
            return Err(too_few());
        }
        let c = svd.solve(&b, 1e-12 * largest).map_err(|e| few(e.to_string()))?;
        Ok([c[0], c[1], c[2]])
    }

    /// The set-up and its start values, from the tool frame at every pose on the nominal robot
    /// (`nominal`): each fixed point by the linear sphere fit `2 p_k . c - t = |p_k|^2 - m_k^2`
    /// (`t = |c|^2`; at least 4 distances), each plane by the total least-squares plane of its
    /// contacts (at least 3, not on a line; the normal towards the robot's side, the base
    /// frame's origin, so that a contact's signed distance is positive on the robot's side);
    /// the camera and the target by [`camera_start`].
    pub fn initial_setup(&self, frames: &[Isometry3<f64>]) -> Result<(SetUp, Vec<f64>), CalibrationError> {
        let nominal: Vec<Vector3<f64>> = frames.iter().map(|f| f.translation.vector).collect();
        let (points, planes) = self.setup_counts();
        let mut values = Vec::with_capacity(3 * (points + planes));
        let few = |what: String| CalibrationError::Observations(what);
        for i in 0..points {
            values.extend(self.sphere_start(i, &nominal)?);
        }
        let mut normals = Vec::with_capacity(planes);
        for i in 0..planes {
            let contacts: Vec<Vector3<f64>> = (self.observations.iter())
                .filter_map(|o| match *o {
                    Observation::Contact { pose, plane, .. } if plane == i => Some(nominal[pose]),
                    _ => None,
                })
                .collect();
            let too_few = || {
                few(format!(
                    "plane {}: {} contacts, expected at least 3 not on one line",
                    i + 1,
                    contacts.len()
                ))
            };
            if contacts.len() < 3 {
                return Err(too_few());
            }
            let centroid = contacts.iter().sum::<Vector3<f64>>() / contacts.len() as f64;
            let m = DMatrix::from_fn(contacts.len(), 3, |r, c| contacts[r][c] - centroid[c]);
            let svd = m.svd(false, true);
            let s = &svd.singular_values;
            let mut sorted: Vec<f64> = s.iter().copied().collect();
            sorted.sort_by(|a, b| b.total_cmp(a));
            if sorted[1].is_nan() || sorted[1] <= 1e-9 * sorted[0] {
                return Err(too_few());
            }
            let v_t = svd.v_t.expect("asked for V");
            let smallest = (0..3).min_by(|&a, &b| s[a].total_cmp(&s[b])).expect("3 values");
            let mut n = Vector3::new(v_t[(smallest, 0)], v_t[(smallest, 1)], v_t[(smallest, 2)]).normalize();
            // Towards the robot's side: the base frame's origin, else the largest component up.
            let towards = -n.dot(&centroid);
            let sign = if towards.abs() > 1e-9 * centroid.norm() { towards } else { n[n.iamax()] };
            n *= sign.signum();
            normals.push(n);
            values.extend([0.0, 0.0, n.dot(&centroid)]);
        }
        let mut setup = SetUp::new(points, &normals);
        if let Some(site) = self.camera() {
            let views = self.views();
            let pairs: Vec<(Isometry3<f64>, Isometry3<f64>)> =
                views.iter().map(|&(pose, view)| (frames[pose], isometry(view.as_slice()))).collect();
            let (camera, target) = camera_start(&pairs, site)?;
            for placement in [camera, target] {
                values.extend(
                    placement.translation.vector.iter().chain(placement.rotation.scaled_axis().iter()),
                );
            }
            setup = setup.with_camera(site);
        }
        if self.coordinates_in_their_own_frame() {
            // The device starts in the measuring frame.
            values.extend([0.0; 6]);
            setup = setup.with_device();
        }
        // The length zeros start at 0: each fixed point's, then the pairs'.
        values.extend(std::iter::repeat_n(0.0, points));
        if self.observations.iter().any(|o| matches!(o, Observation::Distance { .. })) {
            values.push(0.0);
            setup = setup.with_pair_zero();
        }
        Ok((setup, values))
    }

    /// Whether coordinates x, y, z are read in a device frame of their own: with markers, whose
    /// measuring frame (a tracker's) is another device's.
    pub fn coordinates_in_their_own_frame(&self) -> bool {
        let xyz = self.observations.iter().any(|o| matches!(o, Observation::Coordinate { axis: ..3, .. }));
        xyz && !self.markers().is_empty()
    }

    /// Every pose a camera saw, once, with its view (the target's pose in the camera frame).
    fn views(&self) -> Vec<(usize, Vector6<f64>)> {
        let mut views: Vec<(usize, Vector6<f64>)> = Vec::new();
        for o in &self.observations {
            if let Observation::Camera { pose, view, .. } = *o
                && views.last().is_none_or(|&(last, _)| last != pose)
            {
                views.push((pose, view));
            }
        }
        views
    }

    /// Refuse observations that do not fit (for data built by hand rather than read): a pose
    /// that does not exist, joint values not one finite value per joint of a robot with
    /// `dof` joints, a sigma not finite and above 0, an axis beyond 5, a line missing, a view
    /// between a tree's frames (a tree's calibration reads those).
    pub fn check(&self, dof: usize) -> Result<(), CalibrationError> {
        let bad = |what: String| Err(CalibrationError::Observations(what));
        if self.lines.len() != self.observations.len() {
            return bad(format!("{} lines for {} observations", self.lines.len(), self.observations.len()));
        }
        if !self.device.is_empty() && self.device.len() != self.observations.len() {
            return bad(format!(
                "{} device rows for {} observations",
                self.device.len(),
                self.observations.len()
            ));
        }
        if let Some(k) = self.joints.iter().position(|q| q.len() != dof || q.iter().any(|v| !v.is_finite())) {
            return bad(format!("pose {k}: expected {dof} finite joint values"));
        }
        check_sessions(&self.sessions)?;
        for (o, line) in self.observations.iter().zip(&self.lines) {
            let poses = match *o {
                Observation::Distance { a, b, .. } => [a, b],
                Observation::ToPoint { pose, .. } | Observation::Contact { pose, .. } => [pose, pose],
                Observation::Coordinate { pose, axis, .. } if axis < 6 => [pose, pose],
                Observation::Marker { pose, axis, .. } | Observation::Orientation { pose, axis, .. }
                    if axis < 3 =>
                {
                    [pose, pose]
                }
                Observation::Marker { axis, .. } | Observation::Orientation { axis, .. } => {
                    return bad(format!("line {line}: a marker's axis {axis}, expected 0 to 2"));
                }
                Observation::Camera { pose, axis, view, .. } if axis < 6 => {
                    if view.iter().any(|v| !v.is_finite()) {
                        return bad(format!("line {line}: a camera's view of finite values expected"));
                    }
                    [pose, pose]
                }
                Observation::Coordinate { axis, .. } | Observation::Camera { axis, .. } => {
                    return bad(format!("line {line}: axis {axis}, expected 0 to 5"));
                }
            };
            if let Observation::Camera { site: CameraSite::Tree { .. }, .. } = *o {
                return bad(format!(
                    "line {line}: a view between a tree's frames: calibrate it on the tree (a URDF with --tips)"
                ));
            }
            if let Observation::Camera { site, .. } = *o
                && Some(site) != self.camera()
            {
                return bad(format!(
                    "line {line}: a camera on the {}, the first camera row's is on the {}: one camera per set",
                    site.name(),
                    self.camera().map_or("?", CameraSite::name)
                ));
            }
            if poses.iter().any(|&p| p >= self.joints.len()) {
                return bad(format!("line {line}: a pose beyond the {} given", self.joints.len()));
            }
            if !(o.sigma().is_finite() && o.sigma() > 0.0 && o.measured().is_finite()) {
                return bad(format!("line {line}: a finite value and a sigma above 0 expected"));
            }
        }
        if self.device.iter().flatten().any(|v| !v.is_finite()) {
            return bad("a device covariance not finite".into());
        }
        Ok(())
    }

    /// Refuse markers that a calibration of the markers `markers` (numbers less one) does not
    /// have, and observations of the tool point if it has none (`tool`).
    pub(super) fn check_points(&self, markers: &[usize], tool: bool) -> Result<(), CalibrationError> {
        if let Some(m) = self.markers().into_iter().find(|m| !markers.contains(m)) {
            let theirs = match markers.is_empty() {
                true => "the calibration has no markers".to_string(),
                false => {
                    let numbers: Vec<String> = markers.iter().map(|m| (m + 1).to_string()).collect();
                    format!("not among the calibration's markers ({})", numbers.join(", "))
                }
            };
            return Err(CalibrationError::Observations(format!("marker {}: {theirs}", m + 1)));
        }
        if self.sees_the_tool() && !tool {
            return Err(CalibrationError::Observations(
                "observations of the tool point (distances, contacts, coordinates), the calibration has markers \
                 only: its tool point was not calibrated"
                    .into(),
            ));
        }
        Ok(())
    }

    /// Refuse points and planes that `setup` does not have, and sessions other than its.
    pub(super) fn check_against(&self, setup: &SetUp) -> Result<(), CalibrationError> {
        let (points, planes) = self.setup_counts();
        if !setup.per_session().is_empty() && self.session_count() != setup.session_count() {
            return Err(CalibrationError::Observations(format!(
                "{} sessions, the set-up has {}",
                self.session_count(),
                setup.session_count()
            )));
        }

        // A tree's views name their frames, each among the set-up's (checked with its views).
        let serial = |site: &CameraSite| !matches!(site, CameraSite::Tree { .. });
        if self.camera().is_some_and(|s| serial(&s)) && self.camera() != setup.camera() {
            return Err(CalibrationError::Observations(format!(
                "a camera on the {}, the calibration's is {}",
                self.camera().map_or("?", CameraSite::name),
                setup.camera().map_or("absent", CameraSite::name)
            )));
        }
        if points > setup.points || planes > setup.planes() {
            return Err(CalibrationError::Observations(format!(
                "{points} fixed points and {planes} planes, the calibration has {} and {}",
                setup.points,
                setup.planes()
            )));
        }
        Ok(())
    }

    /// What these observations cannot see: the base for distances, contacts and a camera, the
    /// scale for contacts alone, the in-plane motions of every plane (its normal at the set-up
    /// values `s`), a device's placement along the axes it does not measure.
    pub(super) fn unseen(&self, setup: &SetUp, s: &[f64]) -> Vec<Unseen> {
        let mut out = Vec::new();
        let distances = self
            .observations
            .iter()
            .any(|o| matches!(o, Observation::Distance { .. } | Observation::ToPoint { .. }));
        if !self.sees_the_base() {
            let absorbed_by = match self.camera() {
                Some(CameraSite::Hand) => BaseAbsorber::Target,
                Some(CameraSite::World) => BaseAbsorber::Camera,
                _ if distances => BaseAbsorber::Distances,
                _ => BaseAbsorber::Planes,
            };
            out.push(Unseen::Base { absorbed_by });
        }
        if !self.sees_the_scale() && setup.planes() > 0 {
            out.push(Unseen::Scale);
        }
        for i in 0..setup.planes() {
            let (n, d) = setup.plane(s, i);
            // Rounded first, so that a tiny negative prints as 0.0000, not -0.0000.
            let n = n.map(|v| (v * 1e4).round() / 1e4 + 0.0);
            out.push(Unseen::Plane { plane: i + 1, normal: [n.x, n.y, n.z], offset_mm: d });
        }
        if setup.device() {
            let held = self.device_unseen();
            if !held.is_empty() {
                let parameters = held.iter().map(|&i| format!("device.{}", DEVICE_AXES[i])).collect();
                out.push(Unseen::Device { parameters });
            }
        }
        out
    }

    /// The device parameters (0-5: x, y, z, rx, ry, rz of [`SetUp::with_device`]) the measured
    /// coordinates cannot see: the translations along the axes not measured and, with one axis
    /// measured, the rotation about it.
    pub fn device_unseen(&self) -> Vec<usize> {
        let mut measured = [false; 3];
        for o in &self.observations {
            if let Observation::Coordinate { axis: axis @ ..3, .. } = *o {
                measured[axis] = true;
            }
        }
        let one = measured.iter().filter(|&&m| m).count() == 1;
        (0..6).filter(|&i| if i < 3 { !measured[i] } else { one && measured[i - 3] }).collect()
    }
}

/// `numbers` ascending, each once.
fn distinct(numbers: impl Iterator<Item = usize>) -> Vec<usize> {
    // Few distinct numbers among many (a marker's number in each of 600k observations): each
    // inserted in order where it is new, not every one collected and sorted.
    let mut distinct: Vec<usize> = Vec::new();
    for n in numbers {
        if let Err(at) = distinct.binary_search(&n) {
            distinct.insert(at, n);
        }
    }
    distinct
}

/// The names of a device's placement parameters.
const DEVICE_AXES: [&str; 6] = ["x", "y", "z", "rx", "ry", "rz"];

/// The kind of a row's observation.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum RowKind {
    /// A distance between two poses.
    Pair,
    /// A distance to a fixed point.
    ToPoint,
    /// A contact with a plane.
    Contact,
    /// Coordinates.
    Coordinates,
    /// A camera's view of its target.
    Camera,
    /// Marker positions (a `calibrate --data` file): no `kind` cell names it.
    Markers,
}

impl RowKind {
    /// The kind of a `kind` cell.
    fn named(cell: &str) -> Option<Self> {
        Some(match cell {
            "pair" => Self::Pair,
            "point" => Self::ToPoint,
            "contact" => Self::Contact,
            "coordinates" => Self::Coordinates,
            "camera" => Self::Camera,
            _ => return None,
        })
    }
}

/// Where the quantities of an observation file stand in its header.
struct KindColumns {
    joints: Vec<usize>,
    /// Every `<joint>_b`, if the file has them all.
    second: Option<Vec<usize>>,
    distance: Option<usize>,
    point: Option<usize>,
    plane: Option<usize>,
    /// x, y, z, roll, pitch, yaw.
    axes: [Option<usize>; 6],
    sigma: Option<usize>,
    sigma_angle: Option<usize>,
    /// `camera`: `hand` or `world`.
    camera: Option<usize>,
    /// Each marker's number and its `x<k>, y<k>, z<k>` columns.
    markers: Vec<(usize, [usize; 3])>,
    /// A probe's orientation, `qw,qx,qy,qz` or `roll,pitch,yaw` (a marker file's, with one
    /// marker), or none.
    orientation: Vec<usize>,
    /// The `kind` column, or the one kind of a file without it.
    kind: Option<usize>,
    file_kind: Option<RowKind>,
    /// The sigmas of rows without a `sigma` (`sigma_angle`) cell, where the user gave them.
    defaults: RowSigmaDefaults,
}

impl KindColumns {
    /// Find the columns of `table`'s header; without a `kind` column, the file's one kind.
    fn resolve(table: &Table, model: &RobotModel) -> Result<Self, DataError> {
        let header = |column: Option<&str>, m: &str| DataError::new(table.header_line, column, m);
        let second: Vec<Option<usize>> =
            model.joints.iter().map(|j| table.column(&format!("{}_b", j.name))).collect();
        let pairs = second.iter().any(Option::is_some);
        if pairs && second.iter().any(Option::is_none) {
            return Err(header(None, "pairs of poses need every joint of the second pose: <joint>_b"));
        }
        let columns = Self {
            joints: table.joint_columns(model)?,
            second: pairs.then(|| second.into_iter().flatten().collect()),
            distance: table.column("distance"),
            point: table.column("point"),
            plane: table.column("plane"),
            axes: ["x", "y", "z", "roll", "pitch", "yaw"].map(|c| table.column(c)),
            sigma: table.column("sigma"),
            sigma_angle: table.column("sigma_angle"),
            camera: table.column("camera"),
            markers: crate::calibration::data::marker_columns(table)?,
            orientation: Vec::new(),
            kind: table.column("kind"),
            file_kind: None,
            defaults: RowSigmaDefaults::default(),
        };
        if !columns.markers.is_empty() {
            use crate::calibration::data::{OTHER_KINDS, orientation_columns, other_kinds_column};
            // A marker file's own columns of other kinds; a probe's orientation is its own.
            if let Some(name) = other_kinds_column(table, &columns.joints, &OTHER_KINDS) {
                return Err(header(
                    Some(name),
                    "a marker file (x1,y1,z1, ...) has marker positions and a probe's orientation only: give \
                     the other kinds in files of their own",
                ));
            }
            let orientation = orientation_columns(table, &columns.markers)?;
            return Ok(Self { file_kind: Some(RowKind::Markers), orientation, ..columns });
        }
        if columns.kind.is_some() {
            return Ok(columns);
        }
        let camera = columns.camera.is_some();
        let coordinates = columns.axes.iter().any(Option::is_some) && !camera;
        let kinds = [columns.distance.is_some(), columns.plane.is_some(), coordinates, camera];
        if kinds.iter().filter(|&&k| k).count() != 1 {
            return Err(header(
                None,
                "expected one kind: a `distance` column (pairs or to a `point`), a `plane` column, coordinates \
                 (x, y, z, roll, pitch, yaw), or a `camera` column (hand or world) with a camera's view of its \
                 target (x, y, z, roll, pitch, yaw); or a `kind` column naming each row's",
            ));
        }
        if pairs && columns.point.is_some() {
            return Err(header(
                Some("point"),
                "a distance is between two poses or to a fixed point, not both",
            ));
        }
        let file_kind = match kinds {
            [true, ..] if pairs => RowKind::Pair,
            [true, ..] => RowKind::ToPoint,
            [_, true, ..] => RowKind::Contact,
            [_, _, true, _] => RowKind::Coordinates,
            _ => RowKind::Camera,
        };
        Ok(Self { file_kind: Some(file_kind), ..columns })
    }

    /// `column` of `row`, which its kind needs: an error naming it if absent or empty.
    fn needed(&self, row: &Row, column: Option<usize>, name: &str) -> Result<usize, DataError> {
        column.filter(|&c| !row.cells[c].is_empty()).ok_or_else(|| {
            DataError::new(row.line, Some(name), format!("this kind of row needs a `{name}` value"))
        })
    }

    /// The observation of `row`, a `kind` row, with its pose (two for a pair), into `data`.
    fn read_row(
        &self,
        table: &Table,
        row: &Row,
        kind: RowKind,
        model: &RobotModel,
        units: Units,
        data: &mut KindData,
    ) -> Result<(), DataError> {
        let sigmas = self.sigmas(table, row, kind, units)?;
        let s = sigmas.length;
        let pose = data.joints.len();
        data.joints.push(table.joint_values(row, &self.joints, model, units)?);
        let observations = match kind {
            RowKind::Pair => {
                let second = self.second.as_ref().ok_or_else(|| {
                    DataError::new(
                        row.line,
                        Some("kind"),
                        "a pair needs the second pose's columns, <joint>_b",
                    )
                })?;
                let c = self.needed(row, self.distance, "distance")?;
                let measured = positive(table, row, c, units.length_scale())?;
                data.joints.push(table.joint_values(row, second, model, units)?);
                vec![Observation::Distance { a: pose, b: pose + 1, measured, sigma: s }]
            }
            RowKind::ToPoint => {
                let c = self.needed(row, self.distance, "distance")?;
                let measured = positive(table, row, c, units.length_scale())?;
                let point = self.optional(row, self.point).map_or(Ok(0), |c| id(table, row, c))?;
                vec![Observation::ToPoint { pose, point, measured, sigma: s }]
            }
            RowKind::Contact => {
                let c = self.needed(row, self.plane, "plane")?;
                vec![Observation::Contact { pose, plane: id(table, row, c)?, sigma: s }]
            }
            RowKind::Camera => self.camera_row(table, row, pose, &sigmas, units, data.camera())?,
            RowKind::Markers => self.marker_row(table, row, (pose, &sigmas), units)?,
            RowKind::Coordinates => self.coordinate_row(table, row, pose, &sigmas, units)?,
        };
        for o in observations {
            let assumed = if o.is_angle() { sigmas.assumed.1 } else { sigmas.assumed.0 };
            data.assumed_sigmas += usize::from(assumed);
            data.observations.push(o);
            data.lines.push(row.line);
        }
        Ok(())
    }

    /// `column` of `row` if the file has it and the cell is not empty.
    fn optional(&self, row: &Row, column: Option<usize>) -> Option<usize> {
        column.filter(|&c| !row.cells[c].is_empty())
    }

    /// The sigmas of `row` (its `sigma` and `sigma_angle` cells, or the defaults of its `kind`).
    fn sigmas(&self, table: &Table, row: &Row, kind: RowKind, units: Units) -> Result<RowSigmas, DataError> {
        let (default_mm, default_deg) = match kind {
            RowKind::Camera => (DEFAULT_CAMERA_SIGMA_MM, DEFAULT_CAMERA_SIGMA_DEG),
            _ => (DEFAULT_SIGMA_MM, DEFAULT_SIGMA_ANGLE_DEG),
        };
        let given = self.defaults;
        let (length, angle) = (self.optional(row, self.sigma), self.optional(row, self.sigma_angle));
        Ok(RowSigmas {
            length: match length {
                Some(c) => positive(table, row, c, units.length_scale())?,
                None => given.length_mm.unwrap_or(default_mm),
            },
            angle: match angle {
                Some(c) => units.angle(positive(table, row, c, 1.0)?),
                None => given.angle_rad.unwrap_or_else(|| default_deg.to_radians()),
            },
            assumed: (
                length.is_none() && given.length_mm.is_none(),
                angle.is_none() && given.angle_rad.is_none(),
            ),
        })
    }

    /// A camera's view of `row`: six observations, the camera's site the same as the earlier
    /// rows' (`first`).
    fn camera_row(
        &self,
        table: &Table,
        row: &Row,
        pose: usize,
        sigmas: &RowSigmas,
        units: Units,
        first: Option<CameraSite>,
    ) -> Result<Vec<Observation>, DataError> {
        let c = self.needed(row, self.camera, "camera")?;
        let site = match &row.cells[c] {
            "hand" => CameraSite::Hand,
            "world" => CameraSite::World,
            other => {
                let message = format!("`{other}`: expected hand (on the arm) or world (fixed)");
                return Err(DataError::new(row.line, Some("camera"), message));
            }
        };
        if let Some(first) = first
            && first != site
        {
            let message = format!(
                "a camera on the {}, the earlier rows' is on the {}: one camera per file",
                site.name(),
                first.name()
            );
            return Err(DataError::new(row.line, Some("camera"), message));
        }
        let mut v = [0.0; 6];
        for (axis, name) in ["x", "y", "z", "roll", "pitch", "yaw"].into_iter().enumerate() {
            let c = self.needed(row, self.axes[axis], name)?;
            let value = table.number(row, c)?;
            v[axis] = match axis < 3 {
                true => table.within(row, c, value * units.length_scale(), MAX_LENGTH_MM, "mm")?,
                false => units.angle(value),
            };
        }
        let rotation = UnitQuaternion::from_euler_angles(v[3], v[4], v[5]).scaled_axis();
        let view = Vector6::new(v[0], v[1], v[2], rotation.x, rotation.y, rotation.z);
        Ok((0..6)
            .map(|axis| {
                let sigma = if axis < 3 { sigmas.length } else { sigmas.angle };
                Observation::Camera { axis, pose, view, site, sigma }
            })
            .collect())
    }

    /// The marker coordinates of `row` (its non-empty cells: at least one), each with the
    /// length sigma; and a probe's orientation, three rows with the angle sigma, unless its
    /// cells are all empty.
    fn marker_row(
        &self,
        table: &Table,
        row: &Row,
        (pose, sigmas): (usize, &RowSigmas),
        units: Units,
    ) -> Result<Vec<Observation>, DataError> {
        let mut observations = Vec::new();
        for &(k, cells) in &self.markers {
            for (axis, c) in cells.into_iter().enumerate() {
                let Some(c) = self.optional(row, Some(c)) else { continue };
                let v = table.number(row, c)? * units.length_scale();
                let measured = table.within(row, c, v, MAX_LENGTH_MM, "mm")?;
                let sigma = sigmas.length;
                observations.push(Observation::Marker { marker: k - 1, axis, pose, measured, sigma });
            }
        }
        if self.orientation.iter().any(|&c| !row.cells[c].is_empty()) {
            let measured = crate::calibration::data::orientation(table, row, &self.orientation, units)?;
            let (marker, sigma) = (self.markers[0].0 - 1, sigmas.angle);
            observations.extend((0..3).map(|axis| Observation::Orientation {
                marker,
                axis,
                pose,
                measured,
                sigma,
            }));
        }
        if observations.is_empty() {
            return Err(DataError::new(row.line, None, "no marker coordinate: every cell is empty"));
        }
        Ok(observations)
    }

    /// The coordinates of `row` (x, y, z in mm and roll, pitch, yaw: at least one).
    fn coordinate_row(
        &self,
        table: &Table,
        row: &Row,
        pose: usize,
        sigmas: &RowSigmas,
        units: Units,
    ) -> Result<Vec<Observation>, DataError> {
        let mut observations = Vec::new();
        for (axis, c) in self.axes.iter().enumerate() {
            let Some(c) = self.optional(row, *c) else { continue };
            let v = table.number(row, c)?;
            let (measured, sigma) = if axis < 3 {
                (table.within(row, c, v * units.length_scale(), MAX_LENGTH_MM, "mm")?, sigmas.length)
            } else {
                (units.angle(v), sigmas.angle)
            };
            observations.push(Observation::Coordinate { pose, axis, measured, sigma });
        }
        if observations.is_empty() {
            let message = "no coordinate: give at least one of x, y, z, roll, pitch, yaw";
            return Err(DataError::new(row.line, None, message));
        }
        Ok(observations)
    }
}

/// A value `> 0` of `column` (in the length unit, scaled to mm by `scale`).
fn positive(table: &Table, row: &Row, column: usize, scale: f64) -> Result<f64, DataError> {
    let v = table.number(row, column)? * scale;
    if v <= 0.0 {
        return Err(DataError::new(
            row.line,
            Some(&table.header[column]),
            format!("{v}: expected a value > 0"),
        ));
    }
    table.within(row, column, v, MAX_LENGTH_MM, "mm")
}

/// A point or plane number (1, 2, ...) of `column`, 0-based.
fn id(table: &Table, row: &Row, column: usize) -> Result<usize, DataError> {
    let v = table.number(row, column)?;
    if v < 1.0 || v.fract() != 0.0 || v > 1000.0 {
        return Err(DataError::new(
            row.line,
            Some(&table.header[column]),
            format!("{v}: expected a number 1, 2, ... (at most 1000)"),
        ));
    }
    Ok(v as usize - 1)
}

/// A row's measurement sigmas: lengths (mm), angles (rad), and whether each is the default.
struct RowSigmas {
    length: f64,
    angle: f64,
    assumed: (bool, bool),
}
