//! An animated GIF of canvases through the `gif` crate (image-rs; its LZW
//! coder `weezl` is its one dependency without default features). A GIF
//! holds at most 256 colours: one fixed palette serves every frame,
//! [`GREY_LEVELS`] greys for the camera's image and the overlay's colours
//! ([`OVERLAY_COLOURS`]); a grey pixel takes the nearest grey, any other
//! the nearest overlay colour. Fewer greys than the camera's 256 also keep
//! the sensor's noise from changing every pixel of every frame, which is
//! what makes a noisy animation large. (Writing only the pixels that
//! changed from the frame before, the rest transparent, made the GIF of a
//! rendered pick larger, not smaller: the noise still changes a third of
//! the pixels and the holes break LZW's runs.)

use std::fs::File;
use std::io::BufWriter;
use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};

use super::{Canvas, Rgb};

/// Grey levels of the animation's palette (steps of 255 / 31).
pub const GREY_LEVELS: usize = 32;

/// The colours the overlays draw with, besides greys: the animation's
/// palette holds exactly these.
pub const OVERLAY_COLOURS: [Rgb; 10] = [
    [0, 210, 255],   // disc centre
    [255, 220, 0],   // reference
    [60, 230, 60],   // part feature
    [255, 90, 255],  // effector
    [255, 40, 40],   // wrong label, true mark
    [255, 160, 0],   // label on the right mark, point displaced
    [40, 220, 60],   // detections (vision-check)
    [230, 40, 40],   // true centres (vision-check)
    [0, 0, 0],       // outline
    [255, 255, 255], // caption
];

/// The palette, `[r, g, b, ...]`: the greys, then the overlay's colours.
pub fn palette() -> Vec<u8> {
    let mut palette: Vec<u8> = (0..GREY_LEVELS)
        .flat_map(|i| [(i * 255 / (GREY_LEVELS - 1)) as u8; 3])
        .collect();
    palette.extend(OVERLAY_COLOURS.iter().flatten());
    palette
}

/// The palette index of `colour`.
pub fn index_of(colour: Rgb) -> u8 {
    if colour[0] == colour[1] && colour[1] == colour[2] {
        let level = (usize::from(colour[0]) * (GREY_LEVELS - 1) + 127) / 255;
        return level as u8;
    }
    let distance = |c: &Rgb| -> i32 {
        c.iter()
            .zip(colour)
            .map(|(a, b)| (i32::from(*a) - i32::from(b)).pow(2))
            .sum()
    };
    let nearest = OVERLAY_COLOURS
        .iter()
        .enumerate()
        .min_by_key(|(_, c)| distance(c))
        .map_or(0, |(k, _)| k);
    (GREY_LEVELS + nearest) as u8
}

/// `canvas`'s pixels as palette indices.
pub fn indexed(canvas: &Canvas) -> Vec<u8> {
    canvas
        .rgb
        .chunks_exact(3)
        .map(|p| index_of([p[0], p[1], p[2]]))
        .collect()
}

impl Canvas {
    /// Writes the canvas as an indexed PNG with the animation's palette:
    /// a fraction of the size of [`Canvas::write_png`]'s (the sensor's
    /// noise mostly falls between two of the coarser greys), for pages.
    pub fn write_png_indexed(&self, path: &Path) -> Result<()> {
        self.write_png_with(path, &indexed(self), |encoder| {
            encoder.set_color(png::ColorType::Indexed);
            encoder.set_palette(palette());
            encoder.set_compression(png::Compression::Best);
        })
    }
}

/// An animated GIF being written, frame by frame, looping for ever.
pub struct GifWriter {
    encoder: gif::Encoder<BufWriter<File>>,
    width: usize,
    height: usize,
    path: PathBuf,
    frames: usize,
}

impl GifWriter {
    /// Creates `path` for frames of `width` x `height` canvas pixels.
    pub fn create(path: &Path, width: usize, height: usize) -> Result<Self> {
        let (Ok(w), Ok(h)) = (u16::try_from(width), u16::try_from(height)) else {
            bail!("{width} x {height} is larger than a GIF can be (65535 x 65535)");
        };
        let file =
            File::create(path).with_context(|| format!("cannot create {}", path.display()))?;
        let mut encoder = gif::Encoder::new(BufWriter::new(file), w, h, &palette())
            .with_context(|| format!("writing {}", path.display()))?;
        encoder
            .set_repeat(gif::Repeat::Infinite)
            .with_context(|| format!("writing {}", path.display()))?;
        Ok(Self {
            encoder,
            width,
            height,
            path: path.to_path_buf(),
            frames: 0,
        })
    }

    /// Appends `canvas`, shown for `delay_cs` hundredths of a second.
    pub fn push(&mut self, canvas: &Canvas, delay_cs: u16) -> Result<()> {
        if (canvas.width, canvas.height) != (self.width, self.height) {
            bail!(
                "{}: a frame of {} x {} in an animation of {} x {}",
                self.path.display(),
                canvas.width,
                canvas.height,
                self.width,
                self.height
            );
        }
        let frame = gif::Frame {
            delay: delay_cs,
            width: self.width as u16,
            height: self.height as u16,
            buffer: std::borrow::Cow::Owned(indexed(canvas)),
            ..gif::Frame::default()
        };
        self.encoder
            .write_frame(&frame)
            .with_context(|| format!("writing {}", self.path.display()))?;
        self.frames += 1;
        Ok(())
    }

    /// Writes the trailer; returns the frames written.
    pub fn finish(self) -> Result<usize> {
        let frames = self.frames;
        let path = self.path;
        let mut file = self
            .encoder
            .into_inner()
            .with_context(|| format!("writing {}", path.display()))?;
        std::io::Write::flush(&mut file).with_context(|| format!("writing {}", path.display()))?;
        Ok(frames)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn greys_and_overlay_colours_take_their_own_entries() {
        let palette = palette();
        assert!(palette.len() <= 3 * 256);
        for colour in OVERLAY_COLOURS {
            let i = usize::from(index_of(colour));
            assert_eq!(&palette[3 * i..3 * i + 3], &colour);
        }
        for grey in [0u8, 1, 100, 128, 254, 255] {
            let i = usize::from(index_of([grey; 3]));
            let level = palette[3 * i];
            assert!(
                (i32::from(level) - i32::from(grey)).abs() <= 5,
                "{grey} -> {level}"
            );
        }
    }

    #[test]
    fn an_indexed_png_reads_back_in_the_palettes_colours() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("a.png");
        let mut canvas = Canvas::from_gray(3, 1, &[0, 130, 255], 1).unwrap();
        canvas.put(1.0, 0.0, OVERLAY_COLOURS[3]);
        canvas.write_png_indexed(&path).unwrap();
        let mut decoder = png::Decoder::new(std::io::BufReader::new(File::open(&path).unwrap()));
        decoder.set_transformations(png::Transformations::EXPAND);
        let mut reader = decoder.read_info().unwrap();
        let mut rgb = vec![0; reader.output_buffer_size()];
        reader.next_frame(&mut rgb).unwrap();
        assert_eq!(&rgb[..9], &[0, 0, 0, 255, 90, 255, 255, 255, 255]);
    }

    #[test]
    fn an_animation_reads_back_frame_by_frame() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("a.gif");
        let mut writer = GifWriter::create(&path, 6, 4).unwrap();
        let mut canvas = Canvas::from_gray(3, 2, &[0, 60, 120, 180, 240, 255], 2).unwrap();
        writer.push(&canvas, 20).unwrap();
        canvas.put(0.0, 0.0, OVERLAY_COLOURS[1]);
        writer.push(&canvas, 30).unwrap();
        let wrong = Canvas::from_gray(2, 2, &[0; 4], 1).unwrap();
        assert!(writer.push(&wrong, 20).is_err());
        assert_eq!(writer.finish().unwrap(), 2);

        let mut options = gif::DecodeOptions::new();
        options.set_color_output(gif::ColorOutput::RGBA);
        let mut decoder = options.read_info(File::open(&path).unwrap()).unwrap();
        let first = decoder.read_next_frame().unwrap().unwrap();
        assert_eq!((first.width, first.height, first.delay), (6, 4, 20));
        assert_eq!(&first.buffer[..4], &[0, 0, 0, 255]);
        let second = decoder.read_next_frame().unwrap().unwrap();
        assert_eq!(second.delay, 30);
        assert_eq!(&second.buffer[..4], &[255, 220, 0, 255]);
        // Grey 255 at the bottom right, exactly.
        let n = second.buffer.len();
        assert_eq!(&second.buffer[n - 4..], &[255, 255, 255, 255]);
        assert!(decoder.read_next_frame().unwrap().is_none());
    }
}
