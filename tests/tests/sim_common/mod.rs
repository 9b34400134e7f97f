//! Helpers shared by the simulator tests (`sim_*.rs`).
#![allow(dead_code, clippy::result_large_err)]

use std::collections::BTreeMap;
use std::time::Duration;

use yosemitech_rtu::{Client, ClientConfig, RetryPolicy, Transport, crc16};
use yosemitech_sim::{Device, Simulator, UnknownRequestPolicy};
use yosemitech_spec::{Command, Sensor, Spec, Value};

/// The workspace's spec directory, loaded.
pub fn spec() -> Spec {
    yosemitech_spec::load_paths(&[concat!(env!("CARGO_MANIFEST_DIR"), "/../spec").into()]).expect("the spec loads")
}

/// One sensor of the spec.
pub fn sensor(name: &str) -> Sensor {
    spec().sensor(name).unwrap_or_else(|| panic!("no sensor {name}")).clone()
}

/// A simulator of `name` at its factory address.
pub fn sim(name: &str) -> Simulator {
    Simulator::new(sensor(name))
}

/// A simulator of `name` that answers requests matching no command with
/// exceptions ([`UnknownRequestPolicy::Exception`]) instead of silence.
pub fn sim_with_exceptions(name: &str) -> Simulator {
    let mut sim = sim(name);
    sim.set_unknown_request_policy(UnknownRequestPolicy::Exception);
    sim
}

/// A command of a sensor.
pub fn command(sensor: &Sensor, name: &str) -> Command {
    sensor.command(name).unwrap_or_else(|| panic!("no command {name}")).clone()
}

/// The request frame for `command` to `slave` with write `values`.
pub fn request(command: &Command, slave: u8, values: &[(&str, Value)]) -> Vec<u8> {
    let values: BTreeMap<String, Value> = values.iter().map(|(k, v)| (k.to_string(), v.clone())).collect();
    command.encode_request(slave, &values).expect("the request encodes")
}

/// `bytes` followed by their CRC.
pub fn with_crc(bytes: &[u8]) -> Vec<u8> {
    let mut frame = bytes.to_vec();
    frame.extend_from_slice(&crc16(bytes).to_le_bytes());
    frame
}

/// The reply of `device` to `request` (empty for none); panics on a delay.
pub fn exchange(device: &mut impl Device, request: &[u8]) -> Vec<u8> {
    let mut reply = Vec::new();
    let delay = device.handle(request, &mut reply);
    assert_eq!(delay, Duration::ZERO, "no delay expected");
    reply
}

/// The exception reply `slave`, `function | 0x80`, `code`, CRC.
pub fn exception(slave: u8, function: u8, code: u8) -> Vec<u8> {
    with_crc(&[slave, function | 0x80, code])
}

/// A client with a short timeout and no retries.
pub fn client<T: Transport>(transport: T, timeout: Duration) -> Client<T> {
    Client::with_config(transport, ClientConfig { timeout, retry: RetryPolicy::NONE, ..ClientConfig::default() })
}

/// Decoded values equal bit for bit.
pub fn same(a: &[(String, Value)], b: &[(String, Value)]) -> bool {
    a.len() == b.len() && a.iter().zip(b).all(|((na, va), (nb, vb))| na == nb && va.same_as(vb))
}
