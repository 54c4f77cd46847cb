"""Read-only arrays for results: the one helper every frozen result uses for its arrays
(`read_only`), and zeros that nobody can change (`shared_zeros`)."""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, DTypeLike

__all__ = ["read_only", "shared_zeros"]


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


_ZEROS: dict[tuple[int, object], np.ndarray] = {}


def shared_zeros(n: int, dtype: DTypeLike = np.float64) -> np.ndarray:
    """A zero vector (n,) that nobody can change, shared by every caller: a view of a
    read-only array, which numpy refuses to make writeable again (an array that owns its
    memory could be). For results that hold zeros (an absent error, no joint at a bound),
    without allocating and freezing a fresh array every cycle."""
    key = (n, dtype)  # the dtype as given (e.g. bool): hashing a numpy dtype is slower
    z = _ZEROS.get(key)
    if z is None:
        base = np.zeros(n, dtype=dtype)
        base.setflags(write=False)
        z = _ZEROS[key] = base.view()
    return z
