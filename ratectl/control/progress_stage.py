"""What the straight approach and the jog share: `ProgressStage`.

Both move along one direction at a progress the joint limits and the singularities bound
(`ProgressLimits`): the solver's answer for the direction (`ProgressStage.direction`), the
singularity look-ahead along it (`ProgressStage.exact_direction`), and the status flags and
reasons of the bound that holds the progress (`ProgressStage.flags`, which names the kind
of singularity once per encounter with `ratectl.singularity.analyze`).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

import numpy as np

from ..singularity import analyze
from ..solvers.base import (
    DirectionTwist,
    Solver,
    SolveResult,
    direction_result,
    direction_twist_entry,
    sigma_below,
    solve_direction_generic,
    svd_values,
    thin_svd,
)
from .cycle import Cycle
from .progress import ProgressLimits

if TYPE_CHECKING:
    from ..model.chain import Chain
    from ..model.limits import Limits
    from .smoothing import VelocityFilter

__all__ = ["ProgressStage", "with_kind"]

_SHARE = 0.5  # share of amax (and jmax) the progress of an approach or a jog may use itself
_KIND_NEAR = 0.5  # the σ band in which `analyze` names the singularity a progress stops before


def with_kind(sentence: str, kind: str) -> str:
    """A reason's sentence about "a singularity" naming its ``kind`` ("a wrist singularity")."""
    return sentence.replace("a singularity", f"a {kind} singularity", 1)


class ProgressStage:
    """The progress bounds (``bounds``, a `ProgressLimits`) of ``chain`` under ``limits``
    (jerk-limited with a smoothing ``filter``), stopping at ``stop_sigma`` before a
    singularity whose lost direction the motion heads into; ``solver`` answers for the
    directions. Owns the kind of the singularity being approached (``singular_kind``,
    None when none: the controller clears it after a cycle that met none)."""

    def __init__(self, chain: Chain, solver: Any, limits: Limits | None, filter: VelocityFilter | None,
                 *, stop_sigma: float) -> None:
        self.chain = chain
        self.solver = solver
        jmax = filter.jmax if filter is not None else None  # jerk-limited only when smoothed
        self.bounds = ProgressLimits(chain, limits, jmax=jmax, accel_share=_SHARE, stop_sigma=stop_sigma,
                                     watch_sigma=max(4.0 * stop_sigma, 1e-6))
        self.singular_kind: str | None = None
        self._method = str(getattr(solver, "method", "solver"))
        self._solve_direction = (solver.solve_direction if isinstance(solver, Solver)
                                 else lambda J, d, **kw: solve_direction_generic(solver, J, d, **kw))
        self._direction_twist = direction_twist_entry(solver)

    def direction_qd(self, J: np.ndarray, d: np.ndarray, q: np.ndarray, dt: float
                     ) -> tuple[np.ndarray, Any, float]:
        """``(w, sigma, damping)``: the solver's q̇ per unit of the direction ``d`` without
        the joint limits (`Solver.solve_direction`, the validated entry: exact where J is
        regular), what says σ_min(J) (for `sigma_for_watch`) and the damping w has."""
        return self._solve_direction(J, d, q=q, dt=dt)

    def direction_twist(self, J: np.ndarray, d: np.ndarray, xi: np.ndarray, q: np.ndarray,
                        dt: float) -> DirectionTwist:
        """`direction_qd` for ``d`` and the solver's answer for the twist ``xi`` on the same J,
        both without the joint limits (`Solver.solve_direction_twist`): the servo's
        direction w and its feedback c = solver(J, ξ), from one entry that shares their
        work on J."""
        return self._direction_twist(J, d, xi, q=q, dt=dt)

    def direction_result(self, J: np.ndarray, d: np.ndarray, w: np.ndarray, sigma: Any,
                         damping: float) -> Any:
        """The `SolveResult` of a `direction_qd` answer (a `SolveResult` already when the
        solver gave one): q̇ = w, achieved J w, task error d − J w."""
        if isinstance(sigma, SolveResult):
            return sigma
        return direction_result(J, d, w, damping=damping, sigma_min=sigma, method=self._method)

    def exact_direction(self, q: np.ndarray, d: np.ndarray, J_at: tuple | None = None, *,
                        share: bool = True) -> tuple[float, float, np.ndarray | None]:
        """(σ_min, share, w) at ``q`` from one thin SVD J = U S Vᵀ (`thin_svd`): σ_min(J),
        the share of the exact joint speed |J⁺d|² = Σ (uᵢ·d / σᵢ)² that goes into the
        weakest direction (the singularity look-ahead of `ProgressLimits`: is ``d`` being
        lost?), and that exact joint velocity per unit progress w = J⁺d = V (Uᵀd / S) (None
        where J has lost rank). ``J_at`` = (q₀, J(q₀)): the cycle's own Jacobian, used when
        ``q`` is q₀. ``share=False``: σ_min alone (singular values without vectors), share
        NaN and w None."""
        J = J_at[1] if J_at is not None and q is J_at[0] else self.chain.jacobian(q)
        if J.shape[1] < 6:
            return 0.0, 1.0, None
        if not share:
            S = svd_values(J)
            return (float(S[-1]) if S[-1] > S[0] * 1e-12 else 0.0), math.nan, None
        U, S, Vt = thin_svd(J)
        if not S[-1] > S[0] * 1e-12:
            return 0.0, 1.0, None
        c = d.dot(U) / S
        total = float(c.dot(c))
        return float(S[-1]), (float(c[-1] * c[-1]) / total if total > 0.0 else 0.0), c.dot(Vt)

    def sigma_for_watch(self, sigma: Any) -> float | None:
        """None when σ_min of a direction solve (the ``sigma`` of `direction_qd`) is at least
        the watch threshold, else a number below it (σ_min, or an upper bound of it), which
        `ProgressLimits.caps` compares with the threshold: decided without computing σ_min
        where the solver can, on either side (`sigma_below`)."""
        return sigma_below(sigma, self.bounds.watch_sigma)

    def flags(self, cyc: Cycle, q, caps, moving: bool, at_bound: bool) -> None:
        """Status flags and reasons of a progress bound (approach or jog)."""
        if caps.binding == "singularity" and (at_bound or caps.blocked_by):
            if caps.blocked_by and not moving:
                cyc.flags.append("halted-singularity")
            else:
                cyc.flags.append("approaching-singularity")
            kind = self.singular_kind
            if kind is None:  # named once per encounter: `analyze` with a wide "near" band
                kind = self.singular_kind = str(analyze(self.chain, q, near=_KIND_NEAR).kind)
            cyc.kind = kind
            cyc.reasons.append(with_kind(caps.reason, kind))
            return
        elif caps.binding == "position" and (at_bound or caps.blocked_by):
            cyc.flags.append("joint-limit")
            cyc.reasons.append(caps.reason)
            cyc.active.append("position")
        elif caps.binding in ("velocity", "curvature") and at_bound and moving:
            cyc.flags.append("velocity-scaled")
            cyc.active.append("velocity")
            cyc.reasons.append(f"moving at the speed limit of joint {self.bounds.name(caps.joint)} "
                               "along the commanded direction")

