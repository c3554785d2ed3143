//! What the `mesh` and `view` benches share: CPU time a call (the machine is shared, so
//! wall-clock medians count the time other processes hold the core) and fingerprints of
//! outputs (equal before and after a change that keeps them).

/// CPU seconds this thread has used (Linux `/proc`, 10 ms ticks); `None` elsewhere.
fn thread_cpu_seconds() -> Option<f64> {
    let stat = std::fs::read_to_string("/proc/thread-self/stat").ok()?;
    // Fields after the command name: utime and stime are the 12th and 13th, in ticks.
    let fields: Vec<&str> = stat[stat.rfind(')')? + 2..].split_whitespace().collect();
    let ticks = fields.get(11)?.parse::<f64>().ok()? + fields.get(12)?.parse::<f64>().ok()?;
    Some(ticks / 100.0)
}

/// The CPU seconds a call of `f` takes, over `calls` calls; `None` where the thread's CPU
/// time cannot be read.
pub fn cpu_seconds_per_call(calls: usize, mut f: impl FnMut()) -> Option<f64> {
    let start = thread_cpu_seconds()?;
    for _ in 0..calls {
        f();
    }
    Some((thread_cpu_seconds()? - start) / calls as f64)
}

/// FNV-1a over `words`: a fingerprint of a bench's output.
pub fn fnv1a(words: impl Iterator<Item = u64>) -> u64 {
    words.fold(0xcbf2_9ce4_8422_2325, |hash, word| {
        (hash ^ word).wrapping_mul(0x0000_0100_0000_01b3)
    })
}
