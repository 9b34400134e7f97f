//! `cargo xtask callgrind [--check]`: the client's own cost in instructions.
//!
//! Builds `callgrind-transaction` (crate `yosemitech-bench`, without the
//! benchmarks' spec-loading harness) in release mode,
//! runs each of its modes under `valgrind --tool=callgrind`, counting only
//! inside the `measured_*` functions, and prints instructions per
//! transaction. Counted instructions do not depend on the machine's load,
//! so the comparison is exact and repeatable on the same compiler; it is not
//! a timing. With `--check` it fails unless the whole client transaction
//! costs fewer instructions than rmodbus's round trip (the client's target).

use std::path::Path;
use std::process::{Command, ExitCode};

use anyhow::{Context, bail};

use crate::root;

/// The harness's modes, as (mode, what it measures).
const MODES: [(&str, &str); 3] = [
    ("client", "Client::call over the in-memory transport"),
    ("codec", "our encode, the same device, our decode (no client)"),
    ("rmodbus", "rmodbus's request, the same device, its parse and decode"),
];

/// Transactions the harness runs: the repetitions and one checked call first.
const REPETITIONS: u64 = 1000;

const USAGE: &str = "usage: cargo xtask callgrind [--check]

Counts the instructions of one float-read transaction with callgrind (valgrind must be
installed): the client, the codec alone and rmodbus's round trip. --check fails unless the
client costs fewer instructions than rmodbus's round trip.";

pub fn run(args: &[String]) -> anyhow::Result<ExitCode> {
    let Some(check) = crate::check_flag(args, USAGE)? else { return Ok(ExitCode::SUCCESS) };
    let root = root();
    let status = Command::new(env!("CARGO"))
        .args(["build", "--release", "--quiet", "-p", "yosemitech-bench", "--bin", "callgrind-transaction"])
        .arg("--no-default-features")
        .current_dir(&root)
        .status()
        .context("running cargo build")?;
    if !status.success() {
        bail!("building callgrind-transaction failed");
    }
    let target_dir = std::env::var_os("CARGO_TARGET_DIR").map_or_else(|| root.join("target"), Into::into);
    let harness = target_dir.join("release").join("callgrind-transaction");
    let mut counts = Vec::new();
    for (mode, what) in MODES {
        let per_transaction = count(&harness, mode)?;
        println!("{mode:>8}: {per_transaction:>6} instructions a transaction  ({what})");
        counts.push((mode, per_transaction));
    }
    let of = |name: &str| counts.iter().find(|(mode, _)| *mode == name).map(|(_, n)| *n);
    let (Some(client), Some(rmodbus)) = (of("client"), of("rmodbus")) else { bail!("a mode was not measured") };
    if check && client >= rmodbus {
        eprintln!("the client costs {client} instructions a transaction, rmodbus's round trip {rmodbus}: over target");
        return Ok(ExitCode::FAILURE);
    }
    Ok(ExitCode::SUCCESS)
}

/// Instructions per transaction of one mode of the harness.
fn count(harness: &Path, mode: &str) -> anyhow::Result<u64> {
    let out = std::env::temp_dir().join(format!("yosemitech-callgrind-{}-{mode}.out", std::process::id()));
    let output = Command::new("valgrind")
        .args(["--tool=callgrind", "--toggle-collect=*measured_*"])
        .arg(format!("--callgrind-out-file={}", out.display()))
        .arg(harness)
        .args([mode, &REPETITIONS.to_string()])
        .output()
        .context("running valgrind (is it installed? `apt-get install valgrind`)")?;
    if !output.status.success() {
        bail!("callgrind-transaction {mode} failed: {}", String::from_utf8_lossy(&output.stderr));
    }
    let text = std::fs::read_to_string(&out).with_context(|| format!("reading {}", out.display()))?;
    let _ = std::fs::remove_file(&out);
    let total = text
        .lines()
        .find_map(|line| line.strip_prefix("summary:"))
        .and_then(|n| n.trim().parse::<u64>().ok())
        .with_context(|| format!("no `summary:` line in callgrind's output for {mode}"))?;
    if total == 0 {
        bail!("callgrind counted nothing in {mode}: the `measured_*` functions were not entered");
    }
    Ok(total / (REPETITIONS + 1))
}
