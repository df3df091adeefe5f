//! x4 quadrature decoding as a pure state table, for the conveyor encoder that
//! no timer is left to decode (see `conveyor.rs`).
//!
//! The two channels form a 2-bit Gray code `AB`; one full cycle is four edges.
//! Counting every edge of both channels (x4) gives the encoder's full
//! resolution, which is what the joint timers' encoder mode also does, so the
//! conveyor count has the same meaning as a joint count.
//!
//! Convention: the count goes up when A leads B (`AB`: 00 -> 10 -> 11 -> 01 ->
//! 00). Swapping the A and B wires reverses the sign.
//!
//! This file uses nothing but `core`, so its unit tests run on the host without
//! the board: `rustc --edition 2021 --test quadrature.rs -o /tmp/quadrature &&
//! /tmp/quadrature` (see `firmware/README.md`).

/// The two channel levels packed as `(A << 1) | B`: always 0 to 3.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct QuadratureState(u8);

impl QuadratureState {
    /// The state of two sampled channel levels.
    pub const fn from_levels(a_high: bool, b_high: bool) -> Self {
        QuadratureState(((a_high as u8) << 1) | (b_high as u8))
    }

    /// The packed bits, `(A << 1) | B`.
    pub const fn bits(self) -> u8 {
        self.0
    }
}

/// What one transition between two sampled states means.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum QuadratureStep {
    /// No change (e.g. the interrupt of an edge that was already counted, or a
    /// glitch shorter than the sampling).
    Hold,
    /// One edge forward: +1 count.
    Forward,
    /// One edge backward: -1 count.
    Backward,
    /// Both channels changed: at least one edge was missed and the direction
    /// is unknown, so nothing is counted (the caller counts these as errors).
    Skipped,
}

impl QuadratureStep {
    /// The change of the count, in encoder counts.
    pub const fn delta(self) -> i32 {
        match self {
            QuadratureStep::Forward => 1,
            QuadratureStep::Backward => -1,
            QuadratureStep::Hold | QuadratureStep::Skipped => 0,
        }
    }
}

use QuadratureStep::{Backward as B, Forward as F, Hold as H, Skipped as S};

/// The x4 state table, indexed by `(previous << 2) | current` (states as
/// `(A << 1) | B`). Rows are the previous state 00, 01, 10, 11.
const STEP_TABLE: [QuadratureStep; 16] = [
    // previous 00: to 00, 01, 10, 11
    H, B, F, S, //
    // previous 01: to 00, 01, 10, 11
    F, H, S, B, //
    // previous 10: to 00, 01, 10, 11
    B, S, H, F, //
    // previous 11: to 00, 01, 10, 11
    S, F, B, H, //
];

/// Decodes the transition from `previous` to `current`.
pub fn quadrature_step(previous: QuadratureState, current: QuadratureState) -> QuadratureStep {
    let index = usize::from((previous.bits() << 2) | current.bits());
    // Both states are below 4 by construction, so the index is below 16; the
    // fallback is unreachable and only keeps this free of a panicking index.
    STEP_TABLE
        .get(index)
        .copied()
        .unwrap_or(QuadratureStep::Skipped)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Position of each state along the forward Gray sequence 00, 10, 11, 01.
    fn phase(state: QuadratureState) -> i32 {
        match state.bits() {
            0b00 => 0,
            0b10 => 1,
            0b11 => 2,
            _ => 3,
        }
    }

    fn all_states() -> [QuadratureState; 4] {
        [(false, false), (false, true), (true, false), (true, true)]
            .map(|(a, b)| QuadratureState::from_levels(a, b))
    }

    /// The table agrees with the phase difference of the Gray code for all
    /// sixteen transitions (an independent formulation of the same decoder).
    #[test]
    fn table_matches_gray_code_phase_difference() {
        for previous in all_states() {
            for current in all_states() {
                let expected = match (phase(current) - phase(previous)).rem_euclid(4) {
                    0 => QuadratureStep::Hold,
                    1 => QuadratureStep::Forward,
                    3 => QuadratureStep::Backward,
                    _ => QuadratureStep::Skipped,
                };
                assert_eq!(
                    quadrature_step(previous, current),
                    expected,
                    "{previous:?} -> {current:?}"
                );
            }
        }
    }

    #[test]
    fn a_leading_b_counts_up() {
        let sequence = [(false, false), (true, false), (true, true), (false, true)];
        let mut state = QuadratureState::from_levels(false, false);
        let mut count = 0;
        for _ in 0..3 {
            for &(a, b) in sequence.iter().cycle().skip(1).take(4) {
                let next = QuadratureState::from_levels(a, b);
                count += quadrature_step(state, next).delta();
                state = next;
            }
        }
        assert_eq!(count, 12);
    }

    #[test]
    fn states_pack_a_high_and_b_low() {
        let bits = all_states().map(QuadratureState::bits);
        assert_eq!(bits, [0b00, 0b01, 0b10, 0b11]);
    }

    /// xorshift64*: a fixed-seed generator so the random walks are repeatable.
    struct Rng(u64);

    impl Rng {
        fn next(&mut self) -> u64 {
            self.0 ^= self.0 >> 12;
            self.0 ^= self.0 << 25;
            self.0 ^= self.0 >> 27;
            self.0.wrapping_mul(0x2545_F491_4F6C_DD1D)
        }
    }

    /// Channel levels of an encoder at integer position `position` (x4 counts).
    fn levels(position: i64) -> (bool, bool) {
        match position.rem_euclid(4) {
            0 => (false, false),
            1 => (true, false),
            2 => (true, true),
            _ => (false, true),
        }
    }

    /// A disc that moves back and forth at random, sampled at every edge plus
    /// random repeated samples (interrupts for edges already seen) and random
    /// glitches (a channel toggling and back between two samples): the
    /// decoded count follows the true position exactly, with a wrapping u32
    /// counter as the conveyor ISR keeps it.
    #[test]
    fn random_walks_decode_exactly() {
        for seed in 1..=50u64 {
            let mut rng = Rng(seed.wrapping_mul(0x9E37_79B9_7F4A_7C15));
            let mut position: i64 = (rng.next() % 1000) as i64 - 500;
            let (a, b) = levels(position);
            let mut state = QuadratureState::from_levels(a, b);
            let start = position;
            let mut count: u32 = 0;
            for _ in 0..20_000 {
                match rng.next() % 10 {
                    0 => {} // a spurious interrupt: the same state again
                    1..=5 => position += 1,
                    _ => position -= 1,
                }
                let (a, b) = levels(position);
                let next = QuadratureState::from_levels(a, b);
                let step = quadrature_step(state, next);
                assert_ne!(step, QuadratureStep::Skipped);
                count = count.wrapping_add_signed(step.delta());
                state = next;
            }
            assert_eq!(count, (position - start) as u32, "seed {seed}");
        }
    }

    /// Sampling only every other edge (an interrupt too late) is reported as
    /// skipped, never miscounted as a step in the wrong direction.
    #[test]
    fn missed_edges_are_reported_not_miscounted() {
        let mut rng = Rng(0xC0FF_EE00_1234_5678);
        for _ in 0..1000 {
            let position = (rng.next() % 4096) as i64;
            let direction = if rng.next() & 1 == 0 { 2 } else { -2 };
            let (a0, b0) = levels(position);
            let (a1, b1) = levels(position + direction);
            let step = quadrature_step(
                QuadratureState::from_levels(a0, b0),
                QuadratureState::from_levels(a1, b1),
            );
            assert_eq!(step, QuadratureStep::Skipped);
            assert_eq!(step.delta(), 0);
        }
    }
}
