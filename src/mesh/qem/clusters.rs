//! Which vertex absorbed which: every removed vertex (mergee) points at the vertex that
//! absorbed it (merger); [`Clusters::find_merger`] follows the chain with path
//! compression. Each surviving vertex also heads a ring of the samples it absorbed,
//! from which samples whose every neighbour is in the same cluster drop out for good,
//! so a cluster's triangles are found from the samples on its rim.

/// Merger pointers and the cluster rings of a grid.
#[derive(Debug, Clone)]
pub struct Clusters {
    merger: Vec<u32>,
    ring: Vec<u32>,
}

impl Clusters {
    /// Every sample its own cluster.
    pub fn new(samples: usize) -> Clusters {
        let identity: Vec<u32> = (0..samples as u32).collect();
        Clusters {
            merger: identity.clone(),
            ring: identity,
        }
    }

    /// Whether `v` was never merged.
    pub fn is_survivor(&self, v: u32) -> bool {
        self.merger[v as usize] == v
    }

    /// The surviving vertex that absorbed `v` (itself when never merged).
    pub fn find_merger(&mut self, mut v: u32) -> u32 {
        while self.merger[v as usize] != v {
            let up = self.merger[v as usize];
            // Path halving: point at the grandparent on the way up.
            self.merger[v as usize] = self.merger[up as usize];
            v = up;
        }
        v
    }

    /// `merger` absorbs the surviving vertex `mergee` and its cluster.
    pub fn absorb(&mut self, merger: u32, mergee: u32) {
        debug_assert!(self.is_survivor(merger) && self.is_survivor(mergee));
        self.merger[mergee as usize] = merger;
        // Splice the two rings into one.
        self.ring.swap(merger as usize, mergee as usize);
    }

    /// Calls `visit(self, s)` for every sample of survivor `root`'s cluster still on
    /// its rim; `visit` returns whether `s` turned out inside the cluster (every
    /// neighbour in it), and such a sample leaves the ring for good (the root stays).
    pub fn for_each_on_rim(
        &mut self,
        root: u32,
        mut visit: impl FnMut(&mut Clusters, u32) -> bool,
    ) {
        visit(self, root);
        let mut previous = root;
        let mut current = self.ring[root as usize];
        while current != root {
            let next = self.ring[current as usize];
            if visit(self, current) {
                self.ring[previous as usize] = next;
                self.ring[current as usize] = current;
            } else {
                previous = current;
            }
            current = next;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn chains_resolve_to_the_survivor() {
        let mut c = Clusters::new(6);
        c.absorb(1, 0);
        c.absorb(2, 1);
        c.absorb(5, 2);
        assert_eq!(c.find_merger(0), 5);
        assert_eq!(c.find_merger(3), 3);
        assert!(c.is_survivor(5) && !c.is_survivor(2));
        // Path compression: 0 now points higher than 1.
        assert_ne!(c.merger[0], 1);
    }

    #[test]
    fn the_rim_walks_the_cluster_and_drops_inside_samples() {
        let mut c = Clusters::new(5);
        c.absorb(0, 1);
        c.absorb(0, 2);
        c.absorb(3, 4);
        let mut seen = Vec::new();
        c.for_each_on_rim(0, |_, s| {
            seen.push(s);
            s == 2
        });
        seen.sort();
        assert_eq!(seen, vec![0, 1, 2]);
        seen.clear();
        c.for_each_on_rim(0, |_, s| {
            seen.push(s);
            false
        });
        seen.sort();
        assert_eq!(seen, vec![0, 1], "2 left the ring");
        seen.clear();
        c.for_each_on_rim(3, |_, s| {
            seen.push(s);
            false
        });
        seen.sort();
        assert_eq!(seen, vec![3, 4]);
    }
}
