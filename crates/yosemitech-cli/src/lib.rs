//! `yosemitech`: the field tool for Yosemitech water-quality probes on Modbus RTU.
//!
//! Every subcommand is in the `commands` module with its arguments; the top
//! of the command line (the global options, the list of subcommands) is in
//! `cli`, the argument groups several subcommands share in `args`. The
//! spec files of the workspace's `spec/` directory are compiled in
//! (the `catalog` module); `--spec DIR` adds more at run time. Generic commands go
//! through the spec's reference interpreter and `Client::call_raw`: `scan`
//! identifies probes by the serial-number and version roles and each
//! spec's `model_code`, `measure` runs the `procedure` a spec states. No
//! code names a sensor of the spec except the typed procedures (calibrate,
//! coefficients, set-address, demo), which go through the typed `yosemitech`
//! crate.
//!
//! `watch` and `plot` read a station's store (the `stored` module) into plain
//! data (`readings`), which `dashboard` draws on a terminal and `chart` into
//! a PNG or SVG file.
//!
//! The binary is a thin `main` over [`main`]. What `decode` prints is the
//! [`explain`] module's value for the bytes, a library of its own: the
//! fuzzer drives it.
//!
//! Errors are one `error:` line and one `hint:` line on stderr (the `error` module),
//! with exit code 1 for device and protocol errors and 2 for usage errors;
//! nothing the user, a device or a file supplies can make it panic.
#![cfg_attr(not(test), deny(clippy::unwrap_used, clippy::expect_used, clippy::panic))]

mod args;
mod backup;
mod catalog;
mod chart;
mod cli;
mod commands;
mod confirm;
mod dashboard;
mod database;
mod derived;
mod device;
mod doctor;
mod error;
/// The decode library (the `yosemitech-explain` crate), as the commands name it.
pub use yosemitech_explain as explain;
mod explained;
mod format;
mod help;
mod history;
mod identified;
mod port;
mod progress;
mod readings;
mod service;
mod shell;
mod stored;
mod time;
mod timer_slack;
mod units;

use std::io::{IsTerminal as _, Write as _};
use std::process::ExitCode;

use clap::Parser;
use tracing_subscriber::EnvFilter;

/// Frame dumps on stderr: `-v` shows the client's `tx`/`rx` frames (debug),
/// `-vv` everything (trace); `RUST_LOG` overrides both.
fn init_logging(verbose: u8) {
    let level = match verbose {
        // The station logger's own notes (a full store, space back), the portal's refusals and
        // ingest's lost connections show by default.
        0 => "error,yosemitech_station=info,yosemitech_portal=info,yosemitech_ingest=warn",
        1 => "debug",
        _ => "trace",
    };
    let filter = EnvFilter::try_from_env("RUST_LOG").unwrap_or_else(|_| EnvFilter::new(level));
    let _ = tracing_subscriber::fmt()
        .with_env_filter(filter)
        .with_writer(std::io::stderr)
        .with_ansi(std::io::stderr().is_terminal())
        .with_target(false)
        .without_time()
        .try_init();
}

/// Reports a bug as an error line instead of a panic message and backtrace.
fn install_panic_hook() {
    std::panic::set_hook(Box::new(|info| {
        let message = info
            .payload()
            .downcast_ref::<&str>()
            .map(|s| (*s).to_owned())
            .or_else(|| info.payload().downcast_ref::<String>().cloned())
            .unwrap_or_default();
        let place = info.location().map(|l| format!(" at {}:{}", l.file(), l.line())).unwrap_or_default();
        let mut err = std::io::stderr().lock();
        let _ = writeln!(err, "error: internal error{place}: {message}");
        let _ = writeln!(err, "hint: this is a bug in yosemitech; please report it with the command you ran");
    }));
}

/// Runs the tool on the process's arguments: the binary's `main`.
pub fn main() -> ExitCode {
    install_panic_hook();
    timer_slack::tighten();
    let cli = cli::Cli::try_parse().unwrap_or_else(|e| help::exit(e));
    init_logging(cli.global.verbose);
    match commands::run(&cli) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            e.report();
            e.exit_code()
        }
    }
}

/// The spec files compiled into the tool (every `spec/*.yaml` of the
/// workspace at build time), by file name, in name order: what the tool
/// serves without `--spec`.
pub fn embedded_spec() -> &'static [(&'static str, &'static str)] {
    yosemitech_ops::built_in::EMBEDDED_SPEC
}

/// The name of the sensor `yosemitech calibrate ph` drives: the built-in
/// sensor of the pH manual whose typed procedure it runs. Tests ask the tool
/// which sensor that is instead of guessing it from the spec (several
/// sensors may have a calibration point).
pub fn calibrate_ph_sensor() -> &'static str {
    commands::calibrate::SENSOR
}

/// The reads `calibrate ph --compute` takes in each buffer, as
/// `(command, field)`: the electrode potential, then the temperature. Tests
/// set these on a simulated probe instead of naming the pH manual's reads.
pub fn electrode_reads() -> [(&'static str, &'static str); 2] {
    commands::calibrate::electrode::READS
}

/// A unit as the tool shows it to people (`degC` is `°C`): what `read`,
/// `list`, `decode` and `measure` print after a value.
pub fn shown_unit(unit: &str) -> &str {
    format::unit(unit)
}

/// Whether `scan` tells apart, by reads, probes of `candidates`: sensors
/// that read their serial number alike and declare the same model code
/// (each has a read whose register block no other has).
pub fn scan_tells_apart(candidates: &[&yosemitech_spec::Sensor]) -> bool {
    yosemitech_ops::identify::can_tell_apart(candidates)
}

/// The `decode` subcommand's hex parser: hex with or without spaces, `0x`
/// prefixes, commas, colons or dashes between bytes.
pub fn parse_frame(text: &str) -> Result<Vec<u8>, String> {
    format::parse_frame(text).map_err(|e| e.to_string())
}
