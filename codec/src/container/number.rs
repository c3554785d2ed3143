//! Header *numbers*: one varint `v` whose low two bits say what it holds, in the
//! shortest form that gives back every bit of the value (`codec/FORMAT.md`, *Header*):
//!
//! - `v & 3 = 0`: an integer, zigzag, in `v >> 2`;
//! - `v & 3 = 1`, `p = v >> 2`: +∞ (`p = 0`), −∞ (`p = 1`), else with `q = p − 2` a
//!   power of two (`q` even: `±2^e`) or a decimal (`q` odd: `m / 10^k`, perhaps
//!   narrowed to an f32), see [`short_value`];
//! - `v & 3 = 2`: the eight bytes of an f64 follow;
//! - `v & 3 = 3`: the four bytes of an f32 follow, widened to f64.

use super::write_varint;

/// Largest integer every f64 up to which holds exactly.
const EXACT: f64 = (1u64 << 53) as f64;
/// Most digits after the point a decimal holds (10^22 is the largest exact power of ten).
const MAX_DIGITS: u32 = 22;

/// Appends `value` as a number, in its shortest form.
pub(super) fn write_number(out: &mut Vec<u8>, value: f64) {
    if value.fract() == 0.0 && value.abs() <= EXACT && !(value == 0.0 && value.is_sign_negative()) {
        let i = value as i64;
        write_varint(out, zigzag(i) << 2);
        return;
    }
    let short = short_code(value).map(|p| p << 2 | 1);
    let is_f32 = f64::from(value as f32).to_bits() == value.to_bits();
    let raw_len = if is_f32 { 5 } else { 9 };
    match short {
        Some(v) if varint_len(v) <= raw_len => write_varint(out, v),
        _ if is_f32 => {
            write_varint(out, 3);
            out.extend_from_slice(&(value as f32).to_bits().to_le_bytes());
        }
        _ => {
            write_varint(out, 2);
            out.extend_from_slice(&value.to_bits().to_le_bytes());
        }
    }
}

/// The value of code 1 with payload `p` (`v >> 2`), or `None` for an invalid payload.
pub(super) fn short_value(p: u64) -> Option<f64> {
    match p {
        0 => return Some(f64::INFINITY),
        1 => return Some(f64::NEG_INFINITY),
        _ => {}
    }
    let q = p - 2;
    let r = q >> 1;
    if q & 1 == 0 {
        // ±2^e: bit 0 of r the sign, the rest e zigzagged; normal f64s only.
        let e = unzigzag(r >> 1);
        let magnitude = power_of_two(e)?;
        return Some(if r & 1 == 1 { -magnitude } else { magnitude });
    }
    // m / 10^k: bit 0 of r says narrowed to an f32, then 5 bits of k, then m zigzagged.
    let narrow = r & 1 == 1;
    let k = ((r >> 1) & 31) as u32;
    let m = unzigzag(r >> 6);
    if k == 0 || k > MAX_DIGITS || m == 0 || m.unsigned_abs() >= 1 << 53 {
        return None;
    }
    let value = m as f64 / 10f64.powi(k as i32);
    Some(if narrow {
        f64::from(value as f32)
    } else {
        value
    })
}

/// The payload (`v >> 2`) of code 1 for `value`: ±∞, a power of two, or the shortest
/// decimal that gives back its bits, if any.
fn short_code(value: f64) -> Option<u64> {
    if value.is_infinite() {
        return Some(u64::from(value < 0.0));
    }
    if let Some(e) = exponent_of_power(value.abs()) {
        let r = zigzag(i64::from(e)) << 1 | u64::from(value < 0.0);
        return Some((r << 1) + 2);
    }
    let is_f32 = f64::from(value as f32).to_bits() == value.to_bits();
    let shortest = if is_f32 {
        decimal_parts(&format!("{}", value as f32)).map(|(m, k)| (m, k, true))
    } else {
        decimal_parts(&format!("{value}")).map(|(m, k)| (m, k, false))
    };
    let (m, k, narrow) = shortest?;
    let r = ((zigzag(m) << 5 | u64::from(k)) << 1) | u64::from(narrow);
    let p = ((r << 1) | 1) + 2;
    (short_value(p)?.to_bits() == value.to_bits()).then_some(p)
}

/// `text` (Rust's shortest decimal of a finite float, no exponent) as `m / 10^k` with
/// `1 ≤ k ≤ MAX_DIGITS` and `|m| < 2^53`.
fn decimal_parts(text: &str) -> Option<(i64, u32)> {
    let (whole, fraction) = text.split_once('.')?;
    let k = u32::try_from(fraction.len()).ok()?;
    if k == 0 || k > MAX_DIGITS {
        return None;
    }
    let m: i64 = format!("{whole}{fraction}").parse().ok()?;
    (m != 0 && m.unsigned_abs() < 1 << 53).then_some((m, k))
}

/// `e` when `magnitude` is exactly 2^e, a normal f64.
fn exponent_of_power(magnitude: f64) -> Option<i32> {
    let bits = magnitude.to_bits();
    let biased = (bits >> 52) as i32;
    (bits & ((1 << 52) - 1) == 0 && (1..2047).contains(&biased)).then_some(biased - 1023)
}

/// 2^e as a normal f64.
fn power_of_two(e: i64) -> Option<f64> {
    (-1022..=1023)
        .contains(&e)
        .then(|| f64::from_bits(((e + 1023) as u64) << 52))
}

fn zigzag(i: i64) -> u64 {
    ((i << 1) ^ (i >> 63)) as u64
}

fn unzigzag(z: u64) -> i64 {
    (z >> 1) as i64 ^ -((z & 1) as i64)
}

/// Bytes of `v` as a varint.
fn varint_len(v: u64) -> usize {
    (64 - v.leading_zeros() as usize).div_ceil(7).max(1)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Writes `value` and reads it back through the header reader's rules.
    fn round_trip(value: f64) -> (f64, usize) {
        let mut out = Vec::new();
        write_number(&mut out, value);
        let (mut v, mut shift, mut used) = (0u64, 0, 0);
        for &b in &out {
            v |= u64::from(b & 0x7f) << shift;
            shift += 7;
            used += 1;
            if b < 0x80 {
                break;
            }
        }
        let tail = &out[used..];
        let back = match v & 3 {
            0 => unzigzag(v >> 2) as f64,
            1 => short_value(v >> 2).expect("a valid short number"),
            2 => f64::from_le_bytes(tail.try_into().unwrap()),
            _ => f64::from(f32::from_le_bytes(tail.try_into().unwrap())),
        };
        (back, out.len())
    }

    #[test]
    fn every_value_comes_back_bit_for_bit_in_its_shortest_form() {
        let cases: [(f64, usize); 14] = [
            (0.0, 1),
            (-3.0, 1),
            (f64::INFINITY, 1),
            (f64::NEG_INFINITY, 1),
            (0.0078125, 2),
            (-0.5, 1),
            (2f64.powi(-1022), 3),
            (0.1, 2),
            (0.05, 2),
            (f64::from(13.7f32), 3),
            (f64::from(-3.696f32), 4),
            (0.1 + 0.2, 9),
            (f64::from(f32::from_bits(0x4000_0001)), 5),
            (-0.0, 5),
        ];
        for (value, len) in cases {
            let (back, written) = round_trip(value);
            assert_eq!(back.to_bits(), value.to_bits(), "{value}");
            assert_eq!(written, len, "bytes of {value}");
        }
        let (nan, _) = round_trip(f64::from_bits(0x7ff8_0000_0000_1234));
        assert_eq!(nan.to_bits(), 0x7ff8_0000_0000_1234);
    }

    #[test]
    fn invalid_short_payloads_are_refused() {
        // A power of two past the normal range; a decimal with no digits or m = 0.
        let power = |e: i64| (zigzag(e) << 1) << 1;
        assert!(short_value(power(1024) + 2).is_none());
        let decimal = |m: i64, k: u64| ((((zigzag(m) << 5) | k) << 1) << 1 | 1) + 2;
        assert!(short_value(decimal(5, 0)).is_none());
        assert!(short_value(decimal(0, 3)).is_none());
        assert!(short_value(decimal(5, 23)).is_none());
        assert_eq!(short_value(decimal(5, 1)), Some(0.5));
    }
}
