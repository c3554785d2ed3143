//! Vertex classes (seed paper 001, after Algorri and Schmitt): an edge is a feature
//! edge when the normals of its two triangles differ by more than the feature angle;
//! a vertex with no feature edge is plain, with two a ridge vertex, with one or more
//! than two a peak. Border vertices are boundary vertices when their two border edges
//! are collinear (so sliding along them keeps the outline) and peaks otherwise.
//! A class says where a vertex may move: a plain vertex along any edge, a ridge
//! vertex along its ridge, a boundary vertex along the border, a peak nowhere.

use super::topology::{Star, Topology};

/// What a vertex is, and so where it may collapse to.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Class {
    /// No feature edge: may collapse along any edge.
    Plain,
    /// Exactly two feature edges: may collapse onto either far end.
    Ridge([u32; 2]),
    /// On the border between collinear border edges: may collapse onto either far end.
    Boundary([u32; 2]),
    /// A corner, a peak, a non-manifold vertex: never moves.
    Peak,
}

impl Class {
    /// The vertices a vertex of this class with `star` may collapse onto.
    pub fn targets<'a>(&'a self, star: &'a Star) -> &'a [u32] {
        match self {
            Class::Plain => &star.ring,
            Class::Ridge(ends) | Class::Boundary(ends) => ends,
            Class::Peak => &[],
        }
    }
}

/// How feature edges are told.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FeatureRule {
    /// Cosine of the feature angle: normals closer than this make a feature edge.
    pub cos_angle: f64,
    /// Heights are multiplied by this before normals are taken (columns and rows are
    /// one unit apart), so the angle means the same on any vertical unit.
    pub z_scale: f64,
}

/// The class of vertex `v` whose star is `star`.
pub fn classify(
    topology: &Topology,
    heights: &[f64],
    rule: &FeatureRule,
    v: u32,
    star: &Star,
) -> Class {
    if topology.non_manifold[v as usize] {
        return Class::Peak;
    }
    if star.boundary {
        return boundary_class(topology, v, star);
    }
    let n = star.triangles.len();
    let normals: Vec<[f64; 3]> = star
        .triangles
        .iter()
        .map(|&t| unit_normal(topology, heights, rule.z_scale, t))
        .collect();
    let mut features = [0u32; 2];
    let mut count = 0;
    for i in 0..n {
        let (before, after) = (normals[(i + n - 1) % n], normals[i]);
        let cos = before[0] * after[0] + before[1] * after[1] + before[2] * after[2];
        if cos < rule.cos_angle {
            if count < 2 {
                features[count] = star.ring[i];
            }
            count += 1;
        }
    }
    match count {
        0 => Class::Plain,
        2 => Class::Ridge(features),
        _ => Class::Peak,
    }
}

/// A border vertex between two collinear border edges slides along them; any other
/// border vertex is a corner of the outline and stays.
fn boundary_class(topology: &Topology, v: u32, star: &Star) -> Class {
    let (first, last) = (star.ring[0], star.ring[star.ring.len() - 1]);
    let (p, q, c) = (topology.xy(first), topology.xy(last), topology.xy(v));
    let straight = topology.orient(first, v, last) == 0
        && (p.0 - c.0) * (q.0 - c.0) + (p.1 - c.1) * (q.1 - c.1) < 0;
    if straight {
        Class::Boundary([first, last])
    } else {
        Class::Peak
    }
}

/// The unit normal of triangle `t` with heights scaled by `z_scale`.
pub fn unit_normal(topology: &Topology, heights: &[f64], z_scale: f64, t: u32) -> [f64; 3] {
    let point = |v: u32| {
        let (x, y) = topology.xy(v);
        [x as f64, y as f64, heights[v as usize] * z_scale]
    };
    let [a, b, c] = topology.corners[t as usize].map(point);
    let (u, w) = (
        [b[0] - a[0], b[1] - a[1], b[2] - a[2]],
        [c[0] - a[0], c[1] - a[1], c[2] - a[2]],
    );
    let n = [
        u[1] * w[2] - u[2] * w[1],
        u[2] * w[0] - u[0] * w[2],
        u[0] * w[1] - u[1] * w[0],
    ];
    let length = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
    n.map(|c| c / length)
}
