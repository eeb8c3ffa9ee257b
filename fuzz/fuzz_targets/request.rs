//! Fuzz target: arbitrary bytes as a JSON body to every `POST` operation and as a query
//! string to every `GET`, through the full router (decoding, validation, the physics, the
//! answer). Any broken promise of [`stereo_conformance`] (a 5xx, a panic, a problem
//! that names no field, a `null` in a 2xx) is a crash.
//!
//! Run: `cargo +nightly fuzz run request -- -max_total_time=60` (see the README).

#![no_main]

use std::sync::OnceLock;

use libfuzzer_sys::fuzz_target;
use stereo_conformance::Harness;

static HARNESS: OnceLock<Harness> = OnceLock::new();

fuzz_target!(|input: &[u8]| {
    if let Err(broken) = HARNESS.get_or_init(Harness::new).check(input) {
        panic!("{broken}");
    }
});
