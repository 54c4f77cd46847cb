"""The pose error and the inverse-velocity solve of a cycle that is neither a servo nor a
jog (a target with a feed-forward, a twist with q̇_ff): `SolveStage`. The servo and the jog
call its ``solve`` for their own twists."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

from ..arrays import shared_zeros
from ..errors import RatectlError, SingularityError
from ..spatial import pose_error_into
from .cycle import Cycle, Motion, _finite_sum

if TYPE_CHECKING:
    from ..model.chain import Chain
    from ..model.limits import Limits
    from .command import Command
    from .smoothing import VelocityFilter

__all__ = ["SolveStage"]


class SolveStage:
    """ξ = ξ_ff + K·e and q̇ = q̇_ff + solver(J, ξ) through the solver's validated entry
    (``entry``, `Solver.solve_validated`) under ``limits``; the previous q̇ (``motion``) is
    the acceleration bound's reference unless a smoothing ``filter`` bounds the
    acceleration itself; ``halt(q, dt, reason, ...)`` makes the halt's command."""

    def __init__(self, chain: Chain, *, gain: np.ndarray, entry: Any, limits: Limits | None,
                 motion: Motion, filter: VelocityFilter | None, halt: Any, enforcing: bool) -> None:
        self.chain = chain
        self._enforcing = enforcing
        self.gain = gain
        self._entry = entry
        self.limits = limits
        self._m = motion
        self.filter = filter
        self._halt = halt

    def error(self, q, target, twist) -> Cycle:
        """fk and J at q, the pose error e = [p_d − p; log(R_d Rᵀ)] and the twist
        ξ = ξ_ff + K e to resolve; returns the cycle's working state."""
        cyc = Cycle()
        cyc.target = target is not None
        if target is not None:
            T, cyc.J = self.chain.fk_jacobian(q)
            e = cyc.e = np.zeros(6)
            cyc.ep, cyc.eo = pose_error_into(e, target, T)
            xi = self.gain * e
            if twist is not None:
                xi += twist
        else:
            # no target: J alone (its kernel shares fk_jacobian's expressions: the same J, and
            # no pose to build), and no error (the Command's, read-only for good)
            cyc.J = self.chain.jacobian(q)
            cyc.e = shared_zeros(6)
            cyc.ep = cyc.eo = 0.0
            xi = twist.copy() if twist is not None else np.zeros(6)
        cyc.xi = xi
        return cyc

    def solve(self, cyc: Cycle, q, dt, qd_ff, *, bounded: bool = True) -> Command | None:
        """q̇ = q̇_ff + solver(J, ξ); a solver failure or a non-finite answer halts (returns
        the halt's Command), otherwise fills ``cyc.qd``, ``cyc.res`` and the status lists.
        ``bounded=False``: the solver answers without the limits (the servo's feedback,
        whose direction no box or velocity policy may turn: the limiter then scales the
        whole command)."""
        # with smoothing the filter bounds the acceleration (and the jerk) of what is
        # commanded; a solver's acceleration box around the filter's lagging output would
        # throttle it (the QP's answer at q̇_f ± amax·dt keeps Ruckig's target within one
        # period of its state: the arm then accelerates at a fraction of amax)
        qd_prev = self._m.qd if self.filter is None else None
        limits = self.limits
        enforced = self._enforcing
        if not bounded:
            limits = qd_prev = None
            enforced = False
        try:
            # the solver's entry for validated inputs (`Solver.solve_validated`): q, dt and
            # q̇_ff were checked by this cycle, the previous q̇ is this controller's finite
            # state, J and ξ its own float arrays; it returns the correction on top of q̇_ff
            res = self._entry(cyc.J, cyc.xi, limits=limits, q=q, qd_prev=qd_prev, dt=dt, qd_ff=qd_ff)
        except SingularityError as err:
            return self._halt(q, dt, f"singular: {err}", status="singular", sigma_min=err.sigma_min,
                              error=cyc.e, ep=cyc.ep, eo=cyc.eo)
        except (RatectlError, np.linalg.LinAlgError) as err:
            return self._halt(q, dt, f"solver failed: {err}", error=cyc.e, ep=cyc.ep, eo=cyc.eo)
        qd = res.qd if qd_ff is None else res.qd + qd_ff
        halt = self.adopt(cyc, q, dt, res, qd, enforced)
        if halt is None:
            cyc.res = res
        return halt

    def adopt(self, cyc: Cycle, q, dt, res: Any, qd: np.ndarray, enforced: bool = False) -> Command | None:
        """Take the solver's answer q̇ = ``qd`` (its velocity policy, scale and active limits
        from ``res``, a `SolveResult` or a `DirectionTwist`) as the cycle's command: the halt's
        Command for a non-finite q̇, else None with ``cyc.qd`` and the status lists filled
        (``cyc.res`` is the caller's). The unbounded feedback of a servo, solved beside its
        direction (`Solver.solve_direction_twist`), is taken here too."""
        if not _finite_sum(qd):
            return self._halt(q, dt, "solver returned a non-finite q̇", error=cyc.e, ep=cyc.ep, eo=cyc.eo)
        cyc.qd = qd
        cyc.enforced = enforced
        cyc.active = list(res.limits_active)
        cyc.scale = float(res.velocity_scale)
        cyc.smin = None  # σ_min: read from res only when needed (a QP computes it lazily)
        if res.velocity_policy != "none":
            cyc.flags.append("velocity-scaled")
        return None
