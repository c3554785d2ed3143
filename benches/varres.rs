//! The variable-resolution model (seed paper 001): one simplification (the model's
//! build) against extracting a mesh out of it, at the error where about 2 % and 20 %
//! of the grid's triangles remain, on the bundled sample `samples/jacksboro_fault.tif`
//! (403 × 344). The extraction is the model's point: it must be far faster (the
//! target is ≥ 20×) than simplifying again.
//!
//! ```text
//! CARGO_TARGET_DIR=/work/target-bench cargo bench --bench varres -- --warm-up-time 1 --measurement-time 3
//! ```

use std::hint::black_box;
use std::path::Path;

use criterion::{criterion_group, criterion_main, Criterion, SamplingMode};
use wavemesh::dem::{read_dem, ReadOptions};
use wavemesh::lod::Surface;
use wavemesh::mesh::varres::extract::{grid_mesh, triangles_at_error};
use wavemesh::mesh::varres::{build_model, VarresOptions};

fn varres(c: &mut Criterion) {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("samples/jacksboro_fault.tif");
    let raster = read_dem(&path, &ReadOptions::default()).expect("the bundled sample");
    let s = Surface::of(&raster);
    let options = VarresOptions::default();
    let mut group = c.benchmark_group("varres/jacksboro");
    group.sampling_mode(SamplingMode::Flat).sample_size(10);
    group.bench_function("simplify", |b| {
        b.iter(|| build_model(s.width, s.height, &s.heights, &s.valid, black_box(&options)))
    });
    let model = build_model(s.width, s.height, &s.heights, &s.valid, &options).unwrap();
    let grid_triangles = model.step_triangles[0] as usize;
    for percent in [2, 20] {
        let step = model.step_within(grid_triangles * percent / 100);
        let epsilon = model.error_of_step(step);
        let mut triangles = Vec::new();
        group.bench_function(format!("extract_{percent}pct"), |b| {
            b.iter(|| triangles_at_error(&model, black_box(epsilon), &mut triangles))
        });
        group.bench_function(format!("extract_{percent}pct_indexed"), |b| {
            b.iter(|| {
                triangles_at_error(&model, black_box(epsilon), &mut triangles);
                grid_mesh(model.width, model.height, &triangles)
            })
        });
    }
    group.finish();
}

criterion_group!(benches, varres);
criterion_main!(benches);
