//! [`Instant`]: the core's clock, microseconds on the driver's monotonic clock.

use core::fmt;
use core::time::Duration;

/// A point in time, in microseconds since an epoch the driver chooses (its
/// start, the MCU's boot), on a clock that never goes backwards.
///
/// The [`ClientCore`](super::ClientCore) never reads a clock: drivers pass
/// it `Instant`s. Adding a [`Duration`] rounds it up to the next microsecond
/// and saturates, so a silence or a deadline is never shortened by rounding
/// and never wraps.
#[derive(Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Default)]
pub struct Instant {
    micros: u64,
}

impl Instant {
    /// The epoch.
    pub const ZERO: Self = Self { micros: 0 };

    /// The instant `micros` microseconds after the epoch.
    pub const fn from_micros(micros: u64) -> Self {
        Self { micros }
    }

    /// The instant `elapsed` after the epoch (saturating, rounded up).
    pub const fn from_elapsed(elapsed: Duration) -> Self {
        Self::ZERO.saturating_add(elapsed)
    }

    /// Microseconds since the epoch.
    pub const fn as_micros(self) -> u64 {
        self.micros
    }

    /// `self + duration`, rounded up to the microsecond, saturating at the end of time.
    pub const fn saturating_add(self, duration: Duration) -> Self {
        self.add_micros(micros_ceil(duration))
    }

    /// `self` plus `micros` microseconds, saturating at the end of time.
    pub(crate) const fn add_micros(self, micros: u64) -> Self {
        Self { micros: self.micros.saturating_add(micros) }
    }

    /// The time from `earlier` to `self`, zero when `earlier` is later.
    pub const fn saturating_duration_since(self, earlier: Self) -> Duration {
        Duration::from_micros(self.micros.saturating_sub(earlier.micros))
    }
}

/// `duration` in whole microseconds, rounded up and saturating, without
/// 128-bit arithmetic: what a silence or a deadline adds to an [`Instant`].
pub(crate) const fn micros_ceil(duration: Duration) -> u64 {
    let sub_micros = duration.subsec_nanos().div_ceil(1000) as u64;
    duration.as_secs().saturating_mul(1_000_000).saturating_add(sub_micros)
}

impl core::ops::Add<Duration> for Instant {
    type Output = Self;
    /// [`Instant::saturating_add`].
    fn add(self, duration: Duration) -> Self {
        self.saturating_add(duration)
    }
}

impl fmt::Debug for Instant {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}.{:06}s", self.micros / 1_000_000, self.micros % 1_000_000)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn adding_rounds_up_and_saturates() {
        let t = Instant::from_micros(10);
        assert_eq!(t + Duration::from_nanos(1), Instant::from_micros(11));
        assert_eq!(t + Duration::from_micros(5), Instant::from_micros(15));
        assert_eq!(t + Duration::MAX, Instant::from_micros(u64::MAX));
        assert_eq!(Instant::from_micros(u64::MAX) + Duration::from_secs(1), Instant::from_micros(u64::MAX));
        assert_eq!(t.saturating_duration_since(Instant::from_micros(20)), Duration::ZERO);
        assert_eq!(Instant::from_micros(20).saturating_duration_since(t), Duration::from_micros(10));
        assert_eq!(format!("{:?}", Instant::from_micros(1_000_042)), "1.000042s");
    }
}
