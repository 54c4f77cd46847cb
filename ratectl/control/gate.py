"""The controller's gate: input validation and the halt policy (stage 1 of a cycle).

`Gate.validate` checks shapes and types (a wrong shape is a programming error: `InputError`
at once); `Gate.check` checks values and says when the cycle must halt instead: a
non-finite q, target, twist, feed-forward or dt latches the halt (until ``reset``); a
target that is not a rigid pose (scaled, sheared, mirrored), or a target or twist whose
``stamp`` is older than ``timeout`` or ahead of the controller clock, halts this cycle
only. The gate owns that state:
the latched reason, the last target found rigid (checked again only when it changes) and
the last good period (the period a halt on a bad dt brakes over).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from ..errors import InputError
from ..spatial import finite_rows, is_rigid_rows, rigid_transform_defect
from .cycle import _finite_sum, _same_rotation

__all__ = ["Gate"]


def _checked_stamp(stamp) -> float:
    """A target's stamp as a float [s] (NaN stays NaN: a value, which halts), or InputError
    for text, a boolean or anything that is not a real number."""
    if isinstance(stamp, (str, bytes, bool)) or not isinstance(stamp, (int, float, np.integer, np.floating)):
        raise InputError(f"stamp must be a time in seconds on the controller clock ctrl.time, got {stamp!r}",
                         argument="stamp", value=stamp)
    return float(stamp)


def _float_array(value, name: str, what: str) -> np.ndarray:
    try:
        return np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise InputError(f"{name} must be {what}, got {value!r}", argument=name, value=value) from None


class Gate:
    """Validation and the halt policy of a controller of ``n`` joints (see the module
    docstring); ``timeout`` [s]: the age beyond which a stamped target is stale."""

    def __init__(self, n: int, timeout: float) -> None:
        self.n = n
        self.timeout = timeout
        self._target_ok: list[list[float]] | None = None  # the last target found rigid (rows)
        self.reset()

    def reset(self) -> None:
        """Clear the latched halt and forget the last period."""
        self.latched = ""
        self.dt_last: float | None = None

    def validate(self, q: ArrayLike, target: ArrayLike | None, twist: ArrayLike | None, dt: Any,
                 qd_ff: ArrayLike | None, qdd_ff: ArrayLike | None,
                 ) -> tuple[np.ndarray, np.ndarray | None, np.ndarray | None, float,
                             np.ndarray | None, np.ndarray | None]:
        """Shapes and types: returns ``(q, target, twist, dt, qd_ff, qdd_ff)`` as float arrays
        (the caller's arrays are not copied when already float64) or raises
        `InputError`. Values (NaN, inf) are not checked here."""
        n = self.n
        if type(q) is not np.ndarray or q.dtype != np.float64:
            try:
                q = np.asarray(q, dtype=float)
            except (TypeError, ValueError):
                raise InputError(f"q must be {n} numbers", argument="q", value=q) from None
        if q.shape != (n,):
            raise InputError(f"q must have shape ({n},), got {q.shape}", argument="q", value=q)
        try:
            if isinstance(dt, (str, bytes)):  # float("1e-3") would parse: a period is a number
                raise TypeError
            dt = float(dt)
        except (TypeError, ValueError):
            raise InputError(f"dt must be a number [s], got {dt!r}", argument="dt", value=dt) from None
        if target is not None:
            if type(target) is not np.ndarray or target.dtype != np.float64:
                target = _float_array(target, "target", "a 4x4 pose")
            if target.shape != (4, 4):
                raise InputError(f"target must be a 4x4 pose, got shape {target.shape}",
                                 argument="target", value=target)
        if twist is not None:
            if type(twist) is not np.ndarray or twist.dtype != np.float64:
                twist = _float_array(twist, "twist", "6 numbers [v; ω]")
            if twist.shape != (6,):
                raise InputError(f"twist must have shape (6,) [v; ω], got {twist.shape}",
                                 argument="twist", value=twist)
        if qd_ff is not None:
            qd_ff = _float_array(qd_ff, "qd_ff", f"{n} numbers")
            if qd_ff.shape != (n,):
                raise InputError(f"qd_ff must have shape ({n},), got {qd_ff.shape}",
                                 argument="qd_ff", value=qd_ff)
        if qdd_ff is not None:
            qdd_ff = _float_array(qdd_ff, "qdd_ff", f"{n} numbers")
            if qdd_ff.shape != (n,):
                raise InputError(f"qdd_ff must have shape ({n},) [rad/s² or m/s²], got {qdd_ff.shape}",
                                 argument="qdd_ff", value=qdd_ff)
        return q, target, twist, dt, qd_ff, qdd_ff

    def check(self, q, target, twist, dt, qd_ff, qdd_ff, stamp, now: float) -> tuple[str, float] | None:
        """Values that bring a safe halt (non-finite inputs latch it, a stale target does
        not): returns ``(reason, dt)`` for the halt (dt: the period to brake over), or None
        when the cycle may proceed. ``now``: the controller clock [s], for ``stamp``."""
        if not (dt > 0.0 and math.isfinite(dt)):
            self.latched = self.latched or f"non-finite or non-positive dt ({dt!r})"
            return self.latched, self.dt_last or 1e-3
        self.dt_last = dt
        if self.latched:
            return self.latched, dt
        # finiteness through Python float sums (NaN or inf make the sum non-finite; an
        # overflow to inf of finite values is refused too): cheaper than ndarray.sum
        bad = None
        rows = None
        if not _finite_sum(q):
            bad = "q"
        elif target is not None and not finite_rows(rows := target.tolist()):
            bad = "target"
        elif twist is not None and not _finite_sum(twist):
            bad = "twist"
        elif qd_ff is not None and not _finite_sum(qd_ff):
            bad = "qd_ff"
        elif qdd_ff is not None and not _finite_sum(qdd_ff):
            bad = "qdd_ff"
        if bad is not None:
            self.latched = f"non-finite {bad} (NaN or inf); reset() to resume"
            return self.latched, dt
        ok = self._target_ok
        if rows is not None and rows != ok:  # (the rows: NaN equals nothing, −0.0 0.0)
            # rigid: the rotation block and the last row of the last rigid target (a target
            # that only translates; finite, as checked above), else by the test itself
            if not (ok is not None and rows[3] == [0.0, 0.0, 0.0, 1.0] and _same_rotation(rows, ok)
                    or is_rigid_rows(rows)):
                defect = rigid_transform_defect(target)
                if defect is not None:  # a scaled, sheared or mirrored pose: no motion toward it
                    return f"target {defect}", dt
            self._target_ok = rows
        if stamp is not None:  # the age of what the cycle is given: a target, or a twist to jog
            what = "target" if target is not None else "twist" if twist is not None else "command"
            age = now - stamp
            if not age <= self.timeout:
                return f"stale {what}: {age:.3g} s old > timeout {self.timeout:.3g} s", dt
            if age < -self.timeout:  # from the future: the producer's clock is not this controller's
                return (f"{what} stamped {-age:.3g} s ahead of the controller clock ctrl.time (more "
                        f"than timeout {self.timeout:.3g} s): stamp it on ctrl.time", dt)
        return None
