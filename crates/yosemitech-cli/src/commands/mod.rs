//! One module per subcommand.

pub mod calibrate;
pub mod coefficients;
pub mod decode;
pub mod demo;
pub mod encode;
pub mod export;
pub mod list;
pub mod log;
pub mod measure;
pub mod plot;
pub mod poll;
pub mod read;
pub mod scan;
pub mod set_address;
pub mod simulate;
pub mod watch;
pub mod write;

use std::io::{self, Write};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};

use crate::catalog::Catalog;
use crate::cli::{CalibrateCommand, Cli, CoefficientsCommand, Command};
use crate::error::Result;

/// A flag set by Ctrl-C (SIGINT, SIGTERM, SIGHUP), for the commands that
/// run until stopped; the first Ctrl-C stops cleanly, a second one exits.
fn ctrl_c_flag() -> Arc<AtomicBool> {
    let flag = Arc::new(AtomicBool::new(false));
    let handler_flag = Arc::clone(&flag);
    let installed = ctrlc::set_handler(move || {
        if handler_flag.swap(true, Ordering::SeqCst) {
            std::process::exit(130);
        }
    });
    if let Err(e) = installed {
        let _ = writeln!(io::stderr(), "warning: Ctrl-C will not stop cleanly: {e}");
    }
    flag
}

/// Runs the parsed command line.
pub fn run(cli: &Cli) -> Result<()> {
    let catalog = Catalog::load(&cli.global.spec)?;
    let global = &cli.global;
    let stdout = io::stdout();
    let mut out = stdout.lock();
    let result = match &cli.command {
        Command::Demo(args) => demo::run(&catalog, args, &mut out),
        Command::List(args) => list::run(&catalog, args, &mut out),
        Command::Read(args) => read::run(&catalog, global, args, &mut out),
        Command::Write(args) => write::run(&catalog, global, args, &mut out),
        Command::Poll(args) => poll::run(&catalog, global, args, &ctrl_c_flag(), &mut out),
        Command::Measure(args) => measure::run(&catalog, global, args, &mut out),
        Command::Watch(args) => watch::run(args, &ctrl_c_flag()),
        Command::Plot(args) => plot::run(args, &mut out),
        Command::Calibrate(CalibrateCommand::Ph(args)) => calibrate::run(&catalog, global, args, &mut out),
        Command::Coefficients(CoefficientsCommand::Backup(args)) => {
            coefficients::backup(&catalog, global, args, &mut out)
        }
        Command::Coefficients(CoefficientsCommand::Restore(args)) => {
            coefficients::restore(&catalog, global, args, &mut out)
        }
        Command::Scan(args) => scan::run(&catalog, global, args, &mut out),
        Command::SetAddress(args) => set_address::run(&catalog, global, args, &mut out),
        Command::Decode(args) => decode::run(&catalog, args, &mut out),
        Command::Encode(args) => encode::run(&catalog, args, &mut out),
        Command::Simulate(args) => simulate::run(&catalog, args, &ctrl_c_flag(), &mut out),
        Command::Log(args) if args.check => log::check(&catalog, args, &mut out),
        Command::Log(args) => log::run(&catalog, args, &ctrl_c_flag(), &mut out),
        Command::Export(args) => export::run(args, &mut out),
    };
    // Output written before an error stays visible.
    let flushed = out.flush();
    result?;
    flushed?;
    Ok(())
}
