"""The Python package and the command line agree: the same mesh (vertices and triangles
of `wavemesh decode --mesh m.obj`, in every frame) and the same table rows."""

import json
import subprocess

import numpy as np
import pytest
from affine import Affine
from conftest import terrain, write_geotiff

import wavemesh

GEOGRAPHIC = Affine(0.0005, 0.0, 11.0, 0.0, -0.0005, 57.5)


def read_obj(path):
    """Vertices (N × 3) and 0-based triangles (M × 3) of an OBJ file."""
    vertices, faces = [], []
    for line in path.read_text().splitlines():
        if line.startswith("v "):
            vertices.append([float(v) for v in line.split()[1:4]])
        elif line.startswith("f "):
            faces.append([int(v.split("/")[0]) - 1 for v in line.split()[1:4]])
    return np.array(vertices), np.array(faces, dtype=np.uint32)


@pytest.fixture
def geographic_ezw(tmp_path):
    """A lossless stream of a voided EPSG:4326 DEM, written as a file."""
    dem = terrain(np.int16, (97, 81))
    dem[40:45, 10:20] = -32768
    tif = write_geotiff(tmp_path / "dem.tif", dem, nodata=-32768, transform=GEOGRAPHIC, crs="EPSG:4326")
    wavemesh.encode_file(tif, tmp_path / "dem.ezw")
    return tmp_path / "dem.ezw"


@pytest.mark.parametrize("xy", ["geo", "degrees", "pixel"])
@pytest.mark.parametrize("options", [[], ["--mesh-error", "3"], ["--triangles", "400"]])
def test_mesh_equals_the_cli_obj(cli, tmp_path, geographic_ezw, xy, options):
    obj = tmp_path / "mesh.obj"
    subprocess.run(
        [cli, "decode", geographic_ezw, "-o", tmp_path / "out.tif", "--mesh", obj, "--xy", xy, *options],
        check=True,
        capture_output=True,
    )
    kwargs = {}
    if options:
        key = options[0].lstrip("-").replace("-", "_")
        kwargs[key] = float(options[1]) if key == "mesh_error" else int(options[1])
    vertices, triangles = wavemesh.mesh(geographic_ezw, xy=xy, **kwargs)
    expected_vertices, expected_triangles = read_obj(obj)
    assert np.array_equal(vertices, expected_vertices)
    assert np.array_equal(triangles, expected_triangles)


def test_table_rows_equal_the_cli(cli, tmp_path):
    dem = terrain(np.int16, (65, 65))
    tif = write_geotiff(tmp_path / "t.tif", dem, transform=GEOGRAPHIC, crs="EPSG:4326")
    run = subprocess.run(
        [cli, "table", tif, "--thresholds", "64,8,1", "--format", "json", "--runs", "1"],
        check=True,
        capture_output=True,
        text=True,
    )
    expected = json.loads(run.stdout)["rows"]
    from_file = wavemesh.table(tif, thresholds=[64, 8, 1], runs=1)
    # The array has no georeferencing: a shorter header, the same coefficients.
    from_array = wavemesh.table(dem, thresholds=[64, 8, 1], runs=1)
    same = ["plane", "triangles", "vertices", "image_rmse", "remaining_percent"]
    for file_row, array_row, cli_row in zip(from_file, from_array, expected, strict=True):
        for key in same + ["ezw_bytes", "bpp", "saving_ratio"]:
            assert file_row[key] == cli_row[key], key
        for key in same:
            assert array_row[key] == cli_row[key], key
        assert file_row["mesh_rmse"] == array_row["mesh_rmse"] == cli_row["mesh"]["rmse"]
        assert array_row["ezw_bytes"] < cli_row["ezw_bytes"]


@pytest.mark.parametrize("options", [[], ["--bpp", "0.5"], ["--max-error", "2"]])
def test_encode_file_writes_the_cli_bytes(cli, tmp_path, options):
    dem = terrain(np.int16, (97, 81))
    dem[40:45, 10:20] = -32768
    tif = write_geotiff(tmp_path / "dem.tif", dem, nodata=-32768, transform=GEOGRAPHIC, crs="EPSG:4326")
    subprocess.run([cli, "encode", tif, "-o", tmp_path / "cli.ezw", *options], check=True, capture_output=True)
    kwargs = {options[0].lstrip("-").replace("-", "_"): float(options[1])} if options else {}
    wavemesh.encode_file(tif, tmp_path / "py.ezw", **kwargs)
    assert (tmp_path / "py.ezw").read_bytes() == (tmp_path / "cli.ezw").read_bytes()
