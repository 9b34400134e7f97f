//! Argument groups several subcommands share: the options every
//! subcommand takes, where a write keeps its coefficient backup,
//! calibration history, a store's time range and station inputs. The port options are beside the port's opening (`port`).

use crate::time::parse_instant_now as parse_instant;
use clap::ArgAction;
use clap::Args;
use std::path::PathBuf;
use std::time::SystemTime;

/// Options every subcommand takes.
#[derive(Args, Debug, Clone, Default)]
pub struct Global {
    /// Load extra spec files from DIR (a directory of YAML files, or one file) at run time;
    /// repeatable. A file may include `yosemitech-common.yaml` without holding a copy.
    #[arg(long, value_name = "DIR", global = true)]
    pub spec: Vec<PathBuf>,
    /// Show frame dumps on stderr: -v every frame sent and received (debug), -vv everything (trace).
    #[arg(short, long, action = ArgAction::Count, global = true)]
    pub verbose: u8,
}

/// Where a command that writes coefficients saves the ones it replaces.
#[derive(Args, Debug, Default, Clone)]
pub struct BackupDir {
    /// Where to save the coefficient backup [default: the current directory].
    #[arg(long = "backup-dir", id = "backup_dir", value_name = "DIR")]
    pub dir: Option<PathBuf>,
}

/// Where the calibration history is kept, and the note a calibration adds to it.
#[derive(Args, Debug, Default, Clone)]
pub struct HistoryArgs {
    /// Keep the history in this station's store (its readings then name the
    /// calibration in force).
    #[arg(long, value_name = "STATION_TOML", conflicts_with = "history")]
    pub config: Option<PathBuf>,
    /// The history file [default: calibrations.sqlite in $XDG_DATA_HOME/yosemitech or ~/.local/share/yosemitech].
    #[arg(long, value_name = "FILE")]
    pub history: Option<PathBuf>,
    /// The operator's note, kept with the calibration.
    #[arg(long, value_name = "TEXT")]
    pub note: Option<String>,
}

/// A station's store and a time range of it, as `plot` and `export` read them.
#[derive(Args, Debug)]
pub struct StoredRange {
    /// The station's store (the SQLite file `yosemitech log` writes).
    #[arg(long, value_name = "FILE")]
    pub db: PathBuf,
    /// First instant, inclusive (UTC) [default: the first reading].
    #[arg(long, value_name = "TIME", value_parser = parse_instant)]
    pub from: Option<SystemTime>,
    /// Last instant, exclusive (UTC) [default: plot: now; export: the last reading].
    #[arg(long, value_name = "TIME", value_parser = parse_instant)]
    pub to: Option<SystemTime>,
}

/// Station inputs of derived quantities (`read`, `poll`, `measure`).
#[derive(Args, Debug, Default)]
pub struct InputArgs {
    /// A station input of the sensor's derived quantities, e.g. `salinity=35` (repeatable) [default: the spec's].
    #[arg(long = "input", value_name = "NAME=VALUE", value_parser = crate::derived::parse_input)]
    pub inputs: Vec<(String, f64)>,
}
