//! A string that must never be shown: the broker password.

use std::fmt;

/// A secret string (the broker password).
///
/// Its [`Debug`](fmt::Debug) and [`Display`](fmt::Display) print
/// `[redacted]`, so a secret inside a config struct, an error or a log line
/// never shows its content; the only way to read it is [`Secret::expose`],
/// which the publisher calls once, when it hands the password to the MQTT
/// client. It deliberately implements no `Serialize`, so it cannot be written
/// back into a file or a `--check` report either.
#[derive(Clone, PartialEq, Eq)]
pub struct Secret(String);

impl Secret {
    /// Wraps a secret.
    pub fn new(value: impl Into<String>) -> Self {
        Self(value.into())
    }

    /// The secret itself. Call it only to hand the value to the party it is
    /// meant for, never to print it.
    pub fn expose(&self) -> &str {
        &self.0
    }
}

impl fmt::Debug for Secret {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("Secret([redacted])")
    }
}

impl fmt::Display for Secret {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("[redacted]")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn debug_and_display_never_show_the_value() {
        let secret = Secret::new("hunter2-very-secret");
        for shown in [format!("{secret:?}"), format!("{secret}"), format!("{secret:#?}")] {
            assert!(!shown.contains("hunter2"), "{shown}");
            assert!(shown.contains("redacted"), "{shown}");
        }
        assert_eq!(secret.expose(), "hunter2-very-secret");
    }
}
