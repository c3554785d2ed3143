"""wavemesh against rasterio reading the same GeoTIFF: transform, CRS, nodata and
bit-exact lossless samples, on generated files always and on the shared DEMs when they
are beside the repository (skipped with a visible reason otherwise)."""

import math

import numpy as np
import pytest
import rasterio
from affine import Affine
from conftest import DTYPES, shared_dem_sources, shared_dem_tifs, terrain, write_geotiff

import wavemesh

UTM = Affine(10.0, 0.0, 500000.0, 0.0, -10.0, 5000000.0)


def same_nodata(ours, theirs):
    """Nodata values equal, NaN equal to NaN."""
    if ours is None or theirs is None:
        return ours is None and theirs is None
    return ours == theirs or (math.isnan(ours) and math.isnan(theirs))


def check_against_rasterio(tif, ezw_bytes):
    """`ezw_bytes` decodes to what rasterio reads from `tif`, georeferencing included."""
    with rasterio.open(tif) as src:
        expected = src.read(1, masked=True)
        transform, crs, nodata = src.transform, src.crs, src.nodata
    header = wavemesh.info(ezw_bytes)
    back = wavemesh.decode(ezw_bytes)
    assert back.dtype == expected.dtype and back.shape == expected.shape
    assert back.filled().tobytes() == expected.filled().tobytes(), "lossless is bit-exact"
    assert np.array_equal(np.ma.getmaskarray(back), np.ma.getmaskarray(expected))
    assert same_nodata(header["nodata"], nodata)
    if header["geotransform"] is not None:
        assert header["geotransform"] == transform.to_gdal()
    if crs is None:
        assert header["crs_epsg"] is None
    else:
        assert header["crs_epsg"] == crs.to_epsg()
        assert rasterio.crs.CRS.from_wkt(header["crs_wkt"]) == crs


@pytest.mark.parametrize("dtype", DTYPES)
def test_generated_geotiffs_through_encode_file_and_encode(tmp_path, dtype):
    dem = terrain(dtype)
    nodata = float("nan") if dtype == np.float32 else 7
    dem[3:9, 40:47] = nodata
    crs = 32632 if dtype != np.uint8 else 4326
    transform = UTM if crs == 32632 else Affine(0.001, 0, 11.0, 0, -0.001, 58.0)
    tif = write_geotiff(tmp_path / "dem.tif", dem, nodata=nodata, transform=transform, crs=f"EPSG:{crs}")
    wavemesh.encode_file(tif, tmp_path / "dem.ezw")
    check_against_rasterio(tif, (tmp_path / "dem.ezw").read_bytes())
    with rasterio.open(tif) as src:
        profile = src.profile
        from_array = wavemesh.encode(
            src.read(1), nodata=profile["nodata"], transform=profile["transform"], crs=profile["crs"]
        )
    check_against_rasterio(tif, from_array)


def test_a_crs_without_epsg_code_travels_as_wkt(tmp_path):
    dem = terrain(np.int16)
    custom = rasterio.crs.CRS.from_proj4("+proj=tmerc +lat_0=0 +lon_0=9.5 +k=0.9996 +x_0=500000 +datum=WGS84 +units=m")
    assert custom.to_epsg() is None
    header = wavemesh.info(wavemesh.encode(dem, transform=UTM, crs=custom))
    assert header["crs_epsg"] is None
    assert rasterio.crs.CRS.from_wkt(header["crs_wkt"]) == custom


@pytest.mark.filterwarnings("ignore::rasterio.errors.NotGeoreferencedWarning")
@pytest.mark.parametrize("name, tif", shared_dem_tifs())
def test_shared_dems_match_rasterio(tmp_path, name, tif):
    out = tmp_path / f"{name}.ezw"
    wavemesh.encode_file(tif, out)
    check_against_rasterio(tif, out.read_bytes())
    with rasterio.open(tif) as src:
        profile = src.profile
        from_array = wavemesh.encode(
            src.read(1), nodata=profile["nodata"], transform=profile["transform"], crs=profile["crs"]
        )
    check_against_rasterio(tif, from_array)


@pytest.mark.filterwarnings("ignore::rasterio.errors.NotGeoreferencedWarning")
@pytest.mark.parametrize("name, source, tif, terrain_rgb", shared_dem_sources())
def test_shared_dems_in_other_formats_match_their_geotiff(tmp_path, name, source, tif, terrain_rgb):
    """encode_file reads PNG, .hgt and Terrain-RGB as the CLI does: the samples rasterio
    reads from the same file (Terrain-RGB: from the DEM's GeoTIFF, the decoded heights),
    and an .hgt places itself as GDAL places it."""
    out = tmp_path / f"{name}.ezw"
    wavemesh.encode_file(source, out, terrain_rgb=terrain_rgb)
    with rasterio.open(tif if terrain_rgb else source) as src:
        expected = src.read(1)
    back = wavemesh.decode(out)
    assert back.dtype == expected.dtype
    assert back.filled().tobytes() == expected.tobytes()
    if source.suffix == ".hgt":
        check_against_rasterio(source, out.read_bytes())
