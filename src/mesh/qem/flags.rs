//! The seed paper's flag map: 4 bits a sample. Bit 3 is the diagonal of the cell whose
//! top-left corner the sample is; bits 0–2 hold the direction (north, east, south, west)
//! to the next sample on the way to the vertex that absorbed this one, or 0 when the
//! sample was never merged. With the height raster it is the whole simplified mesh:
//! [`super::extract_mesh`] is the paper's extraction.

/// Which diagonal splits a cell.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Diagonal {
    /// Top-left to bottom-right.
    Falling,
    /// Bottom-left to top-right.
    Rising,
}

/// A step to a 4-neighbour on the grid.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Direction {
    /// One row up.
    North,
    /// One column right.
    East,
    /// One row down.
    South,
    /// One column left.
    West,
}

impl Direction {
    /// Every direction, in code order (codes 1–4).
    pub const ALL: [Direction; 4] = [
        Direction::North,
        Direction::East,
        Direction::South,
        Direction::West,
    ];

    /// The sample one step from `s` on a grid `width` wide (the caller keeps it inside).
    pub fn step(self, s: usize, width: usize) -> usize {
        match self {
            Direction::North => s - width,
            Direction::East => s + 1,
            Direction::South => s + width,
            Direction::West => s - 1,
        }
    }

    /// The direction back.
    pub fn reverse(self) -> Direction {
        match self {
            Direction::North => Direction::South,
            Direction::East => Direction::West,
            Direction::South => Direction::North,
            Direction::West => Direction::East,
        }
    }

    fn code(self) -> u8 {
        match self {
            Direction::North => 1,
            Direction::East => 2,
            Direction::South => 3,
            Direction::West => 4,
        }
    }
}

/// Four bits a sample, two samples a byte.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct FlagMap {
    width: usize,
    height: usize,
    nibbles: Vec<u8>,
}

const DIAGONAL_BIT: u8 = 0b1000;
const DIRECTION_BITS: u8 = 0b0111;

impl FlagMap {
    /// Every cell falling, no sample merged.
    pub fn new(width: usize, height: usize) -> FlagMap {
        FlagMap {
            width,
            height,
            nibbles: vec![0; (width * height).div_ceil(2)],
        }
    }

    /// Bytes the map holds: half a byte a sample.
    pub fn bytes(&self) -> usize {
        self.nibbles.len()
    }

    fn nibble(&self, s: usize) -> u8 {
        (self.nibbles[s / 2] >> (4 * (s % 2))) & 0xf
    }

    fn set_nibble(&mut self, s: usize, value: u8) {
        let shift = 4 * (s % 2);
        let byte = &mut self.nibbles[s / 2];
        *byte = (*byte & !(0xf << shift)) | (value << shift);
    }

    /// The diagonal of the cell whose top-left corner is sample `s`.
    pub fn diagonal(&self, s: usize) -> Diagonal {
        if self.nibble(s) & DIAGONAL_BIT == 0 {
            Diagonal::Falling
        } else {
            Diagonal::Rising
        }
    }

    /// Sets the diagonal of the cell whose top-left corner is sample `s`.
    pub fn set_diagonal(&mut self, s: usize, diagonal: Diagonal) {
        let bit = if diagonal == Diagonal::Rising {
            DIAGONAL_BIT
        } else {
            0
        };
        self.set_nibble(s, (self.nibble(s) & DIRECTION_BITS) | bit);
    }

    /// The step from `s` towards its merger, `None` when `s` was never merged.
    pub fn direction(&self, s: usize) -> Option<Direction> {
        match self.nibble(s) & DIRECTION_BITS {
            0 => None,
            code => Some(Direction::ALL[usize::from(code) - 1]),
        }
    }

    /// Sets the step from `s` towards its merger (`None`: not merged).
    pub fn set_direction(&mut self, s: usize, direction: Option<Direction>) {
        let code = direction.map_or(0, Direction::code);
        self.set_nibble(s, (self.nibble(s) & DIAGONAL_BIT) | code);
    }

    /// The vertex that finally absorbed `s` (itself when never merged), by following
    /// the directions.
    pub fn find_merger(&self, mut s: usize) -> usize {
        while let Some(step) = self.direction(s) {
            s = step.step(s, self.width);
        }
        s
    }

    /// [`FlagMap::find_merger`] of every sample at once, each chain walked once (path
    /// compression into the returned table).
    pub fn mergers(&self) -> Vec<u32> {
        const UNKNOWN: u32 = u32::MAX;
        let mut merger = vec![UNKNOWN; self.width * self.height];
        let mut chain = Vec::new();
        for start in 0..merger.len() {
            let mut s = start;
            while merger[s] == UNKNOWN {
                chain.push(s);
                match self.direction(s) {
                    Some(step) => s = step.step(s, self.width),
                    None => {
                        merger[s] = s as u32;
                        break;
                    }
                }
            }
            let root = merger[s];
            for t in chain.drain(..) {
                merger[t] = root;
            }
        }
        merger
    }

    /// Writes the merger directions of a partition into clusters: `root_of(s)` is the
    /// vertex that absorbed sample `s` (itself for a survivor). Each cluster must be
    /// connected through 4-neighbours; its directions form a breadth-first tree to its root.
    pub fn record_mergers(&mut self, root_of: impl Fn(usize) -> u32) {
        let (w, h) = (self.width, self.height);
        let mut queue = Vec::new();
        let mut reached = vec![false; w * h];
        for root in 0..w * h {
            if root_of(root) != root as u32 {
                continue;
            }
            self.set_direction(root, None);
            reached[root] = true;
            queue.clear();
            queue.push(root);
            let mut next = 0;
            while next < queue.len() {
                let s = queue[next];
                next += 1;
                for step in Direction::ALL {
                    let Some(t) = neighbour(s, step, w, h) else {
                        continue;
                    };
                    if !reached[t] && root_of(t) == root as u32 {
                        reached[t] = true;
                        self.set_direction(t, Some(step.reverse()));
                        queue.push(t);
                    }
                }
            }
        }
    }
}

/// The 4-neighbour of `s` in direction `step` on a `w × h` grid, if inside.
pub fn neighbour(s: usize, step: Direction, w: usize, h: usize) -> Option<usize> {
    let (x, y) = (s % w, s / w);
    let inside = match step {
        Direction::North => y > 0,
        Direction::East => x + 1 < w,
        Direction::South => y + 1 < h,
        Direction::West => x > 0,
    };
    inside.then(|| step.step(s, w))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_sample_holds_a_diagonal_and_a_direction_in_four_bits() {
        let mut map = FlagMap::new(3, 3);
        assert_eq!(map.bytes(), 5);
        map.set_diagonal(4, Diagonal::Rising);
        map.set_direction(4, Some(Direction::West));
        map.set_direction(5, Some(Direction::South));
        assert_eq!(map.diagonal(4), Diagonal::Rising);
        assert_eq!(map.direction(4), Some(Direction::West));
        assert_eq!(map.diagonal(5), Diagonal::Falling);
        assert_eq!(map.direction(5), Some(Direction::South));
        map.set_diagonal(4, Diagonal::Falling);
        assert_eq!(map.direction(4), Some(Direction::West));
    }

    #[test]
    fn find_merger_follows_the_chain_to_the_survivor() {
        // 3 × 3: the top row and the centre merged into sample 0.
        let clusters = [0, 0, 0, 3, 0, 5, 6, 7, 8];
        let mut map = FlagMap::new(3, 3);
        map.record_mergers(|s| clusters[s]);
        for (s, &root) in clusters.iter().enumerate() {
            assert_eq!(map.find_merger(s), root as usize, "sample {s}");
        }
        assert_eq!(map.mergers(), clusters.to_vec());
        assert_eq!(map.direction(0), None);
        assert_eq!(map.direction(4), Some(Direction::North));
    }
}
