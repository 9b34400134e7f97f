//! What the `yosemitech` device tests (`cli_demo`, `cli_read`, `cli_scan`
//! and the rest) share: short timeouts, the text the binary shows for a
//! value, what `scan` sends and says of a probe, coefficient edits on a
//! simulated probe, and a read the simulator answers as its manual states.
#![cfg(unix)]

use std::sync::Arc;

use yosemitech_sim::Simulator;
use yosemitech_spec::{CommandSpec, Field, FieldKind, Role, Sensor, Value};
use yosemitech_tests::cli::{Sim, number_after};
use yosemitech_tests::values::varied_float;
use yosemitech_tests::{report, spec};

/// Short timeouts for requests that are meant to fail.
pub const FAST: [&str; 4] = ["--timeout", "150ms", "--retries", "0"];

pub fn float(sim: &yosemitech_tests::cli::Sim<yosemitech_sim::Simulator>, command: &str, field: &str) -> f32 {
    match sim.server.device().get(command, field).unwrap() {
        Value::Float(v) => v,
        other => panic!("{command}.{field} is {other:?}"),
    }
}

/// The number `demo` or `measure` shows for `field` of `read` in `text`:
/// on the line labelled with the field's name, or `read.field` where two
/// reads share the name.
pub fn shown_number(text: &str, read: &str, field: &str) -> f64 {
    let qualified = format!("{read}.{field}");
    let label = if text.lines().any(|l| l.trim_start().starts_with(&format!("{qualified} "))) {
        qualified
    } else {
        format!("{field} ")
    };
    number_after(text, &label)
}

/// The serial-number request `scan` sends to a probe of `sensor` (its
/// serial-number read at its own address), as function, address and count.
pub fn sn_request(sensor: &Sensor) -> Option<(u8, u16, u16)> {
    sensor
        .command_with_role(Role::SerialNumber)
        .filter(|c| c.fixed_slave.is_none())
        .map(|c| (c.function.code(), c.address, c.count))
}

/// The loaded sensors (the spec's, in spec order) `scan` names for a probe
/// of `sensor` that sends model code `code`: those that send the same
/// serial-number request and declare that code.
pub fn declaring(sensor: &Sensor, code: &str) -> Vec<Sensor> {
    let request = sn_request(sensor);
    spec()
        .sensors
        .iter()
        .filter(|s| request.is_some() && sn_request(s) == request && s.declares_model_code(code))
        .cloned()
        .collect()
}

/// A sensor as `scan` names it: `name (model, code 09)`.
pub fn sensor_text(sensor: &Sensor) -> String {
    let about: Vec<String> =
        sensor.model.iter().cloned().chain(sensor.model_code.iter().map(|c| format!("code {c}"))).collect();
    if about.is_empty() { sensor.name.clone() } else { format!("{} ({})", sensor.name, about.join(", ")) }
}

/// What `scan` says of a probe of `sensor` sending its own model code
/// `code` and serial number `sn`: the sensor alone, or, where other loaded
/// sensors send the same request and declare the same code, every one of
/// them and why (`None`: identified alone).
pub fn scan_says(sensor: &Sensor, code: &str, sn: &str) -> (String, Option<Vec<Sensor>>) {
    let twins = declaring(sensor, code);
    assert!(twins.iter().any(|t| t.name == sensor.name), "{} declares {code}", sensor.name);
    let refs: Vec<&Sensor> = twins.iter().collect();
    if twins.len() == 1 || yosemitech_cli::scan_tells_apart(&refs) {
        return (format!("SN {sn}  {}", sensor_text(sensor)), None);
    }
    let (_, address, _) = sn_request(sensor).unwrap();
    let names: Vec<String> = twins.iter().map(sensor_text).collect();
    let line = format!(
        "SN {sn}  not identified: one of {} ({} loaded sensors read their serial number at 0x{address:04X} and declare model code {code})",
        names.join(", "),
        twins.len()
    );
    (line, Some(twins))
}

/// The example of `command` in the sensor's own manual, with values.
pub fn stated_example(command: &CommandSpec) -> Option<&yosemitech_spec::Example> {
    command.examples.iter().find(|e| e.manual.is_none() && e.erratum.is_none() && !e.values.is_empty())
}

/// `value unit` as `read` shows a field: the unit as the CLI shows it.
pub fn shown(value: &Value, unit: Option<&str>) -> String {
    let value = match value {
        Value::Float(f) => f.to_string(),
        Value::Int(i) => i.to_string(),
        Value::Text(t) => t.clone(),
        other => panic!("{other:?}"),
    };
    unit.map_or(value.clone(), |u| format!("{value} {}", yosemitech_cli::shown_unit(u)))
}

/// An address other than `address`: where no simulated probe is.
pub fn elsewhere(address: u8) -> u8 {
    if address == 9 { 10 } else { 9 }
}

/// A read of another sensor at registers `sensor` lacks, sent to its own
/// address: a command the probe does not have.
pub fn foreign_read(sensor: &Sensor, trigger: bool) -> Option<(Sensor, CommandSpec)> {
    spec().sensors.iter().flat_map(|o| o.commands.iter().map(move |c| (o, c))).find_map(|(o, c)| {
        (c.is_read()
            && (trigger || !c.trigger)
            && c.fixed_slave.is_none()
            && !sensor.commands.iter().any(|m| m.function == c.function && m.address == c.address))
        .then(|| (o.clone(), c.clone()))
    })
}

/// An address for a probe to move to, none of `taken`: inside the range of
/// the address write's field, near its middle.
pub fn new_address(set: &CommandSpec, taken: &[u8]) -> u8 {
    let (min, max) = set.named_fields().next().and_then(|f| f.range).unwrap_or((1.0, 247.0));
    let (min, max) = (min.max(1.0) as u8, max.min(247.0) as u8);
    let middle = min + (max - min) / 2;
    (middle..=max).chain(min..middle).find(|a| !taken.contains(a)).expect("a free address in the write's range")
}

/// The columns `poll` shows for `sensor` by default: (read, field, column
/// name) of every measurement, taken from the read the station planner
/// picks for it (the fewest reads that cover every measurement).
pub fn poll_columns(sensor: &Sensor) -> Vec<(String, String, String)> {
    let chosen = yosemitech_station::plan::measurements(sensor);
    yosemitech_station::plan::plan(sensor, &chosen)
        .reads
        .iter()
        .flat_map(|r| r.fields.iter().map(|f| (r.command.name.clone(), (*f).to_owned(), (*f).to_owned())))
        .collect()
}

/// The field a restore writes for coefficient `field` of `read`: the
/// block's write's (whose range bounds the value), else the read's.
pub fn coefficient_field<'s>(sensor: &'s Sensor, read: &str, field: &str) -> &'s Field {
    let blocks = sensor.coefficient_blocks();
    let (write, read) = blocks.iter().find(|(_, r)| r.name == read).unwrap_or_else(|| panic!("no block read {read}"));
    write.field(field).or_else(|| read.field(field)).unwrap_or_else(|| panic!("{}: no field {field}", read.name))
}

/// A float inside `field`'s range unlike `old`: the first of the test kit's
/// varied values, from the `i`-th on, that differs.
pub fn another_float(field: &Field, i: usize, old: f32) -> f32 {
    (i..i + 8).map(|j| varied_float(field, j)).find(|v| v.to_bits() != old.to_bits()).unwrap()
}

/// Every coefficient the simulated probe holds, as (read, field, value)
/// over its sensor's coefficient blocks.
pub fn coefficients(s: &Sim<Simulator>, sensor: &Sensor) -> Vec<(String, String, f32)> {
    sensor
        .coefficient_blocks()
        .iter()
        .flat_map(|(_, r)| r.named_fields().map(|f| (r.name.clone(), f.display_name().to_owned())).collect::<Vec<_>>())
        .map(|(c, f)| {
            let v = float(s, &c, &f);
            (c, f, v)
        })
        .collect()
}

/// Sets each of `coefficients` on the probe to another value inside its
/// range (from the kit's `base`-th varied value on); returns what it set.
pub fn overwrite(
    s: &Sim<Simulator>,
    sensor: &Sensor,
    coefficients: &[(String, String, f32)],
    base: usize,
) -> Vec<(String, String, f32)> {
    coefficients
        .iter()
        .enumerate()
        .map(|(i, (c, f, old))| {
            let value = another_float(coefficient_field(sensor, c, f), base + i, *old);
            s.server.device().set(c, f, Value::Float(value)).unwrap();
            (c.clone(), f.clone(), value)
        })
        .collect()
}

/// The sensor `calibrate ph` drives, as the tool says.
pub fn calibrated_sensor() -> Sensor {
    yosemitech_tests::sensor(yosemitech_cli::calibrate_ph_sensor())
}

/// The serial number a simulated probe of `sensor` sends (`None`: its spec
/// has no serial-number read), as the simulator serves it before anything
/// is set.
pub fn served_serial_number(sensor: &Sensor) -> Option<String> {
    let command = sensor.command_with_role(Role::SerialNumber)?;
    let field = command.named_fields().find(|f| matches!(f.kind, FieldKind::Ascii { .. }))?;
    match Simulator::new(Arc::new(sensor.clone())).get(&command.name, field.display_name()) {
        Ok(Value::Text(text)) => Some(text),
        _ => None,
    }
}

/// The serial-number read of `sensor` and its text field.
pub fn sn_field(sensor: &Sensor) -> (&CommandSpec, &Field) {
    let command = sensor.command_with_role(Role::SerialNumber).unwrap();
    let field = command.named_fields().find(|f| matches!(f.kind, FieldKind::Ascii { .. })).unwrap();
    (command, field)
}

/// The sensors `scan` can identify: a serial-number read at the probe's
/// own address with a text field, and a model code.
pub fn identifiable() -> Vec<Sensor> {
    spec()
        .sensors
        .iter()
        .filter(|&s| {
            s.model_code.is_some()
                && sn_request(s).is_some()
                && s.command_with_role(Role::SerialNumber)
                    .is_some_and(|c| c.named_fields().any(|f| matches!(f.kind, FieldKind::Ascii { .. })))
        })
        .cloned()
        .collect()
}

/// The distinct serial-number requests of the spec: what `scan` may send
/// to an address before one is answered.
pub fn sn_layouts() -> usize {
    let mut requests: Vec<(u8, u16, u16)> = spec().sensors.iter().filter_map(sn_request).collect();
    requests.sort_unstable();
    requests.dedup();
    requests.len()
}

/// `yosemitech simulate` in a child process: the port it prints, and a clean
/// stop on Ctrl-C.
/// The sensor, the read, its true request and reply, and the line `read` shows.
pub type StatedRead = (Sensor, CommandSpec, Vec<u8>, Vec<u8>, String);

/// A measurement read whose example (in the sensor's own manual) the
/// simulator answers: the sensor, the read, the true request and reply,
/// and the line `read` shows for its one f32 field (`name  value unit`).
/// The example's frames go to the sensor's factory address, where the
/// simulator serves it.
pub fn stated_read() -> Option<StatedRead> {
    for sensor in spec().sensors.clone() {
        let device = Simulator::new(Arc::new(sensor.clone()));
        for command in sensor.commands.iter().filter(|c| c.is_read() && c.role.is_none() && c.fixed_slave.is_none()) {
            let mut named = command.named_fields();
            let (Some(field), None) = (named.next(), named.next()) else { continue };
            if !matches!(field.kind, FieldKind::F32 { .. }) || field.unit.is_none() {
                continue;
            }
            let Some(example) = stated_example(command) else { continue };
            let (Some((request, reply)), Some(value)) = (example.true_pair(), example.values.get(field.display_name()))
            else {
                continue;
            };
            if example.slave() != sensor.default_address
                || !device.get(&command.name, field.display_name()).is_ok_and(|v| v.same_as(value))
            {
                continue;
            }
            let line = format!("{}  {}", field.display_name(), shown(value, field.unit.as_deref()));
            return Some((sensor.clone(), command.clone(), request.to_vec(), reply.to_vec(), line));
        }
    }
    report!("no measurement read of the spec has a stated example the simulator answers");
    None
}

/// `yosemitech poll` (CSV, every 50 ms) running against a simulated probe of
/// the first sensor of the spec that has a measurement, past its header and
/// first data row: the simulator, the child and its output. `None` when no
/// sensor has a measurement.
pub fn polling(
    binary: yosemitech_tests::cli::Binary,
) -> Option<(Sim<Simulator>, std::process::Child, std::io::BufReader<std::process::ChildStdout>, String)> {
    use std::io::BufRead as _;
    let sensor = spec().sensors.iter().find(|&s| !poll_columns(s).is_empty())?;
    let s = yosemitech_tests::cli::sim(&sensor.name, sensor.default_address);
    let mut child = binary
        .command()
        .args(["poll", &sensor.name, "-p", &s.path, "--interval", "50ms", "--format", "csv"])
        .stdin(std::process::Stdio::null())
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let mut stdout = std::io::BufReader::new(child.stdout.take().unwrap());
    let mut line = String::new();
    for _ in 0..3 {
        line.clear();
        stdout.read_line(&mut line).unwrap();
    }
    Some((s, child, stdout, line))
}
