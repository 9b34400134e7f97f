//! The promise to the people who add sensors: a new manual's YAML file
//! dropped into `spec/` validates, generates code that compiles, and replays
//! through the interpreter and the simulator, with no Rust written for it.
//!
//! The test copies the real `spec/` into a temporary directory, adds the
//! fixture `tests/fixtures/drop-in/dissolved-oxygen.yaml` (a made-up probe
//! written only from docs/spec-language.md, using the shared fragments), and
//! runs on the copy what `cargo xtask validate`, `cargo xtask codegen` and the
//! build do. The generated crate is compiled with `cargo check` in a scratch
//! crate of its own (its own target directory, so it does not wait for the
//! workspace's build lock).

use std::path::PathBuf;
use std::process::Command;

use yosemitech_sim::{FrameHandler, Simulator};
use yosemitech_spec::Spec;

fn workspace() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..")
}

fn fixture() -> PathBuf {
    workspace().join("tests/fixtures/drop-in/dissolved-oxygen.yaml")
}

/// A fresh directory under the system's temp directory.
fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("yosemitech-drop-in-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// `spec/` plus the fixture, in a temporary directory.
fn spec_with_fixture(name: &str) -> PathBuf {
    let dir = scratch(name).join("spec");
    std::fs::create_dir_all(&dir).unwrap();
    for entry in std::fs::read_dir(workspace().join("spec")).unwrap() {
        let path = entry.unwrap().path();
        if path.is_file() {
            std::fs::copy(&path, dir.join(path.file_name().unwrap())).unwrap();
        }
    }
    std::fs::copy(fixture(), dir.join("dissolved-oxygen.yaml")).unwrap();
    dir
}

/// The sensor the fixture file defines (the file may already be in `spec/`
/// when someone has just dropped it there: then it replaces itself).
fn fixture_name(spec: &Spec) -> String {
    let file = fixture().file_name().unwrap().to_owned();
    let sensor = spec.sensors.iter().find(|s| s.file.file_name() == Some(&file)).expect("the fixture's sensor loads");
    sensor.name.clone()
}

#[test]
fn a_new_sensor_file_validates_and_replays_through_the_interpreter_and_simulator() {
    let dir = spec_with_fixture("replay");
    let before = yosemitech_spec::load_paths(&[workspace().join("spec")]).unwrap_or_else(|d| panic!("{d}"));
    let spec =
        yosemitech_spec::load_paths(std::slice::from_ref(&dir)).unwrap_or_else(|d| panic!("the drop-in spec:\n{d}"));
    let name = fixture_name(&spec);
    let sensor = spec.sensor(&name).unwrap();
    let already_there = before.sensor(&name).is_some();
    assert_eq!(spec.summary().sensors, before.summary().sensors + usize::from(!already_there));

    // Every complete example exchange, answered by a simulator of the new sensor.
    let mut exchanges = 0;
    for command in &sensor.commands {
        for example in &command.examples {
            let Some((request, reply)) = example.true_pair() else { continue };
            let address = if command.fixed_slave.is_some() { sensor.default_address } else { example.slave() };
            let mut sim = Simulator::new(sensor.clone()).with_address(address);
            let mut answer = Vec::new();
            let _ = sim.handle(request, &mut answer);
            let decoded = command.decode_response(example.slave(), &answer);
            assert!(decoded.is_ok(), "{name}.{}: the simulator's reply {answer:02X?} does not decode", command.name);
            if !command.trigger && command.role.is_none() {
                assert_eq!(answer, reply, "{name}.{}: the simulator answers as the example", command.name);
            }
            exchanges += 1;
        }
    }
    assert!(exchanges > 0);
    yosemitech_tests::report!("drop-in: {name} validates; {exchanges} example exchanges through the simulator");
    let _ = std::fs::remove_dir_all(dir.parent().unwrap());
}

#[test]
fn a_new_sensor_file_generates_a_crate_that_compiles() {
    let dir = spec_with_fixture("codegen");
    let generated = yosemitech_codegen::Config::new()
        .std_feature(None)
        .generate(std::slice::from_ref(&dir))
        .unwrap_or_else(|e| panic!("{e}"));
    let crate_dir = dir.parent().unwrap().join("check");
    let src = crate_dir.join("src");
    std::fs::create_dir_all(src.join("generated")).unwrap();
    for (file, source) in generated.files() {
        std::fs::write(src.join("generated").join(file), source).unwrap();
    }
    let runtime = workspace().join("crates/yosemitech-rtu").canonicalize().unwrap();
    std::fs::write(
        crate_dir.join("Cargo.toml"),
        format!(
            "[package]\nname = \"drop-in-check\"\nversion = \"0.0.0\"\nedition = \"2024\"\npublish = false\n\n\
             [dependencies]\nyosemitech-rtu = {{ path = {:?}, default-features = false, features = [\"std\"] }}\n\n\
             [workspace]\n",
            runtime.display().to_string()
        ),
    )
    .unwrap();
    std::fs::write(
        src.join("lib.rs"),
        "//! The generated code of the drop-in spec.\n#![allow(missing_docs)]\ninclude!(\"generated/mod.rs\");\n\n\
         /// Every generated module answers by name.\npub fn names() -> Vec<&'static str> {\n    \
         SENSORS.iter().map(|m| m.info.name).collect()\n}\n",
    )
    .unwrap();
    // The workspace's lock file pins the runtime's dependencies, offline.
    std::fs::copy(workspace().join("Cargo.lock"), crate_dir.join("Cargo.lock")).unwrap();
    let target = workspace().join("target/drop-in-check");
    let cargo = std::env::var_os("CARGO").unwrap_or_else(|| "cargo".into());
    let output = Command::new(cargo)
        .args(["check", "--quiet", "--offline", "--manifest-path"])
        .arg(crate_dir.join("Cargo.toml"))
        .env("CARGO_TARGET_DIR", &target)
        .env_remove("RUSTFLAGS")
        .output()
        .expect("cargo runs");
    assert!(
        output.status.success(),
        "the generated crate does not compile:\n{}",
        String::from_utf8_lossy(&output.stderr)
    );
    let mod_rs = std::fs::read_to_string(src.join("generated/mod.rs")).unwrap();
    assert!(mod_rs.contains("pub mod dissolved_oxygen"), "the new module is declared");
    yosemitech_tests::report!("drop-in: generated {} files; `cargo check` passes", generated.files().len());
    let _ = std::fs::remove_dir_all(dir.parent().unwrap());
}
