"""Shared helpers: generated terrains and GeoTIFFs, the shared DEMs (skipped with a
visible reason when absent) and the command-line binary."""

import json
from pathlib import Path

import numpy as np
import pytest

REPO = Path(__file__).resolve().parents[2]
SHARED_DEMS = REPO.parent / "shared" / "dem"
CLI = REPO / "target" / "release" / "wavemesh"

DTYPES = [np.uint8, np.uint16, np.int16, np.int32, np.float32]


def terrain(dtype, shape=(67, 91), seed=0):
    """A smooth random surface in the range of `dtype`."""
    rng = np.random.default_rng(seed)
    y, x = np.mgrid[0 : shape[0], 0 : shape[1]]
    surface = 100 + 60 * np.sin(x / 9.0) * np.cos(y / 13.0) + rng.normal(0, 2, shape)
    if np.issubdtype(dtype, np.floating):
        return (surface * 1.37).astype(dtype)
    return np.clip(np.round(surface), 0, 255).astype(dtype)


def write_geotiff(path, dem, *, nodata=None, transform=None, crs=None):
    """Writes `dem` as a one-band GeoTIFF with rasterio (an independent writer)."""
    import rasterio

    profile = dict(
        driver="GTiff",
        width=dem.shape[1],
        height=dem.shape[0],
        count=1,
        dtype=dem.dtype.name,
        nodata=nodata,
        compress="deflate",
    )
    if transform is not None:
        profile["transform"] = transform
    if crs is not None:
        profile["crs"] = crs
    with rasterio.open(path, "w", **profile) as dst:
        dst.write(dem, 1)
    return path


def shared_dem_tifs():
    """`(name, GeoTIFF path)` of every shared DEM, or one entry that skips when the
    shared DEMs are absent."""
    manifest = SHARED_DEMS / "manifest.json"
    if not manifest.is_file():
        reason = f"SKIPPED: {SHARED_DEMS} not found (the real DEMs are not beside the repository)"
        return [pytest.param(None, None, marks=pytest.mark.skip(reason=reason))]
    datasets = json.loads(manifest.read_text())["datasets"]
    return [
        pytest.param(d["name"], SHARED_DEMS / d["files"]["tif"], id=d["name"])
        for d in datasets
        if d["files"].get("tif")
    ]


def shared_dem_sources():
    """`(name, source, tif, terrain_rgb)` for every shared DEM's non-GeoTIFF file (a
    grayscale PNG, an SRTM .hgt, a Terrain-RGB PNG) beside its GeoTIFF, or one entry
    that skips when the shared DEMs are absent."""
    manifest = SHARED_DEMS / "manifest.json"
    if not manifest.is_file():
        reason = f"SKIPPED: {SHARED_DEMS} not found (the real DEMs are not beside the repository)"
        return [pytest.param(None, None, None, None, marks=pytest.mark.skip(reason=reason))]
    cases = []
    for d in json.loads(manifest.read_text())["datasets"]:
        files, tif = d["files"], SHARED_DEMS / d["files"]["tif"]
        sources = [files["png"]] if files.get("png") else []
        sources += [f for f in files.get("original", []) if f.endswith(".hgt")]
        if d["name"].endswith("terrainrgb"):
            sources += files["original"]
        for source in sources:
            terrain_rgb = d["name"].endswith("terrainrgb")
            cases.append(pytest.param(d["name"], SHARED_DEMS / source, tif, terrain_rgb, id=source))
    return cases


@pytest.fixture
def cli():
    """The command-line binary `cargo test --release` built, or a visible skip."""
    if not CLI.is_file():
        pytest.skip(f"SKIPPED: {CLI} not built (scripts/test builds it with cargo test)")
    return CLI
