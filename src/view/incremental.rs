//! Frame-to-frame split/merge (Lee et al.'s ping-pong buffers): the previous frame's
//! leaves are read from one buffer and the next frame's written to the other, visiting
//! only leaves whose decision may have changed instead of descending from the roots.
//!
//! Each leaf carries an *expiry*: how far the camera may travel before the leaf could
//! need a split or its parent a merge, in two measures of motion accumulated frame after
//! frame (see [`camera_motion`]): the eye's displacement, which bounds how far any box
//! distance moves, and that plus the rotation angle times the farthest terrain corner,
//! which bounds how far any frustum-plane distance moves. Those bound how much any
//! node's ratio can change; leaves whose expiry is still ahead are copied as they are. The others are evaluated again: a
//! leaf whose parent no longer splits merges up to the highest such ancestor, a leaf that
//! now splits is refined from there down. The result equals [`ViewTerrain::select`] for
//! the same camera (the property tests check it frame after frame). The area rule has no
//! such bound: every leaf is evaluated again each frame.

use super::camera::View;
use super::selection::{NodeView, Rule, ViewTerrain};
use crate::mesh::cells::{Cell, CellTree};

/// A selection kept from frame to frame.
#[derive(Debug)]
pub struct Incremental {
    rule: Rule,
    tree: CellTree,
    /// Expiry of every leaf of `tree`, in the same order.
    expiry: Vec<Expiry>,
    /// The ping-pong buffers the next frame is written to.
    spare_cells: Vec<Cell>,
    spare_expiry: Vec<Expiry>,
    /// Camera motion accumulated since the first frame.
    travelled: Expiry,
    last: View,
    /// Corners of the terrain's bounding box.
    extent: [glam::DVec3; 8],
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

/// Camera motion in the two measures: eye displacement (bounds box distances) and eye
/// displacement plus rotation times reach (bounds frustum-plane distances). Used both
/// for accumulated motion and for the point a leaf expires at.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Expiry {
    /// Box-distance measure.
    pub distance: f64,
    /// Frustum-plane measure.
    pub frustum: f64,
}

impl Expiry {
    const NEVER: Expiry = Expiry {
        distance: f64::INFINITY,
        frustum: f64::INFINITY,
    };
    const NOW: Expiry = Expiry {
        distance: 0.0,
        frustum: 0.0,
    };

    fn min(self, other: Expiry) -> Expiry {
        Expiry {
            distance: self.distance.min(other.distance),
            frustum: self.frustum.min(other.frustum),
        }
    }

    fn after(self, slack: Expiry) -> Expiry {
        Expiry {
            distance: self.distance + slack.distance.max(0.0) * SAFETY,
            frustum: self.frustum + slack.frustum.max(0.0) * SAFETY,
        }
    }

    /// Whether motion `travelled` is still short of this expiry.
    fn ahead_of(self, travelled: Expiry) -> bool {
        self.distance > travelled.distance && self.frustum > travelled.frustum
    }
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
            travelled: Expiry::NOW,
            last: *view,
            extent,
        };
        state.reset_expiry(terrain, view);
        state
    }

    /// The current selection.
    pub fn tree(&self) -> &CellTree {
        &self.tree
    }

    fn reset_expiry(&mut self, terrain: &ViewTerrain<'_>, view: &View) {
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
        if !motion.frustum.is_finite() {
            // A new projection: start again.
            let before = self.tree.leaves().len();
            self.tree = terrain.select(view, self.rule);
            self.reset_expiry(terrain, view);
            return UpdateStats {
                revisited: before,
                ..UpdateStats::default()
            };
        }
        self.travelled.distance += motion.distance;
        self.travelled.frustum += motion.frustum;
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
            if until.ahead_of(self.travelled) {
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
        expiry: &mut Vec<Expiry>,
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
        if own.is_some_and(|o| self.rule.splits(o.ratio)) {
            stats.split += 1;
            self.refine(terrain, view, cell, cells, expiry);
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
                || terrain.splits(view, self.rule, parent.level, i, j)
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

    /// Splits `cell` and refines its subtree from scratch, writing its leaves in
    /// depth-first order.
    fn refine(
        &mut self,
        terrain: &ViewTerrain<'_>,
        view: &View,
        cell: Cell,
        cells: &mut Vec<Cell>,
        expiry: &mut Vec<Expiry>,
    ) {
        self.tree.set_split(cell, true);
        let parent_view = self.evaluate(terrain, view, cell);
        let parent_slack = self.stay_split(terrain, cell, parent_view);
        for child in children(&self.tree, cell) {
            let (i, j) = child.position();
            let void = terrain.is_void(child.level, i, j);
            if child.level == 0 {
                if self.tree.is_meshed(child) {
                    cells.push(child);
                    expiry.push(self.travelled.after(parent_slack));
                }
                continue;
            }
            let own = self.evaluate(terrain, view, child);
            if void || self.rule.splits(own.ratio) {
                self.refine(terrain, view, child, cells, expiry);
            } else {
                cells.push(child);
                let slack = self.stay_unsplit(own).min(parent_slack);
                expiry.push(self.travelled.after(slack));
            }
        }
    }

    fn evaluate(&self, terrain: &ViewTerrain<'_>, view: &View, cell: Cell) -> NodeView {
        let (i, j) = cell.position();
        terrain.evaluate(view, self.rule, cell.level, i, j)
    }

    /// When leaf `cell` must next be looked at (`own`: its evaluation, if known).
    fn leaf_expiry(
        &self,
        terrain: &ViewTerrain<'_>,
        view: &View,
        cell: Cell,
        own: Option<NodeView>,
    ) -> Expiry {
        let own_slack = if cell.level == 0 {
            Expiry::NEVER
        } else {
            self.stay_unsplit(own.unwrap_or_else(|| self.evaluate(terrain, view, cell)))
        };
        let parent_slack = if cell.level >= terrain.levels() {
            Expiry::NEVER
        } else {
            let parent = parent_of(cell);
            self.stay_split(terrain, parent, self.evaluate(terrain, view, parent))
        };
        self.travelled.after(own_slack.min(parent_slack))
    }

    /// How far the camera may move before a node that does not split (`r ≤ 1`) could.
    /// With `r = φ·A/d`: `r' ≤ A / (d − Δ)` stays ≤ 1 while the distance moves less than
    /// `d − A`; when that is not positive (φ < 1 holds the node back),
    /// `r' ≤ (φ + Δ/m) · A / (d − Δ)` stays ≤ 1 for a frustum motion up to
    /// `(d − φA) / (A/m + 1)`.
    fn stay_unsplit(&self, node: NodeView) -> Expiry {
        if !matches!(self.rule, Rule::ScreenSpace { .. }) {
            return Expiry::NOW;
        }
        let a = node.weight;
        if a == 0.0 {
            return Expiry::NEVER;
        }
        if node.distance > a {
            return Expiry {
                distance: node.distance - a,
                frustum: f64::INFINITY,
            };
        }
        Expiry {
            distance: f64::INFINITY,
            frustum: (node.distance - node.frustum * a) / (a / node.margin + 1.0),
        }
    }

    /// How far the camera may move before a split node (`r > 1`) could stop splitting:
    /// while the frustum moves less than the box's clearance φ stays 1 and
    /// `r' ≥ A / (d + Δ)` stays above 1 for a distance motion up to `A − d`; otherwise
    /// `r' ≥ (φ − Δ/m) · A / (d + Δ)` stays above 1 for a frustum motion up to
    /// `(φA − d) / (A/m + 1)`.
    fn stay_split(&self, terrain: &ViewTerrain<'_>, cell: Cell, node: NodeView) -> Expiry {
        let (i, j) = cell.position();
        if terrain.is_void(cell.level, i, j) {
            return Expiry::NEVER;
        }
        if !matches!(self.rule, Rule::ScreenSpace { .. }) {
            return Expiry::NOW;
        }
        let a = node.weight;
        let general = (node.frustum * a - node.distance) / (a / node.margin + 1.0);
        if node.clearance > 0.0 && a - node.distance > general {
            return Expiry {
                distance: a - node.distance,
                frustum: node.clearance,
            };
        }
        Expiry {
            distance: f64::INFINITY,
            frustum: general,
        }
    }
}

/// Upper bounds on how far box distances and frustum-plane distances (for points of the
/// terrain box `extent`) move from `from` to `to`: the eye's displacement, and that plus
/// the frame's rotation angle times the farthest terrain corner. Infinite when the
/// projection changed.
pub fn camera_motion(from: &View, to: &View, extent: &[glam::DVec3; 8]) -> Expiry {
    if from.camera.fov_degrees != to.camera.fov_degrees
        || from.camera.viewport != to.camera.viewport
    {
        return Expiry::NEVER;
    }
    let shift = from.camera.eye.distance(to.camera.eye);
    let angle = from.rotation_to(to);
    if angle == 0.0 {
        return Expiry {
            distance: shift,
            frustum: shift,
        };
    }
    let reach = extent
        .iter()
        .map(|p| p.distance(to.camera.eye))
        .fold(0.0, f64::max);
    // |n' − n| = 2 sin(θ/2) ≤ θ; a small margin covers rounding in the angle.
    Expiry {
        distance: shift,
        frustum: shift + (angle * 1.001 + 1e-12) * reach,
    }
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
