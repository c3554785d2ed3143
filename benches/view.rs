//! View-dependent terrain per frame on two synthetic 4097 × 4097 terrains, each one
//! lossless 5/3 stream decoded once with its significance map: **ridges** (eight octaves
//! of rotated sine ridges plus ±2 m of white noise, 0..~3000 m: the noise is the
//! adversarial case, every near cell misses by it) and **fractal** ([`FractalTerrain`],
//! the project's fBm terrain, ~100..2900 m in whole metres). A 1600 × 900 viewport, 60°
//! field of view and τ = 1 pixel, the camera at 3400 m looking ahead and down:
//!
//! * **select from scratch**: [`ViewTerrain::select`] (the rebuild);
//! * **incremental update**: [`Incremental::update`] on a smooth flight (the camera moves
//!   1 m and turns 0.05° a frame, back and forth between two cameras) and on a straight
//!   one (1 m a frame ahead, no turn);
//! * **morph**: [`morph`] of the selection's mesh (one frame repeated), and on the smooth
//!   flight (the two cameras' own meshes alternately, one [`MorphScratch`] kept);
//! * **triangulate**: the selection's triangles (hanging vertices included).
//!
//! Selection plus morphing a frame is incremental update + morph (+ triangulate to get
//! the mesh the morph reads). Before criterion runs, each terrain prints its frame, the
//! leaves 20 updates revisited, fingerprints of the morph output and of the leaves after
//! those updates (equal before and after a change that keeps the output), the heap the
//! morph keeps from frame to frame ([`MorphScratch::heap_bytes`]), and the CPU
//! time a call of each measurement (the machine is shared: wall-clock medians count the
//! time others hold the core). Run:
//!
//! ```text
//! CARGO_TARGET_DIR=/work/target-bench cargo bench --bench view -- --warm-up-time 1 --measurement-time 3
//! ```

use std::hint::black_box;
use std::time::Instant;

use bitvec::prelude::*;
use criterion::{criterion_group, criterion_main, Criterion};
use glam::DVec3;
use wavemesh::lod::Surface;
use wavemesh::mesh::export::Placement;
use wavemesh::synth::FractalTerrain;
use wavemesh::view::camera::{Camera, View};
use wavemesh::view::incremental::Incremental;
use wavemesh::view::morph::{morph, MorphScratch};
use wavemesh::view::selection::{Rule, ViewTerrain};
use wavemesh_codec::{decode, encode, DecodeOptions, EncodeOptions, Quality, Raster, Samples};

mod support;
use support::{cpu_seconds_per_call, fnv1a};

const SIDE: usize = 4097;

/// Eight octaves of sine ridges in random directions (amplitude halving, frequency
/// doubling) plus ±2 m of noise, in metres as i16.
fn synthetic_terrain(side: usize) -> Raster {
    let mut state = 0x9e37_79b9_7f4a_7c15u64;
    let mut random = move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state >> 11) as f64 / (1u64 << 53) as f64
    };
    let octaves: Vec<(f64, f64, f64, f64)> = (0..8)
        .map(|k| {
            let angle = random() * std::f64::consts::TAU;
            let frequency = 2f64.powi(k) * std::f64::consts::TAU / side as f64 * 1.5;
            (
                angle.cos() * frequency,
                angle.sin() * frequency,
                random() * 6.3,
                1200.0 / 2f64.powi(k),
            )
        })
        .collect();
    let values = (0..side * side)
        .map(|s| {
            let (x, y) = ((s % side) as f64, (s / side) as f64);
            let ridges: f64 = octaves
                .iter()
                .map(|&(fx, fy, phase, amplitude)| {
                    amplitude * (1.0 - (x * fx + y * fy + phase).sin().abs())
                })
                .sum();
            (ridges + 4.0 * random() - 2.0) as i16
        })
        .collect();
    Raster::new(side, side, Samples::I16(values)).expect("valid raster")
}

/// The project's fractal terrain (seed 7), in whole metres.
fn fractal_terrain(side: usize) -> Raster {
    let terrain = FractalTerrain::new(7);
    let mut values = vec![0i16; side * side];
    for (y, row) in values.chunks_mut(side).enumerate() {
        terrain.row_i16(y, row);
    }
    Raster::new(side, side, Samples::I16(values)).expect("valid raster")
}

/// A camera at step `k` of a smooth flight across the terrain.
fn camera(k: f64) -> View {
    let eye = DVec3::new(600.0 + k, 1200.0 + 0.3 * k, 3400.0);
    let heading = 0.5 + k * 0.05f64.to_radians();
    let look = eye + DVec3::new(heading.cos() * 2000.0, heading.sin() * 2000.0, -1500.0);
    Camera::new(eye, look, 60.0, (1600, 900))
        .expect("valid camera")
        .view()
}

/// Prints the CPU time a call of `f` takes over `calls` calls.
fn print_cpu_time(label: &str, calls: usize, f: impl FnMut()) {
    if let Some(seconds) = cpu_seconds_per_call(calls, f) {
        eprintln!(
            "{label}: CPU {:.1} ms a call ({calls} calls)",
            seconds * 1e3
        );
    }
}

/// A camera at step `k` of a straight flight: [`camera`]'s motion without the turn.
fn straight(k: f64) -> View {
    let eye = DVec3::new(600.0 + k, 1200.0 + 0.3 * k, 3400.0);
    let look = eye + DVec3::new(0.5f64.cos() * 2000.0, 0.5f64.sin() * 2000.0, -1500.0);
    Camera::new(eye, look, 60.0, (1600, 900))
        .expect("valid camera")
        .view()
}

fn bench_view(c: &mut Criterion) {
    bench_terrain(c, "ridges", synthetic_terrain(SIDE));
    bench_terrain(c, "fractal", fractal_terrain(SIDE));
}

/// The four measurements on `raster`, in a group named after `name`.
fn bench_terrain(c: &mut Criterion, name: &str, raster: Raster) {
    let start = Instant::now();
    let stream = encode(
        &raster,
        &EncodeOptions::new(Quality::Lossless, None).single_stream(),
    )
    .expect("encodes");
    drop(raster);
    let options = DecodeOptions::default().with_significance_map(true);
    let decoded = decode(&stream.bytes, &options).expect("decodes");
    let surface = Surface::of(&decoded.raster);
    let map = decoded.significance.as_ref().expect("map");
    let valid: BitVec<u64, Lsb0> = surface.valid.clone();
    let terrain = ViewTerrain::new(map, surface.heights(), &valid, Placement::pixel(1.0), 0)
        .expect("sizes agree");
    eprintln!(
        "{name} setup (encode, decode, summaries): {:.1} s",
        start.elapsed().as_secs_f64()
    );
    let rule = Rule::ScreenSpace { tau: 1.0 };
    let (a, b) = (camera(0.0), camera(1.0));
    let tree = terrain.select(&a, rule);
    let mesh = terrain.triangulate(&tree);
    eprintln!(
        "{name} frame: {} cells, {} triangles, {} vertices",
        tree.leaves().len(),
        mesh.triangles.len(),
        mesh.vertices.len()
    );
    let mut incremental = Incremental::new(&terrain, &a, rule);
    let mut flip = false;
    let stats: Vec<_> = (0..20)
        .map(|_| {
            flip = !flip;
            incremental.update(&terrain, if flip { &b } else { &a })
        })
        .collect();
    eprintln!(
        "{name} updates 1..20: revisited {:?} leaves",
        stats.iter().map(|s| s.revisited).collect::<Vec<_>>()
    );
    let mut scratch = MorphScratch::default();
    let morphed = morph(&terrain, &a, rule, &tree, &mesh, &mut scratch);
    let leaves = incremental.tree().leaves();
    eprintln!(
        "{name} fingerprints (equal before and after a speed change): morph {:016x}, leaves after 20 updates {:016x}",
        fnv1a(morphed.iter().map(|z| z.to_bits())),
        fnv1a(leaves.iter().map(|c| u64::from(c.level) << 48 | u64::from(c.j) << 24 | u64::from(c.i)))
    );
    print_cpu_time(&format!("{name} select from scratch"), 8, || {
        black_box(terrain.select(&a, rule));
    });
    print_cpu_time(&format!("{name} incremental update"), 24, || {
        flip = !flip;
        black_box(incremental.update(&terrain, if flip { &b } else { &a }));
    });
    let mut straight_flight = Incremental::new(&terrain, &straight(0.0), rule);
    let mut step = 0.0;
    print_cpu_time(&format!("{name} incremental update, straight"), 24, || {
        step += 1.0;
        black_box(straight_flight.update(&terrain, &straight(step)));
    });
    print_cpu_time(&format!("{name} morph"), 8, || {
        black_box(morph(&terrain, &a, rule, &tree, &mesh, &mut scratch));
    });
    let tree_b = terrain.select(&b, rule);
    let frames = [
        (&a, &tree, &mesh),
        (&b, &tree_b, &terrain.triangulate(&tree_b)),
    ];
    let mut flight_scratch = MorphScratch::default();
    print_cpu_time(&format!("{name} morph, smooth flight"), 24, || {
        flip = !flip;
        let (view, tree, mesh) = frames[usize::from(flip)];
        black_box(morph(&terrain, view, rule, tree, mesh, &mut flight_scratch));
    });
    eprintln!(
        "{name} morph state (MorphScratch): {:.1} MB",
        flight_scratch.heap_bytes() as f64 / 1e6
    );
    print_cpu_time(&format!("{name} triangulate"), 8, || {
        black_box(terrain.triangulate(&tree));
    });
    let mut group = c.benchmark_group(format!("view {name} 4097² 1600×900 τ=1"));
    group.sample_size(10);
    group.bench_function("select from scratch", |bench| {
        bench.iter(|| black_box(terrain.select(black_box(&a), rule)))
    });
    group.bench_function("incremental update (smooth flight)", |bench| {
        bench.iter(|| {
            flip = !flip;
            black_box(incremental.update(&terrain, if flip { &b } else { &a }))
        })
    });
    group.bench_function("incremental update (straight flight)", |bench| {
        bench.iter(|| {
            step += 1.0;
            black_box(straight_flight.update(&terrain, &straight(step)))
        })
    });
    group.bench_function("triangulate", |bench| {
        bench.iter(|| black_box(terrain.triangulate(&tree)))
    });
    group.bench_function("morph", |bench| {
        bench.iter(|| black_box(morph(&terrain, &a, rule, &tree, &mesh, &mut scratch)))
    });
    group.finish();
}

criterion_group!(benches, bench_view);
criterion_main!(benches);
