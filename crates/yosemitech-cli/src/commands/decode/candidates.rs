//! Which commands a frame may be: every loaded command with its sensor, and
//! what `--sensor` and `--command` leave of them.

use yosemitech_spec::CommandSpec;
use yosemitech_spec::suggest::closest;

use crate::catalog::{Catalog, Entry};
use crate::cli::DecodeArgs;
use crate::error::{CliError, Result};

/// The lengths a normal (non-exception) reply of `c` may have: the full
/// reply, and for a trigger read also the short form with byte count 0.
pub(super) fn reply_lens(c: &CommandSpec) -> [Option<usize>; 2] {
    let layout = c.layout();
    [Some(layout.response_len()), layout.short_response_len()]
}

/// Whether a frame to or from `slave` may be of command `c`: a command with a
/// fixed slave address only ever uses it; any other uses 0..=247 (0 being a
/// broadcast, which only writes use).
pub(super) fn fits_slave(c: &CommandSpec, slave: u8) -> bool {
    match c.fixed_slave {
        Some(fixed) => slave == fixed,
        None => slave <= 247 && (slave != 0 || !c.is_read()),
    }
}

/// Which commands `--sensor` and `--command` leave to decode as.
pub(super) struct Filter<'c> {
    /// The sensors considered.
    pub(super) entries: Vec<&'c Entry>,
    /// Only this command (`-` read as `_`).
    pub(super) command: Option<String>,
}

impl<'c> Filter<'c> {
    pub(super) fn new(catalog: &'c Catalog, args: &DecodeArgs) -> Result<Self> {
        let entries: Vec<&Entry> = match &args.sensor {
            Some(name) => vec![catalog.entry(name)?],
            None => catalog.entries().iter().collect(),
        };
        let command = args.command.as_ref().map(|n| n.replace('-', "_"));
        if let (Some(name), Some(wanted)) = (&args.command, &command)
            && !entries.iter().any(|e| e.sensor.command(wanted).is_some())
        {
            let names: Vec<&str> =
                entries.iter().flat_map(|e| e.sensor.commands.iter().map(|c| c.name.as_str())).collect();
            let e = CliError::usage(format!("no loaded sensor has a command `{name}`"));
            return Err(match closest(wanted, &names) {
                Some(best) => e.hint(format!("did you mean `{best}`? `yosemitech list` shows every command")),
                None => e.hint("`yosemitech list` shows every command"),
            });
        }
        Ok(Self { entries, command })
    }

    pub(super) fn allows(&self, c: &Cand<'_>) -> bool {
        self.entries.iter().any(|e| e.sensor.name == c.sensor)
            && self.command.as_ref().is_none_or(|n| *n == c.command.name)
    }
}

/// A command a frame may be, with its sensor.
#[derive(Clone, Copy)]
pub(super) struct Cand<'c> {
    pub(super) sensor: &'c str,
    pub(super) command: &'c CommandSpec,
}

/// A command that fits a frame, with every sensor that has it: [`Cand`]s
/// grouped by [`shared`].
pub(super) struct Candidate<'c> {
    pub(super) sensors: Vec<&'c str>,
    pub(super) command: &'c CommandSpec,
}

impl Candidate<'_> {
    pub(super) fn label(&self) -> String {
        format!(
            "{} {} (0x{:04X}, {} register{})",
            self.sensors.join("/"),
            self.command.name,
            self.command.address,
            self.command.count,
            if self.command.count == 1 { "" } else { "s" }
        )
    }
}

/// `cands` as [`Candidate`]s, in order: a command shared by every probe
/// (a fragment's, such as yosemitech-common.yaml) is one candidate with all
/// its sensors.
pub(super) fn shared<'c>(cands: impl IntoIterator<Item = Cand<'c>>) -> Vec<Candidate<'c>> {
    let mut candidates: Vec<Candidate<'c>> = Vec::new();
    for Cand { sensor, command: c } in cands {
        let same = candidates.iter_mut().find(|k| {
            k.command.name == c.name
                && k.command.shared_from.is_some()
                && k.command.shared_from == c.shared_from
                && k.command.layout() == c.layout()
        });
        match same {
            Some(k) => k.sensors.push(sensor),
            None => candidates.push(Candidate { sensors: vec![sensor], command: c }),
        }
    }
    candidates
}

/// `get_sn of conductivity, ph_orp; get_x of y`: candidates by command name, in order.
pub(super) fn label(cands: &[Cand<'_>]) -> String {
    let mut names: Vec<(&str, Vec<&str>)> = Vec::new();
    for c in cands {
        match names.iter_mut().find(|(n, _)| *n == c.command.name) {
            Some((_, sensors)) => sensors.push(c.sensor),
            None => names.push((&c.command.name, vec![c.sensor])),
        }
    }
    names.iter().map(|(n, sensors)| format!("{n} of {}", sensors.join(", "))).collect::<Vec<_>>().join("; ")
}
