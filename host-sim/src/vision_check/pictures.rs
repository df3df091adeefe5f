//! Pictures of what the detector sees: a rendered frame, enlarged, with the
//! detections circled in green and the marks' true centres crossed (red where
//! the detector should find them, orange where they are partly hidden or at
//! the border); and a PNG sequence of a few seconds of frames.

use std::fs::File;
use std::io::BufWriter;
use std::path::Path;

use anyhow::{Context, Result};

use super::KeptFrame;

/// Enlargement of the pictures.
const SCALE: usize = 3;

struct Canvas {
    width: usize,
    height: usize,
    rgb: Vec<u8>,
}

impl Canvas {
    fn put(&mut self, x: f64, y: f64, colour: [u8; 3]) {
        if x < 0.0 || y < 0.0 {
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

    /// Canvas coordinates of image coordinates (pixel `i`'s centre at `i`).
    fn at(u: f64) -> f64 {
        (u + 0.5) * SCALE as f64
    }

    fn circle(&mut self, u: f64, v: f64, radius_px: f64, colour: [u8; 3]) {
        let (cx, cy, r) = (Self::at(u), Self::at(v), radius_px * SCALE as f64);
        let steps = (r * 8.0).ceil().max(16.0) as usize;
        for k in 0..steps {
            let a = std::f64::consts::TAU * k as f64 / steps as f64;
            self.put(cx + r * a.cos(), cy + r * a.sin(), colour);
        }
    }

    fn cross(&mut self, u: f64, v: f64, colour: [u8; 3]) {
        let (cx, cy) = (Self::at(u), Self::at(v));
        for d in -4..=4 {
            let d = f64::from(d);
            self.put(cx + d, cy + d, colour);
            self.put(cx + d, cy - d, colour);
        }
    }
}

/// Writes `kept` as a PNG with its detections and the truth drawn.
pub fn write_frame_png(kept: &KeptFrame, path: &Path) -> Result<()> {
    let frame = &kept.frame;
    let (width, height) = (frame.width * SCALE, frame.height * SCALE);
    let mut canvas = Canvas {
        width,
        height,
        rgb: vec![0; 3 * width * height],
    };
    for y in 0..height {
        for x in 0..width {
            let grey = frame
                .pixels
                .get((y / SCALE) * frame.width + x / SCALE)
                .copied()
                .unwrap_or(0);
            canvas.put(x as f64, y as f64, [grey; 3]);
        }
    }
    for mark in &kept.marks {
        if !mark.facing || mark.hidden_fraction >= 1.0 {
            continue;
        }
        let colour = if mark.visible() {
            [230, 40, 40]
        } else {
            [255, 160, 0]
        };
        canvas.cross(mark.centre_px[0], mark.centre_px[1], colour);
    }
    for blob in &kept.blobs {
        canvas.circle(
            f64::from(blob.x_px),
            f64::from(blob.y_px),
            f64::from(blob.semi_major_px) + 2.0,
            [40, 220, 60],
        );
    }
    let file = File::create(path).with_context(|| format!("cannot create {}", path.display()))?;
    let mut encoder = png::Encoder::new(BufWriter::new(file), width as u32, height as u32);
    encoder.set_color(png::ColorType::Rgb);
    encoder.set_depth(png::BitDepth::Eight);
    let mut writer = encoder
        .write_header()
        .with_context(|| format!("writing {}", path.display()))?;
    writer
        .write_image_data(&canvas.rgb)
        .with_context(|| format!("writing {}", path.display()))?;
    Ok(())
}

/// Writes a few stills and a sequence of `sequence_frames` consecutive frames
/// (the stretch where most gripper marks are in view) into `dir`; returns the
/// files written.
pub fn write_pictures(
    kept: &[KeptFrame],
    dir: &Path,
    sequence_frames: usize,
) -> Result<Vec<String>> {
    std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
    let mut written = Vec::new();
    let n = kept.len();
    for (name, index) in [
        ("start", 0),
        ("quarter", n / 4),
        ("half", n / 2),
        ("three-quarters", 3 * n / 4),
    ] {
        if let Some(frame) = kept.get(index) {
            let file = format!("frame-{name}-t{:.1}s.png", frame.time_s);
            write_frame_png(frame, &dir.join(&file))?;
            written.push(file);
        }
    }
    let effector_visible = |k: &KeptFrame| {
        k.marks
            .iter()
            .filter(|m| {
                matches!(m.kind, crate::world::render::MarkKind::Effector(_)) && m.visible()
            })
            .count()
    };
    let length = sequence_frames.min(n);
    if length > 0 {
        let best = (0..=n - length)
            .max_by_key(|&start| {
                kept.iter()
                    .skip(start)
                    .take(length)
                    .map(effector_visible)
                    .sum::<usize>()
            })
            .unwrap_or(0);
        let sequence = dir.join("sequence");
        std::fs::create_dir_all(&sequence)?;
        for (i, frame) in kept.iter().skip(best).take(length).enumerate() {
            let file = format!("sequence/{i:03}.png");
            write_frame_png(frame, &dir.join(&file))?;
            written.push(file);
        }
    }
    Ok(written)
}
