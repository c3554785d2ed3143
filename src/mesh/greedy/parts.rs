//! A grid meshed towards a tolerance as independent rectangular parts, on every core.
//!
//! The grid is cut into parts about `PART_SIDE` samples a side (the cuts depend on its
//! size only, never on the thread count, so the mesh is the same on any machine). The
//! lines two parts share (seams) are fitted first, in one dimension: a seam's samples
//! get the vertices that bring its linear interpolation within the tolerance (split at
//! the worst sample until every piece is within). Both parts start from those vertices
//! on their shared sides and never insert another there (their samples are never
//! candidates), so every seam edge is the same on both sides and the union of the
//! parts' meshes is conforming. Each part is then meshed like the whole grid (greedy
//! insertion, resolving flips, error-lowering flips; seam edges are border edges, never
//! flipped), and the parts' meshes are joined in a fixed order.

use std::collections::HashMap;

use rayon::prelude::*;

use super::scan::{scan, Grid, Height, SharedSides};
use super::triangulation::NONE;
use super::{GreedyMesher, GreedyTarget};
use crate::mesh::GridMesh;

/// Parts are about this many samples a side.
const PART_SIDE: usize = 128;

/// The fewest fitted seam vertices a seam sample for a split (see [`dense_enough`]):
/// one a part side on average.
const MIN_SEAM_DENSITY: f64 = 1.0 / PART_SIDE as f64;

/// A seam is fitted this much closer than the tolerance (relative), so that the mesh's
/// planes, rounded differently, still find its samples within.
const SEAM_MARGIN: f64 = 1e-9;

/// One rectangle of the grid; its last column and row are the next parts' first.
#[derive(Debug, Clone)]
struct Part {
    /// First column and row in the grid.
    origin: (usize, usize),
    /// Samples per row and rows.
    size: (usize, usize),
    /// Sides shared with a neighbouring part.
    shared: SharedSides,
    /// Vertices fitted on each shared side (offsets along it from its first sample,
    /// ends excluded): first row, last column, last row, first column.
    seams: [Vec<usize>; 4],
}

/// Whether a `width × height` grid is cut into more than one part.
pub fn splits(width: usize, height: usize) -> bool {
    cuts(width).len() > 2 || cuts(height).len() > 2
}

/// The parts' boundaries along a side of `n` samples: `0 = c₀ < c₁ < … < c_k = n − 1`.
fn cuts(n: usize) -> Vec<usize> {
    let parts = ((n as f64 / PART_SIDE as f64).round() as usize).clamp(1, n.max(2) - 1);
    (0..=parts).map(|k| k * (n - 1) / parts).collect()
}

/// The mesh of `grid` with every valid sample within `tolerance` (nodata left out as
/// in one piece), the parts meshed in parallel, each with `passes` error-lowering
/// passes; `None` when the seams need too few vertices for the split to pay (see
/// `dense_enough`) or a part would strand a valid seam sample (see
/// `GreedyMesher::strands_shared_samples`).
pub fn mesh_in_parts<H: Height>(grid: &Grid<H>, tolerance: f64, passes: usize) -> Option<GridMesh> {
    let parts = layout(grid, tolerance * (1.0 - SEAM_MARGIN));
    if !dense_enough(&parts) {
        return None;
    }
    let meshes: Option<Vec<GridMesh>> = parts
        .par_iter()
        .map(|part| mesh_part(grid, part, tolerance, passes))
        .collect();
    Some(join(grid.width, grid.height, &parts, &meshes?))
}

/// Whether the seams hold at least [`MIN_SEAM_DENSITY`] fitted vertices a sample: a
/// coarse mesh would pay for the seams in triangles (srtm3_utm32_f32 crop513 at
/// E = 50, whose seams need no vertex: 13 triangles in parts against 10 in one piece
/// and Delatin's 10). The cheaper meshes, too, gain least from the split.
fn dense_enough(parts: &[Part]) -> bool {
    let (mut vertices, mut samples) = (0, 0);
    for part in parts {
        for (side, seam) in part.seams.iter().enumerate() {
            let shared = [
                part.shared.first_row,
                part.shared.last_column,
                part.shared.last_row,
                part.shared.first_column,
            ][side];
            if shared {
                vertices += seam.len();
                samples += if side % 2 == 0 {
                    part.size.0
                } else {
                    part.size.1
                };
            }
        }
    }
    vertices as f64 >= MIN_SEAM_DENSITY * samples as f64
}

/// The parts of `grid` with their seams fitted within `seam_tolerance`.
fn layout<H: Height>(grid: &Grid<H>, seam_tolerance: f64) -> Vec<Part> {
    let (columns, rows) = (cuts(grid.width), cuts(grid.height));
    let mut parts = Vec::new();
    for j in 0..rows.len() - 1 {
        for i in 0..columns.len() - 1 {
            let (x0, x1, y0, y1) = (columns[i], columns[i + 1], rows[j], rows[j + 1]);
            let shared = SharedSides {
                first_row: j > 0,
                last_column: i + 2 < columns.len(),
                last_row: j + 2 < rows.len(),
                first_column: i > 0,
            };
            let fit_row = |y: usize, on: bool| match on {
                true => fit_seam(grid, x1 - x0 + 1, |k| (x0 + k, y), seam_tolerance),
                false => Vec::new(),
            };
            let fit_column = |x: usize, on: bool| match on {
                true => fit_seam(grid, y1 - y0 + 1, |k| (x, y0 + k), seam_tolerance),
                false => Vec::new(),
            };
            parts.push(Part {
                origin: (x0, y0),
                size: (x1 - x0 + 1, y1 - y0 + 1),
                shared,
                seams: [
                    fit_row(y0, shared.first_row),
                    fit_column(x1, shared.last_column),
                    fit_row(y1, shared.last_row),
                    fit_column(x0, shared.first_column),
                ],
            });
        }
    }
    parts
}

/// The samples `1..n − 1` of the seam of `n` samples at grid points `point_at(k)` that
/// must be vertices: every valid one with nodata among its eight neighbours (so that
/// both parts cut the voids out beside it without a vertex on the seam), and within
/// each stretch of valid samples between those, the vertices that bring its linear
/// interpolation within `tolerance` ([`fit_line`]). Stretches between two vertices
/// hold only valid samples or only nodata. Sorted.
fn fit_seam<H: Height>(
    grid: &Grid<H>,
    n: usize,
    point_at: impl Fn(usize) -> (usize, usize),
    tolerance: f64,
) -> Vec<usize> {
    let sample_at = |k: usize| {
        let (x, y) = point_at(k);
        y * grid.width + x
    };
    let height_at = |k: usize| -> f64 { grid.heights[sample_at(k)].into() };
    if grid.has_no_nodata() {
        return fit_line(n, height_at, tolerance);
    }
    let valid = |k: usize| grid.is_valid(sample_at(k));
    let mut ends = vec![0];
    ends.extend((1..n - 1).filter(|&k| valid(k) && grid.next_to_nodata(sample_at(k))));
    ends.push(n - 1);
    let mut vertices = Vec::new();
    for piece in ends.windows(2) {
        let (a, b) = (piece[0], piece[1]);
        if b > a + 1 && valid(a) && valid(a + 1) && valid(b) {
            let fitted = fit_line(b - a + 1, |k| height_at(a + k), tolerance);
            vertices.extend(fitted.into_iter().map(|k| a + k));
        }
        if b < n - 1 {
            vertices.push(b);
        }
    }
    vertices
}

/// The samples `1..n − 1` of a line of `n` (heights `height_at`) that must be vertices
/// for its linear interpolation from the ends to be within `tolerance`: every piece
/// over it is split at its worst sample. Sorted.
fn fit_line(n: usize, height_at: impl Fn(usize) -> f64, tolerance: f64) -> Vec<usize> {
    let mut vertices = Vec::new();
    let mut pieces = vec![(0, n - 1)];
    while let Some((a, b)) = pieces.pop() {
        let (za, zb) = (height_at(a), height_at(b));
        let slope = (zb - za) / (b - a) as f64;
        let (mut worst, mut at) = (tolerance, None);
        for k in a + 1..b {
            let error = (za + slope * (k - a) as f64 - height_at(k)).abs();
            if error > worst {
                (worst, at) = (error, Some(k));
            }
        }
        if let Some(k) = at {
            vertices.push(k);
            pieces.extend_from_slice(&[(a, k), (k, b)]);
        }
    }
    vertices.sort_unstable();
    vertices
}

/// The mesh of one part (local sample indices); `None` when a triangle it leaves out
/// over nodata strands a valid sample of a shared side (see
/// [`GreedyMesher::strands_shared_samples`]).
fn mesh_part<H: Height>(
    grid: &Grid<H>,
    part: &Part,
    tolerance: f64,
    passes: usize,
) -> Option<GridMesh> {
    let ((x0, y0), (w, h)) = (part.origin, part.size);
    let mut heights = Vec::with_capacity(w * h);
    for y in y0..y0 + h {
        let row = y * grid.width + x0;
        heights.extend_from_slice(&grid.heights[row..row + w]);
    }
    let valid = part_validity(grid, part);
    let local = Grid::new(w, h, &heights, &valid).with_shared_sides(part.shared);
    let mut mesher = GreedyMesher::unassessed(local).with_resolving_flips();
    mesher.insert_seams(part);
    mesher.assess_touched();
    mesher.run(GreedyTarget::MaxError(tolerance));
    if mesher.strands_shared_samples() {
        return None;
    }
    Some(mesher.optimise_flips(Some(tolerance), passes).0)
}

/// The validity bits of `part`'s samples (a `BitVec<u64, Lsb0>`'s words).
fn part_validity<H: Height>(grid: &Grid<H>, part: &Part) -> Vec<u64> {
    let ((x0, y0), (w, h)) = (part.origin, part.size);
    if grid.has_no_nodata() {
        return vec![u64::MAX; (w * h).div_ceil(64)];
    }
    let mut valid = vec![0u64; (w * h).div_ceil(64)];
    for y in 0..h {
        for x in 0..w {
            if grid.is_valid((y0 + y) * grid.width + x0 + x) {
                let s = y * w + x;
                valid[s / 64] |= 1 << (s % 64);
            }
        }
    }
    valid
}

impl<H: Height> GreedyMesher<'_, H> {
    /// Inserts the fitted vertices of `part`'s shared sides (the rectangle's border,
    /// walked counter-clockwise: first row, last column, last row, first column),
    /// legalising after each; the triangles they touch are left to assess.
    fn insert_seams(&mut self, part: &Part) {
        let (w, h) = (part.size.0 as i64 - 1, part.size.1 as i64 - 1);
        for (side, seam) in part.seams.iter().enumerate() {
            if seam.is_empty() {
                continue;
            }
            // The rectangle's corners are vertices 0..4, side `k` runs from corner `k`.
            let mut edge = self.border_edge_from(side as u32, 0..self.tin.triangle_count() as u32);
            let mut offsets: Vec<i64> = seam.iter().map(|&k| k as i64).collect();
            if side >= 2 {
                offsets.reverse();
            }
            for k in offsets {
                let point = [(k, 0), (w, k), (k, h), (0, k)][side];
                let first = self.touched.len();
                let p = self.insert_point(point, Ok(edge));
                let touched: Vec<u32> = self.touched[first..].to_vec();
                edge = self.border_edge_from(p, touched);
            }
        }
    }

    /// Whether a triangle left out over nodata holds a valid sample of a shared side
    /// besides its corners: no part would cover it (its samples are never candidates),
    /// so the grid is then meshed in one piece. The seam fit makes this rare: a valid
    /// seam sample next to nodata is a vertex.
    fn strands_shared_samples(&self) -> bool {
        (0..self.triangle_count() as u32)
            .filter(|&t| self.assessments[t as usize].touches_void)
            .any(|t| {
                let v = self.tin.triangle_vertices(t);
                let corners = v.map(|v| self.grid.sample(v.point()));
                let mut stranded = false;
                scan(self.grid.width, v.map(|v| v.point()), [0.0; 3], |s, _| {
                    stranded |= self.grid.is_valid(s)
                        && !self.grid.may_be_candidate(s)
                        && !corners.contains(&s);
                });
                stranded
            })
    }

    /// The border half-edge starting at vertex `v` among `triangles`.
    fn border_edge_from(&self, v: u32, triangles: impl IntoIterator<Item = u32>) -> u32 {
        triangles
            .into_iter()
            .flat_map(|t| 3 * t..3 * t + 3)
            .find(|&e| self.tin.corners[e as usize] == v && self.tin.twins[e as usize] == NONE)
            .expect("a vertex on the border starts one border half-edge")
    }
}

/// The parts' meshes as one mesh of the `width × height` grid: vertices on a part's
/// outline are merged with the same sample's in earlier parts.
fn join(width: usize, height: usize, parts: &[Part], meshes: &[GridMesh]) -> GridMesh {
    let mut joined = GridMesh {
        width,
        height,
        vertices: Vec::new(),
        triangles: Vec::new(),
    };
    let mut on_outlines: HashMap<u32, u32> = HashMap::new();
    for (part, mesh) in parts.iter().zip(meshes) {
        let ((x0, y0), (w, h)) = (part.origin, part.size);
        let index: Vec<u32> = (0..mesh.vertices.len() as u32)
            .map(|v| {
                let (x, y) = mesh.vertex_position(v);
                let sample = ((y0 + y) * width + x0 + x) as u32;
                let fresh = joined.vertices.len() as u32;
                let on_outline = x == 0 || y == 0 || x == w - 1 || y == h - 1;
                let at = match on_outline {
                    true => *on_outlines.entry(sample).or_insert(fresh),
                    false => fresh,
                };
                if at == fresh {
                    joined.vertices.push(sample);
                }
                at
            })
            .collect();
        let triangles = mesh.triangles.iter().map(|t| t.map(|v| index[v as usize]));
        joined.triangles.extend(triangles);
    }
    joined
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::greedy::triangulation::orient;
    use crate::mesh::rasterise::mesh_error;
    use bitvec::prelude::*;

    /// Ridges oblique to the grid and to the seams.
    fn terrain(w: usize, h: usize) -> Vec<f64> {
        (0..w * h)
            .map(|s| {
                let (x, y) = ((s % w) as f64, (s / w) as f64);
                60.0 * (-(x - 0.7 * y - 40.0).powi(2) / 200.0).exp()
                    + 8.0 * (x / 11.0).sin() * (y / 7.0).cos()
                    + 0.02 * ((x * 12.9898 + y * 78.233).sin() * 43758.5).fract()
            })
            .collect()
    }

    /// Every triangle counter-clockwise, their areas adding up to the rectangle's, and
    /// every edge either on the rectangle's border or met by the opposite edge of
    /// another triangle (no T-junction, no overlap).
    fn assert_conforming(mesh: &GridMesh) {
        let point = |v: u32| {
            let (x, y) = mesh.vertex_position(v);
            (x as i64, y as i64)
        };
        let mut edges = HashMap::new();
        let mut area = 0;
        for t in &mesh.triangles {
            let twice = orient(point(t[0]), point(t[1]), point(t[2]));
            assert!(twice > 0, "triangle {t:?} is flipped");
            area += twice;
            for k in 0..3 {
                let edge = (
                    mesh.vertices[t[k] as usize],
                    mesh.vertices[t[(k + 1) % 3] as usize],
                );
                assert!(edges.insert(edge, t[k]).is_none(), "edge {edge:?} twice");
            }
        }
        let (w, h) = (mesh.width as i64 - 1, mesh.height as i64 - 1);
        assert_eq!(area, 2 * w * h);
        for (&(a, b), &from) in &edges {
            if edges.contains_key(&(b, a)) {
                continue;
            }
            let to = mesh.vertices.iter().position(|&s| s == b).unwrap() as u32;
            let (p, q) = (point(from), point(to));
            let on_border =
                (p.0 == q.0 && (p.0 == 0 || p.0 == w)) || (p.1 == q.1 && (p.1 == 0 || p.1 == h));
            assert!(on_border, "edge {p:?}-{q:?} has one side only");
        }
    }

    #[test]
    fn cuts_span_the_side_in_parts_of_about_the_part_side() {
        assert_eq!(cuts(2), [0, 1]);
        assert_eq!(cuts(150), [0, 149]);
        assert_eq!(cuts(513), [0, 128, 256, 384, 512]);
        let cut = cuts(2000);
        assert_eq!((cut.len(), cut[0], cut[cut.len() - 1]), (17, 0, 1999));
        assert!(cut.windows(2).all(|c| (120..=136).contains(&(c[1] - c[0]))));
        assert!(!splits(150, 150) && splits(300, 100) && splits(100, 300));
    }

    #[test]
    fn a_fitted_line_is_within_its_tolerance_between_its_vertices() {
        let heights: Vec<f64> = (0..200).map(|k| (k as f64 / 9.0).sin() * 20.0).collect();
        for tolerance in [0.0, 0.5, 4.0] {
            let fit = fit_line(heights.len(), |k| heights[k], tolerance);
            assert!(fit.windows(2).all(|w| w[0] < w[1]) && fit[0] > 0);
            let mut ends = vec![0];
            ends.extend_from_slice(&fit);
            ends.push(heights.len() - 1);
            for piece in ends.windows(2) {
                let (a, b) = (piece[0], piece[1]);
                for k in a..=b {
                    let t = (k - a) as f64 / (b - a) as f64;
                    let z = heights[a] + t * (heights[b] - heights[a]);
                    assert!((z - heights[k]).abs() <= tolerance + 1e-9);
                }
            }
        }
        assert!(fit_line(50, |k| 3.0 * k as f64, 0.0).is_empty());
    }

    #[test]
    fn parts_join_into_one_conforming_mesh_within_the_tolerance() {
        let (w, h) = (530, 400);
        let heights = terrain(w, h);
        let valid = bitvec![u64, Lsb0; 1; w * h];
        let grid = Grid::new(w, h, &heights, valid.as_raw_slice());
        for tolerance in [0.5, 3.0] {
            let mesh = mesh_in_parts(&grid, tolerance, 2).unwrap();
            assert_conforming(&mesh);
            let error = mesh_error(&mesh, &heights, &heights, &valid);
            assert!(error.max_error <= tolerance, "{}", error.max_error);
            assert_eq!(error.uncovered_samples, 0);
        }
    }

    #[test]
    fn the_mesh_is_the_same_on_one_thread_and_on_several() {
        let (w, h) = (400, 600);
        let heights: Vec<f32> = terrain(w, h).iter().map(|&z| z as f32).collect();
        let valid = vec![u64::MAX; (w * h).div_ceil(64)];
        let grid = Grid::new(w, h, &heights, &valid);
        let on = |threads: usize| {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            pool.install(|| mesh_in_parts(&grid, 1.0, 2).unwrap())
        };
        let one = on(1);
        assert!(splits(w, h) && one.triangles.len() > 1000);
        assert_eq!(one, on(2));
        assert_eq!(one, on(3));
    }

    /// Nodata for [`terrain`]'s grid: an oblique collar on two sides, discs across
    /// seams and on a corner where four parts meet, speckle, and a valid line along a
    /// row seam between two rows of nodata (samples no triangle can cover).
    fn voids(w: usize, h: usize) -> BitVec<u64, Lsb0> {
        let (columns, rows) = (cuts(w), cuts(h));
        let mut valid = bitvec![u64, Lsb0; 1; w * h];
        let discs = [
            (150, 150, 20),
            (columns[1], 200, 9),
            (300, rows[1], 12),
            (columns[2], rows[2], 5),
        ];
        let mut noise = 0x9e37_79b9_7f4a_7c15u64;
        for s in 0..w * h {
            let (x, y) = (s % w, s / w);
            let collar = 30 * x < 180 + y || 23 * y < 92 + x;
            let in_disc = discs.iter().any(|&(cx, cy, r)| {
                let (dx, dy) = (x as i64 - cx as i64, y as i64 - cy as i64);
                dx * dx + dy * dy <= r * r
            });
            let line = (350..420).contains(&x) && (y + 1 == rows[1] || y == rows[1] + 1);
            noise ^= noise << 13;
            noise ^= noise >> 7;
            noise ^= noise << 17;
            let speckle = x > w / 2 && noise.is_multiple_of(300);
            if collar || in_disc || line || speckle {
                valid.set(s, false);
            }
        }
        valid
    }

    /// A mesh around nodata: every triangle counter-clockwise, no vertex and no covered
    /// sample at nodata, every edge once a direction, no vertex inside an edge (no
    /// T-junction), the areas within the rectangle's.
    fn assert_conforming_around_voids(mesh: &GridMesh, valid: &BitSlice<u64, Lsb0>) {
        let point = |v: u32| {
            let (x, y) = mesh.vertex_position(v);
            (x as i64, y as i64)
        };
        let vertices: std::collections::HashSet<(i64, i64)> =
            (0..mesh.vertices.len() as u32).map(point).collect();
        assert!(mesh.vertices.iter().all(|&s| valid[s as usize]));
        let (mut edges, mut area) = (std::collections::HashSet::new(), 0);
        for t in &mesh.triangles {
            let p = t.map(point);
            let twice = orient(p[0], p[1], p[2]);
            assert!(twice > 0, "triangle {p:?} is flipped");
            area += twice;
            for k in 0..3 {
                let (a, b) = (p[k], p[(k + 1) % 3]);
                assert!(edges.insert((a, b)), "edge {a:?}-{b:?} twice");
                let (dx, dy) = (b.0 - a.0, b.1 - a.1);
                let steps = gcd(dx.unsigned_abs(), dy.unsigned_abs()) as i64;
                for j in 1..steps {
                    let inside = (a.0 + j * dx / steps, a.1 + j * dy / steps);
                    assert!(!vertices.contains(&inside), "{inside:?} inside {a:?}-{b:?}");
                }
            }
        }
        assert!(area <= 2 * (mesh.width as i64 - 1) * (mesh.height as i64 - 1));
        let heights = vec![0.0; mesh.width * mesh.height];
        let (_, covered) = crate::mesh::rasterise::rasterise(mesh, &heights);
        assert!(covered.iter_ones().all(|s| valid[s]), "nodata covered");
    }

    /// Greatest common divisor.
    fn gcd(a: u64, b: u64) -> u64 {
        if b == 0 {
            a
        } else {
            gcd(b, a % b)
        }
    }

    /// Valid samples with no nodata among their eight neighbours.
    fn away_from_nodata(w: usize, h: usize, valid: &BitSlice<u64, Lsb0>) -> BitVec<u64, Lsb0> {
        let words = valid.to_bitvec().into_vec();
        let heights = vec![0.0; w * h];
        let grid = Grid::new(w, h, &heights, &words);
        (0..w * h)
            .map(|s| valid[s] && !grid.next_to_nodata(s))
            .collect()
    }

    #[test]
    fn parts_around_nodata_conform_hold_the_tolerance_and_cover_what_they_can() {
        let (w, h) = (530, 400);
        let heights = terrain(w, h);
        let valid = voids(w, h);
        let words = valid.as_raw_slice();
        let grid = Grid::new(w, h, &heights, words);
        let away = away_from_nodata(w, h, &valid);
        for tolerance in [0.5, 3.0] {
            let mesh = mesh_in_parts(&grid, tolerance, 2).expect("split in parts");
            assert_conforming_around_voids(&mesh, &valid);
            let error = mesh_error(&mesh, &heights, &heights, &valid);
            assert!(error.max_error <= tolerance, "{}", error.max_error);
            let (_, covered) = crate::mesh::rasterise::rasterise(&mesh, &heights);
            let stranded = (away.clone() & !covered).count_ones();
            assert_eq!(
                stranded, 0,
                "E = {tolerance}: valid samples away from nodata"
            );
        }
    }

    #[test]
    fn parts_around_nodata_are_the_same_on_one_thread_and_on_several() {
        let (w, h) = (400, 530);
        let heights: Vec<f32> = terrain(w, h).iter().map(|&z| z as f32).collect();
        let valid = voids(w, h);
        let grid = Grid::new(w, h, &heights, valid.as_raw_slice());
        let on = |threads: usize| {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            pool.install(|| mesh_in_parts(&grid, 1.0, 2).expect("split in parts"))
        };
        let one = on(1);
        assert!(one.triangles.len() > 1000);
        assert_eq!(one, on(2));
        assert_eq!(one, on(3));
    }

    #[test]
    fn a_seam_sample_only_nodata_triangles_reach_is_stranded() {
        // 5 × 3, row 0 shared, valid only there and at the two lower corners: the
        // triangle (0, 0), (4, 0), (4, 2) holds nodata and, besides its corners, only
        // row 0's valid samples.
        let (w, h) = (5, 3);
        let heights = vec![0.0f64; w * h];
        let mut valid = bitvec![u64, Lsb0; 0; w * h];
        for s in [0, 1, 2, 3, 4, 2 * w, 3 * w - 1] {
            valid.set(s, true);
        }
        let shared = SharedSides {
            first_row: true,
            ..SharedSides::default()
        };
        let grid = Grid::new(w, h, &heights, valid.as_raw_slice()).with_shared_sides(shared);
        let mut mesher = GreedyMesher::new(grid).unwrap();
        mesher.run(GreedyTarget::MaxError(1.0));
        assert!(mesher.strands_shared_samples());
        let unshared = Grid::new(w, h, &heights, valid.as_raw_slice());
        let mut mesher = GreedyMesher::new(unshared).unwrap();
        mesher.run(GreedyTarget::MaxError(1.0));
        assert!(!mesher.strands_shared_samples());
    }
}
