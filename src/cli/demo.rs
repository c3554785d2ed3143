//! `demo`: the bundled sample end to end — lossless, progressive prefixes of one 9/7 and
//! one 5/3 stream, and error-bounded streams — printed as one table; then a mesh of the
//! lossless decode within a height tolerance, and the seed paper's Tables 1 and 2.

use std::path::{Path, PathBuf};
use std::time::Instant;

use serde::Serialize;
use wavemesh::lod::{self, build_mesh, Surface, TableRow, TableRows};
use wavemesh::mesh::cells::SplitRule;
use wavemesh::mesh::export::{write_mesh, MeshFormat, Placement};
use wavemesh::mesh::rasterise::{mesh_error, MeshError};
use wavemesh::mesh::MeshTarget;
use wavemesh::metrics::{self, Distortion};
use wavemesh_codec::{
    decode, encode, DecodeOptions, EncodeOptions, Encoded, Quality, Raster, Wavelet,
};

use super::coding::{compare_rasters, write_output, SCHEMA_VERSION};
use super::mesh::uncovered_note;
use super::{print_json, timed, CliError, InputArgs};

/// The sample the demo uses when none is given, built into the binary so that an
/// installed `wavemesh demo` runs anywhere.
const BUNDLED_SAMPLE: &[u8] = include_bytes!("../../samples/jacksboro_fault.tif");

/// The name the bundled sample gets in the output folder.
const BUNDLED_NAME: &str = "jacksboro_fault.tif";

/// Height tolerance of the demo's mesh, data units (metres for the sample).
const MESH_TOLERANCE: f64 = 5.0;

#[derive(Debug, clap::Args)]
pub struct DemoArgs {
    /// DEM to run on (default: the sample built into the binary, USGS jacksboro_fault).
    input: Option<PathBuf>,
    /// Where to write the encoded and decoded files (and the bundled sample).
    #[arg(long, default_value = "wavemesh-demo")]
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

/// The mesh of the lossless decode within [`MESH_TOLERANCE`].
#[derive(Debug, Serialize)]
struct DemoMesh {
    output: PathBuf,
    format: &'static str,
    tolerance: f64,
    triangles: usize,
    vertices: usize,
    /// Triangles as a percentage of the full grid's `2·(w−1)·(h−1)`.
    remaining_percent: f64,
    /// Against the original DEM (the lossless decode is bit-exact).
    error: MeshError,
    decode_seconds: f64,
    pyramid_seconds: f64,
    mesh_seconds: f64,
    write_seconds: f64,
    file_bytes: u64,
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
    mesh: DemoMesh,
    /// The seed paper's Tables 1 and 2, one row per pass of the lossless stream.
    tables: Vec<TableRow>,
}

/// The DEM to run on: the one given, else the bundled sample written into `out_dir`.
fn sample_path(args: &DemoArgs) -> Result<PathBuf, CliError> {
    if let Some(p) = &args.input {
        return Ok(p.clone());
    }
    let path = args.out_dir.join(BUNDLED_NAME);
    write_output(&path, BUNDLED_SAMPLE)?;
    Ok(path)
}

fn encode_or_fail(raster: &Raster, options: &EncodeOptions) -> Result<(Encoded, f64), CliError> {
    let (encoded, seconds, _) = timed(|| encode(raster, options));
    Ok((encoded.map_err(CliError::Encode)?, seconds))
}

/// Decodes `lossless` with the significance map, meshes it within [`MESH_TOLERANCE`],
/// checks the bound against `raster` and writes the mesh to `path` (glTF binary).
fn demo_mesh(raster: &Raster, lossless: &Encoded, path: &Path) -> Result<DemoMesh, CliError> {
    let options = DecodeOptions::default().with_significance_map(true);
    let (decoded, decode_seconds, _) = timed(|| decode(&lossless.bytes, &options));
    let decoded = decoded.map_err(|e| CliError::Stream(PathBuf::from("5/3 lossless"), e))?;
    let map = decoded
        .significance
        .as_ref()
        .expect("decoded with the significance map");
    let surface = Surface::of(&decoded.raster);
    let timed_mesh = build_mesh(
        map,
        &surface,
        MeshTarget::Tolerance(MESH_TOLERANCE),
        SplitRule::Zerotree,
        None,
    );
    let mesh = &timed_mesh.mesh;
    let reference = Surface::of(raster);
    let error = mesh_error(mesh, &surface.heights, &reference.heights, &reference.valid);
    if error.max_error > MESH_TOLERANCE || error.max_error.is_nan() {
        return Err(CliError::Usage(format!(
            "mesh max error {} exceeds the tolerance {MESH_TOLERANCE}",
            error.max_error
        )));
    }
    let placement = Placement::metric(raster.georef.as_ref(), raster.width, raster.height, 1.0)
        .map_err(|e| CliError::Input(PathBuf::from("sample"), e.to_string()))?;
    let format = MeshFormat::Glb;
    let start = Instant::now();
    write_mesh(path, mesh, &surface.heights, &placement, format)
        .map_err(|e| CliError::Output(path.to_path_buf(), e.to_string()))?;
    let write_seconds = start.elapsed().as_secs_f64();
    let full = 2 * raster.width.saturating_sub(1) * raster.height.saturating_sub(1);
    Ok(DemoMesh {
        output: path.to_path_buf(),
        format: format.name(),
        tolerance: MESH_TOLERANCE,
        triangles: mesh.triangles.len(),
        vertices: mesh.vertices.len(),
        remaining_percent: 100.0 * mesh.triangles.len() as f64 / full.max(1) as f64,
        error,
        decode_seconds,
        pyramid_seconds: timed_mesh.pyramid_seconds,
        mesh_seconds: timed_mesh.mesh_seconds,
        write_seconds,
        file_bytes: std::fs::metadata(path).map_or(0, |m| m.len()),
    })
}

fn decode_row(
    raster: &Raster,
    encoded: &Encoded,
    stream: &str,
    max_bytes: Option<u64>,
    label: String,
) -> Result<Row, CliError> {
    let options = DecodeOptions::default().with_max_bytes(max_bytes);
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
    std::fs::create_dir_all(&args.out_dir)
        .map_err(|e| CliError::Output(args.out_dir.clone(), e.to_string()))?;
    let path = sample_path(args)?;
    let raster = args.input_args.read_to_encode(&path)?;
    let samples = (raster.width * raster.height) as f64;
    let mut rows = Vec::new();

    // Lossless (the 13/11 or the 5/3, as the encoder chooses).
    let (lossless, seconds) = encode_or_fail(
        &raster,
        &EncodeOptions::new(Quality::Lossless, None).single_stream(),
    )?;
    write_output(&args.out_dir.join("lossless.ezw"), &lossless.bytes)?;
    let lossless_name = format!("{} lossless", lossless.header.wavelet.name());
    let mut row = decode_row(&raster, &lossless, &lossless_name, None, "all".into())?;
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
            &lossless_name,
            Some(bytes),
            format!("prefix {rate} bpp"),
        )?);
    }

    // One 9/7 stream at 2 bpp, decoded at every rate.
    let mut options = EncodeOptions::new(Quality::Lossless, Some((2.0 * samples / 8.0) as u64));
    options = options.with_wavelet(Wavelet::Cdf97);
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

    // Error-bounded streams (13/11, or a cut 9/7 with corrections when smaller).
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
            &format!("--max-error {e}"),
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

    // A mesh of the lossless decode, and the seed paper's tables from the same stream.
    let stem = path
        .file_stem()
        .map_or_else(|| "demo".into(), |s| s.to_string_lossy().into_owned());
    let mesh = demo_mesh(
        &raster,
        &lossless,
        &args.out_dir.join(format!("{stem}.glb")),
    )?;
    let tables = lod::paper_table(
        &raster,
        &lossless,
        &TableRows::AllPasses,
        SplitRule::Zerotree,
        3,
    )
    .map_err(|e| CliError::Stream(PathBuf::from("5/3 lossless"), e))?;

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
        mesh,
        tables,
    };
    if args.json {
        print_json(&report);
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
    let m = &report.mesh;
    println!(
        "\nmesh {} (5/3 lossless, tolerance {} data units): {} triangles, {} vertices ({:.2} % of the grid's)",
        m.output.display(),
        m.tolerance,
        m.triangles,
        m.vertices,
        m.remaining_percent
    );
    println!(
        "  vs original DEM: RMSE {:.4}  PSNR {:.2} dB  max error {:.4}{}; decode {:.3} s, error pyramid {:.3} s, mesh {:.3} s, write {:.3} s ({} bytes)",
        m.error.rmse,
        m.error.psnr_db,
        m.error.max_error,
        uncovered_note(&m.error),
        m.decode_seconds,
        m.pyramid_seconds,
        m.mesh_seconds,
        m.write_seconds,
        m.file_bytes
    );
    println!("\n{}", lod::table_markdown(&report.tables).trim_end());
    Ok(())
}
