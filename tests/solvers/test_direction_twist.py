"""`Solver.solve_direction_twist`, the servo's entry for its direction and its feedback on the
same J: the answers of ``solve_direction`` then ``solve_validated(limits=None)``, bit for bit,
whichever solver answers (its own shared work on J or the generic default)."""

import pickle

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import ratectl as rc
from ratectl.solvers.base import DirectionTwist, direction_twist_entry, sigma_at_least

_FIELDS = ("damping", "method", "velocity_policy", "velocity_scale", "limits_active", "fallback")


def _make(name, arm):
    return {
        "qp": lambda: rc.solvers.QP(),
        "qp-weighted": lambda: rc.solvers.QP(joint_weights=[1.0, 2.0, 1.0, 0.5, 3.0, 1.0, 1.0][:arm.dof]),
        "qp-rows": lambda: rc.solvers.QP(task_weights="position"),
        "qp-objective": lambda: rc.solvers.QP(objective="centring", chain=arm),
        "qp-undamped": lambda: rc.solvers.QP(damping=0.0),
        "adaptive": lambda: rc.solvers.AdaptiveDLS(),
        "adaptive-filtered": lambda: rc.solvers.AdaptiveDLS(mode="filtered"),
        "adaptive-weighted": lambda: rc.solvers.AdaptiveDLS(task_weights="position"),
        "dls": lambda: rc.solvers.DLS(),
    }[name]


def _same_result(got, want):
    assert got.qd.tolist() == want.qd.tolist()
    assert got.achieved.tolist() == want.achieved.tolist()
    assert got.task_error.tolist() == want.task_error.tolist()
    assert got.bound.tolist() == want.bound.tolist()
    for f in _FIELDS:
        assert getattr(got, f) == getattr(want, f), f
    assert got.sigma_min == want.sigma_min or (np.isnan(got.sigma_min) and np.isnan(want.sigma_min))
    assert got.info.keys() == want.info.keys()
    for k, v in want.info.items():
        assert (got.info[k].tolist() == v.tolist()) if isinstance(v, np.ndarray) else got.info[k] == v, k
    assert not got.qd.flags.writeable and not got.task_error.flags.writeable


@settings(max_examples=120, deadline=None)
@given(st.integers(0, 10_000),
       st.sampled_from(["qp", "qp-weighted", "qp-rows", "qp-objective", "qp-undamped", "adaptive",
                        "adaptive-filtered", "adaptive-weighted", "dls"]),
       st.sampled_from(["ur5e", "panda"]), st.booleans())
def test_the_joint_entry_answers_as_the_two_entries(seed, name, robot, twice):
    """(w, σ, damping) equal `solve_direction`'s and the twist's answer equals
    `solve_validated`'s without limits, bit for bit (a QP or an `AdaptiveDLS` that shares
    its work on J, and every other solver through the default), at regular and singular
    configurations; `DirectionTwist.result` is the twist's `SolveResult` for its own answer
    and `result_with_qd`'s for a command with more added to it. ``twice``: the same J was
    solved just before (the QP's remembered factor)."""
    rng = np.random.default_rng(seed)
    arm = rc.robots.ur5e() if robot == "ur5e" else rc.robots.panda()
    make = _make(name, arm)
    q = rng.uniform(-2, 2, arm.dof)
    if seed % 4 == 0:
        q[4 if robot == "ur5e" else 5] = rng.choice([0.0, 1e-9, 0.02])  # at or near a wrist singularity
    J = arm.jacobian(q)
    d, xi = rng.standard_normal(6), rng.standard_normal(6) * rng.choice([1e-3, 1.0])
    kw = dict(q=q, dt=1e-3)
    a, b = make(), make()
    if twice:
        a.solve_validated(J, d, limits=None, qd_prev=None, **kw)
        b.solve_validated(J, d, limits=None, qd_prev=None, **kw)
    try:
        w, sig, damping = a.solve_direction(J, d, **kw)
        res = a.solve_validated(J, xi, limits=None, qd_prev=None, **kw)
    except rc.errors.RatectlError as err:
        with pytest.raises(type(err)):
            b.solve_direction_twist(J, d, xi, **kw)
        return
    ans = b.solve_direction_twist(J, d, xi, **kw)
    assert isinstance(ans, DirectionTwist)
    assert ans.w.tolist() == w.tolist() and ans.damping == damping and ans.w.flags.writeable
    for threshold in (1e-3, 0.05, float(res.sigma_min)):
        assert sigma_at_least(ans.sigma, threshold)[0] == sigma_at_least(sig, threshold)[0]
    assert ans.qd.tolist() == res.qd.tolist()
    assert (ans.velocity_policy, ans.velocity_scale, ans.limits_active) == \
        (res.velocity_policy, res.velocity_scale, res.limits_active)
    speed = float(rng.uniform(0.01, 0.5))
    xi2, qd2 = xi + d * speed, ans.qd + ans.w * speed
    want2 = rc.solvers.base.result_with_qd(res, J, xi2, qd2)
    _same_result(ans.result(xi2, qd2), want2)
    assert qd2.flags.writeable  # (the command is copied into its result, not frozen)
    _same_result(ans.result(xi, ans.qd), res)
    # the solver and the results still pickle (nothing unpicklable kept for the shared work)
    _same_result(pickle.loads(pickle.dumps(ans.result(xi2, qd2))), want2)
    if name in ("qp", "adaptive"):  # (a QP that called its OSQP backend keeps it: not picklable)
        pickle.loads(pickle.dumps(b)).solve_direction_twist(J, d, xi, **kw)


def test_a_subclass_that_changes_an_entry_gets_the_generic_joint_entry():
    """A solver class that overrides ``solve``, ``solve_direction`` or ``solve_validated``
    without its own joint entry is asked through those: a parent's shared shortcut would
    bypass them."""
    calls = []

    class Counting(rc.solvers.QP):
        def solve_validated(self, J, xi, **kw):
            calls.append("validated")
            return super().solve_validated(J, xi, **kw)

    class OwnSolve(rc.solvers.AdaptiveDLS):
        def solve(self, J, xi, **kw):
            calls.append("solve")
            return super().solve(J, xi, **kw)

    arm = rc.robots.ur5e()
    q = np.array([0.3, -1.2, 1.5, -1.9, -1.4, 0.6])
    J = arm.jacobian(q)
    Counting().solve_direction_twist(J, np.eye(6)[0], np.eye(6)[1], q=q, dt=1e-3)
    assert calls == ["validated"]
    calls.clear()
    OwnSolve().solve_direction_twist(J, np.eye(6)[0], np.eye(6)[1], q=q, dt=1e-3)
    assert calls == ["solve", "solve"]  # the direction and the twist, each through ``solve``


def test_an_object_that_is_not_a_solver_answers_through_its_solve():
    """`direction_twist_entry` of a plain object with ``solve``: the direction and the twist
    each through that ``solve`` (the twist without limits)."""
    calls = []

    class Wrapper:
        def __init__(self):
            self.inner = rc.solvers.DLS()

        def solve(self, J, xi, **kw):
            calls.append(kw.get("limits", "absent"))
            return self.inner.solve(J, xi, **kw)

    arm = rc.robots.ur5e()
    q = np.array([0.3, -1.2, 1.5, -1.9, -1.4, 0.6])
    J = arm.jacobian(q)
    d, xi = np.eye(6)[0], np.eye(6)[2] * 0.1
    ans = direction_twist_entry(Wrapper())(J, d, xi, q=q, dt=1e-3)
    assert calls == ["absent", None]
    want_w = rc.solvers.DLS().solve(J, d, q=q, dt=1e-3).qd
    assert ans.w.tolist() == want_w.tolist() and ans.sigma.qd.tolist() == want_w.tolist()
    assert ans.qd.tolist() == rc.solvers.DLS().solve(J, xi).qd.tolist()
