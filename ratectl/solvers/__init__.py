"""Inverse velocity: from a desired twist ξ to joint velocities q̇.

Every solver is an object with the same call::

    result = solver.solve(J, xi, *, limits=None, q=None, qd_prev=None, dt=None)

and returns a frozen `SolveResult`. ``limits`` is anything with the arrays
``lower``, ``upper``, ``vmax``, ``amax`` (a `Chain` works, or
`Limits`). Non-QP solvers use only ``vmax``, through their velocity-limit
policy (``"scale"``: scale q̇ uniformly so that no joint exceeds its limit, which keeps
the direction of motion; ``"clip"``: clip each joint; ``None``: ignore the limits).
The QP (`ratectl.solvers.QP`) also uses ``q`` and ``dt``
(position limits) and ``qd_prev`` and ``dt`` (acceleration limits);
`NullSpace` uses ``q`` for its secondary objective.

Solvers (m task rows, n joints; σ_i, u_i, v_i are the singular values and left/right
singular vectors of J):

* `Inverse` — q̇ = J⁻¹ξ (square J); raises `SingularityError`.
* `PseudoInverse` — q̇ = Σ_{σ_i > tol} σ_i⁻¹ v_i u_iᵀ ξ (truncated).
* `DLS` — q̇ = Jᵀ(JJᵀ + λ²I)⁻¹ξ, fixed λ; ‖q̇‖ ≤ ‖ξ‖/(2λ).
* `AdaptiveDLS` — λ scheduled on σ_min (``mode="sigma"``), per direction
  (``mode="filtered"``) or on the manipulability (``mode="manipulability"``).
* `SDLS` — selectively damped least squares (Buss & Kim 2005).
* `NullSpace` — a primary solver plus a secondary objective projected into the
  null space of J (Liégeois 1977).

Task weights (``task_weights=``: a (m,) vector, ``"position"`` or ``"orientation"``)
and joint weights (``joint_weights=``: a (n,) vector) are constructor options of every
solver: they solve min ‖J q̇ − ξ‖²_Wx + λ² q̇ᵀ W_q q̇ (rows of weight 0 are dropped).
"""

from ..model.limits import Limits
from .base import ORIENTATION_ONLY, POSITION_ONLY, VELOCITY_POLICIES, Solver, SolveResult
from .damped import DLS, SDLS, AdaptiveDLS, adaptive_damping
from .exact import Inverse, PseudoInverse
from .nullspace import Gradient, JointCentring, Manipulability, NullSpace
from .qp import QP, VelocityBounds, joint_velocity_bounds

__all__ = [
    "Limits", "SolveResult", "Solver", "Inverse", "PseudoInverse", "DLS", "AdaptiveDLS", "SDLS",
    "NullSpace", "JointCentring", "Manipulability", "Gradient", "QP", "POSITION_ONLY",
    "ORIENTATION_ONLY", "VELOCITY_POLICIES", "adaptive_damping", "joint_velocity_bounds",
    "VelocityBounds",
]
