//! One read of a one-float command (`FloatRead`, chosen in
//! `yosemitech_bench`) round trip, repeated, for counting instructions with callgrind
//! (no timer involved, so the count does not depend on the machine's load):
//!
//! ```sh
//! cargo build --release -p yosemitech-bench --bin callgrind-transaction
//! valgrind --tool=callgrind --toggle-collect='*measured_*' --callgrind-out-file=/tmp/cg.out \
//!     target/release/callgrind-transaction client 1000
//! ```
//!
//! The instructions counted (`summary` in the output file) divided by the
//! repetitions give one transaction. Modes: `client` (`Client::call` over the
//! in-memory `ResponderTransport` with a fixed reply, no line timing, no
//! retries), `codec` (our encode, the same fixed-reply device and our
//! decode, without the client) and `rmodbus` (rmodbus's request generation,
//! the same device and its parsing and decoding).

use std::hint::black_box;
use std::time::Duration;

use yosemitech::{Client, Command, ResponderTransport, Transport};
use yosemitech_bench::{
    FLOAT_READ_VALUE, FloatRead, fixed_float_read_responder, float_read_value, rmodbus_ref, unpaced_config,
};

/// Repetitions when none is given.
const DEFAULT_REPETITIONS: u32 = 1000;

fn main() -> Result<(), String> {
    let mut args = std::env::args().skip(1);
    let mode = args.next().unwrap_or_else(|| "client".into());
    let repetitions = match args.next() {
        Some(n) => n.parse::<u32>().map_err(|e| format!("repetitions: {e}"))?,
        None => DEFAULT_REPETITIONS,
    };
    let mut device = fixed_float_read_responder();
    let mut reply = Vec::with_capacity(256);
    match mode.as_str() {
        "client" => {
            let config = unpaced_config(Duration::from_millis(10));
            let mut client = Client::with_config(ResponderTransport::from_fn(device), config);
            check(measured_client(&mut client))?;
            for _ in 0..repetitions {
                black_box(measured_client(&mut client));
            }
        }
        "codec" => {
            let mut request = [0u8; 256];
            check(measured_codec(&mut request, &mut device, &mut reply))?;
            for _ in 0..repetitions {
                black_box(measured_codec(&mut request, &mut device, &mut reply));
            }
        }
        "rmodbus" => {
            let (mut generator, mut request) = rmodbus_ref::read_request(0x2800, 2).map_err(|e| e.to_string())?;
            check(measured_rmodbus(&mut generator, &mut request, &mut device, &mut reply))?;
            for _ in 0..repetitions {
                black_box(measured_rmodbus(&mut generator, &mut request, &mut device, &mut reply));
            }
        }
        other => return Err(format!("unknown mode {other}: client, codec or rmodbus")),
    }
    Ok(())
}

fn check(value: Option<f32>) -> Result<(), String> {
    if value == Some(FLOAT_READ_VALUE) { Ok(()) } else { Err(format!("the float read gave {value:?}")) }
}

#[inline(never)]
fn measured_client<T: Transport>(client: &mut Client<T>) -> Option<f32> {
    client.call(black_box(1), black_box(&FloatRead::default())).ok().map(|r| float_read_value(&r))
}

#[inline(never)]
fn measured_codec(
    request: &mut [u8; 256],
    device: &mut impl FnMut(&[u8], &mut Vec<u8>),
    reply: &mut Vec<u8>,
) -> Option<f32> {
    let len = black_box(&FloatRead::default()).encode_request(black_box(1), request).ok()?;
    reply.clear();
    device(request.get(..len)?, reply);
    FloatRead::decode_response(1, reply).ok().map(|r| float_read_value(&r))
}

#[inline(never)]
fn measured_rmodbus(
    generator: &mut rmodbus::client::ModbusRequest,
    request: &mut Vec<u8>,
    device: &mut impl FnMut(&[u8], &mut Vec<u8>),
    reply: &mut Vec<u8>,
) -> Option<f32> {
    rmodbus_ref::encode_float_read(generator, request).ok()?;
    reply.clear();
    device(request, reply);
    rmodbus_ref::decode_float_read(generator, reply).ok()
}
