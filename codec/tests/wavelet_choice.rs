//! The encoder's choice between the two reversible wavelets: the one it settles on codes
//! the raster smaller, smooth terrain takes the 13/11, noise-like data the 5/3, a plane
//! too wide for the 13/11's exact arithmetic the 5/3, and an explicit wavelet is kept.

use wavemesh_codec::{decode, encode, DecodeOptions, EncodeOptions, Raster, Samples, Wavelet};

/// A raster of `width × height` i32 samples `f(x, y)`.
fn raster(width: usize, height: usize, f: impl Fn(f64, f64) -> f64) -> Raster {
    let values: Vec<f64> = (0..width * height)
        .map(|i| f((i % width) as f64, (i / width) as f64).round())
        .collect();
    Raster::new(
        width,
        height,
        Samples::I32(values.iter().map(|&v| v as i32).collect()),
    )
    .unwrap()
}

/// Smooth terrain: long waves and a tilt.
fn smooth(x: f64, y: f64) -> f64 {
    1000.0 + 400.0 * (x / 23.0).sin() * (y / 17.0).cos() + 0.3 * x * y / 10.0
}

/// Noise of ±`amplitude` (xorshift on the position) over a gentle slope.
fn noisy(amplitude: f64) -> impl Fn(f64, f64) -> f64 {
    move |x, y| {
        let mut s = (x as u64 * 7919 + y as u64 * 104729) | 1;
        for _ in 0..3 {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
        }
        x + y + amplitude * ((s >> 11) as f64 / (1u64 << 53) as f64 - 0.5)
    }
}

/// Bytes of a lossless one-stream encode with `wavelet` forced, bit-exact checked.
fn lossless_bytes(raster: &Raster, wavelet: Option<Wavelet>) -> (usize, Wavelet) {
    let mut options = EncodeOptions::lossless().single_stream();
    if let Some(w) = wavelet {
        options = options.with_wavelet(w);
    }
    let encoded = encode(raster, &options).unwrap();
    let decoded = decode(&encoded.bytes, &DecodeOptions::default()).unwrap();
    assert_eq!(
        decoded.raster.samples, raster.samples,
        "{wavelet:?} not exact"
    );
    (encoded.bytes.len(), encoded.header.wavelet)
}

#[test]
fn the_wavelet_settled_on_codes_the_raster_smaller() {
    for (name, data, expected) in [
        ("smooth", raster(200, 150, smooth), Wavelet::Int1311),
        ("noisy", raster(200, 150, noisy(200.0)), Wavelet::Int53),
    ] {
        let (chosen_bytes, chosen) = lossless_bytes(&data, None);
        let (bytes_53, _) = lossless_bytes(&data, Some(Wavelet::Int53));
        let (bytes_1311, _) = lossless_bytes(&data, Some(Wavelet::Int1311));
        assert_eq!(
            chosen, expected,
            "{name}: 5/3 {bytes_53} B, 13/11 {bytes_1311} B"
        );
        assert_eq!(chosen_bytes, bytes_53.min(bytes_1311), "{name}");
        assert_ne!(bytes_53, bytes_1311, "{name}");
    }
}

#[test]
fn a_tiled_file_has_the_wavelet_of_the_raster_and_an_explicit_one_is_kept() {
    let data = raster(300, 200, smooth);
    let tiled = EncodeOptions::lossless().with_tile_size(Some(64));
    let encoded = encode(&data, &tiled).unwrap();
    assert_eq!(encoded.header.wavelet, Wavelet::Int1311);
    let decoded = decode(&encoded.bytes, &DecodeOptions::default()).unwrap();
    assert_eq!(decoded.raster.samples, data.samples);
    let forced = tiled.with_wavelet(Wavelet::Int53);
    assert_eq!(
        encode(&data, &forced).unwrap().header.wavelet,
        Wavelet::Int53
    );
    assert!(!forced.adaptive_wavelet);
}

#[test]
fn planes_too_wide_for_the_13_11_take_the_5_3() {
    // Smooth, but beyond ±2^19 the 13/11's sums could wrap: the 5/3, still exact.
    let wide = raster(120, 90, |x, y| smooth(x, y) * 2000.0);
    assert_eq!(lossless_bytes(&wide, None).1, Wavelet::Int53);
    let narrow = raster(120, 90, smooth);
    assert_eq!(lossless_bytes(&narrow, None).1, Wavelet::Int1311);
}
