//! The entropy stage alone, on synthetic data (so it always runs):
//!
//! * **arithmetic coder**: encode and decode 2^20 skewed bits (P(1) ≈ 0.1) through one
//!   adaptive [`BitModel`]; throughput in decisions per second.
//! * **EZW 1024×1024**: `ezw::encode` (no budget, complete lossless stream) and
//!   `Decoder::run` on the 5/3 coefficients of a synthetic terrain (sum of sines plus
//!   xorshift noise, heights 0..20000), with subband shifts and distortion weights computed
//!   as `pipeline.rs` computes them; throughput in coefficients per second.
//! * **EZW sink**: the same EZW encode into the real range coder (`ArithmeticEncoder`,
//!   via `ezw::encode`) and into the ideal-length `BitCounter` (via `ezw::count_bits`),
//!   which shows what the bit-counting backend (used for the context ablation) costs.
//!
//! Run (a separate target dir avoids lock fights with other builds):
//!
//! ```text
//! CARGO_TARGET_DIR=/work/target-bench cargo bench -p wavemesh-codec --bench coder
//! # quicker:
//! CARGO_TARGET_DIR=/work/target-bench cargo bench -p wavemesh-codec --bench coder -- \
//!     --warm-up-time 1 --measurement-time 3
//! ```

use criterion::{criterion_group, criterion_main, Criterion, SamplingMode, Throughput};
use std::hint::black_box;
use std::time::Duration;
use wavemesh_codec::entropy::{ArithmeticDecoder, ArithmeticEncoder, BitModel, BitSink};
use wavemesh_codec::ezw::{self, Coder, CoefficientLayout, ContextChoice, Decoder, Midpoint};
use wavemesh_codec::wavelet::{self, Wavelet};

/// Side of the synthetic terrain.
const SIDE: usize = 1024;
/// Decisions in the arithmetic-coder benchmark.
const BITS: usize = 1 << 20;

/// A xorshift64 generator: deterministic, so every run codes the same data.
struct XorShift(u64);

impl XorShift {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        self.0
    }

    /// Uniform in [0, 1).
    fn unit(&mut self) -> f64 {
        (self.next() >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// `n` bits with P(1) = `p_one`.
fn skewed_bits(n: usize, p_one: f64) -> Vec<bool> {
    let mut rng = XorShift(0x9e37_79b9_7f4a_7c15);
    (0..n).map(|_| rng.unit() < p_one).collect()
}

/// Synthetic terrain, `side × side` integer heights in 0..20000 (say decimetres): broad
/// hills, ridges, finer relief and a little noise.
fn terrain(side: usize) -> Vec<i32> {
    let mut rng = XorShift(0x2545_f491_4f6c_dd1d);
    (0..side * side)
        .map(|i| {
            let (x, y) = ((i % side) as f64, (i / side) as f64);
            let h = 10000.0
                + 7000.0 * (x / 310.0).sin() * (y / 270.0).cos()
                + 1500.0 * (x / 47.0 + y / 83.0).sin()
                + 400.0 * (x / 11.0).cos() * (y / 13.0).sin()
                + 40.0 * (rng.unit() - 0.5);
            h.round().clamp(0.0, 20000.0) as i32
        })
        .collect()
}

/// What the EZW benchmarks code: the layout, the 5/3 coefficients and the distortion
/// weights, prepared the way `pipeline::prepare_53` prepares them for an integer raster.
struct EzwInput {
    layout: CoefficientLayout,
    coefficients: Vec<i32>,
    weights: Vec<f64>,
}

fn ezw_input() -> EzwInput {
    let (width, height) = (SIDE, SIDE);
    let levels = wavelet::default_levels(width, height);
    let mut coefficients = terrain(SIDE);
    wavelet::forward_53(&mut coefficients, width, height, levels);
    // As the pipeline: empty subbands get norm 1, each subband is shifted by its synthesis
    // norm relative to the smallest (in whole planes), and weighted by its squared norm.
    let norms: Vec<f64> = wavelet::synthesis_norms(Wavelet::Int53, width, height, levels)
        .into_iter()
        .map(|n| if n.is_finite() && n > 0.0 { n } else { 1.0 })
        .collect();
    let smallest = norms.iter().cloned().fold(f64::INFINITY, f64::min);
    let shifts: Vec<u32> = norms
        .iter()
        .map(|&n| (n / smallest).log2().round().max(0.0) as u32)
        .collect();
    let weights = norms.iter().map(|n| n * n).collect();
    let subbands = wavelet::subbands(width, height, levels);
    EzwInput {
        layout: CoefficientLayout::new(width, height, &subbands, &shifts),
        coefficients,
        weights,
    }
}

fn bench_arithmetic(c: &mut Criterion) {
    let bits = skewed_bits(BITS, 0.1);
    let encode = |bits: &[bool]| {
        let mut encoder = ArithmeticEncoder::new();
        let mut model = BitModel::new();
        for &bit in bits {
            encoder.encode(bit, &mut model);
        }
        encoder.finish()
    };
    let decode = |stream: &[u8], n: usize| {
        let mut decoder = ArithmeticDecoder::new(stream, true);
        let mut model = BitModel::new();
        (0..n)
            .map(|_| decoder.decode(&mut model))
            .collect::<Vec<bool>>()
    };
    let stream = encode(&bits);
    assert_eq!(decode(&stream, bits.len()), bits, "range coder round trip");
    eprintln!(
        "arithmetic coder: {} bits with p = 0.1 -> {} bytes ({:.4} bits/decision)",
        bits.len(),
        stream.len(),
        stream.len() as f64 * 8.0 / bits.len() as f64
    );

    let mut group = c.benchmark_group("arithmetic coder");
    // Milliseconds an iteration: more samples than the default for a tighter estimate.
    group.sample_size(30);
    group.throughput(Throughput::Elements(bits.len() as u64));
    group.bench_function("encode 1M bits p=0.1", |b| {
        b.iter(|| black_box(encode(black_box(&bits))))
    });
    group.bench_function("decode 1M bits p=0.1", |b| {
        b.iter(|| {
            let mut decoder = ArithmeticDecoder::new(black_box(&stream), true);
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
    let input = ezw_input();
    let EzwInput {
        layout,
        coefficients,
        weights,
    } = &input;
    let top = ezw::top_plane(layout, coefficients);
    let encode = || ezw::encode(layout, coefficients, top, weights, Midpoint::Integer, None);
    let encoded = encode();
    assert!(encoded.complete);
    let decoded = Decoder::run(layout, Coder::default(), &encoded.bytes, true, top, None);
    assert!(decoded.complete);
    assert_eq!(
        &decoded.integer_coefficients(),
        coefficients,
        "EZW round trip"
    );
    eprintln!(
        "ezw {SIDE}x{SIDE}: top plane {:?}, {} passes, {} bytes ({:.3} bits/sample)",
        top,
        encoded.passes.len(),
        encoded.bytes.len(),
        encoded.bytes.len() as f64 * 8.0 / (SIDE * SIDE) as f64
    );

    let mut group = c.benchmark_group(format!("ezw {SIDE}x{SIDE} lossless 5/3"));
    // ~0.1 s an iteration: equal-sized samples rather than criterion's linear ramp.
    group.sampling_mode(SamplingMode::Flat);
    group.throughput(Throughput::Elements((SIDE * SIDE) as u64));
    group.bench_function("encode", |b| b.iter(|| black_box(encode())));
    group.bench_function("decode", |b| {
        b.iter(|| {
            black_box(Decoder::run(
                layout,
                Coder::default(),
                black_box(&encoded.bytes),
                true,
                top,
                None,
            ))
        })
    });
    group.finish();
}

fn bench_sinks(c: &mut Criterion) {
    let input = ezw_input();
    let EzwInput {
        layout,
        coefficients,
        weights,
    } = &input;
    let top = ezw::top_plane(layout, coefficients);
    let real_bits = ezw::encode(layout, coefficients, top, weights, Midpoint::Integer, None)
        .bytes
        .len() as f64
        * 8.0;
    let ideal_bits = ezw::count_bits(layout, coefficients, ContextChoice::ALL);
    eprintln!(
        "ezw sink: range coder {real_bits:.0} bits, ideal code length {ideal_bits:.0} bits \
         (difference {:+.0} bits)",
        real_bits - ideal_bits
    );

    let mut group = c.benchmark_group(format!("ezw {SIDE}x{SIDE} sink"));
    // ~0.1 s an iteration: equal-sized samples rather than criterion's linear ramp.
    group.sampling_mode(SamplingMode::Flat);
    group.throughput(Throughput::Elements((SIDE * SIDE) as u64));
    group.bench_function("ArithmeticEncoder (ezw::encode)", |b| {
        b.iter(|| {
            black_box(ezw::encode(
                layout,
                black_box(coefficients),
                top,
                weights,
                Midpoint::Integer,
                None,
            ))
        })
    });
    group.bench_function("BitCounter (ezw::count_bits)", |b| {
        b.iter(|| {
            black_box(ezw::count_bits(
                layout,
                black_box(coefficients),
                ContextChoice::ALL,
            ))
        })
    });
    group.finish();
}

criterion_group! {
    name = benches;
    // Small samples so the suite runs in about a minute; the command line overrides these.
    config = Criterion::default()
        .sample_size(10)
        .warm_up_time(Duration::from_secs(2))
        .measurement_time(Duration::from_secs(5));
    targets = bench_arithmetic, bench_ezw, bench_sinks
}
criterion_main!(benches);
