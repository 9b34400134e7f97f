//! The README's blocks generated from the spec: the line `validate` prints
//! and the probe models with their sources. A count typed by hand drifts
//! from the spec; these are refreshed by `cargo xtask docs` with the
//! register maps, and `--check` fails when one is stale.
//!
//! A block lies between `<!-- generated: NAME (cargo xtask docs) -->` and
//! `<!-- end: NAME -->`; the text around it is the README's own.

use std::fs;
use std::process::ExitCode;

use anyhow::Context as _;
use yosemitech_spec::{Sensor, Spec};

/// Each block's name and text.
pub fn blocks(spec: &Spec) -> Vec<(&'static str, String)> {
    vec![("validate", format!("```text\n{}\n```\n", crate::validate::summary_line(spec))), ("models", models(spec))]
}

/// `Y520` conductivity probe, or the sensor's name where the spec gives no model.
fn label(s: &Sensor) -> String {
    match &s.model {
        Some(model) => format!("{model} {}", s.title),
        None => s.title.clone(),
    }
}

fn models(spec: &Spec) -> String {
    let manuals: Vec<String> = spec
        .sensors
        .iter()
        .filter(|s| s.manual.is_some())
        .map(|s| {
            let software: Vec<&str> = s.manuals().filter_map(|m| m.software.as_deref()).collect();
            match software.as_slice() {
                [] => label(s),
                [one] => format!("{} (software {one})", label(s)),
                many => format!("{} (software {})", label(s), many.join(", ")),
            }
        })
        .collect();
    let unsourced: Vec<String> = spec.sensors.iter().filter(|s| s.manual.is_none()).map(label).collect();
    let aliases: Vec<String> = spec
        .sensors
        .iter()
        .flat_map(|s| {
            s.aliases.iter().map(move |a| format!("{} (as the {})", a.model, s.model.as_deref().unwrap_or(&s.name)))
        })
        .collect();
    let mut out = format!("- From their Modbus manuals: {}.\n", manuals.join("; "));
    if !unsourced.is_empty() {
        out.push_str(&format!(
            "- Without a Modbus manual, from what the field's drivers and loggers read (each spec says which source, and carries no example frame): {}.\n",
            unsourced.join("; ")
        ));
    }
    if !aliases.is_empty() {
        out.push_str(&format!("- Other models that answer with a sensor's commands: {}.\n", aliases.join("; ")));
    }
    out
}

/// `text` with each block's contents replaced; the names of blocks the
/// text lacks.
fn refreshed(text: &str, blocks: &[(&str, String)]) -> (String, Vec<String>) {
    let mut out = text.to_owned();
    let mut missing = Vec::new();
    for (name, contents) in blocks {
        let (begin, end) =
            (format!("<!-- generated: {name} (cargo xtask docs) -->\n"), format!("<!-- end: {name} -->"));
        let Some(start) = out.find(&begin).map(|i| i + begin.len()) else {
            missing.push((*name).to_owned());
            continue;
        };
        let Some(stop) = out[start..].find(&end).map(|i| start + i) else {
            missing.push((*name).to_owned());
            continue;
        };
        out.replace_range(start..stop, contents);
    }
    (out, missing)
}

/// Writes the README's blocks (or, with `check`, compares them).
pub fn ensure(spec: &Spec, check: bool) -> anyhow::Result<ExitCode> {
    let path = crate::root().join("README.md");
    let text = fs::read_to_string(&path).with_context(|| format!("reading {}", path.display()))?;
    let (fresh, missing) = refreshed(&text, &blocks(spec));
    if !missing.is_empty() {
        eprintln!("error: README.md has no generated block {}", missing.join(", "));
        return Ok(ExitCode::FAILURE);
    }
    if fresh == text {
        println!("README.md: its generated blocks are fresh");
        return Ok(ExitCode::SUCCESS);
    }
    if check {
        eprintln!("error: README.md's generated blocks are stale\nrun `cargo xtask docs` and commit the result");
        return Ok(ExitCode::FAILURE);
    }
    fs::write(&path, fresh).with_context(|| format!("writing {}", path.display()))?;
    println!("README.md: its generated blocks written");
    Ok(ExitCode::SUCCESS)
}

#[cfg(test)]
mod tests {
    use super::refreshed;

    #[test]
    fn a_block_is_replaced_between_its_markers_and_the_rest_kept() {
        let text = "intro\n<!-- generated: n (cargo xtask docs) -->\nold\n<!-- end: n -->\noutro\n";
        let (out, missing) = refreshed(text, &[("n", "new\n".to_owned())]);
        assert_eq!(out, "intro\n<!-- generated: n (cargo xtask docs) -->\nnew\n<!-- end: n -->\noutro\n");
        assert!(missing.is_empty());
        let (_, missing) = refreshed("no markers", &[("n", String::new())]);
        assert_eq!(missing, ["n"]);
    }
}
