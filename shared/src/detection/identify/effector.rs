//! The gripper's two marks: which blob is which, from what the controller
//! knows and never from the truth: the marks' sizes (unlike: the light of
//! mark 0's image is `(d0 / d1)^2` times mark 1's at any height, for the two
//! lie level when the gripper points down), their base-frame centres latched
//! with every frame (joint encoders and kinematics), and the camera's
//! projection of base-frame points once it is fitted ([`super::projection`]).
//!
//! Two stages:
//! 1. **Pairs**, before the projection is known (and only once the disc is,
//!    so that disc marks are told from the rest): a frame with exactly two
//!    free blobs (no disc mark's, not ambiguous, [`CLEAR_PX`] from every
//!    other blob) whose light differs by the marks' ratio is a pair: the
//!    brighter is mark 0. Each blob's light against a disc mark of its size
//!    at the pair's scale (the yardstick) must be a whole mark's (a half
//!    hidden mark 0 would pass the ratio the other way round). The pair is
//!    placed on the level plane the marks lie in (the gripper points down):
//!    each mark where its ray meets a plane of the normal the disc's image
//!    gives ([`level_normals`]; the disc is level too, and its fitted image
//!    gives the camera's tilt), at the distance that puts them their
//!    base-frame separation apart. An affine image leaves two normals, so
//!    each pair is read under both. Its *signature* is the marks' direction
//!    within the plane less their base-frame direction (constant: the
//!    plane's axes are the base's turned about the vertical) and their
//!    separation as seen square on against the square root of their light
//!    (constant: both scale alike with distance). Labels are given only
//!    once a pair agrees with an earlier one from `CONFIRM_MOVE_M` away
//!    that moved rigidly (its midpoint moved in the camera frame as far as
//!    in the base frame), under the same normal; then only to pairs that
//!    agree with that signature and moved rigidly from it and from the
//!    last, under the same normal; each feeds the projection. (Taken as if the camera looked
//!    square at the plane, the depth from the separation was off by up to
//!    `1 / cos(tilt)` with the pair's direction, and a pair turning with
//!    the waist under a tilted camera seldom moved rigidly.)
//! 2. **Projection**, once it holds `MIN_PROJECTION_POINTS` and explains
//!    them: mark `k` is the one blob (of all) in the gate around its
//!    projection, free, [`CLEAR_PX`] from every other blob, of mark `k`'s
//!    light and not the other's (against the square of the projected
//!    separation, which scales like it with distance), and it moved since
//!    the frame before, from the one blob in the gate then, as the
//!    projection did (a blob that appears where a hidden mark should be is
//!    refused).
//!
//! Anything else leaves the mark unlabelled: a dropped point costs a frame,
//! a wrong one would corrupt the base's calibration.

use heapless::Vec;

use super::lens::LensModel;
use super::projection::BaseProjection;
use super::{LabelledPoint, MarkLabel};
use crate::detection::MAX_BLOBS;
use crate::observation::PixelPoint;

/// The gate around a mark's projection, px.
pub const GATE_PX: f64 = 2.5;
/// No other blob within this of a labelled mark's blob, px (a mark beside
/// another is crowded: its blob may be displaced or merged).
pub const CLEAR_PX: f64 = 5.0;
/// The projection's largest RMS to be trusted, px.
const PROJECTION_RMS_PX: f64 = 1.0;
/// The light ratio of the two marks may be off by this factor (light falls
/// off across the image, blur spreads the small mark's rim).
const RATIO_TOLERANCE: f64 = 1.5;
/// Two whole marks send lights whose ratio, against the marks' areas' ratio,
/// lies in this band; a mark the forearm or the gripper's body partly hides
/// sends less, and its blob's centre moves away from the hidden side.
/// Measured on the pair labels of 60 cells of seed 10 through images (540
/// pairs), against the truth: at ratios 0.95 to 1.25 mark 0's error along
/// the pair averages 0.002 to 0.021 px; below 0.9 it is 0.25 to 0.76 px
/// (mark 0 partly hidden), above 1.3 mark 1's is 0.09 to 0.51 px. Seven
/// such sightings in ten put cell 369's base 32 mm off. Whole marks measure
/// above 1 mostly: blur and the threshold take more of the small mark's rim.
const WHOLE_LIGHT_BAND: (f64, f64) = (0.92, 1.28);
/// Signatures agree within these: angle, rad; separation against light, share.
const SIGNATURE_ANGLE_RAD: f64 = 0.15;
const SIGNATURE_SCALE_SHARE: f64 = 0.2;
/// Unconfirmed signatures kept.
const SIGNATURE_CANDIDATES: usize = 4;
/// A mark's light against the square of the projected separation may be
/// this factor off its running mean.
const LIGHT_TOLERANCE: f64 = 1.3;
/// Weight of a new sighting in the running means.
const MEAN_WEIGHT: f64 = 0.1;
/// A gripper mark's light against a disc mark's of its size at its scale
/// (the gain) must lie in this band. Measured on the rendered picks of
/// seeds 1 and 2: 0.6 to 1.3 for whole marks (blur takes more of a small
/// mark's contrast than the dark backing adds); a pair whose mark 0 is half
/// hidden, which the light ratio would take the other way round, has both
/// gains below 0.5.
const GAIN_MIN: f64 = 0.55;
const GAIN_MAX: f64 = 2.0;
/// The base-frame marks must lie this far apart, m (the gripper's drawing).
const MIN_BASE_SEPARATION_M: f64 = 0.02;
/// The pair stage takes no pair while either mark is expected (where
/// [`EffectorMarks::rough_px`] puts it, distorted) within this of the
/// image's edge, px: the mark may be out of view and something else in its
/// place. Images seed 11, cell 873: the gripper's mark 1 had left the image
/// at its top while the arm carried the part off, and the part's feature 0,
/// riding rigidly with the gripper 2 px inside the edge where the mark was
/// expected, made a pair with mark 0 that agreed with the signature and
/// moved rigidly: labelled mark 1 in two frames. The rough place is a few
/// pixels off where the projection was not fitted, a mark's blob 2 to 4 px
/// in radius.
pub const EDGE_MARGIN_PX: f64 = 6.0;

/// Two pairs confirm a signature only when the gripper moved this much
/// between them, m (a wrong pair seen twice in one place would agree with
/// itself).
const CONFIRM_MOVE_M: f64 = 0.05;
/// A confirmed signature whose anchoring pairs no later pair moves rigidly
/// from is confirmed afresh by a pair that this many earlier refused pairs
/// (agreeing with it) moved rigidly to: three pairs, where the first
/// confirmation takes two.
const RECONFIRM_PAIRS: usize = 2;
/// Two pairs' midpoints, placed in the camera frame at the depth their
/// separation gives, must lie as far apart as their base-frame midpoints
/// (a rigid motion keeps distances) within this plus [`RIGID_SHARE`] of it, m.
const RIGID_M: f64 = 0.05;
const RIGID_SHARE: f64 = 0.1;
/// A mark's blob must have moved since the frame before as its projection
/// did, within this, px.
const MOTION_PX: f64 = 1.5;
/// A mark within this of where it was seen is where its blob was, m.
const REST_M: f64 = 0.002;
/// The projection labels on its own once it holds this many points.
const MIN_PROJECTION_POINTS: usize = 20;
/// A mark the projection labels lies within this many of the projection's
/// RMS residuals (when the DLT was last solved) of where it predicts the
/// mark, and at most [`RESIDUAL_FLOOR_PX`] beyond: a mark the arm partly
/// hides is read off its centre by a few tenths of a pixel, which its
/// light (within 30 % of its running mean) does not show. Images seed 11: in the cells with the
/// largest part errors, mark 0 read 0.3 to 0.4 px off for frames on end
/// while the arm rested, and the base came 3.5 to 6 mm off, 9 to 16 times
/// its sigma. With this gate the part's error at the grasp over the 1,000
/// cells fell from 2.24 to 2.09 mm at the 95th percentile (4 sigmas and
/// 0.15 px: 2.13 mm, more labels lost).
const RESIDUAL_SIGMAS: f64 = 5.0;
const RESIDUAL_FLOOR_PX: f64 = 0.25;

/// A pair read under one hypothesis of the level plane's normal
/// ([`level_normals`]): the marks placed on the plane through their rays.
#[derive(Debug, Clone, Copy, PartialEq)]
struct View {
    /// The marks' direction within the plane less their base-frame
    /// direction, rad (constant: the plane's axes are the base's turned
    /// about the vertical).
    angle_rad: f64,
    /// The separation the marks would show square to the camera at their
    /// distance, over the square root of their light with the incidence
    /// undone (constant: both scale alike with the distance).
    scale: f64,
    /// The marks' midpoint in the camera frame (the plane's distance is
    /// the one that puts them their base-frame separation apart), m.
    camera_m: [f64; 3],
}

/// A pair's signature and where it was.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Signature {
    /// The pair under each hypothesis of the plane's normal.
    views: [Option<View>; 2],
    /// The marks' midpoint in the base frame, m.
    base_m: [f64; 3],
}

impl Signature {
    /// Under which hypotheses the two are the same camera and marks (the
    /// same angle and scale), and under which the gripper moved between
    /// them as a rigid body would be seen.
    fn compare(&self, other: &Signature) -> ([bool; 2], [bool; 2]) {
        let moved = distance3(self.base_m, other.base_m);
        let mut agree = [false; 2];
        let mut rigid = [false; 2];
        for k in 0..2 {
            let (Some(Some(a)), Some(Some(b))) = (self.views.get(k), other.views.get(k)) else {
                continue;
            };
            let d = libm::remainder(a.angle_rad - b.angle_rad, core::f64::consts::TAU);
            let same = d.abs() <= SIGNATURE_ANGLE_RAD
                && (a.scale - b.scale).abs() <= SIGNATURE_SCALE_SHARE * b.scale;
            let apart = distance3(a.camera_m, b.camera_m);
            if let (Some(a), Some(r)) = (agree.get_mut(k), rigid.get_mut(k)) {
                *a = same;
                *r = (apart - moved).abs() <= RIGID_M + RIGID_SHARE * moved;
            }
        }
        (agree, rigid)
    }
}

/// One frame's blob as the effector stage sees it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EffectorCandidate {
    /// Pinhole pixel.
    pub pixel: PixelPoint,
    /// Flux (area times mean contrast).
    pub flux: f64,
    /// No disc mark's, not ambiguous: it may be a gripper mark.
    pub free: bool,
    /// Its track, however young, has held still in the disc's rotating
    /// frame while the disc turned: a disc object (a feature, a distractor)
    /// not yet known as one. The pair stage does not take it (a gripper
    /// riding with the part, which the projection labels, would pass).
    pub with_disc: bool,
    /// Its coverage is not lopsided (see [`whole_mark`]): nothing in front
    /// cuts it. A cut mark still tells the pair apart, but is not labelled.
    pub whole: bool,
}

/// A mark's blob of at least this many pixels is judged against
/// [`MAX_LOPSIDEDNESS`]; a smaller one's skewness is noisier (images seed
/// 11, cells 35, 205, 370 and 867: whole marks of 10 to 19 px reach 0.36
/// at the 99th percentile, of 20 to 39 px 0.10 to 0.14).
pub const JUDGED_AREA_PX: u32 = 20;
/// A judged blob more lopsided than this is a mark that something in front
/// cuts. In those cells the forearm hid the rim of gripper mark 0 in a
/// third of its sightings, for frames on end while the arm rested; those
/// blobs read 0.3 to 0.8 px off the mark's centre, and put the base 3.5 to
/// 6 mm off at 9 to 16 times its sigma. Mark 0's blobs above 0.15 read
/// 0.39 px RMS off its centre, the rest 0.064 px.
pub const MAX_LOPSIDEDNESS: f32 = 0.15;
/// Blobs from this many pixels up to [`JUDGED_AREA_PX`] are judged
/// against [`SMALL_MAX_LOPSIDEDNESS`]; smaller ones are not judged.
pub const SMALL_JUDGED_AREA_PX: u32 = 15;
/// The looser limit for blobs of 15 to 19 px: a cut mark 0 shrinks to
/// that size (images seed 11, cell 563: 16 to 19 px at 0.2 to 0.42, read
/// 0.2 to 0.34 px off), while whole gripper marks of that size stay below
/// 0.2 in nine of ten (mark 1 there: 0.06 px RMS off whatever its
/// lopsidedness).
pub const SMALL_MAX_LOPSIDEDNESS: f32 = 0.2;

/// Whether a blob of `area_px` pixels and `lopsidedness` (the detector's
/// whitened skewness) may be taken for a whole mark.
pub fn whole_mark(area_px: u32, lopsidedness: f32) -> bool {
    if area_px >= JUDGED_AREA_PX {
        lopsidedness <= MAX_LOPSIDEDNESS
    } else if area_px >= SMALL_JUDGED_AREA_PX {
        lopsidedness <= SMALL_MAX_LOPSIDEDNESS
    } else {
        true
    }
}

/// The effector stage's state over a run.
#[derive(Debug, Clone)]
pub struct EffectorMarks {
    /// `(d0 / d1)^2`: mark 0's light over mark 1's.
    light_ratio: f64,
    /// Each mark's diameter over the reference mark's, squared.
    area_over_reference: [f64; 2],
    /// The pinhole camera's principal point and focal length, px.
    centre: PixelPoint,
    f_px: f64,
    projection: BaseProjection,
    /// Undoes the camera's tilt on image vectors of a level plane (see
    /// [`level_unwarp`]): the identity until the disc is seen.
    unwarp: [[f64; 2]; 2],
    /// The level plane's normal towards the camera, camera frame: the two
    /// the disc's image allows ([`level_normals`]); straight at the camera
    /// until the disc is seen.
    normals: [Option<[f64; 3]>; 2],
    /// The confirmed signature and the last pair that agreed with it.
    signature: Option<(Signature, Signature)>,
    unconfirmed: Vec<Signature, SIGNATURE_CANDIDATES>,
    /// Each mark's light over the square of the marks' image separation (running mean).
    light: [Option<f64>; 2],
    /// Each mark's projection in the frame before (the projection's stage).
    previous_px: [Option<PixelPoint>; 2],
    /// The one blob in each mark's gate in the frame before, if one was.
    previous_blob_px: [Option<PixelPoint>; 2],
    /// Why each mark went unlabelled in the projection's stage, by reason
    /// (diagnosis: none in gate, two in gate, not free, crowded, not seen
    /// there before, light, outside where the projection was fitted, off
    /// the projection's prediction, cut by an edge in front).
    pub refusals: [[u32; 9]; 2],
    /// The last pair's blobs (mark 0's, mark 1's) and their lights against
    /// the yardstick (diagnosis).
    pub last_pair: Option<([PixelPoint; 2], [f64; 2])>,
    /// The last pair's blobs and the marks' base-frame centres then: while
    /// the arm rests there, its marks are where these blobs were.
    seen_at: Option<([PixelPoint; 2], [[f64; 3]; 2])>,
    /// The camera's lens and image width and height, px, once told
    /// ([`Self::seeing`]): where a mark is expected near the edge, no pair.
    view: Option<(LensModel, [f64; 2])>,
    /// The last pair's signature (angle, rad; scale) and what became of it
    /// (diagnosis: 0 stored unconfirmed, 1 confirmed, 2 agreed, 3 angle or
    /// scale off the confirmed one, 4 not rigid, 5 confirmed afresh).
    pub last_signature: Option<(f64, f64, u8)>,
}

impl EffectorMarks {
    /// A fresh stage for marks of diameters `diameters_m` under a camera of
    /// focal length `f_px` and principal point `centre`.
    pub fn new(diameters_m: [f64; 2], reference_m: f64, centre: PixelPoint, f_px: f64) -> Self {
        let [d0, d1] = diameters_m;
        let area_over_reference = diameters_m.map(|d| {
            if reference_m > 0.0 {
                (d / reference_m) * (d / reference_m)
            } else {
                f64::NAN
            }
        });
        let light_ratio = if d0 > 0.0 && d1 > 0.0 {
            (d0 / d1) * (d0 / d1)
        } else {
            f64::NAN
        };
        Self {
            light_ratio,
            area_over_reference,
            centre,
            f_px,
            projection: BaseProjection::new(centre, f_px),
            unwarp: IDENTITY,
            normals: SQUARE,
            signature: None,
            unconfirmed: Vec::new(),
            light: [None; 2],
            previous_px: [None; 2],
            previous_blob_px: [None; 2],
            refusals: [[0; 9]; 2],
            last_pair: None,
            seen_at: None,
            last_signature: None,
            view: None,
        }
    }

    /// The stage for a camera of `lens` and an image of `size_px` (width,
    /// height): the pair stage then takes no pair while a mark is expected
    /// within [`EDGE_MARGIN_PX`] of the image's edge.
    pub fn seeing(mut self, lens: LensModel, size_px: [u32; 2]) -> Self {
        self.view = Some((lens, size_px.map(f64::from)));
        self
    }

    /// Each of the pair's blobs (`pair`: mark 0's and mark 1's, index and
    /// pixel) is, of all the frame's blobs, the nearest to where its mark
    /// is roughly expected (`expected`: [`Self::rough_px`]; true where
    /// nothing says).
    /// 30 Hz, images seed 11, cell 4: the gripper over the part it tracked,
    /// mark 1 partly hidden and not free, the part's feature 0 6 px from it
    /// and 6 px from where the mark was expected made the frame's one pair
    /// with mark 0, which agreed with the signature and moved rigidly; mark
    /// 1's own blob lay 0.4 px from where it was expected.
    fn nearest_where_expected(
        blobs: &[Option<EffectorCandidate>],
        expected: &[Option<PixelPoint>; 2],
        pair: [(usize, PixelPoint); 2],
    ) -> bool {
        pair.iter().zip(expected.iter()).all(|((index, pixel), q)| {
            let Some(q) = q else {
                return true;
            };
            let own = distance(*pixel, *q);
            blobs
                .iter()
                .enumerate()
                .filter(|(i, _)| i != index)
                .filter_map(|(_, b)| b.as_ref())
                .all(|b| distance(b.pixel, *q) >= own)
        })
    }

    /// Either mark is expected (`expected`: [`Self::rough_px`]) within
    /// [`EDGE_MARGIN_PX`] of the image's edge, or beyond it (false where
    /// nothing says where it is).
    fn expected_near_edge(&self, expected: &[Option<PixelPoint>; 2]) -> bool {
        let Some((lens, [width, height])) = self.view else {
            return false;
        };
        expected.iter().flatten().any(|p| {
            let [u, v] = lens.distort(*p);
            let inside = u >= EDGE_MARGIN_PX
                && v >= EDGE_MARGIN_PX
                && u <= width - 1.0 - EDGE_MARGIN_PX
                && v <= height - 1.0 - EDGE_MARGIN_PX;
            !inside
        })
    }

    /// Where the projection put the marks in the frame just identified,
    /// once it is trusted (`None` before, or when a mark projects nowhere).
    pub fn projected_px(&self) -> [Option<PixelPoint>; 2] {
        self.previous_px
    }

    /// Where the marks at `base_m` are while the arm rests where a pair of
    /// them was last seen (each mark within [`REST_M`] of its place then).
    pub fn resting_px(&self, base_m: &[[f64; 3]; 2]) -> [Option<PixelPoint>; 2] {
        let Some((pixels, then_m)) = self.seen_at else {
            return [None, None];
        };
        let still = (0..2).all(|k| {
            matches!((base_m.get(k), then_m.get(k)), (Some(a), Some(b)) if distance3(*a, *b) <= REST_M)
        });
        if still {
            pixels.map(Some)
        } else {
            [None, None]
        }
    }

    /// Where the marks at `base_m` lie roughly, where the projection does
    /// not label them: by the projection however far from where it was
    /// fitted (a DLT extrapolates a few pixels off), or before it is
    /// trusted by the level plane's map of the sightings so far (see
    /// [`BaseProjection::plane_px`]). Where a disc label is not to be given.
    pub fn rough_px(&self, base_m: &[[f64; 3]; 2]) -> [Option<PixelPoint>; 2] {
        if self.projection.trusted(PROJECTION_RMS_PX) {
            base_m.map(|p| self.projection.project(p))
        } else {
            base_m.map(|p| self.projection.plane_px(p))
        }
    }

    /// The projection's correspondences and RMS, px (diagnosis).
    pub fn projection_state(&self) -> (usize, f64) {
        (self.projection.len(), self.projection.rms_px())
    }

    /// The disc's image: the reference mark's path `c + a cos(theta) + b
    /// sin(theta)` (`centre_px`, `a_px`, `b_px`), the image of a level
    /// circle. From then on pairs are measured with the tilt undone: their
    /// lights against the yardstick at the scale [`level_unwarp`] gives,
    /// their signature on the plane of each normal [`level_normals`] gives
    /// (kept in the order they had, so that a hypothesis stays itself as
    /// the disc's fit is refined). An image that is no ellipse changes
    /// nothing.
    pub fn see_disc(&mut self, centre_px: PixelPoint, a_px: [f64; 2], b_px: [f64; 2]) {
        if let Some(unwarp) = level_unwarp(a_px, b_px) {
            self.unwarp = unwarp;
        }
        let Some([n0, n1]) = level_normals(self.centre, self.f_px, centre_px, a_px, b_px) else {
            return;
        };
        let near = |a: [f64; 3], b: Option<[f64; 3]>| b.map_or(0.0, |b| dot3(a, b));
        let [p0, p1] = self.normals;
        let swapped = p1.is_some() && near(n0, p1) + near(n1, p0) > near(n0, p0) + near(n1, p1);
        self.normals = if swapped {
            [Some(n1), Some(n0)]
        } else {
            [Some(n0), Some(n1)]
        };
    }

    /// The pair `pixels` (mark 0's, mark 1's) of base-frame centres
    /// `base_m` and light `flux_sum` on the level plane of normal `n`
    /// (towards the camera, camera frame).
    fn view(
        &self,
        n: [f64; 3],
        pixels: [PixelPoint; 2],
        base_m: &[[f64; 3]; 2],
        flux_sum: f64,
    ) -> Option<View> {
        let ray = |p: PixelPoint| {
            [
                (p[0] - self.centre[0]) / self.f_px,
                (p[1] - self.centre[1]) / self.f_px,
                1.0,
            ]
        };
        // Each ray meets the plane n . X = -h at X = h r / (-n . r).
        let [q0, q1] = pixels.map(|p| {
            let r = ray(p);
            let d = -dot3(n, r);
            if d > 1e-6 {
                Some(r.map(|x| x / d))
            } else {
                None
            }
        });
        let (q0, q1) = (q0?, q1?);
        let span = distance3(q0, q1);
        let separation_m = distance3(base_m[0], base_m[1]);
        if !(span > 0.0 && separation_m > 0.0) {
            return None;
        }
        let h = separation_m / span;
        let mid =
            [0, 1, 2].map(|k| h * (q0.get(k).unwrap_or(&0.0) + q1.get(k).unwrap_or(&0.0)) / 2.0);
        let v = [0, 1, 2].map(|k| h * (q1.get(k).unwrap_or(&0.0) - q0.get(k).unwrap_or(&0.0)));
        // The plane's axes: the camera's x laid on it, and the normal's
        // cross with that (right-handed about the normal, which is the
        // base's up: the camera looks down).
        let e1 = {
            let raw = [1.0 - n[0] * n[0], -n[0] * n[1], -n[0] * n[2]];
            let norm = libm::sqrt(dot3(raw, raw));
            if norm.is_nan() || norm <= 0.1 {
                return None;
            }
            raw.map(|x| x / norm)
        };
        let e2 = cross3(n, e1);
        let base = [base_m[1][0] - base_m[0][0], base_m[1][1] - base_m[0][1]];
        let distance = libm::sqrt(dot3(mid, mid));
        let incidence = h / distance;
        if !(distance > 0.0 && incidence > 0.0 && flux_sum > 0.0) {
            return None;
        }
        Some(View {
            angle_rad: libm::atan2(dot3(v, e2), dot3(v, e1)) - libm::atan2(base[1], base[0]),
            scale: (self.f_px * separation_m / distance) / libm::sqrt(flux_sum / incidence),
            camera_m: mid,
        })
    }

    /// Mark 0's light `flux0` against mark 1's `flux1` is two whole marks'
    /// ([`WHOLE_LIGHT_BAND`]).
    fn both_whole(&self, flux0: f64, flux1: f64) -> bool {
        let ratio = flux0 / (flux1 * self.light_ratio);
        ratio >= WHOLE_LIGHT_BAND.0 && ratio <= WHOLE_LIGHT_BAND.1
    }

    /// The two marks are unlike enough to be told apart by their light.
    fn unlike(&self) -> bool {
        self.light_ratio.is_finite() && self.light_ratio >= RATIO_TOLERANCE * RATIO_TOLERANCE
    }

    /// Labels the gripper's marks among `blobs` (index = the frame's blob
    /// index), whose base-frame centres are `base_m`.
    /// `yardstick`: the reference mark's light over the square of the
    /// disc's image scale (px per m), known once the disc is: a mark of the
    /// reference's size at scale `s` sends about `yardstick * s^2`; before,
    /// no pair is taken (nor can what turns with the disc be told).
    pub fn identify(
        &mut self,
        blobs: &[Option<EffectorCandidate>],
        base_m: &[[f64; 3]; 2],
        yardstick: Option<f64>,
    ) -> [Option<LabelledPoint>; 2] {
        self.last_pair = None;
        self.last_signature = None;
        let disc_known = yardstick.is_some_and(|y| y.is_finite() && y > 0.0);
        let usable = base_m.iter().flatten().all(|x| x.is_finite())
            && distance3(base_m[0], base_m[1]) >= MIN_BASE_SEPARATION_M
            && self.unlike()
            && disc_known
            && self.f_px > 0.0;
        if !usable {
            self.previous_px = [None; 2];
            self.previous_blob_px = [None; 2];
            return [None, None];
        }
        let covered = base_m.iter().any(|b| self.projection.covers(*b));
        if self.projection.len() >= MIN_PROJECTION_POINTS
            && self.projection.trusted(PROJECTION_RMS_PX)
            && (covered || self.signature.is_none())
        {
            self.by_projection(blobs, base_m)
        } else {
            // Where the projection was not fitted, pairs that agree with
            // the confirmed signature extend it.
            self.previous_px = [None; 2];
            self.previous_blob_px = [None; 2];
            self.by_pair(blobs, base_m, yardstick.unwrap_or(f64::NAN))
        }
    }

    /// Stage 1: the frame's one pair of free blobs.
    fn by_pair(
        &mut self,
        blobs: &[Option<EffectorCandidate>],
        base_m: &[[f64; 3]; 2],
        yardstick: f64,
    ) -> [Option<LabelledPoint>; 2] {
        let mut free: Vec<usize, MAX_BLOBS> = Vec::new();
        for (i, b) in blobs.iter().enumerate() {
            if b.is_some_and(|b| b.free && !b.with_disc) {
                let _ = free.push(i);
            }
        }
        let [i, j] = free.as_slice() else {
            return [None, None];
        };
        let expected = self.rough_px(base_m);
        if self.expected_near_edge(&expected) {
            return [None, None];
        }
        let (Some(Some(a)), Some(Some(b))) = (blobs.get(*i), blobs.get(*j)) else {
            return [None, None];
        };
        if !clear_of_others(blobs, &[*i, *j], a.pixel)
            || !clear_of_others(blobs, &[*i, *j], b.pixel)
        {
            return [None, None];
        }
        // The brighter is mark 0; its light must be the marks' ratio times the other's.
        let ((i0, m0), (i1, m1)) = if a.flux >= b.flux {
            ((*i, a), (*j, b))
        } else {
            ((*j, b), (*i, a))
        };
        if m1.flux <= 0.0 || !within(m0.flux / m1.flux, self.light_ratio, RATIO_TOLERANCE) {
            return [None, None];
        }
        if !Self::nearest_where_expected(blobs, &expected, [(i0, m0.pixel), (i1, m1.pixel)]) {
            return [None, None];
        }
        if !self.both_whole(m0.flux, m1.flux) {
            return [None, None];
        }
        let raw = [m1.pixel[0] - m0.pixel[0], m1.pixel[1] - m0.pixel[1]];
        // The image vector as a camera square to the level plane would see
        // it: its angle, and its length against the base-frame one, are
        // then the same whichever way the pair points.
        let image = apply(&self.unwarp, raw);
        let separation_px = libm::hypot(image[0], image[1]);
        let base = [base_m[1][0] - base_m[0][0], base_m[1][1] - base_m[0][1]];
        if libm::hypot(base[0], base[1]) < MIN_BASE_SEPARATION_M || separation_px < 1.0 {
            return [None, None];
        }
        // Each mark's light against a disc mark of its size at the pair's scale.
        let scale = separation_px / distance3(base_m[0], base_m[1]);
        let gains = [(0, m0.flux), (1, m1.flux)].map(|(k, flux)| {
            flux / (yardstick
                * scale
                * scale
                * self.area_over_reference.get(k).copied().unwrap_or(f64::NAN))
        });
        self.last_pair = Some(([m0.pixel, m1.pixel], gains));
        self.seen_at = Some(([m0.pixel, m1.pixel], *base_m));
        if !gains.iter().all(|g| (GAIN_MIN..=GAIN_MAX).contains(g)) {
            return [None, None];
        }
        let flux_sum = m0.flux + m1.flux;
        let signature = Signature {
            views: self
                .normals
                .map(|n| n.and_then(|n| self.view(n, [m0.pixel, m1.pixel], base_m, flux_sum))),
            base_m: [
                (base_m[0][0] + base_m[1][0]) / 2.0,
                (base_m[0][1] + base_m[1][1]) / 2.0,
                (base_m[0][2] + base_m[1][2]) / 2.0,
            ],
        };
        let first = signature.views.iter().flatten().next().copied();
        let note = |code: u8| first.map(|v| (v.angle_rad, v.scale, code));
        match self.signature {
            Some((known, last)) => {
                // Under either normal: the pair that confirmed the
                // signature may have held under the wrong one alone (the
                // two differ little over a short move), and held to it
                // every later pair failed (seed 6, cell 250).
                let (agree, rigid) = known.compare(&signature);
                let (_, rigid_since) = last.compare(&signature);
                let (([a0, a1], [r0, r1]), [s0, s1]) = ((agree, rigid), rigid_since);
                let holds = [a0 && r0 && s0, a1 && r1 && s1];
                if !agree.iter().any(|a| *a) {
                    self.last_signature = note(3);
                    return [None, None];
                }
                if holds.iter().any(|h| *h) {
                    self.last_signature = note(2);
                    self.signature = Some((known, signature));
                } else if self.confirmed_by_earlier(&signature, agree) >= RECONFIRM_PAIRS {
                    // The pairs the signature was last held to may be off
                    // themselves (a mark cut by the image's edge reads a
                    // wrong depth), and then no later pair moves rigidly
                    // from them (seed 10, cell 112: every pair of the
                    // search's later sweeps refused). Three pairs since,
                    // that agree with the signature and moved rigidly
                    // between them, confirm it afresh, and it is held to
                    // them from now on.
                    self.last_signature = note(5);
                    self.signature = Some((signature, signature));
                    self.unconfirmed.clear();
                } else {
                    self.remember_unconfirmed(signature);
                    self.last_signature = note(4);
                    return [None, None];
                }
            }
            None => {
                // Confirmed by an earlier pair from elsewhere that agrees.
                let confirmed = self.confirmed_by_earlier(&signature, [true, true]) >= 1;
                if !confirmed {
                    self.remember_unconfirmed(signature);
                    self.last_signature = note(0);
                    return [None, None];
                }
                self.last_signature = note(1);
                self.signature = Some((signature, signature));
                self.unconfirmed.clear();
            }
        }
        // Each mark's light against the image's own separation, as the
        // projection's stage measures it. A mark that something in front
        // cuts is read off its centre: the pair still holds, but that mark
        // is neither learnt nor labelled.
        let separation_sq = raw[0] * raw[0] + raw[1] * raw[1];
        let mut found = [None, None];
        for (k, (index, mark)) in [(i0, m0), (i1, m1)].into_iter().enumerate() {
            let (Some(slot), Some(base)) = (found.get_mut(k), base_m.get(k)) else {
                continue;
            };
            if mark.whole {
                self.learn_light(k, mark.flux / separation_sq);
                self.projection.add(*base, mark.pixel);
                *slot = Some(labelled(k, mark.pixel, index));
            }
        }
        if found.iter().any(Option::is_some) {
            self.projection.refit();
        }
        found
    }

    /// How many earlier unconfirmed pairs at least `CONFIRM_MOVE_M` away
    /// agree with `signature` and moved rigidly to it, under a normal
    /// `under` allows.
    fn confirmed_by_earlier(&self, signature: &Signature, under: [bool; 2]) -> usize {
        self.unconfirmed
            .iter()
            .filter(|s| {
                let (agree, rigid) = s.compare(signature);
                let holds = under
                    .iter()
                    .zip(agree)
                    .zip(rigid)
                    .any(|((u, a), r)| *u && a && r);
                holds && distance3(s.base_m, signature.base_m) >= CONFIRM_MOVE_M
            })
            .count()
    }

    /// Keeps `signature` for a later pair to confirm, the oldest dropped.
    /// The newest kept pair gives way to it while it lies within
    /// [`CONFIRM_MOVE_M`] of the pair kept before that one: pairs a frame
    /// apart from a fast camera are millimetres apart (0.35 m/s at 30 Hz:
    /// 12 mm), and [`SIGNATURE_CANDIDATES`] of them spanned too little of
    /// the gripper's path for any later pair to confirm them (30 Hz,
    /// cells 11000045, 86, 146 and 175: `EffectorNotSeen`). So the kept
    /// pairs span the path whatever the frame rate.
    fn remember_unconfirmed(&mut self, signature: Signature) {
        let kept = self.unconfirmed.len();
        let near_the_one_before = kept >= 2
            && self
                .unconfirmed
                .get(kept - 2)
                .is_some_and(|s| distance3(s.base_m, signature.base_m) < CONFIRM_MOVE_M);
        if near_the_one_before {
            if let Some(newest) = self.unconfirmed.last_mut() {
                *newest = signature;
                return;
            }
        }
        if self.unconfirmed.is_full() {
            self.unconfirmed.remove(0);
        }
        let _ = self.unconfirmed.push(signature);
    }

    fn learn_light(&mut self, k: usize, value: f64) {
        if let Some(slot) = self.light.get_mut(k) {
            *slot = Some(match *slot {
                Some(mean) => mean + MEAN_WEIGHT * (value - mean),
                None => value,
            });
        }
    }

    /// Stage 2: each mark where the projection puts it.
    fn by_projection(
        &mut self,
        blobs: &[Option<EffectorCandidate>],
        base_m: &[[f64; 3]; 2],
    ) -> [Option<LabelledPoint>; 2] {
        let predicted = [
            self.projection.project(base_m[0]),
            self.projection.project(base_m[1]),
        ];
        let previous = self.previous_px;
        let previous_blob = self.previous_blob_px;
        self.previous_px = predicted;
        self.previous_blob_px = [None; 2];
        let [Some(p0), Some(p1)] = predicted else {
            return [None, None];
        };
        let separation_sq = (p1[0] - p0[0]) * (p1[0] - p0[0]) + (p1[1] - p0[1]) * (p1[1] - p0[1]);
        if separation_sq < 1.0 {
            return [None, None];
        }
        let mut found = [None, None];
        for (k, slot) in found.iter_mut().enumerate() {
            let Some(Some(p)) = predicted.get(k) else {
                continue;
            };
            // Every blob in the gate, free or not: exactly one.
            let mut in_gate = blobs
                .iter()
                .enumerate()
                .filter_map(|(i, b)| b.map(|b| (i, b)))
                .filter(|(_, b)| distance(b.pixel, *p) <= GATE_PX);
            let refuse = |r: &mut [[u32; 9]; 2], reason: usize| {
                if let Some(c) = r.get_mut(k).and_then(|r| r.get_mut(reason)) {
                    *c += 1;
                }
            };
            // Only where the projection was fitted (it extrapolates badly).
            if !base_m.get(k).is_some_and(|b| self.projection.covers(*b)) {
                refuse(&mut self.refusals, 6);
                continue;
            }
            let (first, second) = (in_gate.next(), in_gate.next());
            let Some((i, blob)) = first else {
                refuse(&mut self.refusals, 0);
                continue;
            };
            if second.is_some() {
                refuse(&mut self.refusals, 1);
                continue;
            }
            if let Some(slot) = self.previous_blob_px.get_mut(k) {
                *slot = Some(blob.pixel);
            }
            if !blob.free {
                refuse(&mut self.refusals, 2);
                continue;
            }
            if !clear_of_others(blobs, &[i], blob.pixel) {
                refuse(&mut self.refusals, 3);
                continue;
            }
            // The one blob in its gate the frame before too, and moved
            // since as the mark's projection did.
            let moved_alike = match (previous.get(k), previous_blob.get(k)) {
                (Some(Some(before)), Some(Some(then))) => {
                    let image = [blob.pixel[0] - then[0], blob.pixel[1] - then[1]];
                    let mark = [p[0] - before[0], p[1] - before[1]];
                    libm::hypot(image[0] - mark[0], image[1] - mark[1]) <= MOTION_PX
                }
                _ => false,
            };
            if !moved_alike {
                refuse(&mut self.refusals, 4);
                continue;
            }
            let residual_gate =
                (RESIDUAL_SIGMAS * self.projection.solved_rms_px()).max(RESIDUAL_FLOOR_PX);
            if distance(blob.pixel, *p) > residual_gate {
                refuse(&mut self.refusals, 7);
                continue;
            }
            if !blob.whole {
                refuse(&mut self.refusals, 8);
                continue;
            }
            // Its light is this mark's, not the other's.
            let light = blob.flux / separation_sq;
            let (Some(Some(own)), Some(Some(other))) = (self.light.get(k), self.light.get(1 - k))
            else {
                continue;
            };
            let own_off = libm::fabs(libm::log(light / own));
            let other_off = libm::fabs(libm::log(light / other));
            if !within(light, *own, LIGHT_TOLERANCE) || other_off <= own_off {
                refuse(&mut self.refusals, 5);
                continue;
            }
            *slot = Some(labelled(k, blob.pixel, i));
        }
        // Both marks seen: their lights must be two whole marks' (one partly
        // hidden is read off its centre, by up to a pixel).
        let flux = |i: usize| blobs.get(i).copied().flatten().map_or(0.0, |b| b.flux);
        if let [Some(a), Some(b)] = found {
            if !self.both_whole(flux(a.blob), flux(b.blob)) {
                for counts in self.refusals.iter_mut() {
                    if let Some(c) = counts.get_mut(5) {
                        *c += 1;
                    }
                }
                found = [None, None];
            }
        }
        // Each labelled mark refines the projection and its light, unless it spoils the fit.
        let before = self.projection.clone();
        for (k, point) in found.iter().enumerate() {
            if let (Some(point), Some(base)) = (point, base_m.get(k)) {
                self.projection.add(*base, point.pixel);
            }
        }
        if found.iter().any(Option::is_some) {
            self.projection.refit();
            if !self.projection.trusted(PROJECTION_RMS_PX) {
                self.projection = before;
            }
        }
        for (k, point) in found.iter().enumerate() {
            if let Some(point) = point {
                self.learn_light(k, flux(point.blob) / separation_sq);
            }
        }
        found
    }
}

const IDENTITY: [[f64; 2]; 2] = [[1.0, 0.0], [0.0, 1.0]];

/// A camera square to the level plane, looking down its normal.
const SQUARE: [Option<[f64; 3]>; 2] = [Some([0.0, 0.0, -1.0]), None];

fn dot3(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn cross3(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

/// The level plane's unit normal towards the camera, in the camera frame
/// (x right, y down, z along the axis), from the image of a level circle
/// `c + a cos(theta) + b sin(theta)` (pinhole pixels; principal point
/// `centre`, focal length `f_px`): the two that image it alike.
///
/// Near the circle's centre the image moves with a step `s` on the plane
/// (in its axes `E`, 3 x 2, orthonormal) as `J s = (f / Z) K E s`, with
/// `K = [I | -c']` and `c' = (c - centre) / f` (the centre's ray is `(c',
/// 1)`). The fit's `[a b]` is `J` up to a turn within the plane, which the
/// normal does not see. `K` loses only the ray's direction, so `E = lambda
/// K^+ J + r w^T` (`r` the unit ray, `K^+ = K^T (K K^T)^-1`) for a scale
/// `lambda` and a 2-vector `w`; `E^T E = I` reads `lambda^2 Q + w w^T = I`
/// with `Q = J^T (K K^T)^-1 J`, so `lambda^2 = 1 / mu_max` and `w = +-
/// sqrt(1 - mu_min / mu_max) v_min` (`Q`'s eigenpairs): two planes, tilted
/// either way about the ray by the same angle, which the affine image
/// cannot tell apart (they coincide for a camera square to the plane).
/// `None` when the image is no ellipse.
pub fn level_normals(
    centre: PixelPoint,
    f_px: f64,
    circle_centre_px: PixelPoint,
    a_px: [f64; 2],
    b_px: [f64; 2],
) -> Option<[[f64; 3]; 2]> {
    if f_px.is_nan() || f_px <= 0.0 {
        return None;
    }
    let c = [
        (circle_centre_px[0] - centre[0]) / f_px,
        (circle_centre_px[1] - centre[1]) / f_px,
    ];
    let k = 1.0 / (1.0 + c[0] * c[0] + c[1] * c[1]);
    // (K K^T)^-1 = I - c c^T / (1 + |c|^2).
    let inv = [
        [1.0 - k * c[0] * c[0], -k * c[0] * c[1]],
        [-k * c[0] * c[1], 1.0 - k * c[1] * c[1]],
    ];
    let columns = [a_px, b_px].map(|v| [v[0] / f_px, v[1] / f_px]);
    let [ja, jb] = columns;
    let (ia, ib) = (apply(&inv, ja), apply(&inv, jb));
    let q00 = ja[0] * ia[0] + ja[1] * ia[1];
    let q01 = ja[0] * ib[0] + ja[1] * ib[1];
    let q11 = jb[0] * ib[0] + jb[1] * ib[1];
    let half_trace = 0.5 * (q00 + q11);
    let root = libm::sqrt((0.25 * (q00 - q11) * (q00 - q11) + q01 * q01).max(0.0));
    let (mu_max, mu_min) = (half_trace + root, half_trace - root);
    // Thinner than an aspect of 0.05 (a camera looking along the plane):
    // no tilt can be read from it.
    if !(mu_max.is_finite() && mu_min > 0.0025 * mu_max) {
        return None;
    }
    // Q's eigenvector of mu_min (either form; the longer).
    let v1 = [q01, mu_min - q00];
    let v2 = [mu_min - q11, q01];
    let v = if v1[0] * v1[0] + v1[1] * v1[1] >= v2[0] * v2[0] + v2[1] * v2[1] {
        v1
    } else {
        v2
    };
    let v_norm = libm::hypot(v[0], v[1]);
    let v_min = if v_norm > 1e-12 * mu_max {
        [v[0] / v_norm, v[1] / v_norm]
    } else {
        [1.0, 0.0]
    };
    let lambda = 1.0 / libm::sqrt(mu_max);
    let w_size = libm::sqrt((1.0 - mu_min / mu_max).max(0.0));
    let r_size = libm::sqrt(k);
    let ray = [c[0] * r_size, c[1] * r_size, r_size];
    // K^+ J, column by column: (inv j, -c . inv j).
    let lift = |i: [f64; 2]| [i[0], i[1], -(c[0] * i[0] + c[1] * i[1])];
    let (ga, gb) = (lift(ia), lift(ib));
    let normal = |sign: f64| -> Option<[f64; 3]> {
        let w = [sign * w_size * v_min[0], sign * w_size * v_min[1]];
        let e1 = [0, 1, 2].map(|i| {
            lambda * ga.get(i).copied().unwrap_or(0.0) + ray.get(i).copied().unwrap_or(0.0) * w[0]
        });
        let e2 = [0, 1, 2].map(|i| {
            lambda * gb.get(i).copied().unwrap_or(0.0) + ray.get(i).copied().unwrap_or(0.0) * w[1]
        });
        let n = cross3(e1, e2);
        let size = libm::sqrt(dot3(n, n));
        if size.is_nan() || size <= 1e-9 {
            return None;
        }
        // Towards the camera: against the ray.
        let sign = if dot3(n, ray) > 0.0 { -1.0 } else { 1.0 };
        Some(n.map(|x| sign * x / size))
    };
    Some([normal(1.0)?, normal(-1.0)?])
}

/// `m v` for a 2 x 2 matrix given by rows.
fn apply(m: &[[f64; 2]; 2], v: [f64; 2]) -> [f64; 2] {
    [
        m[0][0] * v[0] + m[0][1] * v[1],
        m[1][0] * v[0] + m[1][1] * v[1],
    ]
}

/// The map that undoes a tilted camera's foreshortening of a level plane,
/// from the image of a level circle `c + a cos(theta) + b sin(theta)`.
///
/// Under an affine camera a level plane's vector `d` images as `M d`, with
/// `M = [a b] / r` for a circle of radius `r`. With `M = P Q` (`P = (M
/// M^T)^(1/2)` symmetric, `Q` orthogonal, a mirror for a camera looking
/// down), `P^-1 M = Q`: a vector stretched by `sigma_max P^-1` images the
/// plane as a camera square to it would, at the scale of the ellipse's
/// major axis (which the tilt does not shorten). The stretch is along the
/// ellipse's minor axis, by the inverse of its aspect. Returns `None` when
/// the ellipse is degenerate (no tilt can be read from it).
///
/// Closed form for a 2 x 2 symmetric positive definite `S = M M^T`:
/// `S^(1/2) = (S + sqrt(det S) I) / sqrt(tr S + 2 sqrt(det S))`.
pub fn level_unwarp(a_px: [f64; 2], b_px: [f64; 2]) -> Option<[[f64; 2]; 2]> {
    let s00 = a_px[0] * a_px[0] + b_px[0] * b_px[0];
    let s01 = a_px[0] * a_px[1] + b_px[0] * b_px[1];
    let s11 = a_px[1] * a_px[1] + b_px[1] * b_px[1];
    let root_det = libm::fabs(a_px[0] * b_px[1] - a_px[1] * b_px[0]);
    let trace = s00 + s11;
    // The ellipse's half-axes squared are the eigenvalues of S.
    let spread = libm::sqrt(((s00 - s11) * (s00 - s11) + 4.0 * s01 * s01).max(0.0));
    let major_sq = 0.5 * (trace + spread);
    let norm = libm::sqrt(trace + 2.0 * root_det);
    // An ellipse thinner than this (a camera looking along the plane) says nothing.
    if !(root_det.is_finite() && norm.is_finite() && root_det > 0.05 * major_sq && norm > 0.0) {
        return None;
    }
    // sqrt(S) by rows, then its inverse.
    let (r00, r01, r11) = ((s00 + root_det) / norm, s01 / norm, (s11 + root_det) / norm);
    let det_root = r00 * r11 - r01 * r01;
    if det_root.is_nan() || det_root <= 0.0 {
        return None;
    }
    let major = libm::sqrt(major_sq);
    let k = major / det_root;
    Some([[k * r11, -k * r01], [-k * r01, k * r00]])
}

fn labelled(k: usize, pixel: PixelPoint, blob: usize) -> LabelledPoint {
    LabelledPoint {
        label: MarkLabel::Effector(k as u8),
        pixel,
        blob,
    }
}

fn distance(a: PixelPoint, b: PixelPoint) -> f64 {
    libm::hypot(a[0] - b[0], a[1] - b[1])
}

fn distance3(a: [f64; 3], b: [f64; 3]) -> f64 {
    libm::sqrt(
        (a[0] - b[0]) * (a[0] - b[0])
            + (a[1] - b[1]) * (a[1] - b[1])
            + (a[2] - b[2]) * (a[2] - b[2]),
    )
}

/// No blob but those of `own` lies within [`CLEAR_PX`] of `p`.
fn clear_of_others(blobs: &[Option<EffectorCandidate>], own: &[usize], p: PixelPoint) -> bool {
    !blobs
        .iter()
        .enumerate()
        .any(|(i, b)| !own.contains(&i) && b.is_some_and(|b| distance(b.pixel, p) <= CLEAR_PX))
}

fn within(measured: f64, expected: f64, tolerance: f64) -> bool {
    measured >= expected / tolerance && measured <= expected * tolerance
}
