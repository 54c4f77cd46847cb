"""Fuzz: inverse-velocity solvers on generated problems.

* The QP: every answer inside its own box and inside the box computed independently by
  ``joint_velocity_bounds``; velocity, acceleration and next-step position limits held to
  1e-6 relative; the answer's objective equal to an exact reference (a dense enumeration
  of all 3ⁿ active sets for n ≤ 5, and daqp when installed); with ``qd_ff`` the **total**
  inside the box of the total.
* Every solver on hostile inputs (huge, tiny, NaN, empty, complex, strings): a finite
  answer or a ratectl error, never a foreign exception.
"""

from __future__ import annotations

import itertools
import math
import warnings

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

import ratectl as rc
from ratectl.errors import RatectlError
from ratectl.model.limits import Limits
from ratectl.solvers import QP, joint_velocity_bounds
from ratectl.solvers.qp.active_set import box_qp_exact

try:
    import qpsolvers

    HAVE_DAQP = "daqp" in qpsolvers.available_solvers
except ImportError:  # pragma: no cover
    HAVE_DAQP = False

INF = math.inf


def enumerate_box_qp(P, b, lo, hi):
    """The exact minimiser of ½xᵀPx − bᵀx over lo ≤ x ≤ hi by enumeration: for every one of
    the 3ⁿ assignments (free / at lower / at upper) minimise over that face; the best
    feasible face minimiser is the optimum (the optimum lies in the relative interior of
    some face, whose minimiser it is)."""
    n = b.shape[0]
    best, fbest = None, INF
    for state in itertools.product((0, -1, 1), repeat=n):
        s = np.array(state)
        if np.any((s != 0) & ~np.isfinite(np.where(s > 0, hi, lo))):
            continue
        x = np.where(s > 0, hi, np.where(s < 0, lo, 0.0))
        F = np.flatnonzero(s == 0)
        if F.size:
            H = np.flatnonzero(s != 0)
            rhs = b[F] - P[np.ix_(F, H)] @ x[H]
            try:
                x[F] = np.linalg.solve(P[np.ix_(F, F)], rhs)
            except np.linalg.LinAlgError:
                continue
        scale = 1e-9 * (1.0 + np.abs(x))
        if np.any(x < lo - scale) or np.any(x > hi + scale):
            continue
        x = np.clip(x, lo, hi)
        f = 0.5 * x @ P @ x - b @ x
        if f < fbest:
            best, fbest = x, f
    return best


def _problem(seed: int, *, ill: bool = False, extreme: bool = False):
    """A random QP problem: (solver options, J, xi, limits, q, qd_prev, dt)."""
    r = np.random.default_rng(seed)
    n = int(r.integers(1, 6))
    m = int(r.integers(1, 7))
    J = r.standard_normal((m, n)) * 10.0 ** r.uniform(-2, 1)
    if r.random() < 0.3:  # rank deficient
        k = int(r.integers(0, min(m, n)))
        J = r.standard_normal((m, k)) @ r.standard_normal((k, n)) if k else np.zeros((m, n))
    if extreme:
        J = J * 10.0 ** r.uniform(-100, 100)
    xi = r.standard_normal(m) * 10.0 ** r.uniform(-2, 1)
    lower = -r.uniform(0.05, 3.0, n)
    upper = r.uniform(0.05, 3.0, n)
    shift = r.uniform(-1, 1, n)
    lower, upper = lower + shift, upper + shift
    lower[r.random(n) < 0.15] = -INF
    upper[r.random(n) < 0.15] = INF
    vmax = r.uniform(0.05, 3.0, n)
    vmax[r.random(n) < 0.1] = INF
    amax = r.uniform(0.5, 20.0, n)
    amax[r.random(n) < 0.2] = INF
    if extreme and r.random() < 0.5:
        amax = amax * 10.0 ** r.uniform(-250, 0)
    lim = Limits(lower=lower, upper=upper, vmax=vmax, amax=amax)
    lo_f = np.where(np.isfinite(lower), lower, -2.0)
    hi_f = np.where(np.isfinite(upper), upper, 2.0)
    q = lo_f + (hi_f - lo_f) * r.random(n)
    near = r.random(n) < 0.4  # many joints on or next to a limit
    q = np.where(near & (r.random(n) < 0.5), lo_f + r.uniform(0, 0.02, n), q)
    q = np.where(near & (r.random(n) < 0.5), hi_f - r.uniform(0, 0.02, n), q)
    qd_prev = r.uniform(-1, 1, n) * np.minimum(vmax, 2.0) if r.random() < 0.7 else None
    dt = float(10.0 ** r.uniform(-4, -1))
    damping = float(r.choice([0.0, 1e-6, 1e-3, 0.05, 0.3]))
    opts = {"damping": damping}
    if ill:
        w = 10.0 ** r.uniform(-3, 7, m)
        opts["task_weights"] = w
    if r.random() < 0.3:
        opts["joint_weights"] = 10.0 ** r.uniform(-2, 2, n)
    if damping == 0.0 and "joint_weights" not in opts:
        opts["damping"] = 1e-4  # keep P positive definite: the reference needs a unique optimum
    return opts, J, xi, lim, q, qd_prev, dt


def _objective_matrices(opts, J, xi):
    m, n = J.shape
    w = np.asarray(opts.get("task_weights", np.ones(m)), dtype=float)
    wq = np.asarray(opts.get("joint_weights", np.ones(n)), dtype=float)
    P = J.T @ (w[:, None] * J) + opts["damping"] ** 2 * np.diag(wq)
    b = J.T @ (w * xi)
    return P, b


def _check_qp(fuzz, seed, *, ill=False, backend="osqp", with_ff=False):
    opts, J, xi, lim, q, qd_prev, dt = _problem(seed, ill=ill)
    solver = QP(backend=backend, **opts)
    n = J.shape[1]
    r = np.random.default_rng(seed + 1)
    qd_ff = r.uniform(-1, 1, n) * np.minimum(lim.vmax, 1.0) if with_ff else None
    fuzz.count("qp")
    res = solver.solve(J, xi, limits=lim, q=q, qd_prev=qd_prev, dt=dt, qd_ff=qd_ff)
    qd = np.asarray(res.qd)
    assert np.all(np.isfinite(qd))
    vb = joint_velocity_bounds(lim, q=q, qd_prev=qd_prev, dt=dt)
    lo, hi = vb.lower, vb.upper
    total = qd if qd_ff is None else qd + qd_ff
    tol = 1e-6 * (1.0 + np.abs(total))
    # (1) the box, computed independently
    assert np.all(total >= lo - tol) and np.all(total <= hi + tol), (total, lo, hi)
    # (2) the raw limits (the box never exceeds vmax; acceleration and position unless the
    #     bounds conflicted and were resolved by priority)
    assert np.all(np.abs(total) <= lim.vmax * (1 + 1e-6) + 1e-12)
    if not vb.conflicts:
        if qd_prev is not None:
            assert np.all(np.abs(total - qd_prev) <= lim.amax * dt * (1 + 1e-6) + 1e-9)
        inside = (q >= lim.lower) & (q <= lim.upper)
        qn = q + total * dt
        span = np.where(np.isfinite(lim.upper - lim.lower), lim.upper - lim.lower, 1.0)
        assert np.all(~inside | (qn <= lim.upper + 1e-6 * span)), (qn, lim.upper)
        assert np.all(~inside | (qn >= lim.lower - 1e-6 * span)), (qn, lim.lower)
    # (3) optimal: the same objective as an exact reference
    P, b = _objective_matrices(opts, J, xi)
    blo, bhi = (lo, hi) if qd_ff is None else (lo - qd_ff, hi - qd_ff)
    f = 0.5 * qd @ P @ qd - b @ qd
    ref = enumerate_box_qp(P, b, blo, bhi) if n <= 5 else box_qp_exact(P, b, blo, bhi)[0]
    assert ref is not None
    fref = 0.5 * ref @ P @ ref - b @ ref
    fscale = 1e-8 * (1.0 + abs(fref) + float(np.abs(P).max()) * float(np.abs(ref).max() + 1.0) ** 2
                     + float(np.abs(b).max()) * float(np.abs(ref).max() + 1.0))
    assert f <= fref + fscale, (f, fref, res.info["status"])
    return res


def test_qp_answers_are_inside_their_box_and_optimal(fuzz):
    @fuzz.settings(50)
    @given(seed=st.integers(0, 2**32 - 1))
    def prop(seed):
        _check_qp(fuzz, seed)

    prop()


def test_qp_with_ill_conditioned_task_weights_is_certified_optimal(fuzz):
    @fuzz.settings(30)
    @given(seed=st.integers(0, 2**32 - 1))
    def prop(seed):
        _check_qp(fuzz, seed, ill=True)

    prop()


def test_qp_with_feed_forward_bounds_the_total(fuzz):
    @fuzz.settings(30)
    @given(seed=st.integers(0, 2**32 - 1))
    def prop(seed):
        _check_qp(fuzz, seed, with_ff=True)

    prop()


@pytest.mark.skipif(not HAVE_DAQP, reason="daqp not installed")
def test_qp_matches_daqp(fuzz):
    @fuzz.settings(15)
    @given(seed=st.integers(0, 2**32 - 1))
    def prop(seed):
        opts, J, xi, lim, q, qd_prev, dt = _problem(seed)
        a = QP(**opts).solve(J, xi, limits=lim, q=q, qd_prev=qd_prev, dt=dt)
        b = QP(backend="daqp", **opts).solve(J, xi, limits=lim, q=q, qd_prev=qd_prev, dt=dt)
        fuzz.count("qp", 2)
        P, bb = _objective_matrices(opts, J, xi)
        fa = 0.5 * a.qd @ P @ a.qd - bb @ a.qd
        fb = 0.5 * b.qd @ P @ b.qd - bb @ b.qd
        assert fa <= fb + 1e-8 * (1.0 + abs(fb) + float(np.abs(P).max()) + float(np.abs(bb).max()))

    prop()


def test_exact_box_solver_equals_enumeration(fuzz):
    @fuzz.settings(30)
    @given(seed=st.integers(0, 2**32 - 1))
    def prop(seed):
        r = np.random.default_rng(seed)
        n = int(r.integers(1, 6))
        A = r.standard_normal((n + 2, n)) * 10.0 ** r.uniform(-2, 2, n)
        P = A.T @ A + 10.0 ** r.uniform(-8, 0) * np.eye(n)
        b = r.standard_normal(n) * 10.0 ** r.uniform(-2, 2)
        lo = -r.uniform(0, 2, n)
        hi = r.uniform(0, 2, n)
        lo[r.random(n) < 0.2] = -INF
        hi[r.random(n) < 0.2] = INF
        x, state = box_qp_exact(P, b, lo, hi, r.standard_normal(n))
        fuzz.count("box_qp_exact")
        ref = enumerate_box_qp(P, b, lo, hi)
        assert x is not None and np.all(x >= lo) and np.all(x <= hi)
        f, fr = 0.5 * x @ P @ x - b @ x, 0.5 * ref @ P @ ref - b @ ref
        assert f <= fr + 1e-9 * (1.0 + abs(fr) + float(np.abs(P).max()) * (1 + float(np.abs(ref).max())) ** 2)

    prop()


# ---------------------------------------------------------------------- hostile inputs
SOLVERS = [
    lambda: rc.solvers.Inverse(),
    lambda: rc.solvers.PseudoInverse(),
    lambda: rc.solvers.DLS(damping=0.05),
    lambda: rc.solvers.DLS(damping=1e-300),
    lambda: rc.solvers.AdaptiveDLS(),
    lambda: rc.solvers.AdaptiveDLS(mode="filtered"),
    lambda: rc.solvers.AdaptiveDLS(mode="manipulability", manipulability_threshold=0.01),
    lambda: rc.solvers.SDLS(),
    lambda: rc.solvers.SDLS(joint_weights=[1e-4, 1.0, 1e4, 1.0, 1.0, 1.0]),
    lambda: rc.solvers.QP(),
    lambda: rc.solvers.QP(damping=0.0),
    lambda: rc.solvers.QP(task_weights=[1e6, 1, 1, 1, 1, 1]),
]


def _hostile_J(r):
    kind = int(r.integers(0, 9))
    n = 6
    J = r.standard_normal((6, n))
    if kind == 0:
        return J * 10.0 ** r.uniform(100, 200), r.standard_normal(6)
    if kind == 1:
        return J * 10.0 ** r.uniform(-320, -100), r.standard_normal(6)
    if kind == 2:
        J[r.integers(0, 6), r.integers(0, n)] = r.choice([np.nan, np.inf, -np.inf])
        return J, r.standard_normal(6)
    if kind == 3:
        return J, r.standard_normal(6) * 10.0 ** r.uniform(100, 308)
    if kind == 4:
        return np.zeros((6, n)), r.standard_normal(6)
    if kind == 5:
        return J, np.full(6, np.nan)
    if kind == 6:  # rank 1 and huge
        u, v = r.standard_normal(6), r.standard_normal(n)
        return np.outer(u, v) * 1e140, r.standard_normal(6)
    if kind == 7:
        return J * 10.0 ** r.uniform(-6, 6), r.standard_normal(6) * 10.0 ** r.uniform(-6, 6)
    return J.astype(complex) + 1j, r.standard_normal(6)


def test_every_solver_answers_finite_or_raises_a_ratectl_error(fuzz):
    lim = Limits(lower=-np.ones(6), upper=np.ones(6), vmax=np.full(6, 2.0), amax=np.full(6, 10.0))

    @fuzz.settings(20)
    @given(seed=st.integers(0, 2**32 - 1))
    def prop(seed):
        r = np.random.default_rng(seed)
        J, xi = _hostile_J(r)
        for make in SOLVERS:
            s = make()
            for kw in ({}, {"limits": lim, "q": np.zeros(6), "qd_prev": np.zeros(6), "dt": 0.01}):
                fuzz.count("solver")
                with warnings.catch_warnings():
                    warnings.simplefilter("error")  # no RuntimeWarning either
                    try:
                        res = s.solve(J, xi, **kw)
                    except RatectlError:
                        continue
                assert np.all(np.isfinite(res.qd)), (s, res.qd)
                if isinstance(s, rc.solvers.SDLS):
                    assert np.max(np.abs(res.qd)) <= s.gamma_max * (1 + 1e-9)

    prop()


@pytest.mark.parametrize("bad", [np.zeros((0, 0)), np.zeros((6, 0)), np.zeros((0, 6)), "abc", [[1, "x"]],
                                 None, np.zeros((2, 2, 2)), [[1j, 0], [0, 1]]])
def test_malformed_J_is_an_input_error(bad):
    for make in SOLVERS:
        with pytest.raises(rc.errors.InputError):
            make().solve(bad, np.zeros(6) if not isinstance(bad, np.ndarray) or bad.ndim != 2
                         else np.zeros(bad.shape[0]))


@pytest.mark.parametrize("kw", [{"dt": "0.1"}, {"dt": -1.0}, {"dt": np.nan}, {"q": "abc"},
                                {"q": [np.nan, 0.0]}, {"qd_prev": [np.inf, 0.0]}, {"qd_ff": [1j, 0]},
                                {"dt": 1j}, {"q": [0.0]}])
def test_malformed_qp_options_are_input_errors(kw):
    lim = Limits(lower=[-1, -1], upper=[1, 1], vmax=[1, 1], amax=[1, 1])
    base = {"limits": lim, "q": np.zeros(2), "dt": 0.01}
    base.update(kw)
    with pytest.raises(rc.errors.InputError):
        QP().solve(np.eye(2), np.ones(2), **base)


@pytest.mark.skipif(not HAVE_DAQP, reason="daqp not installed")
@pytest.mark.parametrize("ill", [False, True], ids=["plain", "ill-conditioned"])
def test_qp_with_extra_rows_is_feasible_and_matches_daqp(fuzz, ill):
    @fuzz.settings(20)
    @given(seed=st.integers(0, 2**32 - 1))
    def prop(seed):
        opts, J, xi, lim, q, qd_prev, dt = _problem(seed, ill=ill)
        r = np.random.default_rng(seed + 7)
        n = J.shape[1]
        k = int(r.integers(1, 4))
        G = r.standard_normal((k, n))
        h = r.uniform(0.0, 0.5, k)  # q̇ = 0 is feasible for the rows
        kw = dict(limits=lim, q=q, qd_prev=qd_prev, dt=dt, extra_inequalities=(G, h))
        fuzz.count("qp", 2)
        vb = joint_velocity_bounds(lim, q=q, qd_prev=qd_prev, dt=dt)
        try:
            ref = QP(backend="daqp", **opts).solve(J, xi, **kw)
        except RatectlError:
            return  # the box and the rows have no common point (the box may exclude 0)
        a = QP(**opts).solve(J, xi, **kw)  # feasible: an answer, never a SolverError
        assert np.all(G @ a.qd <= h + 1e-6 * (1 + np.abs(h)))
        assert _in_box(a.qd, vb.lower, vb.upper)
        P, bb = _objective_matrices(opts, J, xi)
        fa = 0.5 * a.qd @ P @ a.qd - bb @ a.qd
        fr = 0.5 * ref.qd @ P @ ref.qd - bb @ ref.qd
        assert fa <= fr + 1e-7 * (1.0 + abs(fr) + float(np.abs(P).max()) + float(np.abs(bb).max()))

    prop()


def _degenerate_rows_problem(seed):
    """A small QP with degenerate constraints (a fixed joint lo = hi, a repeated row, rows
    through one point) and an ill-conditioned P: (P, b, lo, hi, G, h)."""
    r = np.random.default_rng(seed)
    n = int(r.integers(1, 6))
    A = r.standard_normal((n + 2, n)) * 10.0 ** r.uniform(-2, 3, n)
    P = A.T @ A + 10.0 ** r.uniform(-8, 0) * np.eye(n)
    b = r.standard_normal(n) * 10.0 ** r.uniform(-2, 3)
    lo, hi = -r.uniform(0, 2, n), r.uniform(0, 2, n)
    fixed = r.random(n) < 0.3
    lo = np.where(fixed, hi, lo)
    G = r.standard_normal((int(r.integers(1, 4)), n))
    if r.random() < 0.5:
        G = np.vstack([G, G[:1]])  # a repeated row
    x_in = lo + (hi - lo) * r.random(n)
    h = G @ x_in + r.uniform(0.0, 0.3, G.shape[0]) * (r.random(G.shape[0]) < 0.6)
    return P, b, lo, hi, G, h


@pytest.mark.skipif(not HAVE_DAQP, reason="daqp not installed")
def test_primal_active_set_solver_matches_daqp_on_degenerate_rows(fuzz):
    """The QP's last resort (`qp_primal_active_set`) is exact where OSQP and the dual give up:
    fixed joints, repeated rows, rows through one point, P with condition up to 1e13."""
    from ratectl.solvers.qp.active_set import qp_primal_active_set

    @fuzz.settings(30)
    @given(seed=st.integers(0, 2**32 - 1))
    def prop(seed):
        P, b, lo, hi, G, h = _degenerate_rows_problem(seed)
        fuzz.count("qp_primal_active_set")
        x = qp_primal_active_set(P, b, lo, hi, G, h)
        assert x is not None  # feasible by construction
        assert np.all(G @ x <= h + 1e-9 * (1 + np.abs(h))) and _in_box(x, lo, hi, rel=1e-9)
        ref = qpsolvers.solve_qp(P, -b, G, h, lb=lo, ub=hi, solver="daqp")
        if ref is None:
            return
        fx, fr = 0.5 * x @ P @ x - b @ x, 0.5 * ref @ P @ ref - b @ ref
        size = float(np.abs(P).max()) * (1 + float(np.abs(ref).max())) ** 2
        # daqp's answer may violate a row by ~1e-9, which buys it |∇f|·1e-9 of objective
        slope = float(np.abs(P @ ref - b).max()) * (1 + float(np.abs(ref).max()))
        assert fx <= fr + 1e-9 * (1.0 + abs(fr) + size) + 1e-8 * slope

    prop()


def _in_box(x, lo, hi, rel=1e-6):
    tol = rel * (1.0 + np.abs(x))
    return bool(np.all(x >= lo - tol) and np.all(x <= hi + tol))


def _qp_loop(seed, *, vary_dt: bool, steps: int = 300):
    """A closed loop of the QP alone: q̇ = q̇_ff + c with a moving feed-forward that drives
    joints into their limits; returns the worst |Δq̇|/(amax·dt) and the worst excursion past a
    position limit [rad]."""
    r = np.random.default_rng(seed)
    n = int(r.integers(1, 4))
    lim = Limits(lower=-r.uniform(0.2, 1.0, n), upper=r.uniform(0.2, 1.0, n),
                 vmax=r.uniform(0.5, 2.0, n), amax=r.uniform(1.0, 10.0, n))
    J = r.standard_normal((int(r.integers(1, 4)), n))
    s = QP(damping=float(r.choice([1e-3, 0.05])))
    q, qd = np.zeros(n), np.zeros(n)
    dt0 = float(r.choice([0.001, 0.004, 0.01]))
    amp, freq = r.uniform(0.5, 3.0, n), r.uniform(0.2, 3.0, n)
    worst_a = worst_q = 0.0
    t = 0.0
    for _ in range(steps):
        dt = float(r.choice([0.001, 0.004, 0.01])) if vary_dt else dt0
        ff = amp * np.sin(freq * t)
        res = s.solve(J, r.standard_normal(J.shape[0]) * 0.2, limits=lim, q=q, qd_prev=qd, dt=dt, qd_ff=ff)
        total = res.qd + ff
        worst_a = max(worst_a, float(np.max(np.abs(total - qd) / (lim.amax * dt))))
        qd, q, t = total, q + total * dt, t + dt
        worst_q = max(worst_q, float(np.max(np.maximum(q - lim.upper, lim.lower - q))))
    return worst_a, worst_q


def test_qp_closed_loop_with_feed_forward_holds_every_limit(fuzz):
    @fuzz.settings(4)
    @given(seed=st.integers(0, 2**32 - 1))
    def prop(seed):
        fuzz.count("qp", 300)
        worst_a, worst_q = _qp_loop(seed, vary_dt=False)
        assert worst_a <= 1.0 + 1e-6 and worst_q <= 1e-9

    prop()


def test_qp_closed_loop_with_changing_dt_holds_every_limit(fuzz):
    """A new dt (1, 4 or 10 ms) every period while joints are braking for their position
    limits: the braking bound holds for any later dt, so the acceleration bound and the
    braking bound always meet (it reached 9.9× amax with the constant-dt bound)."""
    @fuzz.settings(4)
    @given(seed=st.integers(0, 2**32 - 1))
    def prop(seed):
        fuzz.count("qp", 300)
        worst_a, worst_q = _qp_loop(seed, vary_dt=True)
        assert worst_a <= 1.0 + 1e-6 and worst_q <= 1e-9

    prop()


@pytest.mark.skipif(not HAVE_DAQP, reason="daqp not installed")
def test_exact_dual_solver_matches_daqp_with_extra_rows(fuzz):
    from ratectl.solvers.qp.active_set import qp_via_dual

    @fuzz.settings(30)
    @given(seed=st.integers(0, 2**32 - 1))
    def prop(seed):
        opts, J, xi, lim, q, qd_prev, dt = _problem(seed)
        r = np.random.default_rng(seed + 11)
        n = J.shape[1]
        G = r.standard_normal((int(r.integers(1, 4)), n))
        h = r.uniform(0.0, 0.5, G.shape[0])
        vb = joint_velocity_bounds(lim, q=q, qd_prev=qd_prev, dt=dt)
        P, bb = _objective_matrices(opts, J, xi)
        ev = np.linalg.eigvalsh(P)
        if not ev[0] > 1e-12 * ev[-1]:
            return  # the dual needs a positive definite P (damping > 0)
        fuzz.count("qp_via_dual")
        try:
            ref = QP(backend="daqp", **opts).solve(J, xi, limits=lim, q=q, qd_prev=qd_prev, dt=dt,
                                                   extra_inequalities=(G, h)).qd
        except RatectlError:
            return
        x = qp_via_dual(P, bb, vb.lower, vb.upper, G, h)
        if x is None:  # best effort: a degenerate dual may not settle (the QP then reports)
            fuzz.count("qp_via_dual_no_answer")
            return
        assert np.all(G @ x <= h + 1e-6 * (1 + np.abs(h))) and _in_box(x, vb.lower, vb.upper)
        fx, fr = 0.5 * x @ P @ x - bb @ x, 0.5 * ref @ P @ ref - bb @ ref
        # a fallback through P⁻¹: its accuracy follows the conditioning of P (1e-6 relative)
        assert fx <= fr + 1e-6 * (1.0 + abs(fr) + float(np.abs(P).max()) + float(np.abs(bb).max()))

    prop()


def test_no_qp_path_writes_to_stdout(fuzz, capfd):
    """OSQP 1.x prints "Polishing not needed" from C (fd 1) whenever its polish finds no
    active bound, verbose or not; it used to reach the terminal during control steps (an
    interior optimum with the shortcut off, most extra-rows problems). Every path of the
    QP — box only, extra rows, feed-forward, shortcut off, retries — is silent."""
    lim = Limits(lower=[-1.0, -1.0], upper=[1.0, 1.0], vmax=[2.0, 2.0], amax=[10.0, 10.0])
    QP(shortcut=False).solve(np.eye(2), [0.1, 0.1], limits=lim, q=np.zeros(2), dt=0.01)  # interior
    fuzz.count("qp")
    n_calls = fuzz.loops(60)
    for seed in range(n_calls):
        opts, J, xi, lim, q, qd_prev, dt = _problem(seed)
        r = np.random.default_rng(seed + 7)
        G = r.standard_normal((int(r.integers(1, 4)), J.shape[1]))
        h = r.uniform(0.0, 0.5, G.shape[0])
        for kw in ({"extra_inequalities": (G, h)}, {}):
            for shortcut in (True, False):
                fuzz.count("qp")
                try:
                    QP(shortcut=shortcut, **opts).solve(J, xi, limits=lim, q=q, qd_prev=qd_prev, dt=dt, **kw)
                except RatectlError:
                    pass
    out, _ = capfd.readouterr()
    assert out == "", out[:200]
