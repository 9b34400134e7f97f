//! Simulator tests' kit: simulators of spec sensors, exchanges, and
//! commands chosen from the spec by role, field type and layout.

use std::collections::BTreeMap;
use std::time::Duration;

use yosemitech_rtu::{Client, ClientConfig, RetryPolicy, Transport};
use yosemitech_sim::{FrameHandler, Simulator, UnknownRequestPolicy};
use yosemitech_spec::{CommandSpec, Sensor, Spec, Value};

pub use crate::{sensor, spec, with_crc};

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
pub fn command(sensor: &Sensor, name: &str) -> CommandSpec {
    sensor.command(name).unwrap_or_else(|| panic!("no command {name}")).clone()
}

/// The request frame for `command` to `slave` with write `values`.
pub fn request(command: &CommandSpec, slave: u8, values: &[(&str, Value)]) -> Vec<u8> {
    let values: BTreeMap<String, Value> = values.iter().map(|(k, v)| (k.to_string(), v.clone())).collect();
    command.encode_request(slave, &values).expect("the request encodes")
}

/// The reply of `device` to `request` (empty for none); panics on a delay.
pub fn exchange(device: &mut impl FrameHandler, request: &[u8]) -> Vec<u8> {
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

// Choices from the spec: tests pick what they need by role, field type and
// layout, so that a new manual needs no Rust edit.

/// True for an f32 field.
pub fn is_f32(field: &yosemitech_spec::Field) -> bool {
    matches!(field.kind, yosemitech_spec::FieldKind::F32 { .. })
}

/// True for a read a plain request gets at the probe's own address: no
/// fixed slave, not a trigger, with fields, every one a named f32.
pub fn is_float_read(command: &CommandSpec) -> bool {
    command.is_read()
        && command.fixed_slave.is_none()
        && !command.trigger
        && !command.fields.is_empty()
        && command.fields.iter().all(|f| f.name.is_some() && is_f32(f))
}

/// The first sensor of the spec with a read whose only field is an f32, and that read.
pub fn float_read(spec: &Spec) -> (Sensor, CommandSpec) {
    spec.sensors
        .iter()
        .find_map(|s| {
            s.commands.iter().find(|c| is_float_read(c) && c.fields.len() == 1).map(|c| (s.clone(), c.clone()))
        })
        .expect("a sensor with a read whose only field is an f32")
}

/// The name of a command's first field.
pub fn first_field(command: &CommandSpec) -> String {
    command.fields[0].name.clone().expect("a named field")
}

/// `v` as an f32 field puts it on the wire.
pub fn f32_bytes(field: &yosemitech_spec::Field, v: f32) -> [u8; 4] {
    use yosemitech_rtu::ByteOrder4;
    use yosemitech_spec::FieldKind;
    let [a, b, c, d] = v.to_be_bytes();
    match field.kind {
        FieldKind::F32 { order: ByteOrder4::Abcd } => [a, b, c, d],
        FieldKind::F32 { order: ByteOrder4::Dcba } => [d, c, b, a],
        FieldKind::F32 { order: ByteOrder4::Cdab } => [c, d, a, b],
        FieldKind::F32 { order: ByteOrder4::Badc } => [b, a, d, c],
        ref other => panic!("not an f32: {other:?}"),
    }
}

/// A write of f32 fields without a range, and the read at the same
/// registers that reads the same fields back: `(write, read)`.
pub fn float_write_with_readback(sensor: &Sensor) -> Option<(CommandSpec, CommandSpec)> {
    sensor.commands.iter().filter(|w| !w.is_read() && w.fixed_slave.is_none()).find_map(|w| {
        let fields_ok =
            !w.fields.is_empty() && w.fields.iter().all(|f| f.name.is_some() && is_f32(f) && f.range.is_none());
        let read = sensor.commands.iter().find(|r| {
            is_float_read(r)
                && r.address == w.address
                && r.count == w.count
                && r.fields.iter().map(|f| &f.name).eq(w.fields.iter().map(|f| &f.name))
        });
        read.filter(|_| fields_ok).map(|r| (w.clone(), r.clone()))
    })
}

/// The first sensor of the spec with a command of `role`.
pub fn sensor_with_role(spec: &Spec, role: yosemitech_spec::Role) -> Sensor {
    spec.sensors
        .iter()
        .find(|s| s.command_with_role(role).is_some())
        .unwrap_or_else(|| panic!("a sensor with a {} command", role.name()))
        .clone()
}

/// The command of `role` of `sensor`.
pub fn with_role(sensor: &Sensor, role: yosemitech_spec::Role) -> CommandSpec {
    sensor.command_with_role(role).unwrap_or_else(|| panic!("{}: no {} command", sensor.name, role.name())).clone()
}

/// The reply data of the last example of `read` with a reply, decoded:
/// what a simulator serves before anything is set.
pub fn example_reading(read: &CommandSpec) -> Option<yosemitech_spec::Values> {
    read.examples
        .iter()
        .rev()
        .find_map(|e| e.true_response().and_then(|frame| read.decode_response(e.slave(), frame).ok()))
}

/// The reply frame of the last example of `read` with a reply.
pub fn example_reply(read: &CommandSpec) -> Option<Vec<u8>> {
    read.examples.iter().rev().find_map(|e| e.true_response().map(<[u8]>::to_vec))
}

/// Whether `sensor`'s command with `role` has `layout` on the wire.
pub fn plays(sensor: &Sensor, role: yosemitech_spec::Role, layout: yosemitech_rtu::Layout<'static>) -> bool {
    sensor.command_with_role(role).is_some_and(|c| c.layout() == layout)
}

/// Every sensor of the spec whose slave-address write has the layout
/// `set_address` and whose serial-number read has the layout `serial_number`
/// (the shared generated commands), picked by role: the sensors a generic
/// address change can move with those two types.
pub fn sensors_sharing_address_commands(
    set_address: yosemitech_rtu::Layout<'static>,
    serial_number: yosemitech_rtu::Layout<'static>,
) -> Vec<Sensor> {
    use yosemitech_spec::Role;
    spec()
        .sensors
        .iter()
        .filter(|s| plays(s, Role::SetSlaveAddress, set_address) && plays(s, Role::SerialNumber, serial_number))
        .cloned()
        .collect()
}

/// Each generated sensor module (`yosemitech::SENSORS`) with a simulator of
/// its spec sensor at its factory address.
pub fn simulated_modules() -> Vec<(&'static yosemitech_rtu::SensorModule, Simulator)> {
    yosemitech::SENSORS
        .iter()
        .map(|module| {
            let sensor = spec().sensor(module.info.name).expect("every generated sensor is in the spec").clone();
            (module, Simulator::new(sensor))
        })
        .collect()
}

/// A read request of a generated module, encoded by its generated layout.
#[derive(Debug)]
pub struct ReadRequest {
    /// The command's spec name.
    pub name: &'static str,
    /// The command's wire layout.
    pub layout: yosemitech_rtu::Layout<'static>,
    /// Where it goes: the command's fixed slave, else the module's factory address.
    pub slave: u8,
    /// The request frame, CRC included.
    pub frame: Vec<u8>,
}

/// The request of every read command of `module` (reads with no write
/// data), in spec order.
pub fn read_requests(module: &yosemitech_rtu::SensorModule) -> Vec<ReadRequest> {
    use yosemitech_rtu::frame::{Function, MAX_ADU};
    module
        .commands
        .iter()
        .map(|entry| (entry.name, entry.layout))
        .filter(|(_, layout)| layout.function == Function::Read)
        .map(|(name, layout)| {
            let slave = layout.fixed_slave.unwrap_or(module.info.default_address);
            let mut frame = [0u8; MAX_ADU];
            let len = layout.encode_request(slave, &[], &mut frame).unwrap_or_else(|e| panic!("{name}: {e:?}"));
            ReadRequest { name, layout, slave, frame: frame[..len].to_vec() }
        })
        .collect()
}

/// An address `sensor` may be given (inside its `addresses` and 1..=247)
/// that is none of `taken`, the lowest such: where a test moves a probe, or
/// puts several on one bus, without assuming which addresses a manual allows.
pub fn free_address(sensor: &Sensor, taken: &[u8]) -> Option<u8> {
    (sensor.min_address.max(1)..=sensor.max_address.min(247)).find(|a| !taken.contains(a))
}

/// True when the registers of `a` and `b` share a register.
pub fn overlap(a: &CommandSpec, b: &CommandSpec) -> bool {
    let end = |c: &CommandSpec| u32::from(c.address) + u32::from(c.count);
    u32::from(a.address) < end(b) && u32::from(b.address) < end(a)
}

/// The register data a read's example leaves in a fresh simulator's
/// registers: its true reply's data, when the layout decodes it.
fn seeded_data(read: &CommandSpec, example: &yosemitech_spec::Example) -> Option<Vec<u8>> {
    let frame = example.true_response()?;
    read.layout().decode_response(example.slave(), frame).ok().filter(|d| !d.is_empty()).map(<[u8]>::to_vec)
}

/// Whether a fresh simulator of `sensor` serves `read`'s last example reply
/// from power-on, by the simulator's seeding rule (examples of writes
/// first, then of reads, in spec order, each over the last): `read` has an
/// example whose reply data seeds its registers, and no read after it in
/// the spec seeds a register it shares, and no role rewrites them (the
/// serial number, the slave address). Where a later read's example covers
/// the same registers, the manual shows two states of the probe: a test
/// loads the one it needs.
pub fn seeded_from_example(sensor: &Sensor, read: &CommandSpec) -> bool {
    use yosemitech_spec::Role;
    let Some(position) = sensor.commands.iter().position(|c| c.name == read.name) else { return false };
    let rewritten = [Role::SerialNumber, Role::SetSlaveAddress, Role::GetSlaveAddress]
        .iter()
        .filter_map(|role| sensor.command_with_role(*role))
        .any(|c| overlap(c, read));
    read.is_read()
        && !read.trigger
        && !rewritten
        && read.examples.iter().any(|e| seeded_data(read, e).is_some())
        && !reseeded_by_a_later_read(sensor, position)
}

/// Whether a read after `sensor.commands[position]` in the spec has an
/// example that seeds a register of it in a fresh simulator (reads' examples
/// are applied in spec order, each over the last).
fn reseeded_by_a_later_read(sensor: &Sensor, position: usize) -> bool {
    let Some(read) = sensor.commands.get(position) else { return false };
    sensor.commands[position + 1..]
        .iter()
        .filter(|c| c.is_read() && overlap(c, read))
        .any(|c| c.examples.iter().any(|e| seeded_data(c, e).is_some()))
}

/// Whether a read after `read` in the spec seeds a register of `read` from
/// its example in a fresh simulator, so that `read`'s own examples are not
/// what the simulator serves from power-on.
pub fn reseeded_later(sensor: &Sensor, read: &CommandSpec) -> bool {
    sensor.commands.iter().position(|c| c.name == read.name).is_some_and(|i| reseeded_by_a_later_read(sensor, i))
}

/// The first sensor of the spec with a measurement read
/// ([`Sensor::is_measurement`]: the simulator varies it) whose only field is
/// an f32, and that read; `None` when the spec has none.
pub fn measurement_float_read(spec: &Spec) -> Option<(Sensor, CommandSpec)> {
    spec.sensors.iter().find_map(|s| {
        s.commands
            .iter()
            .find(|c| is_float_read(c) && c.fields.len() == 1 && s.is_measurement(c))
            .map(|c| (s.clone(), c.clone()))
    })
}
