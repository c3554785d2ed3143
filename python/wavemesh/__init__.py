"""wavemesh: store, stream and mesh elevation models.

A DEM (a 2-D numpy array of uint8, uint16, int16, int32 or float32) goes in, an embedded
``.ezw`` stream comes out: a lifting wavelet transform (integer 5/3 lossless, CDF 9/7
lossy) feeding an EZW zerotree coder with context-modelled arithmetic coding. Any prefix
of the bytes decodes, so one file serves every bit rate, and the decoder's zerotree gives
a crack-free triangle mesh at any threshold, triangle budget or height tolerance.

>>> import numpy as np, wavemesh
>>> dem = (np.arange(64 * 48).reshape(48, 64) % 97).astype(np.int16)
>>> data = wavemesh.encode(dem)                      # lossless, bit-exact
>>> bool((wavemesh.decode(data) == dem).all())
True
>>> coarse = wavemesh.decode(data, bpp=0.5)          # a prefix: a coarser DEM
>>> vertices, triangles = wavemesh.mesh(data, mesh_error=2.0)

Errors: ``ValueError`` for bad arguments, :class:`CodecError` for data the codec cannot
decode or samples it cannot code. The GIL is released while coding and meshing.
"""

from __future__ import annotations

import os
from typing import Any, Optional, Sequence, Tuple, Union

import numpy as np

from . import _wavemesh
from ._wavemesh import CodecError

__all__ = ["CodecError", "encode", "encode_file", "decode", "info", "mesh"]

Source = Union[bytes, bytearray, memoryview, str, "os.PathLike[str]"]


def _bytes_of(data_or_path: Source) -> bytes:
    """The stream's bytes: given directly, or read from a path."""
    if isinstance(data_or_path, (bytes, bytearray, memoryview)):
        return bytes(data_or_path)
    with open(os.fspath(data_or_path), "rb") as f:
        return f.read()


def _geotransform(transform: Any) -> Optional[Tuple[float, ...]]:
    """A GDAL geotransform from a 6-sequence or a rasterio/affine ``Affine``."""
    if transform is None:
        return None
    if hasattr(transform, "to_gdal"):
        return tuple(float(v) for v in transform.to_gdal())
    values = tuple(float(v) for v in transform)
    if len(values) != 6:
        raise ValueError(f"transform must have 6 numbers (GDAL order), got {len(values)}")
    return values


def encode(
    array: Any,
    *,
    nodata: Optional[float] = None,
    bpp: Optional[float] = None,
    max_error: Optional[float] = None,
    precision: Optional[float] = None,
    wavelet: Optional[str] = None,
    transform: Any = None,
) -> bytes:
    """Encodes a 2-D array into ``.ezw`` bytes.

    Lossless (bit-exact) by default; ``bpp`` cuts a lossy 9/7 stream at that many bits
    per sample; ``max_error`` keeps every valid sample within that many data units;
    ``precision`` quantises floats to that step. A ``numpy.ma`` array's mask, ``nodata``
    and NaN (floats) mark voids. ``transform`` is a GDAL geotransform (6 numbers) or an
    ``Affine`` (rasterio).
    """
    if np.ma.isMaskedArray(array):
        array, nodata = _fill_masked(array, nodata)
    array = np.asarray(array)
    if array.ndim != 2:
        raise ValueError(f"expected a 2-D array, got {array.ndim} dimensions")
    return _wavemesh.encode(
        array,
        nodata=None if nodata is None else float(nodata),
        bpp=bpp,
        max_error=max_error,
        precision=precision,
        wavelet=wavelet,
        geotransform=_geotransform(transform),
    )


def _fill_masked(array: "np.ma.MaskedArray", nodata: Optional[float]):
    """A masked array as plain samples with its voids set to a nodata value."""
    if nodata is None:
        if np.issubdtype(array.dtype, np.floating):
            nodata = float("nan")
        else:
            info = np.iinfo(array.dtype)
            nodata = info.min if info.min < 0 else info.max
    return array.filled(nodata), nodata


def encode_file(path_in: Union[str, "os.PathLike[str]"], path_out, **options) -> int:
    """Encodes a ``.npy`` array file (or any array ``numpy.load`` reads) to ``path_out``;
    GeoTIFFs go through rasterio (see the README) or the ``wavemesh`` command line.
    Returns the bytes written."""
    data = encode(np.load(os.fspath(path_in)), **options)
    tmp = os.fspath(path_out) + ".wavemesh-tmp"
    with open(tmp, "wb") as f:
        f.write(data)
        f.flush()
        os.fsync(f.fileno())
    os.replace(tmp, path_out)
    return len(data)


def decode(
    data_or_path: Source, *, bpp: Optional[float] = None, nbytes: Optional[int] = None
) -> "np.ma.MaskedArray":
    """Decodes ``.ezw`` bytes (or a file) to a masked array (masked where nodata).

    ``bpp`` or ``nbytes`` decode only a prefix of the stream: a coarser DEM.
    """
    samples, valid, nodata = _wavemesh.decode(_bytes_of(data_or_path), bpp=bpp, nbytes=nbytes)
    out = np.ma.MaskedArray(samples, mask=~valid)
    if nodata is not None and not np.isnan(nodata):
        out.fill_value = nodata
    return out


def info(data_or_path: Source) -> dict:
    """The stream's header and pass ladder as a dict."""
    return _wavemesh.info(_bytes_of(data_or_path))


def mesh(
    data_or_path: Source,
    *,
    bpp: Optional[float] = None,
    nbytes: Optional[int] = None,
    triangles: Optional[int] = None,
    mesh_error: Optional[float] = None,
    threshold: Optional[float] = None,
) -> Tuple[np.ndarray, np.ndarray]:
    """The mesh of a decode: ``(vertices, triangles)``.

    ``vertices`` is float64 N×3 (column, row, height), ``triangles`` uint32 M×3 indices,
    counter-clockwise seen from above; nodata samples are never meshed. Default: the
    zerotree partition at the decoder's threshold; ``threshold`` a coarser one;
    ``mesh_error`` keeps every sample within that height; ``triangles`` the largest mesh
    with at most that many triangles.
    """
    return _wavemesh.mesh(
        _bytes_of(data_or_path),
        bpp=bpp,
        nbytes=nbytes,
        triangles=triangles,
        mesh_error=mesh_error,
        threshold=threshold,
    )
