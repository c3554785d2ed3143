//! Rate allocation across tiles: how many bytes of each tile's embedded stream a decode
//! of `budget` bytes reads, chosen so that every tile stops at (nearly) the same
//! rate–distortion slope, as JPEG 2000's post-compression rate–distortion optimisation
//! does for code blocks.

use super::index::TileEntry;

/// Bytes of each tile to read so that the tiles together take at most `budget` bytes
/// and the estimated squared error is smallest: every tile gets its header and mask,
/// then the steepest remaining step of any tile's convex rate–distortion hull is taken
/// until the budget runs out (the last one in part: streams are embedded). `None` when
/// the budget does not cover the tiles' headers and masks.
pub fn allocate(entries: &[TileEntry], lossless: bool, budget: u64) -> Option<Vec<u64>> {
    let points: Vec<Vec<(u64, f64)>> = entries
        .iter()
        .map(|e| e.modelled_points(lossless))
        .collect();
    allocate_points(&points, budget)
}

/// [`allocate`] over each tile's rate–distortion points, sorted by prefix length, the
/// first being its header and mask.
pub(crate) fn allocate_points(tiles: &[Vec<(u64, f64)>], budget: u64) -> Option<Vec<u64>> {
    let mut bytes: Vec<u64> = tiles.iter().map(|points| points[0].0).collect();
    let mut left = budget.checked_sub(bytes.iter().sum())?;
    let mut steps: Vec<Step> = Vec::new();
    for (tile, points) in tiles.iter().enumerate() {
        let hull = lower_hull(points);
        for pair in hull.windows(2) {
            steps.push(Step::between(tile, pair[0], pair[1]));
        }
    }
    // Steepest first; ties in tile order (a tile's own steps are strictly less steep
    // one after another, so each tile's steps come in stream order).
    steps.sort_by(|a, b| {
        b.slope
            .total_cmp(&a.slope)
            .then(a.tile.cmp(&b.tile))
            .then(a.from.cmp(&b.from))
    });
    for step in steps {
        if left == 0 {
            break;
        }
        let take = (step.to - step.from).min(left);
        bytes[step.tile] += take;
        left -= take;
    }
    Some(bytes)
}

/// One segment of a tile's rate–distortion hull.
#[derive(Debug, Clone, Copy)]
struct Step {
    tile: usize,
    from: u64,
    to: u64,
    /// Squared error removed per byte.
    slope: f64,
}

impl Step {
    fn between(tile: usize, (from, e0): (u64, f64), (to, e1): (u64, f64)) -> Step {
        Step {
            tile,
            from,
            to,
            slope: (e0 - e1) / (to - from) as f64,
        }
    }
}

/// The lower convex hull of rate–distortion points sorted by bytes (Andrew's monotone
/// chain): the points a rate-optimal truncation can stop at.
fn lower_hull(points: &[(u64, f64)]) -> Vec<(u64, f64)> {
    let mut hull: Vec<(u64, f64)> = Vec::with_capacity(points.len());
    for &p in points {
        if hull.last().is_some_and(|&(x, _)| x >= p.0) {
            // Same offset (a pass that added no bytes): keep the smaller error.
            let last = hull.last_mut().expect("checked");
            last.1 = last.1.min(p.1);
            continue;
        }
        while hull.len() >= 2 && turn(hull[hull.len() - 2], hull[hull.len() - 1], p) <= 0.0 {
            hull.pop();
        }
        hull.push(p);
    }
    hull
}

/// Cross product of `o→a` and `o→b`: positive for a counter-clockwise turn.
fn turn(o: (u64, f64), a: (u64, f64), b: (u64, f64)) -> f64 {
    let (ax, ay) = (a.0 as f64 - o.0 as f64, a.1 - o.1);
    let (bx, by) = (b.0 as f64 - o.0 as f64, b.1 - o.1);
    ax * by - ay * bx
}

#[cfg(test)]
mod tests {
    use super::*;

    fn entry(head_len: u64, initial_error: f64, passes: &[(u64, f64)]) -> TileEntry {
        TileEntry {
            len: passes.last().map_or(head_len, |p| p.0),
            head_len,
            initial_error,
            passes: passes.to_vec(),
        }
    }

    #[test]
    fn hull_drops_points_above_it() {
        let hull = lower_hull(&[(0, 100.0), (10, 90.0), (20, 20.0), (40, 10.0), (50, 9.9)]);
        assert_eq!(hull, vec![(0, 100.0), (20, 20.0), (40, 10.0), (50, 9.9)]);
    }

    #[test]
    fn the_steeper_tile_gets_the_bytes() {
        // Tile 0 gains 1000 for 100 bytes, tile 1 only 10.
        let tiles = [
            entry(5, 1000.0, &[(105, 0.0)]),
            entry(5, 10.0, &[(105, 0.0)]),
        ];
        assert_eq!(allocate(&tiles, true, 10 + 100), Some(vec![105, 5]));
        assert_eq!(allocate(&tiles, true, 10 + 150), Some(vec![105, 55]));
        assert_eq!(allocate(&tiles, true, 1000), Some(vec![105, 105]));
        assert_eq!(allocate(&tiles, true, 9), None);
    }

    #[test]
    fn a_checkpoint_inside_a_pass_lets_a_tile_stop_there() {
        // Tile 0 removes most of its error in the first 10 bytes of its pass: with the
        // checkpoint it is served before tile 1's flatter pass, without it they tie.
        let with = [
            vec![(10, 100.0), (20, 20.0), (110, 0.0)],
            vec![(10, 100.0), (110, 0.0)],
        ];
        assert_eq!(allocate_points(&with, 40), Some(vec![20, 20]));
        let without = [
            with[0][..1].iter().chain(&with[0][2..]).copied().collect(),
            with[1].clone(),
        ];
        assert_eq!(allocate_points(&without, 40), Some(vec![30, 10]));
    }

    #[test]
    fn a_pass_modelled_to_fall_fastest_first_shares_the_budget() {
        // Tile 0's pass lowers its error 100-fold, tile 1's only 2-fold, over the same
        // 1000 bytes. Along straight lines tile 0 is steeper all the way and takes the
        // whole budget; modelled, its pass flattens towards its end, below the start of
        // tile 1's, which then gets the rest.
        let tiles = [
            entry(10, 1000.0, &[(1010, 10.0)]),
            entry(10, 1000.0, &[(1010, 500.0)]),
        ];
        let bytes = allocate(&tiles, false, 20 + 500).unwrap();
        assert_eq!(bytes.iter().sum::<u64>(), 520);
        assert!(bytes[1] > 10 && bytes[0] > bytes[1], "{bytes:?}");
        let straight: Vec<Vec<(u64, f64)>> = tiles.iter().map(|e| e.points(false)).collect();
        assert_eq!(allocate_points(&straight, 20 + 500), Some(vec![510, 10]));
    }

    #[test]
    fn equal_tiles_share_equally() {
        let passes = [(20, 50.0), (60, 10.0), (140, 0.0)];
        let tiles = vec![entry(10, 500.0, &passes); 4];
        let bytes = allocate(&tiles, true, 4 * 60).unwrap();
        assert_eq!(bytes, vec![60; 4]);
    }
}
