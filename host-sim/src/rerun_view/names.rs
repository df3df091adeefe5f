//! The recording's entity paths, timelines, label names and colours, in one
//! place so that the 3-D cell, the camera's image and the plots agree.

use nalgebra::{Matrix3, Vector3};
use rerun::Color;
use shared::protocol::PointLabel;

use crate::front_end::pictures::{
    DISC_CENTRE_COLOUR, EFFECTOR_COLOUR, PART_FEATURE_COLOUR, REFERENCE_COLOUR, UNLABELLED_COLOUR,
};
use crate::overlay::Rgb;

/// Simulated time, seconds (the world's clock; 0 at the run's start).
pub const SIM_TIME: &str = "sim_time";
/// The camera trigger of the last frame exposed (the frame index).
pub const FRAME: &str = "frame";

/// The robot's base frame: everything 3-D is under it.
pub const CELL: &str = "cell";
/// The disc frame (`base_from_disc`, Eq 13 and 14).
pub const DISC: &str = "cell/disc";
/// The rotating frame (`disc_from_rotating`, the conveyor angle, Eq 2).
pub const DISC_ROTATING: &str = "cell/disc/rotating";
pub const DROP_OFF: &str = "cell/drop_off";
/// The arm's links through the DH frames' origins, from the true joint angles.
pub const ARM_LINKS: &str = "cell/arm/links";
/// The tool frame at the gripper's grasp point.
pub const ARM_TOOL: &str = "cell/arm/tool";
pub const ARM_MARKS: &str = "cell/arm/marks";
/// Where the controller wants the tool (its telemetry).
pub const TOOL_REFERENCE: &str = "cell/arm/tool_reference";
/// The camera: its true pose and pinhole; everything under it is 2-D.
pub const CAMERA: &str = "cell/camera";
pub const CAMERA_IMAGE: &str = "cell/camera/image";
/// The vision computer's labels where it found the blobs (through the lens).
pub const CAMERA_LABELS: &str = "cell/camera/labels";
/// Blobs left unlabelled.
pub const CAMERA_BLOBS: &str = "cell/camera/blobs";
/// The labelled points the controller was sent (pinhole pixels).
pub const CAMERA_RECEIVED: &str = "cell/camera/received";
pub const PART_TRUE_POSE: &str = "cell/part/true_pose";
pub const PART_TRUE_FEATURES: &str = "cell/part/true_features";
pub const PART_ESTIMATE_POSE: &str = "cell/part/estimate_pose";
pub const PART_ESTIMATE: &str = "cell/part/estimate";
/// |estimate - truth| of the part's grasp point, mm.
pub const PART_ERROR_MM: &str = "plots/part_position_error_mm";
/// The controller's own 1-sigma of the part's position, mm.
pub const PART_SIGMA_MM: &str = "plots/part_sigma_mm";
/// The part's yaw error modulo pi, degrees.
pub const PART_YAW_ERROR_DEG: &str = "plots/part_yaw_error_deg";
/// The controller's pick phases as they change.
pub const PHASES: &str = "log/phase";

pub const TRUE_COLOUR: Rgb = [60, 230, 60];
pub const ESTIMATE_COLOUR: Rgb = [255, 140, 0];
pub const ARM_COLOUR: Rgb = [200, 200, 210];
pub const DISC_COLOUR: Rgb = [90, 110, 160];
pub const DROP_OFF_COLOUR: Rgb = [255, 255, 255];

pub fn colour([r, g, b]: Rgb) -> Color {
    Color::from_rgb(r, g, b)
}

/// A label's name on the pictures: `centre`, `ref`, `f<i>`, `e<i>`.
pub fn point_label_name(label: PointLabel) -> String {
    match label {
        PointLabel::DiscCenter => "centre".into(),
        PointLabel::Reference => "ref".into(),
        PointLabel::Part(i) => format!("f{i}"),
        PointLabel::Effector(i) => format!("e{i}"),
    }
}

/// The label the vision computer sends for a front end's label.
/// A label's colour (the front end's pictures' colours).
pub fn point_label_colour(label: PointLabel) -> Color {
    colour(match label {
        PointLabel::DiscCenter => DISC_CENTRE_COLOUR,
        PointLabel::Reference => REFERENCE_COLOUR,
        PointLabel::Part(_) => PART_FEATURE_COLOUR,
        PointLabel::Effector(_) => EFFECTOR_COLOUR,
    })
}

pub fn unlabelled_colour() -> Color {
    colour(UNLABELLED_COLOUR)
}

/// A point as the viewer takes it (single precision).
pub fn point(p: &Vector3<f64>) -> [f32; 3] {
    [p.x as f32, p.y as f32, p.z as f32]
}

/// A rotation's columns (the child frame's axes in the parent's), as the
/// viewer's column-major 3x3.
pub fn columns(rotation: &Matrix3<f64>) -> [[f32; 3]; 3] {
    let column = |i: usize| point(&rotation.column(i).into_owned());
    [column(0), column(1), column(2)]
}
