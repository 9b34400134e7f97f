//! The job of `read_probes` (pH, then temperature and conductivity, on the
//! same bus) written with rmodbus (no_std, heapless buffers): request
//! generation and reply parsing by rmodbus, the reply read with the same
//! timeout (the expected length known in advance), the values decoded from
//! the probes' little-endian float images. For the size comparison.
#![no_std]
#![no_main]

use cortex_m_rt::entry;
use embassy_futures::select::{Either, select};
use embedded_hal_async::delay::DelayNs;
use embedded_io_async::{Read, Write};
use panic_halt as _;
use rmodbus::ModbusProto;
use rmodbus::client::ModbusRequest;
use yosemitech_firmware_example::{CycleDelay, Uart, publish};

type Frame = heapless::Vec<u8, 256>;

/// Sends a read of `count` registers at `address` to `unit` and returns the
/// register data of the checked reply.
async fn read(
    uart: &mut Uart,
    delay: &mut CycleDelay,
    unit: u8,
    address: u16,
    count: u16,
    reply: &mut Frame,
) -> Option<usize> {
    let mut request = ModbusRequest::new(unit, ModbusProto::Rtu);
    let mut frame = Frame::new();
    request.generate_get_holdings(address, count, &mut frame).ok()?;
    delay.delay_ms(4).await; // the inter-frame silence
    uart.write_all(&frame).await.ok()?;
    uart.flush().await.ok()?;
    reply.clear();
    let expected = 5 + 2 * usize::from(count);
    let mut buf = [0u8; 256];
    let mut got = 0;
    while got < expected {
        match select(uart.read(buf.get_mut(got..expected)?), delay.delay_ms(1000)).await {
            Either::First(Ok(n)) => got += n,
            _ => return None,
        }
    }
    reply.extend_from_slice(buf.get(..got)?).ok()?;
    let data = request.parse_slice(reply).ok()?;
    (data.len() == 2 * usize::from(count)).then_some(data.len())
}

fn f32_le(data: &[u8], at: usize) -> Option<f32> {
    Some(f32::from_le_bytes(data.get(at..at + 4)?.try_into().ok()?))
}

#[entry]
fn main() -> ! {
    let (mut uart, mut delay) = (Uart, CycleDelay::default());
    let mut reply = Frame::new();
    loop {
        embassy_futures::block_on(async {
            if read(&mut uart, &mut delay, 1, 0x2800, 2, &mut reply).await.is_some()
                && let Some(ph) = reply.get(3..).and_then(|d| f32_le(d, 0))
            {
                publish(0, ph);
            }
            if read(&mut uart, &mut delay, 2, 0x2600, 5, &mut reply).await.is_some() {
                let data = reply.get(3..).unwrap_or(&[]);
                if let (Some(t), Some(c)) = (f32_le(data, 0), f32_le(data, 4)) {
                    publish(1, t);
                    publish(2, c);
                }
            }
        });
    }
}
