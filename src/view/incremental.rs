//! Frame-to-frame split/merge (Lee et al.'s ping-pong buffers): the previous frame's
//! leaves are read from one buffer and the next frame's written to the other, visiting
//! only leaves whose decision may have changed instead of descending from the roots.
//!
//! Each leaf carries two *expiries*: how far the camera may travel before the leaf could
//! need a split, and before its parent could need a merge, in one measure of motion
//! accumulated frame after frame (see [`camera_motion`]): the eye's displacement, plus
//! the change of heading times the horizontal distance up to which turns are counted
//! (the turn reach `L`, about the median of the leaves in view), plus the change of pitch
//! times the farthest terrain corner.
//!
//! Why a leaf is looked at again before its decision can change: a node's ratio is a
//! function of its box distance, horizontal reach, depth and frustum-plane distances, and
//! its slack (`Incremental::stay_unsplit`, `stays_above`) is how far all of those may
//! move together before the ratio can cross 1. In a frame those move by at most the eye's
//! displacement plus the turn times the node's horizontal reach `h` plus the change of
//! pitch times its distance ([`camera_motion`]'s proof), which is at most the frame's
//! measure times `max(1, h / L)`; `h` grows by no more than the eye moves, so over
//! accumulated motion `x` the node moves by at most `x · max(1, (h₀ + x) / L)`, and the
//! expiry is set where that reaches the slack (`allowance`, then a 0.999 safety
//! factor). Near leaves, those that expire, count turns at their own reach rather than
//! the farthest corner's; farther ones pay for it with an earlier expiry.
//!
//! Leaves whose expiries are still ahead are copied as they are. For the others, what
//! expired is evaluated again (the parent, the leaf, or both): a leaf whose parent no
//! longer splits merges up to the highest such ancestor, a leaf that now splits is
//! refined from there down. The leaves are kept in blocks of `BLOCK` with a lower bound
//! on their expiries, so a block none of whose leaves can have changed is copied whole
//! without looking at them. The result equals [`ViewTerrain::select`] for the same camera
//! (the property tests check it frame after frame, on paths that turn, pitch and look
//! straight down). The area rule has no such bound: every leaf is evaluated again each
//! frame.

use super::camera::View;
use super::selection::{prefetch_read, NodeView, Rule, ViewTerrain};
use crate::mesh::cells::{Cell, CellTree};

/// Leaves per block of the leaf list: an update copies a block whose earliest expiry is
/// still ahead as it is, without looking at its leaves.
const BLOCK: usize = 16;

/// A selection kept from frame to frame.
#[derive(Debug)]
pub struct Incremental {
    rule: Rule,
    tree: CellTree,
    /// The expiries of `tree`'s leaves (its `cells` stay empty: the tree holds them).
    current: Leaves,
    /// The ping-pong buffers the next frame is written to.
    spare: Leaves,
    /// The positions of the leaves an update looks at again (kept for its allocation).
    expired: Vec<usize>,
    /// Camera motion accumulated since the first frame (see [`camera_motion`]).
    travelled: f64,
    last: View,
    /// Corners of the terrain's bounding box.
    extent: [glam::DVec3; 8],
    /// Up to which horizontal distance turns are counted in the motion (see
    /// [`allowance`]): chosen when the expiries are set, the [`TURN_QUANTILE`] of the
    /// horizontal reaches of the leaves in view.
    turn_reach: f64,
    /// The last parent evaluated under the current view: a parent's leaves come one after
    /// another, so it is evaluated once for all of them. Cleared when the view changes.
    last_parent: std::cell::Cell<Option<(Cell, NodeView)>>,
    /// The last parent expiry computed under the current view ([`Incremental::parent_expiry`]
    /// of a parent's leaves is the same for all of them). Cleared with `last_parent`.
    last_parent_expiry: std::cell::Cell<Option<(Cell, f64)>>,
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

/// When a leaf must next be looked at, in accumulated camera motion, held as `f32`
/// rounded down (a leaf is looked at slightly early, never late) so that the leaf list an
/// update copies is smaller.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Expiry {
    /// Until then the leaf does not split.
    own: f32,
    /// Until then its parent splits.
    parent: f32,
}

impl Expiry {
    fn new(own: f64, parent: f64) -> Expiry {
        Expiry {
            own: round_down(own),
            parent: round_down(parent),
        }
    }

    fn own(self) -> f64 {
        f64::from(self.own)
    }

    fn parent(self) -> f64 {
        f64::from(self.parent)
    }

    fn earliest(self) -> f64 {
        f64::from(self.own.min(self.parent))
    }

    /// The bits of the earlier expiry: expiries are never negative (nor NaN), and the
    /// bits of such `f32`s order as their values do.
    #[inline]
    fn earliest_bits(self) -> u32 {
        self.own.to_bits().min(self.parent.to_bits())
    }
}

/// The largest `f32` at most `x`.
pub(super) fn round_down(x: f64) -> f32 {
    let f = x as f32;
    if f64::from(f) > x {
        f.next_down()
    } else {
        f
    }
}

/// Leaves in depth-first order with their expiries, and per block of [`BLOCK`] leaves a
/// lower bound on the block's expiries (conservative: a bound may be lower than the
/// block's smallest expiry, which costs a look at its leaves, never a missed one).
#[derive(Debug, Default)]
struct Leaves {
    cells: Vec<Cell>,
    /// Expiries of every leaf, in the order of `cells`.
    expiry: Vec<Expiry>,
    /// Block `k` covers leaves `k·BLOCK .. (k + 1)·BLOCK`.
    block_expiry: Vec<f64>,
}

impl Leaves {
    fn clear(&mut self) {
        self.cells.clear();
        self.expiry.clear();
        self.block_expiry.clear();
    }

    fn last(&self) -> Option<Cell> {
        self.cells.last().copied()
    }

    fn push(&mut self, cell: Cell, expiry: Expiry) {
        let until = expiry.earliest();
        self.cells.push(cell);
        self.expiry.push(expiry);
        let block = (self.cells.len() - 1) / BLOCK;
        if block == self.block_expiry.len() {
            self.block_expiry.push(until);
        } else {
            let bound = &mut self.block_expiry[block];
            *bound = bound.min(until);
        }
    }

    /// Removes the last leaf (its block's bound stays, still a lower bound).
    fn pop(&mut self) {
        self.cells.pop();
        self.expiry.pop();
    }

    /// The positions of the leaves whose expiries are at most `travelled` (blocks whose
    /// bound is ahead are not looked at), in order, into `out`.
    fn expired(&self, travelled: f64, out: &mut Vec<usize>) {
        out.clear();
        // An `f32` is at most `travelled` exactly when it is at most its rounding down.
        let now = round_down(travelled).to_bits();
        for (block, &bound) in self.block_expiry.iter().enumerate() {
            if bound > travelled {
                continue;
            }
            let start = block * BLOCK;
            let end = (start + BLOCK).min(self.cells.len());
            for (k, expiry) in self.expiry[start..end].iter().enumerate() {
                if expiry.earliest_bits() <= now {
                    out.push(start + k);
                }
            }
        }
    }

    /// Appends `cells` with expiries `expiry`, keeping each block's bound its smallest.
    fn extend(&mut self, cells: &[Cell], expiry: &[Expiry]) {
        let mut at = self.cells.len();
        self.cells.extend_from_slice(cells);
        self.expiry.extend_from_slice(expiry);
        while at < self.cells.len() {
            let block = at / BLOCK;
            let end = ((block + 1) * BLOCK).min(self.cells.len());
            let bits = self.expiry[at..end]
                .iter()
                .fold(u32::MAX, |b, e| b.min(e.earliest_bits()));
            let bound = f64::from(f32::from_bits(bits));
            if block == self.block_expiry.len() {
                self.block_expiry.push(bound);
            } else {
                let kept = &mut self.block_expiry[block];
                *kept = kept.min(bound);
            }
            at = end;
        }
    }
}

/// Which quantile of the leaves' horizontal reaches turns are counted up to.
const TURN_QUANTILE: f64 = 0.5;

/// One leaf in this many is looked at to choose the turn reach.
const REACH_SAMPLE: usize = 16;

/// How many leaves to be looked at ahead an update asks for their node's summary, so
/// that its evaluation does not wait on memory.
const PREFETCH_AHEAD: usize = 8;

/// Slack safety factor: decisions are re-evaluated slightly before the bound says.
const SAFETY: f64 = 0.999;

/// The accumulated motion `slack` after `travelled` (slightly early, by [`SAFETY`]).
#[inline]
pub(super) fn after(travelled: f64, slack: f64) -> f64 {
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
            current: Leaves::default(),
            spare: Leaves::default(),
            expired: Vec::new(),
            travelled: 0.0,
            last: *view,
            extent,
            turn_reach: f64::INFINITY,
            last_parent: std::cell::Cell::new(None),
            last_parent_expiry: std::cell::Cell::new(None),
        };
        state.reset_expiry(terrain, view);
        state
    }

    /// The current selection.
    pub fn tree(&self) -> &CellTree {
        &self.tree
    }

    fn reset_expiry(&mut self, terrain: &ViewTerrain<'_>, view: &View) {
        self.forget_parent();
        self.turn_reach = self.typical_reach(terrain, view);
        let mut fresh = Leaves::default();
        for &cell in self.tree.leaves() {
            fresh.push(cell, self.leaf_expiry(terrain, view, cell, None));
        }
        self.tree.swap_leaves(&mut fresh.cells);
        fresh.cells.clear();
        self.current = fresh;
    }

    /// The [`TURN_QUANTILE`] of the horizontal reaches of the leaves in view (every
    /// [`REACH_SAMPLE`]th leaf), infinite when none is in view.
    fn typical_reach(&self, terrain: &ViewTerrain<'_>, view: &View) -> f64 {
        let mut reaches: Vec<f64> = self
            .tree
            .leaves()
            .iter()
            .step_by(REACH_SAMPLE)
            .filter(|c| c.level > 0)
            .map(|&c| self.evaluate(terrain, view, c))
            .filter(|n| n.frustum > 0.0)
            .map(|n| n.horizontal)
            .collect();
        if reaches.is_empty() {
            return f64::INFINITY;
        }
        let k = ((reaches.len() - 1) as f64 * TURN_QUANTILE) as usize;
        *reaches.select_nth_unstable_by(k, f64::total_cmp).1
    }

    /// Moves the selection to `view`.
    pub fn update(&mut self, terrain: &ViewTerrain<'_>, view: &View) -> UpdateStats {
        let motion = camera_motion(&self.last, view, &self.extent, self.turn_reach);
        self.last = *view;
        self.forget_parent();
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
        let mut old = std::mem::take(&mut self.current);
        self.tree.swap_leaves(&mut old.cells);
        let mut new = std::mem::take(&mut self.spare);
        new.clear();
        let mut stats = UpdateStats::default();
        let mut expired = std::mem::take(&mut self.expired);
        old.expired(self.travelled, &mut expired);
        let mut k = 0;
        for (n, &e) in expired.iter().enumerate() {
            // Two stages: the leaf's cell, then (once it has arrived) its summaries.
            if let Some(&far) = expired.get(n + 2 * PREFETCH_AHEAD) {
                prefetch_read(&old.cells[far]);
            }
            if let Some(&ahead) = expired.get(n + PREFETCH_AHEAD) {
                terrain.prefetch(old.cells[ahead]);
            }
            if e < k {
                // Merged into an earlier leaf.
                continue;
            }
            if k < e {
                new.extend(&old.cells[k..e], &old.expiry[k..e]);
            }
            stats.revisited += 1;
            let merged = stats.merged;
            self.revisit(
                terrain,
                view,
                (old.cells[e], old.expiry[e]),
                &mut new,
                &mut stats,
            );
            k = e + 1;
            // A merge writes a cell holding the next old leaves (a depth-first run); a
            // kept or split leaf holds none of them.
            if stats.merged > merged {
                while k < old.cells.len() && new.last().is_some_and(|l| contains(l, old.cells[k])) {
                    k += 1;
                }
            }
        }
        new.extend(&old.cells[k..], &old.expiry[k..]);
        self.expired = expired;
        self.tree.swap_leaves(&mut new.cells);
        new.cells.clear();
        self.current = new;
        self.spare = old;
        stats
    }

    /// Re-decides leaf `cell` (with expiries `expiry`, one of them passed): merge up,
    /// split down, or keep with new expiries. Only what expired is evaluated again.
    fn revisit(
        &mut self,
        terrain: &ViewTerrain<'_>,
        view: &View,
        (cell, expiry): (Cell, Expiry),
        leaves: &mut Leaves,
        stats: &mut UpdateStats,
    ) {
        let parent_holds = expiry.parent() > self.travelled;
        let top = if parent_holds {
            cell
        } else {
            self.merge_target(terrain, view, cell)
        };
        if top != cell {
            while leaves.last().is_some_and(|c| contains(top, c)) {
                leaves.pop();
            }
            self.clear_subtree(top);
            stats.merged += 1;
            leaves.push(top, self.leaf_expiry(terrain, view, top, None));
            return;
        }
        let parent = if parent_holds {
            expiry.parent()
        } else {
            self.parent_expiry(terrain, view, cell)
        };
        if expiry.own() > self.travelled {
            leaves.push(cell, Expiry::new(expiry.own(), parent));
            return;
        }
        let own = (cell.level > 0).then(|| self.evaluate(terrain, view, cell));
        if let Some(own) = own.filter(|o| self.rule.splits(o.ratio)) {
            stats.split += 1;
            self.refine(terrain, view, (cell, own), leaves);
        } else {
            let own = own.map_or(f64::INFINITY, |o| self.until(self.stay_unsplit(o), &o));
            leaves.push(cell, Expiry::new(own, parent));
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
        leaves: &mut Leaves,
    ) {
        self.tree.set_split(cell, true);
        let parent_until = self.until(self.stay_split(terrain, cell, parent_view), &parent_view);
        for child in children(&self.tree, cell) {
            let (i, j) = child.position();
            let void = terrain.is_void(child.level, i, j);
            if child.level == 0 {
                if self.tree.is_meshed(child) {
                    leaves.push(child, Expiry::new(f64::INFINITY, parent_until));
                }
                continue;
            }
            let own = self.evaluate(terrain, view, child);
            if void || self.rule.splits(own.ratio) {
                self.refine(terrain, view, (child, own), leaves);
            } else {
                let expiry = Expiry::new(self.until(self.stay_unsplit(own), &own), parent_until);
                leaves.push(child, expiry);
            }
        }
    }

    fn evaluate(&self, terrain: &ViewTerrain<'_>, view: &View, cell: Cell) -> NodeView {
        let (i, j) = cell.position();
        terrain.evaluate(view, self.rule, cell.level, i, j)
    }

    /// Clears the one-parent caches (the view or the motion travelled changed).
    fn forget_parent(&self) {
        self.last_parent.set(None);
        self.last_parent_expiry.set(None);
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
    ) -> Expiry {
        let own = if cell.level == 0 {
            f64::INFINITY
        } else {
            let node = own.unwrap_or_else(|| self.evaluate(terrain, view, cell));
            self.until(self.stay_unsplit(node), &node)
        };
        Expiry::new(own, self.parent_expiry(terrain, view, cell))
    }

    /// Until when the parent of leaf `cell` keeps splitting (infinite for a root).
    fn parent_expiry(&self, terrain: &ViewTerrain<'_>, view: &View, cell: Cell) -> f64 {
        if cell.level >= terrain.levels() {
            return f64::INFINITY;
        }
        let parent = parent_of(cell);
        if let Some((cached, until)) = self.last_parent_expiry.get() {
            if cached == parent {
                return until;
            }
        }
        let node = self.evaluate_parent(terrain, view, parent);
        let until = self.until(self.stay_split(terrain, parent, node), &node);
        self.last_parent_expiry.set(Some((parent, until)));
        until
    }

    /// The accumulated motion up to which `node`, whose quantities may move by `slack`
    /// before its decision could change, keeps it: see [`allowance`].
    fn until(&self, slack: f64, node: &NodeView) -> f64 {
        after(
            self.travelled,
            allowance(slack, node.horizontal, self.turn_reach),
        )
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
        stays_above(self.rule, node, 1.0)
    }
}

/// How far the camera may move (in [`camera_motion`]'s measure) before node `node`, whose
/// ratio is above `level`, could fall to `level` (0 under the area rule, which has no
/// bound): the ratio over `level` is the ratio of a node with `1/level` of the weight.
pub(super) fn stays_above(rule: Rule, node: NodeView, level: f64) -> f64 {
    if !matches!(rule, Rule::ScreenSpace { .. }) {
        return 0.0;
    }
    let node = NodeView {
        weight: node.weight / level,
        ..node
    };
    let general = split_holds(node, node.frustum, 1.0 / node.margin);
    if node.clearance > 0.0 {
        general.max(split_holds(node, 1.0, 0.0).min(node.clearance))
    } else {
        general
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
/// `to`: the eye's displacement, plus the change of heading times the farthest
/// horizontal distance to a terrain corner, plus the change of pitch times the farthest
/// distance to one. Infinite when the projection changed.
///
/// Why: distances and reaches do not depend on the camera's frame, and move by at most
/// the eye's displacement `s`. Depths and plane distances are `n · q`, `q = p − eye` and
/// `n` a direction fixed in the camera's frame. With z up in both frames, the frame at
/// heading `h` and pitch `p` is the one at `(h₀, p)` turned by `h − h₀` about the world's
/// z axis, which is the one at `(h₀, p₀)` turned by `p − p₀` about its right axis; so
/// `n` turns by `Δh` about z, which moves `n · q` by at most `|Δh|` times `q`'s
/// horizontal length, then by `Δp`, which moves it by at most `|Δp| · |q|`, and moving
/// the eye adds at most `s`. When either frame looks straight up or down (its image's
/// up is not z) the whole rotation angle counts with `|q|`.
pub fn camera_motion(from: &View, to: &View, extent: &[glam::DVec3; 8], turn_reach: f64) -> f64 {
    if from.camera.fov_degrees != to.camera.fov_degrees
        || from.camera.viewport != to.camera.viewport
    {
        return f64::INFINITY;
    }
    let shift = from.camera.eye.distance(to.camera.eye);
    let (heading, pitch) = match (heading_pitch(from), heading_pitch(to)) {
        (Some((h0, p0)), Some((h1, p1))) => {
            let turn = (h1 - h0).rem_euclid(std::f64::consts::TAU);
            (turn.min(std::f64::consts::TAU - turn), (p1 - p0).abs())
        }
        _ => (0.0, from.rotation_to(to)),
    };
    let eye = to.camera.eye;
    let horizontal = extent
        .iter()
        .map(|p| (*p - eye).truncate().length())
        .fold(0.0, f64::max);
    let reach = extent.iter().map(|p| p.distance(eye)).fold(0.0, f64::max);
    // A small margin covers rounding in the angles.
    let padded = |angle: f64| {
        if angle == 0.0 {
            0.0
        } else {
            angle * 1.001 + 1e-12
        }
    };
    shift + padded(heading) * horizontal.min(turn_reach) + padded(pitch) * reach
}

/// How far the camera may move in [`camera_motion`]'s measure, turns counted up to
/// `turn_reach`, before a node lying within `reach` of the eye horizontally can have
/// moved `slack` (in distance, reach, depth or frustum-plane distance).
///
/// Why: in a frame of measure `μ = s + |Δh|·min(L, H) + |Δp|·R` (`L` = `turn_reach`,
/// `H` and `R` the terrain's farthest horizontal and full distances), the node moves by
/// at most `s + |Δh|·h + |Δp|·R` with `h` its own horizontal reach then, so by at most
/// `μ · max(1, h / L)`. Its reach grows by no more than the eye moves, itself at most
/// the motion `x` accumulated since, so over `x` the node moves by at most
/// `x · max(1, (reach + x) / L)`, which stays below `slack` up to the returned `x`.
pub(super) fn allowance(slack: f64, reach: f64, turn_reach: f64) -> f64 {
    if slack == f64::INFINITY || reach + slack <= turn_reach {
        return slack;
    }
    // The positive root of x·(reach + x) = slack·L.
    let root =
        2.0 * slack * turn_reach / (reach + (reach * reach + 4.0 * slack * turn_reach).sqrt());
    root.min(slack)
}

/// The heading (about z, from +x) and pitch (above the horizontal) of `view`'s forward
/// direction, when its image's up is z's side (not looking straight up or down).
fn heading_pitch(view: &View) -> Option<(f64, f64)> {
    let f = view.forward;
    // As in `Camera::view`, which takes another up vector below this.
    if f.cross(glam::DVec3::Z).length() < 1e-6 {
        return None;
    }
    Some((f.y.atan2(f.x), f.z.clamp(-1.0, 1.0).asin()))
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::view::camera::Camera;
    use glam::DVec3;

    /// Over random pairs of cameras (turning, pitching, rolling onto a view straight
    /// down, moving), every camera-frame direction's distance to every terrain point moves
    /// by at most [`camera_motion`], and the bound is not loose for pure turns.
    #[test]
    fn camera_motion_bounds_depths_and_plane_distances() {
        let mut next = crate::view::unit_random(99);
        let (lo, hi) = (DVec3::new(0.0, 0.0, -50.0), DVec3::new(400.0, 300.0, 250.0));
        let extent = [0, 1, 2, 3, 4, 5, 6, 7]
            .map(|k| DVec3::select(glam::BVec3::new(k & 1 != 0, k & 2 != 0, k & 4 != 0), hi, lo));
        // Pure turns and pure changes of pitch.
        let mut tightest = [0.0f64; 2];
        for case in 0..4000 {
            let eye = DVec3::new(
                next() * 600.0 - 100.0,
                next() * 500.0 - 100.0,
                next() * 400.0,
            );
            let look = eye + DVec3::new(next() - 0.5, next() - 0.5, next() - 0.7) * 100.0;
            let a = Camera::new(eye, look, 50.0, (300, 200)).unwrap().view();
            let small = if case % 8 < 4 { 0.05 } else { 0.5 };
            let (eye_b, look_b) = match case % 4 {
                // A pure turn about the vertical through the eye.
                0 => {
                    let t = (next() - 0.5) * small;
                    let d = look - eye;
                    let turned = DVec3::new(
                        d.x * t.cos() - d.y * t.sin(),
                        d.x * t.sin() + d.y * t.cos(),
                        d.z,
                    );
                    (eye, eye + turned)
                }
                // Straight down.
                1 => (eye, eye - DVec3::Z * 50.0),
                // A pure change of pitch.
                3 => {
                    let d = look - eye;
                    let flat = d.truncate().length();
                    let p = d.z.atan2(flat) + (next() - 0.5) * small;
                    let dir = d.truncate() / flat * p.cos();
                    (eye, eye + dir.extend(p.sin()) * 100.0)
                }
                _ => (
                    eye + (DVec3::new(next(), next(), next()) - 0.5) * small * 20.0,
                    look + (DVec3::new(next(), next(), next()) - 0.5) * small * 40.0,
                ),
            };
            let b = Camera::new(eye_b, look_b, 50.0, (300, 200)).unwrap().view();
            let bound = camera_motion(&a, &b, &extent, f64::INFINITY);
            let n = DVec3::new(next() - 0.5, next() - 0.5, next() - 0.5).normalize();
            let direction = |v: &View| v.right * n.x + v.up * n.y + v.forward * n.z;
            let (na, nb) = (direction(&a), direction(&b));
            let mut moved = 0.0f64;
            for k in 0..28 {
                // The corners, where the bound is reached, and points inside.
                let p = match extent.get(k) {
                    Some(&corner) => corner,
                    None => lo + (hi - lo) * DVec3::new(next(), next(), next()),
                };
                let change = nb.dot(p - b.camera.eye) - na.dot(p - a.camera.eye);
                moved = moved.max(change.abs());
            }
            assert!(
                moved <= bound * (1.0 + 1e-9) + 1e-9,
                "case {case}: {moved} > {bound}"
            );
            if case % 4 % 3 == 0 && bound > 0.0 {
                let pure = case % 4 / 3;
                tightest[pure] = tightest[pure].max(moved / bound);
            }
        }
        assert!(tightest.iter().all(|&t| t > 0.9), "{tightest:?}");
    }

    /// Every block's bound is at most the earliest expiry of the leaves it holds, through
    /// pushes, pops and whole-run copies.
    #[test]
    fn block_bounds_stay_lower_bounds() {
        let mut leaves = Leaves::default();
        let mut seed = 7u64;
        let mut next = move || {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (seed >> 33) as f64
        };
        let source: Vec<(Cell, Expiry)> = (0..500)
            .map(|k| {
                let expiry = Expiry::new(next(), next());
                (Cell::new(0, k, 0), expiry)
            })
            .collect();
        for (round, chunk) in source.chunks(37).enumerate() {
            if round % 2 == 0 {
                let cells: Vec<Cell> = chunk.iter().map(|c| c.0).collect();
                let expiry: Vec<Expiry> = chunk.iter().map(|c| c.1).collect();
                leaves.extend(&cells, &expiry);
            } else {
                for &(cell, expiry) in chunk {
                    leaves.push(cell, expiry);
                }
                for _ in 0..round % 5 {
                    leaves.pop();
                }
            }
        }
        assert!(leaves.cells.len() > 3 * BLOCK);
        for (k, expiry) in leaves.expiry.iter().enumerate() {
            assert!(
                leaves.block_expiry[k / BLOCK] <= expiry.earliest(),
                "leaf {k}"
            );
        }
        // And the leaves found expired are exactly those at or before the motion.
        let travelled = leaves.expiry[10].earliest();
        let mut expired = Vec::new();
        leaves.expired(travelled, &mut expired);
        let exact: Vec<usize> = (0..leaves.cells.len())
            .filter(|&k| leaves.expiry[k].earliest() <= travelled)
            .collect();
        assert!(expired.contains(&10));
        assert_eq!(expired, exact);
    }
}
