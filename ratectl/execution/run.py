"""Drive a robot in real time: `run`.

Every period ``1/rate_hz`` the loop

1. reads the robot (``driver.read()``) — a *fresh* state is one whose stamp advanced;
2. evaluates the reference at the robot's time t = stamp − stamp₀ (a path's pose and
   feed-forward twist, a fixed target, or a twist stream);
3. ``cmd = controller.step(q_measured, target=T_d(t), twist=ξ(t), dt=1/rate_hz)``;
4. sends ``driver.command(cmd.qd)`` — on a stale cycle (no fresh state) the previous
   command is sent again and the controller is not stepped;
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
from typing import cast

import numpy as np

from ..control import ResolvedRateController
from ..errors import DriverError, InputError
from ..paths import Path
from ..spatial import pose_error
from .record import Execution

__all__ = ["run"]

_END_SPEED = 1e-3  # |q̇| [rad/s] below which a halted command counts as "at rest"


def _check_driver(driver) -> None:
    missing = [m for m in ("read", "command", "stop") if not callable(getattr(driver, m, None))]
    if missing or not hasattr(driver, "chain"):
        raise InputError(
            "driver must follow the ratectl.drivers.Driver protocol (chain, read(), command(qd), "
            f"stop()); {type(driver).__name__} lacks {missing or ['chain']}",
            argument="driver",
            value=driver,
        )


def _positive(name: str, value, *, allow_none: bool = False):
    if value is None and allow_none:
        return None
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise InputError(
            f"{name} must be a positive number, got {value!r}", argument=name, value=value
        ) from None
    if not (v > 0.0 and math.isfinite(v)):
        raise InputError(
            f"{name} must be a positive finite number, got {value!r}", argument=name, value=value
        )
    return v


def _is_tty(stream) -> bool:
    try:
        return bool(stream.isatty())
    except (AttributeError, ValueError, OSError):
        return False


class _StatusLine:
    """A one-line live report on stderr, rewritten in place at most every 0.25 s."""

    def __init__(self, enabled: bool, stream=None) -> None:
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


def run(
    driver,
    *,
    path: Path | None = None,
    target=None,
    twist=None,
    controller=None,
    rate_hz: float = 500.0,
    duration: float | None = None,
    timeout: float = 0.1,
    settle: float = 1.0,
    tolerance: tuple[float, float] = (1e-4, 1e-3),
    status_line: bool | None = None,
    on_interrupt: str = "raise",
) -> Execution:
    """Run the resolved-rate controller on a robot in real time; returns an `Execution`.

    Give exactly one reference:

    * ``path`` — a `ratectl.paths.Path` starting at the robot's current tool pose
      (within 1 mm / 0.01 rad; servo there first with ``target=path.start``): target
      P(s(t)) and feed-forward twist dP/ds·ṡ(t) on the path's time law, then up to
      ``settle`` seconds on the end pose until within ``tolerance``;
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
        tolerance: (position [m], orientation [rad]) for "reached".
        status_line: a live one-line status on stderr; None (default) shows it when stderr is
            a terminal and the run may last longer than 2 s.
        on_interrupt: ``"raise"`` (re-raise Ctrl-C after stopping the robot, with the record
            as ``exc.execution``) or ``"return"`` (return the record).

    Returns:
        An `Execution` with source ``"run"``: ``q``/``q_measured`` the measured joint
        positions, ``qd_measured`` the measured velocities, ``qd``/``qdd`` the commanded
        velocity and its change, tool poses fk(q_measured), the path (or target) errors, the
        controller statuses, the robot's stamps, loop periods and overruns. ``info`` holds
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
    n = chain.dof
    given = [name for name, v in (("path", path), ("target", target), ("twist", twist)) if v is not None]
    if len(given) != 1:
        raise InputError(
            f"give exactly one of path=, target=, twist= (got {given or 'none'})",
            argument="path",
            value=given,
        )
    rate_hz = _positive("rate_hz", rate_hz)
    timeout = _positive("timeout", timeout)
    duration = _positive("duration", duration, allow_none=True)
    settle = float(settle)
    if not (settle >= 0.0 and math.isfinite(settle)):
        raise InputError(
            f"settle must be a non-negative time [s], got {settle!r}", argument="settle", value=settle
        )
    if on_interrupt not in ("raise", "return"):
        raise InputError(
            f"on_interrupt must be 'raise' or 'return', got {on_interrupt!r}",
            argument="on_interrupt",
            value=on_interrupt,
        )
    pos_tol, ori_tol = (float(v) for v in tolerance)
    period = 1.0 / rate_hz

    mode = given[0]
    path = cast(Path, path)  # used only in mode "path", where it was given
    Td_fixed = None
    xi_fixed = None
    twist_fn: Callable | None = None
    if mode == "path":
        if not isinstance(path, Path):
            raise InputError(
                f"path must be a ratectl.paths.Path, got {type(path).__name__}", argument="path", value=path
            )
        limit = path.duration + settle if duration is None else duration
    elif mode == "target":
        Td_fixed = np.asarray(target, dtype=float)
        if Td_fixed.shape != (4, 4) or not np.all(np.isfinite(Td_fixed)):
            raise InputError("target must be a finite 4x4 pose", argument="target", value=target)
        limit = 10.0 if duration is None else duration
    else:
        if callable(twist):
            twist_fn = twist
        else:
            xi_fixed = np.asarray(twist, dtype=float)
            if xi_fixed.shape != (6,) or not np.all(np.isfinite(xi_fixed)):
                raise InputError(
                    "twist must be a finite 6-vector [v; ω] or a callable twist(t)",
                    argument="twist",
                    value=twist,
                )
        limit = math.inf if duration is None else duration

    ctrl = controller if controller is not None else ResolvedRateController(chain)
    if getattr(ctrl, "chain", chain).dof != n:
        raise InputError(
            f"the controller was built for a {ctrl.chain.dof}-joint arm, the driver has {n}",
            argument="controller",
            value=controller,
        )
    ctrl.reset()

    # --- the first state (nothing moves yet)
    try:
        state0 = driver.read()
    except Exception as exc:
        raise DriverError(
            f"the first read() of {type(driver).__name__} failed: {type(exc).__name__}: {exc}",
            driver=type(driver).__name__,
            cause=exc,
        ) from exc
    if not state0.finite or state0.q.shape != (n,):
        raise DriverError(
            f"the first state of {type(driver).__name__} is unusable (shape {state0.q.shape}, "
            f"finite {state0.finite}); expected {n} finite joint values",
            driver=type(driver).__name__,
        )
    if mode == "path":
        e0 = pose_error(path.start, chain.fk(state0.q))
        if np.linalg.norm(e0[:3]) > 1e-3 or np.linalg.norm(e0[3:]) > 1e-2:
            raise InputError(
                f"the path starts {np.linalg.norm(e0[:3]) * 1e3:.3g} mm / "
                f"{math.degrees(np.linalg.norm(e0[3:])):.3g}° from the robot's tool pose; servo "
                "there first with rc.run(driver, target=path.start)",
                argument="path",
                value=path,
            )

    # warm-up: one controller step on the first state, then reset — first-call costs (generated
    # kernels, caches) must not land in the first period
    try:
        ctrl.step(
            state0.q,
            target=Td_fixed if Td_fixed is not None else (path.start if mode == "path" else None),
            dt=period,
        )
    except Exception as exc:
        raise InputError(
            f"the controller cannot step on the first state: {type(exc).__name__}: {exc}",
            argument="controller",
            value=controller,
        ) from exc
    ctrl.reset()

    show = status_line if status_line is not None else (_is_tty(sys.stderr) and limit > 2.0)
    line = _StatusLine(bool(show))

    # --- the loop
    T_stamp: list[float] = []
    Q: list[np.ndarray] = []
    QDm: list[np.ndarray] = []
    QD: list[np.ndarray] = []
    QDD: list[np.ndarray] = []
    ST: list[str] = []
    SIG: list[float] = []
    TD: list[np.ndarray | None] = []
    S: list[float] = []
    FRESH: list[bool] = []
    PER: list[float] = []
    trace = (T_stamp, Q, QDm, QD, QDD, ST, SIG, TD, S, FRESH)  # one entry per recorded cycle
    TM = []  # (read, control, command, work) per cycle [s]
    stamp0 = state0.stamp
    last_stamp = -math.inf
    last_fresh_wall = time.perf_counter()
    zero = np.zeros(n)
    zero.setflags(write=False)  # shared by every cycle that records "no command"
    qd_cmd = zero
    status = "regular"
    sigma = math.nan
    Td = Td_fixed
    s_now = 0.0
    reason = ""
    outcome = ""  # "completed", "halted", "interrupted", "timeout" (duration), "" while running
    halting = ""  # the reason of a controller halt being decelerated
    halt_delay = math.nan
    interrupted: KeyboardInterrupt | None = None
    overruns = 0
    phase_settle_start = None
    stop_error = ""
    t0 = time.perf_counter()
    deadline = t0
    prev_start = t0 - period
    state = state0
    try:
        while True:
            start = time.perf_counter()
            PER.append(start - prev_start)
            prev_start = start
            # 1. read
            try:
                state = driver.read()
            except Exception as exc:
                reason = f"driver read() failed: {type(exc).__name__}: {exc}"
                outcome = "halted"
                PER.pop()
                break
            t_read = time.perf_counter()
            fresh = state.stamp > last_stamp
            if fresh:
                last_stamp = state.stamp
                last_fresh_wall = start
            elif start - last_fresh_wall > timeout:
                halt_delay = start - last_fresh_wall
                reason = (
                    f"watchdog: no fresh state for {halt_delay * 1e3:.1f} ms (timeout "
                    f"{timeout * 1e3:.1f} ms); last stamp {state.stamp:.6g} s"
                )
                outcome = "halted"
                _record(trace, state, zero, zero, "halted", sigma, Td, s_now, False)
                TM.append((t_read - start, 0.0, 0.0, time.perf_counter() - start))
                break
            t = state.stamp - stamp0
            qdd_cmd = zero
            t_ctrl = t_read
            if fresh:
                # 2. reference
                xi = None
                try:
                    if mode == "path":
                        if t <= path.duration:
                            s_now, sd, _ = path.progress(t)
                            Td = path.pose_at(s_now)
                            xi = path.twist_at(s_now, sd=sd)
                        else:
                            s_now = path.length
                            Td = path.end
                            if phase_settle_start is None:
                                phase_settle_start = t
                    elif mode == "twist":
                        xi = xi_fixed if twist_fn is None else twist_fn(t)
                        if xi is not None:
                            xi = np.asarray(xi, dtype=float)
                except Exception as exc:
                    reason = f"the reference raised {type(exc).__name__}: {exc}"
                    outcome = "halted"
                    PER.pop()
                    break
                if mode == "twist" and xi is None and not halting:
                    reason = "the twist stream ended"
                    outcome = "completed"
                    PER.pop()
                    break
                # 3. control (a non-finite measurement latches the controller's safe halt)
                q_in = state.q if state.finite else np.full(n, math.nan)
                if not state.finite and not halting:
                    halting = (
                        f"non-finite measured state at t = {t:.4g} s "
                        f"({'q' if not np.all(np.isfinite(state.q)) else 'q̇ or stamp'})"
                    )
                try:
                    cmd = ctrl.step(q_in, target=Td, twist=xi, dt=period)
                except Exception as exc:
                    reason = f"the controller raised {type(exc).__name__}: {exc}"
                    outcome = "halted"
                    PER.pop()
                    break
                t_ctrl = time.perf_counter()
                qd_cmd, qdd_cmd, status, sigma = cmd.qd, cmd.qdd, cmd.status, cmd.sigma_min
                if status == "halted" and getattr(ctrl, "halted", False) and not halting:
                    halting = cmd.reason
            # 4. command
            try:
                driver.command(qd_cmd)
            except Exception as exc:
                reason = f"driver command() failed: {type(exc).__name__}: {exc}"
                outcome = "halted"
                PER.pop()
                break
            t_cmd = time.perf_counter()
            _record(trace, state, qd_cmd, qdd_cmd, status, sigma, Td, s_now, fresh)
            TM.append((t_read - start, t_ctrl - t_read, t_cmd - t_ctrl, t_cmd - start))
            # 5. end conditions (on fresh states)
            if fresh:
                if halting:
                    if float(np.max(np.abs(qd_cmd))) <= _END_SPEED:
                        reason, outcome = halting, "halted"
                        break
                elif mode in ("target", "path") and (mode == "target" or phase_settle_start is not None):
                    if cmd.position_error <= pos_tol and cmd.orientation_error <= ori_tol:
                        reason, outcome = "reached the end pose within tolerance", "completed"
                        break
                if not halting and t >= limit:
                    if mode == "twist":
                        reason, outcome = f"ran for the requested {limit:g} s", "completed"
                    else:
                        reason = (
                            f"did not reach the end pose within {limit:g} s "
                            f"({cmd.position_error * 1e3:.3g} mm, {math.degrees(cmd.orientation_error):.3g}° "
                            "from it)"
                        )
                        outcome = "timeout"
                    break
                if t >= limit + 2.0:  # a halt that does not come to rest: stop anyway
                    reason, outcome = f"{halting}; still moving {limit + 2.0:g} s in", "halted"
                    break
            now = time.perf_counter()
            if line.enabled and now >= line.next:
                line.update(
                    now,
                    f"t {t:7.2f} s | {len(PER) / max(now - t0, 1e-9):6.1f} Hz | {status:<20} | "
                    f"err {(cmd.position_error * 1e3) if fresh and Td is not None else math.nan:7.3f} mm"
                    f" | overruns {overruns}",
                )
            # 6. wait for the next deadline (sleep; never spin)
            deadline += period
            if now > deadline:
                overruns += 1
                if now > deadline + period:  # more than a period behind: skip the missed slots
                    deadline = now
            else:
                time.sleep(deadline - now)
    except KeyboardInterrupt as exc:
        interrupted = exc
        reason, outcome = "interrupted by the user (Ctrl-C)", "interrupted"
    except Exception as exc:  # a bug must still stop the robot and leave a record
        reason, outcome = f"the loop failed: {type(exc).__name__}: {exc}", "halted"
    finally:
        line.close()
        # stop the robot on every way out
        try:
            driver.stop()
        except BaseException as exc:  # noqa: BLE001 - a failing stop must not hide the record
            if isinstance(exc, KeyboardInterrupt) and interrupted is None:
                interrupted = exc
                reason, outcome = "interrupted by the user (Ctrl-C)", "interrupted"
            stop_error = f"{type(exc).__name__}: {exc}"

    ex = _execution(
        chain,
        mode,
        path,
        Td_fixed,
        T_stamp,
        Q,
        QDm,
        QD,
        QDD,
        ST,
        SIG,
        TD,
        S,
        FRESH,
        PER,
        TM,
        period=period,
        rate_hz=rate_hz,
        overruns=overruns,
        outcome=outcome,
        reason=reason,
        halt_delay=halt_delay,
        stop_error=stop_error,
        stamp0=stamp0,
        state0=state0,
        tol=(pos_tol, ori_tol),
    )
    if interrupted is not None and on_interrupt == "raise":
        interrupted.execution = ex  # type: ignore[attr-defined]
        raise interrupted
    return ex


def _record(trace, state, qd, qdd, status, sigma, Td, s, fresh) -> None:
    for column, value in zip(
        trace, (state.stamp, state.q, state.qd, qd, qdd, status, sigma, Td, s, fresh), strict=True
    ):
        column.append(value)


def _execution(
    chain,
    mode,
    path,
    target,
    T_stamp,
    Q,
    QDm,
    QD,
    QDD,
    ST,
    SIG,
    TD,
    S,
    FRESH,
    PER,
    TM,
    *,
    period,
    rate_hz,
    overruns,
    outcome,
    reason,
    halt_delay,
    stop_error,
    stamp0,
    state0,
    tol,
) -> Execution:
    """Fill the record (after the loop; nothing here runs in real time)."""
    n = chain.dof
    if not Q:  # ended before the first cycle was recorded: the first state is the record
        _record(
            (T_stamp, Q, QDm, QD, QDD, ST, SIG, TD, S, FRESH),
            state0,
            np.zeros(n),
            np.zeros(n),
            "halted",
            math.nan,
            target,
            0.0,
            True,
        )
        PER.append(period)
        TM.append((0.0, 0.0, 0.0, 0.0))
    PER[0] = period
    q = np.array(Q, dtype=float).reshape(-1, n)
    stamps = np.array(T_stamp, dtype=float)
    t = stamps - stamp0
    K = len(q)
    ok = np.all(np.isfinite(q), axis=1)
    poses = np.full((K, 4, 4), math.nan)
    if ok.any():
        poses[ok] = chain.fk(q[ok])
    pos_err = ori_err = track = None
    s_arr = None
    if mode in ("path", "target"):
        track = np.full(K, math.nan)
        for k in range(K):
            if ok[k] and TD[k] is not None:
                track[k] = float(np.linalg.norm(poses[k][:3, 3] - TD[k][:3, 3]))
    if mode == "path":
        s_arr = np.array(S, dtype=float)
        pos_err, ori_err = np.full(K, math.nan), np.full(K, math.nan)
        window = 0.25 * path.length + 1e-3
        hint = None
        for k in range(K):
            if ok[k]:
                pos_err[k], ori_err[k], hint = path.distance(
                    poses[k], s_hint=s_arr[k] if hint is None else hint, window=window
                )
        T_end = path.end
        nominal = float(path.duration)
    elif mode == "target":
        pos_err, ori_err = np.full(K, math.nan), np.full(K, math.nan)
        for k in range(K):
            if ok[k]:
                e = pose_error(target, poses[k])
                pos_err[k], ori_err[k] = float(np.linalg.norm(e[:3])), float(np.linalg.norm(e[3:]))
        T_end = target
        nominal = math.nan
    else:
        T_end = None
        nominal = math.nan
    info = {
        "reason": reason,
        "outcome": outcome,
        "mode": mode,
        "halt_delay": halt_delay,
        "timing": {
            name: np.array([row[i] for row in TM])
            for i, name in enumerate(("read", "control", "command", "work"))
        },
        "stop_error": stop_error,
    }
    if T_end is not None and ok.any():
        last = int(np.flatnonzero(ok)[-1])
        e = pose_error(T_end, poses[last])
        info["end_position_error"] = float(np.linalg.norm(e[:3]))
        info["end_orientation_error"] = float(np.linalg.norm(e[3:]))
    completed = outcome == "completed"
    if outcome == "halted":
        message = f"halted: {reason}"
    elif outcome == "interrupted":
        message = reason
    elif outcome == "timeout":
        message = reason
    else:
        message = reason or "ended"
    if stop_error:
        message += f"; driver.stop() failed: {stop_error}"
    statuses = tuple(ST)
    if outcome in ("halted", "interrupted") and statuses and statuses[-1] != "halted":
        statuses = statuses[:-1] + ("halted",)
    qd_m = np.array(QDm, dtype=float).reshape(-1, n)
    return Execution(
        t=t,
        q=q,
        qd=np.array(QD, dtype=float).reshape(-1, n),
        qdd=np.array(QDD, dtype=float).reshape(-1, n),
        poses=poses,
        position_error=pos_err,
        orientation_error=ori_err,
        tracking_error=track,
        statuses=statuses,
        sigma_min=np.array(SIG, dtype=float),
        s=s_arr,
        nominal_duration=nominal,
        duration=float(t[-1] - t[0]) if K else 0.0,
        completed=completed,
        message=message,
        source="run",
        chain_name=chain.name,
        joint_names=tuple(chain.joint_names),
        vmax=np.array(chain.vmax),
        amax=np.array(chain.amax),
        info=info,
        q_measured=q,
        qd_measured=qd_m,
        stamps=stamps,
        fresh=np.array(FRESH, dtype=bool),
        periods=np.array(PER, dtype=float),
        rate_hz=rate_hz,
        overruns=overruns,
    )
