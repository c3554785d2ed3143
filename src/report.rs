//! The side-by-side benchmark: wavemesh on every DEM of a manifest folder, beside what the
//! peer tools reached on the same DEMs (`../shared/peers/results/dev_codecs.csv`).
//!
//! Measures, per DEM: lossless bpp (checked bit-exact), PSNR of prefixes of one 9/7 stream
//! (`--bpp 2`) and of the lossless stream (13/11 or 5/3) at 0.1–2 bpp, bpp at max error 0.5/1/2 m
//! (checked sample by sample), single-thread encode/decode throughput (median of runs) and
//! decode heap peak. [`markdown`] renders the tables the README shows.

use std::path::{Path, PathBuf};
use std::time::Instant;

use serde::{Deserialize, Serialize};
use wavemesh_codec::{
    decode, encode, CodecError, DecodeOptions, EncodeOptions, Quality, Raster, Samples, Wavelet,
};

use crate::dem::{read_dem, ReadOptions};
use crate::metrics::{bits_per_sample, compare};

/// Rates (bpp) at which prefixes are decoded.
pub const RATES: [f64; 5] = [0.1, 0.25, 0.5, 1.0, 2.0];
/// Error bounds, in metres.
pub const BOUNDS_M: [f64; 3] = [0.5, 1.0, 2.0];

/// What can stop a report.
#[derive(Debug, thiserror::Error)]
pub enum ReportError {
    /// A file could not be read or parsed.
    #[error("{path}: {message}")]
    Input {
        /// The file.
        path: PathBuf,
        /// What went wrong.
        message: String,
    },
    /// The codec failed or broke a guarantee.
    #[error("{dem}: {message}")]
    Codec {
        /// The DEM.
        dem: String,
        /// What went wrong.
        message: String,
    },
}

/// One DEM of a manifest.
#[derive(Debug, Clone)]
pub struct Dataset {
    /// Short name.
    pub name: String,
    /// Its GeoTIFF.
    pub tif: PathBuf,
    /// Metres per data unit.
    pub metres_per_unit: f64,
}

#[derive(Deserialize)]
struct Manifest {
    datasets: Vec<ManifestEntry>,
}

#[derive(Deserialize)]
struct ManifestEntry {
    name: String,
    files: ManifestFiles,
    value_to_metres: Option<ValueToMetres>,
}

#[derive(Deserialize)]
struct ManifestFiles {
    tif: String,
}

#[derive(Deserialize)]
struct ValueToMetres {
    scale: f64,
}

/// Reads `manifest.json` of a DEM folder.
pub fn load_manifest(dir: &Path) -> Result<Vec<Dataset>, ReportError> {
    let path = dir.join("manifest.json");
    let text = std::fs::read_to_string(&path).map_err(|e| ReportError::Input {
        path: path.clone(),
        message: e.to_string(),
    })?;
    let manifest: Manifest = serde_json::from_str(&text).map_err(|e| ReportError::Input {
        path: path.clone(),
        message: e.to_string(),
    })?;
    Ok(manifest
        .datasets
        .into_iter()
        .map(|d| Dataset {
            tif: dir.join(d.files.tif),
            metres_per_unit: d.value_to_metres.map_or(1.0, |v| v.scale),
            name: d.name,
        })
        .collect())
}

/// One row of the peers' results CSV (the columns used here).
#[derive(Debug, Clone, Deserialize)]
pub struct PeerRow {
    /// DEM name.
    pub dem: String,
    /// Codec run name (`opj-97`, `lerc`, `jpegxl`, ...).
    pub codec: String,
    /// `lossless`, `rate` or `errbound`.
    pub mode: String,
    /// Requested rate.
    pub target_bpp: Option<f64>,
    /// Requested bound, metres.
    pub max_error_target: Option<f64>,
    /// Achieved bpp.
    pub bpp: Option<f64>,
    /// Achieved PSNR.
    pub psnr_db: Option<f64>,
    /// Achieved RMSE (0 = exact).
    pub rmse: Option<f64>,
    /// Whether the bound was met.
    pub meets_bound: Option<String>,
    /// Encode throughput, Msamples/s.
    pub enc_msps: Option<f64>,
    /// Decode throughput, Msamples/s.
    pub dec_msps: Option<f64>,
}

/// Reads the peers' CSV.
pub fn load_peers(path: &Path) -> Result<Vec<PeerRow>, ReportError> {
    let err = |message: String| ReportError::Input {
        path: path.to_path_buf(),
        message,
    };
    let mut reader = csv::Reader::from_path(path).map_err(|e| err(e.to_string()))?;
    reader
        .deserialize()
        .collect::<Result<Vec<PeerRow>, _>>()
        .map_err(|e| err(e.to_string()))
}

/// PSNR of prefixes at one rate.
#[derive(Debug, Clone, Serialize)]
pub struct RateResult {
    /// Target rate.
    pub bpp: f64,
    /// Rate the 9/7 prefix was decoded at: the rate OpenJPEG 9/7 actually reached for
    /// this target when that is higher (its files include a nodata mask), else the target.
    pub bpp_97: f64,
    /// PSNR of the 9/7 stream's prefix.
    pub psnr_97: f64,
    /// Rate the lossless stream's prefix was decoded at (OpenJPEG 5/3's actual rate when
    /// known).
    pub bpp_53: f64,
    /// PSNR of the lossless stream's prefix.
    pub psnr_53: f64,
}

/// One error-bounded encode.
#[derive(Debug, Clone, Serialize)]
pub struct BoundResult {
    /// Bound in metres.
    pub max_error_m: f64,
    /// Achieved bpp.
    pub bpp: f64,
    /// Achieved max error in metres.
    pub achieved_m: f64,
}

/// Everything measured on one DEM.
#[derive(Debug, Clone, Serialize)]
pub struct DemResult {
    /// Name.
    pub name: String,
    /// Columns.
    pub width: usize,
    /// Rows.
    pub height: usize,
    /// Sample type.
    pub sample_type: String,
    /// Lossless bpp (bit-exact, checked).
    pub lossless_bpp: f64,
    /// Lossless encode throughput, Msamples/s (median of runs).
    pub encode_msps: f64,
    /// Lossless decode throughput, Msamples/s (median of runs).
    pub decode_msps: f64,
    /// Decode heap peak divided by the decoded raster's size.
    pub decode_peak_ratio: f64,
    /// 9/7 at 1 bpp: encode throughput, Msamples/s (median of runs).
    pub lossy_encode_msps: f64,
    /// 9/7 at 1 bpp: decode throughput, Msamples/s (median of runs).
    pub lossy_decode_msps: f64,
    /// Prefix PSNRs.
    pub rates: Vec<RateResult>,
    /// Error-bounded sizes.
    pub bounds: Vec<BoundResult>,
    /// Lossless ideal code length (bits) with every context, each removed, and none.
    pub contexts: Vec<(String, f64)>,
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// Runs the whole measurement on one DEM, `runs` timed repetitions. Prefixes are decoded
/// at the rates the peers actually reached (from `peers`), so each row compares equal
/// file sizes.
pub fn measure(
    dataset: &Dataset,
    runs: usize,
    peers: &[PeerRow],
) -> Result<DemResult, ReportError> {
    let mut raster =
        read_dem(&dataset.tif, &ReadOptions::default()).map_err(|e| ReportError::Input {
            path: dataset.tif.clone(),
            message: e.to_string(),
        })?;
    // Like for like: the peers' files carry no free text items (licence, source).
    raster.metadata.items.clear();
    let codec_err = |message: String| ReportError::Codec {
        dem: dataset.name.clone(),
        message,
    };
    let (w, h) = (raster.width, raster.height);
    let samples = (w * h) as f64;
    let distortion = |other: &Raster| compare(&raster, other).map_err(|e| codec_err(e.to_string()));

    // Lossless, timed on one thread (the speed table's heading; tiled DEMs would
    // otherwise code their tiles on every core).
    let lossless_options = EncodeOptions::new(Quality::Lossless, None).with_threads(1);
    let one_thread = DecodeOptions::default().with_threads(1);
    let mut encode_times = Vec::new();
    let mut decode_times = Vec::new();
    let mut lossless = None;
    let mut peak_ratio = 0.0;
    for _ in 0..runs.max(1) {
        let start = Instant::now();
        let encoded = encode(&raster, &lossless_options).map_err(|e| codec_err(e.to_string()))?;
        encode_times.push(start.elapsed().as_secs_f64());
        let start = Instant::now();
        let (decoded, peak) = crate::memory::measure(|| decode(&encoded.bytes, &one_thread));
        decode_times.push(start.elapsed().as_secs_f64());
        let decoded = decoded.map_err(|e| codec_err(e.to_string()))?;
        if !distortion(&decoded.raster)?.identical {
            return Err(codec_err("lossless round trip is not bit-exact".into()));
        }
        peak_ratio = peak as f64 / (samples * raster.sample_type().bytes() as f64);
        lossless = Some(encoded);
    }
    let lossless = lossless.expect("at least one run");

    // 9/7 at 1 bpp, timed (OpenJPEG's -r 16 runs are the comparison).
    let mut at_one =
        EncodeOptions::new(Quality::Lossless, Some((samples / 8.0) as u64)).with_threads(1);
    at_one = at_one.with_wavelet(Wavelet::Cdf97);
    let mut lossy_encode_times = Vec::new();
    let mut lossy_decode_times = Vec::new();
    for _ in 0..runs.max(1) {
        let start = Instant::now();
        let encoded = encode(&raster, &at_one).map_err(|e| codec_err(e.to_string()))?;
        lossy_encode_times.push(start.elapsed().as_secs_f64());
        let start = Instant::now();
        decode(&encoded.bytes, &one_thread).map_err(|e| codec_err(e.to_string()))?;
        lossy_decode_times.push(start.elapsed().as_secs_f64());
    }

    // Prefixes of one 9/7 stream at 2 bpp and of the lossless stream.
    let mut options = EncodeOptions::new(Quality::Lossless, Some((2.0 * samples / 8.0) as u64));
    options = options.with_wavelet(Wavelet::Cdf97);
    let lossy = encode(&raster, &options).map_err(|e| codec_err(e.to_string()))?;
    let mut rates = Vec::new();
    for &bpp in &RATES {
        // A peer that needed more bytes than the target (a nodata mask) is matched at its
        // real rate; one that saturated below it (nothing left to code) is not.
        let peer_bpp = |codec: &str| {
            peer_rows(peers, &dataset.name)
                .find(|r| r.codec == codec && r.mode == "rate" && r.target_bpp == Some(bpp))
                .and_then(|r| r.bpp)
                .map_or(bpp, |actual| actual.max(bpp))
        };
        let psnr = |bytes: &[u8], rate: f64| -> Result<f64, ReportError> {
            let prefix =
                DecodeOptions::default().with_max_bytes(Some((rate * samples / 8.0) as u64));
            let decoded = decode(bytes, &prefix).map_err(|e| codec_err(e.to_string()))?;
            Ok(distortion(&decoded.raster)?.psnr_db)
        };
        let (bpp_97, bpp_53) = (peer_bpp("opj-97"), peer_bpp("opj-53"));
        rates.push(RateResult {
            bpp,
            bpp_97,
            psnr_97: psnr(&lossy.bytes, bpp_97)?,
            bpp_53,
            psnr_53: psnr(&lossless.bytes, bpp_53)?,
        });
    }

    // Error bounds in metres, converted to data units.
    let mut bounds = Vec::new();
    for &e_m in &BOUNDS_M {
        let e = e_m / dataset.metres_per_unit;
        let encoded = encode(&raster, &EncodeOptions::new(Quality::MaxError(e), None))
            .map_err(|e| codec_err(e.to_string()))?;
        let decoded = decode(&encoded.bytes, &DecodeOptions::default())
            .map_err(|e| codec_err(e.to_string()))?;
        let d = distortion(&decoded.raster)?;
        if d.max_error > e {
            return Err(codec_err(format!(
                "max error {} exceeds the bound {e}",
                d.max_error
            )));
        }
        bounds.push(BoundResult {
            max_error_m: e_m,
            bpp: bits_per_sample(encoded.bytes.len() as u64, w, h),
            achieved_m: d.max_error * dataset.metres_per_unit,
        });
    }

    let contexts = wavemesh_codec::research::context_ablation(&raster)
        .map_err(|e| codec_err(e.to_string()))?
        .into_iter()
        .map(|(name, bits)| (name.to_string(), bits))
        .collect();

    Ok(DemResult {
        contexts,
        name: dataset.name.clone(),
        width: w,
        height: h,
        sample_type: raster.sample_type().name().to_string(),
        lossless_bpp: bits_per_sample(lossless.bytes.len() as u64, w, h),
        encode_msps: samples / median(encode_times) / 1e6,
        decode_msps: samples / median(decode_times) / 1e6,
        decode_peak_ratio: peak_ratio,
        lossy_encode_msps: samples / median(lossy_encode_times) / 1e6,
        lossy_decode_msps: samples / median(lossy_decode_times) / 1e6,
        rates,
        bounds,
    })
}

fn peer_rows<'a>(peers: &'a [PeerRow], dem: &'a str) -> impl Iterator<Item = &'a PeerRow> + 'a {
    peers.iter().filter(move |r| r.dem == dem)
}

/// Smallest exact lossless bpp among the peer runs whose codec name satisfies `pick`.
fn best_lossless(
    peers: &[PeerRow],
    dem: &str,
    pick: impl Fn(&str) -> bool,
) -> Option<(f64, String)> {
    peer_rows(peers, dem)
        .filter(|r| {
            (r.mode == "lossless" || r.max_error_target == Some(0.0))
                && r.rmse == Some(0.0)
                && pick(&r.codec)
        })
        .filter_map(|r| r.bpp.map(|b| (b, r.codec.clone())))
        .min_by(|a, b| a.0.total_cmp(&b.0))
}

fn rate_psnr(peers: &[PeerRow], dem: &str, codec: &str, bpp: f64) -> Option<f64> {
    peer_rows(peers, dem)
        .find(|r| r.codec == codec && r.mode == "rate" && r.target_bpp == Some(bpp))
        .and_then(|r| r.psnr_db)
}

/// Smallest bpp meeting `e_m` among peer runs whose codec satisfies `pick`.
fn best_bounded(
    peers: &[PeerRow],
    dem: &str,
    e_m: f64,
    pick: impl Fn(&str) -> bool,
) -> Option<(f64, String)> {
    peer_rows(peers, dem)
        .filter(|r| {
            r.mode == "errbound"
                && r.max_error_target == Some(e_m)
                && r.meets_bound.as_deref() == Some("True")
                && pick(&r.codec)
        })
        .filter_map(|r| r.bpp.map(|b| (b, r.codec.clone())))
        .min_by(|a, b| a.0.total_cmp(&b.0))
}

fn fmt_opt(v: Option<f64>, digits: usize) -> String {
    v.map_or("n/a".into(), |x| {
        if x.is_finite() {
            format!("{x:.digits$}")
        } else {
            "∞".into()
        }
    })
}

/// The README tables: wavemesh beside the peers, DEM by DEM.
pub fn markdown(results: &[DemResult], peers: &[PeerRow]) -> String {
    let mut out = String::new();
    let gis = |c: &str| {
        c.starts_with("opj-53")
            || c.starts_with("grk-53")
            || c.starts_with("JP2OpenJPEG-53")
            || c.starts_with("lerc")
            || c.starts_with("LERC")
            || c == "PNG16"
            || c.contains("+pred")
    };
    out.push_str("### Lossless (bpp, bit-exact)\n\n");
    out.push_str("| DEM | wavemesh | J2K 5/3 | LERC | PNG16 | GeoTIFF+pred | best of those | vs best | JPEG-LS | JPEG XL | gap to JPEG XL |\n");
    out.push_str("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n");
    for r in results {
        let j2k = best_lossless(peers, &r.name, |c| c == "opj-53");
        let lerc = best_lossless(peers, &r.name, |c| {
            c.starts_with("lerc") || c.starts_with("LERC")
        });
        let png = best_lossless(peers, &r.name, |c| c == "PNG16");
        let gtiff = best_lossless(peers, &r.name, |c| c.contains("+pred"));
        let best = best_lossless(peers, &r.name, gis);
        let jls = best_lossless(peers, &r.name, |c| c == "jpegls");
        let jxl = best_lossless(peers, &r.name, |c| c == "jpegxl");
        let rel = |p: &Option<(f64, String)>| {
            p.as_ref().map_or("n/a".into(), |(b, _)| {
                format!("{:+.1} %", (r.lossless_bpp / b - 1.0) * 100.0)
            })
        };
        out.push_str(&format!(
            "| {} | **{:.3}** | {} | {} | {} | {} | {} | {} | {} | {} | {} |\n",
            r.name,
            r.lossless_bpp,
            fmt_opt(j2k.as_ref().map(|p| p.0), 3),
            fmt_opt(lerc.as_ref().map(|p| p.0), 3),
            fmt_opt(png.as_ref().map(|p| p.0), 3),
            fmt_opt(gtiff.as_ref().map(|p| p.0), 3),
            best.as_ref()
                .map_or("n/a".into(), |(b, c)| format!("{b:.3} ({c})")),
            rel(&best),
            fmt_opt(jls.as_ref().map(|p| p.0), 3),
            fmt_opt(jxl.as_ref().map(|p| p.0), 3),
            rel(&jxl),
        ));
    }
    out.push_str("\n### Rate–distortion (PSNR dB)\n\n");
    out.push_str("wavemesh decodes prefixes of one 9/7 stream (`--bpp 2`) and of the lossless stream (13/11 or 5/3, as the encoder chose), each cut at the target rate, or at the rate OpenJPEG actually reached when that is higher (its files carry a nodata mask; shown as \"at\"). Where OpenJPEG saturates below the target (nothing left to code on narrow-range data), wavemesh still decodes at the target. OpenJPEG and SPERR encode each rate separately.\n\n");
    out.push_str("| DEM | bpp | wavemesh 9/7 | OpenJPEG 9/7 | Δ | SPERR | wavemesh lossless stream | OpenJPEG 5/3 | Δ |\n");
    out.push_str("|---|---:|---:|---:|---:|---:|---:|---:|---:|\n");
    for r in results {
        for rate in &r.rates {
            let opj97 = rate_psnr(peers, &r.name, "opj-97", rate.bpp);
            let opj53 = rate_psnr(peers, &r.name, "opj-53", rate.bpp);
            let sperr = rate_psnr(peers, &r.name, "sperr_bpp", rate.bpp);
            let delta = |ours: f64, theirs: Option<f64>| match theirs {
                Some(t) if ours.is_finite() && t.is_finite() => format!("{:+.2}", ours - t),
                Some(t) if !t.is_finite() && !ours.is_finite() => "=".into(),
                Some(_) if !ours.is_finite() => "+∞ (exact)".into(),
                _ => "n/a".into(),
            };
            let opj97_bpp = peer_rows(peers, &r.name)
                .find(|p| p.codec == "opj-97" && p.mode == "rate" && p.target_bpp == Some(rate.bpp))
                .and_then(|p| p.bpp);
            let shown = match opj97_bpp {
                Some(b) if b < rate.bpp * 0.95 => format!("{} (J2K stops at {b:.3})", rate.bpp),
                _ if rate.bpp_97 > rate.bpp * 1.05 => {
                    format!("{} (at {:.3})", rate.bpp, rate.bpp_97)
                }
                _ => rate.bpp.to_string(),
            };
            out.push_str(&format!(
                "| {} | {} | {} | {} | {} | {} | {} | {} | {} |\n",
                r.name,
                shown,
                fmt_opt(Some(rate.psnr_97), 2),
                fmt_opt(opj97, 2),
                delta(rate.psnr_97, opj97),
                fmt_opt(sperr, 2),
                fmt_opt(Some(rate.psnr_53), 2),
                fmt_opt(opj53, 2),
                delta(rate.psnr_53, opj53),
            ));
        }
    }
    out.push_str(
        "\n### Max error (bpp of the smallest stream keeping every sample within E metres)\n\n",
    );
    out.push_str(
        "| DEM | E (m) | wavemesh | achieved (m) | LERC | best other | wavemesh / best |\n",
    );
    out.push_str("|---|---:|---:|---:|---:|---:|---:|\n");
    for r in results {
        for b in &r.bounds {
            let lerc = best_bounded(peers, &r.name, b.max_error_m, |c| {
                c == "lerc" || c.starts_with("LERC")
            });
            let best = best_bounded(peers, &r.name, b.max_error_m, |_| true);
            out.push_str(&format!(
                "| {} | {} | **{:.3}** | {} | {} | {} | {} |\n",
                r.name,
                b.max_error_m,
                b.bpp,
                fmt_opt(Some(b.achieved_m), 3),
                fmt_opt(lerc.as_ref().map(|p| p.0), 3),
                best.as_ref()
                    .map_or("n/a".into(), |(v, c)| format!("{v:.3} ({c})")),
                best.as_ref()
                    .map_or("n/a".into(), |(v, _)| format!("{:.2}×", b.bpp / v)),
            ));
        }
    }
    out.push_str(
        "\n### What each context buys (lossless payload, % more bits when it is removed)\n\n",
    );
    if let Some(first) = results.first() {
        out.push_str("| DEM | bits/sample, all contexts |");
        for (name, _) in first.contexts.iter().skip(1) {
            out.push_str(&format!(" {name} |"));
        }
        out.push_str("\n|---|---:|");
        for _ in first.contexts.iter().skip(1) {
            out.push_str("---:|");
        }
        out.push('\n');
    }
    for r in results {
        let all = r.contexts.first().map_or(0.0, |c| c.1);
        out.push_str(&format!(
            "| {} | {:.3} |",
            r.name,
            all / (r.width * r.height) as f64
        ));
        for (_, bits) in r.contexts.iter().skip(1) {
            out.push_str(&format!(" {:+.1} % |", (bits / all - 1.0) * 100.0));
        }
        out.push('\n');
    }
    out.push_str(
        "\n### Speed and memory (one thread; OpenJPEG timed as whole processes, so its small-DEM figures are lower bounds)\n\n",
    );
    out.push_str("| DEM | samples | lossless encode MS/s | OpenJPEG 5/3 | lossless decode MS/s | OpenJPEG 5/3 | 9/7 1 bpp encode MS/s | OpenJPEG 9/7 | 9/7 1 bpp decode MS/s | OpenJPEG 9/7 | decode heap peak / raster |\n");
    out.push_str("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n");
    for r in results {
        let opj53 = peer_rows(peers, &r.name).find(|p| p.codec == "opj-53" && p.mode == "lossless");
        let opj97 = peer_rows(peers, &r.name)
            .find(|p| p.codec == "opj-97" && p.mode == "rate" && p.target_bpp == Some(1.0));
        out.push_str(&format!(
            "| {} | {}x{} | {:.1} | {} | {:.1} | {} | {:.1} | {} | {:.1} | {} | {:.2}× |\n",
            r.name,
            r.width,
            r.height,
            r.encode_msps,
            fmt_opt(opj53.and_then(|p| p.enc_msps), 1),
            r.decode_msps,
            fmt_opt(opj53.and_then(|p| p.dec_msps), 1),
            r.lossy_encode_msps,
            fmt_opt(opj97.and_then(|p| p.enc_msps), 1),
            r.lossy_decode_msps,
            fmt_opt(opj97.and_then(|p| p.dec_msps), 1),
            r.decode_peak_ratio,
        ));
    }
    out
}

/// One row of the peers' mesher results (`dev_mesh.csv`, the columns used here).
#[derive(Debug, Clone, Deserialize)]
pub struct MeshPeerRow {
    /// DEM name.
    pub dem: String,
    /// `cropN r0=R c0=C`, `full WxH` or a padded region (not compared).
    pub region: String,
    /// `martini`, `delatin` or `meshopt`.
    pub mesher: String,
    /// The mesher's max-error parameter, data units.
    pub param_max_error_data: f64,
    /// Triangles of its mesh.
    pub triangles: usize,
    /// RMSE over the region, data units.
    pub rmse: f64,
    /// True max error over the region, data units.
    pub maxerr: f64,
}

/// Reads the peers' mesher results.
pub fn load_mesh_peers(path: &Path) -> Result<Vec<MeshPeerRow>, ReportError> {
    let mut reader = csv::Reader::from_path(path).map_err(|e| ReportError::Input {
        path: path.to_path_buf(),
        message: e.to_string(),
    })?;
    reader
        .deserialize()
        .collect::<Result<Vec<MeshPeerRow>, _>>()
        .map_err(|e| ReportError::Input {
            path: path.to_path_buf(),
            message: e.to_string(),
        })
}

/// Our mesh beside one peer mesh: same region, same triangle budget.
#[derive(Debug, Clone, Serialize)]
pub struct MeshComparison {
    /// DEM name.
    pub dem: String,
    /// The region (as the peers' CSV names it).
    pub region: String,
    /// The peer.
    pub mesher: String,
    /// The peer's max-error parameter.
    pub peer_parameter: f64,
    /// The peer's triangles (our budget).
    pub peer_triangles: usize,
    /// The peer's RMSE, data units.
    pub peer_rmse: f64,
    /// The peer's true max error, data units.
    pub peer_max_error: f64,
    /// Our best mesh within that budget: searched over height tolerances, or the one at
    /// the peer's parameter when that fits the budget and misses less.
    pub ours_triangles: usize,
    /// Its RMSE, data units.
    pub ours_rmse: f64,
    /// Its max error, data units.
    pub ours_max_error: f64,
    /// Our zerotree-threshold mesh within the same budget: triangles and RMSE.
    pub zerotree_triangles: usize,
    /// Its RMSE.
    pub zerotree_rmse: f64,
    /// Our mesh at the peer's parameter as a tolerance (`--mesh-error E`): triangles.
    pub ours_at_parameter_triangles: usize,
    /// Its max error (never above the parameter).
    pub ours_at_parameter_max_error: f64,
    /// Our QEM mesh (`mesh --method qem`) within the peer's triangles: triangles.
    pub qem_triangles: usize,
    /// Its RMSE, data units.
    pub qem_rmse: f64,
    /// Its max error, data units.
    pub qem_max_error: f64,
}

/// The `(x0, y0, width, height)` a peer region names on a `w × h` DEM, `None` for padded
/// regions.
fn parse_region(region: &str, w: usize, h: usize) -> Option<(usize, usize, usize, usize)> {
    if region.starts_with("full") {
        return Some((0, 0, w, h));
    }
    let rest = region.strip_prefix("crop")?;
    let mut parts = rest.split_whitespace();
    let size: usize = parts.next()?.parse().ok()?;
    let r0: usize = parts.next()?.strip_prefix("r0=")?.parse().ok()?;
    let c0: usize = parts.next()?.strip_prefix("c0=")?.parse().ok()?;
    (c0 + size <= w && r0 + size <= h).then_some((c0, r0, size, size))
}

/// Measures our meshes against every Martini and Delatin row of `peers` for `dataset`
/// on the same regions (lossless stream, so the mesh is built from the original heights).
pub fn compare_meshes(
    dataset: &Dataset,
    peers: &[MeshPeerRow],
) -> Result<Vec<MeshComparison>, ReportError> {
    use crate::lod::Surface;
    use crate::mesh::cells::SplitRule;
    use crate::mesh::rasterise::mesh_error;
    use crate::mesh::{MeshTarget, Mesher};
    let codec = |e: CodecError| ReportError::Codec {
        dem: dataset.name.clone(),
        message: e.to_string(),
    };
    let raster =
        read_dem(&dataset.tif, &ReadOptions::default()).map_err(|e| ReportError::Input {
            path: dataset.tif.clone(),
            message: e.to_string(),
        })?;
    let mut out = Vec::new();
    let rows: Vec<&MeshPeerRow> = peers
        .iter()
        .filter(|p| p.dem == dataset.name && (p.mesher == "martini" || p.mesher == "delatin"))
        .collect();
    let mut regions: Vec<&str> = rows.iter().map(|p| p.region.as_str()).collect();
    regions.sort();
    regions.dedup();
    for region in regions {
        let Some((x0, y0, w, h)) = parse_region(region, raster.width, raster.height) else {
            continue;
        };
        let crop = crop_raster(&raster, x0, y0, w, h).map_err(codec)?;
        let encoded = encode(&crop, &EncodeOptions::zerotree_mesh()).map_err(codec)?;
        let options = DecodeOptions::default().with_significance_map(true);
        let decoded = decode(&encoded.bytes, &options).map_err(codec)?;
        let surface = Surface::of(&decoded.raster);
        let map = decoded.significance.as_ref().expect("asked for");
        let mut mesher = Mesher::new(map, surface.heights(), &surface.valid);
        let measure = |mesh: &crate::mesh::GridMesh| {
            mesh_error(mesh, &surface.heights, &surface.heights, &surface.valid)
        };
        let budgets: Vec<usize> = rows
            .iter()
            .filter(|p| p.region == region)
            .map(|p| p.triangles)
            .collect();
        let mut qem =
            crate::mesh::qem::qem_meshes_within(w, h, &surface.heights, &surface.valid, &budgets)
                .map_err(|e| ReportError::Codec {
                    dem: dataset.name.clone(),
                    message: e.to_string(),
                })?
                .into_iter();
        for peer in rows.iter().filter(|p| p.region == region) {
            let qem_mesh = qem.next().expect("one QEM mesh per peer row");
            let q = measure(&qem_mesh);
            let budget = mesher.build(
                MeshTarget::TrianglesByTolerance(peer.triangles),
                SplitRule::Zerotree,
                None,
            );
            let zerotree = mesher.build(
                MeshTarget::Triangles(peer.triangles),
                SplitRule::Zerotree,
                None,
            );
            let at_parameter = mesher.build(
                MeshTarget::Tolerance(peer.param_max_error_data),
                SplitRule::Zerotree,
                None,
            );
            let (mut b, z, a) = (
                measure(&budget.mesh),
                measure(&zerotree.mesh),
                measure(&at_parameter.mesh),
            );
            // The tolerance search cannot always land on the budget exactly; the mesh at
            // the peer's own parameter is a mesh within the budget too when it fits.
            let mut ours_triangles = budget.mesh.triangles.len();
            if at_parameter.mesh.triangles.len() <= peer.triangles && a.rmse < b.rmse {
                b = a;
                ours_triangles = at_parameter.mesh.triangles.len();
            }
            out.push(MeshComparison {
                dem: dataset.name.clone(),
                region: region.to_string(),
                mesher: peer.mesher.clone(),
                peer_parameter: peer.param_max_error_data,
                peer_triangles: peer.triangles,
                peer_rmse: peer.rmse,
                peer_max_error: peer.maxerr,
                ours_triangles,
                ours_rmse: b.rmse,
                ours_max_error: b.max_error,
                zerotree_triangles: zerotree.mesh.triangles.len(),
                zerotree_rmse: z.rmse,
                ours_at_parameter_triangles: at_parameter.mesh.triangles.len(),
                ours_at_parameter_max_error: a.max_error,
                qem_triangles: qem_mesh.triangles.len(),
                qem_rmse: q.rmse,
                qem_max_error: q.max_error,
            });
        }
    }
    Ok(out)
}

/// The `w × h` window at `(x0, y0)` of `raster`.
fn crop_raster(
    raster: &Raster,
    x0: usize,
    y0: usize,
    w: usize,
    h: usize,
) -> Result<Raster, CodecError> {
    let values: Vec<f64> = (0..h)
        .flat_map(|y| (0..w).map(move |x| (y0 + y) * raster.width + x0 + x))
        .map(|i| raster.samples.get_f64(i))
        .collect();
    let mut crop = Raster::new(
        w,
        h,
        Samples::from_f64(raster.samples.sample_type(), &values),
    )?;
    crop.nodata = raster.nodata;
    Ok(crop)
}

/// The mesh comparison as a Markdown table.
pub fn mesh_markdown(rows: &[MeshComparison]) -> String {
    let mut s = String::from(
        "| DEM | region | peer | peer E | peer tris | peer RMSE | peer max err | ours tris | ours RMSE | RMSE ours/peer | ours max err | zerotree tris | zerotree RMSE | ours tris at E (max err) | qem tris | qem RMSE | RMSE qem/peer |\n|---|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n",
    );
    for r in rows {
        s.push_str(&format!(
            "| {} | {} | {} | {} | {} | {:.4} | {:.3} | {} | {:.4} | {:.3} | {:.3} | {} | {:.4} | {} ({:.3}) | {} | {:.4} | {:.3} |\n",
            r.dem,
            r.region,
            r.mesher,
            r.peer_parameter,
            r.peer_triangles,
            r.peer_rmse,
            r.peer_max_error,
            r.ours_triangles,
            r.ours_rmse,
            r.ours_rmse / r.peer_rmse,
            r.ours_max_error,
            r.zerotree_triangles,
            r.zerotree_rmse,
            r.ours_at_parameter_triangles,
            r.ours_at_parameter_max_error,
            r.qem_triangles,
            r.qem_rmse,
            r.qem_rmse / r.peer_rmse
        ));
    }
    s
}
