"""Inverse-velocity solvers: exactness where regular, bounded gains at singularities,
filtered damping, SDLS, weights, velocity-limit policies and null-space objectives."""

import dataclasses
import math
import pickle

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import ratectl as rc
from ratectl import solvers as S
from ratectl.errors import InputError, SingularityError


def _smin(J):
    return float(np.linalg.svd(J, compute_uv=False)[-1])


def _regular_configs(chain, rng, count, *, smin_at_least=0.05):
    out = []
    while len(out) < count:
        q = chain.random_q(rng=rng)
        if _smin(chain.jacobian(q)) > smin_at_least:
            out.append(q)
    return out


def _singular_ur5e(rng, joint):
    ur = rc.robots.ur5e()
    q = ur.random_q(rng=rng)
    q[joint] = 0.0  # q5 = 0: wrist singularity; q3 = 0: elbow fully stretched
    return ur, q


# --------------------------------------------------------------------------- regular J
def _all_solvers():
    return [
        S.Inverse(),
        S.PseudoInverse(),
        S.DLS(damping=1e-8),
        S.AdaptiveDLS(epsilon=0.01, max_damping=0.05),
        S.AdaptiveDLS(epsilon=0.01, max_damping=0.05, mode="filtered"),
        S.AdaptiveDLS(max_damping=0.05, mode="manipulability", manipulability_threshold=1e-6),
        S.SDLS(gamma_max=1e3, characteristic_length=0.8),
        S.NullSpace(S.AdaptiveDLS(epsilon=0.01), lambda q: -q),
        S.QP(damping=1e-8),
    ]


def test_every_solver_returns_the_inverse_for_a_regular_square_J(rng):
    ur = rc.robots.ur5e()
    for q in _regular_configs(ur, rng, 10):
        J = ur.jacobian(q)
        xi = 0.1 * rng.standard_normal(6)
        exact = np.linalg.solve(J, xi)
        for solver in _all_solvers():
            r = solver.solve(J, xi, q=q)
            assert np.max(np.abs(r.qd - exact)) < 1e-9, solver
            assert np.max(np.abs(r.task_error)) < 1e-9, solver
            assert np.allclose(r.achieved, J @ r.qd, atol=1e-14)
            assert r.sigma_min == pytest.approx(_smin(J), abs=1e-8), solver


def test_undamped_solvers_report_zero_damping_when_regular(rng):
    ur = rc.robots.ur5e()
    q = _regular_configs(ur, rng, 1)[0]
    J = ur.jacobian(q)
    for solver in (S.Inverse(), S.PseudoInverse(), S.AdaptiveDLS(epsilon=0.01)):
        assert solver.solve(J, np.ones(6)).damping == 0.0


def test_pseudo_inverse_of_a_redundant_arm_is_minimum_norm(rng):
    iiwa = rc.robots.iiwa7()
    for q in _regular_configs(iiwa, rng, 5):
        J = iiwa.jacobian(q)
        xi = rng.standard_normal(6)
        r = S.PseudoInverse().solve(J, xi)
        assert np.allclose(r.qd, np.linalg.pinv(J) @ xi, atol=1e-10)
        assert np.max(np.abs(r.task_error)) < 1e-10
        assert r.info["rank"] == 6


def test_pseudo_inverse_truncates_below_its_tolerance():
    J = np.diag([1.0, 1e-3, 1e-9])
    xi = np.ones(3)
    r = S.PseudoInverse(tolerance=1e-6).solve(J, xi)
    assert np.allclose(r.qd, [1.0, 1e3, 0.0])
    assert r.info["rank"] == 2
    r = S.PseudoInverse(tolerance=1e-2).solve(J, xi)
    assert np.allclose(r.qd, [1.0, 0.0, 0.0])


# --------------------------------------------------------------------------- singular J
@pytest.mark.parametrize("joint", [4, 2], ids=["wrist_q5=0", "elbow_q3=0"])
def test_inverse_raises_at_exact_singularities(rng, joint):
    for _ in range(5):
        ur, q = _singular_ur5e(rng, joint)
        J = ur.jacobian(q)
        assert _smin(J) < 1e-10
        with pytest.raises(SingularityError) as info:
            S.Inverse().solve(J, np.ones(6))
        assert info.value.sigma_min < 1e-10
        assert info.value.tolerance == 1e-6
        assert "sigma_min" in str(info.value)


@pytest.mark.parametrize("joint", [4, 2], ids=["wrist_q5=0", "elbow_q3=0"])
def test_dls_family_is_bounded_at_exact_singularities(rng, joint):
    lam = 0.04
    for _ in range(10):
        ur, q = _singular_ur5e(rng, joint)
        J = ur.jacobian(q)
        U = np.linalg.svd(J)[0]
        # the worst twist for the gain: along the lost direction, plus a random one
        for xi in (0.3 * U[:, -1], rng.standard_normal(6)):
            nxi = np.linalg.norm(xi)
            r = S.DLS(damping=lam).solve(J, xi)
            assert np.all(np.isfinite(r.qd))
            assert np.linalg.norm(r.qd) <= nxi / (2 * lam) * (1 + 1e-9)
            assert r.sigma_min < 1e-7

            ad = S.AdaptiveDLS(epsilon=0.05, max_damping=lam)
            r = ad.solve(J, xi)
            assert np.all(np.isfinite(r.qd))
            assert r.damping == pytest.approx(lam, rel=1e-6)  # σ_min ≈ 0 → λ = λ_max
            assert np.linalg.norm(r.qd) <= nxi / (2 * r.damping) * (1 + 1e-9)
            assert np.linalg.norm(r.qd) <= r.info["gain_bound"] * nxi * (1 + 1e-9)
            assert np.linalg.norm(r.qd) <= ad.gain_bound() * nxi * (1 + 1e-9)

            fd = S.AdaptiveDLS(epsilon=0.05, max_damping=lam, mode="filtered")
            r = fd.solve(J, xi)
            assert np.all(np.isfinite(r.qd))
            assert r.damping == pytest.approx(lam, rel=1e-6)
            assert np.linalg.norm(r.qd) <= fd.gain_bound() * nxi * (1 + 1e-9)

            md = S.AdaptiveDLS(max_damping=lam, mode="manipulability", manipulability_threshold=1e-3)
            r = md.solve(J, xi)
            assert r.damping == pytest.approx(lam, rel=1e-5)  # w ≈ 0 → λ ≈ λ_max
            assert np.linalg.norm(r.qd) <= nxi / (2 * lam) * (1 + 1e-9)

            r = S.SDLS(gamma_max=1.0).solve(J, xi)
            assert np.all(np.isfinite(r.qd)) and np.max(np.abs(r.qd)) <= 1.0 + 1e-12


def test_dls_gain_bound_is_attained_at_sigma_equal_lambda():
    lam = 0.1
    J = np.diag([1.0, lam])
    r = S.DLS(damping=lam).solve(J, np.array([0.0, 1.0]))
    assert np.linalg.norm(r.qd) == pytest.approx(1 / (2 * lam), rel=1e-12)


def test_adaptive_schedule_and_gain_bound_over_a_sweep_of_sigma():
    eps, lam_max = 0.1, 0.05
    ad = S.AdaptiveDLS(epsilon=eps, max_damping=lam_max)
    worst = 0.0
    for s in np.linspace(0.0, 2 * eps, 401):
        J = np.diag([1.0, 0.5, s])
        r = ad.solve(J, np.array([0.0, 0.0, 1.0]))
        expected = lam_max * math.sqrt(1 - (s / eps) ** 2) if s < eps else 0.0
        assert r.damping == pytest.approx(expected, abs=1e-9)
        gain = np.linalg.norm(r.qd)
        assert gain <= r.info["gain_bound"] * (1 + 1e-9)
        worst = max(worst, gain)
    assert worst <= ad.gain_bound() * (1 + 1e-9)
    assert worst >= 0.99 * ad.gain_bound()  # the closed-form supremum is tight
    assert S.adaptive_damping(0.0, epsilon=eps, max_damping=lam_max) == lam_max
    assert S.adaptive_damping(eps, epsilon=eps, max_damping=lam_max) == 0.0


def test_filtered_damping_tracks_the_regular_directions_exactly(rng):
    eps = 0.05
    for joint in (4, 2):
        ur, q = _singular_ur5e(rng, joint)
        J = ur.jacobian(q)
        U, s, _ = np.linalg.svd(J)
        xi = rng.standard_normal(6)
        r = S.AdaptiveDLS(epsilon=eps, max_damping=0.05, mode="filtered").solve(J, xi)
        regular = U[:, s >= eps]
        singular = U[:, s < eps]
        assert regular.shape[1] == 5 and singular.shape[1] == 1
        # the task error has no component along the regular left-singular directions
        assert np.max(np.abs(regular.T @ r.task_error)) < 1e-9 * np.linalg.norm(xi)
        # ... and it does along the lost one (the damping gave it up)
        assert abs(singular[:, 0] @ r.task_error) > 0.1 * abs(singular[:, 0] @ xi)
        assert r.info["damped_directions"] == 1
        # uniform damping, in contrast, spreads the error over the regular directions
        ru = S.AdaptiveDLS(epsilon=eps, max_damping=0.05).solve(J, xi)
        assert np.max(np.abs(regular.T @ ru.task_error)) > 1e-6


def test_manipulability_schedule_follows_nakamura_hanafusa(rng):
    ur = rc.robots.ur5e()
    q = _regular_configs(ur, rng, 1)[0]
    J = ur.jacobian(q)
    w = math.sqrt(np.linalg.det(J @ J.T))
    w0, lam = 2 * w, 0.03
    solver = S.AdaptiveDLS(max_damping=lam, mode="manipulability", manipulability_threshold=w0)
    r = solver.solve(J, np.ones(6))
    assert r.info["manipulability"] == pytest.approx(w, rel=1e-9)
    assert r.damping == pytest.approx(lam * (1 - w / w0), rel=1e-9)
    expected = J.T @ np.linalg.solve(J @ J.T + r.damping**2 * np.eye(6), np.ones(6))
    assert np.allclose(r.qd, expected, atol=1e-10)


def test_sdls_clamps_each_direction_and_the_sum(rng):
    ur = rc.robots.ur5e()
    for _ in range(20):
        q = ur.random_q(rng=rng)
        q[4] = rng.choice([0.0, 1e-3, 0.5])
        J = ur.jacobian(q)
        xi = rng.standard_normal(6)
        r = S.SDLS(gamma_max=0.7, characteristic_length=ur.characteristic_length).solve(J, xi)
        assert np.max(np.abs(r.qd)) <= 0.7 * (1 + 1e-12)
        g = r.info["gammas"]
        assert np.all(g <= 0.7 + 1e-12) and np.all(g >= 0)


def test_sdls_characteristic_length_changes_only_clamped_solutions(rng):
    ur = rc.robots.ur5e()
    q = _regular_configs(ur, rng, 1)[0]
    J = ur.jacobian(q)
    xi = 1e-3 * rng.standard_normal(6)
    a = S.SDLS(gamma_max=10, characteristic_length=0.1).solve(J, xi).qd
    b = S.SDLS(gamma_max=10, characteristic_length=3.0).solve(J, xi).qd
    assert np.allclose(a, np.linalg.solve(J, xi), atol=1e-12)
    assert np.allclose(a, b, atol=1e-12)


# --------------------------------------------------------------------------- policies
def test_velocity_policy_scale_keeps_the_direction(rng):
    ur = rc.robots.ur5e()
    q = _regular_configs(ur, rng, 1)[0]
    J = ur.jacobian(q)
    xi = np.array([1.0, -0.5, 0.8, 2.0, 1.0, -1.5])
    free = S.DLS(damping=0.01, velocity_policy=None).solve(J, xi, limits=ur)
    assert free.velocity_policy == "none" and np.max(np.abs(free.qd) / ur.vmax) > 1
    r = S.DLS(damping=0.01).solve(J, xi, limits=ur)
    assert r.velocity_policy == "scaled"
    assert r.limits_active == ("velocity",)
    assert np.max(np.abs(r.qd) / ur.vmax) == pytest.approx(1.0)
    assert np.allclose(r.qd, r.velocity_scale * free.qd)
    assert 0 < r.velocity_scale < 1
    assert r.bound[np.argmax(np.abs(free.qd) / ur.vmax)]
    assert np.allclose(r.achieved, J @ r.qd)
    c = S.DLS(damping=0.01, velocity_policy="clip").solve(J, xi, limits=ur)
    assert c.velocity_policy == "clipped" and c.velocity_scale == 1.0
    assert np.all(np.abs(c.qd) <= ur.vmax)
    over = np.abs(free.qd) > ur.vmax
    assert np.array_equal(c.bound, over)
    assert np.allclose(c.qd[~over], free.qd[~over])
    small = S.DLS(damping=0.01).solve(J, 1e-3 * xi, limits=ur)
    assert small.velocity_policy == "none" and small.limits_active == () and not small.bound.any()


def test_limits_object_and_bad_limits():
    lim = S.Limits(lower=-np.ones(2), upper=np.ones(2), vmax=np.full(2, 0.5), amax=np.full(2, 1.0))
    r = S.DLS(damping=1e-6).solve(np.eye(2), np.array([1.0, 0.0]), limits=lim)
    assert np.allclose(r.qd, [0.5, 0.0])
    with pytest.raises(InputError):
        S.DLS().solve(np.eye(2), np.ones(2), limits=object())
    with pytest.raises(InputError):
        S.DLS().solve(np.eye(3), np.ones(3), limits=lim)


# --------------------------------------------------------------------------- weights
def test_position_and_orientation_only_tasks(rng):
    ur = rc.robots.ur5e()
    for q in _regular_configs(ur, rng, 5):
        J = ur.jacobian(q)
        xi = rng.standard_normal(6)
        for weights, rows in (("position", slice(0, 3)), (S.ORIENTATION_ONLY, slice(3, 6))):
            expected = np.linalg.pinv(J[rows]) @ xi[rows]  # minimum norm for the 3 rows
            for solver in (S.PseudoInverse(task_weights=weights),
                           S.AdaptiveDLS(epsilon=0.01, task_weights=weights)):
                r = solver.solve(J, xi)
                assert np.allclose(r.achieved[rows], xi[rows], atol=1e-8), solver
                assert np.allclose(r.qd, expected, atol=1e-7), solver
            # the QP regularises with λ²‖q̇‖² (a rank-3 task needs λ > 0): close, not exact
            r = S.QP(damping=1e-4, task_weights=weights).solve(J, xi)
            assert np.allclose(r.qd, expected, atol=1e-4)


def test_partial_twist_for_a_planar_arm(rng):
    arm = rc.robots.planar2r()
    q = np.array([0.3, 1.1])
    J = arm.jacobian(q)
    xi = np.array([0.2, -0.1, 0.0, 0.0, 0.0, 0.0])
    r = S.Inverse(task_weights=(1, 1, 0, 0, 0, 0)).solve(J, xi)
    assert np.allclose(r.qd, np.linalg.solve(J[:2], xi[:2]), atol=1e-12)
    with pytest.raises(InputError, match="square"):
        S.Inverse().solve(J, xi)


def test_joint_weights_give_the_weighted_minimum_norm_solution(rng):
    iiwa = rc.robots.iiwa7()
    q = _regular_configs(iiwa, rng, 1)[0]
    J = iiwa.jacobian(q)
    xi = rng.standard_normal(6)
    w = np.array([100.0, 1, 1, 1, 1, 1, 1])
    Wi = np.diag(1 / w)
    expected = Wi @ J.T @ np.linalg.solve(J @ Wi @ J.T, xi)
    for solver in (S.PseudoInverse(joint_weights=w), S.AdaptiveDLS(epsilon=0.01, joint_weights=w)):
        r = solver.solve(J, xi)
        assert np.allclose(r.qd, expected, atol=1e-7), solver
    assert np.allclose(S.QP(damping=1e-4, joint_weights=w).solve(J, xi).qd, expected, rtol=1e-4, atol=1e-6)
    plain = S.PseudoInverse().solve(J, xi).qd
    assert abs(expected[0]) < abs(plain[0])


def test_bad_weights_raise():
    with pytest.raises(InputError):
        S.DLS(task_weights=[-1, 1, 1, 1, 1, 1])
    with pytest.raises(InputError):
        S.DLS(task_weights="elbow")
    with pytest.raises(InputError):
        S.DLS(joint_weights=[0.0, 1.0])
    with pytest.raises(InputError, match="task_weights"):
        S.DLS(task_weights=(1, 1, 1)).solve(np.eye(6), np.ones(6))


# --------------------------------------------------------------------------- null space
def test_joint_centring_leaves_unlimited_joints_alone():
    """Joints without finite limits get no centring (and no inf − inf on the way)."""
    limits = rc.model.limits.Limits(lower=[-np.inf, -2.0, -np.inf, 0.0], upper=[np.inf, 2.0, 1.0, 1.0],
                                    vmax=np.ones(4), amax=np.ones(4))
    with np.errstate(all="raise"):
        centring = S.JointCentring(limits)
        z = centring([5.0, 1.0, -3.0, 1.0])
    assert np.array_equal(z, [0.0, -0.25, 0.0, -2.0])  # −(q − c)/r² on the limited joints only


def test_null_space_centring_on_iiwa_tracks_the_task_and_centres(rng):
    iiwa = rc.robots.iiwa7()
    centring = S.JointCentring(iiwa)
    solver = S.NullSpace(S.AdaptiveDLS(epsilon=0.01), "centring", chain=iiwa, gain=20.0)
    # primary twist tracked exactly where regular
    for q in _regular_configs(iiwa, rng, 5):
        J = iiwa.jacobian(q)
        xi = rng.standard_normal(6)
        r = solver.solve(J, xi, q=q)
        assert np.max(np.abs(J @ r.qd - xi)) < 1e-9
        assert np.linalg.norm(r.info["secondary"]) > 0
    # holding the pose (ξ = 0), the self-motion decreases the distance from the centres
    q = _regular_configs(iiwa, rng, 1)[0]
    q = np.clip(q, iiwa.lower * 0.9, iiwa.upper * 0.9)
    T0 = iiwa.fk(q)
    costs = [centring.cost(q)]
    dt = 0.01
    for _ in range(200):
        T, J = iiwa.fk_jacobian(q)
        xi = 20.0 * rc.spatial.pose_error(T0, T)  # hold the pose against integration drift
        r = solver.solve(J, xi, q=q)
        q = q + dt * r.qd
        costs.append(centring.cost(q))
    assert all(b <= a + 1e-9 for a, b in zip(costs, costs[1:], strict=False))
    assert costs[-1] < 0.9 * costs[0]  # self-motion is 1-D: the decrease is bounded
    assert np.max(np.abs(rc.spatial.pose_error(T0, iiwa.fk(q)))) < 1e-4


def test_null_space_projection_does_not_leak_through_damping(rng):
    iiwa = rc.robots.iiwa7()
    q = iiwa.random_q(rng=rng)
    q[3] = 1e-3  # near the elbow singularity: the damping is active
    J = iiwa.jacobian(q)
    xi = rng.standard_normal(6)
    primary = S.DLS(damping=0.1, velocity_policy=None)
    p = primary.solve(J, xi)
    r = S.NullSpace(primary, S.Gradient(lambda q: q - 0.5), gain=3.0).solve(J, xi, q=q)
    assert np.linalg.norm(r.info["secondary"]) > 1e-3
    assert np.allclose(r.achieved, p.achieved, atol=1e-9)  # the secondary adds no task motion
    # a projector built from the damped inverse would leak
    Jd = J.T @ np.linalg.inv(J @ J.T + 0.01 * np.eye(6))
    leak = J @ (np.eye(7) - Jd @ J) @ (-(q - 0.5))
    assert np.linalg.norm(leak) > 1e-3


def test_null_space_user_gradient_and_manipulability(rng):
    iiwa = rc.robots.iiwa7()
    q0 = _regular_configs(iiwa, rng, 1)[0]
    target = np.zeros(7)
    g = S.Gradient(lambda q: q - target)  # cost ½‖q‖², descended
    solver = S.NullSpace(S.PseudoInverse(), g, gain=1.0)
    q = q0.copy()
    for _ in range(50):
        q = q + 0.02 * solver.solve(iiwa.jacobian(q), np.zeros(6), q=q).qd
    assert np.linalg.norm(q) < np.linalg.norm(q0)
    # manipulability objective (ratectl.singularity.manipulability_gradient)
    man = S.NullSpace(S.AdaptiveDLS(epsilon=0.01), "manipulability", chain=iiwa, gain=5.0)
    q = q0.copy()
    w0 = rc.manipulability(iiwa.jacobian(q))
    for _ in range(50):
        q = q + 0.01 * man.solve(iiwa.jacobian(q), np.zeros(6), q=q).qd
    assert rc.manipulability(iiwa.jacobian(q)) > w0


def test_null_space_needs_q():
    with pytest.raises(InputError, match="q="):
        S.NullSpace(S.DLS(), lambda q: q).solve(np.ones((6, 7)), np.ones(6))
    with pytest.raises(InputError, match="chain"):
        S.NullSpace(S.DLS(), "centring")


# --------------------------------------------------------------------------- contract
def test_result_is_frozen_and_lazy_sigma_is_transparent(rng):
    ur = rc.robots.ur5e()
    q = _regular_configs(ur, rng, 1)[0]
    J = ur.jacobian(q)
    r = S.DLS().solve(J, np.ones(6))
    with pytest.raises(dataclasses.FrozenInstanceError):
        r.qd = np.zeros(6)
    with pytest.raises(dataclasses.FrozenInstanceError):
        r.sigma_min = 1.0
    assert r.sigma_min == pytest.approx(_smin(J), abs=1e-9)
    assert isinstance(r.sigma_min, float)
    r2 = pickle.loads(pickle.dumps(r))
    assert r2.sigma_min == r.sigma_min
    assert dataclasses.replace(r, damping=1.0).sigma_min == r.sigma_min
    assert "sigma_min=" in repr(r)
    assert [f.name for f in dataclasses.fields(r)][:6] == [
        "qd", "achieved", "task_error", "damping", "sigma_min", "method"]


def test_bad_inputs_raise_input_errors():
    J = np.eye(6)
    for bad_J, bad_xi in ((np.ones(6), np.ones(6)), (J, np.ones(5)), (J * np.nan, np.ones(6)),
                          (J, np.full(6, np.inf)), ("x", np.ones(6))):
        for solver in (S.DLS(), S.AdaptiveDLS(), S.PseudoInverse(), S.Inverse(), S.QP()):
            with pytest.raises(InputError):
                solver.solve(bad_J, bad_xi)
    with pytest.raises(InputError):
        S.DLS(damping=-1)
    with pytest.raises(InputError):
        S.DLS(velocity_policy="shrink")
    with pytest.raises(InputError):
        S.AdaptiveDLS(mode="magic")
    with pytest.raises(InputError, match="manipulability_threshold"):
        S.AdaptiveDLS(mode="manipulability")


def test_public_names():
    for name in ("Inverse", "PseudoInverse", "DLS", "AdaptiveDLS", "SDLS", "QP", "NullSpace"):
        assert hasattr(rc.solvers, name)
    assert rc.solvers.QP is rc.solvers.QP
    assert rc.solvers.DLS(damping=0.1).damping == 0.1
    assert rc.solvers.AdaptiveDLS(epsilon=0.1, max_damping=0.2).max_damping == 0.2


# --------------------------------------------------------------------------- properties
@settings(max_examples=60, deadline=None)
@given(st.integers(1, 6), st.integers(1, 7), st.integers(0, 5), st.integers(0, 2**32 - 1))
def test_gain_bounds_hold_for_random_possibly_rank_deficient_J(m, n, drop, seed):
    rng = np.random.default_rng(seed)
    J = rng.standard_normal((m, n))
    U, s, Vt = np.linalg.svd(J, full_matrices=False)
    s[len(s) - min(drop, len(s)):] *= rng.choice([0.0, 1e-9, 1e-3])  # lose some rank
    J = (U * s) @ Vt
    xi = rng.standard_normal(m)
    nxi = np.linalg.norm(xi)
    lam = 0.05
    r = S.DLS(damping=lam).solve(J, xi)
    assert np.linalg.norm(r.qd) <= nxi / (2 * lam) * (1 + 1e-9)
    for mode in ("sigma", "filtered"):
        ad = S.AdaptiveDLS(epsilon=0.1, max_damping=lam, mode=mode)
        r = ad.solve(J, xi)
        assert np.linalg.norm(r.qd) <= ad.gain_bound() * nxi * (1 + 1e-9)
        assert np.linalg.norm(r.qd) <= r.info["gain_bound"] * nxi * (1 + 1e-9)
    # the DLS result is the minimiser of ‖Jq̇ − ξ‖² + λ²‖q̇‖²
    ref = np.linalg.solve(J.T @ J + lam**2 * np.eye(n), J.T @ xi)
    assert np.allclose(S.DLS(damping=lam).solve(J, xi).qd, ref, atol=1e-9)
