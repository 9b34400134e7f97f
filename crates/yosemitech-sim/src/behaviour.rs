//! Sensor-specific behaviour beyond "reads return registers, writes store
//! them", keyed by the spec's command roles, in one place.
//!
//! Everything else the simulator does follows from the spec's generic
//! attributes (function, address, count, `fixed_slave`, `trigger`, field
//! `range`s, examples). The rules below switch on only when a sensor's spec
//! gives a command the [`Role`] they look for, so a spec loaded at run time
//! with no roles simulates as plain register storage, and one that declares
//! the roles gets the behaviour with no Rust written. No rule looks up a
//! command, field or constant by its name.
//!
//! | rule | keyed by | behaviour |
//! |---|---|---|
//! | slave address | the first named field of the commands with role `set_slave_address` and `get_slave_address` | the field holds the device's address: reads report the current address, a `set_slave_address` write changes the address *after* the reply (which comes from the old address); see [`crate::Simulator::set_address`] |
//! | serial number | the command with role `serial_number` (its `ascii` field and the `reserved` byte right before it), the sensor's `model_code` | see [Serial number](#serial-number) and [`SerialNumberPolicy`] |
//! | measurement trigger | the commands with role `start_measurement` and `stop_measurement` (trigger writes or trigger reads); the sensor's `procedure` (`before`, `warm_up_ms`) | [`MeasurementState`] goes `Idle` → `WarmingUp` → `Measuring` on a start and back to `Idle` on a stop; see [Measurement](#measurement) |
//! | three-point calibration | the write with role `calibration_point` (its first named field is the standard written); the read with role `calibration_status` (its `enum` field, with the variants named [`STATUS_SUCCESS`], [`STATUS_NOT_A_STANDARD`], [`STATUS_TOO_FEW_POINTS`]); the list constant in the point field's unit | see [Three-point calibration](#three-point-calibration) |
//! | a probe in a calibration standard | the write with role `user_calibration` (its two fields: K, then B) and the measured field it calibrates | only after [`crate::Simulator::immerse`]: see [`crate::bath`] |
//!
//! # Serial number
//!
//! Real probes send their model code in the byte before the serial number,
//! where the manuals print `0x00`, and several manuals print a sibling's
//! serial number (Y514's prints Y510's `YL10...`). By default
//! ([`SerialNumberPolicy::ModelCode`]) the simulator answers the
//! `serial_number` command with
//!
//! * the `reserved` byte right before the `ascii` field (when the layout
//!   has one) set to the model code read as hex: `model_code: "09"` sends
//!   `0x09`, `"48"` sends `0x48`;
//! * the manual's serial number with its characters 3-4 replaced by the
//!   sensor's own `model_code` (`YL1014010022` becomes `YL4814010022` for a
//!   Y514).
//!
//! A sensor without `model_code` answers the manual's bytes.
//! [`SerialNumberPolicy::AsPrinted`] answers exactly what the manual prints.
//!
//! A spec that prints no serial number (no example: a model without a
//! manual) gets a made-up one of the family's form, `YL` and digits with the
//! model code as characters 3-4 (`YL4400000001` for code 44).
//!
//! # Measurement
//!
//! A sensor with neither a `start_measurement` nor a `stop_measurement`
//! command is always [`MeasurementState::Measuring`]. Otherwise it starts
//! `Idle` when its procedure sends the `start_measurement` command in
//! `before` (the manual starts measuring, as conductivity SW 1.0 must) or
//! when it has no procedure; else it measures from power-on (the optical
//! probes). A `start_measurement` command (write or read) starts a warm-up
//! of the procedure's `warm_up_ms` (0 without a procedure), after which the
//! state is `Measuring`; `stop_measurement` returns it to `Idle`. Readings
//! are plain meanwhile unless [`WarmUpPolicy::Busy`].
//!
//! # Three-point calibration
//!
//! The standards are the sensor's list constant whose unit is the
//! calibration point field's unit (pH: `ph_calibration_standards`, 4.00,
//! 6.86, 9.18); the rule is off unless exactly one constant fits. Each
//! point written is compared with the next expected standard, within
//! [`STANDARD_TOLERANCE`]:
//!
//! * it matches: the point is recorded; the status becomes `success` after
//!   the last standard (and a new calibration may start), else
//!   `fewer_than_three_points` (the manual does not say what the status
//!   reads between points; this is the only code that fits);
//! * it matches the *first* standard instead: the calibration restarts with
//!   this point (status `fewer_than_three_points`);
//! * otherwise: status `not_a_calibration_standard` and the points recorded
//!   so far are dropped (the manual: on failure the probe restores the
//!   previous coefficients; the simulator keeps no coefficients apart from
//!   the registers, which a calibration does not touch).
//!
//! `coefficients_out_of_range` is never produced: the simulator has no
//! electrode model to go out of range. Values outside the field's `range`
//! (0..14 pH) never get here: they are refused with exception 03.
//!
//! The status codes are the only thing still found by name: the variant
//! names above, since the spec language has no way to say which variant
//! means what.

use std::time::Duration;

use yosemitech_spec::interp::{decode_field, encode_field};
use yosemitech_spec::{CommandSpec, Constant, Field, FieldKind, Role, Sensor, Value};

use crate::registers::RegisterMap;

/// Status variant: the calibration succeeded.
pub const STATUS_SUCCESS: &str = "success";

/// Status variant: a point did not match the expected standard.
pub const STATUS_NOT_A_STANDARD: &str = "not_a_calibration_standard";

/// Status variant: fewer points than standards so far.
pub const STATUS_TOO_FEW_POINTS: &str = "fewer_than_three_points";

/// How close a written point must be to a standard: half the last printed
/// digit of the standards (4.00, 6.86, 9.18).
pub const STANDARD_TOLERANCE: f64 = 0.005;

/// Where a triggered sensor is in its measurement cycle.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MeasurementState {
    /// Not started, or stopped (only sensors with a start or stop command).
    Idle,
    /// Started; readings valid after `remaining`.
    WarmingUp {
        /// Time left until readings are valid.
        remaining: Duration,
    },
    /// Readings are valid (always, for sensors without a start or stop command).
    Measuring,
}

/// How measurement reads are answered before readings are valid
/// ([`MeasurementState::Idle`] or [`MeasurementState::WarmingUp`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum WarmUpPolicy {
    /// With the current register values, as if valid (the default: the
    /// manual does not say what the probe sends).
    #[default]
    Plain,
    /// With exception 0x06 (server device busy), for clients that must wait.
    Busy,
}

/// How the `serial_number` command is answered (see the [module
/// docs](self#serial-number)).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum SerialNumberPolicy {
    /// As a real probe: the model code in the byte before the serial
    /// number, and the sensor's own model code in the serial number.
    #[default]
    ModelCode,
    /// Exactly as the manual prints it (`0x00` before the serial number, the
    /// manual's serial number), for byte-for-byte comparisons with the
    /// manual's frames.
    AsPrinted,
}

/// A field that holds the device's slave address.
#[derive(Debug, Clone)]
pub(crate) struct AddressSlot {
    /// Index of the command.
    pub(crate) command: usize,
    /// The command's first register.
    pub(crate) register: u16,
    /// The field.
    pub(crate) field: Field,
}

/// The address fields: the first named field of the `set_slave_address` and
/// `get_slave_address` commands.
pub(crate) fn address_slots(sensor: &Sensor) -> Vec<AddressSlot> {
    [Role::SetSlaveAddress, Role::GetSlaveAddress]
        .into_iter()
        .filter_map(|role| {
            let command = role_index(sensor, role)?;
            let c = sensor.commands.get(command)?;
            let field = c.named_fields().next()?.clone();
            Some(AddressSlot { command, register: c.address, field })
        })
        .collect()
}

/// The index of the command with `role`.
pub(crate) fn role_index(sensor: &Sensor, role: Role) -> Option<usize> {
    sensor.commands.iter().position(|c| c.role == Some(role))
}

/// The serial-number rule: the registers of the `serial_number` command as
/// the manual prints them and as a real probe sends them.
#[derive(Debug, Clone)]
pub(crate) struct SerialNumber {
    address: u16,
    printed: Vec<u8>,
    own: Vec<u8>,
}

impl SerialNumber {
    /// From the registers as the examples left them; `None` without a
    /// `serial_number` command.
    pub(crate) fn new(sensor: &Sensor, registers: &RegisterMap) -> Option<Self> {
        let command = sensor.command_with_role(Role::SerialNumber)?;
        let printed = registers.read(command.address, command.count);
        let own = with_model_code(command, sensor.model_code.as_deref(), &printed);
        Some(Self { address: command.address, printed, own })
    }

    /// Writes the serial number `policy` asks for to the registers.
    pub(crate) fn apply(&self, policy: SerialNumberPolicy, registers: &mut RegisterMap) {
        let data = match policy {
            SerialNumberPolicy::ModelCode => &self.own,
            SerialNumberPolicy::AsPrinted => &self.printed,
        };
        registers.write(self.address, data);
    }
}

/// The model code's byte: its two digits read as hex (`"09"` is `0x09`,
/// `"48"` is `0x48`).
pub(crate) fn model_code_byte(code: &str) -> Option<u8> {
    if code.len() == 2 && code.bytes().all(|b| b.is_ascii_hexdigit()) {
        u8::from_str_radix(code, 16).ok()
    } else {
        None
    }
}

/// `data` (the serial-number command's register data) as a probe with
/// `model_code` sends it: the code's byte in the reserved byte right before
/// the text, and the code as the text's characters 3-4.
fn with_model_code(command: &CommandSpec, model_code: Option<&str>, data: &[u8]) -> Vec<u8> {
    let mut own = data.to_vec();
    let (Some(code), Some(text)) =
        (model_code, command.fields.iter().find(|f| matches!(f.kind, FieldKind::Ascii { .. })))
    else {
        return own;
    };
    let Some(byte) = model_code_byte(code) else { return own };
    let reserved_before = command
        .fields
        .iter()
        .any(|f| f.is_reserved() && f.size() > 0 && f.offset + f.size() == text.offset && text.offset > 0);
    if reserved_before && let Some(slot) = own.get_mut(text.offset - 1) {
        *slot = byte;
    }
    // No serial number printed (a spec without examples): a made-up one of
    // the family's form, `YL<code>` and digits, so the model code is there.
    if let Some(chars) = own.get_mut(text.offset..text.offset + text.size())
        && chars.len() >= 4
        && chars.iter().all(|&c| c == 0)
    {
        let last = chars.len() - 1;
        for (i, c) in chars.iter_mut().enumerate() {
            *c = match i {
                0 => b'Y',
                1 => b'L',
                _ if i == last => b'1',
                _ => b'0',
            };
        }
    }
    // Characters 3-4 of the text, when the manual's serial number has them.
    if let Some(chars) = own.get_mut(text.offset..text.offset + text.size())
        && chars.len() >= 4
        && chars.iter().take(4).all(|c| c.is_ascii_graphic())
        && let Some(digits) = chars.get_mut(2..4)
    {
        digits.copy_from_slice(code.as_bytes());
    }
    own
}

/// Whether the simulator runs the calibration rule for `sensor`: it has a
/// calibration point write, a calibration status read whose enum names
/// [`STATUS_SUCCESS`], [`STATUS_NOT_A_STANDARD`] and [`STATUS_TOO_FEW_POINTS`],
/// and one list of standards in the point's unit. Otherwise the point is a
/// plain write.
pub fn simulates_calibration(sensor: &Sensor) -> bool {
    Calibration::new(sensor).is_some()
}

/// The calibration standards: the one list constant whose unit is the
/// calibration point field's unit (`None` when none or several fit).
pub fn calibration_standards<'s>(sensor: &'s Sensor, point: &Field) -> Option<&'s Constant> {
    let unit = point.unit.as_deref()?;
    let mut fitting = sensor.constants.iter().filter(|c| c.is_list && c.unit.as_deref() == Some(unit));
    let standards = fitting.next()?;
    fitting.next().is_none().then_some(standards)
}

/// Status codes of the calibration status enum.
#[derive(Debug, Clone, Copy)]
struct StatusCodes {
    success: u16,
    not_a_standard: u16,
    too_few: u16,
}

/// The three-point calibration rule.
#[derive(Debug, Clone)]
struct Calibration {
    /// Index of the point command.
    point: usize,
    /// Address and field of the status.
    status_address: u16,
    status_field: Field,
    standards: Vec<f64>,
    codes: StatusCodes,
    points: Vec<f32>,
}

impl Calibration {
    fn new(sensor: &Sensor) -> Option<Self> {
        let point = role_index(sensor, Role::CalibrationPoint)?;
        let point_command = sensor.commands.get(point).filter(|c| !c.is_read())?;
        let standards = calibration_standards(sensor, point_command.named_fields().next()?)?.values.clone();
        let status = sensor.command_with_role(Role::CalibrationStatus).filter(|c| c.is_read())?;
        let status_field = status.fields.iter().find(|f| matches!(f.kind, FieldKind::Enum { .. }))?;
        let FieldKind::Enum { variants, .. } = &status_field.kind else { return None };
        let code = |name: &str| variants.iter().find(|v| v.name == name).map(|v| v.value);
        let codes = StatusCodes {
            success: code(STATUS_SUCCESS)?,
            not_a_standard: code(STATUS_NOT_A_STANDARD)?,
            too_few: code(STATUS_TOO_FEW_POINTS)?,
        };
        if standards.is_empty() {
            return None;
        }
        Some(Self {
            point,
            status_address: status.address,
            status_field: status_field.clone(),
            standards,
            codes,
            points: Vec::new(),
        })
    }

    fn matches(&self, value: f32, index: usize) -> bool {
        self.standards.get(index).is_some_and(|s| (f64::from(value) - s).abs() <= STANDARD_TOLERANCE)
    }

    /// One point written; returns the new status code.
    fn point(&mut self, value: f32) -> u16 {
        if self.matches(value, self.points.len()) {
            self.points.push(value);
        } else if self.matches(value, 0) {
            self.points.clear();
            self.points.push(value);
        } else {
            self.points.clear();
            return self.codes.not_a_standard;
        }
        if self.points.len() >= self.standards.len() {
            self.points.clear();
            self.codes.success
        } else {
            self.codes.too_few
        }
    }
}

/// Where the measurement cycle is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Cycle {
    /// Not started, or stopped.
    Idle,
    /// Started at this clock time.
    StartedAt(Duration),
    /// Measuring from power-on, or no start or stop command.
    FreeRunning,
}

/// The sensor-specific rules of one simulated device.
#[derive(Debug, Clone)]
pub(crate) struct Behaviour {
    /// Index of the `start_measurement` command.
    start: Option<usize>,
    /// Index of the `stop_measurement` command.
    stop: Option<usize>,
    warm_up: Duration,
    cycle: Cycle,
    calibration: Option<Calibration>,
}

impl Behaviour {
    pub(crate) fn new(sensor: &Sensor) -> Self {
        let start = role_index(sensor, Role::StartMeasurement);
        let stop = role_index(sensor, Role::StopMeasurement);
        let warm_up =
            sensor.procedure.as_ref().map_or(Duration::ZERO, |p| Duration::from_millis(u64::from(p.warm_up_ms)));
        let started_by_procedure = match (&sensor.procedure, start.and_then(|i| sensor.commands.get(i))) {
            (None, _) => true,
            (Some(procedure), Some(start)) => procedure.before.contains(&start.name),
            (Some(_), None) => false,
        };
        let cycle =
            if (start.is_some() || stop.is_some()) && started_by_procedure { Cycle::Idle } else { Cycle::FreeRunning };
        Self { start, stop, warm_up, cycle, calibration: Calibration::new(sensor) }
    }

    /// The measurement state at clock time `now`.
    pub(crate) fn measurement_state(&self, now: Duration) -> MeasurementState {
        match self.cycle {
            Cycle::FreeRunning => MeasurementState::Measuring,
            Cycle::Idle => MeasurementState::Idle,
            Cycle::StartedAt(at) => {
                let remaining = (at + self.warm_up).saturating_sub(now);
                if remaining.is_zero() {
                    MeasurementState::Measuring
                } else {
                    MeasurementState::WarmingUp { remaining }
                }
            }
        }
    }

    /// Measures from now on whatever start or stop arrives (a probe that
    /// refuses Start Measurement and measures from power-on).
    pub(crate) fn free_running(&mut self) {
        self.cycle = Cycle::FreeRunning;
    }

    /// Calibration points recorded since the calibration (re)started.
    pub(crate) fn calibration_points(&self) -> &[f32] {
        self.calibration.as_ref().map_or(&[], |c| &c.points)
    }

    /// Runs the rules for command `index` carried out at clock time `now`
    /// (a read served, or a write stored).
    pub(crate) fn on_command(&mut self, index: usize, now: Duration) {
        if self.start == Some(index) {
            self.cycle = Cycle::StartedAt(now);
        } else if self.stop == Some(index) {
            self.cycle = Cycle::Idle;
        }
    }

    /// Runs the rules for a write of `data` to command `index`, already
    /// checked against the fields' ranges and about to be stored.
    pub(crate) fn on_write(
        &mut self,
        command: &CommandSpec,
        index: usize,
        data: &[u8],
        registers: &mut RegisterMap,
        now: Duration,
    ) {
        self.on_command(index, now);
        if let Some(cal) = self.calibration.as_mut().filter(|c| c.point == index) {
            let Some(field) = command.named_fields().next() else { return };
            let Some(bytes) = data.get(field.offset..field.offset + field.size()) else { return };
            let value = match decode_field(field, bytes) {
                Value::Float(v) => v,
                Value::Int(v) => v as f32,
                _ => return,
            };
            let code = cal.point(value);
            if let Ok(bytes) = encode_field(&cal.status_field, &Value::Enum { raw: code, name: None }) {
                registers.write_bytes(cal.status_address, cal.status_field.offset, &bytes);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn calibration() -> Calibration {
        Calibration {
            point: 0,
            status_address: 0x0E00,
            status_field: Field {
                name: Some("status".into()),
                kind: FieldKind::U8,
                offset: 0,
                unit: None,
                doc: None,
                range: None,
                typical: None,
                absent: None,
                examples: Vec::new(),
            },
            standards: vec![4.0, 6.86, 9.18],
            codes: StatusCodes { success: 0, not_a_standard: 1, too_few: 2 },
            points: Vec::new(),
        }
    }

    #[test]
    fn three_points_in_order_succeed() {
        let mut c = calibration();
        assert_eq!(c.point(4.0), 2);
        assert_eq!(c.point(6.86), 2);
        assert_eq!(c.point(9.18), 0);
        assert!(c.points.is_empty(), "a new calibration may start");
    }

    #[test]
    fn tolerance_and_failures() {
        let mut c = calibration();
        assert_eq!(c.point(4.004), 2, "within the tolerance");
        assert_eq!(c.point(6.87), 1, "0.01 off");
        assert!(c.points.is_empty());
        assert_eq!(c.point(9.18), 1, "out of order");
        assert_eq!(c.point(4.0), 2);
        assert_eq!(c.point(4.0), 2, "the first standard again restarts");
        assert_eq!(c.points, [4.0]);
    }

    #[test]
    fn model_code_bytes_read_the_digits_as_hex() {
        assert_eq!(model_code_byte("09"), Some(0x09));
        assert_eq!(model_code_byte("29"), Some(0x29));
        assert_eq!(model_code_byte("48"), Some(0x48));
        assert_eq!(model_code_byte("4"), None);
        assert_eq!(model_code_byte("4G"), None);
        assert_eq!(model_code_byte("+4"), None);
    }
}
