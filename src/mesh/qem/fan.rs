//! The triangles around one surviving vertex, found from the grid alone: every valid
//! grid triangle with a corner on the vertex's cluster rim, mapped through
//! `find_merger`, kept when its three corners are distinct. From them, whether
//! contracting the vertex onto a neighbour keeps the mesh valid.

use super::clusters::Clusters;
use super::flags::FlagMap;
use super::grid::{orient, Grid, AXIS_NEIGHBOURS};

/// The fan of one surviving vertex.
#[derive(Debug, Clone, Default)]
pub struct Fan {
    /// The surviving vertex.
    pub root: u32,
    /// The far edge `[x, y]` of every triangle `(root, x, y)`, counter-clockwise.
    pub triangles: Vec<[u32; 2]>,
    /// Survivors whose clusters touch the root's through a 4-neighbour step.
    pub axis_neighbours: Vec<u32>,
    /// Every vertex sharing a triangle with the root, once.
    pub link: Vec<u32>,
    /// Link vertices joined to the root by an outline edge (one triangle only).
    pub outline: Vec<u32>,
}

impl Fan {
    /// Gathers the fan of survivor `root` (scratch vectors reused).
    pub fn gather(&mut self, grid: &Grid, flags: &FlagMap, clusters: &mut Clusters, root: u32) {
        self.root = root;
        self.triangles.clear();
        self.axis_neighbours.clear();
        let (triangles, axis) = (&mut self.triangles, &mut self.axis_neighbours);
        clusters.for_each_on_rim(root, |clusters, s| {
            let roots = grid
                .neighbours(s as usize)
                .map(|t| t.map(|t| clusters.find_merger(t)));
            if roots.iter().all(|&r| r.is_none_or(|r| r == root)) {
                return true;
            }
            grid.triangles_around(flags, s as usize, |u, w| {
                if let (Some(fu), Some(fw)) = (roots[u], roots[w]) {
                    if fu != root && fw != root && fu != fw {
                        triangles.push([fu, fw]);
                    }
                }
            });
            axis.extend(
                AXIS_NEIGHBOURS
                    .iter()
                    .filter_map(|&k| roots[k])
                    .filter(|&r| r != root),
            );
            false
        });
        self.axis_neighbours.sort_unstable();
        self.axis_neighbours.dedup();
        self.sort_link();
    }

    /// Fills `link` and `outline` from `triangles`.
    fn sort_link(&mut self) {
        // Each link vertex with its ends: 0 as a triangle's first far corner, 1 second.
        let mut ends: Vec<(u32, u8)> = self
            .triangles
            .iter()
            .flat_map(|&[x, y]| [(x, 0), (y, 1)])
            .collect();
        ends.sort_unstable();
        self.link.clear();
        self.outline.clear();
        for group in ends.chunk_by(|a, b| a.0 == b.0) {
            self.link.push(group[0].0);
            if group.len() == 1 {
                self.outline.push(group[0].0);
            }
        }
    }

    /// Whether the root's cluster has any triangle.
    pub fn is_empty(&self) -> bool {
        self.triangles.is_empty()
    }

    /// The triangles that vanish if the root contracts onto link vertex `merger`, or
    /// `None` when that contraction would break the mesh: a triangle flipped or flat
    /// seen from above, the outline moved (an outline vertex only slides along a
    /// straight outline edge onto its neighbour), or clusters not joined through a
    /// 4-neighbour (the flag map's directions need that).
    pub fn contraction(&self, width: usize, merger: u32) -> Option<usize> {
        if self.axis_neighbours.binary_search(&merger).is_err() {
            return None;
        }
        match self.outline[..] {
            [] => {}
            [c, b] | [b, c] if b == merger => {
                if !straight_between(width, c, self.root, b) {
                    return None;
                }
            }
            _ => return None,
        }
        let mut removed = 0;
        for &[x, y] in &self.triangles {
            if x == merger || y == merger {
                removed += 1;
            } else if orient(width, merger, x, y) <= 0 {
                return None;
            }
        }
        Some(removed)
    }
}

/// Whether `a` lies on the straight segment from `c` to `b`, strictly between them.
fn straight_between(width: usize, c: u32, a: u32, b: u32) -> bool {
    let xy = |s: u32| ((s as usize % width) as i64, (s as usize / width) as i64);
    let ((cx, cy), (ax, ay), (bx, by)) = (xy(c), xy(a), xy(b));
    orient(width, c, a, b) == 0 && (ax - cx) * (bx - ax) + (ay - cy) * (by - ay) > 0
}

#[cfg(test)]
mod tests {
    use super::*;
    use bitvec::prelude::*;

    fn flat(w: usize, h: usize) -> (Vec<f64>, BitVec<u64, Lsb0>) {
        (vec![0.0; w * h], bitvec![u64, Lsb0; 1; w * h])
    }

    #[test]
    fn an_inner_sample_has_a_closed_fan() {
        let (heights, valid) = flat(3, 3);
        let grid = Grid {
            width: 3,
            height: 3,
            heights: &heights,
            valid: &valid,
        };
        let flags = grid.flag_map();
        let mut clusters = Clusters::new(9);
        let mut fan = Fan::default();
        fan.gather(&grid, &flags, &mut clusters, 4);
        assert_eq!(fan.triangles.len(), 6);
        assert!(fan.outline.is_empty());
        assert_eq!(fan.axis_neighbours, vec![1, 3, 5, 7]);
        // Onto a 4-neighbour: two triangles go, none flips.
        assert_eq!(fan.contraction(3, 1), Some(2));
        // Onto the diagonal neighbour 0: not joined by a 4-neighbour step.
        assert_eq!(fan.contraction(3, 0), None);
    }

    #[test]
    fn outline_samples_slide_only_along_a_straight_outline() {
        let (heights, valid) = flat(3, 3);
        let grid = Grid {
            width: 3,
            height: 3,
            heights: &heights,
            valid: &valid,
        };
        let flags = grid.flag_map();
        let mut clusters = Clusters::new(9);
        let mut fan = Fan::default();
        fan.gather(&grid, &flags, &mut clusters, 1);
        assert_eq!(fan.outline.len(), 2);
        assert_eq!(fan.contraction(3, 0), Some(1), "along the top side");
        assert_eq!(fan.contraction(3, 4), None, "inwards moves the outline");
        fan.gather(&grid, &flags, &mut clusters, 0);
        assert_eq!(fan.contraction(3, 1), None, "a corner never moves");
    }

    #[test]
    fn a_contraction_that_folds_or_flattens_a_triangle_is_refused() {
        // Root 12 at (2, 2) of a 5-wide grid; its link 14, 22, 10, 6, 1 is not convex.
        let mut link = vec![14, 22, 10, 6, 1];
        let triangles = (0..5).map(|k| [link[k], link[(k + 1) % 5]]).collect();
        link.sort();
        let fan = Fan {
            root: 12,
            triangles,
            axis_neighbours: vec![10, 14, 22],
            link,
            outline: Vec::new(),
        };
        // Onto 10 at (0, 2): triangle 6 (1, 1), 1 (1, 0) turns clockwise.
        assert_eq!(fan.contraction(5, 10), None);
        assert_eq!(fan.contraction(5, 14), Some(2));
        assert_eq!(fan.contraction(5, 22), Some(2));
    }
}
