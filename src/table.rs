//! The CSV tables robocal reads: measurement files, pose files and repeatability files.
//!
//! All three share one layout (see `docs/formats.md`):
//!
//! ```text
//! # units: joints=deg, lengths=mm
//! j1,j2,j3,j4,j5,j6,x1,y1,z1
//! 10.0,45.0,-30.0,0.0,20.0,5.0,512.3,-140.2,601.7
//! ```
//!
//! Lines starting with `#` are comments; the first of them may declare the units. The first
//! other line is the header; cells are trimmed. Joint columns are named after the model's
//! joints; revolute joint values are in the declared angle unit, prismatic ones in the length
//! unit. A byte-order mark and CR or CRLF line endings are accepted. A header that names a
//! column twice, and a row with more or fewer cells than the header, are refused.
//!
//! The reader reads the text once; each file kind then picks its columns from it.

use crate::limits::{MAX_ANGLE_DEG, MAX_LENGTH_MM, check_magnitude};
use crate::model::{Joint, JointKind, RobotModel};
use std::borrow::Cow;

/// Units of a table file.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Units {
    /// Revolute joint values in degrees (true) or radians.
    pub joints_in_degrees: bool,
    /// Lengths in metres (true) or millimetres.
    pub lengths_in_metres: bool,
}

impl Units {
    /// The units as a `# units:` line says them: `joints=deg, lengths=mm`.
    pub fn words(&self) -> String {
        let joints = if self.joints_in_degrees { "deg" } else { "rad" };
        let lengths = if self.lengths_in_metres { "m" } else { "mm" };
        format!("joints={joints}, lengths={lengths}")
    }

    /// The factor that turns the file's lengths into mm: 1000 for metres, 1 for mm.
    pub fn length_scale(&self) -> f64 {
        if self.lengths_in_metres { 1000.0 } else { 1.0 }
    }

    /// An angle in the file's unit, in radians.
    pub fn angle(&self, value: f64) -> f64 {
        if self.joints_in_degrees { value.to_radians() } else { value }
    }
}

/// A table file that could not be read: where and why.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("line {line}{}: {message}", column.as_ref().map(|c| format!(", column `{c}`")).unwrap_or_default())]
#[non_exhaustive]
pub struct DataError {
    /// Line in the file (1-based).
    pub line: usize,
    /// The column, where one is at fault.
    pub column: Option<String>,
    /// What is wrong and what was expected.
    pub message: String,
}

impl DataError {
    /// The error at `line` (and `column`, if one is at fault).
    pub fn new(line: usize, column: Option<&str>, message: impl Into<String>) -> Self {
        Self { line, column: column.map(str::to_string), message: message.into() }
    }
}

/// One row of a table: its line in the file and its trimmed cells.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Row {
    /// Line in the file (1-based).
    pub line: usize,
    /// The cells, as many as the header's or fewer: one buffer a row, not a string a cell.
    pub cells: csv::StringRecord,
}

/// A table file read whole: the declared units, the header and the rows.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Table {
    /// The units of the `# units:` line, if the file has one.
    pub declared: Option<Units>,
    /// The header's cells.
    pub header: Vec<String>,
    /// The header's line (1-based).
    pub header_line: usize,
    /// The rows after the header.
    pub rows: Vec<Row>,
}

impl Table {
    /// Read a table's text: the units line, the header and every row. Refuses a header that
    /// names a column twice and a row with more or fewer cells than the header.
    pub fn parse(text: &str) -> Result<Self, DataError> {
        let text = normalised(text);
        let declared = declared_units(&text)?;
        let mut reader = reader_of(text.as_bytes(), true);
        let header: Vec<String> = reader
            .headers()
            .map_err(|e| DataError::new(1, None, format!("no header row: {e}")))?
            .iter()
            .map(str::to_string)
            .collect();
        let header_line =
            text.lines().position(|l| !l.trim_start().starts_with('#') && !l.trim().is_empty()).unwrap_or(0)
                + 1;
        if header.iter().all(String::is_empty) {
            return Err(DataError::new(header_line, None, "no header row"));
        }
        if let Some((i, name)) = header.iter().enumerate().find(|(i, h)| header[..*i].contains(h)) {
            let message =
                format!("a column named once, `{name}` is column {} and {}", position(&header, name), i + 1);
            return Err(DataError::new(header_line, Some(name), message));
        }
        // The rows after the header: where the reader stands once it has read it.
        let body = usize::try_from(reader.position().byte()).unwrap_or(text.len()).min(text.len());
        let rows = rows_of(&text, body, header.len())?;
        Ok(Self { declared, header, header_line, rows })
    }

    /// The units: the file's declared ones, else `given` by the caller; `hint` says how else
    /// the user can declare them. Units given that differ from the file's declaration are an
    /// error (the declaration is the file's own word: a flag meant for other files must not
    /// rescale this one).
    pub fn units(&self, given: Option<Units>, hint: &str) -> Result<Units, DataError> {
        match (self.declared, given) {
            (Some(declared), Some(given)) if declared != given => Err(DataError::new(
                1,
                None,
                format!(
                    "the file declares `# units: {}`, and the units given are {}: give units only for files \
                     that declare none, or the ones they declare",
                    declared.words(),
                    given.words()
                ),
            )),
            (Some(declared), _) => Ok(declared),
            (None, Some(given)) => Ok(given),
            (None, None) => Err(DataError::new(
                1,
                None,
                format!(
                    "units not declared: start the file with `# units: joints=deg, lengths=mm` (or rad, m){hint}"
                ),
            )),
        }
    }

    /// The column named `name`, if the header has one.
    pub fn column(&self, name: &str) -> Option<usize> {
        self.header.iter().position(|h| h == name)
    }

    /// The column of each of `model`'s joints, named after the joint; an error names the first
    /// joint missing and lists the model's joints.
    pub fn joint_columns(&self, model: &RobotModel) -> Result<Vec<usize>, DataError> {
        self.columns_of(&model.joints)
    }

    /// The column of each of `joints`, named after the joint, as [`Table::joint_columns`].
    pub fn columns_of(&self, joints: &[Joint]) -> Result<Vec<usize>, DataError> {
        joints
            .iter()
            .map(|j| {
                self.column(&j.name).ok_or_else(|| {
                    let expected: Vec<&str> = joints.iter().map(|j| j.name.as_str()).collect();
                    let message =
                        format!("missing joint column; the model's joints are {}", expected.join(", "));
                    DataError::new(self.header_line, Some(&j.name), message)
                })
            })
            .collect()
    }

    /// The finite number in `column` of `row`.
    pub fn number(&self, row: &Row, column: usize) -> Result<f64, DataError> {
        let name = &self.header[column];
        let Some(text) = row.cells.get(column) else {
            let message = format!("{} values, the header has {}", row.cells.len(), self.header.len());
            return Err(DataError::new(row.line, Some(name), message));
        };
        let v: f64 = text
            .parse()
            .map_err(|_| DataError::new(row.line, Some(name), format!("`{text}` is not a number")))?;
        if v.is_finite() {
            Ok(v)
        } else {
            Err(DataError::new(row.line, Some(name), format!("{v}: expected a finite number")))
        }
    }

    /// `value` (of `column` in `row`, in `unit`) if its magnitude is at most `bound`.
    pub fn within(
        &self,
        row: &Row,
        column: usize,
        value: f64,
        bound: f64,
        unit: &str,
    ) -> Result<f64, DataError> {
        check_magnitude(value, bound, unit)
            .map_err(|e| DataError::new(row.line, Some(&self.header[column]), e))
    }

    /// The joint values of `row` in rad (revolute) and mm (prismatic), from the joint
    /// `columns` of [`Table::joint_columns`].
    pub fn joint_values(
        &self,
        row: &Row,
        columns: &[usize],
        model: &RobotModel,
        units: Units,
    ) -> Result<Vec<f64>, DataError> {
        self.values_of(row, columns, &model.joints, units)
    }

    /// The values of `joints` in `row`, from their `columns` ([`Table::columns_of`]), as
    /// [`Table::joint_values`].
    pub fn values_of(
        &self,
        row: &Row,
        columns: &[usize],
        joints: &[Joint],
        units: Units,
    ) -> Result<Vec<f64>, DataError> {
        joints
            .iter()
            .zip(columns)
            .map(|(joint, &c)| {
                let v = self.number(row, c)?;
                Ok(match joint.kind {
                    JointKind::Revolute => {
                        let radians = units.angle(v);
                        self.within(row, c, radians.to_degrees(), MAX_ANGLE_DEG, "deg")?;
                        radians
                    }
                    JointKind::Prismatic => {
                        self.within(row, c, v * units.length_scale(), MAX_LENGTH_MM, "mm")?
                    }
                })
            })
            .collect()
    }

    /// The rows, or an error naming the header's line when there are none.
    pub fn nonempty_rows(&self) -> Result<&[Row], DataError> {
        if self.rows.is_empty() {
            return Err(DataError::new(self.header_line, None, "no poses after the header"));
        }
        Ok(&self.rows)
    }
}

/// The 1-based position of the first column named `name`.
fn position(header: &[String], name: &str) -> usize {
    header.iter().position(|h| h == name).map_or(0, |i| i + 1)
}

/// `text` without a byte-order mark and with `\n` line endings (CR and CRLF files accepted).
fn normalised(text: &str) -> Cow<'_, str> {
    let text = text.strip_prefix('\u{feff}').unwrap_or(text);
    if text.contains('\r') {
        Cow::Owned(text.replace("\r\n", "\n").replace('\r', "\n"))
    } else {
        Cow::Borrowed(text)
    }
}

/// Bytes of a CSV's rows that one task of [`Table::parse`] reads: whole lines, about this many.
const ROWS_PER_TASK_BYTES: usize = 1 << 16;

/// The CSV reader of every table: `#` comments, cells trimmed, rows of any length (the
/// reader's callers check them against the header), with or without a header.
fn reader_of(bytes: &[u8], headers: bool) -> csv::Reader<&[u8]> {
    csv::ReaderBuilder::new()
        .comment(Some(b'#'))
        .trim(csv::Trim::All)
        .flexible(true)
        .has_headers(headers)
        .from_reader(bytes)
}

/// `text` cut into pieces of whole lines of about `size` bytes at least (the last one shorter),
/// each with its byte offset in `text`.
pub(crate) fn line_chunks(text: &str, size: usize) -> Vec<(usize, &str)> {
    let (bytes, mut chunks, mut start) = (text.as_bytes(), Vec::new(), 0);
    while start < text.len() {
        let newline = bytes.get(start + size..).and_then(|rest| rest.iter().position(|&b| b == b'\n'));
        let end = newline.map_or(text.len(), |i| start + size + i + 1);
        chunks.push((start, &text[start..end]));
        start = end;
    }
    chunks
}

/// The rows of the table `text` from byte `body` on (after its header), each of `width`
/// cells. Read on rayon's threads in pieces of whole lines when no cell is quoted (a quoted
/// cell may hold a line break), in order; where a piece fails, read again in one piece, so
/// that the error is the one reader's, whatever the threads.
fn rows_of(text: &str, body: usize, width: usize) -> Result<Vec<Row>, DataError> {
    use rayon::prelude::*;
    let rest = &text[body..];
    let pieces = match rest.contains('"') {
        true => vec![(0, rest)],
        false => line_chunks(rest, ROWS_PER_TASK_BYTES),
    };
    // The lines before each piece.
    let counts: Vec<usize> = pieces.par_iter().map(|(_, piece)| piece.matches('\n').count()).collect();
    let header_lines = text[..body].matches('\n').count();
    let starts: Vec<usize> = (counts.iter())
        .scan(header_lines, |before, n| {
            let first = *before;
            *before += n;
            Some(first)
        })
        .collect();
    let read: Vec<Result<Vec<Row>, DataError>> = (pieces.into_par_iter().zip(starts))
        .map(|((_, piece), first)| rows_of_piece(piece, first, width))
        .collect();
    if !read.iter().all(Result::is_ok) {
        return rows_of_piece(rest, header_lines, width);
    }
    // Sized once: a growing vector of 100k rows would hold up to twice their room at its peak.
    let mut rows = Vec::with_capacity(read.iter().map(|r| r.as_ref().map_or(0, Vec::len)).sum());
    read.into_iter().for_each(|piece| rows.extend(piece.unwrap_or_default()));
    Ok(rows)
}

/// The rows of `piece`, whole lines of a table after its header, the first its line `first + 1`.
fn rows_of_piece(piece: &str, first: usize, width: usize) -> Result<Vec<Row>, DataError> {
    // The csv reader counts neither blank lines nor comments, and a record's position can
    // be that of the blank or comment lines before it: lines come from byte offsets.
    let newlines: Vec<usize> = piece.match_indices('\n').map(|(i, _)| i).collect();
    let lines: Vec<&str> = piece.split('\n').collect();
    let line_of = |position: Option<&csv::Position>| {
        let Some(p) = position else { return 0 };
        let mut line = newlines.partition_point(|&n| n < p.byte() as usize);
        while lines.get(line).is_some_and(|l| l.trim().is_empty() || l.trim_start().starts_with('#')) {
            line += 1;
        }
        first + line + 1
    };
    let mut rows = Vec::new();
    for record in reader_of(piece.as_bytes(), false).records() {
        let record = record.map_err(|e| DataError::new(line_of(e.position()), None, e.to_string()))?;
        let line = line_of(record.position());
        if record.len() != width {
            let message = format!("{} values, the header has {width}", record.len());
            return Err(DataError::new(line, None, message));
        }
        rows.push(Row { line, cells: record });
    }
    Ok(rows)
}

/// The units of a `# units: joints=deg, lengths=mm` line among the leading comments, if the
/// file has one.
fn declared_units(text: &str) -> Result<Option<Units>, DataError> {
    for (i, line) in text.lines().enumerate() {
        let Some(rest) = line.trim().strip_prefix('#') else { break };
        let Some(spec) = rest.trim().strip_prefix("units:") else { continue };
        let bad = |message: String| DataError::new(i + 1, None, message);
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

#[cfg(test)]
mod tests {
    use super::*;

    const TEXT: &str = "# units: joints=deg, lengths=m\n# a comment\nj1, x1\n1.5,2\n\n# between\n3,4\n";

    #[test]
    fn a_table_is_read_once_with_its_units_and_lines() {
        let table = Table::parse(TEXT).unwrap();
        assert_eq!(table.declared, Some(Units { joints_in_degrees: true, lengths_in_metres: true }));
        assert_eq!(table.header, ["j1", "x1"]);
        assert_eq!(table.header_line, 3);
        assert_eq!(table.rows.iter().map(|r| r.line).collect::<Vec<_>>(), [4, 7]);
        assert_eq!(table.number(&table.rows[1], 1), Ok(4.0));
    }

    #[test]
    fn a_byte_order_mark_and_cr_line_endings_read_as_the_plain_file() {
        let plain = Table::parse(TEXT).unwrap();
        assert_eq!(Table::parse(&format!("\u{feff}{TEXT}")).unwrap(), plain);
        assert_eq!(Table::parse(&TEXT.replace('\n', "\r\n")).unwrap(), plain);
        assert_eq!(Table::parse(&TEXT.replace('\n', "\r")).unwrap(), plain);
    }

    /// A table of many pieces ([`ROWS_PER_TASK_BYTES`]), comments and blank lines among its
    /// rows, is read as in one piece, on any number of threads: the same rows, the same lines,
    /// the same first error (a row of three cells late in the file).
    #[test]
    fn a_long_table_is_read_in_pieces_as_in_one() {
        let mut text = String::from("# units: joints=deg, lengths=mm\nj1,x1\n");
        for k in 0..40_000 {
            text.push_str(&format!("{k}.25,{}\n", k % 7));
            if k % 997 == 0 {
                text.push_str("\n# a comment\n");
            }
        }
        let body = text.find("0.25").unwrap();
        let one = rows_of_piece(&text[body..], 2, 2).unwrap();
        let on = |threads: usize, text: &str| {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
            pool.install(|| Table::parse(text))
        };
        for threads in [1, 2, 3] {
            let table = on(threads, &text).unwrap();
            assert_eq!(table.rows, one, "{threads} threads");
        }
        assert_eq!(one[1000].line, 2 + 1000 + 1 + 2 * 2);
        assert_eq!(one[1000].cells.get(0), Some("1000.25"));
        text.push_str("1,2,3\n4,5\n");
        let late = on(2, &text).unwrap_err();
        assert_eq!(late, rows_of_piece(&text[body..], 2, 2).unwrap_err());
        assert_eq!(late.message, "3 values, the header has 2");
    }

    #[test]
    fn a_column_named_twice_is_refused() {
        let e = Table::parse("j1,x1,j1\n1,2,3\n").unwrap_err();
        assert_eq!(e, DataError::new(1, Some("j1"), "a column named once, `j1` is column 1 and 3"));
    }

    #[test]
    fn a_row_longer_or_shorter_than_the_header_is_refused() {
        let e = Table::parse("j1,x1\n1,2\n1,2,3\n").unwrap_err();
        assert_eq!(e, DataError::new(3, None, "3 values, the header has 2"));
        let e = Table::parse("j1,x1\n1\n").unwrap_err();
        assert_eq!(e, DataError::new(2, None, "1 values, the header has 2"));
    }

    #[test]
    fn a_bad_cell_names_line_and_column() {
        let table = Table::parse("j1,x1\nx,2\n").unwrap();
        assert_eq!(
            table.number(&table.rows[0], 0).unwrap_err().to_string(),
            "line 2, column `j1`: `x` is not a number"
        );
        assert_eq!(
            table
                .number(&Row { line: 9, cells: csv::StringRecord::from(vec!["inf"]) }, 0)
                .unwrap_err()
                .to_string(),
            "line 9, column `j1`: inf: expected a finite number"
        );
    }

    #[test]
    fn units_given_by_the_caller_serve_a_file_that_declares_none() {
        let table = Table::parse("j1\n1\n").unwrap();
        let given = Units { joints_in_degrees: false, lengths_in_metres: false };
        assert_eq!(table.units(Some(given), ""), Ok(given));
        assert!(table.units(None, " or say so").unwrap_err().message.ends_with("(or rad, m) or say so"));
        let bad = Table::parse("# units: joints=deg\nj1\n1\n").unwrap_err();
        assert_eq!(bad.line, 1);
    }

    /// A file's own `# units:` line is its word: units given that agree with it are taken,
    /// units that differ are an error naming both, never a silent rescaling.
    #[test]
    fn units_given_never_override_the_file_s_line() {
        let table = Table::parse("# units: joints=rad, lengths=m\nj1\n1\n").unwrap();
        let declared = Units { joints_in_degrees: false, lengths_in_metres: true };
        assert_eq!(table.units(None, ""), Ok(declared));
        assert_eq!(table.units(Some(declared), ""), Ok(declared));
        let other = Units { joints_in_degrees: true, lengths_in_metres: true };
        let e = table.units(Some(other), "").unwrap_err();
        assert_eq!(e.line, 1);
        assert!(
            e.message.starts_with(
                "the file declares `# units: joints=rad, lengths=m`, and the units given are joints=deg, lengths=m"
            ),
            "{e}"
        );
    }
}
