//! Rasterising in image space with analytic coverage: each primitive is
//! visited only over its bounding box, and a pixel's coverage comes from the
//! signed distance `d` to the primitive's outline in pixels, through the ramp
//! `clamp(0.5 - d, 0, 1)`: for convex outlines (marks, the part) evaluated at
//! 3 x 3 sub-pixels of the pixels the outline crosses (edge-only
//! supersampling, close to the exact area a real pixel integrates), for the
//! arm's capsules at the pixel's centre. Motion blur averages the coverage
//! over sub-instants of the exposure.
//!
//! Hidden surfaces: each pixel keeps the depth (camera z) of its nearest
//! surface that covers at least half of it; a primitive only paints where it
//! is nearer, blending by its coverage, so the arm hides what it stands in
//! front of and is hidden by what stands in front of it.

/// Reflectance (shading included) and depth of each pixel, row by row.
#[derive(Debug, Clone)]
pub struct FrameBuffer {
    pub width: usize,
    pub height: usize,
    pub albedo: Vec<f32>,
    pub depth: Vec<f32>,
}

impl FrameBuffer {
    pub fn new(width: usize, height: usize) -> Self {
        Self {
            width,
            height,
            albedo: vec![0.0; width * height],
            depth: vec![f32::INFINITY; width * height],
        }
    }

    /// Paints `albedo` over pixel `index` with `coverage` if `depth` is nearer
    /// than what the pixel holds.
    #[inline]
    pub fn blend(&mut self, index: usize, coverage: f32, albedo: f32, depth: f32) {
        if coverage <= 0.0 {
            return;
        }
        let (Some(old_albedo), Some(old_depth)) =
            (self.albedo.get_mut(index), self.depth.get_mut(index))
        else {
            return;
        };
        if depth < *old_depth {
            *old_albedo = coverage * albedo + (1.0 - coverage) * *old_albedo;
            if coverage >= 0.5 {
                *old_depth = depth;
            }
        }
    }

    /// The pixel range `[x0, x1] x [y0, y1]` covering `[min, max]` grown by
    /// `grow_px`, clipped to the image; `None` when outside it.
    pub fn clip(&self, min: [f64; 2], max: [f64; 2], grow_px: f64) -> Option<[usize; 4]> {
        let x0 = (min[0] - grow_px).floor().max(0.0);
        let y0 = (min[1] - grow_px).floor().max(0.0);
        let x1 = (max[0] + grow_px).ceil().min(self.width as f64 - 1.0);
        let y1 = (max[1] + grow_px).ceil().min(self.height as f64 - 1.0);
        (x0.is_finite() && y0.is_finite() && x1 >= x0 && y1 >= y0).then_some([
            x0 as usize,
            y0 as usize,
            x1 as usize,
            y1 as usize,
        ])
    }
}

/// Counter-clockwise convex hull (Andrew's monotone chain), collinear points dropped.
pub fn convex_hull(points: &[[f64; 2]]) -> Vec<[f64; 2]> {
    let mut sorted: Vec<[f64; 2]> = points
        .iter()
        .copied()
        .filter(|p| p[0].is_finite() && p[1].is_finite())
        .collect();
    sorted.sort_by(|a, b| a[0].total_cmp(&b[0]).then(a[1].total_cmp(&b[1])));
    sorted.dedup();
    if sorted.len() < 3 {
        return sorted;
    }
    let cross = |o: &[f64; 2], a: &[f64; 2], b: &[f64; 2]| {
        (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])
    };
    let mut hull: Vec<[f64; 2]> = Vec::with_capacity(2 * sorted.len());
    for pass in [false, true] {
        let start = hull.len();
        let iter: Box<dyn Iterator<Item = &[f64; 2]>> = if pass {
            Box::new(sorted.iter().rev())
        } else {
            Box::new(sorted.iter())
        };
        for p in iter {
            while hull.len() >= start + 2 {
                let n = hull.len();
                match (hull.get(n - 2), hull.get(n - 1)) {
                    (Some(a), Some(b)) if cross(a, b, p) <= 0.0 => {
                        hull.pop();
                    }
                    _ => break,
                }
            }
            hull.push(*p);
        }
        hull.pop();
    }
    hull
}

/// A convex polygon's edges as outward unit normals and offsets: the signed
/// distance of `x` from edge `i` is `n_i . x - c_i` (positive outside).
#[derive(Debug, Clone)]
pub struct ConvexOutline {
    edges: Vec<[f64; 3]>,
    min: [f64; 2],
    max: [f64; 2],
}

impl ConvexOutline {
    /// The outline of the convex hull of `points`, or `None` if it has no area.
    pub fn new(points: &[[f64; 2]]) -> Option<Self> {
        let hull = convex_hull(points);
        if hull.len() < 3 {
            return None;
        }
        let mut edges = Vec::with_capacity(hull.len());
        let (mut min, mut max) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
        for (i, a) in hull.iter().enumerate() {
            let b = hull.get((i + 1) % hull.len()).unwrap_or(a);
            let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
            let length = dx.hypot(dy);
            if length > 1e-12 {
                let (nx, ny) = (dy / length, -dx / length);
                edges.push([nx, ny, nx * a[0] + ny * a[1]]);
            }
            for axis in 0..2 {
                min[axis] = min[axis].min(a[axis]);
                max[axis] = max[axis].max(a[axis]);
            }
        }
        Some(Self { edges, min, max })
    }

    /// Signed distance (pixels, positive outside) of `(x, y)`: exact inside
    /// and along the edges, a lower bound beyond the corners.
    #[inline]
    pub fn distance(&self, x: f64, y: f64) -> f64 {
        self.edges.iter().fold(f64::NEG_INFINITY, |d, [nx, ny, c]| {
            d.max(nx * x + ny * y - c)
        })
    }
}

/// Coverage of a pixel whose centre is `d` pixels outside an edge.
#[inline]
pub fn coverage(d: f64) -> f64 {
    (0.5 - d).clamp(0.0, 1.0)
}

/// Sub-pixels per side where an outline crosses a pixel.
const EDGE_SUBSAMPLES: usize = 3;

/// Coverage of the pixel centred at `(x, y)` by a convex outline: 0 or 1 away
/// from its edge; on the edge, the mean over 3 x 3 sub-pixels of the ramp
/// scaled to a sub-pixel, which is within about 1 % of the exact area (the
/// ramp over the whole pixel is exact only for edges along the pixel grid,
/// and would move a 2 px mark's centroid by up to 0.04 px).
#[inline]
fn convex_coverage(outline: &ConvexOutline, x: f64, y: f64) -> f64 {
    let d = outline.distance(x, y);
    if d >= 1.0 {
        return 0.0;
    }
    if d <= -1.0 {
        return 1.0;
    }
    let n = EDGE_SUBSAMPLES as f64;
    let mut sum = 0.0;
    for i in 0..EDGE_SUBSAMPLES {
        for j in 0..EDGE_SUBSAMPLES {
            let sx = x + (i as f64 + 0.5) / n - 0.5;
            let sy = y + (j as f64 + 0.5) / n - 0.5;
            sum += coverage(n * outline.distance(sx, sy));
        }
    }
    sum / (n * n)
}

/// Fills the convex outlines of one primitive at the exposure's sub-instants
/// (coverage averaged over them), painting `albedo` at `depth(x, y)`.
pub fn fill_convex(
    buffer: &mut FrameBuffer,
    outlines: &[ConvexOutline],
    albedo: f32,
    depth: impl Fn(usize, usize) -> f32,
) {
    let Some(first) = outlines.first() else {
        return;
    };
    let (mut min, mut max) = (first.min, first.max);
    for o in outlines {
        for axis in 0..2 {
            min[axis] = min[axis].min(o.min[axis]);
            max[axis] = max[axis].max(o.max[axis]);
        }
    }
    let Some([x0, y0, x1, y1]) = buffer.clip(min, max, 1.0) else {
        return;
    };
    let weight = 1.0 / outlines.len() as f64;
    for y in y0..=y1 {
        for x in x0..=x1 {
            let (xf, yf) = (x as f64, y as f64);
            let c: f64 = outlines
                .iter()
                .map(|o| convex_coverage(o, xf, yf))
                .sum::<f64>()
                * weight;
            if c > 0.0 {
                buffer.blend(y * buffer.width + x, c as f32, albedo, depth(x, y));
            }
        }
    }
}

/// One capsule's image at one sub-instant: a round cone from `a` (radius
/// `ra`, depth `za`) to `b`, pixels.
#[derive(Debug, Clone, Copy)]
pub struct CapsuleImage {
    pub a: [f64; 2],
    pub b: [f64; 2],
    pub ra: f64,
    pub rb: f64,
    pub za: f64,
    pub zb: f64,
    /// Radius in metres, for the bulge of its front surface in depth.
    pub radius_m: f64,
}

impl CapsuleImage {
    /// `(signed distance px, depth of the front surface, normalised distance
    /// from the axis)` at `(x, y)`.
    #[inline]
    fn at(&self, x: f64, y: f64) -> (f64, f64, f64) {
        let (dx, dy) = (self.b[0] - self.a[0], self.b[1] - self.a[1]);
        let length2 = dx * dx + dy * dy;
        let s = if length2 > 1e-12 {
            (((x - self.a[0]) * dx + (y - self.a[1]) * dy) / length2).clamp(0.0, 1.0)
        } else {
            0.0
        };
        let (px, py) = (self.a[0] + s * dx, self.a[1] + s * dy);
        let r = self.ra + s * (self.rb - self.ra);
        let off = (x - px).hypot(y - py);
        let rho = (off / r.max(1e-9)).min(1.0);
        let z = self.za + s * (self.zb - self.za) - self.radius_m * (1.0 - rho * rho).sqrt();
        (off - r, z, rho)
    }

    fn bounds(&self) -> ([f64; 2], [f64; 2]) {
        (
            [
                (self.a[0] - self.ra).min(self.b[0] - self.rb),
                (self.a[1] - self.ra).min(self.b[1] - self.rb),
            ],
            [
                (self.a[0] + self.ra).max(self.b[0] + self.rb),
                (self.a[1] + self.ra).max(self.b[1] + self.rb),
            ],
        )
    }
}

/// Fills a capsule seen at the exposure's sub-instants, shaded as a matte
/// cylinder lit from the camera (darker towards its silhouette).
pub fn fill_capsule(buffer: &mut FrameBuffer, images: &[CapsuleImage], albedo: f32) {
    let Some(first) = images.first() else {
        return;
    };
    let (mut min, mut max) = first.bounds();
    for image in images {
        let (lo, hi) = image.bounds();
        for axis in 0..2 {
            min[axis] = min[axis].min(lo[axis]);
            max[axis] = max[axis].max(hi[axis]);
        }
    }
    let Some([x0, y0, x1, y1]) = buffer.clip(min, max, 1.0) else {
        return;
    };
    let weight = 1.0 / images.len() as f64;
    for y in y0..=y1 {
        for x in x0..=x1 {
            let (xf, yf) = (x as f64, y as f64);
            let (mut c, mut shade, mut depth) = (0.0, 0.0, f64::INFINITY);
            for image in images {
                let (d, z, rho) = image.at(xf, yf);
                let ck = coverage(d);
                if ck > 0.0 {
                    c += ck;
                    shade += ck * (0.55 + 0.45 * (1.0 - rho * rho).sqrt());
                    depth = depth.min(z);
                }
            }
            if c > 0.0 {
                let shade = shade / c;
                buffer.blend(
                    y * buffer.width + x,
                    (c * weight) as f32,
                    albedo * shade as f32,
                    depth as f32,
                );
            }
        }
    }
}
