//! Requests: routing a frame to a command, applying it and building the reply.

use std::sync::Arc;
use std::time::Duration;

use yosemitech_rtu::bytes::{byte, word};
use yosemitech_rtu::frame::{BROADCAST, REQUEST_BYTE_COUNT_AT};
use yosemitech_rtu::{ExceptionCode, Function, Layout, Responder, crc_ok, segment};
use yosemitech_spec::interp::decode_field;
use yosemitech_spec::{Role, Value};

use crate::FrameHandler;
use crate::behaviour::{MeasurementState, WarmUpPolicy};
use crate::fault::FaultKind;

use super::Simulator;
use super::frames::{check_ranges, prints_empty_reply, push_exception, push_frame, requirk, shorten_to_empty};

/// What the device does with a request that matches no command of its
/// sensor: an unknown function code, an address no command uses, a known
/// address with another register count, or a malformed frame (a read not 8
/// bytes long, a write whose byte count is not `2 * count` or not the
/// frame's length).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum UnknownRequestPolicy {
    /// No reply, as a real probe: the client times out (the default).
    /// Counted in [`Stats::ignored_unknown`](crate::Stats::ignored_unknown).
    #[default]
    Silent,
    /// A Modbus exception reply: 01 (illegal function) for an unknown
    /// function, 02 (illegal data address) for an address no command of that
    /// function uses, 03 (illegal data value) for a known address with
    /// another count or a malformed frame. Counted in
    /// [`Stats::exceptions`](crate::Stats::exceptions).
    Exception,
}

/// How a request reached the device.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Route {
    /// To its own address: the device answers.
    Unicast,
    /// To address 0: applied, never answered.
    Broadcast,
    /// To a command's `fixed_slave` address (get_slave_id: 0xFF).
    Wildcard(u8),
}

impl Simulator {
    fn route(&self, slave: u8) -> Option<Route> {
        if slave == self.address {
            Some(Route::Unicast)
        } else if slave == BROADCAST {
            Some(Route::Broadcast)
        } else if self.wildcards.contains(&slave) {
            Some(Route::Wildcard(slave))
        } else {
            None
        }
    }

    /// Finds the command a request is for, and the write's data.
    fn lookup<'r>(&self, request: &'r [u8], route: Route) -> Result<(usize, &'r [u8]), ExceptionCode> {
        let code = byte(request, 1).unwrap_or(0);
        if !self.functions.contains(&code) {
            return Err(ExceptionCode::IllegalFunction);
        }
        let function = Function::from_code(code).ok_or(ExceptionCode::IllegalFunction)?;
        let (address, count) = (word(request, 2).unwrap_or(0), word(request, 4).unwrap_or(0));
        if segment::request_len(request) != Some(request.len()) {
            return Err(ExceptionCode::IllegalDataValue);
        }
        let data: &[u8] = match function {
            Function::Read => &[],
            Function::Write => {
                let byte_count = usize::from(byte(request, REQUEST_BYTE_COUNT_AT).unwrap_or(0));
                if byte_count != 2 * usize::from(count) {
                    return Err(ExceptionCode::IllegalDataValue);
                }
                let data = REQUEST_BYTE_COUNT_AT + 1;
                request.get(data..data + byte_count).ok_or(ExceptionCode::IllegalDataValue)?
            }
        };
        let mut candidates = self.sensor.commands.iter().enumerate().filter(|(_, c)| {
            c.function == function
                && match route {
                    Route::Wildcard(slave) => c.fixed_slave == Some(slave),
                    Route::Unicast | Route::Broadcast => true,
                }
        });
        let mut known_address = false;
        for (index, c) in &mut candidates {
            if c.address == address {
                if c.count == count {
                    return Ok((index, data));
                }
                known_address = true;
            }
        }
        Err(if known_address { ExceptionCode::IllegalDataValue } else { ExceptionCode::IllegalDataAddress })
    }

    /// Carries out a request for command `index` (with the write's `data`,
    /// found by [`Simulator::lookup`]); writes the normal reply to
    /// `self.out` (unless broadcast) and returns the new slave address if it
    /// changes.
    fn process(
        &mut self,
        request: &[u8],
        route: Route,
        index: usize,
        data: &[u8],
    ) -> Result<Option<u8>, ExceptionCode> {
        let sensor = Arc::clone(&self.sensor);
        let command = sensor.commands.get(index).ok_or(ExceptionCode::ServerDeviceFailure)?;
        let layout = Layout {
            fixed_slave: if matches!(route, Route::Wildcard(_)) { command.fixed_slave } else { None },
            ..command.layout()
        };
        let slave = byte(request, 0).unwrap_or(0);
        if command.is_read() {
            if route == Route::Broadcast {
                return Ok(None);
            }
            if self.warm_up_policy == WarmUpPolicy::Busy
                && self.measurement.get(index).copied().unwrap_or(false)
                && self.measurement_state() != MeasurementState::Measuring
            {
                return Err(ExceptionCode::ServerDeviceBusy);
            }
            self.vary(index, command);
            self.show_standard(index, command);
            self.stats.reads += 1;
            // A trigger read's reply carries no value: the layout writes the manuals' form.
            let data = if command.trigger {
                Vec::new()
            } else {
                self.registers_of(index).read(command.address, command.count)
            };
            push_frame(&mut self.out, layout.response_len(), |buf| layout.encode_response(slave, &data, buf))?;
            if command.trigger && prints_empty_reply(command) {
                // The manual prints the 5-byte form (byte count 0, no data), CRC and all.
                shorten_to_empty(&mut self.out);
            }
            let now = self.clock.now();
            self.behaviour.on_command(index, now);
            if self.byte_count_quirk
                && let Some(&quirk) = command.extra_byte_counts.first()
            {
                requirk(&mut self.out, quirk);
            }
            Ok(None)
        } else {
            check_ranges(command, data)?;
            let address_field = self
                .address_slots
                .iter()
                .find(|s| Some(s.command) == self.set_address_command && s.command == index)
                .map(|s| &s.field);
            let new_address = match address_field {
                Some(field) => {
                    let value = data.get(field.offset..field.offset + field.size()).map(|b| decode_field(field, b));
                    match value {
                        Some(Value::Int(a))
                            if (i64::from(sensor.min_address)..=i64::from(sensor.max_address)).contains(&a) =>
                        {
                            u8::try_from(a).ok()
                        }
                        _ => return Err(ExceptionCode::IllegalDataValue),
                    }
                }
                None => None,
            };
            self.registers.write(command.address, data);
            let now = self.clock.now();
            self.behaviour.on_write(command, index, data, &mut self.registers, now);
            self.stats.writes += 1;
            if route != Route::Broadcast {
                push_frame(&mut self.out, layout.response_len(), |buf| layout.encode_response(slave, &[], buf))?;
            }
            Ok(new_address)
        }
    }
}

impl FrameHandler for Simulator {
    fn handle(&mut self, request: &[u8], reply: &mut Vec<u8>) -> Duration {
        self.stats.requests += 1;
        if request.len() < 4 || !crc_ok(request) {
            self.stats.ignored_bad_crc += 1;
            return Duration::ZERO;
        }
        let slave = byte(request, 0).unwrap_or(0);
        let function = byte(request, 1).unwrap_or(0);
        let Some(route) = self.route(slave) else {
            self.stats.ignored_other_slave += 1;
            return Duration::ZERO;
        };
        self.out.clear();
        let found = self.lookup(request, route);
        if route == Route::Broadcast {
            self.stats.broadcasts += 1;
            if let Ok((index, data)) = found
                && let Ok(Some(address)) = self.process(request, route, index, data)
            {
                self.stats.address_changes += 1;
                self.set_address(address);
            }
            self.out.clear();
            return Duration::ZERO;
        }
        if found.is_err() {
            if matches!(route, Route::Wildcard(_)) {
                self.stats.ignored_other_slave += 1;
                return Duration::ZERO;
            }
            if self.unknown_request_policy == UnknownRequestPolicy::Silent {
                self.stats.ignored_unknown += 1;
                return Duration::ZERO;
            }
        }
        let reply_slave = if matches!(route, Route::Wildcard(_)) { slave } else { self.address };
        self.stats.replies += 1;
        let fault = self.injector.draw();
        let mut new_address = None;
        if fault == Some(FaultKind::Busy) {
            push_exception(&mut self.out, reply_slave, function, ExceptionCode::ServerDeviceBusy);
        } else if self.refuses_start
            && let Ok((index, _)) = found
            && self.sensor.commands.get(index).is_some_and(|c| c.role == Some(Role::StartMeasurement))
        {
            // As a real Y533: the start is refused, the probe measures anyway.
            self.stats.exceptions += 1;
            push_exception(&mut self.out, reply_slave, function, ExceptionCode::IllegalFunction);
        } else {
            match found.and_then(|(index, data)| self.process(request, route, index, data)) {
                Ok(address) => new_address = address,
                Err(code) => {
                    self.stats.exceptions += 1;
                    self.out.clear();
                    push_exception(&mut self.out, reply_slave, function, code);
                }
            }
        }
        let delay = match fault {
            Some(kind) if kind != FaultKind::Busy => self.injector.apply(kind, &mut self.out),
            _ => Duration::ZERO,
        };
        reply.extend_from_slice(&self.out);
        // After the reply: it came from the old address.
        if let Some(address) = new_address {
            self.stats.address_changes += 1;
            self.set_address(address);
        }
        delay
    }
}

impl Responder for Simulator {
    /// [`FrameHandler::handle`]; a delayed reply is withheld (it cannot arrive
    /// late in-process, and a client has given up on it by then).
    fn respond(&mut self, request: &[u8], reply: &mut Vec<u8>) {
        if !self.handle(request, reply).is_zero() {
            reply.clear();
        }
    }
}
