//! View-dependent terrain: crack-free meshes every frame, incremental split/merge equal to
//! the from-scratch selection, geomorphing that keeps vertex jumps small, and the rules'
//! basic behaviour; on synthetic terrains with and without voids and on the shared DEMs.

mod support;

use bitvec::prelude::*;
use glam::DVec3;
use proptest::prelude::*;
use wavemesh::mesh::export::Placement;
use wavemesh::mesh::pyramid::Heights;
use wavemesh::view::camera::{Camera, View};
use wavemesh::view::checks::{count_cracks, max_jump, Surface};
use wavemesh::view::incremental::Incremental;
use wavemesh::view::morph::{morph, MorphScratch};
use wavemesh::view::selection::{Rule, ViewTerrain};
use wavemesh_codec::significance::nodes_along;
use wavemesh_codec::{decode, encode, DecodeOptions, EncodeOptions, Quality, Raster, Samples};

/// A rough terrain of `w × h` heights from a seed, with optional voids.
fn terrain(w: usize, h: usize, seed: u64, voids: bool) -> Raster {
    let mut s = seed | 1;
    let mut next = move || {
        s ^= s << 13;
        s ^= s >> 7;
        s ^= s << 17;
        s
    };
    let (fx, fy) = (
        0.05 + (next() % 100) as f64 / 400.0,
        0.04 + (next() % 100) as f64 / 500.0,
    );
    let mut values: Vec<i16> = (0..w * h)
        .map(|i| {
            let (x, y) = ((i % w) as f64, (i / w) as f64);
            let base = 30.0 * (x * fx).sin() * (y * fy).cos() + 0.2 * x;
            (base + (next() % 3) as f64) as i16
        })
        .collect();
    if voids {
        for _ in 0..(w * h / 60).max(1) {
            let i = (next() as usize) % (w * h);
            values[i] = -32768;
        }
    }
    let mut raster = Raster::new(w, h, Samples::I16(values)).unwrap();
    if voids {
        raster.nodata = Some(-32768.0);
    }
    raster
}

/// A decode with its significance map, as the view reads it.
struct Decoded {
    heights: Vec<f64>,
    valid: BitVec<u64, Lsb0>,
    map: wavemesh_codec::SignificanceMap,
    width: usize,
    height: usize,
}

fn decode_with_map(raster: &Raster) -> Decoded {
    let file = encode(raster, &EncodeOptions::new(Quality::Lossless, None)).unwrap();
    let options = DecodeOptions::default().with_significance_map(true);
    let decoded = decode(&file.bytes, &options).unwrap();
    let r = &decoded.raster;
    Decoded {
        heights: r.samples.to_f64(),
        valid: r.valid_mask().into_iter().collect(),
        map: decoded.significance.unwrap(),
        width: r.width,
        height: r.height,
    }
}

impl Decoded {
    fn terrain(&self) -> ViewTerrain<'_> {
        let heights = Heights {
            width: self.width,
            height: self.height,
            values: &self.heights,
        };
        ViewTerrain::new(&self.map, heights, &self.valid, Placement::pixel(1.0), 0).unwrap()
    }
}

/// A camera at `t ∈ [0, 1]` of a straight flight over a `w × h` terrain from one corner
/// region towards the other, looking ahead and down.
fn flight(w: usize, h: usize, t: f64, height: f64, turn: f64) -> View {
    let (w, h) = (w as f64, h as f64);
    let eye = DVec3::new(-0.2 * w + 1.2 * w * t, 0.3 * h + 0.2 * h * t, height);
    let heading = 0.4 + turn * t;
    let look = eye + DVec3::new(heading.cos() * w * 0.5, heading.sin() * h * 0.5, -height);
    Camera::new(eye, look, 60.0, (320, 180)).unwrap().view()
}

/// One frame's mesh and morphed heights, with its crack count.
fn frame_cracks(
    terrain: &ViewTerrain<'_>,
    view: &View,
    rule: Rule,
    incremental: &Incremental,
    scratch: &mut MorphScratch,
) -> usize {
    let tree = incremental.tree();
    let mesh = terrain.triangulate(tree);
    let morphed = morph(terrain, view, rule, tree, &mesh, scratch);
    count_cracks(terrain, &mesh, |_, v| morphed[v as usize])
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    /// Every frame of a random flight: no crack in the morphed mesh, and the incremental
    /// selection equal to the from-scratch one.
    #[test]
    fn random_flights_are_crack_free_and_incremental_equals_rebuild(
        w in 9usize..70, h in 9usize..70, seed in any::<u64>(), voids in any::<bool>(),
        height in 5.0f64..80.0, turn in -2.0f64..2.0, tau in 0.3f64..4.0, frames in 3usize..16, step in 0.001f64..0.1,
    ) {
        let decoded = decode_with_map(&terrain(w, h, seed, voids));
        let terrain = decoded.terrain();
        let rule = Rule::ScreenSpace { tau };
        let mut scratch = MorphScratch::default();
        let first = flight(w, h, 0.0, height, turn);
        let mut incremental = Incremental::new(&terrain, &first, rule);
        for f in 0..frames {
            let view = flight(w, h, f as f64 * step, height, turn);
            if f > 0 {
                incremental.update(&terrain, &view);
            }
            let rebuilt = terrain.select(&view, rule);
            prop_assert!(incremental.tree().leaves() == rebuilt.leaves(), "frame {}: incremental differs from the rebuild", f);
            prop_assert_eq!(frame_cracks(&terrain, &view, rule, &incremental, &mut scratch), 0, "frame {}", f);
        }
    }

    /// Morphing frame after frame with one [`MorphScratch`] (heights and settled blends
    /// kept from frame to frame) gives, bit for bit, the morph from scratch of every frame.
    #[test]
    fn morphs_kept_from_frame_to_frame_equal_the_morph_from_scratch(
        w in 9usize..70, h in 9usize..70, seed in any::<u64>(), voids in any::<bool>(),
        height in 5.0f64..80.0, turn in -2.0f64..2.0, tau in 0.3f64..4.0, frames in 3usize..16, step in 0.0002f64..0.05,
    ) {
        let decoded = decode_with_map(&terrain(w, h, seed, voids));
        let terrain = decoded.terrain();
        let rule = Rule::ScreenSpace { tau };
        let mut kept = MorphScratch::default();
        for f in 0..frames {
            let view = flight(w, h, f as f64 * step, height, turn);
            let tree = terrain.select(&view, rule);
            let mesh = terrain.triangulate(&tree);
            let morphed = morph(&terrain, &view, rule, &tree, &mesh, &mut kept);
            let fresh = morph(&terrain, &view, rule, &tree, &mesh, &mut MorphScratch::default());
            let bits = |z: &[f64]| z.iter().map(|z| z.to_bits()).collect::<Vec<_>>();
            prop_assert!(bits(&morphed) == bits(&fresh), "frame {}: kept morph differs", f);
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(24))]

    /// The morph's lean ratio is [`ViewTerrain::evaluate`]'s, bit for bit, for every node
    /// of every level, in view, partly out of it and out of it.
    #[test]
    fn the_lean_ratio_equals_the_evaluation(
        w in 9usize..70, h in 9usize..70, seed in any::<u64>(), voids in any::<bool>(),
        height in 5.0f64..80.0, turn in -2.0f64..2.0, tau in 0.3f64..4.0, t in -0.5f64..1.5,
    ) {
        let decoded = decode_with_map(&terrain(w, h, seed, voids));
        let terrain = decoded.terrain();
        let view = flight(w, h, t, height, turn);
        let rule = Rule::ScreenSpace { tau };
        for m in 1..=terrain.levels() {
            for j in 0..nodes_along(h, m) {
                for i in 0..nodes_along(w, m) {
                    let lean = terrain.ratio(&view, rule, m, i, j);
                    let full = terrain.evaluate(&view, rule, m, i, j).ratio;
                    prop_assert_eq!(lean.to_bits(), full.to_bits(), "node {} {} {}", m, i, j);
                }
            }
        }
    }
}

/// A camera at `eye` looking along heading `heading` and pitch `pitch` (radians).
fn aimed(eye: DVec3, heading: f64, pitch: f64) -> View {
    let look = eye
        + DVec3::new(
            heading.cos() * pitch.cos(),
            heading.sin() * pitch.cos(),
            pitch.sin(),
        );
    Camera::new(eye, look, 60.0, (320, 180)).unwrap().view()
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(32))]

    /// Random camera paths that move, turn and pitch by random steps each frame, now and
    /// then looking straight down: the incremental selection equals the rebuild every frame.
    #[test]
    fn random_camera_paths_equal_the_rebuild(
        side in 20usize..90, seed in any::<u64>(), voids in any::<bool>(), tau in 0.3f64..3.0,
        steps in proptest::collection::vec((-1.0f64..1.0, -1.0f64..1.0, -1.0f64..1.0, -0.05f64..0.05, -0.05f64..0.05, 0u8..12), 2..14),
    ) {
        let decoded = decode_with_map(&terrain(side, side, seed, voids));
        let terrain = decoded.terrain();
        let rule = Rule::ScreenSpace { tau };
        let mut eye = DVec3::new(side as f64 * 0.2, side as f64 * 0.3, 30.0);
        let (mut heading, mut pitch) = (0.6f64, -0.6f64);
        let mut incremental = Incremental::new(&terrain, &aimed(eye, heading, pitch), rule);
        for (f, &(dx, dy, dz, turn, tilt, down)) in steps.iter().enumerate() {
            eye += DVec3::new(dx, dy, dz * 0.5);
            heading += turn;
            pitch = (pitch + tilt).clamp(-1.5, 0.3);
            let view = if down == 0 { aimed(eye, heading, -std::f64::consts::FRAC_PI_2) } else { aimed(eye, heading, pitch) };
            incremental.update(&terrain, &view);
            let rebuilt = terrain.select(&view, rule);
            prop_assert!(incremental.tree().leaves() == rebuilt.leaves(), "frame {}: incremental differs from the rebuild", f);
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(12))]

    /// Slow flights over larger grids, where most leaves outlive a frame: the updates that
    /// copy unexpired runs and blocks of leaves and re-evaluate only a leaf's expired
    /// bound (its own or its parent's) still equal the rebuild every frame, and do skip
    /// leaves.
    #[test]
    fn slow_flights_skip_leaves_and_equal_the_rebuild(
        side in 120usize..220, seed in any::<u64>(), voids in any::<bool>(),
        turn in -0.5f64..0.5, frames in 10usize..30, step in 0.0005f64..0.004,
    ) {
        let decoded = decode_with_map(&terrain(side, side, seed, voids));
        let terrain = decoded.terrain();
        let rule = Rule::ScreenSpace { tau: 0.5 };
        let mut incremental = Incremental::new(&terrain, &flight(side, side, 0.3, 40.0, turn), rule);
        let mut skipped = 0;
        for f in 1..frames {
            let view = flight(side, side, 0.3 + f as f64 * step, 40.0, turn);
            let before = incremental.tree().leaves().len();
            let stats = incremental.update(&terrain, &view);
            skipped += before - stats.revisited;
            let rebuilt = terrain.select(&view, rule);
            prop_assert!(incremental.tree().leaves() == rebuilt.leaves(), "frame {}: incremental differs from the rebuild", f);
        }
        prop_assert!(skipped > 0, "no update skipped a leaf");
    }
}

/// Morphed heights move little between close frames where the unmorphed ones pop.
#[test]
fn geomorphing_bounds_vertex_jumps() {
    let decoded = decode_with_map(&terrain(129, 129, 7, false));
    let terrain = decoded.terrain();
    let rule = Rule::ScreenSpace { tau: 4.0 };
    let mut scratch = MorphScratch::default();
    let frames = 40;
    let mut incremental = Incremental::new(&terrain, &flight(129, 129, 0.0, 40.0, 0.5), rule);
    let mut previous: Option<(
        wavemesh::mesh::cells::CellTree,
        wavemesh::mesh::GridMesh,
        Vec<f64>,
        Vec<f64>,
    )> = None;
    let (mut morphed_worst, mut unmorphed_worst) = (0.0f64, 0.0f64);
    let mut last_view = flight(129, 129, 0.0, 40.0, 0.5);
    for f in 0..frames {
        let view = flight(129, 129, 0.25 * f as f64 / frames as f64, 40.0, 0.5);
        incremental.update(&terrain, &view);
        let tree = incremental.tree().clone();
        let mesh = terrain.triangulate(&tree);
        let morphed = morph(&terrain, &view, rule, &tree, &mesh, &mut scratch);
        let truth: Vec<f64> = mesh
            .vertices
            .iter()
            .map(|&s| decoded.heights[s as usize])
            .collect();
        if let Some((t0, m0, z0, u0)) = &previous {
            let surface = |tree, mesh, heights| Surface {
                tree,
                mesh,
                heights,
            };
            let jump = max_jump(
                &terrain,
                surface(t0, m0, z0),
                surface(&tree, &mesh, &morphed),
                [&last_view, &view],
            );
            let pop = max_jump(
                &terrain,
                surface(t0, m0, u0),
                surface(&tree, &mesh, &truth),
                [&last_view, &view],
            );
            morphed_worst = morphed_worst.max(jump);
            unmorphed_worst = unmorphed_worst.max(pop);
        }
        previous = Some((tree, mesh, morphed, truth));
        last_view = view;
    }
    eprintln!("max jump: morphed {morphed_worst:.3}, unmorphed {unmorphed_worst:.3}");
    assert!(
        unmorphed_worst >= 1.0,
        "the flight should pop without morphing"
    );
    assert!(
        morphed_worst < 0.1 * unmorphed_worst,
        "morphed {morphed_worst} vs {unmorphed_worst}"
    );
}

/// A camera looking away from the terrain sees nothing: every region stays at the
/// coarsest level (only nodata splits).
#[test]
fn regions_out_of_view_stay_coarsest() {
    for voids in [false, true] {
        let decoded = decode_with_map(&terrain(65, 49, 3, voids));
        let terrain = decoded.terrain();
        let away = Camera::new(
            DVec3::new(-50.0, 20.0, 30.0),
            DVec3::new(-200.0, 20.0, 30.0),
            60.0,
            (320, 180),
        )
        .unwrap()
        .view();
        let coarsest = Rule::ScreenSpace { tau: f64::MAX };
        for rule in [
            Rule::ScreenSpace { tau: 0.01 },
            Rule::Area { a: 0.0, b: 0.0 },
        ] {
            let tree = terrain.select(&away, rule);
            assert!(
                tree.leaves() == terrain.select(&away, coarsest).leaves(),
                "{rule:?} voids {voids}"
            );
        }
        // Looking at it instead, a fine tolerance refines.
        let towards = flight(65, 49, 0.3, 20.0, 0.0);
        let fine = terrain.select(&towards, Rule::ScreenSpace { tau: 0.01 });
        assert!(fine.leaves().len() > terrain.select(&towards, coarsest).leaves().len());
    }
}

/// Finer tolerances (smaller τ, smaller a) never give fewer triangles, and every such
/// mesh is crack-free and covers exactly the cells with four valid corners and half of
/// each cell with three (its one triangle).
#[test]
fn tolerances_order_the_meshes() {
    let decoded = decode_with_map(&terrain(97, 81, 11, true));
    let terrain = decoded.terrain();
    let view = flight(97, 81, 0.35, 25.0, 0.3);
    let mut scratch = MorphScratch::default();
    let valid = &decoded.valid;
    let doubled_area: i64 = (0..80 * 96)
        .map(|c| {
            let s = c / 96 * 97 + c % 96;
            match [s, s + 1, s + 97, s + 98]
                .iter()
                .filter(|&&s| valid[s])
                .count()
            {
                4 => 2,
                3 => 1,
                _ => 0,
            }
        })
        .sum();
    for rules in [
        [0.25, 1.0, 4.0, 16.0].map(|tau| Rule::ScreenSpace { tau }),
        [1e-4, 1e-3, 1e-2, 1e-1].map(|a| Rule::Area { a, b: 0.0 }),
    ] {
        let mut previous = usize::MAX;
        for rule in rules {
            let tree = terrain.select(&view, rule);
            let mesh = terrain.triangulate(&tree);
            let morphed = morph(&terrain, &view, rule, &tree, &mesh, &mut scratch);
            assert_eq!(
                count_cracks(&terrain, &mesh, |_, v| morphed[v as usize]),
                0,
                "{rule:?}"
            );
            let area2: i64 = mesh
                .triangles
                .iter()
                .map(|t| {
                    let p = t.map(|v| {
                        let (x, y) = mesh.vertex_position(v);
                        (x as i64, y as i64)
                    });
                    (p[1].0 - p[0].0) * (p[2].1 - p[0].1) - (p[1].1 - p[0].1) * (p[2].0 - p[0].0)
                })
                .sum();
            assert_eq!(
                area2, doubled_area,
                "{rule:?}: the mesh must cover every valid cell once"
            );
            assert!(
                mesh.triangles.len() <= previous,
                "{rule:?}: {} > {previous}",
                mesh.triangles.len()
            );
            previous = mesh.triangles.len();
        }
    }
}

/// A crack count that can fail: a mesh with a triangle removed, or with one corner's
/// height differing between two triangles, has cracks.
#[test]
fn the_crack_count_sees_holes_and_mismatched_heights() {
    let decoded = decode_with_map(&terrain(33, 33, 5, false));
    let terrain = decoded.terrain();
    let view = flight(33, 33, 0.4, 15.0, 0.0);
    let rule = Rule::ScreenSpace { tau: 1.0 };
    let tree = terrain.select(&view, rule);
    let mut mesh = terrain.triangulate(&tree);
    let heights: Vec<f64> = mesh
        .vertices
        .iter()
        .map(|&s| decoded.heights[s as usize])
        .collect();
    assert_eq!(count_cracks(&terrain, &mesh, |_, v| heights[v as usize]), 0);
    // Triangle 0's corners seen differently by triangle 0 than by its neighbours.
    let shifted = count_cracks(&terrain, &mesh, |t, v| {
        heights[v as usize] + if t == 0 { 1.0 } else { 0.0 }
    });
    assert!(shifted > 0);
    let interior = mesh
        .triangles
        .iter()
        .position(|t| {
            t.iter().all(|&v| {
                let (x, y) = mesh.vertex_position(v);
                x > 0 && y > 0 && x < 32 && y < 32
            })
        })
        .expect("an interior triangle");
    mesh.triangles.remove(interior);
    assert!(count_cracks(&terrain, &mesh, |_, v| heights[v as usize]) > 0);
}

/// The shared DEM with SRTM-style voids: a flight with no crack, the incremental
/// selection equal to the rebuild every frame, and morphing bounding the jumps.
#[test]
fn shared_dem_alps_srtm_voids_flight_needs_shared_dems() {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../shared/dem/alps_srtm_voids/alps_srtm_voids.tif");
    if !path.exists() {
        support::skipped(
            "view::shared_dem_alps_srtm_voids_flight",
            &format!("{} is absent", path.display()),
        );
        return;
    }
    let raster = wavemesh::dem::read_dem(&path, &wavemesh::dem::ReadOptions::default()).unwrap();
    let decoded = decode_with_map(&raster);
    let terrain = decoded.terrain();
    let (w, h) = (decoded.width, decoded.height);
    let rule = Rule::ScreenSpace { tau: 1.0 };
    let mut scratch = MorphScratch::default();
    let path_view = |t: f64| {
        let eye = DVec3::new(w as f64 * (0.1 + 0.6 * t), h as f64 * 0.5, 5500.0);
        Camera::new(
            eye,
            eye + DVec3::new(300.0, 100.0, -2500.0),
            60.0,
            (800, 450),
        )
        .unwrap()
        .view()
    };
    let mut incremental = Incremental::new(&terrain, &path_view(0.0), rule);
    for f in 0..8 {
        let view = path_view(f as f64 * 0.01);
        incremental.update(&terrain, &view);
        assert!(
            incremental.tree().leaves() == terrain.select(&view, rule).leaves(),
            "frame {f}"
        );
        assert_eq!(
            frame_cracks(&terrain, &view, rule, &incremental, &mut scratch),
            0,
            "frame {f}"
        );
    }
}

// --- The command line -----------------------------------------------------------------

fn wavemesh(args: &[&str]) -> std::process::Output {
    std::process::Command::new(env!("CARGO_BIN_EXE_wavemesh"))
        .args(args)
        .output()
        .expect("the binary runs")
}

/// The bundled sample with voids, encoded into `dir`.
fn sample_stream(dir: &std::path::Path) -> String {
    let sample =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("samples/jacksboro_voids.tif");
    let stream = dir.join("voids.ezw");
    let out = wavemesh(&[
        "encode",
        sample.to_str().unwrap(),
        "-o",
        stream.to_str().unwrap(),
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    stream.to_str().unwrap().to_string()
}

fn json(args: &[&str]) -> serde_json::Value {
    let out = wavemesh(args);
    assert!(
        out.status.success(),
        "wavemesh {args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).expect("one JSON object")
}

#[test]
fn cli_view_writes_a_crack_free_mesh_and_compares_the_rules() {
    let dir = tempfile::tempdir().unwrap();
    let stream = sample_stream(dir.path());
    let mesh = dir.path().join("view.obj");
    let png = dir.path().join("view.png");
    let report = json(&[
        "view",
        &stream,
        "--camera",
        "-40,170,1400",
        "--look",
        "200,170,600",
        "--viewport",
        "640x360",
        "--xy",
        "pixel",
        "-o",
        mesh.to_str().unwrap(),
        "--render",
        png.to_str().unwrap(),
        "--compare-rules",
        "--json",
    ]);
    assert_eq!(report["xy_units"], "pixel");
    assert_eq!(report["cracks"], 0);
    let triangles = report["triangles"].as_u64().unwrap();
    assert!(triangles > 100, "{report}");
    assert!(report["screen_error"]["samples"].as_u64().unwrap() > 1000);
    let other = report["other_rule"]["triangles"].as_u64().unwrap();
    assert!(
        other.abs_diff(triangles) * 10 < triangles,
        "{other} vs {triangles}"
    );
    let obj = std::fs::read_to_string(&mesh).unwrap();
    assert_eq!(
        obj.lines().filter(|l| l.starts_with("f ")).count() as u64,
        triangles
    );
    assert!(image::open(&png).unwrap().width() > 100);
}

#[test]
fn cli_flythrough_reports_every_frame() {
    let dir = tempfile::tempdir().unwrap();
    let stream = sample_stream(dir.path());
    let frames = dir.path().join("frames");
    let meshes = dir.path().join("meshes");
    let path = dir.path().join("path.csv");
    std::fs::write(
        &path,
        "x,y,z,lx,ly,lz\n0,170,1300,200,170,600\n60,180,1250,260,180,600\n",
    )
    .unwrap();
    let report = json(&[
        "flythrough",
        &stream,
        "--path",
        path.to_str().unwrap(),
        "--frames",
        "5",
        "--viewport",
        "640x360",
        "--xy",
        "pixel",
        "--render",
        frames.to_str().unwrap(),
        "--export-frames",
        meshes.to_str().unwrap(),
        "--json",
    ]);
    let list = report["frames"].as_array().unwrap();
    assert_eq!(list.len(), 5);
    for frame in list {
        for field in [
            "triangles",
            "split",
            "merged",
            "incremental_ms",
            "rebuild_ms",
            "cracks",
            "max_jump",
            "max_jump_unmorphed",
        ] {
            assert!(frame.get(field).is_some(), "{field} missing: {frame}");
        }
        assert_eq!(frame["cracks"], 0);
        assert_eq!(frame["matches_rebuild"], true);
        assert!(
            frame["max_jump"].as_f64().unwrap()
                <= frame["max_jump_unmorphed"].as_f64().unwrap() + 1e-9
        );
    }
    assert_eq!(std::fs::read_dir(&frames).unwrap().count(), 5);
    assert_eq!(std::fs::read_dir(&meshes).unwrap().count(), 5);
    let orbit = json(&["flythrough", &stream, "--orbit", "--frames", "3", "--json"]);
    assert_eq!(orbit["frames"].as_array().unwrap().len(), 3);
}

#[test]
fn cli_views_of_a_geographic_dem_are_in_metres_by_default() {
    // The sample is on EPSG:4326 (3 arc-seconds, 403 × 344 samples at 36.7° N): in the
    // tangent plane at its centre a sample is about 74.5 m east and 92.6 m north.
    let dir = tempfile::tempdir().unwrap();
    let stream = sample_stream(dir.path());
    let mesh = dir.path().join("view.obj");
    let report = json(&[
        "view",
        &stream,
        "--camera",
        "-20000,-20000,4000",
        "--look",
        "0,0,300",
        "-o",
        mesh.to_str().unwrap(),
        "--json",
    ]);
    assert_eq!(report["xy_units"], "local_tangent");
    assert_eq!(report["cracks"], 0);
    let obj = std::fs::read_to_string(&mesh).unwrap();
    assert!(obj.contains("frame local_tangent"), "{}", &obj[..300]);
    let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
    for line in obj.lines().filter(|l| l.starts_with("v ")) {
        let xy: Vec<f64> = line[2..]
            .split_whitespace()
            .take(2)
            .map(|v| v.parse().unwrap())
            .collect();
        for k in 0..2 {
            lo[k] = lo[k].min(xy[k]);
            hi[k] = hi[k].max(xy[k]);
        }
    }
    // The mesh covers the grid: 402 × 74.5 m by 343 × 92.6 m about the centre.
    for (k, span) in [(0, 402.0 * 74.5), (1, 343.0 * 92.6)] {
        assert!(
            (hi[k] - lo[k] - span).abs() < 0.01 * span,
            "{k}: {lo:?} {hi:?}"
        );
        assert!((hi[k] + lo[k]).abs() < 0.01 * span, "{k}: {lo:?} {hi:?}");
    }
    let orbit = json(&["flythrough", &stream, "--orbit", "--frames", "3", "--json"]);
    assert_eq!(orbit["xy_units"], "local_tangent");
    assert_eq!(orbit["total_cracks"], 0);
    assert_eq!(orbit["all_match_rebuild"], true);
}

#[test]
fn cli_view_refuses_bad_arguments() {
    let dir = tempfile::tempdir().unwrap();
    let stream = sample_stream(dir.path());
    let out = dir.path().join("m.obj");
    let out = out.to_str().unwrap();
    let code = |args: &[&str]| {
        let o = wavemesh(args);
        let stderr = String::from_utf8_lossy(&o.stderr).to_string();
        assert!(
            !stderr.trim().is_empty() && !stderr.contains("panicked"),
            "{args:?}: {stderr}"
        );
        o.status.code()
    };
    assert_eq!(
        code(&["view", &stream, "--camera", "1,1,1", "--look", "1,1,1", "-o", out]),
        Some(2)
    );
    assert_eq!(
        code(&["view", &stream, "--camera", "1,1", "--look", "1,1,1", "-o", out]),
        Some(2)
    );
    assert_eq!(
        code(&["view", &stream, "--camera", "0,0,9", "--look", "1,1,1", "--tau", "0", "-o", out]),
        Some(2)
    );
    assert_eq!(
        code(&["view", &stream, "--camera", "0,0,9", "--look", "1,1,1", "-o", "m.stl"]),
        Some(2)
    );
    assert_eq!(
        code(&[
            "view",
            "/nonexistent.ezw",
            "--camera",
            "0,0,9",
            "--look",
            "1,1,1",
            "-o",
            out
        ]),
        Some(3)
    );
    let bad_path = dir.path().join("bad.csv");
    std::fs::write(&bad_path, "1,2,3\n").unwrap();
    assert_eq!(
        code(&["flythrough", &stream, "--path", bad_path.to_str().unwrap()]),
        Some(3)
    );
}
