//! Hand-written Modbus RTU runtime for Yosemitech probes.
//!
//! Everything generated code relies on lives here once: the CRC, frame
//! encoding and checking ([`frame::Layout`]), register value codecs
//! ([`codec`]), the [`Command`] trait, typed errors, and Modbus TCP framing
//! ([`mbap`]: the MBAP header and conversion to and from RTU frames). The core is `no_std`
//! and allocation-free; the `std` feature adds [`transport`]s (serial with
//! the `serial` feature, RTU-over-TCP, in-memory) and the blocking [`Client`] over the sans-IO [`ClientCore`].
//! The `tokio` feature adds the async client on the same core; the
//! `tokio-modbus` feature runs generated commands over an existing
//! tokio-modbus connection (`tokio_modbus` module).
#![cfg_attr(not(any(feature = "std", test)), no_std)]
#![cfg_attr(not(test), deny(clippy::unwrap_used, clippy::expect_used, clippy::panic, clippy::indexing_slicing))]

#[macro_use]
mod trace;

#[cfg(feature = "std")]
pub mod address;
pub mod bytes;
pub mod client;
pub mod codec;
mod command;
mod crc;
mod declare;
pub mod derived;
pub mod dispatch;
mod error;
pub mod frame;
pub mod mbap;
mod message;
pub mod segment;
mod sensor;
pub mod timing;
#[cfg(feature = "tokio-modbus")]
pub mod tokio_modbus;
#[cfg(feature = "std")]
pub mod transport;
mod value;

pub use codec::{Ascii, Bcd, ByteOrder2, ByteOrder4, Version};
pub use command::Command;
pub use crc::{CRC_INIT, crc_ok, crc16, crc16_update};
pub use derived::{DerivedInfo, DerivedInput, InputSource, NotComputable};
pub use error::{EchoField, EncodeError, ExceptionCode, FrameError};
pub use frame::{Frame, Function, Layout};
pub use mbap::MbapError;
pub use message::{Message, NoData};
pub use sensor::{CoefficientBlock, CommandEntry, RoundTripError, SensorInfo, SensorModule, identify_request};
pub use timing::{CharFormat, DataBits, LineSettings, LineTiming, Parity, StopBits};
pub use value::{FieldInfo, FieldValue};

#[cfg(feature = "tokio")]
pub use client::AsyncClient;
#[cfg(feature = "std")]
pub use client::{Client, Error};
pub use client::{ClientConfig, ClientCore, ClientError, RetryPolicy};
#[cfg(feature = "tokio-serial")]
pub use transport::AsyncSerial;
#[cfg(feature = "tokio")]
pub use transport::{AsyncLink, MbapLink, RtuStream};
#[cfg(feature = "std")]
pub use transport::{MemoryTransport, Responder, ResponderTransport, TcpTransport, Transport};
#[cfg(feature = "serial")]
pub use transport::{SerialConfig, SerialTransport};

/// Shows bytes as space-separated upper-case hex (`01 03 28 00`).
#[derive(Clone, Copy)]
pub struct Hex<'a>(pub &'a [u8]);

impl core::fmt::Display for Hex<'_> {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        for (i, b) in self.0.iter().enumerate() {
            if i > 0 {
                f.write_str(" ")?;
            }
            write!(f, "{b:02X}")?;
        }
        Ok(())
    }
}

impl core::fmt::Debug for Hex<'_> {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        core::fmt::Display::fmt(self, f)
    }
}
