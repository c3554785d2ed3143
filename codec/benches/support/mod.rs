//! What several benches share.

/// Smooth synthetic terrain in metres, `width × height` row-major: a sum of sines plus a
/// little deterministic xorshift noise (±1 m), about 400–2000 m.
pub fn terrain_metres(width: usize, height: usize) -> Vec<f64> {
    let mut state = 0x2545_f491_4f6c_dd1du64;
    (0..width * height)
        .map(|i| {
            let (x, y) = ((i % width) as f64, (i / width) as f64);
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            let noise = (state >> 40) as f64 / (1u64 << 24) as f64 - 0.5;
            1200.0
                + 600.0 * (x / 310.0).sin() * (y / 270.0).cos()
                + 150.0 * (x / 47.0 + y / 83.0).sin()
                + 40.0 * (x / 11.0).cos() * (y / 13.0).sin()
                + 2.0 * noise
        })
        .collect()
}
