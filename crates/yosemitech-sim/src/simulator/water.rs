//! Variation and water: readings that move like a river's, reproducibly.

use std::collections::BTreeMap;
use std::sync::Arc;
use std::time::Duration;

use yosemitech_spec::interp::{decode_field, encode_command_field};
use yosemitech_spec::{CommandSpec, Field, FieldKind, Value};

use crate::fault::Rng;

use super::Simulator;

/// Deterministic variation of the readings: a daily cycle, noise and drift.
///
/// On each read of a *measurement* command (a read that no write command
/// covers and that has a field with a unit: pH, temperature, conductivity,
/// ORP), every f32 quantity it holds is set to
/// `base + swing * span * sin(2 pi t / day + phase) + drift_per_read * n + noise * u`
/// before the reply is built, where `base` is the value when the variation
/// was enabled or last [`Simulator::set`] (see [`Simulator::fill_with_water`]
/// for plausible ones), `span` from [`daily_span`], `t`
/// the time of day (the wall clock, so probes on one bus see the same
/// water; the manual clock when [`Simulator::with_manual_clock`]), `phase`
/// the same for every temperature (unit `degC`) and different for other
/// quantities, `n` the number of earlier reads of the quantity and `u`
/// uniform in `[-1, 1)` from a generator seeded with `seed`, drawn once a
/// second of the clock (a probe measures about once a second); clamped to
/// the field's `range` if it has one. A quantity is a field name of the
/// sensor: the new value goes to every register that holds it, so two
/// reads of pH (`get_ph`, `get_orp_and_ph`) at one moment agree. The
/// registers hold what was sent, so [`Simulator::get`] after a read is the
/// truth the client saw.
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

/// The variation's state. A quantity (a field name of the sensor: `ph`
/// in `get_ph` and in `get_orp_and_ph`) is one value of the water, whatever
/// command reads it: its base, phase, drift and noise are the quantity's,
/// and its new value goes to every register that holds it.
#[derive(Debug, Clone)]
pub(super) struct VariationState {
    config: Variation,
    rng: Rng,
    /// Base value by quantity.
    pub(super) bases: BTreeMap<String, f32>,
    /// Reads served by quantity.
    reads: BTreeMap<String, u64>,
    /// The noise of a quantity and the second of the clock it was drawn
    /// in: a probe measures about once a second, so reads within one
    /// second see one measurement.
    noise: BTreeMap<String, (u64, f32)>,
}

impl Simulator {
    /// Turns deterministic noise and drift of the readings on (`Some`) or off.
    pub fn set_variation(&mut self, variation: Option<Variation>) {
        self.variation = variation.map(|config| VariationState {
            config,
            rng: Rng::new(config.seed),
            bases: BTreeMap::new(),
            reads: BTreeMap::new(),
            noise: BTreeMap::new(),
        });
    }

    /// Sets every f32 field of every measurement read to a plausible value
    /// of natural water: the field's `typical`, else the water temperature
    /// for a temperature (within its range), else the middle of its range;
    /// a field with none of these keeps its value. Variation then cycles
    /// around these.
    pub fn fill_with_water(&mut self) {
        let sensor = Arc::clone(&self.sensor);
        // One value per quantity, from the first field of that name that
        // says enough: every register holding the quantity gets it.
        let mut values: BTreeMap<&str, f64> = BTreeMap::new();
        for (_, field) in self.measured_floats(&sensor) {
            let Some(name) = field.name.as_deref() else { continue };
            if values.contains_key(name) {
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
            values.insert(name, value);
        }
        for (index, field) in self.measured_floats(&sensor) {
            let Some(value) = field.name.as_deref().and_then(|n| values.get(n)) else { continue };
            if let Some(command) = sensor.commands.get(index)
                && let Ok(bytes) = encode_command_field(command, field, &Value::Float(*value as f32))
            {
                self.registers_of_mut(index).write_bytes(command.address, field.offset, &bytes);
            }
        }
        if let Some(v) = self.variation.as_mut() {
            v.bases.clear();
        }
    }

    /// Every f32 field of every measurement read, with its command's index.
    fn measured_floats<'s>(&self, sensor: &'s yosemitech_spec::Sensor) -> Vec<(usize, &'s Field)> {
        sensor
            .commands
            .iter()
            .enumerate()
            .filter(|(index, _)| self.measurement.get(*index).copied().unwrap_or(false))
            .flat_map(|(index, c)| c.fields.iter().map(move |f| (index, f)))
            .filter(|(_, f)| matches!(f.kind, FieldKind::F32 { .. }) && f.name.is_some())
            .collect()
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

    /// Applies the variation to a measurement read about to be served:
    /// each quantity it holds gets its value of now, written to every
    /// register that holds the quantity.
    pub(super) fn vary(&mut self, index: usize, command: &CommandSpec) {
        if !self.measurement.get(index).copied().unwrap_or(false) {
            return;
        }
        let Some(day) = self.variation.as_ref().map(|v| v.config.day) else { return };
        let fraction = self.time_of_day(day);
        let second = self.clock.now().as_secs();
        let sensor = Arc::clone(&self.sensor);
        let quantities = self.measured_floats(&sensor);
        // The phase of a quantity: its place among the sensor's quantities.
        let mut names: Vec<&str> = quantities.iter().filter_map(|(_, f)| f.name.as_deref()).collect();
        names.dedup();
        let mut seen: Vec<&str> = Vec::new();
        for field in command.fields.iter().filter(|f| matches!(f.kind, FieldKind::F32 { .. })) {
            let Some(name) = field.name.as_deref() else { continue };
            if seen.contains(&name) {
                continue;
            }
            seen.push(name);
            let place = names.iter().position(|n| *n == name).unwrap_or(0);
            let registers = self.own_registers.get(&index).unwrap_or(&self.registers);
            let held = registers.read(command.address, command.count);
            let Some(variation) = self.variation.as_mut() else { return };
            let base = *variation.bases.entry(name.to_owned()).or_insert_with(|| {
                match held.get(field.offset..field.offset + field.size()).map(|b| decode_field(field, b)) {
                    Some(Value::Float(v)) => v,
                    _ => 0.0,
                }
            });
            let reads = variation.reads.entry(name.to_owned()).or_insert(0);
            let n = *reads as f32;
            *reads += 1;
            let noise = match variation.noise.get(name) {
                Some((drawn, noise)) if *drawn == second => *noise,
                _ => {
                    let noise = variation.config.noise * variation.rng.next_signed() as f32;
                    variation.noise.insert(name.to_owned(), (second, noise));
                    noise
                }
            };
            // Every temperature swings alike and peaks together (one water);
            // other quantities swing with their range, each at its own hour.
            let temperature = field.unit.as_deref() == Some("degC");
            let span = daily_span(field, base);
            let phase = if temperature { 0.0 } else { 0.7 * (place as f64 + 1.0) };
            let cycle = f64::from(variation.config.daily_swing)
                * span
                * (std::f64::consts::TAU * fraction - std::f64::consts::FRAC_PI_2 + phase).sin();
            let mut value = base + cycle as f32 + variation.config.drift_per_read * n + noise;
            if let Some((min, max)) = field.range {
                value = value.clamp(min as f32, max as f32);
            }
            // Every register of the quantity; a read is not bounded by its
            // range on the wire: encode as the probe would.
            for (holder, f) in quantities.iter().filter(|(_, f)| f.name.as_deref() == Some(name)) {
                let Some(c) = sensor.commands.get(*holder) else { continue };
                if let Ok(bytes) = encode_command_field(c, f, &Value::Float(value)) {
                    self.registers_of_mut(*holder).write_bytes(c.address, f.offset, &bytes);
                }
            }
        }
    }
}
