//! Typed access to the keys of one parsed JSON line, each failure naming the
//! line and the key path (the contract's "error that names the line").

use serde_json::{Map, Value};
use shared::observation::{PixelPoint, Point3};

use super::error::{describe_value, LogError, LogProblem};

/// One JSON object of the log together with its line number, for error reporting.
pub struct Record<'a> {
    pub line: usize,
    pub object: &'a Map<String, Value>,
}

/// The JSON type of `value`, spelled for messages.
fn type_name(value: &Value) -> &'static str {
    match value {
        Value::Null => "null",
        Value::Bool(_) => "a boolean",
        Value::Number(_) => "a number",
        Value::String(_) => "a string",
        Value::Array(_) => "an array",
        Value::Object(_) => "an object",
    }
}

/// Prefix of the string the reader puts in place of a number literal that
/// overflows f64 (e.g. `1e999`), so the decoder can name the field it sits in.
/// A NUL cannot occur in a string of a JSON log unless escaped, so it cannot clash.
pub const OUT_OF_RANGE_MARKER: &str = "\u{0}out-of-range number ";

fn out_of_range_literal(value: &Value) -> Option<&str> {
    value.as_str()?.strip_prefix(OUT_OF_RANGE_MARKER)
}

fn got(value: &Value) -> String {
    if let Some(literal) = out_of_range_literal(value) {
        return format!("a number {literal} (outside the f64 range)");
    }
    match value {
        Value::Null => "null".to_string(),
        other => format!("{} {}", type_name(other), describe_value(other)),
    }
}

impl<'a> Record<'a> {
    /// Borrow `value` as an object, else "expected a JSON object".
    pub fn from_value(line: usize, value: &'a Value) -> Result<Self, LogError> {
        match value {
            Value::Object(object) => Ok(Self { line, object }),
            other => Err(LogError::new(
                line,
                LogProblem::NotAnObject { got: got(other) },
            )),
        }
    }

    /// The value of a required key (which may be JSON null).
    pub fn required(&self, key: &str, path: &str) -> Result<&'a Value, LogError> {
        self.object
            .get(key)
            .ok_or_else(|| LogError::at_field(self.line, path, LogProblem::MissingField))
    }

    /// A nested object under a required key.
    pub fn object(&self, key: &str, path: &str) -> Result<Record<'a>, LogError> {
        match self.required(key, path)? {
            Value::Object(object) => Ok(Record {
                line: self.line,
                object,
            }),
            other => Err(self.wrong_type(path, "an object", other)),
        }
    }

    /// A finite number.
    pub fn finite(&self, key: &str, path: &str) -> Result<f64, LogError> {
        let value = self.required(key, path)?;
        finite_number(self.line, path, value, "a finite number")
    }

    /// A finite number strictly greater than zero.
    pub fn positive(&self, key: &str, path: &str) -> Result<f64, LogError> {
        let number = self.finite(key, path)?;
        if number > 0.0 {
            Ok(number)
        } else {
            Err(LogError::at_field(
                self.line,
                path,
                LogProblem::OutOfRange {
                    expected: "a number greater than 0",
                    got: number.to_string(),
                },
            ))
        }
    }

    /// A non-negative integer that fits `u64`.
    pub fn unsigned(&self, key: &str, path: &str) -> Result<u64, LogError> {
        let value = self.required(key, path)?;
        value
            .as_u64()
            .ok_or_else(|| self.wrong_type(path, "a non-negative integer", value))
    }

    pub fn wrong_type(&self, path: &str, expected: &'static str, value: &Value) -> LogError {
        LogError::at_field(
            self.line,
            path,
            LogProblem::WrongType {
                expected,
                got: got(value),
            },
        )
    }
}

/// How a JSON value reads as a number.
enum Numeric {
    Finite(f64),
    /// A JSON number outside the f64 range (JSON itself has no NaN or infinity).
    NonFinite,
    NotANumber,
}

fn numeric(value: &Value) -> Numeric {
    match value.as_f64() {
        Some(number) if number.is_finite() => Numeric::Finite(number),
        Some(_) => Numeric::NonFinite,
        None if value.is_number() || out_of_range_literal(value).is_some() => Numeric::NonFinite,
        None => Numeric::NotANumber,
    }
}

/// `value` as a finite f64; `shape` is what the field expects, for the message.
fn finite_number(
    line: usize,
    path: &str,
    value: &Value,
    shape: &'static str,
) -> Result<f64, LogError> {
    match numeric(value) {
        Numeric::Finite(number) => Ok(number),
        Numeric::NonFinite => Err(LogError::at_field(
            line,
            path,
            LogProblem::NonFinite { got: got(value) },
        )),
        Numeric::NotANumber => Err(LogError::at_field(
            line,
            path,
            LogProblem::WrongType {
                expected: shape,
                got: got(value),
            },
        )),
    }
}

/// A JSON array of exactly `N` finite numbers; a wrong shape reports `shape` and the
/// whole value, an out-of-range number names its element (`path[i]`).
pub fn fixed_numbers<const N: usize>(
    line: usize,
    path: &str,
    value: &Value,
    shape: &'static str,
) -> Result<[f64; N], LogError> {
    let wrong = || {
        LogError::at_field(
            line,
            path,
            LogProblem::WrongType {
                expected: shape,
                got: got(value),
            },
        )
    };
    let items = value.as_array().ok_or_else(wrong)?;
    if items.len() != N {
        return Err(wrong());
    }
    let mut numbers = [0.0; N];
    for (index, (slot, item)) in numbers.iter_mut().zip(items).enumerate() {
        *slot = match numeric(item) {
            Numeric::Finite(number) => number,
            Numeric::NonFinite => {
                return Err(LogError::at_field(
                    line,
                    format!("{path}[{index}]"),
                    LogProblem::NonFinite { got: got(item) },
                ))
            }
            Numeric::NotANumber => return Err(wrong()),
        };
    }
    Ok(numbers)
}

pub const PIXEL_SHAPE: &str = "[u, v] of 2 finite numbers";
pub const POINT3_SHAPE: &str = "[x, y, z] of 3 finite numbers";

pub fn pixel(line: usize, path: &str, value: &Value) -> Result<PixelPoint, LogError> {
    fixed_numbers::<2>(line, path, value, PIXEL_SHAPE)
}

pub fn point3(line: usize, path: &str, value: &Value) -> Result<Point3, LogError> {
    fixed_numbers::<3>(line, path, value, POINT3_SHAPE)
}

/// `null` or a pixel.
pub fn optional_pixel(
    line: usize,
    path: &str,
    value: &Value,
) -> Result<Option<PixelPoint>, LogError> {
    match value {
        Value::Null => Ok(None),
        other => pixel(line, path, other).map(Some),
    }
}

/// `null` or an array of points, each parsed by `parse_item` with path `path[i]`;
/// `shape` describes the array for the "not an array" message.
pub fn optional_list<'v, T>(
    line: usize,
    path: &str,
    value: &'v Value,
    shape: &'static str,
    mut parse_item: impl FnMut(&str, &'v Value) -> Result<T, LogError>,
) -> Result<Option<Vec<T>>, LogError> {
    match value {
        Value::Null => Ok(None),
        Value::Array(items) => items
            .iter()
            .enumerate()
            .map(|(index, item)| parse_item(&format!("{path}[{index}]"), item))
            .collect::<Result<Vec<T>, LogError>>()
            .map(Some),
        other => Err(LogError::at_field(
            line,
            path,
            LogProblem::WrongType {
                expected: shape,
                got: got(other),
            },
        )),
    }
}
