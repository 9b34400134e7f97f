//! A spec procedure's timing: how long the probe warms up, how many
//! readings it takes and how far apart, as the manual says or as a caller
//! overrides them, and the procedure in one line.

use std::time::Duration;

use yosemitech_spec::Procedure;

/// The waits and the number of readings of one run.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Timing {
    /// Wait after the `before` commands.
    pub warm_up: Duration,
    /// Wait between two readings.
    pub interval: Duration,
    /// Readings taken (at least 1).
    pub readings: u32,
}

impl Timing {
    /// The procedure's own timing.
    pub fn of(procedure: &Procedure) -> Self {
        Self {
            warm_up: Duration::from_millis(u64::from(procedure.warm_up_ms)),
            interval: Duration::from_millis(u64::from(procedure.interval_ms)),
            readings: procedure.readings.max(1),
        }
    }
}

/// `10 s`, `1.5 s`, `250 ms`.
fn seconds(d: Duration) -> String {
    if d.as_millis() < 1000 && !d.is_zero() {
        format!("{} ms", d.as_millis())
    } else {
        format!("{} s", d.as_secs_f64())
    }
}

/// The procedure in a line: `start_measurement, wait 10 s, 10 readings of get_x 3 s apart`.
pub fn describe(procedure: &Procedure, timing: Timing) -> String {
    let mut steps: Vec<String> = procedure.before.clone();
    if !timing.warm_up.is_zero() {
        steps.push(format!("wait {}", seconds(timing.warm_up)));
    }
    let reads = procedure.read.join(" + ");
    steps.push(match timing.readings {
        1 => format!("1 reading of {reads}"),
        n if timing.interval.is_zero() => format!("{n} readings of {reads} back to back"),
        n => format!("{n} readings of {reads} {} apart", seconds(timing.interval)),
    });
    steps.extend(procedure.after.iter().cloned());
    steps.join(", ")
}
