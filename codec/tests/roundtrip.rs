//! End-to-end codec properties: lossless exactness, the max-error guarantee, embedded
//! prefixes, and hostile input.

use proptest::prelude::*;
use wavemesh_codec::{
    decode, encode, DecodeOptions, EncodeOptions, Quality, Raster, SampleType, Samples, Wavelet,
};

/// A smooth-ish random terrain of the given type: ridges plus noise, in the type's range.
fn terrain(
    width: usize,
    height: usize,
    sample_type: SampleType,
    seed: u64,
    amplitude: f64,
) -> Raster {
    let mut state = seed | 1;
    let mut noise = move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state >> 11) as f64 / (1u64 << 53) as f64 - 0.5
    };
    let base = match sample_type {
        SampleType::U8 => 128.0,
        SampleType::U16 => 30000.0,
        _ => 0.0,
    };
    let values: Vec<f64> = (0..width * height)
        .map(|i| {
            let (x, y) = ((i % width) as f64, (i / width) as f64);
            base + amplitude * ((x * 0.21).sin() * (y * 0.13).cos() + 0.3 * noise())
        })
        .collect();
    Raster::new(width, height, Samples::from_f64(sample_type, &values)).unwrap()
}

fn amplitude(sample_type: SampleType) -> f64 {
    match sample_type {
        SampleType::U8 => 100.0,
        SampleType::U16 => 20000.0,
        SampleType::I16 => 3000.0,
        SampleType::I32 => 100_000.0,
        SampleType::F32 => 1234.5,
    }
}

fn roundtrip(raster: &Raster, options: &EncodeOptions) -> Raster {
    let encoded = encode(raster, options).unwrap();
    let decoded = decode(&encoded.bytes, &DecodeOptions::default()).unwrap();
    assert!(decoded.complete || options.budget_bytes.is_some());
    decoded.raster
}

fn max_abs_error(a: &Raster, b: &Raster) -> f64 {
    (0..a.len())
        .filter(|&i| a.is_valid(i))
        .map(|i| (a.samples.get_f64(i) - b.samples.get_f64(i)).abs())
        .fold(0.0, f64::max)
}

fn squared_error(a: &Raster, b: &Raster) -> f64 {
    (0..a.len())
        .filter(|&i| a.is_valid(i))
        .map(|i| (a.samples.get_f64(i) - b.samples.get_f64(i)).powi(2))
        .sum()
}

const TYPES: [SampleType; 5] = [
    SampleType::U8,
    SampleType::U16,
    SampleType::I16,
    SampleType::I32,
    SampleType::F32,
];

proptest! {
    #![proptest_config(ProptestConfig::with_cases(48))]

    #[test]
    fn lossless_is_bit_exact(w in 1usize..40, h in 1usize..40, t in 0usize..5, seed in any::<u64>()) {
        let raster = terrain(w, h, TYPES[t], seed, amplitude(TYPES[t]));
        let decoded = roundtrip(&raster, &EncodeOptions::new(Quality::Lossless, None));
        prop_assert_eq!(decoded, raster);
    }

    #[test]
    fn max_error_holds_on_every_sample(w in 1usize..40, h in 1usize..40, t in 0usize..5, seed in any::<u64>(), e in prop::sample::select(vec![0.5, 1.0, 2.0, 3.5, 10.0])) {
        let raster = terrain(w, h, TYPES[t], seed, amplitude(TYPES[t]));
        let decoded = roundtrip(&raster, &EncodeOptions::new(Quality::MaxError(e), None));
        let err = max_abs_error(&raster, &decoded);
        prop_assert!(err <= e, "max error {} > {}", err, e);
    }

    #[test]
    fn nodata_survives(w in 2usize..30, h in 2usize..30, seed in any::<u64>()) {
        let mut raster = terrain(w, h, SampleType::I16, seed, 2000.0);
        if let Samples::I16(v) = &mut raster.samples {
            for (i, s) in v.iter_mut().enumerate() {
                if (i as u64).wrapping_mul(seed | 1).is_multiple_of(7) {
                    *s = -32768;
                }
            }
        }
        raster.nodata = Some(-32768.0);
        let decoded = roundtrip(&raster, &EncodeOptions::new(Quality::Lossless, None));
        prop_assert_eq!(&decoded, &raster);
        let bounded = roundtrip(&raster, &EncodeOptions::new(Quality::MaxError(3.0), None));
        prop_assert_eq!(bounded.valid_mask(), raster.valid_mask());
        prop_assert!(max_abs_error(&raster, &bounded) <= 3.0);
    }
}

#[test]
fn float_lossless_on_and_off_grid_with_nan_voids() {
    // On a 0.1 grid (as Terrain-RGB), off any grid, and with NaN voids.
    let on_grid: Vec<f32> = (0..50 * 40)
        .map(|i| ((i * 37 % 9000) as f64 * 0.1 + 13.7) as f32)
        .collect();
    let off_grid: Vec<f32> = (0..50 * 40)
        .map(|i| (i as f32 * 0.123_456_7).sin() * 812.345 + 1000.0)
        .collect();
    for values in [on_grid, off_grid] {
        let mut with_voids = values.clone();
        for v in with_voids.iter_mut().step_by(11) {
            *v = f32::NAN;
        }
        for samples in [values, with_voids] {
            let raster = Raster::new(50, 40, Samples::F32(samples)).unwrap();
            let decoded = roundtrip(&raster, &EncodeOptions::new(Quality::Lossless, None));
            let (Samples::F32(a), Samples::F32(b)) = (&raster.samples, &decoded.samples) else {
                panic!("type changed")
            };
            for (x, y) in a.iter().zip(b) {
                assert!(
                    x.to_bits() == y.to_bits() || (x.is_nan() && y.is_nan()),
                    "{x} vs {y}"
                );
            }
        }
    }
}

/// A void costs about its mask and no coefficients: a raster whose right half is NaN
/// codes losslessly in at most 5 % more than its valid left half alone (3.6 %; 7.3 % when
/// the fill was coded), and decodes exactly.
#[test]
fn a_large_void_costs_about_nothing_but_its_mask() {
    let (width, height) = (128, 96);
    let terrain = terrain(
        width,
        height,
        SampleType::F32,
        7,
        amplitude(SampleType::F32),
    );
    let left: Vec<f32> = (0..width / 2 * height)
        .map(|i| {
            terrain
                .samples
                .get_f64((i / (width / 2)) * width + i % (width / 2)) as f32
        })
        .collect();
    let half_void: Vec<f32> = (0..width * height)
        .map(|i| {
            if i % width < width / 2 {
                terrain.samples.get_f64(i) as f32
            } else {
                f32::NAN
            }
        })
        .collect();
    let options = EncodeOptions::new(Quality::Lossless, None);
    let left = Raster::new(width / 2, height, Samples::F32(left)).unwrap();
    let half_void = Raster::new(width, height, Samples::F32(half_void)).unwrap();
    let alone = encode(&left, &options).unwrap().bytes.len();
    let with_void = encode(&half_void, &options).unwrap().bytes.len();
    assert!(
        with_void as f64 <= alone as f64 * 1.05,
        "half void {with_void} bytes, its valid half alone {alone}"
    );
    let decoded = roundtrip(&half_void, &options);
    for i in (0..width * height).filter(|&i| half_void.is_valid(i)) {
        assert_eq!(decoded.samples.get_f64(i), half_void.samples.get_f64(i));
    }
}

#[test]
fn float_precision_bound() {
    let values: Vec<f32> = (0..64 * 64)
        .map(|i| (i as f32 * 0.01).cos() * 500.0 + 700.0)
        .collect();
    let raster = Raster::new(64, 64, Samples::F32(values)).unwrap();
    let decoded = roundtrip(&raster, &EncodeOptions::new(Quality::Precision(0.05), None));
    // Half the step, plus the f32 rounding of values near 1200.
    assert!(max_abs_error(&raster, &decoded) <= 0.025 + 1200.0 * f32::EPSILON as f64);
}

#[test]
fn every_prefix_decodes_and_error_falls() {
    let raster = terrain(37, 29, SampleType::I16, 99, 3000.0);
    for options in [
        EncodeOptions::new(Quality::Lossless, None),
        EncodeOptions::new(Quality::Lossless, Some(4000)).with_wavelet(Wavelet::Cdf97),
    ] {
        let encoded = encode(&raster, &options).unwrap();
        let mut best = f64::INFINITY;
        let mut errors = Vec::new();
        for cut in encoded.header_len..=encoded.bytes.len() {
            let decoded = decode(&encoded.bytes[..cut], &DecodeOptions::default()).unwrap();
            let err = squared_error(&raster, &decoded.raster);
            errors.push(err);
            best = best.min(err);
        }
        // Error at pass boundaries never increases (inside a pass a single refinement
        // may move one coefficient's reconstruction away from its value).
        let mut previous = f64::INFINITY;
        for pass in &encoded.header.passes {
            let cut = encoded.header_len + pass.end_byte as usize;
            let at = errors[cut - encoded.header_len];
            assert!(
                at <= previous * 1.0001 + 1e-9,
                "{:?}: error rose to {at} from {previous} at plane {}",
                options.wavelet,
                pass.plane
            );
            previous = at;
        }
        assert!(best < errors[0]);
    }
}

#[test]
fn an_integer_rasters_complete_97_stream_is_exact_and_a_larger_budget_is_not_spent() {
    for sample_type in [
        SampleType::U8,
        SampleType::U16,
        SampleType::I16,
        SampleType::I32,
    ] {
        let raster = terrain(96, 80, sample_type, 17, amplitude(sample_type));
        let budget = 8 * raster.len() as u64; // 64 bits a sample: more than any stream needs
        let options = EncodeOptions::new(Quality::Lossless, Some(budget))
            .with_wavelet(Wavelet::Cdf97)
            .with_tile_size(None);
        let encoded = encode(&raster, &options).unwrap();
        assert!(
            (encoded.bytes.len() as u64) < budget / 2,
            "{sample_type:?}: {} bytes of a {budget}-byte budget",
            encoded.bytes.len()
        );
        let decoded = decode(&encoded.bytes, &DecodeOptions::default()).unwrap();
        assert!(decoded.complete, "{sample_type:?}");
        assert_eq!(decoded.raster.samples, raster.samples, "{sample_type:?}");
        // Its last plane's interval is at most a quarter of a unit, and more than an
        // eighth: no plane past what the rounding to whole units needs.
        let step = encoded.header.coefficient_step;
        assert!(step > 0.125 && step <= 0.25, "{sample_type:?}: step {step}");
    }
}

#[test]
fn a_budget_the_lossless_file_fits_gets_the_lossless_file_unless_97_is_asked_for() {
    let raster = terrain(96, 80, SampleType::I16, 23, 300.0);
    let lossless = encode(&raster, &EncodeOptions::lossless()).unwrap();
    let fits = lossless.bytes.len() as u64 + 100;
    let default = encode(&raster, &EncodeOptions::budget(fits)).unwrap();
    assert!(default.header.wavelet.is_reversible());
    assert_eq!(default.bytes, lossless.bytes);
    let forced = EncodeOptions::budget(fits).with_wavelet(Wavelet::Cdf97);
    assert_eq!(
        encode(&raster, &forced).unwrap().header.wavelet,
        Wavelet::Cdf97
    );
    // Below the lossless size, the 9/7 as before.
    let short = lossless.bytes.len() as u64 - 100;
    let cut = encode(&raster, &EncodeOptions::budget(short)).unwrap();
    assert_eq!(cut.header.wavelet, Wavelet::Cdf97);
    assert_eq!(cut.bytes.len() as u64, short);
    // Tiled, flat tiles beside detailed ones: the choice is the whole file's, never a
    // tile's (a flat tile's lossless stream fits its cap, the file's does not).
    let rugged = terrain(300, 200, SampleType::I16, 29, 3000.0);
    let values: Vec<f64> = (0..rugged.len())
        .map(|i| {
            if i % 300 < 150 {
                7.0
            } else {
                rugged.samples.get_f64(i)
            }
        })
        .collect();
    let coast = Raster::new(300, 200, Samples::from_f64(SampleType::I16, &values)).unwrap();
    let budget = encode(&coast, &EncodeOptions::lossless().with_tile_size(Some(128)))
        .unwrap()
        .bytes
        .len() as u64
        / 2;
    let default = EncodeOptions::budget(budget).with_tile_size(Some(128));
    let forced = default.clone().with_wavelet(Wavelet::Cdf97);
    let (default, forced) = (encode(&coast, &default), encode(&coast, &forced));
    assert!(
        default.unwrap().bytes == forced.unwrap().bytes,
        "a tile chose alone"
    );
    // Floats off any grid too (their residuals counted in the estimate).
    let floats = terrain(96, 80, SampleType::F32, 23, 300.0);
    let exact = encode(&floats, &EncodeOptions::lossless()).unwrap();
    assert!(exact.header.residual_len > 0, "the floats lie on a grid");
    for (budget, lossless) in [
        (exact.bytes.len() + 100, true),
        (exact.bytes.len() - 100, false),
    ] {
        let coded = encode(&floats, &EncodeOptions::budget(budget as u64)).unwrap();
        assert_eq!(coded.bytes == exact.bytes, lossless, "budget {budget}");
    }
}

#[test]
fn rate_cut_is_exact() {
    let raster = terrain(64, 64, SampleType::U16, 5, 20000.0);
    for budget in [200u64, 512, 1000, 3000] {
        let options = EncodeOptions::new(Quality::Lossless, Some(budget));
        let encoded = encode(&raster, &options).unwrap();
        assert_eq!(encoded.bytes.len() as u64, budget);
        decode(&encoded.bytes, &DecodeOptions::default()).unwrap();
    }
}

#[test]
fn garbage_and_damage_give_errors_or_images_never_panics() {
    let raster = terrain(23, 17, SampleType::I16, 3, 500.0);
    let encoded = encode(&raster, &EncodeOptions::new(Quality::Lossless, None)).unwrap();
    let mut tried = 0;
    // Bit flips at every byte (bits 0, 3 and 7: low, middle and high of each byte).
    for i in 0..encoded.bytes.len() {
        for bit in [0, 3, 7] {
            let mut damaged = encoded.bytes.clone();
            damaged[i] ^= 1 << bit;
            let _ = decode(&damaged, &DecodeOptions::default());
            tried += 1;
        }
    }
    // Random bytes, with and without a valid magic.
    let mut state = 0x1234_5678_9abc_def1u64;
    for n in 0..2000usize {
        let len = n % 300;
        let mut bytes: Vec<u8> = (0..len)
            .map(|_| {
                state ^= state << 13;
                state ^= state >> 7;
                state ^= state << 17;
                state as u8
            })
            .collect();
        if n % 2 == 0 && len >= 8 {
            bytes[..8].copy_from_slice(&wavemesh_codec::format::MAGIC);
        }
        // A forged header would need a matching CRC-32: random bytes never decode.
        assert!(decode(&bytes, &DecodeOptions::default()).is_err());
        tried += 1;
    }
    assert!(tried > 2000);
}

#[test]
fn float_extremes_are_refused_or_round_trip() {
    let specials = [
        (f32::INFINITY, f32::NEG_INFINITY),
        (f32::INFINITY, 1.0),
        (f32::MAX, -f32::MAX),
        (-0.0, 0.0),
        (-0.0, -0.0),
        (0.123_456_79, 0.123_456_79),
    ];
    for (a, b) in specials {
        let values: Vec<f32> = (0..64).map(|i| if i % 3 == 0 { a } else { b }).collect();
        let raster = Raster::new(8, 8, Samples::F32(values.clone())).unwrap();
        for wavelet in [Wavelet::Int53, Wavelet::Cdf97] {
            let options = EncodeOptions::new(Quality::Lossless, None).with_wavelet(wavelet);
            let Ok(encoded) = encode(&raster, &options) else {
                continue;
            };
            let decoded = decode(&encoded.bytes, &DecodeOptions::default())
                .unwrap_or_else(|e| panic!("{a}, {b}, {wavelet:?}: {e}"));
            if wavelet == Wavelet::Int53 {
                let Samples::F32(back) = &decoded.raster.samples else {
                    panic!("sample type");
                };
                let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
                assert_eq!(bits(back), bits(&values), "{a}, {b}");
            }
        }
    }
}

#[test]
fn float_nan_voids_stay_voids_whatever_the_nodata() {
    let values: Vec<f32> = (0..64)
        .map(|i| {
            if i % 5 == 0 {
                f32::NAN
            } else {
                i as f32 * 0.37
            }
        })
        .collect();
    // Nodata values an f32 cannot hold (its voids are the NaNs), and one it can.
    for nodata in [1e-310, 1e300, 0.1, -9999.0] {
        let mut raster = Raster::new(8, 8, Samples::F32(values.clone())).unwrap();
        raster.nodata = Some(nodata);
        let decoded = roundtrip(&raster, &EncodeOptions::new(Quality::Lossless, None));
        assert_eq!(decoded.nodata, Some(nodata));
        for i in 0..64 {
            assert_eq!(
                decoded.is_valid(i),
                raster.is_valid(i),
                "{nodata:e}: sample {i}"
            );
        }
    }
}

#[test]
fn absurd_dimensions_are_refused_before_allocating() {
    let raster = terrain(8, 8, SampleType::U8, 1, 50.0);
    let encoded = encode(&raster, &EncodeOptions::new(Quality::Lossless, None)).unwrap();
    let mut header = encoded.header.clone();
    header.width = 1_000_000;
    header.height = 1_000_000;
    let bytes = header.to_bytes();
    let err = decode(&bytes, &DecodeOptions::default()).unwrap_err();
    assert!(err.to_string().contains("limit"), "{err}");
}

#[test]
fn max_error_by_corrections_holds_and_its_prefixes_decode() {
    // Smooth, wide-range terrain: a cut 9/7 stream plus corrections beats quantising.
    for t in [SampleType::U16, SampleType::F32] {
        let raster = terrain(96, 80, t, 17, 20000.0);
        let e = 40.0;
        let encoded = encode(&raster, &EncodeOptions::new(Quality::MaxError(e), None)).unwrap();
        assert_eq!(
            encoded.header.wavelet,
            Wavelet::Cdf97,
            "{t:?}: corrections not chosen"
        );
        assert!(encoded.header.correction_step > 0.0);
        let decoded = decode(&encoded.bytes, &DecodeOptions::default()).unwrap();
        assert!(decoded.complete);
        assert!(max_abs_error(&raster, &decoded.raster) <= e);
        // Without the corrections (or with part of the payload) it still decodes.
        let h = &encoded.header;
        let corrections_end = encoded.header_len
            + h.mask_len as usize
            + h.payload_len as usize
            + h.residual_len as usize;
        for cut in [
            corrections_end - 1,
            corrections_end / 2,
            encoded.header_len + 3,
        ] {
            let partial = decode(&encoded.bytes[..cut], &DecodeOptions::default()).unwrap();
            assert!(!partial.complete);
        }
    }
}

#[test]
fn every_bit_flip_after_the_header_is_detected_and_the_prefix_before_it_decodes() {
    let raster = terrain(40, 30, SampleType::I16, 8, 900.0);
    let encoded = encode(&raster, &EncodeOptions::new(Quality::Lossless, None)).unwrap();
    let clean = decode(&encoded.bytes, &DecodeOptions::default()).unwrap();
    assert!(clean.damage.is_none() && clean.complete);
    let mut flips = 0;
    for i in encoded.header_len..encoded.bytes.len() {
        for bit in 0..8 {
            let mut damaged = encoded.bytes.clone();
            damaged[i] ^= 1 << bit;
            let decoded = decode(&damaged, &DecodeOptions::default()).unwrap();
            let damage = decoded.damage.expect("a flipped bit is detected");
            assert!(
                damage.offset <= i as u64,
                "damage reported at {} for a flip at {i}",
                damage.offset
            );
            assert!(!decoded.complete || damage.section == "ladder");
            let strict = DecodeOptions::default().with_strict(true);
            assert!(decode(&damaged, &strict).is_err());
            flips += 1;
        }
    }
    assert!(flips > 1000);
    // A garbage tail is damage too; truncation is not.
    let mut longer = encoded.bytes.clone();
    longer.extend_from_slice(b"garbage");
    let tail = decode(&longer, &DecodeOptions::default()).unwrap();
    assert_eq!(tail.damage.map(|d| d.section), Some("trailing bytes"));
    assert_eq!(tail.raster, raster);
    let truncated = decode(
        &encoded.bytes[..encoded.bytes.len() - 10],
        &DecodeOptions::default(),
    )
    .unwrap();
    assert!(truncated.damage.is_none());
}

#[test]
fn wide_range_integers_round_trip() {
    // 26-bit range (millimetres over 67 km): planes up to 30 plus subband shifts take the
    // global plane past 31, which the coder must handle.
    let (w, h) = (520, 300);
    let values: Vec<i32> = (0..w * h)
        .map(|i| {
            let (x, y) = ((i % w) as f64, (i / w) as f64);
            (((x * 0.017).sin() * (y * 0.011).cos()) * 33_000_000.0) as i32
                + (i as i32 * 7919) % 1000
        })
        .collect();
    let raster = Raster::new(w, h, Samples::I32(values)).unwrap();
    let encoded = encode(&raster, &EncodeOptions::new(Quality::Lossless, None)).unwrap();
    let top = encoded.header.top_plane.unwrap();
    eprintln!("top plane {top}");
    assert!(top > 30, "the test must reach global planes above 30");
    assert_eq!(
        decode(&encoded.bytes, &DecodeOptions::default())
            .unwrap()
            .raster,
        raster
    );
}

#[test]
fn full_range_u16_decodes_as_the_i32_path_does_from_every_prefix() {
    // A massif spanning 0 ..= 65535 (as alps_montblanc does): its LL coefficients pass
    // plane 14, so the i16 decode keeps them escaped, and near its extremes the inverse
    // transform overshoots the range. A decode asking for a significance map takes the
    // i32 path: both must give the same samples, whole or cut.
    let (w, h) = (97, 75);
    let values: Vec<u16> = (0..w * h)
        .map(|i| {
            let (x, y) = ((i % w) as f64 / w as f64, (i / w) as f64 / h as f64);
            let peak = (-((x - 0.6).powi(2) + (y - 0.4).powi(2)) * 9.0).exp();
            let ridges = 0.08 * ((x * 41.0).sin() * (y * 37.0).cos());
            ((peak + ridges).clamp(0.0, 1.0) * 65535.0) as u16
        })
        .collect();
    assert!(values.contains(&0) && values.contains(&65535));
    let raster = Raster::new(w, h, Samples::U16(values)).unwrap();
    let encoded = encode(&raster, &EncodeOptions::new(Quality::Lossless, None)).unwrap();
    let wide = DecodeOptions::default().with_significance_map(true);
    for cut in [encoded.bytes.len(), encoded.bytes.len() / 3, 700] {
        let options = DecodeOptions::default().with_max_bytes(Some(cut as u64));
        let narrow = decode(&encoded.bytes, &options).unwrap().raster;
        let wide = decode(&encoded.bytes, &wide.with_max_bytes(Some(cut as u64)));
        assert_eq!(narrow, wide.unwrap().raster, "{cut} bytes");
        if cut == encoded.bytes.len() {
            assert_eq!(narrow, raster);
        }
    }
}

/// 16-bit samples near the top of their range, in rasters of odd widths: the integer
/// decode keeps them as `i16` differences to the middle of the range, and shifting the
/// coarsest band by that middle may push a coefficient out of its slot — which once left
/// it unshifted, and samples tens of thousands off (found by the fuzzer, 46 × 8 in tiles
/// of 25 columns).
#[test]
fn sixteen_bit_samples_near_the_top_of_their_range_are_exact() {
    let levels = [49871u16, 51475, 62625, 65333];
    let mut state = 0x2545_F491_4F6C_DD1Du64;
    for (width, height) in [(25, 8), (23, 8), (25, 9), (47, 13)] {
        for wavelet in [Wavelet::Int53, Wavelet::Int1311] {
            for _ in 0..8 {
                let samples: Vec<u16> = (0..width * height)
                    .map(|_| {
                        state ^= state << 13;
                        state ^= state >> 7;
                        state ^= state << 17;
                        levels[(state % 4) as usize]
                    })
                    .collect();
                let raster = Raster::new(width, height, Samples::U16(samples)).unwrap();
                let options = EncodeOptions::lossless().with_wavelet(wavelet);
                let encoded = encode(&raster, &options).unwrap();
                let decoded = decode(&encoded.bytes, &DecodeOptions::default()).unwrap();
                assert_eq!(
                    decoded.raster.samples, raster.samples,
                    "{width}x{height} {wavelet:?}"
                );
            }
        }
    }
}
