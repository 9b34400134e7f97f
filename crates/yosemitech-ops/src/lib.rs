//! The operations every front end of the Yosemitech tools shares, as
//! cargo's `ops` are to its commands: a front end (a CLI command, the
//! station logger, the Python module) parses its input, makes one call
//! here and renders what comes back. Work on the spec's model
//! ([`yosemitech_spec::Sensor`]), so that spec files loaded at run time
//! work as the built-in ones do, over the runtime's blocking client.
//!
//! - [`bus`]: a serial port or an RTU-over-TCP gateway opened for a client;
//! - [`built_in`]: the spec compiled in, and spec files loaded at run time;
//! - [`transaction`]: one request of a spec command, encoded, sent with the
//!   client's retries and decoded;
//! - [`procedure`]: a spec procedure's timing, and the procedure in a line;
//! - [`identify`]: which probe answers at an address, and which manual
//!   covers its firmware.

#![cfg_attr(not(test), deny(clippy::unwrap_used, clippy::expect_used, clippy::panic))]

pub mod built_in;
pub mod bus;
pub mod identify;
pub mod procedure;
pub mod transaction;

pub use identify::{Identification, Identifier, common_serial, printable, software_revision};
pub use transaction::{TransactionError, call, call_data, target};

use yosemitech_rtu::{Error as RtuError, FrameError, Hex};

/// A failed request in a few words (`no reply`, `exception 2`); `reply` is
/// what the client received ([`yosemitech_rtu::Client::last_reply`]).
pub fn failure_text(e: &RtuError, reply: &[u8]) -> String {
    match e {
        RtuError::Timeout { received: 0, .. } => "no reply".into(),
        RtuError::Timeout { received, .. } => format!("incomplete reply ({received} bytes: {})", Hex(reply)),
        RtuError::Frame { error: FrameError::Exception { code, .. } } => format!("exception {code}"),
        RtuError::Frame { error } => format!("{error} (reply {})", Hex(reply)),
        RtuError::Io(error) => format!("port error: {error}"),
        other => other.to_string(),
    }
}
