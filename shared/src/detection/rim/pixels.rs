//! The pixels near the rim band, found once and read again frame after
//! frame.
//!
//! The camera and the disc's plane do not move, so the band's pixels are the
//! same in every frame: where they are (and where the lens's distortion
//! moves them) is worked out when the fit starts from the disc centre and
//! kept while the fit stays within a fraction of a pixel of that start.
//! A frame only reads their values and masks those a mark covers (the
//! marks turn with the disc).

use heapless::Vec;

use super::ellipse::{Ellipse, Locator};
use crate::detection::identify::lens::LensModel;
use crate::detection::MAX_BLOBS;
use crate::detection::{Blob, GrayImage};

/// Sectors round the rim, each with its own three levels (light varies
/// round the image; the disc's texture round the disc).
pub const RIM_SECTORS: usize = 32;
/// Most pixels the fit holds; more near the band are taken one in so many.
pub const MAX_RIM_PIXELS: usize = 4096;
/// A start farther than this from the one the pixels were found for finds
/// them again, px.
const REGATHER_PX: f64 = 0.3;
/// A pixel's zone when it must be placed against the edges each pass.
pub const ZONE_NEAR: u8 = 3;
/// Points round the ellipse that bound the lens's shift and the box.
const OUTLINE_POINTS: usize = 64;

/// Where one pixel near the band is.
#[derive(Debug, Clone, Copy)]
pub struct Site {
    /// Image column and row.
    u: u16,
    v: u16,
    /// Undistorted position relative to [`RimPixels::origin_px`], px.
    pub x: f32,
    /// The same, y.
    pub y: f32,
}

/// The band a pixel's zone was worked out for: its outer edge, the sine
/// and cosine of that edge's angle, the band's width and the ramps' width
/// with the margin taken.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Classified {
    /// The outer edge.
    pub ellipse: Ellipse,
    /// `sin` and `cos` of its angle.
    pub turn: (f64, f64),
    /// The band's width, px.
    pub band_px: f64,
    /// The disc centre's image that placed the inner edge, px.
    pub pole_px: [f64; 2],
    /// The ramps' width, px.
    pub width_px: f64,
}

/// What the pixels were found for.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Gathered {
    ellipse: Ellipse,
    lens: LensModel,
    size: (usize, usize),
    reach_px: (f64, f64),
}

/// The pixels near the band, their sectors and this frame's values, in
/// fixed memory.
#[derive(Debug, Clone)]
pub struct RimPixels {
    sites: Vec<Site, MAX_RIM_PIXELS>,
    sectors: Vec<u8, MAX_RIM_PIXELS>,
    values: Vec<u8, MAX_RIM_PIXELS>,
    /// Each pixel's zone off the ramps (0 the floor, 1 the band, 2 the
    /// disc's surface) while the edges stay near where they were when it
    /// was worked out, else [`ZONE_NEAR`].
    zones: Vec<u8, MAX_RIM_PIXELS>,
    /// The band the zones were worked out for.
    classified: Option<Classified>,
    /// A bit per pixel: a mark covers it in this frame.
    masked: [u32; MAX_RIM_PIXELS / 32],
    origin_px: [f64; 2],
    /// How far the lens moves the band's pixels, px, and 1 px more.
    lens_shift_px: f64,
    gathered: Option<Gathered>,
}

impl Default for RimPixels {
    fn default() -> Self {
        Self {
            sites: Vec::new(),
            sectors: Vec::new(),
            values: Vec::new(),
            zones: Vec::new(),
            classified: None,
            masked: [0; MAX_RIM_PIXELS / 32],
            origin_px: [0.0; 2],
            lens_shift_px: 0.0,
            gathered: None,
        }
    }
}

/// The sector of a phase round the ellipse.
pub fn sector_of(phase_rad: f64) -> usize {
    let turn = (phase_rad + core::f64::consts::PI) / core::f64::consts::TAU;
    ((turn * RIM_SECTORS as f64) as usize).min(RIM_SECTORS - 1)
}

/// One pixel of a pass: where it is, its sector, value and zone.
#[derive(Debug, Clone, Copy)]
pub struct PassPixel {
    /// Relative to the origin, px.
    pub x: f32,
    /// Relative to the origin, px.
    pub y: f32,
    /// Its sector.
    pub sector: usize,
    /// Its grey level this frame.
    pub value: f32,
    /// Its zone, or [`ZONE_NEAR`].
    pub zone: u8,
}

impl RimPixels {
    /// The point the sites are relative to, undistorted px.
    pub fn origin_px(&self) -> [f64; 2] {
        self.origin_px
    }

    /// Forgets where the pixels are, so that the next gather finds them
    /// anew (a fit started from scratch trusts nothing kept).
    pub fn forget(&mut self) {
        self.gathered = None;
    }

    /// Finds the pixels within `reach_px` (inside, outside) of a band whose
    /// outer edge is `ellipse`, unless those found last are for an edge
    /// within a fraction of a pixel of it.
    pub fn gather(
        &mut self,
        image: &GrayImage<'_>,
        lens: &LensModel,
        ellipse: &Ellipse,
        reach_px: (f64, f64),
    ) {
        let wanted = Gathered {
            ellipse: *ellipse,
            lens: *lens,
            size: (image.width(), image.height()),
            reach_px,
        };
        if self.gathered.is_some_and(|g| g.still_serves(&wanted)) {
            return;
        }
        self.gathered = None;
        self.classified = None;
        self.sites.clear();
        self.sectors.clear();
        self.zones.clear();
        self.origin_px = ellipse.centre_px;
        let locator = ellipse.locator();
        let (inner_reach, outer_reach) = reach_px;
        let r = ellipse.mean_radius_px().max(1.0);
        let outer = Ellipse {
            semi_axes_px: ellipse.semi_axes_px.map(|a| a * (1.0 + outer_reach / r)),
            ..*ellipse
        };
        // The box the outer reach's distorted image spans, and how far the
        // lens moves the rim's pixels: a pixel farther than the reaches and
        // that from the ellipse (taken at its distorted place) is not
        // looked at closer.
        let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
        let mut lens_shift = 0.0f64;
        for k in 0..OUTLINE_POINTS {
            let phase = core::f64::consts::TAU * k as f64 / OUTLINE_POINTS as f64;
            let p = lens.distort(outer.point_at(phase));
            lo = [lo[0].min(p[0]), lo[1].min(p[1])];
            hi = [hi[0].max(p[0]), hi[1].max(p[1])];
            let on = ellipse.point_at(phase);
            let d = lens.distort(on);
            lens_shift = lens_shift.max(libm::hypot(d[0] - on[0], d[1] - on[1]));
        }
        lens_shift += 1.0;
        self.lens_shift_px = lens_shift;
        let (width, height) = (image.width(), image.height());
        // The image's border row and column are not trusted.
        let clamp = |v: f64, size: usize| (v.max(1.0) as usize).min(size.saturating_sub(2));
        let (x0, x1) = (clamp(lo[0] - 2.0, width), clamp(hi[0] + 2.0, width));
        let (y0, y1) = (clamp(lo[1] - 2.0, height), clamp(hi[1] + 2.0, height));
        let mut stride = 1usize;
        loop {
            self.sites.clear();
            self.sectors.clear();
            self.zones.clear();
            let mut index = 0usize;
            let mut overflow = false;
            'rows: for v in y0..=y1 {
                for u in x0..=x1 {
                    let (uf, vf) = (u as f64, v as f64);
                    if !locator.distance_px([uf, vf]).is_some_and(|d| {
                        d <= outer_reach + lens_shift && d >= -(inner_reach + lens_shift)
                    }) {
                        continue;
                    }
                    let Some(p) = lens.undistort([uf, vf]) else {
                        continue;
                    };
                    if !locator
                        .distance_px(p)
                        .is_some_and(|d| d <= outer_reach && d >= -inner_reach)
                    {
                        continue;
                    }
                    index += 1;
                    if !(index - 1).is_multiple_of(stride) {
                        continue;
                    }
                    let site = Site {
                        u: u as u16,
                        v: v as u16,
                        x: (p[0] - self.origin_px[0]) as f32,
                        y: (p[1] - self.origin_px[1]) as f32,
                    };
                    let sector = sector_of(locator.phase_rad(p)) as u8;
                    if self.sites.push(site).is_err()
                        || self.sectors.push(sector).is_err()
                        || self.zones.push(ZONE_NEAR).is_err()
                    {
                        overflow = true;
                        break 'rows;
                    }
                }
            }
            if !overflow {
                break;
            }
            stride *= 2;
        }
        self.gathered = Some(wanted);
    }

    /// Reads this frame's values and masks the pixels near `marks`; gives
    /// the pixels left.
    pub fn load(&mut self, image: &GrayImage<'_>, marks: &[Blob], mark_margin_px: f64) -> usize {
        self.values.clear();
        self.masked = [0; MAX_RIM_PIXELS / 32];
        // Only the marks within reach of the band are checked: each as its
        // centre and squared reach, distorted px, in f32.
        let mut near: Vec<(f32, f32, f32), MAX_BLOBS> = Vec::new();
        if let Some(gathered) = &self.gathered {
            let locator = gathered.ellipse.locator();
            let (inner_reach, outer_reach) = gathered.reach_px;
            for mark in marks {
                let reach = f64::from(mark.semi_major_px) + mark_margin_px;
                let slack = reach + self.lens_shift_px;
                let at = [f64::from(mark.x_px), f64::from(mark.y_px)];
                if locator
                    .distance_px(at)
                    .is_some_and(|d| d <= outer_reach + slack && d >= -(inner_reach + slack))
                {
                    // Past MAX_BLOBS marks (more than the detector
                    // gives) the rest are left to the robust weights.
                    let _ = near.push((mark.x_px, mark.y_px, (reach * reach) as f32));
                }
            }
        }
        let mut left = 0;
        for (k, site) in self.sites.iter().enumerate() {
            let (u, v) = (usize::from(site.u), usize::from(site.v));
            let value = image.row(v).get(u).copied();
            let covered = near.iter().any(|&(x, y, reach2)| {
                let (dx, dy) = (f32::from(site.u) - x, f32::from(site.v) - y);
                dx * dx + dy * dy <= reach2
            });
            let value = match value {
                Some(value) if !covered => {
                    left += 1;
                    value
                }
                _ => {
                    if let Some(word) = self.masked.get_mut(k / 32) {
                        *word |= 1 << (k % 32);
                    }
                    0
                }
            };
            // The values share the sites' capacity.
            let _ = self.values.push(value);
        }
        left
    }

    /// The pixels of this frame no mark covers.
    pub fn pass(&self) -> impl Iterator<Item = PassPixel> + '_ {
        self.sites
            .iter()
            .zip(self.sectors.iter().zip(&self.zones))
            .zip(&self.values)
            .enumerate()
            .filter(|(k, _)| !self.is_masked(*k))
            .map(|(_, ((site, (&sector, &zone)), &value))| PassPixel {
                x: site.x,
                y: site.y,
                sector: usize::from(sector),
                value: f32::from(value),
                zone,
            })
    }

    /// The band the zones were worked out for, if they were.
    pub fn classified(&self) -> Option<&Classified> {
        self.classified.as_ref()
    }

    /// Works out each pixel's zone by `zone_of` (given its position), for
    /// the band `at`.
    pub fn classify(&mut self, at: Classified, zone_of: impl Fn(f32, f32) -> u8) {
        for (zone, site) in self.zones.iter_mut().zip(&self.sites) {
            *zone = zone_of(site.x, site.y);
        }
        self.classified = Some(at);
    }

    fn is_masked(&self, k: usize) -> bool {
        self.masked
            .get(k / 32)
            .is_none_or(|word| word & (1 << (k % 32)) != 0)
    }
}

impl Gathered {
    /// Whether the pixels found for `self` serve a band `wanted`: the same
    /// lens, image and reaches, and an outer edge within [`REGATHER_PX`]
    /// (the reaches are measured from it).
    fn still_serves(&self, wanted: &Self) -> bool {
        if self.lens != wanted.lens || self.size != wanted.size || self.reach_px != wanted.reach_px
        {
            return false;
        }
        let locator: Locator = self.ellipse.locator();
        (0..16).all(|k| {
            let p = wanted
                .ellipse
                .point_at(core::f64::consts::TAU * f64::from(k) / 16.0);
            locator
                .distance_px(p)
                .is_some_and(|d| d.abs() <= REGATHER_PX)
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const LENS: LensModel = LensModel {
        f_px: 290.0,
        cx: 127.5,
        cy: 127.5,
        k1: -0.05,
        k2: 0.0,
    };

    fn ellipse(dx: f64) -> Ellipse {
        Ellipse {
            centre_px: [128.0 + dx, 126.0],
            semi_axes_px: [60.0, 52.0],
            angle_rad: 0.3,
        }
    }

    fn mark(x: f32, y: f32) -> Blob {
        Blob {
            x_px: x,
            y_px: y,
            area_px: 12,
            semi_major_px: 2.0,
            semi_minor_px: 2.0,
            orientation_rad: 0.0,
            peak_contrast: 100,
            mean_contrast: 80.0,
            lopsidedness: 0.0,
        }
    }

    #[test]
    fn the_pixels_are_kept_while_the_band_stays_put_and_found_again_when_it_moves() {
        let frame = std::vec![40u8; 256 * 256];
        let image = GrayImage::packed(256, 256, &frame).unwrap();
        let mut pixels = RimPixels::default();
        pixels.gather(&image, &LENS, &ellipse(0.0), (6.0, 3.5));
        let found = pixels.sites.len();
        // About the band's length times the reaches' 9.5 px.
        assert!((3000..4096).contains(&found), "{found}");
        // Every pixel's undistorted place lies within the reaches.
        let locator = ellipse(0.0).locator();
        for site in &pixels.sites {
            let p = [
                f64::from(site.x) + pixels.origin_px[0],
                f64::from(site.y) + pixels.origin_px[1],
            ];
            let d = locator.distance_px(p).unwrap();
            assert!((-6.0..=3.5).contains(&d), "{d}");
        }
        // A start a tenth of a pixel off keeps them (the origin stays).
        pixels.gather(&image, &LENS, &ellipse(0.1), (6.0, 3.5));
        assert_eq!(pixels.origin_px, ellipse(0.0).centre_px);
        // One a pixel off finds them again; so does another lens.
        pixels.gather(&image, &LENS, &ellipse(1.0), (6.0, 3.5));
        assert_eq!(pixels.origin_px, ellipse(1.0).centre_px);
        let other = LensModel { k1: 0.0, ..LENS };
        pixels.gather(&image, &other, &ellipse(1.0), (6.0, 3.5));
        assert!(pixels.gathered.is_some_and(|g| g.lens == other));
    }

    #[test]
    fn a_frame_masks_the_pixels_a_mark_covers_and_only_those() {
        let frame = std::vec![40u8; 256 * 256];
        let image = GrayImage::packed(256, 256, &frame).unwrap();
        let mut pixels = RimPixels::default();
        pixels.gather(&image, &LENS, &ellipse(0.0), (6.0, 3.5));
        let all = pixels.load(&image, &[], 2.5);
        assert_eq!(all, pixels.sites.len());
        // A mark on the band (its distorted place) and one at the disc's
        // centre, far inside the reach.
        let on_band = LENS.distort(ellipse(0.0).point_at(1.0));
        let marks = [
            mark(on_band[0] as f32, on_band[1] as f32),
            mark(128.0, 126.0),
        ];
        let left = pixels.load(&image, &marks, 2.5);
        let covered = pixels
            .sites
            .iter()
            .filter(|s| (f64::from(s.u) - on_band[0]).hypot(f64::from(s.v) - on_band[1]) <= 4.5)
            .count();
        assert!(covered > 20, "{covered}");
        assert_eq!(left, all - covered);
        assert_eq!(pixels.pass().count(), left);
    }
}
