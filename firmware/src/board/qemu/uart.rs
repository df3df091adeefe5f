//! Interrupt-driven driver for the AN386's CMSDK APB UART0, with
//! `embedded-io-async` `Read` and `Write`.
//!
//! The UART holds one received byte. The RX interrupt moves bytes into a ring
//! buffer; when the ring is full it masks itself and leaves the byte in the
//! UART, so the sender is held off (QEMU stops delivering) instead of bytes
//! being dropped. The reader drains the UART again when it frees space.

use core::cell::RefCell;
use core::future::poll_fn;
use core::task::Poll;

use critical_section::Mutex;
use embassy_sync::waitqueue::AtomicWaker;
use heapless::Deque;

use super::mmio::{self, Irq, Reg};

const UART0: Reg = Reg(0x4000_4000);
const DATA: Reg = UART0.at(0x00);
const STATE: Reg = UART0.at(0x04);
const CTRL: Reg = UART0.at(0x08);
const INTSTATUS: Reg = UART0.at(0x0C);
const BAUDDIV: Reg = UART0.at(0x10);

const STATE_TX_FULL: u32 = 1 << 0;
const STATE_RX_FULL: u32 = 1 << 1;
const CTRL_TX_ENABLE: u32 = 1 << 0;
const CTRL_RX_ENABLE: u32 = 1 << 1;
const CTRL_TX_INT: u32 = 1 << 2;
const CTRL_RX_INT: u32 = 1 << 3;
const INT_TX: u32 = 1 << 0;
const INT_RX: u32 = 1 << 1;

/// 25 MHz / 217 = 115 200 baud on hardware; QEMU needs a divider of at least
/// 16 to pass data at all and then ignores it.
const BAUD_DIVIDER: u32 = 217;

/// Received bytes not yet read (several frames' worth).
const RX_RING_LEN: usize = 512;

static RX_RING: Mutex<RefCell<Deque<u8, RX_RING_LEN>>> = Mutex::new(RefCell::new(Deque::new()));
static RX_WAKER: AtomicWaker = AtomicWaker::new();
static TX_WAKER: AtomicWaker = AtomicWaker::new();

/// UART0, owned once by the board.
pub struct Uart0 {
    _owned: (),
}

/// The UART cannot fail once set up; the error type exists for the traits.
#[derive(Debug, Clone, Copy, PartialEq, Eq, defmt::Format)]
pub enum UartError {}

impl core::fmt::Display for UartError {
    fn fmt(&self, _f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match *self {}
    }
}

impl core::error::Error for UartError {}

impl embedded_io_async::Error for UartError {
    fn kind(&self) -> embedded_io_async::ErrorKind {
        match *self {}
    }
}

impl Uart0 {
    /// Enables UART0 with RX interrupts. Called once by `board::qemu::init`.
    pub(super) fn init() -> Self {
        CTRL.write(0);
        BAUDDIV.write(BAUD_DIVIDER);
        INTSTATUS.write(INT_TX | INT_RX);
        CTRL.write(CTRL_TX_ENABLE | CTRL_RX_ENABLE | CTRL_RX_INT);
        mmio::unmask(Irq::Uart0Rx);
        mmio::unmask(Irq::Uart0Tx);
        Uart0 { _owned: () }
    }
}

/// Moves received bytes from the UART into `ring` until either is empty/full.
/// Returns whether the ring filled up with a byte still waiting in the UART.
fn drain_rx(ring: &mut Deque<u8, RX_RING_LEN>) -> bool {
    while STATE.read() & STATE_RX_FULL != 0 {
        if ring.is_full() {
            return true;
        }
        let byte = (DATA.read() & 0xFF) as u8;
        // Cannot fail: the ring was checked not to be full.
        let _ = ring.push_back(byte);
    }
    false
}

/// Unmasks the RX interrupt, then drains the UART: a byte landing in between
/// raises the interrupt, a byte already there is taken here.
fn refill_rx(ring: &mut Deque<u8, RX_RING_LEN>) {
    CTRL.modify(|c| c | CTRL_RX_INT);
    if drain_rx(ring) {
        CTRL.modify(|c| c & !CTRL_RX_INT);
    }
}

/// UART0 RX interrupt (AN386 line 0).
pub fn on_rx_interrupt() {
    critical_section::with(|cs| {
        INTSTATUS.write(INT_RX);
        let mut ring = RX_RING.borrow_ref_mut(cs);
        if drain_rx(&mut ring) {
            // Hold the sender off until the reader frees space.
            CTRL.modify(|c| c & !CTRL_RX_INT);
        }
    });
    RX_WAKER.wake();
}

/// UART0 TX interrupt (AN386 line 1): the transmitter has room again.
pub fn on_tx_interrupt() {
    critical_section::with(|_| {
        INTSTATUS.write(INT_TX);
        CTRL.modify(|c| c & !CTRL_TX_INT);
    });
    TX_WAKER.wake();
}

impl embedded_io_async::ErrorType for Uart0 {
    type Error = UartError;
}

impl embedded_io_async::Read for Uart0 {
    async fn read(&mut self, buf: &mut [u8]) -> Result<usize, UartError> {
        if buf.is_empty() {
            return Ok(0);
        }
        poll_fn(|cx| {
            critical_section::with(|cs| {
                let mut ring = RX_RING.borrow_ref_mut(cs);
                refill_rx(&mut ring);
                let mut n = 0;
                for (slot, byte) in buf.iter_mut().zip(core::iter::from_fn(|| ring.pop_front())) {
                    *slot = byte;
                    n += 1;
                }
                if n > 0 {
                    // Space was freed: take what the UART holds now.
                    refill_rx(&mut ring);
                    Poll::Ready(Ok(n))
                } else {
                    // In the critical section the RX interrupt cannot slip in
                    // between this check and the registration.
                    RX_WAKER.register(cx.waker());
                    Poll::Pending
                }
            })
        })
        .await
    }
}

impl Uart0 {
    /// Writes bytes while the transmitter has room; `None` when it had none.
    fn try_write(buf: &[u8]) -> Option<usize> {
        let mut n = 0;
        for &byte in buf {
            if STATE.read() & STATE_TX_FULL != 0 {
                break;
            }
            DATA.write(u32::from(byte));
            n += 1;
        }
        (n > 0).then_some(n)
    }

    /// Waits for the transmitter to have room.
    async fn tx_ready() {
        poll_fn(|cx| {
            if STATE.read() & STATE_TX_FULL == 0 {
                return Poll::Ready(());
            }
            TX_WAKER.register(cx.waker());
            // CTRL is shared with the RX path: change it only inside a
            // critical section so an interrupt's update is not overwritten.
            critical_section::with(|_| {
                // Unmask, then check again so a drain in between is not missed.
                CTRL.modify(|c| c | CTRL_TX_INT);
                if STATE.read() & STATE_TX_FULL == 0 {
                    CTRL.modify(|c| c & !CTRL_TX_INT);
                    Poll::Ready(())
                } else {
                    Poll::Pending
                }
            })
        })
        .await
    }
}

impl embedded_io_async::Write for Uart0 {
    async fn write(&mut self, buf: &[u8]) -> Result<usize, UartError> {
        if buf.is_empty() {
            return Ok(0);
        }
        loop {
            if let Some(n) = Self::try_write(buf) {
                return Ok(n);
            }
            Self::tx_ready().await;
        }
    }

    async fn flush(&mut self) -> Result<(), UartError> {
        Self::tx_ready().await;
        Ok(())
    }
}
