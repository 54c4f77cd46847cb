"""The driver protocol: what `ratectl.run` needs from a robot.

A driver is the robot as the control loop sees it — four members:

* ``chain`` — the arm's model (`ratectl.Chain`), with the limits the robot itself
  enforces;
* ``read()`` → `RobotState` — the latest measured state: a time stamp on the
  robot's clock [s] and the joint positions q and velocities q̇ as measured;
* ``command(qd)`` — stream a joint velocity q̇ (n,) [rad/s or m/s]; the robot holds it until
  the next command (or, on robots with a hold time, briefly, then stops by itself);
* ``stop()`` — bring the arm to rest within its own limits (idempotent).

Rules a driver keeps, which the loop relies on:

1. ``read()`` returns promptly (well within a control period). When no new sample has
   arrived it returns the last one again, *with its old stamp*: the loop decides from the
   stamps whether the state is fresh, and halts when it is not fresh for ``timeout``.
2. Stamps of fresh samples increase strictly.
3. A failure of the robot's own library is raised as `ratectl.errors.DriverError`
   (with the original exception as ``cause``); the loop turns it into a safe halt.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Protocol, runtime_checkable

import numpy as np
from numpy.typing import ArrayLike

from ..arrays import read_only
from ..model import Chain

__all__ = ["RobotState", "Driver"]


@dataclass(frozen=True, kw_only=True, eq=False)
class RobotState:
    """One measured state of the robot.

    Attributes:
        stamp: when the robot measured it, on the robot's clock [s] (only differences matter).
        q: (n,) measured joint positions [rad or m] (read-only).
        qd: (n,) measured joint velocities [rad/s or m/s] (read-only).
    """

    stamp: float
    q: np.ndarray
    qd: np.ndarray

    def __post_init__(self) -> None:
        object.__setattr__(self, "stamp", float(self.stamp))
        for name in ("q", "qd"):
            object.__setattr__(self, name, read_only(np.reshape(getattr(self, name), -1)))

    @property
    def finite(self) -> bool:
        """True when the stamp, q and q̇ are all finite numbers."""
        return math.isfinite(self.stamp) and math.isfinite(float(self.q.sum() + self.qd.sum()))

    def __repr__(self) -> str:
        return (
            f"RobotState(stamp={self.stamp:.6g}, q={np.array2string(self.q, precision=4)}, "
            f"qd={np.array2string(self.qd, precision=4)})"
        )


@runtime_checkable
class Driver(Protocol):
    """A robot (or a simulator of one) that `ratectl.run` can drive.

    See the module docstring for the rules; `ScriptedDriver` is a
    complete example in a few dozen lines.
    """

    @property
    def chain(self) -> Chain:
        """The arm's kinematic model, with the limits the robot enforces."""
        ...

    def read(self) -> RobotState:
        """The latest measured state (the previous one again, same stamp, if none is new)."""
        ...

    def command(self, qd: ArrayLike) -> None:
        """Command the joint velocity ``qd`` (n,) [rad/s or m/s]."""
        ...

    def stop(self) -> None:
        """Bring the arm to rest within its own limits; safe to call more than once."""
        ...
