//! The store as the Monitor My Watershed publisher's outbox
//! (`yosemitech_portal::Outbox`), with a cursor per probe.
//!
//! A stored reading becomes a portal record through the station file's
//! result UUIDs: each numeric value of a measurement bound for the reading's
//! probe (in the unit the store holds it in), none of the others. A reading
//! with no bound number (a failed read, a derived quantity that could not
//! be computed) becomes a record without values, which the publisher passes
//! over; no placeholder stands in for a missing value.
//!
//! A request's records must all carry the same result UUIDs (the portal
//! takes parallel arrays), and the probes of a station take turns in the
//! store. With one cursor over the whole store, a request could carry only
//! the run of one probe's readings between two of another's: one reading.
//! So each bound probe has a cursor of its own (`monitor_my_watershed/<label>`)
//! and a request is a batch of one probe's readings; the probe whose oldest
//! unsent reading is the oldest goes first, so a backlog is sent in store
//! order, probe by probe, in full batches.

use yosemitech_portal::{Outbox, PortalConfig, Record};

use crate::store::{Datum, Store, StoreError, StoredReading};
use crate::time::unix_ms;

/// The publisher's name, before the probe label of each cursor.
pub const PORTAL_PUBLISHER: &str = "monitor_my_watershed";

/// The outbox name of the cursor of `probe`'s readings.
pub fn cursor_of(probe: &str) -> String {
    format!("{PORTAL_PUBLISHER}/{probe}")
}

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
    /// The probe whose records [`Outbox::pending`] returned last: the
    /// cursor [`Outbox::mark_sent`] moves.
    drained: Option<String>,
}

impl PortalOutbox {
    /// `store` drained under `config`'s result UUIDs.
    pub fn new(store: Store, config: PortalConfig) -> Self {
        Self { store, config, drained: None }
    }

    /// The bound probe whose oldest unsent reading is the oldest.
    fn next_probe(&self) -> Result<Option<String>, StoreError> {
        let mut next: Option<(i64, &String)> = None;
        for probe in self.config.results.keys() {
            if let Some(id) = self.store.oldest_unpublished_of_probe(&cursor_of(probe), probe)?
                && next.is_none_or(|(oldest, _)| id < oldest)
            {
                next = Some((id, probe));
            }
        }
        Ok(next.map(|(_, probe)| probe.clone()))
    }
}

impl Outbox for PortalOutbox {
    type Error = StoreError;

    fn pending(&mut self, limit: usize) -> Result<Vec<Record>, StoreError> {
        self.drained = self.next_probe()?;
        let Some(probe) = &self.drained else { return Ok(Vec::new()) };
        let unsent = self.store.unpublished_of_probe(&cursor_of(probe), probe, limit)?;
        Ok(unsent.iter().map(|s| record(s, &self.config)).collect())
    }

    fn mark_sent(&mut self, up_to_id: i64) -> Result<(), StoreError> {
        match &self.drained {
            Some(probe) => self.store.mark_published(&cursor_of(probe), up_to_id),
            None => Ok(()),
        }
    }
}
