//! Allocator settings for the coding of tiled files.
//!
//! A tiled encode or decode allocates and frees the same few buffers for every tile (the
//! coefficients, flags and samples of a 1024² tile are about 14 MB). With glibc's
//! defaults each of those is mapped afresh and handed back when freed, so every tile
//! faults its pages in again, and with two threads the mapping and unmapping contend
//! for the process's memory map: a two-thread decode of a 16384² file took 860 k page
//! faults and 2–5 s of system time. Keeping freed memory in one arena lets each tile
//! reuse the last one's pages (56 k faults, system time 0.22 s, peak RSS 125 → 129 MB).
//! Encodes gained as much when they took it (stop 33): sthelens_10m's four tiles, lossless,
//! 28.3 k → 11.3 k page faults with one thread and 30.2 k → 19.3 k with two.

/// Keeps freed buffers below 32 MiB for reuse in a single arena instead of returning
/// them to the kernel (glibc on Linux; elsewhere nothing changes).
#[cfg(all(target_os = "linux", target_env = "gnu"))]
pub fn keep_freed_tile_buffers() {
    // SAFETY: mallopt only changes glibc's allocation parameters; it takes the
    // allocator's own lock and touches no memory of ours.
    unsafe {
        libc::mallopt(libc::M_ARENA_MAX, 1);
        libc::mallopt(libc::M_MMAP_THRESHOLD, 32 << 20);
        libc::mallopt(libc::M_TRIM_THRESHOLD, 128 << 20);
    }
}

/// Nothing to tune off glibc.
#[cfg(not(all(target_os = "linux", target_env = "gnu")))]
pub fn keep_freed_tile_buffers() {}
