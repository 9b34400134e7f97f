//! Several simulated sensors on one RS-485 bus.

use std::time::Duration;

use yosemitech_rtu::Responder;

use crate::FrameHandler;
use crate::simulator::Simulator;

/// Simulated sensors sharing one bus: every request reaches every device,
/// and only the addressed one answers (a broadcast reaches all and none
/// answers).
///
/// When more than one device answers (two at the same address, or several
/// answering get_slave_id's 0xFF), their replies collide: the bytes are
/// ANDed where they overlap (on an RS-485 line a driven 0 tends to win;
/// real collisions are undefined, and the point is only that the result is
/// garbage) and the collision is counted. The reply is held back by the
/// longest delay any answering device asked for.
///
/// ```
/// # let spec = yosemitech_spec::load_paths(&[concat!(env!("CARGO_MANIFEST_DIR"), "/../../spec").into()])?;
/// use yosemitech_sim::{Bus, FrameHandler, Simulator};
///
/// let ph = spec.sensor("ph_orp").unwrap().clone();
/// let cond = spec.sensor("conductivity").unwrap().clone();
/// let mut bus = Bus::new().with(Simulator::new(ph).with_address(1)).with(Simulator::new(cond).with_address(2));
/// let mut reply = Vec::new();
/// bus.handle(&[0x02, 0x03, 0x26, 0x00, 0x00, 0x05, 0x8E, 0xB2], &mut reply);
/// assert_eq!(reply[..3], [0x02, 0x03, 0x0A]);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
#[derive(Debug, Clone, Default)]
pub struct Bus {
    devices: Vec<Simulator>,
    collisions: u64,
    scratch: Vec<u8>,
}

impl Bus {
    /// A bus with no devices: every request goes unanswered.
    pub fn new() -> Self {
        Self::default()
    }

    /// Builder form of [`Bus::push`].
    #[must_use]
    pub fn with(mut self, device: Simulator) -> Self {
        self.push(device);
        self
    }

    /// Connects a device; requests reach devices in the order connected.
    pub fn push(&mut self, device: Simulator) {
        self.devices.push(device);
    }

    /// The devices, in the order they were connected.
    pub fn devices(&self) -> &[Simulator] {
        &self.devices
    }

    /// The devices, mutably.
    pub fn devices_mut(&mut self) -> &mut [Simulator] {
        &mut self.devices
    }

    /// The first device at `address`.
    pub fn device(&self, address: u8) -> Option<&Simulator> {
        self.devices.iter().find(|d| d.address() == address)
    }

    /// The first device at `address`, mutably.
    pub fn device_mut(&mut self, address: u8) -> Option<&mut Simulator> {
        self.devices.iter_mut().find(|d| d.address() == address)
    }

    /// Requests answered by more than one device.
    pub fn collisions(&self) -> u64 {
        self.collisions
    }
}

impl FrameHandler for Bus {
    fn handle(&mut self, request: &[u8], reply: &mut Vec<u8>) -> Duration {
        let start = reply.len();
        let mut answers = 0;
        let mut delay = Duration::ZERO;
        for device in &mut self.devices {
            self.scratch.clear();
            let d = device.handle(request, &mut self.scratch);
            if self.scratch.is_empty() {
                continue;
            }
            answers += 1;
            delay = delay.max(d);
            let line = reply.get_mut(start..).unwrap_or_default();
            for (on_line, &b) in line.iter_mut().zip(&self.scratch) {
                *on_line &= b;
            }
            if let Some(longer) = self.scratch.get(line.len()..) {
                reply.extend_from_slice(longer);
            }
        }
        if answers > 1 {
            self.collisions += 1;
        }
        delay
    }
}

impl Responder for Bus {
    /// [`FrameHandler::handle`]; a delayed reply is withheld, as for [`Simulator`].
    fn respond(&mut self, request: &[u8], reply: &mut Vec<u8>) {
        if !self.handle(request, reply).is_zero() {
            reply.clear();
        }
    }
}
