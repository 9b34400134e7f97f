//! The validated spec: what the generator, interpreter, simulator and CLI read.
//!
//! Every value here has passed [`crate::load_paths`]: names are valid
//! identifiers, fields fill the registers exactly, every example frame has
//! been replayed through the interpreter.

mod command;
mod derived;
mod example;
mod field;
mod manual;
mod sensor;

use std::path::PathBuf;

use serde::Serialize;
use yosemitech_rtu::LineSettings;

pub use self::command::{Calibrates, CommandErratum, CommandSpec};
pub use self::derived::{Derived, DerivedExample, DerivedInput, InputSource, NotComputable};
pub use self::example::{Citation, Example, ExampleErratum, PrintedFrame};
pub use self::field::{EnumRepr, Field, FieldExample, FieldKind, Flag, Variant};
pub use self::manual::{Figure, Manual, Provenance, SerialClaim, Source};

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

impl Procedure {
    /// The least time one run of the procedure takes: its warm-up and the
    /// spacing of its readings (the replies themselves take more).
    pub fn least_duration(&self) -> std::time::Duration {
        let spacing = u64::from(self.interval_ms) * u64::from(self.readings.max(1) - 1);
        std::time::Duration::from_millis(u64::from(self.warm_up_ms) + spacing)
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
