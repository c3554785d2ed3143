//! The triangles waiting to be split, worst first: a binary max-heap that knows where
//! each triangle sits in it, so a triangle assessed again moves in place (or leaves)
//! instead of leaving a stale entry behind.

/// Not in the heap.
const ABSENT: u32 = u32::MAX;

/// Triangles keyed by error; ties go to the higher triangle index, so the worst is
/// the same whatever order the keys were set in.
#[derive(Debug, Clone, Default)]
pub struct WorstFirst {
    /// `error bits << 32 | triangle`: errors are never negative, so their bits order
    /// them, and one `u128` comparison orders (error, triangle) without a branch.
    heap: Vec<u128>,
    /// Each triangle's index in `heap`, or [`ABSENT`].
    position: Vec<u32>,
}

impl WorstFirst {
    /// The worst triangle, if any is waiting.
    #[inline]
    pub fn worst(&self) -> Option<u32> {
        self.heap.first().map(|&key| key as u32)
    }

    /// Queues triangle `t` with `error` (≥ 0), or moves it there if already queued.
    #[inline]
    pub fn set(&mut self, t: u32, error: f64) {
        if self.position.len() <= t as usize {
            self.position.resize(t as usize + 1, ABSENT);
        }
        let key = u128::from(error.to_bits()) << 32 | u128::from(t);
        match self.position[t as usize] {
            ABSENT => {
                self.heap.push(key);
                self.place(self.heap.len() - 1);
                self.sift_up(self.heap.len() - 1);
            }
            at => {
                let at = at as usize;
                let old = std::mem::replace(&mut self.heap[at], key);
                if key > old {
                    self.sift_up(at);
                } else {
                    self.sift_down(at);
                }
            }
        }
    }

    /// Takes triangle `t` out of the queue (nothing when it is not queued).
    #[inline]
    pub fn remove(&mut self, t: u32) {
        let Some(&at) = self.position.get(t as usize) else {
            return;
        };
        if at == ABSENT {
            return;
        }
        let (at, last) = (at as usize, self.heap.len() - 1);
        self.position[t as usize] = ABSENT;
        self.heap.swap(at, last);
        let removed = self.heap.pop().expect("not empty");
        if at < self.heap.len() {
            self.place(at);
            if self.heap[at] > removed {
                self.sift_up(at);
            } else {
                self.sift_down(at);
            }
        }
    }

    /// Records where the entry at `at` now sits.
    #[inline]
    fn place(&mut self, at: usize) {
        self.position[self.heap[at] as u32 as usize] = at as u32;
    }

    /// Moves the entry at `at` up to its place: smaller parents move down into the hole
    /// it leaves (one write an entry moved, no swaps).
    #[inline]
    fn sift_up(&mut self, mut at: usize) {
        let entry = self.heap[at];
        while at > 0 {
            let parent = (at - 1) / 2;
            if self.heap[parent] >= entry {
                break;
            }
            self.heap[at] = self.heap[parent];
            self.place(at);
            at = parent;
        }
        self.heap[at] = entry;
        self.place(at);
    }

    /// Moves the entry at `at` down to its place: larger children move up into the hole.
    #[inline]
    fn sift_down(&mut self, mut at: usize) {
        let (n, entry) = (self.heap.len(), self.heap[at]);
        loop {
            let left = 2 * at + 1;
            if left >= n {
                break;
            }
            let right = left + 1;
            let child = left + usize::from(right < n && self.heap[right] > self.heap[left]);
            if self.heap[child] <= entry {
                break;
            }
            self.heap[at] = self.heap[child];
            self.place(at);
            at = child;
        }
        self.heap[at] = entry;
        self.place(at);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_worst_comes_first_through_updates_and_removals() {
        let mut queue = WorstFirst::default();
        let mut errors = [3.0, 7.5, 1.0, 7.5, 0.25, 9.0, 4.0];
        for (t, &e) in errors.iter().enumerate() {
            queue.set(t as u32, e);
        }
        queue.set(5, 0.5);
        errors[5] = 0.5;
        queue.remove(3);
        queue.remove(3);
        queue.set(2, 8.0);
        errors[2] = 8.0;
        let mut order = Vec::new();
        while let Some(t) = queue.worst() {
            order.push(t);
            queue.remove(t);
        }
        assert_eq!(order, [2, 1, 6, 0, 5, 4]);
        assert!(order
            .windows(2)
            .all(|w| errors[w[0] as usize] >= errors[w[1] as usize]));
    }

    #[test]
    fn ties_go_to_the_higher_triangle() {
        let mut queue = WorstFirst::default();
        for t in [4, 9, 2] {
            queue.set(t, 1.0);
        }
        assert_eq!(queue.worst(), Some(9));
    }
}
