//! The local background: what the image would show without the marks, and how
//! much it varies, so that one threshold copes with light that changes across
//! the image (a lamp to one side, the arm's shadow) and over time.
//!
//! The image is cut into `TILE_PX`-square tiles. In each, the pixels not
//! brighter than the tile's mean plus one deviation are taken as background (a
//! mark covers a small part of a tile, and is bright), and their mean and
//! deviation are the tile's level and noise. Between tile centres both are
//! interpolated bilinearly, so the threshold has no steps at tile borders.

use super::image::{GrayImage, MAX_HEIGHT_PX, MAX_WIDTH_PX};

/// Side of a background tile, pixels.
pub const TILE_PX: usize = 16;
const MAX_TILES_X: usize = MAX_WIDTH_PX.div_ceil(TILE_PX);
const MAX_TILES_Y: usize = MAX_HEIGHT_PX.div_ceil(TILE_PX);
const MAX_TILES: usize = MAX_TILES_X * MAX_TILES_Y;

/// Level and noise of every tile (2 bytes a tile: 2 KiB for the largest image).
#[derive(Debug, Clone)]
pub struct Background {
    tiles_x: usize,
    tiles_y: usize,
    level: [u8; MAX_TILES],
    noise: [u8; MAX_TILES],
}

impl Background {
    /// Measures every tile of `image`.
    pub fn measure(image: &GrayImage<'_>) -> Self {
        let tiles_x = image.width().div_ceil(TILE_PX);
        let tiles_y = image.height().div_ceil(TILE_PX);
        let mut background = Self {
            tiles_x,
            tiles_y,
            level: [0; MAX_TILES],
            noise: [0; MAX_TILES],
        };
        for ty in 0..tiles_y {
            for tx in 0..tiles_x {
                let (level, noise) = tile_statistics(image, tx, ty);
                if let (Some(l), Some(n)) = (
                    background.level.get_mut(ty * tiles_x + tx),
                    background.noise.get_mut(ty * tiles_x + tx),
                ) {
                    *l = level;
                    *n = noise;
                }
            }
        }
        background
    }

    /// The level (rounded) and the threshold (floored) along row `y`, for
    /// the threshold `level + max(min_contrast, noise_factor * noise)`:
    /// both taken at the tile centres and interpolated down the tile
    /// columns for this row; along the row they step linearly in fixed
    /// point between the centres ([`RowRamps::segments`]).
    pub fn row_ramps(&self, y: usize, min_contrast: f32, noise_factor: f32) -> RowRamps {
        let mut ramps = RowRamps::default();
        self.fill_row_ramps(y, min_contrast, noise_factor, &mut ramps);
        ramps
    }

    /// [`Background::row_ramps`] into `ramps` (a row at a time without a
    /// copy).
    pub fn fill_row_ramps(
        &self,
        y: usize,
        min_contrast: f32,
        noise_factor: f32,
        ramps: &mut RowRamps,
    ) {
        let (ty0, ty1, fy) = span(y, self.tiles_y);
        ramps.tiles = self.tiles_x;
        let fixed = |value: f32| (value * 256.0) as i32;
        let tiles = self.tiles_x;
        fn tile_row(values: &[u8; MAX_TILES], ty: usize, tiles: usize) -> &[u8] {
            values.get(ty * tiles..(ty + 1) * tiles).unwrap_or(&[])
        }
        let levels =
            tile_row(&self.level, ty0, tiles)
                .iter()
                .zip(tile_row(&self.level, ty1, tiles));
        let noises =
            tile_row(&self.noise, ty0, tiles)
                .iter()
                .zip(tile_row(&self.noise, ty1, tiles));
        let centres = ramps.level.iter_mut().zip(ramps.threshold.iter_mut());
        for ((cl, ct), ((&l0, &l1), (&n0, &n1))) in centres.zip(levels.zip(noises)) {
            let lerp = |v0: u8, v1: u8| f32::from(v0) + fy * (f32::from(v1) - f32::from(v0));
            let (l, n) = (lerp(l0, l1), lerp(n0, n1));
            let scaled = noise_factor * n;
            let margin = if scaled > min_contrast {
                scaled
            } else {
                min_contrast
            };
            // Rounded level, floored threshold, both as a 24.8 fixed point.
            *cl = fixed(l + 0.5);
            *ct = fixed(l + margin);
        }
    }

    /// The background level (rounded) and the threshold (floored) at every
    /// pixel of row `y` (see [`Background::row_ramps`]).
    pub fn thresholds(
        &self,
        y: usize,
        width: usize,
        min_contrast: f32,
        noise_factor: f32,
        level: &mut [u8],
        threshold: &mut [u8],
    ) {
        let ramps = self.row_ramps(y, min_contrast, noise_factor);
        for segment in ramps.segments(width) {
            let range = segment.x0..segment.x0 + segment.len;
            segment
                .level
                .fill(level.get_mut(range.clone()).unwrap_or(&mut []));
            segment
                .threshold
                .fill(threshold.get_mut(range).unwrap_or(&mut []));
        }
    }

    /// Level at one pixel, interpolated as in [`Background::row`].
    pub fn level_at(&self, x: usize, y: usize) -> f32 {
        let (ty0, ty1, fy) = span(y, self.tiles_y);
        let (tx0, tx1, fx) = span(x, self.tiles_x);
        self.bilinear(&self.level, tx0, tx1, ty0, ty1, fx, fy)
    }

    #[allow(clippy::too_many_arguments)]
    fn bilinear(
        &self,
        values: &[u8; MAX_TILES],
        tx0: usize,
        tx1: usize,
        ty0: usize,
        ty1: usize,
        fx: f32,
        fy: f32,
    ) -> f32 {
        let at = |tx: usize, ty: usize| {
            values
                .get(ty * self.tiles_x + tx)
                .copied()
                .map_or(0.0, f32::from)
        };
        let top = at(tx0, ty0) + fx * (at(tx1, ty0) - at(tx0, ty0));
        let bottom = at(tx0, ty1) + fx * (at(tx1, ty1) - at(tx0, ty1));
        top + fy * (bottom - top)
    }
}

/// A row's level and threshold at the tile centres (pixel `TILE_PX / 2 -
/// 0.5` of each tile), from [`Background::row_ramps`].
#[derive(Debug, Clone, Default)]
pub struct RowRamps {
    tiles: usize,
    /// The level at each centre, rounded (+0.5), 24.8 fixed point.
    level: [i32; MAX_TILES_X],
    /// The threshold at each centre, 24.8 fixed point.
    threshold: [i32; MAX_TILES_X],
}

/// One stretch of a row: `len` pixels from `x0`, over which the level and
/// the threshold each step linearly.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Segment {
    /// First pixel.
    pub x0: usize,
    /// Pixels.
    pub len: usize,
    /// The background level, rounded.
    pub level: Ramp,
    /// The threshold, floored.
    pub threshold: Ramp,
}

/// Grey levels stepping linearly in 24.8 fixed point: the first pixel's
/// `start`, then `step` more each pixel; the integer part, clamped to
/// 0..=255. One addition a pixel.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Ramp {
    start: i32,
    step: i32,
}

impl Ramp {
    fn grey(fixed: i32) -> u8 {
        (fixed >> 8).clamp(0, 255) as u8
    }

    /// The `len` values into `out` (as many as it holds).
    pub fn fill(&self, out: &mut [u8]) {
        let mut value = self.start;
        for cell in out.iter_mut() {
            *cell = Self::grey(value);
            value = value.saturating_add(self.step);
        }
    }
}

impl RowRamps {
    /// The row's segments over `width` pixels, left to right (see
    /// [`RowRamps::segment`]).
    pub fn segments(&self, width: usize) -> impl Iterator<Item = Segment> + '_ {
        (0..self.segment_count()).filter_map(move |k| self.segment(k, width))
    }

    /// Segments in a row (some may be empty).
    pub fn segment_count(&self) -> usize {
        self.tiles + 1
    }

    /// The columns `x0..x1` of segment `k` in a row of `width` pixels
    /// (as [`RowRamps::segment`], without its ramps).
    pub fn segment_columns(&self, k: usize, width: usize) -> (usize, usize) {
        let head = TILE_PX / 2;
        let pairs = self.tiles.saturating_sub(1);
        let (x0, x1) = match k {
            0 => (0, head),
            k if k <= pairs => (head + (k - 1) * TILE_PX, head + k * TILE_PX),
            _ => (head + pairs * TILE_PX, width),
        };
        (x0.min(width), x1.min(width))
    }

    /// A threshold no pixel of segment `k` has a lower one than: the lower
    /// of its two centres' (the ramp between them stays between them).
    pub fn least_threshold(&self, k: usize) -> u8 {
        let at = |t: usize| self.threshold.get(t).copied().unwrap_or(0);
        let last = self.tiles.saturating_sub(1);
        let fixed = match k {
            0 => at(0),
            k if k <= last => at(k - 1).min(at(k)),
            _ => at(last),
        };
        Ramp::grey(fixed)
    }

    /// Segment `k` of a row of `width` pixels (`None` past the row's end
    /// or when empty): up to the first tile centre (`k` = 0) and beyond the
    /// last one (`k` = tiles) the value is the outer centre's; in between
    /// it steps from centre `k - 1` to centre `k` (`TILE_PX` pixels, the
    /// first half a pixel past the first centre).
    pub fn segment(&self, k: usize, width: usize) -> Option<Segment> {
        if k >= self.segment_count() {
            return None;
        }
        let (x0, x1) = self.segment_columns(k, width);
        let last = self.tiles.saturating_sub(1);
        let ramp = |values: &[i32; MAX_TILES_X]| {
            let at = |t: usize| values.get(t).copied().unwrap_or(0);
            match k {
                0 => Ramp {
                    start: at(0),
                    step: 0,
                },
                k if k <= last => {
                    let (a, b) = (at(k - 1), at(k));
                    let step = (b - a) / TILE_PX as i32;
                    Ramp {
                        start: a + step / 2,
                        step,
                    }
                }
                _ => Ramp {
                    start: at(last),
                    step: 0,
                },
            }
        };
        (x1 > x0).then(|| Segment {
            x0,
            len: x1 - x0,
            level: ramp(&self.level),
            threshold: ramp(&self.threshold),
        })
    }
}

/// The two tiles whose centres bracket `coordinate`, and the fraction of the
/// way from the first to the second.
fn span(coordinate: usize, tiles: usize) -> (usize, usize, f32) {
    let last = tiles.saturating_sub(1);
    let position = (coordinate as f32 + 0.5) / TILE_PX as f32 - 0.5;
    if position <= 0.0 {
        return (0, 0, 0.0);
    }
    let first = position as usize;
    if first >= last {
        return (last, last, 0.0);
    }
    (first, first + 1, position - first as f32)
}

/// Background level and noise of one tile, from a quarter of its pixels
/// (every other row, every other pixel, staggered from row to row so that
/// no column pattern aliases): the mean and deviation of those not
/// brighter than the tile's mean plus one deviation, then of those within
/// three of that subset's deviations of its mean. The first cut drops the
/// marks; the second takes back the brighter half of a lighting ramp or a
/// texture that the first dropped with them.
fn tile_statistics(image: &GrayImage<'_>, tx: usize, ty: usize) -> (u8, u8) {
    let x0 = tx * TILE_PX;
    let x1 = (x0 + TILE_PX).min(image.width());
    let y0 = ty * TILE_PX;
    let y1 = (y0 + TILE_PX).min(image.height());
    // The sample, gathered once (a quarter of a tile: 64 pixels), with
    // the moments of all of it.
    let mut sample = [0u8; TILE_PX * TILE_PX / 4];
    let mut taken = 0;
    let mut all = Moments::default();
    for (k, y) in (y0..y1).step_by(2).enumerate() {
        // Even rows from the tile's first pixel, odd rows from its second:
        // bytes 0 and 2, or 1 and 3, of each word.
        let odd = k % 2;
        let row = image.row(y).get(x0..x1).unwrap_or(&[]);
        let words = row.chunks_exact(4);
        let rest = words.remainder();
        let shift = 8 * odd as u32;
        let mut keep = |p: u8| {
            if let Some(cell) = sample.get_mut(taken) {
                *cell = p;
                all.add(u32::from(p));
                taken += 1;
            }
        };
        for word in words {
            let bytes = <[u8; 4]>::try_from(word).map_or(0, u32::from_le_bytes) >> shift;
            keep(bytes as u8);
            keep((bytes >> 16) as u8);
        }
        for &p in rest.iter().skip(odd).step_by(2) {
            keep(p);
        }
    }
    let sample = sample.get(..taken).unwrap_or(&[]);
    let moments_below = |ceiling: f32| {
        let ceiling = if ceiling >= 255.0 { 255 } else { ceiling as u8 };
        let mut moments = Moments::default();
        for &p in sample {
            if p <= ceiling {
                moments.add(u32::from(p));
            }
        }
        moments.mean_and_deviation()
    };
    let (mean, deviation) = all.mean_and_deviation();
    let (mean, deviation) = moments_below(mean + deviation);
    let (level, noise) = moments_below(mean + 3.0 * deviation + 1.0);
    (
        libm::roundf(level).clamp(0.0, 255.0) as u8,
        libm::roundf(noise).clamp(0.0, 255.0) as u8,
    )
}

/// Count, sum and sum of squares of grey levels, exact (a tile's 256
/// squares of 255 fit a `u32` 64 times over).
#[derive(Debug, Default)]
struct Moments {
    count: u32,
    sum: u32,
    squares: u32,
}

impl Moments {
    fn add(&mut self, value: u32) {
        self.count += 1;
        self.sum += value;
        self.squares += value * value;
    }

    fn mean_and_deviation(&self) -> (f32, f32) {
        if self.count == 0 {
            return (0.0, 0.0);
        }
        let n = self.count as f32;
        let mean = self.sum as f32 / n;
        let variance = (self.squares as f32 / n - mean * mean).max(0.0);
        (mean, libm::sqrtf(variance))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_lighting_ramp_is_followed_and_a_bright_mark_ignored() {
        // 64 x 64, light rising left to right from 40 to 103, one 5 x 5 mark at 250.
        let mut pixels = [0u8; 64 * 64];
        for y in 0..64 {
            for x in 0..64 {
                pixels[y * 64 + x] = if (30..35).contains(&x) && (30..35).contains(&y) {
                    250
                } else {
                    40 + x as u8
                };
            }
        }
        let image = GrayImage::packed(64, 64, &pixels).unwrap();
        let background = Background::measure(&image);
        let mut level = [0u8; 64];
        let mut threshold = [0u8; 64];
        background.thresholds(32, 64, 24.0, 4.0, &mut level, &mut threshold);
        // Inside the outer tile centres the interpolation follows the ramp to
        // within two grey levels, even across the mark, and the threshold
        // sits the least contrast above it (the ramp's noise is small).
        for x in 8..56 {
            let expected = 40.0 + x as f32;
            assert!(
                (f32::from(level[x]) - expected).abs() < 2.0,
                "x {x}: {}",
                level[x]
            );
            let margin = f32::from(threshold[x]) - expected;
            assert!((23.0..30.0).contains(&margin), "x {x}: {}", threshold[x]);
        }
    }

    #[test]
    fn rows_agree_with_the_pointwise_interpolation() {
        // 100 x 70: partial tiles at both edges.
        let mut state = 5u64;
        let pixels: std::vec::Vec<u8> = (0..100 * 70)
            .map(|_| (crate::test_rng::splitmix(&mut state) * 255.0) as u8)
            .collect();
        let image = GrayImage::packed(100, 70, &pixels).unwrap();
        let background = Background::measure(&image);
        let mut level = [0u8; 100];
        let mut threshold = [0u8; 100];
        for y in 0..70 {
            background.thresholds(y, 100, 24.0, 4.0, &mut level, &mut threshold);
            for (x, &grey) in level.iter().enumerate() {
                // Rounded in fixed point: within a grey level.
                let exact = background.level_at(x, y);
                assert!(
                    (f32::from(grey) - exact).abs() <= 1.0,
                    "({x}, {y}): {grey} vs {exact}"
                );
            }
        }
    }

    #[test]
    fn no_pixel_of_a_segment_has_a_threshold_below_its_least() {
        let mut state = 9u64;
        for trial in 0..300 {
            let width: usize = 1 + trial % 140;
            let tiles = width.div_ceil(TILE_PX);
            let mut ramps = RowRamps {
                tiles,
                level: [0; MAX_TILES_X],
                threshold: [0; MAX_TILES_X],
            };
            for t in ramps.threshold.iter_mut().take(tiles) {
                *t = (crate::test_rng::splitmix(&mut state) * 300.0 * 256.0) as i32 - 20 * 256;
            }
            let mut threshold = [0u8; 140];
            let mut covered = 0;
            for k in 0..ramps.segment_count() {
                let (x0, x1) = ramps.segment_columns(k, width);
                if let Some(segment) = ramps.segment(k, width) {
                    assert_eq!((segment.x0, segment.x0 + segment.len), (x0, x1));
                    segment.threshold.fill(&mut threshold[x0..x1]);
                    let least = ramps.least_threshold(k);
                    assert!(
                        threshold[x0..x1].iter().all(|&t| t >= least),
                        "width {width} segment {k}: {:?} under {least}",
                        &threshold[x0..x1]
                    );
                } else {
                    assert_eq!(x0, x1, "width {width} segment {k}");
                }
                assert_eq!(x0, covered, "width {width}: segments in order");
                covered = x1;
            }
            assert_eq!(covered, width);
        }
    }

    #[test]
    fn span_brackets_tile_centres() {
        assert_eq!(span(0, 4), (0, 0, 0.0));
        assert_eq!(span(7, 4), (0, 0, 0.0));
        let (a, b, f) = span(16, 4);
        assert_eq!((a, b), (0, 1));
        assert!((f - 0.53125).abs() < 1e-6);
        assert_eq!(span(63, 4), (3, 3, 0.0));
    }
}
