"""The Python package end to end: round trips for every sample type, voids, prefixes,
error bounds, the header, meshes and errors."""

import numpy as np
import pytest

import wavemesh

DTYPES = [np.uint8, np.uint16, np.int16, np.int32, np.float32]


def terrain(dtype, shape=(67, 91), seed=0):
    """A smooth random surface in the range of `dtype`."""
    rng = np.random.default_rng(seed)
    y, x = np.mgrid[0 : shape[0], 0 : shape[1]]
    surface = 100 + 60 * np.sin(x / 9.0) * np.cos(y / 13.0) + rng.normal(0, 2, shape)
    if np.issubdtype(dtype, np.floating):
        return (surface * 1.37).astype(dtype)
    return np.clip(np.round(surface), 0, 255).astype(dtype)


@pytest.mark.parametrize("dtype", DTYPES)
def test_lossless_round_trip_is_bit_exact(dtype):
    dem = terrain(dtype)
    back = wavemesh.decode(wavemesh.encode(dem))
    assert back.dtype == dem.dtype and back.shape == dem.shape
    assert not np.ma.is_masked(back)
    assert back.filled().tobytes() == dem.tobytes()


def test_any_strides_and_order():
    dem = terrain(np.int16, (80, 120))
    for view in [np.asfortranarray(dem), dem[::2, 1::3], dem.T]:
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
    ends = [p["payload_end_byte"] for p in header["passes"]]
    assert ends == sorted(ends) and header["file_bytes"] == len(data)


def test_mesh_is_valid_and_follows_the_tolerance():
    dem = terrain(np.int16, (65, 65))
    data = wavemesh.encode(dem)
    counts = []
    for tolerance in [8.0, 2.0, 0.0]:
        vertices, triangles = wavemesh.mesh(data, mesh_error=tolerance)
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


def test_files_round_trip(tmp_path):
    dem = terrain(np.int32)
    np.save(tmp_path / "dem.npy", dem)
    written = wavemesh.encode_file(tmp_path / "dem.npy", tmp_path / "dem.ezw")
    assert written == (tmp_path / "dem.ezw").stat().st_size
    assert np.array_equal(wavemesh.decode(tmp_path / "dem.ezw").filled(), dem)
