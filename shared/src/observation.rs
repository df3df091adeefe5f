//! Records of the observation log and the calibration result, as fixed by the
//! interface contract `docs/reference/frames-and-log.md` (version 1).
//!
//! These are plain fixed-size types: the host reads and writes them as JSON
//! Lines (`host-sim`), the firmware fills them from camera feature frames.
//! Field names match the contract so that `serde` maps them one to one.

use heapless::Vec;
use serde::{Deserialize, Serialize};

/// The only log version this code reads and writes.
pub const LOG_VERSION: u32 = 1;

/// Most feature points a part may carry (the contract asks for at least 2).
pub const MAX_PART_FEATURES: usize = 8;

/// Number of end-effector points seen per frame (paper Section 3.2 uses two).
pub const EFFECTOR_POINTS: usize = 2;

/// An image point in pixels, `[u, v]` (u right, v down, `(0, 0)` the top-left pixel centre).
pub type PixelPoint = [f64; 2];

/// A point in metres, `[x, y, z]`, in the frame its name says.
pub type Point3 = [f64; 3];

/// Pinhole intrinsics with square pixels and no distortion (paper assumption A5).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct CameraIntrinsics {
    /// Image width, pixels.
    pub width: u32,
    /// Image height, pixels.
    pub height: u32,
    /// Focal length, pixels.
    pub f_px: f64,
    /// Principal point, column, pixels.
    pub cx: f64,
    /// Principal point, row, pixels.
    pub cy: f64,
}

impl CameraIntrinsics {
    /// Whether `p` lies inside the image by the contract's rule
    /// (`-0.5 <= u <= width - 0.5`, likewise for v).
    pub fn contains(&self, p: PixelPoint) -> bool {
        let [u, v] = p;
        u >= -0.5
            && u <= f64::from(self.width) - 0.5
            && v >= -0.5
            && v <= f64::from(self.height) - 0.5
    }
}

/// Line 1 of a log.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct LogHeader {
    /// The log format's version ([`LOG_VERSION`]).
    pub version: u32,
    /// The camera's known intrinsics.
    pub camera: CameraIntrinsics,
    /// The paper's L: distance from the disc centre to the reference point.
    pub reference_radius_m: f64,
    /// How many feature points the part carries (2..=[`MAX_PART_FEATURES`]).
    pub part_feature_count: usize,
    /// The disc's radius to its rim, m, where the rim is measured (this
    /// project's addition: known, as `reference_radius_m` is).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub disc_radius_m: Option<f64>,
}

/// Two end-effector points seen in one frame: their images and their base-frame
/// positions from the robot's joint encoders and kinematics (taken as exact).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct EffectorSighting {
    /// The two end-effector points' images.
    pub px: [PixelPoint; EFFECTOR_POINTS],
    /// Their positions in the base frame, m.
    pub base_m: [Point3; EFFECTOR_POINTS],
}

/// One camera frame of the log. `None` means "not detected in this frame".
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ObservationFrame {
    /// Capture time, non-decreasing within a log.
    pub t_s: f64,
    /// Conveyor encoder angle theta latched at capture, unwrapped, 0 at the first frame.
    pub conveyor_angle_rad: f64,
    /// The disc centre's image, if detected.
    pub center_px: Option<PixelPoint>,
    /// The reference mark's image, if detected.
    pub reference_px: Option<PixelPoint>,
    /// Every feature of the part in its fixed order, or `None` unless all were detected.
    pub part_px: Option<Vec<PixelPoint, MAX_PART_FEATURES>>,
    /// The end effector, when this frame shows it.
    pub effector: Option<EffectorSighting>,
    /// The disc's rim measured in this frame (this project's addition to
    /// the log: a reader that does not know it ignores it).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rim: Option<RimObservation>,
}

/// The disc's rim (the circle of radius `disc_radius_m` on the disc's top)
/// as one frame shows it: an ellipse in pinhole pixels.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct RimObservation {
    /// The ellipse's centre, px.
    pub centre_px: PixelPoint,
    /// Its semi-axes along its own axes, px.
    pub semi_axes_px: [f64; 2],
    /// Angle of its first axis from the image's u axis, rad.
    pub angle_rad: f64,
    /// Standard deviation of its mean radius `sqrt(a b)` from this frame, px.
    pub sigma_px: f64,
}

/// A rigid transform `p_to = rotation * p_from + translation_m`; `rotation` is a list of rows.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct RigidTransform {
    /// Rows of the rotation matrix.
    pub rotation: [[f64; 3]; 3],
    /// The translation, m.
    pub translation_m: Point3,
}

/// The camera's pose found by the virtual rotation (paper Section 2.1).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct CameraEstimate {
    /// Height of the optical centre above the disc plane (`disc_from_camera.translation_m[2]`).
    pub height_m: f64,
    /// `disc_from_camera` (the camera's pose in the disc frame).
    pub disc_from_camera: RigidTransform,
}

/// The part in the rotating frame (paper Eqs 3 to 8).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PartEstimate {
    /// Each feature point in the rotating frame; z is its height above the disc.
    pub features_m: Vec<Point3, MAX_PART_FEATURES>,
    /// 3-D mean of the feature points.
    pub position_m: Point3,
    /// Angle of feature 0 -> feature 1 in the rotating XY-plane.
    pub yaw_rad: f64,
}

/// `p_base = Rz(yaw) * p_disc + translation` (paper Eqs 13 and 14).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct BaseFromDisc {
    /// Angle of the disc's X axis in the base frame, wrapped to (-pi, pi].
    pub yaw_rad: f64,
    /// The disc centre in the base frame.
    pub translation_m: Point3,
}

/// How well the estimate explains the observations.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct CalibrationQuality {
    /// Frames that contributed at least one detection.
    pub frames_used: u32,
    /// Square root of the mean squared 2-D reprojection distance per point.
    pub rms_reprojection_px: f64,
    /// Frames whose end-effector sighting was used for `base_from_disc`.
    #[serde(default)]
    pub effector_frames_used: u32,
    /// Detections rejected as gross outliers.
    #[serde(default)]
    pub outliers_rejected: u32,
    /// Pixel noise measured from the residuals at the estimate: a robust
    /// per-axis standard deviation, px (0 when not measured).
    #[serde(default)]
    pub pixel_sigma_px: f64,
}

/// What a calibration of a log prints.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CalibrationResult {
    /// The camera's pose.
    pub camera: CameraEstimate,
    /// The part in the rotating frame.
    pub part: PartEstimate,
    /// The robot base relative to the disc (Eqs 10 to 15).
    pub base_from_disc: BaseFromDisc,
    /// How well the estimate fits its data.
    pub quality: CalibrationQuality,
}
