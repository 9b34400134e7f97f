//! What a station needs before its first reading, checked in one place:
//! `log --check` reports every finding, and `log` refuses to start on a
//! problem and says the warnings on stderr before it starts.
//!
//! A problem is a file that cannot work as written (a store whose directory
//! cannot be created; a probe whose measuring procedure outlasts its
//! interval, so it would read far less often than the file says). A
//! warning is what may mend itself while the logger runs (a serial adapter
//! not plugged in yet: the bus keeps trying to open its port).

use std::path::Path;
use std::time::Duration;

use crate::config::{Link, StationConfig, show_duration};

/// How much a finding stands in the way.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Severity {
    /// The station cannot run as its file says.
    Problem,
    /// The station runs, but something will fail until it is mended.
    Warning,
}

/// One thing a station needs and does not have.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Finding {
    /// How much it stands in the way.
    pub severity: Severity,
    /// What is wrong, naming the bus or probe.
    pub message: String,
    /// What mends it.
    pub hint: String,
}

/// Every finding for `station`, problems first, in file order.
pub fn preflight(station: &StationConfig) -> Vec<Finding> {
    let mut found = Vec::new();
    store_directory(station, &mut found);
    for bus in &station.buses {
        if let Link::Serial { port, .. } = &bus.link {
            // A name that is not a path (`COM3`) cannot be looked for here.
            if port.starts_with('/') && !Path::new(port).exists() {
                found.push(Finding {
                    severity: Severity::Warning,
                    message: format!("bus `{}`: the serial port {port} does not exist", bus.name),
                    hint: "plug the adapter in, or correct `port` (`ls /dev/serial/by-id/` names the adapters \
                           plugged in); the bus keeps trying to open it"
                        .to_owned(),
                });
            }
        }
        for probe in bus.probes.iter().filter(|p| p.procedure) {
            let Some(procedure) = &probe.sensor.procedure else { continue };
            let least = procedure.least_duration();
            if least >= probe.interval {
                let timing = if procedure.readings > 1 {
                    format!(
                        "{} warm-up, {} readings {} apart",
                        show_duration(Duration::from_millis(u64::from(procedure.warm_up_ms))),
                        procedure.readings,
                        show_duration(Duration::from_millis(u64::from(procedure.interval_ms)))
                    )
                } else {
                    format!("{} warm-up", show_duration(Duration::from_millis(u64::from(procedure.warm_up_ms))))
                };
                found.push(Finding {
                    severity: Severity::Problem,
                    message: format!(
                        "probe `{}`: the {} procedure takes at least {} ({timing}), not less than its interval \
                         of {}: it would read once every {} or more",
                        probe.label,
                        probe.sensor.name,
                        show_duration(least),
                        show_duration(probe.interval),
                        show_duration(least)
                    ),
                    hint: format!(
                        "set `interval` above {} (the replies take time too), or `procedure = false` to read \
                         without it",
                        show_duration(least)
                    ),
                });
            }
        }
    }
    found.sort_by_key(|f| f.severity != Severity::Problem);
    found
}

/// The directory of the store: `log` creates it when missing (as a
/// service's state directory often is before the first run), so only one
/// that cannot be created is a problem.
pub fn store_directory_of(station: &StationConfig) -> &Path {
    match station.storage.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    }
}

fn store_directory(station: &StationConfig, found: &mut Vec<Finding>) {
    let dir = store_directory_of(station);
    // The nearest part of the path that exists must be a directory.
    let Some(existing) = dir.ancestors().find(|a| a.exists() || a.as_os_str().is_empty()) else { return };
    if existing.as_os_str().is_empty() || existing.is_dir() {
        return;
    }
    found.push(Finding {
        severity: Severity::Problem,
        message: format!(
            "the store {}: its directory {} cannot be created, {} is not a directory",
            station.storage.display(),
            dir.display(),
            existing.display()
        ),
        hint: "change `[storage] path`".to_owned(),
    });
}
