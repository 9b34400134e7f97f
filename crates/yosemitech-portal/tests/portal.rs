//! The publisher against the loopback portal of the test kit, which
//! refuses what Monitor My Watershed refuses: every record accepted once,
//! in order, across an outage of the portal; a wrong token refused and
//! reported without the token.

use std::convert::Infallible;
use std::sync::{Arc, Mutex};
use std::time::Duration;

use yosemitech_portal::{Outbox, PortalConfig, Publisher, Record, TOKEN_VAR, TokenSource};
use yosemitech_tests::broker::wait_until;
use yosemitech_tests::portal::Portal;

const FEATURE: &str = "0a1b2c3d-0000-4000-8000-00000000feed";
const TEMPERATURE: &str = "11111111-0000-4000-8000-000000000001";
const PH: &str = "22222222-0000-4000-8000-000000000002";
const TOKEN: &str = "test-token-9f8e7d";

#[derive(Clone, Default)]
struct Memory(Arc<Mutex<(Vec<Record>, i64)>>);

impl Memory {
    fn push(&self, values: &[(&str, f64)]) {
        let mut state = self.0.lock().unwrap();
        let id = state.0.len() as i64 + 1;
        let values = values.iter().map(|(u, v)| ((*u).to_owned(), *v)).collect();
        state.0.push(Record { id, timestamp_ms: 1_795_900_500_000 + id * 1500, values });
    }

    fn mark(&self) -> i64 {
        self.0.lock().unwrap().1
    }
}

impl Outbox for Memory {
    type Error = Infallible;

    fn pending(&mut self, limit: usize) -> Result<Vec<Record>, Infallible> {
        let state = self.0.lock().unwrap();
        Ok(state.0.iter().filter(|r| r.id > state.1).take(limit).cloned().collect())
    }

    fn mark_sent(&mut self, up_to_id: i64) -> Result<(), Infallible> {
        let mut state = self.0.lock().unwrap();
        state.1 = state.1.max(up_to_id);
        Ok(())
    }
}

fn config(portal: &Portal, token: &std::path::Path) -> PortalConfig {
    let mut config = PortalConfig::new(TokenSource::File(token.to_owned()), FEATURE);
    config.url = portal.url();
    config.batch = 4;
    config.retry_min = Duration::from_millis(50);
    config.retry_max = Duration::from_millis(400);
    config.poll_interval = Duration::from_millis(50);
    config
}

fn token_file(dir: &std::path::Path, token: &str) -> std::path::PathBuf {
    use std::os::unix::fs::PermissionsExt;
    let path = dir.join("token");
    std::fs::write(&path, format!("{token}\n")).unwrap();
    std::fs::set_permissions(&path, std::fs::Permissions::from_mode(0o600)).unwrap();
    path
}

#[test]
fn every_record_is_accepted_once_across_an_outage() {
    let dir = tempfile::tempdir().unwrap();
    let mut portal = Portal::start(TOKEN, FEATURE);
    let outbox = Memory::default();
    for i in 0..10 {
        outbox.push(&[(TEMPERATURE, 20.0 + f64::from(i)), (PH, 7.0)]);
    }
    // A reading of a probe the portal does not take, and one with a temperature only.
    outbox.push(&[]);
    outbox.push(&[(TEMPERATURE, 30.5)]);
    let publisher = Publisher::start(&config(&portal, &token_file(dir.path(), TOKEN)), outbox.clone()).unwrap();
    assert!(
        wait_until(|| outbox.mark() == 12),
        "the backlog goes out: {:?} {:?}",
        publisher.status(),
        portal.refused()
    );
    portal.stop();
    for i in 0..9 {
        outbox.push(&[(TEMPERATURE, 40.0 + f64::from(i)), (PH, 6.5)]);
    }
    publisher.wake();
    assert!(wait_until(|| publisher.status().failed >= 2), "requests fail while the portal is away");
    assert_eq!(outbox.mark(), 12, "nothing is marked while the portal is away");
    portal.restart();
    assert!(wait_until(|| outbox.mark() == 21), "the portal back, the rest goes out");
    let status = publisher.shutdown(Duration::from_secs(10));
    assert_eq!(status.sent_up_to, Some(21));

    let stored = portal.stored();
    let expected: Vec<(String, f64)> = outbox
        .0
        .lock()
        .unwrap()
        .0
        .iter()
        .flat_map(|r| {
            let mut v = r.values.clone();
            v.sort_by(|a, b| a.0.cmp(&b.0));
            v
        })
        .collect();
    let got: Vec<(String, f64)> = stored.iter().map(|(u, _, v)| (u.clone(), *v)).collect();
    assert_eq!(got.len(), expected.len(), "each value once: {got:?}");
    let mut keys: Vec<(&str, &str)> = stored.iter().map(|(u, t, _)| (u.as_str(), t.as_str())).collect();
    keys.sort_unstable();
    keys.dedup();
    assert_eq!(keys.len(), stored.len(), "no value twice");
    assert!(portal.refused().is_empty(), "{:?}", portal.refused());
    let bodies = portal.accepted();
    assert!(bodies.iter().any(|b| b.contains("\"timestamp\":[")), "several records go as arrays: {bodies:?}");
    for body in &bodies {
        eprintln!("accepted: {body}");
    }
}

#[test]
fn a_wrong_token_is_refused_retried_slowly_and_never_shown() {
    let dir = tempfile::tempdir().unwrap();
    let portal = Portal::start(TOKEN, FEATURE);
    let outbox = Memory::default();
    outbox.push(&[(TEMPERATURE, 20.0)]);
    let wrong = "wrong-token-abcdef";
    let publisher = Publisher::start(&config(&portal, &token_file(dir.path(), wrong)), outbox.clone()).unwrap();
    assert!(wait_until(|| publisher.status().failed >= 2));
    let status = publisher.shutdown(Duration::from_secs(10));
    assert_eq!(outbox.mark(), 0);
    let why = status.last_error.clone().unwrap();
    assert!(why.contains("403") && why.contains("token"), "{why}");
    assert!(!why.contains(wrong) && !format!("{status:?}").contains(wrong), "{why}");
    assert!(portal.refused().iter().all(|(s, _)| *s == 403));
    // Slowly: at the longest pause (400 ms here), not a request per poll.
    assert!(portal.refused().len() <= 10, "{} refusals", portal.refused().len());
}

#[test]
fn a_missing_token_stops_the_start_and_names_the_variable() {
    let e = TokenSource::Environment.load_with(|_| None).unwrap_err();
    assert!(e.to_string().contains(TOKEN_VAR));
}

#[test]
fn https_is_tls_and_a_plain_http_answer_is_no_acceptance() {
    // A server that answers 201 in clear text where a TLS handshake is due:
    // the publisher must not take it for an acceptance.
    let listener = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
    let address = listener.local_addr().unwrap();
    std::thread::spawn(move || {
        for stream in listener.incoming().flatten() {
            use std::io::Write;
            let mut stream = stream;
            let _ = stream.write_all(b"HTTP/1.1 201 Created\r\nContent-Length: 0\r\n\r\n");
        }
    });
    let dir = tempfile::tempdir().unwrap();
    let outbox = Memory::default();
    outbox.push(&[(TEMPERATURE, 20.0)]);
    let portal = Portal::start(TOKEN, FEATURE);
    let mut config = config(&portal, &token_file(dir.path(), TOKEN));
    config.url = format!("https://{address}/api/data-stream/");
    let publisher = Publisher::start(&config, outbox.clone()).unwrap();
    assert!(wait_until(|| publisher.status().failed >= 2));
    let status = publisher.shutdown(Duration::from_secs(10));
    assert_eq!(outbox.mark(), 0);
    assert!(status.last_error.as_deref().is_some_and(|e| e.contains("no answer")), "{status:?}");
    eprintln!("{status:?}");
}
