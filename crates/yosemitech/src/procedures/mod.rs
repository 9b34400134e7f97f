//! The manuals' procedures as library functions.
//!
//! - [`conductivity`]: start, warm up, average the recommended number of
//!   readings at the manual's interval, discard range-switch errors, TDS.
//! - [`ph`]: the three-point pH calibration in the manual's order, with the
//!   coefficients backed up before anything is written.
//! - [`ph_electrode`]: the electrode coefficients K1..K6 computed on the
//!   master from the potentials read in the buffers, by the vendor's model.
//! - [`linear`]: the statistics of the readings in each standard and the
//!   K/B line through them (a probe's user calibration).
//! - [`backup`]: every calibration coefficient of any sensor, read as one
//!   backup and restored with read-back, from the spec's coefficient blocks.
//! - [`coefficients`]: the pH and conductivity probes' coefficients as
//!   typed values, read and restored with read-back.
//! - [`address`]: changing a probe's slave address, verified at the new one.
//!
//! Every number (warm-up, interval, count, TDS factor, standards, settling
//! time) comes from the spec's constants. Waits go through [`Sleep`], so
//! tests and demos run them instantly.

use std::fmt;
use std::time::Duration;

pub mod backup;
pub mod coefficients;
pub mod conductivity;
pub mod linear;
pub mod ph;
pub mod ph_electrode;

/// Changing a probe's slave address, verified at the new one (it lives in
/// the runtime so that every generated `Device` can call it).
pub use yosemitech_rtu::address;

/// Waits between the steps of a procedure.
pub trait Sleep {
    /// Waits for `duration` (or pretends to).
    fn sleep(&mut self, duration: Duration);
}

/// Really waits ([`std::thread::sleep`]).
#[derive(Debug, Default, Clone, Copy)]
pub struct RealSleep;

impl Sleep for RealSleep {
    fn sleep(&mut self, duration: Duration) {
        std::thread::sleep(duration);
    }
}

/// Does not wait; adds up how long it was asked to (for tests and demos).
#[derive(Debug, Default, Clone, Copy, PartialEq, Eq)]
pub struct NoSleep {
    /// The total of every requested wait.
    pub requested: Duration,
}

impl Sleep for NoSleep {
    fn sleep(&mut self, duration: Duration) {
        self.requested += duration;
    }
}

/// Waits a fixed fraction of every requested wait (a shortened demo).
#[derive(Debug, Clone, Copy)]
pub struct ScaledSleep {
    /// Multiplier applied to each wait (0.0..=1.0 shortens).
    pub factor: f64,
}

impl Sleep for ScaledSleep {
    fn sleep(&mut self, duration: Duration) {
        std::thread::sleep(duration.mul_f64(self.factor.clamp(0.0, 1.0)));
    }
}

/// Why a procedure stopped.
#[derive(Debug)]
#[non_exhaustive]
pub enum ProcedureError {
    /// A request failed.
    Device(crate::Error),
    /// The user (or the caller's guide) stopped the procedure.
    Aborted,
    /// Too many readings were flagged or invalid to form an average.
    NotEnoughReadings {
        /// Readings accepted.
        accepted: usize,
        /// Readings needed.
        needed: usize,
        /// Readings discarded (range-switch error or not finite).
        discarded: usize,
    },
    /// A coefficient to write is NaN or infinite; nothing was written.
    NotFinite {
        /// Which block.
        what: &'static str,
    },
    /// Values written did not read back identically.
    ReadBackMismatch {
        /// Which block.
        what: &'static str,
    },
    /// A coefficient backup does not fit the probe it was to restore;
    /// nothing was written.
    BackupDoesNotFit {
        /// The sensor restored to.
        sensor: &'static str,
        /// The block at fault, when one is.
        block: Option<String>,
        /// What is wrong.
        reason: &'static str,
    },
    /// A restore failed after it began writing: the probe may hold part of
    /// the backup. `replaced` is every coefficient it held before.
    RestoreInterrupted {
        /// The probe's coefficients before the restore.
        replaced: Box<backup::CoefficientBackup>,
        /// Why it stopped.
        cause: Box<ProcedureError>,
    },
}

impl fmt::Display for ProcedureError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Device(e) => write!(f, "{e}"),
            Self::Aborted => f.write_str("stopped before completion"),
            Self::NotEnoughReadings { accepted, needed, discarded } => write!(
                f,
                "only {accepted} of {needed} readings were valid ({discarded} discarded for range-switch errors)"
            ),
            Self::NotFinite { what } => write!(f, "{what} contain a NaN or infinite value; nothing was written"),
            Self::ReadBackMismatch { what } => write!(f, "{what} did not read back as written"),
            Self::BackupDoesNotFit { sensor, block: Some(block), reason } => {
                write!(f, "the backup's `{block}` does not fit this {sensor} probe: {reason}; nothing was written")
            }
            Self::BackupDoesNotFit { sensor, block: None, reason } => {
                write!(f, "the backup does not fit this {sensor} probe: {reason}; nothing was written")
            }
            Self::RestoreInterrupted { replaced, cause } => write!(
                f,
                "the restore stopped after it began writing ({cause}); the coefficients it replaced were: {replaced}"
            ),
        }
    }
}

impl std::error::Error for ProcedureError {}

impl From<crate::Error> for ProcedureError {
    fn from(e: crate::Error) -> Self {
        Self::Device(e)
    }
}

/// Bit-exact equality of two float slices.
pub fn same_bits(a: &[f32], b: &[f32]) -> bool {
    a.len() == b.len() && a.iter().zip(b).all(|(x, y)| x.to_bits() == y.to_bits())
}
