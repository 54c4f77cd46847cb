"""The robot model: a serial chain of revolute and prismatic joints (`Chain`).

A chain is built from a standard (`DH`) or modified/Craig
(`MDH`) Denavit–Hartenberg table, from URDF or MJCF
(parsed by `ratectl.io`), or directly from `Joint`
objects. The kinematics (``fk``, ``jacobian``, ...) live in `ratectl.kinematics`;
the chain exposes them as methods.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from .. import kinematics
from ..arrays import read_only
from ..checks import positive_number, real_array
from ..errors import ImportModelError, InputError, ModelError
from ..io.description import ModelDescription, VisualDescription
from .joints import DH, MDH, Joint, check_transform

__all__ = ["Chain"]


class Chain:
    """A serial robot arm: joints, base and tool transforms, limits and names.

    Build one with `from_dh`, `from_mdh`, the importers, or from
    `Joint` objects. A chain is immutable; `with_tool` and
    `with_base` return new chains.

    Kinematics methods (all broadcast over leading dimensions of ``q``):
    `fk`, `frames`, `jacobian`, `fk_jacobian`,
    `jacobian_dot`, `joint_axes`, `joint_torques`.
    """

    def __init__(self, joints: Sequence[Joint], *, base: ArrayLike | None = None,
                 tool: ArrayLike | None = None, name: str = "chain", table: tuple | None = None,
                 characteristic_length: float | None = None,
                 links: Sequence[tuple[str, int, ArrayLike]] | None = None,
                 visuals: Sequence[VisualDescription] = ()):
        joints = tuple(joints)
        if not joints:
            raise ModelError("a chain needs at least one joint", field="joints")
        for k, j in enumerate(joints):
            if not isinstance(j, Joint):
                raise ModelError(f"joint {k} must be a ratectl.Joint, got {type(j).__name__}",
                                 joint=k, value=j)
        self._joints = joints
        self._base = read_only(check_transform(base, "base"))
        self._tool = read_only(check_transform(tool, "tool"))
        self._name = str(name)
        self._table = table
        self._n = len(joints)
        self._qshape = (self._n,)
        self._lower = read_only([j.qlim[0] for j in joints])
        self._upper = read_only([j.qlim[1] for j in joints])
        self._vmax = read_only([j.vmax for j in joints])
        self._amax = read_only([j.amax for j in joints])
        self._jmax = read_only([j.jmax for j in joints])
        self._prismatic = np.array([j.kind == "prismatic" for j in joints])
        if characteristic_length is None:
            characteristic_length = self.reach()
        self._length = positive_number("characteristic_length", characteristic_length, unit="[m]")
        self._visuals = tuple(visuals)
        self._kernels: dict = {}
        self._links = _check_links(links, self._n)
        self._link_chains: dict[str, Chain | None] = {}
        self._links_plans: dict[tuple, tuple] = {}  # per tuple of links: `fk_jacobian_links`'s kernel

    # ------------------------------------------------------------------ constructors
    @classmethod
    def from_dh(cls, rows: Sequence[DH], *, base: ArrayLike | None = None,
                tool: ArrayLike | None = None, name: str = "chain",
                characteristic_length: float | None = None) -> Chain:
        """Chain from a standard DH table (a list of `DH` rows)."""
        rows = cls._check_rows(rows, DH)
        joints = [r.to_joint(k) for k, r in enumerate(rows)]
        return cls(joints, base=base, tool=tool, name=name, table=tuple(rows),
                   characteristic_length=characteristic_length)

    @classmethod
    def from_mdh(cls, rows: Sequence[MDH], *, base: ArrayLike | None = None,
                 tool: ArrayLike | None = None, name: str = "chain",
                 characteristic_length: float | None = None) -> Chain:
        """Chain from a modified (Craig) DH table (a list of `MDH` rows)."""
        rows = cls._check_rows(rows, MDH)
        joints = [r.to_joint(k) for k, r in enumerate(rows)]
        return cls(joints, base=base, tool=tool, name=name, table=tuple(rows),
                   characteristic_length=characteristic_length)

    @staticmethod
    def _check_rows(rows, kind):
        if isinstance(rows, str | bytes) or not hasattr(rows, "__iter__"):
            raise ModelError(f"a DH table must be a list of {kind.__name__} rows, got {rows!r}"[:200],
                             field="rows", value=rows)
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
    def from_urdf(cls, source: Any, *, tip: str | None = None, base_link: str | None = None,
                  name: str | None = None, qlim: ArrayLike | None = None, vmax: ArrayLike | None = None,
                  amax: ArrayLike | None = None, jmax: ArrayLike | None = None) -> Chain:
        """Chain from a URDF file path or the URDF text itself (see `ratectl.io.urdf`).

        Args:
            source: path to a ``.urdf`` file, or the XML text (a ``str`` starting with ``<``),
                or bytes — e.g. the URDF a robot reports about itself.
            tip: the link that becomes the tool frame (required where the tree branches).
            base_link: the link that becomes the base frame (default: the root link).
            name: chain name (default: the ``<robot name>``).
            qlim, vmax, amax, jmax: limits to set or replace after import, as in
                `with_limits` (URDF carries no acceleration or jerk limits: pass
                ``amax``/``jmax`` here for acceleration-limited or smoothed control).
        """
        from ..io.urdf import parse_urdf

        chain = cls.from_description(parse_urdf(source, tip=tip, base_link=base_link, name=name))
        return chain.with_limits(qlim=qlim, vmax=vmax, amax=amax, jmax=jmax)

    @classmethod
    def from_mjcf(cls, path_or_model: Any, *, tip: str | None = None, name: str | None = None,
                  qlim: ArrayLike | None = None, vmax: ArrayLike | None = None,
                  amax: ArrayLike | None = None, jmax: ArrayLike | None = None) -> Chain:
        """Chain from an MJCF file, its text, or a compiled ``mujoco.MjModel``
        (see `ratectl.io.mjcf`); ``qlim, vmax, amax, jmax`` set or replace limits
        after import, as in `with_limits`."""
        from ..io.mjcf import parse_mjcf

        chain = cls.from_description(parse_mjcf(path_or_model, tip=tip, name=name))
        return chain.with_limits(qlim=qlim, vmax=vmax, amax=amax, jmax=jmax)

    @classmethod
    def from_description(cls, description: ModelDescription) -> Chain:
        """Chain from what a model file says (`ratectl.io.description.ModelDescription`).

        Raises:
            ImportModelError: a joint's transform or limits are not acceptable; the
                message names the file and the element.
        """
        joints = []
        for jd in description.joints:
            try:
                joints.append(Joint(kind=jd.kind, pre=jd.pre, post=jd.post, name=jd.name,
                                    qlim=(-math.inf, math.inf) if jd.qlim is None else jd.qlim,
                                    vmax=math.inf if jd.vmax is None else jd.vmax))
            except ModelError as exc:
                raise ImportModelError(f"{description.label}: {jd.element}: {exc}",
                                       element=jd.element) from None
        try:
            return cls(joints, tool=description.tool, name=description.name,
                       links=description.links or None, visuals=description.visuals)
        except ModelError as exc:
            raise ImportModelError(f"{description.label}: {exc}", element=str(exc.field)) from None

    def with_tool(self, tool: ArrayLike) -> Chain:
        """The same chain with another tool transform (flange → tool, 4×4)."""
        return Chain(self._joints, base=self._base, tool=tool, name=self._name,
                     table=self._table, characteristic_length=self._length, links=self._link_list(),
                     visuals=self._visuals)

    def with_limits(self, *, qlim: ArrayLike | None = None, vmax: ArrayLike | None = None,
                    amax: ArrayLike | None = None, jmax: ArrayLike | None = None) -> Chain:
        """The same chain with some limits set or replaced; ``None`` keeps the chain's.

        Args:
            qlim: position limits (lower, upper) [rad or m]: one pair for every joint, or
                an (n, 2) array; ±inf where absent.
            vmax, amax, jmax: velocity [rad/s or m/s], acceleration [rad/s² or m/s²] and
                jerk [rad/s³ or m/s³] limits (positive magnitudes, inf where absent): a
                scalar for every joint or n values.

        Example: ``rc.Chain.from_urdf(path, tip="tool").with_limits(amax=10.0, jmax=100.0)``.

        Raises:
            InputError: a wrong shape; ModelError: a value that is not a valid limit.
        """
        import dataclasses

        n = self._n
        cols = {}
        if qlim is not None:
            a = real_array("qlim", qlim, f"a pair (lower, upper) or ({n}, 2) numbers")
            if a.shape == (2,):
                a = np.broadcast_to(a, (n, 2))
            if a.shape != (n, 2):
                raise InputError(f"qlim must be a pair (lower, upper) or have shape ({n}, 2), got shape "
                                 f"{a.shape}", argument="qlim", value=qlim)
            cols["qlim"] = [(float(lo), float(hi)) for lo, hi in a]
        for key, v in (("vmax", vmax), ("amax", amax), ("jmax", jmax)):
            if v is None:
                continue
            a = real_array(key, v, f"a number or {n} numbers")
            if a.shape not in ((), (n,)):
                raise InputError(f"{key} must be a scalar or have shape ({n},), got shape {a.shape}",
                                 argument=key, value=v)
            cols[key] = np.broadcast_to(a, (n,)).tolist()
        if not cols:
            return self
        joints = []
        for k, j in enumerate(self._joints):
            try:
                changes: dict[str, Any] = {key: c[k] for key, c in cols.items()}
                joints.append(dataclasses.replace(j, **changes))
            except ModelError as exc:
                raise ModelError(f"{self._name}: joint {k}: {exc}", field=exc.field, joint=k,
                                 value=exc.value) from None
        table = self._table
        if table is not None:
            table = tuple(dataclasses.replace(r, **{key: c[k] for key, c in cols.items()})
                          for k, r in enumerate(table))
        return Chain(joints, base=self._base, tool=self._tool, name=self._name, table=table,
                     characteristic_length=self._length, links=self._link_list(),
                     visuals=self._visuals)

    def with_base(self, base: ArrayLike) -> Chain:
        """The same chain with another base transform (world → frame 0, 4×4)."""
        return Chain(self._joints, base=base, tool=self._tool, name=self._name,
                     table=self._table, characteristic_length=self._length, links=self._link_list(),
                     visuals=self._visuals)

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
    def link_names(self) -> tuple[str, ...]:
        """Names of the frames fixed to the arm that ``fk``/``jacobian`` accept as ``link=``:
        the URDF links (MJCF bodies) rigidly attached to the chain, base link first; for a
        chain built from a DH table or joints, ``"link1"`` … ``"linkn"`` (the frame after
        joint i)."""
        return tuple(self._links)

    def link_placement(self, link: str) -> tuple[int, np.ndarray]:
        """``(k, T)``: the link's frame is the constant ``T`` (4×4, read-only) after the frame
        of joint k (the k-th joint's moving frame; k = 0: the base frame)."""
        try:
            return self._links[link]
        except (KeyError, TypeError):
            raise InputError(f"link {link!r} is not a link of {self._name!r}; links: "
                             f"{list(self._links)}", argument="link", value=link) from None

    def _link_list(self) -> list[tuple[str, int, np.ndarray]]:
        return [(nm, k, T) for nm, (k, T) in self._links.items()]

    def _link_chain(self, link: str) -> Chain | None:
        """The sub-chain of the joints before ``link`` with the link frame as its tool (its
        generated kernels give the link's pose and Jacobian); None for a link on the base."""
        if link in self._link_chains:
            return self._link_chains[link]
        k, T = self.link_placement(link)
        sub = None if k == 0 else Chain(self._joints[:k], base=self._base, tool=T,
                                        name=f"{self._name}:{link}",
                                        characteristic_length=self._length)
        self._link_chains[link] = sub
        return sub

    def _link_fk_jacobian(self, q: ArrayLike, link: str, frame: str, point: ArrayLike | None,
                          want_jacobian: bool = True):
        """Pose (..., 4, 4) and Jacobian (..., 6, n) of a named link (zero columns after it)."""
        if (type(q) is np.ndarray and q.shape == self._qshape and q.dtype == _F64
                and frame == "base" and point is None and type(link) is str):
            # one finite configuration: the link's sub-chain kernel on floats (no check_q,
            # no slicing copies), as the tool's fast path in `fk_jacobian`
            sub = self._link_chain(link)
            v = q.tolist()
            s = sum(v)
            if sub is not None and s - s == 0.0:
                k = sub._n
                if not want_jacobian:
                    kern = sub._kernels.get(_FK) or kinematics.build_kernel(sub, _FK)
                    return _fromiter(kern(*v[:k]), _F64, 16).reshape(4, 4), None
                kern = sub._kernels.get(_FKJAC) or kinematics.build_kernel(sub, _FKJAC)
                a = _fromiter(kern(*v[:k]), _F64, 16 + 6 * k)
                if k == self._n:
                    return a[:16].reshape(4, 4), a[16:].reshape(6, k)
                J = np.zeros((6, self._n))
                J[:, :k] = a[16:].reshape(6, k)
                return a[:16].reshape(4, 4), J
        a = self.check_q(q)
        sub = self._link_chain(link)
        batch = a.shape[:-1]
        if sub is None:
            k, Tl = self._links[link]
            T = np.broadcast_to(self._base @ Tl, batch + (4, 4)).copy()
            if not want_jacobian:
                return T, None
            kinematics.check_frame(frame)
            if point is not None:
                kinematics.check_point(point)
            return T, np.zeros(batch + (6, self._n))
        k = sub.dof
        if not want_jacobian:
            return sub.fk(a[..., :k] if k < self._n else a), None
        T, Jk = sub.fk_jacobian(np.ascontiguousarray(a[..., :k]), frame=frame, point=point)
        if k == self._n:
            return T, Jk
        J = np.zeros(batch + (6, self._n))
        J[..., :k] = Jk
        return T, J

    @property
    def visuals(self) -> tuple[VisualDescription, ...]:
        """The links' geometry read from a model file (URDF ``<visual>``/``<collision>``),
        each placed on a chain frame (`ratectl.io.description.VisualDescription`); empty
        for chains built from DH tables. Used to draw the arm (`ratectl.viewer`)."""
        return self._visuals

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
    def check_q(self, q: ArrayLike, *, name: str = "q") -> np.ndarray:
        """Validate ``q`` (shape (..., n), finite) and return it as a float array."""
        try:
            if isinstance(q, str | bytes) or np.iscomplexobj(q):
                raise TypeError(name)  # no silent conversion: strings, complex numbers
            a = np.asarray(q, dtype=float)
        except (TypeError, ValueError, OverflowError):
            raise InputError(f"{name} must be an array of {self._n} real joint values, got "
                             f"{q!r}"[:300], argument=name, value=q) from None
        if a.ndim == 0 or a.shape[-1] != self._n:
            raise InputError(
                f"{name} must have shape ({self._n},) or (..., {self._n}) — one value per joint "
                f"of {self._name!r} — got shape {a.shape}", argument=name, value=a)
        if not np.all(np.isfinite(a)):
            raise InputError(f"{name} must be finite; got NaN or inf at index "
                             f"{np.argwhere(~np.isfinite(a))[0].tolist()}", argument=name, value=a)
        return a

    def within_limits(self, q: ArrayLike, *, tolerance: float = 0.0) -> np.ndarray:
        """True where every joint of q lies within [lower − tol, upper + tol]."""
        a = self.check_q(q)
        return np.all((a >= self._lower - tolerance) & (a <= self._upper + tolerance), axis=-1)

    def random_q(self, size: int | tuple[int, ...] | None | None = None, *,
                 rng: np.random.Generator | int | None | None = None, margin: float = 0.0) -> np.ndarray:
        """Random configurations, uniform within the limits (±π, or ±1 m, where unlimited;
        a one-sided limit gets a 2π (2 m) range beyond it).

        Args:
            size: batch shape (None for a single (n,) configuration).
            rng: a ``numpy.random.Generator`` or seed.
            margin: keep this far inside the limits [rad or m].
        """
        if isinstance(margin, str | bytes) or not (isinstance(margin, int | float | np.number)
                                                     and margin >= 0 and math.isfinite(margin)):
            raise InputError(f"margin must be a finite non-negative distance [rad or m], got "
                             f"{margin!r}", argument="margin", value=margin)
        try:
            generator = np.random.default_rng(rng)
            shape = (self._n,) if size is None else tuple(int(s) for s in np.atleast_1d(size)) + (self._n,)
        except (TypeError, ValueError) as exc:
            raise InputError(f"random_q: bad size or rng ({exc})", argument="size",
                             value=(size, rng)) from None
        # the margin applies to the limits that exist; an absent side samples ±π (±1 m)
        # around zero, or 2π (2 m) beyond the existing side of a one-sided limit
        default = np.where(self._prismatic, 1.0, math.pi)
        flo, fhi = np.isfinite(self._lower), np.isfinite(self._upper)
        lo = np.where(flo, self._lower + margin,
                      np.where(fhi, self._upper - margin - 2.0 * default, -default))
        hi = np.where(fhi, self._upper - margin, np.where(flo, lo + 2.0 * default, default))
        bad = np.flatnonzero(lo > hi)
        if bad.size:
            j = int(bad[0])
            raise InputError(f"random_q: margin {margin!r} is more than half the range of joint {j} "
                             f"({self._joints[j].name!r}, [{self._lower[j]:.6g}, {self._upper[j]:.6g}]); "
                             "no configuration keeps that far inside the limits", argument="margin",
                             value=margin)
        if any(s < 0 for s in shape):
            raise InputError(f"random_q: size must be non-negative, got {size!r}", argument="size",
                             value=size)
        # lo + (hi − lo)·u can round past hi by an ulp: clip into [lo, hi]
        return np.minimum(np.maximum(lo + (hi - lo) * generator.random(shape), lo), hi)

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
    # `ratectl.kinematics`.
    def fk(self, q: ArrayLike, *, link: str | None = None) -> np.ndarray:
        """Base-to-tool pose ``T_world_tool`` (..., 4, 4) at q (..., n); with ``link`` (one of
        `link_names`) the pose of that link's frame."""
        if link is not None:
            return self._link_fk_jacobian(q, link, "base", None, False)[0]
        if type(q) is np.ndarray and q.shape == self._qshape and q.dtype == _F64:
            v = q.tolist()
            s = sum(v)
            if s - s == 0.0:
                k = self._kernels.get(_FK) or kinematics.build_kernel(self, _FK)
                return _fromiter(k(*v), _F64, 16).reshape(4, 4)
        return kinematics.fk(self, q)

    def jacobian(self, q: ArrayLike, *, frame: str = "base", point: ArrayLike | None = None,
                 link: str | None = None) -> np.ndarray:
        """Geometric Jacobian (..., 6, n), rows [v; ω].

        Args:
            q: joint positions (..., n).
            frame: ``"base"`` (rows in world/base axes) or ``"tool"`` (tool axes).
            point: reference point for the linear rows, as coordinates in the tool
                frame [m] (a point fixed to the tool); default the tool origin.
            link: one of `link_names`: the Jacobian of that link's frame (``frame="tool"``
                and ``point`` then refer to the link frame); the columns of the joints
                after the link are zero.
        """
        if link is not None:
            return self._link_fk_jacobian(q, link, frame, point)[1]
        if (type(q) is np.ndarray and q.shape == self._qshape and q.dtype == _F64
                and frame == "base" and point is None):
            v = q.tolist()
            s = sum(v)
            if s - s == 0.0:
                k = self._kernels.get(_JAC) or kinematics.build_kernel(self, _JAC)
                return _fromiter(k(*v), _F64, 6 * self._n).reshape(6, self._n)
        return kinematics.jacobian(self, q, frame=frame, point=point)

    def fk_jacobian(self, q: ArrayLike, *, frame: str = "base", point: ArrayLike | None = None,
                    link: str | None = None):
        """``(fk(q), jacobian(q))`` computed together (cheaper than two calls); ``link`` as in
        `jacobian`."""
        if link is not None:
            return self._link_fk_jacobian(q, link, frame, point)
        if (type(q) is np.ndarray and q.shape == self._qshape and q.dtype == _F64
                and frame == "base" and point is None):
            v = q.tolist()
            s = sum(v)
            if s - s == 0.0:
                k = self._kernels.get(_FKJAC) or kinematics.build_kernel(self, _FKJAC)
                a = _fromiter(k(*v), _F64, 16 + 6 * self._n)  # (cheaper than np.array of a tuple)
                return a[:16].reshape(4, 4), a[16:].reshape(6, self._n)
        return kinematics.fk_jacobian(self, q, frame=frame, point=point)

    def fk_rows_jacobian(self, q: ArrayLike) -> tuple[Sequence[Sequence[float]], np.ndarray]:
        """The tool pose's first three rows as Python floats (R | p, three sequences of four)
        and the Jacobian (6, n), for one configuration (n,): the numbers of
        ``(fk(q)[:3].tolist(), jacobian(q))`` from one kernel call, for code that works on
        the pose's numbers (a pose error on rows of floats, every control cycle) without an
        array and its ``tolist()``."""
        t = self._fk_jacobian_numbers(q)
        if t is not None:
            n = self._n
            return (t[0:4], t[4:8], t[8:12]), _fromiter(t, _F64, 16 + 6 * n)[16:].reshape(6, n)
        T, J = self.fk_jacobian(q)
        if T.ndim != 2:
            raise InputError(f"fk_rows_jacobian takes one configuration ({self._n},), got a batch of "
                             f"shape {T.shape[:-2]}", argument="q", value=q)
        return T[:3].tolist(), J

    def _fk_jacobian_numbers(self, q: ArrayLike) -> tuple[float, ...] | None:
        """The numbers of ``fk_jacobian(q)`` as the generated kernel gives them, one tuple of
        Python floats: the tool pose's 16 entries then the Jacobian's 6·n, each row-major;
        None unless q is one finite configuration, an (n,) float64 array (the caller then
        takes `fk_jacobian`)."""
        if type(q) is np.ndarray and q.shape == self._qshape and q.dtype == _F64:
            v = q.tolist()
            s = sum(v)
            if s - s == 0.0:
                return self._fkjac_kernel()(*v)
        return None

    def _fkjac_kernel(self) -> Any:
        """The generated kernel of `fk_jacobian` (the tool): ``k(q0, …, q{n-1})`` gives the
        numbers of `_fk_jacobian_numbers` from one finite configuration's n floats, for a
        caller that has checked them."""
        return self._kernels.get(_FKJAC) or kinematics.build_kernel(self, _FKJAC)

    def fk_jacobian_links(self, q: ArrayLike,
                          links: Sequence[str | None]) -> list[tuple[np.ndarray, np.ndarray]]:
        """``[fk_jacobian(q, link=l) for l in links]`` (``None``: the tool), the same numbers,
        computed for one configuration (n,) in one pass of the chain: one generated kernel
        per tuple of links, whose frames branch off one recursion where each link's own
        recursion would end. Anything else (a batch, a link on the base, reference kernels)
        is computed link by link."""
        links = tuple(links)
        if type(q) is np.ndarray and q.shape == self._qshape and q.dtype == _F64:
            v = q.tolist()
            s = sum(v)
            if s - s == 0.0:
                plan = self._links_plans.get(links)
                if plan is None:
                    plan = self._links_plan(links)
                if plan:
                    kern, ks, size = plan
                    a = _fromiter(kern(*v), _F64, size)
                    n = self._n
                    out = []
                    o = 0
                    for k in ks:
                        T = a[o:o + 16].reshape(4, 4)
                        Jk = a[o + 16:o + 16 + 6 * k].reshape(6, k)
                        o += 16 + 6 * k
                        if k < n:
                            J = np.zeros((6, n))
                            J[:, :k] = Jk
                            Jk = J
                        out.append((T, Jk))
                    return out
        return [self.fk_jacobian(q) if lk is None else self.fk_jacobian(q, link=lk) for lk in links]

    def _links_plan(self, links: tuple) -> tuple:
        """``(kernel, k per link, output size)`` of `fk_jacobian_links` (``()``: link by link)."""
        placements = []
        for lk in links:
            placements.append((self._n, self._tool) if lk is None else self.link_placement(lk))
        plan: tuple = ()
        if self._n and all(k >= 1 for k, _ in placements):
            kern = kinematics.build_links_kernel(self, ("links", links), placements)
            if kern is not None:
                ks = tuple(k for k, _ in placements)
                plan = (kern, ks, sum(16 + 6 * k for k in ks))
        self._links_plans[links] = plan
        return plan

    def frames(self, q: ArrayLike) -> np.ndarray:
        """All DH frames ``T_0 … T_n`` in the world, (..., n+1, 4, 4) (T_0 is the base)."""
        return kinematics.frames(self, q)

    def joint_axes(self, q: ArrayLike):
        """World axis (unit, ..., n, 3) and a point on it (..., n, 3) for every joint."""
        return kinematics.joint_axes(self, q)

    def jacobian_dot(self, q: ArrayLike, qd: ArrayLike, *, frame: str = "base",
                     point: ArrayLike | None = None) -> np.ndarray:
        """Time derivative J̇(q, q̇) (..., 6, n), so that the tool acceleration is J q̈ + J̇ q̇."""
        return kinematics.jacobian_dot(self, q, qd, frame=frame, point=point)

    def kernel_source(self, what: str = "fkjac", *, batched: bool = False) -> str:
        """The generated Python source behind `fk`/`jacobian` (``what``: "fk",
        "jac" or "fkjac"), for reading and debugging; see `ratectl.kinematics.codegen`."""
        return kinematics.kernel_source(self, what, batched=batched)

    def joint_torques(self, q: ArrayLike, wrench: ArrayLike, *, frame: str = "base",
                      point: ArrayLike | None = None) -> np.ndarray:
        """Static joint torques τ = Jᵀ F for a tool wrench F = [f; τ], in N and N·m."""
        return kinematics.joint_torques(self, q, wrench, frame=frame, point=point)


def _check_links(links, n: int) -> dict[str, tuple[int, np.ndarray]]:
    """``{name: (k, T)}`` from ``(name, k, T)`` triples; default ``"link1"`` … ``"linkn"``."""
    if links is None:
        return {f"link{i}": (i, read_only(np.eye(4))) for i in range(1, n + 1)}
    out: dict[str, tuple[int, np.ndarray]] = {}
    for item in links:
        try:
            name, k, T = item
        except (TypeError, ValueError):
            raise ModelError(f"links must be (name, joint index, 4x4) triples, got {item!r}",
                             field="links", value=item) from None
        if not isinstance(name, str) or name in out:
            raise ModelError(f"link names must be distinct strings, got {name!r}", field="links",
                             value=name)
        if not (isinstance(k, int | np.integer) and 0 <= int(k) <= n):
            raise ModelError(f"link {name!r}: joint index must be an integer in [0, {n}], got {k!r}",
                             field="links", value=k)
        out[name] = (int(k), read_only(check_transform(T, f"link {name!r}")))
    return out


_F64 = np.dtype(np.float64)
_fromiter = np.fromiter
_FK = ("fk", False)
_JAC = ("jac", False)
_FKJAC = ("fkjac", False)
