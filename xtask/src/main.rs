//! `cargo xtask`: project automation.
//!
//! ```text
//! cargo xtask check [--base REV]   the quick loop: format, spec, clippy, the touched packages' tests
//! cargo xtask validate [PATH...]   check spec files (default: spec/)
//! cargo xtask schema [--check]     write spec/schema.json
//! cargo xtask codegen [--check]    write the generated code where people can read it
//! cargo xtask docs [--check]       write docs/sensors/<sensor>.md
//! cargo xtask fuzz --seconds N     run every fuzz target for N seconds
//! cargo xtask callgrind [--check]  the client's instructions a transaction, against rmodbus
//! cargo xtask semver [--baseline REV | --record TAG]  the published crates' API against the last release
//! cargo xtask import MANUAL [--name NAME] [--out FILE] | MANUAL --into SPEC [--out FILE] [--json] | --accuracy [--write]
//! ```

use std::path::PathBuf;
use std::process::ExitCode;

mod callgrind;
mod check;
mod codegen;
mod docs;
mod fuzz;
mod generated_files;
mod import;
mod readme;
mod schema;
mod semver;
mod validate;

/// The workspace root (the parent of `xtask/`).
pub fn root() -> PathBuf {
    let here = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    here.parent().map(PathBuf::from).unwrap_or(here)
}

/// A task that writes generated files, or with `--check` compares them.
pub type GeneratingTask = fn(&[String]) -> anyhow::Result<ExitCode>;

/// The tasks whose files the spec generates, by name: `.ci/run`, `cargo
/// xtask check` and `cargo test` hold each of them fresh.
pub const SPEC_TASKS: [(&str, GeneratingTask); 3] =
    [("codegen", codegen::run), ("docs", docs::run), ("schema", schema::run)];

/// Parses the `[--check]` flag shared by the generating tasks: `Ok(None)`
/// when help was asked for (and printed).
pub fn check_flag(args: &[String], usage: &str) -> anyhow::Result<Option<bool>> {
    let mut check = false;
    for arg in args {
        match arg.as_str() {
            "--check" => check = true,
            "-h" | "--help" => {
                println!("{usage}");
                return Ok(None);
            }
            other => anyhow::bail!("unknown argument `{other}`; {usage}"),
        }
    }
    Ok(Some(check))
}

const USAGE: &str = "usage: cargo xtask <check [--base REV] | validate [PATH...] | schema [--check] | codegen [--check] | docs [--check] | fuzz --seconds N | callgrind [--check] | semver [--baseline REV | --record TAG] | import MANUAL [--name NAME] [--out FILE] | import MANUAL --into SPEC [--out FILE] [--json] | import --accuracy [--write]>";

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let Some((task, rest)) = args.split_first() else {
        eprintln!("{USAGE}");
        return ExitCode::from(2);
    };
    let result = match task.as_str() {
        "check" => check::run(rest),
        "validate" => validate::run(rest),
        "schema" => schema::run(rest),
        "codegen" => codegen::run(rest),
        "docs" => docs::run(rest),
        "fuzz" => fuzz::run(rest),
        "callgrind" => callgrind::run(rest),
        "semver" => semver::run(rest),
        "import" => import::run(rest),
        "-h" | "--help" | "help" => {
            println!("{USAGE}");
            return ExitCode::SUCCESS;
        }
        other => {
            eprintln!("error: unknown task `{other}`\n{USAGE}");
            return ExitCode::from(2);
        }
    };
    match result {
        Ok(code) => code,
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::FAILURE
        }
    }
}
