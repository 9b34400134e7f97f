//! The promise to the people who add sensors: a new manual's YAML file
//! dropped into `spec/` validates, generates code that compiles, and replays
//! through the interpreter and the simulator, with no Rust written for it.
//!
//! The fast check of the drop-in corpus (`tests/drop-in/`, made-up specs
//! that do what real manuals do and the built-in specs do not): the test
//! copies the real `spec/` and every corpus file into a temporary directory
//! and runs on the copy what `cargo xtask validate`, `cargo xtask codegen`
//! and the build do. The generated crate is compiled with `cargo check` in a
//! scratch crate of its own (its own target directory, so it does not wait
//! for the workspace's build lock). `.ci/run` runs the whole suite once more
//! with the corpus in `spec/`.

use std::path::PathBuf;
use std::process::Command;

use yosemitech_sim::{FrameHandler, Simulator};
use yosemitech_spec::{CommandSpec, Example, Sensor, Spec};

fn workspace() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// Every file of the corpus, found by listing `tests/drop-in/`.
fn corpus() -> Vec<PathBuf> {
    let dir = workspace().join("tests/drop-in");
    let mut files: Vec<PathBuf> = std::fs::read_dir(&dir)
        .unwrap_or_else(|e| panic!("{}: {e}", dir.display()))
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|e| e == "yaml"))
        .collect();
    files.sort();
    assert!(!files.is_empty(), "tests/drop-in holds the corpus");
    files
}

/// A fresh directory under the system's temp directory.
fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("yosemitech-drop-in-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// `spec/` plus the corpus, in a temporary directory (a corpus file already
/// in `spec/`, as in `.ci/run`'s drop-in step, replaces itself).
fn spec_with_corpus(name: &str) -> PathBuf {
    let dir = scratch(name).join("spec");
    std::fs::create_dir_all(&dir).unwrap();
    for entry in std::fs::read_dir(workspace().join("spec")).unwrap() {
        let path = entry.unwrap().path();
        if path.is_file() {
            std::fs::copy(&path, dir.join(path.file_name().unwrap())).unwrap();
        }
    }
    for file in corpus() {
        std::fs::copy(&file, dir.join(file.file_name().unwrap())).unwrap();
    }
    dir
}

/// The sensors the corpus files define.
fn corpus_sensors(spec: &Spec) -> Vec<&Sensor> {
    let names: Vec<_> = corpus().iter().map(|f| f.file_name().unwrap().to_owned()).collect();
    let sensors: Vec<&Sensor> =
        spec.sensors.iter().filter(|s| s.file.file_name().is_some_and(|f| names.iter().any(|n| n == f))).collect();
    assert_eq!(sensors.len(), names.len(), "every corpus file defines a sensor");
    sensors
}

/// Whether `example` is the one a fresh simulator serves for `command`:
/// the last example with a complete reply.
fn served(command: &CommandSpec, example: &Example) -> bool {
    command.examples.iter().rev().find(|e| e.true_response().is_some()).is_some_and(|e| std::ptr::eq(e, example))
}

#[test]
fn the_corpus_validates_and_replays_through_the_interpreter_and_simulator() {
    let dir = spec_with_corpus("replay");
    let before = yosemitech_spec::load_paths(&[workspace().join("spec")]).unwrap_or_else(|d| panic!("{d}"));
    let spec =
        yosemitech_spec::load_paths(std::slice::from_ref(&dir)).unwrap_or_else(|d| panic!("the drop-in spec:\n{d}"));
    let added = corpus_sensors(&spec);
    let new = added.iter().filter(|s| before.sensor(&s.name).is_none()).count();
    assert_eq!(spec.summary().sensors, before.summary().sensors + new);

    // Every complete example exchange, answered by a simulator of its sensor.
    let (mut exchanges, mut exact) = (0, 0);
    for sensor in &added {
        for command in &sensor.commands {
            for example in &command.examples {
                let Some((request, reply)) = example.true_pair() else { continue };
                let address = if command.fixed_slave.is_some() { sensor.default_address } else { example.slave() };
                let mut sim = Simulator::new((*sensor).clone()).with_address(address);
                let mut answer = Vec::new();
                let _ = sim.handle(request, &mut answer);
                let decoded = command.decode_response(example.slave(), &answer);
                assert!(
                    decoded.is_ok(),
                    "{}.{}: the simulator's reply {answer:02X?} does not decode",
                    sensor.name,
                    command.name
                );
                // The reply the simulator serves from power-on, and every write's echo, as printed.
                if !command.trigger && command.role.is_none() && (!command.is_read() || served(command, example)) {
                    assert_eq!(answer, reply, "{}.{}: the simulator answers as the example", sensor.name, command.name);
                    exact += 1;
                }
                exchanges += 1;
            }
        }
    }
    yosemitech_tests::report!(
        "drop-in: {} corpus sensors validate; {exchanges} example exchanges through the simulator ({exact} byte for byte)",
        added.len()
    );
    let _ = std::fs::remove_dir_all(dir.parent().unwrap());
}

#[test]
fn the_corpus_generates_a_crate_that_compiles() {
    let dir = spec_with_corpus("codegen");
    let spec = yosemitech_spec::load_paths(std::slice::from_ref(&dir)).unwrap_or_else(|d| panic!("{d}"));
    let names: Vec<String> = corpus_sensors(&spec).iter().map(|s| s.name.clone()).collect();
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
        "//! The generated code of the drop-in spec.\n#![deny(warnings)]\n#![allow(missing_docs)]\n\
         include!(\"generated/mod.rs\");\n\n\
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
    for name in &names {
        assert!(mod_rs.contains(&format!("pub mod {name}")), "the module {name} is declared");
    }
    yosemitech_tests::report!(
        "drop-in: {} corpus sensors generated into {} files; `cargo check` passes",
        names.len(),
        generated.files().len()
    );
    let _ = std::fs::remove_dir_all(dir.parent().unwrap());
}
