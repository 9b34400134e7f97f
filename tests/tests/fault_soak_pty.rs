//! Fault soak through the serial path: simulators served on pseudo-terminals
//! (`yosemitech_sim::serve_pty`), a `SerialTransport` client on each with a
//! short timeout and no retries, so that every injected fault is observed by
//! exactly one call. Thousands of typed calls (reads and writes) with faults
//! of every kind, drawn from a script:
//!
//! - zero wrong values: every `Ok` equals the simulator's truth, bit for bit;
//! - each failed call fails with the error its fault implies (the fault is
//!   read from the simulator's counters around the call, so a lost or extra
//!   request could not shift the expectations);
//! - a failed write was applied or not as the fault implies;
//! - the call after a fault succeeds (recovery), and every call returns
//!   within the timeout plus a generous margin.
//!
//! The probes sit at addresses that look like function codes: the pH probe
//! at 3 (its read replies start `03 03`), the conductivity probe at 16
//! (0x10: its write replies start `10 10`), so line noise before a reply
//! (the garbage fault) exercises the client's realignment.
#![cfg(unix)]
#![allow(clippy::result_large_err)]

use std::collections::BTreeMap;
use std::path::PathBuf;
use std::time::{Duration, Instant};

use yosemitech::{
    Client, ClientConfig, Error, ExceptionCode, FieldValue, FrameError, RetryPolicy, conductivity, ph_orp,
};
use yosemitech_rtu::{SerialConfig, SerialTransport};
use yosemitech_sim::{FaultConfig, FaultCounts, FaultKind, ServeConfig, Server, Simulator, serve_pty};
use yosemitech_spec::{Spec, Value, load_paths};

/// The client's timeout: the whole reply must arrive within it.
const TIMEOUT: Duration = Duration::from_millis(40);
/// How long a delay fault holds the reply back: past the timeout.
const DELAY_BY: Duration = Duration::from_millis(60);
/// Generous slack on a busy 2-core machine: each call returns within TIMEOUT + MARGIN.
const MARGIN: Duration = Duration::from_millis(400);
/// Calls in all (two thirds to the pH probe).
const CALLS: usize = 2100;
/// The pH probe's address (0x03, the read function code).
const PH_ADDRESS: u8 = 3;
/// The conductivity probe's address (0x10, the write function code).
const COND_ADDRESS: u8 = 16;

fn spec() -> Spec {
    load_paths(&[PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../spec")]).expect("the spec loads")
}

/// A deterministic generator (xorshift64*).
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_F491_4F6C_DD1D)
    }

    fn below(&mut self, n: u64) -> u64 {
        self.next() % n
    }

    /// A float with a varied bit pattern, finite.
    fn value(&mut self) -> f32 {
        (self.below(2_000_000) as f32 - 1_000_000.0) / 1024.0
    }
}

/// The fault script: a fault in about one call in three, each followed by
/// one to three clean calls, so that every fault is followed by a call that
/// must recover. Kinds cycle in a shuffled order, so each appears about as
/// often as the others.
fn script(rng: &mut Rng, calls: usize) -> Vec<Option<FaultKind>> {
    let mut out = Vec::with_capacity(calls + 4);
    let mut kinds = Vec::new();
    while out.len() < calls {
        if kinds.is_empty() {
            kinds = FaultKind::ALL.to_vec();
            for i in (1..kinds.len()).rev() {
                kinds.swap(i, rng.below(i as u64 + 1) as usize);
            }
        }
        out.push(kinds.pop());
        for _ in 0..1 + rng.below(3) {
            out.push(None);
        }
    }
    out
}

/// A simulator on a pty and a serial client on it.
struct Probe {
    server: Server<Simulator>,
    client: Client<SerialTransport>,
    address: u8,
}

fn open(spec: &Spec, sensor: &str, address: u8, script: Vec<Option<FaultKind>>) -> Option<Probe> {
    let sensor = spec.sensor(sensor).expect("the sensor").clone();
    let faults = FaultConfig { delay_by: DELAY_BY, ..FaultConfig::scripted(script) };
    let sim = Simulator::new(sensor).with_address(address).with_faults(faults);
    let server = match serve_pty(sim, ServeConfig::default()) {
        Ok(server) => server,
        Err(e) => {
            eprintln!("skipping: cannot create a pty: {e}");
            return None;
        }
    };
    let path = server.tty_path().expect("a pty path").to_owned();
    // A fast line, so that the soak is about faults, not line time.
    let serial = SerialConfig { baud: 115_200, ..SerialConfig::new(path.clone()) };
    let transport = match SerialTransport::open(&serial) {
        Ok(t) => t,
        Err(e) => {
            eprintln!("skipping: cannot open the pty {path}: {e}");
            return None;
        }
    };
    let config = ClientConfig {
        timeout: TIMEOUT,
        retry: RetryPolicy::NONE,
        min_inter_frame_delay: Duration::from_millis(1),
        ..ClientConfig::default()
    };
    Some(Probe { server, client: Client::with_config(transport, config), address })
}

/// A field value, owned; floats by their bits.
#[derive(Debug, Clone, PartialEq)]
enum Owned {
    Float(u32),
    Int(i64),
    Other(String),
}

fn owned(v: &FieldValue<'_>) -> Owned {
    match v {
        FieldValue::F32(f) => Owned::Float(f.to_bits()),
        FieldValue::Int(i) => Owned::Int(*i),
        other => Owned::Other(other.to_string()),
    }
}

fn owned_value(v: &Value) -> Owned {
    match v {
        Value::Float(f) => Owned::Float(f.to_bits()),
        Value::Int(i) => Owned::Int(*i),
        Value::Enum { raw, name: Some(name) } => Owned::Other(format!("{name} ({raw})")),
        Value::Enum { raw, name: None } => Owned::Other(format!("unknown ({raw})")),
        Value::Version(v) => Owned::Other(v.to_string()),
        Value::Text(t) => Owned::Other(t.clone()),
    }
}

/// The simulator's values of a read command: the truth.
fn truth(probe: &Probe, command: &str) -> Vec<(String, Owned)> {
    let values = probe.server.device().values(command).expect("the command's values");
    values.iter().map(|(n, v)| (n.clone(), owned_value(v))).collect()
}

/// One call of the soak.
#[derive(Debug, Clone, Copy)]
enum Op {
    Read(&'static str),
    /// A write of K and B, and the read command that reads them back.
    WriteKb(&'static str, &'static str),
}

/// What a call returned: a read's fields, or a write's `()`.
type Outcome = Result<Option<Vec<(String, Owned)>>, Error>;

fn fields_of<'a>(it: impl Iterator<Item = (yosemitech::FieldInfo, FieldValue<'a>)>) -> Option<Vec<(String, Owned)>> {
    Some(it.map(|(i, v)| (i.name.to_owned(), owned(&v))).collect())
}

/// Performs `op` through the typed API.
fn call(probe: &mut Probe, op: Op, k: f32, b: f32) -> Outcome {
    let a = probe.address;
    let c = &mut probe.client;
    match op {
        Op::Read("get_ph") => c.call(a, &ph_orp::GetPh).map(|r| fields_of(ph_orp::Response::from(r).fields())),
        Op::Read("get_temperature") => {
            c.call(a, &ph_orp::GetTemperature).map(|r| fields_of(ph_orp::Response::from(r).fields()))
        }
        Op::Read("get_orp") => c.call(a, &ph_orp::GetOrp).map(|r| fields_of(ph_orp::Response::from(r).fields())),
        Op::Read("get_orp_and_ph") => {
            c.call(a, &ph_orp::GetOrpAndPh).map(|r| fields_of(ph_orp::Response::from(r).fields()))
        }
        Op::Read("get_temperature_and_conductivity") => c
            .call(a, &conductivity::GetTemperatureAndConductivity)
            .map(|r| fields_of(conductivity::Response::from(r).fields())),
        Op::WriteKb("set_orp_calibration", _) => {
            c.call(a, &ph_orp::SetOrpCalibration { k_slope: k, b_offset: b }).map(|()| None)
        }
        Op::WriteKb("set_user_calibration", _) => {
            c.call(a, &conductivity::SetUserCalibration { k_slope: k, b_offset: b }).map(|()| None)
        }
        other => panic!("no such operation {other:?}"),
    }
}

/// The one fault the simulator injected between two snapshots of its counters.
fn injected(before: &FaultCounts, after: &FaultCounts) -> Option<FaultKind> {
    assert_eq!(after.replies() - before.replies(), 1, "each call draws exactly one reply");
    let kinds: Vec<FaultKind> = FaultKind::ALL.into_iter().filter(|&k| after.get(k) > before.get(k)).collect();
    assert!(kinds.len() <= 1, "more than one fault in one reply: {kinds:?}");
    kinds.first().copied()
}

/// Checks that `outcome` is what `fault` implies; panics with the details otherwise.
fn check(fault: Option<FaultKind>, address: u8, outcome: &Outcome, context: &str) {
    let ok = match (fault, outcome) {
        (None | Some(FaultKind::Garbage), Ok(_)) => true,
        (Some(FaultKind::Drop | FaultKind::Delay), Err(Error::Timeout { received })) => received.is_empty(),
        (Some(FaultKind::Truncate), Err(Error::Timeout { received })) => !received.is_empty(),
        (Some(FaultKind::CorruptCrc), Err(Error::Frame { error: FrameError::Crc { .. }, .. })) => true,
        (Some(FaultKind::WrongSlave), Err(Error::Frame { error: FrameError::WrongSlave { expected, actual }, .. })) => {
            *expected == address && *actual == address + 1
        }
        (Some(FaultKind::Busy), Err(e)) => e.exception() == Some(ExceptionCode::ServerDeviceBusy),
        _ => false,
    };
    assert!(ok, "{context}: fault {fault:?} gave {outcome:?}");
}

#[derive(Debug, Default)]
struct Tally {
    calls: usize,
    ok: usize,
    values_checked: usize,
    writes_checked: usize,
    recoveries: usize,
    by_kind: BTreeMap<&'static str, usize>,
    slowest: Duration,
}

/// Runs `calls` operations against `probe`, checking each; returns the tally.
fn soak(probe: &mut Probe, ops: &[Op], calls: usize, rng: &mut Rng, tally: &mut Tally) {
    let mut previous_fault: Option<FaultKind> = None;
    for n in 0..calls {
        let op = ops[rng.below(ops.len() as u64) as usize];
        let (k, b) = (rng.value(), rng.value());
        // New readings for a read; the current K and B for a write.
        let expected = match op {
            Op::Read(command) => {
                let mut sim = probe.server.device();
                let names: Vec<String> = sim
                    .sensor()
                    .command(command)
                    .expect("the command")
                    .fields
                    .iter()
                    .filter(|f| matches!(f.kind, yosemitech_spec::FieldKind::F32 { .. }))
                    .filter_map(|f| f.name.clone())
                    .collect();
                for name in names {
                    sim.set(command, &name, Value::Float(rng.value())).expect("a settable field");
                }
                drop(sim);
                truth(probe, command)
            }
            Op::WriteKb(_, readback) => truth(probe, readback),
        };
        let before = *probe.server.device().faults();
        let started = Instant::now();
        let outcome = call(probe, op, k, b);
        let took = started.elapsed();
        let after = *probe.server.device().faults();
        let fault = injected(&before, &after);
        let context = format!("probe {} call {n} ({op:?})", probe.address);
        check(fault, probe.address, &outcome, &context);

        assert!(took <= TIMEOUT + MARGIN, "{context}: took {took:?}");
        tally.slowest = tally.slowest.max(took);
        tally.calls += 1;
        *tally.by_kind.entry(fault.map_or("none", FaultKind::name)).or_default() += 1;
        if previous_fault.is_some() && fault.is_none() {
            assert!(outcome.is_ok(), "{context}: no recovery after {previous_fault:?}");
            tally.recoveries += 1;
        }
        match (op, &outcome) {
            (Op::Read(_), Ok(values)) => {
                let values = values.as_ref().expect("a read returns fields");
                assert_eq!(values, &expected, "{context}: a wrong value");
                tally.values_checked += values.len();
            }
            (Op::WriteKb(_, readback), _) => {
                // Applied unless the device was busy (it did not process it).
                let now = truth(probe, readback);
                let written = vec![
                    ("k_slope".to_owned(), Owned::Float(k.to_bits())),
                    ("b_offset".to_owned(), Owned::Float(b.to_bits())),
                ];
                let want = if fault == Some(FaultKind::Busy) { expected.clone() } else { written };
                assert_eq!(now[..2], want[..], "{context}: the device state after the write");
                tally.writes_checked += 1;
            }
            _ => {}
        }
        tally.ok += usize::from(outcome.is_ok());
        if fault == Some(FaultKind::Delay) {
            // Let the late reply arrive; the next call drops it as stale input.
            std::thread::sleep((DELAY_BY + Duration::from_millis(25)).saturating_sub(took));
        }
        previous_fault = fault;
    }
}

#[test]
fn fault_soak_through_the_pty() {
    let spec = spec();
    let mut rng = Rng(0x5EED_0FFA_1700);
    let ph_calls = CALLS * 2 / 3;
    let cond_calls = CALLS - ph_calls;
    let ph_script = script(&mut rng, ph_calls);
    let cond_script = script(&mut rng, cond_calls);
    let Some(mut ph) = open(&spec, "ph_orp", PH_ADDRESS, ph_script) else { return };
    let Some(mut cond) = open(&spec, "conductivity", COND_ADDRESS, cond_script) else { return };

    let started = Instant::now();
    let mut tally = Tally::default();
    let ph_ops = [
        Op::Read("get_ph"),
        Op::Read("get_temperature"),
        Op::Read("get_orp"),
        Op::Read("get_orp_and_ph"),
        Op::WriteKb("set_orp_calibration", "get_orp_calibration"),
    ];
    soak(&mut ph, &ph_ops, ph_calls, &mut rng, &mut tally);
    let cond_ops =
        [Op::Read("get_temperature_and_conductivity"), Op::WriteKb("set_user_calibration", "get_user_calibration")];
    soak(&mut cond, &cond_ops, cond_calls, &mut rng, &mut tally);
    let elapsed = started.elapsed();

    assert_eq!(tally.calls, CALLS);
    for kind in FaultKind::ALL {
        let n = tally.by_kind.get(kind.name()).copied().unwrap_or(0);
        assert!(n >= 50, "only {n} faults of kind {kind}");
    }
    let counts: Vec<String> = tally.by_kind.iter().map(|(k, n)| format!("{k} {n}")).collect();
    yosemitech_tests::report!(
        "fault soak over ptys: {} calls in {:.1} s ({} ok, {} values and {} writes checked, {} recoveries), \
         slowest call {:?} (bound {:?}); by fault: {}",
        tally.calls,
        elapsed.as_secs_f64(),
        tally.ok,
        tally.values_checked,
        tally.writes_checked,
        tally.recoveries,
        tally.slowest,
        TIMEOUT + MARGIN,
        counts.join(", ")
    );
    let stats = ph.server.device().stats().to_owned();
    assert_eq!(stats.ignored_bad_crc, 0, "no request was garbled on the way");
    ph.server.stop().expect("the pH server stops");
    cond.server.stop().expect("the conductivity server stops");
}

#[test]
fn function_code_addresses_with_noise_through_the_pty() {
    // Every reply of both probes preceded by noise: the case that misframed
    // before the client learned to realign (`AA 03 03 04 ...`).
    let spec = spec();
    let Some(mut ph) = open(&spec, "ph_orp", PH_ADDRESS, vec![Some(FaultKind::Garbage); 200]) else { return };
    let Some(mut cond) = open(&spec, "conductivity", COND_ADDRESS, vec![Some(FaultKind::Garbage); 200]) else { return };
    for i in 0..200 {
        let v = i as f32 * 0.5;
        ph.server.device().set("get_ph", "ph", Value::Float(v)).expect("set");
        assert_eq!(ph.client.call(PH_ADDRESS, &ph_orp::GetPh).expect("get_ph after noise").ph, v);
        cond.client
            .call(COND_ADDRESS, &conductivity::SetUserCalibration { k_slope: v, b_offset: -v })
            .expect("a write to 0x10 after noise");
    }
    assert_eq!(ph.server.device().faults().get(FaultKind::Garbage), 200);
    assert_eq!(cond.server.device().faults().get(FaultKind::Garbage), 200);
}
