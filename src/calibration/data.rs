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
//! prismatic joints take the length unit. An observation file's columns (`distance`, `x`, ...)
//! are refused: such a file fits two kinds. Other columns are ignored and listed. Lines starting
//! with `#` are comments.

use crate::limits::MAX_LENGTH_MM;
use crate::model::RobotModel;
use crate::table::{DataError, Row, Table, Units};
use nalgebra::{UnitQuaternion, Vector3};

/// What a data file holds, read from its header: which calibration reads it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum DataKind {
    /// Marker positions, or a probe's poses: `x1,y1,z1`, ... ([`Measurements`]).
    Markers,
    /// Distances, plane contacts, coordinates or a camera's views of its target
    /// ([`kinds`](super::kinds)).
    Observations,
    /// Views between the branches of a tree: `camera` and `target` links
    /// ([`tree`](super::tree)).
    TreeViews,
}

impl DataKind {
    /// The kind of the CSV `text`: a `target` column makes tree views, marker columns
    /// (`x<k>`) a marker file, anything else observations (whose reader checks the rest). A
    /// marker file with an empty marker or orientation cell (a marker not measured at a pose:
    /// an occlusion) is read cell by cell, as observations
    /// ([`Observation::Marker`](super::kinds::Observation)).
    pub fn of_csv_str(text: &str) -> Result<Self, DataError> {
        // The header (the comments and the units line before it) parsed; the rows are only
        // scanned for empty marker cells, and read once, by the calibration that takes the file.
        let mut end = 0;
        for line in text.split_inclusive('\n') {
            end += line.len();
            if !line.trim().is_empty() && !line.trim_start().starts_with('#') {
                break;
            }
        }
        let table = Table::parse(&text[..end])?;
        let markers = marker_columns(&table)?;
        // A probe's orientation too (a header the readers refuse, they say why).
        let orientation = orientation_columns(&table, &markers).unwrap_or_default();
        let measured: Vec<usize> = markers.iter().flat_map(|(_, c)| *c).chain(orientation).collect();
        Ok(match (table.column("target"), markers.is_empty()) {
            (Some(_), _) => Self::TreeViews,
            (None, false) if leaves_a_cell_empty(&text[end..], &measured) => Self::Observations,
            (None, false) => Self::Markers,
            (None, true) => Self::Observations,
        })
    }

    /// What the kind is, in words.
    pub fn describe(self) -> &'static str {
        match self {
            Self::Markers => "marker positions (x1,y1,z1, ...)",
            Self::Observations => "observations (distances, contacts, coordinates, camera views)",
            Self::TreeViews => "views between a tree's branches (camera, target)",
        }
    }
}

/// Whether a row of `rows` (a CSV's lines after its header) leaves one of the `columns` (a
/// marker's, a probe's orientation) empty; comments and blank lines are no rows.
/// Scanned on rayon's threads, in pieces of whole lines.
fn leaves_a_cell_empty(rows: &str, columns: &[usize]) -> bool {
    use rayon::prelude::*;
    let pieces = crate::table::line_chunks(rows, 1 << 16);
    pieces.into_par_iter().any(|(_, piece)| {
        (piece.lines().map(str::trim)).filter(|l| !l.is_empty() && !l.starts_with('#')).any(|line| {
            line.split(',').enumerate().any(|(i, cell)| cell.trim().is_empty() && columns.contains(&i))
        })
    })
}

/// Measured poses, in mm and rad.
#[derive(Debug, Clone, PartialEq)]
pub struct Measurements {
    /// Joint values of each pose (rad, mm for prismatic joints).
    pub joints: Vec<Vec<f64>>,
    /// Measured marker positions of each pose (mm), marker by marker.
    pub markers: Vec<Vec<Vector3<f64>>>,
    /// The number of each marker in the file (`x3,y3,z3` is marker 3), in the order of
    /// [`Measurements::markers`]; ascending.
    pub marker_ids: Vec<usize>,
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
            marker_ids: self.marker_ids.clone(),
            sigma: self.sigma.as_ref().map(|s| indices.iter().map(|&i| s[i]).collect()),
            orientations: self.orientations.as_ref().map(|o| indices.iter().map(|&i| o[i]).collect()),
            lines: indices.iter().map(|&i| self.lines[i]).collect(),
            ignored: self.ignored.clone(),
        }
    }

    /// The same poses with only the markers numbered `ids` that the file has, in the file's
    /// order; `None` if it has none of them.
    pub fn with_markers(&self, ids: &[usize]) -> Option<Self> {
        let keep: Vec<usize> =
            (0..self.marker_ids.len()).filter(|&m| ids.contains(&self.marker_ids[m])).collect();
        if keep.is_empty() {
            return None;
        }
        Some(Self {
            markers: self.markers.iter().map(|pose| keep.iter().map(|&m| pose[m]).collect()).collect(),
            marker_ids: keep.iter().map(|&m| self.marker_ids[m]).collect(),
            ..self.clone()
        })
    }

    /// Read a measurement file's text for `model`, in the units of its `# units:` line, or
    /// else the `units` declared by the caller (which must agree with the line where both
    /// are given).
    pub fn from_csv_str(text: &str, model: &RobotModel, units: Option<Units>) -> Result<Self, DataError> {
        Self::from_table(&Table::parse(text)?, model, units)
    }

    /// The measurements of a table already read: its columns resolved once, then row by row.
    pub(crate) fn from_table(
        table: &Table,
        model: &RobotModel,
        units: Option<Units>,
    ) -> Result<Self, DataError> {
        let units = table.units(units, " or give --joint-unit and --length-unit")?;
        let columns = Columns::resolve(table, model)?;
        check_markers_measured(table, &columns.markers)?;
        let mut data = Self {
            joints: Vec::new(),
            markers: Vec::new(),
            marker_ids: columns.markers.iter().map(|m| m.0).collect(),
            sigma: columns.sigma.map(|_| Vec::new()),
            orientations: (!columns.orientation.is_empty()).then(Vec::new),
            lines: Vec::new(),
            ignored: columns.ignored(table),
        };
        for row in table.nonempty_rows()? {
            data.joints.push(table.joint_values(row, &columns.joints, model, units)?);
            data.markers.push(columns.markers(table, row, units)?);
            if let Some(sigmas) = data.sigma.as_mut() {
                sigmas.push(columns.sigma(table, row, units)?);
            }
            if let Some(orientations) = data.orientations.as_mut() {
                orientations.push(columns.orientation(table, row, units)?);
            }
            data.lines.push(row.line);
        }
        Ok(data)
    }
}

/// The columns of an observation file that a marker file cannot have (its `roll`, `pitch`,
/// `yaw` are a probe's orientation).
pub(crate) const OTHER_KINDS: [&str; 8] = ["kind", "distance", "point", "plane", "camera", "x", "y", "z"];

/// The first of `names` that `table` has as a column other than a joint's (`joints`: the
/// joint columns; a gantry's joint may be named `x`).
pub(crate) fn other_kinds_column<'n>(table: &Table, joints: &[usize], names: &[&'n str]) -> Option<&'n str> {
    names.iter().copied().find(|c| table.column(c).is_some_and(|i| !joints.contains(&i)))
}

/// The number `k` and the columns `x_k, y_k, z_k` of each marker of `table`'s header, by
/// number: markers are numbered by their columns, `x1,y1,z1`, `x3,y3,z3`, ... (gaps allowed);
/// an `x_k` without its `y_k` or `z_k` is an error, and so are a `y_k` or `z_k` without its
/// `x_k` and a marker column spelled other than in lower case (`X1`), which would otherwise
/// drop the marker.
pub(crate) fn marker_columns(table: &Table) -> Result<Vec<(usize, [usize; 3])>, DataError> {
    let mut markers = Vec::new();
    for name in &table.header {
        let lower = name.to_ascii_lowercase();
        let number = lower.get(1..).and_then(|n| n.parse::<usize>().ok()).filter(|&k| k > 0);
        if let (Some(k), Some(axis @ ('x' | 'y' | 'z'))) = (number, lower.chars().next()) {
            let expected = format!("{axis}{k}");
            if *name != expected {
                let message =
                    format!("expected `{expected}`: marker columns are x{k},y{k},z{k}, in lower case");
                return Err(DataError::new(table.header_line, Some(name), message));
            }
            if axis != 'x' && table.column(&format!("x{k}")).is_none() {
                let message = format!("marker {k} needs x{k} too: its columns are x{k},y{k},z{k}");
                return Err(DataError::new(table.header_line, Some(name), message));
            }
        }
        let Some(k) = name.strip_prefix('x').and_then(|n| n.parse::<usize>().ok()).filter(|&k| k > 0) else {
            continue;
        };
        let x = table.column(name).expect("a header cell");
        match (table.column(&format!("y{k}")), table.column(&format!("z{k}"))) {
            (Some(y), Some(z)) => markers.push((k, [x, y, z])),
            _ => {
                let message = format!("marker {k} needs y{k} and z{k} too");
                return Err(DataError::new(table.header_line, Some(name), message));
            }
        }
    }
    markers.sort_by_key(|m| m.0);
    Ok(markers)
}

/// Refuse a marker of `markers` (from [`marker_columns`]) whose coordinates are 0 in every row
/// of `table` (empty cells aside): an export's placeholder for a marker never measured, which
/// would calibrate nonsense. The error names the header's line and the marker's `x` column.
pub(crate) fn check_markers_measured(
    table: &Table,
    markers: &[(usize, [usize; 3])],
) -> Result<(), DataError> {
    for &(k, columns) in markers {
        let cells = || table.rows.iter().flat_map(|row| columns.iter().filter_map(|&c| row.cells.get(c)));
        let zero = |text: &str| text.parse::<f64>().is_ok_and(|v| v == 0.0);
        if cells().all(|text| text.is_empty() || zero(text)) && cells().any(zero) {
            let message = format!(
                "marker {k} is at 0, 0, 0 in every row: a placeholder, not a measurement; measure it, or \
                 leave out its columns x{k},y{k},z{k}"
            );
            return Err(DataError::new(table.header_line, Some(&format!("x{k}")), message));
        }
    }
    Ok(())
}

/// Where the quantities of a measurement file stand in its header.
struct Columns {
    /// One per joint of the model.
    joints: Vec<usize>,
    /// The number `k` and the columns `x_k, y_k, z_k` of each marker, by number.
    markers: Vec<(usize, [usize; 3])>,
    /// The `sigma` column, if any.
    sigma: Option<usize>,
    /// `qw,qx,qy,qz` or `roll,pitch,yaw`, or none.
    orientation: Vec<usize>,
}

impl Columns {
    /// Find the joint, marker, sigma and orientation columns of `table`'s header.
    fn resolve(table: &Table, model: &RobotModel) -> Result<Self, DataError> {
        let at_header =
            |column: Option<&str>, message: String| DataError::new(table.header_line, column, message);
        let joints = table.joint_columns(model)?;
        let markers = marker_columns(table)?;
        if markers.is_empty() {
            return Err(at_header(None, "no marker columns: expected x1,y1,z1 (and x2,y2,z2, ...)".into()));
        }
        // A column of another kind: the file fits two kinds; read as neither, said why.
        if let Some(name) = other_kinds_column(table, &joints, &OTHER_KINDS) {
            let message = format!(
                "a marker file (x1,y1,z1, ...) holds marker positions and a probe's orientation only: `{name}` is \
                 an observation file's column (distances, contacts, coordinates, camera views); give those in a \
                 file of their own"
            );
            return Err(at_header(Some(name), message));
        }
        let orientation = orientation_columns(table, &markers)?;
        Ok(Self { joints, markers, sigma: table.column("sigma"), orientation })
    }

    /// The header's columns that none of the quantities uses.
    fn ignored(&self, table: &Table) -> Vec<String> {
        let used: Vec<usize> =
            (self.joints.iter().chain(self.markers.iter().flat_map(|m| &m.1)).chain(&self.sigma))
                .chain(&self.orientation)
                .copied()
                .collect();
        (0..table.header.len()).filter(|i| !used.contains(i)).map(|i| table.header[i].clone()).collect()
    }

    /// The measured marker positions of `row` (mm).
    fn markers(&self, table: &Table, row: &Row, units: Units) -> Result<Vec<Vector3<f64>>, DataError> {
        self.markers
            .iter()
            .map(|&(_, [x, y, z])| {
                let mm = |c: usize| {
                    let v = table.number(row, c)? * units.length_scale();
                    table.within(row, c, v, MAX_LENGTH_MM, "mm")
                };
                Ok(Vector3::new(mm(x)?, mm(y)?, mm(z)?))
            })
            .collect()
    }

    /// The row's measurement standard deviation (mm), positive.
    fn sigma(&self, table: &Table, row: &Row, units: Units) -> Result<f64, DataError> {
        let column = self.sigma.expect("called for a file with a sigma column");
        let s = table.number(row, column)?;
        if s <= 0.0 {
            return Err(DataError::new(
                row.line,
                Some("sigma"),
                format!("{s}: expected a standard deviation > 0"),
            ));
        }
        table.within(row, column, s * units.length_scale(), MAX_LENGTH_MM, "mm")
    }

    /// The row's measured orientation ([`orientation`]).
    fn orientation(&self, table: &Table, row: &Row, units: Units) -> Result<UnitQuaternion<f64>, DataError> {
        orientation(table, row, &self.orientation, units)
    }
}

/// A probe's orientation columns in a marker file's header: `qw,qx,qy,qz` or
/// `roll,pitch,yaw` (in that order), or none; with exactly one marker (`markers`, from
/// [`marker_columns`]), the measured frame's origin.
pub(crate) fn orientation_columns(
    table: &Table,
    markers: &[(usize, [usize; 3])],
) -> Result<Vec<usize>, DataError> {
    let at_header = |message: &str| DataError::new(table.header_line, None, message);
    let quaternion = ["qw", "qx", "qy", "qz"].map(|c| table.column(c));
    let rpy = ["roll", "pitch", "yaw"].map(|c| table.column(c));
    let orientation: Vec<usize> = match (quaternion, rpy) {
        ([Some(w), Some(x), Some(y), Some(z)], [None, None, None]) => vec![w, x, y, z],
        ([None, None, None, None], [Some(r), Some(p), Some(y)]) => vec![r, p, y],
        ([None, None, None, None], [None, None, None]) => Vec::new(),
        _ => {
            return Err(at_header(
                "orientation: give all of qw,qx,qy,qz or all of roll,pitch,yaw, not parts or both",
            ));
        }
    };
    if !orientation.is_empty() && markers.len() != 1 {
        return Err(at_header(
            "orientation columns need exactly one marker (x1,y1,z1): the measured frame's origin",
        ));
    }
    Ok(orientation)
}

/// A probe's measured orientation in `row`'s `columns` (from [`orientation_columns`]): a unit
/// quaternion (norm within 1e-3 of 1) or roll-pitch-yaw in the joints' angle unit,
/// `R = Rz(yaw) Ry(pitch) Rx(roll)`.
pub(crate) fn orientation(
    table: &Table,
    row: &Row,
    columns: &[usize],
    units: Units,
) -> Result<UnitQuaternion<f64>, DataError> {
    let v = columns.iter().map(|&c| table.number(row, c)).collect::<Result<Vec<_>, _>>()?;
    if let [w, x, y, z] = v[..] {
        let q = nalgebra::Quaternion::new(w, x, y, z);
        if (q.norm() - 1.0).abs() > 1e-3 {
            let message = format!("a unit quaternion, its norm is {:.6}", q.norm());
            return Err(DataError::new(row.line, Some("qw"), message));
        }
        return Ok(UnitQuaternion::from_quaternion(q));
    }
    Ok(UnitQuaternion::from_euler_angles(units.angle(v[0]), units.angle(v[1]), units.angle(v[2])))
}
