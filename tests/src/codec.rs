//! Shared by the golden, round-trip and differential tests: every generated
//! sensor module seen through its own dispatch API (`CommandId::ALL`,
//! `decode_request`, `decode_response`, `Request`/`Response`), next to the
//! spec command it was generated from.
//!
//! The only hand-written list is the sensor modules ([`sensors`]), and
//! [`sensors`] checks it against the spec directories: a sensor added to the
//! spec without being listed here fails every test that uses it. Commands
//! are never listed by hand.

use std::collections::BTreeMap;
use std::path::PathBuf;
use std::sync::OnceLock;

use yosemitech_rtu::{EncodeError, FieldValue, FrameError, Layout, RoundTripError, SensorModule, Version};
use yosemitech_spec::{FieldKind, Spec, Value};

/// A decoded field value, owned, with floats as bits.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Val {
    /// An f32, by its bits.
    F32(u32),
    /// Any integer.
    Int(i64),
    /// Text without padding, raw bytes.
    Text(Vec<u8>),
    /// A version.
    Version(Version),
    /// A BCD byte, raw.
    Bcd(u8),
    /// An enum code.
    Enum {
        /// The code on the wire.
        raw: u16,
        /// The variant's name, when the code is known.
        name: Option<&'static str>,
    },
}

impl Val {
    /// The owned form of a value generated code produced.
    pub fn of(v: FieldValue<'_>) -> Self {
        match v {
            FieldValue::F32(f) => Self::F32(f.to_bits()),
            FieldValue::Int(i) => Self::Int(i),
            FieldValue::Text(t) => Self::Text(t.to_vec()),
            FieldValue::Version(v) => Self::Version(v),
            FieldValue::Bcd(b) => Self::Bcd(b.0),
            FieldValue::Enum { raw, name } => Self::Enum { raw, name },
        }
    }

    /// Bit-exact equality with an interpreter value ([`Value::matches`]).
    pub fn same_as(&self, v: &Value) -> bool {
        v.matches(&self.as_field())
    }

    /// The borrowed form generated code produces.
    pub fn as_field(&self) -> FieldValue<'_> {
        match self {
            Self::F32(bits) => FieldValue::F32(f32::from_bits(*bits)),
            Self::Int(i) => FieldValue::Int(*i),
            Self::Text(bytes) => FieldValue::Text(bytes),
            Self::Version(v) => FieldValue::Version(*v),
            Self::Bcd(b) => FieldValue::Bcd(yosemitech_rtu::Bcd(*b)),
            Self::Enum { raw, name } => FieldValue::Enum { raw: *raw, name: *name },
        }
    }

    /// The interpreter's value, for encoding through it. `None` for text
    /// the interpreter cannot take (it encodes ASCII text; the generated
    /// `Ascii<N>` keeps whatever bytes the device sent).
    pub fn to_value(&self) -> Option<Value> {
        Some(match self {
            Self::F32(bits) => Value::Float(f32::from_bits(*bits)),
            Self::Int(i) => Value::Int(*i),
            Self::Text(bytes) if bytes.is_ascii() => Value::Text(bytes.iter().map(|&b| char::from(b)).collect()),
            Self::Text(_) => return None,
            Self::Version(v) => Value::Version(*v),
            Self::Bcd(b) => Value::Bcd(yosemitech_rtu::Bcd(*b)),
            Self::Enum { raw, name } => Value::Enum { raw: *raw, name: name.map(str::to_owned) },
        })
    }
}

/// A decoded message: its fields, and what the generated code encodes it back to.
#[derive(Debug, Clone, PartialEq)]
pub struct Decoded {
    /// The slave address (of the request; of the request a reply answers).
    pub slave: u8,
    /// Field names and values, wire order.
    pub values: Vec<(&'static str, Val)>,
    /// The frame the generated code encodes the decoded value to.
    pub encoded: Result<Vec<u8>, EncodeError>,
}

impl Decoded {
    /// Bit-exact equality of the values with interpreter values.
    pub fn same_values(&self, values: &[(String, Value)]) -> bool {
        self.values.len() == values.len()
            && self.values.iter().zip(values).all(|((n, v), (m, w))| n == m && v.same_as(w))
    }

    /// The values as the interpreter's input map, if it can take them.
    pub fn value_map(&self) -> Option<BTreeMap<String, Value>> {
        self.values.iter().map(|(n, v)| Some(((*n).to_owned(), v.to_value()?))).collect()
    }
}

type DecodeRequest = Box<dyn Fn(&[u8]) -> Result<Decoded, FrameError> + Send + Sync>;
type DecodeResponse = Box<dyn Fn(u8, &[u8]) -> Result<Decoded, FrameError> + Send + Sync>;
type IdentifyRequest = Box<dyn Fn(&[u8]) -> Option<&'static str> + Send + Sync>;

/// One generated command, through the generated dispatch API.
pub struct Cmd {
    /// The spec's name (`CommandId::name`).
    pub name: &'static str,
    /// `CommandId::layout`.
    pub layout: Layout<'static>,
    /// `CommandId::decode_request`, then `Request::fields` and `Request::encode`.
    pub decode_request: DecodeRequest,
    /// `CommandId::decode_response`, then `Response::fields` and `Response::encode`.
    pub decode_response: DecodeResponse,
    /// `identify_request` of the command's module.
    pub identify: IdentifyRequest,
}

/// One generated sensor module.
pub struct Api {
    /// The module's (sensor's) name, from its `SENSOR` constant.
    pub sensor: &'static str,
    /// Every command, from `CommandId::ALL`.
    pub commands: Vec<Cmd>,
}

/// Builds the [`Api`] of a generated module from its `MODULE` (the
/// generated dispatch as data), so no test names a sensor.
fn api(module: &'static SensorModule) -> Api {
    Api {
        sensor: module.info.name,
        commands: module
            .commands
            .iter()
            .map(|entry| Cmd {
                name: entry.name,
                layout: entry.layout,
                decode_request: Box::new(move |frame: &[u8]| {
                    let mut values = Vec::new();
                    let slave = entry.visit_request(frame, &mut |info, v| values.push((info.name, Val::of(v))))?;
                    let mut buf = [0u8; 256];
                    let encoded = match entry.reencode_request(frame, &mut buf) {
                        Ok(n) => Ok(buf[..n].to_vec()),
                        Err(RoundTripError::Encode(e)) => Err(e),
                        Err(RoundTripError::Frame(e)) => return Err(e),
                    };
                    Ok(Decoded { slave, values, encoded })
                }),
                decode_response: Box::new(move |slave: u8, frame: &[u8]| {
                    let mut values = Vec::new();
                    entry.visit_response(slave, frame, &mut |info, v| values.push((info.name, Val::of(v))))?;
                    let mut buf = [0u8; 256];
                    let encoded = match entry.reencode_response(slave, frame, &mut buf) {
                        Ok(n) => Ok(buf[..n].to_vec()),
                        Err(RoundTripError::Encode(e)) => Err(e),
                        Err(RoundTripError::Frame(e)) => return Err(e),
                    };
                    Ok(Decoded { slave, values, encoded })
                }),
                identify: Box::new(move |frame: &[u8]| module.identify_request(frame)),
            })
            .collect(),
    }
}

/// The fixture sensor's spec directory.
pub fn fixture_dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("fixtures/do-probe/spec")
}

/// The spec of every generated module: the workspace's and the fixture's.
pub fn generated_spec() -> &'static Spec {
    static SPEC: OnceLock<Spec> = OnceLock::new();
    SPEC.get_or_init(|| {
        let mut spec = yosemitech_spec::load_paths(&[crate::spec_dir()]).unwrap_or_else(|e| panic!("{e}"));
        let fixture = yosemitech_spec::load_paths(&[fixture_dir()]).unwrap_or_else(|e| panic!("{e}"));
        spec.sensors.extend(fixture.sensors);
        spec
    })
}

/// Every generated module with its spec sensor, checked to be one-to-one
/// with the spec, and every module's commands checked against the spec's.
pub fn sensors() -> Vec<(Api, &'static yosemitech_spec::Sensor)> {
    let apis: Vec<Api> = yosemitech::SENSORS.iter().chain(crate::fixture::SENSORS).map(api).collect();
    let spec = generated_spec();
    let listed: Vec<&str> = apis.iter().map(|a| a.sensor).collect();
    let in_spec: Vec<&str> = spec.sensors.iter().map(|s| s.name.as_str()).collect();
    let mut a = listed.clone();
    let mut b = in_spec.clone();
    a.sort();
    b.sort();
    assert_eq!(
        a, b,
        "the generated modules (yosemitech::SENSORS and the fixture's) must be exactly the spec's sensors"
    );
    apis.into_iter()
        .map(|api| {
            let sensor = spec.sensor(api.sensor).expect("checked above");
            let generated: Vec<&str> = api.commands.iter().map(|c| c.name).collect();
            let specified: Vec<&str> = sensor.commands.iter().map(|c| c.name.as_str()).collect();
            assert_eq!(generated, specified, "{}: CommandId::ALL is the spec's commands in order", api.sensor);
            for c in &api.commands {
                assert_eq!(c.layout, sensor.command(c.name).unwrap().layout(), "{}.{}: layout", api.sensor, c.name);
            }
            (api, sensor)
        })
        .collect()
}

/// Register data with every reserved byte set to its fill: what an encoder writes.
pub fn normalized(command: &yosemitech_spec::CommandSpec, data: &[u8]) -> Vec<u8> {
    let mut data = data.to_vec();
    for f in &command.fields {
        if let FieldKind::Reserved { len, fill } = f.kind {
            for b in data.iter_mut().skip(f.offset).take(len) {
                *b = fill;
            }
        }
    }
    data
}

/// A request frame with `data` as register data (writes), built by the runtime's framing.
pub fn request_frame(command: &yosemitech_spec::CommandSpec, slave: u8, data: &[u8]) -> Vec<u8> {
    let layout = command.layout();
    let data = if command.is_read() { &[][..] } else { data };
    let mut out = vec![0u8; layout.request_len()];
    let n = layout.encode_request(slave, data, &mut out).expect("valid layout and slave");
    out.truncate(n);
    out
}

/// A reply frame with `data` as register data (reads), built by the runtime's framing.
pub fn response_frame(command: &yosemitech_spec::CommandSpec, slave: u8, data: &[u8]) -> Vec<u8> {
    let layout = command.layout();
    let data = if command.is_read() && !command.trigger { data } else { &[][..] };
    let mut out = vec![0u8; layout.response_len()];
    let n = layout.encode_response(slave, data, &mut out).expect("valid layout");
    out.truncate(n);
    out
}

/// A slave address the command may be sent to.
pub fn usable_slave(command: &yosemitech_spec::CommandSpec, wanted: u8) -> u8 {
    command.fixed_slave.unwrap_or(wanted.clamp(1, 247))
}

/// Bit patterns of f32s that codecs get wrong: NaN payloads (quiet,
/// signalling, negative), infinities, signed zeros, subnormals, extremes.
pub const SPECIAL_F32: [u32; 12] = [
    0x7FC0_0000, // NaN
    0x7FC0_0001, // NaN with a payload
    0xFFBF_FFFF, // negative NaN, full payload
    0x7F80_0001, // signalling NaN
    0x7F80_0000, // +inf
    0xFF80_0000, // -inf
    0x8000_0000, // -0.0
    0x0000_0000, // +0.0
    0x0000_0001, // smallest subnormal
    0x807F_FFFF, // largest negative subnormal
    0x7F7F_FFFF, // f32::MAX
    0xFF7F_FFFF, // f32::MIN
];

/// Register data of `command` from random bytes, with special f32 patterns
/// put into some float fields (chosen by `specials`, one entry per float field).
pub fn data_with_specials(
    command: &yosemitech_spec::CommandSpec,
    mut data: Vec<u8>,
    specials: &[Option<u32>],
) -> Vec<u8> {
    let floats = command.fields.iter().filter_map(|f| match f.kind {
        FieldKind::F32 { order } => Some((f.offset, order)),
        _ => None,
    });
    for ((offset, order), special) in floats.zip(specials) {
        if let Some(bits) = special {
            let bytes = yosemitech_rtu::codec::f32_to_wire(order, f32::from_bits(*bits));
            data[offset..offset + 4].copy_from_slice(&bytes);
        }
    }
    data
}

/// Random register data for `command`, with special floats (NaN payloads,
/// infinities, -0.0, …) in some f32 fields.
pub fn data_strategy(
    command: &yosemitech_spec::CommandSpec,
) -> impl proptest::strategy::Strategy<Value = Vec<u8>> + use<> {
    use proptest::prelude::*;
    let floats = command.fields.iter().filter(|f| matches!(f.kind, FieldKind::F32 { .. })).count();
    let command = command.clone();
    (
        proptest::collection::vec(any::<u8>(), data_len(&command)),
        proptest::collection::vec(proptest::option::weighted(0.3, proptest::sample::select(&SPECIAL_F32[..])), floats),
    )
        .prop_map(move |(data, specials)| data_with_specials(&command, data, &specials))
}

/// Register data bytes of a command's reply (reads) or request (writes).
pub fn data_len(command: &yosemitech_spec::CommandSpec) -> usize {
    2 * usize::from(command.count)
}

/// `data` with every ASCII field made printable text of `len % (size + 1)`
/// characters followed by padding, as a real device sends.
pub fn asciified(command: &yosemitech_spec::CommandSpec, data: &[u8], len: usize) -> Vec<u8> {
    let mut data = data.to_vec();
    for f in &command.fields {
        if let FieldKind::Ascii { len: size, padding } = f.kind {
            let text = len % (size + 1);
            for (i, b) in data.iter_mut().skip(f.offset).take(size).enumerate() {
                *b = if i < text { b' ' + 1 + *b % 94 } else { padding };
            }
        }
    }
    data
}
