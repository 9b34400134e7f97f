//! Identifying the probes on a bus as `yosemitech scan` does: the
//! serial-number reads of the loaded sensors, each distinct request sent
//! once, the model code its reply carries, reads that tell apart sensors
//! sharing a model code, and the version read that names the manual
//! covering the probe's firmware.

use std::collections::BTreeMap;

use yosemitech_rtu::{Client, Error as RtuError, FrameError, LineSettings, Transport, Version};
use yosemitech_spec::interp::decode_fields;
use yosemitech_spec::{CommandSpec, Manual, Role, Sensor, SerialNumberReply, Value};

use crate::failure_text;
use crate::transaction::{TransactionError, call_data};

/// Identifies probes with the reads of the sensors loaded, in load order
/// (the order breaks ties: which read goes first, which sensor is named first).
pub struct Identifier<'c> {
    loaded: Vec<&'c Sensor>,
    requests: Vec<SnRequest<'c>>,
}

impl<'c> Identifier<'c> {
    /// The reads of `loaded`, in their load order.
    pub fn new(loaded: impl IntoIterator<Item = &'c Sensor>) -> Self {
        let loaded: Vec<&'c Sensor> = loaded.into_iter().collect();
        let requests = sn_requests(&loaded);
        Self { loaded, requests }
    }

    /// The distinct serial-number requests, in the order they are sent:
    /// each one's register address and how many loaded sensors send it.
    /// Empty when no loaded sensor has a serial-number read (nothing can be
    /// identified).
    pub fn requests(&self) -> Vec<(u16, usize)> {
        self.requests.iter().map(|r| (r.command.address, r.sensors())).collect()
    }

    /// Identifies the device at `address`; `None` when nothing answers.
    /// Only a read that cannot be built ([`TransactionError::Request`]) or
    /// a failing port ([`TransactionError::Bus`] with an I/O error) is an
    /// error: silence, exceptions and garbled replies are what a bus scan
    /// meets, and are said in the result.
    pub fn identify<T: Transport>(
        &self,
        client: &mut Client<T>,
        address: u8,
    ) -> Result<Option<Identification<'c>>, TransactionError> {
        identify(&self.loaded, &self.requests, client, address)
    }
}

/// A manual's software revision as a sortable key (`1.10` after `1.9`);
/// what does not parse counts as 0.
pub fn software_revision(text: &str) -> (u16, u16) {
    let mut parts = text.trim().split('.').map(|p| p.trim().parse::<u16>().unwrap_or(0));
    (parts.next().unwrap_or(0), parts.next().unwrap_or(0))
}

/// A serial-number read and the loaded sensors that share its wire layout.
struct SnRead<'c> {
    /// The first sensor's command (they all encode and decode alike).
    command: &'c CommandSpec,
    /// The sensors whose serial-number read this is, in load order.
    sensors: Vec<&'c Sensor>,
}

/// True when two commands are the same on the wire: framing and fields.
fn same_wire(a: &CommandSpec, b: &CommandSpec) -> bool {
    a.layout() == b.layout()
        && a.fields.len() == b.fields.len()
        && a.fields.iter().zip(&b.fields).all(|(x, y)| x.offset == y.offset && x.kind == y.kind)
}

/// Groups `(sensor, command)` pairs by wire layout, the group of most
/// sensors first (ties: load order).
fn group<'c>(pairs: impl Iterator<Item = (&'c Sensor, &'c CommandSpec)>) -> Vec<SnRead<'c>> {
    let mut groups: Vec<SnRead<'c>> = Vec::new();
    for (sensor, command) in pairs {
        match groups.iter_mut().find(|g| same_wire(g.command, command)) {
            Some(g) => g.sensors.push(sensor),
            None => groups.push(SnRead { command, sensors: vec![sensor] }),
        }
    }
    groups.sort_by_key(|g| std::cmp::Reverse(g.sensors.len()));
    groups
}

/// The distinct serial-number reads of `sensors`, most common first.
fn sn_reads<'c>(sensors: &[&'c Sensor]) -> Vec<SnRead<'c>> {
    group(sensors.iter().filter_map(|sensor| {
        let command = sensor.command_with_role(Role::SerialNumber).filter(|c| c.fixed_slave.is_none())?;
        Some((*sensor, command))
    }))
}

/// One serial-number request on the wire and every loaded read that sends
/// it: reads that differ only in how they read the reply (the padding of
/// the text, say) send the same bytes, so `scan` sends it once and reads the
/// reply each of their ways.
struct SnRequest<'c> {
    /// The request's command (of its most common read).
    command: &'c CommandSpec,
    /// The reads that send it, the read of most sensors first.
    reads: Vec<SnRead<'c>>,
}

impl SnRequest<'_> {
    /// How many loaded sensors send this request.
    fn sensors(&self) -> usize {
        self.reads.iter().map(|r| r.sensors.len()).sum()
    }
}

/// True when two commands send the same request frame.
fn same_request(a: &CommandSpec, b: &CommandSpec) -> bool {
    (a.function, a.address, a.count, a.fixed_slave) == (b.function, b.address, b.count, b.fixed_slave)
}

/// The distinct serial-number requests of the loaded sensors, the request
/// of most sensors first (ties: load order).
fn sn_requests<'c>(sensors: &[&'c Sensor]) -> Vec<SnRequest<'c>> {
    let mut requests: Vec<SnRequest<'c>> = Vec::new();
    for read in sn_reads(sensors) {
        match requests.iter_mut().find(|r| same_request(r.command, read.command)) {
            Some(request) => request.reads.push(read),
            None => requests.push(SnRequest { command: read.command, reads: vec![read] }),
        }
    }
    requests.sort_by_key(|r| std::cmp::Reverse(r.sensors()));
    requests
}

/// `sensors` in the load order of `loaded`.
fn in_load_order<'c>(loaded: &[&'c Sensor], mut sensors: Vec<&'c Sensor>) -> Vec<&'c Sensor> {
    sensors.sort_by_key(|s| loaded.iter().position(|l| l.name == s.name));
    sensors.dedup_by(|a, b| a.name == b.name);
    sensors
}

/// What answered at one address, and what it is.
#[derive(Debug, Clone)]
pub struct Identification<'c> {
    /// Where it answered.
    pub address: u8,
    /// Its serial number as read (unescaped: see [`printable`]).
    pub serial_number: Option<String>,
    /// The model code its serial number carries.
    pub model_code: Option<String>,
    /// The sensors it may be; one when identified.
    pub candidates: Vec<&'c Sensor>,
    /// The sensor, when exactly one matches.
    pub identified: Option<&'c Sensor>,
    /// Why it is not identified.
    pub reason: Option<String>,
    /// Its hardware revision, if the version read answered one.
    pub hardware: Option<Version>,
    /// Its software revision, if the version read answered one.
    pub software: Option<Version>,
    /// The manual that covers its firmware.
    pub manual: Option<&'c Manual>,
    /// The models it is: one, or those of the identified sensor that share
    /// its model code and every command (no read tells them apart).
    pub models: Vec<String>,
    /// Why more than one model is named.
    pub models_reason: Option<String>,
    /// Reads sent to tell sensors that share a model code apart, with what came back.
    pub telling_reads: Vec<String>,
    /// What else it did: refusals, garbled replies, a firmware no manual covers.
    pub notes: Vec<String>,
}

/// A serial number as printed: control and non-ASCII characters escaped.
pub fn printable(text: &str) -> String {
    text.chars()
        .map(|c| if c.is_ascii_graphic() || c == ' ' { c.to_string() } else { format!("\\x{:02X}", u32::from(c)) })
        .collect()
}

/// The newest manual of `sensor` whose software revision is at most `software`.
pub fn manual_for(sensor: &Sensor, software: Version) -> Option<&Manual> {
    let probe = (u16::from(software.major), u16::from(software.minor));
    sensor
        .manuals()
        .filter_map(|m| m.software.as_deref().map(|sw| (software_revision(sw), m)))
        .filter(|(key, _)| *key <= probe)
        .max_by_key(|(key, _)| *key)
        .map(|(_, m)| m)
}

/// The serial settings most of `sensors` use (9600 8N1 for none).
pub fn common_serial<'c>(sensors: impl IntoIterator<Item = &'c Sensor>) -> LineSettings {
    let mut counts: Vec<(LineSettings, usize)> = Vec::new();
    for sensor in sensors {
        match counts.iter_mut().find(|(s, _)| *s == sensor.serial) {
            Some((_, n)) => *n += 1,
            None => counts.push((sensor.serial, 1)),
        }
    }
    counts.iter().max_by_key(|(_, n)| *n).map_or(LineSettings::default(), |(s, _)| *s)
}

/// What came back to a read.
enum Answer {
    /// The reply's register data.
    Data(Vec<u8>),
    /// Nothing: no device, or one that lacks the register.
    Silent,
    /// Something else (an exception, a garbled reply), as a note.
    Other(String),
}

/// Sends a read with no values to `address`.
fn probe<T: Transport>(client: &mut Client<T>, command: &CommandSpec, address: u8) -> Result<Answer, TransactionError> {
    let error = match call_data(client, command, address, &BTreeMap::new()) {
        Ok(data) => return Ok(Answer::Data(data.to_vec())),
        Err(error) => error,
    };
    let name = &command.name;
    Ok(match error {
        error @ (TransactionError::Request { .. } | TransactionError::Bus { error: RtuError::Io(_), .. }) => {
            return Err(error);
        }
        TransactionError::Bus { error: RtuError::Timeout { received: 0, .. }, .. } => Answer::Silent,
        TransactionError::Bus { error: e @ RtuError::Frame { error: FrameError::Exception { .. }, .. }, .. } => {
            Answer::Other(format!("refuses {name} ({})", failure_text(&e, client.last_reply())))
        }
        TransactionError::Bus { error, .. } => {
            Answer::Other(format!("answers {name} with {}", failure_text(&error, client.last_reply())))
        }
        TransactionError::Decode { message, .. } => {
            Answer::Other(format!("answers {name}, but not as specified: {message}"))
        }
    })
}

/// What one read of a serial-number request makes of the reply: the
/// serial number, the model code it carries and the read's sensors that
/// declare that code.
struct Reading<'c> {
    serial_number: Option<String>,
    model_code: Option<String>,
    matches: Vec<&'c Sensor>,
}

/// Reads a serial-number reply `read`'s way.
fn read_reply<'c>(read: &SnRead<'c>, data: &[u8]) -> Reading<'c> {
    let reply = SerialNumberReply::read(read.command, data);
    let model_code = reply.model_code(|c| read.sensors.iter().any(|s| s.declares_model_code(c))).map(str::to_owned);
    let matches = model_code
        .as_deref()
        .map_or_else(Vec::new, |c| read.sensors.iter().copied().filter(|s| s.declares_model_code(c)).collect());
    Reading { serial_number: reply.text, model_code, matches }
}

/// Identifies the device at `address`; `None` when nothing answers.
fn identify<'c, T: Transport>(
    loaded: &[&'c Sensor],
    requests: &[SnRequest<'c>],
    client: &mut Client<T>,
    address: u8,
) -> Result<Option<Identification<'c>>, TransactionError> {
    let mut found = Identification {
        address,
        serial_number: None,
        model_code: None,
        candidates: Vec::new(),
        identified: None,
        reason: None,
        hardware: None,
        software: None,
        manual: None,
        models: Vec::new(),
        models_reason: None,
        telling_reads: Vec::new(),
        notes: Vec::new(),
    };
    let mut answered = false;
    let mut sn = None;
    for request in requests {
        match probe(client, request.command, address)? {
            Answer::Data(data) => {
                sn = Some((request, data));
                break;
            }
            Answer::Silent => {}
            Answer::Other(note) => {
                answered = true;
                found.notes.push(note);
            }
        }
    }
    match sn {
        Some((request, data)) => {
            // Every read that sends this request reads the reply its own way.
            let readings: Vec<Reading<'c>> = request.reads.iter().map(|read| read_reply(read, &data)).collect();
            let matches = in_load_order(loaded, readings.iter().flat_map(|r| r.matches.iter().copied()).collect());
            // Shown: what the read that found a sensor makes of it, else the most common read.
            if let Some(reading) = readings.iter().find(|r| !r.matches.is_empty()).or(readings.first()) {
                found.serial_number = reading.serial_number.clone();
                found.model_code = reading.model_code.clone();
            }
            let code = found.model_code.clone();
            let at = format!("0x{:04X}", request.command.address);
            match matches.as_slice() {
                [one] => {
                    found.identified = Some(*one);
                    found.candidates = matches;
                }
                [] => {
                    let all = request.reads.iter().flat_map(|r| r.sensors.iter().copied()).collect();
                    found.candidates = in_load_order(loaded, all);
                    found.reason = Some(match &code {
                        Some(c) => format!(
                            "model code {c} is declared by no loaded sensor that reads its serial number at {at}"
                        ),
                        None => "the serial number carries no model code".to_owned(),
                    });
                }
                many => {
                    found.candidates = matches.clone();
                    match tell_apart(client, address, many, &mut found.telling_reads)? {
                        Some(one) => {
                            found.identified = Some(one);
                            found.candidates = vec![one];
                        }
                        None => {
                            found.reason = Some(format!(
                                "{} loaded sensors read their serial number at {at} and declare model code {}{}",
                                many.len(),
                                code.as_deref().unwrap_or("?"),
                                if found.telling_reads.is_empty() {
                                    String::new()
                                } else {
                                    format!(
                                        "; none answers as only one of them would ({})",
                                        found.telling_reads.join(", ")
                                    )
                                }
                            ));
                        }
                    }
                }
            }
        }
        None if answered => {
            // It refuses or garbles every serial-number read: one of the
            // loaded sensors without one, if any.
            found.candidates =
                loaded.iter().copied().filter(|s| s.command_with_role(Role::SerialNumber).is_none()).collect();
            found.reason = Some("it answers no serial-number read of the loaded sensors".to_owned());
        }
        None => return Ok(None),
    }

    // One more read: the revisions, with the version read most candidates share.
    let versions = group(found.candidates.iter().filter_map(|s| s.command_with_role(Role::Version).map(|c| (*s, c))));
    if let Some(read) = versions.first() {
        match probe(client, read.command, address)? {
            Answer::Data(data) => {
                let values: Vec<(String, Version)> = decode_fields(read.command, &data)
                    .into_iter()
                    .filter_map(|(name, v)| match v {
                        Value::Version(v) => Some((name, v)),
                        _ => None,
                    })
                    .collect();
                // The role reads hardware then software; names decide where the spec gives them.
                let named = |n: &str| values.iter().find(|(name, _)| name == n).map(|(_, v)| *v);
                found.software = named("software").or_else(|| values.last().map(|(_, v)| *v));
                found.hardware =
                    named("hardware").or_else(|| (values.len() > 1).then(|| values.first().map(|(_, v)| *v)).flatten());
            }
            Answer::Silent => found.notes.push(format!("no reply to {}", read.command.name)),
            Answer::Other(note) => found.notes.push(note),
        }
    }
    if let Some(sensor) = found.identified {
        let own = sensor.model.clone().unwrap_or_else(|| sensor.name.clone());
        let models: Vec<String> = match &found.model_code {
            Some(code) if sensor.declares_model_code(code) => {
                sensor.models_with_code(code).into_iter().map(str::to_owned).collect()
            }
            _ => vec![own],
        };
        if models.len() > 1 {
            found.models_reason = Some(format!(
                "{} share model code {} and every command: no read tells them apart",
                models.join(" and "),
                found.model_code.as_deref().unwrap_or("?")
            ));
        }
        found.models = models;
    }
    if let (Some(sensor), Some(software)) = (found.identified, found.software) {
        found.manual = manual_for(sensor, software);
        if found.manual.is_none() {
            let oldest = sensor.manuals().filter_map(|m| m.software.as_deref()).min_by_key(|sw| software_revision(sw));
            found.notes.push(match oldest {
                Some(oldest) => format!("no manual covers SW {software}: the oldest is for SW {oldest}"),
                None => "its manuals state no software revision".to_owned(),
            });
        }
    }
    Ok(Some(found))
}

/// A read that tells `sensor` apart from `others`: one whose register
/// block (address and count) none of them reads, a measurement read first.
/// A probe that lacks a block stays silent, so an answer names the sensor.
fn telling_read<'c>(sensor: &'c Sensor, others: &[&'c Sensor]) -> Option<&'c CommandSpec> {
    let block = |c: &CommandSpec| (c.function, c.address, c.count);
    let telling = |c: &&'c CommandSpec| {
        c.is_read()
            && !c.trigger
            && c.fixed_slave.is_none()
            && others.iter().all(|o| o.commands.iter().all(|d| block(d) != block(c)))
    };
    sensor.measurement_reads().find(telling).or_else(|| sensor.commands.iter().find(telling))
}

/// True when `scan` tells every one of `candidates` (sensors that read
/// their serial number alike and declare one model code) apart by reads:
/// however the probe answers, each step has a sensor with a telling read.
pub fn can_tell_apart(candidates: &[&Sensor]) -> bool {
    let mut left: Vec<&Sensor> = candidates.to_vec();
    while left.len() > 1 {
        let Some(i) = (0..left.len()).find(|&i| {
            let others: Vec<&Sensor> = left.iter().enumerate().filter(|(j, _)| *j != i).map(|(_, o)| *o).collect();
            telling_read(left[i], &others).is_some()
        }) else {
            return false;
        };
        left.remove(i);
    }
    true
}

/// Tells apart sensors that read their serial number alike and declare
/// the same model code, with the fewest reads: each candidate's telling
/// read in load order until one answers, and the last one left is named
/// without a read of its own once every other has stayed silent. `None`
/// when no read tells them apart (or the answers do not settle it).
fn tell_apart<'c, T: Transport>(
    client: &mut Client<T>,
    address: u8,
    candidates: &[&'c Sensor],
    sent: &mut Vec<String>,
) -> Result<Option<&'c Sensor>, TransactionError> {
    let mut left: Vec<&'c Sensor> = candidates.to_vec();
    while left.len() > 1 {
        let Some((i, read)) = left.iter().enumerate().find_map(|(i, s)| {
            let others: Vec<&Sensor> = left.iter().enumerate().filter(|(j, _)| *j != i).map(|(_, o)| *o).collect();
            telling_read(s, &others).map(|c| (i, c))
        }) else {
            return Ok(None);
        };
        let what = format!("{} at 0x{:04X} x{}", read.name, read.address, read.count);
        match probe(client, read, address)? {
            Answer::Data(_) => {
                sent.push(format!("{what}: answered"));
                return Ok(Some(left[i]));
            }
            Answer::Silent => {
                sent.push(format!("{what}: silent"));
                left.remove(i);
            }
            Answer::Other(note) => {
                sent.push(format!("{what}: {note}"));
                left.remove(i);
            }
        }
    }
    Ok(left.first().copied().filter(|_| !sent.is_empty()))
}
#[cfg(test)]
mod tests {
    use super::*;
    use yosemitech_spec::FieldKind;

    /// The workspace's sensors, in load order.
    fn loaded() -> Vec<&'static Sensor> {
        yosemitech_tests::spec().sensors.iter().collect()
    }

    #[test]
    fn groups_the_serial_number_reads_most_common_first() {
        let loaded = loaded();
        let reads = sn_reads(&loaded);
        assert!(!reads.is_empty());
        assert!(reads.windows(2).all(|w| w[0].sensors.len() >= w[1].sensors.len()));
        for s in &loaded {
            let Some(own) = s.command_with_role(Role::SerialNumber) else { continue };
            let groups: Vec<&SnRead<'_>> =
                reads.iter().filter(|r| r.sensors.iter().any(|g| g.name == s.name)).collect();
            assert_eq!(groups.len(), 1, "{} is in one group", s.name);
            assert!(same_wire(groups[0].command, own));
        }
    }

    #[test]
    fn sends_each_serial_number_request_once() {
        let loaded = loaded();
        let requests = sn_requests(&loaded);
        assert!(requests.windows(2).all(|w| w[0].sensors() >= w[1].sensors()));
        for (i, request) in requests.iter().enumerate() {
            assert!(!request.reads.is_empty());
            assert!(request.reads.iter().all(|r| same_request(r.command, request.command)));
            assert!(requests[i + 1..].iter().all(|other| !same_request(other.command, request.command)));
        }
        // Every read is in exactly one request.
        let reads: usize = requests.iter().map(|r| r.reads.len()).sum();
        assert_eq!(reads, sn_reads(&loaded).len());
    }

    #[test]
    fn reads_the_model_code_from_the_byte_before_or_the_text() {
        for s in loaded() {
            let (Some(command), Some(code)) = (s.command_with_role(Role::SerialNumber), &s.model_code) else {
                continue;
            };
            let field = command.named_fields().find(|f| matches!(f.kind, FieldKind::Ascii { .. })).unwrap();
            let sn = format!("YL{code}14010022");
            let values = BTreeMap::from([(field.display_name().to_owned(), Value::Text(sn.clone()))]);
            let mut data = yosemitech_spec::interp::encode_fields(command, &values).unwrap();
            let expected =
                SerialNumberReply { text: Some(sn.clone()), code_before: None, code_in_text: Some(code.clone()) };
            assert_eq!(SerialNumberReply::read(command, &data), expected, "{}", s.name);
            if field.offset > 0 {
                data[field.offset - 1] = u8::from_str_radix(code, 16).unwrap();
                assert_eq!(SerialNumberReply::read(command, &data).code_before.as_ref(), Some(code), "{}", s.name);
            }
        }
        // Garbage is shown, never a panic.
        let command = sn_reads(&loaded())[0].command;
        let garbage = vec![0xC3; 2 * usize::from(command.count)];
        let reply = SerialNumberReply::read(command, &garbage);
        assert!(printable(&reply.text.unwrap()).contains("\\x"));
        assert_eq!(reply.code_in_text, None);
    }

    #[test]
    fn names_the_newest_manual_the_firmware_reaches() {
        let v = |(major, minor): (u16, u16)| Version::new(major as u8, minor as u8);
        for s in loaded() {
            let mut softwares: Vec<(u16, u16)> =
                s.manuals().filter_map(|m| m.software.as_deref().map(software_revision)).collect();
            softwares.sort_unstable();
            for &(major, minor) in &softwares {
                let next = Some((major, minor + 1)).filter(|p| !softwares.contains(p));
                for probe in std::iter::once((major, minor)).chain(next) {
                    let m = manual_for(s, v(probe)).unwrap();
                    assert_eq!(m.software.as_deref().map(software_revision), Some((major, minor)), "{}", s.name);
                }
            }
            // Firmware older than every manual: none covers it.
            let older = match softwares.first() {
                Some(&(major, minor)) if minor > 0 => Some((major, minor - 1)),
                Some(&(major, _)) if major > 0 => Some((major - 1, 255)),
                _ => None,
            };
            if let Some(older) = older {
                assert!(manual_for(s, v(older)).is_none(), "{}", s.name);
            }
        }
    }
}
