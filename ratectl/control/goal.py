"""The joint goal of the smoothed approach to a target: where the tool reaches it.

`JointGoal` solves the inverse kinematics of one target pose for the controller's smoothed
approach (`ResolvedRateController`, ``smoothing=True``), which then moves the joints along
the straight line to that goal. A wrong goal is a wrong motion, so the solve is built to be
safe rather than clever:

* a **new target** (one whose error at the last goal exceeds `_JUMP`) is solved from the
  measured joint position q, never from the goal of an earlier target: the goal is the
  solution on the branch the arm is on, found by descent from where it is;
* every step is a **Levenberg–Marquardt** step g ← g + Jᵀ(J Jᵀ + λ²I)⁻¹ e(g) that is kept only
  if it *decreases* ‖e‖ (else λ grows and the step shrinks toward the gradient), so the
  iterates' pose errors never increase and an unreachable target ends at a local
  least-squares best instead of diverging;
* the goal stays **inside the joint range**: first with room to spare (`_COMFORT`, 0.05
  rad or a tenth of the range: a redundant arm's goal does not end on a limit that the
  jerk-limited stop then brushes), and only if the target is not reached that way up to
  `_MARGIN` (1e-6: a target whose joint position is on a limit stays reachable); joints
  at a bound whose step points out are taken out of the step, so the others still move;
  and no joint moves by more than `_STEP_MAX` in one step (a trust region: near a singular
  target the step may be huge);
* the result is **verified**: `JointGoal.reached` is true only when the tool pose at the goal
  is within a tenth of the controller's tolerances; otherwise the goal is the best effort
  (`JointGoal.best_effort` once the descent has stalled).

A target that moved a little (a moving target) continues from the last goal, one step
per cycle; the caller gives the budget of steps per cycle.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from ..spatial import pose_error_into

if TYPE_CHECKING:
    from ..model.chain import Chain

__all__ = ["JointGoal"]

_MARGIN = 1e-6       # the goal stays this far inside a finite position limit [rad or m]
_COMFORT = 0.05      # ... and this far (at most a tenth of the range) unless the target needs it
_JUMP = 1e-3         # a target farther than this from the last goal [m or rad] is new
_STEP_MAX = 0.2      # the largest change of one joint in one step [rad or m] (trust region)
_ERROR_STEP = 0.05   # the largest share of the pose error one step removes [m and rad]
_LAMBDA2_START = 1e-6  # λ² of the first step (λ = 1e-3)
_LAMBDA2_MIN = 1e-12
_LAMBDA2_STALL = 1e4   # λ² past which no step decreases ‖e‖: a (constrained) local best
_CONVERGED = 1e-18   # ‖e‖² at which the goal reaches the target (1e-9 m and rad)
_STALL_GAIN = 1e-10  # an accepted step that decreases ‖e‖² by less than this share: stalled
_MAX_STEPS = 200     # steps per target (a best effort is settled after that)


class JointGoal:
    """The joint position at which the tool reaches a target (see the module docstring).

    Args:
        chain: the arm.
        lower, upper: (n,) position limits (±inf, or a huge finite number, where absent).
        position_tolerance [m], orientation_tolerance [rad]: the controller's "target
            reached" tolerances; the goal is `reached` within a tenth of them.
    """

    def __init__(self, chain: Chain, lower: np.ndarray, upper: np.ndarray, *,
                 position_tolerance: float, orientation_tolerance: float) -> None:
        self.chain = chain
        lower = np.asarray(lower, dtype=float)
        upper = np.asarray(upper, dtype=float)
        span = np.maximum(upper - lower, 0.0)
        margin = np.minimum(_MARGIN, 0.25 * span)
        comfort = np.minimum(_COMFORT, 0.1 * span)
        self._hard = (lower + margin, upper - margin)
        self._comfort = (lower + comfort, upper - comfort)
        self._lo, self._hi = self._comfort
        self._tol_p = 0.1 * float(position_tolerance)
        self._tol_o = 0.1 * float(orientation_tolerance)
        self._e = np.zeros(6)
        self._e_try = np.zeros(6)
        self._eye6 = np.eye(6)
        self._eye4 = np.eye(4)
        self.reset()

    def reset(self) -> None:
        """Forget the goal (the next `update` solves from the measured q)."""
        self.q: np.ndarray | None = None
        self.target: np.ndarray | None = None
        self.settled = False
        self._steps = 0
        self._lambda2 = _LAMBDA2_START
        self._T: np.ndarray = self._eye4
        self._J: np.ndarray | None = None
        self._ee = math.inf
        self.position_error = self.orientation_error = math.inf

    @property
    def reached(self) -> bool:
        """True when the tool pose at the goal is within a tenth of the tolerances."""
        return self.position_error <= self._tol_p and self.orientation_error <= self._tol_o

    @property
    def best_effort(self) -> bool:
        """True when the descent has stalled short of the target: the goal is a local
        least-squares best inside the joint range, not a pose at the target."""
        return self.settled and not self.reached

    def update(self, q: np.ndarray, target: np.ndarray, *, steps: int) -> np.ndarray:
        """The goal for ``target`` after up to ``steps`` more descent steps (none once
        settled: converged or stalled). A new target starts from ``q``."""
        if self.q is None or self.target is None or not np.array_equal(target, self.target):
            self._new_target(q, target)
        if not self.settled:
            self._descend(steps)
        assert self.q is not None
        return self.q

    def _new_target(self, q: np.ndarray, target: np.ndarray) -> None:
        jump = True
        if self.q is not None:
            ep, eo = pose_error_into(self._e, target, self._T)
            jump = ep > _JUMP or eo > _JUMP
        self.target = target.copy()
        if jump:
            self._lo, self._hi = self._comfort
            g = np.minimum(np.maximum(q, self._lo), self._hi)
            self._T, self._J = self.chain.fk_jacobian(g)
            self.q = g
            ep, eo = pose_error_into(self._e, target, self._T)
        self._lambda2 = _LAMBDA2_START
        self._ee = float(self._e @ self._e)
        self.position_error, self.orientation_error = ep, eo
        self.settled = False
        self._steps = 0

    def _descend(self, steps: int) -> None:
        """Up to ``steps`` Levenberg–Marquardt steps that each decrease ‖e‖² (a rejected
        step raises λ and counts)."""
        g, J, e, target = self.q, self._J, self._e, self.target
        assert g is not None and J is not None and target is not None
        for _ in range(steps):
            if self._ee <= _CONVERGED or self._lambda2 > _LAMBDA2_STALL or self._steps >= _MAX_STEPS:
                break
            self._steps += 1
            step = self._step(g, J, e)
            g_try = np.minimum(np.maximum(g + step, self._lo), self._hi)
            T_try, J_try = self.chain.fk_jacobian(g_try)
            ep, eo = pose_error_into(self._e_try, target, T_try)
            ee = float(self._e_try @ self._e_try)
            if ee < self._ee:
                gain = self._ee - ee
                g, J = g_try, J_try
                self.q, self._T, self._J = g, T_try, J_try
                e[:] = self._e_try
                self.position_error, self.orientation_error = ep, eo
                stalled = gain < _STALL_GAIN * self._ee
                self._ee = ee
                self._lambda2 = max(self._lambda2 * 0.1, _LAMBDA2_MIN)
                if stalled:
                    self.settled = True
                    break
            else:
                self._lambda2 *= 10.0
        if self._ee <= _CONVERGED or self._lambda2 > _LAMBDA2_STALL or self._steps >= _MAX_STEPS:
            self.settled = True
        if self.settled and not self.reached and self._lo is self._comfort[0]:
            # not reached with room to spare from the limits: go on up to them
            self._lo, self._hi = self._hard
            self._lambda2 = _LAMBDA2_START
            self._steps = 0
            self.settled = False

    def _step(self, g: np.ndarray, J: np.ndarray, e: np.ndarray) -> np.ndarray:
        """The damped step Jᵀ(J Jᵀ + λ²I)⁻¹ e without the joints held at a bound it would
        push further out, scaled into the trust region."""
        size = math.sqrt(self._ee)
        if size > _ERROR_STEP:  # a step along the straight line to the target, not a leap
            e = e * (_ERROR_STEP / size)
        A = J @ J.T + self._lambda2 * self._eye6
        step = J.T @ np.linalg.solve(A, e)
        out = ((step < 0.0) & (g <= self._lo)) | ((step > 0.0) & (g >= self._hi))
        if out.any():
            Jf = J.copy()
            Jf[:, out] = 0.0
            step = Jf.T @ np.linalg.solve(Jf @ Jf.T + self._lambda2 * self._eye6, e)
        big = float(np.max(np.abs(step)))
        if big > _STEP_MAX:
            step *= _STEP_MAX / big
        return step
