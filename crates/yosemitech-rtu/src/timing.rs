//! Serial character format and Modbus RTU line timing (character time, t1.5, t3.5).
//!
//! A character on the line is one start bit, the data bits, an optional parity
//! bit and one or two stop bits. Modbus over serial line (V1.02, 2.5.1.1) ends
//! a frame with at least 3.5 character times of silence (t3.5) and forbids gaps
//! longer than 1.5 character times (t1.5) inside one; above 19200 baud both are
//! fixed, at 1750 µs and 750 µs.

use core::fmt;
use core::time::Duration;

/// Data bits per character.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub enum DataBits {
    /// Seven data bits (Modbus ASCII; not RTU).
    Seven,
    /// Eight data bits, as Modbus RTU requires.
    #[default]
    Eight,
}

impl DataBits {
    /// The number of bits: 7 or 8.
    pub const fn bits(self) -> u32 {
        match self {
            Self::Seven => 7,
            Self::Eight => 8,
        }
    }

    /// The setting for `bits` data bits; `None` for anything but 7 and 8.
    pub const fn from_bits(bits: u32) -> Option<Self> {
        match bits {
            7 => Some(Self::Seven),
            8 => Some(Self::Eight),
            _ => None,
        }
    }
}

/// The parity bit of a character.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub enum Parity {
    /// No parity bit (Yosemitech probes: 8N1).
    #[default]
    None,
    /// Even parity (the Modbus default).
    Even,
    /// Odd parity.
    Odd,
}

impl Parity {
    /// Parity bits per character: 0 or 1.
    pub const fn bits(self) -> u32 {
        match self {
            Self::None => 0,
            Self::Even | Self::Odd => 1,
        }
    }

    /// The name the spec language and JSON output use: `none`, `even` or `odd`.
    pub const fn name(self) -> &'static str {
        match self {
            Self::None => "none",
            Self::Even => "even",
            Self::Odd => "odd",
        }
    }

    /// The letter of the `8N1` notation: `N`, `E` or `O`.
    pub const fn letter(self) -> char {
        match self {
            Self::None => 'N',
            Self::Even => 'E',
            Self::Odd => 'O',
        }
    }
}

/// Stop bits per character.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub enum StopBits {
    /// One stop bit.
    #[default]
    One,
    /// Two stop bits.
    Two,
}

impl StopBits {
    /// The number of bits: 1 or 2.
    pub const fn bits(self) -> u32 {
        match self {
            Self::One => 1,
            Self::Two => 2,
        }
    }

    /// The setting for `bits` stop bits; `None` for anything but 1 and 2.
    pub const fn from_bits(bits: u32) -> Option<Self> {
        match bits {
            1 => Some(Self::One),
            2 => Some(Self::Two),
            _ => None,
        }
    }
}

/// The format of one character on the line. The default is 8N1, the setting
/// of every Yosemitech probe (datasheet notes, section 6 item 10).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub struct CharFormat {
    /// Data bits after the start bit: 7 or 8.
    pub data_bits: DataBits,
    /// Whether a parity bit follows the data bits, and which.
    pub parity: Parity,
    /// Stop bits ending the character: 1 or 2.
    pub stop_bits: StopBits,
}

impl CharFormat {
    /// Eight data bits, no parity, one stop bit: 10 bits per character.
    pub const EIGHT_N_1: Self = Self { data_bits: DataBits::Eight, parity: Parity::None, stop_bits: StopBits::One };

    /// Bits per character: one start bit, the data bits, the parity bit and the stop bits.
    pub const fn bits(&self) -> u32 {
        1 + self.data_bits.bits() + self.parity.bits() + self.stop_bits.bits()
    }
}

/// The one `8N1` renderer: data bits, parity letter, stop bits.
impl fmt::Display for CharFormat {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}{}{}", self.data_bits.bits(), self.parity.letter(), self.stop_bits.bits())
    }
}

/// The settings of a serial line: baud rate and character format, as a
/// sensor's spec states them and a port is opened with. The default is
/// 9600 baud 8N1, the factory setting of Yosemitech probes.
///
/// ```
/// use yosemitech_rtu::{CharFormat, LineSettings, Parity};
/// let line = LineSettings { baud: 19_200, format: CharFormat { parity: Parity::Even, ..CharFormat::EIGHT_N_1 } };
/// assert_eq!(line.to_string(), "19200 baud, 8E1");
/// assert_eq!(LineSettings::default().to_string(), "9600 baud, 8N1");
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct LineSettings {
    /// Bits per second (the spec validates 300..=1000000).
    pub baud: u32,
    /// The format of each character.
    pub format: CharFormat,
}

impl LineSettings {
    /// 9600 baud 8N1.
    pub const NINE_SIX_HUNDRED_8N1: Self = Self { baud: 9600, format: CharFormat::EIGHT_N_1 };

    /// The timing of a line with these settings.
    pub const fn timing(&self) -> LineTiming {
        LineTiming::new(self.baud, self.format)
    }
}

impl Default for LineSettings {
    /// 9600 baud 8N1, the factory setting of Yosemitech probes.
    fn default() -> Self {
        Self::NINE_SIX_HUNDRED_8N1
    }
}

/// `9600 baud, 8N1`: the one renderer of a line's settings.
impl fmt::Display for LineSettings {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{} baud, {}", self.baud, self.format)
    }
}

/// Baud rates above this use the fixed t1.5 and t3.5 of the Modbus spec.
pub const FIXED_TIMING_ABOVE_BAUD: u32 = 19_200;

/// t1.5 above [`FIXED_TIMING_ABOVE_BAUD`].
pub const FIXED_T1_5: Duration = Duration::from_micros(750);

/// t3.5 above [`FIXED_TIMING_ABOVE_BAUD`].
pub const FIXED_T3_5: Duration = Duration::from_micros(1750);

/// The timing of a serial line: how long characters and silences last.
///
/// ```
/// use yosemitech_rtu::{CharFormat, LineTiming};
/// let line = LineTiming::new(9600, CharFormat::EIGHT_N_1);
/// assert_eq!(line.char_time().as_nanos(), 1_041_666);
/// assert_eq!(line.t3_5().as_micros(), 3_645);
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct LineTiming {
    baud: u32,
    bits_per_char: u32,
}

impl LineTiming {
    /// The timing of a line at `baud` with characters of `format`. A baud
    /// rate of zero is taken as one (it would otherwise divide by zero).
    pub const fn new(baud: u32, format: CharFormat) -> Self {
        Self { baud: if baud == 0 { 1 } else { baud }, bits_per_char: format.bits() }
    }

    /// Bits per second.
    pub const fn baud(&self) -> u32 {
        self.baud
    }

    /// Bits per character, start and stop bits included.
    pub const fn bits_per_char(&self) -> u32 {
        self.bits_per_char
    }

    /// The time one character takes on the line.
    pub const fn char_time(&self) -> Duration {
        self.tenths_of_chars(10)
    }

    /// The time `bytes` characters take on the line, back to back.
    pub const fn frame_time(&self, bytes: usize) -> Duration {
        self.tenths_of_chars((bytes as u64).saturating_mul(10))
    }

    /// The longest silence allowed inside a frame: 1.5 character times, or
    /// 750 µs above 19200 baud.
    pub const fn t1_5(&self) -> Duration {
        if self.baud > FIXED_TIMING_ABOVE_BAUD { FIXED_T1_5 } else { self.tenths_of_chars(15) }
    }

    /// The silence that separates frames: 3.5 character times, or 1750 µs
    /// above 19200 baud.
    pub const fn t3_5(&self) -> Duration {
        if self.baud > FIXED_TIMING_ABOVE_BAUD { FIXED_T3_5 } else { self.tenths_of_chars(35) }
    }

    /// [`LineTiming::frame_time`] in whole microseconds, rounded up (what a
    /// deadline adds to an `Instant`), without the 64-bit division a 32-bit
    /// MCU calls a library routine for. Exact for frames of at most
    /// [`MAX_ADU`](crate::frame::MAX_ADU) bytes; saturates past 4,294 s.
    pub(crate) fn frame_micros_ceil(&self, bytes: usize) -> u64 {
        self.tenths_of_chars_micros_ceil(u32::try_from(bytes).unwrap_or(u32::MAX).saturating_mul(10))
    }

    /// [`LineTiming::t3_5`] in whole microseconds, rounded up.
    pub(crate) fn t3_5_micros_ceil(&self) -> u64 {
        if self.baud > FIXED_TIMING_ABOVE_BAUD { 1750 } else { self.tenths_of_chars_micros_ceil(35) }
    }

    /// [`LineTiming::tenths_of_chars`] rounded up to the microsecond. With
    /// `bits × tenths × 10⁵ = q × baud + r`, the nanoseconds are
    /// `1000 q + ⌊1000 r / baud⌋`: `q` microseconds, and one more when the
    /// rest is a whole nanosecond or more (`1000 r >= baud`). Every division
    /// is 32-bit.
    fn tenths_of_chars_micros_ceil(&self, tenths: u32) -> u64 {
        let scaled = self.bits_per_char.saturating_mul(tenths).saturating_mul(100_000);
        let (whole, rest) = (scaled / self.baud, scaled % self.baud);
        u64::from(whole) + u64::from(u64::from(rest) * 1000 >= u64::from(self.baud))
    }

    /// `tenths / 10` character times, rounded down to the nanosecond.
    const fn tenths_of_chars(&self, tenths: u64) -> Duration {
        // bits * tenths * 1e8 fits in u64 for any realistic frame; saturate otherwise.
        let numerator = (self.bits_per_char as u64).saturating_mul(tenths).saturating_mul(100_000_000);
        // `baud` is never zero (see `new`).
        Duration::from_nanos(numerator / self.baud as u64)
    }
}

impl Default for LineTiming {
    /// 9600 baud 8N1, the setting of Yosemitech probes.
    fn default() -> Self {
        Self::new(9600, CharFormat::EIGHT_N_1)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ms(d: Duration) -> f64 {
        d.as_secs_f64() * 1e3
    }

    #[test]
    fn timing_at_9600_8n1() {
        let line = LineTiming::new(9600, CharFormat::EIGHT_N_1);
        assert_eq!(line.bits_per_char(), 10);
        assert!((ms(line.char_time()) - 1.0417).abs() < 1e-4, "{:?}", line.char_time());
        assert!((ms(line.t3_5()) - 3.646).abs() < 1e-3, "{:?}", line.t3_5());
        assert!((ms(line.t1_5()) - 1.5625).abs() < 1e-4, "{:?}", line.t1_5());
        // get_ph: 8-byte request, 9-byte reply.
        assert!((ms(line.frame_time(17)) - 17.708).abs() < 1e-3);
        assert_eq!(line, LineTiming::default());
    }

    #[test]
    fn eleven_bit_characters() {
        // Datasheet notes 6.10: 11-bit characters give t3.5 of 4.01 ms.
        let format = CharFormat { parity: Parity::Even, ..CharFormat::EIGHT_N_1 };
        assert_eq!(format.bits(), 11);
        assert_eq!(format.to_string(), "8E1");
        let line = LineTiming::new(9600, format);
        assert!((ms(line.t3_5()) - 4.0104).abs() < 1e-4, "{:?}", line.t3_5());
        let two_stop = CharFormat { stop_bits: StopBits::Two, ..CharFormat::EIGHT_N_1 };
        assert_eq!(two_stop.bits(), 11);
        assert_eq!(CharFormat { data_bits: DataBits::Seven, ..CharFormat::EIGHT_N_1 }.bits(), 9);
    }

    #[test]
    fn fixed_above_19200() {
        let at = LineTiming::new(19_200, CharFormat::EIGHT_N_1);
        assert!((ms(at.t3_5()) - 1.8229).abs() < 1e-4, "computed at exactly 19200: {:?}", at.t3_5());
        assert!((ms(at.t1_5()) - 0.78125).abs() < 1e-5);
        for baud in [38_400, 57_600, 115_200] {
            let line = LineTiming::new(baud, CharFormat::EIGHT_N_1);
            assert_eq!(line.t3_5(), Duration::from_micros(1750));
            assert_eq!(line.t1_5(), Duration::from_micros(750));
        }
        assert_eq!(LineTiming::new(115_200, CharFormat::EIGHT_N_1).char_time().as_nanos(), 86_805);
    }

    #[test]
    fn microseconds_of_frames_are_their_durations_rounded_up() {
        let formats = [
            CharFormat::EIGHT_N_1,
            CharFormat { parity: Parity::Even, stop_bits: StopBits::Two, ..CharFormat::EIGHT_N_1 },
        ];
        let bauds =
            [1, 3, 7, 300, 1200, 2400, 4800, 9600, 14_400, 19_200, 38_400, 57_600, 115_200, 1_000_000, 7_777_777];
        for format in formats {
            for baud in bauds {
                let line = LineTiming::new(baud, format);
                let ceil = |d: Duration| crate::client::micros_ceil(d);
                assert_eq!(line.t3_5_micros_ceil(), ceil(line.t3_5()), "{baud} {format}");
                for bytes in 0..=crate::frame::MAX_ADU {
                    assert_eq!(line.frame_micros_ceil(bytes), ceil(line.frame_time(bytes)), "{baud} {format} {bytes}");
                }
            }
        }
    }

    #[test]
    fn degenerate_inputs_do_not_panic() {
        let zero = LineTiming::new(0, CharFormat::EIGHT_N_1);
        assert_eq!(zero.baud(), 1);
        assert_eq!(zero.char_time(), Duration::from_secs(10));
        let _ = zero.frame_time(usize::MAX);
    }
}
