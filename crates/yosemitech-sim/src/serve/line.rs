//! What a client whose serial settings differ from the device's hears.
//!
//! On a pseudo-terminal no bits cross a wire, but the master side can read
//! the settings the client set on the slave side (`tcgetattr` on a pty
//! master reports its slave's termios on Linux and the BSDs). A device
//! served with [`ServeConfig::settings`](super::ServeConfig::settings)
//! compares them with its own before each request: a UART at another baud
//! rate, data-bit count or parity turns every character into something
//! else, so the device cannot read the request and the client reads
//! garbage. Stop bits are not compared: a receiver set to 1 stop bit also
//! accepts characters sent with 2, and one set to 2 checks only the first.

use yosemitech_rtu::{CharFormat, DataBits, LineSettings, Parity, StopBits};

use crate::fault::Rng;

/// True when a client at `client` and a device at `device` understand each other.
pub(crate) fn compatible(client: LineSettings, device: LineSettings) -> bool {
    client.baud == device.baud
        && client.format.data_bits == device.format.data_bits
        && client.format.parity == device.format.parity
}

/// What the client's UART makes of the device's answer to a request of
/// `request_len` bytes it could not read: garbage, about as many
/// characters as the client's rate fits into that time (fewer when the
/// device is faster), never none.
pub(crate) fn garbage(rng: &mut Rng, request_len: usize, client: LineSettings, device: LineSettings) -> Vec<u8> {
    let scaled = request_len as u64 * u64::from(client.baud) / u64::from(device.baud.max(1));
    let len = scaled.clamp(1, 64) as usize;
    (0..len).map(|_| rng.byte()).collect()
}

/// The settings a serial port is set to, when it can tell them all.
#[cfg(all(unix, feature = "pty"))]
pub(crate) fn settings_of(port: &dyn serialport::SerialPort) -> Option<LineSettings> {
    let data_bits = match port.data_bits().ok()? {
        serialport::DataBits::Seven => DataBits::Seven,
        serialport::DataBits::Eight => DataBits::Eight,
        _ => return None,
    };
    let parity = match port.parity().ok()? {
        serialport::Parity::None => Parity::None,
        serialport::Parity::Even => Parity::Even,
        serialport::Parity::Odd => Parity::Odd,
    };
    let stop_bits = match port.stop_bits().ok()? {
        serialport::StopBits::One => StopBits::One,
        serialport::StopBits::Two => StopBits::Two,
    };
    Some(LineSettings { baud: port.baud_rate().ok()?, format: CharFormat { data_bits, parity, stop_bits } })
}

/// True when the parity set on a pty's `slave` side reads back on its
/// `master` side; the slave is left without parity.
#[cfg(all(unix, feature = "pty"))]
pub(crate) fn keeps_parity(slave: &mut serialport::TTYPort, master: &serialport::TTYPort) -> bool {
    use serialport::SerialPort;
    let kept = slave.set_parity(serialport::Parity::Even).is_ok()
        && master.parity().is_ok_and(|p| p == serialport::Parity::Even);
    let _ = slave.set_parity(serialport::Parity::None);
    kept
}

#[cfg(test)]
mod tests {
    use super::*;

    fn line(baud: u32, parity: Parity, stop_bits: StopBits) -> LineSettings {
        LineSettings { baud, format: CharFormat { parity, stop_bits, ..CharFormat::EIGHT_N_1 } }
    }

    #[test]
    fn stop_bits_alone_do_not_garble() {
        let probe = line(9600, Parity::None, StopBits::One);
        assert!(compatible(line(9600, Parity::None, StopBits::Two), probe));
        assert!(!compatible(line(19_200, Parity::None, StopBits::One), probe));
        assert!(!compatible(line(9600, Parity::Even, StopBits::One), probe));
    }

    #[test]
    fn garbage_is_deterministic_and_scaled_by_the_rates() {
        let (slow, fast) = (line(9600, Parity::None, StopBits::One), line(19_200, Parity::None, StopBits::One));
        let a = garbage(&mut Rng::new(5), 8, slow, fast);
        assert_eq!(a, garbage(&mut Rng::new(5), 8, slow, fast));
        assert_eq!(a.len(), 4);
        assert_eq!(garbage(&mut Rng::new(5), 8, fast, slow).len(), 16);
        assert_eq!(garbage(&mut Rng::new(5), 1, line(2400, Parity::None, StopBits::One), fast).len(), 1);
    }
}
