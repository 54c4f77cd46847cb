"""The resolved-rate controller: one call per control cycle.

``ctrl.step(q, target=T_des, twist=ξ_ff, dt=dt)`` computes

    e  = [p_d − p ; log(R_d Rᵀ)]              (pose error, base axes)
    ξ  = ξ_ff + K e                           (feed-forward plus proportional feedback)
    q̇  = q̇_ff + solver(J(q), ξ)               (inverse velocity; q̇_ff optional)

then, for pure servoing (a target, no feed-forward), shapes the approach so that the arm
can always still stop at the target within its joint limits (see ``_approach``: the
feedback is scaled so each joint can brake within its remaining travel J⁺e; with smoothing,
a one-DOF Ruckig profile on the progress ‖e‖ gives the speed and the acceleration the
filter then follows without lag), and applies the limits in this order: velocity (uniform
scaling, which keeps the direction of motion), acceleration (the change of q̇ per cycle is
scaled to fit amax·dt), joint position (each joint may only move as fast as it can still
stop before its limit at amax in whole periods, ``braking_speed_discrete``; without an
acceleration limit that is d/dt, so the velocity limit alone enforces the range). A solver
that enforces the limits itself (the QP, ``enforces_limits = True``) is not limited again:
its bounds and any extra rows (collision limits) are kept as solved and only reported.
Then the controller optionally smooths the result with a Ruckig velocity filter
(jerk-limited) and integrates ``q_next = q + q̇ dt`` (or Ruckig's exact integral).

Every call returns a frozen `Command` whose ``status`` says what happened
(see `STATUSES`). Bad *values* never raise in the loop: a non-finite q,
target, twist or dt, a target that is not a rigid pose (scaled, mirrored), a target older
than ``timeout``, or a solver failure brings a
**safe halt** — the previous q̇ decelerates to zero within the acceleration (and, with
smoothing, jerk) limits — with the reason in ``Command.reason``. A non-finite input
latches the halt until `ResolvedRateController.reset`; a stale target or a
solver failure does not (the next good cycle resumes). Wrong *shapes* are programming
errors and raise `InputError` at once.
"""

from __future__ import annotations

import math
from operator import mul as _mul
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike

from .. import solvers
from ..errors import InputError, RatectlError, SingularityError
from ..model.limits import (
    Limits,
    braking_speed,
    braking_speed_discrete,
    stopping_distance,
)
from ..spatial import pose_error_into, rigid_transform_defect
from .command import _RANK, STATUSES, Command, make_command
from .smoothing import ProgressProfile, VelocityFilter

if TYPE_CHECKING:
    from ..model.chain import Chain
    from ..solvers.base import Solver

__all__ = ["ResolvedRateController", "Command", "STATUSES", "default_solver"]

_APPROACH_ETA = 0.5  # fraction of amax (and jmax) the approach to a target plans its braking with
_BIG = 1e15  # an absent position or velocity limit in the bound arithmetic (no inf − inf)
_NO_AMAX = 1e200  # an absent acceleration limit: stopping takes one period


def _finite_sum(a: np.ndarray) -> bool:
    """True when the sum of the entries of ``a`` is finite (no NaN, no inf), through a
    Python list: ~5× cheaper than ``ndarray.sum`` on the few numbers of one cycle."""
    s = sum(a.ravel().tolist())
    return s - s == 0.0


def _float_array(value, name: str, what: str) -> np.ndarray:
    try:
        return np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise InputError(f"{name} must be {what}, got {value!r}", argument=name, value=value) from None


class _Cycle:
    """The working state of one control cycle, passed from stage to stage."""

    __slots__ = ("J", "e", "ep", "eo", "xi", "target", "res", "qd", "qdd", "q_next", "flags", "reasons",
                 "active", "scale", "smin", "braking", "approach", "qdd_ff", "approach_qd")

    J: np.ndarray
    e: np.ndarray
    ep: float
    eo: float
    xi: np.ndarray
    target: bool
    res: Any
    smin: float | None
    qd: np.ndarray
    qdd: np.ndarray
    q_next: np.ndarray
    braking: Any
    qdd_ff: np.ndarray | None
    approach_qd: np.ndarray | None

    def __init__(self) -> None:
        self.flags: list[str] = []
        self.reasons: list[str] = []
        self.active: list[str] = []
        self.braking = None
        self.approach = 1.0
        self.qdd_ff = None
        self.approach_qd = None
        self.scale = 1.0
        self.smin = None  # σ_min of the solve, read on demand (`ResolvedRateController._sigma`)


def default_solver():
    """The controller's default inverse-velocity solver: ``rc.solvers.AdaptiveDLS()``."""
    return solvers.AdaptiveDLS()


class ResolvedRateController:
    """A stateful resolved-rate controller for a user's control loop.

    Args:
        chain: the arm (`Chain`).
        solver: an inverse-velocity solver with ``.solve(J, xi, limits=, q=, qd_prev=, dt=)``
            (default: `default_solver`). The controller keeps the solver object, so a QP
            solver stays warm-started between cycles.
        gain: feedback gain K [1/s] on the pose error: a scalar or 6 values [linear ×3; angular ×3].
        limits: ``"chain"`` (the chain's position, velocity, acceleration limits), ``None``
            (no limits) or an object with arrays ``lower, upper, vmax, amax``.
        smoothing: ``False``; ``True`` (a Ruckig `VelocityFilter` with the
            chain's vmax, amax, jmax); or a ``VelocityFilter``.
        position_tolerance [m], orientation_tolerance [rad]: "target reached" thresholds.
        timeout: a target whose ``stamp`` is older than this [s] is stale (halt).
        singular_sigma: below this σ_min a velocity-limited or failed solve is reported as
            "singular" rather than "velocity-scaled".
    """

    def __init__(self, chain: Chain, *, solver: Solver | None = None, gain: float = 10.0,
                 limits: Limits | Chain | str | None = "chain", smoothing: bool = False,
                 position_tolerance: float = 1e-4, orientation_tolerance: float = 1e-3,
                 timeout: float = 0.1, singular_sigma: float = 0.02) -> None:

        self.chain = chain
        self._n = n = chain.dof
        self.solver = default_solver() if solver is None else solver
        if not callable(getattr(self.solver, "solve", None)):
            raise InputError("solver must have a solve(J, xi, ...) method (see ratectl.solvers), "
                             f"got {type(self.solver).__name__}", argument="solver", value=solver)
        K = np.broadcast_to(np.asarray(gain, dtype=float), (6,)).copy() if np.ndim(gain) <= 1 else None
        if K is None or not np.all(np.isfinite(K)) or np.any(K < 0):
            raise InputError(f"gain must be a non-negative scalar or 6 values [1/s], got {gain!r}",
                             argument="gain", value=gain)
        self.gain = K
        kmax = float(K.max())
        self._inv_kmax = 1.0 / kmax if kmax > 0.0 else 0.0
        if isinstance(limits, str):
            if limits != "chain":
                raise InputError(f"limits must be 'chain', None or a limits object, got {limits!r}",
                                 argument="limits", value=limits)
            limits = chain
        self.limits = None if limits is None else Limits.of(limits, n)
        if self.limits is not None:
            lim = self.limits
            self._vmax = lim.vmax
            self._amax = lim.amax
            self._has_v = bool(np.any(np.isfinite(lim.vmax)))
            self._has_a = bool(np.any(np.isfinite(lim.amax)))
            self._has_p = bool(np.any(np.isfinite(lim.lower) | np.isfinite(lim.upper)))
            big = _BIG
            self._inv_vmax = np.where(np.isfinite(lim.vmax), 1.0 / lim.vmax, 0.0)
            self._inv_vmax_l = self._inv_vmax.tolist()
            self._inv_amax = np.where(np.isfinite(lim.amax), 1.0 / lim.amax, 0.0)
            # an absent acceleration limit: a joint can stop in one period, so its position
            # limit is enforced by the velocity limit alone (the braking speed is d/dt)
            self._amax_f = np.where(np.isfinite(lim.amax), lim.amax, _NO_AMAX)
            self._plo = np.where(np.isfinite(lim.lower), lim.lower, -big)
            self._phi = np.where(np.isfinite(lim.upper), lim.upper, big)
            vf = np.where(np.isfinite(lim.vmax), lim.vmax, big)
            # distance within which a joint at full speed may need to brake (per side, so a
            # one-sided limit is watched too): v²/(2a), 0 without an acceleration limit
            fin = np.isfinite(lim.vmax) & np.isfinite(lim.amax)
            vfin = np.where(fin, vf, 0.0)
            self._pbrake = np.where(fin, vfin**2 / (2.0 * np.where(fin, self._amax_f, 1.0)),
                                    np.where(np.isfinite(lim.vmax), 0.0, big))
            self._vf = vf
            self._proom = None
            self._proom_dt = None
        else:
            self._has_v = self._has_a = self._has_p = False
        self._smoothing_option = smoothing
        self._progress: ProgressProfile | None = None
        self._all_joints = np.ones(n, dtype=bool)
        self._target_ok = None  # the last target found rigid (checked again only when it changes)
        self.filter: VelocityFilter | None = None
        if smoothing is not False and smoothing is not None:
            if smoothing is True:
                self._check_finite_limits()
                self.filter = VelocityFilter(n, dt=1e-3, vmax=chain.vmax, amax=chain.amax, jmax=chain.jmax)
            elif isinstance(smoothing, VelocityFilter):
                self.filter = smoothing
            else:
                raise InputError("smoothing must be False, True or a ratectl.smoothing.VelocityFilter, "
                                 f"got {smoothing!r}", argument="smoothing", value=smoothing)
            if self.filter.dof != n:
                raise InputError(f"the VelocityFilter has {self.filter.dof} joints, the chain {n}",
                                 argument="smoothing", value=smoothing)
            if self.limits is not None and self._has_p:
                # a jerk-limited joint needs more room to stop: widen the "near a limit" gate
                f = self.filter
                self._pbrake = np.maximum(self._pbrake,
                                          stopping_distance(f.vmax, f.amax, f.amax, f.jmax))
        self.position_tolerance = float(position_tolerance)
        self.orientation_tolerance = float(orientation_tolerance)
        self.timeout = float(timeout)
        self.singular_sigma = float(singular_sigma)
        self._e = np.zeros(6)
        self.reset()

    def _check_finite_limits(self) -> None:
        c = self.chain
        for name in ("vmax", "amax", "jmax"):
            a = getattr(c, name)
            if not np.all(np.isfinite(a)):
                raise InputError(f"smoothing=True needs finite {name} on every joint of {c.name!r}; "
                                 f"give them with chain.with_limits({name}=...) (or the importer's "
                                 f"{name}= keyword), or pass a VelocityFilter", argument="smoothing",
                                 value=a)

    # ------------------------------------------------------------------ state
    def reset(self, qd: ArrayLike | None = None) -> None:
        """Forget the state: previous q̇ (default zero), halt latch, clock, smoother state."""
        self._qd = np.zeros(self._n) if qd is None else np.asarray(qd, dtype=float).copy()
        self._qdd = np.zeros(self._n)
        self._q_last = None
        self._q_next_last = None
        self._latched = ""
        self._dt_last = None
        self.time = 0.0
        if self.filter is not None:
            self.filter.reset(self._qd)
        reset = getattr(self.solver, "reset", None)
        if callable(reset):
            reset()

    @property
    def qd(self) -> np.ndarray:
        """The last commanded joint velocity."""
        return self._qd.copy()

    @property
    def halted(self) -> bool:
        """True while a latched halt (non-finite input) is in force; cleared by `reset`."""
        return bool(self._latched)

    # ------------------------------------------------------------------ the cycle
    def step(self, q: ArrayLike, *, target: ArrayLike | None = None, twist: ArrayLike | None = None,
             dt: float, qd_ff: ArrayLike | None = None, qdd_ff: ArrayLike | None = None,
             stamp: float | None = None) -> Command:
        """One control cycle (see the module docstring): the stages
        `_validate` → `_halt_reason` → `_error` → `_solve` →
        `_limit` → `_smooth` → `_command`.

        Args:
            q: measured joint positions (n,).
            target: desired tool pose T_des (4×4) or None (no feedback).
            twist: feed-forward tool twist ξ_ff = [v; ω] (6,) [m/s; rad/s] or None.
            dt: control period [s].
            qd_ff: joint-velocity feed-forward (n,) added to the resolved rate (e.g. the
                governor's planned q̇); ``twist`` is then the *extra* twist to resolve.
            qdd_ff: joint-acceleration feed-forward (n,), used by the smoother only (Ruckig's
                target acceleration, clipped to ±amax): with it the jerk-limited filter tracks a
                planned motion without lag.
            stamp: when the target was produced, on the controller clock ``ctrl.time`` [s];
                older than ``timeout`` → halt (stale target).
        """
        return self._cycle(*self._validate(q, target, twist, dt, qd_ff), qdd_ff, stamp)

    def _cycle(self, q: np.ndarray, target: np.ndarray | None, twist: np.ndarray | None, dt: float,
               qd_ff: np.ndarray | None, qdd_ff: ArrayLike | None, stamp: float | None) -> Command:
        """`step` after validation: the stages on float arrays."""
        halt = self._halt_reason(q, target, twist, dt, qd_ff, stamp)
        if halt is not None:
            return halt
        cyc = self._error(q, target, twist)
        halt = self._solve(cyc, q, dt, qd_ff)
        if halt is not None:
            return halt
        if target is not None and qd_ff is None and (twist is None or not twist.any()):
            halt = self._approach(cyc, q, dt)
            if halt is not None:
                return halt
        self._limit(cyc, q, dt)
        if (not cyc.flags and target is not None and qd_ff is None
                and (twist is None or not twist.any()) and cyc.ep <= self.position_tolerance
                and cyc.eo <= self.orientation_tolerance):
            cyc.flags.append("target-reached")
        halt = self._smooth(cyc, q, dt, qdd_ff)
        if halt is not None:
            return halt
        return self._command(cyc, q, dt)

    # --- stage 1: validation (shapes raise, values halt)
    def _validate(self, q: ArrayLike, target: ArrayLike | None, twist: ArrayLike | None, dt: float,
                  qd_ff: ArrayLike | None) -> tuple[np.ndarray, np.ndarray | None, np.ndarray | None,
                                                    float, np.ndarray | None]:
        """Shapes and types: returns ``(q, target, twist, dt, qd_ff)`` as float arrays
        (the caller's arrays are not copied when already float64) or raises
        `InputError`. Values (NaN, inf) are not checked here."""
        n = self._n
        if type(q) is not np.ndarray or q.dtype != np.float64:
            try:
                q = np.asarray(q, dtype=float)
            except (TypeError, ValueError):
                raise InputError(f"q must be {n} numbers", argument="q", value=q) from None
        if q.shape != (n,):
            raise InputError(f"q must have shape ({n},), got {q.shape}", argument="q", value=q)
        try:
            dt = float(dt)
        except (TypeError, ValueError):
            raise InputError(f"dt must be a number [s], got {dt!r}", argument="dt", value=dt) from None
        if target is not None:
            if type(target) is not np.ndarray or target.dtype != np.float64:
                target = _float_array(target, "target", "a 4x4 pose")
            if target.shape != (4, 4):
                raise InputError(f"target must be a 4x4 pose, got shape {target.shape}",
                                 argument="target", value=target)
        if twist is not None:
            if type(twist) is not np.ndarray or twist.dtype != np.float64:
                twist = _float_array(twist, "twist", "6 numbers [v; ω]")
            if twist.shape != (6,):
                raise InputError(f"twist must have shape (6,) [v; ω], got {twist.shape}",
                                 argument="twist", value=twist)
        if qd_ff is not None:
            qd_ff = _float_array(qd_ff, "qd_ff", f"{n} numbers")
            if qd_ff.shape != (n,):
                raise InputError(f"qd_ff must have shape ({n},), got {qd_ff.shape}",
                                 argument="qd_ff", value=qd_ff)
        return q, target, twist, dt, qd_ff

    def _halt_reason(self, q, target, twist, dt, qd_ff, stamp) -> Command | None:
        """Values that bring a safe halt (non-finite inputs latch it, a stale target does
        not): returns the halt's `Command`, or None when the cycle may proceed."""
        if not (dt > 0.0 and math.isfinite(dt)):
            self._latched = self._latched or f"non-finite or non-positive dt ({dt!r})"
            return self._halt(q, self._dt_last or 1e-3, self._latched)
        self._dt_last = dt
        if self._latched:
            return self._halt(q, dt, self._latched)
        # finiteness through Python float sums (NaN or inf make the sum non-finite; an
        # overflow to inf of finite values is refused too): cheaper than ndarray.sum
        bad = None
        if not _finite_sum(q):
            bad = "q"
        elif target is not None and not _finite_sum(target):
            bad = "target"
        elif twist is not None and not _finite_sum(twist):
            bad = "twist"
        elif qd_ff is not None and not _finite_sum(qd_ff):
            bad = "qd_ff"
        if bad is not None:
            self._latched = f"non-finite {bad} (NaN or inf); reset() to resume"
            return self._halt(q, dt, self._latched)
        if target is not None and not (self._target_ok is not None
                                       and np.array_equal(target, self._target_ok)):
            defect = rigid_transform_defect(target)
            if defect is not None:  # a scaled, sheared or mirrored pose: no motion toward it
                return self._halt(q, dt, f"target {defect}")
            self._target_ok = target.copy()
        if stamp is not None and target is not None:
            age = self.time - float(stamp)
            if not age <= self.timeout:
                return self._halt(q, dt, f"stale target: {age:.3g} s old > timeout {self.timeout:.3g} s")
        return None

    # --- stage 2: the pose error and the twist to resolve
    def _error(self, q, target, twist) -> _Cycle:
        """fk and J at q, the pose error e = [p_d − p; log(R_d Rᵀ)] and the twist
        ξ = ξ_ff + K e to resolve; returns the cycle's working state."""
        cyc = _Cycle()
        T, J = self.chain.fk_jacobian(q)
        cyc.J = J
        e = cyc.e = np.zeros(6)
        cyc.target = target is not None
        if target is not None:
            cyc.ep, cyc.eo = pose_error_into(e, target, T)
            xi = self.gain * e
            if twist is not None:
                xi += twist
        else:
            cyc.ep = cyc.eo = 0.0
            xi = twist.copy() if twist is not None else np.zeros(6)
        cyc.xi = xi
        return cyc

    # --- stage 3: the inverse-velocity solve
    def _solve(self, cyc: _Cycle, q, dt, qd_ff) -> Command | None:
        """q̇ = q̇_ff + solver(J, ξ); a solver failure or a non-finite answer halts (returns
        the halt's Command), otherwise fills ``cyc.qd``, ``cyc.res`` and the status lists."""
        try:
            if qd_ff is not None and getattr(self.solver, "enforces_limits", False):
                # a limit-enforcing solver (the QP, or a wrapper of it) takes q̇_ff and bounds
                # the total q̇_ff + correction itself: velocity, position and acceleration
                # limits hold for what is commanded, not only for the correction
                enforcing: Any = self.solver  # the enforces_limits contract includes qd_ff=
                res = enforcing.solve(cyc.J, cyc.xi, limits=self.limits, q=q, qd_prev=self._qd,
                                      dt=dt, qd_ff=qd_ff)
            else:
                if qd_ff is None:
                    q_s, qd_prev_s = q, self._qd
                else:  # the solver resolves the correction on top of q̇_ff: shift its inputs
                    q_s, qd_prev_s = q + qd_ff * dt, self._qd - qd_ff
                res = self.solver.solve(cyc.J, cyc.xi, limits=self.limits, q=q_s, qd_prev=qd_prev_s,
                                        dt=dt)
        except SingularityError as err:
            return self._halt(q, dt, f"singular: {err}", status="singular", sigma_min=err.sigma_min,
                              error=cyc.e, ep=cyc.ep, eo=cyc.eo)
        except (RatectlError, np.linalg.LinAlgError) as err:
            return self._halt(q, dt, f"solver failed: {err}", error=cyc.e, ep=cyc.ep, eo=cyc.eo)
        qd = res.qd if qd_ff is None else res.qd + qd_ff
        if not _finite_sum(qd):
            return self._halt(q, dt, "solver returned a non-finite q̇", error=cyc.e, ep=cyc.ep, eo=cyc.eo)
        cyc.res = res
        cyc.qd = qd
        cyc.active = list(res.limits_active)
        cyc.scale = float(res.velocity_scale)
        cyc.smin = None  # σ_min: read from res only when needed (a QP computes it lazily)
        if res.velocity_policy != "none":
            cyc.flags.append("velocity-scaled")
        return None

    # --- stage 3b: the approach to a target
    def _approach(self, cyc: _Cycle, q, dt) -> Command | None:
        """Shape the feedback q̇ = solver(J, K e) so that the arm can still stop at the
        target within the joint limits (pure servoing: a target, no feed-forward).

        The joint travel still to go is, to first order, w = J⁺e = q̇/K (the solver is
        linear in ξ; for a vector gain the largest K, which under-estimates w: the safe
        side). Joint i may approach at most at the speed from which it can stop within
        w_i: ``braking_speed_discrete`` at η·amax in periods of dt (the discrete
        √(2 η amax w)), or, smoothed, `braking_speed` at η·amax,
        η·jmax — and 0 when the filter's own state (v, a) one period ahead could no longer
        stop within w_i. q̇ is scaled uniformly by the smallest ratio, so the tool keeps its
        straight approach; η = 1/2 keeps headroom for the change of J along the way. Far
        from the target (K·w below the braking speed) this is the proportional law.
        A solver that enforces limits itself (the QP) solves again with the scaled twist."""
        qd = cyc.qd
        if self._inv_kmax == 0.0 or self.limits is None:
            return None
        speed = np.abs(qd)
        w = speed * self._inv_kmax
        f = self.filter
        moving = speed > 0.0
        if not moving.any():
            return None
        if f is not None:
            r, cyc.qdd_ff = self._approach_smoothed(cyc, qd, speed, moving, dt)
        elif self._has_a:
            adt = self._amax_f * (_APPROACH_ETA * dt)
            b = braking_speed_discrete(w, adt, 1.0 / (adt * dt), 1.0 / dt)
            r = float(np.min(b[moving] / speed[moving]))
        else:
            return None
        if r >= 1.0:
            cyc.approach_qd = cyc.qd
            return None
        cyc.approach = r
        cyc.flags.append("acceleration-limited")
        cyc.reasons.append(f"approach to the target slowed to {r:.3g}× its proportional speed to stop "
                           "there within amax")
        if getattr(self.solver, "enforces_limits", False):
            cyc.xi = cyc.xi * r
            return self._solve(cyc, q, dt, None)
        cyc.xi = cyc.xi * r
        cyc.qd = cyc.approach_qd = qd * r
        return None

    def _approach_smoothed(self, cyc: _Cycle, qd, speed, moving, dt):
        """The approach law for the jerk-limited filter, on the scalar progress x = ‖e‖
        toward the target. The joints move as q̇ = ẋ·d with d = q̇_solver/(K x) (= J⁺ê, so
        the tool moves straight along ê), hence the progress may move at ẋ ≤ minᵢ vmaxᵢ/|dᵢ|,
        accelerate at α = η·minᵢ amaxᵢ/|dᵢ| and jerk at ζ = η·minᵢ jmaxᵢ/|dᵢ|. From the
        filter's state projected on d (ṡ = v·d/d·d, s̈ = a·d/d·d), a
        `ProgressProfile` (Ruckig, one degree of freedom)
        gives the time-optimal motion that comes to rest at x; one period of it, capped by
        the proportional law ẋ ≤ K x, is the command. Its acceleration s̈·d is passed to the
        filter as the target acceleration: the reference is feasible, so the filter follows
        it without lag (no lag to turn into overshoot). Returns (r, q̈_ff): the scale of q̇
        and that acceleration."""
        f = self.filter
        assert f is not None
        x = float(np.linalg.norm(cyc.e))
        K = 1.0 / self._inv_kmax
        if x <= 0.0:
            return 1.0, None
        d = qd * (self._inv_kmax / x)
        ad = np.abs(d)[moving]
        vcap = float(np.min(f.vmax[moving] / ad))
        alpha = _APPROACH_ETA * float(np.min(f.amax[moving] / ad))
        zeta = _APPROACH_ETA * float(np.min(f.jmax[moving] / ad))
        dd = float(d @ d)
        s_v = min(max(float(self._qd @ d) / dd, -vcap), vcap)
        s_a = min(max(float(self._qdd @ d) / dd, -alpha), alpha)
        if self._progress is None:
            self._progress = ProgressProfile(dt)
        nxt = self._progress.step(x, s_v, s_a, vmax=max(min(vcap, K * x), 1e-12), amax=alpha, jmax=zeta,
                                  dt=dt)
        if nxt is None:
            return 1.0, None
        v1, a1 = nxt
        return v1 / (K * x), d * a1

    # --- stage 4: the limits
    def _limit(self, cyc: _Cycle, q, dt) -> None:
        """Velocity, acceleration and position limits on ``cyc.qd`` (in that order; see the
        module docstring), or only the report of them for a solver that enforces them."""
        enforcing = getattr(self.solver, "enforces_limits", False)
        if enforcing:
            # the solver (the QP, possibly with extra rows such as collision limits) already
            # bounds q̇ by the velocity, position and acceleration limits; limiting again here
            # would move q̇ off its optimum and could break its extra rows
            cyc.qd, cyc.scale = self._report_solver_limits(cyc, cyc.res, cyc.qd, cyc.flags,
                                                           cyc.reasons, cyc.scale)
        else:
            self._limit_velocity(cyc)
        if "velocity-scaled" in cyc.flags:
            cyc.reasons.append(f"q̇ scaled by {cyc.scale:.3g} to respect vmax")
            smin = self._sigma(cyc)
            if smin < self.singular_sigma:
                cyc.flags.insert(0, "singular")
                cyc.reasons[-1] = (f"near a singularity (σ_min = {smin:.3g}) the solver needs "
                                   f"{1 / cyc.scale:.3g}× vmax; q̇ scaled by {cyc.scale:.3g}")
        if self._has_a and self.filter is None and not enforcing:
            self._limit_acceleration(cyc, dt)
        near = self._near_position_limit(q, dt) if (not enforcing or self.filter is not None) else False
        if near and not enforcing:
            self._limit_position(cyc, q, dt)
        if self.filter is not None and near:
            cyc.qd, cyc.braking = self._jerk_limited_position_guard(q, cyc.qd, dt, cyc.flags,
                                                                    cyc.reasons, cyc.active)
        res = cyc.res
        if res.damping > 0.0 and not (enforcing and self._sigma_at_least(cyc, self.singular_sigma)):
            # a QP's λ is a constant regulariser: it is reported only near a singularity
            cyc.flags.append("damped")
            cyc.reasons.append(f"damped least squares, λ = {res.damping:.3g} "
                               f"(σ_min = {self._sigma(cyc):.3g})")

    def _limit_velocity(self, cyc: _Cycle) -> None:
        """Uniform scaling of q̇ into |q̇_i| ≤ vmax_i (keeps the direction of motion)."""
        if not self._has_v:
            return
        r = float((np.abs(cyc.qd) * self._inv_vmax).max())
        if r > 1.0:
            cyc.qd = cyc.qd / r
            cyc.scale /= r
            cyc.flags.append("velocity-scaled")
            if "velocity" not in cyc.active:
                cyc.active.append("velocity")

    def _limit_acceleration(self, cyc: _Cycle, dt) -> None:
        """The change of q̇ from the previous cycle scaled uniformly into |Δq̇_i| ≤ amax_i dt."""
        dq = cyc.qd - self._qd
        r = float((np.abs(dq) * self._inv_amax).max()) / dt
        if r > 1.0:
            qd = self._qd + dq / r
            cyc.flags.append("acceleration-limited")
            cyc.reasons.append(f"change of q̇ scaled by {1 / r:.3g} to respect amax")
            cyc.active.append("acceleration")
            if self._has_v:  # the velocity limit wins if the previous q̇ was above it
                rv = float((np.abs(qd) * self._inv_vmax).max())
                if rv > 1.0:
                    qd = qd / rv
            cyc.qd = qd

    def _near_position_limit(self, q, dt) -> bool:
        """True if some joint is close enough to one of its position limits that it may
        need to brake: the room to the limit is below the braking distance plus one period
        at vmax (each side on its own, so a one-sided limit counts)."""
        if not self._has_p:
            return False
        if self._proom_dt != dt:
            self._proom = self._pbrake + self._vf * dt
            self._proom_dt = dt
        room = self._proom
        return bool(((self._phi - q) < room).any() or ((q - self._plo) < room).any())

    def _limit_position(self, cyc: _Cycle, q, dt) -> None:
        """Clip each joint's q̇ to the speed from which it can still stop before its limits."""
        adt = self._amax_f * dt
        inv_adt2, inv_dt = 1.0 / (adt * dt), 1.0 / dt
        # the speed from which the joint still stops before the limit, braking by at most
        # amax·dt per period (braking_speed_discrete: the discrete √(2·amax·d), ≥ d/dt; with
        # no acceleration limit exactly d/dt, the velocity limit then bounds the approach)
        hi_v = braking_speed_discrete(self._phi - q, adt, inv_adt2, inv_dt)
        lo_v = -braking_speed_discrete(q - self._plo, adt, inv_adt2, inv_dt)
        # a joint found beyond a limit (a disturbance, or a start outside the range) is
        # brought back no faster than vmax and no harder than amax from the previous q̇
        hi_v = np.maximum(hi_v, np.maximum(-self._vf, self._qd - adt))
        lo_v = np.minimum(lo_v, np.minimum(self._vf, self._qd + adt))
        clipped = np.clip(cyc.qd, lo_v, hi_v)
        changed = clipped != cyc.qd
        if changed.any():
            joints = np.flatnonzero(changed)
            cyc.qd = clipped
            cyc.flags.insert(0, "joint-limit")
            cyc.reasons.insert(0, f"joint(s) {joints.tolist()} held at a position limit")
            cyc.active.append("position")

    # --- stage 5: smoothing and integration
    def _smooth(self, cyc: _Cycle, q, dt, qdd_ff) -> Command | None:
        """The Ruckig filter (if any) turns ``cyc.qd`` into a jerk-limited motion and gives
        its exact integral; without it q_next = q + q̇ dt, q̈ = (q̇ − q̇_prev)/dt."""
        if self.filter is not None:
            if abs(self.filter.dt - dt) > 1e-15:
                self.filter.dt = dt
            if qdd_ff is None and cyc.qdd_ff is not None and cyc.approach_qd is not None:
                # the approach's acceleration belongs to its q̇: kept for the joints whose q̇
                # no limit changed since
                qdd_ff = (cyc.qdd_ff if cyc.qd is cyc.approach_qd
                          else np.where(cyc.qd == cyc.approach_qd, cyc.qdd_ff, 0.0))
            try:
                cyc.q_next, cyc.qd, cyc.qdd = self.filter.update(q, cyc.qd, qdd_ff, independent=cyc.braking)
            except RatectlError as err:
                return self._halt(q, dt, f"smoothing failed: {err}", error=cyc.e, ep=cyc.ep, eo=cyc.eo)
        else:
            cyc.q_next = q + cyc.qd * dt
            cyc.qdd = (cyc.qd - self._qd) / dt
        return None

    # --- stage 6: the command
    def _command(self, cyc: _Cycle, q, dt) -> Command:
        """Update the controller state and return the cycle's frozen `Command`
        (its arrays are read-only and not shared with the controller's state)."""
        qd = cyc.qd
        self._q_next_last = cyc.q_next.copy()
        self._qd = qd.copy()
        self._qdd = cyc.qdd
        self._q_last = q.copy()
        t0 = self.time
        self.time = t0 + dt
        if cyc.flags:
            status = min(cyc.flags, key=_RANK.__getitem__)
            flags = tuple(dict.fromkeys(cyc.flags))
        else:
            status, flags = "regular", ("regular",)
        res = cyc.res
        active = cyc.active
        return make_command(qd=qd, q_next=cyc.q_next, qdd=cyc.qdd.copy(), status=status, flags=flags,
                            reason="; ".join(cyc.reasons), error=cyc.e, position_error=cyc.ep,
                            orientation_error=cyc.eo, twist=cyc.xi,
                            sigma_min=res if cyc.smin is None else cyc.smin,  # lazy: res.sigma_min
                            damping=float(res.damping), task_error=res.task_error,
                            velocity_scale=cyc.scale,
                            limits_active=tuple(dict.fromkeys(active)) if active else (), time=t0,
                            dt=dt, solve=res, chain=self.chain, q=self._q_last)

    def _jerk_limited_position_guard(self, q, qd, dt, flags, reasons, active):
        """Keep a smoothed joint inside its position range: the Ruckig filter lags the
        command, so braking must start while the jerk-limited stop still fits.

        From the filter's state (v, a) the worst case one period ahead towards a limit is
        a₁ = min(a + J·dt, A), v₁ = v + a·dt + J·dt²/2 after travelling v·dt + a·dt²/2 +
        J·dt³/6. If the jerk-limited stop from (v₁, a₁) (`
        stopping_distance`) no longer fits in the room left, the command towards that
        limit is 0 now (Ruckig then brakes time-optimally); otherwise it is at most
        `braking_speed` of the room. The same mirrored towards
        the lower limit. Returns (q̇, braking): the joints that must stop, which the filter
        then moves time-optimally on their own instead of synchronised with the others."""
        f = self.filter
        A, Jm = f.amax, f.jmax
        v, a = self._qd, self._qdd
        jdt = Jm * dt
        ahead_v = 0.5 * jdt * dt
        ahead_x = jdt * dt * dt / 6.0
        room_up = self._phi - q
        room_lo = q - self._plo
        # towards the upper limit
        a1 = np.minimum(a + jdt, A)
        v1 = v + a * dt + ahead_v
        stop_up = stopping_distance(v1, a1, A, Jm) >= room_up - (v * dt + 0.5 * a * dt * dt + ahead_x)
        hi_v = np.where(stop_up, 0.0, braking_speed(room_up, A, Jm))
        # towards the lower limit (mirrored)
        a1 = np.minimum(-a + jdt, A)
        v1 = -v - a * dt + ahead_v
        stop_lo = stopping_distance(v1, a1, A, Jm) >= room_lo - (-v * dt - 0.5 * a * dt * dt + ahead_x)
        lo_v = np.where(stop_lo, 0.0, -braking_speed(room_lo, A, Jm))
        clipped = np.minimum(np.maximum(qd, lo_v), hi_v)
        changed = clipped != qd
        if changed.any():
            joints = np.flatnonzero(changed).tolist()
            if "joint-limit" not in flags:
                flags.insert(0, "joint-limit")
            reasons.insert(0, f"joint(s) {joints} braking for a position limit (jerk-limited stop)")
            active.append("position")
        else:
            clipped = qd  # unchanged: the same array (the approach's acceleration stays valid)
        return clipped, stop_up | stop_lo  # the braking joints stop time-optimally, on their own

    @staticmethod
    def _sigma(cyc: _Cycle) -> float:
        """σ_min of the cycle's solve, computed on the first call only."""
        smin = cyc.smin
        if smin is None:
            smin = cyc.smin = float(cyc.res.sigma_min)
        return smin

    @classmethod
    def _sigma_at_least(cls, cyc: _Cycle, threshold: float) -> bool:
        """σ_min ≥ threshold for the cycle's solve: by the result's ``sigma_min_at_least``
        (a `SolveResult`'s: the QP usually decides it without computing σ_min), else by
        the value."""
        at_least = getattr(cyc.res, "sigma_min_at_least", None) if cyc.smin is None else None
        if at_least is not None:
            return bool(at_least(threshold))
        return cls._sigma(cyc) >= threshold

    def _report_solver_limits(self, cyc, res, qd, flags, reasons, scale):
        """Flags and reasons for a solver that enforces the limits itself (the QP): which
        joints sit at which kind of bound, from ``res.bound`` and ``res.limits_active``.
        Only a q̇ beyond vmax by more than rounding (a bound conflict) is scaled back."""
        if self._has_v:
            r = max(map(abs, map(_mul, qd.tolist(), self._inv_vmax_l)))  # max |q̇_i|/vmax_i
            if r > 1.0 + 1e-9:
                qd = qd / r
                scale /= r
                flags.append("velocity-scaled")
                reasons.append(f"q̇ scaled by {1 / r:.3g} to respect vmax")
        kinds = res.limits_active
        joints = [i for i, held in enumerate(res.bound.tolist()) if held] if kinds else []
        if "position" in kinds:
            flags.insert(0, "joint-limit")
            reasons.insert(0, f"QP: joint(s) {joints} held by a position limit")
        if "velocity" in kinds:
            smin = self._sigma(cyc)
            if smin < self.singular_sigma:
                flags.insert(0, "singular")
                reasons.append(f"near a singularity (σ_min = {smin:.3g}) the QP holds joint(s) "
                               f"{joints} at vmax")
            else:
                flags.append("velocity-scaled")
                reasons.append(f"QP: joint(s) {joints} at vmax")
        if "acceleration" in kinds:
            flags.append("acceleration-limited")
            reasons.append(f"QP: joint(s) {joints} at the acceleration bound")
        extra = res.info.get("extra_active") if isinstance(res.info, dict) else None
        if extra is not None and np.any(extra):
            reasons.append(f"{int(np.count_nonzero(extra))} extra constraint row(s) active "
                           "(e.g. collision avoidance)")
        return qd, scale

    # ------------------------------------------------------------------ halting
    def _halt(self, q, dt, reason, *, status="halted", sigma_min=float("nan"), error=None,
              ep=float("nan"), eo=float("nan")) -> Command:
        """Bring every joint to rest as fast as its own limits allow (each joint on its own,
        so a joint that was braking for its position limit keeps braking at its full rate):
        |q̇_i| drops by amax_i·dt per period (at once without an acceleration limit), or, with
        smoothing, each joint's time-optimal jerk-limited stop. The motion continues from
        the measured q, or — when q is not finite — from the last commanded position, so the
        commanded stream stays continuous."""
        qd_prev = self._qd
        if np.all(np.isfinite(q)):
            base = q
        else:
            base = self._q_next_last if self._q_next_last is not None else self._q_last
        if base is None:
            base = np.zeros(self._n)
        smoothed = False
        if self.filter is not None:
            try:
                q_next, qd, qdd = self.filter.update(base, np.zeros(self._n), independent=self._all_joints)
                smoothed = True
            except RatectlError as err:  # the filter failed: brake without it
                reason = f"{reason}; smoothing failed while halting ({err})"
        if not smoothed:
            amax = self.limits.amax if self.limits is not None else np.full(self._n, np.inf)
            speed = np.maximum(np.abs(qd_prev) - amax * dt, 0.0)  # inf amax: 0 at once
            qd = np.sign(qd_prev) * speed
            q_next = base + qd * dt
            qdd = (qd - qd_prev) / dt
        self._qd = qd.copy()
        self._qdd = qdd
        self._q_last = base.copy()
        self._q_next_last = q_next.copy()
        t0 = self.time
        self.time = t0 + dt
        return make_command(qd=qd, q_next=q_next, qdd=qdd.copy(), status=status, flags=(status,),
                            reason=reason, error=np.zeros(6) if error is None else error.copy(),
                            position_error=ep, orientation_error=eo, twist=np.zeros(6),
                            sigma_min=sigma_min, damping=0.0, task_error=np.zeros(6), velocity_scale=0.0,
                            limits_active=(), time=t0, dt=dt, solve=None, chain=self.chain,
                            q=self._q_last)

    def __repr__(self) -> str:
        return (f"ResolvedRateController({self.chain.name!r}, solver={type(self.solver).__name__}, "
                f"gain={self.gain.tolist()}, smoothing={self.filter is not None})")
