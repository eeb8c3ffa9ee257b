//! The allocator's thresholds the server sets at start (`huge_pages::settle_allocator`): a
//! buffer of a few MiB freed and taken again is served from memory the allocator kept, not
//! mapped and faulted in afresh. A test binary of its own, so that no other test's
//! allocations share its arena or move glibc's thresholds first.

/// Minor page faults of the calling thread so far.
#[cfg(all(target_os = "linux", target_env = "gnu"))]
fn minor_faults() -> i64 {
    // SAFETY: rusage is plain integers, for which zeros are valid; getrusage writes the
    // struct it is given, owned here.
    let (status, usage) = unsafe {
        let mut usage: libc::rusage = std::mem::zeroed();
        (libc::getrusage(libc::RUSAGE_THREAD, &mut usage), usage)
    };
    assert_eq!(status, 0, "getrusage failed");
    usage.ru_minflt
}

/// With the thresholds set, a 24 MiB buffer written, freed and written again costs almost no
/// page faults the second time (fewer than a quarter of its 6144 pages). glibc's defaults
/// map it afresh the first time and, having raised its threshold on that free, grow its heap
/// for the second, so every page is faulted in twice.
#[cfg(all(target_os = "linux", target_env = "gnu"))]
#[test]
fn a_freed_buffer_is_reused_without_faulting_its_pages_again() {
    use stereo_core::vision::huge_pages;
    const BYTES: usize = 24 << 20;
    assert!(
        huge_pages::settle_allocator(),
        "glibc refused the thresholds"
    );
    let first = vec![1u8; BYTES];
    assert_eq!(std::hint::black_box(&first)[BYTES - 1], 1);
    drop(first);
    let before = minor_faults();
    let second = vec![2u8; BYTES];
    assert_eq!(std::hint::black_box(&second)[BYTES / 2], 2);
    let faults = minor_faults() - before;
    let pages = (BYTES / 4096) as i64;
    assert!(
        faults < pages / 4,
        "{faults} page faults taking the buffer again ({pages} pages)"
    );
}
