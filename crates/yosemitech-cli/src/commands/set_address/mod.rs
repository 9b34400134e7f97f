//! `yosemitech set-address`: change a probe's slave address, verified at the new one.

mod plan;

use std::collections::BTreeMap;
use std::io::Write;

use yosemitech::procedures::address::{AddressChangeError, change_address_with};
use yosemitech_rtu::LineSettings;
use yosemitech_spec::{CommandSpec, Role, Sensor, Value};

use crate::catalog::Catalog;
use crate::confirm::{confirm, ensure_can_ask};
use crate::error::{CliError, Result, request_failed};
use crate::port::PortArgs;
use crate::port::{self, Opened, check_address};
use crate::shell;
use clap::Args;
use std::path::PathBuf;

/// `set-address`.
#[derive(Args, Debug)]
pub struct SetAddressArgs {
    #[command(flatten)]
    pub port: PortArgs,
    /// The probe's current address [with --plan: the address every new probe arrives at, default 1].
    #[arg(long, value_name = "A", required_unless_present = "plan")]
    pub from: Option<u32>,
    /// The new address, 1..=247.
    #[arg(long, value_name = "B", required_unless_present = "plan", conflicts_with = "plan")]
    pub to: Option<u32>,
    /// The sensor [default: any; the address commands are shared by every probe].
    #[arg(long, value_name = "SENSOR")]
    pub sensor: Option<String>,
    /// Address a bus of probes that all arrive at --from: connect them one at a time, each
    /// gets the next address of the plan, verified there; ends with the bus table.
    #[arg(long)]
    pub plan: bool,
    /// With --plan: the addresses to give, in order (1,5,10-20) [default: --first, then every --step].
    #[arg(long, value_name = "RANGES", requires = "plan")]
    pub addresses: Option<String>,
    /// With --plan: the first address of the plan [default: --from + 2].
    #[arg(long, value_name = "N", requires = "plan", conflicts_with = "addresses")]
    pub first: Option<u32>,
    /// With --plan: the spacing of the plan's addresses (probes at neighbouring addresses
    /// have been seen to answer for each other).
    #[arg(long, value_name = "N", default_value_t = 2, conflicts_with = "addresses")]
    pub step: u32,
    /// With --plan: stop after N probes [default: when you answer `d`, or at the plan's end].
    #[arg(long, value_name = "N", requires = "plan")]
    pub count: Option<u32>,
    /// With --plan: write a draft station file (`yosemitech log --config`) for the bus table.
    #[arg(long, value_name = "FILE", requires = "plan")]
    pub station_toml: Option<PathBuf>,
    /// Change without asking.
    #[arg(short, long)]
    pub yes: bool,
}

/// A sensor's address write (role `set_slave_address`) and the read that
/// finds the probe (role `serial_number`), both sent to the probe's own address.
pub(crate) fn address_commands(sensor: &Sensor) -> Option<(&CommandSpec, &CommandSpec)> {
    let own = |role| sensor.command_with_role(role).filter(|c| c.fixed_slave.is_none());
    Some((own(Role::SetSlaveAddress)?, own(Role::SerialNumber)?))
}

/// The commands of `--sensor`, or without it the ones most sensors of the
/// catalog share (same frames, same field): the probe's type is unknown,
/// and most Yosemitech probes change their address alike.
pub(crate) fn pick_commands<'c>(
    catalog: &'c Catalog,
    sensor: Option<&str>,
) -> Result<(&'c Sensor, &'c CommandSpec, &'c CommandSpec)> {
    if let Some(name) = sensor {
        let sensor = &catalog.entry(name)?.sensor;
        let Some((write, probe)) = address_commands(sensor) else {
            return Err(CliError::usage(format!(
                "sensor `{}` has no slave-address write and serial-number read sent to its own address",
                sensor.name
            ))
            .hint("write its address command with `yosemitech write` instead"));
        };
        return Ok((sensor, write, probe));
    }
    let all: Vec<(&Sensor, &CommandSpec, &CommandSpec)> =
        catalog.entries().iter().filter_map(|e| address_commands(&e.sensor).map(|(w, p)| (&*e.sensor, w, p))).collect();
    let field = |c: &CommandSpec| c.named_fields().next().map(|f| f.name.clone());
    let alike = |(_, w, p): &(&Sensor, &CommandSpec, &CommandSpec),
                 (_, w2, p2): &(&Sensor, &CommandSpec, &CommandSpec)| {
        w.layout() == w2.layout() && field(w) == field(w2) && p.layout() == p2.layout()
    };
    let sharing = |one| all.iter().filter(|other| alike(one, other)).count();
    // The first of the largest group, so the choice does not depend on ties' order.
    let best = all.iter().map(|one| (sharing(one), one)).fold(None, |best: Option<(usize, _)>, (n, one)| match best {
        Some((m, _)) if m >= n => best,
        _ => Some((n, one)),
    });
    best.map(|(_, one)| *one).ok_or_else(|| {
        CliError::usage("no sensor of the catalog changes its slave address")
            .hint("write the address command with `yosemitech write`")
    })
}

/// Runs `set-address` (`--plan`: [`plan`]).
pub fn run(catalog: &Catalog, args: &SetAddressArgs, out: &mut dyn Write) -> Result<()> {
    if args.plan {
        return plan::run(catalog, args, out);
    }
    let (Some(from), Some(to)) = (args.from, args.to) else {
        return Err(CliError::usage("set-address needs --from and --to").hint("or --plan to address a bus of probes"));
    };
    let from = check_address(from, "--from")?;
    let to = check_address(to, "--to")?;
    if from == to {
        return Err(CliError::usage(format!("--from and --to are both {from}")).hint("give the new address with --to"));
    }
    let (sensor, write, probe) = pick_commands(catalog, args.sensor.as_deref())?;
    let frames = ChangeFrames::build(write, probe, from, to)?;
    let serial = if args.sensor.is_some() { sensor.serial } else { LineSettings::default() };
    ensure_can_ask(args.yes, "change the address")?;
    let mut opened = port::open(&args.port, &serial)?;
    writeln!(out, "changing the slave address of the probe at {from} to {to} on {}", opened.port)?;
    out.flush()?;
    confirm(args.yes, &format!("Change address {from} to {to}?"))?;
    match frames.send(&mut opened) {
        Ok(sn) => {
            writeln!(out, "done: the probe (SN {}) now answers at address {to}", sn.as_deref().unwrap_or("?"))?;
            Ok(())
        }
        Err(e) => Err(explain(&e, opened.bus.last_reply(), &opened.port, from, to, &opened.context(from, &write.name))),
    }
}

/// The frames one address change can send, built before anything is sent.
pub(crate) struct ChangeFrames<'c> {
    probe: &'c CommandSpec,
    from: u8,
    to: u8,
    write: &'c CommandSpec,
    write_frame: Vec<u8>,
    probe_from: Vec<u8>,
    probe_to: Vec<u8>,
}

impl<'c> ChangeFrames<'c> {
    /// The address write of `from` to `to` and the probe read at each address.
    pub(crate) fn build(write: &'c CommandSpec, probe: &'c CommandSpec, from: u8, to: u8) -> Result<Self> {
        let address_field = write.named_fields().next().and_then(|f| f.name.clone()).unwrap_or_default();
        let values = BTreeMap::from([(address_field, Value::Int(i64::from(to)))]);
        let build = |c: &CommandSpec, slave: u8, values: &BTreeMap<String, Value>| {
            c.encode_request(slave, values)
                .map_err(|e| CliError::usage(format!("cannot build the {} request: {e}", c.name)))
        };
        Ok(Self {
            probe,
            from,
            to,
            write,
            write_frame: build(write, from, &values)?,
            probe_from: build(probe, from, &BTreeMap::new())?,
            probe_to: build(probe, to, &BTreeMap::new())?,
        })
    }

    /// Changes the address (the new one must be free, the probe must answer
    /// at the old one) and verifies it at the new one: the serial number
    /// read there, when it decodes.
    pub(crate) fn send(&self, opened: &mut Opened) -> std::result::Result<Option<String>, AddressChangeError> {
        let (write_layout, probe_layout) = (self.write.layout(), self.probe.layout());
        let reply = change_address_with(
            &mut opened.bus,
            self.from,
            self.to,
            |bus| bus.call_raw(&self.write_frame, &write_layout).map(|_| ()),
            |bus, slave| {
                let frame = if slave == self.to { &self.probe_to } else { &self.probe_from };
                bus.call_raw(frame, &probe_layout).map(<[u8]>::to_vec)
            },
        )?;
        Ok(self.probe.decode_response(self.to, &reply).ok().and_then(|v| v.into_iter().next()).map(|(_, v)| match v {
            Value::Text(text) => text.trim_end().to_owned(),
            other => other.to_string(),
        }))
    }
}

pub(crate) fn explain(
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
        AddressChangeError::InvalidAddress(a) => CliError::usage(format!("address {a} is outside 1 to 247")),
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
