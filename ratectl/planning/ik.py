"""Inverse kinematics: the joint positions that put the tool at a pose (`ik`).

Damped Newton iterations on the servoing pose error

    e = [p_d − p ; log(R_d Rᵀ)]                         (exact, accurate near π)
    Δq = Jᵀ (J Jᵀ + λ² I)⁻¹ e,   λ = ``damping``
    q ← q + α Δq,   α = min(1, ``max_step`` / max|Δq|)

from a start configuration q0; the step cap keeps the iteration on the branch nearest
q0 (IK of an arm has several solutions; this finds the one the start leads to). For a
redundant arm the damped step is the minimum-norm one. Joint limits are not enforced
during the iteration; the result says whether the solution lies within them.

This is the one IK of the package: ``follow`` uses it to reach a path start, the demo
and the examples to place an arm on a pose.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike

from ..checks import positive_number as _positive
from ..errors import InputError
from ..spatial import pose_error_into, rigid_transform_defect

if TYPE_CHECKING:
    from ..model.chain import Chain

__all__ = ["ik", "IKResult"]


@dataclass(frozen=True, kw_only=True)
class IKResult:
    """The outcome of `ik`.

    Attributes:
        q: the final joint positions (n,) (read-only).
        converged: True when both error norms are within the tolerances.
        position_error: ‖p_d − p‖ at ``q`` [m].
        orientation_error: rotation angle between the desired and reached orientation [rad].
        iterations: Newton iterations taken.
        within_limits: True when ``q`` lies within the chain's position limits.
    """

    q: np.ndarray
    converged: bool
    position_error: float
    orientation_error: float
    iterations: int
    within_limits: bool

    @property
    def error(self) -> tuple[float, float]:
        """(position error [m], orientation error [rad]) at ``q``."""
        return self.position_error, self.orientation_error

    def __str__(self) -> str:
        state = "converged" if self.converged else "NOT converged"
        return (f"IK {state} in {self.iterations} iterations: {self.position_error * 1e3:.3g} mm, "
                f"{math.degrees(self.orientation_error):.3g}° from the target"
                f"{'' if self.within_limits else ', outside the joint limits'}")


def ik(chain: Chain, T_target: Any, q0: ArrayLike, *, tol: float | tuple[float, float] = (1e-9, 1e-9),
       max_iter: int = 200, damping: float = 1e-3, max_step: float = 0.2) -> IKResult:
    """Joint positions q with ``chain.fk(q) ≈ T_target``, by damped Newton steps from ``q0``.

    Args:
        chain: the arm.
        T_target: desired tool pose (4×4 rigid transform, base frame).
        q0: start configuration (n,); the solution found is the one it leads to.
        tol: (position [m], orientation [rad]) tolerances, or one number for both.
        max_iter: most Newton iterations.
        damping: λ of the damped step [m or rad]; small values converge quadratically
            near a regular solution, larger ones are more robust near singularities.
        max_step: largest joint change per iteration [rad or m] (``math.inf``: none).

    Returns:
        An `IKResult`; ``converged`` is False (not an exception) when the target is
        not reached — out of reach, or a singular start that Newton cannot leave.

    Raises:
        InputError: a target that is not a rigid transform, a bad q0 or bad options.
    """
    from ..model.chain import Chain

    if not isinstance(chain, Chain):
        raise InputError(f"chain must be a ratectl.Chain, got {chain!r}"[:200], argument="chain", value=chain)
    defect = rigid_transform_defect(T_target)
    if defect is not None:
        raise InputError(f"T_target {defect}", argument="T_target", value=T_target)
    Td = np.array(T_target, dtype=float)
    q = chain.check_q(q0).astype(float).copy()
    if q.shape != (chain.dof,):
        raise InputError(f"q0 must be one configuration ({chain.dof},), got shape {q.shape}",
                         argument="q0", value=q0)
    if isinstance(tol, int | float | np.floating):
        tols: tuple = (tol, tol)
    elif isinstance(tol, tuple | list | np.ndarray):
        tols = tuple(tol)
    else:
        tols = ()
    if len(tols) != 2:
        raise InputError(f"tol must be a number or a pair (position [m], orientation [rad]), got {tol!r}",
                         argument="tol", value=tol)
    tol_p = _positive("tol", tols[0])
    tol_o = _positive("tol", tols[1])
    damping = _positive("damping", damping)
    max_step = _positive("max_step", max_step, allow_inf=True)
    if not (isinstance(max_iter, int | np.integer) and max_iter >= 0):
        raise InputError(f"max_iter must be a non-negative integer, got {max_iter!r}",
                         argument="max_iter", value=max_iter)
    lam2 = damping**2
    e = np.empty(6)
    it = 0
    T, J = chain.fk_jacobian(q)
    ep, eo = pose_error_into(e, Td, T)
    while it < max_iter and not (ep <= tol_p and eo <= tol_o):
        JJt = J @ J.T
        JJt[np.diag_indices(6)] += lam2
        try:
            step = J.T @ np.linalg.solve(JJt, e)
        except np.linalg.LinAlgError:  # pragma: no cover - JJᵀ + λ²I is positive definite
            break
        big = float(np.max(np.abs(step)))
        if big > max_step:
            step *= max_step / big
        q += step
        it += 1
        T, J = chain.fk_jacobian(q)
        ep, eo = pose_error_into(e, Td, T)
    q.setflags(write=False)
    inside = bool(np.all((q >= chain.lower) & (q <= chain.upper)))
    return IKResult(q=q, converged=bool(ep <= tol_p and eo <= tol_o), position_error=ep,
                    orientation_error=eo, iterations=it, within_limits=inside)
