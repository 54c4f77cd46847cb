"""Singularity analysis: measures, classification (UR5e, PUMA 560, Stanford, RPR, iiwa),
batched scans, the manipulability gradient, paths and workspace maps."""

import dataclasses
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import ratectl as rc
from ratectl import singularity as S

UR_A2, UR_A3, UR_D5 = -0.425, -0.3922, 0.0997
PUMA_A2, PUMA_A3, PUMA_D4 = 0.4318, 0.0203, 0.4318


# ---------------------------------------------------------------- measures from J
def test_measures_agree_with_their_definitions(arm, rng):
    qs = arm.random_q(5, rng=rng)
    J = arm.jacobian(qs)
    s = rc.singular_values(J)
    m = min(6, arm.dof)
    assert s.shape == (5, m)
    for Ji, si in zip(J, s, strict=True):
        assert np.allclose(si, np.linalg.svd(Ji, compute_uv=False), rtol=1e-12, atol=1e-14)
    w = rc.manipulability(J)
    G = J @ np.swapaxes(J, -1, -2) if arm.dof >= 6 else np.swapaxes(J, -1, -2) @ J
    assert np.allclose(w, np.sqrt(np.linalg.det(G)), rtol=1e-9)
    assert np.allclose(w, np.prod(s, axis=-1), rtol=1e-9)
    assert np.allclose(rc.condition_number(J), s[:, 0] / s[:, -1])
    assert np.allclose(rc.condition_number(J, inverse=True), s[:, -1] / s[:, 0])


def test_length_scaling_divides_the_linear_rows(rng):
    arm = rc.robots.ur5e()
    J = arm.jacobian(arm.random_q(rng=rng))
    L = 0.7
    D = np.diag([1 / L] * 3 + [1.0] * 3)
    assert np.allclose(rc.singular_values(J, length=L), np.linalg.svd(D @ J, compute_uv=False))
    # for a 6×n J (n ≥ 6), w(J_L) = w(J) / L³
    assert math.isclose(float(rc.manipulability(J, length=L)), float(rc.manipulability(J)) / L**3,
                        rel_tol=1e-10)
    with pytest.raises(rc.InputError):
        rc.singular_values(J, length=-1.0)
    with pytest.raises(rc.InputError):
        rc.singular_values(J[:3], length=1.0)


def test_rank_and_condition_at_a_constructed_singular_matrix():
    J = np.zeros((6, 6))
    J[np.arange(5), np.arange(5)] = [3.0, 2.0, 1.0, 1.0, 0.5]
    assert int(S.rank(J)) == 5
    assert np.isinf(rc.condition_number(J))
    assert float(rc.condition_number(J, inverse=True)) == 0.0
    J[5, 5] = 1e-6
    assert int(S.rank(J)) == 6 and int(S.rank(J, rtol=1e-3)) == 5


def test_axes_extracted_from_the_jacobian_are_the_joint_axes(arm, rng):
    # z_i = J_ω,i and p + z_i × J_v,i lies on the axis of revolute joint i
    q = arm.random_q(rng=rng)
    T, J = arm.fk_jacobian(q)
    from ratectl.singularity.structure import _lines

    z, c = _lines(J)
    axes, points = arm.joint_axes(q)
    for i in np.flatnonzero(~arm.prismatic):
        assert np.allclose(z[i], axes[i], atol=1e-12)
        d = T[:3, 3] + c[i] - points[i]
        assert np.linalg.norm(np.cross(d, axes[i])) < 1e-12


# ---------------------------------------------------------------- UR5e
def ur_det(q):
    c2, s3, s5 = math.cos(q[1]), math.sin(q[2]), math.sin(q[4])
    c23, s234 = math.cos(q[1] + q[2]), math.sin(q[1] + q[2] + q[3])
    return s3 * s5 * UR_A2 * UR_A3 * (c2 * UR_A2 + c23 * UR_A3 + s234 * UR_D5)


def test_ur5e_determinant_closed_form(rng):
    arm = rc.robots.ur5e()
    for _ in range(20):
        q = arm.random_q(rng=rng)
        assert abs(np.linalg.det(arm.jacobian(q)) - ur_det(q)) < 1e-12


def ur_shoulder_q(q1=0.5, q2=-1.2, q5=1.0, q6=0.3):
    """A UR5e configuration with c2·a2 + c23·a3 + s234·d5 = 0 (s234 = 1)."""
    c23 = -(UR_D5 + math.cos(q2) * UR_A2) / UR_A3
    q3 = -math.acos(c23) - q2
    q4 = math.pi / 2 - q2 - q3
    return np.array([q1, q2, q3, q4, q5, q6])


UR_REGULAR = np.array([0.3, -1.0, 1.2, -0.7, 0.8, 0.4])


def ur_cases():
    wrist = UR_REGULAR.copy()
    wrist[4] = 0.0
    elbow = UR_REGULAR.copy()
    elbow[2] = 0.0
    shoulder = ur_shoulder_q()
    return [("wrist", wrist, 4), ("elbow", elbow, 2), ("shoulder", shoulder, 2)]


@pytest.mark.parametrize("kind,q_sing,joint", ur_cases(), ids=["wrist", "elbow", "shoulder"])
def test_ur5e_singularities_classified_at_and_near(kind, q_sing, joint):
    arm = rc.robots.ur5e()
    assert abs(ur_det(q_sing)) < 1e-14  # the closed form says it is singular
    r = rc.analyze(arm, q_sing)
    assert r.kind == kind and r.singular and r.rank == 5
    assert r.sigma_min_scaled < 1e-12
    assert kind in r.causes
    prev = None
    for eps in (1e-2, 3e-3, 1e-3, -1e-3, -1e-2):
        q = q_sing.copy()
        q[joint] += eps
        r = rc.analyze(arm, q)
        assert r.kind == kind, (eps, r)
        assert not r.singular and r.rank == 6 and r.near_singular
        if eps > 0:
            # σ_min → 0 as the configuration approaches the singular one
            assert prev is None or r.sigma_min_scaled < prev
            prev = r.sigma_min_scaled
    assert prev < 1e-3


def test_ur5e_reasons_and_closeness():
    arm = rc.robots.ur5e()
    q = UR_REGULAR.copy()
    q[4] = 2e-3
    r = rc.analyze(arm, q)
    assert "axes of joints 'wrist_1' and 'wrist_3' are parallel" in r.reason
    # first-order joint-space distance to the singular set q5 = 0
    assert abs(r.joint_distance - 2e-3) < 1e-4
    assert abs(r.factors["wrist"] - math.sin(2e-3)) < 1e-12
    q = UR_REGULAR.copy()
    q[2] = 5e-3
    r = rc.analyze(arm, q)
    assert "axes of joints 'shoulder_lift' and 'elbow'" in r.reason and "stretched" in r.reason
    assert abs(r.factors["elbow"] - math.sin(5e-3)) < 1e-12
    q[2] = math.pi - 5e-3
    r = rc.analyze(arm, q)
    assert r.kind == "elbow" and "folded" in r.reason


def test_ur5e_shoulder_factor_is_the_distance_from_the_plane():
    # c2·a2 + c23·a3 + s234·d5 is the signed distance of o5 from the plane through axis 1
    # parallel to axis 2; the shoulder factor is its magnitude over L
    arm = rc.robots.ur5e()
    rng = np.random.default_rng(7)
    for _ in range(10):
        q = arm.random_q(rng=rng)
        c2 = math.cos(q[1])
        d = c2 * UR_A2 + math.cos(q[1] + q[2]) * UR_A3 + math.sin(q[1] + q[2] + q[3]) * UR_D5
        r = rc.analyze(arm, q)
        assert abs(r.factors["shoulder"] - abs(d) / arm.characteristic_length) < 1e-12
        assert abs(r.factors["elbow"] - abs(math.sin(q[2]))) < 1e-12
        assert abs(r.factors["wrist"] - abs(math.sin(q[4]))) < 1e-12


def test_ur5e_regular_configurations_are_regular(rng):
    arm = rc.robots.ur5e()
    qs = [UR_REGULAR, np.array([0.0, -1.3, 1.5, -1.8, 1.4, 0.0]), np.array([1.0, -2.0, 1.0, 0.5, -1.2, 2.0])]
    for q in qs:
        r = rc.analyze(arm, q)
        assert r.kind == "regular" and not r.singular and not r.near_singular, r
        assert r.rank == 6 and r.lost_directions_task.shape == (6, 0) and r.null_space.shape == (6, 0)
        assert r.sigma_min_scaled > 0.03


def test_ur5e_has_no_spherical_wrist_and_its_lost_directions_are_null():
    arm = rc.robots.ur5e()
    st = S.structure(arm)
    assert not st.spherical_wrist and st.elbow == (1, 2) and st.shoulder
    q = UR_REGULAR.copy()
    q[4] = 0.0
    r = rc.analyze(arm, q)
    assert r.det_arm is None and r.det_wrist is None
    J = arm.jacobian(q)
    JL = J.copy()
    JL[:3] /= r.length
    assert r.null_space.shape == (6, 1) and np.max(np.abs(J @ r.null_space)) < 1e-12
    assert r.lost_directions_task.shape == (6, 1)
    assert np.max(np.abs(r.lost_directions_task.T @ JL)) < 1e-12
    # the null motion uses the parallel joints 2, 3, 4 and 6 — not 1 or 5
    v = np.abs(r.null_space[:, 0])
    assert v[0] < 1e-9 and v[4] < 1e-9 and np.all(v[[1, 2, 3, 5]] > 1e-3)


# ---------------------------------------------------------------- spherical wrists
@pytest.mark.parametrize("name", ["puma560", "stanford"])
def test_spherical_wrist_decoupling(name, rng):
    arm = rc.robots.BUILTIN[name]()
    assert S.structure(arm).spherical_wrist
    for _ in range(10):
        q = arm.random_q(rng=rng)
        r = rc.analyze(arm, q)
        # refer J to the wrist centre through the kinematics API (tool-frame point)
        T = arm.fk(q)
        point = T[:3, :3].T @ (r.wrist_center - T[:3, 3])
        JW = arm.jacobian(q, point=point)
        assert np.max(np.abs(JW[:3, 3:])) < 1e-12  # J12 = 0
        det11, det22 = np.linalg.det(JW[:3, :3]), np.linalg.det(JW[3:, 3:])
        assert abs(det11 - r.det_arm) < 1e-12 and abs(det22 - r.det_wrist) < 1e-12
        assert abs(np.linalg.det(arm.jacobian(q)) - det11 * det22) < 1e-12
        assert abs(abs(det22) - abs(math.sin(q[4]))) < 1e-12


def test_puma_arm_determinant_closed_form(rng):
    arm = rc.robots.puma560()
    for _ in range(10):
        q = arm.random_q(rng=rng)
        c2, s3, c3 = math.cos(q[1]), math.sin(q[2]), math.cos(q[2])
        s23, c23 = math.sin(q[1] + q[2]), math.cos(q[1] + q[2])
        expected = -PUMA_A2 * (PUMA_D4 * c3 + PUMA_A3 * s3) * (PUMA_A2 * c2 + PUMA_A3 * c23 - PUMA_D4 * s23)
        assert abs(rc.analyze(arm, q).det_arm - expected) < 1e-12


def test_stanford_arm_determinant_closed_form(rng):
    arm = rc.robots.stanford()
    for _ in range(10):
        q = arm.random_q(rng=rng)
        assert abs(rc.analyze(arm, q).det_arm + q[2] ** 2 * math.sin(q[1])) < 1e-12


@pytest.mark.parametrize("name", ["puma560", "stanford"])
def test_wrist_singularity_q5_zero(name, rng):
    arm = rc.robots.BUILTIN[name]()
    checked = 0
    while checked < 5:
        q = arm.random_q(rng=rng)
        # keep clear of the arm singularities
        if abs(rc.analyze(arm, q).det_arm) < 0.02:
            continue
        checked += 1
        q[4] = 0.0
        r = rc.analyze(arm, q)
        assert r.kind == "wrist" and r.singular and r.rank == 5
        assert f"axes of joints {arm.joint_names[3]!r} and {arm.joint_names[5]!r} are aligned" in r.reason
        assert abs(r.det_wrist) < 1e-12
        q[4] = 5e-3
        assert rc.analyze(arm, q).kind == "wrist"


def test_puma_elbow_and_shoulder_from_the_closed_form():
    arm = rc.robots.puma560()
    # elbow: d4·c3 + a3·s3 = 0
    q3 = math.atan2(-PUMA_D4, PUMA_A3)
    q = np.array([0.2, 0.4, q3, 0.3, 0.9, 0.1])
    assert rc.analyze(arm, q).kind == "elbow"
    q[2] += 3e-3
    assert rc.analyze(arm, q).kind == "elbow"
    # shoulder: a2·c2 + a3·c23 − d4·s23 = 0, solved for q2 at q3 = 0.5
    q3 = 0.5
    f = lambda q2: PUMA_A2 * math.cos(q2) + PUMA_A3 * math.cos(q2 + q3) - PUMA_D4 * math.sin(q2 + q3)  # noqa: E731
    lo, hi = 0.0, 1.5
    assert f(lo) * f(hi) < 0
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if f(lo) * f(mid) > 0 else (lo, mid)
    q = np.array([0.2, 0.5 * (lo + hi), q3, 0.3, 0.9, 0.1])
    r = rc.analyze(arm, q)
    assert r.kind == "shoulder" and r.singular
    q[1] += 3e-3
    assert rc.analyze(arm, q).kind == "shoulder"


# ---------------------------------------------------------------- RPR, n < 6
def test_rpr_rank_and_directions_it_never_moves_in(rng):
    arm = rc.robots.rpr(d1=0.4, d3=0.1)
    qs = arm.random_q(500, rng=rng)
    res = rc.scan(arm, qs)
    assert np.all(res.rank == 3) and not np.any(res.singular)
    assert np.all(res.kinds == "regular")
    # the zero row: v_z is never produced, at any q
    J = arm.jacobian(qs)
    assert np.max(np.abs(J[:, 2, :])) < 1e-15  # zero up to rounding (cos(π/2) ≈ 6e-17)
    fixed = S.fixed_lost_directions(arm)
    assert fixed.shape == (6, 1)
    assert np.allclose(np.abs(fixed[:, 0]), [0, 0, 1, 0, 0, 0], atol=1e-12)
    r = rc.analyze(arm, qs[0])
    assert r.rank == 3 and r.max_rank == 3 and r.null_space.shape == (3, 0)
    lost = r.lost_directions_task
    assert lost.shape == (6, 3)
    # v_z lies in the lost subspace at this q; the lost subspace is orthogonal to J_L
    e3 = np.eye(6)[2]
    assert abs(np.linalg.norm(lost.T @ e3) - 1.0) < 1e-12
    JL = J[0].copy()
    JL[:3] /= r.length
    assert np.max(np.abs(lost.T @ JL)) < 1e-12
    assert "3 of the 6 task directions" in r.reason


def test_planar2r_stretched_loses_translation_only():
    arm = rc.robots.planar2r()
    r = rc.analyze(arm, np.array([0.3, 0.0]))
    # the 6×2 J keeps rank 2 (the angular rows differ), but the tool point cannot move
    # radially: for an arm with fewer than 6 joints that is a workspace boundary
    assert r.rank == 2 and r.kind == "boundary"
    assert r.sigma_translational[-1] < 1e-12 and "stretched or folded" in r.reason
    assert rc.scan(arm, np.array([[0.3, 0.0], [0.3, math.pi], [0.3, 1.0]])).kinds.tolist() == \
        ["boundary", "boundary", "regular"]
    assert rc.singularity.classify(arm, [0.3, 0.0])[0] == "boundary"
    assert rc.analyze(rc.robots.rpr(), [0.6, 0.35, -0.4]).kind == "regular"   # v_z is lost everywhere


# ---------------------------------------------------------------- redundant arms
def test_iiwa_rank_of_the_6x7_jacobian(rng):
    arm = rc.robots.iiwa7()
    q = arm.random_q(rng=rng)
    r = rc.analyze(arm, q)
    assert r.max_rank == 6 and r.rank == 6 and r.null_space.shape == (7, 1)
    assert np.max(np.abs(arm.jacobian(q) @ r.null_space)) < 1e-12
    assert S.structure(arm).spherical_wrist and r.det_arm is None  # decoupled dets: 6 joints only
    q = np.array([0.3, 0.7, -0.4, 0.0, 0.5, 0.8, 0.2])  # elbow stretched: q4 = 0
    r = rc.analyze(arm, q)
    assert r.rank == 5 and r.kind == "boundary" and r.null_space.shape == (7, 2)
    assert np.max(np.abs(arm.jacobian(q) @ r.null_space)) < 1e-12


def test_panda_is_not_a_spherical_wrist():
    assert not S.structure(rc.robots.panda()).spherical_wrist


# ---------------------------------------------------------------- batched scans
@pytest.mark.parametrize("name", ["ur5e", "puma560", "stanford", "iiwa7", "rpr", "panda"])
def test_scan_equals_looped_analyze(name):
    arm = rc.robots.BUILTIN[name]()
    rng = np.random.default_rng(3)
    qs = arm.random_q((3, 4), rng=rng)
    if name == "ur5e":  # include singular and near-singular configurations
        qs[0, :] = np.array([c[1] for c in ur_cases()] + [UR_REGULAR])
        qs[1, 0, 4] = 1e-3
    res = rc.scan(arm, qs, raw=True)
    assert res.sigma_scaled.shape == (3, 4, min(6, arm.dof)) and res.kind_code.shape == (3, 4)
    for idx in np.ndindex(3, 4):
        r = rc.analyze(arm, qs[idx])
        assert res.kinds[idx] == r.kind
        assert res.rank[idx] == r.rank
        assert abs(res.sigma_min_scaled[idx] - r.sigma_min_scaled) < 1e-12
        assert np.allclose(res.sigma_scaled[idx], r.sigma_scaled, rtol=1e-12, atol=1e-12)
        assert np.allclose(res.sigma[idx], r.sigma, rtol=1e-12, atol=1e-12)
        assert math.isclose(res.manipulability[idx], r.manipulability, rel_tol=1e-10, abs_tol=1e-14)
        assert math.isclose(res.manipulability_translational[idx], r.manipulability_translational,
                            rel_tol=1e-10, abs_tol=1e-14)
    counts = res.count()
    assert sum(counts.values()) == 12


def test_scan_counts_kinds_over_a_large_batch():
    arm = rc.robots.ur5e()
    qs = arm.random_q(3000, rng=11)
    res = rc.scan(arm, qs)
    # near-singular ⇔ σ_min(J_L) < near; every near-singular UR5e configuration is named
    assert np.array_equal(res.kind_code != 0, res.sigma_min_scaled < S.DEFAULT_NEAR)
    # the singular values match an SVD of the scaled Jacobian
    J = arm.jacobian(qs)
    J[:, :3] /= arm.characteristic_length
    assert np.allclose(res.sigma_scaled, np.linalg.svd(J, compute_uv=False), rtol=1e-8, atol=1e-12)


@pytest.mark.parametrize("name,joint", [("ur5e", 4), ("puma560", 4), ("iiwa7", 3)])
def test_fast_classify_equals_scan(name, joint):
    arm = rc.robots.BUILTIN[name]()
    qs = arm.random_q(400, rng=5)
    qs[:40, joint] = np.linspace(-0.02, 0.02, 40)  # plenty of near-singular configurations
    res = rc.scan(arm, qs)
    assert np.sum(res.near_singular) >= 40
    J = arm.jacobian(qs)
    for i in range(len(qs)):
        kind, smin = S.classify(arm, qs[i])
        assert kind == res.kinds[i] and abs(smin - res.sigma_min_scaled[i]) < 1e-12
        assert S.classify(arm, J=J[i])[0] == kind
    with pytest.raises(rc.InputError):
        S.classify(arm, J=np.zeros((6, 3)))
    with pytest.raises(rc.InputError):
        S.classify(arm)


# ---------------------------------------------------------------- gradient
def test_manipulability_gradient_matches_finite_differences(arm, rng):
    h = 1e-6
    for _ in range(5):
        q = arm.random_q(rng=rng)
        g = rc.manipulability_gradient(arm, q)
        assert g.shape == (arm.dof,)
        E = np.eye(arm.dof) * h
        w = lambda x: rc.manipulability(arm.jacobian(x))  # noqa: E731
        gfd = (w(q + E) - w(q - E)) / (2 * h)
        assert np.max(np.abs(g - gfd)) < 1e-7 * max(1.0, float(np.max(np.abs(gfd))))


def test_manipulability_gradient_is_batched_and_scalable(rng):
    arm = rc.robots.panda()
    qs = arm.random_q((2, 3), rng=rng)
    G = rc.manipulability_gradient(arm, qs)
    assert G.shape == (2, 3, 7)
    for idx in np.ndindex(2, 3):
        assert np.allclose(G[idx], rc.manipulability_gradient(arm, qs[idx]), rtol=1e-10, atol=1e-14)
    # the scaled gradient of a 6×n Jacobian is the raw one over L³
    L = 0.8
    assert np.allclose(rc.manipulability_gradient(arm, qs, length=L), G / L**3, rtol=1e-9, atol=1e-14)


def test_manipulability_gradient_points_away_from_the_wrist_singularity():
    arm = rc.robots.ur5e()
    q = UR_REGULAR.copy()
    q[4] = 0.05
    g = rc.manipulability_gradient(arm, q)
    assert g[4] > 0 and abs(g[4]) == np.max(np.abs(g))  # increase |q5|


# ---------------------------------------------------------------- paths
def test_path_distance_through_the_wrist_singularity():
    arm = rc.robots.ur5e()
    t = np.linspace(-0.2, 0.2, 41)
    qs = np.tile(UR_REGULAR, (41, 1))
    qs[:, 4] = t
    pd = S.path_distance(arm, qs)
    assert pd.closest == 20 and pd.kinds[20] == "wrist"
    assert pd.sigma_min_scaled[20] < 1e-12
    near = np.abs(t) <= 0.02
    assert np.allclose(pd.joint_distance[near], np.abs(t[near]), atol=2e-4)
    assert np.all(pd.kinds[np.abs(t) > 0.1] == "regular")
    assert pd.s[-1] == pytest.approx(0.4)


# ---------------------------------------------------------------- workspace maps
def test_workspace_map_over_two_joints_matches_scan():
    arm = rc.robots.ur5e()
    q = np.array([0.0, -1.0, 1.0, -1.0, 1.0, 0.0])
    wm = S.workspace_map(arm, joints=(1, 2), q=q, resolution=9, measure="sigma_min_scaled")
    assert wm.values.shape == (9, 9) and wm.kind_code.shape == (9, 9)
    iy, ix = 3, 6
    qq = q.copy()
    qq[1], qq[2] = wm.x[ix], wm.y[iy]
    assert abs(wm.values[iy, ix] - rc.analyze(arm, qq).sigma_min_scaled) < 1e-12
    # the row q3 = 0 is an elbow singularity
    row = np.argmin(np.abs(wm.y))
    assert abs(wm.y[row]) < 1e-12 and np.all(wm.values[row] < 1e-12)
    assert np.all(wm.kind_code[row] == KIND_ELBOW)


KIND_ELBOW = S.KINDS.index("elbow")


def test_workspace_map_over_a_plane_and_plot(tmp_path):
    matplotlib = pytest.importorskip("matplotlib")
    matplotlib.use("Agg")
    arm = rc.robots.planar2r()
    wm = S.workspace_map(arm, plane="xy", resolution=21, samples=20000, slab=0.1)
    assert wm.values.shape == (21, 21)
    inside = np.hypot(*np.meshgrid(wm.x, wm.y)) < 1.8
    outside = np.hypot(*np.meshgrid(wm.x, wm.y)) > 2.1
    assert np.all(np.isnan(wm.values[outside]))
    assert np.mean(np.isfinite(wm.values[inside])) > 0.9
    ax = S.plot_workspace_map(wm)
    ax.figure.savefig(tmp_path / "map.png")
    assert (tmp_path / "map.png").stat().st_size > 1000


# ---------------------------------------------------------------- errors and results
def test_errors_and_frozen_results():
    arm = rc.robots.ur5e()
    with pytest.raises(rc.InputError):
        rc.analyze(arm, np.zeros((2, 6)))
    with pytest.raises(rc.InputError):
        rc.analyze(arm, np.zeros(5))
    with pytest.raises(rc.InputError):
        rc.analyze(arm, np.zeros(6), length=0.0)
    with pytest.raises(rc.InputError):
        rc.analyze(arm, np.zeros(6), near=-1.0)
    with pytest.raises(rc.InputError):
        S.workspace_map(arm, joints=(0, 1), plane="xz")
    with pytest.raises(rc.InputError):
        S.workspace_map(arm, joints=(0, 1), measure="volume")
    with pytest.raises(rc.InputError):
        S.workspace_map(arm, joints=(0, 0))
    with pytest.raises(rc.InputError):
        S.workspace_map(arm, joints=(0, 1), ranges=((1.0, -1.0), (0.0, 1.0)))
    with pytest.raises(rc.InputError):
        S.path_distance(arm, np.zeros(6))
    r = rc.analyze(arm, UR_REGULAR)
    with pytest.raises(dataclasses.FrozenInstanceError):
        r.kind = "wrist"
    with pytest.raises(ValueError):
        r.sigma[0] = 1.0
    with pytest.raises(TypeError):
        r.factors["wrist"] = 0.0
    assert isinstance(rc.SingularityReport, type) and r.kind in S.KINDS
    assert "regular" in str(r)


def test_gradient_matches_roboticstoolbox_jacobm():
    rtb = pytest.importorskip("roboticstoolbox")
    peer = rtb.models.DH.UR5()
    rows = [rc.DH(a=L.a, alpha=L.alpha, d=L.d, theta=L.offset) for L in peer.links]
    arm = rc.Chain.from_dh(rows, base=np.asarray(peer.base.A), tool=np.asarray(peer.tool.A))
    rng = np.random.default_rng(9)
    for _ in range(3):
        q = arm.random_q(rng=rng)
        assert math.isclose(float(peer.manipulability(q)), float(rc.manipulability(arm.jacobian(q))),
                            rel_tol=1e-10, abs_tol=1e-15)
        assert np.allclose(np.asarray(peer.jacobm(q)).ravel(), rc.manipulability_gradient(arm, q),
                           rtol=1e-9, atol=1e-13)


@st.composite
def random_chain(draw):
    n = draw(st.integers(1, 8))
    lengths = st.floats(-1.0, 1.0, allow_nan=False)
    angles = st.one_of(st.floats(-math.pi, math.pi, allow_nan=False),
                       st.sampled_from([0.0, math.pi / 2, -math.pi / 2]))
    rows = [rc.DH(a=draw(lengths), d=draw(lengths), alpha=draw(angles), theta=draw(angles),
                  joint=draw(st.sampled_from(["revolute", "revolute", "prismatic"])))
            for _ in range(n)]
    chain = rc.Chain.from_dh(rows)
    seed = draw(st.integers(0, 2**31))
    return chain, chain.random_q(4, rng=seed)


@settings(max_examples=40, deadline=None)
@given(random_chain())
def test_random_chains_scan_analyze_classify_agree(case):
    chain, qs = case
    res = rc.scan(chain, qs)
    for i in range(len(qs)):
        r = rc.analyze(chain, qs[i])
        assert r.kind == res.kinds[i] == S.classify(chain, qs[i])[0]
        assert r.rank == res.rank[i] and r.null_space.shape == (chain.dof, chain.dof - r.rank)
        assert r.lost_directions_task.shape == (6, 6 - r.rank)
        # a null vector belongs to a σ_i(J_L) ≤ rtol·σ₁(J_L) (J_L = diag(I/L, I)·J), so
        # ‖J v‖ ≤ max(L, 1)·rtol·σ₁(J_L) — not exactly zero near a rank change
        J = chain.jacobian(qs[i])
        L = r.length
        bound = max(L, 1.0) * r.rtol * float(np.linalg.norm(np.diag([1 / L] * 3 + [1.0] * 3) @ J, 2))
        assert np.max(np.abs(J @ r.null_space), initial=0.0) <= 1.01 * bound + 1e-12
