//! Headers that claim huge rasters (with valid checksums): every reader refuses them, or
//! reads only what the file holds, before allocating for the claimed size.

use wavemesh_codec::format::{valid_sample_count, verify, Header};
use wavemesh_codec::tiles::TiledLayout;
use wavemesh_codec::{
    decode, encode, DecodeOptions, EncodeOptions, Limits, Quality, Raster, Samples,
};

/// A 64 × 48 terrain with a void, coded as tiles of 32 (`tiled`) or one stream.
fn encoded(tiled: bool) -> Vec<u8> {
    let values = (0..64 * 48)
        .map(|i| {
            if i == 100 {
                -9999
            } else {
                ((i % 64) * 3 + (i / 64) * 2) as i16
            }
        })
        .collect();
    let mut raster = Raster::new(64, 48, Samples::I16(values)).unwrap();
    raster.nodata = Some(-9999.0);
    let options = EncodeOptions::new(Quality::Lossless, None).with_tile_size(tiled.then_some(32));
    encode(&raster, &options).unwrap().bytes
}

/// `file` with its header claiming `side × side` samples.
fn forged(file: &[u8], side: u32) -> Vec<u8> {
    let (mut header, header_len) = Header::parse(file).unwrap();
    header.width = side;
    header.height = side;
    let mut bytes = header.to_bytes();
    bytes.extend_from_slice(&file[header_len..]);
    bytes
}

#[test]
fn forged_huge_headers_are_refused_or_read_within_the_file() {
    for tiled in [false, true] {
        let file = encoded(tiled);
        for side in [65_536, u32::MAX] {
            let bytes = forged(&file, side);
            let what = format!("tiled {tiled}, {side} a side");
            // The header parses (its checksum holds) or is refused as inconsistent.
            let Ok((header, header_len)) = Header::parse(&bytes) else {
                continue;
            };
            assert!(
                header.sample_count() > Limits::default().max_samples / 2,
                "{what}"
            );
            let decoded = decode(&bytes, &DecodeOptions::default());
            assert!(decoded.is_err(), "{what}: decoded");
            let limit = Limits::default().max_memory / 4;
            match TiledLayout::read(&mut &bytes[..], limit) {
                Ok(Some(layout)) => assert!(layout.entries.len() < 1 << 20, "{what}"),
                Ok(None) => assert!(!tiled, "{what}: no layout"),
                Err(_) => {}
            }
            // verify reads every checksum there is: the file's, not the claim's.
            if let Ok(found) = verify(&bytes) {
                assert!(found.usable_bytes <= bytes.len() as u64, "{what}");
            }
            if !tiled {
                let valid = valid_sample_count(&bytes, &header, header_len, &Limits::default());
                assert!(valid.is_err(), "{what}: mask decoded");
            }
        }
    }
}
