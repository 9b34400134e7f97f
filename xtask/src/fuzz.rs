//! `cargo xtask fuzz --seconds N`: builds the libFuzzer targets of `fuzz/`
//! on the stable toolchain, seeds their corpora from the spec, runs each for
//! N seconds and reports executions, speed, corpus size and crashes.
//!
//! The targets are built the way `cargo fuzz build --sanitizer none` builds
//! them, without nightly: release mode, sanitizer-coverage instrumentation
//! through `-Cpasses=sancov-module` and LLVM options, `--cfg fuzzing`, debug
//! assertions and overflow checks, for an explicit `--target` so that build
//! scripts and proc macros stay uninstrumented. `libfuzzer-sys` compiles
//! libFuzzer itself with the system C++ compiler. Nothing else is installed.
//!
//! Files (all ignored by git):
//!
//! - `fuzz/target/`: the build, and `seeds/<target>/`, written on each run
//!   from the spec's example frames, the spec files and the spec corpora;
//! - `fuzz/corpus/<target>/`: the working corpus libFuzzer grows, kept
//!   between runs;
//! - `fuzz/artifacts/<target>/`: inputs that crashed, timed out or ran out
//!   of memory, to replay with `fuzz/target/<triple>/release/<target> <file>`.

use std::fs;
use std::io::{BufRead, BufReader, Write};
use std::path::{Path, PathBuf};
use std::process::{Command, ExitCode, Stdio};
use std::time::Instant;

use anyhow::{Context, bail};
use yosemitech_spec::{Spec, load_paths};

/// The targets, in the order they run.
pub const TARGETS: [&str; 5] = ["decode_response", "frame_reader", "spec_loader", "cli_decode", "segmenter"];

/// The instrumentation `cargo fuzz build --sanitizer none` passes to rustc.
const RUSTFLAGS: &[&str] = &[
    "-Cpasses=sancov-module",
    "-Cllvm-args=-sanitizer-coverage-level=4",
    "-Cllvm-args=-sanitizer-coverage-inline-8bit-counters",
    "-Cllvm-args=-sanitizer-coverage-pc-table",
    "-Cllvm-args=-sanitizer-coverage-trace-compares",
    "--cfg",
    "fuzzing",
    "-Cdebug-assertions",
    "-Coverflow-checks",
];

const USAGE: &str =
    "usage: cargo xtask fuzz --seconds N [--target NAME]... [--timeout S] [--rss-limit-mb M] [--no-build]

Builds the fuzz targets (fuzz/, stable toolchain, libFuzzer), seeds their corpora
from the spec, runs each for N seconds and prints executions, exec/s, corpus size
and crashes. Exits non-zero on any crash, timeout or out-of-memory input.

  --seconds N        run time of each target (required)
  --target NAME      run only this target (repeatable): decode_response, frame_reader,
                     spec_loader, cli_decode, segmenter
  --timeout S        an input taking longer than S seconds is a finding (default 10)
  --rss-limit-mb M   memory limit of a target (default 2048)
  --no-build         use the targets already built";

/// Options of one run.
#[derive(Debug)]
struct Options {
    seconds: u64,
    targets: Vec<String>,
    timeout: u64,
    rss_limit_mb: u64,
    build: bool,
}

fn parse(args: &[String]) -> anyhow::Result<Option<Options>> {
    let mut o = Options { seconds: 0, targets: Vec::new(), timeout: 10, rss_limit_mb: 2048, build: true };
    let mut it = args.iter();
    let number = |flag: &str, v: Option<&String>| -> anyhow::Result<u64> {
        let v = v.with_context(|| format!("`{flag}` needs a value\n{USAGE}"))?;
        v.parse().with_context(|| format!("`{flag} {v}`: not a whole number"))
    };
    while let Some(arg) = it.next() {
        match arg.as_str() {
            "-h" | "--help" => {
                println!("{USAGE}");
                return Ok(None);
            }
            "--seconds" => o.seconds = number(arg, it.next())?,
            "--timeout" => o.timeout = number(arg, it.next())?,
            "--rss-limit-mb" => o.rss_limit_mb = number(arg, it.next())?,
            "--no-build" => o.build = false,
            "--target" => {
                let t = it.next().with_context(|| format!("`--target` needs a value\n{USAGE}"))?;
                if !TARGETS.contains(&t.as_str()) {
                    bail!("unknown target `{t}`; the targets are {}", TARGETS.join(", "));
                }
                o.targets.push(t.clone());
            }
            other => bail!("unknown option `{other}`\n{USAGE}"),
        }
    }
    if o.seconds == 0 {
        bail!("`--seconds N` (N >= 1) is required\n{USAGE}");
    }
    if o.targets.is_empty() {
        o.targets = TARGETS.iter().map(|t| (*t).to_owned()).collect();
    }
    Ok(Some(o))
}

/// Runs the task.
pub fn run(args: &[String]) -> anyhow::Result<ExitCode> {
    let Some(options) = parse(args)? else { return Ok(ExitCode::SUCCESS) };
    let root = crate::root();
    let fuzz = root.join("fuzz");
    let triple = host_triple()?;
    let bin_dir = fuzz.join("target").join(&triple).join("release");
    if options.build {
        build(&fuzz, &triple)?;
    }
    let spec = load_paths(&[root.join("spec")]).map_err(|d| anyhow::anyhow!("the spec does not load:\n{d}"))?;

    let mut reports = Vec::new();
    for target in &options.targets {
        let seeds = fuzz.join("target").join("seeds").join(target);
        let count = write_seeds(target, &seeds, &spec, &root)?;
        let corpus = fuzz.join("corpus").join(target);
        let artifacts = fuzz.join("artifacts").join(target);
        let logs = fuzz.join("target").join("logs");
        for dir in [&corpus, &artifacts, &logs] {
            fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
        }
        let binary = bin_dir.join(target);
        if !binary.is_file() {
            bail!("{} is missing: run without --no-build", binary.display());
        }
        eprintln!("==> {target}: {} s, {count} seeds, corpus {}", options.seconds, rel(&corpus, &root));
        let report =
            run_target(target, &binary, &corpus, &seeds, &artifacts, &logs.join(format!("{target}.log")), &options)?;
        reports.push(report);
    }

    print_table(&reports);
    let failed: Vec<&Report> = reports.iter().filter(|r| r.crashes > 0 || !r.clean_exit).collect();
    if failed.is_empty() {
        return Ok(ExitCode::SUCCESS);
    }
    for r in &failed {
        eprintln!("\nerror: {}: {}", r.target, r.finding.as_deref().unwrap_or("the fuzzer exited with an error"));
        for a in &r.artifacts {
            eprintln!("  artifact: {}", rel(a, &root));
            eprintln!("  reproduce: {} {}", rel(&bin_dir.join(&r.target), &root), rel(a, &root));
        }
        eprintln!("  log: {}", rel(&r.log, &root));
    }
    Ok(ExitCode::FAILURE)
}

/// `path` relative to `root` when it is inside it.
fn rel(path: &Path, root: &Path) -> String {
    path.strip_prefix(root).unwrap_or(path).display().to_string()
}

fn cargo() -> String {
    std::env::var("CARGO").unwrap_or_else(|_| "cargo".into())
}

/// The host's target triple, from `rustc -vV`.
fn host_triple() -> anyhow::Result<String> {
    let rustc = std::env::var("RUSTC").unwrap_or_else(|_| "rustc".into());
    let out = Command::new(&rustc).arg("-vV").output().with_context(|| format!("cannot run `{rustc} -vV`"))?;
    let text = String::from_utf8_lossy(&out.stdout);
    text.lines()
        .find_map(|l| l.strip_prefix("host: "))
        .map(|h| h.trim().to_owned())
        .context("`rustc -vV` printed no host triple")
}

/// Builds every target, instrumented, into `fuzz/target`.
fn build(fuzz: &Path, triple: &str) -> anyhow::Result<()> {
    eprintln!("==> building the fuzz targets for {triple} (the first build takes a few minutes)");
    let started = Instant::now();
    let status = Command::new(cargo())
        .current_dir(fuzz)
        .args(["build", "--release", "--bins", "--target", triple, "--target-dir"])
        .arg(fuzz.join("target"))
        .arg("--manifest-path")
        .arg(fuzz.join("Cargo.toml"))
        // Flags for the targets only: with `--target`, build scripts and proc
        // macros are built for the host without them.
        .env("CARGO_ENCODED_RUSTFLAGS", RUSTFLAGS.join("\u{1f}"))
        .env_remove("RUSTFLAGS")
        .env_remove("CARGO_BUILD_RUSTFLAGS")
        .env_remove("CARGO_TARGET_DIR")
        .env_remove("CARGO_BUILD_TARGET")
        .status()
        .context("cannot run cargo")?;
    if !status.success() {
        bail!("building the fuzz targets failed ({status})");
    }
    eprintln!("==> built in {:.0} s", started.elapsed().as_secs_f64());
    Ok(())
}

/// Writes the seeds of `target` into `dir` (emptied first); returns how many.
fn write_seeds(target: &str, dir: &Path, spec: &Spec, root: &Path) -> anyhow::Result<usize> {
    if dir.exists() {
        fs::remove_dir_all(dir).with_context(|| format!("cannot empty {}", dir.display()))?;
    }
    fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
    let seeds = match target {
        "decode_response" => frame_seeds(spec),
        "frame_reader" => stream_seeds(spec),
        "spec_loader" => spec_seeds(root)?,
        "cli_decode" => hex_seeds(spec),
        "segmenter" => exchange_seeds(spec),
        other => bail!("no seeds for `{other}`"),
    };
    for (i, seed) in seeds.iter().enumerate() {
        let path = dir.join(format!("seed-{i:04}"));
        fs::write(&path, seed).with_context(|| format!("cannot write {}", path.display()))?;
    }
    Ok(seeds.len())
}

/// One example's frames: slave, request, reply as printed, true reply.
type ExampleFrames = (u8, Vec<u8>, Vec<u8>, Vec<u8>);

/// Every example of the spec.
fn examples(spec: &Spec) -> Vec<ExampleFrames> {
    let mut out = Vec::new();
    for sensor in &spec.sensors {
        for c in &sensor.commands {
            for e in &c.examples {
                let Some((request, reply)) = e.true_pair() else { continue };
                let printed = e.response.as_ref().and_then(|f| f.complete.clone()).unwrap_or_else(|| reply.to_vec());
                out.push((e.slave(), request.to_vec(), printed, reply.to_vec()));
            }
        }
    }
    out
}

/// An exception reply from `slave` to `function`.
fn exception(slave: u8, function: u8, code: u8) -> Vec<u8> {
    let mut frame = vec![slave, function | 0x80, code];
    frame.extend_from_slice(&yosemitech_rtu::crc16(&frame).to_le_bytes());
    frame
}

/// decode_response: `[slave, frame...]`.
fn frame_seeds(spec: &Spec) -> Vec<Vec<u8>> {
    let mut seeds = Vec::new();
    for (slave, request, printed, reply) in examples(spec) {
        for frame in [&request, &printed, &reply] {
            let mut s = vec![slave];
            s.extend_from_slice(frame);
            seeds.push(s);
        }
        let mut s = vec![slave];
        s.extend(exception(slave, request.get(1).copied().unwrap_or(3), 2));
        seeds.push(s);
    }
    seeds.sort();
    seeds.dedup();
    seeds
}

/// frame_reader: `[command, slave - 1, stale length, chunk count, chunks..., stale..., stream...]`,
/// commands numbered as the target numbers them (sensors in load order, then commands).
fn stream_seeds(spec: &Spec) -> Vec<Vec<u8>> {
    let mut seeds = Vec::new();
    let mut index = 0u8;
    for sensor in &spec.sensors {
        for c in &sensor.commands {
            for e in &c.examples {
                let slave = e.slave().wrapping_sub(1);
                let Some(reply) = e.true_response() else { continue };
                let mut clean = vec![index, slave, 0, 0];
                clean.extend_from_slice(reply);
                seeds.push(clean);
                let mut noisy = vec![index, slave, 2, 1, 1, 0x00, 0xFF, 0xAA];
                noisy.extend_from_slice(reply);
                seeds.push(noisy);
                let mut exc = vec![index, slave, 0, 0];
                exc.extend(exception(e.slave(), c.function.code(), 6));
                seeds.push(exc);
            }
            index = index.wrapping_add(1);
        }
    }
    seeds
}

/// segmenter: `[chunk, bytes...]`: each example's request and reply one
/// after the other, whole (chunk 255) and three bytes at a time with noise
/// in front.
fn exchange_seeds(spec: &Spec) -> Vec<Vec<u8>> {
    let mut seeds = Vec::new();
    for sensor in &spec.sensors {
        for c in &sensor.commands {
            for e in &c.examples {
                let Some((request, reply)) = e.true_pair() else { continue };
                seeds.push([&[0xFF], request, reply].concat());
                seeds.push([&[2, 0x00, 0xFF, 0xAA], request, reply].concat());
            }
        }
    }
    seeds.sort();
    seeds.dedup();
    seeds
}

/// The fragment every sensor file includes: the spec_loader target takes it
/// as the second of its two files, after a NUL.
const COMMON_FRAGMENT: &str = "yosemitech-common.yaml";

/// Whether a spec file describes a sensor (a top-level `sensor:` key) rather
/// than holding a fragment of shared commands.
fn is_sensor_file(text: &[u8]) -> bool {
    text.split(|&b| b == b'\n').any(|line| line.starts_with(b"sensor:"))
}

/// spec_loader: every sensor file of `spec/`, a NUL and the common fragment
/// (the target supplies the other fragments); every fragment alone; the
/// malformed and hostile spec corpora.
fn spec_seeds(root: &Path) -> anyhow::Result<Vec<Vec<u8>>> {
    let read = |p: &Path| fs::read(p).with_context(|| format!("cannot read {}", p.display()));
    let yaml_files = |dir: &Path| -> anyhow::Result<Vec<PathBuf>> {
        let entries = fs::read_dir(dir).with_context(|| format!("cannot list {}", dir.display()))?;
        let mut files: Vec<PathBuf> = entries
            .flatten()
            .map(|e| e.path())
            .filter(|p| p.is_file() && matches!(p.extension().and_then(|e| e.to_str()), Some("yaml" | "yml")))
            .collect();
        files.sort();
        Ok(files)
    };
    let spec = root.join("spec");
    let common = read(&spec.join(COMMON_FRAGMENT))?;
    let mut sensors = Vec::new();
    let mut fragments = Vec::new();
    for file in yaml_files(&spec)? {
        let text = read(&file)?;
        if is_sensor_file(&text) {
            let mut s = text;
            s.push(0);
            s.extend_from_slice(&common);
            sensors.push(s);
        } else {
            fragments.push(text);
        }
    }
    if sensors.is_empty() {
        bail!("{} holds no sensor file (a file with a top-level `sensor:` key)", spec.display());
    }
    let mut seeds = sensors;
    seeds.extend(fragments);
    for dir in [
        "tests/specs/malformed",
        "tests/specs/malformed/hostile-but-valid",
        "tests/fixtures/hostile-valid/spec",
        "tests/fixtures/do-probe/spec",
    ] {
        let Ok(entries) = fs::read_dir(root.join(dir)) else { continue };
        let mut files: Vec<PathBuf> = entries.flatten().map(|e| e.path()).filter(|p| p.is_file()).collect();
        files.sort();
        for f in files {
            seeds.push(read(&f)?);
        }
    }
    Ok(seeds)
}

/// cli_decode: example frames as a person types them.
fn hex_seeds(spec: &Spec) -> Vec<Vec<u8>> {
    let mut seeds = Vec::new();
    for (_, request, printed, reply) in examples(spec) {
        for frame in [request, printed, reply] {
            let spaced = frame.iter().map(|b| format!("{b:02X}")).collect::<Vec<_>>().join(" ");
            seeds.push(spaced.clone().into_bytes());
            seeds.push(spaced.replace(' ', "").to_lowercase().into_bytes());
            let prefixed: Vec<String> = frame.iter().map(|b| format!("0x{b:02x}")).collect();
            seeds.push(prefixed.join(",").into_bytes());
            seeds.push(spaced.replace(' ', "-").into_bytes());
        }
    }
    seeds.sort();
    seeds.dedup();
    seeds
}

/// What one target's run gave.
#[derive(Debug, Default)]
struct Report {
    target: String,
    executions: u64,
    exec_per_sec: u64,
    corpus: u64,
    new_units: u64,
    peak_rss_mb: u64,
    crashes: usize,
    artifacts: Vec<PathBuf>,
    finding: Option<String>,
    clean_exit: bool,
    seconds: f64,
    log: PathBuf,
}

/// The number after `key` in `line` (`corp: 24/268b` -> 24 for `corp: `).
fn number_after(line: &str, key: &str) -> Option<u64> {
    let rest = &line[line.find(key)? + key.len()..];
    let digits: String = rest.trim_start().chars().take_while(char::is_ascii_digit).collect();
    digits.parse().ok()
}

/// Reads libFuzzer's output (stderr) line by line into `report`.
fn parse_line(line: &str, report: &mut Report) {
    if let Some(v) = line.strip_prefix("stat::number_of_executed_units:") {
        report.executions = v.trim().parse().unwrap_or(report.executions);
    } else if let Some(v) = line.strip_prefix("stat::average_exec_per_sec:") {
        report.exec_per_sec = v.trim().parse().unwrap_or(report.exec_per_sec);
    } else if let Some(v) = line.strip_prefix("stat::new_units_added:") {
        report.new_units = v.trim().parse().unwrap_or(report.new_units);
    } else if let Some(v) = line.strip_prefix("stat::peak_rss_mb:") {
        report.peak_rss_mb = v.trim().parse().unwrap_or(report.peak_rss_mb);
    } else if line.starts_with('#') {
        // `#251927	DONE   cov: 6292 ft: 6354 corp: 24/268b ...`, also `pulse` and `NEW` lines.
        if let Some(n) = number_after(line, "#") {
            report.executions = report.executions.max(n);
        }
        if let Some(n) = number_after(line, "corp: ") {
            report.corpus = n;
        }
    } else if let Some(rest) = line.split_once("Test unit written to ").map(|(_, r)| r) {
        report.crashes += 1;
        report.artifacts.push(PathBuf::from(rest.trim()));
    } else if line.contains("==ERROR: libFuzzer:") || line.starts_with("SUMMARY: libFuzzer:") {
        if report.finding.is_none() {
            report.finding = Some(line.trim().trim_start_matches("==").to_owned());
        }
    } else if line.starts_with("thread '") && line.contains("panicked at") {
        report.finding = Some(line.trim().to_owned());
    }
}

fn run_target(
    target: &str,
    binary: &Path,
    corpus: &Path,
    seeds: &Path,
    artifacts: &Path,
    log: &Path,
    o: &Options,
) -> anyhow::Result<Report> {
    let mut prefix = artifacts.display().to_string();
    prefix.push('/');
    let started = Instant::now();
    let mut child = Command::new(binary)
        .arg(format!("-max_total_time={}", o.seconds))
        .arg(format!("-timeout={}", o.timeout))
        .arg(format!("-rss_limit_mb={}", o.rss_limit_mb))
        .arg(format!("-artifact_prefix={prefix}"))
        .arg("-print_final_stats=1")
        .arg(corpus)
        .arg(seeds)
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .with_context(|| format!("cannot run {}", binary.display()))?;
    let mut report = Report { target: target.to_owned(), log: log.to_path_buf(), ..Report::default() };
    let mut log_file = fs::File::create(log).with_context(|| format!("cannot write {}", log.display()))?;
    if let Some(stderr) = child.stderr.take() {
        for line in BufReader::new(stderr).lines() {
            let line = line.unwrap_or_default();
            writeln!(log_file, "{line}").ok();
            parse_line(&line, &mut report);
        }
    }
    let status = child.wait().context("the fuzzer vanished")?;
    report.seconds = started.elapsed().as_secs_f64();
    report.clean_exit = status.success();
    if !status.success() && report.finding.is_none() {
        report.finding = Some(format!("the fuzzer exited with {status}"));
    }
    if report.exec_per_sec == 0 && report.seconds > 0.0 {
        report.exec_per_sec = (report.executions as f64 / report.seconds) as u64;
    }
    Ok(report)
}

fn print_table(reports: &[Report]) {
    println!();
    println!(
        "{:<16} {:>13} {:>9} {:>8} {:>6} {:>8} {:>7} {:>7}",
        "target", "executions", "exec/s", "corpus", "new", "rss MB", "time s", "crashes"
    );
    for r in reports {
        println!(
            "{:<16} {:>13} {:>9} {:>8} {:>6} {:>8} {:>7.0} {:>7}",
            r.target, r.executions, r.exec_per_sec, r.corpus, r.new_units, r.peak_rss_mb, r.seconds, r.crashes
        );
    }
    let total: u64 = reports.iter().map(|r| r.executions).sum();
    let crashes: usize = reports.iter().map(|r| r.crashes).sum();
    let seconds: f64 = reports.iter().map(|r| r.seconds).sum();
    println!("{:<16} {:>13} {:>9} {:>8} {:>6} {:>8} {:>7.0} {:>7}", "total", total, "", "", "", "", seconds, crashes);
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_libfuzzer_output() {
        let mut r = Report::default();
        for line in [
            "INFO: Seed: 1234",
            "#2\tINITED cov: 10 ft: 11 corp: 3/30b exec/s: 0 rss: 30Mb",
            "#251927\tDONE   cov: 6292 ft: 6354 corp: 24/268b lim: 2435 exec/s: 41987 rss: 36Mb",
            "stat::number_of_executed_units: 251927",
            "stat::average_exec_per_sec:     41987",
            "stat::new_units_added:          38",
            "stat::peak_rss_mb:              36",
        ] {
            parse_line(line, &mut r);
        }
        assert_eq!((r.executions, r.exec_per_sec, r.corpus, r.new_units, r.peak_rss_mb), (251_927, 41_987, 24, 38, 36));
        assert_eq!(r.crashes, 0);

        let mut r = Report::default();
        for line in [
            "thread '<unnamed>' (4222) panicked at src/lib.rs:462:64:",
            "==4222== ERROR: libFuzzer: deadly signal",
            "artifact_prefix='fuzz/artifacts/cli_decode/'; Test unit written to fuzz/artifacts/cli_decode/crash-3fee",
        ] {
            parse_line(line, &mut r);
        }
        assert_eq!(r.crashes, 1);
        assert_eq!(r.artifacts, [PathBuf::from("fuzz/artifacts/cli_decode/crash-3fee")]);
        assert!(r.finding.as_deref().is_some_and(|f| f.contains("panicked at src/lib.rs:462")), "{:?}", r.finding);
    }

    #[test]
    fn every_sensor_file_is_a_spec_loader_seed() {
        let root = crate::root();
        let seeds = spec_seeds(&root).unwrap();
        let spec = load_paths(&[root.join("spec")]).unwrap();
        let common = fs::read(root.join("spec").join(COMMON_FRAGMENT)).unwrap();
        for sensor in &spec.sensors {
            let mut expected = fs::read(&sensor.file).unwrap();
            assert!(is_sensor_file(&expected), "{}", sensor.file.display());
            expected.push(0);
            expected.extend_from_slice(&common);
            assert!(seeds.contains(&expected), "no seed for {}", sensor.file.display());
        }
        assert!(!is_sensor_file(&common));
        assert!(seeds.contains(&common));
    }

    #[test]
    fn options() {
        let args = |s: &str| s.split_whitespace().map(String::from).collect::<Vec<_>>();
        let o = parse(&args("--seconds 5")).unwrap().unwrap();
        assert_eq!((o.seconds, o.targets.len(), o.build), (5, TARGETS.len(), true));
        let o = parse(&args("--seconds 1 --target spec_loader --no-build --timeout 3")).unwrap().unwrap();
        assert_eq!((o.targets, o.build, o.timeout), (vec!["spec_loader".to_string()], false, 3));
        assert!(parse(&args("")).is_err());
        assert!(parse(&args("--seconds 1 --target nope")).is_err());
    }
}
