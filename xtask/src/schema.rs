//! `cargo xtask schema [--check]`: writes `spec/schema.json`, the JSON Schema
//! editors use to complete and check spec files (the files' modeline points at it).

use std::process::ExitCode;

use anyhow::Context;

/// Runs the task.
pub fn run(args: &[String]) -> anyhow::Result<ExitCode> {
    let Some(check) = crate::check_flag(args, "usage: cargo xtask schema [--check]")? else {
        return Ok(ExitCode::SUCCESS);
    };
    let path = crate::root().join("spec").join("schema.json");
    let mut text = serde_json::to_string_pretty(&yosemitech_spec::json_schema())?;
    text.push('\n');
    if check {
        let current = std::fs::read_to_string(&path).unwrap_or_default();
        if current != text {
            eprintln!("error: spec/schema.json is stale; run cargo xtask schema");
            return Ok(ExitCode::FAILURE);
        }
        println!("spec/schema.json is up to date");
        return Ok(ExitCode::SUCCESS);
    }
    std::fs::write(&path, &text).with_context(|| format!("cannot write {}", path.display()))?;
    println!("wrote spec/schema.json ({} bytes)", text.len());
    Ok(ExitCode::SUCCESS)
}
