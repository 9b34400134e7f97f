//! The real `spec/` directory loads and holds what the manuals print.

use yosemitech_spec::Role;
use yosemitech_tests::spec;

/// Every sensor of `spec/`, whatever is there: no sensor is named here, so a
/// new manual's file needs no test edit.
#[test]
fn every_sensor_loads_with_its_identity_and_sources() {
    let spec = spec();
    assert!(!spec.sensors.is_empty());
    for sensor in &spec.sensors {
        assert!(!sensor.commands.is_empty(), "{}", sensor.name);
        assert!(sensor.files.contains(&sensor.file), "{}", sensor.name);
        // A shared command is included from a fragment file this sensor reads.
        for c in sensor.commands.iter().filter(|c| c.shared_from.is_some()) {
            assert!(sensor.files.len() > 1, "{}.{} is shared but no fragment was read", sensor.name, c.name);
        }
        // Every `since` names one of the sensor's manuals.
        let softwares: Vec<&str> = sensor.manuals().filter_map(|m| m.software.as_deref()).collect();
        for c in &sensor.commands {
            if let Some(since) = &c.since {
                assert!(softwares.contains(&since.as_str()), "{}.{}: since {since}", sensor.name, c.name);
            }
        }
        // One command per role, calibration blocks aside.
        let mut roles: Vec<_> =
            sensor.commands.iter().filter_map(|c| c.role).filter(|&r| r != Role::UserCalibration).collect();
        let n = roles.len();
        roles.sort();
        roles.dedup();
        assert_eq!(roles.len(), n, "{}: a role twice", sensor.name);
        // Several calibration blocks each say which field they calibrate, so
        // a tool can tell them apart; each is a coefficient block.
        let blocks = sensor.user_calibrations();
        let writes = sensor.commands.iter().filter(|c| c.role == Some(Role::UserCalibration)).count();
        assert_eq!(blocks.len(), writes, "{}: a calibration block without its read", sensor.name);
        if blocks.len() > 1 {
            let mut fields: Vec<&str> =
                blocks.iter().filter_map(|(w, _)| w.calibrates.as_ref().map(|c| c.field.as_str())).collect();
            fields.sort_unstable();
            fields.dedup();
            assert_eq!(fields.len(), blocks.len(), "{}: calibration blocks not told apart", sensor.name);
        }
        for (write, _) in &blocks {
            if let Some(c) = &write.calibrates {
                assert!(sensor.measurement_with_field(&c.field).is_some(), "{}.{}", sensor.name, write.name);
            }
        }
    }
}

#[test]
fn summary_counts_printed_frames_honestly() {
    let spec = spec();
    let s = spec.summary();
    let examples: Vec<&yosemitech_spec::Example> =
        spec.sensors.iter().flat_map(|x| &x.commands).flat_map(|c| &c.examples).collect();
    assert_eq!(s.sensors, spec.sensors.len());
    assert_eq!(s.commands, spec.sensors.iter().map(|x| x.commands.len()).sum::<usize>());
    assert_eq!(s.examples, examples.len());
    let printed: usize =
        examples.iter().map(|e| usize::from(e.request.is_some()) + usize::from(e.response.is_some())).sum();
    assert_eq!(s.printed_frames, printed);
    let corrections: usize = examples
        .iter()
        .filter_map(|e| e.erratum.as_ref())
        .map(|e| usize::from(e.corrected_request.is_some()) + usize::from(e.corrected_response.is_some()))
        .sum();
    assert_eq!(s.frames, printed + corrections);
    let complete = examples
        .iter()
        .flat_map(|e| [&e.request, &e.response])
        .flatten()
        .filter(|f| f.crc_printed && f.complete.as_deref().is_some_and(yosemitech_rtu::crc_ok))
        .count();
    assert_eq!(s.complete_frames, complete);
    assert!(s.complete_frames <= s.printed_frames);
}

#[test]
fn every_printed_frame_is_kept_as_printed() {
    // A frame with a computed CRC holds the printed bytes followed by that CRC;
    // a frame with placeholders has no complete form.
    for sensor in &spec().sensors {
        for c in &sensor.commands {
            for e in &c.examples {
                for f in [&e.request, &e.response].into_iter().flatten() {
                    let known: Option<Vec<u8>> = if f.open_ended { None } else { f.bytes.iter().copied().collect() };
                    match (&f.complete, known) {
                        (Some(all), Some(known)) if f.crc_printed => assert_eq!(all, &known),
                        (Some(all), Some(known)) => {
                            assert_eq!(&all[..known.len()], &known[..]);
                            assert!(yosemitech_rtu::crc_ok(all), "{}.{}", sensor.name, c.name);
                        }
                        (None, None) => assert!(!f.crc_printed),
                        other => panic!("{}.{}: inconsistent frame {other:?}", sensor.name, c.name),
                    }
                }
            }
        }
    }
}

#[cfg(feature = "schema")]
#[test]
fn schema_describes_the_spec_files() {
    let schema = yosemitech_spec::json_schema();
    assert_eq!(schema["title"], "Yosemitech Modbus sensor spec");
    let command = &schema["$defs"]["CommandDoc"];
    for key in ["name", "use", "function", "address", "count", "fields", "examples"] {
        assert!(command["properties"].get(key).is_some(), "CommandDoc lacks `{key}`");
    }
    assert_eq!(command["additionalProperties"], false);
    // The committed schema is the generated one.
    let committed =
        std::fs::read_to_string(std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../spec/schema.json"))
            .expect("spec/schema.json");
    let mut generated = serde_json::to_string_pretty(&schema).expect("json");
    generated.push('\n');
    assert!(committed == generated, "spec/schema.json is stale; run cargo xtask schema");
}
