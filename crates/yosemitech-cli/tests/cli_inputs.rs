//! `--input NAME=VALUE`: the station inputs of derived quantities given on
//! the command line of `read`, `poll` and `measure`, against simulated
//! probes on pseudo-terminals. Sensors, reads and inputs are picked by
//! role from the spec: every sensor with a derived quantity that takes a
//! station input, every station input of it.
#![cfg(unix)]

use yosemitech_spec::beside::station_inputs;
use yosemitech_spec::{Derived, InputSource, Sensor, Value};
use yosemitech_tests::cli::{Binary, Sim, sim};
use yosemitech_tests::{report, spec};

const YOSEMITECH: Binary = Binary(env!("CARGO_BIN_EXE_yosemitech"));

/// A value of a station input the spec accepts that is not its default:
/// inside every range a quantity of `sensor` declares for it.
fn other_value(sensor: &Sensor, name: &str) -> f64 {
    let inputs = station_inputs(sensor);
    let input = inputs.iter().find(|s| s.name == name).expect("a station input of the sensor");
    let (mut min, mut max) = (f64::NEG_INFINITY, f64::INFINITY);
    for (_, i) in &input.uses {
        if let Some((lo, hi)) = i.range {
            min = min.max(lo);
            max = max.min(hi);
        }
    }
    let default = input.uses.iter().find_map(|(_, i)| i.default);
    let candidates =
        [(min.is_finite() && max.is_finite()).then_some(min + (max - min) * 0.37), default.map(|d| d + 1.0), Some(1.0)];
    candidates
        .into_iter()
        .flatten()
        .find(|v| Some(*v) != default && *v >= min && *v <= max)
        .expect("a value other than the default")
}

/// The lowest value some quantity of `sensor` refuses for station input `name`, if any is declared.
fn out_of_range(sensor: &Sensor, name: &str) -> Option<f64> {
    let inputs = station_inputs(sensor);
    let input = inputs.iter().find(|s| s.name == name)?;
    input.uses.iter().filter_map(|(_, i)| i.range).map(|(_, max)| max + 1.0).reduce(f64::min)
}

/// The reads of `sensor` that give every field input of `d`, when one read does.
fn single_read(d: &Derived) -> Option<String> {
    let mut reads = d.inputs.iter().filter_map(|i| match &i.source {
        InputSource::Field { command, .. } => Some(command.clone()),
        InputSource::Station(_) => None,
    });
    let first = reads.next()?;
    reads.all(|r| r == first).then_some(first)
}

/// What the interpreter computes for `d` from the simulator's values and `given` station inputs.
fn expected(sim: &Sim<yosemitech_sim::Simulator>, d: &Derived, given: &[(&str, f64)]) -> Result<f32, String> {
    let mut inputs = Vec::new();
    for i in &d.inputs {
        let v = match &i.source {
            InputSource::Field { command, field } => match sim.server.device().get(command, field) {
                Ok(Value::Float(v)) => f64::from(v),
                Ok(Value::Int(v)) => v as f64,
                other => return Err(format!("{command}.{field} is {other:?}")),
            },
            InputSource::Station(name) => given
                .iter()
                .find(|(n, _)| n == name)
                .map(|(_, v)| *v)
                .or(i.default)
                .ok_or_else(|| format!("no default for {name}"))?,
        };
        inputs.push(v as f32);
    }
    d.compute(&inputs).map_err(|e| e.to_string())
}

/// Every (sensor, quantity, its read) with a station input, the quantity's fields all from one read.
fn cases() -> Vec<(Sensor, Derived, String)> {
    let mut out = Vec::new();
    for sensor in &spec().sensors {
        for d in &sensor.derived {
            let takes_station = d.inputs.iter().any(|i| matches!(i.source, InputSource::Station(_)));
            if let (true, Some(read)) = (takes_station, single_read(d)) {
                out.push((sensor.clone(), d.clone(), read));
            }
        }
    }
    out
}

fn flags(given: &[(&str, f64)]) -> Vec<String> {
    given.iter().flat_map(|(n, v)| ["--input".to_owned(), format!("{n}={v}")]).collect()
}

#[test]
fn read_computes_derived_values_from_the_inputs_given() {
    let mut changed = 0;
    let mut checked = 0;
    for (sensor, d, read) in cases() {
        let s = sim(&sensor.name, sensor.default_address);
        let names: Vec<&str> = station_inputs(&sensor).iter().map(|i| i.name).collect();
        let at_defaults = expected(&s, &d, &[]);
        // Each station input alone, then all of them together.
        let mut sets: Vec<Vec<(&str, f64)>> = names.iter().map(|n| vec![(*n, other_value(&sensor, n))]).collect();
        sets.push(names.iter().map(|n| (*n, other_value(&sensor, n))).collect());
        for given in sets {
            let extra = flags(&given);
            let mut args = vec!["read", sensor.name.as_str(), read.as_str(), "-p", s.path.as_str()];
            args.extend(extra.iter().map(String::as_str));
            let json = YOSEMITECH.run(&[&args[..], &["--json"]].concat()).json();
            let want = expected(&s, &d, &given);
            let entry = &json["derived"][&d.name];
            match &want {
                Ok(v) => {
                    let got = entry["value"].as_f64().unwrap_or_else(|| panic!("{}: {json}", d.name));
                    assert_eq!((got as f32).to_bits(), v.to_bits(), "{} with {given:?}: {json}", d.name);
                }
                Err(_) => assert!(entry["error"].is_string(), "{} with {given:?}: {json}", d.name),
            }
            // The defaults JSON names exactly the station inputs not given.
            let defaults = entry["defaults"].as_object().unwrap_or_else(|| panic!("{json}"));
            for i in &d.inputs {
                let InputSource::Station(name) = &i.source else { continue };
                let was_given = given.iter().any(|(n, _)| n == name);
                assert_eq!(defaults.contains_key(name), !was_given, "{name}: {json}");
            }
            if want != at_defaults {
                changed += 1;
            }
            // Text: the value on the quantity's line; a note names the defaults assumed, and only those.
            let run = YOSEMITECH.run(&args);
            let out = run.ok();
            let line = out.lines().find(|l| l.starts_with(d.name.as_str())).unwrap_or_else(|| panic!("{out}"));
            assert!(line.ends_with("(derived)"), "{line}");
            if let Ok(v) = want {
                assert!(line.contains(&v.to_string()), "{line}, want {v}");
            }
            let note = out.lines().find(|l| l.starts_with("note: station inputs at the spec's default"));
            for name in &names {
                let defaulted = !given.iter().any(|(n, _)| n == name);
                assert_eq!(note.is_some_and(|n| n.contains(&format!("{name} = "))), defaulted, "{name}:\n{out}");
            }
            checked += 1;
        }
    }
    assert!(changed > 0 || checked == 0, "no --input changed a derived value");
    report!("read --input: {checked} runs checked, {changed} changed a derived value");
}

#[test]
fn poll_and_measure_take_inputs_too() {
    let mut checked = 0;
    for (sensor, d, read) in cases() {
        let s = sim(&sensor.name, sensor.default_address);
        let given: Vec<(&str, f64)> =
            station_inputs(&sensor).iter().map(|i| (i.name, other_value(&sensor, i.name))).collect();
        let extra = flags(&given);
        let want = expected(&s, &d, &given);
        let mut args =
            vec!["poll", sensor.name.as_str(), read.as_str(), "-p", &s.path, "-n", "1", "-i", "0", "-f", "json"];
        args.extend(extra.iter().map(String::as_str));
        let row: serde_json::Value = serde_json::from_str(YOSEMITECH.run(&args).ok().trim()).expect("a JSON row");
        match &want {
            Ok(v) => {
                let got = row["derived"][&d.name]["value"].as_f64().unwrap_or_else(|| panic!("{row}"));
                assert_eq!((got as f32).to_bits(), v.to_bits(), "poll {}: {row}", d.name);
            }
            Err(_) => assert!(row["derived"][&d.name]["error"].is_string(), "{row}"),
        }
        checked += 1;
        // measure, where the procedure reads the quantity's fields: one
        // reading, so that the mean is the value served.
        let Some(p) = &sensor.procedure else { continue };
        if !p.read.contains(&read) {
            continue;
        }
        let mut args = vec!["measure", sensor.name.as_str(), "-p", &s.path, "--fast", "--readings", "1", "--json"];
        args.extend(extra.iter().map(String::as_str));
        let json = YOSEMITECH.run(&args).json();
        match &want {
            Ok(v) => {
                let got = json["derived"][&d.name]["value"].as_f64().unwrap_or_else(|| panic!("{json}"));
                assert_eq!((got as f32).to_bits(), v.to_bits(), "measure {}: {json}", d.name);
            }
            Err(_) => assert!(json["derived"][&d.name]["error"].is_string(), "{json}"),
        }
        let mut args = vec!["measure", sensor.name.as_str(), "-p", &s.path, "--fast", "--readings", "1"];
        args.extend(extra.iter().map(String::as_str));
        let run = YOSEMITECH.run(&args);
        let out = run.ok();
        let line = out.lines().find(|l| l.trim_start().starts_with(d.name.as_str())).unwrap_or_else(|| panic!("{out}"));
        assert!(line.contains("derived"), "{line}");
        assert!(!out.contains("at the spec's default"), "every input was given:\n{out}");
        checked += 1;
    }
    report!("poll and measure --input: {checked} runs checked");
}

#[test]
fn a_bad_input_is_refused_before_anything_is_read() {
    let mut refused = 0;
    for sensor in &spec().sensors {
        let inputs = station_inputs(sensor);
        let Some(read) = sensor.measurement_reads().next() else { continue };
        // No port is opened for a refused input: a path that is no port proves it.
        let port = "/nonexistent/tty-for-a-refused-input";
        let unknown = YOSEMITECH.run(&["read", &sensor.name, &read.name, "-p", port, "--input", "no_such_input_q=1"]);
        let err = unknown.fails_with_hint(2);
        assert!(err.contains("no_such_input_q"), "{err}");
        if inputs.is_empty() {
            assert!(err.contains("takes no station input"), "{err}");
        } else {
            for i in &inputs {
                assert!(err.contains(i.name), "{} not named:\n{err}", i.name);
            }
        }
        refused += 1;
        for i in &inputs {
            for bad in [i.name.to_owned(), format!("{}=abc", i.name), format!("{}=NaN", i.name)] {
                let run = YOSEMITECH.run(&["read", &sensor.name, &read.name, "-p", port, "--input", &bad]);
                assert_eq!(run.code, 2, "{bad}: {run:?}");
                assert!(run.stderr.contains("error"), "{bad}: {}", run.stderr);
                refused += 1;
            }
            if let Some(v) = out_of_range(sensor, i.name) {
                let given = format!("{}={v}", i.name);
                for command in ["read", "poll", "measure"] {
                    let mut args = vec![command, sensor.name.as_str()];
                    if command == "read" {
                        args.push(&read.name);
                    }
                    args.extend(["-p", port, "--input", &given]);
                    let run = YOSEMITECH.run(&args);
                    if command == "measure" && sensor.procedure.is_none() {
                        continue;
                    }
                    let err = run.fails_with_hint(2);
                    assert!(err.contains(i.name) && err.contains("outside"), "{command} {given}: {err}");
                    refused += 1;
                }
            }
        }
    }
    assert!(refused > 0);
    report!("--input: {refused} bad inputs refused");
}
