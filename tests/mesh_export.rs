//! The mesh exporter read back by independent parsers: `gltf` (with its validation) for
//! `.glb`, `tobj` for `.obj` and `ply-rs-bw` for `.ply`.
//!
//! Meshes are built by hand: fully triangulated grids, and a "random-ish" mesh over a
//! subset of a grid's samples with shuffled vertices and mixed diagonals. Every format
//! must give back the vertex and triangle counts, the positions (exactly for OBJ and PLY,
//! to `f32` precision for glTF) and triangles that face up, in pixel units, under
//! north-up, south-up and rotated geotransforms, and in a geographic DEM's local metric
//! (east-north-up) frame.

use std::path::Path;

use gltf::buffer::Source;
use gltf::mesh::Mode;
use ply_rs_bw::parser::Parser;
use ply_rs_bw::ply::{DefaultElement, Encoding, Property};
use serde_json::Value;
use wavemesh::mesh::export::{
    encode_mesh, write_mesh, ExportError, MeshFormat, Placement, XyUnits,
};
use wavemesh::mesh::GridMesh;
use wavemesh_codec::Georef;

/// A UTM-like north-up geotransform (30 m pixels, rows going south).
const NORTH_UP: [f64; 6] = [523_456.789, 30.0, 0.0, 4_123_456.321, 0.0, -30.0];
/// Rows going north (keeps the grid's orientation).
const SOUTH_UP: [f64; 6] = [-1000.25, 0.5, 0.0, 200.125, 0.0, 0.75];
/// Rotated by about 30° and north-up (mirrors the grid).
const ROTATED: [f64; 6] = [650_000.5, 25.98, -15.0, 5_200_000.5, 15.0, -25.98];

/// A small deterministic generator (SplitMix64).
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    fn below(&mut self, n: usize) -> usize {
        (self.next() % n as u64) as usize
    }

    fn unit(&mut self) -> f64 {
        (self.next() >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// Heights with fractional parts that `f32` cannot hold, around 1000 m.
fn heights(samples: usize, seed: u64) -> Vec<f64> {
    let mut rng = Rng(seed);
    (0..samples)
        .map(|_| 1000.0 + 250.0 * rng.unit() + 1e-7)
        .collect()
}

/// The z component of `(b − a) × (c − a)` for (column, row) points.
fn grid_cross(a: (usize, usize), b: (usize, usize), c: (usize, usize)) -> i64 {
    let (ax, ay) = (a.0 as i64, a.1 as i64);
    let (bx, by) = (b.0 as i64, b.1 as i64);
    let (cx, cy) = (c.0 as i64, c.1 as i64);
    (bx - ax) * (cy - ay) - (by - ay) * (cx - ax)
}

/// A mesh over the samples at `cols × rows` (strictly increasing) of a `width × height`
/// grid: every rectangle between neighbouring chosen columns and rows split into two
/// counter-clockwise triangles along the diagonal `diagonal(cell)` picks, vertices in
/// the order `order` gives.
fn rectilinear_mesh(
    width: usize,
    height: usize,
    cols: &[usize],
    rows: &[usize],
    mut diagonal: impl FnMut() -> bool,
    order: &[usize],
) -> GridMesh {
    let nc = cols.len();
    let sample = |i: usize, j: usize| (rows[j] * width + cols[i]) as u32;
    // Vertex `v` is grid point order[v] (point k = j·nc + i).
    let vertices: Vec<u32> = order.iter().map(|&k| sample(k % nc, k / nc)).collect();
    let mut vertex_of = vec![0u32; order.len()];
    for (v, &k) in order.iter().enumerate() {
        vertex_of[k] = v as u32;
    }
    let v = |i: usize, j: usize| vertex_of[j * nc + i];
    let mut triangles = Vec::new();
    for j in 0..rows.len() - 1 {
        for i in 0..nc - 1 {
            let (a, b, c, d) = (v(i, j), v(i + 1, j), v(i, j + 1), v(i + 1, j + 1));
            if diagonal() {
                // Diagonal b–c.
                triangles.push([a, b, c]);
                triangles.push([b, d, c]);
            } else {
                // Diagonal a–d.
                triangles.push([a, b, d]);
                triangles.push([a, d, c]);
            }
        }
    }
    let mesh = GridMesh {
        width,
        height,
        vertices,
        triangles,
    };
    for t in &mesh.triangles {
        let [a, b, c] = t.map(|i| mesh.vertex_position(i));
        assert!(
            grid_cross(a, b, c) > 0,
            "test mesh is not counter-clockwise"
        );
    }
    mesh
}

/// Every sample of a `width × height` grid, in order, two triangles per cell.
fn full_grid(width: usize, height: usize) -> GridMesh {
    let cols: Vec<usize> = (0..width).collect();
    let rows: Vec<usize> = (0..height).collect();
    let order: Vec<usize> = (0..width * height).collect();
    rectilinear_mesh(width, height, &cols, &rows, || true, &order)
}

/// A mesh over a random subset of a 23 × 17 grid's samples (always with the first and last
/// column and row), random diagonals and shuffled vertex order.
fn random_mesh(seed: u64) -> GridMesh {
    let (width, height) = (23, 17);
    let mut rng = Rng(seed);
    let mut pick = |n: usize| -> Vec<usize> {
        (0..n)
            .filter(|&k| k == 0 || k == n - 1 || rng.below(3) != 0)
            .collect()
    };
    let cols = pick(width);
    let rows = pick(height);
    let mut order: Vec<usize> = (0..cols.len() * rows.len()).collect();
    for k in (1..order.len()).rev() {
        order.swap(k, rng.below(k + 1));
    }
    rectilinear_mesh(width, height, &cols, &rows, || rng.below(2) == 0, &order)
}

/// The placements every mesh is exported with.
fn placements() -> Vec<(&'static str, Placement)> {
    vec![
        ("pixel", Placement::pixel(1.0)),
        ("pixel z×2.5", Placement::pixel(2.5)),
        ("north-up", Placement::georeferenced(NORTH_UP, 1.0)),
        ("north-up z×−0.5", Placement::georeferenced(NORTH_UP, -0.5)),
        ("south-up", Placement::georeferenced(SOUTH_UP, 3.0)),
        ("rotated", Placement::georeferenced(ROTATED, 1.0)),
        ("fallback", Placement::default()),
        ("geographic", geographic()),
    ]
}

/// EPSG:4326 with 3" cells around 36.7° N: metres east-north-up of the grid's centre.
fn geographic() -> Placement {
    let step = 1.0 / 1200.0;
    let georef = Georef {
        geotransform: [-84.41375, step, 0.0, 36.73, 0.0, -step],
        geo_key_directory: vec![1, 1, 0, 2, 1024, 0, 1, 2, 2048, 0, 1, 4326],
        ..Georef::default()
    };
    let p = Placement::metric(Some(&georef), 23, 17, 1.0).unwrap();
    assert!(matches!(p.xy, XyUnits::Local(_)));
    p
}

/// The terrain-frame position of vertex `v`, computed here from the definition.
fn expected_position(mesh: &GridMesh, heights: &[f64], p: &Placement, v: u32) -> [f64; 3] {
    let s = mesh.vertices[v as usize] as usize;
    let (col, row) = (s % mesh.width, s / mesh.width);
    let z = heights[s] * p.z_scale;
    match (p.xy, p.geotransform) {
        (XyUnits::Georeferenced, Some(gt)) => {
            let (c, r) = (col as f64 + 0.5, row as f64 + 0.5);
            [
                gt[0] + c * gt[1] + r * gt[2],
                gt[3] + c * gt[4] + r * gt[5],
                z,
            ]
        }
        (XyUnits::Local(frame), Some(gt)) => {
            let (c, r) = (col as f64 + 0.5, row as f64 + 0.5);
            frame.enu(
                gt[0] + c * gt[1] + r * gt[2],
                gt[3] + c * gt[4] + r * gt[5],
                z,
            )
        }
        _ => [col as f64, row as f64, z],
    }
}

/// `(b − a) × (c − a)`.
fn cross(a: [f64; 3], b: [f64; 3], c: [f64; 3]) -> [f64; 3] {
    let u = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
    let w = [c[0] - a[0], c[1] - a[1], c[2] - a[2]];
    [
        u[1] * w[2] - u[2] * w[1],
        u[2] * w[0] - u[0] * w[2],
        u[0] * w[1] - u[1] * w[0],
    ]
}

/// The meshes every format is checked on.
fn meshes() -> Vec<(&'static str, GridMesh, Vec<f64>)> {
    let grid3 = full_grid(3, 3);
    assert_eq!(grid3.triangles.len(), 8);
    let grid = full_grid(9, 6);
    let random = random_mesh(7);
    let random2 = random_mesh(1234);
    vec![
        ("3x3", grid3, heights(9, 1)),
        ("9x6", grid, heights(54, 2)),
        ("random 7", random, heights(23 * 17, 3)),
        ("random 1234", random2, heights(23 * 17, 4)),
    ]
}

/// A mesh read back from a file: terrain-frame positions per triangle corner.
struct ReadBack {
    vertices: usize,
    /// Per triangle, its corners' positions in the terrain frame (x east, y north, z up).
    triangles: Vec<[[f64; 3]; 3]>,
}

/// Checks a read-back mesh against the source: counts, corner positions within `tol`
/// (relative to the coordinate's size; 0 = exact), and every triangle facing up.
fn check(name: &str, mesh: &GridMesh, heights: &[f64], p: &Placement, back: &ReadBack, tol: f64) {
    assert_eq!(back.vertices, mesh.vertices.len(), "{name}: vertex count");
    assert_eq!(
        back.triangles.len(),
        mesh.triangles.len(),
        "{name}: triangle count"
    );
    for (t, (got, src)) in back.triangles.iter().zip(&mesh.triangles).enumerate() {
        // The exporter may swap two corners; the set of corners must match, in a cyclic
        // order that faces up.
        let want = src.map(|v| expected_position(mesh, heights, p, v));
        let same = |a: [f64; 3], b: [f64; 3]| {
            (0..3).all(|k| (a[k] - b[k]).abs() <= tol * (1.0 + b[k].abs()))
        };
        let rotations = [
            [got[0], got[1], got[2]],
            [got[1], got[2], got[0]],
            [got[2], got[0], got[1]],
        ];
        let flipped = [want[0], want[2], want[1]];
        let matches = rotations
            .iter()
            .any(|r| (0..3).all(|k| same(r[k], want[k])) || (0..3).all(|k| same(r[k], flipped[k])));
        assert!(
            matches,
            "{name}: triangle {t} corners {got:?}, expected {want:?} in some order"
        );
        let n = cross(got[0], got[1], got[2]);
        assert!(n[2] > 0.0, "{name}: triangle {t} faces down: normal {n:?}");
    }
}

/// Parses a `.glb` with `gltf` (which validates it) and checks its structure.
fn read_glb(name: &str, bytes: &[u8]) -> (ReadBack, Vec<[f32; 3]>) {
    check_glb_container(name, bytes);
    let gltf = gltf::Gltf::from_slice(bytes).unwrap_or_else(|e| panic!("{name}: invalid glb: {e}"));
    let doc = &gltf.document;
    assert_eq!(doc.as_json().asset.version, "2.0");
    assert_eq!(doc.as_json().asset.generator.as_deref(), Some("wavemesh"));
    let scene = doc.default_scene().expect("a default scene");
    let nodes: Vec<_> = scene.nodes().collect();
    assert_eq!(nodes.len(), 1, "{name}: one node");
    let node = &nodes[0];
    let Some(mesh) = node.mesh() else {
        assert_eq!(doc.meshes().count(), 0);
        assert_eq!(doc.accessors().count(), 0);
        assert_eq!(doc.buffers().count(), 0);
        assert!(gltf.blob.is_none());
        return (
            ReadBack {
                vertices: 0,
                triangles: vec![],
            },
            vec![],
        );
    };
    assert_eq!(doc.meshes().count(), 1);
    let primitives: Vec<_> = mesh.primitives().collect();
    assert_eq!(primitives.len(), 1, "{name}: one primitive");
    let prim = &primitives[0];
    assert_eq!(prim.mode(), Mode::Triangles);

    // Node translation, full precision from the JSON (gltf keeps only f32).
    let json: Value = serde_json::from_slice(glb_chunk(bytes, 0).1).unwrap();
    let t64: Vec<f64> = json["nodes"][0]["translation"]
        .as_array()
        .expect("translation")
        .iter()
        .map(|v| v.as_f64().unwrap())
        .collect();
    let (t32, rotation, scale) = node.transform().decomposed();
    assert_eq!(rotation, [0.0, 0.0, 0.0, 1.0]);
    assert_eq!(scale, [1.0, 1.0, 1.0]);
    for k in 0..3 {
        assert_eq!(t32[k], t64[k] as f32);
    }
    assert_eq!(t64[1], 0.0);

    let blob = gltf.blob.as_deref();
    let reader = prim.reader(|b| match b.source() {
        Source::Bin => blob,
        Source::Uri(_) => None,
    });
    let positions: Vec<[f32; 3]> = reader.read_positions().expect("POSITION").collect();
    let normals: Vec<[f32; 3]> = reader.read_normals().expect("NORMAL").collect();
    let indices: Vec<u32> = reader.read_indices().expect("indices").into_u32().collect();
    assert_eq!(normals.len(), positions.len());
    assert_eq!(indices.len() % 3, 0);

    // POSITION min/max are required and must be the data's bounds.
    let pos_accessor = prim.get(&gltf::Semantic::Positions).unwrap();
    assert_eq!(pos_accessor.data_type(), gltf::accessor::DataType::F32);
    let bound = |v: Value| -> Vec<f32> {
        v.as_array()
            .unwrap()
            .iter()
            .map(|x| x.as_f64().unwrap() as f32)
            .collect()
    };
    let min = bound(pos_accessor.min().expect("POSITION min"));
    let max = bound(pos_accessor.max().expect("POSITION max"));
    for k in 0..3 {
        let lo = positions.iter().map(|p| p[k]).fold(f32::INFINITY, f32::min);
        let hi = positions
            .iter()
            .map(|p| p[k])
            .fold(f32::NEG_INFINITY, f32::max);
        assert_eq!((min[k], max[k]), (lo, hi), "{name}: POSITION bounds");
    }
    // The node translation is the centre of the x/z (terrain x/y) bounding box.
    assert!((min[0] + max[0]).abs() <= 1e-3 * (1.0 + max[0].abs()));
    assert!((min[2] + max[2]).abs() <= 1e-3 * (1.0 + max[2].abs()));

    // Terrain frame: x = X + tx, y = −(Z + tz), z = Y.
    let terrain = |i: u32| {
        let p = positions[i as usize];
        [
            p[0] as f64 + t64[0],
            -(p[2] as f64 + t64[2]),
            p[1] as f64 + t64[1],
        ]
    };
    let triangles = indices
        .chunks_exact(3)
        .map(|t| {
            // Facing up in glTF's own frame: +Y.
            let g = |i: u32| positions[i as usize].map(f64::from);
            let n = cross(g(t[0]), g(t[1]), g(t[2]));
            assert!(n[1] > 0.0, "{name}: glTF triangle {t:?} faces down: {n:?}");
            [terrain(t[0]), terrain(t[1]), terrain(t[2])]
        })
        .collect();
    (
        ReadBack {
            vertices: positions.len(),
            triangles,
        },
        normals,
    )
}

/// Chunk `k` of a `.glb`: (type, data).
fn glb_chunk(bytes: &[u8], k: usize) -> (&[u8], &[u8]) {
    let mut at = 12;
    for _ in 0..k {
        at += 8 + u32_at(bytes, at) as usize;
    }
    let len = u32_at(bytes, at) as usize;
    (&bytes[at + 4..at + 8], &bytes[at + 8..at + 8 + len])
}

fn u32_at(bytes: &[u8], at: usize) -> u32 {
    u32::from_le_bytes(bytes[at..at + 4].try_into().unwrap())
}

/// The GLB container rules: header, 4-byte aligned chunks padded with spaces (JSON) and
/// zeros (BIN), buffer and view lengths consistent.
fn check_glb_container(name: &str, bytes: &[u8]) {
    assert_eq!(&bytes[0..4], b"glTF", "{name}: magic");
    assert_eq!(u32_at(bytes, 4), 2, "{name}: version");
    assert_eq!(u32_at(bytes, 8) as usize, bytes.len(), "{name}: length");
    assert_eq!(bytes.len() % 4, 0);
    let (kind, json) = glb_chunk(bytes, 0);
    assert_eq!(kind, b"JSON");
    assert_eq!(json.len() % 4, 0);
    let doc: Value = serde_json::from_slice(json).expect("JSON chunk parses (trailing spaces)");
    let mut end = 20 + json.len();
    if end == bytes.len() {
        assert!(
            doc.get("buffers").is_none(),
            "{name}: buffer without BIN chunk"
        );
        return;
    }
    let (kind, bin) = glb_chunk(bytes, 1);
    assert_eq!(kind, b"BIN\0");
    assert_eq!(bin.len() % 4, 0);
    end += 8 + bin.len();
    assert_eq!(end, bytes.len(), "{name}: no bytes after the BIN chunk");
    let buffers = doc["buffers"].as_array().unwrap();
    assert_eq!(buffers.len(), 1);
    assert!(buffers[0].get("uri").is_none());
    let byte_length = buffers[0]["byteLength"].as_u64().unwrap() as usize;
    assert!(byte_length <= bin.len() && bin.len() < byte_length + 4);
    assert!(
        bin[byte_length..].iter().all(|&b| b == 0),
        "{name}: BIN padding"
    );
    for view in doc["bufferViews"].as_array().unwrap() {
        let offset = view["byteOffset"].as_u64().unwrap_or(0) as usize;
        let len = view["byteLength"].as_u64().unwrap() as usize;
        assert!(
            len > 0 && offset + len <= byte_length,
            "{name}: view {view}"
        );
        assert_eq!(offset % 4, 0, "{name}: view alignment");
    }
    for accessor in doc["accessors"].as_array().unwrap() {
        assert!(accessor["count"].as_u64().unwrap() > 0);
    }
}

/// Parses a `.obj` with `tobj`.
fn read_obj(name: &str, bytes: &[u8]) -> ReadBack {
    assert!(bytes.starts_with(b"#"), "{name}: header comment");
    // Faces as written: no triangulation, no re-indexing into a single index.
    let options = tobj::LoadOptions::default();
    let (models, _materials) = tobj::load_obj_buf(&mut &bytes[..], &options, |_| {
        Err(tobj::LoadError::OpenFileFailed)
    })
    .unwrap_or_else(|e| panic!("{name}: invalid obj: {e}"));
    let mut vertices = 0;
    let mut triangles = Vec::new();
    for model in &models {
        let m = &model.mesh;
        assert!(
            m.face_arities.iter().all(|&a| a == 3),
            "{name}: triangles only"
        );
        assert_eq!(m.indices.len() % 3, 0);
        // tobj keeps the referenced positions, renumbered.
        vertices += m.positions.len() / 3;
        let pos = |i: u32| {
            let i = i as usize * 3;
            [m.positions[i], m.positions[i + 1], m.positions[i + 2]]
        };
        for t in m.indices.chunks_exact(3) {
            triangles.push([pos(t[0]), pos(t[1]), pos(t[2])]);
        }
    }
    ReadBack {
        vertices,
        triangles,
    }
}

/// Parses a `.ply` with `ply-rs-bw`.
fn read_ply(name: &str, bytes: &[u8]) -> ReadBack {
    let ply = Parser::<DefaultElement>::new()
        .read_ply(&mut &bytes[..])
        .unwrap_or_else(|e| panic!("{name}: invalid ply: {e}"));
    assert_eq!(ply.header.encoding, Encoding::BinaryLittleEndian);
    assert!(ply
        .header
        .comments
        .iter()
        .any(|c| c.contains("generated by wavemesh")));
    let double = |e: &DefaultElement, key: &str| match e.get(key) {
        Some(Property::Double(v)) => *v,
        other => panic!("{name}: vertex {key} is {other:?}"),
    };
    let vertices: Vec<[f64; 3]> = ply.payload["vertex"]
        .iter()
        .map(|e| [double(e, "x"), double(e, "y"), double(e, "z")])
        .collect();
    let triangles = ply.payload["face"]
        .iter()
        .map(|e| match e.get("vertex_indices") {
            Some(Property::ListUInt(list)) => {
                assert_eq!(list.len(), 3, "{name}: triangle");
                [0, 1, 2].map(|k| vertices[list[k] as usize])
            }
            other => panic!("{name}: face is {other:?}"),
        })
        .collect();
    ReadBack {
        vertices: vertices.len(),
        triangles,
    }
}

#[test]
fn glb_reads_back_valid_with_upward_normals() {
    for (mesh_name, mesh, heights) in meshes() {
        for (place_name, placement) in placements() {
            let name = format!("{mesh_name} / {place_name} / glb");
            let bytes = encode_mesh(&mesh, &heights, &placement, MeshFormat::Glb).unwrap();
            let (back, normals) = read_glb(&name, &bytes);
            // Local coordinates are small, so f32 keeps them to about 1e-7 relative; the
            // terrain-frame tolerance is relative to the (possibly UTM-sized) coordinate.
            check(&name, &mesh, &heights, &placement, &back, 1e-6);
            for n in &normals {
                let len = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
                assert!((len - 1.0).abs() < 1e-5, "{name}: normal {n:?} not unit");
                assert!(n[1] > 0.0, "{name}: normal {n:?} does not point up");
            }
        }
    }
}

#[test]
fn obj_reads_back_exactly() {
    for (mesh_name, mesh, heights) in meshes() {
        for (place_name, placement) in placements() {
            let name = format!("{mesh_name} / {place_name} / obj");
            let bytes = encode_mesh(&mesh, &heights, &placement, MeshFormat::Obj).unwrap();
            check(
                &name,
                &mesh,
                &heights,
                &placement,
                &read_obj(&name, &bytes),
                0.0,
            );
        }
    }
}

#[test]
fn ply_reads_back_exactly() {
    for (mesh_name, mesh, heights) in meshes() {
        for (place_name, placement) in placements() {
            let name = format!("{mesh_name} / {place_name} / ply");
            let bytes = encode_mesh(&mesh, &heights, &placement, MeshFormat::Ply).unwrap();
            check(
                &name,
                &mesh,
                &heights,
                &placement,
                &read_ply(&name, &bytes),
                0.0,
            );
        }
    }
}

#[test]
fn north_up_swaps_corners_and_pixel_keeps_them() {
    let mesh = full_grid(3, 3);
    let heights = heights(9, 5);
    let ply_faces = |p: &Placement| {
        let bytes = encode_mesh(&mesh, &heights, p, MeshFormat::Ply).unwrap();
        let ply = Parser::<DefaultElement>::new()
            .read_ply(&mut &bytes[..])
            .unwrap();
        ply.payload["face"]
            .iter()
            .map(|e| match &e["vertex_indices"] {
                Property::ListUInt(l) => [l[0], l[1], l[2]],
                other => panic!("{other:?}"),
            })
            .collect::<Vec<_>>()
    };
    assert_eq!(ply_faces(&Placement::pixel(1.0)), mesh.triangles);
    let swapped: Vec<[u32; 3]> = mesh.triangles.iter().map(|t| [t[0], t[2], t[1]]).collect();
    assert_eq!(ply_faces(&Placement::georeferenced(NORTH_UP, 1.0)), swapped);
}

#[test]
fn large_mesh_uses_u32_indices() {
    // 300 × 300 = 90 000 vertices: past what u16 indices address.
    let mesh = full_grid(300, 300);
    let heights = heights(300 * 300, 9);
    let placement = Placement::georeferenced(NORTH_UP, 1.0);
    let bytes = encode_mesh(&mesh, &heights, &placement, MeshFormat::Glb).unwrap();
    let json: Value = serde_json::from_slice(glb_chunk(&bytes, 0).1).unwrap();
    assert_eq!(json["accessors"][2]["componentType"], 5125);
    let (back, normals) = read_glb("300x300", &bytes);
    check("300x300", &mesh, &heights, &placement, &back, 1e-6);
    assert!(normals.iter().all(|n| n[1] > 0.0));

    // Small meshes use u16.
    let small = full_grid(3, 3);
    let bytes = encode_mesh(&small, &heights[..9], &placement, MeshFormat::Glb).unwrap();
    let json: Value = serde_json::from_slice(glb_chunk(&bytes, 0).1).unwrap();
    assert_eq!(json["accessors"][2]["componentType"], 5123);
}

#[test]
fn empty_meshes_give_valid_files() {
    let no_triangles = GridMesh {
        width: 3,
        height: 2,
        vertices: vec![0, 4, 5],
        triangles: vec![],
    };
    let heights = heights(6, 11);
    for (name, mesh) in [("default", GridMesh::default()), ("points", no_triangles)] {
        for (_, placement) in placements() {
            let glb = encode_mesh(&mesh, &heights, &placement, MeshFormat::Glb).unwrap();
            let (back, normals) = read_glb(name, &glb);
            assert!(back.triangles.is_empty() && normals.is_empty());

            let obj = encode_mesh(&mesh, &heights, &placement, MeshFormat::Obj).unwrap();
            assert!(read_obj(name, &obj).triangles.is_empty());
            let v_lines = String::from_utf8(obj)
                .unwrap()
                .lines()
                .filter(|l| l.starts_with("v "))
                .count();
            assert_eq!(v_lines, mesh.vertices.len());

            let ply = encode_mesh(&mesh, &heights, &placement, MeshFormat::Ply).unwrap();
            let back = read_ply(name, &ply);
            assert_eq!(back.vertices, mesh.vertices.len());
            assert!(back.triangles.is_empty());
        }
    }
}

#[test]
fn bad_input_is_an_error_not_a_panic() {
    let mesh = full_grid(3, 3);
    let mut heights = heights(9, 13);
    let p = Placement::pixel(1.0);
    for format in [MeshFormat::Glb, MeshFormat::Obj, MeshFormat::Ply] {
        assert!(matches!(
            encode_mesh(&mesh, &heights[..8], &p, format),
            Err(ExportError::MissingHeight { .. })
        ));
        heights[4] = f64::INFINITY;
        assert!(matches!(
            encode_mesh(&mesh, &heights, &p, format),
            Err(ExportError::NonFiniteHeight { sample: 4, .. })
        ));
        heights[4] = 0.0;
        let mut bad = mesh.clone();
        bad.triangles[3][1] = 9;
        assert!(matches!(
            encode_mesh(&bad, &heights, &p, format),
            Err(ExportError::BadTriangle { triangle: 3, .. })
        ));
        let nan_gt = Placement::georeferenced([f64::NAN, 1.0, 0.0, 0.0, 0.0, -1.0], 1.0);
        assert!(matches!(
            encode_mesh(&mesh, &heights, &nan_gt, format),
            Err(ExportError::NonFinitePosition { .. })
        ));
    }
}

#[test]
fn write_mesh_writes_the_encoded_bytes() {
    let dir = tempfile::tempdir().unwrap();
    let mesh = random_mesh(3);
    let heights = heights(23 * 17, 3);
    let placement = Placement::georeferenced(NORTH_UP, 1.0);
    for format in [MeshFormat::Glb, MeshFormat::Obj, MeshFormat::Ply] {
        let path = dir.path().join(format!("terrain.{}", format.name()));
        assert_eq!(MeshFormat::from_path(&path), Some(format));
        write_mesh(&path, &mesh, &heights, &placement, format).unwrap();
        let expected = encode_mesh(&mesh, &heights, &placement, format).unwrap();
        assert_eq!(std::fs::read(&path).unwrap(), expected);
    }
    let missing = dir.path().join("no/such/dir/t.obj");
    assert!(matches!(
        write_mesh(&missing, &mesh, &heights, &placement, MeshFormat::Obj),
        Err(ExportError::Io(_))
    ));
}

#[test]
fn format_from_path() {
    let f = |p: &str| MeshFormat::from_path(Path::new(p));
    assert_eq!(f("out/terrain.glb"), Some(MeshFormat::Glb));
    assert_eq!(f("TERRAIN.GLB"), Some(MeshFormat::Glb));
    assert_eq!(f("a.b/terrain.Obj"), Some(MeshFormat::Obj));
    assert_eq!(f("terrain.obj"), Some(MeshFormat::Obj));
    assert_eq!(f("terrain.PLY"), Some(MeshFormat::Ply));
    assert_eq!(f("terrain.gltf"), None);
    assert_eq!(f("terrain.stl"), None);
    assert_eq!(f("terrain"), None);
    assert_eq!(f("glb"), None);
    assert_eq!(f(".glb"), None);
    assert_eq!(f("terrain.glb.tmp"), None);
    assert_eq!(f(""), None);
    assert_eq!(MeshFormat::Glb.name(), "glb");
    assert_eq!(MeshFormat::Obj.name(), "obj");
    assert_eq!(MeshFormat::Ply.name(), "ply");
}
