//! Typed, allocation-free Modbus RTU codecs and device handles for Yosemitech
//! water-quality probes, generated from the vendor manuals.
//!
//! Every sensor module here is generated from the YAML spec files that
//! transcribe the manuals (`spec/*.yaml`: registers, field types, byte
//! orders, units, the manuals' example frames and their errata). The spec is
//! the single source of truth: the same files drive the reference
//! interpreter, the simulator, the golden tests and the register maps in
//! `docs/sensors/`. The crate ships the generated code
//! (`crates/yosemitech/generated/`, written by `cargo xtask codegen`), as
//! `prost-types` ships its well-known types, so that building it compiles
//! neither the spec loader nor the generator; a crate with spec files of
//! its own generates its modules from its `build.rs` with
//! `yosemitech-codegen`.
//!
//! # Decoding a frame
//!
//! ```
//! use yosemitech::Command;
//! use yosemitech::ph_orp::GetPh;
//!
//! // The pH manual's example (figures 23 and 24).
//! let request = GetPh.request_frame(1)?;
//! assert_eq!(&*request, [0x01, 0x03, 0x28, 0x00, 0x00, 0x02, 0xCD, 0xAB]);
//!
//! let reply = [0x01, 0x03, 0x04, 0x33, 0x33, 0xF3, 0x40, 0x40, 0x78];
//! let response = GetPh::decode_response(1, &reply)?;
//! assert_eq!(response.ph, 7.6);
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
//!
//! # Talking to a probe
//!
//! With the `std` feature, each sensor module has a `Device` that borrows a
//! [`Client`] (one per bus) and knows the probe's slave address:
//!
//! ```
//! use yosemitech::{Client, ResponderTransport, ph_orp};
//!
//! // A stand-in for a serial port: answers get_ph like the manual's probe.
//! let transport = ResponderTransport::from_fn(|request: &[u8], reply: &mut Vec<u8>| {
//!     if request == [0x01, 0x03, 0x28, 0x00, 0x00, 0x02, 0xCD, 0xAB] {
//!         reply.extend_from_slice(&[0x01, 0x03, 0x04, 0x33, 0x33, 0xF3, 0x40, 0x40, 0x78]);
//!     }
//! });
//! let mut client = Client::new(transport);
//! let mut probe = ph_orp::Device::new(&mut client, 1);
//! assert_eq!(probe.ph()?.ph, 7.6);
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
//!
//! On hardware, open the RS-485 adapter's serial port (feature `serial`, on
//! by default) at the probe's factory settings, which each module's
//! `SENSOR` states, or use `TcpTransport` (RTU over TCP):
//!
//! ```no_run
//! # #[cfg(feature = "serial")] {
//! use yosemitech::{Client, SerialConfig, SerialTransport, ph_orp};
//!
//! let settings = ph_orp::SENSOR.line_settings();
//! // An error names the port and the settings tried.
//! let port = SerialTransport::open(&SerialConfig::with_settings("/dev/ttyUSB0", settings))?;
//! let mut client = Client::new(port);
//! let mut probe = ph_orp::Device::new(&mut client, ph_orp::SENSOR.default_address);
//! println!("pH {}", probe.ph()?.ph);
//! # }
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
//!
//! Each module's documentation lists its commands with the `Device` method
//! that sends each.
//!
//! The runtime logs nothing unless asked: feature `tracing` adds a debug span
//! per transaction and the frames sent and received as `tracing` events.
//!
//! # Generic code
//!
//! Each module has a `CommandId` enum listing every command, `Request` and
//! `Response` enums over all of them, and field metadata, so loggers and
//! command-line tools can work without naming commands in code:
//!
//! ```
//! use yosemitech::ph_orp::{self, CommandId};
//!
//! let id = CommandId::from_name("get_ph").expect("get_ph is a pH probe command");
//! let reply = [0x01, 0x03, 0x04, 0x33, 0x33, 0xF3, 0x40, 0x40, 0x78];
//! let response = ph_orp::decode_response(id, 1, &reply)?;
//! let shown: Vec<String> = response
//!     .fields()
//!     .map(|(info, value)| format!("{} = {value} {}", info.name, info.unit.unwrap_or("")))
//!     .collect();
//! assert_eq!(shown, ["ph = 7.6 pH"]);
//! # Ok::<(), yosemitech::FrameError>(())
//! ```
//!
//! # Conventions of the generated API
//!
//! For a sensor `s` (one module per spec file: [`ph_orp`], [`conductivity`])
//! and a command `get_ph` of its spec:
//!
//! - **Names** come from the spec: types are the command's name in
//!   UpperCamelCase (`GetPh`), fields keep their snake_case names (`ph`,
//!   `orp_mv`, `temperature_c`), constants are SHOUTY (`PH_CALIBRATION_STANDARDS`).
//! - **Declarations, not code**: a generated module declares types and
//!   tables; the runtime does the work. `GetPh` implements [`Command`] with
//!   its name and [`Layout`] only: encoding and decoding frames are the
//!   trait's provided methods. Requests and replies implement [`Message`]:
//!   `FIELDS` (name, unit), `Data` (`[u8; 2 × registers]`), `from_data`,
//!   `to_data`, `field(i)`, `fields()` and, for writes, `validate()`.
//!   Messages without data (reads' requests, triggers' replies) say
//!   [`rtu::NoData`]. Bring [`Message`] into scope to call its methods.
//! - **Requests**: reads are unit structs; writes are structs of typed
//!   fields (`SetSlaveId { slave_address: 20 }`), and `encode_request`
//!   refuses values outside the spec's `range` with
//!   [`EncodeError::OutOfRange`] (`validate()` checks without encoding).
//! - **Replies**: a read replies with `GetPhResponse`, a struct of named
//!   fields; a write replies with `()` (the runtime checks the echoed address
//!   and count).
//! - **What a later manual adds breaks nothing that did not use it** (see
//!   "Stability" below): replies, coded-field enums, `CommandId`, `Request`
//!   and `Response` are `#[non_exhaustive]`, and the tables are slices.
//! - **Field types**: `f32`, `u8`/`i8`/`u16`/`i16`/`u32`/`i32`, [`Ascii<N>`]
//!   (raw bytes kept, padding trimmed on display), [`Version`], and a
//!   generated enum per coded field with an `Unknown(raw)` arm
//!   (`CalibrationStatus::from_raw(4)`, `.raw()`, `.name()`, `KNOWN`).
//! - **Dispatch**: `COMMANDS`, one [`rtu::CommandEntry`] per command (name,
//!   title, layout, fields, codecs as function pointers), is the module's
//!   command table; `CommandId` indexes it (`ALL`, `name()`, `from_name()`,
//!   `layout()`, `entry()`, `decode_request()`, `decode_response()`), and
//!   `MODULE` ([`rtu::SensorModule`]) carries it for code that serves every
//!   sensor. `Request`, `Response`, `decode_response(id, slave, frame)` and
//!   `identify_request(frame)` (by function, start address and register
//!   count) complete it. A module declares these with
//!   [`rtu::command_set!`], which spells them once for every module.
//! - **Device handles** (`std`): `Device::new(&mut client, address)`; reads
//!   are named after the command without `get_` and return the reply struct,
//!   even of one field (`ph()?.ph`, `orp()?.orp_mv`, `sn()?.serial_number`,
//!   `version()`, `orp_and_ph()`); writes keep
//!   their name and take the field (`set_slave_id(20)`,
//!   `start_ph_calibration(4.0)`) or, with several fields, the request struct
//!   (`set_orp_calibration(SetOrpCalibration { k_slope: 1.0, b_offset: 0.0 })`).
//!   `Device::call` sends any command. Commands with a fixed slave address
//!   (`get_slave_id`, 0xFF) use it instead of the device's.
//! - **Async device handles** (`tokio`): `AsyncDevice::new(&mut client,
//!   address)` over an `rtu::AsyncClient`, with the same
//!   methods as `async fn`s (`probe.ph().await`), generated from the same
//!   parts as `Device`.
//! - **Shared commands**: a command several probes take from the same
//!   fragment of the spec (the serial number, the slave address, the
//!   optical start/stop triggers, ...) is generated once, in a module named
//!   after the fragment ([`yosemitech_common`]), and each sensor module
//!   re-exports it: `ph_orp::GetSn` and `conductivity::GetSn` are one type.
//! - **All sensors as data**: [`SENSORS`] lists every generated module as a
//!   [`SensorModule`](rtu::SensorModule) (layout, identification, typed decode
//!   and re-encode by command name), for code that serves any probe without
//!   naming one.
//! - **Constants** of the procedures (`ph_orp::PH_CALIBRATION_STANDARDS`,
//!   `conductivity::MEASUREMENT_WARM_UP_MS`) and `SENSOR`, a [`SensorInfo`]
//!   with the serial settings and address range.
//! - **Docs** of each type carry the manual's title, text, section and
//!   figures, the command's function, address and count, the printed example
//!   frames, and the errata that concern it.
//!
//! # Stability
//!
//! A new revision of a manual adds fields, codes and commands; code that did
//! not use them compiles unchanged against the crate generated from it:
//!
//! - A reply struct is `#[non_exhaustive]`: read its fields, match it with
//!   `..` (`GetPhResponse { ph, .. }`); outside this crate it is made by
//!   decoding, or from data bytes with [`Message::from_data`] (tests,
//!   simulators).
//! - Coded-field enums, `CommandId`, `Request` and `Response` are
//!   `#[non_exhaustive]`: a `match` needs a `_` arm.
//! - `COMMANDS`, `CommandId::ALL`, each enum's `KNOWN`, `DERIVED` and
//!   [`SENSORS`] are `&'static [T]`: their lengths are no part of a type.
//! - A read's `Device` method returns the reply struct, so a field joining
//!   a one-field reply changes no signature.
//! - Write requests stay exhaustive structs, built by their user: a field a
//!   later manual adds to a write is data the device now needs, and the
//!   compiler should ask every caller for it.
//!
//! Decoding never allocates and never panics on any input: every check
//! (length, CRC, slave, function, byte count, write echo, Modbus exception)
//! is a typed [`FrameError`].
//!
//! # Procedures
//!
//! [`procedures`] runs what the manuals describe, with the spec's numbers:
//! the conductivity measurement (warm-up, averaging, flagged readings
//! discarded, TDS), the three-point pH calibration (coefficients backed up
//! before anything is written), the backup and restore of every coefficient
//! block of any sensor with read-back ([`procedures::backup`], through
//! [`SENSORS`]' module as data), and a slave-address change verified at the
//! new address. Waits are injectable, so tests run instantly.
//! `examples/pty_sensors.rs` reads every measurement from simulated probes
//! on ptys through the serial transport.
//!
//! # Quirks the manuals document
//!
//! - Floats are 4-byte little-endian images (`dcba`), not Modbus big-endian.
//! - `get_ph_electrode_coefficients` accepts byte count 0x0C as well as 0x18
//!   (erratum E4: the manual's example prints 0x0C over 24 data bytes).
//! - `get_slave_id` is sent to and answered from 0xFF (erratum E3).
//! - `conductivity::StartMeasurement` writes zero registers (erratum E11).
//! - The optical probes' Start/Stop Measurement are reads used as triggers:
//!   their reply carries no value and is accepted in each form the manuals'
//!   figures allow (see `rtu::Layout::trigger`).
//! - Real probes do not answer a register they lack: a command a probe's
//!   firmware predates (`since` in the spec) times out.
//!
//! # Features
//!
//! - `std` (default): device handles, the [`Client`] and transports, and
//!   `std::error::Error` for the errors. Without it the crate is `no_std`
//!   and offers the codecs only.
//! - `serial` (default): the serial-port transport (no libudev needed).
//! - `tokio`: `rtu::AsyncClient`, the async device handles
//!   (`AsyncDevice`) and their links: RTU frames on any tokio stream
//!   (`RtuStream`: TCP to a transparent gateway) and Modbus
//!   TCP to an Ethernet gateway (`MbapLink`). Same protocol
//!   core, timing, checks and retries as the blocking [`Client`]; a call
//!   dropped half-way leaves the bus usable; no allocation per transaction.
//! - `tokio-serial`: the tokio serial-port link (`rtu::AsyncSerial`).
//! - `tokio-modbus`: `rtu::tokio_modbus::call` runs any command over an
//!   existing `tokio_modbus::client::Context` (RTU or TCP) and decodes its
//!   reply with the same generated decoder.
#![cfg_attr(not(feature = "std"), no_std)]
#![cfg_attr(not(test), deny(clippy::unwrap_used, clippy::expect_used, clippy::panic, clippy::indexing_slicing))]

// The committed output of `cargo xtask codegen`; `cargo test` fails when it
// is stale (xtask's `every_generated_file_is_fresh`), naming that command.
include!("../generated/mod.rs");

/// The runtime the generated code is built on.
pub use yosemitech_rtu as rtu;

pub use yosemitech_rtu::{
    Ascii, Command, EncodeError, ExceptionCode, FieldInfo, FieldValue, Frame, FrameError, Function, Hex, Layout,
    Message, SensorInfo, Version,
};

#[cfg(feature = "std")]
pub use yosemitech_rtu::{
    Client, ClientConfig, Error, MemoryTransport, ResponderTransport, RetryPolicy, TcpTransport, Transport,
};

#[cfg(feature = "serial")]
pub use yosemitech_rtu::{SerialConfig, SerialTransport};

#[cfg(feature = "tokio")]
pub use yosemitech_rtu::{AsyncClient, AsyncLink, MbapLink, RtuStream};

#[cfg(feature = "std")]
pub mod procedures;

// The README's examples compile as doctests.
#[cfg(all(doctest, feature = "std"))]
#[doc = include_str!("../../../README.md")]
struct ReadmeDoctests;
