//! The camera trigger and the encoder latch at one instant: the trigger line
//! rises and every counter (six joint timers, the conveyor's count) is read
//! straight after it, so the counts the controller pairs with a trigger id are
//! those of the exposure. The caller runs [`latch`] inside one critical
//! section, so no interrupt (the conveyor's EXTI edges, the UART, the time
//! driver) lands between the edge and the last read.
//!
//! Hardware capture is not used: the joint timers decode in encoder mode on
//! their CH1/CH2 inputs, so a capture of CNT at the trigger edge would need
//! the trigger wired to a CH3 or CH4 input of each of the six timers (six
//! more pins, several of them taken: PE13/PE14 are direction lines, PA2/PA3
//! the link, PB8/PB9 PWM), and the conveyor's count is kept in software by
//! the EXTI handler, which no timer can capture. What is left is the skew
//! between the line's edge (the store to GPIOD_BSRR) and the last counter
//! read; `firmware/README.md` gives it from the disassembly of the built image.
//!
//! Pure logic over [`LatchHardware`] (only `core`), so the order is checked by
//! a host unit test: `rustc --edition 2021 --test latch.rs -o /tmp/latch && /tmp/latch`.

/// What the latch touches, in the order it touches it.
pub trait LatchHardware {
    /// Drives the camera trigger line: high exposes (on its rising edge).
    fn set_trigger(&mut self, high: bool);
    /// The six joint timers' 16-bit counters, joint 1 first, read back to back.
    fn joint_counters(&self) -> [u16; 6];
    /// The conveyor encoder's count (wrapping at 2^32).
    fn conveyor_counter(&self) -> u32;
}

/// The raw counts read at the latch.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct LatchedCounts {
    pub joints: [u16; 6],
    pub conveyor: u32,
}

/// Sets the trigger line (high when `camera_trigger`, else low), then reads
/// every counter. Call inside one critical section.
#[inline(always)]
pub fn latch<H: LatchHardware>(hardware: &mut H, camera_trigger: bool) -> LatchedCounts {
    hardware.set_trigger(camera_trigger);
    LatchedCounts {
        joints: hardware.joint_counters(),
        conveyor: hardware.conveyor_counter(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use core::cell::Cell;

    /// Encoders that all move one count per register access (each access is
    /// one tick of a clock), and a trigger line whose rising edge is stamped.
    struct MovingEncoders {
        clock: Cell<u32>,
        line_high: bool,
        rising_edge_at: Option<u32>,
        accesses: Cell<u32>,
    }

    impl MovingEncoders {
        fn tick(&self) -> u32 {
            self.accesses.set(self.accesses.get() + 1);
            let now = self.clock.get();
            self.clock.set(now + 1);
            now
        }
    }

    impl LatchHardware for MovingEncoders {
        fn set_trigger(&mut self, high: bool) {
            let now = self.tick();
            if high && !self.line_high {
                self.rising_edge_at = Some(now);
            }
            self.line_high = high;
        }
        fn joint_counters(&self) -> [u16; 6] {
            // Six reads, one tick each, joint 1 first.
            core::array::from_fn(|joint| (self.tick() as u16).wrapping_add(1_000 * joint as u16))
        }
        fn conveyor_counter(&self) -> u32 {
            self.tick().wrapping_mul(3)
        }
    }

    fn encoders(start: u32) -> MovingEncoders {
        MovingEncoders {
            clock: Cell::new(start),
            line_high: false,
            rising_edge_at: None,
            accesses: Cell::new(0),
        }
    }

    #[test]
    fn the_counts_are_read_right_after_the_trigger_edge() {
        for start in [0u32, 7, 65_530, u32::MAX - 20] {
            let mut hardware = encoders(start);
            let latched = latch(&mut hardware, true);
            let edge = hardware.rising_edge_at.unwrap_or_else(|| panic!("no edge"));
            // Every counter within the seven reads that follow the edge.
            for (joint, &count) in latched.joints.iter().enumerate() {
                let at_edge = (edge as u16).wrapping_add(1_000 * joint as u16);
                let after = count.wrapping_sub(at_edge);
                assert!(
                    (1..=6).contains(&after),
                    "joint {joint}: {after} ticks after"
                );
            }
            let conveyor_after = latched.conveyor.wrapping_sub(edge.wrapping_mul(3)) / 3;
            assert_eq!(conveyor_after, 7);
            assert_eq!(
                hardware.accesses.get(),
                8,
                "one store and seven reads, nothing else"
            );
            assert!(hardware.line_high);
        }
    }

    #[test]
    fn without_a_trigger_the_line_falls_and_the_counts_are_still_read() {
        let mut hardware = encoders(100);
        let _ = latch(&mut hardware, true);
        let latched = latch(&mut hardware, false);
        assert!(!hardware.line_high);
        assert_eq!(latched.joints[0], 109);
        // Back high: a new edge, a new instant.
        let _ = latch(&mut hardware, true);
        assert_eq!(hardware.rising_edge_at, Some(116));
    }
}
