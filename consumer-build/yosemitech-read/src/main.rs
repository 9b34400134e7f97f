use yosemitech::{Client, SerialConfig, SerialTransport, conductivity, ph_orp};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let port = SerialTransport::open(&SerialConfig::with_settings("/dev/ttyUSB0", ph_orp::SENSOR.line_settings()))?;
    let mut client = Client::new(port);
    let ph = ph_orp::Device::new(&mut client, 1).ph()?.ph;
    let reading = conductivity::Device::new(&mut client, 2).temperature_and_conductivity()?;
    println!("pH {ph}, {} degC, {} mS/cm", reading.temperature_c, reading.conductivity_ms_cm);
    Ok(())
}
