//! One simulated sensor: register state, request handling, exceptions, faults.
//!
//! The device and its API are here; `requests` routes and answers frames,
//! `frames` builds their bytes, `water` moves the readings.

use std::collections::BTreeMap;
use std::fmt;
use std::sync::Arc;
use std::time::{Duration, Instant};

use yosemitech_rtu::LineTiming;
use yosemitech_spec::interp::{EncodeValuesError, decode_fields, encode_command_field};
use yosemitech_spec::{CommandSpec, Role, Sensor, Value, Values};

use crate::bath::{Bath, Standard};
use crate::behaviour::{
    AddressSlot, Behaviour, MeasurementState, SerialNumber, SerialNumberPolicy, WarmUpPolicy, address_slots, role_index,
};
use crate::fault::{FaultConfig, FaultCounts, Injector};
use crate::registers::{RegisterMap, reads_of_their_own};
use frames::address_bytes;
pub use requests::UnknownRequestPolicy;
use water::VariationState;
pub use water::{Variation, WATER_TEMPERATURE_C, WATER_TEMPERATURE_SPAN_C, daily_span};

mod frames;
mod requests;
#[cfg(test)]
mod tests;
mod water;

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
        let spec_field = cmd
            .fields
            .iter()
            .find(|f| f.name.as_deref() == Some(field))
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
        // A measured quantity's new base, for every register that holds it.
        let measured = self.measurement.get(index).copied().unwrap_or(false);
        if let (Some(variation), Value::Float(v), true) = (self.variation.as_mut(), &value, measured) {
            variation.bases.insert(field.to_owned(), *v);
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
