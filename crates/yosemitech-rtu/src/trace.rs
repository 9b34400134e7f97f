//! The runtime's log events and spans, through `tracing` with the `tracing`
//! feature and compiled out without it: a consumer that does not collect
//! them neither builds `tracing` nor pays for a span per transaction.

/// An event at `level` (`debug`, `warn`, ...), as `tracing::event!` takes it.
macro_rules! log {
    ($level:ident, $($arg:tt)*) => {
        #[cfg(feature = "tracing")]
        tracing::$level!($($arg)*);
    };
}

/// Enters a debug span, as `tracing::debug_span!` takes it, for the rest of
/// the enclosing block.
#[cfg(feature = "std")]
macro_rules! enter_span {
    ($($arg:tt)*) => {
        #[cfg(feature = "tracing")]
        let _span = tracing::debug_span!($($arg)*).entered();
    };
}

/// The future `$future`, in a debug span (as `tracing::debug_span!` takes it)
/// while it runs.
#[cfg(feature = "tokio")]
macro_rules! in_span {
    ($future:expr, $($arg:tt)*) => {{
        #[cfg(feature = "tracing")]
        let future = tracing::Instrument::instrument($future, tracing::debug_span!($($arg)*));
        #[cfg(not(feature = "tracing"))]
        let future = $future;
        future
    }};
}
