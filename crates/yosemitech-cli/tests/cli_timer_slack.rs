//! The tool asks Linux for sleeps that end on time (its timer slack), so the
//! inter-frame silence it keeps before each request is not stretched by the
//! kernel's default 50 µs: read off a running `poll` against a simulated probe.
#![cfg(target_os = "linux")]

use std::time::Duration;

use crate::device::polling;
use yosemitech_tests::cli::Binary;
use yosemitech_tests::report;

const YOSEMITECH: Binary = Binary(env!("CARGO_BIN_EXE_yosemitech"));

#[test]
fn a_polling_tool_sleeps_with_one_microsecond_of_slack() {
    // Past a data row: the tool is through its start-up and talking to the probe.
    let Some((_sim, mut child, _stdout, _row)) = polling(YOSEMITECH) else {
        report!("no sensor of the spec has a measurement to poll");
        return;
    };
    let slack = std::fs::read_to_string(format!("/proc/{}/timerslack_ns", child.id()));
    child.kill().unwrap();
    yosemitech_tests::cli::wait(&mut child, Duration::from_secs(10));
    match slack {
        Ok(text) => assert_eq!(text.trim(), "1000", "the tool's timer slack, in nanoseconds"),
        // Reading another process's slack takes CAP_SYS_NICE; CI runs as root.
        Err(e) if e.kind() == std::io::ErrorKind::PermissionDenied => {
            report!("cannot read another process's timer slack here: {e}")
        }
        Err(e) => panic!("reading the tool's timer slack: {e}"),
    }
}
