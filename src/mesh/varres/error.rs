//! The cost of a collapse. The paper's metric: the largest distance from every original
//! sample the new triangles cover (the removed samples they hold, the removed vertex
//! and the corners) to the average plane of the new triangles, whose normal is the sum
//! of their normals and whose centre is their area-weighted centre. The metric it is
//! compared with (Schroeder et al.'s decimation): the distance of the removed vertex
//! alone to the average plane of its triangles.
//!
//! Deviation from the paper: areas are areas seen from above and distances are
//! vertical, because a DEM's columns and heights are in different units (and the
//! ground size of a cell is often unknown), while the plane itself (the sum of normals
//! is the area-weighted mean gradient) does not depend on that scale. It also makes
//! the bound exact: a sample within ε of the plane under triangles whose corners are
//! within ε of it is within 2ε of the mesh.

use super::topology::Topology;

/// Which error a collapse costs.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ErrorMetric {
    /// The paper's: every sample the new triangles cover against their average plane.
    AveragePlane,
    /// Schroeder et al.'s: the removed vertex against the average plane of its
    /// triangles before the collapse.
    VertexPlane,
}

/// A plane `z = z0 + gx·(x − x0) + gy·(y − y0)` over the grid.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Plane {
    x0: f64,
    y0: f64,
    z0: f64,
    gx: f64,
    gy: f64,
}

impl Plane {
    /// The average plane of `triangles` (corners as samples): normal the sum of their
    /// normals, through their centres weighted by area seen from above. `None` when
    /// they have no area.
    pub fn average(
        topology: &Topology,
        heights: &[f64],
        triangles: impl Iterator<Item = [u32; 3]>,
    ) -> Option<Plane> {
        let (mut normal, mut centre, mut weight) = ([0.0f64; 3], [0.0f64; 3], 0.0f64);
        for t in triangles {
            let [a, b, c] = t.map(|v| point(topology, heights, v));
            let (u, w) = (sub(b, a), sub(c, a));
            let n = [
                u[1] * w[2] - u[2] * w[1],
                u[2] * w[0] - u[0] * w[2],
                u[0] * w[1] - u[1] * w[0],
            ];
            for k in 0..3 {
                normal[k] += n[k];
                centre[k] += n[2] * (a[k] + b[k] + c[k]) / 3.0;
            }
            weight += n[2];
        }
        (weight > 0.0).then(|| Plane {
            x0: centre[0] / weight,
            y0: centre[1] / weight,
            z0: centre[2] / weight,
            gx: -normal[0] / normal[2],
            gy: -normal[1] / normal[2],
        })
    }

    /// Vertical distance from sample `v` to the plane.
    pub fn distance(&self, topology: &Topology, heights: &[f64], v: u32) -> f64 {
        self.distance_to(point(topology, heights, v))
    }

    /// Vertical distance from the point `(x, y, z)` to the plane.
    pub fn distance_to(&self, [x, y, z]: [f64; 3]) -> f64 {
        (z - self.z0 - self.gx * (x - self.x0) - self.gy * (y - self.y0)).abs()
    }
}

/// `(column, row, height)` of sample `v`.
fn point(topology: &Topology, heights: &[f64], v: u32) -> [f64; 3] {
    let (x, y) = topology.xy(v);
    [x as f64, y as f64, heights[v as usize]]
}

fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}
