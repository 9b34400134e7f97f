//! UTC instants as the store keeps them (milliseconds since the Unix epoch)
//! and as people write them (RFC 3339), without a date-time dependency.

use std::time::{Duration, SystemTime, UNIX_EPOCH};

/// Milliseconds since 1970-01-01T00:00:00Z; instants before the epoch are 0.
pub fn unix_ms(t: SystemTime) -> i64 {
    t.duration_since(UNIX_EPOCH).map_or(0, |d| i64::try_from(d.as_millis()).unwrap_or(i64::MAX))
}

/// The instant `ms` milliseconds after the epoch (negative: the epoch).
pub fn from_unix_ms(ms: i64) -> SystemTime {
    UNIX_EPOCH + Duration::from_millis(u64::try_from(ms).unwrap_or(0))
}

/// Civil date (year, month, day) of a day count since 1970-01-01
/// (Howard Hinnant's `civil_from_days`).
pub fn civil_from_days(days: i64) -> (i64, u32, u32) {
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z.rem_euclid(146_097);
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let day = (doy - (153 * mp + 2) / 5 + 1) as u32;
    let month = if mp < 10 { mp + 3 } else { mp - 9 } as u32;
    let year = yoe + era * 400 + i64::from(month <= 2);
    (year, month, day)
}

/// Days since 1970-01-01 of a civil date (Howard Hinnant's `days_from_civil`).
fn days_from_civil(year: i64, month: u32, day: u32) -> i64 {
    let y = year - i64::from(month <= 2);
    let era = y.div_euclid(400);
    let yoe = y.rem_euclid(400);
    let m = i64::from(month);
    let doy = (153 * (if m > 2 { m - 3 } else { m + 9 }) + 2) / 5 + i64::from(day) - 1;
    let doe = yoe * 365 + yoe / 4 - yoe / 100 + doy;
    era * 146_097 + doe - 719_468
}

/// RFC 3339 UTC with milliseconds, fixed width: `2025-11-23T18:04:05.123Z`.
pub fn rfc3339(t: SystemTime) -> String {
    let since = t.duration_since(UNIX_EPOCH).unwrap_or(Duration::ZERO);
    let secs = since.as_secs();
    let (y, mo, d) = civil_from_days((secs / 86_400) as i64);
    let rem = secs % 86_400;
    let (h, mi, s) = (rem / 3600, rem % 3600 / 60, rem % 60);
    format!("{y:04}-{mo:02}-{d:02}T{h:02}:{mi:02}:{s:02}.{:03}Z", since.subsec_millis())
}

/// Parses a UTC instant: `2025-11-23` (midnight), `2025-11-23T18:04:05Z`,
/// with optional fractional seconds and an optional `Z`. Anything else,
/// including an offset other than `Z` and an impossible date, is an error
/// saying what was expected.
pub fn parse_rfc3339(text: &str) -> Result<SystemTime, String> {
    let bad = || format!("`{text}` is not a UTC time: write 2025-11-23 or 2025-11-23T18:04:05Z");
    let t = text.trim();
    let t = t.strip_suffix('Z').or_else(|| t.strip_suffix('z')).unwrap_or(t);
    let (date, clock) = match t.split_once(['T', 't', ' ']) {
        Some((d, c)) => (d, Some(c)),
        None => (t, None),
    };
    let mut date_parts = date.splitn(3, '-');
    let mut next_number = |max: u32| -> Result<u32, String> {
        date_parts.next().and_then(|p| p.parse::<u32>().ok()).filter(|n| *n <= max).ok_or_else(bad)
    };
    let (year, month, day) = (next_number(9999)?, next_number(12)?, next_number(31)?);
    if month == 0 || day == 0 || year < 1970 {
        return Err(bad());
    }
    let days = days_from_civil(i64::from(year), month, day);
    if civil_from_days(days) != (i64::from(year), month, day) {
        return Err(bad());
    }
    let mut ms = days * 86_400_000;
    if let Some(clock) = clock {
        let (hms, fraction) = clock.split_once('.').unwrap_or((clock, ""));
        let parts: Vec<&str> = hms.split(':').collect();
        let [h, mi, s] = parts.as_slice() else { return Err(bad()) };
        let number = |p: &str, max: i64| p.parse::<i64>().ok().filter(|n| (0..=max).contains(n)).ok_or_else(bad);
        ms += (number(h, 23)? * 3600 + number(mi, 59)? * 60 + number(s, 59)?) * 1000;
        if !fraction.is_empty() {
            if !fraction.bytes().all(|b| b.is_ascii_digit()) {
                return Err(bad());
            }
            let digits: String = fraction.chars().chain("000".chars()).take(3).collect();
            ms += digits.parse::<i64>().map_err(|_| bad())?;
        }
    }
    Ok(from_unix_ms(ms))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn formats_and_parses_known_instants() {
        assert_eq!(rfc3339(UNIX_EPOCH), "1970-01-01T00:00:00.000Z");
        let t = UNIX_EPOCH + Duration::from_millis(951_827_696_789);
        assert_eq!(rfc3339(t), "2000-02-29T12:34:56.789Z");
        assert_eq!(parse_rfc3339("2000-02-29T12:34:56.789Z"), Ok(t));
        assert_eq!(parse_rfc3339("2000-02-29"), Ok(UNIX_EPOCH + Duration::from_secs(951_782_400)));
        assert_eq!(parse_rfc3339("2024-12-31T23:59:59"), Ok(UNIX_EPOCH + Duration::from_secs(1_735_689_599)));
    }

    #[test]
    fn rejects_what_is_not_a_time() {
        for bad in
            ["", "2001-02-29", "2025-13-01", "2025-11-23T24:00:00Z", "2025-11-23T10:00Z", "yesterday", "2025-1-1x"]
        {
            assert!(parse_rfc3339(bad).is_err(), "{bad}");
        }
    }

    #[test]
    fn round_trips_every_day_of_a_leap_cycle() {
        for day in 0..(4 * 366) {
            let t = UNIX_EPOCH + Duration::from_millis(day * 86_400_000 + 12_345);
            assert_eq!(parse_rfc3339(&rfc3339(t)), Ok(t));
        }
    }
}
