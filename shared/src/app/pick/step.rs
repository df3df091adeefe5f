//! The state machine's steps (paper Fig 3, finer than the [`PickPhase`] the
//! pick reports) and what each step implies: its phase, whether it needs fresh
//! frames, whether the view monitor watches it, whether the part is still on
//! the disc.

use crate::protocol::PickPhase;

/// The fine-grained steps behind the reported [`PickPhase`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Step {
    Start,
    /// To the start of the search's first sweep.
    SearchApproach,
    /// Sweeping joint 1's range at the search's radius `n` (`search`).
    SearchSweep(u8),
    /// Out or in to the search's radius `n`, at the end the last sweep reached.
    SearchShift(u8),
    /// Back over where the marks were seen, on the radius they were seen from.
    SearchReturn,
    /// Seen in passing only: slow pass `n` to and fro over where the marks
    /// were seen, for the frames a label needs.
    SearchLook(u8),
    /// The camera has seen the marks often enough and they have left its
    /// view: the sweep comes to rest, to go back over them.
    SearchHalt,
    EstimatePreliminary,
    CalibrateMove(u8),
    CalibrateDwell(u8),
    EstimateFinal,
    Locate,
    Intercept,
    /// The conveyor left the intercept's prediction: the arm comes to rest,
    /// returns to where the part was first located from, and locates it again.
    InterceptAbandoned,
    Relocate,
    Track,
    Descend,
    GraspSettle,
    GraspClose,
    Lift,
    PlaceTransfer,
    PlaceLower,
    Release,
    ReturnRaise,
    ReturnTransfer,
    Done,
    Stopping,
    Faulted,
}

impl Step {
    pub(super) fn phase(self) -> PickPhase {
        match self {
            Self::Start => PickPhase::Idle,
            Self::SearchApproach
            | Self::SearchSweep(_)
            | Self::SearchShift(_)
            | Self::SearchReturn
            | Self::SearchLook(_)
            | Self::SearchHalt => PickPhase::SearchEffector,
            Self::CalibrateMove(_) | Self::CalibrateDwell(_) => PickPhase::CalibrateBase,
            Self::EstimatePreliminary | Self::EstimateFinal => PickPhase::Estimating,
            Self::Locate | Self::InterceptAbandoned | Self::Relocate => PickPhase::Locate,
            Self::Intercept => PickPhase::Intercept,
            Self::Track => PickPhase::Track,
            Self::Descend => PickPhase::Descend,
            Self::GraspSettle | Self::GraspClose => PickPhase::Grasp,
            Self::Lift => PickPhase::Lift,
            Self::PlaceTransfer | Self::PlaceLower => PickPhase::Place,
            Self::Release => PickPhase::Release,
            Self::ReturnRaise | Self::ReturnTransfer => PickPhase::Return,
            Self::Done => PickPhase::Done,
            Self::Stopping => PickPhase::Stopping,
            Self::Faulted => PickPhase::Faulted,
        }
    }

    /// Steps that need fresh camera frames (before the grasp).
    pub(super) fn needs_vision(self) -> bool {
        matches!(
            self,
            Self::SearchApproach
                | Self::SearchSweep(_)
                | Self::SearchShift(_)
                | Self::SearchReturn
                | Self::SearchLook(_)
                | Self::SearchHalt
                | Self::CalibrateMove(_)
                | Self::CalibrateDwell(_)
                | Self::Locate
                | Self::Intercept
                | Self::InterceptAbandoned
                | Self::Relocate
                | Self::Track
                | Self::Descend
        )
    }

    /// Steps in which the view monitor checks the camera and the encoder
    /// against the final calibration: from it to the grasp.
    pub(super) fn watches_view(self) -> bool {
        matches!(
            self,
            Self::Locate
                | Self::Intercept
                | Self::InterceptAbandoned
                | Self::Relocate
                | Self::Track
                | Self::Descend
                | Self::GraspSettle
        )
    }

    /// Steps whose observations may feed the calibrator: the part still sits on the disc.
    pub(super) fn part_on_disc(self) -> bool {
        !matches!(
            self,
            Self::GraspClose
                | Self::Lift
                | Self::PlaceTransfer
                | Self::PlaceLower
                | Self::Release
                | Self::ReturnRaise
                | Self::ReturnTransfer
                | Self::Done
        )
    }

    /// Steps of a controlled stop and the hold after it.
    pub(super) fn stopping(self) -> bool {
        matches!(self, Self::Stopping | Self::Faulted)
    }

    /// Steps in which the arm follows the part: from the intercept to the
    /// gripper closing on it.
    pub(super) fn follows_part(self) -> bool {
        matches!(
            self,
            Self::Intercept | Self::Track | Self::Descend | Self::GraspSettle | Self::GraspClose
        )
    }
}
