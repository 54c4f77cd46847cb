"""Control: the resolved-rate controller, its command, and Ruckig smoothing.

* `controller` — `ResolvedRateController`, one ``step`` per cycle, composing its stages:
  `gate` (validation, the halt policy), `servo` (the approach to a target, with
  `approach`), `jog` (jogging along a twist), `progress_stage` (what both share, with
  `progress`), `limiter` (the joint limits), `smooth_stage` (the smoothed position guard),
  `halt` (the safe halt's motion), `tasks_hook` (with `tasks_stage`); `cycle` holds the
  working state of one cycle;
* `command` — `Command` and the status vocabulary;
* `smoothing` — the Ruckig velocity filter, joint moves and stops.

Braking toward position limits lives with the limits (`ratectl.model.limits`).
"""

from .command import STATUSES, Command
from .controller import ResolvedRateController, default_solver
from .smoothing import JointTrajectory, VelocityFilter, move, stop

__all__ = ["ResolvedRateController", "Command", "STATUSES", "default_solver", "VelocityFilter",
           "JointTrajectory", "move", "stop"]
