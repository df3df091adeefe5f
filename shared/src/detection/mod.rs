//! Mark detection: from an 8-bit grayscale camera image to sub-pixel mark
//! candidates, in fixed working memory, so that the same code runs on the
//! host and on a small smart-camera MCU.
//!
//! The paper's method (Sections 2 and 3) stands on image points: the disc's
//! reference mark, the part's feature points and the end effector's marks.
//! Bright round marks on a darker scene are found in four steps:
//! - [`background`]: the local background level and noise, tile by tile,
//!   so that a threshold of `level + max(min_contrast, noise_factor * noise)`
//!   copes with light that varies across the image and over time;
//! - [`components`]: eight-connected components in one pass over the rows,
//!   with exact integer sums, in memory bounded by the components open across
//!   one row;
//! - [`blob`]: the contrast-weighted centroid, the moment ellipse, and the
//!   refusal of what does not look like a mark;
//! - [`coverage`]: the centre again from every pixel around the mark,
//!   weighted by how much of it the mark covers, and how lopsided that
//!   coverage is (a mark that an edge in front cuts).
//!
//! Which candidate is which mark is decided elsewhere, from what the
//! controller knows; this module only says where round bright things are.
//! [`rim`] measures the disc's rim, the other thing a frame shows of the
//! disc, over the pixels of its dark band.
//!
//! Working memory of a [`Detector`]: [`Detector::WORKING_MEMORY_BYTES`],
//! 14,424 bytes on the Cortex-M4F for images up to 512 x 512 (held within
//! 16 KiB at compile time), and a row's spans and ramps (under 1 KiB) on
//! the stack; the image itself is borrowed, not copied.

pub mod background;
pub mod blob;
pub mod components;
pub mod coverage;
pub mod identify;
pub mod image;
pub mod rim;

use core::fmt;

use heapless::Vec;

use coverage::Coverage;

pub use background::{Background, RowRamps};
pub use blob::{Blob, MarkShape, Refusal};
pub use components::{ComponentError, ComponentSums, Labeller, MAX_OPEN_COMPONENTS, MAX_SPANS};
pub use image::{GrayImage, ImageError, MAX_HEIGHT_PX, MAX_WIDTH_PX};

// The working memory the docs state, held at compile time.
const _: () = assert!(Detector::WORKING_MEMORY_BYTES <= 16 * 1024);
// A row's segments (the head and one past each tile centre) all fit the
// labeller's spans.
const _: () = assert!(MAX_WIDTH_PX.div_ceil(background::TILE_PX) < MAX_SPANS);

/// Most mark candidates one image yields; more are counted and dropped.
pub const MAX_BLOBS: usize = 64;

/// The detector's settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DetectorSettings {
    /// Least contrast above the local background, grey levels.
    pub min_contrast: u8,
    /// The threshold's margin in background deviations.
    pub noise_factor: f32,
    /// What a mark may look like.
    pub shape: MarkShape,
    /// Contrast a pixel around a mark must exceed to weigh in its centre,
    /// grey levels: above the background's texture and noise, far below
    /// the threshold, so that the edge pixels a mark barely covers count.
    pub window_floor: u8,
}

impl Default for DetectorSettings {
    fn default() -> Self {
        Self {
            min_contrast: 24,
            noise_factor: 4.0,
            shape: MarkShape::default(),
            window_floor: 6,
        }
    }
}

/// What one detection found and refused.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct DetectionReport {
    /// Components above the threshold.
    pub components: u32,
    /// Accepted as mark candidates.
    pub accepted: u32,
    /// Refused: too small.
    pub too_small: u32,
    /// Refused: too large.
    pub too_large: u32,
    /// Refused: elongated.
    pub elongated: u32,
    /// Refused: not filling its ellipse.
    pub ragged: u32,
    /// Refused: touching the border.
    pub at_border: u32,
    /// Accepted but beyond [`MAX_BLOBS`]: dropped.
    pub overflow: u32,
}

/// Why an image gave no candidates at all.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DetectionError {
    /// The image itself is unusable.
    Image(ImageError),
    /// Too many components at once (hundreds of blobs in one band of rows):
    /// the frame is refused rather than half read.
    TooManyComponents {
        /// The row at which the component table ran out.
        row: u16,
    },
}

impl fmt::Display for DetectionError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Image(error) => write!(f, "{error}"),
            Self::TooManyComponents { row } => write!(
                f,
                "more than {MAX_OPEN_COMPONENTS} bright components open across row {row}: frame refused"
            ),
        }
    }
}

impl core::error::Error for DetectionError {}

impl From<ImageError> for DetectionError {
    fn from(error: ImageError) -> Self {
        Self::Image(error)
    }
}

/// The detector and its working memory. Large (see
/// [`Detector::WORKING_MEMORY_BYTES`]): keep one in a static or on the heap of
/// a host, not on a small task's stack.
#[derive(Debug, Clone)]
pub struct Detector {
    settings: DetectorSettings,
    level: [u8; MAX_WIDTH_PX],
    threshold: [u8; MAX_WIDTH_PX],
    weights: [u8; MAX_WIDTH_PX],
}

impl Detector {
    /// Bytes of working memory besides the image: the detector itself plus,
    /// during [`Detector::detect`], a [`Background`] and a [`Labeller`] on
    /// the stack.
    pub const WORKING_MEMORY_BYTES: usize = core::mem::size_of::<Self>()
        + core::mem::size_of::<Background>()
        + core::mem::size_of::<Labeller>();

    /// A detector with `settings`.
    pub fn new(settings: DetectorSettings) -> Self {
        Self {
            settings,
            level: [0; MAX_WIDTH_PX],
            threshold: [0; MAX_WIDTH_PX],
            weights: [0; MAX_WIDTH_PX],
        }
    }

    /// The settings in use.
    pub fn settings(&self) -> &DetectorSettings {
        &self.settings
    }

    /// The mark candidates of `image` into `out` (cleared first), and what
    /// was found and refused. A black, saturated or featureless image gives
    /// no candidates and no error.
    pub fn detect(
        &mut self,
        image: &GrayImage<'_>,
        out: &mut Vec<Blob, MAX_BLOBS>,
    ) -> Result<DetectionReport, DetectionError> {
        out.clear();
        let mut report = DetectionReport::default();
        let (width, height) = (image.width(), image.height());
        let background = Background::measure(image);
        let mut labeller = Labeller::new(width);
        let shape = self.settings.shape;
        let floor = f32::from(self.settings.window_floor);
        let mut take = |sums: &ComponentSums| {
            report.components += 1;
            match Blob::from_sums(sums, width, height, &shape) {
                Ok(mut blob) => {
                    if let Some(coverage) = window_coverage(image, &background, sums, floor) {
                        let [x, y] = coverage.centre();
                        blob.x_px = x;
                        blob.y_px = y;
                        blob.lopsidedness = coverage.lopsidedness();
                    }
                    if out.push(blob).is_ok() {
                        report.accepted += 1;
                    } else {
                        report.overflow += 1;
                    }
                }
                Err(Refusal::TooSmall) => report.too_small += 1,
                Err(Refusal::TooLarge) => report.too_large += 1,
                Err(Refusal::Elongated) => report.elongated += 1,
                Err(Refusal::Ragged) => report.ragged += 1,
                Err(Refusal::AtBorder) => report.at_border += 1,
            }
        };
        // At least one grey level: a weight of 0 means background.
        let min_contrast = f32::from(self.settings.min_contrast.max(1));
        let noise_factor = self.settings.noise_factor;
        let mut spans: Vec<(usize, usize), MAX_SPANS> = Vec::new();
        let mut ramps = RowRamps::default();
        for y in 0..height {
            background.fill_row_ramps(y, min_contrast, noise_factor, &mut ramps);
            let row = image.row(y);
            spans.clear();
            // Only the segments with a pixel above their least threshold are
            // weighed and labelled: most of a frame is background.
            for k in 0..ramps.segment_count() {
                let (x0, x1) = ramps.segment_columns(k, width);
                let Some(pixels) = row.get(x0..x1) else {
                    continue;
                };
                if !any_above(pixels, ramps.least_threshold(k)) {
                    continue;
                }
                let (Some(segment), Some(weights)) =
                    (ramps.segment(k, width), self.weights.get_mut(x0..x1))
                else {
                    continue;
                };
                let len = segment.len;
                segment
                    .level
                    .fill(self.level.get_mut(..len).unwrap_or(&mut []));
                segment
                    .threshold
                    .fill(self.threshold.get_mut(..len).unwrap_or(&mut []));
                let limits = self.level.iter().zip(self.threshold.iter());
                for (weight, (&pixel, (&level, &threshold))) in
                    weights.iter_mut().zip(pixels.iter().zip(limits))
                {
                    // Above the threshold is at least one grey level above the level.
                    *weight = if pixel > threshold {
                        pixel.saturating_sub(level).max(1)
                    } else {
                        0
                    };
                }
                // Touching segments go to the labeller as one span (cheaper
                // than its joining them); all fit (held above).
                match spans.last_mut() {
                    Some(last) if last.1 == x0 => last.1 = x1,
                    _ => {
                        let _ = spans.push((x0, x1));
                    }
                }
            }
            labeller
                .push_spans(self.weights.get(..width).unwrap_or(&[]), &spans, &mut take)
                .map_err(|ComponentError::TooManyOpen { row }| {
                    DetectionError::TooManyComponents { row }
                })?;
        }
        labeller.finish(&mut take);
        Ok(report)
    }
}

/// Some pixel of `pixels` is brighter than `ceiling`: four at a time in
/// a 32-bit word (no carry crosses a byte: each byte's low seven bits plus
/// at most 127), then the rest one by one.
fn any_above(pixels: &[u8], ceiling: u8) -> bool {
    const LOW: u32 = 0x7f7f_7f7f;
    const HIGH: u32 = 0x8080_8080;
    const ONES: u32 = 0x0101_0101;
    let words = pixels.chunks_exact(4);
    let rest = words.remainder();
    let found = if ceiling < 0x80 {
        // Above: the high bit set, or the low bits past the ceiling.
        let lift = ONES * u32::from(0x7f - ceiling);
        words.fold(0, |any, word| {
            let x = <[u8; 4]>::try_from(word).map_or(0, u32::from_le_bytes);
            any | (((x & LOW) + lift) | x)
        })
    } else {
        // Above: the high bit set and the low bits past the ceiling's.
        let lift = ONES * u32::from(0xff - ceiling);
        words.fold(0, |any, word| {
            let x = <[u8; 4]>::try_from(word).map_or(0, u32::from_le_bytes);
            any | (((x & LOW) + lift) & x)
        })
    };
    found & HIGH != 0 || rest.iter().any(|&p| p > ceiling)
}

/// The coverage of a mark ([`Coverage`]: its centre and how lopsided it
/// is) from every pixel of its bounding box grown by one, each weighted by
/// the share of it the mark covers. The component holds
/// only the pixels above the threshold; the edge pixels that the mark covers
/// by less than the threshold's share are missing from it, on whichever side
/// the mark's sub-pixel position puts more of them, which biases its
/// centroid by several hundredths of a pixel. Here they count.
///
/// A pixel's share is its contrast over the mark's, `(I - B) / (M - B)`,
/// with `M` the window's brightest pixel and `B` the background beside the
/// pixel ([`WindowSides::background_towards`]). The tiles' smooth level
/// would not do: a mark on a dark backing (the gripper's bar), beside a dark
/// band (the disc's rim) or near the edge of the part's body lies on a step,
/// and its edge pixels on the dark side would count too little, the bright
/// side's background too much, pulling the centre across the step by up to
/// a tenth of a pixel in every frame alike (measured by `host-sim
/// vision-check`: the reference 0.022 px towards the disc centre, the
/// gripper's marks 0.074 px apart, each). Contrast within `floor_grey` of
/// the background (texture, noise) counts nothing.
fn window_coverage(
    image: &GrayImage<'_>,
    background: &Background,
    sums: &ComponentSums,
    floor_grey: f32,
) -> Option<Coverage> {
    let (width, height) = (image.width(), image.height());
    let window = WindowSides::measure(
        image,
        background,
        usize::from(sums.x_min).saturating_sub(1),
        usize::from(sums.y_min).saturating_sub(1),
        (usize::from(sums.x_max) + 1).min(width.saturating_sub(1)),
        (usize::from(sums.y_max) + 1).min(height.saturating_sub(1)),
    );
    let (x0, y0, x1, y1) = (window.x0, window.y0, window.x1, window.y1);
    let pixel = |x: usize, y: usize| image.row(y).get(x).copied().map_or(0.0, f32::from);
    // The component's own centre aims the lines to the sides.
    let n = sums.area.max(1) as f32;
    let (cx, cy) = (sums.sx as f32 / n, sums.sy as f32 / n);
    let brightest = (y0..=y1)
        .filter_map(|y| image.row(y).get(x0..=x1)?.iter().copied().max())
        .max()
        .map_or(0.0, f32::from);
    // Moments about the component's centre keep the f32 sums exact enough.
    let mut coverage = Coverage::about([cx, cy]);
    for y in y0..=y1 {
        for x in x0..=x1 {
            let background = window.background_towards(image, cx, cy, x as f32, y as f32);
            let above = pixel(x, y) - background - floor_grey;
            if above <= 0.0 {
                continue;
            }
            let share = above / larger(brightest - background - floor_grey, 1.0);
            coverage.add(x as f32, y as f32, share);
        }
    }
    coverage.is_some().then_some(coverage)
}

/// Most pixels of a window's side that its background is read from (a
/// longer side is sampled evenly).
const SIDE_SAMPLES: usize = 16;

/// Grey levels by which a window's side must lie below the tiles' level
/// for the mark to count as on a dark backing.
const DARK_BACKING_GREY: f32 = 12.0;

/// A mark's window (its component's box grown by one, both ends included)
/// and the background on each of its four sides: the median of the side's
/// pixels, which passes over the few that the mark's light spills onto.
struct WindowSides {
    x0: usize,
    y0: usize,
    x1: usize,
    y1: usize,
    /// Top (`y0`), bottom (`y1`), left (`x0`), right (`x1`).
    level: [f32; 4],
    /// The tiles' level at the window's middle.
    tile_level: f32,
}

impl WindowSides {
    fn measure(
        image: &GrayImage<'_>,
        background: &Background,
        x0: usize,
        y0: usize,
        x1: usize,
        y1: usize,
    ) -> Self {
        let pixel = |x: usize, y: usize| image.row(y).get(x).copied().unwrap_or(0);
        let side = |count: usize, at: &dyn Fn(usize) -> u8| {
            let mut samples: Vec<u8, SIDE_SAMPLES> = Vec::new();
            let taken = count.min(SIDE_SAMPLES);
            for k in 0..taken {
                // Evenly over the side, both ends included.
                let i = if taken > 1 {
                    k * (count - 1) / (taken - 1)
                } else {
                    0
                };
                let _ = samples.push(at(i));
            }
            samples.sort_unstable();
            median(&samples)
        };
        let (w, h) = (x1 - x0 + 1, y1 - y0 + 1);
        Self {
            x0,
            y0,
            x1,
            y1,
            level: [
                side(w, &|i| pixel(x0 + i, y0)),
                side(w, &|i| pixel(x0 + i, y1)),
                side(h, &|i| pixel(x0, y0 + i)),
                side(h, &|i| pixel(x1, y0 + i)),
            ],
            tile_level: background.level_at((x0 + x1) / 2, (y0 + y1) / 2),
        }
    }

    /// The background beside `(x, y)`, read where the line from the mark's
    /// centre `(cx, cy)` through it leaves the window: the darker of that
    /// side pixel and the side's median (a band or a backing that only part
    /// of a side shows is followed; the mark's light spilt onto the pixel is
    /// passed over). On a dark backing the threshold stands high above the
    /// backing, the component keeps only the mark's brighter pixels, and the
    /// mark's faint rim lies on the window's sides: there the background is
    /// the darker of the side pixel and the pixel one beyond it. Where the
    /// two points coincide, the mean of the four medians.
    fn background_towards(&self, image: &GrayImage<'_>, cx: f32, cy: f32, x: f32, y: f32) -> f32 {
        let [top, bottom, left, right] = self.level;
        let (dx, dy) = (x - cx, y - cy);
        let reach = |d: f32, c: f32, low: usize, high: usize| {
            if d > 1e-3 {
                (high as f32 - c) / d
            } else if d < -1e-3 {
                (low as f32 - c) / d
            } else {
                f32::INFINITY
            }
        };
        let (tx, ty) = (
            reach(dx, cx, self.x0, self.x1),
            reach(dy, cy, self.y0, self.y1),
        );
        let t = lesser(tx, ty);
        if !t.is_finite() {
            return 0.25 * (top + bottom + left + right);
        }
        let on_side = |v: f32, low: usize, high: usize| {
            let r = libm::roundf(v);
            if r <= low as f32 {
                low
            } else if r >= high as f32 {
                high
            } else {
                r as usize
            }
        };
        let (sx, sy) = (
            on_side(cx + t * dx, self.x0, self.x1),
            on_side(cy + t * dy, self.y0, self.y1),
        );
        // The side left by, and the step one pixel beyond it.
        let (side, (bx, by)) = if tx < ty {
            if dx > 0.0 {
                (right, (sx.checked_add(1), Some(sy)))
            } else {
                (left, (sx.checked_sub(1), Some(sy)))
            }
        } else if dy > 0.0 {
            (bottom, (Some(sx), sy.checked_add(1)))
        } else {
            (top, (Some(sx), sy.checked_sub(1)))
        };
        let at = |x: usize, y: usize| image.row(y).get(x).copied().map(f32::from);
        let edge = at(sx, sy).unwrap_or(side);
        if side < self.tile_level - DARK_BACKING_GREY {
            let beyond = match (bx, by) {
                (Some(x), Some(y)) if y < image.height() => at(x, y),
                _ => None,
            };
            beyond.map_or(edge, |b| lesser(b, edge))
        } else {
            lesser(side, edge)
        }
    }
}

/// The lesser of two numbers, neither NaN, as `f32::min` gives it (which
/// is a library call on the Cortex-M4F).
fn lesser(a: f32, b: f32) -> f32 {
    if b < a {
        b
    } else {
        a
    }
}

/// The larger of two numbers, neither NaN, as `f32::max` gives it.
fn larger(a: f32, b: f32) -> f32 {
    if b > a {
        b
    } else {
        a
    }
}

/// The median of sorted values (the mean of the middle two for an even count).
fn median(sorted: &[u8]) -> f32 {
    let n = sorted.len();
    let at = |i: usize| sorted.get(i).copied().map_or(0.0, f32::from);
    if n % 2 == 1 {
        at(n / 2)
    } else if n > 0 {
        0.5 * (at(n / 2 - 1) + at(n / 2))
    } else {
        0.0
    }
}

#[cfg(test)]
mod tests;
