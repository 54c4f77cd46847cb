"""Ruckig smoothing: jerk-limited joint commands.

* `VelocityFilter` — an online filter for a control loop. Every cycle it takes
  the desired joint velocity and returns the next state of a jerk-limited motion
  that moves towards it (Ruckig's *velocity interface*): |q̇| ≤ vmax, |q̈| ≤ amax and
  |q⃛| ≤ jmax per joint, and the position is the exact integral of that motion.
* `move` — a state-to-state joint move (Ruckig's position interface, no
  intermediate waypoints): from a joint state to a goal at rest, time-optimal and
  jerk-limited, all joints synchronised. Used to go to the start of a path.
* `stop` — the jerk-limited motion that brings a moving joint state to rest.
* `stopping_distance` and `braking_speed` — the closed forms of that stop
  per joint (how far a jerk-limited joint travels before it is at rest, and the speed
  from which it can still stop within a distance); the controller uses them to keep a
  smoothed joint inside its position range.

Ruckig's intermediate waypoints are never used (the community build computes them
through a remote service); only single-segment state-to-state and velocity-interface
calls are made, which run locally.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from ..arrays import read_only
from ..errors import InputError, SolverError
from ..model.jerk_profile import PiecewiseJerk

__all__ = ["VelocityFilter", "ProgressProfile", "SpeedProfile", "JointTrajectory", "move", "stop"]


def _limit_array(value, n: int, name: str) -> np.ndarray:
    a = np.broadcast_to(np.asarray(value, dtype=float), (n,)).copy()
    if not np.all(a > 0.0) or not np.all(np.isfinite(a)):
        raise InputError(f"{name} must be positive and finite for every joint to use Ruckig, got {a}",
                         argument=name, value=value)
    return a


def _floats(x: Any) -> list[float]:
    """An (n,) array (or sequence) of numbers as a list of Python floats."""
    return x.tolist() if type(x) is np.ndarray else [float(v) for v in x]


class VelocityFilter:
    """Online jerk-limited velocity filter (Ruckig velocity interface), one per control loop.

    Each `update` advances the filter state by one period ``dt`` towards the
    target velocity (clipped to ±vmax) — and target acceleration, if given: then the
    target is a moving reference, joined in its own frame (see `update`) — with
    |q̈| ≤ amax and |q⃛| ≤ jmax. Ruckig's ``minimum_duration`` is set to ``dt``, so a
    target that is reachable within one period is met exactly at the next cycle
    (a jerk-feasible reference with its acceleration is tracked without lag). The
    Ruckig objects are created once and kept; the filter owns the current velocity and
    acceleration.

    Args:
        dof: number of joints.
        dt: period [s].
        vmax: (n,) or scalar velocity limits.
        amax: (n,) or scalar acceleration limits.
        jmax: (n,) or scalar jerk limits.
    """

    def __init__(self, dof: int, *, dt: float, vmax: ArrayLike, amax: ArrayLike, jmax: ArrayLike) -> None:
        import ruckig

        self._ruckig = ruckig
        self.dof = int(dof)
        dt = float(dt)
        if not (dt > 0.0 and math.isfinite(dt)):
            raise InputError(f"dt must be a positive period [s], got {dt!r}", argument="dt", value=dt)
        self.vmax = _limit_array(vmax, self.dof, "vmax")
        self.amax = _limit_array(amax, self.dof, "amax")
        self.jmax = _limit_array(jmax, self.dof, "jmax")
        self._vmax_list = self.vmax.tolist()
        # targets within vmax·(1 − 1e-7): Ruckig's integration ends a few 1e-9 above a target
        # velocity reached at the limit itself
        # (the per-period arithmetic runs on Python floats, joint by joint: lists of the limits)
        self._vtop = (self.vmax * (1.0 - 1e-7)).tolist()
        self._neg_vmax = [-x for x in self._vtop]
        self._amax_list = self.amax.tolist()
        self._jmax_list = self.jmax.tolist()
        self._otg = ruckig.Ruckig(self.dof, dt)
        self._inp = ruckig.InputParameter(self.dof)
        self._out = ruckig.OutputParameter(self.dof)
        self._inp.control_interface = ruckig.ControlInterface.Velocity
        self._inp.max_velocity = self._vmax_list
        self._inp.max_acceleration = self.amax.tolist()
        self._inp.max_jerk = self.jmax.tolist()
        # reach the target state no earlier than the next cycle: a feasible (q̇, q̈) reference
        # is then met exactly at t + dt instead of early (and overshot by q̈·(dt − T))
        self._inp.minimum_duration = dt
        self._set_atop(dt)
        # the target is rest in the frame of the reference (see `update`)
        self._inp.target_velocity = [0.0] * self.dof
        self._inp.target_acceleration = [0.0] * self.dof
        self._ok = (ruckig.Result.Working, ruckig.Result.Finished)
        self._per_dof = False
        self._no_sync = [ruckig.Synchronization.No] * self.dof
        self._zeros = [0.0] * self.dof
        self._half_inv_j = (0.5 / self.jmax).tolist()
        self._traj: Any = None  # Ruckig's whole trajectory, made on a halt's first use
        self.reset()

    @property
    def dt(self) -> float:
        return float(self._otg.delta_time)

    @dt.setter
    def dt(self, value: float) -> None:
        self._otg.delta_time = float(value)
        self._inp.minimum_duration = float(value)
        self._set_atop(float(value))

    def _set_atop(self, dt: float) -> None:
        """The largest target acceleration: amax less one period of jerk, jmax·dt (at most
        half of amax), so that a joint off a reference line braking or accelerating at the
        limit can still join it (at amax itself the line leaves it no room at all)."""
        self._atop = (self.amax - np.minimum(self.jmax * dt, 0.5 * self.amax)).tolist()

    def reset(self, qd: ArrayLike | None = None, qdd: ArrayLike | None = None) -> None:
        """Set the filter state (default: at rest)."""
        self._v: list[float] = [0.0] * self.dof if qd is None else \
            np.array(qd, dtype=float).reshape(self.dof).tolist()
        self._a: list[float] = [0.0] * self.dof if qdd is None else \
            np.array(qdd, dtype=float).reshape(self.dof).tolist()

    def _calculate(self):
        """One Ruckig update; a RuckigError exception (the Python binding raises some
        failures instead of returning them) becomes an error result."""
        try:
            return self._otg.update(self._inp, self._out)
        except (self._ruckig.RuckigError, ValueError) as exc:  # (ValueError: a code the binding lacks)
            return exc

    @property
    def velocity(self) -> np.ndarray:
        return np.array(self._v)

    @property
    def acceleration(self) -> np.ndarray:
        return np.array(self._a)

    def update(self, q: np.ndarray, qd_target: np.ndarray, qdd_target: np.ndarray | None = None, *,
               independent: np.ndarray | None = None):
        """One period: returns ``(q_next, qd, qdd)`` of the jerk-limited motion from ``q``.

        The target is a moving reference: the velocity line v_r(t) = v̄ + ā·(t − dt) that
        passes the target velocity v̄ at the end of the period with the target acceleration
        ā. Each joint moves onto it time-optimally within |q̈| ≤ amax, |q⃛| ≤ jmax, computed
        in the reference's own frame, e = q̇ − v_r (ë = q⃛, since v_r has no jerk), as Ruckig's
        velocity interface from (e, ė) to rest: a reference reachable within the period is
        met exactly at its end; one that is not (its acceleration does not quite match its
        velocity's change) is joined as fast as the jerk allows, never by a detour to the
        fixed state (v̄, ā), which can take many periods and starts off the wrong way. The
        joints are time-synchronised (they join the reference together, so the joint-space
        direction of the change is kept), except those in ``independent``, which move
        time-optimally on their own (see `_one_period_on_their_own`: the others still meet
        their targets within the period).

        Args:
            q: current joint positions (n,) (the position the motion starts from).
            qd_target: desired joint velocity (n,), clipped to ±vmax.
            qdd_target: desired joint acceleration at that velocity (n,), clipped to ±amax
                (default 0: arrive at the target velocity and stay there).
            independent: optional (n,) booleans: joints that move time-optimally on their
                own this period instead of being stretched to the others' time (a joint
                braking for its position limit must brake as hard as it can).
        """
        inp = self._inp
        inp.current_position = _floats(q)
        v0, a0 = self._v, self._a
        # within ±vmax, less what the present acceleration still adds while it ramps down at
        # jmax (a²/(2·jmax)): a target at vmax met with a > 0 would pass it
        vt: list[float] = []
        for v, a, j, lo, hi in zip(_floats(qd_target), a0, self._jmax_list, self._neg_vmax, self._vtop,
                                   strict=True):
            ramp = a * a / (2.0 * j)
            lo = lo + (ramp if a < 0.0 else 0.0)
            hi = hi - (ramp if a > 0.0 else 0.0)
            v = v if v >= lo else lo
            vt.append(v if v <= hi else hi)
        # a reference (a velocity with its acceleration) is joined by each joint on its own: one
        # that cannot join it soon (a line braking at amax, the joint above it) then stretches
        # no other joint's motion; a velocity alone is met by all joints together
        sync = qdd_target is None
        if qdd_target is None:
            ta = self._zeros
        else:
            clipped = []
            for a, t in zip(_floats(qdd_target), self._atop, strict=True):
                a = a if a >= -t else -t
                clipped.append(a if a <= t else t)
            ta = self._within_room(vt, clipped)
        own: list[bool] | None = None
        alone = None
        if independent is not None and any(independent):
            if all(independent):  # every joint on its own (a halt), to rest acceleration
                sync = False
                ta = self._zeros
            else:
                own = [bool(x) for x in independent]
                alone = self._one_period_on_their_own(vt, ta, own)
                # the others, with the independent joints kept at rest on their lines, so that
                # they do not stretch a synchronised motion
        res = self._calculate_relative(vt, ta, sync=sync, still=own)
        if res not in self._ok and sync:  # (a safety net: a target at rest needs no synchronisation step)
            sync = False
            res = self._calculate_relative(vt, ta, sync=False, still=own)
        if res not in self._ok:
            raise SolverError(f"Ruckig velocity filter failed: {res}", status=res,
                              problem={"target_velocity": np.array(vt), "target_acceleration": np.array(ta),
                                       "velocity": np.array(v0), "acceleration": np.array(a0)})
        q1, v1, a1 = self._absolute(vt, ta)
        if not sync:
            # a joint that joins a line pushing outward from below, faster than the line, would
            # end too fast to stop accelerating before vmax (|q̇| + q̈²/(2·jmax) > vmax, the
            # line itself being within it): it joins the flat line at the target velocity
            # instead, whose time-optimal motion passes no higher than the present state's own
            # ramp |q̇₀| + q̈₀²/(2·jmax) or the target, both within vmax
            over = [(abs(v) + (a * a if v * a > 0.0 else 0.0) * h > vm) and t != 0.0
                    and not (own is not None and own[i])
                    for i, (v, a, h, vm, t) in enumerate(zip(v1, a1, self._half_inv_j, self._vmax_list, ta,
                                                             strict=True))]
            if any(over):
                ta = [0.0 if o else t for o, t in zip(over, ta, strict=True)]
                res = self._calculate_relative(vt, ta, sync=False, still=own)
                if res not in self._ok:
                    raise SolverError(f"Ruckig velocity filter failed: {res}", status=res,
                                      problem={"target_velocity": np.array(vt), "velocity": np.array(v0),
                                               "acceleration": np.array(a0)})
                q1, v1, a1 = self._absolute(vt, ta)
        if own is not None and alone is not None:
            q1, v1, a1 = ([xa if o else x for o, xa, x in zip(own, x_alone, x_all, strict=True)]
                          for x_alone, x_all in zip(alone, (q1, v1, a1), strict=True))
        self._v, self._a = v1, a1
        return np.array(q1), np.array(v1), np.array(a1)

    def synchronised_stop_passes(self, q: np.ndarray, lower: np.ndarray, upper: np.ndarray) -> np.ndarray:
        """The joints whose part of the time-synchronised stop from the filter's state at
        ``q`` (every joint to rest together, Ruckig's whole trajectory) would run past a
        position limit ``lower`` / ``upper`` (n,), or further past one it is already
        beyond: a (n,) mask. A halt stops those joints on their own, each as fast as its
        limits allow. Every joint when Ruckig finds no synchronised stop."""
        self._inp.current_position = q.tolist()
        self._set_relative(self._zeros, self._zeros, sync=True)
        if self._traj is None:
            self._traj = self._ruckig.Trajectory(self.dof)
        try:
            res = self._otg.calculate(self._inp, self._traj)
        except (self._ruckig.RuckigError, ValueError):
            res = None
        if res not in self._ok:
            return np.ones(self.dof, dtype=bool)
        ext = self._traj.position_extrema
        hi = np.array([e.max for e in ext])
        lo = np.array([e.min for e in ext])
        return (hi > np.maximum(upper, q)) | (lo < np.minimum(lower, q))

    def _calculate_relative(self, vt: list[float], ta: list[float], *, sync: bool,
                            still: list[bool] | None = None):
        """Ruckig's update in the frame of the reference line (`_set_relative`)."""
        self._set_relative(vt, ta, sync=sync, still=still)
        return self._calculate()

    def _set_relative(self, vt: list[float], ta: list[float], *, sync: bool,
                      still: list[bool] | None = None) -> None:
        """Ruckig's input in the frame of the reference line v_r(t) = vt + ta·(t − dt):
        from e = q̇ − v_r(0), ė = q̈ − ta to rest, with ė within [−amax − ta, amax − ta];
        the joints time-synchronised or not (``sync``). Joints in ``still`` (a mask) are
        put at rest on their lines (their answer is not used: they stretch nothing)."""
        inp = self._inp
        if sync == self._per_dof:
            inp.per_dof_synchronization = None if sync else self._no_sync
            self._per_dof = not sync
        dt = self.dt
        amax = self._amax_list
        if still is None:
            inp.current_velocity = [v - r + t * dt for v, r, t in zip(self._v, vt, ta, strict=True)]
            inp.current_acceleration = [a - t for a, t in zip(self._a, ta, strict=True)]
            inp.max_acceleration = [m - t for m, t in zip(amax, ta, strict=True)]
            inp.min_acceleration = [-m - t for m, t in zip(amax, ta, strict=True)]
            return
        inp.current_velocity = [0.0 if s else v - r + t * dt
                                for s, v, r, t in zip(still, self._v, vt, ta, strict=True)]
        inp.current_acceleration = [0.0 if s else a - t for s, a, t in zip(still, self._a, ta, strict=True)]
        inp.max_acceleration = [m if s else m - t for s, m, t in zip(still, amax, ta, strict=True)]
        inp.min_acceleration = [-m if s else -m - t for s, m, t in zip(still, amax, ta, strict=True)]

    def _absolute(self, vt: list[float], ta: list[float]) -> tuple[list[float], list[float], list[float]]:
        """``(q, q̇, q̈)`` at the end of the period from Ruckig's answer in the reference's
        frame (`_calculate_relative`): q̇ = v_r + e, q̈ = ta + ė, and q the start plus
        ∫e dt (Ruckig's position) plus ∫v_r dt = vt·dt − ta·dt²/2."""
        out = self._out
        dt = self.dt
        h = 0.5 * dt * dt
        q1 = [p + r * dt - t * h for p, r, t in zip(out.new_position, vt, ta, strict=True)]
        v1 = [e + r for e, r in zip(out.new_velocity, vt, strict=True)]
        a1 = [e + t for e, t in zip(out.new_acceleration, ta, strict=True)]
        return q1, v1, a1

    def _within_room(self, vt: list[float], ta: list[float]) -> list[float]:
        """Target accelerations that keep the filter below vmax: |a| ≤ √(2·jmax·(vmax − |v|)).
        Pushing outward, the motion must still stop accelerating before vmax; pulling back
        (a target reached from below with a braking acceleration), the time-optimal motion
        passes through a = 0 at |v| + a²/(2·jmax) before it brakes, which must not pass vmax
        either (a non-zero target acceleration at the velocity limit overran it)."""
        out = []
        for v, t, j, vm in zip(vt, ta, self._jmax_list, self._vmax_list, strict=True):
            x = vm - abs(v)
            room = math.sqrt(2.0 * j * (x if x > 0.0 else 0.0))
            at = abs(t)
            m = room if room < at else at
            out.append(m if t > 0.0 else (-m if t < 0.0 else 0.0))
        return out

    def _one_period_on_their_own(self, vt: list[float], ta: list[float], independent: list[bool]):
        """The ``independent`` joints' own time-optimal motion to their target velocities at
        rest acceleration (no synchronisation): ``(q, q̇, q̈)`` one period later (only those
        joints' rows mean anything), or None if Ruckig finds none. `update` takes the
        independent joints from this and the others from a second update (Ruckig stretches
        time-synchronised joints to the duration of the whole motion, unsynchronised joints
        included, so a single update with a braking joint unsynchronised would stretch every
        other joint to its stop and lose their targets)."""
        at_rest = [0.0 if i else t for i, t in zip(independent, ta, strict=True)]
        res = self._calculate_relative(vt, at_rest, sync=False, still=[not i for i in independent])
        if res not in self._ok:
            return None
        return self._absolute(vt, at_rest)


class _OneAxis:
    """Ruckig with one degree of freedom, one period at a time: the shared state of
    `ProgressProfile` (position interface) and `SpeedProfile` (velocity interface)."""

    def __init__(self, dt: float, *, velocity: bool = False) -> None:
        import ruckig

        self._ruckig = ruckig
        self._otg = ruckig.Ruckig(1, float(dt))
        self._inp = ruckig.InputParameter(1)
        self._out = ruckig.OutputParameter(1)
        if velocity:
            self._inp.control_interface = ruckig.ControlInterface.Velocity
        self._inp.current_position = [0.0]
        self._inp.target_acceleration = [0.0]
        self._ok = (ruckig.Result.Working, ruckig.Result.Finished)

    def _update(self, dt: float):
        """One update of period ``dt``: the output, or None if Ruckig finds no motion."""
        if self._otg.delta_time != dt:
            self._otg.delta_time = dt
        try:
            res = self._otg.update(self._inp, self._out)
        except self._ruckig.RuckigError:
            return None
        return self._out if res in self._ok else None


class ProgressProfile(_OneAxis):
    """A scalar, jerk-limited motion toward a goal distance, one period at a time (Ruckig's
    position interface with one degree of freedom): the controller's approach to a target
    plans its progress x [m, rad or a mix, as the pose error] with it, so that the motion
    comes to rest at the target within the (mapped) joint limits."""

    def __init__(self, dt: float) -> None:
        super().__init__(dt)
        self._inp.target_velocity = [0.0]

    def step(self, x: float, v: float, a: float, *, vmax: float, amax: float, jmax: float,
             dt: float, brake: float | None = None, v_end: float = 0.0):
        """From progress 0 at speed ``v`` and acceleration ``a``, the time-optimal motion that
        meets a goal now at ``x`` and moving on at ``v_end`` ≥ 0 (0: a goal at rest; clipped
        into [0, vmax]), under |ẋ| ≤ vmax, |x⃛| ≤ jmax, accelerating toward ``x`` by at most
        ``amax`` and decelerating by at most ``brake`` (default amax): returns its (progress,
        speed, acceleration) one period ``dt`` later, or None if Ruckig finds no motion.

        A moving goal is met in its own frame, y = x(t) − v_end·t: from y = 0 at speed
        v − v_end to y = ``x`` at relative rest, the relative speed within
        [−v_end, vmax − v_end] (the progress neither runs backwards nor passes vmax). Its
        progress and speed one period later are y₁ + v_end·dt and ẏ₁ + v_end. (Planned
        instead to arrive at the goal's present place with its speed, the progress would
        close the gap only as v_end·Δv ≈ brake·gap allows, exponentially, at brake/v_end.)"""
        inp = self._inp
        v_goal = min(max(v_end, 0.0), vmax)
        moving = v_goal > 0.0 and vmax - v_goal > 1e-9 * vmax
        if moving:  # in the goal's frame
            inp.target_velocity = [0.0]
            inp.current_velocity = [v - v_goal]
            inp.max_velocity = [vmax - v_goal]
            inp.min_velocity = [-v_goal]
        else:
            inp.target_velocity = [v_goal]
            inp.current_velocity = [v]
            inp.max_velocity = [vmax]
            inp.min_velocity = None
        inp.target_position = [x]
        inp.max_jerk = [jmax]
        brake = amax if brake is None else brake
        if x >= 0.0:  # the target ahead: braking is a negative acceleration
            lo, hi = -brake, amax
        else:
            lo, hi = -amax, brake
        inp.max_acceleration, inp.min_acceleration = [hi], [lo]
        inp.current_acceleration = [min(max(a, lo), hi)]
        out = self._update(dt)
        if out is None:
            return None
        if moving:
            return out.new_position[0] + v_goal * dt, out.new_velocity[0] + v_goal, out.new_acceleration[0]
        return out.new_position[0], out.new_velocity[0], out.new_acceleration[0]


class SpeedProfile(_OneAxis):
    """A scalar, jerk-limited speed toward a goal speed, one period at a time (Ruckig's
    velocity interface with one degree of freedom). A smoothed jog moves its fraction c of
    the commanded twist with it, so that the joint motion c·w it commands is a reference
    the `VelocityFilter` meets exactly (with the acceleration ċ·w + c·ẇ) instead of
    lagging each joint on its own, which turns the tool off the commanded direction."""

    def __init__(self, dt: float) -> None:
        super().__init__(dt, velocity=True)

    def step(self, v: float, a: float, goal: float, *, amax: float, jmax: float, dt: float):
        """From speed ``v`` and acceleration ``a``, the time-optimal jerk-limited motion to the
        speed ``goal`` at rest acceleration, |v̇| ≤ ``amax``, |v̈| ≤ ``jmax``: returns its
        (speed, acceleration) one period ``dt`` later, or None if Ruckig finds no motion."""
        inp = self._inp
        inp.current_velocity = [v]
        inp.current_acceleration = [min(max(a, -amax), amax)]
        inp.target_velocity = [goal]
        inp.max_acceleration = [amax]
        inp.max_jerk = [jmax]
        out = self._update(dt)
        return None if out is None else (out.new_velocity[0], out.new_acceleration[0])


@dataclass(frozen=True, kw_only=True)
class JointTrajectory:
    """A jerk-limited joint trajectory computed by Ruckig (state to state), kept as its
    phases of constant jerk (`ratectl.model.jerk_profile.PiecewiseJerk`: no Ruckig object
    is held).

    Attributes:
        duration: [s].
        start: (n,) joint positions at t = 0 (read-only).
        goal: (n,) joint positions at the end (read-only).
    """

    duration: float
    start: np.ndarray
    goal: np.ndarray
    _traj: Any = field(repr=False)

    def __post_init__(self) -> None:
        for name in ("start", "goal"):
            object.__setattr__(self, name, read_only(getattr(self, name)))

    def at(self, t: float):
        """``(q, q̇, q̈)`` at time ``t`` [s] (clamped to [0, duration])."""
        t = min(max(float(t), 0.0), self.duration)
        return self._traj.at_array(t)

    def sample(self, dt: float):
        """Arrays ``(t, q, q̇, q̈)`` every ``dt`` [s], including both ends."""
        n = int(math.ceil(self.duration / dt - 1e-9)) + 1
        t = np.minimum(np.arange(n) * dt, self.duration)
        rows = [self.at(x) for x in t]
        q, qd, qdd = (np.array([r[i] for r in rows]) for i in range(3))
        return t, q, qd, qdd


def move(q_start: ArrayLike, q_goal: ArrayLike, *, vmax: ArrayLike, amax: ArrayLike, jmax: ArrayLike,
         qd_start: ArrayLike | None = None, qdd_start: ArrayLike | None = None) -> JointTrajectory:
    """Time-optimal, jerk-limited, synchronised joint move to ``q_goal`` at rest (Ruckig position
    interface, one segment — never intermediate waypoints).

    Args:
        q_start: (n,) start joint positions.
        q_goal: (n,) goal joint positions (reached at rest).
        vmax: (n,) or scalar velocity limits.
        amax: (n,) or scalar acceleration limits.
        jmax: (n,) or scalar jerk limits.
        qd_start: initial velocity (default rest).
        qdd_start: initial acceleration (default rest).
    """
    import ruckig

    q0 = np.asarray(q_start, dtype=float)
    q1 = np.asarray(q_goal, dtype=float)
    if q0.ndim != 1 or q0.shape != q1.shape or not (np.all(np.isfinite(q0)) and np.all(np.isfinite(q1))):
        raise InputError(f"q_start and q_goal must be finite (n,) arrays of the same shape, got "
                         f"{q0.shape} and {q1.shape}", argument="q_goal", value=q_goal)
    n = len(q0)
    inp = ruckig.InputParameter(n)
    z = [0.0] * n
    inp.current_position = q0.tolist()
    inp.current_velocity = z if qd_start is None else np.asarray(qd_start, dtype=float).tolist()
    inp.current_acceleration = z if qdd_start is None else np.asarray(qdd_start, dtype=float).tolist()
    inp.target_position, inp.target_velocity, inp.target_acceleration = q1.tolist(), z, z
    inp.max_velocity = _limit_array(vmax, n, "vmax").tolist()
    inp.max_acceleration = _limit_array(amax, n, "amax").tolist()
    inp.max_jerk = _limit_array(jmax, n, "jmax").tolist()
    traj = _calculate(inp, n, "the joint move", {"q_start": q0, "q_goal": q1})
    return JointTrajectory(duration=float(traj.duration), start=q0, goal=q1, _traj=PiecewiseJerk(traj))


def _calculate(inp, n: int, what: str, problem: dict):
    """Ruckig's offline trajectory for ``inp``; a failure raises SolverError naming ``what``."""
    import ruckig

    traj = ruckig.Trajectory(n)
    res = ruckig.Ruckig(n).calculate(inp, traj)
    if res not in (ruckig.Result.Working, ruckig.Result.Finished):
        raise SolverError(f"Ruckig could not compute {what}: {res}", status=res, problem=problem)
    return traj


def stop(q: ArrayLike, qd: ArrayLike, *, qdd: ArrayLike | None = None, amax: ArrayLike,
         jmax: ArrayLike) -> JointTrajectory:
    """The jerk-limited motion that brings the state ``(q, q̇, q̈)`` to rest as fast as the limits
    allow (Ruckig velocity interface with target velocity 0); all joints synchronised."""
    import ruckig

    q = np.asarray(q, dtype=float)
    n = len(q)
    inp = ruckig.InputParameter(n)
    inp.control_interface = ruckig.ControlInterface.Velocity
    z = [0.0] * n
    inp.current_position = q.tolist()
    inp.current_velocity = np.asarray(qd, dtype=float).tolist()
    inp.current_acceleration = z if qdd is None else np.asarray(qdd, dtype=float).tolist()
    inp.target_velocity, inp.target_acceleration = z, z
    inp.max_velocity = [math.inf] * n
    inp.max_acceleration = _limit_array(amax, n, "amax").tolist()
    inp.max_jerk = _limit_array(jmax, n, "jmax").tolist()
    traj = _calculate(inp, n, "the stop", {"q": q, "qd": qd})
    profile = PiecewiseJerk(traj)
    p_end = profile.at_array(profile.duration)[0]
    return JointTrajectory(duration=profile.duration, start=q, goal=p_end, _traj=profile)
