//! When a new cell configuration may replace the running controller.
//!
//! Why a gate: accepting a configuration builds a new pick that starts from
//! its `Start` step, with the gripper open and no memory of the motion the
//! old one was making. Arriving mid-motion it would drop the old controller's
//! deceleration (no brake), and arriving with a part in the jaws it would open
//! them. So a configuration is accepted only when the old controller has
//! nothing left to do: none yet, or its pick has ended (`Done`, `Faulted`) or
//! not begun (`Idle`); the arm is at rest by its encoders; the gripper is open
//! with nothing in it; and, where the board owns the drives and brakes (a
//! real board on its ticker), the drives are off with the arm on its brakes.
//! Otherwise the host gets a refusal with its cause
//! ([`crate::protocol::ErrorCode::ConfigurationRefusedActive`], detail
//! [`ReconfigureRefusal::detail`]) and the old controller runs on.
//!
//! The rule is here, not in the firmware, so that the firmware's control
//! loop and the in-process controller (`crate::app::ControllerApp`) apply the
//! same one, and it is unit-tested on the host.

use crate::protocol::PickPhase;

use super::JOINTS;

/// Fastest joint speed (rad/s, encoders alone, over the interlock's ten
/// periods) still taken as at rest: about 3 deg/s, well above the
/// encoders' quantisation (one count over ten periods is about 0.005 rad/s
/// on the cells tested) and well below any speed the pick commands while it
/// moves (its slowest searches run at tenths of a rad/s).
pub const REST_SPEED_RAD_S: f32 = 0.05;

/// What the gate looks at, taken at the end of the last control period.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CellState {
    /// The pick's phase, `None` before any configuration was accepted.
    pub phase: Option<PickPhase>,
    /// Joint speeds from the encoders (rad/s), `None` until enough samples.
    pub joint_speed_rad_s: Option<[f32; JOINTS]>,
    /// The gripper is commanded closed, or its switch sees a part.
    pub gripper_holds: bool,
    /// The amplifiers are enabled (their brakes released).
    pub drives_on: bool,
    /// Whether this board's drives must be off for a reconfiguration: a real
    /// board, whose amplifiers and brakes the firmware owns. In lock step the
    /// plant (its drives, their watchdog and brakes) is the simulator's, and
    /// a pick that has ended holds the arm still through it.
    pub drives_off_required: bool,
}

/// Why a configuration was refused.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum ReconfigureRefusal {
    /// The pick is moving the arm (or stopping it) in this phase.
    PickActive {
        /// The pick's phase.
        phase: PickPhase,
    },
    /// A joint (0-based) moves faster than [`REST_SPEED_RAD_S`], or its
    /// speed is not a number.
    JointMoving {
        /// The joint, 0-based.
        joint: u8,
    },
    /// Too few samples to know the joints' speeds.
    MotionUnknown,
    /// The gripper is closed or holds a part: a new pick would open it.
    GripperHolds,
    /// The drives are on: the arm is not on its brakes.
    DrivesOn,
}

impl ReconfigureRefusal {
    /// The error report's detail: the kind in the upper half (1 pick active,
    /// 2 joint moving, 3 motion unknown, 4 gripper holds, 5 drives on) and
    /// the phase's index or the joint's (0-based) in the lower half.
    pub fn detail(self) -> u32 {
        match self {
            ReconfigureRefusal::PickActive { phase } => 0x1_0000 | phase_index(phase),
            ReconfigureRefusal::JointMoving { joint } => 0x2_0000 | u32::from(joint),
            ReconfigureRefusal::MotionUnknown => 0x3_0000,
            ReconfigureRefusal::GripperHolds => 0x4_0000,
            ReconfigureRefusal::DrivesOn => 0x5_0000,
        }
    }
}

/// `PickPhase`'s index in declaration order (its postcard tag): a fieldless
/// enum without explicit discriminants casts to exactly that.
fn phase_index(phase: PickPhase) -> u32 {
    phase as u32
}

/// Whether a new configuration may replace the controller now; the first
/// reason against it otherwise (phase, then gripper, then motion, then
/// drives).
pub fn check_reconfigure(state: &CellState) -> Result<(), ReconfigureRefusal> {
    let Some(phase) = state.phase else {
        // Never configured: every period has kept the drives off.
        return Ok(());
    };
    if !matches!(
        phase,
        PickPhase::Idle | PickPhase::Done | PickPhase::Faulted
    ) {
        return Err(ReconfigureRefusal::PickActive { phase });
    }
    if state.gripper_holds {
        return Err(ReconfigureRefusal::GripperHolds);
    }
    // A configured pick still `Idle` has run no period: nothing moved it.
    if phase != PickPhase::Idle {
        let Some(speeds) = state.joint_speed_rad_s else {
            return Err(ReconfigureRefusal::MotionUnknown);
        };
        for (joint, speed) in speeds.iter().enumerate() {
            // Less or equal only: a NaN speed is not at rest either.
            let at_rest = matches!(
                speed.abs().partial_cmp(&REST_SPEED_RAD_S),
                Some(core::cmp::Ordering::Less | core::cmp::Ordering::Equal)
            );
            if !at_rest {
                return Err(ReconfigureRefusal::JointMoving {
                    joint: u8::try_from(joint).unwrap_or(u8::MAX),
                });
            }
        }
    }
    if state.drives_off_required && state.drives_on {
        return Err(ReconfigureRefusal::DrivesOn);
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parked(phase: PickPhase) -> CellState {
        CellState {
            phase: Some(phase),
            joint_speed_rad_s: Some([0.0; JOINTS]),
            gripper_holds: false,
            drives_on: false,
            drives_off_required: true,
        }
    }

    #[test]
    fn the_first_configuration_is_always_accepted() {
        let state = CellState {
            phase: None,
            joint_speed_rad_s: None,
            gripper_holds: false,
            drives_on: false,
            drives_off_required: true,
        };
        assert_eq!(check_reconfigure(&state), Ok(()));
    }

    #[test]
    fn an_ended_pick_at_rest_on_its_brakes_may_be_replaced() {
        for phase in [PickPhase::Done, PickPhase::Faulted, PickPhase::Idle] {
            assert_eq!(check_reconfigure(&parked(phase)), Ok(()), "{phase:?}");
        }
    }

    #[test]
    fn a_pick_in_motion_is_not_replaced() {
        for phase in [
            PickPhase::SearchEffector,
            PickPhase::Intercept,
            PickPhase::Track,
            PickPhase::Lift,
            PickPhase::Stopping,
        ] {
            assert_eq!(
                check_reconfigure(&parked(phase)),
                Err(ReconfigureRefusal::PickActive { phase })
            );
        }
        let refusal = ReconfigureRefusal::PickActive {
            phase: PickPhase::Stopping,
        };
        assert_eq!(refusal.detail(), 0x1_000E);
    }

    #[test]
    fn a_moving_joint_or_unknown_motion_refuses() {
        let mut state = parked(PickPhase::Faulted);
        let mut speeds = [0.0; JOINTS];
        speeds[3] = -2.0 * REST_SPEED_RAD_S;
        state.joint_speed_rad_s = Some(speeds);
        assert_eq!(
            check_reconfigure(&state),
            Err(ReconfigureRefusal::JointMoving { joint: 3 })
        );
        speeds[3] = f32::NAN;
        state.joint_speed_rad_s = Some(speeds);
        assert_eq!(
            check_reconfigure(&state),
            Err(ReconfigureRefusal::JointMoving { joint: 3 })
        );
        speeds[3] = 0.5 * REST_SPEED_RAD_S;
        state.joint_speed_rad_s = Some(speeds);
        assert_eq!(check_reconfigure(&state), Ok(()));
        state.joint_speed_rad_s = None;
        assert_eq!(
            check_reconfigure(&state),
            Err(ReconfigureRefusal::MotionUnknown)
        );
    }

    #[test]
    fn a_part_in_the_jaws_is_never_dropped_by_a_new_configuration() {
        let mut state = parked(PickPhase::Faulted);
        state.gripper_holds = true;
        assert_eq!(
            check_reconfigure(&state),
            Err(ReconfigureRefusal::GripperHolds)
        );
    }

    #[test]
    fn drives_must_be_off_only_where_the_board_owns_them() {
        let mut state = parked(PickPhase::Done);
        state.drives_on = true;
        assert_eq!(check_reconfigure(&state), Err(ReconfigureRefusal::DrivesOn));
        state.drives_off_required = false;
        assert_eq!(check_reconfigure(&state), Ok(()));
    }

    #[test]
    fn the_phase_index_is_the_postcard_tag() {
        for phase in [PickPhase::Idle, PickPhase::Locate, PickPhase::Faulted] {
            let mut buffer = [0u8; 4];
            let tag = postcard::to_slice(&phase, &mut buffer).map(|b| b.to_vec());
            assert_eq!(tag, Ok(vec![phase_index(phase) as u8]), "{phase:?}");
        }
    }
}
