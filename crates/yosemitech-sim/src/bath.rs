//! A probe sitting in a calibration standard, for K/B calibrations.
//!
//! [`crate::Simulator::immerse`] puts the probe in a [`Standard`]: from then
//! on every measurement read with the calibrated field reports
//! final = K x raw + B, with K and B what the user calibration block's
//! registers hold now, and raw = (value - b_true) / k_true + noise: the
//! probe's own error is the line (k_true, b_true), so a calibration that
//! finds K = k_true and B = b_true makes it read the standard again. The
//! noise is uniform in `[-noise, noise]`, from a seeded generator, so a run
//! repeats.

use yosemitech_spec::interp::{decode_field, encode_command_field};
use yosemitech_spec::{CommandSpec, FieldKind, Value};

use crate::fault::Rng;
use crate::registers::RegisterMap;

/// The standard a simulated probe sits in, and the probe's error.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Standard {
    /// The standard's true value, in the calibrated field's unit.
    pub value: f64,
    /// The probe's true slope error: raw = (value - b_true) / k_true.
    pub k_true: f64,
    /// The probe's true offset error.
    pub b_true: f64,
    /// Half-width of the uniform noise on the raw reading.
    pub noise: f64,
    /// Seed of the noise.
    pub seed: u64,
}

/// Where a standard shows: the field and the K/B block applied to it.
#[derive(Debug, Clone)]
pub(crate) struct Bath {
    pub(crate) standard: Standard,
    /// The calibrated field's name.
    pub(crate) field: String,
    /// The user calibration write whose registers hold K and B.
    pub(crate) block: usize,
    rng: Rng,
}

impl Bath {
    pub(crate) fn new(standard: Standard, field: String, block: usize) -> Self {
        Self { rng: Rng::new(standard.seed), standard, field, block }
    }

    /// The raw reading now: the standard through the probe's error, with noise.
    fn raw(&mut self) -> f64 {
        let s = self.standard;
        (s.value - s.b_true) / s.k_true + s.noise * self.rng.next_signed()
    }

    /// The reading of the calibrated field in `read`, through the K and B
    /// `block` holds in `registers`: the field's byte offset and its bytes.
    /// `None` for a read without the field, or a block whose registers do
    /// not decode.
    pub(crate) fn reading(
        &mut self,
        read: &CommandSpec,
        block: &CommandSpec,
        registers: &RegisterMap,
    ) -> Option<(usize, Vec<u8>)> {
        let field = read.named_fields().find(|f| f.display_name() == self.field)?;
        if !matches!(field.kind, FieldKind::F32 { .. }) {
            return None;
        }
        let bytes = registers.read(block.address, block.count);
        let mut coefficients = block.named_fields().map(|f| match bytes.get(f.offset..f.offset + f.size()) {
            Some(b) => match decode_field(f, b) {
                Value::Float(v) => Some(f64::from(v)),
                _ => None,
            },
            None => None,
        });
        let (Some(k), Some(b)) = (coefficients.next().flatten(), coefficients.next().flatten()) else { return None };
        let value = (k * self.raw() + b) as f32;
        encode_command_field(read, field, &Value::Float(value)).ok().map(|encoded| (field.offset, encoded))
    }
}

#[cfg(test)]
mod tests {
    use std::collections::BTreeMap;

    use yosemitech_rtu::Responder;
    use yosemitech_spec::Value;
    use yosemitech_tests::spec;

    use super::Standard;
    use crate::Simulator;

    /// What `read` returns for `field` now, through the simulator's wire path.
    fn served(sim: &mut Simulator, read: &yosemitech_spec::CommandSpec, field: &str) -> f64 {
        let slave = sim.address();
        let request = read.encode_request(slave, &BTreeMap::new()).unwrap();
        let mut reply = Vec::new();
        sim.respond(&request, &mut reply);
        let values = read.decode_response(slave, &reply).unwrap();
        match values.into_iter().find(|(n, _)| n == field) {
            Some((_, Value::Float(v))) => f64::from(v),
            other => panic!("{}.{field}: {other:?}", read.name),
        }
    }

    #[test]
    fn a_probe_in_a_standard_reads_it_through_its_error_and_its_k_and_b() {
        let mut checked = 0;
        for sensor in &spec().sensors {
            for (write, _) in sensor.user_calibrations() {
                let Some(field) = write.calibrates.as_ref().map(|c| c.field.clone()) else { continue };
                let read = sensor.measurement_with_field(&field).unwrap();
                let (k_name, b_name) = {
                    let mut names = write.named_fields().map(|f| f.display_name().to_owned());
                    (names.next().unwrap(), names.next().unwrap())
                };
                let mut sim = Simulator::new(sensor.clone());
                let standard = Standard { value: 20.0, k_true: 0.8, b_true: 1.5, noise: 0.0, seed: 1 };
                sim.immerse(Some((standard, &field, &write.name))).unwrap();
                let raw = (20.0 - 1.5) / 0.8;
                for (k, b) in [(1.0f32, 0.0f32), (0.8, 1.5), (2.0, -3.0)] {
                    sim.set(&write.name, &k_name, Value::Float(k)).unwrap();
                    sim.set(&write.name, &b_name, Value::Float(b)).unwrap();
                    let want = f64::from(k) * raw + f64::from(b);
                    let got = served(&mut sim, read, &field);
                    assert!((got - want).abs() < 1e-4, "{}.{field} with K {k}, B {b}: {got} vs {want}", sensor.name);
                }
                // Noise stays within its bound and varies.
                let noisy = Standard { noise: 0.01, ..standard };
                sim.immerse(Some((noisy, &field, &write.name))).unwrap();
                sim.set(&write.name, &k_name, Value::Float(1.0)).unwrap();
                sim.set(&write.name, &b_name, Value::Float(0.0)).unwrap();
                let readings: Vec<f64> = (0..20).map(|_| served(&mut sim, read, &field)).collect();
                assert!(readings.iter().all(|r| (r - raw).abs() <= 0.0101), "{readings:?}");
                assert!(readings.iter().any(|r| (r - readings[0]).abs() > 0.0), "{readings:?}");
                // Out of the standard, the read returns its registers again.
                sim.immerse(None).unwrap();
                sim.set(&read.name, &field, Value::Float(3.25)).unwrap();
                assert_eq!(served(&mut sim, read, &field), 3.25);
                checked += 1;
            }
        }
        assert!(checked > 1, "no sensor states what its calibration block calibrates");
    }

    #[test]
    fn immersing_needs_a_measured_field_and_a_command() {
        let sensor = spec().sensors.iter().find(|s| !s.user_calibrations().is_empty()).unwrap().clone();
        let (write, _) = sensor.user_calibrations()[0];
        let standard = Standard { value: 1.0, k_true: 1.0, b_true: 0.0, noise: 0.0, seed: 1 };
        let mut sim = Simulator::new(sensor.clone());
        assert!(sim.immerse(Some((standard, "no_such_field", &write.name))).is_err());
        let field = sensor.measurement_reads().flat_map(|r| r.named_fields()).next().unwrap().display_name();
        assert!(sim.immerse(Some((standard, field, "no_such_command"))).is_err());
    }
}
