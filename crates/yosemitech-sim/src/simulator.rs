//! One simulated sensor: register state, request handling, exceptions, faults.

use std::collections::BTreeMap;
use std::fmt;
use std::sync::Arc;
use std::time::{Duration, Instant};

use yosemitech_rtu::bytes::{byte, word};
use yosemitech_rtu::frame::{BROADCAST, REQUEST_BYTE_COUNT_AT, encode_exception};
use yosemitech_rtu::{
    EncodeError, ExceptionCode, Function, Layout, LineTiming, Responder, codec, crc_ok, crc16, segment,
};
use yosemitech_spec::interp::{EncodeValuesError, decode_field, decode_fields, encode_command_field};
use yosemitech_spec::{CommandSpec, EnumRepr, Field, FieldKind, Role, Sensor, Value, Values};

use crate::FrameHandler;
use crate::bath::{Bath, Standard};
use crate::behaviour::{
    AddressSlot, Behaviour, MeasurementState, SerialNumber, SerialNumberPolicy, WarmUpPolicy, address_slots, role_index,
};
use crate::fault::{FaultConfig, FaultCounts, FaultKind, Injector, Rng};
use crate::registers::{RegisterMap, reads_of_their_own};

/// Why a value could not be read or set through the simulator's API.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub enum SimError {
    /// The sensor has no command of that name.
    UnknownCommand(String),
    /// The command has no field of that name.
    UnknownField {
        /// The command asked for (not one of the sensor's).
        command: String,
        /// The field asked for (not one of the command's).
        field: String,
    },
    /// No read command has a field of that name ([`Simulator::set_everywhere`]).
    NoSuchField(String),
    /// The value does not fit the field (wrong type, outside its `range`).
    Value(EncodeValuesError),
}

impl fmt::Display for SimError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::UnknownCommand(name) => write!(f, "no command called `{name}`"),
            Self::UnknownField { command, field } => write!(f, "command `{command}` has no field `{field}`"),
            Self::NoSuchField(field) => write!(f, "no read command has a field `{field}`"),
            Self::Value(e) => write!(f, "{e}"),
        }
    }
}

impl std::error::Error for SimError {}

impl From<EncodeValuesError> for SimError {
    fn from(e: EncodeValuesError) -> Self {
        Self::Value(e)
    }
}

/// What the simulator did with the requests it was given.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Stats {
    /// Request frames handled, whatever their fate.
    pub requests: u64,
    /// Replies produced (normal or exception; before fault injection, so a
    /// dropped reply counts here and in [`FaultCounts`]).
    pub replies: u64,
    /// Requests ignored for a bad CRC (or too short to carry one).
    pub ignored_bad_crc: u64,
    /// Requests ignored because they were for another slave.
    pub ignored_other_slave: u64,
    /// Requests to the device that match no command of the sensor (unknown
    /// function, unknown address, wrong count, malformed), ignored under
    /// [`UnknownRequestPolicy::Silent`] (the default).
    pub ignored_unknown: u64,
    /// Broadcast requests (applied if they were writes, never answered).
    pub broadcasts: u64,
    /// Exception replies produced by the rules (03 for a value out of
    /// range; 01, 02, 03 for unknown requests under
    /// [`UnknownRequestPolicy::Exception`]; 06 under [`WarmUpPolicy::Busy`]);
    /// injected busy faults are in [`FaultCounts`].
    pub exceptions: u64,
    /// Reads answered with register data.
    pub reads: u64,
    /// Writes applied (broadcasts included).
    pub writes: u64,
    /// Slave address changes made by writes.
    pub address_changes: u64,
}

/// Deterministic variation of the readings: a daily cycle, noise and drift.
///
/// On each read of a *measurement* command (a read that no write command
/// covers and that has a field with a unit: pH, temperature, conductivity,
/// ORP), every f32 field is set to
/// `base + swing * span * sin(2 pi t / day + phase) + drift_per_read * n + noise * u`
/// before the reply is built, where `base` is the value when the variation
/// was enabled or last [`Simulator::set`] (see [`Simulator::fill_with_water`]
/// for plausible ones), `span` from [`daily_span`], `t`
/// the time of day (the wall clock, so probes on one bus see the same
/// water; the manual clock when [`Simulator::with_manual_clock`]), `phase`
/// the same for every temperature (unit `degC`) and different for other
/// fields, `n` the number of earlier reads of the command and `u` uniform in
/// `[-1, 1)` from a generator seeded with `seed`; clamped to the field's
/// `range` if it has one. The registers hold what was sent, so
/// [`Simulator::get`] after a read is the truth the client saw.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Variation {
    /// Seed of the noise: the same seed gives the same readings.
    pub seed: u64,
    /// Noise amplitude, in the field's unit.
    pub noise: f32,
    /// Drift per read, in the field's unit.
    pub drift_per_read: f32,
    /// Amplitude of the daily cycle, as a fraction of the field's span (0: none).
    pub daily_swing: f32,
    /// Length of the simulated day (a shorter one shows the cycle sooner).
    pub day: Duration,
}

impl Variation {
    /// Noise and drift only, no daily cycle.
    pub const fn noise(seed: u64, noise: f32, drift_per_read: f32) -> Self {
        Self { seed, noise, drift_per_read, daily_swing: 0.0, day: Duration::from_secs(86_400) }
    }

    /// Natural water: a daily cycle of `daily_swing` of each field's span
    /// over `day`, and a little noise.
    pub const fn water(seed: u64, daily_swing: f32, day: Duration) -> Self {
        Self { seed, noise: 0.0, drift_per_read: 0.0, daily_swing, day }
    }
}

/// The temperature of the simulated water, degrees C, before its daily
/// cycle: a plausible river in spring.
pub const WATER_TEMPERATURE_C: f64 = 18.0;

/// The span a temperature's daily swing is a fraction of, degrees C, the
/// same for every probe whatever its range, so they all read one water.
pub const WATER_TEMPERATURE_SPAN_C: f64 = 50.0;

/// The span a field's daily swing is a fraction of ([`Variation::daily_swing`]):
/// [`WATER_TEMPERATURE_SPAN_C`] for a temperature; for a field with a
/// `typical` value, twice that value, but no more than its range (a river's
/// 12 NTU swings by NTUs, not by the hundreds a 0-1000 NTU range allows);
/// else its range, or `|base|` (at least 1) without one.
pub fn daily_span(field: &Field, base: f32) -> f64 {
    let range = field.range.map(|(min, max)| (max - min).max(0.0));
    match (field.typical, range) {
        _ if field.unit.as_deref() == Some("degC") => WATER_TEMPERATURE_SPAN_C,
        (Some(typical), Some(range)) => (2.0 * typical.abs()).min(range),
        (Some(typical), None) => 2.0 * typical.abs(),
        (None, Some(range)) => range,
        (None, None) => f64::from(base.abs()).max(1.0),
    }
}

#[derive(Debug, Clone)]
struct VariationState {
    config: Variation,
    rng: Rng,
    /// Base value by (command index, field index).
    bases: BTreeMap<(usize, usize), f32>,
    /// Reads served by command index.
    reads: BTreeMap<usize, u64>,
}

/// What the device does with a request that matches no command of its
/// sensor: an unknown function code, an address no command uses, a known
/// address with another register count, or a malformed frame (a read not 8
/// bytes long, a write whose byte count is not `2 * count` or not the
/// frame's length).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum UnknownRequestPolicy {
    /// No reply, as a real probe: the client times out (the default).
    /// Counted in [`Stats::ignored_unknown`].
    #[default]
    Silent,
    /// A Modbus exception reply: 01 (illegal function) for an unknown
    /// function, 02 (illegal data address) for an address no command of that
    /// function uses, 03 (illegal data value) for a known address with
    /// another count or a malformed frame. Counted in [`Stats::exceptions`].
    Exception,
}

/// How a request reached the device.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Route {
    /// To its own address: the device answers.
    Unicast,
    /// To address 0: applied, never answered.
    Broadcast,
    /// To a command's `fixed_slave` address (get_slave_id: 0xFF).
    Wildcard(u8),
}

/// The device's clock: real time, or time advanced by hand.
#[derive(Debug, Clone, Copy)]
struct Clock {
    start: Option<Instant>,
    offset: Duration,
}

impl Clock {
    fn now(&self) -> Duration {
        self.start.map_or(Duration::ZERO, |s| s.elapsed()) + self.offset
    }
}

/// A Yosemitech sensor simulated from its spec.
///
/// Everything comes from the [`Sensor`]: the commands it answers (by
/// function, start address and register count), the register contents at
/// start (the manual's example frames: a read's reply data, a write's
/// request data; reads are applied last, so where both cover a register it
/// reads back as the read example shows), the fields' ranges, the slave
/// address rules and the few sensor-specific rules of [`crate::behaviour`].
///
/// # On the wire
///
/// * Frames with a bad CRC are ignored, as a real slave ignores them.
/// * Requests to another address are ignored. Address 0 is broadcast:
///   writes are applied, nothing is answered. A command's `fixed_slave`
///   (get_slave_id: 0xFF) is answered from that address when the request
///   matches the command exactly; the same registers read at the device's
///   own address are answered from its own address.
/// * A request that matches no command (function, address and register
///   count), or is malformed, is not answered, as a real probe does not
///   answer for a register it lacks ([`UnknownRequestPolicy::Silent`]);
///   [`Simulator::set_unknown_request_policy`] with
///   [`UnknownRequestPolicy::Exception`] answers exceptions 01, 02 or 03
///   instead. A write with a value outside its field's `range`, or a slave
///   address outside the sensor's addresses: exception 03 (the register
///   exists), nothing stored.
/// * Reads return the registers; writes store their data (seen by later
///   reads of the same registers) and are echoed; trigger writes (zero
///   registers) are echoed; trigger reads (optical Start/Stop Measurement)
///   are answered in the manuals' form (byte count 0 and `2 * count` zero
///   bytes). The commands with role `start_measurement` and
///   `stop_measurement` start and stop the measurement
///   ([`crate::behaviour`]).
/// * The `serial_number` command answers with the sensor's model code
///   ([`SerialNumberPolicy`]).
/// * A `set_slave_address` write changes the address after the reply,
///   which comes from the old address.
///
/// ```
/// # let spec = yosemitech_spec::load_paths(&[concat!(env!("CARGO_MANIFEST_DIR"), "/../../spec").into()])?;
/// use yosemitech_sim::{FrameHandler, Simulator};
/// use yosemitech_spec::Value;
///
/// let mut sim = Simulator::new(spec.sensor("ph_orp").unwrap().clone());
/// sim.set("get_ph", "ph", Value::Float(7.0))?;
/// let mut reply = Vec::new();
/// sim.handle(&[0x01, 0x03, 0x28, 0x00, 0x00, 0x02, 0xCD, 0xAB], &mut reply);
/// assert_eq!(reply, [0x01, 0x03, 0x04, 0x00, 0x00, 0xE0, 0x40, 0xB2, 0x03]);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
#[derive(Clone)]
pub struct Simulator {
    sensor: Arc<Sensor>,
    address: u8,
    registers: RegisterMap,
    /// The registers of reads that keep their own ([`reads_of_their_own`]), by command index.
    own_registers: BTreeMap<usize, RegisterMap>,
    address_slots: Vec<AddressSlot>,
    /// Index of the `set_slave_address` command.
    set_address_command: Option<usize>,
    serial_number: Option<SerialNumber>,
    serial_number_policy: SerialNumberPolicy,
    unknown_request_policy: UnknownRequestPolicy,
    /// Function codes some command uses.
    functions: Vec<u8>,
    /// Fixed slave addresses of commands.
    wildcards: Vec<u8>,
    /// Per command: a measurement read (see [`Variation`]).
    measurement: Vec<bool>,
    behaviour: Behaviour,
    injector: Injector,
    variation: Option<VariationState>,
    warm_up_policy: WarmUpPolicy,
    byte_count_quirk: bool,
    clock: Clock,
    stats: Stats,
    /// Start Measurement is refused ([`Simulator::set_refuses_start`]).
    refuses_start: bool,
    /// The calibration standard the probe sits in ([`Simulator::immerse`]).
    bath: Option<Bath>,
    /// The reply being built.
    out: Vec<u8>,
}

impl Simulator {
    /// The sensor at its factory address (`default_address`), registers as
    /// the manual's examples show them, no faults.
    pub fn new(sensor: impl Into<Arc<Sensor>>) -> Self {
        let sensor: Arc<Sensor> = sensor.into();
        let mut functions: Vec<u8> = sensor.commands.iter().map(|c| c.function.code()).collect();
        functions.sort_unstable();
        functions.dedup();
        let mut wildcards: Vec<u8> = sensor.commands.iter().filter_map(|c| c.fixed_slave).collect();
        wildcards.sort_unstable();
        wildcards.dedup();
        let address_slots = address_slots(&sensor);
        let measurement = sensor.commands.iter().map(|c| sensor.is_measurement(c)).collect();
        let mut sim = Self {
            address: sensor.default_address,
            registers: RegisterMap::new(),
            own_registers: reads_of_their_own(&sensor)
                .into_iter()
                .enumerate()
                .filter(|&(_, own)| own)
                .map(|(i, _)| (i, RegisterMap::new()))
                .collect(),
            address_slots,
            set_address_command: role_index(&sensor, Role::SetSlaveAddress),
            serial_number: None,
            serial_number_policy: SerialNumberPolicy::default(),
            unknown_request_policy: UnknownRequestPolicy::default(),
            functions,
            wildcards,
            measurement,
            behaviour: Behaviour::new(&sensor),
            injector: Injector::new(FaultConfig::none()),
            variation: None,
            warm_up_policy: WarmUpPolicy::default(),
            byte_count_quirk: false,
            refuses_start: false,
            bath: None,
            clock: Clock { start: Some(Instant::now()), offset: Duration::ZERO },
            stats: Stats::default(),
            out: Vec::with_capacity(2 * yosemitech_rtu::frame::MAX_ADU),
            sensor,
        };
        sim.load_examples();
        sim.serial_number = SerialNumber::new(&sim.sensor, &sim.registers);
        sim.set_serial_number_policy(sim.serial_number_policy);
        sim.set_address(sim.address);
        sim
    }

    /// Puts the probe in a calibration [`Standard`]: every measurement read
    /// with `field` then reports the standard through the probe's error and
    /// the K and B that the user calibration write `block` holds (see
    /// [`crate::bath`]). `None` takes it out (reads return registers again).
    pub fn immerse(&mut self, standard: Option<(Standard, &str, &str)>) -> Result<(), SimError> {
        let Some((standard, field, block)) = standard else {
            self.bath = None;
            return Ok(());
        };
        let index = self.command_index(block)?;
        if !self.sensor.measurement_reads().any(|r| r.named_fields().any(|f| f.display_name() == field)) {
            return Err(SimError::NoSuchField(field.to_owned()));
        }
        self.bath = Some(Bath::new(standard, field.to_owned(), index));
        Ok(())
    }

    /// The standard the probe sits in, shown in a measurement read about to be served.
    fn show_standard(&mut self, index: usize, command: &CommandSpec) {
        if !self.measurement.get(index).copied().unwrap_or(false) {
            return;
        }
        let sensor = Arc::clone(&self.sensor);
        let Some(bath) = self.bath.as_mut() else { return };
        let Some(block) = sensor.commands.get(bath.block) else { return };
        // Writes land in the shared registers: K and B are read from there.
        let Some((offset, bytes)) = bath.reading(command, block, &self.registers) else { return };
        let out = match self.own_registers.get_mut(&index) {
            Some(own) => own,
            None => &mut self.registers,
        };
        out.write_bytes(command.address, offset, &bytes);
    }

    /// Makes the probe refuse Start Measurement (exception 01) while it
    /// measures and answers reads all the same, as a real Y533 does. A
    /// probe that refuses it starts measuring at power-on.
    pub fn set_refuses_start(&mut self, refuses: bool) {
        self.refuses_start = refuses;
        if refuses {
            self.behaviour.free_running();
        }
    }

    /// Builder form of [`Simulator::set_address`].
    #[must_use]
    pub fn with_address(mut self, address: u8) -> Self {
        self.set_address(address);
        self
    }

    /// Builder form of [`Simulator::set_faults`].
    #[must_use]
    pub fn with_faults(mut self, config: FaultConfig) -> Self {
        self.set_faults(config);
        self
    }

    /// Uses a clock that only moves with [`Simulator::advance`] (for
    /// deterministic warm-up tests). The clock restarts at zero.
    #[must_use]
    pub fn with_manual_clock(mut self) -> Self {
        self.clock = Clock { start: None, offset: Duration::ZERO };
        self
    }

    fn load_examples(&mut self) {
        let sensor = Arc::clone(&self.sensor);
        // Writes first, then reads: where both cover a register, it reads
        // back as the manual's read example shows.
        for reads in [false, true] {
            for (index, command) in sensor.commands.iter().enumerate().filter(|(_, c)| c.is_read() == reads) {
                let layout = command.layout();
                for example in &command.examples {
                    let data = if reads {
                        example.true_response().and_then(|frame| layout.decode_response(example.slave(), frame).ok())
                    } else {
                        example.true_request().and_then(|frame| layout.decode_request(frame).ok().map(|(_, data)| data))
                    };
                    if let Some(data) = data {
                        self.registers_of_mut(index).write(command.address, data);
                    }
                }
            }
        }
    }

    /// The sensor simulated, as given to [`Simulator::new`].
    pub fn sensor(&self) -> &Sensor {
        &self.sensor
    }

    /// The line timing of the sensor's serial settings.
    pub fn line_timing(&self) -> LineTiming {
        self.sensor.serial.timing()
    }

    /// The slave address the device answers.
    pub fn address(&self) -> u8 {
        self.address
    }

    /// Moves the device to `address` at once and stores it in the address
    /// field of the `set_slave_address` and `get_slave_address` commands (so
    /// get_slave_id reports it). Any address is
    /// accepted here, even outside the sensor's range, for client tests;
    /// writes on the wire are checked.
    pub fn set_address(&mut self, address: u8) {
        self.address = address;
        for slot in &self.address_slots {
            if let Some(bytes) = address_bytes(&slot.field, address) {
                self.registers.write_bytes(slot.register, slot.field.offset, &bytes);
            }
        }
    }

    /// The register contents: what reads return and writes change.
    pub fn registers(&self) -> &RegisterMap {
        &self.registers
    }

    /// The registers, to change directly (no rule runs; the address does not follow).
    pub fn registers_mut(&mut self) -> &mut RegisterMap {
        &mut self.registers
    }

    /// The registers command `index` reads: its own, or the shared ones.
    fn registers_of(&self, index: usize) -> &RegisterMap {
        self.own_registers.get(&index).unwrap_or(&self.registers)
    }

    fn registers_of_mut(&mut self, index: usize) -> &mut RegisterMap {
        match self.own_registers.get_mut(&index) {
            Some(own) => own,
            None => &mut self.registers,
        }
    }

    fn command_index(&self, name: &str) -> Result<usize, SimError> {
        self.sensor.commands.iter().position(|c| c.name == name).ok_or_else(|| SimError::UnknownCommand(name.into()))
    }

    /// The current values of `command`'s fields, decoded from the registers
    /// (what a read would return now, variation aside).
    pub fn values(&self, command: &str) -> Result<Values, SimError> {
        let index = self.command_index(command)?;
        let command = self.sensor.commands.get(index).ok_or_else(|| SimError::UnknownCommand(command.into()))?;
        Ok(decode_fields(command, &self.registers_of(index).read(command.address, command.count)))
    }

    /// The current value of one field.
    pub fn get(&self, command: &str, field: &str) -> Result<Value, SimError> {
        self.values(command)?
            .into_iter()
            .find(|(name, _)| name == field)
            .map(|(_, v)| v)
            .ok_or_else(|| SimError::UnknownField { command: command.into(), field: field.into() })
    }

    /// Sets one field of `command` in the registers: a reading
    /// (`set("get_ph", "ph", Value::Float(7.0))`), a coefficient, a serial
    /// number. The value is checked against the field's type, and a write
    /// command's field against its `range`; a read's `range` is the
    /// measuring range, which a probe may leave, so a reading outside it can
    /// be set. Setting the address field of the `set_slave_address` or
    /// `get_slave_address` command moves the device
    /// ([`Simulator::set_address`]).
    pub fn set(&mut self, command: &str, field: &str, value: Value) -> Result<(), SimError> {
        let index = self.command_index(command)?;
        let sensor = Arc::clone(&self.sensor);
        let cmd = sensor.commands.get(index).ok_or_else(|| SimError::UnknownCommand(command.into()))?;
        let (field_index, spec_field) =
            cmd.fields
                .iter()
                .enumerate()
                .find(|(_, f)| f.name.as_deref() == Some(field))
                .ok_or_else(|| SimError::UnknownField { command: command.into(), field: field.into() })?;
        let bytes = encode_command_field(cmd, spec_field, &value)?;
        let address_field = self.address_slots.iter().any(|s| s.command == index && s.field.name == spec_field.name);
        if address_field
            && let Value::Int(a) = value
            && let Ok(a) = u8::try_from(a)
        {
            self.set_address(a);
        }
        self.registers_of_mut(index).write_bytes(cmd.address, spec_field.offset, &bytes);
        if let (Some(variation), Value::Float(v)) = (self.variation.as_mut(), &value) {
            variation.bases.insert((index, field_index), *v);
        }
        Ok(())
    }

    /// [`Simulator::set`] for an f32 field.
    pub fn set_f32(&mut self, command: &str, field: &str, value: f32) -> Result<(), SimError> {
        self.set(command, field, Value::Float(value))
    }

    /// Sets `field` in every read command that has it (pH is in both
    /// get_ph and get_orp_and_ph); returns how many commands.
    pub fn set_everywhere(&mut self, field: &str, value: Value) -> Result<usize, SimError> {
        let names: Vec<String> = self
            .sensor
            .commands
            .iter()
            .filter(|c| c.is_read() && c.field(field).is_some())
            .map(|c| c.name.clone())
            .collect();
        if names.is_empty() {
            return Err(SimError::NoSuchField(field.into()));
        }
        for name in &names {
            self.set(name, field, value.clone())?;
        }
        Ok(names.len())
    }

    /// Whether `command` is a measurement read (see [`Variation`]).
    pub fn is_measurement(&self, command: &str) -> bool {
        self.command_index(command).ok().and_then(|i| self.measurement.get(i).copied()).unwrap_or(false)
    }

    /// Replaces the fault injection (and its generator); counters are kept.
    pub fn set_faults(&mut self, config: FaultConfig) {
        self.injector.reconfigure(config);
    }

    /// The fault configuration (its script shrinks as it is used).
    pub fn fault_config(&self) -> &FaultConfig {
        self.injector.config()
    }

    /// Faults injected so far, by kind.
    pub fn faults(&self) -> &FaultCounts {
        self.injector.counts()
    }

    /// Sets the fault counters to zero.
    pub fn reset_fault_counts(&mut self) {
        self.injector.reset_counts();
    }

    /// What was done with the requests so far.
    pub fn stats(&self) -> &Stats {
        &self.stats
    }

    /// Turns deterministic noise and drift of the readings on (`Some`) or off.
    pub fn set_variation(&mut self, variation: Option<Variation>) {
        self.variation = variation.map(|config| VariationState {
            config,
            rng: Rng::new(config.seed),
            bases: BTreeMap::new(),
            reads: BTreeMap::new(),
        });
    }

    /// How measurement reads are answered before readings are valid.
    pub fn set_warm_up_policy(&mut self, policy: WarmUpPolicy) {
        self.warm_up_policy = policy;
    }

    /// The measurement state (see [`crate::behaviour`]).
    pub fn measurement_state(&self) -> MeasurementState {
        self.behaviour.measurement_state(self.clock.now())
    }

    /// Calibration points recorded since the three-point calibration (re)started.
    pub fn calibration_points(&self) -> &[f32] {
        self.behaviour.calibration_points()
    }

    /// Moves the device's clock forward (skips a warm-up).
    pub fn advance(&mut self, by: Duration) {
        self.clock.offset += by;
    }

    /// What the device does with requests that match no command of its
    /// sensor: nothing (the default, as a real probe) or an exception.
    pub fn set_unknown_request_policy(&mut self, policy: UnknownRequestPolicy) {
        self.unknown_request_policy = policy;
    }

    /// The current [`UnknownRequestPolicy`].
    pub fn unknown_request_policy(&self) -> UnknownRequestPolicy {
        self.unknown_request_policy
    }

    /// How the `serial_number` command is answered: with the sensor's
    /// model code (the default, as a real probe) or exactly as the manual
    /// prints it. Rewrites the serial number's registers (a serial number
    /// [`Simulator::set`] earlier is replaced).
    pub fn set_serial_number_policy(&mut self, policy: SerialNumberPolicy) {
        self.serial_number_policy = policy;
        if let Some(serial) = &self.serial_number {
            serial.apply(policy, &mut self.registers);
        }
    }

    /// The current [`SerialNumberPolicy`].
    pub fn serial_number_policy(&self) -> SerialNumberPolicy {
        self.serial_number_policy
    }

    /// Replies to reads with a declared extra byte count (`extra_byte_counts`)
    /// carry that count, as the firmware the manual printed them from did
    /// (pH Fig 54: 0x0C over 24 bytes), instead of the true `2 * count`.
    pub fn set_byte_count_quirk(&mut self, on: bool) {
        self.byte_count_quirk = on;
    }

    fn route(&self, slave: u8) -> Option<Route> {
        if slave == self.address {
            Some(Route::Unicast)
        } else if slave == BROADCAST {
            Some(Route::Broadcast)
        } else if self.wildcards.contains(&slave) {
            Some(Route::Wildcard(slave))
        } else {
            None
        }
    }

    /// Finds the command a request is for, and the write's data.
    fn lookup<'r>(&self, request: &'r [u8], route: Route) -> Result<(usize, &'r [u8]), ExceptionCode> {
        let code = byte(request, 1).unwrap_or(0);
        if !self.functions.contains(&code) {
            return Err(ExceptionCode::IllegalFunction);
        }
        let function = Function::from_code(code).ok_or(ExceptionCode::IllegalFunction)?;
        let (address, count) = (word(request, 2).unwrap_or(0), word(request, 4).unwrap_or(0));
        if segment::request_len(request) != Some(request.len()) {
            return Err(ExceptionCode::IllegalDataValue);
        }
        let data: &[u8] = match function {
            Function::Read => &[],
            Function::Write => {
                let byte_count = usize::from(byte(request, REQUEST_BYTE_COUNT_AT).unwrap_or(0));
                if byte_count != 2 * usize::from(count) {
                    return Err(ExceptionCode::IllegalDataValue);
                }
                let data = REQUEST_BYTE_COUNT_AT + 1;
                request.get(data..data + byte_count).ok_or(ExceptionCode::IllegalDataValue)?
            }
        };
        let mut candidates = self.sensor.commands.iter().enumerate().filter(|(_, c)| {
            c.function == function
                && match route {
                    Route::Wildcard(slave) => c.fixed_slave == Some(slave),
                    Route::Unicast | Route::Broadcast => true,
                }
        });
        let mut known_address = false;
        for (index, c) in &mut candidates {
            if c.address == address {
                if c.count == count {
                    return Ok((index, data));
                }
                known_address = true;
            }
        }
        Err(if known_address { ExceptionCode::IllegalDataValue } else { ExceptionCode::IllegalDataAddress })
    }

    /// Carries out a request for command `index` (with the write's `data`,
    /// found by [`Simulator::lookup`]); writes the normal reply to
    /// `self.out` (unless broadcast) and returns the new slave address if it
    /// changes.
    fn process(
        &mut self,
        request: &[u8],
        route: Route,
        index: usize,
        data: &[u8],
    ) -> Result<Option<u8>, ExceptionCode> {
        let sensor = Arc::clone(&self.sensor);
        let command = sensor.commands.get(index).ok_or(ExceptionCode::ServerDeviceFailure)?;
        let layout = Layout {
            fixed_slave: if matches!(route, Route::Wildcard(_)) { command.fixed_slave } else { None },
            ..command.layout()
        };
        let slave = byte(request, 0).unwrap_or(0);
        if command.is_read() {
            if route == Route::Broadcast {
                return Ok(None);
            }
            if self.warm_up_policy == WarmUpPolicy::Busy
                && self.measurement.get(index).copied().unwrap_or(false)
                && self.measurement_state() != MeasurementState::Measuring
            {
                return Err(ExceptionCode::ServerDeviceBusy);
            }
            self.vary(index, command);
            self.show_standard(index, command);
            self.stats.reads += 1;
            // A trigger read's reply carries no value: the layout writes the manuals' form.
            let data = if command.trigger {
                Vec::new()
            } else {
                self.registers_of(index).read(command.address, command.count)
            };
            push_frame(&mut self.out, layout.response_len(), |buf| layout.encode_response(slave, &data, buf))?;
            if command.trigger && prints_empty_reply(command) {
                // The manual prints the 5-byte form (byte count 0, no data), CRC and all.
                shorten_to_empty(&mut self.out);
            }
            let now = self.clock.now();
            self.behaviour.on_command(index, now);
            if self.byte_count_quirk
                && let Some(&quirk) = command.extra_byte_counts.first()
            {
                requirk(&mut self.out, quirk);
            }
            Ok(None)
        } else {
            check_ranges(command, data)?;
            let address_field = self
                .address_slots
                .iter()
                .find(|s| Some(s.command) == self.set_address_command && s.command == index)
                .map(|s| &s.field);
            let new_address = match address_field {
                Some(field) => {
                    let value = data.get(field.offset..field.offset + field.size()).map(|b| decode_field(field, b));
                    match value {
                        Some(Value::Int(a))
                            if (i64::from(sensor.min_address)..=i64::from(sensor.max_address)).contains(&a) =>
                        {
                            u8::try_from(a).ok()
                        }
                        _ => return Err(ExceptionCode::IllegalDataValue),
                    }
                }
                None => None,
            };
            self.registers.write(command.address, data);
            let now = self.clock.now();
            self.behaviour.on_write(command, index, data, &mut self.registers, now);
            self.stats.writes += 1;
            if route != Route::Broadcast {
                push_frame(&mut self.out, layout.response_len(), |buf| layout.encode_response(slave, &[], buf))?;
            }
            Ok(new_address)
        }
    }

    /// Sets every f32 field of every measurement read to a plausible value
    /// of natural water: the field's `typical`, else the water temperature
    /// for a temperature (within its range), else the middle of its range;
    /// a field with none of these keeps its value. Variation then cycles
    /// around these.
    pub fn fill_with_water(&mut self) {
        let sensor = Arc::clone(&self.sensor);
        for (index, command) in sensor.commands.iter().enumerate() {
            if !self.measurement.get(index).copied().unwrap_or(false) {
                continue;
            }
            for field in &command.fields {
                if !matches!(field.kind, FieldKind::F32 { .. }) {
                    continue;
                }
                let temperature = field.unit.as_deref() == Some("degC");
                let value = match (field.typical, field.range) {
                    (Some(t), _) => t,
                    (None, Some((min, max))) if temperature => WATER_TEMPERATURE_C.clamp(min, max),
                    (None, Some((min, max))) => (min + max) / 2.0,
                    (None, None) if temperature => WATER_TEMPERATURE_C,
                    (None, None) => continue,
                };
                if let Ok(bytes) = encode_command_field(command, field, &Value::Float(value as f32)) {
                    self.registers_of_mut(index).write_bytes(command.address, field.offset, &bytes);
                }
            }
        }
        if let Some(v) = self.variation.as_mut() {
            v.bases.clear();
        }
    }

    /// The time of day for the daily cycle, in seconds.
    fn time_of_day(&self, day: Duration) -> f64 {
        let now = match self.clock.start {
            Some(_) => std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).unwrap_or_default(),
            None => self.clock.offset,
        };
        let day = day.as_secs_f64().max(1.0);
        now.as_secs_f64() % day / day
    }

    /// Applies the variation to a measurement read about to be served.
    fn vary(&mut self, index: usize, command: &CommandSpec) {
        if !self.measurement.get(index).copied().unwrap_or(false) {
            return;
        }
        let Some(day) = self.variation.as_ref().map(|v| v.config.day) else { return };
        let fraction = self.time_of_day(day);
        let Some(variation) = self.variation.as_mut() else { return };
        let reads = variation.reads.entry(index).or_insert(0);
        let n = *reads as f32;
        *reads += 1;
        for (field_index, field) in command.fields.iter().enumerate() {
            if !matches!(field.kind, FieldKind::F32 { .. }) {
                continue;
            }
            let registers = self.own_registers.get(&index).unwrap_or(&self.registers);
            let base = *variation.bases.entry((index, field_index)).or_insert_with(|| {
                let bytes = registers.read(command.address, command.count);
                match bytes.get(field.offset..field.offset + field.size()).map(|b| decode_field(field, b)) {
                    Some(Value::Float(v)) => v,
                    _ => 0.0,
                }
            });
            let noise = variation.config.noise * variation.rng.next_signed() as f32;
            // Every temperature swings alike and peaks together (one water);
            // other quantities swing with their range, each at its own hour.
            let temperature = field.unit.as_deref() == Some("degC");
            let span = daily_span(field, base);
            let phase = if temperature { 0.0 } else { 0.7 * (field_index as f64 + 1.0) };
            let cycle = f64::from(variation.config.daily_swing)
                * span
                * (std::f64::consts::TAU * fraction - std::f64::consts::FRAC_PI_2 + phase).sin();
            let mut value = base + cycle as f32 + variation.config.drift_per_read * n + noise;
            if let Some((min, max)) = field.range {
                value = value.clamp(min as f32, max as f32);
            }
            // A read is not bounded by its range on the wire: encode as the probe would.
            if let Ok(bytes) = encode_command_field(command, field, &Value::Float(value)) {
                let registers = match self.own_registers.get_mut(&index) {
                    Some(own) => own,
                    None => &mut self.registers,
                };
                registers.write_bytes(command.address, field.offset, &bytes);
            }
        }
    }
}

impl FrameHandler for Simulator {
    fn handle(&mut self, request: &[u8], reply: &mut Vec<u8>) -> Duration {
        self.stats.requests += 1;
        if request.len() < 4 || !crc_ok(request) {
            self.stats.ignored_bad_crc += 1;
            return Duration::ZERO;
        }
        let slave = byte(request, 0).unwrap_or(0);
        let function = byte(request, 1).unwrap_or(0);
        let Some(route) = self.route(slave) else {
            self.stats.ignored_other_slave += 1;
            return Duration::ZERO;
        };
        self.out.clear();
        let found = self.lookup(request, route);
        if route == Route::Broadcast {
            self.stats.broadcasts += 1;
            if let Ok((index, data)) = found
                && let Ok(Some(address)) = self.process(request, route, index, data)
            {
                self.stats.address_changes += 1;
                self.set_address(address);
            }
            self.out.clear();
            return Duration::ZERO;
        }
        if found.is_err() {
            if matches!(route, Route::Wildcard(_)) {
                self.stats.ignored_other_slave += 1;
                return Duration::ZERO;
            }
            if self.unknown_request_policy == UnknownRequestPolicy::Silent {
                self.stats.ignored_unknown += 1;
                return Duration::ZERO;
            }
        }
        let reply_slave = if matches!(route, Route::Wildcard(_)) { slave } else { self.address };
        self.stats.replies += 1;
        let fault = self.injector.draw();
        let mut new_address = None;
        if fault == Some(FaultKind::Busy) {
            push_exception(&mut self.out, reply_slave, function, ExceptionCode::ServerDeviceBusy);
        } else if self.refuses_start
            && let Ok((index, _)) = found
            && self.sensor.commands.get(index).is_some_and(|c| c.role == Some(Role::StartMeasurement))
        {
            // As a real Y533: the start is refused, the probe measures anyway.
            self.stats.exceptions += 1;
            push_exception(&mut self.out, reply_slave, function, ExceptionCode::IllegalFunction);
        } else {
            match found.and_then(|(index, data)| self.process(request, route, index, data)) {
                Ok(address) => new_address = address,
                Err(code) => {
                    self.stats.exceptions += 1;
                    self.out.clear();
                    push_exception(&mut self.out, reply_slave, function, code);
                }
            }
        }
        let delay = match fault {
            Some(kind) if kind != FaultKind::Busy => self.injector.apply(kind, &mut self.out),
            _ => Duration::ZERO,
        };
        reply.extend_from_slice(&self.out);
        // After the reply: it came from the old address.
        if let Some(address) = new_address {
            self.stats.address_changes += 1;
            self.set_address(address);
        }
        delay
    }
}

impl Responder for Simulator {
    /// [`FrameHandler::handle`]; a delayed reply is withheld (it cannot arrive
    /// late in-process, and a client has given up on it by then).
    fn respond(&mut self, request: &[u8], reply: &mut Vec<u8>) {
        if !self.handle(request, reply).is_zero() {
            reply.clear();
        }
    }
}

impl fmt::Debug for Simulator {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("Simulator")
            .field("sensor", &self.sensor.name)
            .field("address", &self.address)
            .field("registers", &self.registers)
            .field("stats", &self.stats)
            .field("faults", self.injector.counts())
            .finish_non_exhaustive()
    }
}

/// The bytes of an address in a `slave_address` field.
fn address_bytes(field: &Field, address: u8) -> Option<Vec<u8>> {
    match &field.kind {
        FieldKind::U8 | FieldKind::I8 | FieldKind::Enum { repr: EnumRepr::U8, .. } => Some(vec![address]),
        FieldKind::U16 { order } | FieldKind::I16 { order } => {
            Some(codec::u16_to_wire(*order, u16::from(address)).to_vec())
        }
        FieldKind::Enum { repr: EnumRepr::U16(order), .. } => {
            Some(codec::u16_to_wire(*order, u16::from(address)).to_vec())
        }
        FieldKind::U32 { order } | FieldKind::I32 { order } => {
            Some(codec::u32_to_wire(*order, u32::from(address)).to_vec())
        }
        _ => None,
    }
}

/// Refuses write data with a value outside its field's `range` (or NaN).
fn check_ranges(command: &CommandSpec, data: &[u8]) -> Result<(), ExceptionCode> {
    for field in command.fields.iter().filter(|f| f.range.is_some()) {
        let Some((min, max)) = field.range else { continue };
        let bytes = data.get(field.offset..field.offset + field.size()).ok_or(ExceptionCode::IllegalDataValue)?;
        let value = match decode_field(field, bytes) {
            Value::Float(v) => f64::from(v),
            Value::Int(v) => v as f64,
            Value::Enum { raw, .. } => f64::from(raw),
            _ => continue,
        };
        if !(min..=max).contains(&value) {
            return Err(ExceptionCode::IllegalDataValue);
        }
    }
    Ok(())
}

/// Appends a frame of at most `len` bytes written by `encode`.
fn push_frame(
    out: &mut Vec<u8>,
    len: usize,
    encode: impl FnOnce(&mut [u8]) -> Result<usize, EncodeError>,
) -> Result<(), ExceptionCode> {
    let start = out.len();
    out.resize(start + len, 0);
    match out.get_mut(start..).map(encode) {
        Some(Ok(n)) => {
            out.truncate(start + n);
            Ok(())
        }
        _ => {
            out.truncate(start);
            Err(ExceptionCode::ServerDeviceFailure)
        }
    }
}

fn push_exception(out: &mut Vec<u8>, slave: u8, function: u8, code: ExceptionCode) {
    let mut frame = [0u8; yosemitech_rtu::frame::EXCEPTION_LEN];
    if let Ok(n) = encode_exception(slave, function, code.to_u8(), &mut frame) {
        out.extend_from_slice(frame.get(..n).unwrap_or(&[]));
    }
}

/// Replaces the byte count of the read reply in `out` and fixes its CRC.
fn requirk(out: &mut Vec<u8>, byte_count: u8) {
    if out.len() < 5 {
        return;
    }
    if let Some(b) = out.get_mut(2) {
        *b = byte_count;
    }
    out.truncate(out.len() - 2);
    let crc = crc16(out);
    out.extend_from_slice(&crc.to_le_bytes());
}

/// Whether a manual prints `command`'s reply, complete with its CRC, as
/// the short form of a trigger read: slave, function, byte count 0.
fn prints_empty_reply(command: &CommandSpec) -> bool {
    command.examples.iter().filter_map(|e| e.true_response()).any(|reply| reply.len() == 5)
}

/// Cuts a read reply down to its header with byte count 0, and a new CRC.
fn shorten_to_empty(out: &mut Vec<u8>) {
    if out.len() < 5 {
        return;
    }
    out.truncate(3);
    if let Some(b) = out.get_mut(2) {
        *b = 0;
    }
    let crc = crc16(out);
    out.extend_from_slice(&crc.to_le_bytes());
}

#[cfg(test)]
mod tests {
    use super::*;

    use yosemitech_tests::{spec, with_crc};

    fn exchange(sim: &mut Simulator, request: &[u8]) -> Vec<u8> {
        let mut reply = Vec::new();
        assert_eq!(sim.handle(request, &mut reply), Duration::ZERO);
        reply
    }

    /// True when the registers of `a` and `b` share a register.
    fn overlap(a: &CommandSpec, b: &CommandSpec) -> bool {
        let end = |c: &CommandSpec| u32::from(c.address) + u32::from(c.count);
        u32::from(a.address) < end(b) && u32::from(b.address) < end(a)
    }

    #[test]
    fn starts_from_the_examples_at_the_factory_address() {
        let (mut reads, mut over_writes, mut overridden) = (0, 0, 0);
        for sensor in spec().sensors.clone() {
            let sim = Simulator::new(sensor.clone());
            assert_eq!(sim.address(), sensor.default_address, "{}", sensor.name);
            // A read that shares no register with another read's example
            // reads back its last example, over what write examples wrote
            // (the serial number and the address have rules of their own,
            // below and in the next test).
            for read in sensor.commands.iter().filter(|c| c.is_read() && !c.trigger) {
                if matches!(read.role, Some(Role::SerialNumber | Role::GetSlaveAddress | Role::SetSlaveAddress))
                    || sensor
                        .commands
                        .iter()
                        .any(|c| c.is_read() && c.name != read.name && !c.examples.is_empty() && overlap(c, read))
                {
                    continue;
                }
                let layout = read.layout();
                let Some(example) = read
                    .examples
                    .iter()
                    .rev()
                    .find(|e| e.true_response().is_some_and(|f| layout.decode_response(e.slave(), f).is_ok()))
                else {
                    continue;
                };
                for (field, stated) in &example.values {
                    let what = format!("{}.{}.{field}", sensor.name, read.name);
                    assert_eq!(&sim.get(&read.name, field).unwrap(), stated, "{what}");
                }
                reads += 1;
                over_writes += usize::from(sensor.commands.iter().any(|w| !w.is_read() && overlap(w, read)));
            }
            // The live address wins over what the examples wrote and read.
            for role in [Role::SetSlaveAddress, Role::GetSlaveAddress] {
                let Some(command) = sensor.command_with_role(role) else { continue };
                let field = command.named_fields().next().unwrap().name.clone().unwrap();
                let live = Value::Int(i64::from(sensor.default_address));
                assert_eq!(sim.get(&command.name, &field).unwrap(), live, "{}.{}", sensor.name, command.name);
                overridden +=
                    command.examples.iter().filter(|e| e.values.get(&field).is_some_and(|v| *v != live)).count();
            }
        }
        assert!(reads > 0 && over_writes > 0, "no read example to start from ({reads}, {over_writes} over writes)");
        assert!(overridden > 0, "no example states another address than the factory one");
    }

    #[test]
    fn the_address_lives_in_the_slave_address_role_fields_of_every_sensor() {
        for sensor in spec().sensors.clone() {
            let sim = Simulator::new(sensor.clone()).with_address(42);
            for role in [Role::SetSlaveAddress, Role::GetSlaveAddress] {
                let Some(command) = sensor.command_with_role(role) else { continue };
                let field = command.named_fields().next().unwrap();
                let value = sim.get(&command.name, field.name.as_deref().unwrap()).unwrap();
                assert_eq!(value, Value::Int(42), "{}.{}", sensor.name, command.name);
                // In the bytes the field's type gives, where a read finds them.
                let bytes = address_bytes(field, 42).unwrap();
                let registers = sim.registers().read(command.address, command.count);
                assert_eq!(registers[field.offset..field.offset + bytes.len()], bytes, "{}", command.name);
            }
        }
    }

    #[test]
    fn measurement_reads_are_the_uncovered_ones_with_units() {
        // The reads a sensor's procedure takes its measurements from.
        let mut measured = 0;
        for sensor in spec().sensors.clone() {
            for name in sensor.procedure.iter().flat_map(|p| &p.read) {
                assert!(sensor.is_measurement(sensor.command(name).unwrap()), "{}.{name}", sensor.name);
                measured += 1;
            }
        }
        assert!(measured > 0);
        // Reads without a unit (serial numbers, versions) and reads a write
        // covers (calibration blocks, settings) are not measurements; the
        // simulator classifies every command as the spec does.
        let (mut unitless, mut written) = (0, 0);
        for sensor in spec().sensors.clone() {
            let sim = Simulator::new(sensor.clone());
            for read in sensor.commands.iter().filter(|c| c.is_read()) {
                let what = format!("{}.{}", sensor.name, read.name);
                let covered = sensor.commands.iter().any(|w| !w.is_read() && w.count > 0 && overlap(w, read));
                if read.fields.iter().all(|f| f.unit.is_none()) {
                    assert!(!sensor.is_measurement(read), "{what}: no unit");
                    unitless += 1;
                } else if covered {
                    assert!(!sensor.is_measurement(read), "{what}: a write sets it");
                    written += 1;
                } else {
                    assert!(sensor.is_measurement(read), "{what}: uncovered, with a unit");
                }
            }
            for command in &sensor.commands {
                assert_eq!(sim.is_measurement(&command.name), sensor.is_measurement(command), "{}", command.name);
            }
        }
        assert!(unitless > 0 && written > 0, "both kinds of non-measurement reads are in the spec");
    }

    /// `frame` with its CRC recomputed over the rest.
    fn recrc(frame: &[u8]) -> Vec<u8> {
        with_crc(&frame[..frame.len() - 2])
    }

    #[test]
    fn nan_and_out_of_range_writes_are_refused() {
        let mut fields = 0;
        for sensor in spec().sensors.clone() {
            for write in sensor.commands.iter().filter(|c| !c.is_read()) {
                let Some(request) = write.examples.iter().find_map(|e| e.true_request()) else { continue };
                for field in &write.fields {
                    let (FieldKind::F32 { order }, Some((min, max))) = (&field.kind, field.range) else { continue };
                    let what = format!("{}.{}.{}", sensor.name, write.name, field.display_name());
                    let with = |value: f32| {
                        let mut frame = request.to_vec();
                        let at = 7 + field.offset;
                        frame[at..at + 4].copy_from_slice(&codec::f32_to_wire(*order, value));
                        recrc(&frame)
                    };
                    let (min, max) = (min as f32, max as f32);
                    for bad in [f32::NAN, min - 0.5, max + 0.5, f32::INFINITY, f32::NEG_INFINITY] {
                        let mut sim = Simulator::new(sensor.clone()).with_address(request[0]);
                        let reply = exchange(&mut sim, &with(bad));
                        assert_eq!(reply, with_crc(&[request[0], 0x90, 0x03]), "{what} = {bad}");
                    }
                    // The bounds themselves are fine.
                    for ok in [min, max] {
                        let mut sim = Simulator::new(sensor.clone()).with_address(request[0]);
                        assert_eq!(exchange(&mut sim, &with(ok)).get(1), Some(&0x10), "{what} = {ok}");
                    }
                    fields += 1;
                }
            }
        }
        assert!(fields > 0, "no write of the spec has a float field with a range");
    }

    #[test]
    fn address_bytes_follow_the_field_type() {
        let field = |kind| Field {
            name: Some("slave_address".into()),
            kind,
            offset: 0,
            unit: None,
            doc: None,
            range: None,
            typical: None,
            absent: None,
            examples: Vec::new(),
        };
        assert_eq!(address_bytes(&field(FieldKind::U8), 7), Some(vec![7]));
        let be = FieldKind::U16 { order: yosemitech_rtu::ByteOrder2::Ab };
        assert_eq!(address_bytes(&field(be), 7), Some(vec![0, 7]));
        let le = FieldKind::U16 { order: yosemitech_rtu::ByteOrder2::Ba };
        assert_eq!(address_bytes(&field(le), 7), Some(vec![7, 0]));
        assert_eq!(address_bytes(&field(FieldKind::Version), 7), None);
    }

    #[test]
    fn requirk_rewrites_count_and_crc() {
        let mut reply = with_crc(&[1, 3, 4, 1, 2, 3, 4]);
        requirk(&mut reply, 2);
        assert_eq!(reply, with_crc(&[1, 3, 2, 1, 2, 3, 4]));
        let mut short = vec![1, 2];
        requirk(&mut short, 9);
        assert_eq!(short, [1, 2]);
    }

    #[test]
    fn arbitrary_bytes_never_panic() {
        for sensor in &spec().sensors {
            for policy in [UnknownRequestPolicy::Silent, UnknownRequestPolicy::Exception] {
                arbitrary_bytes_never_panic_with(sensor, policy);
            }
        }
    }

    fn arbitrary_bytes_never_panic_with(sensor: &Sensor, policy: UnknownRequestPolicy) {
        let mut sim = Simulator::new(sensor.clone()).with_faults(FaultConfig::uniform(5, 0.5));
        sim.set_unknown_request_policy(policy);
        let mut rng = Rng::new(77);
        for _ in 0..20_000 {
            let len = rng.below(40) as usize;
            let mut frame: Vec<u8> = (0..len).map(|_| rng.byte()).collect();
            if rng.chance(0.5) && frame.len() >= 4 {
                // Mostly valid headers for this device, valid CRC.
                frame[0] = if rng.chance(0.8) { sim.address() } else { 0 };
                frame[1] = [0x03, 0x10, 0x04][rng.below(3) as usize];
                let n = frame.len() - 2;
                let crc = crc16(&frame[..n]).to_le_bytes();
                frame[n..].copy_from_slice(&crc);
            }
            let mut reply = Vec::new();
            sim.handle(&frame, &mut reply);
            assert!(reply.len() <= yosemitech_rtu::frame::MAX_ADU + 4, "{}", sensor.name);
        }
        let stats = sim.stats();
        match policy {
            UnknownRequestPolicy::Silent => {
                assert!(stats.ignored_unknown > 0 && stats.exceptions == 0, "{}", sensor.name)
            }
            UnknownRequestPolicy::Exception => {
                assert!(stats.exceptions > 0 && stats.ignored_unknown == 0, "{}", sensor.name)
            }
        }
    }

    /// Requests to `sensor` that match none of its commands: a function it
    /// does not serve (read input registers), a register no read starts at,
    /// and a read's register with a count no read of it has; with the
    /// exception code each earns.
    fn unknown_requests(sensor: &Sensor, slave: u8) -> [(Vec<u8>, u8); 3] {
        assert!(sensor.commands.iter().all(|c| c.function.code() != 0x04), "{} serves function 0x04", sensor.name);
        let reads: Vec<&CommandSpec> = sensor.commands.iter().filter(|c| c.is_read()).collect();
        let read = reads.iter().find(|c| c.fixed_slave.is_none()).expect("a read to the unit's own address");
        let free = (1..)
            .map(|k| read.address.wrapping_sub(k * 0x100))
            .find(|a| reads.iter().all(|c| c.address != *a))
            .unwrap();
        let other_count = (read.count + 1..).find(|n| reads.iter().all(|c| c.address != read.address || c.count != *n));
        let frame = |function: u8, address: u16, count: u16| {
            let [a, b] = address.to_be_bytes();
            let [c, d] = count.to_be_bytes();
            with_crc(&[slave, function, a, b, c, d])
        };
        [
            (frame(0x04, read.address, read.count), 0x01),
            (frame(0x03, free, read.count), 0x02),
            (frame(0x03, read.address, other_count.unwrap()), 0x03),
        ]
    }

    #[test]
    fn unknown_requests_are_silent_unless_exceptions_are_asked_for() {
        for sensor in spec().sensors.clone() {
            let mut sim = Simulator::new(sensor.clone());
            let unknown = unknown_requests(&sensor, sim.address());
            assert_eq!(sim.unknown_request_policy(), UnknownRequestPolicy::Silent);
            for (request, _) in &unknown {
                assert!(exchange(&mut sim, request).is_empty(), "{}", sensor.name);
            }
            assert_eq!(sim.stats().ignored_unknown, unknown.len() as u64);
            assert_eq!((sim.stats().replies, sim.stats().exceptions), (0, 0));
            assert_eq!(sim.faults().replies(), 0, "no reply, no fault drawn");
            sim.set_unknown_request_policy(UnknownRequestPolicy::Exception);
            for (request, code) in &unknown {
                let reply = exchange(&mut sim, request);
                assert_eq!(reply, with_crc(&[request[0], request[1] | 0x80, *code]), "{}", sensor.name);
            }
            assert_eq!(sim.stats().exceptions, unknown.len() as u64);
        }
    }

    #[test]
    fn the_serial_number_carries_the_model_code_unless_printed_is_asked_for() {
        let (mut sensors, mut siblings, mut code_bytes, mut as_printed) = (0, 0, 0, 0);
        for sensor in spec().sensors.clone() {
            let (Some(command), Some(printed), Some(code)) = (
                sensor.command_with_role(Role::SerialNumber).cloned(),
                sensor.example_serial_number(),
                sensor.model_code.clone(),
            ) else {
                continue;
            };
            let what = format!("{}.{}", sensor.name, command.name);
            let text = command.fields.iter().find(|f| matches!(f.kind, FieldKind::Ascii { .. })).unwrap();
            let name = text.name.as_deref().unwrap();
            let mut sim = Simulator::new(sensor.clone());
            let own = format!("{}{code}{}", &printed[..2], &printed[4..]);
            siblings += usize::from(printed[2..4] != code);
            assert_eq!(sim.serial_number_policy(), SerialNumberPolicy::ModelCode);
            assert_eq!(sim.get(&command.name, name).unwrap(), Value::Text(own), "{what}");
            let request = command.encode_request(sim.address(), &BTreeMap::new()).unwrap();
            let reply = exchange(&mut sim, &request);
            let reserved_before =
                command.fields.iter().any(|f| f.is_reserved() && text.offset > 0 && f.offset + f.size() == text.offset);
            if reserved_before {
                let byte = 3 + text.offset - 1;
                assert_eq!(reply[byte], u8::from_str_radix(&code, 16).unwrap(), "{what}: the byte before the text");
                code_bytes += 1;
            }
            // As printed: the manual's reply, byte for byte.
            sim.set_serial_number_policy(SerialNumberPolicy::AsPrinted);
            assert_eq!(sim.get(&command.name, name).unwrap(), Value::Text(printed.clone()), "{what}");
            let manual = command
                .examples
                .iter()
                .find(|e| e.slave() == sim.address() && e.values.get(name) == Some(&Value::Text(printed.clone())))
                .and_then(|e| e.true_response());
            if let Some(manual) = manual {
                assert_eq!(exchange(&mut sim, &request), manual, "{what}");
                as_printed += 1;
            }
            sensors += 1;
        }
        assert!(sensors > 0 && code_bytes > 0, "no serial number with a model code");
        assert!(siblings > 0, "no manual prints a sibling's serial number");
        assert!(as_printed > 0, "no serial number reply compared with the manual's");
    }

    #[test]
    fn trigger_reads_are_answered_in_the_manuals_form() {
        let mut stops = 0;
        for sensor in spec().sensors.clone() {
            let Some(stop) = sensor.command_with_role(Role::StopMeasurement).filter(|c| c.is_read()).cloned() else {
                continue;
            };
            let mut sim = Simulator::new(sensor.clone()).with_manual_clock();
            if sim.measurement_state() != MeasurementState::Measuring {
                let start = sensor.command_with_role(Role::StartMeasurement).unwrap();
                let request = start.encode_request(sim.address(), &BTreeMap::new()).unwrap();
                exchange(&mut sim, &request);
                let warm_up = sensor.procedure.as_ref().map_or(0, |p| p.warm_up_ms);
                sim.advance(Duration::from_millis(u64::from(warm_up)));
            }
            assert_eq!(sim.measurement_state(), MeasurementState::Measuring, "{}", sensor.name);
            let address = sim.address();
            let reply = exchange(&mut sim, &stop.encode_request(address, &BTreeMap::new()).unwrap());
            let long = yosemitech_rtu::Frame::fill(|b| stop.layout().encode_response(address, &[], b)).unwrap();
            if prints_empty_reply(&stop) {
                assert_eq!(reply, with_crc(&[address, 0x03, 0]), "{}: the printed short form", stop.name);
            } else {
                assert_eq!(reply, long.as_bytes(), "{}: byte count 0 and the meaningless registers", stop.name);
            }
            // Every byte the manual prints of the reply (a spec may print none).
            let printed: Vec<_> = stop.examples.iter().filter_map(|e| e.response.as_ref()).collect();
            for frame in printed {
                for (i, got) in reply.iter().enumerate() {
                    assert!(frame.byte(i).is_none_or(|want| want == *got), "{}: byte {i}", stop.name);
                }
            }
            assert_eq!(sim.measurement_state(), MeasurementState::Idle);
            assert_eq!(sim.stats().exceptions, 0);
            stops += 1;
        }
        yosemitech_tests::report!(
            "trigger-read stops answered in the printed form: {stops} sensors (0: the spec has none)"
        );
    }
}
