//! `yosemitech calibrate ph`: the guided three-point pH calibration.
//!
//! The CLI face of the pH manual's own procedure
//! ([`yosemitech::procedures::ph`]), which drives that manual's typed
//! device. The coefficients are saved before the procedure starts, through
//! the spec's coefficient blocks like every other backup, so the file
//! restores with `coefficients restore` like any other.

pub mod electrode;
pub mod linear;
pub mod recorded;

use std::io::{self, BufRead, IsTerminal, Write};
use std::sync::mpsc::{self, Receiver, TryRecvError};
use std::time::Duration;

use yosemitech::ph_orp;
use yosemitech::procedures::coefficients::PhOrpCoefficients;
use yosemitech::procedures::ph::{CalibrationConfig, CalibrationGuide, calibrate, explain};
use yosemitech::procedures::{ProcedureError, RealSleep, Sleep};

use self::linear::CalibrateLinearArgs;
use self::recorded::{CalibrateHistoryArgs, CalibrateRestoreArgs};
use crate::args::BackupDir;
use crate::args::HistoryArgs;
use crate::backup::{self, Backup};
use crate::catalog::{Catalog, Entry};
use crate::confirm::{confirm, ensure_can_ask};
use crate::device::{is_typed, procedure_failed};
use crate::error::{CliError, Result, show_duration};
use crate::history::{self, Probe};
use crate::port::AddressArg;
use crate::port::Opened;
use crate::port::PortArgs;
use crate::{port, progress};
use clap::Args;
use std::path::PathBuf;

/// `calibrate`: a subcommand, or the K/B calibration of a sensor.
#[derive(Args, Debug)]
#[command(args_conflicts_with_subcommands = true, subcommand_negates_reqs = true)]
pub struct CalibrateArgs {
    /// A calibration of its own.
    #[command(subcommand)]
    pub command: Option<CalibrateSubcommand>,
    /// The K/B calibration.
    #[command(flatten)]
    pub linear: CalibrateLinearArgs,
}

/// `calibrate`'s own calibrations.
#[derive(clap::Subcommand, Debug)]
pub enum CalibrateSubcommand {
    /// Guided three-point pH calibration (buffers 4.00, 6.86, 9.18).
    #[command(long_about = "\
The pH manual's three-point calibration. Every coefficient is first saved to a JSON file
(the calibration stops if it cannot be saved) and the command that restores it is printed.
Then, for each buffer in order (4.00, 6.86, 9.18 at 25 °C): put the probe in it and press
Enter (q quits), wait for it to settle (a minute; a progress bar shows it; Enter on a
terminal or --skip-wait skips), and the buffer's pH is written. Finally the probe's
calibration status is read and explained.")]
    Ph(CalibratePhArgs),
    /// List the calibrations recorded (every `calibrate` records its own).
    #[command(long_about = "\
List the calibrations recorded: id, time, sensor, serial number, kind, the coefficients
written and the note. --json prints everything kept, every reading taken and the fit
included. The history is the station's store with --config, the file --history names, or
calibrations.sqlite in the user's data directory.")]
    History(CalibrateHistoryArgs),
    /// Write the coefficients of an earlier calibration back to its probe.
    #[command(long_about = "\
Write the coefficients an earlier calibration wrote (`calibrate history` lists the ids) back
to the probe: the probe's serial number must be the calibration's, every coefficient is saved
to a JSON file first, the write is confirmed (--yes), read back bit for bit, and recorded
in the history as a calibration of kind `restore`.")]
    Restore(CalibrateRestoreArgs),
}

/// `calibrate ph`.
#[derive(Args, Debug)]
pub struct CalibratePhArgs {
    #[command(flatten)]
    pub port: PortArgs,
    #[command(flatten)]
    pub address: AddressArg,
    /// Do not wait for the probe to settle in each buffer.
    #[arg(long)]
    pub skip_wait: bool,
    /// Start without asking (the buffer prompts still read stdin).
    #[arg(short, long)]
    pub yes: bool,
    #[command(flatten)]
    pub backup: BackupDir,
    /// Compute the electrode coefficients K1..K6 here, by the vendor's
    /// model, from the potential and temperature read in each buffer,
    /// instead of the probe's own calibration; show them against the
    /// probe's and write them after a confirmation.
    #[arg(long)]
    pub compute: bool,
    /// With --compute: the readings of each buffer from a CSV file
    /// (`buffer,mv,temperature_c`, one line per buffer, 4.00, 6.86, 9.18),
    /// taken with another tool. Without --port nothing is written.
    #[arg(long, value_name = "FILE")]
    pub readings: Option<PathBuf>,
    /// With --compute: print the readings and the coefficients as JSON.
    #[arg(long)]
    pub json: bool,
    #[command(flatten)]
    pub history: HistoryArgs,
}

/// The sensor `calibrate ph` drives: the pH manual's, whose typed device the
/// procedure takes.
pub const SENSOR: &str = ph_orp::SENSOR.name;

/// Saves every coefficient of the probe (the spec's coefficient blocks) to
/// a new file and returns the command that restores it, and the
/// coefficients. Nothing has been written yet; on an error the calibration
/// does not start.
pub(crate) fn save_backup(
    opened: &mut Opened,
    catalog: &Catalog,
    entry: &Entry,
    slave: u8,
    serial_number: Option<String>,
    args: &CalibratePhArgs,
    out: &mut dyn Write,
) -> Result<(String, backup::Blocks)> {
    let not_started = |e: CliError| CliError {
        message: format!("{}; the calibration did not start, nothing was written", e.message),
        ..e
    };
    let blocks = backup::read_blocks(opened, entry, slave).map_err(not_started)?;
    let backup = Backup::taken_now(opened, entry, slave, serial_number, blocks.clone());
    let path = backup::save_in(args.backup.dir.as_deref(), &backup).map_err(not_started)?;
    let restore = backup::restore_command(catalog, entry, &backup.port, backup.address, &path);
    writeln!(out, "saved every coefficient to {}", path.display())?;
    writeln!(out, "restore with: {restore}")?;
    out.flush()?;
    Ok((restore, blocks))
}

/// Lines typed on stdin, read by a thread so a wait can be cut short.
pub(crate) fn stdin_lines() -> Receiver<String> {
    let (tx, rx) = mpsc::channel();
    std::thread::spawn(move || {
        for line in io::stdin().lock().lines() {
            let Ok(line) = line else { break };
            if tx.send(line).is_err() {
                break;
            }
        }
    });
    rx
}

/// The user's side of the calibration, on stdin and stdout.
struct Guide<'a> {
    out: &'a mut dyn Write,
    input: Receiver<String>,
    interactive: bool,
    skip_wait: bool,
    /// Why the guide stopped the calibration.
    stopped: Option<CliError>,
}

impl Guide<'_> {
    fn say(&mut self, text: &str) {
        let _ = writeln!(self.out, "{text}");
        let _ = self.out.flush();
    }
}

impl CalibrationGuide for Guide<'_> {
    /// The coefficients were saved before the procedure started ([`save_backup`]):
    /// the same registers, read through the spec's coefficient blocks, with
    /// nothing written in between.
    fn backed_up(&mut self, _coefficients: &PhOrpCoefficients) -> bool {
        true
    }

    fn immerse(&mut self, index: usize, standard_ph: f32) -> bool {
        self.say(&format!(
            "\npoint {} of 3: rinse the probe and put it in the pH {standard_ph:.2} buffer, then press Enter (q quits)",
            index + 1
        ));
        match self.input.recv() {
            Ok(line) if line.trim().eq_ignore_ascii_case("q") => {
                self.stopped =
                    Some(CliError::device(format!("calibration stopped by the user at point {}", index + 1)));
                false
            }
            Ok(_) => true,
            Err(_) => {
                self.stopped = Some(
                    CliError::device(format!("stdin ended before point {} was confirmed", index + 1))
                        .hint("answer each buffer prompt with Enter (a line on stdin)"),
                );
                false
            }
        }
    }

    fn settle(&mut self, _index: usize, duration: Duration, sleep: &mut dyn Sleep) {
        if self.skip_wait {
            self.say("  not waiting for the probe to settle (--skip-wait)");
            return;
        }
        let skip = if self.interactive { "; Enter skips" } else { "" };
        self.say(&format!("  letting the probe settle for {}{skip}", show_duration(duration)));
        let bar = progress::timer(duration, "settling");
        let (input, interactive) = (&self.input, self.interactive);
        progress::wait(
            &bar,
            duration,
            |d| sleep.sleep(d),
            || !interactive || matches!(input.try_recv(), Err(TryRecvError::Empty | TryRecvError::Disconnected)),
        );
    }

    fn point_written(&mut self, index: usize, standard_ph: f32) {
        self.say(&format!("  point {}: pH {standard_ph:.2} written", index + 1));
    }
}

/// Runs `calibrate ph`.
pub fn run(catalog: &Catalog, args: &CalibratePhArgs, out: &mut dyn Write) -> Result<()> {
    if args.compute || args.readings.is_some() {
        return electrode::run(catalog, args, out);
    }
    if args.json {
        return Err(CliError::usage("`calibrate ph --json` prints computed coefficients: add --compute"));
    }
    let name = SENSOR;
    let entry = catalog.entry(name)?;
    if !is_typed(entry, name) {
        return Err(CliError::usage(format!("`calibrate ph` needs the built-in {name} sensor"))
            .hint("a --spec file replaced it; run without --spec"));
    }
    let slave = args.address.get(entry.sensor.default_address)?;
    ensure_can_ask(args.yes, "calibrate")?;
    let (mut store, history_file) = history::open(catalog, &args.history)?;
    let mut opened = port::open(&args.port, &entry.sensor.serial)?;
    let identity = history::identity(&mut opened, entry, slave);
    let serial_number = identity.0.clone();
    let config = CalibrationConfig::default();
    writeln!(
        out,
        "three-point pH calibration of the probe at address {slave} on {}{}",
        opened.port,
        serial_number.as_deref().map(|sn| format!(" (SN {sn})")).unwrap_or_default()
    )?;
    writeln!(
        out,
        "buffers in order: {} (at 25 °C); the coefficients are saved first",
        config.standards.map(|s| format!("{s:.2}")).join(", ")
    )?;
    out.flush()?;
    confirm(args.yes, "Start the calibration?")?;

    let (restore, before) = save_backup(&mut opened, catalog, entry, slave, serial_number, args, out)?;
    let with_restore =
        |e: CliError| e.detail(format!("to restore the coefficients saved before the calibration: {restore}"));
    let ctx = opened.context(slave, "the calibration");
    let mut guide = Guide {
        out,
        input: stdin_lines(),
        interactive: io::stdin().is_terminal(),
        skip_wait: args.skip_wait,
        stopped: None,
    };
    let mut probe = ph_orp::Device::new(&mut opened.bus, slave);
    let report = match calibrate(&mut probe, &config, &mut guide, &mut RealSleep) {
        Ok(report) => report,
        Err(ProcedureError::Aborted) => {
            let e = guide.stopped.take().unwrap_or_else(|| CliError::device("calibration stopped"));
            return Err(with_restore(e));
        }
        Err(e) => return Err(with_restore(procedure_failed(&e, probe.client().last_reply(), &ctx))),
    };
    let out = guide.out;
    if report.succeeded() {
        writeln!(out, "\ncalibration succeeded (probe status {})", report.status.raw())?;
        writeln!(out, "coefficients now:")?;
        let after = backup::read_blocks(&mut opened, entry, slave).map_err(with_restore)?;
        for line in backup::show(&after) {
            writeln!(out, "  {line}")?;
        }
        let probe = Probe { entry, address: slave, port: opened.port.clone(), identity };
        let mut record = probe.record("ph_three_point", args.history.note.as_deref());
        record.before = history::blocks_json(&before);
        record.after = history::blocks_json(&after);
        record.standards = serde_json::json!(config.standards);
        history::record(&mut store, &history_file, &record, out)?;
        Ok(())
    } else {
        Err(with_restore(
            CliError::device(format!(
                "calibration failed: status {} ({}): {}",
                report.status.raw(),
                report.status,
                explain(report.status)
            ))
            .hint(
                "the probe keeps its previous coefficients after a failed calibration; fix the cause and run it again",
            ),
        ))
    }
}
