//! Forward and inverse 5/3 and 9/7 transforms of a 2000×2000 synthetic terrain at the
//! default number of levels.

mod support;

use criterion::{criterion_group, criterion_main, BatchSize, Criterion};
use std::hint::black_box;
use wavemesh_codec::wavelet::{default_levels, forward_53, forward_97, inverse_53, inverse_97};

const SIDE: usize = 2000;

fn bench_transforms(c: &mut Criterion) {
    let (w, h) = (SIDE, SIDE);
    let levels = default_levels(w, h);
    let floats: Vec<f32> = support::terrain_metres(w, h)
        .into_iter()
        .map(|m| m as f32)
        .collect();
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
