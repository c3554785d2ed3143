#!/usr/bin/env python3
"""Build the sample DEMs in this folder from the Jacksboro fault DEM shipped with matplotlib.

Outputs (next to this script):
  jacksboro_fault.tif  int16 GeoTIFF, 403 x 344, EPSG:4326, no nodata
  jacksboro_voids.tif  the same heights with synthetic SRTM-style voids (-32768, about 3 %
                       of cells, in blobs on steep slopes), GDAL_NODATA "-32768"

Needs python3 and numpy. The DEM is read from matplotlib's sample data: the script downloads
the matplotlib 3.11.2 wheel from PyPI with `pip download --no-deps` into a temporary folder
and reads matplotlib/mpl-data/sample_data/jacksboro_fault_dem.npz from it. Pass
`--npz PATH` to use an already extracted copy of that .npz instead.

The GeoTIFF writer is hand-written (struct packing, little-endian, uncompressed strips) so
the output depends only on this script and the input array. Running it twice gives
byte-identical files.
"""

import argparse
import io
import os
import struct
import subprocess
import sys
import tempfile
import zipfile

import numpy as np

MPL_VERSION = "3.11.2"
NPZ_IN_WHEEL = "matplotlib/mpl-data/sample_data/jacksboro_fault_dem.npz"
HERE = os.path.dirname(os.path.abspath(__file__))

NODATA = -32768
VOID_FRACTION = 0.03

# GeoKeys for EPSG:4326: GTModelType = geographic (2), GTRasterType = pixel-is-area (1),
# GeographicType = 4326.
GEOKEYS_4326 = [1, 1, 0, 3, 1024, 0, 1, 2, 1025, 0, 1, 1, 2048, 0, 1, 4326]

# TIFF field types: code -> (struct format, size in bytes).
SHORT, LONG, ASCII, DOUBLE = 3, 4, 2, 12
TYPE_INFO = {SHORT: ("H", 2), LONG: ("I", 4), ASCII: ("s", 1), DOUBLE: ("d", 8)}


def load_npz(npz_path):
    """The npz archive, from a file or from the matplotlib wheel on PyPI."""
    if npz_path:
        with open(npz_path, "rb") as f:
            return np.load(io.BytesIO(f.read()))
    with tempfile.TemporaryDirectory() as tmp:
        subprocess.run(
            [sys.executable, "-m", "pip", "download", "--quiet", "--no-deps",
             "--only-binary=:all:", f"matplotlib=={MPL_VERSION}", "-d", tmp],
            check=True,
        )
        wheels = sorted(f for f in os.listdir(tmp) if f.endswith(".whl"))
        if not wheels:
            sys.exit("pip download produced no matplotlib wheel")
        with zipfile.ZipFile(os.path.join(tmp, wheels[0])) as z:
            data = z.read(NPZ_IN_WHEEL)
    return np.load(io.BytesIO(data))


def geotransform(npz, width, height):
    """GDAL geotransform from the npz keys (row 0 = north; ymin/ymax are stored swapped)."""
    dx, dy = float(npz["dx"]), float(npz["dy"])
    xmin, xmax = float(npz["xmin"]), float(npz["xmax"])
    north = max(float(npz["ymin"]), float(npz["ymax"]))
    south = min(float(npz["ymin"]), float(npz["ymax"]))
    # xmin..xmax and south..north span whole cells: they are cell edges, not centres.
    assert abs((xmax - xmin) / dx - width) < 1e-6, "x extent does not match the width"
    assert abs((north - south) / dy - height) < 1e-6, "y extent does not match the height"
    return [xmin, dx, 0.0, north, 0.0, -dy]


class Lcg:
    """Tiny deterministic generator (64-bit LCG), independent of numpy's RNG versions."""

    def __init__(self, seed):
        self.state = seed

    def next(self):
        self.state = (self.state * 6364136223846793005 + 1442695040888963407) % 2**64
        return self.state >> 33

    def uniform(self):
        return self.next() / 2**31

    def below(self, n):
        return self.next() % n


def void_mask(elevation):
    """Blobs of missing cells on steep slopes, where SRTM has radar shadow and layover.

    Blob centres are drawn among the steepest 5 % of cells; each blob is a cluster of a
    few overlapping ellipses. Blobs are added until VOID_FRACTION of the cells is covered.
    """
    h, w = elevation.shape
    gy, gx = np.gradient(elevation.astype(np.float64))
    slope = np.hypot(gx, gy)
    steep = np.flatnonzero(slope >= np.quantile(slope, 0.95))
    rows, cols = np.mgrid[0:h, 0:w]
    mask = np.zeros((h, w), dtype=bool)
    rng = Lcg(20240611)
    target = VOID_FRACTION * h * w
    while mask.sum() < target:
        centre = int(steep[rng.below(len(steep))])
        cy, cx = divmod(centre, w)
        for _ in range(1 + rng.below(4)):
            oy = cy + int(rng.below(9)) - 4
            ox = cx + int(rng.below(9)) - 4
            ry = 1.5 + 4.0 * rng.uniform()
            rx = 1.5 + 4.0 * rng.uniform()
            mask |= ((rows - oy) / ry) ** 2 + ((cols - ox) / rx) ** 2 <= 1.0
    return mask


def pack(fmt, values):
    return struct.pack("<" + fmt * len(values), *values)


def write_geotiff(path, array, gt, geokeys, nodata=None, rows_per_strip=16):
    """Write a single-band int16 GeoTIFF: little-endian, uncompressed strips."""
    assert array.dtype == np.int16 and array.ndim == 2
    assert gt[2] == 0.0 and gt[4] == 0.0 and gt[5] < 0.0, "north-up only"
    height, width = array.shape
    data = array.astype("<i2")
    strips = [data[r:r + rows_per_strip].tobytes() for r in range(0, height, rows_per_strip)]

    def entries(strip_offsets):
        e = [
            (256, SHORT, [width]),                   # ImageWidth
            (257, SHORT, [height]),                  # ImageLength
            (258, SHORT, [16]),                      # BitsPerSample
            (259, SHORT, [1]),                       # Compression: none
            (262, SHORT, [1]),                       # Photometric: BlackIsZero
            (273, LONG, strip_offsets),              # StripOffsets
            (277, SHORT, [1]),                       # SamplesPerPixel
            (278, SHORT, [rows_per_strip]),          # RowsPerStrip
            (279, LONG, [len(s) for s in strips]),   # StripByteCounts
            (284, SHORT, [1]),                       # PlanarConfiguration: chunky
            (339, SHORT, [2]),                       # SampleFormat: signed integer
            (33550, DOUBLE, [gt[1], -gt[5], 0.0]),   # ModelPixelScale
            (33922, DOUBLE, [0.0, 0.0, 0.0, gt[0], gt[3], 0.0]),  # ModelTiepoint
            (34735, SHORT, geokeys),                 # GeoKeyDirectory
        ]
        if nodata is not None:
            e.append((42113, ASCII, str(nodata).encode("ascii") + b"\0"))  # GDAL_NODATA
        return e

    def layout(strip_offsets):
        """IFD bytes and the out-of-line values that follow it."""
        es = entries(strip_offsets)
        ifd_offset = 8
        extra_offset = ifd_offset + 2 + 12 * len(es) + 4
        ifd = struct.pack("<H", len(es))
        extra = b""
        for tag, typ, values in es:
            fmt, size = TYPE_INFO[typ]
            raw = values if typ == ASCII else pack(fmt, values)
            count = len(values)
            if len(raw) <= 4:
                ifd += struct.pack("<HHI", tag, typ, count) + raw.ljust(4, b"\0")
            else:
                ifd += struct.pack("<HHII", tag, typ, count, extra_offset + len(extra))
                extra += raw
                if len(extra) % 2:
                    extra += b"\0"
        ifd += struct.pack("<I", 0)  # no next IFD
        return ifd, extra, extra_offset + len(extra)

    _, _, data_start = layout([0] * len(strips))
    offsets, pos = [], data_start
    for s in strips:
        offsets.append(pos)
        pos += len(s)
    ifd, extra, check = layout(offsets)
    assert check == data_start
    with open(path, "wb") as f:
        f.write(b"II*\0" + struct.pack("<I", 8) + ifd + extra + b"".join(strips))


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--npz", help="use this jacksboro_fault_dem.npz instead of downloading")
    args = parser.parse_args()

    npz = load_npz(args.npz)
    elevation = np.asarray(npz["elevation"])
    assert elevation.dtype == np.int16 and elevation.shape == (344, 403), elevation.shape
    assert (elevation != NODATA).all()
    height, width = elevation.shape
    gt = geotransform(npz, width, height)

    clean = os.path.join(HERE, "jacksboro_fault.tif")
    write_geotiff(clean, elevation, gt, GEOKEYS_4326)

    mask = void_mask(elevation)
    voids = elevation.copy()
    voids[mask] = NODATA
    holed = os.path.join(HERE, "jacksboro_voids.tif")
    write_geotiff(holed, voids, gt, GEOKEYS_4326, nodata=NODATA)

    print(f"{clean}: {width} x {height} int16, {elevation.min()}..{elevation.max()} m")
    print(f"{holed}: {int(mask.sum())} void cells ({100 * mask.mean():.2f} %)")
    print(f"geotransform {gt}")


if __name__ == "__main__":
    main()
