//! What the timing and tuning examples share: reading a pair of image files.

use stereo_core::vision::decode::{self, Decoded};

/// The pair at `left` and `right`, decoded (grey, no colour) with limits wide enough for any
/// camera's frames; exits with the reason when a file cannot be read or decoded.
pub fn read_pair(left: &str, right: &str) -> (Decoded, Decoded) {
    let limits = decode::DecodeLimits {
        max_side: 20_000,
        max_pixels: 50_000_000,
    };
    let read = |path: &str| {
        let bytes = std::fs::read(path).unwrap_or_else(|e| fail(&format!("{path}: {e}")));
        decode::decode(&bytes, limits, false).unwrap_or_else(|e| fail(&format!("{path}: {e:?}")))
    };
    (read(left), read(right))
}

fn fail(why: &str) -> ! {
    eprintln!("{why}");
    std::process::exit(1)
}
