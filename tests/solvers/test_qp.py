"""The QP inverse-velocity solver: limits held, equal to DLS when no limit binds,
backends agree, the warm OSQP instance, failures and fallbacks, extra inequalities."""

import numpy as np
import pytest
import qpsolvers

import ratectl as rc
from ratectl import solvers as S
from ratectl.errors import InputError, SolverError
from ratectl.solvers.qp import joint_velocity_bounds

BACKENDS = [b for b in ("osqp", "daqp", "quadprog", "proxqp") if b in qpsolvers.available_solvers]


def _ur5e_limits(q0, *, width=0.5, vmax=0.6, amax=4.0):
    return S.Limits(lower=q0 - width, upper=q0 + width, vmax=np.full(6, vmax),
                    amax=np.full(6, amax))


def _run(qp, lim, q0, dt, seconds, *, use_acc=True):
    """Drive a UR5e with a twist that needs far more joint motion than the limits allow."""
    ur = rc.robots.ur5e()
    q = q0.copy()
    qd = np.zeros(6)
    steps = []
    for k in range(int(round(seconds / dt))):
        t = k * dt
        xi = np.array([0.4 * np.sin(0.7 * t), 0.3, -0.2 * np.cos(0.5 * t), 0.5,
                       -0.8 * np.sin(0.3 * t), 1.0])
        r = qp.solve(ur.jacobian(q), xi, limits=lim, q=q, qd_prev=qd if use_acc else None, dt=dt)
        steps.append((q.copy(), qd.copy(), r))
        qd = r.qd
        q = q + dt * qd
    return steps, q


@pytest.mark.parametrize("dt", [0.01, 0.002])
def test_limits_hold_at_every_step_of_a_10s_run(dt):
    q0 = np.array([0.0, -1.2, 1.4, -1.6, -1.57, 0.0])
    lim = _ur5e_limits(q0)
    steps, q_end = _run(S.QP(damping=0.05), lim, q0, dt, 10.0)
    kinds = set()
    for q, qd_prev, r in steps:
        qd = r.qd
        kinds |= set(r.limits_active)
        assert np.all(np.abs(qd) <= lim.vmax + 1e-6)                      # velocity
        assert np.all(np.abs(qd - qd_prev) <= lim.amax * dt + 1e-6)       # acceleration
        q_next = q + dt * qd
        assert np.all(q_next <= lim.upper + 1e-6) and np.all(q_next >= lim.lower - 1e-6)  # position
        assert np.all(qd <= r.info["upper"] + 1e-6) and np.all(qd >= r.info["lower"] - 1e-6)
        assert "conflicts" not in r.info  # the braking bound keeps the box non-empty
        assert r.velocity_policy == "none" and not r.fallback
    # the run really pushed into every kind of limit
    assert kinds == {"velocity", "position", "acceleration"}
    assert np.any(np.isclose(q_end, lim.upper, atol=1e-3) | np.isclose(q_end, lim.lower, atol=1e-3))


def test_position_limits_hold_without_acceleration_bounds():
    q0 = np.array([0.3, -1.0, 1.2, -1.4, -1.57, 0.2])
    lim = _ur5e_limits(q0, width=0.3, vmax=1.0, amax=8.0)
    steps, _ = _run(S.QP(damping=0.05, margin=0.01), lim, q0, 0.01, 3.0, use_acc=False)
    hit = False
    for q, _, r in steps:
        q_next = q + 0.01 * r.qd
        assert np.all(q_next <= lim.upper - 0.01 + 1e-6) and np.all(q_next >= lim.lower + 0.01 - 1e-6)
        hit |= "position" in r.limits_active
    assert hit


def test_qp_equals_dls_when_no_limit_is_active(rng):
    ur = rc.robots.ur5e()
    dls = S.DLS(damping=0.05, velocity_policy=None)
    for shortcut in (True, False):
        qp = S.QP(damping=0.05, shortcut=shortcut)
        for _ in range(20):
            q = ur.random_q(rng=rng)
            J = ur.jacobian(q)
            xi = 0.05 * rng.standard_normal(6)
            ref = dls.solve(J, xi)
            if np.max(np.abs(ref.qd)) > 0.5 * np.pi:
                continue  # the velocity limit would bind
            r = qp.solve(J, xi, limits=ur, q=q, qd_prev=ref.qd, dt=0.002)
            assert r.limits_active == () and not r.bound.any()
            # exact through the unconstrained shortcut, to OSQP's tolerance otherwise
            tol = 1e-12 if shortcut else 1e-5
            assert np.max(np.abs(r.qd - ref.qd)) < tol * max(1.0, np.max(np.abs(ref.qd)))
            assert (r.info["status"] == "unconstrained") == shortcut
            assert r.damping == 0.05
            assert r.sigma_min == pytest.approx(ref.sigma_min, abs=1e-9)


def _active_problems(rng, count):
    ur = rc.robots.ur5e()
    out = []
    while len(out) < count:
        q = ur.random_q(rng=rng)
        J = ur.jacobian(q)
        xi = rng.standard_normal(6)
        lim = S.Limits(lower=q - rng.uniform(0.001, 0.2, 6), upper=q + rng.uniform(0.001, 0.2, 6),
                       vmax=np.full(6, 1.0), amax=np.full(6, 10.0))
        qd_prev = rng.uniform(-0.5, 0.5, 6)
        out.append((J, xi, lim, q, qd_prev))
    return out


@pytest.mark.skipif(len(BACKENDS) < 2, reason="needs two QP backends")
def test_every_installed_backend_agrees(rng):
    solvers = {b: S.QP(damping=0.05, backend=b, shortcut=False) for b in BACKENDS}
    n_active = 0
    for J, xi, lim, q, qd_prev in _active_problems(rng, 25):
        results = {b: s.solve(J, xi, limits=lim, q=q, qd_prev=qd_prev, dt=0.01)
                   for b, s in solvers.items()}
        ref = results["osqp"].qd
        n_active += bool(results["osqp"].limits_active)
        for b, r in results.items():
            assert np.max(np.abs(r.qd - ref)) < 1e-5, b
            assert np.all(r.qd <= r.info["upper"] + 1e-6) and np.all(r.qd >= r.info["lower"] - 1e-6)
    assert n_active >= 20


def test_osqp_is_kept_warm_and_reset_on_structure_change(rng):
    qp = S.QP(damping=0.05, shortcut=False)
    probs = _active_problems(rng, 5)
    first = None
    for J, xi, lim, q, _ in probs:
        r = qp.solve(J, xi, limits=lim, q=q, dt=0.01)
        assert r.info["status"] == "solved"
        first = first or qp._warm
        assert qp._warm is first  # same instance: only update() between calls
    J, xi, lim, q, _ = probs[0]
    G = np.zeros((1, 6))
    G[0, 0] = 1.0
    r = qp.solve(J, xi, limits=lim, q=q, dt=0.01, extra_inequalities=(G, [0.01]))
    assert qp._warm is not first and qp._warm.k == 1
    assert r.qd[0] <= 0.01 + 1e-6


def test_box_active_set_is_the_exact_optimum(rng):
    """The default solve answers box-only problems by certified active-set steps; they
    agree with warm OSQP (polished) and, where installed, daqp."""
    fast = S.QP(damping=0.05)
    ref = S.QP(damping=0.05, shortcut=False)
    daqp = S.QP(damping=0.05, backend="daqp", shortcut=False) if "daqp" in BACKENDS else None
    statuses = set()
    for J, xi, lim, q, qd_prev in _active_problems(rng, 40):
        r = fast.solve(J, xi, limits=lim, q=q, qd_prev=qd_prev, dt=0.01)
        statuses.add(r.info["status"])
        r_ref = ref.solve(J, xi, limits=lim, q=q, qd_prev=qd_prev, dt=0.01)
        assert np.max(np.abs(r.qd - r_ref.qd)) < 1e-6
        assert np.array_equal(r.bound, r_ref.bound)
        assert r.limits_active == r_ref.limits_active
        assert np.all(r.qd <= r.info["upper"]) and np.all(r.qd >= r.info["lower"])
        if daqp is not None:
            assert np.max(np.abs(r.qd - daqp.solve(J, xi, limits=lim, q=q, qd_prev=qd_prev,
                                                   dt=0.01).qd)) < 1e-9
    assert "active-set" in statuses


def test_box_active_set_kkt_certificate(rng):
    """Random strictly convex box QPs: when the active-set steps return, x is feasible and
    satisfies the KKT sign conditions; otherwise they decline (None)."""
    from ratectl.solvers.qp.active_set import _box_active_set

    settled = 0
    for _ in range(300):
        n = int(rng.integers(2, 8))
        A = rng.normal(size=(6, n))
        P = A.T @ A + 0.01 * np.eye(n)
        b = rng.normal(size=n) * rng.uniform(0.1, 20.0)
        lo, hi = -rng.uniform(0.01, 2.0, n), rng.uniform(0.01, 2.0, n)
        x, held, _ = _box_active_set(P, b, lo, hi, np.linalg.solve(P, b))
        if x is None:
            continue
        settled += 1
        g = P @ x - b
        assert np.all(x <= hi) and np.all(x >= lo)
        held = np.array(held)
        assert np.allclose(g[held == 0], 0.0, atol=1e-8 * (1 + np.abs(b).max()))
        assert np.all(g[held > 0] <= 1e-9) and np.all(g[held < 0] >= -1e-9)
    assert settled > 200


def test_extra_inequalities_match_daqp(rng):
    for J, xi, lim, q, _ in _active_problems(rng, 10):
        G = rng.standard_normal((2, 6))
        h = np.array([0.05, -0.02])
        a = S.QP(damping=0.05).solve(J, xi, limits=lim, q=q, dt=0.01, extra_inequalities=(G, h))
        assert np.all(G @ a.qd <= h + 1e-6)
        if "daqp" in BACKENDS:
            b = S.QP(damping=0.05, backend="daqp").solve(J, xi, limits=lim, q=q, dt=0.01,
                                                          extra_inequalities=(G, h))
            assert np.max(np.abs(a.qd - b.qd)) < 1e-5
        assert a.info["extra_active"].shape == (2,)
    with pytest.raises(InputError, match="extra_inequalities"):
        S.QP().solve(np.eye(6), np.ones(6), extra_inequalities=(np.ones((2, 5)), np.ones(2)))


def test_failed_osqp_on_a_box_problem_is_answered_by_the_exact_active_set(rng):
    J, xi, lim, q, _ = _active_problems(rng, 1)[0]
    bad = S.QP(damping=0.05, shortcut=False, settings={"max_iter": 1, "polishing": False})
    r = bad.solve(J, xi, limits=lim, q=q, dt=0.01)
    ref = S.QP(damping=0.05).solve(J, xi, limits=lim, q=q, dt=0.01)
    assert r.info["status"] == "exact-active-set" and not r.fallback
    assert np.max(np.abs(r.qd - ref.qd)) < 1e-9


def test_failed_solve_raises_with_the_problem_or_falls_back(rng):
    J, xi, lim, q, _ = _active_problems(rng, 1)[0]
    # extra rows: no exact rescue, OSQP's failure is reported
    extra = (rng.standard_normal((2, 6)), np.array([0.05, -0.02]))
    bad = S.QP(damping=0.05, shortcut=False, settings={"max_iter": 1, "polishing": False})
    with pytest.raises(SolverError) as info:
        bad.solve(J, xi, limits=lim, q=q, dt=0.01, extra_inequalities=extra)
    problem = info.value.problem
    assert set(problem) >= {"P", "q", "lb", "ub"} and problem["P"].shape == (6, 6)
    assert info.value.status is not None
    fb = S.QP(damping=0.05, shortcut=False, fallback=True,
              settings={"max_iter": 1, "polishing": False})
    r = fb.solve(J, xi, limits=lim, q=q, dt=0.01, extra_inequalities=extra)
    assert r.fallback and "error" in r.info
    lo, hi = r.info["problem"]["lb"], r.info["problem"]["ub"]
    assert np.all(r.qd <= hi + 1e-12) and np.all(r.qd >= lo - 1e-12)
    dls = S.DLS(damping=0.05, velocity_policy=None).solve(J, xi).qd
    if r.velocity_policy == "scaled":  # the direction of the DLS solution is kept
        assert np.allclose(r.qd, r.velocity_scale * dls)


def test_bounds_and_braking():
    lim = S.Limits(lower=np.array([-1.0]), upper=np.array([1.0]), vmax=np.array([2.0]),
                   amax=np.array([4.0]))
    dt = 0.01
    # far from the limit only the velocity limit binds
    b = joint_velocity_bounds(lim, q=[0.0], dt=dt)
    assert b.upper[0] == 2.0 and b.lower[0] == -2.0
    # braking: v_stop(d) for d = 0.1 lies just below √(2ad)
    b = joint_velocity_bounds(lim, q=[0.9], dt=dt)
    assert np.sqrt(2 * 4 * 0.1) - 4 * dt < b.upper[0] < np.sqrt(2 * 4 * 0.1)
    assert b.source_upper[0] == 2 and b.source_lower[0] == 1
    # braking from v_stop at a·dt per step never crosses the limit
    q, v = 0.9, b.upper[0]
    while v > 0:
        q += v * dt
        assert q <= 1.0 + 1e-12
        v_next = joint_velocity_bounds(lim, q=[q], dt=dt).upper[0]
        assert v_next >= v - 4 * dt - 1e-12
        v = max(v - 4 * dt, 0.0)
    # at the limit no motion further out; beyond it, motion back
    assert joint_velocity_bounds(lim, q=[1.0], dt=dt).upper[0] == pytest.approx(0.0, abs=1e-15)
    assert joint_velocity_bounds(lim, q=[1.001], dt=dt).upper[0] == pytest.approx(-0.1)
    # acceleration bounds around the previous velocity
    b = joint_velocity_bounds(lim, q=[0.0], qd_prev=[1.0], dt=dt)
    assert b.lower[0] == pytest.approx(0.96) and b.upper[0] == pytest.approx(1.04)
    assert b.source_upper[0] == 3
    # a margin keeps that far from the limit
    b = joint_velocity_bounds(lim, q=[0.95], dt=dt, margin=0.05)
    assert b.upper[0] == pytest.approx(0.0, abs=1e-12)


def test_qp_with_an_objective_and_unlimited_joints(rng):
    iiwa = rc.robots.iiwa7()
    q = iiwa.random_q(rng=rng)
    J = iiwa.jacobian(q)
    xi = 0.1 * rng.standard_normal(6)
    plain = S.QP(damping=0.01).solve(J, xi, q=q)
    centred = S.QP(damping=0.01, objective="centring", chain=iiwa, objective_weight=1e-2,
                   objective_gain=5.0).solve(J, xi, q=q)
    z = S.JointCentring(iiwa)(q)
    assert centred.qd @ z > plain.qd @ z
    unlimited = S.Limits(lower=np.full(7, -np.inf), upper=np.full(7, np.inf),
                         vmax=np.full(7, np.inf), amax=np.full(7, np.inf))
    r = S.QP(damping=0.01).solve(J, xi, limits=unlimited, q=q, qd_prev=np.zeros(7), dt=0.01)
    assert np.allclose(r.qd, plain.qd) and r.limits_active == ()


def test_qp_input_errors():
    with pytest.raises(InputError, match="backend"):
        S.QP(backend="no-such-solver")
    with pytest.raises(InputError, match="dt"):
        S.QP().solve(np.eye(6), np.ones(6), dt=0.0)
    with pytest.raises(InputError, match="q"):
        S.QP().solve(np.eye(6), np.ones(6), q=np.ones(5), limits=rc.robots.ur5e())
    with pytest.raises(InputError, match="needs q"):
        S.QP(objective=lambda q: q).solve(np.eye(6), np.ones(6))
