//! Bringing the arm to rest on its holding brakes with the drives off, when
//! nothing will move it again until the host starts over.
//!
//! Why: after a pick has ended (`Done`, `Faulted`) the controller holds the
//! arm still with its servos, and after the host link is lost it stops and
//! then holds too. Holding on the servos for ever leaves the arm hanging on
//! its drives' current, which a drive fault, a power dip or the next
//! configuration (a new controller) interrupts. So a board that owns its
//! drives and brakes (the real board, on its ticker) parks:
//!
//! 1. `Active`: the pick drives as usual, the brakes are released.
//! 2. Parking starts when the pick has ended and the arm has been at rest
//!    for [`PARK_AFTER_REST_US`], or when no frame has come from the host for
//!    [`LINK_LOSS_PARK_US`] (a bounded hold: whatever the arm does by then,
//!    it is put on its brakes; the pick itself has stopped at the link
//!    timeout, 0.5 s).
//! 3. `Engaging`: the brake output drops (engage) while the drives still
//!    hold the arm, for [`BRAKE_ENGAGE_US`], the time a spring-applied brake
//!    takes to bite; an arm on a vertical axis does not sag in between.
//! 4. `Parked`: brakes engaged, drives off, latched until the host sends a
//!    configuration that is accepted ([`Parking::restart`]).
//!
//! A drive fault or an emergency stop does not wait for any of this: the
//! drives go off and the brakes drop in the same period (the interlock).

/// A pick that has ended and an arm at rest for this long park: long enough
/// for the pick's own hold to settle (`PickSettings::hold_settle_s`) and for
/// a host to look at the result, short enough not to leave the arm hanging
/// on its servos.
pub const PARK_AFTER_REST_US: u64 = 2_000_000;
/// No frame from the host for this long parks the arm whatever it is doing:
/// the pick stopped at the link timeout (0.5 s) and has had 2.5 s to come to
/// rest.
pub const LINK_LOSS_PARK_US: u32 = 3_000_000;
/// The time a holding brake takes to engage after its coil is switched off
/// (spring-applied brakes of this size: 20 to 50 ms); the drives hold the
/// arm for this long before they go off.
pub const BRAKE_ENGAGE_US: u64 = 100_000;

/// What the parking sequence is told every control period.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ParkingInput {
    /// The sample's time, microseconds.
    pub time_us: u64,
    /// The pick has ended (`Done` or `Faulted`).
    pub pick_ended: bool,
    /// Every joint slower than `reconfigure::REST_SPEED_RAD_S` (encoders).
    pub at_rest: bool,
    /// Microseconds since the last valid frame from the host.
    pub since_host_frame_us: u32,
}

/// What the board does this period.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ParkingOutput {
    /// Drop the brake output (the brakes engage).
    pub brake_engaged: bool,
    /// The drives may be on (the interlock still decides).
    pub drives_allowed: bool,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
/// Where the parking sequence stands (see the module's steps).
pub enum ParkState {
    /// The pick drives; the brakes are released.
    Active,
    /// The brakes engage while the drives still hold the arm.
    Engaging,
    /// Brakes engaged, drives off, until a configuration is accepted.
    Parked,
}

/// The sequence above; one per control loop.
#[derive(Debug, Clone, PartialEq)]
pub struct Parking {
    state: ParkState,
    /// When the arm was first seen at rest with the pick ended (Active), or
    /// when the brakes were dropped (Engaging).
    since_us: Option<u64>,
}

impl Default for Parking {
    fn default() -> Self {
        Self::new()
    }
}

impl Parking {
    /// Active: nothing parked.
    pub const fn new() -> Self {
        Parking {
            state: ParkState::Active,
            since_us: None,
        }
    }

    /// Where the sequence stands.
    pub fn state(&self) -> ParkState {
        self.state
    }

    /// A new configuration was accepted: the new pick may drive again.
    pub fn restart(&mut self) {
        *self = Self::new();
    }

    /// One control period.
    pub fn period(&mut self, input: &ParkingInput) -> ParkingOutput {
        match self.state {
            ParkState::Active => {
                let resting = input.pick_ended && input.at_rest;
                self.since_us = if resting {
                    Some(self.since_us.unwrap_or(input.time_us))
                } else {
                    None
                };
                let rested_long = self
                    .since_us
                    .is_some_and(|t| input.time_us.saturating_sub(t) >= PARK_AFTER_REST_US);
                if rested_long || input.since_host_frame_us >= LINK_LOSS_PARK_US {
                    self.state = ParkState::Engaging;
                    self.since_us = Some(input.time_us);
                }
            }
            ParkState::Engaging => {
                let since = self.since_us.unwrap_or(input.time_us);
                if input.time_us.saturating_sub(since) >= BRAKE_ENGAGE_US {
                    self.state = ParkState::Parked;
                }
            }
            ParkState::Parked => {}
        }
        self.output()
    }

    fn output(&self) -> ParkingOutput {
        match self.state {
            ParkState::Active => ParkingOutput {
                brake_engaged: false,
                drives_allowed: true,
            },
            ParkState::Engaging => ParkingOutput {
                brake_engaged: true,
                drives_allowed: true,
            },
            ParkState::Parked => ParkingOutput {
                brake_engaged: true,
                drives_allowed: false,
            },
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const PERIOD_US: u64 = 1_000;

    fn input(time_us: u64, pick_ended: bool, at_rest: bool, since_host: u32) -> ParkingInput {
        ParkingInput {
            time_us,
            pick_ended,
            at_rest,
            since_host_frame_us: since_host,
        }
    }

    /// Runs periods until `until_us`; returns the first time each state was
    /// output.
    fn run(
        parking: &mut Parking,
        from_us: u64,
        until_us: u64,
        f: impl Fn(u64) -> ParkingInput,
    ) -> (Option<u64>, Option<u64>) {
        let (mut engaging, mut parked) = (None, None);
        let mut t = from_us;
        while t <= until_us {
            let out = parking.period(&f(t));
            match parking.state() {
                ParkState::Engaging => {
                    assert_eq!(
                        out,
                        ParkingOutput {
                            brake_engaged: true,
                            drives_allowed: true
                        }
                    );
                    engaging.get_or_insert(t);
                }
                ParkState::Parked => {
                    assert_eq!(
                        out,
                        ParkingOutput {
                            brake_engaged: true,
                            drives_allowed: false
                        }
                    );
                    parked.get_or_insert(t);
                }
                ParkState::Active => {
                    assert_eq!(
                        out,
                        ParkingOutput {
                            brake_engaged: false,
                            drives_allowed: true
                        }
                    );
                }
            }
            t += PERIOD_US;
        }
        (engaging, parked)
    }

    #[test]
    fn a_running_pick_with_its_host_is_never_parked() {
        let mut parking = Parking::new();
        let (engaging, parked) = run(&mut parking, 0, 20_000_000, |t| {
            input(t, false, t % 2 == 0, 5_000)
        });
        assert_eq!((engaging, parked), (None, None));
    }

    #[test]
    fn an_ended_pick_at_rest_parks_after_its_hold_then_its_brakes_bite() {
        let mut parking = Parking::new();
        // Ended at 1 s, still moving until 1.5 s.
        let (engaging, parked) = run(&mut parking, 0, 10_000_000, |t| {
            input(t, t >= 1_000_000, t >= 1_500_000, 1_000)
        });
        assert_eq!(engaging, Some(1_500_000 + PARK_AFTER_REST_US));
        assert_eq!(
            parked,
            Some(1_500_000 + PARK_AFTER_REST_US + BRAKE_ENGAGE_US)
        );
    }

    #[test]
    fn a_lost_link_parks_within_its_bound_even_if_the_arm_still_moves() {
        let mut parking = Parking::new();
        let lost_at = 2_000_000u64;
        let (engaging, parked) = run(&mut parking, 0, 10_000_000, |t| {
            let since = t.saturating_sub(lost_at).max(1_000);
            input(t, false, false, u32::try_from(since).unwrap_or(u32::MAX))
        });
        assert_eq!(engaging, Some(lost_at + u64::from(LINK_LOSS_PARK_US)));
        assert_eq!(
            parked,
            Some(lost_at + u64::from(LINK_LOSS_PARK_US) + BRAKE_ENGAGE_US)
        );
    }

    #[test]
    fn parked_is_latched_until_a_new_configuration() {
        let mut parking = Parking::new();
        run(&mut parking, 0, 4_000_000, |t| input(t, true, true, 1_000));
        assert_eq!(parking.state(), ParkState::Parked);
        // The link comes back and the arm is pushed: still parked.
        let out = parking.period(&input(4_001_000, false, false, 0));
        assert!(!out.drives_allowed && out.brake_engaged);
        parking.restart();
        let out = parking.period(&input(4_002_000, false, false, 0));
        assert!(out.drives_allowed && !out.brake_engaged);
    }

    #[test]
    fn resting_must_be_continuous() {
        let mut parking = Parking::new();
        // At rest except for one period every second: never 2 s in a row.
        let (engaging, _) = run(&mut parking, 0, 10_000_000, |t| {
            input(t, true, t % 1_000_000 != 0, 1_000)
        });
        assert_eq!(engaging, None);
    }
}
