//! The measurement file: one row per pose, joint values and measured marker positions.
//!
//! ```text
//! # units: joints=deg, lengths=mm
//! j1,j2,j3,j4,j5,j6,x1,y1,z1,x2,y2,z2,sigma
//! 10.0,45.0,-30.0,0.0,20.0,5.0,512.3,-140.2,601.7,498.1,-160.0,612.4,0.02
//! ```
//!
//! Joint columns are named after the model's joints; markers are `x1,y1,z1`, `x2,y2,z2`, ...;
//! `sigma` (optional) is the row's measurement standard deviation, in the length unit. With a
//! single marker, the orientation of the measured frame (a 6-DOF probe whose origin is the
//! marker) may follow as `qw,qx,qy,qz` or as `roll,pitch,yaw` (the joints' angle unit,
//! `R = Rz(yaw) Ry(pitch) Rx(roll)`). Units
//! are declared by the first line (`# units: joints=deg|rad, lengths=mm|m`) or by the caller;
//! prismatic joints take the length unit. Other columns are ignored and listed. Lines starting
//! with `#` are comments.

use crate::model::{JointKind, RobotModel};
use nalgebra::{UnitQuaternion, Vector3};

/// Units of a measurement file.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Units {
    /// Revolute joint values in degrees (true) or radians.
    pub joints_in_degrees: bool,
    /// Lengths in metres (true) or millimetres.
    pub lengths_in_metres: bool,
}

/// A measurement file that could not be read: where and why.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("line {line}{}: {message}", column.as_ref().map(|c| format!(", column `{c}`")).unwrap_or_default())]
pub struct DataError {
    /// Line in the file (1-based).
    pub line: usize,
    /// The column, where one is at fault.
    pub column: Option<String>,
    /// What is wrong and what was expected.
    pub message: String,
}

/// Measured poses, in mm and rad.
#[derive(Debug, Clone, PartialEq)]
pub struct Measurements {
    /// Joint values of each pose (rad, mm for prismatic joints).
    pub joints: Vec<Vec<f64>>,
    /// Measured marker positions of each pose (mm), marker by marker.
    pub markers: Vec<Vec<Vector3<f64>>>,
    /// Measurement standard deviation of each pose (mm), if the file gives one.
    pub sigma: Option<Vec<f64>>,
    /// Measured orientation of the frame at marker 1, if the file gives one.
    pub orientations: Option<Vec<UnitQuaternion<f64>>>,
    /// The file line of each pose.
    pub lines: Vec<usize>,
    /// Columns that were not used.
    pub ignored: Vec<String>,
}

impl Measurements {
    /// Number of poses.
    pub fn len(&self) -> usize {
        self.joints.len()
    }

    /// Whether there are no poses.
    pub fn is_empty(&self) -> bool {
        self.joints.is_empty()
    }

    /// Number of markers per pose.
    pub fn marker_count(&self) -> usize {
        self.markers.first().map_or(0, Vec::len)
    }

    /// The poses at `indices`, in that order.
    pub fn subset(&self, indices: &[usize]) -> Self {
        Self {
            joints: indices.iter().map(|&i| self.joints[i].clone()).collect(),
            markers: indices.iter().map(|&i| self.markers[i].clone()).collect(),
            sigma: self.sigma.as_ref().map(|s| indices.iter().map(|&i| s[i]).collect()),
            orientations: self.orientations.as_ref().map(|o| indices.iter().map(|&i| o[i]).collect()),
            lines: indices.iter().map(|&i| self.lines[i]).collect(),
            ignored: self.ignored.clone(),
        }
    }

    /// Read a measurement file's text for `model`. `units` declared by the caller take the
    /// place of the file's `# units:` line; one of the two must declare them.
    pub fn from_csv_str(text: &str, model: &RobotModel, units: Option<Units>) -> Result<Self, DataError> {
        let error = |line: usize, column: Option<&str>, message: String| DataError {
            line,
            column: column.map(str::to_string),
            message,
        };
        let units = match (units, declared_units(text)?) {
            (Some(units), _) | (None, Some(units)) => units,
            (None, None) => {
                return Err(error(
                    1,
                    None,
                    "units not declared: start the file with `# units: joints=deg, lengths=mm` (or rad, m) \
                     or give --joint-unit and --length-unit"
                        .into(),
                ));
            }
        };
        let CsvTable { mut reader, header, header_line } = csv_table(text).map_err(|e| error(1, None, e))?;
        let find = |name: &str| header.iter().position(|h| h == name);
        let joint_columns = table_joint_columns(&header, header_line, model)?;
        let mut marker_columns = Vec::new();
        while let Some(x) = find(&format!("x{}", marker_columns.len() + 1)) {
            let k = marker_columns.len() + 1;
            let (y, z) = (find(&format!("y{k}")), find(&format!("z{k}")));
            match (y, z) {
                (Some(y), Some(z)) => marker_columns.push([x, y, z]),
                _ => {
                    return Err(error(
                        header_line,
                        Some(&format!("x{k}")),
                        format!("marker {k} needs y{k} and z{k} too"),
                    ));
                }
            }
        }
        if marker_columns.is_empty() {
            return Err(error(
                header_line,
                None,
                "no marker columns: expected x1,y1,z1 (and x2,y2,z2, ...)".into(),
            ));
        }
        let sigma_column = find("sigma");
        let quaternion = ["qw", "qx", "qy", "qz"].map(find);
        let rpy = ["roll", "pitch", "yaw"].map(find);
        let orientation_columns: Vec<usize> = match (quaternion, rpy) {
            ([Some(w), Some(x), Some(y), Some(z)], [None, None, None]) => vec![w, x, y, z],
            ([None, None, None, None], [Some(r), Some(p), Some(y)]) => vec![r, p, y],
            ([None, None, None, None], [None, None, None]) => Vec::new(),
            _ => {
                let message =
                    "orientation: give all of qw,qx,qy,qz or all of roll,pitch,yaw, not parts or both";
                return Err(error(header_line, None, message.into()));
            }
        };
        if !orientation_columns.is_empty() && marker_columns.len() != 1 {
            let message =
                "orientation columns need exactly one marker (x1,y1,z1): the measured frame's origin";
            return Err(error(header_line, None, message.into()));
        }
        let used: Vec<usize> = joint_columns
            .iter()
            .copied()
            .chain(marker_columns.iter().flatten().copied())
            .chain(sigma_column)
            .chain(orientation_columns.iter().copied())
            .collect();
        let ignored = (0..header.len()).filter(|i| !used.contains(i)).map(|i| header[i].clone()).collect();

        let length = if units.lengths_in_metres { 1000.0 } else { 1.0 };
        let mut data = Self {
            joints: Vec::new(),
            markers: Vec::new(),
            sigma: sigma_column.map(|_| Vec::new()),
            orientations: (!orientation_columns.is_empty()).then(Vec::new),
            lines: Vec::new(),
            ignored,
        };
        for record in reader.records() {
            let record = record
                .map_err(|e| error(e.position().map_or(0, |p| p.line() as usize), None, e.to_string()))?;
            let line = record.position().map_or(0, |p| p.line() as usize);
            if record.len() < header.len() {
                return Err(error(
                    line,
                    None,
                    format!("{} values, the header has {}", record.len(), header.len()),
                ));
            }
            let value = |column: usize| -> Result<f64, DataError> {
                let text = &record[column];
                let v: f64 = text
                    .parse()
                    .map_err(|_| error(line, Some(&header[column]), format!("`{text}` is not a number")))?;
                if v.is_finite() {
                    Ok(v)
                } else {
                    Err(error(line, Some(&header[column]), format!("{v}: expected a finite number")))
                }
            };
            let joints = model
                .joints
                .iter()
                .zip(&joint_columns)
                .map(|(joint, &c)| {
                    let v = value(c)?;
                    Ok(match joint.kind {
                        JointKind::Revolute if units.joints_in_degrees => v.to_radians(),
                        JointKind::Revolute => v,
                        JointKind::Prismatic => v * length,
                    })
                })
                .collect::<Result<Vec<_>, _>>()?;
            let markers = marker_columns
                .iter()
                .map(|&[x, y, z]| Ok(Vector3::new(value(x)?, value(y)?, value(z)?) * length))
                .collect::<Result<Vec<_>, DataError>>()?;
            if let (Some(c), Some(sigmas)) = (sigma_column, data.sigma.as_mut()) {
                let s = value(c)?;
                if s <= 0.0 {
                    return Err(error(
                        line,
                        Some("sigma"),
                        format!("{s}: expected a standard deviation > 0"),
                    ));
                }
                sigmas.push(s * length);
            }
            if let Some(orientations) = data.orientations.as_mut() {
                let v = orientation_columns.iter().map(|&c| value(c)).collect::<Result<Vec<_>, _>>()?;
                let rotation = if let [w, x, y, z] = v[..] {
                    let q = nalgebra::Quaternion::new(w, x, y, z);
                    if (q.norm() - 1.0).abs() > 1e-3 {
                        return Err(error(
                            line,
                            Some("qw"),
                            format!("a unit quaternion, its norm is {:.6}", q.norm()),
                        ));
                    }
                    UnitQuaternion::from_quaternion(q)
                } else {
                    let angle = |a: f64| if units.joints_in_degrees { a.to_radians() } else { a };
                    UnitQuaternion::from_euler_angles(angle(v[0]), angle(v[1]), angle(v[2]))
                };
                orientations.push(rotation);
            }
            data.joints.push(joints);
            data.markers.push(markers);
            data.lines.push(line);
        }
        if data.is_empty() {
            return Err(error(header_line, None, "no poses after the header".into()));
        }
        Ok(data)
    }
}

/// A CSV file opened past its header.
pub(crate) struct CsvTable<'a> {
    /// The rows after the header.
    pub reader: csv::Reader<&'a [u8]>,
    /// The header's cells.
    pub header: Vec<String>,
    /// The header's line number (1-based).
    pub header_line: usize,
}

/// The column of each of `model`'s joints in `header` (read from line `header_line`), named
/// after the joint; an error names the first joint missing and lists the model's joints.
pub(crate) fn table_joint_columns(
    header: &[String],
    header_line: usize,
    model: &RobotModel,
) -> Result<Vec<usize>, DataError> {
    model
        .joints
        .iter()
        .map(|j| {
            header.iter().position(|h| *h == j.name).ok_or_else(|| {
                let expected: Vec<&str> = model.joints.iter().map(|j| j.name.as_str()).collect();
                DataError {
                    line: header_line,
                    column: Some(j.name.clone()),
                    message: format!("missing joint column; the model's joints are {}", expected.join(", ")),
                }
            })
        })
        .collect()
}

/// A CSV file with `#` comments, trimmed cells and rows of any length, opened past its header;
/// or why there is no header.
pub(crate) fn csv_table(text: &str) -> Result<CsvTable<'_>, String> {
    let mut reader = csv::ReaderBuilder::new()
        .comment(Some(b'#'))
        .trim(csv::Trim::All)
        .flexible(true)
        .from_reader(text.as_bytes());
    let header: Vec<String> = match reader.headers() {
        Ok(cells) => cells.iter().map(str::to_string).collect(),
        Err(e) => return Err(format!("no header row: {e}")),
    };
    let header_line =
        text.lines().position(|l| !l.trim_start().starts_with('#') && !l.trim().is_empty()).unwrap_or(0) + 1;
    Ok(CsvTable { reader, header, header_line })
}

/// The units of a `# units: joints=deg, lengths=mm` line, if the file has one.
pub(crate) fn declared_units(text: &str) -> Result<Option<Units>, DataError> {
    for (i, line) in text.lines().enumerate() {
        let Some(rest) = line.trim().strip_prefix('#') else { break };
        let Some(spec) = rest.trim().strip_prefix("units:") else { continue };
        let bad = |message: String| DataError { line: i + 1, column: None, message };
        let (mut joints, mut lengths) = (None, None);
        for part in spec.split(',').map(str::trim).filter(|p| !p.is_empty()) {
            match part.split_once('=').map(|(k, v)| (k.trim(), v.trim())) {
                Some(("joints", "deg")) => joints = Some(true),
                Some(("joints", "rad")) => joints = Some(false),
                Some(("lengths", "mm")) => lengths = Some(false),
                Some(("lengths", "m")) => lengths = Some(true),
                _ => {
                    return Err(bad(format!(
                        "`{part}` in the units line: expected joints=deg|rad and lengths=mm|m"
                    )));
                }
            }
        }
        return match (joints, lengths) {
            (Some(j), Some(l)) => Ok(Some(Units { joints_in_degrees: j, lengths_in_metres: l })),
            _ => Err(bad("the units line must give both joints=deg|rad and lengths=mm|m".into())),
        };
    }
    Ok(None)
}
