//! The store-and-forward queue the publisher drains.

use std::convert::Infallible;
use std::sync::{Arc, Mutex, MutexGuard, PoisonError};

use crate::message::ReadingMessage;

/// The station's store of readings waiting to be published, oldest first.
///
/// The station implements it on its database (one SQLite connection of its
/// own, for example), and [`crate::Publisher`] calls it from its thread.
///
/// Contract, on which the delivery guarantee rests:
///
/// * Every stored reading has a `reading_id` (its store id) that is unique
///   and increases in commit order: a reading committed later never gets a
///   smaller id (SQLite: `INTEGER PRIMARY KEY AUTOINCREMENT`, committed by
///   one writer). The id is copied into [`ReadingMessage::reading_id`].
/// * [`Outbox::unpublished`] returns readings not yet marked published with
///   an id greater than `after` (all of them when `after` is `None`), in
///   ascending id order, at most `limit` of them. It returns the same
///   message for the same id every time (the payload is rebuilt from the
///   store, so a resend is identical).
/// * [`Outbox::mark_published`] records durably that every reading with an
///   id up to and including `up_to_id` has been acknowledged by the broker,
///   before it returns `Ok`. The publisher calls it with increasing ids and
///   only after the broker's PUBACK for every one of them.
pub trait Outbox {
    /// The store's error.
    type Error: std::error::Error;

    /// Up to `limit` unpublished readings with `reading_id > after`, ascending.
    fn unpublished(&mut self, after: Option<i64>, limit: usize) -> Result<Vec<ReadingMessage>, Self::Error>;

    /// Marks every reading with `reading_id <= up_to_id` published, durably.
    fn mark_published(&mut self, up_to_id: i64) -> Result<(), Self::Error>;
}

/// An [`Outbox`] in memory, for tests and examples. Clones share one queue,
/// so one clone can be given to a publisher while another adds readings and
/// watches progress.
#[derive(Debug, Clone, Default)]
pub struct MemoryOutbox {
    state: Arc<Mutex<MemoryState>>,
}

#[derive(Debug, Default)]
struct MemoryState {
    readings: Vec<ReadingMessage>,
    published_up_to: Option<i64>,
}

impl MemoryOutbox {
    /// An empty outbox.
    pub fn new() -> Self {
        Self::default()
    }

    fn lock(&self) -> MutexGuard<'_, MemoryState> {
        // The state stays consistent at every await-free step, so a panic in
        // another holder does not make it unusable.
        self.state.lock().unwrap_or_else(PoisonError::into_inner)
    }

    /// Stores `message` under the next id (1, 2, ...), which overwrites
    /// `message.reading_id`; returns that id.
    pub fn push(&self, mut message: ReadingMessage) -> i64 {
        let mut state = self.lock();
        let id = state.readings.last().map_or(1, |last| last.reading_id + 1);
        message.reading_id = id;
        state.readings.push(message);
        id
    }

    /// The highest id marked published, if any.
    pub fn published_up_to(&self) -> Option<i64> {
        self.lock().published_up_to
    }

    /// How many readings are stored (published or not).
    pub fn len(&self) -> usize {
        self.lock().readings.len()
    }

    /// Whether nothing is stored.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

impl Outbox for MemoryOutbox {
    type Error = Infallible;

    fn unpublished(&mut self, after: Option<i64>, limit: usize) -> Result<Vec<ReadingMessage>, Infallible> {
        let state = self.lock();
        let floor = after.max(state.published_up_to);
        Ok(state
            .readings
            .iter()
            .filter(|reading| floor.is_none_or(|floor| reading.reading_id > floor))
            .take(limit)
            .cloned()
            .collect())
    }

    fn mark_published(&mut self, up_to_id: i64) -> Result<(), Infallible> {
        let mut state = self.lock();
        state.published_up_to = state.published_up_to.max(Some(up_to_id));
        Ok(())
    }
}
