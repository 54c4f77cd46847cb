"""`Posture`: joint positions (n rows)."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike

from ..errors import InputError
from .base import Task, TaskRows, check_vector

if TYPE_CHECKING:
    from ..model.chain import Chain

__all__ = ["Posture"]


class Posture(Task):
    """Bring the joints to a reference configuration: ``A = I``, ``b = K (q_ref − q)``
    [rad/s or m/s] (n rows; only the joints of ``joints`` when given).

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

    @property
    def has_target(self) -> bool:
        return self._q_ref is not None

    @property
    def target(self) -> np.ndarray | None:
        return None if self._q_ref is None else self._q_ref.copy()

    def set_target(self, q_ref: ArrayLike) -> None:
        """Track the configuration ``q_ref`` (n,) [rad or m]."""
        self._q_ref = check_vector(q_ref, int(np.size(q_ref)), "q_ref", "[rad or m]")

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

    def _row_count(self, chain: Chain, q: np.ndarray) -> int:
        self._checked(chain)
        return chain.dof if self._joints is None else int(self._joints.size)

    def rows(self, chain: Chain, q: np.ndarray) -> TaskRows:
        """``A = I`` (the rows of ``joints``), ``b = K (q_ref − q)``."""
        return self._filled_rows(chain, q)

    def _fill(self, chain: Chain, q: np.ndarray, A: np.ndarray, b: np.ndarray, e: np.ndarray,
              s: float) -> float:
        """``A = I`` (the rows of ``joints``), ``e = q_ref − q``, ``b = K e`` (scaled by s)."""
        q_ref = self._checked(chain)
        j = self._joints
        n = chain.dof
        if j is None:
            np.subtract(q_ref, q, out=e)
        else:
            e[...] = q_ref[j] - q[j]
        np.multiply(e, self.gain * s, out=b)
        key = (n, s)
        if self._A is None or self._A[0] != key:
            rows = np.eye(n) * s
            self._A = (key, rows if j is None else rows[j])
        A[...] = self._A[1]
        return math.sqrt(float(e.dot(e)))
