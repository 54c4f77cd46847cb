"""The cascade's fast paths give the general path's answers, to the bit."""

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from ratectl.solvers.priority import PriorityCascade


class _Box:
    def __init__(self, n, vmax, amax=np.inf, lower=-np.inf, upper=np.inf):
        self.lower = np.full(n, lower, dtype=float)
        self.upper = np.full(n, upper, dtype=float)
        self.vmax = np.full(n, vmax)
        self.amax = np.full(n, amax)


@settings(max_examples=60, deadline=None)
@given(st.integers(0, 2**31 - 1), st.integers(0, 6), st.booleans(), st.floats(0.05, 5.0),
       st.floats(0.001, 1.0), st.sampled_from(["none", "far", "near"]), st.booleans(),
       st.sampled_from([100.0, np.inf]))
def test_one_level_without_rows_is_the_general_cascade(seed, m, weighted, vmax, scale, positions, previous,
                                                       amax):
    # one level and no extra rows takes a shortcut (one solve, no cascade bookkeeping);
    # an extra row that can never be active sends the same problem through the general
    # cascade: the same q̇, residual, activity and box, whether the box holds the answer or
    # not, near a position limit or not, with or without the acceleration side
    rng = np.random.default_rng(seed)
    n = 7
    # a tool-like block of m rows over a posture-like identity (every direction seen)
    A = np.vstack([rng.normal(size=(m, n)), 0.1 * np.eye(n)])
    b = scale * rng.normal(size=m + n)
    w = rng.uniform(0.1, 10.0, size=m + n) if weighted else None
    q, qd_prev = rng.normal(size=n), rng.normal(scale=0.05, size=n) if previous else None
    # position limits absent, far from q, or with some joints near one (within what vmax
    # covers in a few periods): the box's position side then acts or may act
    room = {"none": np.inf, "far": 10.0, "near": rng.uniform(0.0, 0.2, size=n)}[positions]
    lim = _Box(n, vmax, amax=amax, lower=q - room, upper=q + room)
    level = (A, b) if w is None else (A, b, w)
    fast = PriorityCascade().solve([level], limits=lim, q=q, qd_prev=qd_prev, dt=0.01)
    general = PriorityCascade().solve([level], limits=lim, q=q, qd_prev=qd_prev, dt=0.01,
                                      extra_inequalities=(np.zeros((1, n)), np.ones(1)))
    assert fast.qd.tolist() == general.qd.tolist()
    assert fast.residuals.tolist() == general.residuals.tolist()
    for name in ("qps", "freedom", "box_active", "lower", "upper"):
        assert getattr(fast, name).tolist() == getattr(general, name).tolist(), name
    assert fast.rows_active.shape == (0,) and fast.relaxed.shape == (0,)
    assert not fast.qd.flags.writeable and not fast.residuals.flags.writeable


@settings(max_examples=40, deadline=None)
@given(st.integers(0, 2**31 - 1), st.booleans(), st.sampled_from([100.0, np.inf]))
def test_an_answer_clear_of_the_box_reports_the_box_of_the_step(seed, previous, amax):
    # small task velocities, well inside the box (the common control step): the answer,
    # its residual and the box it reports are the general cascade's, and the box is the
    # one `box` gives for the step
    rng = np.random.default_rng(seed)
    n = 7
    A = np.vstack([rng.normal(size=(6, n)), 0.1 * np.eye(n)])
    b = 0.01 * rng.normal(size=6 + n)
    q = rng.normal(size=n)
    qd_prev = rng.normal(scale=0.01, size=n) if previous else None
    lim = _Box(n, 2.0, amax=amax, lower=q - 3.0, upper=q + 3.0)
    cascade = PriorityCascade()
    fast = cascade.solve([(A, b)], limits=lim, q=q, qd_prev=qd_prev, dt=0.01)
    general = PriorityCascade().solve([(A, b)], limits=lim, q=q, qd_prev=qd_prev, dt=0.01,
                                      extra_inequalities=(np.zeros((1, n)), np.ones(1)))
    lo, hi = cascade.box(n, lim, q, qd_prev, 0.01)
    assert fast.qd.tolist() == general.qd.tolist()
    assert fast.residuals.tolist() == general.residuals.tolist()
    assert not fast.box_active.any() and not fast.qps.any()
    assert fast.lower.tolist() == general.lower.tolist() == lo.tolist()
    assert fast.upper.tolist() == general.upper.tolist() == hi.tolist()
    assert not fast.lower.flags.writeable and not fast.upper.flags.writeable


@settings(max_examples=20, deadline=None)
@given(st.integers(0, 2**31 - 1), st.booleans())
def test_a_one_level_tasks_cycle_reports_the_cascades_own_result(seed, previous):
    # the tasks stage solves a one-level cycle clear of the box without building the
    # cascade's result; read, it is the result `solve_validated` gives for the same rows
    import ratectl as rc
    from ratectl.control.tasks_stage import TasksStage

    ch = rc.robots.panda()
    rng = np.random.default_rng(seed)
    q = 0.5 * (ch.qlim[:, 0] + ch.qlim[:, 1]) + rng.uniform(-0.3, 0.3, size=7)  # (far from the limits)
    T = ch.fk(q)
    T[:3, 3] += rng.uniform(-1e-4, 1e-4, size=3)  # (a step of the servo: well inside amax·dt)
    stage = TasksStage(ch, [rc.tasks.Pose(target=T), rc.tasks.Posture(q + 0.001, weight=0.01, gain=1.0)])
    qd_prev = rng.normal(scale=0.001, size=7) if previous else None
    res = stage.solve(q, dt=1e-3, qd_prev=qd_prev, limits=ch)
    A, b, _ = stage._levels[0]
    want = PriorityCascade().solve_validated([(A.copy(), b.copy(), None)], limits=ch, q=q, qd_prev=qd_prev,
                                             dt=1e-3)
    got = res.cascade
    assert got is res.cascade
    assert got.qd is res.qd and got.residuals is res.residuals
    for name in ("qd", "residuals", "qps", "freedom", "box_active", "lower", "upper", "rows_active",
                 "relaxed"):
        assert getattr(got, name).tolist() == getattr(want, name).tolist(), name
    assert got.backend == want.backend
