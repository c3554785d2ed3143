//! `report`: wavemesh beside the peer tools on every DEM of a manifest folder.

use std::path::PathBuf;

use wavemesh::report::{self, DemResult};

use super::coding::SCHEMA_VERSION;
use super::{with_progress, CliError};

#[derive(Debug, clap::Args)]
pub struct ReportArgs {
    /// Folder with manifest.json and the DEMs (e.g. ../shared/dem).
    dem_dir: PathBuf,
    /// Peer results CSV (default: DEM_DIR/../peers/results/dev_codecs.csv).
    #[arg(long)]
    peers: Option<PathBuf>,
    /// Only these DEMs (comma-separated names).
    #[arg(long, value_delimiter = ',')]
    only: Vec<String>,
    /// Timed repetitions per DEM (the median is reported).
    #[arg(long, default_value_t = 3)]
    runs: usize,
    /// Print one JSON object on stdout instead of Markdown tables.
    #[arg(long, conflicts_with = "readme")]
    json: bool,
    /// Also write the tables into this file between `<!-- report:begin -->` and
    /// `<!-- report:end -->` (the README's comparison section).
    #[arg(long, value_name = "FILE")]
    readme: Option<PathBuf>,
    /// Compare meshes instead: ours beside Martini and Delatin at their triangle counts,
    /// from the peers' dev_mesh.csv (default: DEM_DIR/../peers/results/dev_mesh.csv).
    #[arg(long, conflicts_with = "readme")]
    meshes: bool,
}

pub fn run(args: &ReportArgs) -> Result<(), CliError> {
    let to_cli = |e: report::ReportError| CliError::Usage(e.to_string());
    let datasets = report::load_manifest(&args.dem_dir).map_err(to_cli)?;
    if args.meshes {
        return meshes(args, &datasets);
    }
    let peers_path = args
        .peers
        .clone()
        .unwrap_or_else(|| args.dem_dir.join("../peers/results/dev_codecs.csv"));
    let peers = report::load_peers(&peers_path).map_err(to_cli)?;
    let mut results: Vec<DemResult> = Vec::new();
    for dataset in datasets
        .iter()
        .filter(|d| args.only.is_empty() || args.only.contains(&d.name))
    {
        let result = with_progress(&format!("measuring {}", dataset.name), || {
            report::measure(dataset, args.runs, &peers)
        });
        results.push(result.map_err(to_cli)?);
    }
    if args.json {
        let value = serde_json::json!({
            "schema_version": SCHEMA_VERSION,
            "command": "report",
            "dems": results,
        });
        println!("{value}");
    } else {
        let tables = report::markdown(&results, &peers);
        print!("{tables}");
        if let Some(path) = &args.readme {
            splice_into(path, &tables)?;
        }
    }
    Ok(())
}

/// Replaces what lies between the report markers of `path` with `tables`.
/// `report --meshes`.
fn meshes(args: &ReportArgs, datasets: &[report::Dataset]) -> Result<(), CliError> {
    let to_cli = |e: report::ReportError| CliError::Usage(e.to_string());
    let path = args
        .peers
        .clone()
        .unwrap_or_else(|| args.dem_dir.join("../peers/results/dev_mesh.csv"));
    let peers = report::load_mesh_peers(&path).map_err(to_cli)?;
    let mut rows = Vec::new();
    for dataset in datasets
        .iter()
        .filter(|d| args.only.is_empty() || args.only.contains(&d.name))
    {
        let found = with_progress(&format!("meshing {}", dataset.name), || {
            report::compare_meshes(dataset, &peers)
        });
        rows.extend(found.map_err(to_cli)?);
    }
    if args.json {
        let value = serde_json::json!({
            "schema_version": SCHEMA_VERSION,
            "command": "report",
            "meshes": rows,
        });
        println!("{value}");
    } else {
        print!("{}", report::mesh_markdown(&rows));
    }
    Ok(())
}

fn splice_into(path: &std::path::Path, tables: &str) -> Result<(), CliError> {
    const BEGIN: &str = "<!-- report:begin -->";
    const END: &str = "<!-- report:end -->";
    let text = std::fs::read_to_string(path)
        .map_err(|e| CliError::Input(path.to_path_buf(), e.to_string()))?;
    let (Some(begin), Some(end)) = (text.find(BEGIN), text.find(END)) else {
        return Err(CliError::Usage(format!(
            "{} has no {BEGIN} ... {END} section",
            path.display()
        )));
    };
    if end < begin {
        return Err(CliError::Usage(format!(
            "{}: {END} comes before {BEGIN}",
            path.display()
        )));
    }
    let updated = format!("{}{BEGIN}\n{tables}{}", &text[..begin], &text[end..]);
    super::coding::write_output(path, updated.as_bytes())
}
