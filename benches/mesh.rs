//! The mesher against the decoder, on the bundled sample `samples/jacksboro_fault.tif`
//! (403 × 344) and a synthetic 2049 × 2049 fractal terrain (diamond–square, fixed seed).
//! For each DEM, from one lossless 5/3 stream:
//!
//! * **decode + map**: the full decode with the significance map (samples per second);
//! * **mesh plane P**: `Mesher::cells_at_plane` + `Mesher::triangulate` from the stored
//!   map at three planes, those whose meshes first reach about 1 %, 10 % and 50 % of the
//!   full grid's triangles (output triangles per second). Before the groups run, each
//!   plane's mesh time is printed as a share of the full decode's ("coarse mesh / full
//!   decode = X %"): the cost of another level of detail once the stream is decoded,
//!   then its CPU time a call as triangles per second and fingerprints of the mesh;
//! * **tolerance E**: `Mesher::build(MeshTarget::Tolerance(E), ..)` with a fresh mesher
//!   (error pyramid included) and with one whose pyramid is already built (excluded),
//!   at E = 5 and 20 on the sample and E = 20 on the large DEM (output triangles per
//!   second), and on the sample the error pyramid alone (samples per second).
//!
//! Every mesh is checked before it is timed (triangles > 0; tolerance meshes within E of
//! every sample).
//!
//! Run (a separate target dir avoids lock fights with other builds):
//!
//! ```text
//! CARGO_TARGET_DIR=/work/target-bench cargo bench --bench mesh
//! ```

use std::hint::black_box;
use std::path::Path;
use std::time::{Duration, Instant};

use criterion::measurement::WallTime;
use criterion::{
    criterion_group, criterion_main, BenchmarkGroup, Criterion, SamplingMode, Throughput,
};
use wavemesh::dem::{read_dem, ReadOptions};
use wavemesh::lod::Surface;
use wavemesh::mesh::cells::SplitRule;
use wavemesh::mesh::rasterise::mesh_error;
use wavemesh::mesh::{MeshTarget, Mesher};
use wavemesh_codec::{
    decode, encode, DecodeOptions, Decoded, EncodeOptions, Encoded, Quality, Raster, Samples,
};

mod support;
use support::{cpu_seconds_per_call, fnv1a};

/// Side of the synthetic terrain (`2^11 + 1`, diamond–square's natural size).
const SYNTHETIC_SIDE: usize = 2049;

/// A fractal terrain of `side × side` heights (`side = 2^k + 1`) by diamond–square with
/// roughness `0.55`, scaled to 0..3000 m, as i16.
fn fractal_terrain(side: usize, seed: u64) -> Raster {
    assert!((side - 1).is_power_of_two());
    let mut state = seed | 1;
    let mut noise = move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
    };
    let mut z = vec![0.0f64; side * side];
    let at = |x: usize, y: usize| y * side + x;
    for (x, y) in [(0, 0), (side - 1, 0), (0, side - 1), (side - 1, side - 1)] {
        z[at(x, y)] = noise();
    }
    let (mut step, mut amplitude) = (side - 1, 1.0f64);
    while step > 1 {
        let half = step / 2;
        // Diamond: the centre of each square.
        for y in (half..side).step_by(step) {
            for x in (half..side).step_by(step) {
                let mean = (z[at(x - half, y - half)]
                    + z[at(x + half, y - half)]
                    + z[at(x - half, y + half)]
                    + z[at(x + half, y + half)])
                    / 4.0;
                z[at(x, y)] = mean + amplitude * noise();
            }
        }
        // Square: the midpoint of each edge, from the neighbours inside the grid.
        for y in (0..side).step_by(half) {
            let first = if (y / half) % 2 == 0 { half } else { 0 };
            for x in (first..side).step_by(step) {
                let mut sum = 0.0;
                let mut n = 0.0;
                if x >= half {
                    sum += z[at(x - half, y)];
                    n += 1.0;
                }
                if x + half < side {
                    sum += z[at(x + half, y)];
                    n += 1.0;
                }
                if y >= half {
                    sum += z[at(x, y - half)];
                    n += 1.0;
                }
                if y + half < side {
                    sum += z[at(x, y + half)];
                    n += 1.0;
                }
                z[at(x, y)] = sum / n + amplitude * noise();
            }
        }
        step = half;
        amplitude *= 0.55;
    }
    let (lo, hi) = z
        .iter()
        .fold((f64::MAX, f64::MIN), |(lo, hi), &v| (lo.min(v), hi.max(v)));
    let values = z
        .iter()
        .map(|&v| ((v - lo) / (hi - lo) * 3000.0).round() as i16)
        .collect();
    Raster::new(side, side, Samples::I16(values)).expect("a valid raster")
}

/// Median wall-clock seconds of `runs` calls of `work`.
fn median_seconds<T>(runs: usize, mut work: impl FnMut() -> T) -> f64 {
    let mut times: Vec<f64> = (0..runs)
        .map(|_| {
            let start = Instant::now();
            black_box(work());
            start.elapsed().as_secs_f64()
        })
        .collect();
    times.sort_by(f64::total_cmp);
    times[runs / 2]
}

/// Prints the CPU time of `cells_at_plane` + `triangulate` at `plane` (about a
/// second's worth of calls) as output triangles per second, and fingerprints of the
/// mesh's triangles and vertices (equal before and after a change that keeps them).
fn print_extraction_cpu(name: &str, mesher: &Mesher<'_>, plane: u32, triangles: usize) {
    let extract = || mesher.triangulate(&mesher.cells_at_plane(plane, SplitRule::Zerotree));
    let mesh = extract();
    let calls = (100_000_000 / triangles.max(1)).clamp(8, 20_000);
    let Some(seconds) = cpu_seconds_per_call(calls, || {
        black_box(extract());
    }) else {
        return;
    };
    eprintln!(
        "{name}: plane {plane}: extraction CPU {:.3} ms a call ({calls} calls) = {:.1} M triangles/s; \
         fingerprints triangles {:016x}, vertices {:016x}",
        seconds * 1e3,
        triangles as f64 / seconds / 1e6,
        fnv1a(mesh.triangles.iter().flatten().map(|&v| u64::from(v))),
        fnv1a(mesh.vertices.iter().map(|&s| u64::from(s))),
    );
}

/// The DEM's lossless file, its decode with the significance map, and the mesher on it.
struct Prepared {
    encoded: Encoded,
    with_map: DecodeOptions,
    decoded: Decoded,
    surface: Surface,
}

impl Prepared {
    fn of(name: &str, raster: &Raster) -> Prepared {
        let start = Instant::now();
        let encoded = encode(
            raster,
            &EncodeOptions::new(Quality::Lossless, None).single_stream(),
        )
        .expect("encode");
        let encode_seconds = start.elapsed().as_secs_f64();
        let with_map = DecodeOptions::default().with_significance_map(true);
        let decoded = decode(&encoded.bytes, &with_map).expect("decode");
        assert!(decoded.complete, "{name}: complete decode");
        assert_eq!(&decoded.raster, raster, "{name}: lossless round trip");
        let surface = Surface::of(&decoded.raster);
        eprintln!(
            "{name}: {}x{}, lossless {} bytes ({:.3} bpp), top plane {}, encode {encode_seconds:.3} s",
            raster.width,
            raster.height,
            encoded.bytes.len(),
            encoded.bytes.len() as f64 * 8.0 / raster.len() as f64,
            decoded.header.top_plane.map_or(0, u32::from),
        );
        Prepared {
            encoded,
            with_map,
            decoded,
            surface,
        }
    }

    fn mesher(&self) -> Mesher<'_> {
        let map = self
            .decoded
            .significance
            .as_ref()
            .expect("asked for the map");
        Mesher::new(map, self.surface.heights(), &self.surface.valid)
    }
}

/// The planes whose meshes first reach 1 %, 10 % and 50 % of the full grid's
/// `full_triangles` (planes from `top` down, until 50 % or plane 0), with their counts.
fn planes_to_bench(
    name: &str,
    mesher: &Mesher,
    top: u32,
    full_triangles: usize,
) -> Vec<(u32, usize)> {
    let mut counts: Vec<(u32, usize)> = Vec::new();
    for p in (0..=top).rev() {
        let triangles = mesher
            .triangulate(&mesher.cells_at_plane(p, SplitRule::Zerotree))
            .triangles
            .len();
        counts.push((p, triangles));
        if triangles as f64 >= 0.5 * full_triangles as f64 {
            break;
        }
    }
    assert!(
        counts.windows(2).all(|w| w[1].1 >= w[0].1),
        "{name}: triangles grow as the plane falls: {counts:?}"
    );
    let mut planes: Vec<(u32, usize)> = [0.01, 0.10, 0.50]
        .iter()
        .map(|&share| {
            *counts
                .iter()
                .find(|(_, t)| *t as f64 >= share * full_triangles as f64)
                .unwrap_or(counts.last().expect("at least one plane"))
        })
        .collect();
    planes.dedup();
    assert!(planes.iter().all(|&(_, t)| t > 0), "{name}: empty meshes");
    planes
}

/// The shares printed before criterion runs (medians of a few runs each): each plane's
/// mesh against the full decode, and its extraction's CPU time.
fn print_shares(name: &str, prepared: &Prepared, planes: &[(u32, usize)], full_triangles: usize) {
    let mesher = prepared.mesher();
    let runs = if prepared.decoded.raster.len() > 1 << 20 {
        3
    } else {
        9
    };
    let decode_seconds =
        median_seconds(runs, || decode(&prepared.encoded.bytes, &prepared.with_map));
    eprintln!("{name}: full decode with the map = {decode_seconds:.4} s (median of {runs})");
    for &(plane, triangles) in planes {
        let mesh_seconds = median_seconds(runs, || {
            mesher.triangulate(&mesher.cells_at_plane(plane, SplitRule::Zerotree))
        });
        eprintln!(
            "{name}: plane {plane} ({triangles} triangles, {:.2} % of the grid's): \
             coarse mesh / full decode = {:.2} % ({mesh_seconds:.5} s / {decode_seconds:.4} s)",
            100.0 * triangles as f64 / full_triangles as f64,
            100.0 * mesh_seconds / decode_seconds
        );
        print_extraction_cpu(name, &mesher, plane, triangles);
    }
}

/// (d) Tolerance meshes, with and without building the error pyramid.
fn bench_tolerances(group: &mut BenchmarkGroup<'_, WallTime>, name: &str, prepared: &Prepared) {
    let surface = &prepared.surface;
    let samples = surface.heights.len() as u64;
    let full_triangles = 2 * (surface.width - 1) * (surface.height - 1);
    let rule = SplitRule::Zerotree;
    let mut warm = prepared.mesher();
    let start = Instant::now();
    warm.error_pyramid();
    eprintln!(
        "{name}: error pyramid {:.4} s",
        start.elapsed().as_secs_f64()
    );
    // On the large DEM every pyramid costs seconds: one tolerance there, and the
    // pyramid's own time is the difference of the two tolerance lines.
    let large = samples > 1 << 20;
    if !large {
        group.throughput(Throughput::Elements(samples));
        group.bench_function("error pyramid", |b| {
            b.iter(|| {
                let mut fresh = prepared.mesher();
                fresh.error_pyramid();
                black_box(fresh)
            })
        });
    }
    let tolerances: &[f64] = if large { &[20.0] } else { &[5.0, 20.0] };
    for &tolerance in tolerances {
        let result = warm.build(MeshTarget::Tolerance(tolerance), rule, None);
        let triangles = result.mesh.triangles.len();
        assert!(triangles > 0, "{name}: tolerance {tolerance}: no triangles");
        let error = mesh_error(
            &result.mesh,
            &surface.heights,
            &surface.heights,
            &surface.valid,
        );
        assert!(
            error.max_error <= tolerance,
            "{name}: tolerance {tolerance}: max error {}",
            error.max_error
        );
        eprintln!(
            "{name}: tolerance {tolerance}: {triangles} triangles ({:.2} % of the grid's), \
             {} refinement splits, RMSE {:.3}",
            100.0 * triangles as f64 / full_triangles as f64,
            result.refinement_splits,
            error.rmse
        );
        group.throughput(Throughput::Elements(triangles as u64));
        group.bench_function(format!("tolerance {tolerance} with pyramid"), |b| {
            b.iter(|| {
                let mut fresh = prepared.mesher();
                black_box(fresh.build(MeshTarget::Tolerance(tolerance), rule, None))
            })
        });
        group.bench_function(format!("tolerance {tolerance} pyramid built"), |b| {
            b.iter(|| black_box(warm.build(MeshTarget::Tolerance(tolerance), rule, None)))
        });
    }
}

fn bench_dem(c: &mut Criterion, name: &str, raster: &Raster) {
    let full_triangles = 2 * (raster.width - 1) * (raster.height - 1);
    let prepared = Prepared::of(name, raster);
    let mesher = prepared.mesher();
    let top = prepared.decoded.header.top_plane.map_or(0, u32::from);
    let planes = planes_to_bench(name, &mesher, top, full_triangles);
    print_shares(name, &prepared, &planes, full_triangles);

    let mut group = c.benchmark_group(format!("mesh {name}"));
    group.sampling_mode(SamplingMode::Flat);
    // (a) The full decode with the significance map.
    group.throughput(Throughput::Elements(raster.len() as u64));
    group.bench_function("decode lossless + map", |b| {
        b.iter(|| {
            black_box(decode(
                black_box(&prepared.encoded.bytes),
                &prepared.with_map,
            ))
        })
    });
    // (b, c) Cells and triangles from the stored map.
    for &(plane, triangles) in &planes {
        group.throughput(Throughput::Elements(triangles as u64));
        group.bench_function(format!("mesh plane {plane} ({triangles} tri)"), |b| {
            b.iter(|| {
                let tree = mesher.cells_at_plane(black_box(plane), SplitRule::Zerotree);
                black_box(mesher.triangulate(&tree))
            })
        });
    }
    bench_tolerances(&mut group, name, &prepared);
    group.finish();
}

fn bench_mesh(c: &mut Criterion) {
    let sample = Path::new(env!("CARGO_MANIFEST_DIR")).join("samples/jacksboro_fault.tif");
    match read_dem(&sample, &ReadOptions::default()) {
        Ok(raster) => bench_dem(c, "jacksboro_fault", &raster),
        Err(e) => eprintln!("skipping jacksboro_fault: {e}"),
    }
    let start = Instant::now();
    let synthetic = fractal_terrain(SYNTHETIC_SIDE, 0x5eed_1234);
    eprintln!(
        "fractal_{SYNTHETIC_SIDE}: generated in {:.3} s",
        start.elapsed().as_secs_f64()
    );
    bench_dem(c, &format!("fractal_{SYNTHETIC_SIDE}"), &synthetic);
}

criterion_group! {
    name = benches;
    // Small samples so the whole bench runs in a couple of minutes; the command line
    // overrides these.
    config = Criterion::default()
        .without_plots()
        .sample_size(10)
        .warm_up_time(Duration::from_millis(500))
        .measurement_time(Duration::from_secs(2));
    targets = bench_mesh
}
criterion_main!(benches);
