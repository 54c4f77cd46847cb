"""The robot model: a serial chain of revolute and prismatic joints.

A chain is built from a standard (:class:`DH`) or modified/Craig (:class:`MDH`)
Denavit–Hartenberg table, or directly from :class:`Joint` objects (what the URDF
and MJCF importers produce). Internally every joint i is the same thing:

    T_i = T_{i-1} · P_i · M_i(q_i) · Q_i

with constant transforms ``P_i`` (before the joint) and ``Q_i`` (after it), and the
joint motion ``M_i`` = Rz(q_i) for a revolute joint or Tz(q_i) for a prismatic one.
The joint moves about/along the z axis of ``T_{i-1} P_i``.

* Standard DH, ``A_i = Rz(θ_i) Tz(d_i) Tx(a_i) Rx(α_i)``:
  revolute ``P = I``, ``Q = Rz(θ_i) Tz(d_i) Tx(a_i) Rx(α_i)`` (θ_i is the offset);
  prismatic ``P = Rz(θ_i)``, ``Q = Tz(d_i) Tx(a_i) Rx(α_i)`` (d_i is the offset).
* Modified DH, ``A_i = Rx(α_{i-1}) Tx(a_{i-1}) Rz(θ_i) Tz(d_i)``:
  revolute ``P = Rx(α_{i-1}) Tx(a_{i-1})``, ``Q = Rz(θ_i) Tz(d_i)``;
  prismatic ``P = Rx(α_{i-1}) Tx(a_{i-1}) Rz(θ_i)``, ``Q = Tz(d_i)``.

The kinematics (``fk``, ``jacobian``, ...) live in :mod:`ratectl.kinematics`; the
chain exposes them as methods.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from . import kinematics
from .errors import InputError, ModelError

__all__ = ["DH", "MDH", "Joint", "Chain", "JOINT_KINDS"]

JOINT_KINDS = ("revolute", "prismatic")


def _rx(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[1, 0, 0, 0], [0, c, -s, 0], [0, s, c, 0], [0, 0, 0, 1.0]])


def _rz(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, -s, 0, 0], [s, c, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1.0]])


def _tx(a: float) -> np.ndarray:
    T = np.eye(4)
    T[0, 3] = a
    return T


def _tz(d: float) -> np.ndarray:
    T = np.eye(4)
    T[2, 3] = d
    return T


def _check_limits(qlim, vmax, amax, jmax, *, joint: int | None, where: str):
    """Validate and normalise limits; returns (lo, hi, vmax, amax, jmax) as floats."""
    if qlim is None:
        lo, hi = -math.inf, math.inf
    else:
        try:
            lo, hi = (float(x) for x in qlim)
        except (TypeError, ValueError):
            raise ModelError(f"{where}: qlim must be a pair (lower, upper), got {qlim!r}",
                             field="qlim", joint=joint, value=qlim) from None
        if math.isnan(lo) or math.isnan(hi):
            raise ModelError(f"{where}: qlim contains NaN: {qlim!r}",
                             field="qlim", joint=joint, value=qlim)
        if not lo < hi:
            raise ModelError(
                f"{where}: qlim lower bound {lo} must be below upper bound {hi} "
                "(limits are (lower, upper))", field="qlim", joint=joint, value=qlim)
    out = []
    for name, v in (("vmax", vmax), ("amax", amax), ("jmax", jmax)):
        if v is None:
            out.append(math.inf)
            continue
        try:
            fv = float(v)
        except (TypeError, ValueError):
            raise ModelError(f"{where}: {name} must be a positive number, got {v!r}",
                             field=name, joint=joint, value=v) from None
        if not fv > 0.0:  # also catches NaN
            raise ModelError(f"{where}: {name} must be positive (a magnitude in SI units), "
                             f"got {v!r}", field=name, joint=joint, value=v)
        out.append(fv)
    return (lo, hi, *out)


def _check_transform(T, name: str) -> np.ndarray:
    if T is None:
        return np.eye(4)
    A = np.asarray(T, dtype=float)
    if A.shape != (4, 4):
        raise ModelError(f"{name} must be a 4x4 homogeneous transform, got shape {A.shape}",
                         field=name, value=T)
    if not np.all(np.isfinite(A)):
        raise ModelError(f"{name} contains NaN or infinite entries", field=name, value=T)
    R = A[:3, :3]
    if (np.max(np.abs(R @ R.T - np.eye(3))) > 1e-6 or abs(np.linalg.det(R) - 1.0) > 1e-6
            or np.max(np.abs(A[3] - [0, 0, 0, 1])) > 0):
        raise ModelError(f"{name} must be a rigid transform: orthonormal rotation with "
                         "det +1 and last row [0, 0, 0, 1]", field=name, value=T)
    return A.copy()


@dataclass(frozen=True, kw_only=True)
class DH:
    """One row of a standard Denavit–Hartenberg table: ``A = Rz(θ) Tz(d) Tx(a) Rx(α)``.

    Args:
        a: link length [m]. alpha: link twist [rad]. d: link offset [m].
        theta: joint angle offset [rad].
        joint: ``"revolute"`` (q adds to θ) or ``"prismatic"`` (q adds to d).
        qlim: (lower, upper) joint position limits [rad or m], optional.
        vmax, amax, jmax: velocity, acceleration and jerk limits (magnitudes) in
            SI units [rad/s, rad/s², rad/s³ or m/s, ...], optional.
        name: joint name, optional.
    """

    a: float = 0.0
    alpha: float = 0.0
    d: float = 0.0
    theta: float = 0.0
    joint: str = "revolute"
    qlim: tuple[float, float] | None = None
    vmax: float | None = None
    amax: float | None = None
    jmax: float | None = None
    name: str | None = None

    convention = "standard"

    def __post_init__(self) -> None:
        for f in ("a", "alpha", "d", "theta"):
            v = getattr(self, f)
            try:
                fv = float(v)
            except (TypeError, ValueError):
                raise ModelError(f"{type(self).__name__}.{f} must be a number, got {v!r}",
                                 field=f, value=v) from None
            if not math.isfinite(fv):
                raise ModelError(f"{type(self).__name__}.{f} must be finite, got {v!r}",
                                 field=f, value=v)
            object.__setattr__(self, f, fv)
        if self.joint not in JOINT_KINDS:
            raise ModelError(f"joint must be one of {JOINT_KINDS}, got {self.joint!r}",
                             field="joint", value=self.joint)
        _check_limits(self.qlim, self.vmax, self.amax, self.jmax, joint=None,
                      where=type(self).__name__)

    def to_joint(self, index: int = 0) -> Joint:
        """The general :class:`Joint` for this row."""
        lo, hi, vmax, amax, jmax = _check_limits(self.qlim, self.vmax, self.amax, self.jmax,
                                                 joint=index, where=f"joint {index}")
        if self.joint == "revolute":
            pre = np.eye(4)
            post = _rz(self.theta) @ _tz(self.d) @ _tx(self.a) @ _rx(self.alpha)
        else:
            pre = _rz(self.theta)
            post = _tz(self.d) @ _tx(self.a) @ _rx(self.alpha)
        return Joint(kind=self.joint, pre=pre, post=post,
                     name=self.name or f"joint{index + 1}",
                     qlim=(lo, hi), vmax=vmax, amax=amax, jmax=jmax)


@dataclass(frozen=True, kw_only=True)
class MDH(DH):
    """One row of a modified (Craig) DH table: ``A_i = Rx(α_{i-1}) Tx(a_{i-1}) Rz(θ_i) Tz(d_i)``.

    ``a`` and ``alpha`` are the *previous* link's length and twist (a_{i-1}, α_{i-1}),
    as in Craig's tables and Franka's documentation. Other fields as in :class:`DH`.
    """

    convention = "modified"

    def to_joint(self, index: int = 0) -> Joint:
        lo, hi, vmax, amax, jmax = _check_limits(self.qlim, self.vmax, self.amax, self.jmax,
                                                 joint=index, where=f"joint {index}")
        if self.joint == "revolute":
            pre = _rx(self.alpha) @ _tx(self.a)
            post = _rz(self.theta) @ _tz(self.d)
        else:
            pre = _rx(self.alpha) @ _tx(self.a) @ _rz(self.theta)
            post = _tz(self.d)
        return Joint(kind=self.joint, pre=pre, post=post,
                     name=self.name or f"joint{index + 1}",
                     qlim=(lo, hi), vmax=vmax, amax=amax, jmax=jmax)


@dataclass(frozen=True, kw_only=True, eq=False)
class Joint:
    """A joint in general form: ``T_i = T_{i-1} · pre · M(q) · post``.

    ``M(q)`` is Rz(q) for ``kind="revolute"`` and Tz(q) for ``kind="prismatic"``.
    Limits are floats; an absent limit is ±inf.
    """

    kind: str
    pre: np.ndarray = field(default_factory=lambda: np.eye(4))
    post: np.ndarray = field(default_factory=lambda: np.eye(4))
    name: str = "joint"
    qlim: tuple[float, float] = (-math.inf, math.inf)
    vmax: float = math.inf
    amax: float = math.inf
    jmax: float = math.inf

    def __post_init__(self) -> None:
        if self.kind not in JOINT_KINDS:
            raise ModelError(f"joint kind must be one of {JOINT_KINDS}, got {self.kind!r}",
                             field="kind", value=self.kind)
        object.__setattr__(self, "pre", _check_transform(self.pre, f"joint {self.name!r} pre"))
        object.__setattr__(self, "post", _check_transform(self.post,
                                                          f"joint {self.name!r} post"))
        lo, hi, vmax, amax, jmax = _check_limits(self.qlim, self.vmax, self.amax, self.jmax,
                                                 joint=None, where=f"joint {self.name!r}")
        object.__setattr__(self, "qlim", (lo, hi))
        object.__setattr__(self, "vmax", vmax)
        object.__setattr__(self, "amax", amax)
        object.__setattr__(self, "jmax", jmax)
        self.pre.setflags(write=False)
        self.post.setflags(write=False)


class Chain:
    """A serial robot arm: joints, base and tool transforms, limits and names.

    Build one with :meth:`from_dh`, :meth:`from_mdh`, the importers, or from
    :class:`Joint` objects. A chain is immutable; :meth:`with_tool` and
    :meth:`with_base` return new chains.

    Kinematics methods (all broadcast over leading dimensions of ``q``):
    :meth:`fk`, :meth:`frames`, :meth:`jacobian`, :meth:`fk_jacobian`,
    :meth:`jacobian_dot`, :meth:`joint_axes`, :meth:`joint_torques`.
    """

    def __init__(self, joints, *, base=None, tool=None, name: str = "chain",
                 table: tuple | None = None, characteristic_length: float | None = None):
        joints = tuple(joints)
        if not joints:
            raise ModelError("a chain needs at least one joint", field="joints")
        for k, j in enumerate(joints):
            if not isinstance(j, Joint):
                raise ModelError(f"joint {k} must be a ratectl.Joint, got {type(j).__name__}",
                                 joint=k, value=j)
        self._joints = joints
        self._base = _check_transform(base, "base")
        self._tool = _check_transform(tool, "tool")
        self._base.setflags(write=False)
        self._tool.setflags(write=False)
        self._name = str(name)
        self._table = table
        self._n = len(joints)
        self._qshape = (self._n,)
        self._lower = np.array([j.qlim[0] for j in joints])
        self._upper = np.array([j.qlim[1] for j in joints])
        self._vmax = np.array([j.vmax for j in joints])
        self._amax = np.array([j.amax for j in joints])
        self._jmax = np.array([j.jmax for j in joints])
        for a in (self._lower, self._upper, self._vmax, self._amax, self._jmax):
            a.setflags(write=False)
        self._prismatic = np.array([j.kind == "prismatic" for j in joints])
        if characteristic_length is None:
            characteristic_length = self.reach()
        if not (characteristic_length > 0 and math.isfinite(characteristic_length)):
            raise ModelError("characteristic_length must be a positive length [m], "
                             f"got {characteristic_length!r}", field="characteristic_length")
        self._length = float(characteristic_length)
        self._kernels: dict = {}

    # ------------------------------------------------------------------ constructors
    @classmethod
    def from_dh(cls, rows, *, base=None, tool=None, name: str = "chain",
                characteristic_length: float | None = None) -> Chain:
        """Chain from a standard DH table (a list of :class:`DH` rows)."""
        rows = cls._check_rows(rows, DH)
        joints = [r.to_joint(k) for k, r in enumerate(rows)]
        return cls(joints, base=base, tool=tool, name=name, table=tuple(rows),
                   characteristic_length=characteristic_length)

    @classmethod
    def from_mdh(cls, rows, *, base=None, tool=None, name: str = "chain",
                 characteristic_length: float | None = None) -> Chain:
        """Chain from a modified (Craig) DH table (a list of :class:`MDH` rows)."""
        rows = cls._check_rows(rows, MDH)
        joints = [r.to_joint(k) for k, r in enumerate(rows)]
        return cls(joints, base=base, tool=tool, name=name, table=tuple(rows),
                   characteristic_length=characteristic_length)

    @staticmethod
    def _check_rows(rows, kind):
        rows = list(rows)
        if not rows:
            raise ModelError("a DH table needs at least one row", field="rows")
        for k, r in enumerate(rows):
            if type(r) is not kind:
                other = "from_mdh" if kind is DH else "from_dh"
                raise ModelError(
                    f"row {k} is a {type(r).__name__}, expected {kind.__name__}"
                    f"{f' (use Chain.{other} for {type(r).__name__} rows)' if isinstance(r, DH) else ''}",
                    joint=k, value=r)
        return rows

    @classmethod
    def from_urdf(cls, path, *, tip: str | None = None, base_link: str | None = None,
                  name: str | None = None) -> Chain:
        """Chain from a URDF file (see :mod:`ratectl.importers`)."""
        from .importers import chain_from_urdf

        return chain_from_urdf(path, tip=tip, base_link=base_link, name=name)

    @classmethod
    def from_mjcf(cls, path_or_model, *, tip: str | None = None,
                  name: str | None = None) -> Chain:
        """Chain from an MJCF file or a compiled ``mujoco.MjModel`` (see :mod:`ratectl.importers`)."""
        from .importers import chain_from_mjcf

        return chain_from_mjcf(path_or_model, tip=tip, name=name)

    def with_tool(self, tool) -> Chain:
        """The same chain with another tool transform (flange → tool, 4×4)."""
        return Chain(self._joints, base=self._base, tool=tool, name=self._name,
                     table=self._table, characteristic_length=self._length)

    def with_base(self, base) -> Chain:
        """The same chain with another base transform (world → frame 0, 4×4)."""
        return Chain(self._joints, base=base, tool=self._tool, name=self._name,
                     table=self._table, characteristic_length=self._length)

    # ------------------------------------------------------------------ properties
    @property
    def dof(self) -> int:
        """Number of joints n."""
        return self._n

    @property
    def name(self) -> str:
        return self._name

    @property
    def joints(self) -> tuple[Joint, ...]:
        return self._joints

    @property
    def joint_names(self) -> tuple[str, ...]:
        return tuple(j.name for j in self._joints)

    @property
    def table(self) -> tuple | None:
        """The DH/MDH rows the chain was built from, if any."""
        return self._table

    @property
    def base(self) -> np.ndarray:
        """World → frame 0 transform (read-only 4×4)."""
        return self._base

    @property
    def tool(self) -> np.ndarray:
        """Frame n → tool transform (read-only 4×4)."""
        return self._tool

    @property
    def lower(self) -> np.ndarray:
        """Lower joint position limits [rad or m], −inf where absent."""
        return self._lower

    @property
    def upper(self) -> np.ndarray:
        """Upper joint position limits [rad or m], +inf where absent."""
        return self._upper

    @property
    def qlim(self) -> np.ndarray:
        """Joint position limits as a (n, 2) array of (lower, upper)."""
        return np.stack([self._lower, self._upper], axis=1)

    @property
    def vmax(self) -> np.ndarray:
        """Joint velocity limits [rad/s or m/s], inf where absent."""
        return self._vmax

    @property
    def amax(self) -> np.ndarray:
        """Joint acceleration limits [rad/s² or m/s²], inf where absent."""
        return self._amax

    @property
    def jmax(self) -> np.ndarray:
        """Joint jerk limits [rad/s³ or m/s³], inf where absent."""
        return self._jmax

    @property
    def prismatic(self) -> np.ndarray:
        """Boolean mask of prismatic joints."""
        return self._prismatic

    @property
    def characteristic_length(self) -> float:
        """Length L [m] that makes linear and angular rows comparable (default: reach)."""
        return self._length

    def reach(self) -> float:
        """Sum of the constant link translations [m] (an upper bound on the reach at q = 0
        for revolute arms; prismatic travel not included). At least 1e-3 m."""
        total = float(np.linalg.norm(self._tool[:3, 3]))
        for j in self._joints:
            total += float(np.linalg.norm(j.pre[:3, 3]) + np.linalg.norm(j.post[:3, 3]))
        return max(total, 1e-3)

    # ------------------------------------------------------------------ helpers
    def check_q(self, q, *, name: str = "q") -> np.ndarray:
        """Validate ``q`` (shape (..., n), finite) and return it as a float array."""
        try:
            a = np.asarray(q, dtype=float)
        except (TypeError, ValueError):
            raise InputError(f"{name} must be an array of {self._n} joint values, got {q!r}",
                             argument=name, value=q) from None
        if a.ndim == 0 or a.shape[-1] != self._n:
            raise InputError(
                f"{name} must have shape ({self._n},) or (..., {self._n}) — one value per joint "
                f"of {self._name!r} — got shape {a.shape}", argument=name, value=a)
        if not np.all(np.isfinite(a)):
            raise InputError(f"{name} must be finite; got NaN or inf at index "
                             f"{np.argwhere(~np.isfinite(a))[0].tolist()}", argument=name, value=a)
        return a

    def within_limits(self, q, *, tolerance: float = 0.0) -> np.ndarray:
        """True where every joint of q lies within [lower − tol, upper + tol]."""
        a = self.check_q(q)
        return np.all((a >= self._lower - tolerance) & (a <= self._upper + tolerance), axis=-1)

    def random_q(self, size=None, *, rng=None, margin: float = 0.0) -> np.ndarray:
        """Random configurations, uniform within the limits (±π, or ±1 m, where unlimited).

        Args:
            size: batch shape (None for a single (n,) configuration).
            rng: a ``numpy.random.Generator`` or seed.
            margin: keep this far inside the limits [rad or m].
        """
        rng = np.random.default_rng(rng)
        default = np.where(self._prismatic, 1.0, math.pi)
        lo = np.where(np.isfinite(self._lower), self._lower, -default) + margin
        hi = np.where(np.isfinite(self._upper), self._upper, default) - margin
        shape = (self._n,) if size is None else tuple(np.atleast_1d(size)) + (self._n,)
        return lo + (hi - lo) * rng.random(shape)

    def __repr__(self) -> str:
        kinds = "".join("RP"[int(p)] for p in self._prismatic)
        return f"Chain(name={self._name!r}, dof={self._n}, joints={kinds})"

    def describe(self) -> str:
        """A multi-line table of the model (joints, kinds, limits)."""
        lines = [f"{self._name}: {self._n} joints"]
        if self._table is not None:
            conv = self._table[0].convention
            lines.append(f"{conv} DH table (a [m], alpha [rad], d [m], theta [rad])")
            for k, r in enumerate(self._table):
                lines.append(f"  {k + 1}: {r.joint:9s} a={r.a:+.4f} alpha={r.alpha:+.4f} "
                             f"d={r.d:+.4f} theta={r.theta:+.4f}")
        lines.append("limits: name, qlim, vmax, amax, jmax")
        for j in self._joints:
            lines.append(f"  {j.name:12s} [{j.qlim[0]:+.4f}, {j.qlim[1]:+.4f}] "
                         f"{j.vmax:.4g} {j.amax:.4g} {j.jmax:.4g}")
        return "\n".join(lines)

    # ------------------------------------------------------------------ kinematics
    # The single-configuration fast paths are inlined here (no further Python calls
    # than the generated kernel and one numpy conversion); everything else is in
    # :mod:`ratectl.kinematics`.
    def fk(self, q) -> np.ndarray:
        """Base-to-tool pose ``T_world_tool`` (..., 4, 4) at q (..., n)."""
        if type(q) is np.ndarray and q.shape == self._qshape and q.dtype == _F64:
            v = q.tolist()
            s = sum(v)
            if s - s == 0.0:
                k = self._kernels.get(_FK) or kinematics.build_kernel(self, _FK)
                return np.array(k(*v), dtype=_F64).reshape(4, 4)
        return kinematics.fk(self, q)

    def jacobian(self, q, *, frame: str = "base", point=None) -> np.ndarray:
        """Geometric Jacobian (..., 6, n), rows [v; ω].

        Args:
            q: joint positions (..., n).
            frame: ``"base"`` (rows in world/base axes) or ``"tool"`` (tool axes).
            point: reference point for the linear rows, as coordinates in the tool
                frame [m] (a point fixed to the tool); default the tool origin.
        """
        if (type(q) is np.ndarray and q.shape == self._qshape and q.dtype == _F64
                and frame == "base" and point is None):
            v = q.tolist()
            s = sum(v)
            if s - s == 0.0:
                k = self._kernels.get(_JAC) or kinematics.build_kernel(self, _JAC)
                return np.array(k(*v), dtype=_F64).reshape(6, self._n)
        return kinematics.jacobian(self, q, frame=frame, point=point)

    def fk_jacobian(self, q, *, frame: str = "base", point=None):
        """``(fk(q), jacobian(q))`` computed together (cheaper than two calls)."""
        if (type(q) is np.ndarray and q.shape == self._qshape and q.dtype == _F64
                and frame == "base" and point is None):
            v = q.tolist()
            s = sum(v)
            if s - s == 0.0:
                k = self._kernels.get(_FKJAC) or kinematics.build_kernel(self, _FKJAC)
                a = np.array(k(*v), dtype=_F64)
                return a[:16].reshape(4, 4), a[16:].reshape(6, self._n)
        return kinematics.fk_jacobian(self, q, frame=frame, point=point)

    def frames(self, q) -> np.ndarray:
        """All DH frames ``T_0 … T_n`` in the world, (..., n+1, 4, 4) (T_0 is the base)."""
        return kinematics.frames(self, q)

    def joint_axes(self, q):
        """World axis (unit, ..., n, 3) and a point on it (..., n, 3) for every joint."""
        return kinematics.joint_axes(self, q)

    def jacobian_dot(self, q, qd, *, frame: str = "base", point=None) -> np.ndarray:
        """Time derivative J̇(q, q̇) (..., 6, n), so that the tool acceleration is J q̈ + J̇ q̇."""
        return kinematics.jacobian_dot(self, q, qd, frame=frame, point=point)

    def joint_torques(self, q, wrench, *, frame: str = "base", point=None) -> np.ndarray:
        """Static joint torques τ = Jᵀ F for a tool wrench F = [f; τ], in N and N·m."""
        return kinematics.joint_torques(self, q, wrench, frame=frame, point=point)


_F64 = np.dtype(np.float64)
_FK = ("fk", False)
_JAC = ("jac", False)
_FKJAC = ("fkjac", False)
