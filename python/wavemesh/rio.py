"""``.ezw`` files with rasterio-style profiles.

:func:`write` takes an array and a profile as rasterio gives them (``src.profile``:
``transform``, ``crs``, ``nodata``, ``dtype``, ``count``...); :func:`read` returns the
decoded array and a profile with a rasterio ``Affine`` transform and ``CRS``, so code
written for rasterio reads ``.ezw`` files the same way. Needs rasterio.

>>> import numpy as np, rasterio, wavemesh.rio
>>> from affine import Affine
>>> dem = np.full((32, 32), 100, np.int16)
>>> profile = {"transform": Affine(30.0, 0, 500000.0, 0, -30.0, 5000000.0),
...            "crs": rasterio.crs.CRS.from_epsg(32632), "nodata": -32768}
>>> import tempfile, os; path = os.path.join(tempfile.mkdtemp(), "dem.ezw")
>>> _ = wavemesh.rio.write(path, dem, profile)
>>> array, back = wavemesh.rio.read(path)
>>> back["crs"].to_epsg(), back["transform"].a, back["nodata"], back["dtype"]
(32632, 30.0, -32768.0, 'int16')
"""

from __future__ import annotations

from typing import Any, Optional, Tuple

import numpy as np

import wavemesh

__all__ = ["write", "read"]

#: Profile keys that describe a GeoTIFF's storage and mean nothing to a ``.ezw`` file.
IGNORED_KEYS = ("driver", "compress", "tiled", "blockxsize", "blockysize", "interleave")


def _single_band(array: Any, profile: dict) -> Any:
    """``array`` as one 2-D band: ``(1, rows, columns)`` arrays are squeezed; the
    profile's ``count``, ``width`` and ``height``, when given, must agree."""
    if np.ndim(array) == 3 and np.shape(array)[0] == 1:
        array = array[0]
    if profile.get("count", 1) != 1 or np.ndim(array) != 2:
        raise ValueError(
            f"a .ezw file holds one band: got {np.ndim(array)}-D data with count "
            f"{profile.get('count', 1)}"
        )
    rows, columns = np.shape(array)
    if profile.get("width", columns) != columns or profile.get("height", rows) != rows:
        raise ValueError(
            f"the profile says {profile.get('width')} x {profile.get('height')}, "
            f"the array is {columns} x {rows}"
        )
    return array


def _as_profile_dtype(array: Any, dtype: Optional[str]) -> Any:
    """``array`` in the profile's ``dtype``, when the cast changes no value."""
    if dtype is None or np.dtype(dtype) == np.asarray(array).dtype:
        return array
    cast = np.asarray(array).astype(dtype)
    same = cast == array
    if np.issubdtype(cast.dtype, np.floating):
        same |= np.isnan(cast) & np.isnan(np.asarray(array, dtype=np.float64))
    if not np.all(same):
        raise ValueError(
            f"the array's {np.asarray(array).dtype} values do not all fit the profile's "
            f"dtype {dtype}"
        )
    return cast


def write(path: Any, array: Any, profile: Optional[dict] = None, **options: Any) -> int:
    """Encodes one band to a ``.ezw`` file (written atomically); returns its bytes.

    ``array`` is 2-D or ``(1, rows, columns)``, optionally a ``numpy.ma`` array.
    ``profile`` is a rasterio-style dict: ``transform`` (``Affine`` or GDAL 6-tuple),
    ``crs``, ``nodata`` and ``dtype`` (the array is cast to it when no value changes)
    are used; storage keys such as ``driver`` and ``compress`` are ignored. ``options``
    are :func:`wavemesh.encode`'s (``bpp``, ``max_error``, ``precision``, ``wavelet``).
    """
    profile = dict(profile or {})
    array = _as_profile_dtype(_single_band(array, profile), profile.get("dtype"))
    data = wavemesh.encode(
        array,
        nodata=profile.get("nodata"),
        transform=profile.get("transform"),
        crs=profile.get("crs"),
        **options,
    )
    wavemesh._write_atomic(path, data)
    return len(data)


def read(
    path: Any, *, bpp: Optional[float] = None, nbytes: Optional[int] = None
) -> Tuple["np.ma.MaskedArray", dict]:
    """Decodes a ``.ezw`` file: ``(array, profile)``.

    ``array`` is the 2-D masked array :func:`wavemesh.decode` returns (``bpp`` /
    ``nbytes`` decode a prefix). ``profile`` has ``driver`` (``"EZW"``), ``dtype``,
    ``width``, ``height``, ``count`` (1), ``nodata``, ``transform`` (an ``Affine``; the
    identity when the file has none, as rasterio gives) and ``crs`` (a rasterio ``CRS``
    or ``None``).
    """
    try:
        from affine import Affine
        from rasterio.crs import CRS
    except ImportError:
        raise ImportError("wavemesh.rio needs rasterio: pip install rasterio") from None
    data = wavemesh._bytes_of(path)
    array = wavemesh.decode(data, bpp=bpp, nbytes=nbytes)
    header = wavemesh.info(data)
    geotransform = header["geotransform"]
    if header["crs_epsg"] is not None:
        crs = CRS.from_epsg(header["crs_epsg"])
    elif header["crs_wkt"] is not None:
        crs = CRS.from_wkt(header["crs_wkt"])
    else:
        crs = None
    profile = {
        "driver": "EZW",
        "dtype": array.dtype.name,
        "width": header["width"],
        "height": header["height"],
        "count": 1,
        "nodata": header["nodata"],
        "transform": Affine.from_gdal(*geotransform) if geotransform else Affine.identity(),
        "crs": crs,
    }
    return array, profile
