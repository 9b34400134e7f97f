//! The coefficient backup of every sensor (yosemitech::procedures::backup),
//! through the module as data, against each sensor's simulator: the
//! runtime's blocks are the spec's, a restore brings back every coefficient
//! and returns what it replaced, a backup that does not fit writes nothing,
//! and a failed read-back or a reply lost at any step hands back the
//! replaced coefficients, which restore the probe; a backup kept as text
//! reads back as it was and restores the probe.

use std::time::Duration;

use proptest::prelude::*;

use yosemitech::procedures::ProcedureError;
use yosemitech::procedures::backup::{BlockBackup, CoefficientBackup, backup, restore};
use yosemitech::rtu::frame::{Function, MAX_ADU};
use yosemitech::rtu::transport::Responder;
use yosemitech::rtu::{CoefficientBlock, SensorModule};
use yosemitech::{Client, ResponderTransport};
use yosemitech_sim::Simulator;
use yosemitech_tests::sim::{client, f32_bytes, simulated_modules};

/// A simulator that counts the writes reaching it and, while `drop_writes`,
/// answers them from a scratch probe instead (the echo a probe sends, with
/// nothing kept). With `lose_reply_at`, the reply to that request (counted
/// in `requests` from 0) is lost on the way back: the probe acts on it.
struct Probe {
    sim: Simulator,
    scratch: Simulator,
    writes: usize,
    drop_writes: bool,
    requests: usize,
    lose_reply_at: Option<usize>,
}

impl Responder for Probe {
    fn respond(&mut self, request: &[u8], reply: &mut Vec<u8>) {
        let index = self.requests;
        self.requests += 1;
        if self.lose_reply_at == Some(index) {
            self.sim.respond(request, &mut Vec::new());
            return;
        }
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
    /// Each coefficient of `changed` (block, value), in wire order.
    changed_values: Vec<(String, f32)>,
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
        let probe = Probe { sim, scratch, writes: 0, drop_writes: false, requests: 0, lose_reply_at: None };
        let mut client = client(ResponderTransport::new(probe), Duration::from_millis(50));
        let slave = module.info.default_address;
        let saved = backup(&mut client, module, slave).unwrap_or_else(|e| panic!("{}: {e}", module.info.name));
        let (changed, changed_values) = altered(module, &saved);
        test(module.info.name, Case { module, client, slave, saved, changed, changed_values });
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

/// A backup unlike `saved` that every block's write accepts, and the value
/// of each coefficient in it (block, value), in wire order. Each value is
/// chosen from the spec's field (inside its range, unlike the saved one)
/// and placed in the field's byte order.
fn altered(module: &SensorModule, saved: &CoefficientBackup) -> (CoefficientBackup, Vec<(String, f32)>) {
    let sensor = yosemitech_tests::spec().sensor(module.info.name).expect("every module is in the spec");
    let mut changed = saved.clone();
    let mut values = Vec::new();
    for (block, slot) in module.coefficient_blocks().zip(&mut changed.blocks) {
        let write = sensor.commands.iter().find(|c| c.name == slot.write).expect("the block's write is in the spec");
        for field in write.fields.iter().filter(|f| f.name.is_some()) {
            let span = field.offset..field.offset + 4;
            let candidates = match field.range {
                Some((min, max)) => [0.5, 0.25, 0.75].map(|k| (min + (max - min) * k) as f32),
                None => [0.75, 1.5, -2.25],
            };
            let value = candidates
                .into_iter()
                .find(|v| f32_bytes(field, *v)[..] != slot.data[span.clone()])
                .unwrap_or(candidates[0]);
            slot.data[span].copy_from_slice(&f32_bytes(field, value));
            values.push((slot.write.clone(), value));
        }
        assert!(accepts(&block, &slot.data), "{}: the write accepts values inside its ranges", block.write.name);
    }
    assert_ne!(changed, *saved, "{}: a changed backup", module.info.name);
    (changed, values)
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
    for_each_probe(|name, Case { module, mut client, slave, saved, changed, changed_values }| {
        assert_eq!(saved.sensor, name);
        for (block, backed_up) in module.coefficient_blocks().zip(&saved.blocks) {
            assert_eq!(backed_up.write, block.write.name, "{name}");
            assert_eq!(backed_up.data.len(), block.read.layout.data_len(), "{name}: {}", block.write.name);
        }
        assert_eq!(restore(&mut client, module, slave, &changed).unwrap(), saved, "{name}: what it replaced");
        assert_eq!(backup(&mut client, module, slave).unwrap(), changed, "{name}: the probe holds the restore");
        let shown: Vec<(String, u32)> =
            changed.values(module).into_iter().map(|(block, _, v)| (block.to_owned(), v.to_bits())).collect();
        let set: Vec<(String, u32)> = changed_values.iter().map(|(block, v)| (block.clone(), v.to_bits())).collect();
        assert_eq!(shown, set, "{name}: the values shown are those restored");
        // A second restore, not of `saved`: a simulator may start with values
        // outside a write's range, which a restore refuses to write.
        let (again, _) = altered(module, &changed);
        assert_eq!(restore(&mut client, module, slave, &again).unwrap(), changed, "{name}: what it replaced");
        assert_eq!(backup(&mut client, module, slave).unwrap(), again, "{name}: the probe holds the second restore");
    });
}

#[test]
fn a_backup_that_does_not_fit_writes_nothing() {
    for_each_probe(|name, Case { module, mut client, slave, saved, changed, .. }| {
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
    for_each_probe(|name, Case { module, mut client, slave, saved, changed, .. }| {
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

#[test]
fn a_reply_lost_at_any_step_of_a_restore_loses_no_coefficient() {
    for_each_probe(|name, Case { module, mut client, slave, changed, .. }| {
        // From `changed` to another in-range backup: the simulator's own
        // start values may be outside a write's range.
        let (target, _) = altered(module, &changed);
        let mut interrupted = 0;
        for lost in 0.. {
            assert!(lost < 256, "{name}: a restore is a bounded number of exchanges");
            restore(&mut client, module, slave, &changed).unwrap_or_else(|e| panic!("{name}: reset: {e}"));
            let probe = client.transport_mut().responder_mut();
            (probe.requests, probe.lose_reply_at) = (0, Some(lost));
            let result = restore(&mut client, module, slave, &target);
            let probe = client.transport_mut().responder_mut();
            let fired = probe.requests > lost;
            probe.lose_reply_at = None;
            match result {
                Ok(replaced) => {
                    assert!(!fired, "{name}, reply {lost} lost: a restore cannot succeed without a reply");
                    assert_eq!(replaced, changed, "{name}: what it replaced");
                    assert_eq!(backup(&mut client, module, slave).unwrap(), target, "{name}: the probe holds it");
                    break;
                }
                Err(ProcedureError::RestoreInterrupted { replaced, cause }) => {
                    assert!(fired, "{name}, reply {lost}: interrupted by {cause}");
                    assert_eq!(*replaced, changed, "{name}, reply {lost} lost: what the probe held");
                    interrupted += 1;
                    // The coefficients handed back restore the probe.
                    restore(&mut client, module, slave, &replaced)
                        .unwrap_or_else(|e| panic!("{name}, reply {lost} lost: restoring what it replaced: {e}"));
                }
                // Lost before the first write: the probe was not touched.
                Err(error) => assert!(fired, "{name}, reply {lost}: {error}"),
            }
            assert_eq!(backup(&mut client, module, slave).unwrap(), changed, "{name}, reply {lost} lost: nothing lost");
        }
        assert!(interrupted > 0, "{name}: some lost reply falls after a write");
    });
}

#[test]
fn a_backup_kept_as_text_restores_the_probe() {
    for_each_probe(|name, Case { module, mut client, slave, changed, .. }| {
        let kept = changed.to_string();
        let read: CoefficientBackup = kept.parse().unwrap_or_else(|e| panic!("{name}: {kept}: {e}"));
        assert_eq!(read, changed, "{name}: {kept}");
        restore(&mut client, module, slave, &read).unwrap_or_else(|e| panic!("{name}: {e}"));
        assert_eq!(backup(&mut client, module, slave).unwrap(), changed, "{name}: the probe holds the kept backup");
    });
}

#[test]
fn a_damaged_backup_text_is_refused() {
    let kept = "probe: set_one [3F80 0000] set_two [0102]";
    assert!(kept.parse::<CoefficientBackup>().is_ok());
    for (damaged, at) in [
        ("probe set_one [3F80 0000]", 0),
        ("the probe: set_one [3F80]", 0),
        ("probe: set_one [3F80 0000] set_two [0102", 27),
        ("probe: set_one 3F80 0000]", 7),
        ("probe: set_one [3F8 0000]", 7),
        ("probe: set_one [+F80 0000]", 7),
        ("probe: set_one [3G80 0000]", 7),
        ("probe: set one [3F80 0000]", 7),
        ("probe: set_one [3F80] ]", 22),
    ] {
        let error = damaged.parse::<CoefficientBackup>().expect_err(damaged);
        assert_eq!(error.at, at, "{damaged}: {error}");
        assert!(error.to_string().contains(error.reason), "{error}");
    }
}

/// A backup as `backup` makes them: spec names (one snake_case word each)
/// and register data.
fn any_backup() -> impl Strategy<Value = CoefficientBackup> {
    let block = ("[a-z][a-z0-9_]{0,24}", proptest::collection::vec(any::<u8>(), 0..64))
        .prop_map(|(write, data)| BlockBackup { write, data });
    ("[a-z][a-z0-9_]{0,24}", proptest::collection::vec(block, 0..6))
        .prop_map(|(sensor, blocks)| CoefficientBackup { sensor, blocks })
}

proptest! {
    #[test]
    fn every_backup_reads_back_from_its_text(saved in any_backup()) {
        prop_assert_eq!(saved.to_string().parse::<CoefficientBackup>(), Ok(saved));
    }

    #[test]
    fn any_text_is_read_or_refused_and_what_reads_is_its_own_text(text in "\\PC{0,80}|[a-z_ :\\[\\]0-9A-Fa-f+]{0,80}") {
        if let Ok(read) = text.parse::<CoefficientBackup>() {
            prop_assert_eq!(read.to_string().parse::<CoefficientBackup>(), Ok(read));
        }
    }
}
