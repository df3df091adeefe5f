//! A 5 x 7 bitmap font (upper-case letters, digits and a little
//! punctuation; lower case is drawn upper case, anything else as `?`),
//! drawn `size` canvas pixels a font pixel with an optional one-pixel
//! outline so it stays legible on bright and dark ground alike. Enough for
//! the labels and captions of a picture without a font file or a
//! rasteriser.

use super::{Canvas, Rgb};

/// Font pixels of a glyph, across and down.
pub const GLYPH_WIDTH: usize = 5;
pub const GLYPH_HEIGHT: usize = 7;
/// Font pixels from one glyph to the next.
pub const ADVANCE: usize = GLYPH_WIDTH + 1;

/// The rows of `c`, top to bottom; bit 4 is the leftmost pixel.
pub fn glyph(c: char) -> [u8; GLYPH_HEIGHT] {
    match c.to_ascii_uppercase() {
        ' ' => [0; 7],
        '0' => [
            0b01110, 0b10001, 0b10011, 0b10101, 0b11001, 0b10001, 0b01110,
        ],
        '1' => [
            0b00100, 0b01100, 0b00100, 0b00100, 0b00100, 0b00100, 0b01110,
        ],
        '2' => [
            0b01110, 0b10001, 0b00001, 0b00010, 0b00100, 0b01000, 0b11111,
        ],
        '3' => [
            0b11111, 0b00010, 0b00100, 0b00010, 0b00001, 0b10001, 0b01110,
        ],
        '4' => [
            0b00010, 0b00110, 0b01010, 0b10010, 0b11111, 0b00010, 0b00010,
        ],
        '5' => [
            0b11111, 0b10000, 0b11110, 0b00001, 0b00001, 0b10001, 0b01110,
        ],
        '6' => [
            0b00110, 0b01000, 0b10000, 0b11110, 0b10001, 0b10001, 0b01110,
        ],
        '7' => [
            0b11111, 0b00001, 0b00010, 0b00100, 0b01000, 0b01000, 0b01000,
        ],
        '8' => [
            0b01110, 0b10001, 0b10001, 0b01110, 0b10001, 0b10001, 0b01110,
        ],
        '9' => [
            0b01110, 0b10001, 0b10001, 0b01111, 0b00001, 0b00010, 0b01100,
        ],
        'A' => [
            0b01110, 0b10001, 0b10001, 0b11111, 0b10001, 0b10001, 0b10001,
        ],
        'B' => [
            0b11110, 0b10001, 0b10001, 0b11110, 0b10001, 0b10001, 0b11110,
        ],
        'C' => [
            0b01110, 0b10001, 0b10000, 0b10000, 0b10000, 0b10001, 0b01110,
        ],
        'D' => [
            0b11100, 0b10010, 0b10001, 0b10001, 0b10001, 0b10010, 0b11100,
        ],
        'E' => [
            0b11111, 0b10000, 0b10000, 0b11110, 0b10000, 0b10000, 0b11111,
        ],
        'F' => [
            0b11111, 0b10000, 0b10000, 0b11110, 0b10000, 0b10000, 0b10000,
        ],
        'G' => [
            0b01110, 0b10001, 0b10000, 0b10111, 0b10001, 0b10001, 0b01111,
        ],
        'H' => [
            0b10001, 0b10001, 0b10001, 0b11111, 0b10001, 0b10001, 0b10001,
        ],
        'I' => [
            0b01110, 0b00100, 0b00100, 0b00100, 0b00100, 0b00100, 0b01110,
        ],
        'J' => [
            0b00111, 0b00010, 0b00010, 0b00010, 0b00010, 0b10010, 0b01100,
        ],
        'K' => [
            0b10001, 0b10010, 0b10100, 0b11000, 0b10100, 0b10010, 0b10001,
        ],
        'L' => [
            0b10000, 0b10000, 0b10000, 0b10000, 0b10000, 0b10000, 0b11111,
        ],
        'M' => [
            0b10001, 0b11011, 0b10101, 0b10101, 0b10001, 0b10001, 0b10001,
        ],
        'N' => [
            0b10001, 0b10001, 0b11001, 0b10101, 0b10011, 0b10001, 0b10001,
        ],
        'O' => [
            0b01110, 0b10001, 0b10001, 0b10001, 0b10001, 0b10001, 0b01110,
        ],
        'P' => [
            0b11110, 0b10001, 0b10001, 0b11110, 0b10000, 0b10000, 0b10000,
        ],
        'Q' => [
            0b01110, 0b10001, 0b10001, 0b10001, 0b10101, 0b10010, 0b01101,
        ],
        'R' => [
            0b11110, 0b10001, 0b10001, 0b11110, 0b10100, 0b10010, 0b10001,
        ],
        'S' => [
            0b01111, 0b10000, 0b10000, 0b01110, 0b00001, 0b00001, 0b11110,
        ],
        'T' => [
            0b11111, 0b00100, 0b00100, 0b00100, 0b00100, 0b00100, 0b00100,
        ],
        'U' => [
            0b10001, 0b10001, 0b10001, 0b10001, 0b10001, 0b10001, 0b01110,
        ],
        'V' => [
            0b10001, 0b10001, 0b10001, 0b10001, 0b10001, 0b01010, 0b00100,
        ],
        'W' => [
            0b10001, 0b10001, 0b10001, 0b10101, 0b10101, 0b10101, 0b01010,
        ],
        'X' => [
            0b10001, 0b10001, 0b01010, 0b00100, 0b01010, 0b10001, 0b10001,
        ],
        'Y' => [
            0b10001, 0b10001, 0b10001, 0b01010, 0b00100, 0b00100, 0b00100,
        ],
        'Z' => [
            0b11111, 0b00001, 0b00010, 0b00100, 0b01000, 0b10000, 0b11111,
        ],
        '.' => [
            0b00000, 0b00000, 0b00000, 0b00000, 0b00000, 0b01100, 0b01100,
        ],
        ',' => [
            0b00000, 0b00000, 0b00000, 0b00000, 0b01100, 0b00100, 0b01000,
        ],
        '-' => [
            0b00000, 0b00000, 0b00000, 0b11111, 0b00000, 0b00000, 0b00000,
        ],
        ':' => [
            0b00000, 0b01100, 0b01100, 0b00000, 0b01100, 0b01100, 0b00000,
        ],
        '!' => [
            0b00100, 0b00100, 0b00100, 0b00100, 0b00100, 0b00000, 0b00100,
        ],
        '/' => [
            0b00000, 0b00001, 0b00010, 0b00100, 0b01000, 0b10000, 0b00000,
        ],
        '=' => [
            0b00000, 0b00000, 0b11111, 0b00000, 0b11111, 0b00000, 0b00000,
        ],
        '(' => [
            0b00010, 0b00100, 0b01000, 0b01000, 0b01000, 0b00100, 0b00010,
        ],
        ')' => [
            0b01000, 0b00100, 0b00010, 0b00010, 0b00010, 0b00100, 0b01000,
        ],
        '+' => [
            0b00000, 0b00100, 0b00100, 0b11111, 0b00100, 0b00100, 0b00000,
        ],
        '%' => [
            0b11000, 0b11001, 0b00010, 0b00100, 0b01000, 0b10011, 0b00011,
        ],
        _ => [
            0b01110, 0b10001, 0b00001, 0b00010, 0b00100, 0b00000, 0b00100,
        ],
    }
}

/// Canvas pixels `text` takes across at `size`.
pub fn text_width(text: &str, size: usize) -> usize {
    let n = text.chars().count();
    (n * ADVANCE).saturating_sub(1) * size
}

/// Canvas pixels a line takes down at `size`.
pub fn text_height(size: usize) -> usize {
    GLYPH_HEIGHT * size
}

/// The canvas pixels lit by `text` with its top left at `(x, y)`.
fn lit(text: &str, x: f64, y: f64, size: usize) -> impl Iterator<Item = (f64, f64)> + '_ {
    text.chars().enumerate().flat_map(move |(k, c)| {
        let rows = glyph(c);
        let left = x + (k * ADVANCE * size) as f64;
        (0..GLYPH_HEIGHT).flat_map(move |row| {
            (0..GLYPH_WIDTH)
                .filter(move |col| rows[row] >> (GLYPH_WIDTH - 1 - col) & 1 == 1)
                .flat_map(move |col| {
                    (0..size * size).map(move |s| {
                        (
                            left + (col * size + s % size) as f64,
                            y + (row * size + s / size) as f64,
                        )
                    })
                })
        })
    })
}

impl Canvas {
    /// Draws `text` with its top left at canvas `(x, y)`, `size` canvas
    /// pixels a font pixel, ringed by `outline` one canvas pixel wide.
    pub fn text(
        &mut self,
        x: f64,
        y: f64,
        text: &str,
        size: usize,
        colour: Rgb,
        outline: Option<Rgb>,
    ) {
        let size = size.max(1);
        if let Some(outline) = outline {
            let around: Vec<(f64, f64)> = lit(text, x, y, size).collect();
            for (px, py) in &around {
                for (dx, dy) in [(-1.0, 0.0), (1.0, 0.0), (0.0, -1.0), (0.0, 1.0)] {
                    self.put(px + dx, py + dy, outline);
                }
            }
        }
        let pixels: Vec<(f64, f64)> = lit(text, x, y, size).collect();
        for (px, py) in pixels {
            self.put(px, py, colour);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_glyph_fits_five_columns_and_letters_differ() {
        let chars: Vec<char> = ('0'..='9')
            .chain('A'..='Z')
            .chain(".,-:!/=()+% ".chars())
            .collect();
        for &c in &chars {
            assert!(glyph(c).iter().all(|row| *row < 32), "{c}");
        }
        for (i, &a) in chars.iter().enumerate() {
            for &b in &chars[i + 1..] {
                assert_ne!(glyph(a), glyph(b), "{a} and {b} look alike");
            }
        }
        assert_eq!(glyph('e'), glyph('E'));
        assert_eq!(glyph('~'), glyph('?'));
    }

    #[test]
    fn text_lights_its_glyphs_pixels_at_its_size() {
        let mut canvas = Canvas::from_gray(30, 20, &[0; 600], 1).unwrap();
        canvas.text(2.0, 3.0, "L1", 2, [255, 255, 0], Some([9, 9, 9]));
        // L's upright: column 0 of rows 0..7, two canvas pixels a font pixel.
        assert_eq!(canvas.pixel(2, 3), Some([255, 255, 0]));
        assert_eq!(canvas.pixel(3, 16), Some([255, 255, 0]));
        // L's foot: row 6 across.
        assert_eq!(canvas.pixel(10, 15), Some([255, 255, 0]));
        // Beside the upright: unlit, ringed by the outline.
        assert_eq!(canvas.pixel(5, 3), Some([0, 0, 0]));
        assert_eq!(canvas.pixel(4, 3), Some([9, 9, 9]));
        assert_eq!(canvas.pixel(1, 3), Some([9, 9, 9]));
        // The 1 starts one advance (6 font pixels, 12 canvas pixels) on: its top at column 2.
        assert_eq!(canvas.pixel(2 + 12 + 4, 3), Some([255, 255, 0]));
        assert_eq!(text_width("L1", 2), 22);
    }
}
