//! Forward and inverse 5/3 and 9/7 transforms of a 2000×2000 synthetic terrain at the
//! default number of levels.

use criterion::{criterion_group, criterion_main, BatchSize, Criterion};
use std::hint::black_box;
use wavemesh_codec::wavelet::{default_levels, forward_53, forward_97, inverse_53, inverse_97};

const SIDE: usize = 2000;

/// Smooth synthetic terrain in metres (sum of sines plus a little deterministic noise).
fn terrain(width: usize, height: usize) -> Vec<f32> {
    let mut state = 0x2545_f491_4f6c_dd1du64;
    (0..width * height)
        .map(|i| {
            let (x, y) = ((i % width) as f64, (i / width) as f64);
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            let noise = (state >> 40) as f64 / (1u64 << 24) as f64 - 0.5;
            let h = 1200.0
                + 600.0 * (x / 310.0).sin() * (y / 270.0).cos()
                + 150.0 * (x / 47.0 + y / 83.0).sin()
                + 40.0 * (x / 11.0).cos() * (y / 13.0).sin()
                + 2.0 * noise;
            h as f32
        })
        .collect()
}

fn bench_transforms(c: &mut Criterion) {
    let (w, h) = (SIDE, SIDE);
    let levels = default_levels(w, h);
    let floats = terrain(w, h);
    // Decimetres, as the lossless path would see them.
    let ints: Vec<i32> = floats.iter().map(|&v| (v * 10.0).round() as i32).collect();

    let mut coef_53 = ints.clone();
    forward_53(&mut coef_53, w, h, levels);
    let mut coef_97 = floats.clone();
    forward_97(&mut coef_97, w, h, levels);

    let mut group = c.benchmark_group(format!("{w}x{h}"));
    group.sample_size(20);
    group.bench_function("forward_53", |b| {
        b.iter_batched_ref(
            || ints.clone(),
            |data| forward_53(black_box(data), w, h, levels),
            BatchSize::LargeInput,
        )
    });
    group.bench_function("inverse_53", |b| {
        b.iter_batched_ref(
            || coef_53.clone(),
            |data| inverse_53(black_box(data), w, h, levels),
            BatchSize::LargeInput,
        )
    });
    group.bench_function("forward_97", |b| {
        b.iter_batched_ref(
            || floats.clone(),
            |data| forward_97(black_box(data), w, h, levels),
            BatchSize::LargeInput,
        )
    });
    group.bench_function("inverse_97", |b| {
        b.iter_batched_ref(
            || coef_97.clone(),
            |data| inverse_97(black_box(data), w, h, levels),
            BatchSize::LargeInput,
        )
    });
    group.finish();
}

criterion_group!(benches, bench_transforms);
criterion_main!(benches);
