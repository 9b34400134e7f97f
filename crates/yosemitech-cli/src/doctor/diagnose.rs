//! The diagnosis itself: which request next, given what came back.

use std::io;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use yosemitech_rtu::{ExceptionCode, LineSettings};
use yosemitech_spec::interp::decode_fields;
use yosemitech_spec::{CommandSpec, Value};

use super::line::{Heard, exchange, hear};
use super::{Answering, Exchange, Finding, FindingKind, Line, Plan, Probes, Progress, Report, Verdict, VerdictCode};
use crate::error::show_duration;

/// The wildcard address of the `get_slave_address` read.
const WILDCARD: u8 = 0xFF;

/// Garbage findings kept per phase (a scan can hear many).
const GARBAGE_KEPT: usize = 3;

/// Runs a diagnosis on `line`; `stop` (Ctrl-C) ends it early with what it found so far.
pub fn diagnose(
    line: &mut dyn Line,
    probes: &Probes<'_>,
    plan: &Plan,
    progress: &mut dyn Progress,
    stop: &AtomicBool,
) -> io::Result<Report> {
    let started = Instant::now();
    let mut doctor = Doctor {
        line,
        probes,
        plan,
        progress,
        stop,
        findings: Vec::new(),
        requests: 0,
        settings: plan.settings,
        answering: None,
    };
    let verdict = doctor.run()?;
    Ok(Report {
        plan: plan.clone(),
        findings: doctor.findings,
        answering: doctor.answering,
        verdict,
        requests: doctor.requests,
        elapsed: started.elapsed(),
    })
}

/// Why the diagnosis ended early.
enum Stop {
    /// Ctrl-C.
    Interrupted,
    /// The port failed.
    Io(io::Error),
}

impl From<io::Error> for Stop {
    fn from(e: io::Error) -> Self {
        Stop::Io(e)
    }
}

type Step<T> = Result<T, Stop>;

struct Doctor<'a, 'c> {
    line: &'a mut dyn Line,
    probes: &'a Probes<'c>,
    plan: &'a Plan,
    progress: &'a mut dyn Progress,
    stop: &'a AtomicBool,
    findings: Vec<Finding>,
    requests: usize,
    settings: LineSettings,
    answering: Option<Answering>,
}

/// One exchange and what its answer is.
struct Asked<'c> {
    command: &'c CommandSpec,
    address: u8,
    exchange: Exchange,
    heard: Heard,
}

fn verdict(code: VerdictCode, summary: impl Into<String>, next_step: impl Into<String>) -> Verdict {
    Verdict { code, summary: summary.into(), next_step: next_step.into() }
}

fn exception_text(code: u8) -> String {
    format!("exception {code:02X} ({})", ExceptionCode::from_u8(code))
}

/// Rounded up to a tidy timeout: the next 100 ms above 1.5 times `d`.
fn generous(d: Duration) -> Duration {
    let ms = u64::try_from(d.as_millis()).unwrap_or(u64::MAX / 2).saturating_mul(3) / 2;
    Duration::from_millis(ms.div_ceil(100).saturating_mul(100))
}

impl<'c> Doctor<'_, 'c> {
    fn run(&mut self) -> io::Result<Verdict> {
        match self.first_contact() {
            Ok(v) => Ok(v),
            Err(Stop::Io(e)) => Err(e),
            Err(Stop::Interrupted) => Ok(verdict(
                VerdictCode::Interrupted,
                format!("stopped after {} requests, before the diagnosis was complete", self.requests),
                "the findings so far are listed; run `yosemitech doctor` again to finish",
            )),
        }
    }

    fn ask(&mut self, command: &'c CommandSpec, address: u8, wait: Duration) -> Step<Asked<'c>> {
        if self.stop.load(Ordering::SeqCst) {
            return Err(Stop::Interrupted);
        }
        let request = command.encode_request(address, &Default::default()).map_err(|e| {
            Stop::Io(io::Error::new(io::ErrorKind::InvalidInput, format!("cannot build {}: {e}", command.name)))
        })?;
        let exchange = exchange(self.line, &request, wait, self.stop)?;
        self.requests += 1;
        self.progress.request();
        if self.stop.load(Ordering::SeqCst) && exchange.received.is_empty() {
            // Cut short: its silence proves nothing.
            return Err(Stop::Interrupted);
        }
        let heard = hear(command, address, exchange.answer());
        Ok(Asked { command, address, exchange, heard })
    }

    fn note(&mut self, kind: FindingKind, text: impl Into<String>, asked: &Asked<'_>) {
        self.findings.push(Finding {
            kind,
            text: text.into(),
            settings: self.settings,
            address: asked.address,
            command: asked.command.name.clone(),
            sent: asked.exchange.sent.clone(),
            received: asked.exchange.received.clone(),
            turnaround: asked.exchange.turnaround(),
        });
    }

    fn configure(&mut self, settings: LineSettings) -> Step<()> {
        self.line.configure(settings)?;
        self.settings = settings;
        Ok(())
    }

    /// The finding for an answer that is not silence.
    fn note_answer(&mut self, asked: &Asked<'_>) {
        let at = format!("address {} at {}", asked.address, self.settings);
        let (kind, text) = match &asked.heard {
            Heard::Nothing => (FindingKind::Silent, format!("no byte in answer to {} ({at})", asked.command.name)),
            Heard::Reply(_) => (
                FindingKind::Reply,
                format!(
                    "{} answered ({at}) after {}",
                    asked.command.name,
                    asked.exchange.turnaround().map_or_else(|| "?".to_owned(), show_duration)
                ),
            ),
            Heard::Exception(code) => (
                FindingKind::Exception,
                format!("{} refused with {} ({at})", asked.command.name, exception_text(*code)),
            ),
            Heard::OtherAddress(other) => (
                FindingKind::OtherAddress,
                format!(
                    "a well-formed reply to {} came from address {other}, not {}",
                    asked.command.name, asked.address
                ),
            ),
            Heard::Damaged => (
                FindingKind::Damaged,
                format!("a reply to {} from {at} that does not hold together (CRC or length)", asked.command.name),
            ),
            Heard::Garbage => (
                FindingKind::Garbage,
                format!(
                    "{} bytes in answer to {} ({at}) that are no Modbus frame",
                    asked.exchange.answer().len(),
                    asked.command.name
                ),
            ),
        };
        self.note(kind, text, asked);
    }

    fn first_contact(&mut self) -> Step<Verdict> {
        let (address, identify) = (self.plan.address, self.probes.identify);
        self.configure(self.plan.settings)?;
        self.progress.phase(&format!("asking address {address} at {}", self.settings), 1);
        let asked = self.ask(identify, address, self.plan.listen)?;
        if asked.exchange.echoed() {
            self.note(
                FindingKind::Echo,
                format!("the {}-byte request came back as it was sent", asked.exchange.sent.len()),
                &asked,
            );
            if !asked.exchange.answer().is_empty() {
                self.note_answer(&asked);
            }
            let behind = match asked.heard {
                Heard::Reply(_) => " (the probe's reply follows it)",
                Heard::Nothing => " and nothing else",
                _ => " (more bytes follow it)",
            };
            return Ok(verdict(
                VerdictCode::Echo,
                format!("the line reads back every request{behind}: the adapter hears its own transmitter"),
                "turn on the RS-485 adapter's echo suppression: an automatic-direction adapter, or its receiver \
                 disabled while it sends (RE tied to DE, or the adapter's `echo` switch off); a master that \
                 cannot avoid the echo must discard it (SerialConfig::echo_suppression in yosemitech-rtu)",
            ));
        }
        self.note_answer(&asked);
        match asked.heard {
            Heard::Nothing => self.search(),
            Heard::Garbage => self.sweep(true),
            Heard::OtherAddress(other) => {
                self.answering = Some(Answering { settings: self.settings, address: other });
                let health = self.health(other, vec![asked])?;
                Ok(health.unwrap_or_else(|| other_address(other, address)))
            }
            Heard::Reply(_) | Heard::Exception(_) | Heard::Damaged => {
                self.answering = Some(Answering { settings: self.settings, address });
                let health = self.health(address, vec![asked])?;
                Ok(health.unwrap_or_else(|| healthy(address, self.settings)))
            }
        }
    }

    /// Nothing at the address: the wildcard, then every other address.
    fn search(&mut self) -> Step<Verdict> {
        let address = self.plan.address;
        if let Some(wildcard) = self.probes.wildcard {
            self.progress.phase(&format!("asking the wildcard address 0x{WILDCARD:02X}"), 1);
            let asked = self.ask(wildcard, WILDCARD, self.plan.sweep_wait * 2)?;
            if let Some(v) = self.after_wildcard(&asked)? {
                return Ok(v);
            }
        }
        let addresses: Vec<u8> = self.plan.scan_addresses().collect();
        self.progress.phase(&format!("scanning {} addresses at {}", addresses.len(), self.settings), addresses.len());
        let mut garbage = 0;
        for other in addresses {
            let asked = self.ask(self.probes.identify, other, self.plan.scan_wait)?;
            match asked.heard {
                Heard::Nothing => {}
                Heard::Garbage | Heard::OtherAddress(_) => {
                    garbage += 1;
                    if garbage <= GARBAGE_KEPT {
                        self.note_answer(&asked);
                    }
                }
                Heard::Reply(_) | Heard::Exception(_) | Heard::Damaged => {
                    self.note_answer(&asked);
                    self.answering = Some(Answering { settings: self.settings, address: other });
                    let health = self.health(other, vec![asked])?;
                    return Ok(health.unwrap_or_else(|| other_address(other, address)));
                }
            }
        }
        self.sweep(garbage > 0)
    }

    /// What a wildcard answer says: the probe's address, if it gives one.
    fn after_wildcard(&mut self, asked: &Asked<'c>) -> Step<Option<Verdict>> {
        let expected = self.plan.address;
        match &asked.heard {
            Heard::Nothing => Ok(None),
            Heard::Reply(data) => {
                let reported = decode_fields(asked.command, data).into_iter().find_map(|(_, v)| match v {
                    Value::Int(a) => u8::try_from(a).ok(),
                    _ => None,
                });
                let Some(reported) = reported else {
                    self.note(FindingKind::Wildcard, "a probe answered at the wildcard 0xFF without an address", asked);
                    return Ok(None);
                };
                self.note(
                    FindingKind::Wildcard,
                    format!("a probe answered at the wildcard 0xFF: its address is {reported} (0x{reported:02X})"),
                    asked,
                );
                self.answering = Some(Answering { settings: self.settings, address: reported });
                if (1..=247).contains(&reported) && reported != expected {
                    let there = self.ask(self.probes.identify, reported, self.plan.listen)?;
                    self.note_answer(&there);
                    if matches!(there.heard, Heard::Reply(_) | Heard::Exception(_) | Heard::Damaged) {
                        let health = self.health(reported, vec![there])?;
                        return Ok(Some(health.unwrap_or_else(|| other_address(reported, expected))));
                    }
                }
                Ok(Some(verdict(
                    VerdictCode::OnlyWildcard,
                    format!(
                        "the probe answers only at the wildcard 0xFF; it reports address {reported} (0x{reported:02X}){}",
                        if (1..=247).contains(&reported) {
                            ", where it does not answer"
                        } else {
                            ", outside 1 to 247, where no master can reach it"
                        }
                    ),
                    "alone on the bus, give it an address in 1..=247 with the vendor's tool or a set-slave-address \
                     write to 0xFF (`yosemitech encode` builds the frame), then run the doctor again",
                )))
            }
            _ => {
                self.note_answer(asked);
                self.note(
                    FindingKind::Wildcard,
                    "the wildcard 0xFF answer is unreadable: several probes may be answering it at once",
                    asked,
                );
                Ok(None)
            }
        }
    }

    /// The other serial settings, asking the address and the wildcard at each.
    fn sweep(&mut self, heard_garbage: bool) -> Step<Verdict> {
        let (address, sweep) = (self.plan.address, self.plan.sweep.clone());
        self.progress.phase(&format!("trying {} other serial settings", sweep.len()), 2 * sweep.len());
        let mut garbage = usize::from(heard_garbage);
        for settings in sweep {
            self.configure(settings)?;
            let mut asked = vec![self.ask(self.probes.identify, address, self.plan.sweep_wait)?];
            if let Some(wildcard) = self.probes.wildcard
                && asked.iter().all(|a| matches!(a.heard, Heard::Nothing | Heard::Garbage))
            {
                asked.push(self.ask(wildcard, WILDCARD, self.plan.sweep_wait)?);
            }
            for a in &asked {
                if matches!(a.heard, Heard::Garbage) {
                    garbage += 1;
                    if garbage <= GARBAGE_KEPT {
                        self.note_answer(a);
                    }
                }
            }
            let Some(found) =
                asked.into_iter().find(|a| matches!(a.heard, Heard::Reply(_) | Heard::Exception(_) | Heard::Damaged))
            else {
                continue;
            };
            let found_at = match (&found.heard, found.address) {
                (Heard::Reply(data), WILDCARD) => decode_fields(found.command, data)
                    .into_iter()
                    .find_map(|(_, v)| if let Value::Int(a) = v { u8::try_from(a).ok() } else { None })
                    .filter(|a| (1..=247).contains(a))
                    .unwrap_or(address),
                _ => address,
            };
            self.note(FindingKind::Settings, format!("the probe answers at {settings}"), &found);
            self.answering = Some(Answering { settings, address: found_at });
            let first = if found.address == WILDCARD { Vec::new() } else { vec![found] };
            let health = self.health(found_at, first)?;
            let at = if found_at == address { String::new() } else { format!(" and address {found_at}") };
            return Ok(verdict(
                VerdictCode::SerialSettings,
                format!("the probe answers at {settings}{at}, not at {}", self.plan.settings),
                format!(
                    "run the tools at {settings}: --baud {}{}{}; or set the probe back to its factory 9600 baud 8N1 with the vendor's tool{}",
                    settings.baud,
                    if settings.format == self.plan.settings.format {
                        String::new()
                    } else {
                        format!(", with the port at {} (the sensor's spec states the framing)", settings.format)
                    },
                    if found_at == address { String::new() } else { format!(", --address {found_at}") },
                    health.map(|h| format!("; then: {}", h.summary)).unwrap_or_default()
                ),
            ));
        }
        self.configure(self.plan.settings)?;
        Ok(if garbage > 0 {
            verdict(
                VerdictCode::Garbage,
                "bytes come back, but never a Modbus frame, at every serial setting tried",
                "a probe browning out answers garbage (check the supply under load: a brush start draws about \
                 290 mA), or the line is noisy (terminate both ends with 120 ohm, shorten the cable), or the \
                 probe runs at settings not tried (see skipped)",
            )
        } else {
            verdict(
                VerdictCode::Silent,
                "no byte came back at any address or serial setting tried",
                "check the probe's power and its wiring: A/B swapped is the most common fault (swap them and run \
                 again), then ground and the port (is --port the adapter the probe is on?)",
            )
        })
    }

    /// Sends each Start Measurement until one is answered; the verdict when it is refused.
    fn trigger(&mut self, address: u8, wait: Duration) -> Step<Option<Verdict>> {
        let mut last_silent = None;
        for start in self.probes.starts.clone() {
            let a = self.ask(start, address, wait)?;
            match a.heard {
                Heard::Exception(code) => {
                    let text = format!("{} (a trigger) is refused with {}", start.name, exception_text(code));
                    self.note(FindingKind::TriggerRefused, text.clone(), &a);
                    return Ok(Some(verdict(
                        VerdictCode::TriggerRefused,
                        format!("the probe answers reads, but {text}"),
                        "some probes measure from power-on and refuse the trigger: read the measurements without \
                         starting (the tools read on after a refused start); if readings stay stale, power-cycle it",
                    )));
                }
                Heard::Nothing => last_silent = Some(a),
                Heard::Reply(_) => return Ok(None),
                _ => {
                    self.note_answer(&a);
                    return Ok(None);
                }
            }
        }
        if let Some(a) = last_silent {
            let text = format!(
                "no answer to any of {} Start Measurement request(s): the probe may measure without one",
                self.probes.starts.len()
            );
            self.note(FindingKind::TriggerSilent, text, &a);
        }
        Ok(None)
    }

    /// Reads a probe that answers at `address` a few more times, then its
    /// trigger; the verdict for what went wrong, `None` when nothing did.
    fn health(&mut self, address: u8, mut asked: Vec<Asked<'c>>) -> Step<Option<Verdict>> {
        let reads: Vec<&'c CommandSpec> = std::iter::once(self.probes.identify).chain(self.probes.version).collect();
        self.progress.phase(&format!("checking address {address} at {}", self.settings), self.plan.repeats + 1);
        for i in 0..self.plan.repeats {
            let command = reads.get(i % reads.len()).copied().unwrap_or(self.probes.identify);
            let a = self.ask(command, address, self.plan.listen)?;
            asked.push(a);
        }
        let mut verdicts = Vec::new();
        // Two probes at one address: a read whose reply comes back damaged
        // the same way every time, never clean.
        for command in &reads {
            let mine: Vec<&Asked<'_>> = asked.iter().filter(|a| a.command.name == command.name).collect();
            let damaged: Vec<&&Asked<'_>> = mine.iter().filter(|a| a.heard == Heard::Damaged).collect();
            let clean = mine.iter().any(|a| matches!(a.heard, Heard::Reply(_)));
            let repeated = damaged
                .windows(2)
                .any(|w| w.first().map(|a| a.exchange.answer()) == w.get(1).map(|b| b.exchange.answer()));
            if let (false, true, Some(first)) = (clean, repeated, damaged.first()) {
                let text = format!(
                    "{} comes back damaged the same way {} times, never clean: two senders overlapping",
                    command.name,
                    damaged.len()
                );
                self.note(FindingKind::Collision, text, first);
                verdicts.push(verdict(
                    VerdictCode::Collision,
                    format!("more than one probe answers address {address}: {}'s replies collide", command.name),
                    format!(
                        "power off all but one probe, give each its own address, a few apart (yosemitech set-address \
                         --from {address} --to N with only that probe on the bus), and run the doctor on each"
                    ),
                ));
            }
        }
        let total = asked.len();
        let bad: Vec<&Asked<'_>> =
            asked.iter().filter(|a| matches!(a.heard, Heard::Damaged | Heard::Garbage | Heard::Nothing)).collect();
        let good = asked.iter().filter(|a| matches!(a.heard, Heard::Reply(_) | Heard::Exception(_))).count();
        // Damaged or lost replies that are no collision: noise, or a probe
        // browning out, whether or not any reply came through intact.
        if verdicts.is_empty()
            && let Some(first) = bad.iter().find(|a| a.heard != Heard::Nothing).or(bad.first())
        {
            let (damaged, lost) = (
                bad.iter().filter(|a| a.heard != Heard::Nothing).count(),
                bad.iter().filter(|a| a.heard == Heard::Nothing).count(),
            );
            let among = if good > 0 { format!("between {good} good ones") } else { "none intact".to_owned() };
            let text = format!("{damaged} of {total} replies damaged and {lost} lost, {among}");
            self.note(FindingKind::Noise, text.clone(), first);
            verdicts.push(verdict(
                VerdictCode::Noise,
                format!("the line damages replies: {text}"),
                "terminate the bus with 120 ohm at both ends, use twisted pair, shorten it or keep it away from \
                 power cables; meanwhile the tools retry (--retries)",
            ));
        }
        if let Some(slow) = asked
            .iter()
            .filter(|a| matches!(a.heard, Heard::Reply(_) | Heard::Exception(_)))
            .filter_map(|a| a.exchange.turnaround().map(|t| (t, a)))
            .max_by_key(|(t, _)| *t)
            .filter(|(t, _)| *t > self.plan.timeout)
        {
            let (t, a) = slow;
            let text = format!(
                "the probe answered after {}, later than the {} the tools wait",
                show_duration(t),
                show_duration(self.plan.timeout)
            );
            self.note(FindingKind::SlowTurnaround, text.clone(), a);
            verdicts.push(verdict(
                VerdictCode::SlowTurnaround,
                text,
                format!("give the tools more time: --timeout {}", show_duration(generous(t))),
            ));
        }
        if let Some((refused, code)) =
            asked.iter().find_map(|a| if let Heard::Exception(code) = a.heard { Some((a, code)) } else { None })
        {
            let text = format!("{} is refused with {}", refused.command.name, exception_text(code));
            self.note(FindingKind::Exception, text.clone(), refused);
            verdicts.push(verdict(
                VerdictCode::Exception,
                format!("the probe answers, but refuses reads: {text}"),
                "06 (busy) passes once the probe has warmed up: wait and retry; 01/02 mean it lacks the register: \
                 name its sensor with --sensor (`yosemitech scan` identifies it)",
            ));
        }
        // The trigger waits the tools' timeout, longer for a slow probe.
        let slowest = asked.iter().filter_map(|a| a.exchange.turnaround()).max().unwrap_or_default();
        if let Some(refused) = self.trigger(address, (slowest * 2).max(self.plan.timeout))? {
            verdicts.push(refused);
        }
        // The most telling first: collisions and noise explain the rest.
        Ok(verdicts.into_iter().next())
    }
}

fn other_address(found: u8, expected: u8) -> Verdict {
    verdict(
        VerdictCode::OtherAddress,
        format!("the probe answers at address {found} (0x{found:02X}), not {expected}"),
        format!(
            "use --address {found}, or move it: yosemitech set-address --from {found} --to {expected} (with it alone on the bus)"
        ),
    )
}

fn healthy(address: u8, settings: LineSettings) -> Verdict {
    verdict(
        VerdictCode::Healthy,
        format!("the probe answers at address {address}, {settings}, every read intact"),
        "nothing to fix on the line; if readings look wrong, check the probe's warm-up and calibration",
    )
}

#[cfg(test)]
mod tests {
    use super::super::{Quiet, hex};
    use super::*;
    use crate::catalog::Catalog;
    use std::collections::VecDeque;
    use std::sync::Arc;
    use yosemitech_sim::{FrameHandler, Simulator};

    /// A simulated probe straight on the line, no pty: what it answers is
    /// there to read at once.
    struct OnTheLine {
        device: Simulator,
        pending: VecDeque<u8>,
    }

    impl Line for OnTheLine {
        fn configure(&mut self, _: LineSettings) -> io::Result<()> {
            Ok(())
        }
        fn write_all(&mut self, frame: &[u8]) -> io::Result<()> {
            let mut reply = Vec::new();
            self.device.handle(frame, &mut reply);
            self.pending.extend(reply);
            Ok(())
        }
        fn read(&mut self, buf: &mut [u8], timeout: Duration) -> io::Result<usize> {
            if self.pending.is_empty() {
                std::thread::sleep(timeout.min(Duration::from_millis(2)));
            }
            let n = buf.len().min(self.pending.len());
            for (slot, b) in buf.iter_mut().zip(self.pending.drain(..n)) {
                *slot = b;
            }
            Ok(n)
        }
        fn discard_input(&mut self) -> io::Result<()> {
            self.pending.clear();
            Ok(())
        }
    }

    #[test]
    fn every_sensor_of_the_spec_is_found_healthy_or_at_its_address() {
        let catalog = Catalog::load(&[]).unwrap();
        let mut checked = 0;
        for entry in catalog.entries() {
            let sensor = entry.sensor.as_ref();
            let Some(probes) = Probes::of(&[sensor]) else { continue };
            let mut plan =
                Plan::new(sensor.default_address, sensor.serial, Duration::from_secs(1), probes.starts.len());
            // Nothing here is slow: short waits keep the silent steps short.
            (plan.listen, plan.scan_wait, plan.sweep_wait) =
                (Duration::from_millis(80), Duration::from_millis(5), Duration::from_millis(5));
            let run = |address: u8| {
                let device = Simulator::new(Arc::clone(&entry.sensor)).with_address(address);
                let mut line = OnTheLine { device, pending: VecDeque::new() };
                diagnose(&mut line, &probes, &plan, &mut Quiet, &AtomicBool::new(false)).unwrap()
            };
            let report = run(sensor.default_address);
            assert_eq!(report.verdict.code, VerdictCode::Healthy, "{}: {:?}", sensor.name, report.verdict);
            assert_eq!(report.answering.map(|a| a.address), Some(sensor.default_address));
            let elsewhere = if sensor.default_address == 7 { 9 } else { 7 };
            let report = run(elsewhere);
            assert_eq!(report.verdict.code, VerdictCode::OtherAddress, "{}: {:?}", sensor.name, report.verdict);
            assert_eq!(report.answering.map(|a| a.address), Some(elsewhere), "{}", sensor.name);
            assert!(report.requests <= plan.max_requests());
            checked += 1;
        }
        assert!(checked > 0);
    }

    #[test]
    fn a_generous_timeout_is_half_again_rounded_up() {
        assert_eq!(generous(Duration::from_millis(1500)), Duration::from_millis(2300));
        assert_eq!(generous(Duration::from_millis(1000)), Duration::from_millis(1500));
        assert_eq!(generous(Duration::from_millis(1)), Duration::from_millis(100));
    }

    #[test]
    fn hex_is_spaced_upper_case() {
        assert_eq!(hex(&[0x01, 0xAB]), "01 AB");
    }
}
