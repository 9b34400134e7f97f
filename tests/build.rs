//! Generates the fixture sensor (tests/fixtures/do-probe/spec, a made-up
//! probe that is in neither manual) through the public `yosemitech-codegen`
//! API, exactly as a downstream crate would; `src/lib.rs` includes it as
//! `yosemitech_tests::do_probe`. No Rust is written for that sensor.
//!
//! Also writes `devices.rs`: a dispatch from a sensor's name to its
//! generated `yosemitech::<sensor>::Device`, for the sensors of `spec/` whose
//! handle has `set_slave_address`, so that tests reach every sensor's typed
//! handle without a hand-written list.

use std::path::PathBuf;

fn main() -> Result<(), yosemitech_codegen::Error> {
    let manifest_dir = PathBuf::from(std::env::var_os("CARGO_MANIFEST_DIR").unwrap_or_default());
    let out_dir = PathBuf::from(std::env::var_os("OUT_DIR").unwrap_or_default()).join("fixtures");
    // This package has no `std` feature: emit the device handles unconditionally.
    yosemitech_codegen::Config::new()
        .std_feature(None)
        .compile(manifest_dir.join("fixtures/do-probe/spec"), &out_dir)?;
    // The hostile-but-valid fixture (tests/fixtures/hostile-valid): text that
    // tries to escape doc comments and literals, names next to Rust's own,
    // counts at their maximum. `src/lib.rs` includes it as `yosemitech_tests::hostile`.
    yosemitech_codegen::Config::new()
        .std_feature(None)
        .compile(manifest_dir.join("fixtures/hostile-valid/spec"), out_dir.with_file_name("hostile"))?;
    // The derived-quantity fixture (tests/specs/derived): formulas the real
    // specs do not hold yet. `src/lib.rs` includes it as `yosemitech_tests::derived_fixture`.
    yosemitech_codegen::Config::new()
        .std_feature(None)
        .device_handles(false)
        .compile(manifest_dir.join("specs/derived"), out_dir.with_file_name("derived"))?;
    write_device_dispatch(&manifest_dir.join("../spec"), &out_dir.with_file_name("devices.rs"));
    Ok(())
}

/// `change_address_through_device`: for each sensor with a write of role
/// `set_slave_address` and a read of role `serial_number` sent to its own
/// address (the rule `yosemitech-codegen` emits `Device::set_slave_address`
/// by), an arm that moves the probe through the generated handle.
fn write_device_dispatch(spec_dir: &std::path::Path, out: &std::path::Path) {
    use yosemitech_spec::Role;
    println!("cargo:rerun-if-changed={}", spec_dir.display());
    // A spec that does not load fails the yosemitech crate's own build; here it only empties the dispatch.
    let sensors = yosemitech_spec::load_paths(&[spec_dir.to_path_buf()]).map(|s| s.sensors).unwrap_or_default();
    let own =
        |s: &yosemitech_spec::Sensor, role| s.commands.iter().any(|c| c.role == Some(role) && c.fixed_slave.is_none());
    let mut arms = String::new();
    for s in sensors.iter().filter(|s| own(s, Role::SetSlaveAddress) && own(s, Role::SerialNumber)) {
        arms += &format!(
            "        {:?} => {{\n            let mut device = ::yosemitech::{}::Device::new(client, from);\n            \
             Some(device.set_slave_address(to).map(|()| device.address()))\n        }}\n",
            s.name, s.name
        );
    }
    let source = format!(
        "/// Moves the probe at `from` to `to` through sensor `sensor`'s generated\n\
         /// `Device::set_slave_address`; returns the handle's address afterwards,\n\
         /// or `None` for a sensor whose handle has no such method.\n\
         pub fn change_address_through_device<T: ::yosemitech::Transport>(\n    sensor: &str,\n    \
         client: &mut ::yosemitech::Client<T>,\n    from: u8,\n    to: u8,\n\
         ) -> Option<Result<u8, ::yosemitech::procedures::address::AddressChangeError>> {{\n    \
         match sensor {{\n{arms}        _ => None,\n    }}\n}}\n"
    );
    if std::fs::read_to_string(out).ok().as_deref() != Some(source.as_str())
        && let Err(e) = std::fs::write(out, source)
    {
        println!("cargo:warning=cannot write {}: {e}", out.display());
    }
}
