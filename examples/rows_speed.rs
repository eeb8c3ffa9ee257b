//! Times the row check ([`stereo_core::vision::rows`]) on a pair and prints what it found.
//!
//!     cargo run --release --example rows_speed -- LEFT RIGHT MAX_DISPARITY
use std::time::Instant;

use stereo_core::vision::rows;

mod common;

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let [_, left, right, max_d] = &args[..] else {
        eprintln!("usage: rows_speed LEFT RIGHT MAX_DISPARITY");
        std::process::exit(2);
    };
    let (l, r) = common::read_pair(left, right);
    let max_d: i32 = max_d.parse().expect("max disparity");
    for _ in 0..3 {
        let t = Instant::now();
        let found = rows::row_offsets(&l.grey, &r.grey, (0, max_d));
        println!("{found:?} in {:.1} ms", t.elapsed().as_secs_f64() * 1e3);
    }
}
