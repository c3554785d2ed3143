//! Fuzzing harnesses: the checks behind the `cargo fuzz` targets in `fuzz/`, kept here so
//! the same functions replay every saved crash input on stable (`codec/tests/fuzz_regressions.rs`).
//!
//! Each harness takes arbitrary bytes and either returns normally or panics with a message
//! saying which property broke. None of them may panic on any input unless the codec is
//! wrong: refusing an input with an error is always fine, a panic or a broken guarantee is
//! a bug.
//!
//! | harness | fuzz target | input |
//! |---|---|---|
//! | [`decode_arbitrary`] | `decode_ezw` | any bytes, read as a `.ezw` file |
//! | [`inspect_arbitrary`] | `inspect_ezw` | any bytes, read as `info` and `verify` read a `.ezw` file |
//! | [`decode_prefixes`] | `decode_prefix` | parameter bytes + a small raster (≤ 24 × 24) |
//! | [`roundtrip`] | `roundtrip` | parameter bytes + a raster (≤ 64 × 64) |

use crate::container::{self, Header, Mode, CHUNK};
use crate::mask::valid_sample_count;
use crate::pipeline::{
    decode, encode, DecodeOptions, Decoded, EncodeOptions, Encoded, Limits, Quality,
};
use crate::raster::{Raster, SampleType, Samples};
use crate::tiles::{tile_lengths, TiledLayout};
use crate::wavelet::{self, Wavelet};

/// The decoder limits every harness uses: small enough that no input can make a fuzzer
/// allocate gigabytes, large enough for any raster the harnesses encode.
pub const FUZZ_LIMITS: Limits = Limits::new(1 << 22, 1 << 28);

/// The tighter limits of [`decode_arbitrary`]: a few bytes can describe a large raster
/// whose decode costs `planes × samples` work (a valid, tiny, all-zero stream), and the
/// fuzzer drifts towards such inputs; 4096 samples (any aspect ratio, e.g. 4096 × 1) keep
/// it near 10,000 executions a second. Larger rasters are refused before any allocation,
/// which the harness checks too.
pub const DECODE_FUZZ_LIMITS: Limits = Limits::new(1 << 12, 1 << 20);

/// Decode options with [`FUZZ_LIMITS`].
fn fuzz_options() -> DecodeOptions {
    DecodeOptions::default().with_limits(FUZZ_LIMITS)
}

/// Decodes arbitrary bytes as a `.ezw` file; must never panic.
///
/// The bytes are decoded as they are (default options with [`DECODE_FUZZ_LIMITS`]) and checked
/// with [`container::verify`]. Random bytes almost never get past the header checksum, so
/// when the data starts with the magic bytes and a plausible header length, a copy with
/// every checksum recomputed ([`repair_checksums`]) is decoded and verified too — with
/// `max_passes`, `max_bytes` and `strict` chosen from bits 4–6 of the last byte (default
/// options when they are clear) — so the fuzzer reaches the header fields, the mask, the EZW decoder, the residual section and
/// the ladder.
///
/// Any `Ok` result must hold a raster of the header's size and sample type.
#[doc(hidden)]
pub fn decode_arbitrary(data: &[u8]) {
    let options = DecodeOptions::default().with_limits(DECODE_FUZZ_LIMITS);
    check_decode(data, &options);
    let _ = container::verify(data);
    if let Some(repaired) = repair_checksums(data) {
        let _ = container::verify(&repaired);
        let last = data.last().copied().unwrap_or(0);
        let options = options
            .with_max_passes((last & 0x10 != 0).then_some(u32::from(last & 0x0F)))
            .with_max_bytes(
                (last & 0x20 != 0).then(|| repaired.len() as u64 * u64::from(last & 0x0F) / 16),
            )
            .with_strict(last & 0x40 != 0);
        check_decode(&repaired, &options);
    }
}

/// Decodes `data` and checks that an `Ok` result is consistent with its header.
fn check_decode(data: &[u8], options: &DecodeOptions) -> Option<Decoded> {
    let decoded = decode(data, options).ok()?;
    let header = &decoded.header;
    let raster = &decoded.raster;
    assert!(
        header.sample_count() <= options.limits.max_samples,
        "decoded {} samples past the limit {}",
        header.sample_count(),
        options.limits.max_samples
    );
    assert_eq!(
        (raster.width, raster.height),
        (header.width as usize, header.height as usize),
        "decoded raster size differs from the header's"
    );
    assert_eq!(
        raster.samples.len(),
        raster.width * raster.height,
        "decoded sample count is not width x height"
    );
    assert_eq!(
        raster.sample_type(),
        header.sample_type,
        "decoded sample type differs from the header's"
    );
    assert!(
        decoded.bytes_used <= data.len() as u64,
        "bytes_used {} past the {} bytes given",
        decoded.bytes_used,
        data.len()
    );
    Some(decoded)
}

/// A copy of `data` with the header CRC and every chunk CRC the file's framing implies
/// recomputed, or `None` if `data` does not start with the magic bytes and a header
/// length that fits, or if nothing changed.
///
/// Chunks are located exactly as the decoder's unframing does (header length, then the
/// mask, payload, residual and ladder lengths from the header); chunks cut short by the
/// end of the data are left alone.
pub fn repair_checksums(data: &[u8]) -> Option<Vec<u8>> {
    let header_len = Header::declared_len(data)?;
    if header_len < 14 || header_len > data.len() {
        return None;
    }
    let mut out = data.to_vec();
    let crc = crc32fast::hash(&out[..header_len - 4]);
    out[header_len - 4..header_len].copy_from_slice(&crc.to_le_bytes());
    if let Ok((header, _)) = Header::parse(&out) {
        if let Some(tiling) = header.tiling {
            repair_tiled(&mut out, header_len, tiling.index_len);
            return (out != data).then_some(out);
        }
        let mut start = header_len as u64;
        for framed_total in [
            u64::from(header.mask_len),
            header.payload_len,
            u64::from(header.residual_len),
            u64::from(header.ladder_len),
        ] {
            let len = out.len() as u64;
            if start >= len {
                break;
            }
            let end = start.saturating_add(framed_total).min(len);
            let total = usize::try_from(framed_total).unwrap_or(usize::MAX);
            reframe(&mut out[start as usize..end as usize], total);
            start = start.saturating_add(framed_total);
        }
    }
    (out != data).then_some(out)
}

/// Repairs a tiled file's index (`index_len` framed bytes after the header), then every
/// tile the repaired index locates, each as a file of its own (and with code blocks,
/// every block's framed payload).
fn repair_tiled(out: &mut [u8], header_len: usize, index_len: u64) {
    let index_end = (header_len as u64)
        .saturating_add(index_len)
        .min(out.len() as u64);
    let total = usize::try_from(index_len).unwrap_or(usize::MAX);
    reframe(&mut out[header_len..index_end as usize], total);
    let Ok(Some(layout)) = TiledLayout::read(&mut &out[..], DECODE_FUZZ_LIMITS.max_memory) else {
        return;
    };
    let heads = &layout.tile_entries;
    for (e, (entry, &offset)) in layout.entries.iter().zip(&layout.offsets).enumerate() {
        let start = (offset as usize).min(out.len());
        let end = (offset.saturating_add(entry.len) as usize).min(out.len());
        if layout.code_block().is_some() && heads.binary_search(&e).is_err() {
            // A code block: its head byte, then its framed payload.
            let total = usize::try_from(entry.len.saturating_sub(1)).unwrap_or(usize::MAX);
            reframe(&mut out[(start + 1).min(end)..end], total);
        } else if let Some(tile) = repair_checksums(&out[start..end]) {
            out[start..end].copy_from_slice(&tile);
        }
    }
}

/// Runs on arbitrary bytes what `wavemesh info` and `wavemesh verify` run; must never
/// panic.
///
/// The bytes, and a copy with every checksum recomputed ([`repair_checksums`], tiled
/// files' index and tiles included), are checked with [`container::verify`] and read as
/// `info` reads them: a tiled file's header and index (index bytes bounded by
/// [`DECODE_FUZZ_LIMITS`]), then the bytes each tile would get at budgets from nothing to
/// the whole file; a single stream's header, then its nodata mask when the raster is
/// within the limits.
///
/// Checks: a budget's allocation gives no tile more than its length and spends no more
/// than the budget; a mask never counts more valid samples than the raster has.
#[doc(hidden)]
pub fn inspect_arbitrary(data: &[u8]) {
    inspect(data);
    if let Some(repaired) = repair_checksums(data) {
        inspect(&repaired);
    }
}

/// [`inspect_arbitrary`]'s checks on one copy of the bytes.
fn inspect(data: &[u8]) {
    let _ = container::verify(data);
    match TiledLayout::read(&mut &data[..], DECODE_FUZZ_LIMITS.max_memory) {
        Ok(Some(layout)) => inspect_tiled(&layout),
        Ok(None) => inspect_single(data),
        Err(_) => {}
    }
}

/// The allocation `info` estimates rates from, at budgets across the file's length.
fn inspect_tiled(layout: &TiledLayout) {
    let file_len = layout.file_len();
    for budget in [0, layout.head_len(), file_len / 8, file_len / 2, file_len] {
        let Ok(lengths) = tile_lengths(layout, Some(budget)) else {
            continue;
        };
        assert_eq!(lengths.len(), layout.entries.len(), "one length a tile");
        for (length, entry) in lengths.iter().zip(&layout.entries) {
            assert!(
                length <= &entry.len,
                "a tile given {length} of its {} bytes",
                entry.len
            );
        }
        let spent = layout.head_len() + lengths.iter().sum::<u64>();
        if budget < file_len {
            assert!(
                spent <= budget,
                "{spent} bytes spent of a budget of {budget}"
            );
        } else {
            assert_eq!(
                spent, file_len,
                "a budget of the whole file reads all of it"
            );
        }
    }
}

/// The valid-sample count `info` takes from a single stream's nodata mask: refused
/// over the limits, else at most the sample count.
fn inspect_single(data: &[u8]) {
    let Ok((header, header_len)) = Header::parse(data) else {
        return;
    };
    let samples = header.sample_count();
    match valid_sample_count(data, &header, header_len, &DECODE_FUZZ_LIMITS) {
        Ok(valid) => assert!(valid <= samples, "{valid} valid samples of {samples}"),
        Err(e) => assert!(
            samples > DECODE_FUZZ_LIMITS.max_samples || samples / 8 > DECODE_FUZZ_LIMITS.max_memory,
            "{samples} samples refused: {e}"
        ),
    }
}

/// Rewrites the CRC of every complete chunk of a framed section of `framed_total` bytes
/// of which `available` is present (mirrors [`container::unframe`]).
fn reframe(available: &mut [u8], framed_total: usize) {
    let mut start = 0;
    while start < available.len() {
        let data_len = CHUNK.min(framed_total.saturating_sub(start + 4));
        let end = start + data_len;
        if end + 4 > available.len() {
            return;
        }
        let crc = crc32fast::hash(&available[start..end]);
        available[end..end + 4].copy_from_slice(&crc.to_le_bytes());
        start = end + 4;
    }
}

/// Encodes a small raster built from `data`, then decodes prefixes and a damaged copy of
/// the stream.
///
/// Input layout: the [`PARAMS`]-byte parameter block described at [`roundtrip`] (sides
/// 1–24 here), of which bytes 22–37 give eight prefix lengths and bytes 38–39 the
/// position of a flipped bit; the samples follow.
///
/// Checks:
/// - a prefix shorter than the header is an error; every prefix holding the header and
///   the nodata mask decodes (the embedded-stream promise) to a raster of the right size
///   whose voids are still voids;
/// - a prefix that ends before the residual section is complete is never reported
///   `complete`, and `decode` with `max_bytes = cut` gives the same raster as the prefix;
/// - the complete stream decodes `complete`, and when its mode promises it, exactly
///   (lossless) or within the bound (max-error, precision);
/// - a single flipped bit after the header and mask is reported as damage at or before
///   the flipped byte, never a panic; in the header or mask it is an error.
#[doc(hidden)]
pub fn decode_prefixes(data: &[u8]) {
    let (params, sample_bytes) = data.split_at(data.len().min(PARAMS));
    let mut input = Input::new(params);
    let raster = arbitrary_raster(&mut input, sample_bytes, 24);
    let (options, _) = arbitrary_encode_options(&mut input, &raster);
    let cuts: Vec<u16> = (0..8).map(|_| input.u16()).collect();
    let flip = input.u16();
    let Ok(encoded) = encode(&raster, &options) else {
        return;
    };
    // The complete stream.
    let full = decode(&encoded.bytes, &fuzz_options()).expect("the complete stream decodes");
    assert!(
        full.complete,
        "the complete stream is not reported complete"
    );
    assert!(full.damage.is_none(), "damage reported in a fresh stream");
    check_guarantee(&raster, &full, &options);
    check_prefixes(&raster, &encoded, &options, &cuts);
    check_flipped_bit(&raster, &encoded, flip);
}

/// The first byte after the header and the nodata mask, and the first of the ladder.
fn section_ends(encoded: &Encoded) -> (usize, usize) {
    let header = &encoded.header;
    let mask_end = encoded.header_len + header.mask_len as usize;
    (mask_end, encoded.bytes.len() - header.ladder_len as usize)
}

/// [`decode_prefixes`]' checks of prefixes: at fixed places and at the `cuts` the input
/// chose.
fn check_prefixes(raster: &Raster, encoded: &Encoded, options: &EncodeOptions, cuts: &[u16]) {
    let bytes = &encoded.bytes;
    let header_len = encoded.header_len;
    let (mask_end, ladder_start) = section_ends(encoded);
    let len = bytes.len();
    let mut prefixes = vec![
        0,
        7,
        header_len.saturating_sub(1),
        header_len,
        mask_end,
        mask_end + 1,
        ladder_start.saturating_sub(1),
        ladder_start,
        len - 1,
    ];
    prefixes.extend(cuts.iter().map(|&c| usize::from(c) % (len + 1)));
    for cut in prefixes {
        let cut = cut.min(len);
        let result = decode(&bytes[..cut], &fuzz_options());
        if cut < header_len {
            assert!(
                result.is_err(),
                "a {cut}-byte prefix (header {header_len}) decoded"
            );
            continue;
        }
        if cut < mask_end {
            continue;
        }
        let decoded = result.unwrap_or_else(|e| {
            panic!("prefix of {cut} of {len} bytes (header + mask {mask_end}) fails: {e}")
        });
        check_prefix(raster, encoded, options, cut, &decoded);
    }
}

/// The checks of one decodable prefix of `cut` bytes.
fn check_prefix(
    raster: &Raster,
    encoded: &Encoded,
    options: &EncodeOptions,
    cut: usize,
    decoded: &Decoded,
) {
    let (_, ladder_start) = section_ends(encoded);
    check_shape(raster, decoded);
    check_voids(raster, decoded, cut);
    if cut < ladder_start {
        assert!(
            !decoded.complete,
            "prefix of {cut} bytes (sections end at {ladder_start}) reported complete"
        );
    }
    if decoded.complete {
        check_guarantee(raster, decoded, options);
    }
    let limited = fuzz_options().with_max_bytes(Some(cut as u64));
    let same = decode(&encoded.bytes, &limited).expect("max_bytes decode of a decodable prefix");
    assert!(
        same_samples(&same.raster.samples, &decoded.raster.samples),
        "max_bytes = {cut} decodes differently from the {cut}-byte prefix"
    );
}

/// [`decode_prefixes`]' check of one flipped bit, at `flip` modulo the file's bits.
fn check_flipped_bit(raster: &Raster, encoded: &Encoded, flip: u16) {
    let len = encoded.bytes.len();
    let (mask_end, _) = section_ends(encoded);
    let at = usize::from(flip) % (len * 8);
    let mut damaged = encoded.bytes.clone();
    damaged[at / 8] ^= 1 << (at % 8);
    let result = decode(&damaged, &fuzz_options());
    if at / 8 < mask_end {
        if at / 8 < encoded.header_len {
            assert!(
                result.is_err(),
                "bit {at} flipped in the header, decoded anyway"
            );
        }
        return;
    }
    let decoded = result.unwrap_or_else(|e| panic!("bit {at} flipped after the mask: {e}"));
    let damage = decoded
        .damage
        .unwrap_or_else(|| panic!("bit {at} of {len} bytes flipped, no damage reported"));
    assert!(
        damage.offset <= (at / 8) as u64,
        "damage reported at {} for a flip in byte {}",
        damage.offset,
        at / 8
    );
    check_shape(raster, &decoded);
    check_voids(raster, &decoded, at / 8);
}

/// Encodes an arbitrary raster in an arbitrary mode and checks the decoded stream.
///
/// Input layout: a [`PARAMS`]-byte parameter block (missing bytes read as zeros), then
/// the sample bytes, repeated as needed:
///
/// | byte | meaning |
/// |---|---|
/// | 0 | sample type (u8, u16, i16, i32, f32) |
/// | 1, 2 | width, height (1–64) |
/// | 3 | samples: raw bytes, a smooth walk (step scale in the high bits), four distinct values, special values (±0, ±∞, NaN, subnormals, the type's extremes, −9999) |
/// | 4 | nodata: none, NaN, the first sample, the type's minimum, bytes 5–12 as an f64, bytes 5–8 as an f32 |
/// | 5–12 | the nodata value |
/// | 13 | mode: lossless 5/3, max-error, precision, 9/7 at a budget, 5/3 at a budget, any combination (bits 3–7) |
/// | 14 | the error bound or precision step: from a table, or (≥ 0xF0) bytes 15–18 as an f32 |
/// | 19, 20 | byte budget − 100 |
/// | 21 | levels: the default, or (bit 7) the low 4 bits, capped at the maximum unless bit 6; bit 5: tiles of 8 + (bytes 15–18 mod 32) a side |
/// | 22–39 | used by [`decode_prefixes`] only |
///
/// Checks: encoding succeeds where it must (lossless 5/3 of 8- and 16-bit integers and
/// of finite floats); the encoded file fits its budget; the complete stream decodes,
/// `complete`, with the raster's size, type and nodata; lossless streams give every valid
/// sample bit for bit; max-error and precision streams keep every valid sample within the
/// requested bound (and the bound the header claims); every void (nodata or NaN) sample
/// is still a void.
#[doc(hidden)]
pub fn roundtrip(data: &[u8]) {
    let (params, sample_bytes) = data.split_at(data.len().min(PARAMS));
    let mut input = Input::new(params);
    let raster = arbitrary_raster(&mut input, sample_bytes, 64);
    let (options, levels_given) = arbitrary_encode_options(&mut input, &raster);

    let encoded = match encode(&raster, &options) {
        Ok(encoded) => encoded,
        Err(e) => {
            let must_succeed = options.quality == Quality::Lossless
                && options.wavelet.is_reversible()
                && options.budget_bytes.is_none()
                && !levels_given
                && match &raster.samples {
                    Samples::U8(_) | Samples::U16(_) | Samples::I16(_) => true,
                    Samples::F32(v) => v.iter().all(|x| x.is_finite() || x.is_nan()),
                    Samples::I32(_) => false,
                };
            assert!(!must_succeed, "lossless encode refused: {e}");
            return;
        }
    };
    if let Some(budget) = options.budget_bytes {
        assert!(
            encoded.bytes.len() as u64 <= budget,
            "{} bytes for a budget of {budget}",
            encoded.bytes.len()
        );
    }
    let decoded = decode(&encoded.bytes, &fuzz_options())
        .unwrap_or_else(|e| panic!("freshly encoded stream fails to decode: {e}"));
    assert!(decoded.complete, "complete stream not reported complete");
    assert!(
        decoded.damage.is_none(),
        "damage reported in a fresh stream"
    );
    check_guarantee(&raster, &decoded, &options);
}

/// The raster's size and type survive.
fn check_shape(original: &Raster, decoded: &Decoded) {
    let r = &decoded.raster;
    assert_eq!(
        (r.width, r.height),
        (original.width, original.height),
        "size"
    );
    assert_eq!(r.sample_type(), original.sample_type(), "sample type");
    assert_eq!(r.samples.len(), original.len(), "sample count");
}

/// Every void of `original` is a void of the decoded raster (`what` locates the decode
/// in messages).
fn check_voids(original: &Raster, decoded: &Decoded, what: usize) {
    for i in 0..original.len() {
        if !original.is_valid(i) {
            assert!(
                !decoded.raster.is_valid(i),
                "void sample {i} ({}, nodata {:?}) decodes as the valid {} (decoded nodata {:?}) [{what}]",
                original.samples.get_f64(i),
                original.nodata,
                decoded.raster.samples.get_f64(i),
                decoded.raster.nodata,
            );
        }
    }
}

/// What a complete decode must give: the raster's shape and nodata, voids kept, and the
/// accuracy the requested quality and the header's mode promise.
fn check_guarantee(original: &Raster, decoded: &Decoded, options: &EncodeOptions) {
    check_shape(original, decoded);
    let r = &decoded.raster;
    // Nodata: as given, or NaN for float voids without one.
    let nodata_ok = match (original.nodata, r.nodata) {
        (a, b) if a.map(f64::to_bits) == b.map(f64::to_bits) => true,
        (None, Some(b)) => b.is_nan() && original.sample_type() == SampleType::F32,
        _ => false,
    };
    assert!(
        nodata_ok,
        "nodata {:?} decodes as {:?}",
        original.nodata, r.nodata
    );
    check_voids(original, decoded, usize::MAX);
    check_requested(original, decoded, options);
    check_promised(original, decoded);
}

/// What the request in `options` promises, whatever the encoder chose.
fn check_requested(original: &Raster, decoded: &Decoded, options: &EncodeOptions) {
    let header = &decoded.header;
    let r = &decoded.raster;
    let no_budget = options.budget_bytes.is_none();
    match options.quality {
        Quality::Lossless if no_budget && options.wavelet.is_reversible() => {
            assert_eq!(
                header.mode,
                Mode::Lossless,
                "lossless request, {:?} stream",
                header.mode
            );
        }
        Quality::MaxError(e) if no_budget => {
            assert!(
                matches!(header.mode, Mode::Lossless | Mode::MaxError),
                "max-error request, {:?} stream",
                header.mode
            );
            check_bound(original, r, e, "requested max error");
        }
        Quality::Precision(step) if no_budget => {
            assert_eq!(
                header.mode,
                Mode::Precision,
                "precision request, {:?} stream",
                header.mode
            );
            let largest = (0..original.len())
                .filter(|&i| original.is_valid(i))
                .map(|i| original.samples.get_f64(i).abs())
                .fold(0.0, f64::max);
            check_bound(
                original,
                r,
                step / 2.0 + largest * f64::from(f32::EPSILON),
                "precision step / 2",
            );
        }
        _ => {}
    }
}

/// What the stream's header promises.
fn check_promised(original: &Raster, decoded: &Decoded) {
    let r = &decoded.raster;
    match decoded.header.mode {
        Mode::Lossless => {
            for i in 0..original.len() {
                if original.is_valid(i) {
                    assert!(
                        same_sample(&original.samples, &r.samples, i),
                        "lossless stream: sample {i} is {} (bits {:x}), decodes as {} (bits {:x})",
                        original.samples.get_f64(i),
                        sample_bits(&original.samples, i),
                        r.samples.get_f64(i),
                        sample_bits(&r.samples, i),
                    );
                }
            }
        }
        Mode::MaxError | Mode::Precision => {
            check_bound(original, r, decoded.header.max_error, "header max_error")
        }
        Mode::Lossy => {}
    }
}

/// Every valid sample of `original` within `bound` of `decoded` (a NaN fails).
fn check_bound(original: &Raster, decoded: &Raster, bound: f64, what: &str) {
    for i in 0..original.len() {
        if original.is_valid(i) {
            let (a, b) = (original.samples.get_f64(i), decoded.samples.get_f64(i));
            let error = (a - b).abs();
            // Written so that a NaN error fails.
            assert!(
                error <= bound,
                "sample {i}: {a} decodes as {b}, error {error} > {what} {bound}"
            );
        }
    }
}

/// The bits of sample `i`, for messages.
fn sample_bits(samples: &Samples, i: usize) -> u64 {
    match samples {
        Samples::F32(v) => u64::from(v[i].to_bits()),
        other => other.get_f64(i) as i64 as u64,
    }
}

/// Sample `i` identical in both: bit for bit, any NaN equal to any NaN.
fn same_sample(a: &Samples, b: &Samples, i: usize) -> bool {
    match (a, b) {
        (Samples::F32(x), Samples::F32(y)) => {
            x[i].to_bits() == y[i].to_bits() || (x[i].is_nan() && y[i].is_nan())
        }
        _ => a.sample_type() == b.sample_type() && a.get_f64(i) == b.get_f64(i),
    }
}

/// All samples identical (see [`same_sample`]).
fn same_samples(a: &Samples, b: &Samples) -> bool {
    a.len() == b.len() && (0..a.len()).all(|i| same_sample(a, b, i))
}

/// Reads parameter bytes; past the end every read gives zeros.
struct Input<'a> {
    data: &'a [u8],
    pos: usize,
}

impl<'a> Input<'a> {
    fn new(data: &'a [u8]) -> Input<'a> {
        Input { data, pos: 0 }
    }

    fn u8(&mut self) -> u8 {
        let b = self.data.get(self.pos).copied().unwrap_or(0);
        self.pos = self.pos.saturating_add(1);
        b
    }

    fn u16(&mut self) -> u16 {
        u16::from_le_bytes([self.u8(), self.u8()])
    }

    fn u32(&mut self) -> u32 {
        u32::from_le_bytes([self.u8(), self.u8(), self.u8(), self.u8()])
    }

    fn u64(&mut self) -> u64 {
        u64::from(self.u32()) | u64::from(self.u32()) << 32
    }
}

const TYPES: [SampleType; 5] = [
    SampleType::U8,
    SampleType::U16,
    SampleType::I16,
    SampleType::I32,
    SampleType::F32,
];

/// Bit patterns worth trying in every type (cast to the type: `as u8`, `as i16`, ...;
/// for f32 the pattern is the float's bits).
const SPECIAL: [u32; 16] = [
    0,
    1,
    0xFFFF_FFFF,
    0x7FFF_FFFF,
    0x8000_0000,
    0x0000_7FFF,
    0x0000_8000,
    0x0000_00FF,
    0x0000_FFFF,
    0x7F80_0000, // +inf
    0xFF80_0000, // -inf
    0x7FC0_0000, // NaN
    0x0000_0001, // smallest subnormal
    0x7F7F_FFFF, // f32::MAX
    0x3F80_0000, // 1.0
    0xC61C_3C00, // -9999.0
];

/// Length of the parameter block that precedes the samples in the inputs of
/// [`decode_prefixes`] and [`roundtrip`].
pub const PARAMS: usize = 40;

/// A raster of up to `max_side` × `max_side` samples of any type, with a nodata value
/// that may or may not occur in it, from the parameter block (read through `input`) and
/// the sample bytes (see [`roundtrip`] for the layout).
fn arbitrary_raster(input: &mut Input, sample_bytes: &[u8], max_side: usize) -> Raster {
    let sample_type = TYPES[usize::from(input.u8()) % TYPES.len()];
    let width = usize::from(input.u8()) % max_side + 1;
    let height = usize::from(input.u8()) % max_side + 1;
    let style = input.u8();
    let nodata_choice = input.u8();
    let nodata_bits = input.u64();
    let bits = arbitrary_bits(sample_type, style, width * height, sample_bytes);
    let samples = match sample_type {
        SampleType::U8 => Samples::U8(bits.iter().map(|&b| b as u8).collect()),
        SampleType::U16 => Samples::U16(bits.iter().map(|&b| b as u16).collect()),
        SampleType::I16 => Samples::I16(bits.iter().map(|&b| b as u16 as i16).collect()),
        SampleType::I32 => Samples::I32(bits.iter().map(|&b| b as i32).collect()),
        SampleType::F32 => Samples::F32(bits.iter().map(|&b| f32::from_bits(b)).collect()),
    };
    let mut raster = Raster::new(width, height, samples).expect("consistent raster");
    raster.nodata = match nodata_choice % 6 {
        0 => None,
        1 => Some(f64::NAN),
        2 => Some(raster.samples.get_f64(0)),
        3 => Some(sample_type.value_range().0),
        4 => Some(f64::from_bits(nodata_bits)),
        _ => Some(f64::from(f32::from_bits(nodata_bits as u32))),
    };
    raster
}

/// The bit patterns of `n` samples of `sample_type` in one of four styles (see
/// [`roundtrip`]: byte 3), from `sample_bytes` repeated as needed.
fn arbitrary_bits(sample_type: SampleType, style: u8, n: usize, sample_bytes: &[u8]) -> Vec<u32> {
    let byte = |k: usize| -> u8 {
        if sample_bytes.is_empty() {
            0
        } else {
            sample_bytes[k % sample_bytes.len()]
        }
    };
    let word = |k: usize| -> u32 {
        u32::from_le_bytes([
            byte(4 * k),
            byte(4 * k + 1),
            byte(4 * k + 2),
            byte(4 * k + 3),
        ])
    };
    match style % 4 {
        // Raw: each sample from the next bytes.
        0 => (0..n)
            .map(|k| match sample_type {
                SampleType::U8 => u32::from(byte(k)),
                SampleType::U16 | SampleType::I16 => {
                    u32::from(u16::from_le_bytes([byte(2 * k), byte(2 * k + 1)]))
                }
                _ => word(k),
            })
            .collect(),
        // A smooth walk: each byte is a signed step, scaled.
        1 => {
            let scale = [1i64, 3, 50, 1000, 100_000][usize::from(style >> 2) % 5];
            let mut value: i64 = 0;
            (0..n)
                .map(|k| {
                    value = value.wrapping_add(i64::from(byte(k) as i8) * scale);
                    match sample_type {
                        SampleType::F32 => ((value as f64 / 16.0) as f32).to_bits(),
                        SampleType::U8 => (value.rem_euclid(256)) as u32,
                        SampleType::U16 => (value.rem_euclid(65536)) as u32,
                        _ => value as i32 as u32,
                    }
                })
                .collect()
        }
        // Four distinct values, two bits a sample.
        2 => {
            let palette = [word(0), word(1), word(2), word(3)];
            (0..n)
                .map(|k| palette[usize::from(byte(16 + k / 4) >> (2 * (k % 4))) & 3])
                .collect()
        }
        // Special values.
        _ => (0..n)
            .map(|k| SPECIAL[usize::from(byte(k)) % SPECIAL.len()])
            .collect(),
    }
}

/// Encoder options from the input (see [`roundtrip`] for the layout); also says whether
/// the levels were given explicitly.
fn arbitrary_encode_options(input: &mut Input, raster: &Raster) -> (EncodeOptions, bool) {
    const BOUNDS: [f64; 14] = [
        0.5, 1.0, 1.5, 2.0, 3.0, 7.25, 10.0, 100.0, 0.001, 0.1, 1000.0, 65536.0, 1e6, 0.25,
    ];
    let mode = input.u8();
    let bound_choice = input.u8();
    let bound_bits = input.u32();
    let bound = if bound_choice < 0xF0 {
        BOUNDS[usize::from(bound_choice) % BOUNDS.len()]
    } else {
        f64::from(f32::from_bits(bound_bits))
    };
    let budget = u64::from(input.u16()) + 100;
    let levels_byte = input.u8();
    let levels = (levels_byte & 0x80 != 0).then(|| {
        let max = wavelet::max_levels(raster.width, raster.height);
        u32::from(levels_byte & 0x0F).min(max + u32::from(levels_byte & 0x40 != 0))
    });
    let mut options = match mode % 6 {
        0 => EncodeOptions::new(Quality::Lossless, None),
        1 => EncodeOptions::new(Quality::MaxError(bound), None),
        2 => EncodeOptions::new(Quality::Precision(bound), None),
        3 => EncodeOptions::new(Quality::Lossless, Some(budget)),
        4 => EncodeOptions::new(Quality::Lossless, Some(budget)).with_wavelet(Wavelet::Int53),
        // Any combination, including those the encoder must refuse.
        _ => {
            let quality = match (mode >> 3) % 3 {
                0 => Quality::Lossless,
                1 => Quality::MaxError(bound),
                _ => Quality::Precision(bound),
            };
            let wavelet = match (mode & 0x40 != 0, mode & 0x04 != 0) {
                (true, _) => Wavelet::Cdf97,
                (false, false) => Wavelet::Int53,
                (false, true) => Wavelet::Int1311,
            };
            EncodeOptions::new(quality, (mode & 0x80 != 0).then_some(budget))
                .with_wavelet(wavelet)
                .with_tile_size(None)
                .with_threads(1)
        }
    };
    options.levels = levels;
    if levels_byte & 0x20 != 0 {
        options.tile_size = Some(8 + (bound_bits & 31));
    }
    (options, levels.is_some())
}
