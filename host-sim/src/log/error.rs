//! Errors of the observation-log reader and writer: every one names the line
//! (1-based, line 1 is the header) and, where there is one, the field.

use std::fmt;

/// What is wrong with one line of a log.
#[derive(Debug)]
pub enum LogProblem {
    /// The underlying reader or writer failed.
    Io(std::io::Error),
    /// The line is longer than the reader accepts (protects memory on garbage input).
    LineTooLong { limit_bytes: usize },
    /// The line is not valid UTF-8 / JSON.
    InvalidJson(String),
    /// The line is valid JSON but not an object.
    NotAnObject { got: String },
    /// A required key is absent.
    MissingField,
    /// A key has the wrong JSON type or shape.
    WrongType { expected: &'static str, got: String },
    /// A number is NaN or infinite (or out of the f64 range).
    NonFinite { got: String },
    /// A number is finite but outside what the contract allows.
    OutOfRange { expected: &'static str, got: String },
    /// The header's `version` is not 1.
    UnsupportedVersion { got: String },
    /// `type` is not what this line must be (`header` on line 1, `frame` after).
    WrongRecordType { expected: &'static str, got: String },
    /// `t_s` is smaller than the previous frame's.
    TimeWentBackwards { t_s: f64, previous_t_s: f64 },
    /// `part_px` has a different number of points than the header's `part_feature_count`.
    FeatureCount { expected: usize, got: usize },
    /// `effector_px` and `effector_base_m` must be both null or both present.
    EffectorPairing {
        px_present: bool,
        base_present: bool,
    },
    /// The log has no header line at all.
    MissingHeader,
}

/// An error of the log reader or writer, with the line and field it concerns.
#[derive(Debug)]
pub struct LogError {
    /// 1-based line number (line 1 is the header).
    pub line: usize,
    /// The key path concerned, e.g. `camera.f_px` or `part_px[2]`, when there is one.
    pub field: Option<String>,
    pub problem: LogProblem,
}

impl LogError {
    pub fn new(line: usize, problem: LogProblem) -> Self {
        Self {
            line,
            field: None,
            problem,
        }
    }

    pub fn at_field(line: usize, field: impl Into<String>, problem: LogProblem) -> Self {
        Self {
            line,
            field: Some(field.into()),
            problem,
        }
    }
}

impl fmt::Display for LogProblem {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Io(e) => write!(f, "i/o error: {e}"),
            Self::LineTooLong { limit_bytes } => {
                write!(f, "line longer than the limit of {limit_bytes} bytes")
            }
            Self::InvalidJson(msg) => write!(f, "not valid JSON: {msg}"),
            Self::NotAnObject { got } => write!(f, "expected a JSON object, got {got}"),
            Self::MissingField => write!(f, "required key is missing"),
            Self::WrongType { expected, got } => write!(f, "expected {expected}, got {got}"),
            Self::NonFinite { got } => write!(f, "expected a finite number, got {got}"),
            Self::OutOfRange { expected, got } => write!(f, "expected {expected}, got {got}"),
            Self::UnsupportedVersion { got } => {
                write!(f, "unsupported log version {got} (only version 1 is read)")
            }
            Self::WrongRecordType { expected, got } => {
                write!(f, "expected record type \"{expected}\", got {got}")
            }
            Self::TimeWentBackwards { t_s, previous_t_s } => write!(
                f,
                "t_s {} is before the previous frame's t_s {} (must be non-decreasing)",
                Seconds(*t_s),
                Seconds(*previous_t_s)
            ),
            Self::FeatureCount { expected, got } => write!(
                f,
                "expected {expected} feature points (header part_feature_count), got {got}"
            ),
            Self::EffectorPairing {
                px_present,
                base_present,
            } => write!(
                f,
                "effector_px and effector_base_m must be both null or both present \
                 (effector_px {}, effector_base_m {})",
                presence(*px_present),
                presence(*base_present)
            ),
            Self::MissingHeader => write!(f, "the log is empty: line 1 must be the header"),
        }
    }
}

/// A time in an error message: plain for everyday values, in exponent form when
/// huge or tiny (a `t_s` of 1e300 would otherwise print 301 digits).
struct Seconds(f64);

impl fmt::Display for Seconds {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let magnitude = self.0.abs();
        if magnitude == 0.0 || (1e-4..1e15).contains(&magnitude) {
            write!(f, "{}", self.0)
        } else {
            write!(f, "{:e}", self.0)
        }
    }
}

fn presence(present: bool) -> &'static str {
    if present {
        "present"
    } else {
        "null"
    }
}

impl fmt::Display for LogError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match &self.field {
            Some(field) => write!(
                f,
                "line {}: field \"{}\": {}",
                self.line, field, self.problem
            ),
            None => write!(f, "line {}: {}", self.line, self.problem),
        }
    }
}

impl std::error::Error for LogError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match &self.problem {
            LogProblem::Io(e) => Some(e),
            _ => None,
        }
    }
}

/// A short rendering of an offending JSON value for error messages (at most ~80 characters).
pub fn describe_value(value: &serde_json::Value) -> String {
    const MAX_CHARS: usize = 80;
    let text = value.to_string();
    if text.chars().count() <= MAX_CHARS {
        text
    } else {
        let head: String = text.chars().take(MAX_CHARS).collect();
        format!("{head}...")
    }
}
