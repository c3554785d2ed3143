//! Void filling: the samples where the mask is false get a smooth continuation of the
//! valid ones, so filled voids cost almost no bits after the transform.

/// How far from a valid sample the fill is made biharmonic ([`smooth_void_edges`]).
const EDGE_BAND: usize = 4;
/// Gauss–Seidel sweeps of the biharmonic equation over that band.
const EDGE_SWEEPS: usize = 16;

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
/// relaxation sweeps (harmonic; [`smooth_void_edges`] then makes it meet the valid
/// samples with their slope).
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

/// After [`fill_voids`]: Gauss–Seidel sweeps of the biharmonic equation (the 13-point
/// stencil) over the voids within [`EDGE_BAND`] samples of a valid one and two of the
/// image's edges, the other voids keeping the harmonic fill. A harmonic fill meets the
/// terrain with a kink, which the wavelet codes at every level; a biharmonic one
/// continues its slope too (README, *Voids filled biharmonically near the terrain*).
pub(crate) fn smooth_void_edges(values: &mut [f64], width: usize, height: usize, mask: &[bool]) {
    let runs = void_runs_near_valid(mask, width, height);
    for _ in 0..EDGE_SWEEPS {
        for &(start, len) in &runs {
            sweep_run(values, width, start, len);
        }
    }
}

/// One Gauss–Seidel sweep of the biharmonic equation along the `len` samples from
/// `start`, whose rows and columns are at least two samples inside the image.
fn sweep_run(values: &mut [f64], width: usize, start: usize, len: usize) {
    let span = len + 4;
    let (above, rest) = values.split_at_mut(start - 2);
    let (row, below) = rest.split_at_mut(span);
    let up2 = &above[start - 2 * width - 2..][..span];
    let up1 = &above[start - width - 2..][..span];
    let down1 = &below[width - span..][..span];
    let down2 = &below[2 * width - span..][..span];
    for k in 2..len + 2 {
        let near = row[k - 1] + row[k + 1] + up1[k] + down1[k];
        let diagonal = up1[k - 1] + up1[k + 1] + down1[k - 1] + down1[k + 1];
        let far = row[k - 2] + row[k + 2] + up2[k] + down2[k];
        row[k] = (8.0 * near - 2.0 * diagonal - far) * (1.0 / 20.0);
    }
}

/// The voids within [`EDGE_BAND`] samples (in x and y) of a valid sample and at least
/// two samples inside the image, as runs `(start, len)` along rows.
fn void_runs_near_valid(mask: &[bool], width: usize, height: usize) -> Vec<(usize, usize)> {
    let mut in_rows = vec![false; mask.len()];
    for (dst, src) in in_rows
        .chunks_exact_mut(width)
        .zip(mask.chunks_exact(width))
    {
        dilate_row(src, dst);
    }
    let mut near = vec![false; mask.len()];
    for (y, near_row) in near.chunks_exact_mut(width).enumerate() {
        for from in y.saturating_sub(EDGE_BAND)..(y + EDGE_BAND + 1).min(height) {
            for (n, &r) in near_row.iter_mut().zip(&in_rows[from * width..][..width]) {
                *n |= r;
            }
        }
    }
    let mut runs: Vec<(usize, usize)> = Vec::new();
    for y in 2..height.saturating_sub(2) {
        for i in y * width + 2..(y + 1) * width - 2 {
            if mask[i] || !near[i] {
                continue;
            }
            match runs.last_mut() {
                Some((start, len)) if *start + *len == i => *len += 1,
                _ => runs.push((i, 1)),
            }
        }
    }
    runs
}

/// Whether `src` holds a true within [`EDGE_BAND`] places of each place, written to
/// `dst` (a sliding count).
fn dilate_row(src: &[bool], dst: &mut [bool]) {
    let n = src.len();
    let mut inside: usize = src[..n.min(EDGE_BAND)]
        .iter()
        .map(|&v| usize::from(v))
        .sum();
    for k in 0..n {
        if k + EDGE_BAND < n {
            inside += usize::from(src[k + EDGE_BAND]);
        }
        if k > EDGE_BAND {
            inside -= usize::from(src[k - EDGE_BAND - 1]);
        }
        dst[k] = inside > 0;
    }
}
