//! The command line: the tool's options and its subcommands, whose
//! arguments are beside each command (`commands/`).

use crate::args::Global;
use crate::commands::calibrate::CalibrateArgs;
use crate::commands::coefficients::CoefficientsSubcommand;
use crate::commands::decode::DecodeCommandArgs;
use crate::commands::demo::DemoArgs;
use crate::commands::doctor::DoctorArgs;
use crate::commands::encode::EncodeArgs;
use crate::commands::export::ExportArgs;
use crate::commands::ingest::IngestArgs;
use crate::commands::list::ListArgs;
use crate::commands::log::LogArgs;
use crate::commands::measure::MeasureArgs;
use crate::commands::plot::PlotArgs;
use crate::commands::poll::PollArgs;
use crate::commands::read::ReadArgs;
use crate::commands::scan::ScanArgs;
use crate::commands::set_address::SetAddressArgs;
use crate::commands::simulate::SimulateArgs;
use crate::commands::sniff::SniffArgs;
use crate::commands::watch::WatchArgs;
use crate::commands::write::WriteArgs;
use clap::Parser;

const LONG_ABOUT: &str = "\
Field tool for Yosemitech water-quality probes on Modbus RTU. Every sensor of the spec is built in:
{sensors}.

Everything the tool knows about a probe comes from the YAML transcriptions of the vendor
manuals compiled into it (see `yosemitech list`). `--spec DIR` adds spec files at run time:
a new sensor works with the generic commands (list, read, write, poll, measure, decode,
encode, scan) before the tool is rebuilt.

Generic commands work on any command of any sensor through the spec's reference
interpreter (`measure` runs the procedure a spec states, `coefficients` saves and restores
the coefficient blocks a spec pairs, `calibrate SENSOR` calibrates any user calibration block,
`demo` runs every sensor simulated); `calibrate ph` and `set-address` follow the manuals'
procedures through the typed `yosemitech` crate.

Exit codes: 0 success, 1 device or protocol error, 2 usage error.";

const AFTER_HELP: &str = "\
Examples:
{examples}

The port and baud rate may also come from YOSEMITECH_PORT and YOSEMITECH_BAUD.";

/// `yosemitech`: the command line.
#[derive(Parser, Debug)]
#[command(
    name = "yosemitech",
    version,
    about = "Read, log, calibrate, scan and simulate Yosemitech water-quality probes over Modbus RTU",
    long_about = LONG_ABOUT,
    after_help = AFTER_HELP,
    propagate_version = true,
    arg_required_else_help = true
)]
pub struct Cli {
    /// Options every subcommand takes.
    #[command(flatten)]
    pub global: Global,
    /// What to do.
    #[command(subcommand)]
    pub command: Subcommand,
}

/// The subcommands.
#[derive(clap::Subcommand, Debug)]
pub enum Subcommand {
    /// Simulate every sensor of the spec on pseudo-terminals and talk to them.
    #[command(long_about = "\
Start every sensor of the spec simulated on a pseudo-terminal of its own (no hardware, no
root) and run a short session through the real serial code path: read each probe's identity
(serial number, hardware and software revisions), every measurement, its calibration status
and coefficients; run each manual's measuring procedure with the waits shortened; then put
the whole family on one bus and identify it as `scan` does. Takes a second or two.")]
    Demo(DemoArgs),

    /// List the sensors and commands of the spec.
    #[command(long_about = "\
List the sensors the tool knows (built in, plus --spec files) and their commands: function,
start register, register count, and each field's type, unit, byte offset, size and byte order.
--json prints the same as JSON for other programs.")]
    List(ListArgs),

    /// Send any read command and show the values with their units.
    #[command(long_about = "\
Send any read command of a sensor's spec and show the reply's values with their units.
COMMAND is the spec's name (`{read}`); a read's leading `get_` may be left out.")]
    Read(ReadArgs),

    /// Send any write command, after confirmation, and read it back.
    #[command(long_about = "\
Send any write command of a sensor's spec. VALUES are `field=value` pairs or values in field
order; they are checked against the spec's ranges before anything is sent. The frame is shown
and confirmed first (--yes skips the question; without a terminal on stdin, --yes is required).
Where a read command covers the same registers, the values are read back and compared.
Writes of calibration coefficients first save every coefficient to a timestamped JSON file
and print the command that restores it.")]
    Write(WriteArgs),

    /// Log timestamped measurements at an interval (table, CSV or JSON lines).
    #[command(long_about = "\
Read the measurements of a sensor (fields of its reads that no write covers and that carry a
unit; every one unless named, by field or by read) at an interval, one row per poll with an
RFC 3339 UTC timestamp. Each poll sends the fewest reads that cover them: a combined read
where the spec has one instead of a read per quantity. Errors are reported in the row's
`error` column and polling goes on; the exit code is 1 only if every poll failed. Ctrl-C ends
cleanly. --interval 0 polls back to back.")]
    Poll(PollArgs),

    /// Run a sensor's measuring procedure (its manual's section 3) and average the readings.
    #[command(long_about = "\
Run the measuring procedure the sensor's manual states (its spec's `procedure`): send the
commands that start a measurement (a trigger, the brush), wait the warm-up, take the readings
the manual asks for at its interval, and print the mean of every numeric field with its unit
(enum and flag fields: the last value and how often each occurred; a field that reads its
`absent` value, a sub-probe not fitted, is reported absent, not averaged). Commands to send
afterwards are sent at the end. Works for every sensor whose spec states a procedure,
including --spec files; `yosemitech list SENSOR` shows it. Progress bars show the warm-up and
the readings when stderr is a terminal.")]
    Measure(MeasureArgs),

    /// Watch a station's store: every probe's latest values, sparklines and error counts.
    #[command(long_about = "\
A terminal view of a station's store (the SQLite file `yosemitech log` writes), refreshed at
an interval: one box per probe with its sensor, serial number, error and retry counts, and for
each measurement the latest value with its unit, its age and a sparkline of the values over
--window. The store is only read; a logger may be writing it. q, Esc or Ctrl-C quits.")]
    Watch(WatchArgs),

    /// Draw a chart (PNG or SVG) of a time range of a station's store.
    #[command(long_about = "\
Draw the readings of a station's store between --from and --to as a chart: one panel per
measurement, one line per probe, a UTC time axis. The file's extension chooses the format
(.png or .svg). Times are UTC (2025-11-23, 2025-11-23T06:00:00Z), a time ago (90m, 6h, 2d)
or now. Values that are not numbers (NaN) break a line. Fails (exit 1) when the range holds
no reading, and (exit 2) for an unknown probe or measurement.")]
    Plot(PlotArgs),

    /// Run a guided calibration: any probe's K/B block, or the pH probe's own.
    #[command(long_about = CALIBRATE_LONG_ABOUT)]
    Calibrate(Box<CalibrateArgs>),

    /// Back up or restore every calibration coefficient of a probe (JSON).
    #[command(subcommand)]
    Coefficients(CoefficientsSubcommand),

    /// Find the probes on a bus and name each one's model and firmware.
    #[command(long_about = "\
Find the probes on a bus and identify each one. At every address the serial number is read
(the loaded sensors' serial-number reads, the most common layout first; a probe that lacks a
register does not answer, so most addresses cost one read, a probe of a rarer layout two). The model code in
the byte before the serial number (real probes send it there) or in its characters 3-4
(`YL09...`) names the sensor whose spec declares that `model_code`; where no single loaded
sensor matches, the candidates are listed with the reason. One more read gives the hardware
and software revisions, and the manual revision that covers that firmware. The reply timeout
defaults to 100ms here and retries to 0 (--timeout, --retries).")]
    Scan(ScanArgs),

    /// Find out why a probe does not answer: a guided diagnosis of the line.
    #[command(long_about = "\
Diagnose a probe that does not answer, read-only: send it a serial-number read and look at
every byte that comes back. It tells apart no byte at all (power, wiring, A/B, port), the
adapter's echo of our own request, garbage (other serial settings: it tries the common baud
rates in 8N1, 8N2, 8E1, 8O1 and says which answers), replies damaged at a rate (noise,
termination), several probes on one address, a probe at another address (the wildcard 0xFF,
then a scan) or only at 0xFF, a reply later than --reply-timeout (it measures the turnaround),
exceptions, and a refused Start Measurement. Ends with a verdict and the next thing to try,
each finding with the bytes seen. A silent line takes about 40 s; Ctrl-C stops with what it
found so far. --json for a machine-readable report.")]
    Doctor(DoctorArgs),

    /// Change a probe's slave address, verified at the new one.
    #[command(long_about = "\
Change a probe's slave address: both addresses are checked (1..=247, the new one free), the
change is confirmed, sent, and verified at the new address. If anything fails after the write,
the tool finds out where the probe answers and says so.

With --plan, a bus of probes that all leave the factory at the same address (1): connect them
one at a time, leaving the others connected; each is identified (serial number, model), given
the next free address of a plan spaced apart (3, 5, 7, ... by default), and verified there.
It ends with the bus table (address in decimal and hex, serial number, model), from which
--station-toml writes a draft station file.")]
    SetAddress(SetAddressArgs),

    /// Decode frames from a log or a bus capture: command, fields with units, CRC.
    #[command(long_about = DECODE_ABOUT, after_help = DECODE_EXAMPLES)]
    Decode(DecodeCommandArgs),

    /// Listen to a bus another master drives and decode its traffic live.
    #[command(long_about = SNIFF_ABOUT, after_help = SNIFF_EXAMPLES)]
    Sniff(SniffArgs),

    /// Build a request (or reply) frame offline.
    #[command(long_about = "\
Print the frame of a command: the request (for a write, VALUES as field=value or in order),
or with --response the reply a probe would send (for a read, VALUES are the reply's fields).")]
    Encode(EncodeArgs),

    /// Serve a simulated probe on a pseudo-terminal or TCP for other tools.
    #[command(long_about = "\
Serve a sensor simulated from its spec until Ctrl-C: on a new pseudo-terminal (--pty, the
default) or over TCP (--tcp ADDR): as an RTU-over-TCP gateway, or with --protocol mbap as a
Modbus TCP gateway (unit id = the probe's address; a probe that stays silent or answers
garbage gets exception 0x0B, as from a gateway). The first line on stdout is the port to
give other tools (the pty path, tcp://ADDR or mbap://ADDR). Faults can be injected:
--faults drop=0.05,corrupt_crc=0.02 (kinds: drop, corrupt_crc, truncate, garbage,
wrong_slave, delay, busy; all=P spreads P over every kind; delay_by=500ms).")]
    Simulate(SimulateArgs),

    /// Run a station: several probes on several buses, on a schedule, into a SQLite file.
    #[command(long_about = "\
Run the station a TOML file describes: buses (serial ports or RTU-over-TCP gateways), the
probes on each (sensor, address, label, measurements, interval, clock alignment, the spec's
procedure), and the SQLite file every reading is committed to before anything else happens
with it. One master per bus, probes interleaved; a probe that does not answer backs off
without delaying the others. Ctrl-C or SIGTERM stops after the request in flight.
--check validates the file against the spec, prints a summary and exits.")]
    Log(LogArgs),

    /// Write stored readings as CSV or JSON lines.
    #[command(long_about = "\
Write the readings of a station's SQLite file (`yosemitech log`) for a time range: CSV in long
form (one row per value, the reading's columns repeated) or one JSON object per reading.
Times are UTC (2025-11-23 or 2025-11-23T18:00:00Z), a time ago (90m, 6h, 2d) or now; --from
is inclusive, --to exclusive.")]
    Export(ExportArgs),

    /// Store the readings of many stations, from their MQTT broker, in PostgreSQL.
    #[command(long_about = INGEST_ABOUT)]
    Ingest(IngestArgs),
}

const INGEST_ABOUT: &str = "\
Subscribe to every station's reading topic on the broker the stations publish to (`log` with an
[mqtt] section) and store each reading in PostgreSQL: readings, stations and probes (serial
number, sensor, firmware, calibration in force), in a schema `ingest` creates and migrates
itself (docs/postgres.md). A delivery is acknowledged to the broker only once its transaction is
committed, and a reading is stored once however often it is delivered (its identity is the
station's reading id), so a worker may be killed at any moment. Several workers with the same
--group share the readings (an MQTT 5 shared subscription); each needs its own --client-id, its
session on the broker, which must keep sessions across restarts (mosquitto: persistence true).
`export --postgres` reads the readings back.";

const CALIBRATE_LONG_ABOUT: &str = "\
`calibrate SENSOR --standard VALUE ...` calibrates a probe's user calibration block (the
write with role `user_calibration`: final = K x raw + B) in standards of known value. Every
coefficient is saved to a JSON file first (the calibration stops if it cannot be saved), then
K = 1, B = 0 are written, and for each standard in turn: put the probe in it and press Enter
(q quits), watch the readings until they are stable (the coefficient of variation over
--window readings below --cv-threshold, after the spec's settling wait; Enter on a line
accepts them as they are), and --readings readings are averaged (mean, SD, CV). One standard
gives an offset (K = 1), two or more a least-squares line: K, B, each standard's residual and
R² are shown, confirmed, written and read back bit for bit, and the probe is read once more
through them. Stopping at any step (q, end of input, Ctrl-C, a device error, a failed
read-back) writes the saved coefficients back and reads them back. --quantity FIELD names the
measured field when the spec does not say what the block calibrates, or picks one of several
blocks. Every calibration is recorded (`calibrate history`): in the station's store with
--config station.toml (its readings then carry the calibration's id), else in --history FILE or
calibrations.sqlite in the user's data directory.

`calibrate ph` is the pH manual's own three-point calibration (see `calibrate ph --help`).";

const DECODE_ABOUT: &str = "\
Decode frames copied from a log or a bus analyser: one frame, a request and its reply, or a
whole capture. HEX may have spaces, 0x prefixes, commas or colons; several arguments are one
byte stream (`decode REQ REPLY` and `decode \"REQ REPLY\"` are the same).

One frame: the command is identified from the frame where that is unambiguous (requests by
function, start address and register count; replies by length, byte count and function
across every sensor, replies from 0xFF only as commands with a fixed slave address);
otherwise the candidates are listed and --sensor / --command choose. Every field is shown
with its unit, Modbus exceptions are decoded, and the CRC is checked (with the expected CRC
when it is wrong).

Several frames (a request and its reply, a hex stream, or --capture): the bytes are split
into frames. A request is recognised by matching a command's request (function, start
address, register count, CRC, and the fixed slave address where the command has one); a
reply by its CRC and the length the pending request's command expects (5 bytes for an
exception). Each reply is paired with the request before it (same slave, or the command's
fixed slave) and decoded as the command(s) that request names. When several sensors share
the request (the serial-number read is in every probe), the reply is decoded as each:
decodings that fail are dropped, equal ones are reported together (`COMMAND of SENSOR,
SENSOR`), and different ones are all listed: an ambiguity that --sensor / --command resolve
(they only narrow the decoding: a transaction of a command they leave out is reported as
unknown).

--capture FILE (`-` for stdin) reads a capture: one frame per line, or one hex stream
(possibly wrapped over lines; whichever reading explains more bytes as frames wins). A label
before a colon and a space (`12:00:01.250 TX: 01 03 ...`) is skipped, and so are up to four
leading words before the frame (`2024-05-01 12:00:01 01 03 ...`); blank lines and lines
starting with # are ignored. Unpaired frames, noise and lines that are not hex are reported
and decoding goes on.

--json: a single frame or a single request/reply pair prints one JSON document; anything
more (and every --capture) prints JSON lines, one object per transaction, unpaired reply,
noise run or unreadable line, then a `summary` line. Each has a `type` (transaction, reply,
noise, unreadable, summary), an `ok` flag and a `status`: decoded, exception, broadcast (ok);
ambiguous, undecodable, no_reply, unknown_command, unpaired, noise, unreadable (failed).
A transaction lists every reading in `decodings`; when there is one, its `command`,
`sensors`, `values` and `fields` are also at the top. Errors are JSON too: a document with
an `error` object (message, hint, details, exit_code) on stdout; the `error:` line on stderr
and the exit code stay as without --json.

Exit codes: 0 when every frame was decoded (a Modbus exception reply counts as decoded);
1 when a frame check fails (CRC, length, slave) or, for several frames, when some frame
could not be paired or decoded, or was ambiguous; 2 for usage errors: malformed hex, an
unreadable capture file, an ambiguous single frame or pair (choose with --sensor/--command).";

const SNIFF_ABOUT: &str = "\
Listen to a bus that another master (a data logger, a PLC, a display) drives, through a second
adapter on the RS-485 pair, and decode what it hears as it hears it. The port is opened to read
only: sniff never sends a byte, so it cannot disturb the bus.

Bytes are timestamped as they arrive and framed by the line's silences and the spec's lengths
together: frames back to back with short gaps are told apart by their lengths and CRCs, and a
frame a slow adapter hands over in pieces is waited for and flagged (a silence inside a frame
makes a probe drop it). Each request is paired with the reply that follows it. One line per
exchange: the time since the start, the slave, the command and sensor it fits (narrowed to one
sensor as the slave's traffic shows which it is), the values with their units, the reply's
latency, and what breaks the rules: a silence inside a frame, a reply later than --reply-timeout, a
wrong CRC or byte count, an exception, a request with no reply, a reply with no request. Noise
is shown as noise and never ends the listening.

--json prints JSON lines as `decode --capture --json` does, with `time_s`, `latency_ms`,
`gap_before_ms` and `flags`; --csv one row per exchange. --raw FILE also records every byte with
its arrival time; `sniff --replay FILE` hears it again, the same way, and `decode --capture
FILE` reads it too. When it stops (Ctrl-C, --for, the end of a replay) it prints a summary per
slave: requests, replies, requests without reply, CRC errors, exceptions, late replies, and the
replies' latency (median, 90th percentile, longest).";

const SNIFF_EXAMPLES: &str = "\
Examples:
  yosemitech sniff --port /dev/ttyUSB1
  yosemitech sniff --port /dev/ttyUSB1 --raw bus.capture --for 10m
  yosemitech sniff --replay bus.capture --json | jq 'select(.flags != [])'
  yosemitech sniff --port /dev/ttyUSB1 --csv > bus.csv";

const DECODE_EXAMPLES: &str = "\
Examples:
  yosemitech decode {reply} --sensor {sensor} --command {read}
  yosemitech decode \"{request}\" \"{reply}\"
  yosemitech decode {frames} --json
  yosemitech decode --capture bus.log --json | jq 'select(.status != \"decoded\")'
  some-sniffer | yosemitech decode --capture -";
