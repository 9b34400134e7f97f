//! Slow and load-sensitive tests: skipped locally with a note, mandatory in
//! CI. Like the tmux and mosquitto runs, they run where the environment says
//! so (`YOSEMITECH_SLOW_TESTS=1`, set by `.ci/run`), so that a developer's
//! `cargo test` on a busy machine stays quick and a CI run covers everything.

use std::io::Write;

/// The environment variable that makes the slow tests run.
pub const SLOW_TESTS: &str = "YOSEMITECH_SLOW_TESTS";

/// Whether a slow test runs here: `true` with `YOSEMITECH_SLOW_TESTS=1`.
/// Otherwise it says on stderr (past the test harness's capture, so the
/// skip shows in `cargo test` output) that `what` is skipped and why, and
/// the test returns.
#[must_use]
pub fn enabled(what: &str) -> bool {
    if std::env::var_os(SLOW_TESTS).is_some_and(|value| value == "1") {
        return true;
    }
    let _ = writeln!(std::io::stderr(), "    skipped: {what} ({SLOW_TESTS}=1 runs it; CI sets it)");
    false
}
