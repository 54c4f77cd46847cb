"""Execution: running a controller over time and recording what happened.

* :mod:`~ratectl.execution.path_following` — :func:`follow`, a kinematic simulation of the
  controller (and the governor) along a Cartesian path;
* :mod:`~ratectl.execution.run` — :func:`run`, a real-time loop driving a robot through a
  :mod:`ratectl.drivers` driver (deadlines, watchdog, safe halts);
* :mod:`~ratectl.execution.record` — :class:`Execution`, the record every run returns.
"""

from __future__ import annotations

from .path_following import follow
from .record import Execution
from .run import run

__all__ = ["follow", "run", "Execution"]
