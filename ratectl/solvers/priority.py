"""Strict priorities under joint limits: a cascade of small QPs (`PriorityCascade`).

Levels ``k = 0, 1, …`` (0 highest) each ask ``A_k q̇ ≈ b_k`` with row weights ``w_k``.
Level k solves

    minimise    ½‖W_k^{1/2}(A_k q̇ − b_k)‖² + ½λ²‖q̇‖²
    subject to  l ≤ q̇ ≤ u                   (the joint position/velocity/acceleration box,
                                              `ratectl.solvers.qp.joint_velocity_bounds`)
                G q̇ ≤ h                     (extra rows: collision dampers, …)
                A_j q̇ = A_j q̇_j*,  j < k    (every higher level keeps what it achieved)

The equalities are exact for least squares: over a convex set, the minimisers of
‖W^{1/2}(A q̇ − b)‖² are exactly the feasible points with the optimal A q̇, so a lower level
never changes what a higher level achieves within the limits. They are imposed by
parametrisation, not as rows: ``q̇ = x_k + Z_k z`` with ``x_k`` the answer so far and ``Z_k``
an orthonormal basis of the null space of the stacked higher levels' weighted rows
(singular values below ``tolerance``·max(1, σ_max) count as zero — the tolerance of the
equality; a QR factorisation gives the basis where it proves the rank, an SVD otherwise),
so each level is a QP in ``dim Z_k`` unknowns and a redundant higher row never makes the
constraints degenerate. The cascade stops when no freedom is left.

Each level first tries the unconstrained minimiser (the null-space projection
``z = −H⁻¹f``): when it satisfies the box and the rows no QP is solved (that is
null-space projection exactly, where no inequality is active). Otherwise two cases have a
closed form: a level with one free direction (a QP in one unknown) takes its minimiser
clipped to the interval the box and the rows leave on that line; a level with lower levels
after it whose minimisers form a line (its rows leave one direction unseen) takes the point
of that line of least norm (the damping's choice) inside the box and the rows, when the line
crosses them — the lower levels then move along it anyway. Anything else goes to the
backend, which solves the level's QP. When the box and the rows G q̇ ≤ h have no common point (a
collision damper that the acceleration limit cannot honour this period), the rows are
first relaxed by the least-squares slack s ≥ 0 (G q̇ ≤ h + s) that makes them feasible,
and the result says so (``relaxed``).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from operator import gt as _gt
from operator import lt as _lt
from operator import sub as _sub
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike
from scipy.linalg import lapack as _lapack

from ..arrays import read_only, shared_zeros
from ..errors import InputError, SolverError
from ..model.limits import Limits
from .base import _positive, thin_svd
from .qp.active_set import qp_via_dual
from .qp.bounds import _BIG, _BoundCache, _box, _vec

_dposv = _lapack.dposv
_dgeqrf = _lapack.dgeqrf
_dorgqr = _lapack.dorgqr
_dtrtri = _lapack.dtrtri

if TYPE_CHECKING:
    from ..model.chain import Chain

__all__ = ["PriorityCascade", "CascadeResult", "Level", "default_backend"]


@dataclass(frozen=True)
class Level:
    """One priority level: rows ``A q̇ ≈ b`` (A (m, n), b (m,)) with per-row weights (m,)."""

    A: np.ndarray
    b: np.ndarray
    weights: np.ndarray | None = None


@dataclass(frozen=True, kw_only=True)
class CascadeResult:
    """The answer of `PriorityCascade.solve`.

    Attributes:
        qd: joint velocities (n,) [rad/s or m/s], within the box and the rows.
        residuals: (levels,) ‖W_k^{1/2}(A_k q̇ − b_k)‖ per level, in the levels' units.
        qps: (levels,) True where a level needed its QP (an inequality was active at the
            unconstrained answer), False where the null-space projection was the answer.
        freedom: (levels,) the number of joint-velocity directions each level could use.
        lower, upper: the box (n,) of this step.
        box_active: (n,) bool, joints on a face of the box.
        rows_active: (k,) bool, extra rows G q̇ ≤ h that hold with equality.
        relaxed: (k,) the slack s ≥ 0 added to h where box and rows had no common point
            (zeros otherwise).
        backend: the QP backend that was used.
    """

    qd: np.ndarray
    residuals: np.ndarray
    qps: np.ndarray
    freedom: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    box_active: np.ndarray
    rows_active: np.ndarray
    relaxed: np.ndarray
    backend: str

    def __post_init__(self) -> None:
        for name in ("qd", "residuals", "lower", "upper", "relaxed"):
            object.__setattr__(self, name, read_only(getattr(self, name)))
        for name in ("qps", "freedom", "box_active", "rows_active"):
            object.__setattr__(self, name, read_only(getattr(self, name), dtype=None))

    def __getattr__(self, name: str) -> Any:
        # ``lower`` and ``upper`` of a one-level step clear of the box, made on first access
        # (`PriorityCascade._one_level_clear` keeps what they are made of, `_lazy_box`)
        d = self.__dict__
        if (name == "lower" or name == "upper") and "_box_of" in d:
            d["lower"], d["upper"] = _lazy_box(*d["_box_of"])
            return d[name]
        raise AttributeError(f"{type(self).__name__!r} object has no attribute {name!r}")


def _clear_thresholds(bc: _BoundCache) -> tuple[list[float] | None, ...]:
    """The thresholds of `PriorityCascade._one_level_clear`, with ``T = _ACT_TOL·max(2·max
    vmax, 1)``: ``(vmax − 2T, −(vmax − 2T), amax·dt − 2T, −(amax·dt − 2T))`` as lists of
    floats (the last two None without an acceleration side); all None when T exceeds 1e-3
    (velocity limits so large, or absent, that the test would refuse every answer)."""
    t2 = 2.0 * _ACT_TOL * max(2.0 * max(bc.vmax_l), 1.0)
    if not t2 <= 1e-3:
        return None, None, None, None
    hi = [v - t2 for v in bc.vmax_l]
    if bc.amax_dt_l is None or not bc.has_acc:
        return hi, [-v for v in hi], None, None
    acc = [a - t2 for a in bc.amax_dt_l]
    return hi, [-v for v in hi], acc, [-a for a in acc]


def _lazy_box(bc: _BoundCache, qdl: list[float] | None) -> tuple[np.ndarray, np.ndarray]:
    """The box of a step with no joint near a position limit (`_box`'s arithmetic, read-only
    arrays): ±vmax, narrowed to q̇_prev ± amax·dt with ``qdl`` the previous q̇ as floats."""
    if qdl is None:
        return bc.nvmax, bc.vmax
    qd = np.array(qdl)
    lo = np.maximum(bc.nvmax, qd - bc.amax_dt)
    hi = np.minimum(bc.vmax, qd + bc.amax_dt)
    lo.setflags(write=False)
    hi.setflags(write=False)
    return lo, hi


def default_backend() -> str:
    """``"daqp"`` when the package is installed (the ``qp-fast`` extra), else ``"proxqp"``
    when proxsuite is, else ``"exact"`` (ratectl's own dual active-set method, core)."""
    try:
        import daqp  # noqa: F401

        return "daqp"
    except ImportError:
        pass
    try:
        import proxsuite  # noqa: F401

        return "proxqp"
    except ImportError:
        return "exact"


class _Infeasible(Exception):
    """The first level's QP found no point in the box and the rows."""


_ACT_TOL = 1e-7  # a bound or row within this (relative) counts as active
_NO_ROWS = shared_zeros(0, dtype=bool)
_NO_H = shared_zeros(0)
_ONE_OF_ONE = np.ones((1, 1))  # the null space of a zero column (one direction, kept)
_NONE_OF_ONE = np.ones((1, 0))  # the null space of a non-zero column (none)
for _a in (_ONE_OF_ONE, _NONE_OF_ONE):
    _a.setflags(write=False)
_NO_COLUMNS: dict[int, np.ndarray] = {}


def _no_columns(n: int) -> np.ndarray:
    """A basis of no directions, (n, 0) (read-only, one per n)."""
    z = _NO_COLUMNS.get(n)
    if z is None:
        z = _NO_COLUMNS[n] = np.zeros((n, 0))
        z.setflags(write=False)
    return z


class PriorityCascade:
    """Strict-priority inverse velocity under joint limits (see the module docstring).

    Args:
        backend: ``"auto"`` (`default_backend`), ``"daqp"`` (called directly),
            ``"exact"`` (ratectl's dual active-set method: no extra package), or any
            solver name of `qpsolvers.solve_qp` (``"proxqp"``, ``"quadprog"``, ``"osqp"``).
        damping: λ [dimensionless], the regularisation ½λ²‖q̇‖² of every level (keeps
            each level's QP strictly convex; the equalities on the higher levels are exact
            whatever λ).
        tolerance: singular values of a level's weighted rows below
            ``tolerance · max(1, σ_max)`` count as zero (that direction is left to the
            lower levels): the tolerance of the equality on higher levels.
        margin: distance kept from the position limits [rad or m].

    One cascade per controller (it caches the box arithmetic); not thread-safe.
    """

    def __init__(self, *, backend: str = "auto", damping: float = 1e-5, tolerance: float = 1e-9,
                 margin: float = 0.0) -> None:
        if not isinstance(backend, str):
            raise InputError(f"backend must be a solver name, got {backend!r}", argument="backend",
                             value=backend)
        if backend == "auto":
            backend = default_backend()
        if backend not in ("daqp", "exact"):
            import qpsolvers

            if backend not in qpsolvers.available_solvers:
                raise InputError(f"QP backend {backend!r} is not installed; available: 'exact', "
                                 f"{sorted(qpsolvers.available_solvers)}", argument="backend",
                                 value=backend)
        elif backend == "daqp":
            try:
                import daqp  # noqa: F401
            except ImportError:
                raise InputError("backend 'daqp' needs the daqp package (pip install 'ratectl[qp-fast]')",
                                 argument="backend", value=backend) from None
        self.backend = backend
        self.damping = _positive("damping", damping, allow_zero=True)
        self.tolerance = _positive("tolerance", tolerance, allow_zero=True)
        self.margin = _positive("margin", margin, allow_zero=True)
        self._bcache: _BoundCache | None = None
        self._eyes: dict[int, np.ndarray] = {}
        self._kept: dict[tuple, np.ndarray] = {}
        self._no_rows: dict[int, np.ndarray] = {}  # G (0, n) of a solve without extra rows
        self._projection: np.ndarray | None = None  # the last null-space projection within the box
        self._one_fixed: tuple | None = None  # (n, qps, freedom, box_active) of `_one_level`
        self._fbox: tuple | None = None  # (bound cache, *`_clear_thresholds`, ...) of `_one_level_clear`

    def __repr__(self) -> str:
        return f"PriorityCascade(backend={self.backend!r}, damping={self.damping!r})"

    # ------------------------------------------------------------------ the box
    def box(self, n: int, limits: Limits | Chain | None, q: np.ndarray | None, qd_prev: np.ndarray | None,
            dt: float | None) -> tuple[np.ndarray, np.ndarray]:
        """The joint-velocity box (lo, hi) of this step (`joint_velocity_bounds`'s arithmetic;
        ±1e15 where a side is absent)."""
        if limits is None:
            return np.full(n, -_BIG), np.full(n, _BIG)
        lo, hi, _ = _box(self._cache(n, limits, dt), q, qd_prev)
        return lo, hi

    def limit_kinds(self, res: CascadeResult, qd_prev: np.ndarray | None) -> list[tuple[int, str]]:
        """``(joint, kind)`` for each joint on a face of the box of ``res`` (the last solve's,
        with its ``qd_prev``): ``"velocity"`` where the face is ±vmax, ``"acceleration"``
        where it is q̇_prev ± amax·dt, else ``"position"`` (the box holds exact copies of
        these bounds, as `joint_velocity_bounds` reports its sources)."""
        bc = self._bcache
        if bc is None or not res.box_active.any():
            return []
        qd, lo, hi = res.qd.tolist(), res.lower.tolist(), res.upper.tolist()
        vmax, adt = bc.vmax_l, bc.amax_dt_l
        qp = qd_prev.tolist() if qd_prev is not None and bc.has_acc and adt is not None else None
        out = []
        for j in np.flatnonzero(res.box_active).tolist():
            v, sign = (hi[j], 1.0) if abs(qd[j] - hi[j]) <= abs(qd[j] - lo[j]) else (lo[j], -1.0)
            if v == sign * vmax[j]:
                out.append((j, "velocity"))
            elif qp is not None and adt is not None and v == qp[j] + sign * adt[j]:
                out.append((j, "acceleration"))
            else:
                out.append((j, "position"))
        return out

    def _cache(self, n: int, limits: Limits | Chain, dt: float | None) -> _BoundCache:
        bc = self._bcache
        if bc is None or bc.src is not limits or bc.dt != dt or bc.n != n:
            bc = self._bcache = _BoundCache(limits, Limits.of(limits, n), dt, self.margin)
        return bc

    # ------------------------------------------------------------------ solve
    def solve(self, levels: Sequence[Level | tuple], *, limits: Limits | Chain | None = None,
              q: ArrayLike | None = None, qd_prev: ArrayLike | None = None, dt: float | None = None,
              extra_inequalities: tuple[ArrayLike, ArrayLike] | None = None) -> CascadeResult:
        """Solve the levels in order (see the module docstring).

        Args:
            levels: `Level` objects or ``(A, b)`` / ``(A, b, weights)`` tuples, highest
                priority first; every A has n columns.
            limits: a Chain or `Limits` (None: no box).
            q: joint positions (n,): the position side of the box.
            qd_prev: the previous q̇ (n,): with ``dt``, the acceleration side.
            dt: the control period [s].
            extra_inequalities: ``(G, h)``: rows G q̇ ≤ h every level must satisfy.

        Raises:
            InputError: shapes; SolverError: a backend failure on a feasible problem.
        """
        lv = [self._level(L, k) for k, L in enumerate(levels)]
        if not lv:
            raise InputError("solve needs at least one level", argument="levels", value=levels)
        n = lv[0][0].shape[1]
        for k, (A, _, _) in enumerate(lv):
            if A.shape[1] != n:
                raise InputError(f"level {k} has {A.shape[1]} columns, level 0 has {n}",
                                 argument="levels", value=A.shape)
        qv = _vec("q", q, n)
        qdv = _vec("qd_prev", qd_prev, n)
        if dt is not None:
            dt = _positive("dt", dt)
        G, h = self._rows(extra_inequalities, n)
        return self.solve_validated(lv, limits=limits, q=qv, qd_prev=qdv, dt=dt,
                                    extra_inequalities=(G, h) if h.size else None)

    def solve_validated(self, levels: Sequence[tuple[np.ndarray, np.ndarray, np.ndarray | None]], *,
                        limits: Limits | Chain | None, q: np.ndarray | None, qd_prev: np.ndarray | None,
                        dt: float | None,
                        extra_inequalities: tuple[np.ndarray, np.ndarray] | None = None,
                        stacked: tuple[np.ndarray, np.ndarray, tuple[int, ...]] | None = None,
                        ) -> CascadeResult:
        """`solve` without its checks, for a caller that has made them (the controller's
        tasks stage): ``levels`` are ``(A, b, sw)`` triples of finite float64 arrays, A (m, n),
        b (m,) and ``sw`` (m,) the square roots of the row weights or None (all 1); ``q`` and
        ``qd_prev`` finite float64 (n,) or None; ``dt`` > 0 or None; ``extra_inequalities``
        ``(G (k, n), h (k,))`` float64 with k ≥ 1, or None. ``stacked``: when every level's
        A and b are consecutive row blocks of one (M, n) array and one (M,) vector, and no
        level has weights, ``(A_all, b_all, ends)`` with ``ends`` each level's last row + 1:
        the residuals then come from one product. The answer is `solve`'s; a non-finite q̇
        raises SolverError."""
        n = levels[0][0].shape[1]
        if extra_inequalities is None and len(levels) == 1 and n and limits is not None:
            clear = self._one_level_clear(levels[0], n, limits, q, qd_prev, dt)
            if clear is not None:
                return self._clear_result(clear)
        return self._solve_boxed(levels, n, limits, q, qd_prev, dt, extra_inequalities, stacked)

    def _solve_boxed(self, levels: Sequence[tuple[np.ndarray, np.ndarray, np.ndarray | None]], n: int,
                     limits: Limits | Chain | None, q: np.ndarray | None, qd_prev: np.ndarray | None,
                     dt: float | None, extra_inequalities: tuple[np.ndarray, np.ndarray] | None,
                     stacked: tuple[np.ndarray, np.ndarray, tuple[int, ...]] | None) -> CascadeResult:
        """`solve_validated` on the box's arrays: all of it but its first try,
        `_one_level_clear` (one level under limits without extra rows)."""
        lo, hi = self.box(n, limits, q, qd_prev, dt)
        bc = self._bcache
        for a in (lo, hi):  # the step's own box is frozen in place for the result (not copied)
            if bc is None or (a is not bc.vmax and a is not bc.nvmax):
                a.setflags(write=False)
        if extra_inequalities is None and len(levels) == 1 and n and limits is None:
            one = self._one_level(levels[0], lo, hi, n)
            if one is not None:
                return one
        if extra_inequalities is None:
            G = self._no_rows.get(n)
            if G is None:
                G = self._no_rows[n] = np.zeros((0, n))
                G.setflags(write=False)
            h = _NO_H
        else:
            G, h = extra_inequalities
        try:
            return _finite(self._cascade(levels, lo, hi, G, h, np.zeros(h.shape[0]) if h.size else _NO_H, n,
                                         stacked=stacked))
        except _Infeasible:
            if not h.size:
                raise SolverError(f"the priority cascade's first level failed on backend "
                                  f"{self.backend!r}", status="failed") from None
        relaxed, feasible = self._relaxation(lo, hi, G, h)
        return _finite(self._cascade(levels, lo, hi, G, h + relaxed, relaxed, n, fallback=feasible,
                                     stacked=stacked))

    def _one_level_clear(self, level, n: int, limits: Limits | Chain, q: np.ndarray | None,
                         qd_prev: np.ndarray | None, dt: float | None) -> tuple | None:
        """`_one_level` under the limits for the common step, without the box's arrays: when
        no joint is near a position limit (farther than it can travel at vmax in one period
        and still stop: the bound cache's thresholds), the box is

            lo_i = max(−vmax_i, q̇_prev,i − amax_i·dt),   hi_i = min(vmax_i, q̇_prev,i + amax_i·dt)

        (±vmax without the acceleration side), and the minimiser x is clear of its faces by
        more than the activity tolerance ``tol = _ACT_TOL·max(max|hi| + max|lo|, 1)`` when

            |x_i| < vmax_i − 2T   and   |x_i − q̇_prev,i| < amax_i·dt − 2T   for every i,

        with ``T = _ACT_TOL·max(2·max vmax, 1)`` ≥ tol (every |lo_i|, |hi_i| is at most
        vmax_i; the factor 2 covers the rounding of the thresholds). Then x is the answer,
        as `_one_level` would find it: returned as ``(q̇, residuals, q̇_prev as floats or None,
        the thresholds' tuple)``, the arrays fresh and read-only, for `_clear_result` (which
        makes its `CascadeResult`, with ``lower`` and ``upper`` computed on first access,
        `_lazy_box`).
        None otherwise, and for velocity limits so large that T would refuse every answer
        (`solve_validated` decides, on the arrays)."""
        bc = self._bcache
        if bc is None or bc.src is not limits or bc.dt != dt or bc.n != n:
            bc = self._cache(n, limits, dt)
        fb = self._fbox
        if fb is None or fb[0] is not bc:
            # per bound cache: the thresholds, λ²I (None for λ = 0) and the result's constant
            # arrays (qps, freedom, box_active)
            fb = self._fbox = (bc, *_clear_thresholds(bc), self._lam2_eye(n) if self.damping**2 else None,
                               self._frozen([False], bool), self._frozen([n], int),
                               shared_zeros(n, dtype=bool))
        if fb[1] is None:
            return None
        if q is not None and bc.has_pos:
            if bc.inv_dt is None:
                return None
            ql = q.tolist()
            if any(map(_gt, ql, bc.near_hi_l)) or any(map(_lt, ql, bc.near_lo_l)):
                return None
        A, b, sw = level
        M = A if sw is None else sw[:, None] * A
        H = M.T.dot(M)
        if fb[5] is not None:
            H += fb[5]
        x = _spd_solve(H, M.T.dot(b if sw is None else b * sw))
        xl = x.tolist()
        if not (all(map(_lt, xl, fb[1])) and all(map(_gt, xl, fb[2]))):
            return None
        qdl = None
        if qd_prev is not None and fb[3] is not None:
            qdl = qd_prev.tolist()
            d = list(map(_sub, xl, qdl))
            if not (all(map(_lt, d, fb[3])) and all(map(_gt, d, fb[4]))):
                return None
        self._projection = x
        d = A.dot(x)
        d -= b
        if sw is not None:
            d *= sw
        res = np.array([math.sqrt(d.dot(d))])
        x.setflags(write=False)
        res.setflags(write=False)
        return x, res, qdl, fb

    def _clear_result(self, clear: tuple) -> CascadeResult:
        """The `CascadeResult` of a `_one_level_clear` answer ``clear``: no QP, every
        direction free, no joint on a face of the box, the box made on first access."""
        x, res, qdl, fb = clear
        r = object.__new__(CascadeResult)
        object.__setattr__(r, "__dict__", {
            "qd": x, "residuals": res, "qps": fb[6], "freedom": fb[7], "box_active": fb[8],
            "rows_active": _NO_ROWS, "relaxed": _NO_H, "backend": self.backend, "_box_of": (fb[0], qdl)})
        return r

    def _one_level(self, level, lo, hi, n) -> CascadeResult | None:
        """One level and no extra rows, the common case of a single weighted least squares
        under the box: its minimiser ``q̇ = H⁻¹ Mᵀ W^{1/2} b`` (``H = MᵀM + λ²I``, M the
        weighted rows, one Cholesky) when it lies farther than the activity tolerance from
        every face of the box — then it is the answer, with no joint on a face and no QP;
        None otherwise (`_cascade` decides). The same arithmetic as `_cascade`'s first
        pass, without its bookkeeping."""
        A, b, sw = level
        M = A if sw is None else sw[:, None] * A
        H = M.T.dot(M)
        lam2 = self.damping**2
        if lam2:
            H += self._lam2_eye(n)
        x = _spd_solve(H, M.T.dot(b if sw is None else b * sw))
        cl = x.tolist()
        lo_f, hi_f = lo.tolist(), hi.tolist()
        act_tol = _ACT_TOL * max(max(map(abs, hi_f)) + max(map(abs, lo_f)), 1.0)
        if not (min(map(_sub, hi_f, cl)) > act_tol and min(map(_sub, cl, lo_f)) > act_tol):
            return None
        self._projection = x
        d = A.dot(x) - b
        if sw is not None:
            d *= sw
        res = np.array([math.sqrt(d.dot(d))])
        fixed = self._one_fixed
        if fixed is None or fixed[0] != n:
            fixed = self._one_fixed = (n, self._frozen([False], bool), self._frozen([n], int),
                                       shared_zeros(n, dtype=bool))
        # (`_owned_result` with what is known here: x and res fresh, the box frozen by the
        # caller, the rest shared read-only arrays)
        x.setflags(write=False)
        res.setflags(write=False)
        r = object.__new__(CascadeResult)
        object.__setattr__(r, "__dict__", {
            "qd": x, "residuals": res, "qps": fixed[1], "freedom": fixed[2], "lower": lo, "upper": hi,
            "box_active": fixed[3], "rows_active": _NO_ROWS, "relaxed": _NO_H, "backend": self.backend})
        return r

    def _cascade(self, lv, lo, hi, G, h, relaxed, n, fallback=None, stacked=None) -> CascadeResult:
        """The levels in order; ``fallback`` (a q̇ known to satisfy the box and the rows)
        stands in for the first level's QP if its backend finds no point (a relaxed problem
        on the edge of its tolerance).

        First every level's unconstrained minimiser, each in the null space of the levels
        above (null-space projection): when the final q̇ satisfies the box and the rows it
        is the answer — each level's optimum over its free directions lies inside them, so
        no inequality is active at any level. Otherwise the levels again, each one's answer
        tested against the box and the rows (`_solve_level`). Per level: ``H = MᵀM + λ²I`` (M
        the weighted rows in the free directions) solved by one Cholesky (LAPACK
        ``dposv``); the null space for the next level from one QR factorisation of M
        (`_null_space`: an SVD where the QR does not prove the rank), skipped after the
        last level. Neither depends on q̇, so the second pass reuses them."""
        lo_f, hi_f = lo.tolist(), hi.tolist()
        lam2 = self.damping**2
        nlev = len(lv)
        have_rows = h.size > 0
        h_tol = h + 1e-12 * (1.0 + np.abs(h)) if have_rows else h
        # pass 1: null-space projection; each level's (Z, M, H, V) kept
        Z: np.ndarray | None = None  # None: the identity (level 0 uses every direction)
        parts: list[tuple | None] = []
        freedom = [0] * nlev
        x = _NO_H  # (no joints; otherwise the first level, with every direction, sets it)
        for k, (A, b, sw) in enumerate(lv):
            r = n if Z is None else Z.shape[1]
            freedom[k] = r
            if r == 0:
                parts.append(None)
                continue
            Mw = A if sw is None else sw[:, None] * A
            if r == 1 and Z is not None:
                # one free direction v: the level's minimiser along it on floats
                v = Z[:, 0]
                mv = Mw.dot(v)
                rhs = b - A.dot(x)
                if sw is not None:
                    rhs *= sw
                mm = float(mv.dot(mv))
                hh = mm + lam2
                t = (float(mv.dot(rhs)) - lam2 * float(v.dot(x))) / hh if hh > 0.0 else 0.0
                M = mv[:, None]
                V = None
                if k + 1 < nlev:  # `_null_space` of one column: its norm is its singular value
                    s1 = math.sqrt(mm)
                    V = _ONE_OF_ONE if s1 <= self.tolerance * max(1.0, s1) else _NONE_OF_ONE
                parts.append((Z, M, hh, V))  # (H = [[hh]], made in pass 2 if needed)
                x = x + v * t
            else:
                M = Mw if Z is None else Mw.dot(Z)
                H = M.T.dot(M)
                if lam2:
                    H += self._lam2_eye(r)
                V = _null_space(M, self.tolerance) if k + 1 < nlev else None
                parts.append((Z, M, H, V))
                if Z is None:
                    # the first level, every direction free: its minimiser H⁻¹Mᵀ W^{1/2} b
                    # whatever the start (x + H⁻¹(Mᵀ W^{1/2}(b − A x) − λ²x) is that point)
                    x = _spd_solve(H, M.T.dot(b if sw is None else b * sw))
                else:
                    x = x + Z.dot(_spd_solve(H, self._gradient(A, b, sw, M, Z, x, False, lam2)))
            if V is not None:
                if V is _NONE_OF_ONE:  # (Z @ V without the product: no direction left)
                    Z = _no_columns(n)
                elif V is not _ONE_OF_ONE:  # (the one direction stays)
                    Z = V if Z is None else Z.dot(V)
        cl = x.tolist()
        # farther than the activity tolerance from every face of the box (the common case:
        # then strictly inside, and no joint on a face), else within the box: strictly
        # (then the clip below changes nothing), else within the 1e-12 of the test
        act_tol = _ACT_TOL * max(max(map(abs, hi_f)) + max(map(abs, lo_f)), 1.0)
        far = min(map(_sub, hi_f, cl)) > act_tol and min(map(_sub, cl, lo_f)) > act_tol
        inside = far or not (any(map(_lt, cl, lo_f)) or any(map(_gt, cl, hi_f)))
        lo_l = hi_l = None
        ok = inside
        if not inside:
            lo_l = [v - 1e-12 for v in lo_f]
            hi_l = [v + 1e-12 for v in hi_f]
            ok = not (any(map(_lt, cl, lo_l)) or any(map(_gt, cl, hi_l)))
        self._projection = x if ok else None  # (within the box: the answer without the rows)
        if ok and have_rows:
            ok = bool((G.dot(x) <= h_tol).all())
        qps = [False] * nlev
        if not ok:
            if lo_l is None:
                lo_l = [v - 1e-12 for v in lo_f]
                hi_l = [v + 1e-12 for v in hi_f]
            # pass 2: each level's answer within the box and the rows, from the point of
            # the box nearest q̇ = 0; whether the box holds q̇ = 0 (within the 1e-12 of its
            # test: the largest lo_i − 1e-12 is max(lo) − 1e-12, rounding being monotone)
            start_zero = max(lo_f) - 1e-12 <= -1e-12 and min(hi_f) + 1e-12 >= 1e-12
            x = np.zeros(n) if start_zero else np.minimum(np.maximum(lo, 0.0), hi)
            for k, (A, b, sw) in enumerate(lv):
                part = parts[k]
                if part is None:
                    continue
                x, qps[k] = self._solve_level(A, b, sw, part, x, start_zero, lam2, k + 1 < nlev, lo, hi,
                                              lo_l, hi_l, G, h, h_tol, n, fallback)
                start_zero = False
        # q̇ clipped into the box, and the joints on a face of it (within _ACT_TOL of the
        # box's span): on Python floats (a few joints; cheaper than numpy's calls)
        if ok and inside:
            xl = cl  # (the first pass's answer, strictly inside: the clip is the identity)
        else:
            xl = list(map(min, map(max, x.tolist(), lo_f), hi_f))
            x = np.array(xl)
        res = _residuals(lv, x) if stacked is None else _stacked_residuals(stacked, x)
        # (the first pass's answer, far from every face: no joint on one)
        box_active = shared_zeros(n, dtype=bool) if ok and far else self._box_active(xl, lo_f, hi_f, act_tol)
        rows_active = (G.dot(x) >= h - _ACT_TOL * (1.0 + np.abs(h))) if have_rows else _NO_ROWS
        return _owned_result(x, res, self._frozen(qps, bool), self._frozen(freedom, int), lo, hi,
                             box_active, rows_active, relaxed, self.backend)

    def _box_active(self, xl: list[float], lo_f: list[float], hi_f: list[float], tol: float) -> np.ndarray:
        """The joints within ``_ACT_TOL · max(|hi| + |lo|, 1)`` of a face of the box (read-only
        bool (n,)): none when every joint is farther than the largest of these tolerances
        (``tol``, `_ACT_TOL` · max(max|hi| + max|lo|, 1)) from both faces (two passes on
        floats), else joint by joint."""
        if min(map(_sub, hi_f, xl)) > tol and min(map(_sub, xl, lo_f)) > tol:
            return shared_zeros(len(xl), dtype=bool)
        return self._frozen([min(u - v, v - w) <= _ACT_TOL * max(abs(u) + abs(w), 1.0)
                             for v, w, u in zip(xl, lo_f, hi_f, strict=True)], bool)

    def _frozen(self, values: list, dtype: type) -> np.ndarray:
        """``values`` as a read-only array, one kept per distinct list (a cascade sees few)."""
        key = (dtype, tuple(values))
        a = self._kept.get(key)
        if a is None:
            if len(self._kept) > 256:
                self._kept.clear()
            base: np.ndarray = np.array(values, dtype=dtype)
            base.setflags(write=False)
            a = self._kept[key] = base.view()  # (a view: numpy refuses to make it writeable)
        return a

    def residuals_without_rows(self, levels: Sequence[tuple[np.ndarray, np.ndarray, np.ndarray | None]],
                               *, limits: Limits | Chain | None, q: np.ndarray | None,
                               qd_prev: np.ndarray | None, dt: float | None) -> np.ndarray:
        """Each level's residual had the last `solve_validated` of these ``levels`` and
        arguments had no extra rows (the box alone): from that solve's null-space projection
        when it lies within the box (it is then that answer), else by solving again."""
        x = self._projection
        if x is None:
            return self.solve_validated(levels, limits=limits, q=q, qd_prev=qd_prev, dt=dt).residuals
        lo, hi = self.box(levels[0][0].shape[1], limits, q, qd_prev, dt)
        return _residuals(levels, np.minimum(np.maximum(x, lo), hi))

    @staticmethod
    def _gradient(A, b, sw, M, Z, x, x_zero, lam2) -> np.ndarray:
        """−f of a level at the answer so far x: ``Mᵀ W^{1/2}(b − A x) − λ² Zᵀx``."""
        rhs = b if x_zero else b - A.dot(x)
        if sw is not None:
            rhs = rhs * sw
        g = M.T.dot(rhs)
        if lam2 and not x_zero:
            g -= lam2 * (x if Z is None else Z.T.dot(x))
        return g

    def _solve_level(self, A, b, sw, part, x, x_zero, lam2, more, lo, hi, lo_l, hi_l, G, h, h_tol, n,
               fallback) -> tuple[np.ndarray, bool]:
        """One level of the second pass from the answer so far x: ``(x', a QP was needed)``.

        The unconstrained minimiser when it satisfies the box and the rows; else a level
        with one free direction takes its minimiser clipped to the interval left on that
        line, a level with ``more`` levels after it whose minimisers form a line (V has one
        column) takes the line's least-norm point inside the box and the rows, and anything
        else the backend's QP."""
        Z, M, H, V = part
        if type(H) is float:  # (a level with one free direction keeps its 1×1 H as a float)
            H = np.array([[H]])
        r = H.shape[0]
        g = self._gradient(A, b, sw, M, Z, x, x_zero, lam2)
        z = _spd_solve(H, g)
        cand = x + (z if Z is None else Z.dot(z))
        cl = cand.tolist()
        ok = not (any(map(_lt, cl, lo_l)) or any(map(_gt, cl, hi_l)))
        if ok and h.size:
            ok = bool((G.dot(cand) <= h_tol).all())
        if ok:
            return cand, False
        if r == 1:
            # a QP in one unknown: its unconstrained minimiser clipped to the interval the box
            # and the rows leave along the one free direction
            v = Z[:, 0] if Z is not None else np.ones(1)
            seg = _segment(x, v, lo, hi, G, h)
            if seg is not None:
                return x + v * min(max(float(z[0]), seg[0]), seg[1]), True
        elif more and V is not None and V.shape[1] == 1:
            # the level's minimisers are a line through cand (its rows do not see the
            # direction v): where the line crosses the box and the rows, its point of least
            # norm (the damping's choice) is the level's answer
            v = V[:, 0] if Z is None else Z @ V[:, 0]
            seg = _segment(cand, v, lo, hi, G, h)
            if seg is not None:
                return cand + v * min(max(-float(v @ cand), seg[0]), seg[1]), True
        try:
            z = self._level_qp(H, -g, x, Z, lo, hi, G, h, n, r)
        except _Infeasible:
            if fallback is None:
                raise
            z = fallback - x
        return x + (z if Z is None else Z.dot(z)), True

    # ------------------------------------------------------------------ pieces
    def _lam2_eye(self, r: int) -> np.ndarray:
        """λ²I (r, r), kept per size."""
        e = self._eyes.get(r)
        if e is None:
            e = self._eyes[r] = self.damping**2 * np.eye(r)
        return e

    @staticmethod
    def _level(L, k):
        if isinstance(L, Level):
            A, b, w = L.A, L.b, L.weights
        else:
            try:
                A, b, *rest = L
            except (TypeError, ValueError):
                raise InputError(f"level {k} must be a Level or (A, b[, weights]), got {L!r}"[:300],
                                 argument="levels", value=L) from None
            w = rest[0] if rest else None
        A = np.asarray(A, dtype=float)
        b = np.asarray(b, dtype=float)
        if A.ndim != 2 or b.shape != (A.shape[0],):
            raise InputError(f"level {k}: A must be (m, n) and b (m,), got {A.shape} and {b.shape}",
                             argument="levels", value=(A.shape, b.shape))
        sw = None if w is None else np.sqrt(np.broadcast_to(np.asarray(w, dtype=float),
                                                                            (A.shape[0],)))
        finite = np.all(np.isfinite(A)) and np.all(np.isfinite(b))
        if not (finite and (sw is None or np.all(np.isfinite(sw)))):
            raise InputError(f"level {k}: A, b and the weights must be finite", argument="levels",
                             value=k)
        return A, b, sw

    @staticmethod
    def _rows(extra, n):
        if extra is None:
            return np.zeros((0, n)), np.zeros(0)
        try:
            G, h = extra
            G = np.asarray(G, dtype=float).reshape(-1, n)
            h = np.asarray(h, dtype=float).reshape(-1)
        except (TypeError, ValueError):
            raise InputError(f"extra_inequalities must be (G (k, {n}), h (k,))",
                             argument="extra_inequalities", value=extra) from None
        if G.shape[0] != h.shape[0] or not np.all(np.isfinite(G)) or np.any(np.isnan(h)):
            raise InputError(f"extra_inequalities: G {G.shape} and h {h.shape} must agree and be finite",
                             argument="extra_inequalities", value=extra)
        return G, h

    def _relaxation(self, lo, hi, G, h) -> tuple[np.ndarray, np.ndarray]:
        """The slack s ≥ 0 (least squares) with G q̇ ≤ h + s feasible in the box, and a q̇
        of the box that meets the relaxed rows."""
        n = lo.shape[0]
        m = h.shape[0]
        # [q̇; s]: min ½‖s‖² + ½ε‖q̇‖², G q̇ − s ≤ h, box, s ≥ 0
        H = np.diag(np.concatenate([np.full(n, 1e-6), np.ones(m)]))
        Gs = np.hstack([G, -np.eye(m)])
        lo2 = np.concatenate([lo, np.zeros(m)])
        hi2 = np.concatenate([hi, np.full(m, _BIG)])
        sol = self._qp(H, np.zeros(n + m), lo2, hi2, Gs, h)
        if sol is None:
            raise SolverError("the extra rows could not be relaxed to meet the joint-velocity box",
                              status="infeasible")
        qd = np.minimum(np.maximum(sol[:n], lo), hi)
        # the slack the clipped q̇ needs, with a little room for the next solve's tolerance
        slack = np.maximum(np.maximum(sol[n:], G @ qd - h), 0.0)
        return slack * (1.0 + 1e-9) + 1e-9, qd

    def _level_qp(self, H, f, x, Z, lo, hi, G, h, n, r) -> np.ndarray:
        """The level's QP in z: min ½zᵀHz + fᵀz s.t. lo ≤ x + Z z ≤ hi, G(x + Z z) ≤ h."""
        if Z is None:
            sol = self._qp(H, f, lo - x, hi - x, G, h - G @ x)
        else:
            C = np.vstack([Z, -Z, G @ Z]) if h.size else np.vstack([Z, -Z])
            d = np.concatenate([hi - x, x - lo, h - G @ x]) if h.size else np.concatenate([hi - x, x - lo])
            keep = d < 0.5 * _BIG
            sol = self._qp(H, f, None, None, C[keep], np.maximum(d[keep], 0.0))
        if sol is None:
            # x itself (z = 0) is feasible for every level after the first: keep it
            if Z is not None:
                return np.zeros(r)
            raise _Infeasible
        return sol

    def _qp(self, H, f, lb, ub, C, d) -> np.ndarray | None:
        """min ½xᵀHx + fᵀx s.t. lb ≤ x ≤ ub (optional), C x ≤ d; None when infeasible/failed."""
        r = H.shape[0]
        if self.backend == "daqp":
            import daqp

            if lb is not None:
                bu = np.concatenate([np.minimum(ub, _BIG), d])
                bl = np.concatenate([np.maximum(lb, -_BIG), np.full(d.shape[0], -_BIG)])
            else:
                bu = np.ascontiguousarray(d, dtype=float)
                bl = np.full(d.shape[0], -_BIG)
            sense = np.zeros(bu.shape[0], dtype=np.int32)
            Cc = np.array(C, dtype=float) if C.shape[0] else np.zeros((0, r))  # (daqp needs a writable copy)
            x, _, flag, _ = daqp.solve(np.ascontiguousarray(H), np.ascontiguousarray(f, dtype=float), Cc,
                                       bu, bl, sense)
            return np.asarray(x, dtype=float) if flag in (1, 2) else None
        if self.backend == "exact":
            lo_ = np.full(r, -np.inf) if lb is None else lb
            hi_ = np.full(r, np.inf) if ub is None else ub
            return qp_via_dual(H, -f, lo_, hi_, C, d)
        import qpsolvers

        kw: dict[str, Any] = {}
        if lb is not None:
            kw.update(lb=lb, ub=ub)
        try:
            x = qpsolvers.solve_qp(H, f, C if C.shape[0] else None, d if C.shape[0] else None,
                                   solver=self.backend, **kw)
        except Exception:  # a backend's own exception types: reported as a failed level
            return None
        return None if x is None else np.asarray(x, dtype=float)


def _finite(res: CascadeResult) -> CascadeResult:
    """``res`` when its q̇ is finite, else SolverError (finite levels whose arithmetic
    overflowed). The answers of `PriorityCascade._one_level` and `_one_level_clear` are
    finite by their test against the box (NaN passes no comparison)."""
    if not math.isfinite(sum(res.qd.tolist())):
        raise SolverError("the priority cascade gave a non-finite q̇ (task rows too large?)", status="failed")
    return res


def _residuals(levels, x: np.ndarray) -> np.ndarray:
    """‖W_k^{1/2}(A_k q̇ − b_k)‖ of every level at q̇ = x."""
    res = []
    for A, b, sw in levels:
        d = A.dot(x) - b
        if sw is not None:
            d *= sw
        res.append(math.sqrt(d.dot(d)))
    return np.array(res)


def _stacked_residuals(stacked: tuple[np.ndarray, np.ndarray, tuple[int, ...]], x: np.ndarray) -> np.ndarray:
    """`_residuals` of unweighted levels stacked in one array (see `solve_validated`):
    ``d = A_all x − b_all`` once, then each level's ‖d‖ over its rows (one reduction over
    the levels' row blocks when none is empty)."""
    A, b, ends = stacked
    d = A.dot(x) - b
    starts = _STARTS.get(ends)
    if starts is None:
        if len(_STARTS) > 64:
            _STARTS.clear()
        firsts = (0, *ends[:-1])
        starts = _STARTS[ends] = (np.array(firsts, dtype=np.intp)
                                  if all(i < j for i, j in zip(firsts, ends, strict=True)) else False)
    if starts is not False:
        return np.sqrt(np.add.reduceat(d * d, starts))
    out = []
    i = 0
    for j in ends:
        di = d[i:j]
        out.append(math.sqrt(di.dot(di)))
        i = j
    return np.array(out)


#: each ``ends`` of `_stacked_residuals`: its levels' first rows, or False when a level is empty
_STARTS: dict[tuple[int, ...], Any] = {}


def _spd_solve(H: np.ndarray, g: np.ndarray) -> np.ndarray:
    """H⁻¹g for a symmetric positive (semi)definite H (exactly symmetric: MᵀM + λ²I):
    Cholesky (LAPACK ``dposv``), the least-squares answer where H is singular (λ = 0 and
    rank-deficient rows)."""
    # (H is exactly symmetric — numpy forms MᵀM with one symmetric rank-k update — so its
    # transpose, a Fortran-ordered view, holds the same numbers: LAPACK takes it as it is)
    c, z, info = _dposv(H.T, g)
    if info == 0:
        return z
    return np.linalg.lstsq(H, g, rcond=None)[0]


def _segment(c: np.ndarray, v: np.ndarray, lo: np.ndarray, hi: np.ndarray, G: np.ndarray,
             h: np.ndarray) -> tuple[float, float] | None:
    """``(t_min, t_max)``: the t with ``lo ≤ c + v t ≤ hi`` and ``G (c + v t) ≤ h``, or None
    when there is none (on Python floats: a few joints and rows)."""
    tmin, tmax = -math.inf, math.inf
    a = v.tolist()
    lo_d = (lo - c).tolist()
    hi_d = (hi - c).tolist()
    if h.size:
        a += (G @ v).tolist()
        lo_d += [-math.inf] * h.shape[0]
        hi_d += (h - G @ c).tolist()
    for ai, li, ui in zip(a, lo_d, hi_d, strict=True):
        if ai > _SEG_EPS:
            tmin = max(tmin, li / ai)
            tmax = min(tmax, ui / ai)
        elif ai < -_SEG_EPS:
            tmin = max(tmin, ui / ai)
            tmax = min(tmax, li / ai)
        elif li > 1e-12 or ui < -1e-12:
            return None
    return (tmin, tmax) if tmin <= tmax else None


_SEG_EPS = 1e-12  # a direction this small along a bound counts as parallel to it


def _null_space(M: np.ndarray, tolerance: float) -> np.ndarray:
    """An orthonormal basis (r, r − rank) of the null space of M (m, r): the right singular
    vectors whose singular values are below ``tolerance · max(1, σ_max)``.

    Where M has full rank with room to spare (the common case), a QR factorisation answers
    at a fraction of an SVD's cost (`_null_space_qr`); the SVD decides the rank otherwise."""
    m, r = M.shape
    if m == 0:
        return np.eye(r)
    if r == 1:  # one column: its norm is its one singular value
        s1 = math.sqrt(float(M[:, 0].dot(M[:, 0])))
        return np.ones((1, 0 if s1 > tolerance * max(1.0, s1) else 1))
    Z = _null_space_qr(M, tolerance)
    if Z is not None:
        return Z
    _, s, vt = thin_svd(M, full=True)
    tol = tolerance * max(1.0, float(s[0]) if s.size else 0.0)
    rank = int(np.count_nonzero(s > tol))
    return vt[rank:].T


def _null_space_qr(M: np.ndarray, tolerance: float) -> np.ndarray | None:
    """`_null_space` of an M (m, r) of full rank min(m, r), from one QR factorisation
    (LAPACK ``dgeqrf``): of Mᵀ = Q R when m < r — the null space is then spanned by the
    last r − m columns of the full Q (``dorgqr``) — and of M = Q R when m ≥ r (no null
    space). None when the rank is not certain: the singular values of M are those of the
    triangle R (p × p, p = min(m, r)), and

        σ_min ≥ 1/‖R⁻¹‖_F,        σ_max ≤ ‖R‖_F,

    so ``‖R⁻¹‖_F · tolerance · max(1, ‖R‖_F) < 1`` proves every singular value above the
    SVD's threshold ``tolerance · max(1, σ_max)``: both answers then span the same space
    (‖R‖_F = ‖M‖_F; ‖R⁻¹‖_F is bounded by the norm of the whole p × p block that holds
    R⁻¹, whose part below the diagonal keeps the Householder vectors: they only enlarge
    it, so the test stays a proof)."""
    m, r = M.shape
    wide = m < r
    if wide:  # Mᵀ in the first m columns of the r × r array dorgqr will fill with Q (in place)
        a = np.empty((r, r), order="F")
        a[:, :m] = M.T
        qr, tau, _, info = _dgeqrf(a[:, :m], overwrite_a=1)
        p = m
    else:
        qr, tau, _, info = _dgeqrf(M)
        p = r
    inv, info2 = _dtrtri(qr[:p, :p])
    if info != 0 or info2 != 0:
        return None
    f_inv = inv.ravel("K")
    f_r = M.ravel("K")  # (‖R‖_F = ‖M‖_F: Q is orthogonal)
    if not tolerance * tolerance * float(f_inv.dot(f_inv)) * max(1.0, float(f_r.dot(f_r))) < 1.0:
        return None  # (NaN: not proved either)
    if not wide:
        return _no_columns(r)
    q, _, info3 = _dorgqr(a, tau, overwrite_a=1)
    if info3 != 0:  # pragma: no cover - LAPACK's argument check
        return None
    return q[:, m:]


def _owned_result(qd, residuals, qps, freedom, lo, hi, box_active, rows_active, relaxed,
                  backend) -> CascadeResult:
    """The `CascadeResult` of the cascade's own fresh arrays, frozen in place rather than
    copied (``qps`` and ``freedom`` read-only already; the box is the step's own, frozen by
    `PriorityCascade.solve_validated`, or the bound cache's read-only arrays; freezing an
    array that is read-only already changes nothing)."""
    for a in (qd, residuals, box_active, rows_active, relaxed, lo, hi):
        a.setflags(write=False)
    r = object.__new__(CascadeResult)
    object.__setattr__(r, "__dict__", {"qd": qd, "residuals": residuals, "qps": qps, "freedom": freedom,
                                       "lower": lo, "upper": hi, "box_active": box_active,
                                       "rows_active": rows_active, "relaxed": relaxed, "backend": backend})
    return r
