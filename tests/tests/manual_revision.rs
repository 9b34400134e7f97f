//! The promise to the teams that consume the generated crate: a new revision
//! of a manual (a field, a code, a command more) is no breaking change for
//! code that did not use what it adds.
//!
//! The fixture DO probe has a second revision
//! (`tests/fixtures/do-probe/revision-2/`): a field joins a reply and a
//! one-field reply, a code joins an enum, a command joins the table. Code
//! written against the first (`tests/fixtures/do-probe/consumer/lib.rs`) is
//! compiled, as a crate of its own (`#[non_exhaustive]` only binds other
//! crates), against the crate generated from each revision through the
//! public `yosemitech_codegen::Config`, with `cargo check --offline`. The
//! same code with feature `exhaustive-match` or `reply-literal` uses the
//! shapes the generated API refuses (exhaustive matches, a reply built and
//! matched by its fields) and must not compile, which shows the first check
//! is not vacuous.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn workspace() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// The runtime's manifest entry, as the generated crates and the consumer
/// take it (no serial port, no tokio: the `Device` handle needs `std` only).
fn runtime_dependency() -> String {
    let runtime = workspace().join("crates/yosemitech-rtu").canonicalize().expect("crates/yosemitech-rtu");
    format!("yosemitech-rtu = {{ path = {:?}, default-features = false, features = [\"std\"] }}\n", runtime.display())
}

/// A crate `do-probe-fixture` at `dir` holding the code generated from `spec`.
fn generated_crate(spec: &Path, dir: &Path) {
    let generated = yosemitech_codegen::Config::new()
        .std_feature(None)
        .generate(&[spec.to_path_buf()])
        .unwrap_or_else(|e| panic!("{}: {e}", spec.display()));
    let src = dir.join("src/generated");
    std::fs::create_dir_all(&src).unwrap();
    for (file, source) in generated.files() {
        std::fs::write(src.join(file), source).unwrap();
    }
    std::fs::write(
        dir.join("Cargo.toml"),
        format!(
            "[package]\nname = \"do-probe-fixture\"\nversion = \"0.0.0\"\nedition = \"2024\"\npublish = false\n\n\
             [dependencies]\n{}\n[workspace]\n",
            runtime_dependency()
        ),
    )
    .unwrap();
    std::fs::write(
        dir.join("src/lib.rs"),
        "//! The generated code of one revision of the fixture.\n#![allow(missing_docs)]\n\
         include!(\"generated/mod.rs\");\n",
    )
    .unwrap();
}

/// The consumer crate at `dir`, depending on the generated crate at `fixture`.
fn consumer_crate(dir: &Path, fixture: &Path) {
    std::fs::create_dir_all(dir.join("src")).unwrap();
    std::fs::copy(workspace().join("tests/fixtures/do-probe/consumer/lib.rs"), dir.join("src/lib.rs")).unwrap();
    std::fs::write(
        dir.join("Cargo.toml"),
        format!(
            "[package]\nname = \"do-probe-consumer\"\nversion = \"0.0.0\"\nedition = \"2024\"\npublish = false\n\n\
             [features]\nexhaustive-match = []\nreply-literal = []\n\n\
             [dependencies]\nfixture = {{ package = \"do-probe-fixture\", path = {:?} }}\n{}\n[workspace]\n",
            fixture.display(),
            runtime_dependency()
        ),
    )
    .unwrap();
    // The workspace's lock file pins the runtime's dependencies, offline.
    std::fs::copy(workspace().join("Cargo.lock"), dir.join("Cargo.lock")).unwrap();
}

fn cargo_check(dir: &Path, features: &[&str]) -> Output {
    let cargo = std::env::var_os("CARGO").unwrap_or_else(|| "cargo".into());
    Command::new(cargo)
        .args(["check", "--quiet", "--offline", "--manifest-path"])
        .arg(dir.join("Cargo.toml"))
        .args(features.iter().flat_map(|f| ["--features", f]))
        // The drop-in check's target: the runtime's dependencies are built
        // once for both, apart from the workspace's build lock.
        .env("CARGO_TARGET_DIR", workspace().join("target/drop-in-check"))
        .env_remove("RUSTFLAGS")
        .output()
        .expect("cargo runs")
}

#[test]
fn code_written_against_a_revision_compiles_against_the_next() {
    let scratch = std::env::temp_dir().join(format!("yosemitech-manual-revision-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&scratch);
    let fixtures = workspace().join("tests/fixtures/do-probe");
    let (first, second) = (scratch.join("revision-1"), scratch.join("revision-2"));
    generated_crate(&fixtures.join("spec"), &first);
    generated_crate(&fixtures.join("revision-2"), &second);

    // The second revision adds to the first; nothing else differs.
    let rev1 = yosemitech_spec::load_paths(&[fixtures.join("spec")]).unwrap_or_else(|d| panic!("{d}"));
    let rev2 = yosemitech_spec::load_paths(&[fixtures.join("revision-2")]).unwrap_or_else(|d| panic!("{d}"));
    let ([old], [new]) = (rev1.sensors.as_slice(), rev2.sensors.as_slice()) else {
        panic!("each revision is one sensor");
    };
    assert!(new.commands.len() > old.commands.len(), "revision 2 adds a command");
    for command in &old.commands {
        let later = new.commands.iter().find(|c| c.name == command.name).expect("revision 2 keeps every command");
        let names = |c: &yosemitech_spec::CommandSpec| -> Vec<String> {
            c.fields.iter().filter_map(|f| f.name.clone()).collect()
        };
        assert!(names(command).iter().all(|f| names(later).contains(f)), "{} keeps its fields", command.name);
        assert_eq!((command.address, command.count), (later.address, later.count), "{}", command.name);
    }

    let consumer = scratch.join("consumer");
    consumer_crate(&consumer, &first);
    let against_first = cargo_check(&consumer, &[]);
    assert!(
        against_first.status.success(),
        "the consumer does not compile against revision 1:\n{}",
        String::from_utf8_lossy(&against_first.stderr)
    );
    // rustc reports a literal (typeck) before a non-exhaustive match (MIR
    // building) and stops: one check for each.
    for (feature, codes) in [("exhaustive-match", &["E0004"][..]), ("reply-literal", &["E0638", "E0639"])] {
        let refused = cargo_check(&consumer, &[feature]);
        let errors = String::from_utf8_lossy(&refused.stderr);
        assert!(!refused.status.success(), "feature {feature} compiles outside the generated crate");
        for code in codes {
            assert!(errors.contains(code), "feature {feature}: no {code} error:\n{errors}");
        }
    }

    consumer_crate(&consumer, &second);
    let against_second = cargo_check(&consumer, &[]);
    assert!(
        against_second.status.success(),
        "code written against revision 1 breaks against revision 2:\n{}",
        String::from_utf8_lossy(&against_second.stderr)
    );
    let _ = std::fs::remove_dir_all(&scratch);
}
