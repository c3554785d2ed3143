//! Level of detail from one decode: the mesh of a decoded stream at a threshold, triangle
//! budget or height tolerance, measured phase by phase; and the seed paper's two tables
//! (one row per threshold or bit rate) for any DEM.

use std::time::Instant;

use bitvec::prelude::*;
use serde::Serialize;
use wavemesh_codec::format::physical_offset;
use wavemesh_codec::{decode, CodecError, DecodeOptions, Decoded, Encoded, Raster};

use crate::memory;
use crate::mesh::cells::SplitRule;
use crate::mesh::pyramid::Heights;
use crate::mesh::rasterise::{mesh_error, MeshError};
use crate::mesh::{GridMesh, MeshTarget, Mesher};

/// The heights and validity of a decoded raster, as the mesher reads them.
#[derive(Debug, Clone)]
pub struct Surface {
    /// Samples per row.
    pub width: usize,
    /// Rows.
    pub height: usize,
    /// Every sample as `f64` (nodata samples hold the nodata value).
    pub heights: Vec<f64>,
    /// Valid samples.
    pub valid: BitVec<u64, Lsb0>,
}

impl Surface {
    /// The surface of `raster`.
    pub fn of(raster: &Raster) -> Surface {
        let mut valid = bitvec![u64, Lsb0; 0; raster.len()];
        for i in 0..raster.len() {
            valid.set(i, raster.is_valid(i));
        }
        Surface {
            width: raster.width,
            height: raster.height,
            heights: raster.samples.to_f64(),
            valid,
        }
    }

    /// The heights as the mesher takes them.
    pub fn heights(&self) -> Heights<'_> {
        Heights {
            width: self.width,
            height: self.height,
            values: &self.heights,
        }
    }
}

/// The plane of the pass a decode was in when it stopped: the threshold of the decoder's
/// state (0 when the stream was decoded to the end).
pub fn decoded_plane(decoded: &Decoded) -> u32 {
    // After `k` complete passes from the top plane, the decoder is in the pass of plane
    // `top − k` (plane 0 once every pass is done; a stream the encoder cut stops inside
    // a pass like any prefix).
    let top = decoded.header.top_plane.map_or(0, u32::from);
    top.saturating_sub(decoded.passes_decoded)
}

/// The threshold plane for a threshold value `t`: `⌊log2 t⌋`, 0 below 2.
pub fn plane_of_threshold(t: f64) -> u32 {
    if t >= 2.0 {
        (t.log2().floor() as u32).min(62)
    } else {
        0
    }
}

/// A mesh with the time and heap each phase took.
#[derive(Debug, Clone)]
pub struct TimedMesh {
    /// The mesh.
    pub mesh: GridMesh,
    /// Threshold plane of the zerotree partition, if one was used.
    pub plane: Option<u32>,
    /// Height tolerance, if one was used.
    pub tolerance: Option<f64>,
    /// Cells the tolerance refinement split after triangulation.
    pub refinement_splits: usize,
    /// Leaves of the partition.
    pub cells: usize,
    /// Seconds to find the cells and triangulate them (and, for tolerances and budgets,
    /// the searches and refinement rounds).
    pub mesh_seconds: f64,
    /// Seconds to build the error pyramid (tolerances only).
    pub pyramid_seconds: f64,
    /// Heap peak of meshing, bytes.
    pub peak_heap_bytes: usize,
}

/// Builds the mesh of `surface` (decoded with `map`) meeting `target`.
pub fn build_mesh(
    map: &wavemesh_codec::SignificanceMap,
    surface: &Surface,
    target: MeshTarget,
    rule: SplitRule,
    base_plane: Option<u32>,
) -> TimedMesh {
    let ((result, pyramid_seconds, mesh_seconds), peak) = memory::measure(|| {
        let mut mesher = Mesher::new(map, surface.heights(), &surface.valid);
        let needs_pyramid = matches!(
            target,
            MeshTarget::Tolerance(_) | MeshTarget::TrianglesByTolerance(_)
        );
        let start = Instant::now();
        if needs_pyramid {
            mesher.error_pyramid();
        }
        let pyramid_seconds = start.elapsed().as_secs_f64();
        let start = Instant::now();
        let result = mesher.build(target, rule, base_plane);
        (result, pyramid_seconds, start.elapsed().as_secs_f64())
    });
    TimedMesh {
        cells: result.tree.leaves().len(),
        mesh: result.mesh,
        plane: result.plane,
        tolerance: result.tolerance,
        refinement_splits: result.refinement_splits,
        mesh_seconds,
        pyramid_seconds,
        peak_heap_bytes: peak,
    }
}

/// Bytes of a mesh in the seed paper's accounting: 18×3 bits a triangle, 12×3 a vertex.
pub fn paper_mesh_bytes(triangles: usize, vertices: usize) -> f64 {
    (triangles as f64 * 54.0 + vertices as f64 * 36.0) / 8.0
}

/// One row of the seed paper's Tables 1 and 2.
#[derive(Debug, Clone, Serialize)]
pub struct TableRow {
    /// Threshold plane `n` (threshold `2^n`).
    pub plane: u32,
    /// Threshold `2^n` in coefficient units.
    pub threshold: f64,
    /// Triangles of the mesh.
    pub triangles: usize,
    /// Vertices of the mesh.
    pub vertices: usize,
    /// Seconds to find the cells from the significance map.
    pub search_seconds: f64,
    /// Seconds to triangulate them.
    pub triangulation_seconds: f64,
    /// The mesh (vertex heights from the image decoded to this threshold) against the
    /// original DEM.
    pub mesh: MeshError,
    /// The image decoded to this threshold against the original DEM: PSNR, dB.
    pub image_psnr_db: f64,
    /// The image's RMSE, data units.
    pub image_rmse: f64,
    /// Triangles as a percentage of the full grid's `2·(w−1)·(h−1)`.
    pub remaining_percent: f64,
    /// Bytes of the stream decoded for this row.
    pub ezw_bytes: u64,
    /// Bits per sample of those bytes.
    pub bpp: f64,
    /// The mesh in the paper's accounting (18×3 bits a triangle, 12×3 a vertex), bytes.
    pub mesh_bytes_paper: f64,
    /// The mesh as wavemesh holds it in memory (u32 vertex samples, 3×u32 triangles).
    pub mesh_bytes_in_memory: usize,
    /// `mesh_bytes_paper / ezw_bytes`: what storing the stream instead of the mesh saves.
    pub saving_ratio: f64,
}

/// Which rows a table has.
#[derive(Debug, Clone, PartialEq)]
pub enum TableRows {
    /// One row per threshold value (rounded down to a pass plane).
    Thresholds(Vec<f64>),
    /// One row per bit rate: the stream's prefix of that many bits per sample, meshed at
    /// the decoder's state.
    BitRates(Vec<f64>),
    /// One row per pass of the stream.
    AllPasses,
}

/// The median of `values` (sorted in place; 0 when empty).
fn median(values: &mut [f64]) -> f64 {
    values.sort_by(f64::total_cmp);
    values.get(values.len() / 2).copied().unwrap_or(0.0)
}

/// The seed paper's tables for `original`, encoded as `encoded` (any mode), one row per
/// entry of `rows`, with the split `rule`; times are medians of `runs` repetitions.
pub fn paper_table(
    original: &Raster,
    encoded: &Encoded,
    rows: &TableRows,
    rule: SplitRule,
    runs: usize,
) -> Result<Vec<TableRow>, CodecError> {
    let header = &encoded.header;
    let payload_start = (encoded.header_len + header.mask_len as usize) as u64;
    let top = header.top_plane.map_or(0, u32::from);
    let file_len = encoded.bytes.len() as u64;
    let requests: Vec<DecodeOptions> = match rows {
        TableRows::Thresholds(ts) => ts
            .iter()
            .map(|&t| {
                let plane = plane_of_threshold(t).min(top);
                DecodeOptions::default().with_max_passes(Some(top - plane + 1))
            })
            .collect(),
        TableRows::AllPasses => (0..=top)
            .map(|k| DecodeOptions::default().with_max_passes(Some(k + 1)))
            .collect(),
        TableRows::BitRates(rates) => rates
            .iter()
            .map(|&r| {
                DecodeOptions::default()
                    .with_max_bytes(Some((r * original.len() as f64 / 8.0).floor() as u64))
            })
            .collect(),
    };
    let reference = Surface::of(original);
    let full_triangles = 2 * original.width.saturating_sub(1) * original.height.saturating_sub(1);
    let mut out = Vec::with_capacity(requests.len());
    for mut options in requests {
        options.significance_map = true;
        let decoded = decode(&encoded.bytes, &options)?;
        let map = decoded.significance.as_ref().expect("asked for");
        let plane = match options.max_passes {
            Some(passes) => top + 1 - passes,
            None => decoded_plane(&decoded),
        };
        let surface = Surface::of(&decoded.raster);
        let mesher = Mesher::new(map, surface.heights(), &surface.valid);
        // Times are medians of `runs` searches and triangulations.
        let (mut searches, mut triangulations) = (Vec::new(), Vec::new());
        let mut mesh = GridMesh::default();
        for _ in 0..runs.max(1) {
            let start = Instant::now();
            let tree = mesher.cells_at_plane(plane, rule);
            searches.push(start.elapsed().as_secs_f64());
            let start = Instant::now();
            mesh = mesher.triangulate(&tree);
            triangulations.push(start.elapsed().as_secs_f64());
        }
        let search_seconds = median(&mut searches);
        let triangulation_seconds = median(&mut triangulations);
        let error = mesh_error(
            &mesh,
            &surface.heights,
            &reference.heights,
            &reference.valid,
        );
        let image = crate::metrics::compare(original, &decoded.raster)
            .expect("the decoded raster has the original's size");
        let ezw_bytes = match options.max_passes {
            Some(passes) => header
                .passes
                .get(passes as usize - 1)
                .map_or(file_len, |p| payload_start + physical_offset(p.end_byte))
                .min(file_len),
            None => options.max_bytes.unwrap_or(file_len).min(file_len),
        };
        let paper = paper_mesh_bytes(mesh.triangles.len(), mesh.vertices.len());
        out.push(TableRow {
            plane,
            threshold: 2f64.powi(plane as i32),
            triangles: mesh.triangles.len(),
            vertices: mesh.vertices.len(),
            search_seconds,
            triangulation_seconds,
            mesh: error,
            image_psnr_db: image.psnr_db,
            image_rmse: image.rmse,
            remaining_percent: 100.0 * mesh.triangles.len() as f64 / full_triangles.max(1) as f64,
            ezw_bytes,
            bpp: crate::metrics::bits_per_sample(ezw_bytes, original.width, original.height),
            mesh_bytes_paper: paper,
            mesh_bytes_in_memory: mesh.heap_bytes(),
            saving_ratio: paper / ezw_bytes.max(1) as f64,
        });
    }
    Ok(out)
}

/// Table 1 and Table 2 as Markdown.
pub fn table_markdown(rows: &[TableRow]) -> String {
    let mut s = String::new();
    s.push_str("Table 1: threshold, triangles, vertices, search and triangulation time, mesh and decoded-image PSNR, remaining triangles\n\n");
    s.push_str("| threshold (plane) | triangles | vertices | search s | triangulation s | mesh PSNR dB | mesh RMSE | mesh max err | image PSNR dB | remaining % |\n");
    s.push_str("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n");
    for r in rows {
        s.push_str(&format!(
            "| 2^{} | {} | {} | {:.5} | {:.5} | {:.2} | {:.4} | {:.3} | {:.2} | {:.2} |\n",
            r.plane,
            r.triangles,
            r.vertices,
            r.search_seconds,
            r.triangulation_seconds,
            r.mesh.psnr_db,
            r.mesh.rmse,
            r.mesh.max_error,
            r.image_psnr_db,
            r.remaining_percent
        ));
    }
    s.push_str(&uncovered_note(rows));
    s.push_str("\nTable 2: bit rate and memory (paper accounting: 18×3 bits a triangle, 12×3 bits a vertex)\n\n");
    s.push_str("| threshold (plane) | bpp | mesh bytes (paper) | mesh bytes (in memory) | .ezw bytes | saving ratio |\n");
    s.push_str("|---|---:|---:|---:|---:|---:|\n");
    for r in rows {
        s.push_str(&format!(
            "| 2^{} | {:.4} | {:.0} | {} | {} | {:.1} |\n",
            r.plane, r.bpp, r.mesh_bytes_paper, r.mesh_bytes_in_memory, r.ezw_bytes, r.saving_ratio
        ));
    }
    s
}

/// Both tables as one CSV (a header line, one line per row).
pub fn table_csv(rows: &[TableRow]) -> String {
    let mut s = String::from(
        "plane,threshold,triangles,vertices,search_s,triangulation_s,mesh_psnr_db,mesh_rmse,mesh_max_error,image_psnr_db,image_rmse,remaining_percent,bpp,ezw_bytes,mesh_bytes_paper,mesh_bytes_in_memory,saving_ratio,mesh_uncovered_samples\n",
    );
    for r in rows {
        s.push_str(&format!(
            "{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{}\n",
            r.plane,
            r.threshold,
            r.triangles,
            r.vertices,
            r.search_seconds,
            r.triangulation_seconds,
            r.mesh.psnr_db,
            r.mesh.rmse,
            r.mesh.max_error,
            r.image_psnr_db,
            r.image_rmse,
            r.remaining_percent,
            r.bpp,
            r.ezw_bytes,
            r.mesh_bytes_paper,
            r.mesh_bytes_in_memory,
            r.saving_ratio,
            r.mesh.uncovered_samples
        ));
    }
    s
}

/// A line under Table 1 when meshes leave valid samples uncovered (cut off by nodata):
/// their errors are over the covered samples only. Empty otherwise.
fn uncovered_note(rows: &[TableRow]) -> String {
    let counts = rows.iter().map(|r| r.mesh.uncovered_samples);
    match (counts.clone().min(), counts.max()) {
        (Some(lo), Some(hi)) if hi > 0 => {
            let count = if lo == hi {
                hi.to_string()
            } else {
                format!("{lo} to {hi}")
            };
            format!("\nMesh errors are over the samples each mesh covers: {count} valid samples next to nodata are left uncovered and not measured.\n")
        }
        _ => String::new(),
    }
}
