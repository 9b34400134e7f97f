//! `watch`: the terminal view of a station's store, refreshed until q.

use std::io::{self, IsTerminal as _};
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant, SystemTime};

use ratatui::DefaultTerminal;
use ratatui::crossterm::event::{self, Event, KeyCode, KeyEventKind, KeyModifiers};

use crate::dashboard::Dashboard;
use crate::error::{CliError, Result};
use crate::format::parse_duration;
use crate::stored::StoredReadings;
use clap::Args;
use std::path::PathBuf;

/// `watch`.
#[derive(Args, Debug)]
pub struct WatchArgs {
    /// The station's store (the SQLite file `yosemitech log` writes).
    #[arg(long, value_name = "FILE")]
    pub db: PathBuf,
    /// Time between two reads of the store.
    #[arg(short, long, value_name = "DURATION", default_value = "2s", value_parser = parse_duration)]
    pub interval: Duration,
    /// How far back the sparklines and the error and retry counts reach.
    #[arg(long, value_name = "DURATION", default_value = "6h", value_parser = parse_duration)]
    pub window: Duration,
}

/// Values kept per measurement for its sparkline: more than a terminal is wide.
const HISTORY: usize = 512;
/// Longest wait for a key before the view is redrawn (ages tick every second).
const TICK: Duration = Duration::from_millis(250);

/// The terminal in raw mode on the alternate screen, restored when dropped
/// (also on an error or a panic, whose hook ratatui installs).
struct Screen(DefaultTerminal);

impl Screen {
    fn start() -> Result<Self> {
        match ratatui::try_init() {
            Ok(terminal) => Ok(Self(terminal)),
            Err(e) => {
                ratatui::restore();
                Err(CliError::device(format!("cannot set up the terminal: {e}")))
            }
        }
    }
}

impl Drop for Screen {
    fn drop(&mut self) {
        ratatui::restore();
    }
}

/// Runs `watch` until q, Esc, Ctrl-C or `stop` (SIGTERM, SIGHUP).
pub fn run(args: &WatchArgs, stop: &AtomicBool) -> Result<()> {
    if !io::stdout().is_terminal() {
        return Err(CliError::usage("watch draws on a terminal, and stdout is not one")
            .hint("`yosemitech plot` draws a chart file; `yosemitech export` writes the readings"));
    }
    let store = StoredReadings::open(&args.db)?;
    let source = args.db.display().to_string();
    let load = |now| store.snapshot(now, args.window, HISTORY).map_err(|e| e.message);
    // A store that cannot be read at all fails before the screen changes.
    let mut snapshot = load(SystemTime::now()).map_err(CliError::device)?;
    let mut status: Option<String> = None;
    let mut next_load = Instant::now() + args.interval;
    let mut screen = Screen::start()?;
    let drawn = |e: io::Error| CliError::device(format!("cannot draw on the terminal: {e}"));
    loop {
        let now = SystemTime::now();
        if Instant::now() >= next_load {
            // A failed refresh (the logger holds a lock, a disk error) keeps the last view.
            match load(now) {
                Ok(fresh) => (snapshot, status) = (fresh, None),
                Err(e) => status = Some(format!("cannot refresh: {e}")),
            }
            next_load = Instant::now() + args.interval;
        }
        let view =
            Dashboard { source: &source, snapshot: &snapshot, now, window: args.window, status: status.as_deref() };
        screen.0.draw(|frame| frame.render_widget(&view, frame.area())).map_err(drawn)?;
        if stop.load(Ordering::SeqCst) {
            return Ok(());
        }
        let wait = TICK.min(next_load.saturating_duration_since(Instant::now()));
        if event::poll(wait).map_err(drawn)?
            && let Event::Key(key) = event::read().map_err(drawn)?
        {
            let ctrl_c = key.code == KeyCode::Char('c') && key.modifiers.contains(KeyModifiers::CONTROL);
            let quit = matches!(key.code, KeyCode::Char('q') | KeyCode::Esc) || ctrl_c;
            if key.kind == KeyEventKind::Press && quit {
                return Ok(());
            }
        }
    }
}
