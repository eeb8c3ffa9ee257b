//! The soak, a pass/fail check of the release binary under a minute of mixed load (see
//! [`soak`]), as an ignored test. It starts the binary the test was built with, so build and
//! run it in release:
//!
//! ```sh
//! cargo test --release --test soak -- --ignored --nocapture
//! ```
//!
//! `SOAK_SECONDS` (default 60) and `SOAK_CONNECTIONS` (default 32) set its length and load. It
//! shares the load benchmark's client and process code (`benches/load/`).

#[allow(dead_code)]
#[path = "../../benches/load/client.rs"]
mod client;
#[allow(dead_code)]
#[path = "../../benches/load/options.rs"]
mod options;
#[allow(dead_code)]
#[path = "../../benches/load/process.rs"]
mod process;
mod soak;

use std::time::Duration;

/// A number from the environment, or `default`.
fn setting(name: &str, default: u64) -> u64 {
    std::env::var(name)
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(default)
}

/// Under a bounded closed-loop load of mixed requests, every answer has the status its request
/// must get, a sample of them agrees with the physics, and the server's memory does not grow
/// by more than 10 % after its first tenth of the run.
#[test]
#[ignore = "a minute of load against the release binary: cargo test --release --test soak -- --ignored"]
fn the_service_holds_under_a_minute_of_mixed_load() {
    let options = options::Options::parse(&[]).expect("the load options' defaults");
    let duration = Duration::from_secs(setting("SOAK_SECONDS", 60));
    let connections = usize::try_from(setting("SOAK_CONNECTIONS", 32)).unwrap_or(32);
    let (report, passed) = soak::run(&options, duration, connections).expect("the soak ran");
    println!("{report}");
    assert!(passed, "a criterion failed:\n{report}");
}
