//! Meshes out of the variable-resolution model. At one error: the triangles with
//! birth ≤ step < death, a scan of the leading triangles of the death-ordered arrays
//! (the live ones and those born after the step), so time grows with the mesh asked
//! for, not with the model. View-dependent: an error per place; a collapse is applied
//! when its error is within the error at its removed vertex and every collapse that
//! made a triangle it removes is applied. Such a set of collapses replays in order
//! (each finds the triangles it removes), and each replaces a star by a fan over the
//! same polygon, so the result is a conforming triangulation of the same outline, no
//! triangle flipped and no crack (the multi-triangulation guarantee).

use super::history::{History, NEVER};
use crate::mesh::GridMesh;

/// The triangles (corners as samples) of the mesh after `step` collapses.
pub fn triangles_at_step(history: &History, step: usize, out: &mut Vec<[u32; 3]>) {
    out.clear();
    let step = step as u32;
    let alive_or_later = history.death.partition_point(|&d| d > step);
    out.extend(
        (0..alive_or_later)
            .filter(|&t| history.birth[t] <= step)
            .map(|t| history.corners[t]),
    );
}

/// The triangles of the mesh at error `epsilon`: birth error ≤ ε < death error.
pub fn triangles_at_error(history: &History, epsilon: f64, out: &mut Vec<[u32; 3]>) {
    triangles_at_step(history, history.step_at_error(epsilon), out);
}

/// A view-dependent mesh: `epsilon_at(column, row)` is the error allowed where a
/// collapse removes its vertex.
pub fn triangles_varying(history: &History, epsilon_at: impl Fn(f64, f64) -> f64) -> Vec<[u32; 3]> {
    let mut applied = vec![false; history.steps() + 1];
    applied[0] = true;
    // Triangles by death, earliest first: each step's removed triangles together.
    let mut t = history.corners.len();
    for step in 1..=history.steps() {
        let vertex = history.step_vertex[step - 1] as usize;
        let (x, y) = (vertex % history.width, vertex / history.width);
        let mut ok = history.step_error[step - 1] <= epsilon_at(x as f64, y as f64);
        while t > 0 && history.death[t - 1] == step as u32 {
            t -= 1;
            ok &= applied[history.birth[t] as usize];
        }
        applied[step] = ok;
    }
    let present = |k: u32| k != NEVER && applied[k as usize];
    (0..history.corners.len())
        .filter(|&t| present(history.birth[t]) && !present(history.death[t]))
        .map(|t| history.corners[t])
        .collect()
}

/// `triangles` (corners as samples) as an indexed mesh of the `width × height` grid.
pub fn grid_mesh(width: usize, height: usize, triangles: &[[u32; 3]]) -> GridMesh {
    let mut vertices: Vec<u32> = triangles.iter().flatten().copied().collect();
    vertices.sort_unstable();
    vertices.dedup();
    let index = |s: u32| vertices.binary_search(&s).expect("a corner") as u32;
    let triangles = triangles.iter().map(|t| t.map(index)).collect();
    GridMesh {
        width,
        height,
        vertices,
        triangles,
    }
}
