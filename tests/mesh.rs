//! The mesh from the zerotree: watertight, no T-junctions, counter-clockwise, nodata never
//! meshed, coarser thresholds from the stored map equal to decoding less, tolerances met.

use std::collections::HashMap;

use bitvec::prelude::*;
use proptest::prelude::*;
use wavemesh::mesh::cells::SplitRule;
use wavemesh::mesh::pyramid::Heights;
use wavemesh::mesh::rasterise::mesh_error;
use wavemesh::mesh::{GridMesh, MeshTarget, Mesher};
use wavemesh_codec::{decode, encode, DecodeOptions, EncodeOptions, Quality, Raster, Samples};

/// Checks the topology of `mesh` over a grid whose valid samples are `valid`: every
/// triangle non-degenerate and counter-clockwise in the grid frame; every directed edge
/// used once (consistent winding, at most two triangles an edge); every edge with one
/// triangle on the border of the meshed region (so no crack or T-junction); the triangles
/// covering exactly the grid cells whose four corners are valid and half of each grid
/// cell with three (its one triangle, whose diagonal then borders the region).
fn check_topology(mesh: &GridMesh, valid: &BitSlice<u64, Lsb0>) -> Result<(), String> {
    let (w, h) = (mesh.width, mesh.height);
    let pos = |v: u32| {
        let (x, y) = mesh.vertex_position(v);
        (x as i64, y as i64)
    };
    let mut directed: HashMap<(u32, u32), usize> = HashMap::new();
    let mut area2 = 0i64;
    for (t, tri) in mesh.triangles.iter().enumerate() {
        let [a, b, c] = tri.map(pos);
        let cross = (b.0 - a.0) * (c.1 - a.1) - (b.1 - a.1) * (c.0 - a.0);
        if cross <= 0 {
            return Err(format!(
                "triangle {t} {tri:?} is degenerate or clockwise ({cross})"
            ));
        }
        area2 += cross;
        for k in 0..3 {
            let e = (tri[k], tri[(k + 1) % 3]);
            if directed.insert(e, t).is_some() {
                return Err(format!("directed edge {e:?} used twice"));
            }
        }
    }
    // The meshed region: cells with three or four valid corners.
    let valid_corners = |x: i64, y: i64| {
        if x < 0 || y < 0 || x >= w as i64 - 1 || y >= h as i64 - 1 {
            return 0;
        }
        let s = y as usize * w + x as usize;
        [s, s + 1, s + w, s + w + 1]
            .into_iter()
            .filter(|&c| valid[c])
            .count() as i64
    };
    let cell_ok = |x: i64, y: i64| valid_corners(x, y) >= 3;
    let halves: i64 = (0..h as i64 - 1)
        .flat_map(|y| (0..w as i64 - 1).map(move |x| (x, y)))
        .map(|(x, y)| match valid_corners(x, y) {
            4 => 2,
            3 => 1,
            _ => 0,
        })
        .sum();
    if area2 != halves {
        return Err(format!(
            "triangles cover {} cells of {}",
            area2 as f64 / 2.0,
            halves as f64 / 2.0
        ));
    }
    for &(a, b) in directed.keys() {
        if directed.contains_key(&(b, a)) {
            continue;
        }
        // A border edge: axis-aligned, with one meshed cell beside each unit step of it.
        let ((ax, ay), (bx, by)) = (pos(a), pos(b));
        if ax != bx && ay != by {
            if (ax - bx).abs() == 1
                && (ay - by).abs() == 1
                && valid_corners(ax.min(bx), ay.min(by)) == 3
            {
                continue; // the diagonal of a cell with three valid corners
            }
            return Err(format!("diagonal edge {a}-{b} has one triangle"));
        }
        let steps = (bx - ax).abs().max((by - ay).abs());
        let (dx, dy) = ((bx - ax).signum(), (by - ay).signum());
        for k in 0..steps {
            let (x, y) = (ax + k * dx, ay + k * dy);
            let (one, other) = if dy == 0 {
                let xm = x.min(x + dx);
                (cell_ok(xm, y - 1), cell_ok(xm, y))
            } else {
                let ym = y.min(y + dy);
                (cell_ok(x - 1, ym), cell_ok(x, ym))
            };
            if one == other {
                return Err(format!(
                    "edge ({ax},{ay})-({bx},{by}) has one triangle inside the meshed region (crack or T-junction)"
                ));
            }
        }
    }
    for &s in &mesh.vertices {
        if !valid[s as usize] {
            return Err(format!("nodata sample {s} is a vertex"));
        }
    }
    Ok(())
}

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
            let base = 300.0 * (x * fx).sin() * (y * fy).cos() + 2.0 * x;
            (base + (next() % 9) as f64) as i16
        })
        .collect();
    if voids {
        for _ in 0..(w * h / 40).max(1) {
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

struct Decoded {
    heights: Vec<f64>,
    valid: BitVec<u64, Lsb0>,
    map: wavemesh_codec::SignificanceMap,
    width: usize,
    height: usize,
    /// The stream's first pass plane.
    top_plane: u32,
}

fn decode_with_map(
    raster: &Raster,
    quality: Quality,
    budget: Option<u64>,
    passes: Option<u32>,
) -> Decoded {
    let file = encode(raster, &EncodeOptions::new(quality, budget)).unwrap();
    let options = DecodeOptions::default()
        .with_significance_map(true)
        .with_max_passes(passes);
    let decoded = decode(&file.bytes, &options).unwrap();
    let r = &decoded.raster;
    Decoded {
        heights: r.samples.to_f64(),
        valid: r.valid_mask().into_iter().collect(),
        map: decoded.significance.unwrap(),
        width: r.width,
        height: r.height,
        top_plane: decoded.header.top_plane.map_or(0, u32::from),
    }
}

impl Decoded {
    fn mesher(&self) -> Mesher<'_> {
        let heights = Heights {
            width: self.width,
            height: self.height,
            values: &self.heights,
        };
        Mesher::new(&self.map, heights, &self.valid)
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(48))]

    #[test]
    fn meshes_are_watertight_at_every_threshold(
        w in 2usize..40, h in 2usize..40, seed in any::<u64>(), voids in any::<bool>(),
        own in any::<bool>(),
    ) {
        let raster = terrain(w, h, seed, voids);
        let d = decode_with_map(&raster, Quality::Lossless, None, None);
        let mut mesher = d.mesher();
        let rule = if own { SplitRule::OwnCoefficients } else { SplitRule::Zerotree };
        let mut last = 0;
        for plane in (0..=u32::from(d.map.top())).rev() {
            let result = mesher.build(MeshTarget::Plane(plane), rule, None);
            check_topology(&result.mesh, &d.valid).map_err(TestCaseError::fail)?;
            // Triangles never decrease as the threshold falls.
            prop_assert!(result.mesh.triangles.len() >= last);
            last = result.mesh.triangles.len();
        }
    }

    #[test]
    fn tolerances_hold_at_every_sample(
        w in 2usize..40, h in 2usize..40, seed in any::<u64>(), voids in any::<bool>(),
        tolerance in 0.0f64..40.0,
    ) {
        let raster = terrain(w, h, seed, voids);
        let d = decode_with_map(&raster, Quality::Lossless, None, None);
        let mut mesher = d.mesher();
        let result = mesher.build(MeshTarget::Tolerance(tolerance), SplitRule::Zerotree, None);
        check_topology(&result.mesh, &d.valid).map_err(TestCaseError::fail)?;
        let error = mesh_error(&result.mesh, &d.heights, &d.heights, &d.valid);
        prop_assert!(error.max_error <= tolerance, "max error {} > {}", error.max_error, tolerance);
        // Valid samples left out are exactly those with no valid cell around them.
        if !voids {
            prop_assert_eq!(error.uncovered_samples, 0);
        }
    }
}

#[test]
fn a_coarser_threshold_from_the_map_equals_decoding_less() {
    for (w, h, seed) in [(65, 65, 1), (50, 37, 2), (33, 90, 3)] {
        let raster = terrain(w, h, seed, seed == 2);
        let full = decode_with_map(&raster, Quality::Lossless, None, None);
        let top = full.top_plane;
        assert!(u32::from(full.map.top()) <= top + 1);
        let full_mesher = full.mesher();
        for passes in 1..=top + 1 {
            let plane = top + 1 - passes;
            let part = decode_with_map(&raster, Quality::Lossless, None, Some(passes));
            let part_mesher = part.mesher();
            for rule in [SplitRule::Zerotree, SplitRule::OwnCoefficients] {
                let a = full_mesher.cells_at_plane(plane, rule);
                let b = part_mesher.cells_at_plane(plane, rule);
                assert_eq!(a.leaves(), b.leaves(), "{w}x{h} plane {plane} {rule:?}");
            }
        }
    }
}

#[test]
fn lossy_streams_mesh_too() {
    let raster = terrain(129, 97, 7, true);
    let d = decode_with_map(&raster, Quality::Lossless, Some(1500), None);
    let mut mesher = d.mesher();
    for plane in 0..=u32::from(d.map.top()) {
        let result = mesher.build(MeshTarget::Plane(plane), SplitRule::Zerotree, None);
        check_topology(&result.mesh, &d.valid).unwrap();
    }
}

#[test]
fn budgets_are_met() {
    let raster = terrain(129, 129, 11, false);
    let d = decode_with_map(&raster, Quality::Lossless, None, None);
    let mut mesher = d.mesher();
    for budget in [50, 500, 5000] {
        for target in [
            MeshTarget::Triangles(budget),
            MeshTarget::TrianglesByTolerance(budget),
        ] {
            let result = mesher.build(target, SplitRule::Zerotree, None);
            assert!(
                result.mesh.triangles.len() <= budget,
                "{target:?}: {}",
                result.mesh.triangles.len()
            );
            check_topology(&result.mesh, &d.valid).unwrap();
        }
    }
    // Tolerance 0: exact, with at most every grid cell as two triangles.
    let full = mesher.build(MeshTarget::Tolerance(0.0), SplitRule::Zerotree, None);
    assert!(full.mesh.triangles.len() <= 2 * 128 * 128);
    let error = mesh_error(&full.mesh, &d.heights, &d.heights, &d.valid);
    assert_eq!(error.max_error, 0.0);
}
