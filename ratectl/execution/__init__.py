"""Execution: running a controller over time and recording what happened.

* `path_following` — `follow`, a kinematic simulation of the
  controller (and the governor) along a Cartesian path;
* `run` — `run`, a real-time loop driving a robot through a
  `ratectl.drivers` driver (deadlines, watchdog, safe halts);
* `record` — `Execution`, the record every run returns.
"""

from .path_following import follow
from .record import Execution
from .run import run

__all__ = ["follow", "run", "Execution"]
