"""The limit-aware QP solver (`QP`): damped least squares with joint position,
velocity and acceleration bounds and extra inequality rows.
"""

from __future__ import annotations

import math
from operator import sub as _sub
from types import MappingProxyType
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike
from scipy.linalg import lapack as _lapack

from ...arrays import shared_zeros
from ...errors import InputError, SolverError
from ...model.limits import Limits
from ..base import (
    _MAX_ENTRY,
    EXACT_DIRECTION_FLOOR,
    DirectionTwist,
    Solver,
    SolveResult,
    _check_finite,
    _check_problem,
    _checked_entries,
    _LazySigma,
    _owned_result,
    _positive,
    _SigmaReference,
    _store,
    exact_direction_floor,
    min_norm_direction,
    sigma_at_least,
)
from ..damped import DLS
from ..nullspace import _objective
from .active_set import (
    _box_active_set,
    _polish,
    box_qp_exact,
    kkt_violation,
    polish_general,
    qp_primal_active_set,
    qp_via_dual,
)
from .bounds import _BIG, _BoundCache, _box, _sources, _vec
from .warm_osqp import _OSQP_DEFAULTS, _WarmOSQP

if TYPE_CHECKING:
    from ...model.chain import Chain

__all__ = ['QP']


_dposv = _lapack.dposv
_dpotrs = _lapack.dpotrs

_KKT_TOL = 1e-9  # accepted scaled KKT violation (see kkt_violation)


_dot = np.dot

_hypot = math.hypot

_new = object.__new__


class QP(Solver):
    """Inverse velocity as a QP with joint limits (see `ratectl.qp` for the
    formulation and the bounds).

    Args:
        damping: λ, the joint-velocity regularisation (the DLS damping): with no active
            limit the QP returns exactly the DLS solution Jᵀ(JJᵀ + λ²I)⁻¹ξ.
        backend: ``"osqp"`` (default, kept warm across calls) or any solver name of
            `qpsolvers.solve_qp` (``"daqp"``, ``"quadprog"``, ``"proxqp"``, …).
        margin: distance kept from the position limits [rad or m]; per joint at most half
            its range (a joint narrower than 2·margin is kept at the centre of its range).
        task_weights: as for the other solvers (W_x).
        joint_weights: as for the other solvers (W_q).
        objective: optional secondary objective (``"centring"``, ``"manipulability"``
            with ``chain``, or a callable q -> desired q̇), added as ½μ‖q̇ − k·z(q)‖²;
            needs ``q=`` in `solve`.
        objective_weight: μ (small: the term trades task accuracy for the objective).
        objective_gain: k [1/s].
        chain: for the string objectives.
        fallback: on a failed solve return the DLS solution scaled into the velocity
            box (``result.fallback`` = True, ``info["error"]``) instead of raising
            `SolverError`.
        tolerance: bound violation up to which q̇ is clipped back into the box (larger
            violations raise), and the distance at which a bound counts as active.
        settings: extra OSQP settings (override the defaults) or backend keywords.
        shortcut: first try the unconstrained minimiser (one Cholesky solve); when it
            satisfies every bound it is the exact optimum and the backend is not called
            (``info["status"] == "unconstrained"``). ``False`` always calls the backend.
    """

    method = "qp"
    #: the solution already respects the velocity, position and acceleration bounds (and
    #: any extra rows): the controller reports them instead of limiting q̇ again, and passes
    #: a joint feed-forward as ``qd_ff=`` so that the bounds hold for the total command (a
    #: solver that sets this attribute accepts that keyword)
    enforces_limits = True

    def __init__(self, *, damping: float = 0.05, backend: str = "osqp", margin: float = 0.0,
                 task_weights: ArrayLike | None = None, joint_weights: ArrayLike | None = None,
                 objective: Any = None, objective_weight: float = 1e-3, objective_gain: float = 1.0,
                 chain: Chain | None = None, fallback: bool = False, tolerance: float = 1e-6,
                 settings: dict | None = None, shortcut: bool = True) -> None:
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
        self._reg_small: dict[int, bool] = {}  # the regulariser's entries are below 1e300
        self._sigma_ref = _SigmaReference()  # the last exact σ_min, for sigma_min_at_least
        # the info of an unconstrained answer without limits (`solve_direction_twist`'s feedback)
        self._info_unconstrained: dict[str, Any] | None = None
        # the last J's objective terms and P's Cholesky factor: a control cycle solves twice
        # with the same J (the direction of a progress, then the command), and the second
        # solve only needs b = Jᵀξ and two triangular solves ((entries, shape, P, σ, factor))
        self._terms: tuple | None = None
        self._pd = self._lam2 > 0 or (self.objective is not None and self.objective_weight > 0)
        self._dls = DLS(damping=max(self.damping, 1e-6), velocity_policy=None,
                        task_weights=task_weights, joint_weights=joint_weights)

    def __repr__(self) -> str:
        return f"QP(damping={self.damping!r}, backend={self.backend!r}, margin={self.margin!r})"

    def reset(self) -> None:
        """Forget the warm OSQP instance (the next call sets it up again)."""
        self._warm = None

    def solve(self, J: np.ndarray, xi: np.ndarray, *, limits: Limits | Chain | None = None,
              q: ArrayLike | None = None, qd_prev: ArrayLike | None = None, dt: float | None = None,
              extra_inequalities: Any = None, qd_ff: ArrayLike | None = None) -> SolveResult:
        """q̇ for the twist ``xi`` with the Jacobian ``J`` under the joint limits.

        Args:
            J, xi: Jacobian (m, n) and desired twist (m,).
            limits: a Chain or `Limits` (None: no bounds, the QP is the DLS).
            q: joint positions (n,): enables the position bounds (and the objective).
            qd_prev: previous joint velocities (n,): with ``dt``, the acceleration bounds.
            dt: the control step [s].
            extra_inequalities: ``(G, h)`` with G (k, n) and h (k,): extra rows G q̇ ≤ h
                (e.g. collision avoidance); a change of k re-creates the OSQP instance.
            qd_ff: a joint-velocity feed-forward (n,) [rad/s or m/s] that the caller adds to
                the answer. The QP then resolves the correction c (minimising
                ½‖W_x^{1/2}(J c − ξ)‖² + ½λ²cᵀW_q c) and the velocity, position and
                acceleration bounds hold for the **total** q̇_ff + c: the box of the total
                is computed from ``q``, ``qd_prev`` and ``dt`` and shifted by −q̇_ff.
                ``result.qd`` is c, and ``info["lower"]``/``["upper"]`` are c's box; extra
                rows G q̇ ≤ h also hold for the total.

        Every answer for a box-only problem is certified: it lies in its box and the KKT
        conditions hold (`kkt_violation` ≤ 1e-9);
        an answer that is not (an inaccurate OSQP result) is replaced by the exact
        active-set solution (``info["certified"]`` says which path answered). With extra
        rows the OSQP answer is replaced by the exact solution on its active set when
        that passes the KKT check (``info["certified"] == "kkt"``), else kept with
        ``"none"``; every answer is checked feasible (box and rows) to the tolerance.

        Returns:
            `SolveResult` with ``limits_active`` naming the kinds of
            bound that hold q̇ and ``info`` = status, iterations, backend, the box
            (``lower``, ``upper``) and any ``conflicts`` resolved by priority.
        """
        J, xi, entries = _check_problem(J, xi)
        qv, qd_prev_v, qd_ff_v, dt_v = self._check_state(q, qd_prev, qd_ff, dt, J.shape[1])
        return self._solve_checked(J, xi, entries, limits, qv, qd_prev_v, qd_ff_v, dt_v,
                                   extra_inequalities)

    def solve_validated(self, J: np.ndarray, xi: np.ndarray, *, limits: Limits | Chain | None,
                        q: np.ndarray | None, qd_prev: np.ndarray | None, dt: float | None,
                        qd_ff: np.ndarray | None = None) -> SolveResult:
        """`solve` (without extra rows) for a caller that has validated its inputs itself:
        the `ResolvedRateController`'s entry, which saves the per-cycle checks it has
        already made. The caller guarantees: J a float64 ndarray (m, n) with m, n ≥ 1; ξ a
        float64 ndarray (m,); q, qd_prev and qd_ff None or finite float64 ndarrays (n,);
        dt None or a positive finite Python float. J and ξ are still checked here (finite,
        and small enough for their products: the caller cannot know that, a prismatic
        joint far out makes J huge), and answers are certified as by `solve`; anything
        outside the guarantee is undefined (use `solve`)."""
        return self._solve_checked(J, xi, _checked_entries(J, xi), limits, q, qd_prev, qd_ff, dt, None)

    def solve_direction(self, J: np.ndarray, d: np.ndarray, *, q: np.ndarray | None,
                        dt: float | None) -> tuple[np.ndarray, Any, float]:
        """`Solver.solve_direction`: wherever W J has full rank (σ_min(W J) above
        `exact_direction_floor`), the exact direction (`min_norm_direction`: J w = d, the
        least W_q-norm w), so that a motion along it (a jog, the servo's line) is not turned
        by the regulariser λ²‖q̇‖², which shrinks each singular direction by σ²/(σ² + λ²) on
        its own (near a singularity |w| grows as 1/σ_min: the joint limits then slow the
        progress along it); below, the QP's unconstrained minimiser w = P⁻¹b (b = JᵀW d,
        plus the objective's term), as `solve` without limits. With an objective always
        the latter (its pull is part of the answer). Returned with σ_min(W J) lazily; P
        and its factor stay for the cycle's command (a second solve with the same J).
        Inputs as for `solve_validated`."""
        if self.shortcut and self._pd:
            sigma, P, b = self._objective_terms(J, d, q, _checked_entries(J, d))
            if self.objective is None and sigma_at_least(sigma, exact_direction_floor(sigma.entries))[0]:
                if self._rows is not None:
                    rows, _ = self._rows
                    Jw, dw = J[rows] * self._sw[:, None], d[rows] * self._sw
                else:
                    Jw, dw = J, d
                w = min_norm_direction(Jw, dw, self._isw)
                if w is not None:
                    return w, sigma, 0.0
            terms = self._terms
            if terms is not None and terms[2] is P and terms[4] is not None:
                w, info = _dpotrs(terms[4], b)
            else:
                factor, w, info = _dposv(P, b)
                if info == 0 and terms is not None and terms[2] is P:
                    self._terms = (*terms[:4], factor)
            t = sum(w.tolist())
            if info == 0 and t - t == 0.0:
                return w, sigma, self.damping
        res = self.solve(J, d, q=q, dt=dt)  # (the general path: its checks and errors)
        return np.array(res.qd, dtype=float), res, float(res.damping)

    def solve_direction_twist(self, J: np.ndarray, d: np.ndarray, xi: np.ndarray, *,
                              q: np.ndarray | None, dt: float | None) -> DirectionTwist:
        """`Solver.solve_direction_twist` with one P = JᵀJ + λ²W_q for both: where J is regular
        (σ_min above `exact_direction_floor`) the exact direction w (`min_norm_direction`,
        as `solve_direction`) and the feedback c = P⁻¹Jᵀξ, the unconstrained minimiser that
        `solve_validated` answers without limits (``info["status"] == "unconstrained"``),
        from one Cholesky factor of P; the feedback's `SolveResult` is built by
        `DirectionTwist.result` only, for the command it ends in. Anything else (task
        weights, an objective, no shortcut, J near a singularity or out of range, a factor
        that fails) takes the two entries in turn (the default): the same answers."""
        m, n = J.shape
        reg = self._reg.get(n)
        if self._rows is not None or self.objective is not None or not (self.shortcut and self._pd) \
                or reg is None or not self._reg_small[n]:
            return Solver.solve_direction_twist(self, J, d, xi, q=q, dt=dt)
        # the input checks of both entries (`_checked_entries`: √(‖J‖²_F + ‖d‖²) and
        # √(‖J‖²_F + ‖ξ‖²) below 1e145), from ‖J‖_F once, with a margin for its rounding
        # (anything closer takes the entries themselves, which check exactly)
        entries = J.ravel().tolist()
        norm = _hypot(*entries)
        if not max(_hypot(norm, *d.tolist()), _hypot(norm, *xi.tolist())) < _MAX_ENTRY * (1.0 - 1e-12):
            return Solver.solve_direction_twist(self, J, d, xi, q=q, dt=dt)
        terms = self._terms
        if terms is not None and terms[1] == J.shape and terms[0] == entries:  # the last solve's J
            P, sigma, factor = terms[2], terms[3], terms[4]
        else:  # (as `_objective_terms`)
            JtJ = J.T.dot(J)
            P = JtJ + reg
            sigma = (_LazySigma(JtJ, None, self._sigma_ref, shape=J.shape, entries=entries) if n <= m
                     else _LazySigma(None, J.copy(), self._sigma_ref, shape=J.shape, entries=entries))
            factor = None
        self._terms = (entries, J.shape, P, sigma, factor)
        w = None
        if sigma_at_least(sigma, EXACT_DIRECTION_FLOOR * norm)[0]:  # (`exact_direction_floor`)
            w = min_norm_direction(J, d, self._isw)
        if w is None:
            return Solver.solve_direction_twist(self, J, d, xi, q=q, dt=dt)
        b = xi.dot(J)
        if factor is None:
            factor, c, info = _dposv(P, b)
            if info == 0:
                self._terms = (entries, J.shape, P, sigma, factor)
        else:
            c, info = _dpotrs(factor, b)
        # ‖J c‖ ≤ ‖J‖_F‖c‖: the achieved twist and the task error are finite below 1e300
        if info != 0 or not _hypot(*c.tolist()) * norm < 1e300:
            return Solver.solve_direction_twist(self, J, d, xi, q=q, dt=dt)

        info = self._info_unconstrained
        if info is None or info["backend"] != self.backend:  # (one dict, only ever shown read-only)
            info = self._info_unconstrained = {"status": "unconstrained", "iterations": 0,
                                               "backend": self.backend, "lower": None, "upper": None,
                                               "certified": "unconstrained"}

        def make(xi_c: np.ndarray, qd: np.ndarray) -> SolveResult:
            """The feedback's result (as `solve_validated`'s) for the command ``qd``."""
            achieved = J.dot(qd)
            r = _new(SolveResult)
            _store(r, qd if qd is c else qd.copy(), achieved, xi_c - achieved, self.damping, sigma,
                   self.method, "none", 1.0, shared_zeros(n, bool), (), False, MappingProxyType(info))
            return r

        return DirectionTwist(w, sigma, 0.0, c, J=J, make=make)

    def _solve_checked(self, J: np.ndarray, xi: np.ndarray, entries: list[float],
                       limits: Limits | Chain | None, qv: np.ndarray | None, qd_prev_v: np.ndarray | None,
                       qd_ff_v: np.ndarray | None, dt_v: float | None,
                       extra_inequalities: Any) -> SolveResult:
        """`solve` on checked inputs (``entries``: J's, row by row)."""
        n = J.shape[1]
        sigma, P, b = self._objective_terms(J, xi, qv, entries)
        conflicts: tuple = ()
        bc: _BoundCache | None = None
        lo = hi = lo_t = hi_t = None
        if limits is not None:
            bc = self._bcache
            if bc is None or bc.src is not limits or bc.dt != dt_v or bc.n != n:
                bc = self._bcache = _BoundCache(limits, Limits.of(limits, n), dt_v, self.margin)
            lo, hi, conflicts = _box(bc, qv, qd_prev_v)
            lo_t, hi_t = lo, hi  # the box of the total q̇_ff + c
            if qd_ff_v is not None:
                lo, hi = lo - qd_ff_v, hi - qd_ff_v
        G = h = None
        if extra_inequalities is not None:
            G, h = _extra(extra_inequalities, n)
            if qd_ff_v is not None:
                h = h - _dot(G, qd_ff_v)
        qd, held, status, niter, slack = self._shortcut(P, b, lo, hi, G, h)
        certified = status if qd is not None else None
        if qd is None:
            answer = self._solve_and_certify(J, xi, P, b, G, h, lo, hi)
            if isinstance(answer, SolveResult):  # the fallback answered
                return answer
            qd, held, status, niter, certified, slack = answer
        if G is not None and h is not None:  # the extra rows: feasible to the tolerance
            gv = float(np.max(_dot(G, qd) - h)) if G.shape[0] else 0.0
            if gv > self.tolerance * (1.0 + float(np.max(np.abs(qd)))):
                err = SolverError(f"QP ({self.backend}) solution violates an extra inequality by "
                                  f"{gv:.2e}", status=status,
                                  problem=self._problem(P, -b, G, h, lo, hi))
                if not self.fallback:
                    raise err
                return self._fallback_result(J, xi, lo if lo is not None else np.full(n, -_BIG),
                                             hi if hi is not None else np.full(n, _BIG), err)
        achieved = J.dot(qd)
        task_error = xi - achieved
        e = sum(task_error.tolist())
        if e - e != 0.0:
            _check_finite(J, xi)
            raise SolverError("QP: the solution is not finite", status="non-finite",
                              problem=self._problem(P, -b, G, h, lo, hi))
        bound, active = self._bound_sources(qd, held, lo, hi, lo_t, hi_t, bc, qd_prev_v, slack)
        info: dict[str, Any] = {"status": status, "iterations": niter, "backend": self.backend,
                                "lower": lo, "upper": hi}
        if lo is not None and hi is not None:
            lo.setflags(write=False)
            hi.setflags(write=False)
        if certified is not None:
            info["certified"] = certified
        if conflicts:
            info["conflicts"] = conflicts
        if G is not None and h is not None:
            info["extra_active"] = extra = G.dot(qd) >= h - self.tolerance
            extra.setflags(write=False)
        return _owned_result(qd, achieved, task_error, self.damping, sigma, self.method, bound, active,
                             info)

    # ------------------------------------------------------------------ stages of solve
    def _check_state(self, q: ArrayLike | None, qd_prev: ArrayLike | None, qd_ff: ArrayLike | None,
                     dt: float | None, n: int
                     ) -> tuple[np.ndarray | None, np.ndarray | None, np.ndarray | None, float | None]:
        """q, q̇_prev, q̇_ff as finite (n,) float arrays and dt as a positive float (or None)."""
        if dt is not None and (type(dt) is not float or not (dt > 0.0 and dt < math.inf)):
            dt = _positive("dt", dt)
        qv = None
        if q is not None:
            if type(q) is not np.ndarray or q.shape != (n,) or q.dtype != np.float64:
                qv = _vec("q", q, n)
            else:
                t = sum(q.tolist())
                # NaN or inf: the position bounds cannot be computed (_vec raises)
                qv = _vec("q", q, n) if t - t != 0.0 else q
        qd_prev_v = None
        if qd_prev is not None:
            if (type(qd_prev) is not np.ndarray or qd_prev.shape != (n,)
                    or not math.isfinite(sum(qd_prev.tolist()))):
                qd_prev_v = _vec("qd_prev", qd_prev, n)
            else:
                qd_prev_v = qd_prev
        qd_ff_v = None if qd_ff is None else _vec("qd_ff", qd_ff, n)
        return qv, qd_prev_v, qd_ff_v, dt

    def _objective_terms(self, J: np.ndarray, xi: np.ndarray, q: np.ndarray | None,
                         entries: list[float]) -> tuple[_LazySigma, np.ndarray, np.ndarray]:
        """(σ_min of the weighted J, computed on first access; P; b) of the objective
        ½‖W(Jq̇ − ξ)‖² + ½λ²q̇ᵀW_q q̇ (+ ½μ‖q̇ − z‖²) = ½q̇ᵀPq̇ − bᵀq̇; ``entries`` are
        J's, row by row (from `_check_problem`)."""
        m, n = J.shape
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
            self._reg_small[n] = bool(np.all(d < 1e300))
        if self._rows is None and self._reg_small[n]:
            # unweighted J, checked by _check_problem: ‖J‖²_F + ‖ξ‖² < 1e290 bounds every
            # entry of JᵀJ and Jᵀξ by 1e290 (Cauchy–Schwarz), so P and b are finite and the
            # products cannot overflow (no floating-point state to set, no check to make)
            terms = self._terms
            if (self.objective is None and terms is not None and terms[1] == J.shape
                    and terms[0] == entries):  # the same J as the last solve: its P and σ
                return terms[3], terms[2], xiw.dot(Jw)
            JtJ = Jw.T.dot(Jw)
            P = JtJ + reg
            b = xiw.dot(Jw)
        else:
            with np.errstate(over="ignore", invalid="ignore"):
                JtJ = Jw.T.dot(Jw)
                P = JtJ + reg
                b = xiw.dot(Jw)
            t = sum(P.ravel().tolist()) + sum(b.tolist())
            if t - t != 0.0:
                raise InputError("QP: JᵀJ or Jᵀξ overflows (|J| and |ξ| must stay below ~1e150); "
                                 "the problem is outside floating-point range", argument="J", value=J)
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
        # σ_min(W J) from the smaller Gram matrix: JᵀJ, already computed, when n ≤ m, else
        # from an own copy of J (the caller may reuse its array); W J's entries (a list, as
        # the input check read them) for the certificate and its reference
        if Jw is not J:
            entries = Jw.ravel().tolist()
        if n <= Jw.shape[0]:
            sigma = _LazySigma(JtJ, None, self._sigma_ref, shape=Jw.shape, entries=entries)
        else:
            sigma = _LazySigma(None, Jw.copy() if Jw is J else Jw, self._sigma_ref, shape=Jw.shape,
                               entries=entries)
        # remembered for a next solve with the same J (its factor once `_shortcut` has it)
        self._terms = ((entries, J.shape, P, sigma, None)
                       if self.objective is None and self._rows is None and self._reg_small[n] else None)
        return sigma, P, b

    def _shortcut(self, P: np.ndarray, b: np.ndarray, lo: np.ndarray | None, hi: np.ndarray | None,
                  G: np.ndarray | None, h: np.ndarray | None) -> tuple[Any, Any, str, int, float]:
        """The unconstrained minimiser P⁻¹b (= the DLS solution) if it is feasible, else for a
        box-only problem a few certified primal active-set steps from it; ``(qd, held, status,
        iterations, slack)`` with qd None when neither answers."""
        qd: np.ndarray | None = None
        held: Any = None
        status, niter, slack = "", 0, math.inf
        if not (self.shortcut and self._pd):
            return qd, held, status, niter, slack
        terms = self._terms
        if terms is not None and terms[2] is not P:
            terms = None  # (P is not the remembered J's: see _objective_terms)
        if terms is not None and terms[4] is not None:  # factored by the last solve (same J)
            x0, info0 = _dpotrs(terms[4], b)
        else:
            factor, x0, info0 = _dposv(P, b)
            if info0 == 0 and terms is not None:
                self._terms = (*terms[:4], factor)
        if info0 != 0:
            return qd, held, status, niter, slack
        lists = None
        if lo is not None and hi is not None:
            lists = x0l, lol, hil = (x0.tolist(), lo.tolist(), hi.tolist())
            slack = min(min(map(_sub, hil, x0l)), min(map(_sub, x0l, lol)))
        if slack >= 0.0 and (G is None or h is None or bool(np.all(G.dot(x0) <= h))):
            return x0, None, "unconstrained", 0, slack
        if G is None and lo is not None and hi is not None and self.backend == "osqp":
            # a box-only problem: a few primal active-set steps from x0, accepted only with a
            # KKT certificate (then it is the exact optimum); the Schur-complement steps lose
            # accuracy when P is ill-conditioned (tiny damping): certify, else let the backend
            # and the exact active set answer
            qd, held, niter = _box_active_set(P, b, lo, hi, x0, lists=lists)
            if qd is not None:
                status = "active-set"
                if kkt_violation(P, b, lo, hi, qd) > _KKT_TOL:
                    qd = held = None
        return qd, held, status, niter, slack

    def _solve_and_certify(self, J: np.ndarray, xi: np.ndarray, P: np.ndarray, b: np.ndarray,
                           G: np.ndarray | None, h: np.ndarray | None, lo: np.ndarray | None,
                           hi: np.ndarray | None) -> SolveResult | tuple:
        """The backend's answer, certified (KKT, exact active set or dual) and clipped into the
        box; ``(qd, held, status, iterations, certified, slack)``, or the fallback's result."""
        n = P.shape[0]
        lo_ = np.full(n, -_BIG) if lo is None else lo
        hi_ = np.full(n, _BIG) if hi is None else hi
        held = None
        certified = None
        slack = math.inf
        try:
            qd, status, niter, exact = self._backend_solve(P, -b, G, h, lo_, hi_)
        except SolverError as exc:
            rescued = self._rescue(P, b, G, h, lo, hi, lo_, hi_, exc)
            if rescued is None:
                if not self.fallback:
                    raise
                return self._fallback_result(J, xi, lo_, hi_, exc)
            qd, status, niter, exact, held = rescued
        if G is None and lo is not None and hi is not None and held is None:
            if not exact:
                refined = _polish(P, b, lo, hi, qd)
                if refined is not None:
                    qd = refined
            # certify: inside the box and optimal (KKT); else the exact active set
            if kkt_violation(P, b, lo, hi, qd) <= _KKT_TOL:
                certified = "kkt"
            else:
                x2, st2 = box_qp_exact(P, b, lo, hi, qd)
                if x2 is None or kkt_violation(P, b, lo, hi, x2) > _KKT_TOL:
                    err = SolverError(
                        f"QP ({self.backend}): no answer satisfies the optimality (KKT) "
                        "conditions; the problem is too ill-conditioned", status="uncertified",
                        problem=self._problem(P, -b, G, h, lo, hi))
                    if not self.fallback:
                        raise err
                    return self._fallback_result(J, xi, lo, hi, err)
                qd, status, certified = x2, "exact-active-set", "exact-active-set"
                held = st2.tolist()
        elif G is not None and h is not None:
            # extra rows: the exact solution on OSQP's active set, with its KKT certificate;
            # when OSQP's active set is not the optimum's (an inaccurate answer), the exact
            # solvers answer: the dual, then the primal active-set method
            x2 = polish_general(P, b, lo_, hi_, G, h, qd)
            if x2 is not None:
                qd, certified = x2, "kkt"
            elif (x2 := qp_via_dual(P, b, lo_, hi_, G, h)) is not None:
                qd, status, certified = x2, "exact-dual", "exact-dual"
            elif (x2 := qp_primal_active_set(P, b, lo_, hi_, G, h)) is not None:
                qd, status, certified = x2, "exact-primal", "exact-primal"
            else:
                certified = "none"  # feasibility is still checked by solve
        if lo is not None and hi is not None:
            # clip into the box (violations up to the tolerance are numerical)
            slack = min(float((hi - qd).min()), float((qd - lo).min()))
            if slack < 0.0:
                if slack < -self.tolerance:
                    err = SolverError(
                        f"QP ({self.backend}) solution violates its bounds by {-slack:.2e} > "
                        f"tolerance {self.tolerance:.1e}", status=status,
                        problem=self._problem(P, -b, G, h, lo, hi))
                    if not self.fallback:
                        raise err
                    return self._fallback_result(J, xi, lo, hi, err)
                qd = np.minimum(np.maximum(qd, lo), hi)
        return qd, held, status, niter, certified, slack

    def _rescue(self, P: np.ndarray, b: np.ndarray, G: np.ndarray | None, h: np.ndarray | None,
                lo: np.ndarray | None, hi: np.ndarray | None, lo_: np.ndarray, hi_: np.ndarray,
                exc: SolverError) -> tuple | None:
        """An exact answer where the backend failed: the box-only problem by the exact active set;
        with extra rows one cold OSQP retry with a larger budget (then its certified polish), else
        the dual. ``(qd, status, iterations, exact, held)`` or None."""
        if G is None or h is None:
            if lo is not None and hi is not None:  # a box-only problem has an exact answer
                qd, st2 = box_qp_exact(P, b, lo, hi, None)
                if qd is not None:
                    return qd, "exact-active-set", -1, True, st2.tolist()
            return None
        n = P.shape[0]
        if getattr(exc, "iterate", None) is None or "max_iter" in self.settings:
            return None  # not a budget problem, or a budget the user set: the failure stands
        # OSQP ran out of iterations (ill-conditioned P): one cold retry with a much larger
        # budget, accepted only with the KKT certificate of the exact solution on its
        # active set
        try:
            cold = _WarmOSQP(n, G.shape[0], P, -b, G, h, lo_, hi_,
                             {**(self._osqp_settings or {}), "max_iter": 200_000})
            x, sv, _, it2, _ = cold.solve(P, -b, G, h, lo_, hi_)
        except Exception:  # OSQP's own exception types
            x, sv = None, 0
        if sv in (1, 2) and x is not None and np.all(np.isfinite(x)):
            qd = polish_general(P, b, lo_, hi_, G, h, np.array(x))
            if qd is not None:
                return qd, "solved (retry)", it2, True, None
        qd = qp_via_dual(P, b, lo_, hi_, G, h)  # the exact answer through the dual (a box QP)
        if qd is not None:
            return qd, "exact-dual", -1, True, None
        # degenerate or ill-conditioned: the primal active-set method from a feasible point
        # (its termination is the KKT certificate); None only when the rows are infeasible
        qd = qp_primal_active_set(P, b, lo_, hi_, G, h)
        if qd is not None:
            return qd, "exact-primal", -1, True, None
        return None

    def _bound_sources(self, qd: np.ndarray, held: Any, lo: np.ndarray | None, hi: np.ndarray | None,
                       lo_t: np.ndarray | None, hi_t: np.ndarray | None, bc: _BoundCache | None,
                       qd_prev: np.ndarray | None, slack: float) -> tuple[np.ndarray, tuple[str, ...]]:
        """Which joints sit at a bound, and the kinds of limit that set those bounds."""
        n = qd.shape[0]
        if held is not None and bc is not None:  # the active-set step knows which bounds hold
            return np.array(held, dtype=bool), _sources(bc, qd_prev, lo_t, hi_t, held)
        if lo is not None and hi is not None and bc is not None and slack < self.tolerance:
            tol = self.tolerance
            at_hi = qd >= hi - tol  # an absent bound is ±1e15: never reached
            at_lo = qd <= lo + tol
            return at_hi | at_lo, _sources(bc, qd_prev, lo_t, hi_t,
                                           (at_hi.astype(int) - (at_lo & ~at_hi)).tolist())
        return shared_zeros(n, bool), ()  # no joint at a bound

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
            except Exception as exc:  # ValueError, osqp.OSQPException, ...: OSQP's own types
                self._warm = None
                raise SolverError(f"OSQP rejected the problem ({type(exc).__name__}: {exc}); check "
                                  "the settings and that the data are finite and moderate",
                                  status="error", problem=self._problem(P, c, G, h, lo, hi)) from exc
            if sv not in (1, 2) or not np.all(np.isfinite(x)):  # 1 solved, 2 solved inaccurate
                self._warm = None
                failure = SolverError(f"OSQP failed: status {status!r}", status=status,
                                      problem=self._problem(P, c, G, h, lo, hi))
                failure.iterate = np.array(x) if np.all(np.isfinite(x)) else None  # for a polish
                raise failure
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
        return SolveResult(qd=qd, achieved=achieved, task_error=xi - achieved, damping=self._dls.damping,
                           sigma_min=r.sigma_min, method=self.method, velocity_policy=policy,
                           velocity_scale=scale,
                           bound=(qd >= hi - self.tolerance) | (qd <= lo + self.tolerance),
                           limits_active=("velocity",) if scale < 1.0 else (), fallback=True,
                           info={"error": str(exc), "status": getattr(exc, "status", None),
                                 "problem": getattr(exc, "problem", None)})




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
    if np.any(h == -np.inf):
        raise InputError("extra_inequalities: h contains -inf, a row G q̇ ≤ -inf no q̇ satisfies "
                         "(h may be +inf for an inactive row)", argument="extra_inequalities",
                         value=extra)
    return G, h
