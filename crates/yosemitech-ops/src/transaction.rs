//! One request of a spec command: encoded by the spec's interpreter, sent
//! with the client's timing, framing, checks and retries
//! ([`Client::call_raw`]), its reply checked against the command's layout
//! and decoded. The one way every front end talks to a probe of a spec
//! loaded at run time (the typed `yosemitech` crate is the other, for the
//! built-in sensors).

use std::collections::BTreeMap;

use yosemitech_rtu::{Client, Error as RtuError, Transport};
use yosemitech_spec::interp::decode_fields;
use yosemitech_spec::{CommandSpec, Value, Values};

/// Why a request of a spec command came to nothing.
#[derive(Debug, thiserror::Error)]
pub enum TransactionError {
    /// The request could not be built: a value out of its field's range, a
    /// field missing (for a write).
    #[error("cannot build the request: {message}")]
    Request {
        /// The command.
        command: String,
        /// Why.
        message: String,
    },
    /// No valid reply, after the client's retries: silence, a corrupt or
    /// foreign frame, an exception, the port failing.
    #[error("{error}")]
    Bus {
        /// The command.
        command: String,
        /// The client's error.
        error: RtuError,
    },
    /// A reply framed as Modbus but not as the command's layout or fields
    /// say (another sensor at the address).
    #[error("cannot decode the reply: {message}")]
    Decode {
        /// The command.
        command: String,
        /// Why.
        message: String,
    },
}

impl TransactionError {
    /// The command the request was of.
    pub fn command(&self) -> &str {
        match self {
            Self::Request { command, .. } | Self::Bus { command, .. } | Self::Decode { command, .. } => command,
        }
    }

    /// The client's error, when the bus is what failed.
    pub fn bus_error(&self) -> Option<&RtuError> {
        match self {
            Self::Bus { error, .. } => Some(error),
            _ => None,
        }
    }
}

/// The slave a request of `command` goes to: its fixed address (a probe's
/// "get slave id" answers at 0xFF whatever its own) or `slave`.
pub fn target(command: &CommandSpec, slave: u8) -> u8 {
    command.fixed_slave.unwrap_or(slave)
}

/// Sends `command` with `values` (a write's fields; none for a read) to
/// `slave` as given (see [`target`]) and returns the reply's register data,
/// checked against the command's layout.
pub fn call_data<'c, T: Transport>(
    client: &'c mut Client<T>,
    command: &CommandSpec,
    slave: u8,
    values: &BTreeMap<String, Value>,
) -> Result<&'c [u8], TransactionError> {
    let request = command
        .encode_request(slave, values)
        .map_err(|e| TransactionError::Request { command: command.name.clone(), message: e.to_string() })?;
    let layout = command.layout();
    let reply = client
        .call_raw(&request, &layout)
        .map_err(|error| TransactionError::Bus { command: command.name.clone(), error })?;
    layout
        .decode_response(slave, reply)
        .map_err(|e| TransactionError::Decode { command: command.name.clone(), message: e.to_string() })
}

/// [`call_data`], and the reply decoded into the command's fields.
pub fn call<T: Transport>(
    client: &mut Client<T>,
    command: &CommandSpec,
    slave: u8,
    values: &BTreeMap<String, Value>,
) -> Result<Values, TransactionError> {
    call_data(client, command, slave, values).map(|data| decode_fields(command, data))
}
