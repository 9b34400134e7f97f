//! A command: its wire layout, its fields, and where the manual's table is
//! wrong about it.

use serde::Serialize;
use yosemitech_rtu::{Function, Layout};

use super::{Example, Field, Figure, Provenance, Role, Source};

/// One command of a sensor: its wire layout, fields and the manual's frames. Validation guarantees: `count` fits Modbus limits (reads 1..=125, writes 1..=123, zero only for a trigger), fields fill `2 * count` bytes without gap or overlap, and every complete example replays through the interpreter.
#[derive(Debug, Clone, Serialize)]
pub struct CommandSpec {
    /// snake_case identifier, unique within the sensor and not a Rust keyword.
    pub name: String,
    /// The command's title as the manual's table prints it (one line).
    pub title: String,
    /// What the command does, in prose (never empty).
    pub doc: String,
    /// Where this sensor's manual documents it.
    pub source: Source,
    /// Where its facts come from when no manual states them (the sensor's
    /// `provenance` covers every command of a sensor without a manual).
    pub provenance: Option<Provenance>,
    /// `Read` (0x03) or `Write` (0x10): the only functions Yosemitech probes use.
    #[serde(serialize_with = "ser_function")]
    pub function: Function,
    /// First register on the wire.
    pub address: u16,
    /// Registers read or written: 1..=125 for reads, 1..=123 for writes, 0 only for a trigger write.
    pub count: u16,
    /// A command that carries no value: a write of zero registers, or a
    /// read whose reply is ignored (such a read has no fields).
    pub trigger: bool,
    /// The software revision that introduced it; `None`: every revision.
    pub since: Option<String>,
    /// What it is for, where the simulator or the CLI must know.
    pub role: Option<Role>,
    /// Slave address forced on request and reply.
    pub fixed_slave: Option<u8>,
    /// Extra byte counts a read reply may carry.
    pub extra_byte_counts: Vec<u8>,
    /// Register data fields in wire order (reply of a read, request of a write).
    pub fields: Vec<Field>,
    /// Frames printed in the manual.
    pub examples: Vec<Example>,
    /// Where the manual's register table contradicts the spec, each with the value the table prints.
    pub errata: Vec<CommandErratum>,
    /// The fragment this command was included from.
    pub shared_from: Option<String>,
    /// Of a user calibration block: what it calibrates, where the manual says it.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub calibrates: Option<Calibrates>,
}

/// What a user calibration block calibrates. Validation guarantees that
/// `field` is a named field of one of the sensor's measurement reads.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Calibrates {
    /// The measured field K and B apply to.
    pub field: String,
    /// The standards the manual recommends, in the field's unit (may be empty).
    pub standards: Vec<f64>,
    /// Milliseconds to let the probe settle in each standard.
    pub settle_ms: Option<u32>,
}

fn ser_function<S: serde::Serializer>(f: &Function, s: S) -> Result<S::Ok, S::Error> {
    s.serialize_str(match f {
        Function::Read => "read",
        Function::Write => "write",
    })
}

impl CommandSpec {
    /// The wire layout, for framing.
    pub fn layout(&self) -> Layout<'_> {
        Layout {
            function: self.function,
            address: self.address,
            count: self.count,
            fixed_slave: self.fixed_slave,
            extra_byte_counts: &self.extra_byte_counts,
            trigger: self.trigger,
        }
    }

    /// True for a command that sends no values: reads and trigger writes.
    pub fn takes_no_values(&self) -> bool {
        self.is_read() || self.fields.is_empty()
    }

    /// True for reads (function 0x03).
    pub fn is_read(&self) -> bool {
        self.function == Function::Read
    }

    /// Named (non-reserved) fields.
    pub fn named_fields(&self) -> impl Iterator<Item = &Field> {
        self.fields.iter().filter(|f| !f.is_reserved())
    }

    /// The field called `name`.
    pub fn field(&self, name: &str) -> Option<&Field> {
        self.fields.iter().find(|f| f.name.as_deref() == Some(name))
    }
}

/// A table contradiction for one command.
#[derive(Debug, Clone, Serialize)]
pub struct CommandErratum {
    /// Identifier (E1, …).
    pub id: String,
    /// The figure or table with the wrong table; `None` for a table the manual does not number.
    pub figure: Option<Figure>,
    /// The manual's software revision when not the sensor's `manual`.
    pub manual: Option<String>,
    /// The start address the table prints, if wrong.
    pub table_address: Option<u16>,
    /// The register count the table prints, if wrong.
    pub table_count: Option<u16>,
    /// The function the table prints, if wrong.
    #[serde(serialize_with = "ser_opt_function")]
    pub table_function: Option<Function>,
    /// Why the spec's value is the truth.
    pub note: String,
}

fn ser_opt_function<S: serde::Serializer>(f: &Option<Function>, s: S) -> Result<S::Ok, S::Error> {
    match f {
        Some(f) => ser_function(f, s),
        None => s.serialize_none(),
    }
}

impl CommandErratum {
    /// What the table prints, e.g. `["address 0x1100"]`.
    pub fn table_says(&self) -> Vec<String> {
        let mut said = Vec::new();
        if let Some(a) = self.table_address {
            said.push(format!("address 0x{a:04X}"));
        }
        if let Some(n) = self.table_count {
            said.push(format!("count {n}"));
        }
        if let Some(f) = self.table_function {
            said.push(format!("function 0x{:02X}", f.code()));
        }
        said
    }
}
