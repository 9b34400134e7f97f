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
// Out of line without `std`: a firmware's flash keeps one copy of its
// 64-bit arithmetic, not one per deadline; a host inlines it for speed.
#[cfg_attr(not(feature = "std"), inline(never))]
pub(crate) const fn micros_ceil(duration: Duration) -> u64 {
    let sub_micros = duration.subsec_nanos().div_ceil(1000) as u64;
    duration.as_secs().saturating_mul(1_000_000).saturating_add(sub_micros)
}

/// `micros` microseconds, at most `u32::MAX` (about 71 minutes: a longer
/// wait ends early and is asked for again), without the 64-bit division
/// of `Duration::from_micros` (a library routine on a 32-bit MCU).
pub(crate) const fn duration_from_micros_clamped(micros: u64) -> Duration {
    let micros = if micros > u32::MAX as u64 { u32::MAX } else { micros as u32 };
    Duration::new((micros / 1_000_000) as u64, (micros % 1_000_000) * 1000)
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

    #[test]
    fn durations_from_microseconds_are_exact_up_to_the_clamp() {
        for micros in [0, 1, 999_999, 1_000_000, 1_000_001, 4_000_000_123, u64::from(u32::MAX)] {
            assert_eq!(duration_from_micros_clamped(micros), Duration::from_micros(micros));
        }
        let clamp = Duration::from_micros(u64::from(u32::MAX));
        assert_eq!(duration_from_micros_clamped(u64::from(u32::MAX) + 1), clamp);
        assert_eq!(duration_from_micros_clamped(u64::MAX), clamp);
    }
}
