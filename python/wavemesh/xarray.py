"""``.ezw`` files from and to rioxarray ``DataArray`` s.

:func:`to_ezw` encodes a 2-D (or one-band) DataArray with its transform, CRS and nodata
as rioxarray holds them; :func:`open_ezw` decodes a file to a ``(y, x)`` DataArray with
pixel-centre coordinates from the transform and the CRS and nodata written through
rioxarray, as ``rioxarray.open_rasterio`` gives a GeoTIFF. Needs xarray and rioxarray.

>>> import numpy as np, wavemesh.xarray, tempfile, os
>>> dem = np.arange(24 * 32, dtype=np.int16).reshape(24, 32)
>>> path = os.path.join(tempfile.mkdtemp(), "dem.ezw")
>>> import xarray, rioxarray
>>> da = xarray.DataArray(dem, dims=("y", "x")).rio.write_crs(4326)
>>> _ = wavemesh.xarray.to_ezw(da, path)
>>> back = wavemesh.xarray.open_ezw(path)
>>> back.rio.crs.to_epsg(), bool((back.values == dem).all())
(4326, True)
"""

from __future__ import annotations

from typing import Any, Optional

import numpy as np

import wavemesh

__all__ = ["to_ezw", "open_ezw"]


def _modules():
    """xarray, with rioxarray's ``.rio`` accessor registered."""
    try:
        import rioxarray  # noqa: F401  (registers the .rio accessor)
        import xarray
    except ImportError:
        raise ImportError(
            "wavemesh.xarray needs xarray and rioxarray: pip install rioxarray"
        ) from None
    return xarray


def _samples_of(da: Any) -> tuple:
    """The 2-D samples of ``da`` and its nodata value. A DataArray opened with
    ``masked=True`` (NaN voids, nodata in ``rio.encoded_nodata``) goes back to the type
    it was stored as when every value fits it."""
    if da.ndim == 3 and da.shape[0] == 1:
        da = da[0]
    if da.ndim != 2:
        raise ValueError(f"a .ezw file holds one band: got dims {da.dims}")
    values = da.values
    nodata = da.rio.nodata
    encoded = da.rio.encoded_nodata
    stored = da.encoding.get("rasterio_dtype") or da.encoding.get("dtype")
    if encoded is not None:
        nodata = encoded
        if np.issubdtype(values.dtype, np.floating):
            values = np.where(np.isnan(values), encoded, values)
        if stored is not None and np.dtype(stored) != values.dtype:
            cast = values.astype(stored)
            if np.array_equal(cast, values, equal_nan=True):
                values = cast
    return values, nodata


def to_ezw(da: Any, path: Any, **options: Any) -> int:
    """Encodes a rioxarray DataArray to a ``.ezw`` file (written atomically); returns
    its bytes.

    The transform (``da.rio.transform()``), CRS (``da.rio.crs``) and nodata
    (``da.rio.nodata``, or ``da.rio.encoded_nodata`` for NaN-masked data) go into the
    file. ``options`` are :func:`wavemesh.encode`'s (``bpp``, ``max_error``,
    ``precision``, ``wavelet``; ``nodata`` overrides the DataArray's).
    """
    _modules()
    values, nodata = _samples_of(da)
    options.setdefault("nodata", nodata)
    data = wavemesh.encode(values, transform=da.rio.transform(), crs=da.rio.crs, **options)
    wavemesh._write_atomic(path, data)
    return len(data)


def _coordinates(geotransform: Optional[tuple], width: int, height: int) -> dict:
    """Pixel-centre ``x`` and ``y`` coordinates of a north-up geotransform (pixel
    numbers without one; none for a rotated one, which only the transform can say)."""
    if geotransform is None:
        return {"x": np.arange(width) + 0.5, "y": np.arange(height) + 0.5}
    x0, dx, rx, y0, ry, dy = geotransform
    if rx != 0 or ry != 0:
        return {}
    return {"x": x0 + (np.arange(width) + 0.5) * dx, "y": y0 + (np.arange(height) + 0.5) * dy}


def open_ezw(
    path: Any,
    *,
    bpp: Optional[float] = None,
    nbytes: Optional[int] = None,
    masked: bool = False,
) -> Any:
    """Decodes a ``.ezw`` file to a ``(y, x)`` DataArray, as
    ``rioxarray.open_rasterio(...).squeeze("band")`` gives a GeoTIFF.

    Coordinates are pixel centres from the transform; ``rio.crs``, ``rio.transform()``
    and ``rio.nodata`` come from the file. ``masked=True`` gives float values with NaN
    at voids and the nodata value in ``rio.encoded_nodata`` (and the stored type in
    ``encoding["dtype"]``, so :func:`to_ezw` writes it back unchanged). ``bpp`` /
    ``nbytes`` decode a prefix.
    """
    xarray = _modules()
    data = wavemesh._bytes_of(path)
    decoded = wavemesh.decode(data, bpp=bpp, nbytes=nbytes)
    header = wavemesh.info(data)
    geotransform = header["geotransform"]
    nodata = header["nodata"]
    if masked:
        float_type = np.float32 if decoded.dtype == np.float32 else np.float64
        values = decoded.astype(float_type).filled(np.nan)
    else:
        values = decoded.data
    da = xarray.DataArray(
        values,
        dims=("y", "x"),
        coords=_coordinates(geotransform, header["width"], header["height"]),
    )
    if geotransform is not None:
        from affine import Affine

        da = da.rio.write_transform(Affine.from_gdal(*geotransform))
    crs = header["crs_epsg"] or header["crs_wkt"]
    if crs is not None:
        da = da.rio.write_crs(crs)
    if nodata is not None:
        da = da.rio.write_nodata(nodata, encoded=masked)
    if masked:
        da.encoding["dtype"] = str(decoded.dtype)
    return da
