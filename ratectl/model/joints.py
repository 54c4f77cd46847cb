"""Joints of a serial chain: DH and modified-DH table rows and the general `Joint`.

Every joint i is the same thing internally:

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
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..errors import ModelError
from ..spatial import rigid_transform_defect, rotx, rotz, transform, translation

__all__ = ["DH", "MDH", "Joint", "JOINT_KINDS", "MAX_LENGTH", "check_limits", "check_transform"]

JOINT_KINDS = ("revolute", "prismatic")


def _rx(a: float) -> np.ndarray:
    return transform(rotx(a))


def _rz(a: float) -> np.ndarray:
    return transform(rotz(a))


def _tx(a: float) -> np.ndarray:
    return translation(x=a)


def _tz(d: float) -> np.ndarray:
    return translation(z=d)


def check_limits(qlim: Any, vmax: Any, amax: Any, jmax: Any, *, joint: int | None, where: str):
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


def check_transform(T: Any, name: str) -> np.ndarray:
    """A read-write copy of the rigid transform ``T`` (identity for None), or a ModelError
    naming what is wrong (see `ratectl.spatial.rigid_transform_defect`)."""
    if T is None:
        return np.eye(4)
    defect = rigid_transform_defect(T)
    if defect is not None:
        raise ModelError(f"{name} {defect}", field=name, value=T)
    out = np.array(T, dtype=float)
    far = float(np.max(np.abs(out[:3, 3])))
    if not far <= MAX_LENGTH:
        raise ModelError(f"{name}: its translation ({far:.3g} m) exceeds the {MAX_LENGTH:.0e} m "
                         "ratectl accepts for a link (a unit mistake?); lengths are in metres",
                         field=name, value=T)
    return out


#: Largest constant translation [m] of a joint, base or tool transform (and DH a, d): far
#: beyond any robot, and small enough that sums over thousands of links stay finite.
MAX_LENGTH = 1e9


@dataclass(frozen=True, kw_only=True)
class DH:
    """One row of a standard Denavit–Hartenberg table: ``A = Rz(θ) Tz(d) Tx(a) Rx(α)``.

    Args:
        a: link length [m].
        alpha: link twist [rad].
        d: link offset [m].
        theta: joint angle offset [rad].
        joint: ``"revolute"`` (q adds to θ) or ``"prismatic"`` (q adds to d).
        qlim: (lower, upper) joint position limits [rad or m], optional.
        vmax: velocity limit (magnitude) [rad/s or m/s], optional.
        amax: acceleration limit (magnitude) [rad/s² or m/s²], optional.
        jmax: jerk limit (magnitude) [rad/s³ or m/s³], optional.
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
            if f in ("a", "d") and not abs(fv) <= MAX_LENGTH:
                raise ModelError(f"{type(self).__name__}.{f} = {fv:.3g} m exceeds the {MAX_LENGTH:.0e} m "
                                 "ratectl accepts for a link length or offset (a unit mistake?); "
                                 "lengths are in metres", field=f, value=v)
            object.__setattr__(self, f, fv)
        if self.joint not in JOINT_KINDS:
            raise ModelError(f"joint must be one of {JOINT_KINDS}, got {self.joint!r}",
                             field="joint", value=self.joint)
        check_limits(self.qlim, self.vmax, self.amax, self.jmax, joint=None,
                      where=type(self).__name__)

    def to_joint(self, index: int = 0) -> Joint:
        """The general `Joint` for this row."""
        lo, hi, vmax, amax, jmax = check_limits(self.qlim, self.vmax, self.amax, self.jmax,
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
    as in Craig's tables and Franka's documentation. Other fields as in `DH`.
    """

    convention = "modified"

    def to_joint(self, index: int = 0) -> Joint:
        lo, hi, vmax, amax, jmax = check_limits(self.qlim, self.vmax, self.amax, self.jmax,
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
        object.__setattr__(self, "pre", check_transform(self.pre, f"joint {self.name!r} pre"))
        object.__setattr__(self, "post", check_transform(self.post,
                                                          f"joint {self.name!r} post"))
        lo, hi, vmax, amax, jmax = check_limits(self.qlim, self.vmax, self.amax, self.jmax,
                                                 joint=None, where=f"joint {self.name!r}")
        object.__setattr__(self, "qlim", (lo, hi))
        object.__setattr__(self, "vmax", vmax)
        object.__setattr__(self, "amax", amax)
        object.__setattr__(self, "jmax", jmax)
        self.pre.setflags(write=False)
        self.post.setflags(write=False)
