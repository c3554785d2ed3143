//! Where a decoder keeps the coefficients it knows: `i32`, or `i16` with the few that do
//! not fit escaped to a side table ([`Narrow`]), half the memory for 16-bit rasters.

use std::collections::BTreeMap;

use crate::wavelet::max_spilled;

/// The known coefficients as the scans read them.
pub trait Known {
    /// The known value of coefficient `i`.
    fn at(&self, i: usize) -> i32;

    /// The known magnitudes of the 8 neighbours of coefficient `i`, inside an array
    /// `w` wide, the horizontal and vertical ones counted twice.
    #[inline(always)]
    fn interior_sum(&self, i: usize, w: usize) -> u64 {
        neighbour_magnitudes(self, i, w)
    }
}

/// [`Known::interior_sum`] read one coefficient at a time.
#[inline(always)]
fn neighbour_magnitudes<K: Known + ?Sized>(known: &K, i: usize, w: usize) -> u64 {
    let m = |j: usize| u64::from(known.at(j).unsigned_abs());
    2 * (m(i - 1) + m(i + 1) + m(i - w) + m(i + w))
        + m(i - w - 1)
        + m(i - w + 1)
        + m(i + w - 1)
        + m(i + w + 1)
}

impl Known for [i32] {
    #[inline(always)]
    fn at(&self, i: usize) -> i32 {
        self[i]
    }

    #[inline(always)]
    fn interior_sum(&self, i: usize, w: usize) -> u64 {
        rows_sum(self, i, w, |x| u64::from(x.unsigned_abs()))
    }
}

/// [`Known::interior_sum`] of a slice, its three rows of three read as slices: three
/// bounds checks rather than eight.
#[inline(always)]
fn rows_sum<T: Copy>(v: &[T], i: usize, w: usize, m: impl Fn(T) -> u64) -> u64 {
    let (up, row, down) = (
        &v[i - w - 1..i - w + 2],
        &v[i - 1..i + 2],
        &v[i + w - 1..i + w + 2],
    );
    2 * (m(row[0]) + m(row[2]) + m(up[1]) + m(down[1]))
        + m(up[0])
        + m(up[2])
        + m(down[0])
        + m(down[2])
}

impl Known for Vec<i32> {
    #[inline(always)]
    fn at(&self, i: usize) -> i32 {
        self[i]
    }

    #[inline(always)]
    fn interior_sum(&self, i: usize, w: usize) -> u64 {
        rows_sum(self, i, w, |x| u64::from(x.unsigned_abs()))
    }
}

/// A decoder's coefficient store.
pub trait Store: Known + Send + Sized {
    /// The coefficients as the scans of the passes up to [`super::SATURATED_PLANE`] may
    /// read them: any value of magnitude 32767 or more may read as one of 32767 or
    /// 32768 with its sign.
    type Saturated: Known + ?Sized;
    /// `n` coefficients, all 0.
    fn zeroed(n: usize) -> Self;
    /// Stores `v` as coefficient `i`.
    fn set(&mut self, i: usize, v: i32);
    /// Adds 2^`p` to the magnitude of coefficient `i` (not 0).
    #[inline(always)]
    fn grow(&mut self, i: usize, p: u32) {
        let v = self.at(i);
        self.set(i, if v < 0 { v - (1 << p) } else { v + (1 << p) });
    }
    /// The store as [`Store::Saturated`].
    fn saturated(&self) -> &Self::Saturated;
    /// The highest plane of the passes whose scans may read the store through
    /// [`Store::saturated`] (every plane when that reads every value as it is).
    fn saturated_plane(&self) -> u32 {
        u32::MAX
    }
    /// Whether the store holds more than it was meant to (the decode gives up).
    fn overflowed(&self) -> bool;
}

impl Store for Vec<i32> {
    type Saturated = Self;
    fn zeroed(n: usize) -> Self {
        vec![0; n]
    }
    #[inline(always)]
    fn set(&mut self, i: usize, v: i32) {
        self[i] = v;
    }
    #[inline(always)]
    fn saturated(&self) -> &Self {
        self
    }
    fn overflowed(&self) -> bool {
        false
    }
}

/// The `i16` slot of an escaped coefficient: its sign's extreme, so that read as it is
/// the slot has the coefficient's sign and a magnitude of 32767 or 32768.
const fn escape_slot(v: i32) -> i16 {
    if v < 0 {
        i16::MIN
    } else {
        i16::MAX
    }
}

/// Whether `v` is an escaped coefficient's slot (with `ESCAPES`).
#[inline(always)]
pub(crate) fn is_escape(v: i16) -> bool {
    (v as u16).wrapping_sub(i16::MAX as u16) <= 1
}

/// `i16` slots in units of 2^`shift`, read as they are: an escaped slot (see [`Narrow`])
/// reads as its sign's extreme times 2^`shift`.
#[derive(Debug, Clone, Default)]
pub struct Slots {
    values: Vec<i16>,
    shift: u32,
}

impl Known for Slots {
    #[inline(always)]
    fn at(&self, i: usize) -> i32 {
        i32::from(self.values[i]) << self.shift
    }

    #[inline(always)]
    fn interior_sum(&self, i: usize, w: usize) -> u64 {
        rows_sum(&self.values, i, w, |x| u64::from(x.unsigned_abs())) << self.shift
    }
}

/// Coefficients as `i16` slots in units of 2^`shift` (1 for the integer 5/3; for a 9/7
/// stream the lowest plane its decode reads): a value with a bit below plane `shift`
/// overflows the store. With `ESCAPES`, each value whose slot would be outside
/// `−32767 ..= 32766` is escaped: its slot holds `escape_slot` and its value is in a side
/// table, which may hold about one coefficient in 64 (the coarse bands; [`max_spilled`]);
/// past that the store has [`Store::overflowed`]. Without, reading a coefficient costs no
/// test, and one that does not fit overflows the store.
#[derive(Debug, Clone, Default)]
pub struct Narrow<const ESCAPES: bool = true> {
    slots: Slots,
    wide: BTreeMap<usize, i32>,
    /// Whether a value did not fit (without `ESCAPES`, or below plane `shift`).
    outgrown: bool,
}

impl<const ESCAPES: bool> Known for Narrow<ESCAPES> {
    #[inline(always)]
    fn at(&self, i: usize) -> i32 {
        let v = self.slots.values[i];
        if ESCAPES && is_escape(v) {
            self.escaped(i)
        } else {
            i32::from(v) << self.slots.shift
        }
    }

    /// One test for an escape among the 8 neighbours rather than 8.
    #[inline(always)]
    fn interior_sum(&self, i: usize, w: usize) -> u64 {
        let v = &self.slots.values;
        let (up, down) = (&v[i - w - 1..i - w + 2], &v[i + w - 1..i + w + 2]);
        let (left, right) = (v[i - 1], v[i + 1]);
        let escaped = |row: &[i16]| row.iter().fold(false, |e, &x| e | is_escape(x));
        if ESCAPES && (escaped(up) | escaped(down) | is_escape(left) | is_escape(right)) {
            return self.escaped_sum(i, w);
        }
        self.slots.interior_sum(i, w)
    }
}

impl<const ESCAPES: bool> Store for Narrow<ESCAPES> {
    type Saturated = Slots;
    /// In units of 1: [`Narrow::with_shift`] gives others.
    fn zeroed(n: usize) -> Self {
        Narrow::with_shift(n, 0)
    }
    /// In the slot itself when neither the old nor the new value is escaped (nearly
    /// always), else as [`Store::set`] of the grown value.
    #[inline(always)]
    fn grow(&mut self, i: usize, p: u32) {
        let slot = self.slots.values[i];
        if let Some(unit) = p.checked_sub(self.slots.shift) {
            let (v, step) = (i32::from(slot), 1i32 << unit);
            if let Ok(grown) = i16::try_from(if v < 0 { v - step } else { v + step }) {
                if !ESCAPES || !(is_escape(slot) | is_escape(grown)) {
                    self.slots.values[i] = grown;
                    return;
                }
            }
        }
        let v = self.at(i);
        self.set(i, if v < 0 { v - (1 << p) } else { v + (1 << p) });
    }
    #[inline(always)]
    fn set(&mut self, i: usize, v: i32) {
        let shift = self.slots.shift;
        if (v >> shift) << shift != v {
            self.outgrown = true;
            return;
        }
        let values = &mut self.slots.values;
        match i16::try_from(v >> shift) {
            Ok(narrow) if !ESCAPES => values[i] = narrow,
            Ok(narrow) if !is_escape(narrow) && !is_escape(values[i]) => values[i] = narrow,
            _ if !ESCAPES => self.outgrown = true,
            _ => self.set_escaped(i, v),
        }
    }
    #[inline(always)]
    fn saturated(&self) -> &Slots {
        &self.slots
    }
    fn saturated_plane(&self) -> u32 {
        super::SATURATED_PLANE + self.slots.shift
    }
    fn overflowed(&self) -> bool {
        self.outgrown || self.wide.len() > max_spilled(self.slots.values.len())
    }
}

impl<const ESCAPES: bool> Narrow<ESCAPES> {
    /// `n` coefficients, all 0, in units of 2^`shift`.
    pub fn with_shift(n: usize, shift: u32) -> Self {
        Narrow {
            slots: Slots {
                values: vec![0; n],
                shift,
            },
            wide: BTreeMap::new(),
            outgrown: false,
        }
    }

    /// The value of escaped coefficient `i`.
    #[cold]
    #[inline(never)]
    fn escaped(&self, i: usize) -> i32 {
        let slot = self.slots.values[i];
        (self.wide.get(&i).copied()).unwrap_or(i32::from(slot) << self.slots.shift)
    }

    /// [`Known::interior_sum`] with an escaped neighbour.
    #[cold]
    #[inline(never)]
    fn escaped_sum(&self, i: usize, w: usize) -> u64 {
        neighbour_magnitudes(self, i, w)
    }

    /// [`Store::set`] where the old or the new value is escaped.
    #[cold]
    #[inline(never)]
    fn set_escaped(&mut self, i: usize, v: i32) {
        match i16::try_from(v >> self.slots.shift) {
            Ok(narrow) if !is_escape(narrow) => {
                self.wide.remove(&i);
                self.slots.values[i] = narrow;
            }
            _ => {
                self.wide.insert(i, v);
                self.slots.values[i] = escape_slot(v);
            }
        }
    }

    /// The escaped coefficients' indices, in increasing order.
    #[cfg(test)]
    fn escaped_indices(&self) -> impl Iterator<Item = usize> + '_ {
        self.wide.keys().copied()
    }

    /// The slots, their shift and the escaped values by index.
    pub(crate) fn into_parts(self) -> (Vec<i16>, u32, BTreeMap<usize, i32>) {
        (self.slots.values, self.slots.shift, self.wide)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ezw::SATURATED_PLANE;

    #[test]
    fn narrow_store_keeps_every_value_and_escapes_only_the_wide_ones() {
        let mut store = Narrow::<true>::zeroed(8);
        let values = [0, 32767, -32767, -32768, 32768, -70000, 5, i32::MIN];
        for (i, &v) in values.iter().enumerate() {
            store.set(i, v);
        }
        for (i, &v) in values.iter().enumerate() {
            assert_eq!(store.at(i), v, "coefficient {i}");
        }
        // 32767 and −32768 are escaped too; saturated, an escaped coefficient reads
        // as its sign's extreme.
        assert_eq!(store.escaped_indices().collect::<Vec<_>>(), [1, 3, 4, 5, 7]);
        let saturated: Vec<i32> = (0..8).map(|i| store.saturated().at(i)).collect();
        assert_eq!(
            saturated,
            [0, 32767, -32767, -32768, 32767, -32768, 5, -32768]
        );
        // Narrowing back frees the entry; widening a narrow one adds one.
        store.set(4, 12);
        store.set(5, -32766);
        store.set(6, 40000);
        store.grow(6, 3);
        store.grow(5, 1);
        assert_eq!((store.at(4), store.at(5), store.at(6)), (12, -32768, 40008));
        assert_eq!(store.escaped_indices().collect::<Vec<_>>(), [1, 3, 5, 6, 7]);
        assert!(!store.overflowed());
        for (i, v) in [(1, 1), (2, 2), (3, 3), (5, -32766), (6, 6), (7, 7)] {
            store.set(i, v);
        }
        let (values, _, wide) = store.into_parts();
        assert_eq!(values, [0, 1, 2, 3, 12, -32766, 6, 7]);
        assert!(wide.is_empty());
    }

    #[test]
    fn narrow_store_overflows_past_its_table() {
        let mut store = Narrow::<true>::zeroed(64 * 10);
        for i in 0..74 {
            store.set(i, 1 << 20);
        }
        assert!(!store.overflowed());
        store.set(74, -(1 << 20));
        assert!(store.overflowed());
    }

    #[test]
    fn narrow_store_without_escapes_overflows_at_once() {
        let mut store = Narrow::<false>::zeroed(4);
        store.set(0, -32768);
        store.set(1, 32767);
        assert!(!store.overflowed());
        assert_eq!((store.at(0), store.at(1)), (-32768, 32767));
        store.set(2, 32768);
        assert!(store.overflowed());
    }

    #[test]
    fn a_store_without_escapes_holds_its_planes_and_overflows_outside_them() {
        // A 3×3 array: the left and right neighbours of the middle one.
        let mut store = Narrow::<false>::with_shift(9, 15);
        store.set(3, -(32767 << 15));
        store.set(5, 3 << 20);
        store.grow(5, 15);
        assert_eq!(
            (store.at(3), store.at(5)),
            (-(32767 << 15), (3 << 20) + (1 << 15))
        );
        assert_eq!(store.interior_sum(4, 3), (2 * 32767 + 2 * 97) << 15);
        assert!(!store.overflowed());
        store.set(2, 1 << 14);
        assert!(store.overflowed());
        let mut store = Narrow::<false>::with_shift(2, 15);
        store.set(0, 1 << 30);
        assert!(store.overflowed());
    }

    #[test]
    fn a_shifted_store_escapes_the_slots_that_do_not_fit() {
        let mut store = Narrow::<true>::with_shift(9, 4);
        store.set(3, -(32767 << 4));
        store.set(5, 40000 << 4);
        store.set(1, 7 << 4);
        store.grow(5, 4);
        assert_eq!(
            (store.at(1), store.at(3), store.at(5)),
            (7 << 4, -(32767 << 4), (40001 << 4))
        );
        assert_eq!(store.escaped_indices().collect::<Vec<_>>(), [5]);
        // Saturated, the escaped one reads as the sign's extreme in units of 16.
        assert_eq!(store.saturated().at(5), 32767 << 4);
        assert_eq!(store.saturated_plane(), SATURATED_PLANE + 4);
        assert_eq!(
            store.interior_sum(4, 3),
            (2 * 7 + 2 * 32767 + 2 * 40001) << 4
        );
        assert!(!store.overflowed());
        store.set(5, 3 << 4);
        assert_eq!(store.escaped_indices().count(), 0);
        let (slots, shift, wide) = store.into_parts();
        assert_eq!((slots[5], shift, wide.len()), (3, 4, 0));
        let mut store = Narrow::<true>::with_shift(9, 4);
        store.set(0, 1 << 3);
        assert!(store.overflowed(), "a bit below the store's planes");
    }
}
