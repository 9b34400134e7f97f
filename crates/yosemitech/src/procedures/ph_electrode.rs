//! The pH electrode's coefficients K1..K6 computed on the master, by the
//! vendor's model of the electrode (the spec's `electrode_*` constants),
//! from the potential and temperature the probe reads in each of the three
//! standard buffers.
//!
//! The model: E = E0 + S (7 - pH), S = 54.2 + 0.1984 t + S0. K1 and K4 are
//! the potential in the neutral buffer (6.86); K2 and K3 the offset and the
//! slope's departure from the model on the acid segment (4.00 to 6.86), K5
//! and K6 on the alkaline one (6.86 to 9.18). As the vendor's worksheet
//! does, the acid slope is compared with the model at the temperature read
//! in the 6.86 buffer, the alkaline one at that read in the 9.18 buffer.

use std::fmt;

use crate::ph_orp::{ELECTRODE_SLOPE_MV, ELECTRODE_SLOPE_PER_DEGC, ELECTRODE_ZERO_PH, PH_CALIBRATION_STANDARDS};

/// What the probe read in one buffer.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BufferReading {
    /// The buffer's pH (one of the calibration standards).
    pub buffer_ph: f32,
    /// The electrode potential, mV.
    pub potential_mv: f32,
    /// The temperature, degrees C.
    pub temperature_c: f32,
}

/// The slopes a working electrode shows, mV per pH unit: outside them the
/// readings are of a dead electrode, a swapped buffer or a dry probe.
pub const PLAUSIBLE_SLOPE_MV: (f32, f32) = (30.0, 75.0);

/// Why the coefficients cannot be computed.
#[derive(Debug, Clone, PartialEq)]
pub enum ComputeError {
    /// Not one reading per standard buffer, in the standards' order.
    Buffers {
        /// The buffers given, in order.
        given: Vec<f32>,
    },
    /// A reading is not a finite number, or its temperature is outside 0..=60 degrees C.
    Reading {
        /// Which buffer.
        buffer_ph: f32,
        /// What is wrong.
        why: &'static str,
    },
    /// A segment's slope is not what an electrode gives.
    Slope {
        /// The segment's buffers.
        from_ph: f32,
        /// The segment's buffers.
        to_ph: f32,
        /// Its slope, mV per pH unit.
        slope_mv: f32,
    },
}

impl fmt::Display for ComputeError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Buffers { given } => {
                let given: Vec<String> = given.iter().map(|b| format!("{b:.2}")).collect();
                let want: Vec<String> = PH_CALIBRATION_STANDARDS.iter().map(|b| format!("{b:.2}")).collect();
                write!(
                    f,
                    "readings of buffers {} are needed, in that order; given: {}",
                    want.join(", "),
                    given.join(", ")
                )
            }
            Self::Reading { buffer_ph, why } => write!(f, "the reading in buffer {buffer_ph:.2}: {why}"),
            Self::Slope { from_ph, to_ph, slope_mv } => write!(
                f,
                "from buffer {from_ph:.2} to {to_ph:.2} the potential falls {slope_mv:.1} mV per pH unit, where an \
                 electrode gives {:.0} to {:.0}: a swapped buffer, a dry or worn electrode",
                PLAUSIBLE_SLOPE_MV.0, PLAUSIBLE_SLOPE_MV.1
            ),
        }
    }
}

impl std::error::Error for ComputeError {}

/// The model's slope at `temperature_c`, mV per pH unit (S0 = 0).
pub fn model_slope_mv(temperature_c: f32) -> f32 {
    ELECTRODE_SLOPE_MV + ELECTRODE_SLOPE_PER_DEGC * temperature_c
}

/// K1..K6 from one reading per standard buffer, in the standards' order
/// (4.00, 6.86, 9.18).
pub fn compute(readings: &[BufferReading]) -> Result<[f32; 6], ComputeError> {
    let [acid, neutral, alkaline] = readings else {
        return Err(ComputeError::Buffers { given: readings.iter().map(|r| r.buffer_ph).collect() });
    };
    let in_order = readings.iter().zip(PH_CALIBRATION_STANDARDS).all(|(r, s)| (r.buffer_ph - s).abs() < 0.005);
    if !in_order {
        return Err(ComputeError::Buffers { given: readings.iter().map(|r| r.buffer_ph).collect() });
    }
    for r in readings {
        if !r.potential_mv.is_finite() || !r.temperature_c.is_finite() {
            return Err(ComputeError::Reading { buffer_ph: r.buffer_ph, why: "not a number" });
        }
        if !(0.0..=60.0).contains(&r.temperature_c) {
            return Err(ComputeError::Reading { buffer_ph: r.buffer_ph, why: "temperature outside 0 to 60 degrees C" });
        }
    }
    let zero = ELECTRODE_ZERO_PH;
    // The potential falls as the pH rises: each segment's slope, positive.
    let segment = |outer: &BufferReading| -> Result<f32, ComputeError> {
        let slope = (outer.potential_mv - neutral.potential_mv) / (neutral.buffer_ph - outer.buffer_ph);
        let (low, high) = PLAUSIBLE_SLOPE_MV;
        if (low..=high).contains(&slope) {
            Ok(slope)
        } else {
            let (from_ph, to_ph) = if outer.buffer_ph < neutral.buffer_ph {
                (outer.buffer_ph, neutral.buffer_ph)
            } else {
                (neutral.buffer_ph, outer.buffer_ph)
            };
            Err(ComputeError::Slope { from_ph, to_ph, slope_mv: slope })
        }
    };
    let acid_slope = segment(acid)?;
    let alkaline_slope = segment(alkaline)?;
    let offset = |outer: &BufferReading| {
        (neutral.potential_mv * (outer.buffer_ph - zero) - outer.potential_mv * (neutral.buffer_ph - zero))
            / (outer.buffer_ph - neutral.buffer_ph)
    };
    let k1 = neutral.potential_mv;
    let k2 = offset(acid);
    let k3 = acid_slope - model_slope_mv(neutral.temperature_c);
    let k5 = offset(alkaline);
    let k6 = alkaline_slope - model_slope_mv(alkaline.temperature_c);
    Ok([k1, k2, k3, k1, k5, k6])
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The potentials the model gives for an electrode of coefficients `k`,
    /// the inverse of [`compute`] worked by hand: each segment's slope is
    /// the model's plus its K, and its offset fixes the outer buffer.
    fn readings_for(k: [f32; 6], t: [f32; 3]) -> Vec<BufferReading> {
        let [acid_ph, neutral_ph, alkaline_ph] = PH_CALIBRATION_STANDARDS;
        let neutral = k[0];
        let acid = neutral + (k[2] + model_slope_mv(t[1])) * (neutral_ph - acid_ph);
        let alkaline = neutral - (k[5] + model_slope_mv(t[2])) * (alkaline_ph - neutral_ph);
        [(acid_ph, acid, t[0]), (neutral_ph, neutral, t[1]), (alkaline_ph, alkaline, t[2])]
            .map(|(buffer_ph, potential_mv, temperature_c)| BufferReading { buffer_ph, potential_mv, temperature_c })
            .to_vec()
    }

    #[test]
    fn a_real_probes_coefficients_come_back_from_its_potentials() {
        // A probe that read back 60.61, 52.40, -0.49, 60.61, 52.52, -1.39:
        // by hand, K2 = 52.40 puts its 4.00 buffer at 228.33 mV (K1 60.61),
        // and K3 = -0.49 then says the 6.86 buffer was at 24.86 degrees C;
        // K5 = 52.52 puts the 9.18 buffer at -73.45 mV, K6 = -1.39 at 25.07.
        let readings = [
            BufferReading { buffer_ph: 4.0, potential_mv: 228.33, temperature_c: 24.9 },
            BufferReading { buffer_ph: 6.86, potential_mv: 60.61, temperature_c: 24.86 },
            BufferReading { buffer_ph: 9.18, potential_mv: -73.45, temperature_c: 25.07 },
        ];
        let k = compute(&readings).unwrap();
        let expected = [60.61, 52.40, -0.49, 60.61, 52.52, -1.39];
        for (i, (got, want)) in k.iter().zip(expected).enumerate() {
            assert!((got - want).abs() < 0.02, "K{}: {got} (want {want})", i + 1);
        }
    }

    #[test]
    fn the_model_gives_the_vendors_example() {
        // 120 mV at 18 degrees C is pH 7 - 120 / 57.7712 = 4.92.
        assert!((model_slope_mv(18.0) - 57.7712).abs() < 1e-4);
        assert!((ELECTRODE_ZERO_PH - 120.0 / model_slope_mv(18.0) - 4.9228).abs() < 1e-3);
    }

    #[test]
    fn coefficients_round_trip_through_the_potentials_they_predict() {
        for k in [[60.61, 52.40, -0.49, 60.61, 52.52, -1.39], [-12.0, 0.0, 3.5, -12.0, 0.0, -4.0], [0.0; 6]] {
            for t in [[5.0, 5.0, 5.0], [25.0, 24.0, 26.0], [40.0, 41.0, 39.5]] {
                let back = compute(&readings_for(k, t)).unwrap();
                // K2 and K5 are the model's offsets; the others round-trip exactly.
                for i in [0, 2, 3, 5] {
                    assert!((back[i] - k[i]).abs() < 0.01, "K{} of {k:?} at {t:?}: {back:?}", i + 1);
                }
            }
        }
    }

    #[test]
    fn bad_readings_are_refused_with_why() {
        let good = readings_for([60.0, 50.0, 0.0, 60.0, 50.0, 0.0], [25.0; 3]);
        assert!(compute(&good).is_ok());
        assert!(matches!(compute(&good[..2]), Err(ComputeError::Buffers { .. })));
        let mut swapped = good.clone();
        swapped.swap(0, 2);
        assert!(matches!(compute(&swapped), Err(ComputeError::Buffers { .. })));
        let mut nan = good.clone();
        nan[1].potential_mv = f32::NAN;
        assert!(matches!(compute(&nan), Err(ComputeError::Reading { .. })));
        let mut hot = good.clone();
        hot[2].temperature_c = 95.0;
        assert!(matches!(compute(&hot), Err(ComputeError::Reading { .. })));
        // The same potential in every buffer: a probe not in the buffers.
        let flat: Vec<BufferReading> = good.iter().map(|r| BufferReading { potential_mv: 10.0, ..*r }).collect();
        let Err(ComputeError::Slope { slope_mv, .. }) = compute(&flat) else { panic!("a flat electrode") };
        assert_eq!(slope_mv, 0.0);
    }
}
