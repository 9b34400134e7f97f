//! `plot` and `watch` against real SQLite stores written through the
//! station's `Store`: the chart files decode as images of the stated size
//! that are not blank, and `watch` runs in a real terminal (tmux) showing
//! every probe's label and latest values, and quits on `q`.
//!
//! The probes' sensors and measurements come from the spec: the first
//! sensors with a measurement read (`Sensor::measurement_reads`) of numbers.

use std::collections::BTreeSet;
use std::io::{self, Write as _};
use std::path::{Path, PathBuf};
use std::process::Command;
use std::thread;
use std::time::{Duration, Instant, SystemTime};

use yosemitech_tests::cli::{Binary, Run};
use yosemitech_tests::{report, spec};

/// The binary under test.
const YOSEMITECH: Binary = Binary(env!("CARGO_BIN_EXE_yosemitech"));

/// Runs the binary with `args`.
fn yosemitech(args: &[&str]) -> Run {
    YOSEMITECH.run(args)
}
use yosemitech_spec::FieldKind;
use yosemitech_station::{Datum, Measurement, Reading, Store};

/// Probes in the test station.
const PROBES: usize = 3;
/// Readings per probe, one a minute up to now.
const READINGS: u32 = 60;
/// Longest wait for the terminal to show something or the binary to exit.
const SCREEN_DEADLINE: Duration = Duration::from_secs(30);

/// A probe of the test station.
struct Probe {
    label: String,
    sensor: String,
    /// (measurement, unit) of a read of the sensor's spec.
    measurements: Vec<(String, Option<String>)>,
}

/// A store of `PROBES` probes of different sensors, each with `READINGS`
/// readings; the last reading's value of measurement `m` of probe `p` is
/// [`latest`]`(p, m)`. The first probe's last visit failed.
///
/// No value is NaN: the store keeps a NaN as NULL and then refuses the
/// reading as malformed (the views' handling of NaN is tested on their own).
struct Station {
    _dir: tempfile::TempDir,
    db: PathBuf,
    probes: Vec<Probe>,
}

/// The newest value of measurement `m` of probe `p`: between 10 and 100, so
/// the view shows it with two decimals.
fn latest(p: usize, m: usize) -> f64 {
    10.25 + 20.0 * p as f64 + m as f64
}

/// A sensor's measurements: name and unit.
type Measurements = Vec<(String, Option<String>)>;

/// The probes: the spec's first sensors with a measurement read of f32
/// fields, its fields their measurements (the views draw any numbers the
/// store holds, whatever the sensor). A spec with fewer such sensors than
/// probes lends them to several probes; one with none, a made-up sensor.
fn probes() -> Vec<Probe> {
    let sensors: Vec<(String, Measurements)> = spec()
        .sensors
        .iter()
        .filter_map(|sensor| {
            let read = sensor.measurement_reads().find(|c| {
                c.named_fields().count() > 0 && c.named_fields().all(|f| matches!(f.kind, FieldKind::F32 { .. }))
            })?;
            let measurements = read.named_fields().map(|f| (f.display_name().to_owned(), f.unit.clone())).collect();
            Some((sensor.name.clone(), measurements))
        })
        .take(PROBES)
        .collect();
    if sensors.len() < PROBES {
        report!("{} sensors of the spec have a measurement read of numbers, for {PROBES} probes", sensors.len());
    }
    let sensors = if sensors.is_empty() {
        vec![("made_up_probe".to_owned(), vec![("level".to_owned(), Some("m".to_owned()))])]
    } else {
        sensors
    };
    (0..PROBES)
        .map(|i| {
            let (sensor, measurements) = sensors[i % sensors.len()].clone();
            Probe { label: format!("site{i}-{sensor}"), sensor, measurements }
        })
        .collect()
}

impl Station {
    fn new() -> Self {
        let station = Self::empty();
        let now = SystemTime::now();
        let mut store = Store::open(&station.db).unwrap();
        for (p, probe) in station.probes.iter().enumerate() {
            for n in 0..READINGS {
                let at = now - Duration::from_secs(60 * u64::from(READINGS - n));
                let last = n == READINGS - 1;
                let values = probe
                    .measurements
                    .iter()
                    .enumerate()
                    .map(|(m, (name, unit))| {
                        let value = if last { latest(p, m) } else { latest(p, m) + (f64::from(n) / 5.0).sin() * 5.0 };
                        Measurement {
                            name: name.clone(),
                            value: Datum::Number(value),
                            unit: unit.clone(),
                            derived: false,
                        }
                    })
                    .collect();
                store.insert(&reading(probe, at, values, None)).unwrap();
            }
        }
        store.insert(&reading(&station.probes[0], now, Vec::new(), Some("no reply"))).unwrap();
        station
    }

    /// A store with its schema and no reading.
    fn empty() -> Self {
        let dir = tempfile::tempdir().unwrap();
        let db = dir.path().join("station.sqlite");
        drop(Store::open(&db).unwrap());
        Self { _dir: dir, db, probes: probes() }
    }

    fn db(&self) -> &str {
        self.db.to_str().unwrap()
    }

    /// The distinct measurements of the probes: the panels of a chart of them all.
    fn measurements(&self) -> usize {
        self.probes.iter().flat_map(|p| &p.measurements).map(|(m, _)| m.as_str()).collect::<BTreeSet<_>>().len()
    }

    fn out(&self, name: &str) -> PathBuf {
        self.db.with_file_name(name)
    }
}

fn reading(probe: &Probe, at: SystemTime, values: Vec<Measurement>, error: Option<&str>) -> Reading {
    Reading {
        timestamp: at,
        station: "test".into(),
        bus: "bus0".into(),
        probe: probe.label.clone(),
        sensor: probe.sensor.clone(),
        address: 1,
        serial_number: Some(format!("SN-{}", probe.label)),
        firmware: None,
        values,
        retries: u32::from(error.is_some()),
        error: error.map(Into::into),
    }
}

/// A chart height of at least `height` pixels with room for `panels`
/// measurements (`plot` wants 90 pixels each; 100 leaves a margin).
fn tall_enough(height: u32, panels: usize) -> u32 {
    height.max(100 * panels as u32)
}

/// The decoded PNG: width, height and RGB(A) pixels.
fn decode_png(path: &Path) -> (u32, u32, usize, Vec<u8>) {
    let file = std::fs::File::open(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let mut reader = png::Decoder::new(std::io::BufReader::new(file)).read_info().expect("a PNG");
    let mut pixels = vec![0; reader.output_buffer_size()];
    let frame = reader.next_frame(&mut pixels).expect("PNG pixels");
    pixels.truncate(frame.buffer_size());
    (frame.width, frame.height, frame.color_type.samples(), pixels)
}

#[test]
fn plot_png_has_the_stated_size_and_is_not_blank() {
    let station = Station::new();
    let out = station.out("chart.png");
    let measurements = station.measurements();
    let tall = tall_enough(700, measurements);
    let size = format!("900x{tall}");
    let run = yosemitech(&["plot", "--db", station.db(), "--out", out.to_str().unwrap(), "--size", &size]);
    let expected = format!("({size}): {measurements} measurement(s), {PROBES} probe(s)");
    assert!(run.ok().contains(&expected), "`{expected}` not in {}", run.stdout);
    let (width, height, samples, pixels) = decode_png(&out);
    assert_eq!((width, height), (900, tall));
    let colours: BTreeSet<&[u8]> = pixels.chunks(samples).collect();
    let white = pixels.chunks(samples).filter(|p| p.iter().take(3).all(|c| *c == 255)).count();
    let drawn = pixels.len() / samples - white;
    assert!(colours.len() >= 8, "{} distinct colours", colours.len());
    // Lines, axes and text cover more than 1% of the picture, and far from all of it.
    let total = (width * height) as usize;
    assert!(drawn * 100 > total && drawn * 2 < total, "{drawn} of {total} pixels drawn");
}

#[test]
fn plot_svg_parses_with_the_stated_size_and_names_every_probe() {
    let station = Station::new();
    let out = station.out("chart.svg");
    let tall = tall_enough(1500, station.measurements());
    let size = format!("1000x{tall}");
    yosemitech(&["plot", "--db", station.db(), "--out", out.to_str().unwrap(), "--size", &size]).ok();
    let text = std::fs::read_to_string(&out).unwrap();
    let doc = roxmltree::Document::parse(&text).expect("the SVG is XML");
    let root = doc.root_element();
    assert_eq!(root.tag_name().name(), "svg");
    assert_eq!((root.attribute("width"), root.attribute("height")), (Some("1000"), Some(tall.to_string().as_str())));
    let lines = doc.descendants().filter(|n| n.has_tag_name("polyline")).count();
    let series: usize = station.probes.iter().map(|p| p.measurements.len()).sum();
    // A line per series, and one per legend sample.
    assert!(lines >= 2 * series, "{lines} polylines for {series} series");
    let texts: String = doc.descendants().filter_map(|n| n.text()).collect::<Vec<_>>().join("\n");
    for probe in &station.probes {
        assert!(texts.contains(&probe.label), "no `{}` in the chart's text", probe.label);
    }
}

#[test]
fn plot_chooses_a_probe_and_a_measurement() {
    let station = Station::new();
    let probe = &station.probes[1];
    let (measurement, _) = &probe.measurements[0];
    let out = station.out("one.svg");
    let run = yosemitech(&[
        "plot",
        "--db",
        station.db(),
        "--probe",
        &probe.label,
        "--measurement",
        measurement,
        "--from",
        "2h",
        "--out",
        out.to_str().unwrap(),
    ]);
    let said = run.ok();
    let expected = format!("1 measurement(s), 1 probe(s), {READINGS} values");
    assert!(said.contains(&expected), "`{expected}` not in {said}");
    let text = std::fs::read_to_string(&out).unwrap();
    assert!(text.contains(&probe.label));
    for other in station.probes.iter().filter(|p| p.label != probe.label) {
        assert!(!text.contains(&other.label), "{} is drawn", other.label);
    }
}

#[test]
fn plot_refuses_with_a_reason_and_an_exit_code() {
    let station = Station::new();
    let db = station.db();
    let png = station.out("x.png");
    let png = png.to_str().unwrap();
    let cases: [(&[&str], i32, &str); 7] = [
        (&["--from", "2000-01-01", "--to", "2000-01-02"], 1, "no readings in"),
        (&["--probe", "no-such-probe"], 2, "no probe `no-such-probe`"),
        (&["--measurement", "no_such_measurement"], 2, "no measurement `no_such_measurement`"),
        (&["--size", "12x7"], 2, "12x7"),
        (&["--size", "wide"], 2, "wide"),
        (&["--from", "1h", "--to", "2h"], 2, "--from is not before --to"),
        (&["--from", "yesterday"], 2, "yesterday"),
    ];
    for (args, code, message) in cases {
        let mut all = vec!["plot", "--db", db, "--out", png];
        all.extend_from_slice(args);
        let run = yosemitech(&all);
        let stderr = run.fails(code);
        assert!(stderr.contains(message), "{args:?}: `{message}` not in\n{stderr}");
        assert!(!Path::new(png).exists(), "{args:?} wrote a chart");
    }
    let unknown = yosemitech(&["plot", "--db", db, "--probe", "no-such-probe", "--out", png]);
    for probe in &station.probes {
        assert!(unknown.stderr.contains(&probe.label), "the known probes are listed:\n{}", unknown.stderr);
    }
    yosemitech(&["plot", "--db", db, "--out", station.out("x.jpg").to_str().unwrap()]).fails(2);
    let missing = station.out("missing.sqlite");
    yosemitech(&["plot", "--db", missing.to_str().unwrap(), "--out", png]).fails_with_hint(2);
    assert!(!missing.exists(), "plot created a store");
    let empty = Station::empty();
    let stderr = yosemitech(&["plot", "--db", empty.db(), "--out", png]).fails_with_hint(1).to_owned();
    assert!(stderr.contains("holds no readings yet"), "{stderr}");
}

/// A tmux server of the test's own (its socket in a temporary directory),
/// killed when dropped.
struct Tmux {
    socket: PathBuf,
    _dir: tempfile::TempDir,
}

impl Tmux {
    /// A server, or `None` (the test skips) when tmux is not installed and
    /// `YOSEMITECH_REQUIRE_TMUX=1` does not demand it (CI sets it).
    fn start() -> Option<Self> {
        if Command::new("tmux").arg("-V").output().is_err() {
            assert!(
                std::env::var_os("YOSEMITECH_REQUIRE_TMUX").is_none_or(|v| v != "1"),
                "YOSEMITECH_REQUIRE_TMUX=1 and tmux is not installed"
            );
            // Straight to the process's stderr, so that the skip shows in `cargo test` output.
            let _ =
                writeln!(io::stderr(), "    skipped: tmux is not installed (YOSEMITECH_REQUIRE_TMUX=1 fails instead)");
            return None;
        }
        let dir = tempfile::tempdir().unwrap();
        Some(Self { socket: dir.path().join("tmux.sock"), _dir: dir })
    }

    fn tmux(&self, args: &[&str]) -> std::process::Output {
        Command::new("tmux").arg("-S").arg(&self.socket).args(args).output().expect("tmux runs")
    }

    /// Runs `yosemitech watch --db DB` in a detached `width`x`height`
    /// session; its exit code goes to the returned file.
    fn watch(&self, db: &str, width: u16, height: u16) -> PathBuf {
        let status = self.socket.with_file_name("status");
        let script = format!(
            "'{}' watch --db '{db}' --interval 300ms; echo $? > '{}'",
            env!("CARGO_BIN_EXE_yosemitech"),
            status.display()
        );
        let (w, h) = (width.to_string(), height.to_string());
        let out = self.tmux(&["new-session", "-d", "-s", "watch", "-x", &w, "-y", &h, &script]);
        assert!(out.status.success(), "tmux new-session: {}", String::from_utf8_lossy(&out.stderr));
        status
    }

    fn screen(&self) -> String {
        String::from_utf8_lossy(&self.tmux(&["capture-pane", "-p", "-t", "watch"]).stdout).into_owned()
    }

    /// The screen once it shows every one of `expected`.
    fn screen_showing(&self, expected: &[String]) -> String {
        let deadline = Instant::now() + SCREEN_DEADLINE;
        loop {
            let screen = self.screen();
            if expected.iter().all(|e| screen.contains(e.as_str())) {
                return screen;
            }
            let missing: Vec<&String> = expected.iter().filter(|e| !screen.contains(e.as_str())).collect();
            assert!(Instant::now() < deadline, "{missing:?} never shown; the screen:\n{screen}");
            thread::sleep(Duration::from_millis(100));
        }
    }

    /// Sends `key` (in tmux's notation) and returns the exit code of `watch`.
    fn quit(&self, status: &Path, key: &str) -> String {
        self.tmux(&["send-keys", "-t", "watch", key]);
        let deadline = Instant::now() + SCREEN_DEADLINE;
        loop {
            if let Ok(code) = std::fs::read_to_string(status) {
                return code.trim().to_owned();
            }
            assert!(Instant::now() < deadline, "watch did not exit on {key}; the screen:\n{}", self.screen());
            thread::sleep(Duration::from_millis(100));
        }
    }
}

impl Drop for Tmux {
    fn drop(&mut self) {
        let _ = self.tmux(&["kill-server"]);
    }
}

#[test]
fn watch_in_a_terminal_shows_every_probe_and_quits_on_q() {
    let Some(tmux) = Tmux::start() else { return };
    let station = Station::new();
    let status = tmux.watch(station.db(), 160, 60);
    let mut expected = Vec::new();
    for (p, probe) in station.probes.iter().enumerate() {
        expected.push(probe.label.clone());
        expected.push(format!("SN SN-{}", probe.label));
        for (m, (name, _)) in probe.measurements.iter().enumerate() {
            expected.push(name.clone());
            expected.push(format!("{:.2}", latest(p, m)));
        }
    }
    expected.push("errors 1 · retries 1".into());
    expected.push("last visit failed: no reply".into());
    let screen = tmux.screen_showing(&expected);
    assert!(screen.contains("errors 0"), "the other probes have no errors:\n{screen}");
    assert_eq!(tmux.quit(&status, "q"), "0", "watch's exit code");
    let gone = tmux.tmux(&["has-session", "-t", "watch"]);
    assert!(!gone.status.success(), "the session outlived watch");
}

#[test]
fn watch_shows_an_empty_store_survives_a_tiny_terminal_and_quits_on_ctrl_c() {
    let Some(tmux) = Tmux::start() else { return };
    let station = Station::empty();
    let status = tmux.watch(station.db(), 100, 20);
    tmux.screen_showing(&["no readings yet".to_owned()]);
    for (w, h) in [("8", "2"), ("1", "1"), ("100", "20")] {
        let resized = tmux.tmux(&["resize-window", "-t", "watch", "-x", w, "-y", h]);
        assert!(resized.status.success(), "resize: {}", String::from_utf8_lossy(&resized.stderr));
        thread::sleep(Duration::from_millis(500));
    }
    // Still running, and drawing at full size again; Ctrl-C (a key in raw mode) quits cleanly.
    tmux.screen_showing(&["no readings yet".to_owned()]);
    assert_eq!(tmux.quit(&status, "C-c"), "0", "watch's exit code");
}
