//! Times the matcher alone on a pair, with its defaults and a disparity count: best and median
//! wall time of `RUNS` calls, the median run's stage times (cost, aggregation, refine) and the
//! cost cells matched over every level, the allocator tuned as the server tunes it. `PRESET` is `accurate` (the default) or `fast`. For
//! comparing builds side by side: run two binaries in turns. A second line gives a digest of the
//! last call's map (its values', σ_d's and fill flags' bits), which two builds that should agree
//! bit for bit must print alike.
//!
//! ```text
//! cargo build --profile tune --example time_matcher
//! target/tune/examples/time_matcher LEFT.png RIGHT.png COUNT RUNS [PRESET]
//! ```

use std::sync::atomic::AtomicBool;
use std::time::Instant;

use stereo_core::vision::{self, Params, Preset, Settings};

mod common;

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let (left, right, count, runs, preset) = match args.as_slice() {
        [l, r, c, n] => (l, r, c, n, Preset::Accurate),
        [l, r, c, n, p] if p == "fast" => (l, r, c, n, Preset::Fast),
        [l, r, c, n, p] if p == "accurate" => (l, r, c, n, Preset::Accurate),
        _ => {
            eprintln!("usage: time_matcher LEFT.png RIGHT.png COUNT RUNS [accurate|fast]");
            std::process::exit(2);
        }
    };
    // The allocator tuned as the server tunes it under its default 1 GiB budget.
    vision::huge_pages::tune_for_budget(1 << 30);
    let (left, right) = common::read_pair(left, right);
    let count: i32 = count.parse().expect("COUNT is a number");
    let runs: usize = runs.parse().expect("RUNS is a number");
    let params = Params::new(&Settings {
        max_disparity: Some(stereo_core::vision::RangeEnd::Px(count)),
        preset: Some(preset),
        ..Settings::default()
    })
    .expect("valid settings");
    let never = AtomicBool::new(false);
    let mut cells = 0;
    let mut digest = 0u64;
    let mut runs_ms: Vec<(f64, [f64; 3])> = (0..runs.max(1))
        .map(|_| {
            let started = Instant::now();
            let (map, t) =
                vision::disparity(&left.grey, &right.grey, &params, &never).expect("not cancelled");
            cells = t.cells;
            digest = digest_of(&map);
            let ms = |d: std::time::Duration| d.as_secs_f64() * 1e3;
            (
                ms(started.elapsed()),
                [ms(t.cost), ms(t.aggregate), ms(t.refine)],
            )
        })
        .collect();
    runs_ms.sort_by(|a, b| a.0.total_cmp(&b.0));
    let (median, [cost, aggregate, refine]) = runs_ms[runs_ms.len() / 2];
    println!(
        "best {:.2} ms, median {median:.2} ms (cost {cost:.1}, aggregation {aggregate:.1}, refine {refine:.1}); {:.2} M cells",
        runs_ms[0].0,
        cells as f64 / 1e6
    );
    println!("map digest {digest:016x}");
}

/// FNV-1a over the bits of the map's values, σ_d and fill flags.
fn digest_of(map: &vision::Disparity) -> u64 {
    let words = map
        .data
        .iter()
        .chain(&map.std)
        .map(|v| u64::from(v.to_bits()));
    let flags = map.filled.iter().map(|&f| u64::from(f));
    words.chain(flags).fold(0xcbf2_9ce4_8422_2325, |h, v| {
        (h ^ v).wrapping_mul(0x0000_0100_0000_01b3)
    })
}
