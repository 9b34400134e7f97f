//! The brokers and the subscriber of the MQTT tests live in the workspace
//! test kit, [`yosemitech_tests::broker`]. This file only re-exports them
//! for `yosemitech-cli`'s broker test, which still includes it by path;
//! once that test imports the kit it goes.

pub use yosemitech_tests::broker::*;
