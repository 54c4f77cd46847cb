"""The cheap paths of a control step give the same answers as the plain computations:
σ_min certified by the solver's last exact value, the KKT measure on Python floats, the
input checks on Python floats."""

from __future__ import annotations

import math

import numpy as np
import pytest

import ratectl as rc
from ratectl import solvers as S
from ratectl.errors import InputError
from ratectl.solvers.base import _SIGMA_SLOT, SolveResult, _LazySigma
from ratectl.solvers.qp.active_set import kkt_violation


def _kkt_reference(P, b, lo, hi, x):
    """The KKT measure of `kkt_violation`, written with numpy arrays (its definition)."""
    scale = 1.0 + np.max(np.abs(b)) + np.max(np.abs(P)) * np.max(np.abs(x))
    feas = np.max(np.maximum(np.maximum(lo - x, x - hi), 0.0))
    g = P @ x - b
    eps = 1e-12 * (1.0 + np.abs(x))
    at_hi = x >= hi - eps
    at_lo = (x <= lo + eps) & ~at_hi
    gv = np.where(at_hi, np.maximum(g, 0.0), np.where(at_lo, np.maximum(-g, 0.0), np.abs(g)))
    gv = np.where(np.maximum(hi - lo, 0.0) <= eps, 0.0, gv)
    ax = np.max(np.abs(x))
    own = np.abs(np.diagonal(P)) * (1.0 + ax) + 1e-3 * (np.abs(b) + np.abs(P) @ np.abs(x)) + 1e-300
    return max(feas / (1.0 + ax), np.max(gv) / scale, np.max(gv / own))


def test_kkt_violation_equals_its_definition_bit_for_bit():
    rng = np.random.default_rng(7)
    for _ in range(3000):
        n = int(rng.integers(1, 9))
        A = rng.normal(size=(n, n))
        P = A.T @ A + rng.uniform(0.0, 1.0) * np.eye(n)
        b = rng.normal(size=n) * 10 ** rng.uniform(-3, 3)
        lo, hi = -rng.uniform(0, 2, n), rng.uniform(0, 2, n)
        kind = int(rng.integers(0, 3))
        if kind == 1:
            lo[0] = hi[0]  # a fixed joint
        elif kind == 2:
            lo[:] = -1e15  # absent lower bounds
        x = np.clip(rng.normal(size=n), lo - rng.uniform(0, 1e-9, n), hi + rng.uniform(0, 1e-9, n))
        i = int(rng.integers(n))
        x[i] = hi[i] if rng.random() < 0.5 else lo[i]  # one joint exactly at a bound
        assert kkt_violation(P, b, lo, hi, x) == _kkt_reference(P, b, lo, hi, x)
    assert kkt_violation(np.eye(2), np.ones(2), -np.ones(2), np.ones(2), np.array([np.nan, 0.0])) == math.inf


def test_sigma_min_at_least_is_the_comparison_of_the_value_along_a_singular_crossing(ur5e_wrist_line):
    """The QP certifies σ_min ≥ t from its last exact σ_min (Weyl): along a line through the
    wrist singularity, for thresholds around σ_min, the certificate never says yes when the
    exact value says no, and it answers most steps without the eigenvalues."""
    arm, line, q0 = ur5e_wrist_line
    qp = S.QP()
    run = rc.follow(arm, line, q0, dt=2e-3)
    thresholds = (1e-4, 0.01, 0.02, 0.05, 0.2)
    certified = 0
    for q in run.q[::3]:
        J = arm.jacobian(q)
        exact = rc.analyze(arm, q).sigma_min
        for t in thresholds:
            res = qp.solve(J, np.zeros(6), limits=arm, q=q, dt=2e-3)
            answer = res.sigma_min_at_least(t)
            assert answer == (res.sigma_min >= t)
            assert res.sigma_min == pytest.approx(exact, rel=1e-9, abs=1e-7)
            fresh = qp.solve(J, np.zeros(6), limits=arm, q=q, dt=2e-3)
            lazy = _SIGMA_SLOT.__get__(fresh, SolveResult)
            if type(lazy) is _LazySigma and lazy.certainly_at_least(t):
                certified += 1
                assert exact >= t
    assert certified > 0


def test_sigma_below_is_the_comparison_of_the_value_along_a_singular_crossing(ur5e_wrist_line):
    """`sigma_below` (the servo's and the jog's singularity watch) from the QP's lazy σ: None
    exactly when σ_min ≥ t, else a number below t that bounds σ_min from above; along a line
    through the wrist singularity, where the value is never read, the reference decides most
    steps below the threshold too (no eigen-decomposition), and never wrongly."""
    from ratectl.solvers.base import sigma_below

    arm, line, q0 = ur5e_wrist_line
    qp = S.QP()
    run = rc.follow(arm, line, q0, dt=2e-3)
    decided_below = 0
    for q in run.q:
        J = arm.jacobian(q)
        exact = float(np.linalg.svd(J, compute_uv=False)[-1])
        lazy = _SIGMA_SLOT.__get__(qp.solve(J, np.zeros(6), limits=arm, q=q, dt=2e-3), SolveResult)
        assert type(lazy) is _LazySigma
        t = 0.2
        upper = lazy.certainly_below(t)
        if upper is not None:
            decided_below += 1
            assert exact < t and exact <= upper + 1e-12 and upper < t
        got = sigma_below(lazy, t)
        if abs(exact - t) > 1e-9:
            assert (got is None) == (exact >= t)
        if got is not None:
            assert got < t and exact <= got + 1e-9
    assert decided_below > 0


def test_qp_controller_flags_damped_exactly_below_singular_sigma(ur5e_wrist_line):
    """A QP's λ is reported ("damped") exactly when σ_min < singular_sigma, whether the
    controller certified σ_min or computed it, and Command.sigma_min is the exact value."""
    arm, line, q0 = ur5e_wrist_line
    run = rc.follow(arm, line, q0, dt=2e-3)
    ctrl = rc.ResolvedRateController(arm, solver=S.QP(), singular_sigma=0.05)
    seen = set()
    for q in run.q:
        # (a twist with a pose feedback: the QP's answer; a jog alone follows the exact direction)
        cmd = ctrl.step(q, target=arm.fk(q), twist=np.array([0.0, 0.05, 0.0, 0.0, 0.0, 0.0]), dt=2e-3)
        below = cmd.sigma_min < ctrl.singular_sigma
        assert ("damped" in cmd.flags) == below
        assert cmd.sigma_min == pytest.approx(rc.analyze(arm, q).sigma_min, rel=1e-9, abs=1e-7)
        seen.add(below)
    assert seen == {True, False}  # the line crosses the threshold both ways


@pytest.mark.parametrize("solver", [S.DLS(damping=0.05), S.QP(), S.AdaptiveDLS()])
def test_the_input_checks_refuse_what_they_refused(solver):
    J = rc.robots.ur5e().jacobian(np.array([0.3, -1.2, 1.5, -1.9, -1.4, 0.6]))
    xi = np.full(6, 0.1)
    for bad in (np.nan, np.inf, -np.inf):
        Jb = J.copy()
        Jb[2, 3] = bad
        with pytest.raises(InputError, match="J must be finite"):
            solver.solve(Jb, xi)
        xb = xi.copy()
        xb[4] = bad
        with pytest.raises(InputError, match="xi must be finite"):
            solver.solve(J, xb)
    with pytest.raises(InputError, match="entries below"):
        solver.solve(J * 1e146, xi)
    with pytest.raises(InputError, match="entries below"):
        solver.solve(J, xi * 1e146)
    solver.solve(J * 1e140, xi)  # large but within range: accepted


def test_solve_validated_answers_as_solve_bit_for_bit():
    """The controller's entry past the input checks gives solve's answer, certified the same
    way, for valid inputs near and far from the limits (and with a feed-forward); J and ξ
    are still checked there."""
    arm = rc.robots.ur5e()
    rng = np.random.default_rng(3)
    a, b = S.QP(), S.QP()
    for k in range(400):
        q = rng.uniform(arm.lower, arm.upper)
        if k % 3 == 0:  # near a limit
            q[k % 6] = arm.upper[k % 6] - rng.uniform(0.0, 0.02)
        J = arm.jacobian(q)
        xi = rng.normal(size=6) * 10 ** rng.uniform(-2, 0.5)
        qd_prev = rng.normal(size=6) * 0.5
        dt = float(rng.choice([1e-3, 2e-3, 4e-3]))
        ff = rng.normal(size=6) * 0.1 if k % 4 == 1 else None
        r1 = a.solve(J, xi, limits=arm, q=q, qd_prev=qd_prev, dt=dt, qd_ff=ff)
        r2 = b.solve_validated(J, xi, limits=arm, q=q, qd_prev=qd_prev, dt=dt, qd_ff=ff)
        assert r1.qd.tobytes() == r2.qd.tobytes()
        assert r1.limits_active == r2.limits_active and r1.info["status"] == r2.info["status"]
        assert r1.sigma_min == r2.sigma_min
    J = arm.jacobian(arm.lower * 0.5)
    for bad in (np.nan, np.inf):
        Jb = J.copy()
        Jb[1, 1] = bad
        with pytest.raises(InputError, match="J must be finite"):
            a.solve_validated(Jb, np.zeros(6), limits=arm, q=np.zeros(6), qd_prev=np.zeros(6), dt=1e-3)
    with pytest.raises(InputError, match="entries below"):
        a.solve_validated(J, np.full(6, 1e146), limits=arm, q=np.zeros(6), qd_prev=np.zeros(6), dt=1e-3)


def test_the_box_of_a_cycle_equals_joint_velocity_bounds_around_the_near_gate():
    """The QP's per-cycle box skips the braking bounds when every joint is farther from its
    limits than the room to stop from full speed (a gate on thresholds, on Python floats);
    for q just inside and outside that gate, at several dt, its box is
    `joint_velocity_bounds`'s, bit for bit."""
    arm = rc.robots.ur5e()
    lim = rc.solvers.Limits(lower=arm.lower, upper=arm.upper, vmax=arm.vmax, amax=arm.amax)
    rng = np.random.default_rng(11)
    qp = S.QP()
    J = arm.jacobian(np.array([0.3, -1.2, 1.5, -1.9, -1.4, 0.6]))
    for dt in (1e-3, 4e-3, 0.05):
        dstar = arm.vmax * dt + arm.vmax**2 / (2 * arm.amax)
        for _ in range(300):
            q = rng.uniform(arm.lower + 1.0, arm.upper - 1.0)
            j = int(rng.integers(6))
            side = rng.choice([-1.0, 1.0])
            room = dstar[j] * (1.0 + rng.choice([-1.0, 1.0]) * 10 ** rng.uniform(-16, -6))
            q[j] = arm.upper[j] - room if side > 0 else arm.lower[j] + room
            qd_prev = rng.uniform(-1, 1, 6) * arm.vmax
            res = qp.solve(J, np.zeros(6), limits=lim, q=q, qd_prev=qd_prev, dt=dt)
            ref = rc.solvers.qp.joint_velocity_bounds(lim, q=q, qd_prev=qd_prev, dt=dt)
            assert res.info["lower"].tobytes() == ref.lower.tobytes()
            assert res.info["upper"].tobytes() == ref.upper.tobytes()


@pytest.mark.parametrize("name", ["ur5e", "panda", "iiwa7", "puma560", "stanford", "rpr", "planar2r"])
def test_the_jacobian_kernel_gives_fk_jacobians_j_bit_for_bit(name):
    """A cycle without a target computes J alone (`Chain.jacobian`), one with a target both
    (`Chain.fk_jacobian`): the two kernels share their expressions, so J is the same bits
    and a twist-only cycle commands what it did before."""
    arm = getattr(rc.robots, name)()
    rng = np.random.default_rng(5)
    for q in rng.uniform(-3.0, 3.0, (500, arm.dof)):
        assert arm.jacobian(q).tobytes() == arm.fk_jacobian(q)[1].tobytes()


def test_direction_result_equals_the_keyword_result():
    """`direction_result` (a jog's result every period) is the keyword constructor's result
    of the same answer: q̇ a read-only copy of w, J w, d − J w, no bound, no policy, no info."""
    from ratectl.solvers.base import direction_result

    rng = np.random.default_rng(3)
    for n in (3, 6, 7):
        J = rng.normal(size=(6, n))
        d = rng.normal(size=6)
        w = rng.normal(size=n)
        r = direction_result(J, d, w, damping=0.25, sigma_min=0.5, method="qp")
        k = SolveResult(qd=w.copy(), achieved=J @ w, task_error=d - J @ w, damping=0.25, sigma_min=0.5,
                        method="qp")
        for f in ("qd", "achieved", "task_error", "bound"):
            a, b = getattr(r, f), getattr(k, f)
            assert a.dtype == b.dtype and np.array_equal(a, b) and not a.flags.writeable
        assert r.qd is not w and w.flags.writeable  # the caller's w is neither kept nor frozen
        for f in ("damping", "sigma_min", "method", "velocity_policy", "velocity_scale", "limits_active",
                  "fallback"):
            assert getattr(r, f) == getattr(k, f)
        assert dict(r.info) == dict(k.info) == {}
        with pytest.raises(ValueError):
            r.bound[0] = True
