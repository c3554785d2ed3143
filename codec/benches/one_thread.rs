//! Whole encode and decode on one thread, as issue 8's speed target counts them: raster
//! in memory → `.ezw` bytes → raster, one stream (no tiles), lossless 5/3 and 9/7 at
//! 1 bit per sample. Everything around the zerotree scan is in it: the valid mask and
//! range, quantisation, the transform, the container, the output samples.
//!
//! Inputs: `srtm3_n57e011` read from its raw `.hgt` in `../shared/dem` (skipped with a
//! notice on stderr when absent), and a 1024×1024 synthetic u16 terrain (always).
//!
//! Run (a separate target dir avoids lock fights with other builds):
//!
//! ```text
//! CARGO_TARGET_DIR=/work/target-bench cargo bench -p wavemesh-codec --bench one_thread -- \
//!     --warm-up-time 1 --measurement-time 3
//! ```

mod support;

use criterion::{criterion_group, criterion_main, Criterion, SamplingMode, Throughput};
use std::hint::black_box;
use std::path::Path;
use std::time::Duration;
use wavemesh_codec::{
    decode, encode, DecodeOptions, EncodeOptions, Quality, Raster, Samples, Wavelet,
};

/// Side of the synthetic terrain.
const SIDE: usize = 1024;

/// The benches' synthetic terrain in whole decimetres.
fn synthetic() -> Raster {
    let heights = support::terrain_metres(SIDE, SIDE)
        .into_iter()
        .map(|m| (m * 10.0).round() as u16)
        .collect();
    Raster::new(SIDE, SIDE, Samples::U16(heights)).expect("a synthetic raster")
}

/// `srtm3_n57e011` from its `.hgt` (1201 × 1201 big-endian i16, nodata −32768), if present.
fn srtm3() -> Option<Raster> {
    let path =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../../shared/dem/srtm3_n57e011/N57E011.hgt");
    let Ok(bytes) = std::fs::read(&path) else {
        eprintln!("skipping srtm3_n57e011: {} not found", path.display());
        return None;
    };
    let heights = bytes
        .chunks_exact(2)
        .map(|b| i16::from_be_bytes([b[0], b[1]]))
        .collect();
    let mut raster = Raster::new(1201, 1201, Samples::I16(heights)).ok()?;
    raster.nodata = Some(-32768.0);
    Some(raster)
}

/// One stream on one thread: lossless, or 9/7 cut at `budget` bytes.
fn options(wavelet: Wavelet, budget: Option<u64>) -> EncodeOptions {
    let mut options = EncodeOptions::new(Quality::Lossless, budget);
    options.wavelet = wavelet;
    options.tile_size = None;
    options.threads = 1;
    options
}

fn bench_one_thread(c: &mut Criterion) {
    let inputs = [
        ("srtm3_n57e011", srtm3()),
        ("synthetic 1024²", Some(synthetic())),
    ];
    let decode_options = DecodeOptions::default().with_threads(1);
    let mut group = c.benchmark_group("one thread");
    group.sampling_mode(SamplingMode::Flat);
    group.sample_size(10);
    group.measurement_time(Duration::from_secs(5));
    for (name, raster) in inputs {
        let Some(raster) = raster else { continue };
        let samples = raster.len() as u64;
        group.throughput(Throughput::Elements(samples));
        for (mode, wavelet, budget) in [
            ("lossless", Wavelet::Int53, None),
            ("9/7 1 bpp", Wavelet::Cdf97, Some(samples / 8)),
        ] {
            let options = options(wavelet, budget);
            let encoded = encode(&raster, &options).expect("encode");
            let decoded = decode(&encoded.bytes, &decode_options).expect("decode");
            if budget.is_none() {
                assert_eq!(decoded.raster, raster, "{name}: lossless round trip");
            }
            group.bench_function(format!("{name} {mode} encode"), |b| {
                b.iter(|| black_box(encode(black_box(&raster), &options).expect("encode")))
            });
            group.bench_function(format!("{name} {mode} decode"), |b| {
                b.iter(|| black_box(decode(black_box(&encoded.bytes), &decode_options)))
            });
        }
    }
    group.finish();
}

criterion_group!(benches, bench_one_thread);
criterion_main!(benches);
