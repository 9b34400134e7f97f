//! Bus efficiency: get_ph transactions per second through the real serial
//! code path (`SerialTransport` on a pseudo-terminal) against the simulated
//! pH probe emulating the line's timing, as a share of what the line allows.
//!
//! The limit of one transaction is its characters back to back (8 + 9 for
//! get_ph), the probe's turnaround of t3.5 and the master's gap before the
//! next request: `17 × character time + 2 × t3.5` is the wire limit (40 a
//! second at 9600 baud 8N1). The client's default gap is at least 4 ms
//! (`ClientConfig::min_inter_frame_delay`), longer than t3.5 at both rates
//! measured, so each rate is run twice: with the default, and with the gap
//! set to the exact t3.5. Each row states both shares: of the wire limit and
//! of the limit with the client's configured gap.
//!
//! `cargo bench -p yosemitech-bench --bench bus` runs it (about 20 s);
//! without `--bench` (as under `cargo test --benches`) or with `--test` it
//! does one transaction per rate and exits. `--measurement-time S` and
//! `--warm-up-time S` set the time per configuration (default 3 s and
//! 0.5 s). Results go to stdout and to `bus_efficiency/results.json` in
//! criterion's directory, for `bench-report`.

use std::io;
use std::time::{Duration, Instant};

use yosemitech::ph_orp::GetPh;
use yosemitech::{Client, ClientConfig, RetryPolicy, SerialConfig, SerialTransport};
use yosemitech_bench::{GET_PH_REPLY, GET_PH_REQUEST, GET_PH_VALUE, criterion_dir, ph_simulator, transaction_limit};
use yosemitech_rtu::{CharFormat, LineTiming};
use yosemitech_sim::{ServeConfig, Server, Simulator, serve_pty};

/// The benchmark's id, matched by command-line filters.
const ID: &str = "bus_efficiency";

/// Criterion options that take a value (skipped when looking for filters).
const VALUE_OPTIONS: &[&str] = &[
    "--sample-size",
    "--warm-up-time",
    "--measurement-time",
    "--nresamples",
    "--noise-threshold",
    "--confidence-level",
    "--significance-level",
    "--save-baseline",
    "--baseline",
    "--baseline-lenient",
    "--load-baseline",
    "--profile-time",
    "--color",
    "--output-format",
    "--format",
    "--plotting-backend",
    "--sampling-mode",
];

struct Args {
    /// Full measurement (`--bench` without `--test`).
    bench: bool,
    list: bool,
    /// Whether a filter excludes this benchmark.
    filtered_out: bool,
    warm_up: Duration,
    measurement: Duration,
}

fn parse_args() -> Args {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let flag = |name: &str| args.iter().any(|a| a == name);
    let seconds = |name: &str, default: f64| {
        let value = args.iter().position(|a| a == name).and_then(|i| args.get(i + 1)).and_then(|v| v.parse().ok());
        Duration::from_secs_f64(value.unwrap_or(default))
    };
    let mut filters = Vec::new();
    let mut i = 0;
    while let Some(arg) = args.get(i) {
        if VALUE_OPTIONS.contains(&arg.as_str()) {
            i += 1;
        } else if !arg.starts_with('-') {
            filters.push(arg.as_str());
        }
        i += 1;
    }
    Args {
        bench: flag("--bench") && !flag("--test"),
        list: flag("--list"),
        filtered_out: !filters.is_empty() && !filters.iter().any(|f| ID.contains(f)),
        warm_up: seconds("--warm-up-time", 0.5),
        measurement: seconds("--measurement-time", 3.0),
    }
}

/// The client's inter-frame gap in one run.
#[derive(Clone, Copy)]
enum Gap {
    /// `ClientConfig::default()`: t3.5, at least 4 ms.
    Default,
    /// `min_inter_frame_delay` = t3.5: exactly t3.5.
    ExactT35,
    /// No gap and no line emulation at all: the fixed cost of a
    /// transaction over the pty (a diagnostic, not an efficiency).
    NoneUntimed,
}

impl Gap {
    fn name(self) -> &'static str {
        match self {
            Gap::Default => "default (>= 4 ms)",
            Gap::ExactT35 => "exact t3.5",
            Gap::NoneUntimed => "none, line not emulated",
        }
    }
}

struct Outcome {
    baud: u32,
    gap: Gap,
    client_gap: Duration,
    transactions: usize,
    errors: usize,
    elapsed: Duration,
    /// Sorted durations of the measured transactions.
    durations: Vec<Duration>,
    line: LineTiming,
    /// The timer slack of the threads (`/proc/self/timerslack_ns`).
    timer_slack_ns: Option<u64>,
}

impl Outcome {
    fn per_second(&self) -> f64 {
        self.transactions as f64 / self.elapsed.as_secs_f64()
    }

    fn mean(&self) -> Duration {
        self.elapsed / u32::try_from(self.transactions.max(1)).unwrap_or(u32::MAX)
    }

    fn percentile(&self, p: f64) -> Duration {
        let i = ((self.durations.len().saturating_sub(1)) as f64 * p).round() as usize;
        self.durations.get(i).copied().unwrap_or_default()
    }

    fn wire_limit(&self) -> Duration {
        transaction_limit(self.line, GET_PH_REQUEST.len(), GET_PH_REPLY.len(), self.line.t3_5())
    }

    fn configured_limit(&self) -> Duration {
        transaction_limit(self.line, GET_PH_REQUEST.len(), GET_PH_REPLY.len(), self.client_gap)
    }

    fn share(&self, limit: Duration) -> f64 {
        100.0 * limit.as_secs_f64() / self.mean().as_secs_f64()
    }

    fn json(&self) -> serde_json::Value {
        let ms = |d: Duration| d.as_secs_f64() * 1e3;
        let timed = !matches!(self.gap, Gap::NoneUntimed);
        serde_json::json!({
            "baud": self.baud,
            "timer_slack_ns": self.timer_slack_ns,
            "client_gap": self.gap.name(),
            "client_gap_ms": ms(self.client_gap),
            "transactions": self.transactions,
            "errors": self.errors,
            "per_second": self.per_second(),
            "mean_ms": ms(self.mean()),
            "p50_ms": ms(self.percentile(0.5)),
            "p99_ms": ms(self.percentile(0.99)),
            "max_ms": ms(self.durations.last().copied().unwrap_or_default()),
            "wire_limit_ms": timed.then(|| ms(self.wire_limit())),
            "wire_limit_share": timed.then(|| self.share(self.wire_limit())),
            "configured_limit_ms": timed.then(|| ms(self.configured_limit())),
            "configured_limit_share": timed.then(|| self.share(self.configured_limit())),
        })
    }
}

/// Serves a pH probe on a pty, emulating `line` unless `untimed`.
fn serve(line: LineTiming, untimed: bool) -> io::Result<(Server<Simulator>, String)> {
    let sim = ph_simulator().map_err(io::Error::other)?;
    let config = if untimed { ServeConfig::default() } else { ServeConfig::emulating(line) };
    let server = serve_pty(sim, config)?;
    let path = server.tty_path().ok_or_else(|| io::Error::other("no pty path"))?.to_string();
    Ok((server, path))
}

fn run(baud: u32, gap: Gap, warm_up: Duration, measurement: Duration) -> io::Result<Outcome> {
    let line = LineTiming::new(baud, CharFormat::EIGHT_N_1);
    let (server, path) = serve(line, matches!(gap, Gap::NoneUntimed))?;
    let transport = SerialTransport::open(&SerialConfig { baud, ..SerialConfig::new(path) })?;
    let mut config =
        ClientConfig { timeout: Duration::from_secs(1), retry: RetryPolicy::NONE, ..ClientConfig::default() };
    match gap {
        Gap::Default => {}
        Gap::ExactT35 => config.min_inter_frame_delay = line.t3_5(),
        Gap::NoneUntimed => config.inter_frame_delay = Some(Duration::ZERO),
    }
    let mut client = Client::with_config(transport, config);
    let client_gap = client.inter_frame_delay();

    let call = |client: &mut Client<SerialTransport>| match client.call(1, &GetPh) {
        Ok(reply) if reply.ph == GET_PH_VALUE => true,
        Ok(reply) => {
            eprintln!("unexpected pH {}", reply.ph);
            false
        }
        Err(e) => {
            eprintln!("get_ph failed: {e}");
            false
        }
    };
    let start = Instant::now();
    loop {
        call(&mut client);
        if start.elapsed() >= warm_up {
            break;
        }
    }
    // Room for the longest run: 115200 baud at the wire limit is ~200/s.
    let mut durations = Vec::with_capacity(500 + measurement.as_millis() as usize);
    let (mut transactions, mut errors) = (0, 0);
    let start = Instant::now();
    loop {
        let t = Instant::now();
        if call(&mut client) {
            transactions += 1;
        } else {
            errors += 1;
        }
        durations.push(t.elapsed());
        if start.elapsed() >= measurement {
            break;
        }
    }
    let elapsed = start.elapsed();
    drop(client);
    server.stop()?;
    durations.sort_unstable();
    Ok(Outcome { baud, gap, client_gap, transactions, errors, elapsed, durations, line, timer_slack_ns: timer_slack() })
}

/// How much later than asked `thread::sleep` returns: mean and 99th percentile.
fn sleep_overshoot(asked: Duration) -> (Duration, Duration) {
    let mut late: Vec<Duration> = (0..100)
        .map(|_| {
            let t = Instant::now();
            std::thread::sleep(asked);
            t.elapsed().saturating_sub(asked)
        })
        .collect();
    late.sort_unstable();
    let mean = late.iter().sum::<Duration>() / 100;
    (mean, late.get(98).copied().unwrap_or_default())
}

/// This thread's timer slack, on Linux.
fn timer_slack() -> Option<u64> {
    std::fs::read_to_string("/proc/self/timerslack_ns").ok().and_then(|s| s.trim().parse().ok())
}

/// Sets the main thread's timer slack (threads spawned later inherit it);
/// false where that is not possible. Must be called from the main thread.
fn set_timer_slack(ns: u64) -> bool {
    std::fs::write("/proc/self/timerslack_ns", ns.to_string()).is_ok() && timer_slack() == Some(ns)
}

/// [`sleep_overshoot`] of 100 µs and 1 ms sleeps, printed and as JSON.
fn sleep_overshoot_json() -> serde_json::Value {
    let slack = timer_slack();
    let sleeps: Vec<serde_json::Value> = [Duration::from_micros(100), Duration::from_millis(1)]
        .into_iter()
        .map(|asked| {
            let (mean, p99) = sleep_overshoot(asked);
            println!(
                "timer slack {slack:?} ns: thread::sleep({asked:?}) returns late by {:.1} µs on average, {:.1} µs at p99",
                mean.as_secs_f64() * 1e6,
                p99.as_secs_f64() * 1e6
            );
            serde_json::json!({
                "asked_us": asked.as_secs_f64() * 1e6,
                "mean_late_us": mean.as_secs_f64() * 1e6,
                "p99_late_us": p99.as_secs_f64() * 1e6,
            })
        })
        .collect();
    serde_json::json!({"timer_slack_ns": slack, "sleeps": sleeps})
}

fn print_table(outcomes: &[Outcome]) {
    let ms = |d: Duration| format!("{:.3}", d.as_secs_f64() * 1e3);
    println!();
    println!(
        "| baud | client gap | timer slack | tx/s | mean ms | p50 ms | p99 ms | wire limit ms (tx/s) | % of wire limit | limit with client gap ms | % of that | errors |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|---|---|");
    for o in outcomes {
        let limits = match o.gap {
            Gap::NoneUntimed => "n/a | n/a | n/a | n/a".to_string(),
            Gap::Default | Gap::ExactT35 => format!(
                "{} ({:.1}) | {:.1}% | {} | {:.1}%",
                ms(o.wire_limit()),
                1.0 / o.wire_limit().as_secs_f64(),
                o.share(o.wire_limit()),
                ms(o.configured_limit()),
                o.share(o.configured_limit())
            ),
        };
        println!(
            "| {} | {} ({} ms) | {} | {:.1} | {} | {} | {} | {limits} | {} |",
            o.baud,
            o.gap.name(),
            ms(o.client_gap),
            o.timer_slack_ns.map_or("?".to_string(), |ns| format!("{ns} ns")),
            o.per_second(),
            ms(o.mean()),
            ms(o.percentile(0.5)),
            ms(o.percentile(0.99)),
            o.errors
        );
    }
}

fn main() {
    let args = parse_args();
    if args.list {
        println!("{ID}: benchmark");
        return;
    }
    if args.filtered_out {
        return;
    }
    if !args.bench {
        // Test mode: one transaction per rate through the whole path.
        for baud in [9600, 115_200] {
            match run(baud, Gap::ExactT35, Duration::ZERO, Duration::ZERO) {
                Ok(o) => {
                    assert_eq!(o.errors, 0, "get_ph over the pty at {baud} baud failed");
                    println!("Testing {ID} at {baud} baud\nSuccess");
                }
                Err(e) => eprintln!("skipping {ID}: cannot serve on a pty: {e}"),
            }
        }
        return;
    }

    let mut outcomes = Vec::new();
    let report = |o: &Outcome| {
        println!(
            "{ID}/{}/{}/slack {:?} ns: {:.1} tx/s, {:.1}% of the wire limit, {:.1}% of the limit with the client's gap",
            o.baud,
            o.gap.name(),
            o.timer_slack_ns,
            o.per_second(),
            o.share(o.wire_limit()),
            o.share(o.configured_limit())
        );
    };
    for baud in [9600, 115_200] {
        for gap in [Gap::Default, Gap::ExactT35] {
            match run(baud, gap, args.warm_up, args.measurement) {
                Ok(o) => {
                    report(&o);
                    outcomes.push(o);
                }
                Err(e) => {
                    eprintln!("skipping {ID}: cannot serve on a pty: {e}");
                    return;
                }
            }
        }
    }
    // The fixed cost of one transaction over the pty with no line emulation.
    let short = (args.measurement / 4).max(Duration::from_millis(200));
    match run(115_200, Gap::NoneUntimed, args.warm_up.min(Duration::from_millis(200)), short) {
        Ok(o) => outcomes.push(o),
        Err(e) => eprintln!("untimed pty run failed: {e}"),
    }
    let mut overshoot = vec![sleep_overshoot_json()];

    // Diagnosis: the same with a timer slack of 1 ns (inherited by the
    // simulator's thread), which shows how much of the gap to the limit is
    // sleeps returning late.
    let default_slack = timer_slack();
    if default_slack.is_some_and(|ns| ns > 1) && set_timer_slack(1) {
        for baud in [9600, 115_200] {
            match run(baud, Gap::ExactT35, args.warm_up, (args.measurement / 2).max(Duration::from_millis(200))) {
                Ok(o) => {
                    report(&o);
                    outcomes.push(o);
                }
                Err(e) => eprintln!("diagnostic run failed: {e}"),
            }
        }
        overshoot.push(sleep_overshoot_json());
        if let Some(ns) = default_slack {
            set_timer_slack(ns);
        }
    }
    print_table(&outcomes);

    let results = serde_json::json!({
        "runs": outcomes.iter().map(Outcome::json).collect::<Vec<_>>(),
        "sleep_overshoot": overshoot,
    });
    let dir = criterion_dir().join(ID);
    let written =
        std::fs::create_dir_all(&dir).and_then(|()| std::fs::write(dir.join("results.json"), format!("{results:#}")));
    if let Err(e) = written {
        eprintln!("cannot write {}: {e}", dir.display());
    }
}
