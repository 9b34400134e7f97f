//! Zero heap allocations per encode, per decode and per transaction (issue
//! #6, design: "no allocation per transaction"), counted by a global
//! allocator on the test's own thread (`yosemitech_tests::counting_alloc`).

use std::hint::black_box;
use std::time::Duration;

use yosemitech::conductivity::GetTemperatureAndConductivity;
use yosemitech::ph_orp::GetPh;
use yosemitech::rtu::Responder;
use yosemitech::{Client, ClientConfig, Command, ResponderTransport, ph_orp};
use yosemitech_bench::{
    CONDUCTIVITY_REPLY, CONDUCTIVITY_VALUES, GET_PH_REPLY, GET_PH_REQUEST, GET_PH_VALUE, fixed_get_ph_responder,
    ph_simulator, sensor, unpaced_config,
};
use yosemitech_tests::counting_alloc::{CountingAllocator, allocations_in};

#[global_allocator]
static GLOBAL: CountingAllocator = CountingAllocator;

const ROUNDS: usize = 100;

#[test]
fn the_counter_counts() {
    assert_eq!(allocations_in(|| drop(black_box(vec![1u8]))), 1);
    assert_eq!(allocations_in(|| drop(black_box(Box::new(1u64)))), 1);
}

#[test]
fn generated_codecs_do_not_allocate() {
    let mut out = [0u8; 256];
    let n = allocations_in(|| {
        for _ in 0..ROUNDS {
            let len = black_box(&GetPh).encode_request(1, &mut out).unwrap();
            assert_eq!(out[..len], GET_PH_REQUEST);
        }
    });
    assert_eq!(n, 0, "allocations in {ROUNDS} get_ph encodes");

    let n = allocations_in(|| {
        for _ in 0..ROUNDS {
            assert_eq!(GetPh::decode_response(1, black_box(&GET_PH_REPLY)).unwrap().ph, GET_PH_VALUE);
        }
    });
    assert_eq!(n, 0, "allocations in {ROUNDS} get_ph decodes");

    let n = allocations_in(|| {
        for _ in 0..ROUNDS {
            let reading = GetTemperatureAndConductivity::decode_response(1, black_box(&CONDUCTIVITY_REPLY)).unwrap();
            assert_eq!((reading.temperature_c, reading.conductivity_ms_cm), CONDUCTIVITY_VALUES);
        }
    });
    assert_eq!(n, 0, "allocations in {ROUNDS} conductivity decodes");

    // Errors are allocation-free too: a corrupted CRC and a wrong slave.
    let mut bad = GET_PH_REPLY;
    bad[4] ^= 1;
    let n = allocations_in(|| {
        assert!(GetPh::decode_response(1, black_box(&bad)).is_err());
        assert!(GetPh::decode_response(2, black_box(&GET_PH_REPLY)).is_err());
    });
    assert_eq!(n, 0, "allocations in rejected decodes");
}

/// Every complete example frame pair of every command of every sensor,
/// through the generated dispatch (`yosemitech::SENSORS`, no sensor named):
/// identify and decode the request, re-encode it, decode the reply and
/// re-encode it, visit its fields.
#[test]
fn every_command_through_the_dispatch_does_not_allocate() {
    let mut exchanges = 0usize;
    let mut commands_covered = 0usize;
    for module in yosemitech::SENSORS {
        let sensor = sensor(module.info.name).unwrap();
        // (command name, trigger, request, reply), copied out of the spec before counting.
        let frames: Vec<(String, bool, Vec<u8>, Vec<u8>)> = sensor
            .commands
            .iter()
            .flat_map(|c| {
                c.examples.iter().filter_map(|e| {
                    let (request, reply) = e.true_pair()?;
                    Some((c.name.clone(), c.trigger, request.to_vec(), reply.to_vec()))
                })
            })
            .collect();
        let with_pairs: std::collections::BTreeSet<&str> = frames.iter().map(|(n, ..)| n.as_str()).collect();
        commands_covered += with_pairs.len();
        let mut out = [0u8; 256];
        for (name, trigger, request, reply) in &frames {
            let slave = request[0];
            let n = allocations_in(|| {
                for _ in 0..ROUNDS {
                    assert_eq!(module.identify_request(request), Some(name.as_str()), "{name}");
                    let len = module.reencode_request(name, black_box(request), &mut out).unwrap().unwrap();
                    assert_eq!(&out[..len], &request[..], "{name}: request re-encodes");
                    let len = module.reencode_response(name, slave, black_box(reply), &mut out).unwrap().unwrap();
                    if !trigger {
                        assert_eq!(&out[..len], &reply[..], "{name}: reply re-encodes");
                    }
                    let mut fields = 0usize;
                    module.visit_response(name, slave, black_box(reply), &mut |_, _| fields += 1).unwrap().unwrap();
                    black_box(fields);
                }
            });
            assert_eq!(n, 0, "{}::{name}: allocations in {ROUNDS} round trips", module.info.name);
        }
        exchanges += frames.len();
    }
    assert!(commands_covered > 0);
    println!("{exchanges} example exchanges over {commands_covered} commands: no allocation");
}

fn client_config() -> ClientConfig {
    unpaced_config(Duration::from_millis(100))
}

#[test]
fn client_transactions_do_not_allocate() {
    let mut client = Client::with_config(ResponderTransport::from_fn(fixed_get_ph_responder()), client_config());
    assert_eq!(client.call(1, &GetPh).unwrap().ph, GET_PH_VALUE);
    let n = allocations_in(|| {
        for _ in 0..ROUNDS {
            assert_eq!(client.call(1, &GetPh).unwrap().ph, GET_PH_VALUE);
            let mut probe = ph_orp::Device::new(&mut client, 1);
            assert_eq!(probe.ph().unwrap().ph, GET_PH_VALUE);
        }
    });
    assert_eq!(n, 0, "allocations in {} client transactions", 2 * ROUNDS);
}

/// The simulator allocates per request (its register read returns a
/// `Vec`); the client adds nothing to that.
#[test]
fn the_client_adds_no_allocation_to_the_simulators() {
    let mut sim = ph_simulator().unwrap();
    let mut reply = Vec::with_capacity(256);
    sim.respond(&GET_PH_REQUEST, &mut reply);
    let simulator_alone = allocations_in(|| {
        for _ in 0..ROUNDS {
            reply.clear();
            sim.respond(black_box(&GET_PH_REQUEST), &mut reply);
            assert_eq!(reply, GET_PH_REPLY);
        }
    });

    let mut client = Client::with_config(ResponderTransport::new(sim), client_config());
    assert_eq!(client.call(1, &GetPh).unwrap().ph, GET_PH_VALUE);
    let with_client = allocations_in(|| {
        for _ in 0..ROUNDS {
            assert_eq!(client.call(1, &GetPh).unwrap().ph, GET_PH_VALUE);
        }
    });
    println!(
        "allocations per get_ph: simulator alone {:.1}, client + simulator {:.1}",
        simulator_alone as f64 / ROUNDS as f64,
        with_client as f64 / ROUNDS as f64
    );
    assert_eq!(with_client, simulator_alone, "the client's share of {ROUNDS} transactions with the simulator");
}

/// Every derived quantity of every sensor (`SensorModule::derived`, no
/// sensor named), computed at its examples' inputs and at inputs it
/// refuses, through the generated functions.
#[test]
fn derived_quantities_do_not_allocate() {
    let mut computed = 0usize;
    for module in yosemitech::SENSORS {
        let sensor = sensor(module.info.name).unwrap();
        for (d, info) in sensor.derived.iter().zip(module.derived) {
            let mut cases: Vec<Vec<f32>> = d.examples.iter().map(|e| d.example_inputs(e).unwrap()).collect();
            cases.push(vec![f32::NAN; d.inputs.len()]);
            cases.push(vec![0.0; d.inputs.len() + 1]);
            let n = allocations_in(|| {
                for inputs in &cases {
                    let _ = black_box((info.compute)(black_box(inputs)));
                }
            });
            assert_eq!(n, 0, "allocations computing {}.{}", sensor.name, d.name);
            computed += cases.len();
        }
    }
    yosemitech_tests::report!("derived quantities: {computed} computations without an allocation");
}
