"""The record of an executed motion: `Execution`.

Returned by `ratectl.follow` (kinematic path following), by `ratectl.run`
(a real-time loop on a robot) and by the MuJoCo simulation; generic on purpose — arrays
over the K recorded steps plus metadata — so any producer can fill it. Arrays that a
producer does not have are ``None``. The record is frozen: fields are set once, by
keyword, its arrays are read-only and ``info`` is a read-only mapping (nested mappings too;
lists in it become tuples, arrays in it read-only).
"""

from __future__ import annotations

import math
import os
from collections.abc import Mapping
from dataclasses import dataclass, field, fields
from types import MappingProxyType
from typing import IO, TYPE_CHECKING, Any

import numpy as np

from ..arrays import read_only

if TYPE_CHECKING:
    from matplotlib.figure import Figure

__all__ = ["Execution"]

_ARRAY_FIELDS = ("t", "q", "qd", "qdd", "poses", "position_error", "orientation_error", "tracking_error",
                 "sigma_min", "s", "vmax", "amax", "q_measured", "qd_measured", "q_commanded", "stamps",
                 "fresh", "periods")


@dataclass(frozen=True, eq=False, kw_only=True)
class Execution:
    """An executed joint motion and how well it did.

    Attributes (arrays over K recorded steps):
        t: (K,) times [s].
        q: (K, n) joint positions [rad or m].
        qd: (K, n) joint velocities [rad/s or m/s].
        qdd: (K, n) joint accelerations [rad/s² or m/s²].
        poses: (K, 4, 4) tool poses fk(q), or None.
        position_error: (K,) distance of the tool origin from the *path* (nearest point
            of the curve) [m].
        orientation_error: (K,) angle between the tool orientation and the path's
            orientation at that point [rad].
        tracking_error: (K,) distance from the *reference* pose of the same step [m] (how
            far behind or ahead of the schedule), or None.
        statuses: (K,) controller status per step (see ``ratectl.controller.STATUSES``).
        reasons: (K,) the controller's reason per step ("" when regular), or () when not
            recorded.
        kinds: (K,) singularity kind for steps whose status is "damped" or "singular"
            (None elsewhere), or None when not recorded.
        sigma_min: (K,) σ_min(J) per step (NaN where unknown).
        s: (K,) path parameter of the reference per step [m], or None.
        nominal_duration: duration of the path's own time law [s].
        duration: duration of the execution [s]: for ``follow``, the time from which the
            end pose stays within tolerance (not the settle wait after it), else
            ``t[-1] − t[0]``.
        completed: the motion reached the end of the path within tolerance.
        message: a one-line account (why it did not complete, how much longer it took).
        source: who produced it ("follow", "simulate", ...).
        chain_name: the arm's name.
        joint_names: its joint names.
        vmax: (n,) velocity limits used for checks and plots, or None.
        amax: (n,) acceleration limits used for checks and plots, or None.
        info: further numbers (e.g. the governor plan, solver names); a read-only mapping.

    Attributes of a run on a robot (`ratectl.run`; None or defaults elsewhere):
        q_measured, qd_measured: (K, n) joint positions and velocities as the robot measured
            them (``q`` is then the same positions; ``qd`` and ``qdd`` are the *commanded*
            velocity and its change).
        q_commanded: (K, n) the joint positions each command leads to (the controller's
            ``q_next``): the commanded stream beside the measured one.
        stamps: (K,) the robot's time stamps of the measured states [s].
        fresh: (K,) True where the cycle got a new measured state (False: the stamp had not
            advanced and the previous command was held).
        periods: (K,) wall-clock time from the previous cycle's start to this one's [s]
            (the first is the nominal period).
        rate_hz: the requested loop rate [Hz]; overruns: cycles whose work ended after their
            deadline.
    """

    t: np.ndarray
    q: np.ndarray
    qd: np.ndarray
    qdd: np.ndarray
    poses: np.ndarray | None = None
    position_error: np.ndarray | None = None
    orientation_error: np.ndarray | None = None
    tracking_error: np.ndarray | None = None
    statuses: tuple[str, ...] = ()
    reasons: tuple[str, ...] = ()
    kinds: tuple[str | None, ...] | None = None
    sigma_min: np.ndarray | None = None
    s: np.ndarray | None = None
    nominal_duration: float = float("nan")
    duration: float = float("nan")
    completed: bool = False
    message: str = ""
    source: str = ""
    chain_name: str = ""
    joint_names: tuple[str, ...] = ()
    vmax: np.ndarray | None = None
    amax: np.ndarray | None = None
    info: Mapping[str, Any] = field(default_factory=lambda: _EMPTY)
    q_measured: np.ndarray | None = None
    qd_measured: np.ndarray | None = None
    q_commanded: np.ndarray | None = None
    stamps: np.ndarray | None = None
    fresh: np.ndarray | None = None
    periods: np.ndarray | None = None
    rate_hz: float = float("nan")
    overruns: int = 0

    def __post_init__(self) -> None:
        # read-only arrays; an array the caller still writes to is copied first
        for name in _ARRAY_FIELDS:
            a = getattr(self, name)
            if a is None:
                continue
            object.__setattr__(self, name, read_only(a, dtype=None))
        object.__setattr__(self, "info", _frozen(self.info) if self.info else _EMPTY)

    def __reduce__(self) -> tuple[Any, ...]:
        # a mappingproxy cannot be pickled: the record travels with plain dicts and is frozen again
        values = {f.name: getattr(self, f.name) for f in fields(self)}
        values["info"] = _thawed(self.info)
        return _restore_execution, (values,)

    # ------------------------------------------------------------------ summaries
    @property
    def steps(self) -> int:
        return len(self.t)

    @property
    def extra_time(self) -> float:
        """duration − nominal duration [s] (how much longer the motion took)."""
        return self.duration - self.nominal_duration

    @property
    def slowdown(self) -> float:
        """duration / nominal duration (1 = on schedule)."""
        return self.duration / self.nominal_duration if self.nominal_duration > 0 else float("nan")

    @property
    def max_position_error(self) -> float:
        """Largest distance from the path [m]."""
        return float(np.max(self.position_error)) if self.position_error is not None else float("nan")

    @property
    def max_orientation_error(self) -> float:
        """Largest orientation error [rad]."""
        return float(np.max(self.orientation_error)) if self.orientation_error is not None else float("nan")

    @property
    def velocity_ratio(self) -> float:
        """max over steps and joints of |q̇_i|/vmax_i (≤ 1 when the limits held)."""
        if self.vmax is None:
            return float("nan")
        return float(np.max(np.abs(self.qd) / self.vmax))

    @property
    def acceleration_ratio(self) -> float:
        """max over steps and joints of |q̈_i|/amax_i."""
        if self.amax is None:
            return float("nan")
        return float(np.max(np.abs(self.qdd) / self.amax))

    # ------------------------------------------------------------------ loop timing
    def period_quantile(self, p: float) -> float:
        """The p-quantile (0…1) of the loop periods [s] (NaN without timing)."""
        if self.periods is None or len(self.periods) < 2:
            return float("nan")
        return float(np.quantile(self.periods[1:], p))

    @property
    def period_p50(self) -> float:
        """Median loop period [s]."""
        return self.period_quantile(0.5)

    @property
    def period_p99(self) -> float:
        """99th percentile of the loop period [s]."""
        return self.period_quantile(0.99)

    @property
    def period_max(self) -> float:
        """Longest loop period [s]."""
        return float(np.max(self.periods[1:])) if self.periods is not None and len(self.periods) > 1 \
            else float("nan")

    @property
    def achieved_rate_hz(self) -> float:
        """Cycles per second over the run: (K − 1) / (sum of the periods after the first)."""
        if self.periods is None or len(self.periods) < 2:
            return float("nan")
        return float((len(self.periods) - 1) / np.sum(self.periods[1:]))

    def status_counts(self) -> dict[str, int]:
        """How many steps had each status."""
        out: dict[str, int] = {}
        for s in self.statuses:
            out[s] = out.get(s, 0) + 1
        return out

    def summary(self) -> str:
        """A few lines: completion, timing, errors, limits, statuses."""
        lines = [f"{self.source or 'execution'} of {self.chain_name or 'arm'}: "
                 f"{'completed' if self.completed else 'NOT completed'}"
                 + (f" — {self.message}" if self.message and not self.message.startswith("completed")
                    else "")]
        if math.isfinite(self.nominal_duration):
            lines.append(f"  duration {self.duration:.3f} s vs nominal {self.nominal_duration:.3f} s "
                         f"({self.extra_time:+.3f} s, ×{self.slowdown:.2f})")
        lines.extend(self._error_lines())
        lines.append(f"  max |q̇|/vmax {self.velocity_ratio:.3f}, max |q̈|/amax {self.acceleration_ratio:.3f}")
        if self.sigma_min is not None and np.any(np.isfinite(self.sigma_min)):
            lines.append(f"  min σ_min(J) {np.nanmin(self.sigma_min):.4g} (unscaled J, analyze().sigma_min)")
        if self.periods is not None and len(self.periods) > 1:
            lines.append(f"  loop {self.achieved_rate_hz:.1f} Hz of {self.rate_hz:g} Hz requested; period "
                         f"p50 {self.period_p50 * 1e3:.3f} ms, p99 {self.period_p99 * 1e3:.3f} ms, "
                         f"max {self.period_max * 1e3:.3f} ms; {self.overruns} overrun(s)"
                         + (f", {int(np.count_nonzero(~self.fresh))} stale cycle(s)"
                            if self.fresh is not None else ""))
        if self.statuses:
            lines.append("  statuses: " + ", ".join(f"{k} {v}" for k, v in self.status_counts().items()))
        return "\n".join(lines)

    def _error_lines(self) -> list[str]:
        """What the errors mean for this kind of run: the path error of a path, the distance to
        the target over time of a target run, the tracking of a twist stream."""
        mode = self.info.get("mode", "path")
        if mode == "twist":
            lin, ang = self.info.get("twist_linear_error"), self.info.get("twist_angular_error")
            if lin is None or ang is None or not np.any(np.isfinite(lin)):
                return []
            a50, amax = math.degrees(float(np.nanmedian(ang))), math.degrees(float(np.nanmax(ang)))
            return [f"  twist tracking (measured J q̇ − streamed twist): linear median "
                    f"{np.nanmedian(lin) * 1e3:.3g} mm/s, max {np.nanmax(lin) * 1e3:.3g} mm/s; "
                    f"angular median {a50:.3g}°/s, max {amax:.3g}°/s"]
        if self.position_error is None or self.orientation_error is None:
            return []
        if mode == "target":
            pe, oe = self.position_error, self.orientation_error
            marks = [0.0, 0.25, 0.5, 1.0]
            idx = [min(int(round(m * (len(pe) - 1))), len(pe) - 1) for m in marks]
            over = ", ".join(f"t {self.t[k]:.2f} s: {pe[k] * 1e3:.3g} mm / {math.degrees(oe[k]):.3g}°"
                             for k in idx)
            return [f"  distance to the target: {over}"]
        return [f"  max path error {self.max_position_error * 1e3:.4g} mm, "
                f"{math.degrees(self.max_orientation_error):.4g}°"]

    def __repr__(self) -> str:
        return (f"Execution(source={self.source!r}, steps={self.steps}, completed={self.completed}, "
                f"duration={self.duration:.4g} s)")

    # ------------------------------------------------------------------ plot
    def plot(
        self, *, file: str | os.PathLike[str] | IO[bytes] | None = None, title: str | None = None
    ) -> Figure:
        """Joint velocities (with ±vmax), path errors and σ_min against time.

        matplotlib is imported here (optional dependency). Returns the figure; with
        ``file`` it is also saved there (the backend is not changed otherwise).
        """
        import matplotlib.pyplot as plt

        rows = 3 if self.sigma_min is not None else 2
        fig, axes = plt.subplots(rows, 1, sharex=True, figsize=(8, 2.4 * rows + 0.6))
        ax = axes[0]
        names = self.joint_names or tuple(f"q{i + 1}" for i in range(self.qd.shape[1]))
        for i in range(self.qd.shape[1]):
            line, = ax.plot(self.t, self.qd[:, i], lw=1.2, label=names[i])
            if self.vmax is not None and np.isfinite(self.vmax[i]):
                ax.axhline(self.vmax[i], color=line.get_color(), lw=0.6, ls=":")
                ax.axhline(-self.vmax[i], color=line.get_color(), lw=0.6, ls=":")
        ax.set_ylabel("q̇ [rad/s]")
        ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0.0)  # beside
        ax = axes[1]
        if self.position_error is not None and self.orientation_error is not None:
            ax.plot(self.t, self.position_error * 1e3, color="C0", label="position [mm]")
            ax.set_ylabel("path error [mm]")
            ax2 = ax.twinx()
            ax2.plot(self.t, np.degrees(self.orientation_error), color="C3", lw=1, label="orientation [°]")
            ax2.set_ylabel("[°]", color="C3")
            ax.legend(loc="upper left", fontsize=7)
            ax2.legend(loc="upper right", fontsize=7)
        if rows == 3:
            ax = axes[2]
            ax.semilogy(self.t, self.sigma_min, color="k")
            ax.set_ylabel("σ_min(J)")
        axes[-1].set_xlabel("t [s]")
        fig.suptitle(title or f"{self.chain_name} — {self.source}: "
                     f"{self.duration:.2f} s (nominal {self.nominal_duration:.2f} s)", fontsize=10)
        fig.tight_layout()
        if file is not None:
            fig.savefig(file, dpi=110)
        return fig


_EMPTY: Mapping[str, Any] = MappingProxyType({})


def _frozen(value: Any) -> Any:
    """``value`` made read-only, recursively: a mapping → a read-only mapping, a list → a tuple,
    an array → a read-only array (copied first when the caller can still write to it)."""
    if isinstance(value, Mapping):
        return MappingProxyType({k: _frozen(v) for k, v in value.items()})
    if isinstance(value, (list, tuple)) and type(value) in (list, tuple):
        return tuple(_frozen(v) for v in value)
    if isinstance(value, np.ndarray):
        return read_only(value, dtype=None)
    return value


def _thawed(value: Any) -> Any:
    """The inverse of `_frozen` for pickling: read-only mappings → dicts."""
    if isinstance(value, Mapping):
        return {k: _thawed(v) for k, v in value.items()}
    if type(value) is tuple:
        return tuple(_thawed(v) for v in value)
    return value


def _restore_execution(values: dict[str, Any]) -> Execution:
    return Execution(**values)
