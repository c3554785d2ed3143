//! The mesh from the zerotree: quadtree cells from the decoder's significance map, a
//! crack-free triangulation of them, its error against a DEM, and mesh files.
//!
//! Pipeline, one module per stage: [`cells`] (which quadtree nodes split: by the
//! zerotree at a threshold, by the paper's own-coefficient rule, or by a height tolerance,
//! with nodata forcing splits) → [`triangulate`] (every cell with the vertices its smaller
//! neighbours put on its edges, found first by [`vertex_set`]) → [`GridMesh`] →
//! [`export`] (glTF binary, OBJ, PLY).
//! [`rasterise`] puts a mesh back onto the grid to measure it.

pub mod cells;
pub mod export;
pub mod frame;
pub mod greedy;
pub mod pyramid;
pub mod qem;
pub mod rasterise;
pub mod tiled;
pub mod triangulate;
pub mod varres;
pub mod vertex_set;

use bitvec::prelude::*;
use wavemesh_codec::SignificanceMap;

use cells::{significant, too_rough, Across, CellTree, Side, SplitRule};
use pyramid::{DiagonalPyramid, ErrorPyramid, Heights, Shape, VoidPyramid};
use rasterise::rasterise_triangle;
use triangulate::{cell_triangles, Scratch};

/// A triangle mesh over a `width × height` sample grid: every vertex is a grid sample.
///
/// Triangles wind counter-clockwise in the grid frame (x = column, y = row, z up): for
/// each, `(b − a) × (c − a)` has a positive z component with a, b, c as (column, row).
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct GridMesh {
    /// Samples per row of the grid.
    pub width: usize,
    /// Rows of the grid.
    pub height: usize,
    /// The sample index (`row · width + column`) of every vertex.
    pub vertices: Vec<u32>,
    /// Vertex indices of every triangle.
    pub triangles: Vec<[u32; 3]>,
}

impl GridMesh {
    /// Column and row of vertex `v`.
    pub fn vertex_position(&self, v: u32) -> (usize, usize) {
        let s = self.vertices[v as usize] as usize;
        (s % self.width, s / self.width)
    }

    /// Bytes the mesh holds in memory (vertex and triangle arrays).
    pub fn heap_bytes(&self) -> usize {
        self.vertices.len() * 4 + self.triangles.len() * 12
    }
}

/// Builds meshes of one decoded grid from its significance map, at any threshold,
/// triangle budget or height tolerance, without decoding again.
#[derive(Debug)]
pub struct Mesher<'a> {
    map: &'a SignificanceMap,
    heights: Heights<'a>,
    voids: Option<VoidPyramid>,
    errors: Option<ErrorPyramid>,
    /// The threshold cells' diagonals (each level computed on first use).
    diagonals: DiagonalPyramid<'a>,
    fine_borders: FineBorders,
}

/// Sides of the grid along which every sample is a vertex: the cells along them are
/// triangulated with every sample of their side on it, as if single grid cells lay
/// across. Two meshes of grids that share such a side then have the same vertices and
/// edges along it, whatever their interiors (tiles of one DEM).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct FineBorders {
    /// The first row.
    pub top: bool,
    /// The last column.
    pub right: bool,
    /// The last row.
    pub bottom: bool,
    /// The first column.
    pub left: bool,
}

/// What a mesh is asked to meet.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum MeshTarget {
    /// The zerotree partition at threshold `2^plane`.
    Plane(u32),
    /// The most triangles at most this many, searched over the thresholds.
    Triangles(usize),
    /// No sample of the heights farther than this from the mesh (data units).
    Tolerance(f64),
    /// The most triangles at most this many, searched over height tolerances.
    TrianglesByTolerance(usize),
}

/// A partition and its triangulation, with what chose it.
#[derive(Debug, Clone)]
pub struct MeshResult {
    /// The cells.
    pub tree: CellTree,
    /// The triangles.
    pub mesh: GridMesh,
    /// The threshold plane of the zerotree partition, when one was used.
    pub plane: Option<u32>,
    /// The height tolerance, when one was used.
    pub tolerance: Option<f64>,
    /// Cells split after triangulation because their hanging vertices took them past the
    /// tolerance.
    pub refinement_splits: usize,
}

impl<'a> Mesher<'a> {
    /// A mesher for the grid `heights` (valid where `valid`) decoded with `map`.
    ///
    /// # Panics
    /// If the sizes of `map`, `heights` and `valid` differ.
    pub fn new(
        map: &'a SignificanceMap,
        heights: Heights<'a>,
        valid: &BitSlice<u64, Lsb0>,
    ) -> Mesher<'a> {
        assert_eq!((map.width(), map.height()), (heights.width, heights.height));
        assert_eq!(valid.len(), heights.values.len());
        let voids = VoidPyramid::new(heights.width, heights.height, map.levels(), valid);
        Mesher {
            map,
            heights,
            voids,
            errors: None,
            diagonals: DiagonalPyramid::new(heights, map.levels()),
            fine_borders: FineBorders::default(),
        }
    }

    /// The same mesher, with every sample along `sides` a vertex of every mesh it builds.
    pub fn with_fine_borders(self, sides: FineBorders) -> Mesher<'a> {
        Mesher {
            fine_borders: sides,
            ..self
        }
    }

    /// The heights meshes are built from.
    pub fn heights(&self) -> Heights<'a> {
        self.heights
    }

    /// The error pyramid (computed on first use).
    pub fn error_pyramid(&mut self) -> &ErrorPyramid {
        let (heights, levels, voids) = (self.heights, self.map.levels(), self.voids.as_ref());
        self.errors
            .get_or_insert_with(|| ErrorPyramid::new(heights, levels, voids))
    }

    /// The cell partition at threshold `2^plane` under `rule` (the search step).
    pub fn cells_at_plane(&self, plane: u32, rule: SplitRule) -> CellTree {
        let mut tree = CellTree::from_significance(self.map, plane, rule, self.voids.as_ref());
        tree.set_fine_borders(self.fine_borders);
        tree
    }

    /// Triangulates a threshold partition (the triangulation step), every cell as two
    /// triangles along the diagonal [`triangulate::centre_rule`] picks.
    pub fn triangulate(&self, tree: &CellTree) -> GridMesh {
        triangulate::triangulate(tree, self.heights, |cell| {
            triangulate::centre_rule(&self.diagonals, cell)
        })
    }

    /// The mesh meeting `target` (`rule` applies to the threshold searches; a tolerance
    /// is met on top of the zerotree partition at `base_plane`, if given).
    pub fn build(
        &mut self,
        target: MeshTarget,
        rule: SplitRule,
        base_plane: Option<u32>,
    ) -> MeshResult {
        match target {
            MeshTarget::Plane(plane) => self.at_plane(plane, rule),
            MeshTarget::Triangles(budget) => {
                // Triangles grow as the plane falls: find the lowest plane within budget.
                let top = u32::from(self.map.top());
                let mut best = self.at_plane(top, rule);
                let (mut lo, mut hi) = (0u32, top);
                while lo < hi {
                    let mid = (lo + hi) / 2;
                    let result = self.at_plane(mid, rule);
                    if result.mesh.triangles.len() <= budget {
                        hi = mid;
                        best = result;
                    } else {
                        lo = mid + 1;
                    }
                }
                best
            }
            MeshTarget::Tolerance(tolerance) => self.within(tolerance, base_plane, rule),
            MeshTarget::TrianglesByTolerance(budget) => {
                // Bisection on the tolerance; triangle counts are not strictly monotone
                // in it, so the answer is the largest mesh within budget seen.
                let top = f64::from(self.error_pyramid().top_error());
                let mut best = self.within(top, base_plane, rule);
                let (mut lo, mut hi) = (0.0, top);
                for _ in 0..40 {
                    if hi - lo <= 1e-6 * top.max(1e-9) {
                        break;
                    }
                    let mid = 0.5 * (lo + hi);
                    let result = self.within(mid, base_plane, rule);
                    let count = result.mesh.triangles.len();
                    if count <= budget {
                        hi = mid;
                        if count > best.mesh.triangles.len() {
                            best = result;
                        }
                    } else {
                        lo = mid;
                    }
                }
                best
            }
        }
    }

    fn at_plane(&self, plane: u32, rule: SplitRule) -> MeshResult {
        let tree = self.cells_at_plane(plane, rule);
        let mesh = self.triangulate(&tree);
        MeshResult {
            tree,
            mesh,
            plane: Some(plane),
            tolerance: None,
            refinement_splits: 0,
        }
    }

    /// The partition within `tolerance` of the heights at every sample: cells split by
    /// the error pyramid (and the zerotree at `base_plane`), then every cell whose hanging
    /// vertices take it past the tolerance split again until none does.
    fn within(&mut self, tolerance: f64, base_plane: Option<u32>, rule: SplitRule) -> MeshResult {
        self.error_pyramid();
        let errors = self.errors.as_ref().expect("computed above");
        let (map, heights, voids) = (self.map, self.heights, self.voids.as_ref());
        let test = |m: u32, i: usize, j: usize| {
            base_plane.is_some_and(|p| significant(map, p, rule, m, i, j))
                || too_rough(errors, tolerance, m, i, j)
        };
        // Leaves take the cheapest shape within the tolerance; a leaf of the zerotree
        // base that is not within it splits by the test above.
        let shape = |cell: cells::Cell| {
            if cell.level == 0 {
                Shape::Two(pyramid::Diagonal::Falling)
            } else {
                errors.shape_within(cell.level, cell.i as usize, cell.j as usize, tolerance)
            }
        };
        let (width, height) = (heights.width, heights.height);
        let levels = map.levels();
        let mut tree = CellTree::build(width, height, levels, voids, test);
        tree.set_fine_borders(self.fine_borders);
        let mut scratch = Scratch::default();
        let mut triangles: Vec<[u32; 3]> = Vec::new();
        let mut splits = 0;
        loop {
            let mut failed = Vec::new();
            // Fans take the side midpoints they need; a midpoint shared with a larger
            // leaf would be a T-junction, so such a fan splits instead.
            tree.clear_midpoints();
            let leaves: Vec<cells::Cell> = tree.leaves().to_vec();
            for &cell in leaves.iter().filter(|c| c.level > 0) {
                if shape(cell) != Shape::Fan {
                    continue;
                }
                for (k, side) in Side::ALL.into_iter().enumerate() {
                    let (i, j) = cell.position();
                    if !errors.fan_needs_midpoint(cell.level, i, j, k, tolerance) {
                        continue;
                    }
                    match tree.across(cell, side) {
                        Across::Border | Across::Leaf => tree.mark_midpoint(cell, side),
                        Across::Split => {}
                        Across::Larger => {
                            failed.push(cell);
                            break;
                        }
                    }
                }
            }
            // Cells with vertices on their sides (hanging or midpoints) may now miss.
            for &cell in leaves.iter().filter(|c| c.level > 0) {
                triangles.clear();
                let hanging = cell_triangles(&tree, cell, shape(cell), &mut scratch, &mut |t| {
                    triangles.push(t)
                });
                if hanging == 0 {
                    continue;
                }
                let mut worst = 0.0f64;
                for t in &triangles {
                    let corner = |s: u32| {
                        let s = s as usize;
                        (s % width, s / width, heights.values[s])
                    };
                    rasterise_triangle(
                        width,
                        [corner(t[0]), corner(t[1]), corner(t[2])],
                        |s, z| worst = worst.max((z - heights.values[s]).abs()),
                    );
                }
                if worst > tolerance {
                    failed.push(cell);
                }
            }
            if failed.is_empty() {
                break;
            }
            failed.sort_unstable();
            failed.dedup();
            splits += failed.len();
            for &cell in &failed {
                tree.force_split(cell);
            }
            tree.grow(voids, test);
        }
        let mesh = triangulate::triangulate(&tree, heights, shape);
        MeshResult {
            tree,
            mesh,
            plane: base_plane,
            tolerance: Some(tolerance),
            refinement_splits: splits,
        }
    }
}
