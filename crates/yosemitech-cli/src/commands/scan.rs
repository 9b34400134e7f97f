//! `yosemitech scan`: find the probes on a bus.

use std::collections::BTreeMap;
use std::io::Write;
use std::time::Duration;

use serde_json::json;
use yosemitech_rtu::Error as RtuError;
use yosemitech_spec::Value;

use crate::catalog::{Catalog, common_probe, signature_read};
use crate::cli::{Global, ScanArgs};
use crate::error::{CliError, Result, request_failed};
use crate::{port, progress};

/// Parses `1-247`, `1,5,10-20` or `3` into sorted, distinct addresses.
pub fn parse_addresses(text: &str) -> Result<Vec<u8>> {
    let bad = |part: &str| {
        CliError::usage(format!("`{part}` in --addresses is not an address or a range"))
            .hint("write addresses 1..=247 as 1-247, 1,5,10-20 or 3")
    };
    let mut out = Vec::new();
    for part in text.split(',').map(str::trim).filter(|p| !p.is_empty()) {
        let (a, b) = match part.split_once('-') {
            Some((a, b)) => (a.trim(), b.trim()),
            None => (part, part),
        };
        let (a, b): (u32, u32) = (a.parse().map_err(|_| bad(part))?, b.parse().map_err(|_| bad(part))?);
        if a > b {
            return Err(bad(part));
        }
        for address in a..=b {
            out.push(port::check_address(address, "address")?);
        }
    }
    if out.is_empty() {
        return Err(bad(text));
    }
    out.sort_unstable();
    out.dedup();
    Ok(out)
}

/// What answered at one address.
struct Found {
    address: u8,
    serial_number: Option<String>,
    sensors: Vec<String>,
    note: Option<String>,
}

/// Runs `scan`.
pub fn run(catalog: &Catalog, global: &Global, args: &ScanArgs, out: &mut dyn Write) -> Result<()> {
    let addresses = parse_addresses(&args.addresses)?;
    let probe = common_probe(catalog).ok_or_else(|| {
        CliError::usage("the loaded sensors share no read command to probe with")
            .hint("scan needs a read every sensor has (get_sn); check the --spec files")
    })?;
    // The serial settings of the sensors that share the probe, if they
    // agree; else Yosemitech's 9600 8N1.
    let serial = catalog
        .entries()
        .iter()
        .filter(|e| e.sensor.command(&probe.name).is_some_and(|c| c.layout() == probe.layout()))
        .map(|e| e.sensor.serial)
        .reduce(|a, b| if a == b { a } else { port::YOSEMITECH_SERIAL })
        .unwrap_or(port::YOSEMITECH_SERIAL);
    let mut opened = port::open_with(&args.port, global, &serial, Duration::from_millis(100), 0)?;
    if !args.json {
        writeln!(out, "scanning {} address(es) on {} with {}", addresses.len(), opened.port, probe.name)?;
        out.flush()?;
    }
    let bar = progress::bar(addresses.len() as u64, "{msg:12} [{bar:30}] {pos}/{len} addresses");
    let mut found = Vec::new();
    for &address in &addresses {
        bar.set_message(format!("address {address}"));
        let request = probe
            .encode_request(address, &BTreeMap::new())
            .map_err(|e| CliError::usage(format!("cannot build the {} request: {e}", probe.name)))?;
        let answer = match opened.bus.call_raw(&request, &probe.layout()) {
            Ok(reply) => Some(Ok(probe.decode_response(address, reply).unwrap_or_default())),
            Err(e @ RtuError::Io(_)) => return Err(request_failed(&e, &opened.context(address, &probe.name))),
            Err(RtuError::Timeout { received }) if received.is_empty() => None,
            Err(e) => Some(Err(e)),
        };
        if let Some(answer) = answer {
            let mut item = Found { address, serial_number: None, sensors: Vec::new(), note: None };
            match answer {
                Ok(values) => {
                    item.serial_number = values.into_iter().find_map(|(_, v)| match v {
                        Value::Text(t) => Some(t),
                        _ => None,
                    });
                }
                Err(e) => item.note = Some(format!("answers, but not {}: {e}", probe.name)),
            }
            for entry in catalog.entries() {
                if let Some(read) = signature_read(catalog, &entry.sensor)
                    && let Ok(request) = read.encode_request(address, &BTreeMap::new())
                    && opened.bus.call_raw(&request, &read.layout()).is_ok()
                {
                    item.sensors.push(entry.sensor.name.clone());
                }
            }
            if !args.json {
                let line = found_line(&item);
                bar.suspend(|| writeln!(out, "{line}"))?;
            }
            found.push(item);
        }
        bar.inc(1);
    }
    bar.finish_and_clear();
    if args.json {
        let items: Vec<_> = found
            .iter()
            .map(|f| json!({ "address": f.address, "serial_number": f.serial_number, "sensors": f.sensors, "note": f.note }))
            .collect();
        writeln!(out, "{}", serde_json::to_string_pretty(&json!({ "devices": items })).unwrap_or_default())?;
    } else {
        writeln!(out, "found {} device(s)", found.len())?;
    }
    if found.is_empty() {
        return Err(CliError::device(format!("no device answered on {} at {}", opened.port, args.addresses))
            .hint("check power and wiring (A/B), and the baud rate (--baud); slow devices need a longer --timeout"));
    }
    Ok(())
}

fn found_line(f: &Found) -> String {
    let sensors = if f.sensors.is_empty() { "unknown kind".to_owned() } else { f.sensors.join(", ") };
    let mut line = format!("address {:3}  SN {:14}  {sensors}", f.address, f.serial_number.as_deref().unwrap_or("?"));
    if let Some(note) = &f.note {
        line.push_str(&format!("  ({note})"));
    }
    line
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_address_ranges() {
        assert_eq!(parse_addresses("1-3").unwrap(), [1, 2, 3]);
        assert_eq!(parse_addresses("5,1-2,2").unwrap(), [1, 2, 5]);
        assert_eq!(parse_addresses("1-247").unwrap().len(), 247);
        assert!(parse_addresses("0-3").is_err());
        assert!(parse_addresses("1-248").is_err());
        assert!(parse_addresses("3-1").is_err());
        assert!(parse_addresses("x").is_err());
        assert!(parse_addresses("").is_err());
    }
}
