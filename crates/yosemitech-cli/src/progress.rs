//! Progress bars on stderr, hidden when stderr is not a terminal.

use std::io::IsTerminal;
use std::time::Duration;

use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};

/// True when progress may be drawn.
pub fn enabled() -> bool {
    std::io::stderr().is_terminal()
}

/// A bar of `len` steps with `template` (indicatif syntax), or a hidden
/// bar when stderr is not a terminal.
pub fn bar(len: u64, template: &str) -> ProgressBar {
    if !enabled() {
        return ProgressBar::hidden();
    }
    let bar = ProgressBar::with_draw_target(Some(len), ProgressDrawTarget::stderr());
    if let Ok(style) = ProgressStyle::with_template(template) {
        bar.set_style(style.progress_chars("=> "));
    }
    bar
}

/// A bar that fills over `duration` (in milliseconds), labelled `message`.
pub fn timer(duration: Duration, message: impl Into<String>) -> ProgressBar {
    let bar = bar(u64::try_from(duration.as_millis()).unwrap_or(u64::MAX).max(1), "{msg:24} [{bar:30}] {eta} left");
    bar.set_message(message.into());
    bar
}

/// Waits `duration`, filling `bar`, in slices; `tick` is called between
/// slices and may end the wait early by returning `false`.
pub fn wait(
    bar: &ProgressBar,
    duration: Duration,
    mut slice_sleep: impl FnMut(Duration),
    mut tick: impl FnMut() -> bool,
) {
    const STEPS: u32 = 50;
    let step = duration / STEPS;
    for _ in 0..STEPS {
        if !tick() {
            break;
        }
        slice_sleep(step);
        bar.inc(u64::try_from(step.as_millis()).unwrap_or(0));
    }
    bar.finish_and_clear();
}
