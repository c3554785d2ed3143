//! `demo`: the bundled sample end to end — lossless, progressive prefixes of one 9/7 and
//! one 5/3 stream, and error-bounded streams — printed as one table.

use std::path::{Path, PathBuf};

use serde::Serialize;
use wavemesh::metrics::{self, Distortion};
use wavemesh_codec::{
    decode, encode, DecodeOptions, EncodeOptions, Encoded, Quality, Raster, Wavelet,
};

use super::coding::{compare_rasters, write_output, SCHEMA_VERSION};
use super::{timed, CliError, InputArgs};

/// The sample the demo uses when none is given.
const DEFAULT_SAMPLE: &str = "samples/jacksboro_fault.tif";

#[derive(Debug, clap::Args)]
pub struct DemoArgs {
    /// DEM to run on (default: the bundled samples/jacksboro_fault.tif).
    input: Option<PathBuf>,
    /// Where to write the encoded and decoded files.
    #[arg(long, default_value = "target/wavemesh-demo")]
    out_dir: PathBuf,
    /// Print one JSON object on stdout instead of the table.
    #[arg(long)]
    json: bool,
    #[command(flatten)]
    input_args: InputArgs,
}

#[derive(Debug, Serialize)]
struct Row {
    stream: String,
    decoded_at: String,
    bytes: u64,
    bpp: f64,
    psnr_db: f64,
    rmse: f64,
    max_error: f64,
    exact: bool,
    seconds: f64,
}

#[derive(Serialize)]
struct DemoReport<'a> {
    schema_version: u32,
    command: &'static str,
    input: &'a Path,
    width: usize,
    height: usize,
    sample_type: &'static str,
    range: f64,
    rows: Vec<Row>,
}

fn sample_path(args: &DemoArgs) -> PathBuf {
    if let Some(p) = &args.input {
        return p.clone();
    }
    let local = PathBuf::from(DEFAULT_SAMPLE);
    if local.exists() {
        local
    } else {
        Path::new(env!("CARGO_MANIFEST_DIR")).join(DEFAULT_SAMPLE)
    }
}

fn encode_or_fail(raster: &Raster, options: &EncodeOptions) -> Result<(Encoded, f64), CliError> {
    let (encoded, seconds, _) = timed(|| encode(raster, options));
    Ok((encoded.map_err(CliError::Encode)?, seconds))
}

fn decode_row(
    raster: &Raster,
    encoded: &Encoded,
    stream: &str,
    max_bytes: Option<u64>,
    label: String,
) -> Result<Row, CliError> {
    let options = DecodeOptions {
        max_bytes,
        ..DecodeOptions::default()
    };
    let (decoded, seconds, _) = timed(|| decode(&encoded.bytes, &options));
    let decoded = decoded.map_err(|e| CliError::Stream(PathBuf::from(stream), e))?;
    let d: Distortion = compare_rasters(raster, &decoded.raster, Path::new(stream))?;
    let bytes = max_bytes.map_or(encoded.bytes.len() as u64, |m| {
        m.min(encoded.bytes.len() as u64)
    });
    Ok(Row {
        stream: stream.to_string(),
        decoded_at: label,
        bytes,
        bpp: metrics::bits_per_sample(bytes, raster.width, raster.height),
        psnr_db: d.psnr_db,
        rmse: d.rmse,
        max_error: d.max_error,
        exact: d.identical,
        seconds,
    })
}

pub fn run(args: &DemoArgs) -> Result<(), CliError> {
    let path = sample_path(args);
    let raster = args.input_args.read(&path)?;
    let samples = (raster.width * raster.height) as f64;
    std::fs::create_dir_all(&args.out_dir)
        .map_err(|e| CliError::Output(args.out_dir.clone(), e.to_string()))?;
    let mut rows = Vec::new();

    // Lossless 5/3.
    let (lossless, seconds) =
        encode_or_fail(&raster, &EncodeOptions::new(Quality::Lossless, None))?;
    write_output(&args.out_dir.join("lossless.ezw"), &lossless.bytes)?;
    let mut row = decode_row(&raster, &lossless, "5/3 lossless", None, "all".into())?;
    row.seconds += seconds;
    if !row.exact {
        return Err(CliError::Usage(
            "lossless round trip is not bit-exact".into(),
        ));
    }
    rows.push(row);
    let rates = [0.1, 0.25, 0.5, 1.0, 2.0];
    for &rate in &rates {
        let bytes = (rate * samples / 8.0) as u64;
        rows.push(decode_row(
            &raster,
            &lossless,
            "5/3 lossless",
            Some(bytes),
            format!("prefix {rate} bpp"),
        )?);
    }

    // One 9/7 stream at 2 bpp, decoded at every rate.
    let mut options = EncodeOptions::new(Quality::Lossless, Some((2.0 * samples / 8.0) as u64));
    options.wavelet = Wavelet::Cdf97;
    let (lossy, _) = encode_or_fail(&raster, &options)?;
    write_output(&args.out_dir.join("lossy-2bpp.ezw"), &lossy.bytes)?;
    for &rate in &rates {
        let bytes = (rate * samples / 8.0) as u64;
        rows.push(decode_row(
            &raster,
            &lossy,
            "9/7 --bpp 2",
            Some(bytes),
            format!("prefix {rate} bpp"),
        )?);
    }

    // Error-bounded 5/3 streams.
    for e in [0.5, 1.0, 2.0] {
        let (bounded, seconds) =
            encode_or_fail(&raster, &EncodeOptions::new(Quality::MaxError(e), None))?;
        write_output(
            &args.out_dir.join(format!("max-error-{e}.ezw")),
            &bounded.bytes,
        )?;
        let mut row = decode_row(
            &raster,
            &bounded,
            &format!("5/3 --max-error {e}"),
            None,
            "all".into(),
        )?;
        row.seconds += seconds;
        if row.max_error > e {
            return Err(CliError::Usage(format!(
                "max error {} exceeds the bound {e}",
                row.max_error
            )));
        }
        rows.push(row);
    }

    let range = compare_rasters(&raster, &raster, &path)?.range;
    let report = DemoReport {
        schema_version: SCHEMA_VERSION,
        command: "demo",
        input: &path,
        width: raster.width,
        height: raster.height,
        sample_type: raster.sample_type().name(),
        range,
        rows,
    };
    if args.json {
        println!(
            "{}",
            serde_json::to_string(&report).expect("reports serialise")
        );
        return Ok(());
    }
    println!(
        "wavemesh demo: {} ({}x{} {}, R = {}), files in {}\n",
        path.display(),
        report.width,
        report.height,
        report.sample_type,
        report.range,
        args.out_dir.display()
    );
    println!("| stream | decoded | bytes | bpp | PSNR dB | RMSE | max error | exact | seconds |");
    println!("|---|---|---:|---:|---:|---:|---:|:---:|---:|");
    for r in &report.rows {
        println!(
            "| {} | {} | {} | {:.4} | {} | {:.4} | {} | {} | {:.4} |",
            r.stream,
            r.decoded_at,
            r.bytes,
            r.bpp,
            if r.psnr_db.is_finite() {
                format!("{:.2}", r.psnr_db)
            } else {
                "∞".into()
            },
            r.rmse,
            r.max_error,
            if r.exact { "yes" } else { "" },
            r.seconds
        );
    }
    Ok(())
}
