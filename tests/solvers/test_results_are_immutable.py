"""A solver's result cannot be changed, and nothing done to it reaches the solver."""

import numpy as np
import pytest

import ratectl as rc


@pytest.mark.parametrize("solver", [rc.solvers.DLS(), rc.solvers.AdaptiveDLS(), rc.solvers.PseudoInverse(),
                                    rc.solvers.SDLS(), rc.solvers.QP()], ids=lambda s: type(s).__name__)
def test_arrays_and_info_are_read_only(solver):
    arm = rc.robots.ur5e()
    q = np.array([0.3, -1.3, 1.6, -1.9, -1.2, 0.2])
    r = solver.solve(arm.jacobian(q), np.array([0.1, 0, 0, 0, 0, 0.2]), limits=arm, q=q, dt=1e-3)
    for name in ("qd", "achieved", "task_error", "bound"):
        with pytest.raises(ValueError, match="read-only"):
            getattr(r, name)[0] = 1.0
    with pytest.raises(TypeError):
        r.info["anything"] = 1  # type: ignore[index]
    for value in r.info.values():
        if isinstance(value, np.ndarray) and value.size:
            with pytest.raises(ValueError, match="read-only"):
                value.flat[0] = 1.0
    with pytest.raises(TypeError):
        rc.solvers.SolveResult(r.qd, r.achieved, r.task_error, 0.0, 1.0, "dls")  # keyword-only


def test_a_second_solve_does_not_change_the_first_result():
    arm = rc.robots.ur5e()
    q = np.array([0.3, -1.3, 1.6, -1.9, -1.2, 0.2])
    solver = rc.solvers.QP()
    r1 = solver.solve(arm.jacobian(q), np.ones(6) * 0.1, limits=arm, q=q, dt=1e-3)
    before = r1.qd.copy()
    solver.solve(arm.jacobian(q + 0.1), -np.ones(6), limits=arm, q=q + 0.1, qd_prev=r1.qd, dt=1e-3)
    np.testing.assert_array_equal(r1.qd, before)
