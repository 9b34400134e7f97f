//! `yosemitech doctor`: the diagnosis of [`crate::doctor`] on a serial
//! port, with progress on stderr and the report as text or JSON.

use std::io::Write;
use std::sync::Arc;
use std::sync::atomic::AtomicBool;
use std::time::Duration;

use indicatif::ProgressBar;
use yosemitech_spec::Sensor;

use crate::catalog::Catalog;
use crate::doctor::{self, Plan, Probes, Progress, Report, SerialLine, VerdictCode, hex};
use crate::error::{CliError, Result, show_duration};
use crate::port::AddressArg;
use crate::port::PortArgs;
use crate::port::{self, open_failed};
use crate::progress;
use clap::Args;
use yosemitech_ops::common_serial;

/// `doctor`.
#[derive(Args, Debug)]
pub struct DoctorArgs {
    #[command(flatten)]
    pub port: PortArgs,
    #[command(flatten)]
    pub address: AddressArg,
    /// The sensor [default: any; the frames most sensors share].
    #[arg(long, value_name = "SENSOR")]
    pub sensor: Option<String>,
    /// Print the report as JSON.
    #[arg(long)]
    pub json: bool,
}

/// Progress on stderr: a bar per phase on a terminal, a line per phase otherwise.
struct Shown {
    bar: Option<ProgressBar>,
}

impl Progress for Shown {
    fn phase(&mut self, text: &str, requests: usize) {
        if let Some(bar) = self.bar.take() {
            bar.finish_and_clear();
        }
        if progress::enabled() {
            let bar = progress::bar(requests as u64, "{msg:40} [{bar:30}] {pos}/{len} requests");
            bar.set_message(text.to_owned());
            self.bar = Some(bar);
        } else {
            let _ = writeln!(std::io::stderr().lock(), "doctor: {text}");
        }
    }

    fn request(&mut self) {
        if let Some(bar) = &self.bar {
            bar.inc(1);
        }
    }
}

/// Runs `doctor`.
pub fn run(catalog: &Catalog, args: &DoctorArgs, stop: &Arc<AtomicBool>, out: &mut dyn Write) -> Result<()> {
    let port = port::port_name(&args.port)?;
    if port.starts_with("tcp://") {
        return Err(CliError::usage("doctor needs the serial port itself, not a TCP gateway").hint(
            "run it on the machine the RS-485 adapter is plugged into, or use `yosemitech scan` through the gateway",
        ));
    }
    let sensors: Vec<&Sensor> = match &args.sensor {
        Some(name) => vec![catalog.sensor(name)?.as_ref()],
        None => catalog.entries().iter().map(|e| e.sensor.as_ref()).collect(),
    };
    let probes = Probes::of(&sensors).ok_or_else(|| {
        CliError::usage("no sensor to diagnose has a serial-number read at its own address")
            .hint("the doctor reads the command with `role: serial_number`; check --sensor and the --spec files")
    })?;
    let mut settings = match sensors.as_slice() {
        [one] => one.serial,
        _ => common_serial(catalog.entries().iter().map(|e| e.sensor.as_ref())),
    };
    if let Some(baud) = args.port.baud {
        if baud == 0 {
            return Err(
                CliError::usage("--baud 0 is not a baud rate").hint("Yosemitech probes use 9600 unless reconfigured")
            );
        }
        settings.baud = baud;
    }
    let address = args.address.get(sensors.first().map_or(1, |s| s.default_address))?;
    let plan = Plan::new(address, settings, args.port.timeout.unwrap_or(Duration::from_secs(1)), probes.starts.len());
    let mut line = SerialLine::new(port.clone());
    // Opened here first, so a missing port is an error, not a diagnosis.
    doctor::Line::configure(&mut line, settings).map_err(|e| open_failed(&port, &e))?;
    if !args.json {
        writeln!(
            out,
            "diagnosing {port}: address {address}, {settings}; at most {} requests, about {} if nothing answers",
            plan.max_requests(),
            show_duration(plan.silent_duration())
        )?;
        out.flush()?;
    }
    let mut shown = Shown { bar: None };
    let report = doctor::diagnose(&mut line, &probes, &plan, &mut shown, stop)
        .map_err(|e| CliError::device(format!("the diagnosis stopped: {port} failed: {e}")))?;
    if let Some(bar) = shown.bar.take() {
        bar.finish_and_clear();
    }
    if args.json {
        writeln!(out, "{}", serde_json::to_string_pretty(&report.to_json(&port)).unwrap_or_default())?;
    } else {
        write_text(&report, out)?;
    }
    match report.verdict.code {
        VerdictCode::Healthy => Ok(()),
        _ => {
            Err(CliError::device(format!("doctor: {}", report.verdict.summary)).hint(report.verdict.next_step.clone()))
        }
    }
}

fn write_text(report: &Report, out: &mut dyn Write) -> Result<()> {
    for f in &report.findings {
        writeln!(out, "- {} [{}]: {}", f.kind.name(), f.settings, f.text)?;
        let turnaround = f.turnaround.map(|t| format!(" after {}", show_duration(t))).unwrap_or_default();
        writeln!(out, "    sent {} to address {}: {}", f.command, f.address, hex(&f.sent))?;
        if f.received.is_empty() {
            writeln!(out, "    received nothing")?;
        } else {
            writeln!(out, "    received{turnaround}: {}", hex(&f.received))?;
        }
    }
    writeln!(out, "{} requests in {}", report.requests, show_duration(report.elapsed))?;
    writeln!(out, "skipped to stay within a minute:")?;
    for s in report.plan.skipped() {
        writeln!(out, "  {s}")?;
    }
    writeln!(out, "verdict ({}): {}", report.verdict.code.name(), report.verdict.summary)?;
    writeln!(out, "next: {}", report.verdict.next_step)?;
    Ok(())
}
