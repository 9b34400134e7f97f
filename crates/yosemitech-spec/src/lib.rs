//! The YAML spec language for Yosemitech Modbus sensors.
//!
//! A spec file transcribes one vendor manual: every command's function,
//! register address and count, its fields with types, byte orders and units,
//! the frames the manual prints, and the manual's errata. This crate loads
//! spec files with source positions ([`load_paths`]), validates them
//! (every problem at once, rustc-style, see [`Diagnostics`]), and interprets
//! them ([`interp`]): the same walk encodes requests and decodes replies for
//! the validator, the simulator and the CLI.
//!
//! Other YAML a tool reads (`cargo xtask import`'s drafts) goes through
//! the same reader, with the same limits and messages: [`from_yaml_str`].
//!
//! Validation checks, among others: unique names (sensors, commands, fields,
//! variants, constants), also once converted to Rust; names that are
//! snake_case identifiers and not keywords; register counts within Modbus
//! limits (reads 1..=125, writes 1..=123, zero only for a `trigger`); fields
//! that fill the registers exactly; every example frame's CRC (unless an
//! erratum corrects it), its request encoded from the spec and its reply
//! decoded to the stated values; includes that exist, are fragments and do
//! not cycle; and text without control or bidi-override characters. Hostile
//! input is bounded: files over [`sources::MAX_FILE_BYTES`], YAML with more
//! than [`MAX_YAML_NODES`] values, deeper than [`MAX_YAML_DEPTH`] levels or
//! with aliases replaying more than [`MAX_ALIAS_REPLAY`] events are refused.
//!
//! ```
//! let spec = yosemitech_spec::load_paths(&[concat!(env!("CARGO_MANIFEST_DIR"), "/../../spec").into()])?;
//! // A read's reply as a manual prints it, decoded by the interpreter: one value per named field.
//! let (read, reply) = (spec.sensors.iter().flat_map(|s| &s.commands))
//!     .filter(|c| c.is_read())
//!     .find_map(|c| Some((c, c.examples.iter().find_map(|e| e.true_response())?)))
//!     .expect("the spec prints a read's reply");
//! let values = read.decode_response(reply[0], reply)?;
//! assert_eq!(values.len(), read.named_fields().count());
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
#![cfg_attr(not(test), deny(clippy::unwrap_used, clippy::expect_used, clippy::panic))]

pub mod beside;
mod check;
mod diag;
pub mod document;
mod examples;
pub mod expr;
pub mod interp;
pub mod lookup;
pub mod model;
pub mod names;
mod resolve;
pub mod sources;
mod spanned;
pub mod suggest;
pub mod units;
mod yaml;

pub use diag::{Diagnostic, Diagnostics, Pos};
pub use interp::{SerialNumberReply, Value, Values};
pub use model::*;
pub use resolve::{
    IMPORT_TODO, MAX_INCLUDE_DEPTH, MAX_READ_COUNT, MAX_TEXT_LEN, MAX_WRITE_COUNT, Summary, load_paths, load_with,
    parse_hex,
};
pub use spanned::Spanned;
pub use yaml::{MAX_ALIAS_REPLAY, MAX_YAML_ALIASES, MAX_YAML_DEPTH, MAX_YAML_NODES, YamlError, from_yaml_str};

/// The JSON Schema of a spec file, for editors (feature `schema`: the build
/// scripts that generate code do not need it).
#[cfg(feature = "schema")]
pub fn json_schema() -> serde_json::Value {
    serde_json::to_value(schemars::schema_for!(document::SpecFile)).unwrap_or_default()
}
