"""Strict priorities: the cascade (unit) and the Panda acceptance (tool + elbow + posture)."""

import sys
from pathlib import Path

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

import ratectl as rc
from ratectl.solvers.priority import PriorityCascade

sys.path.insert(0, str(Path(__file__).resolve().parent))
from panda_erd import HOME, panda_chain, panda_urdf  # noqa: E402

URDF = panda_urdf()
BACKENDS = ["daqp", "exact", "proxqp", "quadprog"]


class _Box:
    def __init__(self, n, vmax):
        self.lower = np.full(n, -np.inf)
        self.upper = np.full(n, np.inf)
        self.vmax = np.full(n, vmax)
        self.amax = np.full(n, np.inf)


@settings(max_examples=25)
@given(st.integers(0, 2**31 - 1), st.sampled_from(BACKENDS))
def test_lower_level_never_changes_what_a_higher_level_achieves(seed, backend):
    rng = np.random.default_rng(seed)
    n = 7
    A0, b0 = rng.normal(size=(4, n)), rng.normal(size=4)
    A1, b1 = rng.normal(size=(3, n)), 3 * rng.normal(size=3)
    A2, b2 = np.eye(n), rng.normal(size=n)
    lim = _Box(n, float(rng.uniform(0.3, 2.0)))
    c = PriorityCascade(backend=backend)
    alone = c.solve([(A0, b0)], limits=lim)
    full = c.solve([(A0, b0), (A1, b1), (A2, b2)], limits=lim)
    # the higher level's achieved residual is kept (within the solver tolerance)
    assert full.residuals[0] <= alone.residuals[0] + 1e-5 * (1 + alone.residuals[0])
    assert np.all(np.abs(full.qd) <= lim.vmax + 1e-6)
    two = c.solve([(A0, b0), (A1, b1)], limits=lim)
    assert full.residuals[1] <= two.residuals[1] + 1e-5 * (1 + two.residuals[1])


def test_no_active_inequality_is_null_space_projection():
    rng = np.random.default_rng(1)
    n = 7
    A0, b0 = rng.normal(size=(6, n)), rng.normal(size=6)
    z = rng.normal(size=n)
    res = PriorityCascade(damping=0.0).solve([(A0, b0), (np.eye(n), z)])
    pinv = np.linalg.pinv(A0)
    expected = pinv @ b0 + (np.eye(n) - pinv @ A0) @ z
    np.testing.assert_allclose(res.qd, expected, atol=1e-9)
    assert not res.qps.any()


@pytest.mark.parametrize("backend", BACKENDS)
def test_extra_rows_hold_at_every_level(backend):
    rng = np.random.default_rng(2)
    n = 7
    A0, b0 = rng.normal(size=(6, n)), rng.normal(size=6)
    G, h = rng.normal(size=(2, n)), np.array([0.05, -0.02])
    res = PriorityCascade(backend=backend).solve([(A0, b0), (np.eye(n), np.ones(n))], limits=_Box(n, 1.0),
                                                 extra_inequalities=(G, h))
    tol = 1e-4 if backend == "proxqp" else 1e-6  # proxqp stops at its own (looser) tolerance
    assert np.all(G @ res.qd <= h + tol)


def test_infeasible_rows_are_relaxed_and_reported():
    n = 3
    G = np.array([[1.0, 0.0, 0.0]])
    h = np.array([-5.0])  # q̇_0 ≤ −5 with |q̇| ≤ 1: impossible
    res = PriorityCascade().solve([(np.eye(n), np.zeros(n))], limits=_Box(n, 1.0), extra_inequalities=(G, h))
    assert res.relaxed[0] == pytest.approx(4.0, abs=1e-5)
    assert res.qd[0] == pytest.approx(-1.0, abs=1e-6)


def _reference(T0, t, Tf=1.5):
    s = min(t / Tf, 1.0)
    s5 = 10 * s**3 - 15 * s**4 + 6 * s**5
    sp = (30 * s**2 - 60 * s**3 + 30 * s**4) / Tf if t < Tf else 0.0
    dp, w = np.array([0.1, 0.1, -0.1]), np.array([0.0, 0.0, 0.3])
    T = T0.copy()
    T[:3, 3] += s5 * dp
    T[:3, :3] = rc.spatial.so3_exp(s5 * w) @ T0[:3, :3]
    return T, np.concatenate([sp * dp, sp * w])


@pytest.mark.skipif(URDF is None, reason="example-robot-data is not installed")
def test_panda_tool_elbow_posture_acceptance():
    ch = panda_chain(URDF)
    dt, N = 1e-3, 2000
    T0 = ch.fk(HOME)
    p4 = ch.fk(HOME, link="panda_link4")[:3, 3]
    p4t = p4 + np.array([0.0, 0.15, 0.05])

    def run(with_lower):
        tool = rc.tasks.Pose(priority=0)
        tasks = [tool]
        if with_lower:
            tasks += [rc.tasks.Position(link="panda_link4", priority=1, target=p4t, gain=2.0),
                      rc.tasks.Posture(HOME, priority=2, gain=1.0)]
        ctrl = rc.ResolvedRateController(ch, tasks=tasks)
        q = HOME.copy()
        Ts, qs, qds, res = [], [], [], []
        for k in range(N):
            tool.set_target(*_reference(T0, k * dt)[:1], twist=_reference(T0, k * dt)[1])
            cmd = ctrl.step(q, dt=dt)
            assert cmd.status != "halted", cmd.reason
            q = cmd.q_next.copy()
            Ts.append(ch.fk(q))
            qs.append(q)
            qds.append(cmd.qd.copy())
            res.append(cmd.solve.residuals.copy())
        return np.array(Ts), np.array(qs), np.array(qds), res

    Ta, _, _, _ = run(False)
    Tb, qb, qdb, res = run(True)
    assert len(res[-1]) == 3  # each level's residual in the command
    assert np.abs(Ta[:, :3, 3] - Tb[:, :3, 3]).max() <= 1e-5
    dR = max(np.linalg.norm(rc.spatial.so3_log(a[:3, :3] @ b[:3, :3].T)) for a, b in zip(Ta, Tb, strict=True))
    assert dR <= 1e-4
    p_end = ch.fk(qb[-1], link="panda_link4")[:3, 3]
    assert 1 - np.linalg.norm(p_end - p4t) / np.linalg.norm(p4 - p4t) >= 0.3
    assert np.all(np.abs(qdb) <= ch.vmax * (1 + 1e-9))
    qdd = np.diff(np.vstack([np.zeros(7), qdb]), axis=0) / dt
    assert np.all(np.abs(qdd) <= ch.amax * (1 + 1e-6))
    assert ch.within_limits(qb).all()


@pytest.mark.parametrize("backend", ["daqp", "exact"])
@pytest.mark.parametrize("seed", range(6))
def test_rows_relaxed_to_a_corner_of_the_box_still_give_a_command(seed, backend):
    # a row that only the corner q̇ = −sign(G₀)·vmax can come near: the relaxed feasible set
    # is a sliver at that corner (found in the loop: a damper the acceleration box cannot meet)
    rng = np.random.default_rng(seed)
    n = 7
    A, b = rng.normal(size=(6, n)), 3 * rng.normal(size=6)
    G = rng.normal(size=(3, n))
    corner = -np.sign(G[0])
    h = np.concatenate([[G[0] @ corner - 0.05], G[1:] @ corner + 0.5])  # the others hold there
    res = PriorityCascade(backend=backend).solve([(A, b), (np.eye(n), np.zeros(n))], limits=_Box(n, 1.0),
                                                 extra_inequalities=(G, h))
    assert res.relaxed[0] == pytest.approx(0.05, abs=1e-6)
    assert np.all(G @ res.qd <= h + res.relaxed + 1e-9)
    np.testing.assert_allclose(res.qd, corner, atol=1e-4)


class _HoldJoints(rc.tasks.Task):
    """A task that implements rows() alone: hold the first ``m`` joints still (m may change)."""

    def __init__(self) -> None:
        super().__init__(priority=0)
        self.m = 2

    def rows(self, chain, q):
        return rc.tasks.TaskRows(A=np.eye(chain.dof)[: self.m], b=np.zeros(self.m), error=np.zeros(self.m))


def test_a_task_with_rows_alone_is_solved_and_may_change_its_number_of_rows():
    ch = rc.robots.panda()
    q = 0.5 * (ch.qlim[:, 0] + ch.qlim[:, 1])
    hold = _HoldJoints()
    ctrl = rc.ResolvedRateController(ch, tasks=[hold, rc.tasks.Posture(q + 0.3, priority=1, gain=0.01)])
    cmd = ctrl.step(q, dt=1e-3)
    assert cmd.status != "halted", cmd.reason
    assert np.abs(cmd.qd[:2]).max() < 1e-12 < np.abs(cmd.qd[2:]).min()  # held; the rest moves
    hold.m = 4
    cmd = ctrl.step(q, dt=1e-3)
    assert cmd.status != "halted", cmd.reason
    assert np.abs(cmd.qd[:4]).max() < 1e-12 < np.abs(cmd.qd[4:]).min()
    np.testing.assert_allclose(cmd.solve.task_errors, [0.0, np.linalg.norm(0.3 * np.ones(7))])
    assert cmd.solve.task_errors is cmd.solve.task_errors  # (made once, on first access)
    assert not cmd.solve.task_errors.flags.writeable


@pytest.mark.parametrize("seed", range(8))
def test_residuals_without_rows_are_those_of_a_solve_without_rows(seed):
    rng = np.random.default_rng(seed)
    n = 7
    levels = [(rng.normal(size=(6, n)), rng.normal(size=6), None), (np.eye(n), rng.normal(size=n), None)]
    G, h = rng.normal(size=(3, n)), rng.uniform(-0.2, 0.2, size=3)
    lim = _Box(n, float(rng.uniform(0.5, 3.0)))
    c = PriorityCascade()
    with_rows = c.solve_validated(levels, limits=lim, q=None, qd_prev=None, dt=None,
                                  extra_inequalities=(G, h))
    free = c.residuals_without_rows(levels, limits=lim, q=None, qd_prev=None, dt=None)
    alone = PriorityCascade().solve([L[:2] for L in levels], limits=lim)
    np.testing.assert_allclose(free, alone.residuals, rtol=1e-9, atol=1e-12)
    assert np.all(with_rows.residuals[:1] >= alone.residuals[:1] - 1e-9)  # the rows only cost


def _best_residual(A, b, lo, hi, G, h, above=(), at=None):
    """The least ‖A q̇ − b‖ (+ ½·1e-10‖q̇‖²) under the box, the rows and, for the levels
    ``above``, the values their rows take at ``at`` — a QP (proxqp through qpsolvers) with
    those as equalities (an orthonormal basis of their rows, so none is redundant);
    independent of PriorityCascade. None when the solver fails."""
    import qpsolvers

    n = lo.shape[0]
    kw = {}
    if above:
        S = np.vstack(above)
        _, sv, vt = np.linalg.svd(S)
        B = vt[: int(np.sum(sv > 1e-9 * max(1.0, sv[0])))]
        kw = {"A": B, "b": B @ at}
    x = qpsolvers.solve_qp(A.T @ A + 1e-10 * np.eye(n), -A.T @ b, G, h, lb=lo, ub=hi, solver="proxqp",
                           eps_abs=1e-10, eps_rel=0.0, **kw)
    return None if x is None else float(np.linalg.norm(A @ x - b))


@settings(max_examples=60, deadline=None)
@given(st.integers(0, 2**31 - 1), st.sampled_from([(6, 3), (6, 7), (3, 7), (6, 1)]),
       st.sampled_from([0.0, 0.05, 2.0]), st.sampled_from([0.0, 0.5, 2.0]))
def test_the_cascade_reaches_the_textbook_cascade_residuals(seed, rows, off0, off1):
    # the closed forms (one free direction, a line of minimisers) and the projection-first
    # pass must give what a QP per level with the higher levels as equalities gives; each
    # level's target is a point of the box moved by off (0: reachable within the box)
    rng = np.random.default_rng(seed)
    n = 7
    m0, m1 = rows
    centre = rng.normal(scale=0.3, size=n)
    lo, hi = centre - rng.uniform(0.2, 1.0, size=n), centre + rng.uniform(0.2, 1.0, size=n)
    A0, A1 = rng.normal(size=(m0, n)), rng.normal(size=(m1, n))
    levels = [(A0, A0 @ rng.uniform(lo, hi) + off0 * rng.normal(size=m0)),
              (A1, A1 @ rng.uniform(lo, hi) + off1 * rng.normal(size=m1)),
              (np.eye(n), rng.normal(size=n))]
    G = rng.normal(size=(2, n))
    h = G @ (0.5 * (lo + hi)) + rng.uniform(0.0, 0.3, size=2)  # the box centre meets the rows
    lim = _Box(n, 1e6)
    lim.lower, lim.upper = np.full(n, -np.inf), np.full(n, np.inf)
    c = PriorityCascade(backend="daqp")
    c.box = lambda n_, *a: (lo.copy(), hi.copy())  # this step's box, as given
    got = c.solve(levels, limits=lim, extra_inequalities=(G, h))
    assert np.all(got.qd >= lo - 1e-9) and np.all(got.qd <= hi + 1e-9)
    assert np.all(G @ got.qd <= h + 1e-8)
    # each level is the best it can be given what the levels above achieve
    for k, (A, b) in enumerate(levels):
        best = _best_residual(A, b, lo, hi, G, h, [L[0] for L in levels[:k]], got.qd)
        assume(best is not None)
        assert got.residuals[k] <= best + 1e-6 * (1.0 + best)


@settings(max_examples=80, deadline=None)
@given(st.integers(0, 2**31 - 1), st.integers(1, 8), st.integers(2, 8), st.integers(0, 8),
       st.sampled_from([1e-12, 1e-6, 1.0, 1e6]))
def test_the_null_space_spans_the_singular_vectors_the_svd_leaves(seed, m, r, rank, scale):
    # the QR shortcut and the SVD must give the same space (any orthonormal basis of it):
    # full-rank rows and columns, rank-deficient products, tiny and huge scales
    from ratectl.solvers.priority import _null_space

    rng = np.random.default_rng(seed)
    rank = min(rank, m, r)
    M = scale * (rng.normal(size=(m, rank)) @ rng.normal(size=(rank, r)))
    tol = 1e-9
    Z = _null_space(M, tol)
    _, s, vt = np.linalg.svd(M)
    keep = int(np.sum(s > tol * max(1.0, s[0] if s.size else 0.0)))
    N = vt[keep:].T
    assert Z.shape == N.shape
    np.testing.assert_allclose(Z.T @ Z, np.eye(Z.shape[1]), atol=1e-12)
    np.testing.assert_allclose(Z @ Z.T, N @ N.T, atol=1e-9)


@settings(max_examples=40, deadline=None)
@given(st.integers(0, 2**31 - 1), st.integers(1, 9))
def test_a_weighted_first_level_in_a_box_without_zero_is_its_damped_least_squares(seed, m):
    # the first level's minimiser does not depend on where the cascade starts (the box's
    # point nearest q̇ = 0): a box around the answer that excludes q̇ = 0 changes nothing
    rng = np.random.default_rng(seed)
    n = 7
    A, b, w = rng.normal(size=(m, n)), rng.normal(size=m), rng.uniform(0.1, 10.0, size=m)
    lam = 1e-3
    sw = np.sqrt(w)
    # min ‖W^{1/2}(A x − b)‖² + λ²‖x‖², independently: the stacked least-squares problem
    expected = np.linalg.lstsq(np.vstack([sw[:, None] * A, lam * np.eye(n)]),
                               np.concatenate([sw * b, np.zeros(n)]), rcond=None)[0]
    lo = expected - rng.uniform(0.1, 1.0, size=n)
    hi = expected + rng.uniform(0.1, 1.0, size=n)
    j = int(np.argmax(np.abs(expected)))  # this joint's interval holds its answer, not 0
    lo[j], hi[j] = expected[j] - 0.5 * abs(expected[j]), expected[j] + 0.5 * abs(expected[j])
    assume(abs(expected[j]) > 1e-6)
    c = PriorityCascade(damping=lam)
    c.box = lambda n_, *a: (lo.copy(), hi.copy())
    got = c.solve([(A, b, w)], limits=_Box(n, 1e6))
    np.testing.assert_allclose(got.qd, expected, rtol=1e-7, atol=1e-7)  # (H's κ reaches 1e7)
    assert not got.qps.any()


@pytest.mark.parametrize("empty", [0, 1, 2])
def test_each_levels_residual_is_reported_with_an_empty_level_anywhere(empty):
    # three levels in one stacked layout, one of them without rows (a posture on no joints)
    ch = rc.robots.panda()
    q = 0.5 * (ch.qlim[:, 0] + ch.qlim[:, 1]) + 0.1
    link = ch.link_names[3]
    tasks = [rc.tasks.Pose(priority=0, target=ch.fk(q + 0.05)),
             rc.tasks.Position(link=link, priority=1, target=ch.fk(q, link=link)[:3, 3] + 0.02),
             rc.tasks.Posture(q + 0.2, priority=2, gain=1.0)]
    tasks[empty] = rc.tasks.Posture(q, joints=[], priority=empty)
    ctrl = rc.ResolvedRateController(ch, tasks=tasks)
    cmd = ctrl.step(q, dt=1e-3)
    assert cmd.status != "halted", cmd.reason
    expected = []
    for t in tasks:
        r = t.rows(ch, q)
        d = r.A @ cmd.solve.qd - r.b
        expected.append(np.linalg.norm(d))
    np.testing.assert_allclose(cmd.solve.residuals, expected, rtol=1e-12, atol=1e-12)
    assert cmd.solve.residuals[empty] == 0.0
