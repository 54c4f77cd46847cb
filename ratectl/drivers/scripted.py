"""A scripted kinematic robot for tests: `ScriptedDriver`.

The arm integrates the commanded joint velocity exactly over wall-clock time,

    q(t) = q_k + q̇_k · (t − t_k)          (t_k: time of the last command q̇_k),

(a joint commanded slower than its ``dead_band`` stands still: static friction), or with a
velocity ``lag`` τ > 0 the joints' velocity v follows the command as a first-order servo,
v̇ = (q̇_k − v)/τ, integrated exactly:

    v(t) = q̇_k + (v_k − q̇_k)·e^(−(t − t_k)/τ),
    q(t) = q_k + q̇_k·(t − t_k) + (v_k − q̇_k)·τ·(1 − e^(−(t − t_k)/τ))

(a unit-gain servo: at rest again, the arm has covered every commanded displacement, but
later — it keeps moving after a zero command). It serves the arm through the `Driver`
protocol, with faults that can be switched on at given times: slow reads, dropped samples,
a frozen (stale) server, NaN in the measurement, and a connection that dies. It is also
the shortest complete driver — a template for writing one for another robot.
"""

from __future__ import annotations

import math
import time

import numpy as np
from numpy.typing import ArrayLike

from ..checks import positive_number
from ..errors import DriverError, InputError
from ..model import Chain
from .base import RobotState

__all__ = ["ScriptedDriver"]


class ScriptedDriver:
    """A kinematic arm that does what it is told, with injectable faults.

    Times below are measured from the driver's first ``read()`` or ``command()`` [s].

    Args:
        chain: the arm. q0: (n,) initial joint positions.
        strict: refuse (raise `DriverError`) a command faster than the
            chain's vmax or not finite — as real robots do.
        read_delay: every ``read()`` takes this long [s] (a slow link; it is slept).
        drop: probability that a ``read()`` returns the previous sample again, same stamp
            (a dropped sample); drawn from ``seed``.
        stale_after: from this time on the server freezes: ``read()`` returns the same sample
            forever (its stamp no longer advances); the arm keeps moving unseen.
        nan_after: from this time on the measured q contains NaN.
        freeze_joint: ``(j, t)``: from time t on, joint j (0-based) no longer moves, whatever
            is commanded — a stalled joint, a robot that does not follow its command; it is
            measured standing still (q̇ = 0).
        dead_band: [rad/s or m/s], a number or one per joint: a joint commanded slower than
            this does not move (static friction a small velocity command cannot break, as on
            a real arm); it is measured standing still.
        lag: τ [s], the time constant of a first-order velocity servo (module docstring): the
            measured q̇ is the joints' lagging velocity v. 0 (default): v is the command at once.
        period: None (default): the arm moves in wall-clock time. A number [s]: the arm's
            clock advances by this much at each ``read()`` and stands still otherwise (a
            simulated robot stepped by the loop, as `MujocoDriver` is): runs are then
            deterministic however loaded the machine is. Times above are on this clock.
        fail_after: from this time on ``read()`` and ``command()`` raise a bare
            ``ConnectionResetError`` — deliberately *not* a ratectl error, as a careless driver
            would, so that tests can check the loop contains it.
        seed: seed of the drop draws.

    Attributes:
        commands: list of ``(t, qd)`` of every accepted command.
        stops: how many times `stop` was called.
    """

    def __init__(
        self,
        chain: Chain,
        q0: ArrayLike,
        *,
        strict: bool = True,
        read_delay: float = 0.0,
        drop: float = 0.0,
        stale_after: float | None = None,
        nan_after: float | None = None,
        fail_after: float | None = None,
        freeze_joint: tuple[int, float] | None = None,
        dead_band: ArrayLike = 0.0,
        lag: float = 0.0,
        period: float | None = None,
        seed: int = 0,
    ) -> None:
        if not isinstance(chain, Chain):
            raise InputError(
                f"chain must be a ratectl.Chain, got {type(chain).__name__}", argument="chain", value=chain
            )
        self._chain = chain
        q = chain.check_q(q0, name="q0").astype(float).reshape(-1).copy()
        if q.shape != (chain.dof,):
            raise InputError(f"q0 must have shape ({chain.dof},), got {q.shape}", argument="q0", value=q0)
        read_delay = positive_number("read_delay", read_delay, allow_zero=True, unit="[s]")
        drop = positive_number("drop", drop, allow_zero=True)
        if not drop <= 1.0:
            raise InputError(
                f"drop must be a probability in [0, 1], got {drop!r}", argument="drop", value=drop
            )
        if isinstance(seed, bool) or not isinstance(seed, int | np.integer) or seed < 0:
            raise InputError(f"seed must be a non-negative integer, got {seed!r}", argument="seed",
                             value=seed)
        stale_after, nan_after, fail_after = (
            math.inf if v is None else positive_number(name, v, allow_zero=True, allow_inf=True,
                                                       unit="[s]")
            for name, v in (("stale_after", stale_after), ("nan_after", nan_after),
                            ("fail_after", fail_after))
        )
        self._q = q
        self._qd = np.zeros(chain.dof)
        self._t_cmd: float | None = None
        self._t0: float | None = None
        self.strict = bool(strict)
        self.read_delay = read_delay
        self.drop = drop
        self.stale_after = stale_after
        self.nan_after = nan_after
        self.fail_after = fail_after
        self.freeze_joint: tuple[int, float] | None = None
        if freeze_joint is not None:
            try:
                j, t_freeze = int(freeze_joint[0]), float(freeze_joint[1])
            except (TypeError, ValueError, IndexError):
                raise InputError(f"freeze_joint must be (joint index, time [s]), got {freeze_joint!r}",
                                 argument="freeze_joint", value=freeze_joint) from None
            if not 0 <= j < chain.dof:
                raise InputError(f"freeze_joint: joint index must be in 0..{chain.dof - 1}, got {j}",
                                 argument="freeze_joint", value=freeze_joint)
            self.freeze_joint = (j, t_freeze)
        try:
            if isinstance(dead_band, str | bytes) or np.iscomplexobj(dead_band):
                raise TypeError("dead_band")
            band = np.broadcast_to(np.asarray(dead_band, dtype=float), (chain.dof,)).copy()
        except (TypeError, ValueError, OverflowError):
            band = np.full(chain.dof, np.nan)
        if not np.all(np.isfinite(band)) or np.any(band < 0.0):
            raise InputError(f"dead_band must be a non-negative speed [rad/s or m/s], one or one per joint "
                             f"({chain.dof}), got {dead_band!r}"[:200], argument="dead_band", value=dead_band)
        self.dead_band = band
        self.lag = positive_number("lag", lag, allow_zero=True, unit="[s]")
        self._v = np.zeros(chain.dof)  # the joints' velocity (lagging the command when lag > 0)
        self.period = None if period is None else positive_number("period", period, unit="[s]")
        self._clock: float | None = None  # the stepped clock's time [s] (period given), from the first read
        self._rng = np.random.default_rng(int(seed))
        self._last: RobotState | None = None
        self.commands: list[tuple[float, np.ndarray]] = []
        self.stops = 0

    @property
    def chain(self) -> Chain:
        """The arm."""
        return self._chain

    def _now(self, *, tick: bool = False) -> float:
        """The arm's time [s] since the first read or command (``tick``: a read, which steps a
        stepped clock by ``period`` after the first)."""
        if self.period is not None:
            if self._clock is None:
                self._clock = 0.0
            elif tick:
                self._clock += self.period
            return self._clock
        now = time.monotonic()
        if self._t0 is None:
            self._t0 = now
        return now - self._t0

    def _moving(self) -> np.ndarray:
        """The velocity the joints move at: the command, zero within the dead band."""
        return np.where(np.abs(self._qd) < self.dead_band, 0.0, self._qd)

    def _travel(self, h: float) -> tuple[np.ndarray, np.ndarray]:
        """(displacement, velocity at the end) over ``h`` [s] from now under the command
        (module docstring: at once, or through the first-order lag τ)."""
        vc = self._moving()
        if self.lag == 0.0:
            return vc * h, vc
        decay = math.exp(-h / self.lag)
        dv = self._v - vc
        return vc * h + dv * (self.lag * (1.0 - decay)), vc + dv * decay

    def _advance(self, t: float) -> None:
        """Integrate the commanded velocity up to time t (a frozen joint stands still)."""
        if self._t_cmd is not None and t > self._t_cmd:
            moved, v = self._travel(t - self._t_cmd)
            if self.freeze_joint is not None:
                j, t_f = self.freeze_joint
                moved[j] = self._travel(max(0.0, min(t, t_f) - self._t_cmd))[0][j]
                if t >= t_f:
                    v[j] = 0.0
            self._q = self._q + moved
            self._v = v
        self._t_cmd = t

    def _measured_qd(self, t: float) -> np.ndarray:
        qd = self._moving() if self.lag == 0.0 else self._v.copy()
        if self.freeze_joint is None or t < self.freeze_joint[1]:
            return qd
        qd[self.freeze_joint[0]] = 0.0
        return qd

    def read(self) -> RobotState:
        """The arm's state now (see the class docstring for the faults)."""
        if self.read_delay > 0.0:
            time.sleep(self.read_delay)
        t = self._now(tick=True)
        if t >= self.fail_after:
            raise ConnectionResetError("scripted connection reset by peer")
        self._advance(t)
        last = self._last
        if last is not None and (
            t >= self.stale_after or (self.drop > 0.0 and self._rng.random() < self.drop)
        ):
            return last
        q = self._q.copy()
        if t >= self.nan_after:
            q[0] = math.nan
        self._last = RobotState(stamp=t, q=q, qd=self._measured_qd(t))
        return self._last

    def command(self, qd: ArrayLike) -> None:
        """Move at ``qd`` (n,) from now on."""
        t = self._now()
        if t >= self.fail_after:
            raise ConnectionResetError("scripted connection reset by peer")
        try:
            if isinstance(qd, str | bytes) or np.iscomplexobj(qd):
                raise TypeError("qd")
            v = np.asarray(qd, dtype=float).reshape(-1)
        except (TypeError, ValueError, OverflowError):
            raise InputError(f"qd must be a ({self._chain.dof},) vector of joint velocities [rad/s or "
                             f"m/s], got {qd!r}"[:200], argument="qd", value=qd) from None
        if v.shape != (self._chain.dof,):
            raise InputError(
                f"qd must have shape ({self._chain.dof},), got {v.shape}", argument="qd", value=qd
            )
        if self.strict:
            if not np.all(np.isfinite(v)):
                raise DriverError("refused a non-finite joint velocity command", driver="ScriptedDriver")
            over = np.abs(v) > self._chain.vmax * (1.0 + 1e-9)
            if over.any():
                j = int(np.flatnonzero(over)[0])
                raise DriverError(
                    f"refused joint velocity {v[j]:.6g} on joint {self._chain.joint_names[j]!r}: "
                    f"exceeds vmax {self._chain.vmax[j]:.6g}",
                    driver="ScriptedDriver",
                )
        self._advance(t)
        self._qd = v.copy()
        self.commands.append((t, self._qd))

    def stop(self) -> None:
        """Stop at once (a kinematic arm has no dynamics to respect; a lagging one too)."""
        self.stops += 1
        if self._t0 is not None:
            self._advance(self._now())
        self._qd = np.zeros(self._chain.dof)
        self._v = np.zeros(self._chain.dof)

    @property
    def q(self) -> np.ndarray:
        """The arm's true joint positions now, seen or not (for tests)."""
        if self._t0 is not None:
            self._advance(self._now())
        return self._q.copy()

    def __repr__(self) -> str:
        return f"ScriptedDriver({self._chain.name!r}, commands={len(self.commands)}, stops={self.stops})"
