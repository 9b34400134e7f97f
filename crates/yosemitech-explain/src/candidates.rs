//! Which commands a frame may be: every loaded command with its sensor, and
//! what a choice of sensor and command leaves of them.

use yosemitech_spec::{CommandSpec, Sensor, Values};

/// The lengths a normal (non-exception) reply of `c` may have: the full
/// reply, and for a trigger read also the short form with byte count 0.
pub fn reply_lens(c: &CommandSpec) -> [Option<usize>; 2] {
    let layout = c.layout();
    [Some(layout.response_len()), layout.short_response_len()]
}

/// Whether a frame to or from `slave` may be of command `c`: a command with a
/// fixed slave address only ever uses it; any other uses 0..=247 (0 being a
/// broadcast, which only writes use).
pub fn fits_slave(c: &CommandSpec, slave: u8) -> bool {
    match c.fixed_slave {
        Some(fixed) => slave == fixed,
        None => slave <= 247 && (slave != 0 || !c.is_read()),
    }
}

/// A command a frame may be, with its sensor.
#[derive(Clone, Copy)]
pub struct Candidate<'c> {
    /// The sensor's name.
    pub sensor: &'c str,
    /// Its command.
    pub command: &'c CommandSpec,
}

/// The commands frames are explained against: every loaded one frames
/// (framing never depends on a choice), those the choice leaves decode.
pub struct Commands<'c> {
    /// Every loaded sensor, in load order.
    pub sensors: Vec<&'c Sensor>,
    /// Every command of every loaded sensor, in load order.
    pub all: Vec<Candidate<'c>>,
    /// Only this sensor's commands decode.
    pub sensor: Option<&'c str>,
    /// Only this command decodes (`-` read as `_`).
    pub command: Option<String>,
}

impl<'c> Commands<'c> {
    /// Every command of `sensors`, none left out.
    pub fn new(sensors: impl IntoIterator<Item = &'c Sensor>) -> Self {
        let sensors: Vec<&'c Sensor> = sensors.into_iter().collect();
        let all = sensors
            .iter()
            .flat_map(|s| s.commands.iter().map(move |command| Candidate { sensor: &s.name, command }))
            .collect();
        Self { sensors, all, sensor: None, command: None }
    }

    /// The loaded sensor called `name`.
    pub fn sensor_named(&self, name: &str) -> Option<&'c Sensor> {
        self.sensors.iter().copied().find(|s| s.name == name)
    }

    /// Whether the choice leaves `c`.
    pub fn allows(&self, c: &Candidate<'_>) -> bool {
        self.sensor.is_none_or(|s| s == c.sensor) && self.command.as_ref().is_none_or(|n| *n == c.command.name)
    }

    /// The commands of the chosen sensor(s), whatever the chosen command.
    pub fn of_chosen_sensors(&self) -> impl Iterator<Item = &Candidate<'c>> {
        self.all.iter().filter(|c| self.sensor.is_none_or(|s| s == c.sensor))
    }
}

/// One way to read a frame or an exchange: the candidates that read it so,
/// and the values.
pub struct Decoding<'c> {
    /// In load order.
    pub cands: Vec<Candidate<'c>>,
    /// Empty where the frame carries none (or they were not decoded).
    pub values: Values,
}

impl<'c> Decoding<'c> {
    /// The first candidate's command.
    pub fn command(&self) -> Option<&'c CommandSpec> {
        self.cands.first().map(|c| c.command)
    }

    /// The sensors, in order.
    pub fn sensors(&self) -> Vec<&'c str> {
        self.cands.iter().map(|c| c.sensor).collect()
    }

    /// The command's name, when every candidate has the same one.
    pub fn name(&self) -> Option<&str> {
        let first = self.command()?;
        self.cands.iter().all(|c| c.command.name == first.name).then_some(first.name.as_str())
    }
}

/// Candidates of one frame as decodings, in order: a command shared by every
/// probe (a fragment's, such as yosemitech-common.yaml) is one decoding with
/// all its sensors.
pub fn by_shared_command<'c>(cands: impl IntoIterator<Item = Candidate<'c>>) -> Vec<Decoding<'c>> {
    let mut groups: Vec<Decoding<'c>> = Vec::new();
    for cand in cands {
        let c = cand.command;
        let same = groups.iter_mut().find(|g| {
            g.command().is_some_and(|k| {
                k.name == c.name
                    && k.shared_from.is_some()
                    && k.shared_from == c.shared_from
                    && k.layout() == c.layout()
            })
        });
        match same {
            Some(g) => g.cands.push(cand),
            None => groups.push(Decoding { cands: vec![cand], values: Vec::new() }),
        }
    }
    groups
}

/// Candidates with their values, the equal ones together: same fields, same
/// values (bit for bit), same units.
pub fn by_equal_values<'c>(decoded: impl IntoIterator<Item = (Candidate<'c>, Values)>) -> Vec<Decoding<'c>> {
    let mut groups: Vec<Decoding<'c>> = Vec::new();
    for (cand, values) in decoded {
        let same = groups.iter_mut().find(|g| {
            let unit = |c: Option<&CommandSpec>, n: &str| c.and_then(|c| c.field(n)).and_then(|f| f.unit.clone());
            g.values.len() == values.len()
                && g.values.iter().zip(&values).all(|((n1, v1), (n2, v2))| {
                    n1 == n2 && v1.same_as(v2) && unit(g.command(), n1) == unit(Some(cand.command), n2)
                })
        });
        match same {
            Some(g) => g.cands.push(cand),
            None => groups.push(Decoding { cands: vec![cand], values }),
        }
    }
    groups
}

/// `get_sn of conductivity, ph_orp; get_x of y`: candidates by command name, in order.
pub fn label(cands: &[Candidate<'_>]) -> String {
    let mut names: Vec<(&str, Vec<&str>)> = Vec::new();
    for c in cands {
        match names.iter_mut().find(|(n, _)| *n == c.command.name) {
            Some((_, sensors)) => sensors.push(c.sensor),
            None => names.push((&c.command.name, vec![c.sensor])),
        }
    }
    names.iter().map(|(n, sensors)| format!("{n} of {}", sensors.join(", "))).collect::<Vec<_>>().join("; ")
}
