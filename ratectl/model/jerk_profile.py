"""A jerk-limited trajectory kept as plain numbers: piecewise constant jerk per joint
(`PiecewiseJerk`), read once from a Ruckig trajectory.

Ruckig describes the trajectory of each degree of freedom as an optional braking
pre-trajectory (two phases) followed by seven phases of constant jerk j_k lasting t_k,
each entered with the state (p_k, v_k, a_k). Inside phase k, τ after its start:

    p = p_k + v_k τ + a_k τ²/2 + j_k τ³/6,   v = v_k + a_k τ + j_k τ²/2,   a = a_k + j_k τ.

Keeping only these numbers lets a time law or a joint move outlive every Ruckig object:
nothing of the binding is referenced after construction, so nothing is left for
nanobind to report as leaked when the interpreter exits with such an object alive (a
path at module level, a result held by a test).
"""

from __future__ import annotations

from typing import Any

import numpy as np

__all__ = ["PiecewiseJerk"]


class PiecewiseJerk:
    """The phases of a Ruckig trajectory (see the module docstring), evaluated exactly.

    Attributes:
        duration: [s], the trajectory's.
        dof: number of degrees of freedom.
    """

    __slots__ = ("duration", "dof", "_phases", "_end")

    def __init__(self, trajectory: Any) -> None:
        self.duration = float(trajectory.duration)
        profiles = trajectory.profiles[0]
        self.dof = len(profiles)
        self._phases: list[list[tuple[float, float, float, float, float, float]]] = []
        self._end: list[tuple[float, float, float]] = []
        for prof in profiles:
            phases = []
            t0 = 0.0
            brake = prof.brake
            if float(brake.duration) > 0.0:
                for k in range(2):
                    dur = float(brake.t[k])
                    phases.append((t0, dur, float(brake.j[k]), float(brake.p[k]), float(brake.v[k]),
                                   float(brake.a[k])))
                    t0 += dur
            for k in range(7):
                dur = float(prof.t[k])
                phases.append((t0, dur, float(prof.j[k]), float(prof.p[k]), float(prof.v[k]),
                               float(prof.a[k])))
                t0 += dur
            self._phases.append(phases)
            self._end.append((float(prof.p[7]), float(prof.v[7]), float(prof.a[7])))

    def at(self, t: float) -> tuple[list[float], list[float], list[float]]:
        """``(p, v, a)`` per degree of freedom at time ``t`` [s], as lists (t beyond the last
        phase: the final state)."""
        ps, vs, as_ = [], [], []
        for phases, end in zip(self._phases, self._end, strict=True):
            for start, dur, j, p, v, a in reversed(phases):
                if t >= start and dur > 0.0:
                    if t - start > dur:
                        p, v, a = end
                        break
                    tau = t - start
                    p, v, a = (p + tau * (v + tau * (0.5 * a + tau * j / 6.0)), v + tau * (a + 0.5 * tau * j),
                               a + tau * j)
                    break
            else:
                p, v, a = phases[0][3:6] if phases else end
            ps.append(p)
            vs.append(v)
            as_.append(a)
        return ps, vs, as_

    def at_array(self, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """`at` as three (dof,) arrays."""
        p, v, a = self.at(t)
        return np.array(p), np.array(v), np.array(a)
