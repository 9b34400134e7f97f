//! `yosemitech sniff` on a tapped bus: a master (the runtime's client)
//! polls two simulated probes on one line, faults are injected into their
//! replies, and the sniffer listens on a second pty that hears every byte
//! of the line. What it records must match what was sent, exchange by
//! exchange: every byte of the line in exactly one entry, every request
//! once and in order, every fault flagged where it happened, nothing
//! flagged that was not. `--raw` then `--replay` hears the same again.

use std::collections::BTreeMap;
use std::io::{BufRead, BufReader, Read};
use std::process::{Child, Stdio};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use serde_json::Value as Json;
use yosemitech_rtu::{Client, ClientConfig, RetryPolicy, SerialConfig, SerialTransport};
use yosemitech_sim::serve::tap::{Direction, serve_pty_tapped};
use yosemitech_sim::{Bus, FaultConfig, FaultKind, FrameHandler, ServeConfig, Simulator};
use yosemitech_spec::{CommandSpec, Sensor};
use yosemitech_tests::cli::{Binary, interrupt, wait};

const YOSEMITECH: Binary = Binary(env!("CARGO_BIN_EXE_yosemitech"));

/// The sniffer's reply timeout, and the simulator's delay (past it, within
/// the client's), far apart: a loaded machine delays a clean reply too.
/// The sniffer's silence is as generous, so that a scheduler's pause
/// between two chunks of a clean frame is not a silence inside it.
const SNIFF_TIMEOUT: &str = "700ms";
const SNIFF_SILENCE: &str = "200ms";
const DELAY: Duration = Duration::from_millis(1500);
const CLIENT_TIMEOUT: Duration = Duration::from_secs(3);

/// What the master was told of an exchange, and the fault its probe drew.
struct Sent {
    slave: u8,
    request: Vec<u8>,
    fault: Option<FaultKind>,
    /// Two probes answered at once.
    collided: bool,
    reply: Result<Vec<u8>, String>,
}

/// The reads a probe of `sensor` answers with data.
fn reads(sensor: &Sensor) -> Vec<&CommandSpec> {
    sensor.commands.iter().filter(|c| c.is_read() && c.count > 0 && c.fixed_slave.is_none()).collect()
}

fn spec() -> yosemitech_spec::Spec {
    yosemitech_spec::load_paths(&[concat!(env!("CARGO_MANIFEST_DIR"), "/../../spec").into()]).unwrap()
}

fn hex_bytes(text: &str) -> Vec<u8> {
    text.split_whitespace().map(|pair| u8::from_str_radix(pair, 16).unwrap()).collect()
}

/// Starts `sniff` on `args` and waits until it listens; its stdout is read
/// as it comes (a full pipe would stop it), and handed over at the end.
fn start_sniffer(args: &[&str]) -> (Child, JoinHandle<String>) {
    let mut child =
        YOSEMITECH.command().arg("sniff").args(args).stdout(Stdio::piped()).stderr(Stdio::piped()).spawn().unwrap();
    let mut stderr = BufReader::new(child.stderr.take().unwrap());
    let mut line = String::new();
    stderr.read_line(&mut line).unwrap();
    assert!(line.contains("listening"), "sniff says it listens: {line:?}");
    std::thread::spawn(move || {
        let mut rest = String::new();
        let _ = stderr.read_to_string(&mut rest);
    });
    let mut stdout = child.stdout.take().unwrap();
    let output = std::thread::spawn(move || {
        let mut out = String::new();
        stdout.read_to_string(&mut out).unwrap();
        out
    });
    (child, output)
}

/// The JSON lines of a sniffer's output: the entries, then the summary.
fn entries(stdout: &str) -> (Vec<Json>, Json) {
    let mut docs: Vec<Json> = stdout.lines().map(|l| serde_json::from_str(l).unwrap()).collect();
    let summary = docs.pop().expect("a summary line");
    assert_eq!(summary["type"], "summary");
    (docs, summary)
}

/// (offset, bytes) of every frame and noise run in the entries.
fn pieces(entries: &[Json]) -> Vec<(u64, Vec<u8>)> {
    let mut pieces = Vec::new();
    for e in entries {
        for key in ["request", "reply"] {
            if let Some(frame) = e.get(key).filter(|f| f.is_object()) {
                pieces.push((frame["offset"].as_u64().unwrap(), hex_bytes(frame["frame"].as_str().unwrap())));
            }
        }
        if e["type"] == "noise" {
            pieces.push((e["offset"].as_u64().unwrap(), hex_bytes(e["bytes"].as_str().unwrap())));
        }
    }
    pieces.sort();
    pieces
}

fn flags(e: &Json) -> Vec<String> {
    e["flags"].as_array().unwrap().iter().map(|f| f["flag"].as_str().unwrap().to_owned()).collect()
}

#[test]
fn the_sniffer_hears_every_exchange_and_flags_every_fault() {
    let spec = spec();
    // The first two sensors of the spec that answer reads with data.
    let sensors: Vec<&Sensor> = spec.sensors.iter().filter(|s| !reads(s).is_empty()).take(2).collect();
    assert_eq!(sensors.len(), 2, "the spec has two sensors with reads");
    // Probe 1 draws every fault kind once, a clean reply between two.
    let script: Vec<Option<FaultKind>> = FaultKind::ALL.iter().flat_map(|k| [None, Some(*k)]).chain([None]).collect();
    let faults = FaultConfig { delay_by: DELAY, ..FaultConfig::scripted(script.clone()) };
    let bus = Bus::new()
        .with(Simulator::new(sensors[0].clone()).with_address(1).with_faults(faults))
        .with(Simulator::new(sensors[1].clone()).with_address(2));
    let tapped = serve_pty_tapped(bus, ServeConfig::default(), true).unwrap();
    let (sniffer, output) = start_sniffer(&[
        "--port",
        &tapped.tap_path,
        "--json",
        "--reply-timeout",
        SNIFF_TIMEOUT,
        "--silence",
        SNIFF_SILENCE,
    ]);

    let config = ClientConfig {
        timeout: CLIENT_TIMEOUT,
        retry: RetryPolicy { retries: 0, ..RetryPolicy::default() },
        ..ClientConfig::default()
    };
    let mut client =
        Client::with_config(SerialTransport::open(&SerialConfig::new(tapped.path.clone())).unwrap(), config);
    let mut sent: Vec<Sent> = Vec::new();
    let mut faults_of_probe_1 = script.into_iter();
    let mut exchange = |client: &mut Client<SerialTransport>, command: &CommandSpec, slave: u8, collided: bool| {
        let request = command.encode_request(slave, &BTreeMap::new()).unwrap();
        let fault = if slave == 1 { faults_of_probe_1.next().flatten() } else { None };
        let reply = client.call_raw(&request, &command.layout()).map(<[u8]>::to_vec).map_err(|e| e.to_string());
        Sent { slave, request, fault, collided, reply }
    };
    let rounds = FaultKind::ALL.len() * 2 + 1;
    for i in 0..rounds {
        for (slave, sensor) in [(1, sensors[0]), (2, sensors[1])] {
            let commands = reads(sensor);
            sent.push(exchange(&mut client, commands[i % commands.len()], slave, false));
        }
    }
    // Two probes at one address answer at once: probe 2 and a probe of a
    // sensor that answers one of its reads differently.
    let answer = |sensor: &Sensor, request: &[u8]| {
        let mut reply = Vec::new();
        Simulator::new(sensor.clone()).with_address(2).handle(request, &mut reply);
        reply
    };
    let collision = spec.sensors.iter().flat_map(|other| reads(sensors[1]).into_iter().map(move |c| (other, c))).find(
        |(other, c)| {
            let request = c.encode_request(2, &BTreeMap::new()).unwrap();
            let (theirs, ours) = (answer(other, &request), answer(sensors[1], &request));
            !theirs.is_empty() && !ours.is_empty() && theirs != ours
        },
    );
    match collision {
        Some((other, differs)) => {
            tapped.server.device().push(Simulator::new(other.clone()).with_address(2));
            sent.push(exchange(&mut client, differs, 2, true));
            assert!(tapped.server.device().collisions() > 0, "the bus saw a collision");
            assert!(sent.last().is_some_and(|s| s.reply.is_err()), "the collision garbled the reply");
        }
        None => eprintln!("    sniff: no sensor of this spec answers one of probe 2's reads differently: no collision"),
    }

    // The sniffer has heard the last reply (its silence has passed), then stops on Ctrl-C.
    std::thread::sleep(Duration::from_secs(1));
    interrupt(sniffer);
    let out = output.join().unwrap();
    let (heard, summary) = entries(&out);

    // Every byte of the line is in exactly one entry, in order.
    let line: Vec<u8> = tapped.line().into_iter().flat_map(|(_, bytes)| bytes).collect();
    let pieces = pieces(&heard);
    let mut at = 0u64;
    for (offset, bytes) in &pieces {
        assert_eq!(*offset, at, "a gap or an overlap at byte {at}\n{out}");
        at += bytes.len() as u64;
    }
    assert_eq!(pieces.into_iter().flat_map(|(_, b)| b).collect::<Vec<u8>>(), line, "the entries are the line");
    let masters: Vec<u8> =
        tapped.line().into_iter().filter(|(d, _)| *d == Direction::Master).flat_map(|(_, b)| b).collect();
    assert_eq!(masters, sent.iter().flat_map(|s| s.request.clone()).collect::<Vec<u8>>());

    // Every request once, in order, with what its fault made of it.
    let transactions: Vec<&Json> = heard.iter().filter(|e| e["type"] == "transaction").collect();
    assert_eq!(transactions.len(), sent.len(), "exchanges sent and recorded\n{out}");
    let mut flagged = 0;
    for (s, e) in sent.iter().zip(&transactions) {
        let what = format!("{:?} to {} (collided: {}): {e}", s.fault, s.slave, s.collided);
        assert_eq!(hex_bytes(e["request"]["frame"].as_str().unwrap()), s.request, "{what}");
        let status = e["status"].as_str().unwrap();
        let flags = flags(e);
        let clean = s.fault.is_none() && !s.collided;
        match (&s.reply, s.fault) {
            _ if s.collided => assert_ne!(status, "decoded", "{what}"),
            (Ok(reply), None | Some(FaultKind::Garbage)) => {
                assert_eq!(hex_bytes(e["reply"]["frame"].as_str().unwrap()), *reply, "{what}");
                assert!(matches!(status, "decoded" | "ambiguous"), "{what}");
            }
            (Ok(reply), Some(FaultKind::Delay)) => {
                assert_eq!(hex_bytes(e["reply"]["frame"].as_str().unwrap()), *reply, "{what}");
                assert_eq!(flags, ["late_reply"], "{what}");
            }
            (Err(_), Some(FaultKind::Busy)) => assert_eq!(status, "exception", "{what}"),
            (Err(_), Some(FaultKind::Drop | FaultKind::WrongSlave)) => assert_eq!(status, "no_reply", "{what}"),
            (Err(_), Some(FaultKind::CorruptCrc)) => {
                assert_eq!(status, "undecodable", "{what}");
                assert_eq!(e["reply"]["crc_ok"], false, "{what}");
            }
            // A reply cut to a byte or two is noise, not a reply.
            (Err(_), Some(FaultKind::Truncate)) => {
                assert!(matches!(status, "undecodable" | "no_reply"), "{what}");
                assert_ne!(e["reply"]["crc_ok"], true, "{what}");
            }
            (reply, fault) => panic!("{fault:?} gave the client {reply:?}: {what}"),
        }
        if clean {
            assert!(flags.is_empty(), "nothing flagged on a clean exchange: {what}");
        } else {
            flagged += 1;
        }
    }
    // What a fault adds beside its exchange: the garbage's noise, the other slave's reply.
    let noise = heard.iter().filter(|e| e["type"] == "noise").count();
    let unpaired = heard.iter().filter(|e| e["status"] == "unpaired").count();
    assert!(noise >= 1, "the garbage is heard as noise\n{out}");
    assert!(unpaired >= 1, "the reply from another address is heard alone\n{out}");
    let requests: u64 = summary["slaves"].as_array().unwrap().iter().map(|s| s["requests"].as_u64().unwrap()).sum();
    assert_eq!(requests, sent.len() as u64, "{summary}");
    eprintln!(
        "    sniff: {} exchanges sent, {} recorded, {flagged} faults flagged, {} noise runs, {} unpaired, 0 frames lost",
        sent.len(),
        transactions.len(),
        noise,
        unpaired
    );
}

/// A capture `--raw` wrote is heard again by `--replay` as it was live, and
/// `decode --capture` reads it.
#[test]
fn a_raw_capture_replays_as_it_was_heard() {
    let spec = spec();
    let sensor = spec.sensors.iter().find(|s| !reads(s).is_empty()).unwrap();
    let tapped =
        serve_pty_tapped(Simulator::new(sensor.clone()).with_address(1), ServeConfig::default(), true).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let raw = dir.path().join("bus.capture");
    let raw_arg = raw.to_str().unwrap();
    let (sniffer, output) = start_sniffer(&["--port", &tapped.tap_path, "--json", "--raw", raw_arg]);
    let mut client = Client::new(SerialTransport::open(&SerialConfig::new(tapped.path.clone())).unwrap());
    let commands = reads(sensor);
    for command in &commands {
        let request = command.encode_request(1, &BTreeMap::new()).unwrap();
        client.call_raw(&request, &command.layout()).unwrap();
    }
    let started = Instant::now();
    while std::fs::read_to_string(&raw).unwrap_or_default().lines().count() < 3
        && started.elapsed() < Duration::from_secs(30)
    {
        std::thread::sleep(Duration::from_millis(20));
    }
    interrupt(sniffer);
    let (live, _) = entries(&output.join().unwrap());
    // Each read paired with its reply (a reply that several sensors read differently is ambiguous).
    let answered = live.iter().filter(|e| e["type"] == "transaction" && e["reply"]["crc_ok"] == true).count();
    assert_eq!(answered, commands.len(), "{live:?}");

    let mut replay = YOSEMITECH.command();
    replay.args(["sniff", "--replay", raw_arg, "--json"]).stdout(Stdio::piped()).stderr(Stdio::piped());
    let mut child = replay.spawn().unwrap();
    let mut out = String::new();
    child.stdout.take().unwrap().read_to_string(&mut out).unwrap();
    assert_eq!(wait(&mut child, Duration::from_secs(60)), 0);
    let (replayed, _) = entries(&out);
    let frames = |entries: &[Json]| -> Vec<(Json, Json, Json)> {
        entries
            .iter()
            .filter(|e| e["type"] != "summary")
            .map(|e| (e["request"]["frame"].clone(), e["reply"]["frame"].clone(), e["status"].clone()))
            .collect()
    };
    assert_eq!(frames(&replayed), frames(&live), "the replay hears what was heard live");
    for (live, replayed) in live.iter().zip(&replayed) {
        let ms = |e: &Json, key: &str| e[key].as_f64();
        assert_eq!(ms(live, "latency_ms"), ms(replayed, "latency_ms"), "the same times");
    }

    // `decode --capture` reads the same exchanges from it (exit 1 for the
    // ambiguous ones; it does not narrow a slave to a sensor as sniff does).
    let decode = YOSEMITECH.run(&["decode", "--capture", raw_arg, "--json"]);
    let (decoded, _) = entries(&decode.stdout);
    let without_status =
        |frames: Vec<(Json, Json, Json)>| frames.into_iter().map(|(q, r, _)| (q, r)).collect::<Vec<_>>();
    assert_eq!(
        without_status(frames(&decoded)),
        without_status(frames(&live)),
        "decode reads the capture: {}",
        decode.stderr
    );
}

/// Misuse: no port, a TCP address, a capture that is not one.
/// `simulate A --also B@2 --tap` started as a user starts it: the bus and
/// the tap it prints.
fn simulate_tapped(args: &[&str]) -> (Child, String, String) {
    let mut child = YOSEMITECH
        .command()
        .arg("simulate")
        .args(args)
        .arg("--tap")
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut stdout = BufReader::new(child.stdout.take().unwrap());
    let (mut bus, mut tap) = (String::new(), String::new());
    stdout.read_line(&mut bus).unwrap();
    stdout.read_line(&mut tap).unwrap();
    (child, bus.trim().to_owned(), tap.trim().to_owned())
}

/// What each simulated probe did, from `simulate`'s closing line
/// (`address 1: 12 requests, 6 replies, ..., 2 ignored (registers the probe
/// lacks), ...; address 2: ...`): the replies it sent, and the requests to
/// it it left unanswered as a real probe does (registers it lacks).
fn served(stderr: &str) -> BTreeMap<u64, (u64, u64)> {
    let line = stderr.lines().find(|l| l.starts_with("stopped:")).expect("a closing line");
    line.trim_start_matches("stopped:")
        .split("; address ")
        .filter_map(|part| {
            let (address, rest) = part.trim().trim_start_matches("address ").split_once(':')?;
            let count = |what: &str| {
                rest.split(", ").find_map(|count| count.trim().strip_suffix(what)).and_then(|n| n.parse().ok())
            };
            Some((address.parse().ok()?, (count(" replies")?, count(" ignored (registers the probe lacks)")?)))
        })
        .collect()
}

/// The live view a technician gets: the CLI (scan, then polls) drives two
/// simulated probes on one line while `sniff` listens on the simulator's
/// tap. Every exchange is heard: per slave, the replies the probe sent and
/// the requests it left unanswered;
/// each slave is named as scan names it, by the serial number overheard.
#[test]
fn the_cli_driving_two_simulated_probes_is_heard_live() {
    let spec = spec();
    let sensors: Vec<&Sensor> = spec.sensors.iter().filter(|s| !reads(s).is_empty()).take(2).collect();
    assert_eq!(sensors.len(), 2, "the spec has two sensors with reads");
    let also = format!("{}@2", sensors[1].name);
    let (simulator, bus, tap) = simulate_tapped(&[&sensors[0].name, "--address", "1", "--also", &also]);
    let (sniffer, output) = start_sniffer(&["--port", &tap, "--json"]);

    let scan = YOSEMITECH.run(&["scan", "--port", &bus, "--addresses", "1-2", "--json"]);
    let scanned = scan.json();
    for (address, sensor) in [(1, sensors[0]), (2, sensors[1])] {
        let read = reads(sensor)[0];
        let run =
            YOSEMITECH.run(&["read", &sensor.name, &read.name, "--port", &bus, "--address", &address.to_string()]);
        run.ok();
    }
    std::thread::sleep(Duration::from_secs(1));
    interrupt(sniffer);
    let served = served(&interrupt(simulator));
    let (heard, summary) = entries(&output.join().unwrap());
    assert!(heard.iter().all(|e| e["type"] == "transaction"), "no noise, nothing unpaired: {summary}");
    let replies = heard.iter().filter(|e| e["reply"].is_object());
    assert!(replies.clone().count() > 0 && replies.clone().all(|e| e["reply"]["crc_ok"] == true), "{summary}");
    let slaves = summary["slaves"].as_array().unwrap();
    for (address, sensor) in [(1u64, sensors[0]), (2, sensors[1])] {
        let slave = slaves.iter().find(|s| s["slave"] == address).expect("the slave was heard");
        let (replied, ignored) = served[&address];
        // Scan's reads of registers a probe lacks go unanswered, as on a real bus.
        assert_eq!(slave["replies"].as_u64(), Some(replied), "address {address}: {slave}");
        assert_eq!(slave["no_reply"].as_u64(), Some(ignored), "address {address}: {slave}");
        assert_eq!(slave["requests"].as_u64(), Some(replied + ignored), "{slave}");
        match scanned["devices"].as_array().unwrap().iter().find(|d| d["address"] == address) {
            Some(device) => {
                assert_eq!(slave["serial_number"], device["serial_number"], "{slave} / {device}");
                assert_eq!(slave["model_code"], device["model_code"], "{slave} / {device}");
                if device["sensor"] == sensor.name.as_str() {
                    assert_eq!(slave["sensor"], sensor.name.as_str(), "named as scan names it: {slave}");
                }
            }
            // A probe without a serial-number read answers none of scan's reads.
            None => assert_eq!(slave["serial_number"], Json::Null, "{slave}"),
        }
    }
}

#[test]
fn sniff_misuse_is_a_usage_error() {
    let dir = tempfile::tempdir().unwrap();
    let bad = dir.path().join("bad.capture");
    std::fs::write(&bad, "0.5: 01 03\n0.25: 01 03\n").unwrap();
    for (args, says) in [
        (vec!["sniff"], "--port"),
        (vec!["sniff", "--port", "tcp://127.0.0.1:502"], "serial line"),
        (vec!["sniff", "--replay", bad.to_str().unwrap()], "goes back in time"),
        (vec!["sniff", "--replay", "/nonexistent/capture"], "cannot read the capture"),
        (vec!["sniff", "--port", "/dev/null", "--baud", "0"], "--baud 0"),
    ] {
        let run = YOSEMITECH.run(&args);
        assert_eq!(run.code, 2, "{args:?}: {}", run.stderr);
        assert!(run.stderr.contains(says), "{args:?}: {}", run.stderr);
    }
}

/// A soak: a master polling at 115200 baud with no pause between
/// exchanges (a pty delivers as fast as the processes run, faster than
/// the wire): every exchange is recorded, every byte accounted for.
#[test]
fn a_soak_of_back_to_back_polling_loses_no_exchange() {
    const EXCHANGES: usize = 400;
    let spec = spec();
    let sensor = spec.sensors.iter().find(|s| !reads(s).is_empty()).unwrap();
    let tapped =
        serve_pty_tapped(Simulator::new(sensor.clone()).with_address(1), ServeConfig::default(), true).unwrap();
    let (sniffer, output) = start_sniffer(&["--port", &tapped.tap_path, "--json", "--baud", "115200"]);
    let settings = yosemitech_rtu::LineSettings { baud: 115_200, ..yosemitech_rtu::LineSettings::default() };
    let mut client =
        Client::new(SerialTransport::open(&SerialConfig::with_settings(tapped.path.clone(), settings)).unwrap());
    let commands = reads(sensor);
    for i in 0..EXCHANGES {
        let command = commands[i % commands.len()];
        let request = command.encode_request(1, &BTreeMap::new()).unwrap();
        client.call_raw(&request, &command.layout()).unwrap();
    }
    // The sniffer has heard the whole line before it is stopped.
    std::thread::sleep(Duration::from_secs(1));
    let on_the_line = tapped.line().iter().map(|(_, bytes)| bytes.len()).sum::<usize>();
    interrupt(sniffer);
    let out = output.join().unwrap();
    let (heard, summary) = entries(&out);
    let pieces = pieces(&heard);
    assert_eq!(pieces.iter().map(|(_, b)| b.len()).sum::<usize>(), on_the_line, "every byte heard");
    let answered = heard.iter().filter(|e| e["type"] == "transaction" && e["reply"]["crc_ok"] == true).count();
    assert_eq!(answered, EXCHANGES, "{summary}");
    assert!(heard.iter().all(|e| e["type"] == "transaction"), "no noise, nothing unpaired: {summary}");
}
