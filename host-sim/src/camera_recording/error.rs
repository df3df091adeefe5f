//! What can be wrong with a recording, each case naming where: the header's
//! key, the CSV's line and column, or the image's file.

use std::fmt;

/// An error reading or writing a camera recording.
#[derive(Debug)]
pub enum RecordingError {
    /// `recording.json`: a missing, mistyped or out-of-range key.
    Header { key: String, problem: String },
    /// `frames.csv`: a malformed row (1-based line; column by name).
    Row {
        line: usize,
        column: String,
        problem: String,
    },
    /// A frame's image: missing, undecodable or of the wrong size.
    Image { file: String, problem: String },
    /// A file that cannot be opened, read or written.
    Io {
        file: String,
        source: std::io::Error,
    },
}

impl RecordingError {
    pub(crate) fn header(key: &str, problem: impl Into<String>) -> Self {
        Self::Header {
            key: key.to_string(),
            problem: problem.into(),
        }
    }

    pub(crate) fn row(line: usize, column: &str, problem: impl Into<String>) -> Self {
        Self::Row {
            line,
            column: column.to_string(),
            problem: problem.into(),
        }
    }

    pub(crate) fn image(file: &str, problem: impl Into<String>) -> Self {
        Self::Image {
            file: file.to_string(),
            problem: problem.into(),
        }
    }

    pub(crate) fn io(file: &std::path::Path) -> impl FnOnce(std::io::Error) -> Self + '_ {
        move |source| Self::Io {
            file: file.display().to_string(),
            source,
        }
    }
}

impl fmt::Display for RecordingError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Header { key, problem } => write!(f, "recording.json: key `{key}`: {problem}"),
            Self::Row {
                line,
                column,
                problem,
            } => write!(f, "frames.csv line {line}, column `{column}`: {problem}"),
            Self::Image { file, problem } => write!(f, "image {file}: {problem}"),
            Self::Io { file, source } => write!(f, "{file}: {source}"),
        }
    }
}

impl std::error::Error for RecordingError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            Self::Io { source, .. } => Some(source),
            _ => None,
        }
    }
}
