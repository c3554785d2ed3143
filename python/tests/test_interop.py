"""wavemesh.rio (rasterio-style profiles) and wavemesh.xarray (rioxarray DataArrays),
checked against rasterio and rioxarray reading the same GeoTIFF."""

import numpy as np
import pytest
import rasterio
import rioxarray
from affine import Affine
from conftest import terrain, write_geotiff

import wavemesh
import wavemesh.rio
import wavemesh.xarray

UTM = Affine(10.0, 0.0, 500000.0, 0.0, -10.0, 5000000.0)


@pytest.fixture
def voided_tif(tmp_path):
    """A UTM int16 GeoTIFF with a block of nodata."""
    dem = terrain(np.int16)
    dem[10:14, 20:30] = -32768
    return write_geotiff(tmp_path / "dem.tif", dem, nodata=-32768, transform=UTM, crs="EPSG:32632")


def test_rio_profile_round_trip(tmp_path, voided_tif):
    with rasterio.open(voided_tif) as src:
        band, profile = src.read(), src.profile
    assert band.shape[0] == 1, "rasterio's (band, row, column) arrays are taken"
    written = wavemesh.rio.write(tmp_path / "dem.ezw", band, profile)
    assert written == (tmp_path / "dem.ezw").stat().st_size
    array, back = wavemesh.rio.read(tmp_path / "dem.ezw")
    for key in ["dtype", "width", "height", "count", "nodata", "transform", "crs"]:
        assert back[key] == profile[key], key
    assert array.filled().tobytes() == band[0].tobytes()
    assert np.array_equal(array.mask, band[0] == -32768)


def test_rio_refuses_what_a_file_cannot_hold(tmp_path):
    dem = terrain(np.int16)
    with pytest.raises(ValueError, match="one band"):
        wavemesh.rio.write(tmp_path / "x.ezw", np.stack([dem, dem]), {"count": 2})
    with pytest.raises(ValueError, match="profile says"):
        wavemesh.rio.write(tmp_path / "x.ezw", dem, {"width": 5})
    with pytest.raises(ValueError, match="do not all fit"):
        wavemesh.rio.write(tmp_path / "x.ezw", dem + 0.5, {"dtype": "int16"})
    wavemesh.rio.write(tmp_path / "x.ezw", dem.astype(np.float64), {"dtype": "int16"})
    array, profile = wavemesh.rio.read(tmp_path / "x.ezw")
    assert profile["dtype"] == "int16" and profile["crs"] is None
    assert profile["transform"] == Affine.identity() and np.array_equal(array, dem)


def test_xarray_round_trip_matches_rioxarray(tmp_path, voided_tif):
    source = rioxarray.open_rasterio(voided_tif).squeeze("band", drop=True)
    wavemesh.xarray.to_ezw(source, tmp_path / "dem.ezw")
    back = wavemesh.xarray.open_ezw(tmp_path / "dem.ezw")
    assert back.dims == ("y", "x") and back.dtype == source.dtype
    assert back.values.tobytes() == source.values.tobytes()
    np.testing.assert_array_equal(back.x.values, source.x.values)
    np.testing.assert_array_equal(back.y.values, source.y.values)
    assert back.rio.crs == source.rio.crs and back.rio.nodata == source.rio.nodata
    assert back.rio.transform() == source.rio.transform()


def test_xarray_masked_data_goes_back_to_its_type(tmp_path, voided_tif):
    masked = rioxarray.open_rasterio(voided_tif, masked=True)
    assert masked.dtype == np.float32 and masked.rio.encoded_nodata == -32768
    wavemesh.xarray.to_ezw(masked, tmp_path / "dem.ezw")
    header = wavemesh.info(tmp_path / "dem.ezw")
    assert header["sample_type"] == "i16" and header["nodata"] == -32768
    back = wavemesh.xarray.open_ezw(tmp_path / "dem.ezw", masked=True)
    assert back.rio.encoded_nodata == -32768
    np.testing.assert_array_equal(back.values, masked.squeeze("band", drop=True).values)
    wavemesh.xarray.to_ezw(back, tmp_path / "again.ezw")
    assert (tmp_path / "again.ezw").read_bytes() == (tmp_path / "dem.ezw").read_bytes()
