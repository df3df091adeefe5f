//! Writer of a JSON Lines observation log (contract version 1).
//!
//! Every line is checked by the very decoder the reader uses before it is
//! written, so whatever this writer accepts reads back identically (f64 values
//! are printed in their shortest round-trip form) and a frame with NaN, a wrong
//! feature count or a time going backwards is refused with the same error the
//! reader would give.

use std::io::Write;

use serde::Serialize;
use serde_json::Value;
use shared::observation::{
    CameraIntrinsics, LogHeader, ObservationFrame, PixelPoint, Point3, RimObservation,
    EFFECTOR_POINTS,
};

use super::error::{LogError, LogProblem};
use super::record::{parse_frame, parse_header};
use super::ObservationLog;

#[derive(Serialize)]
struct HeaderLine<'a> {
    #[serde(rename = "type")]
    record_type: &'static str,
    version: u32,
    camera: &'a CameraIntrinsics,
    reference_radius_m: f64,
    part_feature_count: usize,
    #[serde(skip_serializing_if = "Option::is_none")]
    disc_radius_m: Option<f64>,
}

#[derive(Serialize)]
struct FrameLine<'a> {
    #[serde(rename = "type")]
    record_type: &'static str,
    t_s: f64,
    conveyor_angle_rad: f64,
    center_px: Option<PixelPoint>,
    reference_px: Option<PixelPoint>,
    part_px: Option<&'a [PixelPoint]>,
    effector_px: Option<&'a [PixelPoint; EFFECTOR_POINTS]>,
    effector_base_m: Option<&'a [Point3; EFFECTOR_POINTS]>,
    #[serde(skip_serializing_if = "Option::is_none")]
    rim: Option<&'a RimObservation>,
}

fn to_value(line: usize, record: &impl Serialize) -> Result<Value, LogError> {
    serde_json::to_value(record)
        .map_err(|e| LogError::new(line, LogProblem::InvalidJson(e.to_string())))
}

/// The record as one line of text, keys in the contract's order, with its newline.
fn to_line(line: usize, record: &impl Serialize) -> Result<String, LogError> {
    let mut text = serde_json::to_string(record)
        .map_err(|e| LogError::new(line, LogProblem::InvalidJson(e.to_string())))?;
    text.push('\n');
    Ok(text)
}

fn io_error(line: usize) -> impl FnOnce(std::io::Error) -> LogError {
    move |e| LogError::new(line, LogProblem::Io(e))
}

/// Writes the header on construction, then one frame per call.
pub struct LogWriter<W: Write> {
    output: W,
    header: LogHeader,
    /// Number of the last line written (1-based).
    line: usize,
    previous_t_s: Option<f64>,
}

impl<W: Write> LogWriter<W> {
    pub fn new(mut output: W, header: &LogHeader) -> Result<Self, LogError> {
        let line = HeaderLine {
            record_type: "header",
            version: header.version,
            camera: &header.camera,
            reference_radius_m: header.reference_radius_m,
            part_feature_count: header.part_feature_count,
            disc_radius_m: header.disc_radius_m,
        };
        let header = parse_header(1, &to_value(1, &line)?)?;
        output
            .write_all(to_line(1, &line)?.as_bytes())
            .map_err(io_error(1))?;
        Ok(Self {
            output,
            header,
            line: 1,
            previous_t_s: None,
        })
    }

    /// Validates and appends one frame; on error nothing is written.
    pub fn write_frame(&mut self, frame: &ObservationFrame) -> Result<(), LogError> {
        let line = self.line + 1;
        let record = FrameLine {
            record_type: "frame",
            t_s: frame.t_s,
            conveyor_angle_rad: frame.conveyor_angle_rad,
            center_px: frame.center_px,
            reference_px: frame.reference_px,
            part_px: frame.part_px.as_deref(),
            effector_px: frame.effector.as_ref().map(|e| &e.px),
            effector_base_m: frame.effector.as_ref().map(|e| &e.base_m),
            rim: frame.rim.as_ref(),
        };
        parse_frame(
            line,
            &to_value(line, &record)?,
            &self.header,
            self.previous_t_s,
        )?;
        let text = to_line(line, &record)?;
        self.output
            .write_all(text.as_bytes())
            .map_err(io_error(line))?;
        self.line = line;
        self.previous_t_s = Some(frame.t_s);
        Ok(())
    }

    /// Flushes and returns the output.
    pub fn finish(mut self) -> Result<W, LogError> {
        self.output.flush().map_err(io_error(self.line))?;
        Ok(self.output)
    }
}

/// Writes a whole log.
pub fn write_log<W: Write>(output: W, log: &ObservationLog) -> Result<W, LogError> {
    let mut writer = LogWriter::new(output, &log.header)?;
    for frame in &log.frames {
        writer.write_frame(frame)?;
    }
    writer.finish()
}
