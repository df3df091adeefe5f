//! Compact records of what the calibrator keeps per frame: pixels in f32 (a 256x256
//! image needs no more than ~1e-5 px resolution), angles and metres of the robot in the
//! precision they need.

use nalgebra::{Vector2, Vector3};

use crate::observation::{EffectorSighting, PixelPoint, EFFECTOR_POINTS};

/// A pixel stored in single precision.
pub type PixelF32 = [f32; 2];

/// A contract pixel in the store's single precision.
pub fn to_f32(pixel: PixelPoint) -> PixelF32 {
    let [u, v] = pixel;
    [u as f32, v as f32]
}

/// A stored pixel as an `f64` vector.
pub fn to_vector(pixel: PixelF32) -> Vector2<f64> {
    let [u, v] = pixel;
    Vector2::new(f64::from(u), f64::from(v))
}

/// One frame's detections of the disc centre, the reference point and the part, as the
/// calibrator reads them back from its [`super::frame_store::FrameStore`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FrameRecord<'a> {
    /// Conveyor angle theta (f64: it is unwrapped and may grow large).
    pub theta: f64,
    /// The disc centre's image, if detected.
    pub centre: Option<PixelF32>,
    /// The reference mark's image, if detected.
    pub reference: Option<PixelF32>,
    /// The part's features, exactly `part_feature_count` of them.
    pub part: Option<&'a [PixelF32]>,
}

/// One sighting of the two end-effector points: images and base-frame positions.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EffectorRecord {
    /// The two points' images.
    pub px: [PixelF32; EFFECTOR_POINTS],
    /// Their base-frame positions, m.
    pub base_m: [[f32; 3]; EFFECTOR_POINTS],
}

impl EffectorRecord {
    /// A sighting in the store's precision.
    pub fn from_sighting(sighting: &EffectorSighting) -> Self {
        let [p0, p1] = sighting.px;
        let [b0, b1] = sighting.base_m;
        let base = |b: [f64; 3]| {
            let [x, y, z] = b;
            [x as f32, y as f32, z as f32]
        };
        Self {
            px: [to_f32(p0), to_f32(p1)],
            base_m: [base(b0), base(b1)],
        }
    }

    /// Point `which`'s base-frame position (0 or 1; 1 for any other).
    pub fn base_point(&self, which: usize) -> Vector3<f64> {
        let [b0, b1] = self.base_m;
        let [x, y, z] = if which == 0 { b0 } else { b1 };
        Vector3::new(f64::from(x), f64::from(y), f64::from(z))
    }

    /// Point `which`'s image (0 or 1; 1 for any other).
    pub fn pixel(&self, which: usize) -> Vector2<f64> {
        let [p0, p1] = self.px;
        to_vector(if which == 0 { p0 } else { p1 })
    }
}
