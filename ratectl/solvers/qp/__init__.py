"""The QP solver and its parts: bounds, exact active-set steps, warm OSQP.

Inverse velocity as a quadratic program, with joint position, velocity and
acceleration limits.

The QP, over q̇ (n,):

    minimise    ½‖W_x^{1/2}(J q̇ − ξ)‖² + ½λ² q̇ᵀ W_q q̇ + ½μ‖q̇ − z(q)‖²
    subject to  l ≤ q̇ ≤ u          (velocity, position and acceleration bounds)
                G q̇ ≤ h            (optional extra rows, e.g. mink's collision limits)

i.e. P = JᵀW_xJ + λ²W_q + μI and c = −JᵀW_xξ − μz. The box [l, u] is the
intersection, per joint, of

* the velocity limit: −vmax ≤ q̇ ≤ vmax;
* the position limit turned into a velocity bound for the step dt with a margin m and
  a braking term that respects the acceleration limit a = amax: with the distance
  d = upper − m − q (resp. q − lower − m), q̇ ≤ v_stop(d) (resp. q̇ ≥ −v_stop(d)), where
  v_stop(d) is the largest speed that, held for this period, still leaves room to brake
  at a: v·dt + v²/(2a) ≤ d, v_stop = 2d/(dt + √(dt² + 2d/a))
  (`ratectl.model.limits.braking_speed_any_dt`). For small d it is d/dt (stop exactly at
  the limit this step), and it is consistent with the acceleration bound for **any** next
  period dt′ (from v_stop(d) the next step's bound is ≥ v_stop − a·dt′), so a joint
  braking into a limit never makes the box empty, even when dt changes every step.
  Beyond a limit (d < 0) the bound moves the joint back (within vmax and amax, never
  further out: `speed_toward_limit`). Without ``dt`` the continuous √(2a·d) is used;
* the acceleration limit given the previous command: |q̇ − q̇_prev| ≤ amax·dt.

When the bounds conflict (e.g. moving too fast toward a limit to stop within the
acceleration limit), priority is velocity > position > acceleration: the box becomes the
point of the higher-priority box nearest to the lower-priority one, and the result says
so in ``info["conflicts"]``.

Before any backend runs, the unconstrained minimiser P⁻¹b (the DLS solution) is tried:
when it lies inside the box (and satisfies G q̇ ≤ h) it is the optimum
(``info["status"] == "unconstrained"``). For a box-only problem on the default backend a
few primal active-set steps follow (`_box_active_set`); their answer is accepted
only with a KKT certificate (``"active-set"``); when they do not settle within four steps
or their answer fails the certificate (an ill-conditioned P), OSQP answers.

Every answer to a box-only problem is certified before it is returned: it must lie in
its box and satisfy the KKT conditions
(`kkt_violation` ≤ 1e-9, scaled); an OSQP answer
that does not — OSQP stops at its tolerances and can say ``solved`` while far from the
optimum with ill-conditioned task weights — is replaced by the exact solution of a
feasible primal active-set method (`box_qp_exact`,
``"exact-active-set"``), which also answers when OSQP fails. With extra rows the OSQP
answer is replaced by the exact solution on its active set when that passes the KKT
check (`polish_general`); when OSQP fails, a cold retry, the dual (`qp_via_dual`) and a
primal active-set method from a feasible point (`qp_primal_active_set`) follow, so only a
problem whose rows and box have no common point raises. ``info["certified"]``
says how the answer was certified. With ``qd_ff`` (a feed-forward the caller adds) the
box is that of the total q̇_ff + q̇.

The default backend is OSQP kept **warm**: the problem is set up once with a fixed
sparsity pattern (P upper-triangular dense, A = [I; G]) and every later call only
updates P's values, q, l, u (and A's values when G is given), then solves, warm-started
from the previous solution. Re-setup happens only when the structure changes (n, or
the number of extra rows). Tolerances are explicit (1e-7; OSQP's own polishing is off —
OSQP 1.x prints to stdout from it regardless of ``verbose`` — and ratectl solves the
active set exactly itself), and the final q̇ is clipped into [l, u] when it is outside
by less than ``tolerance``: limits hold to 1e-6. Other backends (``"daqp"``,
``"quadprog"``, ``"proxqp"``, …) are called through `qpsolvers.solve_qp`.
"""

from .bounds import VelocityBounds, joint_velocity_bounds
from .qp import QP

__all__ = ["QP", "joint_velocity_bounds", "VelocityBounds"]
