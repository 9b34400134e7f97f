//! The sensors the tool knows: the spec compiled into the binary, plus spec
//! files loaded at run time with `--spec`.
//!
//! Built-in files are served from memory ([`MemSources`]) under a virtual
//! directory. A `--spec` directory is read from disk; a file it includes but
//! does not hold (typically `yosemitech-common.yaml`) falls back to the
//! built-in copy of the same name, so a new sensor's YAML file is enough on
//! its own. A `--spec` sensor with a built-in sensor's name replaces it (and
//! is then served through the interpreter, not the typed crate).

use std::path::PathBuf;
use std::sync::Arc;

use yosemitech_ops::built_in;
use yosemitech_spec::lookup::{Lookup, find_sensor};
use yosemitech_spec::suggest::closest;
use yosemitech_spec::{CommandSpec, Sensor};

use crate::error::{CliError, Result};

/// Where a sensor's spec came from.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Origin {
    /// Compiled into the binary: the typed `yosemitech` crate matches it.
    BuiltIn,
    /// Loaded at run time from this `--spec` path.
    Loaded(PathBuf),
}

/// One known sensor.
#[derive(Debug, Clone)]
pub struct Entry {
    /// Its spec.
    pub sensor: Arc<Sensor>,
    /// Where the spec came from.
    pub origin: Origin,
}

/// A measurement read and one exchange of it its manual prints
/// ([`Catalog::example_read`]).
#[derive(Debug, Clone, Copy)]
pub struct ExampleRead<'c> {
    /// The sensor.
    pub sensor: &'c Sensor,
    /// The read.
    pub read: &'c CommandSpec,
    /// The request, with its CRC.
    pub request: &'c [u8],
    /// The reply, with its CRC.
    pub reply: &'c [u8],
}

/// Every sensor the tool knows, in load order.
#[derive(Debug, Clone)]
pub struct Catalog {
    entries: Vec<Entry>,
    /// The `--spec` paths, for commands printed to paste back.
    spec_paths: Vec<PathBuf>,
}

impl Catalog {
    /// The built-in sensors, then those of each `--spec` path.
    pub fn load(extra: &[PathBuf]) -> Result<Self> {
        let spec = built_in::load().map_err(|d| {
            CliError::device(format!("the built-in spec does not load ({} problems)", d.len()))
                .hint("this is a bug in the build; rebuild from a clean checkout")
        })?;
        let mut entries: Vec<Entry> =
            spec.sensors.into_iter().map(|s| Entry { sensor: Arc::new(s), origin: Origin::BuiltIn }).collect();
        for path in extra {
            if !path.exists() {
                return Err(CliError::usage(format!("--spec {}: no such file or directory", path.display()))
                    .hint("give a directory of spec YAML files (like the repository's spec/) or one file"));
            }
            let loaded = built_in::load_file(path).map_err(|d| {
                let mut e = CliError::usage(format!(
                    "the spec in {} has {} problem{}",
                    path.display(),
                    d.len(),
                    if d.len() == 1 { "" } else { "s" }
                ));
                for diag in &d.0 {
                    for line in diag.to_string().lines() {
                        e = e.detail(line.to_owned());
                    }
                }
                e.hint("fix the file; `yosemitech list --spec FILE` checks it again, and an editor checks keys through spec/schema.json")
            })?;
            for sensor in loaded.sensors {
                let entry = Entry { sensor: Arc::new(sensor), origin: Origin::Loaded(path.clone()) };
                match entries.iter_mut().find(|e| e.sensor.name == entry.sensor.name) {
                    Some(existing) => *existing = entry,
                    None => entries.push(entry),
                }
            }
        }
        Ok(Self { entries, spec_paths: extra.to_vec() })
    }

    /// Every sensor.
    pub fn entries(&self) -> &[Entry] {
        &self.entries
    }

    /// The sensor called `name` (`-` may stand for `_`), or an error that
    /// suggests the closest name.
    pub fn entry(&self, name: &str) -> Result<&Entry> {
        let sensors: Vec<&Sensor> = self.entries.iter().map(|e| &*e.sensor).collect();
        match find_sensor(&sensors, name) {
            Lookup::Found { index, .. } => {
                self.entries.get(index).ok_or_else(|| CliError::usage(format!("unknown sensor `{name}`")))
            }
            Lookup::SameModel(indices) => {
                let names: Vec<&str> =
                    indices.iter().filter_map(|&i| sensors.get(i)).map(|s| s.name.as_str()).collect();
                Err(CliError::usage(format!("model `{name}` is {} sensors: {}", names.len(), names.join(", ")))
                    .hint("name the sensor (`yosemitech list` says how they differ)"))
            }
            Lookup::Unknown { closest } => {
                let names: Vec<&str> = sensors.iter().map(|s| s.name.as_str()).collect();
                let e = CliError::usage(format!("unknown sensor `{name}`"));
                Err(match closest {
                    Some(best) => e.hint(format!("did you mean `{best}`? Known sensors: {}", names.join(", "))),
                    None => e.hint(format!(
                        "known sensors: {}; `yosemitech list` shows them, --spec DIR loads more",
                        names.join(", ")
                    )),
                })
            }
        }
    }

    /// The sensor called `name`.
    pub fn sensor(&self, name: &str) -> Result<&Arc<Sensor>> {
        self.entry(name).map(|e| &e.sensor)
    }

    /// The read that help texts and the demo show as an example, with its
    /// sensor and the frames its manual prints: the first read of a
    /// measuring procedure (in load order; so `measure` runs on its sensor)
    /// whose request no other command shares (so `decode` names it from the
    /// request alone) and that has a complete printed request and reply.
    /// Chosen from the spec, so no text names a sensor by hand.
    pub fn example_read(&self) -> Option<ExampleRead<'_>> {
        let same_request = |a: &CommandSpec, b: &CommandSpec| {
            (a.function, a.address, a.count, a.fixed_slave) == (b.function, b.address, b.count, b.fixed_slave)
        };
        let every_command = || self.entries.iter().flat_map(|e| &e.sensor.commands);
        self.entries.iter().find_map(|entry| {
            let procedure = entry.sensor.procedure.as_ref()?;
            procedure.read.iter().filter_map(|name| entry.sensor.command(name)).find_map(|read| {
                if every_command().filter(|c| same_request(c, read)).count() != 1 {
                    return None;
                }
                let (request, reply) = read.examples.iter().find_map(|e| e.true_pair())?;
                Some(ExampleRead { sensor: &entry.sensor, read, request, reply })
            })
        })
    }

    /// `--spec` arguments to repeat in a printed command, for a sensor of this origin.
    pub fn spec_args(&self, origin: &Origin) -> Vec<String> {
        match origin {
            Origin::BuiltIn => Vec::new(),
            Origin::Loaded(_) => {
                self.spec_paths.iter().flat_map(|p| ["--spec".to_owned(), p.display().to_string()]).collect()
            }
        }
    }
}

/// The command called `name` of `sensor` (`-` for `_`, and `ph` for
/// `get_ph` when that is a read), or an error suggesting the closest name.
pub fn command<'s>(sensor: &'s Sensor, name: &str) -> Result<&'s CommandSpec> {
    let wanted = name.replace('-', "_");
    if let Some(c) = sensor.command(&wanted).or_else(|| sensor.command(&format!("get_{wanted}"))) {
        return Ok(c);
    }
    let names: Vec<&str> = sensor.commands.iter().map(|c| c.name.as_str()).collect();
    let e = CliError::usage(format!("sensor `{}` has no command `{name}`", sensor.name));
    Err(match closest(&wanted, &names) {
        Some(best) => e.hint(format!("did you mean `{best}`? `yosemitech list {}` shows every command", sensor.name)),
        None => e.hint(format!("its commands: {}", names.join(", "))),
    })
}

/// Reads a command `write` covers entirely (for read-back), if any: the
/// smallest such read.
pub fn read_back_for<'s>(sensor: &'s Sensor, write: &CommandSpec) -> Option<&'s CommandSpec> {
    if write.count == 0 {
        return None;
    }
    let end = u32::from(write.address) + u32::from(write.count);
    sensor
        .commands
        .iter()
        .filter(|r| r.is_read() && r.address <= write.address && u32::from(r.address) + u32::from(r.count) >= end)
        .min_by_key(|r| r.count)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The workspace's spec, read from disk: what the binary embeds.
    use yosemitech_tests::spec;

    #[test]
    fn built_in_spec_loads_every_file() {
        let catalog = Catalog::load(&[]).unwrap();
        let names: Vec<&str> = catalog.entries().iter().map(|e| e.sensor.name.as_str()).collect();
        let want: Vec<String> = spec().sensors.iter().map(|s| s.name.clone()).collect();
        assert_eq!(names, want);
        assert!(built_in::EMBEDDED_SPEC.iter().any(|(n, _)| *n == "yosemitech-common.yaml"));
        assert!(catalog.entries().iter().all(|e| e.origin == Origin::BuiltIn));
    }

    #[test]
    fn suggests_close_names() {
        let catalog = Catalog::load(&[]).unwrap();
        for entry in catalog.entries() {
            let name = &entry.sensor.name;
            assert_eq!(&catalog.sensor(name).unwrap().name, name);
            assert_eq!(&catalog.sensor(&name.replace('_', "-")).unwrap().name, name);
            // A typo: one letter doubled.
            let typo = format!("{}{}", &name[..1], name);
            let e = catalog.sensor(&typo).unwrap_err();
            assert!(e.hint.unwrap().contains(&format!("did you mean `{name}`")), "{typo}");
        }
    }

    #[test]
    fn the_example_read_is_a_procedure_read_with_a_request_of_its_own() {
        let catalog = Catalog::load(&[]).unwrap();
        let example = catalog.example_read().expect("some measurement read has a printed exchange");
        let procedure = example.sensor.procedure.as_ref().expect("the example's sensor states a procedure");
        assert!(procedure.read.contains(&example.read.name));
        let slave = example.request[0];
        let values = example.read.decode_response(slave, example.reply).unwrap();
        assert!(!values.is_empty());
        // Its request is its own: no other command of any sensor sends it.
        let senders: Vec<&str> = catalog
            .entries()
            .iter()
            .flat_map(|e| &e.sensor.commands)
            .filter(|c| c.encode_request(slave, &Default::default()).is_ok_and(|r| r == example.request))
            .map(|c| c.name.as_str())
            .collect();
        assert_eq!(senders, [example.read.name.as_str()]);
    }

    #[test]
    fn derives_roles_from_the_spec() {
        let catalog = Catalog::load(&[]).unwrap();
        for entry in catalog.entries() {
            let s = &entry.sensor;
            for (w, r) in s.coefficient_blocks() {
                assert!(!w.is_read() && r.is_read() && w.address == r.address && w.count == r.count);
                assert!(w.named_fields().all(|f| matches!(f.kind, yosemitech_spec::FieldKind::F32 { .. })));
            }
            for c in s.measurement_reads() {
                assert!(c.is_read() && c.fields.iter().any(|f| f.unit.is_some()), "{} {}", s.name, c.name);
            }
            // The slave-address write reads back through the slave-address read.
            if let (Some(set), Some(get)) = (
                s.command_with_role(yosemitech_spec::Role::SetSlaveAddress),
                s.command_with_role(yosemitech_spec::Role::GetSlaveAddress),
            ) {
                assert_eq!(read_back_for(s, set).unwrap().name, get.name);
            }
        }
    }
}
