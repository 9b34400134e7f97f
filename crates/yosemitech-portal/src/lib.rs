//! Store-and-forward publishing of station readings to Monitor My
//! Watershed, the EnviroDIY data portal.
//!
//! The portal takes readings at `POST /api/data-stream/` with the site's
//! registration token in a `TOKEN` header and a JSON body naming the site's
//! sampling feature, a timestamp with its UTC offset and one value per
//! result UUID (several records as parallel arrays); it answers 201 when it
//! stored them. A station commits every reading to its store first; the
//! store implements [`Outbox`] with a cursor of the portal's own; a
//! [`Publisher`] drains it in order and moves the cursor only on 201.
//!
//! * [`body`]: which readings go in a request and its JSON, without I/O.
//! * [`PortalConfig`]: the site, the result UUIDs, the pacing.
//! * [`Publisher`]: the thread that sends, over HTTPS (rustls).
//!
//! `docs/monitor-my-watershed.md` tells how a station is set up for it.
#![cfg_attr(not(test), deny(clippy::unwrap_used, clippy::expect_used, clippy::panic))]

pub mod body;
mod config;
mod publisher;

pub use body::Record;
pub use config::{DEFAULT_BATCH, DEFAULT_URL, PortalConfig, TOKEN_VAR, Token, TokenError, TokenSource, is_uuid};
pub use publisher::{Outbox, PortalStatus, Publisher, StartError};
