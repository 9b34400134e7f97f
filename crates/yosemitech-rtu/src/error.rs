//! Typed errors for frames that fail to encode or decode.

use core::fmt;

/// A Modbus exception code, as sent in an exception reply.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum ExceptionCode {
    /// 0x01: the function code is not supported.
    IllegalFunction,
    /// 0x02: the register range is not valid on this device.
    IllegalDataAddress,
    /// 0x03: a value in the request is not acceptable.
    IllegalDataValue,
    /// 0x04: the device failed while performing the action.
    ServerDeviceFailure,
    /// 0x05: accepted; processing takes long.
    Acknowledge,
    /// 0x06: the device is busy.
    ServerDeviceBusy,
    /// 0x08: memory parity error.
    MemoryParityError,
    /// 0x0A: gateway path unavailable.
    GatewayPathUnavailable,
    /// 0x0B: the gateway target did not respond.
    GatewayTargetFailedToRespond,
    /// Any other code.
    Unknown(u8),
}

impl ExceptionCode {
    /// The code from its wire byte.
    pub const fn from_u8(code: u8) -> Self {
        match code {
            0x01 => Self::IllegalFunction,
            0x02 => Self::IllegalDataAddress,
            0x03 => Self::IllegalDataValue,
            0x04 => Self::ServerDeviceFailure,
            0x05 => Self::Acknowledge,
            0x06 => Self::ServerDeviceBusy,
            0x08 => Self::MemoryParityError,
            0x0A => Self::GatewayPathUnavailable,
            0x0B => Self::GatewayTargetFailedToRespond,
            other => Self::Unknown(other),
        }
    }

    /// The wire byte.
    pub const fn to_u8(self) -> u8 {
        match self {
            Self::IllegalFunction => 0x01,
            Self::IllegalDataAddress => 0x02,
            Self::IllegalDataValue => 0x03,
            Self::ServerDeviceFailure => 0x04,
            Self::Acknowledge => 0x05,
            Self::ServerDeviceBusy => 0x06,
            Self::MemoryParityError => 0x08,
            Self::GatewayPathUnavailable => 0x0A,
            Self::GatewayTargetFailedToRespond => 0x0B,
            Self::Unknown(other) => other,
        }
    }
}

impl fmt::Display for ExceptionCode {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let text = match self {
            Self::IllegalFunction => "illegal function",
            Self::IllegalDataAddress => "illegal data address",
            Self::IllegalDataValue => "illegal data value",
            Self::ServerDeviceFailure => "server device failure",
            Self::Acknowledge => "acknowledge",
            Self::ServerDeviceBusy => "server device busy",
            Self::MemoryParityError => "memory parity error",
            Self::GatewayPathUnavailable => "gateway path unavailable",
            Self::GatewayTargetFailedToRespond => "gateway target failed to respond",
            Self::Unknown(_) => "unknown exception",
        };
        write!(f, "{text} (0x{:02X})", self.to_u8())
    }
}

/// Which part of a write reply failed to echo the request.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum EchoField {
    /// The start address.
    Address,
    /// The register count.
    Count,
}

/// Why a frame was rejected. Every check runs in release builds.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[non_exhaustive]
pub enum FrameError {
    /// Fewer bytes than the frame needs.
    Truncated {
        /// Bytes the frame needs.
        expected: usize,
        /// Bytes present.
        actual: usize,
    },
    /// More bytes than the frame may have.
    TooLong {
        /// Bytes the frame needs.
        expected: usize,
        /// Bytes present.
        actual: usize,
    },
    /// The CRC does not match the bytes.
    Crc {
        /// The CRC carried by the frame.
        received: u16,
        /// The CRC of the bytes before it.
        computed: u16,
    },
    /// The frame is from (or to) another slave.
    WrongSlave {
        /// The address we expected.
        expected: u8,
        /// The address in the frame.
        actual: u8,
    },
    /// The function code is not the one requested.
    WrongFunction {
        /// The function we expected.
        expected: u8,
        /// The function in the frame.
        actual: u8,
    },
    /// The byte count is neither the register count times two nor a declared exception.
    ByteCount {
        /// The byte count we expected.
        expected: u8,
        /// The byte count in the frame.
        actual: u8,
    },
    /// A write reply or request header does not match the command.
    EchoMismatch {
        /// Which field differs.
        field: EchoField,
        /// The value we expected.
        expected: u16,
        /// The value in the frame.
        actual: u16,
    },
    /// The device answered with a Modbus exception.
    Exception {
        /// The function code of the request (without the 0x80 bit).
        function: u8,
        /// The exception code.
        code: ExceptionCode,
    },
}

impl fmt::Display for FrameError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            Self::Truncated { expected, actual } => {
                write!(f, "truncated frame: {actual} bytes, expected {expected}")
            }
            Self::TooLong { expected, actual } => {
                write!(f, "frame too long: {actual} bytes, expected {expected}")
            }
            Self::Crc { received, computed } => write!(
                f,
                "CRC mismatch: frame carries {:02X} {:02X}, bytes give {:02X} {:02X}",
                received & 0xFF,
                received >> 8,
                computed & 0xFF,
                computed >> 8
            ),
            Self::WrongSlave { expected, actual } => {
                write!(f, "reply from slave {actual}, expected slave {expected}")
            }
            Self::WrongFunction { expected, actual } => {
                write!(f, "function 0x{actual:02X}, expected 0x{expected:02X}")
            }
            Self::ByteCount { expected, actual } => {
                write!(f, "byte count 0x{actual:02X}, expected 0x{expected:02X}")
            }
            Self::EchoMismatch { field, expected, actual } => {
                let name = match field {
                    EchoField::Address => "start address",
                    EchoField::Count => "register count",
                };
                write!(f, "write reply echoes {name} 0x{actual:04X}, expected 0x{expected:04X}")
            }
            Self::Exception { function, code } => {
                write!(f, "Modbus exception for function 0x{function:02X}: {code}")
            }
        }
    }
}

#[cfg(feature = "std")]
impl std::error::Error for FrameError {}

/// Why a request or response could not be encoded.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[non_exhaustive]
pub enum EncodeError {
    /// The output buffer is smaller than the frame.
    BufferTooSmall {
        /// Bytes the frame needs.
        needed: usize,
    },
    /// The register data given is not the length the layout requires
    /// (`2 * count` bytes for a write request or a read reply, none otherwise).
    DataLength {
        /// Bytes the layout requires.
        expected: usize,
        /// Bytes given.
        actual: usize,
    },
    /// The frame would exceed the largest RTU frame (256 bytes,
    /// [`MAX_ADU`](crate::frame::MAX_ADU)): a register count beyond what
    /// Modbus allows.
    FrameTooLong {
        /// Bytes the frame would take.
        len: usize,
    },
    /// The slave address cannot be used with this command.
    InvalidSlave {
        /// The address given.
        slave: u8,
    },
    /// A field value is outside the range the spec allows.
    OutOfRange {
        /// The field's name in the spec.
        field: &'static str,
    },
    /// A text field is too long or not ASCII.
    InvalidText {
        /// The field's name in the spec.
        field: &'static str,
    },
}

impl fmt::Display for EncodeError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            Self::BufferTooSmall { needed } => write!(f, "output buffer too small: {needed} bytes needed"),
            Self::DataLength { expected, actual } => {
                write!(f, "register data of {actual} bytes, the layout requires {expected}")
            }
            Self::FrameTooLong { len } => write!(f, "a frame of {len} bytes exceeds the RTU maximum of 256"),
            Self::InvalidSlave { slave } => write!(f, "slave address {slave} is not valid for this command"),
            Self::OutOfRange { field } => write!(f, "value of `{field}` is out of range"),
            Self::InvalidText { field } => write!(f, "text of `{field}` is too long or not ASCII"),
        }
    }
}

#[cfg(feature = "std")]
impl std::error::Error for EncodeError {}
