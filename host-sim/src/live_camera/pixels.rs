//! A V4L2 buffer to the recording's 8-bit grey frame: `GREY` is copied row
//! by row (the driver may pad rows), `YUYV` keeps each pixel's luma (every
//! even byte; chroma dropped). Any other layout, a size other than the
//! recording header's, or a buffer too short for its rows is refused with
//! what was expected and what came.

use std::fmt;

/// The camera layouts a frame can be taken from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PixelLayout {
    /// 8-bit grey, one byte a pixel.
    Grey,
    /// 4:2:2 `Y0 U Y1 V`, two bytes a pixel.
    Yuyv,
}

impl PixelLayout {
    /// The layouts in order of preference (grey needs no conversion).
    pub const PREFERRED: [PixelLayout; 2] = [PixelLayout::Grey, PixelLayout::Yuyv];

    /// The V4L2 four-character code.
    pub fn fourcc(self) -> [u8; 4] {
        match self {
            PixelLayout::Grey => *b"GREY",
            PixelLayout::Yuyv => *b"YUYV",
        }
    }

    /// The layout of a V4L2 four-character code.
    pub fn from_fourcc(fourcc: [u8; 4]) -> Result<Self, LiveError> {
        Self::PREFERRED
            .into_iter()
            .find(|l| l.fourcc() == fourcc)
            .ok_or(LiveError::Layout { fourcc })
    }

    fn bytes_per_pixel(self) -> usize {
        match self {
            PixelLayout::Grey => 1,
            PixelLayout::Yuyv => 2,
        }
    }
}

/// What a live frame can go wrong with.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum LiveError {
    /// A pixel layout other than GREY or YUYV.
    Layout { fourcc: [u8; 4] },
    /// The camera's frame size is not the recording header's.
    Size {
        camera: (u32, u32),
        header: (u32, u32),
    },
    /// Rows shorter than the width needs.
    Stride {
        bytes_per_line: usize,
        needed: usize,
    },
    /// A buffer shorter than its rows.
    Short { bytes: usize, needed: usize },
    /// YUYV pairs pixels: an odd width cannot be.
    OddWidth { width: u32 },
}

impl fmt::Display for LiveError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            LiveError::Layout { fourcc } => write!(
                f,
                "the camera delivers {:?}; only GREY (8-bit grey) and YUYV are taken",
                String::from_utf8_lossy(fourcc)
            ),
            LiveError::Size { camera, header } => write!(
                f,
                "the camera delivers {} x {} frames, the recording's header says {} x {} \
                 (camera.width, camera.height): set one to the other",
                camera.0, camera.1, header.0, header.1
            ),
            LiveError::Stride {
                bytes_per_line,
                needed,
            } => write!(
                f,
                "the driver's rows are {bytes_per_line} bytes, the width needs {needed}"
            ),
            LiveError::Short { bytes, needed } => write!(
                f,
                "a frame of {bytes} bytes, its rows need {needed}: a truncated buffer"
            ),
            LiveError::OddWidth { width } => {
                write!(
                    f,
                    "a YUYV frame {width} pixels wide: the width must be even"
                )
            }
        }
    }
}

impl std::error::Error for LiveError {}

/// Refuses a camera size other than the header's.
pub fn check_size(camera: (u32, u32), header: (u32, u32)) -> Result<(), LiveError> {
    if camera == header {
        Ok(())
    } else {
        Err(LiveError::Size { camera, header })
    }
}

/// The grey frame (`width` x `height`, rows top to bottom) of a buffer of
/// `layout` whose rows start `bytes_per_line` apart (0: packed).
pub fn to_grey(
    layout: PixelLayout,
    width: u32,
    height: u32,
    bytes_per_line: usize,
    data: &[u8],
    grey: &mut Vec<u8>,
) -> Result<(), LiveError> {
    if layout == PixelLayout::Yuyv && width % 2 == 1 {
        return Err(LiveError::OddWidth { width });
    }
    let (w, h) = (width as usize, height as usize);
    let row_bytes = w * layout.bytes_per_pixel();
    let stride = if bytes_per_line == 0 {
        row_bytes
    } else {
        bytes_per_line
    };
    if stride < row_bytes {
        return Err(LiveError::Stride {
            bytes_per_line: stride,
            needed: row_bytes,
        });
    }
    // The last row needs no padding after it.
    let needed = if h == 0 {
        0
    } else {
        (h - 1) * stride + row_bytes
    };
    if data.len() < needed {
        return Err(LiveError::Short {
            bytes: data.len(),
            needed,
        });
    }
    grey.clear();
    grey.reserve(w * h);
    for row in data.chunks(stride).take(h) {
        let row = row.get(..row_bytes).ok_or(LiveError::Short {
            bytes: data.len(),
            needed,
        })?;
        match layout {
            PixelLayout::Grey => grey.extend_from_slice(row),
            PixelLayout::Yuyv => grey.extend(row.iter().step_by(2)),
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn yuyv_keeps_the_luma_of_every_pixel() {
        // Two rows of four pixels: Y0 U Y1 V Y2 U Y3 V.
        let data = [
            10, 128, 20, 128, 30, 100, 40, 200, //
            50, 0, 60, 255, 70, 1, 80, 2,
        ];
        let mut grey = Vec::new();
        to_grey(PixelLayout::Yuyv, 4, 2, 0, &data, &mut grey).unwrap();
        assert_eq!(grey, [10, 20, 30, 40, 50, 60, 70, 80]);
    }

    #[test]
    fn padded_rows_are_read_at_their_stride() {
        // GREY 3 x 2 with rows padded to 4 bytes; the last row unpadded.
        let data = [1, 2, 3, 99, 4, 5, 6];
        let mut grey = vec![7; 20];
        to_grey(PixelLayout::Grey, 3, 2, 4, &data, &mut grey).unwrap();
        assert_eq!(grey, [1, 2, 3, 4, 5, 6]);
        // YUYV 2 x 2 with rows of 6 bytes.
        let data = [9, 0, 8, 0, 255, 255, 7, 0, 6, 0];
        to_grey(PixelLayout::Yuyv, 2, 2, 6, &data, &mut grey).unwrap();
        assert_eq!(grey, [9, 8, 7, 6]);
    }

    #[test]
    fn bad_buffers_are_refused_with_what_was_expected() {
        let mut grey = Vec::new();
        assert_eq!(
            to_grey(PixelLayout::Grey, 4, 2, 0, &[0; 7], &mut grey),
            Err(LiveError::Short {
                bytes: 7,
                needed: 8
            })
        );
        assert_eq!(
            to_grey(PixelLayout::Yuyv, 4, 2, 6, &[0; 16], &mut grey),
            Err(LiveError::Stride {
                bytes_per_line: 6,
                needed: 8
            })
        );
        assert_eq!(
            to_grey(PixelLayout::Yuyv, 3, 2, 0, &[0; 12], &mut grey),
            Err(LiveError::OddWidth { width: 3 })
        );
        let text = check_size((640, 480), (256, 256)).unwrap_err().to_string();
        assert!(
            text.contains("640 x 480") && text.contains("256 x 256"),
            "{text}"
        );
        assert!(check_size((256, 256), (256, 256)).is_ok());
    }

    #[test]
    fn only_grey_and_yuyv_are_taken() {
        assert_eq!(PixelLayout::from_fourcc(*b"GREY"), Ok(PixelLayout::Grey));
        assert_eq!(PixelLayout::from_fourcc(*b"YUYV"), Ok(PixelLayout::Yuyv));
        let refused = PixelLayout::from_fourcc(*b"MJPG").unwrap_err();
        assert!(refused.to_string().contains("MJPG"), "{refused}");
    }
}
