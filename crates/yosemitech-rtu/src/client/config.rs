//! How a client times and retries requests: [`ClientConfig`], [`RetryPolicy`].

use core::time::Duration;

use super::error::ClientError;
use crate::error::FrameError;

/// Which failures are retried, how often and how far apart.
///
/// Retried (each class can be switched off): timeouts; corrupt frames (CRC
/// mismatch, truncated, too long); foreign frames (a reply from another slave
/// or for another function: another device's conversation). Never retried:
/// Modbus exceptions, byte counts and write echoes that do not match (the
/// device answered, and would answer the same again), encoding and transport
/// errors.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct RetryPolicy {
    /// Attempts after the first.
    pub retries: u32,
    /// Wait between a failed attempt and the next.
    pub backoff: Duration,
    /// Retry when no complete reply arrived in time.
    pub on_timeout: bool,
    /// Retry CRC mismatches and truncated or overlong frames.
    pub on_corrupt: bool,
    /// Retry replies from another slave or for another function.
    pub on_foreign: bool,
}

impl RetryPolicy {
    /// One attempt, no retries.
    pub const NONE: Self =
        Self { retries: 0, backoff: Duration::ZERO, on_timeout: true, on_corrupt: true, on_foreign: true };

    /// Whether `error` is of a class this policy retries (the attempt count
    /// is the client's business).
    pub fn should_retry<E>(&self, error: &ClientError<E>) -> bool {
        match error {
            ClientError::Timeout { .. } => self.on_timeout,
            ClientError::Frame { error } => match error {
                FrameError::Crc { .. } | FrameError::Truncated { .. } | FrameError::TooLong { .. } => self.on_corrupt,
                FrameError::WrongSlave { .. } | FrameError::WrongFunction { .. } => self.on_foreign,
                FrameError::ByteCount { .. } | FrameError::EchoMismatch { .. } | FrameError::Exception { .. } => false,
            },
            ClientError::Encode(_) | ClientError::Request(_) | ClientError::Io(_) => false,
        }
    }
}

impl Default for RetryPolicy {
    /// Two retries, 50 ms apart, of every retryable class.
    fn default() -> Self {
        Self { retries: 2, backoff: Duration::from_millis(50), on_timeout: true, on_corrupt: true, on_foreign: true }
    }
}

/// How a client times and retries requests. Build with struct update
/// syntax: `ClientConfig { timeout, ..ClientConfig::default() }`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct ClientConfig {
    /// Time allowed for the whole reply of one attempt, from the end of the
    /// request on the line to the reply's last byte. Default 1 s.
    pub timeout: Duration,
    /// Retries.
    pub retry: RetryPolicy,
    /// Silence kept on the bus before each request. `None` (the default)
    /// derives it from the line: t3.5 of its timing, at least
    /// [`ClientConfig::min_inter_frame_delay`], or nothing for links
    /// without line timing (TCP, in-memory). `Some(d)` uses `d` as is;
    /// `Some(Duration::ZERO)` never waits.
    pub inter_frame_delay: Option<Duration>,
    /// The least derived inter-frame delay at 19200 baud and below. Default
    /// 4 ms: the manuals contradict themselves on 10 or 11 bits per
    /// character, whose t3.5 at 9600 baud is 3.65 or 4.01 ms (datasheet
    /// notes, section 6 item 10). Above 19200 baud t3.5 is fixed at 1.75 ms.
    pub min_inter_frame_delay: Duration,
    /// Silence kept after a broadcast before the next request, so slaves
    /// can act on it (the Modbus "turnaround delay"). Default 100 ms.
    pub broadcast_turnaround: Duration,
}

impl Default for ClientConfig {
    fn default() -> Self {
        Self {
            timeout: Duration::from_secs(1),
            retry: RetryPolicy::default(),
            inter_frame_delay: None,
            min_inter_frame_delay: Duration::from_millis(4),
            broadcast_turnaround: Duration::from_millis(100),
        }
    }
}
