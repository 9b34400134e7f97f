use tokio_modbus::prelude::*;

/// An `f32` from two registers holding its bytes little-endian first (the
/// probes' `dcba` image), as each team decodes it by hand with tokio-modbus.
fn f32_of(words: &[u16]) -> Option<f32> {
    let [first, second] = words.get(..2)? else { return None };
    let [a, b] = first.to_be_bytes();
    let [c, d] = second.to_be_bytes();
    Some(f32::from_le_bytes([a, b, c, d]))
}

#[tokio::main(flavor = "current_thread")]
async fn main() -> Result<(), Box<dyn std::error::Error>> {
    let builder = tokio_serial::new("/dev/ttyUSB0", 9600);
    let port = tokio_serial::SerialStream::open(&builder)?;
    let mut ctx = rtu::attach_slave(port, Slave(1));
    let ph = ctx.read_holding_registers(0x2800, 2).await??;
    ctx.set_slave(Slave(2));
    let reading = ctx.read_holding_registers(0x2600, 4).await??;
    let (ph, temperature, conductivity) =
        (f32_of(&ph), f32_of(&reading), reading.get(2..).and_then(f32_of));
    println!("pH {ph:?}, {temperature:?} degC, {conductivity:?} mS/cm");
    Ok(())
}
