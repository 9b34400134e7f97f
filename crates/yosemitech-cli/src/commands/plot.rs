//! `plot`: a chart file of a time range of a station's store.

use std::collections::BTreeSet;
use std::io::Write;
use std::path::Path;
use std::time::{SystemTime, UNIX_EPOCH};

use plotters::prelude::{BitMapBackend, IntoDrawingArea as _, SVGBackend};

use crate::args::StoredRange;
use crate::chart::{self, MIN_PANEL_HEIGHT};
use crate::error::{CliError, Result};
use crate::format::MAX_SIDE;
use crate::format::parse_size;
use crate::readings::{self, Reading, SeriesFilter};
use crate::stored::StoredReadings;
use crate::time;
use clap::Args;
use std::path::PathBuf;

/// `plot`.
#[derive(Args, Debug)]
pub struct PlotArgs {
    /// The store and the time range.
    #[command(flatten)]
    pub range: StoredRange,
    /// Only this probe (its label in the station's configuration).
    #[arg(long, value_name = "LABEL")]
    pub probe: Option<String>,
    /// Only this measurement (the spec's field name).
    #[arg(long, value_name = "NAME")]
    pub measurement: Option<String>,
    /// The chart file: .png or .svg.
    #[arg(short, long, value_name = "FILE")]
    pub out: PathBuf,
    /// Width and height in pixels, e.g. 1200x800 [default: 1200 wide, 300 high per measurement].
    #[arg(long, value_name = "WxH", value_parser = parse_size)]
    pub size: Option<(u32, u32)>,
}

/// Default chart width, in pixels.
const DEFAULT_WIDTH: u32 = 1200;
/// Default height of one measurement's panel, in pixels.
const DEFAULT_PANEL_HEIGHT: u32 = 300;

/// The chart formats, chosen by the output file's extension.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Format {
    Png,
    Svg,
}

impl Format {
    fn of(path: &Path) -> Result<Self> {
        let extension = path.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase);
        match extension.as_deref() {
            Some("png") => Ok(Self::Png),
            Some("svg") => Ok(Self::Svg),
            _ => Err(CliError::usage(format!("{}: a chart file ends in .png or .svg", path.display()))),
        }
    }
}

/// Runs `plot`, saying on `out` what it wrote.
pub fn run(args: &PlotArgs, out: &mut dyn Write) -> Result<()> {
    let format = Format::of(&args.out)?;
    let from = args.range.from.unwrap_or(UNIX_EPOCH);
    let to = args.range.to.unwrap_or_else(SystemTime::now);
    let span = format!("between {} and {}", time::rfc3339(from), time::rfc3339(to));
    if from >= to {
        return Err(CliError::usage(format!("--from is not before --to: nothing {span}")));
    }
    let store = StoredReadings::open(&args.range.db)?;
    let db = args.range.db.display();
    let latest = store.latest()?;
    let readings = store.range(from, to)?;
    check_known(args, &latest, &readings)?;
    let filter = SeriesFilter { probe: args.probe.clone(), measurement: args.measurement.clone() };
    let series = readings::series(&readings, &filter);
    if series.is_empty() {
        let what = match (&args.probe, &args.measurement) {
            (None, None) => "no readings".to_owned(),
            (Some(p), None) => format!("no values of probe {p}"),
            (None, Some(m)) => format!("no values of {m}"),
            (Some(p), Some(m)) => format!("no values of {m} from probe {p}"),
        };
        let newest = latest.iter().map(|r| r.at).max();
        let hint = match newest {
            Some(at) => format!("the newest reading in {db} is from {}; widen --from/--to", time::rfc3339(at)),
            None => format!("{db} holds no readings yet: `yosemitech log` writes them"),
        };
        return Err(CliError::device(format!("{what} in {db} {span}")).hint(hint));
    }
    let panels = chart::panels(&series).len();
    let panels_u32 = u32::try_from(panels).unwrap_or(u32::MAX);
    let (width, height) = args
        .size
        .unwrap_or_else(|| (DEFAULT_WIDTH, panels_u32.saturating_mul(DEFAULT_PANEL_HEIGHT).clamp(400, MAX_SIDE)));
    if height / panels_u32 < MIN_PANEL_HEIGHT {
        return Err(CliError::usage(format!(
            "{panels} measurements do not fit in {height} pixels ({MIN_PANEL_HEIGHT} each at least)"
        ))
        .hint("choose one with --measurement, or a taller --size"));
    }
    let times = || series.iter().flat_map(|s| &s.points).map(|(t, _)| *t);
    let (first, last) = (times().min().unwrap_or(from), times().max().unwrap_or(to));
    let name = args.range.db.file_name().map_or_else(|| db.to_string(), |n| n.to_string_lossy().into_owned());
    let title = format!("{name}: {} to {} UTC", time::rfc3339(first), time::rfc3339(last));
    let drawn = match format {
        Format::Png => {
            chart::draw(&BitMapBackend::new(&args.out, (width, height)).into_drawing_area(), &title, &series)
        }
        Format::Svg => chart::draw(&SVGBackend::new(&args.out, (width, height)).into_drawing_area(), &title, &series),
    };
    drawn.map_err(|e| CliError::device(format!("cannot write the chart {}: {e}", args.out.display())))?;
    let points: usize = series.iter().map(|s| s.points.len()).sum();
    let probes: BTreeSet<&str> = series.iter().map(|s| s.probe.as_str()).collect();
    writeln!(
        out,
        "wrote {} ({width}x{height}): {panels} measurement(s), {} probe(s), {points} values",
        args.out.display(),
        probes.len()
    )?;
    Ok(())
}

/// Refuses a probe label or measurement name the store has never held.
fn check_known(args: &PlotArgs, latest: &[Reading], readings: &[Reading]) -> Result<()> {
    let all = || latest.iter().chain(readings);
    if let Some(probe) = &args.probe {
        let labels: BTreeSet<&str> = all().map(|r| r.probe.as_str()).collect();
        if !labels.contains(probe.as_str()) {
            return Err(unknown("probe", probe, &labels, &args.range.db));
        }
    }
    if let Some(measurement) = &args.measurement {
        let names: BTreeSet<&str> = all()
            .filter(|r| args.probe.as_ref().is_none_or(|p| *p == r.probe))
            .flat_map(|r| &r.values)
            .map(|v| v.measurement.as_str())
            .collect();
        if !names.contains(measurement.as_str()) {
            return Err(unknown("measurement", measurement, &names, &args.range.db));
        }
    }
    Ok(())
}

fn unknown(what: &str, name: &str, known: &BTreeSet<&str>, db: &Path) -> CliError {
    let list = if known.is_empty() { "none".to_owned() } else { known.iter().copied().collect::<Vec<_>>().join(", ") };
    CliError::usage(format!("{} holds no {what} `{name}`", db.display())).hint(format!("known: {list}"))
}
