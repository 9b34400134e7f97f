//! `yosemitech log` with `[mqtt.home_assistant]` against a real broker
//! (rumqttd always, mosquitto when installed; mandatory with
//! `YOSEMITECH_REQUIRE_MOSQUITTO=1`): a station of three simulated probes.
//! The retained discovery configs are checked key by key against Home
//! Assistant's documented MQTT sensor discovery schema and against what the
//! store holds; a probe that goes silent becomes unavailable, the logger's
//! clean stop and its death (the MQTT last will) make every entity
//! unavailable, and a probe removed from the station file has its configs
//! cleared at the next start.

use crate::station;

use std::collections::{BTreeMap, BTreeSet};
use std::time::Duration;

use serde_json::Value;
use station::{Station, start_logger, stored, terminate};
use yosemitech_spec::units;
use yosemitech_station::StoredReading;
use yosemitech_station::outbox::message;
use yosemitech_tests::broker::{Broker, BrokerKind, Subscriber, available, wait_until};

const STATION: &str = "river";
const DISCOVERY_PREFIX: &str = "homeassistant";
const PROBES: usize = 3;

/// Keys Home Assistant's MQTT sensor accepts in a discovery config
/// (<https://www.home-assistant.io/integrations/sensor.mqtt/>), and those of
/// its `device` object.
const SENSOR_KEYS: &[&str] = &[
    "availability",
    "availability_mode",
    "availability_template",
    "availability_topic",
    "device",
    "device_class",
    "enabled_by_default",
    "encoding",
    "entity_category",
    "entity_picture",
    "expire_after",
    "force_update",
    "icon",
    "json_attributes_template",
    "json_attributes_topic",
    "last_reset_value_template",
    "name",
    "object_id",
    "default_entity_id",
    "options",
    "origin",
    "payload_available",
    "payload_not_available",
    "platform",
    "qos",
    "state_class",
    "state_topic",
    "suggested_display_precision",
    "unique_id",
    "unit_of_measurement",
    "value_template",
];
/// Keys of an MQTT binary sensor's discovery config
/// (<https://www.home-assistant.io/integrations/binary_sensor.mqtt/>) this
/// station's own entity may use.
const BINARY_SENSOR_KEYS: &[&str] = &[
    "availability",
    "availability_topic",
    "device",
    "device_class",
    "enabled_by_default",
    "entity_category",
    "expire_after",
    "icon",
    "name",
    "off_delay",
    "payload_off",
    "payload_on",
    "qos",
    "state_topic",
    "unique_id",
    "value_template",
];
const DEVICE_KEYS: &[&str] = &[
    "configuration_url",
    "connections",
    "hw_version",
    "identifiers",
    "manufacturer",
    "model",
    "model_id",
    "name",
    "serial_number",
    "suggested_area",
    "sw_version",
    "via_device",
];

/// Home Assistant's sensor device classes of the quantities a water-quality
/// station has, with the units each accepts (`None`: unitless), from
/// <https://www.home-assistant.io/integrations/sensor/#device-class>.
fn accepted_units(device_class: &str) -> Option<&'static [Option<&'static str>]> {
    Some(match device_class {
        "temperature" => &[Some("°C"), Some("°F"), Some("K")],
        "ph" => &[None],
        "voltage" => &[Some("V"), Some("mV"), Some("µV"), Some("kV"), Some("MV")],
        "conductivity" => &[Some("S/cm"), Some("mS/cm"), Some("µS/cm")],
        "pressure" => &[
            Some("cbar"),
            Some("bar"),
            Some("hPa"),
            Some("mmHg"),
            Some("inHg"),
            Some("kPa"),
            Some("mbar"),
            Some("Pa"),
            Some("psi"),
        ],
        "distance" => &[Some("km"), Some("m"), Some("cm"), Some("mm"), Some("mi"), Some("yd"), Some("in"), Some("ft")],
        "duration" => &[Some("d"), Some("h"), Some("min"), Some("s"), Some("ms")],
        _ => return None,
    })
}

/// The last good reading of each probe, by label.
fn last_good(db: &std::path::Path) -> BTreeMap<String, StoredReading> {
    stored(db).into_iter().filter(|s| !message(s).values.is_empty()).map(|s| (s.reading.probe.clone(), s)).collect()
}

/// The last payload of each topic the subscriber got (retained or live).
fn latest(subscriber: &Subscriber) -> BTreeMap<String, Vec<u8>> {
    subscriber.received().into_iter().map(|r| (r.topic, r.payload)).collect()
}

fn text(payload: Option<&Vec<u8>>) -> Option<&str> {
    payload.and_then(|p| std::str::from_utf8(p).ok())
}

fn is_discovery_id(level: &str) -> bool {
    !level.is_empty() && level.bytes().all(|b| b.is_ascii_alphanumeric() || b == b'_' || b == b'-')
}

/// Checks one sensor config against Home Assistant's schema; returns the
/// (label-free) quantity name its template reads.
fn check_sensor_config(topic: &str, config: &Value) -> String {
    let levels: Vec<&str> = topic.split('/').collect();
    assert!(
        matches!(levels.as_slice(), [prefix, "sensor", node, object, "config"]
            if *prefix == DISCOVERY_PREFIX && is_discovery_id(node) && is_discovery_id(object)),
        "{topic}: <prefix>/sensor/<node_id>/<object_id>/config"
    );
    let object = config.as_object().unwrap_or_else(|| panic!("{topic}: a JSON object"));
    for key in object.keys() {
        assert!(SENSOR_KEYS.contains(&key.as_str()), "{topic}: {key} is not a key of an MQTT sensor");
    }
    for key in ["name", "unique_id", "state_topic", "value_template"] {
        assert!(object.get(key).and_then(Value::as_str).is_some_and(|s| !s.is_empty()), "{topic}: {key} string");
    }
    assert_eq!(config["state_class"], "measurement", "{topic}");
    // Availability: the list form, every entry a topic, both must be online.
    let availability = config["availability"].as_array().unwrap_or_else(|| panic!("{topic}: availability list"));
    assert_eq!(availability.len(), 2, "{topic}: the logger's and the probe's");
    for entry in availability {
        assert!(entry["topic"].as_str().is_some(), "{topic}: availability entry {entry}");
    }
    assert_eq!(config["availability_mode"], "all", "{topic}");
    assert!(
        object.get("availability_topic").is_none(),
        "{topic}: availability_topic and availability exclude each other"
    );
    // Device class: one Home Assistant has, with a unit it accepts for it.
    let unit = config.get("unit_of_measurement").map(|u| u.as_str().unwrap_or_else(|| panic!("{topic}: unit text")));
    if let Some(class) = config.get("device_class") {
        let class = class.as_str().unwrap_or_else(|| panic!("{topic}: device_class text"));
        let units =
            accepted_units(class).unwrap_or_else(|| panic!("{topic}: device class {class} of this test's table"));
        assert!(units.contains(&unit), "{topic}: {class} does not accept unit {unit:?}");
    }
    // The device object.
    let device = config["device"].as_object().unwrap_or_else(|| panic!("{topic}: device object"));
    for key in device.keys() {
        assert!(DEVICE_KEYS.contains(&key.as_str()), "{topic}: {key} is not a device key");
    }
    let identifiers = device["identifiers"].as_array().unwrap_or_else(|| panic!("{topic}: identifiers list"));
    assert!(!identifiers.is_empty() && identifiers.iter().all(|i| i.as_str().is_some()), "{topic}: identifiers");
    for key in ["manufacturer", "model", "name", "via_device"] {
        assert!(device.get(key).and_then(Value::as_str).is_some_and(|s| !s.is_empty()), "{topic}: device.{key}");
    }
    let template = config["value_template"].as_str().unwrap_or_default();
    template
        .strip_prefix("{{ value_json.")
        .and_then(|t| t.strip_suffix(" }}"))
        .unwrap_or_else(|| panic!("{topic}: value template {template}"))
        .to_owned()
}

/// The retained sensor configs a new subscriber gets, once `count` arrived.
fn retained_configs(broker: &Broker, count: usize) -> BTreeMap<String, Value> {
    let subscriber = Subscriber::start(broker, &format!("{DISCOVERY_PREFIX}/#"));
    let sensors = |s: &Subscriber| latest(s).into_iter().filter(|(t, _)| t.contains("/sensor/")).count();
    assert!(wait_until(|| sensors(&subscriber) >= count), "{count} retained sensor configs arrive");
    latest(&subscriber).into_iter().map(|(topic, payload)| (topic, serde_json::from_slice(&payload).unwrap())).collect()
}

fn home_assistant_discovery(kind: BrokerKind) {
    if !available(kind) {
        return;
    }
    let broker = Broker::start(kind, None);
    let own = Subscriber::start(&broker, &format!("{}/{STATION}/#", yosemitech_mqtt::topic::DEFAULT_TOPIC_PREFIX));
    let station = Station::simulated_probes(STATION, "200ms", PROBES);
    let mqtt = format!(
        "[mqtt]\nhost = \"127.0.0.1\"\nport = {}\nclient_id = \"station-{STATION}-{kind:?}\"\nkeep_alive_secs = 5\n\
         [mqtt.publisher]\npoll_interval_ms = 50\nreconnect_min_ms = 100\nreconnect_max_ms = 1000\n\
         [mqtt.home_assistant]\nprefix = \"{DISCOVERY_PREFIX}\"\n",
        broker.port
    );
    let probes_toml = station.toml.clone();
    let mut station = station;
    station.toml = format!("{probes_toml}{mqtt}");
    let config = station.write_config();
    let db = station.db.clone();

    // First run: every probe read a few times.
    let mut logger = start_logger(&config);
    let readings_of = |label: &str| stored(&db).iter().filter(|s| s.reading.probe == label).count();
    assert!(wait_until(|| (0..PROBES).all(|i| readings_of(&format!("p{i}")) >= 3)), "{kind:?}: every probe is read");
    let good = last_good(&db);
    assert_eq!(good.len(), PROBES, "{kind:?}: every probe has a good reading");
    let quantities: BTreeMap<String, Vec<String>> = good
        .iter()
        .map(|(label, s)| (label.clone(), message(s).values.into_iter().map(|v| v.name).collect()))
        .collect();
    let total: usize = quantities.values().map(Vec::len).sum();
    assert!(total >= PROBES, "{kind:?}: quantities to announce");

    // The retained configs, key by key.
    let configs = retained_configs(&broker, total);
    let station_configs: Vec<&Value> =
        configs.iter().filter(|(t, _)| t.contains("/binary_sensor/")).map(|(_, c)| c).collect();
    assert_eq!(station_configs.len(), 1, "{kind:?}: the station's own entity");
    let station_config = station_configs[0].as_object().unwrap();
    for key in station_config.keys() {
        assert!(BINARY_SENSOR_KEYS.contains(&key.as_str()), "{kind:?}: {key} is not a key of an MQTT binary sensor");
    }
    assert_eq!(station_configs[0]["device_class"], "connectivity", "{kind:?}");
    for key in ["unique_id", "state_topic", "payload_on", "payload_off"] {
        assert!(station_configs[0][key].is_string(), "{kind:?}: station config {key}");
    }
    let station_device = &station_configs[0]["device"]["identifiers"][0];
    let sensors: Vec<(&String, &Value)> = configs.iter().filter(|(t, _)| t.contains("/sensor/")).collect();
    assert_eq!(sensors.len(), total, "{kind:?}: one config per quantity");
    let mut unique_ids = BTreeSet::new();
    let mut devices: BTreeMap<String, Value> = BTreeMap::new();
    let states = latest(&own);
    for (topic, config) in &sensors {
        let quantity = check_sensor_config(topic, config);
        assert!(unique_ids.insert(config["unique_id"].as_str().unwrap().to_owned()), "{topic}: unique_id unique");
        assert_eq!(&config["device"]["via_device"], station_device, "{topic}: via the station");
        // Which probe: the one whose state topic it reads.
        let state_topic = config["state_topic"].as_str().unwrap();
        let (label, reading) = good
            .iter()
            .find(|(label, _)| state_topic.ends_with(&format!("/{label}/state")))
            .unwrap_or_else(|| panic!("{topic}: state topic {state_topic} of a probe"));
        let value = message(reading).values.into_iter().find(|v| v.name == quantity);
        let value = value.unwrap_or_else(|| panic!("{topic}: {quantity} is a quantity of {label}"));
        // The unit: Home Assistant's spelling of the stored one when classed, else the stored one.
        match (config.get("device_class"), config.get("unit_of_measurement"), &value.unit) {
            (None, unit, stored) => assert_eq!(unit.and_then(Value::as_str), stored.as_deref(), "{topic}: unit"),
            (Some(_), Some(_), None) => panic!("{topic}: a unit the reading does not have"),
            // Home Assistant's spelling of the same unit (`°C` for `degC`).
            (Some(_), Some(unit), Some(stored)) => {
                let (ha, ours) = (units::lookup(unit.as_str().unwrap()), units::lookup(stored));
                assert!(ha.is_some() && ha == ours, "{topic}: {unit} is not {stored}");
            }
            // Unitless classes (ph) of values whose unit names the quantity itself.
            (Some(_), None, _) => {}
        }
        // The device: the probe's identity as stored.
        let device = &config["device"];
        assert_eq!(device["model"], reading.reading.sensor.as_str(), "{topic}");
        assert_eq!(device["serial_number"].as_str(), reading.reading.serial_number.as_deref(), "{topic}");
        assert_eq!(device["sw_version"].as_str(), reading.reading.firmware.as_deref(), "{topic}");
        if let Some(other) = devices.insert(label.clone(), device.clone()) {
            assert_eq!(other, *device, "{topic}: one device per probe");
        }
        // The state topic is retained JSON holding the quantity.
        let state: Value =
            serde_json::from_slice(states.get(state_topic).unwrap_or_else(|| panic!("{state_topic}"))).unwrap();
        assert!(state[&quantity].is_number() || state[&quantity].is_null(), "{topic}: {quantity} in {state}");
        let availability: Vec<&str> =
            config["availability"].as_array().unwrap().iter().map(|a| a["topic"].as_str().unwrap()).collect();
        for topic in availability {
            assert_eq!(text(states.get(topic)), Some("online"), "{kind:?}: {topic} online");
        }
    }
    let identifiers: BTreeSet<String> = devices.values().map(|d| d["identifiers"].to_string()).collect();
    assert_eq!(identifiers.len(), PROBES, "{kind:?}: a device per probe");
    for (label, names) in &quantities {
        let announced =
            sensors.iter().filter(|(_, c)| c["state_topic"].as_str().unwrap().ends_with(&format!("/{label}/state")));
        assert_eq!(announced.count(), names.len(), "{kind:?}: every quantity of {label}");
    }

    let classes: BTreeSet<String> = sensors
        .iter()
        .map(|(_, c)| format!("{}:{}", c["device_class"], c.get("unit_of_measurement").unwrap_or(&Value::Null)))
        .collect();
    eprintln!("    {kind:?}: {total} sensor configs; device class:unit {classes:?}");
    eprintln!("    {kind:?}: e.g. {}", sensors[0].1);

    // A probe that goes silent becomes unavailable; the others stay available.
    let silent = PROBES - 1;
    let silent_label = format!("p{silent}");
    station.mute(station.addresses[silent]);
    let availability = |label: &str| {
        let topic = format!("{}/{STATION}/{label}/availability", yosemitech_mqtt::topic::DEFAULT_TOPIC_PREFIX);
        text(latest(&own).get(&topic)).map(str::to_owned)
    };
    assert!(wait_until(|| availability(&silent_label).as_deref() == Some("offline")), "{kind:?}: silent probe offline");
    for i in 0..silent {
        assert_eq!(availability(&format!("p{i}")).as_deref(), Some("online"), "{kind:?}: p{i} still online");
    }

    // A clean stop says the logger is offline.
    let status_topic = format!("{}/{STATION}/status", yosemitech_mqtt::topic::DEFAULT_TOPIC_PREFIX);
    assert_eq!(text(latest(&own).get(&status_topic)), Some("online"), "{kind:?}: logger online");
    assert_eq!(terminate(&mut logger, Duration::from_secs(30)), 0, "{kind:?}: SIGTERM stops cleanly");
    assert!(wait_until(|| text(latest(&own).get(&status_topic)) == Some("offline")), "{kind:?}: offline at stop");

    // Second run without the silent probe: its configs are cleared.
    let removed: Vec<String> = sensors
        .iter()
        .filter(|(_, c)| c["state_topic"].as_str().unwrap().ends_with(&format!("/{silent_label}/state")))
        .map(|(t, _)| (*t).clone())
        .collect();
    assert!(!removed.is_empty());
    let live = Subscriber::start(&broker, &format!("{DISCOVERY_PREFIX}/#"));
    let cut = probes_toml.rfind("[[bus.probe]]").unwrap();
    station.toml = format!("{}{mqtt}", &probes_toml[..cut]);
    let config = station.write_config();
    let mut logger = start_logger(&config);
    let cleared = || {
        let latest = latest(&live);
        removed.iter().all(|t| latest.get(t).is_some_and(Vec::is_empty))
    };
    assert!(wait_until(cleared), "{kind:?}: the removed probe's configs are cleared (empty, retained)");
    assert!(wait_until(|| text(latest(&own).get(&status_topic)) == Some("online")), "{kind:?}: online again");
    let remaining = configs_of_remaining(&quantities, &silent_label);
    let after = retained_configs(&broker, remaining);
    for topic in &removed {
        assert!(!after.contains_key(topic), "{kind:?}: {topic} is no longer retained");
    }
    assert_eq!(after.keys().filter(|t| t.contains("/sensor/")).count(), remaining, "{kind:?}: the others stay");

    // Killed: the broker sends the last will.
    logger.kill().unwrap();
    logger.wait().unwrap();
    assert!(wait_until(|| text(latest(&own).get(&status_topic)) == Some("offline")), "{kind:?}: last will");
}

fn configs_of_remaining(quantities: &BTreeMap<String, Vec<String>>, removed: &str) -> usize {
    quantities.iter().filter(|(label, _)| *label != removed).map(|(_, names)| names.len()).sum()
}

/// Every unit the spec's fields and unit table can give a value that gets a
/// device class gets one Home Assistant documents, with a unit it accepts.
#[test]
fn every_device_class_emitted_accepts_its_unit() {
    let spec = yosemitech_tests::spec();
    let field_units =
        spec.sensors.iter().flat_map(|s| &s.commands).flat_map(|c| &c.fields).filter_map(|f| f.unit.clone());
    let derived_units = spec.sensors.iter().flat_map(|s| &s.derived).filter_map(|d| d.unit.clone());
    let table_units = yosemitech_spec::units::UNITS
        .iter()
        .flat_map(|u| std::iter::once(u.symbol).chain(u.aliases.iter().copied()))
        .map(str::to_owned);
    let mut classed = 0;
    for unit in field_units.chain(derived_units).chain(table_units) {
        if let Some((class, ha_unit)) = yosemitech_mqtt::home_assistant::device_class(&unit) {
            let accepted =
                accepted_units(class).unwrap_or_else(|| panic!("{unit}: {class} is not in this test's table"));
            assert!(accepted.contains(&ha_unit), "{unit}: {class} does not accept {ha_unit:?}");
            classed += 1;
        }
    }
    assert!(classed > 0, "some units have a device class");
}

#[test]
fn home_assistant_discovery_rumqttd() {
    home_assistant_discovery(BrokerKind::Rumqttd);
}

#[test]
fn home_assistant_discovery_mosquitto() {
    home_assistant_discovery(BrokerKind::Mosquitto);
}
