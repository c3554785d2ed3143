"""wavemesh: store, stream and mesh elevation models.

A DEM (a 2-D numpy array of uint8, uint16, int16, int32 or float32, or a GeoTIFF, PNG,
SRTM ``.hgt`` or ESRI ``.asc`` file) goes in, an embedded ``.ezw`` stream comes out: a
lifting wavelet transform (integer 13/11 or 5/3 for lossless and error-bounded coding,
CDF 9/7 for rate-driven coding) feeding an EZW zerotree coder with context-modelled arithmetic
coding. Any prefix of the bytes decodes, so one file serves every bit rate, and the
decoder's zerotree gives a crack-free triangle mesh at any threshold, triangle budget or
height tolerance.

>>> import numpy as np, wavemesh
>>> dem = (np.arange(64 * 48).reshape(48, 64) % 97).astype(np.int16)
>>> data = wavemesh.encode(dem, transform=(500000.0, 10.0, 0.0, 5000000.0, 0.0, -10.0),
...                        crs="EPSG:32632")           # lossless, bit-exact
>>> bool((wavemesh.decode(data) == dem).all())
True
>>> coarse = wavemesh.decode(data, bpp=0.5)            # a prefix: a coarser DEM
>>> header = wavemesh.info(data)                       # header, georeferencing, passes
>>> header["crs_epsg"], header["geotransform"][1]
(32632, 10.0)
>>> vertices, triangles = wavemesh.mesh(data, mesh_error=2.0)   # x, y in UTM metres
>>> rows = wavemesh.table(dem, thresholds=[64, 16], runs=1)     # the seed paper's tables

Functions:

- :func:`encode` (numpy array → bytes) and :func:`encode_file` (DEM file → ``.ezw``
  file, through the command line's readers, written atomically).
- :func:`decode` (bytes or a file → ``numpy.ma.MaskedArray``, masked where nodata or
  NaN; ``bpp=``/``nbytes=`` decode a prefix) and :func:`info` (header, georeferencing,
  metadata and the pass ladder as a dict).
- :func:`mesh` (``(vertices, triangles)`` as the command line's ``mesh`` writes them)
  and :func:`table` (the seed paper's Tables 1 and 2 as dicts or a pandas DataFrame).
- :mod:`wavemesh.rio` (rasterio-style profiles) and :mod:`wavemesh.xarray`
  (rioxarray DataArrays).
- :mod:`wavemesh.dask`: ``to_ezw`` encodes a Dask array a tile per task into the bytes
  :func:`encode` gives; ``open_ezw`` decodes a tiled file lazily, a tile per task.

Georeferencing: ``transform`` is a rasterio/affine ``Affine`` or a GDAL 6-tuple; ``crs``
an EPSG code (``32632`` or ``"EPSG:32632"``), WKT, or an object with ``to_epsg()`` /
``to_wkt()`` (rasterio's or pyproj's ``CRS``). A CRS an EPSG code names is stored as
that code (as the command line stores GeoTIFF keys), any other as its WKT text.

Errors: ``ValueError`` for bad arguments, :class:`CodecError` for data the codec cannot
decode (damaged, truncated, not ``.ezw``) or samples it cannot code (±inf), ``OSError``
for files that cannot be read or written; messages are the command line's one-liners.
The GIL is released while coding, meshing and measuring.
"""

from __future__ import annotations

import json
import numbers
import os
import re
import warnings
from typing import Any, List, Optional, Sequence, Tuple, Union

import numpy as np

from . import _wavemesh
from ._wavemesh import CodecError

__all__ = ["CodecError", "encode", "encode_file", "decode", "info", "mesh", "table"]

CodecError.__module__ = "wavemesh"

PathLike = Union[str, "os.PathLike[str]"]
Source = Union[bytes, bytearray, memoryview, PathLike]

#: GDAL's geotransform of a raster without georeferencing (rasterio's identity
#: ``Affine``): with no CRS, :func:`encode` stores no georeferencing for it.
_NOT_GEOREFERENCED = (0.0, 1.0, 0.0, 0.0, 0.0, 1.0)
_EPSG_TEXT = re.compile(r"^\s*EPSG:(\d+)\s*$", re.IGNORECASE)
_WKT_TEXT = re.compile(r"^\s*[A-Z_0-9]+\s*\[", re.IGNORECASE)


def _count(name: str, value: Any) -> Optional[int]:
    """``value`` checked as a non-negative integer (``None`` passes)."""
    if value is None:
        return None
    if isinstance(value, bool) or not isinstance(value, numbers.Integral) or value < 0:
        raise ValueError(f"{name} must be a non-negative integer, got {value!r}")
    return int(value)


def _fill_value_fits(nodata: Optional[float], dtype: np.dtype) -> bool:
    """Whether ``nodata`` is a value of ``dtype`` (NaN only for floats)."""
    if nodata is None:
        return False
    if np.issubdtype(dtype, np.floating):
        return True
    limits = np.iinfo(dtype)
    return float(nodata).is_integer() and limits.min <= nodata <= limits.max


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
    try:
        values = tuple(float(v) for v in transform)
    except TypeError:
        raise ValueError(
            f"transform must be an Affine or 6 numbers (GDAL order), got {transform!r}"
        ) from None
    if len(values) != 6:
        raise ValueError(f"transform must have 6 numbers (GDAL order), got {len(values)}")
    return values


def _crs(crs: Any) -> Tuple[Optional[int], Optional[str]]:
    """``(epsg, wkt)`` of a CRS given as an EPSG code, ``"EPSG:n"``, WKT, or an object
    with ``to_epsg()``/``to_wkt()`` (both: the code is stored when it is known, else the
    WKT)."""
    if crs is None:
        return None, None
    if isinstance(crs, numbers.Integral) and not isinstance(crs, bool):
        return int(crs), None
    if isinstance(crs, str):
        epsg = _EPSG_TEXT.match(crs)
        if epsg:
            return int(epsg.group(1)), None
        if _WKT_TEXT.match(crs):
            return None, crs.strip()
        raise ValueError(f"crs must be an EPSG code, 'EPSG:n' or WKT, got {crs!r}")
    if hasattr(crs, "to_epsg") or hasattr(crs, "to_wkt"):
        code = crs.to_epsg() if hasattr(crs, "to_epsg") else None
        wkt = crs.to_wkt() if hasattr(crs, "to_wkt") else None
        if code or wkt:
            return (int(code) if code else None), wkt
    raise ValueError(
        f"crs must be an EPSG code, 'EPSG:n', WKT or a CRS object, got {type(crs).__name__}"
    )


def _native_2d(array: Any) -> np.ndarray:
    """``array`` as a 2-D numpy array in native byte order, copied only to fix the
    byte order (any strides and both memory orders are read as they are)."""
    array = np.asarray(array)
    if array.ndim != 2:
        raise ValueError(f"expected a 2-D array, got {array.ndim} dimensions")
    if not array.dtype.isnative:
        array = array.astype(array.dtype.newbyteorder("="))
    return array


def _void_value(dtype: np.dtype) -> float:
    """The nodata value a masked array of ``dtype`` gets when none is given: NaN for
    floats, the type's minimum (signed) or maximum (unsigned)."""
    if np.issubdtype(dtype, np.floating):
        return float("nan")
    limits = np.iinfo(dtype)
    return limits.min if limits.min < 0 else limits.max


def _fill_masked(array: "np.ma.MaskedArray", nodata: Optional[float]):
    """A masked array as plain samples with its voids set to a nodata value: ``nodata``,
    else :func:`_void_value`."""
    if nodata is None:
        nodata = _void_value(array.dtype)
    return array.filled(nodata), nodata


def _georef_args(
    transform: Any, crs: Any
) -> Tuple[Optional[Tuple[float, ...]], Optional[int], Optional[str]]:
    """``(geotransform, epsg, wkt)`` of ``encode``'s ``transform`` and ``crs`` (the
    identity transform without a CRS stores no georeferencing)."""
    epsg, wkt = _crs(crs)
    geotransform = _geotransform(transform)
    if geotransform == _NOT_GEOREFERENCED and epsg is None and wkt is None:
        geotransform = None
    return geotransform, epsg, wkt


def _masked(
    samples: np.ndarray, valid: np.ndarray, nodata: Optional[float]
) -> "np.ma.MaskedArray":
    """A decode's samples masked where not ``valid``, ``fill_value`` the nodata value
    when the samples' type holds it."""
    out = np.ma.MaskedArray(samples, mask=~valid)
    if _fill_value_fits(nodata, samples.dtype):
        out.fill_value = nodata
    return out


def encode(
    array: Any,
    *,
    nodata: Optional[float] = None,
    bpp: Optional[float] = None,
    max_error: Optional[float] = None,
    precision: Optional[float] = None,
    wavelet: Optional[str] = None,
    transform: Any = None,
    crs: Any = None,
    tile: int = 1024,
    block: Optional[int] = None,
    threads: int = 0,
) -> bytes:
    """Encodes a 2-D array into ``.ezw`` bytes.

    Lossless (bit-exact, floats included) by default; ``bpp`` cuts the stream at that
    many bits per sample (lossy 9/7 unless ``wavelet`` is ``"53"`` or ``"1311"``; the
    lossless file instead when it fits, unless ``wavelet`` is ``"97"``);
    ``max_error`` keeps every valid sample within that many data units; ``precision``
    quantises floats to that step. ``wavelet`` is ``"97"``, ``"53"`` or ``"1311"``
    (default: 9/7 with ``bpp``, else the reversible 13/11 or 5/3, whichever the array's
    centre codes smaller). Voids: ``nodata``, NaN (floats) and a
    ``numpy.ma`` array's mask (filled with ``nodata``, else NaN or the type's extreme).

    ``transform`` is an ``Affine`` or a GDAL geotransform (6 numbers); ``crs`` an EPSG
    code, ``"EPSG:n"``, WKT or a CRS object (needs ``transform``); the identity
    transform without a CRS (what rasterio gives for a raster without georeferencing)
    stores none. The array may have
    any strides and either memory order: its samples are read once, straight from its
    memory, into the coder's buffer (no intermediate numpy copy; only a non-native byte
    order is converted first).

    An array with a side longer than ``tile`` is coded as independent tiles (as equal
    as the array allows) with an index, so :func:`decode` of a ``window`` or at a rate
    reads only what it needs; ``tile=0`` codes one stream whatever the size (what
    :func:`mesh` needs). ``block`` (a multiple of 64) makes each tile one transform
    coded in code blocks of that side, each indexed on its own: windows read the blocks
    they need and tile borders do not show (``--block``). ``threads`` code tiles in
    parallel (0: one per core); the bytes do not depend on it.
    """
    if np.ma.isMaskedArray(array):
        array, nodata = _fill_masked(array, nodata)
    geotransform, epsg, wkt = _georef_args(transform, crs)
    return _wavemesh.encode(
        _native_2d(array),
        nodata=None if nodata is None else float(nodata),
        bpp=bpp,
        max_error=max_error,
        precision=precision,
        wavelet=wavelet,
        geotransform=geotransform,
        epsg=epsg,
        crs_wkt=wkt,
        tile=_count("tile", tile),
        block=_count("block", block),
        threads=_count("threads", threads),
    )


def encode_file(
    path_in: PathLike,
    path_out: PathLike,
    *,
    bpp: Optional[float] = None,
    max_error: Optional[float] = None,
    precision: Optional[float] = None,
    wavelet: Optional[str] = None,
    terrain_rgb: bool = False,
    accept_lossy_input: bool = False,
    no_metadata_items: bool = False,
    max_samples: Optional[int] = None,
    max_memory: Optional[int] = None,
    tile: int = 1024,
    block: Optional[int] = None,
    threads: int = 0,
) -> int:
    """Encodes a DEM file into a ``.ezw`` file, as ``wavemesh encode`` does; returns the
    bytes written.

    Inputs are read by the command line's readers (GeoTIFF, 8/16-bit PNG, SRTM ``.hgt``,
    ESRI ``.asc``; ``terrain_rgb=True`` for Mapbox Terrain-RGB PNGs), with their nodata,
    georeferencing and GDAL metadata (``no_metadata_items=True`` leaves out the free
    items). ``max_samples`` / ``max_memory`` refuse larger rasters before reading them
    (defaults 2³¹ samples, 2 GiB). The output is written atomically and never replaces
    the input. Quality, ``tile``, ``block`` and ``threads`` options as in :func:`encode`.
    """
    return _wavemesh.encode_file(
        os.fspath(path_in),
        os.fspath(path_out),
        bpp=bpp,
        max_error=max_error,
        precision=precision,
        wavelet=wavelet,
        terrain_rgb=terrain_rgb,
        accept_lossy_input=accept_lossy_input,
        no_metadata_items=no_metadata_items,
        max_samples=_count("max_samples", max_samples),
        max_memory=_count("max_memory", max_memory),
        tile=_count("tile", tile),
        block=_count("block", block),
        threads=_count("threads", threads),
    )


def decode(
    data_or_path: Source,
    *,
    bpp: Optional[float] = None,
    nbytes: Optional[int] = None,
    strict: bool = False,
    max_samples: Optional[int] = None,
    max_memory: Optional[int] = None,
    window: Optional[Tuple[int, int, int, int]] = None,
    threads: int = 0,
) -> "np.ma.MaskedArray":
    """Decodes ``.ezw`` bytes (or a file) to a ``numpy.ma.MaskedArray`` of the source's
    type and shape.

    The mask is always a full boolean array, ``True`` at voids (samples equal to the
    stream's nodata value, and NaN); the data underneath hold the nodata value (NaN for
    float voids without one) and ``fill_value`` is the nodata value, so ``.filled()``
    gives the samples as the source stored them. ``bpp`` or ``nbytes`` decode only a
    prefix of the stream: a coarser DEM. Damage (a failed chunk checksum) decodes the
    undamaged prefix with a ``RuntimeWarning``, or raises :class:`CodecError` with
    ``strict=True``. Georeferencing and metadata: :func:`info`.

    ``window=(x, y, width, height)`` decodes only those columns and rows; of a tiled
    file only the tiles the window touches are decoded (``threads`` of them at once, 0:
    one per core). Of a tiled file, ``bpp``/``nbytes`` is a budget for the whole file,
    shared among the tiles where it lowers the error most.
    """
    if window is not None:
        window = tuple(_count("window", v) for v in window)
        if len(window) != 4:
            raise ValueError(f"window wants (x, y, width, height), got {window!r}")
    samples, valid, nodata, damage = _wavemesh.decode(
        _bytes_of(data_or_path),
        bpp=bpp,
        nbytes=_count("nbytes", nbytes),
        strict=strict,
        max_samples=_count("max_samples", max_samples),
        max_memory=_count("max_memory", max_memory),
        window=window,
        threads=_count("threads", threads),
    )
    if damage is not None:
        where = "" if isinstance(data_or_path, (bytes, bytearray, memoryview)) else (
            f"{os.fspath(data_or_path)}: "
        )
        warnings.warn(f"{where}{damage}", RuntimeWarning, stacklevel=2)
    return _masked(samples, valid, nodata)


def info(
    data_or_path: Source,
    *,
    max_samples: Optional[int] = None,
    max_memory: Optional[int] = None,
) -> dict:
    """The stream's header as a dict, as ``wavemesh info --json`` reports it.

    Keys: ``width``, ``height``, ``sample_type``, ``wavelet``, ``levels``, ``mode``,
    ``max_error_bound`` (``None`` for lossy streams), ``nodata``, ``valid_samples``,
    ``valid_min``/``valid_max``, the section sizes (``header_bytes``, ``mask_bytes``,
    ``payload_bytes``, ``residual_bytes``, ``file_bytes``), ``truncated``; the
    georeferencing: ``geotransform`` (GDAL 6-tuple or ``None``), ``crs_epsg`` (int or
    ``None``), ``crs_wkt`` (the source's WKT, else the EPSG definition); GDAL metadata:
    ``scale``, ``offset``, ``description``, ``unit_type``, ``metadata_items``; and
    ``passes``, the pass ladder: one dict per pass with ``plane``, ``end_byte`` (where it
    ends in the file), ``bpp`` and the encoder's ``estimated_rmse`` and
    ``estimated_psnr_db`` of a decode that stops there. ``tiles`` is ``None`` for a
    single stream, else a dict of ``tile_width``, ``tile_height``, ``count`` and
    ``index_bytes`` (a tiled file's header has no passes of its own, and its
    ``valid_samples`` counts every sample).
    """
    header = _wavemesh.info(
        _bytes_of(data_or_path),
        max_samples=_count("max_samples", max_samples),
        max_memory=_count("max_memory", max_memory),
    )
    if header["geotransform"] is not None:
        header["geotransform"] = tuple(header["geotransform"])
    return header


def mesh(
    data_or_path: Source,
    *,
    bpp: Optional[float] = None,
    nbytes: Optional[int] = None,
    triangles: Optional[int] = None,
    mesh_error: Optional[float] = None,
    threshold: Optional[float] = None,
    search: str = "error",
    rule: str = "zerotree",
    xy: str = "geo",
    z_scale: float = 1.0,
    max_samples: Optional[int] = None,
    max_memory: Optional[int] = None,
) -> Tuple[np.ndarray, np.ndarray]:
    """The mesh of a decode, as ``wavemesh decode --mesh`` writes it: ``(vertices,
    triangles)``, float64 N×3 and uint32 M×3.

    Which mesh: by default the zerotree partition at the decoder's threshold;
    ``threshold`` a coarser pass; ``mesh_error`` every sample of the decoded heights
    within that tolerance (refining ``threshold``'s partition if given); ``triangles``
    the largest mesh with at most that many triangles (``search="error"`` over
    tolerances, ``"threshold"`` over passes). ``rule="own"`` splits on a node's own
    coefficients only. ``bpp``/``nbytes`` mesh a prefix.

    Coordinates (``xy``, as ``--xy``): ``"geo"`` (default) puts a geographic DEM in
    metres east, north and up of its centre, a projected one in its CRS's x/y, an
    unreferenced one in pixels; ``"degrees"`` the CRS's own x/y; ``"pixel"`` (column,
    row). x/y are pixel centres, z the stored value times ``z_scale``. Every triangle is
    counter-clockwise seen from +z; nodata samples are never meshed (a raster without a
    2 × 2 block of valid samples raises :class:`CodecError`).
    """
    return _wavemesh.mesh(
        _bytes_of(data_or_path),
        bpp=bpp,
        nbytes=_count("nbytes", nbytes),
        triangles=_count("triangles", triangles),
        mesh_error=mesh_error,
        threshold=threshold,
        search=search,
        rule=rule,
        xy=xy,
        z_scale=z_scale,
        max_samples=_count("max_samples", max_samples),
        max_memory=_count("max_memory", max_memory),
    )


def _flat_row(row: dict) -> dict:
    """A table row with its nested ``mesh`` errors as ``mesh_*`` columns."""
    flat = {k: v for k, v in row.items() if k != "mesh"}
    for key, value in row["mesh"].items():
        flat[f"mesh_{key}"] = value
    return flat


def table(
    dem: Any,
    *,
    nodata: Optional[float] = None,
    thresholds: Optional[Sequence[float]] = None,
    bpp: Optional[Sequence[float]] = None,
    wavelet: str = "53",
    rule: str = "zerotree",
    runs: int = 5,
    terrain_rgb: bool = False,
    as_frame: bool = False,
    max_samples: Optional[int] = None,
    max_memory: Optional[int] = None,
) -> Union[List[dict], Any]:
    """The seed paper's Tables 1 and 2 for a DEM, as ``wavemesh table`` measures them:
    one row per threshold (``thresholds``), per bit rate (``bpp``: prefixes of one
    stream, lossless 5/3 or with ``wavelet="97"`` a 9/7 stream cut at the largest), or
    per pass of the lossless stream (default).

    ``dem`` is a 2-D array (``nodata`` and a ``numpy.ma`` mask mark voids) or a DEM
    file. Each row is a dict: ``plane``, ``threshold``, ``triangles``, ``vertices``,
    ``search_seconds`` and ``triangulation_seconds`` (medians of ``runs``), the mesh's
    errors against the original as ``mesh_psnr_db``, ``mesh_rmse``, ``mesh_max_error``
    (and the other ``mesh_*`` columns), ``image_psnr_db``, ``image_rmse``,
    ``remaining_percent``, ``ezw_bytes``, ``bpp``, ``mesh_bytes_paper``,
    ``mesh_bytes_in_memory``, ``saving_ratio``. ``as_frame=True`` returns a pandas
    ``DataFrame`` of the same rows (pandas must be installed).
    """
    options = dict(
        thresholds=None if thresholds is None else [float(t) for t in thresholds],
        bpp=None if bpp is None else [float(r) for r in bpp],
        wavelet=wavelet,
        rule=rule,
        runs=_count("runs", runs),
        max_samples=_count("max_samples", max_samples),
        max_memory=_count("max_memory", max_memory),
    )
    if isinstance(dem, (str, os.PathLike)):
        text = _wavemesh.table(path=os.fspath(dem), terrain_rgb=terrain_rgb, **options)
    else:
        if np.ma.isMaskedArray(dem):
            dem, nodata = _fill_masked(dem, nodata)
        text = _wavemesh.table(
            array=_native_2d(dem), nodata=None if nodata is None else float(nodata), **options
        )
    rows = [_flat_row(row) for row in json.loads(text)]
    if not as_frame:
        return rows
    try:
        import pandas
    except ImportError:
        raise ImportError("table(as_frame=True) needs pandas: pip install pandas") from None
    return pandas.DataFrame(rows)


def _write_atomic(path: PathLike, data: bytes) -> None:
    """Writes ``data`` to ``path`` atomically (a temporary file renamed into place)."""
    _wavemesh.write_file(os.fspath(path), data)
