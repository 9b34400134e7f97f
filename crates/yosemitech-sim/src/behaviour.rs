//! Sensor-specific behaviour beyond "reads return registers, writes store
//! them", keyed by the spec's names, in one place.
//!
//! Everything else the simulator does follows from the spec's generic
//! attributes (function, address, count, `fixed_slave`, `trigger`, field
//! `range`s, examples). The rules below switch on only when a sensor's spec
//! has the names they look for, so a spec loaded at run time with none of
//! them simulates as plain register storage, and one that reuses the names
//! gets the behaviour with no Rust written.
//!
//! | rule | keyed by | behaviour |
//! |---|---|---|
//! | slave address | a field named [`ADDRESS_FIELD`] in any command | the field holds the device's address: reads report the current address, a write changes the address *after* the reply (which comes from the old address); see [`crate::Simulator::set_address`] |
//! | measurement trigger | every write command with `trigger: true`; the constant [`WARM_UP_CONSTANT`] (ms, 0 if absent) | a trigger starts a measurement; [`MeasurementState`] goes `Idle` → `WarmingUp` → `Measuring` (a sensor without trigger commands is always `Measuring`); readings are plain meanwhile unless [`WarmUpPolicy::Busy`] |
//! | three-point calibration | constant [`CALIBRATION_STANDARDS_CONSTANT`], write command [`CALIBRATION_POINT_COMMAND`] (its first named field is the standard written), read command [`CALIBRATION_STATUS_COMMAND`] (its enum field with the variants [`STATUS_SUCCESS`], [`STATUS_NOT_A_STANDARD`], [`STATUS_TOO_FEW_POINTS`]) | see below |
//!
//! # Three-point calibration
//!
//! The device expects the standards of the constant in their order (pH:
//! 4.00, 6.86, 9.18). Each point written is compared with the next expected
//! standard, within [`STANDARD_TOLERANCE`]:
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

use std::time::Duration;

use yosemitech_spec::interp::{decode_field, encode_field};
use yosemitech_spec::{Command, Field, FieldKind, Sensor, Value};

use crate::registers::RegisterMap;

/// Field name whose value is the device's slave address.
pub const ADDRESS_FIELD: &str = "slave_address";

/// Constant: milliseconds from a measurement trigger until readings are valid.
pub const WARM_UP_CONSTANT: &str = "measurement_warm_up_ms";

/// Constant: the calibration standards, in the order they must be calibrated.
pub const CALIBRATION_STANDARDS_CONSTANT: &str = "ph_calibration_standards";

/// Write command: calibrates one point (its first named field is the standard).
pub const CALIBRATION_POINT_COMMAND: &str = "start_ph_calibration";

/// Read command: the outcome of the last calibration (an enum field).
pub const CALIBRATION_STATUS_COMMAND: &str = "get_calibration_status";

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
    /// Not triggered yet (only sensors with a trigger command).
    Idle,
    /// Triggered; readings valid after `remaining`.
    WarmingUp {
        /// Time left until readings are valid.
        remaining: Duration,
    },
    /// Readings are valid (always, for sensors without a trigger command).
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
        let standards = sensor.constant(CALIBRATION_STANDARDS_CONSTANT)?.values.clone();
        let point = sensor.commands.iter().position(|c| c.name == CALIBRATION_POINT_COMMAND && !c.is_read())?;
        let status = sensor.command(CALIBRATION_STATUS_COMMAND).filter(|c| c.is_read())?;
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

/// The sensor-specific rules of one simulated device.
#[derive(Debug, Clone)]
pub(crate) struct Behaviour {
    /// Indices of trigger commands.
    triggers: Vec<usize>,
    warm_up: Duration,
    /// Clock time of the last trigger.
    triggered_at: Option<Duration>,
    calibration: Option<Calibration>,
}

impl Behaviour {
    pub(crate) fn new(sensor: &Sensor) -> Self {
        let triggers = sensor.commands.iter().enumerate().filter(|(_, c)| c.trigger).map(|(i, _)| i).collect();
        let warm_up = sensor
            .constant(WARM_UP_CONSTANT)
            .and_then(|c| c.values.first())
            .map_or(Duration::ZERO, |ms| Duration::from_secs_f64(ms.max(0.0) / 1000.0));
        Self { triggers, warm_up, triggered_at: None, calibration: Calibration::new(sensor) }
    }

    /// The measurement state at clock time `now`.
    pub(crate) fn measurement_state(&self, now: Duration) -> MeasurementState {
        if self.triggers.is_empty() {
            return MeasurementState::Measuring;
        }
        match self.triggered_at {
            None => MeasurementState::Idle,
            Some(at) => {
                let remaining = (at + self.warm_up).saturating_sub(now);
                if remaining.is_zero() {
                    MeasurementState::Measuring
                } else {
                    MeasurementState::WarmingUp { remaining }
                }
            }
        }
    }

    /// Calibration points recorded since the calibration (re)started.
    pub(crate) fn calibration_points(&self) -> &[f32] {
        self.calibration.as_ref().map_or(&[], |c| &c.points)
    }

    /// Runs the rules for a write of `data` to command `index`, already
    /// checked against the fields' ranges and about to be stored.
    pub(crate) fn on_write(
        &mut self,
        command: &Command,
        index: usize,
        data: &[u8],
        registers: &mut RegisterMap,
        now: Duration,
    ) {
        if self.triggers.contains(&index) {
            self.triggered_at = Some(now);
        }
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
}
