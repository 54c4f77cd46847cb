"""A MuJoCo model as a robot: `MujocoDriver` (the `ratectl.drivers.Driver` protocol).

Also reachable as ``ratectl.drivers.MujocoDriver`` (imported on first use there).
Each ``command(qd)`` advances the physics by one control ``period`` — the same servo
scheme as `simulate`:

* ``"position"`` servos (force = kp·(u − q) − kv·q̇) track the commanded ramp with velocity
  feed-forward, ``u(τ) = q_k + q̇·τ + (kv/kp)·q̇`` (τ: time since the command);
* ``"velocity"`` servos (force = kv·(u − q̇)) get ``u = q̇``.

``read()`` returns the physics state: the stamp is MuJoCo's ``data.time``, so it advances
only when commands step the physics — run it with ``rate_hz = 1/period`` and the physics
keeps pace with the wall clock.
"""

from __future__ import annotations

import math
import os

import mujoco
import numpy as np
from numpy.typing import ArrayLike

from ...drivers import RobotState
from ...errors import DriverError, InputError
from ...io.mjcf import mjcf_joint_addresses
from ...model import Chain
from .export import compile_mjcf, to_mjcf
from .simulation import ACTUATIONS, _actuators_for, _servo_period

__all__ = ["MujocoDriver"]


class MujocoDriver:
    """A MuJoCo model driven by joint-velocity commands, one control period per command.

    Args:
        chain: the arm; its joint names select the model's joints and actuators.
        model_or_xml: an ``MjModel``, MJCF text or path; None exports ``chain`` with
            `to_mjcf` and actuators of the requested kind.
        q0: initial joint positions (n,) [rad or m]; the arm starts at rest.
        period: physics time advanced per command [s]; a whole multiple of the model time step.
        actuation: ``"position"`` or ``"velocity"`` servos.
        stop_time: how long `stop` may step the physics to bring the arm to rest [s].

    Attributes:
        model, data: the MuJoCo model and data (e.g. to render or read contacts).
    """

    def __init__(
        self,
        chain: Chain,
        model_or_xml: mujoco.MjModel | str | os.PathLike[str] | None = None,
        *,
        q0: ArrayLike,
        period: float = 0.002,
        actuation: str = "position",
        stop_time: float = 1.0,
    ) -> None:
        if not isinstance(chain, Chain):
            raise InputError(
                f"chain must be a ratectl.Chain, got {type(chain).__name__}", argument="chain", value=chain
            )
        if actuation not in ACTUATIONS:
            raise InputError(
                f"actuation must be one of {ACTUATIONS}, got {actuation!r}",
                argument="actuation",
                value=actuation,
            )
        if model_or_xml is None:
            model_or_xml = to_mjcf(chain, actuators=actuation)
        self.model = model = compile_mjcf(model_or_xml)
        self.data = data = mujoco.MjData(model)
        self._chain = chain
        self._qadr, self._dadr = mjcf_joint_addresses(model, chain)
        jids = [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, n) for n in chain.joint_names]
        self._act, kp, kv = _actuators_for(model, jids, chain.joint_names, actuation)
        self._ff = np.where(kp > 0, kv / np.where(kp > 0, kp, 1.0), 0.0)
        self.actuation = actuation
        h = float(model.opt.timestep)
        self._nsub = int(round(float(period) / h))
        if self._nsub < 1 or abs(self._nsub * h - period) > 1e-9 * max(period, 1.0):
            raise InputError(
                f"period = {period} s must be a whole multiple of the model time step {h} s",
                argument="period",
                value=period,
            )
        self.period = self._nsub * h
        self.stop_time = float(stop_time)
        q = chain.check_q(q0, name="q0").astype(float).reshape(-1)
        if q.shape != (chain.dof,):
            raise InputError(f"q0 must have shape ({chain.dof},), got {q.shape}", argument="q0", value=q0)
        data.qpos[self._qadr] = q
        data.qvel[:] = 0.0
        data.ctrl[self._act] = q if actuation == "position" else 0.0
        mujoco.mj_forward(model, data)

    @property
    def chain(self) -> Chain:
        """The arm."""
        return self._chain

    def read(self) -> RobotState:
        """The physics state: stamp ``data.time`` [s], q and q̇ of the chain's joints."""
        d = self.data
        return RobotState(stamp=float(d.time), q=d.qpos[self._qadr], qd=d.qvel[self._dadr])

    def command(self, qd: ArrayLike) -> None:
        """Servo toward ``qd`` (n,) for one period of physics (see the module docstring)."""
        v = np.asarray(qd, dtype=float).reshape(-1)
        if v.shape != (self._chain.dof,):
            raise InputError(
                f"qd must have shape ({self._chain.dof},), got {v.shape}", argument="qd", value=qd
            )
        if not np.all(np.isfinite(v)):
            raise DriverError("refused a non-finite joint velocity command", driver="MujocoDriver")
        self._step(v, self._nsub)

    def _step(self, v: np.ndarray, nsub: int) -> None:
        d = self.data
        q = np.array(d.qpos[self._qadr])
        _, stable = _servo_period(self.model, d, self._act, q, v, self._ff, nsub, self.actuation)
        if not stable:
            raise DriverError(
                f"the MuJoCo simulation became unstable at t = {d.time:.4g} s (non-finite or huge "
                "accelerations; MuJoCo reset the state); lower the servo gains or the time step",
                driver="MujocoDriver",
            )

    def stop(self) -> None:
        """Command zero velocity and step the physics until the arm is at rest (|q̇| < 1e-3)
        or ``stop_time`` has passed."""
        zero = np.zeros(self._chain.dof)
        steps = max(1, int(math.ceil(self.stop_time / self.period)))
        for _ in range(steps):
            if float(np.max(np.abs(self.data.qvel[self._dadr]))) < 1e-3:
                break
            self._step(zero, self._nsub)

    def __repr__(self) -> str:
        return (
            f"MujocoDriver({self._chain.name!r}, actuation={self.actuation!r}, period={self.period:g} s, "
            f"t={self.data.time:.4g} s)"
        )
