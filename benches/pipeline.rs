//! Whole-file encode and decode (raster in memory → `.ezw` bytes → raster), on the bundled
//! sample `samples/jacksboro_fault.tif` and, when `../shared/dem` is present, on
//! `sthelens_10m.tif`. For each DEM:
//!
//! * lossless 5/3: encode and decode;
//! * 9/7 with a 1 bit-per-sample budget (`samples / 8` bytes for the whole file): encode
//!   and decode;
//! * decode of the first `samples / 32` bytes (0.25 bpp) of that 9/7 file (progressive
//!   decoding of a prefix).
//!
//! Throughput is in samples per second. A missing DEM is skipped with a notice on stderr.
//!
//! Run (a separate target dir avoids lock fights with other builds):
//!
//! ```text
//! CARGO_TARGET_DIR=/work/target-bench cargo bench --bench pipeline
//! # quicker:
//! CARGO_TARGET_DIR=/work/target-bench cargo bench --bench pipeline -- \
//!     --warm-up-time 1 --measurement-time 3
//! ```

use criterion::{criterion_group, criterion_main, Criterion, SamplingMode, Throughput};
use std::hint::black_box;
use std::path::{Path, PathBuf};
use std::time::Duration;
use wavemesh::dem::{read_dem, ReadOptions};
use wavemesh_codec::{decode, encode, DecodeOptions, EncodeOptions, Quality, Wavelet};

/// The DEMs to run on, by name; those absent are reported and left out.
fn inputs() -> Vec<(&'static str, PathBuf)> {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    [
        ("jacksboro_fault", root.join("samples/jacksboro_fault.tif")),
        (
            "sthelens_10m",
            root.join("../shared/dem/sthelens_10m/sthelens_10m.tif"),
        ),
    ]
    .into_iter()
    .filter(|(name, path)| {
        let present = path.is_file();
        if !present {
            eprintln!("skipping {name}: {} not found", path.display());
        }
        present
    })
    .collect()
}

fn bench_pipeline(c: &mut Criterion) {
    for (name, path) in inputs() {
        let raster = match read_dem(&path, &ReadOptions::default()) {
            Ok(raster) => raster,
            Err(e) => {
                eprintln!("skipping {name}: {e}");
                continue;
            }
        };
        let samples = raster.len() as u64;

        let lossless_options = EncodeOptions::new(Quality::Lossless, None);
        let lossless = encode(&raster, &lossless_options).expect("lossless encode");
        let round_trip =
            decode(&lossless.bytes, &DecodeOptions::default()).expect("lossless decode");
        assert_eq!(round_trip.raster, raster, "{name}: lossless round trip");

        // 1 bit per sample for the whole file (header included).
        let budget = samples / 8;
        let lossy_options =
            EncodeOptions::new(Quality::Lossless, Some(budget)).with_wavelet(Wavelet::Cdf97);
        let lossy = encode(&raster, &lossy_options).expect("9/7 encode");
        assert!(
            lossy.bytes.len() as u64 <= budget,
            "{name}: 9/7 over budget"
        );
        // The first 0.25 bpp of the 9/7 file.
        let prefix = DecodeOptions::default().with_max_bytes(Some(samples / 32));
        decode(&lossy.bytes, &prefix).expect("prefix decode");

        eprintln!(
            "{name}: {}x{} {:?}, lossless {} bytes ({:.3} bpp), 9/7 {} bytes, prefix {} bytes",
            raster.width,
            raster.height,
            raster.sample_type(),
            lossless.bytes.len(),
            lossless.bytes.len() as f64 * 8.0 / samples as f64,
            lossy.bytes.len(),
            samples / 32
        );

        let mut group = c.benchmark_group(format!("pipeline {name}"));
        // Tens to hundreds of milliseconds an iteration: equal-sized samples.
        group.sampling_mode(SamplingMode::Flat);
        group.throughput(Throughput::Elements(samples));
        group.bench_function("encode lossless 5/3", |b| {
            b.iter(|| black_box(encode(black_box(&raster), &lossless_options)))
        });
        group.bench_function("decode lossless 5/3", |b| {
            b.iter(|| {
                black_box(decode(
                    black_box(&lossless.bytes),
                    &DecodeOptions::default(),
                ))
            })
        });
        group.bench_function("encode 9/7 1 bpp", |b| {
            b.iter(|| black_box(encode(black_box(&raster), &lossy_options)))
        });
        group.bench_function("decode 9/7 1 bpp", |b| {
            b.iter(|| black_box(decode(black_box(&lossy.bytes), &DecodeOptions::default())))
        });
        group.bench_function("decode 9/7 0.25 bpp prefix", |b| {
            b.iter(|| black_box(decode(black_box(&lossy.bytes), &prefix)))
        });
        group.finish();
    }
}

criterion_group! {
    name = benches;
    // Small samples so the suite runs in a few minutes; the command line overrides these.
    config = Criterion::default()
        .sample_size(10)
        .warm_up_time(Duration::from_secs(2))
        .measurement_time(Duration::from_secs(5));
    targets = bench_pipeline
}
criterion_main!(benches);
