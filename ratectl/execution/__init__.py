"""Execution: running a controller over time and recording what happened.

* :mod:`~ratectl.execution.path_following` — :func:`follow`, a kinematic simulation of the
  controller (and the governor) along a Cartesian path;
* :mod:`~ratectl.execution.record` — :class:`Execution`, the record every run returns.
"""

from __future__ import annotations

from .path_following import follow
from .record import Execution

__all__ = ["follow", "Execution"]
