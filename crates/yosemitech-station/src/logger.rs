//! The scheduler: one master per bus, on a thread of its own, interleaving
//! the probes of its bus by their schedules.
//!
//! Each probe samples on its own grid of slots (`interval` apart, from the
//! start or, with `align`, from 00:00 UTC). A sample is a small state
//! machine stepped one transaction group at a time: the procedure's
//! `before` commands, a warm-up during which the bus serves the other
//! probes, the planned reads (repeated and averaged as the procedure says,
//! with its pauses also given to the others), the `after` commands. The
//! reading then goes to the store's writer thread, which commits it (with
//! whatever else is waiting, in one transaction) and only then hands it on
//! (`on_commit`); the bus goes on with its next request meanwhile.
//!
//! A probe that does not answer costs one timeout per attempt (it loses
//! its retries while it keeps failing) and backs off exponentially (one
//! interval, two, four, ... at most `max_backoff`); the others keep their
//! slots. A slot missed as a whole is skipped, never caught up in a burst.
//! When every probe of a bus has failed its last sample the port is
//! reopened (a USB adapter unplugged and plugged back), with its own
//! backoff.
//!
//! Stopping (the `stop` flag: Ctrl-C, SIGTERM) takes effect between two
//! transactions: the one in flight completes, its sample is dropped if
//! incomplete (nothing half-read is stored).

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Mutex, mpsc};
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

use yosemitech_spec::{CommandSpec, FieldKind, Role, Sensor, Value};

use crate::config::{BusConfig, ProbeConfig, StationConfig};
use crate::derive;
use crate::link::{self, Master, Outcome};
use crate::plan::{self, Plan};
use crate::store::{Datum, Measurement, Reading, Store, StoreError};

/// Longest sleep between two checks of the stop flag.
const STOP_CHECK: Duration = Duration::from_millis(50);
/// First and longest pause before reopening a port that failed.
const REOPEN_BACKOFF: (Duration, Duration) = (Duration::from_millis(250), Duration::from_secs(5));

/// What one bus did during a run.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct BusReport {
    /// The bus's name.
    pub name: String,
    /// Requests sent (attempts, retries included).
    pub transactions: u64,
    /// Requests that got no valid reply.
    pub failed_transactions: u64,
    /// Readings committed (failed ones included).
    pub readings: u64,
    /// Readings committed with an error.
    pub failed_readings: u64,
    /// Times the port was (re)opened.
    pub opens: u64,
    /// Time spent inside requests.
    pub busy: Duration,
}

/// Why a run stopped other than by the stop flag.
#[derive(Debug, thiserror::Error)]
pub enum LogError {
    /// Readings could not be committed for another reason than a full
    /// disk: the logger stops rather than lose readings silently.
    #[error("cannot commit readings: {0}")]
    Store(#[from] StoreError),
    /// A thread panicked (a bug).
    #[error("the thread of {0} panicked")]
    Panicked(String),
}

/// Readings committed in one transaction at most.
const BATCH: usize = 256;
/// Readings waiting for the writer before the buses wait for it.
const QUEUE: usize = 4096;

/// Runs every bus of `config` until `stop` is set. Each bus thread hands
/// its readings to one writer thread, which commits them to `store` (all
/// that are waiting in one transaction) and only then calls `on_commit`
/// with each id and reading, in id order. Returns what each bus did once
/// every reading taken is committed.
///
/// # Errors
///
/// Readings could not be committed (every bus then stops; the readings
/// not yet committed are lost and were never announced).
pub fn run(
    config: &StationConfig,
    store: &Mutex<Store>,
    stop: &AtomicBool,
    on_commit: &(dyn Fn(i64, &Reading) + Sync),
) -> Result<Vec<BusReport>, LogError> {
    std::thread::scope(|scope| {
        let (readings, queue) = mpsc::sync_channel::<Reading>(QUEUE);
        let writer = std::thread::Builder::new()
            .name("store writer".into())
            .spawn_scoped(scope, move || {
                let result = write(store, &queue, on_commit);
                if result.is_err() {
                    stop.store(true, Ordering::SeqCst);
                }
                result
            })
            .map_err(|_| LogError::Panicked("the store writer".into()));
        let threads: Vec<_> = config
            .buses
            .iter()
            .map(|bus| {
                let readings = readings.clone();
                let handle = std::thread::Builder::new()
                    .name(format!("bus {}", bus.name))
                    .spawn_scoped(scope, move || BusRun::new(&config.station, bus).run(&readings, stop));
                (bus.name.clone(), handle)
            })
            .collect();
        drop(readings);
        let mut reports = Vec::new();
        let mut first_error = None;
        for (name, handle) in threads {
            match handle.ok().and_then(|h| h.join().ok()) {
                Some(report) => reports.push(report),
                None => {
                    stop.store(true, Ordering::SeqCst);
                    first_error.get_or_insert(LogError::Panicked(format!("bus `{name}`")));
                }
            }
        }
        let written =
            writer.and_then(|w| w.join().unwrap_or_else(|_| Err(LogError::Panicked("the store writer".into()))));
        match (written, first_error) {
            (Err(e), _) | (Ok(()), Some(e)) => Err(e),
            (Ok(()), None) => Ok(reports),
        }
    })
}

/// The writer thread: commits what the buses send, in batches, then announces it.
fn write(
    store: &Mutex<Store>,
    queue: &mpsc::Receiver<Reading>,
    on_commit: &(dyn Fn(i64, &Reading) + Sync),
) -> Result<(), LogError> {
    let mut batch = Vec::with_capacity(BATCH);
    // Readings refused since the store became full.
    let mut refused = 0u64;
    while let Ok(first) = queue.recv() {
        batch.push(first);
        while batch.len() < BATCH {
            match queue.try_recv() {
                Ok(reading) => batch.push(reading),
                Err(_) => break,
            }
        }
        // The lock is released before `on_commit`, which may read the store.
        let inserted = store.lock().unwrap_or_else(std::sync::PoisonError::into_inner).insert_all(&batch);
        match inserted {
            Ok(ids) => {
                if refused > 0 {
                    tracing::info!("the store has room again: {refused} reading(s) were refused while it was full");
                    refused = 0;
                }
                for (id, reading) in ids.into_iter().zip(&batch) {
                    on_commit(id, reading);
                }
            }
            // A full disk (or the store's size cap) refuses the batch; the
            // buses keep their schedule and the next batch tries again.
            Err(e) if e.is_full() => {
                if refused == 0 {
                    tracing::error!(
                        "the store is full ({e}): readings are refused until space returns; the schedule goes on"
                    );
                }
                refused += batch.len() as u64;
            }
            Err(e) => return Err(e.into()),
        }
        batch.clear();
    }
    if refused > 0 {
        tracing::error!("{refused} reading(s) refused at the end of the run: the store was still full");
    }
    Ok(())
}

/// The procedure's steps as commands.
struct Steps<'c> {
    before: Vec<&'c CommandSpec>,
    warm_up: Duration,
    readings: u32,
    interval: Duration,
    after: Vec<&'c CommandSpec>,
}

impl<'c> Steps<'c> {
    fn of(sensor: &'c Sensor) -> Option<Self> {
        let p = sensor.procedure.as_ref()?;
        let commands = |names: &[String]| names.iter().filter_map(|n| sensor.command(n)).collect();
        Some(Self {
            before: commands(&p.before),
            warm_up: Duration::from_millis(u64::from(p.warm_up_ms)),
            readings: p.readings.max(1),
            interval: Duration::from_millis(u64::from(p.interval_ms)),
            after: commands(&p.after),
        })
    }
}

/// The running mean (numbers) or last value (text) of one measurement.
struct Accumulator<'c> {
    name: &'c str,
    unit: Option<&'c str>,
    absent: Option<f64>,
    sum: f64,
    count: u32,
    text: Option<String>,
}

impl Accumulator<'_> {
    fn add(&mut self, value: &Value, kind: &FieldKind) {
        let number = value.number();
        match (number, kind) {
            // Enumerations, flags and versions are codes, not quantities.
            (Some(_), FieldKind::Enum { .. } | FieldKind::Flags { .. }) | (None, _) => {
                self.text = Some(match value {
                    Value::Enum { name: Some(name), .. } => name.clone(),
                    Value::Enum { raw, name: None } => raw.to_string(),
                    Value::Text(t) => t.trim_end_matches(['\0', ' ']).to_owned(),
                    Value::Version(v) => v.to_string(),
                    other => format!("{other:?}"),
                });
            }
            (Some(v), _) if self.absent == Some(v) || !v.is_finite() => {}
            (Some(v), _) => {
                self.sum += v;
                self.count += 1;
            }
        }
    }

    fn measurement(&self) -> Option<Measurement> {
        let value = if self.count > 0 {
            Datum::Number(self.sum / f64::from(self.count))
        } else {
            Datum::Text(self.text.clone()?)
        };
        Some(Measurement { name: self.name.to_owned(), value, unit: self.unit.map(str::to_owned), derived: false })
    }
}

/// A sample in progress.
struct Sample<'c> {
    timestamp: SystemTime,
    /// Readings taken.
    taken: u32,
    values: Vec<Accumulator<'c>>,
    retries: u32,
    errors: Vec<String>,
    /// What failed without spoiling the reading (a refused Start Measurement).
    warnings: Vec<String>,
    /// The `before` commands went out: the `after` commands must too.
    started: bool,
}

/// Where a probe is in its sample.
enum Phase<'c> {
    /// Waiting for its slot.
    Idle,
    /// Between the steps of a sample.
    Sampling(Sample<'c>),
}

/// A probe's schedule and state.
struct ProbeRun<'c> {
    config: &'c ProbeConfig,
    plan: Plan<'c>,
    steps: Option<Steps<'c>>,
    /// Slots are `base + k * interval`.
    base: SystemTime,
    slot: u64,
    wake: Instant,
    phase: Phase<'c>,
    /// Consecutive failed samples.
    failures: u32,
    /// Serial number and firmware, once read since the last failure.
    identity: Option<(Option<String>, Option<String>)>,
}

/// A probe's grid of slots from `start`: its origin and the first slot
/// (`origin + slot * interval`): the start itself, or with `align` the
/// first multiple of the interval since 00:00 UTC at or after it.
fn grid(config: &ProbeConfig, start: SystemTime) -> (SystemTime, u64) {
    if config.align {
        let since = start.duration_since(UNIX_EPOCH).unwrap_or_default().as_millis();
        (UNIX_EPOCH, u64::try_from(since.div_ceil(millis(config.interval))).unwrap_or(0))
    } else {
        (start, 0)
    }
}

/// When a probe started at `start` takes its first sample.
pub fn first_sample(config: &ProbeConfig, start: SystemTime) -> SystemTime {
    let (origin, slot) = grid(config, start);
    slot_time(origin, config.interval, slot)
}

/// The time of slot `slot` of a grid.
fn slot_time(origin: SystemTime, interval: Duration, slot: u64) -> SystemTime {
    let ms = u64::try_from(millis(interval).saturating_mul(u128::from(slot))).unwrap_or(u64::MAX);
    origin.checked_add(Duration::from_millis(ms)).unwrap_or(origin)
}

/// Milliseconds of a duration, at least 1.
fn millis(d: Duration) -> u128 {
    d.as_millis().max(1)
}

impl<'c> ProbeRun<'c> {
    fn new(config: &'c ProbeConfig, start: SystemTime) -> Self {
        let names: Vec<&str> = config.measurements.iter().map(String::as_str).collect();
        let plan = plan::plan(&config.sensor, &names);
        let steps = if config.procedure { Steps::of(&config.sensor) } else { None };
        let (base, slot) = grid(config, start);
        let mut run = Self {
            config,
            plan,
            steps,
            base,
            slot,
            wake: Instant::now(),
            phase: Phase::Idle,
            failures: 0,
            identity: None,
        };
        run.wake = run.instant_of(run.slot);
        run
    }

    fn slot_time(&self, slot: u64) -> SystemTime {
        slot_time(self.base, self.config.interval, slot)
    }

    /// The monotonic instant of a slot.
    fn instant_of(&self, slot: u64) -> Instant {
        let at = self.slot_time(slot);
        let now = SystemTime::now();
        match at.duration_since(now) {
            Ok(ahead) => Instant::now() + ahead,
            Err(_) => Instant::now(),
        }
    }

    /// The slot containing `t`.
    fn slot_at(&self, t: SystemTime) -> u64 {
        let since = t.duration_since(self.base).unwrap_or_default().as_millis();
        u64::try_from(since / millis(self.config.interval)).unwrap_or(u64::MAX)
    }

    /// Schedules the next sample after the one of the current slot:
    /// the next slot, or the current one when whole slots were missed,
    /// and no earlier than the backoff allows.
    fn schedule_next(&mut self, max_backoff: Duration) {
        let now = SystemTime::now();
        let mut next = (self.slot + 1).max(self.slot_at(now));
        if self.failures > 0 {
            let doubling = 2u32.saturating_pow(self.failures.saturating_sub(1).min(20));
            let backoff = self.config.interval.saturating_mul(doubling).min(max_backoff);
            next = next.max(self.slot_at(now + backoff));
        }
        self.slot = next;
        self.wake = self.instant_of(next);
        self.phase = Phase::Idle;
    }

    fn new_sample(&self) -> Sample<'c> {
        let values = self
            .plan
            .reads
            .iter()
            .flat_map(|r| r.fields.iter().map(move |f| (r.command, *f)))
            .filter_map(|(command, name)| {
                let field = command.field(name)?;
                Some(Accumulator {
                    name: field.name.as_deref()?,
                    unit: field.unit.as_deref(),
                    absent: field.absent,
                    sum: 0.0,
                    count: 0,
                    text: None,
                })
            })
            .collect();
        Sample {
            timestamp: SystemTime::now(),
            taken: 0,
            values,
            retries: 0,
            errors: Vec::new(),
            warnings: Vec::new(),
            started: false,
        }
    }
}

/// One bus's thread state.
struct BusRun<'c> {
    station: &'c str,
    config: &'c BusConfig,
    probes: Vec<ProbeRun<'c>>,
    master: Option<Master>,
    open_error: Option<String>,
    reopen_at: Instant,
    reopen_backoff: Duration,
    report: BusReport,
}

impl<'c> BusRun<'c> {
    fn new(station: &'c str, config: &'c BusConfig) -> Self {
        let start = SystemTime::now();
        Self {
            station,
            config,
            probes: config.probes.iter().map(|p| ProbeRun::new(p, start)).collect(),
            master: None,
            open_error: None,
            reopen_at: Instant::now(),
            reopen_backoff: REOPEN_BACKOFF.0,
            report: BusReport { name: config.name.clone(), ..BusReport::default() },
        }
    }

    fn run(mut self, readings: &mpsc::SyncSender<Reading>, stop: &AtomicBool) -> BusReport {
        while !stop.load(Ordering::SeqCst) {
            let Some(next) = (0..self.probes.len()).min_by_key(|i| self.probes[*i].wake) else { break };
            let wait = self.probes[next].wake.saturating_duration_since(Instant::now());
            if !wait.is_zero() {
                std::thread::sleep(wait.min(STOP_CHECK));
                continue;
            }
            self.ensure_open();
            if let Some(mut reading) = self.step(next) {
                // The probe's chosen units, last: whatever the sample computed is in spec units.
                crate::units::apply(&self.probes[next].config.units, &mut reading);
                let ok = reading.error.is_none();
                self.report.readings += 1;
                self.report.failed_readings += u64::from(!ok);
                if readings.send(reading).is_err() {
                    // The writer has stopped (it failed): nothing more can be stored.
                    break;
                }
                self.after_sample(next, ok);
            }
        }
        self.report
    }

    /// Opens the port if it is closed and its backoff has passed.
    fn ensure_open(&mut self) {
        if self.master.is_some() || Instant::now() < self.reopen_at {
            return;
        }
        match link::open(&self.config.link, self.config.timeout, self.config.gap) {
            Ok(master) => {
                self.master = Some(master);
                self.open_error = None;
                self.report.opens += 1;
            }
            Err(e) => {
                self.open_error = Some(format!("cannot open {}: {e}", self.config.link));
                self.reopen_at = Instant::now() + self.reopen_backoff;
                self.reopen_backoff = (self.reopen_backoff * 2).min(REOPEN_BACKOFF.1);
            }
        }
    }

    /// After a committed sample: the probe's next slot; the port is
    /// reopened when every probe has failed its last sample.
    fn after_sample(&mut self, index: usize, ok: bool) {
        let max_backoff = self.config.max_backoff;
        let probe = &mut self.probes[index];
        if ok {
            probe.failures = 0;
            self.reopen_backoff = REOPEN_BACKOFF.0;
        } else {
            probe.failures = probe.failures.saturating_add(1);
            probe.identity = None;
        }
        probe.schedule_next(max_backoff);
        if !ok && self.master.is_some() && self.probes.iter().all(|p| p.failures > 0) {
            self.master = None;
            self.reopen_at = Instant::now() + self.reopen_backoff;
            self.reopen_backoff = (self.reopen_backoff * 2).min(REOPEN_BACKOFF.1);
            // The failures were the port's, not the probes': try each at its next slot.
            for p in &mut self.probes {
                p.failures = 0;
            }
        }
    }

    /// Sends one request, counting it.
    fn transact(&mut self, command: &CommandSpec, slave: u8, retries: u32) -> Option<Outcome> {
        let master = self.master.as_mut()?;
        let started = Instant::now();
        let outcome = link::transact(master, command, slave, retries);
        self.report.busy += started.elapsed();
        self.report.transactions += 1 + u64::from(outcome.retries);
        self.report.failed_transactions += u64::from(outcome.retries) + u64::from(outcome.result.is_err());
        Some(outcome)
    }

    /// Advances probe `index` by one step; returns the reading when its sample is complete.
    fn step(&mut self, index: usize) -> Option<Reading> {
        let phase = std::mem::replace(&mut self.probes[index].phase, Phase::Idle);
        let mut sample = match phase {
            Phase::Idle => self.probes[index].new_sample(),
            Phase::Sampling(s) => s,
        };
        let probe = &self.probes[index];
        let address = probe.config.address;
        let retries = if probe.failures > 0 { 0 } else { self.config.retries };
        if self.master.is_none() {
            sample.errors.push(self.open_error.clone().unwrap_or_else(|| format!("{} is closed", self.config.link)));
            return Some(self.finish(index, sample));
        }
        // Phase 1: the procedure's opening commands, then its warm-up.
        if sample.taken == 0 && !sample.started {
            sample.started = true;
            let before: Vec<&CommandSpec> = probe.steps.as_ref().map(|s| s.before.clone()).unwrap_or_default();
            for command in before {
                // Some probes refuse Start Measurement and read all the same
                // (a real Y533 does): that refusal does not stop the reading.
                if command.role == Some(Role::StartMeasurement) {
                    let Some(outcome) = self.transact(command, address, retries) else {
                        return Some(self.finish(index, sample));
                    };
                    sample.retries += outcome.retries;
                    if let Err(f) = outcome.result {
                        sample.warnings.push(format!("{} refused ({}); read anyway", f.command, f.message));
                    }
                    continue;
                }
                if !self.send(command, address, retries, &mut sample) {
                    return Some(self.finish(index, sample));
                }
            }
            let warm_up = self.probes[index].steps.as_ref().map_or(Duration::ZERO, |s| s.warm_up);
            if !warm_up.is_zero() {
                let probe = &mut self.probes[index];
                probe.wake = Instant::now() + warm_up;
                probe.phase = Phase::Sampling(sample);
                return None;
            }
        }
        // Phase 2: one reading of every planned read.
        let reads: Vec<(&CommandSpec, Vec<&str>)> =
            self.probes[index].plan.reads.iter().map(|r| (r.command, r.fields.clone())).collect();
        for (command, fields) in reads {
            let Some(outcome) = self.transact(command, address, retries) else { break };
            sample.retries += outcome.retries;
            match outcome.result {
                Ok(values) => {
                    for (name, value) in &values {
                        if !fields.contains(&name.as_str()) {
                            continue;
                        }
                        let kind = command.field(name).map(|f| &f.kind);
                        if let (Some(acc), Some(kind)) = (sample.values.iter_mut().find(|a| a.name == name), kind) {
                            acc.add(value, kind);
                        }
                    }
                }
                Err(f) => {
                    sample.errors.push(format!("{}: {}", f.command, f.message));
                    if f.timeout {
                        // A probe that does not answer costs one timeout, not one per read.
                        return Some(self.finish(index, sample));
                    }
                }
            }
        }
        sample.taken += 1;
        let steps = self.probes[index].steps.as_ref().map(|s| (s.readings, s.interval));
        if let Some((readings, interval)) = steps
            && sample.taken < readings
            && sample.errors.is_empty()
        {
            let probe = &mut self.probes[index];
            probe.wake = Instant::now() + interval;
            probe.phase = Phase::Sampling(sample);
            return None;
        }
        Some(self.finish(index, sample))
    }

    /// Sends a procedure command; false (with the error noted) when it failed.
    fn send(&mut self, command: &CommandSpec, address: u8, retries: u32, sample: &mut Sample<'_>) -> bool {
        let Some(outcome) = self.transact(command, address, retries) else { return false };
        sample.retries += outcome.retries;
        match outcome.result {
            Ok(_) => true,
            Err(f) => {
                sample.errors.push(format!("{}: {}", f.command, f.message));
                false
            }
        }
    }

    /// Ends a sample: the closing commands, the identity if unknown, the reading.
    fn finish(&mut self, index: usize, mut sample: Sample<'_>) -> Reading {
        let probe = &self.probes[index];
        let (config, address) = (probe.config, probe.config.address);
        let answered = sample.errors.is_empty();
        let retries = if answered { self.config.retries } else { 0 };
        if sample.started && self.master.is_some() {
            let after: Vec<&CommandSpec> = probe.steps.as_ref().map(|s| s.after.clone()).unwrap_or_default();
            for command in after {
                if !self.send(command, address, retries, &mut sample) {
                    break;
                }
            }
        }
        if answered && self.probes[index].identity.is_none() && self.master.is_some() {
            let sensor = &config.sensor;
            let mut text_of = |role: Role| -> Option<String> {
                let command = sensor.command_with_role(role)?;
                let outcome = self.transact(command, address, retries)?;
                sample.retries += outcome.retries;
                let values = outcome.result.ok()?;
                values.into_iter().find_map(|(_, v)| match v {
                    Value::Text(t) => Some(t.trim_end_matches(['\0', ' ']).to_owned()),
                    Value::Version(v) => Some(v.to_string()),
                    _ => None,
                })
            };
            let serial = text_of(Role::SerialNumber);
            let firmware = text_of(Role::Version);
            self.probes[index].identity = Some((serial, firmware));
        }
        let (serial_number, firmware) = self.probes[index].identity.clone().unwrap_or_default();
        let mut values: Vec<Measurement> = sample.values.iter().filter_map(Accumulator::measurement).collect();
        // A sample without a value has nothing to derive from: its error says enough.
        if !values.is_empty() {
            values.extend(derive::measurements(config, &self.probes[index].plan, &values));
        }
        Reading {
            timestamp: sample.timestamp,
            station: self.station.to_owned(),
            bus: self.config.name.clone(),
            probe: config.label.clone(),
            sensor: config.sensor.name.clone(),
            address,
            serial_number,
            firmware,
            values,
            retries: sample.retries,
            error: {
                let all: Vec<String> = sample.errors.iter().chain(&sample.warnings).cloned().collect();
                (!all.is_empty()).then(|| all.join("; "))
            },
        }
    }
}
