//! The coefficient backup of every sensor (yosemitech::procedures::backup),
//! through the module as data, against each sensor's simulator: the
//! runtime's blocks are the spec's, a restore brings back every coefficient
//! and returns what it replaced, a backup that does not fit writes nothing,
//! and a failed read-back hands back the replaced coefficients.

use std::time::Duration;

use yosemitech::procedures::ProcedureError;
use yosemitech::procedures::backup::{CoefficientBackup, backup, restore};
use yosemitech::rtu::frame::{Function, MAX_ADU};
use yosemitech::rtu::transport::Responder;
use yosemitech::rtu::{CoefficientBlock, SensorModule};
use yosemitech::{Client, ResponderTransport};
use yosemitech_sim::Simulator;
use yosemitech_tests::sim::{client, simulated_modules};

/// A simulator that counts the writes reaching it and, while `drop_writes`,
/// answers them from a scratch probe instead (the echo a probe sends, with
/// nothing kept).
struct Probe {
    sim: Simulator,
    scratch: Simulator,
    writes: usize,
    drop_writes: bool,
}

impl Responder for Probe {
    fn respond(&mut self, request: &[u8], reply: &mut Vec<u8>) {
        if request.get(1) == Some(&Function::Write.code()) {
            self.writes += 1;
            if self.drop_writes {
                return self.scratch.respond(request, reply);
            }
        }
        self.sim.respond(request, reply);
    }
}

/// One probe with coefficient blocks, at its factory address, and what a
/// test starts from: its backup and a restore unlike it.
struct Case {
    module: &'static SensorModule,
    client: Client<ResponderTransport<Probe>>,
    slave: u8,
    saved: CoefficientBackup,
    changed: CoefficientBackup,
}

/// Runs `test` on the simulator of every generated module with coefficient
/// blocks (the spec has some: a test that ran on none would prove nothing).
fn for_each_probe(mut test: impl FnMut(&str, Case)) {
    let mut probes = 0;
    for (module, sim) in simulated_modules() {
        if module.coefficient_blocks().next().is_none() {
            continue;
        }
        let scratch = sim.clone();
        let probe = Probe { sim, scratch, writes: 0, drop_writes: false };
        let mut client = client(ResponderTransport::new(probe), Duration::from_millis(50));
        let slave = module.info.default_address;
        let saved = backup(&mut client, module, slave).unwrap_or_else(|e| panic!("{}: {e}", module.info.name));
        let changed = altered(module, &saved);
        test(module.info.name, Case { module, client, slave, saved, changed });
        probes += 1;
    }
    assert!(probes > 0, "the spec has sensors with coefficient blocks");
}

/// Whether the block's write accepts `data` (its ranges, finite values).
fn accepts(block: &CoefficientBlock, data: &[u8]) -> bool {
    let mut frame = [0; MAX_ADU];
    let Ok(len) = block.write.layout.encode_request(1, data, &mut frame) else { return false };
    let mut finite = true;
    let visited = block.write.visit_request(&frame[..len], &mut |_, v| {
        finite &= !matches!(v, yosemitech::rtu::FieldValue::F32(f) if !f.is_finite());
    });
    visited.is_ok() && finite && block.write.reencode_request(&frame[..len], &mut [0; MAX_ADU]).is_ok()
}

/// A backup unlike `saved` that every block's write accepts: each block's
/// bytes all one value, so every `f32` reads the same in any byte order.
fn altered(module: &SensorModule, saved: &CoefficientBackup) -> CoefficientBackup {
    let mut changed = saved.clone();
    for (block, slot) in module.coefficient_blocks().zip(&mut changed.blocks) {
        let data = [0x3F, 0x40, 0xBF, 0x41]
            .into_iter()
            .map(|byte| vec![byte; slot.data.len()])
            .find(|data| *data != slot.data && accepts(&block, data))
            .unwrap_or_else(|| panic!("{}: no changed coefficients the write accepts", block.write.name));
        slot.data = data;
    }
    changed
}

#[test]
fn every_modules_blocks_are_the_specs() {
    for module in yosemitech::SENSORS {
        let sensor = yosemitech_tests::spec().sensor(module.info.name).expect("every module is in the spec");
        let ours: Vec<(&str, &str)> = module.coefficient_blocks().map(|b| (b.write.name, b.read.name)).collect();
        let spec: Vec<(&str, &str)> =
            sensor.coefficient_blocks().iter().map(|(w, r)| (w.name.as_str(), r.name.as_str())).collect();
        assert_eq!(ours, spec, "{}", module.info.name);
    }
}

#[test]
fn a_restore_brings_back_every_coefficient_and_returns_what_it_replaced() {
    for_each_probe(|name, Case { module, mut client, slave, saved, changed }| {
        assert_eq!(saved.sensor, name);
        for (block, backed_up) in module.coefficient_blocks().zip(&saved.blocks) {
            assert_eq!(backed_up.write, block.write.name, "{name}");
            assert_eq!(backed_up.data.len(), block.read.layout.data_len(), "{name}: {}", block.write.name);
        }
        assert_eq!(restore(&mut client, module, slave, &changed).unwrap(), saved, "{name}: what it replaced");
        assert_eq!(backup(&mut client, module, slave).unwrap(), changed, "{name}: the probe holds the restore");
        // Each changed block is one byte throughout: every value is that byte four times.
        let values = changed.values(module);
        for block in &changed.blocks {
            let of_block: Vec<f32> = values.iter().filter(|(b, ..)| *b == block.write).map(|v| v.2).collect();
            assert!(!of_block.is_empty(), "{name}: {} has values", block.write);
            let bits = u32::from_ne_bytes([block.data[0]; 4]);
            assert!(of_block.iter().all(|v| v.to_bits() == bits), "{name}: {} {of_block:?}", block.write);
        }
        assert_eq!(restore(&mut client, module, slave, &saved).unwrap(), changed, "{name}: what it replaced");
        assert_eq!(backup(&mut client, module, slave).unwrap(), saved, "{name}: back where it started");
    });
}

#[test]
fn a_backup_that_does_not_fit_writes_nothing() {
    for_each_probe(|name, Case { module, mut client, slave, saved, changed }| {
        let mut unfit: Vec<(&str, CoefficientBackup)> = Vec::new();
        let mut other = changed.clone();
        other.sensor.push_str("_other");
        unfit.push(("another sensor's", other));
        let mut missing = changed.clone();
        missing.blocks.pop();
        unfit.push(("a block missing", missing));
        let mut stray = changed.clone();
        stray.blocks[0].write.push_str("_stray");
        unfit.push(("a block the sensor lacks", stray));
        let mut short = changed.clone();
        short.blocks[0].data.truncate(2);
        unfit.push(("a block of another length", short));
        let mut nan = changed.clone();
        nan.blocks[0].data.fill(0xFF);
        unfit.push(("a NaN", nan));
        for (what, backup_) in unfit {
            let error = restore(&mut client, module, slave, &backup_).expect_err(what);
            assert!(
                matches!(error, ProcedureError::BackupDoesNotFit { .. } | ProcedureError::NotFinite { .. }),
                "{name}, {what}: {error}"
            );
            assert_eq!(client.transport().responder().writes, 0, "{name}, {what}: nothing is written");
        }
        assert_eq!(backup(&mut client, module, slave).unwrap(), saved, "{name}: the probe is as it was");
    });
}

#[test]
fn a_failed_read_back_hands_back_what_the_probe_held() {
    for_each_probe(|name, Case { module, mut client, slave, saved, changed }| {
        client.transport_mut().responder_mut().drop_writes = true;
        match restore(&mut client, module, slave, &changed) {
            Err(ProcedureError::RestoreInterrupted { replaced, cause }) => {
                assert_eq!(*replaced, saved, "{name}");
                assert!(matches!(*cause, ProcedureError::ReadBackMismatch { .. }), "{name}: {cause}");
            }
            other => panic!("{name}: a write the probe did not keep is not a restore: {other:?}"),
        }
    });
}
