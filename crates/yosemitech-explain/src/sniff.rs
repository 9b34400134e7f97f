//! Listening to a bus another master drives: bytes as they arrive, with
//! their times, framed, paired and decoded, exchange by exchange.
//!
//! Sans-IO: the caller reads the port (or a capture) and hands over each
//! chunk with the time its last byte arrived ([`Sniffer::push`]), and says
//! when the line has been quiet ([`Sniffer::tick`]); nothing here sleeps or
//! reads a clock, so a replayed capture is heard exactly as it was live.
//!
//! Framing uses the line's silences and the spec's lengths together. A
//! silence of at least [`Timing::silence`] ends a burst, and the
//! [`Scanner`] frames each burst by the commands' lengths and CRCs (several
//! frames back to back with short gaps are still told apart); a burst whose
//! tail is a frame still arriving (a slow adapter hands it over in pieces)
//! is held up to [`Timing::split_wait`] for the rest, and the gap inside the
//! frame is flagged. A line that is never quiet that long (a master polling
//! back to back at a high baud rate) is framed as it goes, once the burst
//! holds more than a frame's worth of bytes. Requests pair with the replies that follow them across
//! bursts; a request gets [`Timing::give_up`] for its reply.
//!
//! What is learnt of each slave: the sensors whose commands explain what
//! it was asked and answered, narrowed further by the model code of a
//! serial-number reply it is overheard sending (the code scan reads). Once
//! one sensor alone is left, the slave's replies decode as that sensor's (an
//! exchange that sensor cannot explain is decoded against every sensor
//! again, and the learning starts over). The serial number and model code
//! heard are kept per slave ([`Sniffer::identified`]).

use std::collections::BTreeMap;
use std::time::Duration;

use yosemitech_rtu::LineTiming;
use yosemitech_rtu::segment;
use yosemitech_spec::{Role, SerialNumberReply};

use super::candidates::Commands;
use super::exchange::{self, Exchange, Report, Status};
use super::scan::{Found, Framed, Scanner};

/// How the sniffer reads the line's timing.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Timing {
    /// A silence this long ends a burst of bytes.
    pub silence: Duration,
    /// How long a burst whose tail is a frame still arriving waits for the rest.
    pub split_wait: Duration,
    /// A reply later than this after its request is flagged late.
    pub reply_timeout: Duration,
    /// A request whose reply has not begun this long after it ends has none.
    pub give_up: Duration,
    /// How long one character takes on the line: the bytes of a chunk are
    /// taken to have arrived one such time apart, the last at the chunk's time.
    pub char_time: Duration,
}

/// A burst this long is framed before its silence comes (see [`Sniffer::push`]):
/// longer than any frame, so the frames it holds are whole.
const LONG_BURST: usize = 512;

/// The floor of [`Timing::silence`]: what an operating system and a USB
/// adapter add to the line's own silences between the chunks they hand over.
pub const MIN_SILENCE: Duration = Duration::from_millis(5);

impl Timing {
    /// The timing of a line, with `reply_timeout` as the master's timeout.
    pub fn of_line(line: LineTiming, reply_timeout: Duration) -> Self {
        let silence = (line.t3_5() * 2).max(MIN_SILENCE);
        Self {
            silence,
            split_wait: (silence * 10).max(Duration::from_millis(50)),
            reply_timeout,
            give_up: reply_timeout * 3,
            char_time: line.char_time(),
        }
    }
}

/// When a frame's bytes arrived.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct FrameTime {
    /// The first byte.
    pub first: Duration,
    /// The last byte.
    pub last: Duration,
    /// The longest silence between two of its bytes.
    pub longest_gap: Duration,
}

/// What breaks the line's rules in an exchange, beside what the frames'
/// explanation finds (CRC, lengths, byte counts, exceptions).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Flag {
    /// A silence inside the request: a slave drops a frame with a gap over t1.5.
    GapInRequest(Duration),
    /// A silence inside the reply.
    GapInReply(Duration),
    /// The reply began this long after the request, later than the timeout.
    LateReply(Duration),
}

impl std::fmt::Display for Flag {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Flag::GapInRequest(gap) => write!(f, "a silence of {} inside the request", millis(*gap)),
            Flag::GapInReply(gap) => write!(f, "a silence of {} inside the reply", millis(*gap)),
            Flag::LateReply(latency) => {
                write!(f, "the reply came {} after the request, past the timeout", millis(*latency))
            }
        }
    }
}

impl Flag {
    /// `late_reply`: its name in JSON and CSV.
    pub fn name(&self) -> &'static str {
        match self {
            Flag::GapInRequest(_) => "gap_in_request",
            Flag::GapInReply(_) => "gap_in_reply",
            Flag::LateReply(_) => "late_reply",
        }
    }
}

/// `12.3 ms`.
pub fn millis(d: Duration) -> String {
    format!("{:.1} ms", d.as_secs_f64() * 1000.0)
}

/// One entry heard: an exchange (or a frame alone, or noise), with its times.
pub struct Heard<'c> {
    /// What it is, decoded.
    pub report: Report<'c>,
    /// When the request (or the frame alone, or the noise) arrived.
    pub first: Option<FrameTime>,
    /// When the reply arrived.
    pub reply: Option<FrameTime>,
    /// The silence between the previous frame's end and this entry's start.
    pub gap_before: Option<Duration>,
    /// From the request's end to the reply's start.
    pub latency: Option<Duration>,
    /// The rules it breaks.
    pub flags: Vec<Flag>,
}

impl Heard<'_> {
    /// When it began.
    pub fn at(&self) -> Duration {
        self.first.or(self.reply).map_or(Duration::ZERO, |t| t.first)
    }
}

/// The listener: see the module's documentation.
pub struct Sniffer<'a, 'c> {
    commands: &'a Commands<'c>,
    scanner: Scanner<'a, 'c>,
    timing: Timing,
    /// The bytes since the last silence, each with its arrival time.
    burst: Vec<u8>,
    times: Vec<Duration>,
    /// Bytes heard before the burst.
    burst_start: usize,
    /// The times of the request waiting for its reply.
    pending: Option<FrameTime>,
    /// When the last frame heard ended.
    last_frame_end: Option<Duration>,
    /// Per slave, the sensor its traffic has shown it to be, as a choice of commands.
    learned: BTreeMap<u8, Learned<'c>>,
    /// Per slave, the last serial-number reply heard from it.
    serials: BTreeMap<u8, Serial>,
}

/// A serial-number reply heard from a slave.
#[derive(Debug, Clone, PartialEq, Eq)]
struct Serial {
    number: Option<String>,
    model_code: Option<String>,
}

/// What the sniffer has learnt of one slave.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Identity<'c> {
    /// Its address.
    pub slave: u8,
    /// The sensor, where one alone explains its traffic and its model code.
    pub sensor: Option<&'c str>,
    /// The serial number it was heard sending.
    pub serial_number: Option<String>,
    /// The model code that serial-number reply carries.
    pub model_code: Option<String>,
}

/// What a slave's traffic says it is.
struct Learned<'c> {
    /// The sensors that explain everything heard since the learning began.
    sensors: Vec<&'c str>,
    /// When one sensor is left: its commands, for decoding.
    chosen: Option<Commands<'c>>,
}

impl<'a, 'c> Sniffer<'a, 'c> {
    /// A sniffer framing by every command of `commands` and decoding by those it allows.
    pub fn new(commands: &'a Commands<'c>, timing: Timing) -> Self {
        Self {
            commands,
            scanner: Scanner::new(&commands.all),
            timing,
            burst: Vec::new(),
            times: Vec::new(),
            burst_start: 0,
            pending: None,
            last_frame_end: None,
            learned: BTreeMap::new(),
            serials: BTreeMap::new(),
        }
    }

    /// The timing it reads the line by.
    pub fn timing(&self) -> Timing {
        self.timing
    }

    /// Bytes that arrived, the last of them at `at` (time since any fixed
    /// start; times never go back). Returns what they complete.
    pub fn push(&mut self, at: Duration, bytes: &[u8]) -> Vec<Heard<'c>> {
        let mut heard = Vec::new();
        if bytes.is_empty() {
            return heard;
        }
        let previous = self.times.last().copied();
        // The bytes of a chunk came one character apart, the last at `at`,
        // none before the bytes already heard.
        let span = self.timing.char_time.saturating_mul(u32::try_from(bytes.len() - 1).unwrap_or(u32::MAX));
        let first = at.saturating_sub(span).max(previous.unwrap_or(Duration::ZERO));
        if let Some(previous) = previous {
            let quiet = first.saturating_sub(previous);
            if quiet >= self.timing.silence && (self.tail_is_complete() || quiet >= self.timing.split_wait) {
                heard.extend(self.flush());
            }
        }
        heard.extend(self.tick(first));
        for (i, byte) in bytes.iter().enumerate() {
            let offset = self.timing.char_time.saturating_mul(u32::try_from(i).unwrap_or(u32::MAX));
            self.times.push((first + offset).min(at.max(first)));
            self.burst.push(*byte);
        }
        // A line busy without a silence (a master polling back to back) is
        // heard as it goes, whole frames at a time: the burst stays small.
        if self.burst.len() >= LONG_BURST {
            let complete = self.complete_prefix();
            heard.extend(self.flush_prefix(complete));
        }
        heard
    }

    /// The line has been quiet up to `now`: ends a burst that a silence
    /// ends, and a wait for a reply that is over.
    pub fn tick(&mut self, now: Duration) -> Vec<Heard<'c>> {
        let mut heard = Vec::new();
        if let Some(&last) = self.times.last() {
            let quiet = now.saturating_sub(last);
            if quiet >= self.timing.silence && (self.tail_is_complete() || quiet >= self.timing.split_wait) {
                heard.extend(self.flush());
            }
        }
        if self.burst.is_empty()
            && let Some(request) = self.pending
            && now.saturating_sub(request.last) >= self.timing.give_up
            && let Some(found) = self.scanner.give_up_pending()
        {
            self.pending = None;
            heard.push(self.hear(found, Some(request), None));
        }
        heard
    }

    /// The end of the input: everything still held, as it is.
    pub fn finish(&mut self) -> Vec<Heard<'c>> {
        let mut heard = self.flush();
        if let Some(found) = self.scanner.give_up_pending() {
            let request = self.pending.take();
            heard.push(self.hear(found, request, None));
        }
        heard
    }

    /// Whether the burst ends where a frame ends (nothing more is needed to
    /// frame it): otherwise a frame may still be arriving.
    fn tail_is_complete(&self) -> bool {
        self.complete_prefix() == self.burst.len()
    }

    /// How many bytes at the burst's start are whole frames and noise; the
    /// rest may be a frame still arriving.
    fn complete_prefix(&self) -> usize {
        let mut at = 0;
        while let Some(rest) = self.burst.get(at..).filter(|rest| !rest.is_empty()) {
            match segment::next_span(rest) {
                // A frame, or noise before one (the frame follows).
                Ok(span) => at += span.len(),
                Err(segment::Incomplete) => break,
            }
        }
        at
    }

    /// Frames the burst and decodes what it completes.
    fn flush(&mut self) -> Vec<Heard<'c>> {
        self.flush_prefix(self.burst.len())
    }

    /// Frames the first `len` bytes of the burst as a burst of their own
    /// and decodes what they complete; the rest stays.
    fn flush_prefix(&mut self, len: usize) -> Vec<Heard<'c>> {
        if len == 0 || self.burst.is_empty() {
            return Vec::new();
        }
        let len = len.min(self.burst.len());
        let rest = self.burst.split_off(len);
        let rest_times = self.times.split_off(len);
        let burst = std::mem::replace(&mut self.burst, rest);
        let times = std::mem::replace(&mut self.times, rest_times);
        let start = self.burst_start;
        self.burst_start += burst.len();
        let found = self.scanner.feed_burst(&burst, start);
        let time_of = |f: &Framed| frame_time(&times, f.place.offset.checked_sub(start)?, f.bytes.len());
        let mut heard = Vec::new();
        for found in found {
            let (first, reply) = match &found {
                // A request from an earlier burst is the one that was pending.
                Found::Pair { request, reply, .. } => {
                    (time_of(request).or_else(|| self.pending.take()), reply.as_ref().and_then(time_of))
                }
                Found::Lone(f) | Found::Noise(f) => (time_of(f), None),
                Found::Unreadable { .. } => (None, None),
            };
            heard.push(self.hear(found, first, reply));
        }
        // The request left waiting, if it came in this burst: its times, for the reply's latency.
        if let Some(request) = self.scanner.pending_request().and_then(time_of) {
            self.pending = Some(request);
        }
        heard
    }

    /// Decodes what was found, with its times and flags.
    fn hear(&mut self, found: Found<'c>, first: Option<FrameTime>, reply: Option<FrameTime>) -> Heard<'c> {
        let is_frame = matches!(found, Found::Pair { .. } | Found::Lone(_));
        let begins = first.or(reply).map(|t| t.first);
        let gap_before = begins.zip(self.last_frame_end).map(|(begins, end)| begins.saturating_sub(end));
        if is_frame && let Some(end) = reply.or(first).map(|t| t.last) {
            self.last_frame_end = Some(self.last_frame_end.map_or(end, |last| last.max(end)));
        }
        let latency = first.zip(reply).map(|(request, reply)| reply.first.saturating_sub(request.last));
        let silence = self.timing.silence;
        let mut flags = Vec::new();
        match &found {
            Found::Pair { .. } => {
                if let Some(gap) = first.map(|t| t.longest_gap).filter(|gap| *gap >= silence) {
                    flags.push(Flag::GapInRequest(gap));
                }
                if let Some(gap) = reply.map(|t| t.longest_gap).filter(|gap| *gap >= silence) {
                    flags.push(Flag::GapInReply(gap));
                }
            }
            Found::Lone(_) => {
                if let Some(gap) = first.map(|t| t.longest_gap).filter(|gap| *gap >= silence) {
                    flags.push(Flag::GapInReply(gap));
                }
            }
            Found::Noise(_) | Found::Unreadable { .. } => {}
        }
        if let Some(latency) = latency.filter(|latency| *latency > self.timing.reply_timeout) {
            flags.push(Flag::LateReply(latency));
        }
        let report = self.decode(found);
        Heard { report, first, reply, gap_before, latency, flags }
    }

    /// Decodes as the sensor the slave has shown itself to be, when one
    /// alone explains its traffic; learns from the result.
    fn decode(&mut self, found: Found<'c>) -> Report<'c> {
        let slave = match &found {
            Found::Pair { header, .. } => Some(header.slave),
            Found::Lone(f) => f.bytes.first().copied(),
            Found::Noise(_) | Found::Unreadable { .. } => None,
        }
        .filter(|slave| *slave != 0);
        let chosen = slave.and_then(|s| self.learned.get(&s)).and_then(|l| l.chosen.as_ref());
        // Kept to decode again should this exchange itself name the sensor.
        let undecided = chosen.is_none().then(|| found.clone());
        let report = match chosen {
            Some(chosen) => {
                let as_chosen = exchange::report(chosen, found.clone());
                if as_chosen.status().ok() {
                    as_chosen
                } else {
                    // Not the sensor it seemed: learn again from everything.
                    if let Some(slave) = slave {
                        self.learned.remove(&slave);
                    }
                    exchange::report(self.commands, found)
                }
            }
            None => exchange::report(self.commands, found),
        };
        if let (Some(slave), Report::Exchange(x)) = (slave, &report)
            && matches!(x.status, Status::Decoded | Status::Ambiguous)
        {
            let by_code = self.hear_serial_number(slave, x);
            if self.commands.sensor.is_none() {
                let named = by_code.is_some();
                let sensors = by_code.unwrap_or_else(|| {
                    let mut sensors: Vec<&'c str> =
                        x.decodings.iter().flat_map(|d| d.cands.iter().map(|c| c.sensor)).collect();
                    sensors.sort_unstable();
                    sensors.dedup();
                    sensors
                });
                self.learn(slave, sensors);
                // A serial number that names the sensor: its own reply is shown as that sensor's.
                if named
                    && let (Some(found), Some(chosen)) =
                        (undecided, self.learned.get(&slave).and_then(|l| l.chosen.as_ref()))
                {
                    return exchange::report(chosen, found);
                }
            }
        }
        report
    }

    /// Keeps the serial number and model code of a serial-number reply in
    /// `x`; returns the sensors among its decodings that declare that code,
    /// when some do.
    fn hear_serial_number(&mut self, slave: u8, x: &Exchange<'c>) -> Option<Vec<&'c str>> {
        let reply = x.reply.as_ref()?;
        let mut heard = None;
        let mut by_code: Vec<&'c str> = Vec::new();
        for decoding in &x.decodings {
            let Some(command) = decoding.command().filter(|c| c.role == Some(Role::SerialNumber)) else { continue };
            let Ok(data) = command.layout().decode_response(slave, &reply.bytes) else { continue };
            let sensors: Vec<_> = decoding.cands.iter().filter_map(|c| self.commands.sensor_named(c.sensor)).collect();
            let read = SerialNumberReply::read(command, data);
            let code = read.model_code(|c| sensors.iter().any(|s| s.declares_model_code(c))).map(str::to_owned);
            if let Some(code) = &code {
                by_code.extend(sensors.iter().filter(|s| s.declares_model_code(code)).map(|s| s.name.as_str()));
            }
            // The reading that names a sensor is the one shown, else the first.
            if heard.is_none() || code.as_deref().is_some_and(|c| sensors.iter().any(|s| s.declares_model_code(c))) {
                heard = Some(Serial { number: read.text, model_code: code });
            }
        }
        self.serials.insert(slave, heard?);
        by_code.sort_unstable();
        by_code.dedup();
        (!by_code.is_empty()).then_some(by_code)
    }

    /// `sensors` explain the latest exchange with `slave`.
    fn learn(&mut self, slave: u8, sensors: Vec<&'c str>) {
        let before = self.learned.remove(&slave).map(|l| l.sensors).unwrap_or_default();
        let both: Vec<&'c str> = before.iter().copied().filter(|s| sensors.contains(s)).collect();
        let sensors = if both.is_empty() { sensors } else { both };
        let chosen = match sensors.as_slice() {
            [one] => Some(Commands {
                sensors: self.commands.sensors.clone(),
                all: self.commands.all.clone(),
                sensor: Some(one),
                command: self.commands.command.clone(),
            }),
            _ => None,
        };
        self.learned.insert(slave, Learned { sensors, chosen });
    }

    /// What each slave heard has shown itself to be: the sensor, where one
    /// alone explains its traffic, and the serial number it sent; slaves of
    /// which neither is known are left out.
    pub fn identified(&self) -> Vec<Identity<'c>> {
        let mut slaves: Vec<u8> = self.learned.keys().chain(self.serials.keys()).copied().collect();
        slaves.sort_unstable();
        slaves.dedup();
        slaves
            .into_iter()
            .filter_map(|slave| {
                let sensor = self.learned.get(&slave).and_then(|l| match l.sensors.as_slice() {
                    [one] => Some(*one),
                    _ => None,
                });
                let serial = self.serials.get(&slave);
                (sensor.is_some() || serial.is_some()).then(|| Identity {
                    slave,
                    sensor,
                    serial_number: serial.and_then(|s| s.number.clone()),
                    model_code: serial.and_then(|s| s.model_code.clone()),
                })
            })
            .collect()
    }
}

/// When the `len` bytes at `at` in a burst arrived.
fn frame_time(times: &[Duration], at: usize, len: usize) -> Option<FrameTime> {
    let bytes = times.get(at..at.checked_add(len)?)?;
    let (&first, &last) = (bytes.first()?, bytes.last()?);
    let longest_gap =
        bytes.iter().zip(bytes.iter().skip(1)).map(|(a, b)| b.saturating_sub(*a)).max().unwrap_or_default();
    Some(FrameTime { first, last, longest_gap })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{Explanation, explain};
    use yosemitech_rtu::CharFormat;
    use yosemitech_spec::Spec;

    const TIMEOUT: Duration = Duration::from_millis(500);

    /// The built-in spec, loaded once for the property's many cases.
    fn catalog() -> &'static Spec {
        yosemitech_tests::spec()
    }

    fn timing() -> Timing {
        Timing::of_line(LineTiming::new(9600, CharFormat::EIGHT_N_1), TIMEOUT)
    }

    /// Every printed example with a request and a reply, with its sensor.
    fn exchanges(catalog: &Spec) -> Vec<(String, Vec<u8>, Vec<u8>)> {
        let mut all = Vec::new();
        for sensor in &catalog.sensors {
            for c in &sensor.commands {
                for e in &c.examples {
                    if let (Some(request), Some(reply)) = (e.true_request(), e.true_response()) {
                        all.push((format!("{} {}", sensor.name, c.name), request.to_vec(), reply.to_vec()));
                    }
                }
            }
        }
        all
    }

    fn exchange<'h, 'c>(h: &'h Heard<'c>) -> &'h exchange::Exchange<'c> {
        match &h.report {
            Report::Exchange(x) => x,
            _ => panic!("not an exchange: {:?}", h.report.status()),
        }
    }

    /// Hands `frame` over from `start` (whole, or a byte at a time, one
    /// character apart): what is heard, and when its last byte came.
    fn send<'c>(
        sniffer: &mut Sniffer<'_, 'c>,
        byte_by_byte: bool,
        start: Duration,
        frame: &[u8],
    ) -> (Vec<Heard<'c>>, Duration) {
        let char_time = sniffer.timing().char_time;
        let end = start + char_time * u32::try_from(frame.len() - 1).unwrap();
        if !byte_by_byte {
            return (sniffer.push(end, frame), end);
        }
        let mut heard = Vec::new();
        for (i, byte) in frame.iter().enumerate() {
            heard.extend(sniffer.push(start + char_time * u32::try_from(i).unwrap(), &[*byte]));
        }
        (heard, end)
    }

    /// Hears every printed exchange, `byte_by_byte` handing the bytes over
    /// (one chunk per frame, or one per byte), with `latency` before each
    /// reply and a second of quiet between exchanges: each is heard once,
    /// as its two frames, decoded as `decode` decodes the pair (or narrowed
    /// to fewer sensors once the slave's traffic shows which it is), with
    /// the latency it was given.
    fn hear_every_example(byte_by_byte: bool, latency: Duration) {
        let catalog = catalog();
        let commands = Commands::new(&catalog.sensors);
        let timing = timing();
        for (what, request, reply) in exchanges(catalog) {
            let mut sniffer = Sniffer::new(&commands, timing);
            let (mut heard, request_end) = send(&mut sniffer, byte_by_byte, Duration::from_secs(1), &request);
            let (more, reply_end) = send(&mut sniffer, byte_by_byte, request_end + latency, &reply);
            heard.extend(more);
            heard.extend(sniffer.tick(reply_end + Duration::from_secs(1)));
            heard.extend(sniffer.finish());
            assert_eq!(heard.len(), 1, "{what}: one entry");
            let x = exchange(&heard[0]);
            assert_eq!(x.request.as_ref().map(|(f, _)| f.bytes.as_slice()), Some(request.as_slice()), "{what}");
            assert_eq!(x.reply.as_ref().map(|f| f.bytes.as_slice()), Some(reply.as_slice()), "{what}");
            let offline = match explain(&commands, &[request.clone(), reply.clone()].concat()) {
                Explanation::Exchange(offline) => offline,
                _ => panic!("{what}: decode does not see one exchange"),
            };
            assert_eq!(x.status.ok(), offline.status.ok(), "{what}: {:?} against {:?}", x.status, offline.status);
            let latency_heard = heard[0].latency.unwrap();
            let error = latency_heard.abs_diff(latency);
            assert!(error <= timing.char_time, "{what}: latency {latency_heard:?}, sent {latency:?}");
            assert!(heard[0].flags.is_empty() || latency > timing.silence, "{what}: {:?}", heard[0].flags);
        }
    }

    #[test]
    fn every_printed_exchange_is_heard_once_from_whole_frames() {
        hear_every_example(false, Duration::from_millis(40));
    }

    #[test]
    fn every_printed_exchange_is_heard_once_byte_by_byte_and_back_to_back() {
        // A reply starting one character after its request: no silence to frame by.
        hear_every_example(true, timing().char_time);
    }

    /// A frame handed over in two pieces with a silence between them is
    /// still one frame, flagged; a reply past the timeout is flagged late;
    /// one past the wait for it is a request with no reply and a lone reply.
    /// A master polling back to back at 115200 baud, never quiet for a
    /// silence: exchanges are heard as they go (not all at the end), each
    /// once and whole.
    #[test]
    fn a_line_never_quiet_is_heard_as_it_goes() {
        let catalog = catalog();
        let commands = Commands::new(&catalog.sensors);
        let line = LineTiming::new(115_200, CharFormat::EIGHT_N_1);
        let mut sniffer = Sniffer::new(&commands, Timing::of_line(line, TIMEOUT));
        let all = exchanges(catalog);
        let (mut now, mut heard, mut heard_before_the_end) = (Duration::ZERO, Vec::new(), 0);
        for (_, request, reply) in all.iter().cycle().take(all.len() * 3) {
            for frame in [request, reply] {
                now += line.t3_5() + line.char_time() * u32::try_from(frame.len()).unwrap();
                heard.extend(sniffer.push(now, frame));
            }
            heard_before_the_end = heard.len();
        }
        heard.extend(sniffer.finish());
        assert!(heard_before_the_end > 0, "nothing heard until the line went quiet");
        assert_eq!(heard.len(), all.len() * 3, "each exchange once");
        for (h, (what, request, reply)) in heard.iter().zip(all.iter().cycle()) {
            let x = exchange(h);
            assert_eq!(x.request.as_ref().map(|(f, _)| f.bytes.as_slice()), Some(request.as_slice()), "{what}");
            assert_eq!(x.reply.as_ref().map(|f| f.bytes.as_slice()), Some(reply.as_slice()), "{what}");
        }
    }

    /// A serial-number reply as a probe of each sensor with a model code
    /// sends it (`YL<code>...`): the slave is known by its serial number and
    /// code, and as the sensor when that code is the sensor's alone.
    #[test]
    fn an_overheard_serial_number_identifies_the_slave() {
        let catalog = catalog();
        let commands = Commands::new(&catalog.sensors);
        let mut heard_any = false;
        for s in &catalog.sensors {
            let (Some(command), Some(code)) = (s.command_with_role(Role::SerialNumber), &s.model_code) else {
                continue;
            };
            let Some(field) =
                command.named_fields().find(|f| matches!(f.kind, yosemitech_spec::FieldKind::Ascii { .. }))
            else {
                continue;
            };
            let slave = command.fixed_slave.unwrap_or(7);
            let sn = format!("YL{code}14010022");
            let values = std::collections::BTreeMap::from([(
                field.display_name().to_owned(),
                yosemitech_spec::Value::Text(sn.clone()),
            )]);
            let request = command.encode_request(slave, &std::collections::BTreeMap::new()).unwrap();
            let reply = command.encode_response(slave, &values).unwrap();
            let mut sniffer = Sniffer::new(&commands, timing());
            let (mut heard, request_end) = send(&mut sniffer, false, Duration::from_secs(1), &request);
            let (more, reply_end) = send(&mut sniffer, false, request_end + Duration::from_millis(20), &reply);
            heard.extend(more);
            heard.extend(sniffer.tick(reply_end + Duration::from_secs(1)));
            assert_eq!(heard.len(), 1, "{}: one exchange", s.name);
            let identified = sniffer.identified();
            let identity = identified.iter().find(|i| i.slave == slave).expect("the slave is known");
            assert_eq!(identity.serial_number.as_deref(), Some(sn.as_str()), "{}", s.name);
            assert_eq!(identity.model_code.as_deref(), Some(code.as_str()), "{}", s.name);
            let declaring: Vec<&str> =
                catalog.sensors.iter().filter(|x| x.declares_model_code(code)).map(|x| x.name.as_str()).collect();
            if let Some(sensor) = identity.sensor {
                assert!(declaring.contains(&sensor), "{}: {sensor} does not declare model code {code}", s.name);
            }
            if declaring == [s.name.as_str()] {
                assert_eq!(identity.sensor, Some(s.name.as_str()), "{}: model code {code} is its alone", s.name);
                // The reply that names it is shown as its own.
                let sensors: Vec<&str> = exchange(&heard[0]).decodings.iter().flat_map(|d| d.sensors()).collect();
                assert_eq!(sensors, [s.name.as_str()], "{}", s.name);
            }
            heard_any = true;
        }
        assert!(heard_any || catalog.sensors.iter().all(|s| s.model_code.is_none()));
    }

    #[test]
    fn split_frames_late_and_missing_replies_are_flagged() {
        let catalog = catalog();
        let commands = Commands::new(&catalog.sensors);
        let timing = timing();
        let (what, request, reply) = exchanges(catalog).into_iter().next().expect("the spec prints an exchange");
        let ms = Duration::from_millis;

        let mut sniffer = Sniffer::new(&commands, timing);
        let mut heard = sniffer.push(ms(1000), &request);
        let (head, tail) = reply.split_at(reply.len() / 2);
        let gap = (timing.silence + timing.split_wait) / 2;
        heard.extend(sniffer.push(ms(1040), head));
        heard.extend(sniffer.push(ms(1040) + gap, tail));
        heard.extend(sniffer.finish());
        assert_eq!(heard.len(), 1, "{what}");
        assert!(
            matches!(heard[0].flags.as_slice(), [Flag::GapInReply(g)] if g.abs_diff(gap) <= timing.char_time * 8),
            "{what}: {:?}",
            heard[0].flags
        );
        assert_eq!(exchange(&heard[0]).reply.as_ref().map(|f| f.bytes.clone()), Some(reply.clone()));

        let late = TIMEOUT + ms(100);
        let mut sniffer = Sniffer::new(&commands, timing);
        let mut heard = sniffer.push(ms(1000), &request);
        heard.extend(sniffer.tick(ms(1000) + late / 2));
        heard.extend(sniffer.push(ms(1000) + late, &reply));
        heard.extend(sniffer.finish());
        assert_eq!(heard.len(), 1, "{what}");
        assert!(matches!(heard[0].flags.as_slice(), [Flag::LateReply(_)]), "{what}: {:?}", heard[0].flags);

        let mut sniffer = Sniffer::new(&commands, timing);
        let mut heard = sniffer.push(ms(1000), &request);
        heard.extend(sniffer.tick(ms(1000) + timing.give_up + ms(1)));
        assert_eq!(heard.len(), 1, "{what}: the wait is over");
        assert_eq!(exchange(&heard[0]).status, Status::NoReply);
        heard.extend(sniffer.push(ms(1000) + timing.give_up + ms(10), &reply));
        heard.extend(sniffer.finish());
        assert_eq!(heard.len(), 2, "{what}");
        assert_eq!(exchange(&heard[1]).status, Status::Unpaired);
    }

    proptest::proptest! {
        /// Any bytes in any chunks at any times: no panic, and every byte
        /// heard is in exactly one entry, in order.
        #[test]
        fn every_byte_is_heard_once_in_order(
            chunks in proptest::collection::vec(
                (0u64..3_000_000, proptest::collection::vec(proptest::prelude::any::<u8>(), 1..40)),
                0..30,
            ),
            seed in proptest::prelude::any::<usize>(),
        ) {
            let catalog = catalog();
            let commands = Commands::new(&catalog.sensors);
            // Some chunks are printed frames, so that exchanges are heard too.
            let examples = exchanges(catalog);
            let mut sniffer = Sniffer::new(&commands, timing());
            let mut at = Duration::ZERO;
            let mut sent = Vec::new();
            let mut heard = Vec::new();
            for (i, (micros, bytes)) in chunks.into_iter().enumerate() {
                at += Duration::from_micros(micros);
                let bytes = match examples.get(seed.wrapping_add(i) % examples.len().max(1)) {
                    Some((_, request, reply)) if micros % 3 == 0 => [request.clone(), reply.clone()].concat(),
                    _ => bytes,
                };
                sent.extend_from_slice(&bytes);
                heard.extend(sniffer.push(at, &bytes));
            }
            heard.extend(sniffer.finish());
            let mut entries: Vec<(usize, Vec<u8>)> = Vec::new();
            for h in &heard {
                match &h.report {
                    Report::Exchange(x) => {
                        entries.extend(x.request.iter().map(|(f, _)| (f.place.offset, f.bytes.clone())));
                        entries.extend(x.reply.iter().map(|f| (f.place.offset, f.bytes.clone())));
                    }
                    Report::Noise(f) => entries.push((f.place.offset, f.bytes.clone())),
                    Report::Unreadable { .. } => {}
                }
            }
            entries.sort();
            let joined: Vec<u8> = entries.into_iter().flat_map(|(_, bytes)| bytes).collect();
            proptest::prop_assert_eq!(joined, sent);
        }
    }
}
