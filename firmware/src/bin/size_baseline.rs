//! The board alone (vector table, runtime, UART, clock, panic handler): the
//! size subtracted from the others in BENCHMARKS.md.
#![no_std]
#![no_main]

use cortex_m_rt::entry;
use embedded_io_async::Write;
use panic_halt as _;
use yosemitech_firmware_example::{Uart, publish};

#[entry]
fn main() -> ! {
    let mut uart = Uart;
    loop {
        embassy_futures::block_on(async {
            if uart.write_all(&[0]).await.is_ok() {
                publish(0, 0.0);
            }
        });
    }
}
