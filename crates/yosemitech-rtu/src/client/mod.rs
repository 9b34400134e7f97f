//! The Modbus RTU master: one request at a time, with RTU timing,
//! stale-input discarding, length-delimited framing, every frame check,
//! retries and frame dumps.
//!
//! The protocol lives once, in the sans-IO [`ClientCore`] (`no_std`, no
//! allocation, no clock, no I/O); drivers run it over a link: the blocking
//! `Client` over a `Transport` (feature `std`), the tokio `AsyncClient` over
//! an `AsyncLink` (feature `tokio`), the async firmware driver
//! `embedded::FirmwareClient` over `embedded-io-async` (feature `embedded`).
//!
//! # One transaction
//!
//! 1. Wait until the bus has been silent for the inter-frame delay (t3.5,
//!    [`ClientCore::inter_frame_delay`]) since the last byte sent or
//!    received, and for the turnaround after a broadcast.
//! 2. Read and drop stale input (logged); if there was any, keep the
//!    silence again after it; then drop what the link still buffers.
//! 3. Send the request, encoded into the core's buffer.
//! 4. Read the first 3 bytes of the reply, then exactly the rest: 2 more for
//!    an exception, [`Layout::response_len`](crate::Layout::response_len) in
//!    all for a normal reply ([`frame::reply_len`](crate::frame::reply_len)).
//!    All reads share one deadline, [`ClientConfig::timeout`] after the
//!    request left. Bytes whose successor is not the expected function code
//!    (line noise as an RS-485 driver turns on) are skipped before the frame;
//!    a candidate frame whose CRC fails is tried again one byte further on
//!    while more bytes arrive (noise before a slave whose address looks like
//!    a function code, slave 3 or 16).
//! 5. Check and decode the reply (the decoder computes its CRC, once per
//!    candidate); on a retryable failure ([`RetryPolicy`]), wait
//!    [`RetryPolicy::backoff`] and start again at 1.
//!
//! A transaction allocates nothing, on success or failure. Errors
//! ([`ClientError`]) are a few words; the bytes of the last reply stay in the
//! client (`last_reply()`). With the `tracing` feature, each call is a debug
//! span, frames go to `tracing` at debug level (`tx`, `rx`, stale and skipped
//! bytes) and retries at warn.

#[cfg(feature = "std")]
mod blocking;
#[cfg(feature = "std")]
mod clock;
mod config;
#[cfg(feature = "embedded")]
pub mod embedded;
mod error;
mod machine;
mod time;
#[cfg(feature = "tokio")]
mod tokio;

#[cfg(feature = "std")]
pub use self::blocking::{Client, Error};
pub use self::config::{ClientConfig, RetryPolicy};
pub use self::error::{ClientError, Sent};
pub use self::machine::{Action, ClientCore};
pub use self::time::Instant;
#[cfg(test)]
pub(crate) use self::time::micros_ceil;
#[cfg(feature = "tokio")]
pub use self::tokio::AsyncClient;
