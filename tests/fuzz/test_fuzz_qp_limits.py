"""Fuzz: the QP on narrow and locked joints with margins, and with weights of extreme size.

* Margins: for any range (locked: lower == upper, or narrower than 2·margin), margin, q
  inside the range, q̇_prev and dt, the next position q + q̇·dt stays inside the range,
  unless the QP reports an acceleration conflict for that joint (the acceleration limit
  cannot stop it in time); a position conflict is reported only for a joint outside its
  range.
* Weights 1e6 / 1e-6 (task and joint weights) on a warm solver over consecutive steps:
  every answer passes the per-joint optimality measure (`kkt_violation`) and its objective
  equals the exact active set's.
"""

from __future__ import annotations

import numpy as np
from hypothesis import given
from hypothesis import strategies as st

import ratectl as rc
from ratectl.model.limits import Limits
from ratectl.solvers import QP, joint_velocity_bounds
from ratectl.solvers.qp.active_set import box_qp_exact, kkt_violation

_ARM = rc.robots.ur5e()


def _narrow_problem(seed):
    r = np.random.default_rng(seed)
    n = 6
    lower = r.uniform(-2.0, 0.0, n)
    width = r.choice([0.0, 1e-6, 1e-4, 1e-3, 1e-2, 1.0], n)
    upper = lower + width
    q = lower + r.random(n) * width
    margin = float(r.choice([0.0, 1e-4, 1e-3, 3e-3, 0.1, 1.0]))
    dt = float(r.choice([1e-3, 1e-2, 0.1, 1.0]))
    qd_prev = r.normal(0.0, 0.5, n) if r.random() < 0.5 else None
    lim = Limits(lower=lower, upper=upper, vmax=r.uniform(0.1, 3.0, n),
                 amax=r.choice([np.inf, 1.0, 10.0, 100.0], n))
    J = _ARM.jacobian(r.uniform(-3.0, 3.0, n))
    xi = r.normal(0.0, 1.0, 6)
    return lim, q, margin, dt, qd_prev, J, xi


def test_a_margin_wider_than_half_the_range_keeps_the_joint_in_its_range(fuzz):
    @fuzz.settings(200)
    @given(seed=st.integers(0, 2**32 - 1))
    def prop(seed):
        lim, q, margin, dt, qd_prev, J, xi = _narrow_problem(seed)
        res = QP(margin=margin).solve(J, xi, limits=lim, q=q, dt=dt, qd_prev=qd_prev)
        vb = joint_velocity_bounds(lim, q=q, dt=dt, qd_prev=qd_prev, margin=margin)
        fuzz.count("qp", 2)
        qn = q + np.asarray(res.qd) * dt
        span = lim.upper - lim.lower
        tol = 1e-9 * (1.0 + np.abs(q))
        out = (qn < lim.lower - tol) | (qn > lim.upper + tol)
        conflicts = dict(res.info.get("conflicts", ()))
        assert conflicts == dict(vb.conflicts)
        for j in np.flatnonzero(out):
            assert "acceleration" in conflicts.get(int(j), ()), (j, qn[j], lim.lower[j], lim.upper[j])
        for j, kinds in conflicts.items():
            if "position" in kinds:  # only a joint beyond its (margin-reduced) range
                m = min(margin, span[j] / 2)
                assert q[j] > lim.upper[j] - m or q[j] < lim.lower[j] + m
        # the margin is kept where the range allows it: the position bound never points
        # farther out than the joint's centre
        centre = 0.5 * (lim.lower + lim.upper)
        narrow = span <= 2 * margin
        if qd_prev is None:
            assert np.all(~narrow | (vb.upper * dt >= np.minimum(centre - q, 0.0) - tol))
            assert np.all(~narrow | (vb.lower * dt <= np.maximum(centre - q, 0.0) + tol))

    prop()


def test_a_locked_joint_with_a_margin_does_not_move():
    lim = Limits(lower=np.r_[0.0, -np.ones(5)], upper=np.r_[0.0, np.ones(5)], vmax=np.full(6, 2.0),
                 amax=np.full(6, 10.0))
    q = np.zeros(6)
    for qd_prev in (None, np.zeros(6), np.full(6, 0.05)):
        res = QP(margin=0.003).solve(_ARM.jacobian(q), np.array([0.1, 0.2, 0, 0, 0, 0.3]), limits=lim, q=q,
                                     dt=0.01, qd_prev=qd_prev)
        assert res.qd[0] == 0.0 or "acceleration" in dict(res.info.get("conflicts", ())).get(0, ())


_WEIGHTS = (1e-6, 1.0, 1e6)


def _release_step(P, b, lo, hi, x):
    """The largest |g_i| / P_ii over joints whose gradient g = Px − b violates the KKT sign
    (free with g ≠ 0, at a bound with g pointing inward): how far, at least, joint i moves
    when released, relative to 1 + ‖x‖∞."""
    g = P @ x - b
    eps = 1e-12 * (1.0 + np.abs(x))
    at_hi = x >= hi - eps
    at_lo = (x <= lo + eps) & ~at_hi
    gv = np.where(at_hi, np.maximum(g, 0.0), np.where(at_lo, np.maximum(-g, 0.0), np.abs(g)))
    gv = np.where(hi - lo <= eps, 0.0, gv)
    return float(np.max(gv / np.diagonal(P))) / (1.0 + float(np.max(np.abs(x))))


def test_warm_qp_with_extreme_weights_is_optimal_joint_by_joint(fuzz):
    arms = [rc.robots.ur5e(), rc.robots.panda(), rc.robots.puma560()]

    @fuzz.settings(80)
    @given(seed=st.integers(0, 2**32 - 1))
    def prop(seed):
        r = np.random.default_rng(seed)
        arm = arms[seed % 3]
        n = arm.dof
        tw = r.choice(_WEIGHTS, 6)
        jw = r.choice(_WEIGHTS, n) if r.random() < 0.5 else None
        solver = QP(task_weights=tw, joint_weights=jw, damping=float(r.choice([1e-3, 0.05])))
        q = r.uniform(arm.lower, arm.upper)
        qd_prev = np.zeros(n)
        for _ in range(6):  # consecutive steps: OSQP stays warm
            J = arm.jacobian(q)
            xi = r.normal(0.0, 1.0, 6)
            res = solver.solve(J, xi, limits=arm, q=q, qd_prev=qd_prev, dt=0.01)
            fuzz.count("qp")
            qd = np.asarray(res.qd)
            lo, hi = res.info["lower"], res.info["upper"]
            wq = np.ones(n) if jw is None else jw
            P = J.T @ (tw[:, None] * J) + solver.damping**2 * np.diag(wq)
            b = J.T @ (tw * xi)
            assert kkt_violation(P, b, lo, hi, qd) <= 1e-9, res.info["status"]
            assert _release_step(P, b, lo, hi, qd) <= 1e-6, res.info["status"]
            ref, _ = box_qp_exact(P, b, lo, hi, None)
            assert ref is not None
            f, fr = 0.5 * qd @ P @ qd - b @ qd, 0.5 * ref @ P @ ref - b @ ref
            assert f <= fr + 1e-10 * (1.0 + abs(fr)), (f, fr, res.info["status"])
            q = q + qd * 0.01
            qd_prev = qd

    prop()
