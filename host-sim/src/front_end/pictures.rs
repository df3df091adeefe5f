//! Pictures of what the front end sees: a stretch of a recording's frames,
//! enlarged, every detected blob circled and each label drawn beside its
//! blob in its kind's colour (disc centre, reference, part feature `i`,
//! effector mark `i`; unlabelled blobs grey), written as PNGs and as an
//! animated GIF at the recording's own pace. With the recording's truth
//! (scoring only), a wrong label is boxed in red and its text ends in `!`;
//! the right mark with its point displaced is boxed in orange.
//!
//! The blobs are drawn where the detector found them (through the lens);
//! the log's points are the same blobs undistorted.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use shared::detection::identify::MarkLabel;

use super::score::{Judge, Verdict};
use super::{FrameLabels, FrontEndRun};
use crate::camera_recording::Recording;
use crate::overlay::animation::GifWriter;
use crate::overlay::font::{text_height, text_width, ADVANCE};
use crate::overlay::{Canvas, Rgb};

/// The colours of the label kinds, of the verdicts and of unlabelled blobs
/// (every one of them in [`crate::overlay::animation::OVERLAY_COLOURS`]
/// but the grey).
pub const DISC_CENTRE_COLOUR: Rgb = [0, 210, 255];
pub const REFERENCE_COLOUR: Rgb = [255, 220, 0];
pub const PART_FEATURE_COLOUR: Rgb = [60, 230, 60];
pub const EFFECTOR_COLOUR: Rgb = [255, 90, 255];
pub const WRONG_COLOUR: Rgb = [255, 40, 40];
pub const OFF_COLOUR: Rgb = [255, 160, 0];
pub const UNLABELLED_COLOUR: Rgb = [150, 150, 150];
const OUTLINE: Rgb = [0, 0, 0];
const CAPTION: Rgb = [255, 255, 255];

/// The name of the animation in the pictures' folder.
pub const ANIMATION_FILE: &str = "labels.gif";

/// What to draw.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct PictureOptions {
    /// The folder to write into (created).
    pub folder: PathBuf,
    /// Frames in the stretch.
    pub frames: usize,
    /// The stretch's first frame (an index into the frames the front end
    /// read, from 0); `None`: the stretch with the most wrong labels, then
    /// the most labels.
    pub first_frame: Option<usize>,
    /// Enlargement.
    pub scale: usize,
    /// PNGs with the animation's palette (smaller, coarser greys).
    pub indexed: bool,
}

/// What was written.
#[derive(Debug, Clone, PartialEq)]
pub struct PicturesWritten {
    pub first_frame: usize,
    pub pngs: Vec<PathBuf>,
    pub animation: PathBuf,
    /// Wrong labels drawn (with the truth).
    pub wrong_labels: usize,
}

/// The colour of `label`'s kind.
pub fn label_colour(label: MarkLabel) -> Rgb {
    match label {
        MarkLabel::DiscCentre => DISC_CENTRE_COLOUR,
        MarkLabel::Reference => REFERENCE_COLOUR,
        MarkLabel::PartFeature(_) => PART_FEATURE_COLOUR,
        MarkLabel::Effector(_) => EFFECTOR_COLOUR,
    }
}

/// The text drawn beside a label's blob: `C`, `R`, `F<i>`, `E<i>`.
pub fn label_text(label: MarkLabel) -> String {
    match label {
        MarkLabel::DiscCentre => "C".into(),
        MarkLabel::Reference => "R".into(),
        MarkLabel::PartFeature(i) => format!("F{i}"),
        MarkLabel::Effector(i) => format!("E{i}"),
    }
}

/// Font size (canvas pixels a font pixel) for a canvas this wide.
fn font_size(canvas: &Canvas) -> usize {
    if canvas.width >= 480 {
        2
    } else {
        1
    }
}

/// A canvas rectangle: left, top, right, bottom.
type Rect = [f64; 4];

fn overlaps(a: &Rect, b: &Rect) -> bool {
    a[0] < b[2] && b[0] < a[2] && a[1] < b[3] && b[1] < a[3]
}

/// Where a label's text of `w` x `h` goes beside the circle of canvas
/// radius `r` about `(cx, cy)`: the first of up right, down right, up
/// left, down left and further up that covers no other text nor another
/// blob's circle; else the place covering fewest.
fn place_text(centre: (f64, f64), r: f64, size: (f64, f64), taken: &[Rect]) -> Rect {
    let ((cx, cy), (w, h)) = (centre, size);
    let (right, left) = (cx + 0.7 * r + 2.0, cx - 0.7 * r - 2.0 - w);
    let (up, down) = (cy - 0.7 * r - h - 1.0, cy + 0.7 * r + 1.0);
    let mut candidates = vec![(right, up), (right, down), (left, up), (left, down)];
    candidates.extend((1..=3).map(|n| (right, up - f64::from(n) * (h + 2.0))));
    candidates
        .into_iter()
        .map(|(x, y)| [x, y, x + w, y + h])
        .enumerate()
        .min_by_key(|(k, rect)| (taken.iter().filter(|t| overlaps(rect, t)).count(), *k))
        .map_or([right, up, right + w, up + h], |(_, rect)| rect)
}

/// Draws `frame`'s blobs and labels on `canvas` (the frame's image,
/// enlarged). `verdicts[k]` judges `frame.points[k]` (empty: no truth).
pub fn draw_labels(canvas: &mut Canvas, frame: &FrameLabels, verdicts: &[Option<Verdict>]) {
    let size = font_size(canvas);
    let scale = canvas.scale as f64;
    let circle_of = |blob: &shared::detection::Blob| {
        let (u, v) = (f64::from(blob.x_px), f64::from(blob.y_px));
        (u, v, f64::from(blob.semi_major_px) + 2.0)
    };
    // Every circle first; the texts keep off them and off each other.
    let mut taken: Vec<Rect> = Vec::new();
    for (b, blob) in frame.blobs.iter().enumerate() {
        let (u, v, radius_px) = circle_of(blob);
        let (cx, cy, r) = (canvas.at(u), canvas.at(v), radius_px * scale + 2.0);
        taken.push([cx - r, cy - r, cx + r, cy + r]);
        let mut labelled = false;
        for (k, point) in frame.points.iter().enumerate().filter(|(_, p)| p.blob == b) {
            labelled = true;
            match verdicts.get(k).copied().flatten() {
                Some(Verdict::Wrong) => canvas.square(u, v, radius_px + 1.5, 2, WRONG_COLOUR),
                Some(Verdict::Off) => canvas.square(u, v, radius_px + 1.5, 1, OFF_COLOUR),
                _ => {}
            }
            canvas.circle(u, v, radius_px, 2, label_colour(point.label));
        }
        if !labelled {
            canvas.circle(u, v, radius_px, 1, UNLABELLED_COLOUR);
        }
    }
    for (k, point) in frame.points.iter().enumerate() {
        let Some(blob) = frame.blobs.get(point.blob) else {
            continue;
        };
        let mut text = label_text(point.label);
        if verdicts.get(k).copied().flatten() == Some(Verdict::Wrong) {
            text.push('!');
        }
        let (u, v, radius_px) = circle_of(blob);
        let (cx, cy) = (canvas.at(u), canvas.at(v));
        // Its own circle is no obstacle.
        let others: Vec<Rect> = taken
            .iter()
            .enumerate()
            .filter(|(i, _)| *i != point.blob)
            .map(|(_, r)| *r)
            .collect();
        let (w, h) = (text_width(&text, size) as f64, text_height(size) as f64);
        let rect = place_text((cx, cy), radius_px * scale, (w + 2.0, h + 2.0), &others);
        canvas.text(
            rect[0] + 1.0,
            rect[1] + 1.0,
            &text,
            size,
            label_colour(point.label),
            Some(OUTLINE),
        );
        taken.push(rect);
    }
}

/// A line of text on a black band across the top or the bottom of the
/// canvas, at the label font's size if it fits, else at the smallest.
fn band(canvas: &mut Canvas, at_bottom: bool, pieces: &[(&str, Rgb)]) {
    let gap = |size: usize| 2 * ADVANCE * size;
    let line_width = |size: usize| -> usize {
        pieces
            .iter()
            .map(|(t, _)| text_width(t, size) + gap(size))
            .sum()
    };
    let size = if line_width(font_size(canvas)) <= canvas.width {
        font_size(canvas)
    } else {
        1
    };
    let height = text_height(size) + 4;
    let y = if at_bottom {
        canvas.height.saturating_sub(height) as f64
    } else {
        0.0
    };
    let width = canvas.width;
    canvas.fill(0.0, y, width, height, OUTLINE);
    let mut x = 3.0;
    for (text, colour) in pieces {
        canvas.text(x, y + 2.0, text, size, *colour, None);
        x += (text_width(text, size) + gap(size)) as f64;
    }
}

/// The caption (top) and the legend (bottom) of a picture.
fn caption_and_legend(canvas: &mut Canvas, caption: &str, judged: bool) {
    band(canvas, false, &[(caption, CAPTION)]);
    let mut legend = vec![
        ("C CENTRE", DISC_CENTRE_COLOUR),
        ("R REFERENCE", REFERENCE_COLOUR),
        ("F PART", PART_FEATURE_COLOUR),
        ("E GRIPPER", EFFECTOR_COLOUR),
        ("UNLABELLED", UNLABELLED_COLOUR),
    ];
    if judged {
        legend.push(("WRONG!", WRONG_COLOUR));
    }
    band(canvas, true, &legend);
}

/// The verdicts of `frame`'s points (empty without a judge).
fn verdicts(frame: &FrameLabels, judge: Option<&Judge>) -> Vec<Option<Verdict>> {
    judge.map_or_else(Vec::new, |judge| {
        frame
            .points
            .iter()
            .map(|p| judge.verdict(frame.trigger_id, p))
            .collect()
    })
}

/// The first frame of the `length` frames with the most wrong labels, then
/// the most labels (the earliest of equals).
fn busiest_stretch(frames: &[FrameLabels], judge: Option<&Judge>, length: usize) -> usize {
    let weight: Vec<(usize, usize)> = frames
        .iter()
        .map(|f| {
            let wrong = verdicts(f, judge)
                .iter()
                .filter(|v| **v == Some(Verdict::Wrong))
                .count();
            (wrong, f.points.len())
        })
        .collect();
    let length = length.clamp(1, frames.len().max(1));
    (0..=frames.len().saturating_sub(length))
        .map(|start| {
            let sum = weight
                .iter()
                .skip(start)
                .take(length)
                .fold((0, 0), |a, w| (a.0 + w.0, a.1 + w.1));
            (start, sum)
        })
        // max_by_key keeps the last of equals: reverse to keep the first.
        .rev()
        .max_by_key(|(_, sum)| *sum)
        .map_or(0, |(start, _)| start)
}

/// Writes the pictures of `run` (the front end over `recording`), judged
/// against the truth by `judge` if given.
pub fn write_pictures(
    recording: &Recording,
    run: &FrontEndRun,
    judge: Option<&Judge>,
    options: &PictureOptions,
) -> Result<PicturesWritten> {
    let folder = &options.folder;
    std::fs::create_dir_all(folder)
        .with_context(|| format!("cannot create {}", folder.display()))?;
    let first = match options.first_frame {
        Some(k) if k >= run.frames.len() => anyhow::bail!(
            "--first-frame {k}: the front end read {} frames",
            run.frames.len()
        ),
        Some(k) => k,
        None => busiest_stretch(&run.frames, judge, options.frames),
    };
    let stretch: Vec<&FrameLabels> = run.frames.iter().skip(first).take(options.frames).collect();
    let (width, height) = (
        recording.header.camera.width as usize,
        recording.header.camera.height as usize,
    );
    let animation = folder.join(ANIMATION_FILE);
    let mut gif = GifWriter::create(
        &animation,
        width * options.scale.max(1),
        height * options.scale.max(1),
    )?;
    let mut written = PicturesWritten {
        first_frame: first,
        pngs: Vec::new(),
        animation: animation.clone(),
        wrong_labels: 0,
    };
    let row_of = |id: u64| recording.rows.iter().find(|r| r.trigger_id == id);
    for (k, frame) in stretch.iter().enumerate() {
        let row = row_of(frame.trigger_id)
            .with_context(|| format!("trigger {} is not in frames.csv", frame.trigger_id))?;
        let pixels = recording
            .image(row)
            .with_context(|| format!("frames.csv line {}", row.line))?;
        let mut canvas = Canvas::from_gray(width, height, &pixels, options.scale)?;
        let judged = verdicts(frame, judge);
        let wrong = judged
            .iter()
            .filter(|v| **v == Some(Verdict::Wrong))
            .count();
        written.wrong_labels += wrong;
        draw_labels(&mut canvas, frame, &judged);
        let mut caption = format!(
            "FRAME {} TRIGGER {} T {:.2} S THETA {:.3} LABELS {}",
            first + k,
            frame.trigger_id,
            row.capture_time_us as f64 * 1e-6,
            row.conveyor_angle_rad,
            frame.points.len()
        );
        if judge.is_some() {
            caption.push_str(&format!(" WRONG {wrong}"));
        }
        caption_and_legend(&mut canvas, &caption, judge.is_some());
        let name = format!("frame-{:04}-trigger-{}.png", first + k, frame.trigger_id);
        let path = folder.join(name);
        if options.indexed {
            canvas.write_png_indexed(&path)?;
        } else {
            canvas.write_png(&path)?;
        }
        written.pngs.push(path);
        // Shown until the next frame was captured (the last as long as the one before).
        let next = stretch
            .get(k + 1)
            .and_then(|f| row_of(f.trigger_id))
            .or_else(|| {
                k.checked_sub(1)
                    .and_then(|j| stretch.get(j))
                    .and_then(|f| row_of(f.trigger_id))
            });
        let interval_us = next.map_or(200_000, |other| {
            other.capture_time_us.abs_diff(row.capture_time_us)
        });
        gif.push(&canvas, delay_cs(interval_us))?;
    }
    gif.finish()?;
    Ok(written)
}

/// A GIF frame's delay for a capture interval: hundredths of a second, at
/// least 2 (what browsers honour), at most 5 s.
fn delay_cs(interval_us: u64) -> u16 {
    ((interval_us + 5_000) / 10_000).clamp(2, 500) as u16
}

/// The folder's PNGs and GIF as a short list for the terminal.
pub fn describe(written: &PicturesWritten, folder: &Path) -> String {
    format!(
        "{} pictures from frame {} and {} in {}{}",
        written.pngs.len(),
        written.first_frame,
        ANIMATION_FILE,
        folder.display(),
        if written.wrong_labels > 0 {
            format!(" ({} wrong labels boxed in red)", written.wrong_labels)
        } else {
            String::new()
        }
    )
}

#[cfg(test)]
mod tests;
