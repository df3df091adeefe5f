//! Streaming reader of a JSON Lines observation log (contract version 1).
//!
//! Lines are read with a length cap so that a corrupt file (say, a binary blob
//! with no newline) fails with a clear error instead of exhausting memory;
//! frames are decoded one at a time so a long log never has to be held whole.

use std::io::{BufRead, Read};

use serde_json::Value;
use shared::observation::{LogHeader, ObservationFrame};

use super::error::{LogError, LogProblem};
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
        return Err(LogError::new(
            line,
            LogProblem::LineTooLong {
                limit_bytes: max_line_bytes,
            },
        ));
    }
    Ok(true)
}

fn parse_json(line: usize, bytes: &[u8]) -> Result<Value, LogError> {
    serde_json::from_slice(bytes)
        .map_err(|e| LogError::new(line, LogProblem::InvalidJson(e.to_string())))
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

/// Reads a whole log into memory.
pub fn read_log<R: BufRead>(input: R) -> Result<ObservationLog, LogError> {
    let mut reader = LogReader::new(input)?;
    let header = *reader.header();
    let frames = reader.by_ref().collect::<Result<Vec<_>, _>>()?;
    Ok(ObservationLog { header, frames })
}
