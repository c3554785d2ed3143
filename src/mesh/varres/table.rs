//! The seed paper's Table 1: its error metric against the distance-to-plane metric
//! of Schroeder et al., as simplification ratio (share of the grid's vertices
//! removed) against the mean distance between the samples and the simplified mesh.
//! Distances are vertical (the mesh rasterised back onto every sample it covers).

use bitvec::prelude::*;
use serde::Serialize;

use super::extract::{grid_mesh, triangles_at_step};
use super::{build_model, ErrorMetric, VarresError, VarresOptions};
use crate::mesh::rasterise::rasterise;

/// The paper's simplification ratios.
pub const PAPER_RATIOS: [f64; 3] = [0.62, 0.70, 0.81];

/// One cell of the table: a metric at a ratio.
#[derive(Debug, Clone, Serialize)]
pub struct MetricRow {
    /// `average_plane` (the paper's) or `vertex_plane` (distance to plane).
    pub metric: &'static str,
    /// Share of the grid's vertices removed, percent.
    pub ratio_percent: f64,
    /// Triangles of the mesh.
    pub triangles: usize,
    /// Mean vertical distance from the valid samples to the mesh, data units.
    pub mean_error: f64,
    /// Largest vertical distance, data units.
    pub max_error: f64,
}

/// The table for one grid: both metrics at every ratio of [`PAPER_RATIOS`].
pub fn metric_table(
    width: usize,
    height: usize,
    heights: &[f64],
    valid: &BitSlice<u64, Lsb0>,
) -> Result<Vec<MetricRow>, VarresError> {
    let vertices = valid.count_ones();
    let mut rows = Vec::new();
    for (metric, name) in [
        (ErrorMetric::AveragePlane, "average_plane"),
        (ErrorMetric::VertexPlane, "vertex_plane"),
    ] {
        let options = VarresOptions {
            metric,
            // Removing 81 % of the vertices leaves about 38 % of the triangles: stop
            // below that.
            min_triangles: vertices / 3,
            ..VarresOptions::default()
        };
        let model = build_model(width, height, heights, valid, &options)?;
        let mut triangles = Vec::new();
        for ratio in PAPER_RATIOS {
            let step = ((vertices as f64 * ratio).round() as usize).min(model.steps());
            triangles_at_step(&model, step, &mut triangles);
            let (mean_error, max_error) = distances(width, height, heights, valid, &triangles);
            rows.push(MetricRow {
                metric: name,
                ratio_percent: 100.0 * step as f64 / vertices as f64,
                triangles: triangles.len(),
                mean_error,
                max_error,
            });
        }
    }
    Ok(rows)
}

/// Mean and largest vertical distance from the valid samples `triangles` cover to them.
fn distances(
    width: usize,
    height: usize,
    heights: &[f64],
    valid: &BitSlice<u64, Lsb0>,
    triangles: &[[u32; 3]],
) -> (f64, f64) {
    let (surface, covered) = rasterise(&grid_mesh(width, height, triangles), heights);
    let (mut sum, mut max, mut count) = (0.0f64, 0.0f64, 0usize);
    for s in valid.iter_ones().filter(|&s| covered[s]) {
        let e = (surface[s] - heights[s]).abs();
        sum += e;
        max = max.max(e);
        count += 1;
    }
    (sum / count.max(1) as f64, max)
}
