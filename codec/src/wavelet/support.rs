//! Which coefficients reach a valid sample: a coefficient whose synthesis support holds
//! no valid sample changes only voids, so the encoder may zero it and spend no bits on
//! what the nodata mask hides anyway.
//!
//! The inverse transform is local: one level's inverse rebuilds sample `p` of a 1-D
//! signal from the low-pass outputs `s[i]` with `|2i − p| ≤ reach_low` and the high-pass
//! outputs `d[i]` with `|2i + 1 − p| ≤ reach_high` (5/3: 1 and 2, the supports of its
//! 3- and 5-tap synthesis filters; 13/11: 5 and 6, of its 11 and 13; 9/7: 3 and 4, of
//! its 7 and 9), and whole-sample symmetric extension mirrors an out-of-range position
//! back inside that window. A level transforms rows then columns, so a coefficient's
//! reach in the finer signal is the product of its row and column windows. Rounding
//! (integer wavelets) and `f32` stores (9/7) are done sample by sample, so a zeroed
//! coefficient outside every valid sample's windows leaves every valid sample's
//! reconstruction bit for bit the same.

use super::{regions, Wavelet};

/// Zeroes the coefficients of a `levels`-level transform in `data` (Mallat layout,
/// row-major, `width × height`) whose synthesis support holds no sample where `valid`
/// is true (nothing to do without voids).
pub(crate) fn zero_unreached<T: Copy + Default>(
    data: &mut [T],
    width: usize,
    height: usize,
    levels: u32,
    wavelet: Wavelet,
    valid: &[bool],
) {
    if valid.iter().all(|&v| v) {
        return;
    }
    let reach = Reach::of(wavelet);
    let regions = regions(width, height, levels);
    // `needed` covers the signal one level finer than the region being visited.
    let mut needed = valid.to_vec();
    for &(lw, lh) in &regions[..levels as usize] {
        let rows = reach.dilate_rows(&needed, lw, lh);
        let region = reach.dilate_columns(&rows, lw, lh);
        let (cw, ch) = (lw.div_ceil(2), lh.div_ceil(2));
        for y in 0..lh {
            for x in 0..lw {
                if (x >= cw || y >= ch) && !region[y * lw + x] {
                    data[y * width + x] = T::default();
                }
            }
        }
        needed = (0..ch)
            .flat_map(|y| region[y * lw..y * lw + cw].iter().copied())
            .collect();
    }
    let (llw, llh) = regions[levels as usize];
    for y in 0..llh {
        for x in 0..llw {
            if !needed[y * llw + x] {
                data[y * width + x] = T::default();
            }
        }
    }
}

/// How far one level's low- and high-pass outputs reach into the finer signal.
struct Reach {
    low: usize,
    high: usize,
}

impl Reach {
    fn of(wavelet: Wavelet) -> Reach {
        match wavelet {
            Wavelet::Int53 => Reach { low: 1, high: 2 },
            Wavelet::Int1311 => Reach { low: 5, high: 6 },
            Wavelet::Cdf97 => Reach { low: 3, high: 4 },
        }
    }

    /// The positions `first..=last` of a signal of `n` samples that output `k` of its
    /// 1-D transform reaches (a single sample is left as it is).
    fn window(&self, k: usize, n: usize) -> (usize, usize) {
        if n < 2 {
            return (0, 0);
        }
        let lows = n.div_ceil(2);
        let (centre, reach) = if k < lows {
            (2 * k, self.low)
        } else {
            (2 * (k - lows) + 1, self.high)
        };
        (centre.saturating_sub(reach), (centre + reach).min(n - 1))
    }

    /// Per position of an `lw × lh` region (stride `lw`): whether its row window holds a
    /// needed sample of the same row.
    fn dilate_rows(&self, needed: &[bool], lw: usize, lh: usize) -> Vec<bool> {
        let mut out = vec![false; lw * lh];
        let mut prefix = vec![0u32; lw + 1];
        for y in 0..lh {
            let row = &needed[y * lw..(y + 1) * lw];
            for (x, &n) in row.iter().enumerate() {
                prefix[x + 1] = prefix[x] + u32::from(n);
            }
            for x in 0..lw {
                let (a, b) = self.window(x, lw);
                out[y * lw + x] = prefix[b + 1] > prefix[a];
            }
        }
        out
    }

    /// Per position of an `lw × lh` region: whether its column window holds a needed
    /// position of the same column.
    fn dilate_columns(&self, needed: &[bool], lw: usize, lh: usize) -> Vec<bool> {
        let mut out = vec![false; lw * lh];
        let mut prefix = vec![0u32; (lh + 1) * lw];
        for y in 0..lh {
            for x in 0..lw {
                prefix[(y + 1) * lw + x] = prefix[y * lw + x] + u32::from(needed[y * lw + x]);
            }
        }
        for y in 0..lh {
            let (a, b) = self.window(y, lh);
            for x in 0..lw {
                out[y * lw + x] = prefix[(b + 1) * lw + x] > prefix[a * lw + x];
            }
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::wavelet::{forward_97, forward_integer, inverse_97, inverse_integer, max_levels};

    /// A small deterministic generator (xorshift) for the random cases.
    fn xorshift(state: &mut u64) -> u64 {
        *state ^= *state << 13;
        *state ^= *state >> 7;
        *state ^= *state << 17;
        *state
    }

    /// Random sizes and levels, and masks of blobs and speckle: valid samples get back
    /// exactly what they had once the unreached coefficients are zeroed.
    #[test]
    fn zeroing_unreached_coefficients_leaves_valid_samples_exact() {
        let mut state = 0x9E37_79B9_7F4A_7C15u64;
        for case in 0..300 {
            let width = 1 + (xorshift(&mut state) % 40) as usize;
            let height = 1 + (xorshift(&mut state) % 40) as usize;
            let levels = (xorshift(&mut state) % (max_levels(width, height) as u64 + 1)) as u32;
            let (cx, cy) = (xorshift(&mut state) % 48, xorshift(&mut state) % 48);
            let radius = 2 + xorshift(&mut state) % 20;
            let speckle = xorshift(&mut state).is_multiple_of(4);
            let valid: Vec<bool> = (0..width * height)
                .map(|i| {
                    let (x, y) = ((i % width) as i64, (i / width) as i64);
                    let (dx, dy) = (x - cx as i64, y - cy as i64);
                    let outside = (dx * dx + dy * dy) as u64 > radius * radius;
                    if speckle {
                        outside && !xorshift(&mut state).is_multiple_of(3)
                    } else {
                        outside
                    }
                })
                .collect();
            let ints: Vec<i32> = (0..width * height)
                .map(|_| (xorshift(&mut state) % 4001) as i32 - 2000)
                .collect();
            for wavelet in [Wavelet::Int53, Wavelet::Int1311] {
                let mut zeroed = ints.clone();
                forward_integer(wavelet, &mut zeroed, (width, height), levels, Some(&valid));
                zero_unreached(&mut zeroed, width, height, levels, wavelet, &valid);
                inverse_integer(wavelet, &mut zeroed, width, height, levels);
                for i in (0..width * height).filter(|&i| valid[i]) {
                    assert_eq!(
                        zeroed[i], ints[i],
                        "{wavelet:?} case {case}: {width}x{height} L{levels} at {i}"
                    );
                }
            }
            let floats: Vec<f32> = ints.iter().map(|&v| v as f32 * 0.37).collect();
            let mut whole = floats.clone();
            forward_97(&mut whole, width, height, levels);
            let mut zeroed = whole.clone();
            zero_unreached(&mut zeroed, width, height, levels, Wavelet::Cdf97, &valid);
            inverse_97(&mut whole, width, height, levels);
            inverse_97(&mut zeroed, width, height, levels);
            for i in (0..width * height).filter(|&i| valid[i]) {
                assert_eq!(
                    zeroed[i].to_bits(),
                    whole[i].to_bits(),
                    "9/7 case {case}: {width}x{height} L{levels} at {i}"
                );
            }
        }
    }

    /// A void far from every valid sample loses its coefficients; one valid sample keeps
    /// those that reach it.
    #[test]
    fn only_coefficients_reaching_a_valid_sample_are_kept() {
        let (width, height, levels) = (32, 32, 3);
        let mut valid = vec![false; width * height];
        valid[5 * width + 7] = true;
        let mut data = vec![1i32; width * height];
        zero_unreached(&mut data, width, height, levels, Wavelet::Int53, &valid);
        let kept = data.iter().filter(|&&v| v != 0).count();
        assert!(kept > 0 && kept < 60, "kept {kept}");
        let mut all = vec![1i32; width * height];
        zero_unreached(
            &mut all,
            width,
            height,
            levels,
            Wavelet::Int53,
            &[true; 1024],
        );
        assert!(all.iter().all(|&v| v == 1));
    }
}
