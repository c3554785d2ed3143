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

/// A file in code blocks whose header claims a huge raster: its blocks are counted only
/// once the index is read, so the claim cannot make the reader count or allocate them.
#[test]
fn forged_huge_headers_of_code_block_files_are_refused() {
    let values = (0..200 * 100)
        .map(|i| ((i % 200) + (i / 200)) as i16)
        .collect();
    let raster = Raster::new(200, 100, Samples::I16(values)).unwrap();
    let options = EncodeOptions::lossless().with_code_block(Some(64));
    let file = encode(&raster, &options).unwrap().bytes;
    // 1.5 M a side in tiles of 200 × 100 with a 469 MiB index: the index could hold
    // their 1.1 × 10^8 entries, so only reading it (the file ends first) refuses them.
    let (mut header, header_len) = Header::parse(&file).unwrap();
    (header.width, header.height) = (1_500_000, 1_500_000);
    let tiling = header.tiling.as_mut().unwrap();
    assert_eq!((tiling.tile_width, tiling.tile_height), (200, 100));
    tiling.index_len = 16384 * 30_000 + 4 * 30_000;
    let mut long_index = header.to_bytes();
    long_index.extend_from_slice(&file[header_len..]);
    assert!(
        Header::parse(&long_index).is_ok(),
        "the claim passes the header's checks"
    );
    let claims = [65_536, 1 << 24, u32::MAX].map(|side| forged(&file, side));
    for (side, bytes) in [65_536, 1 << 24, u32::MAX, 1_500_000]
        .into_iter()
        .zip(claims.into_iter().chain([long_index]))
    {
        let Ok(_) = Header::parse(&bytes) else {
            continue;
        };
        assert!(decode(&bytes, &DecodeOptions::default()).is_err(), "{side}");
        let limit = Limits::default().max_memory / 4;
        if let Ok(Some(layout)) = TiledLayout::read(&mut &bytes[..], limit) {
            assert!(layout.entries.len() < 1 << 20, "{side}");
        }
        if let Ok(found) = verify(&bytes) {
            assert!(found.usable_bytes <= bytes.len() as u64, "{side}");
        }
    }
}
