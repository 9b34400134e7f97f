//! Reads pH from the pH/ORP probe (address 1) and temperature and
//! conductivity from the conductivity probe (address 2) on one RS-485 bus,
//! forever, through the embedded driver and the generated typed commands.
#![no_std]
#![no_main]

use cortex_m_rt::entry;
use panic_halt as _;
use yosemitech::conductivity::GetTemperatureAndConductivity;
use yosemitech::ph_orp::GetPh;
use yosemitech_firmware_example::{CycleClock, CycleDelay, Uart, publish};
use yosemitech_rtu::client::embedded::FirmwareClient;
use yosemitech_rtu::{CharFormat, ClientConfig, LineTiming};

#[entry]
fn main() -> ! {
    let line = LineTiming::new(9600, CharFormat::EIGHT_N_1);
    let mut bus =
        FirmwareClient::new(Uart, CycleDelay::default(), CycleClock::default(), ClientConfig::default(), Some(line));
    loop {
        embassy_futures::block_on(async {
            if let Ok(reading) = bus.call(1, &GetPh).await {
                publish(0, reading.ph);
            }
            if let Ok(reading) = bus.call(2, &GetTemperatureAndConductivity).await {
                publish(1, reading.temperature_c);
                publish(2, reading.conductivity_ms_cm);
            }
        });
    }
}
