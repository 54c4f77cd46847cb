"""Drive a robot in real time: `run`.

Every period ``1/rate_hz`` the loop

1. reads the robot (``driver.read()``) — a *fresh* state is one whose stamp advanced;
2. evaluates the reference at the robot's time t = stamp − stamp₀ (a path: the governor's
   pose P(s) and joint feed-forward, the same `PathReference` as `follow`, its progress
   re-timed from the measured joints so it never runs away from a lagging arm; a fixed
   target; or a twist stream);
3. ``cmd = controller.step(q_measured, target=T_d(t), twist=ξ(t), qd_ff=..., dt=dt)`` with dt
   the robot's own period (the stamps' difference), so vmax and amax hold over the real
   periods, not the nominal one;
4. sends ``driver.command(cmd.qd)`` — on a stale cycle (no fresh state: a dropped or late
   sample) the controller is stepped on the predicted state (the last one advanced by the
   command sent), so its limits brake from where the command has taken the arm; stale for
   longer than half the watchdog, the controller's brake (`ResolvedRateController.brake`) is
   sent instead;
5. sleeps until the next deadline ``t₀ + (k+1)/rate_hz``. It never busy-waits: a spinning
   loop holds Python's GIL and starves anything else in the process (a simulator's server
   thread, a robot library's receive thread). Deadlines are absolute, so an oversleep in
   one period shortens the next and the mean rate holds; a cycle whose work ends after its
   deadline is an *overrun*: the next cycle starts at once, and when the loop is more than
   a whole period behind the schedule restarts from now (missed slots are skipped, never
   made up in a burst).

Safety (every way out stops the robot with ``driver.stop()`` and returns the record):

* **watchdog** — no fresh state for longer than ``timeout``: halt at once (status
  ``"halted"``, reason ``"watchdog: ..."``). The decision is taken within ``timeout`` plus
  one period of the last fresh state;
* **a robot that does not follow its command** (`ratectl.execution.following.FollowWatch`:
  commanded against measured motion over ``follow_window``): the controller brakes to rest
  (status ``"halted"``, the reason names the joint);
* **a non-finite measured state** (NaN or inf in q or q̇): the controller's latched safe
  halt decelerates the last command to zero within the acceleration limits, then the
  robot is stopped;
* **a driver error** (any exception from ``read()`` or ``command()``, foreign or not) or an
  exception of the reference (a twist callable): the robot is stopped, the record says why,
  and nothing is raised;
* **Ctrl-C** (``KeyboardInterrupt``): the robot is stopped first. With
  ``on_interrupt="raise"`` (default) the ``KeyboardInterrupt`` is then re-raised, with the
  record attached as its ``execution`` attribute — a script stops, as Ctrl-C asks; with
  ``"return"`` the record is returned (status ``"interrupted"``).

The statuses per step are the controller's (``ratectl.control.STATUSES``); the record's
``message`` and ``info["reason"]`` say why a run ended.
"""

from __future__ import annotations

import math
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, TextIO

import numpy as np
from numpy.typing import ArrayLike

from ..checks import positive_number as _positive
from ..control import Command, ResolvedRateController
from ..drivers.base import Driver, RobotState
from ..errors import DriverError, InputError
from ..model import Chain
from ..paths import Path
from ..planning import Governor, GovernorPlan
from ..singularity import analyze
from ..spatial import pose_error, rigid_transform_defect
from .following import FollowWatch as _FollowWatch
from .integral import GapIntegral
from .record import Execution
from .reference import PathReference

__all__ = ["run"]

_END_SPEED = 1e-3  # |q̇| [rad/s] below which a halted command counts as "at rest"
_TIMING = ("read", "control", "command", "work")  # per-cycle work times recorded [s]


# ---------------------------------------------------------------------- validation and set-up
def _check_driver(driver: object) -> None:
    missing = [m for m in ("read", "command", "stop") if not callable(getattr(driver, m, None))]
    if missing or not hasattr(driver, "chain"):
        raise InputError(
            "driver must follow the ratectl.drivers.Driver protocol (chain, read(), command(qd), "
            f"stop()); {type(driver).__name__} lacks {missing or ['chain']}",
            argument="driver",
            value=driver,
        )


def _is_tty(stream: TextIO) -> bool:
    try:
        return bool(stream.isatty())
    except (AttributeError, ValueError, OSError):
        return False


class _StatusLine:
    """A one-line live report on stderr, rewritten in place at most every 0.25 s."""

    def __init__(self, enabled: bool, stream: TextIO | None = None) -> None:
        self.enabled = enabled
        self.stream = stream if stream is not None else sys.stderr
        self.next = 0.0
        self.written = False

    def update(self, now: float, text: str) -> None:
        if self.enabled and now >= self.next:
            self.next = now + 0.25
            self.stream.write("\r" + text[:110].ljust(110))
            self.stream.flush()
            self.written = True

    def close(self) -> None:
        if self.written:
            self.stream.write("\n")
            self.stream.flush()


@dataclass(eq=False)
class _Reference:
    """The reference of a run: what the controller is given at robot time t, and when it ends.

    ``mode`` is "path", "target" or "twist". `at` moves ``Td`` (the target pose, None for a
    twist stream), ``s`` (the path parameter [m]) and the joint feed-forward ``qd_ff``/``qdd_ff``
    (a governed path) to time t and returns the feed-forward twist ξ(t) [v; ω] (None: no
    twist, or the stream ended). A path's progress is a `PathReference` (`progress`), the
    one `follow` uses, re-timed here from the measured joints.
    """

    mode: str
    limit: float  # the longest the run may last [s] (robot time)
    path: Path | None = None
    target: np.ndarray | None = None  # a fixed target pose (4, 4)
    twist: np.ndarray | None = None  # a fixed twist (6,)
    twist_fn: Callable[[float], ArrayLike | None] | None = None
    Td: np.ndarray | None = None  # the current target pose
    s: float = 0.0  # the current path parameter [m]
    settle_start: float | None = None  # robot time the path's end was reached [s]
    progress: PathReference | None = None  # a path's progress (set by `_govern`)
    plan: GovernorPlan | None = None
    qd_ff: np.ndarray | None = None  # the joint feed-forward of this cycle
    qdd_ff: np.ndarray | None = None
    xi: np.ndarray | None = None  # the twist of this cycle
    smoothed: bool = False  # the controller smooths (qd_ff, qdd_ff continuous)

    def __post_init__(self) -> None:
        self.Td = self.target

    @property
    def on_end_pose(self) -> bool:
        """True when "within tolerance of the end pose" ends the run (a target, a settled path)."""
        return self.mode == "target" or (self.mode == "path" and self.settle_start is not None)

    def at(self, t: float, dt: float, q: np.ndarray | None, h: float) -> np.ndarray | None:
        """The reference at robot time t, ``dt`` [s] of robot time after the previous one, for
        the measured joints ``q``, commanding a period ``h`` [s] ahead."""
        prog = self.progress
        if prog is not None:
            if self.settle_start is None:
                prog.advance(dt, q)
                r = prog.at(h, smoothed=self.smoothed)
                self.s, self.Td, self.qd_ff, self.qdd_ff = r.s, r.pose, r.qd_ff, r.qdd_ff
                if prog.finished:
                    self.settle_start = t
                self.xi = r.twist
                return r.twist
            self.s, self.Td, self.qd_ff, self.qdd_ff = prog.end_s, prog.end_pose, None, None
            self.xi = None
            return None
        if self.mode == "twist":
            xi = self.twist if self.twist_fn is None else self.twist_fn(t)
            self.xi = None if xi is None else np.asarray(xi, dtype=float)
            return self.xi
        return None


def _one_reference(path: object, target: object, twist: object) -> None:
    given = [name for name, v in (("path", path), ("target", target), ("twist", twist)) if v is not None]
    if len(given) != 1:
        raise InputError(
            f"give exactly one of path=, target=, twist= (got {given or 'none'})",
            argument="path",
            value=given,
        )


def _reference(
    path: Path | None, target: ArrayLike | None, twist: object, duration: float | None, settle: float
) -> _Reference:
    """The one given reference, checked, with its time limit [s]: ``duration``, or by default the
    path's duration + ``settle``, 10 s for a target, unbounded for a twist stream."""
    if path is not None:
        if not isinstance(path, Path):
            raise InputError(
                f"path must be a ratectl.paths.Path, got {type(path).__name__}", argument="path", value=path
            )
        return _Reference("path", path.duration + settle if duration is None else duration, path=path)
    if target is not None:
        defect = rigid_transform_defect(target)
        if defect is not None:
            raise InputError(f"target {defect}", argument="target", value=target)
        Td = np.array(target, dtype=float)
        return _Reference("target", 10.0 if duration is None else duration, target=Td)
    limit = math.inf if duration is None else duration
    if callable(twist):
        return _Reference("twist", limit, twist_fn=twist)
    try:
        if isinstance(twist, str | bytes) or np.iscomplexobj(twist):  # type: ignore[arg-type]
            raise TypeError("twist")
        xi = np.asarray(twist, dtype=float)
    except (TypeError, ValueError, OverflowError):
        xi = np.full(1, np.nan)
    if xi.shape != (6,) or not np.all(np.isfinite(xi)):
        raise InputError(
            "twist must be a finite 6-vector [v; ω] or a callable twist(t)", argument="twist", value=twist
        )
    return _Reference("twist", limit, twist=xi)


def _tolerance(tolerance: Any) -> tuple[float, float]:
    """``tolerance`` as (position [m], orientation [rad]), both positive finite numbers."""
    if isinstance(tolerance, str | bytes) or not hasattr(tolerance, "__len__") or len(tolerance) != 2:
        raise InputError(
            f"tolerance must be a pair (position [m], orientation [rad]) of positive numbers, "
            f"got {tolerance!r}",
            argument="tolerance",
            value=tolerance,
        )
    pos, ori = tolerance
    return (_positive("tolerance[0] (position)", pos, unit="[m]"),
            _positive("tolerance[1] (orientation)", ori, unit="[rad]"))


def _first_state(driver: Driver, ref: _Reference) -> RobotState:
    """The robot's state before anything moves; a path must start at its tool pose."""
    chain, name = driver.chain, type(driver).__name__
    try:
        state0 = driver.read()
    except Exception as exc:
        raise DriverError(
            f"the first read() of {name} failed: {type(exc).__name__}: {exc}", driver=name, cause=exc
        ) from exc
    if not state0.finite or state0.q.shape != (chain.dof,):
        raise DriverError(
            f"the first state of {name} is unusable (shape {state0.q.shape}, "
            f"finite {state0.finite}); expected {chain.dof} finite joint values",
            driver=name,
        )
    if ref.path is not None:
        e0 = pose_error(ref.path.start, chain.fk(state0.q))
        if np.linalg.norm(e0[:3]) > 1e-3 or np.linalg.norm(e0[3:]) > 1e-2:
            raise InputError(
                f"the path starts {np.linalg.norm(e0[:3]) * 1e3:.3g} mm / "
                f"{math.degrees(np.linalg.norm(e0[3:])):.3g}° from the robot's tool pose; servo "
                "there first with rc.run(driver, target=path.start)",
                argument="path",
                value=ref.path,
            )
    return state0


def _controller(controller: ResolvedRateController | None, chain: Chain) -> ResolvedRateController:
    """The controller for ``chain`` (a new one by default), reset."""
    if controller is not None and not isinstance(controller, ResolvedRateController):
        raise InputError(
            f"controller must be a ratectl.ResolvedRateController or None, got {controller!r}"[:200],
            argument="controller",
            value=controller,
        )
    ctrl = controller if controller is not None else ResolvedRateController(chain)
    if getattr(ctrl, "chain", chain).dof != chain.dof:
        raise InputError(
            f"the controller was built for a {ctrl.chain.dof}-joint arm, the driver has {chain.dof}",
            argument="controller",
            value=controller,
        )
    ctrl.reset()
    return ctrl


def _warm_up(
    ctrl: ResolvedRateController,
    ref: _Reference,
    state0: RobotState,
    period: float,
    given: ResolvedRateController | None,
) -> None:
    """One controller step on the first state, then a reset: first-call costs (generated kernels,
    caches) must not land in the first period."""
    try:
        ctrl.step(state0.q, target=ref.target if ref.path is None else ref.path.start, dt=period)
    except Exception as exc:
        raise InputError(
            f"the controller cannot step on the first state: {type(exc).__name__}: {exc}",
            argument="controller",
            value=given,
        ) from exc
    ctrl.reset()


def _govern(
    ref: _Reference,
    chain: Chain,
    q0: np.ndarray,
    period: float,
    governor: Governor | bool | None,
    ctrl: ResolvedRateController,
    duration: float | None,
    settle: float,
) -> None:
    """A path's progress: the governor's plan from the first measured state (as `follow`
    plans it), or the path's own time law (``governor`` False or None); the time limit
    becomes the plan's duration + ``settle`` unless a ``duration`` was given."""
    if ref.path is None:
        return
    if not (governor is None or isinstance(governor, bool | Governor)):
        raise InputError(
            f"governor must be True, False or a ratectl.planning.Governor, got {governor!r}",
            argument="governor",
            value=governor,
        )
    plan = None
    if governor is not False and governor is not None:
        gov = governor if isinstance(governor, Governor) else Governor(check_jerk=ctrl.filter is not None)
        plan = gov.plan(chain, ref.path, q0, dt=period)
    ref.plan = plan
    ref.progress = PathReference(ref.path, plan)
    ref.smoothed = ctrl.filter is not None
    if duration is None:
        ref.limit = ref.progress.duration + settle


def _integral(integral: object, n: int) -> GapIntegral | None:
    """The integral action of a path run (``integral`` checked), or None when switched off."""
    if isinstance(integral, bool | np.bool_):
        return GapIntegral(n) if integral else None
    gain = _positive("integral", integral, allow_zero=True, unit="[1/s]")
    return GapIntegral(n, gain=gain) if gain > 0.0 else None


# ---------------------------------------------------------------------- run
def run(
    driver: Driver,
    *,
    path: Path | None = None,
    target: ArrayLike | None = None,
    twist: ArrayLike | Callable[[float], ArrayLike | None] | None = None,
    controller: ResolvedRateController | None = None,
    rate_hz: float = 500.0,
    duration: float | None = None,
    timeout: float = 0.1,
    settle: float = 1.0,
    tolerance: tuple[float, float] = (1e-4, 1e-3),
    status_line: bool | None = None,
    on_interrupt: str = "raise",
    governor: Governor | bool | None = True,
    path_tolerance: tuple[float, float] = (1e-3, math.radians(0.5)),
    follow_window: float = 0.5,
    integral: bool | float | ArrayLike = True,
) -> Execution:
    """Run the resolved-rate controller on a robot in real time; returns an `Execution`.

    Give exactly one reference:

    * ``path`` — a `ratectl.paths.Path` starting at the robot's current tool pose
      (within 1 mm / 0.01 rad; servo there first with ``target=path.start``): governed
      by default (target P(s) and the planned joint velocity as feed-forward, the progress
      re-timed from the measured state), then up to ``settle`` seconds on the end pose until
      at rest within ``tolerance``; completed only if it stayed within ``path_tolerance``;
    * ``target`` — a 4×4 tool pose to servo to; ends when within ``tolerance``;
    * ``twist`` — a tool twist [v; ω] (6,) [m/s; rad/s], or a callable ``twist(t)`` of the
      time since the start [s] returning one, or None to end the stream.

    Args:
        driver: a `ratectl.drivers.Driver` (its ``chain`` is the controller's model).
        controller: a `ResolvedRateController` for ``driver.chain``
            (default: a new one with the chain's limits). It is reset first.
        rate_hz: loop rate [Hz]; the controller's dt is 1/rate_hz.
        duration: the longest the run may last [s] (robot time). Default: the path's duration
            + ``settle``; 10 s for a target; unbounded for a twist stream (it ends when the
            callable returns None, or on Ctrl-C).
        timeout: the watchdog [s]: no fresh state for longer → safe halt.
        settle: time allowed after a path's end to converge on the end pose [s].
        tolerance: (position [m], orientation [rad]) for "reached", both positive.
        status_line: a live one-line status on stderr; None (default) shows it when stderr is
            a terminal and the run may last longer than 2 s.
        on_interrupt: ``"raise"`` (re-raise Ctrl-C after stopping the robot, with the record
            as ``exc.execution``) or ``"return"`` (return the record).
        governor: a path's timing, as in `follow`: True (default, a `Governor` planned from
            the first measured state), a `Governor`, or False/None (the path's own time law).
        path_tolerance: (position [m], orientation [rad]) a path run must stay within from
            start to end to count as completed (measured on the measured poses).
        follow_window: the window [s] over which commanded and measured motion are compared
            (`FollowWatch`); 0 switches the check off.
        integral: a path run's integral action on the joints' tracking gap (`GapIntegral`:
            closes the steady-state error friction leaves, with anti-windup): True (default,
            K_I = 10 /s), a gain K_I [1/s], or False (proportional only). Target and twist runs
            have none.

    Returns:
        An `Execution` with source ``"run"``: ``q``/``q_measured`` the measured joint
        positions, ``qd_measured`` the measured velocities, ``qd``/``qdd`` the commanded
        velocity and its change, ``q_commanded`` the positions the commands lead to, tool
        poses fk(q_measured), the path (or target) errors, the controller's ``statuses``,
        ``reasons`` and ``kinds`` for every cycle, ``t`` the robot time of each cycle, the
        robot's stamps, loop periods and overruns. ``info`` (a read-only mapping) holds
        ``plan`` (a path's `GovernorPlan`, or None), ``twist_linear_error`` and
        ``twist_angular_error`` (a twist stream: measured J q̇ against the stream, per cycle),
        ``gap_correction`` (a path run: the integral action's joint correction per cycle, (K, n)),
        ``reason`` (why the run ended), ``halt_delay`` (watchdog: time from the last fresh
        state to the halt decision [s]), ``timing`` (per-cycle read, control, command and
        total work times [s]) and ``stop_error`` (if ``driver.stop()`` failed).

    Raises:
        InputError: a bad argument (before anything moves).
        DriverError: the very first ``read()`` failed (before anything moves).
        KeyboardInterrupt: Ctrl-C with ``on_interrupt="raise"``, after the robot was stopped.
    """
    _check_driver(driver)
    chain = driver.chain
    _one_reference(path, target, twist)
    rate_hz = _positive("rate_hz", rate_hz)
    timeout = _positive("timeout", timeout)
    duration = None if duration is None else _positive("duration", duration)
    settle = _positive("settle", settle, allow_zero=True, unit="[s]")
    if on_interrupt not in ("raise", "return"):
        raise InputError(
            f"on_interrupt must be 'raise' or 'return', got {on_interrupt!r}",
            argument="on_interrupt",
            value=on_interrupt,
        )
    pos_tol, ori_tol = _tolerance(tolerance)
    if status_line is not None and not isinstance(status_line, bool | np.bool_):
        raise InputError(f"status_line must be True, False or None, got {status_line!r}",
                         argument="status_line", value=status_line)
    period = 1.0 / rate_hz
    ref = _reference(path, target, twist, duration, settle)
    ctrl = _controller(controller, chain)
    state0 = _first_state(driver, ref)  # nothing moves before the loop
    _warm_up(ctrl, ref, state0, period, controller)
    _govern(ref, chain, state0.q, period, governor, ctrl, duration, settle)
    show = status_line if status_line is not None else (_is_tty(sys.stderr) and ref.limit > 2.0)
    pi = _integral(integral, chain.dof) if ref.mode == "path" else None
    loop = _Loop(
        driver,
        ctrl,
        ref,
        state0,
        period=period,
        timeout=timeout,
        tolerance=(pos_tol, ori_tol),
        line=_StatusLine(bool(show)),
        follow_window=follow_window,
        integral=pi,
    )
    loop.run()
    path_tol = (float(path_tolerance[0]), float(path_tolerance[1]))
    ex = _execution(loop, chain, rate_hz, path_tol)
    if loop.interrupted is not None and on_interrupt == "raise":
        loop.interrupted.execution = ex  # type: ignore[attr-defined]  # the record rides on the exception
        raise loop.interrupted
    return ex


# ---------------------------------------------------------------------- the loop
class _Loop:
    """The state of one run: the trace so far, the watchdog, the schedule and how it ended.

    `_Loop.run` calls `_Loop.cycle` (read → watchdog → reference and controller step →
    command → record → end conditions → wait) until it returns False, then stops the robot
    (`_Loop.stop`); `_execution` makes the record from the trace. ``outcome`` is "completed", "halted",
    "interrupted" or "timeout" (the duration ran out), "" while running; ``reason`` says why.
    """

    def __init__(
        self,
        driver: Driver,
        ctrl: ResolvedRateController,
        ref: _Reference,
        state0: RobotState,
        *,
        period: float,
        timeout: float,
        tolerance: tuple[float, float],
        line: _StatusLine,
        follow_window: float = 0.5,
        integral: GapIntegral | None = None,
    ) -> None:
        self.driver, self.ctrl, self.ref, self.state0, self.line = driver, ctrl, ref, state0, line
        self.integral = integral
        self.settled = False  # the last fresh step was on the end pose within tolerance
        self.gap_u: list[np.ndarray] = []  # the integral correction of each cycle
        self.watch = _FollowWatch(driver.chain, follow_window)
        self.period, self.timeout, self.tolerance = period, timeout, tolerance
        self.n = n = driver.chain.dof
        # the trace: one entry per recorded cycle (periods: per cycle started, popped when the
        # cycle ends the run without a record)
        self.stamps: list[float] = []
        self.q: list[np.ndarray] = []
        self.qd_measured: list[np.ndarray] = []
        self.qd: list[np.ndarray] = []
        self.qdd: list[np.ndarray] = []
        self.statuses: list[str] = []
        self.reasons: list[str] = []
        self.q_cmd: list[np.ndarray] = []  # the commanded position q_next of each cycle
        self.xi: list[np.ndarray | None] = []  # the reference twist of each cycle
        self.t: list[float] = []  # robot time of each cycle [s] (estimated on stale cycles)
        self.sigma: list[float] = []
        self.Td: list[np.ndarray | None] = []
        self.s: list[float] = []
        self.fresh: list[bool] = []
        self.periods: list[float] = []
        self.timing: list[tuple[float, float, float, float]] = []  # (read, control, command, work) [s]
        self.zero = np.zeros(n)
        self.zero.setflags(write=False)  # shared by every cycle that records "no command"
        # the controller's last output (held on stale cycles)
        self.qd_cmd = self.zero
        self.status = "regular"
        self.reason_now = ""
        self.q_next = state0.q
        self.sigma_min = math.nan
        # the loop's robot clock: time of the last cycle and of the last fresh state [s]
        self.t_prev = 0.0
        self.t_fresh = 0.0
        self.t_ref = 0.0  # robot time the reference was last evaluated [s]
        self.q_used = state0.q  # the joint positions the last command was computed from
        self.first = True
        self.stamp0 = state0.stamp
        self.halting = ""  # the reason of a controller halt being decelerated
        # how it ended
        self.reason = ""
        self.outcome = ""
        self.halt_delay = math.nan
        self.interrupted: KeyboardInterrupt | None = None
        self.stop_error = ""
        # the watchdog and the schedule
        self.last_stamp = -math.inf
        self.last_fresh_wall = time.perf_counter()
        self.overruns = 0
        self.t0 = time.perf_counter()
        self.deadline = self.t0
        self.prev_start = self.t0 - period

    def _end(self, reason: str, outcome: str, *, recorded: bool = True) -> None:
        """End the run; ``recorded=False``: the ending cycle left no record (nor its period)."""
        self.reason, self.outcome = reason, outcome
        if not recorded:
            self.periods.pop()

    def record(self, state: RobotState, qd: np.ndarray, qdd: np.ndarray, status: str, fresh: bool,
               t: float | None = None) -> None:
        self.stamps.append(state.stamp)
        self.t.append(state.stamp - self.stamp0 if t is None else t)
        self.q.append(state.q)
        self.qd_measured.append(state.qd)
        self.qd.append(qd)
        self.qdd.append(qdd)
        self.statuses.append(status)
        self.reasons.append(self.reason_now)
        self.q_cmd.append(self.q_next)
        self.xi.append(self.ref.xi)
        self.sigma.append(self.sigma_min)
        self.Td.append(self.ref.Td)
        self.s.append(self.ref.s)
        self.fresh.append(fresh)
        self.gap_u.append(self.integral.correction if self.integral is not None else self.zero)

    def run(self) -> None:
        """Cycle until an end condition; on every way out stop the robot and note why."""
        try:
            while self.cycle():
                pass
        except KeyboardInterrupt as exc:
            self.interrupted = exc
            self._end("interrupted by the user (Ctrl-C)", "interrupted")
        except Exception as exc:  # a bug must still stop the robot and leave a record
            self._end(f"the loop failed: {type(exc).__name__}: {exc}", "halted")
        finally:
            self.line.close()
            self.stop()

    def stop(self) -> None:
        """``driver.stop()``; a failure is noted (``stop_error``), never raised — a Ctrl-C
        during it counts as the interruption."""
        try:
            self.driver.stop()
        except BaseException as exc:  # noqa: BLE001 - a failing stop must not hide the record
            if isinstance(exc, KeyboardInterrupt) and self.interrupted is None:
                self.interrupted = exc
                self._end("interrupted by the user (Ctrl-C)", "interrupted")
            self.stop_error = f"{type(exc).__name__}: {exc}"

    def _clock(self, state: RobotState, fresh: bool, start: float) -> tuple[float, float]:
        """(t, dt): the robot time of this cycle [s] — the measured stamp on a fresh cycle, the
        last stamp plus the wall time since it on a stale one — and the time since the previous
        cycle [s], the period the limits hold over (the nominal period on the first cycle;
        never below 5 % of it)."""
        if self.first:  # the robot clock starts at the first cycle (after any planning)
            self.stamp0 = state.stamp
        if fresh:
            t = state.stamp - self.stamp0
        else:
            t = self.t_fresh + (start - self.last_fresh_wall)
        if self.first:
            dt = self.period
            self.first = False
        else:
            dt = max(t - self.t_prev, 0.05 * self.period)
            t = self.t_prev + dt
        self.t_prev = t
        return t, dt

    def cycle(self) -> bool:
        """One period: read, watchdog, step (on a fresh state) or brake (on a stale one),
        command, end conditions, wait. Returns False when the run ends."""
        start = time.perf_counter()
        self.periods.append(start - self.prev_start)
        self.prev_start = start
        try:
            state = self.driver.read()
        except Exception as exc:
            self._end(f"driver read() failed: {type(exc).__name__}: {exc}", "halted", recorded=False)
            return False
        t_read = time.perf_counter()
        fresh = state.stamp > self.last_stamp
        if fresh:
            self.last_stamp = state.stamp
            self.last_fresh_wall = start
        elif start - self.last_fresh_wall > self.timeout:
            self._watchdog(state, start, t_read)
            return False
        t, dt = self._clock(state, fresh, start)
        dt_ref = t - self.t_ref  # robot time since the reference was last evaluated
        if fresh:
            self.t_fresh = t
            q_now: np.ndarray = state.q if state.finite else np.full(self.n, math.nan)
        else:
            q_now = self.q_used + self.qd_cmd * dt  # the last state advanced by the command sent
        if fresh or (start - self.last_fresh_wall <= 0.5 * self.timeout and not self.halting):
            # a stale cycle steps the controller on the predicted state: its limits brake
            # from where the command has taken the arm (the reference's rate holds)
            cmd = self._step(q_now, fresh, state.finite, t, dt, dt_ref)
            if cmd is None:
                return False
            self.t_ref = t
            self.q_used = q_now
        else:
            # stale for longer than half the watchdog: what the controller brakes to
            cmd = self.ctrl.brake(dt, reason="no fresh measured state for "
                                  f"{(start - self.last_fresh_wall) * 1e3:.0f} ms: braking")
            self.q_used = q_now
        t_ctrl = time.perf_counter()
        self.qd_cmd, self.status, self.sigma_min = cmd.qd, cmd.status, cmd.sigma_min
        self.reason_now, self.q_next = cmd.reason, cmd.q_next
        if cmd.status == "halted" and getattr(self.ctrl, "halted", False) and not self.halting:
            self.halting = cmd.reason
        try:
            self.driver.command(self.qd_cmd)
        except Exception as exc:
            self._end(f"driver command() failed: {type(exc).__name__}: {exc}", "halted", recorded=False)
            return False
        t_cmd = time.perf_counter()
        self.record(state, self.qd_cmd, cmd.qdd, self.status, fresh, t)
        self.timing.append((t_read - start, t_ctrl - t_read, t_cmd - t_ctrl, t_cmd - start))
        if fresh and not self.halting:
            lost = self.watch.update(t, state.q, self.qd_cmd, dt)
            if lost:
                self.halting = lost
        if fresh and self._finished(t, cmd):
            return False
        now = time.perf_counter()
        if self.line.enabled and now >= self.line.next:
            self._report(now, t, cmd if fresh else None)
        self._wait(now)
        return True

    def _watchdog(self, state: RobotState, start: float, t_read: float) -> None:
        """No fresh state for longer than the timeout: record a halted cycle and end."""
        self.halt_delay = start - self.last_fresh_wall
        # no command is sent on this cycle: its row holds the last command sent (what the robot
        # was told until driver.stop() takes over), not a zero command the controller never made
        self.reason_now = (f"watchdog: no fresh state for {self.halt_delay * 1e3:.1f} ms; no command sent, "
                           "the robot is stopped by driver.stop()")
        t_halt = max(self.t_prev, self.t_fresh + self.halt_delay)
        self.record(state, self.qd_cmd, self.zero, "halted", False, t_halt)
        self.timing.append((t_read - start, 0.0, 0.0, time.perf_counter() - start))
        self._end(
            f"watchdog: no fresh state for {self.halt_delay * 1e3:.1f} ms (timeout "
            f"{self.timeout * 1e3:.1f} ms); last stamp {state.stamp:.6g} s",
            "halted",
        )

    def _step(self, q: np.ndarray, fresh: bool, finite: bool, t: float, dt: float,
              dt_ref: float) -> Command | None:
        """The reference at robot time t and the controller's step on the joints ``q`` (measured,
        or predicted on a stale cycle) over the measured period ``dt`` (a non-finite state
        latches the controller's safe halt; a halt of the loop's own — a robot that does not
        follow — brakes); None when the run ends here."""
        if self.halting and not getattr(self.ctrl, "halted", False):
            return self.ctrl.brake(dt, reason=self.halting)
        try:
            xi = self.ref.at(t, dt_ref, q if (fresh and finite) else None, dt)
        except Exception as exc:
            self._end(f"the reference raised {type(exc).__name__}: {exc}", "halted", recorded=False)
            return None
        if self.ref.mode == "twist" and xi is None and not self.halting:
            self._end("the twist stream ended", "completed", recorded=False)
            return None
        if not finite and not self.halting:
            self.halting = f"non-finite measured state at t = {t:.4g} s (q, q̇ or stamp)"
        qd_ff, pi = self.ref.qd_ff, self.integral
        if pi is not None and not self.halting and self.ref.settle_start is not None:
            # on the end pose, the gap's correction is the joint feed-forward: every limit holds
            # over the total
            pi.sent(self.qd_cmd, dt)
            u = pi.update(q, t, self.status, settled=self.settled) if fresh and finite else pi.correction
            if u.any():
                qd_ff = u if qd_ff is None else qd_ff + u
        try:
            cmd = self.ctrl.step(q, target=self.ref.Td, twist=xi, qd_ff=qd_ff, qdd_ff=self.ref.qdd_ff, dt=dt)
        except Exception as exc:
            self._end(f"the controller raised {type(exc).__name__}: {exc}", "halted", recorded=False)
            return None
        if fresh:
            self.settled = self.ref.on_end_pose and cmd.position_error <= self.tolerance[0] \
                and cmd.orientation_error <= self.tolerance[1]
        return cmd

    def _finished(self, t: float, cmd: Command) -> bool:
        """The end conditions, checked after a fresh cycle: a halt come to rest, the end pose
        reached, the time limit (2 s more for a halt that does not come to rest)."""
        limit = self.ref.limit
        if self.halting:
            if float(np.max(np.abs(self.qd_cmd))) <= _END_SPEED:
                self._end(self.halting, "halted")
                return True
        elif self.ref.on_end_pose:
            # a path ends at rest on its end pose (a target: on it, the controller's own arrival)
            at_rest = self.ref.mode != "path" or self._at_rest()
            if cmd.position_error <= self.tolerance[0] and cmd.orientation_error <= self.tolerance[1] \
                    and at_rest:
                self._end("reached the end pose within tolerance", "completed")
                return True
        if not self.halting and t >= limit:
            if self.ref.mode == "twist":
                self._end(f"ran for the requested {limit:g} s", "completed")
            else:
                self._end(
                    f"did not reach the end pose within {limit:g} s ({cmd.position_error * 1e3:.3g} mm, "
                    f"{math.degrees(cmd.orientation_error):.3g}° from it)",
                    "timeout",
                )
            return True
        if t >= limit + 2.0:  # a halt that does not come to rest: stop anyway
            self._end(f"{self.halting}; still moving {limit + 2.0:g} s in", "halted")
            return True
        return False

    def _at_rest(self) -> bool:
        """The command has (practically) come to rest: its tool twist J q̇ within K·tolerance,
        linear and angular (the controller's own arrival rule, K its gain) — what the
        proportional law asks at the tolerance, so friction that holds a joint just off the
        pose does not keep the run waiting."""
        qd = self.qd_cmd
        if float(np.max(np.abs(qd))) <= _END_SPEED:
            return True
        if not np.all(np.isfinite(self.q_used)):
            return False
        xi = self.driver.chain.jacobian(self.q_used) @ qd
        K = np.broadcast_to(np.asarray(getattr(self.ctrl, "gain", 10.0), dtype=float), (6,))
        return bool(np.linalg.norm(xi[:3]) <= K[:3].max() * self.tolerance[0]
                    and np.linalg.norm(xi[3:]) <= K[3:].max() * self.tolerance[1])

    def _report(self, now: float, t: float, cmd: Command | None) -> None:
        err = cmd.position_error * 1e3 if cmd is not None and self.ref.Td is not None else math.nan
        self.line.update(
            now,
            f"t {t:7.2f} s | {len(self.periods) / max(now - self.t0, 1e-9):6.1f} Hz | {self.status:<20} | "
            f"err {err:7.3f} mm | overruns {self.overruns}",
        )

    def _wait(self, now: float) -> None:
        """Sleep until the next deadline (never spin); past it, an overrun — more than a period
        behind, the schedule restarts from now (missed slots are skipped)."""
        self.deadline += self.period
        if now > self.deadline:
            self.overruns += 1
            if now > self.deadline + self.period:
                self.deadline = now
        else:
            time.sleep(self.deadline - now)


# ---------------------------------------------------------------------- the record
def _errors(
    ref: _Reference, poses: np.ndarray, ok: np.ndarray, Td: list[np.ndarray | None], s: np.ndarray
) -> tuple[np.ndarray | None, np.ndarray | None, np.ndarray | None, np.ndarray | None]:
    """(position error, orientation error, tracking error, end pose) of the measured poses.

    A path: distance [m] and angle [rad] from the nearest point of the path (searched near the
    reference's s, then near the previous match); a target: ‖p_d − p‖ and ‖log(R_d Rᵀ)‖. The
    tracking error is ‖p_d(t) − p(t)‖ [m] from the reference of the same cycle. NaN where the
    measured q is not finite; all None for a twist stream.
    """
    if ref.mode == "twist":
        return None, None, None, None
    K = len(poses)
    track = np.full(K, math.nan)
    pos_err, ori_err = np.full(K, math.nan), np.full(K, math.nan)
    for k in range(K):
        Tk = Td[k]
        if ok[k] and Tk is not None:
            track[k] = float(np.linalg.norm(poses[k][:3, 3] - Tk[:3, 3]))
    if ref.path is not None:
        path = ref.path
        window = 0.25 * path.length + 1e-3
        hint = None
        for k in range(K):
            if ok[k]:
                pos_err[k], ori_err[k], hint = path.distance(
                    poses[k], s_hint=s[k] if hint is None else hint, window=window
                )
        return pos_err, ori_err, track, path.end
    assert ref.target is not None  # mode "target"
    for k in range(K):
        if ok[k]:
            e = pose_error(ref.target, poses[k])
            pos_err[k], ori_err[k] = float(np.linalg.norm(e[:3])), float(np.linalg.norm(e[3:]))
    return pos_err, ori_err, track, ref.target


def _message(outcome: str, reason: str, stop_error: str) -> str:
    message = f"halted: {reason}" if outcome == "halted" else (reason or "ended")
    if stop_error:
        message += f"; driver.stop() failed: {stop_error}"
    return message


def _kinds(chain: Chain, q: np.ndarray, t: np.ndarray, statuses: tuple[str, ...]) -> tuple[str | None, ...]:
    """The singularity kind (`ratectl.analyze`) of the cycles whose status is "damped" or
    "singular", None elsewhere; within such a stretch evaluated every 20 ms and carried over
    in between (as `follow` records it)."""
    kinds: list[str | None] = []
    kind, at = None, -math.inf
    for k, st in enumerate(statuses):
        if st in ("damped", "singular") and np.all(np.isfinite(q[k])):
            if t[k] - at >= 0.02 or k == 0 or statuses[k - 1] not in ("damped", "singular"):
                kind, at = analyze(chain, q[k]).kind, t[k]
            kinds.append(kind)
        else:
            kinds.append(None)
    return tuple(kinds)


def _twist_tracking(
    chain: Chain, q: np.ndarray, qd_measured: np.ndarray, xi: list[np.ndarray | None]
) -> dict[str, np.ndarray]:
    """A twist stream's tracking per cycle: the measured tool twist J(q) q̇ against the streamed
    one, linear [m/s] and angular [rad/s] norms of the difference (NaN where the stream gave
    none or the state is not finite)."""
    K = len(q)
    lin, ang = np.full(K, math.nan), np.full(K, math.nan)
    for k in range(K):
        x = xi[k]
        if x is not None and np.all(np.isfinite(q[k])) and np.all(np.isfinite(qd_measured[k])):
            d = chain.jacobian(q[k]) @ qd_measured[k] - x
            lin[k], ang[k] = float(np.linalg.norm(d[:3])), float(np.linalg.norm(d[3:]))
    return {"twist_linear_error": lin, "twist_angular_error": ang}


def _on_path(
    ref: _Reference, outcome: str, reason: str, pos_err: np.ndarray | None, ori_err: np.ndarray | None,
    s: np.ndarray, path_tolerance: tuple[float, float],
) -> tuple[str, str]:
    """(outcome, reason) of a path run: "completed" only on the path — within
    ``path_tolerance`` (position [m], orientation [rad]) all along, on a plan that reaches the
    end within the limits."""
    if ref.mode != "path" or outcome != "completed" or pos_err is None or ori_err is None:
        return outcome, reason
    plan = ref.plan
    if plan is not None and (not plan.complete or not plan.within_limits):
        return "incomplete", f"governor: {plan.message}"
    pe, oe = np.nan_to_num(pos_err, nan=math.inf), np.nan_to_num(ori_err, nan=math.inf)
    if pe.max() > path_tolerance[0] or oe.max() > path_tolerance[1]:
        k = int(np.argmax(pe / path_tolerance[0] + oe / path_tolerance[1]))
        return "left-path", (
            f"left the path: {pe.max() * 1e3:.3g} mm / {math.degrees(oe.max()):.3g}° from it (largest near "
            f"s = {s[k]:.4g} m; path tolerance {path_tolerance[0] * 1e3:.3g} mm / "
            f"{math.degrees(path_tolerance[1]):.3g}°)"
        )
    return outcome, reason


def _execution(
    loop: _Loop, chain: Chain, rate_hz: float, path_tolerance: tuple[float, float] = (math.inf, math.inf)
) -> Execution:
    """The record of the run (after the loop; nothing here runs in real time)."""
    n, ref = chain.dof, loop.ref
    if not loop.q:  # ended before the first cycle was recorded: the first state is the record
        ref.Td, ref.s, loop.sigma_min = ref.target, 0.0, math.nan
        loop.record(loop.state0, np.zeros(n), np.zeros(n), "halted", True)
        loop.periods.append(loop.period)
        loop.timing.append((0.0, 0.0, 0.0, 0.0))
    loop.periods[0] = loop.period
    q = np.array(loop.q, dtype=float).reshape(-1, n)
    stamps = np.array(loop.stamps, dtype=float)
    t = np.array(loop.t, dtype=float)
    K = len(q)
    ok = np.all(np.isfinite(q), axis=1)
    poses = np.full((K, 4, 4), math.nan)
    if ok.any():
        poses[ok] = chain.fk(q[ok])
    s = np.array(loop.s, dtype=float)
    pos_err, ori_err, track, T_end = _errors(ref, poses, ok, loop.Td, s)
    loop.outcome, loop.reason = _on_path(ref, loop.outcome, loop.reason, pos_err, ori_err, s, path_tolerance)
    qd_measured = np.array(loop.qd_measured, dtype=float).reshape(-1, n)
    end: dict[str, float] = {}
    if T_end is not None and ok.any():
        e = pose_error(T_end, poses[int(np.flatnonzero(ok)[-1])])
        end = {
            "end_position_error": float(np.linalg.norm(e[:3])),
            "end_orientation_error": float(np.linalg.norm(e[3:])),
        }
    info = {
        "reason": loop.reason,
        "outcome": loop.outcome,
        "mode": ref.mode,
        "halt_delay": loop.halt_delay,
        "timing": {name: np.array([row[i] for row in loop.timing]) for i, name in enumerate(_TIMING)},
        "stop_error": loop.stop_error,
        "plan": ref.plan,
        "path_tolerance": path_tolerance if ref.mode == "path" else None,
        **end,
        **(_twist_tracking(chain, q, qd_measured, loop.xi) if ref.mode == "twist" else {}),
        **({"gap_correction": np.array(loop.gap_u, dtype=float).reshape(-1, n)}
           if ref.mode == "path" else {}),
    }
    statuses = tuple(loop.statuses)
    if loop.outcome in ("halted", "interrupted") and statuses and statuses[-1] != "halted":
        statuses = statuses[:-1] + ("halted",)
    return Execution(
        t=t,
        q=q,
        qd=np.array(loop.qd, dtype=float).reshape(-1, n),
        qdd=np.array(loop.qdd, dtype=float).reshape(-1, n),
        poses=poses,
        position_error=pos_err,
        orientation_error=ori_err,
        tracking_error=track,
        statuses=statuses,
        reasons=tuple(loop.reasons),
        kinds=_kinds(chain, q, t, statuses),
        sigma_min=np.array(loop.sigma, dtype=float),
        s=s if ref.path is not None else None,
        nominal_duration=float(ref.path.duration) if ref.path is not None else math.nan,
        duration=float(t[-1] - t[0]) if K else 0.0,
        completed=loop.outcome == "completed",
        message=_message(loop.outcome, loop.reason, loop.stop_error),
        source="run",
        chain_name=chain.name,
        joint_names=tuple(chain.joint_names),
        vmax=np.array(chain.vmax),
        amax=np.array(chain.amax),
        info=info,
        q_measured=q,
        qd_measured=qd_measured,
        q_commanded=np.array(loop.q_cmd, dtype=float).reshape(-1, n),
        stamps=stamps,
        fresh=np.array(loop.fresh, dtype=bool),
        periods=np.array(loop.periods, dtype=float),
        rate_hz=rate_hz,
        overruns=loop.overruns,
    )
