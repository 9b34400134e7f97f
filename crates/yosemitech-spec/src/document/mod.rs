//! The YAML shape of a spec file, exactly as written, with source positions.
//!
//! Nothing here is validated beyond YAML types: [`crate::load_paths`] turns these
//! documents into the checked [`crate::model`]. Positions are kept with
//! `Spanned` on every value a semantic error may point at; the model avoids
//! `untagged` and `flatten`, which would lose them.

use std::collections::BTreeMap;

use crate::Spanned;
use serde::Deserialize;
use yosemitech_rtu::{ByteOrder2, ByteOrder4, Parity};

mod command;
pub use command::*;

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
