//! `yosemitech calibrate SENSOR --standard VALUE ...`: the K/B calibration
//! of any probe with a user calibration block, as the vendor's calibrator
//! sheets do it.
//!
//! The block is the write with role `user_calibration` (slope K, then
//! offset B; final = K x raw + B), found by role; the field it calibrates is
//! the spec's `calibrates.field`, or `--quantity`. Every coefficient is
//! backed up first (no backup, no calibration); from the first write on,
//! any failure or stop writes the block's saved values back and reads them
//! back bit for bit (Ctrl-C included: the first one stops the calibration
//! that way, a second one exits at once). The statistics and the fit are
//! [`yosemitech::procedures::linear`]'s; the writes go through the spec's
//! commands by the interpreter, as a coefficient restore does.

use std::collections::{BTreeMap, VecDeque};
use std::io::{self, IsTerminal, Write};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{Receiver, RecvTimeoutError, TryRecvError};
use std::time::{Duration, Instant};

use yosemitech::procedures::linear::{self, LinearFit, ReadingStats, StandardReading};
use yosemitech_spec::{CommandSpec, Sensor, Value};

use serde_json::{Map, json};
use yosemitech_station::Calibration;

use super::stdin_lines;
use crate::args::BackupDir;
use crate::args::HistoryArgs;
use crate::backup::{self, Backup};
use crate::catalog::Catalog;
use crate::confirm::{confirm, ensure_can_ask};
use crate::device;
use crate::error::{CliError, Result, show_duration};
use crate::format::f32_json;
use crate::format::parse_duration;
use crate::history::{self, Probe};
use crate::port::AddressArg;
use crate::port::PortArgs;
use crate::port::{self, Opened};
use clap::Args;

/// `calibrate SENSOR`: the K/B calibration.
#[derive(Args, Debug, Default)]
pub struct CalibrateLinearArgs {
    /// Sensor whose user calibration block to calibrate.
    pub sensor: Option<String>,
    #[command(flatten)]
    pub port: PortArgs,
    #[command(flatten)]
    pub address: AddressArg,
    /// A standard's value, in the calibrated field's unit, in the order the
    /// probe goes into them; repeatable (one: an offset; two or more: a line).
    #[arg(long = "standard", value_name = "VALUE", allow_negative_numbers = true)]
    pub standards: Vec<f64>,
    /// The measured field the block calibrates, where the spec does not say,
    /// or to pick one of several blocks.
    #[arg(long, value_name = "FIELD")]
    pub quantity: Option<String>,
    /// Readings averaged in each standard.
    #[arg(long, value_name = "N", default_value_t = 5)]
    pub readings: u32,
    /// Time between two readings.
    #[arg(long, value_name = "DURATION", default_value = "1s", value_parser = parse_duration)]
    pub interval: Duration,
    /// Readings the stability is judged over.
    #[arg(long, value_name = "N", default_value_t = 10)]
    pub window: u32,
    /// Stable when the coefficient of variation over the window is below this, in percent.
    #[arg(long, value_name = "PERCENT", default_value_t = 0.5)]
    pub cv_threshold: f64,
    /// Stable also when the standard deviation over the window is below this, in
    /// the field's unit (a standard near zero, where a CV means little).
    #[arg(long, value_name = "VALUE")]
    pub sd_threshold: Option<f64>,
    /// Give up when the readings are not stable after this long (the calibration stops).
    #[arg(long, value_name = "DURATION", default_value = "10m", value_parser = parse_duration)]
    pub max_wait: Duration,
    /// Do not wait for stable readings (nor the spec's settling time).
    #[arg(long)]
    pub skip_wait: bool,
    /// Start and write without asking (the standard prompts still read stdin).
    #[arg(short, long)]
    pub yes: bool,
    #[command(flatten)]
    pub backup: BackupDir,
    #[command(flatten)]
    pub history: HistoryArgs,
}

/// The block a calibration writes and the measured field it applies to.
pub(crate) struct Target<'s> {
    /// The write with role `user_calibration`.
    pub write: &'s CommandSpec,
    /// The read of the same registers.
    pub read_back: &'s CommandSpec,
    /// The calibrated field.
    pub field: String,
    /// Its unit, if the spec gives one.
    pub unit: Option<String>,
    /// The measurement read that gives it.
    pub measurement: &'s CommandSpec,
    /// The standards the spec recommends.
    pub recommended: Vec<f64>,
    /// The spec's settling wait in each standard.
    pub settle: Duration,
}

impl Target<'_> {
    /// The names of K and B: the write's two fields, in order.
    fn names(&self) -> Result<(String, String)> {
        let mut names = self.write.named_fields().map(|f| f.display_name().to_owned());
        match (names.next(), names.next()) {
            (Some(k), Some(b)) => Ok((k, b)),
            _ => Err(CliError::usage(format!("`{}` is not a K/B block", self.write.name))),
        }
    }

    /// The write's values for `k` and `b`.
    pub fn values(&self, k: f32, b: f32) -> Result<BTreeMap<String, Value>> {
        let (k_name, b_name) = self.names()?;
        Ok(BTreeMap::from([(k_name, Value::Float(k)), (b_name, Value::Float(b))]))
    }
}

/// The user calibration block of `sensor` that `quantity` names (or the
/// only one), and the field it calibrates.
pub(crate) fn target<'s>(sensor: &'s Sensor, quantity: Option<&str>) -> Result<Target<'s>> {
    let blocks = sensor.user_calibrations();
    let measured = || sensor.measurement_reads().flat_map(|r| r.named_fields().map(|f| f.display_name())).collect();
    let list = |names: Vec<&str>| names.join(", ");
    if blocks.is_empty() {
        return Err(CliError::usage(format!("sensor `{}` has no user calibration block", sensor.name)).hint(
            "a K/B block is a write with role `user_calibration` paired with a read of the same registers; \
             `yosemitech list` shows each sensor's commands",
        ));
    }
    let stated = |w: &CommandSpec| w.calibrates.as_ref().map(|c| c.field.clone());
    let chosen = match quantity {
        Some(q) => blocks
            .iter()
            .find(|(w, _)| stated(w).as_deref() == Some(q))
            .or_else(|| {
                let unstated: Vec<_> = blocks.iter().filter(|(w, _)| w.calibrates.is_none()).collect();
                match unstated.as_slice() {
                    [one] => Some(*one),
                    _ => None,
                }
            })
            .map(|&(w, r)| (w, r, q.to_owned())),
        None => match blocks.as_slice() {
            [(w, r)] => stated(w).map(|f| (*w, *r, f)),
            _ => None,
        },
    };
    let Some((write, read_back, field)) = chosen else {
        let stated: Vec<String> = blocks.iter().filter_map(|(w, _)| stated(w)).collect();
        let (message, hint) = match (quantity, blocks.len()) {
            (Some(q), _) => (
                format!("no user calibration block of `{}` calibrates `{q}`", sensor.name),
                format!(
                    "the blocks calibrate: {}",
                    if stated.is_empty() { "(not stated)".into() } else { stated.join(", ") }
                ),
            ),
            (None, 1) => (
                format!("the spec of `{}` does not say which field its calibration block calibrates", sensor.name),
                format!("give --quantity FIELD (measured fields: {})", list(measured())),
            ),
            (None, n) => (
                format!("sensor `{}` has {n} user calibration blocks", sensor.name),
                format!("pick one with --quantity FIELD ({})", stated.join(", ")),
            ),
        };
        return Err(CliError::usage(message).hint(hint));
    };
    let Some(measurement) = sensor.measurement_with_field(&field) else {
        return Err(CliError::usage(format!("`{field}` is not a field of a measurement read of `{}`", sensor.name))
            .hint(format!("measured fields: {}", list(measured()))));
    };
    let unit = measurement.named_fields().find(|f| f.display_name() == field).and_then(|f| f.unit.clone());
    let calibrates = write.calibrates.as_ref().filter(|c| c.field == field);
    Ok(Target {
        write,
        read_back,
        unit,
        measurement,
        recommended: calibrates.map(|c| c.standards.clone()).unwrap_or_default(),
        settle: Duration::from_millis(calibrates.and_then(|c| c.settle_ms).map_or(0, u64::from)),
        field,
    })
}

/// The readings taken in one standard.
#[derive(Debug, Clone)]
pub(crate) struct StandardRun {
    /// The standard's value.
    pub standard: f64,
    /// Every reading taken while waiting for stability, then the averaged ones.
    pub settling: Vec<f64>,
    /// The readings averaged.
    pub readings: Vec<f64>,
    /// Their statistics.
    pub stats: ReadingStats,
}

/// What a finished calibration did.
#[derive(Debug, Clone)]
pub(crate) struct Outcome {
    /// Each standard's readings.
    pub runs: Vec<StandardRun>,
    /// The line.
    pub fit: LinearFit,
    /// K and B written.
    pub written: (f32, f32),
    /// The probe read through them in the last standard.
    pub check: ReadingStats,
}

/// Checks the options before anything is opened.
fn check_args(args: &CalibrateLinearArgs, target: &Target<'_>) -> Result<()> {
    if args.standards.is_empty() {
        let hint = if target.recommended.is_empty() {
            "give each standard's value with --standard VALUE (one: an offset; two or more: a line)".to_owned()
        } else {
            let shown: Vec<String> = target.recommended.iter().map(|s| format!("--standard {s}")).collect();
            format!("the manual recommends: {}", shown.join(" "))
        };
        return Err(CliError::usage("no --standard given").hint(hint));
    }
    if let Some(bad) = args.standards.iter().find(|s| !s.is_finite()) {
        return Err(CliError::usage(format!("--standard {bad} is not a number")));
    }
    if args.readings == 0 {
        return Err(CliError::usage("--readings must be at least 1"));
    }
    if args.window < 2 {
        return Err(CliError::usage("--window must be at least 2 readings"));
    }
    if !(args.cv_threshold.is_finite() && args.cv_threshold > 0.0) {
        return Err(CliError::usage(format!("--cv-threshold {} is not a positive percentage", args.cv_threshold)));
    }
    if let Some(sd) = args.sd_threshold.filter(|sd| !(sd.is_finite() && *sd > 0.0)) {
        return Err(CliError::usage(format!("--sd-threshold {sd} is not a positive number")));
    }
    Ok(())
}

/// The calibration's conversation: the open port, the probe, the prompts.
struct Session<'a, 's> {
    opened: &'a mut Opened,
    slave: u8,
    target: &'a Target<'s>,
    args: &'a CalibrateLinearArgs,
    input: Receiver<String>,
    /// Set by Ctrl-C: the calibration stops (and the block is written back).
    stop: &'a AtomicBool,
    out: &'a mut dyn Write,
}

impl Session<'_, '_> {
    /// Stops when Ctrl-C was pressed.
    fn check_stop(&self) -> Result<()> {
        if self.stop.load(Ordering::SeqCst) { Err(CliError::device("calibration stopped by Ctrl-C")) } else { Ok(()) }
    }

    /// The next line typed (`None`: the end of input), or a stop by Ctrl-C.
    fn next_line(&mut self) -> Result<Option<String>> {
        loop {
            self.check_stop()?;
            match self.input.recv_timeout(Duration::from_millis(200)) {
                Ok(line) => return Ok(Some(line)),
                Err(RecvTimeoutError::Timeout) => {}
                Err(RecvTimeoutError::Disconnected) => return Ok(None),
            }
        }
    }

    fn say(&mut self, text: &str) -> Result<()> {
        writeln!(self.out, "{text}")?;
        self.out.flush()?;
        Ok(())
    }

    fn unit(&self) -> String {
        self.target.unit.as_deref().map(|u| format!(" {u}")).unwrap_or_default()
    }

    /// One reading of the calibrated field.
    fn read(&mut self) -> Result<f64> {
        self.check_stop()?;
        let values = device::read(self.opened, self.target.measurement, self.slave)?;
        match values.into_iter().find(|(name, _)| *name == self.target.field) {
            Some((_, Value::Float(v))) if v.is_finite() => Ok(f64::from(v)),
            Some((_, other)) => Err(CliError::device(format!("{} read {other:?}, not a number", self.target.field))),
            None => Err(CliError::device(format!("{} gave no {}", self.target.measurement.name, self.target.field))),
        }
    }

    /// Writes K and B and reads them back bit for bit.
    fn write(&mut self, k: f32, b: f32) -> Result<()> {
        let values = self.target.values(k, b)?;
        backup::write_block(self.opened, self.target.write, self.target.read_back, self.slave, &values)
    }

    /// Waits for a line: Enter goes on, `q` or the end of input stops.
    fn wait_for_enter(&mut self, what: &str) -> Result<()> {
        match self.next_line()? {
            Some(line) if line.trim().eq_ignore_ascii_case("q") => {
                Err(CliError::device(format!("calibration stopped by the user at {what}")))
            }
            Some(_) => Ok(()),
            None => Err(CliError::device(format!("stdin ended before {what} was confirmed"))
                .hint("answer each standard's prompt with Enter (a line on stdin)")),
        }
    }

    /// Watches the readings until they are stable over the window (after
    /// the spec's settling wait), Enter accepts them, or `--max-wait` passes.
    fn settle(&mut self, what: &str, seen: &mut Vec<f64>) -> Result<()> {
        let (window, threshold) = (self.args.window as usize, self.args.cv_threshold);
        let live = io::stdout().is_terminal();
        let start = Instant::now();
        let mut recent: VecDeque<f64> = VecDeque::with_capacity(window);
        self.say(&format!(
            "  waiting for stable readings (CV over {window} readings below {threshold}%{}); Enter accepts, q quits",
            if self.target.settle.is_zero() {
                String::new()
            } else {
                format!(", at least {}", show_duration(self.target.settle))
            }
        ))?;
        loop {
            match self.input.try_recv() {
                Ok(line) if line.trim().eq_ignore_ascii_case("q") => {
                    return Err(CliError::device(format!("calibration stopped by the user at {what}")));
                }
                Ok(_) => return self.say("  accepted as stable (Enter)"),
                Err(TryRecvError::Empty | TryRecvError::Disconnected) => {}
            }
            let value = self.read()?;
            seen.push(value);
            if recent.len() == window {
                recent.pop_front();
            }
            recent.push_back(value);
            let values: Vec<f64> = recent.iter().copied().collect();
            let stats = linear::stats(&values);
            let trend = linear::trend(&values).unwrap_or(0.0);
            let cv = stats.and_then(|s| s.cv_percent);
            let shown_cv = cv.map_or_else(|| "-".to_owned(), |cv| format!("{cv:.3}%"));
            let line = format!(
                "  {:>6.1}s  {value:.4}{}  trend {trend:+.5}/reading  CV {shown_cv}",
                start.elapsed().as_secs_f64(),
                self.unit()
            );
            if live {
                write!(self.out, "\r{line}\x1b[K")?;
                self.out.flush()?;
            } else {
                self.say(&line)?;
            }
            let full = recent.len() == window;
            let steady = stats.is_some_and(|s| {
                s.cv_percent.is_some_and(|cv| cv < threshold) || s.sd <= self.args.sd_threshold.unwrap_or(0.0)
            });
            if full && steady && start.elapsed() >= self.target.settle {
                if live {
                    writeln!(self.out)?;
                }
                return self.say(&format!("  stable: CV {shown_cv} over {window} readings"));
            }
            if start.elapsed() >= self.args.max_wait {
                return Err(CliError::device(format!(
                    "the readings in {what} were not stable after {}",
                    show_duration(self.args.max_wait)
                ))
                .hint(
                    "rinse the probe and let it settle, raise --cv-threshold or --max-wait, give --sd-threshold \
                     (a standard near zero), or press Enter",
                ));
            }
            std::thread::sleep(self.args.interval);
        }
    }

    /// Averages `--readings` readings.
    fn measure(&mut self) -> Result<(Vec<f64>, ReadingStats)> {
        let mut readings = Vec::new();
        for n in 0..self.args.readings {
            if n > 0 {
                std::thread::sleep(self.args.interval);
            }
            readings.push(self.read()?);
        }
        let stats = linear::stats(&readings).ok_or_else(|| CliError::device("no reading to average"))?;
        Ok((readings, stats))
    }

    /// Every step after the backup: K = 1, B = 0, each standard, the fit,
    /// the write and its check.
    fn run(&mut self) -> Result<Outcome> {
        self.write(1.0, 0.0)?;
        self.say("wrote K = 1, B = 0 (read back): the readings are now the probe's raw ones")?;
        let standards = self.args.standards.clone();
        let mut runs = Vec::new();
        for (i, &standard) in standards.iter().enumerate() {
            let what = format!("standard {} of {} ({standard}{})", i + 1, standards.len(), self.unit());
            self.say(&format!("\n{what}: rinse the probe and put it in the standard, then press Enter (q quits)"))?;
            self.wait_for_enter(&what)?;
            let mut settling = Vec::new();
            if !self.args.skip_wait {
                self.settle(&what, &mut settling)?;
            }
            let (readings, stats) = self.measure()?;
            self.say(&format!(
                "  {} readings: mean {:.5}{}, SD {:.5}, CV {}",
                stats.count,
                stats.mean,
                self.unit(),
                stats.sd,
                stats.cv_percent.map_or_else(|| "-".to_owned(), |cv| format!("{cv:.3}%"))
            ))?;
            runs.push(StandardRun { standard, settling, readings, stats });
        }
        let points: Vec<StandardReading> =
            runs.iter().map(|r| StandardReading { standard: r.standard, reading: r.stats.mean }).collect();
        let fit = linear::fit(&points).map_err(|e| CliError::device(format!("cannot fit K and B: {e}")))?;
        self.show_fit(&runs, &fit)?;
        let (k, b) = (fit.k as f32, fit.b as f32);
        if !(k.is_finite() && b.is_finite()) || k <= 0.0 {
            return Err(CliError::device(format!("K = {k}, B = {b} cannot be written: K must be positive and finite"))
                .hint("check the standards' values and their order, and that the probe was in each"));
        }
        if !self.args.yes {
            eprint!("Write K = {k}, B = {b} to the probe at address {}? [y/N] ", self.slave);
            let answer = self.next_line()?.unwrap_or_default();
            if !matches!(answer.trim().to_ascii_lowercase().as_str(), "y" | "yes") {
                return Err(CliError::device("not confirmed"));
            }
        }
        self.write(k, b)?;
        self.say(&format!("written and read back: K = {k}, B = {b}"))?;
        let (_, check) = self.measure()?;
        let last = standards.last().copied().unwrap_or_default();
        self.say(&format!(
            "the probe now reads {:.5}{} in the {last}{} standard (error {:+.5})",
            check.mean,
            self.unit(),
            self.unit(),
            check.mean - last
        ))?;
        Ok(Outcome { runs, fit, written: (k, b), check })
    }

    fn show_fit(&mut self, runs: &[StandardRun], fit: &LinearFit) -> Result<()> {
        let how = if runs.len() == 1 { "one standard: an offset" } else { "least-squares line" };
        self.say(&format!("\nfit ({how}), standard = K x reading + B:"))?;
        self.say(&format!("  K = {}", fit.k))?;
        self.say(&format!("  B = {}", fit.b))?;
        for (run, residual) in runs.iter().zip(&fit.residuals) {
            self.say(&format!(
                "  standard {}: mean reading {:.5}, residual {residual:+.5}",
                run.standard, run.stats.mean
            ))?;
        }
        if let Some(r2) = fit.r_squared {
            self.say(&format!("  R² = {r2:.6}"))?;
        }
        Ok(())
    }
}

/// The history's record of a finished calibration.
fn record_of(
    probe: &Probe<'_>,
    target: &Target<'_>,
    args: &CalibrateLinearArgs,
    before: &BTreeMap<String, f32>,
    outcome: &Outcome,
) -> Result<Calibration> {
    let mut record = probe.record("linear", args.history.note.as_deref());
    let block = target.write.name.clone();
    let (k_name, b_name) = target.names()?;
    let (k, b) = outcome.written;
    record.block = Some(block.clone());
    record.before = json!({ &block: before.iter().map(|(n, v)| (n.clone(), f32_json(*v))).collect::<Map<_, _>>() });
    record.after = json!({ &block: { k_name: f32_json(k), b_name: f32_json(b) } });
    record.standards = json!(args.standards);
    record.readings = json!(
        outcome
            .runs
            .iter()
            .map(|r| json!({
                "standard": r.standard,
                "field": target.field,
                "settling": r.settling,
                "readings": r.readings,
                "mean": r.stats.mean,
                "sd": r.stats.sd,
                "cv_percent": r.stats.cv_percent,
            }))
            .collect::<Vec<_>>()
    );
    record.fit = Some(json!({
        "k": outcome.fit.k,
        "b": outcome.fit.b,
        "residuals": outcome.fit.residuals,
        "r_squared": outcome.fit.r_squared,
        "check": {"standard": args.standards.last(), "mean": outcome.check.mean, "sd": outcome.check.sd},
    }));
    Ok(record)
}

/// Runs `calibrate SENSOR`.
pub fn run(catalog: &Catalog, args: &CalibrateLinearArgs, stop: &AtomicBool, out: &mut dyn Write) -> Result<()> {
    let Some(name) = args.sensor.as_deref() else {
        return Err(CliError::usage("`calibrate` needs a sensor (or the subcommand `ph`)")
            .hint("yosemitech calibrate SENSOR --standard VALUE ... -p PORT; `yosemitech list` names the sensors"));
    };
    let entry = catalog.entry(name)?;
    let target = target(&entry.sensor, args.quantity.as_deref())?;
    check_args(args, &target)?;
    let slave = args.address.get(entry.sensor.default_address)?;
    ensure_can_ask(args.yes, "calibrate")?;
    // The history opens before anything is written: a calibration is always recorded.
    let (mut store, history_file) = history::open(catalog, &args.history)?;
    let mut opened = port::open(&args.port, &entry.sensor.serial)?;
    let identity = history::identity(&mut opened, entry, slave);
    let serial_number = identity.0.clone();
    let unit = target.unit.as_deref().map(|u| format!(" {u}")).unwrap_or_default();
    writeln!(
        out,
        "K/B calibration of {} ({}) at address {slave} on {}{}",
        target.field,
        target.write.name,
        opened.port,
        serial_number.as_deref().map(|sn| format!(" (SN {sn})")).unwrap_or_default()
    )?;
    let shown: Vec<String> = args.standards.iter().map(|s| format!("{s}{unit}")).collect();
    writeln!(out, "standards in order: {}; {} readings averaged in each", shown.join(", "), args.readings)?;
    if !target.recommended.is_empty() {
        let recommended: Vec<String> = target.recommended.iter().map(|s| format!("{s}{unit}")).collect();
        writeln!(out, "the manual recommends: {}", recommended.join(", "))?;
    }
    out.flush()?;
    confirm(args.yes, "Start the calibration? (every coefficient is saved first)")?;

    // The backup: without it nothing is written.
    let not_started = |e: CliError| CliError {
        message: format!("{}; the calibration did not start, nothing was written", e.message),
        ..e
    };
    let blocks = backup::read_blocks(&mut opened, entry, slave).map_err(not_started)?;
    let saved = Backup::taken_now(&opened, entry, slave, serial_number, blocks);
    let path = backup::save_in(args.backup.dir.as_deref(), &saved).map_err(not_started)?;
    let restore = backup::restore_command(catalog, entry, &saved.port, slave, &path);
    writeln!(out, "saved every coefficient to {}", path.display())?;
    writeln!(out, "restore with: {restore}")?;
    let before = saved
        .blocks
        .get(&target.write.name)
        .cloned()
        .ok_or_else(|| not_started(CliError::device(format!("the backup has no `{}`", target.write.name))))?;

    let mut session = Session { opened: &mut opened, slave, target: &target, args, input: stdin_lines(), stop, out };
    match session.run() {
        Ok(outcome) => {
            writeln!(out, "calibrated; the previous coefficients restore with: {restore}")?;
            let probe = Probe { entry, address: slave, port: opened.port.clone(), identity };
            let record = record_of(&probe, &target, args, &before, &outcome)?;
            history::record(&mut store, &history_file, &record, out)?;
            Ok(())
        }
        Err(e) => {
            // Whatever stopped it, the probe gets its saved block back.
            let values: BTreeMap<String, Value> = before.iter().map(|(k, v)| (k.clone(), Value::Float(*v))).collect();
            let e = match backup::write_block(&mut opened, target.write, target.read_back, slave, &values) {
                Ok(()) => e.detail(format!(
                    "{} was written back as saved before the calibration and read back bit for bit",
                    target.write.name
                )),
                Err(again) => e
                    .detail(format!("writing back the saved coefficients failed too: {}", again.message))
                    .detail(format!("restore them with: {restore}")),
            };
            Err(e)
        }
    }
}
