//! Edge collapse without new vertices and the variable-resolution model (seed paper
//! 001, Yoo and Ma). The height map's grid triangles are simplified by collapsing
//! one vertex onto a neighbour at a time, cheapest first; every triangle made and
//! removed is recorded with the error at its birth and death, so one simplification
//! gives the mesh at any error, or a view-dependent mesh, by a query.
//!
//! Stages, one module each: [`topology`] (the live mesh), [`classify`](mod@classify) (boundary,
//! peak, ridge, plain: where a vertex may move), [`error`] (the paper's average-plane
//! metric and the distance-to-plane metric it is compared with), [`collapse`]
//! (validity, cost, and the collapse with its samples handed on), [`history`] (births
//! and deaths) and [`extract`] (meshes out of the model). Per vertex the candidate is
//! its shortest valid edge (the paper's rule) or, with
//! [`CandidateRule::LeastError`], its cheapest.
//!
//! Valid by construction: collapses never flip or flatten a triangle seen from above,
//! keep the link condition (manifold), never move a corner of the outline nor move a
//! border vertex off its straight border (the outline, grid border and voids, is kept
//! exactly), and the grid's triangles never touch nodata.

pub mod classify;
pub mod collapse;
pub mod error;
pub mod extract;
pub mod history;
pub mod table;
pub mod topology;

use std::cmp::Reverse;
use std::collections::BinaryHeap;

use bitvec::prelude::*;

use crate::mesh::qem::grid::Grid;
use crate::mesh::rasterise::mesh_error;
use crate::mesh::GridMesh;
use classify::{classify, FeatureRule};
use collapse::Owned;
pub use error::ErrorMetric;
pub use history::History;
use history::Recorder;
use topology::{Star, Topology};

/// Which edge of a vertex is its candidate.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CandidateRule {
    /// The shortest valid edge (the paper).
    Shortest,
    /// The valid edge whose collapse costs least.
    LeastError,
}

/// How the simplification runs.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct VarresOptions {
    /// The collapse cost.
    pub metric: ErrorMetric,
    /// Which edge of each vertex is tried.
    pub candidate: CandidateRule,
    /// Normals of an edge's triangles further apart than this (degrees) make it a
    /// feature edge.
    pub feature_angle_degrees: f64,
    /// Heights are multiplied by this for normals and edge lengths (columns and rows
    /// one unit apart); `None`: scaled to a mean slope of [`DEFAULT_MEAN_SLOPE_DEGREES`].
    pub z_scale: Option<f64>,
    /// Stop once at most this many triangles remain (0: simplify as far as valid
    /// collapses go).
    pub min_triangles: usize,
}

impl Default for VarresOptions {
    fn default() -> VarresOptions {
        VarresOptions {
            metric: ErrorMetric::AveragePlane,
            candidate: CandidateRule::LeastError,
            feature_angle_degrees: 60.0,
            z_scale: None,
            min_triangles: 0,
        }
    }
}

/// Why a variable-resolution model cannot be built: the grid's problem.
pub type VarresError = crate::mesh::qem::grid::GridError;

/// What a mesh out of the model meets.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum VarresTarget {
    /// The mesh with at most this many triangles the simplification passed through.
    Triangles(usize),
    /// The coarsest mesh of the model (searched over its steps) with every valid
    /// sample within this many data units, checked at every sample.
    MaxError(f64),
}

/// Simplifies the `width × height` grid `heights` (valid where `valid`) and returns
/// the variable-resolution model.
pub fn build_model(
    width: usize,
    height: usize,
    heights: &[f64],
    valid: &BitSlice<u64, Lsb0>,
    options: &VarresOptions,
) -> Result<History, VarresError> {
    let grid = Grid {
        width,
        height,
        heights,
        valid,
    };
    check_grid(&grid)?;
    let mut simplifier = Simplifier::new(grid, options);
    simplifier.run();
    let corners = std::mem::take(&mut simplifier.topology.corners);
    Ok(simplifier.recorder.finish(width, height, corners))
}

/// The mesh meeting `target`, from a model built with the default options (stopped
/// at the budget for [`VarresTarget::Triangles`]).
pub fn varres_mesh(
    width: usize,
    height: usize,
    heights: &[f64],
    valid: &BitSlice<u64, Lsb0>,
    target: VarresTarget,
) -> Result<GridMesh, VarresError> {
    let mut options = VarresOptions::default();
    if let VarresTarget::Triangles(n) = target {
        options.min_triangles = n;
    }
    let model = build_model(width, height, heights, valid, &options)?;
    Ok(mesh_meeting(&model, heights, valid, target))
}

/// The mesh of `model` (built on `heights`, valid where `valid`) meeting `target`.
pub fn mesh_meeting(
    model: &History,
    heights: &[f64],
    valid: &BitSlice<u64, Lsb0>,
    target: VarresTarget,
) -> GridMesh {
    let mesh_at = |step: usize| {
        let mut triangles = Vec::new();
        extract::triangles_at_step(model, step, &mut triangles);
        extract::grid_mesh(model.width, model.height, &triangles)
    };
    let limit = match target {
        VarresTarget::Triangles(n) => return mesh_at(model.step_within(n)),
        VarresTarget::MaxError(e) => e,
    };
    // Steps up to error E/2 are within E by the metric's bound; search past them.
    let (mut good, mut bad) = (model.step_at_error(limit / 2.0), model.steps() + 1);
    let mut best = mesh_at(good);
    while bad - good > 1 {
        let mid = good + (bad - good) / 2;
        let mesh = mesh_at(mid);
        if mesh_error(&mesh, heights, heights, valid).max_error <= limit {
            (good, best) = (mid, mesh);
        } else {
            bad = mid;
        }
    }
    best
}

fn check_grid(grid: &Grid) -> Result<(), VarresError> {
    grid.check((u32::MAX / 4) as usize)
}

/// The mean slope the default height scale gives a DEM: a typical terrain's, since
/// the ground size of a cell is often unknown (fuji, normalised heights).
pub const DEFAULT_MEAN_SLOPE_DEGREES: f64 = 10.0;

/// The default height scale: heights scaled so the mean height step between
/// neighbouring samples (along rows and columns) rises [`DEFAULT_MEAN_SLOPE_DEGREES`].
fn mean_slope_z_scale(grid: &Grid) -> f64 {
    let (mut sum, mut count) = (0.0f64, 0usize);
    for s in grid.valid.iter_ones() {
        let (x, y) = (s % grid.width, s / grid.width);
        for t in [
            (x + 1 < grid.width).then_some(s + 1),
            (y + 1 < grid.height).then_some(s + grid.width),
        ]
        .into_iter()
        .flatten()
        {
            if grid.valid[t] {
                sum += (grid.heights[t] - grid.heights[s]).abs();
                count += 1;
            }
        }
    }
    if sum > 0.0 {
        DEFAULT_MEAN_SLOPE_DEGREES.to_radians().tan() * count as f64 / sum
    } else {
        1.0
    }
}

/// A vertex waiting in the queue: its candidate's cost, and the version of its
/// candidate when queued (an older version is stale).
type Entry = Reverse<(u64, u32, u32)>;

/// The state of one simplification.
struct Simplifier<'a> {
    grid: Grid<'a>,
    options: VarresOptions,
    rule: FeatureRule,
    topology: Topology,
    owned: Owned,
    recorder: Recorder,
    queue: BinaryHeap<Entry>,
    /// Each vertex's candidate: the vertex it collapses onto and the cost.
    candidate: Vec<(u32, f64)>,
    version: Vec<u32>,
    live: usize,
    star: Star,
    to_star: Star,
    created: Vec<u32>,
    /// The samples a star covers (scratch).
    covered: Vec<[f64; 3]>,
}

impl<'a> Simplifier<'a> {
    fn new(grid: Grid<'a>, options: &VarresOptions) -> Simplifier<'a> {
        let topology = Topology::of_grid(&grid);
        let triangles = topology.corners.len();
        let rule = FeatureRule {
            cos_angle: options.feature_angle_degrees.to_radians().cos(),
            z_scale: options.z_scale.unwrap_or_else(|| mean_slope_z_scale(&grid)),
        };
        let mut simplifier = Simplifier {
            grid,
            options: *options,
            rule,
            owned: Owned::new(grid.len(), triangles),
            recorder: Recorder::new(triangles),
            queue: BinaryHeap::new(),
            candidate: vec![(topology::NONE, f64::INFINITY); grid.len()],
            version: vec![0; grid.len()],
            live: triangles,
            topology,
            star: Star::default(),
            to_star: Star::default(),
            created: Vec::new(),
            covered: Vec::new(),
        };
        for v in 0..grid.len() as u32 {
            simplifier.refresh(v);
        }
        simplifier
    }

    /// Collapses the cheapest candidate until none is left or the triangle floor.
    fn run(&mut self) {
        while self.live > self.options.min_triangles {
            let Some(Reverse((_, v, version))) = self.queue.pop() else {
                return;
            };
            if version != self.version[v as usize] {
                continue;
            }
            let (to, cost) = self.candidate[v as usize];
            self.topology.star(v, &mut self.star);
            self.topology.star(to, &mut self.to_star);
            if !collapse::is_valid(&self.topology, &self.star, &self.to_star, v, to) {
                self.refresh(v); // `to` changed since v was queued
                continue;
            }
            self.collapse(v, to, cost);
        }
    }

    /// Collapses `from` (its star in `self.star`) onto `to` and refreshes the
    /// candidates of the vertices around.
    fn collapse(&mut self, from: u32, to: u32, cost: f64) {
        let star = std::mem::take(&mut self.star);
        let mut created = std::mem::take(&mut self.created);
        collapse::apply(
            &mut self.topology,
            &mut self.owned,
            &star,
            from,
            to,
            &mut created,
        );
        self.live = self.live + created.len() - star.triangles.len();
        self.recorder
            .step(cost, from, &star.triangles, &created, self.live);
        self.version[from as usize] += 1;
        for &w in &star.ring {
            self.refresh(w);
        }
        self.star = star;
        self.created = created;
    }

    /// Finds vertex `v`'s candidate again and queues it.
    fn refresh(&mut self, v: u32) {
        self.version[v as usize] += 1;
        if self.topology.corner_of[v as usize] == topology::NONE {
            return;
        }
        if let Some((to, cost)) = self.find_candidate(v) {
            self.candidate[v as usize] = (to, cost);
            self.queue
                .push(Reverse((cost.to_bits(), v, self.version[v as usize])));
        }
    }

    /// The candidate of vertex `v` under the options' rule, if any edge is valid:
    /// its allowed edges ranked by length or by cost, the first valid one.
    fn find_candidate(&mut self, v: u32) -> Option<(u32, f64)> {
        let mut star = std::mem::take(&mut self.star);
        self.topology.star(v, &mut star);
        let class = classify(&self.topology, self.grid.heights, &self.rule, v, &star);
        let targets = class.targets(&star);
        let mut found = None;
        if !targets.is_empty() {
            collapse::covered_samples(
                &self.topology,
                self.grid.heights,
                &self.owned,
                &star,
                v,
                &mut self.covered,
            );
            let cost = |to| self.cost(&star, v, to);
            let mut ranked: Vec<(f64, u32)> = match self.options.candidate {
                CandidateRule::Shortest => {
                    targets.iter().map(|&to| (self.length(v, to), to)).collect()
                }
                CandidateRule::LeastError => targets.iter().map(|&to| (cost(to), to)).collect(),
            };
            ranked.sort_by(|a, b| a.0.total_cmp(&b.0));
            found = ranked.into_iter().find_map(|(key, to)| {
                self.topology.star(to, &mut self.to_star);
                collapse::is_valid(&self.topology, &star, &self.to_star, v, to).then(|| match self
                    .options
                    .candidate
                {
                    CandidateRule::Shortest => (to, self.cost(&star, v, to)),
                    CandidateRule::LeastError => (to, key),
                })
            });
        }
        self.star = star;
        found
    }

    /// The cost of collapsing `from` (star `star`, its samples in `self.covered`)
    /// onto `to`.
    fn cost(&self, star: &Star, from: u32, to: u32) -> f64 {
        collapse::cost(
            &self.topology,
            self.grid.heights,
            self.options.metric,
            (star, &self.covered),
            from,
            to,
        )
    }

    /// Squared length of edge `a`–`b`, heights scaled as for normals.
    fn length(&self, a: u32, b: u32) -> f64 {
        let ((ax, ay), (bx, by)) = (self.topology.xy(a), self.topology.xy(b));
        let dz =
            (self.grid.heights[a as usize] - self.grid.heights[b as usize]) * self.rule.z_scale;
        ((ax - bx).pow(2) + (ay - by).pow(2)) as f64 + dz * dz
    }
}

#[cfg(test)]
mod tests;
