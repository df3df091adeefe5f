//! The gripper's geometry, known from its drawing (not calibrated): where its
//! grasp point and the two marks the camera sees sit on the flange.
//!
//! The paper's Section 3.2 calibrates the robot base against the disc from two
//! end-effector points whose base-frame positions the robot's encoders give;
//! these are those two points.

use nalgebra::{convert, Isometry3, RealField, Vector3};

/// From the flange (frame {6}) to the grasp point between the fingertips, along
/// the flange's z axis (which points down when the gripper does).
pub const TOOL_LENGTH_M: f64 = 0.12;

/// The two marks on the gripper's body, in the flange frame: 0.16 m apart
/// across the wrist, so that the segment between them is horizontal when the
/// gripper points down (Eq 15 needs it not parallel to Z). Along the flange's y axis:
/// the pick holds the wrist's yaw at the start pose's relative to the arm's
/// azimuth, which puts the flange's x axis in the forearm's vertical plane,
/// so a mark on x sits under the forearm in the overhead camera's view (on
/// x, mark 0 was hidden in 88 % of the frames it was in view). 8 cm out, not
/// 5: at 5 cm the wrist still half hid mark 0 in about half of its labelled
/// frames, which moved its image's centroid by 0.5 px; the wider pair also
/// measures the camera's scale better (Eq 15).
pub const EFFECTOR_MARKS_FLANGE_M: [[f64; 3]; 2] = [[0.0, 0.08, 0.03], [0.0, -0.08, 0.03]];

/// The grasp point in the base frame for a flange pose.
pub fn tool_point_base<T: RealField + Copy>(base_from_flange: &Isometry3<T>) -> Vector3<T> {
    (base_from_flange * nalgebra::Point3::new(T::zero(), T::zero(), convert(TOOL_LENGTH_M))).coords
}

/// The two marks in the base frame for a flange pose.
pub fn effector_marks_base<T: RealField + Copy>(
    base_from_flange: &Isometry3<T>,
) -> [Vector3<T>; 2] {
    EFFECTOR_MARKS_FLANGE_M.map(|[x, y, z]| {
        (base_from_flange * nalgebra::Point3::new(convert::<f64, T>(x), convert(y), convert(z)))
            .coords
    })
}

/// The flange position that puts the grasp point at `tool_base` with the gripper
/// pointing straight down (the offset is along the vertical, so velocity and
/// acceleration are the same for both points).
pub fn flange_for_tool_down<T: RealField + Copy>(tool_base: &Vector3<T>) -> Vector3<T> {
    tool_base + Vector3::new(T::zero(), T::zero(), convert(TOOL_LENGTH_M))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::planning::gripper_down_rotation;
    use nalgebra::{Translation3, UnitQuaternion};

    #[test]
    fn a_downward_gripper_has_its_grasp_point_below_the_flange_and_level_marks() {
        let flange = Vector3::new(0.5, -0.2, 0.4);
        let pose = Isometry3::from_parts(
            Translation3::from(flange),
            UnitQuaternion::from_rotation_matrix(&gripper_down_rotation(0.3_f64)),
        );
        let tool = tool_point_base(&pose);
        assert!((tool - (flange - Vector3::new(0.0, 0.0, TOOL_LENGTH_M))).norm() < 1e-12);
        assert!((flange_for_tool_down(&tool) - flange).norm() < 1e-12);
        let [a, b] = effector_marks_base(&pose);
        assert!((a.z - b.z).abs() < 1e-12, "marks level when pointing down");
        assert!(((a - b).norm() - 0.16).abs() < 1e-12);
        assert!(a.z < flange.z && a.z > tool.z);
    }
}
