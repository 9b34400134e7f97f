//! One behavioural test, every driver: [`AnyClient`] has the blocking
//! `Client`'s surface and runs either the blocking `Client` or the tokio
//! `AsyncClient` (on a current-thread runtime of its own), over a link both
//! accept; [`behaviour!`](crate::behaviour!) turns each test into one test per driver.

use std::time::Duration;

use yosemitech_rtu::transport::AsyncLink;
use yosemitech_rtu::{AsyncClient, Client, ClientConfig, Command, Error, Layout, Transport};

/// A driver of the client core.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Driver {
    /// `Client`: blocks the thread.
    Blocking,
    /// `AsyncClient` on tokio.
    Tokio,
}

/// A client of either driver.
pub enum AnyClient<T> {
    /// The blocking client.
    Blocking(Client<T>),
    /// The tokio client, with the current-thread runtime that runs it.
    Tokio(AsyncClient<T>, tokio::runtime::Runtime),
}

impl<T: Transport + AsyncLink> AnyClient<T> {
    /// A client of `driver` on `transport` (a runtime of its own for tokio).
    pub fn with_config(driver: Driver, transport: T, config: ClientConfig) -> Self {
        match driver {
            Driver::Blocking => Self::Blocking(Client::with_config(transport, config)),
            Driver::Tokio => {
                let runtime = tokio::runtime::Builder::new_current_thread().enable_time().build().unwrap();
                // The client's clock starts inside the runtime (tokio's clock).
                let client = runtime.block_on(async { AsyncClient::with_config(transport, config) });
                Self::Tokio(client, runtime)
            }
        }
    }

    /// `call` of the driver, run to completion.
    pub fn call<C: Command>(&mut self, slave: u8, command: &C) -> Result<C::Response, Error> {
        match self {
            Self::Blocking(client) => client.call(slave, command),
            Self::Tokio(client, runtime) => runtime.block_on(client.call(slave, command)),
        }
    }

    /// `broadcast` of the driver, run to completion.
    pub fn broadcast<C: Command>(&mut self, command: &C) -> Result<(), Error> {
        match self {
            Self::Blocking(client) => client.broadcast(command),
            Self::Tokio(client, runtime) => runtime.block_on(client.broadcast(command)),
        }
    }

    /// `call_raw` of the driver, run to completion.
    pub fn call_raw(&mut self, request: &[u8], layout: &Layout<'_>) -> Result<&[u8], Error> {
        match self {
            Self::Blocking(client) => client.call_raw(request, layout),
            Self::Tokio(client, runtime) => runtime.block_on(client.call_raw(request, layout)),
        }
    }

    /// `broadcast_raw` of the driver, run to completion.
    pub fn broadcast_raw(&mut self, request: &[u8], layout: &Layout<'_>) -> Result<(), Error> {
        match self {
            Self::Blocking(client) => client.broadcast_raw(request, layout),
            Self::Tokio(client, runtime) => runtime.block_on(client.broadcast_raw(request, layout)),
        }
    }

    /// The bytes of the last reply (`last_reply`).
    pub fn last_reply(&self) -> &[u8] {
        match self {
            Self::Blocking(client) => client.last_reply(),
            Self::Tokio(client, _) => client.last_reply(),
        }
    }

    /// The attempts after the first that the last call took (`ClientCore::retries`).
    pub fn retries(&self) -> u32 {
        match self {
            Self::Blocking(client) => client.core().retries(),
            Self::Tokio(client, _) => client.core().retries(),
        }
    }

    /// The configuration, to change between calls.
    pub fn config_mut(&mut self) -> &mut ClientConfig {
        match self {
            Self::Blocking(client) => client.config_mut(),
            Self::Tokio(client, _) => client.config_mut(),
        }
    }

    /// The silence kept between frames on this link.
    pub fn inter_frame_delay(&self) -> Duration {
        match self {
            Self::Blocking(client) => client.inter_frame_delay(),
            Self::Tokio(client, _) => client.inter_frame_delay(),
        }
    }

    /// The transport (the tokio client's link).
    pub fn transport(&self) -> &T {
        match self {
            Self::Blocking(client) => client.transport(),
            Self::Tokio(client, _) => client.link(),
        }
    }

    /// The transport back, dropping the client.
    pub fn into_transport(self) -> T {
        match self {
            Self::Blocking(client) => client.into_transport(),
            Self::Tokio(client, _) => client.into_link(),
        }
    }
}

/// Each `fn name(driver) { body }` becomes `blocking_driver::name` and
/// `tokio_driver::name`, with `driver` set to that driver.
#[macro_export]
macro_rules! behaviour {
    ($($(#[$meta:meta])* fn $name:ident($driver:ident) $body:block)*) => {
        mod blocking_driver {
            #[allow(unused_imports)]
            use super::*;
            $($(#[$meta])* #[test] fn $name() { let $driver = $crate::driver::Driver::Blocking; $body })*
        }
        mod tokio_driver {
            #[allow(unused_imports)]
            use super::*;
            $($(#[$meta])* #[test] fn $name() { let $driver = $crate::driver::Driver::Tokio; $body })*
        }
    };
}
