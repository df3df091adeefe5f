//! The six servo amplifiers: sign-magnitude PWM (20 kHz), a direction line
//! per joint and one common enable line.
//!
//! | joint | PWM (magnitude) | timer, clock | direction | rated torque at 100 % |
//! | --- | --- | --- | --- | --- |
//! | 1 | PE5 | TIM9 CH1, 168 MHz | PE7 | 97.6 N m |
//! | 2 | PE6 | TIM9 CH2, 168 MHz | PE8 | 186.4 N m |
//! | 3 | PB8 | TIM10 CH1, 168 MHz | PE10 | 89.4 N m |
//! | 4 | PB9 | TIM11 CH1, 168 MHz | PE12 | 24.2 N m |
//! | 5 | PA6 | TIM13 CH1, 84 MHz | PE13 | 20.1 N m |
//! | 6 | PA7 | TIM14 CH1, 84 MHz | PE14 | 21.3 N m |
//!
//! Amplifier enable: PE15, active high. It is driven low before any PWM pin
//! is configured, so the amplifiers stay off from reset (fit a pull-down on
//! the amplifier side for the few microseconds before the firmware runs).
//!
//! PWM is edge-aligned, active high, 20 kHz: a period of 8400 timer counts on
//! TIM9-11 and 4200 on TIM13/14 (their APB1 timer clock is half), so the duty
//! resolution is 1/8400 or 1/4200 of the rated torque.
//!
//! Direction and duty change together. The compare registers are preloaded
//! (a new duty takes effect at the timer's next update event, the next PWM
//! period, at most 50 us later) while a direction line changes at once, so
//! writing the direction first would drive the old magnitude the new way for
//! up to one PWM period at every zero crossing. At a sign change a drive
//! therefore writes duty 0, forces an update event (TIMx_EGR.UG: the zero
//! takes effect now and the PWM period restarts with the output low), then
//! switches the direction line, then writes the new duty, which takes effect
//! at the next update event (`shared::safety::reversal`, whose test checks
//! the order against a model of the preloaded timer). In between the drive
//! delivers zero torque for under one PWM period. TIM9 carries joints 1 and
//! 2: a forced update on one also applies the other's preloaded duty (its
//! newest command) early and restarts its period once, which is harmless.
//! Without a sign change only the duty is written.
//!
//! Each joint torque passes through the joint's motor sign
//! (`super::JOINT_SIGNS`) on its way to the drive, and the enable is not
//! raised while a board fault is latched (`crate::board::fail_safe`).

use embassy_stm32::gpio::{Level, Output, OutputType, Speed};
use embassy_stm32::peripherals::{
    PA6, PA7, PB8, PB9, PE10, PE12, PE13, PE14, PE15, PE5, PE6, PE7, PE8, TIM10, TIM11, TIM13,
    TIM14, TIM9,
};
use embassy_stm32::time::Hertz;
use embassy_stm32::timer::low_level::CountingMode;
use embassy_stm32::timer::simple_pwm::{PwmPin, SimplePwm, SimplePwmChannel};
use embassy_stm32::Peri;

use embassy_stm32::pac;
use shared::robot::table::TORQUE_MAX;
use shared::safety::{sign_magnitude_steps, DriveStep};

use super::sign_magnitude::{duty_counts, torque_to_command, SignMagnitude};
use super::JOINT_SIGNS;
use crate::board::{fail_safe, JOINTS};

/// PWM carrier frequency: above hearing, and 8400 counts of resolution at
/// 168 MHz.
pub const PWM_HZ: u32 = 20_000;

/// Each drive's torque at 100 % duty (N m), joint 1 first: the PUMA 560's
/// maximum joint torques (`shared::robot::table::TORQUE_MAX`, AKB86 Table 7),
/// which are also the controller's torque limits, so a torque the controller
/// may command maps onto the duty range and full duty is the arm's limit.
pub const TAU_RATED_NM: [f32; JOINTS] = rated_torques();

const fn rated_torques() -> [f32; JOINTS] {
    let mut rated = [0.0f32; JOINTS];
    let mut joint = 0;
    while joint < JOINTS {
        // Indexing in a const fn: a bad index is a compile error, not a panic.
        #[allow(clippy::indexing_slicing)]
        {
            rated[joint] = TORQUE_MAX[joint] as f32;
            assert!(rated[joint] > 0.0 && rated[joint] < f32::INFINITY);
        }
        joint += 1;
    }
    rated
}

/// The peripherals the amplifiers take.
pub struct ServoPeripherals {
    pub tim9: Peri<'static, TIM9>,
    pub tim10: Peri<'static, TIM10>,
    pub tim11: Peri<'static, TIM11>,
    pub tim13: Peri<'static, TIM13>,
    pub tim14: Peri<'static, TIM14>,
    pub pwm1: Peri<'static, PE5>,
    pub pwm2: Peri<'static, PE6>,
    pub pwm3: Peri<'static, PB8>,
    pub pwm4: Peri<'static, PB9>,
    pub pwm5: Peri<'static, PA6>,
    pub pwm6: Peri<'static, PA7>,
    pub dir1: Peri<'static, PE7>,
    pub dir2: Peri<'static, PE8>,
    pub dir3: Peri<'static, PE10>,
    pub dir4: Peri<'static, PE12>,
    pub dir5: Peri<'static, PE13>,
    pub dir6: Peri<'static, PE14>,
    pub enable: Peri<'static, PE15>,
}

/// One joint's PWM channel (the timers differ in type, so one variant each).
enum MagnitudeChannel {
    Tim9(SimplePwmChannel<'static, TIM9>),
    Tim10(SimplePwmChannel<'static, TIM10>),
    Tim11(SimplePwmChannel<'static, TIM11>),
    Tim13(SimplePwmChannel<'static, TIM13>),
    Tim14(SimplePwmChannel<'static, TIM14>),
}

impl MagnitudeChannel {
    fn set_duty(&mut self, duty: f32) {
        match self {
            MagnitudeChannel::Tim9(ch) => ch.set_duty_cycle(duty_counts(duty, ch.max_duty_cycle())),
            MagnitudeChannel::Tim10(ch) => {
                ch.set_duty_cycle(duty_counts(duty, ch.max_duty_cycle()))
            }
            MagnitudeChannel::Tim11(ch) => {
                ch.set_duty_cycle(duty_counts(duty, ch.max_duty_cycle()))
            }
            MagnitudeChannel::Tim13(ch) => {
                ch.set_duty_cycle(duty_counts(duty, ch.max_duty_cycle()))
            }
            MagnitudeChannel::Tim14(ch) => {
                ch.set_duty_cycle(duty_counts(duty, ch.max_duty_cycle()))
            }
        }
    }

    /// Forces an update event on the channel's timer (EGR.UG): the preloaded
    /// duty takes effect now and the counter restarts.
    fn apply_now(&mut self) {
        match self {
            MagnitudeChannel::Tim9(_) => pac::TIM9.egr().write(|w| w.set_ug(true)),
            MagnitudeChannel::Tim10(_) => pac::TIM10.egr().write(|w| w.set_ug(true)),
            MagnitudeChannel::Tim11(_) => pac::TIM11.egr().write(|w| w.set_ug(true)),
            MagnitudeChannel::Tim13(_) => pac::TIM13.egr().write(|w| w.set_ug(true)),
            MagnitudeChannel::Tim14(_) => pac::TIM14.egr().write(|w| w.set_ug(true)),
        }
    }

    fn enable(&mut self) {
        match self {
            MagnitudeChannel::Tim9(ch) => ch.enable(),
            MagnitudeChannel::Tim10(ch) => ch.enable(),
            MagnitudeChannel::Tim11(ch) => ch.enable(),
            MagnitudeChannel::Tim13(ch) => ch.enable(),
            MagnitudeChannel::Tim14(ch) => ch.enable(),
        }
    }
}

/// One joint's amplifier inputs.
struct Drive {
    magnitude: MagnitudeChannel,
    direction: Output<'static>,
    /// Where the direction line stands (`true`: reverse).
    line_reverse: bool,
}

impl Drive {
    fn new(mut magnitude: MagnitudeChannel, direction: Output<'static>) -> Self {
        magnitude.set_duty(0.0);
        magnitude.enable();
        Drive {
            magnitude,
            direction,
            line_reverse: false,
        }
    }

    /// Direction and duty together: see the module documentation.
    fn command(&mut self, command: SignMagnitude) {
        for step in sign_magnitude_steps(self.line_reverse, command.reverse, command.duty) {
            match step {
                DriveStep::Duty(duty) => self.magnitude.set_duty(duty),
                DriveStep::ApplyNow => self.magnitude.apply_now(),
                DriveStep::Direction(reverse) => {
                    self.direction
                        .set_level(if reverse { Level::High } else { Level::Low });
                    self.line_reverse = reverse;
                }
            }
        }
    }
}

/// The six drives and their common enable.
pub struct ServoAmplifiers {
    drives: [Drive; JOINTS],
    enable: Output<'static>,
}

fn pwm_pin<
    T: embassy_stm32::timer::GeneralInstance4Channel,
    C: embassy_stm32::timer::TimerChannel,
>(
    pin: Peri<'static, impl embassy_stm32::timer::TimerPin<T, C>>,
) -> PwmPin<'static, T, C> {
    PwmPin::new(pin, OutputType::PushPull)
}

fn direction(pin: Peri<'static, impl embassy_stm32::gpio::Pin>) -> Output<'static> {
    Output::new(pin, Level::Low, Speed::Low)
}

impl ServoAmplifiers {
    /// Enable low first, then the direction lines low and every PWM at 0 %.
    pub fn new(p: ServoPeripherals) -> Self {
        let enable = Output::new(p.enable, Level::Low, Speed::Low);
        let hz = Hertz(PWM_HZ);
        let mode = CountingMode::EdgeAlignedUp;
        let tim9 = SimplePwm::new(
            p.tim9,
            Some(pwm_pin(p.pwm1)),
            Some(pwm_pin(p.pwm2)),
            None,
            None,
            hz,
            mode,
        )
        .split();
        let tim10 = SimplePwm::new(p.tim10, Some(pwm_pin(p.pwm3)), None, None, None, hz, mode);
        let tim11 = SimplePwm::new(p.tim11, Some(pwm_pin(p.pwm4)), None, None, None, hz, mode);
        let tim13 = SimplePwm::new(p.tim13, Some(pwm_pin(p.pwm5)), None, None, None, hz, mode);
        let tim14 = SimplePwm::new(p.tim14, Some(pwm_pin(p.pwm6)), None, None, None, hz, mode);
        let drives = [
            Drive::new(MagnitudeChannel::Tim9(tim9.ch1), direction(p.dir1)),
            Drive::new(MagnitudeChannel::Tim9(tim9.ch2), direction(p.dir2)),
            Drive::new(
                MagnitudeChannel::Tim10(tim10.split().ch1),
                direction(p.dir3),
            ),
            Drive::new(
                MagnitudeChannel::Tim11(tim11.split().ch1),
                direction(p.dir4),
            ),
            Drive::new(
                MagnitudeChannel::Tim13(tim13.split().ch1),
                direction(p.dir5),
            ),
            Drive::new(
                MagnitudeChannel::Tim14(tim14.split().ch1),
                direction(p.dir6),
            ),
        ];
        ServoAmplifiers { drives, enable }
    }

    /// Writes the six joint torques (already validated finite by the
    /// caller), each through its joint's motor sign, as direction and duty,
    /// then enables the amplifiers, unless a board fault is latched: then
    /// they are disabled instead (a handler that ran after this period's
    /// checks must not see its enable raised again).
    pub fn drive(&mut self, torque_nm: &[f32; JOINTS]) {
        if fail_safe::latched().is_some() {
            self.disable();
            return;
        }
        for (joint, ((drive, &tau), &rated)) in self
            .drives
            .iter_mut()
            .zip(torque_nm.iter())
            .zip(TAU_RATED_NM.iter())
            .enumerate()
        {
            drive.command(torque_to_command(
                JOINT_SIGNS.motor_torque(joint, tau),
                rated,
            ));
        }
        self.enable.set_high();
    }

    /// The enable line is high (the drives are on).
    pub fn enabled(&self) -> bool {
        self.enable.is_set_high()
    }

    /// Enable low first (the amplifiers stop at once), then zero duty and
    /// direction lines low, so a later enable starts from zero torque.
    pub fn disable(&mut self) {
        self.enable.set_low();
        for drive in self.drives.iter_mut() {
            drive.command(SignMagnitude::OFF);
        }
    }
}
