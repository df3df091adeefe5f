//! The order of a sign-magnitude drive's writes at a torque sign change.
//!
//! A sign-magnitude amplifier takes a direction line (a GPIO: it changes the
//! moment it is written) and a PWM duty from a timer whose compare register
//! is preloaded (a write takes effect at the timer's next update event, the
//! start of the next PWM period: up to 50 us at 20 kHz). Writing the
//! direction and then the duty would drive the previous magnitude the new
//! way for up to one PWM period at every zero crossing: full duty reversed
//! for 50 us at a saturated reversal.
//!
//! So at a sign change the drive (1) writes duty 0 to the preload register,
//! (2) forces an update event (the timer's UG bit: the preload is
//! transferred at once and the PWM period restarts, its output low at zero
//! duty), (3) switches the direction line, (4) writes the new duty, which
//! takes effect at the next update event, in the new direction. In between
//! the drive delivers zero torque, never the old magnitude the wrong way.
//! Without a sign change only the duty is written (preloaded, glitch-free).

use heapless::Vec;

/// One write to a drive.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum DriveStep {
    /// Write the duty (fraction of full scale) to the preloaded compare
    /// register.
    Duty(f32),
    /// Force an update event: the preloaded duty takes effect now.
    ApplyNow,
    /// Set the direction line (`true`: reverse).
    Direction(bool),
}

/// The writes that take a drive whose direction line stands at
/// `line_reverse` to (`reverse`, `duty`), in order.
pub fn sign_magnitude_steps(line_reverse: bool, reverse: bool, duty: f32) -> Vec<DriveStep, 4> {
    let steps: &[DriveStep] = if line_reverse == reverse {
        &[DriveStep::Duty(duty)]
    } else {
        &[
            DriveStep::Duty(0.0),
            DriveStep::ApplyNow,
            DriveStep::Direction(reverse),
            DriveStep::Duty(duty),
        ]
    };
    let mut out = Vec::new();
    for step in steps {
        // At most four steps: capacity four.
        let _ = out.push(*step);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A timer channel with a preloaded compare register and a direction
    /// line, recording the direction each duty was commanded for.
    struct Model {
        line_reverse: bool,
        /// (duty, the direction it was commanded for) in effect.
        active: (f32, bool),
        preload: (f32, bool),
        /// A duty above zero was ever in effect with the line the other way.
        wrong_way: bool,
    }

    impl Model {
        fn check(&mut self) {
            if self.active.0 > 0.0 && self.active.1 != self.line_reverse {
                self.wrong_way = true;
            }
        }

        /// Carries out `steps` for a command (`reverse`, duty), then the
        /// period ends (update event).
        fn run(&mut self, steps: &[DriveStep], reverse: bool) {
            for step in steps {
                match *step {
                    DriveStep::Duty(duty) => self.preload = (duty, reverse),
                    DriveStep::ApplyNow => self.active = self.preload,
                    DriveStep::Direction(line) => self.line_reverse = line,
                }
                self.check();
            }
            self.active = self.preload;
            self.check();
        }
    }

    fn model() -> Model {
        Model {
            line_reverse: false,
            active: (0.0, false),
            preload: (0.0, false),
            wrong_way: false,
        }
    }

    /// Saturated reversals back and forth: the planned steps never drive a
    /// duty the wrong way; the naive order (direction, then duty) does, and
    /// the model sees it (so the test tells the two orders apart).
    #[test]
    fn a_reversal_never_drives_the_old_duty_the_new_way() {
        let commands = [
            (false, 1.0),
            (true, 1.0),
            (true, 0.3),
            (false, 0.7),
            (false, 0.0),
            (true, 0.5),
        ];
        let mut planned = model();
        let mut old = model();
        for &(reverse, duty) in &commands {
            let steps = sign_magnitude_steps(planned.line_reverse, reverse, duty);
            planned.run(&steps, reverse);
            assert_eq!(planned.active, (duty, reverse));
            assert_eq!(planned.line_reverse, reverse);
            old.run(
                &[DriveStep::Direction(reverse), DriveStep::Duty(duty)],
                reverse,
            );
        }
        assert!(!planned.wrong_way);
        assert!(old.wrong_way);
    }

    #[test]
    fn without_a_sign_change_only_the_duty_is_written() {
        let steps = sign_magnitude_steps(true, true, 0.4);
        assert_eq!(steps.as_slice(), &[DriveStep::Duty(0.4)]);
        let steps = sign_magnitude_steps(true, false, 0.4);
        assert_eq!(steps.len(), 4);
    }
}
