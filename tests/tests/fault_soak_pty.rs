//! Fault soak through the serial path: simulators served on pseudo-terminals
//! (`yosemitech_sim::serve_pty`), a `SerialTransport` client on each with no
//! retries, so that every injected fault is observed by exactly one call.
//! Thousands of calls (reads and writes) through the generated typed codecs
//! (`yosemitech::SENSORS`), with faults of every kind, drawn from a script:
//!
//! - zero wrong values: every `Ok` equals the simulator's truth, bit for bit;
//! - each failed call fails with the error its fault implies (the fault is
//!   read from the simulator's counters around the call, so a lost or extra
//!   request could not shift the expectations);
//! - a failed write was applied or not as the fault implies;
//! - the call after a fault succeeds (recovery).
//!
//! # Load
//!
//! CI runs this on a loaded 2-core machine, so nothing here rests on how fast
//! a reply comes, only on counts and on deadlines measured in seconds:
//!
//! - a call whose reply comes (clean, noise, bad CRC, wrong slave, busy) has
//!   [`REPLY_TIMEOUT`], seconds; it returns as soon as the reply is there;
//! - a call whose reply never comes complete in time (drop, truncate, delay)
//!   must wait its timeout out, so it has the short [`NO_REPLY_TIMEOUT`]:
//!   its outcome, a timeout, does not depend on the load (the test picks the
//!   timeout from the script; the client is not told the fault);
//! - a stalled machine may still turn a due reply into a timeout, or let a
//!   delayed reply in before the client gave up: both are tolerated (and
//!   counted, and bounded), a wrong value or another error never is;
//! - after any timeout the test waits (up to [`SETTLE`]) until the simulator
//!   has finished with the request, so that a late reply cannot reach the
//!   next call and the counters and the device state are final.
//!
//! The probes are chosen from the spec: the first two sensors with float
//! reads and a float write read back at the same registers (a calibration's
//! K and B). They sit at addresses that look like function codes: the first
//! at 3 (its read replies start `03 03`), the second at 16 (0x10: its write
//! replies start `10 10`), so line noise before a reply (the garbage fault)
//! exercises the client's realignment.
#![cfg(unix)]

use yosemitech_tests::sim as sim_common;

use std::collections::BTreeMap;
use std::time::{Duration, Instant};

use sim_common::{float_write_with_readback, is_f32, is_float_read, request, spec};
use yosemitech::{Client, ClientConfig, Error, ExceptionCode, FieldValue, FrameError, RetryPolicy};
use yosemitech_rtu::{SensorModule, SerialConfig, SerialTransport, Transport, crc_ok, crc16};
use yosemitech_sim::{FaultConfig, FaultCounts, FaultKind, ServeConfig, Server, Simulator, serve_pty};
use yosemitech_spec::{CommandSpec, Sensor, Spec, Value};

/// The client's timeout for a call whose reply comes: generous, since a
/// loaded machine may hold a reply back for a while, and free on an idle
/// one (the call returns when the reply is complete).
const REPLY_TIMEOUT: Duration = Duration::from_secs(10);
/// The client's timeout for a call whose reply does not come complete
/// (drop, truncate, delay): it is waited out, so it is short; the outcome
/// is a timeout however loaded the machine is.
const NO_REPLY_TIMEOUT: Duration = Duration::from_millis(40);
/// How long a delay fault holds the reply back: past [`NO_REPLY_TIMEOUT`]
/// (a client stalled longer than this may take the late reply: tolerated).
const DELAY_BY: Duration = Duration::from_millis(100);
/// How long the client waits for more bytes after a candidate frame failed
/// its CRC (noise before the reply), as `min_inter_frame_delay`: generous,
/// so that a reply the scheduler delivers in pieces is still realigned. It
/// is waited out once per corrupt-CRC fault.
const REALIGN_WAIT: Duration = Duration::from_millis(50);
/// How long the simulator may take to catch up after a timeout, and a
/// delayed reply to arrive in full.
const SETTLE: Duration = Duration::from_secs(10);
/// No call returns later than this after its timeout (a hang, not load).
const HANG: Duration = Duration::from_secs(10);
/// Calls in all (two thirds to the first probe).
const CALLS: usize = 2100;
/// The first probe's address (0x03, the read function code).
const FIRST_ADDRESS: u8 = 3;
/// The second probe's address (0x10, the write function code).
const SECOND_ADDRESS: u8 = 16;
/// The address of the barrier requests [`settle`] sends: no probe's, so the
/// simulator reads and ignores them (and counts them).
const BARRIER_ADDRESS: u8 = 200;

/// What the soak does with one sensor of the spec: its float reads, and a
/// float write with the read that reads it back.
struct Choice {
    sensor: Sensor,
    reads: Vec<CommandSpec>,
    write: (CommandSpec, CommandSpec),
}

/// The first two sensors of the spec with float reads and a float write
/// read back, whose generated module the `yosemitech` crate has.
fn probes(spec: &Spec) -> (Choice, Choice) {
    let mut chosen = spec.sensors.iter().filter(|s| module(&s.name).is_some()).filter_map(|s| {
        let reads: Vec<CommandSpec> = s.commands.iter().filter(|c| is_float_read(c)).cloned().collect();
        let write = float_write_with_readback(s)?;
        (!reads.is_empty()).then(|| Choice { sensor: s.clone(), reads, write })
    });
    let first = chosen.next().expect("a sensor with float reads and a float write read back");
    let second = chosen.next().expect("a second sensor with float reads and a float write read back");
    (first, second)
}

/// The generated module of the sensor called `name`.
fn module(name: &str) -> Option<SensorModule> {
    yosemitech::SENSORS.iter().find(|m| m.info.name == name).copied()
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
    /// The sensor's spec and its generated module.
    sensor: Sensor,
    module: SensorModule,
    address: u8,
    /// The simulator's fault script (its copy is consumed as it replies).
    script: Vec<Option<FaultKind>>,
    /// Barrier requests sent by [`settle`].
    barriers: u64,
}

fn open(sensor: &Sensor, address: u8, script: Vec<Option<FaultKind>>) -> Option<Probe> {
    let module = module(&sensor.name).expect("the sensor's generated module");
    let faults = FaultConfig { delay_by: DELAY_BY, ..FaultConfig::scripted(script.clone()) };
    let sim = Simulator::new(sensor.clone()).with_address(address).with_faults(faults);
    // The client writes each request at once; a generous gap allowance keeps
    // a descheduled simulator thread from dropping a request half read.
    let serve = ServeConfig { inter_char_timeout: Duration::from_secs(2), ..ServeConfig::default() };
    let server = match serve_pty(sim, serve) {
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
        timeout: REPLY_TIMEOUT,
        retry: RetryPolicy::NONE,
        // At 115200 baud the inter-frame delay is t3.5 (1.75 ms) whatever
        // this says; it only sets how long realignment waits for more bytes.
        min_inter_frame_delay: REALIGN_WAIT,
        ..ClientConfig::default()
    };
    let client = Client::with_config(transport, config);
    Some(Probe { server, client, sensor: sensor.clone(), module, address, script, barriers: 0 })
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
        Value::Bcd(b) => Owned::Other(b.to_string()),
    }
}

/// The simulator's values of a read command: the truth.
fn truth(probe: &Probe, command: &str) -> Vec<(String, Owned)> {
    let values = probe.server.device().values(command).expect("the command's values");
    values.iter().map(|(n, v)| (n.clone(), owned_value(v))).collect()
}

/// One call of the soak, by command name.
#[derive(Debug, Clone)]
enum Op {
    Read(String),
    /// A write of K and B (fields alternately), and the read command that reads them back.
    WriteKb(String, String),
}

/// The soak's operations on a sensor: every float read, and the write.
fn ops(choice: &Choice) -> Vec<Op> {
    let mut ops: Vec<Op> = choice.reads.iter().map(|c| Op::Read(c.name.clone())).collect();
    ops.push(Op::WriteKb(choice.write.0.name.clone(), choice.write.1.name.clone()));
    ops
}

/// The values a write of K and B sends: its fields alternately K and B.
fn kb_values(write: &CommandSpec, k: f32, b: f32) -> Vec<(String, Value)> {
    write
        .fields
        .iter()
        .enumerate()
        .map(|(i, f)| (f.name.clone().expect("a named field"), Value::Float(if i % 2 == 0 { k } else { b })))
        .collect()
}

/// What a call returned: a read's fields, or a write's `()`.
type Outcome = Result<Option<Vec<(String, Owned)>>, Error>;

/// Performs `op` through the generated typed codecs: the request the spec
/// interpreter builds, checked against the typed encoding, sent as it is;
/// the reply decoded by the typed decoder.
fn call(probe: &mut Probe, op: &Op, k: f32, b: f32) -> Outcome {
    let (name, values) = match op {
        Op::Read(name) => (name, Vec::new()),
        Op::WriteKb(name, _) => (name, kb_values(probe.sensor.command(name).expect("the write"), k, b)),
    };
    let command = probe.sensor.command(name).expect("the command");
    let values: Vec<(&str, Value)> = values.iter().map(|(n, v)| (n.as_str(), v.clone())).collect();
    let frame = request(command, probe.address, &values);
    let mut typed = [0u8; 256];
    let n = probe.module.reencode_request(name, &frame, &mut typed).expect("a generated command").expect("typed");
    assert_eq!(typed[..n], frame[..], "{name}: the typed request is the interpreter's");
    let layout = probe.module.layout(name).expect("the command's layout");
    let reply = probe.client.call_raw(&frame, &layout)?;
    if !command.is_read() {
        return Ok(None);
    }
    let mut fields = Vec::new();
    let decoded = probe.module.visit_response(name, probe.address, reply, &mut |info, value| {
        fields.push((info.name.to_owned(), owned(&value)));
    });
    decoded.expect("a generated command").expect("the typed decoder takes the checked reply");
    Ok(Some(fields))
}

/// The one fault the simulator injected between two snapshots of its counters.
fn injected(before: &FaultCounts, after: &FaultCounts) -> Option<FaultKind> {
    assert_eq!(after.replies() - before.replies(), 1, "each call draws exactly one reply");
    let kinds: Vec<FaultKind> = FaultKind::ALL.into_iter().filter(|&k| after.get(k) > before.get(k)).collect();
    assert!(kinds.len() <= 1, "more than one fault in one reply: {kinds:?}");
    kinds.first().copied()
}

/// Whether `fault` keeps a complete reply from coming in time, so that the
/// client waits its whole timeout out.
fn no_reply(fault: Option<FaultKind>) -> bool {
    matches!(fault, Some(FaultKind::Drop | FaultKind::Truncate | FaultKind::Delay))
}

/// After a call timed out: waits until the simulator has handled the
/// request and sent whatever it was going to send (late, cut short or
/// nothing), so that its counters and device state are final and nothing of
/// this call can reach the next one (the next call drops what is left as
/// stale input). The barrier is a request to another slave: the simulator
/// serves one request at a time and ignores that one, so once it has counted
/// it, it is done with ours. Bounded by [`SETTLE`], not by a sleep.
fn settle(probe: &mut Probe) {
    let seen = probe.server.device().stats().ignored_other_slave;
    let mut barrier = [BARRIER_ADDRESS, 0x03, 0x00, 0x00, 0x00, 0x01, 0, 0];
    let crc = crc16(&barrier[..6]).to_le_bytes();
    barrier[6..].copy_from_slice(&crc);
    probe.client.transport_mut().write_all(&barrier).expect("the barrier request is sent");
    probe.barriers += 1;
    let deadline = Instant::now() + SETTLE;
    while probe.server.device().stats().ignored_other_slave == seen {
        assert!(Instant::now() < deadline, "probe {}: the simulator did not catch up within {SETTLE:?}", probe.address);
        std::thread::sleep(Duration::from_millis(1));
    }
}

/// Reads the rest of a delayed reply whose first bytes (`head`, often none)
/// the client had when it gave up; returns the whole reply, which must be a
/// normal reply from the probe with a good CRC. Call after [`settle`]: the
/// simulator has sent it by then, so this waits for bytes in flight only.
fn late_reply(probe: &mut Probe, head: &[u8], context: &str) -> Vec<u8> {
    let mut frame = head.to_vec();
    let deadline = Instant::now() + SETTLE;
    loop {
        let want = match (frame.get(1), frame.get(2)) {
            (Some(0x03), Some(&count)) => 5 + usize::from(count),
            (Some(0x10), Some(_)) => 8,
            (Some(_), Some(_)) => panic!("{context}: the delayed reply is not a normal reply: {frame:02X?}"),
            _ => 3,
        };
        if frame.len() >= want {
            break;
        }
        let remaining = deadline.saturating_duration_since(Instant::now());
        assert!(!remaining.is_zero(), "{context}: the delayed reply never came in full: {frame:02X?}");
        let mut buf = [0u8; 256];
        let n = probe.client.transport_mut().read(&mut buf[..want - frame.len()], remaining).expect("the pty reads");
        frame.extend_from_slice(&buf[..n]);
    }
    assert!(
        frame.first() == Some(&probe.address) && crc_ok(&frame),
        "{context}: the delayed reply is not the probe's: {frame:02X?}"
    );
    frame
}

/// How a call's outcome relates to its fault.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Verdict {
    /// The outcome the fault implies.
    AsSpecified,
    /// A delayed reply taken late, the client having been held up past the
    /// delay: a correct reply (its values are checked), only late.
    Late,
    /// A timeout where a reply was due: the machine held it up past
    /// [`REPLY_TIMEOUT`].
    Stalled,
}

/// Checks that `outcome` is what `fault` implies, or a tolerated effect of
/// load (see [`Verdict`]); panics with the details otherwise.
fn check(fault: Option<FaultKind>, address: u8, outcome: &Outcome, context: &str) -> Verdict {
    use FaultKind as F;
    let verdict = match (fault, outcome) {
        (None | Some(F::Garbage), Ok(_)) => Some(Verdict::AsSpecified),
        (Some(F::Drop), Err(Error::Timeout { received: 0, .. })) => Some(Verdict::AsSpecified),
        // Cut short or late: the client has at most the first bytes (none
        // when it gave up before they came).
        (Some(F::Truncate | F::Delay), Err(Error::Timeout { .. })) => Some(Verdict::AsSpecified),
        (Some(F::Delay), Ok(_)) => Some(Verdict::Late),
        (Some(F::CorruptCrc), Err(Error::Frame { error: FrameError::Crc { .. }, .. })) => Some(Verdict::AsSpecified),
        (Some(F::WrongSlave), Err(Error::Frame { error: FrameError::WrongSlave { expected, actual }, .. })) => {
            (*expected == address && *actual == address + 1).then_some(Verdict::AsSpecified)
        }
        (Some(F::Busy), Err(e)) if e.exception() == Some(ExceptionCode::ServerDeviceBusy) => Some(Verdict::AsSpecified),
        (None | Some(F::Garbage | F::CorruptCrc | F::WrongSlave | F::Busy), Err(Error::Timeout { .. })) => {
            Some(Verdict::Stalled)
        }
        _ => None,
    };
    verdict.unwrap_or_else(|| panic!("{context}: fault {fault:?} gave {outcome:?}"))
}

#[derive(Debug, Default)]
struct Tally {
    calls: usize,
    ok: usize,
    values_checked: usize,
    writes_checked: usize,
    /// Clean calls right after a fault, and those that succeeded.
    recoveries_due: usize,
    recoveries: usize,
    /// Calls by the fault they drew ("none" for clean calls).
    by_kind: BTreeMap<&'static str, usize>,
    /// Calls by fault whose outcome was the one the fault implies.
    as_specified: BTreeMap<&'static str, usize>,
    late: usize,
    stalled: usize,
    /// Truncated replies of which the client had some bytes.
    truncated_seen: usize,
    /// Delayed replies read in full after the client gave up.
    late_replies_checked: usize,
    /// How long calls given [`REPLY_TIMEOUT`] took, when the reply came.
    reply_times: Vec<Duration>,
    slowest: Duration,
}

/// Runs `calls` operations against `probe`, checking each; returns the tally.
fn soak(probe: &mut Probe, ops: &[Op], calls: usize, rng: &mut Rng, tally: &mut Tally) {
    let mut previous_fault: Option<FaultKind> = None;
    for n in 0..calls {
        let op = ops[rng.below(ops.len() as u64) as usize].clone();
        let (k, b) = (rng.value(), rng.value());
        // New readings for a read; the current K and B for a write.
        let expected = match &op {
            Op::Read(command) => {
                let mut sim = probe.server.device();
                let names: Vec<String> = sim
                    .sensor()
                    .command(command)
                    .expect("the command")
                    .fields
                    .iter()
                    .filter(|f| is_f32(f))
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
        // The fault this call's reply will draw, to pick the timeout: one
        // that is waited out when no reply can come, generous otherwise.
        let scripted = probe.script.get(before.replies() as usize).copied().flatten();
        let timeout = if no_reply(scripted) { NO_REPLY_TIMEOUT } else { REPLY_TIMEOUT };
        probe.client.config_mut().timeout = timeout;
        let started = Instant::now();
        let outcome = call(probe, &op, k, b);
        let took = started.elapsed();
        let timed_out = matches!(outcome, Err(Error::Timeout { .. }));
        if timed_out {
            settle(probe);
        }
        let after = *probe.server.device().faults();
        let fault = injected(&before, &after);
        let context = format!("probe {} call {n} ({op:?})", probe.address);
        assert_eq!(fault, scripted, "{context}: the simulator drew another fault than its script's");
        let verdict = check(fault, probe.address, &outcome, &context);

        // Deadlines that hold under load: a timeout never comes early, and
        // no call hangs.
        if timed_out {
            assert!(took >= timeout, "{context}: gave up after {took:?}, before its timeout {timeout:?}");
        } else if timeout == REPLY_TIMEOUT {
            tally.reply_times.push(took);
        }
        assert!(took <= timeout + HANG, "{context}: took {took:?} with a timeout of {timeout:?}");
        tally.slowest = tally.slowest.max(took);
        if let Err(Error::Timeout { received, .. }) = &outcome {
            match fault {
                Some(FaultKind::Delay) => {
                    let received = probe.client.last_reply().to_vec();
                    late_reply(probe, &received, &context);
                    tally.late_replies_checked += 1;
                }
                Some(FaultKind::Truncate) => tally.truncated_seen += usize::from(*received > 0),
                _ => {}
            }
        }

        tally.calls += 1;
        let kind = fault.map_or("none", FaultKind::name);
        *tally.by_kind.entry(kind).or_default() += 1;
        match verdict {
            Verdict::AsSpecified => *tally.as_specified.entry(kind).or_default() += 1,
            Verdict::Late => tally.late += 1,
            Verdict::Stalled => tally.stalled += 1,
        }
        if previous_fault.is_some() && fault.is_none() {
            tally.recoveries_due += 1;
            tally.recoveries += usize::from(outcome.is_ok());
        }
        match (&op, &outcome) {
            (Op::Read(_), Ok(values)) => {
                let values = values.as_ref().expect("a read returns fields");
                assert_eq!(values, &expected, "{context}: a wrong value");
                tally.values_checked += values.len();
            }
            (Op::WriteKb(write, readback), _) => {
                // Applied unless the device was busy (it did not process it),
                // whatever the client saw (a timed-out call has settled).
                let now = truth(probe, readback);
                let written: Vec<(String, Owned)> = kb_values(probe.sensor.command(write).expect("the write"), k, b)
                    .iter()
                    .map(|(n, v)| (n.clone(), owned_value(v)))
                    .collect();
                let want = if fault == Some(FaultKind::Busy) { expected.clone() } else { written };
                assert_eq!(now, want, "{context}: the device state after the write");
                tally.writes_checked += 1;
            }
            _ => {}
        }
        tally.ok += usize::from(outcome.is_ok());
        previous_fault = fault;
    }
}

/// Checks what the simulator saw of the soak: every request intact, and
/// each barrier ignored as a request to another slave.
fn check_requests(probe: &Probe) {
    let stats = probe.server.device().stats().to_owned();
    assert_eq!(stats.ignored_bad_crc, 0, "probe {}: no request was garbled on the way", probe.address);
    assert_eq!(stats.ignored_other_slave, probe.barriers, "probe {}: the barriers, and only they", probe.address);
}

#[test]
fn fault_soak_through_the_pty() {
    if !yosemitech_tests::slow::enabled("the fault soak through a pty (about 30 s, load-sensitive)") {
        return;
    }
    let spec = spec();
    let mut rng = Rng(0x5EED_0FFA_1700);
    let (first, second) = probes(spec);
    let first_calls = CALLS * 2 / 3;
    let second_calls = CALLS - first_calls;
    let first_script = script(&mut rng, first_calls);
    let second_script = script(&mut rng, second_calls);
    let Some(mut one) = open(&first.sensor, FIRST_ADDRESS, first_script) else { return };
    let Some(mut two) = open(&second.sensor, SECOND_ADDRESS, second_script) else { return };

    let started = Instant::now();
    let mut tally = Tally::default();
    soak(&mut one, &ops(&first), first_calls, &mut rng, &mut tally);
    soak(&mut two, &ops(&second), second_calls, &mut rng, &mut tally);
    let elapsed = started.elapsed();

    tally.reply_times.sort();
    let median = tally.reply_times.get(tally.reply_times.len() / 2).copied().unwrap_or_default();
    let counts: Vec<String> = tally
        .by_kind
        .iter()
        .map(|(k, n)| format!("{k} {}/{n}", tally.as_specified.get(k).copied().unwrap_or(0)))
        .collect();
    yosemitech_tests::report!(
        "fault soak over ptys ({}, {}): {} calls in {:.1} s ({} ok, {} values and {} writes checked, {}/{} recoveries, \
         {} stalled, {} late, {} truncated replies seen, {} delayed replies read late), \
         replies in {median:?} (median), slowest call {:?}; as specified/calls by fault: {}",
        first.sensor.name,
        second.sensor.name,
        tally.calls,
        elapsed.as_secs_f64(),
        tally.ok,
        tally.values_checked,
        tally.writes_checked,
        tally.recoveries,
        tally.recoveries_due,
        tally.stalled,
        tally.late,
        tally.truncated_seen,
        tally.late_replies_checked,
        tally.slowest,
        counts.join(", ")
    );

    // Counts, not timing: they hold on a loaded machine, where the odd reply
    // may come too late (stalled, late), but a wrong value fails at once.
    assert_eq!(tally.calls, CALLS);
    for kind in FaultKind::ALL {
        let n = tally.by_kind.get(kind.name()).copied().unwrap_or(0);
        assert!(n >= 50, "only {n} faults of kind {kind}");
        let handled = tally.as_specified.get(kind.name()).copied().unwrap_or(0);
        assert!(2 * handled >= n, "only {handled} of {n} {kind} faults gave the outcome they imply");
    }
    let clean = tally.by_kind.get("none").copied().unwrap_or(0);
    let clean_ok = tally.as_specified.get("none").copied().unwrap_or(0);
    assert!(clean > 0 && 2 * clean_ok >= clean, "only {clean_ok} of {clean} clean calls succeeded");
    assert!(
        tally.recoveries_due > 0 && 2 * tally.recoveries >= tally.recoveries_due,
        "only {} of {} calls after a fault recovered",
        tally.recoveries,
        tally.recoveries_due
    );
    assert!(tally.truncated_seen > 0, "no truncated reply ever reached the client");
    assert!(tally.late_replies_checked > 0, "no delayed reply was read after the client gave up");
    // A client that waited for its deadline instead of the reply's end would
    // take REPLY_TIMEOUT per call; load costs milliseconds.
    assert!(median < REPLY_TIMEOUT / 10, "replies took {median:?} (median): the client waits out its timeout");
    check_requests(&one);
    check_requests(&two);
    one.server.stop().expect("the first server stops");
    two.server.stop().expect("the second server stops");
}

#[test]
fn function_code_addresses_with_noise_through_the_pty() {
    // Every reply of both probes preceded by noise: the case that misframed
    // before the client learned to realign (`AA 03 03 04 ...`). A reply held
    // up past REPLY_TIMEOUT by a stalled machine is tolerated, not more.
    let spec = spec();
    let (first, second) = probes(spec);
    let Some(mut one) = open(&first.sensor, FIRST_ADDRESS, vec![Some(FaultKind::Garbage); 200]) else { return };
    let Some(mut two) = open(&second.sensor, SECOND_ADDRESS, vec![Some(FaultKind::Garbage); 200]) else { return };
    let read = Op::Read(first.reads[0].name.clone());
    let field = first.reads[0].fields[0].name.clone().expect("a named field");
    let (write, readback) = (&second.write.0, &second.write.1);
    let written = Op::WriteKb(write.name.clone(), readback.name.clone());
    let (mut ok, mut stalled) = (0, 0);
    for i in 0..200 {
        let v = i as f32 * 0.5;
        one.server.device().set(&first.reads[0].name, &field, Value::Float(v)).expect("set");
        match call(&mut one, &read, 0.0, 0.0) {
            Ok(reply) => {
                let reply = reply.expect("a read returns fields");
                assert_eq!(
                    reply[0],
                    (field.clone(), Owned::Float(v.to_bits())),
                    "{read:?} {i} after noise: a wrong value"
                );
                ok += 1;
            }
            Err(Error::Timeout { .. }) => {
                settle(&mut one);
                stalled += 1;
            }
            Err(e) => panic!("{read:?} {i} after noise: {e}"),
        }
        match call(&mut two, &written, v, -v) {
            Ok(_) => ok += 1,
            Err(Error::Timeout { .. }) => {
                settle(&mut two);
                stalled += 1;
            }
            Err(e) => panic!("write {i} to 0x10 after noise: {e}"),
        }
        let now = truth(&two, &readback.name);
        let want: Vec<(String, Owned)> =
            kb_values(write, v, -v).iter().map(|(n, x)| (n.clone(), owned_value(x))).collect();
        assert_eq!(now, want, "write {i} to 0x10 after noise: applied");
    }
    assert!(ok >= 200, "only {ok} of 400 calls succeeded after noise ({stalled} stalled)");
    assert_eq!(one.server.device().faults().get(FaultKind::Garbage), 200);
    assert_eq!(two.server.device().faults().get(FaultKind::Garbage), 200);
    check_requests(&one);
    check_requests(&two);
}
