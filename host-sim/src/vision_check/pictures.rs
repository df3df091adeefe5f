//! Pictures of what the detector sees: a rendered frame, enlarged, with the
//! detections circled in green and the marks' true centres crossed (red where
//! the detector should find them, orange where they are partly hidden or at
//! the border); and a PNG sequence of a few seconds of frames.

use std::path::Path;

use anyhow::{Context, Result};

use super::KeptFrame;
use crate::overlay::Canvas;

/// Enlargement of the pictures.
const SCALE: usize = 3;

/// Writes `kept` as a PNG with its detections and the truth drawn.
pub fn write_frame_png(kept: &KeptFrame, path: &Path) -> Result<()> {
    let frame = &kept.frame;
    let mut canvas = Canvas::from_gray(frame.width, frame.height, &frame.pixels, SCALE)?;
    for mark in &kept.marks {
        if !mark.facing || mark.hidden_fraction >= 1.0 {
            continue;
        }
        let colour = if mark.visible() {
            [230, 40, 40]
        } else {
            [255, 160, 0]
        };
        canvas.cross(mark.centre_px[0], mark.centre_px[1], 4, colour);
    }
    for blob in &kept.blobs {
        canvas.circle(
            f64::from(blob.x_px),
            f64::from(blob.y_px),
            f64::from(blob.semi_major_px) + 2.0,
            1,
            [40, 220, 60],
        );
    }
    canvas.write_png(path)
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
