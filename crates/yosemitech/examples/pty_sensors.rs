//! Reads pH, ORP, temperature and conductivity from simulated probes on
//! pseudo-terminals, through the same serial transport a logger uses on a
//! USB RS-485 adapter.
//!
//! ```sh
//! cargo run -p yosemitech --example pty_sensors
//! ```
//!
//! On hardware, replace the pty paths with the adapter's (`/dev/ttyUSB0`)
//! and drop the simulators.

use std::error::Error;
use std::path::Path;
use std::sync::Arc;
use std::time::Duration;

use yosemitech::procedures::NoSleep;
use yosemitech::procedures::conductivity::{MeasurementConfig, measure};
use yosemitech::{Client, ClientConfig, SerialConfig, SerialTransport, conductivity, ph_orp};
use yosemitech_sim::{ServeConfig, Simulator, serve_pty};

fn main() -> Result<(), Box<dyn Error>> {
    let spec_dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("spec");
    let spec = yosemitech_spec::load_paths(&[spec_dir])?;
    let sensor = |name: &str| spec.sensor(name).cloned().map(Arc::new).ok_or(format!("no sensor {name}"));

    // Two simulated probes, each on its own pty, at the factory address 1.
    let ph_server = serve_pty(Simulator::new(sensor("ph_orp")?), ServeConfig::default())?;
    let cond_server = serve_pty(Simulator::new(sensor("conductivity")?), ServeConfig::default())?;
    let config = ClientConfig { timeout: Duration::from_millis(500), ..ClientConfig::default() };

    let ph_path = ph_server.tty_path().ok_or("the pH simulator has no pty")?;
    let mut ph_bus = Client::with_config(SerialTransport::open(&SerialConfig::new(ph_path))?, config);
    let mut ph = ph_orp::Device::new(&mut ph_bus, ph_orp::SENSOR.default_address);
    println!("pH/ORP probe {} on {ph_path}", ph.sn()?.serial_number);
    println!("  pH           {:.2} pH", ph.ph()?.ph);
    println!("  ORP          {:.2} mV", ph.orp()?.orp_mv);
    println!("  temperature  {:.2} degC", ph.temperature()?.temperature_c);

    let cond_path = cond_server.tty_path().ok_or("the conductivity simulator has no pty")?;
    let mut cond_bus = Client::with_config(SerialTransport::open(&SerialConfig::new(cond_path))?, config);
    let mut cond = conductivity::Device::new(&mut cond_bus, conductivity::SENSOR.default_address);
    println!("conductivity probe {} on {cond_path}", cond.sn()?.serial_number);
    let reading = cond.temperature_and_conductivity()?;
    println!("  conductivity {:.3} mS/cm ({})", reading.conductivity_ms_cm, reading.range_status);
    println!("  temperature  {:.2} degC", reading.temperature_c);

    // The manual's procedure, without its real waits.
    let m = measure(&mut cond, &MeasurementConfig::default(), &mut NoSleep::default(), &mut |_| {})?;
    println!("  mean of {} readings: {:.3} mS/cm, TDS {:.0} mg/L", m.readings, m.conductivity_ms_cm, m.tds_mg_l);
    Ok(())
}
