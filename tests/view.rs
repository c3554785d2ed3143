//! View-dependent terrain: crack-free meshes every frame, incremental split/merge equal to
//! the from-scratch selection, geomorphing that keeps vertex jumps small, and the rules'
//! basic behaviour; on synthetic terrains with and without voids and on the shared DEMs.

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
    let options = DecodeOptions {
        significance_map: true,
        ..DecodeOptions::default()
    };
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
    #![proptest_config(ProptestConfig::with_cases(24))]

    /// Every frame of a random flight: no crack in the morphed mesh, and the incremental
    /// selection equal to the from-scratch one.
    #[test]
    fn random_flights_are_crack_free_and_incremental_equals_rebuild(
        w in 9usize..70, h in 9usize..70, seed in any::<u64>(), voids in any::<bool>(),
        height in 5.0f64..80.0, turn in -2.0f64..2.0, tau in 0.3f64..4.0, frames in 3usize..12,
    ) {
        let decoded = decode_with_map(&terrain(w, h, seed, voids));
        let terrain = decoded.terrain();
        let rule = Rule::ScreenSpace { tau };
        let mut scratch = MorphScratch::default();
        let first = flight(w, h, 0.0, height, turn);
        let mut incremental = Incremental::new(&terrain, &first, rule);
        for f in 0..frames {
            let view = flight(w, h, f as f64 / frames as f64, height, turn);
            if f > 0 {
                incremental.update(&terrain, &view);
            }
            let rebuilt = terrain.select(&view, rule);
            prop_assert!(incremental.tree().leaves() == rebuilt.leaves(), "frame {}: incremental differs from the rebuild", f);
            prop_assert_eq!(frame_cracks(&terrain, &view, rule, &incremental, &mut scratch), 0, "frame {}", f);
        }
    }
}

/// Morphed heights move little between close frames where the unmorphed ones pop.
#[test]
fn geomorphing_bounds_vertex_jumps() {
    let decoded = decode_with_map(&terrain(129, 129, 7, false));
    let terrain = decoded.terrain();
    let rule = Rule::ScreenSpace { tau: 1.0 };
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
        let view = flight(129, 129, f as f64 / frames as f64, 40.0, 0.5);
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
        morphed_worst < 0.25 * unmorphed_worst,
        "morphed {morphed_worst} vs {unmorphed_worst}"
    );
}
