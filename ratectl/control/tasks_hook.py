"""The controller's tasks hook: ``tasks=`` / ``collision=`` wired into a controller.

Several tasks with strict priorities and collision dampers are solved by
`ratectl.control.tasks_stage.TasksStage` (loaded only when a controller has tasks);
`tasks_stage` builds it from the controller's options and `tasks_command` turns one of
its answers into the cycle's `Command` (the tool pose task's error, when there is one).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

import numpy as np

from ..arrays import shared_zeros
from .command import _RANK, Command, make_command
from .cycle import Cycle

if TYPE_CHECKING:
    from ..model.chain import Chain
    from .smoothing import VelocityFilter
    from .tasks_stage import TasksResult, TasksStage

__all__ = ["tasks_stage", "tasks_command", "smoothed_tasks_motion"]

_REGULAR = ("regular",)
_NO_TWIST = shared_zeros(6)  # (a tasks cycle commands no tool twist)


def tasks_stage(chain: Chain, tasks: Any, collision: Any) -> TasksStage | None:
    """The `TasksStage` of ``tasks`` and ``collision`` (None when neither is given)."""
    if tasks is None and collision is None:
        return None
    from .tasks_stage import TasksStage

    return TasksStage(chain, list(tasks or ()), list(collision or ()))


def tasks_command(stage: TasksStage, chain: Chain, res: Any, q_next: np.ndarray, qd: np.ndarray,
                  qdd: np.ndarray, t0: float, dt: float, q: np.ndarray, *,
                  flags: tuple[str, ...] = (), reasons: tuple[str, ...] = ()) -> Command:
    """The `Command` of one tasks cycle at the measured ``q`` (the controller's copy):
    the cascade's answer ``res`` with q_next, q̇, q̈ [rad, rad/s, rad/s²], the period
    starting at ``t0`` [s] and lasting ``dt`` [s]; ``flags`` and ``reasons`` of the cycle's
    own stages (smoothing) after the cascade's."""
    if res.flags or flags:
        flags = tuple(dict.fromkeys(res.flags + flags))
        status = min(flags, key=_RANK.__getitem__)
        reason = "; ".join(res.reasons + reasons)
    else:  # (the common cycle: nothing held the motion back)
        flags, status, reason = _REGULAR, "regular", ""
    e = stage.tool_error()  # the tool pose task's error, when there is one
    if e is None:
        e = np.zeros(6)
        ep = eo = math.nan
    else:
        ex, ey, ez, rx, ry, rz = e.tolist()
        ep, eo = math.sqrt(ex * ex + ey * ey + ez * ez), math.sqrt(rx * rx + ry * ry + rz * rz)
    return make_command({"qd": qd, "q_next": q_next, "qdd": qdd.copy(), "status": status,
                         "flags": flags, "reason": reason, "error": e,
                         "position_error": ep, "orientation_error": eo, "twist": _NO_TWIST,
                         "sigma_min": math.nan, "damping": 0.0, "task_error": res.residuals,
                         "velocity_scale": 1.0, "limits_active": res.limits_active, "time": t0,
                         "dt": dt, "solve": res}, chain, q)


def smoothed_tasks_motion(res: TasksResult, q: np.ndarray, dt: float, *, smooth: Any, near: bool,
                          filter: VelocityFilter | None, qd_prev: np.ndarray, resolve: Any) -> Any:
    """The cascade's q̇ through the controller's smoothing stage (``smooth(cyc, q, dt,
    qdd_ff, near)``: the Ruckig filter inside its position guard), or the halt's `Command`
    it returns. The filter lags the cascade's answer, so the collision dampers G q̇ ≤ h are
    checked on what it commands: where one would break, the cascade is solved again within
    amax of the last command (``resolve()``) and that is commanded as it is, the filter
    restarting from it at rest in acceleration (the jerk limit does not hold for that
    period; the dampers do).
    Returns ``(res, q̇, q̈, q_next, flags, reasons)``."""
    cyc = Cycle()
    cyc.qd = res.qd.copy()
    cyc.e, cyc.ep, cyc.eo = np.zeros(6), float("nan"), float("nan")
    halt = smooth(cyc, q, dt, None, near)
    if halt is not None:
        return halt
    qd, qdd, q_next = cyc.qd, cyc.qdd, cyc.q_next
    flags, reasons = tuple(cyc.flags), tuple(cyc.reasons)
    rows = res.damper_rows
    if rows is not None and rows[1].size and bool(np.any(rows[0] @ qd > rows[1] + 1e-9)):
        res = resolve()
        qd = res.qd.copy()
        qdd = (qd - qd_prev) / dt
        q_next = q + qd * dt
        assert filter is not None
        # (at zero acceleration: a filter restarted with the period's q̈ ramps it down at
        # jmax only, and with a low jmax carries the joint past vmax)
        filter.reset(qd)
        flags = ("collision-avoidance",)
        reasons = ("the smoothed motion would break a collision damper: the cascade's q̇ within amax "
                   "is commanded (the jerk limit does not hold this period)",)
    return res, qd, qdd, q_next, flags, reasons
