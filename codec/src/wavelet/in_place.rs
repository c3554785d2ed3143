//! The 9/7 inverse of coefficients kept as `i16` slots, its samples written over the
//! slots: the coarser levels are inverted whole in an `f32` copy of the level-1 LL
//! region (a quarter of the image), the finest level a few rows at a time (each output
//! row into the slots of rows it no longer reads), then the rows are put in order. Every
//! sample gets the `f64` operations on the same `f32` inputs as in [`inverse_97`], so the
//! samples are those of [`inverse_97`] bit for bit.

use super::{inverse_97, regions, subbands, Kernel, Orientation, CDF97};

/// [`inverse_97`] of the coefficients whose slots are `data` (`width × height`, Mallat
/// layout), writing `sample` of each output value over the slots. `real(band, start,
/// slots, out)` gives the `f32` values of `slots`, a run of band `band` ([`subbands`]
/// order) starting at index `start`. The working memory beside `data` is an `f32` copy of
/// the level-1 LL region and a few rows.
///
/// # Panics
///
/// If `data.len() != width * height` or `levels > max_levels(width, height)`.
pub fn inverse_97_i16(
    data: &mut [i16],
    (width, height, levels): (usize, usize, u32),
    real: impl Fn(usize, usize, &[i16], &mut [f32]),
    sample: impl Fn(f32) -> i16,
) {
    super::check_args(data.len(), width, height, levels);
    if width == 0 || height == 0 {
        return;
    }
    let bands = subbands(width, height, levels);
    let ll = level_one_ll(data, width, height, levels, &bands, &real);
    let mut rows = Rows {
        data,
        width,
        nl: height.div_ceil(2),
        ll,
        lw: width.div_ceil(2),
        // The last three bands, in subbands order.
        fine: [3, 2, 1].map(|k| bands.len().saturating_sub(k)),
        levels,
        bands,
        real,
        sample,
        scratch: vec![0.0; width],
    };
    if levels == 0 {
        for y in 0..height {
            rows.emit_ll(y);
        }
        return;
    }
    synthesize_finest(&mut rows, width, height);
    interleave_rows(rows.data, width, rows.nl);
}

/// The level-1 LL region (the whole image with no level) as `f32`, its coarser levels
/// inverted.
fn level_one_ll(
    data: &[i16],
    width: usize,
    height: usize,
    levels: u32,
    bands: &[super::Subband],
    real: &impl Fn(usize, usize, &[i16], &mut [f32]),
) -> Vec<f32> {
    let (lw, lh) = regions(width, height, levels.min(1))[levels.min(1) as usize];
    let mut ll = vec![0.0f32; lw * lh];
    for (b, sub) in bands
        .iter()
        .enumerate()
        .filter(|(_, s)| s.width > 0 && (s.level > 1 || s.orientation == Orientation::LL))
    {
        for y in sub.y0..sub.y0 + sub.height {
            let start = y * width + sub.x0;
            let out = &mut ll[y * lw + sub.x0..][..sub.width];
            real(b, start, &data[start..start + sub.width], out);
        }
    }
    inverse_97(&mut ll, lw, lh, levels.saturating_sub(1));
    ll
}

/// The finest level's reader and writer: the slots, the level-1 LL region, and what
/// makes values of slots and slots of samples.
struct Rows<'a, R, S> {
    data: &'a mut [i16],
    width: usize,
    /// Rows of the low band (the first `nl` rows).
    nl: usize,
    ll: Vec<f32>,
    /// Columns of the low band.
    lw: usize,
    /// The level-1 HL, LH and HH bands' indices.
    fine: [usize; 3],
    levels: u32,
    bands: Vec<super::Subband>,
    real: R,
    sample: S,
    scratch: Vec<f32>,
}

impl<R: Fn(usize, usize, &[i16], &mut [f32]), S: Fn(f32) -> i16> Rows<'_, R, S> {
    /// Row `r` of the level-1 layout (`r < nl`: low band) widened, into `out`.
    fn load(&mut self, r: usize, out: &mut [f64]) {
        let (w, lw) = (self.width, self.lw);
        let [hl, lh, hh] = self.fine;
        let start = r * w;
        if r < self.nl {
            for (o, &v) in out.iter_mut().zip(&self.ll[r * lw..(r + 1) * lw]) {
                *o = f64::from(v);
            }
            self.real_run(hl, start + lw, w - lw);
        } else {
            self.real_run(lh, start, lw);
            for (o, &v) in out.iter_mut().zip(&self.scratch[..lw]) {
                *o = f64::from(v);
            }
            self.real_run(hh, start + lw, w - lw);
        }
        for (o, &v) in out[lw..].iter_mut().zip(&self.scratch[..w - lw]) {
            *o = f64::from(v);
        }
    }

    /// The values of `len` slots of band `b` from `start` into the scratch row.
    fn real_run(&mut self, b: usize, start: usize, len: usize) {
        debug_assert_eq!(self.bands[b].width, len);
        if len > 0 {
            (self.real)(
                b,
                start,
                &self.data[start..start + len],
                &mut self.scratch[..len],
            );
        }
    }

    /// Output row `r`, in `values` (`f32` values widened), lifted horizontally and
    /// written as samples into the slots of the rows its pair was read from.
    fn emit(&mut self, r: usize, values: &mut [f64]) {
        let w = self.width;
        for v in values.iter_mut() {
            *v = f64::from(*v as f32);
        }
        let nlw = w.div_ceil(2);
        let (lo, hi) = values.split_at_mut(nlw);
        CDF97.synthesize(lo, hi, 1);
        let slot = slot_of(r, self.nl);
        let out = &mut self.data[slot * w..(slot + 1) * w];
        for (o, &l) in out.iter_mut().step_by(2).zip(lo.iter()) {
            *o = (self.sample)(l as f32);
        }
        for (o, &h) in out.iter_mut().skip(1).step_by(2).zip(hi.iter()) {
            *o = (self.sample)(h as f32);
        }
    }

    /// Row `y` of an image of no level: its coefficients made samples in place.
    fn emit_ll(&mut self, y: usize) {
        debug_assert_eq!(self.levels, 0);
        let w = self.width;
        for x in 0..w {
            self.data[y * w + x] = (self.sample)(self.ll[y * w + x]);
        }
    }
}

/// One row of the vertical lifting per low and high index, three of each kept (the
/// lifting steps reach one row each way).
struct Ring {
    lo: [Vec<f64>; 3],
    hi: [Vec<f64>; 3],
}

/// The finest level: vertical synthesis streamed down the rows (each row of the low
/// and high bands loaded once, the four lifting steps of [`CDF97`] applied as soon as
/// their neighbours are there), each output pair lifted horizontally and emitted.
fn synthesize_finest<R, S>(rows: &mut Rows<'_, R, S>, width: usize, height: usize)
where
    R: Fn(usize, usize, &[i16], &mut [f32]),
    S: Fn(f32) -> i16,
{
    let (nl, nh) = (height.div_ceil(2), height / 2);
    let mut ring = Ring {
        lo: std::array::from_fn(|_| vec![0.0; width]),
        hi: std::array::from_fn(|_| vec![0.0; width]),
    };
    if nh == 0 {
        // One row: no vertical lifting (nor its scaling).
        rows.load(0, &mut ring.lo[0]);
        rows.emit(0, &mut ring.lo[0]);
        return;
    }
    let steps = CDF97.steps;
    let (delta, gamma, beta, alpha) = (steps[3], steps[2], steps[1], steps[0]);
    let (lo_scale, hi_scale) = (1.0 / CDF97.lo_gain, 1.0 / CDF97.hi_gain);
    let up = |k: usize| k.saturating_sub(1);
    for t in 0..nl + 2 {
        if t < nl {
            let l = &mut ring.lo[t % 3];
            rows.load(t, l);
            l.iter_mut().for_each(|v| *v *= lo_scale);
            if t < nh {
                let h = &mut ring.hi[t % 3];
                rows.load(nl + t, h);
                h.iter_mut().for_each(|v| *v *= hi_scale);
            }
            lift_row(&mut ring.lo, &ring.hi, t, (up(t), t.min(nh - 1)), delta);
        }
        if let Some(k) = t.checked_sub(1) {
            if k < nh {
                lift_row(&mut ring.hi, &ring.lo, k, (k, (k + 1).min(nl - 1)), gamma);
            }
            if k < nl {
                lift_row(&mut ring.lo, &ring.hi, k, (up(k), k.min(nh - 1)), beta);
            }
        }
        if let Some(k) = t.checked_sub(2) {
            if k < nh {
                lift_row(&mut ring.hi, &ring.lo, k, (k, (k + 1).min(nl - 1)), alpha);
            }
            if k < nl {
                rows.emit(2 * k, &mut ring.lo[k % 3]);
            }
            if k < nh {
                rows.emit(2 * k + 1, &mut ring.hi[k % 3]);
            }
        }
    }
}

/// `rows[k] −= c · (others[a] + others[b])` over a row, in the three-row rings: the
/// update step of [`super::update`] (`rows` the low-pass ring, `others` the high-pass
/// one) or the predict step of [`super::predict`] (the other way round).
fn lift_row(
    rows: &mut [Vec<f64>; 3],
    others: &[Vec<f64>; 3],
    k: usize,
    (a, b): (usize, usize),
    c: f64,
) {
    let (a, b) = (&others[a % 3], &others[b % 3]);
    for ((r, &x), &y) in rows[k % 3].iter_mut().zip(a).zip(b) {
        *r -= c * (x + y);
    }
}

/// The slot of output row `r`: row `2k` goes to slot `k`, row `2k + 1` to slot
/// `nl + k` (where the finest level's low and high rows `k` were).
fn slot_of(r: usize, nl: usize) -> usize {
    if r.is_multiple_of(2) {
        r / 2
    } else {
        nl + r / 2
    }
}

/// Puts the rows in order: row `2k` of the image is in slot `k`, row `2k + 1` in slot
/// `nl + k` (`width` slots a row), each moved once along its cycle of the permutation.
pub(crate) fn interleave_rows(data: &mut [i16], width: usize, nl: usize) {
    let height = data.len() / width.max(1);
    let mut done = vec![false; height];
    let mut kept = vec![0i16; width];
    for start in 0..height {
        if done[start] || slot_of(start, nl) == start {
            continue;
        }
        kept.copy_from_slice(&data[start * width..(start + 1) * width]);
        let mut at = start;
        loop {
            done[at] = true;
            let from = slot_of(at, nl);
            if from == start {
                data[at * width..(at + 1) * width].copy_from_slice(&kept);
                break;
            }
            data.copy_within(from * width..(from + 1) * width, at * width);
            at = from;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::wavelet::max_levels;

    /// A sample made of every bit of an `f32`, so that any difference shows.
    fn bits_sample(v: f32) -> i16 {
        let b = v.to_bits();
        (b ^ b >> 16) as i16
    }

    /// Each slot's value: a pseudo-random `f32` drawn from the slot (its index and
    /// value), as a dequantiser makes one of both.
    fn value_of(i: usize, slot: i16) -> f32 {
        let mut z = (i as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15) ^ slot as u64;
        z = (z ^ (z >> 29)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        ((z >> 40) as f32 / (1u64 << 24) as f32 - 0.5) * 4000.0
    }

    /// The in-place inverse of random slots against [`inverse_97`] of their values.
    fn check(width: usize, height: usize, levels: u32, seed: u64) {
        let n = width * height;
        let slots: Vec<i16> = (0..n)
            .map(|i| (value_of(i + seed as usize, 0) * 8.0) as i16)
            .collect();
        let mut expected: Vec<f32> = (0..n).map(|i| value_of(i, slots[i])).collect();
        inverse_97(&mut expected, width, height, levels);
        let bands = subbands(width, height, levels);
        let mut data = slots.clone();
        inverse_97_i16(
            &mut data,
            (width, height, levels),
            |b, start, run, out| {
                let sub = bands[b];
                let (x, y) = (start % width, start / width);
                assert!(
                    x >= sub.x0 && x + run.len() <= sub.x0 + sub.width,
                    "{b} {sub:?} {start} {} {width}x{height}",
                    run.len()
                );
                assert!(y >= sub.y0 && y < sub.y0 + sub.height);
                for (k, (o, &s)) in out.iter_mut().zip(run).enumerate() {
                    *o = value_of(start + k, s);
                }
            },
            bits_sample,
        );
        let expected: Vec<i16> = expected.into_iter().map(bits_sample).collect();
        assert_eq!(data, expected, "{width}x{height}, {levels} levels");
    }

    #[test]
    fn in_place_inverse_matches_inverse_97_bit_for_bit() {
        let sizes = [
            (1, 1),
            (1, 2),
            (2, 1),
            (1, 9),
            (13, 1),
            (2, 2),
            (3, 3),
            (5, 4),
            (4, 7),
            (17, 33),
            (64, 48),
            (65, 47),
            (100, 3),
            (3, 100),
        ];
        for (k, &(w, h)) in sizes.iter().enumerate() {
            for levels in 0..=max_levels(w, h) {
                check(w, h, levels, k as u64);
            }
        }
    }

    #[test]
    fn rows_are_interleaved_back_in_order() {
        for height in 1..12usize {
            let nl = height.div_ceil(2);
            let width = 3;
            // Row r of the image holds r in each of its samples: the even rows first,
            // then the odd ones.
            let order = (0..height).step_by(2).chain((1..height).step_by(2));
            let mut data: Vec<i16> = order.flat_map(|r| [r as i16; 3]).collect();
            interleave_rows(&mut data, width, nl);
            let expected: Vec<i16> = (0..height * width).map(|i| (i / width) as i16).collect();
            assert_eq!(data, expected, "height {height}");
        }
    }
}
