"""The resolved-rate controller: one call per control cycle.

``ctrl.step(q, target=T_des, twist=ξ_ff, dt=dt)`` computes

    e  = [p_d − p ; log(R_d Rᵀ)]              (pose error, base axes)
    ξ  = ξ_ff + K e                           (feed-forward plus proportional feedback)
    q̇  = q̇_ff + solver(J(q), ξ)               (inverse velocity; q̇_ff optional)

A target alone is a servo: the tool moves on the straight line to it (`StraightApproach`,
``_servo``), a jerk-limited progress within the joint limits mapped onto it
(`ProgressLimits`), and, where that line is blocked, in joint space to an inverse-kinematics
solution (`JointLine`). A twist alone is a jog along it (`Jog`, ``_jog``). Then the
controller applies the limits in this order: velocity (uniform
scaling, which keeps the direction of motion), acceleration (the change of q̇ per cycle is
scaled to fit amax·dt), joint position (each joint may only move as fast as it can still
stop before its limit at amax whatever the later periods are, ``braking_speed_any_dt``;
without an acceleration limit that is d/dt, so the velocity limit alone enforces the
range; after a fault — a measured q inside the stopping distance or beyond a limit — the
position side wins over amax, status ``limit-recovery``). A solver
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
from collections.abc import Mapping
from operator import gt as _gt
from operator import lt as _lt
from operator import mul as _mul
from types import MappingProxyType
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike

from .. import solvers
from ..arrays import shared_zeros
from ..checks import positive_number
from ..errors import InputError, RatectlError, SingularityError
from ..model.limits import (
    Limits,
    braking_speed,
    speed_toward_limit,
    stopping_distance,
)
from ..singularity import analyze
from ..solvers.base import SolveResult, solver_declares, validated_solve
from ..solvers.ik import ik_iterate
from ..spatial import pose_error_into, rigid_transform_defect
from .approach import JointLine, StraightApproach
from .command import _RANK, STATUSES, Command, make_command
from .jog import Jog
from .progress import ProgressLimits
from .smoothing import VelocityFilter

if TYPE_CHECKING:
    from ..model.chain import Chain
    from ..solvers.base import Solver

__all__ = ["ResolvedRateController", "Command", "STATUSES", "default_solver"]

_SHARE = 0.5  # share of amax (and jmax) the progress of an approach or a jog may use itself
_KIND_NEAR = 0.5  # the σ band in which `analyze` names the singularity a progress stops before
_AT_BLOCK = 1e-5  # [progress units ~ m]: an approach at rest this close to a block stands at it
_LAG_MAX = 0.02  # [m, weighted]: the approach's progress stops when the arm is this far behind it
_BIG = 1e15  # an absent position or velocity limit in the bound arithmetic (no inf − inf)
_NO_AMAX = 1e200  # an absent acceleration limit: stopping takes one period


def _finite_sum(a: np.ndarray) -> bool:
    """True when the sum of the entries of ``a`` is finite (no NaN, no inf), through a
    Python list: ~5× cheaper than ``ndarray.sum`` on the few numbers of one cycle."""
    s = sum(a.ravel().tolist())
    return s - s == 0.0


def _info(res: Any) -> Mapping[str, Any]:
    """The ``info`` mapping of a solve result (a `SolveResult` keeps a read-only
    ``MappingProxyType``, recognised by its exact type first: cheaper than the ABC check),
    or an empty one when a solver gave something else."""
    info = res.info
    if type(info) is MappingProxyType or isinstance(info, Mapping):
        return info
    return _NO_INFO


_NO_INFO: Mapping[str, Any] = MappingProxyType({})


def _checked_solver(solver):
    """The solver option: None → the default solver; an instance with a ``solve`` method;
    otherwise InputError (a solver class instead of an instance is named as such)."""
    solver = default_solver() if solver is None else solver
    if isinstance(solver, type):
        raise InputError(f"solver must be a solver instance: pass {solver.__name__}() (with its "
                         f"options), not the class {solver.__name__}", argument="solver", value=solver)
    if not callable(getattr(solver, "solve", None)):
        raise InputError("solver must have a solve(J, xi, ...) method (see ratectl.solvers), "
                         f"got {type(solver).__name__}", argument="solver", value=solver)
    return solver


def _checked_gain(gain) -> np.ndarray:
    """The gain option as 6 non-negative finite values [1/s], or InputError."""
    try:
        K = np.broadcast_to(np.asarray(gain, dtype=float), (6,)).copy()
    except (TypeError, ValueError):  # not numbers, or not a scalar / 6 values
        K = None
    if K is None or not np.all(np.isfinite(K)) or np.any(K < 0):
        raise InputError(f"gain must be a non-negative scalar or 6 values [1/s], got {gain!r}",
                         argument="gain", value=gain)
    return K


def _scaled_like(wanted: np.ndarray, clipped: np.ndarray) -> np.ndarray:
    """``wanted`` scaled uniformly by the smallest ratio clipped/wanted over the joints a
    clip changed (a ratio in [0, 1]; a clip that reversed a joint gives 0): the motion
    slows along its direction instead of turning."""
    changed = clipped != wanted
    if not changed.any():
        return wanted
    ratio = np.where(changed, clipped / np.where(changed, wanted, 1.0), 1.0)
    return wanted * float(np.clip(ratio.min(), 0.0, 1.0))


def _checked_stamp(stamp) -> float:
    """A target's stamp as a float [s] (NaN stays NaN: a value, which halts), or InputError
    for text, a boolean or anything that is not a real number."""
    if isinstance(stamp, (str, bytes, bool)) or not isinstance(stamp, (int, float, np.integer, np.floating)):
        raise InputError(f"stamp must be a time in seconds on the controller clock ctrl.time, got {stamp!r}",
                         argument="stamp", value=stamp)
    return float(stamp)


def _float_array(value, name: str, what: str) -> np.ndarray:
    try:
        return np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise InputError(f"{name} must be {what}, got {value!r}", argument=name, value=value) from None


class _Cycle:
    """The working state of one control cycle, passed from stage to stage."""

    __slots__ = ("J", "e", "ep", "eo", "xi", "target", "res", "qd", "qdd", "q_next", "flags", "reasons",
                 "active", "scale", "smin", "braking", "approach", "qdd_ff", "approach_qd", "kind",
                 "blocked")

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
        self.kind: str | None = None
        self.blocked = ""
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
        stop_sigma: the σ_min at which a jog or an approach stops before a singularity
            whose lost direction it heads into (default: where the solver starts to damp,
            its ``epsilon``, at least ``singular_sigma``).
        blocked: what a servo does where its straight line is blocked (a joint limit or a
            singularity on the way): ``"joint-space"`` (default) moves in joint space to an
            inverse-kinematics solution of the target on the arm's branch when one exists
            (the tool leaves the line; the reason says so); ``"stop"`` stops there
            (``target-unreachable``, the reason names the block).
        tasks: `ratectl.tasks` objects solved with strict priorities under the limits
            (`ratectl.control.tasks_stage`): ``step(q, dt=...)`` then reads the targets from
            the tasks (``step(q, target=T)`` still servos the tool alone).
        collision: `ratectl.collision` models whose damper rows every level must satisfy.
    """

    def __init__(self, chain: Chain, *, solver: Solver | None = None, gain: float = 10.0,
                 limits: Limits | Chain | str | None = "chain", smoothing: bool = False,
                 position_tolerance: float = 1e-4, orientation_tolerance: float = 1e-3,
                 timeout: float = 0.1, singular_sigma: float = 0.02, stop_sigma: float | None = None,
                 blocked: str = "joint-space", tasks: Any = None, collision: Any = None) -> None:

        self.chain = chain
        self._n = n = chain.dof
        self.solver = _checked_solver(solver)
        self._solve_entry = validated_solve(self.solver)
        self._enforcing = solver_declares(self.solver, "enforces_limits")
        K = _checked_gain(gain)
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
            self._inv_amax_f = 1.0 / self._amax_f
            self._two_over_a2 = np.concatenate([2.0 / self._amax_f, 2.0 / self._amax_f])
            self._amax_f2 = np.concatenate([self._amax_f, self._amax_f])
            self._plo = np.where(np.isfinite(lim.lower), lim.lower, -big)
            self._phi = np.where(np.isfinite(lim.upper), lim.upper, big)
            self._plo_l, self._phi_l = self._plo.tolist(), self._phi.tolist()
            vf = np.where(np.isfinite(lim.vmax), lim.vmax, big)
            # distance within which a joint at full speed may need to brake (per side, so a
            # one-sided limit is watched too): v²/(2a), 0 without an acceleration limit; the
            # gate adds one period at vmax (braking_speed_any_dt reaches vmax there)
            fin = np.isfinite(lim.vmax) & np.isfinite(lim.amax)
            vfin = np.where(fin, vf, 0.0)
            self._pbrake = np.where(fin, vfin**2 / (2.0 * np.where(fin, self._amax_f, 1.0)),
                                    np.where(np.isfinite(lim.vmax), 0.0, big))
            self._vf = vf
            self._vf2 = np.concatenate([vf, vf])
            self._proom = None
            self._proom_dt = None
        else:
            self._has_v = self._has_a = self._has_p = False
        self._smoothing_option = smoothing
        self._zeros = np.zeros(n)
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
        self.position_tolerance = positive_number("position_tolerance", position_tolerance, unit="[m]")
        self.orientation_tolerance = positive_number("orientation_tolerance", orientation_tolerance,
                                                     unit="[rad]")
        self.timeout = positive_number("timeout", timeout, allow_inf=True, unit="[s]")
        self.singular_sigma = positive_number("singular_sigma", singular_sigma, allow_zero=True)
        self._init_jog(stop_sigma)
        if blocked not in ("joint-space", "stop"):
            raise InputError(f"blocked must be 'joint-space' or 'stop', got {blocked!r}", argument="blocked",
                             value=blocked)
        self.blocked = blocked
        self._e = np.zeros(6)
        self.reset()
        self._tasks_hook(tasks, collision)

    def _init_jog(self, stop_sigma: float | None) -> None:
        """The jog's state and its bounds (`ProgressLimits`); ``stop_sigma`` None: where the
        solver starts to damp (its ``epsilon``), at least ``singular_sigma``."""
        if stop_sigma is None:
            stop_sigma = max(float(getattr(self.solver, "epsilon", 0.0) or 0.0), self.singular_sigma)
        self.stop_sigma = positive_number("stop_sigma", stop_sigma, allow_zero=True)
        jmax = self.filter.jmax if self.filter is not None else None  # jerk-limited only when smoothed
        self._bounds = ProgressLimits(self.chain, self.limits, jmax=jmax, accel_share=_SHARE,
                                          stop_sigma=self.stop_sigma,
                                          watch_sigma=max(4.0 * self.stop_sigma, 1e-6))
        self._jogger = Jog()
        # the straight approach, not with a solver that bends the path around rows of its own;
        # an arm of fewer than 6 joints cannot follow a line in 6-D: its approach starts anew
        # from the measured pose every period (straight toward the target from where it is)
        self._straight_servo = not solver_declares(self.solver, "adds_rows")
        self._pursuit = self.chain.dof < 6
        self._straight = StraightApproach(length=self.chain.characteristic_length)
        self._joint_line = JointLine()
        self._ik_tried: np.ndarray | None = None  # the last target an IK alternative was sought for
        self._line_blocked = ""
        self._lag_max = _LAG_MAX

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
        """Forget the state: previous q̇ (default zero; else a finite (n,) vector [rad/s or
        m/s], the motion the arm has now), halt latch, clock, smoother state."""
        if qd is None:
            qd_new = np.zeros(self._n)
        else:
            qd_new = np.array(_float_array(qd, "qd", f"{self._n} numbers"), dtype=float)
            if qd_new.shape != (self._n,) or not np.all(np.isfinite(qd_new)):
                raise InputError(f"reset: qd must be a finite ({self._n},) vector, got {qd!r}",
                                 argument="qd", value=qd)
        self._qd = qd_new
        self._qdd = np.zeros(self._n)
        self._q_last = None
        self._q_next_last = None
        self._latched = ""
        self._forget_approach()
        self._jogger.reset()
        self._singular_kind: str | None = None
        self._unreachable: np.ndarray | None = None  # the target last found out of reach
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

    def brake(self, dt: float, *, reason: str = "braking: no fresh measured state") -> Command:
        """One period of the safe halt without a measurement, not latched: the previous q̇
        decelerates toward zero, each joint by amax_i·dt (with smoothing, on its jerk-limited
        stop), continuing from the last commanded position. For a loop whose robot sent no
        fresh state this period (a dropped sample): the command then never extends a motion
        toward a limit. The next `step` resumes from the braked q̇. ``dt``: the period [s]."""
        dt = positive_number("dt", dt, unit="[s]")
        return self._halt(np.full(self._n, math.nan), dt, reason)

    @property
    def halted(self) -> bool:
        """True while a latched halt (non-finite input) is in force; cleared by `reset`."""
        return bool(self._latched)

    # ------------------------------------------------------------------ the cycle
    def step(self, q: ArrayLike, *, target: ArrayLike | None = None, twist: ArrayLike | None = None,
             dt: float, qd_ff: ArrayLike | None = None, qdd_ff: ArrayLike | None = None,
             stamp: float | None = None, frame: str = "base") -> Command:
        """One control cycle (see the module docstring): the stages
        `_validate` → `_halt_reason` → `_error` → `_solve` →
        `_limit` → `_smooth` → `_command`.

        Args:
            q: measured joint positions (n,).
            target: desired tool pose T_des (4×4) or None (no feedback).
            twist: tool twist ξ = [v; ω] (6,) [m/s; rad/s] at the tool point, or None: alone (no
                target, no ``qd_ff``), the twist to jog along (`Jog`: followed in its own
                direction or slowed down along it, never rotated); with a target, a feed-forward.
            dt: control period [s].
            qd_ff: joint-velocity feed-forward (n,) added to the resolved rate (e.g. the
                governor's planned q̇); ``twist`` is then the *extra* twist to resolve.
            qdd_ff: joint-acceleration feed-forward (n,), used by the smoother only (Ruckig's
                target acceleration, clipped to ±amax): with it the jerk-limited filter tracks a
                planned motion without lag.
            stamp: when the target was produced, on the controller clock ``ctrl.time`` [s];
                older than ``timeout`` → halt (stale target).
            frame: the axes of ``twist``: ``"base"`` (default) or ``"tool"`` (the tool frame's
                axes at the measured q; the twist is still taken at the tool point).
        """
        if frame != "base" and frame != "tool":
            raise InputError(f"frame must be 'base' or 'tool', got {frame!r}", argument="frame", value=frame)
        if stamp is not None:
            stamp = _checked_stamp(stamp)
        if self._tasks is not None and target is None and twist is None and qd_ff is None:
            return self._tasks_step(q, dt, stamp)  # tasks hook: targets come from the tasks
        return self._cycle(*self._validate(q, target, twist, dt, qd_ff, qdd_ff), stamp, frame)

    def _cycle(self, q: np.ndarray, target: np.ndarray | None, twist: np.ndarray | None, dt: float,
               qd_ff: np.ndarray | None, qdd_ff: np.ndarray | None, stamp: float | None,
               frame: str = "base") -> Command:
        """`step` after validation: the stages on float arrays."""
        halt = self._halt_reason(q, target, twist, dt, qd_ff, qdd_ff, stamp)
        if halt is not None:
            return halt
        if frame == "tool" and twist is not None:  # tool axes → base axes: [R v; R ω]
            R = self.chain.fk(q)[:3, :3]
            twist = np.concatenate([R @ twist[:3], R @ twist[3:]])
        servo = target is not None and qd_ff is None and (twist is None or not twist.any())
        cyc = _Cycle()
        if servo and self._straight_servo:
            self._jogger.reset()
            halt = self._servo(cyc, q, dt, target)
        elif target is None and qd_ff is None and twist is not None:
            self._forget_approach()
            halt = self._jog(cyc, q, dt, twist)
        else:
            self._jogger.reset()
            self._forget_approach()
            cyc = self._error(q, target, twist)
            halt = self._solve(cyc, q, dt, qd_ff)
        if halt is not None:
            return halt
        self._limit(cyc, q, dt)
        halt = self._smooth(cyc, q, dt, qdd_ff)
        if halt is not None:
            return halt
        if servo:
            assert target is not None
            self._arrival(cyc, target)
        return self._command(cyc, q, dt)

    def _arrival(self, cyc: _Cycle, target: np.ndarray) -> None:
        """``target-reached`` or ``target-unreachable`` (first in the flags, so it is the
        status). Reached: within the tolerances with the command at rest, its tool twist
        J q̇ within K·tolerance (linear and angular; what the proportional law asks at the
        tolerance). Unreachable: outside the tolerances with J q̇, and J (q̇ + q̈/K) one
        time constant ahead, below 1 % of that: the arm has stopped short, no motion within
        the limits lowers the error from here."""
        K = self.gain
        vtol = float(K[:3].max()) * self.position_tolerance
        wtol = float(K[3:].max()) * self.orientation_tolerance
        twist = cyc.J @ cyc.qd
        if not (math.hypot(*twist[:3].tolist()) <= vtol and math.hypot(*twist[3:].tolist()) <= wtol):
            return
        within = cyc.ep <= self.position_tolerance and cyc.eo <= self.orientation_tolerance
        if within:
            cyc.flags.insert(0, "target-reached")
            return
        if cyc.blocked:  # the straight line is blocked where the arm stands
            cyc.flags.insert(0, "target-unreachable")
            cyc.reasons.insert(0, f"stopped {cyc.ep * 1e3:.3g} mm / {math.degrees(cyc.eo):.3g}° from the "
                               f"target, {cyc.approach:.0%} of the way along the straight line to it, "
                               f"which is blocked: {cyc.blocked}")
            return
        # stopped short: below 1 % of that, now and one time constant ahead (an arm that
        # creeps toward a singular target, damped, is still on its way); once said for this
        # target, below 10 % (the last settling does not flicker back to "regular")
        said = self._unreachable is not None and np.array_equal(target, self._unreachable)
        vtol *= 0.1 if said else 0.01
        wtol *= 0.1 if said else 0.01
        ahead = cyc.J @ (cyc.qd + cyc.qdd * self._inv_kmax)
        if not (math.hypot(*twist[:3].tolist()) <= vtol and math.hypot(*twist[3:].tolist()) <= wtol
                and math.hypot(*ahead[:3].tolist()) <= vtol and math.hypot(*ahead[3:].tolist()) <= wtol):
            return
        if not said:
            self._unreachable = target.copy()
        cyc.flags.insert(0, "target-unreachable")
        cyc.reasons.insert(0, f"stopped at a best effort {cyc.ep * 1e3:.3g} mm / "
                           f"{math.degrees(cyc.eo):.3g}° from the target: no motion within the limits "
                           "lowers the pose error from here (the target is out of reach)")

    # --- stage 1: validation (shapes raise, values halt)
    def _validate(self, q: ArrayLike, target: ArrayLike | None, twist: ArrayLike | None, dt: float,
                  qd_ff: ArrayLike | None, qdd_ff: ArrayLike | None,
                  ) -> tuple[np.ndarray, np.ndarray | None, np.ndarray | None, float,
                             np.ndarray | None, np.ndarray | None]:
        """Shapes and types: returns ``(q, target, twist, dt, qd_ff, qdd_ff)`` as float arrays
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
            if isinstance(dt, (str, bytes)):  # float("1e-3") would parse: a period is a number
                raise TypeError
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
        if qdd_ff is not None:
            qdd_ff = _float_array(qdd_ff, "qdd_ff", f"{n} numbers")
            if qdd_ff.shape != (n,):
                raise InputError(f"qdd_ff must have shape ({n},) [rad/s² or m/s²], got {qdd_ff.shape}",
                                 argument="qdd_ff", value=qdd_ff)
        return q, target, twist, dt, qd_ff, qdd_ff

    def _halt_reason(self, q, target, twist, dt, qd_ff, qdd_ff, stamp) -> Command | None:
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
        elif qdd_ff is not None and not _finite_sum(qdd_ff):
            bad = "qdd_ff"
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
            age = self.time - stamp
            if not age <= self.timeout:
                return self._halt(q, dt, f"stale target: {age:.3g} s old > timeout {self.timeout:.3g} s")
            if age < -self.timeout:  # from the future: the producer's clock is not this controller's
                return self._halt(q, dt, f"target stamped {-age:.3g} s ahead of the controller clock "
                                  f"ctrl.time (more than timeout {self.timeout:.3g} s): stamp it on "
                                  "ctrl.time")
        return None

    # --- stage 2: the pose error and the twist to resolve
    def _error(self, q, target, twist) -> _Cycle:
        """fk and J at q, the pose error e = [p_d − p; log(R_d Rᵀ)] and the twist
        ξ = ξ_ff + K e to resolve; returns the cycle's working state."""
        cyc = _Cycle()
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

    # --- stage 3: the inverse-velocity solve
    def _solve(self, cyc: _Cycle, q, dt, qd_ff) -> Command | None:
        """q̇ = q̇_ff + solver(J, ξ); a solver failure or a non-finite answer halts (returns
        the halt's Command), otherwise fills ``cyc.qd``, ``cyc.res`` and the status lists."""
        # with smoothing the filter bounds the acceleration (and the jerk) of what is
        # commanded; a solver's acceleration box around the filter's lagging output would
        # throttle it (the QP's answer at q̇_f ± amax·dt keeps Ruckig's target within one
        # period of its state: the arm then accelerates at a fraction of amax)
        qd_prev = self._qd if self.filter is None else None
        try:
            # the solver's entry for validated inputs (`Solver.solve_validated`): q, dt and
            # q̇_ff were checked by this cycle, the previous q̇ is this controller's finite
            # state, J and ξ its own float arrays; it returns the correction on top of q̇_ff
            res = self._solve_entry(cyc.J, cyc.xi, limits=self.limits, q=q, qd_prev=qd_prev, dt=dt,
                                    qd_ff=qd_ff)
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

    # --- stage 3b: the straight approach to a target
    def _servo(self, cyc: _Cycle, q, dt, target) -> Command | None:
        """The straight approach (`StraightApproach`): fk and J at q, the segment (a new one
        when the target changed), one period of the progress within the joint limits mapped
        onto it (`ProgressLimits`), and the solve of ξ = ṡ̄·d + K·e_ref, the mean progress
        speed of the period along the direction plus feedback on the error to the reference
        pose T(s)."""
        T, J = self.chain.fk_jacobian(q)
        cyc.J = J
        cyc.target = True
        ap = self._straight
        jl = self._joint_line
        if jl.target is not None:
            if np.array_equal(target, jl.target):
                return self._joint_servo(cyc, q, dt, target, T, J)
            jl.reset()  # a new target: a straight line again, from where the arm is
            ap.reset()
        if ap.target is None or self._pursuit or not np.array_equal(target, ap.target):
            if ap.target is None:  # a first target: from the measured pose and the arm's motion
                ap.retarget(target, T, J @ self._qd, J @ self._qdd)
            elif self._pursuit:  # from the measured pose, the progress's own motion carried on
                ap.retarget(target, T, ap.sd * ap.d, ap.sdd * ap.d)
            else:  # a new target: from the reference, which goes on without a jump
                ap.retarget(target, ap.pose(ap.s), ap.sd * ap.d, ap.sdd * ap.d)
        e = cyc.e = np.zeros(6)
        cyc.ep, cyc.eo = pose_error_into(e, target, T)
        e_ref = np.zeros(6)
        pose_error_into(e_ref, ap.pose(ap.s), T)
        lag = ap.weighted_norm(e_ref)
        if lag > self._lag_max:
            # the arm is held off its line (a solver's extra rows such as collision avoidance,
            # or a robot that lags): a new straight segment from where it is, with its motion
            ap.retarget(target, T, J @ self._qd, J @ self._qdd)
            e_ref[:] = 0.0
            lag = 0.0
            cyc.reasons.append("held off the straight line by more than "
                               f"{self._lag_max * 1e3:.3g} mm: a new line from where the arm is")
        caps = None
        w = None
        speed = 0.0
        if ap.L > 0.0:
            try:
                res_w = self._direction(J, ap.d, q, dt)
            except SingularityError as err:
                return self._halt(q, dt, f"singular: {err}", status="singular", sigma_min=err.sigma_min,
                                  error=cyc.e, ep=cyc.ep, eo=cyc.eo)
            except (RatectlError, np.linalg.LinAlgError) as err:
                return self._halt(q, dt, f"solver failed: {err}", error=cyc.e, ep=cyc.ep, eo=cyc.eo)
            w = np.array(res_w.qd, dtype=float)
            if ap.end_accel == math.inf and not self._pursuit and ap.settled:
                self._end_bounds(ap, q, target, dt)  # (a target that moves every period: not yet)
            caps = self._bounds.caps(q, w, dt=dt, sigma=self._sigma_for_watch(res_w),
                                       w_prime=ap.w_prime(w),
                                     exact=lambda q2: self._exact_direction(q2, ap.d))
            w_rate = None if ap.w_prev is None else (w - ap.w_prev) / dt  # ẇ, for the smoother
            # (the room ahead is measured from the arm; the reference leads it along the line)
            speed = ap.advance(caps, dt, speed_scale=max(0.0, 1.0 - lag / self._lag_max),
                               lead=ap.weighted_dot(e_ref, ap.d))
            if self.filter is not None:
                # the filter integrates exactly: its target is the state at the end of the
                # period (ṡ₁ with s̈₁), where q + q̇·dt needs the period's mean speed
                speed = ap.sd
            ap.w_prev = w
        cyc.xi = ap.d * speed + self.gain * e_ref
        halt = self._solve(cyc, q, dt, None)
        if halt is not None:
            return halt
        if w is not None and self.filter is not None:
            # the reference's acceleration s̈·w + ṡ·ẇ, which the filter then meets without lag
            cyc.qdd_ff = w * ap.sdd if w_rate is None else w * ap.sdd + w_rate * ap.sd
            cyc.approach_qd = cyc.qd
        if caps is not None:
            moving = ap.sd > 0.0 or speed > 0.0
            if ap.blocked:  # the stop is planned before a block (a limit, a singularity)
                at_block = not moving and ap.room_left <= _AT_BLOCK
                caps.binding, caps.reason = caps.room_by, caps.room_reason
                caps.blocked_by = caps.room_by if at_block else ""
                self._progress_flags(cyc, q, caps, moving, True)
                cyc.blocked = caps.room_reason if at_block else ""
            else:
                if caps.binding in ("position", "singularity"):
                    caps.binding = ""  # (those bounds are the room ahead, which is not the stop)
                self._progress_flags(cyc, q, caps, moving, ap.sd >= caps.free_speed * (1.0 - 1e-9))
            cyc.approach = ap.s / ap.L
            if cyc.blocked and self.blocked == "joint-space":
                self._try_joint_line(cyc, q, target)
        return None

    def _end_bounds(self, ap: StraightApproach, q, target, dt) -> None:
        """The progress's acceleration bound at the end of the line, where the arm will be:
        from the target's inverse kinematics (the IK core `ratectl.solvers.ik`, from the
        measured q, on the arm's branch) and the direction's q̇ there; a stop planned within
        the smaller of it and the present bound stays feasible as J changes on the way.
        Once per line (NaN when no solution was found: the present bound alone)."""
        res = ik_iterate(self.chain, target, q, tol_position=self.position_tolerance,
                         tol_orientation=self.orientation_tolerance, max_iter=30, damping=0.05,
                         max_step=0.2)
        ap.end_accel = math.nan
        if not res.converged:
            return
        q_end = np.array(res.q)
        try:
            w_end = np.array(self._direction(self.chain.jacobian(q_end), ap.d, q_end, dt).qd, dtype=float)
        except (RatectlError, np.linalg.LinAlgError):
            return
        if _finite_sum(w_end):
            ap.end_accel = self._bounds.caps(q_end, w_end, dt=dt).accel

    def _forget_approach(self) -> None:
        """No approach in progress: the next target starts a new one from where the arm is."""
        self._straight.reset()
        self._joint_line.reset()
        self._ik_tried = None

    def _try_joint_line(self, cyc: _Cycle, q, target) -> None:
        """The straight line is blocked where the arm stands: the alternative is a straight
        line in joint space (`JointLine`) to an inverse-kinematics solution of the target on
        the arm's own branch (the IK core `ratectl.solvers.ik`, from the measured q, steps of
        at most 0.1 rad, within the joint limits). Taken when that solution is verified (the
        pose within a tenth of the tolerances); then the tool leaves its line, the reason
        says why; otherwise the line stays blocked (``target-unreachable``). Tried once per
        target."""
        if self._ik_tried is not None and np.array_equal(target, self._ik_tried):
            return
        self._ik_tried = target.copy()
        res = ik_iterate(self.chain, target, q, tol_position=0.1 * self.position_tolerance,
                         tol_orientation=0.1 * self.orientation_tolerance, max_iter=200,
                         damping=0.05, max_step=0.1)
        if not res.converged:
            cyc.blocked += "; no inverse-kinematics solution within the joint limits from here"
            return
        self._joint_line.start(target, q, np.array(res.q), self._qd)
        self._line_blocked = cyc.blocked
        cyc.reasons.append(f"the straight line is blocked ({cyc.blocked}): moving in joint space to an "
                           "inverse-kinematics solution of the target instead (the tool leaves the line)")
        cyc.blocked = ""

    def _joint_servo(self, cyc: _Cycle, q, dt, target, T, J) -> Command | None:
        """One period on the `JointLine`: q̇ = ṡ̄·u + K·(q(s) − q) (the progress within the
        joint limits, w = u; feedback on the joint reference), its tool twist J q̇ reported."""
        jl = self._joint_line
        e = cyc.e = np.zeros(6)
        cyc.ep, cyc.eo = pose_error_into(e, target, T)
        q_ref = jl.q_at(jl.s)
        caps = self._bounds.caps(q, jl.u, dt=dt)
        speed = jl.advance(caps, dt)
        if self.filter is not None:
            speed = jl.sd
            cyc.qdd_ff = jl.u * jl.sdd
        qd = jl.u * speed + (q_ref - q) * (1.0 / self._inv_kmax if self._inv_kmax > 0.0 else 0.0)
        cyc.qd = cyc.approach_qd = qd
        cyc.xi = J @ qd
        cyc.res = SolveResult(qd=qd, achieved=cyc.xi, task_error=np.zeros(6), damping=0.0,
                              sigma_min=float("nan"), method="joint-line")
        cyc.approach = jl.s / jl.L if jl.L > 0.0 else 1.0
        cyc.reasons.append(f"moving in joint space to an inverse-kinematics solution of the target "
                           f"({cyc.approach:.0%}): the straight line is blocked ({self._line_blocked})")
        return None

    # --- stage 3c: jogging along a twist
    def _direction(self, J: np.ndarray, d: np.ndarray, q: np.ndarray, dt: float) -> Any:
        """The solver's answer for the direction ``d`` (6,) without the joint limits (which
        bound the progress instead): q̇ per unit of progress (``.qd``), with σ_min available
        from the result. ``q`` and ``dt`` go to solvers that need them (extra rows)."""
        return self.solver.solve(J, d, q=q, dt=dt)

    def _exact_direction(self, q: np.ndarray, d: np.ndarray) -> tuple[float, float]:
        """(σ_min, share) at ``q`` from one SVD J = U S Vᵀ: σ_min(J), and the share of the
        exact joint speed |J⁺d|² = Σ (uᵢ·d / σᵢ)² that goes into the weakest direction
        (the singularity look-ahead of `ProgressLimits`: is ``d`` being lost?)."""
        U, S, Vt = np.linalg.svd(self.chain.jacobian(q), full_matrices=False)
        if S.shape[0] < 6 or not S[-1] > S[0] * 1e-12:
            return 0.0, 1.0
        c = (U.T @ d) / S
        total = float(c @ c)
        return float(S[-1]), (float(c[-1] * c[-1]) / total if total > 0.0 else 0.0)

    def _sigma_for_watch(self, res: Any) -> float | None:
        """σ_min of a direction solve when it may be below the watch threshold, else None
        (decided without computing σ_min when the result can)."""
        at_least = getattr(res, "sigma_min_at_least", None)
        if at_least is not None and at_least(self._bounds.watch_sigma):
            return None
        smin = float(res.sigma_min)
        return smin if smin < self._bounds.watch_sigma else None

    def _jog(self, cyc: _Cycle, q, dt, twist) -> Command | None:
        """Jogging (`Jog`): q̇ = c·J⁺ξ with c ∈ [0, 1] within the joint limits mapped onto the
        commanded direction (`ProgressLimits`): the tool moves along ξ or slows down along it,
        never sideways."""
        J = cyc.J = self.chain.jacobian(q)
        cyc.e = shared_zeros(6)
        cyc.ep = cyc.eo = 0.0
        cyc.target = False
        jog = self._jogger
        if jog.twist is None and twist.any():  # a first twist: c from the arm's present motion
            moving = J @ self._qd
            jog.c = min(max(float(moving @ twist) / float(twist @ twist), 0.0), 1.0)
        jog.start(twist)
        if not twist.any():
            jog.c = 0.0
            cyc.xi = twist.copy()
            return self._solve(cyc, q, dt, None)
        try:
            res_w = self._direction(J, twist, q, dt)
        except SingularityError as err:
            return self._halt(q, dt, f"singular: {err}", status="singular", sigma_min=err.sigma_min)
        except (RatectlError, np.linalg.LinAlgError) as err:
            return self._halt(q, dt, f"solver failed: {err}")
        w = np.array(res_w.qd, dtype=float)
        if not _finite_sum(w):
            return self._halt(q, dt, "solver returned a non-finite q̇")
        wp = jog.w_prev
        w_prime = (w - wp) / (jog.c * dt) if (wp is not None and jog.c > 0.0) else None
        caps = self._bounds.caps(q, w, dt=dt, sigma=self._sigma_for_watch(res_w), w_prime=w_prime,
                                   exact=lambda q2: self._exact_direction(q2, twist))
        c_prev = jog.c
        c = jog.advance(caps, dt)
        jog.w_prev = w
        cyc.xi = twist * c
        if self._enforcing:
            halt = self._solve(cyc, q, dt, None)
            if halt is not None:
                return halt
        else:
            cyc.res = res_w
            cyc.qd = w * c
            cyc.active = []
            cyc.scale = 1.0
            cyc.smin = None
        self._progress_flags(cyc, q, caps, c > 0.0, c >= caps.speed * (1.0 - 1e-9) and c < 1.0)
        if c > c_prev and c < min(1.0, caps.speed) * (1.0 - 1e-12):
            cyc.flags.append("acceleration-limited")
            cyc.reasons.append(f"accelerating along the commanded twist within amax ({c:.3g}× the twist)")
            cyc.active.append("acceleration")
        if "velocity" in cyc.active or caps.binding == "velocity":
            cyc.scale = c
        return None

    def _progress_flags(self, cyc: _Cycle, q, caps, moving: bool, at_bound: bool) -> None:
        """Status flags and reasons of a progress bound (approach or jog)."""
        if caps.binding == "singularity" and (at_bound or caps.blocked_by):
            if caps.blocked_by and not moving:
                cyc.flags.append("halted-singularity")
            else:
                cyc.flags.append("approaching-singularity")
            kind = self._singular_kind
            if kind is None:  # named once per encounter: `analyze` with a wide "near" band
                kind = self._singular_kind = str(analyze(self.chain, q, near=_KIND_NEAR).kind)
            cyc.kind = kind
            cyc.reasons.append(caps.reason.replace("a singularity", f"a {kind} singularity", 1))
            return
        elif caps.binding == "position" and (at_bound or caps.blocked_by):
            cyc.flags.append("joint-limit")
            cyc.reasons.append(caps.reason)
            cyc.active.append("position")
        elif caps.binding in ("velocity", "curvature") and at_bound and moving:
            cyc.flags.append("velocity-scaled")
            cyc.active.append("velocity")
            cyc.reasons.append(f"moving at the speed limit of joint {self._bounds.name(caps.joint)} "
                               "along the commanded direction")

    # --- stage 4: the limits
    def _limit(self, cyc: _Cycle, q, dt) -> None:
        """Velocity, acceleration and position limits on ``cyc.qd`` (in that order; see the
        module docstring), or only the report of them for a solver that enforces them."""
        enforcing = self._enforcing
        if enforcing:
            # the solver (the QP, possibly with extra rows such as collision limits) already
            # bounds q̇ by the velocity, position and acceleration limits; limiting again here
            # would move q̇ off its optimum and could break its extra rows
            info = _info(cyc.res)
            cyc.qd, cyc.scale = self._report_solver_limits(cyc, cyc.res, cyc.qd, cyc.flags,
                                                           cyc.reasons, cyc.scale, info)
            if self._has_p:
                self._report_solver_recovery(cyc, q, dt, info)
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
            reference = None  # the progress reference is not met exactly: the worst case one period ahead
            wanted = cyc.qd
            cyc.qd, cyc.braking = self._jerk_limited_position_guard(q, cyc.qd, dt, cyc.flags,
                                                                    cyc.reasons, cyc.active, reference)
            if cyc.approach_qd is not None and cyc.qd is not wanted:
                # an approach keeps its direction: the guard's clip scales the whole motion
                cyc.qd = _scaled_like(wanted, cyc.qd)
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
        """Clip each joint's q̇ to the speed from which it can still stop before its limits
        (`speed_toward_limit`: the braking bound `braking_speed_any_dt`, valid when dt
        changes between cycles; beyond a limit, back into the range within vmax and amax,
        never further out). The position side wins over the acceleration limit: a joint
        whose measured q jumped inside its stopping distance brakes harder than amax for
        one period (status ``limit-recovery``) rather than run past its limit."""
        hi_v, lo_v = self._position_box(q, dt)
        clipped = np.minimum(np.maximum(cyc.qd, lo_v), hi_v)
        changed = clipped != cyc.qd
        hard = None
        ratio = 0.0
        if changed.any():
            joints = np.flatnonzero(changed)
            cyc.qd = clipped
            if "joint-limit" in cyc.flags:  # (the approach held some already: one status)
                cyc.flags.remove("joint-limit")
            cyc.flags.insert(0, "joint-limit")
            cyc.reasons.insert(0, f"joint(s) {self._named(joints)} held at a position limit")
            cyc.active.append("position")
            if self.filter is None:  # (with smoothing the filter then keeps amax and jmax)
                step = np.abs(clipped - self._qd) * self._inv_amax_f / dt
                hard = changed & (step > 1.0 + 1e-9)
                ratio = float(step.max())
        self._report_limit_recovery(cyc, q, hard, ratio)  # also a joint measured beyond a limit

    def _position_box(self, q, dt) -> tuple[np.ndarray, np.ndarray]:
        """(hi, lo): the position side of each joint's velocity box, `speed_toward_limit` toward
        the upper limit and (mirrored) the lower one, from the previous q̇; both sides in one
        stacked call."""
        n = self._n
        b = speed_toward_limit(np.concatenate([self._phi - q, q - self._plo]),
                               np.concatenate([self._qd, -self._qd]), dt=dt, two_over_a=self._two_over_a2,
                               adt=self._amax_f2 * dt, vmax=self._vf2)
        return b[:n], -b[n:]

    def _report_solver_recovery(self, cyc: _Cycle, q, dt, info: Mapping[str, Any]) -> None:
        """``limit-recovery`` for a limit-enforcing solver: its box resolved a conflict of
        the acceleration bound against the position bound (``info["conflicts"]``, the
        position side won), or a joint is measured beyond a position limit."""
        conflicts = info.get("conflicts", ())
        if not conflicts:
            # a joint beyond a limit? (on Python floats: cheaper than two numpy comparisons)
            ql = q.tolist()
            if not (any(map(_gt, ql, self._phi_l)) or any(map(_lt, ql, self._plo_l))):
                return
        hard = np.zeros(self._n, dtype=bool)
        for joint, kinds in conflicts:
            if "acceleration" in kinds:
                hard[joint] = True
        step = np.abs(cyc.qd - self._qd) * self._inv_amax_f / dt
        self._report_limit_recovery(cyc, q, hard, float(step[hard].max()) if hard.any() else 0.0)

    def _report_limit_recovery(self, cyc: _Cycle, q, hard: np.ndarray | None, ratio: float) -> None:
        """Status ``limit-recovery`` (with the reason) for the joints ``hard`` (bool mask) whose
        position bound changed q̇ by more than amax·dt (``ratio`` = the largest |Δq̇|/(amax·dt)),
        and for joints measured beyond a position limit."""
        out = (q > self._phi) | (q < self._plo)
        some_hard = hard is not None and bool(hard.any())
        if not (some_hard or out.any()):
            return
        cyc.flags.insert(0, "limit-recovery")
        if some_hard:
            assert hard is not None
            cyc.reasons.insert(0, f"joint(s) {self._named(hard)} measured within the "
                               "stopping distance of a position limit (or beyond it): braking at "
                               f"{ratio:.3g}× amax to stay inside the range")
        if out.any():
            cyc.reasons.insert(0, f"joint(s) {self._named(out)} measured beyond a position "
                               "limit: commanded back into the range, never further out")

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
            if self._has_p:
                self._smoothed_limit_recovery(cyc, q, dt)
        else:
            cyc.q_next = q + cyc.qd * dt
            cyc.qdd = (cyc.qd - self._qd) / dt
        return None

    def _smoothed_limit_recovery(self, cyc: _Cycle, q, dt) -> None:
        """The position side wins over the filter's jerk and acceleration limits: a joint
        whose smoothed motion would end this period beyond a position limit (further out
        than it is measured) — possible only after a fault, a measured q that jumped inside
        the jerk-limited stopping distance — is commanded, for this period, the largest
        speed that still leaves room for the filter's own jerk-limited stop from rest
        acceleration afterwards (≤ `speed_toward_limit`; beyond a limit: back into the
        range, never further out); its filter state is set to that velocity with the
        period's mean acceleration clipped to ±amax, or 0 where that would speed the joint
        up (``Command.qdd``), and the status is ``limit-recovery``. The later periods are
        then jerk-limited again."""
        q_next = cyc.q_next
        tol = 1e-12 * (1.0 + np.abs(q))
        out = (q_next > np.maximum(self._phi, q) + tol) | (q_next < np.minimum(self._plo, q) - tol)
        f = self.filter
        assert f is not None
        if cyc.braking is not None and cyc.braking.any():
            # a joint the guard brakes: is it already inside its stopping distance? (for the
            # others even the guard's look-ahead stop fits, so the stop from now fits too)
            out |= self._inside_stopping_distance(q, f, cyc.braking)
        if not out.any():
            return
        bounds = []
        hi_b, lo_b = self._position_box(q, dt)
        for room, b in ((self._phi - q, hi_b), (q - self._plo, -lo_b)):
            # after this period the filter brakes jerk-limited from (b, 0): that stop must fit
            rest = np.maximum(room - np.maximum(b, 0.0) * dt, 0.0)
            bounds.append(np.where(room >= 0.0, np.minimum(b, braking_speed(rest, f.amax, f.jmax)), b))
        qd = np.where(out, np.minimum(np.maximum(cyc.qd, -bounds[1]), bounds[0]), cyc.qd)
        cyc.q_next = np.where(out, q + qd * dt, q_next)
        fd = (qd - self._qd) / dt
        ratio = float(np.max(np.abs(fd[out]) * self._inv_amax_f[out]))
        # the filter goes on from there, at the period's mean acceleration clipped to ±amax,
        # or 0 where that would still speed the joint up: its jerk-limited stop from that
        # state is no longer than from (q̇, 0), which fits the room left
        acc = np.where(fd * qd > 0.0, 0.0, np.minimum(np.maximum(fd, -f.amax), f.amax))
        cyc.qdd = np.where(out, acc, cyc.qdd)
        cyc.qd = qd
        f.reset(qd, cyc.qdd)
        joints = np.flatnonzero(out).tolist()
        cyc.flags.insert(0, "limit-recovery")
        cyc.reasons.insert(0, f"joint(s) {self._named(joints)} measured inside their jerk-limited "
                           "stopping distance of a position limit (or beyond it): smoothing overridden for "
                           "one period, "
                           f"braking at {ratio:.3g}× amax to stay inside the range (never further out)")
        if "position" not in cyc.active:
            cyc.active.append("position")

    def _inside_stopping_distance(self, q, f, braking: np.ndarray) -> np.ndarray:
        """Joints (mask) among ``braking`` that can no longer stop before a position limit
        from the filter state (q̇, q̈) at the start of the period: the exact distance of the
        time-optimal jerk-limited stop toward the limit it moves to (`stopping_distance`
        with ``exact_when_braking``, what Ruckig does when told to stop) exceeds the room.
        The guard never lets that happen (it starts braking while the stop still fits):
        only a fault does. The default `stopping_distance` (an over-estimate while braking)
        screens the joints first; the exact one is computed only for those it flags."""
        inside = np.zeros(self._n, dtype=bool)
        i = np.flatnonzero(braking & (self._qd != 0.0))
        if not i.size:
            return inside
        up = self._qd[i] > 0.0  # moving toward the upper limit, else toward the lower one
        room = np.where(up, self._phi[i] - q[i], q[i] - self._plo[i])
        v = np.abs(self._qd[i])
        a = np.where(up, self._qdd[i], -self._qdd[i])
        A, Jm = f.amax[i], f.jmax[i]
        limit = room * (1.0 + 1e-9) + 1e-12
        cand = (room >= 0.0) & (stopping_distance(v, a, A, Jm) > limit)
        if cand.any():
            k = np.flatnonzero(cand)
            cand[k] = stopping_distance(v[k], a[k], A[k], Jm[k], exact_when_braking=True) > limit[k]
        inside[i] = cand
        return inside

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
        if cyc.kind is None:
            self._singular_kind = None
        if cyc.flags:
            status = min(cyc.flags, key=_RANK.__getitem__)
            flags = tuple(dict.fromkeys(cyc.flags))
        else:
            status, flags = "regular", ("regular",)
        res = cyc.res
        active = cyc.active
        return make_command({"qd": qd, "q_next": cyc.q_next, "qdd": cyc.qdd.copy(), "status": status,
                             "flags": flags, "reason": "; ".join(cyc.reasons), "error": cyc.e,
                             "position_error": cyc.ep, "orientation_error": cyc.eo, "twist": cyc.xi,
                             # lazy: the result's σ_min, read on first access
                             "sigma_min": res if cyc.smin is None else cyc.smin,
                             "damping": float(res.damping), "task_error": res.task_error,
                             "velocity_scale": cyc.scale,
                             "limits_active": tuple(dict.fromkeys(active)) if active else (),
                             "time": t0, "dt": dt, "solve": res}, self.chain, self._q_last, kind=cyc.kind)

    def _jerk_limited_position_guard(self, q, qd, dt, flags, reasons, active, qdd_ref=None):
        """Keep a smoothed joint inside its position range: the Ruckig filter lags the
        command, so braking must start while the jerk-limited stop still fits.

        From the filter's state (v, a) the worst case one period ahead towards a limit is
        a₁ = min(a + J·dt, A), v₁ = v + a·dt + J·dt²/2 after travelling v·dt + a·dt²/2 +
        J·dt³/6. If the jerk-limited stop from (v₁, a₁) (`
        stopping_distance`) no longer fits in the room left, the command towards that
        limit is 0 now (Ruckig then brakes time-optimally); otherwise it is at most
        `braking_speed` of the room. The same mirrored towards
        the lower limit. Returns (q̇, braking): the joints that must stop, which the filter
        then moves time-optimally on their own instead of synchronised with the others.

        With the approach's reference (q̇, ``qdd_ref``), which the filter meets exactly, the
        next state is known instead of the worst case: a joint whose jerk-limited stop from
        that state, after the period's constant-jerk travel v·dt + a·dt²/2 + (a₁ − a)·dt²/6,
        still fits before its limit keeps the reference."""
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
        if qdd_ref is not None:
            travel = v * dt + 0.5 * a * dt * dt + (qdd_ref - a) * (dt * dt / 6.0)
            slack = Jm * dt**3  # more than any other one-period motion to the same state travels
            # the exact stop of a reference that is already braking (counting its deceleration
            # as 0 over-estimates the stop: a plan braking onto a goal at the limit was cut off
            # and the other joints ran ahead of the line)
            fits = ((stopping_distance(qd, qdd_ref, A, Jm, exact_when_braking=True)
                     < room_up - travel - slack)
                    & (stopping_distance(-qd, -qdd_ref, A, Jm, exact_when_braking=True)
                       < room_lo + travel - slack))
            hi_v = np.where(fits, np.inf, hi_v)
            lo_v = np.where(fits, -np.inf, lo_v)
            stop_up = stop_up & ~fits
            stop_lo = stop_lo & ~fits
        clipped = np.minimum(np.maximum(qd, lo_v), hi_v)
        changed = clipped != qd
        if changed.any():
            # reported only where the clip changes the motion (not a 1e-13 rad/s remainder)
            joints = np.flatnonzero(np.abs(clipped - qd) > 1e-9).tolist()
            if joints:
                if "joint-limit" not in flags:
                    flags.insert(0, "joint-limit")
                moving = np.abs(v[joints]).max() > 1e-9
                what = ("braking for a position limit (jerk-limited stop)" if moving
                        else "held at a position limit")
                reasons.insert(0, f"joint(s) {self._named(joints)} {what}")
                active.append("position")
        else:
            clipped = qd  # unchanged: the same array (the approach's acceleration stays valid)
        return clipped, stop_up | stop_lo  # the braking joints stop time-optimally, on their own

    def _named(self, joints) -> str:
        """The chain's names of ``joints`` (a boolean mask or indices), for reasons."""
        idx = np.flatnonzero(joints) if np.asarray(joints).dtype == bool else np.asarray(joints, dtype=int)
        names = self.chain.joint_names
        return ", ".join(repr(names[int(i)]) for i in np.ravel(idx))

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

    def _report_solver_limits(self, cyc, res, qd, flags, reasons, scale, info):
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
            reasons.insert(0, f"QP: joint(s) {self._named(joints)} held by a position limit")
        if "velocity" in kinds:
            smin = self._sigma(cyc)
            if smin < self.singular_sigma:
                flags.insert(0, "singular")
                reasons.append(f"near a singularity (σ_min = {smin:.3g}) the QP holds joint(s) "
                               f"{joints} at vmax")
            else:
                flags.append("velocity-scaled")
                reasons.append(f"QP: joint(s) {self._named(joints)} at vmax")
        if "acceleration" in kinds:
            flags.append("acceleration-limited")
            reasons.append(f"QP: joint(s) {self._named(joints)} at the acceleration bound")
        extra = info.get("extra_active")
        if extra is not None and np.any(extra):
            reasons.append(f"{int(np.count_nonzero(extra))} extra constraint row(s) active "
                           "(e.g. collision avoidance)")
        return qd, scale

    # ------------------------------------------------------------------ tasks hook
    # Several tasks with strict priorities and collision dampers: the cycle is
    # `ratectl.control.tasks_stage.TasksStage`; this section only wires it in.
    def _tasks_hook(self, tasks, collision) -> None:
        """``tasks=`` / ``collision=``: build the `TasksStage` (None when neither is given)."""
        self._tasks = None
        if tasks is None and collision is None:
            return
        if self.filter is not None:
            raise InputError("tasks= does not combine with smoothing yet: the cascade bounds the "
                             "acceleration itself; pass smoothing=False", argument="smoothing",
                             value=self._smoothing_option)
        from .tasks_stage import TasksStage

        self._tasks = TasksStage(self.chain, list(tasks or ()), list(collision or ()))

    def _tasks_step(self, q, dt, stamp) -> Command:
        """One cycle of the tasks: validate, halt on bad values, solve the cascade, command."""
        q, _, _, dt, _, _ = self._validate(q, None, None, dt, None, None)
        halt = self._halt_reason(q, None, None, dt, None, None, stamp)
        if halt is not None:
            return halt
        assert self._tasks is not None
        try:
            res = self._tasks.solve(q, dt=dt, qd_prev=self._qd, limits=self.limits)
        except (RatectlError, np.linalg.LinAlgError) as err:
            return self._halt(q, dt, f"tasks: {err}")
        qd = res.qd.copy()
        qdd = (qd - self._qd) / dt
        q_next = q + qd * dt
        self._q_next_last = q_next.copy()
        self._qd = qd.copy()
        self._qdd = qdd
        self._q_last = q.copy()
        t0 = self.time
        self.time = t0 + dt
        flags = res.flags or ("regular",)
        status = min(flags, key=_RANK.__getitem__)
        e = np.zeros(6)
        ep = eo = float("nan")
        for t in self._tasks.tasks:  # the tool pose task's error, when there is one
            if type(t).__name__ == "Pose" and getattr(t, "link", None) is None and t.has_target:
                e = t.rows(self.chain, q).error.copy()
                ep, eo = float(np.linalg.norm(e[:3])), float(np.linalg.norm(e[3:]))
                break
        return make_command({"qd": qd, "q_next": q_next, "qdd": qdd.copy(), "status": status,
                             "flags": flags, "reason": "; ".join(res.reasons), "error": e,
                             "position_error": ep, "orientation_error": eo, "twist": np.zeros(6),
                             "sigma_min": float("nan"), "damping": 0.0, "task_error": res.residuals,
                             "velocity_scale": 1.0, "limits_active": res.limits_active, "time": t0,
                             "dt": dt, "solve": res}, self.chain, self._q_last)

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
        return make_command({"qd": qd, "q_next": q_next, "qdd": qdd.copy(), "status": status,
                             "flags": (status,), "reason": reason,
                             "error": np.zeros(6) if error is None else error.copy(),
                             "position_error": ep, "orientation_error": eo, "twist": np.zeros(6),
                             "sigma_min": sigma_min, "damping": 0.0, "task_error": np.zeros(6),
                             "velocity_scale": 0.0, "limits_active": (), "time": t0, "dt": dt,
                             "solve": None}, self.chain, self._q_last)

    def __repr__(self) -> str:
        return (f"ResolvedRateController({self.chain.name!r}, solver={type(self.solver).__name__}, "
                f"gain={self.gain.tolist()}, smoothing={self.filter is not None})")
