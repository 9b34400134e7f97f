//! UTC timestamps without a date-time dependency: RFC 3339 for logs, a
//! compact form for file names, short forms for charts, and the instants a
//! user types (`--from 2025-11-23T06:00Z`, `--from 6h`).

use std::time::{Duration, SystemTime, UNIX_EPOCH};

use yosemitech_station::time::civil_from_days;

/// The parts of a UTC time: date, hour, minute, second, millisecond.
fn parts(t: SystemTime) -> (i64, u32, u32, u64, u64, u64, u32) {
    let since = t.duration_since(UNIX_EPOCH).unwrap_or(Duration::ZERO);
    let secs = since.as_secs();
    let (y, mo, d) = civil_from_days((secs / 86_400) as i64);
    let rem = secs % 86_400;
    (y, mo, d, rem / 3600, rem % 3600 / 60, rem % 60, since.subsec_millis())
}

/// RFC 3339 UTC with milliseconds: `2025-11-23T18:04:05.123Z` (the
/// station store's format, so that `poll` and `export` agree).
pub fn rfc3339(t: SystemTime) -> String {
    yosemitech_station::time::rfc3339(t)
}

/// Compact UTC for file names: `20251123T180405Z`.
pub fn compact(t: SystemTime) -> String {
    let (y, mo, d, h, mi, s, _) = parts(t);
    format!("{y:04}{mo:02}{d:02}T{h:02}{mi:02}{s:02}Z")
}

/// `18:04:05`: the time of day, UTC.
pub fn clock(t: SystemTime) -> String {
    let (_, _, _, h, mi, s, _) = parts(t);
    format!("{h:02}:{mi:02}:{s:02}")
}

/// `11-23 18:04`: month, day and minute, UTC (chart axes over days).
pub fn day_minute(t: SystemTime) -> String {
    let (_, mo, d, h, mi, _, _) = parts(t);
    format!("{mo:02}-{d:02} {h:02}:{mi:02}")
}

/// `18:04`: hour and minute, UTC (chart axes over hours).
pub fn minute(t: SystemTime) -> String {
    let (_, _, _, h, mi, _, _) = parts(t);
    format!("{h:02}:{mi:02}")
}

/// `2h 05m`: how long ago, in the two largest units.
pub fn age(d: Duration) -> String {
    let s = d.as_secs();
    match s {
        0..60 => format!("{s}s"),
        60..3600 => format!("{}m {:02}s", s / 60, s % 60),
        3600..86_400 => format!("{}h {:02}m", s / 3600, s % 3600 / 60),
        _ => format!("{}d {:02}h", s / 86_400, s % 86_400 / 3600),
    }
}

/// An instant as a user types it: `now`; a time ago (`90m`, `6h`, `2d`);
/// or UTC as the station's store reads it (`2025-11-23`,
/// `2025-11-23T18:04:05Z`, see `yosemitech_station::time::parse_rfc3339`).
pub fn parse_instant(text: &str, now: SystemTime) -> Result<SystemTime, String> {
    let t = text.trim();
    if t == "now" {
        return Ok(now);
    }
    if t.len() < 10 || !t.contains('-') {
        let ago = match t.strip_suffix('d') {
            Some(days) => days
                .parse::<f64>()
                .ok()
                .and_then(|d| Duration::try_from_secs_f64(d * 86_400.0).ok())
                .ok_or_else(|| instant_error(text))?,
            None => crate::format::parse_duration(t).map_err(|_| instant_error(text))?,
        };
        return now
            .checked_sub(ago)
            .filter(|t| *t >= UNIX_EPOCH)
            .ok_or_else(|| format!("`{text}` reaches before 1970"));
    }
    yosemitech_station::time::parse_rfc3339(t).map_err(|_| instant_error(text))
}

/// [`parse_instant`] from the current time: the command line's parser.
pub fn parse_instant_now(text: &str) -> Result<SystemTime, String> {
    parse_instant(text, SystemTime::now())
}

fn instant_error(text: &str) -> String {
    format!(
        "`{text}` is not a time; write 2025-11-23 or 2025-11-23T18:04:05Z (UTC), a time ago such as 6h or 2d, or now"
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn formats_known_instants() {
        assert_eq!(rfc3339(UNIX_EPOCH), "1970-01-01T00:00:00.000Z");
        // 2000-02-29T12:34:56.789Z (a leap day in a century leap year).
        let t = UNIX_EPOCH + Duration::from_millis(951_827_696_789);
        assert_eq!(rfc3339(t), "2000-02-29T12:34:56.789Z");
        assert_eq!(compact(t), "20000229T123456Z");
        // 2024-12-31T23:59:59Z.
        let t = UNIX_EPOCH + Duration::from_secs(1_735_689_599);
        assert_eq!(rfc3339(t), "2024-12-31T23:59:59.000Z");
    }

    #[test]
    fn parses_what_it_prints_and_times_ago() {
        let t = UNIX_EPOCH + Duration::from_millis(951_827_696_789);
        assert_eq!(parse_instant(&rfc3339(t), UNIX_EPOCH), Ok(t));
        let day = UNIX_EPOCH + Duration::from_secs(951_782_400);
        assert_eq!(parse_instant("2000-02-29", UNIX_EPOCH), Ok(day));
        assert_eq!(parse_instant("2000-02-29T12:34:00Z", UNIX_EPOCH), Ok(day + Duration::from_secs(45_240)));
        let now = UNIX_EPOCH + Duration::from_secs(1_000_000);
        assert_eq!(parse_instant("now", now), Ok(now));
        assert_eq!(parse_instant("2h", now), Ok(now - Duration::from_secs(7200)));
        assert_eq!(parse_instant("1d", now), Ok(now - Duration::from_secs(86_400)));
        for bad in ["", "yesterday", "2000-13-01", "2000-02-29T25:00:00Z", "2000-02-29X", "-5h", "2000-02-29T12:3a:00"]
        {
            assert!(parse_instant(bad, now).is_err(), "{bad:?} was accepted");
        }
        assert!(parse_instant("9999d", UNIX_EPOCH).is_err());
    }

    #[test]
    fn short_forms() {
        let t = UNIX_EPOCH + Duration::from_secs(1_735_689_599);
        assert_eq!((clock(t), minute(t), day_minute(t)), ("23:59:59".into(), "23:59".into(), "12-31 23:59".into()));
        assert_eq!(age(Duration::from_secs(59)), "59s");
        assert_eq!(age(Duration::from_secs(3_725)), "1h 02m");
        assert_eq!(age(Duration::from_secs(2 * 86_400 + 3600)), "2d 01h");
    }
}
