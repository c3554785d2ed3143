"""The Python package end to end on generated arrays: round trips for every sample type,
voids, prefixes, error bounds, the header, meshes, tables and errors."""

import numpy as np
import pytest
from affine import Affine
from conftest import DTYPES, terrain, write_geotiff

import wavemesh


@pytest.mark.parametrize("dtype", DTYPES)
def test_lossless_round_trip_is_bit_exact(dtype):
    dem = terrain(dtype)
    back = wavemesh.decode(wavemesh.encode(dem))
    assert back.dtype == dem.dtype and back.shape == dem.shape
    assert not np.ma.is_masked(back)
    assert back.filled().tobytes() == dem.tobytes()


def test_any_strides_and_order():
    dem = terrain(np.int16, (80, 120))
    big_endian = dem.astype(">i2")
    for view in [np.asfortranarray(dem), dem[::2, 1::3], dem.T, dem[::-1, ::-1], big_endian]:
        back = wavemesh.decode(wavemesh.encode(view))
        assert np.array_equal(back.filled(), view)


def test_nan_and_nodata_voids_come_back_masked():
    dem = terrain(np.float32)
    dem[10:20, 30:50] = np.nan
    back = wavemesh.decode(wavemesh.encode(dem, nodata=float("nan")))
    assert np.array_equal(back.mask, np.isnan(dem))
    valid = ~np.isnan(dem)
    assert back.data[valid].tobytes() == dem[valid].tobytes()

    ints = terrain(np.int16)
    ints[5, 5] = -32768
    back = wavemesh.decode(wavemesh.encode(ints, nodata=-32768))
    assert back.mask[5, 5] and back.mask.sum() == 1

    masked = np.ma.MaskedArray(terrain(np.uint16), mask=np.zeros((67, 91), bool))
    masked.mask[0, :] = True
    back = wavemesh.decode(wavemesh.encode(masked))
    assert np.array_equal(back.mask, masked.mask)
    assert np.array_equal(back.compressed(), masked.compressed())


def test_prefixes_decode_and_improve():
    dem = terrain(np.int16, (128, 128))
    data = wavemesh.encode(dem)
    errors = []
    for fraction in [0.05, 0.2, 0.5, 1.0]:
        back = wavemesh.decode(data, nbytes=int(len(data) * fraction))
        errors.append(float(np.sqrt(np.mean((back.filled().astype(float) - dem) ** 2))))
    assert errors == sorted(errors, reverse=True)
    assert errors[-1] == 0.0
    lossy = wavemesh.encode(dem, bpp=1.0)
    assert len(lossy) == 128 * 128 // 8
    assert wavemesh.decode(lossy, bpp=0.5).shape == dem.shape


@pytest.mark.parametrize("dtype", [np.int16, np.float32])
def test_max_error_holds_at_every_sample(dtype):
    dem = terrain(dtype)
    back = wavemesh.decode(wavemesh.encode(dem, max_error=2.0))
    assert np.abs(back.filled().astype(float) - dem.astype(float)).max() <= 2.0


def test_info_reports_the_header_and_ladder():
    dem = terrain(np.int16)
    data = wavemesh.encode(dem, transform=(500000.0, 10.0, 0.0, 5000000.0, 0.0, -10.0))
    header = wavemesh.info(data)
    assert (header["width"], header["height"]) == (91, 67)
    assert header["sample_type"] == "i16" and header["mode"] == "lossless"
    assert list(header["geotransform"]) == [500000.0, 10.0, 0.0, 5000000.0, 0.0, -10.0]
    ends = [p["end_byte"] for p in header["passes"]]
    assert ends == sorted(ends) and ends[-1] <= header["file_bytes"] == len(data)
    psnrs = [p["estimated_psnr_db"] for p in header["passes"]]
    assert psnrs == sorted(psnrs) and header["valid_samples"] == 91 * 67
    # The ladder's estimate is the encoder's (in coefficients): near the real error.
    middle = header["passes"][len(ends) // 2]
    back = wavemesh.decode(data, nbytes=middle["end_byte"]).filled().astype(float)
    rmse = float(np.sqrt(np.mean((back - dem) ** 2)))
    assert rmse == pytest.approx(middle["estimated_rmse"], rel=0.25)


def test_mesh_is_valid_and_follows_the_tolerance():
    dem = terrain(np.int16, (65, 65))
    data = wavemesh.encode(dem)
    counts = []
    for tolerance in [8.0, 2.0, 0.0]:
        vertices, triangles = wavemesh.mesh(data, mesh_error=tolerance, xy="pixel")
        assert vertices.shape[1] == 3 and triangles.shape[1] == 3
        assert triangles.dtype == np.uint32 and triangles.max() < len(vertices)
        a, b, c = (vertices[triangles[:, k], :2] for k in range(3))
        cross = (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0])
        assert (cross > 0).all(), "counter-clockwise in the (column, row) frame"
        cols, rows = vertices[:, 0].astype(int), vertices[:, 1].astype(int)
        assert np.array_equal(vertices[:, 2], dem[rows, cols])
        counts.append(len(triangles))
    assert counts == sorted(counts) and counts[-1] > counts[0]
    _, budget = wavemesh.mesh(data, triangles=500)
    assert len(budget) <= 500


def test_bad_arguments_and_damaged_data_raise():
    with pytest.raises(ValueError):
        wavemesh.encode(np.zeros((4, 4), np.float64))
    with pytest.raises(ValueError):
        wavemesh.encode(np.zeros((4, 4, 2), np.int16))
    with pytest.raises(ValueError):
        wavemesh.encode(terrain(np.int16), bpp=0)
    with pytest.raises(ValueError):
        wavemesh.encode(terrain(np.int16), wavelet="97")
    with pytest.raises(wavemesh.CodecError):
        wavemesh.decode(b"this is not an ezw stream")
    with pytest.raises(wavemesh.CodecError):
        wavemesh.encode(np.array([[1.0, np.inf]], np.float32))
    with pytest.raises(ValueError, match="int64"):
        wavemesh.encode(np.array([[1, 2], [3, 4]]))
    with pytest.raises(ValueError, match="empty"):
        wavemesh.encode(np.zeros((0, 5), np.int16))
    data = wavemesh.encode(terrain(np.uint8))
    for call, kwargs in [(wavemesh.decode, dict(nbytes=-1)), (wavemesh.decode, dict(max_memory=-5)),
                         (wavemesh.mesh, dict(triangles=-3)), (wavemesh.mesh, dict(xy="feet")),
                         (wavemesh.mesh, dict(triangles=9, mesh_error=1.0)),
                         (wavemesh.decode, dict(bpp=1.0, nbytes=10))]:
        with pytest.raises(ValueError):
            call(data, **kwargs)
    with pytest.raises(wavemesh.CodecError, match="nothing to mesh"):
        wavemesh.mesh(wavemesh.encode(np.zeros((1, 9), np.int16)))
    with pytest.raises(wavemesh.CodecError, match="max_memory"):
        wavemesh.decode(data, max_memory=10)


def test_unaligned_arrays_and_nodata_outside_the_type():
    raw = np.frombuffer(bytes(1) + terrain(np.int16, (8, 8)).tobytes(), np.int16, offset=1)
    unaligned = raw.reshape(8, 8)
    assert not unaligned.flags.aligned
    assert wavemesh.decode(wavemesh.encode(unaligned)).filled().tobytes() == unaligned.tobytes()
    dem = terrain(np.uint8)
    back = wavemesh.decode(wavemesh.encode(dem, nodata=-9999))
    assert not back.mask.any() and np.array_equal(back.data, dem)


def test_encode_file_reads_geotiffs_and_writes_atomically(tmp_path):
    dem = terrain(np.int32)
    transform = (300000.0, 5.0, 0.0, 4000000.0, 0.0, -5.0)
    tif = write_geotiff(tmp_path / "dem.tif", dem, nodata=-9999, transform=Affine.from_gdal(*transform))
    written = wavemesh.encode_file(tif, tmp_path / "dem.ezw")
    assert written == (tmp_path / "dem.ezw").stat().st_size
    back = wavemesh.decode(tmp_path / "dem.ezw")
    assert np.array_equal(back.filled(), dem) and back.fill_value == -9999
    assert wavemesh.info(tmp_path / "dem.ezw")["geotransform"] == transform
    assert sorted(p.name for p in tmp_path.iterdir()) == ["dem.ezw", "dem.tif"]
    with pytest.raises(ValueError, match="overwrite the input"):
        wavemesh.encode_file(tif, tif)
    with pytest.raises(FileNotFoundError, match="missing.tif"):
        wavemesh.encode_file(tmp_path / "missing.tif", tmp_path / "x.ezw")
    (tmp_path / "junk.tif").write_bytes(b"not a tiff at all")
    with pytest.raises(wavemesh.CodecError, match="junk.tif"):
        wavemesh.encode_file(tmp_path / "junk.tif", tmp_path / "x.ezw")
    with pytest.raises(wavemesh.CodecError, match="max_samples"):
        wavemesh.encode_file(tif, tmp_path / "x.ezw", max_samples=100)
    assert not (tmp_path / "x.ezw").exists()


def test_damage_warns_or_raises_with_strict():
    dem = terrain(np.int16, (128, 128))
    data = bytearray(wavemesh.encode(dem))
    header = wavemesh.info(bytes(data))
    data[header["passes"][-1]["end_byte"] - 10] ^= 0xFF
    with pytest.warns(RuntimeWarning, match="damaged at byte"):
        back = wavemesh.decode(bytes(data))
    assert back.shape == dem.shape
    with pytest.raises(wavemesh.CodecError, match="damaged"):
        wavemesh.decode(bytes(data), strict=True)
    with pytest.raises(wavemesh.CodecError, match="magic"):
        wavemesh.info(b"GIF89a and so on")


def test_georeferencing_arguments():
    dem = terrain(np.int16)
    gdal = (500000.0, 10.0, 0.0, 5000000.0, 0.0, -10.0)
    for crs in [32632, "EPSG:32632", "epsg:32632"]:
        header = wavemesh.info(wavemesh.encode(dem, transform=gdal, crs=crs))
        assert header["crs_epsg"] == 32632 and header["geotransform"] == gdal
        assert "UTM zone 32N" in header["crs_wkt"]
    local = 'LOCAL_CS["site grid",UNIT["metre",1]]'
    header = wavemesh.info(wavemesh.encode(dem, transform=gdal, crs=local))
    assert header["crs_epsg"] is None and header["crs_wkt"] == local
    class NewCrs:
        """A CRS whose EPSG code is newer than wavemesh's tables."""

        def to_epsg(self):
            return 99999

        def to_wkt(self):
            return local

    header = wavemesh.info(wavemesh.encode(dem, transform=gdal, crs=NewCrs()))
    assert header["crs_epsg"] is None and header["crs_wkt"] == local
    bare = wavemesh.info(wavemesh.encode(dem))
    assert bare["geotransform"] is None and bare["crs_epsg"] is None
    identity = wavemesh.encode(dem, transform=Affine.identity())
    assert wavemesh.info(identity)["geotransform"] is None
    assert len(identity) == bare["file_bytes"]
    for bad in [dict(crs=4326), dict(transform=gdal, crs=99999), dict(transform=gdal, crs="x"),
                dict(transform=gdal[:5]), dict(transform=gdal, crs=object())]:
        with pytest.raises(ValueError):
            wavemesh.encode(dem, **bad)


def test_table_rows_and_data_frame():
    dem = terrain(np.int16, (65, 65))
    rows = wavemesh.table(dem, thresholds=[64, 8, 1], runs=1)
    assert [r["threshold"] for r in rows] == [64.0, 8.0, 1.0]
    triangles = [r["triangles"] for r in rows]
    assert triangles == sorted(triangles) and triangles[0] < triangles[-1]
    assert all(r["mesh_compared_samples"] > 0 for r in rows)
    by_rate = wavemesh.table(dem, bpp=[0.5, 2.0], wavelet="97", runs=1)
    assert [round(r["bpp"], 2) for r in by_rate] == [0.5, 2.0]
    frame = wavemesh.table(dem, thresholds=[64, 8], runs=1, as_frame=True)
    assert list(frame["triangles"]) == triangles[:2] and "mesh_psnr_db" in frame.columns
    every_pass = wavemesh.table(dem, runs=1)
    assert len(every_pass) == len(wavemesh.info(wavemesh.encode(dem))["passes"])
    with pytest.raises(ValueError):
        wavemesh.table(dem, thresholds=[1], bpp=[1.0])
    with pytest.raises(ValueError):
        wavemesh.table(dem, wavelet="97")


def test_the_gil_is_released_while_coding():
    """A Python thread runs while another encodes: with the GIL held for the whole
    encode, the main thread could not wake from its short sleep before the encode ends."""
    import threading
    import time

    dem = terrain(np.float32, (512, 512))
    times = {}

    def encode():
        times["start"] = time.perf_counter()
        wavemesh.encode(dem)
        times["end"] = time.perf_counter()

    worker = threading.Thread(target=encode)
    worker.start()
    while "start" not in times:
        time.sleep(0.001)
    time.sleep(0.01)
    woke = time.perf_counter()
    worker.join()
    assert woke < times["start"] + 0.5 * (times["end"] - times["start"])


def test_tiled_arrays_windows_and_threads():
    dem = terrain(np.dtype("int16"), (200, 300))
    one = wavemesh.encode(dem, tile=64, threads=1)
    assert wavemesh.encode(dem, tile=64, threads=2) == one
    tiles = wavemesh.info(one)["tiles"]
    # 300 = 5 tiles of 60; 200 = 4 tiles of 50.
    assert (tiles["tile_width"], tiles["tile_height"], tiles["count"]) == (60, 50, 20)
    assert wavemesh.info(wavemesh.encode(dem, tile=0))["tiles"] is None
    assert np.array_equal(wavemesh.decode(one).filled(), dem)
    part = wavemesh.decode(one, window=(70, 30, 100, 60))
    assert np.array_equal(part.filled(), dem[30:90, 70:170])
    coarse = wavemesh.decode(one, nbytes=len(one) // 4)
    assert np.abs(coarse.astype(float) - dem).mean() > 0
    with pytest.raises(ValueError):
        wavemesh.decode(one, window=(250, 0, 100, 10))
    with pytest.raises(ValueError):
        wavemesh.decode(one, window=(0, 0, 10))
