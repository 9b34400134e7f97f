//! The topic layout.
//!
//! Every reading is published to
//!
//! ```text
//! <prefix>/<station>/<probe>/reading        e.g. yosemitech/v1/river-01/left%20bank/reading
//! ```
//!
//! * `<prefix>` is `mqtt.topic_prefix`, by default `yosemitech/v1`; the `v1`
//!   is the topic layout's version (the payload carries its own schema
//!   version, see [`crate::message`]).
//! * `<station>` and `<probe>` are the station name and the probe's label,
//!   each escaped into exactly one topic level by [`escape_level`]: bytes
//!   outside `A-Z a-z 0-9 - _ . ~` become `%XX` (upper-case hex of each UTF-8
//!   byte). So a label can never add a level (`/`), act as a wildcard (`+`,
//!   `#`), start a `$SYS`-like topic, or collide with another label; and
//!   [`unescape_level`] gives the label back.
//!
//! Subscriptions: `yosemitech/v1/+/+/reading` for every station,
//! `yosemitech/v1/river-01/#` for one.

/// The default first topic levels.
pub const DEFAULT_TOPIC_PREFIX: &str = "yosemitech/v1";

/// The last topic level of a reading.
pub const READING_LEVEL: &str = "reading";

/// The topic of a reading of probe `probe` at station `station`.
pub fn reading_topic(prefix: &str, station: &str, probe: &str) -> String {
    format!("{prefix}/{}/{}/{READING_LEVEL}", escape_level(station), escape_level(probe))
}

/// Escapes `name` into one topic level: bytes outside `A-Z a-z 0-9 - _ . ~`
/// become `%XX`. Injective, and the result contains no `/`, `+`, `#`, `$`
/// or NUL.
pub fn escape_level(name: &str) -> String {
    let mut level = String::with_capacity(name.len());
    for &byte in name.as_bytes() {
        if byte.is_ascii_alphanumeric() || matches!(byte, b'-' | b'_' | b'.' | b'~') {
            level.push(char::from(byte));
        } else {
            const HEX: &[u8; 16] = b"0123456789ABCDEF";
            level.push('%');
            level.push(char::from(HEX[usize::from(byte >> 4)]));
            level.push(char::from(HEX[usize::from(byte & 0x0f)]));
        }
    }
    level
}

/// The name [`escape_level`] escaped into `level`; `None` if `level` is not
/// such an escape (a bare reserved character, a bad `%XX`, invalid UTF-8).
pub fn unescape_level(level: &str) -> Option<String> {
    let mut bytes = Vec::with_capacity(level.len());
    let mut rest = level.as_bytes();
    while let Some((&byte, tail)) = rest.split_first() {
        if byte == b'%' {
            let [high, low, tail @ ..] = tail else {
                return None;
            };
            let digit = |d: u8| char::from(d).to_digit(16).filter(|_| !d.is_ascii_lowercase());
            let value = digit(*high)? * 16 + digit(*low)?;
            bytes.push(u8::try_from(value).ok()?);
            rest = tail;
        } else if byte.is_ascii_alphanumeric() || matches!(byte, b'-' | b'_' | b'.' | b'~') {
            bytes.push(byte);
            rest = tail;
        } else {
            return None;
        }
    }
    String::from_utf8(bytes).ok()
}

/// Why `prefix` cannot start a topic, if it cannot.
pub fn check_prefix(prefix: &str) -> Result<(), &'static str> {
    if prefix.is_empty() {
        return Err("must not be empty");
    }
    if prefix.contains(['+', '#', '\0']) {
        return Err("must not contain the wildcards + or # or NUL");
    }
    if prefix.starts_with('$') {
        return Err("must not start with $ (reserved for the broker)");
    }
    if prefix.starts_with('/') || prefix.ends_with('/') {
        return Err("must not start or end with /");
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn levels_round_trip_and_never_contain_reserved_characters() {
        for name in ["river-01", "left bank", "a/b", "+", "#", "$SYS", "", "%41", "Ünïcode ✓", "a.b~c_d"] {
            let level = escape_level(name);
            assert!(!level.contains(['/', '+', '#', '$', '\0', ' ']), "{name:?} -> {level:?}");
            assert_eq!(unescape_level(&level).as_deref(), Some(name), "{level:?}");
        }
        assert_eq!(escape_level("left bank/2"), "left%20bank%2F2");
        assert_ne!(escape_level("%41"), escape_level("A"));
    }

    #[test]
    fn unescape_refuses_what_escape_never_produces() {
        for level in ["a b", "a/b", "%4", "%zz", "%4a", "%FF", "+"] {
            assert_eq!(unescape_level(level), None, "{level:?}");
        }
    }

    #[test]
    fn reading_topic_has_the_documented_levels() {
        assert_eq!(
            reading_topic(DEFAULT_TOPIC_PREFIX, "river 01", "in/out"),
            "yosemitech/v1/river%2001/in%2Fout/reading"
        );
    }

    #[test]
    fn prefixes_that_break_topics_are_refused() {
        for prefix in ["", "a/+", "a/#", "$SYS/x", "/a", "a/"] {
            assert!(check_prefix(prefix).is_err(), "{prefix:?}");
        }
        assert!(check_prefix("yosemitech/v1").is_ok());
    }
}
