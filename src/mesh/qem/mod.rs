//! QEM simplification straight on the height map (seed paper 000): every grid vertex
//! gets the quadric of its triangles' planes, the cheapest contraction of a vertex onto
//! a neighbour goes first (a binary heap, stale entries skipped when popped), and the
//! pair always merges onto one of its two grid vertices, never a new position.
//!
//! No triangle mesh is kept. Stages, one module each: [`grid`] (cells and their
//! diagonals), [`quadric`], [`clusters`] (merger pointers and `find_merger`), [`fan`]
//! (a survivor's triangles from the grid, and whether a contraction keeps the mesh
//! valid) and [`flags`] (the paper's 4-bit flag map and its triangle extraction). The
//! result is valid by construction: no triangle flipped seen from above, no
//! non-manifold edge, the outline (grid border and voids) kept exactly, nodata never
//! covered.

pub mod clusters;
pub mod fan;
pub mod flags;
pub mod grid;
pub mod quadric;

use std::cmp::Reverse;
use std::collections::BinaryHeap;

use bitvec::prelude::*;

use super::rasterise::rasterise_triangle;
use super::GridMesh;
use clusters::Clusters;
use fan::Fan;
use flags::FlagMap;
use grid::Grid;
use quadric::Quadric;

/// When simplification stops.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum QemTarget {
    /// At most this many triangles (or as few as valid contractions reach).
    Triangles(usize),
    /// Contract while every valid sample stays within this many data units of the mesh.
    MaxError(f64),
}

/// Why a QEM mesh cannot be built: the grid's problem.
pub type QemError = grid::GridError;

/// The simplified mesh and the compact form it came from.
#[derive(Debug, Clone)]
pub struct QemMesh {
    /// The triangles, extracted from `flags`.
    pub mesh: GridMesh,
    /// The diagonal of every cell and the direction to every sample's merger.
    pub flags: FlagMap,
}

/// Simplifies the `width × height` grid `heights` (valid where `valid`) until `target`.
pub fn qem_mesh(
    width: usize,
    height: usize,
    heights: &[f64],
    valid: &BitSlice<u64, Lsb0>,
    target: QemTarget,
) -> Result<QemMesh, QemError> {
    let grid = Grid {
        width,
        height,
        heights,
        valid,
    };
    check_grid(&grid)?;
    let mut simplifier = Simplifier::new(grid, target);
    simplifier.run(target);
    Ok(simplifier.snapshot())
}

/// The meshes of one simplification at every triangle budget of `budgets` (in the
/// order given): the contraction order does not depend on the budget, so one run
/// stops at each budget in turn and extracts the mesh there.
pub fn qem_meshes_within(
    width: usize,
    height: usize,
    heights: &[f64],
    valid: &BitSlice<u64, Lsb0>,
    budgets: &[usize],
) -> Result<Vec<GridMesh>, QemError> {
    let grid = Grid {
        width,
        height,
        heights,
        valid,
    };
    check_grid(&grid)?;
    let mut order: Vec<usize> = (0..budgets.len()).collect();
    order.sort_by_key(|&k| std::cmp::Reverse(budgets[k]));
    let first = QemTarget::Triangles(budgets.iter().copied().max().unwrap_or(0));
    let mut simplifier = Simplifier::new(grid, first);
    let mut meshes = vec![GridMesh::default(); budgets.len()];
    for k in order {
        simplifier.run(QemTarget::Triangles(budgets[k]));
        meshes[k] = simplifier.snapshot().mesh;
    }
    Ok(meshes)
}

fn check_grid(grid: &Grid) -> Result<(), QemError> {
    grid.check(u32::MAX as usize)
}

/// The most triangles a surviving vertex may have around it: contractions that would
/// give the merger more are refused. Without a cap, flat water collapses into fans of
/// hundreds of slivers whose every evaluation walks them all (srtm3_utm32_f32 ran for
/// over 14 minutes).
pub const MAX_FAN: usize = 24;

/// A vertex waiting in the heap: the cost of its cheapest contraction when queued.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
struct Entry {
    /// The cost's bits (non-negative floats order as their bits).
    cost_bits: u64,
    vertex: u32,
}

/// A contraction of a fan's root onto `merger`.
#[derive(Debug, Clone, Copy)]
struct Candidate {
    merger: u32,
    cost: f64,
    removed: usize,
}

/// The state of one simplification.
struct Simplifier<'a> {
    grid: Grid<'a>,
    flags: FlagMap,
    clusters: Clusters,
    quadrics: Vec<Quadric>,
    queue: BinaryHeap<Reverse<Entry>>,
    /// The cost each vertex was last queued at (infinite: not queued).
    queued_cost: Vec<f64>,
    triangles: usize,
    /// Triangles around each survivor.
    fan_sizes: Vec<u8>,
    max_error: Option<f64>,
    fan: Fan,
    costs: Vec<(f64, u32)>,
}

impl<'a> Simplifier<'a> {
    fn new(grid: Grid<'a>, target: QemTarget) -> Simplifier<'a> {
        let flags = grid.flag_map();
        let (quadrics, fan_sizes, triangles) = initial_quadrics(&grid, &flags);
        let mut simplifier = Simplifier {
            grid,
            flags,
            clusters: Clusters::new(grid.len()),
            quadrics,
            queue: BinaryHeap::new(),
            queued_cost: vec![f64::INFINITY; grid.len()],
            triangles,
            fan_sizes,
            max_error: match target {
                QemTarget::MaxError(e) => Some(e),
                QemTarget::Triangles(_) => None,
            },
            fan: Fan::default(),
            costs: Vec::new(),
        };
        for v in 0..grid.len() as u32 {
            if let Some(candidate) = simplifier.cheapest(v) {
                simplifier.enqueue(v, candidate.cost);
            }
        }
        simplifier
    }

    /// Contracts until `target` is met or no contraction is valid.
    fn run(&mut self, target: QemTarget) {
        loop {
            if let QemTarget::Triangles(n) = target {
                if self.triangles <= n {
                    return;
                }
            }
            let Some(Reverse(entry)) = self.queue.pop() else {
                return;
            };
            let (v, cost) = (entry.vertex, f64::from_bits(entry.cost_bits));
            if !self.clusters.is_survivor(v) || self.queued_cost[v as usize] != cost {
                continue; // stale: contracted, or queued again since
            }
            self.queued_cost[v as usize] = f64::INFINITY;
            match self.cheapest(v) {
                Some(candidate) if candidate.cost > cost => self.enqueue(v, candidate.cost),
                Some(candidate) => self.contract(v, candidate),
                None => {} // stuck until a neighbour's contraction queues it again
            }
        }
    }

    /// Queues `v` at `cost` unless it waits at a lower cost already.
    fn enqueue(&mut self, v: u32, cost: f64) {
        if cost < self.queued_cost[v as usize] {
            self.queued_cost[v as usize] = cost;
            self.queue.push(Reverse(Entry {
                cost_bits: cost.to_bits(),
                vertex: v,
            }));
        }
    }

    /// The cheapest valid contraction of survivor `v` (its fan left in `self.fan`).
    fn cheapest(&mut self, v: u32) -> Option<Candidate> {
        if !self.grid.valid[v as usize] {
            return None;
        }
        self.fan
            .gather(&self.grid, &self.flags, &mut self.clusters, v);
        let mut costs = std::mem::take(&mut self.costs);
        costs.clear();
        costs.extend(
            self.fan
                .axis_neighbours
                .iter()
                .filter(|b| self.fan.link.binary_search(b).is_ok())
                .map(|&b| (self.contraction_cost(v, b), b)),
        );
        costs.sort_unstable_by(|a, b| a.0.total_cmp(&b.0));
        let found = costs.iter().find_map(|&(cost, merger)| {
            let removed = self.fan.contraction(self.grid.width, merger)?;
            let size = self.fan.triangles.len() + usize::from(self.fan_sizes[merger as usize]);
            (size - 2 * removed <= MAX_FAN && self.within_error(merger)).then_some(Candidate {
                merger,
                cost,
                removed,
            })
        });
        self.costs = costs;
        found
    }

    /// The quadric cost of `mergee` contracting onto `merger`'s position.
    fn contraction_cost(&self, mergee: u32, merger: u32) -> f64 {
        self.quadrics[mergee as usize]
            .sum(&self.quadrics[merger as usize])
            .cost_at(self.grid.point(merger))
    }

    /// Whether the fan's triangles, re-made around `merger`, keep every sample they
    /// cover within the max error (always true without one).
    fn within_error(&self, merger: u32) -> bool {
        let Some(limit) = self.max_error else {
            return true;
        };
        let corner = |s: u32| {
            let [x, y, z] = self.grid.point(s);
            (x as usize, y as usize, z)
        };
        let mut worst = 0.0f64;
        for &[x, y] in &self.fan.triangles {
            if x != merger && y != merger {
                rasterise_triangle(
                    self.grid.width,
                    [corner(merger), corner(x), corner(y)],
                    |s, z| worst = worst.max((z - self.grid.heights[s]).abs()),
                );
            }
        }
        worst <= limit
    }

    /// Contracts the fan's root onto the candidate's merger and queues the vertices
    /// whose contractions changed.
    fn contract(&mut self, mergee: u32, candidate: Candidate) {
        let merger = candidate.merger;
        self.clusters.absorb(merger, mergee);
        let absorbed = self.quadrics[mergee as usize];
        self.quadrics[merger as usize].add(&absorbed);
        self.triangles -= candidate.removed;
        self.record_fan_sizes(mergee, candidate);
        let link = std::mem::take(&mut self.fan.link);
        let mut merger_cost = f64::INFINITY;
        for &x in link.iter().filter(|&&x| x != merger) {
            // x may now contract onto the merger, and the merger onto x.
            let cost = self.contraction_cost(x, merger);
            self.enqueue(x, cost);
            merger_cost = merger_cost.min(self.contraction_cost(merger, x));
        }
        self.enqueue(merger, merger_cost);
        self.fan.link = link;
    }

    /// Updates the fan sizes after `mergee` contracted onto the candidate's merger: the
    /// merger takes the mergee's triangles but the removed ones, and the far corner of
    /// each removed triangle loses it.
    fn record_fan_sizes(&mut self, mergee: u32, candidate: Candidate) {
        let merger = candidate.merger as usize;
        let size = self.fan.triangles.len() + usize::from(self.fan_sizes[merger]);
        self.fan_sizes[merger] = (size - 2 * candidate.removed) as u8;
        self.fan_sizes[mergee as usize] = 0;
        for &[x, y] in &self.fan.triangles {
            if x == candidate.merger {
                self.fan_sizes[y as usize] -= 1;
            } else if y == candidate.merger {
                self.fan_sizes[x as usize] -= 1;
            }
        }
    }

    /// Records the merger directions in the flag map and extracts the mesh from it
    /// (simplification may go on afterwards).
    fn snapshot(&mut self) -> QemMesh {
        let clusters = &mut self.clusters;
        let roots: Vec<u32> = (0..self.grid.len() as u32)
            .map(|s| clusters.find_merger(s))
            .collect();
        self.flags.record_mergers(|s| roots[s]);
        drop(roots);
        QemMesh {
            mesh: extract_mesh(&self.grid, &self.flags),
            flags: self.flags.clone(),
        }
    }
}

/// Every sample's quadric (the planes of its valid grid triangles), its number of valid
/// grid triangles, and the number of valid grid triangles.
fn initial_quadrics(grid: &Grid, flags: &FlagMap) -> (Vec<Quadric>, Vec<u8>, usize) {
    let mut quadrics = vec![Quadric::default(); grid.len()];
    let mut fan_sizes = vec![0u8; grid.len()];
    let mut triangles = 0;
    for y in 0..grid.height - 1 {
        for x in 0..grid.width - 1 {
            let cell = y * grid.width + x;
            for t in grid.cell_triangles(cell, flags.diagonal(cell)) {
                if !grid.is_valid_triangle(t) {
                    continue;
                }
                triangles += 1;
                let plane = Quadric::of_triangle(t.map(|s| grid.point(s))).expect("grid triangle");
                for s in t {
                    quadrics[s as usize].add(&plane);
                    fan_sizes[s as usize] += 1;
                }
            }
        }
    }
    (quadrics, fan_sizes, triangles)
}

/// The paper's extraction: every valid grid triangle mapped through `find_merger`, kept
/// when its three corners are distinct.
pub fn extract_mesh(grid: &Grid, flags: &FlagMap) -> GridMesh {
    let mergers = flags.mergers();
    const UNUSED: u32 = u32::MAX;
    let mut index = vec![UNUSED; grid.len()];
    let mut mesh = GridMesh {
        width: grid.width,
        height: grid.height,
        ..GridMesh::default()
    };
    for y in 0..grid.height - 1 {
        for x in 0..grid.width - 1 {
            let cell = y * grid.width + x;
            for t in grid.cell_triangles(cell, flags.diagonal(cell)) {
                if !grid.is_valid_triangle(t) {
                    continue;
                }
                let [a, b, c] = t.map(|s| mergers[s as usize]);
                if a == b || b == c || a == c {
                    continue;
                }
                let corners = [a, b, c].map(|v| {
                    if index[v as usize] == UNUSED {
                        index[v as usize] = mesh.vertices.len() as u32;
                        mesh.vertices.push(v);
                    }
                    index[v as usize]
                });
                mesh.triangles.push(corners);
            }
        }
    }
    mesh
}

#[cfg(test)]
mod tests;
