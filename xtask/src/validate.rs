//! `cargo xtask validate [PATH...]`: loads spec files and reports every problem.
//!
//! Paths are files or directories (their `*.yaml`); the default is the
//! workspace's `spec/`. Diagnostics go to stderr, rustc-style, with paths
//! relative to the current directory; the exit status is 1 on any error. On
//! success one summary line goes to stdout.

use std::path::{Component, Path, PathBuf};
use std::process::ExitCode;

use yosemitech_spec::{Diagnostics, load_paths};

/// Runs the task.
pub fn run(args: &[String]) -> anyhow::Result<ExitCode> {
    if let Some(flag) = args.iter().find(|a| a.starts_with('-')) {
        if flag == "-h" || flag == "--help" {
            println!("usage: cargo xtask validate [PATH...]   (files or directories; default: spec/)");
            return Ok(ExitCode::SUCCESS);
        }
        anyhow::bail!("unknown option `{flag}`; usage: cargo xtask validate [PATH...]");
    }
    let paths: Vec<PathBuf> =
        if args.is_empty() { vec![crate::root().join("spec")] } else { args.iter().map(PathBuf::from).collect() };
    // The loader reads untrusted text: treat a panic as a bug to report, not a crash.
    let loaded = std::panic::catch_unwind(|| load_paths(&paths))
        .map_err(|_| anyhow::anyhow!("internal error: the spec loader panicked; please report this input"))?;
    match loaded {
        Ok(spec) => {
            println!("{}", summary_line(&spec));
            // A note, never an error: a spec may use any unit; only conversion needs the table.
            let outside = units_outside_the_table(&spec);
            if !outside.is_empty() {
                eprintln!(
                    "note: {} of the fields' and derived quantities' units are not in the unit table, so `--unit` and a station's `units` cannot convert them: {}",
                    outside.len(),
                    outside.join(", ")
                );
            }
            Ok(ExitCode::SUCCESS)
        }
        Err(diags) => {
            eprintln!("{}", relative(diags));
            Ok(ExitCode::FAILURE)
        }
    }
}

/// The one line a successful run prints: what the spec holds (README
/// shows it, kept fresh by `cargo xtask docs`).
pub fn summary_line(spec: &yosemitech_spec::Spec) -> String {
    let s = spec.summary();
    let manuals: usize = spec.sensors.iter().map(|x| x.manuals().count()).sum();
    let unsourced = spec.sensors.iter().filter(|x| x.manual.is_none()).count();
    let aliases: usize = spec.sensors.iter().map(|x| x.aliases.len()).sum();
    format!(
        "validated {} ({} from {}, {} without a manual, from the field's sources; {} sharing a sensor's commands), {}, {}: {} frames printed ({} complete with their CRC, {} without a CRC or with placeholders), {} checked with the errata's corrections; {}; {} ({} of their examples computed and held)",
        count(s.sensors, "sensor", "sensors"),
        s.sensors - unsourced,
        count(manuals, "manual", "manuals"),
        unsourced,
        count(aliases, "model alias", "model aliases"),
        count(s.commands, "command", "commands"),
        count(s.examples, "example", "examples"),
        s.printed_frames,
        s.complete_frames,
        s.printed_frames - s.complete_frames,
        s.frames,
        count(s.errata, "erratum", "errata"),
        count(s.derived, "derived quantity", "derived quantities"),
        s.derived_examples,
    )
}

/// The units of fields and derived quantities that `yosemitech_spec::units`
/// does not know, sorted, each once.
fn units_outside_the_table(spec: &yosemitech_spec::Spec) -> Vec<String> {
    let mut out: Vec<String> = spec
        .sensors
        .iter()
        .flat_map(|s| {
            let fields = s.commands.iter().flat_map(|c| c.fields.iter().filter_map(|f| f.unit.clone()));
            fields.chain(s.derived.iter().filter_map(|d| d.unit.clone())).collect::<Vec<_>>()
        })
        .filter(|u| yosemitech_spec::units::lookup(u).is_none())
        .collect();
    out.sort();
    out.dedup();
    out
}

/// `n` and the noun in the right number.
fn count(n: usize, one: &str, many: &str) -> String {
    format!("{n} {}", if n == 1 { one } else { many })
}

/// Rewrites every diagnostic's path relative to the current directory.
fn relative(mut diags: Diagnostics) -> Diagnostics {
    let Ok(cwd) = std::env::current_dir() else { return diags };
    for d in &mut diags.0 {
        d.file = relative_to(&d.file, &cwd);
    }
    diags
}

/// `path` relative to `base` (both made absolute), or `path` unchanged.
fn relative_to(path: &Path, base: &Path) -> PathBuf {
    let absolute = if path.is_absolute() { path.to_path_buf() } else { base.join(path) };
    let absolute = yosemitech_spec::sources::normalize(&absolute);
    let base = yosemitech_spec::sources::normalize(base);
    let (a, b): (Vec<Component<'_>>, Vec<Component<'_>>) =
        (absolute.components().collect(), base.components().collect());
    let common = a.iter().zip(&b).take_while(|(x, y)| x == y).count();
    // Only the root in common (or a different drive): the absolute path reads better.
    if common <= 1 {
        return absolute;
    }
    let mut out = PathBuf::new();
    for _ in common..b.len() {
        out.push("..");
    }
    for c in &a[common..] {
        out.push(c.as_os_str());
    }
    if out.as_os_str().is_empty() { PathBuf::from(".") } else { out }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn relative_paths() {
        let base = Path::new("/work/main");
        assert_eq!(relative_to(Path::new("/work/main/spec/a.yaml"), base), PathBuf::from("spec/a.yaml"));
        assert_eq!(relative_to(Path::new("/work/other/a.yaml"), base), PathBuf::from("../other/a.yaml"));
        assert_eq!(relative_to(Path::new("spec/./a.yaml"), base), PathBuf::from("spec/a.yaml"));
        assert_eq!(relative_to(Path::new("/tmp/a.yaml"), base), PathBuf::from("/tmp/a.yaml"));
    }
}
