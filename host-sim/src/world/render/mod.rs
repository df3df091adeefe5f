//! The camera's image: each frame of the simulated world rendered as a
//! 256 x 256 8-bit grey image, for the mark detector (`shared::detection`) to
//! be measured against the truth (`host-sim vision-check`, docs/vision.md).
//! The controller still receives the labelled points of
//! [`super::vision`]; nothing here feeds it.
//!
//! - [`lens`]: the projection with the known radial distortion and the
//!   pixel convention (pixel `i`'s centre at coordinate `i`), and each pixel's ray.
//! - [`scene`]: what a frame shows at the start, middle and end of its exposure.
//! - [`surface`]: the disc (texture, rim) and the floor, through every pixel's ray.
//! - [`raster`]: marks, the part and the arm, each over its bounding box with
//!   analytic coverage, motion blur and hidden surfaces.
//! - [`sensor`]: light over the image and in time, shot and read noise, 8 bits.
//! - [`truth`]: where each mark's image truly is and whether it is hidden.
//!
//! Marks are white matte discs (bright round spots); everything else is
//! darker: the disc, the part, the arm and the floor.

pub mod lens;
pub mod raster;
pub mod scene;
pub mod sensor;
pub mod surface;
pub mod truth;

#[cfg(test)]
mod tests;

use anyhow::Result;
use nalgebra::Vector3;
use rand::Rng;

use self::lens::{LensCamera, LensDistortion, RayTable};
use self::raster::{fill_capsule, fill_convex, CapsuleImage, ConvexOutline, FrameBuffer};
use self::scene::{Mark, Scene, END, MID, START};
use crate::scenario::pick::ImageSettings;
use crate::world::camera::PinholeCamera;

pub use scene::{build_scene, FrameState, MarkKind, PartPlacement};

/// Points on a mark's rim: its image is their convex hull (a 48-gon in an
/// ellipse of radius rho px departs from it by at most 0.002 rho px).
const RIM_POINTS: usize = 48;
/// Sub-instants of the exposure per pixel of motion, and at most: marks
/// (whose centroids are measured) and the arm (whose blur only shapes it).
const SUBSTEPS_PER_PX: f64 = 3.0;
const MAX_MARK_SUBSTEPS: usize = 32;
const MAX_ARM_SUBSTEPS: usize = 6;
/// Marks are stickers: nearer the camera than their carrier's surface by
/// this much in the depth test, m.
pub const MARK_DEPTH_BIAS_M: f64 = 0.004;
/// The gripper's marks lie on the top of their bar: a larger margin, m.
pub const EFFECTOR_MARK_DEPTH_BIAS_M: f64 = 0.008;
/// Darkening of the part's sides against its top.
const PART_SIDE_SHADE: f64 = 0.6;

/// One rendered grey frame, row by row, pixel `(u, v)` at `v * width + u`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct GrayFrame {
    pub width: usize,
    pub height: usize,
    pub pixels: Vec<u8>,
}

impl GrayFrame {
    /// The frame as the detector's image.
    pub fn as_image(&self) -> Result<shared::detection::GrayImage<'_>> {
        shared::detection::GrayImage::new(self.width, self.height, self.width, &self.pixels)
            .map_err(|e| anyhow::anyhow!("rendered frame: {e}"))
    }
}

/// The renderer of one camera: its rays, settings and frame buffer.
#[derive(Debug, Clone)]
pub struct Renderer {
    settings: ImageSettings,
    rays: RayTable,
    buffer: FrameBuffer,
}

impl Renderer {
    /// A renderer of `camera` with the lens and image of `settings`.
    pub fn new(camera: &PinholeCamera, settings: &ImageSettings) -> Result<Self> {
        settings.validate()?;
        let lens_camera = LensCamera {
            pinhole: camera.clone(),
            lens: LensDistortion {
                k1: settings.k1,
                k2: settings.k2,
            },
        };
        let rays = RayTable::new(&lens_camera)?;
        let buffer = FrameBuffer::new(rays.width(), rays.height());
        Ok(Self {
            settings: *settings,
            rays,
            buffer,
        })
    }

    /// Follows the camera if it moved (the bump fault).
    pub fn follow(&mut self, camera: &PinholeCamera) -> Result<()> {
        if &self.rays.camera().pinhole != camera {
            *self = Self::new(camera, &self.settings)?;
        }
        Ok(())
    }

    /// The renderer in `slot` made ready for `camera`: built on first use
    /// (the camera is known only once the world runs), rebuilt if it moved.
    pub fn ready<'a>(
        slot: &'a mut Option<Self>,
        camera: &PinholeCamera,
        settings: &ImageSettings,
    ) -> Result<&'a mut Self> {
        match slot {
            Some(renderer) => {
                renderer.follow(camera)?;
                Ok(renderer)
            }
            None => Ok(slot.insert(Self::new(camera, settings)?)),
        }
    }

    pub fn camera(&self) -> &LensCamera {
        self.rays.camera()
    }

    pub fn settings(&self) -> &ImageSettings {
        &self.settings
    }

    /// The reflectance and depth of the last rendered scene.
    pub fn buffer(&self) -> &FrameBuffer {
        &self.buffer
    }

    /// Renders `scene` into the frame buffer (no light, no noise yet).
    pub fn render(&mut self, scene: &Scene) {
        surface::paint_surfaces(&mut self.buffer, &self.rays, scene, &self.settings);
        let mark_albedo = self.settings.mark_reflectance as f32;
        let disc_marks = scene.marks.iter().filter(|m| {
            matches!(
                m.kind,
                MarkKind::DiscCentre | MarkKind::Reference | MarkKind::Distractor(_)
            )
        });
        for mark in disc_marks {
            self.paint_mark(mark, mark_albedo, MARK_DEPTH_BIAS_M);
        }
        self.paint_part(scene);
        let features = scene
            .marks
            .iter()
            .filter(|m| matches!(m.kind, MarkKind::Feature(_)));
        for mark in features {
            self.paint_mark(mark, mark_albedo, MARK_DEPTH_BIAS_M);
        }
        self.paint_arm(scene, mark_albedo);
    }

    /// The grey image of the last rendered scene at its time, with the
    /// settings' noise drawn from `rng`; `noise_free` leaves the noise out.
    pub fn expose(&self, time_s: f64, noise_free: bool, rng: &mut impl Rng, out: &mut GrayFrame) {
        let settings = if noise_free {
            self.settings.noise_free()
        } else {
            self.settings
        };
        out.width = self.buffer.width;
        out.height = self.buffer.height;
        sensor::expose(&self.buffer, &settings, time_s, rng, &mut out.pixels);
    }

    /// Renders and exposes in one step.
    pub fn frame(&mut self, scene: &Scene, noise_free: bool, rng: &mut impl Rng) -> GrayFrame {
        self.render(scene);
        let mut frame = GrayFrame {
            width: 0,
            height: 0,
            pixels: Vec::new(),
        };
        self.expose(scene.time_s, noise_free, rng, &mut frame);
        frame
    }

    /// Sub-instants (fractions of the exposure) for a primitive whose
    /// points move `motion_px` over it: one (the middle) when still.
    fn substeps(motion_px: f64, most: usize) -> Vec<Option<f64>> {
        let count = ((motion_px * SUBSTEPS_PER_PX).ceil() as usize).clamp(1, most);
        if count == 1 {
            return vec![None];
        }
        (0..count)
            .map(|k| Some((k as f64 + 0.5) / count as f64))
            .collect()
    }

    /// Largest image motion of `start` points to `end` points, px.
    fn motion_px(&self, start: &[Vector3<f64>], end: &[Vector3<f64>]) -> f64 {
        let camera = self.rays.camera();
        start
            .iter()
            .zip(end)
            .filter_map(|(a, b)| {
                let (pa, pb) = (camera.project(a)?, camera.project(b)?);
                Some((pa[0] - pb[0]).hypot(pa[1] - pb[1]))
            })
            .fold(0.0, f64::max)
    }

    /// The image outline of `points`, or `None` if any is behind the camera.
    fn outline(&self, points: &[Vector3<f64>]) -> Option<ConvexOutline> {
        let camera = self.rays.camera();
        let pixels: Option<Vec<[f64; 2]>> = points.iter().map(|p| camera.project(p)).collect();
        ConvexOutline::new(&pixels?)
    }

    fn paint_mark(&mut self, mark: &Mark, albedo: f32, bias_m: f64) {
        // A sticker seen from behind is hidden by what carries it.
        let o = self.rays.camera().pinhole.optical_centre_disc;
        if mark.normal_disc[MID].dot(&(o - mark.centre_disc[MID])) <= 0.0 {
            return;
        }
        let motion = self.motion_px(
            &mark.centre_disc[START..=START],
            &mark.centre_disc[END..=END],
        );
        let outlines: Option<Vec<ConvexOutline>> = Self::substeps(motion, MAX_MARK_SUBSTEPS)
            .into_iter()
            .map(|f| {
                let (centre, normal) = match f {
                    None => (mark.centre_disc[MID], mark.normal_disc[MID]),
                    Some(f) => (
                        mark.centre_disc[START].lerp(&mark.centre_disc[END], f),
                        mark.normal_disc[START].lerp(&mark.normal_disc[END], f),
                    ),
                };
                self.outline(&mark.rim_at(&centre, &normal, RIM_POINTS))
            })
            .collect();
        let Some(outlines) = outlines else {
            return;
        };
        let Some((_, fallback)) = self
            .rays
            .camera()
            .project_with_depth(&mark.centre_disc[MID])
        else {
            return;
        };
        let depth = plane_depth(
            &self.rays,
            &mark.centre_disc[MID],
            &mark.normal_disc[MID],
            fallback,
        );
        fill_convex(&mut self.buffer, &outlines, albedo, |u, v| {
            (depth(u, v) - bias_m) as f32
        });
    }

    fn paint_part(&mut self, scene: &Scene) {
        let Some(part) = &scene.part else {
            return;
        };
        let motion = self.motion_px(&part.top_disc[START], &part.top_disc[END]);
        let steps = Self::substeps(motion, MAX_ARM_SUBSTEPS);
        let at = |points: &[Vec<Vector3<f64>>; 3], f: Option<f64>| -> Vec<Vector3<f64>> {
            match f {
                None => points[MID].clone(),
                Some(f) => points[START]
                    .iter()
                    .zip(&points[END])
                    .map(|(a, b)| a.lerp(b, f))
                    .collect(),
            }
        };
        let sides: Option<Vec<ConvexOutline>> = steps
            .iter()
            .map(|&f| {
                let mut all = at(&part.top_disc, f);
                all.extend(at(&part.bottom_disc, f));
                self.outline(&all)
            })
            .collect();
        let tops: Option<Vec<ConvexOutline>> = steps
            .iter()
            .map(|&f| self.outline(&at(&part.top_disc, f)))
            .collect();
        let (Some(sides), Some(tops)) = (sides, tops) else {
            return;
        };
        let centre = part.top_disc[MID]
            .iter()
            .fold(Vector3::zeros(), |s, p| s + p)
            / part.top_disc[MID].len().max(1) as f64;
        let Some((_, fallback)) = self.rays.camera().project_with_depth(&centre) else {
            return;
        };
        let top_albedo = self.settings.part_reflectance;
        let depth = plane_depth(&self.rays, &centre, &part.up_disc, fallback);
        // The sides lie below the top: a little further than its plane.
        let side_albedo = (top_albedo * PART_SIDE_SHADE) as f32;
        fill_convex(&mut self.buffer, &sides, side_albedo, |u, v| {
            (depth(u, v) + 0.005) as f32
        });
        fill_convex(&mut self.buffer, &tops, top_albedo as f32, |u, v| {
            depth(u, v) as f32
        });
    }

    fn capsule_images(&self, capsule: &scene::Capsule) -> Option<Vec<CapsuleImage>> {
        let camera = self.rays.camera();
        let f_px = camera.pinhole.intrinsics.f_px;
        let [[a0, b0], [a1, b1]] = &capsule.ends_disc;
        let motion = self.motion_px(&[*a0, *b0], &[*a1, *b1]);
        Self::substeps(motion, MAX_ARM_SUBSTEPS)
            .into_iter()
            .map(|f| {
                let f = f.unwrap_or(0.5);
                let (a, b) = (a0.lerp(a1, f), b0.lerp(b1, f));
                let (pa, za) = camera.project_with_depth(&a)?;
                let (pb, zb) = camera.project_with_depth(&b)?;
                Some(CapsuleImage {
                    a: pa,
                    b: pb,
                    ra: f_px * capsule.radius_m / za,
                    rb: f_px * capsule.radius_m / zb,
                    za,
                    zb,
                    radius_m: capsule.radius_m,
                })
            })
            .collect()
    }

    fn paint_arm(&mut self, scene: &Scene, mark_albedo: f32) {
        let camera = self.rays.camera().clone();
        let depth_of = |p: &Vector3<f64>| camera.camera_from_disc(p).z;
        // Far to near, so that partial coverage at edges blends the right way round.
        let mut order: Vec<(f64, &scene::Capsule)> = scene
            .arm
            .iter()
            .map(|c| {
                let [a, b] = &c.ends_disc[0];
                (0.5 * (depth_of(a) + depth_of(b)), c)
            })
            .collect();
        order.sort_by(|x, y| y.0.total_cmp(&x.0));
        let albedo = self.settings.arm_reflectance as f32;
        let backing = self.settings.mark_backing_reflectance as f32;
        for (_, capsule) in order {
            if let Some(images) = self.capsule_images(capsule) {
                let albedo = if capsule.carries_marks {
                    backing
                } else {
                    albedo
                };
                fill_capsule(&mut self.buffer, &images, albedo);
            }
            if capsule.carries_marks {
                let effector = scene
                    .marks
                    .iter()
                    .filter(|m| matches!(m.kind, MarkKind::Effector(_)));
                for mark in effector {
                    self.paint_mark(mark, mark_albedo, EFFECTOR_MARK_DEPTH_BIAS_M);
                }
            }
        }
    }
}

/// Depth (camera z) at pixel `(u, v)` of the plane through `point` normal to
/// `normal`; `fallback` where the ray runs along it.
fn plane_depth<'a>(
    rays: &'a RayTable,
    point: &Vector3<f64>,
    normal: &Vector3<f64>,
    fallback: f64,
) -> impl Fn(usize, usize) -> f64 + 'a {
    let o = rays.camera().pinhole.optical_centre_disc;
    let numerator = normal.dot(&(point - o));
    let normal = *normal;
    move |u, v| {
        let [dx, dy, dz] = rays.ray(u, v);
        let denominator = normal.x * dx + normal.y * dy + normal.z * dz;
        let t = numerator / denominator;
        if denominator.abs() > 1e-9 && t > 0.0 {
            t
        } else {
            fallback
        }
    }
}
