//! Deterministic fault injection: what can go wrong with a reply, when, and how often it did.

use std::collections::VecDeque;
use std::fmt;
use std::time::Duration;

use yosemitech_rtu::crc16;

/// A small deterministic PRNG (SplitMix64): the same seed gives the same
/// faults, noise and test data on every platform. Not for cryptography.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Rng {
    state: u64,
}

impl Rng {
    /// A generator seeded with `seed`.
    pub const fn new(seed: u64) -> Self {
        Self { state: seed }
    }

    /// The next 64 random bits.
    pub fn next_u64(&mut self) -> u64 {
        self.state = self.state.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.state;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// A uniform number in `[0, 1)`.
    pub fn next_f64(&mut self) -> f64 {
        // 53 random bits: exactly representable.
        (self.next_u64() >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
    }

    /// A uniform number in `[-1, 1)`.
    pub fn next_signed(&mut self) -> f64 {
        2.0 * self.next_f64() - 1.0
    }

    /// A number in `0..n` (0 when `n` is 0). Slightly biased for huge `n`; fine for tests.
    pub fn below(&mut self, n: u64) -> u64 {
        if n == 0 { 0 } else { self.next_u64() % n }
    }

    /// A pseudo-random byte, deterministic from the seed.
    pub fn byte(&mut self) -> u8 {
        (self.next_u64() >> 56) as u8
    }

    /// True with probability `p`.
    pub fn chance(&mut self, p: f64) -> bool {
        self.next_f64() < p
    }
}

/// One kind of injected reply fault.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum FaultKind {
    /// No reply at all (the request was processed; the reply was lost).
    Drop,
    /// The reply with its CRC bytes flipped.
    CorruptCrc,
    /// The reply cut short: 1 to `len - 1` of its bytes.
    Truncate,
    /// 1 to 4 bytes of line noise before the reply. The noise never holds a
    /// byte that could be read as a function or exception code (0x03, 0x10,
    /// 0x83, 0x90), so a master that skips noise, as the rtu client does,
    /// still finds the frame.
    Garbage,
    /// The reply from another slave address (CRC recomputed, so only the
    /// address check can catch it).
    WrongSlave,
    /// The reply held back by [`FaultConfig::delay_by`] (threaded serving
    /// sleeps; in-process the reply is withheld, since it cannot arrive
    /// late: see [`crate::FrameHandler`]).
    Delay,
    /// Exception 0x06 (server device busy) instead of processing the request.
    Busy,
}

impl FaultKind {
    /// Every kind, in declaration order.
    pub const ALL: [FaultKind; 7] = [
        FaultKind::Drop,
        FaultKind::CorruptCrc,
        FaultKind::Truncate,
        FaultKind::Garbage,
        FaultKind::WrongSlave,
        FaultKind::Delay,
        FaultKind::Busy,
    ];

    /// A short snake_case name.
    pub const fn name(self) -> &'static str {
        match self {
            FaultKind::Drop => "drop",
            FaultKind::CorruptCrc => "corrupt_crc",
            FaultKind::Truncate => "truncate",
            FaultKind::Garbage => "garbage",
            FaultKind::WrongSlave => "wrong_slave",
            FaultKind::Delay => "delay",
            FaultKind::Busy => "busy",
        }
    }

    const fn index(self) -> usize {
        self as usize
    }
}

impl fmt::Display for FaultKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// Which faults to inject into replies, and how often.
///
/// Each reply the device would send draws at most one fault: first from
/// [`FaultConfig::script`] while it lasts, then at random with the
/// per-kind probabilities (their sum is capped at 1). Requests the device
/// ignores (other slaves, bad CRC, broadcasts) draw nothing. Build with
/// struct update syntax:
///
/// ```
/// use yosemitech_sim::{FaultConfig, FaultKind};
/// let config = FaultConfig { corrupt_crc: 0.05, drop: 0.05, ..FaultConfig::seeded(7) };
/// assert_eq!(config.probability(FaultKind::Drop), 0.05);
/// let scripted = FaultConfig::scripted([Some(FaultKind::Busy), None, Some(FaultKind::Drop)]);
/// assert_eq!(scripted.script.len(), 3);
/// ```
#[derive(Debug, Clone, PartialEq)]
pub struct FaultConfig {
    /// Seed of the generator that draws faults and their details.
    pub seed: u64,
    /// Probability of [`FaultKind::Drop`] per reply.
    pub drop: f64,
    /// Probability of [`FaultKind::CorruptCrc`] per reply.
    pub corrupt_crc: f64,
    /// Probability of [`FaultKind::Truncate`] per reply.
    pub truncate: f64,
    /// Probability of [`FaultKind::Garbage`] per reply.
    pub garbage: f64,
    /// Probability of [`FaultKind::WrongSlave`] per reply.
    pub wrong_slave: f64,
    /// Probability of [`FaultKind::Delay`] per reply.
    pub delay: f64,
    /// Probability of [`FaultKind::Busy`] per reply.
    pub busy: f64,
    /// Faults for the next replies, in order (`None`: that reply is clean).
    /// Consumed before any random draw.
    pub script: VecDeque<Option<FaultKind>>,
    /// How long a [`FaultKind::Delay`] holds the reply back. Default 1 s.
    pub delay_by: Duration,
}

impl FaultConfig {
    /// No faults, with `seed` for any probabilities set later.
    pub fn seeded(seed: u64) -> Self {
        Self {
            seed,
            drop: 0.0,
            corrupt_crc: 0.0,
            truncate: 0.0,
            garbage: 0.0,
            wrong_slave: 0.0,
            delay: 0.0,
            busy: 0.0,
            script: VecDeque::new(),
            delay_by: Duration::from_secs(1),
        }
    }

    /// No faults at all: every reply is sent intact.
    pub fn none() -> Self {
        Self::seeded(0)
    }

    /// Every kind with the same probability, `total` in all.
    pub fn uniform(seed: u64, total: f64) -> Self {
        let mut config = Self::seeded(seed);
        let each = total / FaultKind::ALL.len() as f64;
        for kind in FaultKind::ALL {
            *config.probability_mut(kind) = each;
        }
        config
    }

    /// The faults `script` for the next replies, then none.
    pub fn scripted(script: impl IntoIterator<Item = Option<FaultKind>>) -> Self {
        Self { script: script.into_iter().collect(), ..Self::none() }
    }

    /// The probability of `kind` per reply.
    pub fn probability(&self, kind: FaultKind) -> f64 {
        match kind {
            FaultKind::Drop => self.drop,
            FaultKind::CorruptCrc => self.corrupt_crc,
            FaultKind::Truncate => self.truncate,
            FaultKind::Garbage => self.garbage,
            FaultKind::WrongSlave => self.wrong_slave,
            FaultKind::Delay => self.delay,
            FaultKind::Busy => self.busy,
        }
    }

    /// The probability of `kind` per reply, to set.
    pub fn probability_mut(&mut self, kind: FaultKind) -> &mut f64 {
        match kind {
            FaultKind::Drop => &mut self.drop,
            FaultKind::CorruptCrc => &mut self.corrupt_crc,
            FaultKind::Truncate => &mut self.truncate,
            FaultKind::Garbage => &mut self.garbage,
            FaultKind::WrongSlave => &mut self.wrong_slave,
            FaultKind::Delay => &mut self.delay,
            FaultKind::Busy => &mut self.busy,
        }
    }
}

impl Default for FaultConfig {
    /// No faults: every reply is sent intact.
    fn default() -> Self {
        Self::none()
    }
}

/// How many faults of each kind were injected, and into how many replies.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct FaultCounts {
    counts: [u64; FaultKind::ALL.len()],
    replies: u64,
}

impl FaultCounts {
    /// Faults of `kind` injected.
    pub fn get(&self, kind: FaultKind) -> u64 {
        self.counts.get(kind.index()).copied().unwrap_or(0)
    }

    /// Faults of every kind injected.
    pub fn total(&self) -> u64 {
        self.counts.iter().sum()
    }

    /// Replies that drew a fault or not (every reply the device would have sent).
    pub fn replies(&self) -> u64 {
        self.replies
    }

    /// Counts by kind, kinds with none included.
    pub fn iter(&self) -> impl Iterator<Item = (FaultKind, u64)> + '_ {
        FaultKind::ALL.into_iter().map(|k| (k, self.get(k)))
    }

    fn record(&mut self, kind: FaultKind) {
        if let Some(c) = self.counts.get_mut(kind.index()) {
            *c += 1;
        }
    }
}

impl fmt::Display for FaultCounts {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{} faults in {} replies (", self.total(), self.replies)?;
        for (i, (kind, n)) in self.iter().enumerate() {
            if i > 0 {
                f.write_str(", ")?;
            }
            write!(f, "{kind} {n}")?;
        }
        f.write_str(")")
    }
}

/// Draws and applies faults.
#[derive(Debug, Clone)]
pub(crate) struct Injector {
    config: FaultConfig,
    rng: Rng,
    counts: FaultCounts,
}

/// Function and exception codes garbage never contains (see [`FaultKind::Garbage`]).
const NOT_GARBAGE: [u8; 4] = [0x03, 0x10, 0x83, 0x90];

impl Injector {
    pub(crate) fn new(config: FaultConfig) -> Self {
        Self { rng: Rng::new(config.seed), config, counts: FaultCounts::default() }
    }

    /// A new configuration and generator; the counts go on.
    pub(crate) fn reconfigure(&mut self, config: FaultConfig) {
        self.rng = Rng::new(config.seed);
        self.config = config;
    }

    pub(crate) fn config(&self) -> &FaultConfig {
        &self.config
    }

    pub(crate) fn counts(&self) -> &FaultCounts {
        &self.counts
    }

    pub(crate) fn reset_counts(&mut self) {
        self.counts = FaultCounts::default();
    }

    /// The fault for the next reply, counted.
    pub(crate) fn draw(&mut self) -> Option<FaultKind> {
        self.counts.replies += 1;
        let fault = match self.config.script.pop_front() {
            Some(scripted) => scripted,
            None => {
                let mut u = self.rng.next_f64();
                let mut chosen = None;
                for kind in FaultKind::ALL {
                    let p = self.config.probability(kind).max(0.0);
                    if u < p {
                        chosen = Some(kind);
                        break;
                    }
                    u -= p;
                }
                chosen
            }
        };
        if let Some(kind) = fault {
            self.counts.record(kind);
        }
        fault
    }

    /// Applies `fault` (not [`FaultKind::Busy`], handled before processing)
    /// to `reply`; returns how long to hold it back.
    pub(crate) fn apply(&mut self, fault: FaultKind, reply: &mut Vec<u8>) -> Duration {
        let len = reply.len();
        match fault {
            FaultKind::Drop => reply.clear(),
            FaultKind::CorruptCrc => {
                // A non-zero mask on the CRC bytes: the CRC can no longer match.
                let mask = (self.rng.below(0xFFFF) + 1) as u16;
                let [lo, hi] = mask.to_le_bytes();
                if let Some(b) = reply.get_mut(len.wrapping_sub(2)) {
                    *b ^= lo;
                }
                if let Some(b) = reply.last_mut() {
                    *b ^= hi;
                }
            }
            FaultKind::Truncate => {
                let keep = 1 + self.rng.below(len.saturating_sub(1) as u64) as usize;
                reply.truncate(keep.min(len.saturating_sub(1)));
            }
            FaultKind::Garbage => {
                let n = 1 + self.rng.below(4) as usize;
                let mut noise = Vec::with_capacity(n);
                while noise.len() < n {
                    let b = self.rng.byte();
                    if !NOT_GARBAGE.contains(&b) {
                        noise.push(b);
                    }
                }
                reply.splice(0..0, noise);
            }
            FaultKind::WrongSlave => {
                if let Some(slave) = reply.first_mut() {
                    *slave = if *slave >= 247 { 1 } else { *slave + 1 };
                }
                if len >= 4 {
                    reply.truncate(len - 2);
                    let crc = crc16(reply);
                    reply.extend_from_slice(&crc.to_le_bytes());
                }
            }
            FaultKind::Delay => return self.config.delay_by,
            FaultKind::Busy => {}
        }
        Duration::ZERO
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use yosemitech_rtu::crc_ok;

    const REPLY: [u8; 9] = [0x01, 0x03, 0x04, 0x33, 0x33, 0xF3, 0x40, 0x40, 0x78];

    #[test]
    fn rng_is_deterministic_and_uniformish() {
        let (mut a, mut b) = (Rng::new(1), Rng::new(1));
        assert_eq!(a.next_u64(), b.next_u64());
        let mut r = Rng::new(42);
        let mean: f64 = (0..10_000).map(|_| r.next_f64()).sum::<f64>() / 10_000.0;
        assert!((mean - 0.5).abs() < 0.02, "{mean}");
        assert!((0..1000).all(|_| r.below(7) < 7));
    }

    #[test]
    fn script_then_probabilities() {
        let mut inj = Injector::new(FaultConfig { busy: 1.0, ..FaultConfig::scripted([None, Some(FaultKind::Drop)]) });
        assert_eq!(inj.draw(), None);
        assert_eq!(inj.draw(), Some(FaultKind::Drop));
        assert_eq!(inj.draw(), Some(FaultKind::Busy));
        assert_eq!(inj.counts().get(FaultKind::Busy), 1);
        assert_eq!(inj.counts().total(), 2);
        assert_eq!(inj.counts().replies(), 3);
    }

    #[test]
    fn uniform_rate_is_close() {
        let mut inj = Injector::new(FaultConfig::uniform(3, 0.1));
        for _ in 0..70_000 {
            inj.draw();
        }
        for (kind, n) in inj.counts().iter() {
            assert!((800..1200).contains(&n), "{kind}: {n}");
        }
    }

    #[test]
    fn faults_change_the_reply_as_documented() {
        let mut inj = Injector::new(FaultConfig::seeded(9));
        for _ in 0..50 {
            let mut r = REPLY.to_vec();
            inj.apply(FaultKind::CorruptCrc, &mut r);
            assert!(!crc_ok(&r) && r[..7] == REPLY[..7]);
            let mut r = REPLY.to_vec();
            inj.apply(FaultKind::Truncate, &mut r);
            assert!(!r.is_empty() && r.len() < REPLY.len() && REPLY.starts_with(&r));
            let mut r = REPLY.to_vec();
            inj.apply(FaultKind::Garbage, &mut r);
            assert!(r.ends_with(&REPLY) && (1..=4).contains(&(r.len() - REPLY.len())));
            assert!(r[..r.len() - REPLY.len()].iter().all(|b| !NOT_GARBAGE.contains(b)));
            let mut r = REPLY.to_vec();
            inj.apply(FaultKind::WrongSlave, &mut r);
            assert!(crc_ok(&r) && r[0] == 2);
        }
        let mut r = REPLY.to_vec();
        assert_eq!(inj.apply(FaultKind::Drop, &mut r), Duration::ZERO);
        assert!(r.is_empty());
        let mut r = REPLY.to_vec();
        assert_eq!(inj.apply(FaultKind::Delay, &mut r), Duration::from_secs(1));
        assert_eq!(r, REPLY);
    }
}
