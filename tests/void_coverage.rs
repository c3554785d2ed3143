//! The zerotree meshes cover every valid sample they can: a grid cell with three valid
//! corners is the one triangle of those corners, so the valid samples left uncovered are
//! exactly those no such triangle reaches ([`uncoverable_samples`]). Around the voids the
//! mesh stays watertight: no nodata vertex, every interior edge shared by two triangles
//! running opposite ways, every boundary edge on the grid's border or a void grid cell.
//! On synthetic rasters always; on the shared DEMs with voids, and on float rasters made
//! 50–80 % NaN by masking a shared DEM (sea-level cuts and blobs), when `../shared/dem`
//! is present. The static meshes (threshold planes and tolerances) and view-dependent
//! frames along a camera path (the view crack checker) are both checked.

mod support;

use bitvec::prelude::*;
use glam::DVec3;
use wavemesh::dem::{read_dem, ReadOptions};
use wavemesh::lod::Surface;
use wavemesh::mesh::cells::SplitRule;
use wavemesh::mesh::export::Placement;
use wavemesh::mesh::rasterise::{mesh_error, uncoverable_samples};
use wavemesh::mesh::{GridMesh, MeshTarget, Mesher};
use wavemesh::view::camera::Camera;
use wavemesh::view::checks::count_cracks;
use wavemesh::view::incremental::Incremental;
use wavemesh::view::morph::{morph, MorphScratch};
use wavemesh::view::selection::{Rule, ViewTerrain};
use wavemesh_codec::{
    decode, encode, DecodeOptions, EncodeOptions, Quality, Raster, Samples, SignificanceMap,
};

/// A deterministic pseudo-random sequence (xorshift).
struct Noise(u64);

impl Noise {
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

/// Smooth hills with some roughness, `w × h`.
fn hills(w: usize, h: usize) -> Vec<f64> {
    let mut noise = Noise(0x9e37_79b9_7f4a_7c15);
    (0..w * h)
        .map(|s| {
            let (x, y) = ((s % w) as f64, (s / w) as f64);
            40.0 * (x * 0.11).sin() * (y * 0.07).cos() + 0.3 * x + 3.0 * noise.unit()
        })
        .collect()
}

/// A float raster of `heights` with NaN where `void`.
fn float_raster(w: usize, h: usize, heights: &[f64], void: impl Fn(usize) -> bool) -> Raster {
    let values = (0..w * h)
        .map(|s| if void(s) { f32::NAN } else { heights[s] as f32 })
        .collect();
    let mut raster = Raster::new(w, h, Samples::F32(values)).unwrap();
    raster.nodata = Some(f64::NAN);
    raster
}

/// The height below which `share` of the valid samples lie.
fn quantile(heights: &[f64], valid: &BitSlice<u64, Lsb0>, share: f64) -> f64 {
    let mut sorted: Vec<f64> = valid.iter_ones().map(|s| heights[s]).collect();
    sorted.sort_by(f64::total_cmp);
    sorted[((sorted.len() - 1) as f64 * share) as usize]
}

/// `surface` with every sample at or below its `share` quantile set to NaN (a sea-level
/// cut; flat sea ties at the level go too), after adding up to `jitter / 2` data units
/// of uniform noise either way (a coastline of noisy soundings).
fn sea_cut(surface: &Surface, share: f64, jitter: f64) -> Raster {
    let mut noise = Noise(0x2545_f491_4f6c_dd1d);
    let jittered: Vec<f64> = surface
        .heights
        .iter()
        .map(|&z| z + jitter * (noise.unit() - 0.5))
        .collect();
    let level = quantile(&jittered, &surface.valid, share);
    float_raster(surface.width, surface.height, &surface.heights, |s| {
        !surface.valid[s] || jittered[s] <= level
    })
}

/// `surface` with NaN discs (radii up to `max_radius`) dropped until `share` of the
/// samples are NaN.
fn blobs(surface: &Surface, share: f64, max_radius: f64) -> Raster {
    let (w, h) = (surface.width, surface.height);
    let mut void = !surface.valid.clone();
    let mut noise = Noise(0xdead_beef_cafe_f00d);
    while (void.count_ones() as f64) < share * (w * h) as f64 {
        let (cx, cy) = (noise.unit() * w as f64, noise.unit() * h as f64);
        let r = 1.0 + noise.unit() * max_radius;
        let (x0, x1) = ((cx - r).max(0.0) as usize, ((cx + r) as usize).min(w - 1));
        let (y0, y1) = ((cy - r).max(0.0) as usize, ((cy + r) as usize).min(h - 1));
        for y in y0..=y1 {
            for x in x0..=x1 {
                if (x as f64 - cx).powi(2) + (y as f64 - cy).powi(2) <= r * r {
                    void.set(y * w + x, true);
                }
            }
        }
    }
    float_raster(w, h, &surface.heights, |s| void[s])
}

/// A lossless decode with its significance map.
fn decode_with_map(raster: &Raster) -> (Surface, SignificanceMap) {
    let options = EncodeOptions::new(Quality::Lossless, None).single_stream();
    let file = encode(raster, &options).unwrap();
    let with_map = DecodeOptions::default().with_significance_map(true);
    let decoded = decode(&file.bytes, &with_map).unwrap();
    (Surface::of(&decoded.raster), decoded.significance.unwrap())
}

/// The four corner samples of every grid cell of a `w × h` raster, row by row.
fn cell_corners(w: usize, h: usize) -> impl Iterator<Item = [usize; 4]> {
    (0..h - 1).flat_map(move |y| {
        (0..w - 1).map(move |x| {
            [
                y * w + x,
                y * w + x + 1,
                (y + 1) * w + x,
                (y + 1) * w + x + 1,
            ]
        })
    })
}

/// Valid samples that no grid cell with four valid corners has as a corner: what the
/// mesh left uncovered before three-corner cells were meshed.
fn uncovered_by_full_cells(w: usize, h: usize, valid: &BitSlice<u64, Lsb0>) -> u64 {
    let mut reached = bitvec![u64, Lsb0; 0; w * h];
    for corners in cell_corners(w, h) {
        if corners.iter().all(|&s| valid[s]) {
            corners.iter().for_each(|&s| reached.set(s, true));
        }
    }
    valid.iter_ones().filter(|&s| !reached[s]).count() as u64
}

/// Grid cells with four and with three valid corners.
fn meshable_cells(w: usize, h: usize, valid: &BitSlice<u64, Lsb0>) -> (u64, u64) {
    let (mut full, mut three) = (0, 0);
    for corners in cell_corners(w, h) {
        match corners.iter().filter(|&&s| valid[s]).count() {
            4 => full += 1,
            3 => three += 1,
            _ => {}
        }
    }
    (full, three)
}

/// Whether the edge between samples `a` and `b` may bound the mesh: along the grid's
/// border, or a unit side or diagonal of a grid cell with a nodata corner.
fn may_bound(w: usize, h: usize, valid: &BitSlice<u64, Lsb0>, a: usize, b: usize) -> bool {
    let ((xa, ya), (xb, yb)) = ((a % w, a / w), (b % w, b / w));
    if (xa == xb && (xa == 0 || xa == w - 1)) || (ya == yb && (ya == 0 || ya == h - 1)) {
        return true;
    }
    let (x, y) = (xa.min(xb), ya.min(yb));
    let cells: Vec<(usize, usize)> = match (xa.abs_diff(xb), ya.abs_diff(yb)) {
        (1, 0) => vec![(x, y - 1), (x, y)],
        (0, 1) => vec![(x - 1, y), (x, y)],
        (1, 1) => vec![(x, y)],
        _ => return false,
    };
    let void_cell = |(cx, cy): (usize, usize)| {
        let corners = [
            cy * w + cx,
            cy * w + cx + 1,
            (cy + 1) * w + cx,
            (cy + 1) * w + cx + 1,
        ];
        corners.iter().any(|&s| !valid[s])
    };
    cells.into_iter().any(void_cell)
}

/// Checks `mesh` against the validity of its grid: no nodata vertex, every triangle
/// counter-clockwise, its area that of the meshable grid cells (no overlap, no gap),
/// every edge shared by at most two triangles running opposite ways, and every edge of
/// one triangle on the border or a void grid cell.
fn check_watertight(label: &str, mesh: &GridMesh, valid: &BitSlice<u64, Lsb0>) {
    let (w, h) = (mesh.width, mesh.height);
    assert!(
        mesh.vertices.iter().all(|&s| valid[s as usize]),
        "{label}: a triangle uses a nodata vertex"
    );
    let mut doubled_area = 0i64;
    let mut edges: Vec<(u32, u32)> = Vec::with_capacity(3 * mesh.triangles.len());
    for t in &mesh.triangles {
        let s = t.map(|v| mesh.vertices[v as usize]);
        let p = s.map(|s| ((s as usize % w) as i64, (s as usize / w) as i64));
        let area = (p[1].0 - p[0].0) * (p[2].1 - p[0].1) - (p[1].1 - p[0].1) * (p[2].0 - p[0].0);
        assert!(area > 0, "{label}: triangle {s:?} is not counter-clockwise");
        doubled_area += area;
        edges.extend([(s[0], s[1]), (s[1], s[2]), (s[2], s[0])]);
    }
    let (full, three) = meshable_cells(w, h, valid);
    assert_eq!(
        doubled_area as u64,
        2 * full + three,
        "{label}: the triangles do not tile the meshable cells"
    );
    edges.sort_unstable_by_key(|&(a, b)| (a.min(b), a.max(b)));
    for run in edges.chunk_by(|p, q| (p.0.min(p.1), p.0.max(p.1)) == (q.0.min(q.1), q.0.max(q.1))) {
        let (a, b) = run[0];
        match run {
            [_] => assert!(
                may_bound(w, h, valid, a as usize, b as usize),
                "{label}: edge {a}–{b} bounds the mesh inside the valid area"
            ),
            [p, q] => assert!(
                p.0 == q.1 && p.1 == q.0,
                "{label}: edge {a}–{b} runs the same way in both its triangles"
            ),
            _ => panic!("{label}: edge {a}–{b} is shared by {} triangles", run.len()),
        }
    }
}

/// One masked raster's coverage figures, in valid samples.
struct Coverage {
    valid: u64,
    before: u64,
    after: u64,
    bound: u64,
}

/// Meshes a raster at `targets` and checks every mesh: watertight, and its uncovered
/// valid samples exactly the bound. Returns the figures of the last mesh.
fn check_meshes(label: &str, raster: &Raster, targets: &[MeshTarget]) -> Coverage {
    let (surface, map) = decode_with_map(raster);
    let (w, h) = (surface.width, surface.height);
    let bound = uncoverable_samples(w, h, &surface.valid);
    let mut mesher = Mesher::new(&map, surface.heights(), &surface.valid);
    let mut after = 0;
    for &target in targets {
        let result = mesher.build(target, SplitRule::Zerotree, None);
        let label = format!("{label} {target:?}");
        check_watertight(&label, &result.mesh, &surface.valid);
        let error = mesh_error(
            &result.mesh,
            &surface.heights,
            &surface.heights,
            &surface.valid,
        );
        assert_eq!(error.uncovered_samples, bound, "{label}: uncovered samples");
        after = error.uncovered_samples;
    }
    Coverage {
        valid: surface.valid.count_ones() as u64,
        before: uncovered_by_full_cells(w, h, &surface.valid),
        after,
        bound,
    }
}

/// The head of the coverage table [`report`] prints rows of.
fn report_head() {
    eprintln!("| raster | valid samples | NaN % | uncovered before | uncovered after | bound |");
    eprintln!("|---|---:|---:|---:|---:|---:|");
}

/// A row of the coverage table, on stderr (`-- --nocapture` shows it).
fn report(name: &str, samples: usize, c: &Coverage) {
    let percent = |n: u64| 100.0 * n as f64 / c.valid.max(1) as f64;
    eprintln!(
        "| {name} | {} | {:.1} | {:.2} % | {:.2} % | {:.2} % |",
        c.valid,
        100.0 - 100.0 * c.valid as f64 / samples as f64,
        percent(c.before),
        percent(c.after),
        percent(c.bound)
    );
}

#[test]
fn three_corner_cells_cover_every_reachable_sample_of_synthetic_voids() {
    let (w, h) = (97, 89);
    let heights = hills(w, h);
    let all = Surface::of(&float_raster(w, h, &heights, |_| false));
    let targets = [
        MeshTarget::Plane(0),
        MeshTarget::Plane(6),
        MeshTarget::Plane(12),
        MeshTarget::Tolerance(2.0),
        MeshTarget::Tolerance(8.0),
    ];
    let mut noise = Noise(7);
    let speckle: Vec<bool> = (0..w * h).map(|_| noise.unit() < 0.15).collect();
    let cases = [
        ("sea cut q60", sea_cut(&all, 0.6, 0.0)),
        ("ragged sea q76 ±15", sea_cut(&all, 0.76, 30.0)),
        ("blobs 55 %", blobs(&all, 0.55, 9.0)),
        ("speckle 15 %", float_raster(w, h, &heights, |s| speckle[s])),
        (
            "checkerboard",
            float_raster(w, h, &heights, |s| (s % w + s / w) % 2 == 0),
        ),
    ];
    report_head();
    for (name, raster) in &cases {
        let c = check_meshes(name, raster, &targets);
        report(name, raster.len(), &c);
        assert!(c.bound <= c.before, "{name}: the bound above the old rule");
    }
    // Where a sea cut leaves ragged coasts, the old rule left more uncovered than the
    // bound: the test would not see a regression to it otherwise.
    let c = check_meshes("ragged sea q76", &cases[1].1, &targets[..1]);
    assert!(c.before > c.bound + 100, "{} vs {}", c.before, c.bound);
}

/// The shared DEM `name` of `dir`.
fn shared_raster(dir: &std::path::Path, name: &str) -> Raster {
    let path = dir.join(name).join(format!("{name}.tif"));
    read_dem(&path, &ReadOptions::default()).unwrap()
}

/// The shared DEMs with voids and float rasters made 50–80 % NaN from them: every mesh
/// watertight and covering every reachable valid sample. Prints the coverage table.
#[test]
fn shared_dems_cover_every_reachable_sample_needs_shared_dems() {
    let Some(dir) = support::shared_dem("void_coverage::shared_dems_cover_every_reachable_sample")
    else {
        return;
    };
    let read = |name: &str| shared_raster(&dir, name);
    let utm = read("srtm3_utm32_f32");
    let fuji = Surface::of(&read("fuji_terrainrgb"));
    let utm_surface = Surface::of(&utm);
    let cases = [
        ("alps_srtm_voids", read("alps_srtm_voids")),
        ("srtm3_utm32_f32", utm),
        (
            "srtm3_utm32_f32 sea cut q60",
            sea_cut(&utm_surface, 0.6, 0.0),
        ),
        (
            "srtm3_utm32_f32 ragged sea q60 ±1 m",
            sea_cut(&utm_surface, 0.6, 2.0),
        ),
        ("srtm3_utm32_f32 blobs 70 %", blobs(&utm_surface, 0.7, 40.0)),
        ("fuji_terrainrgb sea cut q70", sea_cut(&fuji, 0.7, 0.0)),
        (
            "fuji_terrainrgb ragged sea q76 ±75 m",
            sea_cut(&fuji, 0.76, 150.0),
        ),
        ("fuji_terrainrgb blobs 60 %", blobs(&fuji, 0.6, 25.0)),
    ];
    report_head();
    for (name, raster) in &cases {
        let c = check_meshes(name, raster, &[MeshTarget::Plane(0), MeshTarget::Plane(9)]);
        report(name, raster.len(), &c);
    }
}

/// A camera path over `raster` (crossing it at a third of its larger side, looking
/// ahead and down): every frame's morphed mesh has no crack (the view crack checker),
/// the incremental selection equals the rebuild, and the mesh is watertight and covers
/// every reachable valid sample.
fn check_flight(label: &str, raster: &Raster, frames: usize) {
    let (surface, map) = decode_with_map(raster);
    let (w, h) = (surface.width as f64, surface.height as f64);
    let lo = quantile(&surface.heights, &surface.valid, 0.0);
    let hi = quantile(&surface.heights, &surface.valid, 1.0);
    let z_scale = 0.1 * w.max(h) / (hi - lo).max(1e-9);
    let terrain = ViewTerrain::new(
        &map,
        surface.heights(),
        &surface.valid,
        Placement::pixel(z_scale),
        0,
    )
    .unwrap();
    let bound = uncoverable_samples(surface.width, surface.height, &surface.valid);
    let rule = Rule::ScreenSpace { tau: 1.0 };
    let view = |t: f64| {
        let eye = DVec3::new(w * (0.1 + t), -0.1 * h, 0.35 * w.max(h));
        let look = DVec3::new(w * (0.3 + t), 0.6 * h, 0.0);
        Camera::new(eye, look, 60.0, (640, 360)).unwrap().view()
    };
    let mut incremental = Incremental::new(&terrain, &view(0.0), rule);
    let mut scratch = MorphScratch::default();
    for f in 0..frames {
        let camera = view(0.04 * f as f64);
        incremental.update(&terrain, &camera);
        let tree = incremental.tree();
        assert!(
            tree.leaves() == terrain.select(&camera, rule).leaves(),
            "{label} frame {f}: incremental differs from the rebuild"
        );
        let mesh = terrain.triangulate(tree);
        let morphed = morph(&terrain, &camera, rule, tree, &mesh, &mut scratch);
        let cracks = count_cracks(&terrain, &mesh, |_, v| morphed[v as usize]);
        assert_eq!(cracks, 0, "{label} frame {f}: cracks");
        check_watertight(&format!("{label} frame {f}"), &mesh, &surface.valid);
        let error = mesh_error(&mesh, &surface.heights, &surface.heights, &surface.valid);
        assert_eq!(
            error.uncovered_samples, bound,
            "{label} frame {f}: uncovered"
        );
    }
}

#[test]
fn view_frames_over_synthetic_voids_are_crack_free_and_cover_every_reachable_sample() {
    let (w, h) = (129, 113);
    let all = Surface::of(&float_raster(w, h, &hills(w, h), |_| false));
    check_flight("ragged sea q70 ±15", &sea_cut(&all, 0.7, 30.0), 8);
    check_flight("blobs 55 %", &blobs(&all, 0.55, 12.0), 8);
}

#[test]
fn view_frames_over_masked_shared_dems_are_crack_free_needs_shared_dems() {
    let Some(dir) = support::shared_dem("void_coverage::view_frames_over_masked_shared_dems")
    else {
        return;
    };
    let read = |name: &str| Surface::of(&shared_raster(&dir, name));
    let fuji = read("fuji_terrainrgb");
    check_flight(
        "fuji_terrainrgb ragged sea q76 ±75 m",
        &sea_cut(&fuji, 0.76, 150.0),
        6,
    );
    let alps = read_dem(
        &dir.join("alps_srtm_voids/alps_srtm_voids.tif"),
        &ReadOptions::default(),
    )
    .unwrap();
    check_flight("alps_srtm_voids", &alps, 6);
}

/// The JSON report of `mesh INPUT -o OUT --method zerotree`.
fn zerotree_mesh_report(input: &std::path::Path, out: &std::path::Path) -> serde_json::Value {
    support::json(&[
        "mesh",
        input.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
        "--method",
        "zerotree",
        "--json",
    ])
}

/// `mesh --json` reports the bound beside the uncovered samples, and meets it.
#[test]
fn cli_mesh_report_gives_the_uncoverable_samples() {
    let dir = support::scratch("void_coverage");
    let out = dir.path().join("voids.obj");
    let input = support::sample("jacksboro_voids.tif");
    let report = zerotree_mesh_report(&input, &out);
    let mesh = &report["mesh"];
    let bound = mesh["uncoverable_samples"].as_u64().unwrap();
    assert!(
        bound > 0,
        "the sample's voids leave samples no triangle reaches"
    );
    assert_eq!(mesh["error_vs_decoded"]["uncovered_samples"], bound);
}

/// A 2 × 2 raster with one nodata sample is meshed as one triangle, not refused.
#[test]
fn cli_meshes_a_lone_three_corner_cell() {
    let dir = support::scratch("void_coverage");
    let input = dir.path().join("corner.asc");
    std::fs::write(
        &input,
        "ncols 2\nnrows 2\nxllcorner 0\nyllcorner 0\ncellsize 1\nNODATA_value -9999\n1 2\n3 -9999\n",
    )
    .unwrap();
    let out = dir.path().join("corner.obj");
    let report = zerotree_mesh_report(&input, &out);
    assert_eq!(report["mesh"]["triangles"], 1);
    assert_eq!(report["mesh"]["error_vs_decoded"]["uncovered_samples"], 0);
}
