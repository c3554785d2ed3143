from typing import Optional, Sequence, Tuple

import numpy as np

class CodecError(Exception): ...

def encode(
    array: np.ndarray,
    *,
    nodata: Optional[float] = ...,
    bpp: Optional[float] = ...,
    max_error: Optional[float] = ...,
    precision: Optional[float] = ...,
    wavelet: Optional[str] = ...,
    geotransform: Optional[Sequence[float]] = ...,
) -> bytes: ...
def decode(
    data: bytes, *, bpp: Optional[float] = ..., nbytes: Optional[int] = ...
) -> Tuple[np.ndarray, np.ndarray, Optional[float]]: ...
def info(data: bytes) -> dict: ...
def mesh(
    data: bytes,
    *,
    bpp: Optional[float] = ...,
    nbytes: Optional[int] = ...,
    triangles: Optional[int] = ...,
    mesh_error: Optional[float] = ...,
    threshold: Optional[float] = ...,
) -> Tuple[np.ndarray, np.ndarray]: ...
