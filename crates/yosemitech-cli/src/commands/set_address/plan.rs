//! `yosemitech set-address --plan`: address a bus of probes that all leave
//! the factory at one address, connected one at a time.
//!
//! Each probe is identified at the factory address as `scan` identifies it,
//! given the next free address of the plan (spaced apart: probes at
//! neighbouring addresses have been seen to answer for each other) and
//! verified there by its serial number. The probes addressed before stay
//! on the bus, away from the factory address, so the next one arrives alone.

use std::fmt::Write as _;
use std::fs::OpenOptions;
use std::io::{self, BufRead, Write};
use std::path::Path;
use std::time::SystemTime;

use yosemitech::procedures::address::AddressChangeError;
use yosemitech_rtu::Version;
use yosemitech_spec::{CommandSpec, Sensor};

use super::{ChangeFrames, SetAddressArgs, address_commands, explain, pick_commands};
use crate::catalog::Catalog;
use crate::confirm::{confirm, ensure_can_ask};
use crate::error::{CliError, Result};
use crate::identified::{found_line, identify_at};
use crate::port::parse_addresses;
use crate::port::{self, check_address};
use crate::time;
use yosemitech_ops::{Identification, common_serial, printable};

/// One probe of the bus table.
struct Addressed<'c> {
    address: u8,
    serial_number: Option<String>,
    models: Vec<String>,
    software: Option<Version>,
    sensor: Option<&'c Sensor>,
    candidates: Vec<&'c Sensor>,
}

/// The addresses the plan gives, in order: `--addresses`, else `--first`
/// (default `from` + 2) and every `--step` up to 247; never `from` itself,
/// where the next probe arrives.
fn planned_addresses(args: &SetAddressArgs, from: u8) -> Result<Vec<u8>> {
    let plan = if let Some(list) = &args.addresses {
        parse_addresses(list)?
    } else {
        if args.step == 0 {
            return Err(CliError::usage("--step 0 would give every probe one address").hint("use --step 2 or more"));
        }
        let first = check_address(args.first.unwrap_or(u32::from(from) + 2), "--first")?;
        (u32::from(first)..=247).step_by(args.step as usize).filter_map(|a| u8::try_from(a).ok()).collect()
    };
    if plan.contains(&from) {
        return Err(CliError::usage(format!("the plan gives address {from}, where every new probe arrives"))
            .hint("leave the factory address out of --addresses, or give --from another address"));
    }
    Ok(plan)
}

/// `3 (0x03)`: the vendor's tool shows decimal, many sketches hex.
fn both_bases(address: u8) -> String {
    format!("{address} (0x{address:02X})")
}

/// Waits for the user to connect the next probe: false when they are done
/// (`d`, `q` or the end of input).
fn next_probe_connected(number: usize, from: u8) -> Result<bool> {
    let mut err = io::stderr().lock();
    let _ = write!(
        err,
        "\nprobe {number}: connect it alone at address {from} (leave the probes done so far on the bus), \
         then press Enter (d: done) "
    );
    let _ = err.flush();
    drop(err);
    let mut line = String::new();
    let read =
        io::stdin().lock().read_line(&mut line).map_err(|e| CliError::device(format!("cannot read stdin: {e}")))?;
    Ok(read > 0 && !matches!(line.trim().to_ascii_lowercase().as_str(), "d" | "done" | "q" | "quit"))
}

/// Runs `set-address --plan`.
pub fn run(catalog: &Catalog, args: &SetAddressArgs, out: &mut dyn Write) -> Result<()> {
    let from = check_address(args.from.unwrap_or(1), "--from")?;
    let plan = planned_addresses(args, from)?;
    let wanted = match args.count {
        Some(0) => return Err(CliError::usage("--count 0 addresses no probe")),
        Some(n) if n as usize > plan.len() => {
            return Err(CliError::usage(format!("--count {n} but the plan has only {} addresses", plan.len()))
                .hint("give more --addresses, or a smaller --step"));
        }
        Some(n) => n as usize,
        None => plan.len(),
    };
    if let Some(path) = &args.station_toml
        && path.exists()
    {
        return Err(CliError::usage(format!("{} exists; the draft is not written over a file", path.display()))
            .hint("give --station-toml a new file"));
    }
    let (sensor, _, _) = pick_commands(catalog, args.sensor.as_deref())?;
    let serial = if args.sensor.is_some() {
        sensor.serial
    } else {
        common_serial(catalog.entries().iter().map(|e| e.sensor.as_ref()))
    };
    ensure_can_ask(args.yes, "change addresses")?;
    let mut opened = port::open(&args.port, &serial)?;
    let shown: Vec<String> = plan.iter().take(wanted.min(4)).map(|&a| both_bases(a)).collect();
    writeln!(
        out,
        "addressing up to {wanted} probe(s) arriving at address {from} on {}: plan {}{}",
        opened.port,
        shown.join(", "),
        if wanted > shown.len() { ", ..." } else { "" }
    )?;
    out.flush()?;

    let mut table: Vec<Addressed<'_>> = Vec::new();
    let mut plan_left = plan.iter().copied();
    let mut outcome = Ok(());
    while table.len() < wanted && next_probe_connected(table.len() + 1, from)? {
        let Some(found) = identify_at(catalog, &mut opened, from)? else {
            writeln!(out, "nothing answers at address {from}: check power and wiring (A/B), then try again")?;
            continue;
        };
        writeln!(out, "found: {}", found_line(&found))?;
        let serial_number = found.serial_number.as_deref().map(printable);
        match give_next_address(catalog, &mut opened, &found, from, &mut plan_left, args, out) {
            Ok(address) => {
                writeln!(
                    out,
                    "probe {}: SN {} now answers at address {}, verified",
                    table.len() + 1,
                    serial_number.as_deref().unwrap_or("?"),
                    both_bases(address)
                )?;
                table.push(Addressed {
                    address,
                    serial_number,
                    models: found.models,
                    software: found.software,
                    sensor: found.identified,
                    candidates: found.candidates,
                });
            }
            Err(e) => {
                outcome = Err(e);
                break;
            }
        }
        out.flush()?;
    }
    write_table(&table, &opened.port, out)?;
    if let Some(path) = &args.station_toml
        && !table.is_empty()
    {
        write_station_draft(path, &table, &opened.port)?;
        writeln!(
            out,
            "wrote a draft station file to {} (check it with `yosemitech log --config {} --check`)",
            path.display(),
            path.display()
        )?;
    }
    outcome
}

/// Gives the probe at `from` the next free address of the plan and
/// verifies it there; an address another device answers at is skipped.
fn give_next_address(
    catalog: &Catalog,
    opened: &mut port::Opened,
    found: &Identification<'_>,
    from: u8,
    plan: &mut impl Iterator<Item = u8>,
    args: &SetAddressArgs,
    out: &mut dyn Write,
) -> Result<u8> {
    // The probe's own address commands when it is identified, or when every
    // sensor it may be changes its address alike; else the ones most
    // sensors share.
    let own: Vec<_> = found.identified.map_or_else(|| found.candidates.clone(), |s| vec![s]);
    let pairs: Vec<_> = own.into_iter().filter_map(address_commands).collect();
    let alike = |(w, p): &(&CommandSpec, &CommandSpec)| {
        pairs.first().is_some_and(|(w0, p0)| w.layout() == w0.layout() && p.layout() == p0.layout())
    };
    let (write, probe) = match pairs.first() {
        Some(&first) if pairs.iter().all(alike) => first,
        _ => {
            let (_, write, probe) = pick_commands(catalog, args.sensor.as_deref())?;
            (write, probe)
        }
    };
    // Serial numbers as printed (control characters escaped), on both sides.
    let sn_here = found.serial_number.as_deref().map(printable);
    loop {
        let Some(to) = plan.next() else {
            return Err(CliError::usage("the plan has no address left").hint("give more --addresses"));
        };
        let frames = ChangeFrames::build(write, probe, from, to)?;
        confirm(
            args.yes,
            &format!("Give the probe SN {} address {}?", sn_here.as_deref().unwrap_or("?"), both_bases(to)),
        )?;
        match frames.send(opened) {
            Ok(sn_there) => {
                let sn_there = sn_there.as_deref().map(printable);
                if let (Some(there), Some(here)) = (&sn_there, &sn_here)
                    && there != here
                {
                    return Err(CliError::device(format!(
                        "address {to} answers with SN {there}, not the probe's {here}"
                    ))
                    .hint(
                        "two devices may share the address: disconnect the others and check with `yosemitech scan`",
                    ));
                }
                return Ok(to);
            }
            Err(AddressChangeError::AddressInUse(a)) => {
                writeln!(out, "address {} is taken by another device; trying the next of the plan", both_bases(a))?;
            }
            Err(e) => {
                return Err(explain(
                    &e,
                    opened.bus.last_reply(),
                    &opened.port,
                    from,
                    to,
                    &opened.context(from, &write.name),
                ));
            }
        }
    }
}

/// The model column: the identified model(s), else the candidates.
fn model_text(row: &Addressed<'_>) -> String {
    if !row.models.is_empty() {
        row.models.join(" or ")
    } else if let Some(sensor) = row.sensor {
        sensor.model.clone().unwrap_or_else(|| sensor.name.clone())
    } else {
        "?".to_owned()
    }
}

fn write_table(table: &[Addressed<'_>], port: &str, out: &mut dyn Write) -> Result<()> {
    writeln!(out, "\nbus table ({} probe(s) on {port}):", table.len())?;
    writeln!(
        out,
        "  {:>7}  {:>4}  {:<16}  {:<12}  {:<8}  sensor",
        "address", "hex", "serial number", "model", "software"
    )?;
    for row in table {
        let sensor = match (row.sensor, row.candidates.as_slice()) {
            (Some(s), _) => s.name.clone(),
            (None, []) => "?".to_owned(),
            (None, many) => format!("one of {}", many.iter().map(|s| s.name.as_str()).collect::<Vec<_>>().join(", ")),
        };
        writeln!(
            out,
            "  {:>7}  0x{:02X}  {:<16}  {:<12}  {:<8}  {sensor}",
            row.address,
            row.address,
            row.serial_number.as_deref().unwrap_or("?"),
            model_text(row),
            row.software.map_or_else(|| "?".to_owned(), |v| v.to_string())
        )?;
    }
    Ok(())
}

/// A TOML string literal (quoted and escaped).
fn toml_string(text: &str) -> String {
    toml::Value::String(text.to_owned()).to_string()
}

/// The draft station file: one probe per identified row, the others as
/// comments naming their candidates (the draft must pass `log --check`).
fn station_draft(table: &[Addressed<'_>], port: &str) -> String {
    let mut text = String::new();
    let _ = writeln!(
        text,
        "# A draft station file, written by `yosemitech set-address --plan` at {}.",
        time::rfc3339(SystemTime::now())
    );
    let _ =
        writeln!(text, "# Check it with `yosemitech log --config FILE --check`; choose measurements and intervals.");
    let _ = writeln!(text, "station = \"station\"\n\n[storage]\npath = \"station.sqlite\"\n\n[[bus]]\nname = \"bus\"");
    match port.strip_prefix("tcp://") {
        Some(gateway) => {
            let _ = writeln!(text, "tcp = {}", toml_string(gateway));
        }
        None => {
            let _ = writeln!(text, "port = {}", toml_string(port));
        }
    }
    for row in table {
        let _ = writeln!(
            text,
            "\n# address {}, SN {}, model {}",
            both_bases(row.address),
            row.serial_number.as_deref().unwrap_or("?"),
            model_text(row)
        );
        let comment = if row.sensor.is_some() { "" } else { "# " };
        let sensor = row.sensor.map_or_else(
            || {
                let names: Vec<&str> = row.candidates.iter().map(|s| s.name.as_str()).collect();
                format!(
                    "? (not identified{})",
                    if names.is_empty() { String::new() } else { format!(": one of {}", names.join(", ")) }
                )
            },
            |s| s.name.clone(),
        );
        let label =
            row.sensor.map_or_else(|| format!("probe-{}", row.address), |s| format!("{}-{}", s.name, row.address));
        let _ = writeln!(text, "{comment}[[bus.probe]]");
        let _ = writeln!(text, "{comment}label = {}", toml_string(&label));
        let _ = writeln!(text, "{comment}sensor = {}", toml_string(&sensor));
        let _ = writeln!(text, "{comment}address = {}", row.address);
        let _ = writeln!(text, "{comment}interval = \"15m\"");
    }
    text
}

fn write_station_draft(path: &Path, table: &[Addressed<'_>], port: &str) -> Result<()> {
    let failed = |e: io::Error| {
        CliError::device(format!("cannot write {}: {e}", path.display()))
            .hint("the probes are addressed as the table says; copy it from above")
    };
    let mut file = OpenOptions::new().write(true).create_new(true).open(path).map_err(failed)?;
    file.write_all(station_draft(table, port).as_bytes()).map_err(failed)?;
    Ok(())
}
