//! Device-write safety of the procedures (yosemitech::procedures), under
//! faults at every step:
//!
//! - a calibration hands the guide a backup of every coefficient before its
//!   first write, and whatever interrupts it afterwards (the link dying after
//!   point 2, a lost reply at any step), that backup is the probe's state
//!   before the calibration and restores it, verified by read-back;
//! - an address change never leaves the probe at an address the caller was
//!   not told: with a fault at any step, the result (success, or the
//!   failure's whereabouts) names the address the probe really answers at;
//! - an address another device answers at, even with an exception, is in use.

mod sim_common;

use sim_common::{sensor, spec};

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::time::Duration;

use yosemitech::procedures::address::{AddressChangeError, Whereabouts, change_address};
use yosemitech::procedures::coefficients::{self, PhOrpCoefficients};
use yosemitech::procedures::ph::{CalibrationConfig, CalibrationGuide, calibrate};
use yosemitech::procedures::{NoSleep, ProcedureError, Sleep};
use yosemitech::rtu::transport::Responder;
use yosemitech::yosemitech_common::{GetSn, GetSnResponse, SetSlaveId};
use yosemitech::{Client, ClientConfig, Command, Layout, ResponderTransport, RetryPolicy, ph_orp};
use yosemitech_sim::{FaultConfig, FaultKind, Simulator};
use yosemitech_spec::{Role, Sensor};

fn fast() -> ClientConfig {
    ClientConfig {
        timeout: Duration::from_millis(20),
        inter_frame_delay: Some(Duration::ZERO),
        retry: RetryPolicy::NONE,
        ..ClientConfig::default()
    }
}

/// Coefficients unlike the factory ones, so a restore is visible.
fn custom() -> PhOrpCoefficients {
    PhOrpCoefficients::from_array([6.5, -6.25, 0.125, 6.75, -6.5, -1.0, 1.03125, -0.0625, 0.96875, 2.5])
}

/// A guide that records what it was given, and how many writes had reached
/// the probe when the backup arrived.
struct Guide {
    writes: Arc<AtomicUsize>,
    backup: Option<PhOrpCoefficients>,
    writes_before_backup: Option<usize>,
    points: Vec<f32>,
}

impl Guide {
    fn new(writes: Arc<AtomicUsize>) -> Self {
        Self { writes, backup: None, writes_before_backup: None, points: Vec::new() }
    }
}

impl CalibrationGuide for Guide {
    fn backed_up(&mut self, backup: &PhOrpCoefficients) -> bool {
        self.backup = Some(*backup);
        self.writes_before_backup = Some(self.writes.load(Ordering::SeqCst));
        true
    }
    fn immerse(&mut self, _index: usize, _standard_ph: f32) -> bool {
        true
    }
    fn settle(&mut self, _index: usize, duration: Duration, sleep: &mut dyn Sleep) {
        sleep.sleep(duration);
    }
    fn point_written(&mut self, _index: usize, standard_ph: f32) {
        self.points.push(standard_ph);
    }
}

/// A simulator behind a link that can be cut: counts the writes that reach
/// the probe and, once `cut_after_points` calibration points went through,
/// drops everything until `alive` is set again.
struct Link {
    sim: Simulator,
    writes: Arc<AtomicUsize>,
    points: usize,
    cut_after_points: Option<usize>,
    alive: Arc<AtomicBool>,
}

impl Responder for Link {
    fn respond(&mut self, request: &[u8], reply: &mut Vec<u8>) {
        if !self.alive.load(Ordering::SeqCst) {
            return;
        }
        if request.get(1) == Some(&0x10) {
            self.writes.fetch_add(1, Ordering::SeqCst);
        }
        self.sim.respond(request, reply);
        // A calibration point of the pH manual (start_ph_calibration).
        if ph_orp::identify_request(request) == Some(ph_orp::CommandId::StartPhCalibration) {
            self.points += 1;
            if Some(self.points) == self.cut_after_points {
                self.alive.store(false, Ordering::SeqCst);
            }
        }
    }
}

/// Whether `sensor`'s command with `role` is the shared command of `layout`.
fn plays(sensor: &Sensor, role: Role, layout: Layout<'static>) -> bool {
    sensor.command_with_role(role).is_some_and(|c| c.layout() == layout)
}

/// Every sensor of the spec whose slave-address write and serial-number read
/// are the shared `SetSlaveId` and `GetSn`, picked from the spec by role.
fn address_sensors() -> Vec<Sensor> {
    let sensors: Vec<Sensor> = spec()
        .sensors
        .into_iter()
        .filter(|s| plays(s, Role::SetSlaveAddress, SetSlaveId::LAYOUT) && plays(s, Role::SerialNumber, GetSn::LAYOUT))
        .collect();
    assert!(!sensors.is_empty(), "the spec has sensors with the shared address commands");
    sensors
}

fn probe_with(
    coefficients: &PhOrpCoefficients,
    faults: FaultConfig,
    cut_after_points: Option<usize>,
) -> (Client<ResponderTransport<Link>>, Arc<AtomicUsize>, Arc<AtomicBool>) {
    let mut client = Client::with_config(ResponderTransport::new(Simulator::new(sensor(ph_orp::SENSOR.name))), fast());
    coefficients::write_ph_orp(&mut ph_orp::Device::new(&mut client, 1), coefficients)
        .expect("set up the coefficients");
    let mut sim = client.into_transport().into_responder();
    sim.set_faults(faults);
    let writes = Arc::new(AtomicUsize::new(0));
    let alive = Arc::new(AtomicBool::new(true));
    let link = Link { sim, writes: Arc::clone(&writes), points: 0, cut_after_points, alive: Arc::clone(&alive) };
    (Client::with_config(ResponderTransport::new(link), fast()), writes, alive)
}

#[test]
fn a_calibration_cut_off_after_point_2_leaves_a_backup_that_restores() {
    // Covers the pH/ORP manual's three-point pH calibration and its coefficient backup.
    let before = custom();
    let (mut client, writes, alive) = probe_with(&before, FaultConfig::none(), Some(2));
    let mut guide = Guide::new(Arc::clone(&writes));
    let mut probe = ph_orp::Device::new(&mut client, 1);
    let result = calibrate(&mut probe, &CalibrationConfig::default(), &mut guide, &mut NoSleep::default());

    // The link died after the second point: the third fails, with a device error.
    match &result {
        Err(ProcedureError::Device(e)) => assert!(e.is_timeout(), "{e}"),
        other => panic!("expected the interrupted calibration to fail, got {other:?}"),
    }
    assert_eq!(guide.points, [4.00, 6.86], "two points went through");
    assert_eq!(guide.writes_before_backup, Some(0), "the backup came before any write");
    assert_eq!(guide.backup, Some(before), "the backup is the state before the calibration");

    // The link comes back: the backup restores every coefficient, verified.
    alive.store(true, Ordering::SeqCst);
    let backup = guide.backup.expect("a backup");
    coefficients::write_ph_orp(&mut probe, &backup).expect("the restore succeeds and reads back");
    assert_eq!(coefficients::read_ph_orp(&mut probe).expect("read"), before);
}

#[test]
fn a_fault_at_any_step_of_a_calibration_never_loses_the_backup() {
    // Covers the pH/ORP manual's three-point pH calibration and its coefficient backup.
    let before = custom();
    let mut outcomes = [0usize; 3]; // completed, failed before the backup, failed after it
    for kind in [FaultKind::Drop, FaultKind::CorruptCrc, FaultKind::Truncate, FaultKind::WrongSlave, FaultKind::Busy] {
        // A calibration is 3 backup reads, 3 points, a status read and 3 reads after: 10 replies.
        for at in 0..11 {
            let mut script = vec![None; at];
            script.push(Some(kind));
            let (mut client, writes, _alive) = probe_with(&before, FaultConfig::scripted(script), None);
            let mut guide = Guide::new(Arc::clone(&writes));
            let mut probe = ph_orp::Device::new(&mut client, 1);
            let result = calibrate(&mut probe, &CalibrationConfig::default(), &mut guide, &mut NoSleep::default());
            let context = format!("{kind} at reply {at}");
            match (&result, guide.backup) {
                (Ok(report), Some(backup)) => {
                    assert_eq!(backup, before, "{context}");
                    assert_eq!(report.backup, before, "{context}");
                    outcomes[0] += 1;
                }
                (Err(_), None) => {
                    assert_eq!(writes.load(Ordering::SeqCst), 0, "{context}: a write without a backup");
                    outcomes[1] += 1;
                }
                (Err(_), Some(backup)) => {
                    assert_eq!(backup, before, "{context}: the backup is the state before");
                    assert_eq!(guide.writes_before_backup, Some(0), "{context}");
                    // One command (here: one call) puts everything back.
                    coefficients::write_ph_orp(&mut probe, &backup).expect("the restore succeeds");
                    assert_eq!(coefficients::read_ph_orp(&mut probe).expect("read"), before, "{context}");
                    outcomes[2] += 1;
                }
                (Ok(_), None) => panic!("{context}: a calibration without a backup"),
            }
        }
    }
    assert!(outcomes[1] > 0 && outcomes[2] > 0, "{outcomes:?}");
    yosemitech_tests::report!(
        "write safety: calibrations with a fault at every step: {} completed, {} stopped before the backup \
         (nothing written), {} stopped after it (restored from the backup)",
        outcomes[0],
        outcomes[1],
        outcomes[2]
    );
}

/// Where the simulated probe answers after `change_address`, checked
/// against what the result told the caller.
fn told_address(result: &Result<GetSnResponse, AddressChangeError>, from: u8, to: u8) -> Option<u8> {
    match result {
        Ok(_) => Some(to),
        Err(AddressChangeError::Failed { whereabouts: Whereabouts::New(a), .. }) => Some(*a),
        Err(AddressChangeError::Failed { whereabouts: Whereabouts::Old(a), .. }) => Some(*a),
        Err(AddressChangeError::Failed { whereabouts: Whereabouts::Unknown { .. }, .. }) => None,
        Err(_) => Some(from),
    }
}

#[test]
fn an_address_change_with_a_fault_at_any_step_says_where_the_probe_is() {
    let (from, to) = (1u8, 20u8);
    let sensors = address_sensors();
    let mut checked = 0;
    for sensor in &sensors {
        for kind in [
            FaultKind::Drop,
            FaultKind::CorruptCrc,
            FaultKind::Truncate,
            FaultKind::WrongSlave,
            FaultKind::Busy,
            FaultKind::Garbage,
        ] {
            // Replies: the probe at `from`, the write's confirmation, the probe at `to`, then locating.
            for at in 0..6 {
                let mut script = vec![None; at];
                script.push(Some(kind));
                let sim = Simulator::new(sensor.clone()).with_address(from).with_faults(FaultConfig::scripted(script));
                let mut client = Client::with_config(ResponderTransport::new(sim), fast());
                let result = change_address(&mut client, from, to, &SetSlaveId { slave_address: to }, &GetSn);
                let sim = client.into_transport().into_responder();
                let context = format!("{}: {kind} at reply {at}: {result:?}", sensor.name);
                let told = told_address(&result, from, to);
                assert_eq!(told, Some(sim.address()), "{context}: the probe is at {}", sim.address());
                if matches!(result, Err(AddressChangeError::NotFound { .. } | AddressChangeError::AddressInUse(_))) {
                    assert_eq!(sim.stats().writes, 0, "{context}: written although refused");
                }
                checked += 1;
            }
        }
    }
    yosemitech_tests::report!(
        "write safety: {checked} address changes ({} sensors picked from the spec by role) with a fault at one \
         step each, all told the truth",
        sensors.len()
    );
}

#[test]
fn an_address_answered_with_an_exception_is_in_use() {
    for sensor in address_sensors() {
        let name = sensor.name.clone();
        // Another kind of device at 2 answers every request, with exception 02
        // (it has no serial-number register). It is there: moving the probe to 2
        // would put two devices at one address.
        let mut sim = Simulator::new(sensor).with_address(1);
        let responder = move |request: &[u8], reply: &mut Vec<u8>| match request.first() {
            Some(&2) => {
                let mut frame = vec![2, request.get(1).copied().unwrap_or(0) | 0x80, 0x02];
                frame.extend_from_slice(&yosemitech::rtu::crc16(&frame).to_le_bytes());
                reply.extend_from_slice(&frame);
            }
            _ => sim.respond(request, reply),
        };
        let mut client = Client::with_config(ResponderTransport::new(responder), fast());
        let result = change_address(&mut client, 1, 2, &SetSlaveId { slave_address: 2 }, &GetSn);
        assert!(matches!(result, Err(AddressChangeError::AddressInUse(2))), "{name}: {result:?}");
        assert!(client.call(1, &GetSn).is_ok(), "{name}: the probe stays at 1");
    }
}
