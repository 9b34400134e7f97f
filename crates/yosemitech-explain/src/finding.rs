//! What an explanation found unusual or wrong, as values a front end can
//! match on; [`Display`](fmt::Display) words each one (the `decode`
//! command prints and writes the words).

use std::fmt;

/// One observation about a frame or an exchange: an explanation lists each
/// as a note (unusual, accepted) or a problem (wrong).
#[derive(Debug, Clone, PartialEq, Eq)]
#[non_exhaustive]
pub enum Finding {
    /// A request to address 0, which no probe answers.
    Broadcast,
    /// A command that is sent to and answered from its own address (the
    /// wildcard of erratum E3).
    WildcardAddress {
        /// The command, by name.
        command: String,
        /// Its fixed address.
        address: u8,
    },
    /// The same, named for an exchange: request and reply both use it.
    FixedAddressExchange {
        /// The command, by name.
        command: String,
        /// Its fixed address.
        address: u8,
    },
    /// A fixed-address command sent to another address.
    NotItsFixedAddress {
        /// The command, by name.
        command: String,
        /// Its fixed address.
        address: u8,
        /// The slave address the frame names.
        slave: u8,
    },
    /// A slave address outside 1..=247.
    AddressOutOfRange {
        /// The slave address the frame names.
        slave: u8,
    },
    /// A trigger's reply with a byte count and no value.
    TriggerByteCount {
        /// The byte count the frame carries.
        byte_count: u8,
    },
    /// A byte count the spec documents as a firmware quirk.
    QuirkByteCount {
        /// The byte count the frame carries.
        byte_count: u8,
        /// The data bytes the command has.
        data_bytes: usize,
    },
    /// A byte count the command does not allow.
    ByteCount {
        /// The byte count the frame carries.
        byte_count: u8,
        /// What the command has.
        expected: usize,
    },
    /// A request whose length is not its command's.
    RequestLength {
        /// The command, by name.
        command: String,
        /// The frame's length in bytes.
        len: usize,
        /// What the command has.
        expected: usize,
    },
    /// An exception reply that is not 5 bytes.
    ExceptionLength {
        /// The frame's length in bytes.
        len: usize,
    },
    /// A function code no probe serves.
    UnknownFunction {
        /// The function code.
        function: u8,
    },
    /// No loaded command frames this kind of frame.
    NoCommandFits {
        /// The kind of frame.
        kind: &'static str,
    },
    /// A request no loaded sensor has a command for (`what`: the request, described).
    NoCommandFor {
        /// The request, described.
        what: String,
    },
    /// A request whose commands the `--sensor`/`--command` filters leave out.
    LeftOut {
        /// The request, described.
        what: String,
        /// The commands it fits.
        commands: String,
    },
    /// A request nothing answered.
    NoReply {
        /// The slave address the frame names.
        slave: u8,
    },
    /// A reply with no request before it in the capture.
    NoRequest {
        /// The slave address the frame names.
        slave: u8,
    },
    /// A reply shorter than its command's.
    ReplyCutShort {
        /// The frame's length in bytes.
        len: usize,
        /// What the command has.
        expected: usize,
    },
    /// A reply whose CRC is not its bytes' (both as hex).
    ReplyCrc {
        /// The CRC the reply carries.
        carried: String,
        /// The CRC of its bytes.
        computed: String,
    },
    /// A candidate command the reply does not decode as, and why.
    NotDecodedAs {
        /// The command, by name.
        command: String,
        /// The sensor of the command.
        sensor: String,
        /// Why it does not decode.
        reason: String,
    },
}

impl fmt::Display for Finding {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Broadcast => f.write_str("address 0: a broadcast, never answered"),
            Self::WildcardAddress { command, address } => {
                write!(f, "{command} uses the wildcard address 0x{address:02X} (erratum E3)")
            }
            Self::FixedAddressExchange { command, address } => {
                write!(f, "{command} is sent to and answered from the address 0x{address:02X}")
            }
            Self::NotItsFixedAddress { command, address, slave } => {
                write!(f, "{command} is sent to and answered from address 0x{address:02X}, not {slave}")
            }
            Self::AddressOutOfRange { slave } => write!(f, "address {slave} is outside 1 to 247"),
            Self::TriggerByteCount { byte_count } => {
                write!(f, "byte count 0x{byte_count:02X}: a trigger's reply carries no value, accepted")
            }
            Self::QuirkByteCount { byte_count, data_bytes } => write!(
                f,
                "byte count 0x{byte_count:02X} over {data_bytes} data bytes: a firmware quirk the spec documents, accepted"
            ),
            Self::ByteCount { byte_count, expected } => {
                write!(f, "byte count 0x{byte_count:02X}, expected 0x{expected:02X}")
            }
            Self::RequestLength { command, len, expected } => {
                write!(f, "{len} bytes, a {command} request has {expected}")
            }
            Self::ExceptionLength { len } => write!(f, "an exception reply has 5 bytes, this one {len}"),
            Self::UnknownFunction { function } => {
                write!(f, "function 0x{function:02X} is not one the probes use (0x03 read, 0x10 write)")
            }
            Self::NoCommandFits { kind } => write!(f, "no command of the loaded sensors fits this {kind}"),
            Self::NoCommandFor { what } => write!(f, "no loaded sensor has a command for {what}"),
            Self::LeftOut { what, commands } => write!(f, "{what} is {commands}, which --sensor/--command leave out"),
            Self::NoReply { slave } => write!(f, "no reply from address {slave} follows the request"),
            Self::NoRequest { slave } => {
                write!(f, "no request to address {slave} before this reply (lost, or sent before the capture began)")
            }
            Self::ReplyCutShort { len, expected } => write!(f, "the reply is cut short: {len} of {expected} bytes"),
            Self::ReplyCrc { carried, computed } => {
                write!(f, "the reply's CRC is wrong: it carries {carried}, its bytes give {computed}")
            }
            Self::NotDecodedAs { command, sensor, reason } => write!(f, "not {command} of {sensor}: {reason}"),
        }
    }
}
