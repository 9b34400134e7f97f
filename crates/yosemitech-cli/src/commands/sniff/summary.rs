//! What `sniff` prints when it stops: per slave, the requests it heard,
//! the replies, what went wrong, and how long replies took.

use std::collections::BTreeMap;
use std::time::Duration;

use serde_json::{Value as Json, json};
use yosemitech_rtu::crc_ok;

use crate::explain::sniff::{Flag, Heard, Identity, millis};
use crate::explain::{Report, Status};
use yosemitech_ops::printable;

/// Counts of what was heard.
#[derive(Default)]
pub(super) struct Summary {
    entries: usize,
    noise_runs: usize,
    noise_bytes: usize,
    slaves: BTreeMap<u8, Slave>,
}

/// What one slave address was asked and answered.
#[derive(Default)]
struct Slave {
    requests: usize,
    replies: usize,
    no_reply: usize,
    crc_errors: usize,
    exceptions: usize,
    unpaired: usize,
    late: usize,
    gaps: usize,
    latencies: Vec<Duration>,
}

impl Summary {
    /// Counts `h`.
    pub(super) fn add(&mut self, h: &Heard<'_>) {
        self.entries += 1;
        let x = match &h.report {
            Report::Exchange(x) => x,
            Report::Noise(f) => {
                self.noise_runs += 1;
                self.noise_bytes += f.bytes.len();
                return;
            }
            Report::Unreadable { .. } => return,
        };
        let slave = self.slaves.entry(x.slave().unwrap_or(0)).or_default();
        slave.requests += usize::from(x.request.is_some());
        if let Some(reply) = &x.reply {
            slave.replies += 1;
            slave.crc_errors += usize::from(!(reply.bytes.len() >= 4 && crc_ok(&reply.bytes)));
        }
        slave.no_reply += usize::from(x.status == Status::NoReply);
        slave.exceptions += usize::from(x.exception.is_some());
        slave.unpaired += usize::from(x.status == Status::Unpaired);
        for flag in &h.flags {
            match flag {
                Flag::LateReply(_) => slave.late += 1,
                Flag::GapInRequest(_) | Flag::GapInReply(_) => slave.gaps += 1,
            }
        }
        slave.latencies.extend(h.latency);
    }

    /// The summary as text lines.
    pub(super) fn lines(&self, identified: &[Identity<'_>]) -> Vec<String> {
        let mut lines = vec![format!(
            "summary: {} entr{} heard, {} byte(s) of noise in {} run(s)",
            self.entries,
            if self.entries == 1 { "y" } else { "ies" },
            self.noise_bytes,
            self.noise_runs
        )];
        for (address, s) in &self.slaves {
            let sensor = identity_of(identified, *address).map_or(String::new(), identity_text);
            let mut line = format!(
                "  address {address}{sensor}: {} request(s), {} repl(ies), {} without reply, {} CRC error(s), \
                 {} exception(s), {} late, {} with a silence inside, {} unpaired",
                s.requests, s.replies, s.no_reply, s.crc_errors, s.exceptions, s.late, s.gaps, s.unpaired
            );
            if let Some([p50, p90, max]) = percentiles(&s.latencies) {
                line += &format!(
                    "; replies after {} (median), {} (90 %), {} (longest)",
                    millis(p50),
                    millis(p90),
                    millis(max)
                );
            }
            lines.push(line);
        }
        lines
    }

    /// The summary as the last JSON line.
    pub(super) fn json(&self, identified: &[Identity<'_>]) -> Json {
        let ms = |d: Duration| (d.as_secs_f64() * 1e6).round() / 1e3;
        let slaves: Vec<Json> = self
            .slaves
            .iter()
            .map(|(address, s)| {
                let identity = identity_of(identified, *address);
                json!({
                    "slave": address,
                    "sensor": identity.and_then(|i| i.sensor),
                    "serial_number": identity.and_then(|i| i.serial_number.as_deref()),
                    "model_code": identity.and_then(|i| i.model_code.as_deref()),
                    "requests": s.requests,
                    "replies": s.replies,
                    "no_reply": s.no_reply,
                    "crc_errors": s.crc_errors,
                    "exceptions": s.exceptions,
                    "late": s.late,
                    "gaps": s.gaps,
                    "unpaired": s.unpaired,
                    "latency_ms": percentiles(&s.latencies)
                        .map(|[p50, p90, max]| json!({ "p50": ms(p50), "p90": ms(p90), "max": ms(max) })),
                })
            })
            .collect();
        json!({
            "type": "summary",
            "entries": self.entries,
            "noise_runs": self.noise_runs,
            "noise_bytes": self.noise_bytes,
            "slaves": slaves,
        })
    }
}

fn identity_of<'i, 'c>(identified: &'i [Identity<'c>], address: u8) -> Option<&'i Identity<'c>> {
    identified.iter().find(|i| i.slave == address)
}

/// ` (ph_orp, SN YL4314010022, model code 43)`; empty when nothing is known.
fn identity_text(identity: &Identity<'_>) -> String {
    let parts: Vec<String> = identity
        .sensor
        .map(str::to_owned)
        .into_iter()
        .chain(identity.serial_number.as_deref().map(|sn| format!("SN {}", printable(sn))))
        .chain(identity.model_code.as_deref().map(|code| format!("model code {code}")))
        .collect();
    if parts.is_empty() { String::new() } else { format!(" ({})", parts.join(", ")) }
}

/// The median, the 90th percentile (nearest rank) and the longest; `None` for none.
fn percentiles(latencies: &[Duration]) -> Option<[Duration; 3]> {
    let mut sorted = latencies.to_vec();
    sorted.sort_unstable();
    let rank = |p: f64| {
        #[allow(clippy::cast_possible_truncation, clippy::cast_sign_loss, clippy::cast_precision_loss)]
        let rank = (p * sorted.len() as f64).ceil() as usize;
        sorted.get(rank.saturating_sub(1)).copied()
    };
    Some([rank(0.5)?, rank(0.9)?, sorted.last().copied()?])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn percentiles_are_nearest_ranks() {
        let ms = Duration::from_millis;
        assert_eq!(percentiles(&[]), None);
        assert_eq!(percentiles(&[ms(7)]), Some([ms(7), ms(7), ms(7)]));
        let ten: Vec<Duration> = (1..=10).rev().map(ms).collect();
        assert_eq!(percentiles(&ten), Some([ms(5), ms(9), ms(10)]));
    }
}
