//! `yosemitech set-address`: change a probe's slave address, verified at the new one.

use std::io::Write;

use yosemitech::procedures::address::{AddressChangeError, change_address};
use yosemitech::{Command as _, conductivity, ph_orp};

use crate::catalog::{Catalog, Entry};
use crate::cli::{Global, SetAddressArgs};
use crate::confirm::{confirm, ensure_can_ask};
use crate::error::{CliError, Result, request_failed};
use crate::port::{self, check_address};
use crate::shell;

/// Checks that a `--spec` sensor addresses the way the typed commands do.
fn same_as_common(entry: &Entry) -> Result<()> {
    let sensor = &entry.sensor;
    let fits = sensor.command(ph_orp::SetSlaveId::NAME).is_some_and(|c| c.layout() == ph_orp::SetSlaveId::LAYOUT)
        && sensor.command(ph_orp::GetSn::NAME).is_some_and(|c| c.layout() == ph_orp::GetSn::LAYOUT);
    if fits {
        Ok(())
    } else {
        Err(CliError::usage(format!(
            "sensor `{}` does not set its address the way Yosemitech probes do (set_slave_id at 0x3000, get_sn at 0x0900)",
            sensor.name
        ))
        .hint("write its address command with `yosemitech write` instead"))
    }
}

/// Runs `set-address`.
pub fn run(catalog: &Catalog, global: &Global, args: &SetAddressArgs, out: &mut dyn Write) -> Result<()> {
    let from = check_address(args.from, "--from")?;
    let to = check_address(args.to, "--to")?;
    if from == to {
        return Err(CliError::usage(format!("--from and --to are both {from}")).hint("give the new address with --to"));
    }
    let kind = match &args.sensor {
        Some(name) => {
            let entry = catalog.entry(name)?;
            same_as_common(entry)?;
            Some(entry.sensor.name.clone())
        }
        None => None,
    };
    ensure_can_ask(args.yes, "change the address")?;
    let serial = kind.as_deref().and_then(|k| catalog.sensor(k).ok()).map_or(port::YOSEMITECH_SERIAL, |s| s.serial);
    let mut opened = port::open(&args.port, global, &serial)?;
    writeln!(out, "changing the slave address of the probe at {from} to {to} on {}", opened.port)?;
    out.flush()?;
    confirm(args.yes, &format!("Change address {from} to {to}?"))?;
    // Every Yosemitech probe shares set_slave_id and get_sn (yosemitech-common.yaml).
    let result = match kind.as_deref() {
        Some("conductivity") => change_address(
            &mut opened.bus,
            from,
            to,
            &conductivity::SetSlaveId { slave_address: to },
            &conductivity::GetSn,
        )
        .map(|r| r.serial_number.to_string()),
        _ => change_address(&mut opened.bus, from, to, &ph_orp::SetSlaveId { slave_address: to }, &ph_orp::GetSn)
            .map(|r| r.serial_number.to_string()),
    };
    match result {
        Ok(sn) => {
            writeln!(out, "done: the probe (SN {sn}) now answers at address {to}")?;
            Ok(())
        }
        Err(e) => {
            Err(explain(&e, opened.bus.last_reply(), &opened.port, from, to, &opened.context(from, "set_slave_id")))
        }
    }
}

fn explain(
    e: &AddressChangeError,
    reply: &[u8],
    port: &str,
    from: u8,
    to: u8,
    ctx: &crate::error::Context,
) -> CliError {
    let scan = shell::command_line(&["yosemitech", "scan", "--port", port]);
    match e {
        AddressChangeError::AddressInUse(a) => {
            CliError::usage(format!("another device already answers at address {a}"))
                .hint(format!("choose a free address; `{scan}` lists the used ones"))
        }
        AddressChangeError::SameAddress(a) => CliError::usage(format!("the probe is already at address {a}")),
        AddressChangeError::InvalidAddress(a) => CliError::usage(format!("address {a} is outside 1..=247")),
        AddressChangeError::NotFound { address, error } => {
            let base = request_failed(error, reply, ctx);
            CliError::device(format!("no probe answers at address {address}; nothing was written ({})", base.message))
                .hint(format!("check --from; `{scan}` finds the probe"))
        }
        AddressChangeError::Failed { error, whereabouts } => {
            CliError::device(format!("the address change from {from} to {to} failed: {error}"))
                .detail(format!("where it is now: {whereabouts}"))
                .hint(format!("talk to it at the address above; if in doubt, `{scan}` finds it"))
        }
        other => CliError::device(other.to_string()),
    }
}
