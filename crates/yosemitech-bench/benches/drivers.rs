//! The two drivers of one client core, in the same run: CPU per get_ph
//! transaction of the blocking `Client` and of the tokio `AsyncClient`
//! (awaited inside one current-thread runtime, so runtime entry is not
//! counted), over the same in-memory `ResponderTransport` with the manual's
//! fixed reply, no line timing and no waits. Target: tokio within 1.5x.
// `criterion_group!` generates an undocumented `pub fn`.
#![allow(missing_docs)]

use std::hint::black_box;
use std::time::{Duration, Instant};

use criterion::{Criterion, criterion_group, criterion_main};
use yosemitech::ph_orp::GetPh;
use yosemitech::rtu::AsyncClient;
use yosemitech::{Client, ClientConfig, ResponderTransport};
use yosemitech_bench::{GET_PH_VALUE, fixed_get_ph_responder, unpaced_config};

/// The client configuration of every transaction measured (as `transaction.rs`).
fn config() -> ClientConfig {
    unpaced_config(Duration::from_millis(10))
}

fn drivers(c: &mut Criterion) {
    let mut group = c.benchmark_group("transaction_driver");
    let mut blocking = Client::with_config(ResponderTransport::from_fn(fixed_get_ph_responder()), config());
    assert_eq!(blocking.call(1, &GetPh).map(|r| r.ph).ok(), Some(GET_PH_VALUE));
    group.bench_function("blocking", |b| b.iter(|| blocking.call(black_box(1), black_box(&GetPh)).map(|r| r.ph)));

    let runtime = tokio::runtime::Builder::new_current_thread().enable_time().build().expect("a tokio runtime");
    let mut client = runtime
        .block_on(async { AsyncClient::with_config(ResponderTransport::from_fn(fixed_get_ph_responder()), config()) });
    let first = runtime.block_on(client.call(1, &GetPh)).map(|r| r.ph);
    assert_eq!(first.ok(), Some(GET_PH_VALUE));
    group.bench_function("tokio", |b| {
        b.iter_custom(|iterations| {
            runtime.block_on(async {
                let start = Instant::now();
                for _ in 0..iterations {
                    let _ = black_box(client.call(black_box(1), black_box(&GetPh)).await.map(|r| r.ph));
                }
                start.elapsed()
            })
        })
    });
    group.finish();
}

criterion_group! {
    name = benches;
    config = Criterion::default().warm_up_time(Duration::from_secs(1)).measurement_time(Duration::from_secs(3));
    targets = drivers
}
criterion_main!(benches);
