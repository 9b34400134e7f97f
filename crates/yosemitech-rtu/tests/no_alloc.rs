//! A successful transaction allocates nothing (design: "no allocation per
//! transaction"). Counted with a global allocator, on the test's own thread.
// A counting global allocator needs `unsafe impl GlobalAlloc`; it only forwards to `System`.
#![allow(unsafe_code)]

mod common;

use std::alloc::{GlobalAlloc, Layout as AllocLayout, System};
use std::cell::Cell;
use std::time::Duration;

use common::{GET_PH_REPLY, GET_PH_REQUEST, GetPh, ph_probe, with_crc};
use yosemitech_rtu::{Client, ClientConfig, Command, Layout, ResponderTransport, RetryPolicy};

thread_local! {
    static ALLOCATIONS: Cell<usize> = const { Cell::new(0) };
}

struct Counting;

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: AllocLayout) -> *mut u8 {
        ALLOCATIONS.with(|n| n.set(n.get() + 1));
        // SAFETY: forwarded unchanged to the system allocator.
        unsafe { System.alloc(layout) }
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: AllocLayout) {
        // SAFETY: `ptr` came from `System.alloc` with this layout.
        unsafe { System.dealloc(ptr, layout) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

fn allocations() -> usize {
    ALLOCATIONS.with(Cell::get)
}

#[test]
fn transactions_do_not_allocate() {
    let config =
        ClientConfig { timeout: Duration::from_millis(100), retry: RetryPolicy::NONE, ..ClientConfig::default() };
    let mut client = Client::with_config(
        ResponderTransport::from_fn(|req: &[u8], out: &mut Vec<u8>| ph_probe(1, 7.6, req, out)),
        config,
    );
    assert_eq!(client.call(1, &GetPh).unwrap(), 7.6);

    let before = allocations();
    for _ in 0..100 {
        assert_eq!(client.call(1, &GetPh).unwrap(), 7.6);
        assert_eq!(client.call_raw(&GET_PH_REQUEST, &GetPh::LAYOUT).unwrap(), GET_PH_REPLY);
    }
    let after = allocations();
    assert_eq!(after - before, 0, "allocations in 200 transactions");

    // Nor do errors (the reply bytes are kept inline): a timeout (slave 2 is
    // silent) and an exception (the probe has no register 0x9900).
    let unknown = Layout { address: 0x9900, ..GetPh::LAYOUT };
    let request = with_crc(&[0x01, 0x03, 0x99, 0x00, 0x00, 0x02]);
    let before = allocations();
    assert!(client.call(2, &GetPh).unwrap_err().is_timeout());
    assert!(client.call_raw(&request, &unknown).unwrap_err().is_exception());
    assert_eq!(allocations() - before, 0);

    let before = allocations();
    drop(std::hint::black_box(vec![1u8]));
    assert_eq!(allocations() - before, 1, "the counter counts");
}
