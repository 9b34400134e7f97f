//! The manuals' procedures (yosemitech::procedures) against the simulator.

use yosemitech_tests::sim as sim_common;

use sim_common::sensor;

use std::time::Duration;

use yosemitech::conductivity::{GetTemperatureAndConductivity, GetTemperatureAndConductivityResponse, RangeStatus};
use yosemitech::procedures::address::{AddressChangeError, Whereabouts, change_address};
use yosemitech::procedures::coefficients::{self, PhOrpCoefficients};
use yosemitech::procedures::conductivity::{MeasurementConfig, MeasurementEvent, measure, tds_mg_l};
use yosemitech::procedures::ph::{CalibrationConfig, CalibrationGuide, calibrate};
use yosemitech::procedures::{NoSleep, ProcedureError, Sleep};
use yosemitech::rtu::transport::Responder;
use yosemitech::yosemitech_common::{GetSn, SetSlaveId};
use yosemitech::{Client, ClientConfig, Command, Message, ResponderTransport, RetryPolicy, conductivity, ph_orp};
use yosemitech_sim::{Bus, Simulator};
use yosemitech_spec::Sensor;

fn fast() -> ClientConfig {
    ClientConfig {
        timeout: Duration::from_millis(30),
        inter_frame_delay: Some(Duration::ZERO),
        retry: RetryPolicy { retries: 0, ..RetryPolicy::default() },
        ..ClientConfig::default()
    }
}

fn client<R: Responder>(responder: R) -> Client<ResponderTransport<R>> {
    Client::with_config(ResponderTransport::new(responder), fast())
}

/// Two addresses of `sensor`'s: where its probe starts and where it moves
/// (the second outside its addresses only for a sensor that has one).
fn address_pair(sensor: &Sensor) -> (u8, u8) {
    let to = sim_common::free_address(sensor, &[]).unwrap_or(sensor.default_address);
    let from = sim_common::free_address(sensor, &[to]).unwrap_or(if to == 1 { 2 } else { 1 });
    (from, to)
}

/// Every sensor of the spec whose slave-address write and serial-number read
/// are the shared `SetSlaveId` and `GetSn`, picked from the spec by role.
fn address_sensors() -> Vec<Sensor> {
    let sensors = sim_common::sensors_sharing_address_commands(SetSlaveId::LAYOUT, GetSn::LAYOUT);
    assert!(sensors.len() >= 2, "the spec has sensors with the shared address commands");
    sensors
}

/// The conductivity manual's reading in the simulator's registers, changed
/// through the generated reply type (no field names in strings).
fn set_reading(sim: &mut Simulator, change: impl FnOnce(&mut GetTemperatureAndConductivityResponse)) {
    let (address, count) = (GetTemperatureAndConductivity::ADDRESS, GetTemperatureAndConductivity::COUNT);
    let data = sim.registers().read(address, count);
    let data = data.as_slice().try_into().expect("the reply's registers");
    let mut reading = GetTemperatureAndConductivityResponse::from_data(data);
    change(&mut reading);
    sim.registers_mut().write(address, &reading.to_data());
}

/// Whether `request` is the conductivity manual's reading.
fn is_reading(request: &[u8]) -> bool {
    conductivity::identify_request(request) == Some(conductivity::CommandId::GetTemperatureAndConductivity)
}

#[test]
fn conductivity_measurement_averages_the_manuals_count_and_computes_tds() {
    // Covers the conductivity manual's measurement (warm-up, averaging, TDS).
    let mut sim = Simulator::new(sensor(conductivity::SENSOR.name));
    let mut reads = 0u32;
    // Readings 1.0, 2.0, ... so the mean of the first ten is 5.5.
    let responder = move |request: &[u8], reply: &mut Vec<u8>| {
        if is_reading(request) {
            reads += 1;
            set_reading(&mut sim, |r| {
                r.conductivity_ms_cm = reads as f32;
                r.temperature_c = 20.0;
            });
        }
        sim.respond(request, reply);
    };
    let mut client = client(responder);
    let mut probe = conductivity::Device::new(&mut client, 1);
    let mut sleep = NoSleep::default();
    let mut events = Vec::new();
    let m = measure(&mut probe, &MeasurementConfig::default(), &mut sleep, &mut |e| events.push(e)).unwrap();
    assert_eq!(m.readings, 10);
    assert_eq!(m.discarded, 0);
    assert_eq!(m.conductivity_ms_cm, 5.5);
    assert_eq!(m.temperature_c, 20.0);
    assert!((m.tds_mg_l - 5.5 * 640.0).abs() < 0.01, "{}", m.tds_mg_l);
    // Warm-up 10 s plus 9 intervals of 3 s, as the manual says.
    assert_eq!(sleep.requested, Duration::from_secs(10 + 9 * 3));
    assert!(matches!(events.first(), Some(MeasurementEvent::WarmingUp { .. })));
    assert_eq!(events.len(), 11);
}

#[test]
fn flagged_readings_are_discarded_and_replaced() {
    // Covers the conductivity manual's measurement: range-switch flags.
    let mut sim = Simulator::new(sensor(conductivity::SENSOR.name));
    let mut reads = 0u32;
    let responder = move |request: &[u8], reply: &mut Vec<u8>| {
        if is_reading(request) {
            reads += 1;
            // Every third reading has a range-switch error and an absurd value.
            let flagged = reads.is_multiple_of(3);
            set_reading(&mut sim, |r| {
                r.range_status = if flagged { RangeStatus::RangeSwitchError } else { RangeStatus::Ok };
                r.conductivity_ms_cm = if flagged { 999.0 } else { 2.0 };
            });
        }
        sim.respond(request, reply);
    };
    let mut client = client(responder);
    let mut probe = conductivity::Device::new(&mut client, 1);
    let m = measure(&mut probe, &MeasurementConfig::default(), &mut NoSleep::default(), &mut |_| {}).unwrap();
    assert_eq!(m.readings, 10);
    assert_eq!(m.discarded, 4, "reads 3, 6, 9, 12 are flagged before 10 good ones arrive");
    assert_eq!(m.conductivity_ms_cm, 2.0, "flagged values never reach the mean");
    assert_eq!(m.tds_mg_l, tds_mg_l(2.0));
}

#[test]
fn measurement_gives_up_when_every_reading_is_flagged() {
    // Covers the conductivity manual's measurement: range-switch flags.
    let mut sim = Simulator::new(sensor(conductivity::SENSOR.name));
    set_reading(&mut sim, |r| r.range_status = RangeStatus::RangeSwitchError);
    let mut client = client(sim);
    let mut probe = conductivity::Device::new(&mut client, 1);
    let config = MeasurementConfig { readings: 3, max_reads: 5, ..MeasurementConfig::default() };
    match measure(&mut probe, &config, &mut NoSleep::default(), &mut |_| {}) {
        Err(ProcedureError::NotEnoughReadings { accepted: 0, needed: 3, discarded: 5 }) => {}
        other => panic!("expected NotEnoughReadings, got {other:?}"),
    }
}

/// Records what the procedure asked of the user.
#[derive(Default)]
struct Recorder {
    backup: Option<PhOrpCoefficients>,
    immersed: Vec<f32>,
    written: Vec<f32>,
    refuse_backup: bool,
}

impl CalibrationGuide for Recorder {
    fn backed_up(&mut self, backup: &PhOrpCoefficients) -> bool {
        self.backup = Some(*backup);
        !self.refuse_backup
    }
    fn immerse(&mut self, _index: usize, standard_ph: f32) -> bool {
        self.immersed.push(standard_ph);
        true
    }
    fn settle(&mut self, _index: usize, duration: Duration, sleep: &mut dyn Sleep) {
        sleep.sleep(duration);
    }
    fn point_written(&mut self, _index: usize, standard_ph: f32) {
        self.written.push(standard_ph);
    }
}

#[test]
fn ph_calibration_runs_the_three_points_in_order_after_a_backup() {
    // Covers the pH/ORP manual's three-point pH calibration.
    let mut client = client(Simulator::new(sensor(ph_orp::SENSOR.name)));
    let mut probe = ph_orp::Device::new(&mut client, 1);
    let before = coefficients::read_ph_orp(&mut probe).unwrap();
    let mut guide = Recorder::default();
    let mut sleep = NoSleep::default();
    let report = calibrate(&mut probe, &CalibrationConfig::default(), &mut guide, &mut sleep).unwrap();
    assert!(report.succeeded(), "{:?}", report.status);
    assert_eq!(guide.immersed, [4.00, 6.86, 9.18]);
    assert_eq!(guide.written, [4.00, 6.86, 9.18]);
    assert_eq!(guide.backup, Some(before));
    assert_eq!(report.backup, before);
    assert_eq!(sleep.requested, Duration::from_secs(3 * 60), "a minute in each buffer");
}

#[test]
fn ph_calibration_in_the_wrong_order_reports_the_probes_status() {
    // Covers the pH/ORP manual's three-point pH calibration.
    let mut client = client(Simulator::new(sensor(ph_orp::SENSOR.name)));
    let mut probe = ph_orp::Device::new(&mut client, 1);
    let config = CalibrationConfig { standards: [6.86, 4.00, 9.18], ..CalibrationConfig::default() };
    let report = calibrate(&mut probe, &config, &mut Recorder::default(), &mut NoSleep::default()).unwrap();
    assert!(!report.succeeded());
    assert_eq!(report.status, ph_orp::CalibrationStatus::NotACalibrationStandard);
}

#[test]
fn nothing_is_written_when_the_backup_cannot_be_kept() {
    // Covers the pH/ORP manual's three-point pH calibration (its backup).
    let sim = Simulator::new(sensor(ph_orp::SENSOR.name));
    let mut client = client(sim);
    let mut probe = ph_orp::Device::new(&mut client, 1);
    let mut guide = Recorder { refuse_backup: true, ..Recorder::default() };
    let result = calibrate(&mut probe, &CalibrationConfig::default(), &mut guide, &mut NoSleep::default());
    assert!(matches!(result, Err(ProcedureError::Aborted)));
    assert!(guide.written.is_empty());
    let sim = client.into_transport().into_responder();
    assert_eq!(sim.stats().writes, 0, "no write reached the probe");
}

#[test]
fn coefficients_restore_with_read_back() {
    // Covers the pH/ORP and conductivity manuals' coefficient backup and restore.
    let mut client = client(Simulator::new(sensor(ph_orp::SENSOR.name)));
    let mut probe = ph_orp::Device::new(&mut client, 1);
    let original = coefficients::read_ph_orp(&mut probe).unwrap();
    assert_eq!(original.electrode, ph_orp::DEFAULT_ELECTRODE_COEFFICIENTS);
    let changed = PhOrpCoefficients::from_array([1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 0.9, 0.1, 1.1, -0.5]);
    coefficients::write_ph_orp(&mut probe, &changed).unwrap();
    assert_eq!(coefficients::read_ph_orp(&mut probe).unwrap(), changed);
    coefficients::write_ph_orp(&mut probe, &original).unwrap();
    assert_eq!(coefficients::read_ph_orp(&mut probe).unwrap(), original);

    let mut client = self::client(Simulator::new(sensor(conductivity::SENSOR.name)));
    let mut probe = conductivity::Device::new(&mut client, 1);
    let c = coefficients::ConductivityCoefficients { user_calibration: [1.02, -0.003] };
    coefficients::write_conductivity(&mut probe, &c).unwrap();
    assert_eq!(coefficients::read_conductivity(&mut probe).unwrap(), c);
}

#[test]
fn a_write_that_does_not_stick_is_caught_by_read_back() {
    // Covers the conductivity manual's coefficient restore.
    let mut sim = Simulator::new(sensor(conductivity::SENSOR.name));
    // A probe that acknowledges the write but keeps its old coefficients.
    let responder = move |request: &[u8], reply: &mut Vec<u8>| {
        if request.get(1) == Some(&0x10) {
            let echo = &request[..6];
            reply.extend_from_slice(echo);
            reply.extend_from_slice(&yosemitech::rtu::crc16(echo).to_le_bytes());
        } else {
            sim.respond(request, reply);
        }
    };
    let mut client = client(responder);
    let mut probe = conductivity::Device::new(&mut client, 1);
    let c = coefficients::ConductivityCoefficients { user_calibration: [2.0, 1.0] };
    assert!(matches!(coefficients::write_conductivity(&mut probe, &c), Err(ProcedureError::ReadBackMismatch { .. })));
}

#[test]
fn address_change_is_validated_confirmed_and_verified() {
    let mut with_code = 0;
    for sensor in address_sensors() {
        let (name, model_code) = (sensor.name.clone(), sensor.model_code.clone());
        // From one of the sensor's addresses to another.
        let (from, to) = address_pair(&sensor);
        let mut client = client(Simulator::new(sensor).with_address(from));
        let before = client.call(from, &GetSn).unwrap();
        let serial = before.serial_number.as_str().expect("a text serial number").to_owned();
        // The simulator puts the model code in characters 3-4 of a serial number that has them.
        if let Some(code) =
            model_code.filter(|_| serial.len() >= 4 && serial.bytes().take(4).all(|b| b.is_ascii_graphic()))
        {
            assert_eq!(&serial[2..4], code, "{name}: {serial} carries the model code {code}");
            with_code += 1;
        }
        let reply = change_address(&mut client, from, to, &SetSlaveId { slave_address: to }, &GetSn).unwrap();
        assert_eq!(reply.serial_number.as_str(), Some(serial.as_str()), "{name}: the same probe answers at {to}");
        assert!(client.call(from, &GetSn).is_err(), "{name}: the old address is gone");
        assert!(client.call(to, &GetSn).is_ok(), "{name}");

        for bad in [0u8, 248] {
            let err = change_address(&mut client, to, bad, &SetSlaveId { slave_address: bad }, &GetSn);
            assert!(matches!(err, Err(AddressChangeError::InvalidAddress(a)) if a == bad), "{name}");
        }
        let same = change_address(&mut client, to, to, &SetSlaveId { slave_address: to }, &GetSn);
        assert!(matches!(same, Err(AddressChangeError::SameAddress(a)) if a == to), "{name}");
        // Nobody at `absent`: refused before anything is written.
        let absent = (1..=247).find(|a| *a != to).unwrap();
        let other = (1..=247).find(|a| *a != to && *a != absent).unwrap();
        let missing = change_address(&mut client, absent, other, &SetSlaveId { slave_address: other }, &GetSn);
        assert!(matches!(missing, Err(AddressChangeError::NotFound { address, .. }) if address == absent), "{name}");
    }
    yosemitech_tests::report!(
        "address changes: {} sensors by role, {with_code} serial numbers with their model code",
        address_sensors().len()
    );
}

#[test]
fn address_change_refuses_an_address_in_use() {
    // Each sensor at 1, another sensor of the spec at 2.
    let sensors = address_sensors();
    for (i, sensor) in sensors.iter().enumerate() {
        let other = &sensors[(i + 1) % sensors.len()];
        let bus = Bus::new()
            .with(Simulator::new(sensor.clone()).with_address(1))
            .with(Simulator::new(other.clone()).with_address(2));
        let mut client = client(bus);
        let err = change_address(&mut client, 1, 2, &SetSlaveId { slave_address: 2 }, &GetSn);
        let context = format!("{} with {} at 2", sensor.name, other.name);
        assert!(matches!(err, Err(AddressChangeError::AddressInUse(2))), "{context}");
        let bus = client.into_transport().into_responder();
        assert_eq!(bus.device(1).map(|d| d.stats().writes), Some(0), "{context}: nothing was written");
    }
}

#[test]
fn a_lost_confirmation_still_tells_where_the_probe_is() {
    for sensor in address_sensors() {
        let name = sensor.name.clone();
        let (from, to) = address_pair(&sensor);
        let mut sim = Simulator::new(sensor).with_address(from);
        // The probe applies the new address but its reply is lost on the line.
        let responder = move |request: &[u8], reply: &mut Vec<u8>| {
            sim.respond(request, reply);
            if SetSlaveId::decode_request(request).is_ok() {
                reply.clear();
            }
        };
        let mut client = client(responder);
        match change_address(&mut client, from, to, &SetSlaveId { slave_address: to }, &GetSn) {
            Err(AddressChangeError::Failed { error, whereabouts }) => {
                assert!(error.is_timeout(), "{name}");
                assert_eq!(whereabouts, Whereabouts::New(to), "{name}");
            }
            other => panic!("{name}: expected a failure with whereabouts, got {other:?}"),
        }
    }
}

#[test]
fn non_finite_coefficients_are_refused_before_any_write() {
    // Covers the conductivity manual's coefficient restore.
    let mut client = client(Simulator::new(sensor(conductivity::SENSOR.name)));
    let mut probe = conductivity::Device::new(&mut client, 1);
    for bad in [f32::NAN, f32::INFINITY] {
        let c = coefficients::ConductivityCoefficients { user_calibration: [bad, 0.0] };
        assert!(matches!(coefficients::write_conductivity(&mut probe, &c), Err(ProcedureError::NotFinite { .. })));
    }
    let sim = client.into_transport().into_responder();
    assert_eq!(sim.stats().writes, 0);
}

#[test]
fn device_handles_change_their_address_with_verification() {
    // Covers the typed handles of the conductivity and pH/ORP manuals (procedures/device.rs).
    let mut bus = client(Simulator::new(sensor(conductivity::SENSOR.name)));
    let mut probe = conductivity::Device::new(&mut bus, 1);
    probe.set_slave_address(42).unwrap();
    assert_eq!(probe.address(), 42);
    assert_eq!(probe.sn().unwrap().serial_number.as_str(), Some("YL0914010022"), "the handle follows the probe");
    assert!(matches!(probe.set_slave_address(0), Err(AddressChangeError::InvalidAddress(0))));
    assert_eq!(probe.address(), 42, "a refused change leaves the handle where the probe is");

    let mut bus = client(Simulator::new(sensor(ph_orp::SENSOR.name)));
    let mut probe = ph_orp::Device::new(&mut bus, 1);
    probe.set_slave_address(7).unwrap();
    assert_eq!(probe.ph().unwrap().ph, 7.6);
}
