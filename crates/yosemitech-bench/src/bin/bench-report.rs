//! Prints the results of the last `cargo bench -p yosemitech-bench` as the
//! Markdown tables of `BENCHMARKS.md`, with ratios within each comparison
//! group and the issue's targets checked.
//!
//! ```text
//! cargo run -p yosemitech-bench --bin bench-report [CRITERION_DIR]
//! ```
//!
//! The directory defaults to criterion's (see
//! `yosemitech_bench::criterion_dir`).

use std::collections::BTreeMap;
use std::fs;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

use serde_json::Value;

/// The implementation every ratio is taken against.
const OURS: &str = "yosemitech";

/// Groups in the order they are reported.
const GROUPS: &[&str] = &[
    "crc16_8",
    "crc16_13",
    "crc16_256",
    "encode_get_ph",
    "decode_get_ph",
    "decode_conductivity",
    "transaction_get_ph",
];

/// One benchmark's estimates, in nanoseconds.
struct Estimate {
    /// Criterion's headline "time": the slope of time over iterations
    /// (the mean where criterion sampled flat).
    slope: f64,
    median: f64,
    mean: f64,
    mean_low: f64,
    mean_high: f64,
}

fn read_json(path: &Path) -> Option<Value> {
    serde_json::from_str(&fs::read_to_string(path).ok()?).ok()
}

fn number(value: &Value, path: &[&str]) -> Option<f64> {
    path.iter().try_fold(value, |v, key| v.get(key))?.as_f64()
}

/// Every benchmark under `dir`, by group and function.
fn load(dir: &Path) -> BTreeMap<String, Vec<(String, Estimate)>> {
    let mut groups: BTreeMap<String, Vec<(String, Estimate)>> = BTreeMap::new();
    let Ok(entries) = fs::read_dir(dir) else { return groups };
    for group_dir in entries.flatten().map(|e| e.path()) {
        let Ok(functions) = fs::read_dir(&group_dir) else { continue };
        for new in functions.flatten().map(|e| e.path().join("new")) {
            let (Some(benchmark), Some(estimates)) =
                (read_json(&new.join("benchmark.json")), read_json(&new.join("estimates.json")))
            else {
                continue;
            };
            let (Some(group), Some(function)) = (
                benchmark.get("group_id").and_then(Value::as_str),
                benchmark.get("function_id").and_then(Value::as_str),
            ) else {
                continue;
            };
            let estimate = (|| {
                Some(Estimate {
                    slope: number(&estimates, &["slope", "point_estimate"])
                        .or_else(|| number(&estimates, &["mean", "point_estimate"]))?,
                    median: number(&estimates, &["median", "point_estimate"])?,
                    mean: number(&estimates, &["mean", "point_estimate"])?,
                    mean_low: number(&estimates, &["mean", "confidence_interval", "lower_bound"])?,
                    mean_high: number(&estimates, &["mean", "confidence_interval", "upper_bound"])?,
                })
            })();
            if let Some(estimate) = estimate {
                groups.entry(group.to_string()).or_default().push((function.to_string(), estimate));
            }
        }
    }
    for functions in groups.values_mut() {
        functions.sort_by(|a, b| (a.0 != OURS).cmp(&(b.0 != OURS)).then_with(|| a.0.cmp(&b.0)));
    }
    groups
}

fn ns(value: f64) -> String {
    if value >= 10_000.0 { format!("{:.2} µs", value / 1e3) } else { format!("{value:.2} ns") }
}

fn estimate_of<'a>(
    groups: &'a BTreeMap<String, Vec<(String, Estimate)>>,
    group: &str,
    function: &str,
) -> Option<&'a Estimate> {
    groups.get(group)?.iter().find(|(f, _)| f == function).map(|(_, e)| e)
}

fn print_codec(groups: &BTreeMap<String, Vec<(String, Estimate)>>) {
    println!(
        "| group | implementation | time (slope) | median | mean [95% CI] | ÷ yosemitech's (slope) | ÷ yosemitech's (median) |"
    );
    println!("|---|---|---|---|---|---|---|");
    let mut names: Vec<&str> = GROUPS.iter().copied().filter(|g| groups.contains_key(*g)).collect();
    names.extend(groups.keys().map(String::as_str).filter(|g| !GROUPS.contains(g) && *g != "bus_efficiency"));
    for group in names {
        let Some(functions) = groups.get(group) else { continue };
        let base = estimate_of(groups, group, OURS).or_else(|| functions.first().map(|(_, e)| e));
        for (function, e) in functions {
            let (by_slope, by_median) = base.map_or((String::new(), String::new()), |b| {
                (format!("{:.2}", e.slope / b.slope), format!("{:.2}", e.median / b.median))
            });
            println!(
                "| `{group}` | {function} | {} | {} | {} [{} – {}] | {by_slope} | {by_median} |",
                ns(e.slope),
                ns(e.median),
                ns(e.mean),
                ns(e.mean_low),
                ns(e.mean_high)
            );
        }
    }
}

/// "met" when both estimators meet the bound, "MISSED" when neither does.
fn verdict(by_slope: f64, by_median: f64, bound: f64) -> &'static str {
    match (by_slope <= bound, by_median <= bound) {
        (true, true) => "met",
        (false, false) => "MISSED",
        _ => "marginal: the estimators disagree",
    }
}

fn print_targets(groups: &BTreeMap<String, Vec<(String, Estimate)>>, bus: Option<&Value>) {
    println!("\n| target | measured (slope; median) | |");
    println!("|---|---|---|");
    if let (Some(ours), Some(theirs)) =
        (estimate_of(groups, "decode_get_ph", OURS), estimate_of(groups, "decode_get_ph", "rmodbus"))
    {
        let (slope, median) = (ours.slope / theirs.slope, ours.median / theirs.median);
        println!(
            "| decode + validate get_ph ≤ 0.25 × rmodbus | {slope:.3} ×; {median:.3} × | {} |",
            verdict(slope, median, 0.25)
        );
    }
    for len in [8, 13, 256] {
        let group = format!("crc16_{len}");
        let fastest = ["crc_table1", "crc_table16"]
            .iter()
            .filter_map(|f| estimate_of(groups, &group, f).map(|e| (*f, e)))
            .min_by(|a, b| a.1.slope.total_cmp(&b.1.slope));
        if let (Some(ours), Some((name, theirs))) = (estimate_of(groups, &group, OURS), fastest) {
            let (slope, median) = (ours.slope / theirs.slope, ours.median / theirs.median);
            println!(
                "| CRC over {len} bytes ≤ 1.1 × fastest `crc` ({name}) | {slope:.2} ×; {median:.2} × | {} |",
                verdict(slope, median, 1.1)
            );
        }
    }
    let runs = bus.and_then(|b| b.get("runs")).and_then(Value::as_array).cloned().unwrap_or_default();
    for (baud, target) in [(9600, 97.0), (115_200, 90.0)] {
        for run in runs.iter().filter(|r| r.get("baud").and_then(Value::as_u64) == Some(baud) && !is_diagnostic(r)) {
            let (Some(gap), Some(share)) =
                (run.get("client_gap").and_then(Value::as_str), number(run, &["wire_limit_share"]))
            else {
                continue;
            };
            println!(
                "| ≥ {target:.0}% of the wire limit at {baud} baud, client gap {gap} | {share:.1}% | {} |",
                if share >= target { "met" } else { "MISSED" }
            );
        }
    }
}

/// Runs made with the default timer slack; the 1 ns runs are a diagnosis.
fn is_diagnostic(run: &Value) -> bool {
    run.get("timer_slack_ns").and_then(Value::as_u64) == Some(1)
}

fn print_bus(bus: &Value) {
    let Some(runs) = bus.get("runs").and_then(Value::as_array) else { return };
    println!(
        "\n| baud | client gap | timer slack | tx/s | mean | p50 | p99 | wire limit (tx/s) | % of wire limit | limit with the client's gap | % of that | errors |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|---|---|");
    let ms = |run: &Value, key: &str| number(run, &[key]).map_or("n/a".to_string(), |v| format!("{v:.3} ms"));
    let pct = |run: &Value, key: &str| number(run, &[key]).map_or("n/a".to_string(), |v| format!("{v:.1}%"));
    for run in runs {
        let wire = number(run, &["wire_limit_ms"]).map_or("n/a".to_string(), |v| format!("{v:.3} ms ({:.1})", 1e3 / v));
        let slack = run.get("timer_slack_ns").and_then(Value::as_u64).map_or("?".to_string(), |ns| {
            if ns == 1 { "1 ns (diagnosis)".to_string() } else { format!("{} µs", ns as f64 / 1e3) }
        });
        println!(
            "| {} | {} ({}) | {slack} | {:.1} | {} | {} | {} | {wire} | {} | {} | {} | {} |",
            run.get("baud").and_then(Value::as_u64).unwrap_or(0),
            run.get("client_gap").and_then(Value::as_str).unwrap_or("?"),
            ms(run, "client_gap_ms"),
            number(run, &["per_second"]).unwrap_or(0.0),
            ms(run, "mean_ms"),
            ms(run, "p50_ms"),
            ms(run, "p99_ms"),
            pct(run, "wire_limit_share"),
            ms(run, "configured_limit_ms"),
            pct(run, "configured_limit_share"),
            run.get("errors").and_then(Value::as_u64).unwrap_or(0),
        );
    }
    for group in bus.get("sleep_overshoot").and_then(Value::as_array).into_iter().flatten() {
        let slack = group.get("timer_slack_ns").and_then(Value::as_u64).unwrap_or(0);
        for s in group.get("sleeps").and_then(Value::as_array).into_iter().flatten() {
            println!(
                "\nTimer slack {slack} ns: `thread::sleep({:.0} µs)` returned {:.1} µs late on average, {:.1} µs at p99.",
                number(s, &["asked_us"]).unwrap_or(0.0),
                number(s, &["mean_late_us"]).unwrap_or(0.0),
                number(s, &["p99_late_us"]).unwrap_or(0.0)
            );
        }
    }
}

fn main() -> ExitCode {
    let dir = std::env::args().nth(1).map_or_else(yosemitech_bench::criterion_dir, PathBuf::from);
    let groups = load(&dir);
    let bus = read_json(&dir.join("bus_efficiency").join("results.json"));
    if groups.is_empty() && bus.is_none() {
        eprintln!("no results under {}: run `cargo bench -p yosemitech-bench` first", dir.display());
        return ExitCode::FAILURE;
    }
    print_codec(&groups);
    if let Some(bus) = &bus {
        print_bus(bus);
    }
    print_targets(&groups, bus.as_ref());
    ExitCode::SUCCESS
}
