//! The three-point pH calibration (pH manual, sections 2.2.7 and 2.2.8).
//!
//! For each standard solution in the manual's order (4.00, 6.86, 9.18 at
//! 25 °C): immerse the probe, let it settle for at least a minute, write the
//! standard's pH. Then read the calibration status. Before anything is
//! written, every coefficient is read and handed to the guide, which must
//! keep it (the CLI writes it to a file): whatever happens next, the user can
//! restore it with one command. The probe itself restores its previous
//! coefficients when a calibration fails.

use std::time::Duration;

use super::coefficients::{PhOrpCoefficients, read_ph_orp};
use super::{ProcedureError, Sleep};
use crate::Transport;
use crate::ph_orp::{CalibrationStatus, Device, PH_CALIBRATION_SETTLE_MS, PH_CALIBRATION_STANDARDS};

/// The standards and settling time; [`Default`] is the manual's.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CalibrationConfig {
    /// Standard solutions, in calibration order.
    pub standards: [f32; 3],
    /// Settling time in each solution.
    pub settle: Duration,
}

impl Default for CalibrationConfig {
    fn default() -> Self {
        Self { standards: PH_CALIBRATION_STANDARDS, settle: Duration::from_millis(u64::from(PH_CALIBRATION_SETTLE_MS)) }
    }
}

/// The user's side of a calibration: confirmations and progress.
pub trait CalibrationGuide {
    /// The coefficients as they were before the calibration. Return `false`
    /// to stop (e.g. the backup could not be saved); nothing has been written.
    fn backed_up(&mut self, backup: &PhOrpCoefficients) -> bool;
    /// Ask the user to put the probe in `standard_ph` (point `index` of 3,
    /// from 0). Return `false` to stop.
    fn immerse(&mut self, index: usize, standard_ph: f32) -> bool;
    /// Wait for the probe to settle; the guide may wait with `sleep` (showing
    /// progress) or skip it if the user says the probe has settled.
    fn settle(&mut self, index: usize, duration: Duration, sleep: &mut dyn Sleep);
    /// The point was written.
    fn point_written(&mut self, index: usize, standard_ph: f32);
}

/// How a calibration ended.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CalibrationReport {
    /// The probe's verdict.
    pub status: CalibrationStatus,
    /// The coefficients before the calibration.
    pub backup: PhOrpCoefficients,
    /// The coefficients after it.
    pub after: PhOrpCoefficients,
}

impl CalibrationReport {
    /// True when the probe reports success.
    pub fn succeeded(&self) -> bool {
        self.status == CalibrationStatus::Success
    }
}

/// Why a status code means failure, in the manual's words.
pub fn explain(status: CalibrationStatus) -> &'static str {
    match status {
        CalibrationStatus::Success => "calibration succeeded",
        CalibrationStatus::NotACalibrationStandard => {
            "the reading did not match a calibration standard: check the buffer solution and its order (4.00, 6.86, 9.18)"
        }
        CalibrationStatus::FewerThanThreePoints => "fewer than three points were calibrated: run all three buffers",
        CalibrationStatus::CoefficientsOutOfRange => {
            "the calibration coefficients are out of range: the electrode may be worn or the buffers contaminated"
        }
        CalibrationStatus::Unknown(_) => {
            "the probe reported a status the manual does not define (several failure bits may be set)"
        }
    }
}

/// Runs the three-point calibration. On an error after the backup was
/// taken, the backup is in the guide's hands; the error is returned as is.
pub fn calibrate<T: Transport>(
    probe: &mut Device<'_, T>,
    config: &CalibrationConfig,
    guide: &mut dyn CalibrationGuide,
    sleep: &mut dyn Sleep,
) -> Result<CalibrationReport, ProcedureError> {
    let backup = read_ph_orp(probe)?;
    if !guide.backed_up(&backup) {
        return Err(ProcedureError::Aborted);
    }
    for (index, &standard_ph) in config.standards.iter().enumerate() {
        if !guide.immerse(index, standard_ph) {
            return Err(ProcedureError::Aborted);
        }
        guide.settle(index, config.settle, sleep);
        probe.start_ph_calibration(standard_ph)?;
        guide.point_written(index, standard_ph);
    }
    let status = probe.calibration_status()?.status;
    let after = read_ph_orp(probe)?;
    Ok(CalibrationReport { status, backup, after })
}
