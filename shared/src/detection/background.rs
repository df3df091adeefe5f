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

    /// Level and noise at every pixel of row `y`, interpolated between tile
    /// centres (clamped to the outer centres at the image's edges): first
    /// down the tile columns for this row, then along the row.
    pub fn row(&self, y: usize, width: usize, level: &mut [f32], noise: &mut [f32]) {
        let (ty0, ty1, fy) = span(y, self.tiles_y);
        let mut column_level = [0.0f32; MAX_TILES_X];
        let mut column_noise = [0.0f32; MAX_TILES_X];
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
            if let (Some(l), Some(n)) = (column_level.get_mut(tx), column_noise.get_mut(tx)) {
                *l = lerp(&self.level);
                *n = lerp(&self.noise);
            }
        }
        fill_row(&column_level, self.tiles_x, width, level);
        fill_row(&column_noise, self.tiles_x, width, noise);
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
/// (pixel `TILE_PX / 2 - 0.5` of each tile), constant beyond the outer ones:
/// one addition a pixel.
fn fill_row(centres: &[f32; MAX_TILES_X], tiles: usize, width: usize, out: &mut [f32]) {
    let half = TILE_PX as f32 / 2.0 - 0.5;
    let first = centres.first().copied().unwrap_or(0.0);
    let last = centres
        .get(tiles.saturating_sub(1))
        .copied()
        .unwrap_or(first);
    for (x, value) in out.iter_mut().enumerate().take(width) {
        // Before the first centre and after the last: constant.
        if (x as f32) <= half {
            *value = first;
        } else {
            *value = last;
        }
    }
    for tile in 0..tiles.saturating_sub(1) {
        let a = centres.get(tile).copied().unwrap_or(0.0);
        let b = centres.get(tile + 1).copied().unwrap_or(a);
        let step = (b - a) / TILE_PX as f32;
        // Pixels strictly after centre `tile`, up to and including centre `tile + 1`.
        let start = tile * TILE_PX + TILE_PX / 2;
        let mut value = a + step * (start as f32 - (tile * TILE_PX) as f32 - half);
        for cell in out.iter_mut().take(width).skip(start).take(TILE_PX) {
            *cell = value;
            value += step;
        }
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

/// Background level and noise of one tile: the mean and deviation of the
/// pixels not brighter than the tile's mean plus one deviation.
fn tile_statistics(image: &GrayImage<'_>, tx: usize, ty: usize) -> (u8, u8) {
    let x0 = tx * TILE_PX;
    let x1 = (x0 + TILE_PX).min(image.width());
    let y0 = ty * TILE_PX;
    let y1 = (y0 + TILE_PX).min(image.height());
    let mut all = Moments::default();
    for y in y0..y1 {
        for &p in image.row(y).get(x0..x1).unwrap_or(&[]) {
            all.add(u32::from(p));
        }
    }
    let (mean, deviation) = all.mean_and_deviation();
    let ceiling = mean + deviation;
    let mut below = Moments::default();
    for y in y0..y1 {
        for &p in image.row(y).get(x0..x1).unwrap_or(&[]) {
            if f32::from(p) <= ceiling {
                below.add(u32::from(p));
            }
        }
    }
    let (level, noise) = below.mean_and_deviation();
    (
        libm::roundf(level).clamp(0.0, 255.0) as u8,
        libm::roundf(noise).clamp(0.0, 255.0) as u8,
    )
}

/// Count, sum and sum of squares of small integers, exact.
#[derive(Debug, Default)]
struct Moments {
    count: u32,
    sum: u64,
    squares: u64,
}

impl Moments {
    fn add(&mut self, value: u32) {
        self.count += 1;
        self.sum += u64::from(value);
        self.squares += u64::from(value * value);
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
        let mut level = [0.0f32; 64];
        let mut noise = [0.0f32; 64];
        background.row(32, 64, &mut level, &mut noise);
        // Inside the outer tile centres the interpolation follows the ramp to
        // within a grey level, even across the mark.
        for x in 8..56 {
            assert!(
                (level[x] - (40.0 + x as f32)).abs() < 1.5,
                "x {x}: {}",
                level[x]
            );
            assert!(noise[x] < 6.0, "x {x}: noise {}", noise[x]);
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
