//! View-dependent cell selection: per quadtree node, a ratio `r` of what the node misses
//! to what the view tolerates, and a split wherever `r` passes 1.
//!
//! Two rules, both read from what one decode gives (no second decode):
//! - **screen-space error** ([`Rule::ScreenSpace`]): `r = φ · e · f · H / (D² · τ)`, where
//!   `e` is the node's height error from the [`ErrorPyramid`] (its cell drawn as two
//!   triangles, saturated so that a parent's is at least its children's), `f` the pixels
//!   a unit spans at depth 1, `H` the largest horizontal distance from the eye to the
//!   node's bounding box (at least half the largest distance), `D` a lower bound on the
//!   depth of the box's points in view ([`View::seen_depth`]) and `τ` the tolerance in
//!   pixels: `e · f · H / D²` bounds the pixels a vertical error anywhere in the box
//!   spans on screen ([`View::vertical_error_pixels`]), so the node splits when its
//!   error may project to more than τ pixels.
//! - **projected area** ([`Rule::Area`], Yu, Lee & Ra 1997, eq. 4): the node's threshold is
//!   `T_i = a · (A_n / A_i) + b`, at least the decoder's `T`, with `A_i` the node's
//!   footprint projected on the view plane and `A_n` the viewport's area (pixels²); the
//!   node splits when its subtree's largest coefficient reaches `T_i` (from the
//!   [`SignificanceMap`]): `r = φ · 2^(plane − 1) / T_i ≥ 1`.
//!
//! `φ ∈ [0, 1]` is 1 for boxes meeting the view frustum and falls to 0 for boxes more than
//! their own half-diagonal outside it: regions out of view stay at the coarsest level, and
//! every quantity moves continuously with the camera (what geomorphing needs). Boxes,
//! errors, reaches and `φ` only grow from child to parent and depths only shrink, so a
//! split child always has a split parent and the selection is a quadtree partition;
//! the existing triangulation with hanging vertices makes it one crack-free mesh with
//! mixed cell sizes.

use bitvec::prelude::*;
use glam::{DVec2, DVec3};
use wavemesh_codec::significance::nodes_along;
use wavemesh_codec::SignificanceMap;

use super::camera::{box_distance, farthest_distance, horizontal_reach, View};
use super::ViewError;
use crate::mesh::cells::{Cell, CellTree};
use crate::mesh::export::Placement;
use crate::mesh::pyramid::{node_bounds, Diagonal, ErrorPyramid, Heights, Shape, VoidPyramid};
use crate::mesh::triangulate::triangulate;
use crate::mesh::GridMesh;

/// The least share of a height error counted however steeply it is seen (the sine of
/// 30°): the vertical foreshortening alone would let the error vanish under the eye,
/// where a wrong height still shows in shading and silhouettes, and would make ratios
/// there change faster with horizontal motion than geomorphing can blend.
const MIN_FORESHORTENING: f64 = 0.5;

/// How the view sets each node's threshold.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Rule {
    /// Split while a node's height error projects to more than `tau` pixels.
    ScreenSpace {
        /// Tolerance, pixels (> 0).
        tau: f64,
    },
    /// The seed paper's `T_i = a · (A_n / A_i) + b` on the zerotree.
    Area {
        /// Proportionality constant (≥ 0).
        a: f64,
        /// Threshold offset (≥ 0).
        b: f64,
    },
}

impl Rule {
    /// Checks the rule's constants.
    ///
    /// # Errors
    /// [`ViewError::Rule`] for a non-positive or non-finite τ, or negative or non-finite
    /// a, b.
    pub fn checked(self) -> Result<Rule, ViewError> {
        let ok = match self {
            Rule::ScreenSpace { tau } => tau.is_finite() && tau > 0.0,
            Rule::Area { a, b } => a.is_finite() && b.is_finite() && a >= 0.0 && b >= 0.0,
        };
        if ok {
            Ok(self)
        } else {
            Err(ViewError::Rule(format!(
                "{self:?}: tau must be positive, a and b non-negative, all finite"
            )))
        }
    }

    /// Whether a node with ratio `ratio` splits.
    #[inline]
    pub fn splits(self, ratio: f64) -> bool {
        match self {
            Rule::ScreenSpace { .. } => ratio > 1.0,
            Rule::Area { .. } => ratio >= 1.0,
        }
    }
}

/// The blend factor of a split node with ratio `ratio` (Röttger's `b = 2(1 − f)`, with
/// `f = 1 / r`): 0 where the node just split, 1 from twice the tolerance on.
#[inline]
pub fn blend_of_ratio(ratio: f64) -> f64 {
    (2.0 * (1.0 - 1.0 / ratio)).clamp(0.0, 1.0)
}

/// Per-node bounding heights and saturated error (world units).
#[derive(Debug, Clone, Copy, Default)]
struct NodeSummary {
    low: f32,
    high: f32,
    error: f32,
}

/// One node's evaluation under a view.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NodeView {
    /// What the node misses over what the view tolerates (splits past 1).
    pub ratio: f64,
    /// The frustum factor φ.
    pub frustum: f64,
    /// The distance outside the frustum over which φ falls from 1 to 0 (the box's
    /// half-diagonal).
    pub margin: f64,
    /// `e · f / τ` (screen-space rule; 0 for the area rule):
    /// `ratio = φ · weight · reach / depth²`.
    pub weight: f64,
    /// Largest horizontal distance from the eye to the box, at least
    /// `MIN_FORESHORTENING` times the largest distance.
    pub reach: f64,
    /// Largest horizontal distance from the eye to the box.
    pub horizontal: f64,
    /// Lower bound on the depth of the box's points in view ([`View::seen_depth`]).
    pub depth: f64,
    /// The box's [`View::frustum_clearance`].
    pub clearance: f64,
}

/// Everything the view-dependent mesher reads about one decoded grid, computed once:
/// per node its bounding box and saturated two-triangle error, and the void pyramid.
#[derive(Debug)]
pub struct ViewTerrain<'a> {
    heights: Heights<'a>,
    map: &'a SignificanceMap,
    voids: Option<VoidPyramid>,
    placement: Placement,
    decoder_threshold: f64,
    /// Index `m − 1` for level `m`, each level in Z order ([`z_order`]): the four
    /// children of a node are adjacent, and a depth-first walk reads memory in order.
    nodes: Vec<Vec<NodeSummary>>,
    /// World x/y of sample (0, 0) and the steps of one column and one row.
    affine: [DVec2; 3],
    /// Per node, whether it is cut along its rising diagonal (index `m − 1`, Z order).
    rising: Vec<BitVec<u64, Lsb0>>,
}

impl<'a> ViewTerrain<'a> {
    /// Summarises the grid `heights` (valid where `valid`) decoded with `map` down to
    /// threshold plane `decoded_plane`, placed in the world by `placement`.
    ///
    /// # Errors
    /// [`ViewError::SizeMismatch`] when the map, heights and validity differ in size.
    pub fn new(
        map: &'a SignificanceMap,
        heights: Heights<'a>,
        valid: &BitSlice<u64, Lsb0>,
        placement: Placement,
        decoded_plane: u32,
    ) -> Result<ViewTerrain<'a>, ViewError> {
        if (map.width(), map.height()) != (heights.width, heights.height)
            || valid.len() != heights.values.len()
            || heights.values.len() != heights.width * heights.height
        {
            return Err(ViewError::SizeMismatch);
        }
        let levels = map.levels();
        let voids = VoidPyramid::new(heights.width, heights.height, levels, valid);
        let errors = ErrorPyramid::new(heights, levels, voids.as_ref());
        let rising = choose_diagonals(heights, levels);
        let nodes = summarise(heights, valid, levels, &errors, &rising, placement.z_scale);
        let xy = |c: usize, r: usize| DVec2::from_slice(&placement.position(c, r, 0.0)[..2]);
        let origin = xy(0, 0);
        Ok(ViewTerrain {
            heights,
            map,
            voids,
            placement,
            decoder_threshold: 2f64.powi(decoded_plane.min(1000) as i32),
            nodes,
            affine: [origin, xy(1, 0) - origin, xy(0, 1) - origin],
            rising,
        })
    }

    /// The heights.
    pub fn heights(&self) -> Heights<'a> {
        self.heights
    }

    /// How samples are placed in the world.
    pub fn placement(&self) -> &Placement {
        &self.placement
    }

    /// Coarsest quadtree level.
    pub fn levels(&self) -> u32 {
        self.map.levels()
    }

    /// Whether node `(level, i, j)` touches nodata.
    #[inline]
    pub fn is_void(&self, level: u32, i: usize, j: usize) -> bool {
        self.voids.as_ref().is_some_and(|v| v.is_void(level, i, j))
    }

    /// World position of sample (`col`, `row`) at height `h` (data units).
    #[inline]
    pub fn world(&self, col: usize, row: usize, h: f64) -> DVec3 {
        DVec3::from_array(self.placement.position(col, row, h))
    }

    /// World bounding box of the whole terrain.
    pub fn extent(&self) -> (DVec3, DVec3) {
        let (w, h) = (self.heights.width, self.heights.height);
        let levels = self.levels();
        let (mut lo, mut hi) = (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY));
        for j in 0..nodes_along(h, levels) {
            for i in 0..nodes_along(w, levels) {
                let (a, b) = self.node_box(levels, i, j);
                lo = lo.min(a);
                hi = hi.max(b);
            }
        }
        (lo, hi)
    }

    /// World bounding box of node `(level, i, j)` (`level ≥ 1`; level 0 only for grids
    /// without levels, then flat at height 0).
    #[inline]
    pub fn node_box(&self, level: u32, i: usize, j: usize) -> (DVec3, DVec3) {
        let summary = if level == 0 {
            NodeSummary::default()
        } else {
            self.nodes[level as usize - 1][z_order(i, j)]
        };
        self.box_of(level, i, j, summary)
    }

    /// World bounding box of node `(level, i, j)` whose summary is `summary`.
    #[inline]
    fn box_of(&self, level: u32, i: usize, j: usize, summary: NodeSummary) -> (DVec3, DVec3) {
        let (x0, y0, x1, y1) = node_bounds(self.heights.width, self.heights.height, level, i, j);
        let (low, high) = (f64::from(summary.low), f64::from(summary.high));
        let [origin, col, row] = self.affine;
        let (a, b) = (origin + col * x0 as f64, origin + col * x1 as f64);
        let (c, d) = (row * y0 as f64, row * y1 as f64);
        let lo = (a + c).min(a + d).min(b + c).min(b + d);
        let hi = (a + c).max(a + d).max(b + c).max(b + d);
        (lo.extend(low), hi.extend(high))
    }

    /// Node `(level, i, j)` (`level ≥ 1`) under `view` and `rule`.
    #[inline]
    pub fn evaluate(&self, view: &View, rule: Rule, level: u32, i: usize, j: usize) -> NodeView {
        let summary = self.nodes[level as usize - 1][z_order(i, j)];
        let (lo, hi) = self.box_of(level, i, j, summary);
        let eye = view.camera.eye;
        let margin = 0.5 * lo.distance(hi);
        let clearance = view.frustum_clearance(lo, hi);
        let frustum = (1.0 + clearance.min(0.0) / margin.max(f64::MIN_POSITIVE)).clamp(0.0, 1.0);
        let horizontal = horizontal_reach(eye, lo, hi);
        let mut node = NodeView {
            ratio: 0.0,
            frustum,
            margin,
            weight: 0.0,
            reach: horizontal.max(MIN_FORESHORTENING * farthest_distance(eye, lo, hi)),
            horizontal,
            depth: view.seen_depth(lo, hi, box_distance(eye, lo, hi)),
            clearance,
        };
        match rule {
            Rule::ScreenSpace { tau } => {
                let error = f64::from(summary.error);
                node.weight = error * view.pixels_per_unit / tau;
                if frustum > 0.0 && node.weight > 0.0 {
                    node.ratio =
                        frustum * view.vertical_error_pixels(error, node.reach, node.depth) / tau;
                }
            }
            Rule::Area { a, b } => {
                if frustum > 0.0 {
                    node.ratio = frustum * self.area_ratio(view, a, b, level, i, j);
                }
            }
        }
        node
    }

    /// [`ViewTerrain::evaluate`]'s ratio alone, bit for bit, at less cost: with the
    /// screen-space rule the half-diagonal is only computed for boxes reaching outside
    /// the frustum, and the reach takes one square root (`max(√h², ½√f²) = √max(h², f²/4)`:
    /// the square root is monotone and correctly rounded, and halving is exact).
    #[inline]
    pub fn ratio(&self, view: &View, rule: Rule, level: u32, i: usize, j: usize) -> f64 {
        self.ratio_at(view, rule, level, i, j, z_order(i, j))
    }

    /// [`ViewTerrain::ratio`] of node `(level, i, j)` whose Z-order index is `z`.
    #[inline]
    pub(super) fn ratio_at(
        &self,
        view: &View,
        rule: Rule,
        level: u32,
        i: usize,
        j: usize,
        z: usize,
    ) -> f64 {
        let Rule::ScreenSpace { tau } = rule else {
            return self.evaluate(view, rule, level, i, j).ratio;
        };
        let summary = self.nodes[level as usize - 1][z];
        let error = f64::from(summary.error);
        let (lo, hi) = self.box_of(level, i, j, summary);
        let clearance = view.frustum_clearance(lo, hi);
        let frustum = if clearance >= 0.0 {
            1.0
        } else {
            let margin = 0.5 * lo.distance(hi);
            (1.0 + clearance.min(0.0) / margin.max(f64::MIN_POSITIVE)).clamp(0.0, 1.0)
        };
        if frustum > 0.0 && error * view.pixels_per_unit / tau > 0.0 {
            let eye = view.camera.eye;
            let far = (eye - lo).abs().max((hi - eye).abs());
            let horizontal = far.x * far.x + far.y * far.y;
            let farthest = horizontal + far.z * far.z;
            let quarter = MIN_FORESHORTENING * MIN_FORESHORTENING;
            let reach = horizontal.max(quarter * farthest).sqrt();
            let depth = view.seen_depth(lo, hi, box_distance(eye, lo, hi));
            frustum * view.vertical_error_pixels(error, reach, depth) / tau
        } else {
            0.0
        }
    }

    /// `2^(plane − 1) / T_i` for node `(level, i, j)`, 0 when nothing in its subtree is
    /// significant.
    fn area_ratio(&self, view: &View, a: f64, b: f64, level: u32, i: usize, j: usize) -> f64 {
        let plane = self.map.subtree_plane(level, i, j);
        if plane == 0 {
            return 0.0;
        }
        let (x0, y0, x1, y1) = node_bounds(self.heights.width, self.heights.height, level, i, j);
        let at =
            |x: usize, y: usize| self.world(x, y, self.heights.values[y * self.heights.width + x]);
        let quad = [at(x0, y0), at(x1, y0), at(x1, y1), at(x0, y1)];
        let screen = view.viewport_area();
        // A region reaching behind the eye covers the view.
        let area = view.projected_area(quad).unwrap_or(screen).max(1e-12);
        let threshold = (a * screen / area + b).max(self.decoder_threshold);
        2f64.powi(i32::from(plane) - 1) / threshold
    }

    /// Asks the processor to bring the summaries of leaf `cell` and of its parent into
    /// the cache ahead of their evaluation (a hint: nothing else changes).
    #[inline]
    pub fn prefetch(&self, cell: Cell) {
        let (i, j) = cell.position();
        let z = z_order(i, j);
        // The parent's position is the child's with its two lowest bits dropped.
        for (m, k) in [(cell.level, z), (cell.level + 1, z >> 2)] {
            if let Some(summary) = self
                .nodes
                .get((m as usize).wrapping_sub(1))
                .and_then(|l| l.get(k))
            {
                prefetch_read(summary);
            }
        }
    }

    /// Asks the processor to bring the summary of the node of level `level` (≥ 1) whose
    /// Z-order index is `z` into the cache ahead of its evaluation (a hint: nothing else
    /// changes).
    #[inline]
    pub(super) fn prefetch_node(&self, level: u32, z: usize) {
        if let Some(summary) = self.nodes[level as usize - 1].get(z) {
            prefetch_read(summary);
        }
    }

    /// Whether node `(level, i, j)` splits under `view` and `rule` (nodata aside).
    #[inline]
    pub fn splits(&self, view: &View, rule: Rule, level: u32, i: usize, j: usize) -> bool {
        rule.splits(self.evaluate(view, rule, level, i, j).ratio)
    }

    /// The selection for `view` from the roots down.
    pub fn select(&self, view: &View, rule: Rule) -> CellTree {
        let (w, h) = (self.heights.width, self.heights.height);
        CellTree::build(w, h, self.levels(), self.voids.as_ref(), |m, i, j| {
            self.splits(view, rule, m, i, j)
        })
    }

    /// The diagonal node `(level, i, j)` (`level ≥ 1`) is cut along.
    #[inline]
    pub fn diagonal(&self, level: u32, i: usize, j: usize) -> Diagonal {
        self.diagonal_at(level, z_order(i, j))
    }

    /// The diagonal the node of level `level` (≥ 1) whose Z-order index is `z` is cut
    /// along.
    #[inline]
    pub(super) fn diagonal_at(&self, level: u32, z: usize) -> Diagonal {
        if self.rising[level as usize - 1][z] {
            Diagonal::Rising
        } else {
            Diagonal::Falling
        }
    }

    /// How leaf `cell` is drawn: two triangles along its diagonal.
    #[inline]
    pub fn shape(&self, cell: Cell) -> Shape {
        if cell.level == 0 {
            Shape::Two(Diagonal::Falling)
        } else {
            let (i, j) = cell.position();
            Shape::Two(self.diagonal(cell.level, i, j))
        }
    }

    /// The triangles of a selection (every cell as two triangles along its diagonal, plus
    /// its hanging vertices).
    pub fn triangulate(&self, tree: &CellTree) -> GridMesh {
        triangulate(tree, self.heights, |cell: Cell| self.shape(cell))
    }
}

/// Hints the processor to load `value`'s cache line (no effect off x86-64).
#[inline]
pub(super) fn prefetch_read<T>(value: &T) {
    #[cfg(target_arch = "x86_64")]
    // SAFETY: a prefetch never faults nor writes; the pointer comes from a reference.
    unsafe {
        use std::arch::x86_64::{_mm_prefetch, _MM_HINT_T0};
        _mm_prefetch::<_MM_HINT_T0>(std::ptr::from_ref(value).cast());
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = value;
}

/// Per node of levels `1..=levels`: the lowest and highest valid height (times
/// `z_scale`) and the two-triangle error along the node's diagonal, saturated up the tree
/// (void nodes take their children's); each level in Z order (`rising` too).
fn summarise(
    heights: Heights<'_>,
    valid: &BitSlice<u64, Lsb0>,
    levels: u32,
    errors: &ErrorPyramid,
    rising: &[BitVec<u64, Lsb0>],
    z_scale: f64,
) -> Vec<Vec<NodeSummary>> {
    let (w, h) = (heights.width, heights.height);
    let mut out: Vec<Vec<NodeSummary>> = Vec::with_capacity(levels as usize);
    for m in 1..=levels {
        let (nw, nh) = (nodes_along(w, m), nodes_along(h, m));
        let mut level = Vec::with_capacity(nw * nh);
        for j in 0..nh {
            for i in 0..nw {
                let bounds = node_bounds(w, h, m, i, j);
                let diagonal = if rising[m as usize - 1][z_order(i, j)] {
                    Diagonal::Rising
                } else {
                    Diagonal::Falling
                };
                let own = errors.two_triangle_error(m, i, j, diagonal);
                let mut s = NodeSummary {
                    low: f32::INFINITY,
                    high: f32::NEG_INFINITY,
                    error: if own.is_finite() { own } else { 0.0 },
                };
                if m == 1 {
                    let (x0, y0, x1, y1) = bounds;
                    for y in y0..=y1 {
                        for x in x0..=x1 {
                            if valid[y * w + x] {
                                let z = heights.values[y * w + x] as f32;
                                s.low = s.low.min(z);
                                s.high = s.high.max(z);
                            }
                        }
                    }
                } else {
                    let (cw, ch) = (nodes_along(w, m - 1), nodes_along(h, m - 1));
                    for (ci, cj) in
                        [(0, 0), (1, 0), (0, 1), (1, 1)].map(|(a, b)| (2 * i + a, 2 * j + b))
                    {
                        if ci < cw && cj < ch {
                            let c = out[m as usize - 2][cj * cw + ci];
                            s.low = s.low.min(c.low);
                            s.high = s.high.max(c.high);
                            s.error = s.error.max(c.error);
                        }
                    }
                }
                level.push(s);
            }
        }
        out.push(level);
    }
    // World units: scale heights and errors (a negative scale swaps low and high).
    let scale = z_scale as f32;
    for s in out.iter_mut().flatten() {
        if s.low > s.high {
            (s.low, s.high) = (0.0, 0.0);
        }
        let (a, b) = (s.low * scale, s.high * scale);
        (s.low, s.high) = (a.min(b), a.max(b));
        s.error *= scale.abs();
    }
    out.iter()
        .zip(1..)
        .map(|(level, m)| in_z_order(level, nodes_along(w, m), nodes_along(h, m)))
        .collect()
}

/// The position of node `(i, j)` in its level's Z-order (Morton) array: the bits of `i`
/// and `j` interleaved.
#[inline]
pub(super) fn z_order(i: usize, j: usize) -> usize {
    spread_bits(i) | spread_bits(j) << 1
}

/// The low 32 bits of `v` moved to the even bit positions.
#[inline]
fn spread_bits(v: usize) -> usize {
    let mut v = v as u64 & 0xffff_ffff;
    v = (v | v << 16) & 0x0000_ffff_0000_ffff;
    v = (v | v << 8) & 0x00ff_00ff_00ff_00ff;
    v = (v | v << 4) & 0x0f0f_0f0f_0f0f_0f0f;
    v = (v | v << 2) & 0x3333_3333_3333_3333;
    v = (v | v << 1) & 0x5555_5555_5555_5555;
    v as usize
}

/// The row-major `nw × nh` array `rows` in Z order (slots off the grid hold the default).
fn in_z_order<T: Copy + Default>(rows: &[T], nw: usize, nh: usize) -> Vec<T> {
    let mut out = vec![T::default(); z_order(nw.max(1) - 1, nh.max(1) - 1) + 1];
    for (k, &value) in rows.iter().enumerate() {
        out[z_order(k % nw, k / nw)] = value;
    }
    out
}

/// Per node of levels `1..=levels` (index `m − 1`), whether it is cut along its rising
/// diagonal. The children its parent's diagonal crosses take the parent's, so that a
/// node's children, fresh from a split and still at their coarse heights, lie exactly on
/// the surface the node drew (no pop from a flipped diagonal); the others, and the roots,
/// take the diagonal through their centre sample's ridge or valley. Each level in Z order.
fn choose_diagonals(heights: Heights<'_>, levels: u32) -> Vec<BitVec<u64, Lsb0>> {
    let (w, h) = (heights.width, heights.height);
    let mut out: Vec<BitVec<u64, Lsb0>> = vec![BitVec::new(); levels as usize];
    for m in (1..=levels).rev() {
        let (nw, nh) = (nodes_along(w, m), nodes_along(h, m));
        let mut level = bitvec![u64, Lsb0; 0; nw * nh];
        for j in 0..nh {
            for i in 0..nw {
                let own = heights.diagonal(node_bounds(w, h, m, i, j)) == Diagonal::Rising;
                let rising = if m == levels {
                    own
                } else {
                    let parent = &out[m as usize];
                    let parent_rising = parent[(j / 2) * nodes_along(w, m + 1) + i / 2];
                    // Falling crosses the top-left and bottom-right children; rising the
                    // other two.
                    let crossed = (i % 2 == j % 2) != parent_rising;
                    if crossed {
                        parent_rising
                    } else {
                        own
                    }
                };
                level.set(j * nw + i, rising);
            }
        }
        out[m as usize - 1] = level;
    }
    out.iter()
        .zip(1..)
        .map(|(level, m)| {
            let (nw, nh) = (nodes_along(w, m), nodes_along(h, m));
            let mut z = bitvec![u64, Lsb0; 0; z_order(nw - 1, nh - 1) + 1];
            for k in level.iter_ones() {
                z.set(z_order(k % nw, k / nw), true);
            }
            z
        })
        .collect()
}
