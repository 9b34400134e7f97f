//! The terminal view of `watch`: one box per probe with each measurement's
//! latest value, unit, age and a sparkline of its recent values, and the
//! probe's error and retry counts.
//!
//! Drawing is a [`Widget`] over a [`Snapshot`], so it renders into any
//! ratatui buffer (the terminal, or a test backend) and any size, down to
//! none: what does not fit is cut, never a panic.

use std::time::{Duration, SystemTime};

use ratatui::buffer::Buffer;
use ratatui::layout::Rect;
use ratatui::style::{Color, Modifier, Style};
use ratatui::text::{Line, Span};
use ratatui::widgets::{Block, Sparkline, SparklineBar, Widget};

use crate::format;
use crate::readings::{MeasurementStatus, ProbeStatus, Snapshot};
use crate::time;

/// Widest measurement-name column.
const NAME_WIDTH: usize = 24;
/// Widest value column.
const VALUE_WIDTH: usize = 12;
/// Widest unit column.
const UNIT_WIDTH: usize = 10;
/// Width of the age column (`59m 59s`).
const AGE_WIDTH: usize = 8;
/// Bar heights of a sparkline are scaled to SPARK_MIN..=SPARK_MAX.
const SPARK_MAX: u64 = 96;
/// The lowest bar: one eighth of a cell, so that the minimum still shows.
const SPARK_MIN: u64 = SPARK_MAX / 8;

/// What the view shows: the snapshot, where it came from, and when.
#[derive(Debug)]
pub struct Dashboard<'a> {
    /// The store, as the user named it.
    pub source: &'a str,
    /// The probes.
    pub snapshot: &'a Snapshot,
    /// The time the ages count from.
    pub now: SystemTime,
    /// How far back the sparklines and the error and retry counts reach.
    pub window: Duration,
    /// A problem refreshing the snapshot (the last good one is shown).
    pub status: Option<&'a str>,
}

impl Widget for &Dashboard<'_> {
    fn render(self, area: Rect, buf: &mut Buffer) {
        let area = area.intersection(buf.area);
        if area.is_empty() {
            return;
        }
        let header = Line::from(vec![
            Span::styled("yosemitech watch ", Style::new().add_modifier(Modifier::BOLD)),
            Span::raw(self.source),
        ]);
        header.render(row(area, 0), buf);
        // Drawn second, so that on a narrow terminal the clock and the way out win.
        let status =
            format!(" {} UTC · history and counts: last {} · q quits", time::clock(self.now), time::age(self.window));
        Line::raw(status).right_aligned().render(row(area, 0), buf);
        let mut y = 1;
        if let Some(status) = self.status {
            Line::styled(status.to_owned(), Style::new().fg(Color::Red)).render(row(area, y), buf);
            y += 1;
        }
        if self.snapshot.probes.is_empty() {
            Line::raw(format!("no readings yet in {}", self.source)).render(row(area, y), buf);
            return;
        }
        let columns = Columns::of(self.snapshot);
        for (shown, probe) in self.snapshot.probes.iter().enumerate() {
            let height = probe_height(probe);
            let left = area.height.saturating_sub(y);
            let others = self.snapshot.probes.len() - shown;
            // Keep the last row to say what is cut, unless this probe is the last one and fits.
            if height > left || (others > 1 && height == left) {
                let more = format!("… {others} more probe(s): enlarge the terminal");
                Line::styled(more, Style::new().fg(Color::Yellow)).render(row(area, y), buf);
                return;
            }
            let rect = Rect { x: area.x, y: area.y + y, width: area.width, height };
            render_probe(probe, &columns, self.now, rect, buf);
            y += height;
        }
    }
}

/// One line of `area`, empty when `area` has no such line.
fn row(area: Rect, y: u16) -> Rect {
    Rect { x: area.x, y: area.y.saturating_add(y), width: area.width, height: 1 }.intersection(area)
}

/// Rows a probe's box takes: borders, one per measurement, one for the last error.
fn probe_height(probe: &ProbeStatus) -> u16 {
    let lines = probe.measurements.len().max(1) + usize::from(probe.last_error.is_some()) + 2;
    u16::try_from(lines).unwrap_or(u16::MAX)
}

/// Column widths shared by every probe's box, so the values line up.
struct Columns {
    name: usize,
    value: usize,
    unit: usize,
}

impl Columns {
    fn of(snapshot: &Snapshot) -> Self {
        let all = || snapshot.probes.iter().flat_map(|p| &p.measurements);
        let name = all().map(|m| m.name.chars().count()).max().unwrap_or(0).min(NAME_WIDTH);
        let value = all().map(|m| value_text(m).chars().count()).max().unwrap_or(0).min(VALUE_WIDTH);
        let unit = all().map(|m| format::unit(&m.unit).chars().count()).max().unwrap_or(0).min(UNIT_WIDTH);
        Self { name, value, unit }
    }
}

fn render_probe(probe: &ProbeStatus, columns: &Columns, now: SystemTime, area: Rect, buf: &mut Buffer) {
    let mut title = format!(" {} · {}", probe.label, probe.sensor);
    if let Some(serial) = &probe.serial {
        title.push_str(&format!(" · SN {serial}"));
    }
    title.push(' ');
    let counts_style = if probe.errors > 0 { Style::new().fg(Color::Red) } else { Style::new() };
    let counts = Line::styled(format!(" errors {} · retries {} ", probe.errors, probe.retries), counts_style);
    let block = Block::bordered()
        .title(Line::styled(title, Style::new().add_modifier(Modifier::BOLD)))
        .title(counts.right_aligned());
    let inner = block.inner(area);
    block.render(area, buf);
    if probe.measurements.is_empty() {
        let text = match probe.last_visit {
            Some(at) => format!("no values yet (last visit {} ago)", age(now, at)),
            None => "no values yet".to_owned(),
        };
        Line::raw(text).render(row(inner, 0), buf);
    }
    let mut y = 0;
    for m in &probe.measurements {
        render_measurement(m, columns, now, row(inner, y), buf);
        y += 1;
    }
    if let Some(error) = &probe.last_error {
        Line::styled(format!("last visit failed: {error}"), Style::new().fg(Color::Red)).render(row(inner, y), buf);
    }
}

fn render_measurement(m: &MeasurementStatus, columns: &Columns, now: SystemTime, line: Rect, buf: &mut Buffer) {
    if line.is_empty() {
        return;
    }
    let age = m.latest.map(|(at, _)| age(now, at)).unwrap_or_default();
    let text = format!(
        "{:<nw$}  {:>vw$} {:<uw$}  {:>aw$}  ",
        clip(&m.name, columns.name),
        clip(&value_text(m), columns.value),
        clip(format::unit(&m.unit), columns.unit),
        age,
        nw = columns.name,
        vw = columns.value,
        uw = columns.unit,
        aw = AGE_WIDTH,
    );
    let used = u16::try_from(text.chars().count()).unwrap_or(u16::MAX);
    Line::raw(text).render(line, buf);
    let spark =
        Rect { x: line.x.saturating_add(used), width: line.width.saturating_sub(used), ..line }.intersection(line);
    if !spark.is_empty() {
        let bars = sparkline_bars(&m.history, usize::from(spark.width));
        Sparkline::default().data(bars).max(SPARK_MAX).style(Style::new().fg(Color::Cyan)).render(spark, buf);
    }
}

/// The latest value, `—` before the first one.
fn value_text(m: &MeasurementStatus) -> String {
    m.latest.map_or_else(|| "—".to_owned(), |(_, v)| format_value(v))
}

/// A value with four significant digits (at most four decimals); NaN and
/// infinities as words.
pub fn format_value(v: f64) -> String {
    if v.is_nan() {
        return "NaN".to_owned();
    }
    if v.is_infinite() {
        return if v > 0.0 { "inf" } else { "-inf" }.to_owned();
    }
    let magnitude = if v == 0.0 { 0 } else { v.abs().log10().floor() as i32 };
    let decimals = (3 - magnitude).clamp(0, 4) as usize;
    format!("{v:.decimals$}")
}

fn age(now: SystemTime, at: SystemTime) -> String {
    time::age(now.duration_since(at).unwrap_or_default())
}

/// The first `width` characters of `text`.
fn clip(text: &str, width: usize) -> String {
    text.chars().take(width).collect()
}

/// The last `width` values as bars scaled between their finite minimum and
/// maximum, the lowest still visible (a flat line at half height when they
/// are equal); NaN and infinities are absent bars.
fn sparkline_bars(history: &[f64], width: usize) -> Vec<SparklineBar> {
    let recent = &history[history.len().saturating_sub(width)..];
    let finite = || recent.iter().copied().filter(|v| v.is_finite());
    let low = finite().fold(f64::INFINITY, f64::min);
    let high = finite().fold(f64::NEG_INFINITY, f64::max);
    recent
        .iter()
        .map(|&v| {
            if !v.is_finite() {
                return SparklineBar::from(None);
            }
            let fraction = if high > low { (v - low) / (high - low) } else { 0.5 };
            let height = SPARK_MIN as f64 + fraction * (SPARK_MAX - SPARK_MIN) as f64;
            SparklineBar::from(Some(height.round() as u64))
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use std::time::UNIX_EPOCH;

    use ratatui::Terminal;
    use ratatui::backend::TestBackend;

    use super::*;

    fn snapshot() -> Snapshot {
        let at = UNIX_EPOCH + Duration::from_secs(1_000);
        let measurement = |name: &str, unit: &str, history: Vec<f64>| MeasurementStatus {
            name: name.into(),
            unit: unit.into(),
            latest: history.last().map(|v| (at, *v)),
            history,
        };
        Snapshot {
            probes: vec![
                ProbeStatus {
                    label: "river-left".into(),
                    sensor: "sensor_a".into(),
                    serial: Some("ABC123".into()),
                    last_visit: Some(at),
                    measurements: vec![
                        measurement("alpha", "mg/L", vec![1.0, 2.0, 3.0, 2.5]),
                        measurement("beta", "", vec![f64::NAN, 5.0, f64::NAN]),
                    ],
                    errors: 3,
                    retries: 7,
                    last_error: Some("no reply".into()),
                },
                ProbeStatus {
                    label: "outfall".into(),
                    sensor: "sensor_b".into(),
                    serial: None,
                    last_visit: None,
                    measurements: Vec::new(),
                    errors: 0,
                    retries: 0,
                    last_error: None,
                },
            ],
        }
    }

    fn draw(snapshot: &Snapshot, width: u16, height: u16) -> String {
        let now = UNIX_EPOCH + Duration::from_secs(1_065);
        let view = Dashboard { source: "station.db", snapshot, now, window: Duration::from_secs(3600), status: None };
        let mut terminal = Terminal::new(TestBackend::new(width, height)).unwrap();
        terminal.draw(|f| f.render_widget(&view, f.area())).unwrap();
        let buffer = terminal.backend().buffer();
        let mut text = String::new();
        for y in 0..buffer.area.height {
            for x in 0..buffer.area.width {
                text.push_str(buffer[(x, y)].symbol());
            }
            text.push('\n');
        }
        text
    }

    #[test]
    fn shows_every_probe_value_unit_age_and_counts() {
        let screen = draw(&snapshot(), 100, 20);
        for expected in [
            "river-left · sensor_a · SN ABC123",
            "errors 3 · retries 7",
            "2.500 mg/L ",
            "1m 05s",
            "NaN",
            "last visit failed: no reply",
            "outfall · sensor_b",
            "last 1h 00m",
            "no values yet",
        ] {
            assert!(screen.contains(expected), "`{expected}` missing from\n{screen}");
        }
        // The sparkline draws 1, 2, 3, 2.5 as four bars of three heights or more, the lowest visible.
        let alpha = screen.lines().find(|l| l.contains("alpha")).unwrap();
        let bars: Vec<char> = alpha.chars().filter(|c| ('▁'..='█').contains(c)).collect();
        assert_eq!(bars.len(), 4, "sparkline {bars:?} in {alpha}");
        assert!(bars.iter().collect::<std::collections::BTreeSet<_>>().len() >= 3, "sparkline {bars:?}");
    }

    #[test]
    fn an_empty_store_says_so() {
        let screen = draw(&Snapshot::default(), 60, 5);
        assert!(screen.contains("no readings yet in station.db"), "{screen}");
    }

    #[test]
    fn what_does_not_fit_is_counted() {
        let screen = draw(&snapshot(), 80, 7);
        assert!(screen.contains("river-left"), "{screen}");
        assert!(screen.contains("… 1 more probe(s)"), "{screen}");
    }

    #[test]
    fn any_size_renders_without_panicking() {
        let snap = snapshot();
        for width in 0..30 {
            for height in 0..12 {
                draw(&snap, width, height);
            }
        }
    }

    #[test]
    fn values_have_four_significant_digits() {
        assert_eq!(format_value(7.01234), "7.012");
        assert_eq!(format_value(1234.56), "1235");
        assert_eq!(format_value(0.000123), "0.0001");
        assert_eq!(format_value(0.0), "0.000");
        assert_eq!(format_value(-12.5), "-12.50");
        assert_eq!(format_value(f64::NEG_INFINITY), "-inf");
    }

    #[test]
    fn sparkline_scales_finite_values_and_leaves_gaps() {
        let bars = sparkline_bars(&[0.0, f64::NAN, 10.0, 5.0], 3);
        assert_eq!(
            bars,
            [SparklineBar::from(None), SparklineBar::from(Some(SPARK_MAX)), SparklineBar::from(Some(SPARK_MIN))]
        );
        assert_eq!(sparkline_bars(&[2.0, 2.0], 10), [SparklineBar::from(Some((SPARK_MIN + SPARK_MAX) / 2)); 2]);
        assert!(sparkline_bars(&[1.0], 0).is_empty());
    }
}
