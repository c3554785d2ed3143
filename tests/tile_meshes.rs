//! `mesh --tile-meshes`: one glb per tile. Neighbouring tiles have the same border
//! vertices at bit-identical coordinates, their union is watertight along the seams,
//! every tile holds the tolerance at every sample, the bytes do not depend on the thread
//! count, and bad input leaves nothing behind.

mod support;

use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;

use gltf::buffer::Source;
use serde_json::Value;
use support::{json, s, scratch, shared_dem, wavemesh};

/// A grid sample: (column, row) in the whole DEM.
type Sample = (usize, usize);

/// One tile's glb read back: per vertex its stored `f32` coordinates (as bits) and the
/// sample it stands for; its triangles; its node translation.
struct TileGlb {
    bits: Vec<[u32; 3]>,
    samples: Vec<Sample>,
    triangles: Vec<[usize; 3]>,
    translation: [f32; 3],
}

/// The stored positions, indices and translation of a glb's one primitive.
fn read_glb(bytes: &[u8]) -> (Vec<[f32; 3]>, Vec<[usize; 3]>, [f32; 3]) {
    let gltf = gltf::Gltf::from_slice(bytes).expect("a valid glb");
    let node = gltf.document.nodes().next().expect("a node");
    let translation = node.transform().decomposed().0;
    let prim = node.mesh().expect("a mesh").primitives().next().unwrap();
    let blob = gltf.blob.as_deref();
    let reader = prim.reader(|b| match b.source() {
        Source::Bin => blob,
        Source::Uri(_) => None,
    });
    let positions: Vec<[f32; 3]> = reader.read_positions().expect("POSITION").collect();
    let indices: Vec<usize> = reader
        .read_indices()
        .expect("indices")
        .into_u32()
        .map(|i| i as usize)
        .collect();
    let triangles = indices
        .chunks_exact(3)
        .map(|t| [t[0], t[1], t[2]])
        .collect();
    (positions, triangles, translation)
}

/// Reads tile `file` of `folder`; `pixel` is the same tile written with `--xy pixel`,
/// whose coordinates name each vertex's sample (the vertex order does not depend on
/// the frame).
fn read_tile(folder: &Path, pixel: &Path, file: &str) -> TileGlb {
    let (positions, triangles, translation) = read_glb(&std::fs::read(folder.join(file)).unwrap());
    let (pixel_positions, pixel_triangles, t) = read_glb(&std::fs::read(pixel.join(file)).unwrap());
    let corners = |ts: &[[usize; 3]]| -> Vec<[usize; 3]> {
        ts.iter()
            .map(|t| {
                let mut t = *t;
                t.sort_unstable();
                t
            })
            .collect()
    };
    assert_eq!(
        corners(&triangles),
        corners(&pixel_triangles),
        "{file}: the frame changed the triangles"
    );
    let samples = pixel_positions
        .iter()
        .map(|p| {
            let (col, row) = (p[0] + t[0], -(p[2] + t[2]));
            assert!(col.fract() == 0.0 && row.fract() == 0.0 && col >= 0.0 && row >= 0.0);
            (col as usize, row as usize)
        })
        .collect();
    TileGlb {
        bits: positions.iter().map(|p| p.map(f32::to_bits)).collect(),
        samples,
        triangles,
        translation,
    }
}

/// Runs `mesh` with `--tile-meshes` and returns its JSON report.
fn mesh_tiles(dem: &Path, out: &Path, extra: &[&str]) -> Value {
    let mut args = vec!["mesh", s(dem), "-o", s(out), "--tile-meshes", "--json"];
    args.extend_from_slice(extra);
    json(&args)
}

/// Every tile of a run, by (row, column), read back with its pixel twin.
fn read_tiles(report: &Value, folder: &Path, pixel: &Path) -> BTreeMap<(usize, usize), TileGlb> {
    report["tiles"]
        .as_array()
        .unwrap()
        .iter()
        .map(|t| {
            let key = (
                t["row"].as_u64().unwrap() as usize,
                t["column"].as_u64().unwrap() as usize,
            );
            let file = t["file"].as_str().expect("every tile has a mesh");
            (key, read_tile(folder, pixel, file))
        })
        .collect()
}

/// The vertices of `tile` on the line where `on_line` holds, with their stored bits.
fn border_vertices(tile: &TileGlb, on_line: impl Fn(Sample) -> bool) -> BTreeMap<Sample, [u32; 3]> {
    let mut found = BTreeMap::new();
    for (k, &sample) in tile.samples.iter().enumerate() {
        if on_line(sample) {
            assert!(
                found.insert(sample, tile.bits[k]).is_none(),
                "vertex {sample:?} twice"
            );
        }
    }
    found
}

/// The edges of `tile` with both ends on the line, each with the number of triangles
/// that hold it.
fn border_edges(
    tile: &TileGlb,
    on_line: impl Fn(Sample) -> bool,
) -> BTreeMap<(Sample, Sample), usize> {
    let mut edges = BTreeMap::new();
    for t in &tile.triangles {
        for k in 0..3 {
            let (a, b) = (tile.samples[t[k]], tile.samples[t[(k + 1) % 3]]);
            if on_line(a) && on_line(b) {
                *edges.entry((a.min(b), a.max(b))).or_insert(0) += 1;
            }
        }
    }
    edges
}

/// Checks the seam between tiles `a` and `b` along the samples where `on_line` holds:
/// same vertices at the same stored bits, and the same edges, each in one triangle on
/// each side, joining consecutive vertices (no vertex inside another side's edge).
fn check_seam(a: &TileGlb, b: &TileGlb, on_line: impl Fn(Sample) -> bool + Copy, what: &str) {
    let (va, vb) = (border_vertices(a, on_line), border_vertices(b, on_line));
    assert!(!va.is_empty(), "{what}: no border vertex");
    assert_eq!(
        va.keys().collect::<Vec<_>>(),
        vb.keys().collect::<Vec<_>>(),
        "{what}: border vertex sets differ"
    );
    assert_eq!(va, vb, "{what}: border positions differ");
    let (ea, eb) = (border_edges(a, on_line), border_edges(b, on_line));
    assert_eq!(ea, eb, "{what}: border edges differ");
    assert!(
        ea.values().all(|&n| n == 1),
        "{what}: a border edge in two triangles"
    );
    let vertices: Vec<Sample> = va.keys().copied().collect();
    let consecutive: BTreeSet<(Sample, Sample)> =
        vertices.windows(2).map(|w| (w[0], w[1])).collect();
    assert_eq!(
        ea.keys().copied().collect::<BTreeSet<_>>(),
        consecutive,
        "{what}: the border edges do not join consecutive vertices"
    );
}

/// Checks every pair of neighbouring tiles of a run.
fn check_seams(report: &Value, tiles: &BTreeMap<(usize, usize), TileGlb>) {
    let (rows, columns) = (
        report["rows"].as_u64().unwrap() as usize,
        report["columns"].as_u64().unwrap() as usize,
    );
    let (tw, th) = (
        report["tile_width"].as_u64().unwrap() as usize,
        report["tile_height"].as_u64().unwrap() as usize,
    );
    assert!(rows >= 3 && columns >= 3, "a 3 × 3 grid at least");
    let translation = tiles[&(0, 0)].translation;
    let mut seams = 0;
    for (&(r, c), tile) in tiles {
        assert_eq!(
            tile.translation, translation,
            "tile ({r}, {c}) has another centre"
        );
        if c + 1 < columns {
            let x = (c + 1) * tw;
            let rows_of =
                r * th..=((r + 1) * th).min(report["height"].as_u64().unwrap() as usize - 1);
            let on = |(col, row): Sample| col == x && rows_of.contains(&row);
            check_seam(
                tile,
                &tiles[&(r, c + 1)],
                on,
                &format!("tiles ({r}, {c}) | ({r}, {})", c + 1),
            );
            seams += 1;
        }
        if r + 1 < rows {
            let y = (r + 1) * th;
            let cols_of =
                c * tw..=((c + 1) * tw).min(report["width"].as_u64().unwrap() as usize - 1);
            let on = |(col, row): Sample| row == y && cols_of.contains(&col);
            check_seam(
                tile,
                &tiles[&(r + 1, c)],
                on,
                &format!("tiles ({r}, {c}) / ({}, {c})", r + 1),
            );
            seams += 1;
        }
    }
    assert_eq!(seams, rows * (columns - 1) + columns * (rows - 1));
}

/// Largest distance of a sample from `tile`'s surface, with every sample of its window
/// (`x, y, width, height` in `index`) covered: heights from `dem` (width `w`).
fn tile_max_error(tile: &TileGlb, dem: &[f64], w: usize, entry: &Value) -> f64 {
    let get = |k: &str| entry[k].as_u64().unwrap() as usize;
    let (x0, y0, tw, th) = (get("x"), get("y"), get("width"), get("height"));
    let mut covered = vec![false; tw * th];
    let mut worst = 0.0f64;
    for t in &tile.triangles {
        let p = t.map(|k| {
            let (col, row) = tile.samples[k];
            (col as f64, row as f64, dem[row * w + col])
        });
        let (xs, ys) = (p.map(|q| q.0), p.map(|q| q.1));
        let area = (xs[1] - xs[0]) * (ys[2] - ys[0]) - (xs[2] - xs[0]) * (ys[1] - ys[0]);
        assert!(area != 0.0, "a degenerate triangle");
        let lo = |v: [f64; 3]| v.iter().copied().fold(f64::INFINITY, f64::min) as usize;
        let hi = |v: [f64; 3]| v.iter().copied().fold(0.0, f64::max) as usize;
        for row in lo(ys)..=hi(ys) {
            for col in lo(xs)..=hi(xs) {
                let (px, py) = (col as f64, row as f64);
                let l1 = ((xs[2] - xs[1]) * (py - ys[1]) - (px - xs[1]) * (ys[2] - ys[1])) / area;
                let l2 = ((xs[0] - xs[2]) * (py - ys[2]) - (px - xs[2]) * (ys[0] - ys[2])) / area;
                let l3 = 1.0 - l1 - l2;
                if l1 < -1e-12 || l2 < -1e-12 || l3 < -1e-12 {
                    continue;
                }
                let z = l1 * p[0].2 + l2 * p[1].2 + l3 * p[2].2;
                worst = worst.max((z - dem[row * w + col]).abs());
                covered[(row - y0) * tw + (col - x0)] = true;
            }
        }
    }
    assert!(
        covered.iter().all(|&c| c),
        "a sample of the tile at ({x0}, {y0}) is not covered"
    );
    worst
}

/// The heights of `dem` as `f64`, and its width.
fn heights(dem: &Path) -> (Vec<f64>, usize) {
    let raster = wavemesh::dem::read_dem(dem, &Default::default()).expect("the DEM reads");
    (raster.samples.to_f64(), raster.width)
}

/// Meshes `dem` by tiles (in its own frame and in pixels) and checks seams and the
/// tolerance `error` of every tile.
fn check_tiled_mesh(dem: &Path, tile: &str, error: f64, tag: &str) {
    let dir = scratch("tile_meshes");
    let (geo, pixel) = (dir.path().join("geo"), dir.path().join("pixel"));
    let e = error.to_string();
    let options = ["--tile", tile, "--mesh-error", e.as_str()];
    let report = mesh_tiles(dem, &geo, &options);
    mesh_tiles(dem, &pixel, &[&options[..], &["--xy", "pixel"]].concat());
    let tiles = read_tiles(&report, &geo, &pixel);
    check_seams(&report, &tiles);
    let (dem_heights, w) = heights(dem);
    for entry in report["tiles"].as_array().unwrap() {
        let key = (
            entry["row"].as_u64().unwrap() as usize,
            entry["column"].as_u64().unwrap() as usize,
        );
        let worst = tile_max_error(&tiles[&key], &dem_heights, w, entry);
        assert!(
            worst <= error + 1e-9,
            "{tag}: tile {key:?} is {worst} from a sample (bound {error})"
        );
        assert!((worst - entry["max_error"].as_f64().unwrap()).abs() <= 1e-6 * error.max(1.0));
    }
    let index: Value =
        serde_json::from_slice(&std::fs::read(geo.join("tiles.json")).unwrap()).unwrap();
    assert_eq!(
        index["tiles"], report["tiles"],
        "{tag}: the index lists the tiles"
    );
}

/// A small fractal DEM of `width × height` in `dir`.
fn synthetic(dir: &Path, width: usize, height: usize) -> std::path::PathBuf {
    let path = dir.join("synth.tif");
    let size = format!("{width}x{height}");
    support::stdout(&["synth", s(&path), "--size", &size, "--seed", "5"]);
    path
}

#[test]
fn synthetic_tiles_share_their_borders_and_hold_the_tolerance() {
    let dir = scratch("tile_meshes");
    let dem = synthetic(dir.path(), 300, 280);
    check_tiled_mesh(&dem, "100", 3.0, "synthetic");
}

#[test]
fn shared_dem_tiles_share_their_borders_and_hold_the_tolerance() {
    let Some(shared) = shared_dem("shared_dem_tiles_share_their_borders_and_hold_the_tolerance")
    else {
        return;
    };
    // Geographic (east-north-up metres), 1201² in 3 × 3 tiles of 401.
    check_tiled_mesh(
        &shared.join("srtm3_n57e011/srtm3_n57e011.tif"),
        "401",
        2.0,
        "srtm3_n57e011",
    );
}

#[test]
fn output_bytes_do_not_depend_on_threads_and_budgets_are_shared() {
    let dir = scratch("tile_meshes");
    let dem = synthetic(dir.path(), 300, 280);
    let runs: Vec<_> = ["1", "2"]
        .iter()
        .map(|threads| {
            let out = dir.path().join(format!("t{threads}"));
            mesh_tiles(
                &dem,
                &out,
                &[
                    "--tile",
                    "100",
                    "--triangles",
                    "20000",
                    "--threads",
                    threads,
                ],
            );
            out
        })
        .collect();
    let names = |d: &Path| {
        let mut v: Vec<_> = std::fs::read_dir(d)
            .unwrap()
            .map(|e| e.unwrap().file_name())
            .collect();
        v.sort();
        v
    };
    assert_eq!(names(&runs[0]), names(&runs[1]));
    assert_eq!(names(&runs[0]).len(), 10, "9 tiles and the index");
    for name in names(&runs[0]) {
        let (a, b) = (
            std::fs::read(runs[0].join(&name)).unwrap(),
            std::fs::read(runs[1].join(&name)).unwrap(),
        );
        assert!(a == b, "{name:?} differs between 1 and 2 threads");
    }
    let index: Value =
        serde_json::from_slice(&std::fs::read(runs[0].join("tiles.json")).unwrap()).unwrap();
    let total: u64 = index["tiles"]
        .as_array()
        .unwrap()
        .iter()
        .map(|t| t["triangles"].as_u64().unwrap())
        .sum();
    assert!(
        (10_000..=20_000).contains(&total),
        "{total} triangles for a budget of 20000"
    );
}

#[test]
fn blocks_narrower_than_the_raster_give_the_same_files() {
    use wavemesh::dem::{ReadOptions, RowBands};
    use wavemesh::mesh::tiled::{write_tile_meshes, TileMeshOptions, TileTarget};
    let dir = scratch("tile_meshes");
    let dem = dir.path().join("tiled.tif");
    support::stdout(&[
        "synth",
        s(&dem),
        "--size",
        "300x280",
        "--seed",
        "5",
        "--tile",
        "64",
    ]);
    let run = |block_width: usize| {
        let mut bands = RowBands::open(&dem, &ReadOptions::default()).unwrap();
        let info = bands.info().clone();
        let placement = wavemesh::mesh::export::Placement::pixel(1.0);
        let target = TileTarget::Tolerance {
            error: 3.0,
            plane: None,
        };
        let mut options = TileMeshOptions::new(&info, placement, target);
        (options.tile, options.block_width) = (100, block_width);
        let out = dir.path().join(format!("blocks-{block_width}"));
        let mut rows = Vec::new();
        write_tile_meshes(&mut bands, &out, &options, &mut |k| rows.push(k)).unwrap();
        assert_eq!(rows, [1, 2, 3], "each tile row reported once");
        out
    };
    // Tiles of 100 x 94, three across: blocks of one tile, of two, and whole rows.
    let runs = [run(100), run(200), run(usize::MAX)];
    for name in std::fs::read_dir(&runs[2])
        .unwrap()
        .map(|e| e.unwrap().file_name())
    {
        let whole = std::fs::read(runs[2].join(&name)).unwrap();
        for run in &runs[..2] {
            let blocked = std::fs::read(run.join(&name)).unwrap();
            assert!(blocked == whole, "{name:?} differs in {}", run.display());
        }
    }
}

/// Runs a `mesh --tile-meshes` that must fail with `code` and one line on stderr.
fn refused(args: &[&str], code: i32) -> String {
    let out = wavemesh(args);
    let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
    assert_eq!(out.status.code(), Some(code), "{args:?}: {stderr}");
    assert_eq!(stderr.trim_end().lines().count(), 1, "{args:?}: {stderr}");
    stderr
}

#[test]
fn bad_input_is_one_line_and_leaves_nothing() {
    let dir = scratch("tile_meshes");
    let dem = synthetic(dir.path(), 120, 90);
    let file = dir.path().join("file.glb");
    std::fs::write(&file, b"keep").unwrap();
    let out = dir.path().join("out");
    let tiled = |o: &Path, extra: &[&str]| {
        let mut args = vec!["mesh", s(&dem), "-o", s(o), "--tile-meshes"];
        args.extend_from_slice(extra);
        args.iter().map(|a| a.to_string()).collect::<Vec<_>>()
    };
    let run = |args: Vec<String>, code| {
        refused(&args.iter().map(String::as_str).collect::<Vec<_>>(), code)
    };
    assert!(run(tiled(&file, &[]), 4).contains("not a folder"));
    assert_eq!(std::fs::read(&file).unwrap(), b"keep");
    assert!(run(tiled(&out, &["--tile", "0"]), 2).contains("--tile"));
    run(tiled(&out, &["--bpp", "1"]), 2);
    run(tiled(Path::new("-"), &[]), 2);
    assert!(!out.exists());
    // All nodata: nothing to mesh, and no folder made.
    let voids = dir.path().join("voids.asc");
    let grid = "-9999 ".repeat(6) + "\n";
    let text = format!(
        "ncols 6\nnrows 5\nxllcorner 0\nyllcorner 0\ncellsize 1\nNODATA_value -9999\n{}",
        grid.repeat(5)
    );
    std::fs::write(&voids, text).unwrap();
    let args = [
        "mesh",
        s(&voids),
        "-o",
        s(&out),
        "--tile-meshes",
        "--tile",
        "2",
    ];
    assert!(refused(&args, 3).contains("nothing to mesh"));
    assert!(!out.exists(), "a failed run left its folder");
}
