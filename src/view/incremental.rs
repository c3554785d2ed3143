//! Frame-to-frame split/merge (Lee et al.'s ping-pong buffers): the previous frame's
//! leaves are read from one buffer and the next frame's written to the other, visiting
//! only leaves whose decision may have changed instead of descending from the roots.
//!
//! Each leaf carries an *expiry*: how far the camera may travel before the leaf could
//! need a split or its parent a merge, in one measure of motion accumulated frame after
//! frame (see [`camera_motion`]): the eye's displacement plus the rotation angle times the
//! farthest terrain corner, which bounds how far any box distance, horizontal reach,
//! depth or frustum-plane distance moves. Those bound how much any node's ratio can
//! change; leaves whose expiry is still ahead are copied as they are. The others are
//! evaluated again: a leaf whose parent no longer splits merges up to the highest such
//! ancestor, a leaf that now splits is refined from there down. The result equals
//! [`ViewTerrain::select`] for the same camera (the property tests check it frame after
//! frame). The area rule has no such bound: every leaf is evaluated again each frame.

use super::camera::View;
use super::selection::{NodeView, Rule, ViewTerrain};
use crate::mesh::cells::{Cell, CellTree};

/// A selection kept from frame to frame.
#[derive(Debug)]
pub struct Incremental {
    rule: Rule,
    tree: CellTree,
    /// Expiry of every leaf of `tree` (accumulated motion), in the same order.
    expiry: Vec<f64>,
    /// The ping-pong buffers the next frame is written to.
    spare_cells: Vec<Cell>,
    spare_expiry: Vec<f64>,
    /// Camera motion accumulated since the first frame (see [`camera_motion`]).
    travelled: f64,
    last: View,
    /// Corners of the terrain's bounding box.
    extent: [glam::DVec3; 8],
    /// The last parent evaluated under the current view: a parent's leaves come one after
    /// another, so it is evaluated once for all of them. Cleared when the view changes.
    last_parent: std::cell::Cell<Option<(Cell, NodeView)>>,
}

/// What one update changed.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct UpdateStats {
    /// Leaves that split.
    pub split: usize,
    /// Nodes that became leaves by merging their subtree.
    pub merged: usize,
    /// Leaves evaluated again (their expiry had passed).
    pub revisited: usize,
}

/// Slack safety factor: decisions are re-evaluated slightly before the bound says.
const SAFETY: f64 = 0.999;

/// The accumulated motion `slack` after `travelled` (slightly early, by [`SAFETY`]).
#[inline]
fn after(travelled: f64, slack: f64) -> f64 {
    travelled + slack.max(0.0) * SAFETY
}

impl Incremental {
    /// The selection for `view` from scratch, ready to be updated.
    pub fn new(terrain: &ViewTerrain<'_>, view: &View, rule: Rule) -> Incremental {
        let (lo, hi) = terrain.extent();
        let extent = [0, 1, 2, 3, 4, 5, 6, 7].map(|k| {
            glam::DVec3::new(
                if k & 1 == 0 { lo.x } else { hi.x },
                if k & 2 == 0 { lo.y } else { hi.y },
                if k & 4 == 0 { lo.z } else { hi.z },
            )
        });
        let mut state = Incremental {
            rule,
            tree: terrain.select(view, rule),
            expiry: Vec::new(),
            spare_cells: Vec::new(),
            spare_expiry: Vec::new(),
            travelled: 0.0,
            last: *view,
            extent,
            last_parent: std::cell::Cell::new(None),
        };
        state.reset_expiry(terrain, view);
        state
    }

    /// The current selection.
    pub fn tree(&self) -> &CellTree {
        &self.tree
    }

    fn reset_expiry(&mut self, terrain: &ViewTerrain<'_>, view: &View) {
        self.last_parent.set(None);
        let leaves = self.tree.leaves().to_vec();
        let expiry = leaves
            .iter()
            .map(|&c| self.leaf_expiry(terrain, view, c, None))
            .collect();
        self.expiry = expiry;
    }

    /// Moves the selection to `view`.
    pub fn update(&mut self, terrain: &ViewTerrain<'_>, view: &View) -> UpdateStats {
        let motion = camera_motion(&self.last, view, &self.extent);
        self.last = *view;
        self.last_parent.set(None);
        if !motion.is_finite() {
            // A new projection: start again.
            let before = self.tree.leaves().len();
            self.tree = terrain.select(view, self.rule);
            self.reset_expiry(terrain, view);
            return UpdateStats {
                revisited: before,
                ..UpdateStats::default()
            };
        }
        self.travelled += motion;
        let mut old = std::mem::take(&mut self.spare_cells);
        self.tree.swap_leaves(&mut old);
        let mut cells = Vec::new();
        self.tree.swap_leaves(&mut cells);
        cells.clear();
        let old_expiry = std::mem::take(&mut self.expiry);
        let mut expiry = std::mem::take(&mut self.spare_expiry);
        expiry.clear();
        let mut stats = UpdateStats::default();
        for (&cell, &until) in old.iter().zip(&old_expiry) {
            if cells.last().is_some_and(|&last| contains(last, cell)) {
                continue; // merged into the last cell written
            }
            if until > self.travelled {
                cells.push(cell);
                expiry.push(until);
                continue;
            }
            stats.revisited += 1;
            self.revisit(terrain, view, cell, &mut cells, &mut expiry, &mut stats);
        }
        self.tree.swap_leaves(&mut cells);
        self.spare_cells = old;
        self.expiry = expiry;
        self.spare_expiry = old_expiry;
        stats
    }

    /// Re-decides leaf `cell`: merge up, split down, or keep with a new expiry.
    fn revisit(
        &mut self,
        terrain: &ViewTerrain<'_>,
        view: &View,
        cell: Cell,
        cells: &mut Vec<Cell>,
        expiry: &mut Vec<f64>,
        stats: &mut UpdateStats,
    ) {
        let top = self.merge_target(terrain, view, cell);
        if top != cell {
            while cells.last().is_some_and(|&c| contains(top, c)) {
                cells.pop();
                expiry.pop();
            }
            self.clear_subtree(top);
            stats.merged += 1;
            cells.push(top);
            expiry.push(self.leaf_expiry(terrain, view, top, None));
            return;
        }
        let own = (cell.level > 0).then(|| self.evaluate(terrain, view, cell));
        if let Some(own) = own.filter(|o| self.rule.splits(o.ratio)) {
            stats.split += 1;
            self.refine(terrain, view, (cell, own), cells, expiry);
        } else {
            cells.push(cell);
            expiry.push(self.leaf_expiry(terrain, view, cell, own));
        }
    }

    /// The highest ancestor-or-self of `cell` whose parent splits (or a root).
    fn merge_target(&self, terrain: &ViewTerrain<'_>, view: &View, cell: Cell) -> Cell {
        let mut top = cell;
        while top.level < terrain.levels() {
            let parent = parent_of(top);
            let (i, j) = parent.position();
            if terrain.is_void(parent.level, i, j)
                || self
                    .rule
                    .splits(self.evaluate_parent(terrain, view, parent).ratio)
            {
                break;
            }
            top = parent;
        }
        top
    }

    /// Clears the split bits of `top` and of every split node below it.
    fn clear_subtree(&mut self, top: Cell) {
        let mut stack = vec![top];
        while let Some(c) = stack.pop() {
            let (i, j) = c.position();
            if c.level == 0 || !self.tree.is_split(c.level, i, j) {
                continue;
            }
            self.tree.set_split(c, false);
            stack.extend(children(&self.tree, c));
        }
    }

    /// Splits `cell` (evaluated as `parent_view`) and refines its subtree from scratch,
    /// writing its leaves in depth-first order.
    fn refine(
        &mut self,
        terrain: &ViewTerrain<'_>,
        view: &View,
        (cell, parent_view): (Cell, NodeView),
        cells: &mut Vec<Cell>,
        expiry: &mut Vec<f64>,
    ) {
        self.tree.set_split(cell, true);
        let parent_slack = self.stay_split(terrain, cell, parent_view);
        for child in children(&self.tree, cell) {
            let (i, j) = child.position();
            let void = terrain.is_void(child.level, i, j);
            if child.level == 0 {
                if self.tree.is_meshed(child) {
                    cells.push(child);
                    expiry.push(after(self.travelled, parent_slack));
                }
                continue;
            }
            let own = self.evaluate(terrain, view, child);
            if void || self.rule.splits(own.ratio) {
                self.refine(terrain, view, (child, own), cells, expiry);
            } else {
                cells.push(child);
                let slack = self.stay_unsplit(own).min(parent_slack);
                expiry.push(after(self.travelled, slack));
            }
        }
    }

    fn evaluate(&self, terrain: &ViewTerrain<'_>, view: &View, cell: Cell) -> NodeView {
        let (i, j) = cell.position();
        terrain.evaluate(view, self.rule, cell.level, i, j)
    }

    /// [`Incremental::evaluate`] of `parent`, through the one-node cache `last_parent`.
    fn evaluate_parent(&self, terrain: &ViewTerrain<'_>, view: &View, parent: Cell) -> NodeView {
        if let Some((cell, node)) = self.last_parent.get() {
            if cell == parent {
                return node;
            }
        }
        let node = self.evaluate(terrain, view, parent);
        self.last_parent.set(Some((parent, node)));
        node
    }

    /// When leaf `cell` must next be looked at (`own`: its evaluation, if known).
    fn leaf_expiry(
        &self,
        terrain: &ViewTerrain<'_>,
        view: &View,
        cell: Cell,
        own: Option<NodeView>,
    ) -> f64 {
        let own_slack = if cell.level == 0 {
            f64::INFINITY
        } else {
            self.stay_unsplit(own.unwrap_or_else(|| self.evaluate(terrain, view, cell)))
        };
        let parent_slack = if cell.level >= terrain.levels() {
            f64::INFINITY
        } else {
            let parent = parent_of(cell);
            self.stay_split(terrain, parent, self.evaluate_parent(terrain, view, parent))
        };
        after(self.travelled, own_slack.min(parent_slack))
    }

    /// How far the camera may move (in [`camera_motion`]'s measure Δ) before a node that
    /// does not split (`r = φ·W·H/D² ≤ 1`) could. Reach and depth move by at most Δ and
    /// φ by at most Δ/m (m the margin), so `r' ≤ (φ + Δ/m)·W·(H + Δ)/(D − Δ)²` (φ stays
    /// 1 once it is), which stays ≤ 1 up to the first root of the quadratic. A box
    /// farther outside the frustum than its margin keeps φ = 0 (so `r = 0`) until the
    /// frustum has moved the difference.
    fn stay_unsplit(&self, node: NodeView) -> f64 {
        if !matches!(self.rule, Rule::ScreenSpace { .. }) {
            return 0.0;
        }
        let w = node.weight;
        if w == 0.0 {
            return f64::INFINITY;
        }
        let hidden = -node.clearance - node.margin;
        let growth = if node.frustum >= 1.0 {
            0.0
        } else {
            1.0 / node.margin
        };
        let (h, d) = (node.reach, node.depth);
        // (φ + gΔ)·W·(H + Δ) − (D − Δ)² = aΔ² + bΔ + c, c ≤ 0.
        let a = growth * w - 1.0;
        let b = w * (node.frustum + growth * h) + 2.0 * d;
        let c = node.frustum * w * h - d * d;
        let discriminant = b * b - 4.0 * a * c;
        let visible = if discriminant < 0.0 {
            d
        } else {
            (-2.0 * c / (b + discriminant.sqrt())).min(d)
        };
        visible.max(hidden)
    }

    /// How far the camera may move before a split node (`r > 1`) could stop splitting:
    /// `r' ≥ (φ − Δ/m)·W·(H − Δ)/(D + Δ)²`, or with φ' = 1 while the frustum moves less
    /// than the box's clearance, stays above 1 up to the first root of the quadratic.
    fn stay_split(&self, terrain: &ViewTerrain<'_>, cell: Cell, node: NodeView) -> f64 {
        let (i, j) = cell.position();
        if terrain.is_void(cell.level, i, j) {
            return f64::INFINITY;
        }
        if !matches!(self.rule, Rule::ScreenSpace { .. }) {
            return 0.0;
        }
        let general = split_holds(node, node.frustum, 1.0 / node.margin);
        if node.clearance > 0.0 {
            general.max(split_holds(node, 1.0, 0.0).min(node.clearance))
        } else {
            general
        }
    }
}

/// The first Δ > 0 at which `(φ − gΔ)·W·(H − Δ) − (D + Δ)²` (positive at 0) reaches 0.
fn split_holds(node: NodeView, frustum: f64, shrink: f64) -> f64 {
    let (w, h, d) = (node.weight, node.reach, node.depth);
    let a = shrink * w - 1.0;
    let b = -w * (frustum + shrink * h) - 2.0 * d;
    let c = frustum * w * h - d * d;
    if c <= 0.0 {
        return 0.0;
    }
    let discriminant = (b * b - 4.0 * a * c).max(0.0);
    2.0 * c / (-b + discriminant.sqrt())
}

/// An upper bound on how far box distances, horizontal reaches, depths and
/// frustum-plane distances (for points of the terrain box `extent`) move from `from` to
/// `to`: the eye's displacement plus the frame's rotation angle times the farthest
/// terrain corner. Infinite when the projection changed.
pub fn camera_motion(from: &View, to: &View, extent: &[glam::DVec3; 8]) -> f64 {
    if from.camera.fov_degrees != to.camera.fov_degrees
        || from.camera.viewport != to.camera.viewport
    {
        return f64::INFINITY;
    }
    let shift = from.camera.eye.distance(to.camera.eye);
    let angle = from.rotation_to(to);
    if angle == 0.0 {
        return shift;
    }
    let reach = extent
        .iter()
        .map(|p| p.distance(to.camera.eye))
        .fold(0.0, f64::max);
    // |n' − n| = 2 sin(θ/2) ≤ θ; a small margin covers rounding in the angle.
    shift + (angle * 1.001 + 1e-12) * reach
}

fn parent_of(cell: Cell) -> Cell {
    Cell::new(cell.level + 1, cell.i as usize / 2, cell.j as usize / 2)
}

/// Whether node `outer` contains node `inner` (or is it).
#[inline]
fn contains(outer: Cell, inner: Cell) -> bool {
    outer.level >= inner.level
        && inner.i >> (outer.level - inner.level) == outer.i
        && inner.j >> (outer.level - inner.level) == outer.j
}

/// The existing children of `cell`, in the tree's depth-first order.
fn children(tree: &CellTree, cell: Cell) -> impl Iterator<Item = Cell> {
    let (cw, ch) = tree.nodes(cell.level - 1);
    let (i, j) = cell.position();
    [(0, 0), (1, 0), (0, 1), (1, 1)]
        .into_iter()
        .map(move |(a, b)| (2 * i + a, 2 * j + b))
        .filter(move |&(ci, cj)| ci < cw && cj < ch)
        .map(move |(ci, cj)| Cell::new(cell.level - 1, ci, cj))
}
