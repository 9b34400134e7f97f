//! The publisher: drains an [`Outbox`] to the portal, one request at a time.

use std::sync::{Arc, Condvar, Mutex, MutexGuard, PoisonError};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use crate::body::{Record, body, next_batch};
use crate::config::{PortalConfig, Token, TokenError};

/// The station's readings as the portal publisher drains them.
///
/// Contract: [`Outbox::pending`] returns the records with an id above a
/// cursor, ascending, at most `limit`, the same record for the same id
/// every time; [`Outbox::mark_sent`] moves that cursor durably before it
/// returns `Ok`. The publisher calls it only after the portal answered 201
/// for every record up to that id. An outbox may keep several cursors
/// (the station keeps one per probe, so that a request carries a batch of
/// one probe's readings): `mark_sent` then moves the cursor of the records
/// the last `pending` returned.
pub trait Outbox {
    /// The store's error.
    type Error: std::error::Error;

    /// Up to `limit` records not yet sent, ascending ids.
    fn pending(&mut self, limit: usize) -> Result<Vec<Record>, Self::Error>;

    /// Marks every record with an id up to `up_to_id` sent, durably.
    fn mark_sent(&mut self, up_to_id: i64) -> Result<(), Self::Error>;
}

/// What the publisher is doing.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct PortalStatus {
    /// The id up to which the last accepted request marked records sent
    /// (on the cursor of its records).
    pub sent_up_to: Option<i64>,
    /// Requests the portal accepted (201).
    pub accepted: u64,
    /// Requests that failed (refused, or no answer).
    pub failed: u64,
    /// Why the last request failed, if the last one did. It names no token.
    pub last_error: Option<String>,
}

/// Why the publisher could not start.
#[derive(Debug, thiserror::Error)]
pub enum StartError {
    /// The token could not be loaded.
    #[error(transparent)]
    Token(#[from] TokenError),
    /// The thread could not be created.
    #[error("cannot start the portal publisher thread: {0}")]
    Thread(#[from] std::io::Error),
}

#[derive(Default)]
struct State {
    stop: bool,
    woken: bool,
    status: PortalStatus,
}

#[derive(Default)]
struct Shared {
    state: Mutex<State>,
    signal: Condvar,
}

impl Shared {
    fn lock(&self) -> MutexGuard<'_, State> {
        self.state.lock().unwrap_or_else(PoisonError::into_inner)
    }

    /// Waits up to `limit`, or until stopped (and, with `wakeable`, woken);
    /// true when stopped.
    fn pause(&self, limit: Duration, wakeable: bool) -> bool {
        let deadline = Instant::now() + limit;
        let mut state = self.lock();
        loop {
            if state.stop {
                return true;
            }
            if wakeable && state.woken {
                state.woken = false;
                return false;
            }
            let left = deadline.saturating_duration_since(Instant::now());
            if left.is_zero() {
                return false;
            }
            state = self.signal.wait_timeout(state, left).unwrap_or_else(PoisonError::into_inner).0;
        }
    }
}

/// Publishes an [`Outbox`] to Monitor My Watershed from a thread of its own.
///
/// # What is guaranteed
///
/// * Records go in store order, one request at a time, each request a
///   [`crate::body::next_batch`]; the cursor moves only after HTTP 201 for
///   the request, so a record is sent again only if the publisher stopped
///   (was killed) between the 201 and the cursor's commit.
/// * A failed request (no connection, a timeout, any status but 201) is
///   repeated after a pause that doubles from `retry_min` to `retry_max`;
///   a refusal that will not go away by itself (400, 401, 403, 404) waits
///   `retry_max` every time. Each distinct cause is logged once when it
///   starts, and once more when requests succeed again.
/// * The token goes into the `TOKEN` header and nowhere else: not in a
///   log, an error or [`PortalStatus`] (what the server answers is logged
///   with the token blanked out).
pub struct Publisher {
    shared: Arc<Shared>,
    thread: Option<JoinHandle<()>>,
}

/// How one request ended.
enum Outcome {
    Accepted,
    /// A status the portal will answer again to the same request.
    Refused(String),
    /// Anything else worth another try soon.
    Failed(String),
}

impl Publisher {
    /// Loads the token and starts publishing `outbox` from a new thread.
    /// An unreachable portal is no error here: requests are retried.
    ///
    /// # Errors
    ///
    /// The token cannot be loaded, or the thread cannot start.
    pub fn start<O>(config: &PortalConfig, outbox: O) -> Result<Self, StartError>
    where
        O: Outbox + Send + 'static,
    {
        let token = config.token.load()?;
        let shared = Arc::new(Shared::default());
        let worker = Worker { config: config.clone(), token, outbox, shared: Arc::clone(&shared) };
        let thread = std::thread::Builder::new().name("portal-publisher".into()).spawn(move || worker.run())?;
        Ok(Self { shared, thread: Some(thread) })
    }

    /// Tells the publisher that readings were committed.
    pub fn wake(&self) {
        self.shared.lock().woken = true;
        self.shared.signal.notify_all();
    }

    /// What it is doing.
    pub fn status(&self) -> PortalStatus {
        self.shared.lock().status.clone()
    }

    /// Stops it: a request under way is finished (and its records marked
    /// if accepted) if it ends within `limit`; none is started after.
    /// Returns the last status.
    pub fn shutdown(mut self, limit: Duration) -> PortalStatus {
        self.stop(limit);
        self.status()
    }

    fn stop(&mut self, limit: Duration) {
        self.shared.lock().stop = true;
        self.shared.signal.notify_all();
        if let Some(thread) = self.thread.take() {
            let deadline = Instant::now() + limit;
            while !thread.is_finished() && Instant::now() < deadline {
                std::thread::sleep(Duration::from_millis(20));
            }
            if thread.is_finished() {
                let _ = thread.join();
            }
        }
    }
}

impl Drop for Publisher {
    fn drop(&mut self) {
        self.stop(Duration::ZERO);
    }
}

struct Worker<O> {
    config: PortalConfig,
    token: Token,
    outbox: O,
    shared: Arc<Shared>,
}

impl<O: Outbox> Worker<O> {
    fn run(mut self) {
        let agent: ureq::Agent = ureq::Agent::config_builder()
            .timeout_global(Some(self.config.timeout))
            .http_status_as_error(false)
            .max_redirects(0)
            .build()
            .into();
        let mut backoff = self.config.retry_min;
        let mut cause: Option<String> = None;
        loop {
            if self.shared.lock().stop {
                return;
            }
            let pending = match self.outbox.pending(self.config.batch.saturating_mul(4).max(1)) {
                Ok(pending) => pending,
                Err(e) => {
                    self.failed(&mut cause, format!("cannot read the store: {e}"));
                    if self.shared.pause(self.config.retry_max, false) {
                        return;
                    }
                    continue;
                }
            };
            let Some(batch) = next_batch(&pending, self.config.batch) else {
                if self.shared.pause(self.config.poll_interval, true) {
                    return;
                }
                continue;
            };
            let outcome = if batch.records.is_empty() {
                Outcome::Accepted
            } else {
                let body = body(&self.config.sampling_feature, self.config.utc_offset_hours, &batch.records);
                self.post(&agent, &body.to_string())
            };
            let wait = match outcome {
                Outcome::Accepted => match self.outbox.mark_sent(batch.up_to) {
                    Ok(()) => {
                        if let Some(was) = cause.take() {
                            tracing::info!("monitor my watershed: accepting readings again (after: {was})");
                        }
                        backoff = self.config.retry_min;
                        let mut state = self.shared.lock();
                        state.status.sent_up_to = Some(batch.up_to);
                        if !batch.records.is_empty() {
                            state.status.accepted += 1;
                        }
                        state.status.last_error = None;
                        continue;
                    }
                    Err(e) => {
                        self.failed(&mut cause, format!("cannot mark readings sent in the store: {e}"));
                        self.config.retry_max
                    }
                },
                Outcome::Refused(why) => {
                    self.failed(&mut cause, why);
                    self.config.retry_max
                }
                Outcome::Failed(why) => {
                    self.failed(&mut cause, why);
                    let wait = backoff;
                    backoff = (backoff * 2).min(self.config.retry_max);
                    wait
                }
            };
            if self.shared.pause(wait, false) {
                return;
            }
        }
    }

    /// Records a failure; logs it when its cause is new.
    fn failed(&self, cause: &mut Option<String>, why: String) {
        if cause.as_deref() != Some(why.as_str()) {
            tracing::warn!("monitor my watershed: {why}; retrying until it is accepted");
            *cause = Some(why.clone());
        }
        let mut state = self.shared.lock();
        state.status.failed += 1;
        state.status.last_error = Some(why);
    }

    fn post(&self, agent: &ureq::Agent, body: &str) -> Outcome {
        let sent = agent
            .post(&self.config.url)
            .header("TOKEN", self.token.expose())
            .header("Content-Type", "application/json")
            .send(body);
        let mut response = match sent {
            Ok(response) => response,
            // ureq's errors name the URL and the cause, not the headers.
            Err(e) => return Outcome::Failed(self.token.redact(&format!("no answer from {}: {e}", self.config.url))),
        };
        let status = response.status().as_u16();
        if status == 201 {
            return Outcome::Accepted;
        }
        let said = response.body_mut().with_config().limit(512).read_to_string().unwrap_or_default();
        let said: String = said.chars().filter(|c| !c.is_control()).take(200).collect();
        let why = self.token.redact(&format!("the portal answered HTTP {status}{}", meaning(status)))
            + &if said.is_empty() { String::new() } else { format!(": {}", self.token.redact(said.trim())) };
        if matches!(status, 400 | 401 | 403 | 404) { Outcome::Refused(why) } else { Outcome::Failed(why) }
    }
}

/// What a refusal most likely means here.
fn meaning(status: u16) -> &'static str {
    match status {
        400 => " (it refuses the request's body)",
        401 | 403 => " (the token is missing, wrong or of another site: check it and the sampling feature)",
        404 => " (no data endpoint at this url)",
        _ => "",
    }
}
