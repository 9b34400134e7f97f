//! The Python package: its wheel built by maturin from `crates/yosemitech-py`,
//! installed into a real virtual environment, and its pytest suite
//! (`crates/yosemitech-py/tests/`) run there against simulated probes.
//!
//! Needs a Python with maturin and pytest: `YOSEMITECH_PYTHON` names its
//! interpreter (a virtual environment's, which the wheel is installed
//! into). Without it the test skips with a note; `.ci/run` makes the venv
//! and sets `YOSEMITECH_REQUIRE_PYTHON=1`, which makes a missing one a failure.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn package_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../crates/yosemitech-py")
}

fn run(what: &str, command: &mut Command) -> Output {
    let output = command.output().unwrap_or_else(|e| panic!("{what}: cannot start: {e}"));
    assert!(
        output.status.success(),
        "{what} failed ({}):\n{}\n{}",
        output.status,
        String::from_utf8_lossy(&output.stdout),
        String::from_utf8_lossy(&output.stderr)
    );
    output
}

#[test]
fn the_wheel_installed_in_a_venv_passes_the_python_tests() {
    let required = std::env::var("YOSEMITECH_REQUIRE_PYTHON").is_ok_and(|v| v == "1");
    let Some(python) = std::env::var_os("YOSEMITECH_PYTHON") else {
        assert!(!required, "YOSEMITECH_REQUIRE_PYTHON=1 but YOSEMITECH_PYTHON names no interpreter");
        eprintln!("    skipped: set YOSEMITECH_PYTHON to a venv's python with maturin and pytest (.ci/run does)");
        return;
    };
    let wheels = tempfile::tempdir().unwrap();
    run(
        "maturin build",
        Command::new(&python)
            .args(["-m", "maturin", "build", "--quiet", "--out"])
            .arg(wheels.path())
            .current_dir(package_dir()),
    );
    let wheel = std::fs::read_dir(wheels.path())
        .unwrap()
        .filter_map(Result::ok)
        .map(|e| e.path())
        .find(|p| p.extension().is_some_and(|e| e == "whl"))
        .expect("maturin wrote a wheel");
    run(
        "pip install",
        Command::new(&python).args(["-m", "pip", "install", "--quiet", "--force-reinstall", "--no-deps"]).arg(&wheel),
    );
    // From elsewhere than the source tree, so that `import yosemitech` is the installed wheel.
    let output = run(
        "pytest",
        Command::new(&python)
            .args(["-m", "pytest", "-q", "-p", "no:cacheprovider"])
            // Nothing written into the source tree.
            .env("PYTHONDONTWRITEBYTECODE", "1")
            .arg(package_dir().join("tests"))
            .current_dir(wheels.path()),
    );
    eprintln!("    {}", String::from_utf8_lossy(&output.stdout).lines().last().unwrap_or_default());
}
