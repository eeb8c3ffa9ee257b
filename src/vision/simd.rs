//! Runtime dispatch between the portable build and an AVX2 build of the same code: the hot
//! loops are written once, as plain loops over fixed-size chunks that the compiler vectorises,
//! and [`dispatch!`](crate::dispatch) compiles each twice, once with AVX2 enabled. The CPU is
//! asked once; tests force the portable path and check the answers are identical.
//!
//! An AVX-512 build (32 lanes of `u16`, 32 registers) was tried and measured: the aggregation
//! took the same 26.5 ms a stripe on Motorcycle, being bound by the work around each pixel
//! rather than by the lane width, so it is not kept.

use std::sync::atomic::{AtomicU8, Ordering};

const UNKNOWN: u8 = 0;
const PORTABLE: u8 = 1;
const AVX2: u8 = 2;

static LEVEL: AtomicU8 = AtomicU8::new(UNKNOWN);

/// Whether the AVX2 build of the hot loops runs on this CPU.
pub fn avx2() -> bool {
    match LEVEL.load(Ordering::Relaxed) {
        UNKNOWN => {
            let level = if detect() { AVX2 } else { PORTABLE };
            // A concurrent `force_portable` wins: only replace the unknown state.
            let _ = LEVEL.compare_exchange(UNKNOWN, level, Ordering::Relaxed, Ordering::Relaxed);
            LEVEL.load(Ordering::Relaxed) == AVX2
        }
        level => level == AVX2,
    }
}

/// Makes every later call take the portable path (`false`) or the best one the CPU has
/// (`true`): for the tests that compare the two, and for benchmarks.
pub fn use_simd(enabled: bool) {
    let level = if enabled && detect() { AVX2 } else { PORTABLE };
    LEVEL.store(level, Ordering::Relaxed);
}

/// Whether this CPU has every feature the AVX2 build enables.
fn detect() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        use std::is_x86_feature_detected as has;
        has!("avx2") && has!("popcnt") && has!("bmi1") && has!("bmi2") && has!("lzcnt")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

/// Defines a function whose body is compiled twice, for the portable target and with AVX2,
/// and called through [`avx2`] at run time.
#[macro_export]
#[doc(hidden)]
macro_rules! dispatch {
    ($(#[$meta:meta])* $vis:vis fn $name:ident $(<$($lt:lifetime),*>)? ($($arg:ident : $ty:ty),* $(,)?) $(-> $ret:ty)? $body:block) => {
        $(#[$meta])*
        $vis fn $name $(<$($lt),*>)? ($($arg: $ty),*) $(-> $ret)? {
            #[inline(always)]
            fn body $(<$($lt),*>)? ($($arg: $ty),*) $(-> $ret)? $body
            #[cfg(target_arch = "x86_64")]
            {
                #[target_feature(enable = "avx2,popcnt,bmi1,bmi2,lzcnt")]
                fn fast $(<$($lt),*>)? ($($arg: $ty),*) $(-> $ret)? {
                    body($($arg),*)
                }
                if $crate::vision::simd::avx2() {
                    // SAFETY: `avx2()` checked that this CPU has every feature `fast` enables.
                    return unsafe { fast($($arg),*) };
                }
            }
            body($($arg),*)
        }
    };
}
