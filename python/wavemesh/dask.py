"""Tiled ``.ezw`` files on Dask: encode a Dask array a tile per task, decode one lazily.

:func:`to_ezw` cuts the array into the tile grid :func:`wavemesh.encode` would use
(rechunking it: the grid's tiles are as equal as the raster allows, 1201 samples with
``tile=1024`` being 601 + 600, so chunks need not be aligned by hand), encodes each tile
(with the two samples around it that its stream also codes) in a task, and writes header, index and tiles into one file, atomically: the bytes of
``wavemesh.encode(array, tile=tile, ...)`` of the same samples. :func:`open_ezw` gives a
lazy ``dask.array.Array`` of a tiled file, one task per tile, each reading only its
tile's bytes. Tasks run on whatever scheduler is active: Dask's threads by default, a
``dask.distributed`` cluster when a ``Client`` is. Needs ``dask[array]``.

>>> import numpy as np, dask.array as da, wavemesh, wavemesh.dask, tempfile, os
>>> dem = (np.arange(300 * 200) % 251).astype(np.int16).reshape(300, 200)
>>> path = os.path.join(tempfile.mkdtemp(), "dem.ezw")
>>> _ = wavemesh.dask.to_ezw(da.from_array(dem, chunks=100), path, tile=128)
>>> open(path, "rb").read() == wavemesh.encode(dem, tile=128)
True
>>> lazy = wavemesh.dask.open_ezw(path)                 # 3 x 2 tiles of 100 x 100
>>> lazy.chunks
((100, 100, 100), (100, 100))
>>> bool((lazy.compute() == dem).all())
True
"""

from __future__ import annotations

import os
import tempfile
from typing import TYPE_CHECKING, Any, Optional, Tuple

import numpy as np

import wavemesh

from . import _wavemesh

if TYPE_CHECKING:
    import dask.array

__all__ = ["to_ezw", "open_ezw"]

#: The sample types a ``.ezw`` file holds, by the codec's short names.
_SAMPLE_TYPES = {
    "u8": np.dtype(np.uint8),
    "u16": np.dtype(np.uint16),
    "i16": np.dtype(np.int16),
    "i32": np.dtype(np.int32),
    "f32": np.dtype(np.float32),
}


def _modules():
    """dask and dask.array."""
    try:
        import dask
        import dask.array
    except ImportError:
        raise ImportError("wavemesh.dask needs dask: pip install 'dask[array]'") from None
    return dask, dask.array


def _sides(length: int, side: int) -> Tuple[int, ...]:
    """The chunk sizes of ``length`` samples cut every ``side``: the last one shorter."""
    full, rest = divmod(length, side)
    return (side,) * full + ((rest,) if rest else ())


def _tile_size(tile: Any) -> int:
    """``tile`` checked as a positive integer."""
    if isinstance(tile, bool) or not isinstance(tile, (int, np.integer)) or tile <= 0:
        raise ValueError(f"tile must be a positive integer, got {tile!r}")
    return int(tile)


def _checked_array(array: Any):
    """``array`` as a 2-D Dask array of a sample type the codec holds."""
    _, da = _modules()
    array = da.asarray(array)
    if array.ndim != 2:
        raise ValueError(f"expected a 2-D array, got {array.ndim} dimensions")
    if array.dtype.newbyteorder("=") not in _SAMPLE_TYPES.values():
        raise ValueError(
            f"cannot encode {array.dtype} samples: expected a 2-D array of uint8, uint16, "
            "int16, int32 or float32"
        )
    return array


def _encode_block(block: np.ndarray, raster_shape: Tuple[int, int], nodata, quality: dict):
    """One tile's ``(stream, summary)``, in a task: its samples coded as the
    single-machine encoder codes that tile."""
    height, width = raster_shape
    return _wavemesh.encode_tile(
        wavemesh._native_2d(block),
        raster_width=width,
        raster_height=height,
        nodata=nodata,
        **quality,
    )


def _filled(array, nodata: Optional[float]):
    """``(array, nodata)``: a masked Dask array's voids filled with ``nodata`` (else the
    value :func:`wavemesh.encode` fills them with), task by task; ``nodata`` a float."""
    if np.ma.isMaskedArray(array._meta):
        if nodata is None:
            nodata = wavemesh._void_value(array.dtype)
        plain = np.empty((0, 0), array.dtype)
        array = array.map_blocks(np.ma.filled, nodata, dtype=array.dtype, meta=plain)
    return array, None if nodata is None else float(nodata)


def _coded_window(k: int, grid: Tuple[int, int, int], shape: Tuple[int, int]):
    """``(rows, columns)`` slices of the samples tile ``k``'s stream codes: the tile and
    ``overlap`` more on each side, within the raster (``grid`` is tile width, height and
    overlap, ``shape`` the raster's)."""
    (tile_width, tile_height, overlap), (height, width) = grid, shape
    row, column = divmod(k, len(_sides(width, tile_width)))
    y, x = row * tile_height, column * tile_width
    return (
        slice(max(y - overlap, 0), min(y + tile_height + overlap, height)),
        slice(max(x - overlap, 0), min(x + tile_width + overlap, width)),
    )


def _per_tile(array, grid: Tuple[int, int, int], task, *args) -> list:
    """``task(samples, *args)`` of every tile, in grid order, each in its own task on
    ``array`` rechunked to the grid (``grid``: tile width, height and overlap), given
    the samples its stream codes: the tile and the overlap around it."""
    dask, _ = _modules()
    tile_width, tile_height, _ = grid
    height, width = array.shape
    blocks = array.rechunk((_sides(height, tile_height), _sides(width, tile_width)))
    count = len(_sides(height, tile_height)) * len(_sides(width, tile_width))
    run = dask.delayed(task)
    tasks = [run(blocks[_coded_window(k, grid, array.shape)], *args) for k in range(count)]
    return list(dask.compute(*tasks))


def _coded_tiles(array, grid: Tuple[int, int, int], nodata, quality: dict) -> list:
    """Every tile's ``(stream, summary)`` in grid order, each coded in its own task."""
    return _per_tile(array, grid, _encode_block, array.shape, nodata, quality)


def _lossless_if_it_fits(array, path, grid: Tuple[int, int, int], bpp: float, place: dict):
    """The bytes of the lossless file written to ``path`` when it fits a ``bpp`` budget,
    as :func:`wavemesh.encode` writes it instead of a 9/7 one (when the tiles' detail
    says it may fit: one task per tile estimates it); ``None`` when it is not tried or
    does not fit."""
    total = sum(_per_tile(array, grid, _tile_estimate, place["nodata"]))
    height, width = array.shape
    budget = _wavemesh.lossless_budget(total, width=width, height=height, bpp=bpp)
    if budget is None:
        return None
    folder = os.path.dirname(os.path.abspath(os.fspath(path)))
    handle, trial = tempfile.mkstemp(prefix=".wavemesh-", suffix=".ezw", dir=folder)
    os.close(handle)
    try:
        written = to_ezw(array, trial, **place)
        if written > budget:
            return None
        os.replace(trial, os.fspath(path))
        return written
    finally:
        if os.path.exists(trial):
            os.remove(trial)


def _tile_estimate(block: np.ndarray, nodata):
    """One tile's lossless estimate, in a task (see :func:`_lossless_if_it_fits`)."""
    return _wavemesh.tile_lossless_estimate(wavemesh._native_2d(block), nodata=nodata)


def _recoder(array, grid: Tuple[int, int, int], nodata, quality: dict):
    """``recode(k, cap)`` for ``write_tiled``: tile ``k`` coded again up to ``cap`` bytes
    (a tile its first cap starved under a ``bpp`` budget), its samples computed again."""

    def recode(k: int, cap: int):
        block = array[_coded_window(k, grid, array.shape)].compute()
        height, width = array.shape
        return _wavemesh.encode_tile(
            wavemesh._native_2d(block),
            raster_width=width,
            raster_height=height,
            nodata=nodata,
            cap=cap,
            **quality,
        )

    return recode


def to_ezw(
    array: Any,
    path: "wavemesh.PathLike",
    *,
    tile: int = 1024,
    bpp: Optional[float] = None,
    max_error: Optional[float] = None,
    precision: Optional[float] = None,
    wavelet: Optional[str] = None,
    nodata: Optional[float] = None,
    transform: Any = None,
    crs: Any = None,
) -> int:
    """Encodes a 2-D Dask array (or anything ``dask.array.asarray`` takes) into a tiled
    ``.ezw`` file, one task per tile; returns the bytes written.

    The file holds the bytes ``wavemesh.encode(array, tile=tile, ...)`` gives for the
    same samples and keywords (see :func:`wavemesh.encode` for ``bpp``, ``max_error``,
    ``precision``, ``wavelet``, ``nodata``, ``transform`` and ``crs``): the array is
    rechunked to the file's tile grid, each task codes its tile, and the driver writes
    the header, the index and the tiles (cut to the whole-file ``bpp`` budget as the
    single-machine encoder cuts them) to a temporary file renamed into place. The driver
    holds the coded tiles (about the file's size, or four times a ``bpp`` budget) until
    it writes them. A masked array's voids are filled with ``nodata`` (else NaN or the
    type's extreme, as :func:`wavemesh.encode` does). An array no larger than ``tile``
    a side is one stream, coded in one task. Under ``bpp`` an array whose lossless
    file may fit the budget (one task per tile estimates it, as ``encode``
    does) is first coded losslessly, and that file kept when it fits.
    """
    array, nodata = _filled(_checked_array(array), nodata)
    tile = _tile_size(tile)
    geotransform, epsg, wkt = wavemesh._georef_args(transform, crs)
    quality = dict(bpp=bpp, max_error=max_error, precision=precision, wavelet=wavelet)
    height, width = array.shape
    grid = _wavemesh.tile_grid(width, height, tile, **quality)
    if grid is None:
        data = wavemesh.encode(
            array.compute(), tile=tile, nodata=nodata, transform=transform, crs=crs, **quality
        )
        wavemesh._write_atomic(path, data)
        return len(data)
    if bpp is not None and (wavelet, max_error, precision) == (None, None, None):
        place = dict(tile=tile, nodata=nodata, transform=transform, crs=crs)
        written = _lossless_if_it_fits(array, path, grid, bpp, place)
        if written is not None:
            return written
    # Every tile codes with the wavelet the single-machine encoder settles on the
    # raster's centre.
    x, y, w, h = _wavemesh.wavelet_sample(width, height)
    centre = np.asarray(array[y : y + h, x : x + w].compute())
    quality["wavelet"] = _wavemesh.settled_wavelet(
        centre, raster_width=width, raster_height=height, nodata=nodata, **quality
    )
    tile_width, tile_height, overlap = grid
    return _wavemesh.write_tiled(
        os.fspath(path),
        _coded_tiles(array, grid, nodata, quality),
        width=width,
        height=height,
        tile_width=tile_width,
        tile_height=tile_height,
        overlap=overlap,
        nodata=nodata,
        bpp=bpp,
        geotransform=geotransform,
        epsg=epsg,
        crs_wkt=wkt,
        recode=_recoder(array, grid, nodata, quality),
    )


class _TileReader:
    """A tiled file's tiles as ``dask.array.from_array`` reads them: indexing it with
    one tile's rows and columns decodes that tile from its own byte range."""

    def __init__(self, path: str, plan: dict):
        self.path = path
        self.shape = (plan["height"], plan["width"])
        self.ndim = 2
        self.dtype = _SAMPLE_TYPES[plan["sample_type"]]
        self.tile_shape = (plan["tile_height"], plan["tile_width"])
        self.overlap = plan["overlap"]
        self.nodata = plan["nodata"]
        self.compact_tiles = plan["compact_tiles"]
        self.code_block = plan["code_block"]
        self.max_bytes = plan["max_bytes"]
        self.offsets = plan["offsets"]
        self.lengths = plan["lengths"]
        self.passes = plan["passes"]
        self.token = (path, os.stat(path).st_mtime_ns, self.offsets, self.lengths)

    def __dask_tokenize__(self):
        return self.token

    @property
    def chunks(self) -> Tuple[Tuple[int, ...], Tuple[int, ...]]:
        """The tiles' rows and columns, as Dask chunks."""
        return tuple(_sides(n, t) for n, t in zip(self.shape, self.tile_shape))

    def __getitem__(self, key: Tuple[slice, slice]) -> "np.ma.MaskedArray":
        rows, columns = key
        tile_height, tile_width = self.tile_shape
        row, column = rows.start // tile_height, columns.start // tile_width
        height, width = self.chunks[0][row], self.chunks[1][column]
        y, x = row * tile_height, column * tile_width
        if (rows.start, rows.stop, columns.start, columns.stop) != (y, y + height, x, x + width):
            raise IndexError(f"reads whole tiles only, not {key!r}")
        if self.code_block is not None:
            samples, valid = _wavemesh.decode_blocked_tile(
                self.path, x, y, width, height, nbytes=self.max_bytes
            )
            return self._masked(samples, valid)
        k = row * len(self.chunks[1]) + column
        grid = (tile_width, tile_height, self.overlap)
        coded_rows, coded_columns = _coded_window(k, grid, self.shape)
        samples, valid = _wavemesh.decode_tile(
            self.path,
            self.offsets[k],
            self.lengths[k],
            width=width,
            height=height,
            nodata=self.nodata,
            coded=(
                x - coded_columns.start,
                y - coded_rows.start,
                coded_columns.stop - coded_columns.start,
                coded_rows.stop - coded_rows.start,
            ),
            compact_tiles=self.compact_tiles,
            passes=self.passes[k],
        )
        return self._masked(samples, valid)

    def _masked(self, samples: "np.ndarray", valid: "np.ndarray") -> "np.ma.MaskedArray":
        """A decoded tile as a chunk: masked at voids, a fill value Dask can ship."""
        tile = wavemesh._masked(samples, valid, self.nodata)
        if not wavemesh._fill_value_fits(self.nodata, tile.dtype):
            # One the type holds: dask.distributed cannot ship a masked array whose fill
            # value is numpy's default for small integers (999999).
            tile.fill_value = wavemesh._void_value(tile.dtype)
        return tile


def open_ezw(
    path: "wavemesh.PathLike", *, bpp: Optional[float] = None, nbytes: Optional[int] = None
) -> "dask.array.Array":
    """A tiled ``.ezw`` file as a lazy ``dask.array.Array``, one chunk (and one task) per
    tile.

    Opening reads the header and the tile index only; each task reads its tile's bytes
    (one range read; with code blocks, ``encode(..., block=N)``, the tile's head and each
    block, by range; the file must be reachable at the same path wherever the
    task runs) and decodes them. ``bpp`` or ``nbytes`` is a budget for the whole file,
    shared among the tiles as :func:`wavemesh.decode` shares it, so
    ``open_ezw(path, bpp=b).compute()`` equals ``wavemesh.decode(path, bpp=b)``. Chunks
    are ``numpy.ma`` arrays as :func:`wavemesh.decode` returns them: masked at voids,
    the nodata value (NaN for float voids without one) underneath; ``fill_value`` is the
    nodata value, else the value :func:`wavemesh.encode` fills a masked array's voids
    with (NaN, or the type's minimum if signed, maximum if unsigned). A chunk without
    voids that went through ``dask.distributed`` may come back with the mask ``nomask``
    (``np.ma.getmaskarray`` gives the full one).

    A single-stream file raises ``ValueError`` (decode it with :func:`wavemesh.decode`);
    a damaged header or index raises :class:`wavemesh.CodecError` here, a damaged or
    missing tile raises it when that tile is computed.
    """
    _, da = _modules()
    path = os.path.abspath(os.fspath(path))
    plan = _wavemesh.tiled_plan(path, bpp=bpp, nbytes=wavemesh._count("nbytes", nbytes))
    reader = _TileReader(path, plan)
    meta = np.ma.MaskedArray(np.empty((0, 0), reader.dtype), mask=np.empty((0, 0), bool))
    return da.from_array(reader, chunks=reader.chunks, asarray=False, fancy=False, meta=meta)
