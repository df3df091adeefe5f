//! Grabbing frames from a V4L2 capture device through the `linuxvideo`
//! crate (pure Rust: the V4L2 ioctls through `libc`, no libv4l, no
//! bindgen). The device is asked for the recording header's size in GREY,
//! else YUYV; what the driver settles on is checked against the header
//! and refused when it differs ([`super::pixels`]).
//!
//! The capture time is the host's monotonic clock when the buffer is
//! dequeued (`linuxvideo` 0.3 does not pass on the driver's timestamp):
//! later than the exposure's middle by the driver's and the transfer's
//! latency. A latches file with `capture_time_us` replaces it.

use std::path::Path;
use std::time::Instant;

use anyhow::{bail, Context, Result};
use linuxvideo::format::{PixFormat, PixelFormat};
use linuxvideo::stream::ReadStream;
use linuxvideo::{BufType, Device};

use super::pixels::{check_size, to_grey, PixelLayout};

/// An open capture stream.
pub struct Camera {
    stream: ReadStream,
    layout: PixelLayout,
    width: u32,
    height: u32,
    bytes_per_line: usize,
    started: Option<Instant>,
    raw: Vec<u8>,
}

impl Camera {
    /// Opens `path` for frames of `width` x `height`.
    pub fn open(path: &Path, width: u32, height: u32) -> Result<Self> {
        let device =
            Device::open(path).with_context(|| format!("cannot open {}", path.display()))?;
        let offered = device
            .formats(BufType::VIDEO_CAPTURE)
            .map(|f| f.map(|f| f.pixel_format()))
            .collect::<std::io::Result<Vec<PixelFormat>>>()
            .with_context(|| format!("{}: cannot list its formats", path.display()))?;
        let Some(layout) = PixelLayout::PREFERRED
            .into_iter()
            .find(|l| offered.contains(&PixelFormat::from_fourcc(l.fourcc())))
        else {
            let names: Vec<String> = offered
                .iter()
                .map(|f| String::from_utf8_lossy(&f.as_fourcc()).into_owned())
                .collect();
            bail!(
                "{} offers {names:?}; only GREY and YUYV are taken",
                path.display()
            );
        };
        let wanted = PixFormat::new(width, height, PixelFormat::from_fourcc(layout.fourcc()));
        let capture = device
            .video_capture(wanted)
            .with_context(|| format!("{}: cannot set {width} x {height}", path.display()))?;
        let format = capture.format();
        let (size, settled, bytes_per_line) = (
            (format.width(), format.height()),
            format.pixel_format(),
            format.bytes_per_line() as usize,
        );
        // The driver may change the size or the layout: refuse what is not asked.
        check_size(size, (width, height))?;
        let layout = PixelLayout::from_fourcc(settled.as_fourcc())?;
        let stream = capture
            .into_stream()
            .with_context(|| format!("{}: cannot start streaming", path.display()))?;
        Ok(Self {
            stream,
            layout,
            width,
            height,
            bytes_per_line,
            started: None,
            raw: Vec::new(),
        })
    }

    /// The layout the driver delivers.
    pub fn layout(&self) -> PixelLayout {
        self.layout
    }

    /// Waits for the next frame; returns its capture time (us since the
    /// first frame's) with its grey pixels in `grey`. A buffer the driver
    /// flags as corrupt is an error.
    pub fn grab(&mut self, grey: &mut Vec<u8>) -> Result<u64> {
        let raw = &mut self.raw;
        let corrupt = self
            .stream
            .dequeue(|buffer| {
                raw.clear();
                raw.extend_from_slice(&buffer);
                Ok(buffer.is_error())
            })
            .context("cannot dequeue a frame")?;
        let now = Instant::now();
        let started = *self.started.get_or_insert(now);
        if corrupt {
            bail!("the driver flagged a frame as corrupt");
        }
        to_grey(
            self.layout,
            self.width,
            self.height,
            self.bytes_per_line,
            &self.raw,
            grey,
        )?;
        Ok(now.duration_since(started).as_micros() as u64)
    }
}
