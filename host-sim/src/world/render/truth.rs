//! Where each mark's image truly is, to score detections against: the
//! projection of its centre (what the controller's labelled points are) and
//! the centroid of its image region, which differ by the perspective bias
//! (the image of a circle's centre is not the centre of its ellipse); and
//! whether it is in view and not hidden, read from the rendered depths.

use nalgebra::Vector3;

use super::scene::{Mark, MarkKind, Scene, MID};
use super::Renderer;

/// Rim points for the image region's centroid.
const CENTROID_RIM_POINTS: usize = 512;
/// A sample of a mark is hidden when something is this much nearer the
/// camera than the mark (beyond the mark's own depth bias), m.
const HIDDEN_MARGIN_M: f64 = 0.01;

/// Where on its radius a mark's rim is sampled for what hides it: inside
/// the rim, so that the sample's pixel is mostly the mark's.
const RIM_SAMPLE_SHARE: f64 = 0.95;

/// Gap between two marks' images below which they count as crowded, px.
pub const CROWDING_GAP_PX: f64 = 3.0;

/// A mark's image at the middle of the exposure.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MarkImage {
    pub kind: MarkKind,
    /// The projection of the mark's centre, px.
    pub centre_px: [f64; 2],
    /// The centroid of the image of its disc (its ellipse, distorted), px.
    pub region_centroid_px: [f64; 2],
    /// Radius of a circle of the same area, px.
    pub radius_px: f64,
    /// Its image region lies inside the image with `margin_px` to spare
    /// (as [`mark_images`] was asked).
    pub in_view: bool,
    /// Faces the camera.
    pub facing: bool,
    /// Share of its samples (centre, a ring at 0.7 of its radius and one by
    /// its rim) that
    /// something nearer hides, 0 to 1.
    pub hidden_fraction: f64,
    /// Another mark's image comes within [`CROWDING_GAP_PX`] of this one's:
    /// the detector may see the two as one blob.
    pub crowded: bool,
}

impl MarkImage {
    /// In view, facing the camera, nothing in front of it and no other mark
    /// touching it: the detector should find it, alone.
    pub fn visible(&self) -> bool {
        self.in_view && self.facing && self.hidden_fraction == 0.0 && !self.crowded
    }

    /// Facing the camera and not wholly hidden: something of it may show.
    pub fn shows(&self) -> bool {
        self.facing && self.hidden_fraction < 1.0
    }

    /// Perspective bias: region centroid minus projected centre, px.
    pub fn perspective_bias_px(&self) -> [f64; 2] {
        [
            self.region_centroid_px[0] - self.centre_px[0],
            self.region_centroid_px[1] - self.centre_px[1],
        ]
    }
}

/// Area centroid and area of a closed polygon.
pub fn polygon_centroid(points: &[[f64; 2]]) -> Option<([f64; 2], f64)> {
    let n = points.len();
    let (mut a, mut cx, mut cy) = (0.0, 0.0, 0.0);
    let origin = *points.first()?;
    for i in 0..n {
        let (Some(p), Some(q)) = (points.get(i), points.get((i + 1) % n)) else {
            continue;
        };
        let (px, py) = (p[0] - origin[0], p[1] - origin[1]);
        let (qx, qy) = (q[0] - origin[0], q[1] - origin[1]);
        let cross = px * qy - qx * py;
        a += cross;
        cx += (px + qx) * cross;
        cy += (py + qy) * cross;
    }
    (a.abs() > 1e-12).then(|| {
        (
            [origin[0] + cx / (3.0 * a), origin[1] + cy / (3.0 * a)],
            0.5 * a.abs(),
        )
    })
}

fn mark_image(renderer: &Renderer, mark: &Mark, margin_px: f64) -> Option<MarkImage> {
    let camera = renderer.camera();
    let centre = mark.centre_disc[MID];
    let normal = mark.normal_disc[MID];
    let (centre_px, centre_depth) = camera.project_with_depth(&centre)?;
    let rim: Option<Vec<[f64; 2]>> = mark
        .rim(MID, CENTROID_RIM_POINTS)
        .iter()
        .map(|p| camera.project(p))
        .collect();
    let rim = rim?;
    let (region_centroid_px, area) = polygon_centroid(&rim)?;
    let intrinsics = camera.pinhole.intrinsics;
    let (w, h) = (f64::from(intrinsics.width), f64::from(intrinsics.height));
    let in_view = rim.iter().all(|[u, v]| {
        *u >= -0.5 + margin_px
            && *u <= w - 0.5 - margin_px
            && *v >= -0.5 + margin_px
            && *v <= h - 0.5 - margin_px
    });
    let facing = normal.dot(&(camera.pinhole.optical_centre_disc - centre)) > 0.0;
    let bias = match mark.kind {
        MarkKind::Effector(_) => super::EFFECTOR_MARK_DEPTH_BIAS_M,
        _ => super::MARK_DEPTH_BIAS_M,
    };
    let buffer = renderer.buffer();
    let (e1, e2) = super::scene::plane_basis(&normal);
    // The centre, a ring inside and one on the rim: an arm edge that cuts
    // off a mark's rim moves its centroid by tenths of a pixel.
    let ring = |count: u32, share: f64| {
        (0..count).map(move |i| {
            let a = std::f64::consts::TAU * f64::from(i) / f64::from(count);
            centre + (e1 * a.cos() + e2 * a.sin()) * (share * mark.radius_m)
        })
    };
    let samples: Vec<Vector3<f64>> = std::iter::once(centre)
        .chain(ring(8, 0.7))
        .chain(ring(24, RIM_SAMPLE_SHARE))
        .collect();
    let hidden = samples
        .iter()
        .filter(|p| {
            let Some(([u, v], depth)) = camera.project_with_depth(p) else {
                return true;
            };
            let (x, y) = (u.round(), v.round());
            if x < 0.0 || y < 0.0 || x >= w || y >= h {
                return false;
            }
            let seen = buffer
                .depth
                .get(y as usize * buffer.width + x as usize)
                .copied()
                .map_or(f64::INFINITY, f64::from);
            seen < depth - bias - HIDDEN_MARGIN_M
        })
        .count();
    let _ = centre_depth;
    Some(MarkImage {
        kind: mark.kind,
        centre_px,
        region_centroid_px,
        radius_px: (area / std::f64::consts::PI).sqrt(),
        in_view,
        facing,
        hidden_fraction: hidden as f64 / samples.len() as f64,
        crowded: false,
    })
}

/// The images of the marks of `scene`, which `renderer` has just rendered
/// (its depths tell what is hidden); `in_view` asks for `margin_px` from the
/// image border. Marks behind the camera are left out.
pub fn mark_images(renderer: &Renderer, scene: &Scene, margin_px: f64) -> Vec<MarkImage> {
    let mut images: Vec<MarkImage> = scene
        .marks
        .iter()
        .filter_map(|mark| mark_image(renderer, mark, margin_px))
        .collect();
    let crowded: Vec<bool> = images
        .iter()
        .enumerate()
        .map(|(i, a)| {
            images.iter().enumerate().any(|(j, b)| {
                i != j
                    && b.shows()
                    && (a.centre_px[0] - b.centre_px[0]).hypot(a.centre_px[1] - b.centre_px[1])
                        < a.radius_px + b.radius_px + CROWDING_GAP_PX
            })
        })
        .collect();
    for (image, crowded) in images.iter_mut().zip(crowded) {
        image.crowded = crowded;
    }
    images
}
