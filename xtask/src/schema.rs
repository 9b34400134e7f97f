//! `cargo xtask schema [--check]`: writes `spec/schema.json`, the JSON Schema
//! editors use to complete and check spec files (the files' modeline points at it).

use std::process::ExitCode;

/// Runs the task.
pub fn run(args: &[String]) -> anyhow::Result<ExitCode> {
    let Some(check) = crate::check_flag(args, "usage: cargo xtask schema [--check]")? else {
        return Ok(ExitCode::SUCCESS);
    };
    let mut text = serde_json::to_string_pretty(&yosemitech_spec::json_schema())?;
    text.push('\n');
    crate::generated_files::GeneratedFiles {
        what: "the spec's JSON schema",
        command: "cargo xtask schema",
        dir: crate::root().join("spec"),
        files: vec![("schema.json".to_owned(), text)],
        owns_suffix: None,
    }
    .ensure(check)
}
