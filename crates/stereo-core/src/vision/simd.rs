//! Runtime dispatch between the portable build and an AVX2 build of the same code: the hot
//! loops are written once, as plain loops over fixed-size chunks that the compiler vectorises,
//! and [`dispatch!`](crate::dispatch) compiles each twice, once with AVX2 enabled. The CPU is
//! asked once; tests force the portable path and check the answers are identical.
//!
//! Functions marked `wide` are compiled a third time, for CPUs with AVX-512BW and VPOPCNTDQ:
//! the cost's row, whose work is the Hamming distance (`vpopcntq` counts eight signatures'
//! bits in one instruction where AVX2 needs a table lookup per nibble: Motorcycle's cost stage
//! 7 → 5 ms), and the aggregation's pass, whose 8-bit path costs fill 64 lanes a register
//! ([`super::sgm`]). An AVX-512 build of the 16-bit pass with 16-lane chunks had measured no
//! faster than AVX2: the chunks, not the registers, set the width.
//!
//! Beside it, the least and greatest of two floats known not to be NaN, as the vector loops
//! take them.

use std::sync::atomic::{AtomicU8, Ordering};

const UNKNOWN: u8 = 0;
const PORTABLE: u8 = 1;
const AVX2: u8 = 2;
const AVX512: u8 = 3;

static LEVEL: AtomicU8 = AtomicU8::new(UNKNOWN);

/// The build of the hot loops that runs, found once.
fn level() -> u8 {
    match LEVEL.load(Ordering::Relaxed) {
        UNKNOWN => {
            let level = detect();
            // A concurrent `use_simd` wins: only replace the unknown state.
            let _ = LEVEL.compare_exchange(UNKNOWN, level, Ordering::Relaxed, Ordering::Relaxed);
            LEVEL.load(Ordering::Relaxed)
        }
        level => level,
    }
}

/// Whether the AVX2 build of the hot loops runs on this CPU.
pub fn avx2() -> bool {
    level() >= AVX2
}

/// Whether the AVX-512 build of the functions marked `wide` runs on this CPU.
pub fn avx512() -> bool {
    level() == AVX512
}

/// Makes every later call take the portable path (`false`) or the best one the CPU has
/// (`true`): for the tests that compare the two, and for benchmarks.
pub fn use_simd(enabled: bool) {
    let level = if enabled { detect() } else { PORTABLE };
    LEVEL.store(level, Ordering::Relaxed);
}

/// Makes every later call take the AVX2 build even where AVX-512 is there (`false`), or the
/// best the CPU has (`true`): for the tests that compare the builds, and for benchmarks.
pub fn use_avx512(enabled: bool) {
    let level = if enabled {
        detect()
    } else {
        detect().min(AVX2)
    };
    LEVEL.store(level, Ordering::Relaxed);
}

/// The best build this CPU runs: AVX-512 when it has every feature that build enables (those of
/// the AVX2 build too), else AVX2 when it has those, else the portable one.
fn detect() -> u8 {
    #[cfg(target_arch = "x86_64")]
    {
        use std::is_x86_feature_detected as has;
        let avx2 = has!("avx2") && has!("popcnt") && has!("bmi1") && has!("bmi2") && has!("lzcnt");
        let avx512 =
            has!("avx512f") && has!("avx512bw") && has!("avx512vl") && has!("avx512vpopcntdq");
        match (avx2, avx512) {
            (true, true) => AVX512,
            (true, false) => AVX2,
            _ => PORTABLE,
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        PORTABLE
    }
}

/// The smaller of two values neither of which is NaN, as one instruction where the loop is
/// vectorised (`f32::min` also checks for NaN, a compare and a blend more).
#[inline(always)]
pub(crate) fn least(a: f32, b: f32) -> f32 {
    if a < b { a } else { b }
}

/// The greater of two values neither of which is NaN, as one instruction.
#[inline(always)]
pub(crate) fn greatest(a: f32, b: f32) -> f32 {
    if a > b { a } else { b }
}

/// Defines a function whose body is compiled twice, for the portable target and with AVX2,
/// and called through [`avx2`] at run time; marked `wide`, a third time with AVX-512 too,
/// called through [`avx512`].
#[macro_export]
#[doc(hidden)]
macro_rules! dispatch {
    ($(#[$meta:meta])* wide $vis:vis fn $name:ident $(<$($lt:lifetime),*>)? ($($arg:ident : $ty:ty),* $(,)?) $(-> $ret:ty)? $body:block) => {
        $(#[$meta])*
        $vis fn $name $(<$($lt),*>)? ($($arg: $ty),*) $(-> $ret)? {
            #[inline(always)]
            fn body $(<$($lt),*>)? ($($arg: $ty),*) $(-> $ret)? $body
            #[cfg(target_arch = "x86_64")]
            {
                #[target_feature(enable = "avx2,popcnt,bmi1,bmi2,lzcnt,avx512f,avx512bw,avx512vl,avx512vpopcntdq")]
                fn widest $(<$($lt),*>)? ($($arg: $ty),*) $(-> $ret)? {
                    body($($arg),*)
                }
                #[target_feature(enable = "avx2,popcnt,bmi1,bmi2,lzcnt")]
                fn fast $(<$($lt),*>)? ($($arg: $ty),*) $(-> $ret)? {
                    body($($arg),*)
                }
                if $crate::vision::simd::avx512() {
                    // SAFETY: `avx512()` checked that this CPU has every feature `widest`
                    // enables.
                    return unsafe { widest($($arg),*) };
                }
                if $crate::vision::simd::avx2() {
                    // SAFETY: `avx2()` checked that this CPU has every feature `fast` enables.
                    return unsafe { fast($($arg),*) };
                }
            }
            body($($arg),*)
        }
    };
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
