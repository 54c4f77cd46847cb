"""Inverse kinematics: the joint positions that put the tool at a pose (`ik`).

`ik` checks its arguments and calls the iteration core `ratectl.solvers.ik` (damped
Gauss–Newton steps on the servoing pose error e = [p_d − p; log(R_d Rᵀ)] within the
joint limits, see there): from q0 first, the step cap keeping the iteration on the
branch of q0 (IK of an arm has several solutions); then, with ``restarts``, from
seeded random starts within the limits until one converges; with ``nearest``, the
converged solution nearest a given configuration. For a redundant arm the damped step
is the minimum-norm one.

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
from ..checks import real_array
from ..errors import InputError
from ..solvers.ik import check_restarts, ik_search
from ..spatial import rigid_transform_defect

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
        iterations: Newton iterations taken (over all starts).
        within_limits: True when ``q`` lies within the chain's position limits (always,
            since the iteration stays within them).
        starts: starts tried: 1 (q0) plus the random restarts used.
    """

    q: np.ndarray
    converged: bool
    position_error: float
    orientation_error: float
    iterations: int
    within_limits: bool
    starts: int = 1

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
       max_iter: int = 200, damping: float = 1e-3, max_step: float = 0.2, restarts: int = 0,
       seed: int | None = 0, nearest: ArrayLike | None = None) -> IKResult:
    """Joint positions q within the joint limits with ``chain.fk(q) ≈ T_target``, by damped
    Gauss–Newton steps from ``q0`` (and from random restarts when asked).

    Args:
        chain: the arm.
        T_target: desired tool pose (4×4 rigid transform, base frame).
        q0: start configuration (n,), clipped into the limits; without ``nearest`` the
            solution it leads to is returned when it converges.
        tol: (position [m], orientation [rad]) tolerances, or one number for both.
        max_iter: most iterations per start.
        damping: λ₀, the least damping of the step (of the length-scaled problem,
            dimensionless); small values converge quadratically near a regular solution.
        max_step: largest joint change per iteration [rad or m] (``math.inf``: none).
        restarts: how many random starts within the limits to try after q0 while none
            has converged (0: q0 only). ``rc.ik(arm, T, q, restarts=20)`` finds nearly
            every reachable pose.
        seed: seed of the random starts (the same seed, the same starts); None: fresh.
        nearest: a configuration (n,): try every start and return, of the converged
            solutions, the one nearest it (the solution on its branch).

    Returns:
        An `IKResult`; ``converged`` is False (not an exception) when no start reached
        the target — out of reach, or local minima from every start; ``q`` is then the
        closest attempt.

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
    if isinstance(max_iter, bool) or not (isinstance(max_iter, int | np.integer) and max_iter >= 0):
        raise InputError(f"max_iter must be a non-negative integer, got {max_iter!r}",
                         argument="max_iter", value=max_iter)
    restarts, seed = check_restarts(restarts, seed)
    ref = None
    if nearest is not None:
        ref = real_array("nearest", nearest, f"a ({chain.dof},) configuration")
        if ref.shape != (chain.dof,) or not np.all(np.isfinite(ref)):
            raise InputError(f"nearest must be a finite ({chain.dof},) configuration, got {nearest!r}"[:200],
                             argument="nearest", value=nearest)
    r = ik_search(chain, Td, q, tol_position=tol_p, tol_orientation=tol_o, max_iter=int(max_iter),
                  damping=damping, max_step=max_step, restarts=restarts, seed=seed, nearest=ref)
    inside = bool(np.all((r.q >= chain.lower) & (r.q <= chain.upper)))
    return IKResult(q=r.q, converged=r.converged, position_error=r.position_error,
                    orientation_error=r.orientation_error, iterations=r.iterations, within_limits=inside,
                    starts=r.starts)
