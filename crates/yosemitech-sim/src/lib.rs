//! A Yosemitech sensor simulated from its spec: register state, writes, fault injection and line timing.
//!
//! A [`Simulator`] is built from a [`yosemitech_spec::Sensor`] alone, so it
//! serves any sensor whose spec is loaded at run time, with no Rust per
//! sensor. It answers request frames as the probe would (see [`Simulator`]
//! for the rules: addressing, exceptions, the slave-address change), starts
//! with the register contents the manual's examples show, and can vary its
//! readings and inject faults, deterministically from a seed.
//!
//! Where to run it:
//!
//! * in-process: [`Simulator`] and [`Bus`] implement
//!   [`yosemitech_rtu::Responder`], so `Client<ResponderTransport<Simulator>>`
//!   talks to it with no thread;
//! * on a byte stream from a background thread ([`serve`]): a
//!   pseudo-terminal (`serve_pty`, Unix, `pty` feature), RTU over TCP
//!   ([`serve_tcp`]), an in-memory pair ([`serve_memory`]), optionally
//!   emulating the serial line's timing ([`ServeConfig::line_timing`]);
//! * over Modbus TCP as an Ethernet gateway, one probe or a [`Bus`] of them
//!   (unit id = slave address), several connections at once ([`serve_mbap`]).
//!
//! By default the simulator behaves like the real probe: a request that
//! matches no command of the sensor gets no reply
//! ([`UnknownRequestPolicy`]), and the serial number carries the sensor's
//! model code ([`SerialNumberPolicy`]); both can be switched to the
//! manual's textbook behaviour.
//!
//! The few rules that are not generic (the slave address, the serial
//! number, the measurement trigger and its warm-up, the three-point pH
//! calibration) live in [`behaviour`], keyed by the spec's command roles.
//!
//! ```
//! # let spec = yosemitech_spec::load_paths(&[concat!(env!("CARGO_MANIFEST_DIR"), "/../../spec").into()])?;
//! use std::collections::BTreeMap;
//! use yosemitech_rtu::{Client, ResponderTransport};
//! use yosemitech_sim::Simulator;
//! use yosemitech_spec::{FieldKind, Value};
//!
//! // The first read of the spec with a float field: set it, read it over the wire.
//! let (sensor, read, field) = spec
//!     .sensors
//!     .iter()
//!     .find_map(|s| {
//!         let c = s.commands.iter().find(|c| c.is_read() && !c.trigger && c.fixed_slave.is_none()
//!             && c.named_fields().any(|f| matches!(f.kind, FieldKind::F32 { .. })))?;
//!         let f = c.named_fields().find(|f| matches!(f.kind, FieldKind::F32 { .. }))?;
//!         Some((s.clone(), c.clone(), f.display_name().to_owned()))
//!     })
//!     .ok_or("no read with a float field in the spec")?;
//! let address = sensor.default_address;
//! let mut sim = Simulator::new(sensor);
//! sim.set(&read.name, &field, Value::Float(6.5))?;
//! let mut client = Client::new(ResponderTransport::new(sim));
//! let request = read.encode_request(address, &BTreeMap::new())?;
//! let reply = client.call_raw(&request, &read.layout())?;
//! let values = read.decode_response(address, reply)?;
//! assert_eq!(values.iter().find(|(name, _)| *name == field).map(|(_, v)| v), Some(&Value::Float(6.5)));
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
#![cfg_attr(not(test), deny(clippy::unwrap_used, clippy::expect_used, clippy::panic, clippy::indexing_slicing))]

use std::time::Duration;

pub mod bath;
pub mod behaviour;
mod bus;
pub mod fault;
mod registers;
pub mod serve;
mod simulator;

pub use bath::Standard;
pub use behaviour::{MeasurementState, SerialNumberPolicy, WarmUpPolicy};
pub use bus::Bus;
pub use fault::{FaultConfig, FaultCounts, FaultKind, Rng};
pub use registers::RegisterMap;
pub use serve::{Endpoint, ServeConfig, Server, serve_mbap, serve_memory, serve_tcp, serve_transport};
#[cfg(all(unix, feature = "pty"))]
pub use serve::{pty_keeps_parity, serve_pty, tap::serve_pty_tapped};
pub use simulator::{
    SimError, Simulator, Stats, UnknownRequestPolicy, Variation, WATER_TEMPERATURE_C, WATER_TEMPERATURE_SPAN_C,
    daily_span,
};

/// Something on the bus that answers request frames: a [`Simulator`] or a
/// [`Bus`] of them. The serving functions take any `FrameHandler`.
pub trait FrameHandler {
    /// Handles one request frame: appends the reply to `reply` (nothing
    /// for no reply: ignored, broadcast, dropped) and returns how long the
    /// reply is held back before it is sent, zero unless a
    /// [`FaultKind::Delay`] was injected. Threaded servers sleep that long;
    /// in-process [`yosemitech_rtu::Responder`]s withhold a held-back reply.
    fn handle(&mut self, request: &[u8], reply: &mut Vec<u8>) -> Duration;
}

impl<D: FrameHandler + ?Sized> FrameHandler for &mut D {
    fn handle(&mut self, request: &[u8], reply: &mut Vec<u8>) -> Duration {
        (**self).handle(request, reply)
    }
}

impl<D: FrameHandler + ?Sized> FrameHandler for Box<D> {
    fn handle(&mut self, request: &[u8], reply: &mut Vec<u8>) -> Duration {
        (**self).handle(request, reply)
    }
}
