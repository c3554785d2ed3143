"""Type stubs of the compiled half of the package (``wavemesh._wavemesh``); the public
functions in ``wavemesh`` wrap these."""

from typing import List, Optional, Sequence, Tuple

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
