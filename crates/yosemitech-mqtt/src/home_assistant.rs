//! Home Assistant MQTT discovery (`[mqtt.home_assistant]`).
//!
//! Every numeric quantity a probe publishes (measured or derived) becomes a
//! Home Assistant `sensor` entity, announced by a retained JSON config at
//!
//! ```text
//! <ha prefix>/sensor/<node_id>/<object_id>/config     node_id: station and probe, object_id: quantity
//! ```
//!
//! whose values come from one retained JSON state topic per probe
//! (`<topic prefix>/<station>/<probe>/state`, `{"<quantity>": value, ...}`),
//! and whose availability is the logger's (`<topic prefix>/<station>/status`,
//! `online` after each connection, `offline` as the MQTT last will and at a
//! clean stop) and the probe's (`<topic prefix>/<station>/<probe>/availability`,
//! `online` after a good reading, `offline` after a failed one). The station
//! itself is a device with one `binary_sensor` (its connectivity), the
//! `via_device` of its probes. `docs/mqtt.md` shows the payloads.
//!
//! Nothing here knows a sensor: the entities come from the reading messages,
//! the device from their serial number, firmware and spec sensor name.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};
use serde_json::{Value, json};

use crate::message::ReadingMessage;
use crate::topic::escape_level;

/// The default discovery prefix (Home Assistant's own default).
pub const DEFAULT_DISCOVERY_PREFIX: &str = "homeassistant";
/// The availability payload of a logger or probe that works.
pub const ONLINE: &str = "online";
/// The availability payload of a logger that stopped or a probe that does not answer.
pub const OFFLINE: &str = "offline";
/// The `manufacturer` of every device.
pub const MANUFACTURER: &str = "Yosemitech";

/// The `[mqtt.home_assistant]` section: present, the logger publishes
/// discovery configs, probe states and availability.
#[derive(Debug, Clone, PartialEq, Eq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct HomeAssistantConfig {
    /// The discovery prefix Home Assistant listens on. Default `homeassistant`.
    #[serde(default = "default_prefix")]
    pub prefix: String,
}

impl Default for HomeAssistantConfig {
    fn default() -> Self {
        Self { prefix: default_prefix() }
    }
}

fn default_prefix() -> String {
    DEFAULT_DISCOVERY_PREFIX.to_owned()
}

/// The Home Assistant device class of values in `unit`, and the unit as Home
/// Assistant spells it for that class; `None` when Home Assistant has no
/// class accepting that unit (the entity then has no device class and keeps
/// the unit as published).
///
/// The pairs are those of Home Assistant's sensor device classes
/// (<https://www.home-assistant.io/integrations/sensor/#device-class>):
/// `ph` is unitless, so a value in `pH` gets the class and no unit.
pub fn device_class(unit: &str) -> Option<(&'static str, Option<&'static str>)> {
    let (class, unit) = match unit.trim() {
        "degC" | "°C" | "℃" => ("temperature", "°C"),
        "degF" | "°F" | "℉" => ("temperature", "°F"),
        "K" => ("temperature", "K"),
        "pH" => return Some(("ph", None)),
        "V" => ("voltage", "V"),
        "mV" => ("voltage", "mV"),
        "uS/cm" | "µS/cm" | "μS/cm" => ("conductivity", "µS/cm"),
        "mS/cm" => ("conductivity", "mS/cm"),
        "S/cm" => ("conductivity", "S/cm"),
        "Pa" => ("pressure", "Pa"),
        "hPa" => ("pressure", "hPa"),
        "mbar" => ("pressure", "mbar"),
        "kPa" => ("pressure", "kPa"),
        "bar" => ("pressure", "bar"),
        "mmHg" => ("pressure", "mmHg"),
        "psi" => ("pressure", "psi"),
        "mm" => ("distance", "mm"),
        "cm" => ("distance", "cm"),
        "m" => ("distance", "m"),
        "in" => ("distance", "in"),
        "ft" => ("distance", "ft"),
        "ms" => ("duration", "ms"),
        "s" => ("duration", "s"),
        "min" => ("duration", "min"),
        "h" => ("duration", "h"),
        _ => return None,
    };
    Some((class, Some(unit)))
}

/// An identifier Home Assistant accepts as a topic's `node_id` or
/// `object_id` (`[A-Za-z0-9_-]`): letters, digits and `-` are kept, every
/// other byte (`_` too) becomes `_XX` (upper-case hex). Injective, and `__`
/// never occurs in it, so two of them joined by `__` stay apart.
pub fn discovery_id(name: &str) -> String {
    let mut id = String::with_capacity(name.len());
    for &byte in name.as_bytes() {
        if byte.is_ascii_alphanumeric() || byte == b'-' {
            id.push(char::from(byte));
        } else {
            id.push_str(&format!("_{byte:02X}"));
        }
    }
    id
}

/// The topics and payloads of one station's discovery.
#[derive(Debug, Clone)]
pub struct Discovery {
    discovery_prefix: String,
    topic_prefix: String,
    station: String,
}

/// A retained message to publish: topic and payload (empty: clear).
pub type Retained = (String, Vec<u8>);

impl Discovery {
    /// The discovery of station `station`, its own topics under
    /// `topic_prefix` (`mqtt.topic_prefix`).
    pub fn new(config: &HomeAssistantConfig, topic_prefix: &str, station: &str) -> Self {
        Self {
            discovery_prefix: config.prefix.clone(),
            topic_prefix: topic_prefix.to_owned(),
            station: station.to_owned(),
        }
    }

    /// The logger's availability topic (last will `offline`).
    pub fn status_topic(&self) -> String {
        format!("{}/{}/status", self.topic_prefix, escape_level(&self.station))
    }

    /// The retained JSON state of probe `probe`.
    pub fn state_topic(&self, probe: &str) -> String {
        format!("{}/{}/{}/state", self.topic_prefix, escape_level(&self.station), escape_level(probe))
    }

    /// The availability of probe `probe`.
    pub fn availability_topic(&self, probe: &str) -> String {
        format!("{}/{}/{}/availability", self.topic_prefix, escape_level(&self.station), escape_level(probe))
    }

    /// The `node_id` level of probe `probe`'s configs.
    fn node_id(&self, probe: &str) -> String {
        format!("{}__{}", discovery_id(&self.station), discovery_id(probe))
    }

    /// The first levels of every config of probe `probe`, up to and
    /// including its `node_id`.
    fn probe_config_prefix(&self, probe: &str) -> String {
        format!("{}/sensor/{}/", self.discovery_prefix, self.node_id(probe))
    }

    /// The config topic of quantity `quantity` of probe `probe`.
    pub fn config_topic(&self, probe: &str, quantity: &str) -> String {
        format!("{}{}/config", self.probe_config_prefix(probe), discovery_id(quantity))
    }

    /// The config topic of the station's own connectivity entity.
    pub fn station_config_topic(&self) -> String {
        format!("{}/binary_sensor/{}/status/config", self.discovery_prefix, discovery_id(&self.station))
    }

    fn station_identifier(&self) -> String {
        format!("yosemitech_station_{}", discovery_id(&self.station))
    }

    /// The config of the station's connectivity entity: the station device
    /// the probes name as `via_device`.
    pub fn station_config(&self) -> Retained {
        let config = json!({
            "name": "Logger",
            "unique_id": format!("yosemitech:{}:status", escape_level(&self.station)),
            "state_topic": self.status_topic(),
            "payload_on": ONLINE,
            "payload_off": OFFLINE,
            "device_class": "connectivity",
            "entity_category": "diagnostic",
            "device": {
                "identifiers": [self.station_identifier()],
                "name": format!("Station {}", self.station),
                "manufacturer": MANUFACTURER,
                "model": "station logger",
                "sw_version": env!("CARGO_PKG_VERSION"),
            },
        });
        (self.station_config_topic(), config.to_string().into_bytes())
    }

    /// The configs of every numeric quantity of `message`'s probe.
    pub fn configs(&self, message: &ReadingMessage) -> Vec<Retained> {
        let probe = &message.probe;
        let identifier = match &message.serial_number {
            Some(serial) if !serial.is_empty() => format!("yosemitech_{}", discovery_id(serial)),
            _ => format!("yosemitech_{}", self.node_id(probe)),
        };
        let mut device = json!({
            "identifiers": [identifier],
            "name": format!("{} {}", self.station, probe),
            "manufacturer": MANUFACTURER,
            "model": message.sensor,
            "via_device": self.station_identifier(),
        });
        if let Some(firmware) = &message.firmware {
            device["sw_version"] = json!(firmware);
        }
        if let Some(serial) = &message.serial_number {
            device["serial_number"] = json!(serial);
        }
        message
            .values
            .iter()
            .map(|value| {
                let mut config = json!({
                    "name": value.name,
                    "unique_id": format!(
                        "yosemitech:{}:{}:{}",
                        escape_level(&self.station),
                        escape_level(probe),
                        escape_level(&value.name)
                    ),
                    "state_topic": self.state_topic(probe),
                    "value_template": value_template(&value.name),
                    "state_class": "measurement",
                    "availability": [
                        { "topic": self.status_topic() },
                        { "topic": self.availability_topic(probe) },
                    ],
                    "availability_mode": "all",
                    "payload_available": ONLINE,
                    "payload_not_available": OFFLINE,
                    "device": device,
                });
                let class = value.unit.as_deref().and_then(device_class);
                match (class, &value.unit) {
                    (Some((class, unit)), _) => {
                        config["device_class"] = json!(class);
                        if let Some(unit) = unit {
                            config["unit_of_measurement"] = json!(unit);
                        }
                    }
                    (None, Some(unit)) => config["unit_of_measurement"] = json!(unit),
                    (None, None) => {}
                }
                (self.config_topic(probe, &value.name), config.to_string().into_bytes())
            })
            .collect()
    }

    /// The state of `message`'s probe: its values by quantity name (`null`
    /// when not a number); `None` for a reading without values.
    pub fn state(&self, message: &ReadingMessage) -> Option<Retained> {
        if message.values.is_empty() {
            return None;
        }
        let state: serde_json::Map<String, Value> =
            message.values.iter().map(|v| (v.name.clone(), json!(v.value))).collect();
        Some((self.state_topic(&message.probe), Value::Object(state).to_string().into_bytes()))
    }
}

/// `{{ value_json.<name> }}`, or the subscript form for a name that is not
/// an identifier.
fn value_template(name: &str) -> String {
    let identifier = name.chars().next().is_some_and(|c| c.is_ascii_alphabetic() || c == '_')
        && name.chars().all(|c| c.is_ascii_alphanumeric() || c == '_');
    if identifier { format!("{{{{ value_json.{name} }}}}") } else { format!("{{{{ value_json[{}] }}}}", json!(name)) }
}

/// The config topics announced so far, by probe label: kept in a small JSON
/// file so that a later start can clear the configs of a probe removed from
/// the station file.
#[derive(Debug, Default, Serialize, Deserialize)]
struct Announced {
    probes: BTreeMap<String, BTreeSet<String>>,
}

/// Follows the readings of a station and says what to publish, retained, to
/// keep Home Assistant's view of it current; remembers what it announced in
/// a file of its own.
#[derive(Debug)]
pub struct Tracker {
    discovery: Discovery,
    file: PathBuf,
    announced: Announced,
    /// The last config payloads sent per probe, to announce again only on change.
    sent: BTreeMap<String, Vec<Retained>>,
}

impl Tracker {
    /// A tracker remembering its announcements in `file` (read now when it
    /// exists; an unreadable one is treated as empty: its configs then stay
    /// until Home Assistant's user deletes them). Returns the tracker and
    /// the messages to publish at start: the station's config, and an empty
    /// retained config for every config announced earlier for a probe that
    /// is not in `probes` any more (or under other topics: another station
    /// name or prefix). Those stay recorded and are cleared again at every
    /// start, since nothing tells whether the broker got the empty configs
    /// before this process ended; clearing twice does no harm.
    pub fn start(discovery: Discovery, file: &Path, probes: &[&str]) -> (Self, Vec<Retained>) {
        let announced: Announced = std::fs::read(file)
            .ok()
            .and_then(|bytes| match serde_json::from_slice(&bytes) {
                Ok(announced) => Some(announced),
                Err(error) => {
                    tracing::warn!(file = %file.display(), %error, "ignoring an unreadable Home Assistant record");
                    None
                }
            })
            .unwrap_or_default();
        let tracker = Self { discovery, file: file.to_owned(), announced, sent: BTreeMap::new() };
        let mut messages = vec![tracker.discovery.station_config()];
        for (label, topics) in &tracker.announced.probes {
            let prefix = tracker.discovery.probe_config_prefix(label);
            let kept = probes.contains(&label.as_str());
            let stale = topics.iter().filter(|topic| !kept || !topic.starts_with(&prefix));
            messages.extend(stale.map(|topic| (topic.clone(), Vec::new())));
        }
        (tracker, messages)
    }

    /// The logger's availability topic, for the MQTT last will.
    pub fn status_topic(&self) -> String {
        self.discovery.status_topic()
    }

    /// What to publish, retained, after `message` was committed: the
    /// probe's configs when they are new or changed (and empty configs for
    /// quantities it no longer has), its state, its availability.
    pub fn observe(&mut self, message: &ReadingMessage) -> Vec<Retained> {
        let probe = &message.probe;
        let mut out = Vec::new();
        // A reading with values is good (a warning beside them does not
        // make the probe unavailable); one without is a probe not answering.
        if !message.values.is_empty() {
            let known_identity = self.sent.contains_key(probe) && message.serial_number.is_none();
            let configs = self.discovery.configs(message);
            if !known_identity && self.sent.get(probe) != Some(&configs) {
                let topics: BTreeSet<String> = configs.iter().map(|(t, _)| t.clone()).collect();
                let before = self.announced.probes.insert(probe.clone(), topics.clone()).unwrap_or_default();
                out.extend(before.difference(&topics).map(|topic| (topic.clone(), Vec::new())));
                out.extend(configs.iter().cloned());
                self.sent.insert(probe.clone(), configs);
                self.save();
            }
            out.extend(self.discovery.state(message));
        }
        let availability = if message.values.is_empty() { OFFLINE } else { ONLINE };
        out.push((self.discovery.availability_topic(probe), availability.as_bytes().to_vec()));
        out
    }

    fn save(&self) {
        let write = serde_json::to_vec_pretty(&self.announced).map_err(std::io::Error::other).and_then(|bytes| {
            let temporary = self.file.with_extension("tmp");
            std::fs::write(&temporary, bytes)?;
            std::fs::rename(&temporary, &self.file)
        });
        if let Err(error) = write {
            tracing::warn!(file = %self.file.display(), %error, "cannot record the Home Assistant configs");
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::message::{MeasuredValue, SCHEMA_VERSION};

    #[test]
    fn discovery_ids_are_allowed_and_distinct() {
        let names = ["river-01", "left bank", "a_b", "a__b", "a", "b", "x/y", "Ünï"];
        let ids: BTreeSet<String> = names.iter().map(|n| discovery_id(n)).collect();
        assert_eq!(ids.len(), names.len());
        for id in &ids {
            assert!(id.bytes().all(|b| b.is_ascii_alphanumeric() || b == b'_' || b == b'-'), "{id}");
            assert!(!id.contains("__"), "{id}");
        }
    }

    #[test]
    fn value_templates_address_the_quantity() {
        assert_eq!(value_template("temperature"), "{{ value_json.temperature }}");
        assert_eq!(value_template("a b"), "{{ value_json[\"a b\"] }}");
    }

    #[test]
    fn units_home_assistant_refuses_get_no_device_class() {
        assert_eq!(device_class("degC"), Some(("temperature", Some("°C"))));
        assert_eq!(device_class("pH"), Some(("ph", None)));
        for unit in ["NTU", "mg/L", "%", "ppb", "cells/mL", "1/ppt", ""] {
            assert_eq!(device_class(unit), None, "{unit}");
        }
    }

    fn reading(probe: &str, names: &[&str], serial: Option<&str>) -> ReadingMessage {
        ReadingMessage {
            schema: SCHEMA_VERSION,
            reading_id: 1,
            timestamp_ms: 0,
            station: "s".into(),
            probe: probe.into(),
            sensor: "model".into(),
            address: 1,
            serial_number: serial.map(str::to_owned),
            firmware: None,
            values: names.iter().map(|n| MeasuredValue::new(*n, 1.0, None)).collect(),
            retries: 0,
            error: None,
            bus: None,
            calibration_id: None,
        }
    }

    #[test]
    fn configs_are_sent_once_per_change_and_removed_ones_cleared() {
        let dir = tempfile_dir();
        let file = dir.join("announced.json");
        let discovery = Discovery::new(&HomeAssistantConfig::default(), "t", "s");
        let (mut tracker, at_start) = Tracker::start(discovery.clone(), &file, &["p", "q"]);
        assert_eq!(at_start.len(), 1, "only the station's config");
        let first = tracker.observe(&reading("p", &["a", "b"], Some("SN1")));
        assert_eq!(first.iter().filter(|(t, _)| t.ends_with("/config")).count(), 2);
        let again = tracker.observe(&reading("p", &["a", "b"], Some("SN1")));
        assert_eq!(again.iter().filter(|(t, _)| t.ends_with("/config")).count(), 0);
        let fewer = tracker.observe(&reading("p", &["a"], Some("SN1")));
        let cleared: Vec<&String> = fewer.iter().filter(|(_, p)| p.is_empty()).map(|(t, _)| t).collect();
        assert_eq!(cleared, [&discovery.config_topic("p", "b")]);
        tracker.observe(&reading("q", &["c"], None));
        drop(tracker);
        for _ in 0..2 {
            let (_, at_restart) = Tracker::start(discovery.clone(), &file, &["p"]);
            let cleared: Vec<&String> = at_restart.iter().filter(|(_, p)| p.is_empty()).map(|(t, _)| t).collect();
            assert_eq!(cleared, [&discovery.config_topic("q", "c")], "cleared at every start");
        }
        let elsewhere = Discovery::new(&HomeAssistantConfig { prefix: "other".into() }, "t", "s");
        let (_, moved) = Tracker::start(elsewhere, &file, &["p", "q"]);
        assert_eq!(moved.iter().filter(|(_, p)| p.is_empty()).count(), 2, "every config under the old prefix");
    }

    fn tempfile_dir() -> PathBuf {
        let dir =
            std::env::temp_dir().join(format!("ha-tracker-{}-{:?}", std::process::id(), std::thread::current().id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        dir
    }
}
