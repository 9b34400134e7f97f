//! One module per subcommand.

pub mod calibrate;
pub mod coefficients;
pub mod decode;
pub mod demo;
pub mod doctor;
pub mod encode;
pub mod export;
pub mod ingest;
pub mod list;
pub mod log;
pub mod measure;
pub mod plot;
pub mod poll;
pub mod read;
pub mod scan;
pub mod set_address;
pub mod simulate;
pub mod sniff;
pub mod watch;
pub mod write;

use std::io::{self, Write};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};

use crate::catalog::Catalog;
use crate::cli::Cli;
use crate::cli::Subcommand;
use crate::commands::calibrate::CalibrateSubcommand;
use crate::commands::coefficients::CoefficientsSubcommand;
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
    let stdout = io::stdout();
    let mut out = stdout.lock();
    let result = match &cli.command {
        Subcommand::Demo(args) => demo::run(&catalog, args, &mut out),
        Subcommand::List(args) => list::run(&catalog, args, &mut out),
        Subcommand::Read(args) => read::run(&catalog, args, &mut out),
        Subcommand::Write(args) => write::run(&catalog, args, &mut out),
        Subcommand::Poll(args) => poll::run(&catalog, args, &ctrl_c_flag(), &mut out),
        Subcommand::Measure(args) => measure::run(&catalog, args, &mut out),
        Subcommand::Watch(args) => watch::run(args, &ctrl_c_flag()),
        Subcommand::Plot(args) => plot::run(args, &mut out),
        Subcommand::Calibrate(args) => match &args.command {
            Some(CalibrateSubcommand::Ph(args)) => calibrate::run(&catalog, args, &mut out),
            Some(CalibrateSubcommand::History(args)) => calibrate::recorded::list(&catalog, args, &mut out),
            Some(CalibrateSubcommand::Restore(args)) => calibrate::recorded::restore(&catalog, args, &mut out),
            None => calibrate::linear::run(&catalog, &args.linear, &ctrl_c_flag(), &mut out),
        },
        Subcommand::Coefficients(CoefficientsSubcommand::Backup(args)) => {
            coefficients::backup(&catalog, args, &mut out)
        }
        Subcommand::Coefficients(CoefficientsSubcommand::Restore(args)) => {
            coefficients::restore(&catalog, args, &mut out)
        }
        Subcommand::Scan(args) => scan::run(&catalog, args, &mut out),
        Subcommand::Doctor(args) => doctor::run(&catalog, args, &ctrl_c_flag(), &mut out),
        Subcommand::SetAddress(args) => set_address::run(&catalog, args, &mut out),
        Subcommand::Decode(args) => decode::run(&catalog, args, &mut out),
        Subcommand::Sniff(args) => sniff::run(&catalog, args, &ctrl_c_flag(), &mut out),
        Subcommand::Encode(args) => encode::run(&catalog, args, &mut out),
        Subcommand::Simulate(args) => simulate::run(&catalog, args, &ctrl_c_flag(), &mut out),
        Subcommand::Log(args) if args.check => log::check(&catalog, args, &mut out),
        Subcommand::Log(args) => log::run(&catalog, args, &ctrl_c_flag(), &mut out),
        Subcommand::Export(args) => export::run(args, &mut out),
        Subcommand::Ingest(args) => ingest::run(args, &ctrl_c_flag(), &mut out),
    };
    // Output written before an error stays visible.
    let flushed = out.flush();
    result?;
    flushed?;
    Ok(())
}
