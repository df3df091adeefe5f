//! Camera recordings (docs/reference/recording.md): a folder of 8-bit
//! grayscale PNG frames, `frames.csv` (trigger ids, capture times, the
//! encoder angle and the gripper's mark positions latched at each trigger)
//! and `recording.json` (camera, lens, mark sizes). What a vision front end
//! reads ([`crate::front_end`]); the simulator writes its own runs as
//! recordings ([`simulate`]), with a truth file beside them for scoring only.

pub mod error;
pub mod header;
pub mod png_io;
pub mod rows;
pub mod simulate;

use std::fs;
use std::path::{Path, PathBuf};

pub use error::RecordingError;
pub use header::{MarkSpec, Polarity, RecordingHeader};
pub use rows::FrameRow;

/// The header's file name.
pub const HEADER_FILE: &str = "recording.json";
/// The frames' table.
pub const FRAMES_FILE: &str = "frames.csv";

/// A recording opened for reading: the header and every row, checked; the
/// images are read one at a time ([`Recording::image`]).
#[derive(Debug, Clone)]
pub struct Recording {
    pub folder: PathBuf,
    pub header: RecordingHeader,
    pub rows: Vec<FrameRow>,
}

impl Recording {
    /// Opens the recording in `folder`: reads and checks the header and
    /// `frames.csv` (not yet the images).
    pub fn open(folder: &Path) -> Result<Self, RecordingError> {
        let header_path = folder.join(HEADER_FILE);
        let text = fs::read_to_string(&header_path).map_err(RecordingError::io(&header_path))?;
        let header = RecordingHeader::parse(&text)?;
        let rows_path = folder.join(FRAMES_FILE);
        let text = fs::read_to_string(&rows_path).map_err(RecordingError::io(&rows_path))?;
        let rows = rows::parse_rows(&text, header.effector.len())?;
        Ok(Self {
            folder: folder.to_path_buf(),
            header,
            rows,
        })
    }

    /// The pixels of `row`'s frame (rows top to bottom), or an error naming
    /// its file.
    pub fn image(&self, row: &FrameRow) -> Result<Vec<u8>, RecordingError> {
        png_io::read_gray_png(
            &self.folder.join(&row.image),
            &row.image,
            self.header.camera.width,
            self.header.camera.height,
        )
    }

    /// Every frame in order with its pixels. With `skip_bad_images`, a frame
    /// whose image is missing, undecodable or of the wrong size is left out
    /// and counted (the second value); without, it is an error.
    pub fn frames(
        &self,
        skip_bad_images: bool,
    ) -> impl Iterator<Item = Result<(&FrameRow, Vec<u8>), RecordingError>> + '_ {
        self.rows
            .iter()
            .filter_map(move |row| match self.image(row) {
                Ok(pixels) => Some(Ok((row, pixels))),
                Err(RecordingError::Image { .. }) if skip_bad_images => None,
                Err(e) => Some(Err(e)),
            })
    }
}

/// Writes a recording frame by frame: the header and the table's header row
/// on creation, then each frame's PNG and row.
pub struct RecordingWriter {
    folder: PathBuf,
    header: RecordingHeader,
    table: String,
    last: Option<FrameRow>,
}

impl RecordingWriter {
    /// Creates `folder` (and `images/`) and writes `recording.json`.
    pub fn create(folder: &Path, header: &RecordingHeader) -> Result<Self, RecordingError> {
        let images = folder.join("images");
        fs::create_dir_all(&images).map_err(RecordingError::io(&images))?;
        // What the reader would refuse is refused here.
        let text = header.to_json();
        RecordingHeader::parse(&text)?;
        let path = folder.join(HEADER_FILE);
        fs::write(&path, format!("{text}\n")).map_err(RecordingError::io(&path))?;
        let mut table = rows::column_names(header.effector.len()).join(",");
        table.push('\n');
        Ok(Self {
            folder: folder.to_path_buf(),
            header: header.clone(),
            table,
            last: None,
        })
    }

    /// Appends one frame: `row.image` is set to `images/<trigger id>.png`.
    pub fn push(&mut self, mut row: FrameRow, pixels: &[u8]) -> Result<(), RecordingError> {
        row.image = format!("images/{:06}.png", row.trigger_id);
        // The row must read back: increasing ids, finite numbers, first angle 0.
        row.line = self.last.as_ref().map_or(2, |last| last.line + 1);
        if row.effector_base_m.len() != self.header.effector.len() {
            return Err(RecordingError::row(
                row.line,
                "e0_base_x_m",
                "wrong number of effector marks",
            ));
        }
        rows::check_follows(self.last.as_ref(), &row)?;
        let expected = self.header.camera.width as usize * self.header.camera.height as usize;
        if pixels.len() != expected {
            return Err(RecordingError::image(&row.image, "wrong number of pixels"));
        }
        png_io::write_gray_png(
            &self.folder.join(&row.image),
            self.header.camera.width,
            self.header.camera.height,
            pixels,
        )?;
        self.table.push_str(&rows::format_row(&row));
        self.last = Some(row);
        Ok(())
    }

    /// Writes `frames.csv`.
    pub fn finish(self) -> Result<PathBuf, RecordingError> {
        let path = self.folder.join(FRAMES_FILE);
        fs::write(&path, &self.table).map_err(RecordingError::io(&path))?;
        Ok(self.folder)
    }
}

#[cfg(test)]
mod tests;
