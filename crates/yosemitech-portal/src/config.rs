//! The portal's settings and where the registration token comes from.

use std::collections::BTreeMap;
use std::fmt;
use std::path::{Path, PathBuf};
use std::time::Duration;

use serde::Deserialize;

/// Environment variable holding the registration token when
/// `token = "environment"`.
pub const TOKEN_VAR: &str = "YOSEMITECH_MMW_TOKEN";

/// The portal's data endpoint.
pub const DEFAULT_URL: &str = "https://monitormywatershed.org/api/data-stream/";

/// Records per request at most, by default.
pub const DEFAULT_BATCH: usize = 50;

/// Where the registration token comes from.
///
/// In TOML: `token = "environment"` ([`TOKEN_VAR`]) or `token = { file =
/// "/path" }`: a file holding the token on one line (a trailing newline
/// ignored) that only its owner may read or write (mode `0600` or `0400`).
#[derive(Debug, Clone, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "lowercase", deny_unknown_fields)]
pub enum TokenSource {
    /// [`TOKEN_VAR`] from the process environment.
    Environment,
    /// An owner-only file holding the token.
    File(PathBuf),
}

impl fmt::Display for TokenSource {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Environment => write!(f, "the environment ({TOKEN_VAR})"),
            Self::File(path) => write!(f, "the file {}", path.display()),
        }
    }
}

/// The site's registration token. Its `Debug` and `Display` print
/// `[redacted]`; [`Token::expose`] is called once per request, to put it in
/// the `TOKEN` header.
#[derive(Clone, PartialEq, Eq)]
pub struct Token(String);

impl Token {
    /// Wraps a token.
    pub fn new(value: impl Into<String>) -> Self {
        Self(value.into())
    }

    /// The token itself: only for the request header, never for a log.
    pub fn expose(&self) -> &str {
        &self.0
    }

    /// `text` with every occurrence of the token replaced by `[redacted]`:
    /// for what a server sent back, before it is logged.
    pub fn redact(&self, text: &str) -> String {
        if self.0.is_empty() { text.to_owned() } else { text.replace(&self.0, "[redacted]") }
    }
}

impl fmt::Debug for Token {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("Token([redacted])")
    }
}

impl fmt::Display for Token {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("[redacted]")
    }
}

/// Why the token could not be loaded. No variant carries any part of it.
#[derive(Debug, thiserror::Error)]
pub enum TokenError {
    /// The variable is unset, empty or not UTF-8.
    #[error("token = \"environment\" but {TOKEN_VAR} is not set (or empty, or not UTF-8)")]
    MissingVariable,
    /// The file is readable or writable by group or others.
    #[error(
        "token file {} is accessible to group or others (mode {mode:04o}); run `chmod 600 {}` so that only its owner can read it",
        path.display(),
        path.display()
    )]
    FileNotOwnerOnly {
        /// The file.
        path: PathBuf,
        /// Its permission bits.
        mode: u32,
    },
    /// Not a regular file.
    #[error("token file {} is not a regular file", path.display())]
    NotAFile {
        /// The path.
        path: PathBuf,
    },
    /// The file could not be read.
    #[error("cannot read token file {}: {source}", path.display())]
    Read {
        /// The file.
        path: PathBuf,
        /// The I/O error (it holds no file content).
        source: std::io::Error,
    },
    /// The file is not one non-empty line of printable ASCII.
    #[error("token file {} must hold the token on one line (printable ASCII, not empty)", path.display())]
    Malformed {
        /// The file.
        path: PathBuf,
    },
}

impl TokenSource {
    /// Loads the token from the process environment or the file.
    pub fn load(&self) -> Result<Token, TokenError> {
        self.load_with(|name| std::env::var(name).ok())
    }

    /// [`Self::load`] with the environment given as a lookup function.
    pub fn load_with(&self, env: impl Fn(&str) -> Option<String>) -> Result<Token, TokenError> {
        match self {
            Self::Environment => match env(TOKEN_VAR) {
                Some(token) if valid_token(&token) => Ok(Token::new(token)),
                _ => Err(TokenError::MissingVariable),
            },
            Self::File(path) => read_token_file(path),
        }
    }
}

/// A header value the portal can receive: printable ASCII, no spaces at the ends.
fn valid_token(token: &str) -> bool {
    !token.is_empty() && token.bytes().all(|b| b.is_ascii_graphic())
}

fn read_token_file(path: &Path) -> Result<Token, TokenError> {
    let read_error = |source| TokenError::Read { path: path.to_owned(), source };
    let metadata = std::fs::metadata(path).map_err(read_error)?;
    if !metadata.is_file() {
        return Err(TokenError::NotAFile { path: path.to_owned() });
    }
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        let mode = metadata.permissions().mode() & 0o7777;
        if mode & 0o077 != 0 {
            return Err(TokenError::FileNotOwnerOnly { path: path.to_owned(), mode });
        }
    }
    let bytes = std::fs::read(path).map_err(read_error)?;
    // The content goes into no error: a wrong file must not leak into a log.
    let malformed = || TokenError::Malformed { path: path.to_owned() };
    let text = String::from_utf8(bytes).map_err(|_| malformed())?;
    let line = text.strip_suffix('\n').map(|l| l.strip_suffix('\r').unwrap_or(l)).unwrap_or(&text);
    if valid_token(line) { Ok(Token::new(line)) } else { Err(malformed()) }
}

/// Whether `text` is a UUID as the portal writes them: 8-4-4-4-12
/// hexadecimal digits (either case).
pub fn is_uuid(text: &str) -> bool {
    let groups: Vec<&str> = text.split('-').collect();
    groups.len() == 5
        && groups.iter().zip([8, 4, 4, 4, 12]).all(|(g, n)| g.len() == n && g.bytes().all(|b| b.is_ascii_hexdigit()))
}

/// A site on the portal and how the station publishes to it: the
/// `[monitor_my_watershed]` section of a station file, validated.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct PortalConfig {
    /// The data endpoint ([`DEFAULT_URL`]).
    pub url: String,
    /// Where the registration token comes from.
    pub token: TokenSource,
    /// The site's sampling feature UUID.
    pub sampling_feature: String,
    /// The result UUID of each measurement, by probe label then measurement
    /// name.
    pub results: BTreeMap<String, BTreeMap<String, String>>,
    /// The UTC offset the timestamps carry, in whole hours (the portal keeps
    /// whole hours): 0 writes `+00:00`.
    pub utc_offset_hours: i8,
    /// Records per request at most.
    pub batch: usize,
    /// The longest a request may take, connection included.
    pub timeout: Duration,
    /// The first wait after a failed request; it doubles up to `retry_max`.
    pub retry_min: Duration,
    /// The longest wait between attempts; a refusal that will not go away
    /// by itself (a wrong token) waits this long every time.
    pub retry_max: Duration,
    /// How often the store is looked at when nobody wakes the publisher.
    pub poll_interval: Duration,
}

impl PortalConfig {
    /// Defaults for everything but what identifies the site.
    pub fn new(token: TokenSource, sampling_feature: impl Into<String>) -> Self {
        Self {
            url: DEFAULT_URL.to_owned(),
            token,
            sampling_feature: sampling_feature.into(),
            results: BTreeMap::new(),
            utc_offset_hours: 0,
            batch: DEFAULT_BATCH,
            timeout: Duration::from_secs(30),
            retry_min: Duration::from_secs(1),
            retry_max: Duration::from_secs(300),
            poll_interval: Duration::from_secs(1),
        }
    }

    /// The result UUID bound to `measurement` of probe `label`.
    pub fn result(&self, label: &str, measurement: &str) -> Option<&str> {
        self.results.get(label)?.get(measurement).map(String::as_str)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn uuids_are_8_4_4_4_12_hex() {
        assert!(is_uuid("a5a5a5a5-0000-4000-8000-0123456789AB"));
        for bad in [
            "",
            "a5a5a5a5-0000-4000-8000-0123456789a",
            "a5a5a5a5-0000-4000-8000-0123456789abc",
            "a5a5a5a50000-4000-8000-0123456789ab",
            "g5a5a5a5-0000-4000-8000-0123456789ab",
            "a5a5a5a5-0000-4000-8000-0123456789ab-",
            "{a5a5a5a5-0000-4000-8000-0123456789ab}",
        ] {
            assert!(!is_uuid(bad), "{bad}");
        }
    }

    #[test]
    fn the_token_never_shows() {
        let token = Token::new("s3cr3t-token");
        for shown in [format!("{token:?}"), format!("{token}"), token.redact("bad token s3cr3t-token")] {
            assert!(!shown.contains("s3cr3t"), "{shown}");
        }
        let missing = TokenSource::Environment.load_with(|_| None).unwrap_err();
        assert!(missing.to_string().contains(TOKEN_VAR));
    }

    #[cfg(unix)]
    #[test]
    fn a_token_file_must_be_owner_only_and_one_line() {
        use std::os::unix::fs::PermissionsExt;
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("token");
        std::fs::write(&path, "abc123\n").unwrap();
        std::fs::set_permissions(&path, std::fs::Permissions::from_mode(0o644)).unwrap();
        let source = TokenSource::File(path.clone());
        let e = source.load().unwrap_err();
        assert!(matches!(e, TokenError::FileNotOwnerOnly { mode: 0o644, .. }), "{e}");
        std::fs::set_permissions(&path, std::fs::Permissions::from_mode(0o600)).unwrap();
        assert_eq!(source.load().unwrap().expose(), "abc123");
        std::fs::write(&path, "abc123\nsecond line\n").unwrap();
        let e = source.load().unwrap_err();
        assert!(matches!(e, TokenError::Malformed { .. }) && !e.to_string().contains("abc123"), "{e}");
    }
}
