"""Inverse velocity as a quadratic program, with joint position, velocity and
acceleration limits.

The QP, over q̇ (n,):

    minimise    ½‖W_x^{1/2}(J q̇ − ξ)‖² + ½λ² q̇ᵀ W_q q̇ + ½μ‖q̇ − z(q)‖²
    subject to  l ≤ q̇ ≤ u          (velocity, position and acceleration bounds)
                G q̇ ≤ h            (optional extra rows, e.g. mink's collision limits)

i.e. P = JᵀW_xJ + λ²W_q + μI and c = −JᵀW_xξ − μz. The box [l, u] is the
intersection, per joint, of

* the velocity limit: −vmax ≤ q̇ ≤ vmax;
* the position limit turned into a velocity bound for the step dt with a margin m and
  a braking term that respects the acceleration limit a = amax: with the distance
  d = upper − m − q (resp. q − lower − m), q̇ ≤ v_stop(d) (resp. q̇ ≥ −v_stop(d)), where
  v_stop(d) is the largest speed from which braking by a·dt per step still stops within
  d. Braking from v = (k + f)·a·dt (k integer, 0 ≤ f < 1) covers
  a·dt²·((k + 1)f + k(k + 1)/2), so with u = d/(a·dt²), k = ⌊(√(8u + 1) − 1)/2⌋,
  f = min((u − k(k + 1)/2)/(k + 1), 1): v_stop = (k + f)·a·dt. This is the discrete
  form of √(2a·d); for small d it is d/dt (stop exactly at the limit this step), and it
  is consistent with the acceleration bound (from v_stop(d) the next step's bound is
  exactly v_stop − a·dt), so a joint braking into a limit never makes the box empty.
  Beyond a limit (d < 0) the bound is d/dt (move back). Without ``dt`` the continuous
  √(2a·d) is used;
* the acceleration limit given the previous command: |q̇ − q̇_prev| ≤ amax·dt.

When the bounds conflict (e.g. moving too fast toward a limit to stop within the
acceleration limit), priority is velocity > position > acceleration: the box becomes the
point of the higher-priority box nearest to the lower-priority one, and the result says
so in ``info["conflicts"]``.

Before any backend runs, the unconstrained minimiser P⁻¹b (the DLS solution) is tried:
when it lies inside the box (and satisfies G q̇ ≤ h) it is the optimum
(``info["status"] == "unconstrained"``). For a box-only problem on the default backend a
few primal active-set steps follow (:func:`_box_active_set`); their answer is accepted
only with a KKT certificate, so it is the exact optimum (``"active-set"``); when they do
not settle within four steps OSQP answers.

The default backend is OSQP kept **warm**: the problem is set up once with a fixed
sparsity pattern (P upper-triangular dense, A = [I; G]) and every later call only
updates P's values, q, l, u (and A's values when G is given), then solves, warm-started
from the previous solution. Re-setup happens only when the structure changes (n, or
the number of extra rows). Tolerances are explicit (1e-7 with solution polishing, so the
active set is solved exactly), and the final q̇ is clipped into [l, u] when it is outside
by less than ``tolerance``: limits hold to 1e-6. Other backends (``"daqp"``,
``"quadprog"``, ``"proxqp"``, …) are called through :func:`qpsolvers.solve_qp`.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.linalg import lapack as _lapack

from .errors import InputError, SolverError
from .solvers import (
    DLS,
    Limits,
    Solver,
    SolveResult,
    _check_finite,
    _check_problem,
    _LazySigma,
    _objective,
    _positive,
)

__all__ = ["QP", "joint_velocity_bounds", "VelocityBounds"]

_dposv = _lapack.dposv
_dot = np.dot
_zeros = np.zeros
_BIG = 1e15  # stands for an absent (infinite) limit in the bound arithmetic
_CTOL = 1e-9  # conflicts smaller than this are rounding (resolved, not reported)
_NONE, _VEL, _POS, _ACC = 0, 1, 2, 3
_KIND = {_VEL: "velocity", _POS: "position", _ACC: "acceleration"}

_OSQP_DEFAULTS = dict(
    verbose=False,
    eps_abs=1e-7,
    eps_rel=1e-7,
    eps_prim_inf=1e-9,
    eps_dual_inf=1e-9,
    polishing=True,
    polish_refine_iter=3,
    check_termination=5,
    max_iter=4000,
    warm_starting=True,
)


class VelocityBounds:
    """Per-joint velocity box for one step (see :func:`joint_velocity_bounds`).

    Attributes:
        lower, upper: (n,) bounds on q̇ [rad/s or m/s].
        source_lower, source_upper: (n,) int codes of the limit that sets each bound
            (0 none, 1 velocity, 2 position, 3 acceleration).
        conflicts: tuple of (joint, kinds) where bounds conflicted and were resolved by
            priority (velocity > position > acceleration).
    """

    __slots__ = ("lower", "upper", "source_lower", "source_upper", "conflicts")

    def __init__(self, lower, upper, source_lower, source_upper, conflicts):
        self.lower = lower
        self.upper = upper
        self.source_lower = source_lower
        self.source_upper = source_upper
        self.conflicts = conflicts


def _stop_speed(D, adt, inv_adt2, inv_dt):
    """Largest speed toward a limit at distance D (≥ 0) [rad or m] from which the joint
    can still stop before it, braking by at most a·dt per step of dt:

    the braking sequence v, v − a·dt, v − 2a·dt, … (down to 0) covers
    D(v) = a·dt²·((k + 1)·f + k(k + 1)/2) for v = (k + f)·a·dt (k integer, 0 ≤ f < 1);
    this inverts it exactly: u = D/(a·dt²), k = ⌊(√(8u + 1) − 1)/2⌋,
    f = min((u − k(k + 1)/2)/(k + 1), 1), v = (k + f)·a·dt. It is the discrete form of
    √(2a·D) and includes D/dt (k = 0: stop exactly at the limit within this step), and it
    is consistent with the acceleration bound: from v the next step's bound is ≥ v − a·dt.
    For D < 0 (beyond the limit) it returns D/dt (move back).
    """
    Dp = np.maximum(D, 0.0)
    u = Dp * inv_adt2
    k = np.floor(0.5 * (np.sqrt(8.0 * u + 1.0) - 1.0))
    f = np.minimum((u - 0.5 * k * (k + 1.0)) / (k + 1.0), 1.0)
    return (k + f) * adt + np.minimum(D, 0.0) * inv_dt


class _BoundCache:
    """Precomputed arrays for the bound arithmetic of one (limits, dt, margin).

    Position bounds are computed on stacked (2n,) arrays, upper side first, lower side
    mirrored: D = [upper − m − q; q − lower − m], bound = min(stop speed(D), vmax); the
    lower bound is minus the second half. An absent position limit is a large finite
    number (no inf − inf); an absent acceleration limit is a huge finite one (the stop
    speed becomes D/dt).
    """

    __slots__ = ("src", "dt", "n", "limits", "vmax", "nvmax", "hi_lim", "lo_lim", "amax_dt",
                 "has_pos", "has_acc", "inv_dt", "lim2", "sgn2", "idx2", "vmax2", "adt", "inv_adt2",
                 "adt2", "inv_adt22", "two_a", "dstar2", "vmax_l", "amax_dt_l")

    def __init__(self, src, limits: Limits, dt, margin):
        self.src, self.dt = src, dt
        self.limits = limits
        n = self.n = limits.vmax.shape[0]
        self.vmax = np.minimum(limits.vmax, _BIG)
        self.nvmax = -self.vmax
        self.vmax_l = self.vmax.tolist()
        self.hi_lim = np.where(np.isfinite(limits.upper), limits.upper - margin, _BIG)
        self.lo_lim = np.where(np.isfinite(limits.lower), limits.lower + margin, -_BIG)
        afin = np.isfinite(limits.amax)
        a = np.where(afin, limits.amax, 1e200)
        self.two_a = 2.0 * a
        self.has_pos = bool(np.any(np.isfinite(limits.upper)) or np.any(np.isfinite(limits.lower)))
        self.has_acc = bool(np.any(afin))
        self.lim2 = np.concatenate([self.hi_lim, -self.lo_lim])
        self.sgn2 = np.concatenate([np.ones(n), -np.ones(n)])
        self.idx2 = np.concatenate([np.arange(n), np.arange(n)])
        self.vmax2 = np.concatenate([self.vmax, self.vmax])
        if dt is None:
            self.amax_dt = self.inv_dt = self.adt = self.inv_adt2 = self.adt2 = self.inv_adt22 = None
            self.amax_dt_l = None
            self.dstar2 = None
        else:
            self.amax_dt = np.where(afin, a * dt, _BIG)
            self.amax_dt_l = self.amax_dt.tolist()
            self.inv_dt = 1.0 / dt
            self.adt = a * dt
            self.inv_adt2 = 1.0 / (a * dt * dt)
            self.adt2 = np.concatenate([self.adt, self.adt])
            self.inv_adt22 = np.concatenate([self.inv_adt2, self.inv_adt2])
            # the distance from which a joint at full speed can still stop: farther than
            # this from both limits, the velocity limit is the bound (no stop speed needed)
            r = self.vmax / self.adt
            k = np.floor(r)
            f = r - k
            dstar = self.adt * dt * ((k + 1.0) * f + 0.5 * k * (k + 1.0))
            dstar = np.where(limits.vmax < _BIG, dstar * (1.0 + 1e-9) + 1e-12, np.inf)
            self.dstar2 = np.concatenate([dstar, dstar])
        for arr in (self.vmax, self.nvmax):  # returned as the box when no other bound acts
            arr.setflags(write=False)


def _box(bc: _BoundCache, q, qd_prev):
    """Fast path of :func:`_bounds`: (lo, hi, conflicts) without the sources."""
    n = bc.n
    if q is not None and bc.has_pos and bc.inv_dt is not None:
        D = bc.lim2 - q[bc.idx2] * bc.sgn2
        if (D < bc.dstar2).any():  # some joint is near a limit
            U = np.minimum(_stop_speed(D, bc.adt2, bc.inv_adt22, bc.inv_dt), bc.vmax2)
            hi = U[:n]
            lo = -U[n:]
            if float((hi - lo).min()) < 0.0:
                return _careful(bc, q, qd_prev)  # conflicting bounds: the careful path
        else:
            lo, hi = bc.nvmax, bc.vmax
    elif q is not None and bc.has_pos:
        return _careful(bc, q, qd_prev)
    else:
        lo, hi = bc.nvmax, bc.vmax
    if qd_prev is not None and bc.amax_dt is not None and bc.has_acc:
        nlo = np.maximum(lo, qd_prev - bc.amax_dt)
        nhi = np.minimum(hi, qd_prev + bc.amax_dt)
        if float((nhi - nlo).min()) < 0.0:
            return _careful(bc, q, qd_prev)
        lo, hi = nlo, nhi
    return lo, hi, ()


def _sources(bc: _BoundCache, qd_prev, lo, hi, held) -> tuple[str, ...]:
    """Kinds of limit that set the active bounds; ``held[i]`` is +1 / −1 / 0 for a joint
    at its upper / lower bound / free. The box values are exact copies of the velocity
    limit, the acceleration bound or a position bound, so equality identifies them
    (velocity first, then acceleration, else position)."""
    kinds = set()
    vmax = bc.vmax_l
    acc = qd_prev is not None and bc.amax_dt is not None and bc.has_acc
    lol = hil = qdl = None
    for i, st in enumerate(held):
        if not st:
            continue
        if lol is None:
            lol, hil = lo.tolist(), hi.tolist()
            qdl = qd_prev.tolist() if acc else None
        v = hil[i] if st > 0 else lol[i]
        if v == st * vmax[i]:
            kinds.add(_VEL)
        elif acc and v == qdl[i] + st * bc.amax_dt_l[i]:
            kinds.add(_ACC)
        else:
            kinds.add(_POS)
    return tuple(_KIND[k] for k in (_VEL, _POS, _ACC) if k in kinds)


def _careful(bc, q, qd_prev):
    lo, hi, _, _, conflicts = _bounds(bc, q, qd_prev, False)
    return lo, hi, conflicts


def _bounds(cache: _BoundCache, q, qd_prev, want_sources: bool):
    """The velocity box (lo, hi), its sources and the conflicts; see the module docstring."""
    lo = cache.nvmax
    hi = cache.vmax
    conflicts = []
    slo = shi = None
    if want_sources:
        slo = np.where(cache.vmax < _BIG, _VEL, _NONE)
        shi = slo.copy()
    if q is not None and cache.has_pos:
        dup = cache.hi_lim - q
        dlo = q - cache.lo_lim
        if cache.inv_dt is not None:
            pu = _stop_speed(dup, cache.adt, cache.inv_adt2, cache.inv_dt)
            pl = -_stop_speed(dlo, cache.adt, cache.inv_adt2, cache.inv_dt)
        else:  # no step: the continuous braking bound √(2a·d), and no motion beyond a limit
            pu = np.sqrt(cache.two_a * np.maximum(dup, 0.0))
            pl = -np.sqrt(cache.two_a * np.maximum(dlo, 0.0))
        bad = pl > pu
        if bad.any():
            mid = 0.5 * (pl + pu)
            pl = np.where(bad, mid, pl)
            pu = np.where(bad, mid, pu)
            conflicts += [(int(i), ("position",)) for i in np.flatnonzero(bad & (pl - pu > _CTOL))]
        nlo = np.maximum(lo, pl)
        nhi = np.minimum(hi, pu)
        if want_sources:
            slo = np.where(pl > lo, _POS, slo)
            shi = np.where(pu < hi, _POS, shi)
        bad = nlo > nhi
        big = bad & (nlo - nhi > _CTOL)
        if bad.any():  # the position box lies outside the velocity box: keep the nearest velocity
            pt = np.where(pl > hi, hi, lo)
            nlo = np.where(bad, pt, nlo)
            nhi = np.where(bad, pt, nhi)
            if want_sources:
                slo = np.where(bad, _VEL, slo)
                shi = np.where(bad, _VEL, shi)
            conflicts += [(int(i), ("velocity", "position")) for i in np.flatnonzero(big)]
        lo, hi = nlo, nhi
    if qd_prev is not None and cache.amax_dt is not None and cache.has_acc:
        al = qd_prev - cache.amax_dt
        au = qd_prev + cache.amax_dt
        nlo = np.maximum(lo, al)
        nhi = np.minimum(hi, au)
        bad = nlo > nhi
        big = bad & (nlo - nhi > _CTOL)
        if want_sources:
            pt_src = np.where(al > hi, shi, slo)  # the bound of the kept box at the nearest point
            slo = np.where(bad, pt_src, np.where(al > lo, _ACC, slo))
            shi = np.where(bad, pt_src, np.where(au < hi, _ACC, shi))
        if bad.any():  # cannot reach the box within the acceleration limit: nearest point
            pt = np.where(al > hi, hi, lo)
            nlo = np.where(bad, pt, nlo)
            nhi = np.where(bad, pt, nhi)
            conflicts += [(int(i), ("acceleration",)) for i in np.flatnonzero(big)]
        lo, hi = nlo, nhi
    return lo, hi, slo, shi, tuple(conflicts)


def joint_velocity_bounds(limits, *, q=None, qd_prev=None, dt=None, margin: float = 0.0,
                          n: int | None = None) -> VelocityBounds:
    """The per-joint box on q̇ for one step from velocity, position and acceleration
    limits (see :mod:`ratectl.qp`). ``limits`` is a Chain or :class:`Limits`; ``q``
    (n,) enables the position bounds, ``qd_prev`` (n,) with ``dt`` [s] the acceleration
    bounds; ``margin`` [rad or m] keeps that far from the position limits."""
    if n is None:
        n = np.asarray(limits.vmax).shape[0]
    lim = Limits.of(limits, n)
    if dt is not None:
        dt = _positive("dt", dt)
    margin = _positive("margin", margin, allow_zero=True)
    q = _vec("q", q, n)
    qd_prev = _vec("qd_prev", qd_prev, n)
    cache = _BoundCache(limits, lim, dt, margin)
    lo, hi, slo, shi, conflicts = _bounds(cache, q, qd_prev, True)
    return VelocityBounds(np.array(lo, dtype=float), np.array(hi, dtype=float), slo, shi, conflicts)


def _vec(name, v, n):
    if v is None:
        return None
    a = np.asarray(v, dtype=float)
    if a.shape != (n,) or not np.all(np.isfinite(a)):
        raise InputError(f"{name} must be a finite ({n},) vector, got shape {a.shape}", argument=name,
                         value=v)
    return a


class _WarmOSQP:
    """One OSQP instance set up for a fixed structure (n, extra rows k) and updated in place."""

    def __init__(self, n, k, P, c, G, h, lo, hi, settings):
        import osqp
        import scipy.sparse as sp

        self.n, self.k = n, k
        r, cidx = np.triu_indices(n)
        order = np.lexsort((r, cidx))  # CSC order: by column, then row
        self.pr, self.pc = r[order], cidx[order]
        Pm = sp.csc_matrix((P[self.pr, self.pc], (self.pr, self.pc)), shape=(n, n))
        if k:
            A = np.vstack([np.eye(n), G])
            # CSC of a dense (n+k)×n with identity on top: column j holds row j, then rows n..n+k-1
            ar = np.concatenate([np.concatenate([[j], n + np.arange(k)]) for j in range(n)])
            ac = np.repeat(np.arange(n), k + 1)
            self.ar, self.ac = ar, ac
            Am = sp.csc_matrix((A[ar, ac], (ar, ac)), shape=(n + k, n))
            l = np.concatenate([lo, np.full(k, -np.inf)])
            u = np.concatenate([hi, h])
        else:
            Am = sp.identity(n, format="csc")
            l, u = lo, hi
        self.osqp = osqp.OSQP()
        self.osqp.setup(Pm, c, Am, np.maximum(l, -1e30), np.minimum(u, 1e30), **settings)
        # the low-level solver avoids the Python wrapper's per-call bookkeeping (~15 µs)
        self._s = getattr(self.osqp, "_solver", None)
        self._lk = np.full(k, -1e30)

    def solve(self, P, c, G, h, lo, hi):
        s = self._s
        Px = P[self.pr, self.pc]
        if self.k:
            Ax = np.vstack([np.eye(self.n), G])[self.ar, self.ac]
            l = np.concatenate([lo, self._lk])
            u = np.concatenate([hi, np.minimum(h, 1e30)])
        else:
            Ax = None
            l, u = lo, hi
        if s is not None:
            s.update_data_mat(P_x=Px, P_i=None, A_x=Ax, A_i=None)
            s.update_data_vec(q=c, l=l, u=u)
            s.solve()
            info = s.info
            return s.solution.x, int(info.status_val), str(info.status), int(info.iter), \
                int(info.status_polish)
        kw = dict(Px=Px, q=c, l=l, u=u)
        if Ax is not None:
            kw["Ax"] = Ax
        self.osqp.update(**kw)
        res = self.osqp.solve(raise_error=False)
        return (res.x, int(res.info.status_val), str(res.info.status), int(res.info.iter),
                int(res.info.status_polish))


class QP(Solver):
    """Inverse velocity as a QP with joint limits (see :mod:`ratectl.qp` for the
    formulation and the bounds).

    Args:
        damping: λ, the joint-velocity regularisation (the DLS damping): with no active
            limit the QP returns exactly the DLS solution Jᵀ(JJᵀ + λ²I)⁻¹ξ.
        backend: ``"osqp"`` (default, kept warm across calls) or any solver name of
            :func:`qpsolvers.solve_qp` (``"daqp"``, ``"quadprog"``, ``"proxqp"``, …).
        margin: distance kept from the position limits [rad or m].
        task_weights, joint_weights: as for the other solvers (W_x, W_q).
        objective: optional secondary objective (``"centring"``, ``"manipulability"``
            with ``chain``, or a callable q -> desired q̇), added as ½μ‖q̇ − k·z(q)‖²;
            needs ``q=`` in :meth:`solve`.
        objective_weight: μ (small: the term trades task accuracy for the objective).
        objective_gain: k [1/s].
        chain: for the string objectives.
        fallback: on a failed solve return the DLS solution scaled into the velocity
            box (``result.fallback`` = True, ``info["error"]``) instead of raising
            :class:`SolverError`.
        tolerance: bound violation up to which q̇ is clipped back into the box (larger
            violations raise), and the distance at which a bound counts as active.
        settings: extra OSQP settings (override the defaults) or backend keywords.
        shortcut: first try the unconstrained minimiser (one Cholesky solve); when it
            satisfies every bound it is the exact optimum and the backend is not called
            (``info["status"] == "unconstrained"``). ``False`` always calls the backend.
    """

    method = "qp"
    #: the solution already respects the velocity, position and acceleration bounds (and
    #: any extra rows): the controller reports them instead of limiting q̇ again
    enforces_limits = True

    def __init__(self, *, damping: float = 0.05, backend: str = "osqp", margin: float = 0.0,
                 task_weights=None, joint_weights=None, objective=None,
                 objective_weight: float = 1e-3, objective_gain: float = 1.0, chain=None,
                 fallback: bool = False, tolerance: float = 1e-6, settings: dict | None = None,
                 shortcut: bool = True) -> None:
        super().__init__(velocity_policy="scale", task_weights=task_weights,
                         joint_weights=joint_weights)
        self.damping = _positive("damping", damping, allow_zero=True)
        self.margin = _positive("margin", margin, allow_zero=True)
        self.tolerance = _positive("tolerance", tolerance)
        self.objective_weight = _positive("objective_weight", objective_weight, allow_zero=True)
        self.objective_gain = _positive("objective_gain", objective_gain, allow_zero=True)
        self.objective = None if objective is None else _objective(objective, chain)
        self.fallback = bool(fallback)
        self.shortcut = bool(shortcut)
        if not isinstance(backend, str):
            raise InputError(f"backend must be a solver name, got {backend!r}", argument="backend",
                             value=backend)
        if backend != "osqp":
            import qpsolvers

            if backend not in qpsolvers.available_solvers:
                raise InputError(f"QP backend {backend!r} is not installed; available: "
                                 f"{sorted(qpsolvers.available_solvers)}", argument="backend",
                                 value=backend)
        self.backend = backend
        self.settings = dict(settings or {})
        self._osqp_settings = {**_OSQP_DEFAULTS, **self.settings} if backend == "osqp" else None
        self._warm: _WarmOSQP | None = None
        self._bcache: _BoundCache | None = None
        self._lam2 = self.damping**2
        self._wq = None if self._isw is None else 1.0 / self._isw**2
        self._reg: dict[int, np.ndarray] = {}
        self._pd = self._lam2 > 0 or (self.objective is not None and self.objective_weight > 0)
        self._dls = DLS(damping=max(self.damping, 1e-6), velocity_policy=None,
                        task_weights=task_weights, joint_weights=joint_weights)

    def __repr__(self) -> str:
        return f"QP(damping={self.damping!r}, backend={self.backend!r}, margin={self.margin!r})"

    def reset(self) -> None:
        """Forget the warm OSQP instance (the next call sets it up again)."""
        self._warm = None

    def solve(self, J, xi, *, limits=None, q=None, qd_prev=None, dt=None,
              extra_inequalities=None) -> SolveResult:
        """q̇ for the twist ``xi`` with the Jacobian ``J`` under the joint limits.

        Args:
            J, xi: Jacobian (m, n) and desired twist (m,).
            limits: a Chain or :class:`Limits` (None: no bounds, the QP is the DLS).
            q: joint positions (n,): enables the position bounds (and the objective).
            qd_prev: previous joint velocities (n,): with ``dt``, the acceleration bounds.
            dt: the control step [s].
            extra_inequalities: ``(G, h)`` with G (k, n) and h (k,): extra rows G q̇ ≤ h
                (e.g. collision avoidance); a change of k re-creates the OSQP instance.

        Returns:
            :class:`~ratectl.solvers.SolveResult` with ``limits_active`` naming the kinds of
            bound that hold q̇ and ``info`` = status, iterations, backend, the box
            (``lower``, ``upper``) and any ``conflicts`` resolved by priority.
        """
        J, xi = _check_problem(J, xi)
        m, n = J.shape
        if dt is not None and not (dt > 0 and math.isfinite(dt)):
            raise InputError(f"dt must be a positive step [s], got {dt!r}", argument="dt", value=dt)
        if q is not None and (type(q) is not np.ndarray or q.shape != (n,)):
            q = _vec("q", q, n)
        if qd_prev is not None and (type(qd_prev) is not np.ndarray or qd_prev.shape != (n,)):
            qd_prev = _vec("qd_prev", qd_prev, n)
        # objective ½‖W(Jq̇ − ξ)‖² + ½λ²q̇ᵀW_q q̇ (+ ½μ‖q̇ − z‖²)  →  ½q̇ᵀPq̇ − bᵀq̇
        if self._rows is not None:
            rows, mw = self._rows
            if m != mw:
                raise InputError(f"task_weights has {mw} entries but J has {m} rows",
                                 argument="task_weights", value=self.task_weights)
            Jw = J[rows] * self._sw[:, None]
            xiw = xi[rows] * self._sw
        else:
            Jw, xiw = J, xi
        reg = self._reg.get(n)
        if reg is None:
            if self._wq is not None and self._wq.shape[0] != n:
                raise InputError(f"joint_weights has {self._wq.shape[0]} entries but J has {n} "
                                 "columns", argument="joint_weights", value=self.joint_weights)
            d = np.full(n, self._lam2) if self._wq is None else self._lam2 * self._wq
            reg = self._reg[n] = np.diag(d)
        P = _dot(Jw.T, Jw) + reg
        b = _dot(xiw, Jw)
        if self.objective is not None:
            if q is None:
                raise InputError("QP with an objective needs q= (the joint positions)", argument="q",
                                 value=None)
            z = np.asarray(self.objective(q), dtype=float) * self.objective_gain
            if z.shape != (n,) or not np.all(np.isfinite(z)):
                raise InputError(f"the objective must return a finite ({n},) vector, got {z!r}",
                                 argument="objective", value=z)
            P = P + self.objective_weight * np.eye(n)
            b = b + self.objective_weight * z
        # the velocity box
        conflicts = ()
        if limits is None:
            lo = hi = None
        else:
            bc = self._bcache
            if bc is None or bc.src is not limits or bc.dt != dt or bc.n != n:
                bc = self._bcache = _BoundCache(limits, Limits.of(limits, n), dt, self.margin)
            lo, hi, conflicts = _box(bc, q, qd_prev)
        G = h = None
        if extra_inequalities is not None:
            G, h = _extra(extra_inequalities, n)
        # shortcut: the unconstrained minimiser P⁻¹b (= the DLS solution) if it is feasible
        qd = held = None
        slack = math.inf
        if self.shortcut and self._pd:
            _, x0, info0 = _dposv(P, b)
            if info0 == 0:
                if lo is not None:
                    lists = (x0.tolist(), lo.tolist(), hi.tolist())
                    slack = min(min(u - x, x - l) for x, l, u in zip(*lists, strict=True))
                if slack >= 0.0 and (G is None or bool(np.all(_dot(G, x0) <= h))):
                    qd, status, niter = x0, "unconstrained", 0
                elif G is None and lo is not None and self.backend == "osqp":
                    # a box-only problem: a few primal active-set steps from x0, accepted
                    # only with a KKT certificate (then it is the exact optimum)
                    qd, held, niter = _box_active_set(P, b, lo, hi, x0, lists=lists)
                    if qd is not None:
                        status = "active-set"
        if qd is None:
            lo_ = np.full(n, -_BIG) if lo is None else lo
            hi_ = np.full(n, _BIG) if hi is None else hi
            try:
                qd, status, niter, exact = self._backend_solve(P, -b, G, h, lo_, hi_)
            except SolverError as exc:
                if not self.fallback:
                    raise
                return self._fallback_result(J, xi, lo_, hi_, exc)
            if G is None and lo is not None and not exact:
                refined = _polish(P, b, lo, hi, qd)
                if refined is not None:
                    qd = refined
            if lo is not None:
                # clip into the box (violations up to the tolerance are numerical)
                slack = min(float((hi - qd).min()), float((qd - lo).min()))
                if slack < 0.0:
                    if slack < -self.tolerance:
                        exc = SolverError(
                            f"QP ({self.backend}) solution violates its bounds by {-slack:.2e} > "
                            f"tolerance {self.tolerance:.1e}", status=status,
                            problem=self._problem(P, -b, G, h, lo, hi))
                        if not self.fallback:
                            raise exc
                        return self._fallback_result(J, xi, lo, hi, exc)
                    qd = np.minimum(np.maximum(qd, lo), hi)
        achieved = _dot(J, qd)
        err = xi - achieved
        e = sum(err.tolist())
        if e - e != 0.0:
            _check_finite(J, xi)
            raise SolverError("QP: the solution is not finite", status="non-finite",
                              problem=self._problem(P, -b, G, h, lo, hi))
        # which bounds hold q̇
        active = ()
        if held is not None:  # the active-set step knows which bounds hold
            bound = np.array(held, dtype=bool)
            active = _sources(bc, qd_prev, lo, hi, held)
        elif lo is not None and slack < self.tolerance:
            tol = self.tolerance
            at_hi = qd >= hi - tol  # an absent bound is ±1e15: never reached
            at_lo = qd <= lo + tol
            bound = at_hi | at_lo
            active = _sources(bc, qd_prev, lo, hi, (at_hi.astype(int) - (at_lo & ~at_hi)).tolist())
        else:
            bound = _zeros(n, dtype=bool)
        info = {"status": status, "iterations": niter, "backend": self.backend, "lower": lo,
                "upper": hi}
        if conflicts:
            info["conflicts"] = conflicts
        if G is not None:
            info["extra_active"] = _dot(G, qd) >= h - self.tolerance
        return SolveResult(qd, achieved, err, self.damping, _LazySigma(None, Jw), self.method,
                           "none", 1.0, bound, active, False, info)

    # ------------------------------------------------------------------ backends
    @staticmethod
    def _problem(P, c, G, h, lo, hi):
        return {"P": P, "q": c, "G": G, "h": h, "lb": lo, "ub": hi}

    def _backend_solve(self, P, c, G, h, lo, hi):
        n = P.shape[0]
        k = 0 if G is None else G.shape[0]
        if self.backend == "osqp":
            w = self._warm
            try:
                if w is None or w.n != n or w.k != k:
                    w = self._warm = _WarmOSQP(n, k, P, c, G, h, lo, hi, self._osqp_settings)
                x, sv, status, niter, polish = w.solve(P, c, G, h, lo, hi)
            except ValueError as exc:
                self._warm = None
                raise SolverError(f"OSQP rejected the problem: {exc}", status="error",
                                  problem=self._problem(P, c, G, h, lo, hi)) from exc
            if sv not in (1, 2) or not np.all(np.isfinite(x)):  # 1 solved, 2 solved inaccurate
                self._warm = None
                raise SolverError(f"OSQP failed: status {status!r}", status=status,
                                  problem=self._problem(P, c, G, h, lo, hi))
            return np.array(x), status, niter, polish == 1
        import qpsolvers

        kw = dict(self.settings)
        if self.backend == "proxqp":  # its residuals are scaled: needs tighter numbers to match
            kw.setdefault("eps_abs", 1e-11)
            kw.setdefault("eps_rel", 0.0)
            kw.setdefault("check_duality_gap", True)
            kw.setdefault("max_iter", 10000)
        elif self.backend in ("osqp", "scs", "clarabel", "ecos", "piqp"):
            kw.setdefault("eps_abs", 1e-9)
            kw.setdefault("eps_rel", 1e-9)
        Gq = None if G is None else G
        hq = None if h is None else h
        lb = np.where(lo > -_BIG, lo, -np.inf)
        ub = np.where(hi < _BIG, hi, np.inf)
        try:
            x = qpsolvers.solve_qp(P, c, Gq, hq, lb=lb, ub=ub, solver=self.backend, **kw)
        except Exception as exc:  # backends raise their own error types
            raise SolverError(f"QP backend {self.backend!r} failed: {exc}", status="error",
                              problem=self._problem(P, c, G, h, lo, hi)) from exc
        if x is None or not np.all(np.isfinite(x)):
            raise SolverError(f"QP backend {self.backend!r} found no solution", status="failed",
                              problem=self._problem(P, c, G, h, lo, hi))
        # active-set backends are exact; the others get ratectl's active-set polish
        return np.asarray(x, dtype=float), "solved", -1, self.backend in ("daqp", "quadprog")

    def _fallback_result(self, J, xi, lo, hi, exc) -> SolveResult:
        """The DLS solution scaled uniformly into the box (clipped where 0 is outside it)."""
        r = self._dls.solve(J, xi)
        qd = r.qd
        n = qd.shape[0]
        ratio = np.ones(n)
        pos = qd > 0
        neg = qd < 0
        with np.errstate(divide="ignore", invalid="ignore"):
            ratio[pos] = np.where(hi[pos] > 0, hi[pos] / qd[pos], 0.0)
            ratio[neg] = np.where(lo[neg] < 0, lo[neg] / qd[neg], 0.0)
        scale = float(min(1.0, ratio.min())) if n else 1.0
        qd = np.minimum(np.maximum(qd * scale, lo), hi)
        achieved = np.dot(J, qd)
        policy = "scaled" if scale < 1.0 else "none"
        return SolveResult(qd, achieved, xi - achieved, self._dls.damping, r.sigma_min, self.method,
                           policy, scale, (qd >= hi - self.tolerance) | (qd <= lo + self.tolerance),
                           ("velocity",) if scale < 1.0 else (), True,
                           {"error": str(exc), "status": getattr(exc, "status", None),
                            "problem": getattr(exc, "problem", None)})


def _box_active_set(P, b, lo, hi, x0, max_iter: int = 4, lists=None):
    """Exact minimiser of ½xᵀPx − bᵀx over lo ≤ x ≤ hi (P positive definite) by a few
    primal active-set steps from the unconstrained minimiser x0 = P⁻¹b.

    With the working set A (joints held at a bound x_A = f) the minimiser is, by the
    Schur complement of P⁻¹,

        x = x0 − P⁻¹E S⁻¹ (x0_A − f),   S = (P⁻¹)_AA,   g = Px − b = −E S⁻¹ (x0_A − f),

    so each step is one Cholesky solve for the held columns P⁻¹E and one small solve of
    size |A| (a division when one joint is held, the common case).
    The working set starts as the bounds x0 violates; free joints that leave the box
    join it, and held joints whose multiplier has the wrong sign (g > 0 at an upper
    bound, g < 0 at a lower one) leave it. When neither happens the KKT conditions hold
    and x is the optimum (the problem is strictly convex).

    Returns (x, state, steps) with state[i] = +1 / −1 / 0 for a joint at its upper /
    lower bound / free, or (None, None, steps) when ``max_iter`` steps do not settle or
    a solve fails (the caller then uses the backend).
    """
    n = x0.shape[0]
    x0l, lol, hil = (x0.tolist(), lo.tolist(), hi.tolist()) if lists is None else lists
    state = [1 if x0l[i] > hil[i] else (-1 if x0l[i] < lol[i] else 0) for i in range(n)]
    kkt = None
    eye = _eye(n)
    for it in range(1, max_iter + 1):
        A = [i for i in range(n) if state[i]]
        if not A:
            return x0, state, it
        fix = [hil[i] if state[i] > 0 else lol[i] for i in A]
        # only the held columns of P⁻¹ are needed: P⁻¹E from one Cholesky solve
        if len(A) == 1:  # the common case: S is (P⁻¹)_aa, a division
            a = A[0]
            _, col, info = _dposv(P, eye[a])
            if info != 0:
                return None, None, it
            coef = [(x0l[a] - fix[0]) / float(col[a])]
            x = x0 - col * coef[0]
        else:
            _, cols, info = _dposv(P, eye[:, A])
            if info != 0:
                return None, None, it
            _, c, info = _dposv(cols[A], np.array([x0l[i] - f for i, f in zip(A, fix, strict=True)]))
            if info != 0:
                return None, None, it
            coef = c.tolist()
            x = x0 - _dot(cols, c)
        for i, f in zip(A, fix, strict=True):
            x[i] = f  # held joints sit exactly on their bound
        xl = x.tolist()
        moved = False
        for i in range(n):
            if state[i] == 0:
                if xl[i] > hil[i]:
                    state[i] = 1
                    moved = True
                elif xl[i] < lol[i]:
                    state[i] = -1
                    moved = True
        if moved:
            continue
        if kkt is None:
            kkt = 1e-10 * (1.0 + max(map(abs, b.tolist())))
        for j, i in enumerate(A):
            g = -coef[j]
            if (state[i] > 0 and g > kkt) or (state[i] < 0 and g < -kkt):
                state[i] = 0
                moved = True
        if not moved:
            return x, state, it
    return None, None, max_iter


_EYE: dict[int, np.ndarray] = {}


def _eye(n):
    e = _EYE.get(n)
    if e is None:
        e = _EYE[n] = np.eye(n)
        e.setflags(write=False)
    return e


def _polish(P, b, lo, hi, x):
    """Exact solution on the active set of an approximate one (box constraints only).

    Joints within 1e-5 of a bound are fixed there; the others solve
    P_FF x_F = b_F − P_FA x_A. Accepted if the result is inside the box and the KKT signs
    hold (gradient g = Px − b ≤ 0 at upper bounds, ≥ 0 at lower bounds, with a small
    tolerance); otherwise None (keep the backend's solution).
    """
    tol_act = 1e-5 * (1.0 + np.abs(x))
    up = x >= hi - tol_act
    dn = (x <= lo + tol_act) & ~up
    act = up | dn
    xa = np.where(up, hi, np.where(dn, lo, x))
    free = ~act
    if free.any():
        Pff = P[np.ix_(free, free)]
        rhs = b[free] - P[np.ix_(free, act)] @ xa[act]
        _, xf, info = _dposv(Pff, rhs)
        if info != 0:
            return None
        xa[free] = xf
    scale = 1e-12 * (1.0 + float(np.max(np.abs(xa))))
    if np.any(xa > hi + scale) or np.any(xa < lo - scale):
        return None
    g = P @ xa - b
    kkt = 1e-8 * (1.0 + float(np.max(np.abs(b))))
    if np.any(g[up] > kkt) or np.any(g[dn] < -kkt):
        return None
    return np.minimum(np.maximum(xa, lo), hi)


def _extra(extra, n):
    try:
        G, h = extra
    except (TypeError, ValueError):
        raise InputError("extra_inequalities must be a pair (G, h) meaning G q̇ ≤ h",
                         argument="extra_inequalities", value=extra) from None
    G = np.atleast_2d(np.asarray(G, dtype=float))
    h = np.atleast_1d(np.asarray(h, dtype=float))
    if G.ndim != 2 or G.shape[1] != n or h.shape != (G.shape[0],):
        raise InputError(f"extra_inequalities: G must be (k, {n}) and h (k,), got {G.shape} and "
                         f"{h.shape}", argument="extra_inequalities", value=extra)
    if not (np.all(np.isfinite(G)) and not np.any(np.isnan(h))):
        raise InputError("extra_inequalities must be finite (h may be +inf)",
                         argument="extra_inequalities", value=extra)
    return G, h
