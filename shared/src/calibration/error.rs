//! Typed errors of the self-calibration: each says what went wrong and where
//! (which frame, which field, which stage), so a log can be fixed or a run diagnosed.

use core::fmt;

/// Why a conic fitted to the reference point's image is not the ellipse the
/// paper's Step 2 needs (the image of a circle seen from one side is always an ellipse).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ConicKind {
    /// Two branches: the track is not a circle's image.
    Hyperbola,
    /// Unbounded: the track is not a circle's image.
    Parabola,
    /// `A u^2 + ... = 0` has no real point (an empty "ellipse").
    Imaginary,
}

/// Everything the calibration can refuse, with enough context to act on it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum CalibrationError {
    /// The log header cannot describe a workcell (`field` names the bad value).
    InvalidHeader {
        /// The field's name in the header.
        field: &'static str,
    },
    /// A [`super::CalibrationConfig`] value is out of range (`field` names it).
    InvalidConfig {
        /// The field's name in the configuration.
        field: &'static str,
    },
    /// A frame holds NaN or an infinity in `field` (frame = index of the offered frame, from 0).
    NonFiniteValue {
        /// The offered frame's index, from 0.
        frame: u32,
        /// The field holding the value.
        field: &'static str,
    },
    /// A detection lies outside the image (the contract says such a point is not
    /// detected, so a log holding one is malformed).
    OutsideImage {
        /// The offered frame's index, from 0.
        frame: u32,
        /// The field holding the point.
        field: &'static str,
    },
    /// A finite value too large to mean anything (`|value| > limit`): a conveyor
    /// angle f64 can no longer resolve, or an end-effector point kilometres away.
    ValueOutOfRange {
        /// The offered frame's index, from 0.
        frame: u32,
        /// The field holding the value.
        field: &'static str,
        /// The largest magnitude allowed.
        limit: f64,
    },
    /// `part_px` holds `found` points but the header announced `expected`.
    WrongFeatureCount {
        /// The offered frame's index, from 0.
        frame: u32,
        /// The header's `part_feature_count`.
        expected: usize,
        /// The points in the frame's `part_px`.
        found: usize,
    },
    /// `t_s` decreased: the contract requires non-decreasing capture times.
    TimeWentBackwards {
        /// The offered frame's index, from 0.
        frame: u32,
        /// Its capture time, s.
        t_s: f64,
        /// The previous admitted frame's, s.
        previous_t_s: f64,
    },
    /// The two end-effector points coincide in the base frame, so Eq 10 has no scale (s = 0).
    CoincidingEffectorPoints {
        /// The offered frame's index, from 0.
        frame: u32,
    },
    /// Not enough observations of `what` were absorbed (`needed` at least, `found` so far).
    TooFewObservations {
        /// What was observed too rarely.
        what: &'static str,
        /// How many are needed at least.
        needed: u32,
        /// How many were absorbed.
        found: u32,
    },
    /// The reference points do not pin down a conic: collinear (exactly, or within the
    /// pixel noise: a camera in the disc plane) or fewer than five distinct points.
    DegenerateConic {
        /// Reference points absorbed.
        points: u32,
    },
    /// The fitted conic is not an ellipse (Step 2).
    NotAnEllipse {
        /// What the conic is instead.
        kind: ConicKind,
    },
    /// The reference point's image turns the wrong way as theta grows: the camera
    /// sees the disc from below (the spec requires a camera above the disc).
    CameraBelowDisc,
    /// An image point of `field` is seen level with or above the camera, so its ray
    /// never meets the disc plane below: the camera is (nearly) in the disc plane,
    /// or the end effector was shown above the camera.
    AboveCamera {
        /// The field whose point it is.
        field: &'static str,
    },
    /// The conveyor angles absorbed so far span less than `needed_rad`: heights are unobservable.
    InsufficientRotation {
        /// The span of the conveyor angles, rad.
        span_rad: f64,
        /// The least span the configuration asks for, rad.
        needed_rad: f64,
    },
    /// No end-effector sighting has a unique root of Eq 10 with both points in front of the
    /// camera (none real, none valid, or two valid ones); `frame` = index of the first such
    /// sighting among those stored.
    NoValidDepthRoot {
        /// The sighting's index among those stored.
        frame: u32,
    },
    /// A linear system of `stage` was singular or a result came out non-finite.
    NumericalFailure {
        /// The stage that failed.
        stage: &'static str,
    },
}

impl fmt::Display for ConicKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ConicKind::Hyperbola => f.write_str("a hyperbola"),
            ConicKind::Parabola => f.write_str("a parabola"),
            ConicKind::Imaginary => f.write_str("an imaginary ellipse (no real point)"),
        }
    }
}

impl fmt::Display for CalibrationError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            CalibrationError::InvalidHeader { field } => {
                write!(f, "invalid log header: field `{field}` is out of range")
            }
            CalibrationError::InvalidConfig { field } => {
                write!(f, "invalid calibration config: `{field}` is out of range")
            }
            CalibrationError::NonFiniteValue { frame, field } => {
                write!(f, "frame {frame}: field `{field}` is not a finite number")
            }
            CalibrationError::OutsideImage { frame, field } => write!(
                f,
                "frame {frame}: field `{field}` lies outside the image (-0.5 <= u <= width - 0.5, likewise v)"
            ),
            CalibrationError::ValueOutOfRange { frame, field, limit } => write!(
                f,
                "frame {frame}: field `{field}` is out of range (its magnitude must be at most {limit:e})"
            ),
            CalibrationError::WrongFeatureCount { frame, expected, found } => write!(
                f,
                "frame {frame}: `part_px` has {found} points, the header says {expected}"
            ),
            CalibrationError::TimeWentBackwards { frame, t_s, previous_t_s } => write!(
                f,
                "frame {frame}: `t_s` = {t_s} s is before the previous frame's {previous_t_s} s"
            ),
            CalibrationError::CoincidingEffectorPoints { frame } => write!(
                f,
                "frame {frame}: the two `effector_base_m` points coincide (Eq 10 needs s > 0)"
            ),
            CalibrationError::TooFewObservations { what, needed, found } => write!(
                f,
                "too few observations of {what}: need at least {needed}, have {found}"
            ),
            CalibrationError::DegenerateConic { points } => write!(
                f,
                "the {points} reference points do not determine a conic (collinear, or on a line within the pixel noise as seen by a camera in the disc plane, or fewer than 5 distinct)"
            ),
            CalibrationError::NotAnEllipse { kind } => write!(
                f,
                "the conic fitted to the reference points is {kind}, not an ellipse"
            ),
            CalibrationError::CameraBelowDisc => f.write_str(
                "the reference point's image turns counter to theta: the camera is below the disc",
            ),
            CalibrationError::AboveCamera { field } => write!(
                f,
                "a point of `{field}` is seen level with or above the camera (its ray never reaches the disc plane): \
                 mount the camera higher above the disc, or show the end effector below it"
            ),
            CalibrationError::InsufficientRotation { span_rad, needed_rad } => write!(
                f,
                "the conveyor turned only {span_rad} rad over the observations, need {needed_rad} rad"
            ),
            CalibrationError::NoValidDepthRoot { frame } => write!(
                f,
                "effector sighting {frame}: Eq 10 has no unique root with both points in front of the camera"
            ),
            CalibrationError::NumericalFailure { stage } => {
                write!(f, "numerical failure in {stage}: singular system or non-finite result")
            }
        }
    }
}

impl core::error::Error for CalibrationError {}
