//! The chart of `plot`: one panel per measurement (and unit), one line per
//! probe, over a shared UTC time axis, on any plotters backend (PNG and SVG
//! files here).
//!
//! Text is drawn with DejaVu Sans compiled into the binary (plotters'
//! `ab_glyph` feature), so a chart needs no system fonts.

use std::sync::OnceLock;
use std::time::{Duration, SystemTime, UNIX_EPOCH};

use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::FontStyle;

use crate::format;
use crate::readings::Series;
use crate::time;

/// The font family every text element names.
const FONT: &str = "sans-serif";

/// Line colours, one per probe in label order (Tableau 10: distinct on white
/// and for the common colour blindnesses).
const COLOURS: [RGBColor; 10] = [
    RGBColor(31, 119, 180),
    RGBColor(255, 127, 14),
    RGBColor(44, 160, 44),
    RGBColor(214, 39, 40),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
    RGBColor(227, 119, 194),
    RGBColor(127, 127, 127),
    RGBColor(188, 189, 34),
    RGBColor(23, 190, 207),
];

/// The smallest panel height, in pixels, that still shows a readable chart.
pub const MIN_PANEL_HEIGHT: u32 = 90;

/// Registers the embedded font once; an error if the font does not load.
fn register_font() -> Result<(), String> {
    static REGISTERED: OnceLock<bool> = OnceLock::new();
    let ok = *REGISTERED
        .get_or_init(|| plotters::style::register_font(FONT, FontStyle::Normal, dejavu::sans::regular()).is_ok());
    if ok { Ok(()) } else { Err("the embedded chart font does not load".to_owned()) }
}

/// The panels of a chart: each measurement (with its unit) in the order it
/// first appears, and the series that show it.
pub fn panels(series: &[Series]) -> Vec<Vec<&Series>> {
    let mut panels: Vec<Vec<&Series>> = Vec::new();
    for s in series {
        match panels.iter_mut().find(|p| p[0].measurement == s.measurement && p[0].unit == s.unit) {
            Some(panel) => panel.push(s),
            None => panels.push(vec![s]),
        }
    }
    panels
}

/// Draws `series` under `title` on `root` and presents it (writes the file).
/// Non-finite values break a line instead of stretching its axis.
pub fn draw<DB: DrawingBackend>(root: &DrawingArea<DB, Shift>, title: &str, series: &[Series]) -> Result<(), String> {
    register_font()?;
    let failed = |e: DrawingAreaErrorKind<DB::ErrorType>| e.to_string();
    root.fill(&WHITE).map_err(failed)?;
    let body = root.titled(title, (FONT, 20)).map_err(failed)?;
    let panels = panels(series);
    if panels.is_empty() {
        return Err("nothing to draw".to_owned());
    }
    let mut probes: Vec<&str> = series.iter().map(|s| s.probe.as_str()).collect();
    probes.sort_unstable();
    probes.dedup();
    let colour = |probe: &str| COLOURS[probes.iter().position(|p| *p == probe).unwrap_or(0) % COLOURS.len()];
    let (start, end) = time_range(series);
    let span = end - start;
    let label_time = move |x: &f64| {
        let t = UNIX_EPOCH + Duration::from_secs_f64(x.max(0.0));
        if span > 2.0 * 86_400.0 {
            time::day_minute(t)
        } else if span > 600.0 {
            time::minute(t)
        } else {
            time::clock(t)
        }
    };
    for (area, panel) in body.split_evenly((panels.len(), 1)).iter().zip(&panels) {
        let (low, high) = value_range(panel);
        let first = panel[0];
        let caption = if first.unit.is_empty() {
            first.measurement.clone()
        } else {
            format!("{} ({})", first.measurement, format::unit(&first.unit))
        };
        let mut chart = ChartBuilder::on(area)
            .caption(caption, (FONT, 16))
            .margin(8)
            .x_label_area_size(24)
            .y_label_area_size(64)
            .build_cartesian_2d(start..end, low..high)
            .map_err(failed)?;
        chart
            .configure_mesh()
            .x_labels(6)
            .y_labels(5)
            .x_label_formatter(&label_time)
            .label_style((FONT, 12))
            .light_line_style(RGBColor(235, 235, 235))
            .draw()
            .map_err(failed)?;
        let columns = usize::try_from(chart.plotting_area().dim_in_pixel().0).unwrap_or(usize::MAX).max(1);
        for s in panel {
            let style = colour(&s.probe).stroke_width(2);
            for (i, run) in finite_runs(&s.points).into_iter().enumerate() {
                let run = envelope(run, (start, end), columns);
                let drawn = if run.len() == 1 {
                    chart.draw_series(run.iter().map(|&p| Circle::new(p, 3, style.filled()))).map_err(failed)?
                } else {
                    chart.draw_series(LineSeries::new(run, style)).map_err(failed)?
                };
                if i == 0 {
                    drawn
                        .label(s.probe.as_str())
                        .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], style));
                }
            }
        }
        chart
            .configure_series_labels()
            .label_font((FONT, 12))
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK)
            .position(SeriesLabelPosition::UpperRight)
            .draw()
            .map_err(failed)?;
    }
    root.present().map_err(failed)
}

/// Seconds since 1970 of every point, as the x axis: never empty.
fn time_range(series: &[Series]) -> (f64, f64) {
    let seconds = |t: &SystemTime| t.duration_since(UNIX_EPOCH).unwrap_or_default().as_secs_f64();
    let all = || series.iter().flat_map(|s| &s.points).map(|(t, _)| seconds(t));
    let start = all().fold(f64::INFINITY, f64::min);
    let end = all().fold(f64::NEG_INFINITY, f64::max);
    widen(start, end, 30.0)
}

/// The finite values of a panel, with a margin: never empty.
fn value_range(panel: &[&Series]) -> (f64, f64) {
    let all = || panel.iter().flat_map(|s| &s.points).map(|(_, v)| *v).filter(|v| v.is_finite());
    let low = all().fold(f64::INFINITY, f64::min);
    let high = all().fold(f64::NEG_INFINITY, f64::max);
    let margin = (high - low) * 0.05;
    widen(low - margin, high + margin, low.abs().max(1.0) * 0.05)
}

/// `(low, high)`, or `pad` either side when they are equal, or `0..1` when
/// there is nothing finite.
fn widen(low: f64, high: f64, pad: f64) -> (f64, f64) {
    if !low.is_finite() || !high.is_finite() {
        (0.0, 1.0)
    } else if high > low {
        (low, high)
    } else {
        (low - pad, high + pad)
    }
}

/// The runs of consecutive finite points, as chart coordinates.
fn finite_runs(points: &[(SystemTime, f64)]) -> Vec<Vec<(f64, f64)>> {
    let mut runs = vec![Vec::new()];
    for (t, v) in points {
        if v.is_finite() {
            let x = t.duration_since(UNIX_EPOCH).unwrap_or_default().as_secs_f64();
            if let Some(run) = runs.last_mut() {
                run.push((x, *v));
            }
        } else if runs.last().is_some_and(|run| !run.is_empty()) {
            runs.push(Vec::new());
        }
    }
    runs.retain(|run| !run.is_empty());
    runs
}

/// At most the lowest and the highest point of each of `columns` equal
/// slices of `span` (in time order): the line a pixel column can show,
/// however many points fall into it. Runs that fit are kept whole.
fn envelope(run: Vec<(f64, f64)>, span: (f64, f64), columns: usize) -> Vec<(f64, f64)> {
    if run.len() <= 2 * columns {
        return run;
    }
    let width = (span.1 - span.0) / columns as f64;
    let column = |x: f64| if width > 0.0 { ((x - span.0) / width) as usize } else { 0 };
    let mut kept: Vec<(f64, f64)> = Vec::with_capacity(2 * columns + 2);
    let mut slice = run.iter().copied().peekable();
    while let Some(first) = slice.next() {
        let c = column(first.0);
        let (mut low, mut high) = (first, first);
        while let Some(&p) = slice.peek().filter(|p| column(p.0) == c) {
            slice.next();
            if p.1 < low.1 {
                low = p;
            }
            if p.1 > high.1 {
                high = p;
            }
        }
        if low.0 <= high.0 {
            kept.extend([low, high]);
        } else {
            kept.extend([high, low]);
        }
        kept.dedup();
    }
    kept
}

#[cfg(test)]
mod tests {
    use super::*;

    fn at(secs: u64) -> SystemTime {
        UNIX_EPOCH + Duration::from_secs(secs)
    }

    fn wave(probe: &str, measurement: &str, unit: &str, phase: f64) -> Series {
        let points = (0..200u32)
            .map(|i| {
                let v = if i % 50 == 25 { f64::NAN } else { (f64::from(i) / 20.0 + phase).sin() * 3.0 + 7.0 };
                (at(1_700_000_000 + u64::from(i) * 60), v)
            })
            .collect();
        Series { probe: probe.into(), measurement: measurement.into(), unit: unit.into(), points }
    }

    #[test]
    fn draws_a_png_of_the_stated_size_with_every_probe_colour() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("chart.png");
        let series = [wave("a", "m1", "u", 0.0), wave("b", "m1", "u", 1.0), wave("a", "m2", "", 2.0)];
        let root = BitMapBackend::new(&path, (640, 480)).into_drawing_area();
        draw(&root, "title", &series).unwrap();
        drop(root);
        let decoder = png::Decoder::new(std::io::BufReader::new(std::fs::File::open(&path).unwrap()));
        let mut reader = decoder.read_info().unwrap();
        let mut pixels = vec![0; reader.output_buffer_size()];
        let frame = reader.next_frame(&mut pixels).unwrap();
        assert_eq!((frame.width, frame.height), (640, 480));
        assert_eq!(frame.color_type, png::ColorType::Rgb);
        let has = |c: RGBColor| pixels.chunks(3).any(|p| p == [c.0, c.1, c.2]);
        assert!(has(COLOURS[0]) && has(COLOURS[1]), "a line colour is missing");
    }

    #[test]
    fn non_finite_values_split_lines() {
        let points = [(at(1), 1.0), (at(2), f64::NAN), (at(3), 3.0), (at(4), 4.0), (at(5), f64::INFINITY)];
        assert_eq!(finite_runs(&points), [vec![(1.0, 1.0)], vec![(3.0, 3.0), (4.0, 4.0)]]);
        assert!(finite_runs(&[(at(1), f64::NAN)]).is_empty());
    }

    #[test]
    fn long_runs_keep_each_columns_extremes_in_time_order() {
        let run: Vec<(f64, f64)> = (0..10_000u32).map(|i| (f64::from(i), (f64::from(i) / 7.0).sin())).collect();
        let kept = envelope(run.clone(), (0.0, 10_000.0), 100);
        assert!(kept.len() <= 200 && kept.len() >= 100, "{} points kept", kept.len());
        assert!(kept.windows(2).all(|w| w[0].0 < w[1].0), "time order");
        for c in 0..100 {
            let column = |p: &&(f64, f64)| (p.0 / 100.0) as usize == c;
            let extreme = |f: fn(f64, f64) -> f64, points: &[(f64, f64)]| {
                points.iter().filter(column).map(|p| p.1).fold(f64::NAN, f)
            };
            assert_eq!(extreme(f64::min, &kept), extreme(f64::min, &run), "column {c}");
            assert_eq!(extreme(f64::max, &kept), extreme(f64::max, &run), "column {c}");
        }
        let short = run[..150].to_vec();
        assert_eq!(envelope(short.clone(), (0.0, 150.0), 100), short);
    }

    #[test]
    fn ranges_are_never_empty() {
        assert_eq!(widen(f64::INFINITY, f64::NEG_INFINITY, 1.0), (0.0, 1.0));
        assert_eq!(widen(5.0, 5.0, 1.0), (4.0, 6.0));
        let flat =
            Series { probe: "p".into(), measurement: "m".into(), unit: String::new(), points: vec![(at(9), 0.0)] };
        let (low, high) = value_range(&[&flat]);
        assert!(low < 0.0 && high > 0.0);
        let (start, end) = time_range(&[flat]);
        assert!(start < 9.0 && end > 9.0);
    }
}
