//! The publisher's integration tests: one binary, so the workspace links once
//! for all of them. Each module is one file of tests; run one with `cargo test
//! -p yosemitech-mqtt --test integration broker::`.

mod broker;
mod credentials;

/// The rumqttd broker the broker tests start: this binary re-run with
/// `--exact rumqttd_child_process`, so the test sits at the crate root.
#[test]
#[ignore = "the rumqttd broker process of the other tests; they start it"]
fn rumqttd_child_process() {
    yosemitech_tests::broker::rumqttd_child_main();
}
