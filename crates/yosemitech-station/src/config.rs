//! The station file (`station.toml`): buses, the probes on each, storage
//! and publishing, validated against the loaded spec.
//!
//! ```toml
//! station = "river-01"            # names the station in every reading
//!
//! [storage]
//! path = "station.sqlite"         # relative to this file's directory
//! max_size = "64MB"               # optional: beyond it readings are refused, as on a full disk
//!
//! [[bus]]
//! name = "rs485"
//! port = "/dev/ttyUSB0"           # a serial port ...
//! # tcp = "192.168.1.50:4196"     # ... or an RTU-over-TCP gateway
//! # baud = 9600                   # default: the probes' spec serial settings
//! # parity = "none"               # none | even | odd; default: the spec's
//! # timeout = "1s"                # reply timeout per request
//! # retries = 2                   # repeats of a failed request
//! # max_backoff = "10m"           # longest pause of a probe that keeps failing
//! # gap = "t3.5"                  # silence before each request; default t3.5, at least 4 ms
//!
//! [[bus.probe]]
//! label = "upstream-ph"           # unique in the station
//! sensor = "..."                  # a sensor of the spec or its model (`Y504`), as `yosemitech list` shows
//! address = 1
//! measurements = ["..."]          # field or read names; default: every measurement
//! interval = "15m"                # 500ms, 30s, 15m, 1h, 1h30m ...
//! align = true                    # on the clock: 00:00, 00:15, 00:30 ... UTC
//! # procedure = true              # follow the spec's procedure (default when it has one)
//! # inputs = { salinity = 35 }    # this probe's station inputs, over the station's [inputs]
//! # units = { temperature_c = "degF" }  # a measurement or derived quantity in another unit
//!                                 # of its dimension (the spec's unit table): stored,
//!                                 # exported and published converted, with the chosen unit
//!
//! # [inputs]                      # station inputs of derived quantities (`yosemitech list SENSOR`):
//! # salinity = 0.5                # every probe whose derived quantities take them; default: the spec's
//! # barometric_pressure = 98.2
//!
//! # [mqtt] ...                    # `yosemitech_mqtt::MqttConfig`: host, client_id, tls, credentials ...
//! # [mqtt.home_assistant]        # Home Assistant MQTT discovery; prefix = "homeassistant" by default
//!
//! # [monitor_my_watershed]        # publishing to Monitor My Watershed (docs/monitor-my-watershed.md)
//! # token = "environment"        # YOSEMITECH_MMW_TOKEN, or { file = "/etc/yosemitech/mmw.token" } (owner-only)
//! # sampling_feature = "..."     # the site's sampling feature UUID
//! # url = "https://monitormywatershed.org/api/data-stream/"
//! # utc_offset = 0               # whole hours the timestamps carry; default 0 (+00:00)
//! # batch = 50                   # records per request at most
//! # timeout = "30s"              # retry_min = "1s", retry_max = "5m", poll_interval = "1s"
//! # [monitor_my_watershed.results.upstream-ph]   # a probe label
//! # temperature_c = "..."        # measurement (or derived quantity) = its result UUID
//! ```
//!
//! Every error names the file, line and column of the offending value and
//! what is wrong with it; [`load`] reports all of them, not only the first.

use std::collections::{BTreeMap, BTreeSet};
use std::fmt;
use std::ops::Range;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Duration;

use serde::Deserialize;
use toml::Spanned;
use yosemitech_mqtt::MqttConfig;
use yosemitech_portal::{PortalConfig, TokenSource, is_uuid};
use yosemitech_rtu::{LineSettings, Parity};
use yosemitech_spec::Sensor;
use yosemitech_spec::beside::StationInputError;
use yosemitech_spec::lookup::{By, Lookup, find_sensor};
use yosemitech_spec::units::{self, ChoiceError, Conversion, Quantity};

pub use crate::amounts::{parse_duration, parse_size, show_duration};
use crate::plan;

/// Default reply timeout per request.
pub const DEFAULT_TIMEOUT: Duration = Duration::from_secs(1);
/// Default repeats of a failed request.
pub const DEFAULT_RETRIES: u32 = 2;
/// Default longest pause of a probe that keeps failing.
pub const DEFAULT_MAX_BACKOFF: Duration = Duration::from_secs(600);

/// One problem of a station file, located.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ConfigError {
    /// The file.
    pub file: PathBuf,
    /// 1-based line (0: the file as a whole, e.g. it cannot be read).
    pub line: usize,
    /// 1-based column, in characters.
    pub column: usize,
    /// What is wrong, and what would be right.
    pub message: String,
}

impl fmt::Display for ConfigError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.line == 0 {
            write!(f, "{}: {}", self.file.display(), self.message)
        } else {
            write!(f, "{}:{}:{}: {}", self.file.display(), self.line, self.column, self.message)
        }
    }
}

/// Every problem of a station file, in file order.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub struct ConfigErrors(pub Vec<ConfigError>);

impl fmt::Display for ConfigErrors {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        for (i, e) in self.0.iter().enumerate() {
            if i > 0 {
                writeln!(f)?;
            }
            write!(f, "{e}")?;
        }
        Ok(())
    }
}

/// How a bus is reached.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Link {
    /// A serial port with these settings.
    Serial {
        /// The device path (`/dev/ttyUSB0`, `COM3`).
        port: String,
        /// Character format and speed.
        serial: LineSettings,
    },
    /// An RTU-over-TCP gateway (raw RTU frames on a TCP stream).
    Tcp {
        /// `host:port`.
        address: String,
    },
}

impl fmt::Display for Link {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Link::Serial { port, .. } => f.write_str(port),
            Link::Tcp { address } => write!(f, "tcp://{address}"),
        }
    }
}

/// The silence a master keeps on the line before each request.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Gap {
    /// The client's default: t3.5 of the line, at least 4 ms at 19200 baud
    /// and below (the manuals disagree on the bits per character).
    #[default]
    Default,
    /// Exactly t3.5 of the line (`gap = "t3.5"`): the Modbus minimum.
    T35,
    /// This long (`gap = "5ms"`).
    Fixed(Duration),
}

/// A validated probe.
#[derive(Debug, Clone)]
pub struct ProbeConfig {
    /// Unique label in the station.
    pub label: String,
    /// The spec's sensor.
    pub sensor: Arc<Sensor>,
    /// Slave address, within the sensor's range.
    pub address: u8,
    /// The chosen measurement names (field names of the sensor), in spec order.
    pub measurements: Vec<String>,
    /// Time between samples (at least 1 ms).
    pub interval: Duration,
    /// Samples fall on multiples of `interval` since 00:00 UTC 1970-01-01.
    pub align: bool,
    /// Follow the spec's procedure (before, warm-up, averaged readings, after).
    pub procedure: bool,
    /// The station inputs of its derived quantities: the probe's own, else
    /// the station's; an input absent here takes the spec's default.
    pub inputs: BTreeMap<String, f64>,
    /// The units chosen for measurements or derived quantities, by name
    /// (`units = { name = "uS/cm" }`): readings carry the converted value
    /// and the chosen unit. Empty: every value in its spec unit.
    pub units: BTreeMap<String, Conversion>,
}

/// A validated bus.
#[derive(Debug, Clone)]
pub struct BusConfig {
    /// Unique name in the station.
    pub name: String,
    /// How it is reached.
    pub link: Link,
    /// Reply timeout per request.
    pub timeout: Duration,
    /// Repeats of a failed request.
    pub retries: u32,
    /// Longest pause of a probe that keeps failing.
    pub max_backoff: Duration,
    /// Silence kept before each request.
    pub gap: Gap,
    /// Its probes (at least one), in file order.
    pub probes: Vec<ProbeConfig>,
}

/// A validated station file.
#[derive(Debug, Clone)]
pub struct StationConfig {
    /// The file it was read from.
    pub file: PathBuf,
    /// The station's name.
    pub station: String,
    /// The SQLite file (relative paths resolved against the file's directory).
    pub storage: PathBuf,
    /// The most the store may grow to, in bytes (`[storage] max_size`):
    /// beyond it readings are refused, as on a full disk, until rows are
    /// deleted. `None`: as large as the disk allows.
    pub storage_max_size: Option<u64>,
    /// The buses (at least one), in file order.
    pub buses: Vec<BusConfig>,
    /// Publishing, when the file has an `[mqtt]` section (validated by
    /// `yosemitech_mqtt`, credentials included when they come from a file).
    pub mqtt: Option<MqttConfig>,
    /// Publishing to Monitor My Watershed, when the file has a
    /// `[monitor_my_watershed]` section: every result UUID bound to a
    /// measurement its probe reads, the token loaded once to check it.
    pub monitor_my_watershed: Option<PortalConfig>,
}

impl StationConfig {
    /// Every probe with its bus.
    pub fn probes(&self) -> impl Iterator<Item = (&BusConfig, &ProbeConfig)> {
        self.buses.iter().flat_map(|b| b.probes.iter().map(move |p| (b, p)))
    }
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawStation {
    station: Spanned<String>,
    storage: RawStorage,
    #[serde(default)]
    bus: Vec<Spanned<RawBus>>,
    mqtt: Option<Spanned<toml::Table>>,
    monitor_my_watershed: Option<Spanned<RawPortal>>,
    #[serde(default)]
    inputs: RawInputs,
}

/// `[monitor_my_watershed]` as written.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawPortal {
    url: Option<Spanned<String>>,
    #[serde(default)]
    allow_http: bool,
    token: Spanned<TokenSource>,
    sampling_feature: Spanned<String>,
    utc_offset: Option<Spanned<i64>>,
    batch: Option<Spanned<i64>>,
    timeout: Option<Spanned<String>>,
    retry_min: Option<Spanned<String>>,
    retry_max: Option<Spanned<String>>,
    poll_interval: Option<Spanned<String>>,
    /// Probe label -> measurement -> result UUID.
    #[serde(default)]
    results: BTreeMap<Spanned<String>, BTreeMap<Spanned<String>, Spanned<String>>>,
}

/// Station inputs as written: name -> value, both located.
type RawInputs = BTreeMap<Spanned<String>, Spanned<f64>>;

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawStorage {
    path: Spanned<String>,
    max_size: Option<Spanned<String>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawBus {
    name: Spanned<String>,
    port: Option<Spanned<String>>,
    tcp: Option<Spanned<String>>,
    baud: Option<Spanned<u32>>,
    parity: Option<Spanned<String>>,
    timeout: Option<Spanned<String>>,
    retries: Option<Spanned<u32>>,
    max_backoff: Option<Spanned<String>>,
    gap: Option<Spanned<String>>,
    #[serde(default)]
    probe: Vec<Spanned<RawProbe>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawProbe {
    label: Spanned<String>,
    sensor: Spanned<String>,
    address: Spanned<i64>,
    #[serde(default)]
    measurements: Vec<Spanned<String>>,
    interval: Spanned<String>,
    #[serde(default)]
    align: bool,
    procedure: Option<Spanned<bool>>,
    #[serde(default)]
    inputs: RawInputs,
    units: Option<BTreeMap<String, Spanned<String>>>,
}

/// The least `[storage] max_size` accepted: the schema and a few readings.
pub const MIN_STORAGE_SIZE: u64 = 64 * 1024;

/// Locates byte offsets of one file's text.
struct Locator<'a> {
    file: &'a Path,
    text: &'a str,
    errors: Vec<ConfigError>,
}

impl Locator<'_> {
    fn at(&self, span: Range<usize>, message: impl Into<String>) -> ConfigError {
        let start = span.start.min(self.text.len());
        let before = self.text.get(..start).unwrap_or_default();
        let line = before.matches('\n').count() + 1;
        let column = before.rsplit('\n').next().unwrap_or_default().chars().count() + 1;
        ConfigError { file: self.file.to_owned(), line, column, message: message.into() }
    }

    fn error(&mut self, span: Range<usize>, message: impl Into<String>) {
        let e = self.at(span, message);
        self.errors.push(e);
    }
}

/// Reads and validates the station file at `path` against `sensors` (the
/// loaded spec).
///
/// # Errors
///
/// The file cannot be read, is not TOML of this shape, or names what the
/// spec does not have: every problem found, located.
pub fn load(path: &Path, sensors: &[Arc<Sensor>]) -> Result<StationConfig, ConfigErrors> {
    let text = std::fs::read_to_string(path).map_err(|e| {
        ConfigErrors(vec![ConfigError {
            file: path.to_owned(),
            line: 0,
            column: 0,
            message: format!("cannot read it: {e}"),
        }])
    })?;
    parse(path, &text, sensors)
}

/// Validates `text`, the contents of the station file `path` (relative
/// storage paths resolve against `path`'s directory).
///
/// # Errors
///
/// As [`load`].
pub fn parse(path: &Path, text: &str, sensors: &[Arc<Sensor>]) -> Result<StationConfig, ConfigErrors> {
    let mut loc = Locator { file: path, text, errors: Vec::new() };
    let raw: RawStation = match toml::from_str(text) {
        Ok(raw) => raw,
        Err(e) => {
            let message = e.message().trim().to_owned();
            let error = match e.span() {
                Some(span) => loc.at(span, message),
                None => ConfigError { file: path.to_owned(), line: 0, column: 0, message },
            };
            return Err(ConfigErrors(vec![error]));
        }
    };
    if raw.station.get_ref().trim().is_empty() {
        loc.error(raw.station.span(), "the station name is empty");
    }
    let base = path.parent().unwrap_or_else(|| Path::new("."));
    let storage = base.join(raw.storage.path.get_ref());
    let storage_max_size = raw.storage.max_size.as_ref().and_then(|size| {
        match parse_size(size.get_ref()) {
            // Below a few pages SQLite cannot even hold the schema.
            Ok(bytes) if bytes < MIN_STORAGE_SIZE => {
                loc.error(
                    size.span(),
                    format!("max_size {} is below the least a store needs, {MIN_STORAGE_SIZE} bytes", size.get_ref()),
                );
                None
            }
            Ok(bytes) => Some(bytes),
            Err(e) => {
                loc.error(size.span(), e);
                None
            }
        }
    });
    if raw.storage.path.get_ref().trim().is_empty() {
        loc.error(raw.storage.path.span(), "the storage path is empty");
    }
    if raw.bus.is_empty() {
        loc.error(0..0, "no [[bus]]: a station needs at least one bus with a [[bus.probe]]");
    }
    let mut labels: BTreeMap<String, Range<usize>> = BTreeMap::new();
    let mut bus_names = BTreeSet::new();
    let mut buses = Vec::new();
    for bus in raw.bus {
        let bus_span = bus.span();
        let bus = bus.into_inner();
        if !bus_names.insert(bus.name.get_ref().clone()) {
            loc.error(bus.name.span(), format!("a second bus is named `{}`: bus names are unique", bus.name.get_ref()));
        }
        if bus.probe.is_empty() {
            loc.error(bus_span.clone(), format!("bus `{}` has no [[bus.probe]]", bus.name.get_ref()));
        }
        let mut probes = Vec::new();
        let mut addresses: BTreeSet<u8> = BTreeSet::new();
        for probe in bus.probe {
            let Some(probe) = validate_probe(&mut loc, probe.into_inner(), sensors) else { continue };
            if let Some(first) = labels.get(&probe.0.label) {
                let first = loc.at(first.clone(), "");
                loc.error(
                    probe.1.clone(),
                    format!("a second probe is labelled `{}` (the first is at line {})", probe.0.label, first.line),
                );
            } else {
                labels.insert(probe.0.label.clone(), probe.1.clone());
            }
            if !addresses.insert(probe.0.address) {
                loc.error(
                    probe.2.clone(),
                    format!("a second probe on bus `{}` has address {}", bus.name.get_ref(), probe.0.address),
                );
            }
            probes.push(probe.0);
        }
        let link = match (bus.port, bus.tcp) {
            (Some(port), None) => {
                let mut serial = probes.first().map_or(LineSettings::default(), |p| p.sensor.serial);
                if let Some(other) = probes.iter().find(|p| p.sensor.serial != serial)
                    && bus.baud.is_none()
                    && bus.parity.is_none()
                {
                    loc.error(
                        port.span(),
                        format!(
                            "the probes on bus `{}` have different serial settings in the spec (`{}` and `{}`): set baud and parity",
                            bus.name.get_ref(),
                            probes.first().map_or("", |p| p.label.as_str()),
                            other.label
                        ),
                    );
                }
                if let Some(baud) = &bus.baud {
                    if *baud.get_ref() == 0 {
                        loc.error(baud.span(), "baud 0 is not a speed");
                    }
                    serial.baud = *baud.get_ref();
                }
                if let Some(parity) = &bus.parity {
                    serial.format.parity = match parity.get_ref().as_str() {
                        "none" => Parity::None,
                        "even" => Parity::Even,
                        "odd" => Parity::Odd,
                        other => {
                            loc.error(parity.span(), format!("parity `{other}`: write none, even or odd"));
                            serial.format.parity
                        }
                    };
                }
                Link::Serial { port: port.into_inner(), serial }
            }
            (None, Some(tcp)) => {
                if bus.baud.is_some() || bus.parity.is_some() {
                    loc.error(tcp.span(), "baud and parity are the gateway's business: a tcp bus takes neither");
                }
                let address = tcp.get_ref().trim_start_matches("tcp://").to_owned();
                if address.rsplit_once(':').is_none_or(|(_, port)| port.parse::<u16>().is_err()) {
                    loc.error(tcp.span(), format!("`{}` is not HOST:PORT", tcp.get_ref()));
                }
                Link::Tcp { address }
            }
            (Some(port), Some(_)) => {
                loc.error(port.span(), "a bus has a serial `port` or a `tcp` gateway, not both");
                continue;
            }
            (None, None) => {
                loc.error(bus_span, format!("bus `{}` needs a serial `port` or a `tcp` gateway", bus.name.get_ref()));
                continue;
            }
        };
        let gap = match &bus.gap {
            None => Gap::Default,
            Some(g) if g.get_ref() == "t3.5" => Gap::T35,
            Some(g) => match parse_duration(g.get_ref()) {
                Ok(d) => Gap::Fixed(d),
                Err(e) => {
                    loc.error(g.span(), format!("{e}, or t3.5"));
                    Gap::Default
                }
            },
        };
        let mut duration = |d: &Option<Spanned<String>>, default: Duration| match d {
            None => default,
            Some(d) => match parse_duration(d.get_ref()) {
                Ok(v) if !v.is_zero() => v,
                Ok(_) => {
                    loc.error(d.span(), "a zero duration");
                    default
                }
                Err(e) => {
                    loc.error(d.span(), e);
                    default
                }
            },
        };
        let timeout = duration(&bus.timeout, DEFAULT_TIMEOUT);
        let max_backoff = duration(&bus.max_backoff, DEFAULT_MAX_BACKOFF);
        buses.push(BusConfig {
            name: bus.name.into_inner(),
            link,
            timeout,
            retries: bus.retries.map_or(DEFAULT_RETRIES, Spanned::into_inner),
            max_backoff,
            gap,
            probes,
        });
    }
    let mqtt = raw.mqtt.and_then(|table| {
        let span = table.span();
        // The table as written goes to the publisher's own configuration,
        // which says what is wrong (never a credential's value).
        let parsed = table.into_inner().try_into::<MqttConfig>().map_err(|e| e.message().trim().to_owned());
        match parsed.and_then(|c| c.check().map(|()| c).map_err(|e| e.to_string())) {
            Ok(c) => Some(c),
            Err(e) => {
                loc.error(span, format!("[mqtt]: {e}"));
                None
            }
        }
    });
    station_inputs(&mut loc, &raw.inputs, &mut buses);
    let monitor_my_watershed = raw.monitor_my_watershed.and_then(|raw| portal(&mut loc, raw, &buses));
    if loc.errors.is_empty() {
        Ok(StationConfig {
            file: path.to_owned(),
            station: raw.station.into_inner(),
            storage,
            storage_max_size,
            buses,
            mqtt,
            monitor_my_watershed,
        })
    } else {
        loc.errors.sort_by_key(|e| (e.line, e.column));
        Err(ConfigErrors(loc.errors))
    }
}

/// A probe, or `None` after recording why not; with the spans of its
/// label and address.
fn validate_probe(
    loc: &mut Locator<'_>,
    raw: RawProbe,
    sensors: &[Arc<Sensor>],
) -> Option<(ProbeConfig, Range<usize>, Range<usize>)> {
    // The words `read` and `simulate` take: a name or a model (`Y504`). Not
    // a prefix: a file outlives the spec, and a sensor added later could
    // make a prefix name another.
    let refs: Vec<&Sensor> = sensors.iter().map(|s| &**s).collect();
    let word = raw.sensor.get_ref();
    let found = match find_sensor(&refs, word) {
        Lookup::Found { index, by: By::Name | By::Model } => sensors.get(index),
        Lookup::Found { index, by: By::Prefix } => {
            let name = refs.get(index).map_or("", |s| s.name.as_str());
            loc.error(raw.sensor.span(), format!("no sensor `{word}` in the spec; did you mean `{name}`?"));
            return None;
        }
        Lookup::SameModel(indices) => {
            let names: Vec<&str> = indices.iter().filter_map(|&i| refs.get(i)).map(|s| s.name.as_str()).collect();
            loc.error(
                raw.sensor.span(),
                format!("model `{word}` is {} sensors: {}; name one of them", names.len(), names.join(", ")),
            );
            return None;
        }
        Lookup::Unknown { closest } => {
            let known: Vec<&str> =
                sensors.iter().filter(|s| s.measurement_reads().next().is_some()).map(|s| s.name.as_str()).collect();
            let guess = closest.map(|c| format!("did you mean `{c}`? ")).unwrap_or_default();
            loc.error(
                raw.sensor.span(),
                format!("no sensor `{word}` in the spec; {guess}sensors with measurements: {}", known.join(", ")),
            );
            return None;
        }
    };
    let sensor = found?;
    let mut ok = true;
    if raw.label.get_ref().trim().is_empty() {
        loc.error(raw.label.span(), "the probe label is empty");
        ok = false;
    }
    let (min, max) = (sensor.min_address.max(1), sensor.max_address.min(247));
    let address = match u8::try_from(*raw.address.get_ref()) {
        Ok(a) if (min..=max).contains(&a) => a,
        _ => {
            loc.error(
                raw.address.span(),
                format!(
                    "address {} is outside {min} to {max}, the addresses of `{}`",
                    raw.address.get_ref(),
                    sensor.name
                ),
            );
            ok = false;
            0
        }
    };
    let mut names = Vec::new();
    for m in &raw.measurements {
        match plan::choose(sensor, &[m.get_ref()]) {
            Ok(_) => names.push(m.get_ref().clone()),
            Err(e) => {
                loc.error(m.span(), e.to_string());
                ok = false;
            }
        }
    }
    let measurements = match plan::choose(sensor, &names) {
        Ok(chosen) => chosen.into_iter().map(str::to_owned).collect(),
        Err(e) => {
            loc.error(raw.sensor.span(), e.to_string());
            ok = false;
            Vec::new()
        }
    };
    let interval = match parse_duration(raw.interval.get_ref()) {
        Ok(d) if !d.is_zero() => d,
        Ok(_) => {
            loc.error(raw.interval.span(), "the interval is zero");
            ok = false;
            Duration::ZERO
        }
        Err(e) => {
            loc.error(raw.interval.span(), e);
            ok = false;
            Duration::ZERO
        }
    };
    let procedure = match &raw.procedure {
        Some(p) if *p.get_ref() && sensor.procedure.is_none() => {
            loc.error(p.span(), format!("sensor `{}` has no procedure in the spec", sensor.name));
            ok = false;
            false
        }
        Some(p) => *p.get_ref(),
        None => sensor.procedure.is_some(),
    };
    let mut inputs = BTreeMap::new();
    for (name, value) in &raw.inputs {
        match yosemitech_spec::beside::check_station_input(sensor, name.get_ref(), *value.get_ref()) {
            Ok(()) => {
                inputs.insert(name.get_ref().clone(), *value.get_ref());
            }
            Err(e) => {
                let span = if matches!(e, StationInputError::Unknown { .. }) { name.span() } else { value.span() };
                loc.error(span, format!("probe `{}`: {e}", raw.label.get_ref()));
                ok = false;
            }
        }
    }
    let units = match &raw.units {
        Some(chosen) => match probe_units(loc, raw.label.get_ref(), sensor, &measurements, chosen) {
            Some(units) => units,
            None => {
                ok = false;
                BTreeMap::new()
            }
        },
        None => BTreeMap::new(),
    };
    let spans = (raw.label.span(), raw.address.span());
    ok.then(|| {
        (
            ProbeConfig {
                label: raw.label.into_inner(),
                sensor: Arc::clone(sensor),
                address,
                measurements,
                interval,
                align: raw.align,
                procedure,
                inputs,
                units,
            },
            spans.0,
            spans.1,
        )
    })
}

/// The names a probe's readings carry: its measurements and the derived
/// quantities whose inputs its plan reads.
pub fn reading_names(probe: &ProbeConfig) -> Vec<String> {
    let chosen: Vec<&str> = probe.measurements.iter().map(String::as_str).collect();
    let planned = plan::plan(&probe.sensor, &chosen);
    let read = |c: &str, f: &str| planned.reads.iter().any(|r| r.command.name == c && r.fields.contains(&f));
    let derived = yosemitech_spec::beside::beside(&probe.sensor, &read, &|_, _| None, &|_| None);
    probe.measurements.iter().cloned().chain(derived.iter().map(|d| d.quantity.name.clone())).collect()
}

/// `[monitor_my_watershed]`, or `None` after recording what is wrong.
fn portal(loc: &mut Locator<'_>, raw: Spanned<RawPortal>, buses: &[BusConfig]) -> Option<PortalConfig> {
    let section = raw.span();
    let raw = raw.into_inner();
    let before = loc.errors.len();
    let what = "[monitor_my_watershed]";
    let token = raw.token.get_ref().clone();
    // Loaded to check it is there and readable, then dropped: the
    // publisher loads it again when it starts. The error names no token.
    if let Err(e) = token.load() {
        loc.error(raw.token.span(), format!("{what} token: {e}"));
    }
    let feature = raw.sampling_feature.get_ref().trim().to_owned();
    if !is_uuid(&feature) {
        loc.error(
            raw.sampling_feature.span(),
            format!("{what} sampling_feature `{feature}` is not a UUID (8-4-4-4-12 hexadecimal digits)"),
        );
    }
    let mut config = PortalConfig::new(token, feature);
    if let Some(url) = &raw.url {
        let text = url.get_ref().trim();
        if text.starts_with("https://") || (raw.allow_http && text.starts_with("http://")) {
            config.url = text.to_owned();
        } else if text.starts_with("http://") {
            loc.error(
                url.span(),
                format!(
                    "{what} url `{text}`: the token travels with every request, so use https:// \
                         (allow_http = true sends it in the clear, for a portal on a private network)"
                ),
            );
        } else {
            loc.error(url.span(), format!("{what} url `{text}` is not an https:// URL"));
        }
    }
    if let Some(offset) = &raw.utc_offset {
        match i8::try_from(*offset.get_ref()) {
            Ok(hours) if (-12..=14).contains(&hours) => config.utc_offset_hours = hours,
            _ => loc.error(
                offset.span(),
                format!("{what} utc_offset {} is not whole hours in -12 to 14", offset.get_ref()),
            ),
        }
    }
    if let Some(batch) = &raw.batch {
        match usize::try_from(*batch.get_ref()) {
            Ok(n) if (1..=1000).contains(&n) => config.batch = n,
            _ => loc.error(batch.span(), format!("{what} batch {} is not 1 to 1000 records", batch.get_ref())),
        }
    }
    for (raw, field) in [
        (&raw.timeout, &mut config.timeout),
        (&raw.retry_min, &mut config.retry_min),
        (&raw.retry_max, &mut config.retry_max),
        (&raw.poll_interval, &mut config.poll_interval),
    ] {
        if let Some(d) = raw {
            match parse_duration(d.get_ref()) {
                Ok(d) if !d.is_zero() => *field = d,
                Ok(_) => loc.error(d.span(), format!("{what}: a zero duration")),
                Err(e) => loc.error(d.span(), format!("{what}: {e}")),
            }
        }
    }
    if config.retry_min > config.retry_max {
        let span = raw.retry_min.as_ref().map_or(section.clone(), Spanned::span);
        loc.error(span, format!("{what} retry_min is longer than retry_max"));
    }
    if raw.results.is_empty() {
        loc.error(
            section.clone(),
            format!("{what} binds no result: add [monitor_my_watershed.results.<probe label>] with measurement = \"<result uuid>\""),
        );
    }
    let mut seen: BTreeMap<String, (String, String)> = BTreeMap::new();
    for (label, bindings) in &raw.results {
        let Some(probe) = buses.iter().flat_map(|b| &b.probes).find(|p| p.label == *label.get_ref()) else {
            let labels: Vec<&str> = buses.iter().flat_map(|b| &b.probes).map(|p| p.label.as_str()).collect();
            loc.error(
                label.span(),
                format!("{what}: no probe is labelled `{}`; the probes are {}", label.get_ref(), labels.join(", ")),
            );
            continue;
        };
        let names = reading_names(probe);
        let mut bound = BTreeMap::new();
        for (name, uuid) in bindings {
            let (name_text, uuid_text) = (name.get_ref(), uuid.get_ref().trim());
            if !names.contains(name_text) {
                loc.error(
                    name.span(),
                    format!("{what}: probe `{}` reads no `{name_text}`; it reads {}", probe.label, names.join(", ")),
                );
            }
            if !is_uuid(uuid_text) {
                loc.error(
                    uuid.span(),
                    format!("{what}: result `{uuid_text}` is not a UUID (8-4-4-4-12 hexadecimal digits)"),
                );
            } else if let Some((other_probe, other_name)) =
                seen.insert(uuid_text.to_ascii_lowercase(), (probe.label.clone(), name_text.clone()))
            {
                loc.error(
                    uuid.span(),
                    format!(
                        "{what}: result {uuid_text} is bound twice, here and to `{other_name}` of probe `{other_probe}`"
                    ),
                );
            }
            bound.insert(name_text.clone(), uuid_text.to_owned());
        }
        config.results.insert(probe.label.clone(), bound);
    }
    (loc.errors.len() == before).then_some(config)
}

/// Checks the station's `[inputs]` against every probe and gives each
/// probe those its derived quantities take, under its own.
fn station_inputs(loc: &mut Locator<'_>, raw: &RawInputs, buses: &mut [BusConfig]) {
    for (name, value) in raw {
        let (name_span, name, value_span, value) = (name.span(), name.get_ref(), value.span(), *value.get_ref());
        let mut used = false;
        for probe in buses.iter_mut().flat_map(|b| b.probes.iter_mut()) {
            let takes = yosemitech_spec::beside::station_inputs(&probe.sensor).iter().any(|i| i.name == name);
            if !takes {
                continue;
            }
            used = true;
            if let Err(e) = yosemitech_spec::beside::check_station_input(&probe.sensor, name, value) {
                loc.error(value_span.clone(), format!("[inputs] for probe `{}`: {e}", probe.label));
            }
            probe.inputs.entry(name.clone()).or_insert(value);
        }
        if !used {
            let mut known: Vec<String> = buses
                .iter()
                .flat_map(|b| &b.probes)
                .flat_map(|p| yosemitech_spec::beside::station_inputs(&p.sensor).into_iter().map(|i| i.describe()))
                .collect();
            known.sort();
            known.dedup();
            let takes = if known.is_empty() {
                "no probe of the station has a derived quantity with a station input".to_owned()
            } else {
                format!("the probes' station inputs: {}", known.join(", "))
            };
            loc.error(name_span, format!("[inputs]: no derived quantity of any probe takes `{name}`; {takes}"));
        }
    }
}

/// A probe's `units`, checked against its measurements and the sensor's
/// derived quantities through the spec's unit table; `None` after
/// recording every entry that cannot be given.
fn probe_units(
    loc: &mut Locator<'_>,
    label: &str,
    sensor: &Sensor,
    measurements: &[String],
    chosen: &BTreeMap<String, Spanned<String>>,
) -> Option<BTreeMap<String, Conversion>> {
    // The unit of a measurement is its field's in the read the planner takes it from.
    let names: Vec<&str> = measurements.iter().map(String::as_str).collect();
    let planned = plan::plan(sensor, &names);
    let quantities: Vec<Quantity<'_>> = planned
        .reads
        .iter()
        .flat_map(|r| {
            r.fields.iter().map(|f| Quantity { name: f, unit: r.command.field(f).and_then(|f| f.unit.as_deref()) })
        })
        .chain(sensor.derived.iter().map(|d| Quantity { name: &d.name, unit: d.unit.as_deref() }))
        .collect();
    let mut out = BTreeMap::new();
    let mut ok = true;
    for (name, unit) in chosen {
        match units::choose_named(name, unit.get_ref(), &quantities) {
            Ok(c) => {
                out.insert(name.clone(), c);
            }
            Err(e) => {
                let hint = match &e {
                    // Unit symbols are case-sensitive (mS is not MS): a spelling
                    // that differs only in case is the likeliest meaning.
                    ChoiceError::UnknownUnit { unit } => {
                        match units::spellings().find(|s| s.eq_ignore_ascii_case(unit)) {
                            Some(same) => format!(" (did you mean `{same}`?)"),
                            None => format!(
                                " (units that convert: {})",
                                units::UNITS.iter().map(|u| u.symbol).collect::<Vec<_>>().join(", ")
                            ),
                        }
                    }
                    _ => String::new(),
                };
                loc.error(unit.span(), format!("probe `{label}`: units.{name} = \"{}\": {e}{hint}", unit.get_ref()));
                ok = false;
            }
        }
    }
    ok.then_some(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_storage_cap_too_small_or_misspelt_is_located() {
        let dir = tempfile::tempdir().unwrap();
        for (size, says) in [("1kB", "below the least"), ("lots", "not a size")] {
            let path = dir.path().join("station.toml");
            let text = format!("station = \"s\"\n[storage]\npath = \"s.sqlite\"\nmax_size = \"{size}\"\n");
            std::fs::write(&path, text).unwrap();
            let Err(ConfigErrors(errors)) = load(&path, &[]) else { panic!("{size} accepted") };
            assert!(errors.iter().any(|e| e.line == 4 && e.message.contains(says)), "{size}: {errors:?}");
        }
    }
}
