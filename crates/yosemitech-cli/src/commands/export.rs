//! `yosemitech export`: a station's stored readings (or a fleet's, from
//! the PostgreSQL database `ingest` writes) as CSV or JSON lines.

use std::io::Write;
use std::path::PathBuf;
use std::time::{Duration, SystemTime, UNIX_EPOCH};

use yosemitech_station::export;
use yosemitech_station::outbox::stored_of;

use crate::database::database_config;
use crate::error::{CliError, Result};
use crate::stored::open_existing;
use crate::time::parse_instant_now as parse_instant;
use clap::Args;
use clap::ValueEnum;

/// Output formats of `export`.
#[derive(ValueEnum, Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum ExportFormat {
    /// Comma-separated values, one row per value, with a header row.
    #[default]
    Csv,
    /// One JSON object per reading.
    Jsonl,
}

/// `export`.
#[derive(Args, Debug)]
pub struct ExportArgs {
    /// The station's store (the SQLite file `yosemitech log` writes).
    #[arg(long, value_name = "FILE", required_unless_present = "postgres", conflicts_with = "postgres")]
    pub db: Option<PathBuf>,
    /// The fleet's database (`yosemitech ingest`), as a libpq connection string; its password
    /// comes from PGPASSWORD.
    #[arg(long, value_name = "CONNINFO")]
    pub postgres: Option<String>,
    /// First instant, inclusive (UTC) [default: the first reading].
    #[arg(long, value_name = "TIME", value_parser = parse_instant)]
    pub from: Option<SystemTime>,
    /// Last instant, exclusive (UTC) [default: the last reading].
    #[arg(long, value_name = "TIME", value_parser = parse_instant)]
    pub to: Option<SystemTime>,
    /// Output format.
    #[arg(short, long, value_enum, default_value_t = ExportFormat::Csv)]
    pub format: ExportFormat,
}

/// Runs `export`.
pub fn run(args: &ExportArgs, out: &mut dyn Write) -> Result<()> {
    let from = args.from.unwrap_or(UNIX_EPOCH);
    // The far future: every reading.
    let to = args.to.unwrap_or(UNIX_EPOCH + Duration::from_secs(i64::MAX as u64 / 1000 / 2));
    if to < from {
        return Err(CliError::usage("--to is before --from").hint("--from is inclusive, --to exclusive"));
    }
    let readings = match (&args.db, &args.postgres) {
        (Some(db), _) => {
            let store = open_existing(db)?;
            store.range(from, to).map_err(|e| CliError::device(format!("cannot read {}: {e}", db.display())))?
        }
        (None, Some(conninfo)) => {
            let config = database_config(conninfo)?;
            // Times PostgreSQL can hold (the default `to` is far past them).
            let to = to.min(UNIX_EPOCH + Duration::from_millis(253_402_300_800_000));
            let mut database = yosemitech_ingest::Database::open(&config)
                .map_err(|e| CliError::device(format!("cannot open the database: {e}")))?;
            let messages = database
                .readings_between(from, to)
                .map_err(|e| CliError::device(format!("cannot read the database: {e}")))?;
            messages.iter().map(stored_of).collect()
        }
        (None, None) => return Err(CliError::usage("give --db FILE or --postgres CONNINFO")),
    };
    if args.format == ExportFormat::Csv {
        export::write_csv_header(out)?;
    }
    for stored in &readings {
        match args.format {
            ExportFormat::Csv => export::write_csv(stored, out)?,
            ExportFormat::Jsonl => export::write_jsonl(stored, out)?,
        }
    }
    Ok(())
}
