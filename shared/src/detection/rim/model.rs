//! One pixel against the band's model, in `f32` with analytic derivatives:
//! the inner loop of the rim's fit ([`super::fit`]), which runs over some
//! two thousand pixels a frame and must fit a Cortex-M4F's single-precision
//! unit (its `f64` is a software routine).
//!
//! Each edge is a conic `q = A x^2 + 2 B x y + C y^2 + 2 D x + 2 E y + F`,
//! normalised to `-1` at its centre, in pixels relative to an origin near
//! the rim's centre (so that `f32` keeps a hundred-thousandth of a pixel).
//! A pixel's signed distance from it is `d = 2 s (s - 1) / |grad q|` with
//! `s = sqrt(q + 1)`, the same as [`super::ellipse::Locator::distance_px`];
//! its derivatives along the conic's six coefficients are closed-form, and
//! those along the fit's parameters come from a 6 x 6 matrix worked out once
//! an iteration (the edge's `chain`), so that the pencil of concentric
//! circles' images that places the inner edge costs nothing per pixel.

use nalgebra::{Matrix3, SMatrix, SVector, Vector3};

use super::ellipse::Ellipse;

/// The fit's parameters (see [`super::fit`]).
pub const PARAMETERS: usize = 6;

/// A row along the fit's parameters, `f32`.
pub type Row = SVector<f32, PARAMETERS>;

/// One edge of the band, ready to place pixels.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EdgeConic {
    /// `A, B, C, D, E, F` (see the module docs).
    coefficients: [f32; 6],
    /// How the coefficients move with the fit's parameters: column `j` is
    /// `d coefficients / d parameter j`.
    chain: SMatrix<f32, 6, PARAMETERS>,
}

/// `0.39^2`: see [`EdgeConic::side`].
const FAR_SHARE: f32 = 0.1521;

/// Where a pixel lies against an edge's ramp.
#[derive(Debug, Clone, Copy)]
pub enum Side {
    /// Inside the edge, off its ramp.
    Inside,
    /// Outside the edge, off its ramp.
    Outside,
    /// Near enough to need its distance.
    Near(EdgeDistance),
}

/// A pixel seen from one edge: its signed distance (positive outside) and
/// what the distance's derivatives need.
#[derive(Debug, Clone, Copy)]
pub struct EdgeDistance {
    /// Signed distance, px.
    pub distance_px: f32,
    /// `d distance / d q`.
    along_q: f32,
    /// `d distance / d gx` and `d distance / d gy`, with `(gx, gy)` half
    /// of `grad q`.
    along_gx: f32,
    along_gy: f32,
}

/// The normalised coefficients of `ellipse` relative to `origin`, in `f64`,
/// given the sine and cosine of its angle (worked out once an iteration).
pub fn ellipse_coefficients(
    ellipse: &Ellipse,
    (sin, cos): (f64, f64),
    origin: [f64; 2],
) -> [f64; 6] {
    let [a, b] = ellipse.semi_axes_px;
    // x' = cos dx + sin dy, y' = -sin dx + cos dy; x'^2/a^2 + y'^2/b^2 - 1.
    let (ia, ib) = (1.0 / (a * a), 1.0 / (b * b));
    let qxx = cos * cos * ia + sin * sin * ib;
    let qyy = sin * sin * ia + cos * cos * ib;
    let qxy = cos * sin * (ia - ib);
    let cx = ellipse.centre_px[0] - origin[0];
    let cy = ellipse.centre_px[1] - origin[1];
    let lx = -(qxx * cx + qxy * cy);
    let ly = -(qxy * cx + qyy * cy);
    let f = qxx * cx * cx + 2.0 * qxy * cx * cy + qyy * cy * cy - 1.0;
    [qxx, qxy, qyy, lx, ly, f]
}

/// The normalised coefficients of `ellipse` relative to `origin`.
pub fn conic_coefficients(ellipse: &Ellipse, origin: [f64; 2]) -> [f64; 6] {
    ellipse_coefficients(ellipse, libm::sincos(ellipse.angle_rad), origin)
}

/// The coefficients of the image of the circle concentric with the one
/// `outer` images, `1 - fraction` of its radius, given their centre's image
/// `pole` (all relative to the same origin): the pencil of
/// [`Ellipse::concentric`], `C - (1 - (1 - fraction)^2) m m^T / (c^T m)`
/// with `m = C c`, normalised to `-1` at its centre. `None` when the pole is
/// not inside or the result is no ellipse.
pub fn concentric_coefficients(
    outer: &[f64; 6],
    pole: [f64; 2],
    fraction: f64,
) -> Option<[f64; 6]> {
    let [a, b, c, d, e, f] = *outer;
    let m = Matrix3::new(a, b, d, b, c, e, d, e, f) * Vector3::new(pole[0], pole[1], 1.0);
    let inside = pole[0] * m.x + pole[1] * m.y + m.z;
    if inside.is_nan() || inside >= 0.0 {
        return None;
    }
    let keep = 1.0 - fraction;
    let k = (1.0 - keep * keep) / inside;
    let [a, b, c, d, e, f] = [
        a - k * m.x * m.x,
        b - k * m.x * m.y,
        c - k * m.y * m.y,
        d - k * m.x * m.z,
        e - k * m.y * m.z,
        f - k * m.z * m.z,
    ];
    // Its value at its centre, f - l^T Q^-1 l, is -1 once normalised.
    let det = a * c - b * b;
    // NaN fails too.
    if det.is_nan() || det <= 0.0 {
        return None;
    }
    let centre_value = f - (c * d * d - 2.0 * b * d * e + a * e * e) / det;
    let scale = -1.0 / centre_value;
    let normalised = [a, b, c, d, e, f].map(|v| v * scale);
    (normalised[0] > 0.0 && normalised.iter().all(|v| v.is_finite())).then_some(normalised)
}

impl EdgeConic {
    /// An edge of coefficients `coefficients` (relative to the origin, as
    /// [`conic_coefficients`] gives) whose parameter derivatives `chain`
    /// the caller worked out.
    pub fn new(coefficients: [f64; 6], chain: SMatrix<f64, 6, PARAMETERS>) -> Option<Self> {
        let single = coefficients.map(|c| c as f32);
        let chain = chain.map(|c| c as f32);
        (single.iter().all(|c| c.is_finite()) && chain.iter().all(|c| c.is_finite())).then_some(
            Self {
                coefficients: single,
                chain,
            },
        )
    }

    /// Where `(x, y)` (px from the origin) lies, or `None` at the centre
    /// (no gradient) or for a NaN (the tests' view of [`Self::side`]).
    #[cfg(test)]
    pub fn distance(&self, x: f32, y: f32) -> Option<EdgeDistance> {
        match self.side(x, y, f32::INFINITY)? {
            Side::Near(at) => Some(at),
            _ => None,
        }
    }

    /// Where `(x, y)` lies against a ramp `half_width` px either side of
    /// the edge: surely inside or outside it (no square root: most pixels
    /// near the band are on neither ramp), or near it with its distance.
    #[inline]
    pub fn side(&self, x: f32, y: f32, half_width: f32) -> Option<Side> {
        let [a, b, c, d, e, f] = self.coefficients;
        let gx = a * x + b * y + d;
        let gy = b * x + c * y + e;
        let q = (gx + d) * x + (gy + e) * y + f;
        let g2 = gx * gx + gy * gy;
        let s2 = q + 1.0;
        if !(g2 > 1e-30 && s2 > 1e-12) {
            return None;
        }
        // |distance| = |q| / g * s / (s + 1), and s / (s + 1) > 0.39 for
        // s > 0.64 (within a third of the radius of the edge), so that a
        // pixel with 0.39^2 q^2 > half_width^2 g^2 is off the ramp.
        if s2 > 0.41 && FAR_SHARE * q * q > half_width * half_width * g2 {
            return Some(if q < 0.0 { Side::Inside } else { Side::Outside });
        }
        let g = libm::sqrtf(g2);
        let s = libm::sqrtf(s2);
        // distance = s (s - 1) / g, with g = |grad q| / 2.
        let distance_px = s * (s - 1.0) / g;
        Some(Side::Near(EdgeDistance {
            distance_px,
            // d(s (s - 1))/dq = (2 s - 1) / (2 s).
            along_q: (2.0 * s - 1.0) / (2.0 * s * g),
            // d/dg of 1/g is -1/g^2, and dg = (gx dgx + gy dgy) / g.
            along_gx: -distance_px * gx / g2,
            along_gy: -distance_px * gy / g2,
        }))
    }

    /// `d distance / d parameters` of a pixel at `(x, y)` this edge placed
    /// as `at`.
    #[inline]
    pub fn gradient(&self, at: &EdgeDistance, x: f32, y: f32) -> Row {
        let (kq, kx, ky) = (at.along_q, at.along_gx, at.along_gy);
        // dq/dθ = (x², 2xy, y², 2x, 2y, 1); dgx/dθ = (x, y, 0, 1, 0, 0);
        // dgy/dθ = (0, x, y, 0, 1, 0).
        let along_coefficients = SVector::<f32, 6>::new(
            kq * x * x + kx * x,
            kq * 2.0 * x * y + kx * y + ky * x,
            kq * y * y + ky * y,
            kq * 2.0 * x + kx,
            kq * 2.0 * y + ky,
            kq,
        );
        self.chain.tr_mul(&along_coefficients)
    }
}

/// The share of a pixel beyond an edge at signed distance `d` (1 inside),
/// for a ramp `width` px wide, and its slope along `d`.
#[inline]
pub fn ramp(d: f32, width: f32) -> (f32, f32) {
    let a = 0.5 - d / width;
    if a <= 0.0 {
        (0.0, 0.0)
    } else if a >= 1.0 {
        (1.0, 0.0)
    } else {
        (a, -1.0 / width)
    }
}

/// The share of a pixel inside an edge (1 inside) and its slope along the
/// distance, with the distance where the pixel is on the ramp.
#[inline]
fn share(side: Side, width: f32) -> (f32, f32, Option<EdgeDistance>) {
    match side {
        Side::Inside => (1.0, 0.0, None),
        Side::Outside => (0.0, 0.0, None),
        Side::Near(at) => {
            let (a, slope) = ramp(at.distance_px, width);
            (a, slope, (slope != 0.0).then_some(at))
        }
    }
}

/// A pixel's view of the model: the shares of it the floor, the band and
/// the disc's surface cover, and where it lies against the two edges.
#[derive(Debug, Clone, Copy)]
pub struct PixelModel {
    /// `(1 - a_o, a_o (1 - a_i), a_o a_i)`.
    pub basis: Vector3<f32>,
    a_outer: f32,
    a_inner: f32,
    slope_outer: f32,
    slope_inner: f32,
    /// Set where the pixel is on that edge's ramp.
    outer: Option<EdgeDistance>,
    inner: Option<EdgeDistance>,
}

impl PixelModel {
    /// The pixel at `(x, y)` against the band's `outer` and `inner` edges.
    #[inline(always)]
    pub fn at(outer: &EdgeConic, inner: &EdgeConic, x: f32, y: f32, width: f32) -> Option<Self> {
        let half = 0.5 * width;
        let (a_outer, slope_outer, o) = share(outer.side(x, y, half)?, width);
        // Outside the rim the inner edge does not matter.
        let (a_inner, slope_inner, i) = if a_outer == 0.0 {
            (0.0, 0.0, None)
        } else {
            share(inner.side(x, y, half)?, width)
        };
        Some(Self {
            basis: Vector3::new(1.0 - a_outer, a_outer * (1.0 - a_inner), a_outer * a_inner),
            a_outer,
            a_inner,
            slope_outer,
            slope_inner,
            outer: o,
            inner: i,
        })
    }

    /// A pixel known to lie wholly in `zone` (0 the floor, 1 the band, 2
    /// the disc's surface), off both ramps.
    #[inline]
    pub fn in_zone(zone: u8) -> Self {
        let (a_outer, a_inner) = match zone {
            0 => (0.0, 0.0),
            1 => (1.0, 0.0),
            _ => (1.0, 1.0),
        };
        Self {
            basis: Vector3::new(1.0 - a_outer, a_outer * (1.0 - a_inner), a_outer * a_inner),
            a_outer,
            a_inner,
            slope_outer: 0.0,
            slope_inner: 0.0,
            outer: None,
            inner: None,
        }
    }

    /// The zone of a pixel at `(x, y)` farther than `half_width` from both
    /// edges (0 the floor, 1 the band, 2 the disc's surface), else `near`.
    #[inline]
    pub fn zone_at(
        outer: &EdgeConic,
        inner: &EdgeConic,
        x: f32,
        y: f32,
        half_width: f32,
        near: u8,
    ) -> u8 {
        match outer.side(x, y, half_width) {
            Some(Side::Outside) => 0,
            Some(Side::Inside) => match inner.side(x, y, half_width) {
                Some(Side::Outside) => 1,
                Some(Side::Inside) => 2,
                _ => near,
            },
            _ => near,
        }
    }

    /// The zone a pixel off both ramps lies wholly in (0 the floor, 1 the
    /// band, 2 the disc's surface), or `None` on a ramp.
    #[inline]
    pub fn zone(&self) -> Option<usize> {
        if self.outer.is_some() || self.inner.is_some() {
            None
        } else if self.a_outer == 0.0 {
            Some(0)
        } else if self.a_inner == 0.0 {
            Some(1)
        } else {
            Some(2)
        }
    }

    /// `d (levels . basis) / d parameters`: how the model's value of the
    /// pixel moves with the edges, for the sector's `levels`.
    #[inline]
    pub fn row(
        &self,
        outer: &EdgeConic,
        inner: &EdgeConic,
        levels: &Vector3<f32>,
        x: f32,
        y: f32,
    ) -> Row {
        let [floor, band, surface] = [levels.x, levels.y, levels.z];
        let mut row = Row::zeros();
        // d basis / d a_o = (-1, 1 - a_i, a_i); d basis / d a_i = a_o (0, -1, 1).
        if let Some(at) = &self.outer {
            let along =
                self.slope_outer * (-floor + band * (1.0 - self.a_inner) + surface * self.a_inner);
            row += outer.gradient(at, x, y) * along;
        }
        if let Some(at) = &self.inner {
            let along = self.slope_inner * self.a_outer * (surface - band);
            row += inner.gradient(at, x, y) * along;
        }
        row
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ellipse() -> Ellipse {
        Ellipse {
            centre_px: [131.0, 118.0],
            semi_axes_px: [52.0, 41.0],
            angle_rad: 0.4,
        }
    }

    #[test]
    fn the_pencil_gives_the_concentric_ellipse() {
        let e = ellipse();
        let origin = [130.0, 120.0];
        let pole = [133.5, 116.0];
        let want = conic_coefficients(&e.concentric(pole, 0.04).unwrap(), origin);
        let got = concentric_coefficients(
            &conic_coefficients(&e, origin),
            [pole[0] - origin[0], pole[1] - origin[1]],
            0.04,
        )
        .unwrap();
        for (g, w) in got.iter().zip(&want) {
            assert!((g - w).abs() < 1e-12 * w.abs().max(1.0), "{got:?} {want:?}");
        }
        // A pole outside is no centre.
        assert!(
            concentric_coefficients(&conic_coefficients(&e, origin), [90.0, 0.0], 0.04).is_none()
        );
    }

    #[test]
    fn the_conic_places_a_pixel_as_the_locator_does() {
        let e = ellipse();
        let origin = [130.0, 120.0];
        let edge = EdgeConic::new(conic_coefficients(&e, origin), SMatrix::zeros()).unwrap();
        let locator = e.locator();
        for p in [
            [183.5, 120.25],
            [131.0, 160.0],
            [95.0, 80.0],
            [170.0, 150.0],
        ] {
            let want = locator.distance_px(p).unwrap();
            let got = edge
                .distance((p[0] - origin[0]) as f32, (p[1] - origin[1]) as f32)
                .unwrap()
                .distance_px;
            assert!((f64::from(got) - want).abs() < 2e-5, "{p:?} {got} {want}");
        }
    }

    #[test]
    fn the_analytic_derivatives_match_finite_differences() {
        let e = ellipse();
        let origin = [130.0, 120.0];
        let base = conic_coefficients(&e, origin);
        // With the identity chain the row is d distance / d coefficients.
        let mut identity = SMatrix::<f64, 6, PARAMETERS>::zeros();
        for k in 0..6 {
            identity[(k, k)] = 1.0;
        }
        let edge = EdgeConic::new(base, identity).unwrap();
        let (x, y) = (52.7f32, 4.1f32);
        let at = edge.distance(x, y).unwrap();
        let row = edge.gradient(&at, x, y);
        let distance = |c: [f64; 6]| {
            let (x, y) = (f64::from(x), f64::from(y));
            let gx = c[0] * x + c[1] * y + c[3];
            let gy = c[1] * x + c[2] * y + c[4];
            let q = c[0] * x * x
                + 2.0 * c[1] * x * y
                + c[2] * y * y
                + 2.0 * c[3] * x
                + 2.0 * c[4] * y
                + c[5];
            let s = (q + 1.0).sqrt();
            s * (s - 1.0) / (gx * gx + gy * gy).sqrt()
        };
        for k in 0..6 {
            let step = 1e-7 * base[k].abs().max(1e-3);
            let mut up = base;
            up[k] += step;
            let mut down = base;
            down[k] -= step;
            let want = (distance(up) - distance(down)) / (2.0 * step);
            let got = f64::from(row[k]);
            assert!(
                (got - want).abs() <= 1e-3 * want.abs().max(1.0),
                "{k}: {got} {want}"
            );
        }
    }

    #[test]
    fn a_pixel_given_a_zone_is_modelled_as_one_placed_against_the_edges() {
        let outer_ellipse = ellipse();
        let origin = [130.0, 120.0];
        let outer_coefficients = conic_coefficients(&outer_ellipse, origin);
        // A band 4 px wide, so that some pixels lie off both its ramps.
        let inner_coefficients =
            concentric_coefficients(&outer_coefficients, [2.0, -3.0], 0.1).unwrap();
        let outer = EdgeConic::new(outer_coefficients, SMatrix::zeros()).unwrap();
        let inner = EdgeConic::new(inner_coefficients, SMatrix::zeros()).unwrap();
        let (width, near) = (1.0f32, 9u8);
        let mut zoned = [0usize; 3];
        // A grid over the band and either side of it.
        for i in 0..200 {
            for j in 0..200 {
                let (x, y) = (-60.0 + 0.6 * i as f32, -50.0 + 0.5 * j as f32);
                let placed = PixelModel::at(&outer, &inner, x, y, width).unwrap();
                let zone = PixelModel::zone_at(&outer, &inner, x, y, 0.5 * width + 0.4, near);
                if zone == near {
                    continue;
                }
                let given = PixelModel::in_zone(zone);
                assert_eq!(given.basis, placed.basis, "({x}, {y}) zone {zone}");
                assert_eq!(placed.zone(), Some(usize::from(zone)), "({x}, {y})");
                zoned[usize::from(zone)] += 1;
            }
        }
        assert!(zoned.iter().all(|&n| n > 100), "{zoned:?}");
    }
}
