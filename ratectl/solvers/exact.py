"""Undamped inverses: the exact inverse q̇ = J⁻¹ξ and the truncated pseudo-inverse.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from ..errors import InputError, SingularityError
from .base import Solver, _check_finite, _dgesv, _positive, svd_values, thin_svd

__all__ = ['Inverse', 'PseudoInverse']


# --------------------------------------------------------------------------- linear algebra
# --------------------------------------------------------------------------- solvers
class Inverse(Solver):
    """Exact inverse q̇ = J⁻¹ξ for a square J.

    Raises `SingularityError` (carrying ``sigma_min`` and ``tolerance``) when
    σ_min(J) < ``tolerance`` [same units as J's singular values].
    """

    method = "inverse"

    def __init__(self, *, tolerance: float = 1e-6, velocity_policy: str | None = None,
                 task_weights: ArrayLike | None = None, joint_weights: ArrayLike | None = None) -> None:
        super().__init__(velocity_policy=velocity_policy, task_weights=task_weights,
                         joint_weights=joint_weights)
        self.tolerance = _positive("tolerance", tolerance, allow_zero=True)

    def _raw(self, J, xi):
        m, n = J.shape
        if m != n:
            raise InputError(f"the exact inverse needs a square J, got {J.shape}; use "
                             "PseudoInverse, DLS or QP for m != n", argument="J", value=J)
        smin = float(svd_values(J)[-1])
        if not smin >= self.tolerance:
            _check_finite(J, xi)
            raise SingularityError(
                f"J is singular: sigma_min = {smin:.3e} < tolerance {self.tolerance:.1e}; "
                "use a damped solver (DLS, AdaptiveDLS) near singular configurations",
                sigma_min=smin, tolerance=self.tolerance)
        _, _, x, info = _dgesv(J, xi)
        if info != 0:  # pragma: no cover - excluded by the σ_min test
            raise np.linalg.LinAlgError(f"dgesv info {info}")
        return x, 0.0, smin, {}


class PseudoInverse(Solver):
    """Truncated Moore–Penrose pseudo-inverse, any m×n J:

    q̇ = Σ_{σ_i > tol} σ_i⁻¹ v_i u_iᵀ ξ.

    Singular values at or below ``tolerance`` are treated as exactly zero (their
    directions are dropped); ``info["rank"]`` is the number kept. Undamped: the gain
    is 1/σ for the smallest kept σ, unbounded as σ → tol⁺.
    """

    method = "pinv"

    def __init__(self, *, tolerance: float = 1e-6, velocity_policy: str | None = "scale",
                 task_weights: ArrayLike | None = None, joint_weights: ArrayLike | None = None) -> None:
        super().__init__(velocity_policy=velocity_policy, task_weights=task_weights,
                         joint_weights=joint_weights)
        self.tolerance = _positive("tolerance", tolerance, allow_zero=True)

    def _raw(self, J, xi):
        u, s, vt = thin_svd(J)
        keep = s > self.tolerance
        coef = np.zeros_like(s)
        coef[keep] = (xi @ u[:, keep]) / s[keep]
        smin = float(s[-1]) if min(J.shape) == s.shape[0] and s.shape[0] else 0.0
        return coef @ vt, 0.0, smin, {"rank": int(keep.sum()), "singular_values": s}
