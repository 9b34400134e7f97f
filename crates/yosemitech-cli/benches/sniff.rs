//! How fast `sniff`'s listener keeps up, on one core: every exchange the
//! spec prints (request and reply, CRCs included), back to back on a
//! 115200-baud line (a silence of t3.5 between frames, shorter than the
//! listener's silence, so frames are told apart by the spec's lengths
//! alone), handed over in chunks of at most 32 bytes as a USB adapter
//! hands them over, framed, paired and decoded. The figure to beat is the
//! line's own rate: 11,520 bytes a second at 115200 baud 8N1.
//!
//! `cargo bench -p yosemitech-cli --bench sniff` runs it (a few seconds);
//! without `--bench` (as under `cargo test --benches`) it hears the spec's
//! exchanges once and checks them. `--seconds S` sets how long to listen.

use std::time::{Duration, Instant};

use yosemitech_cli::explain::sniff::{Sniffer, Timing};
use yosemitech_cli::explain::{Commands, Report};
use yosemitech_rtu::{CharFormat, LineTiming};

/// The chunk an adapter hands over at most.
const CHUNK: usize = 32;

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let measuring = args.iter().any(|a| a == "--bench");
    let seconds: f64 = args
        .iter()
        .position(|a| a == "--seconds")
        .and_then(|i| args.get(i + 1))
        .and_then(|s| s.parse().ok())
        .unwrap_or(3.0);
    let dir = concat!(env!("CARGO_MANIFEST_DIR"), "/../../spec");
    let spec = match yosemitech_spec::load_paths(&[dir.into()]) {
        Ok(spec) => spec,
        Err(d) => {
            eprintln!("the spec does not load:\n{d}");
            std::process::exit(1);
        }
    };
    let exchanges: Vec<(Vec<u8>, Vec<u8>)> = spec
        .sensors
        .iter()
        .flat_map(|s| &s.commands)
        .flat_map(|c| &c.examples)
        .filter_map(|e| Some((e.true_request()?.to_vec(), e.true_response()?.to_vec())))
        .collect();
    if exchanges.is_empty() {
        println!("sniff: the spec prints no exchange to hear");
        return;
    }
    let commands = Commands::new(&spec.sensors);
    let line = LineTiming::new(115_200, CharFormat::EIGHT_N_1);
    let timing = Timing::of_line(line, Duration::from_secs(1));

    // One pass over the spec's exchanges: every one heard as a transaction.
    let (bytes, heard, transactions, _) = listen(&commands, timing, line, &exchanges, Duration::ZERO);
    assert_eq!((heard, transactions), (exchanges.len(), exchanges.len()), "every exchange heard as one pair");
    if !measuring {
        println!("sniff: {} exchanges ({bytes} bytes) heard once", exchanges.len());
        return;
    }
    let (bytes, heard, transactions, elapsed) =
        listen(&commands, timing, line, &exchanges, Duration::from_secs_f64(seconds));
    let rate = bytes as f64 / elapsed.as_secs_f64();
    let wire = f64::from(line.baud()) / f64::from(line.bits_per_char());
    println!(
        "sniff: {transactions} exchanges ({bytes} bytes, {heard} entries) in {:.2} s on one core: \
         {:.0} bytes/s, {:.0} exchanges/s; the line carries {wire:.0} bytes/s at {} baud: {:.0}x",
        elapsed.as_secs_f64(),
        rate,
        transactions as f64 / elapsed.as_secs_f64(),
        line.baud(),
        rate / wire
    );
}

/// Hears `exchanges` over and over, back to back, for at least `at_least`
/// (once when zero): bytes handed over, entries heard, requests paired
/// with their replies among them, and the time it took.
fn listen(
    commands: &Commands<'_>,
    timing: Timing,
    line: LineTiming,
    exchanges: &[(Vec<u8>, Vec<u8>)],
    at_least: Duration,
) -> (usize, usize, usize, Duration) {
    let mut sniffer = Sniffer::new(commands, timing);
    let char_time = line.char_time();
    let (mut now, mut bytes, mut heard, mut transactions) = (Duration::ZERO, 0, 0, 0);
    let started = Instant::now();
    let mut count = |entries: Vec<yosemitech_cli::explain::sniff::Heard<'_>>| {
        for h in &entries {
            if let Report::Exchange(x) = &h.report
                && x.request.is_some()
                && x.reply.is_some()
            {
                transactions += 1;
            }
        }
        heard += entries.len();
    };
    loop {
        for (request, reply) in exchanges {
            for frame in [request, reply] {
                now += line.t3_5();
                for chunk in frame.chunks(CHUNK) {
                    now += char_time * u32::try_from(chunk.len()).unwrap_or(u32::MAX);
                    count(sniffer.push(now, chunk));
                    bytes += chunk.len();
                }
            }
        }
        if started.elapsed() >= at_least {
            break;
        }
    }
    count(sniffer.tick(now + Duration::from_secs(10)));
    count(sniffer.finish());
    (bytes, heard, transactions, started.elapsed())
}
