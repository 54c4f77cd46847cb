"""Null-space objectives (joint centring, manipulability, any gradient) and the
`NullSpace` solver that projects them (Liégeois 1977).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike

from ..errors import InputError
from .base import Solver, SolveResult, _check_problem, _make_result, _positive, thin_svd

if TYPE_CHECKING:
    from ..model.chain import Chain
    from ..model.limits import Limits

__all__ = ['NullSpace', 'JointCentring', 'Manipulability', 'Gradient']


# --------------------------------------------------------------------------- null space
class JointCentring:
    """Secondary objective: stay near the middle of the joint ranges.

    H(q) = ½ Σ ((q_i − c_i)/r_i)², c = (lower + upper)/2, r = (upper − lower)/2;
    the secondary velocity is z = −∇H = −(q − c)/r² [1/rad]. Joints without finite
    limits are left alone. ``limits`` is a Chain or `Limits`.
    """

    def __init__(self, limits: Limits | Chain) -> None:
        lower = np.asarray(limits.lower, dtype=float)
        upper = np.asarray(limits.upper, dtype=float)
        finite = np.isfinite(lower) & np.isfinite(upper)
        lower, upper = np.where(finite, lower, -1.0), np.where(finite, upper, 1.0)  # no inf − inf
        self.centre = np.where(finite, 0.5 * (lower + upper), 0.0)
        half = 0.5 * (upper - lower)
        self._w = np.where(finite, 1.0 / half**2, 0.0)

    def cost(self, q: ArrayLike) -> float:
        """H(q), dimensionless."""
        d = np.asarray(q, dtype=float) - self.centre
        return 0.5 * float(d @ (self._w * d))

    def __call__(self, q) -> np.ndarray:
        return -self._w * (np.asarray(q, dtype=float) - self.centre)


class Manipulability:
    """Secondary objective: increase the manipulability w(q) = √det(JJᵀ) of ``chain``;
    z = ∇w(q) from `ratectl.singularity.manipulability_gradient`."""

    def __init__(self, chain: Chain) -> None:
        self.chain = chain

    def __call__(self, q) -> np.ndarray:
        from ..singularity import manipulability_gradient

        return np.asarray(manipulability_gradient(self.chain, q), dtype=float)


class Gradient:
    """Secondary objective from a user gradient ``f(q) -> (n,)`` of a cost H(q).

    ``maximize=False`` (default) descends the cost (z = −∇H); ``True`` ascends it.
    """

    def __init__(self, f: Any, *, maximize: bool = False) -> None:
        if not callable(f):
            raise InputError(f"Gradient needs a callable f(q) -> (n,), got {f!r}", argument="f",
                             value=f)
        self.f = f
        self.sign = 1.0 if maximize else -1.0

    def __call__(self, q) -> np.ndarray:
        return self.sign * np.asarray(self.f(q), dtype=float)


def _objective(objective, chain):
    if isinstance(objective, str):
        if chain is None:
            raise InputError(f"objective {objective!r} needs chain= (for the joint limits or the "
                             "manipulability gradient)", argument="chain", value=None)
        if objective in ("centring", "centering"):
            return JointCentring(chain)
        if objective == "manipulability":
            return Manipulability(chain)
        raise InputError("objective must be 'centring', 'manipulability', a JointCentring/"
                         f"Manipulability/Gradient object or a callable; got {objective!r}",
                         argument="objective", value=objective)
    if callable(objective):
        return objective
    raise InputError(f"objective must be a string or a callable q -> (n,), got {objective!r}",
                     argument="objective", value=objective)


class NullSpace(Solver):
    """A primary solver plus a secondary objective in the null space of J (Liégeois 1977):

    q̇ = q̇_primary + k·(I − J⁺J)·z(q),

    where z(q) is the objective's joint velocity (−∇H for a cost H) and J⁺ is the
    **undamped, truncated** pseudo-inverse (singular values ≤ ``tolerance`` dropped).
    With that projector J(I − J⁺J) = 0 up to the dropped σ's, so the secondary motion
    never leaks into the task even when the primary solver is damped (a damped J⁺
    would give J(I − J⁺_λ J) ≠ 0). Needs ``q=`` in `solve`.

    Args:
        primary: any solver (called without limits, so its velocity policy does not act;
            this wrapper's policy applies to the sum). A QP primary gets the limits, but
            the added null-space motion is not bounded by them: for a limit-aware
            secondary objective use ``QP(objective=...)``.
        objective: ``"centring"``, ``"manipulability"`` (both need ``chain``), a
            `JointCentring`, `Manipulability` or `Gradient`, or any
            callable q -> (n,) returning the desired secondary joint velocity.
        gain: k [1/s], the gain on z.
        chain: the chain, for the string objectives.
        tolerance: truncation tolerance of the projector's pseudo-inverse.
    """

    method = "nullspace"

    def __init__(self, primary: Solver, objective: Any = "centring", *, gain: float = 1.0,
                 chain: Chain | None = None, tolerance: float = 1e-6,
                 velocity_policy: str | None = "scale") -> None:
        super().__init__(velocity_policy=velocity_policy)
        if not isinstance(primary, Solver):
            raise InputError(f"primary must be a ratectl solver, got {primary!r}",
                             argument="primary", value=primary)
        self.primary = primary
        self.objective = _objective(objective, chain)
        self.gain = _positive("gain", gain, allow_zero=True)
        self.tolerance = _positive("tolerance", tolerance, allow_zero=True)
        self.method = f"nullspace({primary.method})"

    def solve(self, J: np.ndarray, xi: np.ndarray, *, limits: Limits | Chain | None = None,
              q: ArrayLike | None = None, qd_prev: ArrayLike | None = None,
              dt: float | None = None) -> SolveResult:
        """As `Solver.solve`; ``q`` (n,) is required for the objective."""
        J, xi, _ = _check_problem(J, xi)
        m, n = J.shape
        if q is None:
            raise InputError("NullSpace.solve needs q= (the joint positions) for its secondary "
                             "objective", argument="q", value=None)
        q = np.asarray(q, dtype=float)
        if q.shape != (n,) or not np.all(np.isfinite(q)):
            raise InputError(f"q must be a finite ({n},) vector, got shape {q.shape}", argument="q",
                             value=q)
        # the primary's velocity policy acts only with limits: pass none (this wrapper applies
        # its policy to the sum), except to a QP, whose bounds are part of its solution
        p = self.primary.solve(J, xi, limits=limits if self.primary.method == "qp" else None, q=q,
                               qd_prev=qd_prev, dt=dt)
        z = np.asarray(self.objective(q), dtype=float)
        if z.shape != (n,) or not np.all(np.isfinite(z)):
            raise InputError(f"the secondary objective must return a finite ({n},) vector, got "
                             f"shape {z.shape}", argument="objective", value=z)
        _, s, vt = thin_svd(J)
        Vr = vt[s > self.tolerance]
        zp = z - (z @ Vr.T) @ Vr
        qd = p.qd + self.gain * zp
        info = dict(p.info)
        info.update(secondary=self.gain * zp, primary_qd=p.qd, rank=int(Vr.shape[0]))
        policy, scale, bound, active = "none", 1.0, np.zeros(n, dtype=bool), ()
        if limits is not None and self.velocity_policy is not None:
            qd, policy, scale, bound, active = self._policy(qd, limits, n)
        return _make_result(qd, J, xi, p.damping, p.sigma_min, self.method, policy, scale, bound,
                            active, p.fallback, info)
