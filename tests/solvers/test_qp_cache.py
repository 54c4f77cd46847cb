"""The QP's reuse of P and its Cholesky factor between two solves with the same J."""

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

import ratectl as rc


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
