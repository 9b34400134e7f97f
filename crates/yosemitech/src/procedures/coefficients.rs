//! Every calibration coefficient of a probe, read as one backup and
//! restored with read-back, so no calibration is ever lost.

use super::{ProcedureError, same_bits};
use crate::Transport;
use crate::{conductivity, ph_orp};

/// The coefficients of a pH/ORP probe.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PhOrpCoefficients {
    /// Electrode coefficients K1..K6 (register 0x2900).
    pub electrode: [f32; 6],
    /// pH customer calibration K, B (register 0x1100).
    pub ph_calibration: [f32; 2],
    /// ORP calibration K, B (register 0x3400).
    pub orp_calibration: [f32; 2],
}

impl PhOrpCoefficients {
    /// Every value in a fixed order: K1..K6, pH K, pH B, ORP K, ORP B.
    pub fn to_array(&self) -> [f32; 10] {
        let [k1, k2, k3, k4, k5, k6] = self.electrode;
        let [pk, pb] = self.ph_calibration;
        let [ok, ob] = self.orp_calibration;
        [k1, k2, k3, k4, k5, k6, pk, pb, ok, ob]
    }

    /// The inverse of [`Self::to_array`].
    pub fn from_array(v: [f32; 10]) -> Self {
        let [k1, k2, k3, k4, k5, k6, pk, pb, ok, ob] = v;
        Self { electrode: [k1, k2, k3, k4, k5, k6], ph_calibration: [pk, pb], orp_calibration: [ok, ob] }
    }
}

/// Reads every coefficient of a pH/ORP probe.
pub fn read_ph_orp<T: Transport>(probe: &mut ph_orp::Device<'_, T>) -> Result<PhOrpCoefficients, ProcedureError> {
    let e = probe.ph_electrode_coefficients()?;
    let p = probe.ph_calibration()?;
    let o = probe.orp_calibration()?;
    Ok(PhOrpCoefficients {
        electrode: [e.k1, e.k2, e.k3, e.k4, e.k5, e.k6],
        ph_calibration: [p.k_slope, p.b_offset],
        orp_calibration: [o.k_slope, o.b_offset],
    })
}

/// Writes every coefficient of a pH/ORP probe and reads them back.
pub fn write_ph_orp<T: Transport>(
    probe: &mut ph_orp::Device<'_, T>,
    c: &PhOrpCoefficients,
) -> Result<(), ProcedureError> {
    if !c.to_array().iter().all(|v| v.is_finite()) {
        return Err(ProcedureError::NotFinite { what: "pH/ORP coefficients" });
    }
    let [k1, k2, k3, k4, k5, k6] = c.electrode;
    probe.set_ph_electrode_coefficients(ph_orp::SetPhElectrodeCoefficients { k1, k2, k3, k4, k5, k6 })?;
    let [k_slope, b_offset] = c.ph_calibration;
    probe.set_ph_calibration(ph_orp::SetPhCalibration { k_slope, b_offset })?;
    let [k_slope, b_offset] = c.orp_calibration;
    probe.set_orp_calibration(ph_orp::SetOrpCalibration { k_slope, b_offset })?;
    let back = read_ph_orp(probe)?;
    if !same_bits(&back.to_array(), &c.to_array()) {
        return Err(ProcedureError::ReadBackMismatch { what: "pH/ORP coefficients" });
    }
    Ok(())
}

/// The coefficients of a conductivity probe.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ConductivityCoefficients {
    /// User calibration K, B (register 0x1100): Cond_final = K·Cond + B.
    pub user_calibration: [f32; 2],
}

/// Reads every coefficient of a conductivity probe.
pub fn read_conductivity<T: Transport>(
    probe: &mut conductivity::Device<'_, T>,
) -> Result<ConductivityCoefficients, ProcedureError> {
    let u = probe.user_calibration()?;
    Ok(ConductivityCoefficients { user_calibration: [u.k_slope, u.b_offset] })
}

/// Writes every coefficient of a conductivity probe and reads them back.
pub fn write_conductivity<T: Transport>(
    probe: &mut conductivity::Device<'_, T>,
    c: &ConductivityCoefficients,
) -> Result<(), ProcedureError> {
    if !c.user_calibration.iter().all(|v| v.is_finite()) {
        return Err(ProcedureError::NotFinite { what: "conductivity coefficients" });
    }
    let [k_slope, b_offset] = c.user_calibration;
    probe.set_user_calibration(conductivity::SetUserCalibration { k_slope, b_offset })?;
    let back = read_conductivity(probe)?;
    if !same_bits(&back.user_calibration, &c.user_calibration) {
        return Err(ProcedureError::ReadBackMismatch { what: "conductivity user calibration" });
    }
    Ok(())
}
