//! The board seam: everything the application needs from the hardware, behind
//! small traits, with one implementation per board selected by a cargo
//! feature. The application (`crate::app`) only sees [`Board`] and these
//! traits, so it is the same code on both boards.
//!
//! - serial link to the vision computer / simulator: [`SerialLink`]
//!   (`embedded-io-async` `Read + Write`);
//! - the plant: [`PlantIo`] (joint and conveyor encoders in; servo torques,
//!   gripper and camera trigger out), and where control periods come from
//!   ([`ControlSource`]);
//! - a [`CycleCounter`] to measure the control cycle;
//! - a hardware [`Watchdog`] that the control loop feeds once per period (the
//!   STM32's IWDG; a documented no-op on the emulated board);
//! - constants: `CPU_HZ` (the nominal clock a control period's budget is
//!   counted against) and `CONTROL_IRQ` / `LINK_IRQ` (two spare NVIC lines for
//!   the interrupt executors; the board's handlers for them call
//!   `crate::executor::on_interrupt`).
//! - clock: the board's `embassy_time_driver::Driver` (the QEMU board's own
//!   driver on the CMSDK dual timer; embassy-stm32's TIM12 driver on the
//!   STM32F407), used through `embassy_time` by the application.

use core::fmt;

use shared::safety::InterlockSettings;

pub mod fail_safe;
pub mod interrupt_time;
#[cfg(any(
    all(feature = "board-qemu", not(feature = "free-run")),
    all(feature = "board-stm32f407", feature = "lock-step")
))]
pub mod lock_step;

#[cfg(all(feature = "board-qemu", feature = "board-stm32f407"))]
compile_error!(
    "select exactly one board: `--no-default-features --features board-qemu` or the default `board-stm32f407`"
);
#[cfg(not(any(feature = "board-qemu", feature = "board-stm32f407")))]
compile_error!("select a board feature: board-qemu or board-stm32f407");

#[cfg(feature = "board-qemu")]
pub mod qemu;
#[cfg(feature = "board-qemu")]
pub use qemu as active;

#[cfg(all(feature = "board-stm32f407", not(feature = "board-qemu")))]
pub mod stm32f407;
#[cfg(all(feature = "board-stm32f407", not(feature = "board-qemu")))]
pub use stm32f407 as active;

/// Joints of the PUMA 560.
pub const JOINTS: usize = 6;

/// Encoder counts per joint, joint 1 first.
pub type JointCounts = [i32; JOINTS];

/// What went wrong at the board level.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum BoardError {
    /// A joint's unwrapped encoder count left the protocol's `i32` range.
    #[cfg_attr(
        feature = "board-qemu",
        allow(dead_code, reason = "the emulated board has no encoders of its own")
    )]
    EncoderOutOfRange { joint: usize },
    /// A servo torque was NaN or infinite.
    NonFiniteTorque { joint: usize },
    /// The board has no such device: the emulated board's encoders and
    /// servos are the simulator's, reached through the link in lock step.
    #[cfg_attr(
        any(not(feature = "board-qemu"), feature = "free-run"),
        allow(
            dead_code,
            reason = "only the lock-step emulated board lacks its own devices"
        )
    )]
    NotOnThisBoard { device: &'static str },
    /// The emulated board running free has had no plant state from the host
    /// yet (its encoders are the simulated plant's, sent over the link).
    #[cfg_attr(
        not(feature = "free-run"),
        allow(
            dead_code,
            reason = "only the free-running emulated board reads a remote plant"
        )
    )]
    NoPlantState,
}

impl fmt::Display for BoardError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            BoardError::EncoderOutOfRange { joint } => write!(
                f,
                "encoder count of joint {} is outside the i32 range",
                joint + 1
            ),
            BoardError::NonFiniteTorque { joint } => {
                write!(f, "servo torque for joint {} is not finite", joint + 1)
            }
            BoardError::NotOnThisBoard { device } => write!(
                f,
                "{device}: not on this board (the simulator's, through the link in lock step)"
            ),
            BoardError::NoPlantState => {
                write!(f, "encoders: no plant state from the host's simulator yet")
            }
        }
    }
}

/// The same sentences as `Display`, in defmt's encoding (through
/// `Display2Format` the board would link core::fmt to format them).
impl defmt::Format for BoardError {
    fn format(&self, f: defmt::Formatter<'_>) {
        match self {
            BoardError::EncoderOutOfRange { joint } => defmt::write!(
                f,
                "encoder count of joint {} is outside the i32 range",
                joint + 1
            ),
            BoardError::NonFiniteTorque { joint } => {
                defmt::write!(f, "servo torque for joint {} is not finite", joint + 1)
            }
            BoardError::NotOnThisBoard { device } => defmt::write!(
                f,
                "{=str}: not on this board (the simulator's, through the link in lock step)",
                device
            ),
            BoardError::NoPlantState => {
                defmt::write!(f, "encoders: no plant state from the host's simulator yet")
            }
        }
    }
}

/// The byte link to the vision computer / simulator.
pub trait SerialLink: embedded_io_async::Read + embedded_io_async::Write {}

impl<T: embedded_io_async::Read + embedded_io_async::Write> SerialLink for T {}

/// Where the control loop's sensor samples come from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, defmt::Format)]
pub enum ControlSource {
    /// A fixed-rate ticker; the loop reads its plant's encoders
    /// ([`PlantIo::read_sample`]) and drives its outputs whenever its own
    /// clock says, whatever the plant does (the STM32F407's own devices; the
    /// emulated board built with `free-run`, whose plant is a simulator on
    /// the host running free on the host's clock).
    Ticker,
    /// Lock step with a simulated plant: every `SensorSample` frame from the
    /// link is one control period, answered with an `ActuatorCommand` frame
    /// (the emulated board). Deterministic whatever the emulator's speed.
    LockStep,
}

/// Homing's inputs (see [`PlantIo::read_homing_inputs`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HomingInputs {
    pub joint_pots_rad: [f32; JOINTS],
    pub joint_index_counts: [Option<i32>; JOINTS],
}

/// One reading of the plant's sensors.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct PlantReading {
    pub joint_counts: JointCounts,
    pub conveyor_counts: u32,
    pub part_in_gripper: bool,
    /// The emergency-stop chain is open (pressed, or a wire broken).
    pub emergency_stop: bool,
    /// A servo amplifier's fault output is active.
    pub drive_fault: bool,
}

/// The plant side of the control loop: encoders in, servo amplifiers, gripper
/// and camera trigger out. Called only from the control loop, once per period.
pub trait PlantIo {
    /// When the counts the next [`read_sample`](PlantIo::read_sample)
    /// returns were true, microseconds, on the clock the period's sample is
    /// stamped with: `now_us`, the period's start on the controller's clock,
    /// for a board that reads its own encoders now (the STM32F407); the
    /// plant's own stamp of its newest state for a plant that sends its state
    /// over the link (the emulated board running free), which `read_sample`
    /// then returns. The control loop decides the camera trigger on this
    /// instant, so the sample paired with a trigger carries the instant of
    /// its counts.
    fn reading_time_us(&mut self, now_us: u64) -> Result<u64, BoardError>;

    /// Joint encoder counts (unwrapped, joint 1 first), the conveyor
    /// encoder's raw hardware counter (it wraps; the controller unwraps it)
    /// and the gripper's part-present switch.
    ///
    /// With `camera_trigger` the camera trigger line rises here, at the
    /// instant the counts are latched (the STM32F407: one critical section
    /// that raises the line and reads every counter back to back), so the
    /// counts the controller pairs with the trigger are those of the
    /// exposure. Without it the line goes (or stays) low: a pulse is one
    /// control period wide.
    fn read_sample(&mut self, camera_trigger: bool) -> Result<PlantReading, BoardError>;

    /// Homing's inputs, read right after [`read_sample`](PlantIo::read_sample)
    /// and only while homing (the ADC's conversions would otherwise cost
    /// every pick period): each joint's potentiometer, rad, and its counter
    /// as its last index pulse latched it (`None` before the first), on the
    /// same scale as `read_sample`'s counts.
    fn read_homing_inputs(&mut self) -> Result<HomingInputs, BoardError> {
        Err(BoardError::NotOnThisBoard {
            device: "potentiometers and index inputs",
        })
    }

    /// Drives the servo amplifiers with the joint torques (N m) and the
    /// gripper. Rejects a non-finite torque before any output changes (then
    /// the drives are off).
    fn apply(&mut self, torque_nm: &[f32; JOINTS], gripper_closed: bool) -> Result<(), BoardError>;

    /// Stops driving all joints (zero torque, amplifiers disabled) and
    /// engages the holding brakes: an arm without its drives is held only by
    /// them.
    fn disable(&mut self);

    /// Engages (`true`) or releases the joints' holding brakes, separately
    /// from the amplifier enable: parking engages them while the drives still
    /// hold the arm, for as long as they take to bite
    /// (`shared::safety::parking`). Call after `apply`, so that a release
    /// follows the drives coming on.
    fn set_brakes(&mut self, engaged: bool);
}

/// A free-running counter for measuring the control cycle's cost: CPU cycles
/// on real silicon (DWT), emulated instructions on QEMU with `-icount`. A
/// handle is `Copy`: every task that measures holds one.
pub trait CycleCounter: Copy {
    /// The counter now (wraps).
    fn now(&self) -> u32;
    /// Instructions (or cycles) per count.
    fn scale(&self) -> u32;
    /// What one unit of `(now() - then) * scale()` is.
    fn cost_unit(&self) -> shared::protocol::CostUnit;
    /// The same as text, for logs.
    fn unit(&self) -> &'static str {
        match self.cost_unit() {
            shared::protocol::CostUnit::Cycles => "cycles",
            shared::protocol::CostUnit::Instructions => "instructions",
            shared::protocol::CostUnit::NotMeasured => "(not measured)",
            shared::protocol::CostUnit::Nanoseconds => "ns",
        }
    }
}

/// A hardware watchdog that resets the board when the control loop stops
/// running periods (a hung or crashed firmware: a fault handler's loop, a
/// higher-priority interrupt that never returns, a stopped time driver), so
/// that the reset takes the drives off.
///
/// The control loop calls [`feed`](Watchdog::feed) once per period, as soon
/// as the period's sample is in and before anything that can skip the rest of
/// the period. The first call arms it: no board arms it at boot. Once armed it
/// cannot be disarmed (the STM32's IWDG stops only at reset), so every later
/// period must feed it within the board's timeout. In ticker mode periods run
/// from the first tick whether or not the host has configured anything (an
/// unconfigured period disables the drives and goes on), so the watchdog is
/// armed about a millisecond after boot and an idle board waiting for its link
/// keeps feeding it: it is not reset for having no host. In lock step a
/// period is a sample from the host, so the first sample would arm it (the
/// emulated board's watchdog is a no-op, see `board::qemu`).
///
/// A trait of its own, not a method of [`PlantIo`]: it watches the firmware's
/// liveness, not a plant signal, and the two boards answer it differently
/// (the emulated board's plant is the simulator behind the link, which has
/// its own drive watchdog in simulated time). Like the plant it is moved into
/// the control loop's task, so nothing else can feed it and keep a stalled
/// loop's watchdog quiet; the other tasks are watched by the control loop
/// (the link timeout, the pick's job results).
pub trait Watchdog {
    /// Arms the watchdog on the first call; restarts its countdown on every
    /// call.
    fn feed(&mut self);
}

/// The watchdog of the emulated board and of the STM32F407 in lock step:
/// feeding it does nothing, on purpose.
///
/// QEMU's mps2-an386 does model the CMSDK APB watchdog (at 0x4000_8000,
/// clocked at 25 MHz, its interrupt on the NMI; the second expiry with RESEN
/// set resets the machine, QEMU's default `-watchdog-action`), and the
/// STM32F407 has its IWDG, so either could be fed here. But in lock step a
/// control period is a sample from the host, and a watchdog runs on while
/// the CPU sleeps waiting for that sample (QEMU's virtual clock at the
/// host's pace, with or without `-icount`). Fed once per period it would
/// time the host's pauses, not the firmware: the host thinking, a session
/// ending, or no host at all until the next session would reset the board;
/// and the loop also waits there for the worker's due results (seconds on a
/// 168 MHz M4F). Between sessions the wait is unbounded, so no timeout is
/// both long enough never to fire then and short enough ever to catch a
/// hang. A firmware that hangs in lock step is already seen where it
/// matters: the simulator gets no actuator command, and its drives' own
/// watchdog brakes the arm (5 ms, in simulated time); a board's own drives
/// are never on in lock step ([`lock_step`]). The emulated board running
/// free keeps it too: QEMU's clock there follows a host that may be
/// preempted for tens of milliseconds.
#[cfg(any(feature = "board-qemu", feature = "lock-step"))]
pub struct NoWatchdog {
    _owned: (),
}

#[cfg(any(feature = "board-qemu", feature = "lock-step"))]
impl NoWatchdog {
    /// The board's only one.
    pub(crate) fn take() -> Self {
        Self { _owned: () }
    }
}

#[cfg(any(feature = "board-qemu", feature = "lock-step"))]
impl Watchdog for NoWatchdog {
    fn feed(&mut self) {}
}

/// The drive interlock's settings: the PUMA 560's limits, and with the
/// `commissioning` feature every torque capped at
/// [`COMMISSIONING_TORQUE_FRACTION`] of its rating, so that a first run with
/// unverified encoder and motor signs (each board's `JOINT_SIGNS`) moves the
/// arm gently while the interlock's motion check finds a wrong sign. A
/// static: in flash, not in the control task's RAM.
pub static INTERLOCK_SETTINGS: InterlockSettings = if cfg!(feature = "commissioning") {
    InterlockSettings::PUMA560.with_commissioning_cap(COMMISSIONING_TORQUE_FRACTION)
} else {
    InterlockSettings::PUMA560
};

/// The commissioning torque cap, as a fraction of each joint's rating: 20 %
/// lifts no arm joint against its own weight at full stretch (joint 2 holds up
/// to 46 N m of 186.4), so the arm must be supported or near its rest pose
/// when a sign is first tried.
pub const COMMISSIONING_TORQUE_FRACTION: f32 = 0.2;

/// Checks a torque set before any output is touched.
pub fn validate_torques(torque_nm: &[f32; JOINTS]) -> Result<(), BoardError> {
    for (joint, &tau) in torque_nm.iter().enumerate() {
        if !tau.is_finite() {
            return Err(BoardError::NonFiniteTorque { joint });
        }
    }
    Ok(())
}

/// The board's devices, handed to the application once at boot.
pub struct Board<S: SerialLink, P: PlantIo, C: CycleCounter, W: Watchdog> {
    /// Reported to the host in `HelloAck`.
    pub name: &'static str,
    pub serial: S,
    pub plant: P,
    pub cycles: C,
    /// Not armed yet: the control loop's first period arms it.
    pub watchdog: W,
    pub control_source: ControlSource,
}

/// The selected board's concrete devices.
pub type ActiveBoard = Board<active::Serial, active::Plant, active::Cycles, active::Watchdog>;
