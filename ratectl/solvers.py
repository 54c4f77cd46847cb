"""Inverse velocity: from a desired twist ξ to joint velocities q̇.

Every solver is an object with the same call::

    result = solver.solve(J, xi, *, limits=None, q=None, qd_prev=None, dt=None)

and returns a frozen :class:`SolveResult`. ``limits`` is anything with the arrays
``lower``, ``upper``, ``vmax``, ``amax`` (a :class:`~ratectl.chain.Chain` works, or
:class:`Limits`). Non-QP solvers use only ``vmax``, through their velocity-limit
policy; the QP (:mod:`ratectl.qp`) also uses ``q`` and ``dt`` (position limits) and
``qd_prev`` and ``dt`` (acceleration limits).

This module is the skeleton of the contract shared by the controller; the full
family (pseudo-inverse, adaptive and selective damping, weights, null space) is
built on :class:`Solver`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from .errors import InputError, SingularityError

__all__ = ["Limits", "SolveResult", "Solver", "Inverse", "DLS"]

VELOCITY_POLICIES = ("scale", "clip", None)


@dataclass(frozen=True)
class Limits:
    """Joint limits in SI units; ±inf where absent. Shapes (n,)."""

    lower: np.ndarray
    upper: np.ndarray
    vmax: np.ndarray
    amax: np.ndarray

    @classmethod
    def of(cls, obj, n: int) -> Limits:
        """Limits from a Chain, a Limits, or None (unlimited)."""
        if obj is None:
            inf = np.full(n, math.inf)
            return cls(-inf, inf, inf, inf)
        try:
            arrs = [np.asarray(getattr(obj, k), dtype=float) for k in ("lower", "upper", "vmax", "amax")]
        except AttributeError:
            raise InputError("limits must have arrays lower, upper, vmax, amax (a Chain or "
                             f"ratectl.solvers.Limits), got {type(obj).__name__}",
                             argument="limits", value=obj) from None
        for a in arrs:
            if a.shape != (n,):
                raise InputError(f"limits must have one value per joint ({n}), got shape {a.shape}",
                                 argument="limits", value=obj)
        return cls(*arrs)


@dataclass(frozen=True)
class SolveResult:
    """What an inverse-velocity solver returns.

    Attributes:
        qd: joint velocities (n,) [rad/s or m/s].
        achieved: the twist actually produced, ``J q̇`` (m,).
        task_error: ``ξ − J q̇`` (m,): what the solver gave up (damping, limits).
        damping: damping λ used (0 for undamped solutions).
        sigma_min: smallest singular value of J (of the weighted J for weighted solvers).
        method: solver name ("inverse", "dls", ...).
        velocity_policy: the velocity-limit policy *applied*: "none", "scaled" or "clipped".
        velocity_scale: the uniform factor applied by "scaled" (1.0 otherwise).
        bound: (n,) booleans, joints that sit at an active bound.
        limits_active: which kinds of limit bound: subset of
            ("velocity", "position", "acceleration").
        fallback: True when the requested method failed and a fallback answered.
        info: extra numbers (solver-specific), e.g. iteration counts.
    """

    qd: np.ndarray
    achieved: np.ndarray
    task_error: np.ndarray
    damping: float
    sigma_min: float
    method: str
    velocity_policy: str = "none"
    velocity_scale: float = 1.0
    bound: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=bool))
    limits_active: tuple[str, ...] = ()
    fallback: bool = False
    info: dict = field(default_factory=dict)


def _check_problem(J, xi):
    J = np.asarray(J, dtype=float)
    xi = np.asarray(xi, dtype=float)
    if J.ndim != 2:
        raise InputError(f"J must be a 2-D (m, n) matrix, got shape {J.shape}", argument="J", value=J)
    if xi.shape != (J.shape[0],):
        raise InputError(f"xi must have shape ({J.shape[0]},) to match J {J.shape}, got {xi.shape}",
                         argument="xi", value=xi)
    if not (np.all(np.isfinite(J)) and np.all(np.isfinite(xi))):
        raise InputError("J and xi must be finite", argument="xi", value=xi)
    return J, xi


class Solver:
    """Base class: validation, the velocity-limit policy and the result.

    Subclasses implement ``_raw(J, xi) -> (qd, damping, sigma_min, info)``.
    """

    method = "base"

    def __init__(self, *, velocity_policy: str | None = "scale") -> None:
        if velocity_policy not in VELOCITY_POLICIES:
            raise InputError(f"velocity_policy must be one of {VELOCITY_POLICIES}, "
                             f"got {velocity_policy!r}", argument="velocity_policy",
                             value=velocity_policy)
        self.velocity_policy = velocity_policy

    def _raw(self, J, xi):  # pragma: no cover - abstract
        raise NotImplementedError

    def solve(self, J, xi, *, limits=None, q=None, qd_prev=None, dt=None) -> SolveResult:
        """Joint velocities for the twist ``xi`` (see the module docstring)."""
        J, xi = _check_problem(J, xi)
        n = J.shape[1]
        qd, damping, sigma_min, info = self._raw(J, xi)
        policy, scale = "none", 1.0
        bound = np.zeros(n, dtype=bool)
        active: tuple[str, ...] = ()
        if limits is not None and self.velocity_policy is not None:
            vmax = Limits.of(limits, n).vmax
            ratio = np.abs(qd) / vmax
            worst = float(np.max(ratio)) if n else 0.0
            if worst > 1.0:
                active = ("velocity",)
                if self.velocity_policy == "scale":
                    scale = 1.0 / worst
                    qd = qd * scale
                    policy = "scaled"
                    bound = ratio >= worst * (1 - 1e-12)
                else:
                    bound = ratio > 1.0
                    qd = np.clip(qd, -vmax, vmax)
                    policy = "clipped"
        achieved = J @ qd
        return SolveResult(qd=qd, achieved=achieved, task_error=xi - achieved, damping=damping,
                           sigma_min=sigma_min, method=self.method, velocity_policy=policy,
                           velocity_scale=scale, bound=bound, limits_active=active, info=info)


class Inverse(Solver):
    """Exact inverse q̇ = J⁻¹ξ for a square J; raises :class:`SingularityError` when
    σ_min(J) < ``tolerance``."""

    method = "inverse"

    def __init__(self, *, tolerance: float = 1e-6, velocity_policy: str | None = None) -> None:
        super().__init__(velocity_policy=velocity_policy)
        self.tolerance = float(tolerance)

    def _raw(self, J, xi):
        m, n = J.shape
        if m != n:
            raise InputError(f"the exact inverse needs a square J, got {J.shape}; use "
                             "PseudoInverse, DLS or QP for m != n", argument="J", value=J)
        s = np.linalg.svd(J, compute_uv=False)
        smin = float(s[-1])
        if smin < self.tolerance:
            raise SingularityError(
                f"J is singular: sigma_min = {smin:.3e} < tolerance {self.tolerance:.1e}; "
                "use a damped solver (DLS, AdaptiveDLS) near singular configurations",
                sigma_min=smin, tolerance=self.tolerance)
        return np.linalg.solve(J, xi), 0.0, smin, {}


class DLS(Solver):
    """Damped least squares with a fixed λ: q̇ = Jᵀ(JJᵀ + λ²I)⁻¹ξ, so ‖q̇‖ ≤ ‖ξ‖/(2λ)."""

    method = "dls"

    def __init__(self, *, damping: float = 0.05, velocity_policy: str | None = "scale") -> None:
        super().__init__(velocity_policy=velocity_policy)
        if not (damping > 0 and math.isfinite(damping)):
            raise InputError(f"damping must be a positive number, got {damping!r}",
                             argument="damping", value=damping)
        self.damping = float(damping)

    def _raw(self, J, xi):
        m = J.shape[0]
        lam2 = self.damping**2
        A = J @ J.T
        A[np.diag_indices(m)] += lam2
        qd = J.T @ np.linalg.solve(A, xi)
        return qd, self.damping, float("nan"), {}
