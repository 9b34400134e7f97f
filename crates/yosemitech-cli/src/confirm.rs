//! Asking before anything is written to a probe.

use std::io::{self, BufRead, IsTerminal, Write};

use crate::error::{CliError, Result};

/// Refuses early when a confirmation will be needed but cannot be asked:
/// no `--yes` and stdin is not a terminal.
pub fn ensure_can_ask(yes: bool, action: &str) -> Result<()> {
    if yes || io::stdin().is_terminal() {
        Ok(())
    } else {
        Err(CliError::usage(format!("refusing to {action} without confirmation: stdin is not a terminal"))
            .hint("add --yes to confirm in advance (scripts), or run it from a terminal"))
    }
}

/// Asks `question` on stderr and reads y/N from stdin; `--yes` answers for
/// the user. A "no" (or end of input) is an error: nothing was written.
pub fn confirm(yes: bool, question: &str) -> Result<()> {
    if yes {
        return Ok(());
    }
    ensure_can_ask(yes, "write")?;
    let mut err = io::stderr().lock();
    let _ = write!(err, "{question} [y/N] ");
    let _ = err.flush();
    drop(err);
    let mut answer = String::new();
    io::stdin().lock().read_line(&mut answer).map_err(|e| CliError::device(format!("cannot read the answer: {e}")))?;
    match answer.trim().to_ascii_lowercase().as_str() {
        "y" | "yes" => Ok(()),
        _ => Err(CliError::device("cancelled; nothing was written").hint("answer y to go ahead, or pass --yes")),
    }
}
