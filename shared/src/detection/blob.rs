//! From a component's sums to a mark candidate: its sub-pixel centre, its size
//! and shape, and whether it looks like a mark at all.
//!
//! The centre is the contrast-weighted centroid: a pixel the mark half covers
//! is half as bright above the background and counts half, which puts the
//! centre between pixel centres. Pixel `(i, j)` has its centre at `(i, j)`.
//! The shape comes from the unweighted second moments: a solid ellipse with
//! semi-axes `a >= b` has moment eigenvalues `a^2 / 4` and `b^2 / 4` and
//! area `pi a b`, so a mark (a disc seen at an angle) fills its moment
//! ellipse, while a streak, a ring or two touching blobs do not.

use super::components::ComponentSums;

/// What a mark may look like; anything else is refused.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MarkShape {
    /// Fewest pixels.
    pub min_area_px: u32,
    /// Most pixels.
    pub max_area_px: u32,
    /// Least ratio of the moment ellipse's minor to major axis (a disc
    /// tilted by 60 degrees is 0.5; motion blur lowers it further).
    pub min_axis_ratio: f32,
    /// Range of area over the moment ellipse's area (1 for a solid ellipse).
    pub fill_range: (f32, f32),
    /// Pixels a mark keeps from the image border (a cut mark has a biased centre).
    pub border_px: u16,
}

impl Default for MarkShape {
    fn default() -> Self {
        Self {
            min_area_px: 3,
            max_area_px: 600,
            min_axis_ratio: 0.35,
            fill_range: (0.6, 1.5),
            border_px: 1,
        }
    }
}

/// A detected mark candidate.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Blob {
    /// Contrast-weighted centre, pixels (pixel `i`'s centre at `i`).
    pub x_px: f32,
    /// Contrast-weighted centre, pixels.
    pub y_px: f32,
    /// Pixels above the threshold.
    pub area_px: u32,
    /// Semi-axes of the moment ellipse, pixels.
    pub semi_major_px: f32,
    /// Minor semi-axis, pixels.
    pub semi_minor_px: f32,
    /// Direction of the major axis from +x towards +y, radians.
    pub orientation_rad: f32,
    /// Brightest contrast above the background, grey levels.
    pub peak_contrast: u8,
    /// Mean contrast above the background, grey levels.
    pub mean_contrast: f32,
    /// Skewness of the mark's coverage, whitened by its moment ellipse
    /// ([`crate::detection::coverage`]): near 0 for a whole mark, larger
    /// when something in front cuts a piece off it.
    pub lopsidedness: f32,
}

/// Why a component is not a mark.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Refusal {
    /// Fewer pixels than a mark.
    TooSmall,
    /// More pixels than a mark.
    TooLarge,
    /// Too elongated (a streak, an edge).
    Elongated,
    /// Does not fill its moment ellipse (a ring, a cluster, a ragged glint).
    Ragged,
    /// Touches the image border.
    AtBorder,
}

impl Blob {
    /// The mark candidate of a component of an image `width` x `height`, or
    /// why it is not one.
    pub fn from_sums(
        sums: &ComponentSums,
        width: usize,
        height: usize,
        shape: &MarkShape,
    ) -> Result<Self, Refusal> {
        if sums.area < shape.min_area_px {
            return Err(Refusal::TooSmall);
        }
        if sums.area > shape.max_area_px {
            return Err(Refusal::TooLarge);
        }
        let border = usize::from(shape.border_px);
        if usize::from(sums.x_min) < border
            || usize::from(sums.y_min) < border
            || usize::from(sums.x_max) + border >= width
            || usize::from(sums.y_max) + border >= height
        {
            return Err(Refusal::AtBorder);
        }
        // Central moments in f64: the sums are exact, the differences are not
        // small next to them.
        let n = f64::from(sums.area);
        let mx = sums.sx as f64 / n;
        let my = sums.sy as f64 / n;
        // A pixel is a unit square: each adds 1/12 to its own variance.
        let cxx = sums.sxx as f64 / n - mx * mx + 1.0 / 12.0;
        let cyy = sums.syy as f64 / n - my * my + 1.0 / 12.0;
        let cxy = sums.sxy as f64 / n - mx * my;
        let half_trace = 0.5 * (cxx + cyy);
        let spread = libm::sqrt(0.25 * (cxx - cyy) * (cxx - cyy) + cxy * cxy);
        let major = (half_trace + spread).max(0.0);
        let minor = (half_trace - spread).max(0.0);
        let semi_major = 2.0 * libm::sqrt(major);
        let semi_minor = 2.0 * libm::sqrt(minor);
        if semi_major <= 0.0 || semi_minor / semi_major < f64::from(shape.min_axis_ratio) {
            return Err(Refusal::Elongated);
        }
        let fill = n / (core::f64::consts::PI * semi_major * semi_minor);
        if fill < f64::from(shape.fill_range.0) || fill > f64::from(shape.fill_range.1) {
            return Err(Refusal::Ragged);
        }
        let (x_px, y_px) = if sums.sw > 0 {
            let w = sums.sw as f64;
            (sums.swx as f64 / w, sums.swy as f64 / w)
        } else {
            (mx, my)
        };
        Ok(Self {
            x_px: x_px as f32,
            y_px: y_px as f32,
            area_px: sums.area,
            semi_major_px: semi_major as f32,
            semi_minor_px: semi_minor as f32,
            orientation_rad: (0.5 * libm::atan2(2.0 * cxy, cxx - cyy)) as f32,
            peak_contrast: sums.peak,
            mean_contrast: (sums.sw as f64 / n) as f32,
            lopsidedness: 0.0,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sums_of(pixels: &[(u16, u16, u8)]) -> ComponentSums {
        let mut sums = ComponentSums {
            x_min: u16::MAX,
            y_min: u16::MAX,
            ..ComponentSums::default()
        };
        for &(x, y, w) in pixels {
            let (xl, yl, wl) = (u64::from(x), u64::from(y), u64::from(w));
            sums.area += 1;
            sums.sx += xl;
            sums.sy += yl;
            sums.sxx += xl * xl;
            sums.syy += yl * yl;
            sums.sxy += xl * yl;
            sums.sw += wl;
            sums.swx += wl * xl;
            sums.swy += wl * yl;
            sums.peak = sums.peak.max(w);
            sums.x_min = sums.x_min.min(x);
            sums.x_max = sums.x_max.max(x);
            sums.y_min = sums.y_min.min(y);
            sums.y_max = sums.y_max.max(y);
        }
        sums
    }

    #[test]
    fn a_pixelated_disc_is_a_round_mark_of_its_radius() {
        let (cx, cy, r) = (20.0f32, 30.0f32, 4.0f32);
        let mut pixels = std::vec::Vec::new();
        for y in 20..40u16 {
            for x in 10..30u16 {
                let (dx, dy) = (x as f32 - cx, y as f32 - cy);
                if dx * dx + dy * dy <= r * r {
                    pixels.push((x, y, 100));
                }
            }
        }
        let blob = Blob::from_sums(&sums_of(&pixels), 64, 64, &MarkShape::default()).unwrap();
        assert!((blob.x_px - cx).abs() < 1e-4 && (blob.y_px - cy).abs() < 1e-4);
        assert!((blob.semi_major_px - r).abs() < 0.35, "{blob:?}");
        assert!(blob.semi_minor_px / blob.semi_major_px > 0.95);
    }

    #[test]
    fn weights_move_the_centre_between_pixels() {
        // Two columns, the right one a quarter as bright: the centre sits a
        // fifth of the way across.
        let pixels = [(10, 10, 100), (11, 10, 25), (10, 11, 100), (11, 11, 25)];
        let blob = Blob::from_sums(&sums_of(&pixels), 64, 64, &MarkShape::default()).unwrap();
        assert!((blob.x_px - 10.2).abs() < 1e-5 && (blob.y_px - 10.5).abs() < 1e-5);
    }

    #[test]
    fn streaks_rings_and_cut_marks_are_refused() {
        let shape = MarkShape::default();
        let streak: std::vec::Vec<_> = (5..25).map(|x| (x, 10, 50)).collect();
        assert_eq!(
            Blob::from_sums(&sums_of(&streak), 64, 64, &shape),
            Err(Refusal::Elongated)
        );
        let mut ring = std::vec::Vec::new();
        for y in 10..31u16 {
            for x in 10..31u16 {
                let d2 = (x as i32 - 20).pow(2) + (y as i32 - 20).pow(2);
                if (81..=100).contains(&d2) {
                    ring.push((x, y, 50));
                }
            }
        }
        assert_eq!(
            Blob::from_sums(&sums_of(&ring), 64, 64, &shape),
            Err(Refusal::Ragged)
        );
        let cut = [(0, 5, 50), (1, 5, 50), (0, 6, 50), (1, 6, 50)];
        assert_eq!(
            Blob::from_sums(&sums_of(&cut), 64, 64, &shape),
            Err(Refusal::AtBorder)
        );
        assert_eq!(
            Blob::from_sums(&sums_of(&[(5, 5, 9)]), 64, 64, &shape),
            Err(Refusal::TooSmall)
        );
    }
}
