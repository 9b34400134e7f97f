//! [`SensorInfo`]: what generated sensor modules say about their sensor.

use crate::timing::{CharFormat, LineTiming};

/// Static facts about one sensor model, from its spec: generated code
/// declares one `SENSOR` constant of this type per sensor module.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct SensorInfo {
    /// The spec's snake_case name (the Rust module name).
    pub name: &'static str,
    /// Human title.
    pub title: &'static str,
    /// Title of the vendor manual the spec transcribes.
    pub manual: &'static str,
    /// Hardware and firmware revisions the manual covers.
    pub revision: &'static str,
    /// Factory baud rate.
    pub baud: u32,
    /// Factory character format (8N1 for every Yosemitech probe).
    pub format: CharFormat,
    /// Lowest valid slave address.
    pub min_address: u8,
    /// Highest valid slave address.
    pub max_address: u8,
    /// Factory slave address.
    pub default_address: u8,
}

impl SensorInfo {
    /// The timing of a line at the factory serial settings.
    pub const fn line_timing(&self) -> LineTiming {
        LineTiming::new(self.baud, self.format)
    }

    /// True when `address` is a valid slave address for this sensor.
    pub const fn is_valid_address(&self, address: u8) -> bool {
        address >= self.min_address && address <= self.max_address
    }
}
