//! Help with examples taken from the spec.
//!
//! The help texts of [`crate::cli`] name no sensor and no command: where an
//! example needs one they hold a placeholder (`{sensors}`, `{examples}`,
//! `{sensor}`, `{read}`, `{request}`, `{reply}`, `{frames}`), filled from the
//! built-in spec ([`Catalog::example_read`]) only when help is shown, so a
//! run that shows none does not load the spec for it.

use clap::builder::StyledStr;
use std::io::Write as _;

use clap::error::{ContextKind, ErrorKind};
use clap::{Command, CommandFactory};

use crate::catalog::Catalog;
use crate::cli::Cli;
use crate::format::hex;

/// Where the sensors' titles are wrapped in the long help.
const WIDTH: usize = 92;

/// Exits as clap does for a parse error; help is rendered again with its
/// placeholders filled in first.
pub fn exit(e: clap::Error) -> ! {
    if let Some(variable) = from_environment(&e) {
        let value = std::env::var(variable).unwrap_or_default();
        let _ = writeln!(
            std::io::stderr(),
            "error: {variable}={value:?} is not valid for {}\nhint: set {variable} to a valid value, or unset it \
             and give the option on the command line",
            e.get(ContextKind::InvalidArg).map(ToString::to_string).unwrap_or_default()
        );
        std::process::exit(2);
    }
    if matches!(e.kind(), ErrorKind::DisplayHelp | ErrorKind::DisplayHelpOnMissingArgumentOrSubcommand)
        && let Ok(catalog) = Catalog::load(&[])
        && let Err(filled) = fill(Cli::command(), &Placeholders::of(&catalog)).try_get_matches()
    {
        filled.exit()
    }
    e.exit()
}

/// The environment variable a refused value came from: the option has one
/// (`YOSEMITECH_BAUD` for `--baud`), it is set, and the command line does
/// not give the option. Clap's own message blames the option.
fn from_environment(e: &clap::Error) -> Option<&'static str> {
    if !matches!(e.kind(), ErrorKind::ValueValidation | ErrorKind::InvalidValue) {
        return None;
    }
    let arg = e.get(ContextKind::InvalidArg)?.to_string();
    let args: Vec<String> = std::env::args().collect();
    let given = |long: &str, short: &str| {
        args.iter().any(|a| a == long || a.starts_with(&format!("{long}=")) || a.starts_with(short))
    };
    [("--baud", "-b", "YOSEMITECH_BAUD"), ("--port", "-p", "YOSEMITECH_PORT")]
        .into_iter()
        .find(|(long, short, variable)| {
            arg.starts_with(long) && !given(long, short) && std::env::var_os(variable).is_some()
        })
        .map(|(_, _, variable)| variable)
}

/// Each placeholder and its text.
#[derive(Debug)]
pub struct Placeholders(Vec<(&'static str, String)>);

impl Placeholders {
    /// The texts for `catalog`: its sensors' titles and examples built on
    /// its example read (`SENSOR`, `COMMAND` and `HEX` where it has none).
    pub fn of(catalog: &Catalog) -> Self {
        let titles: Vec<&str> = catalog.entries().iter().map(|e| e.sensor.title.as_str()).collect();
        let (sensor, read, request, reply) = match catalog.example_read() {
            Some(e) => (e.sensor.name.clone(), e.read.name.clone(), hex(e.request), hex(e.reply)),
            None => ("SENSOR".into(), "COMMAND".into(), "HEX".into(), "HEX".into()),
        };
        let compact = |frame: &str| frame.replace(' ', "");
        let frames = format!("{}{}", compact(&request), compact(&reply));
        let examples = [
            ("yosemitech demo".to_owned(), "every sensor simulated, no hardware needed"),
            (format!("yosemitech list {sensor}"), "commands, registers and fields"),
            (format!("yosemitech read {sensor} {read} --port /dev/ttyUSB0"), ""),
            (format!("yosemitech poll {sensor} -p /dev/ttyUSB0 --interval 10s --format csv >> log.csv"), ""),
            (format!("yosemitech measure {sensor} -p /dev/ttyUSB0"), "its manual's measuring procedure"),
            (format!("yosemitech decode \"{request}\" \"{reply}\""), ""),
            ("yosemitech scan --port /dev/ttyUSB0".to_owned(), ""),
            ("yosemitech watch --db station.db".to_owned(), "a station's latest values, live"),
            ("yosemitech plot --db station.db --from 1d --out day.png".to_owned(), ""),
        ];
        let examples: Vec<String> = examples
            .iter()
            .map(|(line, what)| if what.is_empty() { format!("  {line}") } else { format!("  {line:48} {what}") })
            .collect();
        Self(vec![
            ("{sensors}", wrap(&titles, WIDTH)),
            ("{examples}", examples.join("\n")),
            ("{sensor}", sensor),
            ("{read}", read),
            ("{request}", request),
            ("{reply}", reply),
            ("{frames}", frames),
        ])
    }

    /// `text` with every placeholder replaced.
    pub fn apply(&self, text: &str) -> String {
        self.0.iter().fold(text.to_owned(), |text, (placeholder, value)| text.replace(placeholder, value))
    }
}

/// `items` joined with `, ` into lines of at most `width` characters,
/// never breaking an item (a longer one has a line of its own).
fn wrap(items: &[&str], width: usize) -> String {
    let mut lines: Vec<String> = Vec::new();
    for item in items {
        match lines.last_mut() {
            Some(line) if line.chars().count() + 3 + item.chars().count() <= width => {
                line.push_str(", ");
                line.push_str(item);
            }
            Some(line) => {
                line.push(',');
                lines.push((*item).to_owned());
            }
            None => lines.push((*item).to_owned()),
        }
    }
    lines.join("\n")
}

/// `command` and its subcommands with every help text's placeholders filled.
pub fn fill(command: Command, placeholders: &Placeholders) -> Command {
    let filled = |text: Option<&StyledStr>| {
        text.map(ToString::to_string).filter(|t| t.contains('{')).map(|t| placeholders.apply(&t))
    };
    let mut command = command;
    if let Some(text) = filled(command.get_about()) {
        command = command.about(text);
    }
    if let Some(text) = filled(command.get_long_about()) {
        command = command.long_about(text);
    }
    if let Some(text) = filled(command.get_after_help()) {
        command = command.after_help(text);
    }
    if let Some(text) = filled(command.get_after_long_help()) {
        command = command.after_long_help(text);
    }
    command
        .mut_args(|arg| {
            let (help, long) = (filled(arg.get_help()), filled(arg.get_long_help()));
            let arg = match help {
                Some(text) => arg.help(text),
                None => arg,
            };
            match long {
                Some(text) => arg.long_help(text),
                None => arg,
            }
        })
        .mut_subcommands(|sub| fill(sub, placeholders))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every help text of the tool, filled.
    fn every_text(command: &Command, out: &mut Vec<String>) {
        let texts = [command.get_about(), command.get_long_about(), command.get_after_help()];
        out.extend(texts.into_iter().flatten().map(ToString::to_string));
        out.extend(command.get_arguments().filter_map(|a| a.get_help()).map(ToString::to_string));
        for sub in command.get_subcommands() {
            every_text(sub, out);
        }
    }

    #[test]
    fn every_placeholder_is_filled_from_the_spec() {
        let catalog = Catalog::load(&[]).unwrap();
        let placeholders = Placeholders::of(&catalog);
        let mut raw = Vec::new();
        every_text(&Cli::command(), &mut raw);
        let used: Vec<&str> =
            placeholders.0.iter().map(|(p, _)| *p).filter(|p| raw.iter().any(|t| t.contains(p))).collect();
        assert_eq!(used.len(), placeholders.0.len(), "every placeholder is used somewhere: {used:?}");
        let mut texts = Vec::new();
        every_text(&fill(Cli::command(), &placeholders), &mut texts);
        for text in &texts {
            assert!(placeholders.0.iter().all(|(p, _)| !text.contains(p)), "{text}");
        }
        let example = catalog.example_read().unwrap();
        let all = texts.join("\n");
        assert!(all.contains(&format!("yosemitech read {} {} ", example.sensor.name, example.read.name)), "{all}");
        assert!(all.contains(&hex(example.reply)), "{all}");
        for entry in catalog.entries() {
            assert!(all.contains(&entry.sensor.title), "{}", entry.sensor.title);
        }
    }

    #[test]
    fn wraps_between_items() {
        assert_eq!(wrap(&["aa", "bb", "cc"], 7), "aa, bb,\ncc");
        assert_eq!(wrap(&["aaaaaaaa", "bb"], 5), "aaaaaaaa,\nbb");
        assert_eq!(wrap(&[], 5), "");
    }
}
