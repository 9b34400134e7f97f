//! [`MonotonicClock`]: the blocking driver's clock, as core [`Instant`]s.

use super::Instant;

/// The OS's monotonic clock (the one `std::time::Instant` reads), in
/// microseconds since the clock was made. Never goes backwards.
///
/// On Unix it reads `clock_gettime(CLOCK_MONOTONIC)` and keeps whole
/// microseconds: one multiply-add a read, where `std::time::Instant::elapsed`
/// subtracts and normalises two `timespec`s into a `Duration` that the core
/// would then convert back. The driver reads it twice a transaction.
#[derive(Debug, Clone, Copy)]
pub(crate) struct MonotonicClock {
    #[cfg(unix)]
    origin_micros: u64,
    #[cfg(not(unix))]
    origin: std::time::Instant,
}

impl MonotonicClock {
    /// A clock whose epoch is now.
    pub(crate) fn start() -> Self {
        #[cfg(unix)]
        return Self { origin_micros: raw_micros() };
        #[cfg(not(unix))]
        return Self { origin: std::time::Instant::now() };
    }

    /// The time since [`MonotonicClock::start`].
    #[inline]
    pub(crate) fn now(&self) -> Instant {
        #[cfg(unix)]
        return Instant::from_micros(raw_micros().saturating_sub(self.origin_micros));
        #[cfg(not(unix))]
        return Instant::from_elapsed(self.origin.elapsed());
    }
}

/// `CLOCK_MONOTONIC` in whole microseconds (a `timespec` holds seconds below
/// 2^63 and nanoseconds below 10^9, so this neither overflows for 292,000
/// years nor goes backwards).
#[cfg(unix)]
#[inline]
fn raw_micros() -> u64 {
    let now = rustix::time::clock_gettime(rustix::time::ClockId::Monotonic);
    let seconds = u64::try_from(now.tv_sec).unwrap_or(0);
    let nanos = u64::try_from(now.tv_nsec).unwrap_or(0);
    seconds.saturating_mul(1_000_000).saturating_add(nanos / 1_000)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::time::Duration;

    #[test]
    fn the_clock_follows_std_and_never_goes_back() {
        // std's clock starts first and is read last, so it measures longer.
        let std_start = std::time::Instant::now();
        let clock = MonotonicClock::start();
        let first = clock.now();
        std::thread::sleep(Duration::from_millis(20));
        let second = clock.now();
        let std_elapsed = std_start.elapsed();
        assert!(second > first, "{first:?} then {second:?}");
        let measured = second.saturating_duration_since(Instant::ZERO);
        // The clocks are one; whole microseconds lose less than one at each end.
        assert!(measured >= Duration::from_millis(20), "{measured:?}");
        assert!(measured <= std_elapsed + Duration::from_micros(2), "{measured:?} against std's {std_elapsed:?}");
    }
}
