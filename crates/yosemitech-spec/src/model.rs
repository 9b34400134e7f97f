//! The validated spec: what the generator, interpreter, simulator and CLI read.
//!
//! Every value here has passed [`crate::load_paths`]: names are valid
//! identifiers, fields fill the registers exactly, every example frame has
//! been replayed through the interpreter.

use std::collections::BTreeMap;
use std::path::PathBuf;

use serde::Serialize;
use yosemitech_rtu::{ByteOrder2, ByteOrder4, Function, Layout, LineSettings};

/// All sensors of a spec directory.
#[derive(Debug, Clone, Serialize)]
pub struct Spec {
    /// Sensors, in file-name order.
    pub sensors: Vec<Sensor>,
    /// The fragments the sensors include, with their commands as the
    /// fragment defines them (before any sensor's `use` adds its own title,
    /// units and examples), in file-name order.
    pub fragments: Vec<Fragment>,
}

/// A file of commands several sensors share.
#[derive(Debug, Clone, Serialize)]
pub struct Fragment {
    /// snake_case identifier (the generated module's name), unique among fragments.
    pub name: String,
    /// What the commands have in common, one or more sentences (never empty).
    pub doc: String,
    /// The fragment's file, as given to the loader.
    pub file: PathBuf,
    /// Its commands, as defined there.
    pub commands: Vec<CommandSpec>,
}

impl Spec {
    /// The sensor called `name`.
    pub fn sensor(&self, name: &str) -> Option<&Sensor> {
        self.sensors.iter().find(|s| s.name == name)
    }

    /// Every file the spec was read from, included fragments once each.
    pub fn files(&self) -> Vec<PathBuf> {
        let mut files: Vec<PathBuf> = self.sensors.iter().flat_map(|s| s.files.iter().cloned()).collect();
        files.sort();
        files.dedup();
        files
    }
}

/// One sensor: one vendor manual.
#[derive(Debug, Clone, Serialize)]
pub struct Sensor {
    /// snake_case name (the Rust module).
    pub name: String,
    /// The probe's name as the manual's title gives it (one line, no control characters).
    pub title: String,
    /// What the probe measures, in prose (never empty).
    pub doc: String,
    /// The vendor's model name (`Y520`), when the spec states it.
    pub model: Option<String>,
    /// The two-digit model code of the serial number (`"09"` in `YL0914010022`).
    pub model_code: Option<String>,
    /// Other model codes the model's serial numbers have carried.
    pub also_model_codes: Vec<String>,
    /// Other models that answer with exactly these commands.
    pub aliases: Vec<ModelAlias>,
    /// The manual whose figure numbers the spec cites by default; `None`
    /// when no Modbus manual covers the model (see `provenance`).
    pub manual: Option<Manual>,
    /// Where the facts come from when no manual covers the model.
    pub provenance: Option<Provenance>,
    /// Other manuals of the same probe, in the order written.
    pub revisions: Vec<Revision>,
    /// Serial settings (of the newest firmware).
    #[serde(serialize_with = "ser_line")]
    pub serial: LineSettings,
    /// Lowest valid slave address.
    pub min_address: u8,
    /// Highest valid slave address.
    pub max_address: u8,
    /// Factory slave address, within `min_address..=max_address`.
    pub default_address: u8,
    /// Commands, in spec order (included ones where they are included).
    pub commands: Vec<CommandSpec>,
    /// The manual's measuring procedure.
    pub procedure: Option<Procedure>,
    /// Numbers the procedures use.
    pub constants: Vec<Constant>,
    /// Errata that concern the manual as a whole, not one command.
    pub errata: Vec<Erratum>,
    /// Quantities computed from the fields, constants and station inputs.
    pub derived: Vec<Derived>,
    /// The sensor's own file, as given to the loader.
    pub file: PathBuf,
    /// The sensor's file and every file it includes.
    pub files: Vec<PathBuf>,
}

impl Sensor {
    /// The command called `name`.
    pub fn command(&self, name: &str) -> Option<&CommandSpec> {
        self.commands.iter().find(|c| c.name == name)
    }

    /// The derived quantity called `name`.
    pub fn derived(&self, name: &str) -> Option<&Derived> {
        self.derived.iter().find(|d| d.name == name)
    }

    /// The constant called `name`.
    pub fn constant(&self, name: &str) -> Option<&Constant> {
        self.constants.iter().find(|c| c.name == name)
    }

    /// Every example frame of every command.
    pub fn example_count(&self) -> usize {
        self.commands.iter().map(|c| c.examples.len()).sum()
    }

    /// True for a measurement read: a read with a field that has a unit,
    /// whose registers no write command of the sensor covers (a trigger write
    /// of zero registers covers none) (so neither a
    /// setting nor a calibration block). The simulator varies these, `poll`
    /// and the station logger read them.
    pub fn is_measurement(&self, read: &CommandSpec) -> bool {
        is_measurement_among(&self.commands, read)
    }

    /// The measurement reads ([`Sensor::is_measurement`]), in spec order.
    pub fn measurement_reads(&self) -> impl Iterator<Item = &CommandSpec> {
        self.commands.iter().filter(|c| self.is_measurement(c))
    }

    /// The calibration-coefficient blocks, in spec order: each write of
    /// float fields only (not a trigger, not the slave address) paired with
    /// the read of exactly the same registers. What a coefficient backup
    /// saves and a restore writes back and reads back.
    pub fn coefficient_blocks(&self) -> Vec<(&CommandSpec, &CommandSpec)> {
        self.commands
            .iter()
            .filter(|w| !w.is_read() && !w.trigger && w.count > 0)
            .filter(|w| w.named_fields().all(|f| matches!(f.kind, FieldKind::F32 { .. })))
            .filter(|w| w.field("slave_address").is_none())
            .filter_map(|w| {
                self.commands
                    .iter()
                    .find(|r| r.is_read() && r.address == w.address && r.count == w.count)
                    .map(|r| (w, r))
            })
            .collect()
    }

    /// The user calibration blocks: each write with role `user_calibration`
    /// paired with the read of the same registers (validation guarantees
    /// the read), in spec order. Their fields are slope K, then offset B.
    pub fn user_calibrations(&self) -> Vec<(&CommandSpec, &CommandSpec)> {
        self.coefficient_blocks().into_iter().filter(|(w, _)| w.role == Some(Role::UserCalibration)).collect()
    }

    /// The named fields of the measurement reads among `commands` (see
    /// [`Sensor::is_measurement`]), in order.
    pub fn measured_fields(commands: &[CommandSpec]) -> Vec<&str> {
        commands
            .iter()
            .filter(|read| is_measurement_among(commands, read))
            .flat_map(|c| c.named_fields().map(Field::display_name))
            .collect()
    }

    /// The measurement read with a named field called `field`.
    pub fn measurement_with_field(&self, field: &str) -> Option<&CommandSpec> {
        self.measurement_reads().find(|c| c.named_fields().any(|f| f.display_name() == field))
    }

    /// The command with `role`, if the sensor has one.
    pub fn command_with_role(&self, role: Role) -> Option<&CommandSpec> {
        self.commands.iter().find(|c| c.role == Some(role))
    }

    /// Every manual of the probe: the file's `manual` first, then its revisions.
    pub fn manuals(&self) -> impl Iterator<Item = &Manual> {
        self.manual.iter().chain(self.revisions.iter().map(|r| &r.manual))
    }

    /// Every model code the sensor's own model carries, the main one first.
    pub fn model_codes(&self) -> impl Iterator<Item = &str> {
        self.model_code.iter().chain(&self.also_model_codes).map(String::as_str)
    }

    /// The models whose serial numbers carry `code`: the sensor's own model
    /// and its aliases (an alias without a code of its own shares the
    /// sensor's). Empty when the sensor declares no such code.
    pub fn models_with_code(&self, code: &str) -> Vec<&str> {
        let own = self.model_codes().any(|c| c == code);
        let mut models: Vec<&str> = Vec::new();
        if own {
            models.push(self.model.as_deref().unwrap_or(&self.name));
        }
        for alias in &self.aliases {
            let alias_code = alias.model_code.as_deref().or(self.model_code.as_deref());
            if alias_code == Some(code) {
                models.push(&alias.model);
            }
        }
        models
    }

    /// True when `code` names this sensor's model or one of its aliases.
    pub fn declares_model_code(&self, code: &str) -> bool {
        !self.models_with_code(code).is_empty()
    }

    /// True when `name` is the sensor's name, its model or one of its
    /// aliases' models (ignoring ASCII case).
    pub fn answers_to(&self, name: &str) -> bool {
        self.name.eq_ignore_ascii_case(name)
            || self.model.as_deref().is_some_and(|m| m.eq_ignore_ascii_case(name))
            || self.aliases.iter().any(|a| a.model.eq_ignore_ascii_case(name))
    }

    /// Where a command's facts come from when no manual states them: its
    /// own provenance, else the sensor's.
    pub fn provenance_of<'s>(&'s self, command: &'s CommandSpec) -> Option<&'s Provenance> {
        command.provenance.as_ref().or(self.provenance.as_ref())
    }

    /// The serial settings of a probe running `software` (the newest when unknown).
    pub fn serial_for(&self, software: &str) -> LineSettings {
        self.revisions.iter().find(|r| r.manual.software.as_deref() == Some(software)).map_or(self.serial, |r| r.serial)
    }

    /// The serial number the manual prints (the first example of the
    /// `serial_number` command), if any.
    pub fn example_serial_number(&self) -> Option<String> {
        let command = self.command_with_role(Role::SerialNumber)?;
        command.examples.iter().find_map(|e| match e.values.values().next() {
            Some(crate::Value::Text(t)) => Some(t.clone()),
            _ => None,
        })
    }
}

/// Another manual of the same probe, usually for other firmware.
#[derive(Debug, Clone, Serialize)]
pub struct Revision {
    /// The manual; its `software` is always set.
    pub manual: Manual,
    /// What changed against the sensor's `manual`.
    pub doc: Option<String>,
    /// Serial settings of this firmware (the sensor's when the manual states no others).
    #[serde(serialize_with = "ser_line")]
    pub serial: LineSettings,
}

/// [`Sensor::is_measurement`] for a sensor of `commands`.
fn is_measurement_among(commands: &[CommandSpec], read: &CommandSpec) -> bool {
    let end = |c: &CommandSpec| u32::from(c.address) + u32::from(c.count);
    read.is_read()
        && read.fields.iter().any(|f| f.unit.is_some())
        && !commands.iter().any(|w| {
            !w.is_read() && w.count > 0 && u32::from(w.address) < end(read) && u32::from(read.address) < end(w)
        })
}

/// What a command is for, where the simulator or the CLI must know. A sensor
/// has at most one command per role (but any number of `user_calibration`
/// blocks); validation checks each role's shape.
pub use crate::document::RoleDoc as Role;

impl Role {
    /// Every role, in the order the spec language documents them.
    pub const ALL: [Role; 10] = [
        Role::SetSlaveAddress,
        Role::GetSlaveAddress,
        Role::SerialNumber,
        Role::Version,
        Role::StartMeasurement,
        Role::StopMeasurement,
        Role::Wipe,
        Role::CalibrationPoint,
        Role::CalibrationStatus,
        Role::UserCalibration,
    ];

    /// The spec's name of the role.
    pub fn name(self) -> &'static str {
        match self {
            Role::SetSlaveAddress => "set_slave_address",
            Role::GetSlaveAddress => "get_slave_address",
            Role::SerialNumber => "serial_number",
            Role::Version => "version",
            Role::StartMeasurement => "start_measurement",
            Role::StopMeasurement => "stop_measurement",
            Role::Wipe => "wipe",
            Role::CalibrationPoint => "calibration_point",
            Role::CalibrationStatus => "calibration_status",
            Role::UserCalibration => "user_calibration",
        }
    }
}

/// The manual's measuring procedure. Every command it names exists;
/// `before` and `after` take no values; `read` are reads with fields.
#[derive(Debug, Clone, Serialize)]
pub struct Procedure {
    /// Where the manual describes it.
    pub source: Option<Source>,
    /// Where its steps and timings come from when no manual states them.
    pub provenance: Option<Provenance>,
    /// The procedure in the manual's words, when the spec transcribes them.
    pub doc: Option<String>,
    /// Commands sent first, in order.
    pub before: Vec<String>,
    /// Milliseconds to wait after `before`.
    pub warm_up_ms: u32,
    /// Reads that give the measurements.
    pub read: Vec<String>,
    /// Readings averaged (at least 1).
    pub readings: u32,
    /// Milliseconds between readings.
    pub interval_ms: u32,
    /// Commands sent at the end, in order.
    pub after: Vec<String>,
}

/// Where facts come from when no Modbus manual states them.
#[derive(Debug, Clone, Serialize, PartialEq, Eq)]
pub struct Provenance {
    /// Each source (a driver and its version, an issue), never empty.
    pub sources: Vec<String>,
    /// What the sources say and leave open.
    pub doc: Option<String>,
}

impl Provenance {
    /// `no manual: from A; B`, as `list`, the docs and the register maps show it.
    pub fn summary(&self) -> String {
        format!("no manual: from {}", self.sources.join("; "))
    }
}

/// Another model that answers with a sensor's commands.
#[derive(Debug, Clone, Serialize)]
pub struct ModelAlias {
    /// The vendor's model name.
    pub model: String,
    /// Its serial numbers' model code, when not the sensor's.
    pub model_code: Option<String>,
    /// What sets it apart.
    pub doc: Option<String>,
    /// Where the fact that it shares the commands comes from.
    pub provenance: Provenance,
}

/// The manual a sensor's spec transcribes.
#[derive(Debug, Clone, Serialize)]
pub struct Manual {
    /// The manual's title, one line, as printed on its cover.
    pub title: String,
    /// Revisions covered, as the manual's scope line states them.
    pub revision: String,
    /// The software revision it documents (`"1.7"`), when stated.
    pub software: Option<String>,
    /// The text extraction used.
    pub file: Option<String>,
    /// The serial settings the manual's builds state (claims, as printed;
    /// a client uses the sensor's or the revision's `serial`).
    pub serial_claims: Vec<SerialClaim>,
}

/// Serial settings a build of a manual states.
#[derive(Debug, Clone, Serialize)]
pub struct SerialClaim {
    /// The settings as printed.
    #[serde(serialize_with = "ser_line")]
    pub serial: LineSettings,
    /// The text extraction of the build, when not the manual's `file`.
    pub file: Option<String>,
    /// What is known about the build.
    pub doc: Option<String>,
}

/// Serializes line settings in the spec's own form,
/// `{"baud": 9600, "data_bits": 8, "parity": "none", "stop_bits": 1}`, as
/// the model's `serial` fields are serialized and the CLI's JSON shows them.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct LineSettingsJson(pub LineSettings);

impl Serialize for LineSettingsJson {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        use serde::ser::SerializeStruct;
        let Self(line) = self;
        let mut out = s.serialize_struct("LineSettings", 4)?;
        out.serialize_field("baud", &line.baud)?;
        out.serialize_field("data_bits", &line.format.data_bits.bits())?;
        out.serialize_field("parity", line.format.parity.name())?;
        out.serialize_field("stop_bits", &line.format.stop_bits.bits())?;
        out.end()
    }
}

fn ser_line<S: serde::Serializer>(line: &LineSettings, s: S) -> Result<S::Ok, S::Error> {
    LineSettingsJson(*line).serialize(s)
}

/// Where the manual documents something.
#[derive(Debug, Clone, Serialize, PartialEq, Eq, Default)]
pub struct Source {
    /// Section, e.g. "2.2.3".
    pub section: String,
    /// Figures and tables cited, in the order written; may be empty.
    pub figures: Vec<Figure>,
    /// The manual's software revision when not the sensor's `manual`.
    pub manual: Option<String>,
}

/// A figure or table of a manual.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Figure {
    /// Figure `number`; `occurrence` 2 for the second figure a manual gives that number.
    Figure {
        /// The number printed under the figure (1 or more).
        number: u32,
        /// 1, or 2 and more for a number the manual repeats.
        occurrence: u8,
    },
    /// Table `number`, as printed (1 or more).
    Table(u32),
}

impl Figure {
    /// Figure `number` (its first occurrence).
    pub const fn number(number: u32) -> Self {
        Figure::Figure { number, occurrence: 1 }
    }

    /// Parses the spec's form: `23`, `"T4"` (Table 4), `"43b"` (the second figure 43).
    pub fn parse(text: &str) -> Result<Self, String> {
        let t = text.trim();
        let bad = || {
            format!(
                "`{}` is not a figure: use a number (23), `T<n>` for a table, `<n>b` for a repeated number",
                crate::names::escape(t)
            )
        };
        if let Some(n) = t.strip_prefix('T').or_else(|| t.strip_prefix("Table ")) {
            return n.parse::<u32>().map(Figure::Table).map_err(|_| bad());
        }
        let digits = t.trim_end_matches(|c: char| c.is_ascii_lowercase());
        let suffix = &t[digits.len()..];
        let number = digits.parse::<u32>().map_err(|_| bad())?;
        let occurrence = match suffix {
            "" => 1,
            s if s.len() == 1 => s.as_bytes()[0] - b'a' + 1,
            _ => return Err(bad()),
        };
        Ok(Figure::Figure { number, occurrence })
    }
}

impl std::fmt::Display for Figure {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Figure::Figure { number, occurrence: 1 } => write!(f, "{number}"),
            Figure::Figure { number, occurrence } => {
                write!(f, "{number}{}", char::from(b'a' + occurrence.saturating_sub(1)))
            }
            Figure::Table(n) => write!(f, "T{n}"),
        }
    }
}

impl Serialize for Figure {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        match self {
            Figure::Figure { number, occurrence: 1 } => s.serialize_u32(*number),
            other => s.collect_str(other),
        }
    }
}

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

/// A manual-wide erratum.
#[derive(Debug, Clone, Serialize)]
pub struct Erratum {
    /// Identifier, unique within the sensor (`E1`, `Y514-4`).
    pub id: String,
    /// Figures the erratum concerns; may be empty.
    pub figures: Vec<Figure>,
    /// The manual's software revision when not the sensor's `manual`.
    pub manual: Option<String>,
    /// Manual sections the erratum concerns (`2.2.3`).
    pub sections: Vec<String>,
    /// Why the spec departs from the manual, in prose (never empty).
    pub note: String,
}

/// One field of register data.
#[derive(Debug, Clone, Serialize)]
pub struct Field {
    /// snake_case name; `None` only for reserved bytes.
    pub name: Option<String>,
    /// The field's type and wire encoding; its size is `kind.size()` bytes.
    pub kind: FieldKind,
    /// Byte offset in the register data.
    pub offset: usize,
    /// Unit of the value (`mS/cm`, `degC`) as the manual gives it; `None` for unitless values.
    pub unit: Option<String>,
    /// What the value means, in prose.
    pub doc: Option<String>,
    /// Values a write may send (inclusive); on a read, the measuring range.
    pub range: Option<(f64, f64)>,
    /// The value of natural water the simulator centres a reading on.
    pub typical: Option<f64>,
    /// The value read where a sub-probe is not fitted.
    pub absent: Option<f64>,
    /// Values with their bytes, printed outside a frame; each verified both ways.
    pub examples: Vec<FieldExample>,
}

/// A field's value and its bytes, as a manual prints them outside a frame.
#[derive(Debug, Clone, Serialize)]
pub struct FieldExample {
    /// The bytes as printed, `field.size()` of them.
    pub bytes: Vec<u8>,
    /// The value they decode to.
    pub value: crate::Value,
    /// Where the manual prints it.
    pub figures: Vec<Figure>,
}

/// A named bit of a flags field.
#[derive(Debug, Clone, Serialize, PartialEq, Eq)]
pub struct Flag {
    /// snake_case identifier, unique within the field.
    pub name: String,
    /// The mask: exactly one bit set, within the field's size.
    pub mask: u16,
    /// What the bit means when set.
    pub doc: Option<String>,
}

impl Field {
    /// Bytes on the wire: `kind.size()`.
    pub fn size(&self) -> usize {
        self.kind.size()
    }

    /// True for reserved bytes.
    pub fn is_reserved(&self) -> bool {
        matches!(self.kind, FieldKind::Reserved { .. })
    }

    /// The field's name, or `reserved`.
    pub fn display_name(&self) -> &str {
        self.name.as_deref().unwrap_or("reserved")
    }
}

fn ser_order2<S: serde::Serializer>(o: &ByteOrder2, s: S) -> Result<S::Ok, S::Error> {
    s.serialize_str(o.name())
}

fn ser_order4<S: serde::Serializer>(o: &ByteOrder4, s: S) -> Result<S::Ok, S::Error> {
    s.serialize_str(o.name())
}

/// The size of an enum code.
#[derive(Debug, Clone, Copy, Serialize, PartialEq, Eq)]
#[serde(rename_all = "snake_case")]
pub enum EnumRepr {
    /// One byte, no byte order.
    U8,
    /// Two bytes in the given order.
    U16(#[serde(serialize_with = "ser_order2")] ByteOrder2),
}

/// A named enum code: a value the field may carry, with its meaning.
#[derive(Debug, Clone, Serialize, PartialEq, Eq)]
pub struct Variant {
    /// snake_case identifier, unique within the field, also as a Rust name.
    pub name: String,
    /// The code on the wire; fits the enum's size (0..=255 for one byte).
    pub value: u16,
    /// What the code means.
    pub doc: Option<String>,
}

/// Type and encoding of a field.
#[derive(Debug, Clone, Serialize, PartialEq)]
#[serde(rename_all = "snake_case", tag = "type")]
pub enum FieldKind {
    /// IEEE 754 single, 4 bytes, decoded bit for bit (NaN payloads kept).
    F32 {
        /// The order of its 4 bytes on the wire.
        #[serde(serialize_with = "ser_order4")]
        order: ByteOrder4,
    },
    /// Unsigned byte.
    U8,
    /// Signed byte (two's complement).
    I8,
    /// Unsigned 16-bit integer, 2 bytes.
    U16 {
        /// The order of its 2 bytes on the wire.
        #[serde(serialize_with = "ser_order2")]
        order: ByteOrder2,
    },
    /// Signed 16-bit integer, 2 bytes (two's complement).
    I16 {
        /// The order of its 2 bytes on the wire.
        #[serde(serialize_with = "ser_order2")]
        order: ByteOrder2,
    },
    /// Unsigned 32-bit integer, 4 bytes.
    U32 {
        /// The order of its 4 bytes on the wire.
        #[serde(serialize_with = "ser_order4")]
        order: ByteOrder4,
    },
    /// Signed 32-bit integer, 4 bytes (two's complement).
    I32 {
        /// The order of its 4 bytes on the wire.
        #[serde(serialize_with = "ser_order4")]
        order: ByteOrder4,
    },
    /// Fixed-length text: `len` bytes, printable ASCII, padded at the end.
    Ascii {
        /// Bytes on the wire, padding included (1 or more).
        len: usize,
        /// The byte that fills the text to `len` (0x00 or a space).
        padding: u8,
    },
    /// Major, minor.
    Version,
    /// Named codes: an enum of one or two bytes; unknown codes decode as raw values.
    Enum {
        /// The size of the code, and its byte order when two bytes.
        repr: EnumRepr,
        /// The codes the manual names, unique by value and by name.
        variants: Vec<Variant>,
    },
    /// Bytes the device sends and ignores; written as `fill`.
    Reserved {
        /// Bytes on the wire (1 or more).
        len: usize,
        /// The byte an encoder writes in each reserved byte.
        fill: u8,
    },
    /// One byte, two decimal digits.
    Bcd,
    /// Independent named bits of one or two bytes; unnamed bits are kept as read.
    Flags {
        /// Size and order of the bit field.
        repr: EnumRepr,
        /// The named bits: each mask has exactly one bit, unique within the field.
        flags: Vec<Flag>,
    },
}

impl FieldKind {
    /// Bytes on the wire: 1, 2, 4, or a text's or reserved run's length.
    pub fn size(&self) -> usize {
        match self {
            Self::U8 | Self::I8 | Self::Bcd => 1,
            Self::Flags { repr: EnumRepr::U8, .. } => 1,
            Self::Flags { repr: EnumRepr::U16(_), .. } => 2,
            Self::U16 { .. } | Self::I16 { .. } | Self::Version => 2,
            Self::F32 { .. } | Self::U32 { .. } | Self::I32 { .. } => 4,
            Self::Ascii { len, .. } | Self::Reserved { len, .. } => *len,
            Self::Enum { repr: EnumRepr::U8, .. } => 1,
            Self::Enum { repr: EnumRepr::U16(_), .. } => 2,
        }
    }

    /// The spec's name (`dcba`, `ab`) of the byte order of a multi-byte
    /// number, enum or flags field; `None` for a field of one byte, text, a
    /// version or reserved bytes, which have no byte order.
    pub fn byte_order_name(&self) -> Option<&'static str> {
        match self {
            Self::F32 { order } | Self::U32 { order } | Self::I32 { order } => Some(order.name()),
            Self::U16 { order }
            | Self::I16 { order }
            | Self::Enum { repr: EnumRepr::U16(order), .. }
            | Self::Flags { repr: EnumRepr::U16(order), .. } => Some(order.name()),
            _ => None,
        }
    }

    /// The spec's name of the type.
    pub fn type_name(&self) -> &'static str {
        match self {
            Self::F32 { .. } => "f32",
            Self::U8 => "u8",
            Self::I8 => "i8",
            Self::U16 { .. } => "u16",
            Self::I16 { .. } => "i16",
            Self::U32 { .. } => "u32",
            Self::I32 { .. } => "i32",
            Self::Ascii { .. } => "ascii",
            Self::Version => "version",
            Self::Enum { .. } => "enum",
            Self::Reserved { .. } => "reserved",
            Self::Bcd => "bcd",
            Self::Flags { .. } => "flags",
        }
    }
}

/// A frame as a manual prints it.
#[derive(Debug, Clone, Serialize, PartialEq, Eq)]
pub struct PrintedFrame {
    /// The bytes printed, CRC included when printed; `None` for a placeholder
    /// ("Value", "Time") the manual prints instead of a byte.
    pub bytes: Vec<Option<u8>>,
    /// The manual prints bytes of unknown number after `bytes` ("meaningless").
    pub open_ended: bool,
    /// Whether the manual prints the CRC.
    pub crc_printed: bool,
    /// The whole frame, CRC included (computed when not printed), when every
    /// byte is known; validation checked the printed CRC against it.
    pub complete: Option<Vec<u8>>,
}

impl PrintedFrame {
    /// True when every byte is known (the CRC may still be computed).
    pub fn is_complete(&self) -> bool {
        self.complete.is_some()
    }

    /// The byte at `at`, when printed.
    pub fn byte(&self, at: usize) -> Option<u8> {
        self.bytes.get(at).copied().flatten()
    }
}

/// A frame pair (or one side of it) printed in the manual.
#[derive(Debug, Clone, Serialize)]
pub struct Example {
    /// Figures and tables that print the frame.
    pub figures: Vec<Figure>,
    /// The manual's software revision when not the sensor's `manual`.
    pub manual: Option<String>,
    /// The request as printed; `None` when the manual prints none.
    pub request: Option<PrintedFrame>,
    /// The reply as printed; `None` when the manual prints none.
    pub response: Option<PrintedFrame>,
    /// Values the manual states, by field name.
    pub values: BTreeMap<String, crate::Value>,
    /// Remarks on the example, in prose.
    pub doc: Option<String>,
    /// Where the printed frame is wrong.
    pub erratum: Option<ExampleErratum>,
    /// Other manuals that print the same frames, with their figures.
    pub also_in: Vec<Citation>,
}

/// Another manual's figures that print an example's frames byte for byte.
#[derive(Debug, Clone, Serialize, PartialEq, Eq)]
pub struct Citation {
    /// The manual's software revision.
    pub manual: String,
    /// Its figures and tables.
    pub figures: Vec<Figure>,
}

impl Example {
    /// The true request, complete with its CRC: the correction if the
    /// printed one is wrong; `None` when not every byte is known.
    pub fn true_request(&self) -> Option<&[u8]> {
        self.erratum
            .as_ref()
            .and_then(|e| e.corrected_request.as_deref())
            .or_else(|| self.request.as_ref()?.complete.as_deref())
    }

    /// The true reply, complete with its CRC: the correction if the printed
    /// one is wrong; `None` when not every byte is known.
    pub fn true_response(&self) -> Option<&[u8]> {
        self.erratum
            .as_ref()
            .and_then(|e| e.corrected_response.as_deref())
            .or_else(|| self.response.as_ref()?.complete.as_deref())
    }

    /// Both true frames, when both are complete: what a golden test replays.
    pub fn true_pair(&self) -> Option<(&[u8], &[u8])> {
        Some((self.true_request()?, self.true_response()?))
    }

    /// The slave address the request is sent to (from the reply when no
    /// request is printed).
    pub fn slave(&self) -> u8 {
        let from = |f: &Option<PrintedFrame>| f.as_ref().and_then(|f| f.byte(0));
        self.true_request()
            .and_then(|r| r.first().copied())
            .or_else(|| from(&self.request))
            .or_else(|| from(&self.response))
            .unwrap_or(0)
    }

    /// Frames printed in this example (one or two).
    pub fn frames_printed(&self) -> usize {
        usize::from(self.request.is_some()) + usize::from(self.response.is_some())
    }

    /// Printed frames whose every byte and CRC the manual gives.
    pub fn frames_printed_complete(&self) -> usize {
        [&self.request, &self.response]
            .into_iter()
            .flatten()
            .filter(|f| f.crc_printed && f.complete.as_deref().is_some_and(yosemitech_rtu::crc_ok))
            .count()
    }
}

/// A printed frame that is wrong.
#[derive(Debug, Clone, Serialize)]
pub struct ExampleErratum {
    /// Identifier, unique within the sensor.
    pub id: String,
    /// The figure that prints the wrong frame.
    pub figure: Figure,
    /// What is wrong with the printed frame, in prose.
    pub printed: String,
    /// The true request with its CRC, when the printed one is wrong.
    pub corrected_request: Option<Vec<u8>>,
    /// The true reply with its CRC, when the printed one is wrong.
    pub corrected_response: Option<Vec<u8>>,
    /// Whether our decoder accepts the printed frame.
    pub printed_decodes: bool,
}

/// A number a procedure uses.
#[derive(Debug, Clone, Serialize)]
pub struct Constant {
    /// snake_case identifier, unique within the sensor.
    pub name: String,
    /// The Rust type the generated constant has.
    pub ty: ConstantType,
    /// The values; one for a scalar.
    pub values: Vec<f64>,
    /// True when declared with `values:` (an array).
    pub is_list: bool,
    /// Unit of the values, when they have one.
    pub unit: Option<String>,
    /// What the constant is for, in prose (never empty).
    pub doc: String,
    /// Where the manual states the number, when it does.
    pub source: Option<Source>,
}

/// Rust type of a constant.
#[derive(Debug, Clone, Copy, Serialize, PartialEq, Eq)]
#[serde(rename_all = "snake_case")]
pub enum ConstantType {
    /// f32.
    F32,
    /// u8.
    U8,
    /// u16.
    U16,
    /// u32.
    U32,
}

/// A quantity the probe does not send, computed by a formula from fields of
/// its reads, the sensor's constants and station inputs. Validation
/// guarantees that every name of the formula resolves, that its units agree
/// (where declared) and that every example holds.
#[derive(Debug, Clone, Serialize)]
pub struct Derived {
    /// snake_case identifier: the generated function.
    pub name: String,
    /// Human title (one line).
    pub title: String,
    /// The result's unit, when declared.
    pub unit: Option<String>,
    /// What the quantity is, in prose (never empty).
    pub doc: String,
    /// Where the manual gives the formula.
    pub source: Option<Source>,
    /// The inputs, in parameter order.
    pub inputs: Vec<DerivedInput>,
    /// The formula as written.
    pub expr: String,
    /// The formula, names resolved to inputs and constants.
    #[serde(skip)]
    pub formula: crate::expr::Expr,
    /// Values computed independently, each with its source.
    pub examples: Vec<DerivedExample>,
}

/// Where a derived quantity's input comes from.
#[derive(Debug, Clone, Serialize, PartialEq, Eq)]
#[serde(rename_all = "snake_case")]
pub enum InputSource {
    /// A field of a read of the sensor.
    Field {
        /// The read.
        command: String,
        /// Its field (a number).
        field: String,
    },
    /// A value of the station (salinity, barometric pressure).
    Station(String),
}

/// One input of a derived quantity.
#[derive(Debug, Clone, Serialize)]
pub struct DerivedInput {
    /// snake_case identifier, unique within the quantity.
    pub name: String,
    /// Where the value comes from.
    pub source: InputSource,
    /// Its unit (a field input's is its field's).
    pub unit: Option<String>,
    /// The value taken when a station gives none.
    pub default: Option<f64>,
    /// The values the formula takes, inclusive.
    pub range: Option<(f64, f64)>,
}

/// A value of a derived quantity from another source than its formula.
#[derive(Debug, Clone, Serialize)]
pub struct DerivedExample {
    /// The inputs given, by name (the others take their default).
    pub inputs: BTreeMap<String, f64>,
    /// The value.
    pub value: f64,
    /// How far the formula's value may be from it.
    pub tolerance: f64,
    /// Where the value comes from.
    pub doc: String,
}

impl Derived {
    /// The input called `name`.
    pub fn input(&self, name: &str) -> Option<&DerivedInput> {
        self.inputs.iter().find(|i| i.name == name)
    }

    /// The inputs of `example` in parameter order, station inputs it does
    /// not give at their default; `None` names the input that has none.
    pub fn example_inputs(&self, example: &DerivedExample) -> Result<Vec<f32>, String> {
        self.inputs
            .iter()
            .map(|i| example.inputs.get(&i.name).copied().or(i.default).map(|v| v as f32).ok_or_else(|| i.name.clone()))
            .collect()
    }

    /// The formula's value for `inputs` (in parameter order), as the
    /// generated function computes it: inputs checked (finite, in range),
    /// arithmetic in `f64`, the result an `f32` that must be finite.
    pub fn compute(&self, inputs: &[f32]) -> Result<f32, NotComputable> {
        if inputs.len() != self.inputs.len() {
            return Err(NotComputable::Inputs { expected: self.inputs.len(), given: inputs.len() });
        }
        let mut wide = Vec::with_capacity(inputs.len());
        for (decl, &v) in self.inputs.iter().zip(inputs) {
            if !v.is_finite() {
                return Err(NotComputable::NotFinite { input: decl.name.clone() });
            }
            let w = f64::from(v);
            if let Some((min, max)) = decl.range
                && !(min..=max).contains(&w)
            {
                return Err(NotComputable::OutOfRange { input: decl.name.clone(), value: v, min, max });
            }
            wide.push(w);
        }
        let value = self.formula.eval(&wide).ok_or(NotComputable::Undefined)?;
        let narrow = value as f32;
        if narrow.is_finite() { Ok(narrow) } else { Err(NotComputable::Undefined) }
    }
}

/// Why the interpreter has no value for a derived quantity: the same cases
/// as the runtime's `NotComputable`, with owned names.
#[derive(Debug, Clone, PartialEq)]
pub enum NotComputable {
    /// An input is NaN or infinite.
    NotFinite {
        /// The input.
        input: String,
    },
    /// An input lies outside its declared range.
    OutOfRange {
        /// The input.
        input: String,
        /// The value given.
        value: f32,
        /// Lowest value taken.
        min: f64,
        /// Highest value taken.
        max: f64,
    },
    /// The formula has no finite value for these inputs.
    Undefined,
    /// The wrong number of inputs.
    Inputs {
        /// How many the quantity takes.
        expected: usize,
        /// How many were given.
        given: usize,
    },
}

impl NotComputable {
    /// True when the runtime's error is the same case, for the same input.
    pub fn same_as(&self, other: &yosemitech_rtu::NotComputable) -> bool {
        use yosemitech_rtu::NotComputable as R;
        match (self, other) {
            (Self::NotFinite { input }, R::NotFinite { input: i }) => input == i,
            (Self::OutOfRange { input, .. }, R::OutOfRange { input: i, .. }) => input == i,
            (Self::Undefined, R::Undefined) => true,
            (Self::Inputs { expected, given }, R::Inputs { expected: e, given: g }) => expected == e && given == g,
            _ => false,
        }
    }
}

impl std::fmt::Display for NotComputable {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::NotFinite { input } => write!(f, "input `{input}` is not a finite number"),
            Self::OutOfRange { input, value, min, max } => {
                write!(f, "input `{input}` is {value}, outside {min}..={max}")
            }
            Self::Undefined => f.write_str("the formula has no finite value for these inputs"),
            Self::Inputs { expected, given } => write!(f, "{given} inputs given, {expected} expected"),
        }
    }
}

impl std::error::Error for NotComputable {}
