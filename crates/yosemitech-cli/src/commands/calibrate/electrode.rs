//! `yosemitech calibrate ph --compute`: the electrode coefficients K1..K6
//! computed here, by the vendor's model
//! ([`yosemitech::procedures::ph_electrode`]), from the potential and the
//! temperature in each buffer: measured through the port, or taken from a
//! CSV file of readings made with another tool (`--readings`). With a port
//! the result is shown against the probe's own, written after a
//! confirmation and a backup of every coefficient, and read back bit for
//! bit; without one nothing is written.

use std::io::{self, Write};
use std::path::Path;
use std::sync::mpsc::Receiver;
use std::time::Duration;

use yosemitech::procedures::ph_electrode::{BufferReading, compute};
use yosemitech::procedures::{RealSleep, Sleep, same_bits};
use yosemitech::{Command, ph_orp};

use super::{CalibratePhArgs, SENSOR, save_backup, stdin_lines};
use crate::catalog::Catalog;
use crate::confirm::ensure_can_ask;
use crate::device::is_typed;
use crate::error::{CliError, Result, request_failed, show_duration};
use crate::format::f32_json;
use crate::history::{self, Probe};
use crate::port;

/// Readings averaged in each buffer.
const READINGS_PER_BUFFER: usize = 5;
/// Between two of them.
const READING_INTERVAL: Duration = Duration::from_secs(1);

/// The reads taken in each buffer, `(command, field)`: the potential, then
/// the temperature (what [`run`] reads through the typed device).
pub const READS: [(&str, &str); 2] =
    [(<ph_orp::GetOrpAndPh as Command>::NAME, "orp_mv"), (<ph_orp::GetTemperature as Command>::NAME, "temperature_c")];

/// Reads `--readings`: a header `buffer,mv,temperature_c`, then one line per buffer.
fn read_csv(path: &Path) -> Result<Vec<BufferReading>> {
    let text =
        std::fs::read_to_string(path).map_err(|e| CliError::usage(format!("cannot read {}: {e}", path.display())))?;
    let at = |line: usize, what: String| {
        CliError::usage(format!("{}:{line}: {what}", path.display()))
            .hint("the file is CSV: a header `buffer,mv,temperature_c`, then one line per buffer (4.00, 6.86, 9.18)")
    };
    let mut lines = text.lines().enumerate().filter(|(_, l)| !l.trim().is_empty());
    let header: Vec<String> = match lines.next() {
        Some((_, l)) => l.split(',').map(|c| c.trim().to_ascii_lowercase()).collect(),
        None => return Err(at(1, "the file is empty".into())),
    };
    if header != ["buffer", "mv", "temperature_c"] {
        return Err(at(1, format!("the header is `{}`, not `buffer,mv,temperature_c`", header.join(","))));
    }
    let mut readings = Vec::new();
    for (index, line) in lines {
        let cells: Vec<&str> = line.split(',').map(str::trim).collect();
        let [buffer, mv, t] = cells.as_slice() else {
            return Err(at(index + 1, format!("{} values, not 3: `{line}`", cells.len())));
        };
        let number = |cell: &str, what: &str| {
            cell.parse::<f32>()
                .ok()
                .filter(|v| v.is_finite())
                .ok_or_else(|| at(index + 1, format!("{what} `{cell}` is not a number")))
        };
        readings.push(BufferReading {
            buffer_ph: number(buffer, "buffer")?,
            potential_mv: number(mv, "mv")?,
            temperature_c: number(t, "temperature_c")?,
        });
    }
    Ok(readings)
}

/// Waits for a line on `input`; `q` or the end of input stops.
fn wait_for_enter(input: &Receiver<String>, what: &str) -> Result<()> {
    match input.recv() {
        Ok(line) if line.trim().eq_ignore_ascii_case("q") => {
            Err(CliError::device(format!("stopped by the user at {what}; nothing was written")))
        }
        Ok(_) => Ok(()),
        Err(_) => Err(CliError::device(format!("stdin ended before {what} was confirmed; nothing was written"))
            .hint("answer each buffer prompt with Enter (a line on stdin)")),
    }
}

/// Runs `calibrate ph --compute` (and `calibrate ph --readings FILE`).
pub fn run(catalog: &Catalog, args: &CalibratePhArgs, out: &mut dyn Write) -> Result<()> {
    let entry = catalog.entry(SENSOR)?;
    if !is_typed(entry, SENSOR) {
        return Err(CliError::usage(format!("`calibrate ph --compute` needs the built-in {SENSOR} sensor"))
            .hint("a --spec file replaced it; run without --spec"));
    }
    let from_file = match &args.readings {
        Some(path) => Some(read_csv(path)?),
        None => None,
    };
    if from_file.is_none() && args.port.port.is_none() {
        return Err(CliError::usage("`calibrate ph --compute` needs --port (to measure) or --readings FILE")
            .hint("give --readings FILE to compute from readings taken with another tool; nothing is written then"));
    }
    // Offline: compute and show, write nothing.
    let Some(_) = args.port.port.as_ref() else {
        let readings = from_file.unwrap_or_default();
        let k = compute(&readings).map_err(|e| CliError::usage(format!("cannot compute K1..K6: {e}")))?;
        if args.json {
            return print_json(out, &readings, &k, None, false);
        }
        return show(out, &readings, &k, None);
    };
    let slave = args.address.get(entry.sensor.default_address)?;
    ensure_can_ask(args.yes, "write electrode coefficients")?;
    let (mut store, history_file) = history::open(catalog, &args.history)?;
    let mut opened = port::open(&args.port, &entry.sensor.serial)?;
    let ctx = opened.context(slave, "the electrode calibration");
    let input = stdin_lines();
    let readings = match from_file {
        Some(readings) => readings,
        None => {
            let mut probe = ph_orp::Device::new(&mut opened.bus, slave);
            let mut readings = Vec::new();
            for buffer_ph in ph_orp::PH_CALIBRATION_STANDARDS {
                let say = |out: &mut dyn Write, text: String| -> Result<()> {
                    if !args.json {
                        writeln!(out, "{text}")?;
                        out.flush()?;
                    } else {
                        eprintln!("{text}");
                    }
                    Ok(())
                };
                say(
                    out,
                    format!("rinse the probe, put it in the pH {buffer_ph:.2} buffer, then press Enter (q quits)"),
                )?;
                wait_for_enter(&input, &format!("buffer {buffer_ph:.2}"))?;
                if !args.skip_wait {
                    let settle = Duration::from_millis(u64::from(ph_orp::PH_CALIBRATION_SETTLE_MS));
                    say(out, format!("  letting the probe settle for {}", show_duration(settle)))?;
                    RealSleep.sleep(settle);
                }
                let (mut mv, mut t) = (0.0f32, 0.0f32);
                for n in 0..READINGS_PER_BUFFER {
                    if n > 0 && !args.skip_wait {
                        RealSleep.sleep(READING_INTERVAL);
                    }
                    let e = probe.orp_and_ph().map_err(|e| request_failed(&e, probe.client().last_reply(), &ctx))?;
                    let temperature =
                        probe.temperature().map_err(|e| request_failed(&e, probe.client().last_reply(), &ctx))?;
                    mv += e.orp_mv;
                    t += temperature.temperature_c;
                }
                let reading = BufferReading {
                    buffer_ph,
                    potential_mv: mv / READINGS_PER_BUFFER as f32,
                    temperature_c: t / READINGS_PER_BUFFER as f32,
                };
                say(
                    out,
                    format!(
                        "  mean of {READINGS_PER_BUFFER} readings: {:.2} mV at {:.2} °C",
                        reading.potential_mv, reading.temperature_c
                    ),
                )?;
                readings.push(reading);
            }
            readings
        }
    };
    let k =
        compute(&readings).map_err(|e| CliError::device(format!("cannot compute K1..K6: {e}; nothing was written")))?;
    let current = {
        let mut probe = ph_orp::Device::new(&mut opened.bus, slave);
        let c = probe.ph_electrode_coefficients().map_err(|e| request_failed(&e, probe.client().last_reply(), &ctx))?;
        [c.k1, c.k2, c.k3, c.k4, c.k5, c.k6]
    };
    if !args.json {
        show(out, &readings, &k, Some(&current))?;
        out.flush()?;
    }
    // The write: confirmed, after a backup of every coefficient.
    // (Without --yes stdin is a terminal, `ensure_can_ask` saw to it; its
    // lines come through `input`, which the buffer prompts read too.)
    if !args.yes {
        eprint!("Write these K1..K6 to the probe at address {slave}? [y/N] ");
        let answer = input.recv().unwrap_or_default();
        if !matches!(answer.trim().to_ascii_lowercase().as_str(), "y" | "yes") {
            return Err(CliError::device("not confirmed: nothing was written"));
        }
    }
    let identity = history::identity(&mut opened, entry, slave);
    let mut quiet = io::sink();
    let backup_out: &mut dyn Write = if args.json { &mut quiet } else { out };
    let (restore, _) = save_backup(&mut opened, catalog, entry, slave, identity.0.clone(), args, backup_out)?;
    let with_restore = |e: CliError| e.detail(format!("to restore the coefficients saved before the write: {restore}"));
    let mut probe = ph_orp::Device::new(&mut opened.bus, slave);
    let [k1, k2, k3, k4, k5, k6] = k;
    probe
        .set_ph_electrode_coefficients(ph_orp::SetPhElectrodeCoefficients { k1, k2, k3, k4, k5, k6 })
        .map_err(|e| with_restore(request_failed(&e, probe.client().last_reply(), &ctx)))?;
    let back = probe
        .ph_electrode_coefficients()
        .map_err(|e| with_restore(request_failed(&e, probe.client().last_reply(), &ctx)))?;
    let back = [back.k1, back.k2, back.k3, back.k4, back.k5, back.k6];
    if !same_bits(&back, &k) {
        return Err(with_restore(CliError::device(format!(
            "the probe read back K1..K6 = {back:?}, not what was written ({k:?})"
        ))));
    }
    let probe = Probe { entry, address: slave, port: opened.port.clone(), identity };
    let mut record = probe.record("ph_electrode", args.history.note.as_deref());
    let block = <ph_orp::SetPhElectrodeCoefficients as Command>::NAME;
    let named = |v: &[f32; 6]| -> serde_json::Map<String, serde_json::Value> {
        ["k1", "k2", "k3", "k4", "k5", "k6"].iter().zip(v).map(|(n, v)| ((*n).to_owned(), f32_json(*v))).collect()
    };
    record.block = Some(block.to_owned());
    record.before = serde_json::json!({ block: named(&current) });
    record.after = serde_json::json!({ block: named(&k) });
    record.standards = serde_json::json!(readings.iter().map(|r| r.buffer_ph).collect::<Vec<_>>());
    record.readings = serde_json::json!(
        readings
            .iter()
            .map(|r| serde_json::json!({
                "buffer": r.buffer_ph, "mv": r.potential_mv, "temperature_c": r.temperature_c,
            }))
            .collect::<Vec<_>>()
    );
    if args.json {
        let mut quiet = io::sink();
        history::record(&mut store, &history_file, &record, &mut quiet)?;
        print_json(out, &readings, &k, Some(&current), true)
    } else {
        writeln!(out, "written and read back: K1..K6 = {}", join(&k))?;
        writeln!(out, "restore the previous coefficients with: {restore}")?;
        history::record(&mut store, &history_file, &record, out)?;
        Ok(())
    }
}

fn join(k: &[f32]) -> String {
    k.iter().map(|v| format!("{v:.4}")).collect::<Vec<_>>().join(", ")
}

/// The readings and the coefficients as one JSON document: `previous` the
/// probe's before the write (`null` offline), `written` whether they are now its.
fn print_json(
    out: &mut dyn Write,
    readings: &[BufferReading],
    k: &[f32; 6],
    previous: Option<&[f32; 6]>,
    written: bool,
) -> Result<()> {
    let names = ["k1", "k2", "k3", "k4", "k5", "k6"];
    let map = |v: &[f32; 6]| -> serde_json::Map<String, serde_json::Value> {
        names.iter().zip(v).map(|(n, v)| ((*n).to_owned(), serde_json::json!(v))).collect()
    };
    let doc = serde_json::json!({
        "readings": readings.iter().map(|r| serde_json::json!({
            "buffer": r.buffer_ph, "mv": r.potential_mv, "temperature_c": r.temperature_c,
        })).collect::<Vec<_>>(),
        "coefficients": map(k),
        "previous": previous.map(map),
        "written": written,
    });
    writeln!(out, "{}", serde_json::to_string_pretty(&doc).unwrap_or_default())?;
    Ok(())
}

/// The readings and the coefficients, against the probe's when read.
fn show(out: &mut dyn Write, readings: &[BufferReading], k: &[f32; 6], current: Option<&[f32; 6]>) -> Result<()> {
    writeln!(out, "electrode coefficients by the vendor's model, from:")?;
    for r in readings {
        writeln!(out, "  buffer {:.2}: {:.2} mV at {:.2} °C", r.buffer_ph, r.potential_mv, r.temperature_c)?;
    }
    match current {
        Some(current) => {
            writeln!(out, "       computed     the probe's")?;
            for (i, (new, old)) in k.iter().zip(current).enumerate() {
                writeln!(out, "  K{}  {new:>10.4}  {old:>10.4}", i + 1)?;
            }
        }
        None => {
            for (i, new) in k.iter().enumerate() {
                writeln!(out, "  K{}  {new:>10.4}", i + 1)?;
            }
            writeln!(out, "nothing written: give --port to write them to a probe")?;
        }
    }
    Ok(())
}
