//! The library's errors as Python exceptions: `robocal.InputError` for what was given (a file,
//! an array, an option), `robocal.EstimationError` for a calibration the data cannot make.
//! Each carries the whole message (the error and its sources, as the command line prints
//! them) and, where the error names them, the file, the line and the field or column.

use pyo3::prelude::*;
use robocal::calibration::CalibrationError;
use robocal::error::FieldError;
use robocal::io::InputError;
use robocal::table::DataError;
use std::error::Error;

/// Which Python exception.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Kind {
    /// `robocal.InputError`.
    Input,
    /// `robocal.EstimationError`.
    Estimation,
}

/// Where an error is: the file, the line and the field (or column), as far as it says.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Place {
    /// The file.
    pub file: Option<String>,
    /// The line in it (1-based).
    pub line: Option<usize>,
    /// The field or column at fault.
    pub field: Option<String>,
}

/// The exception `kind` with `message` at `place`.
pub fn raise(kind: Kind, message: String, place: Place) -> PyErr {
    Python::attach(|py| {
        let name = match kind {
            Kind::Input => "InputError",
            Kind::Estimation => "EstimationError",
        };
        let made = py.import("robocal._errors").and_then(|m| m.getattr(name)).and_then(|class| {
            class.call1((message.clone(), place.file.clone(), place.line, place.field.clone()))
        });
        match made {
            Ok(value) => PyErr::from_value(value),
            Err(e) => e,
        }
    })
}

/// An input error with a message and nothing more precise.
pub fn input(message: impl Into<String>) -> PyErr {
    raise(Kind::Input, message.into(), Place::default())
}

/// An input error about the argument `field`.
pub fn argument(field: &str, message: impl std::fmt::Display) -> PyErr {
    raise(Kind::Input, format!("{field}: {message}"), Place { field: Some(field.into()), ..Place::default() })
}

/// `error` as an exception of `kind`, its place found among its sources; `context` (a file, an
/// argument) goes before the message, and is the file unless a source names one.
pub fn from_error(kind: Kind, error: &(dyn Error + 'static), context: Option<&str>) -> PyErr {
    let mut place = Place { file: context.map(str::to_string), ..Place::default() };
    let mut source: Option<&(dyn Error + 'static)> = Some(error);
    while let Some(e) = source {
        if let Some(input) = e.downcast_ref::<InputError>() {
            place.file = file_of(input).or(place.file);
        } else if let Some(data) = e.downcast_ref::<DataError>() {
            place.line = Some(data.line);
            place.field = data.column.clone();
        } else if let Some(field) = e.downcast_ref::<FieldError>() {
            place.field = Some(field.field.clone());
        } else if let Some(toml) = e.downcast_ref::<toml_line::TomlError>() {
            place.line = toml_line::line(toml);
        }
        source = e.source();
    }
    let chain = robocal::error::chain(error);
    let message = match context {
        Some(c) if !chain.starts_with(c) => format!("{c}: {chain}"),
        _ => chain,
    };
    raise(kind, message, place)
}

/// A calibration's error: a parameter name or a prior that matches nothing is the options'
/// (an input error about `params`, `hold`, `keep` or `prior`), anything else the data's.
pub fn calibration(error: &CalibrationError, data: &str) -> PyErr {
    match error {
        CalibrationError::Selection(_) => {
            let place = Place { field: Some("params".into()), ..Place::default() };
            raise(Kind::Input, format!("params, hold or keep: {}", robocal::error::chain(error)), place)
        }
        CalibrationError::Folds { .. } => {
            let place = Place { field: Some("folds".into()), ..Place::default() };
            raise(Kind::Input, robocal::error::chain(error), place)
        }
        CalibrationError::Point { field, .. } => {
            let field = match field {
                robocal::calibration::PointName::Tool => "tool",
                _ => "marker",
            };
            let place = Place { field: Some(field.into()), ..Place::default() };
            raise(Kind::Input, robocal::error::chain(error), place)
        }
        CalibrationError::Prior(_) => {
            let place = Place { field: Some("prior".into()), ..Place::default() };
            raise(Kind::Input, format!("prior: {}", robocal::error::chain(error)), place)
        }
        _ => from_error(Kind::Estimation, error, Some(data)),
    }
}

/// The file an input error names.
fn file_of(error: &InputError) -> Option<String> {
    match error {
        InputError::Read { path, .. }
        | InputError::Model { path, .. }
        | InputError::Study { path, .. }
        | InputError::Data { path, .. }
        | InputError::Noise { path, .. }
        | InputError::Branch { path, .. } => Some(path.display().to_string()),
        _ => None,
    }
}

/// The line a TOML parser's error names (it says `at line N` in its message).
mod toml_line {
    /// The TOML parser's error, as the model and noise readers keep it.
    pub type TomlError = toml::de::Error;

    /// The line `error` names.
    pub fn line(error: &TomlError) -> Option<usize> {
        let text = error.to_string();
        let rest = &text[text.find("line ")? + 5..];
        let digits: String = rest.chars().take_while(char::is_ascii_digit).collect();
        digits.parse().ok()
    }
}
