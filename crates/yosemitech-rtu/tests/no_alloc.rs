//! A successful transaction allocates nothing (design: "no allocation per
//! transaction"). Counted with a global allocator, on the test's own thread.

use std::time::Duration;

use yosemitech_rtu::{Client, ClientConfig, Command, Layout, ResponderTransport, RetryPolicy};
use yosemitech_tests::counting_alloc::{CountingAllocator, allocations};
use yosemitech_tests::rtu::{READ_FLOAT_REPLY, READ_FLOAT_REQUEST, ReadFloat, float_probe};
use yosemitech_tests::with_crc;

#[global_allocator]
static GLOBAL: CountingAllocator = CountingAllocator;

#[test]
fn transactions_do_not_allocate() {
    let config =
        ClientConfig { timeout: Duration::from_millis(100), retry: RetryPolicy::NONE, ..ClientConfig::default() };
    let mut client = Client::with_config(
        ResponderTransport::from_fn(|req: &[u8], out: &mut Vec<u8>| float_probe(1, 7.6, req, out)),
        config,
    );
    assert_eq!(client.call(1, &ReadFloat).unwrap(), 7.6);

    let before = allocations();
    for _ in 0..100 {
        assert_eq!(client.call(1, &ReadFloat).unwrap(), 7.6);
        assert_eq!(client.call_raw(&READ_FLOAT_REQUEST, &ReadFloat::LAYOUT).unwrap(), READ_FLOAT_REPLY);
    }
    let after = allocations();
    assert_eq!(after - before, 0, "allocations in 200 transactions");

    // Nor do errors (the reply bytes are kept inline): a timeout (slave 2 is
    // silent) and an exception (the probe has no register 0x9900).
    let unknown = Layout { address: 0x9900, ..ReadFloat::LAYOUT };
    let request = with_crc(&[0x01, 0x03, 0x99, 0x00, 0x00, 0x02]);
    let before = allocations();
    assert!(client.call(2, &ReadFloat).unwrap_err().is_timeout());
    assert!(client.call_raw(&request, &unknown).unwrap_err().is_exception());
    assert_eq!(allocations() - before, 0);

    let before = allocations();
    drop(std::hint::black_box(vec![1u8]));
    assert_eq!(allocations() - before, 1, "the counter counts");
}
