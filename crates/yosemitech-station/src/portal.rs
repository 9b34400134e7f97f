//! The store as the Monitor My Watershed publisher's outbox
//! (`yosemitech_portal::Outbox`), with a cursor of its own.
//!
//! A stored reading becomes a portal record through the station file's
//! result UUIDs: each numeric value of a measurement bound for the reading's
//! probe (in the unit the store holds it in), none of the others. A reading
//! with no bound number (another probe, a failed read, a derived quantity
//! that could not be computed) becomes a record without values, which the
//! publisher passes over; no placeholder stands in for a missing value.

use yosemitech_portal::{Outbox, PortalConfig, Record};

use crate::store::{Datum, Store, StoreError, StoredReading};
use crate::time::unix_ms;

/// The publisher's name in the store's outbox.
pub const PORTAL_PUBLISHER: &str = "monitor_my_watershed";

/// The record of `stored` under `config`'s result UUIDs.
pub fn record(stored: &StoredReading, config: &PortalConfig) -> Record {
    let r = &stored.reading;
    let values = r
        .values
        .iter()
        .filter_map(|m| match m.value {
            Datum::Number(n) if n.is_finite() => Some((config.result(&r.probe, &m.name)?.to_owned(), n)),
            Datum::Number(_) | Datum::Text(_) | Datum::NotComputable(_) => None,
        })
        .collect();
    Record { id: stored.id, timestamp_ms: unix_ms(r.timestamp), values }
}

/// A [`Store`] connection serving as the portal publisher's outbox.
#[derive(Debug)]
pub struct PortalOutbox {
    store: Store,
    config: PortalConfig,
}

impl PortalOutbox {
    /// `store` drained under `config`'s result UUIDs.
    pub fn new(store: Store, config: PortalConfig) -> Self {
        Self { store, config }
    }
}

impl Outbox for PortalOutbox {
    type Error = StoreError;

    fn pending(&mut self, limit: usize) -> Result<Vec<Record>, StoreError> {
        Ok(self.store.unpublished(PORTAL_PUBLISHER, limit)?.iter().map(|s| record(s, &self.config)).collect())
    }

    fn mark_sent(&mut self, up_to_id: i64) -> Result<(), StoreError> {
        self.store.mark_published(PORTAL_PUBLISHER, up_to_id)
    }
}
