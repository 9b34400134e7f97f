//! Zero heap allocations per transaction of the tokio `AsyncClient`,
//! counted by a global allocator on the test's own thread,
//! around the awaited calls only, after a warm-up, on a current-thread
//! runtime (so every poll runs on this thread and is counted). In memory
//! (the in-process responder), and over real sockets: RTU on TCP and Modbus
//! TCP to served simulators (which allocate on their own threads, not
//! counted).

use std::hint::black_box;
use std::time::Duration;

use yosemitech::ph_orp::{self, GetPh};
use yosemitech::rtu::transport::AsyncLink;
use yosemitech::rtu::{AsyncClient, MbapLink, RtuStream};
use yosemitech::{ClientConfig, ResponderTransport};
use yosemitech_bench::{GET_PH_VALUE, fixed_get_ph_responder, ph_simulator, unpaced_config};
use yosemitech_sim::{ServeConfig, serve_mbap, serve_tcp};
use yosemitech_tests::counting_alloc::{CountingAllocator, allocations, allocations_in};

#[global_allocator]
static GLOBAL: CountingAllocator = CountingAllocator;

const ROUNDS: usize = 100;

fn config() -> ClientConfig {
    unpaced_config(Duration::from_secs(5))
}

fn runtime() -> tokio::runtime::Runtime {
    tokio::runtime::Builder::new_current_thread().enable_all().build().unwrap()
}

/// Allocations in `ROUNDS` get_ph calls (typed, and through the async
/// device handle) after a warm-up round, counted around the awaits only.
async fn allocations_per_rounds<L: AsyncLink>(client: &mut AsyncClient<L>) -> usize {
    assert_eq!(client.call(1, &GetPh).await.unwrap().ph, GET_PH_VALUE, "warm-up");
    assert_eq!(ph_orp::AsyncDevice::new(client, 1).ph().await.unwrap().ph, GET_PH_VALUE, "warm-up");
    let mut counted = 0;
    for _ in 0..ROUNDS {
        let before = allocations();
        let reply = client.call(black_box(1), black_box(&GetPh)).await;
        counted += allocations() - before;
        assert_eq!(reply.unwrap().ph, GET_PH_VALUE);
        let mut probe = ph_orp::AsyncDevice::new(client, 1);
        let before = allocations();
        let ph = probe.ph().await;
        counted += allocations() - before;
        assert_eq!(ph.unwrap().ph, GET_PH_VALUE);
    }
    counted
}

#[test]
fn the_counter_counts() {
    assert_eq!(allocations_in(|| drop(black_box(vec![1u8]))), 1);
}

#[test]
fn async_transactions_in_memory_do_not_allocate() {
    let runtime = runtime();
    let n = runtime.block_on(async {
        let mut client = AsyncClient::with_config(ResponderTransport::from_fn(fixed_get_ph_responder()), config());
        allocations_per_rounds(&mut client).await
    });
    assert_eq!(n, 0, "allocations in {} async transactions", 2 * ROUNDS);
}

#[test]
fn async_transactions_over_tcp_and_modbus_tcp_do_not_allocate() {
    let runtime = runtime();
    let rtu_server = serve_tcp(ph_simulator().unwrap(), "127.0.0.1:0", ServeConfig::default()).unwrap();
    let mbap_server = serve_mbap(ph_simulator().unwrap(), "127.0.0.1:0", ServeConfig::default()).unwrap();
    let (rtu, mbap) = runtime.block_on(async {
        let stream = tokio::net::TcpStream::connect(rtu_server.local_addr().unwrap()).await.unwrap();
        let mut client = AsyncClient::with_config(RtuStream::new(stream), config());
        let rtu = allocations_per_rounds(&mut client).await;
        let stream = tokio::net::TcpStream::connect(mbap_server.local_addr().unwrap()).await.unwrap();
        let mut client = AsyncClient::with_config(MbapLink::new(stream), config());
        let mbap = allocations_per_rounds(&mut client).await;
        (rtu, mbap)
    });
    assert_eq!(rtu, 0, "allocations in {} transactions, RTU on TCP", 2 * ROUNDS);
    assert_eq!(mbap, 0, "allocations in {} transactions, Modbus TCP", 2 * ROUNDS);
}
