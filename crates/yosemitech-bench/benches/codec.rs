//! CRC, request encoding and reply decoding: the generated codecs against
//! the `crc` crate and `rmodbus`, each comparison in one criterion group so
//! the ratios come from the same run.
//!
//! `tokio-modbus` (0.17) is not compared: its RTU codec is `pub(crate)`.
// `criterion_group!` generates an undocumented `pub fn`.
#![allow(missing_docs)]

use std::hint::black_box;
use std::time::Duration;

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use yosemitech::Command;
use yosemitech::conductivity::GetTemperatureAndConductivity;
use yosemitech::ph_orp::GetPh;
use yosemitech_bench::{CONDUCTIVITY_REPLY, GET_PH_REPLY, crc_ref, rmodbus_ref};

fn crc(c: &mut Criterion) {
    // Deterministic, non-trivial data (a frame-like prefix, then a ramp).
    let data: Vec<u8> = (0..256u32).map(|i| (i.wrapping_mul(151) ^ 0x5A) as u8).collect();
    for len in [8usize, 13, 256] {
        let bytes = &data[..len];
        let mut group = c.benchmark_group(format!("crc16_{len}"));
        group.throughput(Throughput::Bytes(len as u64));
        group.bench_function("yosemitech", |b| b.iter(|| yosemitech_rtu::crc16(black_box(bytes))));
        group.bench_function("crc_table1", |b| b.iter(|| crc_ref::TABLE_1.checksum(black_box(bytes))));
        group.bench_function("crc_table16", |b| b.iter(|| crc_ref::TABLE_16.checksum(black_box(bytes))));
        group.finish();
    }
}

fn encode(c: &mut Criterion) {
    let mut group = c.benchmark_group("encode_get_ph");
    let mut out = [0u8; 256];
    group.bench_function("yosemitech", |b| {
        b.iter(|| black_box(&GetPh).encode_request(black_box(1), &mut out).map(|n| out[n - 1]))
    });
    let (mut request, mut frame) = rmodbus_ref::read_request(0x2800, 2).expect("rmodbus generates get_ph");
    group.bench_function("rmodbus", |b| {
        b.iter(|| rmodbus_ref::encode_get_ph(black_box(&mut request), &mut frame).map(|()| frame.last().copied()))
    });
    group.finish();
}

fn decode(c: &mut Criterion) {
    let mut group = c.benchmark_group("decode_get_ph");
    assert_eq!(GetPh::decode_response(1, &GET_PH_REPLY).map(|r| r.ph), Ok(7.6));
    group.bench_function("yosemitech", |b| b.iter(|| GetPh::decode_response(black_box(1), black_box(&GET_PH_REPLY))));
    let (ph, _) = rmodbus_ref::read_request(0x2800, 2).expect("rmodbus generates get_ph");
    assert_eq!(rmodbus_ref::decode_get_ph(&ph, &GET_PH_REPLY).ok(), Some(7.6));
    group
        .bench_function("rmodbus", |b| b.iter(|| rmodbus_ref::decode_get_ph(black_box(&ph), black_box(&GET_PH_REPLY))));
    group.finish();

    let mut group = c.benchmark_group("decode_conductivity");
    assert!(GetTemperatureAndConductivity::decode_response(1, &CONDUCTIVITY_REPLY).is_ok());
    group.bench_function("yosemitech", |b| {
        b.iter(|| GetTemperatureAndConductivity::decode_response(black_box(1), black_box(&CONDUCTIVITY_REPLY)))
    });
    let (cond, _) = rmodbus_ref::read_request(0x2600, 5).expect("rmodbus generates the read");
    assert!(rmodbus_ref::decode_conductivity(&cond, &CONDUCTIVITY_REPLY).is_ok());
    group.bench_function("rmodbus", |b| {
        b.iter(|| rmodbus_ref::decode_conductivity(black_box(&cond), black_box(&CONDUCTIVITY_REPLY)))
    });
    group.finish();
}

/// Every complete example reply of every sensor of the spec, decoded by
/// name through the generated dispatch (`yosemitech::SENSORS`): the cost of
/// the family's replies, with no sensor named here.
fn decode_every_example(c: &mut Criterion) {
    let mut group = c.benchmark_group("decode_every_example");
    for module in yosemitech::SENSORS {
        let Ok(sensor) = yosemitech_bench::sensor(module.info.name) else { continue };
        for command in sensor.commands.iter().filter(|c| c.is_read()) {
            let Some(example) = command.examples.iter().find(|e| e.true_pair().is_some()) else { continue };
            let Some(reply) = example.true_response().map(<[u8]>::to_vec) else { continue };
            let slave = example.slave();
            let name = command.name.clone();
            let decoded = module.visit_response(&name, slave, &reply, &mut |_, _| {});
            assert_eq!(decoded, Some(Ok(())), "{}.{name}", module.info.name);
            group.bench_function(format!("{}/{name}", module.info.name), |b| {
                b.iter(|| {
                    let mut fields = 0usize;
                    let _ = module.visit_response(&name, black_box(slave), black_box(&reply), &mut |_, _| fields += 1);
                    fields
                })
            });
        }
    }
    group.finish();
}

criterion_group! {
    name = benches;
    // Short defaults for a shared machine; `-- --measurement-time N` overrides.
    config = Criterion::default().warm_up_time(Duration::from_secs(1)).measurement_time(Duration::from_secs(3));
    targets = crc, encode, decode, decode_every_example
}
criterion_main!(benches);
