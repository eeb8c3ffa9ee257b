//! Runtime dispatch between the portable build and an AVX2 build of the same code: the hot
//! loops are written once, as plain loops over fixed-size chunks that the compiler vectorises,
//! and [`dispatch!`](crate::dispatch) compiles each twice, once with AVX2 enabled. The CPU is
//! asked once; tests force each level in turn and check the answers are identical.
//!
//! An AVX-512 level (32 lanes of `u16`, 32 registers) was built and measured: the aggregation
//! took the same 26.5 ms a stripe on Motorcycle, being bound by the work around each pixel
//! rather than by the lane width, so it is not kept.

use std::sync::atomic::{AtomicU8, Ordering};

/// A build of the hot loops.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub enum Level {
    /// Whatever the compile target allows (SSE2 on a default x86-64 build).
    Portable = 1,
    /// AVX2 with POPCNT, BMI and LZCNT: 16 lanes of `u16`.
    Avx2 = 2,
}

const UNKNOWN: u8 = 0;

static LEVEL: AtomicU8 = AtomicU8::new(UNKNOWN);

/// The level the hot loops run at: the best this CPU has, unless [`set_level`] lowered it.
pub fn level() -> Level {
    match LEVEL.load(Ordering::Relaxed) {
        UNKNOWN => {
            // A concurrent `set_level` wins: only replace the unknown state.
            let _ = LEVEL.compare_exchange(
                UNKNOWN,
                detect() as u8,
                Ordering::Relaxed,
                Ordering::Relaxed,
            );
            from_u8(LEVEL.load(Ordering::Relaxed))
        }
        level => from_u8(level),
    }
}

fn from_u8(level: u8) -> Level {
    match level {
        2 => Level::Avx2,
        _ => Level::Portable,
    }
}

/// Makes every later call run at `wanted`, or at the best this CPU has if that is lower
/// (for the tests that compare the levels, and for benchmarks); returns the level set.
pub fn set_level(wanted: Level) -> Level {
    let level = wanted.min(detect());
    LEVEL.store(level as u8, Ordering::Relaxed);
    level
}

/// The levels this CPU can run, from [`Level::Portable`] up.
pub fn available() -> Vec<Level> {
    [Level::Portable, Level::Avx2]
        .into_iter()
        .filter(|&l| l <= detect())
        .collect()
}

fn detect() -> Level {
    #[cfg(target_arch = "x86_64")]
    {
        use std::is_x86_feature_detected as has;
        if has!("avx2") && has!("popcnt") && has!("bmi1") && has!("bmi2") && has!("lzcnt") {
            Level::Avx2
        } else {
            Level::Portable
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        Level::Portable
    }
}

/// Defines a function whose body is compiled twice, for the portable target and with AVX2,
/// and called through [`level`] at run time.
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
                if $crate::vision::simd::level() == $crate::vision::simd::Level::Avx2 {
                    // SAFETY: `level()` checked that this CPU has every feature `fast` enables.
                    return unsafe { fast($($arg),*) };
                }
            }
            body($($arg),*)
        }
    };
}
