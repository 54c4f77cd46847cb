"""Read-only arrays for results: the one helper every frozen result uses for its arrays."""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, DTypeLike

__all__ = ["read_only"]


def read_only(a: ArrayLike, *, dtype: DTypeLike | None = np.float64) -> np.ndarray:
    """A read-only array of ``a`` with ``dtype`` (None: keep the input's dtype).

    An array that is already read-only and of that dtype is returned as is; anything else is
    copied first, so a caller's own array is never frozen and a result never shares writable
    memory with the object that produced it.
    """
    if type(a) is np.ndarray and not a.flags.writeable and (dtype is None or a.dtype == dtype):
        return a
    out = np.array(a, dtype=dtype)
    out.flags.writeable = False
    return out
