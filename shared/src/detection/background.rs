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

    /// Background level (rounded) and threshold (floored: a pixel is
    /// foreground when brighter than it) at every pixel of row `y`, for the
    /// threshold `level + max(min_contrast, noise_factor * noise)`: both
    /// taken at the tile centres, interpolated down the tile columns for this
    /// row, then along the row in fixed point (one addition a pixel).
    pub fn thresholds(
        &self,
        y: usize,
        width: usize,
        min_contrast: f32,
        noise_factor: f32,
        level: &mut [u8],
        threshold: &mut [u8],
    ) {
        let (ty0, ty1, fy) = span(y, self.tiles_y);
        let mut column_level = [0.0f32; MAX_TILES_X];
        let mut column_threshold = [0.0f32; MAX_TILES_X];
        for tx in 0..self.tiles_x {
            let at = |values: &[u8; MAX_TILES], ty: usize| {
                values
                    .get(ty * self.tiles_x + tx)
                    .copied()
                    .map_or(0.0, f32::from)
            };
            let lerp = |values: &[u8; MAX_TILES]| {
                at(values, ty0) + fy * (at(values, ty1) - at(values, ty0))
            };
            let (l, n) = (lerp(&self.level), lerp(&self.noise));
            let scaled = noise_factor * n;
            let margin = if scaled > min_contrast {
                scaled
            } else {
                min_contrast
            };
            if let (Some(cl), Some(ct)) = (column_level.get_mut(tx), column_threshold.get_mut(tx)) {
                // Rounded level, floored threshold, both as a 24.8 fixed point.
                *cl = l + 0.5;
                *ct = l + margin;
            }
        }
        fill_row(&column_level, self.tiles_x, width, level);
        fill_row(&column_threshold, self.tiles_x, width, threshold);
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

/// Linear interpolation along a row between the values at the tile centres
/// (pixel `TILE_PX / 2 - 0.5` of each tile), constant beyond the outer ones,
/// in 24.8 fixed point: one addition a pixel, then the integer part,
/// clamped to 0..=255.
fn fill_row(centres: &[f32; MAX_TILES_X], tiles: usize, width: usize, out: &mut [u8]) {
    const ONE: f32 = 256.0;
    let to_grey = |fixed: i32| (fixed >> 8).clamp(0, 255) as u8;
    let fixed = |value: f32| (value * ONE) as i32;
    let first = centres.first().copied().map_or(0, fixed);
    let last = centres
        .get(tiles.saturating_sub(1))
        .copied()
        .map_or(first, fixed);
    let out = out.get_mut(..width).unwrap_or(&mut []);
    // Up to the first centre (pixel TILE_PX / 2 - 1 is the last before it).
    let (head, rest) = out.split_at_mut((TILE_PX / 2).min(width));
    head.fill(to_grey(first));
    let mut cells = rest.iter_mut();
    for pair in centres.get(..tiles).unwrap_or(&[]).windows(2) {
        let (a, b) = match pair {
            [a, b] => (fixed(*a), fixed(*b)),
            _ => continue,
        };
        // Pixels after centre `a` up to centre `b`: the first is half a
        // pixel past `a`.
        let step = (b - a) / TILE_PX as i32;
        let mut value = a + step / 2;
        for cell in cells.by_ref().take(TILE_PX) {
            *cell = to_grey(value);
            value += step;
        }
    }
    for cell in cells {
        *cell = to_grey(last);
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
    let moments_below = |ceiling: f32| {
        let ceiling = if ceiling >= 255.0 { 255 } else { ceiling as u8 };
        let mut moments = Moments::default();
        for (k, y) in (y0..y1).step_by(2).enumerate() {
            let start = (x0 + k % 2).min(x1);
            for &p in image.row(y).get(start..x1).unwrap_or(&[]).iter().step_by(2) {
                if p <= ceiling {
                    moments.add(u32::from(p));
                }
            }
        }
        moments.mean_and_deviation()
    };
    let (mean, deviation) = moments_below(255.0);
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
    fn span_brackets_tile_centres() {
        assert_eq!(span(0, 4), (0, 0, 0.0));
        assert_eq!(span(7, 4), (0, 0, 0.0));
        let (a, b, f) = span(16, 4);
        assert_eq!((a, b), (0, 1));
        assert!((f - 0.53125).abs() < 1e-6);
        assert_eq!(span(63, 4), (3, 3, 0.0));
    }
}
