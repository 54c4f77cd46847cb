"""What every task has: a priority, a weight within its level, a gain, a target, and its rows
``A q̇ ≈ b`` at a configuration (`Task`, `TaskRows`); `FrameTask`, the base of the tasks on
a link's frame."""

from __future__ import annotations

import math
import struct
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike

from ..arrays import read_only
from ..checks import positive_number
from ..errors import InputError
from ..spatial import rigid_transform_defect, rotation_error_rows

if TYPE_CHECKING:
    from ..model.chain import Chain

__all__ = ["Task", "TaskRows", "FrameTask"]


@dataclass(frozen=True, kw_only=True)
class TaskRows:
    """A task's rows at one configuration: ``A q̇ ≈ b``.

    Attributes:
        A: (m, n) rows [task unit per rad/s].
        b: (m,) desired task velocity: feed-forward + gain · error.
        error: (m,) the task error (target − actual, in the task's units) [m, rad or rad].
    """

    A: np.ndarray
    b: np.ndarray
    error: np.ndarray

    def __post_init__(self) -> None:
        for name in ("A", "b", "error"):
            object.__setattr__(self, name, read_only(getattr(self, name)))


class Task:
    """A thing the controller is asked to do besides (or instead of) the tool pose.

    Args:
        priority: 0 is the highest; a level of lower priority (a larger number) never
            changes what a higher level achieves within the limits.
        weight: the task's weight within its level (its rows are scaled by √weight).
        gain: K [1/s] on the task error: ``b = feed-forward + K · error``.

    Subclasses implement `rows`; `set_target` sets what the task tracks.
    """

    #: rows per task (None: depends on the chain)
    size: int | None = None
    #: advanced whenever a task changes its place in a controller's level arrays: a priority
    #: or a weight set, a first target, a posture's new reference (`_layout_changed`)
    _layout_epoch = 0
    #: whether that place (`_layout_key`) changes only with `_layout_epoch`: the tasks of
    #: this package; a subclass defined elsewhere may count its rows anew any cycle
    _static_layout = True

    def __init_subclass__(cls, **kwargs: Any) -> None:
        super().__init_subclass__(**kwargs)
        if not cls.__module__.startswith("ratectl."):
            cls._static_layout = False

    def __init__(self, *, priority: int = 0, weight: float = 1.0, gain: float = 10.0) -> None:
        self.priority = priority
        self.weight = weight
        self.gain = positive_number("gain", gain, allow_zero=True, unit="[1/s]")

    @property
    def priority(self) -> int:
        """0 is the highest (an integer ≥ 0)."""
        return self._priority

    @priority.setter
    def priority(self, value: int) -> None:
        if isinstance(value, bool) or not isinstance(value, int | np.integer) or value < 0:
            raise InputError(f"priority must be an integer ≥ 0 (0 is the highest), got {value!r}",
                             argument="priority", value=value)
        self._priority = int(value)
        _layout_changed()

    @property
    def weight(self) -> float:
        """The task's weight within its level (> 0)."""
        return self._weight

    @weight.setter
    def weight(self, value: float) -> None:
        self._weight = positive_number("weight", value)
        _layout_changed()

    @property
    def has_target(self) -> bool:
        """True once the task has something to track."""
        return True

    def rows(self, chain: Chain, q: np.ndarray) -> TaskRows:
        """The task's rows ``A q̇ ≈ b`` at ``q`` (n,) of ``chain``."""
        raise NotImplementedError

    # The controller's per-cycle path: the rows written into its preallocated level arrays
    # (no `TaskRows` per task and cycle). The built-in tasks implement `_fill` and build
    # `rows` on it; a subclass that implements `rows` alone works through these defaults.
    def _row_count(self, chain: Chain, q: np.ndarray) -> int:
        """How many rows the task has on ``chain`` at ``q`` (asked every cycle: cheap for the
        built-in tasks, one `rows` call for a task that implements `rows` alone)."""
        if self.size is not None:
            return self.size
        return int(self.rows(chain, q).b.shape[0])

    def _layout_key(self, chain: Chain, q: np.ndarray) -> tuple[int, float, int] | None:
        """``(priority, weight, rows)``, or None without a target: what fixes the task's place
        in the controller's level arrays (asked every cycle)."""
        return (self.priority, self.weight, self._row_count(chain, q)) if self.has_target else None

    def _fill(self, chain: Chain, q: np.ndarray, A: np.ndarray, b: np.ndarray, e: np.ndarray,
              s: float) -> float:
        """Write the rows at ``q`` (finite, (n,) float64) scaled by ``s`` (√weight) into ``A``
        (m, n) and ``b`` (m,), and the error into ``e`` (m,), m = `_row_count`; returns ‖e‖."""
        r = self.rows(chain, q)
        if r.b.shape != b.shape or r.A.shape != A.shape or r.error.shape != e.shape:
            raise InputError(f"{self!r}: rows() gave {r.A.shape[0]} rows, {b.shape[0]} expected "
                             f"(a task's number of rows may not change between cycles)",
                             argument="tasks", value=self)
        if not (np.all(np.isfinite(r.A)) and np.all(np.isfinite(r.b))):
            raise InputError(f"{self!r}: rows() gave non-finite A or b", argument="tasks", value=self)
        np.multiply(r.A, s, out=A)
        np.multiply(r.b, s, out=b)
        e[...] = r.error
        return math.sqrt(float(e.dot(e)))

    def _filled_rows(self, chain: Chain, q: np.ndarray) -> TaskRows:
        """`rows` of a task that implements `_fill`: its rows at ``q`` written into fresh
        arrays (unscaled)."""
        q = chain.check_q(q)
        if q.shape != (chain.dof,):
            raise InputError(f"rows take one configuration ({chain.dof},), got shape {q.shape}",
                             argument="q", value=q)
        m = self._row_count(chain, q)
        A, b, e = np.empty((m, chain.dof)), np.empty(m), np.empty(m)
        self._fill(chain, q, A, b, e, 1.0)
        return TaskRows(A=A, b=b, error=e)

    def __repr__(self) -> str:
        return f"{type(self).__name__}(priority={self.priority}, weight={self.weight:g}, gain={self.gain:g})"


_STRUCTS: dict[int, Any] = {}


def _float_writers(*arrays: np.ndarray) -> tuple[tuple[Any, memoryview], ...] | None:
    """For each array (float64, C-contiguous, writeable), ``(pack_into, memory)``:
    ``pack_into(memory, 0, *values)`` writes ``a.size`` Python floats into the array in
    order (`struct`, native doubles) — cheaper, for a few numbers every cycle, than numpy's
    conversion of a sequence. None when an array is not such an array (the caller then
    assigns)."""
    out = []
    for a in arrays:
        if a.dtype != np.float64 or not a.flags.c_contiguous or not a.flags.writeable:
            return None
        st = _STRUCTS.get(a.size)
        if st is None:
            st = _STRUCTS[a.size] = struct.Struct(f"={a.size}d")
        out.append((st.pack_into, memoryview(a).cast("B")))  # type: ignore[arg-type]
    return tuple(out)


def _layout_changed() -> None:
    """A task changed its place in the level arrays (see `Task._layout_epoch`)."""
    Task._layout_epoch += 1


def check_pose(T: ArrayLike, name: str = "target") -> np.ndarray:
    """``T`` as a rigid 4×4 pose, else InputError."""
    try:
        a = np.array(T, dtype=float)
    except (TypeError, ValueError):
        raise InputError(f"{name} must be a 4x4 pose, got {T!r}"[:300], argument=name, value=T) from None
    if a.shape != (4, 4) or not np.all(np.isfinite(a)):
        raise InputError(f"{name} must be a finite 4x4 pose, got shape {a.shape}", argument=name, value=T)
    defect = rigid_transform_defect(a)
    if defect is not None:
        raise InputError(f"{name} {defect}", argument=name, value=T)
    return a


def check_vector(v: ArrayLike | None, size: int, name: str, unit: str) -> np.ndarray | None:
    """``v`` as a finite (size,) float array (None stays None), else InputError."""
    if v is None:
        return None
    try:
        if isinstance(v, str | bytes) or np.iscomplexobj(v):
            raise TypeError(name)
        a = np.array(v, dtype=float)
    except (TypeError, ValueError):
        raise InputError(f"{name} must be {size} real numbers {unit}, got {v!r}"[:300], argument=name,
                         value=v) from None
    if a.shape != (size,) or not np.all(np.isfinite(a)):
        raise InputError(f"{name} must be a finite ({size},) vector {unit}, got shape {a.shape}",
                         argument=name, value=v)
    return a


class FrameTask(Task):
    """A task on a link's frame (``link=None``: the tool): the shared target handling of
    `Pose`, `Position` and `Orientation`.

    The error is the one pose error of the package, `ratectl.spatial.pose_error`:
    ``e = [p_d − p ; log(R_d Rᵀ)]`` in base axes; the rows are the link's geometric
    Jacobian (base axes, linear rows at the link origin), restricted to the task's rows.
    """

    _rows: slice = slice(0, 6)

    def __init__(self, *, link: str | None = None, priority: int = 0, weight: float = 1.0,
                 gain: float = 10.0) -> None:
        super().__init__(priority=priority, weight=weight, gain=gain)
        if link is not None and not isinstance(link, str):
            raise InputError(f"link must be a link name (a string) or None for the tool, got {link!r}",
                             argument="link", value=link)
        self.link = link
        self._target: np.ndarray | None = None
        self._target_rows: list[list[float]] = []  # the target's rows as floats (set with it)
        self._twist = np.zeros(6)
        self._has_twist = False
        # (pose, Jacobian) of the frame at this cycle's q, set just before `_fill` by a caller
        # that computes several tasks' frames in one pass (the controller's tasks stage)
        self._frame_now: tuple[np.ndarray, np.ndarray] | None = None
        self._writers: tuple | None = None  # (A, b, e, their `_float_writers`) of the last `_fill`

    @property
    def has_target(self) -> bool:
        return self._target is not None

    @property
    def target(self) -> np.ndarray | None:
        """The target pose (4×4, a copy) or None."""
        return None if self._target is None else self._target.copy()

    def _set(self, T: np.ndarray, twist: np.ndarray | None) -> None:
        if self._target is None:  # (a first target: the task joins its level)
            _layout_changed()
        self._target = T
        self._target_rows = T.tolist()
        self._twist = np.zeros(6)
        if twist is not None:
            self._twist[self._rows] = twist
        self._has_twist = twist is not None

    def frame(self, chain: Chain, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(pose (4, 4), Jacobian (6, n)) of the task's frame at q."""
        return chain.fk_jacobian(q, link=self.link) if self.link is not None else chain.fk_jacobian(q)

    def rows(self, chain: Chain, q: np.ndarray) -> TaskRows:
        """``A = J[rows]``, ``b = ξ_ff[rows] + K · e[rows]`` with ``e`` the pose error."""
        return self._filled_rows(chain, q)

    def _fill(self, chain: Chain, q: np.ndarray, A: np.ndarray, b: np.ndarray, e: np.ndarray,
              s: float) -> float:
        if self._target is None:
            raise InputError(f"{self!r} has no target: call set_target first", argument="target",
                             value=None)
        pre = self._frame_now
        t = None
        if pre is not None:  # (computed with the other tasks' frames by the controller)
            T, J = pre
            self._frame_now = None
            a = T.tolist()
        elif self.link is None and type(self).frame is FrameTask.frame:
            # the tool: the kernel's numbers, no arrays (q is one finite configuration: `_fill`)
            t = chain._fkjac_kernel()(*q.tolist())
            a = (t[0:4], t[4:8], t[8:12])
        else:
            T, J = self.frame(chain, q)
            a = T.tolist()
        # the pose error [p_d − p; log(R_d Rᵀ)] on the rows of floats (its rotational part
        # `rotation_error_rows`, as in `pose_error_into`)
        d = self._target_rows
        ex, ey, ez = d[0][3] - a[0][3], d[1][3] - a[1][3], d[2][3] - a[2][3]
        r = self._rows
        g = self.gain * s
        if r.stop == 3:  # the position alone (no rotation error to compute)
            ev: tuple[float, ...] = (ex, ey, ez)
            bv: tuple[float, ...] = (ex * g, ey * g, ez * g)
            norm = math.sqrt(ex * ex + ey * ey + ez * ez)
        else:
            x, y, z, th = rotation_error_rows(d, a)
            if r.start == 0:  # the full pose
                ev = (ex, ey, ez, x, y, z)
                bv = (ex * g, ey * g, ez * g, x * g, y * g, z * g)
                ep = math.sqrt(ex * ex + ey * ey + ez * ez)
                norm = math.sqrt(ep * ep + th * th)
            else:  # the orientation alone
                ev = (x, y, z)
                bv = (x * g, y * g, z * g)
                norm = th
        w = self._writers
        if w is None or w[0] is not A or w[1] is not b or w[2] is not e:
            w = self._writers = (A, b, e, _float_writers(A, b, e))
        wr = w[3]
        if wr is not None:  # (the numbers straight into the arrays' memory)
            wr[1][0](wr[1][1], 0, *bv)
            wr[2][0](wr[2][1], 0, *ev)
        else:
            b[:] = bv
            e[:] = ev
        if t is not None and wr is not None:
            # the Jacobian's rows straight from the kernel's numbers into A's memory
            n = A.shape[1]
            wr[0][0](wr[0][1], 0, *t[16 + r.start * n:16 + r.stop * n])
            if s != 1.0:
                A *= s
        else:
            if t is not None:
                n = A.shape[1]
                J = np.array(t[16:]).reshape(6, n)
            Jr = J if r.stop - r.start == 6 else J[r]
            if s == 1.0:  # (a weight of 1: the rows as they are, a copy)
                A[...] = Jr
            else:
                np.multiply(Jr, s, out=A)
        if self._has_twist:
            b += s * self._twist[r]
        return norm

    def __repr__(self) -> str:
        link = "tool" if self.link is None else repr(self.link)
        return f"{type(self).__name__}(link={link}, priority={self.priority}, weight={self.weight:g})"
