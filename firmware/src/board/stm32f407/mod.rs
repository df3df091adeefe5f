//! The real board: STM32F407VG (e.g. STM32F4-Discovery) on embassy-stm32.
//!
//! Peripheral plan (one owner each, taken here so nothing else can use them;
//! the full pin map is in `firmware/README.md`):
//! - clock: 168 MHz from the board's 8 MHz crystal (HSE) through the PLL
//!   ([`clock`]), with the flash accelerator (prefetch, instruction and data
//!   caches) turned back on after embassy's clock set-up clears it
//!   ([`registers`]);
//! - a 256-byte MPU guard at the bottom of the stack (SRAM), whose
//!   MemManage fault drops the drives ([`registers`]);
//! - host link: USART2, TX on PA2, RX on PA3, 115 200 baud, interrupt-driven
//!   with ring buffers (`BufferedUart`);
//! - time: embassy-stm32's time driver on TIM12 (cargo feature
//!   `time-driver-tim12`), so the timers below stay free;
//! - joint encoders: TIM1, TIM8, TIM2, TIM5, TIM3, TIM4 in quadrature mode
//!   ([`encoders`]);
//! - conveyor encoder: PD2/PD3 on EXTI2/EXTI3, x4-decoded in software
//!   ([`conveyor`], [`quadrature`]);
//! - servo amplifiers: sign-magnitude PWM at 20 kHz on TIM9 CH1/CH2, TIM10,
//!   TIM11, TIM13, TIM14 CH1, direction lines PE7/8/10/12/13/14, enable PE15
//!   ([`servo`], [`sign_magnitude`]);
//! - gripper PD0, camera trigger PD1, part-present switch PD4, emergency
//!   stop PD8, amplifier fault PD9, holding brakes PD10 ([`plant`]); the
//!   trigger's edge and every encoder counter in one critical section
//!   ([`latch`]);
//! - cycle counter: the DWT's CYCCNT ([`cycles`]);
//! - the independent watchdog (IWDG), armed by the control loop's first
//!   period, 32 ms nominal ([`watchdog`]); `init` logs a reset it caused.
//!
//! The plant runs from the board's own ticker ([`ControlSource::Ticker`]);
//! built with the `lock-step` feature it is instead the simulator's, in lock
//! step over USART2 at 921,600 baud (hardware in the loop, the emulated
//! board's mode): every device above is still brought up, and then held safe
//! for the whole run (amplifiers disabled, brakes engaged:
//! [`crate::board::lock_step`]); the watchdog is not armed
//! ([`crate::board::NoWatchdog`]).
//!
//! Drives that fail safe:
//! - the amplifier enable PE15 is driven low by `__pre_init`, the first code
//!   after reset (before RAM is initialised and the stack painted), and stays
//!   low through `embassy_stm32::init` (which only turns the GPIO clocks on)
//!   until the servos take the pin, low;
//! - the panic handler, HardFault and the default handler (an unexpected
//!   interrupt, NMI) drop the enable with one store ([`drives_off_now`])
//!   before anything else, then latch the cause ([`crate::board::fail_safe`]);
//!   a panic or HardFault also leaves its cause in RAM that survives the reset
//!   the watchdog then makes, and `init` latches it again (as it does an IWDG
//!   reset), so the drives stay off after the reboot until the host
//!   acknowledges;
//! - the joints' wiring signs are board configuration ([`JOINT_SIGNS`]).

mod clock;
mod conveyor;
mod cycles;
mod encoders;
mod homing_inputs;
mod latch;
mod plant;
mod quadrature;
mod registers;
mod servo;
mod sign_magnitude;
#[cfg_attr(
    feature = "lock-step",
    allow(
        dead_code,
        reason = "the lock-step build leaves the IWDG off (see NoWatchdog)"
    )
)]
mod watchdog;

use defmt_rtt as _;
use embassy_stm32::gpio::{Input, Level, Output, Pull, Speed};
use embassy_stm32::peripherals::USART2;
use embassy_stm32::timer::qei::Qei;
use embassy_stm32::usart::{BufferedInterruptHandler, BufferedUart, Config as UartConfig};
use embassy_stm32::{bind_interrupts, interrupt};

pub use cycles::{count_now, DwtCycles};
pub use encoders::QuadratureEncoders;
use encoders::{qei_config, EncoderPeripherals};
use plant::PlantDevices;
pub use plant::Stm32Plant;
use servo::{ServoAmplifiers, ServoPeripherals};
#[cfg(not(feature = "lock-step"))]
pub use watchdog::IndependentWatchdogFeed;

use shared::safety::{BoardFault, JointSigns};

#[cfg(feature = "lock-step")]
use super::lock_step::LockStepPlant;
#[cfg(feature = "lock-step")]
use super::NoWatchdog;
use super::{fail_safe, interrupt_time, Board, ControlSource};

/// Each joint's encoder and motor sign on this cell's wiring (joint 1 first).
/// A swapped quadrature channel or motor lead is entered here at
/// commissioning (build with the `commissioning` feature: torques capped, and
/// a wrong sign shows as the interlock's `MotionDisagreement` on its joint),
/// not rewired by trial and error or found by a runaway.
pub const JOINT_SIGNS: JointSigns = JointSigns::AS_WIRED;

/// Drops the amplifier enable (PE15) with one store to GPIOE's BSRR: no HAL
/// state, no lock, so any handler can call it first, whatever the firmware
/// was doing. Harmless before the pin is an output (its output latch is then
/// low already, see `__pre_init`). One store only: with the brake's store
/// beside it the size-tuned build outlined the pair into a shared function,
/// a call before the enable drops (the image test caught it).
#[inline(always)]
pub fn drives_off_now() {
    embassy_stm32::pac::GPIOE
        .bsrr()
        .write(|w| w.set_br(15, true));
}

/// Drops the brake release (PD10): the holding brakes engage. Each fault
/// handler calls it after [`drives_off_now`] and its first call (in
/// `latch_and_remember`, or after the latch in `DefaultHandler`): called
/// right after the store, the size-tuned build outlined "store, call" into
/// one shared function, a call before the enable drops. Harmless before the pin is an output (its latch is low from
/// reset).
#[inline(never)]
pub fn brakes_on_now() {
    embassy_stm32::pac::GPIOD
        .bsrr()
        .write(|w| w.set_br(10, true));
}

// The first code after reset (cortex-m-rt calls `__pre_init` before it
// initialises RAM, so it is assembly: no Rust code may run yet). PE15, the
// amplifier enable, becomes an output driving low: GPIOE's clock on
// (RCC_AHB1ENR.GPIOEEN), a read back (the clock needs two cycles before the
// port answers), BSRR.BR15 (output latch low), then MODER15 = 01 (output).
// Until this runs (a few hundred nanoseconds after reset) the pin floats,
// held low by the pull-down the pin map requires on the amplifier side.
core::arch::global_asm!(
    ".section .text.__pre_init,\"ax\"",
    ".global __pre_init",
    ".type __pre_init,%function",
    ".thumb_func",
    "__pre_init:",
    "ldr r0, =0x40023830",
    "ldr r1, [r0]",
    "orr r1, r1, #0x10",
    "str r1, [r0]",
    "ldr r1, [r0]",
    "ldr r0, =0x40021018",
    "mov r1, #0x80000000",
    "str r1, [r0]",
    "ldr r0, =0x40021000",
    "ldr r1, [r0]",
    "bic r1, r1, #0xC0000000",
    "orr r1, r1, #0x40000000",
    "str r1, [r0]",
    "bx lr",
    ".size __pre_init, . - __pre_init",
);

/// A fault's cause, kept across the reset that follows it: `.uninit` is
/// neither zeroed nor loaded by cortex-m-rt. A mark in the upper 24 bits
/// tells a stored cause from RAM's power-on contents
/// (`shared::safety::reset_word`).
#[link_section = ".uninit.FAIL_SAFE"]
static mut LAST_RUN_FAULT: core::mem::MaybeUninit<u32> = core::mem::MaybeUninit::uninit();

/// Keeps `fault` for the next boot unless this run already kept one (a
/// panic's `udf` ends in HardFault: the panic is the cause to report).
fn remember_fault(fault: BoardFault) {
    // SAFETY: a word-aligned static of our own (`init` cleared it at boot),
    // read and written with volatile accesses; handlers may race it, and
    // either value is a valid fault.
    unsafe {
        let slot = core::ptr::addr_of_mut!(LAST_RUN_FAULT).cast::<u32>();
        if shared::safety::fault_from_reset_word(slot.read_volatile()).is_none() {
            slot.write_volatile(shared::safety::reset_word(fault));
        }
    }
}

/// The cause the previous run left, cleared so the next boot sees only its own.
fn take_remembered_fault() -> Option<BoardFault> {
    // SAFETY: as in `remember_fault`; any bit pattern is a valid u32.
    let word = unsafe {
        let slot = core::ptr::addr_of_mut!(LAST_RUN_FAULT).cast::<u32>();
        let word = slot.read_volatile();
        slot.write_volatile(0);
        word
    };
    shared::safety::fault_from_reset_word(word)
}

/// A fault handler's duties once the drives are off (each handler calls
/// [`drives_off_now`] itself, first, inlined: not behind a call that the
/// optimiser may keep out of line): the brakes engaged, the cause latched
/// for the control loop and kept for the next boot.
fn latch_and_remember(fault: BoardFault) {
    brakes_on_now();
    fail_safe::latch(fault);
    remember_fault(fault);
}

bind_interrupts!(struct Irqs {
    USART2 => BufferedInterruptHandler<USART2>;
    EXTI2 => conveyor::EdgeHandler;
    EXTI3 => conveyor::EdgeHandler;
    EXTI4 => homing_inputs::IndexHandler;
    EXTI15_10 => homing_inputs::IndexHandler;
});

pub type Serial = BufferedUart<'static>;
#[cfg(not(feature = "lock-step"))]
pub type Plant = Stm32Plant;
#[cfg(feature = "lock-step")]
pub type Plant = LockStepPlant<Stm32Plant>;
pub type Cycles = DwtCycles;
#[cfg(not(feature = "lock-step"))]
pub type Watchdog = IndependentWatchdogFeed;
#[cfg(feature = "lock-step")]
pub type Watchdog = NoWatchdog;

/// Name reported in `HelloAck`.
#[cfg(not(feature = "lock-step"))]
pub const BOARD_NAME: &str = "stm32f407";
/// Name reported in `HelloAck`: the host's simulated plant runs in lock step.
#[cfg(feature = "lock-step")]
pub const BOARD_NAME: &str = "stm32f407-lock-step";

/// Where control periods come from.
const CONTROL_SOURCE: ControlSource = if cfg!(feature = "lock-step") {
    ControlSource::LockStep
} else {
    ControlSource::Ticker
};

/// The core clock ([`clock`]): a control period's budget in cycles is
/// `CPU_HZ / rate`.
pub const CPU_HZ: u32 = 168_000_000;

/// Spare NVIC lines for the interrupt executors: UART4 and UART5, whose
/// peripherals this firmware never enables.
pub const CONTROL_IRQ: u16 = interrupt::UART4 as u16;
pub const LINK_IRQ: u16 = interrupt::UART5 as u16;

/// The control loop's interrupt executor (its time charged to itself, not to
/// the worker it preempts; the HAL's own USART2 and timer handlers, bound by
/// `bind_interrupts!`, are not wrapped: their few hundred cycles a message
/// stay in the worker's figures).
#[interrupt]
fn UART4() {
    interrupt_time::enter();
    crate::executor::on_interrupt(crate::executor::Level::Control);
    interrupt_time::leave();
}

/// The link's interrupt executor.
#[interrupt]
fn UART5() {
    interrupt_time::enter();
    crate::executor::on_interrupt(crate::executor::Level::Link);
    interrupt_time::leave();
}

/// The host link's rate. In lock step every control period's sample and
/// command cross it (about 85 bytes each way), so it runs at 921,600 baud
/// (USART2 on the 42 MHz APB1: 0.16 % off), about 1,000 periods a second
/// at best; on its own ticker 115,200 carries the frames and telemetry.
const LINK_BAUD: u32 = if cfg!(feature = "lock-step") {
    921_600
} else {
    115_200
};
const UART_BUFFER_LEN: usize = 512;

/// Errors bringing the board up.
#[derive(Debug, Clone, Copy, PartialEq, Eq, defmt::Format)]
pub enum InitError {
    /// `BufferedUart::new` rejected the link configuration.
    UartConfig,
    /// The Cortex-M core peripherals (DWT, DCB) were already taken.
    CorePeripheralsTaken,
    /// The clock tree did not come up at the planned core clock (Hz, 0 if
    /// unknown): the PWM periods and cycle counts would be wrong.
    CoreClock { sys_hz: u32 },
}

impl core::fmt::Display for InitError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            InitError::UartConfig => write!(f, "USART2 rejected the host link configuration"),
            InitError::CorePeripheralsTaken => {
                write!(
                    f,
                    "the Cortex-M core peripherals (DWT, DCB) were already taken"
                )
            }
            InitError::CoreClock { sys_hz } => write!(
                f,
                "core clock is {} Hz, not the planned {} Hz",
                sys_hz,
                clock::SYSCLK_HZ
            ),
        }
    }
}

/// Turns the flash accelerator back on (prefetch, instruction and data
/// caches): embassy-stm32's clock set-up writes FLASH_ACR whole for the wait
/// states and clears them (see [`registers`]).
fn enable_flash_accelerator() {
    let acr = embassy_stm32::pac::FLASH.acr().as_ptr().cast::<u32>();
    // SAFETY: FLASH_ACR, written only here after the HAL's clock set-up,
    // with the values `flash_acr_accelerated` derives from its wait states
    // (the caches are reset while still disabled, then enabled).
    unsafe {
        for value in registers::flash_acr_accelerated(acr.read_volatile()) {
            acr.write_volatile(value);
        }
    }
}

/// Sets the joint encoders' input filters (TIMx_CCMR1 IC1F, IC2F), which
/// `Qei::new` leaves off. Call after the six `Qei::new`.
fn filter_encoder_inputs() {
    use embassy_stm32::pac;
    // CCMR1 is at offset 0x18 in every timer.
    let ccmr1 = [
        pac::TIM1.as_ptr(),
        pac::TIM8.as_ptr(),
        pac::TIM2.as_ptr(),
        pac::TIM5.as_ptr(),
        pac::TIM3.as_ptr(),
        pac::TIM4.as_ptr(),
    ];
    for base in ccmr1 {
        let register = base.cast::<u8>().wrapping_add(0x18).cast::<u32>();
        // SAFETY: TIMx_CCMR1 of a timer the encoders own (its `Qei` was
        // built above), in input mode; only the filter fields change, before
        // the control loop first reads the counts.
        unsafe {
            register.write_volatile(registers::ccmr1_with_input_filters(
                register.read_volatile(),
                registers::ENCODER_INPUT_FILTER,
            ));
        }
    }
}

/// Makes the bottom of the stack (`_stack_guard`, the start of SRAM) a
/// no-access MPU region and enables the MemManage fault, so an overflow
/// faults there ([`MemoryManagement`]) rather than running on into
/// whatever lies below.
fn guard_stack(mpu: &mut cortex_m::peripheral::MPU, scb: &mut cortex_m::peripheral::SCB) {
    unsafe extern "C" {
        static _stack_guard: u32;
    }
    let base = core::ptr::addr_of!(_stack_guard) as u32;
    // SAFETY: region 0 is the only MPU region; the default map stays in
    // force everywhere else (PRIVDEFENA), and nothing runs in the guard (it
    // is below `_stack_limit`, the painted stack's bottom).
    unsafe {
        mpu.rnr.write(0);
        mpu.rbar.write(registers::mpu_guard_rbar(base));
        mpu.rasr.write(registers::mpu_guard_rasr());
        mpu.ctrl.write(registers::MPU_CTRL_GUARD);
    }
    cortex_m::asm::dsb();
    cortex_m::asm::isb();
    scb.enable(cortex_m::peripheral::scb::Exception::MemoryManagement);
}

// MemManage: the stack reached its guard. The fault may have come while an
// exception frame was being stacked, so SP points into the guard and any
// push would fault again: drop the enable (PE15) and the brake release
// (PD10) with one store each, move MSP back to the top of the stack (all
// that was on it is abandoned), and only then call Rust.
core::arch::global_asm!(
    ".section .text.MemoryManagement,\"ax\"",
    ".global MemoryManagement",
    ".type MemoryManagement,%function",
    ".thumb_func",
    "MemoryManagement:",
    "ldr r0, =0x40021018",
    "mov r1, #0x80000000",
    "str r1, [r0]",
    "ldr r0, =0x40020C18",
    "mov r1, #0x04000000",
    "str r1, [r0]",
    "ldr r0, =_stack_start",
    "msr msp, r0",
    "b {overflow}",
    ".size MemoryManagement, . - MemoryManagement",
    overflow = sym stack_overflow,
);

/// The rest of the MemManage handler, on a fresh stack: latch and keep the
/// cause, then wait for the watchdog's reset (the interrupted code cannot be
/// resumed: its stack is gone).
extern "C" fn stack_overflow() -> ! {
    latch_and_remember(BoardFault::StackOverflow);
    defmt::error!("stack overflow (MPU guard); drives off");
    loop {
        cortex_m::asm::wfi();
    }
}

/// Brings up the clock tree, the time driver, USART2 and the plant I/O with
/// every amplifier disabled, and sets up the IWDG without starting it. Call
/// once, first in `main`.
pub fn init() -> Result<Board<Serial, Plant, Cycles, Watchdog>, InitError> {
    let reset_by_watchdog = watchdog::take_iwdg_reset_flag();
    let last_run_fault = take_remembered_fault();
    let p = embassy_stm32::init(clock::config());
    enable_flash_accelerator();
    if let Some(fault) = last_run_fault {
        fail_safe::latch(fault);
        defmt::error!(
            "the last run ended in {}: drives off until the host acknowledges",
            fault
        );
    }
    if reset_by_watchdog {
        fail_safe::latch(BoardFault::WatchdogReset);
        defmt::warn!(
            "last reset by the independent watchdog: the control loop had stopped, the drives went off; they stay off until the host acknowledges"
        );
    }
    let sys_hz = embassy_stm32::rcc::clocks(&p.RCC)
        .sys
        .to_hertz()
        .map_or(0, |hz| hz.0);
    if sys_hz != clock::SYSCLK_HZ {
        return Err(InitError::CoreClock { sys_hz });
    }
    // First of all outputs: the amplifiers stay off until the first `apply`.
    let servos = ServoAmplifiers::new(ServoPeripherals {
        tim9: p.TIM9,
        tim10: p.TIM10,
        tim11: p.TIM11,
        tim13: p.TIM13,
        tim14: p.TIM14,
        pwm1: p.PE5,
        pwm2: p.PE6,
        pwm3: p.PB8,
        pwm4: p.PB9,
        pwm5: p.PA6,
        pwm6: p.PA7,
        dir1: p.PE7,
        dir2: p.PE8,
        dir3: p.PE10,
        dir4: p.PE12,
        dir5: p.PE13,
        dir6: p.PE14,
        enable: p.PE15,
    });

    let mut core = cortex_m::Peripherals::take().ok_or(InitError::CorePeripheralsTaken)?;
    let cycles = DwtCycles::start(core.DCB, core.DWT);
    guard_stack(&mut core.MPU, &mut core.SCB);

    static mut TX_BUFFER: [u8; UART_BUFFER_LEN] = [0; UART_BUFFER_LEN];
    static mut RX_BUFFER: [u8; UART_BUFFER_LEN] = [0; UART_BUFFER_LEN];
    // SAFETY: `init` runs once (embassy_stm32::init above would panic on a
    // second call, taking the peripherals twice), so these are the only
    // references ever made to the buffers.
    let (tx_buffer, rx_buffer) = unsafe {
        (
            &mut *core::ptr::addr_of_mut!(TX_BUFFER),
            &mut *core::ptr::addr_of_mut!(RX_BUFFER),
        )
    };
    let mut config = UartConfig::default();
    config.baudrate = LINK_BAUD;
    let serial = BufferedUart::new(p.USART2, p.PA3, p.PA2, tx_buffer, rx_buffer, Irqs, config)
        .map_err(|_| InitError::UartConfig)?;

    let joints = QuadratureEncoders::new(EncoderPeripherals {
        joint1: Qei::new(p.TIM1, p.PE9, p.PE11, qei_config()),
        joint2: Qei::new(p.TIM8, p.PC6, p.PC7, qei_config()),
        joint3: Qei::new(p.TIM2, p.PA15, p.PB3, qei_config()),
        joint4: Qei::new(p.TIM5, p.PA0, p.PA1, qei_config()),
        joint5: Qei::new(p.TIM3, p.PB4, p.PB5, qei_config()),
        joint6: Qei::new(p.TIM4, p.PB6, p.PB7, qei_config()),
    });
    filter_encoder_inputs();
    let conveyor = conveyor::ConveyorEncoder::start(p.PD2, p.EXTI2, p.PD3, p.EXTI3);
    let plant = Stm32Plant::new(PlantDevices {
        joints,
        conveyor,
        servos,
        gripper: Output::new(p.PD0, Level::Low, Speed::Low),
        camera_trigger: Output::new(p.PD1, Level::Low, Speed::Low),
        part_present: Input::new(p.PD4, Pull::Down),
        emergency_stop_ok: Input::new(p.PD8, Pull::Down),
        drive_fault_n: Input::new(p.PD9, Pull::Up),
        brake_release: Output::new(p.PD10, Level::Low, Speed::Low),
        homing: homing_inputs::HomingSensors::new(homing_inputs::HomingPeripherals {
            adc: p.ADC1,
            pot1: p.PC1,
            pot2: p.PC2,
            pot3: p.PC4,
            pot4: p.PC5,
            pot5: p.PB0,
            pot6: p.PB1,
            index1: (p.PE4, p.EXTI4),
            index2: (p.PB11, p.EXTI11),
            index3: (p.PB12, p.EXTI12),
            index4: (p.PB13, p.EXTI13),
            index5: (p.PB14, p.EXTI14),
            index6: (p.PB15, p.EXTI15),
        }),
    });

    #[cfg(feature = "lock-step")]
    let (plant, watchdog) = (LockStepPlant::holding(plant), NoWatchdog::take());
    #[cfg(not(feature = "lock-step"))]
    let watchdog = IndependentWatchdogFeed::new(p.IWDG);
    Ok(Board {
        name: BOARD_NAME,
        serial,
        plant,
        cycles,
        watchdog,
        control_source: CONTROL_SOURCE,
    })
}

/// Drops the enable first, then logs where, then stops the core on an
/// undefined instruction (a probe attached sees the fault; without one the
/// independent watchdog resets the board). The location only, not the
/// message: formatting it would link core::fmt (several KB of flash) for
/// panic sites the panic-free code never reaches.
#[panic_handler]
fn panic(info: &core::panic::PanicInfo) -> ! {
    drives_off_now();
    latch_and_remember(BoardFault::Panic);
    match info.location() {
        Some(at) => defmt::error!("panic at {=str}:{=u32}", at.file(), at.line()),
        None => defmt::error!("panic"),
    }
    cortex_m::asm::udf()
}

/// Drops the enable first; then waits for the watchdog's reset (if it is not
/// armed yet the board stays here, drives off).
#[cortex_m_rt::exception]
unsafe fn HardFault(frame: &cortex_m_rt::ExceptionFrame) -> ! {
    drives_off_now();
    latch_and_remember(BoardFault::HardFault);
    defmt::error!("hard fault at pc={=u32:#x}; drives off", frame.pc());
    loop {
        cortex_m::asm::wfi();
    }
}

/// An interrupt (or NMI) with no handler of its own: the enable drops first,
/// the fault is latched, and an external interrupt is masked so that it does
/// not fire again; the firmware runs on, drives off, until the host
/// acknowledges.
#[cortex_m_rt::exception]
unsafe fn DefaultHandler(irqn: i16) {
    // Not kept across a reset: none follows, the host acknowledges this one.
    drives_off_now();
    fail_safe::latch(BoardFault::UnexpectedInterrupt);
    brakes_on_now();
    if let Ok(line) = u16::try_from(irqn) {
        cortex_m::peripheral::NVIC::mask(UnexpectedLine(line));
    }
    defmt::error!("unexpected interrupt {}; drives off", irqn);
}

/// An NVIC line by number, to mask one the firmware did not expect.
#[derive(Clone, Copy)]
struct UnexpectedLine(u16);

// SAFETY: the number came from the active exception, so the line exists.
unsafe impl cortex_m::interrupt::InterruptNumber for UnexpectedLine {
    fn number(self) -> u16 {
        self.0
    }
}
