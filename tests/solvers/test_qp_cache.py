"""The QP's reuse of P and its Cholesky factor between two solves with the same J."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import ratectl as rc
from ratectl.solvers.base import exact_direction_floor, sigma_at_least


@settings(max_examples=60, deadline=None)
@given(st.integers(0, 10_000), st.booleans())
def test_a_second_solve_with_the_same_J_equals_a_fresh_solve(seed, limited):
    """solve(J, a) then solve(J, b) gives what a fresh QP gives for (J, b), with and without
    limits; a J changed in place between the two is not mistaken for the same J."""
    rng = np.random.default_rng(seed)
    arm = rc.robots.ur5e()
    q = rng.uniform(-2, 2, 6)
    J = arm.jacobian(q)
    a, b = rng.standard_normal(6), rng.standard_normal(6)
    kw = dict(limits=arm, q=q, qd_prev=np.zeros(6), dt=1e-3) if limited else {}
    warm = rc.solvers.QP()
    warm.solve(J, a, **kw)
    got = warm.solve(J, b, **kw)
    want = rc.solvers.QP().solve(J, b, **kw)
    assert np.allclose(got.qd, want.qd, rtol=0, atol=1e-12 * (1 + np.abs(want.qd).max()))
    assert got.sigma_min == want.sigma_min or abs(got.sigma_min - want.sigma_min) < 1e-12
    J2 = J.copy()
    warm.solve(J2, a, **kw)
    J2[:, 0] *= 2.0  # the same array, other entries
    got2 = warm.solve(J2, b, **kw)
    want2 = rc.solvers.QP().solve(J2, b, **kw)
    assert np.allclose(got2.qd, want2.qd, rtol=0, atol=1e-12 * (1 + np.abs(want2.qd).max()))


@settings(max_examples=80, deadline=None)
@given(st.integers(0, 10_000), st.sampled_from(["plain", "weighted", "rows", "objective", "undamped"]),
       st.sampled_from(["QP", "DLS"]))
def test_solve_direction_is_exact_where_J_is_regular(seed, kind, name):
    """`Solver.solve_direction` (the jog's and the servo's direction per unit of progress):
    wherever J has full rank (σ_min above `exact_direction_floor`) a constant-damping solver
    (QP, DLS) answers exactly — J w = d, the least W_q-norm w (the regulariser would shrink
    each singular direction on its own and turn the motion); below, or with an objective,
    it is what ``solve`` gives without limits, bit for bit. Its σ says the same as the
    result's σ_min, and a following limited solve with the same J still equals a fresh one."""
    rng = np.random.default_rng(seed)
    arm = rc.robots.ur5e()
    q = rng.uniform(-2, 2, 6)
    if seed % 5 == 0:
        q[4] = rng.choice([0.0, 0.02, 0.06])  # at, or near, a wrist singularity
    J = arm.jacobian(q)
    d = rng.standard_normal(6)
    wq = rng.uniform(0.5, 2.0, 6)
    kw = {"plain": {}, "weighted": {"joint_weights": wq}, "rows": {"task_weights": "position"},
          "objective": {"objective": "centring", "chain": arm}, "undamped": {"damping": 0.0}}[kind]
    if name == "DLS" and kind in ("objective", "undamped"):  # (not DLS options)
        kind, kw = "plain", {}
    make = (lambda: rc.solvers.QP(**kw)) if name == "QP" else (lambda: rc.solvers.DLS(**kw))
    try:
        want = make().solve(J, d, q=q, dt=1e-3)
    except rc.errors.RatectlError as err:
        with pytest.raises(type(err)):
            make().solve_direction(J, d, q=q, dt=1e-3)
        return
    solver = make()
    w, sig, damping = solver.solve_direction(J, d, q=q, dt=1e-3)
    assert w.flags.writeable
    rows = [0, 1, 2] if kind == "rows" else list(range(6))
    smin = np.linalg.svd(J[rows], compute_uv=False)[-1]
    # exact wherever the (row-selected) J has full rank: σ_min above the floor
    floor = exact_direction_floor(J=J[rows])
    # (the undamped QP has no positive-definite P, hence no shortcut: its answer is `solve`'s)
    exact = kind not in ("objective", "undamped") and smin >= floor * (1 + 1e-6)
    if exact:
        assert damping == 0.0
        # J w = d on the rows, and w the least W_q-norm solution: w = W_q⁻¹ Jᵀ y
        assert np.allclose(J[rows] @ w, d[rows], rtol=0, atol=1e-8 * (1 + np.abs(w).max()))
        W = np.diag(1 / wq) if kind == "weighted" else np.eye(6)
        want_w = W @ J[rows].T @ np.linalg.solve(J[rows] @ W @ J[rows].T, d[rows])
        assert np.allclose(w, want_w, rtol=1e-7, atol=1e-9)
    elif kind == "objective" or smin < floor * (1 - 1e-6):
        assert w.tolist() == want.qd.tolist() and damping == want.damping
    for threshold in (1e-3, 0.05, 0.2, float(want.sigma_min) * (1 + 1e-9)):
        above, value = sigma_at_least(sig, threshold)
        assert above == (want.sigma_min >= threshold)
        assert np.isnan(value) or abs(value - want.sigma_min) <= 1e-12
    if name == "QP":
        xi = rng.standard_normal(6)
        lim = dict(limits=arm, q=q, qd_prev=np.zeros(6), dt=1e-3)
        got = solver.solve(J, xi, **lim)
        fresh = make().solve(J, xi, **lim)
        assert np.allclose(got.qd, fresh.qd, rtol=0, atol=1e-12 * (1 + np.abs(fresh.qd).max()))


def test_a_subclass_with_its_own_solve_keeps_it_for_directions():
    """A QP subclass that overrides ``solve`` (rows of its own) is asked through that
    ``solve`` for a direction too: the QP's factorisation-only entry would bypass it."""
    calls = []

    class Counting(rc.solvers.QP):
        def solve(self, J, xi, **kw):
            calls.append(kw)
            return super().solve(J, xi, **kw)

    arm = rc.robots.ur5e()
    q = np.array([0.3, -1.2, 1.5, -1.9, -1.4, 0.6])
    w, res, _ = Counting().solve_direction(arm.jacobian(q), np.eye(6)[0], q=q, dt=1e-3)
    assert len(calls) == 1 and w.tolist() == res.qd.tolist()
