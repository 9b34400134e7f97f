//! The CLI's integration tests: one binary, so the workspace links once for all
//! of them. Each module is one subcommand or feature, as its file name says;
//! run one with `cargo test -p yosemitech-cli --test integration cli_scan::`.

mod device;
mod station;

mod cli_address_plan;
mod cli_calibrate;
mod cli_calibrate_ph;
mod cli_coefficients;
mod cli_decode;
mod cli_demo;
mod cli_doctor;
mod cli_home_assistant;
mod cli_ingest;
mod cli_inputs;
mod cli_measure;
mod cli_monitor_my_watershed;
mod cli_offline;
mod cli_poll;
mod cli_power_cut;
mod cli_read;
mod cli_scan;
mod cli_set_address;
mod cli_simulate;
mod cli_sniff;
mod cli_spec_files;
mod cli_station;
mod cli_station_check;
mod cli_station_mqtt;
mod cli_timer_slack;
mod cli_units;
mod cli_view;
mod cli_write;

/// The rumqttd broker the MQTT tests start: this binary re-run with
/// `--exact rumqttd_child_process`, so the test sits at the crate root.
#[test]
#[ignore = "the rumqttd broker process of the other tests; they start it"]
fn rumqttd_child_process() {
    yosemitech_tests::broker::rumqttd_child_main();
}
