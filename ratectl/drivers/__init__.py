"""Drivers: the robot as the control loop sees it.

* `base` — the `Driver` protocol (``chain``, ``read()`` →
  `RobotState`, ``command(qd)``, ``stop()``) and the rules a driver keeps;
* `scripted` — `ScriptedDriver`, a kinematic arm with
  injectable faults (for tests, and the template for a new driver);
* `franka` — `FrankyDriver`, Franka arms over franky
  (``franky`` is imported only when one is made);
* ``MujocoDriver`` — a MuJoCo model stepping its physics. It lives in
  `ratectl.interop.mujoco.driver` (MuJoCo interop sits above this layer) and is
  re-exported here lazily: ``rc.drivers.MujocoDriver`` imports it, and ``mujoco``, on
  first use.

`ratectl.run` drives any of them.
"""

import importlib as _importlib
from typing import Any as _Any

from .base import Driver, RobotState
from .franka import FrankyDriver, FrankySim, franky_chain
from .scripted import ScriptedDriver

__all__ = [
    "Driver",
    "RobotState",
    "ScriptedDriver",
    "FrankyDriver",
    "FrankySim",
    "franky_chain",
    "MujocoDriver",
]


def __getattr__(name: str) -> _Any:
    # a re-export from the interop layer, resolved on first use (no import at load time)
    if name == "MujocoDriver":
        value = _importlib.import_module("ratectl.interop.mujoco.driver").MujocoDriver
        globals()[name] = value
        return value
    raise AttributeError(f"module 'ratectl.drivers' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
