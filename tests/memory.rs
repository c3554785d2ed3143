//! The counting allocator, alone in its test binary so no other test allocates meanwhile.

use wavemesh::memory::{current_bytes, measure, peak_bytes, CountingAllocator};

#[global_allocator]
static ALLOCATOR: CountingAllocator = CountingAllocator;

#[test]
fn counts_allocations_reallocations_and_frees() {
    let before = current_bytes();
    let ((), peak) = measure(|| {
        let mut v: Vec<u8> = Vec::with_capacity(1 << 20);
        v.resize(1 << 20, 7);
        v.reserve_exact(3 << 20); // realloc upwards: 4 MiB in all
        let zeroed = vec![0u64; 1 << 17]; // alloc_zeroed, 1 MiB
        assert!(current_bytes() >= before + (5 << 20));
        assert_eq!(zeroed.iter().sum::<u64>() + v[0] as u64, 7);
        v.truncate(10);
        v.shrink_to_fit(); // realloc downwards
        assert!(current_bytes() < before + (2 << 20));
    });
    assert!(peak >= 5 << 20, "peak {peak}");
    assert!(peak < 6 << 20, "peak {peak}");
    assert!(peak_bytes() >= before + peak);
    assert!(current_bytes() <= before + 4096, "everything was freed");
}
