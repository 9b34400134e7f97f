//! Sleeps that end when they were asked to.
//!
//! Linux lets a sleeping thread wake up to its timer slack late (50 µs by
//! default) so that it can batch wake-ups. On a Modbus line the client sleeps
//! out the inter-frame silence before every request, and at 115200 baud that
//! silence is 1.75 ms and a character 87 µs: the default slack costs most of a
//! character on every transaction (BENCHMARKS.md, "Against minimalmodbus").
//! The tool asks for 1 µs once, from the main thread before it starts any
//! other, so that every thread it starts inherits it.

/// The slack the tool asks for, in nanoseconds.
pub const NANOS: u64 = 1_000;

/// Sets the process's timer slack to [`NANOS`]. Best effort: other systems,
/// and kernels without `/proc/self/timerslack_ns` (before 4.6), keep their
/// default, which costs only speed.
pub fn tighten() {
    // /proc/self is the main thread, the caller; a process may always set its own.
    #[cfg(target_os = "linux")]
    let _ = std::fs::write("/proc/self/timerslack_ns", NANOS.to_string());
}
