//! A guided diagnosis of a probe that does not answer: what `yosemitech
//! doctor` runs, kept free of the terminal so tests drive it directly.
//!
//! It sends a few reads (built from the spec by role, see [`Probes`]) on a
//! raw [`Line`], looks at every byte that comes back ([`line::Heard`]),
//! and follows the evidence: an echo of its own request, silence (the
//! wildcard address, then an address scan, then other serial settings),
//! garbage (other serial settings), damaged replies (noise, or two probes
//! at one address), a late answer, exceptions. The [`Report`] holds each
//! finding with the bytes that prove it and one [`Verdict`] with the next
//! thing to try. It never writes a register; the only request that is not
//! a read is Start Measurement, a trigger, sent to a probe that answers.

mod diagnose;
pub mod line;
mod probes;

use std::time::Duration;

use serde_json::{Value as Json, json};
use yosemitech_rtu::{CharFormat, LineSettings, Parity, StopBits};

pub use diagnose::diagnose;
pub use line::{Exchange, Line, SerialLine, hex};
pub use probes::Probes;

/// The ways the doctor tries the line, and how long it waits.
#[derive(Debug, Clone)]
pub struct Plan {
    /// The address the probe should answer at.
    pub address: u8,
    /// The serial settings the probe should run at.
    pub settings: LineSettings,
    /// The reply timeout the user's tools wait: a later answer is a finding.
    pub timeout: Duration,
    /// How long the first request and each check of an answering probe wait.
    pub listen: Duration,
    /// How long each request of the address scan waits.
    pub scan_wait: Duration,
    /// How long each request at other serial settings waits.
    pub sweep_wait: Duration,
    /// Other serial settings to try on a silent or garbled line, in order.
    pub sweep: Vec<LineSettings>,
    /// Reads sent to a probe that answers, to measure its error rate.
    pub repeats: usize,
    /// Start Measurement requests sent to a probe that answers, at most.
    pub triggers: usize,
}

/// Baud rates to try, those real probes are most likely set to first.
const BAUD_RATES: [u32; 7] = [9600, 19_200, 4800, 38_400, 2400, 57_600, 115_200];

/// Character formats to try, 8N1 first (every field driver's), then 8N2
/// (some manuals' claim), then the parities.
fn formats() -> [CharFormat; 4] {
    let with = |parity, stop_bits| CharFormat { parity, stop_bits, ..CharFormat::EIGHT_N_1 };
    [
        CharFormat::EIGHT_N_1,
        with(Parity::None, StopBits::Two),
        with(Parity::Even, StopBits::One),
        with(Parity::Odd, StopBits::One),
    ]
}

impl Plan {
    /// A plan for a probe expected at `address` and `settings`, by tools
    /// that wait `timeout`.
    pub fn new(address: u8, settings: LineSettings, timeout: Duration, triggers: usize) -> Self {
        let sweep = std::iter::once(settings.baud)
            .chain(BAUD_RATES)
            .flat_map(|baud| formats().map(move |format| LineSettings { baud, format }))
            .filter(|s| *s != settings)
            .fold(Vec::new(), |mut all, s| {
                if !all.contains(&s) {
                    all.push(s);
                }
                all
            });
        Self {
            address,
            settings,
            timeout,
            // Twice the tools' timeout, to measure a late answer; within
            // 3..=10 s so that a silent line stays under a minute.
            listen: (timeout * 2).clamp(Duration::from_secs(3), Duration::from_secs(10)),
            scan_wait: Duration::from_millis(100),
            sweep_wait: Duration::from_millis(150),
            sweep,
            repeats: 6,
            triggers,
        }
    }

    /// Addresses the scan asks: every unicast address but the expected one.
    pub fn scan_addresses(&self) -> impl Iterator<Item = u8> + '_ {
        (1..=247).filter(move |a| *a != self.address)
    }

    /// The most requests a diagnosis sends: the first request, the
    /// wildcard and the probe's reported address, the scan, two per other
    /// setting, and the checks of a probe found.
    pub fn max_requests(&self) -> usize {
        1 + 2 + self.scan_addresses().count() + 2 * self.sweep.len() + self.repeats + self.triggers
    }

    /// How long a diagnosis of a line where nothing answers takes, waits only.
    pub fn silent_duration(&self) -> Duration {
        let scan = u32::try_from(self.scan_addresses().count()).unwrap_or(u32::MAX);
        let sweep = u32::try_from(2 * self.sweep.len()).unwrap_or(u32::MAX);
        self.listen + self.scan_wait * (scan + 1) + self.sweep_wait * sweep
    }

    /// What the plan leaves out to stay within a minute.
    pub fn skipped(&self) -> Vec<String> {
        vec![
            format!(
                "the address scan runs at {} only; at the {} other serial settings only address {} and the wildcard 0xFF are asked (a full scan at each would be {} requests)",
                self.settings,
                self.sweep.len(),
                self.address,
                self.sweep.len() * 247
            ),
            format!(
                "baud rates other than {} and framings other than 8N1, 8N2, 8E1, 8O1 (7 data bits, 8E2, 8O2)",
                BAUD_RATES.map(|b| b.to_string()).join(", ")
            ),
            format!(
                "answers later than {} during the scan and the settings sweep ({} at the other settings); only the first request waits {}",
                crate::error::show_duration(self.scan_wait),
                crate::error::show_duration(self.sweep_wait),
                crate::error::show_duration(self.listen)
            ),
            "every write: the doctor never changes a register".to_owned(),
        ]
    }
}

/// What one finding is about.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FindingKind {
    /// No byte came back.
    Silent,
    /// The request came back as it was sent.
    Echo,
    /// A good reply.
    Reply,
    /// An exception reply to a read.
    Exception,
    /// A good reply from another address.
    OtherAddress,
    /// An answer at the wildcard address 0xFF.
    Wildcard,
    /// A reply from the address asked that does not hold together.
    Damaged,
    /// Bytes that are no reply.
    Garbage,
    /// The probe answers at other serial settings.
    Settings,
    /// Damaged replies between good ones, at a rate.
    Noise,
    /// The same damaged reply every time to one read, others clean.
    Collision,
    /// An answer later than the tools wait.
    SlowTurnaround,
    /// Start Measurement refused with an exception.
    TriggerRefused,
    /// No answer to Start Measurement.
    TriggerSilent,
}

impl FindingKind {
    /// A short snake_case name, for reports.
    pub fn name(self) -> &'static str {
        match self {
            FindingKind::Silent => "silent",
            FindingKind::Echo => "echo",
            FindingKind::Reply => "reply",
            FindingKind::Exception => "exception",
            FindingKind::OtherAddress => "other_address",
            FindingKind::Wildcard => "wildcard",
            FindingKind::Damaged => "damaged",
            FindingKind::Garbage => "garbage",
            FindingKind::Settings => "settings",
            FindingKind::Noise => "noise",
            FindingKind::Collision => "collision",
            FindingKind::SlowTurnaround => "slow_turnaround",
            FindingKind::TriggerRefused => "trigger_refused",
            FindingKind::TriggerSilent => "trigger_silent",
        }
    }
}

/// One thing the doctor saw, with the bytes that show it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Finding {
    /// What it is about.
    pub kind: FindingKind,
    /// What it means, in words.
    pub text: String,
    /// The line's settings when it was seen.
    pub settings: LineSettings,
    /// The address the request went to.
    pub address: u8,
    /// The spec command sent.
    pub command: String,
    /// The request's bytes.
    pub sent: Vec<u8>,
    /// Every byte that came back.
    pub received: Vec<u8>,
    /// From the end of the request to the answer's first byte.
    pub turnaround: Option<Duration>,
}

/// The verdict's machine-readable code.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum VerdictCode {
    /// The probe answers at the address and settings expected; nothing wrong seen.
    Healthy,
    /// No byte in answer to anything.
    Silent,
    /// The adapter reads back its own requests.
    Echo,
    /// The probe answers at other serial settings.
    SerialSettings,
    /// Bytes, never a frame, at every setting tried.
    Garbage,
    /// Damaged replies at a rate.
    Noise,
    /// Several probes answer one address.
    Collision,
    /// The probe answers at another address.
    OtherAddress,
    /// The probe answers only at the wildcard 0xFF.
    OnlyWildcard,
    /// The probe answers later than the tools wait.
    SlowTurnaround,
    /// The probe answers reads with exceptions.
    Exception,
    /// The probe answers reads but refuses Start Measurement.
    TriggerRefused,
    /// Stopped before the end (Ctrl-C).
    Interrupted,
}

impl VerdictCode {
    /// A short snake_case name, for reports.
    pub fn name(self) -> &'static str {
        match self {
            VerdictCode::Healthy => "healthy",
            VerdictCode::Silent => "silent",
            VerdictCode::Echo => "echo",
            VerdictCode::SerialSettings => "serial_settings",
            VerdictCode::Garbage => "garbage",
            VerdictCode::Noise => "noise",
            VerdictCode::Collision => "collision",
            VerdictCode::OtherAddress => "other_address",
            VerdictCode::OnlyWildcard => "only_wildcard",
            VerdictCode::SlowTurnaround => "slow_turnaround",
            VerdictCode::Exception => "exception",
            VerdictCode::TriggerRefused => "trigger_refused",
            VerdictCode::Interrupted => "interrupted",
        }
    }
}

/// The conclusion and the next thing to try.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Verdict {
    /// Machine-readable.
    pub code: VerdictCode,
    /// What is wrong, in a sentence.
    pub summary: String,
    /// What to do next.
    pub next_step: String,
}

/// Where a probe answered.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Answering {
    /// The serial settings it answered at.
    pub settings: LineSettings,
    /// The address it answered at.
    pub address: u8,
}

/// A whole diagnosis.
#[derive(Debug, Clone)]
pub struct Report {
    /// What was tried and how.
    pub plan: Plan,
    /// What was seen, in order.
    pub findings: Vec<Finding>,
    /// Where a probe answered, if one did.
    pub answering: Option<Answering>,
    /// The conclusion.
    pub verdict: Verdict,
    /// Requests sent.
    pub requests: usize,
    /// How long it took.
    pub elapsed: Duration,
}

fn millis(d: Duration) -> u64 {
    u64::try_from(d.as_millis()).unwrap_or(u64::MAX)
}

impl Finding {
    /// The finding as JSON: the bytes as hex, the settings as `9600 baud, 8N1`.
    pub fn to_json(&self) -> Json {
        json!({
            "kind": self.kind.name(),
            "text": self.text,
            "settings": self.settings.to_string(),
            "address": self.address,
            "command": self.command,
            "sent": hex(&self.sent),
            "received": hex(&self.received),
            "turnaround_ms": self.turnaround.map(millis),
        })
    }
}

impl Report {
    /// The report as JSON, for `--json`.
    pub fn to_json(&self, port: &str) -> Json {
        json!({
            "port": port,
            "address": self.plan.address,
            "settings": self.plan.settings.to_string(),
            "timeout_ms": millis(self.plan.timeout),
            "verdict": {
                "code": self.verdict.code.name(),
                "summary": self.verdict.summary,
                "next_step": self.verdict.next_step,
            },
            "answering": self.answering.map(|a| json!({ "settings": a.settings.to_string(), "address": a.address })),
            "findings": self.findings.iter().map(Finding::to_json).collect::<Vec<_>>(),
            "requests": self.requests,
            "max_requests": self.plan.max_requests(),
            "elapsed_ms": millis(self.elapsed),
            "skipped": self.plan.skipped(),
        })
    }
}

/// Told of the diagnosis's steps as they happen (a progress bar).
pub trait Progress {
    /// A new phase of at most `requests` requests begins.
    fn phase(&mut self, text: &str, requests: usize);
    /// One request of the phase was answered or timed out.
    fn request(&mut self);
}

/// No progress shown.
#[cfg(test)]
pub struct Quiet;

#[cfg(test)]
impl Progress for Quiet {
    fn phase(&mut self, _: &str, _: usize) {}
    fn request(&mut self) {}
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_silent_line_is_diagnosed_in_well_under_a_minute() {
        let plan = Plan::new(1, LineSettings::default(), Duration::from_secs(1), 2);
        assert!(plan.silent_duration() < Duration::from_secs(45), "{:?}", plan.silent_duration());
        assert!(!plan.sweep.contains(&plan.settings));
        assert_eq!(plan.sweep.len(), BAUD_RATES.len() * formats().len() - 1);
        // 8N2 at the same rate comes right after the settings expected, parities after.
        assert_eq!(plan.sweep[0], LineSettings { format: formats()[1], ..plan.settings });
        assert!(plan.max_requests() < 400);
        // However long the tools wait.
        let patient = Plan::new(1, LineSettings::default(), Duration::from_secs(60), 2);
        assert!(patient.silent_duration() < Duration::from_secs(50), "{:?}", patient.silent_duration());
    }
}
