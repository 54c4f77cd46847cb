"""Control: the resolved-rate controller, its command, and Ruckig smoothing.

* `controller` — `ResolvedRateController`, one ``step`` per cycle;
* `command` — `Command` and the status vocabulary;
* `smoothing` — the Ruckig velocity filter, joint moves and stops.

Braking toward position limits lives with the limits (`ratectl.model.limits`).
"""

from .command import STATUSES, Command
from .controller import ResolvedRateController, default_solver
from .smoothing import JointTrajectory, VelocityFilter, move, stop

__all__ = ["ResolvedRateController", "Command", "STATUSES", "default_solver", "VelocityFilter",
           "JointTrajectory", "move", "stop"]
