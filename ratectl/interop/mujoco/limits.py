"""mink limits (collision avoidance in particular) as velocity-level rows ``G q̇ ≤ h`` for
ratectl's QP.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import mujoco
import numpy as np
from numpy.typing import ArrayLike

from ...errors import InputError, SolverError
from .kinematics import MinkKinematics

if TYPE_CHECKING:
    import mink

    from ...model.chain import Chain
    from ...model.limits import Limits
    from ...solvers.base import SolveResult
    from ...solvers.qp import QP

__all__ = ['mink_inequalities', 'MinkLimitedSolver', 'geom_distance']


# ---------------------------------------------------------------------- mink limits
def mink_inequalities(limits: Sequence[Any], configuration: mink.Configuration, *, dt: float,
                      dofs: ArrayLike | None = None, keep_inactive: bool = False) -> tuple[np.ndarray,
                      np.ndarray]:
    """Velocity-level rows ``G q̇ ≤ h`` [rad/s or m/s on the left] from mink limits.

    mink's ``compute_qp_inequalities(configuration, dt)`` returns rows
    ``G Δq ≤ h`` on the *displacement* ``Δq = q̇·dt`` of one step. For
    ``ConfigurationLimit`` and ``VelocityLimit`` ``h`` is a displacement (gain ·
    distance to the joint limit [rad], ``vmax·dt``), so the velocity rows are
    ``G q̇ ≤ h/dt``.

    ``CollisionAvoidanceLimit`` is different: its bound ``gain·(d − d_min)/dt +
    relaxation`` is velocity-scaled although its row ``G = −n̂ᵀ(J₂ − J₁)`` multiplies a
    displacement, so read literally it lets one step close ``gain·(d − d_min)/dt``
    metres — 1/dt times more than intended (100× at 100 Hz). ratectl evaluates it
    with ``dt = 1`` so that ``h = gain·(d − d_min) + relaxation`` is the distance [m]
    the step may close, and divides by the real ``dt``:

        −ḋ = −n̂ᵀ(J₂ − J₁) q̇ ≤ gain·(d − d_min)/dt   [m/s]

    which keeps ``d_{k+1} − d_min ≥ (1 − gain)(d_k − d_min)`` to first order, so
    the distance never falls below ``d_min``. Rows whose bound is ``+inf`` (pairs
    farther apart than the detection distance) are dropped unless ``keep_inactive``
    (then they stay as zero rows with ``h = +inf``, so the number of rows is constant
    and a warm QP keeps its structure).

    Args:
        limits: mink ``Limit`` objects.
        configuration: the ``mink.Configuration``, already updated to the current q.
        dt: control period [s].
        dofs: dof indices of the chain joints in the model (columns kept, in chain
            order); default all dofs.

    Returns:
        ``(G, h)`` with ``G`` (m, n) and ``h`` (m,).
    """
    import mink

    if not (dt > 0 and math.isfinite(dt)):
        raise InputError(f"dt must be a positive time step [s], got {dt!r}", argument="dt", value=dt)
    nv = configuration.model.nv
    cols = np.arange(nv) if dofs is None else np.asarray(dofs, dtype=int)
    Gs, hs = [], []
    for lim in limits:
        if isinstance(lim, mink.CollisionAvoidanceLimit):
            c = lim.compute_qp_inequalities(configuration, 1.0)
        else:
            c = lim.compute_qp_inequalities(configuration, dt)
        if c.G is None or c.h is None:
            continue
        G = np.atleast_2d(np.asarray(c.G, dtype=float))
        h = np.asarray(c.h, dtype=float).ravel()
        keep = np.ones(h.shape, dtype=bool) if keep_inactive else np.isfinite(h)
        if not np.any(keep):
            continue
        Gs.append(G[keep][:, cols])
        hs.append(h[keep] / dt)
    if not Gs:
        return np.zeros((0, cols.size)), np.zeros(0)
    return np.vstack(Gs), np.concatenate(hs)


def geom_distance(model: mujoco.MjModel, data: mujoco.MjData, pairs: Sequence[tuple[str, str]], *,
                  distmax: float = 1.0) -> float:
    """Smallest signed distance [m] over geom pairs (names or ids) at ``data``'s state
    (``mj_geomDistance``; capped at ``distmax``)."""
    best = distmax
    geom = mujoco.mjtObj.mjOBJ_GEOM
    for g1, g2 in pairs:
        i1 = g1 if isinstance(g1, int | np.integer) else mujoco.mj_name2id(model, geom, g1)
        i2 = g2 if isinstance(g2, int | np.integer) else mujoco.mj_name2id(model, geom, g2)
        if i1 < 0 or i2 < 0:
            raise InputError(f"unknown geom in pair {(g1, g2)!r}", argument="pairs", value=(g1, g2))
        best = min(best, float(mujoco.mj_geomDistance(model, data, int(i1), int(i2), distmax, None)))
    return best


class MinkLimitedSolver:
    """Wrap a ratectl QP so that every solve also obeys mink limits.

    On ``solve(J, xi, *, q, dt, ...)`` the kinematics' mink configuration is updated to
    ``q``, the limits are turned into velocity rows by `mink_inequalities` and
    passed to the wrapped solver as ``extra_inequalities=(G, h)`` (``G q̇ ≤ h``).

    Args:
        kinematics: the `MinkKinematics` whose configuration the limits read.
        limits: mink ``Limit`` objects (e.g. ``mink.CollisionAvoidanceLimit``).
        solver: a solver accepting ``extra_inequalities`` (default ``ratectl.solvers.QP()``).
        drop_acceleration_on_conflict: when the QP is infeasible (the rows and the
            acceleration bounds |q̇ − q̇_prev| ≤ amax·dt conflict), solve again without the
            acceleration bounds — the distance comes first — and say so in
            ``result.info["acceleration_bounds_dropped"]``; False re-raises the
            `SolverError`.

    Choosing the gain: the rows let the distance close at most at ``gain·(d − d_min)/dt``
    [m/s], an exponential approach at rate ``gain/dt``; braking from a closing speed v
    then needs a Cartesian deceleration of about ``v·gain/dt``. Keep ``gain ≤ a·dt/v`` for
    the arm's deceleration a (e.g. gain 0.1 at 100 Hz for 0.25 m/s and 2.5 m/s²),
    otherwise the acceleration bounds cannot be met near obstacles.
    """

    method = "qp+mink"
    enforces_limits = True  # the wrapped QP's bounds, and the mink rows on top
    adds_rows = True

    def __init__(self, kinematics: MinkKinematics, limits: Sequence[Any], *, solver: QP | None = None,
                 drop_acceleration_on_conflict: bool = True) -> None:
        if not isinstance(kinematics, MinkKinematics):
            raise InputError("kinematics must be a ratectl.mujoco.MinkKinematics",
                             argument="kinematics", value=kinematics)
        if solver is None:
            from ... import solvers

            solver = solvers.QP()
        self.kinematics = kinematics
        self.limits = tuple(limits)
        self.solver = solver
        self.drop_acceleration_on_conflict = bool(drop_acceleration_on_conflict)
        self.last_rows = (np.zeros((0, kinematics.chain.dof)), np.zeros(0))

    def __getattr__(self, name):
        if name.startswith("__"):
            raise AttributeError(name)
        return getattr(self.__dict__["solver"], name)

    def solve(self, J: np.ndarray, xi: np.ndarray, *, limits: Limits | Chain | None = None,
              q: ArrayLike | None = None, qd_prev: ArrayLike | None = None, dt: float | None = None,
              **options: Any) -> SolveResult:
        if q is None or dt is None:
            raise InputError("MinkLimitedSolver needs q and dt (the mink limits depend on the "
                             "configuration and the step)", argument="q", value=q)
        self.kinematics.update(q)
        G, h = mink_inequalities(self.limits, self.kinematics.configuration, dt=dt,
                                 dofs=self.kinematics.dof_indices, keep_inactive=True)
        extra = options.pop("extra_inequalities", None)
        if extra is not None:
            G = np.vstack([G, extra[0]])
            h = np.concatenate([h, extra[1]])
        self.last_rows = (G, h)
        try:
            return self.solver.solve(J, xi, limits=limits, q=q, qd_prev=qd_prev, dt=dt,
                                     extra_inequalities=(G, h), **options)
        except SolverError as exc:
            if qd_prev is None or not self.drop_acceleration_on_conflict:
                raise
            # the rows and the acceleration bounds conflict (the arm approaches faster than
            # it can brake within amax·dt): keeping the distance comes first
            res = self.solver.solve(J, xi, limits=limits, q=q, qd_prev=None, dt=dt,
                                    extra_inequalities=(G, h), **options)
            return dataclasses.replace(res, info={**res.info, "acceleration_bounds_dropped": str(exc)})
