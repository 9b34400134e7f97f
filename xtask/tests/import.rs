//! `cargo xtask import` on bad input: one clear error, exit code 2, nothing written.

use std::path::PathBuf;
use std::process::Command;

fn dir(tag: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("xtask-import-cli-{tag}-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn run(input: &std::path::Path, out: &std::path::Path) -> (i32, String) {
    let o = Command::new(env!("CARGO_BIN_EXE_xtask"))
        .args(["import", input.to_str().unwrap(), "--name", "probe", "--out", out.to_str().unwrap()])
        .output()
        .unwrap();
    (o.status.code().unwrap_or(-1), String::from_utf8_lossy(&o.stderr).into_owned())
}

#[test]
fn bad_inputs_exit_2_and_write_nothing() {
    let d = dir("bad");
    let cases: Vec<(&str, Vec<u8>, &str)> = vec![
        ("empty.txt", Vec::new(), "empty"),
        ("binary.txt", vec![0, 159, 146, 150, 0, 1, 2], "binary"),
        ("other.txt", b"Minutes of the meeting\nNothing about probes.\n".to_vec(), "not a Yosemitech"),
        ("fake.pdf", b"%PDF-1.4\n%garbage that is no PDF\n".to_vec(), "pdf"),
    ];
    for (name, bytes, expect) in cases {
        let input = d.join(name);
        std::fs::write(&input, bytes).unwrap();
        let out = d.join(format!("{name}.yaml"));
        let (code, err) = run(&input, &out);
        assert_eq!(code, 2, "{name}: {err}");
        assert!(err.to_lowercase().contains(&expect.to_lowercase()), "{name}: {err}");
        assert_eq!(err.trim().lines().count(), 1, "{name}: one message: {err}");
        assert!(!err.contains("panicked"), "{name}: {err}");
        assert!(!out.exists(), "{name}: nothing written");
    }
    let big = d.join("big.txt");
    std::fs::File::create(&big).unwrap().set_len(100 * 1024 * 1024).unwrap();
    let out = d.join("big.yaml");
    let (code, err) = run(&big, &out);
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("too large"), "{err}");
    assert!(!out.exists());
    std::fs::remove_dir_all(&d).unwrap();
}
