//! The YAML shape of a spec file, exactly as written, with source positions.
//!
//! Nothing here is validated beyond YAML types: [`crate::load_paths`] turns these
//! documents into the checked [`crate::model`]. Positions are kept with
//! `Spanned` on every value a semantic error may point at; the model avoids
//! `untagged` and `flatten`, which would lose them.

use std::collections::BTreeMap;

use serde::Deserialize;
use serde_saphyr::Spanned;
use yosemitech_rtu::{ByteOrder2, ByteOrder4, Parity};

/// One spec file: a sensor (one vendor manual) or a fragment of shared commands.
#[derive(Debug, Deserialize)]
#[cfg_attr(feature = "serialize", derive(serde::Serialize))]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[serde(deny_unknown_fields)]
#[cfg_attr(feature = "schema", schemars(title = "Yosemitech Modbus sensor spec"))]
#[cfg_attr(feature = "schema", schemars(extend("oneOf" = [{"required": ["sensor"]}, {"required": ["fragment"]}])))]
pub struct SpecFile {
    /// The sensor this file describes. A file has `sensor` or `fragment`, not both.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub sensor: Option<SensorDoc>,
    /// A file of commands shared by several sensors, included by sensor files.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub fragment: Option<FragmentDoc>,
    /// Fragment files whose commands this file includes, relative to this
    /// file: a file name (every command), or `{file, only: [names]}`.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    #[cfg_attr(feature = "schema", schemars(with = "Vec<IncludeSchema>"))]
    pub include: Vec<Spanned<IncludeDoc>>,
    /// The commands: full definitions, or `use:` entries that add this
    /// manual's source and examples to an included command.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub commands: Vec<CommandDoc>,
    /// The manual's measuring procedure, as data.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub procedure: Option<ProcedureDoc>,
    /// Numbers the manual's procedures use.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub constants: Vec<ConstantDoc>,
    /// Contradictions in the manual that no single command or frame carries.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub errata: Vec<ErratumDoc>,
    /// Measurements the probe does not send, computed from its fields, the
    /// constants and per-station inputs.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub derived: Vec<DerivedDoc>,
}

/// The sensor a manual describes.
#[derive(Debug, Deserialize)]
#[cfg_attr(feature = "serialize", derive(serde::Serialize))]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[serde(deny_unknown_fields)]
pub struct SensorDoc {
    /// snake_case name; becomes the Rust module name.
    #[cfg_attr(feature = "schema", schemars(with = "String"))]
    pub name: Spanned<String>,
    /// Human title.
    #[cfg_attr(feature = "schema", schemars(with = "String"))]
    pub title: Spanned<String>,
    /// What the sensor measures.
    #[cfg_attr(feature = "schema", schemars(with = "String"))]
    pub doc: Spanned<String>,
    /// The vendor's model name, like `Y520`.
    #[cfg_attr(feature = "schema", schemars(with = "Option<String>"))]
    #[serde(skip_serializing_if = "Option::is_none")]
    pub model: Option<Spanned<String>>,
    /// The two-digit model code of the serial number (`"09"` in `YL0914010022`).
    #[cfg_attr(feature = "schema", schemars(with = "Option<String>"))]
    #[serde(skip_serializing_if = "Option::is_none")]
    pub model_code: Option<Spanned<String>>,
    /// Other model codes this model's serial numbers have carried (over the years).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    #[cfg_attr(feature = "schema", schemars(with = "Vec<String>"))]
    pub also_model_codes: Vec<Spanned<String>>,
    /// Other models that answer with exactly these commands.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub aliases: Vec<AliasDoc>,
    /// The manual whose figure numbers this file cites by default; absent
    /// for a sensor whose facts come from other sources (`provenance`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub manual: Option<ManualDoc>,
    /// Where the facts come from when no Modbus manual covers the model.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub provenance: Option<ProvenanceDoc>,
    /// Other manuals (older or newer firmware) of the same probe.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub revisions: Vec<RevisionDoc>,
    /// Serial line settings (of the newest firmware).
    pub serial: SerialDoc,
    /// Valid slave addresses.
    pub addresses: AddressRangeDoc,
    /// The factory slave address.
    #[cfg_attr(feature = "schema", schemars(with = "u32"))]
    pub default_address: Spanned<u32>,
}

/// Where facts come from when no Modbus manual states them: the field's
/// drivers, loggers and issue trackers.
#[derive(Debug, Deserialize)]
#[cfg_attr(feature = "serialize", derive(serde::Serialize))]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[serde(deny_unknown_fields)]
pub struct ProvenanceDoc {
    /// Each source, as a reader can find it (a driver and version, an issue).
    #[cfg_attr(feature = "schema", schemars(with = "Vec<String>"))]
    pub sources: Vec<Spanned<String>>,
    /// What the sources say and do not say.
    #[cfg_attr(feature = "schema", schemars(with = "Option<String>"))]
    #[serde(skip_serializing_if = "Option::is_none")]
    pub doc: Option<Spanned<String>>,
}

/// Another model that answers with the sensor's commands.
#[derive(Debug, Deserialize)]
#[cfg_attr(feature = "serialize", derive(serde::Serialize))]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[serde(deny_unknown_fields)]
pub struct AliasDoc {
    /// The vendor's model name, like `Y521`.
    #[cfg_attr(feature = "schema", schemars(with = "String"))]
    pub model: Spanned<String>,
    /// Its serial numbers' model code, when it differs from the sensor's.
    #[cfg_attr(feature = "schema", schemars(with = "Option<String>"))]
    #[serde(skip_serializing_if = "Option::is_none")]
    pub model_code: Option<Spanned<String>>,
    /// What sets it apart from the sensor's model.
    #[cfg_attr(feature = "schema", schemars(with = "Option<String>"))]
    #[serde(skip_serializing_if = "Option::is_none")]
    pub doc: Option<Spanned<String>>,
    /// Where the fact that it shares the commands comes from.
    pub provenance: ProvenanceDoc,
}

/// The manual a spec transcribes.
#[derive(Debug, Deserialize)]
#[cfg_attr(feature = "serialize", derive(serde::Serialize))]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[serde(deny_unknown_fields)]
pub struct ManualDoc {
    /// The manual's title.
    #[cfg_attr(feature = "schema", schemars(with = "String"))]
    pub title: Spanned<String>,
    /// Hardware and software revisions the manual covers.
    #[cfg_attr(feature = "schema", schemars(with = "String"))]
    pub revision: Spanned<String>,
    /// The software revision the manual documents, like `"1.7"`.
    #[cfg_attr(feature = "schema", schemars(with = "Option<String>"))]
    #[serde(skip_serializing_if = "Option::is_none")]
    pub software: Option<Spanned<String>>,
    /// The text extraction the spec was written from.
    #[cfg_attr(feature = "schema", schemars(with = "Option<String>"))]
    #[serde(skip_serializing_if = "Option::is_none")]
    pub file: Option<Spanned<String>>,
    /// The serial settings this manual (each build of it) states: a claim,
    /// recorded as printed. A client uses the sensor's (or the revision's)
    /// `serial`, not these; two builds of one revision that disagree are two
    /// claims.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub serial_claims: Vec<SerialClaimDoc>,
}

/// Serial settings a manual states.
#[derive(Debug, Deserialize)]
#[cfg_attr(feature = "serialize", derive(serde::Serialize))]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[serde(deny_unknown_fields)]
pub struct SerialClaimDoc {
    /// The settings as the manual prints them.
    pub serial: SerialDoc,
    /// The text extraction of the build that states them, when not the manual's `file`.
    #[cfg_attr(feature = "schema", schemars(with = "Option<String>"))]
    #[serde(skip_serializing_if = "Option::is_none")]
    pub file: Option<Spanned<String>>,
    /// What is known about this build (its date, where it came from).
    #[cfg_attr(feature = "schema", schemars(with = "Option<String>"))]
    #[serde(skip_serializing_if = "Option::is_none")]
    pub doc: Option<Spanned<String>>,
}

/// Another manual of the same probe.
#[derive(Debug, Deserialize)]
#[cfg_attr(feature = "serialize", derive(serde::Serialize))]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[serde(deny_unknown_fields)]
pub struct RevisionDoc {
    /// The manual; `software` is required here.
    pub manual: ManualDoc,
    /// What changed against the file's `manual`.
    #[cfg_attr(feature = "schema", schemars(with = "Option<String>"))]
    #[serde(skip_serializing_if = "Option::is_none")]
    pub doc: Option<Spanned<String>>,
    /// Serial settings of this firmware, when they differ.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub serial: Option<SerialDoc>,
}

/// One `include` entry, as written: a file, or a file and the commands to take.
#[derive(Debug)]
pub struct IncludeDoc {
    /// The fragment file, relative to the including file.
    pub file: String,
    /// The commands to take; `None` for every command.
    pub only: Option<Vec<Spanned<String>>>,
}

/// The JSON-schema shape of an `include` entry.
#[cfg(feature = "schema")]
#[derive(schemars::JsonSchema)]
#[serde(untagged)]
#[allow(dead_code)]
pub enum IncludeSchema {
    /// Every command of the fragment file.
    File(String),
    /// Some commands of a fragment file.
    Some {
        /// The fragment file.
        file: String,
        /// The commands to take.
        only: Vec<String>,
    },
}

impl<'de> Deserialize<'de> for IncludeDoc {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct V;
        impl<'de> serde::de::Visitor<'de> for V {
            type Value = IncludeDoc;
            fn expecting(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
                f.write_str("a fragment file name, or `{file: NAME, only: [COMMAND, ...]}`")
            }
            fn visit_str<E: serde::de::Error>(self, v: &str) -> Result<IncludeDoc, E> {
                Ok(IncludeDoc { file: v.to_string(), only: None })
            }
            fn visit_map<A: serde::de::MapAccess<'de>>(self, mut map: A) -> Result<IncludeDoc, A::Error> {
                let mut file = None;
                let mut only = None;
                while let Some(key) = map.next_key::<String>()? {
                    match key.as_str() {
                        "file" if file.is_none() => file = Some(map.next_value::<String>()?),
                        "only" if only.is_none() => only = Some(map.next_value::<Vec<Spanned<String>>>()?),
                        "file" | "only" => return Err(serde::de::Error::duplicate_field("include key")),
                        other => return Err(serde::de::Error::unknown_field(other, &["file", "only"])),
                    }
                }
                let file = file.ok_or_else(|| serde::de::Error::missing_field("file"))?;
                let only = only.ok_or_else(|| serde::de::Error::missing_field("only"))?;
                Ok(IncludeDoc { file, only: Some(only) })
            }
        }
        d.deserialize_any(V)
    }
}

/// An entry that takes every command is written as the bare file name, the
/// shorter of the two spellings the loader reads.
#[cfg(feature = "serialize")]
impl serde::Serialize for IncludeDoc {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        use serde::ser::SerializeMap as _;
        match &self.only {
            None => s.serialize_str(&self.file),
            Some(only) => {
                let mut map = s.serialize_map(Some(2))?;
                map.serialize_entry("file", &self.file)?;
                map.serialize_entry("only", only)?;
                map.end()
            }
        }
    }
}

/// Serial line settings.
#[derive(Debug, Deserialize)]
#[cfg_attr(feature = "serialize", derive(serde::Serialize))]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[serde(deny_unknown_fields)]
pub struct SerialDoc {
    /// Bits per second.
    #[cfg_attr(feature = "schema", schemars(with = "u32"))]
    pub baud: Spanned<u32>,
    /// Data bits per character (7 or 8).
    #[cfg_attr(feature = "schema", schemars(with = "u32"))]
    pub data_bits: Spanned<u32>,
    /// Parity.
    pub parity: ParityDoc,
    /// Stop bits (1 or 2).
    #[cfg_attr(feature = "schema", schemars(with = "u32"))]
    pub stop_bits: Spanned<u32>,
}

/// Parity bit.
#[derive(Debug, Clone, Copy, Deserialize, PartialEq, Eq)]
#[cfg_attr(feature = "serialize", derive(serde::Serialize))]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[serde(rename_all = "snake_case")]
pub enum ParityDoc {
    /// No parity bit.
    None,
    /// Even parity.
    Even,
    /// Odd parity.
    Odd,
}

impl ParityDoc {
    /// The runtime parity this spelling names: the one mapping of the syntax.
    pub fn parity(self) -> Parity {
        match self {
            Self::None => Parity::None,
            Self::Even => Parity::Even,
            Self::Odd => Parity::Odd,
        }
    }
}

/// An inclusive range of slave addresses.
#[derive(Debug, Deserialize)]
#[cfg_attr(feature = "serialize", derive(serde::Serialize))]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[serde(deny_unknown_fields)]
pub struct AddressRangeDoc {
    /// Lowest address.
    #[cfg_attr(feature = "schema", schemars(with = "u32"))]
    pub min: Spanned<u32>,
    /// Highest address.
    #[cfg_attr(feature = "schema", schemars(with = "u32"))]
    pub max: Spanned<u32>,
}

/// A file of shared commands.
#[derive(Debug, Deserialize)]
#[cfg_attr(feature = "serialize", derive(serde::Serialize))]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[serde(deny_unknown_fields)]
pub struct FragmentDoc {
    /// snake_case name.
    #[cfg_attr(feature = "schema", schemars(with = "String"))]
    pub name: Spanned<String>,
    /// What the fragment holds.
    #[cfg_attr(feature = "schema", schemars(with = "String"))]
    pub doc: Spanned<String>,
}

/// Where in the manual something is documented.
#[derive(Debug, Clone, Deserialize)]
#[cfg_attr(feature = "serialize", derive(serde::Serialize))]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[serde(deny_unknown_fields)]
pub struct SourceDoc {
    /// Section number, e.g. "2.2.3".
    #[cfg_attr(feature = "schema", schemars(with = "String"))]
    pub section: Spanned<String>,
    /// Figures and tables.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub figures: Vec<FigureDoc>,
    /// The manual (its `software` revision) when not the file's `manual`.
    #[cfg_attr(feature = "schema", schemars(with = "Option<String>"))]
    #[serde(skip_serializing_if = "Option::is_none")]
    pub manual: Option<Spanned<String>>,
}

/// A figure reference: `23` (Figure 23), `"T4"` (Table 4), `"43b"` (the second Figure 43).
#[derive(Debug, Clone, Deserialize, PartialEq, Eq)]
#[cfg_attr(feature = "serialize", derive(serde::Serialize))]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[serde(untagged)]
pub enum FigureDoc {
    /// A figure number.
    Number(u32),
    /// `T<n>` for a table, `<n>b` for a figure number used a second time.
    Text(String),
}

/// What a command is for, where the simulator or the CLI must know.
#[derive(Debug, Clone, Copy, Deserialize, serde::Serialize, PartialEq, Eq, Hash, PartialOrd, Ord)]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[serde(rename_all = "snake_case")]
pub enum RoleDoc {
    /// Writes the slave address.
    SetSlaveAddress,
    /// Reads the slave address.
    GetSlaveAddress,
    /// Reads the serial number.
    SerialNumber,
    /// Reads hardware and software revisions.
    Version,
    /// Starts measuring.
    StartMeasurement,
    /// Stops measuring.
    StopMeasurement,
    /// Runs the wiper or brush once.
    Wipe,
    /// Writes one calibration standard.
    CalibrationPoint,
    /// Reads the result of a calibration.
    CalibrationStatus,
    /// Writes a user calibration block: slope K, then offset B (two `f32`),
    /// applied as final = K x raw + B; a read of the same registers pairs it.
    UserCalibration,
}

/// What a user calibration block (role `user_calibration`) calibrates,
/// where the manual says it.
#[derive(Debug, Deserialize)]
#[cfg_attr(feature = "serialize", derive(serde::Serialize))]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[serde(deny_unknown_fields)]
pub struct CalibratesDoc {
    /// The measured field K and B apply to: a named field of a measurement read.
    #[cfg_attr(feature = "schema", schemars(with = "String"))]
    pub field: Spanned<String>,
    /// The standards the manual recommends, in the field's unit.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    #[cfg_attr(feature = "schema", schemars(with = "Vec<f64>"))]
    pub standards: Vec<Spanned<f64>>,
    /// Milliseconds to let the probe settle in each standard.
    #[cfg_attr(feature = "schema", schemars(with = "Option<u32>"))]
    #[serde(skip_serializing_if = "Option::is_none")]
    pub settle_ms: Option<Spanned<u32>>,
}

/// The measuring procedure of a manual.
#[derive(Debug, Deserialize)]
#[cfg_attr(feature = "serialize", derive(serde::Serialize))]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[serde(deny_unknown_fields)]
pub struct ProcedureDoc {
    /// Where the manual describes it.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub source: Option<SourceDoc>,
    /// Where its steps and timings come from when no manual states them.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub provenance: Option<ProvenanceDoc>,
    /// The procedure in words.
    #[cfg_attr(feature = "schema", schemars(with = "Option<String>"))]
    #[serde(skip_serializing_if = "Option::is_none")]
    pub doc: Option<Spanned<String>>,
    /// Commands sent first, in order (commands that take no values).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    #[cfg_attr(feature = "schema", schemars(with = "Vec<String>"))]
    pub before: Vec<Spanned<String>>,
    /// Milliseconds to wait after `before`.
    #[serde(default)]
    #[cfg_attr(feature = "schema", schemars(with = "Option<u32>"))]
    #[serde(skip_serializing_if = "Option::is_none")]
    pub warm_up_ms: Option<Spanned<u32>>,
    /// The reads that give the measurements.
    #[cfg_attr(feature = "schema", schemars(with = "Vec<String>"))]
    pub read: Spanned<Vec<Spanned<String>>>,
    /// Readings to average (default 1).
    #[cfg_attr(feature = "schema", schemars(with = "Option<u32>"))]
    #[serde(skip_serializing_if = "Option::is_none")]
    pub readings: Option<Spanned<u32>>,
    /// Milliseconds between readings.
    #[cfg_attr(feature = "schema", schemars(with = "Option<u32>"))]
    #[serde(skip_serializing_if = "Option::is_none")]
    pub interval_ms: Option<Spanned<u32>>,
    /// Commands sent at the end, in order.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    #[cfg_attr(feature = "schema", schemars(with = "Vec<String>"))]
    pub after: Vec<Spanned<String>>,
}

/// Read or write.
#[derive(Debug, Clone, Copy, Deserialize, PartialEq, Eq)]
#[cfg_attr(feature = "serialize", derive(serde::Serialize))]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[serde(rename_all = "snake_case")]
pub enum FunctionDoc {
    /// 0x03, read holding registers.
    Read,
    /// 0x10, write multiple registers.
    Write,
}

/// A command: a full definition (`name`), or `use` of an included one.
#[derive(Debug, Deserialize)]
#[cfg_attr(feature = "serialize", derive(serde::Serialize))]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[serde(deny_unknown_fields)]
#[cfg_attr(feature = "schema", schemars(extend("oneOf" = [{"required": ["name"]}, {"required": ["use"]}])))]
pub struct CommandDoc {
    /// snake_case name of a new command.
    #[cfg_attr(feature = "schema", schemars(with = "Option<String>"))]
    #[serde(skip_serializing_if = "Option::is_none")]
    pub name: Option<Spanned<String>>,
    /// Name of an included command this entry adds `source`, `examples` and `errata` to.
    #[serde(rename = "use")]
    #[cfg_attr(feature = "schema", schemars(with = "Option<String>"))]
    #[serde(skip_serializing_if = "Option::is_none")]
    pub uses: Option<Spanned<String>>,
    /// Human title, as in the manual's section heading.
    #[cfg_attr(feature = "schema", schemars(with = "Option<String>"))]
    #[serde(skip_serializing_if = "Option::is_none")]
    pub title: Option<Spanned<String>>,
    /// The software revision that introduced the command (a manual's `software`).
    #[cfg_attr(feature = "schema", schemars(with = "Option<String>"))]
    #[serde(skip_serializing_if = "Option::is_none")]
    pub since: Option<Spanned<String>>,
    /// What the command is for, where the simulator or the CLI must know.
    #[cfg_attr(feature = "schema", schemars(with = "Option<RoleDoc>"))]
    #[serde(skip_serializing_if = "Option::is_none")]
    pub role: Option<Spanned<RoleDoc>>,
    /// Of a user calibration block: the field it calibrates, where the manual says it.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub calibrates: Option<CalibratesDoc>,
    /// In a `use` entry: the unit this manual states for a field.
    #[cfg_attr(feature = "schema", schemars(with = "Option<BTreeMap<String, String>>"))]
    #[serde(skip_serializing_if = "Option::is_none")]
    pub units: Option<Spanned<BTreeMap<String, Spanned<String>>>>,
    /// What the command does; becomes the rustdoc.
    #[cfg_attr(feature = "schema", schemars(with = "Option<String>"))]
    #[serde(skip_serializing_if = "Option::is_none")]
    pub doc: Option<Spanned<String>>,
    /// Where the manual documents it.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub source: Option<SourceDoc>,
    /// Where its facts come from when no manual states them.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub provenance: Option<ProvenanceDoc>,
    /// `read` (0x03) or `write` (0x10).
    #[cfg_attr(feature = "schema", schemars(with = "Option<FunctionDoc>"))]
    #[serde(skip_serializing_if = "Option::is_none")]
    pub function: Option<Spanned<FunctionDoc>>,
    /// First register, as sent on the wire.
    #[cfg_attr(feature = "schema", schemars(with = "Option<u32>"))]
    #[serde(skip_serializing_if = "Option::is_none")]
    pub address: Option<Spanned<u32>>,
    /// Number of registers.
    #[cfg_attr(feature = "schema", schemars(with = "Option<u32>"))]
    #[serde(skip_serializing_if = "Option::is_none")]
    pub count: Option<Spanned<u32>>,
    /// A command that carries no value: a write of zero registers, or a read whose reply is ignored.
    #[cfg_attr(feature = "schema", schemars(with = "Option<bool>"))]
    #[serde(skip_serializing_if = "Option::is_none")]
    pub trigger: Option<Spanned<bool>>,
    /// A slave address the request and the reply always use (e.g. 0xFF).
    #[cfg_attr(feature = "schema", schemars(with = "Option<u32>"))]
    #[serde(skip_serializing_if = "Option::is_none")]
    pub fixed_slave: Option<Spanned<u32>>,
    /// Byte counts a read reply may carry besides `2 * count`, for firmware quirks.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    #[cfg_attr(feature = "schema", schemars(with = "Vec<u32>"))]
    pub extra_byte_counts: Vec<Spanned<u32>>,
    /// The register data, in wire order: the reply of a read, the request of a write.
    #[cfg_attr(feature = "schema", schemars(with = "Option<Vec<FieldDoc>>"))]
    #[serde(skip_serializing_if = "Option::is_none")]
    pub fields: Option<Spanned<Vec<FieldDoc>>>,
    /// Frames printed in the manual.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub examples: Vec<ExampleDoc>,
    /// Places where the manual's command table contradicts its examples.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub errata: Vec<CommandErratumDoc>,
}

/// The type of a field.
#[derive(Debug, Clone, Copy, Deserialize, PartialEq, Eq)]
#[cfg_attr(feature = "serialize", derive(serde::Serialize))]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[serde(rename_all = "snake_case")]
pub enum FieldTypeDoc {
    /// IEEE 754 single, 4 bytes, needs `byte_order`.
    F32,
    /// One byte, unsigned.
    U8,
    /// One byte, signed.
    I8,
    /// Two bytes, unsigned, needs `byte_order`.
    U16,
    /// Two bytes, signed, needs `byte_order`.
    I16,
    /// Four bytes, unsigned, needs `byte_order`.
    U32,
    /// Four bytes, signed, needs `byte_order`.
    I32,
    /// Fixed-length text of `size` bytes, padded with `padding`.
    Ascii,
    /// Two bytes: major, minor.
    Version,
    /// A code with named `variants`; `size` 1 or 2 bytes.
    Enum,
    /// `size` bytes the device ignores or fills with `fill`.
    Reserved,
    /// One byte of two decimal digits (`0x59` = 59).
    Bcd,
    /// Independent bits with names; `size` 1 or 2 bytes.
    Flags,
}

/// Byte order of a multi-byte value, as wire letters (A = most significant).
#[derive(Debug, Clone, Copy, Deserialize, PartialEq, Eq)]
#[cfg_attr(feature = "serialize", derive(serde::Serialize))]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[serde(rename_all = "snake_case")]
pub enum ByteOrderDoc {
    /// Two bytes, big-endian.
    Ab,
    /// Two bytes, little-endian.
    Ba,
    /// Four bytes, big-endian.
    Abcd,
    /// Four bytes, little-endian memory image.
    Dcba,
    /// Four bytes, word-swapped.
    Cdab,
    /// Four bytes, byte-swapped.
    Badc,
}

impl ByteOrderDoc {
    /// The two-byte runtime order this spelling names; `None` for a four-byte one.
    pub fn two(self) -> Option<ByteOrder2> {
        match self {
            Self::Ab => Some(ByteOrder2::Ab),
            Self::Ba => Some(ByteOrder2::Ba),
            Self::Abcd | Self::Dcba | Self::Cdab | Self::Badc => None,
        }
    }

    /// The four-byte runtime order this spelling names; `None` for a two-byte one.
    pub fn four(self) -> Option<ByteOrder4> {
        match self {
            Self::Abcd => Some(ByteOrder4::Abcd),
            Self::Dcba => Some(ByteOrder4::Dcba),
            Self::Cdab => Some(ByteOrder4::Cdab),
            Self::Badc => Some(ByteOrder4::Badc),
            Self::Ab | Self::Ba => None,
        }
    }

    /// The spelling, as the runtime names the order (`ab`, `dcba`).
    pub fn name(self) -> &'static str {
        match (self.two(), self.four()) {
            (Some(two), _) => two.name(),
            (None, Some(four)) => four.name(),
            (None, None) => "",
        }
    }
}

/// Text padding byte.
#[derive(Debug, Clone, Copy, Deserialize, PartialEq, Eq)]
#[cfg_attr(feature = "serialize", derive(serde::Serialize))]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[serde(rename_all = "snake_case")]
pub enum PaddingDoc {
    /// 0x00.
    Nul,
    /// 0x20.
    Space,
}

/// An inclusive range of valid values.
#[derive(Debug, Deserialize)]
#[cfg_attr(feature = "serialize", derive(serde::Serialize))]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[serde(deny_unknown_fields)]
pub struct RangeDoc {
    /// Lowest valid value.
    pub min: f64,
    /// Highest valid value.
    pub max: f64,
}

/// One field of register data.
#[derive(Debug, Deserialize)]
#[cfg_attr(feature = "serialize", derive(serde::Serialize))]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[serde(deny_unknown_fields)]
pub struct FieldDoc {
    /// snake_case name; optional for `reserved`.
    #[cfg_attr(feature = "schema", schemars(with = "Option<String>"))]
    #[serde(skip_serializing_if = "Option::is_none")]
    pub name: Option<Spanned<String>>,
    /// The value's type.
    #[serde(rename = "type")]
    #[cfg_attr(feature = "schema", schemars(with = "FieldTypeDoc"))]
    pub ty: Spanned<FieldTypeDoc>,
    /// Byte offset in the register data; defaults to right after the previous field.
    #[cfg_attr(feature = "schema", schemars(with = "Option<u32>"))]
    #[serde(skip_serializing_if = "Option::is_none")]
    pub offset: Option<Spanned<u32>>,
    /// Wire byte order, for 2- and 4-byte numbers.
    #[cfg_attr(feature = "schema", schemars(with = "Option<ByteOrderDoc>"))]
    #[serde(skip_serializing_if = "Option::is_none")]
    pub byte_order: Option<Spanned<ByteOrderDoc>>,
    /// Bytes, for `ascii`, `enum` and `reserved`.
    #[cfg_attr(feature = "schema", schemars(with = "Option<u32>"))]
    #[serde(skip_serializing_if = "Option::is_none")]
    pub size: Option<Spanned<u32>>,
    /// Padding of `ascii` text.
    #[cfg_attr(feature = "schema", schemars(with = "Option<PaddingDoc>"))]
    #[serde(skip_serializing_if = "Option::is_none")]
    pub padding: Option<Spanned<PaddingDoc>>,
    /// Byte written into `reserved` bytes (default 0).
    #[cfg_attr(feature = "schema", schemars(with = "Option<u32>"))]
    #[serde(skip_serializing_if = "Option::is_none")]
    pub fill: Option<Spanned<u32>>,
    /// Physical unit (pH, mV, degC, mS/cm).
    #[cfg_attr(feature = "schema", schemars(with = "Option<String>"))]
    #[serde(skip_serializing_if = "Option::is_none")]
    pub unit: Option<Spanned<String>>,
    /// What the value means.
    #[cfg_attr(feature = "schema", schemars(with = "Option<String>"))]
    #[serde(skip_serializing_if = "Option::is_none")]
    pub doc: Option<Spanned<String>>,
    /// Values a write may send.
    #[cfg_attr(feature = "schema", schemars(with = "Option<RangeDoc>"))]
    #[serde(skip_serializing_if = "Option::is_none")]
    pub range: Option<Spanned<RangeDoc>>,
    /// The value of natural water the simulator centres a reading on
    /// (default: the middle of `range`). Not a fact of the probe.
    #[cfg_attr(feature = "schema", schemars(with = "Option<f64>"))]
    #[serde(skip_serializing_if = "Option::is_none")]
    pub typical: Option<Spanned<f64>>,
    /// Named codes of an `enum`.
    #[cfg_attr(feature = "schema", schemars(with = "Option<Vec<VariantDoc>>"))]
    #[serde(skip_serializing_if = "Option::is_none")]
    pub variants: Option<Spanned<Vec<VariantDoc>>>,
    /// Named bits of a `flags` field.
    #[cfg_attr(feature = "schema", schemars(with = "Option<Vec<FlagDoc>>"))]
    #[serde(skip_serializing_if = "Option::is_none")]
    pub flags: Option<Spanned<Vec<FlagDoc>>>,
    /// The value read where a sub-probe is not fitted.
    #[cfg_attr(feature = "schema", schemars(with = "Option<f64>"))]
    #[serde(skip_serializing_if = "Option::is_none")]
    pub absent: Option<Spanned<f64>>,
    /// Values with their bytes, as the manual prints them outside a frame.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub examples: Vec<FieldExampleDoc>,
}

/// A named bit of a flags field.
#[derive(Debug, Deserialize)]
#[cfg_attr(feature = "serialize", derive(serde::Serialize))]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[serde(deny_unknown_fields)]
pub struct FlagDoc {
    /// snake_case name.
    #[cfg_attr(feature = "schema", schemars(with = "String"))]
    pub name: Spanned<String>,
    /// The bit, as a mask with one bit set (`0x04`).
    #[cfg_attr(feature = "schema", schemars(with = "u32"))]
    pub mask: Spanned<u32>,
    /// What the bit means.
    #[cfg_attr(feature = "schema", schemars(with = "Option<String>"))]
    #[serde(skip_serializing_if = "Option::is_none")]
    pub doc: Option<Spanned<String>>,
}

/// A field's value and its bytes, printed outside a frame.
#[derive(Debug, Deserialize)]
#[cfg_attr(feature = "serialize", derive(serde::Serialize))]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[serde(deny_unknown_fields)]
pub struct FieldExampleDoc {
    /// The bytes, hex separated by spaces.
    #[cfg_attr(feature = "schema", schemars(with = "String"))]
    pub bytes: Spanned<String>,
    /// The value the manual states.
    #[cfg_attr(feature = "schema", schemars(with = "StatedValue"))]
    pub value: Spanned<StatedValue>,
    /// Where the manual prints it.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub figures: Vec<FigureDoc>,
}

/// A named code of an enum field.
#[derive(Debug, Deserialize)]
#[cfg_attr(feature = "serialize", derive(serde::Serialize))]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[serde(deny_unknown_fields)]
pub struct VariantDoc {
    /// snake_case name; becomes a CamelCase variant.
    #[cfg_attr(feature = "schema", schemars(with = "String"))]
    pub name: Spanned<String>,
    /// The code on the wire.
    #[cfg_attr(feature = "schema", schemars(with = "u32"))]
    pub value: Spanned<u32>,
    /// What the code means.
    #[cfg_attr(feature = "schema", schemars(with = "Option<String>"))]
    #[serde(skip_serializing_if = "Option::is_none")]
    pub doc: Option<Spanned<String>>,
}

/// A value stated by the manual for an example frame.
#[derive(Debug, Clone, Deserialize, PartialEq)]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[serde(untagged)]
pub enum StatedValue {
    /// A number.
    Number(f64),
    /// Text, a version ("1.1") or an enum variant name.
    Text(String),
}

/// A whole number is written without a fraction (`20`, not `20.0`), as a
/// manual prints an address or a count; it reads back as the same number.
#[cfg(feature = "serialize")]
impl serde::Serialize for StatedValue {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        // Past 2^53 an f64 no longer holds every integer: keep its own spelling.
        const EXACT: f64 = 9_007_199_254_740_992.0;
        match self {
            Self::Number(n) if n.fract() == 0.0 && n.abs() < EXACT => s.serialize_i64(*n as i64),
            Self::Number(n) => s.serialize_f64(*n),
            Self::Text(t) => s.serialize_str(t),
        }
    }
}

/// Whether the manual prints a frame's CRC.
#[derive(Debug, Clone, Copy, Deserialize, PartialEq, Eq)]
#[cfg_attr(feature = "serialize", derive(serde::Serialize))]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[serde(rename_all = "snake_case")]
pub enum CrcDoc {
    /// The CRC is printed (the default).
    Printed,
    /// The CRC cells are empty: the text holds the bytes before the CRC.
    Missing,
}

/// A frame pair printed in the manual.
#[derive(Debug, Deserialize)]
#[cfg_attr(feature = "serialize", derive(serde::Serialize))]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[serde(deny_unknown_fields)]
pub struct ExampleDoc {
    /// The figures that print the frames (and their register tables).
    pub figures: Vec<FigureDoc>,
    /// The manual (its `software` revision) when not the file's `manual`.
    #[cfg_attr(feature = "schema", schemars(with = "Option<String>"))]
    #[serde(skip_serializing_if = "Option::is_none")]
    pub manual: Option<Spanned<String>>,
    /// The request as printed, hex bytes separated by spaces; `??` for a
    /// placeholder byte, a final `...` for bytes of unknown number.
    #[cfg_attr(feature = "schema", schemars(with = "Option<String>"))]
    #[serde(skip_serializing_if = "Option::is_none")]
    pub request: Option<Spanned<String>>,
    /// Whether the request's CRC is printed.
    #[cfg_attr(feature = "schema", schemars(with = "Option<CrcDoc>"))]
    #[serde(skip_serializing_if = "Option::is_none")]
    pub request_crc: Option<Spanned<CrcDoc>>,
    /// The reply as printed, like `request`.
    #[cfg_attr(feature = "schema", schemars(with = "Option<String>"))]
    #[serde(skip_serializing_if = "Option::is_none")]
    pub response: Option<Spanned<String>>,
    /// Whether the reply's CRC is printed.
    #[cfg_attr(feature = "schema", schemars(with = "Option<CrcDoc>"))]
    #[serde(skip_serializing_if = "Option::is_none")]
    pub response_crc: Option<Spanned<CrcDoc>>,
    /// The values the manual states, by field name (none for an example
    /// whose frames carry no values).
    #[cfg_attr(feature = "schema", schemars(with = "Option<BTreeMap<String, StatedValue>>"))]
    #[serde(skip_serializing_if = "Option::is_none")]
    pub values: Option<Spanned<BTreeMap<String, Spanned<StatedValue>>>>,
    /// Remarks on the example.
    #[cfg_attr(feature = "schema", schemars(with = "Option<String>"))]
    #[serde(skip_serializing_if = "Option::is_none")]
    pub doc: Option<Spanned<String>>,
    /// Where a printed frame contradicts the truth.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub erratum: Option<ExampleErratumDoc>,
    /// Other manuals that print the same frames, byte for byte: cited with
    /// their own figure numbers instead of copied.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub also_in: Vec<CitationDoc>,
}

/// Another manual's figures that print an example's frames identically.
#[derive(Debug, Deserialize)]
#[cfg_attr(feature = "serialize", derive(serde::Serialize))]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[serde(deny_unknown_fields)]
pub struct CitationDoc {
    /// The manual (its `software` revision).
    #[cfg_attr(feature = "schema", schemars(with = "String"))]
    pub manual: Spanned<String>,
    /// Its figures and tables that print the frames.
    pub figures: Vec<FigureDoc>,
}

/// A printed frame that is wrong, and its correction.
#[derive(Debug, Deserialize)]
#[cfg_attr(feature = "serialize", derive(serde::Serialize))]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[serde(deny_unknown_fields)]
pub struct ExampleErratumDoc {
    /// Identifier in datasheet-notes.md (E4, E5, …).
    #[cfg_attr(feature = "schema", schemars(with = "String"))]
    pub id: Spanned<String>,
    /// The figure that prints the wrong frame.
    #[cfg_attr(feature = "schema", schemars(with = "FigureDoc"))]
    pub figure: Spanned<FigureDoc>,
    /// What is wrong with the printed frame.
    #[cfg_attr(feature = "schema", schemars(with = "String"))]
    pub printed: Spanned<String>,
    /// The true request, when the printed request is wrong.
    #[cfg_attr(feature = "schema", schemars(with = "Option<String>"))]
    #[serde(skip_serializing_if = "Option::is_none")]
    pub corrected_request: Option<Spanned<String>>,
    /// The true reply, when the printed reply is wrong.
    #[cfg_attr(feature = "schema", schemars(with = "Option<String>"))]
    #[serde(skip_serializing_if = "Option::is_none")]
    pub corrected_response: Option<Spanned<String>>,
    /// Whether our decoder accepts the printed frame as it is.
    #[cfg_attr(feature = "schema", schemars(with = "bool"))]
    pub printed_decodes: Spanned<bool>,
}

/// What a manual's command table says where it contradicts the examples.
#[derive(Debug, Deserialize)]
#[cfg_attr(feature = "serialize", derive(serde::Serialize))]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[serde(deny_unknown_fields)]
pub struct TableSaysDoc {
    /// The start address the table prints.
    #[cfg_attr(feature = "schema", schemars(with = "Option<u32>"))]
    #[serde(skip_serializing_if = "Option::is_none")]
    pub address: Option<Spanned<u32>>,
    /// The register count the table prints.
    #[cfg_attr(feature = "schema", schemars(with = "Option<u32>"))]
    #[serde(skip_serializing_if = "Option::is_none")]
    pub count: Option<Spanned<u32>>,
    /// The function the table prints.
    #[cfg_attr(feature = "schema", schemars(with = "Option<FunctionDoc>"))]
    #[serde(skip_serializing_if = "Option::is_none")]
    pub function: Option<Spanned<FunctionDoc>>,
}

/// A command table that contradicts the command's examples.
#[derive(Debug, Deserialize)]
#[cfg_attr(feature = "serialize", derive(serde::Serialize))]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[serde(deny_unknown_fields)]
pub struct CommandErratumDoc {
    /// Identifier in datasheet-notes.md (E1, E2, …).
    #[cfg_attr(feature = "schema", schemars(with = "String"))]
    pub id: Spanned<String>,
    /// The figure or table with the wrong table; none for a table the manual does not number.
    #[cfg_attr(feature = "schema", schemars(with = "Option<FigureDoc>"))]
    #[serde(skip_serializing_if = "Option::is_none")]
    pub figure: Option<Spanned<FigureDoc>>,
    /// The manual (its `software` revision) when not the file's `manual`.
    #[cfg_attr(feature = "schema", schemars(with = "Option<String>"))]
    #[serde(skip_serializing_if = "Option::is_none")]
    pub manual: Option<Spanned<String>>,
    /// What the table prints instead of the truth.
    pub table: TableSaysDoc,
    /// Why the spec's value is the truth.
    #[cfg_attr(feature = "schema", schemars(with = "String"))]
    pub note: Spanned<String>,
}

/// A contradiction in the manual that no command carries.
#[derive(Debug, Deserialize)]
#[cfg_attr(feature = "serialize", derive(serde::Serialize))]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[serde(deny_unknown_fields)]
pub struct ErratumDoc {
    /// Identifier in datasheet-notes.md.
    #[cfg_attr(feature = "schema", schemars(with = "String"))]
    pub id: Spanned<String>,
    /// Figures or tables concerned.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub figures: Vec<FigureDoc>,
    /// The manual (its `software` revision) when not the file's `manual`.
    #[cfg_attr(feature = "schema", schemars(with = "Option<String>"))]
    #[serde(skip_serializing_if = "Option::is_none")]
    pub manual: Option<Spanned<String>>,
    /// Manual sections concerned.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub sections: Vec<String>,
    /// What the manual says and what the spec takes as the truth.
    #[cfg_attr(feature = "schema", schemars(with = "String"))]
    pub note: Spanned<String>,
}

/// The Rust type of a constant.
#[derive(Debug, Clone, Copy, Deserialize, PartialEq, Eq)]
#[cfg_attr(feature = "serialize", derive(serde::Serialize))]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[serde(rename_all = "snake_case")]
pub enum ConstantTypeDoc {
    /// f32.
    F32,
    /// u8.
    U8,
    /// u16.
    U16,
    /// u32.
    U32,
}

/// A number a procedure uses.
#[derive(Debug, Deserialize)]
#[cfg_attr(feature = "serialize", derive(serde::Serialize))]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[serde(deny_unknown_fields)]
pub struct ConstantDoc {
    /// snake_case name; becomes an UPPER_CASE constant.
    #[cfg_attr(feature = "schema", schemars(with = "String"))]
    pub name: Spanned<String>,
    /// The Rust type.
    #[serde(rename = "type")]
    #[cfg_attr(feature = "schema", schemars(with = "ConstantTypeDoc"))]
    pub ty: Spanned<ConstantTypeDoc>,
    /// A single value (exactly one of `value` and `values`).
    #[cfg_attr(feature = "schema", schemars(with = "Option<f64>"))]
    #[serde(skip_serializing_if = "Option::is_none")]
    pub value: Option<Spanned<f64>>,
    /// A list of values, in order.
    #[cfg_attr(feature = "schema", schemars(with = "Option<Vec<f64>>"))]
    #[serde(skip_serializing_if = "Option::is_none")]
    pub values: Option<Spanned<Vec<f64>>>,
    /// Unit.
    #[cfg_attr(feature = "schema", schemars(with = "Option<String>"))]
    #[serde(skip_serializing_if = "Option::is_none")]
    pub unit: Option<Spanned<String>>,
    /// What it is for.
    #[cfg_attr(feature = "schema", schemars(with = "String"))]
    pub doc: Spanned<String>,
    /// Where the manual states it.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub source: Option<SourceDoc>,
}

/// A derived quantity: a formula over fields, constants and station inputs.
#[derive(Debug, Deserialize)]
#[cfg_attr(feature = "serialize", derive(serde::Serialize))]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[serde(deny_unknown_fields)]
pub struct DerivedDoc {
    /// snake_case name; becomes the generated function's name.
    #[cfg_attr(feature = "schema", schemars(with = "String"))]
    pub name: Spanned<String>,
    /// Human title.
    #[cfg_attr(feature = "schema", schemars(with = "String"))]
    pub title: Spanned<String>,
    /// The result's unit, checked against the formula's.
    #[cfg_attr(feature = "schema", schemars(with = "Option<String>"))]
    #[serde(skip_serializing_if = "Option::is_none")]
    pub unit: Option<Spanned<String>>,
    /// What the quantity is.
    #[cfg_attr(feature = "schema", schemars(with = "String"))]
    pub doc: Spanned<String>,
    /// Where the manual gives the formula.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub source: Option<SourceDoc>,
    /// The formula's inputs, in parameter order.
    #[cfg_attr(feature = "schema", schemars(with = "Vec<DerivedInputDoc>"))]
    pub inputs: Spanned<Vec<DerivedInputDoc>>,
    /// The formula: numbers, inputs and constants by name, `+ - * / ^`,
    /// parentheses, `exp()`, `ln()`, comparisons and `if(c, a, b)`.
    #[cfg_attr(feature = "schema", schemars(with = "String"))]
    pub expr: Spanned<String>,
    /// Values computed independently, each with its source.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub examples: Vec<DerivedExampleDoc>,
}

/// One input of a derived quantity: a field of a read, or a station value.
#[derive(Debug, Deserialize)]
#[cfg_attr(feature = "serialize", derive(serde::Serialize))]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[serde(deny_unknown_fields)]
#[cfg_attr(feature = "schema", schemars(extend("oneOf" = [{"required": ["field"]}, {"required": ["station"]}])))]
pub struct DerivedInputDoc {
    /// snake_case name the formula uses; the generated function's parameter.
    #[cfg_attr(feature = "schema", schemars(with = "String"))]
    pub name: Spanned<String>,
    /// `command.field` of a read of the sensor.
    #[cfg_attr(feature = "schema", schemars(with = "Option<String>"))]
    #[serde(skip_serializing_if = "Option::is_none")]
    pub field: Option<Spanned<String>>,
    /// The station input's name (`salinity`, `barometric_pressure`).
    #[cfg_attr(feature = "schema", schemars(with = "Option<String>"))]
    #[serde(skip_serializing_if = "Option::is_none")]
    pub station: Option<Spanned<String>>,
    /// The unit of a station input (a field input has its field's).
    #[cfg_attr(feature = "schema", schemars(with = "Option<String>"))]
    #[serde(skip_serializing_if = "Option::is_none")]
    pub unit: Option<Spanned<String>>,
    /// The value used when a station gives none.
    #[cfg_attr(feature = "schema", schemars(with = "Option<f64>"))]
    #[serde(skip_serializing_if = "Option::is_none")]
    pub default: Option<Spanned<f64>>,
    /// The values the formula takes; others make the quantity not computable.
    #[cfg_attr(feature = "schema", schemars(with = "Option<RangeDoc>"))]
    #[serde(skip_serializing_if = "Option::is_none")]
    pub range: Option<Spanned<RangeDoc>>,
}

/// A value of a derived quantity computed independently of the formula.
#[derive(Debug, Deserialize)]
#[cfg_attr(feature = "serialize", derive(serde::Serialize))]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[serde(deny_unknown_fields)]
pub struct DerivedExampleDoc {
    /// The inputs by name (station inputs left out take their `default`).
    #[cfg_attr(feature = "schema", schemars(with = "BTreeMap<String, f64>"))]
    pub inputs: Spanned<BTreeMap<String, Spanned<f64>>>,
    /// The value the source gives.
    #[cfg_attr(feature = "schema", schemars(with = "f64"))]
    pub value: Spanned<f64>,
    /// How far the formula's value may be from `value`.
    #[cfg_attr(feature = "schema", schemars(with = "Option<f64>"))]
    #[serde(skip_serializing_if = "Option::is_none")]
    pub tolerance: Option<Spanned<f64>>,
    /// Where the value comes from.
    #[cfg_attr(feature = "schema", schemars(with = "String"))]
    pub doc: Spanned<String>,
}
