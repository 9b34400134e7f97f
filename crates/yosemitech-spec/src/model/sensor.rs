//! What the CLI, the simulator and the station ask of a sensor: its
//! commands by name and by role, its measurements, its calibration blocks,
//! its models and manuals.

use yosemitech_rtu::LineSettings;

use super::{CommandSpec, Constant, Derived, Field, FieldKind, Manual, Provenance, Role, Sensor};

impl Sensor {
    /// The command called `name`.
    pub fn command(&self, name: &str) -> Option<&CommandSpec> {
        self.commands.iter().find(|c| c.name == name)
    }

    /// The derived quantity called `name`.
    pub fn derived(&self, name: &str) -> Option<&Derived> {
        self.derived.iter().find(|d| d.name == name)
    }

    /// The constant called `name`.
    pub fn constant(&self, name: &str) -> Option<&Constant> {
        self.constants.iter().find(|c| c.name == name)
    }

    /// Every example frame of every command.
    pub fn example_count(&self) -> usize {
        self.commands.iter().map(|c| c.examples.len()).sum()
    }

    /// True for a measurement read: a read with a field that has a unit,
    /// whose registers no write command of the sensor covers (a trigger write
    /// of zero registers covers none) (so neither a
    /// setting nor a calibration block). The simulator varies these, `poll`
    /// and the station logger read them.
    pub fn is_measurement(&self, read: &CommandSpec) -> bool {
        is_measurement_among(&self.commands, read)
    }

    /// The measurement reads ([`Sensor::is_measurement`]), in spec order.
    pub fn measurement_reads(&self) -> impl Iterator<Item = &CommandSpec> {
        self.commands.iter().filter(|c| self.is_measurement(c))
    }

    /// The calibration-coefficient blocks, in spec order: each write of
    /// float fields only (not a trigger, not the slave address) paired with
    /// the read of exactly the same registers. What a coefficient backup
    /// saves and a restore writes back and reads back.
    pub fn coefficient_blocks(&self) -> Vec<(&CommandSpec, &CommandSpec)> {
        self.commands
            .iter()
            .filter(|w| !w.is_read() && !w.trigger && w.count > 0)
            .filter(|w| w.named_fields().all(|f| matches!(f.kind, FieldKind::F32 { .. })))
            .filter(|w| w.field("slave_address").is_none())
            .filter_map(|w| {
                self.commands
                    .iter()
                    .find(|r| r.is_read() && r.address == w.address && r.count == w.count)
                    .map(|r| (w, r))
            })
            .collect()
    }

    /// The user calibration blocks: each write with role `user_calibration`
    /// paired with the read of the same registers (validation guarantees
    /// the read), in spec order. Their fields are slope K, then offset B.
    pub fn user_calibrations(&self) -> Vec<(&CommandSpec, &CommandSpec)> {
        self.coefficient_blocks().into_iter().filter(|(w, _)| w.role == Some(Role::UserCalibration)).collect()
    }

    /// The named fields of the measurement reads among `commands` (see
    /// [`Sensor::is_measurement`]), in order.
    pub fn measured_fields(commands: &[CommandSpec]) -> Vec<&str> {
        commands
            .iter()
            .filter(|read| is_measurement_among(commands, read))
            .flat_map(|c| c.named_fields().map(Field::display_name))
            .collect()
    }

    /// The measurement read with a named field called `field`.
    pub fn measurement_with_field(&self, field: &str) -> Option<&CommandSpec> {
        self.measurement_reads().find(|c| c.named_fields().any(|f| f.display_name() == field))
    }

    /// The command with `role`, if the sensor has one.
    pub fn command_with_role(&self, role: Role) -> Option<&CommandSpec> {
        self.commands.iter().find(|c| c.role == Some(role))
    }

    /// Every manual of the probe: the file's `manual` first, then its revisions.
    pub fn manuals(&self) -> impl Iterator<Item = &Manual> {
        self.manual.iter().chain(self.revisions.iter().map(|r| &r.manual))
    }

    /// Every model code the sensor's own model carries, the main one first.
    pub fn model_codes(&self) -> impl Iterator<Item = &str> {
        self.model_code.iter().chain(&self.also_model_codes).map(String::as_str)
    }

    /// The models whose serial numbers carry `code`: the sensor's own model
    /// and its aliases (an alias without a code of its own shares the
    /// sensor's). Empty when the sensor declares no such code.
    pub fn models_with_code(&self, code: &str) -> Vec<&str> {
        let own = self.model_codes().any(|c| c == code);
        let mut models: Vec<&str> = Vec::new();
        if own {
            models.push(self.model.as_deref().unwrap_or(&self.name));
        }
        for alias in &self.aliases {
            let alias_code = alias.model_code.as_deref().or(self.model_code.as_deref());
            if alias_code == Some(code) {
                models.push(&alias.model);
            }
        }
        models
    }

    /// True when `code` names this sensor's model or one of its aliases.
    pub fn declares_model_code(&self, code: &str) -> bool {
        !self.models_with_code(code).is_empty()
    }

    /// True when `name` is the sensor's name, its model or one of its
    /// aliases' models (ignoring ASCII case).
    pub fn answers_to(&self, name: &str) -> bool {
        self.name.eq_ignore_ascii_case(name)
            || self.model.as_deref().is_some_and(|m| m.eq_ignore_ascii_case(name))
            || self.aliases.iter().any(|a| a.model.eq_ignore_ascii_case(name))
    }

    /// Where a command's facts come from when no manual states them: its
    /// own provenance, else the sensor's.
    pub fn provenance_of<'s>(&'s self, command: &'s CommandSpec) -> Option<&'s Provenance> {
        command.provenance.as_ref().or(self.provenance.as_ref())
    }

    /// The serial settings of a probe running `software` (the newest when unknown).
    pub fn serial_for(&self, software: &str) -> LineSettings {
        self.revisions.iter().find(|r| r.manual.software.as_deref() == Some(software)).map_or(self.serial, |r| r.serial)
    }

    /// The serial number the manual prints (the first example of the
    /// `serial_number` command), if any.
    pub fn example_serial_number(&self) -> Option<String> {
        let command = self.command_with_role(Role::SerialNumber)?;
        command.examples.iter().find_map(|e| match e.values.values().next() {
            Some(crate::Value::Text(t)) => Some(t.clone()),
            _ => None,
        })
    }
}

/// [`Sensor::is_measurement`] for a sensor of `commands`.
fn is_measurement_among(commands: &[CommandSpec], read: &CommandSpec) -> bool {
    let end = |c: &CommandSpec| u32::from(c.address) + u32::from(c.count);
    read.is_read()
        && read.fields.iter().any(|f| f.unit.is_some())
        && !commands.iter().any(|w| {
            !w.is_read() && w.count > 0 && u32::from(w.address) < end(read) && u32::from(read.address) < end(w)
        })
}
