"""Checks of scalar options shared by every subpackage: one wording for one kind of mistake."""

from __future__ import annotations

import math

import numpy as np

from .errors import InputError

__all__ = ["positive_number", "real_array"]


def positive_number(name: str, value: object, *, allow_zero: bool = False, allow_inf: bool = False,
                    unit: str = "") -> float:
    """``value`` as a float if it is a real number > 0 (≥ 0 with ``allow_zero``), finite unless
    ``allow_inf``; otherwise `InputError` naming ``name``, the value and what is allowed.

    Text and complex numbers are refused rather than converted (``float("1e-3")`` would
    parse; a complex number would lose its imaginary part). ``unit`` (e.g. ``"[s]"``) is
    written after the word "number" in the message.
    """
    unit = f" {unit}" if unit else ""
    try:
        if isinstance(value, str | bytes) or np.iscomplexobj(value):  # type: ignore[arg-type]
            raise TypeError(name)
        v = float(value)  # type: ignore[arg-type]
    except (TypeError, ValueError, OverflowError):
        raise InputError(f"{name} must be a number{unit}, got {value!r}", argument=name,
                         value=value) from None
    if not ((v >= 0.0 if allow_zero else v > 0.0) and (allow_inf or math.isfinite(v))):
        kind = "non-negative" if allow_zero else "positive"
        kind += " number (inf allowed)" if allow_inf else " finite number"
        raise InputError(f"{name} must be a {kind}{unit}, got {value!r}", argument=name, value=value)
    return v


def real_array(name: str, value: object, what: str) -> np.ndarray:
    """``value`` as a float64 array; text, complex numbers and ragged or non-numeric
    sequences raise `InputError` naming ``name`` and saying it must be ``what`` (e.g.
    ``"a (6,) vector"``) "of real numbers" — never converted (``float("1")`` would
    parse, a complex number would lose its imaginary part). Shape and finiteness are the
    caller's to check."""
    try:
        if isinstance(value, str | bytes) or np.iscomplexobj(value):  # type: ignore[arg-type]
            raise TypeError(name)
        return np.asarray(value, dtype=float)
    except (TypeError, ValueError, OverflowError):
        raise InputError(f"{name} must be {what} of real numbers, got {value!r}"[:300], argument=name,
                         value=value) from None
