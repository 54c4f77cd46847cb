"""The per-cycle glue between tasks, collision models and the priority cascade
(`TasksStage`): given q, dt, the previous q̇ and the limits, it builds each level's rows
and the collision dampers, solves the cascade, and says what held the motion back.

Levels are the tasks grouped by priority (0 first); within a level each task's rows are
weighted by its ``weight``. Every collision model adds its damper rows ``G q̇ ≤ h`` as hard
constraints of every level, beside the joint position, velocity and acceleration box.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from ..arrays import read_only, shared_zeros
from ..errors import InputError
from ..solvers.priority import CascadeResult, PriorityCascade
from ..tasks.base import FrameTask, Task

if TYPE_CHECKING:
    from ..model.chain import Chain
    from ..model.limits import Limits

__all__ = ["TasksStage", "TasksResult"]

_NONE: list = []  # (no collision pairs: never written)

@dataclass(frozen=True, kw_only=True)
class TasksResult:
    """What one `TasksStage.solve` gives (``Command.solve`` of a tasks cycle).

    Attributes:
        qd: joint velocities (n,) [rad/s or m/s].
        priorities: the priority of each level, highest first.
        residuals: (levels,) ‖W^{1/2}(A q̇ − b)‖ of each level after the solve.
        task_errors: the error norm of each task (in the order given) [m, rad or rad];
            NaN for a task without a target.
        flags: statuses that apply ("collision-avoidance", "joint-limit",
            "velocity-scaled", "acceleration-limited").
        reasons: one sentence per flag.
        limits_active: kinds of joint limit holding q̇.
        collision_distance: the smallest distance over the collision pairs near enough to be
            checked [m] (inf without collision models or when none is near).
        cascade: the cascade's full `ratectl.solvers.priority.CascadeResult`.
        damper_rows: the collision dampers G q̇ ≤ h of this step, ``(G, h)`` (k, n) and
            (k,), or None without collision models (read-only).
    """

    qd: np.ndarray
    priorities: tuple[int, ...]
    residuals: np.ndarray
    task_errors: np.ndarray
    flags: tuple[str, ...]
    reasons: tuple[str, ...]
    limits_active: tuple[str, ...]
    collision_distance: float
    cascade: CascadeResult
    damper_rows: tuple[np.ndarray, np.ndarray] | None = None

    def __post_init__(self) -> None:
        for name in ("qd", "residuals", "task_errors"):
            object.__setattr__(self, name, read_only(getattr(self, name)))
        if self.damper_rows is not None:
            object.__setattr__(self, "damper_rows", tuple(read_only(a) for a in self.damper_rows))

    # what the controller's report reads from a solver result
    @property
    def task_error(self) -> np.ndarray:
        return self.residuals

    def __getattr__(self, name: str) -> Any:
        # ``task_errors`` of `TasksStage.solve`'s result, made from the list of the cycle's
        # error norms, and the ``cascade`` of a one-level cycle clear of the box: made on
        # first access (most cycles never read them)
        d = self.__dict__
        if name == "task_errors" and "_errors" in d:
            a = d["task_errors"] = read_only(np.array(d["_errors"]))
            return a
        if name == "cascade" and "_cascade_of" in d:  # (a one-level cycle clear of the box)
            cascade, clear = d["_cascade_of"]
            r = d["cascade"] = cascade._clear_result(clear)
            return r
        raise AttributeError(f"{type(self).__name__!r} object has no attribute {name!r}")


class TasksStage:
    """Tasks and collision models solved with strict priorities under the limits.

    Args:
        chain: the arm.
        tasks: `ratectl.tasks.Task` objects (any priorities; a level is all the tasks of
            one priority).
        collision: collision models (`ratectl.collision.SelfCollision`, `Obstacles`).
        cascade: the `PriorityCascade` (default: ``PriorityCascade()``, daqp when installed).

    One stage per controller; not thread-safe (the cascade and the tasks keep state).
    """

    def __init__(self, chain: Chain, tasks: Sequence[Task] = (), collision: Sequence[Any] = (), *,
                 cascade: PriorityCascade | None = None) -> None:
        tasks = list(tasks)
        for t in tasks:
            if not isinstance(t, Task):
                raise InputError(f"tasks must be ratectl.tasks objects (Pose, Position, Orientation, "
                                 f"Posture, ...), got {t!r}", argument="tasks", value=t)
            link = getattr(t, "link", None)
            if link is not None:
                chain.link_placement(link)  # an unknown link fails now, naming the links
        collision = list(collision)
        for c in collision:
            if not callable(getattr(c, "rows", None)):
                raise InputError(f"collision must be ratectl.collision models, got {c!r}",
                                 argument="collision", value=c)
        if not tasks:
            raise InputError("tasks= needs at least one task (e.g. rc.tasks.Pose(priority=0))",
                             argument="tasks", value=tasks)
        self.chain = chain
        self.tasks = tasks
        self.collision = collision
        self.cascade = cascade if cascade is not None else PriorityCascade()
        self._key: list | None = None  # (priority, weight, rows) of each task with a target
        # the `Task._layout_epoch` of that key: asked again only when the epoch moves, when
        # every task is one of the package's (`Task._static_layout`), else every cycle
        self._static = all(t._static_layout for t in tasks)
        self._epoch = -1
        # per task with a target: (index, task, its slices of A, b and the errors, √weight)
        self._fills: list[tuple[int, Task, np.ndarray, np.ndarray, np.ndarray, float]] = []
        self._levels: list[tuple[np.ndarray, np.ndarray, np.ndarray | None]] = []
        self._priorities: tuple[int, ...] = ()
        self._tool_e: np.ndarray | None = None
        self._stacked: tuple[np.ndarray, np.ndarray, tuple[int, ...]] | None = None
        self._framed: tuple[list[FrameTask], tuple[str | None, ...], list[int]] | None = None
        self._no_joint = shared_zeros(chain.dof, dtype=bool)  # (the cascade's "no joint on a face")
        self._period: tuple[float, np.ndarray] | None = None  # (dt, `period`)

    def _layout(self, q: np.ndarray, key: list) -> None:
        """Each level's arrays (the weighted rows √w·A (m, n) and √w·b (m,), the errors (m,))
        and each task's slice of them; rebuilt when a task gains or loses its target or
        changes priority, weight or number of rows."""
        chain = self.chain
        n = chain.dof
        by_priority: dict[int, list[tuple[int, Task, int]]] = {}
        for k, t in enumerate(self.tasks):
            if key[k] is not None:
                by_priority.setdefault(t.priority, []).append((k, t, key[k][2]))
        if not by_priority:
            raise InputError("no task has a target: call set_target on at least one task",
                             argument="tasks", value=self.tasks)
        self._priorities = tuple(sorted(by_priority))
        self._fills, self._levels, self._tool_e = [], [], None
        # every level's rows in one array (its consecutive blocks): the cascade's residuals
        # in one product
        total = sum(size for items in by_priority.values() for _, _, size in items)
        A_all, b_all, e_all = np.zeros((total, n)), np.zeros(total), np.zeros(total)
        ends: list[int] = []
        start = 0
        for p in self._priorities:
            items = by_priority[p]
            m = sum(size for _, _, size in items)
            A, b, e = A_all[start:start + m], b_all[start:start + m], e_all[start:start + m]
            start += m
            ends.append(start)
            i = 0
            for k, t, size in items:
                sl = slice(i, i + size)
                self._fills.append((k, t, A[sl], b[sl], e[sl], math.sqrt(t.weight)))
                if (self._tool_e is None and type(t).__name__ == "Pose"
                        and getattr(t, "link", None) is None):
                    self._tool_e = e[sl]
                i += size
            self._levels.append((A, b, None))  # the rows are written weighted (× √weight)
        self._stacked = (A_all, b_all, tuple(ends)) if len(ends) > 1 else None
        # frame tasks on two links or more: their frames in one pass of the chain
        framed = [t for _, t, *_ in self._fills
                  if isinstance(t, FrameTask) and type(t).frame is FrameTask.frame]
        for t in self.tasks:  # (no frame left over from a cycle that did not finish)
            if isinstance(t, FrameTask):
                t._frame_now = None
        links = tuple(dict.fromkeys(t.link for t in framed))
        self._framed = (framed, links, [links.index(t.link) for t in framed]) if len(links) > 1 else None
        self._key = key

    def period(self, dt: float) -> np.ndarray:
        """``dt`` [s] as a read-only (n,) array, kept while the period stays the same: numpy
        arithmetic of a joint vector with it gives the numbers of that with the float, at a
        third of the cost of the float's conversion every cycle."""
        p = self._period
        if p is None or p[0] != dt:
            a = np.full(self.chain.dof, dt)
            a.setflags(write=False)
            p = self._period = (dt, a)
        return p[1]

    def tool_error(self) -> np.ndarray | None:
        """The tool `Pose` task's error [p_d − p; log(R_d Rᵀ)] (6,) of the last solve (a
        copy), or None without one."""
        return None if self._tool_e is None else self._tool_e.copy()

    def solve(self, q: np.ndarray, *, dt: float, qd_prev: np.ndarray | None,
              limits: Limits | Chain | None) -> TasksResult:
        """q̇ for this cycle (see the module docstring). ``q`` finite (n,) float64 and ``dt``
        > 0, as the controller's gate passes them."""
        chain = self.chain
        epoch = Task._layout_epoch
        if epoch != self._epoch:  # (a task may have changed its place in the levels)
            key = [t._layout_key(chain, q) for t in self.tasks]
            if key != self._key:
                self._layout(q, key)
            if self._static:
                self._epoch = epoch
        errs = [math.nan] * len(self.tasks)
        framed = self._framed
        if framed is not None:
            frames = chain.fk_jacobian_links(q, framed[1])
            for ft, i in zip(framed[0], framed[2], strict=True):
                ft._frame_now = frames[i]
        for k, t, A_t, b_t, e_t, sw in self._fills:
            errs[k] = t._fill(chain, q, A_t, b_t, e_t, sw)
        levels = self._levels
        damper = None
        rows: tuple[np.ndarray, np.ndarray] | None = None
        if self.collision:
            G, h, pairs, dist, closest = self._dampers(q)
            damper = (read_only(G), read_only(h))
            if h.size:
                rows = (G, h)
        else:
            pairs, dist, closest = _NONE, _NONE, math.inf
        cascade = self.cascade
        n = chain.dof
        if rows is None and len(levels) == 1 and limits is not None and n:
            # one level clear of the box, the common cycle (`solve_validated`'s first try): its
            # CascadeResult made when read
            clear = cascade._one_level_clear(levels[0], n, limits, q, qd_prev, dt)
            if clear is not None:
                return _owned_result(TasksResult, {
                    "qd": clear[0], "priorities": self._priorities, "residuals": clear[1], "_errors": errs,
                    "flags": (), "reasons": (), "limits_active": (), "collision_distance": math.inf,
                    "_cascade_of": (cascade, clear), "damper_rows": None})
        res = cascade._solve_boxed(levels, n, limits, q, qd_prev, dt, rows, self._stacked)
        active_box = res.box_active
        if rows is None and (limits is None or active_box is self._no_joint
                             or True not in active_box.tolist()):
            flags: tuple[str, ...] = ()  # (the common cycle: nothing held the motion back)
            reasons: tuple[str, ...] = ()
            active: tuple[str, ...] = ()
        else:
            flags, reasons, active = self._held_back(res, rows, pairs, dist, q=q, qd_prev=qd_prev, dt=dt,
                                                     limits=limits)
        return _owned_result(TasksResult, {
            "qd": res.qd, "priorities": self._priorities, "residuals": res.residuals, "_errors": errs,
            "flags": flags, "reasons": reasons, "limits_active": active,
            "collision_distance": float(closest), "cascade": res, "damper_rows": damper})

    def _dampers(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray, list[tuple[str, str]], list[float],
                                               float]:
        """The collision models' damper rows at ``q``: ``(G (k, n), h (k,), the pair of each
        row, its distance [m], the smallest distance checked [m])``."""
        parts = [c.rows(q) for c in self.collision]
        if len(parts) == 1:
            G, h = parts[0].G, parts[0].h
        else:
            G = np.vstack([p.G for p in parts])
            h = np.concatenate([p.h for p in parts])
        pairs: list[tuple[str, str]] = []
        dist: list[float] = []
        closest = math.inf
        for p in parts:
            pairs += p.pairs
            dist += p.distance.tolist()
            closest = min(closest, p.closest)
        return G, h, pairs, dist, closest

    def _held_back(self, res: CascadeResult, rows: tuple[np.ndarray, np.ndarray] | None,
                   pairs: list[tuple[str, str]], dist: list[float], *, q: np.ndarray,
                   qd_prev: np.ndarray | None, dt: float, limits: Limits | Chain | None,
                   ) -> tuple[tuple[str, ...], tuple[str, ...], tuple[str, ...]]:
        """What held the motion back in the solve ``res``: ``(flags, reasons, kinds of joint
        limit active)`` — active collision dampers that make a level do worse than the box
        alone would, relaxed dampers, joints on a face of the box."""
        levels = self._levels
        flags: list[str] = []
        reasons: list[str] = []
        if rows is not None and True in res.rows_active.tolist():
            # held back = the level does worse than with the box alone (one more cascade,
            # only in the cycles where a damper row is active)
            free = self.cascade.residuals_without_rows(levels, limits=limits, q=q, qd_prev=qd_prev, dt=dt)
            scale = 1.0 + float(np.abs(levels[0][1]).max())  # (the weighted b)
            blocked = [p for p, r, r0 in zip(self._priorities, res.residuals.tolist(), free.tolist(),
                                             strict=True)
                       if r > r0 + 1e-6 * scale]
            if blocked:
                act = np.flatnonzero(res.rows_active)
                worst = int(act[np.argmin(np.asarray(dist)[act])])
                flags.append("collision-avoidance")
                reasons.append(f"collision avoidance holds back priority level(s) {blocked}: "
                               f"{act.size} damper row(s) active, closest {pairs[worst][0]} – "
                               f"{pairs[worst][1]} at {dist[worst] * 1e3:.3g} mm")
        if rows is not None and max(res.relaxed.tolist(), default=0.0) > 0.0:
            flags.append("collision-avoidance")
            reasons.append(f"a collision damper could not be met within the joint limits this period "
                           f"(relaxed by up to {float(res.relaxed.max()):.3g} m/s)")
        active: tuple[str, ...] = ()
        if limits is not None and True in res.box_active.tolist():
            by_kind: dict[str, list[str]] = {}
            for j, kind in self.cascade.limit_kinds(res, qd_prev):
                by_kind.setdefault(kind, []).append(self.chain.joint_names[j])
            active = tuple(k for k in ("velocity", "position", "acceleration") if k in by_kind)
            for kind, flag in (("position", "joint-limit"), ("velocity", "velocity-scaled"),
                               ("acceleration", "acceleration-limited")):
                if kind in by_kind:
                    flags.append(flag)
                    reasons.append(f"joint(s) {by_kind[kind]} at their {kind} bound")
        return tuple(dict.fromkeys(flags)), tuple(reasons), active


def _owned_result(cls: type, fields: dict[str, Any]) -> Any:
    """A frozen result of ``cls`` from ``fields``, whose arrays are read-only already (the
    cascade's own, or frozen in place by the caller): no dataclass ``__init__``, no copies."""
    r: Any = object.__new__(cls)
    object.__setattr__(r, "__dict__", fields)
    return r
