//! The 3-D cell in the robot's base frame, from the world's truth: the disc
//! (`base_from_disc`, turning by the conveyor's true angle), the arm through
//! its DH frames' origins from the true joint angles, the tool frame and the
//! gripper's marks, the camera's true pose with its pinhole (the viewer draws
//! the frustum and puts the image in it) and the part where it truly is.

use anyhow::Result;
use nalgebra::{Matrix3, Vector3};
use rerun::{
    Cylinders3D, LineStrips3D, Pinhole, Points3D, RecordingStream, Transform3D, TransformAxes3D,
    ViewCoordinates,
};
use shared::app::tool::{effector_marks_base, tool_point_base};
use shared::robot::JointTrig;

use super::names::{self, colour, columns, point};
use crate::geometry::rotation_z;
use crate::world::camera::PinholeCamera;
use crate::world::dimensions::DISC_RADIUS_M;
use crate::world::{World, WorldTruth};

/// Segments of the disc's rim.
const RIM_SEGMENTS: usize = 96;
/// Drawn thickness of the disc, m (the world's disc is a plane).
const DISC_THICKNESS_M: f32 = 0.01;
/// Length of the drawn axes of the tool and the part poses, m.
const AXIS_LENGTH_M: f32 = 0.06;

/// What does not move: the base frame's axes and up direction, the disc's
/// pose and shape, the reference and centre marks in the rotating frame, the
/// drop-off.
pub fn log_fixed(rec: &RecordingStream, world: &World) -> Result<()> {
    rec.log_static(names::CELL, &ViewCoordinates::RIGHT_HAND_Z_UP())?;
    rec.log_static(names::CELL, &TransformAxes3D::new(0.2))?;
    let workcell = world.workcell();
    rec.log_static(
        names::DISC,
        &Transform3D::from_translation_mat3x3(
            point(&workcell.base_from_disc_translation_m),
            columns(&rotation_z(workcell.base_from_disc_yaw_rad)),
        ),
    )?;
    let radius = DISC_RADIUS_M as f32;
    rec.log_static(
        names::DISC,
        &Cylinders3D::from_lengths_and_radii([DISC_THICKNESS_M], [radius])
            .with_centers([[0.0, 0.0, -DISC_THICKNESS_M / 2.0]])
            .with_colors([rerun::Color::from_unmultiplied_rgba(90, 110, 160, 90)]),
    )?;
    let rim: Vec<[f32; 3]> = (0..=RIM_SEGMENTS)
        .map(|i| {
            let angle = std::f32::consts::TAU * i as f32 / RIM_SEGMENTS as f32;
            [radius * angle.cos(), radius * angle.sin(), 0.0]
        })
        .collect();
    rec.log_static(
        format!("{}/rim", names::DISC),
        &LineStrips3D::new([rim]).with_colors([colour(names::DISC_COLOUR)]),
    )?;
    // The spoke through the reference mark turns with the disc.
    let reference = workcell.reference_radius_m as f32;
    rec.log_static(
        format!("{}/spoke", names::DISC_ROTATING),
        &LineStrips3D::new([[[0.0, 0.0, 0.0], [radius, 0.0, 0.0]]])
            .with_colors([colour(names::DISC_COLOUR)]),
    )?;
    rec.log_static(
        format!("{}/marks", names::DISC_ROTATING),
        &Points3D::new([[0.0, 0.0, 0.0], [reference, 0.0, 0.0]])
            .with_labels(["centre", "ref"])
            .with_colors([
                names::point_label_colour(shared::protocol::PointLabel::DiscCenter),
                names::point_label_colour(shared::protocol::PointLabel::Reference),
            ])
            .with_radii([0.01]),
    )?;
    rec.log_static(
        names::DROP_OFF,
        &Points3D::new([point(&Vector3::from(world.drop_off_base()))])
            .with_labels(["drop-off"])
            .with_colors([colour(names::DROP_OFF_COLOUR)])
            .with_radii([0.02]),
    )?;
    Ok(())
}

/// The camera's pose in the base frame (`base_from_disc` after
/// `disc_from_camera`) with its pinhole: the viewer draws the frustum.
pub fn log_camera(rec: &RecordingStream, world: &World, camera: &PinholeCamera) -> Result<()> {
    let workcell = world.workcell();
    let base_from_camera: Matrix3<f64> =
        rotation_z(workcell.base_from_disc_yaw_rad) * camera.disc_from_camera_rotation;
    rec.log(
        names::CAMERA,
        &Transform3D::from_translation_mat3x3(
            point(&workcell.base_from_disc(&camera.optical_centre_disc)),
            columns(&base_from_camera),
        ),
    )?;
    let intrinsics = camera.intrinsics;
    let f = intrinsics.f_px as f32;
    // Columns: the pinhole's image_from_camera (u right, v down, z forward:
    // the viewer's default RDF camera, the contract's too).
    rec.log(
        names::CAMERA,
        &Pinhole::new([
            [f, 0.0, 0.0],
            [0.0, f, 0.0],
            [intrinsics.cx as f32, intrinsics.cy as f32, 1.0],
        ])
        .with_resolution([intrinsics.width as f32, intrinsics.height as f32])
        .with_image_plane_distance(0.15),
    )?;
    Ok(())
}

/// The moving things now: the disc's angle, the arm, the tool frame, the
/// gripper's marks and the part where it truly is.
pub fn log_moving(rec: &RecordingStream, world: &World, truth: &WorldTruth) -> Result<()> {
    rec.log(
        names::DISC_ROTATING,
        &Transform3D::from_mat3x3(columns(&rotation_z(truth.theta_rad))),
    )?;

    let model = world.plant().model();
    let q = world.plant().state().q;
    let chain = model.frame_chain_with(&JointTrig::new(&q));
    let flange = model.forward_kinematics(&q);
    let tool = tool_point_base(&flange);
    let mut links: Vec<[f32; 3]> = chain.origins.iter().map(point).collect();
    links.push(point(&tool));
    rec.log(
        names::ARM_LINKS,
        &LineStrips3D::new([links])
            .with_colors([colour(names::ARM_COLOUR)])
            .with_radii([0.012]),
    )?;
    rec.log(
        names::ARM_TOOL,
        &Transform3D::from_translation_mat3x3(
            point(&tool),
            columns(flange.rotation.to_rotation_matrix().matrix()),
        ),
    )?;
    rec.log(names::ARM_TOOL, &TransformAxes3D::new(AXIS_LENGTH_M))?;
    rec.log(
        names::ARM_MARKS,
        &Points3D::new(effector_marks_base(&flange).iter().map(point))
            .with_labels(["e0", "e1"])
            .with_colors([names::point_label_colour(
                shared::protocol::PointLabel::Effector(0),
            )])
            .with_radii([0.008]),
    )?;

    let features = world.part_features_base();
    rec.log(
        names::PART_TRUE_FEATURES,
        &Points3D::new(features.iter().map(point))
            .with_labels((0..features.len()).map(|i| format!("f{i}")))
            .with_colors([colour(names::TRUE_COLOUR)])
            .with_radii([0.006]),
    )?;
    log_pose(
        rec,
        names::PART_TRUE_POSE,
        &Vector3::from(truth.part_base_m),
        truth.part_yaw_rad,
    )
}

/// A part pose (grasp point and yaw about the base's z) as axes.
pub fn log_pose(
    rec: &RecordingStream,
    entity: &str,
    position_base_m: &Vector3<f64>,
    yaw_rad: f64,
) -> Result<()> {
    rec.log(
        entity,
        &Transform3D::from_translation_mat3x3(
            point(position_base_m),
            columns(&rotation_z(yaw_rad)),
        ),
    )?;
    rec.log(entity, &TransformAxes3D::new(AXIS_LENGTH_M))?;
    Ok(())
}
