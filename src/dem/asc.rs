//! ESRI ASCII grids (`.asc`).
//!
//! Header keys (case-insensitive): `ncols`, `nrows`, `xllcorner` or `xllcenter`,
//! `yllcorner` or `yllcenter`, `cellsize` (or `dx` and `dy`), optional `NODATA_value`,
//! followed by `ncols × nrows` whitespace-separated values, north row first.
//!
//! A grid whose values are all integers fitting `i32` (and whose nodata value is an
//! integer in that range) is read as I32, anything else as F32. The header becomes a
//! north-up geotransform without GeoKeys; writing drops GeoKeys (the format has none).

use std::io::{self, BufRead, Write};
use std::path::Path;

use wavemesh_codec::{Georef, Raster, SampleType, Samples};

use super::{checked_sample_count, make_raster, read_error, DemError, ReadOptions};

/// The header keywords, lower-case.
const KEYS: [&str; 10] = [
    "ncols",
    "nrows",
    "xllcorner",
    "xllcenter",
    "yllcorner",
    "yllcenter",
    "cellsize",
    "dx",
    "dy",
    "nodata_value",
];

/// The UTF-8 byte order mark some editors put at the start of text files.
const UTF8_BOM: &[u8] = b"\xEF\xBB\xBF";

/// Whether `first_bytes` start (after whitespace) with an ESRI ASCII header keyword.
pub(super) fn looks_like_header(first_bytes: &[u8]) -> bool {
    let text = first_bytes.strip_prefix(UTF8_BOM).unwrap_or(first_bytes);
    let token: Vec<u8> = text
        .iter()
        .skip_while(|b| b.is_ascii_whitespace())
        .take_while(|b| !b.is_ascii_whitespace())
        .map(u8::to_ascii_lowercase)
        .collect();
    KEYS.iter().any(|k| k.as_bytes() == token.as_slice())
}

/// Header values as read.
#[derive(Default)]
struct Header {
    ncols: Option<u64>,
    nrows: Option<u64>,
    xllcorner: Option<f64>,
    xllcenter: Option<f64>,
    yllcorner: Option<f64>,
    yllcenter: Option<f64>,
    cellsize: Option<f64>,
    dx: Option<f64>,
    dy: Option<f64>,
    nodata: Option<f64>,
}

impl Header {
    /// Records `key value` from line `line_no`.
    fn set(&mut self, key: &str, value: &str, line_no: usize) -> Result<(), DemError> {
        let float = || {
            value.parse::<f64>().map_err(|_| {
                DemError::Malformed(format!(
                    "line {line_no}: {key} is '{value}'; expected a number"
                ))
            })
        };
        let count = || {
            value.parse::<u64>().map_err(|_| {
                DemError::Malformed(format!(
                    "line {line_no}: {key} is '{value}'; expected a positive integer"
                ))
            })
        };
        let slot = match key {
            "ncols" => return set_once(&mut self.ncols, count()?, key, line_no),
            "nrows" => return set_once(&mut self.nrows, count()?, key, line_no),
            "xllcorner" => &mut self.xllcorner,
            "xllcenter" => &mut self.xllcenter,
            "yllcorner" => &mut self.yllcorner,
            "yllcenter" => &mut self.yllcenter,
            "cellsize" => &mut self.cellsize,
            "dx" => &mut self.dx,
            "dy" => &mut self.dy,
            _ => &mut self.nodata,
        };
        set_once(slot, float()?, key, line_no)
    }

    /// Checks completeness; returns `(ncols, nrows, geotransform)`.
    fn finish(&self) -> Result<(u64, u64, [f64; 6]), DemError> {
        let missing = |what: &str| DemError::Malformed(format!("ESRI ASCII header lacks {what}"));
        let ncols = self.ncols.ok_or_else(|| missing("ncols"))?;
        let nrows = self.nrows.ok_or_else(|| missing("nrows"))?;
        let (dx, dy) = match (self.cellsize, self.dx, self.dy) {
            (Some(c), None, None) => (c, c),
            (None, Some(dx), Some(dy)) => (dx, dy),
            _ => return Err(missing("either cellsize or both dx and dy")),
        };
        if !(dx > 0.0 && dy > 0.0 && dx.is_finite() && dy.is_finite()) {
            return Err(DemError::Malformed(format!(
                "cell size {dx} x {dy}; expected positive finite numbers"
            )));
        }
        let x0 = match (self.xllcorner, self.xllcenter) {
            (Some(x), None) => x,
            (None, Some(x)) => x - 0.5 * dx,
            _ => return Err(missing("exactly one of xllcorner and xllcenter")),
        };
        let y0 = match (self.yllcorner, self.yllcenter) {
            (Some(y), None) => y,
            (None, Some(y)) => y - 0.5 * dy,
            _ => return Err(missing("exactly one of yllcorner and yllcenter")),
        };
        let top = y0 + nrows as f64 * dy;
        Ok((ncols, nrows, [x0, dx, 0.0, top, 0.0, -dy]))
    }
}

fn set_once<T>(slot: &mut Option<T>, value: T, key: &str, line_no: usize) -> Result<(), DemError> {
    if slot.is_some() {
        return Err(DemError::Malformed(format!(
            "line {line_no}: {key} appears twice in the header"
        )));
    }
    *slot = Some(value);
    Ok(())
}

/// Grid values while reading: integers until the first non-integer token.
enum Values {
    Int(Vec<i32>),
    Float(Vec<f32>),
}

impl Values {
    fn len(&self) -> usize {
        match self {
            Values::Int(v) => v.len(),
            Values::Float(v) => v.len(),
        }
    }

    /// Switches to floats, converting the integers read so far.
    fn make_float(&mut self) {
        if let Values::Int(ints) = self {
            *self = Values::Float(ints.iter().map(|&i| i as f32).collect());
        }
    }

    /// Parses and appends one token from line `line_no`.
    fn push(&mut self, token: &str, line_no: usize) -> Result<(), DemError> {
        if let Values::Int(v) = self {
            if let Ok(i) = token.parse::<i32>() {
                v.push(i);
                return Ok(());
            }
        }
        let f = token.parse::<f32>().map_err(|_| {
            DemError::Malformed(format!("line {line_no}: '{token}' is not a number"))
        })?;
        self.make_float();
        if let Values::Float(v) = self {
            v.push(f);
        }
        Ok(())
    }
}

/// Reads one line into `buf`; `Ok(false)` at end of file.
fn next_line<R: BufRead>(
    reader: &mut R,
    buf: &mut String,
    line_no: usize,
    path: &Path,
) -> Result<bool, DemError> {
    buf.clear();
    match reader.read_line(buf) {
        Ok(n) => Ok(n > 0),
        Err(e) if e.kind() == io::ErrorKind::InvalidData => Err(DemError::Malformed(format!(
            "line {line_no} is not valid UTF-8 text"
        ))),
        Err(e) => Err(read_error(path, e)),
    }
}

/// Reads an ESRI ASCII grid.
pub(super) fn read<R: BufRead>(
    mut reader: R,
    path: &Path,
    options: &ReadOptions,
) -> Result<Raster, DemError> {
    let mut header = Header::default();
    let mut line = String::new();
    let mut line_no = 0;
    // Header lines, up to the first line that does not start with a keyword.
    let mut pending = false;
    while next_line(&mut reader, &mut line, line_no + 1, path)? {
        line_no += 1;
        let text = if line_no == 1 {
            line.trim_start_matches('\u{feff}')
        } else {
            &line
        };
        let mut tokens = text.split_ascii_whitespace();
        let Some(first) = tokens.next() else { continue };
        let key = first.to_ascii_lowercase();
        if !KEYS.contains(&key.as_str()) {
            pending = true;
            break;
        }
        let value = tokens
            .next()
            .ok_or_else(|| DemError::Malformed(format!("line {line_no}: {first} has no value")))?;
        header.set(&key, value, line_no)?;
    }
    let (ncols, nrows, geotransform) = header.finish()?;
    let count = checked_sample_count(ncols, nrows, SampleType::F32, options)?;

    // Grow as values arrive rather than trusting the header with a huge allocation.
    let mut values = Values::Int(Vec::with_capacity(count.min(1 << 20)));
    let mut found: u64 = 0;
    loop {
        if pending {
            for token in line.split_ascii_whitespace() {
                found += 1;
                if values.len() < count {
                    values.push(token, line_no)?;
                }
            }
        }
        if !next_line(&mut reader, &mut line, line_no + 1, path)? {
            break;
        }
        line_no += 1;
        pending = true;
    }
    if found != count as u64 {
        return Err(DemError::Malformed(format!(
            "expected ncols x nrows = {ncols} x {nrows} = {count} values, found {found}"
        )));
    }

    let mut nodata = header.nodata;
    if let (Values::Int(_), Some(nd)) = (&values, nodata) {
        if nd.fract() != 0.0 || nd < f64::from(i32::MIN) || nd > f64::from(i32::MAX) {
            values.make_float();
        }
    }
    let samples = match values {
        Values::Int(v) => Samples::I32(v),
        Values::Float(v) => {
            // Compare like with like: the nodata value as the f32 the samples hold.
            nodata = nodata.map(|nd| f64::from(nd as f32));
            Samples::F32(v)
        }
    };
    let mut raster = make_raster(ncols as usize, nrows as usize, samples)?;
    raster.nodata = nodata;
    raster.georef = Some(Georef {
        geotransform,
        ..Georef::default()
    });
    Ok(raster)
}

/// Refuses rasters whose georeferencing an ASCII grid cannot express.
pub(super) fn check_writable(raster: &Raster) -> Result<(), DemError> {
    if let Some(g) = &raster.georef {
        let gt = g.geotransform;
        let north_up = gt[2] == 0.0 && gt[4] == 0.0 && gt[1] > 0.0 && gt[5] < 0.0;
        if !north_up {
            return Err(DemError::Unsupported(format!(
                "geotransform {gt:?} is rotated or not north-up; ESRI ASCII grids need \
                 [x, dx > 0, 0, y, 0, -dy < 0] (write .tif instead)"
            )));
        }
    }
    Ok(())
}

/// Writes `raster` as an ESRI ASCII grid (call [`check_writable`] first).
///
/// Integers are printed as integers, `f32` values with Rust's shortest round-trip
/// formatting, so reading back gives the same values.
pub(super) fn write(raster: &Raster, w: &mut dyn Write) -> io::Result<()> {
    let (x0, dx, top, dy) = match &raster.georef {
        Some(g) => {
            let gt = g.geotransform;
            (gt[0], gt[1], gt[3], -gt[5])
        }
        None => (0.0, 1.0, raster.height as f64, 1.0),
    };
    writeln!(w, "ncols {}", raster.width)?;
    writeln!(w, "nrows {}", raster.height)?;
    writeln!(w, "xllcorner {x0}")?;
    writeln!(w, "yllcorner {}", top - raster.height as f64 * dy)?;
    if dx == dy {
        writeln!(w, "cellsize {dx}")?;
    } else {
        writeln!(w, "dx {dx}")?;
        writeln!(w, "dy {dy}")?;
    }
    let nan_stand_in = nan_nodata_stand_in(raster);
    if let Some(nd) = raster.nodata {
        match raster.samples {
            Samples::F32(_) => writeln!(w, "NODATA_value {}", nan_stand_in.unwrap_or(nd as f32))?,
            _ if nd.fract() == 0.0 && nd.abs() < 1e18 => writeln!(w, "NODATA_value {}", nd as i64)?,
            _ => writeln!(w, "NODATA_value {nd}")?,
        }
    }
    write_rows(raster, nan_stand_in, w)
}

/// For `f32` rasters whose nodata is NaN: a finite value no valid sample holds, written
/// for the voids instead of `NaN` (GDAL before 3.7 cannot read a `NaN` token).
fn nan_nodata_stand_in(raster: &Raster) -> Option<f32> {
    let Samples::F32(values) = &raster.samples else {
        return None;
    };
    if !raster.nodata.is_some_and(f64::is_nan) {
        return None;
    }
    let candidates = [-9999.0f32, -99999.0, -999999.0, -3.4028235e38, 3.4028235e38];
    candidates
        .into_iter()
        .find(|c| !values.contains(c))
        .or(Some(-9999.0))
}

/// Writes the data lines, with `nan_stand_in` for NaN samples when given.
fn write_rows(raster: &Raster, nan_stand_in: Option<f32>, w: &mut dyn Write) -> io::Result<()> {
    let mut row = String::new();
    for r in 0..raster.height {
        row.clear();
        let range = r * raster.width..(r + 1) * raster.width;
        match &raster.samples {
            Samples::U8(v) => join(&mut row, &v[range]),
            Samples::U16(v) => join(&mut row, &v[range]),
            Samples::I16(v) => join(&mut row, &v[range]),
            Samples::I32(v) => join(&mut row, &v[range]),
            Samples::F32(v) => match nan_stand_in {
                Some(stand_in) => join_floats(&mut row, &v[range], stand_in),
                None => join(&mut row, &v[range]),
            },
        }
        row.push('\n');
        w.write_all(row.as_bytes())?;
    }
    Ok(())
}

/// Appends `values` to `out`, separated by single spaces.
fn join<T: std::fmt::Display>(out: &mut String, values: &[T]) {
    use std::fmt::Write as _;
    for (i, v) in values.iter().enumerate() {
        if i > 0 {
            out.push(' ');
        }
        // Writing to a String cannot fail.
        let _ = write!(out, "{v}");
    }
}

/// [`join`] for floats, with `nan_stand_in` written for every NaN.
fn join_floats(out: &mut String, values: &[f32], nan_stand_in: f32) {
    use std::fmt::Write as _;
    for (i, v) in values.iter().enumerate() {
        if i > 0 {
            out.push(' ');
        }
        let v = if v.is_nan() { nan_stand_in } else { *v };
        // Writing to a String cannot fail.
        let _ = write!(out, "{v}");
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::Cursor;

    fn parse(text: &str) -> Result<Raster, DemError> {
        read(
            Cursor::new(text.as_bytes()),
            Path::new("t.asc"),
            &ReadOptions::default(),
        )
    }

    fn to_text(raster: &Raster) -> String {
        check_writable(raster).unwrap();
        let mut out = Vec::new();
        write(raster, &mut out).unwrap();
        String::from_utf8(out).unwrap()
    }

    #[test]
    fn reads_integer_grid_with_nodata() {
        let r = parse(
            "NCOLS 3\nnrows 2\nxllcorner 100\nYLLCORNER 200\ncellsize 10\nNODATA_value -9999\n\
             1 2 3\n-9999 5 2147483647\n",
        )
        .unwrap();
        assert_eq!(r.samples, Samples::I32(vec![1, 2, 3, -9999, 5, i32::MAX]));
        assert_eq!(r.nodata, Some(-9999.0));
        let g = r.georef.unwrap();
        assert_eq!(g.geotransform, [100.0, 10.0, 0.0, 220.0, 0.0, -10.0]);
        assert!(g.geo_key_directory.is_empty());
    }

    #[test]
    fn tolerates_bom_blank_lines_and_crlf() {
        let r = parse(
            "\u{feff}ncols 2\r\n\r\nnrows 1\r\nxllcorner 0\r\nyllcorner 0\r\ncellsize 1\r\n7 8\r\n",
        )
        .unwrap();
        assert_eq!(r.samples, Samples::I32(vec![7, 8]));
    }

    #[test]
    fn floats_centres_and_dx_dy() {
        let r = parse(
            "ncols 2\nnrows 2\nxllcenter 0.5\nyllcenter 1\ndx 1\ndy 2\n\
             1 2.5\n3 4 \n",
        )
        .unwrap();
        assert_eq!(r.samples, Samples::F32(vec![1.0, 2.5, 3.0, 4.0]));
        assert_eq!(
            r.georef.unwrap().geotransform,
            [0.0, 1.0, 0.0, 4.0, 0.0, -2.0]
        );
        // Values may wrap across lines freely, and an integer too big for i32 makes floats.
        let r = parse("ncols 3\nnrows 1\nxllcorner 0\nyllcorner 0\ncellsize 1\n1\n2 3000000000\n")
            .unwrap();
        assert_eq!(r.samples, Samples::F32(vec![1.0, 2.0, 3e9]));
    }

    #[test]
    fn float_nodata_makes_floats_and_matches_f32() {
        let r = parse(
            "ncols 2\nnrows 1\nxllcorner 0\nyllcorner 0\ncellsize 1\nnodata_value -0.1\n1 -0.1\n",
        )
        .unwrap();
        assert!(!r.is_valid(1));
        assert!(r.is_valid(0));
        assert_eq!(r.sample_type(), wavemesh_codec::SampleType::F32);
    }

    #[test]
    fn lying_header_is_malformed() {
        let base = "ncols 3\nnrows 2\nxllcorner 0\nyllcorner 0\ncellsize 1\n";
        let err = parse(&format!("{base}1 2 3\n4 5\n"))
            .unwrap_err()
            .to_string();
        assert!(err.contains("6 values, found 5"), "{err}");
        let err = parse(&format!("{base}1 2 3\n4 5 6 7\n"))
            .unwrap_err()
            .to_string();
        assert!(err.contains("6 values, found 7"), "{err}");
    }

    #[test]
    fn bad_tokens_name_the_line() {
        let err = parse("ncols 2\nnrows 2\nxllcorner 0\nyllcorner 0\ncellsize 1\n1 2\n3 x4\n")
            .unwrap_err()
            .to_string();
        assert!(err.contains("line 7") && err.contains("x4"), "{err}");
        let err = parse("ncols two\nnrows 2\n").unwrap_err().to_string();
        assert!(err.contains("line 1"), "{err}");
        assert!(parse("ncols 2\nnrows 2\ncellsize 1\n1 2 3 4\n").is_err());
        assert!(parse("ncols 1\nncols 1\n").is_err());
        assert!(parse("ncols 1\nnrows 1\nxllcorner 0\nyllcorner 0\ncellsize -1\n5\n").is_err());
        assert!(parse("ncols 0\nnrows 1\nxllcorner 0\nyllcorner 0\ncellsize 1\n").is_err());
        assert!(parse("").is_err());
        let bytes = b"ncols 1\nnrows 1\nxllcorner 0\nyllcorner 0\ncellsize 1\n\xff\n";
        let err = read(
            Cursor::new(&bytes[..]),
            Path::new("t.asc"),
            &ReadOptions::default(),
        );
        assert!(matches!(err, Err(DemError::Malformed(m)) if m.contains("line 6")));
    }

    #[test]
    fn absurd_header_is_refused_before_allocating() {
        let text = "ncols 100000000\nnrows 100000000\nxllcorner 0\nyllcorner 0\ncellsize 1\n1\n";
        assert!(matches!(parse(text), Err(DemError::TooLarge { .. })));
        // Over the memory limit: refused before reading a value.
        let text = "ncols 40000\nnrows 40000\nxllcorner 0\nyllcorner 0\ncellsize 1\n1\n";
        assert!(matches!(parse(text), Err(DemError::OverMemory { .. })));
        // Within the limits but lying: no huge allocation, just a count mismatch.
        let text = "ncols 20000\nnrows 20000\nxllcorner 0\nyllcorner 0\ncellsize 1\n1\n";
        assert!(matches!(parse(text), Err(DemError::Malformed(_))));
    }

    #[test]
    fn detects_header() {
        assert!(looks_like_header(b"  NCOLS 5"));
        assert!(looks_like_header(b"nodata_value -1"));
        assert!(looks_like_header(b"\xEF\xBB\xBFncols 1"));
        assert!(!looks_like_header(b"ncolsx 5"));
        assert!(!looks_like_header(b""));
    }

    #[test]
    fn round_trips_every_type() {
        let g = Georef {
            geotransform: [-120.5, 0.25, 0.0, 45.0, 0.0, -0.25],
            ..Georef::default()
        };
        let cases = [
            (Samples::U8(vec![0, 1, 255, 7, 8, 9]), Some(255.0)),
            (Samples::U16(vec![0, 1, 65535, 7, 8, 9]), None),
            (
                Samples::I16(vec![-32768, 1, 32767, 7, 8, 9]),
                Some(-32768.0),
            ),
            (
                Samples::I32(vec![i32::MIN, 1, i32::MAX, -7, 8, 9]),
                Some(-9999.0),
            ),
        ];
        for (samples, nodata) in cases {
            let mut r = Raster::new(3, 2, samples).unwrap();
            r.nodata = nodata;
            r.georef = Some(g.clone());
            let back = parse(&to_text(&r)).unwrap();
            assert_eq!(back.samples.to_f64(), r.samples.to_f64());
            assert_eq!(back.nodata, r.nodata);
            assert_eq!(back.georef, r.georef);
        }
    }

    #[test]
    fn round_trips_f32_exactly_with_nan() {
        let values = vec![
            0.1f32,
            -1.0e-7,
            3.4028235e38,
            f32::MIN_POSITIVE,
            f32::NAN,
            1234.5677,
            -9999.0,
            -0.0,
        ];
        let mut r = Raster::new(4, 2, Samples::F32(values.clone())).unwrap();
        r.nodata = Some(f64::NAN);
        r.georef = Some(Georef {
            geotransform: [0.0, 2.0, 0.0, 10.0, 0.0, -0.5],
            ..Georef::default()
        });
        let text = to_text(&r);
        assert!(text.contains("dx 2\ndy 0.5\n"), "{text}");
        let back = parse(&text).unwrap();
        let Samples::F32(got) = &back.samples else {
            panic!("type")
        };
        // NaN voids are written as a finite stand-in no valid sample holds (-9999 is
        // taken here), so that every GDAL since 2.x reads the grid; no line holds "NaN".
        assert!(text.contains("NODATA_value -99999\n"), "{text}");
        assert!(!text.to_ascii_lowercase().contains("nan"), "{text}");
        for (a, b) in values.iter().zip(got) {
            if a.is_nan() {
                assert_eq!(*b, -99999.0);
            } else {
                assert_eq!(a.to_bits(), b.to_bits());
            }
        }
        assert_eq!(back.nodata, Some(-99999.0));
        assert_eq!(back.georef, r.georef);
    }

    #[test]
    fn no_georef_writes_unit_cells_and_rotation_is_refused() {
        let r = Raster::new(2, 1, Samples::I16(vec![1, 2])).unwrap();
        let text = to_text(&r);
        assert!(text.starts_with("ncols 2\nnrows 1\nxllcorner 0\nyllcorner 0\ncellsize 1\n"));
        let mut rot = r.clone();
        rot.georef = Some(Georef {
            geotransform: [0.0, 1.0, 0.1, 0.0, 0.0, -1.0],
            ..Georef::default()
        });
        assert!(matches!(
            check_writable(&rot),
            Err(DemError::Unsupported(_))
        ));
    }
}
