"""Franka arms (FR3, Panda) over the libfranka network protocol: `FrankyDriver`.

Built on `franky <https://github.com/TimSchneider42/franky>`_ (``pip install
ratectl[franka]``; ``franky`` is imported only when a `FrankyDriver` is made). It
works the same against a real arm and against ``franky-sim``, a simulated FR3 served on
loopback.

* The model comes from the robot itself: ``robot.model_urdf`` →
  `ratectl.Chain.from_urdf` with the flange link as tip (``link8``), then the tool.
* The limits are the ones franky enforces: ``robot.joint_velocity_limit``,
  ``joint_acceleration_limit`` and ``joint_jerk_limit``, times the dynamics factor. On the
  FR3 these are 2.175 rad/s on joints 1–4 (the URDF says 2.62): franky refuses a faster
  command, so the chain must carry these.
* ``command(qd)`` streams an asynchronous joint-velocity waypoint motion held for
  ``hold`` seconds: a new command takes over seamlessly; if none comes, the robot
  stops by itself after the hold.
* ``read()`` returns ``robot.state``: the stamp is the robot's own clock (1 ms resolution),
  q and q̇ as measured. While a motion runs, franky serves the state of its control thread
  — if the connection dies, the stamp stops advancing and `ratectl.run`'s watchdog
  halts.
* ``stop()`` runs franky's ``JointVelocityStopMotion`` (a jerk-limited stop) and waits
  for it up to ``stop_timeout``.
"""

from __future__ import annotations

import dataclasses
import time
from types import ModuleType
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from ..errors import DriverError, InputError
from ..model import Chain
from .base import RobotState

__all__ = ["FrankyDriver", "FrankySim", "franky_chain"]


def _import_franky() -> ModuleType:
    try:
        import franky
    except ImportError as exc:  # pragma: no cover - depends on the environment
        raise DriverError(
            f"FrankyDriver needs the franky package: pip install 'ratectl[franka]' (import failed: {exc})",
            driver="FrankyDriver",
            cause=exc,
        ) from exc
    return franky


def franky_chain(
    urdf: str,
    *,
    flange: str = "link8",
    tool: ArrayLike | None = None,
    vmax: ArrayLike | None = None,
    amax: ArrayLike | None = None,
    jmax: ArrayLike | None = None,
) -> Chain:
    """The arm's chain from its URDF text, tip ``flange``, with ``tool`` (flange → tool, 4×4,
    after the URDF's own fixed transforms up to the flange) and the given per-joint limits
    (None keeps the URDF's).

    Separate from `FrankyDriver` so that it can be checked without a robot.
    """
    chain = Chain.from_urdf(urdf, tip=flange)
    joints = []
    for i, j in enumerate(chain.joints):
        changes: dict[str, Any] = {}
        for name, value in (("vmax", vmax), ("amax", amax), ("jmax", jmax)):
            if value is not None:
                changes[name] = float(np.broadcast_to(np.asarray(value, dtype=float), (chain.dof,))[i])
        joints.append(dataclasses.replace(j, **changes))
    out = Chain(joints, base=chain.base, tool=chain.tool, name=chain.name)
    # the URDF's fixed joints up to the flange are the chain's tool already: the user's tool follows them
    return out if tool is None else out.with_tool(out.tool @ np.asarray(tool, dtype=float))


class FrankyDriver:
    """A Franka arm through franky, streaming joint velocities.

    Args:
        hostname: the robot's (FCI) address, e.g. ``"172.16.0.2"``, or franky-sim's loopback
            address (``sim_robot.hostname``).
        tool: flange → tool transform (4×4) for the chain, or None (the flange).
        flange: the URDF link that is the flange (the chain's tip), default ``"link8"``.
        dynamics_factor: franky's relative dynamics factor in (0, 1]: a number, or
            (velocity, acceleration, jerk). The chain's vmax, amax, jmax are the robot's limits
            times these factors.
        hold: how long the robot holds a velocity command without a new one [s] (franky's
            ``hold_target_duration``, whole milliseconds); afterwards it stops by itself.
        realtime: require a real-time kernel (franky's ``RealtimeConfig.Enforce``); the default
            ignores it (a simulator, a development machine).
        stop_timeout: how long `stop` waits for the arm to come to rest [s].
        connect_timeout: how long to keep trying to get the robot's first state [s].
        robot: an already connected ``franky.Robot`` to use instead of connecting.

    Raises:
        DriverError: franky is missing, the robot cannot be reached, or it refuses a setting.
    """

    def __init__(
        self,
        hostname: str,
        *,
        tool: ArrayLike | None = None,
        flange: str = "link8",
        dynamics_factor: ArrayLike = 1.0,
        hold: float = 0.02,
        realtime: bool = False,
        stop_timeout: float = 1.0,
        connect_timeout: float = 5.0,
        robot: Any = None,
    ) -> None:
        franky = _import_franky()
        self._franky = franky
        f = (
            np.broadcast_to(np.asarray(dynamics_factor, dtype=float), (3,))
            if np.ndim(dynamics_factor) <= 1
            else None
        )
        if f is None or f.shape != (3,) or not np.all((f > 0.0) & (f <= 1.0)):
            raise InputError(
                "dynamics_factor must be a number in (0, 1] or (velocity, acceleration, jerk) "
                f"factors in (0, 1], got {dynamics_factor!r}",
                argument="dynamics_factor",
                value=dynamics_factor,
            )
        hold_ms = int(round(float(hold) * 1000.0))
        if hold_ms < 1:
            raise InputError(f"hold must be at least 1 ms, got {hold!r} s", argument="hold", value=hold)
        self.hostname = str(hostname)
        self.hold = hold_ms / 1000.0
        self.stop_timeout = float(stop_timeout)
        try:
            if robot is None:
                cfg = franky.RealtimeConfig.Enforce if realtime else franky.RealtimeConfig.Ignore
                robot = franky.Robot(self.hostname, realtime_config=cfg)
            robot.relative_dynamics_factor = franky.RelativeDynamicsFactor(*map(float, f))
            urdf = robot.model_urdf
            # the first state: libfranka waits 1 s for a packet; a robot (or simulator) that is
            # still starting up may need a few tries
            deadline = time.monotonic() + float(connect_timeout)
            while True:
                try:
                    _ = robot.state
                    break
                except Exception:
                    if time.monotonic() > deadline:
                        raise
            vmax = np.asarray(robot.joint_velocity_limit.get(), dtype=float) * f[0]
            amax = np.asarray(robot.joint_acceleration_limit.get(), dtype=float) * f[1]
            jmax = np.asarray(robot.joint_jerk_limit.get(), dtype=float) * f[2]
        except Exception as exc:
            raise DriverError(
                f"cannot connect to the Franka robot at {self.hostname!r}: {type(exc).__name__}: {exc}",
                driver="FrankyDriver",
                cause=exc,
            ) from exc
        self._robot = robot
        self._hold = franky.Duration(hold_ms)
        self._Waypoint = franky.JointVelocityWaypoint
        self._Motion = franky.JointVelocityWaypointMotion
        self._chain = franky_chain(urdf, flange=flange, tool=tool, vmax=vmax, amax=amax, jmax=jmax)
        self.urdf = urdf

    @property
    def chain(self) -> Chain:
        """The arm from its own URDF, with the limits franky enforces (see the class docstring)."""
        return self._chain

    @property
    def robot(self) -> Any:
        """The underlying ``franky.Robot``."""
        return self._robot

    def read(self) -> RobotState:
        """``robot.state``: stamp (robot clock, 1 ms resolution) [s], q, q̇ as measured."""
        try:
            s = self._robot.state
            return RobotState(stamp=s.time.to_sec(), q=s.q, qd=s.dq)
        except Exception as exc:
            raise DriverError(
                f"reading the state of {self.hostname!r} failed: {type(exc).__name__}: {exc}",
                driver="FrankyDriver",
                cause=exc,
            ) from exc

    def command(self, qd: ArrayLike) -> None:
        """Stream ``qd`` (7,) [rad/s] as an asynchronous joint-velocity motion held for ``hold``."""
        v = np.asarray(qd, dtype=float).reshape(-1)
        if v.shape != (self._chain.dof,):
            raise InputError(
                f"qd must have shape ({self._chain.dof},), got {v.shape}", argument="qd", value=qd
            )
        try:
            motion = self._Motion([self._Waypoint(v, hold_target_duration=self._hold)])
            self._robot.move(motion, asynchronous=True)
        except Exception as exc:
            raise DriverError(
                f"the robot at {self.hostname!r} refused the velocity command "
                f"{np.array2string(v, precision=4)}: {type(exc).__name__}: {exc}",
                driver="FrankyDriver",
                cause=exc,
            ) from exc

    def stop(self) -> None:
        """A jerk-limited stop (franky's ``JointVelocityStopMotion``), waited for up to
        ``stop_timeout``; errors of a motion that ended badly are reported as DriverError."""
        try:
            if self._robot.is_in_control:
                self._robot.move(self._franky.JointVelocityStopMotion(), asynchronous=True)
            self._robot.join_motion(timeout=self.stop_timeout)
        except Exception as exc:
            raise DriverError(
                f"stopping the robot at {self.hostname!r} failed: {type(exc).__name__}: {exc}",
                driver="FrankyDriver",
                cause=exc,
            ) from exc

    def recover(self) -> bool:
        """Franka's automatic error recovery (after a reflex); True when it succeeded."""
        try:
            return bool(self._robot.recover_from_errors())
        except Exception as exc:
            raise DriverError(
                f"error recovery of {self.hostname!r} failed: {exc}", driver="FrankyDriver", cause=exc
            ) from exc

    def __repr__(self) -> str:
        return f"FrankyDriver({self.hostname!r}, chain={self._chain.name!r}, hold={self.hold:g} s)"


_SIM_SERVER = r"""
import os, random, sys
import franky_sim
from franky_sim.mujoco_simulator import MujocoSimulator

def candidates(start):
    for k in range(20000):
        i = (start + k) % 16000000 + 1
        yield f"127.{(i >> 16) & 255}.{(i >> 8) & 255}.{i & 255}"

q0 = tuple(float(v) for v in sys.argv[1].split(",")) if len(sys.argv) > 1 and sys.argv[1] else None
if len(sys.argv) > 2 and sys.argv[2]:
    try:  # a higher priority keeps the 1 kHz simulation on time on a busy machine, where allowed
        os.nice(int(sys.argv[2]))
    except OSError:
        pass
with MujocoSimulator() as sim:
    robot = sim.add_robot() if q0 is None else sim.add_robot(initial_q=q0)
    hosts = candidates(random.randrange(16000000))
    with franky_sim.SimulationServer(sim, hostname_candidates=hosts) as server:
        server.run_async()
        print("READY", robot.hostname, flush=True)
        sys.stdin.read()  # until the parent closes stdin
        server.running = False
"""


class FrankySim:
    """franky-sim's simulated FR3 served on loopback, in a process of its own.

    A separate process has its own interpreter lock, as a real robot has its own computer:
    the client's loop cannot starve the simulator. Use as a context manager::

        with FrankySim() as sim:
            driver = FrankyDriver(sim.hostname)
            ...

    Args:
        q0: the arm's initial joint positions (7,) [rad], default franky-sim's.
        nice: change the server's scheduling priority by this (``os.nice``; negative = higher,
            which needs the privilege — without it the request is ignored). On a busy machine the
            simulation, a Python loop at 1 kHz, otherwise falls behind real time.
        startup_timeout: how long to wait for the server to come up [s].

    Attributes:
        hostname: the loopback address the robot is served on (``127.x.y.z``).
        process: the server's ``subprocess.Popen``.
    """

    def __init__(
        self, *, q0: ArrayLike | None = None, nice: int | None = None, startup_timeout: float = 60.0
    ) -> None:
        import select
        import subprocess
        import sys

        arg = "" if q0 is None else ",".join(repr(float(v)) for v in np.asarray(q0, dtype=float).reshape(-1))
        self.process = subprocess.Popen(
            [sys.executable, "-c", _SIM_SERVER, arg, "" if nice is None else str(int(nice))],
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        )
        out = self.process.stdout
        assert out is not None
        ready, _, _ = select.select([out], [], [], float(startup_timeout))
        line = out.readline() if ready else ""
        if not line.startswith("READY"):
            self.kill()
            err = self.process.stderr.read()[-2000:] if self.process.stderr else ""
            raise DriverError(
                f"franky-sim did not start within {startup_timeout:g} s: {line.strip()} {err}",
                driver="FrankySim",
            )
        self.hostname = line.split()[1]

    def __enter__(self) -> FrankySim:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    @property
    def alive(self) -> bool:
        """True while the server process runs."""
        return self.process.poll() is None

    def close(self, timeout: float = 5.0) -> None:
        """Shut the server down (closes its stdin; kills it if it does not exit in ``timeout``)."""
        import subprocess

        if self.process.poll() is None:
            try:
                if self.process.stdin is not None:
                    self.process.stdin.close()
                self.process.wait(timeout)
            except (OSError, subprocess.TimeoutExpired):
                self.kill()
        try:
            self.process.wait(5.0)
        except subprocess.TimeoutExpired:  # pragma: no cover - a process that ignores SIGKILL
            pass
        for f in (self.process.stdout, self.process.stderr):
            if f is not None:
                f.close()

    def kill(self) -> None:
        """Kill the server at once (a robot that disappears); returns without waiting for the
        process to end (`close` reaps it)."""
        if self.process.poll() is None:
            self.process.kill()

    def pause(self) -> None:
        """Freeze the server (SIGSTOP): its state stops advancing, the connection stays."""
        import signal

        self.process.send_signal(signal.SIGSTOP)

    def resume(self) -> None:
        """Resume a paused server (SIGCONT)."""
        import signal

        self.process.send_signal(signal.SIGCONT)

    def __repr__(self) -> str:
        return f"FrankySim(hostname={getattr(self, 'hostname', None)!r}, alive={self.alive})"
