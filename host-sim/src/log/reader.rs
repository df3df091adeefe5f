//! Streaming reader of a JSON Lines observation log (contract version 1).
//!
//! Lines are read with a length cap so that a corrupt file (say, a binary blob
//! with no newline) fails with a clear error instead of exhausting memory;
//! frames are decoded one at a time so a long log never has to be held whole.

use std::borrow::Cow;
use std::io::{BufRead, Read};

use serde_json::Value;
use shared::observation::{LogHeader, ObservationFrame};

use super::error::{LogError, LogProblem};
use super::fields::OUT_OF_RANGE_MARKER;
use super::locate::field_at;
use super::record::{parse_frame, parse_header};
use super::ObservationLog;

/// Longest line accepted by default (4 MiB). A 8-feature frame is under 1 KiB.
pub const DEFAULT_MAX_LINE_BYTES: usize = 4 * 1024 * 1024;

/// Reads the header on construction, then yields frames; stops after the first error.
pub struct LogReader<R> {
    input: R,
    header: LogHeader,
    max_line_bytes: usize,
    /// Number of the line last read (1-based).
    line: usize,
    previous_t_s: Option<f64>,
    buffer: Vec<u8>,
    finished: bool,
}

/// Reads one line into `buffer` (without its `\n` / `\r\n`), at most `max_line_bytes` long.
/// `Ok(false)` at end of input.
fn read_bounded_line<R: BufRead>(
    input: &mut R,
    buffer: &mut Vec<u8>,
    max_line_bytes: usize,
    line: usize,
) -> Result<bool, LogError> {
    buffer.clear();
    let budget = u64::try_from(max_line_bytes)
        .unwrap_or(u64::MAX)
        .saturating_add(1);
    let read = input
        .by_ref()
        .take(budget)
        .read_until(b'\n', buffer)
        .map_err(|e| LogError::new(line, LogProblem::Io(e)))?;
    if read == 0 {
        return Ok(false);
    }
    if buffer.last() == Some(&b'\n') {
        buffer.pop();
        if buffer.last() == Some(&b'\r') {
            buffer.pop();
        }
    } else if buffer.len() > max_line_bytes {
        let problem = LogProblem::LineTooLong {
            limit_bytes: max_line_bytes,
        };
        // The field whose value runs past the cap, found in the part that was read.
        return Err(match field_at(buffer, buffer.len()) {
            Some(field) => LogError::at_field(line, field, problem),
            None => LogError::new(line, problem),
        });
    }
    Ok(true)
}

/// Most overflowing number literals one line may hold before it is refused outright.
const MAX_OUT_OF_RANGE_NUMBERS: usize = 16;

fn is_number_byte(byte: u8) -> bool {
    byte.is_ascii_digit() || matches!(byte, b'-' | b'+' | b'.' | b'e' | b'E')
}

/// Replaces the number literal around byte `column - 1` (serde_json's 1-based
/// column of a "number out of range" error) by a marker string.
fn mark_out_of_range(text: &[u8], column: usize) -> Option<Vec<u8>> {
    let at = column.checked_sub(1)?;
    if !is_number_byte(*text.get(at)?) {
        return None;
    }
    let start = text
        .get(..at)?
        .iter()
        .rposition(|b| !is_number_byte(*b))
        .map_or(0, |i| i + 1);
    let end = text
        .get(at..)?
        .iter()
        .position(|b| !is_number_byte(*b))
        .map_or(text.len(), |i| at + i);
    let literal = std::str::from_utf8(text.get(start..end)?).ok()?;
    let marker = serde_json::to_string(&format!("{OUT_OF_RANGE_MARKER}{literal}")).ok()?;
    Some([text.get(..start)?, marker.as_bytes(), text.get(end..)?].concat())
}

/// serde_json's message with its position as a column of this log line (its own
/// "line 1" would read as the log's line 1).
fn json_message(error: &serde_json::Error) -> String {
    let text = error.to_string();
    let message = text
        .rfind(" at line ")
        .and_then(|at| text.get(..at))
        .unwrap_or(&text);
    format!("{message} at column {}", error.column())
}

/// Parses one line. JSON has no NaN or infinity, but a literal such as `1e999`
/// overflows f64: such literals are marked so that the decoder reports them as
/// non-finite numbers naming their field, rather than as a bare syntax error.
///
/// A line that still does not parse (cut off, a `NaN` literal) is reported with
/// the field the syntax error falls in, when it falls in one.
fn parse_json(line: usize, bytes: &[u8]) -> Result<Value, LogError> {
    let invalid = |text: &[u8], e: serde_json::Error| {
        let problem = LogProblem::InvalidJson(json_message(&e));
        // serde_json's column is 1-based and counts bytes: the scan stops on the offending byte.
        match field_at(text, e.column()) {
            Some(field) => LogError::at_field(line, field, problem),
            None => LogError::new(line, problem),
        }
    };
    if let Err(e) = std::str::from_utf8(bytes) {
        let at = e.valid_up_to();
        let problem = LogProblem::InvalidJson(format!("invalid UTF-8 at column {}", at + 1));
        return Err(match field_at(bytes, at) {
            Some(field) => LogError::at_field(line, field, problem),
            None => LogError::new(line, problem),
        });
    }
    let mut text = Cow::Borrowed(bytes);
    for _ in 0..MAX_OUT_OF_RANGE_NUMBERS {
        match serde_json::from_slice(&text) {
            Ok(value) => return Ok(value),
            Err(e) if e.to_string().starts_with("number out of range") => {
                match mark_out_of_range(&text, e.column()) {
                    Some(marked) => text = Cow::Owned(marked),
                    None => return Err(invalid(&text, e)),
                }
            }
            Err(e) => return Err(invalid(&text, e)),
        }
    }
    serde_json::from_slice(&text).map_err(|e| invalid(&text, e))
}

fn is_blank(bytes: &[u8]) -> bool {
    bytes.iter().all(u8::is_ascii_whitespace)
}

impl<R: BufRead> LogReader<R> {
    /// Reads and validates line 1 (the header) with the default line cap.
    pub fn new(input: R) -> Result<Self, LogError> {
        Self::with_max_line_bytes(input, DEFAULT_MAX_LINE_BYTES)
    }

    pub fn with_max_line_bytes(mut input: R, max_line_bytes: usize) -> Result<Self, LogError> {
        let mut buffer = Vec::new();
        if !read_bounded_line(&mut input, &mut buffer, max_line_bytes, 1)? {
            return Err(LogError::new(1, LogProblem::MissingHeader));
        }
        let header = parse_header(1, &parse_json(1, &buffer)?)?;
        Ok(Self {
            input,
            header,
            max_line_bytes,
            line: 1,
            previous_t_s: None,
            buffer,
            finished: false,
        })
    }

    pub fn header(&self) -> &LogHeader {
        &self.header
    }

    /// Number of the last line read (1-based).
    pub fn line(&self) -> usize {
        self.line
    }

    fn next_frame(&mut self) -> Result<Option<ObservationFrame>, LogError> {
        loop {
            self.line += 1;
            if !read_bounded_line(
                &mut self.input,
                &mut self.buffer,
                self.max_line_bytes,
                self.line,
            )? {
                return Ok(None);
            }
            // Blank lines after the header (e.g. a trailing empty line) carry nothing.
            if !is_blank(&self.buffer) {
                break;
            }
        }
        let value = parse_json(self.line, &self.buffer)?;
        let frame = parse_frame(self.line, &value, &self.header, self.previous_t_s)?;
        self.previous_t_s = Some(frame.t_s);
        Ok(Some(frame))
    }
}

impl<R: BufRead> Iterator for LogReader<R> {
    type Item = Result<ObservationFrame, LogError>;

    fn next(&mut self) -> Option<Self::Item> {
        if self.finished {
            return None;
        }
        match self.next_frame() {
            Ok(Some(frame)) => Some(Ok(frame)),
            Ok(None) => {
                self.finished = true;
                None
            }
            Err(e) => {
                self.finished = true;
                Some(Err(e))
            }
        }
    }
}

impl<R: BufRead> LogReader<R> {
    /// Frames together with the line each came from (blank lines are skipped, so
    /// a frame's line is not always its index + 2).
    pub fn numbered(self) -> NumberedFrames<R> {
        NumberedFrames(self)
    }
}

/// Iterator of `(line, frame)`; see [`LogReader::numbered`].
pub struct NumberedFrames<R>(LogReader<R>);

impl<R: BufRead> Iterator for NumberedFrames<R> {
    type Item = Result<(usize, ObservationFrame), LogError>;

    fn next(&mut self) -> Option<Self::Item> {
        let frame = self.0.next()?;
        Some(frame.map(|frame| (self.0.line, frame)))
    }
}

/// Reads a whole log into memory.
pub fn read_log<R: BufRead>(input: R) -> Result<ObservationLog, LogError> {
    let mut reader = LogReader::new(input)?;
    let header = *reader.header();
    let frames = reader.by_ref().collect::<Result<Vec<_>, _>>()?;
    Ok(ObservationLog { header, frames })
}
