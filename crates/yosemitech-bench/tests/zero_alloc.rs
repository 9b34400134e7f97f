//! Zero heap allocations per encode, per decode and per transaction (issue
//! #6, design: "no allocation per transaction"), counted by a global
//! allocator on the test's own thread.
// A counting global allocator needs `unsafe impl GlobalAlloc`; it only forwards to `System`.
#![allow(unsafe_code, clippy::result_large_err)]

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::hint::black_box;
use std::time::Duration;

use yosemitech::conductivity::GetTemperatureAndConductivity;
use yosemitech::ph_orp::GetPh;
use yosemitech::rtu::Responder;
use yosemitech::{Client, ClientConfig, Command, ResponderTransport, RetryPolicy, conductivity, ph_orp};
use yosemitech_bench::{
    CONDUCTIVITY_REPLY, CONDUCTIVITY_VALUES, GET_PH_REPLY, GET_PH_REQUEST, GET_PH_VALUE, fixed_get_ph_responder,
    ph_simulator, sensor,
};

thread_local! {
    static ALLOCATIONS: Cell<usize> = const { Cell::new(0) };
}

/// Counts allocations (and reallocations, which the default `realloc`
/// routes through `alloc`) per thread, so parallel tests do not interfere.
struct Counting;

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        ALLOCATIONS.with(|n| n.set(n.get() + 1));
        // SAFETY: forwarded unchanged to the system allocator.
        unsafe { System.alloc(layout) }
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: `ptr` came from `System.alloc` with this layout.
        unsafe { System.dealloc(ptr, layout) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

/// Runs `f` and returns how many allocations it made on this thread.
fn allocations_in(f: impl FnOnce()) -> usize {
    let before = ALLOCATIONS.with(Cell::get);
    f();
    ALLOCATIONS.with(Cell::get) - before
}

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

/// Every example frame of every command of both sensors, through the
/// generated dispatch: identify and decode the request, re-encode it, decode
/// the reply and re-encode it.
macro_rules! dispatch_round_trip {
    ($module:ident, $sensor:literal) => {{
        let sensor = sensor($sensor).unwrap();
        // (command name, request, reply), copied out of the spec before counting.
        let frames: Vec<(String, Vec<u8>, Vec<u8>)> = sensor
            .commands
            .iter()
            .flat_map(|c| {
                c.examples.iter().map(|e| (c.name.clone(), e.true_request().to_vec(), e.true_response().to_vec()))
            })
            .collect();
        let ids: Vec<$module::CommandId> =
            frames.iter().map(|(name, _, _)| $module::CommandId::from_name(name).unwrap()).collect();
        let commands: std::collections::BTreeSet<_> = ids.iter().map(|id| id.name()).collect();
        assert_eq!(commands.len(), $module::CommandId::ALL.len(), "every command of {} has an example", $sensor);
        let mut out = [0u8; 256];
        for ((name, request, reply), id) in frames.iter().zip(&ids) {
            let n = allocations_in(|| {
                for _ in 0..ROUNDS {
                    assert_eq!($module::identify_request(request), Some(*id), "{name}");
                    let (slave, decoded) = id.decode_request(black_box(request)).unwrap();
                    let len = decoded.encode(slave, &mut out).unwrap();
                    assert_eq!(&out[..len], &request[..], "{name}: request re-encodes");
                    let response = $module::decode_response(*id, slave, black_box(reply)).unwrap();
                    let len = response.encode(slave, &mut out).unwrap();
                    assert_eq!(&out[..len], &reply[..], "{name}: reply re-encodes");
                    black_box(response.fields().count());
                }
            });
            assert_eq!(n, 0, "{}::{name}: allocations in {ROUNDS} round trips", $sensor);
        }
        frames.len()
    }};
}

#[test]
fn every_command_through_the_dispatch_does_not_allocate() {
    let ph = dispatch_round_trip!(ph_orp, "ph_orp");
    let cond = dispatch_round_trip!(conductivity, "conductivity");
    println!("{ph} pH/ORP and {cond} conductivity example exchanges: no allocation");
}

fn client_config() -> ClientConfig {
    ClientConfig {
        timeout: Duration::from_millis(100),
        retry: RetryPolicy::NONE,
        inter_frame_delay: Some(Duration::ZERO),
        ..ClientConfig::default()
    }
}

#[test]
fn client_transactions_do_not_allocate() {
    let mut client = Client::with_config(ResponderTransport::from_fn(fixed_get_ph_responder()), client_config());
    assert_eq!(client.call(1, &GetPh).unwrap().ph, GET_PH_VALUE);
    let n = allocations_in(|| {
        for _ in 0..ROUNDS {
            assert_eq!(client.call(1, &GetPh).unwrap().ph, GET_PH_VALUE);
            let mut probe = ph_orp::Device::new(&mut client, 1);
            assert_eq!(probe.ph().unwrap(), GET_PH_VALUE);
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
