//! The entropy stage alone: the adaptive binary arithmetic coder on skewed bits, and the
//! EZW coder (encode and decode) on the 5/3 coefficients of a 1024×1024 synthetic
//! terrain, with the real range coder and with the bit-counting backend.
//!
//! `cargo bench -p wavemesh-codec --bench coder`

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use std::hint::black_box;
use wavemesh_codec::entropy::{ArithmeticDecoder, ArithmeticEncoder, BitModel, BitSink};
use wavemesh_codec::ezw::{self, CoefficientLayout, ContextChoice, Decoder, Midpoint};
use wavemesh_codec::wavelet::{self, Wavelet};

const SIDE: usize = 1024;

/// Deterministic xorshift bits with P(1) = `p_one`.
fn skewed_bits(n: usize, p_one: f64) -> Vec<bool> {
    let mut state = 0x9e37_79b9_7f4a_7c15u64;
    (0..n)
        .map(|_| {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            ((state >> 11) as f64 / (1u64 << 53) as f64) < p_one
        })
        .collect()
}

/// Decimetre terrain (sum of sines plus noise), transformed by the 5/3 wavelet.
fn coefficients() -> (CoefficientLayout, Vec<i32>) {
    let mut state = 0x2545_f491_4f6c_dd1du64;
    let mut values: Vec<i32> = (0..SIDE * SIDE)
        .map(|i| {
            let (x, y) = ((i % SIDE) as f64, (i / SIDE) as f64);
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            let noise = (state >> 40) as f64 / (1u64 << 24) as f64 - 0.5;
            (10000.0
                + 6000.0 * (x / 310.0).sin() * (y / 270.0).cos()
                + 400.0 * (x / 23.0 + y / 41.0).sin()
                + 20.0 * noise) as i32
        })
        .collect();
    let levels = wavelet::default_levels(SIDE, SIDE);
    wavelet::forward_53(&mut values, SIDE, SIDE, levels);
    let norms = wavelet::synthesis_norms(Wavelet::Int53, SIDE, SIDE, levels);
    let smallest = norms.iter().cloned().fold(f64::INFINITY, f64::min);
    let shifts: Vec<u32> = norms
        .iter()
        .map(|&n| (n / smallest).log2().round().max(0.0) as u32)
        .collect();
    let layout =
        CoefficientLayout::new(SIDE, SIDE, &wavelet::subbands(SIDE, SIDE, levels), &shifts);
    (layout, values)
}

fn bench_arithmetic(c: &mut Criterion) {
    let bits = skewed_bits(1 << 20, 0.1);
    let mut encoder = ArithmeticEncoder::new();
    let mut model = BitModel::new();
    for &b in &bits {
        encoder.encode(b, &mut model);
    }
    let stream = encoder.finish();
    let mut group = c.benchmark_group("arithmetic coder");
    group.throughput(Throughput::Elements(bits.len() as u64));
    group.bench_function("encode 1M bits p=0.1", |b| {
        b.iter(|| {
            let mut encoder = ArithmeticEncoder::new();
            let mut model = BitModel::new();
            for &bit in &bits {
                encoder.encode(bit, &mut model);
            }
            black_box(encoder.finish())
        })
    });
    group.bench_function("decode 1M bits p=0.1", |b| {
        b.iter(|| {
            let mut decoder = ArithmeticDecoder::new(&stream, true);
            let mut model = BitModel::new();
            let mut ones = 0u32;
            for _ in 0..bits.len() {
                ones += decoder.decode(&mut model) as u32;
            }
            black_box(ones)
        })
    });
    group.finish();
}

fn bench_ezw(c: &mut Criterion) {
    let (layout, coefficients) = coefficients();
    let weights = vec![1.0; 3 * wavelet::default_levels(SIDE, SIDE) as usize + 1];
    let encoded = ezw::encode(&layout, &coefficients, &weights, Midpoint::Integer, None);
    let mut group = c.benchmark_group("ezw 1024x1024 lossless");
    group.sample_size(10);
    group.throughput(Throughput::Elements((SIDE * SIDE) as u64));
    group.bench_function("encode", |b| {
        b.iter(|| {
            black_box(ezw::encode(
                &layout,
                &coefficients,
                &weights,
                Midpoint::Integer,
                None,
            ))
        })
    });
    group.bench_function("decode", |b| {
        b.iter(|| {
            black_box(Decoder::run(
                &layout,
                &encoded.bytes,
                true,
                encoded.top_plane,
                None,
            ))
        })
    });
    group.bench_function("count bits (no bytes produced)", |b| {
        b.iter(|| black_box(ezw::count_bits(&layout, &coefficients, ContextChoice::ALL)))
    });
    group.finish();
}

criterion_group!(benches, bench_arithmetic, bench_ezw);
criterion_main!(benches);
