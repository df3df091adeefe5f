//! Identification: which detected blob is which mark (disc centre, reference
//! mark, part feature `i`, effector mark `i`), from what a front end knows and
//! never from the world's truth: the encoder angle latched at each frame (the
//! disc's marks turn about the disc centre's image in step with `theta`), the
//! marks' sizes (the recording's header), the gripper marks' base-frame
//! centres at each frame (joint encoders and kinematics) and the lens.
//!
//! The steps of one frame ([`Identifier::identify`]):
//! 1. undistort each blob to its pinhole pixel ([`lens`]);
//! 2. follow blobs from frame to frame ([`track`]): each track predicts its
//!    blob at the new angle from the fit of its path against `theta` (or by
//!    moving it linearly with the angle); a blob is taken only when it is the
//!    one blob within the gate of one track and no other track's gate holds
//!    it; two candidates in a gate leave both unlabelled for that frame;
//! 3. the reference mark: the one turning track for which the hypothesis
//!    "this is the reference" (its path's size gives the image scale,
//!    `L` metres) makes its own size the reference mark's, puts every other
//!    turning track inside the disc and leaves at most the part's feature
//!    count of feature-sized tracks; its path gives the disc's image
//!    (`c + A Rz(theta) p` for a point `p` of the rotating frame);
//! 4. the disc centre: the one still track of the centre mark's size at the
//!    reference path's centre;
//! 5. the part's features: the turning tracks of the feature marks' size;
//!    the first time exactly `part_feature_count` of them are seen their
//!    rotating-frame positions are stored in a fixed order (by angle about
//!    the disc centre), later each takes the label of the stored position it
//!    alone is near;
//! 6. the effector marks ([`effector`]): first from pairs of free blobs
//!    (no disc mark's) whose light has the two marks' ratio and whose
//!    geometry agrees with earlier pairs', then from the camera's projection
//!    of base-frame points ([`projection`]) fitted from those pairs; each
//!    mark is the one blob near its projection, of its light, seen there the
//!    frame before, with no other blob near.
//!
//! Anything ambiguous, hidden or unexplained is left unlabelled: a dropped
//! point costs a frame, a wrong label would corrupt the calibration.
//!
//! Working memory: [`Identifier::WORKING_MEMORY_BYTES`] (fixed, no heap).

pub mod effector;
pub mod lens;
pub mod projection;
pub mod track;

use heapless::Vec;

use self::effector::{EffectorCandidate, EffectorMarks};
use self::lens::LensModel;
use self::track::Track;
use super::{Blob, MAX_BLOBS};
use crate::observation::{PixelPoint, MAX_PART_FEATURES};

// The working memory the docs state, held at compile time.
const _: () = assert!(Identifier::WORKING_MEMORY_BYTES <= 32 * 1024);

/// Tracks followed at once.
pub const MAX_TRACKS: usize = 48;
/// Labels one frame can carry: centre, reference, the features, two effector marks.
pub const MAX_LABELS: usize = 2 + MAX_PART_FEATURES + 2;

/// No disc label within this of where the projection beyond where it was
/// fitted, or the level plane's map, puts a gripper mark, px (their own
/// errors, a few pixels, beside a mark's radius).
const ROUGH_VETO_PX: f64 = 6.0;
/// A young track whose last two observations lie this close in the disc's
/// rotating frame, m, after the disc turned at least
/// `WITH_DISC_MIN_TURN_RAD` between them, is a disc object (a gripper mark
/// sweeping past moves centimetres in the rotating frame a frame).
const WITH_DISC_M: f64 = 0.004;
const WITH_DISC_MIN_TURN_RAD: f64 = 0.03;
/// Frames a track survives unseen.
const MAX_MISSES: u32 = 4;
/// The recent fit predicts once it spans this arc, rad, and fits this well, px.
const PREDICT_ARC_RAD: f64 = 0.25;
const PREDICT_RMS_PX: f64 = 0.35;
/// A track is turning with the disc (or still on it) when its recent fit
/// explains it within `DISC_RMS_PX` plus `DISC_RMS_SHARE` of its path's
/// radius (the affine model's departure from perspective grows with it).
const DISC_RMS_PX: f64 = 0.35;
const DISC_RMS_SHARE: f64 = 0.015;

/// The recent fit's largest RMS for a path of `radius_px`.
fn disc_rms_px(radius_px: f64) -> f64 {
    DISC_RMS_PX + DISC_RMS_SHARE * radius_px
}
/// Its path's size is measured over at least this arc, rad.
const MEASURE_ARC_RAD: f64 = 1.2;
/// Fewest observations to call a track turning or still.
const MIN_HITS: u32 = 6;
/// A path smaller than this is still, px; larger than `MIN_TURNING_PX`, turning.
const STILL_PX: f64 = 0.4;
const MIN_TURNING_PX: f64 = 4.0;
/// A mark's measured diameter may be this factor off its header's.
const SIZE_TOLERANCE: f64 = 1.3;
/// A feature's diameter from its flux may be this factor off (the light
/// varies by some 20 % across the image: 10 % in diameter).
const FLUX_SIZE_TOLERANCE: f64 = 1.25;
/// Observations of each feature track before the features' order is stored.
const SETTLED_HITS: u32 = 15;
/// A disc mark's label is given only when its blob lies this close to where
/// its track predicted it, px, and the track was seen the frame before: an
/// effector mark that takes a hidden disc mark's place seldom lands so well.
const OUTPUT_GATE_PX: f64 = 1.0;
/// A followed blob's flux may differ by this factor from its track's mean
/// (the light varies across the image) ...
const FLUX_JUMP: f64 = 1.5;
/// ... and by this factor from the blob it followed in the frame before
/// (the light changes little between frames; noise moves a mark's flux by a
/// few per cent). Another mark in a hidden one's place sends a different
/// light: the gripper's small mark over the disc centre 0.69 of it, the key
/// feature over it 0.63, a feature for the gripper's small mark 0.64 (the
/// 1,000 cells of seed 10 through images gave each such wrong label once
/// under `FLUX_JUMP` alone).
const FLUX_STEP: f64 = 1.25;
/// Turning things lie on the disc: within this factor of its radius.
const DISC_MARGIN: f64 = 1.1;
/// The disc centre's mark lies within this share of the reference path's
/// radius (at least `CENTRE_GATE_MIN_PX`) of that path's centre (the
/// affine model's centre is off the centre's image under perspective).
const CENTRE_GATE_SHARE: f64 = 0.12;
const CENTRE_GATE_MIN_PX: f64 = 3.0;
/// A feature takes a stored position's label within this share of the
/// stored features' least spacing.
const FEATURE_GATE_SHARE: f64 = 0.25;
/// The reference hypothesis asks that the candidate's light over the
/// disc-centre mark's, against the marks' diameters squared, lie nearer
/// the reference's (1) than a part feature's (`(d_f / d_r)^2`), and below
/// this: measured on the rendered picks of seed 2 (6 distractors, tracks
/// followed 6 frames or more), the reference's light over the centre's
/// spans 0.71 to 1.41 (the light falls off across the image), a
/// feature's 0.32 to 0.55 (nominal 0.44), a large distractor's 2.8.
const REFERENCE_LIGHT_MAX: f64 = 1.8;
/// No other turning track within this of the reference, m on the disc,
/// sends light within [`NEIGHBOUR_LIGHT`] of its own: the part's features
/// lie together and alike; the reference has no mark of its size beside it
/// (a feature there sends less than half its light in the same light).
const NEIGHBOUR_M: f64 = 0.15;
const NEIGHBOUR_LIGHT: f64 = 1.5;
/// With a key mark, the key is told from the reference by its neighbours:
/// at least this many marks within [`NEIGHBOUR_M`] send about a plain
/// feature's light against it (`(d_f / d_key)^2` within
/// [`FEATURE_LIKE_LIGHT`], however young their tracks). The key's plain
/// neighbours send 0.63 of its light as measured (0.71 nominal: the
/// threshold trims a small mark's fringe more), beyond
/// [`NEIGHBOUR_LIGHT`]; a reference beside the part has only the key in
/// that band (the plain features send 0.37 to 0.44 of its light). Offline
/// campaign seed 7, trial 148: the key, alone while its neighbours were
/// young, was taken for the reference.
const KEY_NEIGHBOURS: usize = 2;

/// A known disc whose reference has not been seen while the disc turned
/// this far, rad, is forgotten: the reference was wrong (its mark gone
/// with the part) or the disc is to be found again; else a wrong first
/// reference would keep the true one out for the rest of the run.
const REFERENCE_UNSEEN_RAD: f64 = core::f64::consts::TAU;
/// The part's features are alike: a feature's light lies within this
/// factor of the others' (the gripper's smaller mark, following the part
/// before the grasp, turns with the disc too and is about a feature's size
/// by the reference's light, but sends 1.5 to 1.8 times a feature's).
const FEATURE_LIKE_LIGHT: f64 = 1.3;
/// A feature's path turns about the disc's centre: its fit over at least
/// this arc, rad, is centred within the centre's gate.
const FEATURE_CENTRED_ARC_RAD: f64 = 0.6;
/// Which mark a blob is.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum MarkLabel {
    /// The mark at the disc's centre.
    DiscCentre,
    /// The reference mark at `L` from the centre.
    Reference,
    /// Part feature `i` in this run's fixed order.
    PartFeature(u8),
    /// Effector mark `i` (columns `e{i}_base_*` of the recording).
    Effector(u8),
}

/// The marks' diameters, m (the recording's header).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MarkDiameters {
    /// Disc-centre mark.
    pub disc_centre_m: f64,
    /// Reference mark.
    pub reference_m: f64,
    /// Each part feature's mark.
    pub part_feature_m: f64,
    /// Part feature 0's mark when it is larger than the others (the key):
    /// the features are then numbered from it, counter-clockwise seen from
    /// the camera, as the part's drawing numbers them. Without a key the
    /// order is the front end's own (by angle about the disc centre from the
    /// reference), fixed for the run but not the part's.
    pub part_key_m: Option<f64>,
    /// The two effector marks.
    pub effector_m: [f64; 2],
}

/// What identification is told about the cell.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct IdentifySettings {
    /// The camera's intrinsics and lens.
    pub lens: LensModel,
    /// The image's width and height, px.
    pub image_size_px: [u32; 2],
    /// `L`, m.
    pub reference_radius_m: f64,
    /// The disc's radius, m.
    pub disc_radius_m: f64,
    /// Feature marks on the part.
    pub part_feature_count: usize,
    /// The marks' sizes.
    pub diameters: MarkDiameters,
    /// Gate around a track's predicted position, px.
    pub gate_px: f64,
    /// A track seen once, before the disc's image is known, cannot be
    /// predicted: its gate grows by this much per radian the disc turned
    /// (about the largest image radius of a disc point), px per rad.
    pub first_gate_px_per_rad: f64,
}

/// A labelled point: the blob's pinhole pixel.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LabelledPoint {
    /// Which mark.
    pub label: MarkLabel,
    /// Undistorted (pinhole) pixel, as the observation log wants it.
    pub pixel: PixelPoint,
    /// Index of the blob in the frame's detections.
    pub blob: usize,
}

/// What one frame's identification did.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct IdentifyReport {
    /// Blobs in the frame.
    pub blobs: u32,
    /// Blobs given a label.
    pub labelled: u32,
    /// Blobs within the gate of two tracks, or two blobs in one gate.
    pub ambiguous: u32,
    /// Tracks that had to be dropped for want of room.
    pub tracks_full: u32,
    /// Blobs refused to a disc mark's track because they did not move with
    /// the disc (another mark passing where it was predicted).
    pub off_disc_motion: u32,
}

/// The disc's image from the reference mark's path: a rotating-frame point
/// `p` (m) is imaged at `centre + A Rz(theta) p`, `A = [a b] / L`.
#[derive(Debug, Clone, Copy, PartialEq)]
struct DiscImage {
    centre_px: PixelPoint,
    a_px: [f64; 2],
    b_px: [f64; 2],
    /// Path radius, px (RMS of the half-axes).
    radius_px: f64,
    /// Image scale along the path's major axis, px per metre at the disc.
    scale_px_per_m: f64,
    /// Minor over major axis (foreshortening).
    aspect: f64,
}

impl DiscImage {
    /// The rotating-frame point (m) imaged at `pixel` at `theta`.
    fn rotating(&self, pixel: PixelPoint, theta: f64, reference_radius_m: f64) -> Option<[f64; 2]> {
        let [a0, a1] = self.a_px;
        let [b0, b1] = self.b_px;
        let det = a0 * b1 - b0 * a1;
        if det.abs() < 1e-9 {
            return None;
        }
        let dx = pixel[0] - self.centre_px[0];
        let dy = pixel[1] - self.centre_px[1];
        // [a b] w = d, w = Rz(theta) p / L.
        let w0 = (b1 * dx - b0 * dy) / det * reference_radius_m;
        let w1 = (-a1 * dx + a0 * dy) / det * reference_radius_m;
        let (s, c) = libm::sincos(theta);
        Some([c * w0 + s * w1, -s * w0 + c * w1])
    }

    /// The image at `theta` of the rotating-frame point `p` (m).
    fn pixel(&self, p: [f64; 2], theta: f64, reference_radius_m: f64) -> PixelPoint {
        let (s, c) = libm::sincos(theta);
        let w0 = (c * p[0] - s * p[1]) / reference_radius_m;
        let w1 = (s * p[0] + c * p[1]) / reference_radius_m;
        [
            self.centre_px[0] + self.a_px[0] * w0 + self.b_px[0] * w1,
            self.centre_px[1] + self.a_px[1] * w0 + self.b_px[1] * w1,
        ]
    }

    /// A blob's mark diameter, m, from its mean area under this scale.
    fn diameter_m(&self, area_px: f64) -> f64 {
        2.0 * libm::sqrt(area_px / core::f64::consts::PI / self.aspect.max(0.1))
            / self.scale_px_per_m
    }
}

/// The image scale and foreshortening of a path (`[a b]`'s singular values).
fn axes(a: [f64; 2], b: [f64; 2]) -> (f64, f64) {
    // M^T M = [[a.a, a.b], [a.b, b.b]].
    let p = a[0] * a[0] + a[1] * a[1];
    let q = a[0] * b[0] + a[1] * b[1];
    let r = b[0] * b[0] + b[1] * b[1];
    let mean = (p + r) / 2.0;
    let half = libm::hypot((p - r) / 2.0, q);
    (
        libm::sqrt((mean + half).max(0.0)),
        libm::sqrt((mean - half).max(0.0)),
    )
}

/// A followed blob and what it was found to be.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Followed {
    track: Track,
    label: Option<MarkLabel>,
    /// Once taken for an effector mark: never a disc mark.
    on_arm: bool,
    /// Index of this frame's blob, when seen.
    blob: Option<usize>,
    /// This frame's blob lay within [`OUTPUT_GATE_PX`] of the prediction
    /// and the track was seen in the frame before: its label may be given.
    sure: bool,
}

/// Identification's state over a run.
#[derive(Debug, Clone)]
pub struct Identifier {
    settings: IdentifySettings,
    tracks: Vec<Followed, MAX_TRACKS>,
    disc: Option<DiscImage>,
    features_rotating: Vec<[f64; 2], MAX_PART_FEATURES>,
    /// The disc centre's image once found (it does not move): the centre's
    /// label is given only within [`OUTPUT_GATE_PX`] of it (a gripper mark
    /// resting beside the hidden centre would otherwise be followed as it).
    centre_px: Option<PixelPoint>,
    /// The centre mark's flux while it was labelled: a mark taking its place
    /// (the gripper's small mark held over it sends 0.69 of its light, the
    /// key feature 0.63) is not the centre.
    centre_flux: Option<f64>,
    effector: EffectorMarks,
    /// The reference mark's mean flux, the yardstick of the other marks' sizes.
    reference_flux: Option<f64>,
    /// The encoder angle when the reference was last seen.
    reference_seen_theta: Option<f64>,
}

impl Identifier {
    /// Bytes of the identifier's state (all of its working memory).
    pub const WORKING_MEMORY_BYTES: usize = core::mem::size_of::<Self>();

    /// A fresh identifier (a run starts).
    pub fn new(settings: IdentifySettings) -> Self {
        let lens = settings.lens;
        Self {
            settings,
            tracks: Vec::new(),
            disc: None,
            features_rotating: Vec::new(),
            centre_px: None,
            centre_flux: None,
            effector: EffectorMarks::new(
                settings.diameters.effector_m,
                settings.diameters.reference_m,
                [lens.cx, lens.cy],
                lens.f_px,
            )
            .seeing(lens, settings.image_size_px),
            reference_flux: None,
            reference_seen_theta: None,
        }
    }

    /// The tracks followed now with their labels (for pictures and diagnosis).
    pub fn tracks(&self) -> impl Iterator<Item = (&Track, Option<MarkLabel>)> {
        self.tracks.iter().map(|f| (&f.track, f.label))
    }

    /// The disc's image once the reference mark is known: the centre of the
    /// reference path, px, and the image scale at the disc, px per metre.
    pub fn disc_image(&self) -> Option<(PixelPoint, f64)> {
        self.disc.map(|d| (d.centre_px, d.scale_px_per_m))
    }

    /// The base-frame projection's correspondences and RMS, px (diagnosis).
    pub fn projection_state(&self) -> (usize, f64) {
        self.effector.projection_state()
    }

    /// Why the gripper's marks went unlabelled once the projection was
    /// known, per mark (see [`EffectorMarks::refusals`]).
    pub fn effector_refusals(&self) -> [[u32; 9]; 2] {
        self.effector.refusals
    }

    /// This frame's pair's signature and what became of it (diagnosis, see
    /// [`EffectorMarks::last_signature`]).
    pub fn effector_signature(&self) -> Option<(f64, f64, u8)> {
        self.effector.last_signature
    }

    /// Where the gripper's marks at `effector_base_m` lie roughly, where
    /// the projection does not label them (diagnosis; see
    /// [`EffectorMarks::rough_px`]).
    pub fn gripper_rough_px(&self, effector_base_m: &[[f64; 3]; 2]) -> [Option<PixelPoint>; 2] {
        self.effector.rough_px(effector_base_m)
    }

    /// This frame's pair of free blobs, if the pair stage saw one, with
    /// their lights against the yardstick (diagnosis).
    pub fn effector_pair(&self) -> Option<([PixelPoint; 2], [f64; 2])> {
        self.effector.last_pair
    }

    /// Labels the `blobs` of the frame at `theta` (the encoder angle latched
    /// at its trigger), with the effector marks' base-frame centres then,
    /// into `out` (cleared first).
    pub fn identify(
        &mut self,
        theta: f64,
        blobs: &[Blob],
        effector_base_m: &[[f64; 3]; 2],
        out: &mut Vec<LabelledPoint, MAX_LABELS>,
    ) -> IdentifyReport {
        out.clear();
        let mut report = IdentifyReport {
            blobs: blobs.len() as u32,
            ..IdentifyReport::default()
        };
        if !theta.is_finite() {
            return report;
        }
        // 1. Pinhole pixels.
        let mut points: Vec<Option<(PixelPoint, f64, f64)>, MAX_BLOBS> = Vec::new();
        let mut whole: Vec<bool, MAX_BLOBS> = Vec::new();
        for blob in blobs.iter().take(MAX_BLOBS) {
            let _ = whole.push(effector::whole_mark(blob.area_px, blob.lopsidedness));
            let pixel = self
                .settings
                .lens
                .undistort([f64::from(blob.x_px), f64::from(blob.y_px)]);
            let area = f64::from(blob.area_px);
            let flux = area * f64::from(blob.mean_contrast);
            let _ = points.push(pixel.map(|p| (p, area, flux)));
        }
        // 2. Association, unique both ways.
        let (ambiguous, near_disc_mark) = self.associate(theta, &points, &mut report);
        // 3-5. Disc marks.
        self.find_reference(theta, &points);
        self.find_centre();
        self.find_features(theta);
        // 6. Effector marks.
        let effector = self.find_effector(
            theta,
            &points,
            &whole,
            &ambiguous,
            &near_disc_mark,
            effector_base_m,
        );

        // Where the gripper's marks project now: a disc label there may be a
        // gripper mark standing in a disc mark's place, and is not given.
        // Where the projection does not label them, it or the map of the
        // search's level plane says it, less sharply (seed 11 of the images
        // Monte Carlo: a gripper mark slid over the reference mark within a
        // pixel of its prediction in cell 172, and half hid the centre
        // mark below where the projection was fitted in cell 853).
        // And where the arm rests where a pair of its marks was seen, they
        // are where that pair's blobs were (a gripper mark at rest half over
        // the reference mark: cell 274).
        let projected = self.effector.projected_px();
        let (gripper_px, veto_px) = if projected.iter().any(Option::is_some) {
            (projected, effector::GATE_PX + OUTPUT_GATE_PX)
        } else {
            (self.effector.rough_px(effector_base_m), ROUGH_VETO_PX)
        };
        let resting_px = self.effector.resting_px(effector_base_m);
        let vetoes = gripper_px.iter().flatten().map(|q| (q, veto_px)).chain(
            resting_px
                .iter()
                .flatten()
                .map(|q| (q, effector::GATE_PX + OUTPUT_GATE_PX)),
        );
        for followed in self.tracks.iter() {
            if let (Some(label), Some(blob), true) = (followed.label, followed.blob, followed.sure)
            {
                if matches!(label, MarkLabel::Effector(_)) {
                    continue;
                }
                let p = followed.track.latest.1;
                if vetoes
                    .clone()
                    .any(|(q, r)| libm::hypot(p[0] - q[0], p[1] - q[1]) <= r)
                {
                    continue;
                }
                if let Some(Some((pixel, _, _))) = points.get(blob) {
                    let _ = out.push(LabelledPoint {
                        label,
                        pixel: *pixel,
                        blob,
                    });
                }
            }
        }
        for point in effector.iter().flatten() {
            // An effector blob that a disc label also claims is dropped both ways.
            if out.iter().any(|p| p.blob == point.blob) {
                out.retain(|p| p.blob != point.blob);
                continue;
            }
            let _ = out.push(*point);
        }
        // No label twice, no blob twice.
        let mut keep: Vec<LabelledPoint, MAX_LABELS> = Vec::new();
        for p in out.iter() {
            let twice = out
                .iter()
                .filter(|q| q.label == p.label || q.blob == p.blob)
                .count()
                > 1;
            if !twice {
                let _ = keep.push(*p);
            }
        }
        *out = keep;
        report.labelled = out.len() as u32;
        report.ambiguous += ambiguous.iter().filter(|&&a| a).count() as u32;
        report
    }

    /// Matches tracks and blobs; returns which blobs were ambiguous and
    /// which lay near where a disc mark's track (one labelled, turning with
    /// the disc or still on it) predicted its blob, whether taken or not (a
    /// disc mark half hidden, refused for its light, is still no gripper
    /// mark).
    fn associate(
        &mut self,
        theta: f64,
        points: &[Option<(PixelPoint, f64, f64)>],
        report: &mut IdentifyReport,
    ) -> (Vec<bool, MAX_BLOBS>, Vec<bool, MAX_BLOBS>) {
        let gate = self.settings.gate_px;
        let mut disc_like: Vec<bool, MAX_TRACKS> = Vec::new();
        let mut at_rest: Vec<bool, MAX_TRACKS> = Vec::new();
        for f in self.tracks.iter() {
            let _ = disc_like
                .push(!f.on_arm && (f.label.is_some() || Self::turning(f) || self.still(f)));
            let _ = at_rest.push(self.still(f) || f.label == Some(MarkLabel::DiscCentre));
        }
        let centre_home = self.centre_px;
        let mut near_disc_mark: Vec<bool, MAX_BLOBS> = Vec::new();
        for _ in points {
            let _ = near_disc_mark.push(false);
        }
        let mut claims: Vec<u8, MAX_BLOBS> = Vec::new();
        let mut choice: Vec<Option<usize>, MAX_TRACKS> = Vec::new();
        for _ in points {
            let _ = claims.push(0);
        }
        let disc = self.disc;
        let l = self.settings.reference_radius_m;
        let first_gate = self.settings.first_gate_px_per_rad;
        let mut innovation: Vec<f64, MAX_TRACKS> = Vec::new();
        let mut with_disc: Vec<Option<(PixelPoint, f64)>, MAX_TRACKS> = Vec::new();
        for (t, followed) in self.tracks.iter_mut().enumerate() {
            followed.blob = None;
            followed.sure = false;
            let track = &followed.track;
            let (theta1, p1) = track.latest;
            let first_seen = track.previous.is_none();
            let on_disc = disc.and_then(|d| {
                let q = d.rotating(p1, theta1, l)?;
                Some(d.pixel(q, theta, l))
            });
            // A still mark does not move while unseen: its gate does not
            // grow (a gripper mark resting beside the hidden disc centre
            // is not taken for it); the centre is looked for where it is.
            let resting = at_rest.get(t).copied().unwrap_or(false);
            let (predicted, reach) = match (first_seen, on_disc) {
                (true, Some(p)) => (p, gate),
                (true, None) => (p1, gate + first_gate * (theta - theta1).abs()),
                (false, _) if resting => (
                    match (followed.label, centre_home) {
                        (Some(MarkLabel::DiscCentre), Some(home)) => home,
                        _ => track.predict(theta, PREDICT_ARC_RAD, PREDICT_RMS_PX),
                    },
                    gate,
                ),
                (false, _) => (
                    track.predict(theta, PREDICT_ARC_RAD, PREDICT_RMS_PX),
                    gate * (1.0 + f64::from(track.misses.min(2))),
                ),
            };
            let mut found = None;
            let mut count = 0;
            let mut nearest = f64::INFINITY;
            let disc_mark = disc_like.get(t).copied().unwrap_or(false);
            for (i, point) in points.iter().enumerate() {
                if let Some((p, _, _)) = point {
                    let d = libm::hypot(p[0] - predicted[0], p[1] - predicted[1]);
                    if disc_mark && d <= reach + effector::CLEAR_PX {
                        if let Some(near) = near_disc_mark.get_mut(i) {
                            *near = true;
                        }
                    }
                    if d <= reach {
                        nearest = nearest.min(d);
                        count += 1;
                        found = Some(i);
                        if let Some(c) = claims.get_mut(i) {
                            *c = c.saturating_add(1);
                        }
                    }
                }
            }
            let _ = choice.push(if count == 1 { found } else { None });
            // A disc mark's blob turns with the disc from where the mark
            // was last seen. The disc's image is the reference's path: a
            // feature's own path turns about a centre within the centre
            // gate of it (`find_features`), so the disc's motion misses a
            // true feature by at most that gate per radian turned. A
            // gripper mark crossing the spot where a hidden disc mark was
            // predicted, and followed from there by the track's own
            // prediction (30 Hz, cells 11000096 and 11000173: 3 to 4 px a
            // frame off the disc's motion against at most 0.4 px for the
            // true marks), is not.
            let disc_label = matches!(
                followed.label,
                Some(MarkLabel::Reference | MarkLabel::PartFeature(_))
            );
            let _ = with_disc.push(disc.zip(on_disc).filter(|_| disc_label).map(|(d, p)| {
                let centre_gate = (CENTRE_GATE_SHARE * d.radius_px).max(CENTRE_GATE_MIN_PX);
                (p, OUTPUT_GATE_PX + centre_gate * libm::fabs(theta - theta1))
            }));
            let _ = innovation.push(if track.misses == 0 {
                nearest
            } else {
                f64::INFINITY
            });
            if count > 1 {
                report.ambiguous += 1;
            }
        }
        let mut ambiguous: Vec<bool, MAX_BLOBS> = Vec::new();
        for c in claims.iter() {
            let _ = ambiguous.push(*c > 1);
        }
        for (((followed, chosen), innovation), with_disc) in self
            .tracks
            .iter_mut()
            .zip(choice.iter())
            .zip(innovation.iter())
            .zip(with_disc.iter())
        {
            let taken = chosen.filter(|&i| claims.get(i).copied() == Some(1));
            // A followed mark keeps its brightness: a blob sending much more
            // or less light is another mark in its place (the gripper's over
            // a feature) or the mark half hidden; it is not taken.
            // (The centre does not move across the image: its light keeps
            // within FLUX_STEP of its mean, and a half-hidden frame cannot
            // walk it down to the gripper's mark's.)
            let mean_band = if followed.label == Some(MarkLabel::DiscCentre) {
                FLUX_STEP
            } else {
                FLUX_JUMP
            };
            let steady = |flux: f64| {
                let track = &followed.track;
                track.hits < MIN_HITS
                    || (Self::in_band(flux, track.mean_flux(), mean_band)
                        && Self::in_band(flux, track.latest_flux, FLUX_STEP))
            };
            let taken = taken.filter(|&i| {
                points
                    .get(i)
                    .copied()
                    .flatten()
                    .is_some_and(|(_, _, flux)| steady(flux))
            });
            let off_disc = |i: usize| {
                with_disc.is_some_and(|(q, reach)| {
                    points
                        .get(i)
                        .copied()
                        .flatten()
                        .is_some_and(|(p, _, _)| libm::hypot(p[0] - q[0], p[1] - q[1]) > reach)
                })
            };
            if taken.is_some_and(off_disc) {
                report.off_disc_motion += 1;
            }
            let taken = taken.filter(|&i| !off_disc(i));
            match taken.and_then(|i| points.get(i).copied().flatten().map(|p| (i, p))) {
                Some((i, (p, area, flux))) => {
                    followed.track.update(theta, p, area, flux);
                    followed.blob = Some(i);
                    followed.sure = *innovation <= OUTPUT_GATE_PX;
                    // The centre's label holds only at the centre's image.
                    if followed.label == Some(MarkLabel::DiscCentre)
                        && centre_home
                            .is_some_and(|q| libm::hypot(p[0] - q[0], p[1] - q[1]) > OUTPUT_GATE_PX)
                    {
                        followed.label = None;
                    }
                    // A disc label holds only while the track turns with the disc.
                    if matches!(
                        followed.label,
                        Some(MarkLabel::Reference | MarkLabel::PartFeature(_))
                    ) && followed
                        .track
                        .fit
                        .model(PREDICT_ARC_RAD)
                        .is_some_and(|m| m.rms_px > disc_rms_px(m.radius_px()))
                    {
                        followed.label = None;
                    }
                }
                None => followed.track.misses += 1,
            }
        }
        // A track seen once and then not is dropped at once: it predicts nothing.
        self.tracks
            .retain(|f| f.track.misses <= if f.track.hits < 2 { 0 } else { MAX_MISSES });
        for (i, point) in points.iter().enumerate() {
            if let (Some((p, area, flux)), Some(0)) = (point, claims.get(i).copied()) {
                let new = Followed {
                    track: Track::start(theta, *p, *area, *flux),
                    label: None,
                    on_arm: false,
                    blob: Some(i),
                    sure: false,
                };
                if self.tracks.push(new).is_err() {
                    report.tracks_full += 1;
                }
            }
        }
        (ambiguous, near_disc_mark)
    }

    /// The disc model of a turning track taken as the reference.
    fn disc_of(&self, track: &Track) -> Option<DiscImage> {
        let model = track.whole.model(MEASURE_ARC_RAD)?;
        let (major, minor) = axes(model.a_px, model.b_px);
        if major.is_nan() || major <= 0.0 {
            return None;
        }
        Some(DiscImage {
            centre_px: model.centre_px,
            a_px: model.a_px,
            b_px: model.b_px,
            radius_px: model.radius_px(),
            scale_px_per_m: major / self.settings.reference_radius_m,
            aspect: minor / major,
        })
    }

    /// A track turning with the disc: measured and explained by its fit.
    fn turning(followed: &Followed) -> bool {
        let track = &followed.track;
        !followed.on_arm
            && track.hits >= MIN_HITS
            && track.fit.model(PREDICT_ARC_RAD).is_some_and(|m| {
                m.rms_px <= disc_rms_px(m.radius_px()) && m.radius_px() >= MIN_TURNING_PX
            })
    }

    fn in_band(measured: f64, expected: f64, tolerance: f64) -> bool {
        measured >= expected / tolerance && measured <= expected * tolerance
    }

    /// The light of `candidate_flux` against the disc-centre mark's
    /// (`centre_flux`) is the reference mark's and not a part feature's:
    /// the two marks lie on the disc under the same light, their light is
    /// their area's (blur spreads a mark's image but keeps its light).
    fn reference_light(&self, candidate_flux: f64, centre_flux: f64) -> bool {
        let d = self.settings.diameters;
        if centre_flux <= 0.0 || d.disc_centre_m <= 0.0 || d.reference_m <= 0.0 {
            return false;
        }
        let expected = (d.reference_m / d.disc_centre_m) * (d.reference_m / d.disc_centre_m);
        let ratio = candidate_flux / centre_flux / expected;
        let feature = (d.part_feature_m / d.reference_m) * (d.part_feature_m / d.reference_m);
        // Nearer the reference's light than a feature's (in ratio), and no brighter than a
        // reference can be.
        libm::fabs(libm::log(ratio)) < libm::fabs(libm::log(ratio / feature))
            && ratio <= REFERENCE_LIGHT_MAX
    }

    /// Another turning track lies within [`NEIGHBOUR_M`] of `candidate`
    /// (under the disc image `disc`) and sends about its light: the
    /// candidate is one of several like marks, a part feature.
    /// With a key mark (and [`KEY_NEIGHBOURS`] plain ones), the candidate
    /// also counts as a part feature when that many marks near it send a
    /// plain feature's light against the key's.
    fn has_like_neighbour(&self, candidate: &Followed, disc: &DiscImage) -> bool {
        let reach_px = NEIGHBOUR_M * disc.scale_px_per_m;
        let p = candidate.track.latest.1;
        let candidate_flux = candidate.track.mean_flux();
        let near = |other: &Followed| {
            !core::ptr::eq(other, candidate)
                && other.track.misses == 0
                && !other.on_arm
                && libm::hypot(
                    other.track.latest.1[0] - p[0],
                    other.track.latest.1[1] - p[1],
                ) <= reach_px
        };
        let alike = self.tracks.iter().any(|other| {
            near(other)
                && Self::turning(other)
                && Self::in_band(other.track.mean_flux(), candidate_flux, NEIGHBOUR_LIGHT)
        });
        let key_with_plain = self.plain_share().is_some_and(|plain_share| {
            self.tracks
                .iter()
                .filter(|other| {
                    near(other)
                        && Self::in_band(
                            other.track.mean_flux(),
                            candidate_flux * plain_share,
                            FEATURE_LIKE_LIGHT,
                        )
                })
                .count()
                >= KEY_NEIGHBOURS
        });
        alike || key_with_plain
    }

    /// With a key mark, [`KEY_NEIGHBOURS`] of this frame's blobs near
    /// `candidate` (not its own) send a plain feature's light against it,
    /// whatever their tracks: a part's plain features a few pixels apart,
    /// moving faster than a young track's gate, start new tracks frame after
    /// frame and never turn long enough to count, and the key among them, of
    /// the reference's size and light, looks alone (images, seed 13, cell
    /// 955: the key taken for the reference in 6 frames). The blobs of still
    /// marks (the disc's centre) and of the gripper's known marks are left
    /// out. Only the key's test, not the like light's: a blob of like
    /// light near the true reference may be a gripper mark not yet known
    /// (seed 12, cell 382: the reference refused while the gripper passed,
    /// until the arm hid the key's neighbours and the key, alone, was
    /// taken). This only keeps a candidate from being chosen, never resets
    /// a reference found.
    fn has_plain_blobs_near(
        &self,
        candidate: &Followed,
        disc: &DiscImage,
        points: &[Option<(PixelPoint, f64, f64)>],
    ) -> bool {
        let Some(share) = self.plain_share() else {
            return false;
        };
        let reach_px = NEIGHBOUR_M * disc.scale_px_per_m;
        let p = candidate.track.latest.1;
        let plain_flux = candidate.track.mean_flux() * share;
        let left_out = |i: usize| {
            candidate.blob == Some(i)
                || self.tracks.iter().any(|f| {
                    f.blob == Some(i)
                        && (f.on_arm || self.still(f) || f.label == Some(MarkLabel::DiscCentre))
                })
        };
        points
            .iter()
            .enumerate()
            .filter(|(i, _)| !left_out(*i))
            .filter_map(|(_, point)| *point)
            .filter(|(q, _, flux)| {
                libm::hypot(q[0] - p[0], q[1] - p[1]) <= reach_px
                    && Self::in_band(*flux, plain_flux, FEATURE_LIKE_LIGHT)
            })
            .count()
            >= KEY_NEIGHBOURS
    }

    /// A plain feature's light against the key's, where the part has a key
    /// mark and [`KEY_NEIGHBOURS`] plain ones besides.
    fn plain_share(&self) -> Option<f64> {
        let d = self.settings.diameters;
        match d.part_key_m {
            Some(key_m) if key_m > 0.0 && self.settings.part_feature_count > KEY_NEIGHBOURS => {
                Some((d.part_feature_m / key_m) * (d.part_feature_m / key_m))
            }
            _ => None,
        }
    }

    /// Forgets the disc stage (a reference found wrong): the disc's image,
    /// the reference, the centre and the features start again.
    fn reset_disc(&mut self) {
        for f in self.tracks.iter_mut() {
            if matches!(
                f.label,
                Some(MarkLabel::Reference | MarkLabel::DiscCentre | MarkLabel::PartFeature(_))
            ) {
                f.label = None;
            }
        }
        self.disc = None;
        self.features_rotating.clear();
        self.centre_px = None;
        self.centre_flux = None;
        self.reference_flux = None;
        self.reference_seen_theta = None;
    }

    fn find_reference(&mut self, theta: f64, points: &[Option<(PixelPoint, f64, f64)>]) {
        let d = self.settings.diameters;
        if let Some(reference) = self
            .tracks
            .iter()
            .find(|f| f.label == Some(MarkLabel::Reference))
        {
            // Still the reference by its light against the centre's, and
            // alone of its light: else the hypothesis was wrong.
            let centre_flux = self
                .tracks
                .iter()
                .find(|f| f.label == Some(MarkLabel::DiscCentre))
                .map(|f| f.track.mean_flux());
            if reference.track.misses == 0 {
                self.reference_seen_theta = Some(theta);
            }
            let disc = self.disc_of(&reference.track);
            let wrong = centre_flux
                .is_some_and(|c| !self.reference_light(reference.track.mean_flux(), c))
                || disc.is_some_and(|disc| {
                    reference.track.misses == 0 && self.has_like_neighbour(reference, &disc)
                });
            if wrong {
                self.reset_disc();
                return;
            }
            if let Some(disc) = disc {
                self.disc = Some(disc);
            }
            return;
        }
        if self.disc.is_some()
            && self
                .reference_seen_theta
                .is_some_and(|seen| libm::fabs(theta - seen) > REFERENCE_UNSEEN_RAD)
        {
            self.reset_disc();
        }
        let mut chosen: Option<usize> = None;
        let mut consistent = 0;
        for (i, candidate) in self.tracks.iter().enumerate() {
            if !Self::turning(candidate) {
                continue;
            }
            let Some(disc) = self.disc_of(&candidate.track) else {
                continue;
            };
            if !Self::in_band(
                disc.diameter_m(candidate.track.mean_area_px()),
                d.reference_m,
                SIZE_TOLERANCE,
            ) {
                continue;
            }
            // A known disc: the reference is where the reference was.
            if let Some(known) = &self.disc {
                let Some(p) = known.rotating(
                    candidate.track.latest.1,
                    candidate.track.latest.0,
                    self.settings.reference_radius_m,
                ) else {
                    continue;
                };
                let off = libm::hypot(p[0] - self.settings.reference_radius_m, p[1]);
                if off > 0.1 * self.settings.reference_radius_m {
                    continue;
                }
            }
            // Its path turns about a still mark of the centre mark's size.
            let gate = (CENTRE_GATE_SHARE * disc.radius_px).max(CENTRE_GATE_MIN_PX);
            let whole_fits = candidate
                .track
                .whole
                .model(MEASURE_ARC_RAD)
                .is_some_and(|m| m.rms_px <= 2.0 * disc_rms_px(m.radius_px()));
            // ... whose light is the reference's against it.
            let centred = self.tracks.iter().any(|other| {
                self.still(other)
                    && Self::in_band(
                        disc.diameter_m(other.track.mean_area_px()),
                        d.disc_centre_m,
                        SIZE_TOLERANCE,
                    )
                    && libm::hypot(
                        other.track.latest.1[0] - disc.centre_px[0],
                        other.track.latest.1[1] - disc.centre_px[1],
                    ) <= gate
                    && self.reference_light(candidate.track.mean_flux(), other.track.mean_flux())
            });
            if !whole_fits
                || !centred
                || self.has_like_neighbour(candidate, &disc)
                || self.has_plain_blobs_near(candidate, &disc, points)
            {
                continue;
            }
            let mut features = 0;
            let mut inside = true;
            for other in self.tracks.iter() {
                if core::ptr::eq(other, candidate) || !Self::turning(other) {
                    continue;
                }
                let Some(model) = other.track.fit.model(PREDICT_ARC_RAD) else {
                    continue;
                };
                let radius_m =
                    model.radius_px() / disc.radius_px * self.settings.reference_radius_m;
                if radius_m > self.settings.disc_radius_m * DISC_MARGIN {
                    inside = false;
                }
                // Sizes by flux against the candidate's (see `find_features`).
                let flux_ratio = other.track.mean_flux() / candidate.track.mean_flux().max(1e-9);
                let by_flux = d.reference_m * libm::sqrt(flux_ratio.max(0.0));
                if Self::in_band(by_flux, d.part_feature_m, FLUX_SIZE_TOLERANCE)
                    && Self::in_band(
                        disc.diameter_m(other.track.mean_area_px()),
                        d.part_feature_m,
                        SIZE_TOLERANCE,
                    )
                {
                    features += 1;
                }
            }
            if inside && features <= self.settings.part_feature_count {
                consistent += 1;
                chosen = Some(i);
            }
        }
        if consistent == 1 {
            if let Some(followed) = chosen.and_then(|i| self.tracks.get_mut(i)) {
                followed.label = Some(MarkLabel::Reference);
            }
            if let Some(track) = chosen.and_then(|i| self.tracks.get(i)).map(|f| f.track) {
                self.disc = self.disc_of(&track).or(self.disc);
                self.reference_seen_theta = Some(theta);
            }
        }
    }

    /// The track's last two observations are one point of the disc's
    /// rotating frame, the disc having turned between them: a disc object
    /// however young its track (before [`MIN_HITS`] no fit says it turns).
    fn holds_still_on_disc(&self, track: &Track) -> bool {
        let (Some(disc), Some((theta0, p0))) = (self.disc, track.previous) else {
            return false;
        };
        let (theta1, p1) = track.latest;
        let l = self.settings.reference_radius_m;
        if libm::fabs(theta1 - theta0) < WITH_DISC_MIN_TURN_RAD {
            return false;
        }
        match (disc.rotating(p0, theta0, l), disc.rotating(p1, theta1, l)) {
            (Some(a), Some(b)) => libm::hypot(a[0] - b[0], a[1] - b[1]) <= WITH_DISC_M,
            _ => false,
        }
    }

    /// A track at rest while the disc turned.
    fn still(&self, f: &Followed) -> bool {
        !f.on_arm
            && f.track.hits >= MIN_HITS
            && f.track
                .whole
                .model(MEASURE_ARC_RAD)
                .is_some_and(|m| m.radius_px() <= STILL_PX && m.rms_px <= DISC_RMS_PX)
    }

    fn find_centre(&mut self) {
        let Some(disc) = self.disc else {
            return;
        };
        if let Some(centre) = self
            .tracks
            .iter()
            .find(|f| f.label == Some(MarkLabel::DiscCentre))
        {
            self.centre_flux = Some(centre.track.mean_flux());
            return;
        }
        // Once the centre's image is known, the centre is the one track
        // seen there in this frame and the one before (its path may hold
        // what stood there while the centre was hidden), of the centre's light.
        if let Some(home) = self.centre_px {
            let at_home =
                |p: PixelPoint| libm::hypot(p[0] - home[0], p[1] - home[1]) <= OUTPUT_GATE_PX;
            let centre_flux = self.centre_flux;
            let mut there = self.tracks.iter_mut().filter(|f| {
                f.label.is_none()
                    && !f.on_arm
                    && f.track.misses == 0
                    && at_home(f.track.latest.1)
                    && f.track.previous.is_some_and(|(_, p)| at_home(p))
                    && centre_flux
                        .is_none_or(|flux| Self::in_band(f.track.latest_flux, flux, FLUX_STEP))
            });
            if let (Some(f), None) = (there.next(), there.next()) {
                f.label = Some(MarkLabel::DiscCentre);
            }
            return;
        }
        let gate = (CENTRE_GATE_SHARE * disc.radius_px).max(CENTRE_GATE_MIN_PX);
        let mut chosen = None;
        let mut count = 0;
        for (i, f) in self.tracks.iter().enumerate() {
            if f.label.is_some() || !self.still(f) {
                continue;
            }
            let p = f.track.latest.1;
            let near = libm::hypot(p[0] - disc.centre_px[0], p[1] - disc.centre_px[1]) <= gate;
            let sized = Self::in_band(
                disc.diameter_m(f.track.mean_area_px()),
                self.settings.diameters.disc_centre_m,
                SIZE_TOLERANCE,
            );
            if near {
                count += 1;
                if sized {
                    chosen = Some(i);
                }
            }
        }
        if count == 1 {
            if let Some(f) = chosen.and_then(|i| self.tracks.get_mut(i)) {
                f.label = Some(MarkLabel::DiscCentre);
                let at = f
                    .track
                    .whole
                    .model(MEASURE_ARC_RAD)
                    .map_or(f.track.latest.1, |m| m.centre_px);
                self.centre_px = Some(at);
            }
        }
    }

    /// Orders the settled feature `candidates` (track index, rotating-frame
    /// position, light) as the part's drawing numbers them: the key first,
    /// then the rest counter-clockwise about their centroid. The key is the
    /// brightest, clearly brighter than every other (a mark's light grows
    /// with the square of its diameter: it must stand out by at least the
    /// square root of the key's ratio, and by no more than the ratio with
    /// the light's spread), and the others are alike in light. `false` when
    /// that does not hold: the order waits.
    fn order_from_key(
        &self,
        candidates: &mut Vec<(usize, [f64; 2], f64), MAX_TRACKS>,
        key_m: f64,
    ) -> bool {
        let plain_m = self.settings.diameters.part_feature_m;
        let ratio = (key_m / plain_m) * (key_m / plain_m);
        let Some(key_at) = candidates
            .iter()
            .enumerate()
            .max_by(|a, b| a.1 .2.total_cmp(&b.1 .2))
            .map(|(k, _)| k)
        else {
            return false;
        };
        let key_light = candidates.get(key_at).map_or(0.0, |c| c.2);
        let (least, most) = candidates
            .iter()
            .enumerate()
            .filter(|(k, _)| *k != key_at)
            .fold((f64::INFINITY, 0.0f64), |(a, b), (_, c)| {
                (a.min(c.2), b.max(c.2))
            });
        let others_alike = least > 0.0 && most <= least * FEATURE_LIKE_LIGHT;
        let stands_out = key_light >= libm::sqrt(ratio) * most
            && key_light <= ratio * FEATURE_LIKE_LIGHT * least;
        if !(others_alike && stands_out) {
            return false;
        }
        let count = candidates.len().max(1) as f64;
        let (sx, sy) = candidates
            .iter()
            .fold((0.0, 0.0), |(sx, sy), c| (sx + c.1[0], sy + c.1[1]));
        let centroid = [sx / count, sy / count];
        let Some(key_p) = candidates.get(key_at).map(|c| c.1) else {
            return false;
        };
        let key_angle = libm::atan2(key_p[1] - centroid[1], key_p[0] - centroid[0]);
        let turn = |p: &[f64; 2]| {
            let a = libm::atan2(p[1] - centroid[1], p[0] - centroid[0]) - key_angle;
            if a < 0.0 {
                a + core::f64::consts::TAU
            } else {
                a
            }
        };
        candidates.sort_unstable_by(|x, y| turn(&x.1).total_cmp(&turn(&y.1)));
        true
    }

    fn find_features(&mut self, theta: f64) {
        let Some(disc) = self.disc else {
            return;
        };
        let l = self.settings.reference_radius_m;
        let expected = self.settings.diameters.part_feature_m;
        let reference_flux = self
            .tracks
            .iter()
            .find(|f| f.label == Some(MarkLabel::Reference))
            .map(|f| f.track.mean_flux())
            .filter(|&x| x > 0.0)
            .or(self.reference_flux);
        self.reference_flux = reference_flux;
        let mut candidates: Vec<(usize, [f64; 2], f64), MAX_TRACKS> = Vec::new();
        for (i, f) in self.tracks.iter().enumerate() {
            if f.label.is_some() || f.blob.is_none() || !Self::turning(f) {
                continue;
            }
            let key = self.settings.diameters.part_key_m;
            let sized = |diameter_m: f64, tolerance: f64| {
                Self::in_band(diameter_m, expected, tolerance)
                    || key.is_some_and(|key| Self::in_band(diameter_m, key, tolerance))
            };
            if !sized(disc.diameter_m(f.track.mean_area_px()), SIZE_TOLERANCE) {
                continue;
            }
            // The light it sends against the reference mark's: blur spreads
            // a small mark's image but keeps its flux.
            if let Some(reference_flux) = reference_flux {
                let d = self.settings.diameters.reference_m
                    * libm::sqrt((f.track.mean_flux() / reference_flux).max(0.0));
                if !sized(d, FLUX_SIZE_TOLERANCE) {
                    continue;
                }
            }
            // Its path turns about the disc's centre (a gripper mark
            // following the part turns about another point).
            let gate = (CENTRE_GATE_SHARE * disc.radius_px).max(CENTRE_GATE_MIN_PX);
            let centred = f
                .track
                .whole
                .model(FEATURE_CENTRED_ARC_RAD)
                .is_some_and(|m| {
                    libm::hypot(
                        m.centre_px[0] - disc.centre_px[0],
                        m.centre_px[1] - disc.centre_px[1],
                    ) <= gate
                });
            if !centred {
                continue;
            }
            if let Some(p) = disc.rotating(f.track.latest.1, theta, l) {
                if libm::hypot(p[0], p[1]) <= self.settings.disc_radius_m * DISC_MARGIN {
                    let _ = candidates.push((i, p, f.track.mean_flux()));
                }
            }
        }
        let count = self.settings.part_feature_count;
        if self.features_rotating.is_empty() {
            let unlabelled_features = !self
                .tracks
                .iter()
                .any(|f| matches!(f.label, Some(MarkLabel::PartFeature(_))));
            // The order is stored once: only from tracks followed long
            // enough for their sizes to be well measured.
            let settled = candidates.iter().all(|(i, _, _)| {
                self.tracks
                    .get(*i)
                    .is_some_and(|f| f.track.hits >= SETTLED_HITS)
            });
            // ... and alike in light.
            let (least, most) = candidates
                .iter()
                .fold((f64::INFINITY, 0.0f64), |(a, b), (_, _, flux)| {
                    (a.min(*flux), b.max(*flux))
                });
            // (With a key mark, `order_from_key` checks the others alike.)
            let alike = self.settings.diameters.part_key_m.is_some()
                || (least > 0.0 && most <= least * FEATURE_LIKE_LIGHT);
            // ... and only while the reference mark is in hand, labelled and
            // seen now. A reference whose track lost its label (the arm hid
            // it) turns with the disc like a feature, and is followed long
            // enough to be a feature candidate (0.6 rad) before it is long
            // enough to be taken back as the reference (1.2 rad): with the
            // key feature hidden at that moment it once made a set of three
            // that passed every check (its light 2.25 plain features', the
            // key's 1.41), and every part label was wrong for the rest of the
            // run (cell 10000803: 296 wrong labels, part 167 mm off).
            let reference_in_hand = self
                .tracks
                .iter()
                .any(|f| f.label == Some(MarkLabel::Reference) && f.blob.is_some());
            if candidates.len() != count
                || !unlabelled_features
                || !settled
                || !alike
                || !reference_in_hand
            {
                return;
            }
            match self.settings.diameters.part_key_m {
                Some(key_m) => {
                    if !self.order_from_key(&mut candidates, key_m) {
                        return;
                    }
                }
                // A fixed order: by angle about the disc centre, from the reference.
                None => candidates.sort_unstable_by(|x, y| {
                    libm::atan2(x.1[1], x.1[0]).total_cmp(&libm::atan2(y.1[1], y.1[0]))
                }),
            }
            for (k, (i, p, _)) in candidates.iter().enumerate() {
                let _ = self.features_rotating.push(*p);
                if let Some(f) = self.tracks.get_mut(*i) {
                    f.label = Some(MarkLabel::PartFeature(k as u8));
                }
            }
            return;
        }
        let mut spacing = f64::INFINITY;
        for (k, p) in self.features_rotating.iter().enumerate() {
            for q in self.features_rotating.iter().skip(k + 1) {
                spacing = spacing.min(libm::hypot(p[0] - q[0], p[1] - q[1]));
            }
        }
        let gate = FEATURE_GATE_SHARE * spacing;
        // An anchor: a labelled feature seen now. A lost feature is looked
        // for at its stored offset from the anchor (the disc model's errors
        // and a slow drift of the part cancel between neighbours); without
        // an anchor, none is taken back.
        let anchor = self.tracks.iter().find_map(|f| match (f.label, f.blob) {
            (Some(MarkLabel::PartFeature(j)), Some(_)) => {
                let now = disc.rotating(f.track.latest.1, theta, l)?;
                let stored = self.features_rotating.get(usize::from(j))?;
                Some([now[0] - stored[0], now[1] - stored[1]])
            }
            _ => None,
        });
        let Some(shift) = anchor else {
            return;
        };
        // The labelled features' light: a lost one is taken back only by a
        // track of about their light.
        // (The key mark's light counts at a plain mark's.)
        let key_ratio = self.settings.diameters.part_key_m.map_or(1.0, |key_m| {
            let plain_m = self.settings.diameters.part_feature_m;
            (key_m / plain_m) * (key_m / plain_m)
        });
        let weight = |k: usize| if k == 0 { key_ratio } else { 1.0 };
        let (mut sum, mut n) = (0.0, 0.0);
        for f in self.tracks.iter() {
            if let Some(MarkLabel::PartFeature(j)) = f.label {
                sum += f.track.mean_flux() / weight(usize::from(j));
                n += 1.0;
            }
        }
        let plain_flux = sum / n;
        for (k, stored) in self.features_rotating.iter().enumerate() {
            let label = MarkLabel::PartFeature(k as u8);
            let feature_flux = plain_flux * weight(k);
            if self.tracks.iter().any(|f| f.label == Some(label)) {
                continue;
            }
            let near: Vec<usize, MAX_TRACKS> = candidates
                .iter()
                .filter(|(_, p, flux)| {
                    libm::hypot(p[0] - stored[0] - shift[0], p[1] - stored[1] - shift[1]) <= gate
                        && Self::in_band(*flux, feature_flux, FEATURE_LIKE_LIGHT)
                })
                .map(|(i, _, _)| *i)
                .collect();
            if let [i] = near.as_slice() {
                if let Some(f) = self.tracks.get_mut(*i) {
                    f.label = Some(label);
                }
            }
        }
    }

    /// The gripper's marks ([`effector`]): each blob with whether it may be
    /// one (not ambiguous, no disc mark's: neither labelled as one nor
    /// turning with the disc or still on it, unless taken for a gripper
    /// mark before, nor near where a disc mark is known to be).
    fn find_effector(
        &mut self,
        theta: f64,
        points: &[Option<(PixelPoint, f64, f64)>],
        whole: &[bool],
        ambiguous: &[bool],
        near_disc_mark: &[bool],
        effector_base_m: &[[f64; 3]; 2],
    ) -> [Option<LabelledPoint>; 2] {
        // Where the disc's marks are known to be, seen or not: the centre's
        // image, and the reference and the part's features as the disc
        // model turns them (a disc mark that reappears from under the arm
        // starts a new track, which says nothing yet).
        let mut disc_marks: Vec<PixelPoint, MAX_LABELS> = Vec::new();
        if let Some(centre) = self.centre_px {
            let _ = disc_marks.push(centre);
        }
        if let Some(disc) = self.disc {
            let l = self.settings.reference_radius_m;
            let _ = disc_marks.push(disc.pixel([l, 0.0], theta, l));
            for p in self.features_rotating.iter() {
                let _ = disc_marks.push(disc.pixel(*p, theta, l));
            }
        }
        let keep_off = self.settings.gate_px + effector::CLEAR_PX;
        let mut candidates: Vec<Option<EffectorCandidate>, MAX_BLOBS> = Vec::new();
        for (i, point) in points.iter().enumerate() {
            let candidate = point.map(|(pixel, _, flux)| {
                let holder = self.tracks.iter().find(|f| f.blob == Some(i));
                let on_disc = holder.is_some_and(|f| {
                    !f.on_arm && (f.label.is_some() || Self::turning(f) || self.still(f))
                });
                let with_disc =
                    holder.is_some_and(|f| !f.on_arm && self.holds_still_on_disc(&f.track));
                EffectorCandidate {
                    pixel,
                    flux,
                    with_disc,
                    whole: whole.get(i).copied().unwrap_or(false),
                    free: !on_disc
                        && !disc_marks
                            .iter()
                            .any(|q| libm::hypot(q[0] - pixel[0], q[1] - pixel[1]) <= keep_off)
                        && !ambiguous.get(i).copied().unwrap_or(true)
                        && !near_disc_mark.get(i).copied().unwrap_or(true),
                }
            });
            let _ = candidates.push(candidate);
        }
        let yardstick = self
            .disc
            .zip(self.reference_flux)
            .map(|(disc, flux)| flux / (disc.scale_px_per_m * disc.scale_px_per_m));
        if let Some(disc) = self.disc {
            self.effector.see_disc(disc.centre_px, disc.a_px, disc.b_px);
        }
        let found = self
            .effector
            .identify(&candidates, effector_base_m, yardstick);
        for f in self.tracks.iter_mut() {
            if found.iter().flatten().any(|p| f.blob == Some(p.blob)) {
                f.on_arm = true;
                f.label = None;
            }
        }
        found
    }
}

#[cfg(test)]
mod tests;
