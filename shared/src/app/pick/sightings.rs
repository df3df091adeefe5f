//! What the camera's sightings of the gripper's marks tell the pick before
//! any calibration: which way round the base axis the disc is (the mean
//! direction of the sightings), and how low the flange has been while the
//! camera saw the marks, so that nothing goes far below a height known to be
//! clear of the disc and the part; and whether the camera has shown the part.

use super::handoff::Sighting;
use crate::app::tool::EFFECTOR_MARKS_FLANGE_M;

/// How far the gripper's marks sit below the flange with the gripper down.
const MARK_BELOW_FLANGE_M: f32 = EFFECTOR_MARKS_FLANGE_M[0][2] as f32;

/// The sightings so far.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Sightings {
    /// Sum of the unit vectors towards the marks where the camera saw them (their
    /// mean direction is where the disc is, roughly).
    direction: [f32; 2],
    /// The lowest flange height known to be clear: where the arm started,
    /// until the camera has seen the marks; then the lowest height at which
    /// it saw them.
    known_clear_flange_z: f32,
    seen_marks: bool,
    /// When the marks were last seen, s (the pick's clock).
    last_seen_s: f32,
    /// Frames given to the calibrator that showed the part's features.
    part_frames: u32,
}

impl Sightings {
    /// None yet, and no height known clear.
    pub(super) fn new() -> Self {
        Self {
            direction: [0.0; 2],
            known_clear_flange_z: f32::INFINITY,
            seen_marks: false,
            last_seen_s: f32::NEG_INFINITY,
            part_frames: 0,
        }
    }

    /// The arm starts with its flange at `flange_z`: until the camera has seen
    /// the marks, that height or the travel height `travel_z` (declared clear
    /// of any disc and part), if lower, is the known-clear one.
    pub(super) fn start_at(&mut self, flange_z: f32, travel_z: f32) {
        if !self.seen_marks {
            self.known_clear_flange_z = flange_z.min(travel_z);
        }
    }

    /// The camera saw the marks at `now_s`: the disc is that way round the
    /// base axis, and the flange has been this low in the camera's view.
    pub(super) fn record(&mut self, sighting: &Sighting, now_s: f32) {
        self.last_seen_s = now_s;
        let [x, y] = sighting.direction_xy;
        let [sx, sy] = self.direction;
        self.direction = [sx + x, sy + y];
        // The marks sit MARK_BELOW_FLANGE_M under the flange, gripper down.
        let flange_z = sighting.mark_z_m + MARK_BELOW_FLANGE_M;
        if flange_z.is_finite() {
            if !self.seen_marks || flange_z < self.known_clear_flange_z {
                self.known_clear_flange_z = flange_z;
            }
            self.seen_marks = true;
        }
    }

    /// A frame given to the calibrator showed the part.
    pub(super) fn part_seen(&mut self) {
        self.part_frames = self.part_frames.saturating_add(1);
    }

    /// Frames so far that showed the part: the first estimate needs it
    /// (through images the front end labels the part only once it has
    /// followed it round with the disc, up to 12 s after the disc).
    pub(super) fn part_frames(&self) -> u32 {
        self.part_frames
    }

    /// How long the marks have gone unseen at `now_s`, s (infinite before
    /// the first sighting).
    pub(super) fn unseen_for(&self, now_s: f32) -> f32 {
        now_s - self.last_seen_s
    }

    /// The sightings' mean azimuth round the base axis (where the disc is).
    pub(super) fn azimuth(&self) -> f32 {
        let [sx, sy] = self.direction;
        libm::atan2f(sy, sx)
    }

    /// The lowest flange height a motion may go to before the calibration is
    /// accepted: `max_descent_step_m` below the known-clear height.
    pub(super) fn safe_floor_z(&self, max_descent_step_m: f32) -> f32 {
        self.known_clear_flange_z - max_descent_step_m
    }
}
