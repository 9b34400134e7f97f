//! Requests through the spec's interpreter (`yosemitech_ops::transaction`)
//! as the CLI reports them, and errors of the typed procedures.

use std::collections::BTreeMap;

use yosemitech::procedures::ProcedureError;
use yosemitech_ops::TransactionError;
use yosemitech_spec::{CommandSpec, Value, Values};

use crate::catalog::{Entry, Origin};
use crate::error::{CliError, Context, Result, request_failed};
use crate::port::Opened;

pub use yosemitech_ops::target;

/// Encodes `command` for `slave` with `values` (a write's fields), sends it
/// with the client's timing and retries, and decodes the reply (a read's values).
pub fn call(opened: &mut Opened, command: &CommandSpec, slave: u8, values: &BTreeMap<String, Value>) -> Result<Values> {
    let slave = target(command, slave);
    yosemitech_ops::call(&mut opened.bus, command, slave, values).map_err(|e| match e {
        TransactionError::Request { message, .. } => {
            CliError::usage(format!("cannot build the {} request: {message}", command.name))
        }
        TransactionError::Bus { error, .. } => {
            request_failed(&error, opened.bus.last_reply(), &opened.context(slave, &command.name))
        }
        TransactionError::Decode { message, .. } => {
            CliError::device(format!("cannot decode the reply to {}: {message}", command.name))
                .hint("the device may not be the sensor type you named; -v shows the frames")
        }
    })
}

/// Sends a read and returns its values, or the request's own error for
/// the caller to report (the outer error: the request cannot be built).
pub fn try_read(
    opened: &mut Opened,
    command: &CommandSpec,
    slave: u8,
) -> Result<std::result::Result<Values, yosemitech_rtu::Error>> {
    match yosemitech_ops::call(&mut opened.bus, command, target(command, slave), &BTreeMap::new()) {
        Ok(values) => Ok(Ok(values)),
        Err(TransactionError::Bus { error, .. }) => Ok(Err(error)),
        // A reply that does not decode has no values to show.
        Err(TransactionError::Decode { .. }) => Ok(Ok(Values::default())),
        Err(TransactionError::Request { message, .. }) => {
            Err(CliError::usage(format!("cannot build the {} request: {message}", command.name)))
        }
    }
}

/// A read with no values.
pub fn read(opened: &mut Opened, command: &CommandSpec, slave: u8) -> Result<Values> {
    call(opened, command, slave, &BTreeMap::new())
}

/// True when the typed `yosemitech` crate describes this sensor: a built-in
/// sensor called `name` (a `--spec` file of the same name replaces it).
pub fn is_typed(entry: &Entry, name: &str) -> bool {
    entry.origin == Origin::BuiltIn && entry.sensor.name == name
}

/// A procedure's error as the user sees it.
/// `reply` is what the client received last (`Client::last_reply`).
pub fn procedure_failed(e: &ProcedureError, reply: &[u8], ctx: &Context) -> CliError {
    match e {
        ProcedureError::Device(e) => request_failed(e, reply, ctx),
        ProcedureError::Aborted => CliError::device("stopped before completion"),
        ProcedureError::NotEnoughReadings { .. } => CliError::device(format!("measurement failed: {e}"))
            .hint("the probe kept flagging range-switch errors: check it is immersed and clean"),
        ProcedureError::ReadBackMismatch { .. } => CliError::device(format!("verification failed: {e}"))
            .hint("the probe did not keep the values written; read them with `yosemitech read` and retry"),
        other => CliError::device(other.to_string()),
    }
}
