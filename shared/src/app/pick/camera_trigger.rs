//! The camera's trigger: fired every `camera_period_ms`, on the first control
//! period at or after each due time, each trigger numbered so that the frame
//! that comes back pairs with the encoder values latched with it.

/// When the next trigger is due and its number.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct CameraTrigger {
    next_trigger_s: f32,
    next_trigger_id: u32,
}

impl CameraTrigger {
    /// Trigger 1 due at once.
    pub(super) fn new() -> Self {
        Self {
            next_trigger_s: 0.0,
            next_trigger_id: 1,
        }
    }

    /// Whether a trigger is due at `now_s`: the one rule, for the period
    /// and for a board that asks before it latches its encoders.
    pub(super) fn due(&self, now_s: f32) -> bool {
        now_s + 1e-6 >= self.next_trigger_s
    }

    /// The trigger to fire at `now_s`, if one is due. A period missed
    /// altogether is not made up: the next trigger is a period from now.
    pub(super) fn fire(&mut self, now_s: f32, period_s: f32) -> Option<u32> {
        if !self.due(now_s) {
            return None;
        }
        self.next_trigger_s += period_s;
        if self.next_trigger_s <= now_s {
            self.next_trigger_s = now_s + period_s;
        }
        let trigger_id = self.next_trigger_id;
        self.next_trigger_id = self.next_trigger_id.wrapping_add(1);
        Some(trigger_id)
    }
}

#[cfg(test)]
mod tests {
    use super::CameraTrigger;

    #[test]
    fn triggers_come_a_period_apart_and_skip_what_was_missed() {
        let mut trigger = CameraTrigger::new();
        assert_eq!(trigger.fire(0.0, 0.2), Some(1));
        assert_eq!(trigger.fire(0.1, 0.2), None);
        assert_eq!(trigger.fire(0.2, 0.2), Some(2));
        // A stall: the next trigger is a period after the late one.
        assert_eq!(trigger.fire(1.0, 0.2), Some(3));
        assert_eq!(trigger.fire(1.1, 0.2), None);
        assert_eq!(trigger.fire(1.2, 0.2), Some(4));
    }
}
