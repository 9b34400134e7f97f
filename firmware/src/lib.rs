//! The board the example binaries run on: a polled RS-485 UART (USART2 of an
//! STM32F4 at 9600 baud 8N1, its driver-enable pin wired to the UART's RTS in
//! hardware), the Cortex-M cycle counter as the clock, and a delay on it. All
//! `no_std`, no allocator; the executor is `embassy_futures::block_on`.
#![no_std]

use core::future::poll_fn;
use core::ptr::{read_volatile, write_volatile};
use core::task::Poll;

use yosemitech_rtu::client::Instant;
use yosemitech_rtu::client::embedded::Clock;

/// Core clock: the reset default (16 MHz internal oscillator).
const CYCLES_PER_MICRO: u32 = 16;

const USART2: usize = 0x4000_4400;
const SR: usize = USART2;
const DR: usize = USART2 + 0x04;
const RXNE: u32 = 1 << 5;
const TXE: u32 = 1 << 7;
const TC: u32 = 1 << 6;

const DWT_CYCCNT: usize = 0xE000_1004;

fn sr() -> u32 {
    // SAFETY: USART2's status register, a valid MMIO address on the part.
    unsafe { read_volatile(SR as *const u32) }
}

/// USART2 as an `embedded-io-async` link (cancel-safe: a byte is taken from
/// the data register only by the poll that returns it).
#[derive(Debug, Default)]
pub struct Uart;

impl embedded_io_async::ErrorType for Uart {
    type Error = core::convert::Infallible;
}

impl embedded_io_async::Read for Uart {
    async fn read(&mut self, buf: &mut [u8]) -> Result<usize, Self::Error> {
        poll_fn(|cx| {
            let mut n = 0;
            while n < buf.len() && sr() & RXNE != 0 {
                // SAFETY: USART2's data register; reading it takes the received byte.
                let byte = unsafe { read_volatile(DR as *const u32) } as u8;
                if let Some(slot) = buf.get_mut(n) {
                    *slot = byte;
                }
                n += 1;
            }
            if n > 0 || buf.is_empty() {
                Poll::Ready(Ok(n))
            } else {
                cx.waker().wake_by_ref();
                Poll::Pending
            }
        })
        .await
    }
}

impl embedded_io_async::Write for Uart {
    async fn write(&mut self, bytes: &[u8]) -> Result<usize, Self::Error> {
        for &byte in bytes {
            poll_fn(|cx| {
                if sr() & TXE != 0 {
                    Poll::Ready(())
                } else {
                    cx.waker().wake_by_ref();
                    Poll::Pending
                }
            })
            .await;
            // SAFETY: USART2's data register; writing it sends the byte.
            unsafe { write_volatile(DR as *mut u32, u32::from(byte)) };
        }
        Ok(bytes.len())
    }

    async fn flush(&mut self) -> Result<(), Self::Error> {
        // Returns when the last stop bit has left: the bus is free from here.
        poll_fn(|cx| {
            if sr() & TC != 0 {
                Poll::Ready(Ok(()))
            } else {
                cx.waker().wake_by_ref();
                Poll::Pending
            }
        })
        .await
    }
}

/// Microseconds from the 32-bit cycle counter, extended to 64 bits (read
/// at least once per wrap, every 268 s at 16 MHz: every transaction does).
#[derive(Debug, Default)]
pub struct CycleClock {
    last: u32,
    high: u64,
}

impl CycleClock {
    // Out of line: the clock and the delay read it in several places.
    #[inline(never)]
    fn cycles(&mut self) -> u64 {
        // SAFETY: the DWT cycle counter, a valid read-only MMIO address.
        let now = unsafe { read_volatile(DWT_CYCCNT as *const u32) };
        if now < self.last {
            self.high += 1 << 32;
        }
        self.last = now;
        self.high | u64::from(now)
    }
}

impl Clock for CycleClock {
    fn now(&mut self) -> Instant {
        Instant::from_micros(self.cycles() / u64::from(CYCLES_PER_MICRO))
    }
}

/// A delay on its own cycle clock, yielding while it waits.
#[derive(Debug, Default)]
pub struct CycleDelay {
    clock: CycleClock,
}

impl CycleDelay {
    async fn delay_cycles(&mut self, cycles: u64) {
        let until = self.clock.cycles() + cycles;
        poll_fn(|cx| {
            if self.clock.cycles() >= until {
                Poll::Ready(())
            } else {
                cx.waker().wake_by_ref();
                Poll::Pending
            }
        })
        .await
    }
}

// The waits in cycles, each a 32-bit multiplication or division (a 64-bit
// division links a kilobyte of library code on this core); the default
// `delay_us` and `delay_ms` would split long waits into chunks of `delay_ns`.
impl embedded_hal_async::delay::DelayNs for CycleDelay {
    async fn delay_ns(&mut self, ns: u32) {
        self.delay_cycles(u64::from(ns.div_ceil(1000)) * u64::from(CYCLES_PER_MICRO)).await
    }

    async fn delay_us(&mut self, us: u32) {
        self.delay_cycles(u64::from(us) * u64::from(CYCLES_PER_MICRO)).await
    }

    async fn delay_ms(&mut self, ms: u32) {
        self.delay_cycles(u64::from(ms) * 1000 * u64::from(CYCLES_PER_MICRO)).await
    }
}

/// Where the example keeps its last readings (a debugger or a display reads them).
pub static mut READINGS: [f32; 3] = [0.0; 3];

/// Records a reading for the outside world.
pub fn publish(index: usize, value: f32) {
    // SAFETY: single-threaded firmware, no interrupt touches READINGS.
    unsafe {
        let readings = &raw mut READINGS;
        if let Some(slot) = (*readings).get_mut(index) {
            write_volatile(slot, value);
        }
    }
}
