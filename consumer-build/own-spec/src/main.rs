//! A crate with a spec of its own: `build.rs` generates `bench_thermometer`
//! from `spec/bench-thermometer.yaml`, and the same runtime as `yosemitech`
//! frames and decodes it. Run, it checks its spec's example frames.

include!(concat!(env!("OUT_DIR"), "/mod.rs"));

use bench_thermometer::{GetTemperatures, SetSamplePeriod};
use yosemitech_rtu::Command;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let request = GetTemperatures.request_frame(5)?;
    assert_eq!(&*request, [0x05, 0x03, 0x10, 0x00, 0x00, 0x04, 0x41, 0x4D]);
    let reply = [0x05, 0x03, 0x08, 0x00, 0x00, 0xAC, 0x41, 0x00, 0x00, 0x0D, 0x42, 0x20, 0x25];
    let reading = GetTemperatures::decode_response(5, &reply)?;
    println!("water {} degC, air {} degC", reading.water_c, reading.air_c);

    let write = SetSamplePeriod { period_s: 60 }.request_frame(5)?;
    assert_eq!(&*write, [0x05, 0x10, 0x20, 0x00, 0x00, 0x01, 0x02, 0x00, 0x3C, 0xB5, 0x43]);
    let too_long = SetSamplePeriod { period_s: 7200 }.request_frame(5);
    println!("period 7200 s: {}", too_long.map_or_else(|e| e.to_string(), |_| "accepted".to_owned()));
    Ok(())
}
