//! The workspace's golden, property, differential, corpus and end-to-end tests:
//! one binary, so the workspace links once for all of them. Each module is one
//! file of tests; run one with `cargo test -p yosemitech-tests --test
//! integration async_client::`.

mod async_client;
mod codegen_fixture;
mod coefficient_backup;
mod derived;
mod device_address;
mod differential;
mod drop_in;
mod fault_soak_pty;
mod golden;
mod hostile_specs;
mod layering;
mod manual_revision;
mod no_sensor_names;
mod procedures;
mod python_package;
mod roundtrip;
mod segment_examples;
mod sim_behaviour;
mod sim_examples;
mod sim_faults;
mod sim_serve;
mod spec_corpus;
mod tokio_modbus_interop;
mod write_safety;
