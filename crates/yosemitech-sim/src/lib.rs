//! A Yosemitech sensor simulated from its spec: register state, writes, fault injection and line timing.
