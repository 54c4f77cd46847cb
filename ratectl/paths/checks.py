"""Argument checks shared by the path classes.
"""

from __future__ import annotations

import numpy as np

from ..errors import InputError
from ..spatial import rigid_transform_defect


def _pose(T, name: str) -> np.ndarray:
    defect = rigid_transform_defect(T)
    if defect is not None:
        raise InputError(f"{name} {defect}", argument=name, value=T)
    return np.array(T, dtype=float)


def _vec3(v, name: str) -> np.ndarray:
    try:
        if isinstance(v, str | bytes) or np.iscomplexobj(v):
            raise TypeError(name)
        a = np.asarray(v, dtype=float)
    except (TypeError, ValueError, OverflowError):
        raise InputError(f"{name} must be a finite 3-vector, got {v!r}", argument=name, value=v) from None
    if a.shape != (3,) or not np.all(np.isfinite(a)):
        raise InputError(f"{name} must be a finite 3-vector, got {v!r}", argument=name, value=v)
    return a
