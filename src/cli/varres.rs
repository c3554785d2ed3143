//! `compare-meshers --varres-metrics`: the seed paper 001's Table 1 for one DEM (its
//! average-plane error metric against the distance-to-plane metric: simplification
//! ratio against mean distance).

use std::path::Path;

use wavemesh::lod::Surface;
use wavemesh::mesh::varres::table::metric_table;
use wavemesh_codec::Raster;

use super::coding::SCHEMA_VERSION;
use super::{with_progress, CliError};

/// Prints the table for `raster` (read from `input`) as Markdown or JSON.
pub fn varres_metrics(input: &Path, raster: &Raster, json: bool) -> Result<(), CliError> {
    let surface = Surface::of(raster);
    let (w, h) = (surface.width, surface.height);
    let rows = with_progress("simplifying", || {
        metric_table(w, h, &surface.heights, &surface.valid)
    })
    .map_err(|e| CliError::Input(input.to_path_buf(), e.to_string()))?;
    if json {
        let report = serde_json::json!({
            "schema_version": SCHEMA_VERSION,
            "command": "compare-meshers",
            "input": input,
            "width": w,
            "height": h,
            "varres_metrics": rows,
        });
        println!(
            "{}",
            serde_json::to_string_pretty(&report).expect("reports serialise")
        );
        return Ok(());
    }
    let name = input.file_name().unwrap_or_default().to_string_lossy();
    println!("| DEM | metric | simplified | triangles | mean distance | max distance |\n|---|---|---:|---:|---:|---:|");
    for r in &rows {
        let metric = match r.metric {
            "average_plane" => "average plane (paper)",
            _ => "distance to plane",
        };
        println!(
            "| {name} | {metric} | {:.0} % | {} | {:.3} | {:.2} |",
            r.ratio_percent, r.triangles, r.mean_error, r.max_error
        );
    }
    Ok(())
}
