//! Torque to sign-magnitude PWM, as pure functions: the joint torques `tau`
//! of the paper's control law (Eq 23, the torques of the dynamic model Eq 16)
//! reach the motors only through these duties.
//!
//! The servo amplifiers take a direction line and a PWM magnitude: the drive
//! delivers its rated torque at 100 % duty and scales linearly below it (a
//! current-mode amplifier: torque is proportional to motor current, which is
//! proportional to duty). So the duty for a joint torque `tau` is
//! `|tau| / tau_rated`, clipped to 1, and the direction line carries the sign.
//! Clipping is the same saturation the controller already expects at the
//! torque limits (its `torque_limits` are these rated values).
//!
//! This file uses nothing but `core`, so its unit tests run on the host without
//! the board: `rustc --edition 2021 --test sign_magnitude.rs -o
//! /tmp/sign_magnitude && /tmp/sign_magnitude` (see `firmware/README.md`).

/// One joint's amplifier command.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SignMagnitude {
    /// Direction line: `true` drives the joint in the negative direction.
    pub reverse: bool,
    /// Magnitude, as a fraction of the rated torque: always in `[0, 1]`.
    pub duty: f32,
}

impl SignMagnitude {
    /// Zero torque (direction line low).
    pub const OFF: SignMagnitude = SignMagnitude {
        reverse: false,
        duty: 0.0,
    };
}

/// The amplifier command for torque `tau_nm` on a drive rated `tau_rated_nm`
/// (its torque at 100 % duty).
///
/// Total: a non-finite torque, or a rating that is not a positive finite
/// number, gives [`SignMagnitude::OFF`] (the board rejects non-finite torques
/// before this is reached, and its ratings are checked at compile time; this
/// only keeps a bad value from ever becoming full duty, which `f32::min` would
/// make of a NaN).
pub fn torque_to_command(tau_nm: f32, tau_rated_nm: f32) -> SignMagnitude {
    let rated_ok = tau_rated_nm.is_finite() && tau_rated_nm > 0.0;
    if !tau_nm.is_finite() || !rated_ok {
        return SignMagnitude::OFF;
    }
    let duty = tau_nm.abs() / tau_rated_nm;
    SignMagnitude {
        reverse: tau_nm < 0.0,
        duty: if duty > 1.0 { 1.0 } else { duty },
    }
}

/// The compare value for `duty` (a fraction in `[0, 1]`) on a PWM channel whose
/// 100 % value is `full_scale` (the timer's period in counts), rounded to the
/// nearest count and never above `full_scale` (the HAL rejects larger values).
/// Anything outside `[0, 1]`, NaN included, is clipped to the range.
pub fn duty_counts(duty: f32, full_scale: u32) -> u32 {
    let duty = if duty.is_nan() || duty <= 0.0 {
        0.0
    } else if duty >= 1.0 {
        1.0
    } else {
        duty
    };
    // f32 has 24 bits of mantissa: for a 16-bit period the product and the
    // +0.5 each round by at most 2^-9 counts, so the result is within
    // 0.5 + 2^-8 counts of the exact duty (a 1/8400 step is 12 ppm anyway).
    let counts = duty * full_scale as f32 + 0.5;
    // `as` saturates float to integer; the min keeps the HAL's bound even
    // where the f32 product rounds up past `full_scale`.
    (counts as u32).min(full_scale)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The PUMA 560 ratings the board uses (N m at 100 % duty).
    const RATED: [f32; 6] = [97.6, 186.4, 89.4, 24.2, 20.1, 21.3];

    struct Rng(u64);

    impl Rng {
        fn next(&mut self) -> u64 {
            self.0 ^= self.0 >> 12;
            self.0 ^= self.0 << 25;
            self.0 ^= self.0 >> 27;
            self.0.wrapping_mul(0x2545_F491_4F6C_DD1D)
        }

        /// Uniform in [-1, 1).
        fn signed_unit(&mut self) -> f32 {
            ((self.next() >> 40) as f32 / (1u64 << 24) as f32) * 2.0 - 1.0
        }
    }

    #[test]
    fn rated_torque_is_full_duty_and_sign_sets_direction() {
        for &rated in &RATED {
            assert_eq!(
                torque_to_command(rated, rated),
                SignMagnitude {
                    reverse: false,
                    duty: 1.0
                }
            );
            assert_eq!(
                torque_to_command(-rated, rated),
                SignMagnitude {
                    reverse: true,
                    duty: 1.0
                }
            );
            let half = torque_to_command(-0.5 * rated, rated);
            assert!(half.reverse);
            assert!((half.duty - 0.5).abs() < 1e-6);
        }
    }

    /// Seeded random torques up to three times the rating: the command
    /// reproduces the torque (direction times duty times rating) inside the
    /// rating, and saturates at full duty with the right sign beyond it.
    #[test]
    fn random_torques_round_trip_or_saturate() {
        let mut rng = Rng(0x5EED_0000_0000_0006);
        for _ in 0..100_000 {
            for &rated in &RATED {
                let tau = 3.0 * rated * rng.signed_unit();
                let command = torque_to_command(tau, rated);
                assert!((0.0..=1.0).contains(&command.duty));
                assert_eq!(command.reverse, tau < 0.0);
                let sign = if command.reverse { -1.0 } else { 1.0 };
                let reproduced = sign * command.duty * rated;
                if tau.abs() <= rated {
                    assert!((reproduced - tau).abs() <= 1e-6 * rated, "{tau} {rated}");
                } else {
                    assert_eq!(command.duty, 1.0);
                }
            }
        }
    }

    #[test]
    fn bad_values_turn_the_drive_off() {
        for tau in [f32::NAN, f32::INFINITY, f32::NEG_INFINITY] {
            assert_eq!(torque_to_command(tau, 97.6), SignMagnitude::OFF);
        }
        for rated in [0.0, -1.0, f32::NAN, f32::INFINITY] {
            assert_eq!(torque_to_command(10.0, rated), SignMagnitude::OFF);
        }
        assert_eq!(torque_to_command(0.0, 97.6), SignMagnitude::OFF);
        assert!(!torque_to_command(-0.0, 97.6).reverse);
    }

    #[test]
    fn duty_counts_round_and_stay_in_range() {
        // The two timer periods at 20 kHz: 168 MHz / 20 kHz and 84 MHz / 20 kHz.
        for full_scale in [8400u32, 4200] {
            assert_eq!(duty_counts(0.0, full_scale), 0);
            assert_eq!(duty_counts(1.0, full_scale), full_scale);
            assert_eq!(duty_counts(0.5, full_scale), full_scale / 2);
            assert_eq!(duty_counts(f32::NAN, full_scale), 0);
            assert_eq!(duty_counts(-3.0, full_scale), 0);
            assert_eq!(duty_counts(7.0, full_scale), full_scale);
            assert_eq!(duty_counts(f32::INFINITY, full_scale), full_scale);
        }
        let mut rng = Rng(0x5EED_0000_0000_0007);
        for _ in 0..100_000 {
            let full_scale = 1 + (rng.next() % 65_536) as u32;
            let duty = rng.signed_unit().abs();
            let counts = duty_counts(duty, full_scale);
            assert!(counts <= full_scale);
            let exact = f64::from(duty) * f64::from(full_scale);
            let error = (f64::from(counts) - exact).abs();
            assert!(error <= 0.5 + 1.0 / 256.0, "{duty} {full_scale}: {error}");
        }
    }
}
