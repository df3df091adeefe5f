//! A borrowed 8-bit grayscale image: the detector's only input.

use core::fmt;

/// Widest image the detector takes: its row buffers are sized for it.
pub const MAX_WIDTH_PX: usize = 512;
/// Tallest image the detector takes: its background tiles are sized for it.
pub const MAX_HEIGHT_PX: usize = 512;

/// A grayscale image in row-major order, `stride` bytes from one row to the next.
#[derive(Debug, Clone, Copy)]
pub struct GrayImage<'a> {
    width: usize,
    height: usize,
    stride: usize,
    pixels: &'a [u8],
}

/// Why an image cannot be looked at.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ImageError {
    /// Width or height zero, or beyond [`MAX_WIDTH_PX`] x [`MAX_HEIGHT_PX`].
    UnsupportedSize {
        /// Columns.
        width: usize,
        /// Rows.
        height: usize,
    },
    /// The stride is shorter than a row.
    StrideTooShort {
        /// Bytes from one row to the next.
        stride: usize,
        /// Columns.
        width: usize,
    },
    /// The buffer is shorter than `stride * (height - 1) + width`.
    Truncated {
        /// Bytes the geometry needs.
        needed: usize,
        /// Bytes given.
        given: usize,
    },
}

impl fmt::Display for ImageError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::UnsupportedSize { width, height } => write!(
                f,
                "image {width} x {height} px: the detector takes 1 to {MAX_WIDTH_PX} x {MAX_HEIGHT_PX} px"
            ),
            Self::StrideTooShort { stride, width } => {
                write!(f, "image stride {stride} B is shorter than its {width} px row")
            }
            Self::Truncated { needed, given } => {
                write!(f, "image buffer of {given} B, its geometry needs {needed} B")
            }
        }
    }
}

impl core::error::Error for ImageError {}

impl<'a> GrayImage<'a> {
    /// Checks the geometry against the buffer once, so that every later pixel
    /// read is in bounds.
    pub fn new(
        width: usize,
        height: usize,
        stride: usize,
        pixels: &'a [u8],
    ) -> Result<Self, ImageError> {
        if width == 0 || height == 0 || width > MAX_WIDTH_PX || height > MAX_HEIGHT_PX {
            return Err(ImageError::UnsupportedSize { width, height });
        }
        if stride < width {
            return Err(ImageError::StrideTooShort { stride, width });
        }
        let needed = stride * (height - 1) + width;
        if pixels.len() < needed {
            return Err(ImageError::Truncated {
                needed,
                given: pixels.len(),
            });
        }
        Ok(Self {
            width,
            height,
            stride,
            pixels,
        })
    }

    /// A tightly packed image (`stride == width`).
    pub fn packed(width: usize, height: usize, pixels: &'a [u8]) -> Result<Self, ImageError> {
        Self::new(width, height, width, pixels)
    }

    /// Columns.
    pub fn width(&self) -> usize {
        self.width
    }

    /// Rows.
    pub fn height(&self) -> usize {
        self.height
    }

    /// Row `y` (empty beyond the last row).
    pub fn row(&self, y: usize) -> &'a [u8] {
        let start = y.saturating_mul(self.stride);
        self.pixels
            .get(start..start.saturating_add(self.width))
            .unwrap_or(&[])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn geometry_is_checked_against_the_buffer() {
        let pixels = [0u8; 30];
        assert!(GrayImage::packed(6, 5, &pixels).is_ok());
        assert_eq!(
            GrayImage::packed(6, 6, &pixels).err(),
            Some(ImageError::Truncated {
                needed: 36,
                given: 30
            })
        );
        assert!(matches!(
            GrayImage::new(6, 2, 4, &pixels),
            Err(ImageError::StrideTooShort { .. })
        ));
        assert!(matches!(
            GrayImage::packed(0, 5, &pixels),
            Err(ImageError::UnsupportedSize { .. })
        ));
        let image = GrayImage::new(4, 3, 10, &pixels).ok();
        assert_eq!(image.map(|i| i.row(2).len()), Some(4));
        assert_eq!(image.map(|i| i.row(3).len()), Some(0));
    }
}
