//! Large buffers (the cost volume, the first pass's sums) asking the kernel for transparent
//! huge pages before they are first touched: a fresh 2 MiB page costs one fault where 4 KiB
//! pages cost 512, and on a virtual machine those faults are most of the time a fresh
//! volume takes (Motorcycle with 128 disparities: 260 ms of aggregation with 4 KiB pages,
//! 47 ms with huge pages). Where the kernel has THP off (`never`), or off Linux, the advice is
//! a no-op and the buffers are ordinary ones.

/// A `Vec` of `len` zeros, huge-page backed where the kernel allows. A large one comes
/// straight from the kernel already zeroed, so it is not written here at all.
pub fn zeroed<T: Copy + Default>(len: usize) -> Vec<T> {
    // `vec![0; n]` asks the allocator for zeroed memory (`calloc`), which maps fresh pages
    // for a large buffer and leaves them untouched until first written, after the advice.
    let mut v = vec![T::default(); len];
    advise(v.as_mut_ptr().cast(), len.saturating_mul(size_of::<T>()));
    v
}

/// Advises `MADV_HUGEPAGE` for the whole pages inside `[start, start + bytes)`, untouched
/// memory that this process owns. Failure (no THP, an old kernel) changes nothing.
#[cfg(target_os = "linux")]
fn advise(start: *mut u8, bytes: usize) {
    const PAGE: usize = 4096;
    // Too small to hold a huge page: not worth a system call.
    if bytes < 4 << 20 {
        return;
    }
    let first = (start as usize).next_multiple_of(PAGE);
    let end = (start as usize + bytes) / PAGE * PAGE;
    if end > first {
        // SAFETY: the range lies inside an allocation this process owns (the vector's
        // capacity), and MADV_HUGEPAGE changes how its pages are backed, never their
        // contents or the mapping's validity.
        unsafe {
            libc::madvise(first as *mut libc::c_void, end - first, libc::MADV_HUGEPAGE);
        }
    }
}

#[cfg(not(target_os = "linux"))]
fn advise(_start: *mut u8, _bytes: usize) {}

#[cfg(test)]
mod tests {
    use super::*;

    /// A large buffer and a small one hold zeros, as many as asked for.
    #[test]
    fn buffers_hold_their_values() {
        assert_eq!(zeroed::<u8>(3), vec![0, 0, 0]);
        let zeros: Vec<u16> = zeroed(5 << 20);
        assert_eq!(zeros.len(), 5 << 20);
        assert!(zeros.iter().all(|&v| v == 0));
    }
}
