//! Derived quantities: the generated functions (through each module's
//! `DERIVED` table, `rtu::SensorModule::derived`) against the spec's
//! interpreter (`yosemitech_spec::Derived::compute`), for every derived
//! quantity of every spec (`spec/` and the fixture `tests/specs/derived/`);
//! no sensor or quantity is named here.
//!
//! - every example of every quantity holds for both;
//! - over each quantity's input ranges both give the same value (within a
//!   generous float tolerance: libm's exp/ln against std's) or the same
//!   `NotComputable`;
//! - NaN, infinite and out-of-range inputs give `NotComputable` for both;
//! - the DO block saved for spec/dissolved-oxygen.yaml is the fixture's.

use proptest::prelude::*;
use proptest::test_runner::{Config, TestRunner};
use yosemitech_rtu::{DerivedInfo, InputSource as RtInputSource, NotComputable, SensorModule};
use yosemitech_spec::{Derived, InputSource, Sensor, Spec};

/// Every (spec quantity, generated table entry), each spec sensor paired
/// with its generated module by name.
fn quantities() -> Vec<(Sensor, Derived, &'static DerivedInfo)> {
    let fixture = yosemitech_spec::load_paths(&[yosemitech_tests::derived_spec_dir()]).expect("the fixture loads");
    let sets: [(&Spec, &[SensorModule]); 2] =
        [(yosemitech_tests::spec(), yosemitech::SENSORS), (&fixture, yosemitech_tests::derived_fixture::SENSORS)];
    let mut out = Vec::new();
    for (spec, modules) in sets {
        for sensor in &spec.sensors {
            let module = modules.iter().find(|m| m.info.name == sensor.name).expect("a generated module per sensor");
            assert_eq!(module.derived.len(), sensor.derived.len(), "{}: DERIVED lists every quantity", sensor.name);
            for (d, info) in sensor.derived.iter().zip(module.derived) {
                assert_eq!(d.name, info.name, "{}: DERIVED in spec order", sensor.name);
                out.push((sensor.clone(), d.clone(), info));
            }
        }
    }
    // Both sets together hold at least one quantity: the fixture's.
    assert!(!out.is_empty(), "no derived quantity to test");
    out
}

/// The range an input is exercised over: its own, its field's, or a wide one.
fn test_range(sensor: &Sensor, d: &Derived, input: usize) -> (f64, f64) {
    let i = &d.inputs[input];
    if let Some(r) = i.range {
        return r;
    }
    if let InputSource::Field { command, field } = &i.source
        && let Some(r) = sensor.command(command).and_then(|c| c.field(field)).and_then(|f| f.range)
    {
        return r;
    }
    (-1000.0, 1000.0)
}

/// Values agree: equal, both not finite, or within a relative 1e-5.
fn close(a: f32, b: f32) -> bool {
    let (a, b) = (f64::from(a), f64::from(b));
    a == b || (a - b).abs() <= 1e-5 * a.abs().max(b.abs()).max(1e-3)
}

fn both(d: &Derived, info: &DerivedInfo, inputs: &[f32]) -> Result<(), String> {
    match (d.compute(inputs), (info.compute)(inputs)) {
        (Ok(a), Ok(b)) if close(a, b) => Ok(()),
        (Err(a), Err(b)) if a.same_as(&b) => Ok(()),
        (a, b) => Err(format!("{}({inputs:?}): interpreter {a:?}, generated {b:?}", d.name)),
    }
}

#[test]
fn every_example_holds_for_the_generated_function_and_the_interpreter() {
    let mut checked = 0;
    for (sensor, d, info) in quantities() {
        for e in &d.examples {
            let inputs = d.example_inputs(e).expect("validation saw every input given or defaulted");
            let allowed = e.tolerance.max(e.value.abs().max(1.0) * 4.0 * f64::from(f32::EPSILON));
            let interp = d.compute(&inputs).unwrap_or_else(|err| panic!("{}.{}: {err}", sensor.name, d.name));
            let generated = (info.compute)(&inputs).unwrap_or_else(|err| panic!("{}.{}: {err}", sensor.name, d.name));
            for (who, got) in [("interpreter", interp), ("generated", generated)] {
                let diff = (f64::from(got) - e.value).abs();
                assert!(
                    diff <= allowed,
                    "{}.{}: the {who} gives {got} for {:?}, expected {} within {allowed} ({})",
                    sensor.name,
                    d.name,
                    e.inputs,
                    e.value,
                    e.doc
                );
            }
            checked += 1;
        }
    }
    yosemitech_tests::report!("derived examples: {checked} hold for the generated functions and the interpreter");
}

#[test]
fn the_generated_table_describes_the_spec() {
    for (sensor, d, info) in quantities() {
        assert_eq!(info.unit, d.unit.as_deref(), "{}.{}", sensor.name, d.name);
        assert!(info.expr.split_whitespace().eq(d.expr.split_whitespace()), "{}.{}", sensor.name, d.name);
        assert_eq!(info.inputs.len(), d.inputs.len());
        for (spec, table) in d.inputs.iter().zip(info.inputs) {
            assert_eq!(table.name, spec.name);
            assert_eq!(table.default, spec.default);
            assert_eq!(table.range, spec.range);
            assert_eq!(table.unit, spec.unit.as_deref());
            match (&spec.source, table.source) {
                (InputSource::Field { command, field }, RtInputSource::Field { command: c, field: f }) => {
                    assert_eq!((command.as_str(), field.as_str()), (c, f));
                    let read = sensor.command(command).expect("the input's read");
                    assert!(read.is_read() && read.field(field).is_some());
                }
                (InputSource::Station(name), RtInputSource::Station { name: n }) => assert_eq!(name, n),
                (a, b) => panic!("{}.{}: {a:?} against {b:?}", sensor.name, d.name),
            }
        }
        // The wrong number of inputs is an error, not a panic.
        let too_many = vec![0.0f32; d.inputs.len() + 1];
        assert!(matches!((info.compute)(&too_many), Err(NotComputable::Inputs { .. })));
        assert!(d.compute(&too_many).is_err());
    }
}

#[test]
fn generated_functions_agree_with_the_interpreter_over_the_input_ranges() {
    let mut cases = 0;
    for (sensor, d, info) in quantities() {
        let ranges: Vec<(f64, f64)> = (0..d.inputs.len()).map(|k| test_range(&sensor, &d, k)).collect();
        // Inside the ranges, at their bounds, and a little beyond them.
        let strategy = ranges
            .iter()
            .map(|&(min, max)| {
                let span = (max - min).max(1.0);
                prop_oneof![
                    8 => min..=max,
                    1 => Just(min),
                    1 => Just(max),
                    1 => (min - span * 0.1)..=(max + span * 0.1),
                ]
                .prop_map(|v| v as f32)
            })
            .collect::<Vec<_>>();
        let mut runner = TestRunner::new(Config { cases: 512, failure_persistence: None, ..Config::default() });
        runner
            .run(&strategy, |inputs| {
                both(&d, info, &inputs).map_err(TestCaseError::fail)?;
                Ok(())
            })
            .unwrap_or_else(|e| panic!("{}.{}: {e}", sensor.name, d.name));
        cases += 512;
    }
    yosemitech_tests::report!("derived differential: {cases} cases agree");
}

#[test]
fn nan_infinite_and_out_of_range_inputs_are_not_computable() {
    let mut checked = 0;
    for (sensor, d, info) in quantities() {
        let ranges: Vec<(f64, f64)> = (0..d.inputs.len()).map(|k| test_range(&sensor, &d, k)).collect();
        let middle: Vec<f32> = ranges.iter().map(|(a, b)| ((a + b) / 2.0) as f32).collect();
        for k in 0..d.inputs.len() {
            let name = d.inputs[k].name.as_str();
            for bad in [f32::NAN, f32::INFINITY, f32::NEG_INFINITY] {
                let mut inputs = middle.clone();
                inputs[k] = bad;
                assert_eq!((info.compute)(&inputs), Err(NotComputable::NotFinite { input: info.inputs[k].name }));
                assert!(
                    matches!(d.compute(&inputs), Err(yosemitech_spec::NotComputable::NotFinite { input }) if input == name)
                );
                checked += 1;
            }
            if let Some((min, max)) = d.inputs[k].range {
                for outside in [min - (max - min).max(1.0), max + (max - min).max(1.0)] {
                    let mut inputs = middle.clone();
                    inputs[k] = outside as f32;
                    assert!(
                        matches!((info.compute)(&inputs), Err(NotComputable::OutOfRange { input, .. }) if input == name),
                        "{}.{}: {name} = {outside}",
                        sensor.name,
                        d.name
                    );
                    assert!(
                        matches!(d.compute(&inputs), Err(yosemitech_spec::NotComputable::OutOfRange { input, .. }) if input == name)
                    );
                    checked += 1;
                }
            }
        }
    }
    yosemitech_tests::report!("derived inputs: {checked} NaN, infinite or out-of-range inputs refused by both");
}
