//! Void filling: the samples where the mask is false get a smooth continuation of the
//! valid ones, so filled voids cost almost no bits after the transform.

/// One level of the push–pull pyramid: its size, and per cell the sum and the count of
/// the valid samples it covers.
struct Level {
    width: usize,
    height: usize,
    sums: Vec<f64>,
    weights: Vec<f64>,
}

/// Fills the samples where `mask` is false with a smooth continuation of the valid ones:
/// a push–pull pyramid (averages of valid samples, coarse to fine) followed by a few
/// relaxation sweeps.
pub(crate) fn fill_voids(values: &mut [f64], width: usize, height: usize, mask: &[bool]) {
    if mask.iter().all(|&m| m) {
        return;
    }
    if !mask.iter().any(|&m| m) {
        values.iter_mut().for_each(|v| *v = 0.0);
        return;
    }
    let filled = pull(push(values, width, height, mask));
    for i in 0..values.len() {
        if !mask[i] {
            values[i] = filled[i];
        }
    }
    relax(values, width, height, mask);
}

/// Push: the pyramid of (sum, weight) from the samples up to a single cell.
fn push(values: &[f64], width: usize, height: usize, mask: &[bool]) -> Vec<Level> {
    let sums: Vec<f64> = values
        .iter()
        .zip(mask)
        .map(|(&v, &m)| if m { v } else { 0.0 })
        .collect();
    let weights: Vec<f64> = mask.iter().map(|&m| m as u8 as f64).collect();
    let mut levels = vec![Level {
        width,
        height,
        sums,
        weights,
    }];
    while let Some(level) = levels.last().filter(|l| l.width > 1 || l.height > 1) {
        let (w, h) = (level.width, level.height);
        let (nw, nh) = (w.div_ceil(2), h.div_ceil(2));
        let mut sums = vec![0.0; nw * nh];
        let mut weights = vec![0.0; nw * nh];
        for y in 0..h {
            for x in 0..w {
                let j = (y / 2) * nw + x / 2;
                sums[j] += level.sums[y * w + x];
                weights[j] += level.weights[y * w + x];
            }
        }
        levels.push(Level {
            width: nw,
            height: nh,
            sums,
            weights,
        });
    }
    levels
}

/// Pull: from the coarsest level down, each cell's average of its valid samples, or its
/// parent's average when it has none; the finest level's averages.
fn pull(levels: Vec<Level>) -> Vec<f64> {
    let mut parent: Option<(usize, Vec<f64>)> = None;
    for level in levels.into_iter().rev() {
        let (w, h) = (level.width, level.height);
        let mut avg = vec![0.0; w * h];
        for y in 0..h {
            for x in 0..w {
                let i = y * w + x;
                avg[i] = if level.weights[i] > 0.0 {
                    level.sums[i] / level.weights[i]
                } else if let Some((pw, ref pa)) = parent {
                    pa[(y / 2) * pw + x / 2]
                } else {
                    0.0
                };
            }
        }
        parent = Some((w, avg));
    }
    parent.expect("pyramid has a level").1
}

/// Relax: Gauss–Seidel sweeps of the Laplace equation over the void samples.
fn relax(values: &mut [f64], width: usize, height: usize, mask: &[bool]) {
    let voids: Vec<usize> = (0..values.len()).filter(|&i| !mask[i]).collect();
    for _ in 0..8 {
        for &i in &voids {
            let (x, y) = (i % width, i / width);
            let mut sum = 0.0;
            let mut count = 0.0;
            if x > 0 {
                sum += values[i - 1];
                count += 1.0;
            }
            if x + 1 < width {
                sum += values[i + 1];
                count += 1.0;
            }
            if y > 0 {
                sum += values[i - width];
                count += 1.0;
            }
            if y + 1 < height {
                sum += values[i + width];
                count += 1.0;
            }
            if count > 0.0 {
                values[i] = sum / count;
            }
        }
    }
}
