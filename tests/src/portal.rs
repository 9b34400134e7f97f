//! A loopback stand-in for Monitor My Watershed's data endpoint that
//! enforces the portal's documented rules: `POST /api/data-stream/` with
//! the site's token in `TOKEN` (missing: 401, another: 403), a JSON body
//! with the site's `sampling_feature` (missing: 400, another site's: 403),
//! every timestamp with its UTC offset (`+hh:mm` or `-hh:mm`, else 400),
//! several records only as arrays of one length (else 400); result UUIDs
//! it does not know are ignored, as the portal does. It answers 201 and
//! records the body when it accepts one. It can be stopped (connections
//! refused) and started again on the same port, keeping what it recorded.

use std::io::{BufRead, BufReader, Read, Write};
use std::net::{SocketAddr, TcpListener, TcpStream};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, PoisonError};
use std::thread::JoinHandle;
use std::time::Duration;

use serde_json::Value;

/// One value the portal stored: (result uuid, timestamp as sent, value).
pub type Stored = (String, String, f64);

#[derive(Default)]
struct Log {
    /// Every body accepted, as received.
    accepted: Vec<String>,
    /// Every refusal: (status, why).
    refused: Vec<(u16, String)>,
}

/// The portal on a loopback port; stopped on drop.
pub struct Portal {
    /// Its address.
    pub address: SocketAddr,
    token: String,
    sampling_feature: String,
    log: Arc<Mutex<Log>>,
    running: Option<(Arc<AtomicBool>, JoinHandle<()>)>,
}

impl Portal {
    /// A portal for the site of `sampling_feature` whose token is `token`.
    pub fn start(token: &str, sampling_feature: &str) -> Portal {
        let listener = TcpListener::bind("127.0.0.1:0").expect("a loopback port");
        let address = listener.local_addr().expect("its address");
        let mut portal = Portal {
            address,
            token: token.to_owned(),
            sampling_feature: sampling_feature.to_owned(),
            log: Arc::default(),
            running: None,
        };
        portal.serve(listener);
        portal
    }

    /// The data endpoint's URL.
    pub fn url(&self) -> String {
        format!("http://{}/api/data-stream/", self.address)
    }

    fn serve(&mut self, listener: TcpListener) {
        let stop = Arc::new(AtomicBool::new(false));
        let (log, token, feature, halt) =
            (Arc::clone(&self.log), self.token.clone(), self.sampling_feature.clone(), Arc::clone(&stop));
        let thread = std::thread::spawn(move || {
            for stream in listener.incoming() {
                if halt.load(Ordering::SeqCst) {
                    break;
                }
                if let Ok(stream) = stream {
                    let _ = handle(stream, &token, &feature, &log);
                }
            }
        });
        self.running = Some((stop, thread));
    }

    /// Stops listening: connections are refused until [`Portal::restart`].
    pub fn stop(&mut self) {
        if let Some((stop, thread)) = self.running.take() {
            stop.store(true, Ordering::SeqCst);
            let _ = TcpStream::connect(self.address);
            let _ = thread.join();
        }
    }

    /// Listens again on the same port.
    pub fn restart(&mut self) {
        assert!(self.running.is_none(), "the portal is running");
        // The port may linger a moment after the stop; bind again until it is free.
        let mut tries = 0;
        let listener = loop {
            match TcpListener::bind(self.address) {
                Ok(l) => break l,
                Err(_) if tries < 200 => {
                    tries += 1;
                    std::thread::sleep(Duration::from_millis(50));
                }
                Err(e) => panic!("cannot listen on {} again: {e}", self.address),
            }
        };
        self.serve(listener);
    }

    /// The bodies accepted so far, as received.
    pub fn accepted(&self) -> Vec<String> {
        self.log.lock().unwrap_or_else(PoisonError::into_inner).accepted.clone()
    }

    /// The refusals so far: (status, why).
    pub fn refused(&self) -> Vec<(u16, String)> {
        self.log.lock().unwrap_or_else(PoisonError::into_inner).refused.clone()
    }

    /// Every value of every accepted body, in the order received.
    pub fn stored(&self) -> Vec<Stored> {
        self.accepted().iter().flat_map(|body| values(body)).collect()
    }
}

impl Drop for Portal {
    fn drop(&mut self) {
        self.stop();
    }
}

/// The values of an accepted body: (uuid, timestamp, value) per record.
pub fn values(body: &str) -> Vec<Stored> {
    let Ok(Value::Object(body)) = serde_json::from_str::<Value>(body) else { return Vec::new() };
    let stamps: Vec<String> = match &body["timestamp"] {
        Value::Array(a) => a.iter().filter_map(|t| t.as_str().map(str::to_owned)).collect(),
        Value::String(t) => vec![t.clone()],
        _ => Vec::new(),
    };
    let mut out = Vec::new();
    for (key, column) in &body {
        if key == "sampling_feature" || key == "timestamp" {
            continue;
        }
        let column: Vec<&Value> = match column {
            Value::Array(a) => a.iter().collect(),
            one => vec![one],
        };
        for (stamp, v) in stamps.iter().zip(column) {
            if let Some(v) = v.as_f64() {
                out.push((key.clone(), stamp.clone(), v));
            }
        }
    }
    out
}

/// Whether `t` ends in a UTC offset `+hh:mm` / `-hh:mm` after a time.
fn has_offset(t: &str) -> bool {
    let b = t.as_bytes();
    b.len() >= 6 + 19
        && t.get(..19).is_some_and(|head| head.as_bytes()[10] == b'T')
        && matches!(b[b.len() - 6], b'+' | b'-')
        && b[b.len() - 5..b.len() - 3].iter().all(u8::is_ascii_digit)
        && b[b.len() - 3] == b':'
        && b[b.len() - 2..].iter().all(u8::is_ascii_digit)
}

/// The portal's verdict on a request: 201, or the status and why.
fn judge(method: &str, path: &str, token: Option<&str>, body: &str, site: (&str, &str)) -> Result<(), (u16, String)> {
    if method != "POST" || path != "/api/data-stream/" {
        return Err((404, format!("no {method} {path}")));
    }
    match token {
        None => return Err((401, "no TOKEN header".into())),
        Some(t) if t != site.0 => return Err((403, "a token of no site here".into())),
        Some(_) => {}
    }
    let Ok(Value::Object(body)) = serde_json::from_str::<Value>(body) else {
        return Err((400, "the body is not a JSON object".into()));
    };
    match body.get("sampling_feature").and_then(Value::as_str) {
        None => return Err((400, "no sampling_feature".into())),
        Some(s) if s != site.1 => return Err((403, "the token is not this sampling feature's".into())),
        Some(_) => {}
    }
    let n = match body.get("timestamp") {
        Some(Value::String(t)) if has_offset(t) => None,
        Some(Value::Array(a)) if a.iter().all(|t| t.as_str().is_some_and(has_offset)) => Some(a.len()),
        Some(_) => return Err((400, "a timestamp without its UTC offset".into())),
        None => return Err((400, "no timestamp".into())),
    };
    for (key, v) in &body {
        if key == "sampling_feature" || key == "timestamp" {
            continue;
        }
        let ok = match (n, v) {
            (None, Value::Number(_)) => true,
            (Some(n), Value::Array(a)) => a.len() == n && a.iter().all(Value::is_number),
            _ => false,
        };
        if !ok {
            return Err((400, format!("`{key}`: not one number per timestamp")));
        }
    }
    Ok(())
}

fn handle(stream: TcpStream, token: &str, feature: &str, log: &Mutex<Log>) -> std::io::Result<()> {
    stream.set_read_timeout(Some(Duration::from_secs(10)))?;
    let mut reader = BufReader::new(stream.try_clone()?);
    let mut line = String::new();
    reader.read_line(&mut line)?;
    let mut parts = line.split_whitespace();
    let (method, path) = (parts.next().unwrap_or_default().to_owned(), parts.next().unwrap_or_default().to_owned());
    let (mut length, mut sent_token) = (0usize, None);
    loop {
        let mut header = String::new();
        if reader.read_line(&mut header)? == 0 || header.trim().is_empty() {
            break;
        }
        if let Some((name, value)) = header.split_once(':') {
            let value = value.trim().to_owned();
            if name.eq_ignore_ascii_case("content-length") {
                length = value.parse().unwrap_or(0);
            } else if name.eq_ignore_ascii_case("token") {
                sent_token = Some(value);
            }
        }
    }
    let mut body = vec![0; length];
    reader.read_exact(&mut body)?;
    let body = String::from_utf8_lossy(&body).into_owned();
    let verdict = judge(&method, &path, sent_token.as_deref(), &body, (token, feature));
    let (status, text) = match &verdict {
        Ok(()) => (201, "Created".to_owned()),
        Err((status, why)) => (*status, why.clone()),
    };
    {
        let mut log = log.lock().unwrap_or_else(PoisonError::into_inner);
        match verdict {
            Ok(()) => log.accepted.push(body),
            Err(refusal) => log.refused.push(refusal),
        }
    }
    let mut stream = stream;
    write!(
        stream,
        "HTTP/1.1 {status} {}\r\nContent-Type: text/plain\r\nContent-Length: {}\r\nConnection: close\r\n\r\n{text}",
        if status == 201 { "Created" } else { "Refused" },
        text.len()
    )?;
    stream.flush()
}

#[cfg(test)]
mod tests {
    use super::*;

    const SITE: (&str, &str) = ("tok", "feat");

    #[test]
    fn it_refuses_what_the_portal_refuses() {
        let ok = r#"{"sampling_feature":"feat","timestamp":["2026-01-01T00:00:00+00:00","2026-01-01T00:01:00-05:00"],"u":[1,2]}"#;
        assert_eq!(judge("POST", "/api/data-stream/", Some("tok"), ok, SITE), Ok(()));
        let one = r#"{"sampling_feature":"feat","timestamp":"2026-01-01T00:00:00.250+01:00","u":1.5}"#;
        assert_eq!(judge("POST", "/api/data-stream/", Some("tok"), one, SITE), Ok(()));
        let status =
            |token: Option<&str>, body: &str| judge("POST", "/api/data-stream/", token, body, SITE).err().map(|e| e.0);
        assert_eq!(status(None, ok), Some(401));
        assert_eq!(status(Some("other"), ok), Some(403));
        assert_eq!(status(Some("tok"), r#"{"timestamp":"2026-01-01T00:00:00+00:00","u":1}"#), Some(400));
        assert_eq!(
            status(Some("tok"), r#"{"sampling_feature":"feat","timestamp":"2026-01-01T00:00:00","u":1}"#),
            Some(400)
        );
        assert_eq!(
            status(Some("tok"), r#"{"sampling_feature":"feat","timestamp":"2026-01-01T00:00:00Z","u":1}"#),
            Some(400)
        );
        let unequal = r#"{"sampling_feature":"feat","timestamp":["2026-01-01T00:00:00+00:00"],"u":[1,2]}"#;
        assert_eq!(status(Some("tok"), unequal), Some(400));
        assert_eq!(values(ok).len(), 2);
    }
}
