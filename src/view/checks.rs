//! What a frame is checked against: cracks (edges not shared the way a watertight mesh
//! shares them, or shared with different heights) and popping (how far the surface moves
//! at a vertex from one frame to the next).

use crate::mesh::cells::{Cell, CellTree};
use crate::mesh::triangulate::{cell_triangles, Scratch};
use crate::mesh::GridMesh;

use super::camera::View;
use super::selection::ViewTerrain;

/// A frame's mesh with a height (data units) for every vertex.
#[derive(Debug, Clone, Copy)]
pub struct Surface<'a> {
    /// The cells the mesh triangulates.
    pub tree: &'a CellTree,
    /// The mesh.
    pub mesh: &'a GridMesh,
    /// One height per vertex of `mesh`.
    pub heights: &'a [f64],
}

impl Surface<'_> {
    /// The height of vertex sample `s`, if it is a vertex (vertices are in sample order).
    fn vertex_height(&self, s: u32) -> Option<f64> {
        self.mesh
            .vertices
            .binary_search(&s)
            .ok()
            .map(|v| self.heights[v])
    }

    /// The surface's height above grid point (`x`, `y`): `None` where no cell covers it.
    pub fn height_at(
        &self,
        terrain: &ViewTerrain<'_>,
        x: usize,
        y: usize,
        scratch: &mut Scratch,
    ) -> Option<f64> {
        let s = (y * self.mesh.width + x) as u32;
        if let Some(z) = self.vertex_height(s) {
            return Some(z);
        }
        let cell = leaf_at(self.tree, x, y)?;
        let shape = terrain.shape(cell);
        let w = self.mesh.width;
        let mut found = None;
        cell_triangles(self.tree, cell, shape, scratch, &mut |t| {
            if found.is_some() {
                return;
            }
            let p = t.map(|s| ((s as usize % w) as f64, (s as usize / w) as f64));
            if let Some(weights) = barycentric(p, (x as f64, y as f64)) {
                let z = t.map(|s| self.vertex_height(s));
                if let [Some(a), Some(b), Some(c)] = z {
                    found = Some(weights[0] * a + weights[1] * b + weights[2] * c);
                }
            }
        });
        found
    }
}

/// Barycentric weights of `q` in triangle `p` (None outside it).
fn barycentric(p: [(f64, f64); 3], q: (f64, f64)) -> Option<[f64; 3]> {
    let cross = |a: (f64, f64), b: (f64, f64), c: (f64, f64)| {
        (b.0 - a.0) * (c.1 - a.1) - (b.1 - a.1) * (c.0 - a.0)
    };
    let area = cross(p[0], p[1], p[2]);
    if area == 0.0 {
        return None;
    }
    let w0 = cross(p[1], p[2], q) / area;
    let w1 = cross(p[2], p[0], q) / area;
    let w2 = 1.0 - w0 - w1;
    let eps = -1e-12;
    (w0 >= eps && w1 >= eps && w2 >= eps).then_some([w0, w1, w2])
}

/// A leaf of `tree` whose closed range holds grid point (`x`, `y`), if one does.
pub fn leaf_at(tree: &CellTree, x: usize, y: usize) -> Option<Cell> {
    let (nw, nh) = tree.nodes(0);
    [(0, 0), (1, 0), (0, 1), (1, 1)]
        .into_iter()
        .filter_map(|(a, b)| Some((x.checked_sub(a)?, y.checked_sub(b)?)))
        .filter(|&(cx, cy)| cx < nw && cy < nh)
        .find_map(|(cx, cy)| leaf_over(tree, cx, cy))
}

/// The leaf covering grid cell (`cx`, `cy`): `None` when it is a grid cell left out.
fn leaf_over(tree: &CellTree, cx: usize, cy: usize) -> Option<Cell> {
    let mut level = tree.levels();
    while level > 0 && tree.is_split(level, cx >> level, cy >> level) {
        level -= 1;
    }
    let cell = Cell::new(level, cx >> level, cy >> level);
    tree.is_meshed(cell).then_some(cell)
}

/// Counts the cracks of a frame: edges used by more than two triangles, edges used by
/// one triangle that do not lie on the grid's border, beside a void grid cell or across
/// one, and
/// shared edges whose two triangles see different heights at an end (the heights are
/// read per triangle corner).
pub fn count_cracks(
    terrain: &ViewTerrain<'_>,
    mesh: &GridMesh,
    corner_heights: impl Fn(usize, u32) -> f64,
) -> usize {
    let mut edges: Vec<(u64, f64, f64)> = Vec::with_capacity(mesh.triangles.len() * 3);
    for (t, tri) in mesh.triangles.iter().enumerate() {
        for k in 0..3 {
            let (a, b) = (tri[k], tri[(k + 1) % 3]);
            let (lo, hi) = (a.min(b), a.max(b));
            edges.push((
                (u64::from(lo) << 32) | u64::from(hi),
                corner_heights(t, lo),
                corner_heights(t, hi),
            ));
        }
    }
    edges.sort_unstable_by_key(|e| e.0);
    let mut cracks = 0;
    for run in edges.chunk_by(|a, b| a.0 == b.0) {
        let (lo, hi) = ((run[0].0 >> 32) as u32, run[0].0 as u32);
        cracks += match run.len() {
            1 => usize::from(!on_boundary(terrain, mesh, lo, hi)),
            2 => usize::from(run[0].1 != run[1].1 || run[0].2 != run[1].2),
            _ => 1,
        };
    }
    cracks
}

/// Whether the edge between vertices `a` and `b` may bound the mesh: along the grid's
/// border, a grid-cell side beside a void grid cell, or a void grid cell's diagonal.
fn on_boundary(terrain: &ViewTerrain<'_>, mesh: &GridMesh, a: u32, b: u32) -> bool {
    let ((xa, ya), (xb, yb)) = (mesh.vertex_position(a), mesh.vertex_position(b));
    let (w, h) = (mesh.width, mesh.height);
    if (xa == xb && (xa == 0 || xa == w - 1)) || (ya == yb && (ya == 0 || ya == h - 1)) {
        return true;
    }
    let beside: Vec<(usize, usize)> = if ya == yb && xa.abs_diff(xb) == 1 {
        let x = xa.min(xb);
        vec![(x, ya - 1), (x, ya)]
    } else if xa == xb && ya.abs_diff(yb) == 1 {
        let y = ya.min(yb);
        vec![(xa - 1, y), (xa, y)]
    } else if xa.abs_diff(xb) == 1 && ya.abs_diff(yb) == 1 {
        // The diagonal of a grid cell with three valid corners.
        vec![(xa.min(xb), ya.min(yb))]
    } else {
        return false;
    };
    beside.into_iter().any(|(i, j)| terrain.is_void(0, i, j))
}

/// The popping measure between two frames: the largest height change of the surface, in
/// world units, at any vertex of either frame that both cameras see (a vertex only one
/// frame has is compared with the other frame's surface at its place). Off-screen
/// regions coarsen as they leave the view, which no viewer sees.
pub fn max_jump(
    terrain: &ViewTerrain<'_>,
    before: Surface<'_>,
    after: Surface<'_>,
    cameras: [&View; 2],
) -> f64 {
    let mut scratch = Scratch::default();
    let heights = terrain.heights();
    let w = heights.width;
    let mut worst = 0.0f64;
    let samples = before.mesh.vertices.iter().chain(&after.mesh.vertices);
    for &s in samples {
        let (x, y) = (s as usize % w, s as usize / w);
        let p = terrain.world(x, y, heights.values[s as usize]);
        if cameras.iter().any(|c| c.outside_distance(p, p) > 0.0) {
            continue;
        }
        let a = before.height_at(terrain, x, y, &mut scratch);
        let b = after.height_at(terrain, x, y, &mut scratch);
        if let (Some(a), Some(b)) = (a, b) {
            worst = worst.max((a - b).abs());
        }
    }
    worst * terrain.placement().z_scale.abs()
}
