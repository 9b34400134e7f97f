//! Changing a probe's slave address, so the user always knows where it is.
//!
//! The address is validated (1..=247, not the current one, not taken by
//! another device: anything that answers there, even with an exception),
//! the write is confirmed by the probe's reply from its old address, and
//! the probe is read back at the new one. If anything fails after the write
//! was sent, both addresses are probed and the error says where the probe
//! answers.

use std::fmt;

use crate::{Client, Command, Error, Transport};

/// Where a probe answers after a failed change.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Whereabouts {
    /// At its old address: the change did not take.
    Old(u8),
    /// At its new address: the change took, the confirmation was lost.
    New(u8),
    /// At neither (power loss, wiring): try `scan`.
    Unknown {
        /// The old address.
        old: u8,
        /// The new address.
        new: u8,
    },
}

impl fmt::Display for Whereabouts {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Old(a) => write!(f, "the probe still answers at its old address {a}"),
            Self::New(a) => write!(f, "the probe answers at its new address {a}"),
            Self::Unknown { old, new } => {
                write!(f, "the probe answers at neither {old} nor {new}; scan the bus to find it")
            }
        }
    }
}

/// Why an address change was refused or failed.
#[derive(Debug)]
#[non_exhaustive]
pub enum AddressChangeError {
    /// An address is outside 1..=247.
    InvalidAddress(u8),
    /// The new address is the current one.
    SameAddress(u8),
    /// Another device already answers at the new address (with a reply, an
    /// exception or a frame that fails a check).
    AddressInUse(u8),
    /// No probe answers at the old address; nothing was written.
    NotFound {
        /// The old address.
        address: u8,
        /// The error of the probe request.
        error: Error,
    },
    /// The write or its verification failed; `whereabouts` says where the probe is.
    Failed {
        /// What failed.
        error: Error,
        /// Where the probe answers now.
        whereabouts: Whereabouts,
    },
}

impl fmt::Display for AddressChangeError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::InvalidAddress(a) => write!(f, "address {a} is outside 1 to 247"),
            Self::SameAddress(a) => write!(f, "the probe is already at address {a}"),
            Self::AddressInUse(a) => write!(f, "another device already answers at address {a}"),
            Self::NotFound { address, error } => write!(f, "no probe answers at address {address}: {error}"),
            Self::Failed { error, whereabouts } => write!(f, "{error}; {whereabouts}"),
        }
    }
}

impl std::error::Error for AddressChangeError {}

fn valid(a: u8) -> Result<(), AddressChangeError> {
    if (1..=247).contains(&a) { Ok(()) } else { Err(AddressChangeError::InvalidAddress(a)) }
}

/// Changes the probe at `from` to `to`.
///
/// `write` is the sensor's request of role `set_slave_address` carrying
/// `to`; `probe` is any read the probe answers (its `serial_number` read),
/// used to check addresses before and after. Generated `Device` handles
/// call this from their `set_slave_address`.
/// Returns the probe's reply to `probe` at its new address.
pub fn change_address<T: Transport, W: Command, P: Command>(
    client: &mut Client<T>,
    from: u8,
    to: u8,
    write: &W,
    probe: &P,
) -> Result<P::Response, AddressChangeError> {
    change_address_with(
        client,
        from,
        to,
        |client| client.call(from, write).map(|_| ()),
        |client, slave| client.call(slave, probe),
    )
}

/// [`change_address`] for requests built at run time (from a spec): `write`
/// sends the address write to `from`, `probe(client, slave)` sends the probe
/// read to `slave`. The same checks, in the same order, decide the outcome.
pub fn change_address_with<T: Transport, R>(
    client: &mut Client<T>,
    from: u8,
    to: u8,
    mut write: impl FnMut(&mut Client<T>) -> Result<(), Error>,
    mut probe: impl FnMut(&mut Client<T>, u8) -> Result<R, Error>,
) -> Result<R, AddressChangeError> {
    valid(from)?;
    valid(to)?;
    if from == to {
        return Err(AddressChangeError::SameAddress(to));
    }
    // Any reply at the new address, even an exception or a bad frame, is a
    // device there: moving the probe onto it would put two at one address.
    if let Ok(_) | Err(Error::Frame { .. }) = probe(client, to) {
        return Err(AddressChangeError::AddressInUse(to));
    }
    if let Err(error) = probe(client, from) {
        return Err(AddressChangeError::NotFound { address: from, error });
    }
    if let Err(error) = write(client) {
        let whereabouts = locate(client, &mut probe, from, to);
        return Err(AddressChangeError::Failed { error, whereabouts });
    }
    match probe(client, to) {
        Ok(reply) => Ok(reply),
        Err(error) => {
            let whereabouts = locate(client, &mut probe, from, to);
            Err(AddressChangeError::Failed { error, whereabouts })
        }
    }
}

/// Where the probe answers after a failed change: the new address first.
fn locate<T: Transport, R>(
    client: &mut Client<T>,
    probe: &mut impl FnMut(&mut Client<T>, u8) -> Result<R, Error>,
    from: u8,
    to: u8,
) -> Whereabouts {
    if probe(client, to).is_ok() {
        Whereabouts::New(to)
    } else if probe(client, from).is_ok() {
        Whereabouts::Old(from)
    } else {
        Whereabouts::Unknown { old: from, new: to }
    }
}
