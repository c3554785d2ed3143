//! The variable-resolution model (seed paper 001, after Cignoni, Puppo and Scopigno):
//! every triangle the simplification ever had, with the step that made it (its birth)
//! and the step that removed it (its death), and each step's error. The error of a
//! step is the largest collapse cost so far, so errors never fall along the
//! simplification and "the mesh at error ε" is the mesh after every step whose error
//! is at most ε: the triangles with birth error ≤ ε < death error.

/// A triangle never removed.
pub const NEVER: u32 = u32::MAX;

/// Births, deaths and step errors as the simplification goes.
#[derive(Debug, Clone, Default)]
pub struct Recorder {
    birth: Vec<u32>,
    death: Vec<u32>,
    step_error: Vec<f64>,
    step_vertex: Vec<u32>,
    step_triangles: Vec<u32>,
}

impl Recorder {
    /// A record of `triangles` grid triangles, all born at step 0.
    pub fn new(triangles: usize) -> Recorder {
        Recorder {
            birth: vec![0; triangles],
            death: vec![NEVER; triangles],
            step_error: Vec::new(),
            step_vertex: Vec::new(),
            step_triangles: vec![triangles as u32],
        }
    }

    /// The error the last step reached (0 before any).
    pub fn error(&self) -> f64 {
        self.step_error.last().copied().unwrap_or(0.0)
    }

    /// Records one collapse of `vertex` costing `cost`: `removed` die and `created`
    /// are born; `live` triangles remain.
    pub fn step(&mut self, cost: f64, vertex: u32, removed: &[u32], created: &[u32], live: usize) {
        let step = self.step_error.len() as u32 + 1;
        self.step_error.push(self.error().max(cost));
        self.step_vertex.push(vertex);
        self.step_triangles.push(live as u32);
        for &t in removed {
            self.death[t as usize] = step;
        }
        for &t in created {
            if self.birth.len() <= t as usize {
                self.birth.resize(t as usize + 1, 0);
                self.death.resize(t as usize + 1, NEVER);
            }
            self.birth[t as usize] = step;
        }
    }

    /// The finished model: triangles (`corners`, indexed as the records are) ordered by
    /// death, latest first, so the triangles alive at a step lead the arrays.
    pub fn finish(self, width: usize, height: usize, corners: Vec<[u32; 3]>) -> History {
        let mut order: Vec<u32> = (0..corners.len() as u32).collect();
        order.sort_unstable_by_key(|&t| std::cmp::Reverse(self.death[t as usize]));
        History {
            width,
            height,
            corners: order.iter().map(|&t| corners[t as usize]).collect(),
            birth: order.iter().map(|&t| self.birth[t as usize]).collect(),
            death: order.iter().map(|&t| self.death[t as usize]).collect(),
            step_error: self.step_error,
            step_vertex: self.step_vertex,
            step_triangles: self.step_triangles,
        }
    }
}

/// The variable-resolution model of one DEM.
#[derive(Debug, Clone)]
pub struct History {
    /// Samples per row of the grid.
    pub width: usize,
    /// Rows of the grid.
    pub height: usize,
    /// Corners (samples) of every triangle ever made, latest death first.
    pub corners: Vec<[u32; 3]>,
    /// The step that made each triangle (0: the grid's).
    pub birth: Vec<u32>,
    /// The step that removed each triangle ([`NEVER`]: in the final mesh).
    pub death: Vec<u32>,
    /// The error of each step (step `k` at `k − 1`), never falling.
    pub step_error: Vec<f64>,
    /// The vertex each step removed.
    pub step_vertex: Vec<u32>,
    /// Live triangles after each step (the grid's at 0).
    pub step_triangles: Vec<u32>,
}

impl History {
    /// Steps (collapses) recorded.
    pub fn steps(&self) -> usize {
        self.step_error.len()
    }

    /// The last step whose error is at most `epsilon` (0: none).
    pub fn step_at_error(&self, epsilon: f64) -> usize {
        self.step_error.partition_point(|&e| e <= epsilon)
    }

    /// The first step after which at most `triangles` remain (the last step when
    /// the simplification never got that low).
    pub fn step_within(&self, triangles: usize) -> usize {
        self.step_triangles
            .iter()
            .position(|&n| n as usize <= triangles)
            .unwrap_or(self.steps())
    }

    /// The error of step `step` (0 for the grid).
    pub fn error_of_step(&self, step: usize) -> f64 {
        step.checked_sub(1).map_or(0.0, |k| self.step_error[k])
    }
}
