//! The observation log of `spec/frames-and-log.md` as JSON Lines: a streaming
//! reader whose every error names the line and the field, and a writer that
//! refuses anything the reader would refuse.

pub mod error;
mod fields;
mod locate;
pub mod reader;
mod record;
pub mod writer;

use std::fs::File;
use std::io::{BufReader, BufWriter};
use std::path::Path;

use anyhow::Context;
use shared::observation::{LogHeader, ObservationFrame};

pub use error::{LogError, LogProblem};
pub use reader::{read_log, LogReader, NumberedFrames, DEFAULT_MAX_LINE_BYTES};
pub use writer::{write_log, LogWriter};

/// A whole log held in memory: the header and the frames in file order.
#[derive(Debug, Clone, PartialEq)]
pub struct ObservationLog {
    pub header: LogHeader,
    pub frames: Vec<ObservationFrame>,
}

/// Opens `path` for streaming (the header is read and checked here).
pub fn open_log(path: &Path) -> anyhow::Result<LogReader<BufReader<File>>> {
    let file = File::open(path).with_context(|| format!("cannot open log {}", path.display()))?;
    LogReader::new(BufReader::new(file)).with_context(|| format!("in log {}", path.display()))
}

/// Reads the whole log at `path`.
pub fn read_log_file(path: &Path) -> anyhow::Result<ObservationLog> {
    let file = File::open(path).with_context(|| format!("cannot open log {}", path.display()))?;
    read_log(BufReader::new(file)).with_context(|| format!("in log {}", path.display()))
}

/// Writes `log` to `path` (created or truncated).
pub fn write_log_file(path: &Path, log: &ObservationLog) -> anyhow::Result<()> {
    let file =
        File::create(path).with_context(|| format!("cannot create log {}", path.display()))?;
    write_log(BufWriter::new(file), log)
        .map(drop)
        .with_context(|| format!("writing log {}", path.display()))
}
