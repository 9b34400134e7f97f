//! `read --unit` and `poll --unit` against simulated probes on ptys: the
//! value shown is the simulator's, converted by the unit table's factor,
//! with the new unit; misuse exits 2 before any port is opened. Fields are
//! picked by role ("a field whose unit has another unit of its dimension"),
//! never by name.
#![cfg(unix)]

use yosemitech_spec::units::{self, Conversion, UnitDef};
use yosemitech_spec::{CommandSpec, Field, FieldKind, Sensor, Value};
use yosemitech_tests::cli::{Binary, sim};
use yosemitech_tests::{report, spec};

/// The binary under test.
const YOSEMITECH: Binary = Binary(env!("CARGO_BIN_EXE_yosemitech"));

/// Another unit of the same dimension as `field`'s, if the table has one.
fn other_unit(field: &Field) -> Option<(&'static UnitDef, &'static UnitDef)> {
    let from = units::lookup(field.unit.as_deref()?)?;
    let to = units::UNITS.iter().find(|u| u.dimension == from.dimension && !std::ptr::eq(*u, from))?;
    Some((from, to))
}

/// A number field (not an enumeration or flags).
fn is_number(field: &Field) -> bool {
    !matches!(field.kind, FieldKind::Enum { .. } | FieldKind::Flags { .. } | FieldKind::Ascii { .. })
}

/// Each sensor's first measurement (as `poll` and the station choose
/// them) that is a number whose unit converts to another, with the read the
/// planner takes it from.
fn convertible_reads() -> Vec<(Sensor, CommandSpec, Field)> {
    let mut out = Vec::new();
    for sensor in &spec().sensors {
        let found = yosemitech_station::plan::measurements(sensor).into_iter().find_map(|name| {
            let planned = yosemitech_station::plan::plan(sensor, &[name]);
            let command = planned.reads.first()?.command;
            let field = command.field(name).filter(|f| is_number(f) && other_unit(f).is_some())?;
            Some((command.clone(), field.clone()))
        });
        if let Some((command, field)) = found {
            out.push((sensor.clone(), command, field));
        }
    }
    out
}

/// The number of a simulated value.
fn number(value: &Value) -> f64 {
    match value {
        Value::Float(v) => f64::from(*v),
        Value::Int(v) => *v as f64,
        other => panic!("not a number: {other:?}"),
    }
}

#[test]
fn read_unit_converts_the_served_value_by_the_tables_factor() {
    let reads = convertible_reads();
    assert!(!reads.is_empty(), "some field of the spec has a unit that converts");
    let mut checked = 0;
    for (sensor, command, field) in &reads {
        let (from, to) = other_unit(field).unwrap();
        let name = field.display_name();
        let s = sim(&sensor.name, sensor.default_address);
        let served = number(&s.server.device().get(&command.name, name).unwrap());
        let want = Conversion::between(from, to).unwrap().apply(served) as f32;
        // The conversion is not the identity here, or the test would prove nothing.
        assert!(
            served == 0.0 || want != served as f32,
            "{} {name}: {served} {} is {want} {}",
            sensor.name,
            from.symbol,
            to.symbol
        );
        // By name and by dimension alike.
        for choice in [format!("{name}={}", to.symbol), to.symbol.to_owned()] {
            let args = ["read", &sensor.name, &command.name, "-p", &s.path, "--unit", &choice];
            let json = YOSEMITECH.run(&[&args[..], &["--json"]].concat()).json();
            let got = json["values"][name].as_f64().unwrap_or_else(|| panic!("{json}"));
            assert_eq!((got as f32).to_bits(), want.to_bits(), "{} {name} --unit {choice}: {json}", sensor.name);
            let shown = json["fields"].as_array().unwrap().iter().find(|f| f["name"] == name).unwrap().clone();
            assert_eq!(shown["unit"], to.symbol, "{shown}");
            let text = YOSEMITECH.run(&args).ok().to_owned();
            let line = format!("{want} {}", yosemitech_cli::shown_unit(to.symbol));
            assert!(
                text.lines().any(|l| l.starts_with(name) && l.trim_end().ends_with(&line)),
                "`{name} ... {line}` in:\n{text}"
            );
        }
        // Without --unit, the spec's unit and the served value.
        let json = YOSEMITECH.run(&["read", &sensor.name, &command.name, "-p", &s.path, "--json"]).json();
        assert_eq!(json["values"][name].as_f64().map(|v| v as f32), Some(served as f32), "{json}");
        checked += 1;
    }
    report!("read --unit: {checked} fields converted by the table's factor, by name and by dimension");
}

#[test]
fn poll_unit_converts_csv_cells_and_names_the_unit() {
    let mut checked = 0;
    for (sensor, command, field) in convertible_reads() {
        let (from, to) = other_unit(&field).unwrap();
        let name = field.display_name();
        let s = sim(&sensor.name, sensor.default_address);
        let choice = format!("{name}={}", to.symbol);
        let args = ["poll", &sensor.name, name, "-p", &s.path, "-n", "1", "-i", "0", "-f", "csv", "--unit", &choice];
        let run = YOSEMITECH.run(&args);
        let out = run.ok();
        let lines: Vec<&str> = out.lines().collect();
        let head = format!("{name} [{}]", yosemitech_cli::shown_unit(to.symbol));
        let column = lines[0].split(',').position(|h| h == head).unwrap_or_else(|| panic!("`{head}` in {}", lines[0]));
        // `command` is the read poll plans for the field.
        let served = number(&s.server.device().get(&command.name, name).unwrap());
        let want = Conversion::between(from, to).unwrap().apply(served) as f32;
        assert_eq!(lines[1].split(',').nth(column), Some(want.to_string().as_str()), "{out}");
        let json = YOSEMITECH
            .run(&["poll", &sensor.name, name, "-p", &s.path, "-n", "1", "-i", "0", "-f", "json", "--unit", &choice])
            .json();
        assert_eq!(json["units"][name], to.symbol, "{json}");
        assert_eq!(json["values"][name].as_f64().map(|v| (v as f32).to_bits()), Some(want.to_bits()), "{json}");
        checked += 1;
    }
    report!("poll --unit: {checked} columns converted in CSV and JSON");
}

#[test]
fn derived_quantities_convert_too() {
    let mut checked = 0;
    for sensor in &spec().sensors {
        for d in &sensor.derived {
            let Some(from) = d.unit.as_deref().and_then(units::lookup) else { continue };
            let Some(to) = units::UNITS.iter().find(|u| u.dimension == from.dimension && !std::ptr::eq(*u, from))
            else {
                continue;
            };
            // A read every field input of the quantity comes from.
            let mut reads = d.inputs.iter().filter_map(|i| match &i.source {
                yosemitech_spec::InputSource::Field { command, .. } => Some(command.clone()),
                yosemitech_spec::InputSource::Station(_) => None,
            });
            let Some(read) = reads.next() else { continue };
            if reads.any(|r| r != read) {
                continue;
            }
            let s = sim(&sensor.name, sensor.default_address);
            let base = ["read", &sensor.name, &read, "-p", &s.path, "--json"];
            let plain = YOSEMITECH.run(&base).json();
            let Some(value) = plain["derived"][&d.name]["value"].as_f64() else { continue };
            let choice = format!("{}={}", d.name, to.symbol);
            let json = YOSEMITECH.run(&[&base[..], &["--unit", &choice]].concat()).json();
            let want = Conversion::between(from, to).unwrap().apply(f64::from(value as f32)) as f32;
            assert_eq!(json["derived"][&d.name]["unit"], to.symbol, "{json}");
            let got = json["derived"][&d.name]["value"].as_f64().unwrap_or_else(|| panic!("{json}"));
            assert_eq!((got as f32).to_bits(), want.to_bits(), "{json}");
            checked += 1;
        }
    }
    report!("read --unit: {checked} derived quantities converted");
}

#[test]
fn misuse_exits_2_before_the_port_opens() {
    let Some((sensor, command, field)) = convertible_reads().into_iter().next() else { panic!("no convertible field") };
    let (from, _) = other_unit(&field).unwrap();
    let name = field.display_name();
    // No port is there: a usage error must come first.
    let port = "/nonexistent/yosemitech-units-test";
    let foreign = units::UNITS.iter().find(|u| u.dimension != from.dimension).unwrap();
    // A dimension none of the command's fields (or derived quantities) has.
    let dimensions: Vec<_> = command.named_fields().filter_map(|f| f.unit.as_deref().and_then(units::lookup)).collect();
    let absent = units::UNITS
        .iter()
        .find(|u| {
            dimensions.iter().all(|d| d.dimension != u.dimension)
                && sensor
                    .derived
                    .iter()
                    .all(|d| d.unit.as_deref().and_then(units::lookup).is_none_or(|du| du.dimension != u.dimension))
        })
        .unwrap();
    let typo = format!("{}x", from.symbol);
    let cases: Vec<(String, &str)> = vec![
        ("no-such-unit".into(), "unknown unit `no-such-unit`"),
        (typo.clone(), "did you mean"),
        (format!("{name}={}", foreign.symbol), "choose one of"),
        (format!("no_such_field={}", from.symbol), "no measurement or derived quantity `no_such_field`"),
        (absent.symbol.to_owned(), "no measurement here is a"),
    ];
    for (choice, says) in &cases {
        for args in [
            vec!["read", &sensor.name, &command.name, "-p", port, "--unit", choice],
            vec!["poll", &sensor.name, "-p", port, "-n", "1", "--unit", choice],
        ] {
            let run = YOSEMITECH.run(&args);
            let err = run.fails_with_hint(2);
            assert!(err.contains(says), "{args:?}: `{says}` in\n{err}");
            assert!(!err.contains("cannot open"), "{args:?} opened the port:\n{err}");
        }
    }
    // Two units for one quantity.
    let twice = format!("{name}={}", from.symbol);
    let err = YOSEMITECH.run(&["read", &sensor.name, &command.name, "-p", port, "--unit", &twice, "--unit", &twice]);
    assert!(err.fails_with_hint(2).contains("two units"), "{}", err.stderr);
    report!("--unit misuse: {} cases refused with exit 2 by read and poll", cases.len() + 1);
}
