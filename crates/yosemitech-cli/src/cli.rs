//! The command line: every subcommand, option and help text.

use std::path::PathBuf;
use std::time::{Duration, SystemTime};

use clap::{ArgAction, Args, Parser, ValueEnum};

use crate::format::{parse_duration, parse_size};
use crate::port::{AddressArg, PortArgs};
use crate::time::parse_instant_now as parse_instant;

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

/// Options every subcommand takes.
#[derive(Args, Debug, Clone, Default)]
pub struct Global {
    /// Load extra spec files from DIR (a directory of YAML files, or one file) at run time;
    /// repeatable. A file may include `yosemitech-common.yaml` without holding a copy.
    #[arg(long, value_name = "DIR", global = true)]
    pub spec: Vec<PathBuf>,
    /// Show frame dumps on stderr: -v every frame sent and received (debug), -vv everything (trace).
    #[arg(short, long, action = ArgAction::Count, global = true)]
    pub verbose: u8,
    /// Time allowed for each reply, e.g. 500ms, 2s [default: 1s; scan: 100ms].
    #[arg(long, value_name = "DURATION", value_parser = parse_duration, global = true)]
    pub timeout: Option<Duration>,
    /// Retries after a timeout or a corrupt reply [default: 2; scan: 0].
    #[arg(long, value_name = "N", global = true)]
    pub retries: Option<u32>,
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
then a scan) or only at 0xFF, a reply later than --timeout (it measures the turnaround),
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
}

/// `demo`.
#[derive(Args, Debug, Default)]
pub struct DemoArgs {
    /// Emulate the serial line's timing at 9600 baud (slower, like real probes).
    #[arg(long)]
    pub line_timing: bool,
}

/// `list`.
#[derive(Args, Debug)]
pub struct ListArgs {
    /// Only this sensor.
    pub sensor: Option<String>,
    /// Print JSON.
    #[arg(long)]
    pub json: bool,
}

/// `read`.
#[derive(Args, Debug)]
pub struct ReadArgs {
    /// Sensor (`yosemitech list` shows them).
    pub sensor: String,
    /// Read command (`yosemitech list SENSOR` shows them).
    pub command: String,
    #[command(flatten)]
    pub port: PortArgs,
    #[command(flatten)]
    pub address: AddressArg,
    /// Print JSON.
    #[arg(long)]
    pub json: bool,
    #[command(flatten)]
    pub inputs: InputArgs,
    /// Show values in another unit of the same dimension: `UNIT` for every
    /// value of its dimension (`degF`, `uS/cm`), `NAME=UNIT` for one field
    /// or derived quantity; repeatable.
    #[arg(long = "unit", value_name = "[NAME=]UNIT")]
    pub units: Vec<String>,
}

/// `write`.
#[derive(Args, Debug)]
pub struct WriteArgs {
    /// Sensor.
    pub sensor: String,
    /// Write command (`yosemitech list SENSOR` shows them).
    pub command: String,
    /// Values: field=value pairs, or values in field order.
    #[arg(value_name = "VALUES", allow_negative_numbers = true)]
    pub values: Vec<String>,
    #[command(flatten)]
    pub port: PortArgs,
    #[command(flatten)]
    pub address: AddressArg,
    /// Send without asking.
    #[arg(short, long)]
    pub yes: bool,
    /// Where to save the coefficient backup [default: the current directory].
    #[arg(long, value_name = "DIR")]
    pub backup_dir: Option<PathBuf>,
}

/// What `simulate --tcp` speaks.
#[derive(ValueEnum, Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum TcpProtocol {
    /// RTU frames (with CRC) over TCP, as a transparent serial gateway.
    #[default]
    Rtu,
    /// Modbus TCP: MBAP header, no CRC; several connections at once.
    Mbap,
}

/// Output formats of `poll`.
#[derive(ValueEnum, Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum PollFormat {
    /// Aligned columns with units.
    #[default]
    Table,
    /// Comma-separated values with a header row.
    Csv,
    /// One JSON object per line.
    Json,
}

/// `poll`.
#[derive(Args, Debug)]
pub struct PollArgs {
    /// Sensor.
    pub sensor: String,
    /// Measurements to read: field names or measurement reads (`yosemitech list SENSOR`) [default: every one].
    #[arg(value_name = "MEASUREMENT")]
    pub measurements: Vec<String>,
    #[command(flatten)]
    pub port: PortArgs,
    #[command(flatten)]
    pub address: AddressArg,
    /// Time between the starts of two polls; 0 polls back to back.
    #[arg(short, long, value_name = "DURATION", default_value = "3s", value_parser = parse_duration)]
    pub interval: Duration,
    /// Stop after N polls [default: until Ctrl-C].
    #[arg(short = 'n', long, value_name = "N")]
    pub count: Option<u64>,
    /// Output format.
    #[arg(short, long, value_enum, default_value_t = PollFormat::Table)]
    pub format: PollFormat,
    #[command(flatten)]
    pub inputs: InputArgs,
    /// Show values in another unit of the same dimension: `UNIT` for every
    /// value of its dimension (`degF`, `uS/cm`), `NAME=UNIT` for one field
    /// or derived quantity; repeatable.
    #[arg(long = "unit", value_name = "[NAME=]UNIT")]
    pub units: Vec<String>,
}

/// `measure`.
#[derive(Args, Debug)]
pub struct MeasureArgs {
    /// Sensor (`yosemitech list` shows which have a procedure).
    pub sensor: String,
    #[command(flatten)]
    pub port: PortArgs,
    #[command(flatten)]
    pub address: AddressArg,
    /// Print JSON.
    #[arg(long)]
    pub json: bool,
    /// Override the warm-up (tests, demos).
    #[arg(long, hide = true, value_parser = parse_duration)]
    pub warm_up: Option<Duration>,
    /// Override the reading interval (tests, demos).
    #[arg(long, hide = true, value_parser = parse_duration)]
    pub interval: Option<Duration>,
    /// Override the number of readings averaged (tests, demos).
    #[arg(long, hide = true)]
    pub readings: Option<u32>,
    /// Shorthand for --warm-up 0 --interval 0 (tests, demos).
    #[arg(long, hide = true)]
    pub fast: bool,
    #[command(flatten)]
    pub inputs: InputArgs,
}

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
    /// Where to save the coefficient backup [default: the current directory].
    #[arg(long, value_name = "DIR")]
    pub backup_dir: Option<PathBuf>,
    #[command(flatten)]
    pub history: HistoryArgs,
}

/// Where the calibration history is kept, and the note a calibration adds to it.
#[derive(Args, Debug, Default, Clone)]
pub struct HistoryArgs {
    /// Keep the history in this station's store (its readings then name the
    /// calibration in force).
    #[arg(long, value_name = "STATION_TOML", conflicts_with = "history")]
    pub config: Option<PathBuf>,
    /// The history file [default: calibrations.sqlite in $XDG_DATA_HOME/yosemitech or ~/.local/share/yosemitech].
    #[arg(long, value_name = "FILE")]
    pub history: Option<PathBuf>,
    /// The operator's note, kept with the calibration.
    #[arg(long, value_name = "TEXT")]
    pub note: Option<String>,
}

/// `calibrate history`.
#[derive(Args, Debug)]
pub struct CalibrateHistoryArgs {
    /// Only the calibrations of the probe with this serial number.
    #[arg(long, value_name = "SN")]
    pub sn: Option<String>,
    /// Print every calibration, with all its readings, as one JSON array.
    #[arg(long)]
    pub json: bool,
    #[command(flatten)]
    pub history: HistoryArgs,
}

/// `calibrate restore`.
#[derive(Args, Debug)]
pub struct CalibrateRestoreArgs {
    /// The calibration to write back (`calibrate history` lists the ids).
    pub id: i64,
    #[command(flatten)]
    pub port: PortArgs,
    #[command(flatten)]
    pub address: AddressArg,
    /// Write without asking.
    #[arg(short, long)]
    pub yes: bool,
    /// Where to save the coefficient backup [default: the current directory].
    #[arg(long, value_name = "DIR")]
    pub backup_dir: Option<PathBuf>,
    #[command(flatten)]
    pub history: HistoryArgs,
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
    /// Where to save the coefficient backup [default: the current directory].
    #[arg(long, value_name = "DIR")]
    pub backup_dir: Option<PathBuf>,
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

/// `coefficients`.
#[derive(clap::Subcommand, Debug)]
pub enum CoefficientsSubcommand {
    /// Save every calibration coefficient to a JSON file.
    Backup(CoefficientsBackupArgs),
    /// Write every calibration coefficient from a JSON file, then read it back.
    Restore(CoefficientsRestoreArgs),
}

/// `coefficients backup`.
#[derive(Args, Debug)]
pub struct CoefficientsBackupArgs {
    /// Sensor.
    pub sensor: String,
    #[command(flatten)]
    pub port: PortArgs,
    #[command(flatten)]
    pub address: AddressArg,
    /// The JSON file to write (not overwritten) [default: a timestamped file here].
    #[arg(short, long, value_name = "FILE")]
    pub file: Option<PathBuf>,
}

/// `coefficients restore`.
#[derive(Args, Debug)]
pub struct CoefficientsRestoreArgs {
    /// Sensor.
    pub sensor: String,
    #[command(flatten)]
    pub port: PortArgs,
    #[command(flatten)]
    pub address: AddressArg,
    /// The JSON file written by `coefficients backup` (or by a calibration).
    #[arg(short, long, value_name = "FILE")]
    pub file: PathBuf,
    /// Write without asking.
    #[arg(short, long)]
    pub yes: bool,
}

/// `scan`.
#[derive(Args, Debug)]
pub struct ScanArgs {
    #[command(flatten)]
    pub port: PortArgs,
    /// Addresses to probe: 1-247, 1,5,10-20 or 3.
    #[arg(long, value_name = "RANGES", default_value = "1-247")]
    pub addresses: String,
    /// Print JSON.
    #[arg(long)]
    pub json: bool,
}

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

const DECODE_EXAMPLES: &str = "\
Examples:
  yosemitech decode {reply} --sensor {sensor} --command {read}
  yosemitech decode \"{request}\" \"{reply}\"
  yosemitech decode {frames} --json
  yosemitech decode --capture bus.log --json | jq 'select(.status != \"decoded\")'
  some-sniffer | yosemitech decode --capture -";

/// `decode`: the frames and how to read them.
#[derive(Args, Debug)]
pub struct DecodeArgs {
    /// Frames in hex: one frame, a request and its reply, or a stream (arguments are joined).
    #[arg(value_name = "HEX", required_unless_present = "capture", conflicts_with = "capture", num_args = 1..)]
    pub hex: Vec<String>,
    /// Only consider this sensor's commands.
    #[arg(long, value_name = "SENSOR")]
    pub sensor: Option<String>,
    /// Decode as this command.
    #[arg(long, value_name = "COMMAND")]
    pub command: Option<String>,
    /// Print JSON (one document; JSON lines for several transactions and captures).
    #[arg(long)]
    pub json: bool,
}

/// `decode` on the command line: [`DecodeArgs`] and a capture file.
#[derive(Args, Debug)]
pub struct DecodeCommandArgs {
    /// The frames and options.
    #[command(flatten)]
    pub frames: DecodeArgs,
    /// Read a capture from FILE (`-`: stdin): one frame per line, or a hex stream.
    #[arg(long, value_name = "FILE")]
    pub capture: Option<PathBuf>,
}

/// `encode`.
#[derive(Args, Debug)]
pub struct EncodeArgs {
    /// Sensor.
    pub sensor: String,
    /// Command.
    pub command: String,
    /// Values: field=value pairs, or values in field order.
    #[arg(value_name = "VALUES", allow_negative_numbers = true)]
    pub values: Vec<String>,
    #[command(flatten)]
    pub address: AddressArg,
    /// Encode the reply instead of the request.
    #[arg(long)]
    pub response: bool,
}

/// `simulate`.
#[derive(Args, Debug)]
pub struct SimulateArgs {
    /// Sensor to simulate.
    pub sensor: String,
    #[command(flatten)]
    pub address: AddressArg,
    /// Serve on a new pseudo-terminal (the default).
    #[arg(long, conflicts_with = "tcp")]
    pub pty: bool,
    /// Serve over TCP on ADDR (127.0.0.1:5020; port 0 picks a free one).
    #[arg(long, value_name = "ADDR")]
    pub tcp: Option<String>,
    /// What --tcp speaks: raw RTU frames, as a transparent serial gateway
    /// (rtu), or Modbus TCP with MBAP headers, unit id = address (mbap).
    #[arg(long, value_enum, default_value_t = TcpProtocol::Rtu, requires = "tcp")]
    pub protocol: TcpProtocol,
    /// Faults to inject: kind=probability,... (see the long help).
    #[arg(long, value_name = "SPEC")]
    pub faults: Option<String>,
    /// Seed of the fault and noise generator.
    #[arg(long, value_name = "N", default_value_t = 1)]
    pub seed: u64,
    /// Noise amplitude added to every measurement, in its unit.
    #[arg(long, value_name = "X")]
    pub noise: Option<f32>,
    /// Serve plausible values of natural water (each quantity's typical
    /// value or the middle of its range, the temperature of a river) that
    /// follow a daily cycle, instead of the manual's example values.
    #[arg(long)]
    pub water: bool,
    /// Emulate the serial line's timing at the sensor's baud rate (at 9600 baud, about 1 ms a byte).
    #[arg(long)]
    pub line_timing: bool,
    /// Answer requests for registers the probe lacks with Modbus exceptions
    /// (01/02/03), as a general Modbus stack does; a real probe stays silent.
    #[arg(long)]
    pub exceptions: bool,
    /// Send the serial number exactly as the manual prints it (0x00 before
    /// it, the manual's text), instead of with the model code, as real probes do.
    #[arg(long)]
    pub serial_as_printed: bool,
    /// Line faults, to diagnose a link (`yosemitech doctor`).
    #[command(flatten)]
    pub line: SimulatedLineArgs,
}

/// `simulate`'s line faults: what a link to a probe can get wrong.
#[derive(Args, Debug, Default)]
pub struct SimulatedLineArgs {
    /// Never answer (a probe without power, or a broken wire).
    #[arg(long)]
    pub mute: bool,
    /// Write every request back before answering (an RS-485 adapter without echo suppression).
    #[arg(long)]
    pub echo: bool,
    /// Wait this long before every reply (a probe slow to answer), e.g. 1500ms.
    #[arg(long, value_name = "DURATION", value_parser = parse_duration)]
    pub turnaround: Option<Duration>,
    /// Run at these serial settings, BAUD-8N1 (8N2, 8E1, 8O1); on a pty a client at
    /// another baud rate or parity reads garbage (where the pty keeps parity: Linux ptys drop it).
    #[arg(long, value_name = "BAUD-FORMAT", conflicts_with = "tcp")]
    pub serial: Option<String>,
    /// Two probes at the address answer every request at once (their serial numbers differ).
    #[arg(long)]
    pub collide: bool,
    /// Refuse Start Measurement with an exception and answer reads all the same.
    #[arg(long)]
    pub refuse_start: bool,
}

/// `watch`.
#[derive(Args, Debug)]
pub struct WatchArgs {
    /// The station's store (the SQLite file `yosemitech log` writes).
    #[arg(long, value_name = "FILE")]
    pub db: PathBuf,
    /// Time between two reads of the store.
    #[arg(short, long, value_name = "DURATION", default_value = "2s", value_parser = parse_duration)]
    pub interval: Duration,
    /// How far back the sparklines and the error and retry counts reach.
    #[arg(long, value_name = "DURATION", default_value = "6h", value_parser = parse_duration)]
    pub window: Duration,
}

/// A station's store and a time range of it, as `plot` and `export` read them.
#[derive(Args, Debug)]
pub struct StoredRange {
    /// The station's store (the SQLite file `yosemitech log` writes).
    #[arg(long, value_name = "FILE")]
    pub db: PathBuf,
    /// First instant, inclusive (UTC) [default: the first reading].
    #[arg(long, value_name = "TIME", value_parser = parse_instant)]
    pub from: Option<SystemTime>,
    /// Last instant, exclusive (UTC) [default: plot: now; export: the last reading].
    #[arg(long, value_name = "TIME", value_parser = parse_instant)]
    pub to: Option<SystemTime>,
}

/// `plot`.
#[derive(Args, Debug)]
pub struct PlotArgs {
    /// The store and the time range.
    #[command(flatten)]
    pub range: StoredRange,
    /// Only this probe (its label in the station's configuration).
    #[arg(long, value_name = "LABEL")]
    pub probe: Option<String>,
    /// Only this measurement (the spec's field name).
    #[arg(long, value_name = "NAME")]
    pub measurement: Option<String>,
    /// The chart file: .png or .svg.
    #[arg(short, long, value_name = "FILE")]
    pub out: PathBuf,
    /// Width and height in pixels, e.g. 1200x800 [default: 1200 wide, 300 high per measurement].
    #[arg(long, value_name = "WxH", value_parser = parse_size)]
    pub size: Option<(u32, u32)>,
}

/// `log`.
#[derive(Args, Debug)]
pub struct LogArgs {
    /// The station file (TOML).
    #[arg(long, value_name = "FILE")]
    pub config: PathBuf,
    /// Validate the file against the spec, print a summary and exit.
    #[arg(long)]
    pub check: bool,
}

/// Output formats of `export`.
#[derive(ValueEnum, Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum ExportFormat {
    /// Comma-separated values, one row per value, with a header row.
    #[default]
    Csv,
    /// One JSON object per reading.
    Jsonl,
}

/// `export`.
#[derive(Args, Debug)]
pub struct ExportArgs {
    /// The store and the time range.
    #[command(flatten)]
    pub range: StoredRange,
    /// Output format.
    #[arg(short, long, value_enum, default_value_t = ExportFormat::Csv)]
    pub format: ExportFormat,
}

/// Station inputs of derived quantities (`read`, `poll`, `measure`).
#[derive(Args, Debug, Default)]
pub struct InputArgs {
    /// A station input of the sensor's derived quantities, e.g. `salinity=35` (repeatable) [default: the spec's].
    #[arg(long = "input", value_name = "NAME=VALUE", value_parser = crate::derived::parse_input)]
    pub inputs: Vec<(String, f64)>,
}
