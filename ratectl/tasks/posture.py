"""`Posture`: joint positions (n rows)."""

from __future__ import annotations

import math
from operator import gt as _gt
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike

from ..errors import InputError
from ..model.limits import braking_speed_scalar
from .base import Task, TaskRows, _layout_changed, check_vector

if TYPE_CHECKING:
    from ..model.chain import Chain

__all__ = ["Posture"]


class Posture(Task):
    """Bring the joints to a reference configuration: ``A = I``, ``b = K (q_ref − q)``
    [rad/s or m/s] (n rows; only the joints of ``joints`` when given), each joint's speed
    bounded by the one from which it can stop within its error:

        b_i = sign(e_i) · min(K |e_i|, v_stop(|e_i|)),   e = q_ref − q,

    with ``v_stop`` the jerk-limited braking speed of the joint's amax and jmax
    (`ratectl.model.limits.braking_speed`; √(2·amax·|e|) without jmax, no bound without
    amax). Below ``|e_i| = e*`` the law is the linear ``K e_i``: e* = jmax/K³ when
    jmax ≤ amax·K, else 2·amax/K² − amax²/(jmax·K). A high gain on a large error would
    otherwise ask for more than the joint can brake from: the joint overshoots, reverses at
    vmax, and a smoothing filter, which shapes each joint on its own, leaves the direction
    the levels above left free while it reverses (the tool moves).

    A posture on the lowest level fixes the motion the higher levels leave free (a 7-axis
    arm's elbow), so the answer is unique.

    Args:
        q_ref: the reference configuration (n,) [rad or m], or None until `set_target`.
        joints: indices of the joints the task holds (default: all).
        priority, weight, gain: see `Task`.
    """

    def __init__(self, q_ref: ArrayLike | None = None, *, joints: ArrayLike | None = None,
                 priority: int = 0, weight: float = 1.0, gain: float = 10.0) -> None:
        super().__init__(priority=priority, weight=weight, gain=gain)
        self._q_ref = None if q_ref is None else check_vector(q_ref, int(np.size(q_ref)), "q_ref",
                                                               "[rad or m]")
        self._joints = None if joints is None else np.asarray(joints, dtype=int).ravel()
        self._A: tuple[tuple[int, float], np.ndarray] | None = None  # the scaled rows of I, kept
        self._estar: tuple | None = None  # (chain, gain, e* per joint, amax, jmax lists)
        self._rows_in: tuple | None = None  # (A, s, n): the array whose rows were last written
        self._valid: tuple | None = None  # (q_ref, chain, rows): the last q_ref checked on a chain
        self._gain_row: tuple[float, np.ndarray] | None = None  # (K·s, K·s per row) of `_brake`

    @property
    def has_target(self) -> bool:
        return self._q_ref is not None

    @property
    def target(self) -> np.ndarray | None:
        return None if self._q_ref is None else self._q_ref.copy()

    def set_target(self, q_ref: ArrayLike) -> None:
        """Track the configuration ``q_ref`` (n,) [rad or m]."""
        self._q_ref = check_vector(q_ref, int(np.size(q_ref)), "q_ref", "[rad or m]")
        _layout_changed()  # (a first target, or another number of joints: checked again)

    def _checked(self, chain: Chain) -> np.ndarray:
        """q_ref, checked against the chain (its size, the joint indices)."""
        n = chain.dof
        if self._q_ref is None:
            raise InputError("Posture has no target: pass q_ref or call set_target", argument="q_ref",
                             value=None)
        if self._q_ref.shape != (n,):
            raise InputError(f"Posture: q_ref has {self._q_ref.size} values, the chain {n} joints",
                             argument="q_ref", value=self._q_ref)
        if self._joints is not None and self._joints.size and not (0 <= self._joints.min()
                                                                   and self._joints.max() < n):
            raise InputError(f"Posture: joints must be indices in [0, {n}), got "
                             f"{self._joints.tolist()}", argument="joints", value=self._joints)
        return self._q_ref

    def _brake(self, chain: Chain, e: np.ndarray, b: np.ndarray, s: float) -> None:
        """``b = s·K·e``, bounded to ``s·v_stop(|e_i|)`` where the error is past e* (see the
        class docstring); e* per joint is kept per (chain limits, gain)."""
        K = self.gain
        c = self._estar
        if c is None or c[0] is not chain or c[1] != K:
            j = slice(None) if self._joints is None else self._joints
            al, jl = chain.amax[j].tolist(), chain.jmax[j].tolist()
            c = self._estar = (chain, K, [_linear_up_to(K, a, jj) for a, jj in zip(al, jl, strict=True)],
                               al, jl)
        estar = c[2]
        el = e.tolist()
        g = self._gain_row
        if g is None or g[0] != K * s or g[1].shape != e.shape:
            g = self._gain_row = (K * s, np.full(e.shape, K * s))
        np.multiply(e, g[1], b)  # (K·s as an array: the numbers of the float's product, cheaper)
        if not any(map(_gt, map(abs, el), estar)):
            return  # every joint within its linear range (the common case)
        al, jl = c[3], c[4]
        for i, (ei, es) in enumerate(zip(el, estar, strict=True)):
            if abs(ei) > es:
                v = min(K * abs(ei), braking_speed_scalar(abs(ei), al[i], jl[i]))
                b[i] = s * math.copysign(v, ei)

    def _row_count(self, chain: Chain, q: np.ndarray) -> int:
        v = self._valid
        if v is None or v[0] is not self._q_ref or v[1] is not chain:  # (checked once per target)
            self._checked(chain)
            self._valid = (self._q_ref, chain, chain.dof if self._joints is None else int(self._joints.size))
            v = self._valid
        return v[2]

    def rows(self, chain: Chain, q: np.ndarray) -> TaskRows:
        """``A = I`` (the rows of ``joints``), ``b = K (q_ref − q)``."""
        return self._filled_rows(chain, q)

    def _fill(self, chain: Chain, q: np.ndarray, A: np.ndarray, b: np.ndarray, e: np.ndarray,
              s: float) -> float:
        """``A = I`` (the rows of ``joints``), ``e = q_ref − q``, ``b = K e`` (scaled by s)."""
        q_ref = self._q_ref  # (checked against the chain by _row_count, asked after every set_target)
        if q_ref is None:
            q_ref = self._checked(chain)  # raises
        j = self._joints
        n = chain.dof
        if j is None:
            np.subtract(q_ref, q, out=e)
        else:
            e[...] = q_ref[j] - q[j]
        self._brake(chain, e, b, s)
        w = self._rows_in
        if w is None or w[0] is not A or w[1] != s or w[2] != n:  # (the controller's level arrays keep them)
            key = (n, s)
            if self._A is None or self._A[0] != key:
                rows = np.eye(n) * s
                self._A = (key, rows if j is None else rows[j])
            A[...] = self._A[1]
            self._rows_in = (A, s, n)
        return math.sqrt(e.dot(e))


def _linear_up_to(K: float, amax: float, jmax: float) -> float:
    """e* [rad or m]: the error up to which ``K·e`` is at most the braking speed
    `braking_speed_scalar` (e, amax, jmax) — where ``K e = (e²·jmax)^{1/3}`` (jmax ≤ amax·K)
    or ``K e = (−k + √(k² + 8·amax·e))/2`` with k = amax²/jmax (otherwise); inf for K = 0
    and without both limits."""
    K3 = K * K * K
    if K3 == 0.0:  # no gain (or one so small that K³ underflows): never bounded
        return math.inf
    if jmax <= amax * K:
        return jmax / K3
    return 2.0 * amax / (K * K) - amax * amax / (jmax * K)
