//! Pictures drawn over camera frames: a grey frame enlarged into an RGB
//! canvas, circles, crosses, squares and text (a built-in 5 x 7 bitmap font,
//! [`font`]) drawn on it, written as PNG; and an animated GIF of such
//! canvases ([`animation`]). What `host-sim vision-check` draws its
//! detections with and `host-sim vision-log --pictures` its labels.

pub mod animation;
pub mod font;

use std::fs::File;
use std::io::BufWriter;
use std::path::Path;

use anyhow::{bail, Context, Result};

/// An RGB colour.
pub type Rgb = [u8; 3];

/// A frame enlarged `scale` times, to draw on. Canvas pixel `(x, y)` is
/// `rgb[3 * (y * width + x)..][..3]`.
#[derive(Debug, Clone, PartialEq)]
pub struct Canvas {
    pub width: usize,
    pub height: usize,
    pub scale: usize,
    pub rgb: Vec<u8>,
}

impl Canvas {
    /// `pixels` (8-bit grey, `width` x `height`, rows top to bottom), each
    /// pixel a `scale` x `scale` square.
    pub fn from_gray(width: usize, height: usize, pixels: &[u8], scale: usize) -> Result<Self> {
        if pixels.len() != width * height {
            bail!("{} pixels for a {width} x {height} frame", pixels.len());
        }
        if scale == 0 {
            bail!("a picture's enlargement must be at least 1");
        }
        let (cw, ch) = (width * scale, height * scale);
        let mut rgb = Vec::with_capacity(3 * cw * ch);
        for row in pixels.chunks_exact(width.max(1)) {
            let mut line = Vec::with_capacity(3 * cw);
            for &grey in row {
                for _ in 0..scale {
                    line.extend_from_slice(&[grey; 3]);
                }
            }
            for _ in 0..scale {
                rgb.extend_from_slice(&line);
            }
        }
        Ok(Self {
            width: cw,
            height: ch,
            scale,
            rgb,
        })
    }

    /// The colour of canvas pixel `(x, y)`, if inside.
    pub fn pixel(&self, x: usize, y: usize) -> Option<Rgb> {
        if x >= self.width || y >= self.height {
            return None;
        }
        let i = 3 * (y * self.width + x);
        self.rgb.get(i..i + 3).map(|p| [p[0], p[1], p[2]])
    }

    /// Paints canvas pixel `(x, y)`; outside the canvas, nothing.
    pub fn put(&mut self, x: f64, y: f64, colour: Rgb) {
        if !(x >= 0.0 && y >= 0.0) {
            return;
        }
        let (x, y) = (x as usize, y as usize);
        if x >= self.width || y >= self.height {
            return;
        }
        let i = 3 * (y * self.width + x);
        if let Some(pixel) = self.rgb.get_mut(i..i + 3) {
            pixel.copy_from_slice(&colour);
        }
    }

    /// Canvas coordinate of image coordinate `u` (image pixel `i`'s centre
    /// at `i`, the detector's convention).
    pub fn at(&self, u: f64) -> f64 {
        (u + 0.5) * self.scale as f64
    }

    /// A circle about image point `(u, v)` of `radius_px` image pixels,
    /// `thickness` canvas pixels wide (growing outwards).
    pub fn circle(&mut self, u: f64, v: f64, radius_px: f64, thickness: usize, colour: Rgb) {
        let (cx, cy) = (self.at(u), self.at(v));
        for t in 0..thickness.max(1) {
            let r = radius_px * self.scale as f64 + t as f64;
            let steps = (r * 8.0).ceil().max(16.0) as usize;
            for k in 0..steps {
                let a = std::f64::consts::TAU * k as f64 / steps as f64;
                self.put(cx + r * a.cos(), cy + r * a.sin(), colour);
            }
        }
    }

    /// An X of half-size `half` canvas pixels on image point `(u, v)`.
    pub fn cross(&mut self, u: f64, v: f64, half: i32, colour: Rgb) {
        let (cx, cy) = (self.at(u), self.at(v));
        for d in -half..=half {
            let d = f64::from(d);
            self.put(cx + d, cy + d, colour);
            self.put(cx + d, cy - d, colour);
        }
    }

    /// A square outline about image point `(u, v)`, `half_px` image pixels
    /// from centre to side, `thickness` canvas pixels wide (growing outwards).
    pub fn square(&mut self, u: f64, v: f64, half_px: f64, thickness: usize, colour: Rgb) {
        let (cx, cy) = (self.at(u), self.at(v));
        for t in 0..thickness.max(1) {
            let h = (half_px * self.scale as f64 + t as f64).round();
            let n = (2.0 * h) as i64;
            for k in 0..=n {
                let s = -h + k as f64;
                self.put(cx + s, cy - h, colour);
                self.put(cx + s, cy + h, colour);
                self.put(cx - h, cy + s, colour);
                self.put(cx + h, cy + s, colour);
            }
        }
    }

    /// Fills the canvas rectangle at `(x, y)` (top left), `w` x `h`.
    pub fn fill(&mut self, x: f64, y: f64, w: usize, h: usize, colour: Rgb) {
        for j in 0..h {
            for i in 0..w {
                self.put(x + i as f64, y + j as f64, colour);
            }
        }
    }

    /// Writes the canvas as an RGB PNG.
    pub fn write_png(&self, path: &Path) -> Result<()> {
        self.write_png_with(path, &self.rgb, |encoder| {
            encoder.set_color(png::ColorType::Rgb);
        })
    }

    /// Writes `data` (8 bits a sample) as a PNG of the canvas's size, the
    /// encoder set up by `setup` (colour type, palette, compression).
    fn write_png_with(
        &self,
        path: &Path,
        data: &[u8],
        setup: impl FnOnce(&mut png::Encoder<'_, BufWriter<File>>),
    ) -> Result<()> {
        let file =
            File::create(path).with_context(|| format!("cannot create {}", path.display()))?;
        let mut encoder =
            png::Encoder::new(BufWriter::new(file), self.width as u32, self.height as u32);
        encoder.set_depth(png::BitDepth::Eight);
        setup(&mut encoder);
        let mut writer = encoder
            .write_header()
            .with_context(|| format!("writing {}", path.display()))?;
        writer
            .write_image_data(data)
            .with_context(|| format!("writing {}", path.display()))?;
        writer
            .finish()
            .with_context(|| format!("writing {}", path.display()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_frame_is_enlarged_pixel_for_pixel() {
        let canvas = Canvas::from_gray(2, 2, &[0, 50, 100, 200], 3).unwrap();
        assert_eq!((canvas.width, canvas.height), (6, 6));
        assert_eq!(canvas.pixel(2, 2), Some([0; 3]));
        assert_eq!(canvas.pixel(3, 0), Some([50; 3]));
        assert_eq!(canvas.pixel(0, 3), Some([100; 3]));
        assert_eq!(canvas.pixel(5, 5), Some([200; 3]));
        assert_eq!(canvas.pixel(6, 0), None);
        assert!(Canvas::from_gray(2, 2, &[0; 3], 3).is_err());
        assert!(Canvas::from_gray(2, 2, &[0; 4], 0).is_err());
    }

    #[test]
    fn a_circle_is_drawn_at_its_radius_and_nowhere_else() {
        let mut canvas = Canvas::from_gray(20, 20, &[0; 400], 3).unwrap();
        canvas.circle(10.0, 10.0, 4.0, 1, [255, 0, 0]);
        let (cx, cy) = (canvas.at(10.0), canvas.at(10.0));
        for y in 0..canvas.height {
            for x in 0..canvas.width {
                if canvas.pixel(x, y) == Some([255, 0, 0]) {
                    let r = (x as f64 + 0.5 - cx).hypot(y as f64 + 0.5 - cy);
                    assert!((r - 12.0).abs() < 1.5, "({x}, {y}) at {r}");
                }
            }
        }
        // Right of the centre, on the circle.
        assert_eq!(
            canvas.pixel((cx + 12.0) as usize, cy as usize),
            Some([255, 0, 0])
        );
    }

    #[test]
    fn a_png_reads_back_at_its_size() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("a.png");
        let mut canvas = Canvas::from_gray(4, 3, &[7; 12], 2).unwrap();
        canvas.fill(0.0, 0.0, 1, 1, [1, 2, 3]);
        canvas.write_png(&path).unwrap();
        let decoder = png::Decoder::new(std::io::BufReader::new(File::open(&path).unwrap()));
        let mut reader = decoder.read_info().unwrap();
        let mut buf = vec![0; reader.output_buffer_size()];
        let info = reader.next_frame(&mut buf).unwrap();
        assert_eq!((info.width, info.height), (8, 6));
        assert_eq!(&buf[..6], &[1, 2, 3, 7, 7, 7]);
    }
}
