//! `yosemitech sniff`: another master's traffic on a bus, decoded as it is
//! heard. Reads a port (never writing to it) or a capture it wrote, hands
//! the bytes with their times to [`crate::explain::sniff::Sniffer`], and
//! prints each exchange as it completes, then a summary.

use std::fs::File;
use std::io::{BufRead, BufReader, BufWriter, Write};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use clap::Args;
use serde_json::{Value as Json, json};
use yosemitech_rtu::{LineSettings, SerialConfig, SerialTransport, Transport};

use crate::catalog::Catalog;
use crate::error::{CliError, Result};
use crate::explain::Commands;
use crate::explain::sniff::{Heard, Sniffer, Timing, millis};
use crate::explain::{Report, Status};
use crate::explained::{report_json, report_text, values_text};
use crate::format::{csv_field, hex, parse_duration, parse_frame};
use crate::port::open_failed;

mod summary;

use self::summary::Summary;

/// `sniff`: where to listen and how to print.
#[derive(Args, Debug)]
pub struct SniffArgs {
    /// Serial port of the adapter on the bus (opened to read only: sniff never sends a byte).
    #[arg(short, long, env = "YOSEMITECH_PORT", value_name = "PATH", required_unless_present = "replay")]
    pub port: Option<String>,
    /// Baud rate of the bus [default: 9600, the probes' factory setting].
    #[arg(short, long, env = "YOSEMITECH_BAUD", value_name = "BAUD")]
    pub baud: Option<u32>,
    /// Hear a capture `--raw` wrote instead of a port, with its times.
    #[arg(long, value_name = "FILE", conflicts_with_all = ["port", "raw"])]
    pub replay: Option<PathBuf>,
    /// Also write every byte heard, with its time, to FILE (for --replay and `decode --capture`).
    #[arg(long, value_name = "FILE")]
    pub raw: Option<PathBuf>,
    /// The master's reply timeout: a later reply is flagged, e.g. 500ms [default: 1s].
    #[arg(long, value_name = "DURATION", value_parser = parse_duration, default_value = "1s")]
    pub reply_timeout: Duration,
    /// A silence that ends a frame [default: twice t3.5 at the baud, at least 5ms].
    #[arg(long, value_name = "DURATION", value_parser = parse_duration)]
    pub silence: Option<Duration>,
    /// Stop after this long, e.g. 10m [default: until Ctrl-C].
    #[arg(long = "for", value_name = "DURATION", value_parser = parse_duration)]
    pub duration: Option<Duration>,
    /// Only consider this sensor's commands.
    #[arg(long, value_name = "SENSOR")]
    pub sensor: Option<String>,
    /// Print JSON lines (one per exchange, then a summary).
    #[arg(long, conflicts_with = "csv")]
    pub json: bool,
    /// Print CSV (a header, one row per exchange; the summary on stderr).
    #[arg(long)]
    pub csv: bool,
}

/// How entries are printed.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Output {
    Text,
    Json,
    Csv,
}

/// The columns of `--csv`.
const CSV_HEADER: &str = "time_s,slave,status,command,values,latency_ms,gap_before_ms,flags,problems,request,reply";

/// The first line of a `--raw` capture.
const RAW_HEADER: &str = "# yosemitech sniff capture: seconds since the start, then the bytes as they arrived";

/// Runs `sniff` until the input ends, `--for` is over or `stop` is set (Ctrl-C).
pub fn run(catalog: &Catalog, args: &SniffArgs, stop: &Arc<AtomicBool>, out: &mut dyn Write) -> Result<()> {
    let mut commands = Commands::new(catalog.entries().iter().map(|e| &*e.sensor));
    if let Some(name) = &args.sensor {
        commands.sensor = Some(catalog.entry(name)?.sensor.name.as_str());
    }
    let baud = args.baud.unwrap_or(LineSettings::default().baud);
    if baud == 0 {
        return Err(
            CliError::usage("--baud 0 is not a baud rate").hint("Yosemitech probes use 9600 unless reconfigured")
        );
    }
    let settings = LineSettings { baud, ..LineSettings::default() };
    let mut timing = Timing::of_line(settings.timing(), args.reply_timeout);
    if let Some(silence) = args.silence {
        timing = Timing { silence, split_wait: timing.split_wait.max(silence * 2), ..timing };
    }
    let output = match (args.json, args.csv) {
        (true, _) => Output::Json,
        (_, true) => Output::Csv,
        _ => Output::Text,
    };
    let mut sniffer = Sniffer::new(&commands, timing);
    let mut printer = Printer { output, out, summary: Summary::default() };
    printer.start()?;
    match &args.replay {
        Some(path) => replay(path, &mut sniffer, &mut printer)?,
        None => listen(args, settings, stop, &mut sniffer, &mut printer)?,
    }
    let last = sniffer.finish();
    printer.print(&last)?;
    printer.finish(&sniffer)
}

/// Reads the port until stopped.
fn listen(
    args: &SniffArgs,
    settings: LineSettings,
    stop: &AtomicBool,
    sniffer: &mut Sniffer<'_, '_>,
    printer: &mut Printer<'_>,
) -> Result<()> {
    let port = match args.port.as_deref().map(str::trim) {
        Some(p) if p.starts_with("tcp://") => {
            return Err(CliError::usage(format!("sniff listens on a serial line, not {p}"))
                .hint("tap the RS-485 pair with a second adapter and give its port, e.g. --port /dev/ttyUSB1"));
        }
        Some(p) if !p.is_empty() => p.to_owned(),
        _ => {
            return Err(CliError::usage("no port given")
                .hint("pass --port with the adapter on the bus (or set YOSEMITECH_PORT), or --replay FILE"));
        }
    };
    // Only `read` is ever called on the transport: a sniffer must not drive the line.
    let mut transport = SerialTransport::open(&SerialConfig::with_settings(port.clone(), settings))
        .map_err(|e| open_failed(&port, &e))?;
    // What the adapter held from before we listened has no times to frame it by.
    transport.discard_input().map_err(|e| CliError::device(format!("clearing {port}'s input: {e}")))?;
    let mut raw = match &args.raw {
        Some(path) => Some(raw_file(path, &format!("{port} at {settings}"))?),
        None => None,
    };
    let _ = writeln!(
        std::io::stderr(),
        "sniff: listening on {port} at {settings} (a silence of {} ends a frame); Ctrl-C stops",
        millis(sniffer.timing().silence)
    );
    let started = Instant::now();
    let poll = (sniffer.timing().silence / 2).max(Duration::from_millis(1));
    let mut buf = [0u8; 512];
    while !stop.load(Ordering::SeqCst) && args.duration.is_none_or(|d| started.elapsed() < d) {
        let n = transport.read(&mut buf, poll).map_err(|e| CliError::device(format!("reading {port}: {e}")))?;
        // Heard at the capture's resolution, so that its replay hears the same times.
        let now = whole_micros(started.elapsed());
        let heard = match buf.get(..n).filter(|b| !b.is_empty()) {
            Some(bytes) => {
                if let Some(raw) = &mut raw {
                    writeln!(raw, "{}.{:06}: {}", now.as_secs(), now.subsec_micros(), hex(bytes))
                        .and_then(|()| raw.flush())
                        .map_err(|e| CliError::device(format!("writing the capture: {e}")))?;
                }
                sniffer.push(now, bytes)
            }
            None => sniffer.tick(now),
        };
        printer.print(&heard)?;
    }
    Ok(())
}

/// A new capture file with its header.
fn raw_file(path: &Path, what: &str) -> Result<BufWriter<File>> {
    let mut file = File::create(path)
        .map(BufWriter::new)
        .map_err(|e| CliError::usage(format!("cannot create the capture {}: {e}", path.display())))?;
    writeln!(file, "{RAW_HEADER}\n# {what}")
        .map_err(|e| CliError::usage(format!("cannot write the capture {}: {e}", path.display())))?;
    Ok(file)
}

/// Hears a capture `--raw` wrote, with its times.
fn replay(path: &Path, sniffer: &mut Sniffer<'_, '_>, printer: &mut Printer<'_>) -> Result<()> {
    let shown = path.display();
    let file = File::open(path).map_err(|e| {
        CliError::usage(format!("cannot read the capture {shown}: {e}")).hint("give a file `sniff --raw FILE` wrote")
    })?;
    let mut last = Duration::ZERO;
    for (i, line) in BufReader::new(file).lines().enumerate() {
        let line = line.map_err(|e| CliError::usage(format!("{shown}: line {}: {e}", i + 1)))?;
        let line = line.trim();
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        let bad = |why: &str| {
            CliError::usage(format!("{shown}: line {}: {why}", i + 1))
                .hint("a capture line is `SECONDS: HEX BYTES`, as `sniff --raw` writes it")
        };
        let (time, bytes) = line.split_once(": ").ok_or_else(|| bad("no `SECONDS: ` before the bytes"))?;
        let at = capture_time(time.trim()).ok_or_else(|| bad(&format!("`{time}` is not a time in seconds")))?;
        if at < last {
            return Err(bad(&format!("{time} s goes back in time")));
        }
        last = at;
        let bytes = parse_frame(bytes).map_err(|e| bad(&e.message))?;
        let heard = sniffer.push(at, &bytes);
        printer.print(&heard)?;
    }
    // The line stays quiet after the capture's end.
    let heard = sniffer.tick(last + sniffer.timing().give_up + sniffer.timing().split_wait);
    printer.print(&heard)
}

/// A time cut to the microseconds a capture keeps.
fn whole_micros(time: Duration) -> Duration {
    Duration::new(time.as_secs(), time.subsec_micros() * 1_000)
}

/// A capture's `SECONDS[.FRACTION]`, read exactly (through a float, 1.000001
/// would come back a nanosecond short and move a latency's last digit); digits
/// past the microsecond are cut, as the capture cuts them.
fn capture_time(text: &str) -> Option<Duration> {
    let (whole, fraction) = text.split_once('.').unwrap_or((text, ""));
    let digits = |s: &str| !s.is_empty() && s.bytes().all(|b| b.is_ascii_digit());
    if !digits(whole) || !(fraction.is_empty() || digits(fraction)) {
        return None;
    }
    let micros =
        fraction.bytes().chain(std::iter::repeat(b'0')).take(6).fold(0u32, |n, b| n * 10 + u32::from(b - b'0'));
    Some(Duration::new(whole.parse().ok()?, micros * 1_000))
}

/// Prints entries as they are heard, and counts them.
struct Printer<'o> {
    output: Output,
    out: &'o mut dyn Write,
    summary: Summary,
}

impl Printer<'_> {
    fn start(&mut self) -> Result<()> {
        if self.output == Output::Csv {
            writeln!(self.out, "{CSV_HEADER}")?;
        }
        Ok(())
    }

    fn print(&mut self, heard: &[Heard<'_>]) -> Result<()> {
        for h in heard {
            self.summary.add(h);
            match self.output {
                Output::Text => writeln!(self.out, "{}", text_line(h))?,
                Output::Json => writeln!(self.out, "{}", serde_json::to_string(&heard_json(h)).unwrap_or_default())?,
                Output::Csv => writeln!(self.out, "{}", csv_row(h))?,
            }
        }
        if !heard.is_empty() {
            // A closed pipe ends the listening with an error, not silently.
            self.out.flush()?;
        }
        Ok(())
    }

    fn finish(&mut self, sniffer: &Sniffer<'_, '_>) -> Result<()> {
        let identified = sniffer.identified();
        match self.output {
            Output::Json => {
                writeln!(self.out, "{}", serde_json::to_string(&self.summary.json(&identified)).unwrap_or_default())?
            }
            Output::Text => {
                for line in self.summary.lines(&identified) {
                    writeln!(self.out, "{line}")?;
                }
            }
            Output::Csv => {
                let mut err = std::io::stderr().lock();
                for line in self.summary.lines(&identified) {
                    let _ = writeln!(err, "{line}");
                }
            }
        }
        self.out.flush()?;
        Ok(())
    }
}

/// `  +12.345 s  address 1   ph_orp get_ph: ph = 7.02 pH  (reply after 45.2 ms)`.
fn text_line(h: &Heard<'_>) -> String {
    let mut line = format!("{:>10.3} s  {}", h.at().as_secs_f64(), report_text(&h.report));
    if let Some(latency) = h.latency {
        line += &format!("  (reply after {})", millis(latency));
    }
    for flag in &h.flags {
        line += &format!("  [{flag}]");
    }
    if let Report::Exchange(x) = &h.report
        && !matches!(x.status, Status::Decoded | Status::Ambiguous | Status::UnknownCommand | Status::Unpaired)
        && let Some(problem) = x.problems.first()
        && !line.contains(&problem.to_string())
    {
        line += &format!("  [{problem}]");
    }
    line
}

/// The entry as `decode --json` prints it, with its times and flags.
fn heard_json(h: &Heard<'_>) -> Json {
    let mut doc = report_json(&h.report);
    let ms = |d: Duration| (d.as_secs_f64() * 1e6).round() / 1e3;
    let extra = json!({
        "time_s": h.at().as_secs_f64(),
        "request_time_s": h.first.map(|t| t.first.as_secs_f64()),
        "reply_time_s": h.reply.map(|t| t.first.as_secs_f64()),
        "latency_ms": h.latency.map(ms),
        "gap_before_ms": h.gap_before.map(ms),
        "flags": h.flags.iter().map(|f| json!({ "flag": f.name(), "text": f.to_string() })).collect::<Vec<_>>(),
    });
    if let (Json::Object(doc), Json::Object(extra)) = (&mut doc, extra) {
        doc.extend(extra);
    }
    doc
}

/// One `--csv` row (see [`CSV_HEADER`]).
fn csv_row(h: &Heard<'_>) -> String {
    let doc = report_json(&h.report);
    let text = |key: &str| doc.get(key).and_then(Json::as_str).unwrap_or_default().to_owned();
    let slave = doc.get("slave").and_then(Json::as_u64).map(|s| s.to_string()).unwrap_or_default();
    let values = match &h.report {
        Report::Exchange(x) => x.chosen().map(values_text).unwrap_or_default(),
        _ => String::new(),
    };
    let problems = doc
        .get("problems")
        .and_then(Json::as_array)
        .map(|p| p.iter().filter_map(Json::as_str).collect::<Vec<_>>().join("; "))
        .unwrap_or_default();
    let ms = |d: Option<Duration>| d.map(|d| format!("{:.3}", d.as_secs_f64() * 1000.0)).unwrap_or_default();
    let (request, reply) = match &h.report {
        Report::Exchange(x) => (
            x.request.as_ref().map(|(f, _)| hex(&f.bytes)).unwrap_or_default(),
            x.reply.as_ref().map(|f| hex(&f.bytes)).unwrap_or_default(),
        ),
        Report::Noise(f) => (String::new(), hex(&f.bytes)),
        Report::Unreadable { .. } => (String::new(), String::new()),
    };
    let flags = h.flags.iter().map(|f| f.name()).collect::<Vec<_>>().join(";");
    [
        format!("{:.6}", h.at().as_secs_f64()),
        slave,
        text("status"),
        text("command"),
        values,
        ms(h.latency),
        ms(h.gap_before),
        flags,
        problems,
        request,
        reply,
    ]
    .iter()
    .map(|field| csv_field(field))
    .collect::<Vec<_>>()
    .join(",")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_capture_time_reads_back_as_written() {
        for nanos in [0u64, 1, 999, 1_000, 1_000_001, 1_234_567_891, 86_399_999_999_999] {
            let heard = whole_micros(Duration::from_nanos(nanos));
            let written = format!("{}.{:06}", heard.as_secs(), heard.subsec_micros());
            assert_eq!(capture_time(&written), Some(heard), "{written}");
        }
        assert_eq!(capture_time("2"), Some(Duration::from_secs(2)));
        assert_eq!(capture_time("2.5"), Some(Duration::from_millis(2500)));
        assert_eq!(capture_time("2.0000019"), Some(Duration::from_micros(2_000_001)));
        for bad in ["", ".", "-1.0", "1e3", "1.2.3", " 1.0", "1,5", "18446744073709551616.0"] {
            assert_eq!(capture_time(bad), None, "{bad:?}");
        }
    }
}
