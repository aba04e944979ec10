//! The one piece of error vocabulary the input formats share.
//!
//! Every reader (model TOML and URDF, noise file, study file) says what is wrong with a field
//! in the same words: the field's path and what was expected there. A syntax error keeps the
//! parser's own error as its source, so that the line and column it names are printed once,
//! after the file's name.

/// A field of an input file with a value that makes no sense there.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("field `{field}`: {expected}")]
pub struct FieldError {
    /// The field's path, e.g. `joints[2].limits_deg` or `noise.device.sigma_r_mm`.
    pub field: String,
    /// What was expected there, and what was found.
    pub expected: String,
}

impl FieldError {
    /// The error of `field`.
    pub fn new(field: impl Into<String>, expected: impl Into<String>) -> Self {
        Self { field: field.into(), expected: expected.into() }
    }

    /// The same error with `prefix` before the field's path (`noise.device.` + `sigma_r_mm`).
    pub fn within(self, prefix: &str) -> Self {
        Self { field: format!("{prefix}{}", self.field), ..self }
    }
}

/// `error` and each of its sources in turn, joined by `: ` — the whole message, as the
/// command line prints it (`path: line 3, column 7: ...`).
pub fn chain(error: &dyn std::error::Error) -> String {
    let mut message = error.to_string();
    let mut source = error.source();
    while let Some(cause) = source {
        message = format!("{message}: {cause}");
        source = cause.source();
    }
    message
}

#[cfg(test)]
mod tests {
    use super::*;

    #[derive(Debug, thiserror::Error)]
    #[error("not a file")]
    struct Syntax(#[source] toml::de::Error);

    #[test]
    fn a_chain_names_every_source_once() {
        let syntax = toml::from_str::<toml::Table>("a = ").unwrap_err();
        assert_eq!(chain(&Syntax(syntax.clone())), format!("not a file: {syntax}"));
        assert_eq!(chain(&FieldError::new("a", "b").within("x.")), "field `x.a`: b");
    }
}
