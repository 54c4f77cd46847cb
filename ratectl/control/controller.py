"""The resolved-rate controller: one call per control cycle.

``ctrl.step(q, target=T_des, twist=ξ_ff, dt=dt)`` computes

    e  = [p_d − p ; log(R_d Rᵀ)]              (pose error, base axes)
    ξ  = ξ_ff + K e                           (feed-forward plus proportional feedback)
    q̇  = q̇_ff + solver(J(q), ξ)               (inverse velocity; q̇_ff optional)

The controller composes stage objects, each owning its state, in the order of a cycle
(``_cycle``):

1. the gate (`ratectl.control.gate`): shapes and types, and the halt policy for values;
2. a target alone is a servo (`ratectl.control.servo`: the straight line to it, a
   jerk-limited progress within the joint limits, a joint-space alternative where the line
   is blocked); a twist alone is a jog along it (`ratectl.control.jog`); both share
   `ratectl.control.progress_stage`. Otherwise the pose error and the solve
   (`ratectl.control.solve_stage`) through the solver's validated entry
   (`Solver.solve_validated`);
3. the limits (`ratectl.control.limiter`): velocity (uniform scaling), acceleration (the
   change of q̇ scaled into amax·dt), joint position (braking in time whatever the later
   periods are; after a fault the position side wins, ``limit-recovery``). What a solver
   that enforces the limits itself (``enforces_limits``) answered under its bounds is only
   reported; the servo's and the jog's commands are always limited here (uniformly: a box
   would turn the tool's motion);
4. optionally a Ruckig velocity filter (``_smooth``) inside its position guard
   (`ratectl.control.smooth_stage`), and the integration ``q_next = q + q̇ dt``;
5. the servo's arrival status and the `Command` (``_command``); a halt's braking motion is
   `ratectl.control.halt`, the tasks hook `ratectl.control.tasks_hook`, the options
   `ratectl.control.options`.

Every call returns a frozen `Command` whose ``status`` says what happened (see
`STATUSES`). Bad *values* never raise in the loop: a non-finite input, a target that is not
a rigid pose, a target older than ``timeout``, or a solver failure brings a **safe halt**
(the previous q̇ decelerates to zero within the limits) with the reason in
``Command.reason``; a non-finite input latches it until `ResolvedRateController.reset`.
Wrong *shapes* are programming errors and raise `InputError` at once.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike

from ..checks import positive_number
from ..errors import InputError, RatectlError
from ..model.limits import Limits
from ..solvers.base import solver_declares, validated_solve
from .command import _RANK, STATUSES, Command, make_command
from .cycle import Cycle, Motion
from .gate import Gate, _checked_stamp, _float_array
from .halt import brake
from .jog import JogStage
from .limiter import Limiter
from .options import _checked_filter, _checked_gain, _checked_solver, default_solver
from .progress_stage import ProgressStage
from .servo import Servo
from .smooth_stage import SmoothGuard
from .smoothing import VelocityFilter
from .solve_stage import SolveStage
from .tasks_hook import smoothed_tasks_motion, tasks_command, tasks_stage

if TYPE_CHECKING:
    from ..model.chain import Chain
    from ..solvers.base import Solver

__all__ = ["ResolvedRateController", "Command", "STATUSES", "default_solver"]


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
        timeout: a target or twist whose ``stamp`` is older than this [s] is stale (halt).
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
        self._solve_entry = validated_solve(self.solver)  # the solver contract (`Solver`)
        self._enforcing = solver_declares(self.solver, "enforces_limits")
        self.gain = _checked_gain(gain)
        if isinstance(limits, str):
            if limits != "chain":
                raise InputError(f"limits must be 'chain', None or a limits object, got {limits!r}",
                                 argument="limits", value=limits)
            limits = chain
        self.limits = None if limits is None else Limits.of(limits, n)
        self.filter: VelocityFilter | None = _checked_filter(smoothing, chain)
        self.position_tolerance = positive_number("position_tolerance", position_tolerance, unit="[m]")
        self.orientation_tolerance = positive_number("orientation_tolerance", orientation_tolerance,
                                                     unit="[rad]")
        self.timeout = positive_number("timeout", timeout, allow_inf=True, unit="[s]")
        self.singular_sigma = positive_number("singular_sigma", singular_sigma, allow_zero=True)
        if stop_sigma is None:  # where the solver starts to damp, at least singular_sigma
            stop_sigma = max(_damping_starts(self.solver), self.singular_sigma)
        self.stop_sigma = positive_number("stop_sigma", stop_sigma, allow_zero=True)
        if blocked not in ("joint-space", "stop"):
            raise InputError(f"blocked must be 'joint-space' or 'stop', got {blocked!r}", argument="blocked",
                             value=blocked)
        self.blocked = blocked
        # the stages, in the order of a cycle; they share the last command (`Motion`)
        self._m = m = Motion(n)
        self._gate = Gate(n, self.timeout)
        self._solver_stage = SolveStage(chain, gain=self.gain, entry=self._solve_entry, limits=self.limits,
                                        motion=m, filter=self.filter, halt=self._halt,
                                        enforcing=self._enforcing)
        self._error, self._solve = self._solver_stage.error, self._solver_stage.solve
        self._progress = ProgressStage(chain, self.solver, self.limits, self.filter,
                                       stop_sigma=self.stop_sigma)
        self._servo = Servo(chain, self._progress, m, self.filter, gain=self.gain,
                            position_tolerance=self.position_tolerance,
                            orientation_tolerance=self.orientation_tolerance, blocked=blocked,
                            solve=self._solve, adopt=self._solver_stage.adopt, halt=self._halt)
        self._jog = JogStage(chain, self._progress, m, adds_rows=solver_declares(self.solver, "adds_rows"),
                             solve=self._solve, halt=self._halt)
        self._limiter = Limiter(chain, self.limits, m, self.filter, singular_sigma=self.singular_sigma,
                                constant_damping=self._enforcing)
        self._guard = None if self.filter is None else SmoothGuard(self._limiter, self.filter, m)
        # the straight approach, not with a solver that bends the path around rows of its own
        self._straight_servo = not solver_declares(self.solver, "adds_rows")
        self.reset()
        self._tasks_hook(tasks, collision)

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
        self._m.qd = qd_new
        self._m.qdd = np.zeros(self._n)
        self._q_last: np.ndarray | None = None
        self._m.q_next = self._m.q_lead = None
        self._gate.reset()
        self._servo.reset()
        self._jog.reset()
        self._progress.singular_kind = None
        self.time = 0.0
        if self.filter is not None:
            self.filter.reset(self._m.qd)
        reset = getattr(self.solver, "reset", None)
        if callable(reset):
            reset()

    @property
    def qd(self) -> np.ndarray:
        """The last commanded joint velocity."""
        return self._m.qd.copy()

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
        return bool(self._gate.latched)

    # ------------------------------------------------------------------ the cycle
    def step(self, q: ArrayLike, *, target: ArrayLike | None = None, twist: ArrayLike | None = None,
             dt: float, qd_ff: ArrayLike | None = None, qdd_ff: ArrayLike | None = None,
             stamp: float | None = None, frame: str = "base") -> Command:
        """One control cycle (see the module docstring and `_cycle`).

        Args:
            q: measured joint positions (n,).
            target: desired tool pose T_des (4×4) or None (no feedback).
            twist: tool twist ξ = [v; ω] (6,) [m/s; rad/s] at the tool point, or None: alone (no
                target, no ``qd_ff``), the twist to jog along (`Jog`: followed in its own
                direction or slowed down along it, never rotated); with a target, a feed-forward.
            dt: control period [s]; when it varies, the time since the previous step (the
                difference of the robot's stamps, as ``rc.run`` passes it): a moving
                target's velocity is estimated as its change over dt.
            qd_ff: joint-velocity feed-forward (n,) added to the resolved rate (e.g. the
                governor's planned q̇); ``twist`` is then the *extra* twist to resolve.
            qdd_ff: joint-acceleration feed-forward (n,), used by the smoother only (Ruckig's
                target acceleration, clipped to ±amax): with it the jerk-limited filter tracks a
                planned motion without lag.
            stamp: when the target (or, jogging, the twist) was produced, on the controller
                clock ``ctrl.time`` [s]; older than ``timeout`` → halt (stale target or twist:
                a teleoperator's last twist is not followed on once its stream stops).
            frame: the axes of ``twist``: ``"base"`` (default) or ``"tool"`` (the tool frame's
                axes at the measured q; the twist is still taken at the tool point).
        """
        if frame != "base" and frame != "tool":
            raise InputError(f"frame must be 'base' or 'tool', got {frame!r}", argument="frame", value=frame)
        if stamp is not None:
            stamp = _checked_stamp(stamp)
        if self._tasks is not None:  # tasks hook: the targets come from the tasks
            _refuse_with_tasks(target=target, twist=twist, qd_ff=qd_ff)
            return self._tasks_step(q, dt, stamp)
        return self._cycle(*self._gate.validate(q, target, twist, dt, qd_ff, qdd_ff), stamp, frame)

    def _cycle(self, q: np.ndarray, target: np.ndarray | None, twist: np.ndarray | None, dt: float,
               qd_ff: np.ndarray | None, qdd_ff: np.ndarray | None, stamp: float | None,
               frame: str = "base") -> Command:
        """`step` after validation, the stages on float arrays: the gate's halt policy
        (`Gate`), then the approach to a target alone (`Servo`), the jog along a twist
        alone (`JogStage`) or the pose error and the solve (`_error`, `_solve`), then the
        limits (`Limiter`), the smoothing (`_smooth`, with its `SmoothGuard`), the servo's
        arrival status and the command (`_command`)."""
        halt = self._halt_reason(q, target, twist, dt, qd_ff, qdd_ff, stamp)
        if halt is not None:
            return halt
        if frame == "tool" and twist is not None:  # tool axes → base axes: [R v; R ω]
            R = self.chain.fk(q)[:3, :3]
            twist = np.concatenate([R.dot(twist[:3]), R.dot(twist[3:])])
        servo = target is not None and qd_ff is None and (twist is None or not twist.any())
        cyc = Cycle()
        if servo and self._straight_servo:
            self._jog.reset()
            halt = self._servo.step(cyc, q, dt, target)
        elif target is None and qd_ff is None and twist is not None:
            self._servo.forget()
            halt = self._jog.step(cyc, q, dt, twist)
        else:
            self._jog.reset()
            self._servo.forget()
            cyc = self._error(q, target, twist)
            halt = self._solve(cyc, q, dt, qd_ff)
        if halt is not None:
            return halt
        near = self._limiter.limit(cyc, q, dt)
        halt = self._smooth(cyc, q, dt, qdd_ff, near)
        if halt is not None:
            return halt
        if servo:
            assert target is not None
            self._servo.arrival(cyc, target)
        return self._command(cyc, q, dt)

    def _halt_reason(self, q, target, twist, dt, qd_ff, qdd_ff, stamp) -> Command | None:
        """The gate's verdict on the cycle's values (`Gate.check`): the halt's `Command`, or
        None when the cycle may proceed."""
        halt = self._gate.check(q, target, twist, dt, qd_ff, qdd_ff, stamp, self.time)
        return None if halt is None else self._halt(q, halt[1], halt[0])

    # --- smoothing and integration
    def _smooth(self, cyc: Cycle, q, dt, qdd_ff, near: bool = False) -> Command | None:
        """The Ruckig filter (if any) turns ``cyc.qd`` into a jerk-limited motion and gives
        its exact integral, inside the position guard (`SmoothGuard`: before the filter when
        a joint is ``near`` a position limit, after it against a fault); without it
        q_next = q + q̇ dt, q̈ = (q̇ − q̇_prev)/dt."""
        if self.filter is not None:
            assert self._guard is not None
            if near:
                self._guard.guard(cyc, q, dt)
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
            if self._limiter.has_p:
                self._guard.recover(cyc, q, dt)
        else:
            cyc.q_next = q + cyc.qd * dt
            cyc.qdd = (cyc.qd - self._m.qd) / dt
        return None

    # --- the command
    def _advance(self, q, q_next, qd, qdd, dt) -> float:
        """Record a command (the measured or base q, q_next, q̇, q̈) as the controller's
        state and advance its clock by ``dt``; returns the period's start time [s]."""
        self._m.commanded(q, self._q_last, q_next)  # the lead, before q̇ and q become this command's
        self._m.q_next = q_next.copy()
        self._m.qd = qd.copy()
        self._m.qdd = qdd
        self._q_last = q.copy()
        t0 = self.time
        self.time = t0 + dt
        return t0

    def _command(self, cyc: Cycle, q, dt) -> Command:
        """Update the controller state and return the cycle's frozen `Command`
        (its arrays are read-only and not shared with the controller's state)."""
        qd = cyc.qd
        t0 = self._advance(q, cyc.q_next, qd, cyc.qdd, dt)
        if cyc.kind is None:
            self._progress.singular_kind = None
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

    # ------------------------------------------------------------------ tasks hook
    # Several tasks with strict priorities and collision dampers: the cycle is
    # `ratectl.control.tasks_stage.TasksStage`; `ratectl.control.tasks_hook` wires it in.
    def _tasks_hook(self, tasks, collision) -> None:
        """``tasks=`` / ``collision=``: build the `TasksStage` (None when neither is given)."""
        self._tasks = tasks_stage(self.chain, tasks, collision)

    def _tasks_step(self, q, dt, stamp) -> Command:
        """One cycle of the tasks: validate, halt on bad values, solve the cascade, command."""
        q, _, _, dt, _, _ = self._gate.validate(q, None, None, dt, None, None)
        halt = self._halt_reason(q, None, None, dt, None, None, stamp)
        if halt is not None:
            return halt
        assert self._tasks is not None
        smoothed = self.filter is not None
        try:
            # with smoothing the filter bounds q̈ and q⃛ of what is commanded: no acceleration
            # box around its lagging output (as for a smoothed QP)
            res = self._tasks.solve(q, dt=dt, qd_prev=None if smoothed else self._m.qd, limits=self.limits)
        except (RatectlError, np.linalg.LinAlgError) as err:
            return self._halt(q, dt, f"tasks: {err}")
        flags: tuple[str, ...] = ()
        reasons: tuple[str, ...] = ()
        if smoothed:
            try:
                out = smoothed_tasks_motion(
                    res, q, dt, smooth=self._smooth, near=self._limiter._near_position_limit(q, dt),
                    filter=self.filter, qd_prev=self._m.qd,
                    resolve=lambda: self._tasks.solve(q, dt=dt, qd_prev=self._m.qd, limits=self.limits))
            except (RatectlError, np.linalg.LinAlgError) as err:
                return self._halt(q, dt, f"tasks: {err}")
            if isinstance(out, Command):
                return out
            res, qd, qdd, q_next, flags, reasons = out
        else:
            qd = res.qd  # (read-only: the result's, shared with the command)
            period = self._tasks.period(dt)  # (dt as an array: cheaper arithmetic, the same numbers)
            qdd = (qd - self._m.qd) / period
            q_next = q + qd * period
        t0 = self._advance(q, q_next, qd, qdd, dt)
        assert self._q_last is not None
        return tasks_command(self._tasks, self.chain, res, q_next, qd, qdd, t0, dt, self._q_last,
                             flags=flags, reasons=reasons)

    # ------------------------------------------------------------------ halting
    def _halt(self, q, dt, reason, *, status="halted", sigma_min=float("nan"), error=None,
              ep=float("nan"), eo=float("nan")) -> Command:
        """Bring the joints to rest together, along the direction they move in (`brake`,
        `ratectl.control.halt`: the slowest joint's own stop, the others scaled to it; with
        smoothing the filter's synchronised jerk-limited stop); a joint whose share of that
        stop would run past its position limit brakes on its own at its full rate. The
        motion continues from the measured q, or — when q is not finite — from the last
        commanded position, so the commanded stream stays continuous. The servo's approach is
        forgotten: its reference went on while the arm braked, so the next target starts a
        new line from where the arm is, with the motion the halt commanded."""
        self._servo.forget()
        qd_prev = self._m.qd
        if np.all(np.isfinite(q)):
            base = q
        else:
            base = self._m.q_next if self._m.q_next is not None else self._q_last
        if base is None:
            base = np.zeros(self._n)
        q_next, qd, qdd, reason = brake(base, qd_prev, dt, self.filter, self.limits, reason)
        t0 = self._advance(base, q_next, qd, qdd, dt)
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


def _refuse_with_tasks(target: Any = None, twist: Any = None, qd_ff: Any = None) -> None:
    """A controller with tasks takes q and dt only: ``target=``, ``twist=`` or ``qd_ff=``
    would bypass every task (a posture, collision rows), so they raise `InputError`."""
    if target is None and twist is None and qd_ff is None:
        return  # (every cycle)
    for name, value in (("target", target), ("twist", twist), ("qd_ff", qd_ff)):
        if value is not None:
            raise InputError(f"this controller resolves its tasks (tasks=[...]) and takes q and dt only, "
                             f"got {name}=: set each task's target with task.set_target(...)",
                             argument=name, value=value)


def _damping_starts(solver: Any) -> float:
    """The σ_min below which ``solver`` damps what it solves (the feedback, a twist with a
    target): an adaptive solver's ``epsilon``, a constant λ (``damping``: the QP, DLS); 0
    for the others. A jog or an approach stops there before a singularity by default (its
    direction, `Solver.solve_direction`, stays exact below, with joint speeds ∝ 1/σ_min)."""
    for name in ("epsilon", "damping"):
        v = getattr(solver, name, None)
        if isinstance(v, int | float) and v > 0.0:
            return float(v)
    return 0.0
