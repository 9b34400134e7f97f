//! The embedded driver alone: one raw request and its checked reply, no
//! generated codec (the request is a constant frame, checked by its layout).
#![no_std]
#![no_main]

use cortex_m_rt::entry;
use panic_halt as _;
use yosemitech_firmware_example::{CycleClock, CycleDelay, Uart, publish};
use yosemitech_rtu::client::embedded::FirmwareClient;
use yosemitech_rtu::{CharFormat, ClientConfig, Layout, LineTiming};

const READ_2: Layout<'static> = Layout::read(0x2800, 2);
const REQUEST: [u8; 8] = [0x01, 0x03, 0x28, 0x00, 0x00, 0x02, 0xCD, 0xAB];

#[entry]
fn main() -> ! {
    let line = LineTiming::new(9600, CharFormat::EIGHT_N_1);
    let mut bus =
        FirmwareClient::new(Uart, CycleDelay::default(), CycleClock::default(), ClientConfig::default(), Some(line));
    loop {
        embassy_futures::block_on(async {
            if let Ok(reply) = bus.call_raw(&REQUEST, &READ_2).await {
                publish(0, f32::from(reply.get(3).copied().unwrap_or(0)));
            }
        });
    }
}
