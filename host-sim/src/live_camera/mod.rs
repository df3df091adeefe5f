//! A live camera as a recording's source (`host-sim vision-live`): frames
//! grabbed from a V4L2 device (the `v4l2` feature, [`device`]), converted
//! to 8-bit grey ([`pixels`]) and written as a recording's images with
//! `captures.csv` (trigger count, host capture time, image) beside them.
//! The encoder values a recording needs at each trigger (the conveyor's
//! angle, the gripper marks' base-frame positions) cannot come from a
//! camera: given a latches CSV ([`latches`]), `frames.csv` is written from
//! it and the folder is a complete recording (docs/reference/recording.md);
//! without, it is not one, and `vision-log` says which columns it lacks.

#[cfg(feature = "v4l2")]
pub mod device;
pub mod latches;
pub mod pixels;

use std::fs;
use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};

use self::latches::Latch;
use crate::camera_recording::png_io::write_gray_png;
use crate::camera_recording::rows::{check_follows, column_names, format_row};
use crate::camera_recording::{FrameRow, Recording, RecordingHeader, FRAMES_FILE, HEADER_FILE};

/// The captures' table: what the camera alone gives.
pub const CAPTURES_FILE: &str = "captures.csv";

/// One grabbed frame.
#[derive(Debug, Clone, PartialEq)]
struct Captured {
    capture_time_us: u64,
    image: String,
}

/// A live recording being written.
pub struct LiveRecording {
    folder: PathBuf,
    header: RecordingHeader,
    captured: Vec<Captured>,
}

/// What was written.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct LiveWritten {
    pub frames: usize,
    /// `frames.csv` was written: the folder is a complete recording.
    pub complete: bool,
}

impl LiveRecording {
    /// Creates `folder` (and `images/`) and writes the header.
    pub fn create(folder: &Path, header: &RecordingHeader) -> Result<Self> {
        let images = folder.join("images");
        fs::create_dir_all(&images)
            .with_context(|| format!("cannot create {}", images.display()))?;
        let text = header.to_json();
        RecordingHeader::parse(&text)?;
        let path = folder.join(HEADER_FILE);
        fs::write(&path, format!("{text}\n")).with_context(|| path.display().to_string())?;
        Ok(Self {
            folder: folder.to_path_buf(),
            header: header.clone(),
            captured: Vec::new(),
        })
    }

    /// Writes one grey frame captured at `capture_time_us` (host clock).
    pub fn push(&mut self, capture_time_us: u64, grey: &[u8]) -> Result<()> {
        let camera = &self.header.camera;
        if grey.len() != camera.width as usize * camera.height as usize {
            bail!(
                "a frame of {} pixels for the header's {} x {}",
                grey.len(),
                camera.width,
                camera.height
            );
        }
        let image = format!("images/{:06}.png", self.captured.len());
        write_gray_png(&self.folder.join(&image), camera.width, camera.height, grey)?;
        self.captured.push(Captured {
            capture_time_us,
            image,
        });
        Ok(())
    }

    /// Writes `captures.csv` and, with `latches` (one a frame, in order),
    /// `frames.csv`, read back as a recording to be sure.
    pub fn finish(self, latches: Option<&[Latch]>) -> Result<LiveWritten> {
        let mut captures = String::from("trigger_id,capture_time_us,image\n");
        for (k, c) in self.captured.iter().enumerate() {
            captures.push_str(&format!("{k},{},{}\n", c.capture_time_us, c.image));
        }
        let path = self.folder.join(CAPTURES_FILE);
        fs::write(&path, captures).with_context(|| path.display().to_string())?;
        let frames = self.captured.len();
        let Some(latches) = latches else {
            return Ok(LiveWritten {
                frames,
                complete: false,
            });
        };
        let rows = latched_rows(&self.captured, latches, self.header.effector.len())?;
        let mut table = column_names(self.header.effector.len()).join(",");
        table.push('\n');
        for row in &rows {
            table.push_str(&format_row(row));
        }
        let path = self.folder.join(FRAMES_FILE);
        fs::write(&path, table).with_context(|| path.display().to_string())?;
        Recording::open(&self.folder)
            .with_context(|| format!("the recording written in {}", self.folder.display()))?;
        Ok(LiveWritten {
            frames,
            complete: true,
        })
    }
}

/// Refuses a latches file with fewer rows than frames to grab (before
/// grabbing).
pub fn check_latch_count(latches: &[Latch], frames: usize) -> Result<()> {
    if latches.len() < frames {
        bail!(
            "{frames} frames to grab, the latches file has {} rows (one a trigger)",
            latches.len()
        );
    }
    Ok(())
}

/// The frames' rows: the k-th frame with the k-th latch.
fn latched_rows(
    captured: &[Captured],
    latches: &[Latch],
    effector_marks: usize,
) -> Result<Vec<FrameRow>> {
    check_latch_count(latches, captured.len())?;
    let first_angle = latches.first().map_or(0.0, |l| l.conveyor_angle_rad);
    let mut rows: Vec<FrameRow> = Vec::with_capacity(captured.len());
    for (k, (c, latch)) in captured.iter().zip(latches).enumerate() {
        if latch.effector_base_m.len() != effector_marks {
            bail!(
                "latch {k}: {} effector marks, the header has {effector_marks}",
                latch.effector_base_m.len()
            );
        }
        let row = FrameRow {
            line: k + 2,
            trigger_id: latch.trigger_id.unwrap_or(k as u64),
            capture_time_us: latch.capture_time_us.unwrap_or(c.capture_time_us),
            conveyor_angle_rad: latch.conveyor_angle_rad - first_angle,
            image: c.image.clone(),
            effector_base_m: latch.effector_base_m.clone(),
        };
        check_follows(rows.last(), &row)?;
        rows.push(row);
    }
    Ok(rows)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn header() -> RecordingHeader {
        let text = std::fs::read_to_string(
            Path::new(env!("CARGO_MANIFEST_DIR"))
                .join("../tests/data/recording-small/recording.json"),
        )
        .unwrap();
        RecordingHeader::parse(&text).unwrap()
    }

    fn latch(angle: f64) -> Latch {
        Latch {
            trigger_id: None,
            capture_time_us: None,
            conveyor_angle_rad: angle,
            effector_base_m: vec![[0.5, -0.1, 0.6], [0.6, -0.1, 0.6]],
        }
    }

    #[test]
    fn grabbed_frames_with_latches_make_a_recording_the_reader_takes() {
        let dir = tempfile::tempdir().unwrap();
        let mut live = LiveRecording::create(dir.path(), &header()).unwrap();
        for k in 0..3u8 {
            live.push(1_000 * u64::from(k), &vec![k; 256 * 256])
                .unwrap();
        }
        assert!(live.push(0, &[0; 10]).is_err());
        let latches = [latch(1.0), latch(1.1), latch(1.25), latch(1.3)];
        let written = live.finish(Some(&latches)).unwrap();
        assert_eq!(
            written,
            LiveWritten {
                frames: 3,
                complete: true
            }
        );
        let recording = Recording::open(dir.path()).unwrap();
        assert_eq!(recording.rows.len(), 3);
        assert_eq!(recording.rows[0].conveyor_angle_rad, 0.0);
        assert!((recording.rows[2].conveyor_angle_rad - 0.25).abs() < 1e-12);
        assert_eq!(recording.rows[1].capture_time_us, 1_000);
        assert_eq!(
            recording.image(&recording.rows[2]).unwrap(),
            vec![2; 256 * 256]
        );
        assert!(dir.path().join(CAPTURES_FILE).exists());
    }

    #[test]
    fn without_latches_the_folder_is_no_recording_and_says_what_it_lacks() {
        let dir = tempfile::tempdir().unwrap();
        let mut live = LiveRecording::create(dir.path(), &header()).unwrap();
        live.push(0, &vec![9; 256 * 256]).unwrap();
        let written = live.finish(None).unwrap();
        assert!(!written.complete);
        let captures = std::fs::read_to_string(dir.path().join(CAPTURES_FILE)).unwrap();
        assert_eq!(
            captures,
            "trigger_id,capture_time_us,image\n0,0,images/000000.png\n"
        );
        assert!(Recording::open(dir.path()).is_err());
    }

    #[test]
    fn too_few_latches_or_marks_are_refused() {
        assert!(check_latch_count(&[latch(0.0)], 2).is_err());
        let captured = vec![
            Captured {
                capture_time_us: 0,
                image: "a".into(),
            },
            Captured {
                capture_time_us: 5,
                image: "b".into(),
            },
        ];
        let error = latched_rows(&captured, &[latch(0.0)], 2).unwrap_err();
        assert!(error.to_string().contains("2 frames"), "{error}");
        let mut one_mark = latch(0.0);
        one_mark.effector_base_m.pop();
        assert!(latched_rows(&captured, &[latch(0.0), one_mark], 2).is_err());
        // Capture times that go back (from the latches) are refused as the reader would.
        let mut late = latch(0.1);
        late.capture_time_us = Some(0);
        let mut early = latch(0.0);
        early.capture_time_us = Some(10);
        assert!(latched_rows(&captured, &[early, late], 2).is_err());
    }
}
