//! Camera triggers and the encoder values latched with them.
//!
//! The controller fires the camera and, in the same instant, latches the
//! conveyor count (and the joint angles, for the end-effector sighting). The
//! camera's feature frame comes back later, carrying the trigger id; pairing it
//! with the latched values means vision latency never biases theta (the frame's
//! `conveyor_angle_rad` is the angle at capture, not at arrival). Frames may come
//! back late or out of order; a frame whose trigger has been overwritten by
//! `N` newer triggers is refused (stale).

/// Values latched at one camera trigger.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LatchedSample {
    /// The trigger the camera was fired with.
    pub trigger_id: u32,
    /// Unwrapped conveyor count at the trigger.
    pub conveyor_counts: i64,
    /// Controller time at the trigger.
    pub time_us: u64,
    /// Joint angles at the trigger (rad), for the end-effector sighting.
    pub joint_q: [f32; 6],
}

/// A record kept per trigger: the latched values, maybe with more context.
pub trait Triggered: Copy {
    /// The trigger this record was latched at.
    fn trigger_id(&self) -> u32;
}

impl Triggered for LatchedSample {
    fn trigger_id(&self) -> u32 {
        self.trigger_id
    }
}

/// The last `N` triggers awaiting their frames.
#[derive(Debug, Clone)]
pub struct TriggerLatch<const N: usize, T: Triggered = LatchedSample> {
    slots: [Option<T>; N],
    next: usize,
}

impl<const N: usize, T: Triggered> Default for TriggerLatch<N, T> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const N: usize, T: Triggered> TriggerLatch<N, T> {
    /// No trigger pending.
    pub const fn new() -> Self {
        Self {
            slots: [None; N],
            next: 0,
        }
    }

    /// Records a trigger, overwriting the oldest pending one when full.
    pub fn latch(&mut self, sample: T) {
        if let Some(slot) = self.slots.get_mut(self.next) {
            *slot = Some(sample);
        }
        self.next = if self.next + 1 >= N { 0 } else { self.next + 1 };
    }

    /// The values latched for `trigger_id`, removed from the latch; `None` when the
    /// trigger is unknown or stale.
    pub fn take(&mut self, trigger_id: u32) -> Option<T> {
        self.slots
            .iter_mut()
            .find(|slot| matches!(slot, Some(s) if s.trigger_id() == trigger_id))
            .and_then(Option::take)
    }

    /// Triggers still awaiting their frames.
    pub fn pending(&self) -> usize {
        self.slots.iter().filter(|s| s.is_some()).count()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample(id: u32) -> LatchedSample {
        LatchedSample {
            trigger_id: id,
            conveyor_counts: i64::from(id) * 100,
            time_us: u64::from(id) * 200_000,
            joint_q: [0.0; 6],
        }
    }

    #[test]
    fn pairs_out_of_order_frames_and_refuses_stale_and_repeated_ones() {
        let mut latch = TriggerLatch::<4>::new();
        for id in 1..=6 {
            latch.latch(sample(id));
        }
        assert_eq!(latch.pending(), 4);
        assert_eq!(latch.take(5).map(|s| s.conveyor_counts), Some(500));
        assert_eq!(latch.take(3).map(|s| s.conveyor_counts), Some(300));
        assert_eq!(latch.take(1), None, "overwritten by newer triggers");
        assert_eq!(latch.take(5), None, "already paired");
        assert_eq!(latch.pending(), 2);
    }

    #[test]
    fn a_zero_capacity_latch_holds_nothing_and_does_not_panic() {
        let mut latch = TriggerLatch::<0>::new();
        latch.latch(sample(1));
        assert_eq!(latch.take(1), None);
    }
}
