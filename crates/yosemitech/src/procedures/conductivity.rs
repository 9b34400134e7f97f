//! The conductivity measurement procedure (conductivity manual, section 3).
//!
//! Start Measurement, wait the warm-up (10 s), then read temperature and
//! conductivity every 3 s and average 10 readings; TDS (mg/L) is the mean
//! conductivity in uS/cm times 0.64. The manual leaves open what to do with
//! readings whose range-switch flag is set: they are discarded and replaced
//! by further readings, up to [`MeasurementConfig::max_reads`]. Temperature
//! is averaged over the same readings.

use std::time::Duration;

use super::{ProcedureError, Sleep};
use crate::Transport;
use crate::conductivity::{
    Device, GetTemperatureAndConductivityResponse, MEASUREMENT_WARM_UP_MS, READING_INTERVAL_MS, READINGS_TO_AVERAGE,
    RangeStatus, TDS_MG_L_PER_US_CM,
};

/// Timing and averaging of a measurement; [`Default`] is the manual's.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct MeasurementConfig {
    /// Wait after Start Measurement.
    pub warm_up: Duration,
    /// Wait between readings.
    pub interval: Duration,
    /// Valid readings to average.
    pub readings: usize,
    /// Most readings to take in all, flagged ones included.
    pub max_reads: usize,
}

impl Default for MeasurementConfig {
    fn default() -> Self {
        let readings = READINGS_TO_AVERAGE as usize;
        Self {
            warm_up: Duration::from_millis(u64::from(MEASUREMENT_WARM_UP_MS)),
            interval: Duration::from_millis(u64::from(READING_INTERVAL_MS)),
            readings,
            max_reads: readings * 2,
        }
    }
}

/// The result of a measurement.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Measurement {
    /// Mean conductivity, mS/cm.
    pub conductivity_ms_cm: f32,
    /// Mean temperature, degrees C.
    pub temperature_c: f32,
    /// Total dissolved solids, mg/L (mean uS/cm x 0.64).
    pub tds_mg_l: f32,
    /// Readings averaged.
    pub readings: usize,
    /// Readings discarded (range-switch error or not finite).
    pub discarded: usize,
}

/// What a measurement is doing, for progress display.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum MeasurementEvent {
    /// Measurement started; waiting `warm_up`.
    WarmingUp {
        /// The wait.
        warm_up: Duration,
    },
    /// A reading arrived.
    Reading {
        /// Valid readings so far (this one included if accepted).
        accepted: usize,
        /// Valid readings needed.
        needed: usize,
        /// The reading.
        reading: GetTemperatureAndConductivityResponse,
        /// Whether it counts towards the average.
        valid: bool,
    },
}

/// TDS in mg/L from conductivity in mS/cm: uS/cm x 0.64.
pub fn tds_mg_l(conductivity_ms_cm: f32) -> f32 {
    (f64::from(conductivity_ms_cm) * 1000.0 * f64::from(TDS_MG_L_PER_US_CM)) as f32
}

/// Whether a reading may be averaged.
pub fn is_valid(reading: &GetTemperatureAndConductivityResponse) -> bool {
    reading.range_status == RangeStatus::Ok
        && reading.conductivity_ms_cm.is_finite()
        && reading.temperature_c.is_finite()
}

/// Runs the manual's measurement procedure on `probe`.
pub fn measure<T: Transport>(
    probe: &mut Device<'_, T>,
    config: &MeasurementConfig,
    sleep: &mut dyn Sleep,
    events: &mut dyn FnMut(MeasurementEvent),
) -> Result<Measurement, ProcedureError> {
    probe.start_measurement()?;
    events(MeasurementEvent::WarmingUp { warm_up: config.warm_up });
    sleep.sleep(config.warm_up);
    let (mut sum_cond, mut sum_temp) = (0f64, 0f64);
    let (mut accepted, mut discarded) = (0usize, 0usize);
    for read in 0..config.max_reads.max(config.readings) {
        if accepted == config.readings {
            break;
        }
        if read > 0 {
            sleep.sleep(config.interval);
        }
        let reading = probe.temperature_and_conductivity()?;
        let valid = is_valid(&reading);
        if valid {
            accepted += 1;
            sum_cond += f64::from(reading.conductivity_ms_cm);
            sum_temp += f64::from(reading.temperature_c);
        } else {
            discarded += 1;
        }
        events(MeasurementEvent::Reading { accepted, needed: config.readings, reading, valid });
    }
    if accepted < config.readings || accepted == 0 {
        return Err(ProcedureError::NotEnoughReadings { accepted, needed: config.readings, discarded });
    }
    let n = accepted as f64;
    let conductivity_ms_cm = (sum_cond / n) as f32;
    Ok(Measurement {
        conductivity_ms_cm,
        temperature_c: (sum_temp / n) as f32,
        tds_mg_l: tds_mg_l(conductivity_ms_cm),
        readings: accepted,
        discarded,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tds_follows_the_manual() {
        // 17.625 mS/cm = 17625 uS/cm; x 0.64 = 11280 mg/L.
        assert!((tds_mg_l(17.625) - 11280.0).abs() < 0.01);
    }

    #[test]
    fn defaults_are_the_manuals() {
        let c = MeasurementConfig::default();
        assert_eq!(c.warm_up, Duration::from_secs(10));
        assert_eq!(c.interval, Duration::from_secs(3));
        assert_eq!(c.readings, 10);
    }
}
