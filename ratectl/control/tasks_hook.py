"""The controller's tasks hook: ``tasks=`` / ``collision=`` wired into a controller.

Several tasks with strict priorities and collision dampers are solved by
`ratectl.control.tasks_stage.TasksStage` (loaded only when a controller has tasks);
`tasks_stage` builds it from the controller's options and `tasks_command` turns one of
its answers into the cycle's `Command` (the tool pose task's error, when there is one).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

from ..errors import InputError
from .command import _RANK, Command, make_command

if TYPE_CHECKING:
    from ..model.chain import Chain
    from .tasks_stage import TasksStage

__all__ = ["tasks_stage", "tasks_command"]


def tasks_stage(chain: Chain, tasks: Any, collision: Any, *, smoothed: bool,
                smoothing: Any) -> TasksStage | None:
    """The `TasksStage` of ``tasks`` and ``collision`` (None when neither is given), or
    InputError with smoothing (``smoothing``: the option as given, for the message)."""
    if tasks is None and collision is None:
        return None
    if smoothed:
        raise InputError("tasks= does not combine with smoothing yet: the cascade bounds the "
                         "acceleration itself; pass smoothing=False", argument="smoothing",
                         value=smoothing)
    from .tasks_stage import TasksStage

    return TasksStage(chain, list(tasks or ()), list(collision or ()))


def tasks_command(stage: TasksStage, chain: Chain, res: Any, q_next: np.ndarray, qd: np.ndarray,
                  qdd: np.ndarray, t0: float, dt: float, q: np.ndarray) -> Command:
    """The `Command` of one tasks cycle at the measured ``q`` (the controller's copy):
    the cascade's answer ``res`` with q_next, q̇, q̈ [rad, rad/s, rad/s²], the period
    starting at ``t0`` [s] and lasting ``dt`` [s]."""
    flags = res.flags or ("regular",)
    status = min(flags, key=_RANK.__getitem__)
    e = np.zeros(6)
    ep = eo = float("nan")
    for t in stage.tasks:  # the tool pose task's error, when there is one
        if type(t).__name__ == "Pose" and getattr(t, "link", None) is None and t.has_target:
            e = t.rows(chain, q).error.copy()
            ep, eo = float(np.linalg.norm(e[:3])), float(np.linalg.norm(e[3:]))
            break
    return make_command({"qd": qd, "q_next": q_next, "qdd": qdd.copy(), "status": status,
                         "flags": flags, "reason": "; ".join(res.reasons), "error": e,
                         "position_error": ep, "orientation_error": eo, "twist": np.zeros(6),
                         "sigma_min": float("nan"), "damping": 0.0, "task_error": res.residuals,
                         "velocity_scale": 1.0, "limits_active": res.limits_active, "time": t0,
                         "dt": dt, "solve": res}, chain, q)
