//! Whole-file encode and decode (DEM in memory → `.ezw` bytes → DEM) on the bundled sample
//! and, when `../shared/dem` is present, on `sthelens_10m` (2000×2000 u16): lossless 5/3,
//! 9/7 at 1 bpp, and a 0.25 bpp prefix of that 9/7 stream.
//!
//! `cargo bench --bench pipeline`

use std::path::{Path, PathBuf};

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use std::hint::black_box;
use wavemesh::dem::{read_dem, ReadOptions};
use wavemesh_codec::{decode, encode, DecodeOptions, EncodeOptions, Quality, Wavelet};

fn inputs() -> Vec<(String, PathBuf)> {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut out = vec![(
        "jacksboro_fault".to_string(),
        root.join("samples/jacksboro_fault.tif"),
    )];
    let sthelens = root.join("../shared/dem/sthelens_10m/sthelens_10m.tif");
    if sthelens.exists() {
        out.push(("sthelens_10m".to_string(), sthelens));
    } else {
        eprintln!("skipping sthelens_10m: ../shared/dem not found");
    }
    out
}

fn bench_pipeline(c: &mut Criterion) {
    for (name, path) in inputs() {
        let raster = match read_dem(&path, &ReadOptions::default()) {
            Ok(r) => r,
            Err(e) => {
                eprintln!("skipping {name}: {e}");
                continue;
            }
        };
        let samples = raster.len() as u64;
        let lossless_options = EncodeOptions::new(Quality::Lossless, None);
        let lossless = encode(&raster, &lossless_options).expect("lossless encode");
        let mut lossy_options = EncodeOptions::new(Quality::Lossless, Some(samples / 8));
        lossy_options.wavelet = Wavelet::Cdf97;
        let lossy = encode(&raster, &lossy_options).expect("9/7 encode");
        let prefix = DecodeOptions {
            max_bytes: Some(samples / 32),
            ..DecodeOptions::default()
        };

        let mut group = c.benchmark_group(format!("pipeline {name}"));
        group.sample_size(10);
        group.measurement_time(std::time::Duration::from_secs(5));
        group.throughput(Throughput::Elements(samples));
        group.bench_function("encode lossless 5/3", |b| {
            b.iter(|| black_box(encode(&raster, &lossless_options)))
        });
        group.bench_function("decode lossless 5/3", |b| {
            b.iter(|| black_box(decode(&lossless.bytes, &DecodeOptions::default())))
        });
        group.bench_function("encode 9/7 1 bpp", |b| {
            b.iter(|| black_box(encode(&raster, &lossy_options)))
        });
        group.bench_function("decode 9/7 1 bpp", |b| {
            b.iter(|| black_box(decode(&lossy.bytes, &DecodeOptions::default())))
        });
        group.bench_function("decode 9/7 prefix 0.25 bpp", |b| {
            b.iter(|| black_box(decode(&lossy.bytes, &prefix)))
        });
        group.finish();
    }
}

criterion_group!(benches, bench_pipeline);
criterion_main!(benches);
