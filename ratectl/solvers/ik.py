"""The inverse-kinematics iteration core: damped Gauss–Newton (Levenberg–Marquardt) steps
within the joint limits (`ik_iterate`), and seeded, bounded restarts around it
(`ik_search`). `ratectl.ik` (planning) is the user-facing wrapper; a servo may call these
directly, every cycle if it wants, on a start it chooses.

One iteration, from q (inside the limits):

    e   = [ (p_d − p)/L ; log(R_d Rᵀ) ]                 (the servoing pose error, position
                                                         scaled by the chain's
                                                         characteristic length L)
    J_s = [ J_v/L ; J_ω ]                                (the same scaling of the Jacobian,
                                                         columns of joints held at a limit
                                                         that the step would push out: 0)
    Δq  = J_sᵀ (J_s J_sᵀ + λ² I)⁻¹ e = (J_sᵀJ_s + λ² I)⁻¹ J_sᵀ e  (the smaller system),
          α = min(1, max_step / max|Δq|)
    q'  = clip(q + α Δq, lower, upper)

q' is accepted when it lowers ‖e‖ (then λ ← max(λ/3, 1e-9): λ falls below λ₀ on a run of
good steps, so the iteration converges fast also at a singular solution), otherwise
λ ← 10 λ and the
step is retried; the iteration ends when both errors are within the tolerances
(converged), after ``max_iter`` accepted or refused steps, or when λ exceeds 1e6 (a local
minimum of ‖e‖ inside the box or at its faces: not converged). The scaling makes a metre
at the scale of the arm weigh like a radian, so neither part of the pose dominates;
λ₀ = ``damping`` keeps the step bounded near a singularity; the step cap keeps the
iteration on the branch of the start.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike

from ..arrays import read_only
from ..errors import InputError
from ..spatial import pose_error_into

if TYPE_CHECKING:
    from ..model.chain import Chain

__all__ = ["IKIterate", "ik_iterate", "ik_search"]

_LAMBDA_MAX = 1e6  # λ beyond this: no descent direction left (a local minimum)
_LAMBDA_MIN = 1e-9  # λ falls this low after accepted steps (fast convergence at a singular solution)


@dataclass(frozen=True, kw_only=True)
class IKIterate:
    """The outcome of `ik_iterate` / `ik_search`.

    Attributes:
        q: final joint positions (n,) (read-only), inside the joint limits.
        converged: both errors within their tolerances.
        position_error: ‖p_d − p‖ at ``q`` [m].
        orientation_error: rotation angle between R_d and R at ``q`` [rad].
        iterations: steps tried (accepted or refused), over all starts for `ik_search`.
        starts: starts tried (1 for `ik_iterate`).
    """

    q: np.ndarray
    converged: bool
    position_error: float
    orientation_error: float
    iterations: int
    starts: int = 1

    def __post_init__(self) -> None:
        object.__setattr__(self, "q", read_only(self.q))


def ik_iterate(chain: Chain, T_target: np.ndarray, q0: np.ndarray, *, tol_position: float,
               tol_orientation: float, max_iter: int, damping: float, max_step: float) -> IKIterate:
    """Damped Gauss–Newton steps within the joint limits from ``q0`` (see the module
    docstring for the equations).

    A layer below the controller and the planner: the caller has checked its inputs.
    ``T_target`` a rigid 4×4 float array; ``q0`` a finite (n,) float array (clipped into
    the limits first); ``tol_position`` [m], ``tol_orientation`` [rad], ``damping`` λ₀
    (dimensionless, of the scaled problem) and ``max_step`` [rad or m, inf allowed]
    positive; ``max_iter`` ≥ 0. Never raises on a valid call; ``converged`` False says the
    target was not reached from this start (out of reach, or a local minimum).
    """
    lower, upper = chain.lower, chain.upper
    L = chain.characteristic_length
    q = np.minimum(np.maximum(np.array(q0, dtype=float), lower), upper)
    e = np.empty(6)
    T, J = chain.fk_jacobian(q)
    ep, eo = pose_error_into(e, T_target, T)
    es = e.copy()
    es[:3] /= L
    cost = float(es @ es)
    lam = damping
    it = 0
    eye = np.eye(6)
    n = q.shape[0]
    eye_n = np.eye(n)
    while it < max_iter and not (ep <= tol_position and eo <= tol_orientation):
        Js = J.copy()
        Js[:3] /= L
        # a joint at a limit whose unconstrained step would push it further out is held
        # (its column removed), so the others solve the task without it
        g = Js.T @ es  # the descent direction of ½‖e_s‖² is +Jᵀe
        held = ((q <= lower) & (g < 0.0)) | ((q >= upper) & (g > 0.0))
        if held.any():
            Js[:, held] = 0.0
        it += 1
        try:  # the smaller of the two equal forms: (JᵀJ + λ²I)⁻¹Jᵀe for n ≤ 6
            if n <= 6:
                step = np.linalg.solve(Js.T @ Js + (lam * lam) * eye_n, g if not held.any() else Js.T @ es)
            else:
                step = Js.T @ np.linalg.solve(Js @ Js.T + (lam * lam) * eye, es)
        except np.linalg.LinAlgError:  # pragma: no cover - the damped matrix is positive definite
            break
        big = float(np.max(np.abs(step))) if step.size else 0.0
        if not math.isfinite(big):
            break
        if big > max_step:
            step *= max_step / big
        q_new = np.minimum(np.maximum(q + step, lower), upper)
        T_new, J_new = chain.fk_jacobian(q_new)
        e_new = np.empty(6)
        ep_new, eo_new = pose_error_into(e_new, T_target, T_new)
        es_new = e_new.copy()
        es_new[:3] /= L
        cost_new = float(es_new @ es_new)
        if cost_new < cost:
            q, J, e, es, ep, eo, cost = q_new, J_new, e_new, es_new, ep_new, eo_new, cost_new
            lam = max(lam / 3.0, _LAMBDA_MIN)
        else:
            lam *= 10.0
            if lam > _LAMBDA_MAX:
                break
    return IKIterate(q=q, converged=bool(ep <= tol_position and eo <= tol_orientation),
                     position_error=float(ep), orientation_error=float(eo), iterations=it)


def random_starts(chain: Chain, count: int, rng: np.random.Generator) -> np.ndarray:
    """``count`` joint configurations drawn uniformly within the limits (±π for a joint
    without limits), (count, n)."""
    lo = np.where(np.isfinite(chain.lower), chain.lower, -math.pi)
    hi = np.where(np.isfinite(chain.upper), chain.upper, math.pi)
    return lo + (hi - lo) * rng.random((count, chain.dof))


def ik_search(chain: Chain, T_target: np.ndarray, q0: np.ndarray, *, tol_position: float,
              tol_orientation: float, max_iter: int, damping: float, max_step: float,
              restarts: int = 0, seed: int | None = 0, nearest: ArrayLike | None = None) -> IKIterate:
    """`ik_iterate` from ``q0``, then, while none has converged, from up to ``restarts``
    random starts within the limits drawn from ``seed`` (reproducible: the same seed gives
    the same starts). With ``nearest`` (a configuration (n,)): every start is tried and,
    of the converged solutions, the one nearest it (smallest ‖q − nearest‖) is returned —
    the solution on the branch of that configuration.

    Returns the first converged solution (the nearest one with ``nearest``), or, when
    none converged, the attempt that came closest (smallest scaled pose error), with
    ``converged`` False. Inputs as for `ik_iterate` (checked by the caller); ``restarts``
    ≥ 0; ``nearest`` None or a finite (n,) array.
    """
    best: IKIterate | None = None
    best_key: tuple[int, float] = (2, math.inf)
    total = 0
    L = chain.characteristic_length
    ref = None if nearest is None else np.asarray(nearest, dtype=float)
    starts = [np.asarray(q0, dtype=float)]
    if restarts:
        starts += list(random_starts(chain, restarts, np.random.default_rng(seed)))
    tried = 0
    for start in starts:
        tried += 1
        r = ik_iterate(chain, T_target, start, tol_position=tol_position, tol_orientation=tol_orientation,
                       max_iter=max_iter, damping=damping, max_step=max_step)
        total += r.iterations
        if r.converged:  # any converged one beats every unconverged one
            key = (0, 0.0 if ref is None else float(np.linalg.norm(r.q - ref)))
        else:
            key = (1, math.hypot(r.position_error / L, r.orientation_error))
        if key < best_key:
            best, best_key = r, key
        if r.converged and ref is None:
            break
    assert best is not None
    return IKIterate(q=best.q, converged=best.converged, position_error=best.position_error,
                     orientation_error=best.orientation_error, iterations=total, starts=tried)


def check_restarts(restarts: object, seed: object) -> tuple[int, int | None]:
    """(restarts, seed) checked: a non-negative int count and an int seed ≥ 0 or None."""
    if isinstance(restarts, bool) or not isinstance(restarts, int | np.integer) or restarts < 0:
        raise InputError(f"restarts must be a non-negative integer (random starts after q0), got "
                         f"{restarts!r}", argument="restarts", value=restarts)
    if seed is not None and (isinstance(seed, bool) or not isinstance(seed, int | np.integer) or seed < 0):
        raise InputError(f"seed must be a non-negative integer or None, got {seed!r}", argument="seed",
                         value=seed)
    return int(restarts), None if seed is None else int(seed)
