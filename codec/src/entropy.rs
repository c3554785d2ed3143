//! Adaptive binary arithmetic coding.
//!
//! A range coder in the style of LZMA's (32-bit range, byte-wise output with carry
//! propagation through a cached byte) driven by adaptive probability models
//! ([`BitModel`]). Each model mixes a fast- and a slow-adapting estimate, which tracks both
//! quickly changing and stationary statistics.
//!
//! Encoders implement [`BitSink`]; besides the real [`ArithmeticEncoder`] there is a
//! `BitCounter` (behind the `internals` and `research` features) that only sums the ideal code length, so the EZW coder can measure what a
//! context buys without producing bytes.
//!
//! The decoder reads zeros past the end of its input and reports [`ArithmeticDecoder::exhausted`]
//! as soon as a decision depended on such a padding byte: the embedded decoder stops there,
//! which is how a truncated stream decodes to the best image its bytes allow.

/// Probabilities are 16-bit fixed point: `p0 / 65536` is the probability of a 0 bit.
const PROB_BITS: u32 = 16;
const PROB_ONE: u32 = 1 << PROB_BITS;
/// Renormalise when the range drops below 2^24.
const TOP: u32 = 1 << 24;
/// Smallest probability a model gives either bit, in 1/65536 units.
const PROB_FLOOR: u32 = 64;
/// Adaptation rates (right shifts) of the fast and slow estimates.
const FAST_RATE: u32 = 4;
const SLOW_RATE: u32 = 7;
/// The age a [primed](BitModel::primed) model starts at: its first update moves it by
/// 1/32 (the fast estimate by 1/16), as if four bits had been seen.
pub const PRIMED_AGE: u16 = 4;

/// An adaptive estimate of the probability that the next bit in its context is 0.
#[derive(Debug, Clone, Copy)]
pub struct BitModel {
    fast: u16,
    slow: u16,
    /// Bits seen so far, saturating: young models adapt faster.
    count: u16,
}

impl Default for BitModel {
    fn default() -> Self {
        BitModel::new()
    }
}

impl BitModel {
    /// A model with no knowledge (p = 1/2).
    pub const fn new() -> BitModel {
        BitModel {
            fast: 1 << 15,
            slow: 1 << 15,
            count: 0,
        }
    }

    /// A model that starts from the probability `p0` of a 0 bit (in 1/65536 units,
    /// clamped to the range the estimates keep), as sure of it as
    /// [`PRIMED_AGE`] bits would have made it.
    pub const fn primed(p0: u16) -> BitModel {
        let p = if (p0 as u32) < PROB_FLOOR {
            PROB_FLOOR as u16
        } else if p0 as u32 > PROB_ONE - PROB_FLOOR {
            (PROB_ONE - PROB_FLOOR) as u16
        } else {
            p0
        };
        BitModel {
            fast: p,
            slow: p,
            count: PRIMED_AGE,
        }
    }

    /// Probability of a 0 bit, in 1/65536 units; always within
    /// `[PROB_FLOOR, 65536 − PROB_FLOOR]` because the estimates never leave that range.
    #[inline]
    pub fn p0(&self) -> u32 {
        (self.fast as u32 + self.slow as u32) >> 1
    }

    /// Updates the model after coding `bit`.
    #[inline]
    pub fn update(&mut self, bit: bool) {
        // Move both estimates toward 0 (after a 1) or 65535 (after a 0) without a branch:
        // `p += (target − p) >> rate` with an arithmetic shift.
        // Targets stop `PROB_FLOOR` short of certainty, and the flooring shift never
        // overshoots a target, so no clamp is needed.
        let target = PROB_FLOOR as i32 + (!bit as i32) * (PROB_ONE as i32 - 2 * PROB_FLOOR as i32);
        let fast = self.fast as i32;
        let slow = self.slow as i32;
        // Settled models (nearly every update): constant rates, no age to keep.
        if self.count >= SLOW_RATE as u16 {
            self.fast = (fast + ((target - fast) >> FAST_RATE)) as u16;
            self.slow = (slow + ((target - slow) >> SLOW_RATE)) as u16;
            return;
        }
        // The slow estimate starts as a running average (rate 1, 2, 3, ... after the first
        // bits) and settles at SLOW_RATE; the fast one likewise up to FAST_RATE.
        let age = self.count as u32 + 1;
        self.fast = (fast + ((target - fast) >> FAST_RATE.min(age))) as u16;
        self.slow = (slow + ((target - slow) >> SLOW_RATE.min(age))) as u16;
        self.count += 1;
    }
}

/// Anything that can consume modelled binary decisions: the real encoder or a bit counter.
pub trait BitSink {
    /// Codes `bit` with the probability held by `model`, then adapts the model.
    fn encode(&mut self, bit: bool, model: &mut BitModel);
    /// Codes `bit` with a fixed probability of 1/2 (no model).
    fn encode_raw(&mut self, bit: bool);
    /// Bytes produced so far, including bytes still held back for carry propagation.
    fn bytes_so_far(&self) -> usize;
}

/// The range encoder.
#[derive(Debug)]
pub struct ArithmeticEncoder {
    low: u64,
    range: u32,
    cache: u8,
    cache_size: u64,
    out: Vec<u8>,
}

impl Default for ArithmeticEncoder {
    fn default() -> Self {
        ArithmeticEncoder::new()
    }
}

impl ArithmeticEncoder {
    /// A fresh encoder with an empty output.
    pub fn new() -> ArithmeticEncoder {
        ArithmeticEncoder {
            low: 0,
            range: u32::MAX,
            cache: 0,
            cache_size: 1,
            out: Vec::new(),
        }
    }

    #[inline]
    fn shift_low(&mut self) {
        if (self.low as u32) < 0xFF00_0000 || (self.low >> 32) != 0 {
            let carry = (self.low >> 32) as u8;
            let mut byte = self.cache;
            loop {
                self.out.push(byte.wrapping_add(carry));
                byte = 0xFF;
                self.cache_size -= 1;
                if self.cache_size == 0 {
                    break;
                }
            }
            self.cache = (self.low >> 24) as u8;
        }
        self.cache_size += 1;
        self.low = (self.low & 0x00FF_FFFF) << 8;
    }

    #[inline(always)]
    fn encode_with_bound(&mut self, bit: bool, bound: u32) {
        // Branch-free, as in the decoder: the coded bit is unpredictable by nature.
        let mask = (bit as u32).wrapping_neg();
        self.low += u64::from(bound & mask);
        self.range = (bound & !mask) | (self.range.wrapping_sub(bound) & mask);
        while self.range < TOP {
            self.range <<= 8;
            self.shift_low();
        }
    }

    /// Flushes the coder state and returns the bytes. The first byte of a range-coded
    /// stream is always 0 and is dropped here (the decoder supplies it).
    pub fn finish(mut self) -> Vec<u8> {
        for _ in 0..5 {
            self.shift_low();
        }
        let mut out = self.out;
        out.remove(0);
        // Trailing zero bytes carry no information: the decoder pads with zeros.
        while out.last() == Some(&0) {
            out.pop();
        }
        out
    }
}

impl BitSink for ArithmeticEncoder {
    #[inline(always)]
    fn encode(&mut self, bit: bool, model: &mut BitModel) {
        let bound = (self.range >> PROB_BITS) * model.p0();
        model.update(bit);
        self.encode_with_bound(bit, bound);
    }

    #[inline]
    fn encode_raw(&mut self, bit: bool) {
        let bound = self.range >> 1;
        self.encode_with_bound(bit, bound);
    }

    fn bytes_so_far(&self) -> usize {
        // Bytes already written minus the leading zero, plus held-back cache bytes and
        // the bytes of `low` that a flush would emit.
        self.out.len() + self.cache_size as usize + 4 - 1
    }
}

/// Sums the ideal code length (−log2 p) of every decision instead of producing bytes.
#[cfg(any(test, feature = "internals", feature = "research"))]
#[derive(Debug, Default, Clone)]
pub struct BitCounter {
    bits: f64,
}

#[cfg(any(test, feature = "internals", feature = "research"))]
impl BitCounter {
    /// A counter at zero.
    pub fn new() -> BitCounter {
        BitCounter::default()
    }

    /// Total ideal code length so far, in bits.
    pub fn bits(&self) -> f64 {
        self.bits
    }
}

#[cfg(any(test, feature = "internals", feature = "research"))]
impl BitSink for BitCounter {
    #[inline]
    fn encode(&mut self, bit: bool, model: &mut BitModel) {
        let p0 = model.p0() as f64 / PROB_ONE as f64;
        let p = if bit { 1.0 - p0 } else { p0 };
        self.bits -= p.log2();
        model.update(bit);
    }

    fn encode_raw(&mut self, _bit: bool) {
        self.bits += 1.0;
    }

    fn bytes_so_far(&self) -> usize {
        (self.bits / 8.0).ceil() as usize
    }
}

/// The range decoder. Reads zeros past the end of its input.
#[derive(Debug)]
pub struct ArithmeticDecoder<'a> {
    data: &'a [u8],
    /// Stream bytes consumed so far (zero padding included).
    pos: usize,
    /// Stream bytes available.
    len: usize,
    /// Bytes to skip after every `1 << chunk_bits` stream bytes (checksums of a framed
    /// section; 0 for a plain stream).
    skip: usize,
    chunk_bits: u32,
    range: u32,
    code: u32,
    /// Bytes consumed up to which every decision is exact: `len`, or `usize::MAX` for a
    /// complete stream (its zero padding is genuine).
    trusted: usize,
}

impl<'a> ArithmeticDecoder<'a> {
    /// Starts decoding `data`, the output of [`ArithmeticEncoder::finish`] or a prefix of it.
    ///
    /// `complete` says that `data` is the whole stream: its trailing zero bytes were
    /// stripped by the encoder, so the zero padding read past its end is genuine and
    /// [`ArithmeticDecoder::exhausted`] never becomes true.
    pub fn new(data: &'a [u8], complete: bool) -> ArithmeticDecoder<'a> {
        ArithmeticDecoder::start(data, data.len(), 0, 0, complete)
    }

    /// Starts decoding a stream stored framed, in place: after every `chunk` stream bytes
    /// (a power of two) `skip` bytes follow that are not part of it (a checksum). `len`
    /// is the number of stream bytes `framed` holds; `complete` as for [`Self::new`].
    pub fn new_framed(
        framed: &'a [u8],
        len: usize,
        chunk: usize,
        skip: usize,
        complete: bool,
    ) -> ArithmeticDecoder<'a> {
        assert!(
            chunk.is_power_of_two(),
            "chunk size {chunk} is not a power of two"
        );
        ArithmeticDecoder::start(framed, len, skip, chunk.trailing_zeros(), complete)
    }

    fn start(
        data: &'a [u8],
        len: usize,
        skip: usize,
        chunk_bits: u32,
        complete: bool,
    ) -> ArithmeticDecoder<'a> {
        let mut decoder = ArithmeticDecoder {
            data,
            pos: 0,
            len,
            skip,
            chunk_bits,
            range: u32::MAX,
            code: 0,
            trusted: if complete { usize::MAX } else { len },
        };
        for _ in 0..4 {
            decoder.code = (decoder.code << 8) | decoder.next_byte() as u32;
        }
        decoder
    }

    #[inline]
    fn next_byte(&mut self) -> u8 {
        let byte = if self.pos < self.len {
            let index = self.pos + self.skip * (self.pos >> self.chunk_bits);
            self.data.get(index).copied().unwrap_or(0)
        } else {
            0
        };
        self.pos += 1;
        byte
    }

    /// True once the decoder's window holds bytes past the end of a truncated input: the
    /// last decision returned may differ from what the encoder coded. Every decision
    /// returned while this was still false is exact.
    #[inline]
    pub fn exhausted(&self) -> bool {
        self.pos > self.trusted
    }

    #[inline]
    fn decode_with_bound(&mut self, bound: u32) -> bool {
        // Branch-free: the decoded bit is unpredictable by nature.
        let bit = self.code >= bound;
        let mask = (bit as u32).wrapping_neg();
        self.code -= bound & mask;
        self.range = (bound & !mask) | (self.range.wrapping_sub(bound) & mask);
        while self.range < TOP {
            self.range <<= 8;
            self.code = (self.code << 8) | self.next_byte() as u32;
        }
        bit
    }

    /// Decodes one bit with `model` and adapts it.
    #[inline]
    pub fn decode(&mut self, model: &mut BitModel) -> bool {
        let bound = (self.range >> PROB_BITS) * model.p0();
        let bit = self.decode_with_bound(bound);
        model.update(bit);
        bit
    }

    /// Decodes one bit coded with [`BitSink::encode_raw`].
    #[inline]
    pub fn decode_raw(&mut self) -> bool {
        let bound = self.range >> 1;
        self.decode_with_bound(bound)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Deterministic pseudo-random bits with a skewed distribution.
    fn bits(n: usize, seed: u64, p_one: f64) -> Vec<bool> {
        let mut state = seed;
        (0..n)
            .map(|_| {
                state ^= state << 13;
                state ^= state >> 7;
                state ^= state << 17;
                ((state >> 11) as f64 / (1u64 << 53) as f64) < p_one
            })
            .collect()
    }

    fn encode_all(input: &[bool], contexts: usize) -> Vec<u8> {
        let mut enc = ArithmeticEncoder::new();
        let mut models = vec![BitModel::new(); contexts];
        for (i, &b) in input.iter().enumerate() {
            if i % 7 == 3 {
                enc.encode_raw(b);
            } else {
                enc.encode(b, &mut models[i % contexts]);
            }
        }
        enc.finish()
    }

    #[test]
    fn round_trip_various_skews() {
        for (seed, p) in [(1, 0.5), (2, 0.05), (3, 0.95), (4, 0.001), (5, 0.3)] {
            let input = bits(20_000, seed, p);
            let stream = encode_all(&input, 3);
            let mut dec = ArithmeticDecoder::new(&stream, true);
            let mut models = [BitModel::new(); 3];
            for (i, &b) in input.iter().enumerate() {
                let got = if i % 7 == 3 {
                    dec.decode_raw()
                } else {
                    dec.decode(&mut models[i % 3])
                };
                assert_eq!(got, b, "bit {i} with p={p}");
            }
        }
    }

    #[test]
    fn skewed_bits_compress() {
        let input = bits(80_000, 9, 0.02);
        let mut enc = ArithmeticEncoder::new();
        let mut model = BitModel::new();
        for &b in &input {
            enc.encode(b, &mut model);
        }
        let bytes = enc.finish().len();
        // Entropy of p = 0.02 is 0.1414 bits: 80 000 bits -> ~1414 bytes.
        assert!(bytes < 1600, "{bytes} bytes");
    }

    #[test]
    fn counter_agrees_with_encoder() {
        let input = bits(50_000, 11, 0.1);
        let mut enc = ArithmeticEncoder::new();
        let mut counter = BitCounter::new();
        let (mut m1, mut m2) = (BitModel::new(), BitModel::new());
        for &b in &input {
            enc.encode(b, &mut m1);
            counter.encode(b, &mut m2);
        }
        let real = enc.finish().len() as f64 * 8.0;
        assert!(
            (real - counter.bits()).abs() < 64.0,
            "{real} vs {}",
            counter.bits()
        );
    }

    #[test]
    fn every_prefix_decodes_a_correct_prefix_of_decisions() {
        let input = bits(3_000, 21, 0.2);
        let stream = encode_all(&input, 2);
        let mut previous = 0;
        for cut in 0..=stream.len() {
            let mut dec = ArithmeticDecoder::new(&stream[..cut], cut == stream.len());
            let mut models = [BitModel::new(); 2];
            let mut correct = 0;
            for (i, &b) in input.iter().enumerate() {
                let got = if i % 7 == 3 {
                    dec.decode_raw()
                } else {
                    dec.decode(&mut models[i % 2])
                };
                if dec.exhausted() {
                    break;
                }
                assert_eq!(
                    got, b,
                    "cut {cut}: bit {i} decoded wrongly before exhaustion"
                );
                correct += 1;
            }
            if cut == stream.len() {
                assert_eq!(
                    correct,
                    input.len(),
                    "the complete stream decodes every bit"
                );
            }
            assert!(
                correct >= previous,
                "a longer prefix never decodes fewer bits"
            );
            previous = correct;
        }
    }

    #[test]
    fn bytes_so_far_tracks_output() {
        let input = bits(40_000, 5, 0.3);
        let mut enc = ArithmeticEncoder::new();
        let mut model = BitModel::new();
        for &b in &input {
            enc.encode(b, &mut model);
        }
        let estimate = enc.bytes_so_far();
        let real = enc.finish().len();
        assert!(estimate.abs_diff(real) <= 5, "{estimate} vs {real}");
    }
}
