"""Type stubs of the compiled half of the package (``wavemesh._wavemesh``); the public
functions in ``wavemesh`` wrap these."""

from typing import Callable, List, Optional, Sequence, Tuple

import numpy as np

class CodecError(Exception):
    """A ``.ezw`` stream could not be decoded or a raster could not be encoded."""

def encode(
    array: np.ndarray,
    *,
    nodata: Optional[float] = ...,
    bpp: Optional[float] = ...,
    max_error: Optional[float] = ...,
    precision: Optional[float] = ...,
    wavelet: Optional[str] = ...,
    geotransform: Optional[Sequence[float]] = ...,
    epsg: Optional[int] = ...,
    crs_wkt: Optional[str] = ...,
    tile: int = ...,
    threads: int = ...,
) -> bytes: ...
def encode_file(
    path_in: str,
    path_out: str,
    *,
    bpp: Optional[float] = ...,
    max_error: Optional[float] = ...,
    precision: Optional[float] = ...,
    wavelet: Optional[str] = ...,
    terrain_rgb: bool = ...,
    accept_lossy_input: bool = ...,
    no_metadata_items: bool = ...,
    max_samples: Optional[int] = ...,
    max_memory: Optional[int] = ...,
    tile: int = ...,
    threads: int = ...,
) -> int: ...
def decode(
    data: bytes,
    *,
    bpp: Optional[float] = ...,
    nbytes: Optional[int] = ...,
    strict: bool = ...,
    max_samples: Optional[int] = ...,
    max_memory: Optional[int] = ...,
    window: Optional[Tuple[int, int, int, int]] = ...,
    threads: int = ...,
) -> Tuple[np.ndarray, np.ndarray, Optional[float], Optional[str]]:
    """``(samples, valid, nodata, damage)``: ``damage`` is the warning's text, if any."""

def info(
    data: bytes, *, max_samples: Optional[int] = ..., max_memory: Optional[int] = ...
) -> dict: ...
def mesh(
    data: bytes,
    *,
    bpp: Optional[float] = ...,
    nbytes: Optional[int] = ...,
    triangles: Optional[int] = ...,
    mesh_error: Optional[float] = ...,
    threshold: Optional[float] = ...,
    search: str = ...,
    rule: str = ...,
    xy: str = ...,
    z_scale: float = ...,
    max_samples: Optional[int] = ...,
    max_memory: Optional[int] = ...,
) -> Tuple[np.ndarray, np.ndarray]: ...
def table(
    *,
    array: Optional[np.ndarray] = ...,
    path: Optional[str] = ...,
    nodata: Optional[float] = ...,
    thresholds: Optional[List[float]] = ...,
    bpp: Optional[List[float]] = ...,
    wavelet: str = ...,
    rule: str = ...,
    runs: int = ...,
    terrain_rgb: bool = ...,
    max_samples: Optional[int] = ...,
    max_memory: Optional[int] = ...,
) -> str:
    """The rows as the command line's ``table --format json`` (a JSON array)."""

def write_file(path: str, data: bytes) -> None: ...

# wavemesh.dask: a tiled file encoded and decoded a tile at a time.

#: A tile's summary as ``encode_tile`` returns it (opaque: ``write_tiled`` takes it back).
TileSummary = Tuple[
    int, int, float, List[Tuple[int, float]], str, float, Optional[Tuple[float, float]], int, int
]

def tile_grid(
    width: int,
    height: int,
    tile: int,
    *,
    bpp: Optional[float] = ...,
    max_error: Optional[float] = ...,
    precision: Optional[float] = ...,
    wavelet: Optional[str] = ...,
) -> Optional[Tuple[int, int, int]]:
    """``(tile_width, tile_height, overlap)`` of the raster's balanced grid, ``None`` for
    one stream."""

def encode_tile(
    array: np.ndarray,
    *,
    raster_width: int,
    raster_height: int,
    nodata: Optional[float] = ...,
    bpp: Optional[float] = ...,
    max_error: Optional[float] = ...,
    precision: Optional[float] = ...,
    wavelet: Optional[str] = ...,
    cap: Optional[int] = ...,
) -> Tuple[bytes, TileSummary]:
    """One tile's stream and summary (``array``: the tile and its overlap), as the
    single-machine encoder codes that tile (up to ``cap`` bytes when given)."""

def tile_lossless_estimate(array: np.ndarray, *, nodata: Optional[float] = ...) -> float:
    """The bytes one tile's lossless stream is estimated at (``array``: the tile and its
    overlap), for ``lossless_budget``."""

def lossless_budget(estimate: float, *, width: int, height: int, bpp: float) -> Optional[int]:
    """The byte budget of ``bpp`` when ``encode`` tries the lossless file of an integer
    raster whose tiles' estimates sum to ``estimate``, else ``None``."""

def write_tiled(
    path: str,
    tiles: List[Tuple[bytes, TileSummary]],
    *,
    width: int,
    height: int,
    tile_width: int,
    tile_height: int,
    overlap: int,
    nodata: Optional[float] = ...,
    bpp: Optional[float] = ...,
    geotransform: Optional[Sequence[float]] = ...,
    epsg: Optional[int] = ...,
    crs_wkt: Optional[str] = ...,
    recode: Optional[Callable[[int, int], Tuple[bytes, TileSummary]]] = ...,
) -> int:
    """Writes header, index and tiles (cut to a ``bpp`` budget, tiles a first cap starved
    coded again by ``recode(k, cap)``) atomically; the bytes written."""

def tiled_plan(path: str, *, bpp: Optional[float] = ..., nbytes: Optional[int] = ...) -> dict:
    """The grid, sample type, nodata, and per tile ``offsets`` and ``lengths`` to read."""

def decode_tile(
    path: str,
    offset: int,
    length: int,
    *,
    width: int,
    height: int,
    nodata: Optional[float] = ...,
    coded: Optional[Tuple[int, int, int, int]] = ...,
) -> Tuple[np.ndarray, np.ndarray]:
    """``(samples, valid)`` of one tile, from one range read of the file; ``coded`` is
    ``(x, y, width, height)``: where the tile lies in what its stream codes."""
