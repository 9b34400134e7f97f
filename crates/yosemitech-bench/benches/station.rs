//! Station scale: one logger process (`yosemitech_station::logger`) with 8
//! buses of 4 simulated probes each, every bus a pty whose simulator
//! emulates the line at the probes' spec speed (9600 baud); and rows per
//! second with and without read planning for every sensor where planning
//! saves a read.
//!
//! The simulators run in a child process (this program re-executed with
//! `--serve`), so that `getrusage(RUSAGE_SELF)` in the parent counts the
//! logger's CPU time only: bus threads, the store writer and SQLite.
//!
//! Each probe samples with `interval = "1ms"`, so every bus is always busy;
//! a bus's share of its wire limit is the sum, over the transactions it
//! completed, of `(request + reply) × character time + 2 × t3.5` (the
//! probe's turnaround and the master's gap, as `transaction_limit` has it),
//! divided by the run's wall time.
//!
//! `cargo bench -p yosemitech-bench --bench station` runs it (about 30 s;
//! `--measurement-time S` sets the scale run's length, default 10 s);
//! without `--bench` (as under `cargo test --benches`) it runs for 1 s.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use std::collections::BTreeMap;
use std::io::{BufRead, BufReader, Read as _, Write as _};
use std::process::{Command as Process, Stdio};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

use yosemitech_bench::{spec_dir, transaction_limit};
use yosemitech_rtu::LineTiming;
use yosemitech_sim::{Bus, ServeConfig, Simulator, line_timing, serve_pty};
use yosemitech_spec::{Command, Sensor};
use yosemitech_station::plan::{self, Plan};
use yosemitech_station::{Store, config, link, logger};

const BUSES: usize = 8;
const PROBES_PER_BUS: usize = 4;

/// Every sensor of the spec with a measurement, cycled to `n`.
fn sensors(n: usize) -> Vec<Arc<Sensor>> {
    let spec = yosemitech_spec::load_paths(&[spec_dir()]).expect("the spec loads");
    let all: Vec<Arc<Sensor>> =
        spec.sensors.into_iter().filter(|s| !plan::measurements(s).is_empty()).map(Arc::new).collect();
    all.iter().cycle().take(n).cloned().collect()
}

/// The probes of bus `b`: (sensor, address).
fn bus_probes(all: &[Arc<Sensor>], b: usize) -> Vec<(Arc<Sensor>, u8)> {
    (0..PROBES_PER_BUS).map(|p| (Arc::clone(&all[(b * PROBES_PER_BUS + p) % all.len()]), p as u8 + 1)).collect()
}

/// Child mode: serve the buses, print their ptys, run until stdin closes.
fn serve() {
    let all = sensors(BUSES * PROBES_PER_BUS);
    let servers: Vec<_> = (0..BUSES)
        .map(|b| {
            let probes = bus_probes(&all, b);
            let timing = line_timing(&probes[0].0);
            let bus = probes.iter().fold(Bus::new(), |bus, (s, a)| bus.with(Simulator::new(Arc::clone(s)).with_address(*a)));
            serve_pty(bus, ServeConfig::emulating(timing)).expect("a pty")
        })
        .collect();
    let mut out = std::io::stdout().lock();
    for s in &servers {
        writeln!(out, "{}", s.tty_path().unwrap()).unwrap();
    }
    out.flush().unwrap();
    drop(out);
    let _ = std::io::stdin().read_to_end(&mut Vec::new());
}

/// User and system CPU time of this process.
fn cpu_time() -> Duration {
    let mut usage = std::mem::MaybeUninit::<libc::rusage>::zeroed();
    // SAFETY: getrusage writes a `rusage` into the pointer it is given.
    #[allow(unsafe_code)]
    let usage = unsafe {
        libc::getrusage(libc::RUSAGE_SELF, usage.as_mut_ptr());
        usage.assume_init()
    };
    let tv = |t: libc::timeval| Duration::from_secs(t.tv_sec as u64) + Duration::from_micros(t.tv_usec as u64);
    tv(usage.ru_utime) + tv(usage.ru_stime)
}

/// The wire limit of one read: request, reply, turnaround and gap.
fn read_limit(line: LineTiming, command: &Command) -> Duration {
    transaction_limit(line, 8, 5 + 2 * usize::from(command.count), line.t3_5())
}

fn plan_limit(line: LineTiming, plan: &Plan<'_>) -> Duration {
    plan.reads.iter().map(|r| read_limit(line, r.command)).sum()
}

fn scale(run_for: Duration) {
    let mut child = Process::new(std::env::current_exe().unwrap())
        .arg("--serve")
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .spawn()
        .expect("the simulator process starts");
    let mut lines = BufReader::new(child.stdout.take().unwrap()).lines();
    let ptys: Vec<String> = (0..BUSES).map(|_| lines.next().unwrap().unwrap()).collect();

    let all = sensors(BUSES * PROBES_PER_BUS);
    let dir = tempfile::tempdir().unwrap();
    let mut toml = format!("station = \"bench\"\n[storage]\npath = \"{}\"\n", dir.path().join("s.sqlite").display());
    for (b, pty) in ptys.iter().enumerate() {
        toml += &format!("[[bus]]\nname = \"bus{b}\"\nport = \"{pty}\"\nretries = 0\n");
        for (i, (s, a)) in bus_probes(&all, b).iter().enumerate() {
            toml += &format!(
                "[[bus.probe]]\nlabel = \"b{b}p{i}\"\nsensor = \"{}\"\naddress = {a}\ninterval = \"1ms\"\nprocedure = false\n",
                s.name
            );
        }
    }
    let path = dir.path().join("station.toml");
    std::fs::write(&path, &toml).unwrap();
    let station = config::load(&path, &all).unwrap_or_else(|e| panic!("{e}"));
    let store = Mutex::new(Store::open(&station.storage).unwrap());
    let stop = AtomicBool::new(false);

    let (cpu0, t0) = (cpu_time(), Instant::now());
    let reports = std::thread::scope(|scope| {
        let logger = scope.spawn(|| logger::run(&station, &store, &stop, &|_, _| {}));
        std::thread::sleep(run_for);
        stop.store(true, Ordering::SeqCst);
        logger.join().unwrap().unwrap()
    });
    let (cpu, elapsed) = (cpu_time() - cpu0, t0.elapsed());
    drop(child.stdin.take());
    let _ = child.wait();

    let rows = store.lock().unwrap().range(UNIX_EPOCH, SystemTime::now() + Duration::from_secs(60)).unwrap();
    let mut per_probe: BTreeMap<(String, String), (u64, u64, bool, bool)> = BTreeMap::new();
    for r in &rows {
        let e = per_probe.entry((r.reading.bus.clone(), r.reading.probe.clone())).or_default();
        if r.reading.error.is_none() {
            e.0 += 1;
        } else {
            e.1 += 1;
        }
        e.2 |= r.reading.serial_number.is_some();
        e.3 |= r.reading.firmware.is_some();
    }
    println!("station_scale: {BUSES} buses x {PROBES_PER_BUS} probes, {:.1} s, line emulated at the spec's speed", elapsed.as_secs_f64());
    println!("| bus | probes (sensor: rows) | transactions | failed | wire time of those | % of wire limit |");
    println!("|---|---|---|---|---|---|");
    let mut shares = Vec::new();
    let mut total_tx = 0;
    for (bus, report) in station.buses.iter().zip(&reports) {
        let line = line_timing(&bus.probes[0].sensor);
        let mut wire = Duration::ZERO;
        let mut who = Vec::new();
        for probe in &bus.probes {
            let chosen: Vec<&str> = probe.measurements.iter().map(String::as_str).collect();
            let planned = plan::plan(&probe.sensor, &chosen);
            let (ok, failed, serial, firmware) =
                per_probe.get(&(bus.name.clone(), probe.label.clone())).copied().unwrap_or_default();
            wire += plan_limit(line, &planned) * u32::try_from(ok).unwrap();
            for (read, role) in [(serial, yosemitech_spec::Role::SerialNumber), (firmware, yosemitech_spec::Role::Version)] {
                if let (true, Some(c)) = (read, probe.sensor.command_with_role(role)) {
                    wire += read_limit(line, c);
                }
            }
            who.push(format!("{}: {ok}{}", probe.sensor.name, if failed > 0 { format!(" ({failed} failed)") } else { String::new() }));
        }
        let share = 100.0 * wire.as_secs_f64() / elapsed.as_secs_f64();
        shares.push(share);
        total_tx += report.transactions;
        println!(
            "| {} | {} | {} | {} | {:.3} s | {share:.1} % |",
            bus.name,
            who.join(", "),
            report.transactions,
            report.failed_transactions,
            wire.as_secs_f64()
        );
    }
    let min = shares.iter().copied().fold(f64::INFINITY, f64::min);
    println!(
        "station_scale: {total_tx} transactions, {} readings; lowest bus {min:.1} % of its wire limit; CPU {:.3} s = {:.1} µs per transaction ({:.1} % of one core)",
        rows.len(),
        cpu.as_secs_f64(),
        cpu.as_secs_f64() * 1e6 / total_tx as f64,
        100.0 * cpu.as_secs_f64() / elapsed.as_secs_f64()
    );
}

/// Rows per second of one probe on its own emulated line, reading `plan`.
fn rows_per_second(sensor: &Arc<Sensor>, plan: &Plan<'_>, run_for: Duration) -> (f64, u64) {
    let server = serve_pty(Simulator::new(Arc::clone(sensor)).with_address(1), ServeConfig::emulating(line_timing(sensor)))
        .expect("a pty");
    let link = config::Link::Serial { port: server.tty_path().unwrap().to_owned(), serial: sensor.serial };
    let mut master = link::open(&link, Duration::from_secs(1)).unwrap();
    let (mut rows, mut errors) = (0u64, 0u64);
    let start = Instant::now();
    while start.elapsed() < run_for {
        for read in &plan.reads {
            errors += u64::from(link::transact(&mut master, read.command, 1, 0).result.is_err());
        }
        rows += 1;
    }
    (rows as f64 / start.elapsed().as_secs_f64(), errors)
}

fn planning(run_for: Duration) {
    println!("| sensor | measurements | reads planned | rows/s planned | limit | reads naive | rows/s naive | limit | errors |");
    println!("|---|---|---|---|---|---|---|---|---|");
    let spec = yosemitech_spec::load_paths(&[spec_dir()]).expect("the spec loads");
    for sensor in spec.sensors.into_iter().map(Arc::new) {
        let chosen = plan::measurements(&sensor);
        let (planned, naive) = (plan::plan(&sensor, &chosen), plan::naive(&sensor, &chosen));
        if planned.reads.len() >= naive.reads.len() {
            continue;
        }
        let line = line_timing(&sensor);
        let (with, e1) = rows_per_second(&sensor, &planned, run_for);
        let (without, e2) = rows_per_second(&sensor, &naive, run_for);
        println!(
            "| {} | {} | {} | {with:.1} | {:.1} | {} | {without:.1} | {:.1} | {} |",
            sensor.name,
            chosen.join(", "),
            planned.reads.len(),
            1.0 / plan_limit(line, &planned).as_secs_f64(),
            naive.reads.len(),
            1.0 / plan_limit(line, &naive).as_secs_f64(),
            e1 + e2
        );
    }
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    if args.iter().any(|a| a == "--serve") {
        serve();
        return;
    }
    if args.iter().any(|a| a == "--list") {
        println!("station_scale: benchmark");
        return;
    }
    let bench = args.iter().any(|a| a == "--bench") && !args.iter().any(|a| a == "--test");
    let seconds = args
        .iter()
        .position(|a| a == "--measurement-time")
        .and_then(|i| args.get(i + 1))
        .and_then(|v| v.parse::<f64>().ok())
        .unwrap_or(10.0);
    let run_for = if bench { Duration::from_secs_f64(seconds) } else { Duration::from_secs(1) };
    scale(run_for);
    planning(if bench { Duration::from_secs(5) } else { Duration::from_millis(500) });
}
