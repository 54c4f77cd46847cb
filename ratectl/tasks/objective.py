"""The null-space objectives of `ratectl.solvers.nullspace` (joint centring, manipulability,
any gradient) as tasks: `Objective`, `JointCentring`, `Manipulability`."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

import numpy as np

from ..errors import InputError
from ..solvers import nullspace
from .base import Task, TaskRows

if TYPE_CHECKING:
    from ..model.chain import Chain

__all__ = ["Objective", "JointCentring", "Manipulability"]


class Objective(Task):
    """A null-space objective as a task: ``A = I``, ``b = K · z(q)`` (n rows), where z(q) is
    the objective's desired joint velocity (−∇H for a cost H, `ratectl.solvers.nullspace`).

    On the lowest level, under a tool task, this is the gradient projection of
    `ratectl.solvers.NullSpace` with the limits as hard constraints.

    Args:
        objective: ``"centring"``, ``"manipulability"``, or a callable q -> (n,) (as for
            `ratectl.solvers.NullSpace`); the string forms are built for the chain at the
            first call.
        priority, weight, gain: see `Task`.
    """

    def __init__(self, objective: Any = "centring", *, priority: int = 1, weight: float = 1.0,
                 gain: float = 1.0) -> None:
        super().__init__(priority=priority, weight=weight, gain=gain)
        if not (isinstance(objective, str) or callable(objective)):
            raise InputError(f"objective must be 'centring', 'manipulability' or a callable q -> (n,), "
                             f"got {objective!r}", argument="objective", value=objective)
        self.objective = objective
        self._built: dict[int, Any] = {}

    def _row_count(self, chain: Chain, q: np.ndarray) -> int:
        return chain.dof

    def rows(self, chain: Chain, q: np.ndarray) -> TaskRows:
        """``A = I``, ``b = K z(q)``."""
        return self._filled_rows(chain, q)

    def _fill(self, chain: Chain, q: np.ndarray, A: np.ndarray, b: np.ndarray, e: np.ndarray,
              s: float) -> float:
        """``A = I``, ``e = z(q)``, ``b = K z(q)`` (scaled by s)."""
        f = self._built.get(id(chain))
        if f is None:
            f = self._built[id(chain)] = _build(self.objective, chain)
        z = np.asarray(f(q), dtype=float)
        n = chain.dof
        if z.shape != (n,) or not np.all(np.isfinite(z)):
            raise InputError(f"the objective must return a finite ({n},) vector, got shape {z.shape}",
                             argument="objective", value=z)
        A[...] = np.eye(n) * s
        e[...] = z
        np.multiply(z, self.gain * s, out=b)
        return math.sqrt(float(z.dot(z)))


def _build(objective: Any, chain: Chain) -> Any:
    if not isinstance(objective, str):
        return objective
    if objective in ("centring", "centering"):
        return nullspace.JointCentring(chain)
    if objective == "manipulability":
        return nullspace.Manipulability(chain)
    raise InputError(f"objective must be 'centring', 'manipulability' or a callable, got {objective!r}",
                     argument="objective", value=objective)


class JointCentring(Objective):
    """Stay near the middle of the joint ranges (`ratectl.solvers.JointCentring`) as a task."""

    def __init__(self, *, priority: int = 1, weight: float = 1.0, gain: float = 1.0) -> None:
        super().__init__("centring", priority=priority, weight=weight, gain=gain)


class Manipulability(Objective):
    """Increase √det(JJᵀ) (`ratectl.solvers.Manipulability`) as a task."""

    def __init__(self, *, priority: int = 1, weight: float = 1.0, gain: float = 1.0) -> None:
        super().__init__("manipulability", priority=priority, weight=weight, gain=gain)
