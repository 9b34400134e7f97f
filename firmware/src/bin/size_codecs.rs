//! One sensor's generated codecs, all of them (the module's dispatch keeps
//! every command's encoder and decoder): build with `SENSOR=<name>` (a module
//! of `yosemitech::SENSORS`); the driver is not linked. The module's derived
//! quantities are linked too, unless built with `COMMANDS_ONLY=1`.
#![no_std]
#![no_main]

use cortex_m_rt::entry;
use panic_halt as _;
use yosemitech::SENSORS;
use yosemitech_firmware_example::publish;

/// The sensor's index in `SENSORS`, chosen when building.
const CHOSEN: usize = position(match option_env!("SENSOR") {
    Some(name) => name,
    None => "",
});

const fn position(name: &str) -> usize {
    let mut i = 0;
    while i < SENSORS.len() {
        if same(SENSORS[i].info.name.as_bytes(), name.as_bytes()) {
            return i;
        }
        i += 1;
    }
    0
}

const fn same(a: &[u8], b: &[u8]) -> bool {
    if a.len() != b.len() {
        return false;
    }
    let mut i = 0;
    while i < a.len() {
        if a[i] != b[i] {
            return false;
        }
        i += 1;
    }
    true
}

/// Only the chosen module is linked (indexing `SENSORS` at run time would
/// link all). Built with `COMMANDS_ONLY=1`, without its derived quantities
/// (their functions and the `f64` and `libm` code they need): the codecs alone.
static MODULE: yosemitech_rtu::SensorModule = match option_env!("COMMANDS_ONLY") {
    Some(_) => yosemitech_rtu::SensorModule { derived: &[], ..SENSORS[CHOSEN] },
    None => SENSORS[CHOSEN],
};

#[entry]
fn main() -> ! {
    let module = core::hint::black_box(&MODULE);
    let mut frame = [0u8; 256];
    loop {
        let request = core::hint::black_box(&[0x01, 0x03, 0x28, 0x00, 0x00, 0x02, 0xCD, 0xAB][..]);
        // Every command's request and reply codecs, through the module's dispatch.
        if let Some(name) = module.identify_request(request) {
            let n = module.reencode_request(name, request, &mut frame).and_then(Result::ok).unwrap_or(0);
            let m = module.reencode_response(name, 1, request, &mut frame).and_then(Result::ok).unwrap_or(0);
            publish(0, (n + m) as f32);
            let _ = module.visit_request(name, request, &mut |_, _| {});
            let _ = module.visit_response(name, 1, request, &mut |_, _| {});
        }
    }
}
