//! `yosemitech export`: a station's stored readings as CSV or JSON lines.

use std::io::Write;
use std::time::{Duration, UNIX_EPOCH};

use yosemitech_station::export;

use crate::args::StoredRange;
use crate::error::{CliError, Result};
use crate::stored::open_existing;
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
    /// The store and the time range.
    #[command(flatten)]
    pub range: StoredRange,
    /// Output format.
    #[arg(short, long, value_enum, default_value_t = ExportFormat::Csv)]
    pub format: ExportFormat,
}

/// Runs `export`.
pub fn run(args: &ExportArgs, out: &mut dyn Write) -> Result<()> {
    let store = open_existing(&args.range.db)?;
    let from = args.range.from.unwrap_or(UNIX_EPOCH);
    // The far future: every reading.
    let to = args.range.to.unwrap_or(UNIX_EPOCH + Duration::from_secs(i64::MAX as u64 / 1000 / 2));
    if to < from {
        return Err(CliError::usage("--to is before --from").hint("--from is inclusive, --to exclusive"));
    }
    let readings =
        store.range(from, to).map_err(|e| CliError::device(format!("cannot read {}: {e}", args.range.db.display())))?;
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
