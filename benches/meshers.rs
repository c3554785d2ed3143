//! Greedy insertion and QEM (`qem`) against the `delatin` crate, side by side on the same heights: our
//! `greedy` (data-dependent flips), our `delaunay` (Delatin's algorithm) and the crate,
//! each meshing to a height tolerance E, on the bundled sample
//! `samples/jacksboro_fault.tif` (403 × 344) and, when `../shared/dem` is present, on
//! `fuji_terrainrgb` (512 × 512, the fixture Delatin and Martini test with).
//!
//! Run (a separate target dir avoids lock fights with other builds):
//!
//! ```text
//! CARGO_TARGET_DIR=/work/target-bench cargo bench --bench meshers -- --warm-up-time 1 --measurement-time 3
//! ```

use std::hint::black_box;
use std::path::Path;

use criterion::{criterion_group, criterion_main, Criterion, SamplingMode};
use wavemesh::dem::{read_dem, ReadOptions};
use wavemesh::lod::Surface;
use wavemesh::meshers::{build, Budget, Method};
use wavemesh_codec::Raster;

/// The DEMs benched: the bundled sample, and fuji when the shared folder is there.
fn dems() -> Vec<(&'static str, Raster)> {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut out = Vec::new();
    let read = |p: &Path| read_dem(p, &ReadOptions::default()).expect("a readable DEM");
    out.push(("jacksboro", read(&root.join("samples/jacksboro_fault.tif"))));
    let fuji = root.join("../shared/dem/fuji_terrainrgb/fuji_terrainrgb.tif");
    if fuji.exists() {
        out.push(("fuji", read(&fuji)));
    } else {
        eprintln!("SKIPPED fuji: {} not found", fuji.display());
    }
    out
}

fn meshers(c: &mut Criterion) {
    for (name, raster) in dems() {
        let surface = Surface::of(&raster);
        let mut group = c.benchmark_group(format!("meshers/{name}"));
        group.sampling_mode(SamplingMode::Flat).sample_size(10);
        for e in [10.0, 2.0] {
            for method in [
                Method::Greedy,
                Method::Delaunay,
                Method::Qem,
                Method::Delatin,
            ] {
                let mesh = build(method, &raster, &surface, Budget::MaxError(e)).unwrap();
                eprintln!(
                    "{name} {} E={e}: {} triangles",
                    method.name(),
                    mesh.triangles.len()
                );
                group.bench_function(format!("{} E={e}", method.name()), |b| {
                    b.iter(|| black_box(build(method, &raster, &surface, Budget::MaxError(e))))
                });
            }
        }
        group.finish();
    }
}

criterion_group!(benches, meshers);
criterion_main!(benches);
