//! The sensor header: name, title, model, the manual and its revisions,
//! the serial line and the address range; and the references to manuals
//! (`since`, `source`, `manual`) throughout a sensor file.
//!
//! A header resolves only when all of it is valid: the serial line is
//! plausible (baud, data and stop bits), addresses are a range within
//! 1..=247 holding the default address, and each revision states the
//! software it documents, once. Every `since` and `manual` of the file names
//! the software of one of the sensor's manuals.

use std::collections::BTreeMap;

use crate::Spanned;

use crate::check::{check_name, check_role, check_text, resolve_figures};
use crate::diag::{Pos, Reporter};
use crate::document::{ManualDoc, ProvenanceDoc, SensorDoc, SerialDoc, SourceDoc, SpecFile};
use crate::model::{Manual, ModelAlias, Provenance, Revision, SerialClaim, Source};
use crate::names::escape;
use yosemitech_rtu::{CharFormat, DataBits, LineSettings, StopBits};

use super::command::command_key;

/// Every `since` and `manual` of a sensor file names one of its manuals' `software`.
pub(super) fn check_manual_refs(sensor: &SensorDoc, doc: &SpecFile, r: &mut Reporter<'_>) {
    let known: Vec<&str> = sensor
        .manual
        .iter()
        .chain(sensor.revisions.iter().map(|rev| &rev.manual))
        .filter_map(|m| m.software.as_ref().map(|s| s.value.as_str()))
        .collect();
    let check = |value: &Spanned<String>, key: String, r: &mut Reporter<'_>| {
        if !known.contains(&value.value.as_str()) {
            let help = if known.is_empty() {
                "state the manuals' software revisions: `sensor.manual.software` and `sensor.revisions`".to_string()
            } else {
                format!(
                    "the file's manuals document software {}; add the manual of software {} to `sensor.revisions`",
                    known.join(", "),
                    escape(&value.value)
                )
            };
            r.error(
                Pos::at(value),
                key,
                format!("no manual of this sensor documents software `{}`", escape(&value.value)),
                Some(help),
            );
        }
    };
    for (i, c) in doc.commands.iter().enumerate() {
        let key = command_key(i, c);
        if let Some(since) = &c.since {
            check(since, format!("{key}.since"), r);
        }
        if let Some(m) = c.source.as_ref().and_then(|s| s.manual.as_ref()) {
            check(m, format!("{key}.source.manual"), r);
        }
        for (j, e) in c.examples.iter().enumerate() {
            if let Some(m) = &e.manual {
                check(m, format!("{key}.examples[{j}].manual"), r);
            }
            for (k, cited) in e.also_in.iter().enumerate() {
                let cited_key = format!("{key}.examples[{j}].also_in[{k}].manual");
                check(&cited.manual, cited_key.clone(), r);
                let default = sensor.manual.as_ref().and_then(|m| m.software.as_ref()).map(|s| &s.value);
                if e.manual.is_none() && default == Some(&cited.manual.value) {
                    r.error(
                        Pos::at(&cited.manual),
                        cited_key,
                        format!(
                            "the example's own manual is the file's `manual` (software `{}`); `also_in` cites other manuals",
                            escape(&cited.manual.value)
                        ),
                        Some("remove this citation, or give the example the `manual:` it was printed in".into()),
                    );
                }
            }
        }
        for (j, e) in c.errata.iter().enumerate() {
            if let Some(m) = &e.manual {
                check(m, format!("{key}.errata[{j}].manual"), r);
            }
        }
    }
    for (i, e) in doc.errata.iter().enumerate() {
        if let Some(m) = &e.manual {
            check(m, format!("errata[{i}].manual"), r);
        }
    }
    if let Some(m) = doc.procedure.as_ref().and_then(|p| p.source.as_ref()).and_then(|s| s.manual.as_ref()) {
        check(m, "procedure.source.manual".into(), r);
    }
}

/// Facts from a driver carry no manual's figures and no example: no frame,
/// CRC or value that no source states. That holds for every command of a
/// sensor with `provenance`, and for a command with its own.
pub(super) fn check_unsourced(sensor: &SensorDoc, doc: &SpecFile, r: &mut Reporter<'_>) {
    let sensor_unsourced = sensor.manual.is_none();
    for (i, c) in doc.commands.iter().enumerate() {
        if !(sensor_unsourced || c.provenance.is_some()) {
            continue;
        }
        let key = command_key(i, c);
        let why = if sensor_unsourced {
            "the sensor has no manual"
        } else {
            "the command's facts come from its `provenance`"
        };
        if let Some(e) = c.examples.first() {
            let at = e.request.as_ref().or(e.response.as_ref()).map(Pos::at);
            r.error(
                at.unwrap_or_else(|| c.name.as_ref().or(c.uses.as_ref()).map_or(Pos::at(&sensor.name), Pos::at)),
                format!("{key}.examples"),
                format!("{why}: an example would be a frame no source prints"),
                Some("remove `examples`; the tests take values from each field's type and range".into()),
            );
        }
        if let Some(src) = &c.source
            && sensor_unsourced
        {
            r.error(
                Pos::at(&src.section),
                format!("{key}.source"),
                format!("{why}: there are no sections or figures to cite"),
                Some("name where the facts come from in `sensor.provenance` (or the command's `provenance`)".into()),
            );
        }
        for (j, f) in c.fields.iter().flat_map(|f| f.value.iter()).enumerate() {
            if let Some(e) = f.examples.first() {
                r.error(
                    Pos::at(&e.bytes),
                    format!("{key}.fields[{j}].examples"),
                    format!("{why}: a printed value needs a printed source"),
                    Some("remove the field's `examples`".into()),
                );
            }
        }
    }
    if sensor_unsourced
        && let Some(p) = &doc.procedure
        && let Some(src) = &p.source
    {
        r.error(
            Pos::at(&src.section),
            "procedure.source",
            "the sensor has no manual: there is no section to cite",
            Some("say where the steps and timings come from with `procedure.provenance`".into()),
        );
    }
}

/// A sensor's header, checked.
pub(super) struct Head {
    pub(super) name: String,
    pub(super) title: String,
    pub(super) doc: String,
    pub(super) model: Option<String>,
    pub(super) model_code: Option<String>,
    pub(super) also_model_codes: Vec<String>,
    pub(super) aliases: Vec<ModelAlias>,
    pub(super) manual: Option<Manual>,
    pub(super) provenance: Option<Provenance>,
    pub(super) revisions: Vec<Revision>,
    pub(super) serial: LineSettings,
    pub(super) min_address: u8,
    pub(super) max_address: u8,
    pub(super) default_address: u8,
}

pub(super) fn resolve_sensor_head(s: &SensorDoc, r: &mut Reporter<'_>) -> Option<Head> {
    let name_ok = check_name(&s.name, "sensor.name", r)
        && check_role(
            &s.name,
            "sensor.name",
            crate::names::check_sensor_name,
            "rename the sensor, e.g. `<name>_probe`",
            r,
        );
    let title = check_text(&s.title, "sensor.title", r);
    let doc = check_text(&s.doc, "sensor.doc", r);
    let manual = s.manual.as_ref().map(|m| resolve_manual(m, "sensor.manual", r));
    let provenance = s.provenance.as_ref().map(|p| resolve_provenance(p, "sensor.provenance", Pos::at(&s.name), r));
    let mut ok = name_ok;
    match (&s.manual, &s.provenance) {
        (None, None) => {
            r.error(
                Pos::at(&s.name),
                "sensor.manual",
                "a sensor states its `manual`, or its `provenance` when no Modbus manual covers the model",
                Some("add `manual: {title: ..., revision: ...}`, or `provenance: {sources: [...]}` naming the driver or logger the facts come from".into()),
            );
            ok = false;
        }
        (Some(m), Some(_)) => {
            r.error(
                Pos::at(&m.title),
                "sensor.provenance",
                "a sensor with a `manual` takes its facts from it: `provenance` is for a sensor without one",
                Some(
                    "remove `sensor.provenance`, or give `provenance` to the commands whose facts come from elsewhere"
                        .into(),
                ),
            );
            ok = false;
        }
        _ => {}
    }
    if s.manual.is_none()
        && let Some(first) = s.revisions.first()
    {
        r.error(
            Pos::at(&first.manual.title),
            "sensor.revisions",
            "a sensor without a `manual` has no other manual revisions",
            Some("make one of the manuals the sensor's `manual` and drop `provenance`".into()),
        );
        ok = false;
    }
    let model = s.model.as_ref().map(|m| check_text(m, "sensor.model", r));
    let model_code = s.model_code.as_ref().map(|m| check_model_code(m, "sensor.model_code", r));
    let also_model_codes: Vec<String> = s
        .also_model_codes
        .iter()
        .enumerate()
        .map(|(i, m)| check_model_code(m, &format!("sensor.also_model_codes[{i}]"), r))
        .collect();
    if let Some(first) = s.also_model_codes.first()
        && s.model_code.is_none()
    {
        r.error(
            Pos::at(first),
            "sensor.model_code",
            "`also_model_codes` lists codes besides the sensor's `model_code`, which is missing",
            Some("state the model's current code as `model_code`".into()),
        );
        ok = false;
    }
    let mut aliases = Vec::new();
    for (i, a) in s.aliases.iter().enumerate() {
        let key = format!("sensor.aliases[{i}]");
        let alias_model = check_text(&a.model, &format!("{key}.model"), r);
        if s.model.is_none() {
            r.error(
                Pos::at(&a.model),
                "sensor.model",
                "a sensor with `aliases` states its own `model` too",
                Some("add `model:` to `sensor`".into()),
            );
            ok = false;
        }
        let taken = s.model.as_ref().is_some_and(|m| m.value.eq_ignore_ascii_case(&a.model.value))
            || s.aliases[..i].iter().any(|b| b.model.value.eq_ignore_ascii_case(&a.model.value));
        if taken {
            r.error(
                Pos::at(&a.model),
                format!("{key}.model"),
                format!("model `{}` is named twice in this sensor", escape(&a.model.value)),
                Some("each alias is another model".into()),
            );
            ok = false;
        }
        let alias_code = a.model_code.as_ref().map(|m| check_model_code(m, &format!("{key}.model_code"), r));
        let doc = a.doc.as_ref().map(|d| check_text(d, &format!("{key}.doc"), r));
        let provenance = resolve_provenance(&a.provenance, &format!("{key}.provenance"), Pos::at(&a.model), r);
        aliases.push(ModelAlias { model: alias_model, model_code: alias_code, doc, provenance });
    }
    let serial = resolve_serial(&s.serial, "sensor.serial", r);
    ok &= serial.is_some();
    let mut revisions = Vec::new();
    let mut softwares: BTreeMap<String, Pos> = BTreeMap::new();
    if let Some(sw) = s.manual.as_ref().and_then(|m| m.software.as_ref()) {
        softwares.insert(sw.value.clone(), Pos::at(sw));
    }
    for (i, rev) in s.revisions.iter().enumerate() {
        let key = format!("sensor.revisions[{i}]");
        let rev_manual = resolve_manual(&rev.manual, &format!("{key}.manual"), r);
        match &rev.manual.software {
            None => {
                r.error(
                    Pos::at(&rev.manual.title),
                    format!("{key}.manual.software"),
                    "a revision's manual needs `software`, the firmware revision it documents",
                    Some("add `software: \"1.8\"` as the manual's scope line states it".into()),
                );
                ok = false;
            }
            Some(sw) => {
                if let Some(m) = s.manual.as_ref().filter(|m| m.software.is_none()) {
                    r.error(
                        Pos::at(&m.title),
                        "sensor.manual.software",
                        "a sensor with `revisions` states the `software` of its `manual` too",
                        Some("add `software:` to `sensor.manual`".into()),
                    );
                    ok = false;
                }
                if let Some(first) = softwares.insert(sw.value.clone(), Pos::at(sw)) {
                    r.error(
                        Pos::at(sw),
                        format!("{key}.manual.software"),
                        format!("software `{}` is already the revision of another manual", escape(&sw.value)),
                        Some(format!(
                            "each manual documents one software revision (the first is at line {})",
                            first.line
                        )),
                    );
                    ok = false;
                }
            }
        }
        let rev_serial = match &rev.serial {
            Some(sd) => resolve_serial(sd, &format!("{key}.serial"), r),
            None => serial,
        };
        let doc = rev.doc.as_ref().map(|d| check_text(d, &format!("{key}.doc"), r));
        match rev_serial {
            Some(serial) => revisions.push(Revision { manual: rev_manual, doc, serial }),
            None => ok = false,
        }
    }
    let min = s.addresses.min.value;
    let max = s.addresses.max.value;
    if !(1..=247).contains(&min) || !(1..=247).contains(&max) || min > max {
        r.error(
            Pos::at(&s.addresses.min),
            "sensor.addresses",
            format!("address range {min}..={max} is not a range of Modbus slave addresses"),
            Some("use min <= max within 1..=247".into()),
        );
        ok = false;
    }
    let default = s.default_address.value;
    if default < min || default > max {
        r.error(
            Pos::at(&s.default_address),
            "sensor.default_address",
            format!("default address {default} is outside {min}..={max}"),
            Some("the factory address must be one of `addresses`".into()),
        );
        ok = false;
    }
    if !ok {
        return None;
    }
    Some(Head {
        name: s.name.value.clone(),
        title,
        doc,
        model,
        model_code,
        also_model_codes,
        aliases,
        manual,
        provenance,
        revisions,
        serial: serial?,
        min_address: min as u8,
        max_address: max as u8,
        default_address: default as u8,
    })
}

fn check_model_code(m: &Spanned<String>, key: &str, r: &mut Reporter<'_>) -> String {
    let code = m.value.trim();
    if code.len() != 2 || !code.chars().all(|c| c.is_ascii_digit()) {
        r.error(
            Pos::at(m),
            key,
            format!("model code `{}` is not two digits", escape(&m.value)),
            Some("write the two digits after `YL` in the serial number, quoted: `model_code: \"09\"`".into()),
        );
    }
    code.to_string()
}

/// The sources of facts no manual states: at least one, each one line.
pub(super) fn resolve_provenance(p: &ProvenanceDoc, key: &str, at: Pos, r: &mut Reporter<'_>) -> Provenance {
    if p.sources.is_empty() {
        r.error(
            at,
            format!("{key}.sources"),
            "a provenance names at least one source",
            Some("add `sources: [\"<driver> <version>\", \"<its issue>\"]`: where a reader can check the facts".into()),
        );
    }
    Provenance {
        sources: p
            .sources
            .iter()
            .enumerate()
            .map(|(i, src)| check_text(src, &format!("{key}.sources[{i}]"), r))
            .collect(),
        doc: p.doc.as_ref().map(|d| check_text(d, &format!("{key}.doc"), r)),
    }
}

fn resolve_manual(m: &ManualDoc, key: &str, r: &mut Reporter<'_>) -> Manual {
    let mut serial_claims = Vec::new();
    for (i, claim) in m.serial_claims.iter().enumerate() {
        let claim_key = format!("{key}.serial_claims[{i}]");
        let serial = resolve_serial(&claim.serial, &format!("{claim_key}.serial"), r);
        let file = claim.file.as_ref().map(|f| check_text(f, &format!("{claim_key}.file"), r));
        let doc = claim.doc.as_ref().map(|d| check_text(d, &format!("{claim_key}.doc"), r));
        if let Some(serial) = serial {
            serial_claims.push(SerialClaim { serial, file, doc });
        }
    }
    Manual {
        title: check_text(&m.title, &format!("{key}.title"), r),
        revision: check_text(&m.revision, &format!("{key}.revision"), r),
        software: m.software.as_ref().map(|s| check_text(s, &format!("{key}.software"), r)),
        file: m.file.as_ref().map(|f| check_text(f, &format!("{key}.file"), r)),
        serial_claims,
    }
}

fn resolve_serial(serial: &SerialDoc, key: &str, r: &mut Reporter<'_>) -> Option<LineSettings> {
    let baud = serial.baud.value;
    let baud_ok = (300..=1_000_000).contains(&baud);
    if !baud_ok {
        r.error(
            Pos::at(&serial.baud),
            format!("{key}.baud"),
            format!("baud rate {baud} is not plausible"),
            Some("use 300..=1000000 (the manuals say 9600)".into()),
        );
    }
    let data_bits = DataBits::from_bits(serial.data_bits.value);
    let stop_bits = StopBits::from_bits(serial.stop_bits.value);
    for (bits, known, name, usual, spanned) in [
        (data_bits.map(DataBits::bits), "7 or 8", "data", 8, &serial.data_bits),
        (stop_bits.map(StopBits::bits), "1 or 2", "stop", 1, &serial.stop_bits),
    ] {
        if bits.is_none() {
            r.error(
                Pos::at(spanned),
                format!("{key}.{name}_bits"),
                format!("a serial line has {known} {name} bits, not {}", spanned.value),
                Some(format!("use {known} (the manuals say {usual})")),
            );
        }
    }
    let format = CharFormat { data_bits: data_bits?, parity: serial.parity.parity(), stop_bits: stop_bits? };
    baud_ok.then_some(LineSettings { baud, format })
}

pub(super) fn resolve_source(s: &SourceDoc, key: &str, r: &mut Reporter<'_>) -> Source {
    let at = Pos::at(&s.section);
    Source {
        section: check_text(&s.section, &format!("{key}.section"), r),
        figures: resolve_figures(&s.figures, &format!("{key}.figures"), at, r),
        manual: s.manual.as_ref().map(|m| check_text(m, &format!("{key}.manual"), r)),
    }
}
