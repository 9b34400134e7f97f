//! One get_ph transaction through `Client::call` over the in-memory
//! `ResponderTransport`, no line timing: the CPU cost of a transaction
//! (encode, CRC, transport calls, frame checks, decode).
//!
//! `simulator` answers with the spec-driven simulator (its own lookup and
//! encoding included); `fixed_reply` with a closure that copies the manual's
//! reply, which leaves the client's own cost.
// `criterion_group!` generates an undocumented `pub fn`.
#![allow(missing_docs)]

use std::hint::black_box;
use std::time::Duration;

use criterion::{Criterion, criterion_group, criterion_main};
use yosemitech::ph_orp::GetPh;
use yosemitech::{Client, ClientConfig, ResponderTransport, Transport};
use yosemitech_bench::{GET_PH_VALUE, fixed_get_ph_responder, ph_simulator, unpaced_config};

/// The client configuration of every transaction measured (as `drivers.rs`).
fn config() -> ClientConfig {
    unpaced_config(Duration::from_millis(10))
}

fn bench_call<T: Transport>(
    group: &mut criterion::BenchmarkGroup<'_, criterion::measurement::WallTime>,
    name: &str,
    transport: T,
) {
    let mut client = Client::with_config(transport, config());
    assert_eq!(client.call(1, &GetPh).map(|r| r.ph).ok(), Some(GET_PH_VALUE), "{name}: get_ph answers");
    group.bench_function(name, |b| b.iter(|| client.call(black_box(1), black_box(&GetPh)).map(|r| r.ph)));
}

fn transaction(c: &mut Criterion) {
    let mut group = c.benchmark_group("transaction_get_ph");
    let sim = ph_simulator().expect("the pH simulator loads from the spec");
    bench_call(&mut group, "simulator", ResponderTransport::new(sim));
    bench_call(&mut group, "fixed_reply", ResponderTransport::from_fn(fixed_get_ph_responder()));
    group.finish();
}

criterion_group! {
    name = benches;
    config = Criterion::default().warm_up_time(Duration::from_secs(1)).measurement_time(Duration::from_secs(3));
    targets = transaction
}
criterion_main!(benches);
